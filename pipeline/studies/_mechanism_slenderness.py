"""The mechanism kind's row "slender enough for the beam model (BEAM)" per member (#22, s28).

Every beam of a mechanism is solved by the same beam model as a ``polyline_beam``
(fea/beam.py's element, tied by constraints in fea/mechanism.py), so the same bound holds:
its figures are the member's only while its span is several thicknesses longer than its two
end zones (each about one thickness long, where the stress is not M c / I). The bound, its
measurement against plane stress and its reason are pipeline/studies/_polyline_slenderness.py's
(:class:`Slenderness`, ``L/t >= 6``); this module only says what L and t are for a member:

* L: the arc length of the beam as made (``MechanismOutline.beams[name].shape``: clipped where
  it enters a body, its ends flared into the roots' fillets), the flexible length the solver
  bends, from the face of one pad or body to the other's;
* t: the largest thickness of the beam as drawn (``geometry.beams[name]``), not the flares'
  (a fillet's flare is part of the end zone the bound is about).

Each beam is a member of its own (a beam joined to another beam's end is judged on its own
length, which is the stricter reading). The rows are checks: the optimiser does not hold them
(a run finds the same designs); the reported verdict is NOT MET for a member below the bound,
with the member and the reason.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from flexopt.optimise.requirements import Verdict
from flexopt.pipeline.studies._polyline_slenderness import (
    SLENDER_ROW,
    SLENDERNESS,
    Slenderness,
    slenderness_ratio,
)

__all__ = ["member_slenderness", "slenderness_verdicts"]

#: what a mechanism's user can do below the bound
_FIX = (
    "(docs/mechanism.md, 'Slender members'); lengthen the beam or thin it, or model a stubby "
    "block as a body"
)


def member_slenderness(solved: Any) -> dict[str, float]:
    """L/t of each beam of a solved design (a
    :class:`~pipeline.studies._mechanism_result.Solved`): its as-made arc length (mm) over its
    largest drawn thickness (mm); by beam name, in the study's order."""
    out = {}
    for name, made in solved.outline.beams.items():
        p = np.asarray(made.shape.points_mm, dtype=float)
        length = float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))
        out[name] = slenderness_ratio(length, solved.geometry.beams[name].thickness())
    return out


def slenderness_verdicts(solved: Any) -> tuple[Verdict, ...]:
    """One row per beam, "slender enough for the beam model (NAME)", MET at ``L/t >= 6``."""
    rows = []
    for name, ratio in member_slenderness(solved).items():
        row = Slenderness(quantity=SLENDERNESS, name=f"{SLENDER_ROW} ({name})", fix=_FIX)
        rows.append(row.check({SLENDERNESS: ratio}))
    return tuple(rows)
