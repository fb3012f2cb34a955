"""The mechanism kind's beam joints as made (#22, session 28): the rows "beam joint as made
(A | B)" and "pinned joint as made (A)".

Where a beam meets its pad or a body the part as made is filleted and judged with the
shoulder's Kt (geometry/mechanism.py ``as_made_beams``, docs/mechanism.md "The part as made");
a driven bare end held in rotation is NOT MET (_mechanism_driven_end.py). Two joints were left:

* **A clamped joint of two beam ends** (``{a: one.end, b: two.start}``): the solver ties the two
  sections rigidly at a point (Kt 1); the outline draws the two bands and a disc of the joint's
  thickness (geometry/mechanism.py ``mechanism_outline``), so where the beams meet at an angle
  the inner side is a sharp re-entrant corner (the two bands' inner faces crossing), and where
  their thicknesses differ a sharp step. Its stress has no bound in 2D elasticity (measured in
  tests/pipeline/test_mechanism_joints.py on the exported outline of an L-shaped spring: the
  plane-stress peak at the inner corner rises under refinement); no figure of the study bounds
  it (the fidelity check's peak there is its mesh's, a lower bound). Two ends that continue
  each other (the same direction within :data:`TURN_TOL_DEG`, the same thickness within
  :data:`STEP_TOL_MM`) are one strip with no corner: no row.
* **A pinned beam end** (``type: pinned`` to the ground, a body or another beam end): the
  solver lets the section turn freely there (no moment), but the outline prints the joint
  solid (a pad, the body's root, the joint's disc): the part as made carries a moment the
  model sets to zero, so its stiffness and stresses are not the model's.

Decision: each such joint adds a row NOT MET with the reason (the overall verdict NOT MET); the
way out is to join the beams at a body (its fillets and Kt are judged), to draw them as one
beam whose centreline rounds the turn, or to clamp the joint the part has. The rows are checks:
the optimiser does not hold them, so a run finds the same design. A beam's own inner corner
(a turn at one of its points, up to ``max_corner_deg``) has the same sharp inner face and is not
judged by these rows (docs/mechanism.md "What it does not do").
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from flexopt.optimise.requirements import Verdict

__all__ = [
    "BEAM_JOINT",
    "PINNED_JOINT",
    "STEP_TOL_MM",
    "TURN_TOL_DEG",
    "joint_turn",
    "joint_verdicts",
]

#: the rows' names (the joint's parts are added in brackets)
BEAM_JOINT = "beam joint as made"
PINNED_JOINT = "pinned joint as made"

#: two joined ends whose directions differ by less than this continue each other, deg
TURN_TOL_DEG = 1e-6
#: ... and whose thicknesses differ by less than this, mm
STEP_TOL_MM = 1e-9


def _end(beams: Any, ref: str) -> tuple[str, str] | None:
    beam, _, end = ref.partition(".")
    return (beam, end) if end in ("start", "end") and beam in beams else None


def _into(points: np.ndarray, end: str, curvature_per_mm: Any = None) -> np.ndarray:
    """Unit tangent of a beam's centreline ((n, 2) mm; its end segments arcs of the signed
    ``curvature_per_mm`` (n - 1,) 1/mm, positive turning left, when given) arriving at ``end``:
    an arc's tangent is its chord's turned by half the angle it subtends (geometry/profile.py
    ``segment_start_angles_rad``)."""
    last = end == "end"
    d = points[-1] - points[-2] if last else points[1] - points[0]
    angle = math.atan2(d[1], d[0])
    k = 0.0 if curvature_per_mm is None else float(curvature_per_mm[-1 if last else 0])
    if k:
        chord = float(np.hypot(*d))
        half = math.asin(min(1.0, abs(k) * chord / 2))  # half the arc's angle, rad
        angle += math.copysign(half, k) if last else -math.copysign(half, k)
    tangent = np.array([math.cos(angle), math.sin(angle)])
    return tangent if last else -tangent


def joint_turn(beams: Any, a: str, b: str) -> tuple[float, float]:
    """How two joined beam ends ``a`` and ``b`` (``beam.start`` / ``beam.end``) fail to continue
    each other: the turn from ``a``'s direction into the joint to ``b``'s out of it (deg, 0 =
    straight on) and the step between their thicknesses there (mm). ``beams``: name ->
    :class:`~pipeline.studies._mechanism_schema.BeamSpec` (the design's geometry)."""
    (na, ea), (nb, eb) = _end(beams, a), _end(beams, b)  # type: ignore[misc]
    pa, pb = (np.asarray(beams[n].centreline(), dtype=float) for n in (na, nb))
    d_in = _into(pa, ea, beams[na].curvature_per_mm)
    d_out = -_into(pb, eb, beams[nb].curvature_per_mm)
    cross = float(d_in[0] * d_out[1] - d_in[1] * d_out[0])
    turn = math.degrees(math.atan2(abs(cross), float(d_in @ d_out)))
    ta = float(beams[na].thickness()[-1 if ea == "end" else 0])
    tb = float(beams[nb].thickness()[-1 if eb == "end" else 0])
    return turn, abs(ta - tb)


def joint_verdicts(geometry: Any) -> tuple[Verdict, ...]:
    """One NOT MET row per clamped beam-to-beam joint with a corner and per pinned beam end of
    a design's ``geometry`` (a :class:`~pipeline.studies._mechanism_schema.MechanismGeometry`)."""
    beams = geometry.beams
    rows = []
    for i, j in enumerate(geometry.joints):
        ends = [r for r in (j.a, j.b) if _end(beams, r)]
        if j.type == "pinned" and ends:
            why = (
                f"geometry.joints[{i}] pins {' and '.join(ends)}: the model lets the section "
                "turn freely there (no moment), but the exported outline prints the joint solid "
                "(a pad, the body's root or the joint's disc), so the part as made carries a "
                "moment there and its stiffness and stresses are not the model's; clamp the "
                "joint (type: clamped: the part's fillets and Kt are then judged) or model the "
                "pin the part will have"
            )
            label = f"{PINNED_JOINT} ({' | '.join((j.a, j.b))})"
            rows.append(Verdict(label, "pinned_joint_as_made", 0.0, "= no pin", -1.0, None,
                                False, "", "check", why))  # fmt: skip
            continue
        if len(ends) < 2:
            continue
        turn, step = joint_turn(beams, j.a, j.b)
        if turn <= TURN_TOL_DEG and step <= STEP_TOL_MM:
            continue  # one strip through the joint: no corner
        shape = (
            f"they meet turning {turn:.3g} deg" if turn > TURN_TOL_DEG else "they meet in line"
        ) + (f" with a {step:.3g} mm step in thickness" if step > STEP_TOL_MM else "")
        why = (
            f"geometry.joints[{i}] clamps {j.a} to {j.b}; {shape}: the model ties the two "
            "sections rigidly at a point (Kt 1), but the exported outline has a sharp "
            "re-entrant corner there, whose stress no figure of the study bounds; join the "
            "beams at a body (its fillets and Kt are judged, docs/mechanism.md) or draw them "
            "as one beam whose centreline rounds the turn"
        )
        label = f"{BEAM_JOINT} ({j.a} | {j.b})"
        rows.append(Verdict(label, "beam_joint_as_made", 0.0, "= no corner", -1.0, None, False,
                            "", "check", why))  # fmt: skip
    return tuple(rows)
