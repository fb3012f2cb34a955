"""Planar torsional springs of curved arms: a hub, ``n`` identical arms, a mounting pad on each.

The second topology beside the serpentine of :mod:`geometry.sea_spring` (paper 004's sets of
concentric arcs). Each arm is one slender member from the hub rim to an outer pad, its centreline
given in polar coordinates by a few control points and its in-plane width by a few control
values; the arms are repeated ``n`` times around the axis (rotational symmetry, no outer ring, as
paper 004 asks). A spiral arm (radius growing with the polar angle) is the classic clock-spring
shape: a long member in a small disc that carries the hub torque mostly as a bending moment
spread evenly along it, which is what a low peak stress needs (docs/sea_spring.md, section 5).
The same generator shapes the threshold-torque spring of paper 000 (arms whose geometric
nonlinearity makes the torque level off; docs/threshold_torque.md).

Units: mm and degrees in the parameters, rad inside.

**Centreline** of arm 0, a parameter ``t`` in [0, 1] from hub to pad::

    r(t)   = PCHIP through (t_i, radii_mm[i]),   t_i = i / (m - 1)
    phi(t) = PCHIP through (t_i, angles_deg[i])
    x, y   = r cos(phi), r sin(phi)

PCHIP (monotone cubic Hermite) keeps ``r`` and ``phi`` between neighbouring control values, so a
spiral with increasing control radii never folds back. ``radii_mm[0]`` is where the centreline
starts, normally half a root width inside the hub rim, so the arm's band overlaps the hub;
``radii_mm[-1]`` is the pad centre. Arm ``k`` is arm 0 turned by ``k 360/n`` degrees.

**Width** ``w(t)``: PCHIP through ``widths_mm`` at evenly spaced ``t``; the band is the
centreline offset by ``±w/2`` along its normal.

**Junctions**: the arm meets the hub rim and the pad boss in concave corners; they get fillets of
radius ``root_fillet_mm`` by a closing (``buffer(+r).buffer(-r)``) kept only near the two ends of
each arm, so the slots between arms elsewhere stay as drawn, and trimmed by the envelope. Every
other concave corner gets the frame's ``fillet_mm``. The optimiser's outline draws a fillet's
quarter circle in 16 (root) or ``fillet_segments`` (frame) segments; the fine outline of the
final stress check and the exported part (``curve_step_mm``) at most
:data:`FINE_FILLET_STEP_DEG` a facet, so that its refined peak stress converges at a root.

:func:`build_arm_spring` returns a :class:`geometry.sea_spring.SpringGeometry` (the same
outlines, rigid footprints, boundaries and checks as the serpentine, so the FE and the study code
take either) with the arms' refinement regions.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
import shapely
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.sea_spring import (
    SpringFrame,
    SpringGeometry,
    refuse_holes_outside_footprints,
)
from scipy.interpolate import PchipInterpolator
from shapely import affinity
from shapely.geometry import MultiPolygon, Point, Polygon
from shapely.geometry.base import BaseGeometry

_DEFAULT_FRAME = SpringFrame()

__all__ = [
    "FINE_FILLET_STEP_DEG",
    "ArmSpringParams",
    "ArmSpringGeometry",
    "arm_centreline",
    "arm_clearances",
    "build_arm_spring",
    "SPIRAL_LEVELS",
    "spiral_level_values",
    "SPIRAL_VARIABLES",
    "SPIRAL_BOUNDS",
    "spiral_params",
]


@dataclass(frozen=True)
class ArmSpringParams:
    """One arm's shape, repeated ``n_arms`` times.

    Attributes
    ----------
    radii_mm : (m,) float, mm — centreline radius at the control points ``t_i = i/(m-1)``;
        the first is inside the hub, the last is the pad centre.
    angles_deg : (m,) float, degrees — centreline polar angle at the same points (first 0).
    widths_mm : (k,) float, mm — in-plane width at ``t_j = j/(k-1)`` (k >= 1).
    thickness_mm : float, mm — out-of-plane thickness, the extrusion (ST).
    n_arms : int — arms around the hub.
    root_fillet_mm : float, mm — fillet radius where an arm meets the hub and its pad.
    """

    radii_mm: tuple[float, ...]
    angles_deg: tuple[float, ...]
    widths_mm: tuple[float, ...]
    thickness_mm: float
    n_arms: int = 4
    root_fillet_mm: float = 1.0

    def __post_init__(self) -> None:
        for name in ("radii_mm", "angles_deg", "widths_mm"):
            vals = tuple(float(v) for v in getattr(self, name))
            object.__setattr__(self, name, vals)
            if not all(math.isfinite(v) for v in vals):
                raise GeometryError(f"ArmSpringParams.{name} = {vals} must be finite numbers")
        if len(self.radii_mm) < 2 or len(self.radii_mm) != len(self.angles_deg):
            raise GeometryError(
                f"{len(self.radii_mm)} control radii and {len(self.angles_deg)} angles: give the "
                "same number, at least 2 (hub end and pad)"
            )
        if not self.widths_mm:
            raise GeometryError("widths_mm is empty; give at least one width")
        positive = {
            "radii_mm": self.radii_mm,
            "widths_mm": self.widths_mm,
            "thickness_mm": (self.thickness_mm,),
        }
        for name, vals in positive.items():
            if not all(v > 0 for v in vals):
                raise GeometryError(f"ArmSpringParams.{name} = {vals} must be positive")
        if not (math.isfinite(self.root_fillet_mm) and self.root_fillet_mm >= 0):
            raise GeometryError(f"root_fillet_mm = {self.root_fillet_mm} must be >= 0")
        if int(self.n_arms) != self.n_arms or self.n_arms < 1:
            raise GeometryError(f"n_arms = {self.n_arms} must be a whole number >= 1")

    @property
    def pitch_deg(self) -> float:
        """Angle between neighbouring arms, 360 / n."""
        return 360.0 / self.n_arms

    # SpringGeometry's properties read these two names
    @property
    def n_sets(self) -> int:
        return int(self.n_arms)


def arm_centreline(p: ArmSpringParams, max_step_mm: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Sampled centreline and width of arm 0.

    Returns
    -------
    xy : (s, 2) float, mm — centreline points from hub to pad, at most ``max_step_mm`` apart.
    w : (s,) float, mm — width at those points.
    """
    m = len(p.radii_mm)
    t_ctrl = np.linspace(0.0, 1.0, m)
    r_of = PchipInterpolator(t_ctrl, p.radii_mm)
    a_of = PchipInterpolator(t_ctrl, np.radians(p.angles_deg))
    # A fine first pass measures the length, then the samples are spread evenly in t.
    t = np.linspace(0.0, 1.0, 2001)
    r, a = r_of(t), a_of(t)
    xy = np.column_stack([r * np.cos(a), r * np.sin(a)])
    length = float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))
    n = max(8, int(math.ceil(length / max_step_mm)) + 1)
    t = np.linspace(0.0, 1.0, n)
    r, a = r_of(t), a_of(t)
    xy = np.column_stack([r * np.cos(a), r * np.sin(a)])
    k = len(p.widths_mm)
    if k == 1:
        w = np.full(n, p.widths_mm[0])
    else:
        w = PchipInterpolator(np.linspace(0.0, 1.0, k), p.widths_mm)(t)
    return xy, w


