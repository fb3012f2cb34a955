"""``flexopt run`` and ``flexopt export``: optimise a study's design problem into a run folder.

A run is: validate the study, build the kind's :class:`~optimise.DesignProblem` once, create the
run folder, then let :func:`optimise.run_ga` ask for populations that an :class:`Evaluator`
answers. The evaluator is the one place designs are solved: it serves repeated designs from a cache
keyed by the design vector's bytes and hands the rest to a *backend* (``evaluate_batch``: serial, in
this process), which turns any exception of the kind into an infeasible Evaluation with a reason.
A process pool, Dask or a persisted cache replace the backend or the cache mapping; nothing else
changes.

Every file is written atomically; ``evaluations.csv``, ``history.csv`` and ``run.json`` are
rewritten after each generation, so a killed run leaves a consistent folder of what was done.
"""

from __future__ import annotations

import contextlib
import logging
import os
import platform
import signal
import socket
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable, Mapping, MutableMapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from datetime import datetime
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.ga import GAConfig, GAResult, Generation, best_of, pareto_front, run_ga
from flexopt.optimise.problem import DesignDetail, DesignProblem
from flexopt.optimise.requirements import Verdict, verdict_record
from flexopt.optimise.space import DesignSpace
from flexopt.pipeline import plots
from flexopt.pipeline.backends import open_backend
from flexopt.pipeline.checkpoint import (
    CHECKPOINT_FILE,
    STORE_FILE,
    EvaluationStore,
    checkpoint_text,
    study_sha256,
)
from flexopt.pipeline.errors import StudyError, Terminated
from flexopt.pipeline.evaluate import versions
from flexopt.pipeline.parallel import (
    BackendError,
    BatchBackend,
    ParallelSettings,
    design_key,
    evaluate_batch,
    evaluate_one,
)
from flexopt.pipeline.parallel import one_line as _one_line
from flexopt.pipeline.problems import (
    ExportError,
    build_base_problem,
    parallel_settings,
)
from flexopt.pipeline.problems import nominal_design as _nominal_design
from flexopt.pipeline.report import ReportData, render_report
from flexopt.pipeline.report_html import HtmlData, render_html
from flexopt.pipeline.responses import case_responses, stacked_table, stress_allowable
from flexopt.pipeline.runfolder import (
    RunDirLock,
    cell_float,
    check_out_dir,
    copy_inputs,
    echo,
    input_files,
    input_hashes,
    load_folder_study,
    lock_run_dir,
    make_run_dir,
    new_run_dir_path,
    probe_writable,
    read_folder_csv,
    read_folder_json,
    read_run_json,
    records_to_csv,
    study_sha256_with_inputs,
    table_to_csv,
    to_json,
    write_atomic,
)
from flexopt.pipeline.studies import get_kind
from flexopt.pipeline.study import OptimiserSpec, Study, load_study, study_to_yaml
from flexopt.pipeline.verdict import judge_detail

if TYPE_CHECKING:  # geometry.solid (manifold3d, trimesh) is imported when a part is made
    from flexopt.geometry.solid import FlatPart

__all__ = [
    "Evaluator",
    "ExportError",
    "ExportOutcome",
    "GenerationReport",
    "Resume",
    "RunOutcome",
    "RunSetup",
    "evaluate_batch",
    "evaluate_one",
    "export_design",
    "parallel_settings",
    "prepare_run",
    "rebuild_report",
    "resume_run",
    "run_study",
]

log = logging.getLogger(__name__)

#: Files a finished run folder can hold (plots, STL and the response only when the kind gives what
#: they need). run.json is written first and last: its ``status`` says whether the run finished.
RUN_FILES = (
    "study.yaml",
    "run.json",
    "evaluations.csv",
    "evaluations.jsonl",
    "checkpoint.json",
    "history.csv",
    "best.json",
    "best_response.csv",
    "force_displacement.png",
    "stress.png",
    "convergence.png",
    "shapes.png",
    "stress_map.png",
    "front.png",
    "best.stl",
    "best.dxf",
    "best.step",
    "report.md",
    "report.html",
)

#: The nice level of best.step's child while the workers solve: the lowest priority, so its
#: import of build123d takes only the CPU time the workers and this process leave idle.
EARLY_STEP_NICE = 19

_EXTRA_DISTRIBUTIONS = {
    "pymoo": "pymoo",
    "shapely": "shapely",
    "trimesh": "trimesh",
    "manifold3d": "manifold3d",
}


# --------------------------------------------------------------------------------------------
# Evaluating designs: one function, one cache


class Evaluator:
    """Evaluates batches of designs through a backend; a design is never solved twice.

    Parameters
    ----------
    problem : DesignProblem
    backend : BatchBackend
        How designs not in the cache are solved (default :func:`evaluate_batch`, serial).
    cache : mutable mapping of bytes to Evaluation, optional
        Evaluations by :func:`design_key`; give a persistent mapping to share it between runs.
    on_result : callable, optional
        Called once per design the backend finishes.
    store : EvaluationStore, optional
        Every design the backend finishes is appended here at once (fsynced by
        :meth:`_Run.generation_done` before the generation is reported, and by the store's
        own interval).
    restored : iterable of Evaluation, optional
        Evaluations finished by an earlier session of this run (``--resume``): served instead of
        solved, and counted as that session counted them, so the replayed run's tables are those
        of an uninterrupted run.

    Attributes
    ----------
    solved : list of Evaluation
        Every design evaluated for this run, restored ones included, in the order the optimiser
        first asked for them (whatever order the backend finished them in).
    n_cache_hits : int
        Designs served from the cache (repeats across generations and within a batch).
    n_restored : int
        Designs served from ``restored``.
    n_backend : int
        Designs the backend solved in this session.
    """

    def __init__(
        self,
        problem: DesignProblem,
        backend: BatchBackend = evaluate_batch,
        cache: MutableMapping[bytes, Evaluation] | None = None,
        on_result: Callable[[], None] | None = None,
        store: EvaluationStore | None = None,
        restored: Iterable[Evaluation] = (),
    ) -> None:
        self.problem = problem
        self.backend = backend
        self.cache: MutableMapping[bytes, Evaluation] = {} if cache is None else cache
        self.on_result = on_result
        self.store = store
        self.restored = {design_key(ev.x): ev for ev in restored}
        self.solved: list[Evaluation] = []
        self.n_cache_hits = 0
        self.n_restored = 0
        self.n_backend = 0

    def map(self, X: np.ndarray) -> list[Evaluation]:
        """Evaluate (m, n_var) designs; returns m Evaluations in order."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        keys = [design_key(x) for x in X]
        new: dict[bytes, int] = {}  # first appearance in this batch -> its row
        for row, key in enumerate(keys):
            if key not in self.cache and key not in new:
                new[key] = row
        self.n_cache_hits += len(keys) - len(new)
        todo = [key for key in new if key not in self.restored]
        for key in new:
            if key in self.restored:
                self.cache[key] = self.restored.pop(key)
                self.n_restored += 1
        finished: dict[bytes, Evaluation] = {}

        def keep(row: int, evaluation: Evaluation) -> None:
            key = todo[row]
            if key not in finished:  # a backend may report and also return it
                finished[key] = evaluation
                self.cache[key] = evaluation
                self.n_backend += 1
                if self.store is not None:
                    self.store.append(evaluation)
                if self.on_result is not None:
                    self.on_result()

        try:
            if todo:
                rows = [new[key] for key in todo]
                results = self.backend(self.problem, X[rows], on_result=keep)
                if len(results) != len(todo):
                    raise RuntimeError(f"backend: {len(results)} results for {len(todo)} designs")
                for row, evaluation in enumerate(results):
                    keep(row, evaluation)
        finally:
            # In the order asked, not the order finished: the same tables on every backend. An
            # interrupted batch keeps what did finish.
            self.solved.extend(self.cache[key] for key in new if key in self.cache)
        return [self.cache[key] for key in keys]

    __call__ = map  # run_ga calls the evaluator like a function


# --------------------------------------------------------------------------------------------
# Setting a run up (everything that can refuse the inputs, before any file is written)


@dataclass(frozen=True)
class RunSetup:
    """A validated run, ready to go.

    Attributes
    ----------
    study : the study as it will run (``optimiser.seed`` replaced by ``--seed``).
    problem : the kind's design problem, built once.
    config : GA settings (``--quick`` applied).
    quick : whether ``--quick`` was given.
    initial : (k, n_var) designs seeded into the first population, from the problem's optional
        ``initial_designs()`` (e.g. a published optimum), or None.
    """

    study: Study
    problem: DesignProblem
    config: GAConfig
    quick: bool
    initial: np.ndarray | None = None


def build_problem(study: Study) -> DesignProblem:
    """The kind's design problem for ``study``, as ``flexopt run`` optimises it: the kind's own
    problem with the study's ``role: constraint`` requirements as g rows
    (:func:`pipeline.problems.build_base_problem`), scored by its worst scatter sample when
    ``robustness.objective`` is ``worst``.

    Raises
    ------
    StudyError
        When the kind cannot be optimised, or refuses the study while building the problem.
    """
    from flexopt.pipeline.robustness import with_worst_case

    return with_worst_case(study, build_base_problem(study))


def prepare_run(study: Study, quick: bool = False, seed: int | None = None) -> RunSetup:
    """Check the optimiser settings and build the design problem once.

    Parameters
    ----------
    study : Study
        A validated study whose kind has a ``problem``.
    quick : bool
        Use ``optimiser.quick_pop_size`` and ``optimiser.quick_n_gen``.
    seed : int, optional
        Replaces ``optimiser.seed`` (also in the resolved study.yaml).

    Raises
    ------
    StudyError
        Naming the key path, for anything that would stop the run before it starts.
    """
    spec = getattr(study, "optimiser", None)
    if spec is None:
        spec = OptimiserSpec()
    if seed is not None:
        spec = spec.model_copy(update={"seed": int(seed)})
        if hasattr(study, "optimiser"):
            study = study.model_copy(update={"optimiser": spec})
    problem = build_problem(study)
    n_obj = len(problem.objective_names)
    if spec.algorithm == "ga" and n_obj != 1:
        raise StudyError(
            "optimiser.algorithm",
            f"'ga' optimises one objective but kind '{study.kind}' has {n_obj} "
            f"({', '.join(problem.objective_names)}); set algorithm: nsga2",
        )
    pop_size, n_gen = (
        (spec.quick_pop_size, spec.quick_n_gen) if quick else (spec.pop_size, spec.n_gen)
    )
    try:
        config = GAConfig(spec.algorithm, pop_size, n_gen, spec.seed)
    except OptimiseError as exc:
        raise StudyError("optimiser", str(exc)) from None
    return RunSetup(study, problem, config, quick, initial_designs(problem))


def initial_designs(problem: DesignProblem) -> np.ndarray | None:
    """The designs a problem asks to seed the first population with (its
    :meth:`~optimise.problem.DesignProblem.initial_designs`), as (k, n_var), or None."""
    initial = problem.initial_designs()
    if initial is None:
        return None
    initial = np.atleast_2d(np.asarray(initial, dtype=float))
    if initial.ndim != 2 or initial.shape[1] != problem.space.n_var or not len(initial):
        raise TypeError(
            f"initial_designs() returned shape {initial.shape}; expected (k, {problem.space.n_var})"
        )
    return initial


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


@dataclass(frozen=True)
class RunOutcome:
    """Where a run went and what it found."""

    run_dir: Path
    result: GAResult
    detail: DesignDetail | None
    record: dict[str, Any]
    notes: tuple[str, ...] = ()
    verdicts: tuple[Verdict, ...] = ()  # the best design against the study's requirements


@dataclass
class _Columns:
    """CSV column names of the variables, objectives, constraints and metrics, made unique."""

    variables: tuple[str, ...] = ()
    objectives: tuple[str, ...] = ()
    constraints: tuple[str, ...] = ()
    metric_names: dict[str, str] = field(default_factory=dict)
    used: set[str] = field(
        default_factory=lambda: {"generation", "index", "feasible", "reason", "time_s"}
    )

    def _unique(self, name: str, prefix: str) -> str:
        column = name if name not in self.used else f"{prefix}_{name}"
        while column in self.used:
            column = f"{prefix}_{column}"
        self.used.add(column)
        return column

    @classmethod
    def of(cls, problem: DesignProblem) -> _Columns:
        columns = cls()
        columns.variables = tuple(columns._unique(n, "x") for n in problem.space.names)
        columns.objectives = tuple(columns._unique(n, "objective") for n in problem.objective_names)
        columns.constraints = tuple(
            columns._unique(n, "constraint") for n in problem.constraint_names
        )
        return columns

    @classmethod
    def of_space(cls, space: DesignSpace) -> _Columns:
        """The variables' columns alone (as :meth:`of` names them: they come first)."""
        columns = cls()
        columns.variables = tuple(columns._unique(n, "x") for n in space.names)
        return columns

    def metric(self, key: str) -> str:
        if key not in self.metric_names:
            self.metric_names[key] = self._unique(key, "metric")
        return self.metric_names[key]

    def row(self, generation: int, index: int, ev: Evaluation) -> dict[str, Any]:
        row: dict[str, Any] = {"generation": generation, "index": index}
        row.update(zip(self.variables, map(float, ev.x), strict=True))
        row.update(zip(self.objectives, map(float, ev.f), strict=True))
        row.update(zip(self.constraints, map(float, ev.g), strict=True))
        row["feasible"] = ev.feasible
        for key, value in ev.metrics.items():
            row[self.metric(str(key))] = value
        row["reason"] = ev.reason
        row["time_s"] = float(ev.time_s)
        return row

    def header(self) -> list[str]:
        return [
            "generation",
            "index",
            *self.variables,
            *self.objectives,
            *self.constraints,
            "feasible",
            *self.metric_names.values(),
            "reason",
            "time_s",
        ]


