"""Rotationally periodic plane meshes: one sector meshed, the whole made of its rotated copies.

A part with n identical arms, supports that repeat every 2 pi / n about a centre and a load
that is a rigid turn of the hub about that centre is invariant under the rotation R by
2 pi / n; its linear solution is unique, so it is invariant too, ``u(R x) = R u(x)``. One
sector of it, with the nodes of one cut tied to the rotated nodes of the other, gives the
whole part's answer (:class:`fea.solid3d.Solid3DModel` with ``periodic=``): half the 3D model
for the SEA spring's two arms (docs/solid3d.md, "The sector solve").

That needs a mesh that repeats exactly, which Triangle's mesh of the whole outline does not:
here the sector (the outline between the rays at ``angle0`` and ``angle0 + 2 pi / n`` from the
centre) is meshed once, with the same node distribution on its two cuts, and the whole mesh is
its n rotated copies with the cut nodes merged.

Matching nodes on the cuts. Each cut is meshed with its points given as input vertices of the
polygon (Triangle keeps input vertices exactly): a point at distance s from the centre on cut A
has its partner at the same s on cut B. The sector is meshed with the union of the two cuts'
points (mesh_polygon, the plane model's sizes and refinement); Triangle may add points on a cut
(a segment split for quality or size); those are added to both cuts and the sector meshed again,
until the two cuts carry the same points (a few rounds: once the cut is split at its resolution
Triangle splits it no more).

Numbering. The sector's nodes are numbered: the centre (if a node), cut A by distance, cut B in
the same order, then the rest. The whole mesh numbers the centre, the cuts (cut k = cut A of copy
k = cut B of copy k - 1) and then each copy's rest. :func:`fea.solid3d.extrude_mesh` cuts each
prism's quad faces by the order of their two vertices, so with this numbering the tetrahedra of
every copy are the rotated tetrahedra of the sector (except a triangle touching both cuts away
from the centre, possible only for n >= 3 next to the centre, which the whole mesh's test
avoids); the cut faces are split alike from both sides (cut B keeps cut A's order).

The outline is used as sector 0 holds it: a generator that samples curves with vertices that do
not repeat under R (the SEA spring's arcs: 256 of 1622 vertices off by up to 0.03 mm, 0.011 mm^2
of 1704 mm^2) gives a periodic mesh of sector 0's sampling. :func:`rotational_symmetry_problem`
says why a part is not symmetric enough to be solved so.

Units: mm, rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.fea.mesh import Refinement, TriMesh, mesh_polygon
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

__all__ = [
    "PeriodicMesh",
    "periodic_mesh",
    "rotation_matrix",
    "rotational_symmetry_problem",
    "choose_cut_angle",
    "sector_or_reason",
    "whole_field",
]


def rotation_matrix(angle_rad: float) -> np.ndarray:
    """(2, 2) rotation by ``angle_rad`` counter-clockwise."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s], [s, c]])


@dataclass(frozen=True)
class PeriodicMesh:
    """A sector mesh and the whole mesh made of its n rotated copies.

    sector : TriMesh — the sector, nodes (ns, 2) mm: ``fixed`` first, then cut A, cut B, rest.
    whole : TriMesh — the n copies, nodes (nw, 2) mm, cut nodes merged.
    n : int — copies (the arms); the rotation R turns by 2 pi / n counter-clockwise.
    centre_mm : (2,) float, mm — the axis.
    angle0_rad : float, rad — direction of cut A from the centre; cut B at angle0 + 2 pi / n.
    cut_a, cut_b : (c,) int — sector nodes on the cuts, ``points[cut_b] = R points[cut_a]``.
    fixed : (f,) int — sector nodes on the axis (0 or 1), their own partners.
    rounds : int — meshings it took until both cuts carried the same points.
    """

    sector: TriMesh
    whole: TriMesh
    n: int
    centre_mm: np.ndarray
    angle0_rad: float
    cut_a: np.ndarray
    cut_b: np.ndarray
    fixed: np.ndarray
    rounds: int

    @property
    def step_rad(self) -> float:
        """2 pi / n, rad."""
        return 2.0 * math.pi / self.n

    def rotation(self, copies: int = 1) -> np.ndarray:
        """(2, 2) the turn by ``copies`` steps of 2 pi / n (fea.solid3d uses the mesh's own
        methods: it does not import this module, which imports it)."""
        return rotation_matrix(copies * self.step_rad)

    def whole_field(self, field: dict) -> dict:
        """:func:`whole_field` of a sector's field."""
        return whole_field(field, self)

    def rotate(self, xy: np.ndarray, copies: int = 1) -> np.ndarray:
        """xy (k, 2) mm turned by ``copies`` steps about the centre, (k, 2) mm."""
        c = self.centre_mm
        return (np.asarray(xy, dtype=float) - c) @ rotation_matrix(copies * self.step_rad).T + c


