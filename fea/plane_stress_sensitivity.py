"""Exact derivatives of a plane-stress solve's responses with respect to the mesh's node
coordinates, by the adjoint method on the converged path (issue 27 item 1; docs/sensitivities.md,
"Plane stress").

For a solved :class:`fea.plane_stress.PlaneStressModel` (its rows kept: ``keep_states=True``),
every converged row's

* torque on the drive about its centre, N·mm (``torque_Nmm``),
* reaction force on the drive, N (``force_N``, (2,): x and y),
* KS aggregate of the vertex-averaged von Mises stress over the checked vertices, MPa (``ks_MPa``),
  ``KS = max + ln(sum_v exp(rho (sigma_v - max))) / rho``, a smooth upper bound of the peak
  (``peak_nodal_stress_MPa``, the figure the spring kinds judge) within ``ln(n_v) / rho``,

are differentiated with respect to the mesh's vertex coordinates ``X`` (n_vertices, 2), mm, at
fixed mesh topology (P2 mid-side nodes at the edge midpoints, as the mesh is built).

Derivation (a response ``J(u, X)`` with ``u = P q + ubar(X)`` and equilibrium
``r = P^T f(u, X) = 0``; ``f`` the internal force, ``K = df/du`` the tangent at the converged row):
``J`` may read the internal force at the drive, ``J = w . f + j(u, X)`` (torque, force; ``w`` the
lever arms or the direction), so

    dJ/dX = dj/dX|_u + (a + K psi) . dubar/dX + psi . df/dX|_u,
    a = dj/du,  lambda = (P^T K P)^-1 P^T (a + K w),  psi = w - P lambda,

one back-substitution with the row's factorised tangent per response and row. ``psi . df/dX|_u``
is the shape derivative of the internal virtual work of the field ``psi`` (a "material
derivative" at fixed nodal values): with ``V`` the vertex velocity interpolated linearly on each
straight-sided triangle (``G = grad V``, constant per element), ``d(dx) = dx tr G``,
``d(grad N) = -grad N G``, ``d(grad u) = -H G`` (``H = grad u``), so per element

    psi . df/dX : V = b sum_q dx M : G,
    M = (P : L) I - L^T P - H^T B,   L = grad psi,   B = A : L,

with ``P`` the first Piola–Kirchhoff stress and ``A`` the tangent tensor (nonlinear; ``P = sigma``,
``A = C`` linear). ``B = L S + F (C : sym(F^T L))`` for St Venant–Kirchhoff. The KS term's
``dj/dX`` follows the same way from ``d(grad u) = -H G`` at the element corners; the derivative
of the von Mises stress with respect to ``grad u`` at a corner is taken by the complex step
(exact to round-off, four complex evaluations of the closed form).

Units: mm, N, MPa, N·mm; derivatives per mm of a vertex coordinate.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from flexopt.fea.errors import FeaError
from flexopt.fea.plane_stress import PlaneStressModel, PlaneStressResponse, Rotate

__all__ = [
    "KS_RHO_YIELD",
    "PlaneStressSensitivity",
    "fe_node_map",
    "ks_rho",
    "node_sensitivities",
]

#: The KS parameter as ``rho = KS_RHO_YIELD / yield`` (1/MPa): 500 / 2000 MPa = 0.25 /MPa for
#: maraging 300, so KS exceeds the peak by at most ln(n_vertices) / rho (~36 MPa for 7000
#: vertices) and in practice by the few vertices near the peak (docs/sensitivities.md: measured
#: on the SEA spring). A larger rho follows the max closer and curves more.
KS_RHO_YIELD = 500.0


def ks_rho(yield_MPa: float) -> float:
    """The KS parameter (1/MPa) of a material of yield ``yield_MPa``: ``KS_RHO_YIELD / yield``."""
    return KS_RHO_YIELD / float(yield_MPa)


@dataclass(frozen=True)
class PlaneStressSensitivity:
    """Responses of the differentiated rows and their derivatives by the vertex coordinates.

    ``k`` rows (``rows``), ``n`` mesh vertices. Derivatives are per mm of a vertex coordinate,
    in the vertex order of ``model.mesh.points``, last axis (x, y).

    Attributes
    ----------
    rows : (k,) int — the response rows differentiated (converged, drive value not 0).
    torque_Nmm : (k,) N·mm; d_torque : (k, n, 2) N·mm/mm.
    force_N : (k, 2) N (x, y); d_force : (k, 2, n, 2) N/mm.
    ks_MPa : (k,) MPa; d_ks : (k, n, 2) MPa/mm. rho_per_MPa : the KS parameter, 1/MPa.
    peak_nodal_MPa : (k,) MPa — the max the KS aggregates (for comparison).
    residual_N : (k,) N — the equilibrium residual norm at each row (the adjoint assumes 0).
    info : costs (``cpu_s``), the solver's factorisations.
    """

    rows: np.ndarray
    torque_Nmm: np.ndarray
    d_torque: np.ndarray
    force_N: np.ndarray
    d_force: np.ndarray
    ks_MPa: np.ndarray
    d_ks: np.ndarray
    rho_per_MPa: float
    peak_nodal_MPa: np.ndarray
    residual_N: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# Tables of the mesh


def _tables(basis: Any) -> tuple[np.ndarray, np.ndarray]:
    """Scalar shape-function gradients g (E, Q, ns, 2), 1/mm, and the DOFs (E, 2 ns) in (c, a)
    order of a vector P1/P2 basis (each local function is a scalar one times a unit vector)."""
    nb = int(basis.Nbfun)
    G = [np.asarray(basis.basis[j][0].grad) for j in range(nb)]  # each (2, 2, E, Q)
    comp = np.array([int(np.argmax([np.abs(Gj[c]).sum() for c in (0, 1)])) for Gj in G])
    idx = [np.flatnonzero(comp == c) for c in (0, 1)]
    if idx[0].size != idx[1].size:
        raise FeaError("node sensitivities need a vector element of one scalar element")
    g = np.ascontiguousarray(np.stack([G[i][0] for i in idx[0]]).transpose(2, 3, 0, 1))
    dofs = np.asarray(basis.element_dofs).T[:, np.concatenate(idx)]
    return g, np.ascontiguousarray(dofs)


def _hat_gradients(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(E, 3, 2) 1/mm: gradients of the three linear hat functions of each triangle (vertices
    ``points[tri]``), which carry a vertex velocity into ``G = grad V`` (constant per element)."""
    x = points[tri]  # (E, 3, 2)
    d1, d2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]  # 2 area
    # grad N1 = (d2_y, -d2_x) / det, grad N2 = (-d1_y, d1_x) / det, grad N0 = -(sum)
    n1 = np.column_stack([d2[:, 1], -d2[:, 0]]) / det[:, None]
    n2 = np.column_stack([-d1[:, 1], d1[:, 0]]) / det[:, None]
    return np.stack([-(n1 + n2), n1, n2], axis=1)


