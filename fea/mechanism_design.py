"""The mechanics of one ``mechanism`` design around the solver: its responses as columns, the
width they scale with, the path a printed part follows, its roots' stress, its parts' clearance.

:mod:`fea.mechanism` solves a mechanism in one load case; the ``mechanism`` study kind
(pipeline/studies/mechanism.py) composes a design from its study file and asks this module:

* :func:`solve_printed_path` — the case solved along the path the printed part follows (the
  drawn part, and where it bifurcates the part with a small imperfection along its buckling
  mode);
* :func:`case_table` — a response as named columns (drive, drive reaction, the user's outputs
  and their slopes and ratios, the peak stress of the beams as made), forces scaled from the
  reference width (:func:`width_exponent`: a force is linear in the shared width);
* :func:`width_for_range`, :func:`width_for_target` — the shared width that puts a force-like
  figure in the middle of its bound (the width scaling law solved from a target);
* :func:`as_made_stress` — the beams' peak stress with their filleted roots' Kt;
* :func:`interference` — the overlap and the clearance of the deformed parts over the stroke
  (:func:`deformed_bands` draws a beam as its band; :func:`self_overlap`, a beam on itself).

The solver (scipy and the compiled kernels) is imported with the first solve, not with this
module: a kind imports this module when it registers. Units: mm, N, N·mm, rad (deg in the
columns of a rotation drive and of outputs named ``_deg``), MPa, mm².
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from flexopt.geometry.mechanism import AsMadeBeam, MechanismOutline, attachments

if TYPE_CHECKING:
    from flexopt.fea.mechanism import LoadCase, Mechanism, MechanismResponse, MechOutput

__all__ = [
    "DRIVE_UNIT",
    "INTERFERENCE_MM2",
    "REACTION_UNIT",
    "OutputColumn",
    "as_made_stress",
    "case_table",
    "deformed_bands",
    "interference",
    "self_overlap",
    "solve_printed_path",
    "stable_part",
    "width_exponent",
    "width_for_range",
    "width_for_target",
]

#: The unit of a drive's value per control (the drive column is ``drive_<unit>``).
DRIVE_UNIT = {"displacement": "mm", "rotation": "deg", "force": "N", "moment": "Nmm"}
#: The unit of the drive's reaction per control (column ``drive_reaction_<unit>``).
REACTION_UNIT = {"displacement": "N", "force": "N", "rotation": "Nmm", "moment": "Nmm"}
#: Overlap area (mm^2) of two deformed parts that counts as interference (round-off of bands
#: built from the solver's node positions is far smaller).
INTERFERENCE_MM2 = 1e-3


def _solver():
    # imported with the first solve: the kinds import this module when they register
    import flexopt.fea.mechanism as fm

    return fm


@dataclasses.dataclass(frozen=True)
class OutputColumn:
    """One named output of a load case, as :func:`case_table` writes its column.

    Attributes
    ----------
    name : str — the column's name (its unit at the end: ``force_N``, ``turn_deg``).
    quantity : str — what :class:`fea.mechanism.MechOutput` reads (``reaction``,
        ``displacement``, ...), or ``slope`` (of one output along the drive) or ``ratio`` (of
        two outputs).
    of : tuple of str — the output a slope differentiates, ``(numerator, denominator)`` of a
        ratio; empty otherwise.
    part : str — the beam a ``peak_stress`` output reads ('' = every beam).
    degrees : bool — a rotation written in deg (the solver's are rad).
    exponent : int — the power of the width scale the column carries (:func:`width_exponent`).
    """

    name: str
    quantity: str
    of: tuple[str, ...] = ()
    part: str = ""
    degrees: bool = False
    exponent: int = 0


def width_exponent(
    outputs: Mapping[str, tuple[str, tuple[str, ...]]], name: str, seen: tuple[str, ...] = ()
) -> int:
    """How output ``name`` scales with the shared width: 1 (a force or moment, linear in the
    width), 0 (a motion, a stress), or another power for slopes and ratios of them.

    ``outputs`` maps each output's name to ``(quantity, of)`` (:class:`OutputColumn`'s fields);
    a slope or ratio that refers back to one already followed (``seen``) counts 0."""
    quantity, of = outputs[name]
    if quantity in ("reaction", "reaction_force", "reaction_moment"):
        return 1
    if quantity == "slope" and len(of) == 1 and of[0] not in seen:
        return width_exponent(outputs, of[0], (*seen, name))
    if quantity == "ratio" and len(of) == 2:
        a, b = of
        if a in seen or b in seen:
            return 0
        return width_exponent(outputs, a, (*seen, name)) - width_exponent(outputs, b, (*seen, name))
    return 0


def as_made_stress(
    response: MechanismResponse, made: Mapping[str, AsMadeBeam] | None
) -> np.ndarray:
    """(rows, beams) peak stress of each beam as made, MPa: the beam model's peak, and at each
    filleted root the shoulder's Kt times the largest beam-model stress over the root's flare
    (``EndJunction.kt``, :func:`geometry.mechanism.shoulder_kt`): the flare is modelled as a
    thickening beam, whose stress at the fillet's toe is the nominal stress Kt multiplies.
    ``made`` is ``MechanismOutline.beams`` in the mechanism's beam order (None: the beam model's
    peak alone)."""
    peak = np.asarray(response.peak_stress_MPa, dtype=float)
    roots = np.asarray(getattr(response, "root_stress_MPa", np.zeros((0, 0, 2))), dtype=float)
    if made is None or roots.shape[:2] != peak.shape:
        return peak
    kt = np.array([[m.start.kt, m.end.kt] for m in made.values()], dtype=float)  # (beams, 2)
    with np.errstate(invalid="ignore"):
        return np.fmax(peak, np.max(roots * kt[None], axis=2))


def case_table(
    control: str,
    outputs: Sequence[OutputColumn],
    response: MechanismResponse,
    scale: float,
    made: Mapping[str, AsMadeBeam] | None = None,
) -> dict[str, np.ndarray]:
    """A load case's response as named columns, one (rows,) array each.

    ``control`` is the case's drive control; ``outputs`` the case's outputs in order; force-like
    columns are multiplied by ``scale`` (= width / the width solved, no unit) to the power of
    their :attr:`OutputColumn.exponent` (the drive reaction to the first power under displacement
    or rotation control, where the force is linear in the width); with ``made`` the stresses are
    the beams' as made (:func:`as_made_stress`). Columns: ``step``, ``drive_<unit>``,
    ``drive_reaction_<unit>``, the outputs, ``peak_stress_MPa``, ``converged``, ``stable``; the
    rows from the first unstable one on are NaN (:func:`stable_part`)."""
    drive = np.asarray(response.drive, dtype=float)
    if control == "rotation":
        drive = np.degrees(drive)
    force_like = control in ("displacement", "rotation")
    reaction = np.asarray(response.outputs["__drive_reaction"], dtype=float)
    table: dict[str, np.ndarray] = {
        "step": np.arange(len(drive)),
        f"drive_{DRIVE_UNIT[control]}": drive,
        f"drive_reaction_{REACTION_UNIT[control]}": reaction * (scale if force_like else 1.0),
    }
    for o in outputs:
        if o.quantity in ("slope", "ratio"):
            continue
        values = np.asarray(response.outputs[o.name], dtype=float)
        if o.quantity == "rotation" and o.degrees:
            values = np.degrees(values)
        table[o.name] = values * scale**o.exponent
    pending = [o for o in outputs if o.name not in table]
    for _ in range(len(pending) + 1):  # derived outputs may build on each other
        for o in list(pending):
            if not all(r in table for r in o.of):
                continue
            if o.quantity == "slope":
                y = table[o.of[0]]
                table[o.name] = np.gradient(y, drive) if len(drive) > 2 else np.full_like(y, np.nan)
            else:
                with np.errstate(divide="ignore", invalid="ignore"):
                    ratio = table[o.of[0]] / table[o.of[1]]
                table[o.name] = np.where(np.isfinite(ratio), ratio, np.nan)
            pending.remove(o)
    for o in pending:  # refers to an output not read in this case
        table[o.name] = np.full(len(drive), np.nan)
    per_beam = as_made_stress(response, made)
    # the largest beam's per row; a row the solver did not reach is NaN in every beam and stays
    # NaN (fmax.reduce: no "All-NaN slice" warning); the verdict says the stroke was not solved
    # through (pipeline/stroke_verdict.py)
    row_peak = np.fmax.reduce(per_beam, axis=1)
    for o in outputs:  # a peak stress output reads the roots' factors too
        if o.quantity == "peak_stress" and made is not None:
            i = list(made).index(o.part) if o.part in made else None
            table[o.name] = row_peak.copy() if i is None else per_beam[:, i]
    table["peak_stress_MPa"] = row_peak
    table["converged"] = np.asarray(response.converged, dtype=bool)
    table["stable"] = np.asarray(response.stable, dtype=bool)
    return stable_part(table, response)


def stable_part(table: dict[str, np.ndarray], response: MechanismResponse) -> dict[str, np.ndarray]:
    """The table with every value from the first unstable row on set to NaN: no requirement,
    metric or plot reads a value beyond a point the part cannot pass on that path (the rows,
    their drive and their flags are kept; the case's message says where the curve stops)."""
    row = _solver().first_unstable_row(response)
    if row is None:
        return table
    keep = {"step", "converged", "stable"} | {k for k in table if k.startswith("drive_")}
    keep.discard(next((k for k in table if k.startswith("drive_reaction_")), ""))
    out = dict(table)
    for key, col in table.items():
        if key not in keep:
            arr = np.asarray(col, dtype=float).copy()
            arr[row:] = np.nan
            out[key] = arr
    return out


def solve_printed_path(
    mech: Mechanism,
    load_case: LoadCase,
    outputs: Sequence[MechOutput],
    imperfection_mm: float,
    unit: str,
    settings: Any = None,
) -> MechanismResponse:
    """The case solved along the path the printed part follows (issue 22, item 3).

    The mechanism as drawn is solved first. Where its path loses stability (a bifurcation: a
    symmetric switch's asymmetric mode), the made part, never perfectly symmetric, leaves the
    traced path there: it is solved again with its stress-free shape moved ``imperfection_mm``
    (mm; 0: never) along the buckling mode (:func:`fea.mechanism.imperfect_mechanism`) and that
    response is the case's. The part as exported keeps the drawn shape. Rows that are still
    unstable are cut by :func:`stable_part`. The response's message says which path it is,
    with drive values in ``unit`` (the drive's: ``deg`` for a rotation, the solver's rad shown
    in deg). ``settings``: the :class:`fea.mechanism.MechanismSettings` of both solves (None:
    the defaults; a study with stops passes its contact penalty there).
    """
    fm = _solver()
    response = fm.solve_mechanism(mech, load_case, outputs, settings)
    row = fm.first_unstable_row(response)
    amplitude = float(imperfection_mm)

    def shown(value: float) -> str:
        return f"{math.degrees(value) if unit == 'deg' else value:.4g} {unit}"

    notes = []
    if row is not None and amplitude > 0.0 and response.critical_mode is not None:
        notes.append(
            f"the part as drawn bifurcates at drive {shown(response.critical_drive)}: the "
            f"responses are those of the part with a {amplitude:g} mm imperfection along its "
            "buckling mode (imperfection_mm), the branch a printed part follows"
        )
        response = fm.solve_mechanism(
            fm.imperfect_mechanism(mech, response, amplitude), load_case, outputs, settings
        )
        row = fm.first_unstable_row(response)
    if row is not None:
        notes.append(
            f"the curve stops at row {row} (drive {shown(float(response.drive[row]))}): from "
            "there the path is unstable, and no output or requirement reads it"
        )
    if not notes:
        return response
    message = "; ".join([response.message, *notes] if response.message else notes)
    return dataclasses.replace(response, message=message)


# --------------------------------------------------------------------------------------------
# The width solved from a target (forces are linear in the shared width)


def width_for_range(
    quantity: str, value: float | None, minimum: float, maximum: float, ref_width_mm: float
) -> tuple[float, str]:
    """The width (mm) that puts ``quantity``, ``value`` at ``ref_width_mm`` (linear in the
    width), in the middle of ``[minimum, maximum]``; ``(nan, why)`` when it cannot."""
    if value is None or not math.isfinite(value):
        return math.nan, f"{quantity} was not computed at the reference width"
    target = 0.5 * (minimum + maximum)
    if value == 0 or target / value <= 0:
        return math.nan, (
            f"{quantity} = {value:.4g} at the reference width cannot be scaled to "
            f"{target:.4g} (opposite sign or zero)"
        )
    return ref_width_mm * target / value, ""


def width_for_target(
    quantity: str,
    x: np.ndarray,
    y: np.ndarray,
    target: Callable[[np.ndarray], np.ndarray],
    over: tuple[float, float] | None,
    relative: bool,
    ref_width_mm: float,
) -> tuple[float, str]:
    """The width (mm) that fits the curve ``y(x)`` at ``ref_width_mm`` ((rows,) each, y linear
    in the width) to its target ``target(x)`` (in y's unit) over ``over`` (all of x: None):
    the scale that centres the ratio y / target in a relative band (``relative``, minimax), else
    the least-squares scale to an absolute band; ``(nan, why)`` when it cannot."""
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    if over is not None:
        inside = (x >= over[0]) & (x <= over[1])
        x, y = x[inside], y[inside]
    t = target(x)
    use = np.abs(t) > 1e-12 * max(1.0, float(np.max(np.abs(t), initial=0.0)))
    if not use.any() or not np.any(np.abs(y[use]) > 0):
        return math.nan, f"{quantity} is zero where the target is not; nothing to scale"
    if relative:
        r = y[use] / t[use]
        if np.any(r <= 0):
            return math.nan, f"{quantity} has the wrong sign against its target"
        # the scale that centres the ratio y/t in the relative band (minimax)
        scale = 2.0 / (float(np.max(r)) + float(np.min(r)))
    else:
        scale = float(np.dot(y, t) / np.dot(y, y))  # least squares to an absolute band
        if not scale > 0:
            return math.nan, f"{quantity} has the wrong sign against its target"
    return ref_width_mm * scale, ""


# --------------------------------------------------------------------------------------------
# The parts' clearance over the stroke


def _mitred_offsets(p: np.ndarray, thickness_mm: np.ndarray) -> np.ndarray:
    """The half-thickness offsets (rows, n, 2) mm of a band's edges at the nodes ``p`` (rows,
    n, 2) mm, along the mitred normals (see :func:`deformed_bands`)."""
    d = np.diff(p, axis=1)
    u = d / np.linalg.norm(d, axis=2, keepdims=True)
    tangent = np.concatenate([u[:, :1], u[:, :-1] + u[:, 1:], u[:, -1:]], axis=1)
    tangent /= np.linalg.norm(tangent, axis=2, keepdims=True)
    cos_half = np.ones(p.shape[:2])
    cos_half[:, 1:-1] = np.sum(u[:, :-1] * tangent[:, 1:-1], axis=2)  # cos of half the turn
    normal = np.stack([-tangent[..., 1], tangent[..., 0]], axis=2)
    half = 0.5 * np.asarray(thickness_mm, dtype=float)[None, :] / np.maximum(cos_half, 0.5)
    return half[..., None] * normal


def deformed_bands(points_mm: np.ndarray, thickness_mm: np.ndarray) -> np.ndarray:
    """A beam as a band of its thickness along its deformed centreline at every row: nodes
    (rows, n, 2) mm and thickness (n,) mm -> (rows,) shapely Polygons. Both edges are offset at
    the nodes along the mitred normals (by ``t / 2 / cos(turn / 2)``, so a kink's outer corner
    is the mitre, which holds the round corner of the material: a touch of extra material,
    never less); one polygon per row, made for all rows at once."""
    import shapely

    p = np.asarray(points_mm, dtype=float)
    offset = _mitred_offsets(p, thickness_mm)
    bands = shapely.polygons(np.concatenate([p + offset, (p - offset)[:, ::-1]], axis=1))
    bad = ~shapely.is_valid(bands)
    if bad.any():  # an inner edge folded at a kink
        bands[bad] = shapely.buffer(bands[bad], 0.0)
    return bands


def self_overlap(
    points_mm: np.ndarray, thickness_mm: np.ndarray, s_mm: np.ndarray, skip_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """How far a beam's band overlaps itself at every row: its parts farther apart than
    ``skip_mm`` of arc length compared with each other (nearer parts touch by construction).

    The band (:func:`deformed_bands`' mitred edges, the thickness as made) is cut into one
    quadrilateral per segment between two nodes; a pair of segments counts when one ends
    more than ``skip_mm`` before the other starts (the rule of the self-contact pairs,
    :func:`fea.body_contact.default_skip_mm`), and its overlap is the area the two share.

    Parameters
    ----------
    points_mm : (rows, n, 2) float — deformed centreline nodes, mm.
    thickness_mm : (n,) float — thickness at the nodes, mm.
    s_mm : (n,) float — the nodes' arc length along the beam as made, mm.
    skip_mm : arc length (mm) within which parts of the beam are not compared.

    Returns
    -------
    area_mm2 : (rows,) float — the summed overlap of all far segment pairs, mm² (0 where none).
    where_mm : (rows, 2) float — the arc lengths (mm, segment midpoints) of the row's most
        overlapping pair (NaN where none).
    """
    import shapely

    p = np.asarray(points_mm, dtype=float)
    s = np.asarray(s_mm, dtype=float)
    rows, n = p.shape[:2]
    area = np.zeros(rows)
    where = np.full((rows, 2), np.nan)
    if n < 3:
        return area, where
    off = _mitred_offsets(p, thickness_mm)
    left, right = p + off, p - off
    quads = np.stack([left[:, :-1], left[:, 1:], right[:, 1:], right[:, :-1]], axis=2)
    # the far pairs (segment ib starts more than the skip after segment ia ends: ib > ia),
    # then those whose boxes meet at some row; only these are made shapes (most have none)
    ia, ib = np.nonzero(s[None, :-1] > s[1:, None] + skip_mm)
    lo, hi = quads.min(axis=2), quads.max(axis=2)  # (rows, n - 1, 2) mm
    meet = np.all((lo[:, ia] <= hi[:, ib]) & (lo[:, ib] <= hi[:, ia]), axis=2)  # (rows, pairs)
    r, k = np.nonzero(meet)
    if r.size == 0:
        return area, where
    ia, ib = ia[k], ib[k]
    first, second = shapely.polygons(quads[r, ia]), shapely.polygons(quads[r, ib])
    for g in (first, second):
        bad = ~shapely.is_valid(g)
        if bad.any():  # a segment folded at a kink: its area is what it covers
            g[bad] = shapely.make_valid(g[bad])
    shared = shapely.area(shapely.intersection(first, second))
    np.add.at(area, r, shared)
    mid = 0.5 * (s[:-1] + s[1:])
    for row in np.unique(r):
        j = np.flatnonzero(r == row)
        j = j[np.argmax(shared[j])]
        where[row] = (mid[ia[j]], mid[ib[j]])
    return area, where


def _self_worst(
    worst: tuple[float, str],
    resp: MechanismResponse,
    i: int,
    name: str,
    pts: np.ndarray,
    t: np.ndarray,
    at: Sequence[str],
    declared: bool,
) -> tuple[float, str]:
    """``worst`` (area mm², text) or beam ``i``'s overlap with itself (:func:`self_overlap`
    over the checked rows ``pts`` (rows, n, 2) mm, named by ``at``) where that is larger and
    above :data:`INTERFERENCE_MM2`. A declared self contact (``[[a, a]]``) keeps its parts
    apart to the penalty's penetration, so only a deeper overlap reaches the threshold, as for
    any declared pair. Without the beam's model (a response not from the solver) no arc length:
    unchecked."""
    if i >= len(resp.beam_models):
        return worst
    from flexopt.fea.body_contact import default_skip_mm  # the self-contact pairs' rule

    model = resp.beam_models[i]
    area, where = self_overlap(pts, t, model.s_nodes, default_skip_mm(model))
    k = int(np.argmax(area))
    if area[k] <= max(worst[0], INTERFERENCE_MM2):
        return worst
    why = (
        "self contact declared: deeper than the contact's penetration"
        if declared
        else "self contact not declared"
    )
    return (
        float(area[k]),
        f"{at[k]}: beam {name} passes through itself (s = {where[k, 0]:.4g} mm and "
        f"s = {where[k, 1]:.4g} mm along it; {area[k]:.3g} mm²; {why})",
    )


def interference(
    mech: Mechanism,
    outline: MechanismOutline,
    ground_outlines_mm: Sequence[Sequence[Sequence[float]]],
    responses: Mapping[str, MechanismResponse],
    controls: Mapping[str, str],
) -> dict[str, Any]:
    """Interference and clearance of the deformed parts at every converged row of every case.

    Parts: every beam of ``mech`` as a band of its thickness along its deformed centreline (the
    beams as made, ``outline.beams``), every body with an outline at its pose, the grounded
    ends' pads (``outline.pads``) and ``ground_outlines_mm`` (fixed, each (k, 2) mm). A beam's
    roots (a disc about each held end: its fillets) are left out, and parts joined there (a
    beam end and its body, its pad or the beam end it is joined to; a grounded end and the
    ground outlines) are checked only for overlap elsewhere; every other pair also for its
    distance. Each pair is checked at all rows of a case at once (shapely's array functions).
    Every beam is also checked against itself for overlap (:func:`self_overlap`, its parts
    farther apart along it than the self contact's skip; a beam declared with itself in
    ``mech.beam_contacts`` as a declared pair: only an overlap deeper than the penalty's
    penetration reaches the threshold); its distance to itself is not a clearance.
    ``controls`` maps each case to its drive control (the rows are named by their drive).

    Returns
    -------
    dict — ``min_clearance_mm`` (float | None: the smallest distance between parts that are not
    joined, over every row; None with fewer than two such parts), ``clearance_at`` (text: case,
    row, drive and the parts), ``interference_mm2`` (largest overlap area of any row, mm^2, 0
    when none) and ``interference_at`` (text, "" when none).
    """
    import shapely
    from shapely.geometry import Polygon

    made = outline.beams
    body_names = [b.name for b in mech.bodies]
    joints = [(j.a, j.b) for j in mech.joints]
    held = {(a.beam, a.end): a.to for a in attachments(joints, body_names)}
    grounded_bodies = {a for a, b in joints if b == "ground" and a in body_names}
    fixed = [(f"pad {k}", g) for k, g in outline.pads.items()]
    fixed += [(f"ground outline [{k}]", Polygon(np.array(o, dtype=float)))
              for k, o in enumerate(ground_outlines_mm)]  # fmt: skip
    best: tuple[float, str] = (math.inf, "")
    worst: tuple[float, str] = (0.0, "")
    for case, resp in responses.items():
        rows = np.flatnonzero(np.asarray(resp.converged, dtype=bool))
        if rows.size == 0:
            continue
        control = controls[case]
        drive = np.asarray(resp.drive, dtype=float)
        if control == "rotation":
            drive = np.degrees(drive)

        unit = DRIVE_UNIT[control]
        at = [f"load case {case}, row {r} (drive {drive[r]:.4g} {unit})" for r in rows]
        parts: list[tuple[str, Any, set[str]]] = []  # label, (rows,) shapes, what it is joined to
        for i, beam in enumerate(mech.beams):
            name = beam.name
            pts = np.asarray(resp.shapes_mm[i], dtype=float)[rows]
            t = np.asarray(resp.thickness_at_nodes_mm[i], dtype=float)
            free = deformed_bands(pts, t)
            joined: set[str] = set()
            for end, k in (("start", 0), ("end", -1)):
                to = held.get((name, end))
                if to is None:
                    continue
                junction = made[name].start if end == "start" else made[name].end
                radius = 0.5 * t[k] + 1.5 * junction.fillet_mm + 1e-3
                if to not in ("ground", *body_names):  # another beam's end
                    radius = 2.0 * t[k]
                    joined.add(f"beam {to.rsplit('.', 1)[0]}")
                elif to == "ground":  # its own pad, and the ground outlines holding it
                    joined |= {f"pad {name}.{end}"} | {
                        label for label, _ in fixed if label.startswith("ground outline")
                    }
                else:
                    joined.add(f"body {to}")
                discs = shapely.buffer(shapely.points(pts[:, k]), radius, quad_segs=8)
                free = shapely.difference(free, discs)
            # a declared contact pair touches by design (modelled): overlap is still checked
            joined |= {f"{'body' if o in body_names else 'beam'} {o}" for a, b in mech.beam_contacts
                       if name in (a, b) for o in (b if a == name else a,)}  # fmt: skip
            parts.append((f"beam {name}", free, joined))
            worst = _self_worst(
                worst, resp, i, name, pts, t, at, (name, name) in mech.beam_contacts
            )
        for k_body, body in enumerate(mech.bodies):
            if body.outline_mm is None:
                continue
            pose = np.asarray(resp.body_poses, dtype=float)[rows, k_body]  # (R, 3)
            c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
            rel = np.array(body.outline_mm, dtype=float) - np.array(body.ref_mm, dtype=float)
            xy = np.stack(
                [c[:, None] * rel[:, 0] - s[:, None] * rel[:, 1] + pose[:, :1],
                 s[:, None] * rel[:, 0] + c[:, None] * rel[:, 1] + pose[:, 1:2]],
                axis=2,
            )  # fmt: skip
            joined = {label for label, _ in fixed} if body.name in grounded_bodies else set()
            joined |= {f"body {b if a == body.name else a}" for a, b in mech.beam_contacts
                       if body.name in (a, b) and {a, b} <= set(body_names)}  # fmt: skip
            parts.append((f"body {body.name}", shapely.polygons(xy), joined))
        everything = [*parts, *((label, g, set()) for label, g in fixed)]
        for i, (la, ga, ja) in enumerate(parts):
            for lb, gb, jb in everything[i + 1 :]:
                area = np.zeros(rows.size)
                hit = shapely.intersects(ga, gb)
                if hit.any():
                    gb_hit = gb[hit] if isinstance(gb, np.ndarray) else gb
                    area[hit] = shapely.area(shapely.intersection(ga[hit], gb_hit))
                k = int(np.argmax(area))
                if area[k] > max(worst[0], INTERFERENCE_MM2):
                    worst = (float(area[k]), f"{at[k]}: {la} passes through {lb} "
                             f"({area[k]:.3g} mm²)")  # fmt: skip
                if lb not in ja and la not in jb:
                    gap = shapely.distance(ga, gb)
                    k = int(np.argmin(gap))
                    if gap[k] < best[0]:
                        best = (float(gap[k]), f"{at[k]}: {la} and {lb}")
    return {
        "min_clearance_mm": None if not math.isfinite(best[0]) else best[0],
        "clearance_at": best[1],
        "interference_mm2": worst[0],
        "interference_at": worst[1],
    }
