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

YAML (abridged)::

    geometry:
      kind: mechanism
      width_mm: 6.0
      beams:
        upper: {points_mm: [[0, 10], [40, 10]], thickness_mm: 1.2}
        lower: {points_mm: [[0, -10], [40, -10]], thickness_mm: 1.2}
      bodies:
        shuttle: {ref_mm: [44, 0], outline_mm: [[40, -13], [48, -13], [48, 13], [40, 13]]}
      joints:
        - {a: upper.start, b: ground}
        - {a: upper.end, b: shuttle}
    material: PA12
    load_cases:
      stroke: {drive: {part: shuttle, control: displacement, direction: [0, 1], min_mm: -5,
                       max_mm: 5, steps: 20}}
    outputs:
      force_N: {quantity: reaction}
      stiffness_N_per_mm: {quantity: slope, of: force_N}
    variables: [{path: geometry.beams.upper.thickness_mm, bounds: [0.8, 2.5], tie: [...]}]
    requirements: [{quantity: min_stiffness_N_per_mm, min: 2.85}]
    objectives: [{minimise: mass_g}]

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
import io
import math
import re
import sys
import time
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.mechanism import (
    FILLET_CHORDS,
    AsMadeBeam,
    Attachment,
    BeamShape,
    BodyShape,
    MechanismOutline,
    curve_points,
    mechanism_outline,
)
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.evaluation import INFEASIBLE_VALUE, Evaluation
from flexopt.optimise.names import check_name
from flexopt.optimise.problem import CaseResponse, DesignDetail, DesignProblem
from flexopt.optimise.requirements import (
    MinFeature,
    Range,
    Requirement,
    RequirementSpec,
    TargetBand,
    Verdict,
    unit_of,
)
from flexopt.optimise.space import DesignSpace
from flexopt.optimise.variables import (
    DesignVariables,
    VariableError,
    VariableSpec,
    resolve_variables,
)
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.plot_targets import band_spec
from flexopt.pipeline.runfolder import table_to_csv
from flexopt.pipeline.studies import EvaluationResult, StudyKind, register
from flexopt.pipeline.studies._mechanism_fidelity import (
    MechanismFidelitySpec,
    annotate,
    with_fidelity,
)
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study, material_record
from flexopt.pipeline.verdict import envelope_values, with_design_range
from pydantic import BaseModel, Field, ValidationError, field_validator, model_validator

__all__ = [
    "BeamSpec",
    "BodySpec",
    "CurveSpec",
    "DriveSpec",
    "JointSpec",
    "LoadCaseSpec",
    "MechanismGeometry",
    "MechanismProblem",
    "MechanismStudy",
    "ObjectiveSpec",
    "OutputSpec",
    "WidthSolveSpec",
    "check",
    "evaluate",
    "problem",
]

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")
_DRIVE_UNIT = {"displacement": "mm", "rotation": "deg", "force": "N", "moment": "Nmm"}
_REACTION_UNIT = {"displacement": "N", "force": "N", "rotation": "Nmm", "moment": "Nmm"}
#: Statistics of every output over the converged rows of its case (metric ``<stat>_<output>``).
_STATS = ("max", "min", "max_abs", "mean", "end", "start", "first_peak")
#: Columns every case table has; an output may not take one of these names.
_BUILTIN_COLUMNS = ("step", "converged", "stable", "peak_stress_MPa")


def _check_name(value: str, what: str) -> str:
    check_name(value, what)  # the one rule of names (docs/usage.md), then this kind's own
    if not _NAME.fullmatch(value) or value == "ground":
        raise ValueError(
            f"'{value}' cannot name a {what}: use letters, digits, '_' and '-', starting with a "
            "letter, not 'ground' (joints name parts as name.start / name.end)"
        )
    return value


# --------------------------------------------------------------------------------------------
# The study file


class CurveSpec(BaseModel):
    """``curve:`` of a beam: its centreline generated between two points (mm)."""

    model_config = STUDY_CONFIG

    start_mm: tuple[float, float] = Field(description="[x, y] of the beam's start, mm")
    end_mm: tuple[float, float] = Field(description="[x, y] of the beam's end, mm")
    shape: Literal["straight", "cosine", "arc", "half_cosine"] = Field(
        "straight",
        description="straight, cosine (first clamped-clamped mode), arc, or half_cosine (y from "
        "start to end along half a cosine wave, level at both ends)",
    )
    rise_mm: float = Field(0.0, description="largest distance from the chord, mm (left if > 0)")
    points: int = Field(21, ge=2, le=2001, description="points along the centreline")


class BeamSpec(BaseModel):
    """One entry of ``geometry.beams``."""

    model_config = STUDY_CONFIG

    points_mm: tuple[tuple[float, float], ...] | None = Field(
        None, min_length=2, description="centreline points [x, y] from start to end, mm"
    )
    curve: CurveSpec | None = Field(None, description="or: {start_mm, end_mm, shape, rise_mm}")
    thickness_mm: float | tuple[float, ...] = Field(
        description="in-plane thickness, mm: one value, or one per point"
    )
    width_mm: float | None = Field(
        None, gt=0, description="out-of-plane width, mm (default geometry.width_mm)"
    )
    curvature_per_mm: tuple[float, ...] | None = Field(
        None, description="signed curvature of each segment of points_mm, 1/mm (0 = straight)"
    )
    elements: int = Field(0, ge=0, le=5000, description="beam elements; 0 = the solver's choice")

    @model_validator(mode="after")
    def _one_centreline(self) -> BeamSpec:
        if (self.points_mm is None) == (self.curve is None):
            raise ValueError("give points_mm or curve (one of them) for the centreline")
        if self.curve is not None and self.curvature_per_mm is not None:
            raise ValueError("curvature_per_mm goes with points_mm; a curve has its shape")
        n = self.n_points
        if isinstance(self.thickness_mm, tuple):
            if len(self.thickness_mm) not in (1, n):
                raise ValueError(
                    f"thickness_mm has {len(self.thickness_mm)} values for {n} points; give one "
                    f"value or {n}"
                )
            if any(not t > 0 for t in self.thickness_mm):
                raise ValueError("every thickness_mm must be > 0 mm")
        elif not self.thickness_mm > 0:
            raise ValueError(f"thickness_mm = {self.thickness_mm:g} must be > 0 mm")
        if self.curvature_per_mm is not None and len(self.curvature_per_mm) != n - 1:
            raise ValueError(f"curvature_per_mm needs one value per segment ({n - 1})")
        return self

    @property
    def n_points(self) -> int:
        if self.points_mm is not None:
            return len(self.points_mm)
        return self.curve.points if self.curve is not None else 0

    def centreline(self) -> np.ndarray:
        """(n, 2) mm."""
        if self.points_mm is not None:
            return np.array(self.points_mm, dtype=float)
        c = self.curve
        assert c is not None
        return curve_points(c.start_mm, c.end_mm, c.shape, c.rise_mm, c.points)

    def thickness(self) -> np.ndarray:
        """(n,) mm."""
        t = self.thickness_mm
        values = np.atleast_1d(np.array(t, dtype=float))
        return np.full(self.n_points, values[0]) if values.size == 1 else values


class BodySpec(BaseModel):
    """One entry of ``geometry.bodies``: a rigid part."""

    model_config = STUDY_CONFIG

    ref_mm: tuple[float, float] = Field(
        description="reference point [x, y], mm: drives act at it and outputs read it"
    )
    outline_mm: tuple[tuple[float, float], ...] | None = Field(
        None, min_length=3, description="outline corners [x, y] in order, mm (printed part)"
    )


class JointSpec(BaseModel):
    """One joint: beam end ``a`` attached to ``b``."""

    model_config = STUDY_CONFIG

    a: str = Field(description="beam.start or beam.end (or a body held to the ground)")
    b: str = Field(description="ground, a body, or another beam's end (beam.start / beam.end)")
    type: Literal["clamped", "pinned"] = Field(
        "clamped", description="clamped (rotation tied) or pinned (rotation free)"
    )


class DriveSpec(BaseModel):
    """``drive:`` of a load case. The value keys carry the control's unit."""

    model_config = STUDY_CONFIG

    part: str = Field(description="a body (acts at ref_mm) or a beam end (beam.end)")
    control: Literal["displacement", "rotation", "force", "moment"] = Field(
        description="displacement (mm), rotation (deg), force (N) or moment (N mm)"
    )
    direction: tuple[float, float] = Field(
        (1.0, 0.0), description="[dx, dy] of a displacement or force (normalised)"
    )
    max_mm: float | None = Field(None, description="displacement of the last row, mm")
    min_mm: float | None = Field(None, description="displacement of row 0, mm (default 0)")
    max_deg: float | None = Field(None, description="rotation of the last row, deg")
    min_deg: float | None = Field(None, description="rotation of row 0, deg")
    max_N: float | None = Field(None, description="force of the last row, N")
    min_N: float | None = Field(None, description="force of row 0, N")
    max_Nmm: float | None = Field(None, description="moment of the last row, N mm")
    min_Nmm: float | None = Field(None, description="moment of row 0, N mm")
    steps: int = Field(20, ge=1, le=2000, description="rows after row 0")
    transverse: Literal["held", "free"] = Field(
        "free", description="motion across direction (for rotation / moment: the translation)"
    )
    rotation: Literal["held", "free"] = Field(
        "free", description="rotation of the driven part (displacement / force)"
    )

    @model_validator(mode="after")
    def _values_match_control(self) -> DriveSpec:
        unit = _DRIVE_UNIT[self.control]
        for other in set(_DRIVE_UNIT.values()) - {unit}:
            for end in ("max", "min"):
                if getattr(self, f"{end}_{other}") is not None:
                    raise ValueError(
                        f"{end}_{other} does not go with control: {self.control}; give "
                        f"{end}_{unit} instead"
                    )
        if getattr(self, f"max_{unit}") is None:
            raise ValueError(f"control: {self.control} needs max_{unit} (the last row's value)")
        if self.range[0] == self.range[1]:
            raise ValueError(f"min_{unit} equals max_{unit}: the drive would not move")
        if math.hypot(*self.direction) < 1e-12:
            raise ValueError(f"direction {list(self.direction)} has no length; e.g. [0, 1]")
        return self

    @property
    def unit(self) -> str:
        return _DRIVE_UNIT[self.control]

    @property
    def range(self) -> tuple[float, float]:
        """(row 0, last row) in the drive's unit."""
        lo = getattr(self, f"min_{self.unit}")
        return (0.0 if lo is None else float(lo), float(getattr(self, f"max_{self.unit}")))


