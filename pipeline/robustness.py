"""A design under manufacturing scatter: the ``robustness:`` block of a study, run.

For each sample of :mod:`optimise.robustness` (``E_factor, thickness_delta_mm,
width_delta_mm``) the design is rebuilt with Young's modulus scaled and every thickness and
width shifted, solved, and judged against the requirements of the verdict. The samples are
evaluations like any other: they run through the study's parallel backend (serial, a process
pool or Dask) as design vectors of :class:`SampleProblem`, a design problem over the three
scatter variables.

How a sample changes a design
-----------------------------
The **study** (:func:`perturb_study`): ``material.E_MPa`` times ``E_factor``; every number under
a key ending in ``thickness_mm`` plus ``thickness_delta_mm`` and under a key ending in
``width_mm`` plus ``width_delta_mm`` (``geometry.thickness_mm``, ``geometry.width_mm``,
``geometry.beams.<b>.thickness_mm``, ``geometry.pad_thickness_mm``, ``design.thickness_mm`` ...),
except under ``design_space``, ``requirements``, ``optimiser``, ``parallel`` and ``robustness``
(bounds and limits are not printed). The kind's cross-checks of one design (``fidelity``,
``prb``, ``check_3d``, ``solid_3d.check``) are switched off in a sample, to keep it cheap; the
figures the nominal verdict judges on them (the constant-force plane-stress peak and force) are
given to every sample by the nominal design's measured ratios, and a sample near a bound is
solved again with its checks on (:mod:`pipeline.robust_fidelity`, :func:`judge_samples`).

The **design vector** of a kind that ``flexopt run`` optimises (:func:`scatter_design`): the
problem's :meth:`~optimise.problem.DesignProblem.scatter_design` when it gives one (a kind
whose variable names do not say what they are: ``t1_mm``, ``B_mm``); else, for a
problem whose ``variables`` are :class:`optimise.variables.DesignVariables` (variables on key
paths), each variable that sets a ``*thickness_mm`` / ``*width_mm`` key moves that key by the
delta; else every variable whose name contains ``thickness`` gets ``thickness_delta_mm`` and
every one whose name contains ``width`` gets ``width_delta_mm``. The record's ``perturbed``
lists exactly what moved.

A quantity the problem **solves per design** (the SEA and threshold springs' thickness ST, from
the stiffness target) is not re-solved in a sample, or every sample would meet the target by
construction: a problem that names it in its ``held_scatter`` (``{name: "width"}``, also
listed in ``perturbed``) has ``held_state(evaluation) -> {name: value}`` take it from the
nominal design's evaluation, and ``hold_solved(held, thickness_delta_mm, width_delta_mm)``
make the sample's problem use it, moved by the scatter (ST by ``width_delta_mm``: a plate's
thickness is the out-of-plane width of the print or cut); the hooks of
:class:`~optimise.problem.DesignProblem`.

Which path a sample takes
-------------------------
``design``: a kind with a design problem and a design (the chosen design of ``flexopt run``; the
study's nominal design in ``flexopt evaluate``): the perturbed study's problem gives the
``detail`` of the shifted design vector, judged as ``flexopt run`` judges its best design.
``study``: a kind that is only evaluated: the kind's ``evaluate`` of the perturbed study, judged
as ``flexopt evaluate`` judges it.

Robust requirements
-------------------
A ``requirements:`` item with ``robust:`` (:mod:`optimise.robust_requirements`) is held by the
GA on fixed draws of the same scatter (:class:`RobustConstraints`, the run's problem: one
``robust_<name>`` row per constraint, the k-th smallest per-draw row), and judged for the
verdict on fresh draws by :func:`run_robustness` (``robust_verdicts``, ``robust_record``): one
row ``<name> (robust)`` per item, MET when the demonstrated share reaches the required one; a
run's record adds what robustness cost against its nominal optimum (:func:`nominal_optimum`),
judged on the same draws. The draws are prints like the samples above: the study perturbed,
the design vector moved, a quantity the problem solves per design held.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from flexopt.optimise.evaluation import INFEASIBLE_VALUE, Evaluation
from flexopt.optimise.problem import DesignProblem, ProblemWrapper, as_design_problem
from flexopt.optimise.requirements import MISSING_CONSTRAINT, Verdict
from flexopt.optimise.robust_requirements import (
    GA_STREAM,
    VERDICT_STREAM,
    RobustShareSpec,
    demonstrated_share,
    kth_constraint,
    scatter_draws,
)
from flexopt.optimise.robustness import (
    SAMPLE_COLUMNS,
    RobustnessSpec,
    met_robustly,
    response_band,
    samples_of,
    share_met,
)
from flexopt.optimise.space import DesignSpace
from flexopt.optimise.variables import DesignVariables
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.robust_fidelity import FidelityTransfer, fidelity_transfer, measured_ratios
from flexopt.pipeline.study import Study, check_robustness, validate_study

__all__ = [
    "RobustConstraints",
    "RobustnessResult",
    "SampleProblem",
    "WorstCaseProblem",
    "check_robustness",
    "compact",
    "perturb_study",
    "robustness_lines",
    "robustness_markdown",
    "run_robustness",
    "scatter_design",
    "nominal_optimum",
    "robust_verdict_rows",
    "with_robust_constraints",
    "with_robust_rows",
    "with_worst_case",
]

log = logging.getLogger(__name__)

#: Top-level blocks a sample leaves alone: bounds, limits and run settings are not printed.
UNPERTURBED_BLOCKS = ("design_space", "requirements", "optimiser", "parallel", "robustness")

#: Cross-checks of one design: off in a sample (the constant-force plane-stress check ~0.7 s CPU
#: against the beam's 0.03 s); the figures they give the verdict reach a sample through
#: pipeline.robust_fidelity (the nominal's ratios; re-solved with them near a bound).
SAMPLE_SWITCHES: tuple[tuple[tuple[str, ...], Any], ...] = (
    (("fidelity", "enabled"), False),
    (("check_3d",), False),
    (("solid_3d", "check"), False),  # sea_spring, threshold_spring: ~20 s and ~3 GB per check
)
SAMPLE_DROPPED = ("prb",)

#: The quantity of the SEA kind's "checked in 3D" row (pipeline/studies/_sea_spring_3d_off.py):
#: NOT MET whenever a study's 3D check is off, which SAMPLE_SWITCHES makes it in every sample.
CHECKED_3D = "checked_3d"


def sample_requirements(study: Any) -> list[Any]:
    """The requirements a sample is judged on: the verdict's (:func:`pipeline.verdict.
    study_requirements` of the sample's own study) less the "checked in 3D" row, which the
    sample's switched-off 3D check (SAMPLE_SWITCHES, a cost choice of the sampler, not the
    user's) would make NOT MET in every sample. A sample of a SEA spring is judged on plane
    stress; the nominal design's verdict keeps its 3D rows (docs/robustness.md)."""
    from flexopt.pipeline.verdict import study_requirements

    return [r for r in study_requirements(study) if getattr(r, "quantity", None) != CHECKED_3D]


#: Key endings shifted by the thickness scatter. The printable minimum moves with the print: it
#: is a rule on the drawing (every feature at least two extrusion lines), so a sample printed
#: 0.1 mm thin is judged, and solved, as the print of a printable drawing, not refused as
#: unprintable (the constant-force problem refuses to solve a design under the minimum).
THICKNESS_KEYS = ("thickness_mm", "min_feature_mm")


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def perturb_study(
    study: Study,
    E_factor: float,
    thickness_delta_mm: float,
    width_delta_mm: float,
    checks: bool = False,
) -> tuple[Study, tuple[str, ...]]:
    """The study of one sample, and the key paths it changed; ``checks``: keep the kind's
    cross-checks as the study sets them (a sample re-checked near a bound,
    :mod:`pipeline.robust_fidelity`), else they are switched off (SAMPLE_SWITCHES).

    Raises
    ------
    StudyError
        When the perturbed study is invalid (a thickness shifted to zero or below, a value moved
        outside a variable's bounds): :class:`SampleProblem` makes that sample a failed one,
        which meets nothing and is named in the record, never a refusal of the study.
    """
    data, changed = _perturbed_data(study, E_factor, thickness_delta_mm, width_delta_mm, checks)
    return validate_study(data), changed


def _perturbed_data(
    study: Study,
    E_factor: float,
    thickness_delta_mm: float,
    width_delta_mm: float,
    checks: bool = False,
) -> tuple[dict[str, Any], tuple[str, ...]]:
    """:func:`perturb_study`'s plain data, not validated (what a sample changes, in words)."""
    data = study.model_dump(mode="json", exclude_none=True)
    changed: list[str] = []
    material = data.get("material")
    if E_factor != 1.0 and isinstance(material, dict) and _is_number(material.get("E_MPa")):
        material["E_MPa"] = float(material["E_MPa"]) * float(E_factor)
        changed.append("material.E_MPa")

    def shift(node: Any, path: str, delta: float) -> Any:
        if _is_number(node):
            changed.append(path)
            return float(node) + delta
        if isinstance(node, list):
            return [shift(v, f"{path}[{i}]", delta) for i, v in enumerate(node)]
        return node

    def walk(node: Any, path: str) -> None:
        if not isinstance(node, dict):
            if isinstance(node, list):
                for i, item in enumerate(node):
                    walk(item, f"{path}[{i}]")
            return
        for key, value in node.items():
            where = f"{path}.{key}" if path else str(key)
            if not path and key in UNPERTURBED_BLOCKS:
                continue
            if str(key).endswith(THICKNESS_KEYS) and thickness_delta_mm != 0.0:
                node[key] = shift(value, where, thickness_delta_mm)
            elif str(key).endswith("width_mm") and width_delta_mm != 0.0:
                node[key] = shift(value, where, width_delta_mm)
            else:
                walk(value, where)

    walk(data, "")
    data.pop("robustness", None)
    for item in data.get("requirements") or []:
        # a print is judged on the plain requirement: the share is over the prints
        if isinstance(item, dict):
            item.pop("robust", None)
    for keys, value in () if checks else SAMPLE_SWITCHES:
        node = data
        for key in keys[:-1]:
            node = node.get(key) if isinstance(node, dict) else None
        if isinstance(node, dict) and keys[-1] in node:
            node[keys[-1]] = value
    for key in SAMPLE_DROPPED:
        data.pop(key, None)
    return data, tuple(changed)


def scatter_design(
    problem: Any, x: np.ndarray, thickness_delta_mm: float, width_delta_mm: float
) -> np.ndarray:
    """The design vector of one sample (see the module docstring).

    Returns
    -------
    (n_var,) float
        In the units of ``problem.space``.
    """
    x = np.array(x, dtype=float)
    problem = as_design_problem(problem)
    own = problem.scatter_design(x.copy(), thickness_delta_mm, width_delta_mm)
    if own is not None:
        out = np.asarray(own, dtype=float)
        if out.shape != x.shape:
            raise TypeError(f"scatter_design() gave shape {out.shape}, expected {x.shape}")
        return out
    variables = problem.variables
    if isinstance(variables, DesignVariables):  # variables on key paths (the mechanism kind)
        for i, targets in enumerate(variables.targets):
            # the key the variable sets moves by the delta: factor * x' + offset = value + delta
            key = next((p for p in reversed(targets[0].path) if isinstance(p, str)), "")
            if key.endswith(THICKNESS_KEYS[0]):
                x[i] += thickness_delta_mm / targets[0].factor
            elif key.endswith("width_mm"):
                x[i] += width_delta_mm / targets[0].factor
        return x
    for i, name in enumerate(problem.space.names):
        lowered = name.lower()
        if "thickness" in lowered:
            x[i] += thickness_delta_mm
        elif "width" in lowered:
            x[i] += width_delta_mm
    return x


def held_state(problem: Any, evaluation: Evaluation) -> dict[str, float]:
    """What the problem solved for the nominal design and a print holds (``{}`` when the
    problem solves nothing per design): see the module docstring."""
    return dict(as_design_problem(problem).held_state(evaluation))


def hold_solved(
    problem: Any, held: Mapping[str, float], thickness_delta_mm: float, width_delta_mm: float
) -> None:
    """Make a sample's problem use the nominal design's solved quantities, moved by the
    scatter, instead of solving them again (an empty ``held`` makes it solve them again: the
    worst-case problem reuses a sample's problem for every design)."""
    as_design_problem(problem).hold_solved(held, thickness_delta_mm, width_delta_mm)


# --------------------------------------------------------------------------------------------
# One sample, as a design problem over the scatter


@dataclass(frozen=True)
class _Outcome:
    """What a sample carries back beside its Evaluation (in ``metrics['robustness']``).

    ``fidelity``: "" (no figure to transfer), ``transferred`` (judged on the nominal design's
    ratios, :mod:`pipeline.robust_fidelity`) or ``re-checked`` (solved again with the checks on:
    near a bound); ``deviation``: a re-checked sample's ``{figure: |ratio / nominal - 1|}``."""

    verdicts: tuple[Verdict, ...]
    table: dict[str, np.ndarray]
    fidelity: str = ""
    deviation: dict[str, float] = field(default_factory=dict)


#: the detail of a row a sample judged on its own checks (its transferred figure was near the bound)
RECHECKED = "re-solved with the checks on: the transferred figure was near the bound"

#: what a sample whose solve did not reach the end of its stroke says (its reason)
UNSOLVED_SAMPLE = "not solved through its stroke"


def unsolved_reason(message: str) -> str:
    """The reason of a sample whose solve stopped part-way (``message``: the solver's)."""
    return f"{UNSOLVED_SAMPLE} ({message or 'did not converge'}): meets no requirement"


def _not_solved(verdict: Verdict, reason: str) -> Verdict:
    """``verdict`` of a sample that did not solve through its stroke: NOT MET, no margin (its
    value over the rows reached is kept, named as such)."""
    return replace(
        verdict,
        met=False,
        margin=math.nan,
        margin_rel=None,
        detail=f"{reason}; {verdict.value:.4g} {verdict.unit} over the rows reached only",
    )


class SampleProblem(DesignProblem):
    """A design problem whose design vector is one sample ``(E_factor, thickness_delta_mm,
    width_delta_mm)`` of a fixed design; picklable, for the parallel backends.

    ``evaluate`` returns one objective, the number of requirements the sample does not meet,
    no constraint, and in ``metrics['robustness']`` the verdicts and the response table; a
    sample that cannot be built or solved comes back failed (it meets nothing).
    """

    objective_names = ("requirements_not_met",)
    constraint_names: tuple[str, ...] = ()

    def __init__(
        self,
        study: Study,
        mode: Literal["design", "study"],
        x: np.ndarray | None,
        held: Mapping[str, float] | None = None,
        transfer: FidelityTransfer | None = None,
        decide: Sequence[str] | None = None,
    ) -> None:
        self.study = study
        self.mode = mode
        self.x = None if x is None else np.asarray(x, dtype=float)
        self.held = dict(held or {})  # solved at the nominal design, held in a sample
        # the nominal design's fidelity ratios: a sample is judged on the verdict's figures
        self.transfer = transfer if transfer else None
        # the requirements whose closeness to a bound re-solves a sample (None: every one; a
        # robust requirement's draws: its own rows, the others are not reported from them)
        self.decide = None if decide is None else tuple(decide)
        self.space = DesignSpace(SAMPLE_COLUMNS, np.array([0.01, -50.0, -50.0]), np.ones(3) * 50)

    def _solve(self, study: Study, dt: float, dw: float) -> tuple[Any, str]:
        """One sample's study solved: its result and why it failed ("" when it did not)."""
        from flexopt.pipeline.problems import build_base_problem, study_result

        if self.mode == "design":
            problem = build_base_problem(study)
            hold_solved(problem, self.held, dt, dw)
            result = problem.detail(scatter_design(problem, self.x, dt, dw))
            return result, result.evaluation.reason if result.evaluation is not None else ""
        result = study_result(study, 1)
        return result, "" if result.converged else (result.message or "did not converge")

    def evaluate(self, s: np.ndarray) -> Evaluation:
        from flexopt.pipeline.verdict import judge_result

        E_factor, dt, dw = (float(v) for v in np.asarray(s, dtype=float).ravel())
        try:
            study, _ = perturb_study(self.study, E_factor, dt, dw)
        except StudyError as exc:  # the sample's study is one the study file could not be
            # (a value outside a variable's bounds): it meets nothing, named in the record
            return Evaluation.failed(
                s, 1, 0, f"the sample cannot be built: {exc.path}: {exc.problem}"
            )
        result, reason = self._solve(study, dt, dw)
        moved: dict[str, float] = {}
        if self.transfer is not None:  # the figures the nominal verdict judges, by its ratios
            result, moved = self.transfer.apply(result)
        # the sample's own study: its printable minimum moved with the print (THICKNESS_KEYS),
        # every other requirement is the verdict's
        verdicts = judge_result(study, result, requirements=sample_requirements(study))
        fidelity, deviation = "", {}
        if moved and self.transfer is not None:
            fidelity = "transferred"
            if self.transfer.decisive(verdicts, moved, self.decide):
                # near a bound the ratio's spread could change the side: judged as made, on
                # its own figures (the same study with the kind's checks on)
                study = perturb_study(self.study, E_factor, dt, dw, checks=True)[0]
                result, reason = self._solve(study, dt, dw)
                deviation = measured_ratios(self.transfer, result)
                verdicts = tuple(
                    replace(v, detail=f"{RECHECKED}; {v.detail}" if v.detail else RECHECKED)
                    if v.model
                    else v
                    for v in judge_result(study, result, requirements=sample_requirements(study))
                )
                fidelity = "re-checked"
            else:
                verdicts = self.transfer.note(verdicts, moved)
        table = dict(result.table)
        if getattr(result, "converged", True) is False:
            # a print whose solve stopped part-way is judged on no rows: its figures over the
            # rows it reached under-read the stroke (#27; the nominal's "solved through the
            # stroke" row, pipeline/stroke_verdict.py)
            reason = unsolved_reason(result.message or reason)
            verdicts = tuple(_not_solved(v, reason) for v in verdicts)
        n_not_met = sum(not v.met for v in verdicts)
        return Evaluation(
            np.asarray(s, dtype=float),
            np.array([float(n_not_met)]),
            np.zeros(0),
            {"robustness": _Outcome(verdicts, table, fidelity, deviation)},
            reason,
        )

    def detail(self, s: np.ndarray) -> Any:
        raise NotImplementedError("a robustness sample has no detail; evaluate it")


# --------------------------------------------------------------------------------------------
# All samples


@dataclass(frozen=True)
class RobustnessResult:
    """The samples of one design, judged.

    Attributes
    ----------
    spec : the ``robustness:`` block.
    samples : (n_samples, 3) rows ``(E_factor, thickness_delta_mm, width_delta_mm)``; row 0 is
        the nominal design.
    perturbed : what a sample changes, in words and key paths.
    names : (n_req,) requirement names, in verdict order.
    nominal : (n_req,) verdicts of the nominal sample.
    met : (n_samples, n_req) bool.
    share_percent : (n_req,) float, %.
    robust : (n_req,) bool, share reaches ``spec.share_percent``.
    worst_margin : (n_req,) float, the smallest margin over the samples (unit of each requirement;
        NaN where a sample gave none).
    band : ``{column: (low, high)}`` per-row min/max over the samples (see
        :func:`optimise.robustness.response_band`).
    nominal_table : the nominal sample's response columns.
    reasons : (n_samples,) why a sample failed, "" when it was solved.
    x, y : the columns to plot (driving quantity, response).
    """

    spec: RobustnessSpec
    samples: np.ndarray
    perturbed: tuple[str, ...]
    names: tuple[str, ...]
    nominal: tuple[Verdict, ...]
    met: np.ndarray
    share_percent: np.ndarray
    robust: np.ndarray
    worst_margin: np.ndarray
    band: dict[str, tuple[np.ndarray, np.ndarray]]
    nominal_table: dict[str, np.ndarray]
    reasons: tuple[str, ...]
    x: str = "displacement_mm"
    y: str = "force_N"
    units: tuple[str, ...] = field(default=())
    target: float | None = None
    tolerance: float | None = None
    #: the verdict rows of the robust requirements (:func:`robust_rows`), judged on fresh samples
    robust_verdicts: tuple[Verdict, ...] = ()
    #: their record (``robust_requirements`` of :meth:`record`), None without robust requirements
    robust_record: dict[str, Any] | None = None
    #: how the samples were judged on the verdict's figures (:func:`_fidelity_record`), None
    #: when the nominal design has no figure above the kind's own model
    fidelity: dict[str, Any] | None = None
    #: (n_samples,) how each sample's figures were judged: "", "transferred", "re-checked"
    judged: tuple[str, ...] = ()

    def with_robust_rows(self, verdicts: Sequence[Verdict]) -> tuple[Verdict, ...]:
        """``verdicts`` with each robust requirement's row after its nominal row."""
        return with_robust_rows(verdicts, self.robust_verdicts)

    @property
    def n_samples(self) -> int:
        return int(len(self.samples))

    def record(self) -> dict[str, Any]:
        """JSON-ready: method, counts, what was perturbed, each requirement's share, the band."""
        spec = self.spec

        def num(v: float) -> float | None:
            return float(v) if math.isfinite(float(v)) else None

        band_cols = [c for c in (self.x, self.y) if c in self.band]
        return {
            "method": spec.method,
            "n_samples": self.n_samples,
            "seed": spec.seed if spec.method == "monte_carlo" else None,
            "scatter": {
                "E_percent": spec.E_percent,
                "thickness_mm": spec.thickness_mm,
                "width_mm": spec.width_mm,
            },
            "share_percent_required": spec.share_percent,
            "n_failed": sum(bool(r) for r in self.reasons),
            "failure": next((r for r in self.reasons if r), ""),
            "objective": spec.objective,
            "perturbed": list(self.perturbed),
            "requirements": [
                {
                    "name": name,
                    "nominal_margin": num(v.margin) if v is not None else None,
                    "nominal_verdict": v.word if v is not None else None,
                    "worst_margin": num(w),
                    "unit": unit,
                    "share_percent": float(share),
                    "met_robustly": bool(ok),
                }
                for name, v, w, unit, share, ok in zip(
                    self.names,
                    self.nominal,
                    self.worst_margin,
                    self.units,
                    self.share_percent,
                    self.robust,
                    strict=True,
                )
            ],
            "samples": [
                {
                    **{c: float(s[i]) for i, c in enumerate(SAMPLE_COLUMNS)},
                    "met": int(row.sum()),
                    "of": int(row.size),
                    "reason": reason,
                    **({"fidelity": how} if how else {}),
                }
                for s, row, reason, how in zip(
                    self.samples,
                    self.met,
                    self.reasons,
                    self.judged or ("",) * len(self.samples),
                    strict=True,
                )
            ],
            "band": {
                c: {
                    "low": [num(v) for v in self.band[c][0]],
                    "high": [num(v) for v in self.band[c][1]],
                }
                for c in band_cols
            },
            **({"fidelity": self.fidelity} if self.fidelity else {}),
            **({"robust_requirements": self.robust_record} if self.robust_record else {}),
        }

    def lines(self) -> list[str]:
        """Console lines: one per requirement with its share of samples."""
        return robustness_lines(self.record())

    def markdown(self, plot_file: str | None = None) -> str:
        """The report's "Robustness" section (Markdown)."""
        return robustness_markdown(self.record(), plot_file)

    def png(self, title: str = "") -> bytes | None:
        """The response with its band (min–max over the samples) around the nominal curve."""
        from flexopt.pipeline.plots import plot_band

        if self.x not in self.band or self.y not in self.band:
            return None
        if self.x not in self.nominal_table or self.y not in self.nominal_table:
            return None
        return plot_band(
            self.nominal_table[self.x],
            self.nominal_table[self.y],
            self.band[self.y][0],
            self.band[self.y][1],
            x=self.x,
            y=self.y,
            title=title,
            note=f"{self.n_samples} samples: {scatter_text(self.record())}",
            target=self.target,
            tolerance=self.tolerance,
        )


def robustness_lines(record: Mapping[str, Any] | None) -> list[str]:
    """Console lines of a robustness record (:meth:`RobustnessResult.record`, or its
    :func:`compact` form): a header, then one line per requirement with its share."""
    if not record:
        return []
    n = record.get("n_samples", 0)
    required = record.get("share_percent_required", 100.0)
    out = [
        f"robustness ({record.get('method')}, {n} samples: {scatter_text(record)}; MET "
        f"robustly at >= {required:g} % of samples):"
    ]
    reqs = record.get("requirements") or []
    width = max((len(r["name"]) for r in reqs), default=0)
    for r in reqs:
        word = "MET" if r["met_robustly"] else "NOT MET"
        k = round(r["share_percent"] * n / 100.0) if n else 0
        out.append(
            f"  {r['name'].ljust(width)}  {r['share_percent']:5.1f} % of samples ({k}/{n})  {word}"
        )
    if not reqs:
        out.append("  (no requirement to judge)")
    if record.get("fidelity"):
        out.append(f"  {fidelity_text(record['fidelity'])}")
    for r in (record.get("robust_requirements") or {}).get("requirements") or []:
        out.append(
            f"  {r['name']} (robust): {r['met_samples']}/{r['verdict_samples']} fresh samples "
            f"met, demonstrated {r['demonstrated_share_percent']:.1f} % (need "
            f"{r['share_percent_required']:g} % at {r['confidence_percent']:g} % confidence)  "
            + ("MET" if r["met"] else "NOT MET")
        )
    return out


def fidelity_text(fidelity: Mapping[str, Any]) -> str:
    """One sentence: how the samples were judged on the nominal verdict's figures (the
    ``fidelity`` of a robustness record, :func:`judge_samples`)."""
    parts = []
    for figure, r in (fidelity.get("ratios") or {}).items():
        if r.get("ratio") is not None:
            parts.append(f"{r['model']} = {r['of']} x {r['ratio']:.5g}")
        elif r.get("ratio_min") is not None:
            parts.append(f"{figure} = {r['of']} x {r['ratio_min']:.5g}-{r['ratio_max']:.5g}")
    band = fidelity.get("recheck_band_percent")
    spread = fidelity.get("ratio_spread_percent")
    if not fidelity.get("samples_transferred") and not fidelity.get("samples_rechecked"):
        # the kind's checks ran in every sample (the gripper's resolved constant-force study)
        return "every sample judged on the verdict's figures of its own: nothing transferred"
    text = (
        "samples judged on the nominal verdict's figures: "
        + "; ".join(parts)
        + " (the nominal design's ratios); "
        + f"{fidelity.get('samples_rechecked', 0)} sample(s) within "
        + (f"{band:g} %" if band is not None else "any distance")
        + " of a bound re-solved with the checks on"
    )
    if spread is not None:
        text += f" (their ratios within {spread:.2g} % of the nominal's)"
    if fidelity.get("rechecked_all"):
        text += "; a ratio moved more than the band: every sample re-solved with the checks on"
    return text


def scatter_text(record: Mapping[str, Any]) -> str:
    scatter = record.get("scatter") or {}
    return ", ".join(
        text.format(scatter[key])
        for key, text in (
            ("E_percent", "E ±{:g} %"),
            ("thickness_mm", "thickness ±{:g} mm"),
            ("width_mm", "width ±{:g} mm"),
        )
        if scatter.get(key)
    )


def robustness_markdown(record: Mapping[str, Any], plot_file: str | None = None) -> str:
    """The report's "Robustness" section from a robustness record (Markdown): what was
    scattered and perturbed, and per requirement the nominal and worst margins, the share of
    samples that meet it and the robust verdict."""
    required = record.get("share_percent_required", 100.0)
    how = f"seed {record.get('seed')}" if record.get("method") == "monte_carlo" else "corners"
    lines = [
        "## Robustness",
        "",
        f"{record.get('n_samples')} samples ({how}, the nominal design included) of "
        f"{scatter_text(record)}. A requirement is MET robustly when at least {required:g} % "
        "of the samples meet it.",
        "",
        "Perturbed: " + "; ".join(record.get("perturbed") or ["nothing"]) + ".",
        "",
        "| requirement | nominal margin | worst margin | share of samples MET | "
        f"robust verdict (at {required:g} %) |",
        "|---|---|---|---|---|",
    ]

    def margin(value: Any, unit: str) -> str:
        if value is None:
            return "n/a"
        return f"{value:+.4g}" + (f" {unit}" if unit else "")

    for r in record.get("requirements") or []:
        lines.append(
            f"| {r['name']} | {margin(r.get('nominal_margin'), r.get('unit', ''))} | "
            f"{margin(r.get('worst_margin'), r.get('unit', ''))} | {r['share_percent']:.1f} % | "
            f"{'MET' if r['met_robustly'] else 'NOT MET'} |"
        )
    if not record.get("requirements"):
        lines.append("| (no requirement to judge) | | | | |")
    if record.get("fidelity"):
        lines += [
            "",
            fidelity_text(record["fidelity"])[0].upper()
            + fidelity_text(record["fidelity"])[1:]
            + ".",
        ]
    if record.get("n_failed"):
        lines += [
            "",
            f"{record['n_failed']} sample(s) could not be solved or built (they meet what their "
            f"verdicts say, a missing value meets nothing), e.g.: {record.get('failure')}",
        ]
    lines += robust_markdown(record)
    if plot_file:
        lines += ["", f"![the response with its band over the samples]({plot_file})"]
    return "\n".join(lines) + "\n"


def compact(record: Mapping[str, Any]) -> dict[str, Any]:
    """A robustness record without its per-sample rows and band (for run.json)."""
    return {k: v for k, v in record.items() if k not in ("samples", "band")}


class WorstCaseProblem(ProblemWrapper):
    """A design problem scored by its worst scatter sample (``robustness.objective: worst``).

    Each design is evaluated at every sample of the block (the problem of the sample's study,
    the design vector moved by :func:`scatter_design`); its objectives and constraints are the
    largest over the samples, row by row (every objective is minimised and every constraint is
    ``g <= 0``, so the largest is the worst), named ``worst_<name>``. A sample that cannot be
    built or solved makes the design failed, with the sample named in the reason. The metrics
    are the nominal sample's, with ``worst_sample`` (the row that set the first objective).

    Cost: ``spec.n_samples`` evaluations per design (2^k + 1 for corners: 9 for E, thickness
    and width). Picklable: the samples' problems are built once per process, on first use.
    """

    def __init__(self, inner: Any, study: Study) -> None:
        spec: RobustnessSpec = study.robustness  # type: ignore[attr-defined]
        super().__init__(as_design_problem(inner))
        # the study the samples perturb (``study`` stays the inner problem's, where the design
        # lives: the gripper's is its resolved constant-force study)
        self.sampled_study = study
        self.samples = samples_of(spec)
        self.objective_names = tuple(f"worst_{n}" for n in inner.objective_names)
        self.constraint_names = tuple(f"worst_{n}" for n in inner.constraint_names)
        self._problems: dict[int, Any] = {}

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_problems": {}}  # rebuilt in each worker

    def _problem(self, row: int) -> Any:
        if row not in self._problems:
            from flexopt.pipeline.problems import build_base_problem

            e, dt, dw = (float(v) for v in self.samples[row])
            study = perturb_study(self.sampled_study, e, dt, dw)[0]
            self._problems[row] = build_base_problem(study)
        return self._problems[row]

    def evaluate(self, x: np.ndarray) -> Evaluation:
        from flexopt.pipeline.parallel import evaluate_one

        x = np.asarray(x, dtype=float)
        evaluations: list[Evaluation] = []
        held: dict[str, float] = {}
        for row, (_, dt, dw) in enumerate(self.samples):
            problem = self.inner if row == 0 else self._problem(row)
            if row > 0:
                hold_solved(problem, held, dt, dw)
            xs = x if row == 0 else scatter_design(problem, x, dt, dw)
            ev = evaluate_one(problem, xs)
            evaluations.append(ev)
            if row == 0:
                held = held_state(self.inner, ev)
            if ev.reason and np.any(ev.f >= INFEASIBLE_VALUE):
                break  # failed: the worst case is this sample's whatever the others give
        f = np.max([ev.f for ev in evaluations], axis=0)
        g = np.max([ev.g for ev in evaluations], axis=0)
        nominal = evaluations[0]
        worst = int(np.argmax([ev.f[0] for ev in evaluations]))
        reason = nominal.reason
        if not reason:
            failed = next((i for i, ev in enumerate(evaluations) if ev.reason), None)
            if failed is not None:
                e, dt, dw = self.samples[failed]
                reason = (
                    f"robustness sample {failed} (E x{e:.3g}, thickness {dt:+.3g} mm, width "
                    f"{dw:+.3g} mm): {evaluations[failed].reason}"
                )
        metrics = {**nominal.metrics, "worst_sample": worst}
        return Evaluation(x, f, g, metrics, reason, sum(ev.time_s for ev in evaluations))

    def detail(self, x: np.ndarray) -> Any:
        detail = self.inner.detail(x)
        return replace(detail, evaluation=self.evaluate(x))


def with_worst_case(study: Study, problem: Any) -> Any:
    """``problem`` scored by its worst sample when ``robustness.objective`` is ``worst``."""
    spec: RobustnessSpec | None = getattr(study, "robustness", None)
    if spec is None or spec.objective != "worst":
        return problem
    return WorstCaseProblem(problem, study)


def _plot_columns(spec: Mapping[str, Any]) -> tuple[str, str]:
    """The band's columns: the plot spec's ``x`` and ``y``
    (:func:`pipeline.plot_targets.plot_spec`)."""
    from flexopt.pipeline.plot_targets import plot_spec

    spec = plot_spec(spec)
    return str(spec["x"]), str(spec["y"])


def _backend_opener() -> Any:
    # The backends are moving from pipeline.parallel to pipeline.backends (issue 14 item 1).
    try:
        from flexopt.pipeline.backends import open_backend  # type: ignore[import-not-found]
    except ImportError:
        from flexopt.pipeline.parallel import open_backend
    return open_backend


def run_robustness(
    study: Study,
    x: np.ndarray | None = None,
    settings: Any = None,
    plot: Mapping[str, Any] | None = None,
    backend: Any = None,
    history: tuple[Any, Evaluation, Sequence[Evaluation]] | None = None,
) -> RobustnessResult | None:
    """Evaluate the study's design at every sample of its ``robustness:`` block.

    Parameters
    ----------
    study : Study
        The nominal study (None is returned when it has no ``robustness:`` block).
    x : (n_var,) float, optional
        The design vector (``flexopt run``'s chosen design). Without it, a kind that is
        optimised takes the study's nominal design; one that is only evaluated takes the study.
    settings : ParallelSettings, optional
        Where the samples run (default: the study's ``parallel:`` block).
    plot : mapping, optional
        The nominal response's plot dict (its ``x`` and ``y``): the band's columns.
    backend : BatchBackend, optional
        Run the samples here instead of opening the backend ``settings`` describe.
    history : (problem, chosen evaluation, every evaluation), optional
        A run's: the robust requirements' record then compares the chosen design with the
        run's nominal optimum (:func:`nominal_optimum`) and judges both on the same samples.

    The study's ``robust:`` requirements are judged on their fresh samples on the same backend
    (``robust_verdicts`` and ``robust_record`` of the result; docs/robustness.md).

    Raises
    ------
    StudyError
        When the study cannot be perturbed at all (its nominal sample is refused).
    """
    spec: RobustnessSpec | None = getattr(study, "robustness", None)
    if spec is None:
        return None
    check_robustness(study)
    from flexopt.pipeline.problems import build_base_problem, nominal_design, parallel_settings
    from flexopt.pipeline.studies import get_kind

    kind = get_kind(study.kind)
    mode: Literal["design", "study"] = "study"
    problem = None
    if kind.problem is not None:
        problem = build_base_problem(study)
        if x is None:
            try:
                x = nominal_design(problem, study)
            except Exception:  # noqa: BLE001 - no design in the study: evaluate the study
                x = None
        mode = "design" if x is not None else "study"
    if mode == "study" and kind.evaluate is None:
        raise StudyError("robustness", f"kind '{study.kind}' has neither a design nor evaluate")
    samples = samples_of(spec)
    perturbed = _describe(study, spec, problem if mode == "design" else None, x)
    held: dict[str, float] = {}
    if mode == "design" and problem is not None and problem.held_scatter:
        held = held_state(problem, problem.evaluate(x))  # one solve: ST for the target
    transfer = nominal_transfer(study, mode, problem, x)
    sample_problem = SampleProblem(study, mode, x, held, transfer)
    settings = settings if settings is not None else parallel_settings(study)
    log.info("robustness: %d samples on %s", len(samples), settings.describe())

    def run_on(batch_problem: SampleProblem, rows: np.ndarray) -> Sequence[Evaluation]:
        if backend is not None:
            return backend(batch_problem, rows)
        # a pool is opened for one problem (its workers hold it): one pool per design sampled
        with _backend_opener()(settings, batch_problem) as opened:
            return opened(batch_problem, rows)

    evaluations, judged = judge_samples(sample_problem, samples, run_on)
    robust_record = _robust_record(study, problem, mode, x, run_on, history, transfer)
    result = _collect(spec, samples, perturbed, evaluations, _plot_columns(plot or {}))
    return replace(
        result,
        **_target_of(plot or {}),
        robust_verdicts=robust_verdict_rows(robust_record),
        robust_record=robust_record,
        fidelity=judged,
    )


def nominal_transfer(
    study: Study, mode: Literal["design", "study"], problem: Any, x: np.ndarray | None
) -> FidelityTransfer | None:
    """The nominal design's fidelity ratios (:func:`~pipeline.robust_fidelity.
    fidelity_transfer`): one solve of the nominal with the study's checks, or None when it has
    no figure above the kind's own model (its checks off: it is judged on that model too)."""
    from flexopt.pipeline.problems import study_result
    from flexopt.pipeline.verdict import figures_of

    if not figures_of(study):  # the kind has one model: nothing to transfer, no solve spent
        return None
    try:
        result = problem.detail(x) if mode == "design" else study_result(study, 1)
    except Exception as exc:  # noqa: BLE001 - the nominal sample names the failure
        log.warning("robustness: the nominal design's checks could not be solved: %s", exc)
        return None
    transfer = fidelity_transfer(study, result)
    return transfer if transfer else None


def judge_samples(
    sample_problem: SampleProblem, rows: np.ndarray, run_on: Any
) -> tuple[list[Evaluation], dict[str, Any] | None]:
    """``sample_problem`` evaluated at ``rows`` (n, 3) through ``run_on(problem, rows)``, and
    how they were judged on the verdict's figures (None without a transfer): the counts of
    transferred and re-checked samples and the largest deviation of a re-checked sample's ratio
    from the nominal's. When that deviation exceeds the re-check band, the band is not earned
    on this design: every transferred sample is solved again with its checks on."""
    evaluations = list(run_on(sample_problem, rows))
    transfer = sample_problem.transfer
    if transfer is None:
        return evaluations, None
    spread = _spread(evaluations)
    everything = False
    if spread > transfer.band_rel:
        again = [i for i, ev in enumerate(evaluations) if _fidelity_of(ev) == "transferred"]
        if again:
            log.warning(
                "robustness: a re-checked sample's fidelity ratio is %.2f %% off the nominal's "
                "(band %.2f %%): every sample re-checked",
                100 * spread,
                100 * transfer.band_rel,
            )
            every = replace(transfer, band_rel=math.inf)
            redo = SampleProblem(
                sample_problem.study, sample_problem.mode, sample_problem.x,
                sample_problem.held, every, sample_problem.decide,
            )  # fmt: skip
            for i, ev in zip(again, run_on(redo, rows[again]), strict=True):
                evaluations[i] = ev
            spread, everything = _spread(evaluations), True
    kinds = [_fidelity_of(ev) for ev in evaluations]
    return evaluations, {
        **transfer.record(),
        "samples_transferred": kinds.count("transferred"),
        "samples_rechecked": kinds.count("re-checked"),
        "ratio_spread_percent": 100.0 * spread if kinds.count("re-checked") else None,
        "rechecked_all": everything,
    }


def _fidelity_of(ev: Evaluation) -> str:
    outcome = ev.metrics.get("robustness") if ev.metrics else None
    return outcome.fidelity if outcome is not None else ""


def _spread(evaluations: Sequence[Evaluation]) -> float:
    """The largest |ratio / nominal ratio - 1| a re-checked sample measured (0 without one)."""
    out = 0.0
    for ev in evaluations:
        outcome = ev.metrics.get("robustness") if ev.metrics else None
        if outcome is not None and outcome.deviation:
            out = max(out, *outcome.deviation.values())
    return out


def _target_of(plot: Mapping[str, Any]) -> dict[str, float | None]:
    """A constant target and its band half-width from a kind's plot dict (else None)."""
    target = plot.get("target")
    if not _is_number(target):
        return {"target": None, "tolerance": None}
    tolerance = plot.get("tolerance")
    if not _is_number(tolerance) and _is_number(plot.get("tolerance_rel")):
        tolerance = abs(float(target)) * float(plot["tolerance_rel"])
    return {
        "target": float(target),
        "tolerance": float(tolerance) if _is_number(tolerance) else None,
    }


def _describe(study: Study, spec: RobustnessSpec, problem: Any, x: np.ndarray | None) -> tuple:
    """What a sample changes: ``E (material.E_MPa)``, the study keys and design variables."""
    e = 1.0 + spec.E_percent / 100.0
    # what a sample changes, in words: read off the data (not validated: a sample moved past a
    # variable's bounds is a failed sample, not a refused study)
    _, changed = _perturbed_data(study, e, spec.thickness_mm, spec.width_mm)
    words = []
    if spec.E_percent:
        where = "material.E_MPa" if "material.E_MPa" in changed else "nothing: no material E"
        words.append(f"E ±{spec.E_percent:g} %: {where}")
    thick = [c for c in changed if c.split("[")[0].endswith(THICKNESS_KEYS)]
    wide = [c for c in changed if c.split("[")[0].endswith("width_mm")]
    if problem is not None and x is not None:
        names = problem.space.names
        dt = scatter_design(problem, x, spec.thickness_mm, 0.0) - np.asarray(x, dtype=float)
        dw = scatter_design(problem, x, 0.0, spec.width_mm) - np.asarray(x, dtype=float)
        thick += [f"design variable {n}" for n, d in zip(names, dt, strict=True) if d != 0]
        wide += [f"design variable {n}" for n, d in zip(names, dw, strict=True) if d != 0]
        for name, which in as_design_problem(problem).held_scatter.items():
            (wide if which == "width" else thick).append(
                f"{name} (solved for the nominal design, then held)"
            )
    if spec.thickness_mm:
        what = ", ".join(thick) if thick else "nothing: no thickness found in this study"
        words.append(f"thickness ±{spec.thickness_mm:g} mm: {what}")
    if spec.width_mm:
        what = ", ".join(wide) if wide else "nothing: no width found in this study"
        words.append(f"width ±{spec.width_mm:g} mm: {what}")
    return tuple(words)


def _collect(
    spec: RobustnessSpec,
    samples: np.ndarray,
    perturbed: tuple[str, ...],
    evaluations: Sequence[Evaluation],
    columns: tuple[str, str],
) -> RobustnessResult:
    outcomes: list[_Outcome | None] = [ev.metrics.get("robustness") for ev in evaluations]
    reference = next((o for o in outcomes if o is not None and o.verdicts), None)
    names = tuple(v.name for v in reference.verdicts) if reference else ()
    units = tuple(v.unit for v in reference.verdicts) if reference else ()
    met = np.zeros((len(samples), len(names)), dtype=bool)
    margins = np.full((len(samples), len(names)), np.nan)
    for i, outcome in enumerate(outcomes):
        if outcome is None:
            continue
        by_name = {v.name: v for v in outcome.verdicts}
        for j, name in enumerate(names):
            v = by_name.get(name)
            if v is not None:
                met[i, j] = bool(v.met)
                margins[i, j] = v.margin
    share = share_met(met) if len(names) else np.zeros(0)
    nominal = outcomes[0]
    nominal_verdicts = {v.name: v for v in nominal.verdicts} if nominal else {}
    with np.errstate(all="ignore"):
        worst = np.array(
            [
                np.nan if np.isnan(margins[:, j]).any() else float(margins[:, j].min())
                for j in range(len(names))
            ]
        )
    return RobustnessResult(
        spec=spec,
        samples=samples,
        perturbed=perturbed,
        names=names,
        nominal=tuple(nominal_verdicts.get(n) for n in names),  # type: ignore[misc]
        met=met,
        share_percent=share,
        robust=met_robustly(share, spec.share_percent),
        worst_margin=worst,
        band=response_band([o.table if o else None for o in outcomes]),
        nominal_table=dict(nominal.table) if nominal else {},
        reasons=tuple(ev.reason for ev in evaluations),
        judged=tuple(o.fidelity if o is not None else "" for o in outcomes),
        x=columns[0],
        y=columns[1],
        units=units,
    )


# --------------------------------------------------------------------------------------------
# Robust requirements (optimise.robust_requirements): the optimiser's constraint on fixed
# samples, the verdict on fresh ones, and what robustness cost


def _sample_words(row: np.ndarray) -> str:
    e, dt, dw = (float(v) for v in row)
    return f"E x{e:.4g}, thickness {dt:+.3g} mm, width {dw:+.3g} mm"


def _scalar_metrics(metrics: Mapping[str, Any]) -> dict[str, Any]:
    """The scalar metrics a requirement's constraint reads (numpy scalars as Python ones)."""
    out: dict[str, Any] = {}
    for key, value in metrics.items():
        if isinstance(value, np.generic):
            value = value.item()
        if value is None or isinstance(value, bool | int | float):
            out[str(key)] = value
    return out


def _failed(ev: Evaluation) -> bool:
    """A design that could not be built or solved (not one that only misses a constraint)."""
    return bool(ev.reason) and bool(np.any(np.asarray(ev.f, dtype=float) >= INFEASIBLE_VALUE))


class RobustConstraints(ProblemWrapper):
    """A design problem holding its ``robust:`` constraints on fixed scatter samples.

    Each robust requirement with ``role: constraint`` adds one row ``robust_<name>``: the
    :func:`~optimise.robust_requirements.kth_constraint` of its per-sample rows over the
    ``spec.n_optimiser`` draws of ``default_rng([seed, 0])`` (the same draws for every design:
    common random numbers), with ``k = spec.k_optimiser``. Every design is evaluated at the
    nominal (the inner problem, whose objectives, constraints and metrics it keeps) and then at
    each draw, one after the other in the worker that evaluates the design, through the same
    runner, store and resume as any evaluation (the wrapper is the run's problem). A draw that
    cannot be built or solved fails every requirement; ``metrics`` count them
    (``robust_failed_samples``) and name the first (``robust_failure``), and carry the share of
    draws that meet each requirement (``robust_<name>_share_percent``).

    Picklable: the draws' problems are built once per process, on first use.
    """

    def __init__(
        self, inner: Any, study: Study, items: Sequence[tuple[Any, RobustShareSpec]]
    ) -> None:
        super().__init__(as_design_problem(inner))
        spec: RobustnessSpec = study.robustness  # type: ignore[attr-defined]
        self.sampled_study = study
        self.items = tuple(items)
        longest: dict[int, int] = {}
        for _, rs in self.items:
            longest[rs.seed] = max(longest.get(rs.seed, 0), rs.n_optimiser)
        self.draws = {
            seed: scatter_draws(
                spec.E_percent, spec.thickness_mm, spec.width_mm, n, seed, GA_STREAM
            )
            for seed, n in longest.items()
        }
        self.n_nominal = len(self.inner.constraint_names)
        self.constraint_names = (
            *self.inner.constraint_names,
            *(f"robust_{req.label}" for req, _ in self.items),
        )
        self._problems: dict[tuple[int, int], Any] = {}

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_problems": {}}  # rebuilt in each worker

    def _problem(self, seed: int, row: int) -> Any:
        """The problem of one draw, or why it cannot be built (a str)."""
        if (seed, row) not in self._problems:
            from flexopt.pipeline.problems import build_base_problem

            e, dt, dw = (float(v) for v in self.draws[seed][row])
            try:
                self._problems[seed, row] = build_base_problem(
                    perturb_study(self.sampled_study, e, dt, dw)[0]
                )
            except StudyError as exc:
                self._problems[seed, row] = f"the sample cannot be built: {exc.path}: {exc.problem}"
        return self._problems[seed, row]

    def _extend(self, x: np.ndarray, nominal: Evaluation) -> Evaluation:
        from flexopt.pipeline.parallel import evaluate_one

        x = np.asarray(x, dtype=float)
        g_nominal = np.asarray(nominal.g, dtype=float)
        if _failed(nominal):  # the nominal design itself failed: so does every row
            extra = np.full(len(self.items), float(np.max(g_nominal, initial=1.0e12)))
            return replace(nominal, g=np.concatenate([g_nominal, extra]))
        held = held_state(self.inner, nominal)
        rows: dict[int, np.ndarray] = {}
        n_failed, first, time_s = 0, "", float(nominal.time_s)
        for seed, draws in self.draws.items():
            g = np.full((len(draws), len(self.items)), MISSING_CONSTRAINT)
            for row, (_, dt, dw) in enumerate(draws):
                problem = self._problem(seed, row)
                reason = problem if isinstance(problem, str) else ""
                if not reason:
                    hold_solved(problem, held, dt, dw)
                    ev = evaluate_one(problem, scatter_design(problem, x, dt, dw))
                    time_s += float(ev.time_s)
                    if _failed(ev):
                        reason = ev.reason
                    else:
                        metrics = _scalar_metrics(ev.metrics)
                        g[row] = [req.constraint(metrics) for req, _ in self.items]
                if reason:
                    n_failed += 1
                    first = first or f"sample {row} ({_sample_words(draws[row])}): {reason}"
            rows[seed] = g
        extra = np.empty(len(self.items))
        metrics = dict(nominal.metrics)
        for j, (req, rs) in enumerate(self.items):
            g = rows[rs.seed][: rs.n_optimiser, j]
            extra[j] = kth_constraint(g, rs.k_optimiser)
            metrics[f"robust_{req.label}_share_percent"] = 100.0 * float(np.mean(g <= 0.0))
        metrics["robust_failed_samples"] = n_failed
        metrics["robust_failure"] = first
        return replace(
            nominal, g=np.concatenate([g_nominal, extra]), metrics=metrics, time_s=time_s
        )

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return self._extend(x, self.inner.evaluate(x))

    def detail(self, x: np.ndarray) -> Any:
        detail = self.inner.detail(x)
        nominal = detail.evaluation if detail.evaluation is not None else self.inner.evaluate(x)
        return replace(detail, evaluation=self._extend(x, nominal))


def with_robust_constraints(study: Study, problem: Any) -> Any:
    """``problem`` holding the study's ``robust:`` requirements of ``role: constraint``
    (:class:`RobustConstraints`), or itself when there is none."""
    from flexopt.pipeline.verdict import robust_items

    items = [(req, rs) for req, rs in robust_items(study) if req.role == "constraint"]
    if not items:
        return problem
    return RobustConstraints(problem, study, items)


def nominal_constraints(problem: Any) -> int | None:
    """How many of ``problem``'s constraint rows are the nominal design's (the rows before the
    robust ones), or None when no :class:`RobustConstraints` is in its chain of wrappers."""
    while problem is not None:
        if isinstance(problem, RobustConstraints):
            return problem.n_nominal
        problem = problem.__dict__.get("inner") if hasattr(problem, "__dict__") else None
    return None


def nominal_optimum(problem: Any, solved: Sequence[Evaluation]) -> Evaluation | None:
    """The best design of a run that meets every nominal constraint, its robust rows ignored
    (the first objective, the lowest), or None (no robust constraint, or none such)."""
    n = nominal_constraints(problem)
    if n is None:
        return None
    ok = [
        ev
        for ev in solved
        if not ev.reason
        and np.all(np.isfinite(ev.f))
        and bool(np.all(np.asarray(ev.g, dtype=float)[:n] <= 0.0))
    ]
    return min(ok, key=lambda ev: float(ev.f[0])) if ok else None


def _cost_figures(problem: Any, ev: Evaluation, quantities: Sequence[str]) -> dict[str, Any]:
    """What a design costs: its variables, objectives and the metrics robustness moves."""
    metrics = _scalar_metrics(ev.metrics)
    wanted = ["mass_g", "volume_mm3", *quantities]
    wanted += [m for m in metrics if "stress" in m and m.endswith("_MPa")]
    wanted += [m for m in metrics if m.startswith("robust_") and m.endswith("_share_percent")]
    return {
        "parameters": dict(zip(problem.space.names, map(float, ev.x), strict=True)),
        "objectives": dict(zip(problem.objective_names, map(float, ev.f), strict=True)),
        "metrics": {m: metrics[m] for m in dict.fromkeys(wanted) if metrics.get(m) is not None},
    }


def _verdict_draws(
    study: Study, items: Sequence[tuple[Any, RobustShareSpec]]
) -> dict[int, np.ndarray]:
    """``{seed: (n, 3) draws}`` of the verdict's stream, the longest each seed's items need."""
    spec: RobustnessSpec = study.robustness  # type: ignore[attr-defined]
    longest: dict[int, int] = {}
    for _, rs in items:
        longest[rs.seed] = max(longest.get(rs.seed, 0), rs.n_verdict)
    return {
        seed: scatter_draws(
            spec.E_percent, spec.thickness_mm, spec.width_mm, n, seed, VERDICT_STREAM
        )
        for seed, n in longest.items()
    }


def _shares(
    items: Sequence[tuple[Any, RobustShareSpec]],
    draws: Mapping[int, np.ndarray],
    evaluations: Mapping[int, Sequence[Evaluation]],
) -> list[dict[str, Any]]:
    """Each robust requirement judged on its draws' evaluations: met count, demonstrated share,
    worst margin, the failed samples."""
    out = []
    for req, rs in items:
        n = rs.n_verdict
        met, margins, failures = 0, [], []
        models: dict[str, int] = {}
        fidelity = {"transferred": 0, "re-checked": 0}
        for row, ev in enumerate(evaluations[rs.seed][:n]):
            outcome = ev.metrics.get("robustness") if ev.metrics else None
            verdict = None
            if outcome is not None:
                verdict = next((v for v in outcome.verdicts if v.name == req.label), None)
            if verdict is not None and verdict.model:  # judged on one of several figures
                models[verdict.model] = models.get(verdict.model, 0) + 1
                if outcome.fidelity in fidelity:
                    fidelity[outcome.fidelity] += 1
            if verdict is None or ev.reason:  # not built, not solved, or solved part-way
                why = ev.reason or "the requirement was not judged"
                failures.append(f"sample {row} ({_sample_words(draws[rs.seed][row])}): {why}")
            if verdict is None:
                margins.append(math.nan)
                continue
            met += bool(verdict.met)
            margins.append(float(verdict.margin))
        shown = demonstrated_share(met, n, rs.confidence_percent)
        finite = [m for m in margins if math.isfinite(m)]
        out.append(
            {
                "name": req.label,
                "quantity": req.quantity,
                "unit": req.unit,
                "role": req.role,
                "share_percent_required": rs.share_percent,
                "confidence_percent": rs.confidence_percent,
                "seed": rs.seed,
                "verdict_samples": n,
                "met_samples": met,
                "point_share_percent": 100.0 * met / n,
                "demonstrated_share_percent": shown,
                "met": bool(shown >= rs.share_percent - 1e-9),
                "worst_margin": min(finite) if len(finite) == n else None,
                "n_failed": len(failures),
                "failure": failures[0] if failures else "",
                # the model each sample's figure came from, and how (pipeline.robust_fidelity)
                "judged_on": models,
                "transferred_samples": fidelity["transferred"],
                "rechecked_samples": fidelity["re-checked"],
                "optimiser": (
                    {
                        "samples": rs.n_optimiser,
                        "required": rs.k_optimiser,
                        "demonstrates_percent": demonstrated_share(
                            rs.k_optimiser, rs.n_optimiser, rs.confidence_percent
                        ),
                    }
                    if req.role == "constraint"
                    else None
                ),
            }
        )
    return out


def robust_verdict_rows(record: Mapping[str, Any] | None) -> tuple[Verdict, ...]:
    """The verdict rows of a ``robust_requirements`` record: one per robust requirement, MET
    when the share its fresh samples demonstrate reaches the required share."""
    rows = []
    for r in (record or {}).get("requirements") or []:
        p, c, n = r["share_percent_required"], r["confidence_percent"], r["verdict_samples"]
        shown = float(r["demonstrated_share_percent"])
        detail = f"{r['met_samples']} of {n} fresh samples met ({r['point_share_percent']:.1f} %)"
        if r.get("optimiser"):
            o = r["optimiser"]
            detail += f"; the optimiser held {o['required']} of its {o['samples']} samples"
        if r.get("n_failed"):
            detail += f"; {r['n_failed']} sample(s) failed, e.g. {r['failure']}"
        detail += judged_on_text(r)
        rows.append(
            Verdict(
                name=f"{r['name']} (robust)",
                quantity="share_of_prints_percent",
                value=shown,
                bound=f">= {p:g} % of prints ({c:g} % confidence, {n} samples)",
                margin=shown - p,
                margin_rel=(shown - p) / p,
                met=bool(r["met"]),
                unit="%",
                role=r.get("role", "check"),
                detail=detail,
            )
        )
    return tuple(rows)


def judged_on_text(r: Mapping[str, Any]) -> str:
    """ "; judged on <model>: n transferred ..., m re-checked ..." for a robust requirement's
    record ``r`` whose samples were judged on one of several figures, else ""."""
    models = r.get("judged_on") or {}
    if not models:
        return ""
    return (
        f"; judged on {', '.join(models)}: {r.get('transferred_samples', 0)} samples by the "
        "nominal design's ratio to the kind's own model, "
        f"{r.get('rechecked_samples', 0)} near the bound re-solved with the checks on"
    )


def with_robust_rows(verdicts: Sequence[Verdict], robust: Sequence[Verdict]) -> tuple[Verdict, ...]:
    """``verdicts`` with each robust row right after the row of its requirement (at the end
    when that row is missing)."""
    out = list(verdicts)
    for row in robust:
        base = row.name.removesuffix(" (robust)")
        at = next((i for i, v in enumerate(out) if v.name == base), None)
        out.insert(len(out) if at is None else at + 1, row)
    return tuple(out)


def _robust_record(
    study: Study,
    problem: Any,
    mode: Literal["design", "study"],
    x: np.ndarray | None,
    run_backend: Any,
    history: tuple[Any, Evaluation, Sequence[Evaluation]] | None,
    transfer: FidelityTransfer | None = None,
) -> dict[str, Any] | None:
    """The ``robust_requirements`` record: each robust requirement of ``study`` judged on fresh
    samples of the design ``x``; with a run's ``history`` (its problem, its chosen evaluation,
    every evaluation), the nominal optimum judged on the same samples and the cost of
    robustness. ``run_backend(sample_problem, rows)`` evaluates sample rows (a backend opened
    for that problem: a process pool's workers hold the problem they were started with)."""
    from flexopt.pipeline.verdict import robust_items

    items = robust_items(study)
    if not items:
        return None
    draws = _verdict_draws(study, items)
    seeds = list(draws)
    decide = tuple(req.label for req, _ in items)  # what these draws are judged for
    rows = np.vstack([draws[s] for s in seeds])

    fidelity: dict[str, Any] = {}

    def judged(sample_problem: SampleProblem, key: str = "chosen") -> list[dict[str, Any]]:
        evaluations, how = judge_samples(sample_problem, rows, run_backend)
        if how is not None:
            fidelity[key] = how
        by_seed, start = {}, 0
        for s in seeds:
            by_seed[s] = evaluations[start : start + len(draws[s])]
            start += len(draws[s])
        return _shares(items, draws, by_seed)

    held: dict[str, float] = {}
    if mode == "design" and problem is not None and problem.held_scatter:
        held = held_state(problem, problem.evaluate(x))
    record: dict[str, Any] = {
        "sampling": "uniform within the ± band of robustness:, fresh draws "
        "(default_rng([seed, 1])); the optimiser's were default_rng([seed, 0])",
        "requirements": judged(SampleProblem(study, mode, x, held, transfer, decide)),
    }
    if history is not None:
        run_problem, best, solved = history
        reference = nominal_optimum(run_problem, solved)
        quantities = [req.quantity for req, _ in items]
        cost: dict[str, Any] = {
            "reference": "the best design this run evaluated that meets every nominal "
            "constraint, its robust rows ignored",
            "robust_optimum": _cost_figures(run_problem, best, quantities),
            # the chosen design holds every constraint, robust rows included (else it is only
            # the least infeasible design of the run: no robust optimum to compare)
            "robust_feasible": bool(best.feasible),
        }
        if reference is None:
            cost["nominal_optimum"] = None
        else:
            cost["nominal_optimum"] = _cost_figures(run_problem, reference, quantities)
            same = np.array_equal(np.asarray(reference.x), np.asarray(best.x))
            cost["same_design"] = bool(same)
            if not same and problem is not None:
                held_ref: dict[str, float] = {}
                if problem.held_scatter:
                    held_ref = held_state(problem, problem.evaluate(reference.x))
                shares = judged(
                    SampleProblem(
                        study, "design", reference.x, held_ref,
                        nominal_transfer(study, "design", problem, reference.x), decide,
                    ),
                    "nominal_optimum",
                )  # fmt: skip
                cost["nominal_optimum"]["robust"] = [
                    {
                        k: s[k]
                        for k in (
                            "name",
                            "met_samples",
                            "verdict_samples",
                            "point_share_percent",
                            "demonstrated_share_percent",
                            "met",
                        )
                    }  # fmt: skip
                    for s in shares
                ]
        record["cost"] = cost
    if fidelity:
        record["fidelity"] = fidelity
    return record


def _fmt(value: Any, unit: str = "") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    if isinstance(value, bool):
        return "yes" if value else "no"
    text = f"{value:.4g}" if isinstance(value, int | float) else str(value)
    return f"{text} {unit}" if unit else text


def robust_tables(
    record: Mapping[str, Any] | None,
) -> list[tuple[str, list[str], list[list[str]], str]]:
    """The robust requirements of a robustness record as tables, ``(title, header, rows,
    note)`` each: the verdict on fresh samples, and what robustness cost against the nominal
    optimum (for report.md and report.html alike)."""
    rr = (record or {}).get("robust_requirements")
    if not rr:
        return []
    cost = rr.get("cost") or {}
    nominal = cost.get("nominal_optimum") or {}
    by_name = {r["name"]: r for r in nominal.get("robust") or []}
    same = cost.get("same_design")
    rows = []
    for r in rr.get("requirements") or []:
        o = r.get("optimiser")
        held = (
            f"{o['required']} of {o['samples']} (demonstrates {o['demonstrates_percent']:.1f} %)"
            if o
            else "not a constraint"
        )
        ref = by_name.get(r["name"])
        if ref is not None:
            ref_text = (
                f"{ref['met_samples']}/{ref['verdict_samples']} met "
                f"({ref['point_share_percent']:.1f} %), demonstrated "
                f"{ref['demonstrated_share_percent']:.1f} %: {'MET' if ref['met'] else 'NOT MET'}"
            )
        else:
            ref_text = "the same design" if same else "n/a"
        rows.append(
            [
                r["name"],
                f"{r['share_percent_required']:g} % at {r['confidence_percent']:g} % confidence",
                held,
                f"{r['met_samples']}/{r['verdict_samples']} ({r['point_share_percent']:.1f} %)",
                f"{r['demonstrated_share_percent']:.1f} %",
                "MET" if r["met"] else "NOT MET",
                ref_text,
            ]
        )
    failed = [r for r in rr.get("requirements") or [] if r.get("n_failed")]
    note = (
        "A requirement is MET robustly when the share of prints its fresh samples demonstrate "
        "(the one-sided Clopper-Pearson lower bound at the stated confidence) reaches the "
        "required share; the optimiser held it on fixed samples of its own (common to every "
        "design), which cannot be the evidence for the design they chose."
    )
    if failed:
        note += " " + "; ".join(
            f"{r['name']}: {r['n_failed']} sample(s) failed (counted as not met), e.g. "
            f"{r['failure']}"
            for r in failed
        )
    out = [
        (
            "Robust requirements",
            [
                "requirement",
                "required",
                "optimiser held (of its samples)",
                "fresh samples met",
                "demonstrated share",
                "verdict",
                "nominal optimum",
            ],
            rows,
            note,
        )  # fmt: skip
    ]
    if cost:
        robust = cost.get("robust_optimum") or {}
        names: list[tuple[str, str]] = []
        for group in ("objectives", "metrics"):
            for key in {**(nominal.get(group) or {}), **(robust.get(group) or {})}:
                if all(key != k for _, k in names):  # an objective that is also a metric: once
                    names.append((group, key))
        crows = []
        for group, key in names:
            a = (nominal.get(group) or {}).get(key)
            b = (robust.get(group) or {}).get(key)
            change = "n/a"
            if isinstance(a, int | float) and isinstance(b, int | float):
                change = f"{b - a:+.4g}" + (f" ({(b - a) / abs(a) * 100:+.1f} %)" if a else "")
            crows.append([key, _fmt(a), _fmt(b), change])
        if not nominal:
            what = "no design of this run met the nominal constraints: nothing to compare"
        elif cost.get("robust_feasible") is False:
            what = (
                "no design of this run held every constraint, robust rows included: the chosen "
                "one is the least infeasible, not a robust optimum (a longer run may find one)"
            )
        elif same:
            what = "the nominal optimum of this run is the robust one: robustness cost nothing"
        else:
            what = f"nominal optimum: {cost.get('reference')}"
        out.append(
            (
                "What robustness cost",
                ["figure", "nominal optimum", "robust optimum", "change"],
                crows,
                what,
            )  # fmt: skip
        )
    return out


def robust_markdown(record: Mapping[str, Any] | None) -> list[str]:
    """report.md lines of :func:`robust_tables` (empty without robust requirements)."""
    lines: list[str] = []
    for title, header, rows, note in robust_tables(record):
        lines += ["", f"### {title}", "", "| " + " | ".join(header) + " |"]
        lines.append("|" + "---|" * len(header))
        lines += ["| " + " | ".join(row) + " |" for row in rows]
        lines += ["", note]
    return lines
