"""A result's plot spec: its one vocabulary (:func:`plot_spec`) and the target a response plot
draws (:func:`target_overlay`).

A kind's plot dict (:attr:`optimise.problem.DesignResult.plot`, of ``flexopt evaluate`` and of
``flexopt run``'s best design alike; :attr:`optimise.problem.CaseResponse.plot` of a load case)
names its columns and its words with these keys:

- columns: ``x`` (the abscissa, default ``displacement_mm``), ``y`` (the response, default
  ``force_N``) and ``stress`` (the second panel, default ``peak_stress_MPa``: the peak stress of
  every structural kind; a kind without one names its second response there, the SEA window's
  ``bandwidth_Hz``);
- words: ``x_label``, ``y_label``, ``stress_label`` (axes; ``y_label`` also names a lone
  response curve in the legend), ``y_title``, ``stress_title`` (panel titles), and for the line
  on the stress panel ``allowable_MPa`` (its value, MPa), ``allowable_label`` (its word, "yield"
  by default for a stress column, "allowable" otherwise) or ``allowable_text`` (its whole
  legend);
- the target of ``y``, below.

Every reader (the PNG plots, report.html, the robustness band, the run folder) reads a spec
through :func:`plot_spec`, the one place that knows the old names a plugin may still give:
``left`` / ``right`` for ``y`` / ``stress`` (the vocabulary of the kinds' former evaluate
results), ``xlabel`` / ``ylabel`` and ``left_label`` for ``x_label`` / ``y_label``,
``right_label`` for ``stress_label``, ``left_title`` / ``right_title`` for ``y_title`` /
``stress_title`` (:data:`OLD_PLOT_KEYS`).

A spec may state the target of its response column in one of three forms, all in the column's
unit:

- ``target``: a constant (a force of 1.5 N, a stiffness of 300 N·mm/rad);
- ``target_curve``: the name of a table column holding the target at each row (the cam's
  ``target_torque_Nm``), or a mapping ``{"x": (m,) array, "y": (m,) array}`` for a target that
  is not a column (a flexure pivot's torque ``K θ`` against rotation);
- ``target_range``: ``[low, high]``, a band with no single target value (a window of
  stiffness).

The band around a ``target`` or ``target_curve`` is ``tolerance`` (half-width, the column's
unit), ``tolerance_rel`` (a fraction of the target at each point, 0.02 = ±2 %) or
``tolerance_of_max`` (a fraction of the largest |target|, as the threshold-spring error
measure normalises). ``band_x`` ``[x0, x1]`` limits the target to part of the x range;
``target_label`` names it in the legend (default "target"); ``target_of`` names the column the
target belongs to when it is not the spec's response column.

:func:`target_overlay` resolves this once into plain arrays, which both the PNG plots
(``pipeline/plots.py``) and report.html (``pipeline/report_html.py``) draw, so the two show the
same target.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np

__all__ = [
    "OLD_PLOT_KEYS",
    "PLOT_DEFAULTS",
    "TargetOverlay",
    "band_spec",
    "measure_band",
    "plot_spec",
    "response_column",
    "target_overlay",
]

#: The columns a spec names, with the column each means when the spec does not name it.
PLOT_DEFAULTS: Mapping[str, str] = MappingProxyType(
    {"x": "displacement_mm", "y": "force_N", "stress": "peak_stress_MPa"}
)

#: The old names of plot-spec keys a plugin may still give, with the key each stands for. Where
#: a spec gives both, the key of the one vocabulary wins; among old names, the first listed.
OLD_PLOT_KEYS: Mapping[str, str] = MappingProxyType(
    {
        "left": "y",
        "right": "stress",
        "xlabel": "x_label",
        "ylabel": "y_label",
        "left_label": "y_label",
        "right_label": "stress_label",
        "left_title": "y_title",
        "right_title": "stress_title",
    }
)


def plot_spec(spec: Mapping[str, Any] | None) -> dict[str, Any]:
    """``spec`` in the one vocabulary (the module docstring): every old key
    (:data:`OLD_PLOT_KEYS`) under its new name, the columns ``x``, ``y`` and ``stress`` always
    present (:data:`PLOT_DEFAULTS` where the spec names none; a column given as None stays None:
    the spec has none, e.g. no stress panel). The target and word keys pass as they are; the
    input is not changed."""
    spec = spec or {}
    out = {key: value for key, value in spec.items() if key not in OLD_PLOT_KEYS}
    for old, new in OLD_PLOT_KEYS.items():
        if old in spec and new not in out:
            out[new] = spec[old]
    for key, default in PLOT_DEFAULTS.items():
        out.setdefault(key, default)
    return out


@dataclass(frozen=True)
class TargetOverlay:
    """A target to draw over a response curve.

    Attributes
    ----------
    column : str
        The response column the target belongs to.
    x : (m,) float
        Abscissae of the target, in the unit of the plot's x column.
    y : (m,) float or None
        The target, in the column's unit; None for a range without a single target value.
    lower, upper : (m,) float or None
        The band around it (the range itself for ``target_range``); None when there is no band.
    label : str
        Words for the legend: ``target 1.5 ± 0.03`` or ``target curve ± 5 % of max``.
    """

    column: str
    x: np.ndarray
    y: np.ndarray | None
    lower: np.ndarray | None
    upper: np.ndarray | None
    label: str


def _float(value: Any) -> float | None:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


def measure_band(measure: str, tolerance: float) -> dict[str, float]:
    """The band key of a plot spec for a tolerance on a target-curve error measure
    (:data:`optimise.targets.MEASURES`): ``*_normalised`` measures are fractions of the largest
    target (``tolerance_of_max``), ``*_relative`` ones of the local target (``tolerance_rel``);
    the absolute measures (``rms``, ``max_abs``) are in the curve's own unit, which the plotted
    column need not share, so they give no band (the target curve alone is drawn)."""
    if measure.endswith("_normalised"):
        return {"tolerance_of_max": float(tolerance)}
    if measure.endswith("_relative"):
        return {"tolerance_rel": float(tolerance)}
    return {}


def band_spec(
    requirements: Iterable[Any],
    table: Mapping[str, Any],
    x: str,
    key: str = "y",
    prefix: str = "",
) -> dict[str, Any]:
    """Plot-spec entries drawing a study's target band (an
    :class:`optimise.requirements.TargetBand` on a column of ``table`` against ``x``): that
    column as the response (under ``key``, ``y``) with its words (``y_label``), its target curve
    at the rows of ``over`` and the band's tolerance. ``prefix`` (``case.``) keeps the
    requirements of one load case of a multi-case study. Empty when there is none.
    """
    from flexopt.optimise.requirements import TargetBand

    for r in requirements:
        if not isinstance(r, TargetBand) or not r.quantity.startswith(prefix):
            continue
        column, along = r.quantity[len(prefix) :], r.x.removeprefix(prefix)
        if column not in table or along != x or x not in table:
            continue
        xs = np.asarray(table[x], dtype=float)
        if r.over is not None:
            xs = xs[(xs >= r.over[0] - 1e-12) & (xs <= r.over[1] + 1e-12)]
        try:
            ys = r.target_at(xs)  # the target in the column's unit
        except Exception:  # a target outside its table: nothing to draw, never a failure
            continue
        band = {"tolerance": r.tolerance} if r.tolerance is not None else {}
        if r.tolerance_rel is not None:
            band = {"tolerance_rel": r.tolerance_rel}
        from flexopt.pipeline.labels import label

        words = label(column, plain=True)  # a study's own column: its own words, not NAMES
        return {
            key: column,
            "y_label": words,
            "target_curve": {"x": xs, "y": ys},
            **band,
            "target_label": f"target ({r.label})" if r.label else "target",
        }
    return {}


def response_column(spec: Mapping[str, Any]) -> str:
    """The response column of a plot spec: its ``y`` (:func:`plot_spec`; ``force_N`` when it
    names none)."""
    return str(plot_spec(spec)["y"] or PLOT_DEFAULTS["y"])


def _band_text(spec: Mapping[str, Any], unit: str) -> str:
    if _float(spec.get("tolerance")):
        return f" ± {float(spec['tolerance']):.4g}{unit}"
    if _float(spec.get("tolerance_rel")):
        return f" ± {100 * float(spec['tolerance_rel']):g} %"
    if _float(spec.get("tolerance_of_max")):
        return f" ± {100 * float(spec['tolerance_of_max']):g} % of its maximum"
    return ""


def target_overlay(
    spec: Mapping[str, Any],
    table: Mapping[str, Any],
    column: str | None = None,
    unit: str | None = None,
) -> TargetOverlay | None:
    """The target of ``column`` (default: the spec's response column) as arrays, or None.

    None when the spec states no target, when it states one for another column
    (``target_of``), or when its target curve is not in the table.

    Parameters
    ----------
    spec : mapping
        The kind's plot dict (keys in the module docstring).
    table : mapping of str to (n,) array
        The response; ``spec["x"]`` (default ``displacement_mm``) is its abscissa.
    column : str, optional
        The column being drawn.
    unit : str, optional
        Written after the numbers of the legend (``" N"``), when given.
    """
    spec = plot_spec(spec)
    y_name = response_column(spec)
    column = column or y_name
    if column != str(spec.get("target_of") or y_name):
        return None
    x_name = spec["x"]
    if x_name not in table:
        return None
    xs = np.asarray(table[x_name], dtype=float)
    if xs.size == 0:
        return None
    u = f" {unit}" if unit else ""
    word = str(spec.get("target_label") or "target")
    constant = _float(spec.get("target"))
    curve = spec.get("target_curve")
    window = spec.get("target_range")
    if constant is not None:
        x = np.array([np.nanmin(xs), np.nanmax(xs)])
        y = np.full(2, constant)
        label = f"{word} {constant:.4g}{u}{_band_text(spec, u)}"
    elif isinstance(curve, str):
        if curve not in table:
            return None
        x, y = xs, np.asarray(table[curve], dtype=float)
        label = f"{word}{_band_text(spec, u)}"
    elif isinstance(curve, Mapping) and "x" in curve and "y" in curve:
        x = np.asarray(curve["x"], dtype=float).ravel()
        y = np.asarray(curve["y"], dtype=float).ravel()
        if x.shape != y.shape or x.size == 0:
            return None
        label = f"{word}{_band_text(spec, u)}"
    elif window is not None and len(window) == 2:
        lo, hi = sorted(float(v) for v in window)
        x = np.array([np.nanmin(xs), np.nanmax(xs)])
        label = f"{word} {lo:g}–{hi:g}{u}"
        x, lower, upper = _clip(spec, x, np.full(2, lo), np.full(2, hi))
        return TargetOverlay(column, x, None, lower, upper, label)
    else:
        return None
    lower = upper = None
    tol = _float(spec.get("tolerance"))
    rel = _float(spec.get("tolerance_rel"))
    of_max = _float(spec.get("tolerance_of_max"))
    if tol:
        half = np.full_like(y, abs(tol))
    elif rel:
        half = abs(rel) * np.abs(y)
    elif of_max:
        half = np.full_like(y, abs(of_max) * float(np.nanmax(np.abs(y))))
    else:
        half = None
    if half is not None:
        lower, upper = y - half, y + half
    x, y2, lower, upper = _clip(spec, x, y, lower, upper)
    return TargetOverlay(column, x, y2, lower, upper, label)


def _clip(spec: Mapping[str, Any], x: np.ndarray, *arrays: np.ndarray | None) -> tuple:
    """``x`` and ``arrays`` restricted to ``spec["band_x"]`` (a constant target is drawn from
    the band's start to its end)."""
    band = spec.get("band_x")
    if band is None or len(band) != 2:
        return (x, *arrays)
    b0, b1 = sorted(float(v) for v in band)
    if x.size == 2 and all(a is None or np.ptp(a) == 0 for a in arrays):
        return (np.array([b0, b1]), *arrays)  # a constant: from the band's start to its end
    keep = (x >= b0 - 1e-12) & (x <= b1 + 1e-12)
    return (x[keep], *(None if a is None else a[keep] for a in arrays))
