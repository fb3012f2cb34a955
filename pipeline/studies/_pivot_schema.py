"""The ``flexure_pivot`` kind's ``fidelity:`` and ``design:`` blocks and its type names, kept
apart from pipeline/studies/flexure_pivot.py (the kind module's size limit,
tests/test_layering.py); the kind re-exports them.
"""

from __future__ import annotations

from typing import Literal

from flexopt.pipeline.study import STUDY_CONFIG
from pydantic import BaseModel, Field

__all__ = ["PivotDesign", "PivotFidelity", "PivotType"]

PivotType = Literal[
    "leaf", "variable_leaf", "circular_notch", "elliptical_notch", "corner_filleted", "cross_axis"
]


class PivotFidelity(BaseModel):
    """The ``fidelity:`` block: how the best design is checked in the report."""

    model_config = STUDY_CONFIG

    steps: int = Field(10, ge=2, le=200, description="rows of the beam sweep in the report")
    ga_steps: int = Field(3, ge=1, le=50, description="rows of the beam solve of each GA design")
    plane_stress: bool = Field(True, description="check the best planar design by plane stress")
    plane_stress_steps: int = Field(3, ge=1, le=50, description="nonlinear plane-stress rows")
    web_elements: float = Field(
        4.0, ge=1.0, le=16.0, description="plane-stress elements through the thinnest section"
    )


class PivotDesign(BaseModel):
    """The ``design:`` block: one design for ``flexopt evaluate``."""

    model_config = STUDY_CONFIG

    type: PivotType = Field(description="pivot type")
    length_mm: float = Field(gt=0, description="compliant length, mm (see the table)")
    thickness_mm: float = Field(gt=0, description="thinnest section, mm")
    shape: float = Field(0.5, ge=0, le=1, description="type-specific shape in [0, 1]")
