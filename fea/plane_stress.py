"""Plane-stress elasticity of a flat part of thickness b, linear or geometrically nonlinear.

The part is a planar outline meshed with triangles (see :mod:`fea.mesh`) and extruded by its
out-of-plane thickness ``b``. One set of nodes is clamped; another (the *drive*) is moved as a rigid
body, either translated along a direction or rotated about a centre, in ``steps`` equal
increments. Each row of the response holds the driven value, the reaction the driver feels (force
vector, torque about the centre), the peak von Mises stress and where it sits.

Kinematics (registry :data:`KINEMATICS`):

``"linear"``
    Small strain, ``sigma = lambda* tr(eps) I + 2 mu eps`` with the plane-stress Lamé constant
    ``lambda* = 2 lambda mu / (lambda + 2 mu)``. A rotation drive is linearised
    (``u = theta e_z x (X - c)``).
``"nonlinear"``
    Total Lagrangian, St Venant–Kirchhoff: ``F = I + grad u``, ``E = (F^T F - I) / 2``,
    ``S = lambda* tr(E) I + 2 mu E``, first Piola–Kirchhoff ``P = F S``. For SVK the plane-stress
    condition ``S33 = 0`` is met exactly by the 2D law with ``lambda*``. Solved by Newton's method
    with the consistent tangent, with automatic cut-back of the load increment.

The weak forms are module-level scikit-fem forms fed with the current state through ``w``, in the
style of scikit-fem's hyperelasticity example. Everything is per unit thickness in the forms; the
thickness multiplies the assembled vectors and matrices. Numerical failure is returned as data
(``converged`` flags and ``message``), never raised. See docs/plane_stress.md.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
import scipy.sparse as sp
import shapely
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import TriMesh, to_skfem
from scipy.sparse.linalg import splu
from shapely.geometry.base import BaseGeometry
from skfem import (
    Basis,
    BilinearForm,
    ElementTriP1,
    ElementTriP2,
    ElementVector,
    LinearForm,
    asm,
)
from skfem.helpers import ddot, grad, sym_grad, trace, transpose

log = logging.getLogger(__name__)

__all__ = [
    "Clamp",
    "Translate",
    "Rotate",
    "PlaneStressSettings",
    "PlaneStressResponse",
    "PlaneStressModel",
    "KINEMATICS",
    "ELEMENTS",
    "plane_stress_lame",
    "interpolate_displacement",
    "MeshNumbering",
    "solve_plane_stress",
]


# --------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Clamp:
    """Nodes held fixed (both displacement components zero).

    region : shapely geometry, mm — every node on or inside it (within ``select_tol_mm``) is held.
    """

    region: BaseGeometry


@dataclass(frozen=True)
class Translate:
    """Drive nodes translated as a rigid body.

    region : shapely geometry, mm — the driven nodes (on or inside it).
    direction : (2,) — normalised internally; the driven displacement is along it.
    max_mm : float, mm — displacement at the last step (may be negative).
    steps : int — response rows after the initial row, at ``k * max_mm / steps``.
    transverse : "fixed" holds the motion perpendicular to ``direction`` at 0; "free" lets the
        driven nodes slide together perpendicular to it (one shared unknown), so the transverse
        reaction is zero.
    centre_mm : (2,) mm, optional — point the reported torque is taken about; default the
        centroid of the driven nodes.
    """

    region: BaseGeometry
    direction: tuple[float, float] = (1.0, 0.0)
    max_mm: float = 1.0
    steps: int = 10
    transverse: Literal["fixed", "free"] = "fixed"
    centre_mm: tuple[float, float] | None = None


@dataclass(frozen=True)
class Rotate:
    """Drive nodes rotated as a rigid body about a centre (counter-clockwise positive).

    region : shapely geometry, mm — the driven nodes.
    centre_mm : (2,) mm — centre of rotation.
    max_rad : float, rad — rotation at the last step.
    steps : int — response rows after the initial row, at ``k * max_rad / steps``.
    """

    region: BaseGeometry
    centre_mm: tuple[float, float] = (0.0, 0.0)
    max_rad: float = 0.1
    steps: int = 10


Drive = Translate | Rotate


@dataclass(frozen=True)
class PlaneStressSettings:
    """Discretisation and solver tolerances, each with its reason."""

    # Quadratic triangles: P1 locks in bending (a slender strip needs many P1 elements through
    # the thickness to get within a few % of beam theory); P2 is within 1 % with 2-4.
    element: Literal["P1", "P2"] = "P2"
    # Quadrature order; None picks 2 * p, which integrates the SVK residual and tangent exactly on
    # straight-sided triangles (S is quadratic, grad u of degree p - 1).
    intorder: int | None = None
    # Newton stops when the residual at the free DOFs is below this fraction of the internal-force
    # norm (which at equilibrium is the reaction). Newton converges quadratically, so 1e-9 costs
    # one iteration more than 1e-5 and makes the reactions accurate to the printed digits.
    rtol_residual: float = 1e-9
    # Absolute floor for the same test, N: far below any force a printed part carries, it only
    # matters at a zero-load state where the relative test is 0 / 0.
    atol_residual_N: float = 1e-10
    # Iterations per increment before it counts as failed and is cut back. Quadratic convergence
    # from the linearised predictor needs 2-6; more means the increment is too large.
    max_newton_iter: int = 15
    # Give an increment up early when the residual grew this many iterations in a row: Newton
    # from a bad predictor can wander before converging, but three rises means it left the basin.
    diverging_iterations: int = 3
    # Increment cut-back factor on failure, and growth factor after an easy increment.
    cutback_factor: float = 0.5
    growth_factor: float = 2.0
    # An increment that converged in at most this many iterations counts as easy.
    easy_iterations: int = 5
    # Give up a step after this many halvings (increment down to step / 2**8): by then the failure
    # is a physical limit (snap-through, element inversion, SVK's collapse under large
    # compression), not a too-large increment, and more halvings only burn time.
    max_cutbacks: int = 8
    # An element whose det F drops below this has (nearly) turned inside out; the iterate is
    # rejected. 0.05 is far beyond the strains a printed polymer survives (~5 %).
    min_det_F: float = 0.05
    # Distance under which a DOF location counts as on a clamp / drive geometry, mm.
    select_tol_mm: float = 1e-6
    # "vectorised": residual and tangent from basis-gradient tables precomputed once per mesh,
    # contracted with numpy and summed into a sparsity pattern found once (about 10x faster
    # than scikit-fem's per-basis-pair loop on P2). "compiled": the same tables and pattern, the
    # residual and tangent in one numba pass over the elements (fea/_plane_stress_kernels.py;
    # ~10 ms instead of ~90 ms per tangent at 30k DOFs, equal to round-off). "skfem": the
    # module-level forms through skfem.asm, kept as the readable reference (the tests check that
    # all agree). "auto": the environment variable FLEXOPT_PLANE_STRESS_ASSEMBLY if set, else
    # "compiled" (or "vectorised" when numba does not import).
    assembly: Literal["auto", "compiled", "vectorised", "skfem"] = "auto"
    # "direct" factorises every tangent (SuperLU). "krylov" solves each Newton system by
    # conjugate gradients preconditioned with the last factorisation (at first the linear
    # stiffness's, which the linear solve made anyway) and factorises the tangent only when CG
    # stalls. The tangent of a hyperelastic law under displacement control is symmetric, so CG
    # applies up to a limit point. Measured on an 11 degree step of a 30k-DOF torsion spring
    # (docs/plane_stress.md) it saves little: members turn by 20 degrees and more, the tangent
    # moves far from any earlier factorisation and CG needs 10-30 solves per iteration, each
    # ~1/20 of a factorisation. "pardiso": Intel MKL PARDISO through the optional package
    # pypardiso, symmetric indefinite, with the symbolic analysis of the (fixed) sparsity
    # pattern done once per model and only the numerical factorisation per tangent: 5-8x faster
    # than SuperLU on the spring (docs/plane_stress.md). "cholmod": sparse Cholesky (CHOLMOD,
    # supernodal, through cvxopt's wheels), the fill-reducing analysis of the fixed pattern done
    # once per model and only the numerical factorisation per tangent: ~11 ms against SuperLU's
    # ~120 ms at 30k DOFs. cvxopt is GPL-3.0, hence an optional extra. "qdldl": sparse LDLᵀ
    # (QDLDL, AMD ordering; Apache-2.0, a dependency of flexopt), the analysis kept the same
    # way: 14-21 ms per tangent at 26-30k DOFs, the solver of a plain install; a tangent with a
    # pivot <= 0 counts as not positive definite. Past a bifurcation or limit point the tangent
    # is indefinite and Cholesky (or LDLᵀ) stops; that tangent is then factorised by SuperLU
    # (counters["cholesky_failures"], which at a converged state says the equilibrium is
    # unstable under the drive). "auto": the environment variable FLEXOPT_PLANE_STRESS_SOLVER if
    # set, else cholmod when cvxopt imports, else qdldl when it imports, else pardiso when
    # pypardiso and MKL load, else "direct".
    solver: Literal["auto", "cholmod", "qdldl", "pardiso", "direct", "krylov"] = "auto"
    # CG stops at this residual relative to the right-hand side: Newton then keeps its
    # quadratic rate down to ~1e-10 of the force (an inexact solve of 1e-10 costs 2-3 more CG
    # iterations than 1e-6 and spares Newton iterations).
    krylov_rtol: float = 1e-10
    # CG iterations before the preconditioner counts as stale (and the tangent is factorised):
    # a good preconditioner converges in 5-30; 60 means the tangent moved too far from it.
    krylov_max_iter: int = 60


@dataclass(frozen=True)
class PlaneStressResponse:
    """One row per requested step (row 0 = undeformed). Arrays have shape (steps + 1,) unless noted.

    drive : "translate" or "rotate".
    kinematics : "linear" or "nonlinear".
    drive_value : driven value per row, mm (translate) or rad (rotate).
    displacement_mm : translation of the driven nodes along ``direction`` (0 for rotate).
    transverse_displacement_mm : their translation perpendicular to it (left of direction).
    force_N : force applied to the driven nodes projected on ``direction`` (positive when it
        pushes along ``direction``); for rotate, projected on x.
    transverse_force_N : the same, perpendicular (left of direction); for rotate, on y.
    reaction_N : (steps + 1, 2) force vector applied to the driven nodes, N.
    torque_Nmm : moment about the centre applied to the driven nodes, N·mm (counter-clockwise +).
    rotation_rad : rotation of the driven nodes (0 for translate).
    clamp_reaction_N : (steps + 1, 2) force vector applied to the clamped nodes, N.
    peak_stress_MPa : max von Mises Cauchy stress over the quadrature points (element level).
    peak_stress_xy_mm : (steps + 1, 2) where, in undeformed coordinates.
    peak_nodal_stress_MPa : max of the von Mises stress averaged at mesh vertices (nodal level;
        closer to the surface value in bending, but mesh dependent at sharp re-entrant corners).
    peak_nodal_stress_xy_mm : (steps + 1, 2) where, undeformed coordinates.
    iterations : (steps + 1,) int — Newton iterations spent reaching each row.
    converged : (steps + 1,) bool.
    ok : bool — every row converged.
    message : str — why not, when not ok.
    points_mm : (n, 2) mesh vertices, mm.
    displacement_field_mm : (n, 2) displacement of the vertices at the last converged row, mm.
    dofs : (N,) the full solution vector at the last converged row (scikit-fem DOF order).
    n_dofs : int — number of unknowns (2 per P2 node).
    solve_time_s : float — model build plus solve.
    extra : solver and assembly that ran ("cholmod" / "qdldl" / "pardiso" / "direct" / "krylov";
        "compiled" / "vectorised" / "skfem"), cholesky_failures: tangents the Cholesky
        (or LDLᵀ) path found indefinite and handed to LU, counted over the model's life, and
        guess: whether the first row started from a ``guess`` (see PlaneStressModel.solve).
    row_dofs : tuple of (N,) float arrays, mm, or None — the full solution vector at every
        converged row (None at a row that did not converge), kept only when the solve was asked
        to (``keep_states``: a detailed design's per-step fields, issue #26 item 5); None
        otherwise.
    """

    drive: str
    kinematics: str
    drive_value: np.ndarray
    displacement_mm: np.ndarray
    transverse_displacement_mm: np.ndarray
    force_N: np.ndarray
    transverse_force_N: np.ndarray
    reaction_N: np.ndarray
    torque_Nmm: np.ndarray
    rotation_rad: np.ndarray
    clamp_reaction_N: np.ndarray
    peak_stress_MPa: np.ndarray
    peak_stress_xy_mm: np.ndarray
    peak_nodal_stress_MPa: np.ndarray
    peak_nodal_stress_xy_mm: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    ok: bool
    message: str
    points_mm: np.ndarray
    displacement_field_mm: np.ndarray
    dofs: np.ndarray
    n_dofs: int
    solve_time_s: float
    extra: dict = field(default_factory=dict)
    row_dofs: tuple[np.ndarray | None, ...] | None = None


# --------------------------------------------------------------------------------------------
# Constitutive law and weak forms (per unit thickness)
# --------------------------------------------------------------------------------------------


def plane_stress_lame(E_MPa: float, nu: float) -> tuple[float, float]:
    """Plane-stress Lamé constants ``(lambda*, mu)`` in MPa.

    ``lambda* = 2 lambda mu / (lambda + 2 mu) = E nu / (1 - nu^2)``, ``mu = E / (2 (1 + nu))``.
    """
    mu = E_MPa / (2.0 * (1.0 + nu))
    lam = E_MPa * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    return 2.0 * lam * mu / (lam + 2.0 * mu), mu


def _matmul(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Matrix product of (2, 2, ...) fields."""
    return np.einsum("ik...,kj...->ij...", A, B)


def _eye_like(A: np.ndarray) -> np.ndarray:
    eye = np.zeros_like(A)
    eye[0, 0] = 1.0
    eye[1, 1] = 1.0
    return eye


def _svk_stress(E: np.ndarray, lam: float, mu: float) -> np.ndarray:
    """S = lambda* tr(E) I + 2 mu E for a (2, 2, ...) strain field."""
    return lam * trace(E) * _eye_like(E) + 2.0 * mu * E


def _sym(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + transpose(A))


@BilinearForm
def linear_stiffness(u, v, w):
    """a(u, v) = ∫ sigma(eps(u)) : eps(v) dA."""
    return ddot(_svk_stress(sym_grad(u), w.lam, w.mu), sym_grad(v))


@LinearForm
def internal_force(v, w):
    """r(v) = ∫ P : grad v dA with P = F S (first Piola–Kirchhoff), at the state in w."""
    return ddot(_matmul(w["F"], w["S"]), grad(v))


def _material_tensor(lam: float, mu: float) -> np.ndarray:
    """Plane-stress elasticity tensor C_IJKL = lambda* d_IJ d_KL + mu (d_IK d_JL + d_IL d_JK)."""
    d = np.eye(2)
    return lam * np.einsum("IJ,KL->IJKL", d, d) + mu * (
        np.einsum("IK,JL->IJKL", d, d) + np.einsum("IL,JK->IJKL", d, d)
    )


def _tangent_tensor(F: np.ndarray, S: np.ndarray, lam: float, mu: float) -> np.ndarray:
    """dP/dF for SVK: A_iJkL = d_ik S_JL + F_iM C_MJNL F_kN, shape (2, 2, 2, 2, nel, nqp).

    The first term is the geometric (initial-stress) stiffness, the second the material one.
    Building A once per Newton iteration lets the tangent form be a single contraction, which
    makes scikit-fem's per-basis-pair assembly loop about 4x faster than re-deriving
    ``sym(F^T grad du)`` for every pair.
    """
    C = _material_tensor(lam, mu)
    geometric = np.einsum("ik,JL...->iJkL...", np.eye(2), S)
    material = np.einsum("iM...,MJNL,kN...->iJkL...", F, C, F, optimize=True)
    return geometric + material


@BilinearForm
def tangent_stiffness(du, v, w):
    """Consistent tangent: ∫ grad v : A : grad du dA with A = dP/dF from w."""
    return np.einsum("ijkl...,kl...,ij...->...", w["A"], grad(du), grad(v))


# --------------------------------------------------------------------------------------------
# Vectorised assembly and the preconditioned solver
# --------------------------------------------------------------------------------------------


_KERNELS: list = []  # fea._plane_stress_kernels once imported, or None when numba cannot


def _compiled():
    """fea._plane_stress_kernels, or None when numba cannot be imported (numpy then runs)."""
    if not _KERNELS:
        try:
            from flexopt.fea import _plane_stress_kernels

            _KERNELS.append(_plane_stress_kernels)
        except Exception as exc:  # ImportError, or a numba that fails on this platform's LLVM
            log.debug("numba plane-stress kernel unavailable (%s: %s)", type(exc).__name__, exc)
            _KERNELS.append(None)
    return _KERNELS[0]


def _scalar_tables(basis: Basis) -> tuple[np.ndarray, np.ndarray]:
    """Scalar shape-function gradients g (E, Q, ns, 2), 1/mm, and DOFs (E, 2 ns) of a basis.

    A vector P1/P2 element's local function ``c * ns + a`` is scalar function ``a`` times unit
    vector ``e_c``, so its gradient is ``e_c (x) grad N_a``: only ``grad N_a`` is tabulated, and
    the DOF columns are reordered to ``(c, a)``.
    """
    nb = int(basis.Nbfun)
    G = [np.asarray(basis.basis[j][0].grad) for j in range(nb)]  # each (2, 2, E, Q)
    # Per function, not on one stacked (nb, 2, 2, E, Q) copy: ~10 ms -> ~4 ms at 30k DOFs.
    comp = np.array([np.argmax([np.abs(Gj[c]).sum() for c in (0, 1)]) for Gj in G])
    idx = [np.flatnonzero(comp == c) for c in (0, 1)]
    if idx[0].size != idx[1].size or not all(
        np.array_equal(G[i][0], G[j][1]) or np.allclose(G[i][0], G[j][1])
        for i, j in zip(idx[0], idx[1], strict=True)
    ):
        raise FeaError("vectorised assembly needs a vector element of one scalar element")
    g = np.ascontiguousarray(np.stack([G[i][0] for i in idx[0]]).transpose(2, 3, 0, 1))
    dofs = np.ascontiguousarray(np.asarray(basis.element_dofs).T[:, np.concatenate(idx)])
    return g, dofs


class _VectorAssembly:
    """Residual and tangent of a vector P1/P2 basis by whole-mesh numpy contractions.

    The same weak forms as :data:`internal_force` and :data:`tangent_stiffness`, written out for
    a vector element whose every local function is a scalar function times a unit vector:
    ``grad(phi_(c,a)) = e_c (x) grad(N_a)``. So only the scalar gradients are tabulated,
    ``g`` (nel, nqp, ns, 2), once per mesh, and

        f_(c,a) = b sum_q dx P_cJ g_aJ
        K_(c,a)(d,b) = b sum_q dx g_aJ A_cJdL g_bL

    The sparsity pattern (CSR indices and the position of every element entry in it) is found
    once; each assembly is then a ``bincount`` of the element entries into the CSR data.

    Parameters
    ----------
    basis : skfem Basis of ElementVector(ElementTriP1 / ElementTriP2).
    """

    def __init__(self, basis: Basis) -> None:
        self.g, self.dofs = _scalar_tables(basis)  # (E, Q, ns, 2), (E, 2 ns)
        self.ns = int(self.g.shape[2])
        self.gT = np.ascontiguousarray(self.g.transpose(0, 1, 3, 2))  # (E, Q, 2, ns)
        self.dx = np.asarray(basis.dx)  # (E, Q): quadrature weight times Jacobian
        self.N = int(basis.N)
        m = 2 * self.ns
        kernels = _compiled()
        if kernels is not None:
            # Same pattern and positions as the np.unique route below, without sorting the
            # 1e6 (row, col) keys of a 30k-DOF P2 mesh (~150 ms there, ~15 ms compiled).
            dofs = self.dofs.astype(np.int64)
            ns = self.ns
            nodes = dofs[:, :ns] // 2
            if self.N % 2 == 0 and np.array_equal(dofs, np.hstack([2 * nodes, 2 * nodes + 1])):
                # scikit-fem's vector numbering (DOF 2 node + component): the node pattern,
                # expanded, is the same pattern in a quarter of the work
                indptr, indices, where = kernels.csr_pattern_paired(nodes, self.N // 2)
            else:
                indptr, indices, where = kernels.csr_pattern(dofs, self.N)
            self._map = where
            self._rows = np.repeat(np.arange(self.N), np.diff(indptr))
            self._cols = indices
            self.nnz = int(indices.size)
            self.indptr = indptr.astype(np.int32)
        else:
            rows = np.repeat(self.dofs, m, axis=1).ravel().astype(np.int64)
            cols = np.tile(self.dofs, (1, m)).ravel().astype(np.int64)
            # Sorted unique (row, col) keys are exactly CSR order; the inverse places each
            # element entry in the data array.
            keys, self._map = np.unique(rows * self.N + cols, return_inverse=True)
            self._map = self._map.ravel()
            self._rows, self._cols = keys // self.N, keys % self.N
            self.nnz = int(keys.size)
            self.indptr = np.searchsorted(self._rows, np.arange(self.N + 1)).astype(np.int32)
        self.indices = self._cols.astype(np.int32)
        self._keep: np.ndarray | None = None  # (k,) positions of the reduced entries
        self._dofs64 = np.ascontiguousarray(self.dofs, dtype=np.int64)
        self._g = np.ascontiguousarray(self.g, dtype=float)
        # the compiled kernel reads 1e6 positions a tangent: int32 halves that stream (~6 %)
        self._where = self._map.astype(np.int32) if self.nnz < 2**31 else self._map

    def reduce_to(self, free: np.ndarray) -> None:
        """Also write the sub-matrix K[free][:, free] with every tangent (free sorted)."""
        pos = np.full(self.N, -1)
        pos[free] = np.arange(free.size)
        self._keep = (pos[self._rows] >= 0) & (pos[self._cols] >= 0)
        # pos is increasing on free, so the kept entries stay in CSR order.
        r, c = pos[self._rows[self._keep]], pos[self._cols[self._keep]]
        # positions, not the mask: np.take of 600k values is ~3x faster than a boolean mask
        self._keep = np.flatnonzero(self._keep)
        self._r_indices = c.astype(np.int32)
        # r is sorted: the row pointers are the cumulated row counts (a searchsorted of 30k
        # rows in 600k entries took ~10 ms).
        self._r_indptr = np.zeros(free.size + 1, dtype=np.int32)
        np.cumsum(np.bincount(r, minlength=free.size), out=self._r_indptr[1:])
        self._n_free = int(free.size)

    def deformation_gradient(self, u: np.ndarray) -> np.ndarray:
        """F = I + grad u, (2, 2, nel, nqp)."""
        ue = u[self.dofs].reshape(-1, 2, self.ns)
        F = np.einsum("eca,eqaJ->cJeq", ue, self.g)
        F[0, 0] += 1.0
        F[1, 1] += 1.0
        return F

    def internal_force(self, P: np.ndarray, thickness: float) -> np.ndarray:
        """(N,) internal force of a first Piola-Kirchhoff field P (2, 2, nel, nqp)."""
        fe = np.einsum("cJeq,eqaJ->eca", P * (self.dx * thickness), self.g)
        return np.bincount(self.dofs.ravel(), weights=fe.ravel(), minlength=self.N)

    def tangent(self, A: np.ndarray, thickness: float) -> sp.csr_matrix:
        """(N, N) stiffness of a tangent tensor A_iJkL, (2, 2, 2, 2, nel or 1, nqp or 1)."""
        E, Q = self.g.shape[:2]
        W = np.broadcast_to(A * (self.dx * thickness), (2, 2, 2, 2, E, Q))
        W = np.moveaxis(W, (4, 5), (0, 1))  # (E, Q, c, J, d, L)
        # H[e,q,c,a,d,L] = sum_J g[e,q,a,J] W[e,q,c,J,d,L]: two broadcast products, no loop.
        g = self.g
        H = (
            g[:, :, None, :, 0, None, None] * W[:, :, :, None, 0, :, :]
            + g[:, :, None, :, 1, None, None] * W[:, :, :, None, 1, :, :]
        )  # (E, Q, c, a, d, L)
        # Ke[e,(c,a,d),b] = sum_(q,L) H[e,q,c,a,d,L] g[e,q,b,L]: one batched matmul per mesh.
        Hm = np.moveaxis(H, 1, 4).reshape(E, 4 * self.ns, 2 * Q)  # (E, c a d, q L)
        Ke = np.matmul(Hm, self.gT.reshape(E, 2 * Q, self.ns))  # (E, c a d, b)
        data = np.bincount(self._map, weights=Ke.ravel(), minlength=self.nnz)
        return self.matrix(data)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """(N, N) CSR matrix of CSR data (nnz,) on the mesh's pattern (with its reduced block)."""
        K = sp.csr_matrix((data, self.indices, self.indptr), shape=(self.N, self.N))
        if self._keep is not None:
            n = self._n_free
            K._reduced = sp.csr_matrix(  # read by PlaneStressModel._reduced
                (np.take(data, self._keep), self._r_indices, self._r_indptr), shape=(n, n)
            )
        return K

    def compiled_state(
        self, u: np.ndarray, lam: float, mu: float, thickness: float, want_tangent: bool = True
    ) -> tuple[np.ndarray, sp.csr_matrix | None, float]:
        """SVK internal force (N,) N, tangent (N, N) N/mm (or None) and min det F, compiled.

        The same quantities as :meth:`deformation_gradient` + :meth:`internal_force` +
        :meth:`tangent` of :func:`_tangent_tensor`, in one pass (fea/_plane_stress_kernels.py).
        """
        f, data, min_det = _compiled().svk_assemble(
            np.ascontiguousarray(u, dtype=float), self._dofs64, self._g, self.dx,
            float(thickness), float(lam), float(mu), self._where, self.nnz, want_tangent,
        )  # fmt: skip
        return f, (self.matrix(data) if want_tangent else None), float(min_det)


def _pcg(
    A: sp.csr_matrix,
    b: np.ndarray,
    precondition: Callable[[np.ndarray], np.ndarray],
    rtol: float,
    max_iter: int,
) -> tuple[np.ndarray | None, int]:
    """Preconditioned conjugate gradients for A x = b (A symmetric).

    Returns ``(x, iterations)``, or ``(None, iterations)`` when the residual did not fall below
    ``rtol * |b|`` within ``max_iter`` iterations or A showed a non-positive curvature (CG does
    not apply; the caller factorises instead).
    """
    x = np.zeros_like(b)
    bnorm = float(np.linalg.norm(b))
    if bnorm == 0.0:
        return x, 0
    r = b.copy()
    z = precondition(r)
    p = z.copy()
    rz = float(r @ z)
    for k in range(1, max_iter + 1):
        Ap = A @ p
        curvature = float(p @ Ap)
        if not curvature > 0.0:
            return None, k
        alpha = rz / curvature
        x += alpha * p
        r -= alpha * Ap
        if np.linalg.norm(r) <= rtol * bnorm:
            return x, k
        z = precondition(r)
        rz_new = float(r @ z)
        p = z + (rz_new / rz) * p
        rz = rz_new
    return None, max_iter


class _Pardiso:
    """Intel MKL PARDISO (optional package pypardiso) on a fixed sparsity pattern.

    The matrix type is real symmetric indefinite (-2): the tangent is symmetric, positive
    definite until a limit point, and Bunch-Kaufman pivoting keeps the factorisation going past
    it. The fill-reducing analysis (phase 11) runs on the first matrix only; every later matrix
    has the same pattern (the vectorised assembly writes a fixed CSR structure), so only the
    numerical factorisation (phase 22) is repeated. Errors become RuntimeError, which the
    Newton loop treats like SuperLU's "singular" failure.

    Raises
    ------
    ImportError
        pypardiso is not installed or MKL's runtime library is not found.
    """

    def __init__(self) -> None:
        import pypardiso

        self._solver = pypardiso.PyPardisoSolver(mtype=-2)
        self._error = pypardiso.pardiso_wrapper.PyPardisoError
        self._pattern: tuple | None = None
        self._A: sp.csr_matrix | None = None

    def _upper(self, K: sp.csr_matrix) -> sp.csr_matrix:
        K = K.tocsr()
        if not K.has_sorted_indices:
            K = K.sorted_indices()
        key = (K.shape, K.indptr.tobytes(), K.indices.tobytes())
        if self._pattern is None or self._pattern[0] != key:
            rows = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
            keep = K.indices >= rows
            indptr = np.concatenate([[0], np.cumsum(np.bincount(rows[keep], minlength=K.shape[0]))])
            self._pattern = (key, keep, K.indices[keep].copy(), indptr, False)
        _, keep, indices, indptr, _ = self._pattern
        return sp.csr_matrix((K.data[keep], indices, indptr), shape=K.shape)

    def factorise(self, K: sp.csr_matrix) -> None:
        A = self._upper(K)
        key, keep, indices, indptr, analysed = self._pattern
        rhs = np.zeros((A.shape[0], 1))
        try:
            if not analysed:
                self._solver.set_phase(11)
                self._solver._call_pardiso(A, rhs)
                self._pattern = (key, keep, indices, indptr, True)
            self._solver.set_phase(22)
            self._solver._call_pardiso(A, rhs)
        except self._error as exc:
            raise RuntimeError(f"PARDISO factorisation failed: {exc}") from exc
        self._A = A

    def __del__(self) -> None:
        # pypardiso keeps MKL's factors until told otherwise: without this every model would
        # leak its factorisation (about 40 MB at 30k DOFs), gigabytes over an optimisation.
        try:
            self._solver.free_memory(everything=True)
        except Exception:  # interpreter shutdown: MKL may already be gone
            pass

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        self._solver.set_phase(33)
        try:
            x = self._solver._call_pardiso(self._A, np.asarray(rhs, dtype=float).reshape(-1, 1))
        except self._error as exc:
            raise RuntimeError(f"PARDISO solve failed: {exc}") from exc
        return np.asarray(x).ravel()


class _Cholmod:
    """CHOLMOD sparse Cholesky (SuiteSparse, through cvxopt) on a fixed sparsity pattern.

    The fill-reducing ordering and the symbolic factorisation (``cholmod.symbolic``) run on the
    first matrix of a pattern only; every later matrix of that pattern (the assembly writes a
    fixed CSR structure) is factorised numerically (``cholmod.numeric``) into the same factor.
    CHOLMOD picks its supernodal method here, dense BLAS on the supernodes: ~11 ms for the 29.5k
    free DOFs of the SEA spring against ~120 ms for SuperLU and ~100 ms for cholespy (whose
    wheels carry CHOLMOD's simplicial method only, with no way to keep the analysis).

    Why cvxopt: its wheels (Linux, macOS, Windows; x86-64 and arm64) carry SuiteSparse and a
    BLAS, so ``pip install .`` needs no compiler; scikit-sparse publishes no wheels.

    Raises
    ------
    ImportError
        cvxopt is not installed.
    """

    def __init__(self) -> None:
        from cvxopt import cholmod, matrix, spmatrix

        self._cholmod, self._matrix, self._spmatrix = cholmod, matrix, spmatrix
        self._indptr: np.ndarray | None = None  # the pattern analysed, (n + 1,) and (nnz,)
        self._indices: np.ndarray | None = None
        self._upper: np.ndarray | None = None  # (k,) int: positions of the entries col >= row
        self._A = None  # cvxopt spmatrix: the lower triangle on the pattern
        self._F = None  # CHOLMOD factor of the pattern (symbolic, then numeric)

    def _same_pattern(self, K: sp.csr_matrix) -> bool:
        if self._indptr is None:
            return False
        if K.indptr is self._indptr and K.indices.size == self._indices.size:
            # The assembly hands the same indptr array to every matrix of its pattern (scipy
            # keeps indptr but copies indices); comparing 600k indices costs ~2 ms a tangent.
            return True
        return np.array_equal(K.indptr, self._indptr) and np.array_equal(K.indices, self._indices)

    def factorise(self, K: sp.csr_matrix) -> bool:
        """Factorise a symmetric (n, n) CSR matrix; False when it is not positive definite.

        Only its upper triangle is read (as the lower triangle of the CSC transpose, which is
        the same storage): K must be symmetric.
        """
        if not K.has_sorted_indices:
            K = K.sorted_indices()
        n = K.shape[0]
        if not self._same_pattern(K):
            rows = np.repeat(np.arange(n), np.diff(K.indptr))
            # positions, not a mask: np.take of 300k values is ~3x faster than a boolean mask
            self._upper = np.flatnonzero(K.indices >= rows)
            # CSR's upper triangle, read column-major, is the CSC lower triangle already in
            # CHOLMOD's order (column, then row), so the values keep their order in the matrix.
            i = self._matrix(K.indices[self._upper].astype(np.int64))
            j = self._matrix(rows[self._upper].astype(np.int64))
            self._A = self._spmatrix(self._matrix(K.data[self._upper]), i, j, (n, n))
            self._F = self._cholmod.symbolic(self._A, uplo="L")
            self._indptr, self._indices = K.indptr, K.indices
        else:
            self._A.V = self._matrix(np.take(K.data, self._upper))
        try:
            self._cholmod.numeric(self._A, self._F)
        except ArithmeticError:  # CHOLMOD: "not positive definite" at the column it reports
            return False
        return True

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """x (n,) with K x = rhs (n,), K the last matrix factorised."""
        x = self._matrix(np.array(rhs, dtype=float))
        self._cholmod.solve(self._F, x)
        return np.asarray(x).ravel()


class _Qdldl:
    """QDLDL sparse LDLᵀ (the OSQP project's, AMD ordering; package qdldl) on a fixed pattern.

    The interface of :class:`_Cholmod`, for a plain install: qdldl is Apache-2.0 with wheels for
    Linux, macOS and Windows and needs only numpy and scipy, where cvxopt (CHOLMOD) is GPL-3.0
    and so an extra. The ordering and symbolic analysis run when the solver is built on the
    first matrix of a pattern; later matrices of it are refactorised numerically
    (``Solver.update``): ~14-21 ms for the SEA spring's 26-30k free DOFs against CHOLMOD's
    11-13 ms and SuperLU's 65-88 ms.

    LDLᵀ without pivoting also factorises an indefinite matrix (when no pivot is exactly zero),
    so "positive definite" is decided here from D: by Sylvester's law of inertia K is positive
    definite exactly when every pivot is > 0. An indefinite K returns False as CHOLMOD's
    refusal does, and the model hands it to LU; ``cholesky_failures`` keeps its meaning.

    Raises
    ------
    ImportError
        qdldl is not installed.
    """

    def __init__(self) -> None:
        import qdldl

        self._qdldl = qdldl
        self._indptr: np.ndarray | None = None  # the CSR pattern analysed, (n + 1,) and (nnz,)
        self._indices: np.ndarray | None = None
        self._lower: np.ndarray | None = None  # (k,) int: positions of the entries col <= row
        self._U: sp.csc_matrix | None = None  # the upper triangle, CSC, on the pattern
        self._solver = None  # qdldl.Solver of the pattern (analysis kept)

    _same_pattern = _Cholmod._same_pattern

    def factorise(self, K: sp.csr_matrix) -> bool:
        """Factorise a symmetric (n, n) CSR matrix; False when it is not positive definite.

        Only its lower triangle is read (as the upper triangle of the CSC transpose, which is
        the same storage): K must be symmetric.
        """
        if not K.has_sorted_indices:
            K = K.sorted_indices()
        n = K.shape[0]
        try:
            if not self._same_pattern(K) or self._solver is None:
                rows = np.repeat(np.arange(n), np.diff(K.indptr))
                self._lower = np.flatnonzero(K.indices <= rows)
                # CSR's lower triangle, read column-major, is the CSC upper triangle with its
                # rows sorted in each column: the values keep their order in the matrix.
                indptr = np.concatenate(
                    [[0], np.cumsum(np.bincount(rows[self._lower], minlength=n))]
                )
                self._U = sp.csc_matrix(
                    (K.data[self._lower], K.indices[self._lower], indptr), shape=(n, n)
                )
                self._solver = None  # a failed build below leaves no stale factor behind
                self._indptr, self._indices = K.indptr, K.indices
                self._solver = self._qdldl.Solver(self._U, upper=True)
            else:
                self._U.data = np.take(K.data, self._lower)
                self._solver.update(self._U, upper=True)
        except RuntimeError:  # a zero pivot (QDLDL: "not quasi-definite")
            return False
        # factors() copies L too (~2 ms at 30k DOFs, ~10 % of the refactorisation); it is the
        # only way the package gives D. A zero pivot in update() leaves zeros here, not an error.
        d = self._solver.factors()[1]
        return bool(np.all(d > 0.0))  # False for any D <= 0 and for NaN

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """x (n,) with K x = rhs (n,), K the last matrix factorised."""
        return np.asarray(self._solver.solve(np.asarray(rhs, dtype=float)), dtype=float).ravel()


SOLVERS = ("auto", "cholmod", "qdldl", "pardiso", "direct", "krylov")
"""PlaneStressSettings.solver values."""
SOLVER_ENV = "FLEXOPT_PLANE_STRESS_SOLVER"
"""Environment variable that sets the solver where the settings say "auto"."""
ASSEMBLIES = ("auto", "compiled", "vectorised", "skfem")
"""PlaneStressSettings.assembly values."""
ASSEMBLY_ENV = "FLEXOPT_PLANE_STRESS_ASSEMBLY"
"""Environment variable that sets the assembly where the settings say "auto"."""


def _pick(what: str, value: str, allowed: tuple[str, ...], env: str) -> str:
    """The setting ``value``, or for "auto" the environment's choice (or "auto" when unset)."""
    if value not in allowed:
        raise FeaError(f"{what} '{value}' unknown; use one of {', '.join(allowed)}")
    if value == "auto":
        value = os.environ.get(env, "").strip().lower() or "auto"
        if value not in allowed:
            raise FeaError(f"{env}={value!r} unknown; use one of {', '.join(allowed[1:])}")
        if what == "assembly" and value == "auto":
            value = "compiled"
    return value


# --------------------------------------------------------------------------------------------
# Model
# --------------------------------------------------------------------------------------------


def _set_facets(skmesh) -> None:
    """Give a scikit-fem triangle mesh its facet table and triangle-to-facet map, found by a unique
    over one int64 key per edge: the arrays scikit-fem's ``build_entities`` makes (a unique over
    the columns of a (2, 3m) array, ~10 ms at 7k triangles, against ~2 ms). Left to scikit-fem
    when the mesh has them already or is not laid out as this expects."""
    if hasattr(skmesh, "_facets") or not hasattr(skmesh, "_init_facets"):
        return
    t = np.asarray(skmesh.t)
    indices = skmesh.elem.refdom.facets
    if t.ndim != 2 or any(len(ix) != 2 for ix in indices):
        return
    ends = np.sort(np.hstack([t[ix] for ix in indices]), axis=0)  # (2, k m), each edge sorted
    # Sorted unique keys are the columns in scikit-fem's (lexicographic) order.
    key = ends[0].astype(np.int64) * (int(ends.max()) + 1) + ends[1]
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    skmesh._facets = np.ascontiguousarray(ends[:, first])
    skmesh._t2f = inverse.reshape((len(indices), t.shape[1]))


ELEMENTS: dict[str, Callable[[], object]] = {"P1": ElementTriP1, "P2": ElementTriP2}
"""Scalar element per settings.element; the displacement is its 2-vector."""


@dataclass
class _State:
    """Internal force and tangent at a displacement, per the kinematics."""

    f: np.ndarray
    K: sp.csr_matrix | None  # None: a force-only state (see PlaneStressModel._increment)
    min_det_F: float


@dataclass
class _Increment:
    """Outcome of one load increment: the new equilibrium, or why there is none."""

    ok: bool
    u: np.ndarray | None
    state: _State | None
    iterations: int
    reason: str = ""

    @classmethod
    def failed(cls, iterations: int, reason: str) -> _Increment:
        return cls(False, None, None, iterations, reason)


class PlaneStressModel:
    """Plane-stress model of a meshed outline: bases, DOF sets and constraints built once.

    Parameters
    ----------
    mesh : TriMesh
        Nodes (n, 2) mm and triangles.
    material : Material
        E (MPa) and nu are used; yield is left to the caller.
    thickness_mm : float, mm
        Out-of-plane thickness b.
    clamp : Clamp
        Held nodes.
    drive : Translate or Rotate
        Driven nodes and their motion.
    settings : PlaneStressSettings
    stress_ignore : shapely geometry, optional
        Elements touching it are left out of the peak-stress search (e.g. the clamp and drive
        pads, where a rigid clamp makes corner stresses singular).

    Raises
    ------
    FeaError
        Bad thickness, empty or overlapping clamp / drive sets, unknown element.
    """

    def __init__(
        self,
        mesh: TriMesh,
        material: Material,
        thickness_mm: float,
        clamp: Clamp,
        drive: Drive,
        settings: PlaneStressSettings = PlaneStressSettings(),
        stress_ignore: BaseGeometry | None = None,
    ) -> None:
        if not (np.isfinite(thickness_mm) and thickness_mm > 0):
            raise FeaError(f"thickness_mm = {thickness_mm} must be > 0 mm")
        if settings.element not in ELEMENTS:
            raise FeaError(
                f"element '{settings.element}' unknown; choose one of {', '.join(ELEMENTS)}"
            )
        if not isinstance(drive, Translate | Rotate):
            raise FeaError(f"drive must be Translate or Rotate, got {type(drive).__name__}")
        if drive.steps < 1:
            raise FeaError(f"drive.steps = {drive.steps} must be >= 1")
        self.mesh = mesh
        self.material = material
        self.thickness_mm = float(thickness_mm)
        self.clamp = clamp
        self.drive = drive
        self.settings = settings
        self.lam, self.mu = plane_stress_lame(material.E_MPa, material.nu)
        # 3D Lamé lambda, for the thickness strain E33 = -lambda tr(E) / (lambda + 2 mu).
        nu = material.nu
        self._lam3d = material.E_MPa * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))

        scalar = ELEMENTS[settings.element]()
        p = 2 if settings.element == "P2" else 1
        intorder = settings.intorder if settings.intorder is not None else 2 * p
        self.skmesh = to_skfem(mesh)
        _set_facets(self.skmesh)
        self.basis = Basis(self.skmesh, ElementVector(scalar), intorder=intorder)
        # Stress at the element corners, for vertex-averaged (nodal) values: a basis whose
        # "quadrature points" are the reference triangle's vertices, in the mesh's node order.
        corners = (np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), np.full(3, 1.0 / 6.0))
        self.corner_basis = Basis(
            self.skmesh, ElementVector(scalar), quadrature=corners, dofs=self.basis.dofs
        )  # the same DOFs: numbered once
        self.n_dofs = int(self.basis.N)
        self.ix, self.iy = self.basis.split_indices()
        self.xy = self.basis.doflocs[:, self.ix].T  # (n_nodes, 2): location of each FE node
        self.qp_xy = np.asarray(self.basis.global_coordinates())  # (2, nel, nqp)
        self._stress_mask = self._stress_elements(stress_ignore)
        self._K_lin: sp.csr_matrix | None = None  # linear stiffness, assembled on first use
        self._lu_lin = None  # and its factorisation
        self._lu_pre = None  # the factorisation CG is preconditioned with (krylov solver)
        self.counters = {
            "factorisations": 0,
            "cg_iterations": 0,
            "tangents": 0,
            "cholesky_failures": 0,
        }
        self.assembly = _pick("assembly", settings.assembly, ASSEMBLIES, ASSEMBLY_ENV)
        if self.assembly == "compiled" and _compiled() is None:
            self.assembly = "vectorised"  # numba missing: the numpy path, same answers
        solver = _pick("solver", settings.solver, SOLVERS, SOLVER_ENV)
        self._pardiso = None  # PARDISO handle (symbolic analysis kept) and what it holds
        self._pardiso_K = None
        # Cholesky handle (_Cholmod or _Qdldl, analysis kept), the K it holds, its LU stand-in
        self._chol = None
        self._chol_K = None
        self._chol_lu = None
        if solver == "auto":
            solver = "direct"
            for name, make in (("cholmod", _Cholmod), ("qdldl", _Qdldl), ("pardiso", _Pardiso)):
                try:
                    make()
                except ImportError:
                    continue
                solver = name
                break
        if solver == "cholmod":
            try:
                self._chol = _Cholmod()
            except ImportError as exc:
                raise FeaError(
                    f"solver 'cholmod' needs cvxopt ({exc}); pip install cvxopt, or use 'direct'"
                ) from exc
        elif solver == "qdldl":
            try:
                self._chol = _Qdldl()
            except ImportError as exc:
                raise FeaError(
                    f"solver 'qdldl' needs the package qdldl ({exc}); pip install qdldl, "
                    "or use 'direct'"
                ) from exc
        elif solver == "pardiso":
            try:
                self._pardiso = _Pardiso()
            except ImportError as exc:
                raise FeaError(
                    f"solver 'pardiso' needs pypardiso and Intel MKL ({exc}); "
                    "pip install pypardiso mkl, or use solver 'direct'"
                ) from exc
        #: the solver that runs: "cholmod", "qdldl", "pardiso", "direct" or "krylov"
        self.solver = solver
        self._asm = _VectorAssembly(self.basis) if self.assembly != "skfem" else None
        # von_mises' gradient tables by basis (the basis kept alive beside them, so its id stays
        # its own)
        self._vm_tables: dict[int, tuple] = {}
        # the undeformed row's measurements by reference point (see solve)
        self._rest_rows: dict[bytes, dict] = {}
        self._build_constraints()

    # ---- setup ------------------------------------------------------------------------------

    def _select(self, region: BaseGeometry, what: str) -> np.ndarray:
        tol = self.settings.select_tol_mm
        # Only nodes in the bounding box of one of the region's parts (grown by tol) can be
        # within tol of it; the exact distance, O(region vertices) per node, is then taken for
        # those few (a 15k-node mesh: 30 ms -> ~2 ms). Parts: pads spread around a spring make a
        # MultiPolygon whose overall box holds the whole mesh.
        x, y = self.xy[:, 0], self.xy[:, 1]
        in_box = np.zeros(x.size, dtype=bool)
        for x0, y0, x1, y1 in shapely.bounds(shapely.get_parts(region)).reshape(-1, 4):
            in_box |= (x >= x0 - tol) & (x <= x1 + tol) & (y >= y0 - tol) & (y <= y1 + tol)
        near = np.flatnonzero(in_box)
        nodes = near[shapely.distance(region, shapely.points(self.xy[near])) <= tol]
        if nodes.size == 0:
            d = shapely.distance(region, shapely.points(self.xy))  # for the message only
            raise FeaError(
                f"the {what} region selects no mesh node (nearest node is {d.min():.3g} mm away, "
                f"tolerance {self.settings.select_tol_mm:g} mm); put the {what} geometry on the "
                "outline boundary or make it a polygon overlapping the part"
            )
        return nodes

    def _stress_elements(self, ignore: BaseGeometry | None) -> np.ndarray:
        mask = np.ones(self.mesh.n_triangles, dtype=bool)
        if ignore is not None:
            # Only a triangle whose bounding box meets one of the region's parts' boxes can
            # touch it; the exact test is made for those (the hub and pad footprints of a
            # spring: a few hundred of 7k triangles, ~12 ms -> ~2 ms).
            # Part by part (a triangle touches a multi-part region when it touches a part), each
            # part a prepared copy (get_parts clones): ~3 ms -> ~1 ms for a spring's footprints.
            corners = self.mesh.points[self.mesh.triangles]  # (m, 3, 2)
            lo, hi = corners.min(axis=1), corners.max(axis=1)
            parts = shapely.get_parts(ignore)
            shapely.prepare(parts)
            for part, (x0, y0, x1, y1) in zip(parts, shapely.bounds(parts), strict=True):
                near = (hi[:, 0] >= x0) & (lo[:, 0] <= x1) & (hi[:, 1] >= y0) & (lo[:, 1] <= y1)
                idx = np.flatnonzero(near & mask)
                mask[idx[shapely.intersects(part, shapely.polygons(corners[idx]))]] = False
            if not mask.any():
                raise FeaError("stress_ignore covers every element; nothing left to check")
        return mask

    def _build_constraints(self) -> None:
        clamp_nodes = self._select(self.clamp.region, "clamp")
        drive_nodes = self._select(self.drive.region, "drive")
        both = np.intersect1d(clamp_nodes, drive_nodes)
        if both.size:
            x, y = self.xy[both[0]]
            raise FeaError(
                f"{both.size} node(s) are both clamped and driven, e.g. at ({x:.4g}, {y:.4g}) mm; "
                "separate the clamp and drive regions"
            )
        self.clamp_nodes, self.drive_nodes = clamp_nodes, drive_nodes
        self.clamp_dofs = np.concatenate([self.ix[clamp_nodes], self.iy[clamp_nodes]])
        self.drive_dofs_x = self.ix[drive_nodes]
        self.drive_dofs_y = self.iy[drive_nodes]
        fixed = np.concatenate([self.clamp_dofs, self.drive_dofs_x, self.drive_dofs_y])
        is_free = np.ones(self.n_dofs, dtype=bool)
        is_free[fixed] = False
        free = np.flatnonzero(is_free)  # = setdiff1d(arange, fixed), without its sort (~3 ms)
        # u = P q + ubar(value): q holds the free DOFs and, for a translation free transversely,
        # one more unknown shared by the driven nodes (their common sideways slide).
        cols = [
            sp.csr_matrix(
                (np.ones(free.size), (free, np.arange(free.size))), shape=(self.n_dofs, free.size)
            )
        ]
        d = self._direction()
        if isinstance(self.drive, Translate):
            if self.drive.transverse not in ("fixed", "free"):
                raise FeaError(f"transverse = '{self.drive.transverse}' must be 'fixed' or 'free'")
            if self.drive.transverse == "free":
                n = np.array([-d[1], d[0]])
                rows = np.concatenate([self.drive_dofs_x, self.drive_dofs_y])
                vals = np.concatenate(
                    [np.full(drive_nodes.size, n[0]), np.full(drive_nodes.size, n[1])]
                )
                slide = sp.csr_matrix(
                    (vals, (rows, np.zeros(rows.size, dtype=int))), shape=(self.n_dofs, 1)
                )
                cols.append(slide)
        self.P = sp.hstack(cols).tocsr()
        self.PT = self.P.T.tocsr()
        self._PTP = np.asarray(self.P.multiply(self.P).sum(axis=0)).ravel()  # diag(P^T P)
        self.free = free
        # With a pure selection (no shared sliding unknown) the reduced matrix is a sub-matrix,
        # which the vectorised assembly writes directly instead of forming P^T K P.
        self._selection_only = len(cols) == 1
        if self._asm is not None and self._selection_only:
            self._asm.reduce_to(free)

    def _direction(self) -> np.ndarray:
        if isinstance(self.drive, Rotate):
            return np.array([1.0, 0.0])
        d = np.asarray(self.drive.direction, dtype=float)
        norm = np.linalg.norm(d)
        if not (d.shape == (2,) and np.isfinite(norm) and norm > 0):
            raise FeaError(f"drive direction {self.drive.direction} must be a non-zero (dx, dy)")
        return d / norm

    def _centre(self) -> np.ndarray:
        c = self.drive.centre_mm
        if c is None:
            return self.xy[self.drive_nodes].mean(axis=0)
        return np.asarray(c, dtype=float)

    def prescribed(self, value: float, kinematics: str) -> np.ndarray:
        """ubar (N,): the driven DOFs' prescribed displacement at a driven value (mm or rad)."""
        ubar = np.zeros(self.n_dofs)
        X = self.xy[self.drive_nodes]
        if isinstance(self.drive, Translate):
            move = np.broadcast_to(value * self._direction(), X.shape)
        else:
            r = X - self._centre()
            if kinematics == "linear":
                # Linear theory cannot carry a finite rigid rotation; use its linearisation so the
                # linear torque is exactly proportional to the angle.
                move = value * np.column_stack([-r[:, 1], r[:, 0]])
            else:
                c, s = np.cos(value), np.sin(value)
                move = np.column_stack([c * r[:, 0] - s * r[:, 1], s * r[:, 0] + c * r[:, 1]]) - r
        ubar[self.drive_dofs_x] = move[:, 0]
        ubar[self.drive_dofs_y] = move[:, 1]
        return ubar

    # ---- physics ----------------------------------------------------------------------------

    def linear_stiffness(self) -> sp.csr_matrix:
        """(n_dofs, n_dofs) N/mm: the stiffness at u = 0 (the SVK tangent there), assembled once
        and kept."""
        return self._linear_stiffness()

    def reduced_solve(self, K: sp.csr_matrix, rhs: np.ndarray) -> np.ndarray:
        """The free DOFs' correction (n_free,) of ``P^T K P dq = rhs`` for a tangent ``K``
        (n_dofs, n_dofs) N/mm of this model and a reduced right-hand side ``rhs`` (n_free,) N,
        with the model's own factoriser (CHOLMOD with the pattern's analysis kept, SuperLU
        where a tangent is not positive definite; PARDISO or SuperLU / PCG otherwise) and its
        counters (``counters["factorisations"]`` ...)."""
        return self._reduced_solve(K, rhs)

    def _linear_stiffness(self) -> sp.csr_matrix:
        return self._state_linear(np.zeros(self.n_dofs)).K

    def _state_linear(self, u: np.ndarray) -> _State:
        if self._K_lin is None:
            if self.assembly == "compiled":
                # F = I and S = 0 at u = 0: the SVK tangent there is the linear stiffness.
                _, self._K_lin, _ = self._asm.compiled_state(
                    np.zeros(self.n_dofs), self.lam, self.mu, self.thickness_mm
                )
            elif self._asm is not None:
                C = _material_tensor(self.lam, self.mu)[:, :, :, :, None, None]
                self._K_lin = self._asm.tangent(C, self.thickness_mm)
            else:
                self._K_lin = (
                    asm(linear_stiffness, self.basis, lam=self.lam, mu=self.mu) * self.thickness_mm
                ).tocsr()
        return _State(self._K_lin @ u, self._K_lin, 1.0)

    def _deformation(self, u: np.ndarray, basis: Basis) -> tuple[np.ndarray, np.ndarray]:
        """F and S at the quadrature points of ``basis``, each (2, 2, nel, nqp)."""
        F = basis.interpolate(u).grad + _eye_like(np.empty((2, 2, 1, 1)))
        E = 0.5 * (_matmul(transpose(F), F) - _eye_like(F))
        return F, _svk_stress(E, self.lam, self.mu)

    def _state_nonlinear(self, u: np.ndarray, tangent: bool = True) -> _State:
        """Force, tangent and min det F at u; ``tangent=False`` (compiled assembly only) leaves
        the tangent out (``K`` None)."""
        b = self.thickness_mm
        if self.assembly == "compiled" and not tangent:
            f, _, min_det = self._asm.compiled_state(u, self.lam, self.mu, b, False)
            return _State(f, None, min_det)
        self.counters["tangents"] += 1
        if self.assembly == "compiled":
            if self._K_lin is not None and not u.any():
                # The undeformed state: F = I and S = 0 exactly, so the compiled tangent is the
                # linear stiffness to the bit (same kernel at u = 0) and the force is zero. The
                # same matrix object also spares its refactorisation after a linear solve.
                return _State(np.zeros(self.n_dofs), self._K_lin, 1.0)
            f, K, min_det = self._asm.compiled_state(u, self.lam, self.mu, b)
            return _State(f, K, min_det)
        if self._asm is not None:
            F = self._asm.deformation_gradient(u)
            E = 0.5 * (_matmul(transpose(F), F) - _eye_like(F))
            S = _svk_stress(E, self.lam, self.mu)
            det = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
            f = self._asm.internal_force(_matmul(F, S), b)
            K = self._asm.tangent(_tangent_tensor(F, S, self.lam, self.mu), b)
            return _State(f, K, float(det.min()))
        F, S = self._deformation(u, self.basis)
        det = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
        f = asm(internal_force, self.basis, F=F, S=S) * b
        A = _tangent_tensor(F, S, self.lam, self.mu)
        K = asm(tangent_stiffness, self.basis, A=A) * b
        return _State(f, K.tocsr(), float(det.min()))

    def state(self, u: np.ndarray, kinematics: str) -> _State:
        """Internal force (N,) in N and tangent (N, N) in N/mm at displacement u (N,) mm."""
        return KINEMATICS[kinematics](self, u)

    def von_mises(self, u: np.ndarray, kinematics: str, basis: Basis | None = None) -> np.ndarray:
        """Von Mises Cauchy stress, MPa, (nel, nqp) at the quadrature points of ``basis``."""
        basis = self.basis if basis is None else basis
        if self.assembly == "compiled":
            # The same formulas compiled on gradient tables made once per basis (~1 ms instead
            # of ~15 ms for skfem's interpolate and the numpy tensor algebra at 30k DOFs).
            tables = self._vm_tables.get(id(basis))
            if tables is None:
                if basis is self.basis:  # the assembly's tables, made with the model
                    tables = (basis, self._asm.g, self._asm.dofs)
                else:
                    tables = (basis, *_scalar_tables(basis))
                self._vm_tables[id(basis)] = tables
            _, g, dofs = tables
            return _compiled().von_mises(
                np.ascontiguousarray(u, dtype=float), dofs.astype(np.int64), g,
                self.lam, self.mu, self._lam3d, kinematics != "linear",
            )  # fmt: skip
        if kinematics == "linear":
            eps = _sym(basis.interpolate(u).grad)
            sig = _svk_stress(eps, self.lam, self.mu)
        else:
            F, S = self._deformation(u, basis)
            det2 = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
            # Thickness stretch from S33 = 0: E33 = -lambda tr(E) / (lambda + 2 mu), with the 3D
            # lambda; J = det(F_2D) * lambda3 turns PK2 into Cauchy stress.
            E = 0.5 * (_matmul(transpose(F), F) - _eye_like(F))
            E33 = -self._lam3d * trace(E) / (self._lam3d + 2.0 * self.mu)
            # The clip only keeps the sqrt real past SVK's collapse, where no row converges anyway.
            J = det2 * np.sqrt(np.maximum(1.0 + 2.0 * E33, 1e-12))
            sig = _matmul(_matmul(F, S), transpose(F)) / J
        s11, s22, s12 = sig[0, 0], sig[1, 1], sig[0, 1]
        return np.sqrt(np.maximum(s11**2 - s11 * s22 + s22**2 + 3.0 * s12**2, 0.0))

    @property
    def stress_mask(self) -> np.ndarray:
        """(n_triangles,) bool: the elements :meth:`peak_stress` counts (those not touching
        ``stress_ignore``); the model's own array, read-only by contract."""
        return self._stress_mask

    def peak_stress(
        self, u: np.ndarray, kinematics: str
    ) -> tuple[float, np.ndarray, float, np.ndarray]:
        """Peak von Mises stress at quadrature points and at vertices (averaged), with locations.

        Returns
        -------
        peak_MPa, xy_mm (2,), peak_nodal_MPa, nodal_xy_mm (2,)
        """
        vm = self.von_mises(u, kinematics)[self._stress_mask]
        k = np.unravel_index(np.argmax(vm), vm.shape)
        xy = self.qp_xy[:, self._stress_mask][:, k[0], k[1]]
        vc = self.von_mises(u, kinematics, self.corner_basis)  # (nel, 3), corners in t order
        t = self.skmesh.t.T  # (nel, 3)
        n = self.mesh.n_points
        total = np.bincount(t.ravel(), weights=vc.ravel(), minlength=n)
        count = np.bincount(t.ravel(), minlength=n)
        nodal = total / np.maximum(count, 1)
        allowed = np.zeros(n, dtype=bool)
        allowed[t[self._stress_mask].ravel()] = True
        nodal[~allowed] = -np.inf
        j = int(np.argmax(nodal))
        return float(vm[k]), xy, float(nodal[j]), self.skmesh.p[:, j].copy()

    # ---- solver -----------------------------------------------------------------------------

    def _reduced(self, K: sp.csr_matrix) -> sp.csr_matrix:
        """P^T K P: a sub-matrix written by the assembly when P is a selection."""
        Kr = getattr(K, "_reduced", None)
        return Kr if Kr is not None else (self.PT @ K @ self.P).tocsr()

    def reduced(self, K: sp.csr_matrix) -> sp.csr_matrix:
        """P^T K P (n_free, n_free) N/mm: the tangent ``K`` (N, N) on the free DOFs."""
        return self._reduced(K)

    def cholesky_factor(self, K: sp.csr_matrix) -> Any | None:
        """The model's factor of P^T K P, with ``solve(rhs)``: its Cholesky (the pattern's
        analysis kept; LU where K is not positive definite), made as a solve makes it or kept
        from the last solve of this K. None when the model's solver is not a Cholesky (CHOLMOD,
        QDLDL)."""
        if self._chol is None:
            return None
        self._reduced_solve(K, np.zeros(self.P.shape[1]))  # factorises K (or keeps it)
        return self._chol if self._chol_lu is None else self._chol_lu

    def _factorise(self, Kr: sp.csr_matrix):
        self.counters["factorisations"] += 1
        # A minimum-degree ordering of A^T + A suits these symmetric tangents: 30 % less fill and
        # ~15 % less time than SuperLU's default COLAMD on a 25k-DOF strip.
        return splu(Kr.tocsc(), permc_spec="MMD_AT_PLUS_A")

    def _reduced_solve(self, K: sp.csr_matrix, rhs: np.ndarray) -> np.ndarray:
        if self._chol is not None:
            # One handle: the pattern's analysis is kept, the numbers refactorised on a new K.
            if self._chol_K is not K:
                self.counters["factorisations"] += 1
                Kr = self._reduced(K)
                self._chol_lu = None
                if not self._chol.factorise(Kr):
                    # Not positive definite: past a bifurcation or limit point, or a Newton
                    # iterate far from equilibrium. LU (partial pivoting) solves it all the same.
                    self.counters["cholesky_failures"] += 1
                    self._chol_lu = self._factorise(Kr)
                self._chol_K = K
            if self._chol_lu is not None:
                return self._chol_lu.solve(rhs)
            return self._chol.solve(rhs)
        if self._pardiso is not None:
            # One handle: the pattern's analysis is kept, the numbers refactorised on a new K.
            if self._pardiso_K is not K:
                self.counters["factorisations"] += 1
                self._pardiso.factorise(self._reduced(K))
                self._pardiso_K = K
            return self._pardiso.solve(rhs)
        if K is self._K_lin:
            if self._lu_lin is None:  # the linear stiffness is factorised once
                self._lu_lin = self._factorise(self._reduced(K))
            return self._lu_lin.solve(rhs)
        Kr = self._reduced(K)
        if self.solver == "direct":
            return self._factorise(Kr).solve(rhs)
        pre = self._lu_pre
        if pre is None:
            if self._lu_lin is None:
                self._lu_lin = self._factorise(self._reduced(self._linear_stiffness()))
            pre = self._lu_pre = self._lu_lin
        x, n_iter = _pcg(
            Kr, rhs, pre.solve, self.settings.krylov_rtol, self.settings.krylov_max_iter
        )
        self.counters["cg_iterations"] += n_iter
        if x is not None:
            return x
        # The tangent has moved away from the preconditioner (large rotation, stress
        # stiffening, a limit point near): factorise it and precondition with it from now on.
        self._lu_pre = self._factorise(Kr)
        return self._lu_pre.solve(rhs)

    def _increment(
        self,
        u0: np.ndarray,
        s0: _State,
        ubar_step: np.ndarray,
        kinematics: str,
        guess: np.ndarray | None = None,
    ) -> _Increment:
        """Newton from equilibrium u0 to the next prescribed value; ubar_step = ubar_new - ubar_old.

        The first iteration linearises at u0 with the boundary increment on the right-hand side,
        so the driven nodes move without first distorting the elements next to them. With a
        ``guess`` (N,) mm, Newton starts instead from the guess's unknowns (the prescribed DOFs
        at their new values): see :meth:`solve`.
        """
        cfg = self.settings
        if guess is not None:
            ub = u0 + ubar_step
            # The guess's unknowns q = argmin |P q - (guess - ub)|: P^T P is diagonal (a
            # selection, plus a shared sliding column for a transversely free drive).
            u = ub + self.P @ ((self.PT @ (guess - ub)) / self._PTP)
        else:
            if s0.K is None:  # the last increment converged on a force-only state
                s0 = self.state(u0, kinematics)
            try:
                dq = self._reduced_solve(s0.K, -(self.PT @ (s0.f + s0.K @ ubar_step)))
            except RuntimeError as exc:  # SuperLU: "Factor is exactly singular"
                return _Increment.failed(
                    1, f"singular stiffness ({exc}): a mechanism or a limit point"
                )
            u = u0 + ubar_step + self.P @ dq
        history: list[float] = []
        n_rise = cfg.diverging_iterations
        scale = 0.0
        for it in range(1, cfg.max_newton_iter + 1):
            # Near convergence the force alone decides: when the quadratic rate of the last two
            # residuals puts this one a decade under the tolerance, the force is found first
            # (~2 ms compiled) and the tangent (~8 ms, unused at a converged state) only if it
            # is still needed. The iterates and answers are the same either way.
            likely = (
                self.assembly == "compiled"
                and kinematics != "linear"
                and len(history) >= 2
                and 0.0 < history[-1] < history[-2]
                and history[-1] ** 3 / history[-2] ** 2
                < 0.1 * (cfg.rtol_residual * scale + cfg.atol_residual_N)
            )
            st = self._state_nonlinear(u, tangent=False) if likely else self.state(u, kinematics)
            if not np.all(np.isfinite(st.f)):
                return _Increment.failed(it, "non-finite internal force")
            if st.min_det_F < cfg.min_det_F:
                return _Increment.failed(it, f"element inverted (det F = {st.min_det_F:.3g})")
            r = self.PT @ st.f
            res = float(np.linalg.norm(r))
            scale = float(np.linalg.norm(st.f))
            if res <= cfg.rtol_residual * scale + cfg.atol_residual_N:
                return _Increment(True, u, st, it)
            if st.K is None:  # not converged after all: the tangent at the same state
                st = self.state(u, kinematics)
            if guess is not None and history and res > 10.0 * history[-1]:
                # From a good guess Newton converges from the start; a residual ten times the
                # last one means the guess was outside the basin (a two-arm spring turned 0.3
                # rad: 14 iterations from the reflected guess against 6 from the linearised
                # step): solve from the linearised step instead.
                return _Increment.failed(it, f"the residual grew tenfold to {res:.3g} N")
            history.append(res)
            if len(history) > n_rise and all(np.diff(history[-n_rise - 1 :]) > 0):
                return _Increment.failed(it, f"Newton diverging (residual {res:.3g} N, growing)")
            refused = self.counters["cholesky_failures"]
            try:
                u = self._newton_update(u, self.P @ self._reduced_solve(st.K, -r), res)
            except RuntimeError as exc:
                return _Increment.failed(it, f"singular tangent ({exc})")
            if guess is not None and self.counters["cholesky_failures"] > refused:
                # An indefinite tangent on the way from a guess: Newton is off the stable path
                # the drive follows from rest; the linearised step finds out for itself.
                return _Increment.failed(it, "an indefinite tangent on the way")
        return _Increment.failed(
            cfg.max_newton_iter,
            f"no convergence in {cfg.max_newton_iter} Newton iterations "
            f"(residual {res:.3g} N vs force scale {scale:.3g} N)",
        )

    def _newton_update(self, u: np.ndarray, du: np.ndarray, res: float) -> np.ndarray:
        """The next Newton iterate from u (N,) mm along the full step du (N,) mm, where the
        residual norm is res (N); a subclass may shorten the step (fea/plane_stress_contact.py
        searches along it when contact is active)."""
        return u + du

    def _measure(self, u: np.ndarray, st: _State, kinematics: str) -> dict:
        b_f = np.array([st.f[self.drive_dofs_x].sum(), st.f[self.drive_dofs_y].sum()])
        c_f = np.array(
            [
                st.f[self.ix[self.clamp_nodes]].sum(),
                st.f[self.iy[self.clamp_nodes]].sum(),
            ]
        )
        fx, fy = st.f[self.drive_dofs_x], st.f[self.drive_dofs_y]
        arm = self.xy[self.drive_nodes] - self._centre()
        if kinematics != "linear":
            # Virtual work of a rigid rotation uses the current lever arms.
            arm = arm + np.column_stack([u[self.drive_dofs_x], u[self.drive_dofs_y]])
        torque = float(np.sum(arm[:, 0] * fy - arm[:, 1] * fx))
        ux = float(u[self.drive_dofs_x].mean())
        uy = float(u[self.drive_dofs_y].mean())
        peak, xy, peak_n, xy_n = self.peak_stress(u, kinematics)
        return {
            "reaction": b_f,
            "clamp": c_f,
            "torque": torque,
            "u_drive": np.array([ux, uy]),
            "peak": peak,
            "peak_xy": xy,
            "peak_n": peak_n,
            "peak_n_xy": xy_n,
        }

    def _force(self, u: np.ndarray) -> np.ndarray:
        """Nonlinear internal force (N,) N at u (N,) mm, without the tangent where possible."""
        if self.assembly == "compiled":
            return self._state_nonlinear(u, tangent=False).f
        return self._state_nonlinear(u).f

    def series_predictor(self, value: float) -> tuple[np.ndarray, np.ndarray]:
        """The nonlinear equilibrium at drive value ``value`` (mm or rad), to second order in it.

        The Saint Venant-Kirchhoff internal force is a cubic polynomial in u,
        f(u) = K0 u + f2(u) + f3(u) (K0 the linear stiffness, f2 quadratic, f3 cubic), since
        P = F S with F = I + grad u and S linear in E = sym grad u + grad uᵀ grad u / 2. Expand
        the equilibrium path and the prescribed motion in the drive value v,
        u(v) = v U1 + v² U2 + v³ U3 + ... and ubar(v) likewise: the free rows at order v give
        Pᵀ K0 U1 = 0 (the linear solution) and at order v² Pᵀ (K0 U2 + f2(U1)) = 0, the classical
        perturbation (asymptotic) expansion. f2 is read off exactly as the even part of the
        force, (f(u) + f(-u)) / 2 = f2(u), and the prescribed motion is split into its odd and
        even parts in v the same way (a rotation's is not linear in the angle).

        Returns
        -------
        u_odd : (N,) mm
            K0's response to the odd part of the prescribed motion, (ubar(v) - ubar(-v)) / 2:
            v U1 + O(v³).
        u_even : (N,) mm
            K0's response to the even part, (ubar(v) + ubar(-v)) / 2, with the force
            -f2(u_odd): v² U2 + O(v⁴).

        So u(±v) = ±u_odd + u_even + O(v³), where the linear solution alone is off by O(v²);
        and once u(v) is solved, u(-v) = 2 u_even - u(v) + O(v⁴) (the odd orders cancel). Both
        are starting points for :meth:`solve`'s ``guess``. Cost: two force evaluations and two
        solves with K0, whose factorisation is kept (no refactorisation right after a linear
        solve).
        """
        value = float(value)
        if not np.isfinite(value):
            raise FeaError(f"series_predictor: drive value {value} must be finite")
        K0 = self._linear_stiffness()
        ub_p = self.prescribed(value, "nonlinear")
        ub_m = self.prescribed(-value, "nonlinear")
        q_odd, q_even = 0.5 * (ub_p - ub_m), 0.5 * (ub_p + ub_m)

        def response(q: np.ndarray, f: np.ndarray | None) -> np.ndarray:
            rhs = K0 @ q if f is None else f + K0 @ q
            return q + self.P @ self._reduced_solve(K0, -(self.PT @ rhs))

        u_odd = response(q_odd, None)
        f2 = 0.5 * (self._force(u_odd) + self._force(-u_odd))
        return u_odd, response(q_even, f2)

    def solve(
        self,
        kinematics: Literal["linear", "nonlinear"] = "nonlinear",
        guess: np.ndarray | None = None,
        keep_states: bool = False,
    ) -> PlaneStressResponse:
        """Step the drive from 0 to its maximum; see :class:`PlaneStressResponse`.

        guess : (N,) mm, optional
            A displacement near the equilibrium of the first row (drive value max / steps),
            e.g. from :meth:`series_predictor`: that row's Newton starts from its unknowns
            (the clamped and driven DOFs at their prescribed values) instead of from the
            linearised step. Newton stops at the same tolerance either way, so the answers
            agree to it, in fewer iterations from a good guess. When Newton fails from the
            guess, the row is solved from the linearised step as without one (the cut-backs
            are not spent on it); ``extra["guess"]`` says "used", "failed: <why>" or "none".
        keep_states : bool
            Keep a copy of the solution vector at every converged row (``row_dofs``, (N,) mm
            each): the per-load-step fields of a detailed design. Off for the optimiser's
            designs, which need only the rows' figures (steps + 1 vectors of N floats each).
        """
        t0 = time.perf_counter()
        if kinematics not in KINEMATICS:
            raise FeaError(
                f"kinematics '{kinematics}' unknown; choose one of {', '.join(KINEMATICS)}"
            )
        guess_note = "none"
        if guess is not None:
            guess = np.asarray(guess, dtype=float)
            if guess.shape != (self.n_dofs,) or not np.all(np.isfinite(guess)):
                raise FeaError(
                    f"guess must be a finite ({self.n_dofs},) displacement vector, mm; "
                    f"got shape {guess.shape}"
                )
        cfg = self.settings
        drive = self.drive
        is_rot = isinstance(drive, Rotate)
        vmax = float(drive.max_rad if is_rot else drive.max_mm)
        n_rows = drive.steps + 1
        targets = np.linspace(0.0, vmax, n_rows)

        rows = {
            "reaction": np.full((n_rows, 2), np.nan),
            "clamp": np.full((n_rows, 2), np.nan),
            "torque": np.full(n_rows, np.nan),
            "u_drive": np.full((n_rows, 2), np.nan),
            "peak": np.full(n_rows, np.nan),
            "peak_xy": np.full((n_rows, 2), np.nan),
            "peak_n": np.full(n_rows, np.nan),
            "peak_n_xy": np.full((n_rows, 2), np.nan),
        }
        iterations = np.zeros(n_rows, dtype=int)
        converged = np.zeros(n_rows, dtype=bool)

        u = np.zeros(self.n_dofs)
        if guess is not None and kinematics == "nonlinear":
            # The first row starts from the guess, not from a step linearised at rest: the rest
            # state's force is read (zero) but its tangent only if the guess fails, and then
            # _increment assembles it (the same matrix). ~one tangent assembly less a warm solve
            # (the compiled assembly; session 32, the peak re-solves' note of session 31).
            st = self._state_nonlinear(u, tangent=False)
        else:
            st = self.state(u, kinematics)
        # At u = 0 every kinematics has F = I, zero stress and zero force exactly, so the first
        # row depends only on the nodes and the reference point: measured once per model (it
        # took ~4 ms of every solve; a spring solves three times on one model).
        rest = self._rest_rows.get(self._centre().tobytes())
        if rest is None:
            rest = self._rest_rows[self._centre().tobytes()] = self._measure(u, st, kinematics)
        for key, val in rest.items():
            rows[key][0] = val
        converged[0] = True
        kept: list[np.ndarray | None] | None = None
        if keep_states:
            kept = [u.copy()] + [None] * (n_rows - 1)
        message = ""
        frac, inc = 0.0, 1.0 / drive.steps  # progress and increment as fractions of vmax
        min_inc = inc * cfg.cutback_factor**cfg.max_cutbacks
        ubar_now = self.prescribed(0.0, kinematics)
        for k in range(1, n_rows):
            goal = k / drive.steps
            # Sums of halved fractions carry rounding; 1e-12 of the stroke is "arrived".
            while frac < goal - 1e-12:
                step = min(inc, goal - frac)
                ubar_new = self.prescribed((frac + step) * vmax, kinematics)
                ubar_step = ubar_new - ubar_now
                out = None
                if guess is not None:  # the first row's first try: from the guess
                    out = self._increment(u, st, ubar_step, kinematics, guess=guess)
                    guess = None
                    guess_note = "used" if out.ok else f"failed: {out.reason}"
                    if not out.ok:
                        iterations[k] += out.iterations
                        out = None
                if out is None:
                    out = self._increment(u, st, ubar_step, kinematics)
                iterations[k] += out.iterations
                if out.ok:
                    u, st, ubar_now = out.u, out.state, ubar_new
                    frac += step
                    if out.iterations <= cfg.easy_iterations:
                        inc = min(inc * cfg.growth_factor, 1.0 / drive.steps)
                    continue
                inc = step * cfg.cutback_factor
                if inc < min_inc:
                    message = (
                        f"step {k} of {drive.steps} failed at drive value "
                        f"{(frac + step) * vmax:.6g} after {cfg.max_cutbacks} cut-backs: "
                        f"{out.reason}"
                    )
                    break
            if message:
                break
            for key, val in self._measure(u, st, kinematics).items():
                rows[key][k] = val
            converged[k] = True
            if kept is not None:
                kept[k] = u.copy()

        d = self._direction()
        n = np.array([-d[1], d[0]])
        reaction = rows["reaction"]
        u_drive = rows["u_drive"]
        if is_rot:
            disp = np.zeros(n_rows)
            trans = np.zeros(n_rows)
            rot = np.where(converged, targets, np.nan)
        else:
            disp = u_drive @ d
            trans = u_drive @ n
            rot = np.zeros(n_rows)
        ok = bool(converged.all())
        field_xy = np.column_stack([u[self.basis.nodal_dofs[0]], u[self.basis.nodal_dofs[1]]])
        return PlaneStressResponse(
            drive="rotate" if is_rot else "translate",
            kinematics=kinematics,
            drive_value=targets,
            displacement_mm=disp,
            transverse_displacement_mm=trans,
            force_N=reaction @ d,
            transverse_force_N=reaction @ n,
            reaction_N=reaction,
            torque_Nmm=rows["torque"],
            rotation_rad=rot,
            clamp_reaction_N=rows["clamp"],
            peak_stress_MPa=rows["peak"],
            peak_stress_xy_mm=rows["peak_xy"],
            peak_nodal_stress_MPa=rows["peak_n"],
            peak_nodal_stress_xy_mm=rows["peak_n_xy"],
            iterations=iterations,
            converged=converged,
            ok=ok,
            message=message,
            points_mm=self.mesh.points,
            displacement_field_mm=field_xy,
            dofs=u,
            n_dofs=self.n_dofs,
            solve_time_s=time.perf_counter() - t0,
            extra={
                "solver": self.solver,
                "assembly": self.assembly,
                # Tangents Cholesky refused (solved by LU): at a converged row, an equilibrium
                # that is unstable under the drive (past a bifurcation or limit point).
                "cholesky_failures": self.counters["cholesky_failures"],
                "guess": guess_note,
            },
            row_dofs=None if kept is None else tuple(kept),
        )


