"""The ``leaf_spring_joint`` kind's rigid stops (issue 25, item 3): the study's ``stops:`` block
(:class:`~pipeline.studies._stops.StopsSpec`, as in ``polyline_beam``, ``mechanism`` and
``flexure_pivot``) given to the constrained-beam engine through
:func:`fea.leaf_joint.sliding_response` (``stops=``: frictionless penalty contact of the leaf
with them inside Newton), and what the kind reports of it.

Frame: the stops are fixed to the ground and given in the joint's frame, the joint centre O at
(0, 0) and the output arm at rest along +x (the leaf's tip B0 at (l_j, 0), the leaf along the x
axis from the movable support O' at (s_mp, 0), s_mp = l_j - l). Every effective length puts
the support, and so the leaf's clamp, elsewhere under the same stops. A leaf deflected by a
positive angle bends towards +y.

Outputs, per curve ``<structure>_l<l>`` of ``flexopt evaluate``: the columns
``<name>_contact_force_N_<curve>`` (N, on one leaf), ``<name>_gap_mm_<curve>`` (mm) and
``<name>_in_contact_<curve>``; the summary's ``<curve>_first_contact_deflection_deg``,
``<curve>_max_contact_force_N``, ... and over every curve (and the design mode's two settings)
``first_contact_deflection_deg``, ``max_contact_force_N``, ``max_penetration_mm``, the
penalty and per stop ``<name>_max_contact_force_N``, ``<name>_first_contact_deflection_deg``,
``<name>_min_gap_mm`` (the Durability section's contact table); the built-in row "contact
penetration within tolerance". The elastic limit and the check deflection are traced with the
stops too.

Refused: stops with the ``fixed`` structure (in ``geometry.structures`` or
``target.structure``: its leaf is traced once and scaled to each loaded length, which a stop
at a fixed place would not follow), a stop overlapping a leaf of the study's joint at one of its
effective lengths (``stops.outlines[i]``). The arm does not touch the stops. A study without
``stops:`` runs exactly as before. The kind is pipeline/studies/leaf_spring_joint.py;
docs/leaf_joint.md and docs/contact.md.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from flexopt.fea.beam import BeamModel, BeamSettings
from flexopt.fea.stops import BeamContact, ContactSettings, RigidStop, overlaps
from flexopt.optimise.requirements import Requirement
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import _builtin
from flexopt.pipeline.studies._pivot_stops import PENETRATION_ROW, contact_figures
from flexopt.pipeline.studies._polyline_slenderness import SLENDERNESS, Slenderness
from flexopt.pipeline.studies._stops import PenetrationWithin
from pydantic import Field

__all__ = [
    "FIELD",
    "check",
    "columns",
    "overlap",
    "quantities",
    "requirements",
    "solve_args",
    "summary",
]

#: the study's ``stops:`` field (pipeline.studies.leaf_spring_joint.LeafSpringJointStudy)
FIELD: Any = Field(
    None,
    description="rigid stops fixed to the ground that the leaf meets (sliding structure; "
    "frictionless penalty contact): {outlines: [{name, points_mm, closed}], penalty_factor}; "
    "in the joint's frame, centre O at (0, 0), arm at rest along +x (docs/leaf_joint.md)",
)
#: the deflection's unit in the names
UNIT = "deflection_deg"


def _stops(study: Any, joint: Any) -> tuple[RigidStop, ...]:
    """The study's stops in ``joint``'s leaf frame (origin the support O', O at centre_mm)."""
    spec = study.stops
    if spec is None:
        return ()
    shift = np.asarray(joint.centre_mm, dtype=float)
    return tuple(
        RigidStop(np.array(o.points_mm, dtype=float) + shift, o.closed, o.name)
        for o in spec.outlines
    )


def solve_args(study: Any, joint: Any) -> dict[str, Any]:
    """The keyword arguments of :func:`fea.leaf_joint.joint_response` for the study's stops at
    ``joint`` (empty without stops: the solve as before)."""
    if study.stops is None:
        return {}
    contact = ContactSettings(penalty_factor=study.stops.penalty_factor)
    return {"stops": _stops(study, joint), "contact": contact}


def check(study: Any, joints: Mapping[int, Any]) -> None:
    """Refuse the stops the kind cannot model (see the module). ``joints``: the study's joint
    at each effective length, by its index in ``geometry.effective_lengths_mm``.

    Raises
    ------
    StudyError
        At ``stops`` (the fixed structure) or ``stops.outlines[i]`` (an overlap).
    """
    if study.stops is None:
        return
    if "fixed" in study.geometry.structures or study.target.structure == "fixed":
        raise StudyError(
            "stops",
            "stops are modelled for the sliding structure only (the fixed structure's leaf is "
            "traced once and scaled to each loaded length, which a fixed stop would not "
            "follow); remove 'fixed' from geometry.structures and target.structure",
        )
    for i, joint in joints.items():
        found = _overlap(study, joint)
        if found is not None:
            raise StudyError(
                f"stops.outlines[{found[0]}]",
                f"{found[1]} at geometry.effective_lengths_mm[{i}] = "
                f"{joint.effective_length_mm:g} mm (the leaf's surface is t/2 from its "
                "centreline); move it clear",
            )


def _overlap(study: Any, joint: Any) -> tuple[int, str] | None:
    stops = _stops(study, joint)
    if not stops:
        return None
    settings = BeamSettings(n_elements=study.geometry.elements)
    model = BeamModel(joint.leaf_profile(), study.material.to_material(), settings=settings)
    for j, depth in overlaps(BeamContact(model, stops)):
        return j, f"stop '{stops[j].name}' overlaps the undeformed leaf by {depth:.4g} mm"
    return None


def overlap(study: Any, joint: Any) -> str:
    """Why ``joint``'s undeformed leaf overlaps a stop ("" when clear or without stops): a
    design mode's joint at its softest setting, which the GA's solve does not trace."""
    found = _overlap(study, joint)
    return "" if found is None else f"{found[1]} at l = {joint.effective_length_mm:.4g} mm"


def columns(study: Any, curve: str, response: Any) -> dict[str, np.ndarray]:
    """The stop columns (each (rows,)) of one curve (:class:`fea.leaf_joint.JointResponse`):
    force on one leaf (N), gap (mm), in contact. Empty without stops."""
    contact = getattr(response, "contact", None)
    if study.stops is None or contact is None:
        return {}
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(contact.names):
        out[f"{name}_contact_force_N_{curve}"] = np.asarray(contact.force_N[:, j], dtype=float)
        out[f"{name}_gap_mm_{curve}"] = np.asarray(contact.gap_mm[:, j], dtype=float)
        out[f"{name}_in_contact_{curve}"] = np.asarray(contact.in_contact[:, j], dtype=bool)
    return out


def summary(study: Any, responses: Mapping[str, Any]) -> dict[str, Any]:
    """The stop figures of the curves ``responses`` (name -> JointResponse): each curve's
    prefixed by its name, and over all of them the first contact (the smallest deflection),
    the largest force and penetration, per stop the largest force, first contact and smallest
    gap. Empty without stops."""
    if study.stops is None:
        return {}
    out: dict[str, Any] = {}
    per = {c: contact_figures(r, UNIT) for c, r in responses.items() if r.contact is not None}
    for curve, figures in per.items():
        out.update({f"{curve}_{k}": v for k, v in figures.items()})

    def pick(key: str, best: Any) -> Any:
        values = [f[key] for f in per.values() if f.get(key) is not None]
        return best(values) if values else None

    first = f"first_contact_{UNIT}"
    out[first] = pick(first, min)
    out["max_contact_force_N"] = pick("max_contact_force_N", max) or 0.0
    out["max_penetration_mm"] = pick("max_penetration_mm", max) or 0.0
    out["contact_penetration_tolerance_mm"] = pick("contact_penetration_tolerance_mm", min)
    out["contact_penetration_ok"] = all(f["contact_penetration_ok"] for f in per.values())
    out["contact_penalty_factor"] = pick("contact_penalty_factor", max)
    out["contact_penalty_raises"] = pick("contact_penalty_raises", max)
    out["contact_rows"] = pick("contact_rows", max)
    out["contact_message"] = "; ".join(
        f"{c}: {f['contact_message']}" for c, f in per.items() if f["contact_message"]
    )
    for stop in study.stops.outlines:
        n = stop.name
        out[f"{n}_max_contact_force_N"] = pick(f"{n}_max_contact_force_N", max)
        out[f"{n}_first_contact_{UNIT}"] = pick(f"{n}_first_contact_{UNIT}", min)
        out[f"{n}_min_gap_mm"] = pick(f"{n}_min_gap_mm", min)
    return {k: v for k, v in out.items() if not (isinstance(v, float) and math.isnan(v))}


def requirements(study: Any) -> list[Requirement]:
    """The kind's built-in requirements; with stops also "contact penetration within
    tolerance" (``max_penetration_mm`` at most ``ContactSettings.penetration_tol`` x the
    thinnest leaf: ``geometry.thickness_mm``, or the design space's lower bound, whichever is
    thinner)."""
    reqs = list(_builtin.leaf_spring_joint(study))
    # the support's edge as made: its stated Kt, or NOT MET with the reason (#27)
    from flexopt.pipeline.studies._leaf_support import support_rows

    reqs += support_rows(study, study.target.allowable_stress_MPa or study.material.yield_MPa)
    # the shortest leaf over its thickness: below L/t 6 the beam's figures are not the leaf's
    # (the bounds allow it: a free length of 10 mm at t 2 mm); polyline_beam's row, measured there
    reqs.append(Slenderness())
    if study.stops is not None:
        thinnest = min(study.geometry.thickness_mm, study.design_space.thickness_mm[0])
        tolerance = ContactSettings().penetration_tol * thinnest
        reqs.append(PenetrationWithin("max_penetration_mm", PENETRATION_ROW, "check", tolerance))
    return reqs


def quantities(study: Any) -> tuple[str, ...]:
    """The names a requirement may judge; with stops, the stop figures over all curves too."""
    names = [*_builtin.LEAF_SPRING_JOINT, SLENDERNESS]
    if study.stops is None:
        return tuple(names)
    names += [f"first_contact_{UNIT}", "max_contact_force_N", "max_penetration_mm"]
    for stop in study.stops.outlines:
        n = stop.name
        names += [f"{n}_max_contact_force_N", f"{n}_first_contact_{UNIT}", f"{n}_min_gap_mm"]
    return tuple(names)
