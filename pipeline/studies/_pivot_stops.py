"""The ``flexure_pivot`` kind's rigid stops (issue 25, item 3): the study's ``stops:`` block
(:class:`~pipeline.studies._stops.StopsSpec`, the same block as ``polyline_beam``'s and
``mechanism``'s) given to the constrained-beam engine (:func:`fea.pivot.beam_pivot` with
``stops=``: frictionless penalty contact of every member with them inside Newton,
fea/constrained_beams.py), and what the kind reports of it:

* the table's columns ``<name>_contact_force_N`` (the resultant force the stop exerts on the
  members, N), ``<name>_gap_mm`` (the smallest gap between a member's surface and the stop, mm:
  clearance > 0, penetration < 0) and ``<name>_in_contact``;
* the summary's ``first_contact_rotation_deg`` (the block's rotation at which the first stop
  closes, deg), ``max_contact_force_N``, ``max_penetration_mm``,
  ``contact_penetration_tolerance_mm`` / ``_ok``, ``contact_penalty_factor`` / ``_raises``,
  ``contact_rows``, ``contact_message`` and per stop ``<name>_first_contact_rotation_deg``,
  ``<name>_max_contact_force_N``, ``<name>_min_gap_mm`` (the Durability section's contact
  table, pipeline/durability_report.py, reads them);
* the built-in row "contact penetration within tolerance";
* refusals: a stop overlapping the study's design (``stops.outlines[i]``); stops with a notch
  hinge among the candidates (the GA judges notches by their closed forms, which have no
  contact). A GA design whose members overlap a stop fails with that reason.

The moving and the ground blocks do not touch the stops (not modelled): only the members do.
Every figure the GA and the report judge (stiffness, stress, centre shift) is the beam model's
with the stops in place. A study without ``stops:`` gets none of it and runs exactly as before.
The kind is pipeline/studies/flexure_pivot.py; docs/flexures.md ("Stops") and docs/contact.md.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from flexopt.fea.beam import BeamModel, BeamSettings
from flexopt.fea.stops import BeamContact, ContactSettings, RigidStop, overlaps
from flexopt.optimise.requirements import Requirement
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import _builtin
from flexopt.pipeline.studies._stops import PenetrationWithin, StopsSpec
from pydantic import Field

__all__ = [
    "FIELD",
    "PENETRATION_ROW",
    "PLANE_STRESS_NOTE",
    "check",
    "columns",
    "contact_figures",
    "headline",
    "overlap",
    "quantities",
    "requirements",
    "solve_args",
    "summary",
]

#: the types judged by the beam model in the GA (fea.flexure_design.BEAM_TYPES): the only ones
#: that may meet a stop
STOP_TYPES = ("leaf", "variable_leaf", "cross_axis")
#: the built-in requirement's name
PENETRATION_ROW = "contact penetration within tolerance"
#: why a study with stops has no plane-stress check of its outline
PLANE_STRESS_NOTE = (
    "stops: no plane-stress check of the outline (that solve has no contact); stiffness and "
    "stress are the beam model's with the stops in place"
)
#: the study's ``stops:`` field (pipeline.studies.flexure_pivot.FlexurePivotStudy)
FIELD: Any = Field(
    None,
    description="rigid stops fixed to the ground that the members meet (frictionless penalty "
    "contact inside the beam solve): {outlines: [{name, points_mm, closed}], penalty_factor}; "
    "coordinates in the flexure's frame (docs/flexures.md)",
)


def _stops(study: Any) -> tuple[RigidStop, ...]:
    spec: StopsSpec | None = study.stops
    if spec is None:
        return ()
    return tuple(
        RigidStop(np.array(o.points_mm, dtype=float), o.closed, o.name) for o in spec.outlines
    )


def solve_args(study: Any) -> dict[str, Any]:
    """The keyword arguments of :func:`fea.pivot.beam_pivot` for the study's stops (empty
    without stops: the solve as before)."""
    if study.stops is None:
        return {}
    return {
        "stops": _stops(study),
        "contact": ContactSettings(penalty_factor=study.stops.penalty_factor),
    }


def _overlap(study: Any, flexure: Any) -> tuple[int, str] | None:
    stops = _stops(study)
    material = study.material.to_material()
    for i, profile in enumerate(flexure.beams() if stops else ()):
        settings = BeamSettings(n_elements=study.geometry.elements)
        contact = BeamContact(BeamModel(profile, material, settings=settings), stops)
        for j, depth in overlaps(contact):
            return j, (
                f"stop '{stops[j].name}' overlaps member {i} of the undeformed pivot by "
                f"{depth:.4g} mm (a member's surface is t/2 from its centreline); move it clear"
            )
    return None


def overlap(study: Any, flexure: Any) -> str:
    """Why ``flexure``'s undeformed members overlap a stop (deeper than the penetration
    tolerance), or "" when they are clear (always "" without stops)."""
    found = _overlap(study, flexure)
    return "" if found is None else found[1]


def check(study: Any, flexure: Any | None) -> None:
    """Refuse stops the kind cannot model: with a notch hinge among ``geometry.candidates``,
    or overlapping the study's design ``flexure`` (None without a design).

    Raises
    ------
    StudyError
        At ``stops`` (a notch candidate) or ``stops.outlines[i]`` (an overlap).
    """
    if study.stops is None:
        return
    notches = [c for c in study.geometry.candidates if c not in STOP_TYPES]
    if notches:
        raise StudyError(
            "stops",
            f"the candidates {', '.join(notches)} are notch hinges, judged by their closed "
            "forms, which have no contact; with stops give candidates among "
            f"{', '.join(STOP_TYPES)}",
        )
    found = _overlap(study, flexure) if flexure is not None else None
    if found is not None:
        raise StudyError(f"stops.outlines[{found[0]}]", found[1])


# ---------------------------------------------------------------------------- figures


def columns(study: Any, response: Any) -> dict[str, np.ndarray]:
    """The table's stop columns (each (rows,)) of a :class:`fea.pivot.PivotResponse`: force
    (N), gap (mm), in contact; NaN where a row did not converge. Empty without stops."""
    contact = getattr(response, "contact", None)
    if study.stops is None or contact is None:
        return {}
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(contact.names):
        out[f"{name}_contact_force_N"] = np.asarray(contact.force_N[:, j], dtype=float)
        out[f"{name}_gap_mm"] = np.asarray(contact.gap_mm[:, j], dtype=float)
        out[f"{name}_in_contact"] = np.asarray(contact.in_contact[:, j], dtype=bool)
    return out


def summary(study: Any, response: Any) -> dict[str, Any]:
    """The stop figures of a :class:`fea.pivot.PivotResponse` (see the module; the rotation at
    first contact in deg, the closing value of fea.stops.contact_rows). Empty without stops."""
    contact = getattr(response, "contact", None)
    if study.stops is None or contact is None:
        return {}
    return contact_figures(response, "rotation_deg")


def contact_figures(response: Any, unit: str) -> dict[str, Any]:
    """The stop figures (see the module) of a response with ``converged`` (rows,) and
    ``contact`` (fea.stops.ContactResponse, closing values in rad), the first contact named
    ``first_contact_<unit>`` in deg (a pivot's rotation, a leaf joint's deflection)."""
    contact = response.contact
    ok = np.asarray(response.converged, dtype=bool)
    closing = np.degrees(np.asarray(contact.closing_value, dtype=float))
    out: dict[str, Any] = {}
    for j, name in enumerate(contact.names):
        force = np.asarray(contact.force_N[ok, j], dtype=float)
        gap = np.asarray(contact.gap_mm[ok, j], dtype=float)
        first = float(closing[j])
        out[f"{name}_first_contact_{unit}"] = first if math.isfinite(first) else None
        out[f"{name}_max_contact_force_N"] = float(force.max()) if force.size else None
        out[f"{name}_min_gap_mm"] = float(np.nanmin(gap)) if np.isfinite(gap).any() else None
    finite = closing[np.isfinite(closing)]
    # the first stop to close along the rotation: the smallest |angle| (rows run away from 0)
    first_any = float(finite[np.argmin(np.abs(finite))]) if finite.size else None
    out[f"first_contact_{unit}"] = first_any
    forces = np.asarray(contact.force_N, dtype=float)[ok]
    out["max_contact_force_N"] = float(np.nanmax(forces)) if np.isfinite(forces).any() else 0.0
    pen = np.asarray(contact.max_penetration_mm, dtype=float)[ok]
    out["max_penetration_mm"] = float(pen.max()) if pen.size else 0.0
    out["contact_penetration_tolerance_mm"] = float(contact.extra.get("tolerance_mm", math.nan))
    out["contact_penetration_ok"] = bool(contact.penetration_ok)
    out["contact_penalty_factor"] = contact.extra.get("penalty_factor")
    out["contact_penalty_raises"] = contact.extra.get("raises")
    out["contact_rows"] = int(np.sum(np.asarray(contact.rows_in_contact, dtype=bool) & ok))
    out["contact_message"] = contact.message
    return out


def headline(study: Any) -> tuple[str, ...]:
    """The stop figures the CLI's table shows (none without stops)."""
    if study.stops is None:
        return ()
    return ("first_contact_rotation_deg", "max_contact_force_N", "max_penetration_mm")


