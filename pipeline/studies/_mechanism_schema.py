"""The ``mechanism`` study file: its pydantic models (the full key reference is
``docs/mechanism.md``; units are in the key names: mm, deg, N, N·mm), and what they say to the
solver: the printable part (:func:`build_outline`), the mechanism (:func:`build_mechanism`),
each load case (:func:`build_load_case`, :func:`build_outputs`) and the columns of its response
(:func:`output_columns`). The kind is pipeline/studies/mechanism.py.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any, ClassVar, Literal

import numpy as np
from flexopt.fea.materials import Material
from flexopt.fea.mechanism_design import DRIVE_UNIT, OutputColumn, width_exponent
from flexopt.geometry.mechanism import (
    AsMadeBeam,
    BeamShape,
    BodyShape,
    MechanismOutline,
    attachments,
    curvature_as_made,
    curve_points,
    mechanism_outline,
)
from flexopt.optimise.names import check_name
from flexopt.optimise.requirements import RequirementSpec, unit_of
from flexopt.optimise.variables import VariableSpec
from flexopt.pipeline.studies._mechanism_optimiser import default_method
from flexopt.pipeline.studies._stops import StopsSpec
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study
from pydantic import BaseModel, Field, ValidationInfo, field_validator, model_validator

__all__ = [
    "BeamSpec",
    "MechanismFidelitySpec",
    "build_load_case",
    "build_mechanism",
    "build_outline",
    "build_outputs",
    "case_prefix",
    "output_columns",
    "output_exponent",
    "output_refs",
    "outputs_in",
    "BodySpec",
    "CurveSpec",
    "DriveSpec",
    "JointSpec",
    "LoadCaseSpec",
    "MechanismGeometry",
    "MechanismStudy",
    "ObjectiveSpec",
    "OutputSpec",
    "WidthSolveSpec",
]

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")


def _check_name(value: str, what: str) -> str:
    check_name(value, what)  # the one rule of names (docs/usage.md), then this kind's own
    if not _NAME.fullmatch(value) or value == "ground":
        raise ValueError(
            f"'{value}' cannot name a {what}: use letters, digits, '_' and '-', starting with a "
            "letter, not 'ground' (joints name parts as name.start / name.end)"
        )
    return value


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
        unit = DRIVE_UNIT[self.control]
        for other in set(DRIVE_UNIT.values()) - {unit}:
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
        return DRIVE_UNIT[self.control]

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


class MechanismFidelitySpec(BaseModel):
    """``fidelity:`` of a mechanism study: the check of the exported outline."""

    model_config = STUDY_CONFIG

    enabled: bool = Field(True, description="check the reported design in plane stress / 3D")
    elements_through: float = Field(
        2.0, ge=1.0, le=8.0, description="P2 triangles across the thinnest beam"
    )
    solid: Literal["auto", "always", "never"] = Field(
        "auto", description="3D solid check: auto (width >= 3 x the thinnest beam), always or never"
    )
    layers: int = Field(2, ge=1, le=8, description="prism layers through half the width (3D)")
    beam_stress_factor: float = Field(
        1.0,
        ge=1.0,
        le=2.0,
        description="the optimiser judges each design's beam-model peak stress (the roots' Kt "
        "included) times this: the check's peak / beam ratio measured on this study's designs, "
        "so that the reported design also meets its stress requirements on the check, which "
        "the verdict reads",
    )


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
        description="algorithm, pop_size, n_gen, seed, quick_pop_size, quick_n_gen, method "
        "(unset: hybrid where it applies; ga: the GA alone), hybrid",
        validate_default=True,  # the default block gets the default method too
    )  # fmt: skip
    stops: StopsSpec | None = Field(
        None,
        description="rigid stops fixed to the ground that the beams meet (frictionless penalty "
        "contact): {outlines: [{name, points_mm, closed}], penalty_factor} (or the list of "
        "outlines), mm in the study's coordinates",
    )

    contact: tuple[tuple[str, str], ...] | None = Field(
        None,
        description="pairs of parts that may touch each other, [[a, b], ...]: two beams, two "
        "bodies (by their outlines), a body and a beam, or one beam twice (its self contact): "
        "frictionless penalty contact between them (any other meeting is interference)",
    )

    # a study without stops dumps as it did before the block existed (Study's serializer)
    OPTIONAL_BLOCKS: ClassVar[tuple[str, ...]] = (*Study.OPTIONAL_BLOCKS, "stops", "contact")

    @field_validator("load_cases", "outputs")
    @classmethod
    def _names(cls, value: dict[str, Any]) -> dict[str, Any]:
        for name in value:
            _check_name(name, "load case or output")
        return value

    @field_validator("optimiser")
    @classmethod
    def _default_method(cls, value: OptimiserSpec, info: ValidationInfo) -> OptimiserSpec:
        # the kind's default optimiser: the hybrid where it applies (variables, objectives are
        # declared above, so validated before it)
        return default_method(
            value, info.data.get("variables", ()), info.data.get("objectives", ())
        )


# --------------------------------------------------------------------------------------------


# --------------------------------------------------------------------------------------------
# From the study file to the solver's inputs


def _fea():
    # the engine, imported late so the kind always registers
    import flexopt.fea.mechanism as fm

    return fm


def case_prefix(study: MechanismStudy, case: str) -> str:
    """``"<case>."`` with more than one load case ('' with one): what the case's metrics and
    columns are prefixed with."""
    return f"{case}." if len(study.load_cases) > 1 else ""


def outputs_in(study: MechanismStudy, case: str) -> list[str]:
    """The outputs read in load case ``case``, in the study's order."""
    return [n for n, o in study.outputs.items() if o.cases is None or case in o.cases]