def all_versions() -> dict[str, str | None]:
    """Versions of Python, flexopt, the numerical stack and the optimiser/solid libraries."""
    found = versions()
    for key, dist in _EXTRA_DISTRIBUTIONS.items():
        try:
            found[key] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            found[key] = None
    return found


def _now() -> datetime:
    return datetime.now().astimezone()


def _stamp(moment: datetime) -> str:
    return moment.isoformat(timespec="seconds")


class _Run:
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
        self.columns = _Columns.of(setup.problem)
        self.evaluator = Evaluator(
            setup.problem, backend, on_result=on_result, store=store, restored=restored
        )
        self.n_backend_last = 0
        self.rows: list[dict[str, Any]] = []
        self.where: dict[bytes, tuple[int, int]] = {}  # design -> (generation, index) solved
        self.history: list[dict[str, Any]] = []
        self.generations: list[Generation] = []
        self.t0 = time.perf_counter()
        self.t_last = self.t0
        self.notes: list[str] = []
        self.files: list[str] = []
        self.stl: dict[str, Any] = {}
        # evaluations.csv: the header its rows were formatted with, their text, how many
        # the writer thread of the per-generation files (see generation_done)
        self._writer: ThreadPoolExecutor | None = None
        self._pending: Future | None = None
        # files made in forked children at the end of the run (see artefact)
        self._groups: dict[str, list[tuple[str, Callable[[], str | bytes | None]]]] = {}
        self._started: list[_ForkedMakes | _EarlyStep] = []
        self._early: _EarlyStep | None = None  # best.step's child, once it has the part
        self._csv_header: list[str] | None = None
        self._csv_body: list[str] = []
        self._csv_rows = 0

    # -- bookkeeping ------------------------------------------------------------------------

    def _collect(self, generation: int) -> int:
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
        self._collect(number)
        # solved now, not served from the store of an earlier session: the rate a user can plan by
        n_new = self.evaluator.n_backend - self.n_backend_last
        self.n_backend_last = self.evaluator.n_backend
        gen_wall = now - self.t_last
        self.t_last = now
        self.generations.append(gen)
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
        )
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
            "generation %d/%d: %d evaluations, best %s, %.0f%% feasible, %.3g eval/s",
            number,
            report.n_gen,
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
        self._pending = self._writer.submit(_write_files, self.run_dir, files)

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

    def write_tables(self) -> None:
        """evaluations.csv and history.csv now, after anything the writer thread still holds."""
        self.drain_writes()
        _write_files(self.run_dir, self.table_texts())

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
        write_atomic(self.run_dir / name, data)
        self.files.append(name)

    def start_groups(self) -> None:
        """Make each queued group of files in a child process (see :class:`_ForkedMakes`)."""
        self._started = [_ForkedMakes(items) for items in self._groups.values()]
        self._groups = {}

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

    def finish(self, result: GAResult, early: _EarlyStep | None = None) -> DesignDetail | None:
        # best.step's child: the one the run started (``early``, it imported build123d at low
        # priority while the workers solved), else forked now: it imports build123d (~3 s)
        # while the best design's detail is solved, once a core is idle (see _EarlyStep)
        if early is None and step_available():
            early = _EarlyStep.start()
        try:
            return self._finish(result, early)
        finally:
            if early is not None:
                early.close()

    def _finish(self, result: GAResult, early: _EarlyStep | None) -> DesignDetail | None:
        study, problem = self.setup.study, self.problem
        best = result.best
        title = f"{study.name}: best design"
        best_json = self.best_record(best)
        detail: DesignDetail | None = None
        try:
            detail = problem.detail(np.array(best.x, dtype=float))
        except Exception as exc:
            note = f"the best design's detail failed: {_one_line(f'{type(exc).__name__}: {exc}')}"
            log.warning(note)  # the CLI prints the notes; the traceback only with -v
            log.info("the best design's detail: traceback", exc_info=True)
            self.notes.append(note + " (no response, plots of it, STL)")
        self.verdicts = self.judge(best, detail)
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
        robust = self.robustness(best, detail)
        if robust is not None:  # the chosen design under the study's scatter (docs/robustness.md)
            best_json["robustness"] = robust.record()
            self.record["robustness"] = {
                k: v for k, v in best_json["robustness"].items() if k not in ("samples", "band")
            }
        if detail is not None and detail.info:
            best_json["info"] = detail.info
        if len(result.front) > 1:
            best_json["front"] = [self.best_record(ev) for ev in result.front]
        write_atomic(self.run_dir / "best.json", to_json(best_json))
        self.files.append("best.json")

        table = dict(detail.table) if detail is not None else {}
        spec = dict(detail.plot) if detail is not None else {}
        x = spec.get("x", "displacement_mm")
        y = spec.get("y", "force_N")
        stress = spec.get("stress", "peak_stress_MPa")
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
            case: stress_allowable(self.verdicts, case, _float_or_none(c.plot.get("allowable_MPa")))
            for case, c in case_responses(table, spec, cases).items()
        }
        if cases:  # several load cases: one panel each, every output on the axis of its unit
            self._case_plots(cases, allowables, title)
        elif x in table and y in table:
            self.artefact(
                "force_displacement.png", lambda: _curve_png(table, spec, title), group="png"
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
                    x_label=_spec_label(spec, "x"),
                    title=title,
                    allowable_label=line[1] if line else None,
                ),
                group="png",
            )
        elif table and not cases:
            self.notes.append(f"stress.png skipped: the response has no '{stress}' column")
        self.artefact(
            "convergence.png", lambda: _convergence_png(self.history, self.columns), group="png"
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
                    limit=_float_or_none(fmap.get("limit")),
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
        design = self._flat_part(detail, "design") if part is not None else None
        if part is not None and design is not None:  # STL on the bed, DXF and STEP as designed
            self.artefact("best.stl", lambda: self._stl(part))
            dxf = part if export_frame("dxf", sheet=part.sheet) == "bed" else design
            self.artefact("best.dxf", lambda: part_bytes(dxf, "dxf", f"{study.name}: best"))
            if early is not None and early.send(design):
                self._early = early
            elif step_available():  # the optional extra; without it no STEP and no note
                self.artefact("best.step", lambda: part_bytes(design, "step"), group="step")
        elif detail is not None and (detail.outline is None or not detail.height_mm):
            self.notes.append(
                "best.stl and best.dxf skipped: the kind gives no outline and height_mm"
            )
        # The plots and the STEP solid are made in forked children while this process writes
        # report.html: the report phase otherwise runs on one core with the other idle.
        self.start_groups()
        if self._early is not None:
            self._started.append(self._early)
            self._early = None
        # every design to explore, offline (plotly.js inline); a failure is a note
        self.artefact("report.html", lambda: render_html(HtmlData(
            study.name, study.kind, problem, tuple(self.evaluator.solved), best,
            tuple(result.front), detail, self.verdicts, self.record,
            best_json.get("robustness"))))  # fmt: skip
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
            )
        except Exception as exc:
            note = f"robustness not evaluated: {_one_line(f'{type(exc).__name__}: {exc}')}"
            log.warning(note)
            log.info("robustness: traceback", exc_info=True)
            self.notes.append(note)
            return None

    def _front_png(self, result: GAResult, title: str) -> bytes:
        """First two objectives of every feasible evaluation, the front and the chosen one."""
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