def _band(xy: np.ndarray, w: np.ndarray) -> Polygon:
    """The region within ±w/2 of a polyline along its (averaged) normals, as one polygon.

    Raises
    ------
    GeometryError
        A centreline that stands still (repeated points: a degenerate shape) or a band that
        shapely cannot close.
    """
    step = np.hypot(*np.diff(xy, axis=0).T)
    keep = np.concatenate([[True], step > 1e-9])
    xy, w = xy[keep], w[keep]
    if len(xy) < 2:
        raise GeometryError("the arm centreline has no length; check its control points")
    d = np.gradient(xy, axis=0)
    norm = np.hypot(d[:, 0], d[:, 1])
    if not np.all(norm > 0):
        raise GeometryError("the arm centreline turns back on itself; check its control points")
    d /= norm[:, None]
    nrm = np.column_stack([-d[:, 1], d[:, 0]])
    left = xy + 0.5 * w[:, None] * nrm
    right = xy - 0.5 * w[:, None] * nrm
    try:
        poly = Polygon(np.vstack([left, right[::-1]]))
        if not poly.is_valid:
            # A width larger than the local radius of curvature folds an offset curve;
            # buffer(0) resolves the fold into the region it encloses.
            poly = poly.buffer(0)
    except shapely.errors.GEOSException as exc:
        raise GeometryError(f"the arm band cannot be drawn ({exc}); check the shape") from exc
    return poly


def _rotate(geom: BaseGeometry, angle_deg: float) -> BaseGeometry:
    return affinity.rotate(geom, angle_deg, origin=(0.0, 0.0))


