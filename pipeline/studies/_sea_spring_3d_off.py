"""The verdict row of a SEA spring study whose 3D check is off (#27, session 27).

A spiral SEA spring's plate is stiffer as a 3D solid than plane stress says: the shipped
spring at ST = 19.19 mm is x1.0216 stiffer in 3D (docs/solid3d.md, "The correction: designs
that meet the requirement in 3D", check 1), which moves its clockwise stiffness from 280.34
N·m/rad (plane stress, +1.94 %) to 286.39 N·m/rad (+4.14 %), outside the ±2 % band of 275
N·m/rad. The 3D check (``solid_3d: {check: true}``, the default) sees that, corrects ST for it
and judges each direction's 3D stiffness; a study that switches it off (``sea-spring-quick``,
a smoke run) has only the plane-stress rows, and those were MET on a part whose stiffness as
made is not.

Decision: such a study keeps its plane-stress rows (they judge the plane-stress design at its
own ST) and gets one more row, "checked in 3D", NOT MET with the reason, so its overall verdict
is NOT MET. A refusal would forbid the smoke run the example exists for; a correction by a
fixed factor would be a figure the run did not compute (the ratio depends on the design: 1.0205
to 1.0222 in docs/solid3d.md). The row is a check: the optimiser does not hold it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from flexopt.optimise.requirements import Requirement, Verdict

__all__ = ["NOT_CHECKED_3D", "THRESHOLD_REASON", "Unchecked3D"]

#: the row's name
NOT_CHECKED_3D = "checked in 3D"

#: why it is NOT MET
REASON = (
    "3D check off (solid_3d.check: false): the plate's 3D stiffening (x1.02 for the shipped "
    "spiral, docs/solid3d.md) is not seen, so the stiffness and peak-stress rows judge plane "
    "stress only, not the part as made; set solid_3d: {check: true} to judge it"
)


#: why a threshold spring with its 3D check off is NOT MET (the same hole: its plate's curve as
#: made is the plane-stress curve times the 3D/2D stiffness ratio, docs/threshold_torque.md)
THRESHOLD_REASON = (
    "3D check off (solid_3d.check: false, or fidelity off): the plate's 3D stiffening is not "
    "seen, so the curve-error and peak-stress rows judge plane stress (or the beam) only, not "
    "the part as made; set solid_3d: {check: true} and fidelity: {enabled: true} to judge it"
)


@dataclass(frozen=True)
class Unchecked3D(Requirement):
    """NOT MET whatever the design: the part as made was not judged in 3D (see the module
    docstring). Value 0 (no), margin -1, as a :class:`~optimise.requirements.Flag` not met."""

    quantity: str = "checked_3d"
    name: str = NOT_CHECKED_3D
    reason: str = REASON

    def check(self, metrics: Any, curves: Any = None) -> Verdict:  # noqa: ARG002 - the API's
        return Verdict(
            self.label, self.quantity, 0.0, "= yes", -1.0, None, False, "", self.role, self.reason
        )


def unchecked_3d_rows(study: Any) -> list[Requirement]:
    """``[Unchecked3D()]`` for a SEA spring study with a stiffness target and its 3D check off;
    ``[]`` otherwise."""
    s3 = getattr(study, "solid_3d", None)
    if s3 is None or s3.check or study.target.stiffness_Nm_per_rad is None:
        return []
    return [Unchecked3D()]
