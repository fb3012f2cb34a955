"""The ``threshold_spring`` study file: its pydantic models (the key reference is
``docs/threshold_torque.md``, section 4; units are in the key names: mm, deg, N·m, MPa) and what
they say to the optimiser: the design space of the arm shape (:func:`design_space`), the design
``flexopt evaluate`` traces (:func:`design_vector`) and the refusals before a run
(:func:`check`). The kind is pipeline/studies/threshold_spring.py.
"""

from __future__ import annotations

import difflib
from typing import Literal

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.threshold_spring import THRESHOLD_BOUNDS, THRESHOLD_VARIABLES
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.space import DesignSpace
from flexopt.optimise.targets import TargetSpec
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies._blocks import CurveSolid3DSpec, ImpactSpec
from flexopt.pipeline.studies._spring_frame import SpringFrameBlock
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study
from pydantic import BaseModel, Field, field_validator, model_validator

__all__ = [
    "BeamSpec",
    "FidelitySpec",
    "ThresholdSpringGeometry",
    "ThresholdSpringStudy",
    "check",
    "design_space",
    "design_vector",
]


# --------------------------------------------------------------------------------------------
# The study file


class ThresholdSpringGeometry(SpringFrameBlock):
    """The ``geometry:`` block: arm count, thickness range and the shared frame keys (mm)."""

    kind: Literal["threshold_spring"] = Field(description="threshold_spring")
    n_arms: int = Field(3, ge=1, le=8, description="identical arms around the hub")
    envelope_diameter_mm: float = Field(100.0, gt=0, description="the spring fits this circle")
    thickness_range_mm: tuple[float, float] = Field(
        (2.0, 20.0), description="allowed spring thickness ST [lower, upper], mm"
    )
    root_fillet_mm: float = Field(1.0, ge=0, le=5, description="fillet at arm roots, mm")

    @model_validator(mode="after")
    def _thickness_range(self) -> ThresholdSpringGeometry:
        lo, hi = self.thickness_range_mm
        if not 0 < lo < hi:
            raise ValueError(
                f"thickness_range_mm = {[lo, hi]} must be [lower, upper] with 0 < lower < upper"
            )
        return self


class BeamSpec(BaseModel):
    """The ``beam:`` block: the search model's discretisation."""

    model_config = STUDY_CONFIG

    elements: int = Field(24, ge=4, le=400, description="P2 elements along an arm")
    rows: int = Field(24, ge=4, le=400, description="rows of the torque curve over the range")


class FidelitySpec(BaseModel):
    """The ``fidelity:`` block: the plane-stress check of the chosen design."""

    model_config = STUDY_CONFIG

    enabled: bool = Field(True, description="solve the chosen design in plane stress")
    max_edge_mm: float = Field(2.0, gt=0.1, le=10, description="largest triangle edge, mm")
    elements_through: float = Field(2.0, ge=0.5, le=6, description="P2 triangles across an arm")
    fillet_segments: int = Field(4, ge=1, le=16, description="segments per quarter fillet")
    # at least 2: with one step the check's only loaded row is the range's end, and the
    # window's normalised curve error has no non-zero target row to divide by
    steps: int = Field(8, ge=2, le=80, description="load steps (rows) over the design range")


class ThresholdSpringStudy(Study):
    """A whole ``threshold_spring`` study file."""

    geometry: ThresholdSpringGeometry = Field(description="kind: threshold_spring and limits")
    target: TargetSpec = Field(description="the torque target, with measure and window_deg")
    tolerance: float = Field(0.05, gt=0, description="largest error measure accepted")
    allowable_stress_MPa: float | None = Field(
        None, gt=0, description="peak stress allowed, MPa (default 0.9 x the material's yield)"
    )
    beam: BeamSpec = Field(default_factory=BeamSpec, description="search model")
    fidelity: FidelitySpec = Field(default_factory=FidelitySpec, description="plane stress")
    solid_3d: CurveSolid3DSpec = Field(
        default_factory=CurveSolid3DSpec,
        description="the chosen design as a 3D solid on the fidelity mesh: 3D/2D stiffness "
        "ratio, 3D torque error and peak stress; with correct (default), ST refitted to the 3D "
        "curve when its error exceeds the tolerance and re-checked in 3D",
    )
    stack_plates: int = Field(
        1,
        ge=1,
        le=100,
        description="plates stacked on one hub for the impact (the torque is times this; "
        "the ideal target too)",
    )
    impact: ImpactSpec = Field(
        default_factory=lambda: ImpactSpec(rotor_torque_Nm=1.0),
        description="the impact the spring is scored in (fea.collision, paper defaults)",
    )
    design_space: dict[str, list[float]] = Field(
        default_factory=dict,
        description="bounds [lower, upper] by variable name; unlisted ones keep the defaults",
    )
    design: dict[str, float] | None = Field(
        None, description="the design flexopt evaluate traces (mid-range if null)"
    )
    optimiser: OptimiserSpec = Field(
        default_factory=lambda: OptimiserSpec(
            algorithm="ga", pop_size=40, n_gen=30, quick_pop_size=8, quick_n_gen=3
        ),
        description="algorithm (ga), pop_size, n_gen, seed, quick_pop_size, quick_n_gen",
    )

    @field_validator("target")
    @classmethod
    def _torque_target_with_window(cls, target: TargetSpec) -> TargetSpec:
        if target.quantity != "torque":
            raise ValueError(
                "a spring's target is torque-rotation; give max_torque_Nm and rate_per_rad "
                "(threshold), torque_Nm, stiffness_Nm_per_rad or a table in N·m"
            )
        if target.window_deg is None:
            raise ValueError(
                "give window_deg: [lower, upper], the design range the curve is scored over "
                "(e.g. [0, 6])"
            )
        if target.window_deg[0] < 0:
            raise ValueError(
                f"window_deg = {list(target.window_deg)}; the spring turns counter-clockwise "
                "only, use a window in degrees >= 0"
            )
        return target


