"""What the optimiser and the verdict read from one ``mechanism`` design: its metrics'
statistics, its objectives, its requirement rows and the built-in no-interference requirement.

The ``mechanism`` study kind (pipeline/studies/mechanism.py) solves a design into one table of
columns per load case (:func:`fea.mechanism_design.case_table`); this module turns them into

* metrics: :data:`STATS` of every output over its case's rows (:func:`statistic`);
* :func:`curves_table` — every case's columns in one table (prefixed ``<case>.`` with more than
  one case), NaN where a row did not converge: what curve requirements read;
* objectives: :func:`objective_values` (minimise / maximise a metric, the RMS error to a
  target or the stroke inside its band, :func:`target_objective`) and their names
  (:func:`objective_name`);
* requirement verdicts (:func:`judge`, :func:`interference_verdict`) and the constraint rows
  ``g <= 0`` the problem adds itself (:func:`curve_constraints`, :func:`constraint_rows`).

Units are those of the quantities (mm, N, N·mm, deg, MPa, mm²).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from flexopt.fea.mechanism_design import INTERFERENCE_MM2, REACTION_UNIT
from flexopt.optimise.evaluation import INFEASIBLE_VALUE
from flexopt.optimise.requirements import Requirement, TargetBand, Verdict, unit_of

__all__ = [
    "STATS",
    "constraint_rows",
    "curve_constraints",
    "curves_table",
    "interference_verdict",
    "judge",
    "objective_name",
    "objective_values",
    "output_statistics",
    "response_metrics",
    "statistic",
    "target_objective",
    "verdict_json",
    "with_stress_factor",
]

#: Statistics of every output over the converged rows of its case (metric ``<stat>_<output>``).
STATS = ("max", "min", "max_abs", "mean", "end", "start", "first_peak")


def statistic(values: np.ndarray, how: str) -> float | None:
    """One of :data:`STATS` of a (rows,) column over its finite values (``end`` / ``start``:
    the last / first row; ``first_peak``: the first local maximum along the drive, a
    snap-through force); None where there is none."""
    v = np.asarray(values, dtype=float)
    finite = v[np.isfinite(v)]
    if how in ("end", "start"):
        x = v[-1] if how == "end" else v[0]
        return float(x) if np.isfinite(x) else None
    if not finite.size:
        return None
    if how == "mean":
        return float(np.mean(finite))
    if how == "first_peak":  # the first local maximum along the drive: a snap-through force
        y = v[np.isfinite(v)]
        for k in range(1, len(y) - 1):
            if y[k] >= y[k - 1] and y[k] > y[k + 1]:
                return float(y[k])
        return None
    return float(
        {"max": np.max, "min": np.min, "max_abs": lambda a: np.max(np.abs(a))}[how](finite)
    )


def output_statistics(
    table: Mapping[str, np.ndarray], outputs: Sequence[str], prefix: str
) -> dict[str, float | None]:
    """``{prefix}{stat}_{output}`` for every output column of ``table`` and every stat."""
    return {f"{prefix}{how}_{name}": statistic(table[name], how) for name in outputs
            for how in STATS}  # fmt: skip


def response_metrics(
    tables: Mapping[str, Mapping[str, np.ndarray]],
    cases: Mapping[str, tuple[str, str, str, Sequence[str]]],
    yield_MPa: float,
    part: Mapping[str, Any],
) -> dict[str, Any]:
    """The metrics of a design's responses.

    ``tables`` are the cases' columns (:func:`fea.mechanism_design.case_table`); ``cases`` maps
    each case to ``(prefix, control, unit, outputs)``: its metrics' prefix, its drive's control
    and unit, its outputs. Per case ``stable_positions`` and ``second_stable_position_<unit>``
    (:func:`fea.mechanism.stable_positions`, under displacement or rotation control; None
    otherwise), ``max_peak_stress_MPa`` (MPa) and :func:`output_statistics`; overall
    ``max_peak_stress_MPa``, ``stress_yield_ratio`` (to ``yield_MPa``), then ``part`` (the
    part's own metrics, e.g. its mass), then ``stable`` (no converged row unstable) and
    ``unstable_rows``."""
    from flexopt.fea.mechanism import stable_positions  # the solver's module: loaded late

    m: dict[str, Any] = {}
    peaks = []
    unstable = 0
    for case, table in tables.items():
        p, control, unit, outputs = cases[case]
        drive = table[f"drive_{unit}"]
        reaction = table[f"drive_reaction_{REACTION_UNIT[control]}"]
        if control in ("displacement", "rotation"):
            count, second = stable_positions(drive, reaction)
        else:
            count, second = None, None
        m[f"{p}stable_positions"] = count
        m[f"{p}second_stable_position_{unit}"] = second
        peak = statistic(table["peak_stress_MPa"], "max")
        m[f"{p}max_peak_stress_MPa"] = peak
        peaks.append(peak if peak is not None else math.nan)
        unstable += int(np.sum(table["converged"] & ~table["stable"]))
        m.update(output_statistics(table, outputs, p))
    peak_all = float(np.nanmax(peaks)) if np.isfinite(peaks).any() else None
    m["max_peak_stress_MPa"] = peak_all
    m["stress_yield_ratio"] = None if peak_all is None else peak_all / yield_MPa
    m.update(part)
    m["stable"] = unstable == 0
    m["unstable_rows"] = unstable
    return m


def curves_table(
    tables: Mapping[str, Mapping[str, np.ndarray]], prefixes: Mapping[str, str]
) -> dict[str, np.ndarray]:
    """Every case's columns (``step``, ``converged``, ``stable`` left out), named
    ``{prefixes[case]}{column}``, NaN where the row did not converge."""
    out = {}
    for case, table in tables.items():
        p = prefixes[case]
        ok = np.asarray(table["converged"], dtype=bool)
        for key, col in table.items():
            if key in ("converged", "stable", "step"):
                continue
            arr = np.asarray(col, dtype=float).copy()
            arr[~ok] = np.nan
            out[f"{p}{key}"] = arr
    return out


def with_stress_factor(
    metrics: Mapping[str, Any], tables: Mapping[str, Mapping[str, np.ndarray]], factor: float
) -> tuple[dict[str, Any], dict[str, dict[str, np.ndarray]]]:
    """Metrics and tables with every peak stress (and stress / yield ratio) times ``factor``:
    the beam model's peak as the optimiser judges it (``fidelity.beam_stress_factor``)."""
    out = dict(metrics)
    for key, value in metrics.items():
        stress = key.endswith("max_peak_stress_MPa") or key.endswith("stress_yield_ratio")
        if stress and isinstance(value, int | float) and value is not None:
            out[key] = float(value) * factor
    scaled = {
        case: {
            k: np.asarray(v, float) * factor if k == "peak_stress_MPa" else v
            for k, v in table.items()
        }
        for case, table in tables.items()
    }
    return out, scaled


# --------------------------------------------------------------------------------------------
# Objectives


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_")


def _unit_suffix(quantity: str) -> str:
    unit = unit_of(quantity)
    return {"N·mm": "Nmm", "N/mm": "N_per_mm", "": "1"}.get(unit, unit)


def objective_name(key: str, name: str, labels: Mapping[str, Requirement]) -> str:
    """The column name of objective ``key: name`` (``minimise`` / ``maximise`` a metric,
    ``target_error`` / ``band_stroke`` of the target requirement labelled ``name``)."""
    if key == "minimise":
        return name
    if key == "maximise":
        return f"negative_{name}"
    req = labels[name]
    if key == "target_error":
        return f"{_slug(name)}_rms_error_{_unit_suffix(req.quantity)}"
    return f"negative_{_slug(name)}_band_stroke_{_unit_suffix(getattr(req, 'x', ''))}"


def target_objective(
    req: TargetBand, x: np.ndarray | None, y: np.ndarray | None, key: str
) -> float:
    """RMS error to the target over its range (unit of the quantity), or minus the longest
    stretch of x inside the band (unit of x); :data:`INFEASIBLE_VALUE` without a response."""
    if x is None or y is None:
        return INFEASIBLE_VALUE
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    if x.size < 2:
        return INFEASIBLE_VALUE
    order = np.argsort(x)
    x, y = x[order], y[order]
    lo, hi = (x[0], x[-1]) if req.over is None else req.over
    if x[0] > lo + 1e-9 or x[-1] < hi - 1e-9:
        return INFEASIBLE_VALUE
    xs = np.linspace(lo, hi, 201)
    ys = np.interp(xs, x, y)
    t = req.target_at(xs)
    if key == "target_error":
        return float(np.sqrt(np.mean((ys - t) ** 2)))
    band = (
        np.full_like(t, float(req.tolerance))
        if req.tolerance is not None
        else float(req.tolerance_rel) * np.abs(t)  # type: ignore[arg-type]
    )
    inside = np.abs(ys - t) <= band
    best = run = 0
    for flag in inside:
        run = run + 1 if flag else 0
        best = max(best, run)
    step = (hi - lo) / (len(xs) - 1)
    rms = float(np.sqrt(np.mean((ys - t) ** 2)))
    # the RMS error orders designs that hold no stretch of the band (a tie-breaker)
    return -max(0.0, (best - 1) * step) + 1e-3 * (hi - lo) * rms / max(float(np.max(band)), 1e-12)


def objective_values(
    objectives: Sequence[tuple[str, str]],
    labels: Mapping[str, Requirement],
    metrics: Mapping[str, Any],
    curves: Mapping[str, np.ndarray],
) -> np.ndarray:
    """(n_obj,) the objectives ``(key, name)`` of a design (all minimised; a maximised metric
    negated; :data:`INFEASIBLE_VALUE` where a metric is missing)."""
    out = []
    for key, name in objectives:
        if key in ("minimise", "maximise"):
            value = metrics.get(name)
            if value is None or not math.isfinite(float(value)):
                out.append(INFEASIBLE_VALUE)
            else:
                out.append(float(value) if key == "minimise" else -float(value))
            continue
        req = labels[name]
        assert isinstance(req, TargetBand)
        out.append(target_objective(req, curves.get(req.x), curves.get(req.quantity), key))
    return np.array(out, dtype=float)


# --------------------------------------------------------------------------------------------
# Requirements


def judge(
    requirements: Sequence[Requirement],
    metrics: Mapping[str, Any],
    curves: Mapping[str, np.ndarray],
) -> tuple[Verdict, ...]:
    """Each requirement's verdict: target bands on their curves, scalars on the metrics, and a
    column that is no metric by its worst value (largest |value|)."""
    pairs = {}
    for r in requirements:
        if isinstance(r, TargetBand):
            x = curves.get(r.x)
            y = curves.get(r.quantity)
            if x is not None and y is not None:
                pairs[r.quantity] = (x, y)
    values = dict(metrics)
    for key, col in curves.items():  # a column judged by its worst value
        if key not in values:
            values[key] = statistic(col, "max_abs")
    return tuple(r.check(values, pairs) for r in requirements)


def interference_verdict(metrics: Mapping[str, Any], clearance: Mapping[str, Any]) -> Verdict:
    """The built-in requirement of every mechanism: no part passes through another at any row
    of any load case (contact is not modelled, so a part that would touch is NOT MET).
    ``clearance`` is :func:`fea.mechanism_design.interference`'s result."""
    area = metrics.get("interference_mm2")
    gap = clearance.get("min_clearance_mm")
    at = clearance.get("clearance_at")
    shown = "" if gap is None else f"; smallest clearance {gap:.3g} mm at {at}"
    met = area is not None and area <= INTERFERENCE_MM2
    detail = (clearance.get("interference_at") or "no interference at any row") + shown
    return Verdict(
        name="no_interference",
        quantity="interference_mm2",
        value=float(area) if area is not None else math.nan,
        bound="0 mm² at every row (contact is not modelled)",
        margin=0.0 - float(area) if area is not None else math.nan,
        margin_rel=None,
        met=bool(met),
        unit="mm²",
        role="constraint",
        detail=detail,
    )


def curve_constraints(requirements: Sequence[Requirement]) -> tuple[Requirement, ...]:
    """The ``role: constraint`` requirements this problem turns into ``g`` rows itself: those
    judged on a response curve (a target band). Scalar ones are added by the pipeline for every
    kind (:func:`pipeline.verdict.with_requirement_constraints`) from the evaluation's metrics,
    which carry every scalar metric of the design (the solved width included)."""
    return tuple(r for r in requirements if r.role == "constraint" and r.needs_curve)


def constraint_rows(
    constraints: Sequence[Requirement], verdicts: Sequence[Verdict], metrics: Mapping[str, Any]
) -> list[float]:
    """``g <= 0`` rows: each curve constraint's margin over its scale (1e6 without one), then
    no interference: the overlap area (mm^2) when parts interfere, else minus the smallest
    clearance (mm), so that the optimiser is drawn away from touching parts."""
    g = []
    for r in constraints:
        v = next(v for v in verdicts if v.name == r.label)
        g.append(-v.margin / r.scale() if math.isfinite(v.margin) else 1.0e6)
    area = metrics.get("interference_mm2")
    gap = metrics.get("min_clearance_mm")
    g.append(1.0e6 if area is None else area if area > INTERFERENCE_MM2 else -(gap or 0.0))
    return g


def verdict_json(v: Verdict) -> dict[str, Any]:
    """A verdict as JSON (non-finite numbers as null)."""

    def num(value: float | None) -> float | None:
        return None if value is None or not math.isfinite(value) else float(value)

    return {
        "name": v.name, "quantity": v.quantity, "value": num(v.value), "bound": v.bound,
        "margin": num(v.margin), "verdict": v.word, "role": v.role, "detail": v.detail,
    }  # fmt: skip
