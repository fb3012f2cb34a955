"""The state of one run and the files it keeps up to date, each generation and at its end."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.ga import GAResult, Generation
from flexopt.optimise.hybrid import GradientStep
from flexopt.optimise.problem import DesignDetail
from flexopt.optimise.requirements import Verdict, verdict_record
from flexopt.pipeline.checkpoint import (
    CHECKPOINT_FILE,
    STORE_FILE,
    EvaluationStore,
    checkpoint_text,
)
from flexopt.pipeline.fork import ForkedMakes
from flexopt.pipeline.parallel import BatchBackend, ParallelSettings, design_key, evaluate_batch
from flexopt.pipeline.parallel import one_line as _one_line
from flexopt.pipeline.plot_targets import plot_spec
from flexopt.pipeline.responses import case_responses, stacked_table, stress_allowable
from flexopt.pipeline.run.evaluator import Evaluator
from flexopt.pipeline.run.export import (
    EXPORT_FORMATS,
    export_frame,
    handoff_files,
    part_bytes,
    part_of,
    step_available,
)
from flexopt.pipeline.run.folder import RUN_FILES, Columns, write_files
from flexopt.pipeline.run.setup import RunSetup
from flexopt.pipeline.run.split_makes import SplitMakes, WithEarly, forked
from flexopt.pipeline.run.step_child import EarlyStep
from flexopt.pipeline.runfolder import records_to_csv, table_to_csv, to_json, write_atomic
from flexopt.pipeline.verdict import judge_detail

if TYPE_CHECKING:  # geometry.solid (manifold3d, trimesh) is imported when a part is made
    from flexopt.geometry.solid import FlatPart

# The report's modules (report.html, the plots, the VTU files, the durability record: ~0.06 s
# CPU to import) are imported where the report is made, not with this module: a run imports
# this module before its pool forks, where every import is on the start's critical path while
# the other core idles; the run's preload thread imports them while the workers solve
# (pipeline/run/runner.py).

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------------------------
# The run


@dataclass(frozen=True)
class GenerationReport:
    """Progress after one generation (what the CLI prints).

    Attributes
    ----------
    generation : 1-based generation number; ``n_gen`` in all.
    n_evaluations : designs solved so far (cache hits not counted).
    n_cache_hits : designs served from the cache so far.
    best : the best design so far.
    feasible_fraction : share of this generation's designs that are feasible.
    evaluations_per_s : designs solved per second of this generation.
    wall_s : s since the optimisation started.
    objective_names : the objectives of ``best.f`` (``negative_X``: X maximised).
    stage : ``"ga"`` (a generation of the GA, also the hybrid optimiser's GA stage) or
        ``"gradient"`` (one batch of the hybrid's gradient stage: ``generation`` counts on past
        the GA's ``n_gen``, ``step`` is its number in the stage, 1-based; 0 in the GA).
    last : the optimisation ends with this report: a GA run's generation ``n_gen``; a hybrid
        run, whose end no generation foretells, repeats its last report once with ``last``
        when its gradient stage has ended (nothing new solved).
    """

    generation: int
    n_gen: int
    n_evaluations: int
    n_cache_hits: int
    best: Evaluation
    feasible_fraction: float
    evaluations_per_s: float
    wall_s: float
    objective_names: tuple[str, ...] = ()
    stage: str = "ga"
    step: int = 0
    last: bool = False


class RunState:
    """The state of one run and the files it keeps up to date."""

    def __init__(
        self,
        setup: RunSetup,
        run_dir: Path,
        record: dict[str, Any],
        on_generation: Callable[[GenerationReport], None] | None,
        on_result: Callable[[], None] | None,
        backend: BatchBackend = evaluate_batch,
        store: EvaluationStore | None = None,
        restored: Iterable[Evaluation] = (),
    ) -> None:
        self.setup = setup
        self.problem = setup.problem
        self.run_dir = run_dir
        self.record = record
        self.on_generation = on_generation
        self.columns = Columns.of(setup.problem)
        self.evaluator = Evaluator(
            setup.problem, backend, on_result=on_result, store=store, restored=restored
        )
        self.n_backend_last = 0
        self.rows: list[dict[str, Any]] = []
        self.where: dict[bytes, tuple[int, int]] = {}  # design -> (generation, index) solved
        self.history: list[dict[str, Any]] = []
        self.generations: list[Generation] = []
        self.gradient_steps = 0  # batches of the hybrid's gradient stage so far
        self.last_report: GenerationReport | None = None
        self.t0 = time.perf_counter()
        self.t_last = self.t0
        self.notes: list[str] = []
        self.files: list[str] = []
        self.stl: dict[str, Any] = {}
        # evaluations.csv: the header its rows were formatted with, their text, how many
        # the writer thread of the per-generation files (see generation_done)
        self._writer: ThreadPoolExecutor | None = None
        self._pending: Future | None = None
        # the report's files queued on their writer thread, in order (see _write_soon)
        self._report_writer: ThreadPoolExecutor | None = None
        self._report_writes: list[Future] = []
        # files made in forked children at the end of the run (see artefact)
        self._groups: dict[str, list[tuple[str, Callable[[], str | bytes | None]]]] = {}
        self._started: list[ForkedMakes | SplitMakes | WithEarly | EarlyStep] = []
        # files of a group started before the best design's detail (see start_early)
        self._early_made: dict[str, ForkedMakes] = {}
        self._early: EarlyStep | None = None  # best.step's child, once it has the part
        self._csv_header: list[str] | None = None
        self._csv_body: list[str] = []
        self._csv_rows = 0

    # -- bookkeeping ------------------------------------------------------------------------

    def collect(self, generation: int) -> int:
        """Rows for the designs solved since the last call; returns how many."""
        new = self.evaluator.solved[len(self.rows) :]
        for ev in new:
            index = len(self.rows)
            self.rows.append(self.columns.row(generation, index, ev))
            self.where.setdefault(design_key(ev.x), (generation, index))
        return len(new)

    def generation_done(self, gen: Generation) -> None:
        # One fsync of the store per generation, before anything reports the generation: a
        # design a checkpoint, run.json or the console counts is on disk (docs/parallel.md).
        if self.evaluator.store is not None:
            self.evaluator.store.sync()
        now = time.perf_counter()
        number = gen.index + 1
        self.collect(number)
        # solved now, not served from the store of an earlier session: the rate a user can plan by
        n_new = self.evaluator.n_backend - self.n_backend_last
        self.n_backend_last = self.evaluator.n_backend
        gen_wall = now - self.t_last
        self.t_last = now
        self.generations.append(gen)
        gradient = isinstance(gen, GradientStep)
        self.gradient_steps += gradient
        report = GenerationReport(
            generation=number,
            n_gen=self.setup.config.n_gen,
            n_evaluations=len(self.rows),
            n_cache_hits=self.evaluator.n_cache_hits,
            best=gen.best,
            feasible_fraction=gen.feasible_fraction,
            evaluations_per_s=n_new / gen_wall if gen_wall > 0 else 0.0,
            wall_s=now - self.t0,
            objective_names=tuple(self.problem.objective_names),
            stage="gradient" if gradient else "ga",
            step=self.gradient_steps if gradient else 0,
            last=self.setup.hybrid is None and number == self.setup.config.n_gen,
        )
        self.last_report = report
        entry: dict[str, Any] = {
            "generation": number,
            "n_evaluations": report.n_evaluations,
            "n_cache_hits": report.n_cache_hits,
        }
        entry.update(
            {
                f"best_{name}": float(v)
                for name, v in zip(self.columns.objectives, gen.best.f, strict=True)
            }
        )
        entry["best_feasible"] = gen.best.feasible
        entry["feasible_fraction"] = report.feasible_fraction
        entry["evaluations_per_s"] = report.evaluations_per_s
        entry["wall_s"] = report.wall_s
        self.history.append(entry)
        self.record.update(
            generations_done=number,
            n_evaluations=report.n_evaluations,
            n_cache_hits=report.n_cache_hits,
            n_restored=self.evaluator.n_restored,
            n_solved=self.evaluator.n_backend,
            optimise_wall_s=report.wall_s,
        )
        if self.setup.hybrid is not None:  # flexopt status: which stage, and how far
            self.record.update(
                stage=report.stage,
                ga_generations=number - self.gradient_steps,
                gradient_steps=self.gradient_steps,
            )
        # The generation's files are formatted here and written (each atomically, fsynced) by
        # one writer thread while the workers solve the next generation: their fsyncs (four per
        # generation, 5-15 ms each on the development machine) no longer hold the workers idle.
        # The store, the only file a resume needs, was fsynced above, before anything counts the
        # generation. The writes keep their order; one generation's are in flight at most.
        # The CSV rows are formatted on the writer thread too (~10 ms a generation at the end
        # of a 2400-design run), from a snapshot: the header, the row count, the history.
        # checkpoint.json and run.json are formatted there too (indented JSON is encoded in
        # Python, ~3 ms a generation), from their data as it stands now: the checkpoint's dict
        # is built here and the record copied (generation_done only replaces its values).
        snapshot = (self.columns.header(), len(self.rows), list(self.history))
        checkpoint = self.checkpoint_data(gen)
        record = dict(self.record)
        files: list[Any] = [
            lambda: self.table_texts(*snapshot),
            lambda: [(CHECKPOINT_FILE, checkpoint_text(checkpoint))],
            lambda: [("run.json", to_json(record))],
        ]
        self.write_later(files)
        log.info(
            "gradient step %d: %d evaluations, best %s, %.0f%% feasible, %.3g eval/s"
            if gradient
            else "generation %d/%d: %d evaluations, best %s, %.0f%% feasible, %.3g eval/s",
            *((report.step,) if gradient else (number, report.n_gen)),
            report.n_evaluations,
            gen.best.f.tolist(),
            100 * report.feasible_fraction,
            report.evaluations_per_s,
        )
        if self.on_generation is not None:
            self.on_generation(report)

    def write_later(self, files: list[Any]) -> None:
        """Write ``files`` ((name, text) in the run folder, or callables that make such pairs,
        in order) on the writer thread.

        Waits for the previous generation's writes first, so at most one generation's files are
        in flight and a failed write (a full disk) raises here, one generation late.
        """
        self.drain_writes()
        if self._writer is None:
            self._writer = ThreadPoolExecutor(1, thread_name_prefix="flexopt-writes")
        self._pending = self._writer.submit(write_files, self.run_dir, files)

    def drain_writes(self) -> None:
        """Wait until the writer thread has written everything handed to it (raises its error)."""
        pending, self._pending = self._pending, None
        if pending is not None:
            pending.result()

    def finish_writes(self, raise_errors: bool = True) -> None:
        """Drain and stop the writer thread (at the end of the optimisation, or when it fails:
        then ``raise_errors=False`` keeps the original error and logs the write's)."""
        try:
            self.drain_writes()
        except Exception as exc:
            if raise_errors:
                raise
            log.warning("a run file was not written: %s", _one_line(f"{type(exc).__name__}: {exc}"))
        finally:
            if self._writer is not None:
                self._writer.shutdown(wait=True)
                self._writer = None

    def checkpoint_data(self, gen: Generation) -> dict[str, Any]:
        """checkpoint.json: what a resume needs besides the store, and what ``status`` shows."""
        config = self.setup.config
        population = gen.population if gen.population is not None else np.empty((0, 0))
        return dict(
            {
                "study_sha256": self.record["study_sha256"],
                "generation": gen.index + 1,
                "n_gen": config.n_gen,
                "pop_size": config.pop_size,
                "algorithm": config.algorithm,
                "quick": self.setup.quick,
                # pymoo draws every random number from a Generator seeded once with this seed,
                # so the seed and the evaluations (the store) determine the whole run: a resume
                # replays it rather than restoring a random state.
                "rng": {"seed": config.seed, "library": "pymoo", "resume": "replay"},
                "store": STORE_FILE,
                "n_evaluations": len(self.rows),
                "n_cache_hits": self.evaluator.n_cache_hits,
                "variables": list(self.problem.space.names),
                "population": [[float(v) for v in x] for x in population],
                "best": {
                    "x": [float(v) for v in gen.best.x],
                    "f": [float(v) for v in gen.best.f],
                    "feasible": gen.best.feasible,
                },
            },
        )

    def settle_best(self, best: Evaluation) -> None:
        """history.csv's last row names the run's ``best`` (rewritten now if it did not).

        A generation's best is the best of the optimiser's rows so far; a calibrated hybrid's
        best is the lowest design whose check was met (optimise/hybrid.py), which can be above
        the lowest row (a lower design's check was not met) and is chosen after the last batch.
        The last row is the run's state when the optimisation ended, so it says the design the
        run chose: history.csv, best.json, report.md and the console then name one best design.
        """
        if not self.history:
            return
        row = self.history[-1]
        chosen = {
            f"best_{name}": float(v)
            for name, v in zip(self.columns.objectives, best.f, strict=True)
        }
        chosen["best_feasible"] = best.feasible
        if all(row.get(k) == v for k, v in chosen.items()):
            return
        row.update(chosen)
        self.write_tables()

    def write_tables(self) -> None:
        """evaluations.csv and history.csv now, after anything the writer thread still holds."""
        self.drain_writes()
        write_files(self.run_dir, self.table_texts())

    def table_texts(
        self,
        header: list[str] | None = None,
        upto: int | None = None,
        history: list[dict[str, Any]] | None = None,
    ) -> list[tuple[str, str]]:
        """(name, text) of evaluations.csv and history.csv: as they stand, or with ``header``,
        the first ``upto`` rows and ``history`` (a snapshot; the writer thread formats it while
        this thread goes on appending rows)."""
        header = self.columns.header() if header is None else header
        upto = len(self.rows) if upto is None else upto
        history = self.history if history is None else history
        # evaluations.csv is rewritten whole (atomically) every generation, but each row is
        # formatted once: formatting all rows every generation made a 2400-design run spend
        # ~1 s per generation at the end in records_to_csv, with the workers idle. A row's text
        # depends only on the header, which grows when a new metric appears: then all again.
        if header != self._csv_header:
            self._csv_header, self._csv_body, self._csv_rows = header, [], 0
        new = self.rows[self._csv_rows : upto]
        if new:
            text = records_to_csv(new, header, exact=set(self.columns.variables))
            self._csv_body.append(text[text.index("\n") + 1 :])  # without its header line
            self._csv_rows = upto
        head = records_to_csv([], header)
        files = [("evaluations.csv", head + "".join(self._csv_body))]
        if history:
            files.append(("history.csv", records_to_csv(history, list(history[0]))))
        return files

    # -- the end of a run ----------------------------------------------------------------------

    def artefact(
        self, name: str, make: Callable[[], str | bytes | None], group: str | None = None
    ) -> None:
        """Write one result file; a failure to *make* it is a note, not the end of the run.

        With a ``group`` the file is only queued: :meth:`start_groups` makes each group's files
        in a forked child process while this one goes on, :meth:`collect_groups` writes them.
        """
        if group is not None:
            self._groups.setdefault(group, []).append((name, make))
            return
        try:
            data = make()
        except Exception as exc:
            log.info("%s: traceback", name, exc_info=True)
            self._made(name, None, _one_line(f"{type(exc).__name__}: {exc}"))
            return
        self._made(name, data, None)

    def _made(self, name: str, data: str | bytes | None, error: str | None) -> None:
        if error is not None:
            note = f"{name} not written: {error}"
            log.warning(note)  # the CLI prints the notes; the traceback only with -v
            self.notes.append(note)
            return
        if data is None:
            return
        self._write_soon(name, data)
        self.files.append(name)

    def _write_soon(self, name: str, data: str | bytes) -> None:
        """Write one file of the report (atomically, fsynced: :func:`write_atomic`) on the
        writer thread, in the order queued, while this thread goes on.

        A constant-force run's report writes 78 files (best_steps/ holds one VTU per load
        step), each with its fsync (~5 ms a file on the development machine's disk, more where
        other processes write): one after another in this thread they were ~0.4 s of the
        report's critical path; now they overlap the making of the next files and report.html.
        :meth:`finish` waits for them (:meth:`drain_report_writes`) before the run's report.md
        and run.json say it finished.
        """
        if self._report_writer is None:
            self._report_writer = ThreadPoolExecutor(1, thread_name_prefix="flexopt-report-writes")
        self._report_writes.append(
            self._report_writer.submit(write_atomic, self.run_dir / name, data)
        )

    def drain_report_writes(self, raise_errors: bool = True) -> None:
        """Wait until every report file queued by :meth:`_write_soon` is written, and stop the
        writer thread; the first failed write raises (with ``raise_errors=False``: logged)."""
        writes, self._report_writes = self._report_writes, []
        error: BaseException | None = None
        for write in writes:
            try:
                write.result()
            except Exception as exc:
                error = error or exc
        if self._report_writer is not None:
            self._report_writer.shutdown(wait=True)
            self._report_writer = None
        if error is not None:
            if raise_errors:
                raise error
            log.warning(
                "a report file was not written: %s", _one_line(f"{type(error).__name__}: {error}")
            )

    def start_groups(self) -> None:
        """Make each group queued since the last call in a child process (see
        :class:`ForkedMakes`); a group of :data:`SPLIT_GROUP_AT` files or more in two
        (:class:`SplitMakes`). :meth:`collect_groups` writes them in the order they started.

        The files queued for the writer thread are written first: no thread of this process
        is then inside a write (a lock it holds, e.g. tempfile's, would stay held in the child).
        """
        if self._groups and self._report_writes:
            self.drain_report_writes()
        for items in self._groups.values():
            early = {n: self._early_made.pop(n) for n, _ in items if n in self._early_made}
            self._started.append(WithEarly(items, early) if early else forked(items))
        self._groups = {}

    def start_early(self, name: str, make: Callable[[], str | bytes | None]) -> None:
        """Start making ``name`` in a forked child now (:class:`ForkedMakes`), before the
        best design's detail: its :meth:`artefact` call later (with a group) takes the child's
        file instead of making it again, and writes it in its place among the group's.

        Called before any writer thread runs (no thread holds a lock the child needs).
        """
        self._early_made[name] = ForkedMakes([(name, make)])

    def reap_early(self) -> None:
        """Wait for early children whose file was never queued (the report ended first)."""
        early, self._early_made = self._early_made, {}
        for job in early.values():
            job.results()

    def collect_groups(self) -> None:
        """Write the files the children made, in the order they were queued."""
        started, self._started = self._started, []
        for job in started:
            for name, data, error in job.results():
                self._made(name, data, error)

    def best_record(self, best: Evaluation) -> dict[str, Any]:
        generation, index = self.where.get(design_key(best.x), (None, None))
        return {
            "study": self.setup.study.name,
            "kind": self.setup.study.kind,
            "generation": generation,
            "index": index,
            "feasible": best.feasible,
            "reason": best.reason,
            "parameters": dict(zip(self.problem.space.names, map(float, best.x), strict=True)),
            "objectives": dict(zip(self.problem.objective_names, map(float, best.f), strict=True)),
            "constraints": dict(
                zip(self.problem.constraint_names, map(float, best.g), strict=True)
            ),
            "metrics": best.metrics,
            "time_s": best.time_s,
            "x": [float(v) for v in best.x],
        }

    def judge(self, best: Evaluation, detail: DesignDetail | None) -> tuple[Verdict, ...]:
        """The best design against the study's requirements (a failure is a note, not the end)."""
        try:
            return judge_detail(self.setup.study, detail, best)
        except Exception as exc:
            note = f"the verdict failed: {_one_line(f'{type(exc).__name__}: {exc}')}"
            log.warning(note)
            self.notes.append(note)
            return ()

    def finish(self, result: GAResult, early: EarlyStep | None = None) -> DesignDetail | None:
        if self.setup.hybrid is not None and self.last_report is not None:
            self.settle_best(result.best)
            # the hybrid's gradient stage has ended: the end a GA run's generation n_gen marks
            if self.on_generation is not None:
                self.on_generation(replace(self.last_report, last=True, best=result.best))
        # best.step's child: the one the run started (``early``, it imported build123d at low
        # priority while the workers solved), else forked now: it imports build123d (~3 s)
        # while the best design's detail is solved, once a core is idle (see EarlyStep)
        if early is None and step_available():
            early = EarlyStep.start()
        try:
            detail = self._finish(result, early)
        except BaseException:
            self.drain_report_writes(raise_errors=False)  # the original error goes on
            raise
        finally:
            if early is not None:
                early.close()
            self.reap_early()
        self.drain_report_writes()  # every file on disk before the run says it finished
        return detail

    def _finish(self, result: GAResult, early: EarlyStep | None) -> DesignDetail | None:
        from flexopt.pipeline import plots
        from flexopt.pipeline.durability_report import durability_record
        from flexopt.pipeline.report_html import HtmlData, render_html
        from flexopt.pipeline.run.figures import (
            convergence_png,
            curve_png,
            float_or_none,
            spec_label,
        )
        from flexopt.pipeline.vtu import has_mesh, vtu_makers

        study, problem = self.setup.study, self.problem
        best = result.best
        title = f"{study.name}: best design"
        best_json = self.best_record(best)
        # The plots that need only the run's history and designs start now, in a child, on the
        # core that idles while this process solves the best design's detail (one process); the
        # others need the detail. They are written in their place among the plots.
        self.start_early("convergence.png", lambda: convergence_png(self.history, self.columns))
        if len(result.front) > 1 and len(problem.objective_names) >= 2:
            self.start_early("front.png", lambda: self._front_png(result, title))
        detail: DesignDetail | None = None
        try:
            detail = problem.detail(np.array(best.x, dtype=float))
        except Exception as exc:
            note = f"the best design's detail failed: {_one_line(f'{type(exc).__name__}: {exc}')}"
            log.warning(note)  # the CLI prints the notes; the traceback only with -v
            log.info("the best design's detail: traceback", exc_info=True)
            self.notes.append(note + " (no response, plots of it, STL)")
        self.verdicts = self.judge(best, detail)
        robust = self.robustness(best, detail)
        if robust is not None:  # robust: requirements, judged on fresh scatter samples
            self.verdicts = robust.with_robust_rows(self.verdicts)
        if detail is not None:
            detail = replace(detail, verdicts=self.verdicts)
        part = self._flat_part(detail)
        if detail is not None and part is not None:  # the footprint in best.json and the report
            frames = {f: export_frame(f, sheet=part.sheet) for f in EXPORT_FORMATS}
            record = {**part.record(), "frames": {f"best.{f}": v for f, v in frames.items()}}
            detail = replace(detail, info={**detail.info, "part": record})
        best_json = {"verdict": verdict_record(self.verdicts), **best_json}  # the verdict first
        made = detail.evaluation.metrics if detail is not None and detail.evaluation else None
        if made and to_json(made) != to_json(best.metrics):
            # the detail solved the part as exported again (a check of its outline that corrects
            # forces and re-solves the width): best.json's metrics are that part's, the ones
            # flexopt evaluate of the design gives; the optimiser's record of the same x stays
            # beside them (and in evaluations.csv)
            best_json["metrics"] = made
            best_json["optimiser_metrics"] = best.metrics
        if robust is not None:  # the chosen design under the study's scatter (docs/robustness.md)
            best_json["robustness"] = robust.record()
            self.record["robustness"] = {
                k: v for k, v in best_json["robustness"].items() if k not in ("samples", "band")
            }
        if detail is not None and detail.info:
            best_json["info"] = detail.info
        # the study's duty_cycle, hold and stops: one record, as report.md / report.html show it
        durability = durability_record(study, detail) if detail is not None else {}
        if durability:
            best_json["durability"] = durability
        if len(result.front) > 1:
            best_json["front"] = [self.best_record(ev) for ev in result.front]
        self._write_soon("best.json", to_json(best_json))
        self.files.append("best.json")

        table = dict(detail.table) if detail is not None else {}
        spec = plot_spec(detail.plot if detail is not None else None)
        x, y, stress = spec["x"], spec["y"], spec["stress"]
        if detail is not None and detail.cases:  # every case, a load_case column first
            every = stacked_table(detail.cases)
            self.artefact("best_response.csv", lambda: table_to_csv(every))
        elif table:
            self.artefact("best_response.csv", lambda: table_to_csv(table))
        elif detail is not None:
            self.notes.append("the kind gives no response table: no best_response.csv")
        cases = dict(detail.cases) if detail is not None else {}
        # the stress line at the allowable the verdict uses (yield / SF, a plane-stress limit)
        allowables = {
            case: stress_allowable(self.verdicts, case, float_or_none(c.plot.get("allowable_MPa")))
            for case, c in case_responses(table, spec, cases).items()
        }
        if cases:  # several load cases: one panel each, every output on the axis of its unit
            self._case_plots(cases, allowables, title)
        elif x in table and y in table:
            self.artefact(
                "force_displacement.png", lambda: curve_png(table, spec, title), group="png"
            )
        elif table:
            self.notes.append(f"force_displacement.png skipped: no columns '{x}' and '{y}'")
        if not cases and x in table and stress in table:
            line = allowables.get("")
            self.artefact(
                "stress.png",
                lambda: plots.plot_stress(
                    table,
                    x,
                    stress,
                    allowable_MPa=line[0] if line else None,
                    x_label=spec_label(spec, "x"),
                    title=title,
                    allowable_label=line[1] if line else None,
                ),
                group="png",
            )
        elif table and not cases:
            self.notes.append(f"stress.png skipped: the response has no '{stress}' column")
        self.artefact(
            "convergence.png", lambda: convergence_png(self.history, self.columns), group="png"
        )
        if detail is not None and detail.shapes_mm is not None:
            values = table.get(x)
            shapes = np.asarray(detail.shapes_mm)
            if values is not None and len(values) != len(shapes):
                values = None
            self.artefact(
                "shapes.png",
                lambda: plots.plot_shapes(shapes, values, value_label=x, title=title),
                group="png",
            )
        fmap = getattr(detail, "field_map", None) if detail is not None else None
        if fmap:
            self.artefact(
                "stress_map.png",
                lambda: plots.plot_field(
                    fmap["points_mm"],
                    fmap["triangles"],
                    fmap["values"],
                    label=fmap.get("label", "von Mises stress (MPa)"),
                    limit=float_or_none(fmap.get("limit")),
                    title=title,
                ),
                group="png",
            )
            if fmap.get("displacement_mm") is not None:  # the same field on the deformed part
                self.artefact(
                    "stress_deformed.png",
                    lambda: plots.plot_field_deformed(
                        fmap["points_mm"],
                        fmap["triangles"],
                        fmap["values"],
                        fmap["displacement_mm"],
                        label=fmap.get("label", "von Mises stress (MPa)"),
                        limit=float_or_none(fmap.get("limit")),
                        title=title,
                    ),
                    group="png",
                )
        for name, data in (getattr(detail, "files", None) or {}).items():
            if cases and name == "outputs.png":
                continue  # the pipeline draws every case's outputs (_case_plots)
            if name in RUN_FILES or "/" in name or name.startswith("."):
                self.notes.append(f"{name} from the kind not written: a reserved or unsafe name")
                continue
            self.artefact(name, lambda data=data: data)
        if len(result.front) > 1 and len(problem.objective_names) >= 2:
            self.artefact("front.png", lambda: self._front_png(result, title), group="png")
        if robust is not None:
            self.artefact(
                "robustness.png", lambda: robust.png(f"{study.name}: robustness"), group="png"
            )
        # the plots (every PNG is queued by now) start in their children at once: they need
        # only the detail, and this process makes the part's files below beside them (STL,
        # DXF, 3MF, VTU: ~0.2-0.3 s CPU that otherwise came before the children's start)
        self.start_groups()
        design = self._flat_part(detail, "design") if part is not None else None
        if part is not None and design is not None:  # STL on the bed, DXF and STEP as designed
            self.artefact("best.stl", lambda: self._stl(part))
            dxf = part if export_frame("dxf", sheet=part.sheet) == "bed" else design
            self.artefact("best.dxf", lambda: part_bytes(dxf, "dxf", f"{study.name}: best"))
            if early is not None and early.send(design):
                self._early = early
            elif step_available():  # the optional extra; without it no STEP and no note
                self.artefact("best.step", lambda: part_bytes(design, "step"), group="step")
            x_best = np.array(best.x, dtype=float)  # best_cad.py, best.3mf, print_sheet.md
            for name, make in handoff_files(
                study, problem, x_best, detail, part, design, run_dir=str(self.run_dir.resolve())
            ).items():
                self.artefact(name, make)
        elif detail is not None and (detail.outline is None or not detail.height_mm):
            self.notes.append(
                "best.stl and best.dxf skipped: the kind gives no outline and height_mm"
            )
        if detail is not None and has_mesh(detail):  # ParaView: best.vtu, best.pvd and its steps
            (self.run_dir / "best_steps").mkdir(exist_ok=True)
            for name, make in vtu_makers(detail, "best").items():
                self.artefact(name, make)
        # The plots (started above) and the STEP solid are made in forked children while this
        # process writes report.html: the report phase otherwise runs on one core with the
        # other idle. A "step" group (no early child) starts here.
        self.start_groups()
        if self._early is not None:
            self._started.append(self._early)
            self._early = None
        # every design to explore, offline (plotly.js inline); a failure is a note
        self.artefact("report.html", lambda: render_html(HtmlData(
            study.name, study.kind, problem, tuple(self.evaluator.solved), best,
            tuple(result.front), detail, self.verdicts, self.record,
            best_json.get("robustness"), durability)))  # fmt: skip
        self.collect_groups()
        return detail

    def _case_plots(
        self,
        cases: Mapping[str, Any],
        allowables: Mapping[str, tuple[float, str] | None],
        title: str,
    ) -> None:
        """force_displacement.png, stress.png and outputs.png of a kind with load cases: one
        column per case (the kind's own outputs.png is replaced by the pipeline's)."""
        from flexopt.pipeline import plots

        files = [("force_displacement.png", ("curve",)), ("stress.png", ("stress",))]
        if any(c.outputs for c in cases.values()):
            files.append(("outputs.png", ("outputs",)))
        for name, rows in files:
            self.artefact(
                name,
                lambda rows=rows: plots.plot_cases(cases, rows, allowables, title),
                group="png",
            )

    def robustness(self, best: Evaluation, detail: DesignDetail | None) -> Any:
        """The chosen design at every sample of the study's ``robustness:`` block, on the run's
        kind of backend (None without the block; a failure is a note, not the end)."""
        if getattr(self.setup.study, "robustness", None) is None:
            return None
        from flexopt.pipeline.robustness import run_robustness

        spec = {k: v for k, v in self.record["parallel"].items() if k != "description"}
        try:
            return run_robustness(
                self.setup.study,
                np.array(best.x, dtype=float),
                ParallelSettings(**spec),
                plot=detail.plot if detail is not None else None,
                history=(self.problem, best, tuple(self.evaluator.solved)),
            )
        except Exception as exc:
            note = f"robustness not evaluated: {_one_line(f'{type(exc).__name__}: {exc}')}"
            log.warning(note)
            log.info("robustness: traceback", exc_info=True)
            self.notes.append(note)
            return None

    def _front_png(self, result: GAResult, title: str) -> bytes:
        """First two objectives of every feasible evaluation, the front and the chosen one."""
        from flexopt.pipeline import plots

        feasible = [ev.f[:2] for ev in self.evaluator.solved if ev.feasible]
        names = self.problem.objective_names
        return plots.plot_front(
            np.array(feasible, dtype=float).reshape(-1, 2),
            np.array([ev.f[:2] for ev in result.front], dtype=float),
            (names[0], names[1]),
            best=np.asarray(result.best.f[:2], dtype=float),
            title=f"{title}: Pareto front",
        )

    def _flat_part(self, detail: DesignDetail | None, frame: str = "bed") -> FlatPart | None:
        """The best design's part laid flat or in the design ``frame`` (None, with a note, when
        it cannot be made)."""
        if detail is None or detail.outline is None or not detail.height_mm:
            return None
        try:
            return part_of(detail, frame)
        except Exception as exc:
            note = f"best.stl and best.dxf not written: {_one_line(f'{type(exc).__name__}: {exc}')}"
            log.warning(note)
            self.notes.append(note)
            return None

    def _stl(self, part: FlatPart) -> bytes:
        from flexopt.geometry.solid import extrude, stl_bytes

        mesh = extrude(part.outline, part.thickness_mm)
        lo, hi = mesh.bounds
        self.stl = {
            "volume_mm3": float(mesh.volume),
            "triangles": len(mesh.faces),
            "watertight": bool(mesh.is_watertight),
            "size_mm": [float(v) for v in hi - lo],
        }
        return stl_bytes(mesh)
