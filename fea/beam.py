"""Geometrically exact (Simo–Reissner) planar beam on scikit-fem.  (API stub; solver in progress)"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from fea.materials import Material
from geometry.profile import BeamProfile

__all__ = ["EndDrive", "BeamSettings", "BeamResponse", "BeamModel", "solve_beam"]


@dataclass(frozen=True)
class EndDrive:
    """How the ``end`` of the beam (last centreline point) is driven.

    control : "displacement" (max_value in mm) or "force" (max_value in N).
    direction : unit-normalised internally; the driven component is along it.
    steps : number of response rows after the initial row (rows at k*max/steps).
    rotation : "fixed" (end rotation held at 0) or "free".
    transverse : "fixed" (end motion perpendicular to direction held at 0) or "free".
    """

    control: Literal["displacement", "force"] = "displacement"
    direction: tuple[float, float] = (1.0, 0.0)
    max_value: float = 1.0
    steps: int = 20
    rotation: Literal["fixed", "free"] = "fixed"
    transverse: Literal["fixed", "free"] = "fixed"


@dataclass(frozen=True)
class BeamSettings:
    n_elements: int = 20
    shear_factor: float = 5.0 / 6.0


@dataclass(frozen=True)
class BeamResponse:
    """One row per requested step (row 0 = undeformed). All arrays shape (steps + 1,) unless noted.

    displacement_mm : driven end displacement projected on direction.
    force_N : force applied at the driven end, projected on direction.
    transverse_displacement_mm, transverse_force_N : the same, perpendicular (left of direction).
    moment_Nmm : moment applied at the driven end (counter-clockwise positive).
    end_rotation_rad : rotation of the driven end section.
    peak_stress_MPa : max over the beam of |N|/A + |M| c / I.
    peak_stress_s_mm : arc length where it occurs.
    iterations : (steps+1,) int, Newton iterations spent reaching each row.
    converged : (steps+1,) bool.
    shapes_mm : (steps+1, n_nodes, 2) deformed centreline node positions.
    ok : bool — every row converged.
    message : str — why not, when not ok.
    """

    displacement_mm: np.ndarray
    force_N: np.ndarray
    transverse_displacement_mm: np.ndarray
    transverse_force_N: np.ndarray
    moment_Nmm: np.ndarray
    end_rotation_rad: np.ndarray
    peak_stress_MPa: np.ndarray
    peak_stress_s_mm: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    shapes_mm: np.ndarray
    ok: bool
    message: str = ""
    extra: dict = field(default_factory=dict)


class BeamModel:
    def __init__(
        self,
        profile: BeamProfile,
        material: Material,
        start: Literal["clamped", "pinned"] = "clamped",
        settings: BeamSettings = BeamSettings(),
    ) -> None:
        raise NotImplementedError

    def solve(self, drive: EndDrive) -> BeamResponse:
        raise NotImplementedError


def solve_beam(
    profile: BeamProfile,
    material: Material,
    drive: EndDrive,
    start: Literal["clamped", "pinned"] = "clamped",
    settings: BeamSettings = BeamSettings(),
) -> BeamResponse:
    """Build a :class:`BeamModel` and trace the response under ``drive``."""
    return BeamModel(profile, material, start, settings).solve(drive)