def fe_node_map(model: PlaneStressModel) -> sp.csr_matrix:
    """(n_fe_nodes, n_vertices) the FE nodes' coordinates as a linear map of the vertices' (a
    vertex itself, a P2 mid-side node the mean of its edge's ends), rows in ``model.xy`` order."""
    basis = model.basis
    n_v = int(model.skmesh.p.shape[1])
    pos = np.full(model.n_dofs, -1)
    pos[model.ix] = np.arange(model.ix.size)
    rows = [pos[np.asarray(basis.nodal_dofs[0])]]
    cols = [np.arange(n_v)]
    vals = [np.ones(n_v)]
    if model.settings.element == "P2":
        fd = pos[np.asarray(basis.facet_dofs[0])]
        ends = np.asarray(model.skmesh.facets)  # (2, n_facets)
        rows += [fd, fd]
        cols += [ends[0], ends[1]]
        vals += [np.full(fd.size, 0.5)] * 2
    r, c, v = (np.concatenate(a) for a in (rows, cols, vals))
    if np.any(r < 0):
        raise FeaError("node sensitivities: a vertex or mid-side DOF is not an x DOF")
    return sp.csr_matrix((v, (r, c)), shape=(model.ix.size, n_v))


class _Geometry:
    """What the derivatives read of a model's mesh, made once per model."""

    def __init__(self, model: PlaneStressModel) -> None:
        self.g, self.dofs = _tables(model.basis)  # (E, Q, ns, 2), (E, 2 ns)
        self.dx = np.asarray(model.basis.dx)  # (E, Q) mm^2
        self.gc, self.dofs_c = _tables(model.corner_basis)  # (E, 3, ns, 2) at the corners
        self.ns = int(self.g.shape[2])
        self.tri = np.asarray(model.skmesh.t).T  # (E, 3) vertices, the corners' order
        self.points = np.asarray(model.skmesh.p).T  # (n, 2) mm
        self.hat = _hat_gradients(self.points, self.tri)  # (E, 3, 2)
        self.node_map = fe_node_map(model)
        n = self.points.shape[0]
        self.count = np.bincount(self.tri.ravel(), minlength=n)
        allowed = np.zeros(n, dtype=bool)
        allowed[self.tri[model.stress_mask].ravel()] = True
        self.allowed = allowed

    def grad(self, v: np.ndarray, g: np.ndarray, dofs: np.ndarray) -> np.ndarray:
        """(E, Q, 2, 2) grad of a nodal field v (N,) at the points of table g: [e, q, c, J]."""
        ve = v[dofs].reshape(dofs.shape[0], 2, self.ns)  # (E, c, a)
        return np.einsum("eca,eqaJ->eqcJ", ve, g)

    def to_vertices(self, M: np.ndarray) -> np.ndarray:
        """(n, 2): the vertex gradient of ``sum_e M_e : G_e`` for element tensors M (E, 2, 2)
        (``G = sum_v V_v (x) grad N_v``: d/dV_(v,i) = sum_J M_iJ grad_J N_v)."""
        per = np.einsum("eiJ,ekJ->eki", M, self.hat)  # (E, 3 corners, i)
        n = self.points.shape[0]
        out = np.zeros((n, 2))
        for i in range(2):
            out[:, i] = np.bincount(self.tri.ravel(), weights=per[:, :, i].ravel(), minlength=n)
        return out


