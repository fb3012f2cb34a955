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

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
import scipy.sparse as sp
import shapely
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

from fea.errors import FeaError
from fea.materials import Material
from fea.mesh import TriMesh, to_skfem

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
# Model
# --------------------------------------------------------------------------------------------

ELEMENTS: dict[str, Callable[[], object]] = {"P1": ElementTriP1, "P2": ElementTriP2}
"""Scalar element per settings.element; the displacement is its 2-vector."""


@dataclass
class _State:
    """Internal force and tangent at a displacement, per the kinematics."""

    f: np.ndarray
    K: sp.csr_matrix
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
        self.basis = Basis(self.skmesh, ElementVector(scalar), intorder=intorder)
        # Stress at the element corners, for vertex-averaged (nodal) values: a basis whose
        # "quadrature points" are the reference triangle's vertices, in the mesh's node order.
        corners = (np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), np.full(3, 1.0 / 6.0))
        self.corner_basis = Basis(self.skmesh, ElementVector(scalar), quadrature=corners)
        self.n_dofs = int(self.basis.N)
        self.ix, self.iy = self.basis.split_indices()
        self.xy = self.basis.doflocs[:, self.ix].T  # (n_nodes, 2): location of each FE node
        self.qp_xy = np.asarray(self.basis.global_coordinates())  # (2, nel, nqp)
        self._stress_mask = self._stress_elements(stress_ignore)
        self._K_lin: sp.csr_matrix | None = None  # linear stiffness, assembled on first use
        self._lu_lin = None  # and its factorisation
        self._build_constraints()

    # ---- setup ------------------------------------------------------------------------------

    def _select(self, region: BaseGeometry, what: str) -> np.ndarray:
        d = shapely.distance(region, shapely.points(self.xy))
        nodes = np.flatnonzero(d <= self.settings.select_tol_mm)
        if nodes.size == 0:
            raise FeaError(
                f"the {what} region selects no mesh node (nearest node is {d.min():.3g} mm away, "
                f"tolerance {self.settings.select_tol_mm:g} mm); put the {what} geometry on the "
                "outline boundary or make it a polygon overlapping the part"
            )
        return nodes

    def _stress_elements(self, ignore: BaseGeometry | None) -> np.ndarray:
        mask = np.ones(self.mesh.n_triangles, dtype=bool)
        if ignore is not None:
            tris = shapely.polygons(self.mesh.points[self.mesh.triangles])
            mask &= ~shapely.intersects(ignore, tris)
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
        free = np.setdiff1d(np.arange(self.n_dofs), fixed)
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

    def _state_linear(self, u: np.ndarray) -> _State:
        if self._K_lin is None:
            self._K_lin = (
                asm(linear_stiffness, self.basis, lam=self.lam, mu=self.mu) * self.thickness_mm
            ).tocsr()
        return _State(self._K_lin @ u, self._K_lin, 1.0)

    def _deformation(self, u: np.ndarray, basis: Basis) -> tuple[np.ndarray, np.ndarray]:
        """F and S at the quadrature points of ``basis``, each (2, 2, nel, nqp)."""
        F = basis.interpolate(u).grad + _eye_like(np.empty((2, 2, 1, 1)))
        E = 0.5 * (_matmul(transpose(F), F) - _eye_like(F))
        return F, _svk_stress(E, self.lam, self.mu)

    def _state_nonlinear(self, u: np.ndarray) -> _State:
        F, S = self._deformation(u, self.basis)
        det = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
        b = self.thickness_mm
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

    def _reduced_solve(self, K: sp.csr_matrix, rhs: np.ndarray) -> np.ndarray:
        if self._lu_lin is not None and K is self._K_lin:
            return self._lu_lin.solve(rhs)  # the linear stiffness is factorised once
        Kr = (self.PT @ K @ self.P).tocsc()
        # A minimum-degree ordering of A^T + A suits these symmetric tangents: 30 % less fill and
        # ~15 % less time than SuperLU's default COLAMD on a 25k-DOF strip.
        lu = splu(Kr, permc_spec="MMD_AT_PLUS_A")
        if K is self._K_lin:
            self._lu_lin = lu
        return lu.solve(rhs)

    def _increment(
        self, u0: np.ndarray, s0: _State, ubar_step: np.ndarray, kinematics: str
    ) -> _Increment:
        """Newton from equilibrium u0 to the next prescribed value; ubar_step = ubar_new - ubar_old.

        The first iteration linearises at u0 with the boundary increment on the right-hand side,
        so the driven nodes move without first distorting the elements next to them.
        """
        cfg = self.settings
        try:
            dq = self._reduced_solve(s0.K, -(self.PT @ (s0.f + s0.K @ ubar_step)))
        except RuntimeError as exc:  # SuperLU: "Factor is exactly singular"
            return _Increment.failed(1, f"singular stiffness ({exc}): a mechanism or a limit point")
        u = u0 + ubar_step + self.P @ dq
        history: list[float] = []
        n_rise = cfg.diverging_iterations
        for it in range(1, cfg.max_newton_iter + 1):
            st = self.state(u, kinematics)
            if not np.all(np.isfinite(st.f)):
                return _Increment.failed(it, "non-finite internal force")
            if st.min_det_F < cfg.min_det_F:
                return _Increment.failed(it, f"element inverted (det F = {st.min_det_F:.3g})")
            r = self.PT @ st.f
            res = float(np.linalg.norm(r))
            scale = float(np.linalg.norm(st.f))
            if res <= cfg.rtol_residual * scale + cfg.atol_residual_N:
                return _Increment(True, u, st, it)
            history.append(res)
            if len(history) > n_rise and all(np.diff(history[-n_rise - 1 :]) > 0):
                return _Increment.failed(it, f"Newton diverging (residual {res:.3g} N, growing)")
            try:
                u = u + self.P @ self._reduced_solve(st.K, -r)
            except RuntimeError as exc:
                return _Increment.failed(it, f"singular tangent ({exc})")
        return _Increment.failed(
            cfg.max_newton_iter,
            f"no convergence in {cfg.max_newton_iter} Newton iterations "
            f"(residual {res:.3g} N vs force scale {scale:.3g} N)",
        )

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

    def solve(
        self, kinematics: Literal["linear", "nonlinear"] = "nonlinear"
    ) -> PlaneStressResponse:
        """Step the drive from 0 to its maximum; see :class:`PlaneStressResponse`."""
        t0 = time.perf_counter()
        if kinematics not in KINEMATICS:
            raise FeaError(
                f"kinematics '{kinematics}' unknown; choose one of {', '.join(KINEMATICS)}"
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
        st = self.state(u, kinematics)
        for key, val in self._measure(u, st, kinematics).items():
            rows[key][0] = val
        converged[0] = True
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
        )


KINEMATICS: dict[str, Callable[[PlaneStressModel, np.ndarray], _State]] = {
    "linear": PlaneStressModel._state_linear,
    "nonlinear": PlaneStressModel._state_nonlinear,
}
"""Internal force and tangent by kinematics name (the YAML string)."""


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