@dataclass(frozen=True)
class ArmSpringGeometry(SpringGeometry):
    """A built arm spring: :class:`geometry.sea_spring.SpringGeometry` with the arms' bands.

    Attributes (beyond SpringGeometry's)
    ------------------------------------
    arm_pieces : list of (Polygon, width mm) — pieces of every arm band with their smallest
        width, for the mesh refinement.
    centreline_mm : (s, 2) float, mm — arm 0's centreline (hub to pad).
    """

    arm_pieces: list = field(default_factory=list)
    centreline_mm: np.ndarray | None = None

    def mesh_regions(self, elements_through: float = 2.0, max_mm: float = 2.0) -> list:
        """Every arm piece at its width / ``elements_through`` (list of (geometry, size mm))."""
        return [(g, min(max_mm, w / elements_through)) for g, w in self.arm_pieces]

    def mesh_lines(self) -> list:
        """The rigid regions' boundaries (the hub's drive disc, every pad's clamp disc) as
        closed rings, mm, for :func:`fea.mesh.mesh_polygon`'s ``lines``: the FE model holds or
        turns the nodes on or inside them, so a mesh with them on its edges holds exactly these
        discs. Otherwise the held set is jagged at the scale of the elements there and changes
        from one re-mesh to the next: ST moved by up to 3.5e-3 mm for a 1e-4 relative change
        of W4 (the quick study's spring, 4 mm mesh), which kept the morphed mesh's answer from
        approaching the re-meshed one's under refinement (docs/sea_spring.md, "The morph's
        refinement test"). Rings not strictly inside ``fe_outline`` are left out."""
        rings = [self.hub_region.exterior]
        rings += [g.exterior for g in getattr(self.pad_region, "geoms", [self.pad_region])]
        return [
            r
            for r in rings
            if self.fe_outline.contains(r) and self.fe_outline.boundary.distance(r) > 1e-6
        ]


def arm_clearances(p: ArmSpringParams, frame: SpringFrame = _DEFAULT_FRAME) -> dict[str, float]:
    """Signed margins (mm, >= 0 when met) of an arm spring, from its drawn arms.

    * ``envelope_mm``: envelope radius minus the farthest point of an arm or pad;
    * ``thinnest_mm``: narrowest arm width minus ``min_feature_mm``;
    * ``slot_mm``: smallest gap between two different arms (with their pads) away from the hub,
      minus ``min_slot_mm`` (a root fillet that would bridge a slot is refused by the builder);
    * ``hub_mm``: the arm's start lies inside the hub (the hub rim minus the first radius).
    """
    return dict(_arm_clearances(p, frame))


@functools.lru_cache(maxsize=8)
def _arm_clearances(p: ArmSpringParams, frame: SpringFrame) -> dict[str, float]:
    # Kept for the next caller with equal parameters: an optimiser's evaluation checks the
    # margins, then builds the same shape, which checks them again (~5 ms of ~0.5 s).
    arm, pad, _, _ = _arm_zero(p, frame)
    one = arm.union(pad)
    outer = max(
        float(np.hypot(*shapely.get_coordinates(one).T).max()),
        p.radii_mm[-1] + frame.pad_radius_mm,
    )
    _, w = arm_centreline(p)
    slot = _slot(one, p, frame)
    return {
        "envelope_mm": frame.envelope_radius_mm - outer,
        "thinnest_mm": float(w.min()) - frame.min_feature_mm,
        "slot_mm": slot - frame.min_slot_mm,
        "hub_mm": frame.hub_radius_mm - p.radii_mm[0],
    }


def _slot(one: BaseGeometry, p: ArmSpringParams, frame: SpringFrame) -> float:
    if p.n_arms < 2:
        return math.inf
    # Away from the hub (the arms all join it) and its root fillets.
    keep_out = Point(0.0, 0.0).buffer(frame.hub_radius_mm + 0.5 * p.root_fillet_mm, quad_segs=32)
    mine = one.difference(keep_out)
    others = shapely.union_all([_rotate(one, k * p.pitch_deg) for k in range(1, p.n_arms)])
    return float(mine.distance(others.difference(keep_out)))


#: Largest turn (degrees) between two facets of a fillet on the fine outline (``curve_step_mm``
#: given): a fillet polygon's every vertex is a weak re-entrant corner, on which the refined peak
#: stress keeps creeping (Williams); the 16 segments per quarter circle of the optimiser's
#: outline turn by 5.6 deg, and the 0.3 mm frame fillets at 4 segments by 22.5 deg. 0.25 deg is
#: below the centreline's own turn at 0.1 mm steps (0.3 deg on an 18 mm flank, 0.5 deg on a
#: 12 mm one), so a fillet is not where the refined peak creeps most (0.5 deg: ~0.3 % a
#: halving on a root fillet; docs/sea_spring.md, "Root fillets on the fine outline").
FINE_FILLET_STEP_DEG = 0.25


def _fillet_segments(coarse: int, curve_step_mm: float | None) -> int:
    """Segments per quarter circle of a fillet: ``coarse`` on the optimiser's outline (its
    designs stay as they were), at most :data:`FINE_FILLET_STEP_DEG` a facet on the fine one."""
    if curve_step_mm is None:
        return int(coarse)
    return max(int(coarse), math.ceil(90.0 / FINE_FILLET_STEP_DEG))


@functools.lru_cache(maxsize=4)
def _envelope_disc(radius_mm: float) -> Polygon:
    """The envelope as a polygon inscribed in its circle (every point within ``radius_mm``)."""
    return Point(0.0, 0.0).buffer(radius_mm, quad_segs=256)


