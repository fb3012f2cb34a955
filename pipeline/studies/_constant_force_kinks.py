"""The constant-force part's plane-stress check at blended kinks, with its peak re-solved on a
locally refined mesh (docs/constant_force.md, "The plane-stress peak under refinement").

Why: where the taper changes (a design vertex) the mitred outline has a kink, re-entrant on the
side where it turns inward. Its stress is singular in elasticity (weakly: ~ r^(-2 kink / pi)),
so the plane-stress peak there never converges: on the shipped design it rose 0.26 / 0.39 /
0.33 MPa per halving of the edge within 1 mm of the kink (41.31 -> 42.30 MPa from 0.5 to
0.0625 mm), the verdict reading the 0.5 mm figure. The part as exported now blends each kink
(:data:`KINK_BLEND_MM`, :func:`geometry.constant_force.outline`'s ``blend_mm``), whose peak
converges (40.99 / 41.00 / 41.01 / 41.02 MPa on the same meshes), and the check re-solves the row
of its peak with the mesh refined :data:`REFINE_FACTOR` x within :data:`REFINE_RADIUS_MM` of
the peak: the verdict judges the larger of the two figures (``plane_stress_refined_peak_MPa``),
so a design whose peak is not yet converged at the study's mesh is not judged on the lower one.
The beam keeps the mitred thickness: at a blended vertex the part is thicker by at most
``blend x kink / 4`` per side (2.6 um at the shipped design's peak vertex), so the beam's
figure there over-reads the part's (on the safe side).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from flexopt.fea.fidelity import plane_stress_check
from flexopt.geometry.constant_force import WORK_DIRECTION
from flexopt.pipeline.studies._constant_force_clamp import REFINED_PEAK
from flexopt.pipeline.studies._constant_force_fillet import KINK_BLEND_MM
from flexopt.pipeline.studies._constant_force_reuse import (  # the kind's checks, kept
    CheckMemo,
    adopt_check,
)
from flexopt.pipeline.studies._constant_force_split import (
    CHECK_PART,
    CHECK_PARTS,
    merge_records,
    part_rows,
)
from shapely.geometry import Point

__all__ = [
    "CHECK_PARTS",
    "KINK_BLEND_MM",
    "CheckMemo",
    "adopt_check",
    "REFINED_PEAK",
    "REFINE_FACTOR",
    "REFINE_RADIUS_MM",
    "refined_check",
]

#: the local refinement of the re-solve: the study's max edge / this within the radius below
REFINE_FACTOR = 4.0

#: mm: the radius around the 0.5 mm mesh's peak refined (two of the shipped design's beam
#: thicknesses: the stress field of a kink decays over about one thickness)
REFINE_RADIUS_MM = 1.0


def refined_check(
    problem: Any,
    design: Any,
    beam: Any,
    shape: Any,
    response: Any,
    rows: np.ndarray,
    hi: float,
) -> dict[str, Any]:
    """:func:`fea.fidelity.plane_stress_check` of the study's outline ``shape`` (a shapely
    Polygon, mm) and its beam model ``beam`` at ``rows`` (k,) of ``response`` (strokes up to
    ``hi`` mm), and, when every row converged, the row of the largest peak re-solved with the
    mesh refined within :data:`REFINE_RADIUS_MM` of where that peak sits.

    Adds ``plane_stress_refined_peak_MPa`` (MPa) and ``refined``: ``stroke_mm``, ``at_mm``
    (2,) mm, ``radius_mm``, ``max_edge_mm``, ``coarse_peak_MPa`` (the study mesh's figure at
    that row), ``peak_MPa`` and ``triangles``; or ``skipped`` with the reason when the re-solve
    was not made or did not converge (then the verdict has the study mesh's figure only)."""
    g = problem.study.geometry
    edge = problem.study.fidelity.max_edge_mm
    args = (beam, shape, problem.material, design.B, g.pad_length_mm, g.pad_thickness_mm)
    mode = CHECK_PART.get()  # the whole check, one part of it, or its parts to merge
    if isinstance(mode, int):  # one part, in a pool's worker (._constant_force_split)
        mine = part_rows(response, rows, mode)
        if not len(mine):
            return {"rows": []}
        result = plane_stress_check(*args, WORK_DIRECTION, response, mine, hi, edge)
        if mode == 1 and "skipped" not in result:
            result = _refine_peak(args, edge, response, mine, hi, result)
        return {"rows": [int(r) for r in mine], **result}
    if isinstance(mode, tuple):  # the parts' records, in the run's process
        merged = _merged(args, edge, response, rows, hi, *mode)
        if merged is not None:
            return merged
    result = plane_stress_check(*args, WORK_DIRECTION, response, rows, hi, edge)
    if "skipped" in result:
        return result
    return _refine_peak(args, edge, response, rows, hi, result)


def _merged(
    args: tuple[Any, ...],
    edge: float,
    response: Any,
    rows: np.ndarray,
    hi: float,
    first: dict[str, Any] | None,
    second: dict[str, Any] | None,
) -> dict[str, Any] | None:
    """The whole check's record from its two parts' records (part 0's ``first``, part 1's
    ``second``: :mod:`._constant_force_split`); None when they are not the parts of this check
    (other rows, a part missing: the caller then makes the whole check)."""
    if second is None or first is None:
        return None
    mine = [int(r) for r in part_rows(response, rows, 1)]
    others = [int(r) for r in part_rows(response, rows, 0)]
    if second.get("rows") != mine or first.get("rows") != others:
        return None
    if "skipped" in second:  # the same mesh failed in both (the whole check's reason)
        return {k: v for k, v in second.items() if k != "rows"}
    if "skipped" in first:
        return {k: v for k, v in first.items() if k != "rows"}
    result = merge_records(first if others else None, second, rows)
    if not all(result["converged"]):
        result["refined"] = {"skipped": "a checked stroke did not converge"}
        return result
    j = int(np.argmax(result["plane_stress_peak_nodal_von_mises_MPa"]))
    if int(np.asarray(rows)[j]) != mine[0]:  # the peak is elsewhere: its re-solve here
        return _refine_peak(args, edge, response, rows, hi, result)
    if REFINED_PEAK in second:  # part 1 re-solved the peak's row (keys in the whole's order)
        result[REFINED_PEAK] = second[REFINED_PEAK]
    result["refined"] = second["refined"]
    return result


def _refine_peak(
    args: tuple[Any, ...],
    edge: float,
    response: Any,
    rows: np.ndarray,
    hi: float,
    result: dict[str, Any],
) -> dict[str, Any]:
    """``result`` (plane_stress_check's record of ``rows``) with the row of its largest peak
    re-solved on the mesh refined around that peak (see :func:`refined_check`)."""
    peaks = result["plane_stress_peak_nodal_von_mises_MPa"]
    if not all(result["converged"]):
        result["refined"] = {"skipped": "a checked stroke did not converge"}
        return result
    j = int(np.argmax(peaks))
    field = result["field"]
    xy = np.asarray(field["points_mm"], dtype=float)
    counted = np.asarray(field["stress_counted"], dtype=bool)
    vm = np.asarray(field["steps"][j]["von_mises_MPa"], dtype=float)
    k = int(np.flatnonzero(counted)[np.argmax(vm[counted])])
    fine = edge / REFINE_FACTOR
    disc = Point(xy[k]).buffer(REFINE_RADIUS_MM)
    # eigenvalue=False: the re-solve is read for its peak and convergence only (its stability
    # was never read: the coarse row's eigenvalue is the check's), ~20 ms less a check
    again = plane_stress_check(
        *args,
        WORK_DIRECTION,
        response,
        np.asarray(rows)[[j]],
        hi,
        edge,
        [(disc, fine)],
        eigenvalue=False,
    )
    info: dict[str, Any] = {
        "stroke_mm": result["stroke_mm"][j],
        "at_mm": xy[k].tolist(),
        "radius_mm": REFINE_RADIUS_MM,
        "max_edge_mm": fine,
        "coarse_peak_MPa": float(peaks[j]),
    }
    if "skipped" in again or not all(again["converged"]):
        info["skipped"] = again.get("skipped", "the refined re-solve did not converge")
    else:
        info["peak_MPa"] = float(again["plane_stress_peak_nodal_von_mises_MPa"][0])
        info["triangles"] = again["mesh"]["triangles"]
        result[REFINED_PEAK] = info["peak_MPa"]
    result["refined"] = info
    return result