KINEMATICS: dict[str, Callable[[PlaneStressModel, np.ndarray], _State]] = {
    "linear": PlaneStressModel._state_linear,
    "nonlinear": PlaneStressModel._state_nonlinear,
}
"""Internal force and tangent by kinematics name (the YAML string)."""


@dataclass(frozen=True)
class MeshNumbering:
    """What :func:`interpolate_displacement` reads of a model: its mesh, element and DOF
    numbering, without its quadrature tables, matrices and factor (hundreds of MB on a
    100k-DOF P2 mesh), so a caller can free the model and keep this.

    skmesh : skfem MeshTri — vertices (2, n) mm, triangles (3, m)
    element : skfem ElementVector of the model's scalar element
    element_dofs : (n_local, m) int — the DOFs of each triangle, in the element's local order
    n_dofs : int
    """

    skmesh: Any
    element: Any
    element_dofs: np.ndarray
    n_dofs: int

    @classmethod
    def of(cls, model: PlaneStressModel) -> MeshNumbering:
        return cls(model.skmesh, model.basis.elem, model.basis.element_dofs, model.n_dofs)


def interpolate_displacement(
    source: PlaneStressModel | MeshNumbering,
    u: np.ndarray,
    target: PlaneStressModel,
    candidates: int = 8,
) -> np.ndarray:
    """A displacement of ``source``'s mesh, ``u``, interpolated onto ``target``'s nodes.

    Each node of ``target`` (vertices and, for P2, edge midpoints) takes the value of
    ``source``'s finite-element field at its location: the source triangle that holds it is
    found among the ``candidates`` nearest by centroid (the one whose smallest barycentric
    coordinate is largest, so a node on the common boundary, outside every triangle by
    round-off, takes the nearest one's, extended by that round-off), and its shape functions
    are evaluated there. Exact for a field of the source element's degree (a test checks a
    quadratic on P2). Meant as Newton's starting point on a refined mesh of the same outline
    (:meth:`PlaneStressModel.solve`'s ``guess``): a node outside the source mesh by more than
    round-off still gets the nearest triangle's extension, and Newton corrects it.

    Parameters
    ----------
    source : PlaneStressModel, or its :class:`MeshNumbering`
    u : (source.n_dofs,) mm
    target : PlaneStressModel — the same element (P1 or P2), another mesh.
    candidates : int — nearest source triangles tried per node.

    Returns
    -------
    (target.n_dofs,) mm
    """
    from scipy.spatial import cKDTree
    from skfem import MappingAffine

    if isinstance(source, PlaneStressModel):
        source = MeshNumbering.of(source)
    u = np.asarray(u, dtype=float)
    if u.shape != (source.n_dofs,):
        raise FeaError(f"u must be a ({source.n_dofs},) displacement vector, mm; got {u.shape}")
    p, t = source.skmesh.p, source.skmesh.t  # (2, n_vertices) mm, (3, n_triangles)
    x = target.xy.T  # (2, n) mm: the target's nodes
    k = min(int(candidates), t.shape[1])
    _, cand = cKDTree(p[:, t].mean(axis=1).T).query(x.T, k=k)
    cand = cand.reshape(x.shape[1], k)  # (n, k)
    a, b, c = (p[:, t[i, cand]] for i in range(3))  # (2, n, k) each: the candidates' corners
    xx = x[:, :, None]

    def cross(e: np.ndarray, f: np.ndarray) -> np.ndarray:
        return e[0] * f[1] - e[1] * f[0]

    area = cross(b - a, c - a)  # (n, k), twice the signed area
    bary = np.stack([cross(b - xx, c - xx), cross(c - xx, a - xx), cross(a - xx, b - xx)]) / area
    best = np.argmax(bary.min(axis=0), axis=1)  # (n,)
    cells = cand[np.arange(x.shape[1]), best]
    mapping = MappingAffine(source.skmesh)  # straight-sided triangles (the models' own)
    ref = mapping.invF(x[:, :, None], tind=cells)  # (2, n, 1) reference coordinates
    field = np.zeros(x.shape)
    for i in range(source.element_dofs.shape[0]):  # the shape functions: (2, n, 1) values
        phi = np.asarray(source.element.gbasis(mapping, ref, i, tind=cells)[0])
        field += phi[:, :, 0] * u[source.element_dofs[i, cells]]
    out = np.zeros(target.n_dofs)
    out[target.ix], out[target.iy] = field[0], field[1]
    return out


