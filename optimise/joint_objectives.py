"""Objectives and constraints of the joint kinds (flexure pivot, leaf-spring joint, gripper).

What the GA and the verdict see of a joint design, from the numbers the fea/ models return:

* :class:`PivotLimits`, :func:`pivot_objective` — a flexure pivot: the stress ratio
  ``sigma / sigma_allowable`` at the range of motion (minimised: its inverse is the safety
  factor) and the constraints ``g <= 0`` on the stiffness band, the stress, the envelope and,
  optionally, the centre shift.
* :func:`pivot_plane_stress_figures` — the plane-stress figures of a pivot the verdict judges.
* :func:`leaf_joint_layout_constraints`, :func:`leaf_joint_unreachable`,
  :func:`leaf_joint_objective` — a leaf-spring joint sized for a stiffness range: the support's
  travel inside the mechanism's limits, and the leaf's stress ratio.
* :func:`plateau_mean_N` — the mean force of a traced curve over a stroke window (the gripper's
  constant-force beam is rescaled and judged by it).

Units: mm, N, MPa, N·mm, rad; constraint values are dimensionless (``value / limit - 1``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "PivotLimits",
    "leaf_joint_layout_constraints",
    "leaf_joint_objective",
    "leaf_joint_unreachable",
    "pivot_objective",
    "pivot_plane_stress_figures",
    "plateau_mean_N",
]


@dataclass(frozen=True)
class PivotLimits:
    """What a flexure pivot is held to.

    Attributes
    ----------
    target_Nmm_per_rad : float, N·mm/rad — small-angle stiffness M / theta to meet.
    tolerance : float — the stiffness band's half-width, a fraction of the target.
    allowable_MPa : float, MPa — allowable stress at the range of motion.
    max_length_mm, max_height_mm : float, mm — the envelope.
    max_centre_shift_mm : float or None, mm — adds the centre-shift constraint when given.
    """

    target_Nmm_per_rad: float
    tolerance: float
    allowable_MPa: float
    max_length_mm: float
    max_height_mm: float
    max_centre_shift_mm: float | None = None

    @property
    def constraint_names(self) -> tuple[str, ...]:
        """Names of the constraints :func:`pivot_objective` returns, in its order."""
        names = ("stiffness_band", "stress", "envelope_length", "envelope_height")
        return names if self.max_centre_shift_mm is None else (*names, "centre_shift")


def pivot_objective(
    limits: PivotLimits,
    stiffness_Nmm_per_rad: float,
    stress_MPa: float,
    envelope_mm: tuple[float, float],
    centre_shift_mm: float,
) -> tuple[float, np.ndarray]:
    """The stress ratio and the constraints of a flexure pivot.

    Parameters
    ----------
    limits : PivotLimits.
    stiffness_Nmm_per_rad : float, N·mm/rad — small-angle stiffness M / theta.
    stress_MPa : float, MPa — design stress at the range of motion.
    envelope_mm : (length, height), mm — the part's bounding box.
    centre_shift_mm : float, mm — centre shift at the range of motion (NaN when not traced).

    Returns
    -------
    ratio : float — ``stress / allowable`` (the objective).
    g : (4,) or (5,) float — stiffness band, stress, envelope length, envelope height[, centre
        shift], each ``<= 0`` when met (:attr:`PivotLimits.constraint_names`).
    """
    length, height = envelope_mm
    ratio = stress_MPa / limits.allowable_MPa
    g = [
        abs(stiffness_Nmm_per_rad / limits.target_Nmm_per_rad - 1.0) - limits.tolerance,
        ratio - 1.0,
        length / limits.max_length_mm - 1.0,
        height / limits.max_height_mm - 1.0,
    ]
    if limits.max_centre_shift_mm is not None:
        g.append(centre_shift_mm / limits.max_centre_shift_mm - 1.0)
    return ratio, np.array(g)


def pivot_plane_stress_figures(ps: Mapping[str, Any]) -> dict[str, Any]:
    """The plane-stress figures the verdict judges from a plane-stress check record
    (:func:`fea.flexure_design.plane_stress_check`): the linear stiffness (N·mm/rad), and the peak
    von Mises stress (MPa), the largest of every row from rest to the range of motion, when the
    nonlinear solve reached the range (a record without the rows' figure: the last row's)."""
    out: dict[str, Any] = {}
    if "linear_stiffness_Nmm_per_rad" in ps:
        out["plane_stress_stiffness_Nmm_per_rad"] = ps["linear_stiffness_Nmm_per_rad"]
    if ps.get("ok") and "peak_von_mises_at_range_MPa" in ps:
        out["plane_stress_peak_stress_MPa"] = ps.get(
            "peak_von_mises_MPa", ps["peak_von_mises_at_range_MPa"]
        )
    return out


def leaf_joint_layout_constraints(
    l_min_mm: float,
    l_max_mm: float,
    arm_mm: float,
    min_effective_length_mm: float,
    min_support_offset_mm: float,
) -> tuple[float, float]:
    """(g_length, g_hub) of a leaf-spring joint whose support travels over ``[l_min, l_max]``:
    the shortest free length the support allows, and the support kept ``min_support_offset_mm``
    off the centre O (it may not enter the hub), each ``<= 0`` when met."""
    return (
        min_effective_length_mm / l_min_mm - 1.0,
        (l_max_mm + min_support_offset_mm) / arm_mm - 1.0,
    )


def leaf_joint_unreachable(g_length: float, g_hub: float) -> tuple[np.ndarray, np.ndarray]:
    """(f (1,), g (3,)) of a joint whose support cannot reach the soft end: no solve is made (its
    stress would mean nothing), the objective and the stress constraint are a penalty that still
    falls as the hub constraint does, so the GA is led back into the feasible layouts."""
    penalty = 10.0 + g_hub
    return np.array([penalty]), np.array([g_length, g_hub, penalty])


def leaf_joint_objective(
    stress_MPa: float, allowable_MPa: float, g_length: float, g_hub: float
) -> tuple[float, np.ndarray]:
    """(ratio, g (3,)) of a traced joint: the stress ratio ``stress / allowable`` at the largest
    deflection (the objective), and the constraints (length, hub, stress)."""
    ratio = stress_MPa / allowable_MPa
    return ratio, np.array([g_length, g_hub, ratio - 1.0])


def plateau_mean_N(
    displacement_mm: np.ndarray, force_N: np.ndarray, lo_mm: float, hi_mm: float
) -> float:
    """Mean force of the piecewise-linear curve over ``[lo_mm, hi_mm]`` (its integral over the
    window's length), N.

    Parameters
    ----------
    displacement_mm : (n,) float, mm — increasing.
    force_N : (n,) float, N — at those displacements.
    lo_mm, hi_mm : float, mm — the window.
    """
    s = np.asarray(displacement_mm, dtype=float)
    f = np.asarray(force_N, dtype=float)
    inner = (s > lo_mm) & (s < hi_mm)
    ss = np.concatenate([[lo_mm], s[inner], [hi_mm]])
    return float(np.trapezoid(np.interp(ss, s, f), ss) / (hi_mm - lo_mm))