def _without_cracks(body: BaseGeometry, width_mm: float = 1e-3) -> BaseGeometry:
    """``body`` with the slits and pinholes the unions leave between pieces that should share an
    edge closed (a closing by ``width_mm``), when it has any.

    A fillet piece turned to another arm does not meet the hub's or its pad's polygon exactly:
    a slit ~1e-5 mm wide may stay between them. The frame fillets' mitred closing may grow the
    slit's mouth, a corner turning by ~180 deg, into a spike up to 20 fillet radii long, which
    the erosion leaves sticking out of the part: a pad near the envelope then built or was
    refused depending on the rounding of the design (issue 27's "cliff", 0.1-0.4 mm beyond
    the envelope). A body without slits or pinholes (no vertex turning by more than 150 deg,
    no interior ring) is returned as it is.
    """
    polys = list(getattr(body, "geoms", [body]))
    sharp = False
    for poly in polys:
        if len(poly.interiors) > 0:
            sharp = True
            break
        xy = np.asarray(poly.exterior.coords)[:-1]
        a, b = np.roll(xy, -1, axis=0) - xy, xy - np.roll(xy, 1, axis=0)
        turn = np.arctan2(b[:, 0] * a[:, 1] - b[:, 1] * a[:, 0], np.sum(a * b, axis=1))
        if np.any(np.abs(turn) > math.radians(150.0)):
            sharp = True
            break
    if not sharp:
        return body
    # mitred both ways: nothing is rounded (no arcs of width_mm radius, whose vertices would
    # be edges of a fraction of a micrometre for the mesher), the slits close
    return body.buffer(width_mm, join_style="mitre").buffer(-width_mm, join_style="mitre")


def _simplified_by_sector(body: BaseGeometry, n: int, tolerance_mm: float) -> BaseGeometry:
    """``body`` simplified (Douglas-Peucker, ``tolerance_mm``) and made to repeat every
    360 / ``n`` deg about the origin by construction: one sector of its outline simplified and
    turned ``n`` times.

    The body of ``n`` arms turned by the pitch repeats to round-off only; simplifying the whole
    ring keeps different vertices at different arms (Douglas-Peucker's choices hang on where
    the ring starts and on 1e-12 mm differences), which left the optimiser's outline of
    threshold-spring.yaml's design 1.7e-4 of its area off its turn, over the 3D check's
    1e-4 (fea/solid3d_sector.rotational_symmetry_problem): the check then solved the whole
    part, and the stiffness rows judged a part unlike the exported (symmetric) one. The
    exterior of a part around the origin winds once about it, so its turn by the pitch is the
    same ring shifted by 1/n of its length: the piece from the outermost vertex v0 to its
    image R v0 (projected onto the ring), simplified with both ends kept, turned ``k`` pitches
    for k = 0 .. n-1 and joined end to end, is the ring. Returned as ``shapely.simplify``
    would when ``body`` is not one polygon without holes, ``n`` < 2, or the construction does
    not give a valid polygon whose area is within ``tolerance_mm`` x perimeter of ``body``'s
    (left to the sector test to judge).
    """
    plain = shapely.simplify(body, tolerance_mm, preserve_topology=True)
    if n < 2 or not isinstance(body, Polygon) or len(body.interiors) != 0:
        return plain
    ring = np.asarray(shapely.geometry.polygon.orient(body, 1.0).exterior.coords)[:-1]
    i0 = int(np.argmax(np.hypot(ring[:, 0], ring[:, 1])))
    ring = np.roll(ring, -i0, axis=0)  # v0 first, counter-clockwise
    closed = shapely.LineString(np.vstack([ring, ring[:1]]))
    step = 2.0 * math.pi / n
    turn = np.array([[math.cos(step), -math.sin(step)], [math.sin(step), math.cos(step)]])
    image = turn @ ring[0]
    s_image = float(closed.project(shapely.Point(*image)))
    near = float(closed.distance(shapely.Point(*image)))
    if near > 1e-6 or abs(s_image - closed.length / n) > 1e-3 * closed.length:
        return plain  # not one ring shifted by its turn (then not symmetric: the test says)
    s_vertex = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(ring, axis=0).T))])
    piece = np.vstack([ring[s_vertex < s_image - 1e-9], image])
    piece = np.asarray(
        shapely.simplify(shapely.LineString(piece), tolerance_mm, preserve_topology=True).coords
    )[:-1]  # Douglas-Peucker keeps both ends: v0 here, its image starts the next piece
    pieces = [piece]
    for _ in range(1, n):
        pieces.append(pieces[-1] @ turn.T)
    built = Polygon(np.vstack(pieces))
    # Douglas-Peucker moves no point of the ring more than tolerance_mm
    if not built.is_valid or abs(built.area - body.area) > tolerance_mm * closed.length:
        return plain
    return built