def _spec_label(spec: Mapping[str, Any], axis: str) -> str | None:
    """Axis label of a DesignDetail.plot: ``x_label`` or ``xlabel`` (both are in use)."""
    return spec.get(f"{axis}_label") or spec.get(f"{axis}label")


def _float_or_none(value: Any) -> float | None:
    return None if value is None else float(value)


def _curve_png(table: Mapping[str, np.ndarray], spec: Mapping[str, Any], title: str) -> bytes:
    target = _float_or_none(spec.get("target"))
    tolerance = _float_or_none(spec.get("tolerance"))
    if tolerance is None and target is not None and spec.get("tolerance_rel") is not None:
        tolerance = abs(target) * float(spec["tolerance_rel"])
    band = spec.get("band_x")
    return plots.plot_curve(
        table,
        spec.get("x", "displacement_mm"),
        spec.get("y", "force_N"),
        target=target,
        tolerance=tolerance,
        band_x=(float(band[0]), float(band[1])) if band is not None else None,
        x_label=_spec_label(spec, "x"),
        y_label=_spec_label(spec, "y"),
        title=title,
        spec=spec,  # a target curve or range of the kind (pipeline.plot_targets)
    )


def _convergence_png(history: list[dict[str, Any]], columns: _Columns) -> bytes:
    from flexopt.pipeline.labels import MAXIMISED

    best = np.array([[h[f"best_{name}"] for name in columns.objectives] for h in history])
    # a maximised objective drawn as the study states it: X rising, not its negative falling
    sign = np.array([-1.0 if n.startswith(MAXIMISED) else 1.0 for n in columns.objectives])
    names = tuple(n.removeprefix(MAXIMISED) for n in columns.objectives)  # "best": the largest
    return plots.plot_convergence(
        np.array([h["generation"] for h in history]),
        best.reshape(len(history), len(names)) * sign,
        np.array([h["best_feasible"] for h in history]),
        np.array([h["feasible_fraction"] for h in history]),
        names,
    )


@dataclass(frozen=True)
class Resume:
    """What ``--resume`` carries into :func:`run_study`: the run's record and its store.

    Attributes
    ----------
    record : run.json of the interrupted run.
    restored : every evaluation its store (evaluations.jsonl) holds.
    """

    record: dict[str, Any]
    restored: tuple[Evaluation, ...]


def run_study(
    setup: RunSetup,
    out: Path | None = None,
    source: str = "",
    command_line: str = "",
    runs_root: Path = Path("runs"),
    on_start: Callable[[Path, GAConfig], None] | None = None,
    on_generation: Callable[[GenerationReport], None] | None = None,
    on_result: Callable[[], None] | None = None,
    parallel: ParallelSettings | None = None,
    resume: Resume | None = None,
    lock: RunDirLock | None = None,
) -> RunOutcome:
    """Optimise a prepared study and write its run folder.

    Parameters
    ----------
    setup : RunSetup
        From :func:`prepare_run` (which refuses bad inputs before anything is written).
    out : Path, optional
        Run folder; default ``runs_root/<name>-run-<timestamp>``. A folder that already holds
        a run (run.json) is refused, unless resuming it.
    source : str
        Where the study came from, recorded in run.json.
    command_line : str
        The command as typed, recorded in run.json.
    on_start : callable(run_dir, config), optional
        Called once the folder exists, before the first design is solved.
    on_generation : callable(GenerationReport), optional
        Called after each generation.
    on_result : callable(), optional
        Called after each solved design (progress within a generation).
    parallel : ParallelSettings, optional
        Where designs are evaluated (default: :func:`parallel_settings` of the study, a local
        process pool unless the study says otherwise).
    resume : Resume, optional
        Continue the run in ``out`` (see :func:`resume_run`, which checks it may be).
    lock : RunDirLock, optional
        The lock of ``out``, already held (``--resume`` takes it before it reads the folder);
        otherwise the folder's lock is taken here, before the folder is checked or written. It
        is released when the run ends (a killed process's lock is released by the kernel).

    Returns
    -------
    RunOutcome

    Raises
    ------
    StudyError
        When ``out`` cannot be a new run folder (it holds a run, or another flexopt process
        holds its lock), or the workers or the cluster cannot take the problem (at
        ``--workers`` / ``--dask``); nothing is written.
    BackendError
        When worker processes die before they can load the problem (mid-run).
    OSError
        When the run folder cannot be written; a folder that is read-only or full is found by a
        probe before anything else is done.
    KeyboardInterrupt
        After writing run.json with status ``interrupted`` (and every evaluation so far).
    """
    if out is not None:
        check_out_dir(out)
        if resume is None:
            _refuse_a_run_in(out)  # at once, before workers start (again under the lock below)
    if resume is not None and (out is None or lock is None):
        raise ValueError("resume needs the run folder as out, and its lock")
    study = setup.study
    settings = parallel or parallel_settings(study)
    started = _now()
    run_dir = out or new_run_dir_path(runs_root, study.name, "run", started)
    probe_writable(run_dir)  # a read-only or full disk now, not after hours of solving
    stack = contextlib.ExitStack()
    if lock is not None:
        stack.callback(lock.release)
    try:
        backend = stack.enter_context(open_backend(settings, setup.problem))
    except BackendError as exc:
        stack.close()
        where = "--dask" if settings.backend == "dask" else "--workers"
        raise StudyError(where, str(exc)) from None
    except BaseException:
        stack.close()
        raise
    with stack:
        run_dir = make_run_dir(run_dir)
        if lock is None:
            # Released first when the run ends (a callback after the backend's exit runs first).
            lock = stack.enter_context(_lock_new_run_dir(run_dir))
        lock.claim("run")
        return _run_in(
            setup,
            run_dir,
            settings,
            backend,
            started,
            source,
            command_line,
            on_start,
            on_generation,
            on_result,
            resume,
        )


def _refuse_a_run_in(out: Path) -> None:
    """Refuse an ``--out`` that already holds a run (its run.json)."""
    if (out / "run.json").exists():
        raise StudyError(
            "--out", f"'{out}' already holds a run (run.json); give a new folder or remove it"
        )


def _lock_new_run_dir(run_dir: Path) -> RunDirLock:
    """Lock the folder of a new run, then check (under the lock) that it holds no run yet."""
    lock = lock_run_dir(run_dir, "--out", "wait for it or give another folder with --out")
    try:
        _refuse_a_run_in(run_dir)
    except BaseException:
        lock.release()
        raise
    return lock


