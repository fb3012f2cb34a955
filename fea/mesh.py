"""Quality triangle meshes of planar outlines, and naming parts of them by geometry.

``mesh_polygon`` turns a shapely polygon (holes allowed, units mm) into a :class:`TriMesh` with
Shewchuk's Triangle (``p`` planar straight-line graph, ``q`` minimum angle, ``a`` area bound), then
refines it locally where the caller asks for smaller elements: near fillets, notch hinges or
other small features. ``to_skfem`` hands the mesh to scikit-fem. The ``select_*`` helpers find the
nodes or boundary edges lying on or inside a shapely geometry, so callers can name boundary parts
("clamp", "drive") with the same geometry they built the outline from.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import shapely
import triangle
from flexopt.fea.errors import FeaError
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient

__all__ = [
    "MeshSettings",
    "TriMesh",
    "SizeField",
    "Refinement",
    "mesh_polygon",
    "to_skfem",
    "select_nodes",
    "select_boundary_edges",
]

SizeField = Callable[[np.ndarray], np.ndarray]
"""A target element edge length field: ``size(xy)`` with xy (k, 2) mm returns (k,) mm."""

Refinement = SizeField | Sequence[tuple[BaseGeometry, float]]
"""Either a :data:`SizeField` or a list of ``(shapely geometry, edge length mm)`` regions."""

# Area of an equilateral triangle with unit edge: the area bound handed to Triangle for a target
# edge length h is this times h**2.
_EQUILATERAL_AREA = np.sqrt(3.0) / 4.0


@dataclass(frozen=True)
class MeshSettings:
    """Tolerances of the mesher, one place, each with its reason."""

    # Triangle guarantees termination up to about 33.8 degrees; 30 keeps every element well shaped
    # (P2 stiffness conditioning and stress recovery degrade with slivers) without over-refining.
    min_angle_deg: float = 30.0
    # Each refinement pass splits every too-large triangle at least once, and quality splitting
    # grades the transition; 8 passes reach a 2**8 = 256x size contrast, far beyond what a part
    # needs. Passes stop early once every triangle meets its size.
    max_refine_passes: int = 8
    # A triangle counts as meeting its size when its area is within this factor of the
    # equilateral area for the target edge: Triangle's quality splits leave triangles a little
    # smaller or larger than the bound, and chasing the last few percent only adds elements.
    area_slack: float = 1.05
    # Distance under which a node counts as lying on a selecting geometry. Coordinates are mm
    # and Triangle places boundary points by exact-ish arithmetic, so 1e-6 mm separates "on the
    # line" from "one element away" for any element larger than a micrometre.
    select_tol_mm: float = 1e-6
    # Safety cap: a mesh this large is certainly a units mistake (m given as mm, size 1e-3 ...).
    max_triangles: int = 2_000_000


@dataclass(frozen=True)
class TriMesh:
    """A planar linear-triangle mesh.

    Parameters
    ----------
    points : (n, 2) float, mm
        Node coordinates.
    triangles : (m, 3) int
        Node indices of each triangle, counter-clockwise.
    boundary_edges : (k, 2) int
        Node pairs of the edges on the boundary (outer contour and holes); each edge has the
        material on its left.
    """

    points: np.ndarray
    triangles: np.ndarray
    boundary_edges: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        pts = np.ascontiguousarray(self.points, dtype=float)
        tri = np.ascontiguousarray(self.triangles, dtype=np.int64)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise FeaError(f"TriMesh.points must have shape (n, 2), got {pts.shape}")
        if tri.ndim != 2 or tri.shape[1] != 3 or tri.shape[0] == 0:
            raise FeaError(f"TriMesh.triangles must have shape (m, 3) with m >= 1, got {tri.shape}")
        if tri.min() < 0 or tri.max() >= pts.shape[0]:
            raise FeaError(
                f"TriMesh.triangles index nodes 0..{pts.shape[0] - 1}, got range "
                f"{tri.min()}..{tri.max()}"
            )
        # Counter-clockwise order makes the Jacobian of every element positive, which the FE code
        # relies on for its areas and deformation checks.
        cw = _signed_areas(pts, tri) < 0
        if np.any(cw):
            tri = tri.copy()
            tri[cw] = tri[cw][:, [0, 2, 1]]
        edges = _boundary_edges(tri) if self.boundary_edges is None else self.boundary_edges
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "triangles", tri)
        object.__setattr__(self, "boundary_edges", np.asarray(edges, dtype=np.int64).reshape(-1, 2))
        for name in ("points", "triangles", "boundary_edges"):
            getattr(self, name).setflags(write=False)

    @property
    def n_points(self) -> int:
        """Number of nodes."""
        return int(self.points.shape[0])

    @property
    def n_triangles(self) -> int:
        """Number of triangles."""
        return int(self.triangles.shape[0])

    @property
    def areas_mm2(self) -> np.ndarray:
        """(m,) float, mm^2 — area of each triangle."""
        return _signed_areas(self.points, self.triangles)

    @property
    def area_mm2(self) -> float:
        """Total meshed area, mm^2."""
        return float(self.areas_mm2.sum())

    @property
    def edge_lengths_mm(self) -> np.ndarray:
        """(m, 3) float, mm — lengths of the edges (0-1, 1-2, 2-0) of each triangle."""
        p = self.points[self.triangles]
        return np.linalg.norm(p[:, [1, 2, 0]] - p, axis=2)

    @property
    def min_angle_deg(self) -> float:
        """Smallest interior angle over all triangles, degrees."""
        p = self.points[self.triangles]
        angles = []
        for k in range(3):
            a = p[:, (k + 1) % 3] - p[:, k]
            b = p[:, (k + 2) % 3] - p[:, k]
            cos = np.einsum("ij,ij->i", a, b) / (
                np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
            )
            angles.append(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
        return float(np.min(angles))

    @property
    def boundary_nodes(self) -> np.ndarray:
        """(k,) int — sorted indices of the nodes on the boundary."""
        return np.unique(self.boundary_edges)


def _signed_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    p = points[triangles]
    d1 = p[:, 1] - p[:, 0]
    d2 = p[:, 2] - p[:, 0]
    return 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])


def _boundary_edges(triangles: np.ndarray) -> np.ndarray:
    """Edges used by exactly one triangle, oriented as in that (counter-clockwise) triangle."""
    edges = triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.sort(edges, axis=1)
    # One int64 per edge: unique over a 1-D key is ~10x faster than over rows (axis=0).
    code = key[:, 0] * (int(key.max()) + 1) + key[:, 1]
    _, inverse, counts = np.unique(code, return_inverse=True, return_counts=True)
    return edges[counts[inverse.ravel()] == 1]


def _check_polygon(polygon: Polygon, max_edge_mm: float) -> Polygon:
    if not isinstance(polygon, Polygon):
        raise FeaError(
            f"mesh_polygon needs one shapely Polygon (one body), got {polygon.geom_type}; "
            "mesh the parts separately or union them into one connected polygon"
        )
    if not polygon.is_valid:
        reason = shapely.is_valid_reason(polygon)
        raise FeaError(
            f"mesh_polygon got an invalid polygon ({reason}); fix self-intersections, "
            "e.g. with polygon.buffer(0) or shapely.make_valid"
        )
    if polygon.is_empty or not polygon.area > 0:
        raise FeaError("mesh_polygon got an empty polygon (area 0); check the outline parameters")
    if not (np.isfinite(max_edge_mm) and max_edge_mm > 0):
        raise FeaError(f"max_edge_mm = {max_edge_mm} must be a positive number of mm")
    return orient(polygon, sign=1.0)


def _planar_graph(polygon: Polygon, max_edge_mm: float, lines: Sequence = ()) -> dict:
    """Vertices, segments and hole points of the polygon (and of the closed ``lines`` inside it,
    as constrained segments) as Triangle's input."""
    # Splitting long boundary edges to the target size before meshing gives Triangle a boundary
    # already at resolution, so element size along straight edges does not depend on how the
    # generator happened to sample them.
    poly = shapely.segmentize(polygon, max_edge_mm)
    vertices, segments, holes = [], [], []
    offset = 0
    for k, ring in enumerate([poly.exterior, *poly.interiors]):
        xy = np.asarray(ring.coords, dtype=float)[:-1]
        n = xy.shape[0]
        vertices.append(xy)
        idx = np.arange(n)
        segments.append(offset + np.column_stack([idx, (idx + 1) % n]))
        offset += n
        if k > 0:
            # Any point strictly inside the hole tells Triangle which region to eat.
            holes.append(np.asarray(Polygon(ring).representative_point().coords[0]))
    for line in lines:
        xy = np.asarray(shapely.segmentize(line, max_edge_mm).coords, dtype=float)[:-1]
        n = xy.shape[0]
        vertices.append(xy)
        idx = np.arange(n)
        segments.append(offset + np.column_stack([idx, (idx + 1) % n]))
        offset += n
    graph = {"vertices": np.vstack(vertices), "segments": np.vstack(segments)}
    if holes:
        graph["holes"] = np.vstack(holes)
    return graph