def _hub_disc(radius_mm: float, quad_segs: int, n: int) -> Polygon:
    """A disc about the origin that repeats every 360 / ``n`` deg: ``Point.buffer``'s
    (4 ``quad_segs`` vertices) when ``n`` divides their number, else ``n`` ceil(4 quad_segs / n)
    vertices from angle 0, on the circle of ``radius_mm`` (mm)."""
    if (4 * quad_segs) % n == 0:
        return Point(0.0, 0.0).buffer(radius_mm, quad_segs=quad_segs)
    m = n * math.ceil(4 * quad_segs / n)
    a = 2.0 * math.pi * np.arange(m) / m
    return Polygon(np.column_stack([radius_mm * np.cos(a), radius_mm * np.sin(a)]))


def _hub_hole_count(frame: SpringFrame) -> int:
    """The hub bolt holes an arm spring gets: ``frame.hub_holes`` as asked (0 when there are
    none). Not rounded to a multiple of the arm count: the holes must match the user's flange
    (4 bolts on a 3-arm spring are 4 holes); they lie in the flange's rigid footprint (checked
    in :func:`_arm_spring_holes`), so the models, which hold that footprint rigid, see the
    same part whether or not the pattern repeats under the arms' pitch."""
    if frame.hub_holes <= 0 or frame.hub_hole_diameter_mm <= 0:
        return 0
    return int(frame.hub_holes)


def _arm_spring_holes(frame: SpringFrame, pad0_xy: np.ndarray, n: int) -> BaseGeometry:
    """The bore, the hub bolt holes and a bolt hole in every pad of an ``n``-arm spring whose
    arm 0 has its pad centre at ``pad0_xy`` (2,) mm, as one geometry (empty when none), built
    to repeat every 360 / ``n`` deg about the origin: one sector's holes turned ``n`` times.

    :func:`geometry.sea_spring.mounting_holes` (the serpentine's) buffers every hole about its
    own centre (a polygon whose vertices do not turn with the arms unless the pitch is a
    multiple of their spacing) and places ``frame.hub_holes`` bolt holes whatever the arm
    count: for 3, 5, 6, 7 or 8 arms the exported part did not repeat under the pitch (45.7
    mm^2 off for 4 hub holes). Here the bore is a :func:`_hub_disc`, the pad holes are arm 0's
    turned, and the hub holes (:func:`_hub_hole_count`: ``hub_holes`` as asked) are half a
    hole pitch off arm 0's direction as before, one hole turned by the hole pitch: when
    ``hub_holes`` is a multiple of ``n`` the whole exported outline repeats under the arms'
    pitch; otherwise only the hub holes' pattern does not (e.g. 4 bolts on 3 arms), which the
    models cannot see: the holes lie in the flange's rigid footprint (below).

    The FE models (plane stress and 3D) mesh the outline without the holes (``fe_outline``):
    that is the exported part only while every hole lies inside a rigid footprint (the hub's
    flange footprint ``hub_clamp_radius_mm``, the pads' washers ``pad_clamp_radius_mm``),
    where a hole changes nothing; a hole reaching past one is refused (GeometryError), as are
    hub holes closer than ``min_feature_mm`` to each other
    (:func:`geometry.sea_spring.refuse_holes_outside_footprints`, the serpentine's too).
    """
    step = 360.0 / n
    holes: list[BaseGeometry] = []
    refuse_holes_outside_footprints(frame)
    if frame.bore_diameter_mm > 0:
        holes.append(_hub_disc(0.5 * frame.bore_diameter_mm, 16, n))
    k = _hub_hole_count(frame)
    if k > 0:
        rc, rh = 0.5 * frame.hub_hole_circle_diameter_mm, 0.5 * frame.hub_hole_diameter_mm
        # half a hole pitch off the arms, as mounting_holes places them; every hole is hole
        # 0 turned by the hole pitch, so a pattern of a multiple of n holes repeats under the
        # arms' pitch to round-off
        t = math.pi / k
        hole0 = Point(rc * math.cos(t), rc * math.sin(t)).buffer(rh, quad_segs=12)
        holes += [_rotate(hole0, j * 360.0 / k) for j in range(k)]
    if frame.pad_hole_diameter_mm > 0:
        hole0 = Point(*pad0_xy).buffer(0.5 * frame.pad_hole_diameter_mm, quad_segs=12)
        holes += [_rotate(hole0, m * step) for m in range(n)]
    return shapely.union_all(holes) if holes else Polygon()


def _arm_zero(p: ArmSpringParams, frame: SpringFrame, curve_step_mm: float | None = None):
    step = min(0.5, 0.25 * min(p.widths_mm) + 0.1) if curve_step_mm is None else curve_step_mm
    xy, w = arm_centreline(p, max_step_mm=step)
    arm = _band(xy, w)
    centre = Point(*xy[-1])
    pad = centre.buffer(frame.pad_radius_mm, quad_segs=32)
    return arm, pad, xy, w