def _unit(angle: float) -> np.ndarray:
    return np.array([math.cos(angle), math.sin(angle)])


def _boundary_edges(outline: Polygon) -> tuple[np.ndarray, np.ndarray]:
    """The outline's boundary segments: starts (k, 2) and ends (k, 2), mm."""
    a, b = [], []
    for ring in [outline.exterior, *outline.interiors]:
        xy = np.asarray(ring.coords, dtype=float)
        a.append(xy[:-1])
        b.append(xy[1:])
    return np.vstack(a), np.vstack(b)


def _ray_crossings(a: np.ndarray, b: np.ndarray, centre: np.ndarray, angle: float):
    """Where the ray from ``centre`` at ``angle`` crosses the segments a-b: distances s (k,) mm
    along the ray, the sine of the crossing angle (k,) and the distance from each crossing to
    the nearer end of its segment (k,) mm."""
    d = _unit(angle)
    e = b - a
    den = d[0] * e[:, 1] - d[1] * e[:, 0]  # cross(d, e)
    w = a - centre
    ok = np.abs(den) > 1e-300
    den_s = np.where(ok, den, 1.0)
    s = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / den_s  # along the ray
    t = (w[:, 0] * d[1] - w[:, 1] * d[0]) / den_s  # along the segment
    hit = ok & (s >= 0.0) & (t >= 0.0) & (t < 1.0)
    length = np.linalg.norm(e[hit], axis=1)
    sine = np.abs(den[hit]) / length
    return s[hit], sine, np.minimum(t[hit], 1.0 - t[hit]) * length


def choose_cut_angle(outline: Polygon, n: int, centre_mm=(0.0, 0.0), candidates: int = 720,
                     tol_mm: float = 1e-9, avoid_mm: np.ndarray | None = None,
                     clearance_mm: float = 0.0) -> float:  # fmt: skip
    """The direction of cut A, rad, among ``candidates`` directions in [0, 2 pi / n), by
    these criteria in turn:

    1. its crossings of the outline repeat on cut B (the same distances from the centre
       within ``tol_mm``; else the least mismatch);
    2. both cuts pass at least ``clearance_mm`` from the points ``avoid_mm`` (k, 2) mm and
       their turned copies (the plane-stress peak: a cut's line of nodes through it changes
       the mesh there, and with it the vertex-averaged peak, by more than elsewhere: the SEA
       spring's default design, cut through its peak, read its 2D peak 5 % higher);
    3. no crossing shallower than 30 deg (a shallow one leaves a sliver beside the cut), the
       steepest below that;
    4. the crossings furthest from the outline's vertices (a crossing next to a vertex leaves
       a tiny boundary segment that Triangle refines around).

    Ties go to the smaller angle."""
    a, b = _boundary_edges(outline)
    c = np.asarray(centre_mm, dtype=float)
    step = 2.0 * math.pi / n
    pts = np.zeros((0, 2)) if avoid_mm is None else np.asarray(avoid_mm, float).reshape(-1, 2)
    pts = np.vstack([(pts - c) @ rotation_matrix(j * step).T + c for j in range(n)])
    best = None
    for k in range(candidates):
        ang = (k + 0.5) * step / candidates
        sa, ka, ga = _ray_crossings(a, b, c, ang)
        sb, kb, gb = _ray_crossings(a, b, c, ang + step)
        if sa.size != sb.size:
            continue
        mismatch = float(np.max(np.abs(np.sort(sa) - np.sort(sb)), initial=0.0))
        steep = float(min(ka.min(initial=1.0), kb.min(initial=1.0)))
        gap = float(min(ga.min(initial=np.inf), gb.min(initial=np.inf)))
        near = 0.0
        for ray in (ang, ang + step):  # the avoided points' distance to the ray, mm
            d = _unit(ray)
            w = pts - c
            along = np.maximum(w @ d, 0.0)
            near = max(near, float(np.sum(np.linalg.norm(w - along[:, None] * d, axis=1)
                                          < clearance_mm)))  # fmt: skip
        key = (max(mismatch, tol_mm), near, -min(steep, 0.5), -gap)
        if best is None or key < best[0]:
            best = (key, ang)
    if best is None:
        raise FeaError(f"no direction crosses the outline alike on both cuts of a 1/{n} sector")
    return best[1]


