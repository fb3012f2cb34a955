"""The cam kind's schema blocks and the build from them: shared by ``cam`` and ``collision``.

``collision`` realises its threshold spring as the cam of the ``cam`` kind; both read the same
``geometry:`` / ``springs:`` blocks and build the cam with :func:`build_cam`. Moved here from
``pipeline/studies/cam.py`` unchanged (a kind never imports another kind).
"""

from __future__ import annotations

import math
from typing import Any, Literal

from flexopt.fea.contact import PAPER_CORRECTION, CorrectedCurve, fit_correction, synthesise_cam
from flexopt.geometry.cam import CamLayout, CamProfile, CamSprings
from flexopt.geometry.errors import GeometryError
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.targets import TargetCurve, TargetSpec
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study
from flexopt.pipeline.targets import resolve_target
from pydantic import BaseModel, Field, model_validator

__all__ = [
    "CAM_LIFE_REFUSAL",
    "CAM_VARIABLES",
    "CamGeometry",
    "CamStudyFields",
    "CorrectionSpec",
    "LimitsSpec",
    "RollerSpec",
    "SABSpec",
    "SpringsSpec",
    "build_cam",
    "refuse_duty_cycle",
]

#: Why a cam has no fatigue life (issue 25; docs/durability.md, "The cam"): what could fatigue
#: is the plate's track under the rolling follower (Hertz contact: pitting, whose surface
#: fatigue strength needs data flexopt has no source for) and the followers' springs (bought
#: parts given by rate and free length: no wire, no stress).
CAM_LIFE_REFUSAL = (
    "kind cam computes no fatigue life: its plate is rigid and its only stress is the Hertz "
    "contact pressure of the rolling follower, whose surface (pitting) fatigue strength flexopt "
    "has no sourced value of for any built-in material, and its springs are given by rate and "
    "free length only (no wire, no stress: their life is the spring maker's rating); judge "
    "max_contact_pressure_MPa (stress_yield_ratio: against the onset of yield under the "
    "contact, 1.67 x yield) instead"
)


class CamGeometry(BaseModel):
    """The ``geometry:`` block: where the followers run and the plate (mm, degrees)."""

    model_config = STUDY_CONFIG

    kind: Literal["cam"] = Field(description="cam")
    rest_radius_mm: float = Field(gt=0, description="r0: follower centre at zero rotation, mm")
    roller_radius_mm: float = Field(gt=0, description="r1: follower roller radius, mm")
    followers: int = Field(2, ge=2, le=8, description="followers evenly around the cam (paper 2)")
    max_rotation_deg: float = Field(
        90.0, gt=0, le=90, description="synthesised range, degrees (at most 180/followers)"
    )
    thickness_mm: float = Field(10.0, gt=0, description="plate thickness = contact width, mm")
    bore_diameter_mm: float = Field(6.0, ge=0, description="shaft bore, mm (0: none)")
    points: int = Field(361, ge=11, le=20001, description="synthesis grid points over the range")


class SpringsSpec(BaseModel):
    """The ``springs:`` block (paper Eq. 13): count springs of rate K per follower."""

    model_config = STUDY_CONFIG

    stiffness_N_per_mm: float = Field(gt=0, description="K of one extension spring, N/mm")
    free_length_mm: float = Field(ge=0, description="l0, initial length, mm")
    offset_mm: float = Field(0.0, ge=0, description="b, lateral anchor offset, mm")
    count: int = Field(4, ge=1, le=32, description="springs per follower (paper 4)")


class CorrectionSpec(BaseModel):
    """The ``correction:`` block (Eq. 17): given coefficients or a fit through the SAB."""

    model_config = STUDY_CONFIG

    coefficients: tuple[float, float, float] | None = Field(
        None, description="[a0, a1, a2] of T_cor = T (a0 + a1 γ + a2 γ²), γ in rad"
    )
    fit: bool = Field(False, description="fit [a0, a1, a2] by least squares through sab:")

    @model_validator(mode="after")
    def _one_source(self) -> CorrectionSpec:
        if (self.coefficients is None) == (not self.fit):
            raise ValueError("give coefficients: [a0, a1, a2] or fit: true (needs sab:), not both")
        return self


class SABSpec(BaseModel):
    """The ``sab:`` block: the stiffness-adjusting block of Eqs. 15–16."""

    model_config = STUDY_CONFIG

    a_mm: float = Field(gt=0, description="lever distance a, mm (Eq. 15a range)")
    R_mm: float = Field(gt=0, description="ring radius R, mm")
    R1_over_R2: float = Field(gt=1, description="gear ratio R1/R2 (paper's illustration: 7.5)")
    max_output_deg: float | None = Field(
        None, gt=0, description="output range for the fit, degrees (default Eq. 15b's limit)"
    )


class RollerSpec(BaseModel):
    """The ``roller:`` block: the follower roller's material (for the contact pressure)."""

    model_config = STUDY_CONFIG

    E_MPa: float = Field(210_000.0, gt=0, description="roller Young's modulus (steel), MPa")
    nu: float = Field(0.3, gt=-1, lt=0.5, description="roller Poisson's ratio")


class LimitsSpec(BaseModel):
    """The ``limits:`` block: what a usable cam must keep to."""

    model_config = STUDY_CONFIG

    max_pressure_angle_deg: float = Field(
        45.0, gt=0, lt=90, description="largest angle between contact normal and guide, degrees"
    )
    max_diameter_mm: float | None = Field(
        None, gt=0, description="largest mechanism diameter 2 (r_max + r1), mm (optional)"
    )