def _run_in(
    setup: RunSetup,
    run_dir: Path,
    settings: ParallelSettings,
    backend: BatchBackend,
    started: datetime,
    source: str,
    command_line: str,
    on_start: Callable[[Path, GAConfig], None] | None,
    on_generation: Callable[[GenerationReport], None] | None,
    on_result: Callable[[], None] | None,
    resume: Resume | None,
) -> RunOutcome:
    """The body of :func:`run_study` once the folder can be written and the backend is up."""
    study, config = setup.study, setup.config
    session = {
        "status": "running",
        "error": "",
        "finished": None,
        "pid": os.getpid(),
        "hostname": socket.gethostname(),
        "parallel": {**asdict(settings), "description": settings.describe()},
        "versions": all_versions(),
        "host": {"platform": platform.platform(), "cpu_count": os.cpu_count()},
    }
    if resume is not None:
        record = dict(resume.record)
        record.update(session)
        record["resumed"] = [
            *record.get("resumed", []),
            {
                "at": _stamp(started),
                "command_line": command_line,
                "n_in_store": len(resume.restored),
            },
        ]
    else:
        record = {
            "study": study.name,
            "kind": study.kind,
            "command": "run",
            "command_line": command_line,
            "source": source,
            **session,
            "quick": setup.quick,
            "seed": config.seed,
            "study_sha256": study_sha256_with_inputs(study, study_sha256(study)),
            "optimiser": {
                "algorithm": config.algorithm,
                "pop_size": config.pop_size,
                "n_gen": config.n_gen,
                "seed": config.seed,
            },
            "objectives": list(setup.problem.objective_names),
            "constraints": list(setup.problem.constraint_names),
            "variables": list(setup.problem.space.names),
            "started": _stamp(started),
            "generations_done": 0,
            "n_evaluations": 0,
            "n_cache_hits": 0,
            "n_restored": 0,
            "n_solved": 0,
            "wall_s": None,
            "optimise_wall_s": None,
            "evaluations_per_s": None,
        }
        rerun = f"flexopt run {run_dir / 'study.yaml'}" + (" --quick" if setup.quick else "")
        header = (
            f"Resolved study written by flexopt run on {record['started']}\n"
            f"from {source or 'memory'}; re-run with: {rerun}"
        )
        # the target tables the study reads, copied: the folder stands alone (report, export,
        # resume from anywhere), and a resume checks their bytes against the run's
        folder_study, inputs = copy_inputs(study, run_dir)
        if inputs:
            record["input_files"] = inputs
        write_atomic(run_dir / "study.yaml", study_to_yaml(folder_study, header))
    write_atomic(run_dir / "run.json", to_json(record))
    log.info("run folder %s; %s; %s", run_dir, config, settings.describe())
    # best.step's child now, while this process runs no other thread (forked later, a thread
    # could hold a lock the child needs): it imports build123d (~3 s CPU) at the lowest
    # priority, in the moments a core idles while the workers solve (generation barriers),
    # instead of on the report's critical path.
    early = (
        _EarlyStep.start(nice=EARLY_STEP_NICE)
        if threading.active_count() == 1 and step_available() and _can_restore_priority()
        else None
    )
    if on_start is not None:
        on_start(run_dir, config)

    store = EvaluationStore(run_dir / STORE_FILE)
    restored = resume.restored if resume is not None else ()
    run = _Run(setup, run_dir, record, on_generation, on_result, backend, store, restored)
    t_start = time.perf_counter()
    preload = _preload_report(setup.problem, settings)

    def close(status: str, error: str = "", write: bool = True) -> None:
        wall = time.perf_counter() - t_start
        solved = run.evaluator.solved
        n = len(solved)
        n_now = run.evaluator.n_backend
        # a run that stopped mid-generation solved its last designs after optimise_wall_s
        optimise_wall = (record.get("optimise_wall_s") or wall) if status == "finished" else wall
        failed = [ev for ev in solved if ev.reason]
        now_times = [ev.time_s for ev in solved[-n_now:]] if n_now else []
        record.update(
            status=status,
            error=error,
            finished=_stamp(_now()),
            wall_s=wall,
            n_evaluations=n,
            n_cache_hits=run.evaluator.n_cache_hits,
            n_restored=run.evaluator.n_restored,
            n_solved=n_now,
            n_failed=len(failed),
            n_feasible=sum(ev.feasible for ev in solved),
            evaluations_per_s=n_now / optimise_wall if optimise_wall > 0 and n_now else None,
            mean_evaluation_s=float(np.mean([ev.time_s for ev in solved])) if n else None,
            # the share of the wall time the workers spent solving (1 - overhead - idle)
            worker_utilisation=(
                sum(now_times) / (optimise_wall * _n_workers(settings))
                if now_times and optimise_wall > 0
                else None
            ),
            failure_reasons=dict(Counter(ev.reason for ev in failed).most_common(10)),
            notes=run.notes,
            files=sorted(
                set(run.files)
                | {"study.yaml", "run.json", "evaluations.csv", STORE_FILE}
                | ({CHECKPOINT_FILE} if run.generations else set())
            ),
        )
        if write:
            write_atomic(run_dir / "run.json", to_json(record))

    def abandon(status: str, error: str) -> None:
        # Keep what was done; a folder that cannot be written any more must not hide the cause.
        with contextlib.suppress(OSError):
            run._collect(len(run.generations) + 1)  # the unfinished generation's designs
            run.write_tables()
            close(status, error)

    optimised = False
    try:
        try:
            result = run_ga(
                setup.problem.space,
                run.evaluator,
                len(setup.problem.objective_names),
                len(setup.problem.constraint_names),
                config,
                on_generation=run.generation_done,
                initial=setup.initial,
            )
            optimised = True
        finally:
            try:
                store.close()
            finally:  # every generation's files on disk before anything else is written
                run.finish_writes(raise_errors=optimised)
        record["optimise_wall_s"] = time.perf_counter() - t_start
        run.files += ["evaluations.csv", "history.csv"]
        if preload is not None:
            preload.join()
        early, handed = None, early
        detail = run.finish(result, handed)
        run.files.append("report.md")
        close("finished", write=False)  # the numbers the report shows
        report = ReportData(
            record=record,
            study=study,
            problem=setup.problem,
            best=result.best,
            best_where=run.where.get(design_key(result.best.x), (None, None)),
            front=result.front,
            detail=detail,
            files=tuple(run.files),
            notes=tuple(run.notes),
            stl=run.stl,
            verdicts=run.verdicts,
        )
        write_atomic(run_dir / "report.md", render_report(report))
        close("finished")
    except Terminated:
        abandon("stopped", "stopped by SIGTERM")
        raise
    except KeyboardInterrupt:
        abandon("interrupted", "interrupted by the user (Ctrl-C)")
        raise
    except BaseException as exc:
        abandon("failed", _one_line(f"{type(exc).__name__}: {exc}"))
        raise
    finally:
        if early is not None:  # the run ended before its report: the child has nothing to make
            early.close()
    log.info("finished %s in %.3g s", run_dir, record["wall_s"])
    return RunOutcome(run_dir, result, detail, record, tuple(run.notes), run.verdicts)


def _preload_report(problem: DesignProblem, settings: ParallelSettings) -> Any:
    """Import and load what the report will need, in a thread, while the workers solve.

    The report runs in this process after the optimisation, on the run's critical path; what it
    first has to import and load (matplotlib for the plots, and the problem's
    ``warm_up_detail``: e.g. the constant-force study's plane-stress kernels, ~1.5 s from numba's
    cache) is loaded here instead, while this process mostly waits for its workers. Only with
    worker processes: a serial run solves in this process, where the thread would compete. A
    failure is only logged: the report then loads what it needs itself. Returns the thread or
    None.
    """
    if settings.backend == "serial":
        return None
    warm = problem.warm_up_detail

    def load() -> None:
        try:
            import matplotlib.backends.backend_agg  # noqa: F401  (the plots' first import)
            import matplotlib.figure  # noqa: F401

            warm()
            # the part's STL (trimesh, ~0.5 s) and DXF (ezdxf). Not build123d for best.step
            # (~2.6 s): the STEP file is made in a forked child that imports it and exits
            # without the ~1 s of interpreter teardown OpenCascade adds to a process.
            import flexopt.geometry.dxf  # noqa: F401
            import flexopt.geometry.solid  # noqa: F401
        except Exception as exc:  # the report loads it again, and says what fails
            log.info("preloading the report failed: %s", _one_line(f"{type(exc).__name__}: {exc}"))

    thread = threading.Thread(target=load, name="flexopt-preload", daemon=True)
    thread.start()
    return thread


class _ForkedMakes:
    """Make some result files in a forked child process while this one goes on.

    ``items`` are (name, make) pairs; the child runs each ``make`` in order and sends back
    (name, data, None) or (name, None, error text). Forking shares everything already imported
    and computed (matplotlib, the detail), so nothing is pickled on the way in. Where fork is not
    available (Windows, macOS) or the child cannot start, the files are made here, in order. A
    child that dies without an answer (a crash in a native library) gives each of its files a
    note instead of bringing the run down with it.
    """

    def __init__(self, items: list[tuple[str, Callable[[], str | bytes | None]]]) -> None:
        self.items = items
        self.conn: Any = None
        self.process: Any = None
        ctx = _fork_context()
        if ctx is None:
            return
        try:
            receive, send = ctx.Pipe(duplex=False)
            self.process = ctx.Process(
                target=_make_in_child,
                args=(send, items, receive),
                name="flexopt-report",
                daemon=True,
            )
            self.process.start()
            send.close()
            self.conn = receive
        except Exception as exc:  # no fork here: make them in this process
            log.info("report files made in this process: %s", _one_line(str(exc)))
            self.conn = self.process = None

    def results(self) -> list[tuple[str, str | bytes | None, str | None]]:
        if self.conn is None:
            return _make_here(self.items)
        try:
            return self.conn.recv()
        except (EOFError, OSError):
            self.process.join(5)
            code = self.process.exitcode
            how = f"signal {-code}" if code is not None and code < 0 else f"exit code {code}"
            return [(name, None, f"the process making it died ({how})") for name, _ in self.items]
        finally:
            self.conn.close()
            self.process.join(5)