def _unknown(name: str, path: str) -> StudyError:
    close = [n for n in THRESHOLD_VARIABLES if n.lower() == name.lower()]
    close = close or difflib.get_close_matches(name, THRESHOLD_VARIABLES, n=1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    return StudyError(
        f"{path}.{name}",
        f"unknown design variable '{name}'; {hint}use {', '.join(THRESHOLD_VARIABLES)}",
    )


def design_space(study: ThresholdSpringStudy) -> DesignSpace:
    """Default bounds overridden by ``design_space:``.

    Raises
    ------
    StudyError
        At ``design_space.<name>``: unknown name, not two numbers, swapped or equal bounds.
    """
    bounds = {k: list(v) for k, v in THRESHOLD_BOUNDS.items()}
    bounds["pad_radius_mm"][1] = min(
        bounds["pad_radius_mm"][1],
        0.5 * study.geometry.envelope_diameter_mm - study.geometry.pad_radius_mm,
    )
    for name, b in study.design_space.items():
        path = f"design_space.{name}"
        if name not in bounds:
            raise _unknown(name, "design_space")
        if len(b) != 2:
            raise StudyError(path, f"got {list(b)}; give two bounds [lower, upper]")
        lo, hi = float(b[0]), float(b[1])
        if lo > hi:
            raise StudyError(path, f"lower {lo:g} > upper {hi:g}; did you swap them?")
        if lo == hi:
            raise StudyError(path, f"equal bounds [{lo:g}, {hi:g}]; give a range")
        if name[0] in "FG" and not (0.0 <= lo and hi <= 1.0):
            raise StudyError(path, f"[{lo:g}, {hi:g}]: {name} is a fraction, keep it in [0, 1]")
        if name.endswith("_mm") and not lo > 0:
            raise StudyError(path, f"lower bound {lo:g} must be > 0 mm")
        bounds[name] = [lo, hi]
    lo_pad, hi_pad = bounds["pad_radius_mm"]
    if not lo_pad < hi_pad:
        raise StudyError(
            "design_space.pad_radius_mm",
            f"[{lo_pad:g}, {hi_pad:g}] leaves no room inside the envelope "
            f"({study.geometry.envelope_diameter_mm:g} mm); widen the envelope or lower the bound",
        )
    return DesignSpace(
        THRESHOLD_VARIABLES,
        np.array([bounds[n][0] for n in THRESHOLD_VARIABLES]),
        np.array([bounds[n][1] for n in THRESHOLD_VARIABLES]),
    )


def design_vector(study: ThresholdSpringStudy) -> np.ndarray:
    """(n_var,) the study's ``design:`` (unlisted variables at the middle of their range).

    Raises
    ------
    StudyError
        At ``design.<name>`` for an unknown variable.
    """
    space = design_space(study)
    x = 0.5 * (space.lower + space.upper)
    for name, value in (study.design or {}).items():
        if name not in THRESHOLD_VARIABLES:
            raise _unknown(name, "design")
        x[THRESHOLD_VARIABLES.index(name)] = float(value)
    return x


def check(study: ThresholdSpringStudy) -> None:
    """Refuse what would stop a run, before any folder exists (no FE here)."""
    try:
        study.geometry.frame()
    except GeometryError as exc:
        raise StudyError("geometry", str(exc)) from exc
    try:
        study.target.to_curve()
    except OptimiseError as exc:
        raise StudyError("target", str(exc)) from exc
    design_space(study)
    design_vector(study)
    if study.target.window_deg[1] > 90.0:  # type: ignore[index]
        raise StudyError(
            "target.window_deg",
            f"upper {study.target.window_deg[1]:g} degrees: a planar arm spring turns far less; "  # type: ignore[index]
            "keep the design range <= 90",
        )
    try:
        study.impact.model()
    except FeaError as exc:
        raise StudyError("impact", str(exc)) from exc
