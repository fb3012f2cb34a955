"""The ``mechanism`` kind's rigid stops (issue 25, item 3): the study's ``stops:`` block
(:class:`~pipeline.studies._stops.StopsSpec`, the same block as ``polyline_beam``'s) given to
the engine (:attr:`fea.mechanism.Mechanism.stops`, frictionless penalty contact of every beam
with them inside Newton), and what the kind reports of it:

* per load case the columns ``stop_<name>_force_N`` (the resultant force the stop exerts on the
  beams, N, scaled with the width like the drive's reaction), ``stop_<name>_gap_mm`` (the
  smallest gap between a beam's surface and the stop, mm: clearance > 0, penetration < 0) and
  ``stop_<name>_in_contact``;
* the metrics ``max_stop_force_N``, ``max_penetration_mm``, ``contact_penalty_factor``,
  ``contact_penalty_raises`` and per case (prefixed like the case's other metrics)
  ``first_contact_<unit>`` (the drive value at which the first stop closes, in the drive's
  unit), ``contact_rows``, and per stop ``stop_<name>_max_force_N``,
  ``stop_<name>_first_contact_<unit>``, ``stop_<name>_min_gap_mm``;
* the built-in row "contact penetration within tolerance";
* the interference check: a beam or a moving body (one with an outline, not clamped to the
  ground) meeting a declared stop is contact, modelled (:mod:`fea.body_contact`: the stop's
  columns carry the force on beams and bodies together); an overlap deeper than the engine's
  penetration, or a body clamped to the ground overlapping a stop, is interference;
* ``contact_shapes.png``: the beams' deformed shapes (solid where in contact) with the stops.

Declared contact (``contact: [[a, b], ...]``, :attr:`fea.mechanism.Mechanism.beam_contacts`):
two beams, two bodies, a body and a beam, or one beam named twice (its self contact,
``[[a, a]]``); per declared pair and load case the columns ``contact_<a>_<b>_force_N`` (the
force between the two beams, N, scaled like a stop's), ``contact_<a>_<b>_gap_mm``,
``contact_<a>_<b>_in_contact`` (a beam with itself: the force is the sum of its contact pairs'
normal forces), the metrics ``<case>contact_<a>_<b>_max_force_N`` and the pairs'
penetration in ``max_penetration_mm`` (the same built-in row); a declared pair touching is
modelled contact, not interference (its overlap is still checked), any other meeting stays
interference. The penalty is the ``stops:`` block's (default without it).

A study without ``stops:`` or ``contact:`` gets none of it and runs exactly as before. The kind
is pipeline/studies/mechanism.py; docs/mechanism.md ("Stops") and docs/contact.md.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from flexopt.fea.mechanism_design import DRIVE_UNIT, INTERFERENCE_MM2, stable_part
from flexopt.fea.stops import ContactSettings, RigidStop
from flexopt.optimise.requirements import Requirement, Verdict
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies._mechanism_schema import MechanismStudy, case_prefix
from flexopt.pipeline.studies._stops import PenetrationWithin

__all__ = [
    "column_names",
    "columns",
    "contact_png",
    "headline",
    "metric_names",
    "metrics",
    "refusal",
    "requirements",
    "settings",
    "stop_interference",
    "interference_verdict",
    "with_stops",
]

#: the built-in requirement's name
PENETRATION_ROW = "contact penetration within tolerance"


def _stops(study: MechanismStudy) -> tuple[RigidStop, ...]:
    spec = study.stops
    if spec is None:
        return ()
    return tuple(
        RigidStop(np.array(o.points_mm, dtype=float), o.closed, o.name) for o in spec.outlines
    )


def _pairs(study: MechanismStudy) -> tuple[tuple[str, str], ...]:
    return tuple((str(a), str(b)) for a, b in (study.contact or ()))


def _contact(study: MechanismStudy) -> bool:
    """The study declares stops or beam-beam contact."""
    return study.stops is not None or bool(_pairs(study))


def with_stops(mech: Any, study: MechanismStudy) -> Any:
    """The solver's mechanism with the study's stops and declared beam pairs (``mech`` itself
    without either)."""
    stops, pairs = _stops(study), _pairs(study)
    if stops:
        mech = dataclasses.replace(mech, stops=stops)
    return dataclasses.replace(mech, beam_contacts=pairs) if pairs else mech


def settings(study: MechanismStudy) -> Any:
    """The :class:`fea.mechanism.MechanismSettings` with the study's penalty factor; None
    without stops (the solver's defaults: the old path)."""
    if not _contact(study):
        return None
    from flexopt.fea.mechanism import MechanismSettings  # the engine, with the first solve

    factor = ContactSettings().penalty_factor if study.stops is None else study.stops.penalty_factor
    contact = ContactSettings(penalty_factor=factor, element_length="mean")
    return MechanismSettings(contact=contact)


def refusal(study: MechanismStudy, message: str) -> StudyError | None:
    """The engine's refusal of a stop overlapping a beam as a StudyError at
    ``stops.outlines[i]``, of a declared beam pair at ``contact[i]`` (None when ``message`` is
    about something else)."""
    pairs = _pairs(study)
    for i, (a, b) in enumerate(pairs):
        if message.startswith(f"beam contact [{a}, {b}]"):
            return StudyError(f"contact[{i}]", message)
    if study.stops is None or not message.startswith("stop '"):
        return None
    name = message.split("'", 2)[1]
    names = [o.name for o in study.stops.outlines]
    if name not in names:
        return None
    return StudyError(f"stops.outlines[{names.index(name)}]", message)


# ---------------------------------------------------------------------------- names


def _unit(study: MechanismStudy, case: str) -> str:
    return DRIVE_UNIT[study.load_cases[case].drive.control]


def column_names(study: MechanismStudy) -> set[str]:
    """Every case's stop and beam-pair columns, prefixed by the case (empty without)."""
    out = set()
    names = [f"stop_{o.name}" for o in (study.stops.outlines if study.stops else ())]
    names += [f"contact_{a}_{b}" for a, b in _pairs(study)]
    for case in study.load_cases:
        p = case_prefix(study, case)
        for n in names:
            out |= {f"{p}{n}_{s}" for s in ("force_N", "gap_mm", "in_contact")}
    return out


def metric_names(study: MechanismStudy) -> set[str]:
    """The stop and beam-pair metrics a design reports (empty without)."""
    pairs = {
        f"{case_prefix(study, case)}contact_{a}_{b}_max_force_N"
        for case in study.load_cases
        for a, b in _pairs(study)
    }
    if pairs:
        pairs.add("max_penetration_mm")
    if study.stops is None:
        return pairs
    out = {"max_stop_force_N", "max_penetration_mm", "contact_penalty_factor"}
    out |= {"contact_penalty_raises"} | pairs
    for case in study.load_cases:
        p, unit = case_prefix(study, case), _unit(study, case)
        out |= {f"{p}first_contact_{unit}", f"{p}contact_rows"}
        for o in study.stops.outlines:
            n = f"{p}stop_{o.name}"
            out |= {f"{n}_max_force_N", f"{n}_first_contact_{unit}", f"{n}_min_gap_mm"}
    return out


def headline(study: MechanismStudy) -> tuple[str, ...]:
    """The stop figures the CLI's table shows (the first case's first contact)."""
    if study.stops is None:
        return ()
    case = next(iter(study.load_cases))
    first = f"{case_prefix(study, case)}first_contact_{_unit(study, case)}"
    return ("max_stop_force_N", first, "max_penetration_mm")


# ---------------------------------------------------------------------------- figures


def _force_scale(study: MechanismStudy, case: str, scale: float) -> float:
    """A stop's force scales with the width like the drive's reaction (N under displacement or
    rotation control); under force or moment control the motion does instead."""
    control = study.load_cases[case].drive.control
    return scale if control in ("displacement", "rotation") else 1.0


def columns(study: MechanismStudy, case: str, response: Any, scale: float) -> dict[str, Any]:
    """The case's stop columns (each (rows,)): force (N, times the width ``scale`` where forces
    scale), gap (mm), in contact; NaN from the first unstable row on like the case's other
    columns (:func:`fea.mechanism_design.stable_part`). Empty without stops."""
    f = _force_scale(study, case, scale)
    out = _pair_columns(study, response, f)
    contact = getattr(response, "contact", None)
    if study.stops is None or contact is None:
        return out
    values: dict[str, Any] = {}
    for j, name in enumerate(contact.names):
        values[f"stop_{name}_force_N"] = np.asarray(contact.force_N[:, j], dtype=float) * f
        values[f"stop_{name}_gap_mm"] = np.asarray(contact.gap_mm[:, j], dtype=float)
    out.update(stable_part(values, response))
    for j, name in enumerate(contact.names):
        out[f"stop_{name}_in_contact"] = np.asarray(contact.in_contact[:, j], dtype=bool)
    return out


def _pair_columns(study: MechanismStudy, response: Any, scale: float) -> dict[str, Any]:
    """The declared beam pairs' columns of one case (force N times ``scale``, gap mm, in
    contact), NaN from the first unstable row on (empty without pairs)."""
    found = getattr(response, "beam_contact", None)
    if not found:
        return {}
    values: dict[str, Any] = {}
    for a, b in _pairs(study):
        c = found[f"{a}/{b}"]
        values[f"contact_{a}_{b}_force_N"] = np.asarray(c["force_N"], dtype=float) * scale
        values[f"contact_{a}_{b}_gap_mm"] = np.asarray(c["gap_mm"], dtype=float)
    out = dict(stable_part(values, response))
    for a, b in _pairs(study):
        out[f"contact_{a}_{b}_in_contact"] = np.asarray(found[f"{a}/{b}"]["in_contact"], bool)
    return out


def _pair_metrics(
    study: MechanismStudy, responses: Mapping[str, Any], tables: Mapping[str, Mapping[str, Any]]
) -> dict[str, Any]:
    """Per case and declared pair the largest force (N), and the pairs' largest penetration
    (mm) as ``max_penetration_mm`` (empty without pairs)."""
    pairs = _pairs(study)
    if not pairs:
        return {}
    out: dict[str, Any] = {}
    pen = [0.0]
    for case in responses:
        p, table = case_prefix(study, case), tables[case]
        for a, b in pairs:
            force = np.asarray(table[f"contact_{a}_{b}_force_N"], dtype=float)
            ok = np.isfinite(force)
            out[f"{p}contact_{a}_{b}_max_force_N"] = float(force[ok].max()) if ok.any() else None
            gap = np.asarray(table[f"contact_{a}_{b}_gap_mm"], dtype=float)
            pen += [float(-g) for g in gap[np.isfinite(gap)] if g < 0.0]
    out["max_penetration_mm"] = max(pen)
    return out


def metrics(
    study: MechanismStudy, responses: Mapping[str, Any], tables: Mapping[str, Mapping[str, Any]]
) -> dict[str, Any]:
    """The stop metrics of a design (see the module) from its ``responses`` (the first contact,
    the penetration, the penalty) and its case ``tables`` (the forces, as scaled). Empty
    without stops; with declared beam pairs their figures (:func:`_pair_metrics`)."""
    pairs = _pair_metrics(study, responses, tables)
    if study.stops is None:
        return pairs
    out: dict[str, Any] = {}
    forces, pen, factor, raises = [], [pairs.get("max_penetration_mm", 0.0)], None, 0
    for case, resp in responses.items():
        contact = getattr(resp, "contact", None)
        if contact is None:
            continue
        p, unit = case_prefix(study, case), _unit(study, case)
        table = tables[case]
        ok = np.asarray(resp.converged, dtype=bool)
        closing = np.asarray(contact.closing_value, dtype=float)
        if unit == "deg":
            closing = np.degrees(closing)
        for j, name in enumerate(contact.names):
            force = np.asarray(table[f"stop_{name}_force_N"], dtype=float)
            gap = np.asarray(table[f"stop_{name}_gap_mm"], dtype=float)
            n = f"{p}stop_{name}"
            out[f"{n}_max_force_N"] = float(np.nanmax(force)) if np.isfinite(force).any() else None
            first = float(closing[j])
            out[f"{n}_first_contact_{unit}"] = first if math.isfinite(first) else None
            out[f"{n}_min_gap_mm"] = float(np.nanmin(gap)) if np.isfinite(gap).any() else None
            forces += [float(v) for v in force[np.isfinite(force)]]
        finite = closing[np.isfinite(closing)]
        # the first stop to close along the drive: the smallest |drive| (rows run away from 0)
        out[f"{p}first_contact_{unit}"] = (
            float(finite[np.argmin(np.abs(finite))]) if finite.size else None
        )
        out[f"{p}contact_rows"] = int(np.sum(np.asarray(contact.rows_in_contact, bool) & ok))
        pen += [float(v) for v in np.asarray(contact.max_penetration_mm, dtype=float)[ok]]
        factor = contact.extra.get("penalty_factor", factor)
        raises = max(raises, int(contact.extra.get("raises", 0)))
    out["max_stop_force_N"] = max(forces) if forces else 0.0
    out["max_penetration_mm"] = max(pen)
    out["contact_penalty_factor"] = factor
    out["contact_penalty_raises"] = raises
    return {**pairs, **out}


def requirements(study: MechanismStudy) -> list[Requirement]:
    """The built-in "contact penetration within tolerance" (``max_penetration_mm`` at most
    ``ContactSettings.penetration_tol`` x the thinnest beam, the engine's tolerance); none
    without stops (or declared beam pairs)."""
    if not _contact(study):
        return []
    thinnest = min(float(np.min(b.thickness())) for b in study.geometry.beams.values())
    tolerance = ContactSettings().penetration_tol * thinnest
    return [PenetrationWithin("max_penetration_mm", PENETRATION_ROW, "check", tolerance)]


# ---------------------------------------------------------------------------- interference


def _stop_shape(stop: RigidStop) -> Any:
    """A stop as a shapely shape with an area: a polygon as itself, a point or a wall as a
    band 0.01 mm either side (a body crossing it then overlaps it by an area)."""
    import shapely
    from shapely.geometry import LineString, Point, Polygon

    p = stop.outline_mm
    if stop.closed:
        return shapely.make_valid(Polygon(p))
    line = Point(p[0]) if p.shape[0] == 1 else LineString(p)
    return line.buffer(0.01)


def stop_interference(
    study: MechanismStudy,
    mech: Any,
    clearance: Mapping[str, Any],
    responses: Mapping[str, Any],
) -> dict[str, Any]:
    """``clearance`` (:func:`fea.mechanism_design.interference`: the parts among themselves)
    with every body outline's overlap with every stop at every converged row: the engine keeps
    the beams and the moving bodies out of the stops (contact, modelled: not interference, and
    no clearance to keep; their penetration, ~1e-6 mm, overlaps far less than the threshold),
    but not a body clamped to the ground, which stays interference where it meets a stop; an
    overlap above the threshold is interference either way. Unchanged without stops."""
    stops = _stops(study)
    if not stops:
        return dict(clearance)
    import shapely

    out = dict(clearance)
    worst = (float(out.get("interference_mm2") or 0.0), out.get("interference_at", ""))
    shapes = [(st.name, _stop_shape(st)) for st in stops]
    held = {j.a for j in mech.joints if j.b == "ground" and j.type == "clamped"}
    for case, resp in responses.items():
        rows = np.flatnonzero(np.asarray(resp.converged, dtype=bool))
        if rows.size == 0:
            continue
        d = study.load_cases[case].drive
        drive = np.asarray(resp.drive, dtype=float)
        drive = np.degrees(drive) if d.control == "rotation" else drive
        for k, body in enumerate(mech.bodies):
            if body.outline_mm is None:
                continue
            pose = np.asarray(resp.body_poses, dtype=float)[rows, k]
            c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
            rel = np.asarray(body.outline_mm, dtype=float) - np.asarray(body.ref_mm, dtype=float)
            xy = np.stack(
                [c[:, None] * rel[:, 0] - s[:, None] * rel[:, 1] + pose[:, :1],
                 s[:, None] * rel[:, 0] + c[:, None] * rel[:, 1] + pose[:, 1:2]],
                axis=2,
            )  # fmt: skip
            polys = shapely.polygons(xy)
            for name, shape in shapes:
                area = shapely.area(shapely.intersection(polys, shape))
                i = int(np.argmax(area))
                if area[i] > max(worst[0], INTERFERENCE_MM2):
                    r = rows[i]
                    why = (
                        "a body clamped to the ground is not in the contact solve"
                        if body.name in held
                        else "deeper than the contact's penetration"
                    )
                    worst = (
                        float(area[i]),
                        f"load case {case}, row {r} (drive {drive[r]:.4g} {d.unit}): body "
                        f"{body.name} passes through stop {name} ({area[i]:.3g} mm²; {why})",
                    )
    out["interference_mm2"], out["interference_at"] = worst
    return out


def interference_verdict(study: MechanismStudy, verdict: Verdict) -> Verdict:
    """The built-in no-interference row, its bound saying which contact is modelled."""
    if not _contact(study):
        return verdict
    declared = "the declared stops" if study.stops is not None else ""
    if _pairs(study):
        pairs = ", ".join(f"{a}-{b}" for a, b in _pairs(study))
        declared = f"{declared} and the pairs {pairs}".removeprefix(" and ")
    parts = "the beams and moving bodies" if study.stops is not None else "the parts"
    bound = (
        f"0 mm² at every row (contact modelled between {parts} and {declared} only; "
        "any other meeting is interference)"
    )
    return dataclasses.replace(verdict, bound=bound)


# ---------------------------------------------------------------------------- figure


def contact_png(study: MechanismStudy, responses: Mapping[str, Any]) -> bytes | None:
    """contact_shapes.png of the first displacement-driven case (the figure's legend reads
    the drive in mm): every beam's deformed centreline, solid in rows in contact, with the
    stops (:func:`pipeline.plots.stops_shapes_png`). None without stops or such a case."""
    stops = _stops(study)
    case = next((c for c, s in study.load_cases.items() if s.drive.control == "displacement"), None)
    if not stops or case is None or getattr(responses[case], "contact", None) is None:
        return None
    from flexopt.pipeline import plots  # matplotlib only when there is a figure to draw

    resp = responses[case]
    ok = np.asarray(resp.converged, dtype=bool)
    # the beams one after the other, a NaN point between two (matplotlib breaks the line there)
    parts = []
    for shape in resp.shapes_mm:
        parts += [np.asarray(shape, dtype=float)[ok], np.full((int(ok.sum()), 1, 2), np.nan)]
    return plots.stops_shapes_png(
        np.concatenate(parts[:-1], axis=1),
        [(st.name, st.outline_mm, st.closed) for st in stops],
        np.asarray(resp.drive, dtype=float)[ok],
        np.asarray(resp.contact.rows_in_contact, dtype=bool)[ok],
    )
