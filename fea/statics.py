r"""Statics of a gripper finger: the force its drive must hold (paper 001, Vela, Vela, Miclosina
2023, Eqs. 1–14).

The paper's finger (its Fig. 3) turns about the pivot E. The actuator side pushes along a fixed
line at the perpendicular distance ``l1`` from E (Eqs. 3, 10–11: ``F1 cos α · l1/cos α = F1 l1``,
so the moment of ``F1`` is ``F1 l1`` whatever ``α``); the jaw contact J sits at ``l2`` from E, on a
line at ``ψ = α + β`` above the horizontal (Eq. 8 takes the part of the jaw force perpendicular
to ``l2`` as ``F2 cos(α + β)``, which is that for a vertical ``F2``). Moment balance about E:

.. math:: F_1 l_1 = |\vec{r}_{EJ} \times \vec{F}_2|, \qquad \vec{F}_2 = w\,G\,\hat g + N\,\hat n

with ``G = m g`` (Eq. 7), ``ĝ`` the direction of gravity, ``N`` the contact normal force along
``n̂`` (the push of the workpiece on the jaw) and ``w`` the share of the weight this jaw carries.

**Where the paper adds vectors as scalars.** Eq. 5 writes ``F2 = G + N`` as vectors and Eq. 6
takes ``|F2| = G + N``; Eq. 10 then uses ``(G + N) cos(α + β)``. That is exact only when ``N`` is
parallel to ``G`` and the jaw carries the whole weight (``n̂ = ĝ``, ``w = 1``): the paper's lower
finger of a horizontal gripper, the workpiece resting on the jaw. For any other jaw —
the upper finger (``N`` against gravity: ``N - G``), fingers closing horizontally (``N ⟂ G``,
the weight held by friction and shared between jaws), inclined or V-jaws — the vector form gives
a different, usually smaller, moment; :func:`finger_force` returns both and their difference.
Eqs. 1–2 (``F1 = Fa - Fspr``) add coaxial forces and are exact.

Units: N, mm, N·mm, rad, kg; ``g`` in m/s².
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from flexopt.fea.errors import FeaError

__all__ = [
    "STANDARD_GRAVITY_M_PER_S2",
    "FingerGeometry",
    "FingerRequirement",
    "JawLoad",
    "actuator_force_N",
    "finger_force",
    "finger_force_paper_N",
    "normal_force_for_friction_N",
    "overtravel_mm",
    "unit_vector",
]

STANDARD_GRAVITY_M_PER_S2 = 9.80665


def unit_vector(angle_rad: float) -> np.ndarray:
    """(2,) unit vector at ``angle_rad`` from +x, counter-clockwise (``-π/2`` is down)."""
    return np.array([math.cos(angle_rad), math.sin(angle_rad)])


@dataclass(frozen=True)
class FingerGeometry:
    """The finger of paper 001, Fig. 3.

    Attributes
    ----------
    lever_mm : float, mm — ``l1``: perpendicular distance from the pivot E to the line of the
        actuator force ``F1`` (Eq. 11: ``l1 = l1' cos α``).
    jaw_mm : float, mm — ``l2``: from E to the jaw contact J.
    alpha_rad : float, rad — ``α``: the finger's rotation (set by the workpiece size).
    beta_rad : float, rad — ``β``: the fixed angle of the jaw arm; E→J is at ``α + β`` from
        the horizontal.
    """

    lever_mm: float
    jaw_mm: float
    alpha_rad: float
    beta_rad: float

    def __post_init__(self) -> None:
        if not (self.lever_mm > 0 and self.jaw_mm > 0):
            raise FeaError(
                f"finger lever_mm = {self.lever_mm} and jaw_mm = {self.jaw_mm} must be > 0"
            )

    @property
    def jaw_angle_rad(self) -> float:
        """``ψ = α + β``, the angle of E→J from the horizontal."""
        return self.alpha_rad + self.beta_rad


@dataclass(frozen=True)
class JawLoad:
    """What the workpiece does to one jaw.

    Attributes
    ----------
    mass_kg : float, kg — the workpiece.
    normal_force_N : float, N — ``N``, the contact normal force (the grip).
    normal_angle_rad : float, rad — direction of the workpiece's push on the jaw, from +x
        (paper's lower finger: ``-π/2``, down, parallel to gravity).
    gravity_angle_rad : float, rad — direction of gravity, from +x (``-π/2``).
    weight_share : float — share of ``G`` this jaw carries (paper: 1, the workpiece rests on the
        lower jaw; fingers that hold by friction share it, e.g. 1/2).
    acceleration_m_per_s2 : float, m/s² — extra acceleration of the gripper along gravity
        (``G = m (g + a)``; 0 at rest).
    """

    mass_kg: float
    normal_force_N: float
    normal_angle_rad: float = -0.5 * math.pi
    gravity_angle_rad: float = -0.5 * math.pi
    weight_share: float = 1.0
    acceleration_m_per_s2: float = 0.0

    def __post_init__(self) -> None:
        if not self.mass_kg >= 0:
            raise FeaError(f"mass_kg = {self.mass_kg} must be >= 0")
        if not self.normal_force_N >= 0:
            raise FeaError(f"normal_force_N = {self.normal_force_N} must be >= 0")
        if not 0 <= self.weight_share <= 1:
            raise FeaError(f"weight_share = {self.weight_share} must lie in [0, 1]")

    @property
    def weight_N(self) -> float:
        """``G = m (g + a)``, N (Eq. 7)."""
        return self.mass_kg * (STANDARD_GRAVITY_M_PER_S2 + self.acceleration_m_per_s2)

    @property
    def jaw_force_vector_N(self) -> np.ndarray:
        """(2,) ``F2 = w G ĝ + N n̂``, N (Eq. 5 as vectors)."""
        return self.weight_share * self.weight_N * unit_vector(
            self.gravity_angle_rad
        ) + self.normal_force_N * unit_vector(self.normal_angle_rad)


@dataclass(frozen=True)
class FingerRequirement:
    """The force the finger's drive must hold, by the vector form and by the paper's Eq. 14.

    Attributes
    ----------
    finger_force_N : float, N — ``F1 = |r_EJ × F2| / l1`` (vector form).
    paper_finger_force_N : float, N — Eq. 14, ``(G + N) cos(α + β) l2/l1``.
    relative_difference : float — ``paper / vector - 1`` (0 where they agree).
    moment_Nmm : float, N·mm — signed moment of the jaw force about E (counter-clockwise > 0).
    jaw_force_N : float, N — ``|F2|`` as a vector sum.
    paper_jaw_force_N : float, N — Eq. 6, ``G + N``.
    weight_N : float, N — G.
    """

    finger_force_N: float
    paper_finger_force_N: float
    relative_difference: float
    moment_Nmm: float
    jaw_force_N: float
    paper_jaw_force_N: float
    weight_N: float


def finger_force_paper_N(load: JawLoad, finger: FingerGeometry) -> float:
    """Eq. 14 as printed: ``F1 = (G + N) cos(α + β) l2 / l1``, N (with the load's full ``G``)."""
    return (
        (load.weight_N + load.normal_force_N)
        * math.cos(finger.jaw_angle_rad)
        * finger.jaw_mm
        / finger.lever_mm
    )


def finger_force(load: JawLoad, finger: FingerGeometry) -> FingerRequirement:
    """The drive force ``F1`` that holds the jaw load, by moments about the pivot E.

    Returns
    -------
    FingerRequirement
        The vector form and Eq. 14 side by side.
    """
    arm = finger.jaw_mm * unit_vector(finger.jaw_angle_rad)
    f2 = load.jaw_force_vector_N
    moment = float(arm[0] * f2[1] - arm[1] * f2[0])
    f1 = abs(moment) / finger.lever_mm
    paper = finger_force_paper_N(load, finger)
    return FingerRequirement(
        finger_force_N=f1,
        paper_finger_force_N=paper,
        relative_difference=paper / f1 - 1.0 if f1 > 0 else math.inf,
        moment_Nmm=moment,
        jaw_force_N=float(np.hypot(*f2)),
        paper_jaw_force_N=load.weight_N + load.normal_force_N,
        weight_N=load.weight_N,
    )


def actuator_force_N(finger_force_N: float, return_spring_N: float) -> float:
    """Eq. 13: the actuator must add the return spring's force, ``F_a = F1 + F_spr``, N."""
    return finger_force_N + return_spring_N


def normal_force_for_friction_N(
    mass_kg: float,
    friction: float,
    contacts: int = 2,
    safety: float = 2.0,
    acceleration_m_per_s2: float = 0.0,
) -> float:
    """Grip normal force that holds a workpiece by friction: ``N = S m (g + a) / (n μ)``, N.

    Parameters
    ----------
    mass_kg : float, kg.
    friction : float — μ between jaw and workpiece, > 0.
    contacts : int — jaws sharing the weight.
    safety : float — S >= 1.
    acceleration_m_per_s2 : float, m/s² — of the gripper along gravity.
    """
    if not friction > 0:
        raise FeaError(f"friction = {friction} must be > 0 to hold a workpiece by friction")
    if contacts < 1 or safety < 1:
        raise FeaError(f"contacts = {contacts} must be >= 1 and safety = {safety} >= 1")
    return (
        safety
        * mass_kg
        * (STANDARD_GRAVITY_M_PER_S2 + acceleration_m_per_s2)
        / (contacts * friction)
    )


def overtravel_mm(lever_mm: float, alpha_range_rad: Any) -> float:
    """Travel of the drive line between the finger rotations ``α_min, α_max``, mm.

    The drive pushes along a fixed line at ``l1`` from E, meeting the finger (a pin in a slot,
    the paper's joints C/D) at ``l1 tan α`` along it; workpieces whose sizes close the finger at
    different ``α`` leave the drive this much travel to absorb — the stroke a constant-force
    element in the drive must hold its force over.
    """
    a = np.asarray(alpha_range_rad, dtype=float)
    if a.shape != (2,) or not np.all(np.abs(a) < 0.5 * math.pi):
        raise FeaError(f"alpha range {a} must be two angles inside (-90°, 90°)")
    return float(lever_mm * abs(math.tan(a[1]) - math.tan(a[0])))