def build_arm_spring(
    p: ArmSpringParams, frame: SpringFrame = _DEFAULT_FRAME, curve_step_mm: float | None = None
) -> ArmSpringGeometry:
    """Build the outline of an arm spring and check it.

    Parameters
    ----------
    p : ArmSpringParams
    frame : SpringFrame — envelope, hub, pads, holes, fillets, manufacturing limits.
    curve_step_mm : float, mm, optional — sample the arm centreline this finely (and simplify
        the outline only by 5e-6 mm) instead of the optimiser's 0.5 mm, and every fillet (root
        and frame) at :data:`FINE_FILLET_STEP_DEG` a facet instead of its quarter circle in 16
        (root) or ``frame.fillet_segments`` segments. A
        flank of radius R sampled at step s turns by s / R rad at every vertex, a weak
        re-entrant corner on its concave side: 0.43 mm on the default optimum's R = 18 mm flank
        is 1.4 deg, which keeps the peak stress there from converging (docs/solid3d.md); 0.1 mm
        gives 0.3 deg. For the final stress check and the exported part only: finer boundary
        segments mean more triangles.

    Both outlines close the slits between the unions' pieces before the frame fillets; the
    optimiser's (``curve_step_mm`` None) is simplified one sector at a time and turned, so it
    repeats under the turn by the pitch to round-off (:func:`_simplified_by_sector`), as do
    the hub and pad regions: the 3D check solves one sector of the part the plane-stress
    model judges.

    Returns
    -------
    ArmSpringGeometry

    Raises
    ------
    GeometryError
        A failed check of :func:`arm_clearances` (named, with its fix), or an outline that is
        not one valid polygon.
    """
    margins = arm_clearances(p, frame)
    fixes = {
        "envelope_mm": "bring the pad radius (last control radius) or the widths in",
        "thinnest_mm": "widen the thinnest arm section or lower min_feature_mm",
        "slot_mm": "fewer arms, less sweep, narrower arms or a smaller root fillet",
        "hub_mm": "start the centreline inside the hub (first radius <= hub_radius_mm)",
    }
    for key, margin in margins.items():
        if margin < -1e-9:
            raise GeometryError(
                f"arm spring check {key} fails by {-margin:.3g} mm; {fixes[key]} "
                "(see geometry.arm_spring.arm_clearances)"
            )
    arm0, pad0, xy, w = _arm_zero(p, frame, curve_step_mm)
    hub = Point(0.0, 0.0).buffer(frame.hub_radius_mm, quad_segs=64)
    arms = [_rotate(arm0, k * p.pitch_deg) for k in range(p.n_arms)]
    pads = [_rotate(pad0, k * p.pitch_deg) for k in range(p.n_arms)]
    body = shapely.union_all([hub, *arms, *pads])
    if p.root_fillet_mm > 0:
        # Fillets at the two junctions of every arm only: the closing of one arm with the hub
        # and its own pad (no neighbour to bridge to), of which the pieces touching the hub rim
        # or the pad boss are kept, then turned to every arm.
        rf = p.root_fillet_mm
        own = shapely.union_all([hub, arm0, pad0])
        closed = own.buffer(rf, join_style="mitre", mitre_limit=20.0).buffer(
            -rf, quad_segs=_fillet_segments(16, curve_step_mm)
        )
        # keep the pieces that fill a corner at the hub rim or at the pad boss
        near = hub.exterior.buffer(0.01).union(pad0.exterior.buffer(0.01))
        new = closed.difference(own)
        fill = shapely.union_all(
            [g for g in getattr(new, "geoms", [new]) if not g.is_empty and g.intersects(near)]
        )
        # A fillet in the corner between a pad on the envelope and an arm running close to it
        # could reach past the envelope (the corner's tangents do; not seen in 374 random
        # designs with R_pad at its bound, where the refusals "at a junction fillet" were
        # spikes grown from slits: _without_cracks). It is trimmed by the envelope (a convex
        # corner there, no stress raiser), so whether a design fits is its arms' and pads'
        # business alone (arm_clearances); the part built and analysed is the trimmed one.
        envelope = _envelope_disc(frame.envelope_radius_mm)
        if not fill.within(envelope):  # (only then: an overlay re-nodes what it returns)
            fill = fill.intersection(envelope)
        body = body.union(
            shapely.union_all([_rotate(fill, k * p.pitch_deg) for k in range(p.n_arms)])
        )
    if frame.fillet_mm > 0:
        r = frame.fillet_mm
        segments = _fillet_segments(frame.fillet_segments, curve_step_mm)

        def closing(shape: BaseGeometry) -> BaseGeometry:
            return shape.buffer(r, join_style="mitre", mitre_limit=20.0).buffer(
                -r, quad_segs=segments
            )

        # Slits closed first, always: the mitred closing grows a fill around a slit's mouth,
        # and the unions leave slits at some arms' junctions and not at others (round-off of
        # the turn by the pitch), which made the optimiser's outline of sea-spring.yaml's
        # session-29 design miss its half turn by 0.85 mm^2 (docs/sea_spring.md, "The
        # optimiser's outline made symmetric (session 30)").
        body = closing(_without_cracks(body))
    else:
        body = _without_cracks(body)
    # 2 um merges the near-collinear vertices of the unions; a fine sampling keeps its own. At
    # 5e-6 mm a fillet of radius > 0.53 mm keeps its 0.25 deg facets (r (1 - cos 0.25 deg) off
    # the chord of two; 1e-5 mm merged a 1 mm fillet's into 0.5 deg ones), a 0.3 mm frame
    # fillet's merge into ~0.7 deg ones, and the two vertices 1.6 um apart into which the frame
    # closing splits each vertex of a concave flank merge back (at 2e-6 mm they stay: 4.7x
    # the triangles).
    if curve_step_mm is None:
        body = _simplified_by_sector(body, p.n_arms, 2e-3)
    else:
        body = _simplified_by_sector(body, p.n_arms, 5e-6)
    if isinstance(body, MultiPolygon) or not isinstance(body, Polygon) or not body.is_valid:
        raise GeometryError(
            f"the arm spring outline is not one valid polygon ({body.geom_type}, "
            f"{shapely.is_valid_reason(body)}); check the widths and the slots"
        )
    if len(body.interiors) != 0:
        raise GeometryError(
            f"the arm spring outline closed {len(body.interiors)} slot(s) into holes; widen the "
            "slots or reduce root_fillet_mm"
        )
    centres = [_rotate(Point(*xy[-1]), k * p.pitch_deg) for k in range(p.n_arms)]
    holes = _arm_spring_holes(frame, xy[-1], p.n_arms)
    outline = body.difference(holes) if not holes.is_empty else body
    if not isinstance(outline, Polygon) or not outline.is_valid:
        raise GeometryError("the mounting holes cut the spring apart; make them smaller")
    # The supports repeat under the turn by the pitch as the outline does (the 3D check solves
    # one sector only when they do too): arm 0's pad discs turned, and hub discs whose vertex
    # count is a multiple of n_arms (a buffer's 4 quad_segs is not for 3, 5 or 6 arms).
    pad0_centre = Point(*xy[-1])
    pad_region = MultiPolygon(
        [_rotate(pad0_centre.buffer(frame.pad_clamp_radius_mm, quad_segs=16), k * p.pitch_deg)
         for k in range(p.n_arms)]
    )  # fmt: skip
    boundaries = {
        "hub": _hub_disc(frame.hub_radius_mm + 1e-6, 64, p.n_arms),
        "pads": shapely.union_all(
            [_rotate(pad0_centre.buffer(frame.pad_radius_mm + 1e-6, quad_segs=32), k * p.pitch_deg)
             for k in range(p.n_arms)]
        ),
    }  # fmt: skip
    hub_region = _hub_disc(frame.hub_clamp_radius_mm, 32, p.n_arms)
    pieces = []
    n_pieces = 12
    edges = np.linspace(0, len(xy) - 1, n_pieces + 1).astype(int)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        piece = _band(xy[a : b + 1], w[a : b + 1]).buffer(0.05)
        for k in range(p.n_arms):
            pieces.append((_rotate(piece, k * p.pitch_deg), float(w[a : b + 1].min())))
    exy = np.asarray(outline.exterior.coords)
    outer = float(np.hypot(exy[:, 0], exy[:, 1]).max())
    if outer > frame.envelope_radius_mm + 1e-9:
        # not expected: the junction fillets are trimmed to the envelope and a closing of a
        # shape inside the (convex) envelope stays inside it; kept as the outline's own check
        raise GeometryError(
            f"arm spring check envelope_mm fails by {outer - frame.envelope_radius_mm:.3g} mm "
            "(at a fillet); bring the pad radius in or reduce root_fillet_mm"
        )
    checks = dict(margins)
    checks["envelope_mm"] = min(margins["envelope_mm"], frame.envelope_radius_mm - outer)
    checks.update(
        {"outer_radius_mm": outer,
         "area_mm2": float(outline.area),
         "arm_length_mm": float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))}
    )  # fmt: skip
    return ArmSpringGeometry(
        params=p,  # type: ignore[arg-type]
        frame=frame,
        outline=outline,
        fe_outline=body,
        hub_region=hub_region,
        pad_region=pad_region,
        boundaries=boundaries,
        pad_centres_mm=np.array([[c.x, c.y] for c in centres]),
        checks=checks,
        arm_pieces=pieces,
        centreline_mm=xy,
    )