class LoadCaseSpec(BaseModel):
    """One entry of ``load_cases``."""

    model_config = STUDY_CONFIG

    drive: DriveSpec = Field(description="the one drive of the case")
    supports: tuple[JointSpec, ...] = Field(
        (), description="joints of this case only, to ground (a jaw held: blocked force)"
    )


class OutputSpec(BaseModel):
    """One entry of ``outputs`` (its name carries its unit: ``force_N``, ``rotation_deg``)."""

    model_config = STUDY_CONFIG

    quantity: Literal[
        "reaction",
        "reaction_force",
        "reaction_moment",
        "displacement",
        "rotation",
        "peak_stress",
        "slope",
        "ratio",
    ] = Field(description="what the output reads (see docs/mechanism.md)")
    part: str = Field("", description="body, beam end or beam it reads ('' = the drive / all)")
    direction: tuple[float, float] = Field(
        (1.0, 0.0), description="[dx, dy] of a displacement or reaction_force"
    )
    of: str | tuple[str, str] | None = Field(
        None, description="slope: the output differentiated by the drive; ratio: [num, den]"
    )
    cases: tuple[str, ...] | None = Field(
        None, description="load cases it is read in (default: every case)"
    )


class ObjectiveSpec(BaseModel):
    """One entry of ``objectives``: exactly one key."""

    model_config = STUDY_CONFIG

    minimise: str | None = Field(None, description="a metric to minimise (mass_g)")
    maximise: str | None = Field(None, description="a metric to maximise")
    target_error: str | None = Field(
        None, description="a target requirement's name: minimise the RMS error to it"
    )
    band_stroke: str | None = Field(
        None, description="a target requirement's name: maximise the stroke inside its band"
    )

    @model_validator(mode="after")
    def _one_key(self) -> ObjectiveSpec:
        given = [k for k in type(self).model_fields if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of minimise, maximise, target_error or band_stroke")
        return self

    @property
    def key(self) -> tuple[str, str]:
        for k in type(self).model_fields:
            if getattr(self, k) is not None:
                return k, str(getattr(self, k))
        raise AssertionError


class WidthSolveSpec(BaseModel):
    """``solve_width_from``: the shared width that meets a force-like requirement exactly."""

    model_config = STUDY_CONFIG

    requirement: str = Field(description="name of a range or target requirement on a force")
    range_mm: tuple[float, float] | None = Field(
        None,
        description="[lower, upper] the solved width must lie in, mm (a built-in requirement; "
        "default: at least geometry.min_feature_mm)",
    )

    @model_validator(mode="after")
    def _range(self) -> WidthSolveSpec:
        if self.range_mm is not None and not 0 < self.range_mm[0] < self.range_mm[1]:
            raise ValueError(
                f"range_mm = {list(self.range_mm)} must be [lower, upper], 0 < lower < upper"
            )
        return self


class MechanismGeometry(BaseModel):
    """The ``geometry:`` block (mm)."""

    model_config = STUDY_CONFIG

    kind: Literal["mechanism"] = Field(description="mechanism")
    width_mm: float = Field(gt=0, description="shared out-of-plane width, mm")
    beams: dict[str, BeamSpec] = Field(min_length=1, description="named beams")
    bodies: dict[str, BodySpec] = Field(default_factory=dict, description="named rigid bodies")
    joints: tuple[JointSpec, ...] = Field(min_length=1, description="joints {a, b, type}")
    min_feature_mm: float = Field(0.8, gt=0, description="thinnest printable wall, mm")
    pad_length_mm: float = Field(6.0, gt=0, description="clamping pad beyond a grounded end, mm")
    pad_thickness_mm: float = Field(4.0, gt=0, description="clamping pad thickness, mm")
    ground_outlines_mm: tuple[tuple[tuple[float, float], ...], ...] = Field(
        (), description="fixed frame outlines printed with the part (not analysed), mm"
    )
    fillet_mm: float = Field(
        1.0, gt=0, description="fillet radius where a beam meets a pad or a body, mm"
    )
    max_corner_deg: float = Field(
        90.0,
        gt=0,
        le=90,
        description="sharpest corner (turn at a point) of a beam's centreline accepted, deg; at "
        "most 90 (past it the legs merge into a block the beam model does not see)",
    )

    @field_validator("beams", "bodies")
    @classmethod
    def _names(cls, value: dict[str, Any]) -> dict[str, Any]:
        for name in value:
            _check_name(name, "part")
        return value

    @model_validator(mode="after")
    def _unique_parts(self) -> MechanismGeometry:
        both = sorted(set(self.beams) & set(self.bodies))
        if both:
            raise ValueError(f"'{both[0]}' names a beam and a body; rename one")
        return self


class MechanismStudy(Study):
    """A whole ``mechanism`` study file."""

    geometry: MechanismGeometry = Field(description="kind: mechanism, beams, bodies, joints")
    load_cases: dict[str, LoadCaseSpec] = Field(
        min_length=1, description="named load cases: {drive, supports}"
    )
    outputs: dict[str, OutputSpec] = Field(
        default_factory=dict, description="named outputs, units in the names"
    )
    variables: tuple[VariableSpec, ...] = Field(
        (), description="design variables [{path, bounds, tie, initial}]"
    )
    objectives: tuple[ObjectiveSpec, ...] = Field(
        (), description="minimise / maximise / target_error / band_stroke"
    )
    requirements: tuple[RequirementSpec, ...] = Field(
        (), description="what the design must meet (MET / NOT MET)"
    )
    solve_width_from: WidthSolveSpec | None = Field(
        None, description="solve the shared width from a force requirement"
    )
    fidelity: MechanismFidelitySpec = Field(
        default_factory=MechanismFidelitySpec,
        description="the reported design's check of its exported outline in plane stress / 3D",
    )
    imperfection_mm: float = Field(
        0.02,
        ge=0.0,
        le=1.0,
        description="where a load case's path loses stability, the part is solved again with "
        "its shape moved this far (mm) along the buckling mode: the branch a printed part "
        "follows (0: stop the curve at the first unstable row)",
    )
    optimiser: OptimiserSpec = Field(
        default_factory=lambda: OptimiserSpec(pop_size=24, n_gen=15, quick_pop_size=4,
                                              quick_n_gen=1),
        description="algorithm, pop_size, n_gen, seed, quick_pop_size, quick_n_gen",
    )  # fmt: skip

    @field_validator("load_cases", "outputs")
    @classmethod
    def _names(cls, value: dict[str, Any]) -> dict[str, Any]:
        for name in value:
            _check_name(name, "load case or output")
        return value


# --------------------------------------------------------------------------------------------
# From the study to the solver


def _fea():
    # the engine, imported late so the kind always registers
    import flexopt.fea.mechanism as fm

    return fm


def _end_ref(ref: str) -> tuple[str, str] | None:
    name, _, end = ref.rpartition(".")
    return (name, end) if name and end in ("start", "end") else None


def _part_exists(geometry: MechanismGeometry, ref: str, allow_beam: bool = False) -> bool:
    end = _end_ref(ref)
    if end is not None:
        return end[0] in geometry.beams
    return ref in geometry.bodies or (allow_beam and ref in geometry.beams)


def _part_hint(geometry: MechanismGeometry) -> str:
    ends = [f"{b}.start, {b}.end" for b in list(geometry.beams)[:3]]
    return ", ".join([*ends, *list(geometry.bodies)[:3]])


def _output_unit_problem(name: str, spec: OutputSpec, control: str) -> str | None:
    """Why an output's name does not carry its quantity's unit (None when it does)."""
    wanted = {
        "reaction_force": ("N",),
        "reaction_moment": ("N·mm",),
        "displacement": ("mm",),
        "rotation": ("deg", "rad"),
        "peak_stress": ("MPa",),
        "reaction": ("N·mm",) if _REACTION_UNIT[control] == "Nmm" else ("N",),
    }.get(spec.quantity)
    if wanted is None or unit_of(name) in wanted:
        return None
    suffix = {"N·mm": "_Nmm"}.get(wanted[0], f"_{wanted[0]}")
    return (
        f"a {spec.quantity} output is in {' or '.join(wanted)}; end its name with the unit, "
        f"e.g. {name.rsplit('_', 1)[0] if '_' in name else name}{suffix}"
    )


def _prefix(study: MechanismStudy, case: str) -> str:
    return f"{case}." if len(study.load_cases) > 1 else ""


def _outputs_in(study: MechanismStudy, case: str) -> list[str]:
    return [n for n, o in study.outputs.items() if o.cases is None or case in o.cases]


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
        for o in _outputs_in(study, case):
            names |= {f"{p}{s}_{o}" for s in _STATS}
    return tuple(sorted(names))


def column_names(study: MechanismStudy) -> tuple[str, ...]:
    """Response columns (judged by their worst value, or as curves by target requirements)."""
    names = set()
    for case, spec in study.load_cases.items():
        p = _prefix(study, case)
        names |= {f"{p}drive_{spec.drive.unit}", f"{p}peak_stress_MPa"}
        names |= {f"{p}{o}" for o in _outputs_in(study, case)}
    return tuple(sorted(names))


def quantities(study: MechanismStudy) -> tuple[str, ...]:
    """The names a ``requirements:`` item may judge."""
    return tuple(sorted(set(metric_names(study)) | set(column_names(study))))


def _refuse_derived_cycles(study: MechanismStudy) -> None:
    """Refuse slopes and ratios that refer to each other in a loop (``a`` the slope of ``b``,
    ``b`` the slope of ``a``): nothing can be computed first, so every such column would be NaN."""

    def refs(name: str) -> list[str]:
        o = study.outputs[name]
        if o.quantity not in ("slope", "ratio"):
            return []
        return [o.of] if isinstance(o.of, str) else list(o.of or ())

    done: set[str] = set()
    for start in study.outputs:
        path: list[str] = []
        stack: list[tuple[str, int]] = [(start, 0)]
        while stack:  # depth-first, iterative: a long chain of outputs cannot overflow
            name, i = stack.pop()
            if i == 0:
                if name in done:
                    continue
                if name in path:
                    loop = " -> ".join([*path[path.index(name) :], name])
                    raise StudyError(
                        f"outputs.{name}.of",
                        f"outputs refer to each other in a loop ({loop}), so none of them can "
                        "be computed; make one of them a measured quantity (reaction, "
                        "displacement, rotation) or refer to one",
                    )
                path.append(name)
            children = [r for r in refs(name) if r in study.outputs]
            if i < len(children):
                stack.append((name, i + 1))
                stack.append((children[i], 0))
            else:
                done.add(path.pop())


def _requirements(study: MechanismStudy) -> list[Requirement]:
    out = []
    for i, spec in enumerate(study.requirements):
        table = columns = None
        if spec.target is not None and spec.target.kind == "table" and spec.target.file:
            from flexopt.pipeline.studies._targets import read_table_csv  # a target table's file

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


def _exponent(study: MechanismStudy, output: str, seen: tuple[str, ...] = ()) -> int:
    """How an output scales with the shared width: 1 (a force or moment), 0 (a motion, a
    stress), or another power for ratios of them."""
    spec = study.outputs[output]
    if spec.quantity in ("reaction", "reaction_force", "reaction_moment"):
        return 1
    if spec.quantity == "slope" and isinstance(spec.of, str) and spec.of not in seen:
        return _exponent(study, spec.of, (*seen, output))
    if spec.quantity == "ratio" and isinstance(spec.of, tuple):
        a, b = spec.of
        if a in seen or b in seen:
            return 0
        return _exponent(study, a, (*seen, output)) - _exponent(study, b, (*seen, output))
    return 0


def _quantity_output(study: MechanismStudy, quantity: str) -> str | None:
    """The output a metric or column name reads (``blocked.max_jaw_force_N`` → jaw_force_N)."""
    name = quantity.split(".", 1)[1] if "." in quantity else quantity
    for stat in sorted(_STATS, key=len, reverse=True):
        if name.startswith(f"{stat}_") and name[len(stat) + 1 :] in study.outputs:
            return name[len(stat) + 1 :]
    return name if name in study.outputs else None


def check(study: MechanismStudy) -> None:
    """Every refusal with its key path before any run folder exists: parts named by joints,
    drives, supports and outputs; output units; variables; requirements and objectives; the
    initial design's geometry (printable, one body) and a free rigid-body motion in any case."""
    g = study.geometry
    hint = _part_hint(g)
    for i, joint in enumerate(g.joints):
        for key in ("a", "b"):
            ref = getattr(joint, key)
            ok = ref == "ground" and key == "b" or _part_exists(g, ref)
            if not ok:
                raise StudyError(
                    f"geometry.joints[{i}].{key}",
                    f"'{ref}' names no part; use a beam end ({hint})"
                    + (", or ground" if key == "b" else ""),
                )
    for case, spec in study.load_cases.items():
        here = f"load_cases.{case}"
        if not _part_exists(g, spec.drive.part):
            raise StudyError(f"{here}.drive.part", f"'{spec.drive.part}' names no part; use {hint}")
        for j, s in enumerate(spec.supports):
            if s.b != "ground":
                raise StudyError(f"{here}.supports[{j}].b", "a support holds to ground; b: ground")
            if not _part_exists(g, s.a):
                raise StudyError(f"{here}.supports[{j}].a", f"'{s.a}' names no part; use {hint}")
    for name, o in study.outputs.items():
        here = f"outputs.{name}"
        if name in _BUILTIN_COLUMNS or name.startswith("drive_"):
            raise StudyError(here, f"'{name}' is a column every response has; rename the output")
        for case in o.cases or ():
            if case not in study.load_cases:
                raise StudyError(
                    f"{here}.cases",
                    f"'{case}' is no load case; use {', '.join(study.load_cases)}",
                )
        if o.quantity in ("slope", "ratio"):
            refs = [o.of] if isinstance(o.of, str) else list(o.of or ())
            if len(refs) != (1 if o.quantity == "slope" else 2):
                need = "of: <output>" if o.quantity == "slope" else "of: [numerator, denominator]"
                raise StudyError(f"{here}.of", f"a {o.quantity} needs {need}")
            for ref in refs:
                if ref not in study.outputs or ref == name:
                    raise StudyError(
                        f"{here}.of", f"'{ref}' is no other output; use one of the outputs"
                    )
        elif o.part and not (_part_exists(g, o.part, allow_beam=o.quantity == "peak_stress")):
            raise StudyError(f"{here}.part", f"'{o.part}' names no part; use {hint}")
        for case in o.cases or study.load_cases:
            problem = _output_unit_problem(name, o, study.load_cases[case].drive.control)
            if problem:
                raise StudyError(here, problem)
    _refuse_derived_cycles(study)
    reqs = _requirements(study)
    valid = set(quantities(study))
    labels = {r.label: r for r in reqs}
    for i, (spec, req) in enumerate(zip(study.requirements, reqs, strict=True)):
        for key, name in (("quantity", spec.quantity), ("x", spec.x)):
            if name is not None and name not in valid:
                import difflib

                close = difflib.get_close_matches(name, sorted(valid), n=1)
                raise StudyError(
                    f"requirements[{i}].{key}",
                    f"this study reports no '{name}'; "
                    + (f"did you mean '{close[0]}'? " if close else "")
                    + f"use one of {', '.join(sorted(valid))}",
                )
        del req
    for i, obj in enumerate(study.objectives):
        key, name = obj.key
        if key in ("minimise", "maximise"):
            if name not in metric_names(study):
                raise StudyError(
                    f"objectives[{i}].{key}",
                    f"'{name}' is no metric of this study; use one of "
                    + ", ".join(metric_names(study)),
                )
        elif not isinstance(labels.get(name), TargetBand):
            targets = [r.label for r in reqs if isinstance(r, TargetBand)]
            raise StudyError(
                f"objectives[{i}].{key}",
                f"'{name}' is no target requirement; name one of: "
                + (", ".join(targets) or "(none: add a requirement with target:)"),
            )
    if study.solve_width_from is not None:
        _check_width_solve(study, labels)
    if len(study.objectives) > 1 and study.optimiser.algorithm == "ga":
        raise StudyError(
            "optimiser.algorithm",
            f"{len(study.objectives)} objectives need algorithm: nsga2 (ga optimises one)",
        )
    variables = _variables(study)
    x0 = variables.initial if variables is not None else None
    geometry = _geometry_of(study, x0)
    try:
        shapes, outline = _outline(geometry)
    except GeometryError as exc:
        raise StudyError(
            _geometry_path(str(exc)), f"the initial design is not buildable: {exc}"
        ) from None
    fm = _fea()
    mech = _mechanism(study, geometry, made=outline.beams)
    for case in study.load_cases:
        try:
            fm.check_mechanism(mech, _load_case(study, case))
        except FeaError as exc:
            raise StudyError(_fea_path(study, case, str(exc)), _fea_fix(str(exc))) from None


def _geometry_path(message: str) -> str:
    """The key path a geometry refusal is about: the beam it names (and the point), else the
    geometry."""
    m = re.match(r"beam '([A-Za-z][A-Za-z0-9_-]*)'(?: turns .* at point \[(\d+)\])?", message)
    if m is None:
        return "geometry"
    return f"geometry.beams.{m[1]}" + (f".points_mm[{m[2]}]" if m[2] else "")


def _check_width_solve(study: MechanismStudy, labels: Mapping[str, Requirement]) -> None:
    spec = study.solve_width_from
    assert spec is not None
    here = "solve_width_from.requirement"
    req = labels.get(spec.requirement)
    if not isinstance(req, Range | TargetBand):
        raise StudyError(
            here,
            f"'{spec.requirement}' is no range or target requirement; name one of: "
            + ", ".join(r for r, q in labels.items() if isinstance(q, Range | TargetBand)),
        )
    output = _quantity_output(study, req.quantity)
    if output is None or _exponent(study, output) != 1:
        raise StudyError(
            here,
            f"'{req.quantity}' does not scale with the width (only forces, moments and their "
            "slopes do); solve the width from a force requirement",
        )
    per_beam = [n for n, b in study.geometry.beams.items() if b.width_mm is not None]
    if per_beam:
        raise StudyError(
            f"geometry.beams.{per_beam[0]}.width_mm",
            "a beam of its own width does not scale with the shared width; remove width_mm here "
            "or drop solve_width_from",
        )
    for case, c in study.load_cases.items():
        if c.drive.control in ("force", "moment"):
            raise StudyError(
                f"load_cases.{case}.drive.control",
                "under force control the motion, not the force, changes with the width; drive "
                "by displacement or rotation to solve the width",
            )
    for i, v in enumerate(study.variables):
        if v.path.strip() == "geometry.width_mm":
            raise StudyError(
                f"variables[{i}].path", "the width is solved (solve_width_from); drop this variable"
            )


def _fea_path(study: MechanismStudy, case: str, message: str) -> str:
    """The key path a refusal of the engine is about: the joints for a free motion or a joint,
    the case's drive or supports when the message starts with them."""
    head = message.split(":", 1)[0]
    if "free rigid-body motion" in message or "joint" in head:
        return "geometry.joints"
    if "support" in head:
        return f"load_cases.{case}.supports"
    if "drive" in head:
        return f"load_cases.{case}.drive"
    return "geometry.joints"


def _fea_fix(message: str) -> str:
    if "free" in message and "add a joint" not in message:
        return f"{message}; add a joint or a support that holds it"
    return message


def _geometry_of(study: MechanismStudy, x: np.ndarray | None) -> MechanismGeometry:
    """The validated geometry of a design (``x`` None: the study's own)."""
    variables = _variables(study) if x is not None else None
    if variables is None:
        return study.geometry
    raw = variables.apply(_root(study), x)["geometry"]
    return MechanismGeometry.model_validate(raw)


def _beam_shapes(geometry: MechanismGeometry) -> list[BeamShape]:
    return [BeamShape(n, b.centreline(), b.thickness()) for n, b in geometry.beams.items()]


def _attachments(geometry: MechanismGeometry) -> list[Attachment]:
    out = []
    for j in geometry.joints:
        for own, other in ((j.a, j.b), (j.b, j.a)):
            end = _end_ref(own)
            if end is not None and (
                other == "ground" or other in geometry.bodies or _end_ref(other)
            ):
                out.append(Attachment(end[0], end[1], other))  # type: ignore[arg-type]
    return out


def _outline(geometry: MechanismGeometry) -> tuple[list[BeamShape], MechanismOutline]:
    shapes = _beam_shapes(geometry)
    bodies = [
        BodyShape(n, np.array(b.outline_mm, dtype=float))
        for n, b in geometry.bodies.items()
        if b.outline_mm is not None
    ]
    outline = mechanism_outline(
        shapes,
        bodies,
        _attachments(geometry),
        min_feature_mm=geometry.min_feature_mm,
        pad_length_mm=geometry.pad_length_mm,
        pad_thickness_mm=geometry.pad_thickness_mm,
        ground_outlines_mm=[np.array(o, dtype=float) for o in geometry.ground_outlines_mm],
        fillet_mm=geometry.fillet_mm,
        max_corner_deg=geometry.max_corner_deg,
    )
    for name, b in geometry.beams.items():
        _curvature_as_made(name, b, outline.beams[name])  # refuses what it cannot follow
    return shapes, outline


def _curvature_as_made(name: str, spec: BeamSpec, made: AsMadeBeam) -> np.ndarray | None:
    """``curvature_per_mm`` of the beam as made: a straight (0) value for each chord of a flare
    added on a straight end segment. Raises GeometryError for a clipped beam or a flared curved
    end segment (the flare is laid along the chord)."""
    if spec.curvature_per_mm is None:
        return None
    curv = list(spec.curvature_per_mm)
    if made.start.clipped_mm > 0 or made.end.clipped_mm > 0:
        raise GeometryError(
            f"beam '{name}' (geometry.beams.{name}.curvature_per_mm) runs into the body it is "
            "attached to; a beam of exact arcs must end on the body's outline"
        )
    for junction, k in ((made.start, 0), (made.end, -1)):
        if junction.fillet_mm > 0 and curv[k] != 0:
            raise GeometryError(
                f"beam '{name}' (geometry.beams.{name}.curvature_per_mm): its root fillet needs "
                "a straight end segment; give that segment curvature 0 (add a point)"
            )
    added = len(made.shape.points_mm) - len(spec.points_mm or ())
    n_start = FILLET_CHORDS if made.start.fillet_mm > 0 else 0
    return np.array([0.0] * n_start + curv + [0.0] * (added - n_start), dtype=float)


def _mechanism(
    study: MechanismStudy,
    geometry: MechanismGeometry,
    width_mm: float | None = None,
    made: Mapping[str, AsMadeBeam] | None = None,
):
    """The solver's mechanism; with ``made`` (``MechanismOutline.beams``) the beams as made:
    clipped at the bodies they enter, flared into their roots' fillets, with the flares' lengths
    as the roots whose stress the concentration factors multiply."""
    fm = _fea()
    width = geometry.width_mm if width_mm is None else width_mm
    beams = []
    for name, b in geometry.beams.items():
        curvature = None
        points, thickness, root = b.centreline(), b.thickness(), (0.0, 0.0)
        if made is not None:
            shape = made[name].shape
            points, thickness = shape.points_mm, shape.thickness_mm
            root = (made[name].start.root_mm, made[name].end.root_mm)
            curvature = _curvature_as_made(name, b, made[name])
        elif b.curvature_per_mm is not None:
            curvature = np.array(b.curvature_per_mm, dtype=float)
        beams.append(
            fm.MechBeam(
                name,
                points,
                thickness,
                float(b.width_mm if b.width_mm is not None else width),
                int(b.elements),
                curvature,
                root,
            )
        )
    bodies = [
        fm.MechBody(
            n,
            np.array(b.ref_mm, dtype=float),
            None if b.outline_mm is None else np.array(b.outline_mm, dtype=float),
        )
        for n, b in geometry.bodies.items()
    ]
    joints = [fm.MechJoint(j.a, j.b, j.type) for j in geometry.joints]
    material = study.material.to_material()
    return fm.Mechanism(tuple(beams), tuple(bodies), tuple(joints), material)


def _load_case(study: MechanismStudy, case: str):
    fm = _fea()
    spec = study.load_cases[case]
    d = spec.drive
    lo, hi = d.range
    factor = math.pi / 180.0 if d.control == "rotation" else 1.0
    drive = fm.MechDrive(
        d.part,
        d.control,
        hi * factor,
        d.steps,
        (float(d.direction[0]), float(d.direction[1])),
        d.transverse,
        d.rotation,
        lo * factor,
    )
    supports = tuple(fm.MechJoint(s.a, s.b, s.type) for s in spec.supports)
    return fm.LoadCase(case, drive, supports)


def _fea_outputs(study: MechanismStudy, case: str) -> list[Any]:
    fm = _fea()
    out = [fm.MechOutput("__drive_reaction", "reaction")]
    for name in _outputs_in(study, case):
        o = study.outputs[name]
        if o.quantity in ("slope", "ratio"):
            continue
        direction = (float(o.direction[0]), float(o.direction[1]))
        out.append(fm.MechOutput(name, o.quantity, o.part, direction))
    return out


# --------------------------------------------------------------------------------------------
# One design


@dataclasses.dataclass
class _Solved:
    """Everything one design's solve gives (before and after the width is solved)."""

    geometry: MechanismGeometry
    shapes: list[BeamShape]
    outline: MechanismOutline
    width_mm: float
    responses: dict[str, Any]  # case -> MechanismResponse (at the reference width)
    tables: dict[str, dict[str, np.ndarray]]  # case -> columns (width solved)
    metrics: dict[str, Any]
    curves_table: dict[str, np.ndarray]  # every case's columns, prefixed: what requirements read
    reason: str = ""
    clearance: dict[str, Any] = dataclasses.field(default_factory=dict)  # _interference()
    fidelity: dict[str, Any] | None = None  # the check of the exported outline (detail, evaluate)


def _case_table(
    study: MechanismStudy,
    case: str,
    response: Any,
    scale: float,
    made: Mapping[str, AsMadeBeam] | None = None,
) -> dict[str, np.ndarray]:
    """The case's response as columns (forces scaled by ``scale`` = width / reference width);
    with ``made`` the stresses are the beams' as made (:func:`_as_made_stress`)."""
    spec = study.load_cases[case]
    d = spec.drive
    drive = np.asarray(response.drive, dtype=float)
    if d.control == "rotation":
        drive = np.degrees(drive)
    force_like = d.control in ("displacement", "rotation")
    reaction = np.asarray(response.outputs["__drive_reaction"], dtype=float)
    table: dict[str, np.ndarray] = {
        "step": np.arange(len(drive)),
        f"drive_{d.unit}": drive,
        f"drive_reaction_{_REACTION_UNIT[d.control]}": reaction * (scale if force_like else 1.0),
    }
    for name in _outputs_in(study, case):
        o = study.outputs[name]
        if o.quantity in ("slope", "ratio"):
            continue
        values = np.asarray(response.outputs[name], dtype=float)
        if o.quantity == "rotation" and unit_of(name) == "deg":
            values = np.degrees(values)
        table[name] = values * scale ** _exponent(study, name)
    pending = [n for n in _outputs_in(study, case) if n not in table]
    for _ in range(len(pending) + 1):  # derived outputs may build on each other
        for name in list(pending):
            o = study.outputs[name]
            refs = [o.of] if isinstance(o.of, str) else list(o.of or ())
            if not all(r in table for r in refs):
                continue
            if o.quantity == "slope":
                y = table[refs[0]]
                table[name] = np.gradient(y, drive) if len(drive) > 2 else np.full_like(y, np.nan)
            else:
                with np.errstate(divide="ignore", invalid="ignore"):
                    ratio = table[refs[0]] / table[refs[1]]
                table[name] = np.where(np.isfinite(ratio), ratio, np.nan)
            pending.remove(name)
    for name in pending:  # refers to an output not read in this case
        table[name] = np.full(len(drive), np.nan)
    per_beam = _as_made_stress(response, made)
    for name in _outputs_in(study, case):  # a peak stress output reads the roots' factors too
        o = study.outputs[name]
        if o.quantity == "peak_stress" and made is not None:
            i = list(made).index(o.part) if o.part in made else None
            table[name] = np.nanmax(per_beam, axis=1) if i is None else per_beam[:, i]
    table["peak_stress_MPa"] = np.nanmax(per_beam, axis=1)
    table["converged"] = np.asarray(response.converged, dtype=bool)
    table["stable"] = np.asarray(response.stable, dtype=bool)
    return _stable_part(table, response)


def _solve_printed_path(study: MechanismStudy, mech: Any, case: str) -> Any:
    """The case solved along the path the printed part follows (issue 22, item 3).

    The mechanism as drawn is solved first. Where its path loses stability (a bifurcation: a
    symmetric switch's asymmetric mode), the made part, never perfectly symmetric, leaves the
    traced path there: it is solved again with its stress-free shape moved
    ``study.imperfection_mm`` along the buckling mode (:func:`fea.mechanism.imperfect_mechanism`)
    and that response is the case's. The part as exported keeps the drawn shape. Rows that are
    still unstable are cut by :func:`_stable_part`. The case's message says which path it is.
    """
    fm = _fea()
    load_case = _load_case(study, case)
    outputs = _fea_outputs(study, case)
    response = fm.solve_mechanism(mech, load_case, outputs)
    row = fm.first_unstable_row(response)
    amplitude = float(study.imperfection_mm)
    unit = study.load_cases[case].drive.unit

    def shown(value: float) -> str:
        return f"{math.degrees(value) if unit == 'deg' else value:.4g} {unit}"

    notes = []
    if row is not None and amplitude > 0.0 and response.critical_mode is not None:
        notes.append(
            f"the part as drawn bifurcates at drive {shown(response.critical_drive)}: the "
            f"responses are those of the part with a {amplitude:g} mm imperfection along its "
            "buckling mode (imperfection_mm), the branch a printed part follows"
        )
        response = fm.solve_mechanism(
            fm.imperfect_mechanism(mech, response, amplitude), load_case, outputs
        )
        row = fm.first_unstable_row(response)
    if row is not None:
        notes.append(
            f"the curve stops at row {row} (drive {shown(float(response.drive[row]))}): from "
            "there the path is unstable, and no output or requirement reads it"
        )
    if not notes:
        return response
    message = "; ".join([response.message, *notes] if response.message else notes)
    return dataclasses.replace(response, message=message)


def _stable_part(table: dict[str, np.ndarray], response: Any) -> dict[str, np.ndarray]:
    """The table with every value from the first unstable row on set to NaN: no requirement,
    metric or plot reads a value beyond a point the part cannot pass on that path (the rows,
    their drive and their flags are kept; the case's message says where the curve stops)."""
    row = _fea().first_unstable_row(response)
    if row is None:
        return table
    keep = {"step", "converged", "stable"} | {k for k in table if k.startswith("drive_")}
    keep.discard(next((k for k in table if k.startswith("drive_reaction_")), ""))
    out = dict(table)
    for key, col in table.items():
        if key not in keep:
            arr = np.asarray(col, dtype=float).copy()
            arr[row:] = np.nan
            out[key] = arr
    return out


def _stat(values: np.ndarray, how: str) -> float | None:
    v = np.asarray(values, dtype=float)
    finite = v[np.isfinite(v)]
    if how in ("end", "start"):
        x = v[-1] if how == "end" else v[0]
        return float(x) if np.isfinite(x) else None
    if not finite.size:
        return None
    if how == "mean":
        return float(np.mean(finite))
    if how == "first_peak":  # the first local maximum along the drive: a snap-through force
        y = v[np.isfinite(v)]
        for k in range(1, len(y) - 1):
            if y[k] >= y[k - 1] and y[k] > y[k + 1]:
                return float(y[k])
        return None
    return float(
        {"max": np.max, "min": np.min, "max_abs": lambda a: np.max(np.abs(a))}[how](finite)
    )


def _as_the_optimiser_judges(study: MechanismStudy, solved: _Solved) -> _Solved:
    """``solved`` with its peak stresses times ``fidelity.beam_stress_factor``: the optimiser
    solves every design with the beam model, and the reported design's check of its exported
    outline finds the peak a few % higher (the verdict reads the larger figure,
    :func:`~pipeline.studies._mechanism_fidelity.with_fidelity`), so the optimiser holds the
    beam model's stress times the ratio measured on the study's designs. Only the optimiser's
    evaluations (evaluations.csv) carry the factor; the reported design is the check's."""
    factor = float(study.fidelity.beam_stress_factor)
    if factor == 1.0 or not study.fidelity.enabled:
        return solved
    metrics = dict(solved.metrics)
    for key, value in solved.metrics.items():
        stress = key.endswith("max_peak_stress_MPa") or key.endswith("stress_yield_ratio")
        if stress and isinstance(value, int | float) and value is not None:
            metrics[key] = float(value) * factor
    tables = {
        case: {
            k: np.asarray(v, float) * factor if k == "peak_stress_MPa" else v
            for k, v in table.items()
        }
        for case, table in solved.tables.items()
    }
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
    interference over the stroke (:func:`_interference`) and the envelope as exported. One place
    for the solve and for the check of the exported outline, which solves the width again."""
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
    fm = _fea()
    m: dict[str, Any] = {}
    peaks = []
    unstable = 0
    for case, table in tables.items():
        p = _prefix(study, case)
        spec = study.load_cases[case].drive
        drive = table[f"drive_{spec.unit}"]
        reaction = table[f"drive_reaction_{_REACTION_UNIT[spec.control]}"]
        if spec.control in ("displacement", "rotation"):
            count, second = _fea().stable_positions(drive, reaction)
        else:
            count, second = None, None
        m[f"{p}stable_positions"] = count
        m[f"{p}second_stable_position_{spec.unit}"] = second
        peak = _stat(table["peak_stress_MPa"], "max")
        m[f"{p}max_peak_stress_MPa"] = peak
        peaks.append(peak if peak is not None else math.nan)
        unstable += int(np.sum(table["converged"] & ~table["stable"]))
        for name in _outputs_in(study, case):
            for how in _STATS:
                m[f"{p}{how}_{name}"] = _stat(table[name], how)
    peak_all = float(np.nanmax(peaks)) if np.isfinite(peaks).any() else None
    m["max_peak_stress_MPa"] = peak_all
    m["stress_yield_ratio"] = None if peak_all is None else peak_all / material.yield_MPa
    m["width_mm"] = float(width_mm)
    m["min_thickness_mm"] = float(min(np.min(b.thickness()) for b in geometry.beams.values()))
    mech = _mechanism(study, geometry, width_mm, made)
    mass = fm.mass_g(mech, body_thickness_mm=width_mm)
    m["mass_g"] = float(mass) if math.isfinite(mass) else None
    m["stable"] = unstable == 0
    m["unstable_rows"] = unstable
    return m


def _curves_table(
    study: MechanismStudy, tables: Mapping[str, Mapping[str, np.ndarray]]
) -> dict[str, np.ndarray]:
    out = {}
    for case, table in tables.items():
        p = _prefix(study, case)
        ok = np.asarray(table["converged"], dtype=bool)
        for key, col in table.items():
            if key in ("converged", "stable", "step"):
                continue
            arr = np.asarray(col, dtype=float).copy()
            arr[~ok] = np.nan
            out[f"{p}{key}"] = arr
    return out


def _solve_width(
    study: MechanismStudy,
    req: Requirement,
    ref_tables: Mapping[str, Mapping[str, np.ndarray]],
    ref_width: float,
) -> tuple[float, str]:
    """The width that puts a force-like requirement in the middle of its bound, and why not."""
    reference = _curves_table(study, ref_tables)
    if isinstance(req, Range):
        metrics = _metrics(
            study, study.geometry, ref_tables, ref_width, study.material.to_material()
        )
        value = metrics.get(req.quantity)
        if value is None or not math.isfinite(value):
            return math.nan, f"{req.quantity} was not computed at the reference width"
        target = 0.5 * (req.minimum + req.maximum)
        if value == 0 or target / value <= 0:
            return math.nan, (
                f"{req.quantity} = {value:.4g} at the reference width cannot be scaled to "
                f"{target:.4g} (opposite sign or zero)"
            )
        return ref_width * target / value, ""
    assert isinstance(req, TargetBand)
    x = reference.get(req.x)
    y = reference.get(req.quantity)
    if x is None or y is None:
        return math.nan, f"no {req.quantity}({req.x}) to solve the width from"
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    if req.over is not None:
        inside = (x >= req.over[0]) & (x <= req.over[1])
        x, y = x[inside], y[inside]
    t = req._target_in_y_units(x)  # noqa: SLF001 - the target in the column's unit
    use = np.abs(t) > 1e-12 * max(1.0, float(np.max(np.abs(t), initial=0.0)))
    if not use.any() or not np.any(np.abs(y[use]) > 0):
        return math.nan, f"{req.quantity} is zero where the target is not; nothing to scale"
    if req.tolerance_rel is not None:
        r = y[use] / t[use]
        if np.any(r <= 0):
            return math.nan, f"{req.quantity} has the wrong sign against its target"
        # the scale that centres the ratio y/t in the relative band (minimax)
        scale = 2.0 / (float(np.max(r)) + float(np.min(r)))
    else:
        scale = float(np.dot(y, t) / np.dot(y, y))  # least squares to an absolute band
        if not scale > 0:
            return math.nan, f"{req.quantity} has the wrong sign against its target"
    return ref_width * scale, ""


class MechanismProblem(DesignProblem):
    """The :class:`optimise.DesignProblem` of a ``mechanism`` study (picklable, deterministic,
    never raises for a bad design)."""

    def warm_up(self) -> None:
        """Load the compiled beam, constrained-beam and mechanism kernels (a pool calls this
        before it forks its workers, :func:`pipeline.backends.open_backend`)."""
        from flexopt.fea.mechanism import warm_up

        warm_up()  # calls fea.constrained_beams.warm_up (and so fea.beam's) first

    def __init__(self, study: MechanismStudy) -> None:
        self.study = study
        self.variables = _variables(study)
        if self.variables is None:
            raise StudyError(
                "variables",
                "flexopt run needs design variables; add variables: [{path, bounds}] (see "
                "docs/mechanism.md) or use flexopt evaluate",
            )
        self.space: DesignSpace = self.variables.space
        self.material = study.material.to_material()
        self.requirements = _requirements(study) + _solved_size_requirements(study)
        self.labels = {r.label: r for r in self.requirements}
        objectives = list(study.objectives) or self._default_objectives()
        self.objectives = tuple(o.key for o in objectives)
        self.objective_names = tuple(self._objective_name(k, n) for k, n in self.objectives)
        self.constraints = _curve_constraints(self.requirements)
        self.constraint_names = (*(f"req_{r.label}" for r in self.constraints), "no_interference")

    def _default_objectives(self) -> list[ObjectiveSpec]:
        for r in self.requirements:
            if isinstance(r, TargetBand):
                return [ObjectiveSpec(target_error=r.label)]
        return [ObjectiveSpec(minimise="mass_g")]

    def _objective_name(self, key: str, name: str) -> str:
        if key == "minimise":
            return name
        if key == "maximise":
            return f"negative_{name}"
        req = self.labels[name]
        if key == "target_error":
            return f"{_slug(name)}_rms_error_{_unit_suffix(req.quantity)}"
        return f"negative_{_slug(name)}_band_stroke_{_unit_suffix(getattr(req, 'x', ''))}"

    def nominal_design(self) -> np.ndarray:
        """(n_var,) the study's initial design (what ``flexopt evaluate`` solves)."""
        assert self.variables is not None
        return np.asarray(self.variables.initial, dtype=float)

    def initial_designs(self) -> np.ndarray:
        """The study's initial design seeds the first population."""
        assert self.variables is not None
        return self.space.clip(self.variables.initial)[None, :]

    # ---- solving

    def solve(self, x: np.ndarray | None) -> _Solved | tuple[None, str]:
        """Build, check and solve one design; ``(None, reason)`` when it cannot be."""
        study = self.study
        try:
            geometry = _geometry_of(study, x)
        except ValidationError as exc:
            err = exc.errors(include_url=False)[0]
            loc = ".".join(str(p) for p in err["loc"])
            return None, f"invalid geometry: geometry.{loc}: {err['msg']}"
        try:
            shapes, outline = _outline(geometry)
        except GeometryError as exc:
            return None, f"invalid geometry: {exc}"
        mech = _mechanism(study, geometry, made=outline.beams)
        responses = {}
        for case in study.load_cases:
            try:
                response = _solve_printed_path(study, mech, case)
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
        if study.solve_width_from is not None and not reason:
            req = self.labels[study.solve_width_from.requirement]
            width, why = _solve_width(study, req, ref, geometry.width_mm)
            if why:
                reason = f"width not solved: {why}"
        if not math.isfinite(width):
            width = geometry.width_mm
        scale = width / geometry.width_mm
        tables = {c: _case_table(study, c, r, scale, outline.beams) for c, r in responses.items()}
        clearance = _interference(study, geometry, outline, responses)
        metrics = _part_metrics(study, geometry, outline, tables, width, self.material, clearance)
        return _Solved(
            geometry, shapes, outline, width, responses, tables, metrics,
            _curves_table(study, tables), reason, clearance,
        )  # fmt: skip

    def verdicts(self, solved: _Solved) -> tuple[Verdict, ...]:
        return annotate(self._verdicts(solved), solved)

    def _verdicts(self, solved: _Solved) -> tuple[Verdict, ...]:
        curves = {}
        for r in self.requirements:
            if isinstance(r, TargetBand):
                x = solved.curves_table.get(r.x)
                y = solved.curves_table.get(r.quantity)
                if x is not None and y is not None:
                    curves[r.quantity] = (x, y)
        values = dict(solved.metrics)
        for key, col in solved.curves_table.items():  # a column judged by its worst value
            if key not in values:
                values[key] = _stat(col, "max_abs")
        judged = tuple(r.check(values, curves) for r in self.requirements)
        return (*judged, _interference_verdict(solved))

    def _objective_values(self, solved: _Solved) -> np.ndarray:
        out = []
        for key, name in self.objectives:
            if key in ("minimise", "maximise"):
                value = solved.metrics.get(name)
                if value is None or not math.isfinite(float(value)):
                    out.append(INFEASIBLE_VALUE)
                else:
                    out.append(float(value) if key == "minimise" else -float(value))
                continue
            req = self.labels[name]
            assert isinstance(req, TargetBand)
            x = solved.curves_table.get(req.x)
            y = solved.curves_table.get(req.quantity)
            out.append(_target_objective(req, x, y, key))
        return np.array(out, dtype=float)

    def _evaluation(self, x: np.ndarray, solved: _Solved, t0: float) -> Evaluation:
        verdicts = self.verdicts(solved)
        metrics = dict(solved.metrics)
        metrics["verdict"] = "MET" if verdicts and all(v.met for v in verdicts) else "NOT MET"
        f = self._objective_values(solved)
        g = []
        for r in self.constraints:
            v = next(v for v in verdicts if v.name == r.label)
            g.append(-v.margin / r.scale() if math.isfinite(v.margin) else 1.0e6)
        # no interference: the overlap area (mm^2) when parts interfere, else minus the smallest
        # clearance (mm), so that the optimiser is drawn away from touching parts
        area = solved.metrics.get("interference_mm2")
        gap = solved.metrics.get("min_clearance_mm")
        g.append(1.0e6 if area is None else area if area > _INTERFERENCE_MM2 else -(gap or 0.0))
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

    def detail(self, x: np.ndarray) -> DesignDetail:
        t0 = time.perf_counter()
        solved = self.solve(x)
        if not isinstance(solved, tuple):
            solved = with_fidelity(self, solved, sys.modules[__name__])
        if isinstance(solved, tuple):
            ev = Evaluation.failed(
                x, len(self.objective_names), len(self.constraint_names), solved[1],
                time.perf_counter() - t0,
            )  # fmt: skip
            return DesignDetail(ev, info={"reason": solved[1]})
        ev = self._evaluation(x, solved, t0)
        verdicts = self.verdicts(solved)
        first = next(iter(solved.tables))
        kwargs: dict[str, Any] = {}
        if "verdicts" in {f.name for f in dataclasses.fields(DesignDetail)}:
            kwargs["verdicts"] = verdicts
        return DesignDetail(
            evaluation=ev,
            table=solved.tables[first],
            plot={
                **_plot_spec(self.study, first, self.material),
                **band_spec(
                    self.requirements,
                    solved.tables[first],
                    _plot_spec(self.study, first, self.material)["x"],
                    "y",
                    _prefix(self.study, first),
                ),  # a target band, drawn
            },  # fmt: skip
            outline=solved.outline.polygon,
            height_mm=solved.width_mm,
            info={
                **_info(self.study, solved),
                "verdicts": [_verdict_json(v) for v in verdicts],
            },
            files=_files(self.study, solved, self.requirements),
            cases=_cases(self.study, solved, self.material, self.requirements),
            **kwargs,
        )


def _curve_constraints(requirements: Sequence[Requirement]) -> tuple[Requirement, ...]:
    """The ``role: constraint`` requirements this problem turns into ``g`` rows itself: those
    judged on a response curve (a target band). Scalar ones are added by the pipeline for every
    kind (:func:`pipeline.verdict.with_requirement_constraints`) from the evaluation's metrics,
    which carry every scalar metric of the design (the solved width included)."""
    return tuple(r for r in requirements if r.role == "constraint" and r.needs_curve)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_")


def _unit_suffix(quantity: str) -> str:
    unit = unit_of(quantity)
    return {"N·mm": "Nmm", "N/mm": "N_per_mm", "": "1"}.get(unit, unit)


def _target_objective(
    req: TargetBand, x: np.ndarray | None, y: np.ndarray | None, key: str
) -> float:
    """RMS error to the target over its range (unit of the quantity), or minus the longest
    stretch of x inside the band (unit of x); :data:`INFEASIBLE_VALUE` without a response."""
    if x is None or y is None:
        return INFEASIBLE_VALUE
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    if x.size < 2:
        return INFEASIBLE_VALUE
    order = np.argsort(x)
    x, y = x[order], y[order]
    lo, hi = (x[0], x[-1]) if req.over is None else req.over
    if x[0] > lo + 1e-9 or x[-1] < hi - 1e-9:
        return INFEASIBLE_VALUE
    xs = np.linspace(lo, hi, 201)
    ys = np.interp(xs, x, y)
    t = req._target_in_y_units(xs)  # noqa: SLF001
    if key == "target_error":
        return float(np.sqrt(np.mean((ys - t) ** 2)))
    band = (
        np.full_like(t, float(req.tolerance))
        if req.tolerance is not None
        else float(req.tolerance_rel) * np.abs(t)  # type: ignore[arg-type]
    )
    inside = np.abs(ys - t) <= band
    best = run = 0
    for flag in inside:
        run = run + 1 if flag else 0
        best = max(best, run)
    step = (hi - lo) / (len(xs) - 1)
    rms = float(np.sqrt(np.mean((ys - t) ** 2)))
    # the RMS error orders designs that hold no stretch of the band (a tie-breaker)
    return -max(0.0, (best - 1) * step) + 1e-3 * (hi - lo) * rms / max(float(np.max(band)), 1e-12)


def _verdict_json(v: Verdict) -> dict[str, Any]:
    def num(value: float | None) -> float | None:
        return None if value is None or not math.isfinite(value) else float(value)

    return {
        "name": v.name, "quantity": v.quantity, "value": num(v.value), "bound": v.bound,
        "margin": num(v.margin), "verdict": v.word, "role": v.role, "detail": v.detail,
    }  # fmt: skip


def _plot_spec(study: MechanismStudy, case: str, material: Material) -> dict[str, Any]:
    d = study.load_cases[case].drive
    return {
        "x": f"drive_{d.unit}",
        "y": f"drive_reaction_{_REACTION_UNIT[d.control]}",
        "stress": "peak_stress_MPa",
        "allowable_MPa": material.yield_MPa,
    }


def _cases(
    study: MechanismStudy,
    solved: _Solved,
    material: Material,
    requirements: Sequence[Requirement],
) -> dict[str, CaseResponse]:
    """Every load case's table, plot spec (with its target band) and the user's outputs in it:
    what the pipeline draws and tabulates for each case (pipeline/responses.py)."""
    out = {}
    for case, table in solved.tables.items():
        plot = _plot_spec(study, case, material)
        plot.update(band_spec(requirements, table, plot["x"], "y", _prefix(study, case)))
        d = study.load_cases[case].drive
        plot["x_label"] = f"drive of {d.part} ({d.control}, {d.unit})"
        out[case] = CaseResponse(table, plot, tuple(_outputs_in(study, case)))
    return out


def _info(study: MechanismStudy, solved: _Solved) -> dict[str, Any]:
    g = solved.geometry
    return {
        "width_mm": solved.width_mm,
        "width_solved": study.solve_width_from is not None,
        "outline_area_mm2": solved.outline.area_mm2,
        "beams": {
            n: {
                "points_mm": b.centreline().round(6).tolist(),
                "thickness_mm": b.thickness().round(6).tolist(),
                **_as_made_info(solved.outline.beams.get(n)),
            }
            for n, b in g.beams.items()
        },
        "clearance": dict(solved.clearance),
        "bodies": {n: {"ref_mm": list(b.ref_mm)} for n, b in g.bodies.items()},
        "cases": {c: {"ok": bool(r.ok), "message": r.message} for c, r in solved.responses.items()},
        **({"fidelity": solved.fidelity} if solved.fidelity is not None else {}),
    }


# --------------------------------------------------------------------------------------------
# The part as made: its roots' stress and its parts' clearance over the stroke


def _as_made_stress(response: Any, made: Mapping[str, AsMadeBeam] | None) -> np.ndarray:
    """(rows, beams) peak stress of each beam as made, MPa: the beam model's peak, and at each
    filleted root the shoulder's Kt times the largest beam-model stress over the root's flare
    (``EndJunction.kt``, :func:`geometry.mechanism.shoulder_kt`): the flare is modelled as a
    thickening beam, whose stress at the fillet's toe is the nominal stress Kt multiplies."""
    peak = np.asarray(response.peak_stress_MPa, dtype=float)
    roots = np.asarray(getattr(response, "root_stress_MPa", np.zeros((0, 0, 2))), dtype=float)
    if made is None or roots.shape[:2] != peak.shape:
        return peak
    kt = np.array([[m.start.kt, m.end.kt] for m in made.values()], dtype=float)  # (beams, 2)
    with np.errstate(invalid="ignore"):
        return np.fmax(peak, np.max(roots * kt[None], axis=2))


#: Overlap area (mm^2) of two deformed parts that counts as interference (round-off of bands
#: built from the solver's node positions is far smaller).
_INTERFERENCE_MM2 = 1e-3


def _deformed_bands(points_mm: np.ndarray, thickness_mm: np.ndarray) -> np.ndarray:
    """A beam as a band of its thickness along its deformed centreline at every row: nodes
    (rows, n, 2) mm and thickness (n,) mm -> (rows,) shapely Polygons. Both edges are offset at
    the nodes along the mitred normals (by ``t / 2 / cos(turn / 2)``, so a kink's outer corner
    is the mitre, which holds the round corner of the material: a touch of extra material,
    never less); one polygon per row, made for all rows at once."""
    import shapely

    p = np.asarray(points_mm, dtype=float)
    d = np.diff(p, axis=1)
    u = d / np.linalg.norm(d, axis=2, keepdims=True)
    tangent = np.concatenate([u[:, :1], u[:, :-1] + u[:, 1:], u[:, -1:]], axis=1)
    tangent /= np.linalg.norm(tangent, axis=2, keepdims=True)
    cos_half = np.ones(p.shape[:2])
    cos_half[:, 1:-1] = np.sum(u[:, :-1] * tangent[:, 1:-1], axis=2)  # cos of half the turn
    normal = np.stack([-tangent[..., 1], tangent[..., 0]], axis=2)
    half = 0.5 * np.asarray(thickness_mm, dtype=float)[None, :] / np.maximum(cos_half, 0.5)
    offset = half[..., None] * normal
    bands = shapely.polygons(np.concatenate([p + offset, (p - offset)[:, ::-1]], axis=1))
    bad = ~shapely.is_valid(bands)
    if bad.any():  # an inner edge folded at a kink
        bands[bad] = shapely.buffer(bands[bad], 0.0)
    return bands


def _interference(
    study: MechanismStudy,
    geometry: MechanismGeometry,
    outline: MechanismOutline,
    responses: Mapping[str, Any],
) -> dict[str, Any]:
    """Interference and clearance of the deformed parts at every converged row of every case.

    Parts: every beam as a band of its thickness along its deformed centreline (the beams as
    made), every body at its pose, the grounded ends' pads and the ground outlines (fixed).
    A beam's roots (a disc about each held end: its fillets) are left out, and parts joined there
    (a beam end and its body, its pad or the beam end it is joined to; a grounded end and the
    ground outlines) are checked only for overlap elsewhere; every other pair also for its
    distance. Each pair is checked at all rows of a case at once (shapely's array functions).

    Returns
    -------
    dict — ``min_clearance_mm`` (float | None: the smallest distance between parts that are not
    joined, over every row; None with fewer than two such parts), ``clearance_at`` (text: case,
    row, drive and the parts), ``interference_mm2`` (largest overlap area of any row, mm^2, 0
    when none) and ``interference_at`` (text, "" when none).
    """
    import shapely
    from shapely.geometry import Polygon

    made = outline.beams
    held = {(a.beam, a.end): a.to for a in _attachments(geometry)}
    grounded_bodies = {j.a for j in geometry.joints if j.b == "ground" and j.a in geometry.bodies}
    fixed = [(f"pad {k}", g) for k, g in outline.pads.items()]
    fixed += [(f"ground outline [{k}]", Polygon(np.array(o, dtype=float)))
              for k, o in enumerate(geometry.ground_outlines_mm)]  # fmt: skip
    best: tuple[float, str] = (math.inf, "")
    worst: tuple[float, str] = (0.0, "")
    for case, resp in responses.items():
        rows = np.flatnonzero(np.asarray(resp.converged, dtype=bool))
        if rows.size == 0:
            continue
        d = study.load_cases[case].drive
        drive = np.asarray(resp.drive, dtype=float)
        if d.control == "rotation":
            drive = np.degrees(drive)

        at = [f"load case {case}, row {r} (drive {drive[r]:.4g} {d.unit})" for r in rows]
        parts: list[tuple[str, Any, set[str]]] = []  # label, (rows,) shapes, what it is joined to
        for i, name in enumerate(geometry.beams):
            pts = np.asarray(resp.shapes_mm[i], dtype=float)[rows]
            t = np.asarray(resp.thickness_at_nodes_mm[i], dtype=float)
            free = _deformed_bands(pts, t)
            joined: set[str] = set()
            for end, k in (("start", 0), ("end", -1)):
                to = held.get((name, end))
                if to is None:
                    continue
                junction = made[name].start if end == "start" else made[name].end
                radius = 0.5 * t[k] + 1.5 * junction.fillet_mm + 1e-3
                if to not in ("ground", *geometry.bodies):  # another beam's end
                    radius = 2.0 * t[k]
                    joined.add(f"beam {to.rsplit('.', 1)[0]}")
                elif to == "ground":  # its own pad, and the ground outlines holding it
                    joined |= {f"pad {name}.{end}"} | {
                        label for label, _ in fixed if label.startswith("ground outline")
                    }
                else:
                    joined.add(f"body {to}")
                discs = shapely.buffer(shapely.points(pts[:, k]), radius, quad_segs=8)
                free = shapely.difference(free, discs)
            parts.append((f"beam {name}", free, joined))
        for k_body, (name, b) in enumerate(geometry.bodies.items()):
            if b.outline_mm is None:
                continue
            pose = np.asarray(resp.body_poses, dtype=float)[rows, k_body]  # (R, 3)
            c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
            rel = np.array(b.outline_mm, dtype=float) - np.array(b.ref_mm, dtype=float)
            xy = np.stack(
                [c[:, None] * rel[:, 0] - s[:, None] * rel[:, 1] + pose[:, :1],
                 s[:, None] * rel[:, 0] + c[:, None] * rel[:, 1] + pose[:, 1:2]],
                axis=2,
            )  # fmt: skip
            joined = {label for label, _ in fixed} if name in grounded_bodies else set()
            parts.append((f"body {name}", shapely.polygons(xy), joined))
        everything = [*parts, *((label, g, set()) for label, g in fixed)]
        for i, (la, ga, ja) in enumerate(parts):
            for lb, gb, jb in everything[i + 1 :]:
                area = np.zeros(rows.size)
                hit = shapely.intersects(ga, gb)
                if hit.any():
                    gb_hit = gb[hit] if isinstance(gb, np.ndarray) else gb
                    area[hit] = shapely.area(shapely.intersection(ga[hit], gb_hit))
                k = int(np.argmax(area))
                if area[k] > max(worst[0], _INTERFERENCE_MM2):
                    worst = (float(area[k]), f"{at[k]}: {la} passes through {lb} "
                             f"({area[k]:.3g} mm²)")  # fmt: skip
                if lb not in ja and la not in jb:
                    gap = shapely.distance(ga, gb)
                    k = int(np.argmin(gap))
                    if gap[k] < best[0]:
                        best = (float(gap[k]), f"{at[k]}: {la} and {lb}")
    return {
        "min_clearance_mm": None if not math.isfinite(best[0]) else best[0],
        "clearance_at": best[1],
        "interference_mm2": worst[0],
        "interference_at": worst[1],
    }


def _as_made_info(made: AsMadeBeam | None) -> dict[str, Any]:
    """What of a beam was clipped (rigid, inside its body) and filleted, [start, end]."""
    if made is None:
        return {}
    ends = (made.start, made.end)
    return {
        "clipped_mm": [round(e.clipped_mm, 6) for e in ends],
        "fillet_mm": [round(e.fillet_mm, 6) for e in ends],
        "root_kt": [round(e.kt, 4) for e in ends],
    }


def _interference_verdict(solved: _Solved) -> Verdict:
    """The built-in requirement of every mechanism: no part passes through another at any row
    of any load case (contact is not modelled, so a part that would touch is NOT MET)."""
    area = solved.metrics.get("interference_mm2")
    info = solved.clearance
    clearance = info.get("min_clearance_mm")
    shown = (
        ""
        if clearance is None
        else f"; smallest clearance {clearance:.3g} mm at {info['clearance_at']}"
    )
    met = area is not None and area <= _INTERFERENCE_MM2
    detail = (info.get("interference_at") or "no interference at any row") + shown
    return Verdict(
        name="no_interference",
        quantity="interference_mm2",
        value=float(area) if area is not None else math.nan,
        bound="0 mm² at every row (contact is not modelled)",
        margin=0.0 - float(area) if area is not None else math.nan,
        margin_rel=None,
        met=bool(met),
        unit="mm²",
        role="constraint",
        detail=detail,
    )


# --------------------------------------------------------------------------------------------
# Plots and files


def _png(fig: Any) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    return buffer.getvalue()


def _figure(n_panels: int, width: float = 5.2, height: float = 4.2):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width * n_panels, height), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, n_panels, squeeze=False)[0]
    return fig, axes


