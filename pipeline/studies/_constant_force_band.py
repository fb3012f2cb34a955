"""The force band as a constraint row of the ``constant_force`` kind (issue 27): with objective
``rms_error`` and ``optimiser.method: hybrid`` the optimiser holds the beam's force within
:data:`~optimise.curve_objectives.BAND_SHARE` of the band at every row the verdict judges (from
the first row, 0.5 mm on the paper's study, to the end of the drive), which Eq. 8's samples (3,
6, ..., 30 mm) do not see; a design whose RMS error is above 0.008 N only keeps its worst row
within 3 x it (BAND_REACH). The GA alone (the default) has no such row: its problem is main's.
The arithmetic is :func:`optimise.curve_objectives.force_band_ratio`; docs/constant_force.md,
"The band as a constraint", says why and what it changed.
"""

from __future__ import annotations

from typing import Any

from flexopt.optimise.curve_objectives import BAND_ROW, force_band_ratio

__all__ = ["band_names", "band_rows"]


def band_names(study: Any) -> list[str]:
    """The band's constraint row names for ``study`` (a ConstantForceStudy): ``[BAND_ROW]``
    with objective ``rms_error`` (the verdict's band requirement exists only then) and
    ``optimiser.method: hybrid``, else [].

    Only the hybrid: its gradient stage exploits what Eq. 8's samples miss, which the row closes;
    the GA alone (the default) keeps main's problem, so its runs, every ``flexopt evaluate`` of a
    study without ``method: hybrid`` and their goldens are unchanged (no ``force_band_excess``).
    """
    optimiser = getattr(study, "optimiser", None)
    hybrid = getattr(optimiser, "method", None) == "hybrid"
    return [BAND_ROW] if study.objective == "rms_error" and hybrid else []


def band_rows(study: Any, response: Any, rms_error_N: float) -> list[float]:
    """The band's constraint values (``g <= 0``, fractions of the target force) of a traced
    ``response`` (a :class:`fea.beam.BeamResponse`: ``displacement_mm``, ``force_N`` (rows,),
    mm and N) whose RMS error (Eq. 8) is ``rms_error_N`` (N), in the order of
    :func:`band_names`."""
    if not band_names(study):
        return []
    t, b = study.target, study.boundary
    first_mm = b.stroke_mm / b.rows  # the verdict's: row 0 is the unloaded state
    return [
        force_band_ratio(
            response.displacement_mm,
            response.force_N,
            t.force_N,
            t.tolerance_percent / 100.0,
            first_mm,
            rms_error_N=rms_error_N,
        )
    ]