# ---------------------------------------------------------------------------- requirements


def requirements(study: Any) -> list[Requirement]:
    """The kind's built-in requirements (pipeline.studies._builtin.flexure_pivot); with stops
    also "contact penetration within tolerance": ``max_penetration_mm`` at most
    ``ContactSettings.penetration_tol`` x ``geometry.min_feature_mm`` (no design of the study
    is thinner, so the bound is at most the engine's own tolerance, penetration_tol x the
    design's thinnest section)."""
    reqs = list(_builtin.flexure_pivot(study))
    if study.stops is not None:
        tolerance = ContactSettings().penetration_tol * study.geometry.min_feature_mm
        reqs.append(PenetrationWithin("max_penetration_mm", PENETRATION_ROW, "check", tolerance))
    return reqs


def quantities(study: Any) -> tuple[str, ...]:
    """The names a requirement may judge; with stops, each stop's columns and figures too."""
    names = list(_builtin.FLEXURE_PIVOT)
    if study.stops is None:
        return tuple(names)
    names += ["first_contact_rotation_deg", "max_contact_force_N", "max_penetration_mm"]
    names += ["contact_rows"]
    for stop in study.stops.outlines:
        n = stop.name
        names += [
            f"{n}_contact_force_N", f"{n}_gap_mm", f"{n}_in_contact",
            f"{n}_first_contact_rotation_deg", f"{n}_max_contact_force_N", f"{n}_min_gap_mm",
        ]  # fmt: skip
    return tuple(names)
