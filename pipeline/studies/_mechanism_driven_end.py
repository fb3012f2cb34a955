"""The verdict row of a mechanism whose drive holds a bare beam end's rotation (#27, session 27).

A load case that drives a beam end (``drive: {part: beam.end, ...}``) with its rotation held
(``rotation: held``, or ``control: rotation`` / ``moment``) clamps that end ideally in the
model: the section stays square to the drive, the stress there is the beam's nominal
N/A + M c/I (Kt 1). The part as made is held by something there (a slider, a pad, a gripper's
jaw), and where the beam meets it is a corner: a sharp one has a stress no figure of the
study bounds, a filleted one the shoulder's Kt (x1.3-2 for the constant-force beam's pads,
docs/constant_force.md "Fillets at the pads"). A grounded end or one attached to a body gets
its pad's or body's fillets and Kt (geometry/mechanism.py ``as_made_beams``); a driven bare
end got neither, and its peak-stress row could be MET on Kt 1 (constant-force-mechanism: its
beam's end S6 is driven 30 mm with the rotation held; the constant_force kind models the same
end as a pad with fillets and judges their Kt).

Decision: such a load case adds the row "driven end held as made" NOT MET with the reason (the
overall verdict NOT MET); the way out is to model what holds the end (attach the end to a
body and drive the body: its fillets and Kt are judged), or to drive it with the rotation free
where the part as made lets it turn (a pin). The row is a check: the optimiser does not hold
it, so a run finds the same design.
"""

from __future__ import annotations

from typing import Any

from flexopt.optimise.requirements import Verdict

__all__ = ["DRIVEN_END", "driven_end_verdicts"]

#: the row's name (the load case's name is added when the study has more than one)
DRIVEN_END = "driven end held as made"


def _held_bare_end(study: Any, part: str) -> bool:
    """``part`` is a beam end (``beam.start`` / ``beam.end``) joined to no body and no ground."""
    beam, _, end = part.partition(".")
    if end not in ("start", "end") or beam not in study.geometry.beams:
        return False
    for joint in study.geometry.joints:
        if part in (joint.a, joint.b):
            other = joint.b if joint.a == part else joint.a
            if other == "ground" or other in study.geometry.bodies:
                return False  # its pad's or body's fillets and Kt are judged
    return True


def driven_end_verdicts(study: Any) -> tuple[Verdict, ...]:
    """One NOT MET row per load case whose drive holds a bare beam end's rotation."""
    cases = dict(study.load_cases)
    rows = []
    for name, case in cases.items():
        d = case.drive
        holds = d.control in ("rotation", "moment") or d.rotation == "held"
        if not (holds and _held_bare_end(study, d.part)):
            continue
        why = (
            f"load_cases.{name}.drive holds the rotation of the bare beam end {d.part}: the "
            "model clamps it ideally (Kt 1), but the part as made is held there by something "
            "and has a corner whose stress concentration no figure of the study bounds; attach "
            "the end to a body and drive the body (its fillets and Kt are judged, "
            "docs/mechanism.md), or drive it with rotation: free"
        )
        label = DRIVEN_END if len(cases) == 1 else f"{DRIVEN_END} ({name})"
        rows.append(Verdict(label, "driven_end_as_made", 0.0, "= yes", -1.0, None, False, "",
                            "check", why))  # fmt: skip
    return tuple(rows)
