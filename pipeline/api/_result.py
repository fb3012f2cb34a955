"""What :func:`flexopt.evaluate` and :func:`flexopt.run` return: plain, frozen values.

:class:`Result` is one solve of a study (its response table, summary and verdict);
:class:`RunResult` is an optimisation's run folder read back (the best design, the Pareto front,
every evaluation). Both read from memory or the run folder; neither solves anything again.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from flexopt.pipeline.errors import StudyError

if TYPE_CHECKING:
    import pandas
    from flexopt.optimise.requirements import Verdict
    from flexopt.pipeline.study import Study
    from matplotlib.figure import Figure

__all__ = ["BestDesign", "Result", "RunResult"]

PANDAS_HINT = (
    "needs pandas, an optional extra of flexopt: pip install 'flexopt[dataframe]' "
    "(or pip install pandas)"
)


def _pandas() -> Any:
    try:
        import pandas
    except ImportError:
        raise ImportError(f"to_dataframe() / evaluations {PANDAS_HINT}") from None
    return pandas


def readonly_table(table: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """Copies of the columns as read-only arrays: a frozen result stays as it was solved."""
    out = {}
    for name, column in table.items():
        arr = np.array(column, copy=True)
        arr.setflags(write=False)
        out[str(name)] = arr
    return out


def _all_met(verdicts: Sequence[Verdict]) -> bool:
    # no requirement at all is not "met": nothing was shown (optimise.requirements.overall)
    return bool(verdicts) and all(v.met for v in verdicts)


def _verdict_word(verdicts: Sequence[Verdict]) -> str:
    met = sum(v.met for v in verdicts)
    return f"{'MET' if _all_met(verdicts) else 'NOT MET'} ({met} of {len(verdicts)})"


@dataclass(frozen=True, repr=False)
class Result:
    """One solve of a study (:func:`flexopt.evaluate`).

    Attributes
    ----------
    study : Study
        The study solved.
    table : dict of str to (n_rows,) ndarray
        The response, one row per step; names carry units (``displacement_mm``, ``force_N``,
        ``peak_stress_MPa``), ``converged`` is boolean. Read-only arrays. A study with load
        cases (a mechanism) has every case's rows, case after case, and a ``load_case`` column
        first; a column a case does not have (its own output) is NaN in its rows.
    summary : dict
        Scalar results (names carry units); None where a value is undefined.
    verdict : tuple of Verdict
        Every requirement (the kind's built-in ones, then ``requirements:``) with value, bound,
        margin and ``met``, judged as ``flexopt evaluate`` judges.
    converged : bool
        Every row converged (a solve that does not converge is a result, not an error).
    message : str
        Why not, when not converged.
    solve_time_s : float, s
        Median wall time of building the model and solving, over ``repeat`` solves.
    run_dir : Path or None
        The evaluate folder, when ``out`` was given.
    cases : dict of str to dict of str to (n_rows,) ndarray
        Each load case's own table by case name (empty for a kind without load cases).
    durability : dict
        The design under the study's ``duty_cycle:``, ``hold:`` and ``stops:``
        (:func:`pipeline.durability_report.durability_record`): ``fatigue`` (the levels with
        amplitude, mean, cycles and damage, Miner's sum, the life in cycles and hours, the
        stress figure, the S-N data and its source), ``hold`` (the creep law, its source, the
        held value, the retention, the stress ratio against the law's limit) and ``contact``
        (per stop the largest force, first contact and smallest gap; the penetration and the
        penalty); only the blocks the study has, empty without any. What report.md,
        report.html and best.json show (docs/api.md).
    """

    study: Study
    table: dict[str, np.ndarray]
    summary: dict[str, Any]
    verdict: tuple[Verdict, ...]
    converged: bool
    message: str
    solve_time_s: float
    run_dir: Path | None = None
    plot_args: dict[str, Any] = field(default_factory=dict)
    cases: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    durability: dict[str, Any] = field(default_factory=dict)

    @property
    def met(self) -> bool:
        """Every requirement is MET (False when the study states none)."""
        return _all_met(self.verdict)

    def to_dataframe(self) -> pandas.DataFrame:
        """The response table as a pandas DataFrame (needs the ``dataframe`` extra); with load
        cases, a ``load_case`` column says each row's case."""
        return _pandas().DataFrame({name: np.array(col) for name, col in self.table.items()})

    def plot(self) -> Figure:
        """The response as a matplotlib Figure: what ``force_displacement.png`` of
        ``flexopt evaluate`` shows (only converged rows are drawn). With load cases: one column
        per case; rows of the drive's reaction, the peak stress (with the allowable the verdict
        uses) and the user's outputs, one row per unit."""
        from flexopt.pipeline.plots import cases_figure, response_figure

        if "cases" in self.plot_args:
            return cases_figure(**self.plot_args)
        return response_figure(self.table, **self.plot_args)

    def verdict_text(self) -> str:
        """The verdict as ``flexopt evaluate`` prints it: one line per requirement, then the
        overall word."""
        from flexopt.optimise.requirements import verdict_lines

        return "\n".join(verdict_lines(self.verdict))

    def __repr__(self) -> str:
        n_rows = len(next(iter(self.table.values()))) if self.table else 0
        cases = f" in {len(self.cases)} load cases" if len(self.cases) > 1 else ""
        state = "converged" if self.converged else f"NOT converged: {self.message[:60]}"
        where = f", {self.run_dir}" if self.run_dir is not None else ""
        return (
            f"<Result {self.study.name} ({self.study.kind}): {_verdict_word(self.verdict)}, "
            f"{state}, {n_rows} rows{cases} x {len(self.table)} columns, "
            f"solve {self.solve_time_s:.3g} s{where}>"
        )


@dataclass(frozen=True, repr=False)
class BestDesign:
    """One design of a run, as best.json records it.

    Attributes
    ----------
    x : (n_var,) ndarray
        The design vector, in the variables' own units.
    variables : dict of str to float
        Variable name → value (the same numbers as ``x``).
    objectives, constraints : dict of str to float
        The optimiser's objectives (minimised: ``negative_X`` is X maximised, negated; the repr
        shows X) and constraints (g <= 0 is met).
    metrics : dict
        The kind's scalar results of this design (names carry units).
    feasible : bool
        Every optimiser constraint is met.
    reason : str
        Why the design could not be evaluated ("" when it was).
    generation, index : int or None
        Where in the run it was first solved (a row of evaluations.csv).
    verdict : tuple of Verdict
        The design against the study's requirements (the best design only; empty for the
        other rows of a Pareto front).
    info : dict
        What the kind reports beyond the metrics (the part's footprint, ...); best design only.
    durability : dict
        best.json's ``durability``: the best design's fatigue, creep hold and contact, as
        :attr:`Result.durability` (empty without a ``duty_cycle:``, ``hold:`` or ``stops:``).
    """

    x: np.ndarray
    variables: dict[str, float]
    objectives: dict[str, float]
    constraints: dict[str, float]
    metrics: dict[str, Any]
    feasible: bool
    reason: str = ""
    generation: int | None = None
    index: int | None = None
    verdict: tuple[Verdict, ...] = ()
    info: dict[str, Any] = field(default_factory=dict)
    durability: dict[str, Any] = field(default_factory=dict)

    @property
    def met(self) -> bool:
        """Every requirement of the verdict is MET (False without a verdict)."""
        return _all_met(self.verdict)

    def __repr__(self) -> str:
        objectives = _objectives_text(self.objectives, self.metrics)
        where = f", generation {self.generation} #{self.index}" if self.generation else ""
        judged = f", {_verdict_word(self.verdict)}" if self.verdict else ""
        return (
            f"<BestDesign {objectives}, {'feasible' if self.feasible else 'NOT feasible'}"
            f"{judged}, {len(self.variables)} variables{where}>"
        )


@dataclass(frozen=True, repr=False)
class RunResult:
    """An optimisation run read from its folder (:func:`flexopt.run`, :func:`flexopt.open_run`).

    Attributes
    ----------
    run_dir : Path
        The run folder (report.md, report.html, best.stl, ... are there).
    record : dict
        run.json: status, seed, counts, times, the parallel backend, versions.
    best : BestDesign
        best.json: the best design (the least violating one when none is feasible).
    front : tuple of BestDesign
        The Pareto front of a study with several objectives; empty for one objective.
    evaluation_table : dict of str to (n_evaluations,) ndarray
        evaluations.csv, every design solved, one entry per column: ``generation``, ``index``,
        the variables, objectives, constraints, ``feasible``, the kind's metrics, ``reason``,
        ``time_s``. :attr:`evaluations` gives it as a DataFrame.
    """

    run_dir: Path
    record: dict[str, Any]
    best: BestDesign
    front: tuple[BestDesign, ...]
    evaluation_table: dict[str, np.ndarray]

    @property
    def verdict(self) -> tuple[Verdict, ...]:
        """The best design against the study's requirements."""
        return self.best.verdict

    @property
    def met(self) -> bool:
        """Every requirement is MET by the best design."""
        return self.best.met

    def verdict_text(self) -> str:
        """The best design's verdict as ``flexopt run`` prints it."""
        from flexopt.optimise.requirements import verdict_lines

        return "\n".join(verdict_lines(self.verdict))

    @property
    def notes(self) -> tuple[str, ...]:
        """What the run skipped and why (a plot or file not written), from run.json."""
        return tuple(str(n) for n in self.record.get("notes") or ())

    @property
    def status(self) -> str:
        """run.json's status: finished, interrupted, stopped, failed (or running)."""
        return str(self.record.get("status", ""))

    @property
    def evaluations(self) -> pandas.DataFrame:
        """Every evaluation of the run as a pandas DataFrame (needs the ``dataframe`` extra)."""
        return _pandas().DataFrame(
            {name: np.array(col) for name, col in self.evaluation_table.items()}
        )

    @cached_property
    def study(self) -> Study:
        """The resolved study the run started with (its study.yaml; its target tables are the
        run folder's copies, found from any working folder)."""
        from flexopt.pipeline.runfolder import load_folder_study

        return load_folder_study(self.run_dir, self.run_dir / "study.yaml")

    def best_study(self, design: int | str = "best") -> Study:
        """The run's best design (or evaluation ``design``, an index of evaluations.csv) as a
        study: the run's study with the design's values where its kind keeps its design (the
        variables' ``initial``, the ``design:`` block, ...), so :func:`flexopt.evaluate` of it
        gives the numbers of best.json; ``flexopt export RUN --format yaml`` writes the same
        study as a file.

        Raises
        ------
        StudyError
            At ``design`` for a design that is not in the run, or when the run's kind cannot
            keep the design in its study (the message says why).
        """
        from flexopt.pipeline.problems import ExportError
        from flexopt.pipeline.run import design_study_of

        if isinstance(design, bool) or not isinstance(design, int | str):
            raise StudyError("design", f"got {design!r}; give 'best' or an evaluation index")
        try:
            return design_study_of(self.run_dir, str(design))[0]
        except ExportError as exc:
            raise StudyError("design", str(exc)) from None

    def __repr__(self) -> str:
        n = len(next(iter(self.evaluation_table.values()))) if self.evaluation_table else 0
        objectives = _objectives_text(self.best.objectives, self.best.metrics)
        front = f", front of {len(self.front)}" if self.front else ""
        judged = _verdict_word(self.verdict) if self.verdict else "no verdict"
        return (
            f"<RunResult {self.record.get('study', '?')} ({self.record.get('kind', '?')}), "
            f"{self.status}: best {objectives}, {judged}, {n} evaluations{front}, "
            f"{self.run_dir}>"
        )


def _objectives_text(objectives: Mapping[str, float], metrics: Mapping[str, Any]) -> str:
    """``maximise free.min_advantage = 4.436``: as the study states them, not as minimised."""
    from flexopt.pipeline.labels import objective_text

    return ", ".join(objective_text(k, v, metrics) for k, v in objectives.items())


def finite_or_nan(value: Any) -> float:
    """A JSON number or null as a float (null, the JSON form of NaN, becomes NaN)."""
    return math.nan if value is None else float(value)
