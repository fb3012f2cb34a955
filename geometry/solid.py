"""Printable solids from planar outlines: extrusion, STL bytes and a minimum-wall check.

A compliant part is a planar outline extruded by its out-of-plane thickness and printed lying flat,
so the solid is ``polygon x [0, height]``. :func:`extrude` builds it with manifold3d (guaranteed
manifold booleans and extrusion) and checks it is one watertight body of the right volume;
:func:`stl_bytes` serialises it as binary STL (writing the file is the pipeline's job).

:func:`min_feature_mm` estimates the thinnest wall of an outline by morphological opening: a
feature thinner than ``w`` disappears when the outline is eroded by ``w / 2``, which shows as a
change of topology (a neck breaks, a wall between a hole and the outside opens, the whole part
vanishes) or as a tab that the opening (erode then dilate by ``w / 2``) cuts off. Corners are
rounded by the opening too, but the piece cut off a corner stays within about ``w`` of the
opened outline, while a thin tab sticks out by its length; the check tells them apart by that
distance. :func:`check_printable` applies it at the printer's minimum wall.

:func:`flat_part` gives the part a file is written of, in one of two frames (:data:`FRAMES`):
``design`` (where the kind draws it, for CAD and assemblies) or ``bed`` (laid flat, for a
printer or a sheet), its outline cleaned of repeated and collinear vertices first
(:func:`clean_outline`, :data:`COLLINEAR_TOL_MM`), which OpenCascade would otherwise merge into
fewer STEP faces than the outline has edges. :func:`step_bytes` writes it as a STEP solid.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import shapely
from flexopt.geometry.errors import FlexoptError, GeometryError
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient

if TYPE_CHECKING:  # trimesh (with scipy.spatial) and manifold3d are imported by the functions
    # that make a solid (~0.4 s CPU): a kind that imports this module for its outline checks
    # (geometry.mechanism) does not pay them in load_study, nor its pool's workers
    import trimesh

__all__ = [
    "SolidSettings",
    "extrude",
    "check_solid",
    "stl_bytes",
    "min_feature_mm",
    "thin_feature_at",
    "check_printable",
    "COLLINEAR_TOL_MM",
    "clean_outline",
    "FRAMES",
    "FlatPart",
    "SHEET_HINT",
    "lay_flat",
    "sheet_profile",
    "flat_part",
    "StepUnavailable",
    "step_bytes",
]


@dataclass(frozen=True)
class SolidSettings:
    """Tolerances of the solid checks, each with its reason."""

    # Relative volume mismatch always allowed between the mesh and area x height. manifold3d
    # hands its vertices out as float32, so each coordinate is rounded by up to 2^-24 of its
    # magnitude: check_solid adds the volume that rounding can move (surface area x largest
    # coordinate x 2^-24, twice for safety), which for a slender part far from the origin is
    # more than 1e-6 (a run lost its STL at 1.4e-6). A missing hole or face is off by far more.
    volume_rtol: float = 1e-6
    # Safety factor on the float32 rounding bound above.
    float32_factor: float = 2.0
    # Segments per quarter circle of the buffers used by the thin-feature test: 16 keeps the
    # polygonal arcs within 0.5 % of the radius, well inside the bisection tolerance below.
    quad_segs: int = 16
    # Resolution of the minimum-feature bisection, mm: a tenth of a typical 0.4 mm nozzle width.
    feature_tol_mm: float = 0.01
    # Growth of the upward scan for the first thin width: 1.25 costs ~30 cheap buffer tests from
    # 0.01 mm to 100 mm and brackets the answer within 25 % before the bisection.
    feature_scan_ratio: float = 1.25
    # A piece cut off by the opening at width w is a thin tab (not a rounded corner) when it sticks
    # out more than this many w from the opened outline. Corner slivers reach
    # (w/2)(1/sin(alpha/2) - 1): 0.21 w at 90 degrees, 0.5 w at 60, 1.4 w at 30, so 2 w lets
    # corners down to about 23 degrees pass while a tab longer than two nozzle widths fails.
    tab_extent_factor: float = 2.0


def _check_outline(polygon: BaseGeometry, what: str) -> Polygon:
    if isinstance(polygon, MultiPolygon):
        raise GeometryError(
            f"{what} needs one connected outline but got {len(polygon.geoms)} separate pieces; "
            "join them (e.g. widen the links between them) so the part prints as one body"
        )
    if not isinstance(polygon, Polygon):
        raise GeometryError(f"{what} needs a shapely Polygon, got {type(polygon).__name__}")
    if not polygon.is_valid:
        raise GeometryError(
            f"{what} got an invalid outline ({shapely.is_valid_reason(polygon)}); remove "
            "self-intersections, e.g. with polygon.buffer(0)"
        )
    if polygon.is_empty or not polygon.area > 0:
        raise GeometryError(f"{what} got an empty outline (area 0); check the outline parameters")
    return orient(polygon, sign=1.0)


def extrude(
    polygon: Polygon, height_mm: float, settings: SolidSettings = SolidSettings()
) -> trimesh.Trimesh:
    """Extrude an outline into a solid lying flat on the build plate (z from 0 to height).

    Parameters
    ----------
    polygon : shapely Polygon, mm
        The outline in the x-y plane; holes become through-holes.
    height_mm : float, mm
        Extrusion height (the part's out-of-plane thickness).
    settings : SolidSettings

    Returns
    -------
    trimesh.Trimesh
        Vertices (n, 3) mm, faces (m, 3); one watertight body of volume area x height.

    Raises
    ------
    GeometryError
        The outline is not one valid polygon, the height is not positive, or the solid fails
        :func:`check_solid`.
    """
    poly = _check_outline(polygon, "extrude")
    if not (np.isfinite(height_mm) and height_mm > 0):
        raise GeometryError(f"extrusion height_mm = {height_mm} must be > 0 mm")
    # orient() gives a counter-clockwise exterior and clockwise holes, which is what the Positive
    # fill rule reads as material and voids.
    contours = [
        np.asarray(ring.coords, dtype=float)[:-1] for ring in (poly.exterior, *poly.interiors)
    ]
    import manifold3d
    import trimesh

    section = manifold3d.CrossSection(contours, manifold3d.FillRule.Positive)
    solid = manifold3d.Manifold.extrude(section, float(height_mm))
    out = solid.to_mesh()
    mesh = trimesh.Trimesh(
        vertices=np.asarray(out.vert_properties, dtype=float)[:, :3],
        faces=np.asarray(out.tri_verts, dtype=np.int64),
        process=True,
    )
    check_solid(mesh, poly.area * float(height_mm), settings)
    return mesh


def check_solid(
    mesh: trimesh.Trimesh, expected_volume_mm3: float, settings: SolidSettings = SolidSettings()
) -> None:
    """Check a solid is one watertight body of the expected volume.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Vertices in mm.
    expected_volume_mm3 : float, mm^3
    settings : SolidSettings

    Raises
    ------
    GeometryError
        Naming what failed: open edges, several bodies, or the volume mismatch.
    """
    if not mesh.is_watertight:
        raise GeometryError(
            "the solid is not watertight (it has open or non-manifold edges); the outline "
            "probably has touching rings or zero-width slivers — clean it with buffer(0)"
        )
    n_bodies = int(mesh.body_count)
    if n_bodies != 1:
        raise GeometryError(
            f"the solid has {n_bodies} separate bodies, expected 1; connect the pieces of the "
            "outline"
        )
    volume = float(mesh.volume)
    # What float32 vertices can move the volume by: every face shifted along its normal by the
    # rounding of the largest coordinate (a bound, as the roundings do not all add up).
    scale = float(np.abs(mesh.vertices).max()) if len(mesh.vertices) else 0.0
    rounding = settings.float32_factor * float(mesh.area) * scale * float(np.finfo(np.float32).eps)
    allowed = settings.volume_rtol * abs(expected_volume_mm3) + rounding
    if not abs(volume - expected_volume_mm3) <= allowed:
        raise GeometryError(
            f"the solid's volume {volume:.9g} mm^3 differs from area x height = "
            f"{expected_volume_mm3:.9g} mm^3 by more than {allowed:.3g} mm^3 (what float32 "
            "vertices can move it by); the extrusion lost or added material (inverted or "
            "overlapping rings?)"
        )


def stl_bytes(mesh: trimesh.Trimesh) -> bytes:
    """Binary STL of a mesh (units mm, as slicers assume).

    Parameters
    ----------
    mesh : trimesh.Trimesh

    Returns
    -------
    bytes
        80-byte header, triangle count, 50 bytes per triangle.
    """
    data = mesh.export(file_type="stl")
    return bytes(data)


# ---- printability ---------------------------------------------------------------------------


def _parts(geom: BaseGeometry) -> list[Polygon]:
    if geom.is_empty:
        return []
    if isinstance(geom, Polygon):
        return [geom]
    return [g for g in getattr(geom, "geoms", []) if isinstance(g, Polygon) and not g.is_empty]


def _n_holes(parts: list[Polygon]) -> int:
    return sum(len(p.interiors) for p in parts)


def _extent(piece: Polygon, opened: BaseGeometry, step_mm: float) -> float:
    """How far a cut-off piece sticks out of the opened outline (sampled on its boundary), mm."""
    if opened.is_empty:
        return np.inf
    pts = shapely.get_coordinates(shapely.segmentize(piece.boundary, step_mm))
    return float(shapely.distance(opened, shapely.points(pts)).max())


def thin_feature_at(
    polygon: Polygon, width_mm: float, settings: SolidSettings = SolidSettings()
) -> tuple[float, float] | None:
    """Where the outline has a feature thinner than ``width_mm``, or None if it has none.

    Parameters
    ----------
    polygon : shapely Polygon, mm
    width_mm : float, mm
        The wall width to test against.
    settings : SolidSettings

    Returns
    -------
    (x, y) mm of a point in the thin feature, or None.
    """
    poly = _check_outline(polygon, "thin_feature_at")
    r = 0.5 * float(width_mm)
    if not r > 0:
        return None
    eroded = poly.buffer(-r, quad_segs=settings.quad_segs)
    opened = eroded.buffer(r, quad_segs=settings.quad_segs)
    cut = poly.difference(opened)
    pieces = sorted(_parts(cut), key=lambda p: -p.area)
    if eroded.is_empty:
        x, y = poly.representative_point().coords[0]
        return (x, y)
    eroded_parts = _parts(eroded)
    # Erosion can only split material and merge holes, never the reverse: any change in the
    # number of parts or holes is a neck or a wall thinner than the width.
    topology_changed = len(eroded_parts) != 1 or _n_holes(eroded_parts) != len(poly.interiors)
    for piece in pieces:
        if topology_changed or _extent(piece, opened, r / 4.0) > settings.tab_extent_factor * 2 * r:
            x, y = piece.representative_point().coords[0]
            return (x, y)
    if topology_changed:  # a break without a piece big enough to show (should not happen)
        x, y = poly.representative_point().coords[0]
        return (x, y)
    return None


def min_feature_mm(polygon: Polygon, settings: SolidSettings = SolidSettings()) -> float:
    """Estimate the thinnest wall of an outline, mm (bisection on :func:`thin_feature_at`).

    Parameters
    ----------
    polygon : shapely Polygon, mm
    settings : SolidSettings

    Returns
    -------
    float, mm
        The smallest width at which a thin feature shows, to ``settings.feature_tol_mm``.
        Corners are not features (see :class:`SolidSettings`); a strip of width t gives t.
    """
    poly = _check_outline(polygon, "min_feature_mm")
    x0, y0, x1, y1 = poly.bounds
    top = min(x1 - x0, y1 - y0) * 1.01  # nothing survives erosion by half the smaller side
    # The test is not monotone in w for a tab (its length is compared with w), so scan upwards
    # on a geometric grid for the first thin width, then bisect below it.
    lo, hi = 0.0, settings.feature_tol_mm
    while hi < top and thin_feature_at(poly, hi, settings) is None:
        lo, hi = hi, hi * settings.feature_scan_ratio
    hi = min(hi, top)
    while hi - lo > settings.feature_tol_mm:
        mid = 0.5 * (lo + hi)
        if thin_feature_at(poly, mid, settings) is None:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


# check_printable's keyword shadows the function's name inside it.
_estimate_min_feature = min_feature_mm


def check_printable(
    polygon: Polygon,
    min_feature_mm: float = 0.8,
    raise_error: bool = False,
    settings: SolidSettings = SolidSettings(),
) -> str | None:
    """Check an outline prints as one body with no wall thinner than the printer's minimum.

    Parameters
    ----------
    polygon : shapely Polygon, mm
    min_feature_mm : float, mm
        Thinnest wall the printer makes reliably (0.8 mm: two 0.4 mm nozzle lines).
    raise_error : bool
        Raise instead of returning the reason.
    settings : SolidSettings

    Returns
    -------
    str or None
        None when printable, else the reason (with where, and the estimated thinnest wall).

    Raises
    ------
    GeometryError
        With the reason, if ``raise_error`` and not printable (or the outline is invalid).
    """
    try:
        poly = _check_outline(polygon, "check_printable")
    except GeometryError as exc:
        if raise_error:
            raise
        return str(exc)
    where = thin_feature_at(poly, min_feature_mm, settings)
    if where is None:
        return None
    thinnest = _estimate_min_feature(poly, settings)
    reason = (
        f"wall thinner than the printable minimum {min_feature_mm:g} mm near "
        f"({where[0]:.3g}, {where[1]:.3g}) mm (thinnest wall about {thinnest:.2g} mm); thicken "
        f"it to at least {min_feature_mm:g} mm or lower min_feature_mm if the printer allows"
    )
    if raise_error:
        raise GeometryError(reason)
    return reason


# ---- the outline as it is written: cleaned, in the design frame or laid flat on the bed -------

#: Vertices within this distance (mm) of the chord between their neighbours are dropped before
#: a solid or a drawing is made (:func:`clean_outline`). Why 1e-6 mm: OpenCascade merges the side
#: faces of two edges that lie in one plane within its linear tolerance (1e-7 mm,
#: ``Precision::Confusion``, build123d's ``clean()``), so a STEP solid of an outline with a
#: collinear vertex has one face fewer than it has edges (the mechanism kind's pads joined to
#: their beams: 22 faces for 24 edges); every vertex this keeps bends the outline by more than
#: 1e-6 mm, which no OpenCascade tolerance merges. 1 nm is far below any printed or cut feature
#: and far above the round-off of the coordinates (~1e-14 mm at 100 mm).
COLLINEAR_TOL_MM = 1e-6

#: The frames a part is written in: ``design`` (the kind's own coordinates: the outline where
#: the kind draws it, e.g. a spring's hub axis at the origin, extruded from z = 0 to its
#: thickness: what an assembly needs) and ``bed`` (laid flat: turned to its smallest enclosing
#: rectangle and moved into the first quadrant, a sheet part as its flat profile: what a
#: printer's bed or a sheet of stock needs).
FRAMES = ("design", "bed")


def clean_outline(polygon: BaseGeometry, tol_mm: float = COLLINEAR_TOL_MM) -> Polygon:
    """The outline without repeated and collinear vertices, counter-clockwise outside.

    Douglas-Peucker simplification (:func:`shapely.simplify`, topology preserved) at
    ``tol_mm``: a vertex goes when the ring stays within ``tol_mm`` of it, so the cleaned
    outline is within ``tol_mm`` of the given one everywhere (its area within
    ``tol_mm`` x perimeter).

    Parameters
    ----------
    polygon : shapely Polygon, mm
    tol_mm : float, mm
        :data:`COLLINEAR_TOL_MM` by default (see there why).

    Returns
    -------
    shapely Polygon, mm

    Raises
    ------
    GeometryError
        When the outline is not one valid polygon, before or after.
    """
    poly = _check_outline(polygon, "clean_outline")
    cleaned = shapely.simplify(poly, float(tol_mm), preserve_topology=True)
    return _check_outline(cleaned, "clean_outline (after removing collinear vertices)")


@dataclass(frozen=True)
class FlatPart:
    """A planar part as it is written: its outline in the x-y plane and its extrusion along z.

    Attributes
    ----------
    outline : shapely Polygon, mm
        Without collinear vertices (:func:`clean_outline`). In the ``bed`` frame: its
        minimum-area bounding rectangle aligned with x and y and its lower-left corner at the
        origin (first quadrant); in the ``design`` frame: where the kind draws it.
    thickness_mm : float, mm
        Extrusion along z, from z = 0 (the out-of-plane thickness; the sheet thickness of a
        sheet part laid flat, the strip's width of one in the design frame).
    footprint_mm : (float, float), mm
        Size of the outline along x and y.
    rotation_deg : float, deg
        Rotation about the origin applied to the kind's outline (counter-clockwise positive),
        before the shift; 0 in the design frame and for a sheet part (its flat profile is drawn
        anew).
    offset_mm : (float, float), mm
        Shift applied after the rotation (0 in the design frame).
    sheet : bool
        The kind's outline was the sheet standing on its edge (length x thickness, extruded by
        the width) and ``outline`` is its flat profile (length x width), laid flat.
    frame : str
        ``bed`` or ``design`` (:data:`FRAMES`).
    """

    outline: Polygon
    thickness_mm: float
    footprint_mm: tuple[float, float]
    rotation_deg: float = 0.0
    offset_mm: tuple[float, float] = (0.0, 0.0)
    sheet: bool = False
    frame: str = "bed"

    def record(self) -> dict[str, object]:
        """What a report says about the part: footprint, thickness and how it was laid."""
        w, h = self.footprint_mm
        return {
            "footprint_mm": [round(w, 4), round(h, 4)],
            "thickness_mm": round(self.thickness_mm, 6),
            "rotated_deg": round(self.rotation_deg, 4),
            "flat_sheet_profile": self.sheet,
        }


#: The minimum-area rectangle must save more than this share of the axis-aligned box's area
#: before a part is turned: a round part (whose rectangle is anywhere) stays as drawn, a part
#: tilted by more than ~0.005 deg is turned.
ALIGN_MIN_GAIN = 1e-3


def lay_flat(polygon: Polygon) -> tuple[Polygon, float, tuple[float, float]]:
    """Turn an outline so its minimum-area bounding rectangle is aligned with x and y, and move
    it into the first quadrant.

    The turn is the smallest of the four that align the rectangle (|angle| <= 45 deg), and it is
    made only when it shrinks the axis-aligned box by more than :data:`ALIGN_MIN_GAIN`.

    Parameters
    ----------
    polygon : shapely Polygon, mm

    Returns
    -------
    (outline, rotation_deg, offset_mm)
        The laid-flat outline (lower-left corner of its bounds at (0, 0)), the rotation about
        the origin (deg, counter-clockwise) and the shift (x, y) mm applied after it.
    """
    from shapely import affinity

    poly = clean_outline(polygon)
    x0, y0, x1, y1 = poly.bounds
    box_area = (x1 - x0) * (y1 - y0)
    rect = shapely.minimum_rotated_rectangle(poly)
    angle = 0.0
    if isinstance(rect, Polygon) and rect.area < (1.0 - ALIGN_MIN_GAIN) * box_area:
        corners = np.asarray(rect.exterior.coords)[:2]
        dx, dy = corners[1] - corners[0]
        edge_deg = float(np.degrees(np.arctan2(dy, dx)))
        angle = -(((edge_deg + 45.0) % 90.0) - 45.0)  # in [-45, 45)
        poly = orient(affinity.rotate(poly, angle, origin=(0.0, 0.0)), sign=1.0)
    x0, y0, _, _ = poly.bounds
    poly = affinity.translate(poly, -x0, -y0)
    return poly, angle, (0.0 - x0, 0.0 - y0)


def sheet_profile(edge: Polygon, width_mm: float) -> tuple[Polygon, float]:
    """The flat profile of a sheet part given standing on its edge.

    A kind may draw a strip cut from sheet (a leaf spring) as its edge view, length x thickness,
    extruded by the strip's width; made from sheet, the part is a length x width profile cut
    from stock of that thickness.

    Parameters
    ----------
    edge : shapely Polygon, mm
        The edge view: a rectangle (at any angle), long side the length, short side the
        thickness.
    width_mm : float, mm
        The strip's width (what the edge view is extruded by).

    Returns
    -------
    (profile, thickness_mm)
        The rectangle length x width at the origin, and the sheet thickness (mm).

    Raises
    ------
    GeometryError
        When the edge view is not a rectangle (then it is not a flat strip).
    """
    poly = _check_outline(edge, "sheet_profile")
    rect = shapely.minimum_rotated_rectangle(poly)
    if poly.interiors or not abs(rect.area - poly.area) <= 1e-6 * rect.area:
        raise GeometryError(
            "a sheet part needs a rectangular edge view (length x thickness); this outline is "
            "not a rectangle, so export it as drawn (drop the kind's 'sheet' hint)"
        )
    if not (np.isfinite(width_mm) and width_mm > 0):
        raise GeometryError(f"sheet width_mm = {width_mm} must be > 0 mm")
    sides = np.hypot(*np.diff(np.asarray(rect.exterior.coords)[:3], axis=0).T)
    length, thickness = float(sides.max()), float(sides.min())
    return Polygon([(0, 0), (length, 0), (length, width_mm), (0, width_mm)]), thickness


#: The ``DesignDetail.info`` key by which a kind says its outline is a sheet standing on its
#: edge (value true): exporters then write the flat profile (:func:`sheet_profile`).
SHEET_HINT = "made_from_sheet"


def flat_part(
    outline: Polygon, height_mm: float, sheet: bool = False, frame: str = "bed"
) -> FlatPart:
    """The part of a kind's outline and height, laid flat on the bed or in the design frame.

    Parameters
    ----------
    outline : shapely Polygon, mm
        The kind's outline (DesignDetail.outline).
    height_mm : float, mm
        Its extrusion height (DesignDetail.height_mm).
    sheet : bool
        The outline is a sheet standing on its edge (:func:`sheet_profile`); laid flat, the
        part is its flat profile, in the design frame it stays the edge view extruded by the
        strip's width (the leaf where it sits in the mechanism).
    frame : str
        ``bed`` (laid flat, :func:`lay_flat`) or ``design`` (the outline where the kind draws
        it, only cleaned of collinear vertices).

    Returns
    -------
    FlatPart
    """
    if not (np.isfinite(height_mm) and height_mm > 0):
        raise GeometryError(f"extrusion height_mm = {height_mm} must be > 0 mm")
    if frame not in FRAMES:
        raise GeometryError(f"frame {frame!r} is not one of {', '.join(FRAMES)}")
    if frame == "design":
        poly = clean_outline(outline)
        return FlatPart(poly, float(height_mm), _size(poly), frame="design")
    if sheet:
        profile, thickness = sheet_profile(outline, float(height_mm))
        flat, angle, offset = lay_flat(profile)
        return FlatPart(flat, thickness, _size(flat), 0.0, offset, True)
    flat, angle, offset = lay_flat(outline)
    return FlatPart(flat, float(height_mm), _size(flat), angle, offset, False)


def _size(poly: Polygon) -> tuple[float, float]:
    x0, y0, x1, y1 = poly.bounds
    return (float(x1 - x0), float(y1 - y0))


# ---- STEP (optional: an OCC-based library) ---------------------------------------------------


def _n_edges(ring) -> int:
    """Edges of a closed ring, a repeated vertex (a zero-length edge) not counted."""
    xy = np.asarray(ring.coords)
    return int(np.count_nonzero(np.any(np.diff(xy, axis=0) != 0.0, axis=1)))


class StepUnavailable(FlexoptError, ImportError):
    """STEP needs build123d (``pip install 'flexopt[step]'``), which is not installed (the
    pipeline writes STEP only with it; :func:`step_bytes` needs it for an outline the direct
    writer refuses)."""


def step_bytes(part: FlatPart) -> bytes:
    """The part as a STEP solid (AP214, mm): written directly (:mod:`geometry.step_writer`),
    or via build123d (OpenCascade) where the direct writer refuses the outline.

    The direct writer writes the same B-rep OpenCascade makes of the prism (a planar side face
    per outline edge, top and bottom, line edges, the outline's coordinates exactly), ~30x
    faster: OpenCascade's STEP transfer took ~17 s of a SEA spring's 9 279 edges
    (docs/benchmarks.md). It refuses (and OpenCascade writes) an outline with an edge, or a
    gap between two rings, shorter than :data:`geometry.step_writer.MIN_FEATURE_MM`.

    Parameters
    ----------
    part : FlatPart
        Its outline (holes become through-holes) extruded by its thickness along z.

    Returns
    -------
    bytes
        The STEP file's text.

    Raises
    ------
    StepUnavailable
        When the outline needs OpenCascade and build123d cannot be imported.
    GeometryError
        When the outline is not a valid polygon, or OpenCascade does not make one valid solid
        of the expected volume.
    """
    poly = part.outline
    if not poly.is_valid:
        raise GeometryError(
            f"the outline is not a valid polygon ({shapely.is_valid_reason(poly)}); "
            "no STEP solid made of it"
        )
    # OpenCascade merges the faces of collinear edges (COLLINEAR_TOL_MM): none are left, so the
    # direct writer's file and OpenCascade's have the same faces
    poly = orient(clean_outline(poly), sign=1.0)
    from flexopt.geometry.step_writer import MIN_FEATURE_MM, PrismRefused, prism_step

    rings = [poly.exterior, *poly.interiors]
    try:
        gap = min(
            (float(shapely.distance(a, b)) for i, a in enumerate(rings) for b in rings[i + 1 :]),
            default=np.inf,
        )
        if gap < MIN_FEATURE_MM:  # a hole touching the outside or another hole at a point
            raise PrismRefused(f"two rings are {gap:.3g} mm apart")
        coords = [shapely.get_coordinates(r) for r in rings]
        return prism_step(coords, float(part.thickness_mm))
    except PrismRefused:
        return _occ_step_bytes(poly, float(part.thickness_mm))


def _occ_step_bytes(poly: Polygon, thickness_mm: float) -> bytes:
    """:func:`step_bytes` by build123d (OpenCascade), for an outline the direct writer refuses;
    ``poly`` valid and cleaned."""
    try:
        import build123d as bd
    except ImportError as exc:  # also a broken OCP install
        raise StepUnavailable(str(exc)) from exc
    import os
    import tempfile

    def wire(ring) -> object:
        pts = [(float(x), float(y), 0.0) for x, y in np.asarray(ring.coords)[:-1]]
        return bd.Wire.make_polygon(pts, close=True)

    # The checks are shapely's and cheap ones on the result, not OpenCascade's shape analyser
    # (BRepCheck_Analyzer, `solid.is_valid`): on a SEA spring's outline (1976 edges) it took
    # 2.5-3.2 s, most of best.step's time, to confirm what these establish. A valid polygon has
    # simple rings that do not cross, so the face bounded by them is a valid planar face and its
    # prism a valid solid by construction; what can still go wrong in OpenCascade (a ring
    # dropped or misoriented, a hole filled, a sliver) shows in the volume, the face count or
    # the number of solids.
    face = bd.Face(wire(poly.exterior), [wire(r) for r in poly.interiors])
    solid = bd.extrude(face, amount=thickness_mm)
    expected = poly.area * thickness_mm
    edges = sum(_n_edges(r) for r in (poly.exterior, *poly.interiors))
    n_faces, n_solids = len(solid.faces()), len(solid.solids())
    if not abs(solid.volume - expected) <= 1e-6 * expected + 1e-9:
        raise GeometryError(
            f"OpenCascade made a solid of volume {solid.volume:.9g} mm^3, expected area x "
            f"thickness = {expected:.9g} mm^3; export STL or DXF instead"
        )
    if n_solids != 1 or n_faces != edges + 2:
        raise GeometryError(
            f"OpenCascade made {n_solids} solid(s) with {n_faces} faces, expected one with "
            f"{edges + 2} (a side face per outline edge, top and bottom); export STL or DXF instead"
        )
    fd, name = tempfile.mkstemp(suffix=".step")
    os.close(fd)
    try:
        if not bd.export_step(solid, name):
            raise GeometryError("build123d could not write the STEP file; export STL or DXF")
        with open(name, "rb") as fh:
            return fh.read()
    finally:
        os.unlink(name)
