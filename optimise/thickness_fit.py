"""The thickness that scales a shape's torque curve closest to a target (planar parts: T ∝ ST).

Used by the ``threshold_spring`` kind, which solves the out-of-plane thickness from the target
instead of searching it. Moved here from ``pipeline/studies/threshold_spring.py`` unchanged.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from flexopt.optimise.targets import curve_error

__all__ = ["fit_thickness"]


def fit_thickness(
    rotation_rad: np.ndarray,
    torque_per_mm_Nmm: np.ndarray,
    target: Any,
    measure: str,
    window: tuple[float, float],
) -> tuple[float, float]:
    """The thickness that brings a shape's torque curve closest to the target.

    The torque is proportional to the thickness, so the error measure of ``c T_1`` (T_1 the
    torque per mm of thickness) is a one-dimensional function of ``c``; for the max and rms
    measures it is convex, and a bounded scalar search finds its minimum.

    Parameters
    ----------
    rotation_rad : (n,) float, rad.
    torque_per_mm_Nmm : (n,) float, N·mm per mm of thickness.
    target : TargetCurve (N·mm over rad).
    measure : str — a key of optimise.targets.MEASURES.
    window : (float, float), rad.

    Returns
    -------
    (thickness_mm, error) : float, float — the best thickness and the measure there.
    """
    x = np.asarray(rotation_rad, dtype=float)
    y = np.asarray(torque_per_mm_Nmm, dtype=float)
    level = float(np.max(np.abs(target(x[(x >= window[0]) & (x <= window[1])]))))
    peak = float(np.max(np.abs(y)))
    if not (np.all(np.isfinite(y)) and peak > 0):
        return math.nan, math.inf
    hi = 4.0 * level / peak

    def err(c: float) -> float:
        return float(curve_error(target, x, c * y, measure, window))

    # imported here: scipy.optimize (~0.1 s CPU) is not needed by the kinds that only import
    # this module
    from scipy.optimize import minimize_scalar

    res = minimize_scalar(err, bounds=(0.0, hi), method="bounded", options={"xatol": 1e-7 * hi})
    return float(res.x), float(res.fun)