def shapes_png(study: MechanismStudy, solved: _Solved, title: str, n_shapes: int = 4) -> bytes:
    """One panel per load case: the part at a few rows, each beam drawn as its band at its own
    thickness along the deformed centreline, the bodies moved with their poses; grey: row 0."""
    from matplotlib.patches import Polygon as Patch

    def draw(ax: Any, poly: Any, colour: str, alpha: float) -> None:
        geoms = getattr(poly, "geoms", [poly])
        for gm in geoms:
            if gm.is_empty:
                continue
            ax.add_patch(Patch(np.asarray(gm.exterior.coords), closed=True, fc=colour,
                               ec=colour, alpha=alpha, lw=0.5))  # fmt: skip

    fig, axes = _figure(len(solved.responses), 5.5, 5.0)
    geometry = solved.geometry
    bodies = [(n, b) for n, b in geometry.bodies.items()]
    for ax, (case, response) in zip(axes, solved.responses.items(), strict=True):
        ok = np.flatnonzero(np.asarray(response.converged, bool))
        rows = ok[
            np.unique(np.linspace(0, len(ok) - 1, min(n_shapes, len(ok))).round().astype(int))
        ]
        draw(ax, solved.outline.polygon, "0.75", 0.6)
        cmap = __import__("matplotlib").colormaps["viridis"]
        for j, row in enumerate(rows):
            colour = cmap(j / max(1, len(rows) - 1))
            for i in range(len(geometry.beams)):
                pts = np.asarray(response.shapes_mm[i][row], dtype=float)
                t = np.asarray(response.thickness_at_nodes_mm[i], dtype=float)
                # the band the interference check uses (a disc per node would bulge at the
                # roots' flares, where the thickness changes fast)
                draw(ax, _deformed_bands(pts[None], t)[0], colour, 0.55)
            for k, (_, body) in enumerate(bodies):
                if body.outline_mm is None:
                    continue
                x, y, th = response.body_poses[row, k]
                ref = np.array(body.ref_mm, dtype=float)
                rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
                corners = (np.array(body.outline_mm, float) - ref) @ rot.T + np.array([x, y])
                ax.add_patch(Patch(corners, closed=True, fc=colour, ec="k", alpha=0.35, lw=0.5))
        d = study.load_cases[case].drive
        drive = np.asarray(response.drive, float)[rows]
        if d.control == "rotation":
            drive = np.degrees(drive)
        ax.set_title(f"{case}: drive " + ", ".join(f"{v:.3g}" for v in drive) + f" {d.unit}")
        ax.set_aspect("equal")
        ax.autoscale_view()
        ax.grid(True, alpha=0.3)
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
    fig.suptitle(title)
    return _png(fig)


