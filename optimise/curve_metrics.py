"""Constant-force metrics of one force-stroke curve: RMS error, operative window, flatness.

The scoring of the ``constant_force`` kind (paper 003): the response is taken as piecewise linear
between its rows and every band or stress crossing is found exactly on that interpolant (see
:func:`curve_metrics`). Moved here from ``pipeline/studies/constant_force.py`` unchanged.
Units: mm, N, MPa (as named).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["CurveMetrics", "curve_metrics"]


@dataclass(frozen=True)
class CurveMetrics:
    """What the response of one design says about constant force (see :func:`curve_metrics`).

    Attributes
    ----------
    rms_error_N : float, N — RMS of F - target over the objective samples (Eq. 8).
    operative_stroke_mm : float, mm — length of the longest window where the force is in the band
        and the stress is allowable; 0 when there is none.
    window_mm : (float, float), mm — that window (``(nan, nan)`` when there is none).
    mean_force_N, flatness_percent : float or None — mean of F over the window and max |F - mean|
        / mean in percent; None without a window.
    peak_stress_MPa : float, MPa — over the whole stroke.
    window_peak_stress_MPa : float, MPa — over ``[0, window end]`` (0 without a window).
    stress_limit_stroke_mm : float or None, mm — first stroke where the stress reaches the
        allowable; None when it never does.
    plateau_mean_force_N, plateau_flatness_percent : float or None — the same as mean_force and
        flatness, over the stress-admissible part of the stroke from the first row on, whatever
        the target (how constant the force is, not whether it is the right one).
    """

    rms_error_N: float
    operative_stroke_mm: float
    window_mm: tuple[float, float]
    mean_force_N: float | None
    flatness_percent: float | None
    peak_stress_MPa: float
    window_peak_stress_MPa: float
    stress_limit_stroke_mm: float | None
    plateau_mean_force_N: float | None
    plateau_flatness_percent: float | None


def _interval(y0: float, y1: float, lo: float, hi: float) -> tuple[float, float] | None:
    """Part ``[u0, u1]`` of [0, 1] where ``lo <= y0 + u (y1 - y0) <= hi`` (or None)."""
    dy = y1 - y0
    if dy == 0.0:
        return (0.0, 1.0) if lo <= y0 <= hi else None
    a, b = (lo - y0) / dy, (hi - y0) / dy
    u0, u1 = max(0.0, min(a, b)), min(1.0, max(a, b))
    return (u0, u1) if u0 <= u1 else None


def _windows(
    s: np.ndarray,
    force: np.ndarray,
    stress: np.ndarray,
    band: tuple[float, float],
    allowable: float,
) -> list[tuple[float, float]]:
    """Stroke intervals where the piecewise-linear force is in ``band`` and the piecewise-linear
    stress is at most ``allowable``, merged where they touch, in stroke order."""
    out: list[list[float]] = []
    for k in range(len(s) - 1):
        fi = _interval(force[k], force[k + 1], *band)
        si = _interval(stress[k], stress[k + 1], -np.inf, allowable)
        if fi is None or si is None:
            continue
        u0, u1 = max(fi[0], si[0]), min(fi[1], si[1])
        if u0 > u1:
            continue
        a = s[k] + u0 * (s[k + 1] - s[k])
        b = s[k] + u1 * (s[k + 1] - s[k])
        if out and abs(out[-1][1] - a) <= 1e-12 * max(1.0, abs(a)):
            out[-1][1] = b
        else:
            out.append([a, b])
    return [(a, b) for a, b in out]


def _piecewise_stats(
    s: np.ndarray, force: np.ndarray, a: float, b: float
) -> tuple[float | None, float | None]:
    """Mean (integral / length) and max |F - mean| / mean in percent of the piecewise-linear
    force over [a, b]; its extremes sit at the rows inside and the interpolated ends."""
    if not b > a:
        return None, None
    inner = (s > a) & (s < b)
    ss = np.concatenate([[a], s[inner], [b]])
    ff = np.interp(ss, s, force)
    mean = float(np.trapezoid(ff, ss) / (b - a))
    if mean == 0.0:
        return mean, None
    return mean, float(np.max(np.abs(ff - mean)) / abs(mean) * 100.0)


def curve_metrics(
    stroke_mm: np.ndarray,
    force_N: np.ndarray,
    stress_MPa: np.ndarray,
    target_N: float,
    tolerance: float,
    allowable_MPa: float,
    samples: int,
) -> CurveMetrics:
    """Constant-force metrics of one traced response.

    The response is taken as piecewise linear between its rows; every crossing (band edges,
    allowable stress) is found exactly on that interpolant, so the metrics are finer than the
    objective's ``samples`` and need no extra solve. Row 0 is the unloaded state (F = 0) and the
    beam buckles within a fraction of a millimetre after it, so the straight line from row 0 to
    row 1 says nothing about the force in between (it would cross any band on the way up): the
    windows are searched from row 1 on. A window therefore starts at the earliest at
    ``stroke / rows``, up to one row spacing later than the physical plateau (conservative).

    Parameters
    ----------
    stroke_mm : (n,) float, mm — increasing from 0.
    force_N : (n,) float, N — output force at those strokes.
    stress_MPa : (n,) float, MPa — peak stress over the beam at those strokes.
    target_N : float, N.
    tolerance : float — half-width of the band as a fraction of ``target_N`` (0.02 = 2 %).
    allowable_MPa : float, MPa.
    samples : int — r; the RMS objective uses the strokes ``stroke_max * i / r``, i = 1..r.

    Returns
    -------
    CurveMetrics
    """
    s = np.asarray(stroke_mm, dtype=float)
    f = np.asarray(force_N, dtype=float)
    sig = np.asarray(stress_MPa, dtype=float)
    probes = s[-1] * np.arange(1, samples + 1) / samples
    rms = float(np.sqrt(np.mean((np.interp(probes, s, f) - target_N) ** 2)))
    band = (target_N * (1.0 - tolerance), target_N * (1.0 + tolerance))
    windows = _windows(s[1:], f[1:], sig[1:], band, allowable_MPa)
    if windows:
        a, b = max(windows, key=lambda w: (w[1] - w[0], -w[0]))
        mean, flat = _piecewise_stats(s, f, a, b)
        window_stress = float(np.max(np.interp(np.append(s[s <= b], b), s, sig)))
    else:
        a = b = math.nan
        mean = flat = None
        window_stress = 0.0
    over = np.flatnonzero(sig >= allowable_MPa)
    if over.size == 0:
        limit = None
    elif over[0] == 0:
        limit = 0.0
    else:
        k = int(over[0])
        u = (allowable_MPa - sig[k - 1]) / (sig[k] - sig[k - 1])
        limit = float(s[k - 1] + u * (s[k] - s[k - 1]))
    plateau_end = s[-1] if limit is None else limit
    plateau_mean, plateau_flat = _piecewise_stats(s, f, float(s[1]), float(plateau_end))
    return CurveMetrics(
        rms_error_N=rms,
        operative_stroke_mm=float(b - a) if windows else 0.0,
        window_mm=(float(a), float(b)),
        mean_force_N=mean,
        flatness_percent=flat,
        peak_stress_MPa=float(np.max(sig)),
        window_peak_stress_MPa=window_stress,
        stress_limit_stroke_mm=limit,
        plateau_mean_force_N=plateau_mean,
        plateau_flatness_percent=plateau_flat,
    )