class _EarlyStep:
    """best.step made in a child forked before the part is known: when the run starts, at the
    lowest priority (:data:`EARLY_STEP_NICE`), or else when the report starts.

    The STEP writer's import (build123d and OpenCascade, ~3 s) needs nothing of the run, so the
    child does it while the best design's detail is solved, but only once a core is idle
    (:func:`_wait_for_idle_core`): the SEA spring's 3D checks keep one core busy and its peak
    convergence the other for their first ~10 s, and an import beside them would slow the
    checks. When the part arrives (:meth:`send`) the child imports at once if it has not yet,
    makes the file and sends it back (:meth:`results`, as :class:`_ForkedMakes`). Where fork is
    not available or the child cannot start, :meth:`start` gives None and the file is made as
    before (a "step" group).
    """

    items = (("best.step", None),)  # what it makes, for a dead child's notes

    def __init__(self, conn: Any, process: Any) -> None:
        self.conn, self.process = conn, process
        self._sent = False

    @classmethod
    def start(cls, nice: int = 0) -> _EarlyStep | None:
        """Fork the child; with ``nice`` > 0 it runs at that lower priority and imports at once
        (it only takes CPU time no other process wants)."""
        ctx = _fork_context()
        if ctx is None:
            return None
        try:
            ours, theirs = ctx.Pipe(duplex=True)
            process = ctx.Process(
                target=_early_step_main,
                args=(theirs, nice, ours),
                name="flexopt-step",
                daemon=True,
            )
            process.start()
            theirs.close()
        except Exception as exc:
            log.info("best.step made later: %s", _one_line(str(exc)))
            return None
        return cls(ours, process)

    def send(self, part: FlatPart) -> bool:
        """Hand the child the part; False when it is gone (then make the file another way)."""
        try:
            self.conn.send(part)
        except (OSError, ValueError, EOFError):
            return False
        self._sent = True
        return True

    def results(self) -> list[tuple[str, str | bytes | None, str | None]]:
        try:
            return self.conn.recv()
        except (EOFError, OSError):
            self.process.join(5)
            code = self.process.exitcode
            how = f"signal {-code}" if code is not None and code < 0 else f"exit code {code}"
            return [("best.step", None, f"the process making it died ({how})")]

    def close(self) -> None:
        """End the child: told there is no part when it has none, else its answer was read."""
        if not self._sent:
            with contextlib.suppress(OSError, ValueError):
                self.conn.send(None)
        self.conn.close()
        self.process.join(5)
        if self.process.is_alive():  # stuck in OpenCascade: a file is not worth a hung run
            self.process.kill()
            self.process.join(5)


def _can_restore_priority(nice: int = EARLY_STEP_NICE) -> bool:
    """Whether a child lowered by ``nice`` (and put on SCHED_IDLE) may come back to this
    process's priority: root, or an RLIMIT_NICE that allows it (Linux's rule for leaving
    SCHED_IDLE is the same). An ordinary user's limit is 0: a child there would build best.step
    at the lowest priority, starved while the report's processes keep the cores busy, so the
    run then starts the child when the report starts instead (the path before issue 13's
    early child)."""
    try:
        if os.geteuid() == 0:
            return True
        import resource

        limit = resource.getrlimit(resource.RLIMIT_NICE)[0]
        here = os.getpriority(os.PRIO_PROCESS, 0)
    except (AttributeError, OSError, ValueError, ImportError):
        return False
    # RLIMIT_NICE r lets a process lower its nice value down to 20 - r
    return limit == resource.RLIM_INFINITY or 20 - limit <= here


def _early_step_main(conn: Any, nice: int = 0, ours: Any = None) -> None:
    """:class:`_EarlyStep`'s child: import the STEP writer when a core is idle (at once when
    ``nice`` > 0: at that priority it only gets idle CPU time), then make the part it is sent
    (None: nothing to make)."""
    # Ctrl-C reaches the whole process group and a forked child inherits the CLI's SIGTERM
    # handler: the run decides what stops, and closes this child (as a pool worker).
    _quiet_child()
    if ours is not None:  # the parent's end, inherited: closed, so a parent that dies is an
        ours.close()  # end of file here instead of a child waiting for a part forever
    try:
        priority = None
        if nice > 0:
            with contextlib.suppress(OSError, AttributeError):
                priority = os.getpriority(os.PRIO_PROCESS, 0)
                os.nice(nice)
                # Linux: SCHED_IDLE runs only when no other task wants the core (a worker that
                # wakes takes it back at once); the nice level alone still slowed the workers
                os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
        else:
            _wait_for_idle_core(conn.poll)
        # the parent may already be gone (or have no part): read that before a long import
        early = conn.recv() if conn.poll(0) else ...
        if early is None:
            return
        with contextlib.suppress(Exception):  # step_bytes says what fails, as a note
            import build123d  # noqa: F401
        part = conn.recv() if early is ... else early
        if priority is not None:  # the report waits for the part now: back to the run's
            # priority where the system allows it (root, RLIMIT_NICE); else it stays low
            with contextlib.suppress(OSError, AttributeError):
                os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
                os.setpriority(os.PRIO_PROCESS, 0, priority)
        if part is not None:
            conn.send(_make_here([("best.step", lambda: part_bytes(part, "step"))]))
    except BaseException:  # noqa: BLE001 - the parent is gone or closed the pipe, or stopped:
        pass  # it says why in one line; this child ends quietly
    finally:
        with contextlib.suppress(Exception):
            conn.close()


def _wait_for_idle_core(ready: Callable[[float], bool], period_s: float = 0.2,
                        idle_cores: float = 0.6, limit_s: float = 600.0) -> None:  # fmt: skip
    """Return once the machine has ``idle_cores`` of idle CPU over a ``period_s`` (from
    /proc/stat), or ``ready(period_s)`` says there is work, or after ``limit_s``.

    Where /proc/stat cannot be read (not Linux) it returns at once."""

    def idle_total() -> tuple[float, float]:
        with open("/proc/stat") as fh:
            v = [float(x) for x in fh.readline().split()[1:]]
        return v[3] + v[4], sum(v[:8])  # idle + iowait; user .. steal

    try:
        last = idle_total()
    except (OSError, ValueError, IndexError):
        return
    n_cpu = os.cpu_count() or 1
    t_end = time.monotonic() + limit_s
    while time.monotonic() < t_end:
        if ready(period_s):
            return
        try:
            now = idle_total()
        except (OSError, ValueError, IndexError):
            return
        d_idle, d_total = now[0] - last[0], now[1] - last[1]
        last = now
        if d_total > 0 and d_idle / d_total * n_cpu >= idle_cores:
            return


def _fork_context() -> Any:
    """multiprocessing's fork context where forking is safe (Linux and the like), else None."""
    import multiprocessing as mp

    if sys.platform in ("darwin", "win32") or "fork" not in mp.get_all_start_methods():
        return None
    return mp.get_context("fork")


def _make_here(
    items: list[tuple[str, Callable[[], str | bytes | None]]],
) -> list[tuple[str, str | bytes | None, str | None]]:
    out: list[tuple[str, str | bytes | None, str | None]] = []
    for name, make in items:
        try:
            out.append((name, make(), None))
        except Exception as exc:
            out.append((name, None, _one_line(f"{type(exc).__name__}: {exc}")))
    return out


def _quiet_child() -> None:
    """Signals in a forked report child: Ctrl-C reaches the whole process group, and a child
    inherits the CLI's SIGTERM handler (which raises :class:`Terminated`); the run decides what
    stops and says it in one line, so the child ignores Ctrl-C and dies of SIGTERM at once,
    without a traceback of its own."""
    with contextlib.suppress(ValueError, OSError):  # not the main thread: nothing to change
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _make_in_child(
    conn: Any, items: list[tuple[str, Callable[[], str | bytes | None]]], theirs: Any = None
) -> None:
    _quiet_child()
    if theirs is not None:  # the parent's end, inherited: closed, so that a parent that gives
        theirs.close()  # up makes the answer fail at once instead of blocking on a full pipe
    try:
        conn.send(_make_here(items))
    except BaseException:  # noqa: BLE001 - the parent stopped (SIGTERM, a full disk) or closed
        # the pipe: it reports what happened in its own line; a child's traceback after that
        # line would bury it (the parent notes a child that died without an answer)
        pass
    finally:
        with contextlib.suppress(Exception):
            conn.close()


def _write_files(run_dir: Path, files: Iterable[Any]) -> None:
    """Write each (name, text) into ``run_dir`` atomically, in order; an item may also be a
    callable that returns such pairs (formatted here, on the writer thread)."""
    for item in files:
        for name, text in item() if callable(item) else (item,):
            write_atomic(run_dir / name, text)


def _n_workers(settings: ParallelSettings) -> int:
    return 1 if settings.backend == "serial" else settings.n_workers


def _pid_alive(pid: Any) -> bool:
    try:
        os.kill(int(pid), 0)
    except (OSError, TypeError, ValueError):
        return False
    return True


def run_is_live(record: Mapping[str, Any]) -> bool:
    """Whether the process that wrote ``record`` (status running) still runs on this host."""
    return (
        record.get("status") == "running"
        and record.get("hostname") == socket.gethostname()
        and record.get("pid") != os.getpid()
        and _pid_alive(record.get("pid"))
    )


def read_run_record(run_dir: Path, option: str = "RUN_DIR") -> dict[str, Any]:
    """run.json of a run folder, every field a command relies on checked
    (:func:`pipeline.runfolder.read_run_json`).

    Raises
    ------
    StudyError
        At ``option`` when the folder is not a run folder of ``flexopt run`` or its run.json is
        damaged (the message names the file, what is wrong and what to do).
    """
    return read_run_json(run_dir, option)


def _run_folder_study(run_dir: Path, option: str) -> Study:
    """The study.yaml of a run folder (a missing one is named as such, not as an example)."""
    path = run_dir / "study.yaml"
    if not path.exists():
        raise StudyError(
            option, f"'{run_dir}' has no study.yaml; give a run folder written by flexopt run"
        )
    if not path.is_file():
        raise StudyError(
            option,
            f"'{path}' is not a file; restore the run's study.yaml (the resolved study the run "
            "started with) from a copy",
        )
    return load_folder_study(run_dir, path)


