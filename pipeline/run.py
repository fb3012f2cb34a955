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
import json
import logging
import os
import platform
import time
from collections import Counter
from collections.abc import Callable, Mapping, MutableMapping
from dataclasses import dataclass, field, replace
from datetime import datetime
from importlib import metadata
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from optimise.errors import OptimiseError
from optimise.evaluation import Evaluation
from optimise.ga import GAConfig, GAResult, Generation, run_ga
from optimise.problem import DesignDetail, DesignProblem
from optimise.space import DesignSpace
from pipeline import plots
from pipeline.errors import StudyError
from pipeline.evaluate import versions
from pipeline.report import ReportData, render_report
from pipeline.runfolder import (
    check_out_dir,
    make_run_dir,
    new_run_dir_path,
    read_records_csv,
    records_to_csv,
    table_to_csv,
    to_json,
    write_atomic,
)
from pipeline.studies import get_kind, kinds
from pipeline.study import OptimiserSpec, Study, load_study, study_to_yaml

__all__ = [
    "Evaluator",
    "ExportError",
    "ExportOutcome",
    "GenerationReport",
    "RunOutcome",
    "RunSetup",
    "evaluate_batch",
    "evaluate_one",
    "export_design",
    "prepare_run",
    "run_study",
]

log = logging.getLogger(__name__)

#: Files a finished run folder can hold (plots, STL and the response only when the kind gives what
#: they need). run.json is written first and last: its ``status`` says whether the run finished.
RUN_FILES = (
    "study.yaml",
    "run.json",
    "evaluations.csv",
    "history.csv",
    "best.json",
    "best_response.csv",
    "force_displacement.png",
    "stress.png",
    "convergence.png",
    "shapes.png",
    "best.stl",
    "report.md",
)

#: Longest failure reason kept in a row (exception messages can quote whole arrays).
MAX_REASON_CHARS = 300

_EXTRA_DISTRIBUTIONS = {
    "pymoo": "pymoo",
    "shapely": "shapely",
    "trimesh": "trimesh",
    "manifold3d": "manifold3d",
}


class ExportError(RuntimeError):
    """A design could not be rebuilt or turned into a solid (the message says why)."""


# --------------------------------------------------------------------------------------------
# Evaluating designs: one function, one cache


class BatchBackend(Protocol):
    """Evaluates designs; reports each as it finishes through ``on_result(row, evaluation)``.

    Reporting as results arrive lets the evaluator keep every finished design when the run is
    interrupted mid-batch, and lets a parallel backend finish designs in any order.
    """

    def __call__(
        self,
        problem: DesignProblem,
        X: np.ndarray,
        on_result: Callable[[int, Evaluation], None] | None = None,
    ) -> list[Evaluation]: ...


def _one_line(text: str) -> str:
    text = " ".join(text.split())
    return text if len(text) <= MAX_REASON_CHARS else text[: MAX_REASON_CHARS - 3] + "..."