def _stress(H: np.ndarray, lam: float, mu: float, nonlinear: bool):
    """(F, P, S) at (..., 2, 2) displacement gradients H; S None in the linear case."""
    eye = np.eye(2)
    if not nonlinear:
        eps = 0.5 * (H + np.swapaxes(H, -1, -2))
        tr = np.trace(eps, axis1=-2, axis2=-1)[..., None, None]
        return None, lam * tr * eye + 2.0 * mu * eps, None
    F = eye + H
    E = 0.5 * (np.swapaxes(F, -1, -2) @ F - eye)
    tr = np.trace(E, axis1=-2, axis2=-1)[..., None, None]
    S = lam * tr * eye + 2.0 * mu * E
    return F, F @ S, S


def _shape_work(
    model: PlaneStressModel,
    geo: _Geometry,
    u: np.ndarray,
    psi: np.ndarray,
    nonlinear: bool,
    state: tuple | None = None,
) -> np.ndarray:
    """(n_vertices, 2) N: ``psi . df/dX`` at fixed nodal values — the derivative of the internal
    virtual work of the field ``psi`` (N,) mm at the displacement ``u`` (N,) mm by the vertex
    coordinates (module docstring). ``state``: :func:`_point_state` of ``u``, when made."""
    lam, mu, b = model.lam, model.mu, model.thickness_mm
    H, F, P, S = _point_state(model, geo, u, nonlinear) if state is None else state
    L = geo.grad(psi, geo.g, geo.dofs)
    eye = np.eye(2)
    if nonlinear:
        FtL = np.swapaxes(F, -1, -2) @ L
        symFL = 0.5 * (FtL + np.swapaxes(FtL, -1, -2))
        trFL = np.trace(FtL, axis1=-2, axis2=-1)[..., None, None]
        B = L @ S + F @ (lam * trFL * eye + 2.0 * mu * symFL)
    else:
        symL = 0.5 * (L + np.swapaxes(L, -1, -2))
        trL = np.trace(L, axis1=-2, axis2=-1)[..., None, None]
        B = lam * trL * eye + 2.0 * mu * symL
    PL = np.sum(P * L, axis=(-2, -1))[..., None, None]
    M = PL * eye - np.swapaxes(L, -1, -2) @ P - np.swapaxes(H, -1, -2) @ B  # (E, Q, 2, 2)
    Me = np.einsum("eqiJ,eq->eiJ", M, geo.dx * b)
    return geo.to_vertices(Me)


