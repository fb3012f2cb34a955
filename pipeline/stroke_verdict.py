"""The verdict row of a solve that did not reach the end of its stroke (#22 class, session 26).

Every figure a verdict judges over a response (a peak stress, a force band, a stop's force) is
taken over the rows the solve reached: NaN rows (not converged) are left out. A design whose
solve stops converging part-way through its stroke was therefore judged on the part of the
stroke it reached, and could be MET on it: parallel-guide-landing with its load case cut after
row 8 of 20 (4 of 10 N) read MET 7 of 7, its peak stress 6.73 MPa against the 9.96 MPa of the
whole stroke (tests/pipeline/test_stroke_verdict.py). The only trace was ``converged: false`` in
evaluation.json, a warning on stderr and, in the mechanism kind, numpy's "All-NaN slice" warning
from the rows the solver did not reach (fea/mechanism_design.py).

:func:`with_stroke_row` adds the row "solved through the stroke" to such a result's verdicts:
NOT MET, with the solver's message, so the overall verdict is NOT MET. A result that converged
(every shipped example does) is judged exactly as before.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

from flexopt.optimise.requirements import Flag, Verdict

__all__ = [
    "STROKE_ROW",
    "UNBOUNDED_LIFE",
    "UNBOUNDED_STRESS",
    "with_life_reason",
    "with_stroke_row",
]

#: the row's name
STROKE_ROW = "solved through the stroke"

#: the summary flag of a design whose part as exported has a stress no figure of its kind bounds
#: (a sharp corner: a flexure pivot's leaf roots, pipeline/studies/_pivot_roots.py): its peak
#: stress row is NOT MET and its fatigue life is not computed (pipeline.verdict.life_of_result)
UNBOUNDED_STRESS = "unbounded_stress"

#: why such a design has no fatigue life: a part's life is that of its most stressed point
UNBOUNDED_LIFE = (
    "the part as exported has a stress the model does not bound (a sharp corner: see the "
    "peak-stress row), so no life is computed"
)


def with_stroke_row(verdicts: Sequence[Verdict], result: Any) -> tuple[Verdict, ...]:
    """``verdicts`` with the NOT MET row :data:`STROKE_ROW` appended when ``result`` (a
    :class:`~optimise.problem.DesignResult`) says its solve did not converge
    (``result.converged is False``); unchanged otherwise (also for an object without the
    attribute, e.g. a design's detail)."""
    if getattr(result, "converged", True) is not False:
        return tuple(verdicts)
    message = getattr(result, "message", "") or "no message"
    row = Flag("converged", STROKE_ROW, "check", True).check({"converged": False})
    detail = (
        f"the solve did not converge ({message}); every other row is judged on the rows it "
        "reached only, not on the whole stroke"
    )
    return (*verdicts, replace(row, detail=detail))


def with_life_reason(
    verdicts: Sequence[Verdict], result: Any, life_quantities: Sequence[str]
) -> tuple[Verdict, ...]:
    """``verdicts`` whose life rows (quantity in ``life_quantities``) that have no value say why
    the life was not computed: ``result.summary["fatigue_note"]`` (pipeline.verdict.with_life's
    reason, e.g. a pivot leaf's sharp roots); unchanged without a note."""
    note = (getattr(result, "summary", None) or {}).get("fatigue_note")
    if not isinstance(note, str) or not note:
        return tuple(verdicts)
    return tuple(
        replace(v, detail=f"life not computed: {note}")
        if v.quantity in life_quantities and not v.met and math.isnan(v.value)
        else v
        for v in verdicts
    )
