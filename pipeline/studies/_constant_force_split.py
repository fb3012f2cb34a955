"""The constant-force calibration's check in two parts, one per pool worker (issue 27 item 3,
session 31): the hybrid's three checks were ~0.8-1.0 s of CPU each, one after the other inside
one call, and held their lockstep round (and so the other start) on one worker while the other
idled: ~2.9 s of the gradient stage's ~6.5 s critical path (docs/benchmarks.md, "Constant-force
checks off the critical path (session 31)").

The check (:func:`constant_force.fidelity_check` -> :func:`._constant_force_kinks.refined_check`)
is a plane-stress solve at each checked row (k rows, each Newton from the beam's shape at that
row: independent of the others) and then the row of the largest peak re-solved on a locally
refined mesh. It splits into:

* part 0: the coarse rows but one (:func:`guess_row`);
* part 1: that row's coarse solve and its refined re-solve, taken before it is known to be the
  peak's row (the guess: the row of the beam's largest peak among the checked rows; the row the
  check refines on every design measured).

:func:`merge_records` puts the rows back in order; where the plane-stress peak is at the
guessed row (every check of the shipped study's run), part 1's refined re-solve is the one the
whole check makes; otherwise the run's process makes the right one
(:func:`._constant_force_kinks.refined_check`). Each row's solve is the same computation on the
same mesh in either process, so the merged record equals the whole check's (its figures to the
bit: tests/pipeline/test_constant_force_split.py), but for ``time_s`` and the tangent's smallest
eigenvalue (ARPACK's random start vector, whose seed moves with the calls a process made: the
15th digit, as between two runs of the whole check).

Which part a call computes, or which parts it merges, is set for the duration of one
:func:`constant_force.fidelity_check` by :data:`CHECK_PART` (a context variable: the kind's
function keeps its signature and the check's code path stays one); a part's record is never
kept in the problem's :class:`._constant_force_reuse.CheckMemo` (it is not the verdict's).
"""

from __future__ import annotations

from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from flexopt.pipeline.studies._constant_force_clamp import REFINED_PEAK

__all__ = ["CHECK_PART", "CHECK_PARTS", "CheckPart", "guess_row", "merge_records", "part_rows"]

#: how many parts the check splits into (the hybrid asks for them on different workers)
CHECK_PARTS = 2

#: None: the whole check; an int: compute that part; a tuple of :class:`CheckPart`: merge them
CHECK_PART: ContextVar[Any] = ContextVar("constant_force_check_part", default=None)

#: keys of a plane-stress check record (fea.fidelity.plane_stress_check) with one entry per row
PER_ROW = (
    "stroke_mm",
    "beam_force_N",
    "plane_stress_force_N",
    "relative_difference",
    "beam_peak_stress_MPa",
    "plane_stress_peak_nodal_von_mises_MPa",
    "beam_transverse_force_N",
    "plane_stress_transverse_force_N",
    "converged",
    "stable",
    "min_tangent_eigenvalue_N_per_mm",
    "newton_iterations",
    "max_shape_change_mm",
)


@dataclass(frozen=True)
class CheckPart:
    """One part of a check (what a worker's ``check_constraints(x, part=p)`` returns).

    Attributes
    ----------
    part : 0 or 1 (see the module's doc).
    rows : the response rows this part solved (its share of the check's rows).
    record : the part's plane-stress record (fea.fidelity.plane_stress_check's keys, its rows
        only; part 1's with ``refined``), or ``{"skipped": reason}``; None when the part had
        no rows.
    time_s : s, wall time of the part where it ran.
    """

    part: int
    rows: tuple[int, ...]
    record: dict[str, Any] | None = field(default=None, repr=False)
    time_s: float = 0.0


def guess_row(response: Any, rows: np.ndarray) -> int:
    """The checked row (one of ``rows`` (k,)) part 1 refines before the check knows where the
    plane-stress peak is: the row of the beam's largest peak stress among them (the first such
    row on a tie)."""
    rows = np.asarray(rows, dtype=int)
    beam = np.asarray(response.peak_stress_MPa, dtype=float)[rows]
    beam = np.where(np.isfinite(beam), beam, -np.inf)
    return int(rows[int(np.argmax(beam))])


def part_rows(response: Any, rows: np.ndarray, part: int) -> np.ndarray:
    """(k_part,) int: the rows of ``rows`` (k,) that ``part`` solves (part 1: the guessed row;
    part 0: the others, in order)."""
    rows = np.asarray(rows, dtype=int)
    guess = guess_row(response, rows)
    return rows[rows == guess] if part == 1 else rows[rows != guess]


def merge_records(
    first: dict[str, Any] | None, second: dict[str, Any], rows: np.ndarray
) -> dict[str, Any]:
    """The plane-stress record of all ``rows`` (k,) from part 0's record ``first`` (its rows;
    None when it had none) and part 1's ``second`` (the guessed row), as
    fea.fidelity.plane_stress_check of all the rows makes it: per-row lists in row order,
    ``max_abs_relative_difference`` and ``within_5_percent`` over them, the mesh (the same in
    both), and the field's steps in row order. ``refined`` is not carried (the caller decides
    whose it is); ``time_s`` is the larger part's."""
    rows = [int(r) for r in np.asarray(rows, dtype=int)]
    parts = [(second, part_rows_of(second))]
    if first is not None:
        parts.append((first, part_rows_of(first)))
    where: dict[int, tuple[dict[str, Any], int]] = {}
    for record, its_rows in parts:
        for i, row in enumerate(its_rows):
            where[row] = (record, i)
    rel = np.asarray([where[row][0]["relative_difference"][where[row][1]] for row in rows])
    out: dict[str, Any] = {}
    for key, value in second.items():  # plane_stress_check's keys, in its order
        if key in PER_ROW:
            out[key] = [where[row][0][key][where[row][1]] for row in rows]
        elif key == "max_abs_relative_difference":
            out[key] = float(np.max(np.abs(rel)))
        elif key == "within_5_percent":
            ok = all(where[row][0]["converged"][where[row][1]] for row in rows)
            out[key] = bool(ok and np.max(np.abs(rel)) <= 0.05)
        elif key == "time_s":
            out[key] = max(float(r.get("time_s", 0.0)) for r, _ in parts)
        elif key == "field":
            steps = [where[row][0]["field"]["steps"][where[row][1]] for row in rows]
            out[key] = {k: v for k, v in value.items() if k != "steps"} | {"steps": steps}
        elif key not in ("rows", "refined", REFINED_PEAK):
            out[key] = value  # the model's name, the mesh: the same in both parts
    return out


def part_rows_of(record: dict[str, Any]) -> list[int]:
    """The response rows a part's record holds (its ``rows``, kept with it by the part)."""
    return [int(r) for r in record["rows"]]