def _refuse_changed_inputs(run_dir: Path, record: dict[str, Any], study: Study) -> None:
    """Name a target table whose bytes changed since the run started, when that is what makes
    the study differ (the message says which file and how to go on)."""
    recorded = record.get("input_files")
    if not isinstance(recorded, dict):
        return
    now = input_hashes(study)
    for key, file in input_files(study):
        entry = recorded.get(key)
        if isinstance(entry, dict) and entry.get("sha256") not in (None, now.get(key)):
            raise StudyError(
                "--resume",
                f"{key}: the file {echo(file)} differs from the one this run started with "
                f"(sha256 {now[key][:12]} is not {str(entry['sha256'])[:12]}): a resumed run "
                f"would mix designs made for two targets; resume with the run's own copy "
                f"(flexopt run --resume {run_dir}, no STUDY) or start a new run",
            )


def resume_run(
    run_dir: Path,
    study_path: str | Path | None = None,
    parallel: ParallelSettings | None = None,
    workers: int | None = None,
    dask: str | None = None,
    eval_timeout_s: float | None = None,
    command_line: str = "",
    on_start: Callable[[Path, GAConfig], None] | None = None,
    on_generation: Callable[[GenerationReport], None] | None = None,
    on_result: Callable[[], None] | None = None,
) -> RunOutcome:
    """Finish an interrupted or killed run by replaying it from its seed and its store.

    Every evaluation in ``evaluations.jsonl`` is served from there (none is solved again); the
    optimiser, seeded as before, asks for the same designs, so the run ends as an uninterrupted
    run with the same seed would.

    Parameters
    ----------
    run_dir : Path
        The run folder of the run to continue.
    study_path : path, optional
        The study to check against the run's (default: the run folder's study.yaml). Its hash
        (sha256 of the resolved YAML, the ``parallel:`` block left out) must match.
    parallel, workers, dask, eval_timeout_s :
        Where to evaluate (``parallel`` as is, or the study's block with these options applied);
        a run may be resumed on other workers.

    Raises
    ------
    StudyError
        At ``--resume`` when the folder is not a resumable run (finished, in use by another
        flexopt process, no hash, a damaged run.json or store) or the study changed; nothing is
        written then. The folder's lock is taken before anything is read and held to the end.
    """
    if not run_dir.is_dir():
        raise StudyError(
            "--resume", f"'{run_dir}' is not a folder; give a run folder of flexopt run"
        )
    # The lock first: two resumes of one folder must not both get past the checks below.
    with lock_run_dir(
        run_dir, "--resume", f"wait for it to finish (flexopt status {run_dir} shows it)"
    ) as lock:
        record = read_run_record(run_dir, "--resume")
        if record.get("status") == "finished":
            raise StudyError(
                "--resume",
                f"the run in '{run_dir}' has finished; nothing to resume (flexopt report "
                f"{run_dir} rebuilds its report)",
            )
        # No process holds the lock, so a status "running" is a run that was killed.
        expected = record.get("study_sha256")
        if not expected:
            raise StudyError(
                "--resume",
                f"'{run_dir}' was written without a study hash (an older flexopt); start a new run",
            )
        study = (
            load_study(study_path)
            if study_path is not None
            else _run_folder_study(run_dir, "--resume")
        )
        quick = bool(record.get("quick", False))
        spec = getattr(study, "optimiser", None) or OptimiserSpec()
        seed = record.get("seed")
        setup = prepare_run(study, quick=quick, seed=None if seed == spec.seed else seed)
        found = study_sha256_with_inputs(setup.study, study_sha256(setup.study))
        if found != expected:
            _refuse_changed_inputs(run_dir, record, setup.study)
            raise StudyError(
                "--resume",
                f"the study differs from the one this run started with (sha256 {found[:12]} is "
                f"not {expected[:12]}); resume with the run's own study (flexopt run --resume "
                f"{run_dir}) or start a new run",
            )
        problem = setup.problem
        store = EvaluationStore(run_dir / STORE_FILE)
        restored = store.load(
            problem.space.n_var,
            len(problem.objective_names),
            len(problem.constraint_names),
            option="--resume",
        )
        settings = parallel or parallel_settings(setup.study, workers, dask, eval_timeout_s)
        log.info("resuming %s with %d evaluations from its store", run_dir, len(restored))
        return run_study(
            setup,
            out=run_dir,
            source=str(record.get("source", "")),
            command_line=command_line,
            on_start=on_start,
            on_generation=on_generation,
            on_result=on_result,
            parallel=settings,
            resume=Resume(record, tuple(restored)),
            lock=lock,
        )


# --------------------------------------------------------------------------------------------
# flexopt report


@dataclass(frozen=True)
class ReportOutcome:
    """What ``flexopt report`` rebuilt.

    Attributes
    ----------
    run_dir : the run folder.
    best : the best evaluation of every evaluation in the folder.
    n_evaluations : evaluations the report is built from.
    files : files (re)written.
    notes : what was skipped and why.
    """

    run_dir: Path
    best: Evaluation
    n_evaluations: int
    files: tuple[str, ...]
    notes: tuple[str, ...]


def _csv_fix(run_dir: Path) -> str:
    return (
        "was it edited or cut short? restore it from a copy, or move it away (flexopt report "
        "works from the store evaluations.jsonl without it)"
    )


def _evaluations_csv(run_dir: Path, columns: _Columns, option: str) -> list[dict[str, str]] | None:
    """evaluations.csv, checked: its columns are the study's, its indices and designs numbers."""
    path = run_dir / "evaluations.csv"
    fix = _csv_fix(run_dir)
    required = ["generation", "index", *columns.variables, *columns.objectives]
    rows = read_folder_csv(path, option, fix, [*required, *columns.constraints])
    if rows is None:
        return None
    for number, row in enumerate(rows, 2):
        where = f"'{path}' line {number}"
        for column in ("generation", "index"):
            if not row[column].isdigit():
                raise StudyError(
                    option,
                    f"{where}, column {column}: {echo(row[column])} is not a whole number; {fix}",
                )
        for column in required[2:] + list(columns.constraints):
            cell_float(row, column, where, option, fix)
        time_s = row.get("time_s", "")
        if time_s:
            cell_float(row, "time_s", where, option, fix)
    return rows


def _evaluations_in(
    run_dir: Path, problem: DesignProblem, option: str = "RUN_DIR"
) -> tuple[list[Evaluation], list[str]]:
    """The run's evaluations (the lossless store, or evaluations.csv in a folder without one)
    and notes on what was skipped (a torn last line of the store). Nothing is written.

    Raises
    ------
    StudyError
        For a damaged store or evaluations.csv (naming the file, the line and the fix).
    """
    store = EvaluationStore(run_dir / STORE_FILE)
    n_var, n_obj = problem.space.n_var, len(problem.objective_names)
    n_con = len(problem.constraint_names)
    if store.path.exists() or store.path.is_symlink():  # a folder there is refused by load
        return store.load(n_var, n_obj, n_con, option=option), list(store.notes)
    columns = _Columns.of(problem)
    rows = _evaluations_csv(run_dir, columns, option)
    out = []
    for row in rows or []:
        out.append(
            Evaluation(
                np.array([float(row[c]) for c in columns.variables]),
                np.array([float(row[c]) for c in columns.objectives]),
                np.array([float(row[c]) for c in columns.constraints]),
                {},
                row.get("reason", ""),
                float(row.get("time_s") or 0.0),
            )
        )
    return out, []


def _history_in(run_dir: Path, columns: _Columns | None = None) -> list[dict[str, Any]]:
    """history.csv with its numbers and booleans read back (checked when ``columns`` are given:
    the columns the convergence plot reads are there and hold numbers)."""
    path = run_dir / "history.csv"
    fix = (
        "was it edited or cut short? restore it from a copy, or delete it (the report then has "
        "no convergence plot)"
    )
    numeric = ["generation", "feasible_fraction"]
    if columns is not None:
        numeric += [f"best_{name}" for name in columns.objectives]
    required = [*numeric, "best_feasible"] if columns is not None else []
    rows = read_folder_csv(path, "RUN_DIR", fix, required)
    if rows is None:
        return []
    for number, row in enumerate(rows, 2):
        where = f"'{path}' line {number}"
        for column in numeric if columns is not None else ():
            cell_float(row, column, where, "RUN_DIR", fix)
        if columns is not None and row["best_feasible"] not in ("true", "false"):
            raise StudyError(
                "RUN_DIR",
                f"{where}, column best_feasible: {echo(row['best_feasible'])} is not true or "
                f"false; {fix}",
            )

    def value(text: str) -> Any:
        if text in ("true", "false"):
            return text == "true"
        try:
            return float(text)
        except ValueError:
            return text

    return [{k: value(v) for k, v in row.items()} for row in rows]


def rebuild_report(run_dir: Path) -> ReportOutcome:
    """Rebuild best.json, the best design's response, plots, STL and report.md from a run folder.

    Nothing is optimised again: the evaluations come from the folder (evaluations.jsonl, else
    evaluations.csv); only the best design's detail is solved again, for its response and shape.
    Works on a finished, interrupted or stopped (killed) run (a report of what is done so far);
    run.json, evaluations.csv and the store are only read. It takes the folder's lock, so it is
    refused while a run (or another report) is writing the folder.

    Raises
    ------
    StudyError
        When the folder is not a run folder, a file it reads is damaged (run.json, study.yaml,
        the store, evaluations.csv, history.csv), it holds no evaluation yet or another flexopt
        process holds its lock; nothing is written then.
    OSError
        When the folder cannot be written.
    """
    if not run_dir.is_dir():
        raise StudyError(
            "RUN_DIR", f"'{run_dir}' is not a folder; give a run folder of flexopt run"
        )
    with lock_run_dir(
        run_dir,
        "RUN_DIR",
        f"wait for it to finish (flexopt status {run_dir} shows it), then rebuild the report",
    ) as lock:
        return _rebuild_report(run_dir, lock)


