"""Frictionless contact between facing boundaries of a plane-stress part (node to segment).

A flat part whose slots close under load (the windings of a torsional spring) or two bodies of
one mesh pressed together: the boundary nodes of one side must not pass through the boundary
of the other. :class:`ContactPlaneStressModel` is a :class:`fea.plane_stress.PlaneStressModel`
whose nonlinear internal force and tangent carry a penalty contact term, so the same Newton
iteration (with its cut-backs, solvers and predictors) solves the contact problem; everything
else of the model is unchanged, and without an active contact pair its answers are the plain
model's to the bit.

Formulation (docs/plane_stress.md, "Contact"):

* **Surfaces.** The mesh's boundary (edges with the material on their left) as a polyline
  through every FE node on it: vertex, P2 mid-side node, vertex. Each boundary node is a
  *slave* point with a length weight ``w`` (P2: Simpson's 1/6, 2/3, 1/6 of each edge; P1: half
  of each edge), so a uniform pressure gives exactly the element's consistent nodal forces.
* **Pairs.** :class:`SelfContact`: every boundary node against every boundary segment within
  ``reach_mm`` of it in the current configuration that faces it (outward normals more than
  ``facing_deg`` apart), lies more than ``3 reach_mm`` away along the boundary (not the same
  wall) and has the node in front of it in the undeformed part (not the far wall of the node's
  own member): the two sides of every slot, found from the mesh. :class:`ContactPair`: the
  nodes of one declared side against the segments of the other, both ways. The pairs are
  searched again in every state (:func:`candidates`): the sides of a slot slide past each
  other by more than a segment.
* **Gap.** For a slave point s and a master segment p -> q in the current configuration,
  ``g = (x_s - x_p) . n`` with ``n`` the segment's outward unit normal; each slave takes its
  nearest candidate segment (distance to the segment). Contact is active where ``g < 0`` and
  the projection falls on the segment.
* **Penalty.** Energy ``W = 1/2 k g^2`` per active slave, ``k = eps w b / 2`` with the contact
  pressure stiffness ``eps = alpha E / h`` (N/mm^3; ``h`` the boundary edge length at the slave,
  ``alpha`` :attr:`ContactSettings.penalty_factor`, ``b`` the thickness) and the 1/2 because
  each side is slave once (two-pass, symmetric). The contact pressure is ``p = eps (-g)`` and
  the penetration ``-g = p h / (alpha E)``: mesh-scaled, so it shrinks with the mesh; the
  answer's error is O(1/alpha) (tests/fea/test_plane_stress_contact.py checks both).
* **Tangent.** The exact Hessian of W: ``k (grad g grad g^T + g hess g)``, with the derivatives
  of the gap with respect to the six coordinates of s, p, q in closed form (:func:`gap_terms`),
  so Newton keeps its quadratic rate inside an active set.
* **Line search.** W is only once differentiable where a node touches; when contact is active
  and a full Newton step raises the residual, the step is halved (up to
  :attr:`ContactSettings.max_halvings` times) and the lowest residual kept.

Units: mm, N, MPa, N/mm^3 (penalty pressure stiffness).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
import scipy.sparse as sp
import shapely
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import TriMesh
from flexopt.fea.plane_stress import (
    Clamp,
    Drive,
    PlaneStressModel,
    PlaneStressResponse,
    PlaneStressSettings,
)
from scipy.spatial import cKDTree
from shapely.geometry.base import BaseGeometry

__all__ = [
    "ContactPair",
    "ContactPlaneStressModel",
    "ContactSettings",
    "ContactSurfaces",
    "SelfContact",
    "build_surfaces",
    "candidates",
    "free_gap_mm",
    "gap_terms",
    "nearest",
]


@dataclass(frozen=True)
class SelfContact:
    """The boundary against itself where it faces itself across a narrow gap (slots).

    reach_mm : float, mm — a node and a segment farther apart than this in the current state are
        not paired (larger than an element, so a closing wall is found before it touches); a
        node and a segment less than 3 reach_mm apart along the boundary are never paired (the
        same wall).
    facing_deg : float, degrees — the outward normals of a node and a segment must be more than
        this apart (180: exactly opposite) to pair them; 120 keeps the two walls of a slot and
        its rounded end and leaves out neighbours along one wall.
    region : shapely geometry, optional — only boundary nodes and segments within it (default
        the whole boundary).
    """

    reach_mm: float = 3.0
    facing_deg: float = 120.0
    region: BaseGeometry | None = None


@dataclass(frozen=True)
class ContactPair:
    """Two declared boundary parts that may touch (each side slave of the other once).

    side_a, side_b : shapely geometry, mm — the boundary nodes within ``select_tol_mm`` of it
        (and the boundary segments with both ends so) form the side.
    reach_mm : float, mm — as :class:`SelfContact`.
    """

    side_a: BaseGeometry
    side_b: BaseGeometry
    reach_mm: float = 3.0


@dataclass(frozen=True)
class ContactSettings:
    """The penalty and the activation, each with its reason."""

    # eps = penalty_factor * E / h: a contact pressure p penetrates p h / (alpha E), i.e.
    # p / (alpha E) of an element size, and the answer's error is O(1 / alpha). At 1 the
    # 2500 MPa where a steel spring's windings first touch (E = 190 GPa, h = 0.2 mm) penetrate
    # 2.6 um, 0.1 % of the 2 mm slot, and the overload torque is within 0.05 % of alpha = 10's
    # (docs/plane_stress.md, Contact). Larger alpha converges the same answer but a node-to-
    # segment contact at a corner then costs Newton 5-10 times the iterations (the penalty
    # tangent is stiffer than the windings by alpha times their aspect ratio).
    penalty_factor: float = 1.0
    # A slave whose projection falls this fraction of a segment beyond its ends still counts
    # on it: at a convex corner of the master polyline the projection misses both segments by
    # a little; without the slack such a slave would slip through.
    projection_slack: float = 0.02
    # Step halvings of the line search when contact is active and a full Newton step raises the
    # residual (ContactPlaneStressModel._newton_update): 6 reach 1/64 of the step.
    max_halvings: int = 6


@dataclass
class ContactSurfaces:
    """The contact points, segments and declared pairings of a mesh (built once per model).

    Attributes
    ----------
    dofs : (n_pts, 2) int — the x and y DOF of each boundary FE node.
    X : (n_pts, 2) float, mm — their undeformed positions.
    weight_mm : (n_pts,) float, mm — length each point carries (Simpson weights on P2).
    h_mm : (n_pts,) float, mm — boundary edge length at the point (the penalty's mesh scale).
    seg : (n_seg, 2) int — point indices of each boundary segment, material on its left.
    loop : (n_pts,) int — the boundary loop of each point; arc_mm (n_pts,) mm its position
        along it; loop_mm (n_loops,) mm each loop's length.
    ways : list of (slave mask (n_pts,), master mask (n_seg,), reach mm, cos of the facing
        angle, least separation along the boundary mm): one per pass of each declaration.
    """

    dofs: np.ndarray
    X: np.ndarray
    weight_mm: np.ndarray
    h_mm: np.ndarray
    seg: np.ndarray
    loop: np.ndarray
    arc_mm: np.ndarray
    loop_mm: np.ndarray
    ways: list = field(default_factory=list)


def _outward(t: np.ndarray) -> np.ndarray:
    """Outward unit normals (k, 2) of segments with direction t (k, 2), material on the left."""
    n = np.column_stack([t[:, 1], -t[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def _loops(seg: np.ndarray, X: np.ndarray, n_pts: int) -> tuple:
    """Loop index and arc position (mm) of every point, and the loops' lengths (mm)."""
    nxt = np.full(n_pts, -1)
    nxt[seg[:, 0]] = seg[:, 1]
    loop = np.full(n_pts, -1)
    arc = np.zeros(n_pts)
    lengths = []
    for start in range(n_pts):
        if loop[start] >= 0 or nxt[start] < 0:
            continue
        k, i, s = len(lengths), start, 0.0
        while loop[i] < 0:
            loop[i], arc[i] = k, s
            j = nxt[i]
            s += float(np.hypot(*(X[j] - X[i])))
            i = j
        lengths.append(s)
    return loop, arc, np.asarray(lengths)


def build_surfaces(
    model: PlaneStressModel, surfaces: SelfContact | ContactPair | list
) -> ContactSurfaces:
    """The boundary polyline of ``model``'s mesh and the declared pairings.

    Raises
    ------
    FeaError
        A bad declaration, or a pair side that selects no boundary node.
    """
    mesh = model.mesh
    basis = model.basis
    edges = np.asarray(mesh.boundary_edges)  # (k, 2), material on the left
    nodal = np.asarray(basis.nodal_dofs)  # (2, n_vertices)
    p2 = model.settings.element == "P2"
    L = np.linalg.norm(mesh.points[edges[:, 1]] - mesh.points[edges[:, 0]], axis=1)
    verts = np.unique(edges)
    vid = np.full(mesh.n_points, -1)
    vid[verts] = np.arange(verts.size)
    dofs = [nodal[:, verts].T]
    X = [mesh.points[verts]]
    hsum = np.zeros(verts.size)
    hcnt = np.zeros(verts.size)
    a, b = vid[edges[:, 0]], vid[edges[:, 1]]
    for end in (a, b):
        np.add.at(hsum, end, L)
        np.add.at(hcnt, end, 1.0)
    h = [hsum / np.maximum(hcnt, 1.0)]
    mid = None
    if p2:
        # The mid-side node of each boundary edge: scikit-fem's facet DOFs, facet found by its
        # (sorted) vertex pair.
        facets = np.asarray(model.skmesh.facets)  # (2, nf), sorted pairs
        n = mesh.n_points
        code = {int(k): i for i, k in enumerate(facets[0] * n + facets[1])}
        lo, hi = np.sort(edges, axis=1).T
        f = np.array([code[int(k)] for k in lo * n + hi])
        mid = verts.size + np.arange(edges.shape[0])
        dofs.append(np.asarray(basis.facet_dofs)[:, f].T)
        X.append(0.5 * (mesh.points[edges[:, 0]] + mesh.points[edges[:, 1]]))
        h.append(L)
        seg = np.concatenate([np.column_stack([a, mid]), np.column_stack([mid, b])])
    else:
        seg = np.column_stack([a, b])
    Xa = np.vstack(X)
    loop, arc, loop_mm = _loops(seg, Xa, Xa.shape[0])
    tol = model.settings.select_tol_mm
    items = surfaces if isinstance(surfaces, list | tuple) else [surfaces]
    ways = []
    side = np.zeros(Xa.shape[0], dtype=bool)  # the points of some contact side
    for item in items:
        if isinstance(item, SelfContact):
            if not (item.reach_mm > 0 and 90.0 <= item.facing_deg <= 180.0):
                raise FeaError(
                    f"self-contact: reach_mm = {item.reach_mm} must be > 0 and facing_deg = "
                    f"{item.facing_deg} in [90, 180]"
                )
            on = _near(item.region, Xa, tol)
            cos_max = math.cos(math.radians(item.facing_deg))
            # a node and a segment of one wall are closer than this along the boundary: the
            # two sides of a slot are at least about its width times pi / 2 apart (round end)
            ways.append((on, on[seg[:, 0]] & on[seg[:, 1]], item.reach_mm, cos_max,
                         3.0 * item.reach_mm))  # fmt: skip
            side |= on
        elif isinstance(item, ContactPair):
            if not item.reach_mm > 0:
                raise FeaError(f"contact pair: reach_mm = {item.reach_mm} must be > 0")
            for s_geom, m_geom, name in ((item.side_a, item.side_b, "side_a"),
                                         (item.side_b, item.side_a, "side_b")):  # fmt: skip
                s_on, m_on = _near(s_geom, Xa, tol), _near(m_geom, Xa, tol)
                if not s_on.any():
                    raise FeaError(f"contact pair: {name} selects no boundary node")
                ways.append((s_on, m_on[seg[:, 0]] & m_on[seg[:, 1]], item.reach_mm, 0.0, 0.0))
                side |= s_on
        else:
            raise FeaError(f"contact surfaces must be SelfContact or ContactPair, got {item!r}")
    # A point's length is that of its boundary edges on a contact side (both ends on it): the
    # end node of a side must not carry the edge round the corner, or a uniform pressure would
    # not give the element's consistent nodal forces (the corner would press twice).
    counted = side[a] & side[b]
    w = np.zeros(verts.size)
    for end in (a, b):
        np.add.at(w, end[counted], (L / 6.0 if p2 else L / 2.0)[counted])
    weight = [np.where(w > 0, w, 0.5 * hsum / np.maximum(hcnt, 1.0))]
    if p2:
        weight.append(2.0 * L / 3.0)
    return ContactSurfaces(
        dofs=np.vstack(dofs).astype(np.int64),
        X=Xa,
        weight_mm=np.concatenate(weight),
        h_mm=np.concatenate(h),
        seg=seg.astype(np.int64),
        loop=loop,
        arc_mm=arc,
        loop_mm=loop_mm,
        ways=ways,
    )


def _near(geom: BaseGeometry | None, X: np.ndarray, tol: float) -> np.ndarray:
    if geom is None:
        return np.ones(X.shape[0], dtype=bool)
    return shapely.distance(geom, shapely.points(X)) <= tol


def candidates(surf: ContactSurfaces, x: np.ndarray) -> np.ndarray:
    """(k, 3) int (slave, p, q) pairs that may touch in the configuration x (n_pts, 2) mm.

    Searched anew in every state (the sides of a slot slide along each other by more than a
    segment): a slave point and a master segment within ``reach`` of each other now, facing
    (outward normals more than the facing angle apart now), apart along the boundary (self
    contact), and the slave in front of the segment's line in the undeformed part (so a node
    is never paired with the far wall of its own member, which faces it from behind).
    """
    seg, X = surf.seg, surf.X
    t = x[seg[:, 1]] - x[seg[:, 0]]
    L = np.linalg.norm(t, axis=1)
    n_seg = _outward(t)
    n_pt = np.zeros_like(x)
    np.add.at(n_pt, seg[:, 0], n_seg)
    np.add.at(n_pt, seg[:, 1], n_seg)
    n_pt /= np.maximum(np.linalg.norm(n_pt, axis=1, keepdims=True), 1e-300)
    T = X[seg[:, 1]] - X[seg[:, 0]]
    N_seg = _outward(T)
    mid = 0.5 * (x[seg[:, 0]] + x[seg[:, 1]])
    tree = cKDTree(x)
    out = []
    for slaves, masters, reach, cos_max, min_arc in surf.ways:
        js = np.flatnonzero(masters)
        near = tree.query_ball_point(mid[js], 0.5 * L[js] + reach)
        cnt = np.fromiter(map(len, near), dtype=np.intp, count=len(near))
        if cnt.sum() == 0:
            continue
        j = np.repeat(js, cnt)
        s = np.fromiter(itertools.chain.from_iterable(near), dtype=np.intp, count=cnt.sum())
        keep = slaves[s] & (s != seg[j, 0]) & (s != seg[j, 1])
        if min_arc > 0:
            p = seg[j, 0]
            same = surf.loop[s] == surf.loop[p]
            da = np.abs(surf.arc_mm[s] - surf.arc_mm[p])
            da = np.minimum(da, surf.loop_mm[np.maximum(surf.loop[s], 0)] - da)
            keep &= ~same | (da >= min_arc)
        s, j = s[keep], j[keep]
        facing = np.einsum("ij,ij->i", n_pt[s], n_seg[j]) < cos_max
        front = np.einsum("ij,ij->i", X[s] - X[seg[j, 0]], N_seg[j]) > 0.0
        ok = facing & front
        out.append(np.column_stack([s[ok], seg[j[ok], 0], seg[j[ok], 1]]))
    if not out:
        return np.zeros((0, 3), dtype=np.int64)
    return np.vstack(out).astype(np.int64)


def nearest(surf: ContactSurfaces, x: np.ndarray, slack: float = 0.02) -> tuple:
    """Each slave's nearest candidate segment in the configuration x (n_pts, 2) mm.

    Returns
    -------
    cand : (k, 3) int — :func:`candidates`; first : (m,) int — the row of cand each slave
    keeps (nearest by distance to the segment); on : (m,) bool — its projection falls on the
    segment (within ``slack`` of its length); gap : (m,) mm — signed gap to it; min_gap : float,
    mm — the smallest gap of those on their segment (inf: none); where : (2,) mm — that
    slave's undeformed position.
    """
    cand = candidates(surf, x)
    if cand.shape[0] == 0:
        none = np.zeros(0, dtype=np.int64)
        return cand, none, none.astype(bool), np.zeros(0), math.inf, np.full(2, np.nan)
    cs, cp, cq = cand.T
    t = x[cq] - x[cp]
    d = x[cs] - x[cp]
    L2 = np.einsum("ij,ij->i", t, t)
    xi = np.einsum("ij,ij->i", d, t) / L2
    dist = np.linalg.norm(d - np.clip(xi, 0.0, 1.0)[:, None] * t, axis=1)
    g_all = (d[:, 0] * t[:, 1] - d[:, 1] * t[:, 0]) / np.sqrt(L2)
    # each slave's nearest candidate segment (the first of equally near ones)
    order = np.lexsort((dist, cs))
    first = order[np.concatenate([[True], cs[order][1:] != cs[order][:-1]])]
    g1 = g_all[first]
    on = (xi[first] >= -slack) & (xi[first] <= 1.0 + slack)
    open_g = np.where(on, g1, np.inf)
    i_min = int(np.argmin(open_g))
    min_gap = float(open_g[i_min])
    where = surf.X[cs[first[i_min]]] if math.isfinite(min_gap) else np.full(2, np.nan)
    return cand, first, on, g1, min_gap, where


def free_gap_mm(
    model: PlaneStressModel, u: np.ndarray, surfaces: SelfContact | ContactPair | None = None
) -> tuple[float, np.ndarray]:
    """The signed gap across the contact surfaces of a plain model's state, no contact solved.

    model : PlaneStressModel (with or without contact); u : (N,) mm its displacement;
    surfaces : default ``SelfContact()``. Returns the smallest gap (mm; < 0: the boundary
    passes through itself, which a model without contact allows) and where (undeformed, mm).
    """
    surf = build_surfaces(model, SelfContact() if surfaces is None else surfaces)
    out = nearest(surf, surf.X + u[surf.dofs])
    return out[4], out[5]


# The map from the (s, p, q) coordinates (6) to (t, d) = (x_q - x_p, x_s - x_p) (4).
_M = np.array(
    [
        [0, 0, -1, 0, 1, 0],
        [0, 0, 0, -1, 0, 1],
        [1, 0, -1, 0, 0, 0],
        [0, 1, 0, -1, 0, 0],
    ],
    dtype=float,
)


def gap_terms(
    xs: np.ndarray, xp: np.ndarray, xq: np.ndarray, hessian: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Signed gap of slave points to segments, its gradient and Hessian, in closed form.

    ``g = (x_s - x_p) . n`` with ``n = (t_y, -t_x) / |t|``, ``t = x_q - x_p`` (the outward
    normal of a boundary segment with the material on its left): positive outside, negative
    inside (penetration). With ``c = t_x d_y - t_y d_x`` (``d = x_s - x_p``), ``g = -c / L``:

        dg/dt = -c_t / L + c t / L^3,      dg/dd = -c_d / L,
        d2g/dt2 = (c_t t^T + t c_t^T) / L^3 + c I / L^3 - 3 c t t^T / L^5,
        d2g/dt dd = -C / L + t c_d^T / L^3,   d2g/dd2 = 0,

    with ``c_t = (d_y, -d_x)``, ``c_d = (-t_y, t_x)``, ``C = [[0, 1], [-1, 0]]``, mapped to the
    coordinates (s, p, q) by the constant chain rule ``t = x_q - x_p``, ``d = x_s - x_p``.

    Parameters
    ----------
    xs, xp, xq : (k, 2) float, mm — slave point, segment start, segment end.

    Returns
    -------
    g : (k,) mm; xi : (k,) projection parameter on the segment (0 at p, 1 at q);
    grad : (k, 6) in the order (s_x, s_y, p_x, p_y, q_x, q_y), dimensionless;
    hess : (k, 6, 6) 1/mm, or None without ``hessian``.
    """
    t = xq - xp
    d = xs - xp
    L2 = np.einsum("ij,ij->i", t, t)
    L = np.sqrt(L2)
    c = t[:, 0] * d[:, 1] - t[:, 1] * d[:, 0]
    g = -c / L
    xi = np.einsum("ij,ij->i", d, t) / L2
    c_t = np.column_stack([d[:, 1], -d[:, 0]])
    c_d = np.column_stack([-t[:, 1], t[:, 0]])
    L3 = (L2 * L)[:, None]
    g_t = -c_t / L[:, None] + c[:, None] * t / L3
    g_d = -c_d / L[:, None]
    grad = np.concatenate([g_t, g_d], axis=1) @ _M  # (k, 4) @ (4, 6)
    if not hessian:
        return g, xi, grad, None
    k = g.size
    H = np.zeros((k, 4, 4))
    L3b = L3[:, :, None]
    H[:, :2, :2] = (
        (c_t[:, :, None] * t[:, None, :] + t[:, :, None] * c_t[:, None, :]) / L3b
        + (c / (L2 * L))[:, None, None] * np.eye(2)
        - 3.0 * (c / (L2 * L2 * L))[:, None, None] * t[:, :, None] * t[:, None, :]
    )
    C = np.array([[0.0, 1.0], [-1.0, 0.0]])
    H_td = -C[None] / L[:, None, None] + t[:, :, None] * c_d[:, None, :] / L3b
    H[:, :2, 2:] = H_td
    H[:, 2:, :2] = H_td.transpose(0, 2, 1)
    hess = np.einsum("ai,kab,bj->kij", _M, H, _M)
    return g, xi, grad, hess


@dataclass
class ContactState:
    """Contact at one displacement.

    Attributes
    ----------
    slave : (a,) int — active slave points; gap_mm (a,) their gaps (< 0), pressure_MPa (a,)
        ``eps (-g)``, force_N (a,) ``k (-g)`` (the normal force of the slave's pass).
    min_gap_mm : float, mm — smallest gap over every slave's nearest candidate (inf: none).
    min_gap_xy_mm : (2,) mm — where (the slave's undeformed position).
    f : (N,) N — contact force on the DOFs (added to the internal force).
    K : (N, N) N/mm or None — its tangent.
    """

    slave: np.ndarray
    gap_mm: np.ndarray
    pressure_MPa: np.ndarray
    force_N: np.ndarray
    min_gap_mm: float
    min_gap_xy_mm: np.ndarray
    f: np.ndarray | None = None
    K: sp.csr_matrix | None = None

    @property
    def total_force_N(self) -> float:
        """Sum of the normal forces over both passes: the force carried across the contact."""
        return float(self.force_N.sum())


class ContactPlaneStressModel(PlaneStressModel):
    """A :class:`PlaneStressModel` with frictionless penalty contact in its nonlinear solve.

    Parameters
    ----------
    mesh, material, thickness_mm, clamp, drive, settings, stress_ignore
        As :class:`PlaneStressModel`.
    surfaces : SelfContact, ContactPair or a list of them
        Where contact may happen (pairs searched in every state, :func:`candidates`).
    contact : ContactSettings

    The contact acts in the ``"nonlinear"`` kinematics (the linear solve, used for the linear
    stiffness and the predictor, is the plain model's). :meth:`solve` returns the plain
    response with ``extra["contact"]``: per row (steps + 1,) ``force_N`` (normal force carried
    across all contacts, N), ``min_gap_mm`` (mm, < 0 where in contact: the penetration),
    ``max_pressure_MPa``, ``active_nodes`` (int) and ``in_contact`` (bool); and at the last
    converged row ``pressure_xy_mm`` (a, 2) mm and ``pressure_MPa`` (a,) of the active nodes.
    """

    def __init__(
        self,
        mesh: TriMesh,
        material: Material,
        thickness_mm: float,
        clamp: Clamp,
        drive: Drive,
        surfaces: SelfContact | ContactPair | list,
        settings: PlaneStressSettings | None = None,
        stress_ignore: BaseGeometry | None = None,
        contact: ContactSettings | None = None,
    ) -> None:
        settings = PlaneStressSettings() if settings is None else settings
        contact = ContactSettings() if contact is None else contact
        super().__init__(mesh, material, thickness_mm, clamp, drive, settings, stress_ignore)
        if not (np.isfinite(contact.penalty_factor) and contact.penalty_factor > 0):
            raise FeaError(f"contact penalty_factor = {contact.penalty_factor} must be > 0")
        self.contact_settings = contact
        self.surfaces = build_surfaces(self, surfaces)
        # eps (n_pts,) N/mm^3: the contact pressure per mm of penetration, mesh-scaled
        self.eps = contact.penalty_factor * material.E_MPa / self.surfaces.h_mm
        # k (n_pts,) N/mm: the penalty spring of each slave, half for the two passes
        self.k_slave = 0.5 * self.eps * self.surfaces.weight_mm * self.thickness_mm
        self._log: list[ContactState] = []

    # ---- contact terms ----------------------------------------------------------------------

    def contact_state(self, u: np.ndarray, tangent: bool = True) -> ContactState:
        """Contact force (and tangent) at the displacement u (N,) mm."""
        s = self.surfaces
        x = s.X + u[s.dofs]
        n = self.n_dofs
        cand, first, on, g1, min_gap, where = nearest(s, x, self.contact_settings.projection_slack)
        if first.size == 0:
            empty = np.zeros(0)
            none = np.zeros(0, dtype=np.int64)
            return ContactState(none, empty, empty, empty, math.inf, np.full(2, np.nan))
        cs, cp, cq = cand.T
        act = first[on & (g1 < 0.0)]
        if act.size == 0:
            empty = np.zeros(0)
            return ContactState(np.zeros(0, dtype=np.int64), empty, empty, empty, min_gap, where)
        g, _, grad, hess = gap_terms(x[cs[act]], x[cp[act]], x[cq[act]], tangent)
        k = self.k_slave[cs[act]]
        dof = np.concatenate([s.dofs[cs[act]], s.dofs[cp[act]], s.dofs[cq[act]]], axis=1)
        f = np.bincount(dof.ravel(), weights=((k * g)[:, None] * grad).ravel(), minlength=n)
        K = None
        if tangent:
            Ke = k[:, None, None] * (grad[:, :, None] * grad[:, None, :] + g[:, None, None] * hess)
            rows = np.repeat(dof, 6, axis=1).ravel()
            cols = np.tile(dof, (1, 6)).ravel()
            K = sp.csr_matrix((Ke.ravel(), (rows, cols)), shape=(n, n))
        return ContactState(
            slave=cs[act],
            gap_mm=g,
            pressure_MPa=self.eps[cs[act]] * -g,
            force_N=k * -g,
            min_gap_mm=min_gap,
            min_gap_xy_mm=where,
            f=f,
            K=K,
        )

    # ---- the model's hooks: the nonlinear state carries the contact terms --------------------

    def state(self, u: np.ndarray, kinematics: str):
        """Internal plus contact force (N,) N and tangent (N, N) N/mm at u (N,) mm."""
        if kinematics == "nonlinear":
            return self._state_nonlinear(u)
        return super().state(u, kinematics)

    def _state_nonlinear(self, u: np.ndarray, tangent: bool = True):
        st = super()._state_nonlinear(u, tangent)
        c = self.contact_state(u, tangent=tangent and st.K is not None)
        if c.f is None:  # nothing active: the plain state (its K object kept, and factor)
            return st
        return replace(st, f=st.f + c.f, K=None if st.K is None else (st.K + c.K).tocsr())

    def _newton_update(self, u: np.ndarray, du: np.ndarray, res: float) -> np.ndarray:
        # Penalty contact makes the energy only once differentiable where a node touches: a
        # full Newton step can push a node through a wall and back out, cycling. When contact
        # is active at either end of the step and the full step raises the residual, the step
        # is halved (up to max_halvings times) and the lowest residual taken: a backtracking
        # line search on the residual norm. Without contact the plain full step, unchanged.
        u1 = u + du
        r1 = self._residual_norm(u1)
        if r1 <= res or not (self._in_contact(u) or self._in_contact(u1)):
            return u1
        best_r, best_a, a = r1, 1.0, 1.0
        for _ in range(self.contact_settings.max_halvings):
            a *= 0.5
            ra = self._residual_norm(u + a * du)
            if ra < best_r:
                best_r, best_a = ra, a
            if ra <= res:
                break
        self.counters["contact_line_search"] = self.counters.get("contact_line_search", 0) + 1
        return u + best_a * du

    def _residual_norm(self, u: np.ndarray) -> float:
        f = self._state_nonlinear(u, tangent=False).f
        r = float(np.linalg.norm(self.PT @ f))
        return r if np.isfinite(r) else math.inf

    def _in_contact(self, u: np.ndarray) -> bool:
        return self.contact_state(u, tangent=False).slave.size > 0

    def _measure(self, u: np.ndarray, st: Any, kinematics: str) -> dict:
        self._log.append(self.contact_state(u, tangent=False))
        return super()._measure(u, st, kinematics)

    def solve(
        self,
        kinematics: Literal["linear", "nonlinear"] = "nonlinear",
        guess: np.ndarray | None = None,
    ) -> PlaneStressResponse:
        """:meth:`PlaneStressModel.solve` with the contact rows in ``extra["contact"]``."""
        self._log = []
        res = super().solve(kinematics, guess)
        if kinematics != "nonlinear":
            return res
        n_rows = res.converged.size
        n_conv = int(np.argmin(res.converged)) if not res.ok else n_rows
        states = [self.contact_state(np.zeros(self.n_dofs), tangent=False)]
        states += self._log[len(self._log) - (n_conv - 1) :] if n_conv > 1 else []
        table = {
            "force_N": np.full(n_rows, np.nan),
            "min_gap_mm": np.full(n_rows, np.nan),
            "max_pressure_MPa": np.full(n_rows, np.nan),
            "active_nodes": np.zeros(n_rows, dtype=int),
            "in_contact": np.zeros(n_rows, dtype=bool),
        }
        for i, c in enumerate(states):
            table["force_N"][i] = c.total_force_N
            table["min_gap_mm"][i] = c.min_gap_mm
            table["max_pressure_MPa"][i] = c.pressure_MPa.max() if c.slave.size else 0.0
            table["active_nodes"][i] = c.slave.size
            table["in_contact"][i] = c.slave.size > 0
        last = states[-1]
        table["pressure_xy_mm"] = self.surfaces.X[last.slave]
        table["pressure_MPa"] = last.pressure_MPa
        table["penalty_factor"] = self.contact_settings.penalty_factor
        return replace(res, extra={**res.extra, "contact": table})