def output_refs(spec: OutputSpec) -> tuple[str, ...]:
    """The outputs a slope or ratio refers to (none for a measured output)."""
    return (spec.of,) if isinstance(spec.of, str) else tuple(spec.of or ())


def output_exponent(study: MechanismStudy, output: str) -> int:
    """How an output scales with the shared width (:func:`fea.mechanism_design.width_exponent`)."""
    reads = {n: (o.quantity, output_refs(o)) for n, o in study.outputs.items()}
    return width_exponent(reads, output)


def output_columns(study: MechanismStudy, case: str) -> list[OutputColumn]:
    """The case's outputs as its table writes them (:func:`fea.mechanism_design.case_table`)."""
    out = []
    for name in outputs_in(study, case):
        o = study.outputs[name]
        degrees = o.quantity == "rotation" and unit_of(name) == "deg"
        exponent = output_exponent(study, name)
        out.append(OutputColumn(name, o.quantity, output_refs(o), o.part, degrees, exponent))
    return out


def build_outline(geometry: MechanismGeometry) -> tuple[list[BeamShape], MechanismOutline]:
    """The beams' drawn shapes and the printable part (:func:`geometry.mechanism_outline`).

    Raises
    ------
    GeometryError
        Where the part cannot be printed or is not the mechanism the solver analyses.
    """
    shapes = [BeamShape(n, b.centreline(), b.thickness()) for n, b in geometry.beams.items()]
    bodies = [
        BodyShape(n, np.array(b.outline_mm, dtype=float))
        for n, b in geometry.bodies.items()
        if b.outline_mm is not None
    ]
    outline = mechanism_outline(
        shapes,
        bodies,
        attachments([(j.a, j.b) for j in geometry.joints], list(geometry.bodies)),
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
    return curvature_as_made(name, spec.curvature_per_mm, len(spec.points_mm or ()), made)


def build_mechanism(
    geometry: MechanismGeometry,
    material: Material,
    width_mm: float | None = None,
    made: Mapping[str, AsMadeBeam] | None = None,
):
    """The solver's :class:`fea.mechanism.Mechanism` at ``width_mm`` (None: the geometry's);
    with ``made`` (``MechanismOutline.beams``) the beams as made: clipped at the bodies they
    enter, flared into their roots' fillets, with the flares' lengths as the roots whose stress
    the concentration factors multiply."""
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
        own = float(b.width_mm if b.width_mm is not None else width)
        beams.append(fm.MechBeam(name, points, thickness, own, int(b.elements), curvature, root))
    bodies = [
        fm.MechBody(
            n,
            np.array(b.ref_mm, dtype=float),
            None if b.outline_mm is None else np.array(b.outline_mm, dtype=float),
        )
        for n, b in geometry.bodies.items()
    ]
    joints = [fm.MechJoint(j.a, j.b, j.type) for j in geometry.joints]
    return fm.Mechanism(tuple(beams), tuple(bodies), tuple(joints), material)


def build_load_case(study: MechanismStudy, case: str):
    """The solver's :class:`fea.mechanism.LoadCase` of ``load_cases.<case>`` (a rotation's
    values in rad)."""
    fm = _fea()
    spec = study.load_cases[case]
    d = spec.drive
    lo, hi = d.range
    factor = math.pi / 180.0 if d.control == "rotation" else 1.0
    direction = (float(d.direction[0]), float(d.direction[1]))
    drive = fm.MechDrive(
        d.part, d.control, hi * factor, d.steps, direction, d.transverse, d.rotation, lo * factor
    )
    supports = tuple(fm.MechJoint(s.a, s.b, s.type) for s in spec.supports)
    return fm.LoadCase(case, drive, supports)


def build_outputs(study: MechanismStudy, case: str) -> list[Any]:
    """The solver's :class:`fea.mechanism.MechOutput` of the case: the drive's reaction
    (``__drive_reaction``), then every measured output read in it (slopes and ratios are
    computed from the columns)."""
    fm = _fea()
    out = [fm.MechOutput("__drive_reaction", "reaction")]
    for name in outputs_in(study, case):
        o = study.outputs[name]
        if o.quantity in ("slope", "ratio"):
            continue
        direction = (float(o.direction[0]), float(o.direction[1]))
        out.append(fm.MechOutput(name, o.quantity, o.part, direction))
    return out