def _rebuild_report(run_dir: Path, lock: RunDirLock) -> ReportOutcome:
    """:func:`rebuild_report` under the folder's lock: read and check everything, then write."""
    record = read_run_record(run_dir)
    study = _run_folder_study(run_dir, "RUN_DIR")
    setup = prepare_run(study, quick=bool(record.get("quick", False)))
    problem = setup.problem
    evaluations, notes = _evaluations_in(run_dir, problem)
    if not evaluations:
        raise StudyError("RUN_DIR", f"'{run_dir}' holds no evaluation yet; nothing to report")
    columns = _Columns.of(problem)
    history = _history_in(run_dir, columns)
    rows = _evaluations_csv(run_dir, columns, "RUN_DIR") or []
    for name in RUN_FILES:  # what the report may write must not be a folder
        path = run_dir / name
        if path.exists() and not path.is_file():
            raise StudyError(
                "RUN_DIR", f"'{path}' is not a file; move it away so that the report can write it"
            )
    probe_writable(run_dir)
    lock.claim("report")
    run = _Run(setup, run_dir, record, None, None)
    run.notes.extend(notes)
    run.evaluator.solved = list(evaluations)
    run.history = history
    for row in rows:
        x = np.array([float(row[c]) for c in columns.variables])
        run.where.setdefault(design_key(x), (int(row["generation"]), int(row["index"])))
    best = best_of(evaluations)
    n_obj = len(problem.objective_names)
    front = pareto_front(evaluations) if n_obj > 1 else (best,)
    result = GAResult(best, front, ())
    detail = run.finish(result)
    files = list(run.files)
    report = ReportData(
        record=record,
        study=setup.study,
        problem=problem,
        best=best,
        best_where=run.where.get(design_key(best.x), (None, None)),
        front=front,
        detail=detail,
        files=tuple([*record.get("files", []), *files]),
        notes=tuple(run.notes),
        stl=run.stl,
    )
    write_atomic(run_dir / "report.md", render_report(report))
    files.append("report.md")
    return ReportOutcome(run_dir, best, len(evaluations), tuple(files), tuple(run.notes))


# --------------------------------------------------------------------------------------------
# flexopt export


#: What ``flexopt export --format`` writes: binary STL (to print), DXF (the outline, to cut) and
#: STEP (a solid for CAD; needs the optional extra ``flexopt[step]``).
EXPORT_FORMATS = ("stl", "dxf", "step")

#: File name endings taken as a format when ``--format`` is not given.
_SUFFIX_FORMATS = {".stl": "stl", ".dxf": "dxf", ".step": "step", ".stp": "step"}

STEP_EXTRA_FIX = "--format step needs the optional extra: pip install 'flexopt[step]'"
#: The frame each format is written in unless ``--frame`` says otherwise (docs/usage.md): STL is
#: the file to print, laid flat on the bed; DXF and STEP are for CAD and assemblies, in the
#: kind's own coordinates. A sheet part's DXF is always its flat profile (what is cut).
DEFAULT_FRAMES = {"stl": "bed", "dxf": "design", "step": "design"}


def export_frame(fmt: str, frame: str | None = None, sheet: bool = False) -> str:
    """The frame a part in ``fmt`` is written in: ``frame`` if given, else the format's
    (:data:`DEFAULT_FRAMES`); ``bed`` for the DXF of a sheet part (its flat profile)."""
    if fmt == "dxf" and sheet:
        return "bed"
    return frame or DEFAULT_FRAMES[fmt]


@dataclass(frozen=True)
class ExportOutcome:
    """What ``flexopt export`` wrote.

    Attributes
    ----------
    path : the file written.
    design : ``"best"``, the evaluation index, or ``"evaluated"`` (an evaluate folder's design).
    x : (n_var,) float, the design vector.
    evaluation : the design re-evaluated by ``problem.detail``.
    volume_mm3 : mm^3 (area x thickness), triangles : count (STL only, else 0),
    size_mm : size (x, y, z) of the part as written (in its frame), mm.
    format : ``stl``, ``dxf`` or ``step``.
    footprint_mm : (x, y) mm, the size in its frame; thickness_mm : mm along z.
    rotation_deg : deg the kind's outline was turned to align it; sheet : laid flat from a sheet
        standing on its edge (its flat profile).
    frame : ``design`` (the kind's coordinates) or ``bed`` (laid flat).
    """

    path: Path
    design: str
    x: np.ndarray
    evaluation: Evaluation
    volume_mm3: float
    triangles: int
    size_mm: tuple[float, float, float]
    format: str = "stl"
    footprint_mm: tuple[float, float] = (0.0, 0.0)
    thickness_mm: float = 0.0
    rotation_deg: float = 0.0
    sheet: bool = False
    frame: str = "bed"


def _design_vector(
    run_dir: Path, design: str, space: DesignSpace, columns: _Columns | None = None
) -> tuple[np.ndarray, dict[str, Any]]:
    """The design vector of ``best`` or of evaluation INDEX, and where it came from.

    Raises
    ------
    StudyError
        For a design that is not in the run, or a damaged best.json or evaluations.csv (naming
        the file, what is wrong and what to do).
    """
    if design == "best":
        path = run_dir / "best.json"
        fix = f"rebuild it with flexopt report {run_dir}"
        data = read_folder_json(path, "RUN_DIR", fix)
        if data is None:
            raise StudyError(
                "--design",
                f"'{run_dir}' has no best.json (the run did not finish); export one of its "
                "evaluations with --design INDEX (the index column of evaluations.csv), or "
                f"write it with flexopt report {run_dir}",
            )
        if not isinstance(data, dict) or not isinstance(data.get("parameters"), dict):
            what = echo(data.get("parameters")) if isinstance(data, dict) else echo(data)
            raise StudyError(
                "RUN_DIR",
                f"'{path}' has no parameters mapping (found {what}); {fix}",
            )
        values: Mapping[str, Any] = data["parameters"]
        source = f"'{path}'"
    else:
        try:
            index = int(design)
        except ValueError:
            raise StudyError(
                "--design",
                f"got {echo(design)}; give 'best' or a whole number (an evaluation index)",
            ) from None
        path = run_dir / "evaluations.csv"
        columns = columns or _Columns.of_space(space)
        rows = _evaluations_csv(run_dir, columns, "RUN_DIR")
        if rows is None:
            raise StudyError("RUN_DIR", f"'{run_dir}' has no evaluations.csv; is it a run folder?")
        if not 0 <= index < len(rows):
            last = f"0 … {len(rows) - 1}" if rows else "none yet"
            raise StudyError(
                "--design",
                f"no evaluation {index}: the run has {len(rows)} ({last}); pick an index from "
                "the index column of evaluations.csv",
            )
        # a variable's column is not always its name (one named `feasible` is written as
        # `x_feasible`, see _Columns): read each by the column the writer gave it
        row = rows[index]
        values = {n: row[c] for n, c in zip(space.names, columns.variables, strict=True)}
        source = f"'{path}' row {index}"
        fix = _csv_fix(run_dir)
    missing = [name for name in space.names if name not in values]
    if missing:
        raise StudyError(
            "RUN_DIR",
            f"{source} has no value for {', '.join(echo(m) for m in missing[:3])}; the study.yaml "
            f"of this run folder does not match its results (was it edited?); {fix}",
        )
    for name in space.names:
        value = values[name]
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if isinstance(value, str):
            with contextlib.suppress(ValueError):
                number = bool(float(value) == float(value))  # not nan
        if not number or not np.isfinite(float(value)):
            raise StudyError(
                "RUN_DIR", f"{source}: {name} is {echo(value)}, not a finite number; {fix}"
            )
    x = np.array([float(values[name]) for name in space.names], dtype=float)
    return x, {"source": source}


def step_available() -> bool:
    """Whether the optional STEP writer (build123d) is installed (not imported here)."""
    import importlib.util

    return importlib.util.find_spec("build123d") is not None


def part_of(detail: DesignDetail, frame: str = "bed") -> FlatPart:
    """A design's part laid flat or in the design ``frame`` (:func:`geometry.solid.flat_part`),
    the kind's sheet hint (``info[SHEET_HINT]``) honoured.

    Raises
    ------
    GeometryError
        When the outline is not one valid polygon (or a sheet's edge view is not a rectangle).
    """
    from flexopt.geometry.solid import SHEET_HINT, flat_part

    sheet = bool((detail.info or {}).get(SHEET_HINT))
    return flat_part(detail.outline, float(detail.height_mm or 0.0), sheet=sheet, frame=frame)


def part_bytes(part: FlatPart, fmt: str, comment: str = "") -> bytes:
    """The file of a part (laid flat or in the design frame) in ``fmt`` (one of
    :data:`EXPORT_FORMATS`).

    Raises
    ------
    GeometryError
        When the solid fails its checks.
    geometry.solid.StepUnavailable
        For ``step`` without build123d.
    """
    from flexopt.geometry.solid import extrude, step_bytes, stl_bytes

    if fmt == "stl":
        return stl_bytes(extrude(part.outline, part.thickness_mm))
    if fmt == "dxf":
        from flexopt.geometry.dxf import dxf_bytes

        return dxf_bytes(part.outline, comment)
    if fmt == "step":
        return step_bytes(part)
    raise ValueError(f"unknown export format {fmt!r}; use one of {', '.join(EXPORT_FORMATS)}")


def is_evaluate_folder(run_dir: Path) -> bool:
    """A folder of ``flexopt evaluate`` (evaluation.json, no run.json)."""
    return (run_dir / "evaluation.json").is_file() and not (run_dir / "run.json").exists()