def evaluate_one(problem: DesignProblem, x: np.ndarray) -> Evaluation:
    """Evaluate one design, turning every failure into an infeasible Evaluation with a reason.

    Parameters
    ----------
    problem : DesignProblem
    x : (n_var,) float
        The design vector, in the units of ``problem.space``.

    Returns
    -------
    Evaluation
        The kind's Evaluation (``time_s`` filled in with the wall time when the kind left it 0);
        or ``Evaluation.failed`` when ``problem.evaluate`` raised (reason
        ``"<ExceptionType>: <message>"``), returned something that is not an Evaluation with
        ``n_obj`` objectives and ``n_con`` constraints, or returned a NaN/inf objective or
        constraint without a reason (pymoo cannot rank those).
    """
    n_obj, n_con = len(problem.objective_names), len(problem.constraint_names)
    x = np.array(x, dtype=float)
    start = time.perf_counter()
    try:
        evaluation = problem.evaluate(x.copy())
    except Exception as exc:  # fault isolation: a bad design never stops the run
        elapsed = time.perf_counter() - start
        log.debug("design %s raised", x, exc_info=True)
        return Evaluation.failed(
            x, n_obj, n_con, _one_line(f"{type(exc).__name__}: {exc}"), elapsed
        )
    elapsed = time.perf_counter() - start
    if not isinstance(evaluation, Evaluation):
        return Evaluation.failed(
            x,
            n_obj,
            n_con,
            f"TypeError: evaluate returned {type(evaluation).__name__}, not an Evaluation",
            elapsed,
        )
    f, g = np.asarray(evaluation.f, dtype=float), np.asarray(evaluation.g, dtype=float)
    if f.shape != (n_obj,) or g.shape != (n_con,):
        return Evaluation.failed(
            x,
            n_obj,
            n_con,
            f"ValueError: evaluate returned f of shape {f.shape} and g of shape {g.shape}; the "
            f"problem names {n_obj} objectives and {n_con} constraints",
            elapsed,
            evaluation.metrics,
        )
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(g))):
        reason = evaluation.reason or f"non-finite result (f = {f.tolist()}, g = {g.tolist()})"
        return Evaluation.failed(x, n_obj, n_con, _one_line(reason), elapsed, evaluation.metrics)
    if evaluation.time_s <= 0.0:
        evaluation = replace(evaluation, time_s=elapsed)
    return evaluation


def evaluate_batch(
    problem: DesignProblem,
    X: np.ndarray,
    on_result: Callable[[int, Evaluation], None] | None = None,
) -> list[Evaluation]:
    """Evaluate designs one after the other in this process (the serial backend).

    Parameters
    ----------
    problem : DesignProblem
    X : (m, n_var) float
        Design vectors.
    on_result : callable(row, evaluation), optional
        Called after each design with its row in ``X``.

    Returns
    -------
    list of Evaluation
        m evaluations in the order of ``X``; failures are infeasible Evaluations with a reason
        (see :func:`evaluate_one`), so this never raises for a bad design.
    """
    out = []
    for row, x in enumerate(np.atleast_2d(np.asarray(X, dtype=float))):
        out.append(evaluate_one(problem, x))
        if on_result is not None:
            on_result(row, out[-1])
    return out


def design_key(x: np.ndarray) -> bytes:
    """Cache key of a design: the bytes of its float64 vector (bit-identical designs only)."""
    return np.ascontiguousarray(x, dtype=np.float64).tobytes()


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

    Attributes
    ----------
    solved : list of Evaluation
        Every design the backend solved, in order (cache hits are not repeated here).
    n_cache_hits : int
        Designs served from the cache (repeats across generations and within a batch).
    """

    def __init__(
        self,
        problem: DesignProblem,
        backend: BatchBackend = evaluate_batch,
        cache: MutableMapping[bytes, Evaluation] | None = None,
        on_result: Callable[[], None] | None = None,
    ) -> None:
        self.problem = problem
        self.backend = backend
        self.cache: MutableMapping[bytes, Evaluation] = {} if cache is None else cache
        self.on_result = on_result
        self.solved: list[Evaluation] = []
        self.n_cache_hits = 0

    def map(self, X: np.ndarray) -> list[Evaluation]:
        """Evaluate (m, n_var) designs; returns m Evaluations in order."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        keys = [design_key(x) for x in X]
        todo: dict[bytes, int] = {}
        for row, key in enumerate(keys):
            if key not in self.cache and key not in todo:
                todo[key] = row
        self.n_cache_hits += len(keys) - len(todo)
        if todo:
            new_keys = list(todo)

            def keep(row: int, evaluation: Evaluation) -> None:
                if new_keys[row] not in self.cache:  # a backend may report and also return it
                    self.cache[new_keys[row]] = evaluation
                    self.solved.append(evaluation)
                    if self.on_result is not None:
                        self.on_result()

            new = self.backend(self.problem, X[list(todo.values())], on_result=keep)
            if len(new) != len(todo):
                raise RuntimeError(f"the backend returned {len(new)} results for {len(todo)}")
            for row, evaluation in enumerate(new):
                keep(row, evaluation)
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