def rotational_symmetry_problem(outline: Polygon, n: int, centre_mm=(0.0, 0.0),
                                regions: dict[str, BaseGeometry] | None = None,
                                area_rtol: float = 1e-4) -> str | None:  # fmt: skip
    """Why the part is not n-fold rotationally symmetric about ``centre_mm``, or None.

    The outline and every region (supports, stress-ignore) turned by 2 pi / n must cover
    themselves: the area of the symmetric difference at most ``area_rtol`` of the outline's
    area (the SEA spring's sampled arcs: 6.5e-6).
    """
    from shapely import affinity

    if not (isinstance(n, int | np.integer) and n >= 2):
        return f"{n} arms: a rotational sector needs 2 or more"
    c = tuple(float(v) for v in centre_mm)
    deg = 360.0 / n
    scale = float(outline.area)
    for name, g in {"outline": outline, **(regions or {})}.items():
        off = g.symmetric_difference(affinity.rotate(g, deg, origin=c)).area
        if off > area_rtol * scale:
            return (
                f"the {name} turned by 360/{n} deg about ({c[0]:g}, {c[1]:g}) misses itself by "
                f"{off:.3g} mm^2 (more than {area_rtol:g} of the outline's {scale:.4g} mm^2)"
            )
    return None


def _wedge(centre: np.ndarray, a0: float, step: float, radius: float) -> Polygon:
    """The wedge from the centre between the angles a0 and a0 + step (<= pi), as a polygon."""
    k = max(2, int(math.ceil(step / (math.pi / 8))))
    arc = [centre + radius * _unit(a0 + step * j / k) for j in range(k + 1)]
    return Polygon([tuple(centre), *map(tuple, arc)])


def _on_ray(xy: np.ndarray, centre: np.ndarray, angle: float, tol: float) -> tuple:
    """(mask (k,) bool, distance s (k,) mm) of the points xy (k, 2) on the ray."""
    d = _unit(angle)
    w = xy - centre
    s = w @ d
    off = np.abs(w[:, 0] * d[1] - w[:, 1] * d[0])
    return (off <= tol) & (s >= -tol), s


