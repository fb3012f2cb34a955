"""Planar outline of a compliant mechanism given as data: beams, rigid bodies, ground pads.

A generic mechanism (the ``mechanism`` study kind) is a set of named beams, each a centreline
polyline with an in-plane thickness per point (linear in arc length between points), named rigid
bodies given by their outlines, and attachments of beam ends to the ground, to a body or to
another beam's end. This module turns that data into the printable part:

* :func:`curve_points` generates a centreline (straight, cosine-shaped or circular arc) between
  two points, so a pre-curved beam is a few numbers (its rise) rather than a list of points;
* :func:`beam_band` thickens one centreline to its local thickness (a union of one trapezoid per
  segment and a disc of the local thickness at every inner point, so the band has no gaps or
  self-overlaps at bends);
* :func:`mechanism_outline` unites the bands with the bodies and with a clamping pad at every
  grounded beam end, and refuses geometry that cannot be printed or is not the mechanism the
  solver analyses (:class:`~geometry.errors.GeometryError` with the reason): a beam thinner than
  the printable minimum, two beams that cross or overlap where they are not joined, a beam that
  runs through a body it is not attached to, a part that falls into several pieces, and any wall
  thinner than the minimum (:func:`geometry.solid.thin_feature_at`).

Units: mm. No FE here: the solver reads the same centrelines and thicknesses.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import shapely
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.solid import thin_feature_at
from shapely.geometry import LineString, MultiPolygon, Point, Polygon
from shapely.geometry.base import BaseGeometry

__all__ = [
    "Attachment",
    "BeamShape",
    "BodyShape",
    "MechanismOutline",
    "beam_band",
    "curve_points",
    "end_pad",
    "mechanism_outline",
]

#: Segments per quarter circle of the discs at inner points: 8 keeps the polygonal disc within
#: 2 % of its radius, far below a printer's resolution at beam thicknesses of ~1 mm.
_QUAD_SEGS = 8
#: Overlap area (mm^2) below which two shapes only touch (round-off of the unions).
_AREA_TOL_MM2 = 1e-4


@dataclass(frozen=True)
class BeamShape:
    """One beam's centreline and thickness.

    Attributes
    ----------
    name : str
    points_mm : (n, 2) float, mm — centreline from the start end to the end end, n >= 2.
    thickness_mm : (n,) float, mm — in-plane thickness at each point (linear in between).
    """

    name: str
    points_mm: np.ndarray
    thickness_mm: np.ndarray

    def __post_init__(self) -> None:
        p = np.asarray(self.points_mm, dtype=float)
        t = np.asarray(self.thickness_mm, dtype=float)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2:
            raise GeometryError(f"beam '{self.name}': points_mm needs at least 2 [x, y] points")
        if t.shape != (len(p),):
            raise GeometryError(
                f"beam '{self.name}': {len(p)} points but {t.size} thickness values; give one "
                "per point"
            )
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(t))):
            raise GeometryError(f"beam '{self.name}': points and thicknesses must be finite")
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        if np.any(seg <= 1e-9):
            k = int(np.argmax(seg <= 1e-9))
            raise GeometryError(
                f"beam '{self.name}': points [{k}] and [{k + 1}] coincide; remove the duplicate"
            )
        if np.any(t <= 0):
            k = int(np.argmax(t <= 0))
            raise GeometryError(f"beam '{self.name}': thickness [{k}] = {t[k]:g} must be > 0 mm")
        object.__setattr__(self, "points_mm", p)
        object.__setattr__(self, "thickness_mm", t)


@dataclass(frozen=True)
class BodyShape:
    """A rigid body: its outline, (k, 2) float, mm (closed implicitly, k >= 3)."""

    name: str
    outline_mm: np.ndarray

    def __post_init__(self) -> None:
        o = np.asarray(self.outline_mm, dtype=float)
        if o.ndim != 2 or o.shape[1] != 2 or len(o) < 3:
            raise GeometryError(f"body '{self.name}': outline_mm needs at least 3 [x, y] points")
        object.__setattr__(self, "outline_mm", o)

    def polygon(self) -> Polygon:
        poly = Polygon(self.outline_mm)
        if not poly.is_valid:
            raise GeometryError(
                f"body '{self.name}': its outline crosses itself "
                f"({shapely.is_valid_reason(poly)}); list the corners in order around it"
            )
        if not poly.area > 0:
            raise GeometryError(f"body '{self.name}': its outline encloses no area")
        return poly


@dataclass(frozen=True)
class Attachment:
    """A beam end and what holds it: ``"ground"``, a body's name, or another beam's end
    (``"beam.start"`` / ``"beam.end"``)."""

    beam: str
    end: Literal["start", "end"]
    to: str


@dataclass(frozen=True)
class MechanismOutline:
    """The printable part.

    Attributes
    ----------
    polygon : shapely Polygon, mm — the whole part (one connected body).
    bands : name -> Polygon — each beam thickened.
    pads : "beam.end" -> Polygon — the clamping pad at each grounded end.
    bodies : name -> Polygon.
    area_mm2 : float, mm^2.
    """

    polygon: Polygon
    bands: dict[str, Polygon] = field(default_factory=dict)
    pads: dict[str, Polygon] = field(default_factory=dict)
    bodies: dict[str, Polygon] = field(default_factory=dict)

    @property
    def area_mm2(self) -> float:
        return float(self.polygon.area)


# --------------------------------------------------------------------------------------------
# Centrelines


def curve_points(
    start_mm: Sequence[float],
    end_mm: Sequence[float],
    shape: Literal["straight", "cosine", "arc", "half_cosine"] = "straight",
    rise_mm: float = 0.0,
    points: int = 21,
) -> np.ndarray:
    """A centreline between two points, (points, 2) float, mm.

    Parameters
    ----------
    start_mm, end_mm : (2,) mm — the ends.
    shape : straight; ``cosine``: the first buckling mode of a clamped-clamped beam,
        ``w(s) = rise/2 (1 - cos(2 pi s / L))`` off the chord (the classic pre-shaped bistable
        beam, slope zero at both ends); ``arc``: a circular arc whose mid-point lies ``rise``
        off the chord; ``half_cosine``: from start to end with x linear and y following half a
        cosine wave, ``y = y0 + (y1 - y0) (1 - cos(pi u)) / 2``, so the tangent is along x at both
        ends (half of a cosine-shaped clamped-clamped beam, ending on a shuttle at its apex;
        ``rise_mm`` is not used: the rise is ``y1 - y0``).
    rise_mm : mm — the largest distance from the chord, to the left of start→end when > 0.
    points : int — at least 2 (a straight beam needs only 2).

    Raises
    ------
    GeometryError
        For coincident ends, fewer than 2 points or an arc rise of half the chord or more.
    """
    a = np.asarray(start_mm, dtype=float)
    b = np.asarray(end_mm, dtype=float)
    chord = b - a
    length = float(np.hypot(*chord))
    if not length > 1e-9:
        raise GeometryError("the curve's start_mm and end_mm coincide; move one of them")
    if points < 2:
        raise GeometryError(f"points = {points}: a centreline needs at least 2")
    u = np.linspace(0.0, 1.0, points)
    normal = np.array([-chord[1], chord[0]]) / length
    if shape == "half_cosine":
        if abs(chord[0]) < 1e-9:
            raise GeometryError("a half_cosine needs start and end apart in x; it runs along x")
        xy = np.empty((points, 2))
        xy[:, 0] = a[0] + u * chord[0]
        xy[:, 1] = a[1] + chord[1] * 0.5 * (1.0 - np.cos(np.pi * u))
        return xy
    if shape == "straight" or rise_mm == 0.0:
        offset = np.zeros_like(u)
    elif shape == "cosine":
        offset = 0.5 * rise_mm * (1.0 - np.cos(2.0 * np.pi * u))
    elif shape == "arc":
        h = abs(rise_mm)
        if not h < 0.5 * length:
            raise GeometryError(
                f"an arc of rise {rise_mm:g} mm over a chord of {length:g} mm is more than a "
                "half circle; keep |rise_mm| below half the chord"
            )
        radius = (h**2 + 0.25 * length**2) / (2.0 * h)
        half_angle = np.arcsin(0.5 * length / radius)
        angle = (2.0 * u - 1.0) * half_angle
        # distance from the chord of a point on the arc at angle from the apex
        offset = np.sign(rise_mm) * (radius * np.cos(angle) - (radius - h))
        along = 0.5 + radius * np.sin(angle) / length
        return a + np.outer(along, chord) + np.outer(offset, normal)
    else:
        raise GeometryError(f"unknown shape '{shape}'; use straight, cosine, arc or half_cosine")
    return a + np.outer(u, chord) + np.outer(offset, normal)


# --------------------------------------------------------------------------------------------
# Bands and pads


def beam_band(beam: BeamShape) -> Polygon:
    """The beam thickened along its centreline to its local thickness, mm.

    One trapezoid per segment (perpendicular to it, of the end thicknesses) and a disc of the
    local thickness at every inner point: at a bend the trapezoids leave a wedge open on the
    outside and overlap on the inside; the disc closes the wedge exactly as the material of a
    smoothly bent beam would.
    """
    p, t = beam.points_mm, beam.thickness_mm
    pieces: list[BaseGeometry] = []
    for k in range(len(p) - 1):
        d = p[k + 1] - p[k]
        n = np.array([-d[1], d[0]]) / np.hypot(*d)
        pieces.append(
            Polygon(
                [
                    p[k] + 0.5 * t[k] * n,
                    p[k + 1] + 0.5 * t[k + 1] * n,
                    p[k + 1] - 0.5 * t[k + 1] * n,
                    p[k] - 0.5 * t[k] * n,
                ]
            )
        )
    for k in range(1, len(p) - 1):
        pieces.append(Point(p[k]).buffer(0.5 * t[k], quad_segs=_QUAD_SEGS))
    band = shapely.union_all(pieces)
    if isinstance(band, MultiPolygon) or not isinstance(band, Polygon):
        raise GeometryError(f"beam '{beam.name}': its band is not one piece; check its points")
    return band


def end_pad(
    beam: BeamShape, end: Literal["start", "end"], length_mm: float, thickness_mm: float
) -> Polygon:
    """A clamping pad at a beam end: a rectangle ``length_mm`` long beyond the end along the
    end tangent, ``max(thickness_mm, end thickness)`` thick. It reaches half the end thickness
    back into the beam: a pad face collinear with the beam's end face leaves GEOS a zero-width
    spike in the union."""
    p = beam.points_mm
    if end == "start":
        tip, tangent, t = p[0], p[0] - p[1], beam.thickness_mm[0]
    else:
        tip, tangent, t = p[-1], p[-1] - p[-2], beam.thickness_mm[-1]
    tangent = tangent / np.hypot(*tangent)
    n = np.array([-tangent[1], tangent[0]]) * 0.5 * max(thickness_mm, t)
    far = tip + tangent * length_mm
    near = tip - tangent * 0.5 * t
    return Polygon([near - n, far - n, far + n, near + n])


def _where(geom: BaseGeometry) -> str:
    x, y = geom.representative_point().coords[0]
    return f"({x:.3g}, {y:.3g}) mm"


# --------------------------------------------------------------------------------------------
# The whole part


def mechanism_outline(
    beams: Sequence[BeamShape],
    bodies: Sequence[BodyShape] = (),
    attachments: Sequence[Attachment] = (),
    min_feature_mm: float = 0.8,
    pad_length_mm: float = 6.0,
    pad_thickness_mm: float = 4.0,
    ground_outlines_mm: Sequence[np.ndarray] = (),
    check_walls: bool = True,
) -> MechanismOutline:
    """The outline of the whole part, checked printable and as analysed.

    Parameters
    ----------
    beams, bodies : the mechanism's parts (mm).
    attachments : how beam ends are held; a grounded end gets a pad (``pad_length_mm`` x
        ``pad_thickness_mm``, mm).
    min_feature_mm : mm — thinnest printable wall.
    ground_outlines_mm : optional fixed frame outlines (k, 2) mm, printed with the part (a base
        that ties the grounded pads together); they take no part in the analysis.
    check_walls : also run the morphological thin-wall test on the union (a few buffers).

    Returns
    -------
    MechanismOutline

    Raises
    ------
    GeometryError
        With the reason and where: a beam thinner than ``min_feature_mm``; two beams crossing
        or overlapping where they are not joined; a beam running into a body it is not attached
        to; a part in several pieces (naming them); a wall thinner than the minimum.
    """
    for beam in beams:
        k = int(np.argmin(beam.thickness_mm))
        if beam.thickness_mm[k] < min_feature_mm:
            raise GeometryError(
                f"beam '{beam.name}' is {beam.thickness_mm[k]:.3g} mm thick at point [{k}], "
                f"thinner than the printable minimum {min_feature_mm:g} mm; thicken it or lower "
                "min_feature_mm"
            )
        if not LineString(beam.points_mm).is_simple:
            raise GeometryError(f"beam '{beam.name}' crosses itself; reorder or move its points")
    by_name = {b.name: b for b in beams}
    bands = {b.name: beam_band(b) for b in beams}
    body_polys = {b.name: b.polygon() for b in bodies}
    pads: dict[str, Polygon] = {}
    anchor: dict[tuple[str, str], str] = {}  # (beam, end) -> what holds it
    joints_in: list[Polygon] = []  # beam ends carried into the bodies they are attached to
    for a in attachments:
        beam = by_name.get(a.beam)
        if beam is None:
            raise GeometryError(f"an attachment names beam '{a.beam}', which does not exist")
        if a.to == "ground":
            pads[f"{a.beam}.{a.end}"] = end_pad(beam, a.end, pad_length_mm, pad_thickness_mm)
            anchor[(a.beam, a.end)] = "ground"
        elif a.to in body_polys:
            anchor[(a.beam, a.end)] = f"body:{a.to}"
            # the end carried on into the body by one thickness: an end face flush with the
            # body's edge leaves GEOS a zero-width seam that reads as a thin wall
            t_end = float(beam.thickness_mm[0 if a.end == "start" else -1])
            joints_in.append(end_pad(beam, a.end, t_end, t_end))
        else:  # another beam's end: both ends share one joint
            other = a.to.rsplit(".", 1)
            key = "joint:" + "|".join(sorted([f"{a.beam}.{a.end}", a.to]))
            anchor[(a.beam, a.end)] = key
            if len(other) == 2:
                anchor.setdefault((other[0], other[1]), key)
    frames = [Polygon(np.asarray(o, dtype=float)) for o in ground_outlines_mm]
    # Two beam ends joined to each other meet like an inner point of one beam: a disc of the
    # joint's thickness fills the notch their square ends would leave (a neck the solver, which
    # joins the sections rigidly, does not have).
    joints: list[Polygon] = []
    for a in attachments:
        if a.to != "ground" and a.to not in body_polys:
            b = by_name[a.beam]
            i = 0 if a.end == "start" else -1
            joints.append(
                Point(b.points_mm[i]).buffer(0.5 * float(b.thickness_mm[i]), quad_segs=_QUAD_SEGS)
            )

    # Joined ends may overlap near their joint; anything else that overlaps is a crossing.
    def end_disc(name: str, end: str) -> Polygon:
        b = by_name[name]
        i = 0 if end == "start" else -1
        return Point(b.points_mm[i]).buffer(2.0 * float(b.thickness_mm[i]), quad_segs=_QUAD_SEGS)

    allowed_base = shapely.union_all([*body_polys.values(), *pads.values(), *frames])
    names = list(bands)
    for i, a_name in enumerate(names):
        for b_name in names[i + 1 :]:
            overlap = bands[a_name].intersection(bands[b_name])
            if overlap.area <= _AREA_TOL_MM2:
                continue
            joined = [
                end_disc(n, e)
                for n, e in ((a_name, "start"), (a_name, "end"), (b_name, "start"), (b_name, "end"))
                if (n, e) in anchor
                and any(
                    anchor[(n, e)] == anchor.get((m, f))
                    for m, f in (
                        (a_name, "start"),
                        (a_name, "end"),
                        (b_name, "start"),
                        (b_name, "end"),
                    )
                    if m != n
                )
            ]
            rest = overlap.difference(shapely.union_all([allowed_base, *joined]))
            if rest.area > _AREA_TOL_MM2:
                raise GeometryError(
                    f"beams '{a_name}' and '{b_name}' cross or overlap near {_where(rest)} where "
                    "they are not joined; move them apart (or join their ends)"
                )
    for b_name, band in bands.items():
        attached = {anchor.get((b_name, "start")), anchor.get((b_name, "end"))}
        for body_name, poly in body_polys.items():
            if f"body:{body_name}" in attached:
                continue
            hit = band.intersection(poly)
            if hit.area > _AREA_TOL_MM2:
                raise GeometryError(
                    f"beam '{b_name}' runs into body '{body_name}' near {_where(hit)}, which it is "
                    "not attached to; move the beam or attach it"
                )

    labelled: list[tuple[str, BaseGeometry]] = [
        *((f"beam {n}", g) for n, g in bands.items()),
        *((f"body {n}", g) for n, g in body_polys.items()),
        *((f"pad {n}", g) for n, g in pads.items()),
        *((f"frame [{k}]", g) for k, g in enumerate(frames)),
        *(("joint", g) for g in joints),
        *(("joint", g) for g in joints_in),
    ]
    union = shapely.union_all([g for _, g in labelled])
    if isinstance(union, MultiPolygon):
        pieces = sorted(union.geoms, key=lambda g: -g.area)
        groups = [
            ", ".join(label for label, g in labelled if g.intersects(piece)) for piece in pieces
        ]
        shown = "; ".join(f"{{{g}}}" for g in groups[:4])
        raise GeometryError(
            f"the part falls into {len(pieces)} separate pieces: {shown}; join them (attach the "
            "beam ends to the bodies they should hold, or add a ground frame)"
        )
    if not isinstance(union, Polygon) or union.is_empty:
        raise GeometryError("the mechanism has no material; give beams or bodies")
    # Snap to a 1e-6 mm grid: drops the zero-width spikes and slivers that unions of touching
    # edges can leave (they would read as thin walls), far below any printer's resolution.
    polygon = shapely.set_precision(union, 1e-6)
    if not isinstance(polygon, Polygon) or not polygon.is_valid:
        polygon = shapely.make_valid(union)
    if check_walls:
        try:
            spot = thin_feature_at(polygon, min_feature_mm)
        except shapely.errors.GEOSException as exc:  # a degenerate union GEOS cannot buffer
            raise GeometryError(f"the outline cannot be checked for thin walls ({exc})") from exc
        if spot is not None:
            raise GeometryError(
                f"a wall near ({spot[0]:.3g}, {spot[1]:.3g}) mm is thinner than the printable "
                f"minimum {min_feature_mm:g} mm (a sliver where parts meet, or a thin body); "
                "thicken it or change the angle at which the parts meet"
            )
    return MechanismOutline(polygon, bands, pads, body_polys)


def beams_from_mapping(
    beams: Mapping[str, tuple[np.ndarray, np.ndarray]],
) -> list[BeamShape]:
    """``{name: (points_mm (n, 2), thickness_mm (n,))}`` → BeamShapes (a convenience)."""
    return [BeamShape(n, p, t) for n, (p, t) in beams.items()]