def _size_field(refine: Refinement | None) -> Callable[[np.ndarray], np.ndarray] | None:
    """Turn the refine argument into a function of triangle corner coordinates (m, 3, 2)."""
    if refine is None:
        return None
    if callable(refine):

        def from_field(corners: np.ndarray) -> np.ndarray:
            m = corners.shape[0]
            # Sample corners and centroid: a field that varies within a triangle is honoured at
            # its smallest sampled value.
            samples = np.concatenate([corners, corners.mean(axis=1, keepdims=True)], axis=1)
            h = np.asarray(refine(samples.reshape(-1, 2)), dtype=float).reshape(m, 4)
            if not np.all(np.isfinite(h) & (h > 0)):
                raise FeaError("the refine size field returned a non-positive or non-finite size")
            return h.min(axis=1)

        return from_field
    regions = list(refine)
    for k, item in enumerate(regions):
        if not (
            isinstance(item, tuple | list)
            and len(item) == 2
            and isinstance(item[0], BaseGeometry)
            and float(item[1]) > 0
        ):
            raise FeaError(
                f"refine[{k}] must be a (shapely geometry, edge length mm > 0) pair, got {item!r}"
            )

    def from_regions(corners: np.ndarray) -> np.ndarray:
        tris = shapely.polygons(np.concatenate([corners, corners[:, :1]], axis=1))
        h = np.full(corners.shape[0], np.inf)
        lo, hi = corners.min(axis=1), corners.max(axis=1)
        for geom, size in regions:
            # only a triangle whose box meets the region's box can touch it (the exact test
            # for those alone: a spring's 24 arm pieces each cover a few % of the triangles)
            x0, y0, x1, y1 = geom.bounds
            near = (hi[:, 0] >= x0) & (lo[:, 0] <= x1) & (hi[:, 1] >= y0) & (lo[:, 1] <= y1)
            hit = np.flatnonzero(near)
            hit = hit[shapely.intersects(geom, tris[hit])]
            h[hit] = np.minimum(h[hit], float(size))
        return h

    return from_regions