def _point_state(model: PlaneStressModel, geo: _Geometry, u: np.ndarray, nonlinear: bool):
    """(H, F, P, S) at the quadrature points of ``u`` (N,) mm, each (E, Q, 2, 2)."""
    H = geo.grad(u, geo.g, geo.dofs)
    F, P, S = _stress(H, model.lam, model.mu, nonlinear)
    return H, F, P, S


def _von_mises_of(H: Any, lam: float, mu: float, lam3d: float, nonlinear: bool) -> Any:
    """Von Mises Cauchy stress, MPa, of displacement gradients H (..., 2, 2), real or complex
    (the complex step), by the formulas of :func:`fea._plane_stress_kernels.von_mises`
    without its clips (which only act past SVK's collapse)."""
    h00, h01, h10, h11 = H[..., 0, 0], H[..., 0, 1], H[..., 1, 0], H[..., 1, 1]
    if not nonlinear:
        tr = h00 + h11
        s11 = lam * tr + 2.0 * mu * h00
        s22 = lam * tr + 2.0 * mu * h11
        s12 = mu * (h01 + h10)
    else:
        f00, f01, f10, f11 = 1.0 + h00, h01, h10, 1.0 + h11
        E00 = 0.5 * (f00 * f00 + f10 * f10 - 1.0)
        E11 = 0.5 * (f01 * f01 + f11 * f11 - 1.0)
        E01 = 0.5 * (f00 * f01 + f10 * f11)
        tr = E00 + E11
        S00 = lam * tr + 2.0 * mu * E00
        S11 = lam * tr + 2.0 * mu * E11
        S01 = 2.0 * mu * E01
        E33 = -lam3d * tr / (lam3d + 2.0 * mu)
        J = (f00 * f11 - f01 * f10) * np.sqrt(1.0 + 2.0 * E33)
        p00 = f00 * S00 + f01 * S01
        p01 = f00 * S01 + f01 * S11
        p10 = f10 * S00 + f11 * S01
        p11 = f10 * S01 + f11 * S11
        s11 = (p00 * f00 + p01 * f01) / J
        s22 = (p10 * f10 + p11 * f11) / J
        s12 = (p00 * f10 + p01 * f11) / J
    return np.sqrt(s11 * s11 - s11 * s22 + s22 * s22 + 3.0 * s12 * s12)