def _files(
    study: MechanismStudy, solved: _Solved, requirements: Sequence[Requirement]
) -> dict[str, bytes]:
    # (outputs.png, every case's outputs on the axis of their unit, is the pipeline's: cases=)
    files = {"deformed_shapes.png": shapes_png(study, solved, f"{study.name}: deformed shapes")}
    if len(solved.tables) > 1:
        for case, table in solved.tables.items():
            files[f"response_{case}.csv"] = table_to_csv(table).encode("utf-8")
    return files


# --------------------------------------------------------------------------------------------
# Registry hooks


def problem(study: MechanismStudy) -> MechanismProblem:
    """The design problem ``flexopt run`` optimises."""
    return MechanismProblem(study)


class _Evaluator(MechanismProblem):
    """The problem's machinery for ``flexopt evaluate`` (variables are optional there)."""

    def __init__(self, study: MechanismStudy) -> None:  # noqa: D107
        self.study = study
        self.variables = _variables(study)
        self.material = study.material.to_material()
        self.requirements = _requirements(study) + _solved_size_requirements(study)
        self.labels = {r.label: r for r in self.requirements}
        objectives = list(study.objectives) or self._default_objectives()
        self.objectives = tuple(o.key for o in objectives)
        self.objective_names = tuple(self._objective_name(k, n) for k, n in self.objectives)
        self.constraints = _curve_constraints(self.requirements)
        self.constraint_names = (*(f"req_{r.label}" for r in self.constraints), "no_interference")


