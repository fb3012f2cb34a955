"""Schema blocks shared by several study kinds (a kind never imports another kind).

- :class:`MeshSpec` — the ``mesh:`` block of the plane-stress spring kinds (``sea_spring``,
  ``threshold_spring``'s ``plane_stress:``); it satisfies :class:`fea.spring_analysis.MeshSize`.
- :class:`ImpactSpec` — the ``impact:`` block of Fig. 14's head impact (``collision``,
  ``threshold_spring``).
- :class:`Solid3DCheckSpec` — the 3D check alone; :class:`CurveSolid3DSpec` —
  ``threshold_spring``'s, with ST refitted to the 3D curve and re-checked; :class:`Solid3DSpec`
  — ``sea_spring``'s, with the thickness correction and the converged peak (issue 15;
  docs/solid3d.md).
"""

from __future__ import annotations

import math
from typing import Any, Literal

from flexopt.fea.collision import CollisionModel, CollisionSettings
from flexopt.pipeline.study import STUDY_CONFIG
from pydantic import BaseModel, Field, field_validator, model_serializer

__all__ = ["CurveSolid3DSpec", "ImpactSpec", "MeshSpec", "Solid3DCheckSpec", "Solid3DSpec"]


class MeshSpec(BaseModel):
    """The ``mesh:`` block: discretisation of every FE run."""

    model_config = STUDY_CONFIG

    max_edge_mm: float = Field(3.0, gt=0.1, le=10, description="largest triangle edge, mm")
    elements_through: float = Field(
        1.0, ge=0.5, le=6, description="P2 triangles across a member (1: stiffness to 0.1 %)"
    )
    fillet_segments: int = Field(4, ge=1, le=16, description="segments per quarter fillet")
    curve_steps: int = Field(4, ge=1, le=40, description="rows of the reported torque curve")


class ImpactSpec(BaseModel):
    """The ``impact:`` block: Fig. 14's parameters, SI, paper defaults (l. 252–258, Fig. 17)."""

    model_config = STUDY_CONFIG

    neck_damping_N_s_per_m: float = Field(12.0, ge=0, description="d_N")
    neck_stiffness_N_per_m: float = Field(3300.0, ge=0, description="k_N")
    head_mass_kg: float = Field(5.09, gt=0, description="M_head")
    contact_damping_N_s_per_m: float = Field(10.0, ge=0, description="d_c")
    contact_stiffness_N_per_m: float = Field(1500.0, gt=0, description="k_c")
    arm_length_m: float = Field(0.6, gt=0, description="l, contact point on the arm")
    arm_inertia_kg_m2: float = Field(0.14, gt=0, description="I_arm")
    rotor_inertia_kg_m2: float = Field(0.175, gt=0, description="I_rotor (Fig. 17)")
    rotor_torque_Nm: float = Field(15.0, ge=0, description="rotor torque during the impact")
    speed_rad_per_s: float = Field(math.pi, gt=0, description="joint speed at impact")
    initial_spring: Literal["unloaded", "accelerating", "held"] = Field(
        "unloaded",
        description="spring state at impact: unloaded, accelerating (carries the arm's share of "
        "the rotor torque) or held (carries all of it)",
    )
    dt_s: float = Field(2e-4, gt=0, le=1e-3, description="RK4 and output step, s")
    duration_s: float = Field(0.25, gt=0, le=5, description="simulated time, s")

    def model(self) -> CollisionModel:
        keys = (
            "neck_damping_N_s_per_m",
            "neck_stiffness_N_per_m",
            "head_mass_kg",
            "contact_damping_N_s_per_m",
            "contact_stiffness_N_per_m",
            "arm_length_m",
            "arm_inertia_kg_m2",
            "rotor_inertia_kg_m2",
            "rotor_torque_Nm",
            "speed_rad_per_s",
            "initial_spring",
        )
        return CollisionModel(**{k: getattr(self, k) for k in keys})

    def settings(self) -> CollisionSettings:
        return CollisionSettings(dt_s=self.dt_s, duration_s=self.duration_s)