#: The cam's design variables by name (``design_space:`` keys of a cam study), mm and N/mm.
CAM_VARIABLES = ("rest_radius_mm", "stiffness_N_per_mm", "free_length_mm", "offset_mm")


class CamStudyFields(Study):
    """The fields of a whole ``cam`` study file (:class:`pipeline.studies.cam.CamStudy`).

    The ``collision`` kind builds one for the cam side of its reducer.
    """

    geometry: CamGeometry = Field(description="kind: cam, rest_radius_mm, roller_radius_mm, ...")
    springs: SpringsSpec = Field(description="stiffness_N_per_mm, free_length_mm, offset_mm, count")
    friction: float = Field(0.0, ge=0, lt=1, description="μ of the follower guides (Eq. 3)")
    target: TargetSpec = Field(
        default_factory=lambda: TargetSpec(
            kind="threshold", max_torque_Nm=2.05, rate_per_rad=50.0, measure="max_normalised"
        ),
        description="the torque-rotation curve to make (default the paper's prototype)",
    )
    correction: CorrectionSpec | None = Field(None, description="Eq. 17 profile correction")
    sab: SABSpec | None = Field(None, description="stiffness-adjusting block, Eqs. 15-16")
    roller: RollerSpec = Field(default_factory=RollerSpec, description="roller E_MPa and nu")
    limits: LimitsSpec = Field(default_factory=LimitsSpec, description="max_pressure_angle_deg")
    rows: int = Field(91, ge=3, le=2001, description="rows of the response table over the range")
    design_space: dict[str, tuple[float, float]] = Field(
        default_factory=dict,
        description="bounds by name for flexopt run: " + ", ".join(CAM_VARIABLES),
    )
    objective: Literal["diameter", "pressure_angle"] = Field(
        "diameter", description="minimise the mechanism diameter or the largest pressure angle"
    )
    optimiser: OptimiserSpec = Field(
        default_factory=lambda: OptimiserSpec(pop_size=24, n_gen=20),
        description="algorithm, pop_size, n_gen, seed, quick_pop_size, quick_n_gen",
    )


def _layout(study: CamStudyFields) -> CamLayout:
    g = study.geometry
    try:
        return CamLayout(
            rest_radius_mm=g.rest_radius_mm,
            roller_radius_mm=g.roller_radius_mm,
            followers=g.followers,
            max_rotation_rad=math.radians(g.max_rotation_deg),
            friction=study.friction,
            thickness_mm=g.thickness_mm,
            bore_diameter_mm=g.bore_diameter_mm,
        )
    except GeometryError as exc:
        raise StudyError("geometry", str(exc)) from exc


def _springs(spec: SpringsSpec) -> CamSprings:
    return CamSprings(spec.stiffness_N_per_mm, spec.free_length_mm, spec.offset_mm, spec.count)


def _design_curve(study: CamStudyFields, target: TargetCurve) -> tuple[Any, dict[str, Any]]:
    """The curve the cam is cut for: the target, or the target times the Eq. 17 factor."""
    info: dict[str, Any] = {}
    spec = study.correction
    gmax = math.radians(study.geometry.max_rotation_deg)
    if spec is None:
        return target, info
    if spec.coefficients is not None:
        coefficients = spec.coefficients
        info["source"] = "given"
    else:
        sab = study.sab
        assert sab is not None  # checked
        top = None if sab.max_output_deg is None else math.radians(sab.max_output_deg)
        coefficients, fit = fit_correction(target, sab.a_mm, sab.R_mm, sab.R1_over_R2, top)
        info["source"] = "least-squares fit through the SAB (Eq. 15)"
        info["max_relative_error_uncorrected"] = fit["max_relative_error_uncorrected"]
        info["max_relative_error_corrected"] = fit["max_relative_error_corrected"]
    info["coefficients"] = list(coefficients)
    info["paper_coefficients"] = list(PAPER_CORRECTION)
    return CorrectedCurve(target, coefficients, gmax), info


def build_cam(study: CamStudyFields) -> tuple[TargetCurve, Any, CamProfile, dict[str, Any]]:
    """Target, design curve, synthesised profile and correction info of a study.

    Raises
    ------
    StudyError
        Naming the key path when the target, springs or layout cannot make a cam.
    """
    target = resolve_target(study.target)
    if target.quantity != "torque":
        raise StudyError(
            "target",
            "a cam makes a torque-rotation curve; give torque keys (torque_Nm, "
            "stiffness_Nm_per_rad, max_torque_Nm + rate_per_rad, or table columns "
            "[rotation_deg, torque_Nm])",
        )
    layout = _layout(study)
    try:
        springs = _springs(study.springs)
    except GeometryError as exc:
        raise StudyError("springs", str(exc)) from exc
    curve, info = _design_curve(study, target)
    try:
        profile = synthesise_cam(curve, springs, layout, study.geometry.points)
    except GeometryError as exc:
        raise StudyError(_geometry_path(str(exc)), str(exc)) from exc
    except OptimiseError as exc:  # a table target asked beyond its rows
        raise StudyError("target", str(exc)) from exc
    return target, curve, profile, info


def _geometry_path(message: str) -> str:
    if "slack" in message or "self-lock" in message:
        return "springs"
    if "target" in message:
        return "target"
    return "geometry"


def refuse_duty_cycle(study: Any) -> None:
    """Refuse a ``duty_cycle:`` block on a cam at load time (:data:`CAM_LIFE_REFUSAL`).

    Raises
    ------
    StudyError
        At ``duty_cycle``, with the reason and what to judge instead.
    """
    if getattr(study, "duty_cycle", None) is not None:
        raise StudyError("duty_cycle", CAM_LIFE_REFUSAL)