def _rim_point(xy: np.ndarray, radius: float) -> np.ndarray:
    """The first centreline point at or beyond ``radius`` (where the arm leaves the hub)."""
    r = np.hypot(xy[:, 0], xy[:, 1])
    i = int(np.argmax(r >= radius)) if np.any(r >= radius) else 0
    return xy[i]


# --------------------------------------------------------------------------------------------
# The spiral parameterisation of the SEA study (topology: spiral)

#: GA variables of a spiral arm (mm, degrees): the angle the arm sweeps from hub to pad, the pad
#: centre radius, the radial shape (F1: fraction of the radial rise reached at a third of the
#: sweep; F2: fraction of the *remaining* rise reached at two thirds) and the width at
#: t = 0, 1/3, 2/3, 1; ST the out-of-plane thickness.
SPIRAL_VARIABLES: tuple[str, ...] = (
    "sweep", "R_pad", "F1", "F2", "W1", "W2", "W3", "W4", "ST",
)  # fmt: skip

#: Bounds of the spiral variables (mm; sweep in degrees; F1, F2 fractions). The pad centre stays
#: a pad radius (3.5 mm) inside the 36 mm envelope; widths span the serpentine's S and W ranges.
SPIRAL_BOUNDS: dict[str, tuple[float, float]] = {
    "sweep": (150.0, 480.0),
    "R_pad": (22.0, 32.5),
    "F1": (0.1, 0.7),
    "F2": (0.1, 0.9),
    "W1": (1.0, 6.0),
    "W2": (1.0, 6.0),
    "W3": (1.0, 6.0),
    "W4": (1.0, 6.0),
    "ST": (8.0, 20.0),
}