class Solid3DCheckSpec(BaseModel):
    """The ``solid_3d:`` block of a kind that checks its chosen design as a 3D solid and
    reports it (issue 15; docs/solid3d.md)."""

    model_config = STUDY_CONFIG

    check: bool = Field(
        True,
        description="check the chosen design as a 3D solid (fea/solid3d.py, linear P2 "
        "tetrahedra, ~20 s and ~3 GB per check): stiffness and peak stress beside plane stress",
    )
    layers: int = Field(
        4,
        ge=1,
        le=12,
        description="prism layers through the half thickness (fea.solid3d.Solid3DSettings: 4 "
        "resolve the free-face layer; the SEA stiffness moves < 0.1 % from 4 to 8)",
    )
    solver: Literal["auto", "multigrid", "cholmod", "qdldl", "superlu"] = Field(
        "auto",
        description="3D solver: auto = CHOLMOD with the cholmod extra, else multigrid from "
        "150k DOFs; multigrid = least memory, ~3x CHOLMOD's time (docs/solid3d.md)",
    )

    @field_validator("solver")
    @classmethod
    def _solver_installed(cls, value: str) -> str:
        from flexopt.fea.solid3d import cholmod_available

        if value == "cholmod" and not cholmod_available():
            raise ValueError(
                "'cholmod' needs CHOLMOD, which is not installed: install the cholmod extra "
                "(pip install 'flexopt[cholmod]', cvxopt) or pick auto, multigrid, qdldl or "
                "superlu"
            )
        return value

    @model_serializer(mode="wrap")
    def _without_default_solver(self, handler: Any) -> Any:
        # a study that leaves the solver to "auto" dumps as it did before the key existed
        # (run folders and their study.yaml stay the same)
        data = handler(self)
        if isinstance(data, dict) and data.get("solver") == "auto":
            del data["solver"]
        return data


class CurveSolid3DSpec(Solid3DCheckSpec):
    """The ``solid_3d:`` block of a kind whose requirement is an error measure on a curve (the
    threshold spring): the 3D check, and ST corrected for it when the 3D curve misses the
    tolerance (issue 15 item 2; docs/solid3d.md)."""

    correct: bool = Field(
        True,
        description="when the 3D curve error exceeds the tolerance, adopt the ST that fits "
        "the 3D curve best (ST_fit_3d_mm) and re-check it in 3D (a second 3D solve)",
    )
    converge_peak: bool = Field(
        True,
        description="refine the plane mesh at the peak stress of the chosen design (end of "
        "the design range, nonlinear) until it moves < 1 %, on an outline sampled every "
        "curve_step_mm; the 3D peak is that value times the 3D/2D peak ratio",
    )
    curve_step_mm: float = Field(
        0.1,
        gt=0.01,
        le=0.5,
        description="arm sampling of that outline, mm (the optimiser's is ~0.5 mm: facets on "
        "which the peak does not converge)",
    )


class Solid3DSpec(Solid3DCheckSpec):
    """The ``solid_3d:`` block: the chosen design checked as a 3D solid, corrected for it, and
    its peak stress checked for mesh convergence (issue 15; docs/solid3d.md)."""

    correct: bool = Field(
        True,
        description="correct ST for the 3D stiffness (ST x target / mean 3D stiffness, "
        "re-checked in 3D) when the 3D/2D ratio is off 1 by more than "
        "max_fraction_of_tolerance of the stiffness band",
    )
    max_fraction_of_tolerance: float = Field(
        0.25,
        gt=0,
        le=1,
        description="correct when |3D/2D - 1| > this x target.tolerance_percent; also how "
        "close to the target the corrected mean must come",
    )
    max_checks: int = Field(
        3, ge=2, le=5, description="3D checks at most (calibration, then re-checks)"
    )
    converge_peak: bool = Field(
        True,
        description="refine the plane mesh at the peak stress of the chosen design until it "
        "moves < 1 %, on an outline sampled every curve_step_mm",
    )
    curve_step_mm: float = Field(
        0.1,
        gt=0.01,
        le=0.5,
        description="arm sampling of that outline, mm (the optimiser's is ~0.5 mm: 1.4 deg "
        "facets on which the peak does not converge)",
    )
