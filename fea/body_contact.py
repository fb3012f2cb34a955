"""Frictionless contact of a mechanism's rigid bodies, and of a beam with itself (issue 25 item 3).

:mod:`fea.stops` keeps the beams of a mechanism out of the rigid stops and out of each other.
This module adds, inside the same Newton (:class:`fea.mechanism.Mechanism`):

* **a body against the stops**: every body with an outline that is not clamped to the ground
  meets every stop of ``Mechanism.stops``;
* **declared pairs with a body** (``Mechanism.beam_contacts`` naming a body): body - body and
  body - beam;
* **self contact of a beam** (``Mechanism.beam_contacts`` naming one beam twice): the beam's
  nodes against its own centreline, the pairs of neighbouring parts within ``skip_mm`` of arc
  length left out (default ``max(2 h_max, pi t_max)``: two points of a beam bent no tighter than
  a radius of t that are ``pi t`` apart along it are at least ``t`` apart, so nearer parts do
  not meet unless the beam folds tighter than beam theory can describe; the nodes of an
  element always touch it, so at least two elements are left out).

A body is a rigid polygon moving with its reference point: the point ``o`` of it (an offset
from the reference point ``ref``, mm) is at ``x = ref + (U, V) + R(theta) o``; its three DOFs
``(U, V, theta)`` are the mechanism's. Two node-to-segment pair kinds cover the outlines:

* **point - rigid face**: a body's convex corners against a stop's or another body's faces, a
  stop's contact vertices (its points, an open polyline's vertices, a polygon's convex corners)
  against a body's faces, a declared beam's nodes against the body's faces. The gap is taken in
  the face owner's frame: ``g = n0 . (R_F^T (x_p - c_F)) - n0 . A0 - r_p`` (``n0`` the face's
  outward normal, ``A0`` its start, both in the owner's frame; ``c_F``, ``R_F`` the owner's
  reference point and rotation; ``r_p`` the point's radius: t/2 for a beam node, 0 for a
  corner). With ``y = x_p - c_F`` and ``n = R_F n0`` its derivatives w.r.t. (x_p, c_F,
  theta_F) are ``(n, -n, (J n) . y)`` and the only second derivatives ``d2g/dx_p dtheta_F = J n``,
  ``d2g/dc_F dtheta_F = -J n``, ``d2g/dtheta_F^2 = -n . y`` (``J`` the quarter turn); a point on
  a body adds ``n . (-R_p o_p)`` to its ``theta_p theta_p`` entry (``x_p``'s curvature in its
  rotation). The pair acts where the point's closest point on the outline lies inside the face.
* **body corner - beam curve** (a declared body - beam pair): the corner against the beam's P2
  centreline, ``g = min_xi |x_c - x(xi)| - t(xi)/2`` with the exact gradient and Hessian of
  :func:`fea.stops.vertex_curve_derivatives` (the minimum function's, a moving vertex), chained
  through the corner's rigid motion.

Penalty: ``1/2 k g^2`` for each pair with ``g < 0``, the force ``-k g grad g``, the tangent
``k (grad grad^T + g hess)`` — the exact Hessian, so Newton stays quadratic. ``k`` follows the
rule of :class:`fea.stops.ContactSettings` (``penalty_factor x EI / h^3``): a pair with a beam
node takes the node's ``k``, a pair with a beam's curve the smallest ``k`` of that beam; a body
has no ``EI / h^3`` of its own, so pairs of bodies and stops take the smallest ``k`` of the
mechanism's beams (the softest member that holds a body: the stop is still ~1e3 times stiffer
than any beam element). The penetration check and the 10x raises of
:func:`fea.mechanism.solve_mechanism` cover a body's penetration of a stop like a beam's.

Limits: frictionless; node-to-segment (a corner against a corner is found only where one lies
inside the other's face: fine once penetrating, not for two corners meeting head-on, which the
penalty resolves one step later); bodies are their outlines (convex corners press, concave
corners do not); a beam's self contact keeps no memory of sides (a Newton iterate carrying a
node through the beam's other part would be pushed on through; the branch guards reject such a
step in practice). Units mm, N, N/mm, rad.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from flexopt.fea.beam import BeamModel
from flexopt.fea.errors import FeaError
from flexopt.fea.stops import (
    BeamContact,
    ContactSettings,
    RigidStop,
    closest_on_element,
    vertex_curve_derivatives,
)

__all__ = ["MechanismContacts", "default_skip_mm"]

_J = np.array([[0.0, -1.0], [1.0, 0.0]])  # the quarter turn: d R(theta) / d theta = J R


def _rot(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def default_skip_mm(model: BeamModel) -> float:
    """The arc length (mm) within which a beam's self contact leaves pairs out:
    ``max(2 h_max, pi t_max)`` (see the module docstring)."""
    s = model.s_nodes[0::2]
    t = np.interp(model.s_nodes, model.profile.arc_length_mm, model.profile.thickness_mm)
    return float(max(2.0 * np.diff(s).max(), np.pi * t.max()))


class _Rigid:
    """A rigid outline: a stop (fixed, ``dofs`` None) or a body (three DOFs (U, V, theta)).

    ``local`` (m, 2) mm: the outline relative to ``ref`` (2,) mm (a stop: ``ref`` = 0)."""

    def __init__(self, name, outline, closed, ref, dofs):
        self.name = name
        self.ref = np.asarray(ref, dtype=float)
        self.dofs = None if dofs is None else np.asarray(dofs, dtype=int)
        self.shape = RigidStop(np.asarray(outline, float) - self.ref, closed, name)
        self.closed = closed
        a, b = self.shape.faces()
        self.a, self.b = a, b
        d = b - a
        self.ell = np.hypot(d[:, 0], d[:, 1])
        self.tau = d / np.where(self.ell > 0, self.ell, 1.0)[:, None]
        self.left = np.stack([-self.tau[:, 1], self.tau[:, 0]], axis=1)
        area2 = float(np.sum(a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1])) if closed else 0.0
        self.out = -np.sign(area2)  # outward normal = out x left normal (closed only)
        self.corners = self.shape.contact_vertices()  # (v, 2) local

    def pose(self, z: np.ndarray) -> tuple[np.ndarray, float]:
        """(c (2,) mm: the reference point's position, theta rad) at state ``z``."""
        if self.dofs is None:
            return self.ref, 0.0
        return self.ref + z[self.dofs[:2]], float(z[self.dofs[2]])

    def corner_points(self, z: np.ndarray):
        """The convex corners at ``z``: positions (v, 2) mm, and per corner its Jacobian (2, 3)
        w.r.t. (U, V, theta) and ``d2x/dtheta2`` (2,) (None for a stop)."""
        c, th = self.pose(z)
        ro = self.corners @ _rot(th).T  # (v, 2): R o
        x = c + ro
        if self.dofs is None:
            return x, None, None
        jac = np.zeros((ro.shape[0], 2, 3))
        jac[:, 0, 0] = jac[:, 1, 1] = 1.0
        jac[:, :, 2] = ro @ _J.T  # J R o
        return x, jac, -ro

    def nearest_faces(self, w: np.ndarray):
        """For points ``w`` (k, 2) in this outline's frame: (face (k,), lam (k,) along it, the
        signed distance along the left normal (k,), the distance to the face (k,))."""
        rel = w[:, None, :] - self.a[None]  # (k, f, 2)
        lam = np.einsum("kfi,fi->kf", rel, self.tau) / self.ell[None]
        lam_c = np.clip(lam, 0.0, 1.0)
        foot = self.a[None] + lam_c[..., None] * (self.b - self.a)[None]
        dist = np.hypot(*(w[:, None, :] - foot).transpose(2, 0, 1))
        f = np.argmin(dist, axis=1)
        k = np.arange(w.shape[0])
        dn = np.einsum("ki,ki->k", rel[k, f], self.left[f])
        return f, lam[k, f], dn, dist[k, f]


class _Term:
    """One evaluated pair: its group (a stop's index, or a declared pair's label), gap (mm),
    global DOFs (d,), gradient (d,), Hessian (d, d), penalty (N/mm), the contact point (2,) mm
    and its key (for the set of acting pairs)."""

    __slots__ = ("group", "key", "gap", "dofs", "grad", "hess", "k", "point")

    def __init__(self, group, key, gap, dofs, grad, hess, k, point):
        self.group, self.key, self.gap, self.dofs = group, key, gap, dofs
        self.grad, self.hess, self.k, self.point = grad, hess, k, point


def _point_face(face, f, nsign, x_p, dofs_p, jac_p, curv_p, r_p, c_f, th_f):
    """Gap, DOFs, gradient and Hessian of a point at ``x_p`` (2,) mm (DOFs ``dofs_p`` (dp,),
    Jacobian ``jac_p`` (2, dp), ``curv_p`` (2,) its second derivative in its own rotation, the
    last of its DOFs, or None; radius ``r_p`` mm) against face ``f`` of the rigid ``face`` at
    pose (``c_f``, ``th_f``), ``nsign`` x the face's left normal pointing to the point's side."""
    R = _rot(th_f)
    n0 = nsign * face.left[f]
    n = R @ n0
    y = x_p - c_f
    gap = float(n @ y - n0 @ face.a[f] - r_p)
    gv = np.concatenate([n, -n, [float((_J @ n) @ y)]])  # w.r.t. (x_p, c_F, theta_F)
    hv = np.zeros((5, 5))
    jn = _J @ n
    hv[0:2, 4] = hv[4, 0:2] = jn
    hv[2:4, 4] = hv[4, 2:4] = -jn
    hv[4, 4] = -float(n @ y)
    dp = len(dofs_p)
    dofs_f = () if face.dofs is None else tuple(face.dofs)
    T = np.zeros((5, dp + len(dofs_f)))
    T[0:2, :dp] = jac_p
    if dofs_f:
        T[2:4, dp : dp + 2] = np.eye(2)
        T[4, dp + 2] = 1.0
    grad = T.T @ gv
    hess = T.T @ hv @ T
    if curv_p is not None:
        hess[dp - 1, dp - 1] += float(n @ curv_p)
    return gap, np.array(tuple(dofs_p) + dofs_f, dtype=int), grad, hess


class MechanismContacts:
    """The bodies' contact terms and the beams' self contact of one mechanism.

    Parameters
    ----------
    models : the beams (fea.beam.BeamModel), in the mechanism's order.
    offsets : (B + 1,) int — the first DOF of each beam (each node's (u, v, phi) in turn).
    bodies : the bodies (fea.mechanism.MechBody): name, ref_mm (2,) mm, outline_mm (k, 2) mm
        or None; body ``i``'s DOFs are ``body_dofs + 3 i + (0, 1, 2)``.
    body_dofs : int — the first body DOF.
    stops : fea.stops.RigidStop fixed to the ground.
    declared : (name, name) pairs with a body, or a beam named twice (self contact).
    grounded : names of the bodies clamped to the ground (they meet no stop).
    settings : ContactSettings (the penalty rule).
    beam_names : the beams' names.
    skip_mm : the self contact's left-out arc length (None: :func:`default_skip_mm`).
    """

    def __init__(
        self,
        models: Sequence[BeamModel],
        offsets: np.ndarray,
        bodies: Sequence,
        body_dofs: int,
        stops: Sequence[RigidStop],
        declared: Sequence[tuple[str, str]],
        grounded: set[str],
        settings: ContactSettings,
        beam_names: Sequence[str],
        skip_mm: float | None = None,
    ) -> None:
        self.models = list(models)
        self.offsets = np.asarray(offsets, dtype=int)
        self.beams = [BeamContact(m, (), settings) for m in self.models]
        self._h_max = [float(np.diff(m.s_nodes[0::2]).max()) for m in self.models]  # mm
        self.tolerance_mm = min(c.tolerance_mm for c in self.beams)
        #: a body's pairs: the smallest k of the mechanism's beams (N/mm)
        self.k_body = float(min(c.k_elements.min() for c in self.beams))
        self.stop_names = tuple(st.name or f"stop{i}" for i, st in enumerate(stops))
        self.stops = [_Rigid(st.name, st.outline_mm, st.closed, np.zeros(2), None) for st in stops]
        self.point_stops = [st.outline_mm.shape[0] == 1 for st in stops]
        self.beam_index = beam_index = {nm: i for i, nm in enumerate(beam_names)}
        self.body_names = [b.name for b in bodies]
        self.bodies: dict[str, _Rigid] = {}
        for i, b in enumerate(bodies):
            if b.outline_mm is None:
                continue
            dofs = body_dofs + 3 * i + np.arange(3)
            self.bodies[b.name] = _Rigid(b.name, b.outline_mm, True, b.ref_mm, dofs)
        #: bodies that meet the stops
        self.movable = [nm for nm in self.bodies if nm not in grounded] if stops else []
        self.declared: list[tuple[str, str, str, object]] = []  # (label, a, b, what)
        for a, b in declared:
            label = f"{a}/{b}"
            if a == b and a in beam_index:
                i = beam_index[a]
                skip = default_skip_mm(self.models[i]) if skip_mm is None else float(skip_mm)
                self.declared.append((label, a, b, ("self", i, self._far(i, skip))))
                continue
            for nm in (a, b):
                if nm not in beam_index and nm not in self.body_names:
                    raise FeaError(
                        f"beam contact [{a}, {b}]: {nm!r} is not a beam or a body of the mechanism"
                    )
                if nm in self.body_names and nm not in self.bodies:
                    raise FeaError(
                        f"beam contact [{a}, {b}]: body {nm!r} has no outline_mm (a body meets "
                        "others by its outline)"
                    )
            if a == b:
                raise FeaError(f"beam contact [{a}, {b}]: a body with itself")
            if a in self.bodies and b in self.bodies:
                self.declared.append((label, a, b, ("bodies",)))
            else:
                body, beam = (a, b) if a in self.bodies else (b, a)
                self.declared.append((label, a, b, ("body-beam", body, beam_index[beam])))
        # the side of an open polyline (thin wall) each body corner is on, undeformed
        z0 = np.zeros(body_dofs + 3 * len(bodies))
        self._wall_side = {}
        for nm in self.movable:
            x, _, _ = self.bodies[nm].corner_points(z0)
            for j, st in enumerate(self.stops):
                if not st.closed and st.a.shape[0]:
                    f, _, dn, _ = st.nearest_faces(x)
                    self._wall_side[nm, j] = np.where(dn >= 0.0, 1.0, -1.0)
        #: the acting pairs of the last :meth:`add`
        self.active: frozenset = frozenset()
        self._check_clear(z0)

    # ------------------------------------------------------------------ set-up

    def _far(self, i: int, skip: float) -> np.ndarray:
        """(n_nodes, n_elements) bool: element e lies entirely farther than ``skip`` mm of arc
        length from node n (the pairs self contact considers)."""
        m = self.models[i]
        s = m.s_nodes
        s0, s1 = s[0:-1:2], s[2::2]
        return (s0[None, :] > s[:, None] + skip) | (s1[None, :] < s[:, None] - skip)

    def _check_clear(self, z0: np.ndarray) -> None:
        """Refuse an undeformed overlap deeper than the tolerance, naming the parts."""
        for t in self.terms(z0, active_only=False):
            if t.gap >= -self.tolerance_mm:
                continue
            if isinstance(t.group, int):
                body = t.key[1]
                raise FeaError(
                    f"stop {self.stop_names[t.group]!r} overlaps body {body!r} undeformed by "
                    f"{-t.gap:.4g} mm; move it clear"
                )
            a, _, b = t.group.partition("/")
            what = "the beam's parts overlap" if a == b else "the parts overlap"
            raise FeaError(
                f"beam contact [{a}, {b}]: {what} undeformed by {-t.gap:.4g} mm (joined, or "
                "crossing); declare only parts that are apart"
            )

    # ------------------------------------------------------------------ pairs

    def _nodes(self, z: np.ndarray, i: int) -> np.ndarray:
        q = z[self.offsets[i] : self.offsets[i + 1]].reshape(-1, 3)
        return self.models[i].reference_nodes_mm + q[:, :2]

    def terms(self, z: np.ndarray, active_only: bool = True) -> list[_Term]:
        """The pairs at state ``z`` (N,): with ``active_only`` those with ``g < 0`` (pushing);
        otherwise every candidate (the gap outputs)."""
        self._z = z
        out: list[_Term] = []
        keep = (lambda g: g < 0.0) if active_only else (lambda g: True)
        for nm in self.movable:
            body = self.bodies[nm]
            for j, st in enumerate(self.stops):
                out += self._rigid_rigid(body, st, j, (j, nm), keep)
        for label, a, b, what in self.declared:
            if what[0] == "bodies":
                out += self._rigid_rigid(self.bodies[a], self.bodies[b], label, (label,), keep)
            elif what[0] == "body-beam":
                out += self._body_beam(z, self.bodies[what[1]], what[2], label, keep)
            else:
                out += self._self(z, what[1], what[2], label, keep)
        return out

    def _rigid_rigid(self, p, q, group, key, keep) -> list[_Term]:
        """Corners of ``p`` against faces of ``q`` and corners of ``q`` against faces of ``p``
        (rigid outlines; a stop is a point, a wall or a polygon)."""
        z = self._z
        out = []
        for own, face in ((p, q), (q, p)):
            if face.a.shape[0] == 0:
                continue
            x, jac, curv = own.corner_points(z)
            c_f, th_f = face.pose(z)
            w = (x - c_f) @ _rot(th_f)  # R^T (x - c) row by row
            f, lam, dn, _ = face.nearest_faces(w)
            for v in range(x.shape[0]):
                if not 0.0 < lam[v] < 1.0:
                    continue
                if face.closed:
                    nsign = face.out
                else:  # a thin wall: the side the corner was on undeformed
                    nsign = self._wall_side[own.name, group][v]
                if not keep(nsign * dn[v]):  # the gap below, without its derivatives
                    continue
                dofs_p = () if own.dofs is None else tuple(own.dofs)
                gap, dofs, grad, hess = _point_face(
                    face, f[v], nsign, x[v], dofs_p,
                    np.zeros((2, 0)) if jac is None else jac[v], None if curv is None else curv[v],
                    0.0, c_f, th_f,
                )  # fmt: skip
                if not keep(gap):
                    continue
                foot = c_f + _rot(th_f) @ (face.a[f[v]] + lam[v] * (face.b[f[v]] - face.a[f[v]]))
                point = x[v] if own.dofs is None else foot  # on the stop when there is one
                out.append(_Term(group, (*key, own.name, v), gap, dofs, grad, hess, self.k_body,
                                 point))  # fmt: skip
        return out

    def _body_beam(self, z, body, i, label, keep) -> list[_Term]:
        """Beam ``i``'s nodes against the body's faces, the body's corners against the beam."""
        out = []
        contact = self.beams[i]
        xn = self._nodes(z, i)
        r = contact.radii_mm
        c_f, th_f = body.pose(z)
        w = (xn - c_f) @ _rot(th_f)
        f, lam, dn, _ = body.nearest_faces(w)
        for n in np.flatnonzero((lam > 0.0) & (lam < 1.0)):
            if not keep(body.out * dn[n] - r[n]):  # the gap below, without its derivatives
                continue
            base = int(self.offsets[i]) + 3 * n
            gap, dofs, grad, hess = _point_face(
                body, f[n], body.out, xn[n], (base, base + 1), np.eye(2), None, r[n], c_f, th_f
            )
            if keep(gap):
                out.append(_Term(label, ("n", i, int(n)), gap, dofs, grad, hess,
                                 float(contact.k_nodes[n]), xn[n].copy()))  # fmt: skip
        k_curve = float(contact.k_elements.min())
        x, jac, curv = body.corner_points(z)
        for v in range(x.shape[0]):
            if np.sqrt(((xn - x[v]) ** 2).sum(axis=1).min()) > contact.reach_mm:
                continue
            phi, xi, e, _ = contact.closest(x[v], xn)
            if not keep(phi):
                continue
            nodes = 2 * e + np.arange(3)
            g8, h8 = vertex_curve_derivatives(x[v], xn[nodes], xi, r[nodes[0]], r[nodes[2]])
            T = np.zeros((8, 9))
            T[0:2, 0:3] = jac[v]
            T[2:8, 3:9] = np.eye(6)
            grad, hess = T.T @ g8, T.T @ h8 @ T
            hess[2, 2] += float(g8[0:2] @ curv[v])
            beam_dofs = (int(self.offsets[i]) + 3 * nodes[:, None] + np.arange(2)).ravel()
            dofs = np.concatenate([body.dofs, beam_dofs])
            out.append(_Term(label, ("c", i, v), float(phi), dofs, grad, hess, k_curve,
                             x[v].copy()))  # fmt: skip
        return out

    def _self(self, z, i, far, label, keep) -> list[_Term]:
        """Beam ``i``'s nodes against its own centreline beyond the left-out arc length."""
        contact = self.beams[i]
        x = self._nodes(z, i)
        r = contact.radii_mm
        n_el = self.models[i].n_elements
        k_curve = float(contact.k_elements.min())
        if not np.any(far):
            return []
        d = np.hypot(x[:, None, 0] - x[None, :, 0], x[:, None, 1] - x[None, :, 1])
        # a node's distance to each far element's nearest node: every point of a P2 element
        # lies within a quarter of its length (along it) of one of its three nodes, so the
        # curve is no nearer than that distance less h/4 (h/2 keeps a margin for stretch)
        d_el = np.minimum(np.minimum(d[:, 0:-1:2], d[:, 1::2]), d[:, 2::2])  # (n, E)
        d_el = np.where(far, d_el, np.inf)
        dmin = d_el.min(axis=1)  # (n,) mm
        h = self._h_max[i]
        cand = np.flatnonzero(dmin - 0.5 * h <= r + r.max())  # those that may touch
        if keep(1.0):  # every candidate (the gap output): also the nodes nearest to the rest
            cand = np.union1d(cand, np.flatnonzero(dmin <= dmin.min() + h))
        out = []
        for n in cand:
            best = (np.inf, 0.0, -1)
            for e in np.flatnonzero(d_el[n] <= dmin[n] + 0.5 * h):
                nodes = 2 * e + np.arange(3)
                phi, xi, _ = closest_on_element(x[n], x[nodes], r[nodes[0]], r[nodes[2]])
                if phi < best[0]:
                    best = (phi, xi, int(e))
            phi, xi, e = best
            gap = float(phi - r[n])
            if e < 0 or e >= n_el or not keep(gap):
                continue
            nodes = 2 * e + np.arange(3)
            grad, hess = vertex_curve_derivatives(x[n], x[nodes], xi, r[nodes[0]], r[nodes[2]])
            all_nodes = np.concatenate([[n], nodes])
            dofs = (int(self.offsets[i]) + 3 * all_nodes[:, None] + np.arange(2)).ravel()
            k = min(float(contact.k_nodes[n]), k_curve)
            out.append(_Term(label, ("s", i, n, e), gap, dofs, grad, hess, k, x[n].copy()))
        return out

    # ------------------------------------------------------------------ assembly

    def add(self, z: np.ndarray, r: np.ndarray, rows: list, cols: list, vals: list) -> None:
        """Add the penalty forces to ``r`` (N,) and the tangent's COO triplets to the lists."""
        self._z = z
        terms = self.terms(z)
        self.active = frozenset((t.group, t.key) for t in terms)
        for t in terms:
            np.add.at(r, t.dofs, t.k * t.gap * t.grad)  # d(1/2 k g^2)/dz, N
            kt = t.k * (np.outer(t.grad, t.grad) + t.gap * t.hess)
            rows.append(np.repeat(t.dofs, t.dofs.size))
            cols.append(np.tile(t.dofs, t.dofs.size))
            vals.append(kt.ravel())

    # ------------------------------------------------------------------ outputs

    def stop_rows(self, Z: np.ndarray, converged: np.ndarray):
        """The bodies' share of every stop at every converged row of ``Z`` (rows, N):
        force on the bodies (rows, n_stops, 2) N, smallest gap of any body (rows, n_stops) mm
        (inf when no body faces the stop), the force magnitude (rows, n_stops) N and the
        force-weighted sum of the contact points (rows, n_stops, 2) N mm (for
        :func:`fea.stops.contact_over_beams`). NaN rows where not converged."""
        rows, ns = Z.shape[0], len(self.stops)
        force = np.full((rows, ns, 2), np.nan)
        gap = np.full((rows, ns), np.nan)
        weight = np.full((rows, ns), np.nan)
        psum = np.full((rows, ns, 2), np.nan)
        for k in np.flatnonzero(converged):
            self._z = Z[k]
            force[k], gap[k], weight[k], psum[k] = 0.0, np.inf, 0.0, 0.0
            for t in self.terms(Z[k], active_only=False):
                if not isinstance(t.group, int):
                    continue
                j = t.group
                gap[k, j] = min(gap[k, j], t.gap)
                if t.gap < 0.0:
                    body = self.bodies[t.key[1]]
                    sel = np.isin(t.dofs, body.dofs[:2])
                    f = -t.k * t.gap * t.grad[sel]  # the stop's force on the body, N
                    force[k, j] += f
                    weight[k, j] += -t.k * t.gap
                    psum[k, j] += -t.k * t.gap * t.point
        return force, gap, weight, psum

    def pair_rows(self, Z: np.ndarray, converged: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
        """Per declared pair ``"a/b"`` (rows,) arrays: ``force_N`` (the magnitude of the
        resultant contact force on part a, N; b carries the opposite; a beam with itself: the
        sum of its pairs' normal forces), ``gap_mm`` (smallest gap, mm; inf when nothing is
        within reach) and ``in_contact``; NaN where not converged."""
        out = {}
        rows = Z.shape[0]
        for label, *_ in self.declared:
            out[label] = {"force_N": np.full(rows, np.nan), "gap_mm": np.full(rows, np.nan)}
        for k in np.flatnonzero(converged):
            self._z = Z[k]
            acc = {lab: (np.zeros(2), np.inf, 0.0) for lab, *_ in self.declared}
            for t in self.terms(Z[k], active_only=False):
                if isinstance(t.group, int):
                    continue
                f_vec, g, total = acc[t.group]
                g = min(g, t.gap)
                if t.gap < 0.0:
                    f = -t.k * t.gap * t.grad
                    f_vec = f_vec + self._on_first(t, f)
                    total += -t.k * t.gap
                acc[t.group] = (f_vec, g, total)
            for label, a, b, _ in self.declared:
                f_vec, g, total = acc[label]
                out[label]["force_N"][k] = total if a == b else float(np.hypot(*f_vec))
                out[label]["gap_mm"][k] = g
        for label in out:
            out[label]["in_contact"] = out[label]["force_N"] > 0.0
        return out

    def _on_first(self, t: _Term, f: np.ndarray) -> np.ndarray:
        """The part of the force ``f`` (per DOF of ``t``, N) on the pair's first part (x, y)."""
        a = t.group.partition("/")[0]
        if a in self.bodies:
            sel = self.bodies[a].dofs
            return np.array([f[t.dofs == sel[0]].sum(), f[t.dofs == sel[1]].sum()])
        i = self.beam_index[a]
        lo, hi = self.offsets[i], self.offsets[i + 1]
        on = (t.dofs >= lo) & (t.dofs < hi)
        comp = (t.dofs - lo) % 3
        return np.array([f[on & (comp == 0)].sum(), f[on & (comp == 1)].sum()])