def mesh_polygon(
    polygon: Polygon,
    max_edge_mm: float,
    refine: Refinement | None = None,
    settings: MeshSettings = MeshSettings(),
    lines: Sequence | None = None,
) -> TriMesh:
    """Mesh a polygon with quality triangles, optionally refined locally.

    Parameters
    ----------
    polygon : shapely Polygon, mm
        The outline; holes (interior rings) are left unmeshed. Must be valid and one body.
    max_edge_mm : float, mm
        Target edge length everywhere (boundary edges are split to at most this length).
    refine : callable or list of (geometry, float), optional
        Local target edge length in mm, either a size field ``size(xy) -> (k,)`` with
        xy (k, 2) mm, or ``(shapely geometry, edge length)`` regions: every triangle touching a
        region is refined to that size. The smaller of this and ``max_edge_mm`` applies.
    settings : MeshSettings
    lines : sequence of closed shapely rings (LinearRing), mm, optional
        Curves strictly inside the polygon meshed as constrained edges (split to at most
        ``max_edge_mm``): every one lies on element edges. A region selected by its nodes (a
        clamp's or a drive's footprint) whose boundary is such a line is the region itself in
        every mesh; otherwise its node set is a jagged approximation that changes with the mesh
        at the scale of its elements (docs/sea_spring.md, "The morph's refinement test").

    Returns
    -------
    TriMesh
        Nodes (n, 2) mm and counter-clockwise triangles (m, 3).

    Raises
    ------
    FeaError
        The polygon is not one valid polygon, or the sizes are not positive.
    """
    poly = _check_polygon(polygon, max_edge_mm)
    estimate = poly.area / (_EQUILATERAL_AREA * max_edge_mm**2)
    if estimate > settings.max_triangles:
        raise FeaError(
            f"max_edge_mm = {max_edge_mm:g} on an outline of {poly.area:.4g} mm^2 would need about "
            f"{estimate:.3g} triangles (cap {settings.max_triangles}); use a larger max_edge_mm "
            "(units are mm)"
        )
    opts = f"pq{settings.min_angle_deg:g}"
    lines = [] if lines is None else list(lines)
    for line in lines:
        if not (line.is_closed and poly.contains(line) and poly.boundary.distance(line) > 1e-6):
            raise FeaError(
                "mesh_polygon's lines must be closed rings strictly inside the polygon "
                f"(one comes {poly.boundary.distance(line):.3g} mm from its outline)"
            )
    graph = _planar_graph(poly, max_edge_mm, lines)
    out = triangle.triangulate(graph, f"{opts}a{_EQUILATERAL_AREA * max_edge_mm**2:.17g}")
    if refine is not None and not callable(refine):
        refine = list(refine)  # read twice below: an iterator would be spent by the first
    local = _size_field(refine)
    # The smallest size the regions ask for: no triangle needs refining while every one is
    # within the area that size allows (exactly the loop's own test with its smallest target,
    # so the same meshes; spares testing every triangle against every region, ~25 ms a spring).
    floor = (
        None
        if local is None or callable(refine)
        else min((float(s) for _, s in refine), default=float("inf"))
    )
    if local is not None:
        for _ in range(settings.max_refine_passes):
            if floor is not None:
                areas = np.abs(_signed_areas(out["vertices"], out["triangles"]))
                least = _EQUILATERAL_AREA * min(floor, max_edge_mm) ** 2
                if np.all(areas <= settings.area_slack * least):
                    break
            corners = out["vertices"][out["triangles"]]
            target = np.minimum(local(corners), max_edge_mm)
            max_area = _EQUILATERAL_AREA * target**2
            areas = np.abs(_signed_areas(out["vertices"], out["triangles"]))
            if np.all(areas <= settings.area_slack * max_area):
                break
            if out["triangles"].shape[0] > settings.max_triangles:
                raise FeaError(
                    f"local refinement exceeded {settings.max_triangles} triangles; the smallest "
                    f"requested size {target.min():g} mm is too small for this outline"
                )
            out = triangle.triangulate(
                {
                    "vertices": out["vertices"],
                    "triangles": out["triangles"],
                    "segments": out["segments"],
                    "triangle_max_area": max_area,
                },
                f"r{opts}a",
            )
    mesh = TriMesh(out["vertices"], out["triangles"])
    # Triangle only ever adds points; a mesh whose area differs from the polygon's means a hole
    # point fell outside its hole or a ring was dropped, which must not pass silently.
    if not np.isclose(mesh.area_mm2, poly.area, rtol=1e-9, atol=0.0):
        raise FeaError(
            f"meshed area {mesh.area_mm2:.9g} mm^2 differs from polygon area {poly.area:.9g} mm^2; "
            "the polygon is probably degenerate (touching rings or slivers)"
        )
    return mesh