def _export_format(fmt: str | None, out: Path | None) -> str:
    """The format asked for, else the one ``--out`` ends in, else STL; a clash is refused."""
    implied = _SUFFIX_FORMATS.get(out.suffix.lower()) if out is not None else None
    if fmt is None:
        return implied or "stl"
    if fmt not in EXPORT_FORMATS:
        raise StudyError("--format", f"got {echo(fmt)}; use one of {', '.join(EXPORT_FORMATS)}")
    if implied is not None and implied != fmt:
        raise StudyError(
            "--out",
            f"'{out}' ends in {out.suffix} but --format is {fmt}; name the file .{fmt} or drop "  # type: ignore[union-attr]
            "--format",
        )
    return fmt


def _evaluate_folder_study(run_dir: Path) -> Study:
    path = run_dir / "study.yaml"
    if not path.is_file():
        raise StudyError(
            "RUN_DIR",
            f"'{run_dir}' has evaluation.json but no study.yaml file; restore it from a copy, or "
            "evaluate the study again with flexopt evaluate",
        )
    return load_folder_study(run_dir, path)


def export_design(
    run_dir: Path,
    design: str = "best",
    out: Path | None = None,
    fmt: str | None = None,
    frame: str | None = None,
) -> ExportOutcome:
    """Rebuild one design of a run or evaluate folder and write its part: STL, DXF or STEP.

    The part is the kind's outline extruded by its height, in the ``design`` frame (where the
    kind draws it) or laid flat on the ``bed`` (turned so its minimum-area rectangle is aligned
    with x and y, moved into the first quadrant); a kind that marks its outline as a sheet
    standing on its edge (``info[geometry.solid.SHEET_HINT]``) gets its flat profile on the bed
    (and as DXF in either frame).

    Parameters
    ----------
    run_dir : Path
        A folder written by ``flexopt run`` (its study.yaml rebuilds the problem), or by
        ``flexopt evaluate`` (its study.yaml is the design).
    design : str
        ``"best"`` (best.json) or an evaluation index (the ``index`` column of evaluations.csv);
        an evaluate folder holds one design, so only ``"best"`` (the default).
    out : Path, optional
        The file; default ``run_dir/best.<fmt>``, ``run_dir/design-<INDEX>.<fmt>`` or, in an
        evaluate folder, ``run_dir/design.<fmt>``.
    fmt : str, optional
        ``stl``, ``dxf`` or ``step``; default the one ``out`` ends in, else ``stl``.
    frame : str, optional
        ``design`` or ``bed``; default the format's (:data:`DEFAULT_FRAMES`: STL on the bed,
        DXF and STEP in the design frame).

    Raises
    ------
    StudyError
        For a missing or unusable folder (a damaged run.json, study.yaml, best.json or
        evaluations.csv), a design that is not in it, a bad format, or ``step`` without the
        optional extra (bad arguments). Export takes no lock: it reads files that are replaced
        atomically, also while a run writes the folder.
    ExportError
        When the design cannot be rebuilt or has no outline to make a part of.
    OSError
        When the file cannot be written.
    """
    fmt = _export_format(fmt, out)
    if frame is not None and frame not in DEFAULT_FRAMES.values():
        raise StudyError("--frame", f"got {echo(frame)}; use design or bed")
    if fmt == "step" and not step_available():
        raise StudyError("", STEP_EXTRA_FIX)
    evaluate = run_dir.is_dir() and is_evaluate_folder(run_dir)
    if evaluate:
        if design != "best":
            raise StudyError(
                "--design",
                f"'{run_dir}' is a folder of flexopt evaluate, which holds one design; drop "
                "--design",
            )
        study = _evaluate_folder_study(run_dir)
        if get_kind(study.kind).problem is None:
            raise ExportError(f"kind '{study.kind}' gives no part outline to export")
        problem = build_problem(study)
        x = _nominal_design(problem, study)
        design = "evaluated"
        default = f"design.{fmt}"
    else:
        read_run_record(run_dir)  # a folder of flexopt run, its run.json readable
        study = _run_folder_study(run_dir, "RUN_DIR")
        problem = build_problem(study)
        x, _ = _design_vector(run_dir, design, problem.space, _Columns.of(problem))
        default = f"best.{fmt}" if design == "best" else f"design-{int(design)}.{fmt}"
    target = out or run_dir / default
    if target.is_dir():
        raise StudyError("--out", f"'{target}' is a folder; give a file name ending in .{fmt}")
    if not target.parent.is_dir():
        raise StudyError("--out", f"folder '{target.parent}' does not exist; create it first")
    try:
        detail = problem.detail(x)
    except Exception as exc:
        raise ExportError(
            f"design {design} could not be rebuilt: {_one_line(f'{type(exc).__name__}: {exc}')}"
        ) from exc
    if detail.outline is None or not detail.height_mm:
        raise ExportError(f"kind '{study.kind}' gives no outline and height_mm to extrude")
    from flexopt.geometry.solid import StepUnavailable

    try:
        bed = part_of(detail)
        used = export_frame(fmt, frame, bed.sheet)
        part = bed if used == "bed" else part_of(detail, used)
        data = part_bytes(part, fmt, f"{study.name}: design {design}")
    except StepUnavailable:
        raise StudyError("", STEP_EXTRA_FIX) from None
    except ValueError as exc:  # GeometryError
        raise ExportError(f"design {design} cannot be made a part: {exc}") from exc
    triangles = 0
    if fmt == "stl":
        import trimesh

        triangles = len(trimesh.load(trimesh.util.wrap_as_stream(data), file_type="stl").faces)
    write_atomic(target, data)
    w, h = part.footprint_mm
    log.info("wrote %s (%s)", target, fmt)
    return ExportOutcome(
        target,
        design,
        x,
        detail.evaluation,
        float(part.outline.area * part.thickness_mm),
        triangles,
        (w, h, part.thickness_mm),
        fmt,
        (w, h),
        part.thickness_mm,
        part.rotation_deg,
        part.sheet,
        part.frame,
    )


# --------------------------------------------------------------------------------------------
# A design as a study (flexopt export --format yaml)

#: File name endings taken as ``--format yaml``.
STUDY_SUFFIXES = (".yaml", ".yml")


@dataclass(frozen=True)
class StudyExportOutcome:
    """What ``flexopt export --format yaml`` wrote.

    Attributes
    ----------
    path : the study file written.
    design : ``"best"``, the evaluation index, or ``"evaluated"`` (an evaluate folder's design).
    study : the study written (``flexopt evaluate`` of it solves the design).
    x : (n_var,) float, the design vector (None for an evaluate folder: its study as it is).
    """

    path: Path
    design: str
    study: Study
    x: np.ndarray | None


def design_study_of(run_dir: Path, design: str = "best") -> tuple[Study, str, np.ndarray | None]:
    """The study that describes one design of a run folder (``best`` or an evaluation index),
    or an evaluate folder's own study: ``flexopt evaluate`` of it gives the design's numbers.

    Raises
    ------
    StudyError
        For a folder or design that is not there or is damaged (as :func:`export_design`).
    ExportError
        When the kind cannot keep the design in its study (:mod:`pipeline.design_study`).
    """
    from flexopt.pipeline.design_study import design_study

    if run_dir.is_dir() and is_evaluate_folder(run_dir):
        if design != "best":
            raise StudyError(
                "--design",
                f"'{run_dir}' is a folder of flexopt evaluate, which holds one design; drop "
                "--design",
            )
        return _evaluate_folder_study(run_dir), "evaluated", None
    read_run_record(run_dir)
    study = _run_folder_study(run_dir, "RUN_DIR")
    problem = build_problem(study)
    x, _ = _design_vector(run_dir, design, problem.space, _Columns.of(problem))
    return design_study(study, problem, x), design, x


def export_study(
    run_dir: Path, design: str = "best", out: Path | None = None
) -> StudyExportOutcome:
    """Write one design of a run (or an evaluate folder's design) as a study YAML file.

    The file is the run's study with the design's values where the kind keeps its design (the
    variables' ``initial``, the ``design:`` block, ...; :mod:`pipeline.design_study`), so
    ``flexopt evaluate FILE`` solves that design and gives the numbers of best.json.

    Parameters
    ----------
    out : Path, optional
        Default ``run_dir/best.yaml``, ``run_dir/design-<INDEX>.yaml`` or, in an evaluate
        folder, ``run_dir/design.yaml``; it must end in .yaml or .yml.

    Raises
    ------
    StudyError
        As :func:`design_study_of`, and for an ``out`` that is a folder, in a missing folder, or
        not a .yaml file.
    ExportError
        When the kind cannot keep the design in its study.
    OSError
        When the file cannot be written.
    """
    if out is not None and out.suffix.lower() not in STUDY_SUFFIXES:
        raise StudyError(
            "--out", f"'{out}' does not end in .yaml; name the study file .yaml (--format yaml)"
        )
    study, design, x = design_study_of(run_dir, design)
    names = {"best": "best.yaml", "evaluated": "design.yaml"}
    target = out or run_dir / (names.get(design) or f"design-{int(design)}.yaml")
    if target.is_dir():
        raise StudyError("--out", f"'{target}' is a folder; give a file name ending in .yaml")
    if not target.parent.is_dir():
        raise StudyError("--out", f"folder '{target.parent}' does not exist; create it first")
    header = (
        f"Design {design} of {run_dir}, written by flexopt export as a study\n"
        f"(the design's values where the {study.kind} kind keeps its design);\n"
        f"solve it with: flexopt evaluate {target}"
    )
    write_atomic(target, study_to_yaml(study, header))
    log.info("wrote %s (yaml)", target)
    return StudyExportOutcome(target, design, study, x)
