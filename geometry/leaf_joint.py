"""The leaf-spring variable-stiffness joint of paper 002 (Wang, Fang & Zhou 2018), as geometry.

Principle (paper Fig. 1): an output arm turns about the joint centre O. Each of ``n`` leaf
springs (two, diametrically opposite, so they act together) is clamped on the position carrier
and held by a *movable support* O' that slides along it; from O' the leaf runs radially outwards
to the load point B, where it meets the output arm at the *joint arm* ``l_j = |OB|``. The free
(effective) length ``l = |O'B|`` sets the stiffness (Eq. 4)::

    l = l_j - s_mp,   s_mp = 0.5 m N_s + 0.5 m N_p + l_c cos(theta_p)          (Eq. 3)

(the support is moved by a crank on the planet of a differential gear: module m, sun N_s, planet
N_p teeth, crank l_c, planet angle theta_p).

Two ways the arm can load the leaf tip (Fig. 5):

``sliding`` — structure (a)
    A rod fixed to the leaf tip slides in a slot along the output arm. The tip stays on the arm's
    radial line through O and may slide along it and turn; without friction the arm can only push
    *normal to the slot*. The effective length l stays constant.
``fixed`` — structure (b)
    A rod fixed to the arm at radius ``l_j`` presses on the side of the leaf, which slides past it.
    The contact point stays on the arm (circle of radius l_j about O); the force is *normal to the
    leaf* there and the loaded length (O' to the contact) grows as the joint deflects. The leaf
    must run past the rod far enough (``overhang_mm``).

Frame: O' at the origin, the undeformed leaf along +x, O at ``(l - l_j, 0)``, B at ``(l, 0)``;
the joint deflection ``theta_j`` turns the arm counter-clockwise. Units: mm, rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.profile import BeamProfile
from shapely.geometry import Polygon, box

__all__ = [
    "STRUCTURES",
    "PAPER_GEARS",
    "LeafJoint",
    "planet_teeth",
    "support_offset_mm",
    "effective_length_mm",
    "crank_angle_for_length_rad",
]

STRUCTURES = ("sliding", "fixed")
"""Leaf-tip structures: ``sliding`` = paper Fig. 5a, ``fixed`` = Fig. 5b."""

PAPER_GEARS = {"n_sun": 18, "n_ring": 54, "module_mm": 1.0, "crank_mm": 10.0, "arm_mm": 56.0}
"""The paper's gear train (sun 18, ring 54 teeth, ratio -3, Eq. 10) and a reconstruction of what it
does not give: with module 1 mm the planet has 18 teeth and Eq. 3 is s_mp = 18 + l_c cos(theta_p);
a 10 mm crank and l_j = 56 mm then give exactly the tested l = 28..48 mm (Eq. 4)."""


def planet_teeth(n_sun: int, n_ring: int) -> int:
    """Planet teeth of a simple planetary train, (N_r - N_s) / 2.

    Raises
    ------
    GeometryError
        When the ring is not larger than the sun by an even number of teeth.
    """
    if n_ring <= n_sun or (n_ring - n_sun) % 2:
        raise GeometryError(
            f"n_ring = {n_ring} and n_sun = {n_sun} give no whole planet; the ring needs "
            "n_sun + 2 N_p teeth"
        )
    return (n_ring - n_sun) // 2


def support_offset_mm(
    module_mm: float, n_sun: int, n_planet: int, crank_mm: float, crank_angle_rad: float
) -> float:
    """Distance s_mp from the joint centre to the movable support (paper Eq. 3), mm."""
    return 0.5 * module_mm * (n_sun + n_planet) + crank_mm * math.cos(crank_angle_rad)


def effective_length_mm(arm_mm: float, offset_mm: float) -> float:
    """Effective leaf length l = l_j - s_mp (paper Eq. 4), mm."""
    return arm_mm - offset_mm


def crank_angle_for_length_rad(
    length_mm: float,
    arm_mm: float = PAPER_GEARS["arm_mm"],
    module_mm: float = PAPER_GEARS["module_mm"],
    n_sun: int = PAPER_GEARS["n_sun"],
    n_ring: int = PAPER_GEARS["n_ring"],
    crank_mm: float = PAPER_GEARS["crank_mm"],
) -> float:
    """Planet (crank) angle theta_p in [0, pi] that sets the effective length, rad (Eqs. 3-4).

    Raises
    ------
    GeometryError
        When the crank cannot reach that length (the message gives the reachable range).
    """
    centre = 0.5 * module_mm * (n_sun + planet_teeth(n_sun, n_ring))
    c = (arm_mm - length_mm - centre) / crank_mm
    if not -1.0 <= c <= 1.0:
        lo, hi = arm_mm - centre - crank_mm, arm_mm - centre + crank_mm
        raise GeometryError(
            f"effective length {length_mm:g} mm is out of the crank's reach [{lo:g}, {hi:g}] mm "
            f"(l_j = {arm_mm:g}, module {module_mm:g}, crank {crank_mm:g} mm)"
        )
    return math.acos(c)


@dataclass(frozen=True)
class LeafJoint:
    """One leaf of the joint and where the arm meets it (all leaves are alike).

    Attributes
    ----------
    arm_mm : float, mm — joint arm l_j = |OB|.
    effective_length_mm : float, mm — free length l = |O'B| at rest, 0 < l < l_j.
    thickness_mm : float, mm — leaf thickness t (paper: 0.5).
    width_mm : float, mm — leaf width b (paper: 11).
    n_leaves : int — leaves acting together (paper: 2).
    structure : "sliding" (paper a) or "fixed" (paper b).
    clamp_mm : float, mm — leaf length held behind the support (drawn in the outline).
    overhang_mm : float, mm — leaf length beyond B at rest (the fixed rod slides onto it).
    """

    arm_mm: float = 56.0
    effective_length_mm: float = 28.0
    thickness_mm: float = 0.5
    width_mm: float = 11.0
    n_leaves: int = 2
    structure: Literal["sliding", "fixed"] = "sliding"
    clamp_mm: float = 10.0
    overhang_mm: float = 10.0

    def __post_init__(self) -> None:
        for name in ("arm_mm", "effective_length_mm", "thickness_mm", "width_mm", "clamp_mm"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0):
                raise GeometryError(f"{name} = {value:g} must be a finite number > 0 mm")
        if not (math.isfinite(self.overhang_mm) and self.overhang_mm >= 0):
            raise GeometryError(f"overhang_mm = {self.overhang_mm:g} must be >= 0 mm")
        if self.effective_length_mm >= self.arm_mm:
            raise GeometryError(
                f"effective_length_mm = {self.effective_length_mm:g} must be shorter than the "
                f"joint arm arm_mm = {self.arm_mm:g} (the support sits between O and B)"
            )
        if int(self.n_leaves) < 1:
            raise GeometryError(f"n_leaves = {self.n_leaves} must be >= 1")
        if self.structure not in STRUCTURES:
            raise GeometryError(
                f"structure = {self.structure!r}; use 'sliding' (paper Fig. 5a) or 'fixed' (5b)"
            )

    @property
    def support_offset_mm(self) -> float:
        """s_mp = l_j - l, distance from O to the support, mm."""
        return self.arm_mm - self.effective_length_mm

    @property
    def centre_mm(self) -> np.ndarray:
        """(2,) joint centre O, mm (support O' at the origin)."""
        return np.array([self.effective_length_mm - self.arm_mm, 0.0])

    @property
    def pin_rest_mm(self) -> np.ndarray:
        """(2,) load point B at rest, mm."""
        return np.array([self.effective_length_mm, 0.0])

    def arm_direction(self, theta_rad: float) -> np.ndarray:
        """(2,) unit vector along the output arm at deflection theta."""
        return np.array([math.cos(theta_rad), math.sin(theta_rad)])

    def arm_normal(self, theta_rad: float) -> np.ndarray:
        """(2,) unit normal of the arm (the direction the arm pushes the leaf in structure a)."""
        return np.array([-math.sin(theta_rad), math.cos(theta_rad)])

    def pin_mm(self, theta_rad: float) -> np.ndarray:
        """(2,) the rod fixed to the arm (structure b) at deflection theta, mm."""
        return self.centre_mm + self.arm_mm * self.arm_direction(theta_rad)

    @property
    def second_moment_mm4(self) -> float:
        """I = b t^3 / 12, mm^4."""
        return self.width_mm * self.thickness_mm**3 / 12.0

    def leaf_profile(self, length_mm: float | None = None) -> BeamProfile:
        """The loaded leaf from O' along +x (default length l)."""
        L = self.effective_length_mm if length_mm is None else float(length_mm)
        t = np.full(2, self.thickness_mm)
        return BeamProfile(np.array([[0.0, 0.0], [L, 0.0]]), t, self.width_mm)

    def max_sliding_deflection_rad(self) -> float:
        """Largest deflection structure (a) can reach at all: the arm's line must pass within l
        of the support, s_mp sin(theta) <= l (the leaf is inextensible); pi/2 if it always does."""
        s = self.support_offset_mm
        return (
            math.asin(self.effective_length_mm / s) if s > self.effective_length_mm else math.pi / 2
        )

    def leaf_outline(self, free_length_mm: float | None = None) -> Polygon:
        """The leaf as a flat strip (mm): clamp + free length + overhang long, t thick; extrude it
        by ``width_mm`` for the part."""
        L = self.effective_length_mm if free_length_mm is None else float(free_length_mm)
        h = 0.5 * self.thickness_mm
        return box(-self.clamp_mm, -h, L + self.overhang_mm, h)