def _ks_terms(
    model: PlaneStressModel, geo: _Geometry, u: np.ndarray, rho: float, nonlinear: bool
) -> tuple[float, float, np.ndarray, np.ndarray]:
    """KS of the vertex-averaged von Mises over the checked vertices at ``u`` (N,) mm: (KS MPa,
    max MPa, dKS/du (N,) MPa/mm at fixed X, dKS/dX (n, 2) MPa/mm at fixed nodal u)."""
    lam, mu = model.lam, model.mu
    nu = model.material.nu  # the 3D Lamé lambda of the thickness strain, as the model's
    lam3d = model.material.E_MPa * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    H = geo.grad(u, geo.gc, geo.dofs_c)  # (E, 3, 2, 2) at the corners, t order
    vm = _von_mises_of(H, lam, mu, lam3d, nonlinear).real
    n = geo.points.shape[0]
    nodal = np.bincount(geo.tri.ravel(), weights=vm.ravel(), minlength=n) / np.maximum(geo.count, 1)
    s = nodal[geo.allowed]
    top = float(s.max())
    e = np.exp(rho * (s - top))
    ks = top + float(np.log(e.sum())) / rho
    omega = np.zeros(n)
    omega[geo.allowed] = e / e.sum()
    coef = (omega / np.maximum(geo.count, 1))[geo.tri]  # (E, 3): weight of each corner value
    # dvm/dH by the complex step, one component at a time (exact to round-off)
    D = np.zeros(H.shape)
    hstep = 1e-30
    for c in range(2):
        for J in range(2):
            Hc = H.astype(complex)
            Hc[..., c, J] += 1j * hstep
            D[..., c, J] = _von_mises_of(Hc, lam, mu, lam3d, nonlinear).imag / hstep
    W = coef[..., None, None] * D  # (E, 3, 2, 2): dKS/dH per corner
    # d/du: H_cJ = sum_a u_(c,a) g_aJ
    fe = np.einsum("ekcJ,ekaJ->eca", W, geo.gc).reshape(W.shape[0], -1)
    dks_du = np.bincount(geo.dofs_c.ravel(), weights=fe.ravel(), minlength=model.n_dofs)
    # d/dX: dH = -H G, so M = -H^T W summed over the corners
    M = -np.einsum("ekcI,ekcJ->eIJ", H, W)
    return ks, top, dks_du, geo.to_vertices(M)


class _Row:
    """One converged row's adjoint: its tangent ``K`` (factorised by the model's solver on the
    first back-substitution, kept for the next), the drive's ``dubar/dx`` (2, 2) and the
    quadrature-point state."""

    def __init__(self, model, geo, MT, u, K, dub, nonlinear, state) -> None:
        self.model, self.geo, self.MT, self.u, self.K = model, geo, MT, u, K
        self.dub, self.nonlinear, self.state = dub, nonlinear, state

    def total(self, w: np.ndarray, a: np.ndarray, expl_nodes: np.ndarray) -> np.ndarray:
        """dJ/dX (n, 2) of ``J = w . f + j`` with ``dj/du = a`` (N,) and ``dj/dx`` of the FE
        nodes ``expl_nodes`` (n_fe_nodes, 2) at fixed u."""
        model, K = self.model, self.K
        lam_q = model.reduced_solve(K, model.PT @ (a + K @ w))
        psi = w - model.P @ lam_q
        xi = a + K @ psi  # zero on the free DOFs: the drive's reaction to the adjoint
        node_grad = expl_nodes.copy()
        node_grad[model.drive_nodes] += (
            np.column_stack([xi[model.drive_dofs_x], xi[model.drive_dofs_y]]) @ self.dub
        )
        work = _shape_work(model, self.geo, self.u, psi, self.nonlinear, self.state)
        return self.MT @ node_grad + work


