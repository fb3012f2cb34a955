"""Thickness and width laws solved from a target: the closed forms a study kind sizes a section
with instead of searching for it (issue #24: physics in fea/, not in the kinds).

* **Small-length flexural pivots** (Bilancia et al. 2019, Eq. 12): ``K = E I / L`` with ``I = h^3
  b / 12``, and its two inversions, the thickness or the width that give a stiffness ``K``
  (moved from ``geometry/constant_force.py``).
* **Thickness-proportional responses**: a planar part's torque or force under an imposed motion
  is proportional to its out-of-plane thickness (the same in-plane field times the thickness), so
  a curve solved at one thickness is the curve at another times their ratio
  (:func:`at_thickness`; the threshold spring solves its arm at a reference thickness and scales).

The errors are :class:`geometry.errors.GeometryError`, as before the move. Units: mm, N, N·mm,
rad, MPa.
"""

from __future__ import annotations

import numpy as np
from flexopt.geometry.errors import GeometryError

__all__ = [
    "require_positive",
    "flexure_stiffness_Nmm",
    "flexure_thickness_mm",
    "flexure_width_mm",
    "at_thickness",
]


def require_positive(name: str, value: np.ndarray | float) -> np.ndarray:
    """``value`` as a float array; GeometryError (naming ``name``) unless all finite and > 0."""
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise GeometryError(f"{name} = {value} must be finite and > 0")
    return arr


def flexure_stiffness_Nmm(
    E_MPa: float, width_mm: np.ndarray, thickness_mm: np.ndarray, length_mm: np.ndarray
) -> np.ndarray:
    """Rotational stiffness of a small-length flexural pivot, ``K = E I / L``, ``I = h^3 b / 12``
    (Eq. 12). Broadcasts over its array arguments.

    Parameters
    ----------
    E_MPa : float, MPa
    width_mm, thickness_mm, length_mm : float or (k,), mm — b, h, L.

    Returns
    -------
    float or (k,) float, N·mm/rad
    """
    b = require_positive("width_mm", width_mm)
    h = require_positive("thickness_mm", thickness_mm)
    L = require_positive("length_mm", length_mm)
    return require_positive("E_MPa", E_MPa) * h**3 * b / 12.0 / L


def flexure_thickness_mm(
    K_Nmm: np.ndarray, E_MPa: float, width_mm: np.ndarray, length_mm: np.ndarray
) -> np.ndarray:
    """Thickness giving stiffness ``K``: ``h = (12 K L / (E b))^(1/3)`` (Eq. 12 inverted).

    Returns
    -------
    float or (k,) float, mm
    """
    K = require_positive("K_Nmm", K_Nmm)
    b = require_positive("width_mm", width_mm)
    L = require_positive("length_mm", length_mm)
    return np.cbrt(12.0 * K * L / (require_positive("E_MPa", E_MPa) * b))


def flexure_width_mm(
    K_Nmm: np.ndarray, E_MPa: float, thickness_mm: np.ndarray, length_mm: np.ndarray
) -> np.ndarray:
    """Width giving stiffness ``K``: ``b = 12 K L / (E h^3)`` (Eq. 12 inverted).

    Returns
    -------
    float or (k,) float, mm
    """
    K = require_positive("K_Nmm", K_Nmm)
    h = require_positive("thickness_mm", thickness_mm)
    L = require_positive("length_mm", length_mm)
    return 12.0 * K * L / (require_positive("E_MPa", E_MPa) * h**3)


def at_thickness(values: np.ndarray, from_mm: float, to_mm: float) -> np.ndarray:
    """A thickness-proportional response (torque, force, stiffness) solved at ``from_mm`` as it
    is at ``to_mm``: ``values * (to_mm / from_mm)``.

    Parameters
    ----------
    values : (m,) float — in any unit; the result has the same unit and shape.
    from_mm, to_mm : float, mm — the thickness solved at and the one wanted.
    """
    return values * (to_mm / from_mm)