def _with_cut_points(ring: np.ndarray, centre, a0: float, a1: float, s_cut: np.ndarray,
                     tol: float) -> np.ndarray:  # fmt: skip
    """A closed ring (k, 2) (open: last != first) with its vertices on either cut snapped to
    the cut's points and each cut edge split at every point of ``s_cut`` (distances) it spans."""
    out = []
    k = ring.shape[0]
    on, s = {}, {}
    for name, ang in (("a", a0), ("b", a1)):
        on[name], s[name] = _on_ray(ring, centre, ang, tol)
    for i in range(k):
        j = (i + 1) % k
        p = ring[i]
        for name, ang in (("a", a0), ("b", a1)):
            if on[name][i]:
                # snap: the nearest cut point (the cut's points include this vertex's s)
                m = int(np.argmin(np.abs(s_cut - s[name][i])))
                p = centre + s_cut[m] * _unit(ang) if s_cut[m] > tol else centre.copy()
                break
        out.append(p)
        for name, ang in (("a", a0), ("b", a1)):
            if on[name][i] and on[name][j]:
                lo, hi = sorted((s[name][i], s[name][j]))
                inner = s_cut[(s_cut > lo + tol) & (s_cut < hi - tol)]
                if s[name][j] < s[name][i]:
                    inner = inner[::-1]
                out.extend(centre + si * _unit(ang) for si in inner)
                break
    return np.asarray(out)


def _merge_sorted(values: np.ndarray, tol: float) -> np.ndarray:
    v = np.sort(np.asarray(values, dtype=float))
    if v.size == 0:
        return v
    keep = np.concatenate([[True], np.diff(v) > tol])
    return v[keep]


def periodic_mesh(
    outline: Polygon,
    n: int,
    max_edge_mm: float,
    refine: Refinement | None = None,
    centre_mm=(0.0, 0.0),
    angle0_rad: float | None = None,
    max_rounds: int = 8,
    avoid_mm: np.ndarray | None = None,
) -> PeriodicMesh:
    """Mesh one 1/n sector of ``outline`` with matching cuts and rotate it into the whole.

    Parameters
    ----------
    outline : shapely Polygon, mm — the part (its n-fold symmetry is the caller's to check:
        :func:`rotational_symmetry_problem`; the sector between the cuts is what is meshed).
    n : int >= 2 — sectors.
    max_edge_mm, refine : as :func:`fea.mesh.mesh_polygon` (applied to the sector).
    centre_mm : (2,) mm — the axis.
    angle0_rad : rad — direction of cut A; default :func:`choose_cut_angle`, the cuts kept
        2 ``max_edge_mm`` from the points ``avoid_mm`` (k, 2) mm (the peak stress) if given.
    max_rounds : int — meshings at most until the cuts match.

    Returns
    -------
    PeriodicMesh

    Raises
    ------
    FeaError — n < 2, cuts that do not match after ``max_rounds``, an invalid sector.
    """
    if not (isinstance(n, int | np.integer) and n >= 2):
        raise FeaError(f"n = {n}: a periodic mesh needs 2 or more sectors")
    n = int(n)
    centre = np.asarray(centre_mm, dtype=float)
    step = 2.0 * math.pi / n
    if angle0_rad is None:
        a0 = choose_cut_angle(outline, n, centre, avoid_mm=avoid_mm, clearance_mm=2 * max_edge_mm)
    else:
        a0 = float(angle0_rad)
    a1 = a0 + step
    x0, y0, x1, y1 = outline.bounds
    radius = 4.0 * (math.hypot(x1 - x0, y1 - y0) + float(np.abs(centre).max()) + 1.0)
    # points closer than this are one point: far below any mesh size, far above round-off
    tol = 1e-9 * radius
    raw = outline.intersection(_wedge(centre, a0, step, radius))
    pieces = [g for g in getattr(raw, "geoms", [raw]) if isinstance(g, Polygon) and g.area > 0]
    if not pieces:
        raise FeaError("the sector holds no part of the outline")
    # the cut points, as distances from the centre: every ring vertex on either cut, each cut
    # edge split at max_edge_mm (as mesh_polygon would); the centre when it is in the part
    s_cut = []
    for poly in pieces:
        for ring in [poly.exterior, *poly.interiors]:
            xy = np.asarray(ring.coords, dtype=float)[:-1]
            for ang in (a0, a1):
                on, s = _on_ray(xy, centre, ang, 1e-7 * radius)
                s_cut.append(s[on])
                k = xy.shape[0]
                for i in np.flatnonzero(on & np.roll(on, -1)):
                    lo, hi = sorted((s[i], s[(i + 1) % k]))
                    m = int(math.ceil((hi - lo) / max_edge_mm))
                    s_cut.append(lo + (hi - lo) * np.arange(1, m) / m)
    s_cut = _merge_sorted(np.concatenate(s_cut), 1e-7 * radius)
    rounds = 0
    for rounds in range(1, max_rounds + 1):  # noqa: B007 (the count is returned)
        meshes = []
        for poly in pieces:
            rings = [
                _with_cut_points(
                    np.asarray(r.coords, dtype=float)[:-1], centre, a0, a1, s_cut, 1e-7 * radius
                )  # fmt: skip
                for r in [poly.exterior, *poly.interiors]
            ]
            meshes.append(mesh_polygon(Polygon(rings[0], rings[1:]), max_edge_mm, refine=refine))
        pts = np.vstack([m.points for m in meshes])
        offs = np.cumsum([0] + [m.n_points for m in meshes])
        tris = np.vstack([m.triangles + o for m, o in zip(meshes, offs[:-1], strict=True)])
        on_a, sa = _on_ray(pts, centre, a0, tol)
        on_b, sb = _on_ray(pts, centre, a1, tol)
        found = _merge_sorted(np.concatenate([sa[on_a], sb[on_b], s_cut]), tol)
        if found.size == s_cut.size and np.allclose(found, s_cut, rtol=0.0, atol=tol):
            break
        s_cut = found
    else:
        raise FeaError(f"the sector's two cuts did not get matching nodes in {max_rounds} meshings")
    return _assemble(pts, tris, n, centre, a0, tol, rounds)