def solve_plane_stress(
    mesh: TriMesh,
    material: Material,
    thickness_mm: float,
    clamp: Clamp,
    drive: Drive,
    kinematics: Literal["linear", "nonlinear"] = "nonlinear",
    settings: PlaneStressSettings = PlaneStressSettings(),
    stress_ignore: BaseGeometry | None = None,
) -> PlaneStressResponse:
    """Build a :class:`PlaneStressModel` and step its drive; ``solve_time_s`` includes the build.

    Parameters
    ----------
    mesh : TriMesh
        Nodes (n, 2) mm, triangles (m, 3).
    material : Material
    thickness_mm : float, mm
        Out-of-plane thickness.
    clamp : Clamp
    drive : Translate or Rotate
    kinematics : "linear" or "nonlinear"
    settings : PlaneStressSettings
    stress_ignore : shapely geometry, optional
        Elements touching it are left out of the peak-stress search.

    Returns
    -------
    PlaneStressResponse
    """
    t0 = time.perf_counter()
    model = PlaneStressModel(mesh, material, thickness_mm, clamp, drive, settings, stress_ignore)
    build = time.perf_counter() - t0
    res = model.solve(kinematics)
    return replace(res, solve_time_s=res.solve_time_s + build)


def warm_up() -> str:
    """Load the compiled plane-stress kernels from numba's cache (or compile them), now.

    A process pool calls this before it forks its workers (through a problem's ``warm_up``,
    :func:`pipeline.backends.open_backend`): forked workers inherit the loaded code and the
    imported solver instead of each loading them on its first design (~1 s CPU a worker, ~30 s
    once per install to compile). One tiny linear and nonlinear solve of two P2 triangles
    touches every kernel a solve uses (pattern, assembly with and without the tangent, von
    Mises) and the sparse Cholesky. Answers of later solves do not depend on it.

    Returns
    -------
    str
        The assembly that runs: "compiled", or "vectorised" when numba is unavailable.
    """
    from flexopt.fea.materials import Material

    mesh = TriMesh(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]),
                   np.array([[0, 1, 2], [0, 2, 3]]))  # fmt: skip
    model = PlaneStressModel(
        mesh,
        Material("warm-up", E_MPa=1000.0, nu=0.3, yield_MPa=10.0),
        1.0,
        Clamp(shapely.LineString([(0.0, 0.0), (0.0, 1.0)])),
        Rotate(shapely.LineString([(2.0, 0.0), (2.0, 1.0)]), (2.0, 0.5), 1e-3, 1),
    )
    model.solve("linear")
    model.solve("nonlinear")
    model.von_mises(np.zeros(model.n_dofs), "nonlinear", model.corner_basis)
    if model.assembly == "compiled":
        model._asm.compiled_state(np.zeros(model.n_dofs), model.lam, model.mu, 1.0, False)
    return model.assembly