def to_skfem(
    mesh: TriMesh,
    boundaries: dict[str, BaseGeometry] | None = None,
    tol_mm: float | None = None,
):
    """The mesh as a scikit-fem ``MeshTri`` (linear geometry; use ElementTriP2 on it for P2).

    Parameters
    ----------
    mesh : TriMesh
    boundaries : dict of name -> shapely geometry, optional
        Named boundary parts: each becomes a scikit-fem boundary (``skmesh.boundaries[name]``,
        usable as ``basis.get_dofs(name)`` or ``FacetBasis(skmesh, e, facets=name)``) holding
        the boundary facets that lie on or inside the geometry.
    tol_mm : float, mm, optional
        Selection tolerance (default ``MeshSettings.select_tol_mm``).

    Returns
    -------
    skfem.MeshTri
        Same nodes and triangles, transposed to scikit-fem's (2, n) and (3, m) layout.

    Raises
    ------
    FeaError
        A named boundary selects no boundary facet.
    """
    from skfem import MeshTri

    # sort_t=False keeps the counter-clockwise node order of each triangle.
    skmesh = MeshTri(mesh.points.T.copy(), mesh.triangles.T.copy(), sort_t=False)
    if not boundaries:
        return skmesh
    tol = MeshSettings().select_tol_mm if tol_mm is None else float(tol_mm)
    facets = skmesh.boundary_facets()
    ends = skmesh.p[:, skmesh.facets[:, facets]]  # (2 coords, 2 ends, k)
    probes = np.stack([ends[:, 0], 0.5 * (ends[:, 0] + ends[:, 1]), ends[:, 1]], axis=-1)
    probes = probes.transpose(1, 2, 0).reshape(-1, 2)  # (k * 3, 2)
    named = {}
    for name, geom in boundaries.items():
        d = shapely.distance(geom, shapely.points(probes)).reshape(-1, 3)
        hit = facets[np.all(d <= tol, axis=1)]
        if hit.size == 0:
            raise FeaError(
                f"boundary '{name}' selects no boundary facet (tolerance {tol:g} mm); put its "
                "geometry on the outline"
            )
        named[name] = hit
    return skmesh.with_boundaries(named)


