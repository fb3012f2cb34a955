"""A mesh moved with the shape it was made for, at fixed topology: the smooth map ``X(p)`` that
turns a design's plane-stress responses into smooth functions of its parameters (issue 27 item 1;
docs/sensitivities.md, "Plane stress").

Triangle re-meshes every design, so a response of re-meshed designs jumps at the mesh's own
scale whenever a node appears or moves from one edge to another: it cannot be differentiated
across meshes. At a design ``p0`` the mesh is kept and its vertices are moved with the shape:

* **rigid parts** move rigidly: the hub disc stays, each pad boss (and everything meshed inside
  it: the arm's end, the washer footprint the FE holds) translates with its pad centre, so the
  FE model's clamp and drive node sets and its stress search stay the same;
* **boundary vertices** follow the outline analytically, in the frame of their arm (arm ``k``
  is arm 0 turned by ``k`` pitches): a vertex on an arm flank keeps its curve parameter ``t0``
  and its small offset from the analytic flank ``e(t) = c(t) ± w(t)/2 n(t)`` (the PCHIP
  centreline and width of :func:`geometry.arm_spring.arm_centreline`, ``n`` the unit normal) —
  so it moves as the flank point ``e(t0)`` moves; a vertex on a root fillet keeps its angular
  fraction of the arc and its offset from the circle, the arc being the circle of radius
  ``root_fillet_mm`` tangent to the flank and to the hub rim (or the pad boss), found by a root
  of ``|O(t)| = R_hub + r_f`` (``|O(t) - C| = R_boss + r_f``) with ``O(t)`` the flank's offset
  curve;
* **interior vertices** by a Laplace morph: each displacement component harmonic with the moved
  vertices as its boundary values (the P1 Laplacian of the mesh at ``p0``, factorised once), a
  linear map of the boundary displacement.

The map is smooth in ``p`` near ``p0`` and ``X(p0) = X0`` exactly. The generator itself (shapely
unions, buffers and a simplification of the polygon, a sampling count that follows the arm
length) is not differentiable, so ``dX/dp`` (:meth:`SpiralMorph.jacobian`) is a central
difference of this smooth map (cheap: no FE, no mesh). The morphed mesh is not the re-meshed
design: the two responses differ by the discretisation error, which falls with refinement
(tests/pipeline/test_sea_spring_gradient.py measures it).

Only the spiral topology (:mod:`geometry.arm_spring`) has a morph; the serpentine's arcs and
links (:mod:`geometry.sea_spring`) are not mapped (:class:`MorphError`).

Units: mm, degrees in the parameters as there, rad inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from flexopt.fea.errors import FeaError
from flexopt.fea.mesh import TriMesh
from flexopt.geometry.arm_spring import ArmSpringParams
from flexopt.geometry.sea_spring import SpringFrame
from scipy.interpolate import PchipInterpolator
from scipy.optimize import brentq
from scipy.sparse.linalg import splu
from scipy.spatial import cKDTree

__all__ = ["MorphError", "SpiralMorph", "laplace_matrix"]


class MorphError(FeaError):
    """The mesh cannot be morphed with the shape (a vertex on no known part of the outline, a
    topology without a morph)."""


#: a boundary vertex farther than this from every analytic piece of the outline is refused, mm:
#: the polygon's chords (0.5 mm steps on R >= 5 mm flanks: 6 um; 16 segments a quarter of a
#: 1.5 mm fillet: 2 um) and its 2 um simplification stay far inside it
CLASSIFY_TOL_MM = 0.05
#: at most this fraction of the free boundary vertices may lie on no analytic piece
MAX_UNMAPPED = 0.05
#: the relative step of the central difference of the morph map (of each variable's value,
#: at least 1e-6 of its unit): the map is smooth and cheap, so its truncation ~step^2 is ~1e-12
MAP_STEP = 1e-5


def laplace_matrix(points: np.ndarray, triangles: np.ndarray) -> sp.csr_matrix:
    """(n, n) the P1 stiffness of the Laplacian on a triangle mesh (points (n, 2) mm, triangles
    (m, 3)): ``sum_e area_e grad N_a . grad N_b`` (dimensionless)."""
    x = points[triangles]  # (m, 3, 2)
    d1, d2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    n1 = np.column_stack([d2[:, 1], -d2[:, 0]]) / det[:, None]
    n2 = np.column_stack([-d1[:, 1], d1[:, 0]]) / det[:, None]
    grads = np.stack([-(n1 + n2), n1, n2], axis=1)  # (m, 3, 2)
    ke = 0.5 * np.abs(det)[:, None, None] * np.einsum("eai,ebi->eab", grads, grads)
    rows = np.repeat(triangles, 3, axis=1).ravel()
    cols = np.tile(triangles, (1, 3)).ravel()
    n = points.shape[0]
    return sp.csr_matrix((ke.ravel(), (rows, cols)), shape=(n, n))


@dataclass(frozen=True)
class _Arm:
    """The analytic arm 0 of a design: centreline, width, flanks and their offset curves."""

    p: ArmSpringParams

    def __post_init__(self) -> None:
        m = len(self.p.radii_mm)
        t = np.linspace(0.0, 1.0, m)
        object.__setattr__(self, "_r", PchipInterpolator(t, self.p.radii_mm))
        object.__setattr__(self, "_a", PchipInterpolator(t, np.radians(self.p.angles_deg)))
        k = len(self.p.widths_mm)
        w = (
            PchipInterpolator(np.linspace(0.0, 1.0, k), self.p.widths_mm)
            if k > 1
            else (lambda tt: np.full(np.shape(tt), self.p.widths_mm[0]))
        )
        object.__setattr__(self, "_w", w)

    def centre(self, t: np.ndarray, nu: int = 0) -> np.ndarray:
        """(..., 2) mm: the centreline c(t) (nu = 0) or its first / second t-derivative."""
        r, a = self._r(t), self._a(t)
        cs = np.stack([np.cos(a), np.sin(a)], axis=-1)
        ts = np.stack([-np.sin(a), np.cos(a)], axis=-1)
        if nu == 0:
            return r[..., None] * cs
        r1, a1 = self._r(t, 1), self._a(t, 1)
        if nu == 1:
            return r1[..., None] * cs + (r * a1)[..., None] * ts
        r2, a2 = self._r(t, 2), self._a(t, 2)
        return (r2 - r * a1 * a1)[..., None] * cs + (2 * r1 * a1 + r * a2)[..., None] * ts

    def flank(self, t: np.ndarray, side: float) -> np.ndarray:
        """(..., 2) mm: the band's edge ``c + side w/2 n`` (side +1 left of the centreline)."""
        d = self.centre(t, 1)
        n = np.stack([-d[..., 1], d[..., 0]], axis=-1) / np.linalg.norm(d, axis=-1)[..., None]
        return self.centre(t) + side * 0.5 * np.asarray(self._w(t))[..., None] * n

    def offset(self, t, side: float, dist: float) -> tuple[np.ndarray, np.ndarray]:
        """(O, e), each (..., 2) mm at t (...,): the point ``dist`` outside the flank ``e(t)``
        along its outward normal (the centre of a fillet of radius ``dist`` tangent to the
        flank there)."""
        t = np.asarray(t, dtype=float)
        e = self.flank(t, side)
        h = 1e-6  # the flank's tangent by a central difference in t (smooth; ~1e-12 off)
        de = self.flank(t + h, side) - self.flank(t - h, side)
        nl = np.stack([-de[..., 1], de[..., 0]], axis=-1)
        nl /= np.linalg.norm(nl, axis=-1)[..., None]
        return e + side * dist * nl, e


