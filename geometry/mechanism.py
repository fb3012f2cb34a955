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

import math
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
    "FILLET_CHORDS",
    "AsMadeBeam",
    "Attachment",
    "BeamShape",
    "BodyShape",
    "EndJunction",
    "MechanismOutline",
    "as_made_beams",
    "as_made_info",
    "attachments",
    "beam_band",
    "curvature_as_made",
    "end_ref",
    "max_turn_deg",
    "shoulder_kt",
    "curve_points",
    "end_pad",
    "mechanism_outline",
]

#: Segments per quarter circle of the discs at inner points: 8 keeps the polygonal disc within
#: 2 % of its radius, far below a printer's resolution at beam thicknesses of ~1 mm.
_QUAD_SEGS = 8
#: Overlap area (mm^2) below which two shapes only touch (round-off of the unions).
_AREA_TOL_MM2 = 1e-4
#: How far a pad overlaps the beam it clamps, mm: far below any printer's resolution, and enough
#: that the union of pad and beam has no collinear faces.
_PAD_OVERLAP_MM = 1e-3
#: Chords of a fillet's quarter arc in a beam's flare (the arc is within r (1 - cos 7.5 deg) =
#: 0.9 % of r of them, and each chord is one beam element).
FILLET_CHORDS = 6
#: Largest angle between a beam and the normal of the body edge it leaves, deg: the fillets and
#: the shoulder's stress-concentration factor are those of a square shoulder.
_MAX_JUNCTION_DEG = 15.0
#: Shoulder height, in fillet radii, that stands for a body (a shoulder of unbounded height): the
#: fit of :func:`shoulder_kt` holds to h/r = 20, and Kt has levelled off there (it changes by
#: less than 0.4 % from h/r = 10 to 20 for r/d from 0.05 to 2).
_BODY_SHOULDER_RADII = 20.0


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
    beams : name -> AsMadeBeam — the beams as made, the ones the solver must analyse (clipped at
        the bodies they are attached to, flared into their roots' fillets), with what was
        clipped and filleted and the roots' stress-concentration factors.
    area_mm2 : float, mm^2.
    """

    polygon: Polygon
    bands: dict[str, Polygon] = field(default_factory=dict)
    pads: dict[str, Polygon] = field(default_factory=dict)
    bodies: dict[str, Polygon] = field(default_factory=dict)
    beams: dict[str, AsMadeBeam] = field(default_factory=dict)

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
    d = np.diff(p, axis=0)
    n_seg = np.column_stack([-d[:, 1], d[:, 0]]) / np.hypot(d[:, 0], d[:, 1])[:, None]
    a, b = d[:-1], d[1:]
    cross = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    # a straight run (a fillet's flare): no disc (it would bulge beyond a thickness that changes
    # there), and both trapezoids take the same normal at the point, so that they share their
    # edge exactly (normals differing by round-off would leave them touching at one point)
    straight = np.concatenate(
        [
            [False],
            (cross <= 1e-12 * np.hypot(*a.T) * np.hypot(*b.T)) & (np.sum(a * b, 1) > 0),
            [False],
        ]
    )
    n_pt = np.vstack([n_seg[:1], n_seg[:-1] + n_seg[1:], n_seg[-1:]])
    n_pt /= np.hypot(n_pt[:, 0], n_pt[:, 1])[:, None]
    pieces: list[BaseGeometry] = []
    for k in range(len(p) - 1):
        n0 = n_pt[k] if straight[k] else n_seg[k]
        n1 = n_pt[k + 1] if straight[k + 1] else n_seg[k]
        pieces.append(
            Polygon(
                [
                    p[k] + 0.5 * t[k] * n0,
                    p[k + 1] + 0.5 * t[k + 1] * n1,
                    p[k + 1] - 0.5 * t[k + 1] * n1,
                    p[k] - 0.5 * t[k] * n0,
                ]
            )
        )
    for k in range(1, len(p) - 1):
        if not straight[k]:
            pieces.append(Point(p[k]).buffer(0.5 * t[k], quad_segs=_QUAD_SEGS))
    band = shapely.union_all(pieces)
    if isinstance(band, MultiPolygon) or not isinstance(band, Polygon):
        raise GeometryError(f"beam '{beam.name}': its band is not one piece; check its points")
    return band


def end_pad(
    beam: BeamShape, end: Literal["start", "end"], length_mm: float, thickness_mm: float
) -> Polygon:
    """A clamping pad at a beam end: a rectangle ``length_mm`` long beyond the end along the
    end tangent, ``max(thickness_mm, end thickness)`` thick, from the end's face on: it does not
    reach into the beam, so the printed beam is as long as the analysed one (the flexible length
    ends where the pad begins). It overlaps the beam by ``_PAD_OVERLAP_MM`` only, so that the
    union has no collinear faces (which can leave GEOS a zero-width spike)."""
    p = beam.points_mm
    if end == "start":
        tip, tangent, t = p[0], p[0] - p[1], beam.thickness_mm[0]
    else:
        tip, tangent, t = p[-1], p[-1] - p[-2], beam.thickness_mm[-1]
    tangent = tangent / np.hypot(*tangent)
    n = np.array([-tangent[1], tangent[0]]) * 0.5 * max(thickness_mm, t)
    far = tip + tangent * length_mm
    near = tip - tangent * min(_PAD_OVERLAP_MM, 0.5 * t)
    return Polygon([near - n, far - n, far + n, near + n])


def _root_disc(beam: BeamShape, made: AsMadeBeam, end: str) -> Polygon:
    """A disc about a beam end that holds its root (fillets and a face up to 15 deg off the
    edge it stands on), mm."""
    i = 0 if end == "start" else -1
    junction = made.start if end == "start" else made.end
    radius = 0.5 * float(beam.thickness_mm[i]) + 1.5 * junction.fillet_mm + 1e-3
    return Point(beam.points_mm[i]).buffer(radius, quad_segs=_QUAD_SEGS)


def _where(geom: BaseGeometry) -> str:
    x, y = geom.representative_point().coords[0]
    return f"({x:.3g}, {y:.3g}) mm"


# --------------------------------------------------------------------------------------------
# The beams as made: clipped at the bodies they enter, flared into fillets at their roots


def shoulder_kt(wide_mm: float, narrow_mm: float, radius_mm: float) -> float:
    """Elastic stress-concentration factor of a filleted square shoulder in in-plane bending.

    A bar of thickness ``narrow_mm`` (d) enters a wider part of thickness ``wide_mm`` (D) with a
    fillet of ``radius_mm`` (r) on both sides; the peak stress at the fillet is ``Kt`` times the
    nominal bending stress ``6 M / (b d^2)`` of the narrow section at the shoulder. The fit of
    Young & Budynas, *Roark's Formulas for Stress and Strain*, 7th ed., Table 17.1, "square
    shoulder with fillet in a member of rectangular section", in-plane bending (a fit to the
    flat-bar shoulder-fillet data collected in Pilkey & Pilkey, *Peterson's Stress
    Concentration Factors*, 3rd ed., ch. 3), with the step height ``h = (D - d) / 2``::

        Kt = C1 + C2 (2h/D) + C3 (2h/D)^2 + C4 (2h/D)^3
        0.1 <= h/r <= 2:  C1 =  1.007 + 1.000 sqrt(h/r) - 0.031 h/r
                          C2 = -0.270 - 2.404 sqrt(h/r) + 0.749 h/r
                          C3 =  0.677 + 1.133 sqrt(h/r) - 0.904 h/r
                          C4 = -0.414 + 0.271 sqrt(h/r) + 0.186 h/r
        2 <= h/r <= 20:   C1 =  1.042 + 0.982 sqrt(h/r) - 0.036 h/r
                          C2 = -3.599 + 1.619 sqrt(h/r) - 0.431 h/r
                          C3 =  6.084 - 5.607 sqrt(h/r) + 1.158 h/r
                          C4 = -2.527 + 3.006 sqrt(h/r) - 0.691 h/r

    Outside the fit's range: a shoulder lower than 0.1 r has Kt 1 to within the fit's own error
    (1.0 returned for h = 0, no shoulder), and h/r is capped at 20 (a body: Kt changes by less
    than 0.4 % between h/r = 10 and 20 for r/d from 0.05 to 2).

    Parameters
    ----------
    wide_mm, narrow_mm, radius_mm : float, mm.

    Returns
    -------
    float — Kt >= 1.
    """
    if not (radius_mm > 0 and narrow_mm > 0):
        raise GeometryError(f"a fillet of {radius_mm:g} mm on a {narrow_mm:g} mm beam has no Kt")
    h = 0.5 * (wide_mm - narrow_mm)
    if h <= 0:
        return 1.0
    h = min(h, 20.0 * radius_mm)
    q = max(h / radius_mm, 0.1)
    wide = narrow_mm + 2.0 * h
    root = math.sqrt(q)
    if q <= 2.0:
        c = (
            1.007 + 1.000 * root - 0.031 * q,
            -0.270 - 2.404 * root + 0.749 * q,
            0.677 + 1.133 * root - 0.904 * q,
            -0.414 + 0.271 * root + 0.186 * q,
        )
    else:
        c = (
            1.042 + 0.982 * root - 0.036 * q,
            -3.599 + 1.619 * root - 0.431 * q,
            6.084 - 5.607 * root + 1.158 * q,
            -2.527 + 3.006 * root - 0.691 * q,
        )
    x = 2.0 * h / wide
    return max(1.0, c[0] + c[1] * x + c[2] * x**2 + c[3] * x**3)


@dataclass(frozen=True)
class EndJunction:
    """How one beam end meets what holds it, as made.

    Attributes
    ----------
    clipped_mm : float, mm — centreline length inside the body the end is attached to: rigid,
        part of the body; the flexible beam starts at the body's outline.
    fillet_mm : float, mm — radius of the fillets where the beam meets a wider pad or a body
        (0: no shoulder, e.g. a joint with another beam end).
    kt : float — stress-concentration factor of that filleted shoulder (:func:`shoulder_kt`;
        1 without one), to multiply the beam-model stress over ``root_mm`` with.
    root_mm : float, mm — arc length from the end over which ``kt`` applies: the fillet's flare
        up to its toe, where the beam has its own thickness (the nominal section).
    """

    clipped_mm: float = 0.0
    fillet_mm: float = 0.0
    kt: float = 1.0
    root_mm: float = 0.0


@dataclass(frozen=True)
class AsMadeBeam:
    """A beam as made and analysed: ``shape`` is the flexible beam (clipped at the bodies it is
    attached to, its ends flared into the fillets), what the outline draws and the solver
    solves; ``start`` / ``end`` say what was clipped and filleted."""

    shape: BeamShape
    start: EndJunction
    end: EndJunction


def max_turn_deg(beam: BeamShape) -> tuple[float, int]:
    """The sharpest turn of the centreline (deg, 0 = straight on) and the point it is at."""
    d = np.diff(beam.points_mm, axis=0)
    if len(d) < 2:
        return 0.0, 0
    a, b = d[:-1], d[1:]
    turn = np.degrees(
        np.abs(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.sum(a * b, axis=1)))
    )
    k = int(np.argmax(turn))
    return float(turn[k]), k + 1


def _arc_lengths(p: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])


def _clip_in_body(beam: BeamShape, end: str, body: str, poly: Polygon) -> tuple[BeamShape, float]:
    """The beam without its length inside ``poly`` from ``end`` on, and that length (mm)."""
    p, t = beam.points_mm, beam.thickness_mm
    if end == "end":
        p, t = p[::-1], t[::-1]
    tip = Point(p[0])
    gap = poly.distance(tip)
    if gap > 1e-6:
        raise GeometryError(
            f"beam '{beam.name}' ends {gap:.3g} mm outside body '{body}', which its {end} is "
            "attached to; end it on the body's outline or inside it (the part inside is rigid)"
        )
    line = LineString(p)
    s = _arc_lengths(p)
    inside = line.intersection(poly)
    s_cut = 0.0
    for g in getattr(inside, "geoms", [inside]):
        if not g.is_empty and g.distance(tip) < 1e-9:
            s_cut = max(s_cut, *(line.project(Point(c)) for c in g.coords))
    if s_cut >= s[-1] - 1e-9:
        raise GeometryError(
            f"beam '{beam.name}' lies wholly inside body '{body}'; move it out of the body"
        )
    if s_cut > 1e-9:
        k = int(np.searchsorted(s, s_cut, side="right"))  # first point beyond the cut
        cut = np.interp(s_cut, s, p[:, 0]), np.interp(s_cut, s, p[:, 1])
        t_cut = float(np.interp(s_cut, s, t))
        keep = s[k:] - s_cut > 1e-6  # a point within 1 um of the cut is the cut
        p = np.vstack([np.array(cut)[None], p[k:][keep]])
        t = np.concatenate([[t_cut], t[k:][keep]])
        if len(p) < 2:
            raise GeometryError(
                f"beam '{beam.name}' lies wholly inside body '{body}'; move it out of the body"
            )
    if end == "end":
        p, t = p[::-1], t[::-1]
    return BeamShape(beam.name, p, t), float(s_cut)


def _junction_angle_deg(p: np.ndarray, poly: Polygon) -> float:
    """Angle (deg) between a beam leaving ``poly`` at ``p[0]`` along ``p[1] - p[0]`` and the
    outward normal of the body edge it leaves through."""
    ring = np.asarray(poly.exterior.coords)
    a, b = ring[:-1], ring[1:]
    ab = b - a
    w = np.clip(np.sum((p[0] - a) * ab, axis=1) / np.sum(ab * ab, axis=1), 0.0, 1.0)
    dist = np.hypot(*(a + w[:, None] * ab - p[0]).T)
    k = int(np.argmin(dist))
    tangent = ab[k] / np.hypot(*ab[k])
    normal = np.array([tangent[1], -tangent[0]])  # either way round: the angle is unsigned
    d = (p[1] - p[0]) / np.hypot(*(p[1] - p[0]))
    return float(np.degrees(np.arccos(np.clip(abs(d @ normal), -1.0, 1.0))))


def _flare(beam: BeamShape, end: str, radius_mm: float) -> BeamShape:
    """The beam with its ``end`` flared into two fillets of ``radius_mm`` (mm): points on the
    end segment at the arcs' chord ends, thickness ``t(s) + 2 (r - r sin psi)`` at arc length
    ``s = r (1 - cos psi)`` from the end, psi from 0 (the shoulder, ``t + 2 r``) to 90 deg (the
    toe, ``t``)."""
    p, t = beam.points_mm, beam.thickness_mm
    if end == "end":
        p, t = p[::-1], t[::-1]
    d = p[1] - p[0]
    seg = float(np.hypot(*d))
    d = d / seg
    psi = np.linspace(0.0, 0.5 * np.pi, FILLET_CHORDS + 1)
    s = radius_mm * (1.0 - np.cos(psi))
    t_own = t[0] + (t[1] - t[0]) * s / seg
    flare_t = t_own + 2.0 * radius_mm * (1.0 - np.sin(psi))
    pts = p[0] + np.outer(s, d)
    rest = slice(1, None) if seg - radius_mm > 1e-6 else slice(2, None)
    p2 = np.vstack([pts, p[rest]])
    t2 = np.concatenate([flare_t, t[rest]])
    if end == "end":
        p2, t2 = p2[::-1], t2[::-1]
    return BeamShape(beam.name, p2, t2)


def as_made_beams(
    beams: Sequence[BeamShape],
    bodies: Sequence[BodyShape] = (),
    attachments: Sequence[Attachment] = (),
    pad_thickness_mm: float = 4.0,
    fillet_mm: float = 1.0,
    max_corner_deg: float = 90.0,
    max_junction_deg: float = _MAX_JUNCTION_DEG,
) -> dict[str, AsMadeBeam]:
    """Each beam as it is printed and analysed, or a :class:`GeometryError` naming the key.

    * A corner of a centreline turning more than ``max_corner_deg`` is refused: the inner faces
      of its two legs would merge over more than half a thickness ``(t/2) tan(turn/2)`` from the
      point, a solid block that the beam model (which joins the legs at a point) does not see.
    * A beam end attached to a body with an outline is clipped at the outline: the length inside
      is rigid, part of the body (``clipped_mm``), and the flexible beam starts where the
      centreline leaves the body, attached rigidly there (the solver carries the new end with
      the body). An end outside its body, a beam wholly inside it, or one that leaves the body
      more than 15 deg off the edge's normal is refused.
    * Where a beam meets a wider pad (a grounded end) or a body, both edges get a fillet of
      radius ``r = min(fillet_mm, shoulder height, half the end segment)`` (for a pad the
      shoulder is ``(pad thickness - t) / 2``): the beam's end segment is flared along the two
      arcs (:func:`_flare`), so the outline and the solver have the same fillets, and the
      stress over the flare is multiplied by the shoulder's Kt (:func:`shoulder_kt`).

    Parameters
    ----------
    beams, bodies, attachments : the mechanism (mm).
    pad_thickness_mm : mm — thickness of a grounded end's pad.
    fillet_mm : mm — fillet radius at beam roots (> 0).
    max_corner_deg : deg — sharpest centreline corner accepted.
    max_junction_deg : deg — largest angle off square at which a beam may leave its body.

    Returns
    -------
    dict name -> AsMadeBeam
    """
    polys = {b.name: b.polygon() for b in bodies}
    held = {(a.beam, a.end): a.to for a in attachments}
    out = {}
    for beam in beams:
        turn, k = max_turn_deg(beam)
        if turn > max_corner_deg:
            x, y = beam.points_mm[k]
            raise GeometryError(
                f"beam '{beam.name}' turns {turn:.0f} deg at point [{k}] ({x:.3g}, {y:.3g}) mm, "
                f"sharper than {max_corner_deg:g} deg: the legs of its "
                f"{beam.thickness_mm[k]:.3g} mm section would merge into a block the beam model "
                "does not see; round the corner (points along an arc of radius at least the "
                "thickness, or a curve:)"
            )
        shape = beam
        clipped = {"start": 0.0, "end": 0.0}
        for end in ("start", "end"):
            to = held.get((beam.name, end))
            if to in polys:
                shape, clipped[end] = _clip_in_body(shape, end, to, polys[to])
        junction = {}
        for end in ("start", "end"):
            to = held.get((beam.name, end))
            p = shape.points_mm if end == "start" else shape.points_mm[::-1]
            t_end = float(shape.thickness_mm[0 if end == "start" else -1])
            seg = float(np.hypot(*(p[1] - p[0])))
            if to == "ground":
                shoulder = 0.5 * (max(pad_thickness_mm, t_end) - t_end)
            elif to in polys:
                angle = _junction_angle_deg(p, polys[to])
                if angle > max_junction_deg:
                    raise GeometryError(
                        f"beam '{beam.name}' leaves body '{to}' {angle:.0f} deg off square at "
                        f"({p[0][0]:.3g}, {p[0][1]:.3g}) mm; its root's fillets and stress "
                        f"factor are those of a square shoulder: turn the beam or the body's "
                        f"edge to within {_MAX_JUNCTION_DEG:g} deg of square"
                    )
                shoulder = math.inf
            else:
                shoulder = 0.0
            radius = min(fillet_mm, shoulder, 0.5 * seg)
            if radius <= 1e-6:
                junction[end] = EndJunction(clipped[end])
                continue
            wide = t_end + 2.0 * min(shoulder, _BODY_SHOULDER_RADII * radius)
            shape = _flare(shape, end, radius)
            junction[end] = EndJunction(
                clipped[end], radius, shoulder_kt(wide, t_end, radius), radius
            )
        out[beam.name] = AsMadeBeam(shape, junction["start"], junction["end"])
    return out


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
    fillet_mm: float = 1.0,
    max_corner_deg: float = 90.0,
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
    fillet_mm, max_corner_deg : the roots' fillet radius (mm) and the sharpest corner (deg)
        accepted: see :func:`as_made_beams`, which turns ``beams`` into the beams as made (clipped
        at the bodies they are attached to, flared into fillets); the outline is built from
        those, and ``MechanismOutline.beams`` holds them for the solver.

    Returns
    -------
    MechanismOutline

    Raises
    ------
    GeometryError
        With the reason and where: a beam thinner than ``min_feature_mm``; two beams crossing
        or overlapping where they are not joined; a beam running into a body other than at the
        end attached to it, or into a ground outline; a corner sharper than ``max_corner_deg``;
        a part in several pieces (naming them); a wall thinner than the minimum.
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
    if not {a.beam for a in attachments} <= {b.name for b in beams}:
        missing = sorted({a.beam for a in attachments} - {b.name for b in beams})
        raise GeometryError(f"an attachment names beam '{missing[0]}', which does not exist")
    made = as_made_beams(
        beams, bodies, attachments, pad_thickness_mm, fillet_mm, max_corner_deg, math.inf
    )
    originals = list(beams)
    beams = [made[b.name].shape for b in beams]
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
        for body_name, poly in [
            *body_polys.items(),
            *((f"[{k}]", f) for k, f in enumerate(frames)),
        ]:
            # the root of an end attached here (its fillets, a square face within 15 deg of the
            # edge) touches the body; anything else of the beam inside it is not analysed
            roots = [
                _root_disc(by_name[b_name], made[b_name], e)
                for e in ("start", "end")
                if anchor.get((b_name, e)) in (f"body:{body_name}", "ground")
            ]
            hit = band.intersection(poly)
            if roots and hit.area > _AREA_TOL_MM2:
                hit = hit.difference(shapely.union_all(roots))
            if hit.area > _AREA_TOL_MM2:
                what = (
                    f"ground outline {body_name}" if body_name.startswith("[") else
                    f"body '{body_name}'"
                )  # fmt: skip
                raise GeometryError(
                    f"beam '{b_name}' runs into {what} near {_where(hit)}, where it is not "
                    "attached (the solver would take that length as flexible); move the beam "
                    "out of it, or end the beam there and attach it"
                )

    # a beam that leaves its body off square, refused after the crossings (the likelier cause)
    as_made_beams(originals, bodies, attachments, pad_thickness_mm, fillet_mm, max_corner_deg)
    labelled: list[tuple[str, BaseGeometry]] = [
        *((f"beam {n}", g) for n, g in bands.items()),
        *((f"body {n}", g) for n, g in body_polys.items()),
        *((f"pad {n}", g) for n, g in pads.items()),
        *((f"frame [{k}]", g) for k, g in enumerate(frames)),
        *(("joint", g) for g in joints),
        *(("joint", g) for g in joints_in),
    ]
    union = shapely.union_all([g for _, g in labelled])
    if isinstance(union, MultiPolygon) and len(union.geoms) == 1:
        union = union.geoms[0]  # GEOS can return one polygon wrapped as a MultiPolygon
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
    # drop vertices in the middle of a straight edge (a fillet that reaches its pad's edge meets
    # the pad's side there): a CAD kernel merges such edges, and the STEP export counts faces
    simpler = shapely.simplify(polygon, 1e-9)
    if isinstance(simpler, Polygon) and simpler.is_valid:
        polygon = simpler
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
    return MechanismOutline(polygon, bands, pads, body_polys, made)


def beams_from_mapping(
    beams: Mapping[str, tuple[np.ndarray, np.ndarray]],
) -> list[BeamShape]:
    """``{name: (points_mm (n, 2), thickness_mm (n,))}`` → BeamShapes (a convenience)."""
    return [BeamShape(n, p, t) for n, (p, t) in beams.items()]


def end_ref(ref: str) -> tuple[str, str] | None:
    """``"beam.start"`` / ``"beam.end"`` → ``(beam, end)``; None for any other reference (a
    body, ``ground``)."""
    name, _, end = ref.rpartition(".")
    return (name, end) if name and end in ("start", "end") else None


def attachments(joints: Sequence[tuple[str, str]], bodies: Sequence[str]) -> list[Attachment]:
    """The beam ends the joints hold, each with what holds it.

    ``joints`` are ``(a, b)`` part references (``beam.start``, ``beam.end``, a body's name or
    ``ground``); a joint gives an attachment for each of its sides that is a beam end held by
    the ground, one of ``bodies`` or another beam end (in joint order, side ``a`` first)."""
    out = []
    for a, b in joints:
        for own, other in ((a, b), (b, a)):
            end = end_ref(own)
            if end is not None and (other == "ground" or other in bodies or end_ref(other)):
                out.append(Attachment(end[0], end[1], other))  # type: ignore[arg-type]
    return out


def curvature_as_made(
    name: str, curvature_per_mm: Sequence[float] | None, n_points: int, made: AsMadeBeam
) -> np.ndarray | None:
    """A beam's ``curvature_per_mm`` (one value per segment of its ``n_points`` drawn points,
    1/mm) for the beam as made: a straight (0) value for each chord of a flare added on a
    straight end segment; None when the beam is drawn without curvatures.

    Raises
    ------
    GeometryError
        For a clipped beam (a beam of exact arcs must end on the body's outline) or a flared
        curved end segment (the flare is laid along the chord).
    """
    if curvature_per_mm is None:
        return None
    curv = list(curvature_per_mm)
    if made.start.clipped_mm > 0 or made.end.clipped_mm > 0:
        raise GeometryError(
            f"beam '{name}' (geometry.beams.{name}.curvature_per_mm) runs into the body it is "
            "attached to; a beam of exact arcs must end on the body's outline"
        )
    for junction, k in ((made.start, 0), (made.end, -1)):
        if junction.fillet_mm > 0 and curv[k] != 0:
            raise GeometryError(
                f"beam '{name}' (geometry.beams.{name}.curvature_per_mm): its root fillet needs "
                "a straight end segment; give that segment curvature 0 (add a point)"
            )
    added = len(made.shape.points_mm) - n_points
    n_start = FILLET_CHORDS if made.start.fillet_mm > 0 else 0
    return np.array([0.0] * n_start + curv + [0.0] * (added - n_start), dtype=float)


def as_made_info(made: AsMadeBeam | None) -> dict[str, list[float]]:
    """What of a beam was clipped (rigid, inside its body, mm) and filleted (radius, mm), and
    its roots' Kt, each as ``[start, end]``; empty for None."""
    if made is None:
        return {}
    ends = (made.start, made.end)
    return {
        "clipped_mm": [round(e.clipped_mm, 6) for e in ends],
        "fillet_mm": [round(e.fillet_mm, 6) for e in ends],
        "root_kt": [round(e.kt, 4) for e in ends],
    }
