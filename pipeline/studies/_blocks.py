"""Schema blocks shared by several study kinds (a kind never imports another kind).

- :class:`MeshSpec` — the ``mesh:`` block of the plane-stress spring kinds (``sea_spring``,
  ``threshold_spring``'s ``plane_stress:``); it satisfies :class:`fea.spring_analysis.MeshSize`.
- :class:`ImpactSpec` — the ``impact:`` block of Fig. 14's head impact (``collision``,
  ``threshold_spring``).
"""

from __future__ import annotations

import math
from typing import Literal

from flexopt.fea.collision import CollisionModel, CollisionSettings
from flexopt.pipeline.study import STUDY_CONFIG
from pydantic import BaseModel, Field

__all__ = ["ImpactSpec", "MeshSpec"]


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