def _assemble(pts, tris, n, centre, a0, tol, rounds) -> PeriodicMesh:
    """Merge the pieces' shared points, number the sector (axis, cut A, cut B, rest) and make
    the whole of its n rotated copies."""
    step = 2.0 * math.pi / n
    # merge coincident points (pieces touching at a point, e.g. on the axis)
    key = np.round(pts / tol).astype(np.int64)
    _, first, back = np.unique(key, axis=0, return_index=True, return_inverse=True)
    back = back.ravel()
    pts, tris = pts[first], back[tris]
    fixed = np.flatnonzero(np.linalg.norm(pts - centre, axis=1) <= tol)
    on_a, sa = _on_ray(pts, centre, a0, tol)
    on_b, sb = _on_ray(pts, centre, a0 + step, tol)
    on_a[fixed] = on_b[fixed] = False
    ia, ib = np.flatnonzero(on_a), np.flatnonzero(on_b)
    ia, ib = ia[np.argsort(sa[ia])], ib[np.argsort(sb[ib])]
    if ia.size != ib.size or not np.allclose(sa[ia], sb[ib], rtol=0.0, atol=tol):
        raise FeaError("the sector's cuts carry different nodes")
    # exact partners: cut B's points are the rotated cut A points
    pts = pts.copy()
    pts[ia] = centre + sa[ia, None] * _unit(a0)
    pts[ib] = centre + sa[ia, None] * _unit(a0 + step)
    rest = np.setdiff1d(np.arange(pts.shape[0]), np.concatenate([fixed, ia, ib]))
    order = np.concatenate([fixed, ia, ib, rest])
    new = np.empty_like(order)
    new[order] = np.arange(order.size)
    spts, stris = pts[order], new[tris]
    sector = TriMesh(spts, stris)
    f, c = fixed.size, ia.size
    cut_a, cut_b = f + np.arange(c), f + c + np.arange(c)
    # the whole: axis, cuts 0..n-1 (cut k = cut A turned k steps), then each copy's rest
    r = rest.size
    nw = f + n * c + n * r
    wpts = np.empty((nw, 2))
    wpts[:f] = spts[:f]
    s_a = sa[ia]
    tri_w = []
    for k in range(n):
        wpts[f + k * c : f + (k + 1) * c] = centre + s_a[:, None] * _unit(a0 + k * step)
        R = rotation_matrix(k * step)
        wpts[f + n * c + k * r : f + n * c + (k + 1) * r] = (
            spts[f + 2 * c :] - centre
        ) @ R.T + centre
        glob = np.concatenate([
            np.arange(f),
            f + k * c + np.arange(c),
            f + ((k + 1) % n) * c + np.arange(c),
            f + n * c + k * r + np.arange(r),
        ])  # fmt: skip
        tri_w.append(glob[stris])
    whole = TriMesh(wpts, np.vstack(tri_w))
    return PeriodicMesh(sector, whole, n, centre, float(a0), cut_a, cut_b,
                        np.arange(f), rounds)  # fmt: skip