def _angle(v: np.ndarray) -> float:
    return math.atan2(float(v[1]), float(v[0]))


def _fillet(arm: _Arm, side: float, rf: float, centre: np.ndarray, radius: float, hub: bool):
    """The root fillet of one flank: (O, T_flank, T_circle) mm, tangent to the flank and to the
    circle of ``radius`` about ``centre`` (the hub rim, or a pad boss), outside both."""

    def gap(t):
        o, _ = arm.offset(t, side, rf)
        return np.hypot(*np.moveaxis(o - centre, -1, 0)) - (radius + rf)

    ts = np.linspace(0.0, 0.4, 401) if hub else np.linspace(1.0, 0.6, 401)
    g = gap(ts)
    # hub: the first t where the offset curve leaves the circle grown by rf (g from - to +);
    # pad: walking from the pad end, the first t where it leaves the pad's grown circle
    i = np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:]))
    if i.size == 0:
        raise MorphError("a root fillet's centre is not found along its flank")
    j = int(i[0])
    lo, hi = min(ts[j], ts[j + 1]), max(ts[j], ts[j + 1])
    t = brentq(lambda tt: float(gap(tt)), lo, hi, xtol=1e-15, rtol=1e-15)
    o, e = arm.offset(t, side, rf)
    d = o - centre
    return o, e, centre + d * (radius / float(np.hypot(*d)))