def evaluate(study: MechanismStudy, repeat: int = 1) -> EvaluationResult:
    """``flexopt evaluate``: solve the initial design (the geometry with every variable at its
    initial value) in every load case.

    Raises
    ------
    StudyError
        When the initial design cannot be built (check() reports it first).
    """
    ev = _Evaluator(study)
    x0 = ev.variables.initial if ev.variables is not None else None
    times = []
    solved: Any = None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        solved = ev.solve(x0)
        times.append(time.perf_counter() - t0)
    if isinstance(solved, tuple):
        raise StudyError("geometry", f"the initial design cannot be solved: {solved[1]}")
    solved = with_fidelity(ev, solved, sys.modules[__name__])
    # the kind's own verdicts, with "every variable in its range" of the initial design
    # (a run's best design gets it from pipeline.verdict.judge_detail)
    verdicts = with_design_range(study, ev.verdicts(solved))
    first = next(iter(solved.tables))
    summary = dict(solved.metrics)
    if x0 is not None:
        evaluation = ev._evaluation(x0, solved, time.perf_counter())  # noqa: SLF001
        for name, value in zip(ev.objective_names, map(float, evaluation.f), strict=True):
            summary.setdefault(name, value)  # a metric minimised as itself keeps its value
    summary["verdict"] = "MET" if verdicts and all(v.met for v in verdicts) else "NOT MET"
    converged = all(bool(r.ok) for r in solved.responses.values())
    message = "; ".join(f"{c}: {r.message}" for c, r in solved.responses.items() if r.message)
    if solved.reason and solved.reason not in message:
        message = "; ".join(m for m in (message, solved.reason) if m)
    kwargs: dict[str, Any] = {}
    if "verdicts" in {f.name for f in dataclasses.fields(EvaluationResult)}:
        kwargs["verdicts"] = verdicts
    plot = _plot_spec(study, first, ev.material)
    plot.update(band_spec(ev.requirements, solved.tables[first], plot["x"], "y",
                          _prefix(study, first)))  # a target band, drawn  # fmt: skip
    return EvaluationResult(
        table=solved.tables[first],
        summary=summary,
        converged=converged,
        message=message,
        solve_times_s=tuple(times),
        inputs={
            "material": material_record(ev.material),
            "design": None if ev.variables is None else ev.variables.values(x0),
            "verdicts": [_verdict_json(v) for v in verdicts],
            **_info(study, solved),
        },
        plot={
            **plot,  # the target band of a requirement, when the study has one
            "x": plot["x"],
            "left": plot["y"],
            "right": "peak_stress_MPa",
            "allowable_MPa": ev.material.yield_MPa,
        },  # fmt: skip
        headline=tuple(
            k
            for k in ("verdict", "mass_g", "max_peak_stress_MPa", "width_mm", "stable")
            if k in summary
        ),
        files=_files(study, solved, ev.requirements),
        cases=_cases(study, solved, ev.material, ev.requirements),
        **kwargs,
    )


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
    return StudyKind("mechanism", MechanismStudy, check, evaluate, problem, **extra)  # type: ignore[arg-type]


register(_kind())