def select_nodes(
    mesh: TriMesh,
    geometry: BaseGeometry,
    tol_mm: float | None = None,
    boundary_only: bool = False,
) -> np.ndarray:
    """Nodes lying on or inside a geometry.

    Parameters
    ----------
    mesh : TriMesh
    geometry : shapely geometry, mm
        A LineString (a boundary part), a Polygon (a pad region), a Point, or a collection.
    tol_mm : float, mm, optional
        Distance under which a node counts as on the geometry (default ``select_tol_mm``).
    boundary_only : bool
        Keep only boundary nodes.

    Returns
    -------
    (k,) int
        Sorted node indices.
    """
    tol = MeshSettings().select_tol_mm if tol_mm is None else float(tol_mm)
    candidates = mesh.boundary_nodes if boundary_only else np.arange(mesh.n_points)
    d = shapely.distance(geometry, shapely.points(mesh.points[candidates]))
    return np.sort(candidates[d <= tol])


def select_boundary_edges(
    mesh: TriMesh, geometry: BaseGeometry, tol_mm: float | None = None
) -> np.ndarray:
    """Boundary edges lying on or inside a geometry (both ends and midpoint within tolerance).

    Parameters
    ----------
    mesh : TriMesh
    geometry : shapely geometry, mm
    tol_mm : float, mm, optional
        Default ``select_tol_mm``.

    Returns
    -------
    (k,) int
        Row indices into ``mesh.boundary_edges``.
    """
    tol = MeshSettings().select_tol_mm if tol_mm is None else float(tol_mm)
    p = mesh.points[mesh.boundary_edges]
    probes = np.stack([p[:, 0], 0.5 * (p[:, 0] + p[:, 1]), p[:, 1]], axis=1)
    d = shapely.distance(geometry, shapely.points(probes.reshape(-1, 2))).reshape(-1, 3)
    return np.flatnonzero(np.all(d <= tol, axis=1))