def _optimisable() -> str:
    names = sorted(name for name, kind in kinds().items() if kind.problem is not None)
    return ", ".join(names) if names else "(none yet)"


def build_problem(study: Study) -> DesignProblem:
    """The kind's design problem for ``study``.

    Raises
    ------
    StudyError
        When the kind cannot be optimised, or refuses the study while building the problem.
    """
    kind = get_kind(study.kind)
    if kind.problem is None:
        raise StudyError(
            "geometry.kind",
            f"kind '{kind.name}' has nothing to optimise; solve it with `flexopt evaluate`, or "
            f"use a kind that `flexopt run` optimises: {_optimisable()}",
        )
    try:
        problem = kind.problem(study)
    except StudyError:
        raise
    except (ValueError, OptimiseError) as exc:  # geometry/fea/optimise refusals are ValueErrors
        raise StudyError(
            "", f"the design problem cannot be set up: {type(exc).__name__}: {exc}"
        ) from exc
    if not isinstance(problem, DesignProblem) or not isinstance(problem.space, DesignSpace):
        raise TypeError(
            f"kind '{kind.name}' returned {type(problem).__name__}, which is not a DesignProblem "
            "(space, objective_names, constraint_names, evaluate, detail)"
        )
    return problem


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
    """The designs a problem asks to seed the first population with (optional
    ``initial_designs()`` method beyond the DesignProblem protocol), as (k, n_var), or None."""
    method = getattr(problem, "initial_designs", None)
    if not callable(method):
        return None
    initial = method()
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
    """

    generation: int
    n_gen: int
    n_evaluations: int
    n_cache_hits: int
    best: Evaluation
    feasible_fraction: float
    evaluations_per_s: float
    wall_s: float


@dataclass(frozen=True)
class RunOutcome:
    """Where a run went and what it found."""

    run_dir: Path
    result: GAResult
    detail: DesignDetail | None
    record: dict[str, Any]
    notes: tuple[str, ...] = ()


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
    ) -> None:
        self.setup = setup
        self.problem = setup.problem
        self.run_dir = run_dir
        self.record = record
        self.on_generation = on_generation
        self.columns = _Columns.of(setup.problem)
        self.evaluator = Evaluator(setup.problem, on_result=on_result)
        self.rows: list[dict[str, Any]] = []
        self.where: dict[bytes, tuple[int, int]] = {}  # design -> (generation, index) solved
        self.history: list[dict[str, Any]] = []
        self.generations: list[Generation] = []
        self.t0 = time.perf_counter()
        self.t_last = self.t0
        self.notes: list[str] = []
        self.files: list[str] = []
        self.stl: dict[str, Any] = {}

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
        now = time.perf_counter()
        number = gen.index + 1
        n_new = self._collect(number)
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
            optimise_wall_s=report.wall_s,
        )
        self.write_tables()
        write_atomic(self.run_dir / "run.json", to_json(self.record))
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

    def write_tables(self) -> None:
        exact = set(self.columns.variables)
        write_atomic(
            self.run_dir / "evaluations.csv",
            records_to_csv(self.rows, self.columns.header(), exact=exact),
        )
        if self.history:
            write_atomic(
                self.run_dir / "history.csv",
                records_to_csv(self.history, list(self.history[0])),
            )

    # -- the end of a run ----------------------------------------------------------------------

    def artefact(self, name: str, make: Callable[[], str | bytes | None]) -> None:
        """Write one result file; a failure to *make* it is a note, not the end of the run."""
        try:
            data = make()
        except Exception as exc:
            note = f"{name} not written: {_one_line(f'{type(exc).__name__}: {exc}')}"
            log.warning(note, exc_info=True)
            self.notes.append(note)
            return
        if data is None:
            return
        write_atomic(self.run_dir / name, data)
        self.files.append(name)

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

    def finish(self, result: GAResult) -> DesignDetail | None:
        study, problem = self.setup.study, self.problem
        best = result.best
        title = f"{study.name}: best design"
        best_json = self.best_record(best)
        detail: DesignDetail | None = None
        try:
            detail = problem.detail(np.array(best.x, dtype=float))
        except Exception as exc:
            note = f"the best design's detail failed: {_one_line(f'{type(exc).__name__}: {exc}')}"
            log.warning(note, exc_info=True)
            self.notes.append(note + " (no response, plots of it, STL)")
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
        if table:
            self.artefact("best_response.csv", lambda: table_to_csv(table))
        elif detail is not None:
            self.notes.append("the kind gives no response table: no best_response.csv")
        if x in table and y in table:
            self.artefact("force_displacement.png", lambda: _curve_png(table, spec, title))
        elif table:
            self.notes.append(f"force_displacement.png skipped: no columns '{x}' and '{y}'")
        if x in table and stress in table:
            self.artefact(
                "stress.png",
                lambda: plots.plot_stress(
                    table,
                    x,
                    stress,
                    allowable_MPa=_float_or_none(spec.get("allowable_MPa")),
                    x_label=_spec_label(spec, "x"),
                    title=title,
                ),
            )
        elif table:
            self.notes.append(f"stress.png skipped: the response has no '{stress}' column")
        self.artefact("convergence.png", lambda: _convergence_png(self.history, self.columns))
        if detail is not None and detail.shapes_mm is not None:
            values = table.get(x)
            shapes = np.asarray(detail.shapes_mm)
            if values is not None and len(values) != len(shapes):
                values = None
            self.artefact(
                "shapes.png",
                lambda: plots.plot_shapes(shapes, values, value_label=x, title=title),
            )
        if detail is not None and detail.outline is not None and detail.height_mm:
            self.artefact("best.stl", lambda: self._stl(detail))
        elif detail is not None:
            self.notes.append("best.stl skipped: the kind gives no outline and height_mm")
        return detail

    def _stl(self, detail: DesignDetail) -> bytes | None:
        try:
            from geometry.solid import extrude, stl_bytes
        except ImportError:
            self.notes.append("best.stl skipped: geometry.solid is not available in this install")
            return None
        mesh = extrude(detail.outline, float(detail.height_mm))  # type: ignore[arg-type]
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
    )


def _convergence_png(history: list[dict[str, Any]], columns: _Columns) -> bytes:
    return plots.plot_convergence(
        np.array([h["generation"] for h in history]),
        np.array([[h[f"best_{name}"] for name in columns.objectives] for h in history]),
        np.array([h["best_feasible"] for h in history]),
        np.array([h["feasible_fraction"] for h in history]),
        columns.objectives,
    )


def run_study(
    setup: RunSetup,
    out: Path | None = None,
    source: str = "",
    command_line: str = "",
    runs_root: Path = Path("runs"),
    on_start: Callable[[Path, GAConfig], None] | None = None,
    on_generation: Callable[[GenerationReport], None] | None = None,
    on_result: Callable[[], None] | None = None,
) -> RunOutcome:
    """Optimise a prepared study and write its run folder.

    Parameters
    ----------
    setup : RunSetup
        From :func:`prepare_run` (which refuses bad inputs before anything is written).
    out : Path, optional
        Run folder; default ``runs_root/<name>-run-<timestamp>``. A folder that already holds
        a run (run.json) is refused.
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

    Returns
    -------
    RunOutcome

    Raises
    ------
    StudyError
        When ``out`` cannot be a new run folder (nothing is written).
    OSError
        When the run folder cannot be written.
    KeyboardInterrupt
        After writing run.json with status ``interrupted`` (and every evaluation so far).
    """
    if out is not None:
        check_out_dir(out)
        if (out / "run.json").exists():
            raise StudyError(
                "--out", f"'{out}' already holds a run (run.json); give a new folder or remove it"
            )
    study, config = setup.study, setup.config
    started = _now()
    run_dir = make_run_dir(out or new_run_dir_path(runs_root, study.name, "run", started))
    record: dict[str, Any] = {
        "study": study.name,
        "kind": study.kind,
        "command": "run",
        "command_line": command_line,
        "source": source,
        "status": "running",
        "error": "",
        "quick": setup.quick,
        "seed": config.seed,
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
        "finished": None,
        "generations_done": 0,
        "n_evaluations": 0,
        "n_cache_hits": 0,
        "wall_s": None,
        "optimise_wall_s": None,
        "evaluations_per_s": None,
        "versions": all_versions(),
        "host": {"platform": platform.platform(), "cpu_count": os.cpu_count()},
    }
    rerun = f"flexopt run {run_dir / 'study.yaml'}" + (" --quick" if setup.quick else "")
    header = (
        f"Resolved study written by flexopt run on {record['started']}\n"
        f"from {source or 'memory'}; re-run with: {rerun}"
    )
    write_atomic(run_dir / "study.yaml", study_to_yaml(study, header))
    write_atomic(run_dir / "run.json", to_json(record))
    log.info("run folder %s; %s", run_dir, config)
    if on_start is not None:
        on_start(run_dir, config)

    run = _Run(setup, run_dir, record, on_generation, on_result)
    t_start = time.perf_counter()

    def close(status: str, error: str = "", write: bool = True) -> None:
        wall = time.perf_counter() - t_start
        n = len(run.evaluator.solved)
        optimise_wall = record.get("optimise_wall_s") or wall
        failed = [ev for ev in run.evaluator.solved if ev.reason]
        record.update(
            status=status,
            error=error,
            finished=_stamp(_now()),
            wall_s=wall,
            n_evaluations=n,
            n_cache_hits=run.evaluator.n_cache_hits,
            n_failed=len(failed),
            n_feasible=sum(ev.feasible for ev in run.evaluator.solved),
            evaluations_per_s=n / optimise_wall if optimise_wall > 0 else None,
            mean_evaluation_s=(
                float(np.mean([ev.time_s for ev in run.evaluator.solved])) if n else None
            ),
            failure_reasons=dict(Counter(ev.reason for ev in failed).most_common(10)),
            notes=run.notes,
            files=sorted(set(run.files) | {"study.yaml", "run.json", "evaluations.csv"}),
        )
        if write:
            write_atomic(run_dir / "run.json", to_json(record))

    def abandon(status: str, error: str) -> None:
        # Keep what was done; a folder that cannot be written any more must not hide the cause.
        with contextlib.suppress(OSError):
            run._collect(len(run.generations) + 1)  # the unfinished generation's designs
            run.write_tables()
            close(status, error)

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
        record["optimise_wall_s"] = time.perf_counter() - t_start
        run.files += ["evaluations.csv", "history.csv"]
        detail = run.finish(result)
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
        )
        write_atomic(run_dir / "report.md", render_report(report))
        close("finished")
    except KeyboardInterrupt:
        abandon("interrupted", "interrupted by the user (Ctrl-C)")
        raise
    except BaseException as exc:
        abandon("failed", _one_line(f"{type(exc).__name__}: {exc}"))
        raise
    log.info("finished %s in %.3g s", run_dir, record["wall_s"])
    return RunOutcome(run_dir, result, detail, record, tuple(run.notes))


# --------------------------------------------------------------------------------------------
# flexopt export


@dataclass(frozen=True)
class ExportOutcome:
    """What ``flexopt export`` wrote.

    Attributes
    ----------
    path : the STL file.
    design : ``"best"`` or the evaluation index.
    x : (n_var,) float, the design vector.
    evaluation : the design re-evaluated by ``problem.detail``.
    volume_mm3 : mm^3, triangles : count, size_mm : bounding-box size (x, y, z) of the solid.
    """

    path: Path
    design: str
    x: np.ndarray
    evaluation: Evaluation
    volume_mm3: float
    triangles: int
    size_mm: tuple[float, float, float]


def _design_vector(
    run_dir: Path, design: str, space: DesignSpace
) -> tuple[np.ndarray, dict[str, Any]]:
    """The design vector of ``best`` or of evaluation INDEX, and where it came from."""
    if design == "best":
        path = run_dir / "best.json"
        if not path.is_file():
            raise StudyError(
                "--design",
                f"'{run_dir}' has no best.json (the run did not finish); export one of its "
                "evaluations with --design INDEX (the index column of evaluations.csv)",
            )
        values = json.loads(path.read_text(encoding="utf-8")).get("parameters", {})
        source = "best.json"
    else:
        try:
            index = int(design)
        except ValueError:
            raise StudyError(
                "--design", f"got {design!r}; give 'best' or a whole number (an evaluation index)"
            ) from None
        path = run_dir / "evaluations.csv"
        if not path.is_file():
            raise StudyError("RUN_DIR", f"'{run_dir}' has no evaluations.csv; is it a run folder?")
        rows = read_records_csv(path)
        if not 0 <= index < len(rows):
            raise StudyError(
                "--design",
                f"no evaluation {index}: the run has {len(rows)} (0 … {len(rows) - 1}); pick "
                "an index from the index column of evaluations.csv",
            )
        values = rows[index]
        source = f"evaluations.csv row {index}"
    missing = [name for name in space.names if name not in values]
    if missing:
        raise StudyError(
            "--design",
            f"{source} has no value for {', '.join(missing)}; the study.yaml of this run folder "
            "does not match its results (was it edited?)",
        )
    try:
        x = np.array([float(values[name]) for name in space.names], dtype=float)
    except (TypeError, ValueError):
        raise StudyError(
            "--design", f"{source} holds a design value that is not a number"
        ) from None
    return x, {"source": source}


def export_design(run_dir: Path, design: str = "best", out: Path | None = None) -> ExportOutcome:
    """Rebuild one design of a run and write it as a binary STL.

    Parameters
    ----------
    run_dir : Path
        A folder written by ``flexopt run`` (its study.yaml rebuilds the problem).
    design : str
        ``"best"`` (best.json) or an evaluation index (the ``index`` column of evaluations.csv).
    out : Path, optional
        The STL file; default ``run_dir/best.stl`` or ``run_dir/design-<INDEX>.stl``.

    Raises
    ------
    StudyError
        For a missing or unusable run folder, or a design that is not in it (bad arguments).
    ExportError
        When the design cannot be rebuilt or has no printable outline.
    OSError
        When the STL cannot be written.
    """
    if not run_dir.is_dir():
        raise StudyError(
            "RUN_DIR", f"'{run_dir}' is not a folder; give a run folder of flexopt run"
        )
    if not (run_dir / "study.yaml").is_file():
        raise StudyError(
            "RUN_DIR", f"'{run_dir}' has no study.yaml; give a run folder written by flexopt run"
        )
    study = load_study(run_dir / "study.yaml")
    problem = build_problem(study)
    x, _ = _design_vector(run_dir, design, problem.space)
    target = out or run_dir / ("best.stl" if design == "best" else f"design-{int(design)}.stl")
    if target.is_dir():
        raise StudyError("--out", f"'{target}' is a folder; give a file name ending in .stl")
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
    try:
        from geometry.solid import extrude, stl_bytes
    except ImportError as exc:
        raise ExportError("geometry.solid is not available in this install") from exc
    try:
        mesh = extrude(detail.outline, float(detail.height_mm))
    except ValueError as exc:  # GeometryError
        raise ExportError(f"design {design} cannot be made a solid: {exc}") from exc
    write_atomic(target, stl_bytes(mesh))
    lo, hi = mesh.bounds
    size = tuple(float(v) for v in hi - lo)
    log.info("wrote %s (%d triangles)", target, len(mesh.faces))
    return ExportOutcome(
        target,
        design,
        x,
        detail.evaluation,
        float(mesh.volume),
        len(mesh.faces),
        size,  # type: ignore[arg-type]
    )
