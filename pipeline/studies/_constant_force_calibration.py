"""The constant-force study's constraint check for the hybrid optimiser (issue 27):
:meth:`ConstantForceProblem.check_constraints`, the verdict's own peak-stress figure at a design.

The verdict judges the peak stress on ``checked_peak_stress_MPa`` (:mod:`._constant_force_clamp`):
the larger of the plane-stress check of the part as exported (blended kinks, pad fillets, its
peak's row re-solved on a locally refined mesh) and the beam's nominal stress. The optimiser's
row ``stress_ratio_minus_1`` holds the beam's peak x ``fidelity.beam_stress_factor``; near a
taper kink the plane-stress peak reads up to ~4 % over the beam's, more than the factor, so a
design held at the row's bound can be NOT MET. This check runs exactly what the verdict runs
(:func:`constant_force.fidelity_check` over the rows :func:`compared_over` picks, then
:func:`checked_peak_figures`) and returns the factor ``k = checked / (beam peak x factor)`` by
which the row under-reads the verdict at this design; the hybrid's gradient stage then holds
``k (g + 1) - 1 <= 0`` (:func:`optimise.hybrid.run_hybrid`). A deterministic function of the
design (the same mesh, the same Newton solves), so a resumed run makes the same checks.

Only the stress row is calibrated: the force band's plane-stress figures differ from the beam's
by 0.08-0.22 % of the force on this study's designs, within the share of the band the band row
leaves free (:data:`optimise.curve_objectives.BAND_SHARE`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from flexopt.optimise.curve_objectives import compared_over
from flexopt.optimise.hybrid import ConstraintCheck
from flexopt.pipeline.studies import _constant_force_solved
from flexopt.pipeline.studies._constant_force_clamp import CHECKED_PEAK, checked_peak_figures
from flexopt.pipeline.studies._constant_force_split import CHECK_PART, CHECK_PARTS, CheckPart

__all__ = ["CHECK_PARTS", "check_constraints"]

#: the constraint row calibrated: ``stress_ratio_minus_1`` is the problem's first
STRESS_ROW = 0


def check_constraints(
    problem: Any,
    x: np.ndarray,
    solve: Callable[[np.ndarray], tuple[Any, Any, str]],
    metrics: Callable[[Any, Any], Any],
    fidelity: Callable[..., dict[str, Any]],
    part: Any = None,
) -> ConstraintCheck | CheckPart | None:
    """The verdict's peak-stress figure at the design ``x`` (23,) and the stress row's factor
    (:class:`optimise.hybrid.ConstraintCheck`: ``factors`` {0: k}, ``met``: the checked peak
    within the allowable; ``info``: ``checked_peak_stress_MPa``, ``beam_row_stress_MPa`` (the
    beam's peak x beam_stress_factor, the row's figure), ``allowable_MPa``); None when the
    objective is not ``rms_error``, the fidelity check is off or skipped, or the design does not
    solve (the verdict then judges as it does). ``kept``: the problem's kept records of ``x``
    (its ``checks``, a CheckMemo), for the run's process when this ran in a worker.

    ``part`` (:mod:`._constant_force_split`): 0 or 1, that part of the check only, as a
    :class:`~._constant_force_split.CheckPart` (None where the whole check would be None); a
    sequence of the two parts' answers (CheckPart or None, in part order): the whole check
    from them, as without ``part`` (any part missing or not of this design: the whole check
    is made here)."""
    # solve (x -> design, response, reason) and metrics (design, response -> CurveMetrics) are
    # the problem's own, fidelity (design, response, lo, hi -> record) the verdict's guarded
    # fidelity check: passed in by ConstantForceProblem.check_constraints, so that this module
    # does not import the kind (an import cycle)
    t0 = time.perf_counter()
    study = problem.study
    if study.objective != "rms_error" or not study.fidelity.enabled:
        return None
    x = np.asarray(x, dtype=float)
    # The beam's path at x, as the problem's solve makes it: the one this process kept when it
    # evaluated x (_constant_force_solved: the design a check is asked at was evaluated just
    # before, often in the same worker; the same objects solve(x) would build, as the exact
    # Jacobian reuses them), else solved here (~30 ms CPU a part, session 32).
    kept = _constant_force_solved.kept(problem, x)
    if kept is not None:
        design, _, response = kept
        reason = ""
    else:
        design, response, reason = solve(x)
    if reason or design is None or response is None:
        return None
    m = metrics(design, response)
    lo, hi = compared_over(m, study.boundary.stroke_mm)
    if isinstance(part, int):  # one part, in a pool's worker: its record goes back as it is
        token = CHECK_PART.set(part)
        try:
            record = fidelity(design, response, lo, hi)
        finally:
            CHECK_PART.reset(token)
        rows = tuple(int(r) for r in record.get("rows", ()))
        return CheckPart(part, rows, record, time.perf_counter() - t0)
    merge = None
    if part is not None:  # the parts' records (None where a part did not answer)
        merge = tuple(getattr(p, "record", None) for p in part)
    token = CHECK_PART.set(merge)
    try:
        check = fidelity(design, response, lo, hi)  # the verdict's
    finally:
        CHECK_PART.reset(token)
    figures = checked_peak_figures(check, response.peak_stress_MPa)
    checked = figures.get(CHECKED_PEAK)
    if checked is None or not np.isfinite(checked):
        return None
    row = float(m.peak_stress_MPa) * study.fidelity.beam_stress_factor  # the row's own figure
    if not row > 0.0:
        return None
    allowable = float(problem.allowable_MPa)
    found = ConstraintCheck(
        factors={STRESS_ROW: float(checked) / row},
        met=bool(checked <= allowable),
        info={
            CHECKED_PEAK: float(checked),
            "beam_row_stress_MPa": row,
            "allowable_MPa": allowable,
        },
        time_s=time.perf_counter() - t0,
    )
    # the check's records ride along (ConstraintCheck.kept): where it ran in a pool's worker,
    # the run's process adopts them (the problem's adopt_check) and the report serves them
    memo = getattr(problem, "checks", None)
    if memo is None or part is not None:  # merged here: the record is in this process's memo
        return found
    return memo.attach(x, found)