def node_sensitivities(
    model: PlaneStressModel,
    response: PlaneStressResponse,
    rho_per_MPa: float,
    rows: np.ndarray | None = None,
) -> PlaneStressSensitivity:
    """The derivatives of the torque, the reaction force and the KS stress of every converged
    row of ``response`` (solved on ``model`` with ``keep_states=True``) by the vertex coordinates
    (module docstring).

    Parameters
    ----------
    model : the solved model; its drive as it was solved (a spring's reverse solve: set the
        drive back to the solved direction first).
    response : its response, with ``row_dofs``.
    rho_per_MPa : the KS parameter, 1/MPa (:func:`ks_rho`).
    rows : (k,) int, optional — the rows to differentiate (default every converged row but 0).

    Raises
    ------
    FeaError
        No kept states, or a row asked for that did not converge.
    """
    t0 = time.process_time()
    if response.row_dofs is None:
        raise FeaError("node sensitivities need the rows' states: solve with keep_states=True")
    kin = response.kinematics
    nonlinear = kin != "linear"
    n_rows = len(response.row_dofs)
    if rows is None:
        rows = np.array([k for k in range(1, n_rows) if response.converged[k]], dtype=int)
    rows = np.asarray(rows, dtype=int)
    for k in rows:
        if not response.converged[k] or response.row_dofs[k] is None:
            raise FeaError(f"node sensitivities: row {k} did not converge")
    geo = _Geometry(model)
    n = geo.points.shape[0]
    d_nodes = model.drive_nodes
    ixd, iyd = model.drive_dofs_x, model.drive_dofs_y
    xd = model.xy[d_nodes]  # (m, 2) mm
    centre = model.drive.centre_mm
    centroid = centre is None
    c0 = xd.mean(axis=0) if centroid else np.asarray(centre, dtype=float)
    is_rot = isinstance(model.drive, Rotate)
    MT = geo.node_map.T.tocsr()  # FE-node gradients -> vertex gradients
    out = {k: [] for k in ("T", "dT", "F", "dF", "ks", "dks", "top", "res")}
    for k in rows:
        u = np.asarray(response.row_dofs[k], dtype=float)
        st = model.state(u, kin)
        f, K = st.f, st.K
        out["res"].append(float(np.linalg.norm(model.PT @ f)))
        value = float(response.drive_value[k])
        # dubar/dx_d of a driven node (2, 2): rotation R - I (linearised: value [[0,-1],[1,0]])
        if is_rot:
            if nonlinear:
                cth, sth = np.cos(value), np.sin(value)
                dub = np.array([[cth - 1.0, -sth], [sth, cth - 1.0]])
            else:
                dub = value * np.array([[0.0, -1.0], [1.0, 0.0]])
        else:
            dub = np.zeros((2, 2))

        state = _point_state(model, geo, u, nonlinear)
        row = _Row(model, geo, MT, u, K, dub, nonlinear, state)
        total = row.total

        fx, fy = f[ixd], f[iyd]
        arm = xd - c0
        if nonlinear:
            arm = arm + np.column_stack([u[ixd], u[iyd]])
        torque = float(np.sum(arm[:, 0] * fy - arm[:, 1] * fx))
        w = np.zeros(model.n_dofs)
        w[ixd], w[iyd] = -arm[:, 1], arm[:, 0]
        a = np.zeros(model.n_dofs)
        if nonlinear:
            a[ixd], a[iyd] = fy, -fx
        expl = np.zeros((model.xy.shape[0], 2))
        expl[d_nodes] = np.column_stack([fy, -fx])  # the lever arms' own x_d
        if centroid:  # the centre is the driven nodes' centroid: it moves with them
            expl[d_nodes] -= np.array([fy.sum(), -fx.sum()]) / d_nodes.size
        out["T"].append(torque)
        out["dT"].append(total(w, a, expl))
        zeros_nodes = np.zeros_like(expl)
        dF = []
        for comp in (ixd, iyd):
            w = np.zeros(model.n_dofs)
            w[comp] = 1.0
            dF.append(total(w, np.zeros(model.n_dofs), zeros_nodes))
        out["F"].append([fx.sum(), fy.sum()])
        out["dF"].append(dF)
        ks, top, dks_du, dks_dx = _ks_terms(model, geo, u, rho_per_MPa, nonlinear)
        out["ks"].append(ks)
        out["top"].append(top)
        out["dks"].append(dks_dx + total(np.zeros(model.n_dofs), dks_du, zeros_nodes))
    shape = (0, n, 2)
    arr = {key: np.asarray(val, dtype=float) for key, val in out.items()}
    return PlaneStressSensitivity(
        rows=rows,
        torque_Nmm=arr["T"],
        d_torque=arr["dT"] if rows.size else np.zeros(shape),
        force_N=arr["F"].reshape(-1, 2),
        d_force=arr["dF"] if rows.size else np.zeros((0, 2, n, 2)),
        ks_MPa=arr["ks"],
        d_ks=arr["dks"] if rows.size else np.zeros(shape),
        rho_per_MPa=float(rho_per_MPa),
        peak_nodal_MPa=arr["top"],
        residual_N=arr["res"],
        info={"cpu_s": time.process_time() - t0},
    )


