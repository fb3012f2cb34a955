"""Study kind ``mechanism``: any planar compliant mechanism as data, optimised from YAML alone.

Beams (polylines or generated curves, thickness per point, width per beam or shared), rigid
bodies (outline and reference point), joints (a beam end to the ground, a body or another beam
end; clamped or pinned), load cases (one drive each: a body or beam end moved, turned or loaded,
the other motions held or free, plus supports of that case), named outputs read from the
solution (reactions, displacements, rotations, peak stress, and their slopes and ratios),
design variables on any numeric key of the geometry (:mod:`optimise.variables`), objectives
chosen from the outputs, and requirements judged MET / NOT MET (:mod:`optimise.requirements`).
The physics is :mod:`fea.mechanism` (geometrically exact beams tied by constraints); the
printable part is :mod:`geometry.mechanism`. The full key reference is ``docs/mechanism.md``.

The study file's models and their translation to the solver's inputs are
pipeline/studies/_mechanism_schema.py, its refusals across keys _mechanism_check.py; the
physics of a design around the solver is :mod:`fea.mechanism_design`, its scoring
:mod:`optimise.mechanism_objectives`, the check of its exported outline _mechanism_fidelity.py.
The example studies: pipeline/examples/parallel-guide.yaml and the other mechanism examples.

Metric names (what requirements and objectives name): per output ``o`` of a load case,
``max_o``, ``min_o``, ``max_abs_o``, ``mean_o`` (over the converged rows), ``end_o`` (last
row), ``start_o`` (row 0) and ``first_peak_o`` (the first local maximum along the drive: a
snap-through force; None when the curve has none); with more than
one load case each is prefixed by the case name and a dot (``blocked.max_jaw_force_N``). Per
case ``stable_positions`` (zero crossings of the drive reaction with positive stiffness, the
undeformed state included) and ``second_stable_position_<unit>``; overall ``mass_g``,
``max_peak_stress_MPa``, ``stress_yield_ratio``, ``width_mm``, ``min_thickness_mm``.

A design whose geometry is invalid (crossing beams, a beam below the printable minimum, a part
in pieces) or whose solve does not converge is an infeasible evaluation with that reason.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping
from typing import Any

import flexopt.pipeline.studies._mechanism_stops as stops
import numpy as np
from flexopt.fea import mechanism_design as design
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mechanism_fields import solved_vtu
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.mechanism import AsMadeBeam, MechanismOutline
from flexopt.optimise import mechanism_objectives as scoring
from flexopt.optimise.durability import LIFE_QUANTITIES
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.mechanism_objectives import STATS
from flexopt.optimise.mechanism_objectives import verdict_json as _verdict_json
from flexopt.optimise.problem import DesignProblem, DesignResult
from flexopt.optimise.requirements import MinFeature, Range, Requirement, TargetBand, Verdict
from flexopt.optimise.space import DesignSpace
from flexopt.optimise.variables import DesignVariables, VariableError, resolve_variables
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.studies._mechanism_check import (
    check_choices,
    check_references,
    fea_refusal,
    geometry_path,
)
from flexopt.pipeline.studies._mechanism_driven_end import driven_end_verdicts
from flexopt.pipeline.studies._mechanism_fidelity import annotate, with_fidelity
from flexopt.pipeline.studies._mechanism_gradient import mechanism_jacobian
from flexopt.pipeline.studies._mechanism_joints import joint_verdicts
from flexopt.pipeline.studies._mechanism_result import (
    Solved,
    case_responses,
    design_files,
    design_info,
    response_plot,
)
from flexopt.pipeline.studies._mechanism_schema import (
    MechanismGeometry,
    MechanismStudy,
    ObjectiveSpec,
    build_load_case,
    build_mechanism,
    build_outline,
    build_outputs,
    case_prefix,
    output_columns,
    outputs_in,
)
from flexopt.pipeline.studies._mechanism_slenderness import slenderness_verdicts
from flexopt.pipeline.studies._mechanism_width import width_key
from flexopt.pipeline.study import material_record
from flexopt.pipeline.verdict import envelope_values, with_design_range
from pydantic import ValidationError

#: the study file's models are _mechanism_schema's (MechanismStudy, MechanismGeometry, ...)
__all__ = ["MechanismProblem", "MechanismStudy", "check", "problem"]

# --------------------------------------------------------------------------------------------
# From the study to the solver


def _fea():
    # the engine, imported late so the kind always registers
    import flexopt.fea.mechanism as fm

    return fm


_prefix = case_prefix  # (the metric builders below read it by this name)


def metric_names(study: MechanismStudy) -> tuple[str, ...]:
    """Every scalar metric a design of ``study`` reports (what requirements may name)."""
    names = {"mass_g", "max_peak_stress_MPa", "stress_yield_ratio", "width_mm"}
    names |= {"min_clearance_mm", "interference_mm2"}
    names |= {"envelope_width_mm", "envelope_height_mm", "envelope_depth_mm"}  # as exported
    names |= {"min_thickness_mm", "stable", "unstable_rows"}
    for case, spec in study.load_cases.items():
        p = _prefix(study, case)
        unit = spec.drive.unit
        names |= {f"{p}stable_positions", f"{p}second_stable_position_{unit}"}
        names |= {f"{p}max_peak_stress_MPa"}
        for o in outputs_in(study, case):
            names |= {f"{p}{s}_{o}" for s in STATS}
    return tuple(sorted(names | stops.metric_names(study)))


def column_names(study: MechanismStudy) -> tuple[str, ...]:
    """Response columns (judged by their worst value, or as curves by target requirements)."""
    names = set()
    for case, spec in study.load_cases.items():
        p = _prefix(study, case)
        names |= {f"{p}drive_{spec.drive.unit}", f"{p}peak_stress_MPa"}
        names |= {f"{p}{o}" for o in outputs_in(study, case)}
    return tuple(sorted(names | stops.column_names(study)))


def quantities(study: MechanismStudy) -> tuple[str, ...]:
    """The names a ``requirements:`` item may judge (the life's with a ``duty_cycle:``)."""
    life = LIFE_QUANTITIES if study.duty_cycle is not None else ()
    return tuple(sorted(set(metric_names(study)) | set(column_names(study)) | set(life)))


def _requirements(study: MechanismStudy) -> list[Requirement]:
    out = []
    for i, spec in enumerate(study.requirements):
        table = columns = None
        if spec.target is not None and spec.target.kind == "table" and spec.target.file:
            from flexopt.pipeline.targets import read_table_csv  # a target table's file

            table, columns = read_table_csv(
                spec.target.file, spec.target.columns, f"requirements[{i}].target.file"
            )
        try:
            out.append(spec.to_requirement(study.material.yield_MPa, table, columns))
        except OptimiseError as exc:
            raise StudyError(f"requirements[{i}]", str(exc)) from None
    return out


def _solved_size_requirements(study: MechanismStudy) -> list[Requirement]:
    """Built in (issue 22): a solved width inside its range, else at least printable."""
    spec = study.solve_width_from
    if spec is None:
        return []
    if spec.range_mm is not None:
        return [Range("width_mm", "solved width in its range", "check", *spec.range_mm)]
    lo = study.geometry.min_feature_mm
    return [MinFeature("width_mm", "solved width printable", "check", lo)]


def _root(study: MechanismStudy) -> dict[str, Any]:
    return {"geometry": study.geometry.model_dump(mode="json", exclude_none=True)}


def _variables(study: MechanismStudy) -> DesignVariables | None:
    if not study.variables:
        return None
    try:
        return resolve_variables(study.variables, _root(study))
    except VariableError as exc:
        raise StudyError(exc.path, exc.problem) from None


def check(study: MechanismStudy) -> None:
    """Every refusal with its key path before any run folder exists: parts named by joints,
    drives, supports and outputs; output units; variables; requirements and objectives; the
    initial design's geometry (printable, one body) and a free rigid-body motion in any case."""
    check_references(study)
    check_choices(study, _requirements(study), quantities(study), metric_names(study))
    variables = _variables(study)
    x0 = variables.initial if variables is not None else None
    geometry = _geometry_of(study, x0)
    try:
        _, outline = build_outline(geometry)
    except GeometryError as exc:
        where = geometry_path(str(exc))
        raise StudyError(where, f"the initial design is not buildable: {exc}") from None
    mech = _mechanism(study, geometry, made=outline.beams)
    for case in study.load_cases:
        try:
            _fea().check_mechanism(mech, build_load_case(study, case))
        except FeaError as exc:
            raise stops.refusal(study, str(exc)) or fea_refusal(case, str(exc)) from None


def _geometry_of(study: MechanismStudy, x: np.ndarray | None) -> MechanismGeometry:
    """The validated geometry of a design (``x`` None: the study's own)."""
    variables = _variables(study) if x is not None else None
    if variables is None:
        return study.geometry
    raw = variables.apply(_root(study), x)["geometry"]
    return MechanismGeometry.model_validate(raw)


def _mechanism(
    study: MechanismStudy,
    geometry: MechanismGeometry,
    width_mm: float | None = None,
    made: Mapping[str, AsMadeBeam] | None = None,
):
    """The solver's mechanism (:func:`build_mechanism`; ``made``: the beams as made) with the
    study's stops."""
    mech = build_mechanism(geometry, study.material.to_material(), width_mm, made)
    return stops.with_stops(mech, study)


# --------------------------------------------------------------------------------------------
# One design


def _case_table(
    study: MechanismStudy,
    case: str,
    response: Any,
    scale: float,
    made: Mapping[str, AsMadeBeam] | None = None,
) -> dict[str, np.ndarray]:
    """The case's response as columns (forces scaled by ``scale`` = width / reference width);
    with ``made`` the stresses are the beams' as made."""
    control = study.load_cases[case].drive.control
    table = design.case_table(control, output_columns(study, case), response, scale, made)
    return {**table, **stops.columns(study, case, response, scale)}


def _solve_printed_path(study: MechanismStudy, mech: Any, case: str) -> Any:
    """The case solved along the path the printed part follows (issue 22, item 3;
    :func:`fea.mechanism_design.solve_printed_path`)."""
    load_case, outputs = build_load_case(study, case), build_outputs(study, case)
    unit = study.load_cases[case].drive.unit
    settings = stops.settings(study)  # None without stops: the solver's defaults
    return design.solve_printed_path(
        mech, load_case, outputs, study.imperfection_mm, unit, settings
    )


def _as_the_optimiser_judges(study: MechanismStudy, solved: Solved) -> Solved:
    """``solved`` with its peak stresses times ``fidelity.beam_stress_factor``: the optimiser
    solves every design with the beam model, and the reported design's check of its exported
    outline finds the peak a few % higher (the verdict reads the larger figure,
    :func:`~pipeline.studies._mechanism_fidelity.with_fidelity`), so the optimiser holds the
    beam model's stress times the ratio measured on the study's designs. Only the optimiser's
    evaluations (evaluations.csv) carry the factor; the reported design is the check's."""
    factor = float(study.fidelity.beam_stress_factor)
    if factor == 1.0 or not study.fidelity.enabled:
        return solved
    metrics, tables = scoring.with_stress_factor(solved.metrics, solved.tables, factor)
    return dataclasses.replace(
        solved, metrics=metrics, tables=tables, curves_table=_curves_table(study, tables)
    )


def _part_metrics(
    study: MechanismStudy,
    geometry: MechanismGeometry,
    outline: MechanismOutline,
    tables: Mapping[str, Mapping[str, np.ndarray]],
    width_mm: float,
    material: Material,
    clearance: Mapping[str, Any],
) -> dict[str, Any]:
    """Every metric of the part as made at ``width_mm``: :func:`_metrics` of its tables, the
    interference over the stroke (``clearance``: :func:`fea.mechanism_design.interference`) and
    the envelope as exported. One place for the solve and for the check of the exported
    outline, which solves the width again."""
    metrics = _metrics(study, geometry, tables, width_mm, material, outline.beams)
    metrics["min_clearance_mm"] = clearance["min_clearance_mm"]
    metrics["interference_mm2"] = clearance["interference_mm2"]
    metrics.update(envelope_values(outline.polygon, width_mm))  # the part as exported
    return metrics


def _metrics(
    study: MechanismStudy,
    geometry: MechanismGeometry,
    tables: Mapping[str, Mapping[str, np.ndarray]],
    width_mm: float,
    material: Material,
    made: Mapping[str, AsMadeBeam] | None = None,
) -> dict[str, Any]:
    """The metrics of the tables (:func:`optimise.mechanism_objectives.response_metrics`) with
    the part's width, thinnest beam and mass (beams as ``made``, bodies ``width_mm`` deep)."""
    drives = {c: study.load_cases[c].drive for c in tables}
    cases = {
        c: (_prefix(study, c), d.control, d.unit, outputs_in(study, c)) for c, d in drives.items()
    }
    mass = _fea().mass_g(_mechanism(study, geometry, width_mm, made), body_thickness_mm=width_mm)
    part = {
        "width_mm": float(width_mm),
        "min_thickness_mm": float(min(np.min(b.thickness()) for b in geometry.beams.values())),
        "mass_g": float(mass) if math.isfinite(mass) else None,
    }
    return scoring.response_metrics(tables, cases, material.yield_MPa, part)


def _curves_table(
    study: MechanismStudy, tables: Mapping[str, Mapping[str, np.ndarray]]
) -> dict[str, np.ndarray]:
    return scoring.curves_table(tables, {case: _prefix(study, case) for case in tables})


def _solve_width(
    study: MechanismStudy,
    req: Requirement,
    ref_tables: Mapping[str, Mapping[str, np.ndarray]],
    ref_width: float,
) -> tuple[float, str]:
    """The width that puts a force-like requirement in the middle of its bound, and why not."""
    if isinstance(req, Range):
        material = study.material.to_material()
        metrics = _metrics(study, study.geometry, ref_tables, ref_width, material)
        value = metrics.get(req.quantity)
        return design.width_for_range(req.quantity, value, req.minimum, req.maximum, ref_width)
    assert isinstance(req, TargetBand)
    reference = _curves_table(study, ref_tables)
    x, y = reference.get(req.x), reference.get(req.quantity)
    if x is None or y is None:
        return math.nan, f"no {req.quantity}({req.x}) to solve the width from"
    target = req.target_at  # the target (a function of x) in the column's unit
    relative = req.tolerance_rel is not None
    return design.width_for_target(req.quantity, x, y, target, req.over, relative, ref_width)


class MechanismProblem(DesignProblem):
    """The :class:`optimise.DesignProblem` of a ``mechanism`` study (picklable, deterministic,
    never raises for a bad design). A study without ``variables:`` is one design: its space
    has no variables, ``flexopt evaluate`` solves it and ``flexopt run`` refuses it
    (:meth:`initial_designs`)."""

    #: case -> MechanismResponse used instead of solving (the Jacobian's linearised responses)
    given_responses: Mapping[str, Any] | None = None

    def warm_up(self) -> None:
        """Load the compiled beam, constrained-beam and mechanism kernels (a pool calls this
        before it forks its workers, :func:`pipeline.backends.open_backend`)."""
        from flexopt.fea.mechanism import warm_up

        warm_up()  # calls fea.constrained_beams.warm_up (and so fea.beam's) first

    def __init__(self, study: MechanismStudy) -> None:
        self.variables = _variables(study)
        none = np.zeros(0)
        self.space: DesignSpace = (
            self.variables.space if self.variables is not None else DesignSpace((), none, none)
        )
        self.study = study
        self.material = study.material.to_material()
        self.requirements = _requirements(study) + _solved_size_requirements(study)
        self.requirements += stops.requirements(study)
        self.labels = {r.label: r for r in self.requirements}
        objectives = list(study.objectives) or self._default_objectives()
        self.objectives = tuple(o.key for o in objectives)
        self.objective_names = tuple(
            scoring.objective_name(k, n, self.labels) for k, n in self.objectives
        )
        self.constraints = scoring.curve_constraints(self.requirements)
        self.constraint_names = (*(f"req_{r.label}" for r in self.constraints), "no_interference")

    def _default_objectives(self) -> list[ObjectiveSpec]:
        for r in self.requirements:
            if isinstance(r, TargetBand):
                return [ObjectiveSpec(target_error=r.label)]
        return [ObjectiveSpec(minimise="mass_g")]

    def nominal_design(self) -> np.ndarray:
        """(n_var,) the study's initial design (what ``flexopt evaluate`` solves); (0,) without
        variables."""
        if self.variables is None:
            return np.zeros(0)
        return np.asarray(self.variables.initial, dtype=float)

    def initial_designs(self) -> np.ndarray:
        """The study's initial design seeds the first population.

        Raises
        ------
        StudyError
            At ``variables`` for a study without variables: ``flexopt run`` asks for the first
            population before it writes anything, and such a study has nothing to optimise.
        """
        if self.variables is None:
            raise StudyError(
                "variables",
                "flexopt run needs design variables; add variables: [{path, bounds}] (see "
                "docs/mechanism.md) or use flexopt evaluate",
            )
        return self.space.clip(self.variables.initial)[None, :]

    # ---- the parts of a design's answer the check of the exported outline recomputes

    def width_requirement(self) -> Requirement | None:
        """The requirement the width is solved from (``solve_width_from``), or None."""
        spec = self.study.solve_width_from
        return None if spec is None else self.labels[spec.requirement]

    def case_table(
        self, case: str, response: Any, scale: float, made: Mapping[str, AsMadeBeam] | None = None
    ) -> dict[str, np.ndarray]:
        """The load case's response as columns, forces times ``scale`` (width / reference
        width), stresses of the beams as ``made`` (each column (n_rows,))."""
        return _case_table(self.study, case, response, scale, made)

    def part_metrics(
        self,
        geometry: MechanismGeometry,
        outline: MechanismOutline,
        tables: Mapping[str, Mapping[str, np.ndarray]],
        width_mm: float,
        clearance: Mapping[str, Any],
    ) -> dict[str, Any]:
        """Every metric of the part as made at ``width_mm`` (mm) from its case ``tables``."""
        return _part_metrics(
            self.study, geometry, outline, tables, width_mm, self.material, clearance
        )

    def curves_table(self, tables: Mapping[str, Mapping[str, np.ndarray]]) -> dict[str, Any]:
        """Every case's columns, prefixed by the case: what the requirements read."""
        return _curves_table(self.study, tables)

    # ---- solving

    def solve(self, x: np.ndarray | None) -> Solved | tuple[None, str]:
        """Build, check and solve one design; ``(None, reason)`` when it cannot be."""
        study = self.study
        try:
            geometry = _geometry_of(study, x)
        except ValidationError as exc:
            err = exc.errors(include_url=False)[0]
            loc = ".".join(str(p) for p in err["loc"])
            return None, f"invalid geometry: geometry.{loc}: {err['msg']}"
        try:
            shapes, outline = build_outline(geometry)
        except GeometryError as exc:
            return None, f"invalid geometry: {exc}"
        mech = _mechanism(study, geometry, made=outline.beams)
        responses = {}
        for case in study.load_cases:
            try:
                given = self.given_responses
                response = given[case] if given else _solve_printed_path(study, mech, case)
            except FeaError as exc:
                return None, f"cannot solve load case {case}: {exc}"
            responses[case] = response
        width = geometry.width_mm
        ref = {c: _case_table(study, c, r, 1.0, outline.beams) for c, r in responses.items()}
        reason = next(
            (f"load case {c} did not converge: {r.message}" for c, r in responses.items()
             if not r.ok),
            "",
        )  # fmt: skip
        req = self.width_requirement()
        if req is not None and not reason:
            width, why = _solve_width(study, req, ref, geometry.width_mm)
            if why:
                reason = f"width not solved: {why}"
        if not math.isfinite(width):
            width = geometry.width_mm
        scale = width / geometry.width_mm
        tables = {c: _case_table(study, c, r, scale, outline.beams) for c, r in responses.items()}
        controls = {c: s.drive.control for c, s in study.load_cases.items()}
        grounds = geometry.ground_outlines_mm
        clearance = design.interference(mech, outline, grounds, responses, controls)
        clearance = stops.stop_interference(study, mech, clearance, responses)
        metrics = _part_metrics(study, geometry, outline, tables, width, self.material, clearance)
        metrics.update(stops.metrics(study, responses, tables))
        return Solved(
            geometry, shapes, outline, width, responses, tables, metrics,
            _curves_table(study, tables), reason, clearance,
        )  # fmt: skip

    jacobian_extends = True  # a wrapper's rows of the metrics join (pipeline.verdict)

    def jacobian(self, x: np.ndarray, extend: Any = None) -> Any:
        """Exact derivatives of f and g (pipeline/studies/_mechanism_gradient.py), or None."""
        return mechanism_jacobian(self, x, extend)

    def verdicts(self, solved: Solved) -> tuple[Verdict, ...]:
        """:meth:`judge`, each verdict the check of the exported outline changed saying so."""
        return annotate(self.judge(solved), solved)

    def judge(self, solved: Solved) -> tuple[Verdict, ...]:
        """The requirements and the interference judged on ``solved``'s figures."""
        # the life rows are the pipeline's (pipeline.verdict, with the life it computes for every
        # kind): judged here, without the life in the metrics, they would read NOT MET
        own = [r for r in self.requirements if r.quantity not in LIFE_QUANTITIES]
        judged = scoring.judge(own, solved.metrics, solved.curves_table)
        clear = scoring.interference_verdict(solved.metrics, solved.clearance)
        # a drive that holds a bare beam end's rotation: a corner as made (#27)
        held = driven_end_verdicts(self.study)
        # each beam's L/t: below 6 the beam model's figures are not the member's (#22)
        slender = slenderness_verdicts(solved)
        # a beam-to-beam joint's sharp corner, a pinned end printed solid (#22)
        joints = joint_verdicts(solved.geometry)
        return (*judged, stops.interference_verdict(self.study, clear), *held, *slender, *joints)

    def _evaluation(self, x: np.ndarray, solved: Solved, t0: float) -> Evaluation:
        verdicts = self.verdicts(solved)
        metrics = dict(solved.metrics)
        metrics["verdict"] = "MET" if verdicts and all(v.met for v in verdicts) else "NOT MET"
        f = scoring.objective_values(
            self.objectives, self.labels, solved.metrics, solved.curves_table
        )
        g = scoring.constraint_rows(self.constraints, verdicts, solved.metrics)
        ev = Evaluation(
            np.asarray(x, dtype=float), f, np.array(g, dtype=float), metrics, solved.reason,
            time.perf_counter() - t0,
        )  # fmt: skip
        if solved.reason:
            bad = Evaluation.failed(x, len(f), len(g), solved.reason, ev.time_s, metrics)
            return bad
        return ev

    def evaluate(self, x: np.ndarray) -> Evaluation:
        t0 = time.perf_counter()
        try:
            solved = self.solve(x)
        except Exception as exc:  # never crash the optimiser: the design is infeasible
            return Evaluation.failed(
                x, len(self.objective_names), len(self.constraint_names),
                f"failed: {type(exc).__name__}: {exc}", time.perf_counter() - t0,
            )  # fmt: skip
        if isinstance(solved, tuple):
            return Evaluation.failed(
                x, len(self.objective_names), len(self.constraint_names), solved[1],
                time.perf_counter() - t0,
            )  # fmt: skip
        return self._evaluation(x, _as_the_optimiser_judges(self.study, solved), t0)

    def detail(self, x: np.ndarray) -> DesignResult:
        t0 = time.perf_counter()
        solved = self.solve(x)
        if isinstance(solved, tuple):
            ev = Evaluation.failed(
                x, len(self.objective_names), len(self.constraint_names), solved[1],
                time.perf_counter() - t0,
            )  # fmt: skip
            return DesignResult(ev, info={"reason": solved[1]})
        solved = with_fidelity(self, solved)
        ev = self._evaluation(x, solved, t0)
        verdicts = self.verdicts(solved)
        first = next(iter(solved.tables))
        return DesignResult(
            evaluation=ev,
            table=solved.tables[first],
            plot=response_plot(self.study, solved, first, self.material, self.requirements),
            outline=solved.outline.polygon,
            height_mm=solved.width_mm,
            info={
                **design_info(self.study, solved),
                "verdicts": [_verdict_json(v) for v in verdicts],
            },
            files=design_files(self.study, solved),
            cases=case_responses(self.study, solved, self.material, self.requirements),
            verdicts=verdicts,
            **solved_vtu(solved, first),  # best.vtu: the beams' sections and stresses
        )

    def result(self, x: np.ndarray, repeat: int = 1) -> DesignResult:
        """``flexopt evaluate``: the design ``x`` (n_var,) (the study's initial design,
        :meth:`nominal_design`; none without variables) solved ``repeat`` times in every load
        case and checked as exported; the kind's verdicts with "every variable in its range",
        the metrics (and the objectives' values) as the summary.

        Raises
        ------
        StudyError
            When the design cannot be built or solved (check() reports it first).
        """
        x = np.asarray(x, dtype=float)
        times, solved = [], None
        for _ in range(max(1, int(repeat))):
            t0 = time.perf_counter()
            solved = self.solve(x)
            times.append(time.perf_counter() - t0)
        if isinstance(solved, tuple) or solved is None:
            why = solved[1] if solved is not None else "not solved"
            raise StudyError("geometry", f"the initial design cannot be solved: {why}")
        solved = with_fidelity(self, solved)
        designed = self.variables is not None
        # "every variable in its range" of this design (a run's best design gets it from
        # pipeline.verdict.judge_result)
        verdicts = with_design_range(self.study, self.verdicts(solved), x if designed else None)
        summary = dict(solved.metrics)
        if designed:
            evaluation = self._evaluation(x, solved, time.perf_counter())
            for name, value in zip(self.objective_names, map(float, evaluation.f), strict=True):
                summary.setdefault(name, value)  # a metric minimised as itself keeps its value
        met = verdicts and all(v.met for v in verdicts) and not solved.reason  # whole stroke
        summary["verdict"] = "MET" if met else "NOT MET"  # as pipeline/stroke_verdict.py's row
        message = "; ".join(f"{c}: {r.message}" for c, r in solved.responses.items() if r.message)
        if solved.reason and solved.reason not in message:
            message = "; ".join(m for m in (message, solved.reason) if m)
        first = next(iter(solved.tables))
        headline = ("verdict", "mass_g", "max_peak_stress_MPa", "width_mm", "stable")
        headline += stops.headline(self.study)
        return DesignResult(
            table=solved.tables[first],
            summary=summary,
            converged=all(bool(r.ok) for r in solved.responses.values()),
            message=message,
            solve_times_s=tuple(times),
            inputs={
                "material": material_record(self.material),
                "design": self.variables.values(x) if self.variables is not None else None,
                "verdicts": [_verdict_json(v) for v in verdicts],
                **design_info(self.study, solved),
            },
            plot=response_plot(self.study, solved, first, self.material, self.requirements),
            headline=tuple(k for k in headline if k in summary),
            files=design_files(self.study, solved),
            cases=case_responses(self.study, solved, self.material, self.requirements),
            verdicts=verdicts,
            **solved_vtu(solved, first),  # best.vtu: the beams' sections and stresses
        )


# --------------------------------------------------------------------------------------------
# Registry hooks


def problem(study: MechanismStudy) -> MechanismProblem:
    """The design problem ``flexopt run`` optimises."""
    return MechanismProblem(study)


def design_of(study: MechanismStudy) -> tuple[DesignSpace, np.ndarray, str] | None:
    """The variables' space and the initial design (what ``flexopt evaluate`` solves), or
    None without variables (pipeline.verdict's design-range row)."""
    variables = _variables(study)
    if variables is None:
        return None
    return variables.space, np.asarray(variables.initial, dtype=float), "variables[i].bounds"


def _kind() -> StudyKind:
    names = {f.name for f in dataclasses.fields(StudyKind)}
    extra: dict[str, Any] = {}
    if "quantities" in names:
        extra["quantities"] = quantities
    if "design_space" in names:
        extra["design_space"] = design_of
    if "summary" in names:  # `flexopt list`'s line: the model's module is _mechanism_schema
        extra["summary"] = __doc__.split("\n\n")[0].removeprefix("Study kind ``mechanism``:")
    if "width_key" in names:  # flexopt retrim's default --key, where it is exact
        extra["width_key"] = width_key
    # flexopt evaluate: the nominal design's MechanismProblem.result (pipeline.problems)
    return StudyKind("mechanism", MechanismStudy, check, None, problem, **extra)  # type: ignore[arg-type]


register(_kind())