def spiral_params(
    values: dict[str, float], n_arms: int, frame: SpringFrame = _DEFAULT_FRAME,
    root_fillet_mm: float = 1.0,
) -> ArmSpringParams:  # fmt: skip
    """A spiral arm spring from the named variables of :data:`SPIRAL_VARIABLES`.

    The centreline starts inside the hub rim (``r0 = hub_radius - W1/2 - 1 mm``) at
    angle 0 and reaches the pad centre ``R_pad`` at angle ``sweep``; in between it passes
    ``r(1/3) = r0 + F1 (R_pad - r0)`` at a third of the sweep and
    ``r(2/3) = r(1/3) + F2 (R_pad - r(1/3))`` at two thirds, so any F1, F2 in (0, 1) give a
    radius that grows from hub to pad (F1 = 1/3, F2 = 1/2 is an Archimedean spiral; a large F1
    leaves the hub steeply, a small one winds close around it first). The width runs through
    W1..W4 at t = 0, 1/3, 2/3, 1.

    Raises
    ------
    GeometryError
        F1 or F2 outside (0, 1), or parameters ArmSpringParams refuses.
    """
    v = values
    f1, f2 = float(v["F1"]), float(v["F2"])
    if not (0.0 < f1 < 1.0 and 0.0 < f2 < 1.0):
        raise GeometryError(
            f"spiral shape F1 = {f1:g}, F2 = {f2:g}: both must lie in (0, 1) (fractions of the "
            "radial rise)"
        )
    # 1 mm deeper than half the root width: the band's square start end then lies wholly inside
    # the hub even where the centreline leaves it at a slant.
    r0 = frame.hub_radius_mm - 0.5 * float(v["W1"]) - 1.0
    r3 = float(v["R_pad"])
    r1 = r0 + f1 * (r3 - r0)
    r2 = r1 + f2 * (r3 - r1)
    sweep = float(v["sweep"])
    return ArmSpringParams(
        radii_mm=(r0, r1, r2, r3),
        angles_deg=(0.0, sweep / 3.0, 2.0 * sweep / 3.0, sweep),
        widths_mm=(v["W1"], v["W2"], v["W3"], v["W4"]),
        thickness_mm=v["ST"],
        n_arms=n_arms,
        root_fillet_mm=root_fillet_mm,
    )


#: Five levels of each Taguchi factor of a spiral spring (stage 1 with ``topology: spiral``):
#: RP arms around the hub, the sweep (degrees), one width W for the whole arm (mm), the radial
#: shape F1 (F2 = 1/2), the pad radius R_pad (mm) and ST (mm). They span SPIRAL_BOUNDS the way
#: Table 6 spans the serpentine's ranges.
SPIRAL_LEVELS: dict[str, tuple[float, ...]] = {
    "RP": (2, 3, 4, 5, 6),
    "sweep": (180.0, 247.5, 315.0, 382.5, 450.0),
    "W": (1.5, 2.25, 3.0, 3.75, 4.5),
    "F1": (0.15, 0.25, 0.35, 0.45, 0.55),
    "R_pad": (24.0, 26.0, 28.0, 30.0, 32.0),
    "ST": (8.0, 11.0, 14.0, 17.0, 20.0),
}


def spiral_level_values(levels: dict[str, float]) -> dict[str, float]:
    """The :data:`SPIRAL_VARIABLES` of a Taguchi run of :data:`SPIRAL_LEVELS` (a uniform width,
    F2 = 1/2)."""
    w = float(levels["W"])
    return {
        "sweep": float(levels["sweep"]),
        "R_pad": float(levels["R_pad"]),
        "F1": float(levels["F1"]),
        "F2": 0.5,
        "W1": w,
        "W2": w,
        "W3": w,
        "W4": w,
        "ST": float(levels["ST"]),
    }