def gap_sensitivity(
    model: PlaneStressModel, response: PlaneStressResponse, row: int, pairs: np.ndarray
) -> tuple[float, np.ndarray]:
    """The narrowest deformed distance of the node ``pairs`` (p, 2) (FE node indices into
    ``model.xy``: a spring's slot pairs, :func:`fea.spring_analysis.slot_pairs`) at the converged
    ``row`` of ``response`` (solved on ``model`` with ``keep_states=True``, its drive as it was
    solved), mm, and its derivative (n_vertices, 2) by the vertex coordinates.

    The distance of the closest pair ``a, b``, ``J = |x_a + u_a - x_b - u_b|``, differentiated
    with that pair held (the min over pairs is not differentiable where two pairs tie; the
    derivative is the active pair's, as the KS stress's is the aggregate's): ``dJ/du`` is the
    unit vector ``n`` at a's displacements and ``-n`` at b's, ``dJ/dx`` the same at the nodes'
    coordinates, and the adjoint of :func:`node_sensitivities` (``w = 0``) carries ``dJ/du``
    through the equilibrium.

    Raises
    ------
    FeaError
        No kept states, or the row did not converge.
    """
    if response.row_dofs is None or response.row_dofs[row] is None:
        raise FeaError("the gap's sensitivity needs the row's state: solve with keep_states=True")
    if not response.converged[row]:
        raise FeaError(f"the gap's sensitivity: row {row} did not converge")
    kin = response.kinematics
    nonlinear = kin != "linear"
    u = np.asarray(response.row_dofs[row], dtype=float)
    xy = np.asarray(model.xy)
    moved = xy + np.column_stack([u[model.ix], u[model.iy]])
    d = moved[pairs[:, 0]] - moved[pairs[:, 1]]
    dist = np.hypot(d[:, 0], d[:, 1])
    k = int(np.argmin(dist))
    a, b = (int(i) for i in pairs[k])
    gap = float(dist[k])
    n = d[k] / gap
    da = np.zeros(model.n_dofs)
    da[model.ix[a]], da[model.iy[a]] = n
    da[model.ix[b]] -= n[0]
    da[model.iy[b]] -= n[1]
    expl = np.zeros((xy.shape[0], 2))
    expl[a] += n
    expl[b] -= n
    st = model.state(u, kin)
    geo = _Geometry(model)
    value = float(response.drive_value[row])
    if isinstance(model.drive, Rotate):
        if nonlinear:
            c, s = np.cos(value), np.sin(value)
            dub = np.array([[c - 1.0, -s], [s, c - 1.0]])
        else:
            dub = value * np.array([[0.0, -1.0], [1.0, 0.0]])
    else:
        dub = np.zeros((2, 2))
    state = _point_state(model, geo, u, nonlinear)
    MT = geo.node_map.T.tocsr()
    r = _Row(model, geo, MT, u, st.K, dub, nonlinear, state)
    return gap, r.total(np.zeros(model.n_dofs), da, expl)
