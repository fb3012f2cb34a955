"""Frictionless contact between the planar beam and rigid stops, inside the nonlinear solve.

A :class:`RigidStop` is a rigid outline in the beam's plane (mm): a point, an open polyline (one
or more line segments: a thin wall, both sides) or a closed polygon (a rigid body). The beam is
its centreline swept by a disk of radius ``t(s)/2`` (half the local in-plane thickness): the
distance between the beam and a stop is the distance between the centreline and the outline minus
``t/2``. Two kinds of contact pairs (node-to-segment, both ways) cover every outline:

* **beam node - stop face**: every mesh node of the beam (P2 vertices and mid-points) against
  every face (segment) of a polyline or polygon, where the node's closest point on the outline is
  inside the face. Gap ``g = n . (x - A) - t/2`` with ``n`` the face's normal towards the node
  (polygon: outward; open polyline: the side the node is on). Linear in the node's position.
* **stop vertex - beam curve**: every point stop, every end of an open polyline and every convex
  corner of a polygon against the beam's centreline, the P2 interpolation
  ``x(xi) = sum_a N_a(xi) x_a`` of each element: ``g = min_xi |V - x(xi)| - t(xi)/2``. A corner
  or a point can press on the beam between nodes, which a node-to-segment check from the beam's
  nodes alone would miss (the point would slip between two nodes).

Enforcement: penalty, inside Newton. A pair with ``g < 0`` stores the energy ``1/2 k g^2``; its
force on the beam is ``-k g grad g`` (N, pushing the beam out of the stop), its tangent
``k (grad g grad g^T + g hess g)``, the exact Hessian of the energy, so Newton keeps its
quadratic convergence once the set of active pairs stops changing. For the vertex-curve pairs
``g`` is a minimum over ``xi``, and its Hessian is that of a minimum function,
``phi_XX - phi_Xxi phi_xixi^-1 phi_xiX`` at the closest point (``phi = |V - x(xi)| - t(xi)/2``;
``phi_XX`` alone when the closest point is an element end).

Penalty stiffness (:class:`ContactSettings`): ``k = penalty_factor x EI / h^3`` per element
(``EI`` at the element's middle, ``h`` its length; a node takes the mean of its elements, a stop
vertex keeps the element it faces in the undeformed state, so that its force does not jump where
the contact slides over an element end). The stiffness of one element of the beam against a
transverse motion of a node is of order ``EI / h^3``, so the factor says how much stiffer than
the beam itself the stop is, whatever the units, the section and the mesh. The default 1e3 keeps
the penetration ``F / k`` far below the mesh's own error (a cantilever pressed on a stop at
mid-span with 20 elements: penetration ~1e-6 of the deflection) while the tangent stays well
conditioned (k ~ 1e3 EI / h^3 is of the order of the axial stiffness EA / h of a slender
element). Every converged row is checked: its largest penetration must stay below
``penetration_tol x t`` (t the thinnest section); :func:`solve_with_stops` traces a path beyond
it again with a 10x stiffer penalty (``max_raises`` times at most) and flags one still beyond it
(``ContactResponse.penetration_ok``, ``message``).

A stop's point or corner exactly on the undeformed centreline overlaps the beam by t/2: it is
refused by name like any other overlap (:func:`overlaps`; the distance's kink there has no
normal, handled in ``_phi``).

Limits: frictionless; rigid stops that do not move; node-to-segment pairs (a face is resolved at
the beam's nodes, a vertex anywhere along the beam); a thin wall (open polyline) must not be
crossed by the centreline inside one increment (the penetration would exceed t/2 there). Two
beams of a mechanism: :class:`BeamPairContact`; a mechanism's bodies and a beam's self contact:
:mod:`fea.body_contact`; the plane-stress self-contact across slots: fea/plane_stress_contact.py.
See docs/contact.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from flexopt.fea.beam import BeamModel, BeamResponse, EndDrive
from flexopt.fea.errors import FeaError

__all__ = [
    "RigidStop",
    "ContactSettings",
    "ContactResponse",
    "BeamContact",
    "contact_rows",
    "contact_over_beams",
    "BeamPairContact",
    "overlaps",
    "solve_with_stops",
    "closest_on_element",
    "vertex_curve_derivatives",
]


@dataclass(frozen=True)
class RigidStop:
    """A rigid outline in the beam's plane.

    Attributes
    ----------
    outline_mm : (m, 2) float, mm — one point (a point stop), or the vertices of an open polyline
        (``closed`` False: m - 1 segments, a thin wall acting on both sides) or of a polygon
        (``closed`` True, m >= 3, either orientation: a rigid body; the beam is kept outside).
    closed : the outline is a polygon.
    name : label of the stop in the outputs.
    """

    outline_mm: np.ndarray
    closed: bool = False
    name: str = ""

    def __post_init__(self) -> None:
        pts = np.array(self.outline_mm, dtype=float).reshape(-1, 2)
        if pts.shape[0] < 1 or not np.all(np.isfinite(pts)):
            raise FeaError(f"stop {self.name!r}: outline_mm must be finite [x, y] pairs")
        if self.closed and pts.shape[0] < 3:
            raise FeaError(f"stop {self.name!r}: a closed outline needs at least 3 points")
        if pts.shape[0] > 1 and np.any(np.hypot(*np.diff(pts, axis=0).T) <= 0.0):
            raise FeaError(f"stop {self.name!r}: repeated consecutive points in the outline")
        pts.setflags(write=False)
        object.__setattr__(self, "outline_mm", pts)

    @classmethod
    def point(cls, xy: tuple[float, float], name: str = "") -> RigidStop:
        """A point stop at ``xy`` (mm): a pin of zero radius."""
        return cls(np.array([xy], dtype=float), False, name)

    @classmethod
    def segment(cls, a: tuple[float, float], b: tuple[float, float], name: str = "") -> RigidStop:
        """A straight wall from ``a`` to ``b`` (mm), acting on both sides."""
        return cls(np.array([a, b], dtype=float), False, name)

    @classmethod
    def polygon(cls, points: np.ndarray, name: str = "") -> RigidStop:
        """A rigid body bounded by the polygon ``points`` (m, 2) mm."""
        return cls(np.asarray(points, dtype=float), True, name)

    # -- the outline's features, as the contact pairs use them
    def faces(self) -> tuple[np.ndarray, np.ndarray]:
        """Face start points ``A`` (f, 2) and end points ``B`` (f, 2), mm; f = 0 for a point."""
        p = self.outline_mm
        if p.shape[0] == 1:
            return np.empty((0, 2)), np.empty((0, 2))
        if self.closed:
            return p, np.roll(p, -1, axis=0)
        return p[:-1], p[1:]

    def contact_vertices(self) -> np.ndarray:
        """(v, 2) mm: the vertices that may press on the beam between nodes: a point stop, the two
        ends of an open polyline (its interior corners too), the convex corners of a polygon."""
        p = self.outline_mm
        if not self.closed:
            return p
        area2 = np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
        e_in = p - np.roll(p, 1, axis=0)
        e_out = np.roll(p, -1, axis=0) - p
        turn = e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0]
        return p[turn * np.sign(area2) > 0.0]

    def inside(self, x: np.ndarray) -> np.ndarray:
        """(k,) bool: the points ``x`` (k, 2) mm are inside the polygon (even-odd rule); all
        False for a point or an open polyline."""
        if not self.closed:
            return np.zeros(x.shape[0], dtype=bool)
        a, b = self.faces()
        xa, ya = a[None, :, 0], a[None, :, 1]
        xb, yb = b[None, :, 0], b[None, :, 1]
        px, py = x[:, None, 0], x[:, None, 1]
        crosses = (ya > py) != (yb > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = xa + (py - ya) * (xb - xa) / (yb - ya)
        return np.sum(crosses & (px < xc), axis=1) % 2 == 1


@dataclass(frozen=True)
class ContactSettings:
    """Penalty contact settings (see the module docstring for the choice).

    Attributes
    ----------
    penalty_factor : k = penalty_factor x EI / h^3 (N/mm) per element of length h (mm), EI at its
        middle (N mm^2).
    penetration_tol : largest accepted penetration as a fraction of the thinnest section's
        thickness.
    max_raises : when a traced path penetrates deeper than the tolerance,
        :func:`solve_with_stops` traces it again with the penalty 10x stiffer, at most this many
        times; a path still beyond it is flagged (``ContactResponse.penetration_ok``), not
        rejected.
    element_length : the h of ``EI / h^3``: "local" (each element's own length) or "mean"
        (the beam's length over its elements, for every element). A graded mesh (a mechanism's
        beams as made: elements of ~0.03 mm in a root's fillet flare, 3 mm at mid-span) makes
        the local ``EI / h^3`` there ~1e6 times the mid-span value, a penalty that round-off
        defeats and Newton cannot converge with; "mean" keeps the penalty of a uniform mesh of
        the same beam (the mechanism engine's choice).
    """

    penalty_factor: float = 1e3
    penetration_tol: float = 1e-3
    max_raises: int = 2
    element_length: Literal["local", "mean"] = "local"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.penalty_factor) and self.penalty_factor > 0.0):
            raise FeaError(f"penalty_factor = {self.penalty_factor} must be > 0")
        if not (np.isfinite(self.penetration_tol) and self.penetration_tol > 0.0):
            raise FeaError(f"penetration_tol = {self.penetration_tol} must be > 0")
        if int(self.max_raises) < 0:
            raise FeaError(f"max_raises = {self.max_raises} must be >= 0")
        if self.element_length not in ("local", "mean"):
            raise FeaError(f"element_length = {self.element_length!r}: use 'local' or 'mean'")


@dataclass(frozen=True)
class ContactResponse:
    """Contact outputs of a traced path, one row per :class:`fea.beam.BeamResponse` row.

    Attributes
    ----------
    names : (n_stops,) the stops' names (``stop<i>`` when unnamed).
    force_N : (rows, n_stops) float, N — magnitude of the resultant force the stop exerts on the
        beam (0 when not touching; NaN for rows that did not converge).
    force_vector_N : (rows, n_stops, 2) float, N — that resultant in x, y.
    gap_mm : (rows, n_stops) float, mm — the smallest signed gap between the beam's surface
        (centreline +- t/2) and the stop: positive = clearance, negative = penetration (of the
        order of the force / k once in contact).
    in_contact : (rows, n_stops) bool — the stop pushes on the beam in that row.
    rows_in_contact : (rows,) bool — some stop does.
    point_mm : (rows, n_stops, 2) float, mm — the contact point on the stop (force-weighted mean
        of the active pairs' points on the outline); NaN when not in contact.
    initial_gap_mm : (n_stops,) float, mm — the gap in the undeformed state.
    closing_value : (n_stops,) float — the driven value (mm or N, as the drive) at which the gap
        first closes: the gap of the last two open rows extrapolated linearly to zero, kept
        between the last open and the first closed row (exact where the gap is linear in the
        driven value, as in small deflection; refine the rows near it otherwise); NaN when it
        never closes (or is closed from the start).
    max_penetration_mm : (rows,) float, mm — the largest penetration over all stops (>= 0).
    penetration_ok : every converged row's penetration is below the tolerance.
    penalty_N_per_mm : (n_elements,) float, N/mm — the penalty stiffness of each element.
    message : why not ``penetration_ok``; empty otherwise.
    extra : tolerance_mm (the penetration tolerance, mm); from :func:`solve_with_stops` also
        penalty_factor (the one used) and raises (how many times it was raised).
    """

    names: tuple[str, ...]
    force_N: np.ndarray
    force_vector_N: np.ndarray
    gap_mm: np.ndarray
    in_contact: np.ndarray
    rows_in_contact: np.ndarray
    point_mm: np.ndarray
    initial_gap_mm: np.ndarray
    closing_value: np.ndarray
    max_penetration_mm: np.ndarray
    penetration_ok: bool
    penalty_N_per_mm: np.ndarray
    message: str = ""
    extra: dict = field(default_factory=dict)


class _Pair:
    """One evaluated contact pair (all quantities at the current state)."""

    __slots__ = ("stop", "gap", "nodes", "grad", "hess", "k", "point")

    def __init__(self, stop, gap, nodes, grad, hess, k, point):
        self.stop = stop  # index of the stop
        self.gap = gap  # mm
        self.nodes = nodes  # (m,) beam node indices the pair involves
        self.grad = grad  # (2 m,) d gap / d (x, y) of those nodes
        self.hess = hess  # (2 m, 2 m) or None (gap linear in the positions)
        self.k = k  # N/mm
        self.point = point  # (2,) mm, the contact point on the stop


class BeamContact:
    """The contact terms of a :class:`fea.beam.BeamModel` against rigid stops.

    An object of this class is passed to :meth:`fea.beam.BeamModel.solve` (``contact=``): its
    :meth:`add` adds the penalty forces and tangent to every assembly. :meth:`pairs` evaluates the
    gaps of a deformed state; :meth:`response` builds the :class:`ContactResponse` of a traced path.

    Parameters
    ----------
    model : the beam.
    stops : the rigid stops.
    settings : ContactSettings.
    """

    def __init__(
        self,
        model: BeamModel,
        stops: tuple[RigidStop, ...] | list[RigidStop],
        settings: ContactSettings = ContactSettings(),
    ) -> None:
        self.model = model
        self.stops = tuple(stops)
        self.settings = settings
        self.names = tuple(st.name or f"stop{i}" for i, st in enumerate(self.stops))
        prof = model.profile
        s_nodes = model.s_nodes
        s_vert = s_nodes[0::2]
        h = np.diff(s_vert)  # (E,) element lengths, mm
        t_nodes = np.interp(s_nodes, prof.arc_length_mm, prof.thickness_mm)
        self._r_nodes = 0.5 * t_nodes  # (n_nodes,) disk radius, mm
        t_mid = t_nodes[1::2]
        ei = model.material.E_MPa * prof.width_mm * t_mid**3 / 12.0  # (E,) N mm^2
        if settings.element_length == "mean":
            h_k = np.full_like(h, float(h.sum()) / h.size)
        else:
            h_k = h
        self.k_elements = settings.penalty_factor * ei / h_k**3  # (E,) N/mm
        # a node takes the mean of its elements' stiffness
        kn = np.zeros(model.n_nodes)
        cnt = np.zeros(model.n_nodes)
        for a in range(3):
            np.add.at(kn, 2 * np.arange(model.n_elements) + a, self.k_elements)
            np.add.at(cnt, 2 * np.arange(model.n_elements) + a, 1.0)
        self._k_nodes = kn / cnt
        self._h_max = float(h.max())
        self.tolerance_mm = settings.penetration_tol * float(t_nodes.min())
        #: the pairs acting in the last :meth:`add`, as (stop, beam nodes) (fea.beam.ContactTerms)
        self.active: frozenset = frozenset()
        self._faces = [st.faces() for st in self.stops]
        self._vertices = [st.contact_vertices() for st in self.stops]
        # The side of a thin wall (open polyline) each node is on, and the side of the beam each
        # stop vertex is on, in the undeformed state (+1 / -1; 0: a vertex beyond the beam's
        # ends, judged by distance alone). A gap measured on that side stays negative when a
        # Newton iterate (a long predictor step) carries the centreline across a wall or the
        # beam across a point: the stop then pushes it back instead of letting it through.
        x0 = model.reference_nodes_mm
        self._face_side = []
        for a, b in self._faces:
            d = b - a
            nrm = np.stack([-d[:, 1], d[:, 0]], axis=1)
            dn = np.einsum("nfk,fk->nf", x0[:, None, :] - a[None], nrm)
            self._face_side.append(np.where(dn >= 0.0, 1.0, -1.0))
        # A vertex keeps the penalty of the element it faces in the undeformed state: with the
        # k of whichever element it touches, the force would jump where the contact point slides
        # over an element end of a tapered beam (a jump Newton cannot follow quadratically).
        closest0 = [[self._closest(v, x0) for v in verts] for verts in self._vertices]
        self._vertex_side = [np.array([c[3] for c in cs]) for cs in closest0]
        self._vertex_k = [np.array([self.k_elements[c[2]] for c in cs]) for cs in closest0]
        self._r_max = float(self._r_nodes.max())

    # ------------------------------------------------------------------ public views

    @property
    def radii_mm(self) -> np.ndarray:
        """(n_nodes,) mm: the disk radius t/2 at each mesh node (read-only view)."""
        return self._r_nodes

    @property
    def k_nodes(self) -> np.ndarray:
        """(n_nodes,) N/mm: each node's penalty stiffness (the mean of its elements')."""
        return self._k_nodes

    @property
    def reach_mm(self) -> float:
        """mm: a point farther than this from every node is clear of the beam's curve
        (two longest elements plus the largest radius)."""
        return 2.0 * self._h_max + self._r_max

    def closest(self, v: np.ndarray, x: np.ndarray) -> tuple[float, float, int, float]:
        """Closest point of the centreline (nodes ``x`` (n_nodes, 2) mm) to ``v`` (2,) mm:
        ``(distance - t/2 mm, xi, element, side)`` (see :meth:`_closest`)."""
        return self._closest(v, x)

    # ------------------------------------------------------------------ gaps

    def pairs(self, x: np.ndarray, active_only: bool = True) -> list[_Pair]:
        """The contact pairs at node positions ``x`` (n_nodes, 2) mm.

        With ``active_only`` only those with a negative gap (pushing), with their derivatives;
        otherwise the closest pair of each stop too (for the gap output: derivatives unused).
        """
        out: list[_Pair] = []
        for i, st in enumerate(self.stops):
            found = self._face_pairs(i, st, x, active_only)
            found += self._vertex_pairs(i, x, active_only)
            if active_only:
                out += [p for p in found if p.gap < 0.0]
            elif found:
                act = [p for p in found if p.gap < 0.0]
                out += act if act else [min(found, key=lambda p: p.gap)]
        return out

    def _face_pairs(self, i: int, st: RigidStop, x: np.ndarray, active_only: bool) -> list[_Pair]:
        """Beam node - stop face pairs: each node against its closest face, where the closest
        point of the whole outline is inside that face (a vertex is a vertex-curve pair)."""
        a, b = self._faces[i]
        if a.shape[0] == 0:
            return []
        d = b - a  # (f, 2)
        ell = np.hypot(d[:, 0], d[:, 1])
        tau = d / ell[:, None]
        nrm = np.stack([-tau[:, 1], tau[:, 0]], axis=1)  # left normal
        rel = x[:, None, :] - a[None, :, :]  # (n, f, 2)
        lam = np.einsum("nfk,fk->nf", rel, tau) / ell[None, :]
        lam_c = np.clip(lam, 0.0, 1.0)
        foot = a[None] + lam_c[..., None] * d[None]
        dist = np.hypot(*(x[:, None, :] - foot).transpose(2, 0, 1))  # (n, f)
        f_best = np.argmin(dist, axis=1)
        n_idx = np.arange(x.shape[0])
        lam_b = lam[n_idx, f_best]
        interior = (lam_b > 0.0) & (lam_b < 1.0)
        dn = np.einsum("nk,nk->n", rel[n_idx, f_best], nrm[f_best])  # signed, left normal
        if st.closed:
            # outward normal: the polygon's orientation; inside = negative distance
            area2 = np.sum(a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1])
            side = -np.sign(area2) * np.ones_like(dn)
            inside = st.inside(x)
            dist_s = np.where(inside, -dist[n_idx, f_best], dist[n_idx, f_best])
        else:
            side = self._face_side[i][n_idx, f_best]
            dist_s = side * dn
        gap = dist_s - self._r_nodes
        cand = np.flatnonzero(interior & (gap < 0.0)) if active_only else np.flatnonzero(interior)
        out = []
        for n in cand:
            f = f_best[n]
            g_n = side[n] * nrm[f]  # d gap / d x: the face normal towards the outside
            gp = float(side[n] * dn[n] - self._r_nodes[n])
            out.append(_Pair(i, gp, np.array([n]), g_n, None, self._k_nodes[n], foot[n, f].copy()))
        return out

    def _vertex_pairs(self, i: int, x: np.ndarray, active_only: bool) -> list[_Pair]:
        """Stop vertex - beam curve pairs: each contact vertex against its closest point on the
        P2 centreline (over the elements near it)."""
        out = []
        r = self._r_nodes
        verts = zip(self._vertices[i], self._vertex_side[i], self._vertex_k[i], strict=True)
        for v, side0, k in verts:
            # far from every node: the curve (within h_max of a node, with some stretch to
            # spare) is farther than its radius, no contact (only the gap output needs it)
            if active_only:
                dmin = np.sqrt(((x - v) ** 2).sum(axis=1).min())
                if dmin > 2.0 * self._h_max + self._r_max:
                    continue
            phi, xi, e, side = self._closest(v, x)
            # on the undeformed side: +1; crossed: -1 (then the gap is -(distance) - t/2)
            m = 1.0 if side0 == 0.0 else side0 * side
            nodes = 2 * e + np.arange(3)
            r0, r1 = r[nodes[0]], r[nodes[2]]
            gap = phi if m > 0.0 else -(phi + r0 + (r1 - r0) * xi) - (r0 + (r1 - r0) * xi)
            if active_only and gap >= 0.0:
                continue
            grad, hess = _vertex_derivatives(v, x[nodes], xi, r0, r1)
            out.append(_Pair(i, gap, nodes, m * grad, m * hess, k, v.copy()))
        return out

    def _closest(self, v: np.ndarray, x: np.ndarray) -> tuple[float, float, int, float]:
        """Closest point of the beam's centreline (nodes ``x`` (n_nodes, 2) mm) to ``v`` (2,):
        ``(phi = distance - t/2 [mm], xi, element, side)``; side = +1 / -1 when ``v`` is left /
        right of the centreline's tangent there, 0 at the beam's two ends (beyond them)."""
        r = self._r_nodes
        n_el = self.model.n_elements
        dv = np.hypot(x[:, 0] - v[0], x[:, 1] - v[1])
        # the elements of the nodes nearest to v (node j belongs to element j // 2, and a
        # vertex node 2e also to element e - 1): the closest point lies on one of them
        near = np.flatnonzero(dv <= dv.min() + self._h_max + 1e-12)
        els = np.unique(np.concatenate([near // 2, (near - 1) // 2]))
        best = (np.inf, 0.0, 0)
        for e in els[(els >= 0) & (els < n_el)]:
            nodes = 2 * e + np.arange(3)
            phi, xi, _ = _closest_on_element(v, x[nodes], r[nodes[0]], r[nodes[2]])
            if phi < best[0]:
                best = (phi, xi, int(e))
        phi, xi, e = best
        if (e == 0 and xi == 0.0) or (e == n_el - 1 and xi == 1.0):
            return phi, xi, e, 0.0
        xe = x[2 * e : 2 * e + 3]
        n, dn, _ = _p2(xi)
        c = v - n @ xe
        x1 = dn @ xe
        cross = x1[0] * c[1] - x1[1] * c[0]
        return phi, xi, e, (1.0 if cross >= 0.0 else -1.0)

    # ------------------------------------------------------------------ assembly

    def add(self, u: np.ndarray, frame: np.ndarray, r: np.ndarray, ab: np.ndarray) -> None:
        """Add the penalty forces and tangent (see :class:`fea.beam.ContactTerms`)."""
        m = self.model
        x = m.reference_nodes_mm + u.reshape(-1, 3)[:, :2]
        n_last = m.n_nodes - 1
        kv = 2 * ((ab.shape[0] - 1) // 3)  # kl + ku: ab has 2 kl + ku + 1 rows, kl = ku
        pairs = self.pairs(x)
        self.active = frozenset((p.stop, tuple(p.nodes)) for p in pairs)
        for p in pairs:
            dofs = (3 * p.nodes[:, None] + np.arange(2)[None, :]).ravel()  # (2 m,)
            f = p.k * p.gap * p.grad  # d(1/2 k g^2)/dx, N
            kt = p.k * np.outer(p.grad, p.grad)
            if p.hess is not None:
                kt = kt + p.k * p.gap * p.hess
            last = np.flatnonzero(p.nodes == n_last)
            if last.size:
                # the end node's translations are generalised in the drive's frame: u = F^T q
                j = 2 * int(last[0])
                T = np.eye(dofs.size)
                T[j : j + 2, j : j + 2] = frame.T
                f = T.T @ f
                kt = T.T @ kt @ T
            r[dofs] += f
            rows, cols = np.meshgrid(dofs, dofs, indexing="ij")
            np.add.at(ab, (kv + rows - cols, cols), kt)

    # ------------------------------------------------------------------ outputs

    def state(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per stop at node positions ``x`` (n_nodes, 2) mm: the force on the beam (n_stops, 2)
        N, the smallest gap (n_stops,) mm, in contact (n_stops,) bool and the contact point
        (n_stops, 2) mm (NaN when not in contact)."""
        ns = len(self.stops)
        force = np.zeros((ns, 2))
        gap = np.full(ns, np.inf)
        point = np.zeros((ns, 2))
        weight = np.zeros(ns)
        for p in self.pairs(x, active_only=False):
            gap[p.stop] = min(gap[p.stop], p.gap)
            if p.gap < 0.0:
                fmag = -p.k * p.gap
                # the force on the beam: -k g grad g, summed over the pair's nodes
                force[p.stop] -= p.k * p.gap * p.grad.reshape(-1, 2).sum(axis=0)
                point[p.stop] += fmag * p.point
                weight[p.stop] += fmag
        touching = weight > 0.0
        point = np.where(
            touching[:, None], point / np.where(touching, weight, 1.0)[:, None], np.nan
        )
        return force, gap, touching, point

    def response(self, beam: BeamResponse, drive: EndDrive) -> ContactResponse:
        """The :class:`ContactResponse` of the traced path ``beam`` (from its deformed shapes)."""
        rows, ns = beam.shapes_mm.shape[0], len(self.stops)
        force = np.full((rows, ns, 2), np.nan)
        gap = np.full((rows, ns), np.nan)
        touch = np.zeros((rows, ns), dtype=bool)
        point = np.full((rows, ns, 2), np.nan)
        for k in np.flatnonzero(beam.converged):
            force[k], gap[k], touch[k], point[k] = self.state(beam.shapes_mm[k])
        driven = beam.displacement_mm if drive.control == "displacement" else beam.force_N
        return contact_rows(
            self.names, force, gap, touch, point, driven, self.tolerance_mm, self.k_elements
        )


def contact_rows(
    names: tuple[str, ...],
    force: np.ndarray,
    gap: np.ndarray,
    touch: np.ndarray,
    point: np.ndarray,
    driven: np.ndarray,
    tolerance_mm: float,
    penalty: np.ndarray,
) -> ContactResponse:
    """The :class:`ContactResponse` of a traced path from its per-row contact state.

    ``force`` (rows, n_stops, 2) N, ``gap`` (rows, n_stops) mm, ``touch`` (rows, n_stops) bool,
    ``point`` (rows, n_stops, 2) mm (NaN rows: not converged), as :meth:`BeamContact.state`
    gives them row by row (summed over the beams of a mechanism); ``driven`` (rows,) the driven
    value of each row (mm, rad, N or N mm); ``tolerance_mm`` the penetration tolerance (mm);
    ``penalty`` (n_elements,) N/mm the penalty stiffness used. Adds the closing value of each
    stop, the penetration check and its message (shared by the beam and the mechanism engine).
    """
    rows, ns = gap.shape
    closing = np.full(ns, np.nan)
    for j in range(ns):
        g = gap[:, j]
        for k in range(1, rows):
            if g[k - 1] >= 0.0 and g[k] < 0.0:  # NaN rows never match
                # Once closed the gap stays near zero (the penetration), so interpolating to
                # row k would place the closing late: extrapolate the open rows' trend
                # (the last two), kept inside the bracket [row k - 1, row k].
                lo, hi = driven[k - 1], driven[k]
                w = g[k - 1] / (g[k - 1] - g[k])
                closing[j] = lo + w * (hi - lo)
                if k >= 2 and g[k - 2] > g[k - 1]:
                    ext = lo + g[k - 1] * (lo - driven[k - 2]) / (g[k - 2] - g[k - 1])
                    closing[j] = min(max(ext, min(lo, hi)), max(lo, hi))
                break
    pen = np.where(np.isnan(gap), 0.0, np.maximum(-gap, 0.0)).max(axis=1, initial=0.0)
    bad = np.flatnonzero(pen > tolerance_mm)
    message = ""
    if bad.size:
        message = (
            f"penetration {pen.max():.3g} mm exceeds the tolerance {tolerance_mm:.3g} mm "
            f"in {bad.size} row(s) (first: row {bad[0]}): raise ContactSettings.penalty_factor"
        )
    return ContactResponse(
        names=tuple(names),
        force_N=np.hypot(force[..., 0], force[..., 1]),
        force_vector_N=force,
        gap_mm=gap,
        in_contact=touch,
        rows_in_contact=touch.any(axis=1),
        point_mm=point,
        initial_gap_mm=gap[0].copy(),
        closing_value=closing,
        max_penetration_mm=pen,
        penetration_ok=bad.size == 0,
        penalty_N_per_mm=np.asarray(penalty, dtype=float).copy(),
        message=message,
        extra={"tolerance_mm": tolerance_mm},
    )


def contact_over_beams(
    contacts: list[BeamContact] | tuple[BeamContact, ...],
    shapes: list[np.ndarray] | tuple[np.ndarray, ...],
    driven: np.ndarray,
    converged: np.ndarray,
    bodies: tuple[np.ndarray, ...] | None = None,
) -> ContactResponse:
    """The :class:`ContactResponse` of several beams against the same stops (a mechanism, a
    flexure pivot's members): per stop and converged row the resultant of its forces on all the
    beams (N), the smallest gap over the beams (mm) and the force-weighted contact point (mm).

    ``contacts`` one :class:`BeamContact` per beam (same stops, same order); ``shapes`` per
    beam (rows, n_nodes_i, 2) mm, the deformed nodes; ``driven`` (rows,) the driven value of
    each row (mm, rad, N or N mm); ``converged`` (rows,) bool. ``extra["force_by_beam_N"]``
    (rows, n_beams, n_stops) N is each beam's share. ``bodies``: the rigid bodies' share
    (:meth:`fea.body_contact.MechanismContacts.stop_rows`: force (rows, n_stops, 2) N, gap
    (rows, n_stops) mm, force magnitude (rows, n_stops) N, force-weighted contact points
    (rows, n_stops, 2) N mm), added to the resultant, the smallest gap and the contact point;
    then ``extra["force_by_bodies_N"]`` (rows, n_stops) N is the bodies' share.
    """
    rows, nb, ns = driven.shape[0], len(contacts), len(contacts[0].stops)
    force = np.full((rows, ns, 2), np.nan)
    by_beam = np.full((rows, nb, ns), np.nan)
    gap = np.full((rows, ns), np.nan)
    touch = np.zeros((rows, ns), dtype=bool)
    point = np.full((rows, ns, 2), np.nan)
    for k in np.flatnonzero(converged):
        f_sum, g_min, w_sum, p_sum = np.zeros((ns, 2)), np.full(ns, np.inf), np.zeros(ns), 0.0
        for i, c in enumerate(contacts):
            f, g, t, pt = c.state(shapes[i][k])
            w = np.hypot(f[:, 0], f[:, 1]) * t
            by_beam[k, i] = np.hypot(f[:, 0], f[:, 1])
            f_sum, g_min, w_sum = f_sum + f, np.minimum(g_min, g), w_sum + w
            p_sum = p_sum + np.where(t[:, None], pt, 0.0) * w[:, None]
        if bodies is not None:
            f_sum, g_min = f_sum + bodies[0][k], np.minimum(g_min, bodies[1][k])
            w_sum, p_sum = w_sum + bodies[2][k], p_sum + bodies[3][k]
        force[k], gap[k], touch[k] = f_sum, g_min, w_sum > 0.0
        point[k] = np.where(
            touch[k][:, None], p_sum / np.where(touch[k], w_sum, 1.0)[:, None], np.nan
        )
    tolerance = min(c.tolerance_mm for c in contacts)
    penalty = np.concatenate([c.k_elements for c in contacts])
    out = contact_rows(contacts[0].names, force, gap, touch, point, driven, tolerance, penalty)
    out.extra["force_by_beam_N"] = by_beam
    if bodies is not None:
        out.extra["force_by_bodies_N"] = np.hypot(bodies[0][..., 0], bodies[0][..., 1])
    return out


def overlaps(contact: BeamContact) -> list[tuple[int, float]]:
    """The stops of ``contact`` that overlap its undeformed beam deeper than the penetration
    tolerance, as ``(index of the stop, overlap depth in mm > 0)``; empty when all are clear
    (touching is clear)."""
    _, gap0, _, _ = contact.state(contact.model.reference_nodes_mm)
    return [(i, float(-g)) for i, g in enumerate(gap0) if g < -contact.tolerance_mm]


def solve_with_stops(
    model: BeamModel,
    drive: EndDrive,
    stops: tuple[RigidStop, ...] | list[RigidStop],
    settings: ContactSettings = ContactSettings(),
) -> BeamResponse:
    """Trace ``model`` under ``drive`` with frictionless contact against the rigid ``stops``.

    Raises FeaError when a stop overlaps the undeformed beam (deeper than the tolerance).
    A path that penetrates a stop deeper than ``settings.penetration_tol`` is traced again with
    a 10x stiffer penalty (at most ``settings.max_raises`` times; ``contact.extra`` says the
    factor used and how many raises it took).

    Returns the :class:`fea.beam.BeamResponse` with ``contact`` set to a
    :class:`ContactResponse`. The reactions (``force_N`` ...) include the stops' forces where
    the driven end itself touches a stop. Without stops this is ``model.solve(drive)`` exactly
    (same code, same numbers); with stops the Python tracing loop runs (same decisions as the
    compiled one), with the compiled element kernel when that is the model's kernel.
    """
    if not stops:
        return model.solve(drive)
    # the undeformed beam must be clear of the stops (touching is fine): the first row is not
    # solved, and a stop across the beam has no side to push it to
    first = BeamContact(model, stops, settings)
    for i, depth in overlaps(first):
        raise FeaError(
            f"stop {first.names[i]!r} overlaps the undeformed beam by {depth:.4g} mm; move it "
            f"clear (the gap is measured from the beam's surface, t/2 from the centreline)"
        )
    for raises in range(int(settings.max_raises) + 1):
        contact = first if raises == 0 else BeamContact(model, stops, settings)
        beam = model.solve(drive, contact=contact)
        result = contact.response(beam, drive)
        if result.penetration_ok or raises == settings.max_raises:
            break
        # deeper than the tolerance: the same path with a 10x stiffer penalty
        settings = replace(settings, penalty_factor=10.0 * settings.penalty_factor)
    result.extra.update(penalty_factor=settings.penalty_factor, raises=raises)
    return replace(beam, contact=result)


# -- the vertex - curve pair: closest point on a P2 element and the derivatives of the gap -------


def _p2(xi: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """P2 shape functions on [0, 1] (nodes at 0, 1/2, 1) and their first and second derivatives."""
    n = np.array([(1 - xi) * (1 - 2 * xi), 4 * xi * (1 - xi), xi * (2 * xi - 1)])
    dn = np.array([4 * xi - 3, 4 - 8 * xi, 4 * xi - 1])
    ddn = np.array([4.0, -8.0, 4.0])
    return n, dn, ddn


def _phi(v, xe, xi, r0, r1):
    """phi = |v - x(xi)| - r(xi) and its xi-derivatives (phi, phi_xi, phi_xixi, n, d, x')."""
    n, dn, ddn = _p2(xi)
    c = v - n @ xe
    d = float(np.hypot(*c))
    x1 = dn @ xe
    x2 = ddn @ xe
    dr = r1 - r0
    phi = d - (r0 + dr * xi)
    if d == 0.0:
        # v on the centreline itself (a stop's corner placed exactly on the undeformed beam):
        # the distance has a kink there, no normal; the gap -r is all the overlap check
        # needs. The left normal stands in for n, and phi_xixi = inf stops the taper's Newton.
        nv = np.array([-x1[1], x1[0]]) / max(float(np.hypot(*x1)), 1e-300)
        return phi, -float(nv @ x1) - dr, np.inf, nv, d, x1
    nv = c / d
    phi_xi = -float(nv @ x1) - dr
    phi_xixi = float(x1 @ x1 - (nv @ x1) ** 2) / d - float(nv @ x2)
    return phi, phi_xi, phi_xixi, nv, d, x1


def _closest_on_element(v, xe, r0, r1) -> tuple[float, float, bool]:
    """(gap mm, xi, interior) of vertex ``v`` (2,) against element nodes ``xe`` (3, 2) mm with
    disk radii ``r0``, ``r1`` (mm) at its ends: the minimum of phi over xi in [0, 1].

    The closest point of the centreline (``c . x' = 0``, a cubic in xi for the P2 curve
    ``x = x0 + xi a1 + xi^2 a2``) is found exactly from the cubic's roots and the two ends; for a
    tapered element (r0 != r1) a damped Newton on phi_xi = 0 then moves it to the minimum of phi,
    to round-off (the global Newton's quadratic convergence needs an exact closest point)."""
    a1 = -3.0 * xe[0] + 4.0 * xe[1] - xe[2]
    a2 = 2.0 * xe[0] - 4.0 * xe[1] + 2.0 * xe[2]
    w = v - xe[0]
    coef = [-2.0 * (a2 @ a2), -3.0 * (a1 @ a2), 2.0 * (w @ a2) - a1 @ a1, w @ a1]
    cand = [0.0, 1.0]
    if np.any(coef[:3]):
        roots = np.roots(np.trim_zeros(coef, "f"))
        cand += [float(z.real) for z in roots if abs(z.imag) < 1e-12 and 0.0 < z.real < 1.0]
    vals = [_phi(v, xe, c, r0, r1)[0] for c in cand]
    k = int(np.argmin(vals))
    xi, phi = cand[k], vals[k]
    if r1 != r0:
        # Newton on phi_xi = 0 from the centreline's closest point (the taper moves the minimum
        # only a little), a step halved until |phi_xi| falls: phi itself is flat at its minimum,
        # so a test on phi would stop ~sqrt(eps) short of it, and the force's derivative with it
        for _ in range(50):
            _, g, h, *_ = _phi(v, xe, xi, r0, r1)
            if g == 0.0:
                break
            step = -g / h if h > 0.0 else -np.sign(g) * 0.1
            for _ in range(40):
                new = min(1.0, max(0.0, xi + step))
                if new == xi or abs(_phi(v, xe, new, r0, r1)[1]) < abs(g):
                    break
                step *= 0.5
            if new == xi:  # converged, or at an end with phi still falling beyond it
                break
            xi = new
        phi = _phi(v, xe, xi, r0, r1)[0]
    return float(phi), xi, 0.0 < xi < 1.0


def _vertex_derivatives(v, xe, xi, r0, r1) -> tuple[np.ndarray, np.ndarray]:
    """Gradient (6,) and Hessian (6, 6) of the gap of vertex ``v`` against the element with nodes
    ``xe`` (3, 2) mm, w.r.t. the nodes' (x, y), at the closest point ``xi``.

    g(X) = min_xi phi(xi, X): grad g = phi_X; hess g = phi_XX - phi_Xxi phi_xixi^-1 phi_xiX when
    the minimum is inside the element (phi_xi = 0 there), phi_XX at an end."""
    n, dn, _ = _p2(xi)
    phi, _, phi_xixi, nv, d, x1 = _phi(v, xe, xi, r0, r1)
    grad = -np.kron(n, nv)  # d phi / d x_a = -N_a n
    proj = np.eye(2) - np.outer(nv, nv)
    if d == 0.0:
        # v on the centreline: the gap is not differentiable there (see _phi); its gradient
        # along the stand-in normal, no curvature term (a pair t/2 deep, far beyond the
        # penetration tolerance: the path is flagged, and at the start refused by overlaps)
        return grad, np.zeros((6, 6))
    hess = np.kron(np.outer(n, n), proj) / d
    if 0.0 < xi < 1.0 and np.isfinite(phi_xixi) and phi_xixi > 0.0:
        # d phi_xi / d x_a = N_a (I - n n^T) x' / d - N_a' n
        cross = np.kron(n, proj @ x1 / d) - np.kron(dn, nv)
        hess = hess - np.outer(cross, cross) / phi_xixi
    return grad, hess


# -- contact between two beams (a declared pair of a mechanism) ----------------------------------


class BeamPairContact:
    """Frictionless penalty contact between two beams ``a`` and ``b`` (a pair a mechanism study
    declares), node-to-curve both ways: every mesh node of one beam against the P2 centreline of
    the other, the gap ``g = min_xi |x_n - x_o(xi)| - r_n - r_o(xi)`` (the two disks of radius
    t/2 swept along the centrelines). Its derivatives with respect to both the node (2 DOFs)
    and the other beam's element (6 DOFs) are exact, the Hessian that of a minimum function as
    for a stop's vertex (``_pair_derivatives``), so the penalty energy ``1/2 k g^2`` of every
    pair with ``g < 0`` adds a symmetric, consistent tangent coupling the two beams.

    A node keeps the side of the other beam it is on in the undeformed state (a Newton iterate
    that carries it across is pushed back, not through). The penalty of a pair is
    ``min(k of the node, smallest k of the other beam's elements)`` with ``k =
    penalty_factor x EI / h^3`` as for the stops (:class:`ContactSettings`): constant per node,
    so the force does not jump as the contact slides along the other beam. Where both
    directions act on one spot (a node against a curve's end) the pair is enforced twice as
    stiffly there, which moves the force by O(F/k) only.

    Parameters
    ----------
    model_a, model_b : the two beams (fea.beam.BeamModel).
    settings : ContactSettings.
    name : label of the pair in the outputs.
    """

    def __init__(
        self, model_a: BeamModel, model_b: BeamModel, settings: ContactSettings, name: str = ""
    ) -> None:
        self.name = name
        self.sides = (BeamContact(model_a, (), settings), BeamContact(model_b, (), settings))
        self.tolerance_mm = min(c.tolerance_mm for c in self.sides)
        self._k = [
            np.minimum(self.sides[i]._k_nodes, float(self.sides[1 - i].k_elements.min()))
            for i in (0, 1)
        ]
        x0 = [c.model.reference_nodes_mm for c in self.sides]
        # each node's side of the other beam, undeformed (0: beyond the other beam's ends)
        self._side0 = [
            np.array([self.sides[1 - i]._closest(v, x0[1 - i])[3] for v in x0[i]]) for i in (0, 1)
        ]
        #: the pairs acting in the last :meth:`pairs` call with ``active_only``
        self.active: frozenset = frozenset()

    def pairs(self, xa: np.ndarray, xb: np.ndarray, active_only: bool = True) -> list[tuple]:
        """The node-curve pairs at node positions ``xa`` (n_a, 2) and ``xb`` (n_b, 2) mm, as
        ``(beam of the node (0 = a, 1 = b), node, element of the other beam, gap mm, grad (8,),
        hess (8, 8) or None, k N/mm)``; grad and hess with respect to (node x, y, the other's
        element nodes' x, y). With ``active_only`` only those with ``g < 0`` (with their
        derivatives); otherwise also the closest pair of each node within reach (derivatives
        None, for the gap output)."""
        xs = (xa, xb)
        out = []
        for i in (0, 1):
            other, x_n, x_o = self.sides[1 - i], xs[i], xs[1 - i]
            r_n = self.sides[i]._r_nodes
            reach = 2.0 * other._h_max + other._r_max
            for n in range(x_n.shape[0]):
                v = x_n[n]
                dmin = float(np.sqrt(((x_o - v) ** 2).sum(axis=1).min()))
                if dmin - r_n[n] > reach:
                    continue
                phi, xi, e, side = other._closest(v, x_o)
                side0 = self._side0[i][n]
                m = 1.0 if side0 == 0.0 else side0 * side
                nodes = 2 * e + np.arange(3)
                r0, r1 = other._r_nodes[nodes[0]], other._r_nodes[nodes[2]]
                r_o = r0 + (r1 - r0) * xi
                gap = phi - r_n[n] if m > 0.0 else -(phi + r_o) - r_o - r_n[n]
                if active_only and gap >= 0.0:
                    continue
                grad = hess = None
                if gap < 0.0 or active_only:
                    grad, hess = _pair_derivatives(v, x_o[nodes], xi, r0, r1)
                    grad, hess = m * grad, m * hess
                out.append((i, n, e, gap, grad, hess, float(self._k[i][n])))
        if active_only:
            self.active = frozenset((p[0], p[1], p[2]) for p in out)
        return out

    def dofs(self, pair: tuple, offsets: tuple[int, int]) -> np.ndarray:
        """(8,) global DOF indices (x, y of the node, then of the other beam's element nodes)
        of ``pair`` when beam a's DOFs start at ``offsets[0]`` and b's at ``offsets[1]`` (the
        beams' DOFs node by node (u, v, phi))."""
        i, n, e = pair[0], pair[1], pair[2]
        nodes = [(i, n)] + [(1 - i, 2 * e + k) for k in range(3)]
        return np.array([offsets[b] + 3 * node + f for b, node in nodes for f in (0, 1)])

    def state(self, xa: np.ndarray, xb: np.ndarray) -> tuple[float, float, np.ndarray]:
        """At node positions ``xa``, ``xb`` (mm): the resultant force (N) the pair's contact
        exerts on beam a (its magnitude; b gets the opposite), the smallest gap (mm; inf when no
        node is within reach) and that force as (2,) N."""
        force = np.zeros(2)
        gap = np.inf
        for p in self.pairs(xa, xb, active_only=False):
            gap = min(gap, p[3])
            if p[3] < 0.0:
                f = -p[6] * p[3] * p[4]  # -k g grad g on (node, element nodes), N
                on_node, on_element = f[:2], f[2:].reshape(3, 2).sum(axis=0)
                force += on_node if p[0] == 0 else on_element
        return float(np.hypot(*force)), gap, force


def _pair_derivatives(v, xe, xi, r0, r1) -> tuple[np.ndarray, np.ndarray]:
    """Gradient (8,) and Hessian (8, 8) of ``g = min_xi |v - x(xi)| - r(xi)`` (the radius of the
    node's own disk is a constant) with respect to (v, the element's nodes ``xe`` (3, 2)), at
    the closest point ``xi``: with ``c = v - sum N_a x_a`` = ``sum w_k z_k`` (w = (1, -N)),
    ``grad = w (x) n``, ``hess = w w^T (x) P / d - q q^T / phi_xixi`` (P = I - n n^T; q the
    mixed derivative of phi_xi, inside the element only), the vertex-curve pair's of a moving
    vertex."""
    n, dn, _ = _p2(xi)
    _, _, phi_xixi, nv, d, x1 = _phi(v, xe, xi, r0, r1)
    w = np.concatenate([[1.0], -n])
    grad = np.kron(w, nv)
    if d == 0.0:  # on the centreline: no normal (see _phi); no curvature term
        return grad, np.zeros((8, 8))
    proj = np.eye(2) - np.outer(nv, nv)
    hess = np.kron(np.outer(w, w), proj) / d
    if 0.0 < xi < 1.0 and np.isfinite(phi_xixi) and phi_xixi > 0.0:
        px = proj @ x1 / d
        q = np.concatenate([-px, np.kron(n, px) - np.kron(dn, nv)])
        hess = hess - np.outer(q, q) / phi_xixi
    return grad, hess


#: public names of the vertex-curve helpers (fea.body_contact: a body's corner or a beam's own
#: node against a beam's P2 centreline)
closest_on_element = _closest_on_element
vertex_curve_derivatives = _pair_derivatives