def sector_or_reason(
    outline: Polygon,
    n: int,
    max_edge_mm: float,
    refine: Refinement | None,
    regions: dict[str, BaseGeometry],
    solver: str = "auto",
    centre_mm=(0.0, 0.0),
    avoid_mm: np.ndarray | None = None,
) -> tuple[PeriodicMesh | None, str]:
    """The periodic mesh a 3D check solves one sector of, or None and the reason the whole
    model is solved instead; the second item says which in one line (for the record).

    The caller's load must be a rigid turn about ``centre_mm`` (the SEA spring's hub); the
    outline and ``regions`` (supports, stress-ignore) must repeat every 2 pi / n
    (:func:`rotational_symmetry_problem`). ``solver``: the check's
    :attr:`fea.solid3d.Solid3DSettings.solver`; every solver solves the sector (multigrid
    on P^T K P with the tied P1 functions as its coarse space: a plain install, where "auto"
    takes multigrid on a model this large, solves the sector too). ``avoid_mm`` (k, 2) mm:
    points the cuts keep away from (:func:`choose_cut_angle`; the plane-stress peak).
    """
    why = rotational_symmetry_problem(outline, n, centre_mm, regions)
    if why is not None:
        return None, f"whole model: not rotationally symmetric ({why})"
    try:
        pm = periodic_mesh(outline, n, max_edge_mm, refine=refine, centre_mm=centre_mm,
                           avoid_mm=avoid_mm)  # fmt: skip
    except FeaError as exc:
        return None, f"whole model: no periodic mesh ({exc})"
    return pm, (
        f"one sector of {pm.n} (rotational symmetry about ({pm.centre_mm[0]:g}, "
        f"{pm.centre_mm[1]:g}) mm: cut A at {math.degrees(pm.angle0_rad):.4g} deg, cut B "
        f"{360.0 / pm.n:g} deg further tied to cut A turned; {pm.cut_a.size} plane nodes a cut)"
    )


def whole_field(field: dict, pm: PeriodicMesh) -> dict:
    """A sector's :meth:`fea.solid3d.Solid3DModel.last_field` as the whole part's: its n
    copies turned by k 2 pi / n (points and displacements turned, the von Mises stress and
    the counted flags repeated; a cut's nodes appear once in each of its two copies, with
    the same values there, since u_B = R u_A). Keys and units as there."""
    pts, disp = field["points_mm"], field["displacement_mm"]
    c = np.append(pm.centre_mm, 0.0)
    out_p, out_u, out_t = [], [], []
    for k in range(pm.n):
        R = np.eye(3)
        R[:2, :2] = rotation_matrix(k * pm.step_rad)
        out_p.append((pts - c) @ R.T + c)
        out_u.append(disp @ R.T)
        out_t.append(field["tetra10"] + k * pts.shape[0])
    return {
        **field,
        "points_mm": np.vstack(out_p),
        "tetra10": np.vstack(out_t),
        "displacement_mm": np.vstack(out_u),
        "von_mises_MPa": np.tile(field["von_mises_MPa"], pm.n),
        "stress_counted": np.tile(field["stress_counted"], pm.n),
    }
