"""Every load case of a response, the same way everywhere it is shown.

A kind with several load cases (a mechanism's free and blocked jaw) gives each case's table, plot
spec and the user's outputs (:class:`optimise.problem.CaseResponse`, in
``DesignResult.cases``, of a run's design and of ``flexopt evaluate`` alike); a kind with one
gives only ``table`` and ``plot``. :func:`case_responses` makes both one mapping of case name to
response, so the plots, report.md, report.html, the console and :class:`flexopt.Result` show
every case and every output from the same data. :func:`stress_allowable` is the allowable the
verdict judges a case's stress against (a stress line drawn at the yield when the verdict uses
yield / 1.5 would mislead).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from flexopt.optimise.problem import CaseResponse
from flexopt.optimise.requirements import Verdict
from flexopt.pipeline import labels
from flexopt.pipeline.plot_targets import plot_spec

__all__ = [
    "LOAD_CASE",
    "case_responses",
    "case_rows",
    "output_units",
    "stacked_table",
    "stress_allowable",
]

#: The column of :func:`stacked_table` that names each row's load case.
LOAD_CASE = "load_case"


def case_responses(
    table: Mapping[str, Any] | None,
    plot: Mapping[str, Any] | None,
    cases: Mapping[str, CaseResponse] | None = None,
) -> dict[str, CaseResponse]:
    """Every load case of a response by name: ``cases`` when the kind gives them, else the one
    response as a case named ``""`` (nothing when there is no table)."""
    if cases:
        return dict(cases)
    if not table:
        return {}
    return {"": CaseResponse(dict(table), dict(plot or {}), ())}


def stacked_table(cases: Mapping[str, CaseResponse]) -> dict[str, np.ndarray]:
    """One table of every case's rows, case after case, with a :data:`LOAD_CASE` column first.

    A column some cases do not have (a case's own output, the drive in N of a force-driven case
    beside one in mm) is NaN in their rows (``None`` for a column of booleans or text).

    Returns
    -------
    dict of str to (sum of n_rows,) array
    """
    names: list[str] = []
    for case in cases.values():
        names += [n for n in case.table if n not in names]
    sizes = [len(next(iter(c.table.values()))) if c.table else 0 for c in cases.values()]
    out: dict[str, np.ndarray] = {
        LOAD_CASE: np.array([n for n, k in zip(cases, sizes, strict=True) for _ in range(k)])
    }
    for name in names:
        parts = []
        for case in cases.values():
            column = case.table.get(name)
            parts.append(np.asarray(column) if column is not None else None)
        kinds = {p.dtype.kind for p in parts if p is not None}
        if all(p is not None for p in parts) and (len(kinds) == 1 or kinds <= {"f", "i", "u"}):
            out[name] = np.concatenate(parts)  # (whole numbers stay whole: the step)
        elif kinds <= {"f", "i", "u"}:
            filled = [p.astype(float) if p is not None else np.full(k, np.nan) for p, k in
                      zip(parts, sizes, strict=True)]  # fmt: skip
            out[name] = np.concatenate(filled) if filled else np.zeros(0)
        else:
            filled = [p.astype(object) if p is not None else np.full(k, None, dtype=object)
                      for p, k in zip(parts, sizes, strict=True)]  # fmt: skip
            out[name] = np.concatenate(filled)
    return out


def output_units(cases: Mapping[str, CaseResponse]) -> dict[str, list[str]]:
    """The user's outputs of every case grouped by unit (``N``, ``mm``, ``""`` for a ratio), in
    the order they first appear: one axis per unit."""
    groups: dict[str, list[str]] = {}
    for case in cases.values():
        for name in case.outputs:
            unit = labels.unit_of(name) or ""
            if name not in groups.setdefault(unit, []):
                groups[unit].append(name)
    return groups


_BOUND_MPA = re.compile(r"^<=\s*([-+0-9.eE]+)\s*MPa")


def stress_allowable(
    verdicts: Sequence[Verdict], case: str = "", fallback_MPa: float | None = None
) -> tuple[float, str] | None:
    """The allowable stress the verdict judges ``case``'s peak stress against, with its label.

    The verdicts of stress requirements (unit MPa, ``stress`` in the quantity, an upper bound)
    of this case (``case.`` quantities) or of the whole design (no case prefix); the smallest
    bound when there are several, labelled with the requirement's bound text (``allowable 32 MPa
    (yield 48 MPa / SF 1.5)``). Without one: ``fallback_MPa`` (the kind's plot line), labelled
    as a limit no requirement judges.

    Returns
    -------
    (float, str) or None
        MPa and the legend text.
    """
    found: list[tuple[float, str]] = []
    for v in verdicts:
        prefix, _, quantity = v.quantity.rpartition(".")
        if v.unit != "MPa" or "stress" not in quantity or (prefix and prefix != case):
            continue
        match = _BOUND_MPA.match(v.bound or "")
        if match is None:
            continue
        value = float(match.group(1))
        if math.isfinite(value):
            found.append((value, f"allowable {v.bound.removeprefix('<=').strip()}"))
    if found:
        return min(found)
    if fallback_MPa is not None and math.isfinite(float(fallback_MPa)):
        return float(fallback_MPa), f"limit {float(fallback_MPa):g} MPa (no requirement judges it)"
    return None


def case_rows(case: CaseResponse) -> list[tuple[str, str, str, float, float, float, float]]:
    """One row per column worth reading of a load case: the drive, its reaction, the peak
    stress and every output of the case, as ``(column, "response" or "output", unit, start,
    end, smallest, largest)`` over the converged rows (NaN where a column has no value)."""
    table, spec = case.table, plot_spec(case.plot)
    ok = np.asarray(table.get("converged", []), dtype=bool)
    columns = [spec["x"], spec["y"], spec["stress"]]
    columns += [c for c in case.outputs if c not in columns]
    rows = []
    for column in columns:
        if column is None or column not in table:
            continue
        values = np.asarray(table[column], dtype=float)
        if ok.size == values.size:
            values = values[ok]
        finite = values[np.isfinite(values)]
        what = "output" if column in case.outputs else "response"
        unit = labels.unit_of(column) or "–"
        if finite.size == 0:
            rows.append((column, what, unit, math.nan, math.nan, math.nan, math.nan))
        else:
            rows.append((column, what, unit, float(finite[0]), float(finite[-1]),
                         float(finite.min()), float(finite.max())))  # fmt: skip
    return rows