class SpiralMorph:
    """The morph of a spiral SEA spring's mesh (module docstring).

    Parameters
    ----------
    mesh : TriMesh — the mesh of the design ``p0`` (vertices (n, 2) mm).
    p0 : ArmSpringParams — the design it was made for.
    frame : SpringFrame — hub and pad radii.

    Raises
    ------
    MorphError
        A boundary vertex on no piece of the outline within :data:`CLASSIFY_TOL_MM`.
    """

    def __init__(self, mesh: TriMesh, p0: ArmSpringParams, frame: SpringFrame) -> None:
        self.mesh, self.p0, self.frame = mesh, p0, frame
        X = np.asarray(mesh.points, dtype=float)
        n = X.shape[0]
        self.pitch = 2.0 * math.pi / p0.n_arms
        r_hub = frame.hub_radius_mm
        r_boss = frame.pad_radius_mm
        arm0 = _Arm(p0)
        c0 = arm0.centre(np.array(1.0))
        # the arm each vertex belongs to: the nearest pad centre's arm for pad vertices, the
        # nearest arm's flank otherwise (found below); turned into arm 0's frame
        kind = np.full(n, -1)  # 0 hub (fixed), 1 pad (rigid), 2 flank, 3 hub fillet, 4 pad fillet
        arm_of = np.zeros(n, dtype=int)
        kind[np.hypot(X[:, 0], X[:, 1]) <= r_hub + 1e-6] = 0
        for k in range(p0.n_arms):
            ck = _rot(c0, k * self.pitch)
            inside = (np.hypot(*(X - ck).T) <= r_boss + 1e-6) & (kind < 0)
            kind[inside] = 1
            arm_of[inside] = k
        bnd = np.unique(np.asarray(mesh.boundary_edges).ravel())
        free_b = bnd[kind[bnd] < 0]
        fill = {
            (side, hub): _fillet(arm0, side, p0.root_fillet_mm, np.zeros(2) if hub else c0,
                                 r_hub if hub else r_boss, hub)
            for side in (1.0, -1.0) for hub in (True, False)
        } if p0.root_fillet_mm > 0 else {}  # fmt: skip
        ts = np.linspace(0.0, 1.0, 4001)
        self.param = np.zeros((n, 2))  # flank: (t0, side); fillet: (s, side)
        self.offset = np.zeros((n, 2))  # flank: X0 - e(t0); fillet: (radial offset, 0)
        xb = X[free_b]
        best = np.full(free_b.size, np.inf)
        for k in range(p0.n_arms):
            x = _rot(xb, -k * self.pitch)  # arm 0's frame
            for side in (1.0, -1.0):
                fl = arm0.flank(ts, side)
                d, i = cKDTree(fl).query(x)
                take = d < best
                best[take] = d[take]
                v = free_b[take]
                kind[v], arm_of[v] = 2, k
                self.param[v] = np.column_stack([ts[i[take]], np.full(v.size, side)])
                self.offset[v] = x[take] - fl[i[take]]
            for (side, hub), (o, t1, t2) in fill.items():
                rad = np.hypot(*(x - o).T) - p0.root_fillet_mm
                frac = _fractions(x - o, t1 - o, t2 - o)
                take = (frac >= -0.02) & (frac <= 1.02) & (np.abs(rad) < best)
                best[take] = np.abs(rad[take])
                v = free_b[take]
                kind[v], arm_of[v] = (3 if hub else 4), k
                self.param[v] = np.column_stack([frac[take], np.full(v.size, side)])
                self.offset[v] = np.column_stack([rad[take], np.zeros(v.size)])
        # on no analytic piece: a small feature of the generator's polygon operations (e.g. a
        # closing's sliver on the hub rim, 0.36 mm high on the quick study's design); it
        # follows its neighbours by the Laplace morph like an interior vertex
        far = best > CLASSIFY_TOL_MM
        kind[free_b[far]] = -1
        unmapped = [int(v) for v in free_b[far]]
        if len(unmapped) > MAX_UNMAPPED * free_b.size:
            v = unmapped[0]
            raise MorphError(
                f"{len(unmapped)} of {free_b.size} boundary vertices lie on no arm flank or root "
                f"fillet, e.g. {v} at ({X[v, 0]:.4g}, {X[v, 1]:.4g}) mm"
            )
        #: boundary vertices moved by the Laplace morph (on no analytic piece), by index
        self.unmapped = np.array(unmapped, dtype=int)
        self.kind, self.arm_of = kind, arm_of
        self.moved = np.flatnonzero(kind >= 0)  # the vertices the map places
        inner = np.flatnonzero(kind < 0)
        self.inner = inner
        L = laplace_matrix(X, np.asarray(mesh.triangles)).tocsr()
        self._L_ib = L[inner][:, self.moved]
        self._lu = splu(L[inner][:, inner].tocsc()) if inner.size else None
        self._b0 = self._boundary(p0)

    def _boundary(self, p: ArmSpringParams) -> np.ndarray:
        """(len(moved), 2) mm: where the map puts the moved vertices for design ``p``."""
        if p.n_arms != self.p0.n_arms or p.root_fillet_mm != self.p0.root_fillet_mm:
            raise MorphError("the morph keeps the arm count and the root fillet of its design")
        X = np.asarray(self.mesh.points, dtype=float)
        arm0, arm00 = _Arm(p), _Arm(self.p0)
        c, c00 = arm0.centre(np.array(1.0)), arm00.centre(np.array(1.0))
        out = X[self.moved].copy()
        kind = self.kind[self.moved]
        k_of = self.arm_of[self.moved]
        a, side = self.param[self.moved, 0], self.param[self.moved, 1]
        off = self.offset[self.moved]
        rf = p.root_fillet_mm
        fill = {}
        for s in (1.0, -1.0):
            for kd, hub in ((3, True), (4, False)):
                if np.any((kind == kd) & (side == s)):
                    centre = np.zeros(2) if hub else c
                    radius = self.frame.hub_radius_mm if hub else self.frame.pad_radius_mm
                    fill[(s, kd)] = _fillet(arm0, s, rf, centre, radius, hub)
        for k in range(p.n_arms):
            ang = k * self.pitch
            sel = (kind == 1) & (k_of == k)
            out[sel] += _rot(c - c00, ang)
            for s in (1.0, -1.0):
                fl = (kind == 2) & (k_of == k) & (side == s)
                if fl.any():
                    out[fl] = _rot(arm0.flank(a[fl], s) + off[fl], ang)
                for kd in (3, 4):
                    sel = (kind == kd) & (k_of == k) & (side == s)
                    if not sel.any():
                        continue
                    o, t1, t2 = fill[(s, kd)]
                    phi1, span = _arc(t1 - o, t2 - o)
                    phi = phi1 + a[sel] * span
                    rad = rf + off[sel, 0]
                    pts = o + rad[:, None] * np.column_stack([np.cos(phi), np.sin(phi)])
                    out[sel] = _rot(pts, ang)
        return out

    def points(self, p: ArmSpringParams) -> np.ndarray:
        """(n, 2) mm: the mesh's vertices moved to design ``p`` (``X(p0) = X0`` exactly)."""
        X = np.array(self.mesh.points, dtype=float)
        return X + self._extend(self._boundary(p) - self._b0)

    def _extend(self, db: np.ndarray) -> np.ndarray:
        """(n, 2): the displacement of every vertex from that of the moved ones (Laplace)."""
        d = np.zeros((self.mesh.points.shape[0],) + db.shape[1:])
        d[self.moved] = db
        if self._lu is not None:
            rhs = -(self._L_ib @ db.reshape(db.shape[0], -1))
            d[self.inner] = self._lu.solve(np.asarray(rhs)).reshape((-1,) + db.shape[1:])
        return d

    def jacobian(self, params_of, x0: np.ndarray, steps: np.ndarray | None = None) -> np.ndarray:
        """(n, 2, n_var) mm per unit of each variable: ``dX/dx`` at ``x0`` (n_var,), with
        ``params_of(x) -> ArmSpringParams`` the design map; central differences of the boundary
        map (steps ``MAP_STEP`` times each |x|, at least 1e-6), extended by the Laplace morph."""
        x0 = np.asarray(x0, dtype=float)
        if steps is None:
            steps = MAP_STEP * np.maximum(np.abs(x0), 0.1)
        cols = []
        for i in range(x0.size):
            xp, xm = x0.copy(), x0.copy()
            xp[i] += steps[i]
            xm[i] -= steps[i]
            cols.append(
                (self._boundary(params_of(xp)) - self._boundary(params_of(xm))) / (2.0 * steps[i])
            )
        db = np.stack(cols, axis=-1)  # (moved, 2, n_var)
        return self._extend(db)


def _rot(v: np.ndarray, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    v = np.asarray(v, dtype=float)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def _arc(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(start angle, signed span) rad of the shorter arc from direction a to direction b."""
    phi1 = _angle(a)
    span = (_angle(b) - phi1 + math.pi) % (2.0 * math.pi) - math.pi
    return phi1, span


def _fractions(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(k,) where each direction x (k, 2) lies on the shorter arc from a to b (0 at a, 1 at b)."""
    phi1, span = _arc(a, b)
    d = (np.arctan2(x[:, 1], x[:, 0]) - phi1 + math.pi) % (2.0 * math.pi) - math.pi
    return d / span if span != 0 else np.full(x.shape[0], np.inf)
