"""A 3D linear-elastic check of a flat part: its planar outline extruded to its thickness.

Plane stress (:mod:`fea.plane_stress`) assumes the out-of-plane stresses vanish through the whole
thickness. That holds for thin plates; a deep part (thickness several times the width of its
members) is stiffer, because the Poisson contraction across the depth is restrained wherever the
cross-section is held: at rigid clamps and hubs, and where the bending moment varies along a
member. With ``nu = 0`` there is nothing to restrain and 3D and plane stress agree exactly. This
module measures the difference on the part as meshed for plane stress.

Mesh
    The plane-stress triangle mesh (:class:`fea.mesh.TriMesh`) is extruded into layers of
    prisms, and each prism is split into three tetrahedra by the rule "each quad face is cut by
    the diagonal from the bottom of its lower-numbered vertex to the top of the higher-numbered
    one": the rule depends only on the two vertices of the face, so neighbouring prisms cut their
    shared face the same way and the mesh is conforming. Quadratic tetrahedra (P2) on it. No
    mesher beyond Triangle is needed, the layers are graded towards the free faces (where the
    stress departs from the interior state) and every node lies above a node of the plane mesh,
    so supports and stress-ignore regions are the plane model's, through the thickness.
Symmetry
    Loads and supports are in-plane and the same at every height, so the solution is symmetric
    about the mid-plane: half the thickness is meshed, with ``w = 0`` on the mid-plane, and the
    forces are doubled.
Supports (the plane model's, through the thickness)
    :class:`~fea.plane_stress.Clamp`: every node whose (x, y) lies on or in the region is held
    (u = v = w = 0). :class:`~fea.plane_stress.Rotate`: the driven nodes turn rigidly about the
    z axis through ``centre_mm`` (linearised, ``u = theta e_z x (X - c)``, ``w = 0``).
    :class:`~fea.plane_stress.Translate`: the driven nodes move rigidly along ``direction``
    (``w = 0``); ``transverse = "free"`` lets them slide together perpendicular to it.
Physics
    Small-strain linear elasticity, ``sigma = lambda tr(eps) I + 2 mu eps`` with the 3D Lamé
    constants. The linear 3D/2D ratio of a design carries to the geometrically nonlinear 2D
    answer: the ratio is a property of the cross-sections (measured 1.022 at 1 and 11 degrees
    on the SEA spring, issue 15), so this check is linear. Solved by a sparse Cholesky
    factorisation (CHOLMOD through cvxopt; QDLDL, else SuperLU, when cvxopt does not import)
    or by conjugate gradients with a two-grid preconditioner (P2 smoothed, its P1 subspace
    factorised): half CHOLMOD's memory at ~3x its time, and less memory and time than QDLDL.
    ``solver = "auto"`` takes multigrid from ``Solid3DSettings.multigrid_from_dofs`` DOFs on
    when CHOLMOD does not import (a plain install), CHOLMOD wherever it does.
Rotational sector (``Solid3DModel(periodic=)``, fea/solid3d_sector.py)
    A part whose outline, supports and load (a hub turned about the axis) repeat every
    2 pi / n: one sector of a periodic mesh, cut B's DOFs tied to cut A's turned
    (``u_B = R u_A``), gives the whole part's answer on that mesh (stiffness n times the
    sector's torque, the sector's peak); the SEA spring's check in half the memory.
Several thicknesses (:class:`Solid3DModel`)
    The layers scale with the thickness, so one assembly serves every thickness (the
    stiffness is a sum of three parts weighted by t, 1 and 1/t); a thickness after the first
    is solved by conjugate gradients preconditioned with the first one's factor.
Assembly
    ``Solid3DSettings.assembly = "compiled"``: the P2 tables, the node-block pattern with the
    stiffness parts, K(t)'s blocks, the reduced lower triangle (in compressed columns, from which
    CHOLMOD's matrix is made without cvxopt's triplet constructor) and the stress in numba
    kernels (fea/_solid3d_kernels.py); "numpy" is the reference (scikit-fem's Basis, one sort of
    every element's node pairs), and what runs without numba. Both give the same matrix to
    round-off (tests/fea/test_solid3d_kernels.py).

Units: mm, N, MPa, N·mm, rad. See docs/solid3d.md.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import TYPE_CHECKING, Literal

import numpy as np
import scipy.sparse as sp
import shapely
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import Refinement, TriMesh, mesh_polygon
from flexopt.fea.plane_stress import Clamp, Rotate, Translate
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

if TYPE_CHECKING:
    from flexopt.fea.solid3d_sector import PeriodicMesh

__all__ = [
    "Solid3DSettings",
    "Solid3DResult",
    "extrude_layers_mm",
    "extrude_mesh",
    "solve_solid3d",
    "Solid3DModel",
    "check_solid3d",
    "cholmod_available",
    "compare_with_plane_stress",
    "converge_peak_stress",
    "band_reachable",
    "correction_needed",
    "corrected_thickness_mm",
    "correct_thickness_3d",
]

Drive = Translate | Rotate


@dataclass(frozen=True)
class Solid3DSettings:
    """Discretisation and solver choices of the 3D check, each with its reason."""

    # Prism layers through the meshed height (half the thickness with symmetry). The stress
    # departs from its interior state in a layer about one member width deep under each free
    # face; 4 layers graded towards the face resolve it with P2 (docs/solid3d.md: the SEA
    # spring's stiffness moves < 0.1 % from 4 to 8 layers).
    layers: int = 4
    # Ratio of the thickest layer (at the mid-plane) to the thinnest (at the free face); the
    # layer heights form a geometric series. 1 = uniform.
    grading: float = 3.0
    # Mesh half the thickness with a symmetry plane w = 0 at mid-thickness (loads and supports
    # are in-plane and the same at every height, so the solution is mirror-symmetric).
    symmetric: bool = True
    # Distance under which a node counts as on a clamp / drive geometry, mm (the plane model's).
    select_tol_mm: float = 1e-6
    # "multigrid": conjugate gradients preconditioned by a two-grid cycle (symmetric
    # Gauss-Seidel on the P2 unknowns, the P1 subspace of the same mesh solved directly;
    # Solid3DModel._solve_multigrid), no factor of the whole: the SEA spring's check at
    # 1.04 GB peak against CHOLMOD's 2.03 GB and QDLDL's 4.65 GB, its answers those of the
    # direct solve to ~1e-10, at ~3.5x CHOLMOD's CPU time (about QDLDL's) (docs/solid3d.md,
    # "Memory"). It needs the compiled assembly and unknowns that are a selection of DOFs
    # (not a Translate with transverse = "free"); elsewhere the direct solvers run. "cholmod":
    # CHOLMOD's supernodal Cholesky (through cvxopt, the `cholmod` extra); "qdldl": QDLDL's
    # LDLᵀ; "superlu": SciPy's LU (see SparseSolver for the measured difference). "auto":
    # CHOLMOD whenever it imports (cholmod_available(): the fast route, 2.0 GB on the SEA
    # spring's check); without it multigrid from multigrid_from_dofs DOFs on (there both less
    # memory and less time than QDLDL: 1.04 GB and 28.5 s CPU against 4.65 GB and 35.8 s),
    # below that QDLDL, else SuperLU. A sector model (Solid3DModel(periodic=); the SEA
    # spring's check) takes the same choice: multigrid on P^T K P with the tied P1 functions
    # as its coarse space (a plain install: half the whole model's CPU, docs/solid3d.md).
    solver: Literal["auto", "cholmod", "qdldl", "superlu", "multigrid"] = "auto"
    # Where "auto" without CHOLMOD turns to multigrid: a direct factor of a P2 model this
    # large is ~0.5 GB and grows faster than the model (the SEA spring's 408k DOFs: CHOLMOD's
    # 1.04 GB, QDLDL's check peaks at 4.65 GB), while the multigrid solver's memory is
    # ~2.5 kB per DOF; below it the factor is small and a direct solve the quicker. 150k since
    # session 27: the SEA serpentine's quarter sector (165k DOFs) peaks at 1.76 GB with QDLDL,
    # 0.75 GB by multigrid (issue 27's 1.5 GB for the check; docs/solid3d.md).
    multigrid_from_dofs: int = 150_000
    # Elements per assembly block: bounds the memory of the (block, 30, 30) element matrices
    # (20 000 blocks use ~150 MB each) independently of the mesh size. Solid3DModel's
    # assembly uses blocks of 2 000 at most (its batched products run ~10x faster in cache).
    block_elements: int = 20_000
    # A model this large is a units or settings mistake on a 24 GB machine (a 1.2 M-DOF P2
    # tetrahedral model factorises in ~6 GB).
    max_dofs: int = 1_500_000
    # Solid3DModel.solve at a thickness after the first: "pcg" solves by conjugate gradients
    # preconditioned with the Cholesky factor of the first thickness (a model a few percent
    # deeper or shallower: ~5 iterations, each a pair of triangular solves, against a new
    # factorisation; the SEA spring's corrections, docs/solid3d.md); "direct" factorises each
    # thickness anew (the reference).
    later_solves: Literal["pcg", "direct"] = "pcg"
    # PCG stops when |K q - b| <= pcg_rtol |b| (true residual, reduced system). The direct
    # Cholesky solve of a 400k-DOF P2 model leaves ~1e-15-1e-14; at 1e-12 the stiffness and
    # peak stress agree with it to ~1e-10.
    pcg_rtol: float = 1e-12
    # More iterations than this means the factorised thickness is too far off: factorise anew.
    pcg_max_iterations: int = 40
    # solver = "multigrid": CG stops at |K q - b| <= multigrid_rtol |b| (true residual). At
    # 1e-10 the SEA spring's stiffness and peak stresses agree with CHOLMOD's to <= 3e-9
    # (tests/fea/test_solid3d_multigrid.py checks 1e-8 on a small model; the 3D check's
    # requirement is 1e-4); each decade costs ~8 of the ~60 iterations (76 at 1e-12).
    multigrid_rtol: float = 1e-10
    # More iterations than this is an error (a model the two-grid cycle does not suit: a
    # direct solver is named), not a silent answer: the SEA spring needs ~60 (~30 from the
    # previous thickness's answer).
    multigrid_max_iterations: int = 400
    # solver = "multigrid": a later thickness within this fraction of the thickness whose P1
    # coarse grid was factorised keeps that factor as its cycle's coarse solve (the coarse
    # product and factorisation, ~1.5 s CPU a check on the SEA spring, not made again; the
    # cycle stays symmetric positive definite and CG still stops at multigrid_rtol, so only
    # the iterations can change: the SEA spring's re-check 2 % thinner takes 32 with either,
    # docs/solid3d.md). 0: factorised at every thickness.
    multigrid_coarse_reuse: float = 0.05
    # "compiled": the P2 tables from the vertex coordinates, the node-block pattern and the
    # stiffness parts row by row, and the reduced lower triangle in compressed-column order,
    # in numba kernels (fea/_solid3d_kernels.py): the SEA spring's 405k-DOF build and first
    # solve spend ~2 s beside CHOLMOD's factorisation instead of ~8 s (docs/solid3d.md,
    # "Build and first solve"). "numpy":
    # scikit-fem's Basis and a global sort of the node pairs, the reference (the tests check
    # that both agree to round-off); also what runs when numba does not import.
    assembly: Literal["compiled", "numpy"] = "compiled"
    # With the compiled assembly: drop the stiffness parts and the reduced lower triangle's
    # pattern (the model's two largest arrays, ~0.4 GB on the SEA spring's 408k DOFs) while
    # CHOLMOD factorises, and make them again from the mesh afterwards (~1 s; the same
    # arrays bit for bit): the factorisation is the check's peak of memory (docs/solid3d.md,
    # "Memory"). False keeps them (the reference for the tests and the benchmark).
    lean_factorisation: bool = True
    # solver = "multigrid" on a sector (a tie: P^T K P formed, fea/solid3d_sector.py): keep
    # the stiffness parts and the block pattern through the CG solve instead of dropping
    # them (lean_factorisation) and making them again after: ~0.4 s CPU a check (the kernel
    # and the P2 gradients), the answers the same bit for bit. They are 0.19 GB on the SEA
    # spring's sector, whose check by multigrid peaks when P^T K P is formed (the parts held
    # there anyway), not in the CG (docs/solid3d.md, "Memory"); a whole model by multigrid
    # (the threshold spring's 544k DOFs) still drops them. False: dropped as there.
    multigrid_sector_keeps_parts: bool = True


@dataclass(frozen=True)
class Solid3DResult:
    """The 3D linear answer at the drive's full value (``max_rad`` or ``max_mm``).

    Forces and torques are for the whole part (doubled from the half model under symmetry).

    drive : "rotate" or "translate".
    drive_value : float — rad (rotate) or mm (translate).
    reaction_N : (3,) float, N — force applied to the driven nodes.
    torque_Nmm : float, N·mm — moment about the z axis through the centre applied to them.
    force_N : float, N — reaction along the drive direction (translate; for rotate, on x).
    stiffness : float — N·mm/rad (rotate: torque / angle) or N/mm (translate: force / stroke).
    clamp_reaction_N : (3,) float, N — force applied to the clamped nodes.
    peak_stress_MPa : float, MPa — max von Mises at quadrature points (element level).
    peak_stress_xyz_mm : (3,) float, mm — where.
    peak_nodal_stress_MPa : float, MPa — max of the von Mises averaged at mesh vertices over the
        tetrahedra sharing them (the value plane stress reports as its peak).
    peak_nodal_stress_xyz_mm : (3,) float, mm — where.
    n_dofs : int — unknowns including the prescribed ones (3 per P2 node of the meshed part).
    n_tets : int; n_layers : int; symmetric : bool; solver : str.
    times_s : dict — "mesh", "assemble", "factorise_solve", "stress", "total", s.
    """

    drive: str
    drive_value: float
    reaction_N: np.ndarray
    torque_Nmm: float
    force_N: float
    stiffness: float
    clamp_reaction_N: np.ndarray
    peak_stress_MPa: float
    peak_stress_xyz_mm: np.ndarray
    peak_nodal_stress_MPa: float
    peak_nodal_stress_xyz_mm: np.ndarray
    n_dofs: int
    n_tets: int
    n_layers: int
    symmetric: bool
    solver: str
    times_s: dict = field(default_factory=dict)
    # conjugate-gradient iterations (Solid3DModel's later thicknesses); 0 for a direct solve
    iterations: int = 0
    # the model was one sector of this many (a rotationally periodic part: n_dofs, n_tets are
    # the sector's; forces, torque and stiffness the whole part's)
    sectors: int = 1

    @property
    def solve_time_s(self) -> float:
        """Wall time of the whole check, s."""
        return float(self.times_s.get("total", float("nan")))

    def summary(self) -> dict:
        """Plain-number record (JSON-ready)."""
        return {
            "drive": self.drive,
            "drive_value": self.drive_value,
            "stiffness": self.stiffness,
            "stiffness_unit": "N mm/rad" if self.drive == "rotate" else "N/mm",
            "torque_Nmm": self.torque_Nmm,
            "force_N": self.force_N,
            "peak_stress_MPa": self.peak_stress_MPa,
            "peak_stress_xyz_mm": [float(v) for v in self.peak_stress_xyz_mm],
            "peak_nodal_stress_MPa": self.peak_nodal_stress_MPa,
            "peak_nodal_stress_xyz_mm": [float(v) for v in self.peak_nodal_stress_xyz_mm],
            "n_dofs": self.n_dofs,
            "n_tets": self.n_tets,
            "n_layers": self.n_layers,
            "symmetric": self.symmetric,
            "solver": self.solver,
            "iterations": self.iterations,
            "times_s": dict(self.times_s),
            # a sector model only (the whole part's records stay as they were)
            **({"sectors": self.sectors} if self.sectors > 1 else {}),
        }


# --------------------------------------------------------------------------------------------
# Mesh


def extrude_layers_mm(thickness_mm: float, settings: Solid3DSettings = Solid3DSettings()):
    """Heights of the layer interfaces, (layers + 1,) mm, ascending.

    With symmetry they run from the mid-plane z = 0 to the free face z = thickness / 2, else
    from -thickness / 2 to +thickness / 2 (mirrored, ``layers`` per half, so both meshes resolve
    the free faces alike). Layer heights shrink geometrically towards the free face by
    ``grading`` overall.
    """
    n = int(settings.layers)
    if n < 1:
        raise FeaError(f"layers = {settings.layers} must be >= 1")
    if not settings.grading >= 1.0:
        raise FeaError(f"grading = {settings.grading} must be >= 1 (1 = uniform layers)")
    half = 0.5 * float(thickness_mm)
    # Layer k (from the mid-plane) has height proportional to q**-k with q**(n-1) = grading.
    q = settings.grading ** (1.0 / (n - 1)) if n > 1 else 1.0
    h = q ** -np.arange(n, dtype=float)
    z = np.concatenate([[0.0], np.cumsum(h)]) / h.sum() * half
    z[-1] = half
    if settings.symmetric:
        return z
    return np.concatenate([-z[:0:-1], z])


def extrude_mesh(mesh: TriMesh, z_mm: np.ndarray):
    """A conforming tetrahedral mesh of the triangle mesh extruded through the heights z_mm.

    Parameters
    ----------
    mesh : TriMesh
        Nodes (n, 2) mm, triangles (m, 3).
    z_mm : (L + 1,) float, mm
        Heights of the layer interfaces, strictly ascending.

    Returns
    -------
    skfem.MeshTet
        (L + 1) n nodes, node ``k n + i`` above plane node i at height ``z_mm[k]``;
        3 L m positively oriented tetrahedra, element ``3 (k m + j) + s`` in layer k above
        triangle j.
    """
    from skfem import MeshTet

    z = np.asarray(z_mm, dtype=float)
    if z.ndim != 1 or z.size < 2 or np.any(np.diff(z) <= 0):
        raise FeaError("z_mm must hold at least two strictly ascending heights")
    n, L = mesh.n_points, z.size - 1
    pts = np.column_stack([np.tile(mesh.points, (L + 1, 1)), np.repeat(z, n)])  # ((L+1) n, 3)
    # Sort each triangle's vertices by global index: the cut of a quad face then depends only
    # on its two vertices (diagonal bottom-of-lower to top-of-higher), the same from both sides.
    tri = np.sort(mesh.triangles, axis=1)
    a, b, c = tri.T
    tets = []
    for k in range(L):
        lo, hi = k * n, (k + 1) * n
        # Faces (a,b), (b,c), (a,c) get the diagonals a-b', b-c', a-c' (primes on top).
        t = np.stack(
            [
                np.column_stack([a + lo, b + lo, c + lo, c + hi]),
                np.column_stack([a + lo, b + lo, b + hi, c + hi]),
                np.column_stack([a + lo, a + hi, b + hi, c + hi]),
            ],
            axis=1,
        ).reshape(-1, 4)
        tets.append(t)
    t = np.vstack(tets)
    # Positive orientation (positive Jacobian) by swapping two vertices where needed.
    p = pts[t]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    neg = vol < 0
    t[neg] = t[neg][:, [0, 2, 1, 3]]
    return MeshTet(pts.T.copy(), t.T.copy(), sort_t=False)


# --------------------------------------------------------------------------------------------
# Assembly and solve


def _lame(material: Material) -> tuple[float, float]:
    """3D Lamé constants (lambda, mu), MPa."""
    E, nu = material.E_MPa, material.nu
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def _gradients(basis) -> np.ndarray:
    """Scalar basis gradients (nel, nqp, nloc, 3) of a scalar scikit-fem basis."""
    return np.stack([np.moveaxis(phi[0].grad, 0, -1) for phi in basis.basis], axis=2)


def _stiffness(sbasis, lam: float, mu: float, block: int) -> sp.csr_matrix:
    """Linear-elastic stiffness in the DOF numbering ``3 s + c`` (s scalar P2 DOF, c component).

    The element-by-element reference assembly (the tests check :func:`_stiffness_parts`
    against it). Per element, with g_a the scalar gradient of local function a and dx the
    quadrature weights:
    ``K_(a c)(b d) = sum_q dx (lam g_ac g_bd + mu g_ad g_bc + mu delta_cd g_a . g_b)``,
    N/mm per mm of height (the mesh carries the height).
    """
    dofs = sbasis.element_dofs.T  # (nel, 10)
    nel, nloc = dofs.shape
    ndof = 3 * sbasis.N
    K = sp.csr_matrix((ndof, ndof))
    G_all = _gradients(sbasis)  # (nel, nqp, 10, 3)
    dx_all = sbasis.dx  # (nel, nqp)
    eye = np.eye(3)
    for s in range(0, nel, block):
        G, dx = G_all[s : s + block], dx_all[s : s + block]
        Gw = G * dx[:, :, None, None]
        # (e, a, c, b, d)
        Ke = lam * np.einsum("eqac,eqbd->eacbd", Gw, G, optimize=True)
        Ke += mu * np.einsum("eqad,eqbc->eacbd", Gw, G, optimize=True)
        Ke += mu * np.einsum("eqak,eqbk,cd->eacbd", Gw, G, eye, optimize=True)
        ldof = (3 * dofs[s : s + block, :, None] + np.arange(3)).reshape(-1, 3 * nloc)
        m = ldof.shape[0]
        rows = np.broadcast_to(ldof[:, :, None], (m, 3 * nloc, 3 * nloc)).ravel()
        cols = np.broadcast_to(ldof[:, None, :], (m, 3 * nloc, 3 * nloc)).ravel()
        K = K + sp.csr_matrix((Ke.ravel(), (rows, cols)), shape=(ndof, ndof))
    return K


def cholmod_available() -> bool:
    """True when CHOLMOD imports (cvxopt, the ``cholmod`` extra): what ``solver = "auto"``
    takes then, and what ``solver = "cholmod"`` needs."""
    try:
        from cvxopt import cholmod  # noqa: F401
    except ImportError:
        return False
    return True


def _gathered(vals) -> np.ndarray:
    """Values given as an array, as a pair (data, flat) for ``data[flat]``, or as a
    one-element list holding either (emptied: the caller hands its only reference over, so
    that the values can be freed as soon as a solver has copied them)."""
    if isinstance(vals, list):
        vals = vals.pop()
    return vals[0][vals[1]] if isinstance(vals, tuple) else vals


def _trim_heap() -> None:
    """Give the C heap's free pages back to the system (glibc's ``malloc_trim``; nothing
    elsewhere). Arrays under glibc's mmap threshold (up to 32 MB once larger ones were freed)
    come from the heap, and what they leave when freed stays resident; the P^T K P product's
    pieces and the plane comparison leave ~0.1 GB there on the SEA spring's check, which
    would otherwise sit under CHOLMOD's factorisation, the check's peak (docs/solid3d.md,
    "Memory"). No number changes."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc (e.g. musl): nothing to trim this way
        pass


class SparseSolver:
    """Factorise a symmetric positive definite matrix once and solve with it.

    "cholmod": CHOLMOD's supernodal Cholesky through cvxopt (the optional ``cholmod`` extra,
    see fea/plane_stress.py), reading the lower triangle only. "qdldl": QDLDL's LDLᵀ (a
    runtime dependency), the upper triangle, what "auto" takes without cvxopt. "superlu":
    scipy's LU, the last fallback. Measured on the SEA-spring study's chosen design extruded
    (372k free DOFs, one BLAS thread, under load 2-3): CHOLMOD 5-8 s (analysis and numeric
    factorisation), QDLDL 34-39 s (a simplicial method: no dense blocks), SuperLU 135 s; on a
    39k-DOF strip ~0.3 s for CHOLMOD against ~3 s for cholespy (CHOLMOD's simplicial method
    only) and ~5 s for SuperLU.
    """

    def __init__(self, K: sp.spmatrix | None, which: str, lower: tuple | None = None,
                 columns: tuple | None = None) -> None:  # fmt: skip
        """``K`` (n, n) symmetric; or ``lower`` = (values, rows, cols, n): its lower triangle
        as triplets (rows >= cols, no duplicates); or ``columns`` = (values, rows, colptr, n):
        its lower triangle in compressed columns (rows sorted within each), the values
        possibly as a pair (data, flat) for ``data[flat]``; the values and the rows possibly
        in one-element lists that are emptied (:func:`_gathered`)."""
        if which not in ("auto", "cholmod", "qdldl", "superlu"):
            raise FeaError(f"solver '{which}' unknown; use 'auto', 'cholmod', 'qdldl' or 'superlu'")
        if lower is None and columns is None:
            assert K is not None
            L = sp.tril(K, format="coo")
            lower = (L.data, L.row, L.col, K.shape[0])
        compressed = columns is not None
        if columns is not None:
            vals, rows, colptr, self.n = columns
            cols = None
        else:
            assert lower is not None
            vals, rows, cols, self.n = lower
        # the caller's tuples go: a list in them (see _gathered) then holds the values alone
        del lower, columns
        vals = _gathered(vals)
        # the rows may come in a one-element list too (emptied: freed once CHOLMOD's copy is
        # made, not held through its factorisation: 4 bytes an entry, 42 MB on the SEA sector)
        rows = rows.pop() if isinstance(rows, list) else rows
        if which in ("auto", "cholmod"):
            try:
                from cvxopt import cholmod, matrix, spmatrix
            except ImportError as exc:
                if which == "cholmod":
                    raise FeaError(f"solver 'cholmod' needs cvxopt ({exc})") from exc
            else:
                # cvxopt copies each array into its own matrix and then into the sparse
                # matrix: made one at a time and each numpy array let go as soon as it is
                # copied, at most three arrays of the triangle's length live beside CHOLMOD's
                # matrix instead of five (docs/solid3d.md, "Memory").
                xv = matrix(np.asarray(vals, dtype=float))
                vals = None
                xr = matrix(np.asarray(rows, dtype=np.int64))
                rows = None
                if cols is None:
                    cols = np.repeat(np.arange(self.n, dtype=np.int64), np.diff(colptr))
                xc = matrix(np.asarray(cols, dtype=np.int64))
                cols = None
                A = spmatrix(xv, xr, xc, (self.n, self.n))
                del xv, xr, xc
                _trim_heap()  # the factorisation is the check's peak
                self._cholmod, self._matrix = cholmod, matrix
                self._F = cholmod.symbolic(A, uplo="L")
                try:
                    cholmod.numeric(A, self._F)
                except ArithmeticError as exc:
                    raise self._not_definite(exc) from exc
                self.name = "cholmod"
                return
        if compressed:
            L = sp.csc_matrix((vals, rows, colptr), shape=(self.n, self.n))
        else:
            L = sp.coo_matrix((vals, (rows, cols)), shape=(self.n, self.n)).tocsc()
        if which in ("auto", "qdldl"):
            try:
                import qdldl
            except ImportError as exc:
                if which == "qdldl":
                    raise FeaError(f"solver 'qdldl' needs the package qdldl ({exc})") from exc
            else:
                try:
                    self._qdldl = qdldl.Solver(L.T.tocsc(), upper=True)
                except RuntimeError as exc:  # a zero pivot
                    raise self._not_definite(exc) from exc
                # LDLᵀ without pivoting also factorises an indefinite matrix: D's signs say
                if not np.all(self._qdldl.factors()[1] > 0.0):
                    raise self._not_definite("a pivot <= 0")
                self.name = "qdldl"
                return
        from scipy.sparse.linalg import splu

        K = L + L.T - sp.diags(L.diagonal())
        # Minimum degree on A^T + A suits symmetric matrices (as in fea.plane_stress).
        self._lu = splu(sp.csc_matrix(K), permc_spec="MMD_AT_PLUS_A")
        self.name = "superlu"

    @staticmethod
    def _not_definite(why: object) -> FeaError:
        return FeaError(
            f"the 3D stiffness is not positive definite ({why}): a part not held by the clamp "
            "and drive (a free body), or a degenerate element"
        )

    def solve(self, b: np.ndarray) -> np.ndarray:
        """x (n,) with K x = b (n,)."""
        if self.name == "cholmod":
            x = self._matrix(np.array(b, dtype=float))
            self._cholmod.solve(self._F, x)
            return np.asarray(x).ravel()
        if self.name == "qdldl":
            return self._qdldl.solve(np.asarray(b, dtype=float))
        return self._lu.solve(b)


def _von_mises(grad_u: np.ndarray, lam: float, mu: float) -> np.ndarray:
    """Von Mises stress, MPa, from displacement gradients (..., 3, 3)."""
    eps = 0.5 * (grad_u + np.swapaxes(grad_u, -1, -2))
    tr = np.trace(eps, axis1=-2, axis2=-1)
    dev = 2.0 * mu * (eps - tr[..., None, None] * np.eye(3) / 3.0)  # deviatoric stress
    return np.sqrt(1.5 * np.einsum("...ij,...ij->...", dev, dev))


def _distinct_xy(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of ``xy`` (n, 2) as shapely points, and each row's index among them.

    Every node lies above a vertex or an edge midpoint of the plane mesh, so there are a
    ninth as many with 4 layers. One unique over (x, y) read as a complex number: the rows
    of ``np.unique(xy, axis=0)`` in the same order, ~6x faster.
    """
    xc = np.ascontiguousarray(xy, dtype=float).view(np.complex128).ravel()
    u, back = np.unique(xc, return_inverse=True)
    return shapely.points(np.column_stack([u.real, u.imag])), back.ravel()


def _select(xy: np.ndarray, region: BaseGeometry, what: str, tol: float,
            distinct: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:  # fmt: skip
    """The nodes (rows of ``xy`` (n, 2) mm) within ``tol`` mm of ``region``, each distinct
    (x, y) measured once (``distinct``: :func:`_distinct_xy` of ``xy``, if known)."""
    points, back = distinct if distinct is not None else _distinct_xy(xy)
    d = shapely.distance(region, points)[back]
    nodes = np.flatnonzero(d <= tol)
    if nodes.size == 0:
        raise FeaError(
            f"the {what} region selects no node of the 3D mesh (nearest is {d.min():.3g} mm "
            f"away, tolerance {tol:g} mm); put it on the outline or overlapping the part"
        )
    return nodes


def solve_solid3d(
    mesh: TriMesh,
    material: Material,
    thickness_mm: float,
    clamp: Clamp,
    drive: Drive,
    settings: Solid3DSettings = Solid3DSettings(),
    stress_ignore: BaseGeometry | None = None,
) -> Solid3DResult:
    """Linear 3D elasticity of the plane mesh extruded to ``thickness_mm``, at the full drive.

    Parameters
    ----------
    mesh : TriMesh
        The plane mesh, nodes (n, 2) mm (typically the one the plane-stress model used).
    material : Material
        E (MPa) and nu.
    thickness_mm : float, mm
        Out-of-plane thickness.
    clamp : Clamp
        Held region (through the thickness).
    drive : Rotate or Translate
        Driven region and its motion; the value is ``max_rad`` / ``max_mm`` (``steps`` is
        ignored: the answer is linear).
    settings : Solid3DSettings
    stress_ignore : shapely geometry, optional
        Elements whose plane footprint touches it are left out of the peak stress (as in
        :class:`fea.plane_stress.PlaneStressModel`).

    Returns
    -------
    Solid3DResult

    Raises
    ------
    FeaError
        Bad thickness or regions, a model over ``max_dofs``.

    Notes
    -----
    The reference answer: a :class:`Solid3DModel` built at this thickness (its stiffness
    parts summed with unit weights, no stretch) and factorised. ``_stiffness`` assembles the
    same matrix element by element (the tests compare them entry by entry).
    """
    if not (np.isfinite(thickness_mm) and thickness_mm > 0):
        raise FeaError(f"thickness_mm = {thickness_mm} must be > 0 mm")
    model = Solid3DModel(mesh, material, clamp, drive, settings, stress_ignore,
                         reference_thickness_mm=float(thickness_mm))  # fmt: skip
    return model.solve(thickness_mm)


@dataclass(frozen=True)
class _Supports:
    """The clamp and drive of a 3D model: prescribed displacements and the free unknowns.

    DOF of component c at scalar P2 node s is ``3 s + c``. ``u = ubar + P q`` with q the
    unknowns; ``free`` are the DOFs P selects one to one (``P`` holds one more column, the
    common transverse slide, with ``transverse = "free"``).
    """

    clamp_nodes: np.ndarray  # (nc,) int, scalar nodes
    drive_nodes: np.ndarray  # (nd,) int
    ubar: np.ndarray  # (ndof,) float, mm
    P: sp.csr_matrix  # (ndof, nq)
    free: np.ndarray  # (nfree,) int, DOFs
    arm_mm: np.ndarray  # (nd, 2) float, mm: drive node minus the centre
    direction: np.ndarray  # (2,) unit
    value: float  # rad or mm
    is_rot: bool
    # False when P ties DOFs together (a rotational sector's cut B to cut A): not a selection
    selection: bool = True
    # rotated copies of the meshed part in the whole (a sector model: n), for the reactions
    copies: int = 1


def _supports(locs: np.ndarray, ndof: int, clamp: Clamp, drive: Drive,
              settings: Solid3DSettings) -> _Supports:  # fmt: skip
    """Clamp, drive and mid-plane symmetry on the P2 nodes ``locs`` (Ns, 3) mm."""
    tol = settings.select_tol_mm
    distinct = _distinct_xy(locs[:, :2])
    clamp_nodes = _select(locs[:, :2], clamp.region, "clamp", tol, distinct)
    drive_nodes = _select(locs[:, :2], drive.region, "drive", tol, distinct)
    held = np.zeros((locs.shape[0], 3), dtype=bool)  # (node, component) prescribed
    held[clamp_nodes] = True
    both = np.count_nonzero(held[drive_nodes, 0])
    if both:
        raise FeaError(f"{both} node(s) are both clamped and driven; separate the regions")
    held[drive_nodes] = True
    ubar = np.zeros(ndof)
    if settings.symmetric:
        # Mid-plane symmetry: no out-of-plane motion at z = 0.
        held[np.abs(locs[:, 2]) <= tol, 2] = True
    X = locs[drive_nodes, :2]
    is_rot = isinstance(drive, Rotate)
    if is_rot:
        centre = np.asarray(drive.centre_mm, dtype=float)
        value = float(drive.max_rad)
        r = X - centre
        move = value * np.column_stack([-r[:, 1], r[:, 0]])  # linearised rigid rotation
        direction = np.array([1.0, 0.0])
    else:
        d = np.asarray(drive.direction, dtype=float)
        if not (d.shape == (2,) and np.linalg.norm(d) > 0):
            raise FeaError(f"drive direction {drive.direction} must be a non-zero (dx, dy)")
        direction = d / np.linalg.norm(d)
        centre = X.mean(axis=0) if drive.centre_mm is None else np.asarray(drive.centre_mm)
        value = float(drive.max_mm)
        move = np.broadcast_to(value * direction, X.shape)
    ubar[3 * drive_nodes] = move[:, 0]
    ubar[3 * drive_nodes + 1] = move[:, 1]
    free = np.flatnonzero(~held.ravel())  # DOF 3 s + c
    cols = [sp.csr_matrix((np.ones(free.size), (free, np.arange(free.size))), (ndof, free.size))]
    if not is_rot and drive.transverse == "free":
        # One shared unknown: the driven nodes slide together perpendicular to the direction.
        nrm = np.array([-direction[1], direction[0]])
        rows = np.concatenate([3 * drive_nodes, 3 * drive_nodes + 1])
        vals = np.concatenate(
            [np.full(drive_nodes.size, nrm[0]), np.full(drive_nodes.size, nrm[1])]
        )
        cols.append(sp.csr_matrix((vals, (rows, np.zeros(rows.size, dtype=int))), (ndof, 1)))
    elif not is_rot and drive.transverse != "fixed":
        raise FeaError(f"transverse = '{drive.transverse}' must be 'fixed' or 'free'")
    return _Supports(clamp_nodes, drive_nodes, ubar, sp.hstack(cols).tocsr(), free, X - centre,
                     direction, value, is_rot)  # fmt: skip


def _partners(xyz: np.ndarray, pm: PeriodicMesh, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The points of ``xyz`` (k, 3) mm on the sector's cut B and, for each, its partner on
    cut A (the point that the rotation R turns onto it, at the same z): (b (m,), a (m,)) int.
    Points on the axis are on neither. Raises FeaError when a cut point has no partner."""
    c = pm.centre_mm
    w = xyz[:, :2] - c
    r = np.linalg.norm(w, axis=1)
    on = {}
    for name, ang in (("a", pm.angle0_rad), ("b", pm.angle0_rad + pm.step_rad)):
        d = np.array([math.cos(ang), math.sin(ang)])
        on[name] = np.flatnonzero((np.abs(w[:, 0] * d[1] - w[:, 1] * d[0]) <= tol)
                                  & (w @ d > tol) & (r > tol))  # fmt: skip
    a, b = on["a"], on["b"]
    if a.size != b.size:
        raise FeaError(f"the sector's cuts hold {a.size} and {b.size} nodes: not periodic")
    # cut B turned back onto cut A: the same (x, y, z) up to round-off
    back = np.column_stack([w[b] @ pm.rotation(-1).T + c, xyz[b, 2]])
    from scipy.spatial import cKDTree

    dist, k = cKDTree(xyz[a]).query(back)
    if a.size and (dist.max() > tol or np.unique(k).size != a.size):
        raise FeaError(
            f"a node of the sector's cut B has no partner on cut A ({dist.max():.3g} mm away): "
            "the cuts are not meshed alike"
        )
    return b, a[k]


def _periodic_supports(sup: _Supports, locs: np.ndarray, pm: PeriodicMesh, drive: Drive,
                       settings: Solid3DSettings) -> _Supports:  # fmt: skip
    """The supports ``sup`` of a sector's P2 nodes ``locs`` (Ns, 3) mm with its cut B tied
    to cut A: ``u_B = R u_A`` (R the turn by 2 pi / n about z through the centre), cut B's DOFs
    no unknowns of their own (their rows of P are R times cut A's); a free node on the axis
    (its own partner: R u = u) keeps only w. The clamp and drive must hold cut A's and cut B's
    nodes alike (a part and supports that repeat), and the drive be a Rotate about the centre.
    """
    if not isinstance(drive, Rotate):
        raise FeaError("a sector model needs the drive to be a Rotate (a translation is not "
                       "repeated by the rotation)")  # fmt: skip
    if not np.allclose(drive.centre_mm, pm.centre_mm, rtol=0.0, atol=settings.select_tol_mm):
        raise FeaError(f"the drive turns about {tuple(drive.centre_mm)}, the sector's axis is "
                       f"{tuple(pm.centre_mm)}: not a symmetric load")  # fmt: skip
    tol = settings.select_tol_mm
    ndof = sup.ubar.size
    b, a = _partners(locs, pm, tol)
    held = np.ones(ndof, dtype=bool)
    held[sup.free] = False
    hb, ha = held.reshape(-1, 3)[b], held.reshape(-1, 3)[a]
    if np.any(hb != ha):
        raise FeaError(
            f"{int(np.any(hb != ha, axis=1).sum())} node(s) of the sector's cut B are held "
            "unlike their partners on cut A: the supports do not repeat"
        )
    # R ubar_A = ubar_B where both are held (the supports repeat; the rigid turn does)
    c, s = math.cos(pm.step_rad), math.sin(pm.step_rad)
    R3 = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    ua = sup.ubar.reshape(-1, 3)[a] @ R3.T
    ub = sup.ubar.reshape(-1, 3)[b]
    off = np.abs(np.where(hb, ua - ub, 0.0)).max(initial=0.0)
    if off > 1e-9 * max(1.0, np.abs(sup.ubar).max(initial=0.0)):
        raise FeaError(f"a held node of cut B moves unlike its partner turned ({off:.3g} mm)")
    held3 = held.reshape(-1, 3).copy()
    held3[b] = True  # cut B: no unknowns of its own
    w = locs[:, :2] - pm.centre_mm
    axis = np.flatnonzero(np.linalg.norm(w, axis=1) <= tol)
    held3[axis, :2] = True  # R u = u on the axis: u = v = 0 (n >= 2), held at 0
    ubar = sup.ubar.copy()
    ubar.reshape(-1, 3)[axis[~held.reshape(-1, 3)[axis, 0]], :2] = 0.0
    free = np.flatnonzero(~held3.ravel())
    col = np.full(ndof, -1, dtype=np.int64)
    col[free] = np.arange(free.size)
    rows, cols, vals = [free], [np.arange(free.size)], [np.ones(free.size)]
    fb = ~hb  # (m, 3) free components of cut B (those of cut A alike)
    for ci in range(3):
        for di in range(3):
            if R3[ci, di] == 0.0:
                continue
            k = fb[:, ci] & fb[:, di]
            rows.append(3 * b[k] + ci)
            cols.append(col[3 * a[k] + di])
            vals.append(np.full(int(k.sum()), R3[ci, di]))
    r_, c_, v_ = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    if np.any(c_ < 0):
        raise FeaError("a free component of cut B is tied to a held one of cut A")
    P = sp.csr_matrix((v_, (r_, c_)), shape=(ndof, free.size))
    return _Supports(sup.clamp_nodes, sup.drive_nodes, ubar, P, free, sup.arm_mm,
                     sup.direction, sup.value, sup.is_rot, selection=False,
                     copies=pm.n)  # fmt: skip


def _partner_class(p: np.ndarray, pm: PeriodicMesh, tol: float) -> np.ndarray:
    """(nv,) int: each tetrahedral vertex (p (nv, 3) mm) stands for itself, a cut B vertex
    for its partner on cut A (the whole part's one vertex there)."""
    cls = np.arange(p.shape[0])
    b, a = _partners(p, pm, tol)
    cls[b] = a
    return cls


def _reactions(f: np.ndarray, sup: _Supports, settings: Solid3DSettings) -> dict:
    """Drive and clamp reactions of the whole part from the internal force ``f`` (ndof,) N."""
    # Whole part: the half model carries half the in-plane forces; the z forces of the two
    # mirrored halves are equal and opposite, so the part's is 0.
    # A sector stands for its n rotated copies: the torque is n times its own, and the net
    # in-plane forces of the copies, sum_k R^k f, vanish (sum_k R^k = 0 in the plane, n >= 2).
    scale = (2.0 if settings.symmetric else 1.0) * sup.copies
    keep_z = 0.0 if settings.symmetric else 1.0
    dn, cn, arm = sup.drive_nodes, sup.clamp_nodes, sup.arm_mm
    fd = np.array([f[3 * dn + c].sum() for c in range(3)]) * scale
    fc = np.array([f[3 * cn + c].sum() for c in range(3)]) * scale
    fd[2] *= keep_z
    fc[2] *= keep_z
    if sup.copies > 1:
        fd[:2] = 0.0
        fc[:2] = 0.0
    torque = float(np.sum(arm[:, 0] * f[3 * dn + 1] - arm[:, 1] * f[3 * dn])) * scale
    force = float(fd[:2] @ sup.direction)
    stiffness = torque / sup.value if sup.is_rot else force / sup.value
    return {"fd": fd, "fc": fc, "torque": torque, "force": force, "stiffness": stiffness}


def _result(sup: _Supports, rx: dict, peaks: tuple, ndof: int, n_tets: int, n_layers: int,
            settings: Solid3DSettings, solver: str, times: dict,
            iterations: int = 0) -> Solid3DResult:  # fmt: skip
    peak, where, peak_n, where_n = peaks
    return Solid3DResult(
        drive="rotate" if sup.is_rot else "translate",
        drive_value=sup.value,
        reaction_N=rx["fd"],
        torque_Nmm=rx["torque"],
        force_N=rx["force"],
        stiffness=float(rx["stiffness"]),
        clamp_reaction_N=rx["fc"],
        peak_stress_MPa=peak,
        peak_stress_xyz_mm=where,
        peak_nodal_stress_MPa=peak_n,
        peak_nodal_stress_xyz_mm=where_n,
        n_dofs=int(ndof),
        n_tets=int(n_tets),
        n_layers=int(n_layers),
        symmetric=bool(settings.symmetric),
        solver=solver,
        times_s=times,
        iterations=int(iterations),
        sectors=int(sup.copies),
    )


# The four corners of the reference tetrahedron as a "quadrature" (weights unused): the P2
# gradient there gives the vertex values of the stress.
_CORNERS = (np.array([[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]),
            np.full(4, 1.0 / 24.0))  # fmt: skip


def _stress_mask(nel: int, mesh: TriMesh, ignore: BaseGeometry | None) -> np.ndarray:
    """(nel,) bool: the tetrahedra whose plane footprint does not touch ``ignore``."""
    mask = np.ones(nel, dtype=bool)
    if ignore is not None:
        tris = shapely.polygons(mesh.points[mesh.triangles])
        hit = shapely.intersects(ignore, tris)  # (m,) per plane triangle
        # Element 3 (k m + j) + s lies above plane triangle j.
        j = (np.arange(nel) // 3) % mesh.n_triangles
        mask = ~hit[j]
        if not mask.any():
            raise FeaError("stress_ignore covers every element; nothing left to check")
    return mask


def peak_stresses(u, dofs, G, xyz_qp, Gc, t, p, mask, lam, mu, z_scale=1.0, kernels=None,
                  merge=None):  # fmt: skip
    """Peak von Mises at quadrature points and vertex-averaged, with their (x, y, z), mm.

    u (ndof,) mm; dofs (nel, 10) scalar P2 DOFs; G (nel, nqp, 10, 3) and Gc (nel, 4, 10, 3)
    scalar basis gradients, 1/mm, at the quadrature points and the corners; xyz_qp
    (3, nel, nqp) mm; t (nel, 4) vertices; p (3, nv) mm; mask (nel,) bool: elements judged.
    z_scale: the mesh the gradients belong to stretched by this along z (their z components
    divided by it; xyz_qp and p are the stretched mesh's). kernels: the compiled module
    (:func:`fea._solid3d_kernels.von_mises`, one pass over the elements) or None (numpy).
    merge: (nv,) int or None: vertices averaged together (a sector's cut B vertex with its
    partner on cut A: in the whole part both are one vertex, with the tetrahedra of both
    sides; a vertex's class is the index of the vertex standing for it).
    """
    if kernels is not None:
        vm = kernels.von_mises(u, dofs, G, mu, z_scale)  # (nel, nqp)
        vc = kernels.von_mises(u, dofs, Gc, mu, z_scale)  # (nel, 4)
        return _peak_values(vm, vc, xyz_qp, t, p, mask, merge)
    ue = u.reshape(-1, 3)[dofs]  # (nel, 10, 3)

    def grad_u(G: np.ndarray) -> np.ndarray:  # G (nel, nqp, 10, 3) -> (nel, nqp, 3, 3)
        g = np.einsum("eac,eqaj->eqcj", ue, G)
        if z_scale != 1.0:
            g[..., 2] /= z_scale
        return g

    vm = _von_mises(grad_u(G), lam, mu)  # (nel, nqp)
    # Vertex values: the P2 gradient at the tetrahedron's corners, averaged over its elements.
    vc = _von_mises(grad_u(Gc), lam, mu)  # (nel, 4) in t order
    return _peak_values(vm, vc, xyz_qp, t, p, mask, merge)


def _vertex_average(vc, t, nv, merge=None):
    """(nv,) the corner values vc (nel, 4) averaged at each vertex over its tetrahedra (t
    (nel, 4)), vertices of one class of ``merge`` (nv,) together."""
    tv = t.ravel() if merge is None else merge[t.ravel()]
    total = np.bincount(tv, weights=vc.ravel(), minlength=nv)
    count = np.bincount(tv, minlength=nv)
    nodal = total / np.maximum(count, 1)
    return nodal if merge is None else nodal[merge]


def _peak_values(vm, vc, xyz_qp, t, p, mask, merge=None):
    """peak_stresses' answer from the von Mises stress vm (nel, nqp) and vc (nel, 4), MPa."""
    vm_m = np.where(mask[:, None], vm, -np.inf)
    e, qp = np.unravel_index(np.argmax(vm_m), vm_m.shape)
    xyz = xyz_qp[:, e, qp]
    n = p.shape[1]
    nodal = _vertex_average(vc, t, n, merge)
    allowed = np.zeros(n, dtype=bool)
    if merge is None:
        allowed[t[mask].ravel()] = True
    else:  # a class is judged when any of its vertices' elements is
        allowed[merge[t[mask].ravel()]] = True
        allowed = allowed[merge]
    nodal[~allowed] = -np.inf
    k = int(np.argmax(nodal))
    return float(vm[e, qp]), xyz.copy(), float(nodal[k]), p[:, k].copy()


# --------------------------------------------------------------------------------------------
# One model for every thickness


_KERNELS: list = []


def _compiled():
    """fea._solid3d_kernels, or None when numba cannot be imported (the numpy path then runs)."""
    if not _KERNELS:
        try:
            from flexopt.fea import _solid3d_kernels

            _KERNELS.append(_solid3d_kernels)
        except Exception:  # ImportError, or a numba that fails on this platform's LLVM
            _KERNELS.append(None)
    return _KERNELS[0]


def p2_tables(tmesh, kernels) -> tuple:
    """The P2 tables of a tetrahedral mesh without scikit-fem's Basis (the compiled path).

    scikit-fem's numbering (the tests check it): the vertices, then one node per edge, the
    edges sorted by (lower vertex, higher vertex); an element's local nodes are its 4
    vertices, then its edges in ``kernels._EDGES`` order. Gradients from the vertex
    coordinates (:func:`fea._solid3d_kernels.p2_tables`) at scikit-fem's order-2 rule.

    Returns
    -------
    dofs : (nel, 10) int64; n_scalar : int; doflocs : (n_scalar, 3) float, mm;
    G : (nel, nqp, 10, 3), 1/mm; dx : (nel, nqp), mm^3; Gc : (nel, 4, 10, 3), 1/mm (at the
    corners, in t order); xyz_qp : (3, nel, nqp), mm.
    """
    from skfem.quadrature import get_quadrature
    from skfem.refdom import RefTet

    p = np.ascontiguousarray(tmesh.p, dtype=float)
    t = np.ascontiguousarray(tmesh.t.T, dtype=np.int64)
    nv = p.shape[1]
    ends = kernels._EDGES
    a, b = t[:, ends[:, 0]], t[:, ends[:, 1]]
    key = (np.minimum(a, b) * nv + np.maximum(a, b)).ravel()
    uniq, inv = np.unique(key, return_inverse=True)
    dofs = np.hstack([t, nv + inv.reshape(-1, 6)])
    lo, hi = np.divmod(uniq, nv)
    doflocs = np.hstack([p, 0.5 * (p[:, lo] + p[:, hi])]).T
    X, w = get_quadrature(RefTet, 2)
    G, dx, xyz = kernels.p2_tables(p, t, np.ascontiguousarray(X, dtype=float),
                                   np.ascontiguousarray(w, dtype=float), ends)  # fmt: skip
    Gc = kernels.p2_tables(p, t, _CORNERS[0], _CORNERS[1], ends)[0]
    return dofs, nv + uniq.size, doflocs, G, dx, Gc, xyz


def _p2_gradients(tmesh, kernels) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``G``, ``dx`` and ``Gc`` of :func:`_p2_tables` again, bit for bit (the same kernel on
    the same vertices): the compiled model drops them after the assembly and makes them anew
    for the stress (and the parts, :attr:`Solid3DSettings.lean_factorisation`), so that they
    (2 x 74 MB on the SEA spring) are not held while CHOLMOD factorises."""
    from skfem.quadrature import get_quadrature
    from skfem.refdom import RefTet

    p = np.ascontiguousarray(tmesh.p, dtype=float)
    t = np.ascontiguousarray(tmesh.t.T, dtype=np.int64)
    X, w = get_quadrature(RefTet, 2)
    G, dx, _ = kernels.p2_tables(p, t, np.ascontiguousarray(X, dtype=float),
                                 np.ascontiguousarray(w, dtype=float), kernels._EDGES)  # fmt: skip
    Gc = kernels.p2_tables(p, t, _CORNERS[0], _CORNERS[1], kernels._EDGES)[0]
    return G, dx, Gc


# Columns of P^T K P made at a time for a sector's tie (Solid3DModel._tied_lower): each
# slice's K P and P^T K P are ~1/4 of the whole's on the SEA spring's 219k unknowns.
_TIED_COLUMNS = 65_536

# Components (c, d) of a 3x3 node block that each part of the stiffness fills: the in-plane
# part (both gradients in-plane) has the in-plane block and, from mu delta_cd g_a.g_b, the
# (z, z) entry; the mixed part the four entries with one z; the out-of-plane part the
# diagonal (lam + 2 mu on (z, z), mu g_az g_bz on the in-plane ones).
_PP = ((0, 0), (0, 1), (1, 0), (1, 1), (2, 2))
_PZ = ((0, 2), (1, 2), (2, 0), (2, 1))
_ZZ = ((0, 0), (1, 1), (2, 2))


def _stiffness_parts(G: np.ndarray, dx: np.ndarray, dofs: np.ndarray, n_scalar: int,
                     lam: float, mu: float, block: int):  # fmt: skip
    """The stiffness split by the directions of the two gradients, on one block pattern.

    ``K_(a c)(b d) = sum_q dx (lam g_ac g_bd + mu g_ad g_bc + mu delta_cd g_a . g_b)``
    (:func:`_stiffness`); each product of two gradient components is in-plane x in-plane,
    mixed, or z x z. Stretching the mesh along z by s multiplies them by s, 1 and 1 / s
    (g_z scales by 1 / s, dx by s), so ``K(s) = s K_pp + K_pz + K_zz / s`` exactly.

    Parameters
    ----------
    G : (nel, nqp, 10, 3) float, 1/mm — scalar gradients; dx : (nel, nqp) float, mm^3.
    dofs : (nel, 10) int — scalar P2 DOFs; n_scalar : int — their number.
    lam, mu : float, MPa; block : int — elements per batch (bounds the memory).

    Returns
    -------
    indptr (n_scalar + 1,), indices (nnzb,) — the scalar (block-row) pattern, sorted;
    parts : (nnzb, 12) float, N/mm — each node block's entries listed in _PP, _PZ, _ZZ, in
    that order.
    """
    nel, nloc = dofs.shape
    # (element, a, b) -> node block: one sort of the 100 pairs of every element (a stable
    # sort: the elements' order already groups most pairs, np.unique's sort is ~3x slower)
    keys = np.repeat(dofs.astype(np.int64) * n_scalar, nloc, axis=1)
    keys += np.tile(dofs, (1, nloc))
    keys = keys.ravel()
    order = np.argsort(keys, kind="stable")
    sk = keys[order]
    del keys
    first = np.empty(sk.size, dtype=bool)
    first[0] = True
    np.not_equal(sk[1:], sk[:-1], out=first[1:])
    uniq = sk[first]
    del sk
    inv = np.empty(order.size, dtype=np.int64)
    inv[order] = np.cumsum(first) - 1
    del order, first
    nnzb = uniq.size
    brow, bcol = np.divmod(uniq, n_scalar)
    indptr = np.concatenate([[0], np.cumsum(np.bincount(brow, minlength=n_scalar))])
    del uniq, brow
    parts = {k: np.zeros((len(c), nnzb)) for k, c in (("pp", _PP), ("pz", _PZ), ("zz", _ZZ))}
    per = nloc * nloc
    for s in range(0, nel, block):
        Gb, dxb = G[s : s + block], dx[s : s + block]
        m = Gb.shape[0]
        Gw = (Gb * dxb[:, :, None, None]).reshape(m, -1, 3 * nloc)
        # M[e, a, b, i, j] = sum_q dx g_ai g_bj (small blocks: the batched product is ~10x
        # slower once its operands leave the cache)
        M = np.matmul(Gw.transpose(0, 2, 1), Gb.reshape(m, -1, 3 * nloc))
        M = M.reshape(m, nloc, 3, nloc, 3).transpose(0, 1, 3, 2, 4)
        # the block's own node blocks: summing into them, then into the whole pattern, keeps
        # each sum as long as the block (not nnzb)
        used, ib = np.unique(inv[s * per : (s + m) * per], return_inverse=True)
        inplane = mu * (M[..., 0, 0] + M[..., 1, 1])
        for name, comps in (("pp", _PP), ("pz", _PZ), ("zz", _ZZ)):
            for j, (c, d) in enumerate(comps):
                if name == "pp" and c == 2:
                    w = inplane  # mu delta_cd g_a.g_b, in-plane gradients, on (z, z)
                elif name == "zz":
                    # (z, z): lam + mu (swapped) + mu (delta); in-plane diagonal: the delta's
                    w = (lam + 2.0 * mu if c == 2 else mu) * M[..., 2, 2]
                else:
                    w = lam * M[..., c, d] + mu * M[..., d, c]
                    if c == d:
                        w = w + inplane
                parts[name][j, used] += np.bincount(ib, weights=w.ravel(), minlength=used.size)
    # (nnzb, 10): the blocks of K(t) are then one product with a (10, 9) table
    return indptr, bcol, np.concatenate([parts["pp"], parts["pz"], parts["zz"]]).T.copy()


def _pcg(matvec: Callable, b: np.ndarray, precondition: Callable, x0: np.ndarray,
         rtol: float, max_iterations: int) -> tuple[np.ndarray, int, bool]:  # fmt: skip
    """Preconditioned conjugate gradients for a symmetric positive definite system.

    Stops when the true residual |b - A x| <= rtol |b| (checked whenever the recursive one
    says so, so round-off in the recursion cannot end it early). Returns (x, iterations,
    converged).
    """
    bnorm = float(np.linalg.norm(b))
    if bnorm == 0.0:
        return np.zeros_like(b), 0, True
    x = np.array(x0, dtype=float)
    r = b - matvec(x)
    z = precondition(r)
    p = z.copy()
    rz = float(r @ z)
    for it in range(1, max_iterations + 1):
        Ap = matvec(p)
        alpha = rz / float(p @ Ap)
        x += alpha * p
        r -= alpha * Ap
        if np.linalg.norm(r) <= rtol * bnorm:
            r = b - matvec(x)  # the true residual decides
            if np.linalg.norm(r) <= rtol * bnorm:
                return x, it, True
        z = precondition(r)
        rz_new = float(r @ z)
        p = z + (rz_new / rz) * p
        rz = rz_new
    return x, max_iterations, False


class Solid3DModel:
    """The 3D model of a plane mesh at any thickness: extruded, assembled and supported once.

    The layer heights are proportional to the thickness (:func:`extrude_layers_mm`), so the
    model at thickness t is the 1 mm model stretched by t along z: its stiffness is
    ``K(t) = t K_pp + K_pz + K_zz / t`` (:func:`_stiffness_parts`), assembled once, and its
    stresses follow from the 1 mm model's basis gradients with their z components divided by
    t (any reference thickness in place of 1 mm). Every node keeps its (x, y), so the
    supports select the same DOFs at every thickness. The first :meth:`solve` factorises K
    (``settings.solver``: CHOLMOD, else QDLDL without cvxopt, else SuperLU; or every
    thickness by multigrid, :meth:`_solve_multigrid`, from the previous answer: "multigrid",
    or "auto" from ``multigrid_from_dofs`` on when CHOLMOD does not import); with
    ``settings.later_solves = "pcg"`` a later thickness is solved by conjugate gradients
    preconditioned with that factor, to ``pcg_rtol``; with "direct" it is factorised anew.
    :func:`solve_solid3d` is the reference (a model built at its thickness, factorised); the
    answers agree to solver round-off (tests/fea/test_solid3d_model.py).

    Parameters
    ----------
    mesh : TriMesh — the plane mesh, (n, 2) mm; material : Material
    clamp : Clamp; drive : Rotate or Translate — as :func:`solve_solid3d`
    settings : Solid3DSettings; stress_ignore : shapely geometry, optional
    reference_thickness_mm : float, mm — the extrusion the model is built at (1 mm; a
        model solved at its reference thickness involves no stretch: solve_solid3d)
    periodic : fea.solid3d_sector.PeriodicMesh, optional — ``mesh`` is its sector: the
        model is that sector with cut B's nodes tied to cut A's turned, ``u_B = R u_A``
        (:func:`_periodic_supports`), which is the whole part's answer when the part, its
        supports and the drive (a Rotate about the same centre) repeat every 2 pi / n:
        stiffness n times the sector's torque, the sector's peak stress (vertex averages on
        the cuts over both sides' tetrahedra); the plane-stress comparison runs on
        ``periodic.whole``. The tie is no DOF selection: the reduced matrix is P^T K P,
        factorised, or solved by multigrid with the tied P1 functions as the coarse space
        (:meth:`_tied_prolongation`). docs/solid3d.md, "The sector solve".

    Memory: the factor of the first thickness is kept (CHOLMOD: 1.04 GB for the SEA spring's
    375k free DOFs) while the model lives. The peak is the first factorisation (2.0 GB there):
    K is not held through it, and with ``lean_factorisation`` neither are the parts nor the
    reduced triangle's pattern (made again after). The multigrid solver (``solver =
    "multigrid"``, or "auto" from ``multigrid_from_dofs`` on without CHOLMOD) keeps no factor
    of the whole:
    the matrix in compressed rows (0.33 GB there) and the P1 factor (< 0.1 GB) while it
    solves, 1.04 GB peak; docs/solid3d.md, "Memory".
    """

    def __init__(
        self,
        mesh: TriMesh,
        material: Material,
        clamp: Clamp,
        drive: Drive,
        settings: Solid3DSettings = Solid3DSettings(),
        stress_ignore: BaseGeometry | None = None,
        reference_thickness_mm: float = 1.0,
        periodic: PeriodicMesh | None = None,
    ) -> None:
        from skfem import Basis, ElementTetP2

        t0 = time.perf_counter()
        if not isinstance(drive, Translate | Rotate):
            raise FeaError(f"drive must be Translate or Rotate, got {type(drive).__name__}")
        if settings.later_solves not in ("pcg", "direct"):
            raise FeaError(f"later_solves '{settings.later_solves}': use 'pcg' or 'direct'")
        self.mesh, self.material, self.settings = mesh, material, settings
        if periodic is not None and periodic.sector is not mesh:
            raise FeaError("a periodic model's mesh must be its PeriodicMesh's sector")
        self.periodic = periodic
        # the plane mesh of the whole part (compare_with_plane_stress solves plane stress on it)
        self.comparison_mesh = mesh if periodic is None else periodic.whole
        self.clamp, self.drive, self.stress_ignore = clamp, drive, stress_ignore
        # the thickness the model is built at, mm (any: the parts are exact at every one)
        self.reference_thickness_mm = float(reference_thickness_mm)
        z = extrude_layers_mm(self.reference_thickness_mm, settings)
        est = 3 * (2 * (z.size - 1) + 1) * 4 * mesh.n_points
        if est > settings.max_dofs:
            raise FeaError(
                f"the 3D model would have about {est} DOFs (cap {settings.max_dofs}); use "
                "fewer layers or a coarser plane mesh"
            )
        if settings.assembly not in ("compiled", "numpy"):
            raise FeaError(f"assembly '{settings.assembly}': use 'compiled' or 'numpy'")
        kernels = _compiled() if settings.assembly == "compiled" else None
        # what runs: "numpy" also when numba does not import (the same answers)
        self.assembly = "compiled" if kernels is not None else "numpy"
        self._kernels = kernels
        self._n_layers = z.size - 1
        tmesh = extrude_mesh(mesh, z)
        if kernels is not None:
            self._dofs, n_scalar, doflocs, self._G, dx, self._Gc, self._xyz_qp = p2_tables(
                tmesh, kernels
            )
        else:
            sbasis = Basis(tmesh, ElementTetP2(), intorder=2)
            cbasis = Basis(tmesh, sbasis.elem, quadrature=_CORNERS)
            self._dofs = sbasis.element_dofs.T  # (nel, 10)
            self._G = _gradients(sbasis)  # (nel, nqp, 10, 3), 1/mm at 1 mm
            self._Gc = _gradients(cbasis)  # (nel, 4, 10, 3)
            self._xyz_qp = np.asarray(sbasis.global_coordinates())  # (3, nel, nqp), mm at 1 mm
            n_scalar, doflocs, dx = sbasis.N, sbasis.doflocs.T, sbasis.dx
        self._t, self._p = tmesh.t.T, tmesh.p  # (nel, 4), (3, nv)
        self._mask = _stress_mask(tmesh.t.shape[1], mesh, stress_ignore)
        self.n_dofs = 3 * n_scalar
        if self.n_dofs > settings.max_dofs:
            raise FeaError(f"{self.n_dofs} DOFs exceed max_dofs = {settings.max_dofs}")
        self._sup = _supports(doflocs, self.n_dofs, clamp, drive, settings)
        self._vertex_class: np.ndarray | None = None  # vertices averaged together (sector)
        if periodic is not None:
            self._sup = _periodic_supports(self._sup, doflocs, periodic, drive, settings)
            self._vertex_class = _partner_class(tmesh.p.T, periodic, settings.select_tol_mm)
        t1 = time.perf_counter()
        self._lam, self._mu = _lame(material)
        if kernels is not None:
            self._indptr, self._indices, self._parts = kernels.block_pattern_parts(
                self._dofs, n_scalar, self._G, dx, self._lam, self._mu
            )
        else:
            self._indptr, self._indices, self._parts = _stiffness_parts(
                self._G, dx, self._dofs, n_scalar, self._lam, self._mu,
                min(2_000, settings.block_elements),
            )  # fmt: skip
        self._lower = self._reduced_lower_pattern(kernels)
        if kernels is not None:
            # Made anew for the stress (_p2_gradients, ~0.1 s): not held while CHOLMOD
            # factorises (docs/solid3d.md, "Memory").
            self._tmesh = tmesh
            self._G = self._Gc = None
        self._build_times = {"mesh": t1 - t0, "assemble": time.perf_counter() - t1}
        self._factor: SparseSolver | None = None
        self._q: np.ndarray | None = None
        # the thickness of the last solve and the solve before it with its unknowns: a later
        # iterative solve starts from their line (_start)
        self._t_q = math.nan
        self._before: tuple[float, np.ndarray] | None = None
        # multigrid where it is asked for (or "auto" on a large model without CHOLMOD, whose
        # factor would be ~3x faster) and can run: compiled kernels, unknowns a DOF selection
        wanted = settings.solver == "multigrid" or (
            settings.solver == "auto"
            and self.n_dofs >= settings.multigrid_from_dofs
            and not cholmod_available()
        )
        # the unknowns a DOF selection (self._lower), or a sector's tie (P^T K P formed:
        # _tied_lower; its coarse space the tied P1 functions, _coarse_prolongation)
        self._multigrid = (
            wanted and kernels is not None and (self._lower is not None or periodic is not None)
        )
        self._coarse_P: sp.csr_matrix | None = None
        self._coarse_name = ""  # the coarse grid's direct solver
        # (thickness mm, factor) of the P1 coarse grid last factorised (_solve_multigrid)
        self._coarse: tuple[float, SparseSolver] | None = None
        # the linear plane-stress answer of the first compared thickness (_plane_linear):
        # a later thickness scales it (compare_with_plane_stress)
        self._plane: dict | None = None

    def _assemble_compiled(self) -> None:
        """The compiled path's pattern, parts and reduced lower triangle, made again from the
        mesh (the same kernels on the same input: the same arrays, bit for bit) after a
        factorisation that ran without them (:attr:`Solid3DSettings.lean_factorisation`)."""
        kernels = self._kernels
        G, dx, _ = _p2_gradients(self._tmesh, kernels)
        self._indptr, self._indices, self._parts = kernels.block_pattern_parts(
            self._dofs, self.n_dofs // 3, G, dx, self._lam, self._mu
        )
        del G, dx
        self._lower = self._reduced_lower_pattern(kernels)

    def _reduced_lower_pattern(self, kernels=None) -> tuple | None:
        """Where the reduced matrix's lower triangle sits in the blocks: (flat index into the
        (nnzb, 3, 3) block values, reduced row, reduced column), or None when the unknowns are
        not a selection of DOFs (a common transverse slide): then P^T K P is formed.
        ``kernels``: the compiled module, whose entries come sorted by column, then row, and
        whose third array is the column pointers (nfree + 1,) instead of the columns: CHOLMOD's
        matrix is made from the compressed columns; or None
        (numpy: triplets)."""
        sup = self._sup
        if sup.P.shape[1] != sup.free.size or not sup.selection:
            return None
        red = np.full(self.n_dofs, -1, dtype=np.int64)
        red[sup.free] = np.arange(sup.free.size)
        if kernels is not None:
            colptr = kernels.reduced_lower_count(self._indptr, self._indices, red)
            # int32 halves the two largest arrays the model keeps (max_dofs bounds the 9
            # entries of the blocks far below 2^31)
            index = np.int32 if 9 * self._indices.size < 2**31 else np.int64
            flat = np.empty(colptr[-1], dtype=index)
            rows = np.empty(colptr[-1], dtype=index)
            kernels.reduced_lower_fill(self._indptr, self._indices, red, colptr, flat, rows)
            return flat, rows, colptr
        nb = np.diff(self._indptr)
        brow = np.repeat(np.arange(nb.size), nb)
        kb = np.flatnonzero(self._indices >= brow)  # blocks on or above the diagonal
        br, bc = brow[kb], self._indices[kb]
        del brow
        free3 = (red >= 0).reshape(-1, 3)  # (node, component)
        keep = free3[br][:, :, None] & free3[bc][:, None, :]  # (block, c, d)
        keep[br == bc] &= np.triu(np.ones((3, 3), dtype=bool))  # upper part of diagonal blocks
        k, cd = np.divmod(np.flatnonzero(keep.ravel()), 9)
        del keep
        c, d = np.divmod(cd, 3)
        flat = 9 * kb[k] + cd
        # the upper triangle of K (row 3 br + c, column 3 bc + d) is the lower of its transpose
        return flat, red[3 * bc[k] + d], red[3 * br[k] + c]

    def stiffness_matrix(self, thickness_mm: float) -> sp.bsr_matrix:
        """K(t), (ndof, ndof) N/mm, DOF ``3 s + c`` (as :func:`_stiffness` at that thickness)."""
        s = float(thickness_mm) / self.reference_thickness_mm
        if self._kernels is not None:
            B = self._kernels.stiffness_blocks(self._parts, s)
            return sp.bsr_matrix((B, self._indices, self._indptr),
                                 shape=(self.n_dofs, self.n_dofs))  # fmt: skip
        # (12, 9): part column -> block entry, times the part's power of s
        table = np.zeros((len(_PP) + len(_PZ) + len(_ZZ), 9))
        j = 0
        for comps, f in ((_PP, s), (_PZ, 1.0), (_ZZ, 1.0 / s)):
            for c, d in comps:
                table[j, 3 * c + d] = f
                j += 1
        B = (self._parts @ table).reshape(-1, 3, 3)
        return sp.bsr_matrix((B, self._indices, self._indptr),
                             shape=(self.n_dofs, self.n_dofs))  # fmt: skip

    def solve(self, thickness_mm: float) -> Solid3DResult:
        """The linear 3D answer at ``thickness_mm``, as :func:`solve_solid3d` gives it.

        ``times_s``: the first solve carries the model's meshing and assembly; a later one
        "assemble" is forming K(t). ``iterations``: PCG's (0 when factorised).
        """
        t0 = time.perf_counter()
        if not (np.isfinite(thickness_mm) and thickness_mm > 0):
            raise FeaError(f"thickness_mm = {thickness_mm} must be > 0 mm")
        st = self.settings
        first = self._factor is None
        # "multigrid" where it cannot run: the direct solvers, as "auto" chooses them
        direct = "auto" if st.solver == "multigrid" else st.solver
        # the build's times go with the first solve (multigrid keeps no factor: by the answer)
        times = dict(self._build_times) if self._q is None else {"mesh": 0.0}
        # K(t)'s blocks are formed only for what reads them (a factorisation, the multigrid
        # solver's matrix; the numpy path's products): the compiled path's products come
        # from the parts (_matvec, the same figures bit for bit), so that a PCG re-check
        # holds no K beside CHOLMOD's factor (docs/solid3d.md, "Memory")
        compiled = self._kernels is not None
        pcg_next = not first and st.later_solves == "pcg" and not self._multigrid
        K = None if compiled and pcg_next else self.stiffness_matrix(thickness_mm)
        t1 = time.perf_counter()
        times["assemble"] = times.get("assemble", 0.0) + (t1 - t0)
        sup = self._sup
        P = sup.P
        b = -(P.T @ (K @ sup.ubar if K is not None else self._matvec(thickness_mm, sup.ubar)))
        iterations = 0
        q = None
        if self._multigrid:
            # K's blocks (245 MB on the SEA spring) are not held beside the solver's matrix
            # (the reactions' product comes from the parts, _matvec, as on the direct path)
            # the lower triangle handed over in a one-element list (see _gathered)
            if sup.selection:
                lower = [(K.data.ravel()[self._lower[0]], self._lower[1], self._lower[2])]
            else:  # a sector's tie: the lower triangle of P^T K P (_tied_lower)
                held = [K]
                K = None
                vals, rows, colptr = self._tied_lower(held)
                # int64 pointers: the kernel's compiled signature
                lower = [(vals.pop(), rows, colptr.astype(np.int64))]
                del rows, colptr
            K = None
            lean = st.lean_factorisation and (sup.selection or not st.multigrid_sector_keeps_parts)
            if lean:  # made again below, bit for bit, from the mesh
                self._parts = self._indices = self._indptr = None
            try:
                x0 = self._start(thickness_mm) if self._q is not None else None
                q, iterations = self._solve_multigrid(lower, b, lean, x0, float(thickness_mm))
            finally:  # also after an error: the model stays usable (e.g. with another solver)
                if lean:
                    self._assemble_compiled()
        elif pcg_next:
            assert self._factor is not None and self._q is not None
            Kq = K
            q, iterations, ok = _pcg(
                lambda x: P.T @ (Kq @ (P @ x) if Kq is not None
                                 else self._matvec(thickness_mm, P @ x)),
                b, self._factor.solve, self._start(thickness_mm),
                st.pcg_rtol, st.pcg_max_iterations,
            )  # fmt: skip
            if not ok:
                q = None  # too far from the factorised thickness: factorise this one
                if K is None:
                    K = self.stiffness_matrix(thickness_mm)
        if q is None:
            iterations = 0
            self._factor = None  # release the old factor before the new one is built
            if self._lower is not None:
                flat, rows, third = self._lower
                # Only the reduced lower triangle's values are kept through the
                # factorisation: K (its blocks, 245 MB on the SEA spring) is formed again
                # afterwards, and the values go to the solver in a one-element list that it
                # empties, so that it frees them once CHOLMOD's copy is made.
                vals = [K.data.ravel()[flat]]
                K = flat = None
                lean = self._kernels is not None and st.lean_factorisation
                if lean:  # made again below, bit for bit, from the mesh
                    self._parts = self._lower = self._indices = self._indptr = None
                held_rows = [rows]  # handed over like the values (SparseSolver)
                rows = None
                if self._kernels is not None:  # compressed columns
                    self._factor = SparseSolver(
                        None, direct, columns=(vals, held_rows, third, P.shape[1])
                    )
                else:  # triplets
                    self._factor = SparseSolver(None, direct,
                                                (vals, held_rows, third, P.shape[1]))  # fmt: skip
                del held_rows, third
                if lean:
                    self._assemble_compiled()
                if not compiled:
                    K = self.stiffness_matrix(thickness_mm)
            elif not sup.selection:  # a sector's tie: P^T K P formed lean (_factor_tied)
                held = [K]
                K = None
                self._factor = self._factor_tied(held, direct)
                if not compiled:
                    K = self.stiffness_matrix(thickness_mm)
            else:
                self._factor = SparseSolver((P.T @ K.tocsr() @ P).tocsr(), direct)
            q = self._factor.solve(b)
        if self._q is not None:
            self._before = (self._t_q, self._q)
        self._q, self._t_q = q, float(thickness_mm)
        u = sup.ubar + P @ q
        times["factorise_solve"] = time.perf_counter() - t1
        # internal force = force applied by the supports
        rx = _reactions(K @ u if K is not None else self._matvec(thickness_mm, u), sup, st)
        K = None  # not held beside the stress gradients
        t2 = time.perf_counter()
        peaks = self.peak_stresses(u, float(thickness_mm))
        times["stress"] = time.perf_counter() - t2
        times["total"] = sum(times.values())
        if self._multigrid:
            solver = f"multigrid (pcg, P1 coarse: {self._coarse_name})"
        else:
            solver = self._factor.name if iterations == 0 else f"pcg ({self._factor.name})"
        return _result(sup, rx, peaks, self.n_dofs, self._t.shape[0], self._n_layers, st,
                       solver, times, iterations)  # fmt: skip

    def _matvec(self, thickness_mm: float, x: np.ndarray) -> np.ndarray:
        """K(t) @ x, (ndof,) N for x (ndof,) mm: from the parts without K(t)'s blocks on the
        compiled path (``parts_matvec``: ``stiffness_matrix(t) @ x`` bit for bit), else by
        forming K(t)."""
        if self._kernels is None:
            return self.stiffness_matrix(thickness_mm) @ x
        s = float(thickness_mm) / self.reference_thickness_mm
        return self._kernels.parts_matvec(self._indptr, self._indices, self._parts, s,
                                          np.asarray(x, dtype=float))  # fmt: skip

    def _factor_tied(self, held: list, which: str) -> SparseSolver:
        """The factor of P^T K P when P ties DOFs (a sector: cut B = R cut A), K (ndof, ndof)
        N/mm handed over in the one-element list ``held`` (emptied: its only reference, so
        that each intermediate goes as soon as the next is made). Only the reduced lower
        triangle reaches the solver, in compressed columns; with the compiled assembly and
        ``lean_factorisation`` the stiffness parts and the block pattern are dropped while
        it factorises and made again after, as on the selection path (docs/solid3d.md, "The
        sector solve": the SEA spring's check 1.69 GB with everything held, see there)."""
        P = self._sup.P
        vals, rows, colptr = self._tied_lower(held)
        lean = self._kernels is not None and self.settings.lean_factorisation
        if lean:  # made again below, bit for bit, from the mesh
            self._parts = self._lower = self._indices = self._indptr = None
        held_rows = [rows]  # handed over like the values: freed once CHOLMOD copied them
        del rows
        try:
            return SparseSolver(None, which, columns=(vals, held_rows, colptr, P.shape[1]))
        finally:
            del held_rows, colptr
            if lean:
                self._assemble_compiled()

    def _start(self, thickness_mm: float) -> np.ndarray:
        """Where an iterative solve at ``thickness_mm`` starts, (nq,) mm: the last answer, or
        with two earlier answers at distinct thicknesses their line through it (q changes
        smoothly with the depth: the ST correction's third check, ~0.02 mm from the second
        and ~0.4 mm from the first, starts ~2 decades nearer; the stopping rule, a
        residual relative to |b|, is the same, so only the iterations change)."""
        q = self._q
        if self._before is not None:
            t0, q0 = self._before
            t1 = self._t_q
            if t1 != t0 and abs(float(thickness_mm) - t1) <= abs(t1 - t0):
                return q + ((float(thickness_mm) - t1) / (t1 - t0)) * (q - q0)
        return q

    def _tied_lower(self, held: list) -> tuple[list, np.ndarray, np.ndarray]:
        """The lower triangle of P^T K P (nq, nq) N/mm in compressed columns, rows sorted in
        each column, for a P that ties DOFs (a sector), K (ndof, ndof) handed over in the
        one-element list ``held`` (emptied, so that each intermediate goes once the next is
        made). Returns ([values (nnz,)], rows (nnz,) int32, column pointers (nq + 1,)).

        Made by slices of ``_TIED_COLUMNS`` columns, each slice's lower part kept: the whole
        product P^T K P (both triangles, in two formats) and K P were each held at once
        before (0.4 GB above the model on the SEA spring's sector, the check's peak on a
        plain install). Each entry is the same sum in the same order as the whole product's
        (a column of K P and of P^T (K P) reads only that column of P), so the values are
        the same bit for bit (tests/fea/test_solid3d_sector.py)."""
        P = self._sup.P
        nq = P.shape[1]
        A = held.pop().tocsr()
        Pc, PT = P.tocsc(), P.T.tocsr()
        data, index, counts = [], [], [np.zeros(1, dtype=np.int64)]
        for c0 in range(0, nq, _TIED_COLUMNS):
            c1 = min(nq, c0 + _TIED_COLUMNS)
            B = (PT @ (A @ Pc[:, c0:c1])).tocsc()  # columns c0..c1 of P^T K P
            B = sp.tril(B, k=-c0, format="csc")  # rows >= the global column
            B.sort_indices()
            data.append(B.data)
            index.append(B.indices)
            counts.append(np.diff(B.indptr).astype(np.int64))
            del B
        del A, Pc, PT
        colptr = np.cumsum(np.concatenate(counts))
        vals = [np.concatenate(data)]
        del data
        rows = np.concatenate(index).astype(np.int32, copy=False)
        return vals, rows, colptr

    def _coarse_prolongation(self) -> sp.csr_matrix:
        """The P1 functions of the tetrahedral mesh as P2 vectors on the unknowns, (nfree,
        ncoarse): a vertex node takes its vertex's value, an edge node the mean of its two
        ends' (the P2 interpolation of a linear function is exact, so the coarse space is
        the P1 subspace of the P2 one and P^T K P is the P1 stiffness with the same supports).
        Coarse unknowns: the free DOFs of the vertices, in order. Made once per model.

        A sector (P ties cut B to cut A turned): the coarse unknowns are the unknowns of the
        vertices, the P1 function's vertex values those P gives them (cut B's: R times cut
        A's), and an edge node's value the mean of its ends'; on the mesh that repeats, cut
        B's edge nodes then take R times cut A's, so the coarse space is the tied P1
        functions, a subspace of the tied P2 ones (:meth:`_tied_prolongation`)."""
        if self._coarse_P is None and not self._sup.selection:
            self._coarse_P = self._tied_prolongation()
        if self._coarse_P is None:
            tm = self._tmesh
            nv = tm.p.shape[1]
            t = np.ascontiguousarray(tm.t.T, dtype=np.int64)
            ends = self._kernels._EDGES
            a, b = t[:, ends[:, 0]], t[:, ends[:, 1]]
            # the edges in p2_tables' order: edge node nv + k joins ends[k]
            uniq = np.unique((np.minimum(a, b) * nv + np.maximum(a, b)).ravel())
            del a, b, t
            lo, hi = np.divmod(uniq, nv)
            free = self._sup.free
            node, comp = np.divmod(free, 3)
            coarse = np.full(3 * nv, -1, dtype=np.int64)  # vertex DOF -> coarse unknown
            vfree = free[free < 3 * nv]
            coarse[vfree] = np.arange(vfree.size)
            vert = np.flatnonzero(node < nv)
            edge = np.flatnonzero(node >= nv)
            e = node[edge] - nv
            rows = [vert, edge, edge]
            cols = [coarse[free[vert]], coarse[3 * lo[e] + comp[edge]],
                    coarse[3 * hi[e] + comp[edge]]]  # fmt: skip
            w = [np.ones(vert.size), np.full(edge.size, 0.5), np.full(edge.size, 0.5)]
            r, c, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
            keep = c >= 0  # a held end contributes nothing (its coarse value is 0)
            self._coarse_P = sp.csr_matrix((w[keep], (r[keep], c[keep])),
                                           shape=(free.size, vfree.size))  # fmt: skip
        return self._coarse_P

    def _tied_prolongation(self) -> sp.csr_matrix:
        """:meth:`_coarse_prolongation` of a sector, (nq, ncoarse): the P1 functions with the
        tie, as P2 vectors on the unknowns. Coarse unknowns: the unknowns whose DOF is at a
        vertex, in order."""
        tm, sup = self._tmesh, self._sup
        nv = tm.p.shape[1]
        t = np.ascontiguousarray(tm.t.T, dtype=np.int64)
        ends = self._kernels._EDGES
        a, b = t[:, ends[:, 0]], t[:, ends[:, 1]]
        uniq = np.unique((np.minimum(a, b) * nv + np.maximum(a, b)).ravel())
        del a, b, t
        lo, hi = np.divmod(uniq, nv)
        free = sup.free
        vcols = np.flatnonzero(free < 3 * nv)  # the unknowns at vertices: coarse unknowns
        # the vertices' DOFs (3 nv,) from the coarse unknowns, as P ties them
        Pv = sup.P[: 3 * nv][:, vcols].tocsr()
        if sup.P[: 3 * nv].nnz != Pv.nnz:
            raise FeaError("a vertex of the sector is tied to an edge node: not a periodic mesh")
        node, comp = np.divmod(free, 3)
        vert = np.flatnonzero(node < nv)
        edge = np.flatnonzero(node >= nv)
        e = node[edge] - nv
        # each unknown's value from the vertex DOFs (nq, 3 nv): a vertex its own, an edge
        # node the mean of its ends'
        rows = np.concatenate([vert, edge, edge])
        cols = np.concatenate([free[vert], 3 * lo[e] + comp[edge], 3 * hi[e] + comp[edge]])
        w = np.concatenate([np.ones(vert.size), np.full(2 * edge.size, 0.5)])
        Iv = sp.csr_matrix((w, (rows, cols)), shape=(free.size, 3 * nv))
        Pc = (Iv @ Pv).tocsr()
        Pc.eliminate_zeros()
        return Pc

    def _solve_multigrid(self, lower: list, b: np.ndarray, lean: bool,
                         x0: np.ndarray | None = None,
                         thickness_mm: float = math.nan) -> tuple[np.ndarray, int]:  # fmt: skip
        """q (nfree,) mm with K q = b (nfree,) N by conjugate gradients preconditioned with a
        two-grid cycle; ``lower``: a one-element list holding the reduced lower triangle,
        (values (nnz,) N/mm, rows (nnz,), column pointers (nfree + 1,) int64) in compressed
        columns (``self._lower``'s pattern, or a sector's :meth:`_tied_lower`; emptied, so
        that it goes once the whole matrix is made); ``lean``: the lower triangle's pattern
        is dropped too (the caller makes it again); ``x0`` (nfree,) mm: where CG starts
        (zeros when None); ``thickness_mm``: the model's thickness, mm (the coarse factor is kept
        for a later thickness within ``multigrid_coarse_reuse`` of it; NaN: never kept).
        Returns (q, iterations).

        The cycle: a symmetric Gauss-Seidel sweep (forward, then backward) on the P2 unknowns,
        the residual's P1 part solved directly (:meth:`_coarse_prolongation`; ~56k unknowns
        on the SEA spring's 375k, its factor < 0.1 GB), another symmetric sweep: a
        symmetric positive definite preconditioner. The whole matrix is held once, in
        compressed rows (both triangles, int32 columns: 0.33 GB there), and never factorised.
        A later thickness starts from the previous answers (:meth:`_start`).
        """
        st, kern = self.settings, self._kernels
        vals, rows, colptr = lower.pop()
        indptr, indices, data = kern.full_from_lower(colptr, rows, vals)
        del vals
        n = colptr.size - 1
        del rows, colptr
        if lean:
            self._lower = None
        A = sp.csr_matrix((data, indices, indptr), shape=(n, n), copy=False)
        diagonal = A.diagonal()
        # where each row's diagonal sits: the pre-smoothing's sweep from zero reads the
        # strictly lower part only (smooth_from_zero)
        dpos = kern.diagonal_positions(indptr, indices)
        if n and (dpos.min() < 0 or diagonal.min() <= 0.0):
            raise SparseSolver._not_definite("a diagonal entry <= 0")
        Pc = self._coarse_prolongation()
        t = thickness_mm
        if self._coarse is not None and abs(t / self._coarse[0] - 1.0) <= st.multigrid_coarse_reuse:
            coarse = self._coarse[1]  # a thickness near the factorised one's: kept
        else:
            self._coarse = None  # the old factor goes before the new one is made
            # P^T A P by slices of rows: the product A P of the whole (~15 M entries on the
            # SEA spring) is never formed at once
            Ac = sp.csr_matrix((Pc.shape[1], Pc.shape[1]))
            for s in range(0, n, 32_768):
                Ac = Ac + Pc[s : s + 32_768].T @ (A[s : s + 32_768] @ Pc)
            coarse = SparseSolver(Ac.tocsc(), "auto")
            del Ac
            self._coarse = (t, coarse)
        self._coarse_name = coarse.name

        def cycle(r: np.ndarray) -> np.ndarray:
            x = np.empty_like(r)
            kern.smooth_from_zero(indptr, indices, data, dpos, diagonal, r, x)
            x += Pc @ coarse.solve(Pc.T @ (r - A @ x))
            kern.symmetric_gauss_seidel(indptr, indices, data, diagonal, r, x)
            return x

        x0 = np.zeros(n) if x0 is None else x0
        q, iterations, ok = _pcg(lambda x: A @ x, b, cycle, x0, st.multigrid_rtol,
                                 st.multigrid_max_iterations)  # fmt: skip
        if not ok:
            raise FeaError(
                f"the multigrid solver did not reach a residual of {st.multigrid_rtol:g} in "
                f"{st.multigrid_max_iterations} iterations; use Solid3DSettings(solver="
                "'cholmod') or 'qdldl' (a direct factorisation)"
            )
        return q, iterations

    @property
    def kernels(self) -> ModuleType | None:
        """The compiled kernels this model assembles with (fea/_solid3d_kernels.py: pass them
        to :func:`p2_tables` for its node tables), or None on the numpy path."""
        return self._kernels

    def peak_stresses(self, u: np.ndarray, thickness_mm: float) -> tuple:
        """The peak von Mises stresses of the displacement ``u`` (n_dofs,) mm of this model
        extruded to ``thickness_mm`` (:func:`peak_stresses`). The stress gradient tables are made
        anew when the lean factorisation dropped them (``_p2_gradients``, ~0.1 s) and not kept."""
        zs = float(thickness_mm) / self.reference_thickness_mm
        stretch = np.array([1.0, 1.0, zs])
        if self._G is None:
            G, _, Gc = _p2_gradients(self._tmesh, self._kernels)
        else:
            G, Gc = self._G, self._Gc
        return peak_stresses(u, self._dofs, G, self._xyz_qp * stretch[:, None, None], Gc,
                             self._t, self._p * stretch[:, None], self._mask, self._lam,
                             self._mu, z_scale=zs, kernels=self._kernels,
                             merge=self._vertex_class)  # fmt: skip

    def last_field(self, thickness_mm: float) -> dict | None:
        """The last :meth:`solve`'s state on the P2 tetrahedra, for best_3d.vtu (no new solve:
        the model keeps its last unknowns). ``thickness_mm`` must be that solve's thickness.

        Returns
        -------
        dict or None (None before any solve)
            ``points_mm`` (n_nodes, 3) mm, the P2 nodes of the mesh extruded to
            ``thickness_mm`` (vertices first, then one per edge); ``tetra10`` (nel, 10) int, each
            element's nodes in VTK's quadratic-tetrahedron order (4 vertices, then the edges
            01, 12, 02, 03, 13, 23); ``displacement_mm`` (n_nodes, 3) mm;
            ``von_mises_MPa`` (n_nodes,) MPa: at a vertex the P2 stress at the corners of its
            tetrahedra averaged (the value :meth:`peak_stresses` reports as the nodal peak), at
            an edge node the mean of its two vertices; ``stress_counted`` (n_nodes,) bool, the
            vertices of the elements the peak counts (edge nodes: both ends counted);
            ``symmetric`` bool, the half model z >= 0 (mirror about z = 0 for the whole part).
        """
        if self._q is None:
            return None
        zs = float(thickness_mm) / self.reference_thickness_mm
        u = self._sup.ubar + self._sup.P @ self._q
        if self._G is None:
            _, _, Gc = _p2_gradients(self._tmesh, self._kernels)
        else:
            Gc = self._Gc
        ue = u.reshape(-1, 3)
        if self._kernels is not None:
            vc = self._kernels.von_mises(u, self._dofs, Gc, self._mu, zs)  # (nel, 4)
        else:
            g = np.einsum("eac,eqaj->eqcj", ue[self._dofs], Gc)
            g[..., 2] /= zs
            vc = _von_mises(g, self._lam, self._mu)
        del Gc
        t, nv = self._t, self._p.shape[1]
        vertex = _vertex_average(vc, t, nv, self._vertex_class)
        counted_v = np.zeros(nv, dtype=bool)
        cls = self._vertex_class
        if cls is None:
            counted_v[t[self._mask].ravel()] = True
        else:  # a cut vertex is counted as the whole part's one vertex there (peak_stresses)
            counted_v[cls[t[self._mask].ravel()]] = True
            counted_v = counted_v[cls]
        n_nodes = ue.shape[0]
        ends = np.empty((n_nodes - nv, 2), dtype=np.int64)  # each edge node's two vertices
        for j, (a, b) in enumerate(((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))):
            ends[self._dofs[:, 4 + j] - nv] = np.column_stack([t[:, a], t[:, b]])
        p = self._p.T * np.array([1.0, 1.0, zs])
        field = {
            "points_mm": np.vstack([p, 0.5 * (p[ends[:, 0]] + p[ends[:, 1]])]),
            "tetra10": np.asarray(self._dofs, dtype=np.int64),
            "displacement_mm": ue,
            "von_mises_MPa": np.concatenate([vertex, vertex[ends].mean(axis=1)]),
            "stress_counted": np.concatenate([counted_v, counted_v[ends].all(axis=1)]),
            "symmetric": bool(self.settings.symmetric),
        }
        if self.periodic is not None:  # the whole part: the sector's n turned copies
            field = self.periodic.whole_field(field)
        return field

    def compare_with_plane_stress(self, thickness_mm: float) -> dict:
        """:func:`compare_with_plane_stress` at ``thickness_mm`` with this model's 3D solve.

        The linear plane-stress solve is made at the first thickness compared only: the plane
        model at thickness t is the one at t0 with its stiffness times t / t0 (every element
        matrix carries the thickness as a factor), so with displacement supports its answer
        is the same displacement, the reaction times t / t0 and the same stresses; a later
        thickness scales that (the same figures as a solve at t to its round-off, ~1e-10;
        tests/fea/test_solid3d_model.py). ``time_2d_s`` is 0 then (no solve made).
        """
        plane = self._plane
        fresh = plane is None
        if plane is None:
            # before the 3D solve: its memory (the plane model and its factor) is then not
            # on top of the 3D factor's (the SEA check's peak; docs/solid3d.md, "Memory")
            plane = self._plane = _plane_linear(self.comparison_mesh, self.material,
                                                thickness_mm, self.clamp, self.drive,
                                                self.stress_ignore)  # fmt: skip
        r3 = self.solve(thickness_mm)
        return _ratios(plane, float(thickness_mm), r3, fresh)


# --------------------------------------------------------------------------------------------
# Entry points


def check_solid3d(
    outline: Polygon,
    thickness_mm: float,
    material: Material,
    clamp: Clamp,
    drive: Drive,
    max_edge_mm: float,
    refine: Refinement | None = None,
    settings: Solid3DSettings = Solid3DSettings(),
    stress_ignore: BaseGeometry | None = None,
) -> Solid3DResult:
    """Mesh a planar outline and run :func:`solve_solid3d` on it extruded to its thickness.

    Parameters
    ----------
    outline : shapely Polygon, mm
    thickness_mm : float, mm
    material : Material
    clamp, drive : the plane-stress supports (:class:`~fea.plane_stress.Clamp`,
        :class:`~fea.plane_stress.Rotate` or :class:`~fea.plane_stress.Translate`).
    max_edge_mm : float, mm — plane mesh size; refine : as :func:`fea.mesh.mesh_polygon`.
    settings : Solid3DSettings
    stress_ignore : shapely geometry, optional

    Returns
    -------
    Solid3DResult (``times_s["mesh"]`` includes the plane mesh)
    """
    t0 = time.perf_counter()
    mesh = mesh_polygon(outline, max_edge_mm, refine=refine)
    t_plane = time.perf_counter() - t0
    res = solve_solid3d(mesh, material, thickness_mm, clamp, drive, settings, stress_ignore)
    res.times_s["mesh"] += t_plane
    res.times_s["total"] += t_plane
    return res


def compare_with_plane_stress(
    mesh: TriMesh,
    material: Material,
    thickness_mm: float,
    clamp: Clamp,
    drive: Drive,
    settings: Solid3DSettings = Solid3DSettings(),
    stress_ignore: BaseGeometry | None = None,
) -> dict:
    """The linear 3D and linear plane-stress answers on the same plane mesh, and their ratios.

    Returns
    -------
    dict
        ``stiffness_3d`` / ``stiffness_2d`` (N·mm/rad or N/mm), ``stiffness_ratio`` (3D / 2D),
        ``peak_nodal_stress_3d_MPa`` / ``..._2d_MPa`` and ``peak_stress_ratio`` (vertex-averaged
        peaks, as plane stress reports them), ``solid3d`` (:meth:`Solid3DResult.summary`),
        ``time_2d_s``.
    """
    r3 = solve_solid3d(mesh, material, thickness_mm, clamp, drive, settings, stress_ignore)
    return _compare(mesh, material, thickness_mm, clamp, drive, stress_ignore, r3)


def _compare(mesh, material, thickness_mm, clamp, drive, stress_ignore, r3) -> dict:
    """compare_with_plane_stress's record from the 3D answer ``r3``: the 2D solve and ratios."""
    plane = _plane_linear(mesh, material, thickness_mm, clamp, drive, stress_ignore)
    return _ratios(plane, float(thickness_mm), r3, True)


def _plane_linear(mesh, material, thickness_mm, clamp, drive, stress_ignore) -> dict:
    """The linear plane-stress answer on ``mesh`` at ``thickness_mm`` mm, one step of the
    drive: ``thickness_mm``, ``stiffness_2d`` (N·mm/rad or N/mm), the vertex-averaged and
    quadrature-point peaks (MPa), ``n_dofs_2d`` and ``time_2d_s`` (s)."""
    from dataclasses import replace

    from flexopt.fea.plane_stress import solve_plane_stress

    d2 = replace(drive, steps=1)
    r2 = solve_plane_stress(mesh, material, thickness_mm, clamp, d2, "linear",
                            stress_ignore=stress_ignore)  # fmt: skip
    if isinstance(drive, Rotate):
        k2 = float(r2.torque_Nmm[-1] / drive.max_rad)
    else:
        k2 = float(r2.force_N[-1] / drive.max_mm)
    return {
        "thickness_mm": float(thickness_mm),
        "stiffness_2d": k2,
        "peak_nodal_stress_2d_MPa": float(r2.peak_nodal_stress_MPa[-1]),
        "peak_stress_qp_2d_MPa": float(r2.peak_stress_MPa[-1]),
        "n_dofs_2d": int(r2.n_dofs),
        "time_2d_s": float(r2.solve_time_s),
    }


def _ratios(plane: dict, thickness_mm: float, r3, solved: bool) -> dict:
    """compare_with_plane_stress's record: the 3D answer ``r3`` at ``thickness_mm`` against the
    plane-stress answer ``plane`` (:func:`_plane_linear`, at its own thickness: the stiffness
    is proportional to the thickness, the stresses independent of it); ``solved``: whether
    the plane answer was solved for this record (else its time is not counted again)."""
    k2 = plane["stiffness_2d"]
    if thickness_mm != plane["thickness_mm"]:
        k2 = k2 * thickness_mm / plane["thickness_mm"]
    s2 = plane["peak_nodal_stress_2d_MPa"]
    return {
        "stiffness_2d": k2,
        "stiffness_3d": r3.stiffness,
        "stiffness_ratio": r3.stiffness / k2,
        "peak_nodal_stress_2d_MPa": s2,
        "peak_nodal_stress_3d_MPa": r3.peak_nodal_stress_MPa,
        "peak_stress_ratio": r3.peak_nodal_stress_MPa / s2,
        "peak_stress_qp_2d_MPa": plane["peak_stress_qp_2d_MPa"],
        "peak_stress_qp_3d_MPa": r3.peak_stress_MPa,
        "n_dofs_2d": plane["n_dofs_2d"],
        "time_2d_s": plane["time_2d_s"] if solved else 0.0,
        "solid3d": r3.summary(),
    }


# --------------------------------------------------------------------------------------------
# Mesh convergence of a plane-stress peak stress


def _reentrant_corner(
    outline: Polygon, xy: np.ndarray, within_mm: float, held: BaseGeometry | None = None
) -> dict | None:
    """The re-entrant (reflex) outline vertex nearest ``xy`` within ``within_mm``, or None.

    ``held`` (clamped or driven geometry): a vertex on it gets ``"held": True``; Williams'
    traction-free exponent does not apply there (a held corner over 180 degrees is singular
    too, with another exponent).

    Returns ``{"xy_mm": [x, y], "interior_angle_deg": a, "distance_mm": d}``; a > 180.
    """
    from shapely.geometry.polygon import orient

    poly = orient(outline, sign=1.0)  # exterior counter-clockwise, holes clockwise
    best = None
    for ring in [poly.exterior, *poly.interiors]:
        p = np.asarray(ring.coords)[:-1]
        e_in = p - np.roll(p, 1, axis=0)
        e_out = np.roll(p, -1, axis=0) - p
        cross = e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0]
        dot = np.einsum("ij,ij->i", e_in, e_out)
        # With the material on the left of every ring, a right turn (cross < 0) is re-entrant.
        turn = np.degrees(np.arctan2(cross, dot))
        d = np.linalg.norm(p - xy, axis=1)
        for k in np.flatnonzero((turn < -1e-9) & (d <= within_mm)):
            if best is None or d[k] < best["distance_mm"]:
                best = {
                    "xy_mm": [float(v) for v in p[k]],
                    "interior_angle_deg": float(180.0 - turn[k]),
                    "distance_mm": float(d[k]),
                    "held": bool(
                        held is not None and shapely.distance(held, shapely.Point(p[k])) <= 1e-6
                    ),
                }
    return best


def _williams_growth(angle_deg: float) -> float:
    """Rise of a corner's peak stress per halving of the mesh, %, from Williams' exponent.

    Near a traction-free corner of interior angle ``a`` (> 180 deg) the symmetric stress field
    goes as r**(lambda - 1), lambda the root in (1/2, 1) of sin(lambda a) + lambda sin(a) = 0
    (Williams 1952), so a mesh half the size sees a peak 2**(1 - lambda) times larger. For
    a = 180 + d degrees, lambda ~ 1 - 2 d / 180: a 1.4 degree facet gives ~1.1 % per halving.
    """
    from scipy.optimize import brentq

    a = math.radians(angle_deg)
    if not math.pi < a < 2.0 * math.pi:
        return 0.0
    lam = brentq(lambda x: math.sin(x * a) + x * math.sin(a), 0.5, 1.0 - 1e-12)
    return (2.0 ** (1.0 - lam) - 1.0) * 100.0


def _first_row_value(drive: Drive) -> float:
    """The drive's value at its first row (rad or mm): its maximum over its steps."""
    return float(drive.max_rad if isinstance(drive, Rotate) else drive.max_mm) / drive.steps


def converge_peak_stress(
    outline: Polygon,
    thickness_mm: float,
    material: Material,
    clamp: Clamp,
    drive: Drive,
    max_edge_mm: float,
    refine: list | None = None,
    stress_ignore: BaseGeometry | None = None,
    kinematics: Literal["linear", "nonlinear"] = "linear",
    rtol: float = 0.01,
    min_rounds: int = 3,
    max_rounds: int = 6,
    region_factor: float = 4.0,
    warm_start: bool = True,
) -> dict:
    """Refine the plane mesh around the peak von Mises stress until the peak moves < ``rtol``.

    Each round meshes the outline (:func:`fea.mesh.mesh_polygon`, with ``refine`` plus every
    earlier round's region), solves plane stress at the drive's full value and finds the
    vertex-averaged peak (``peak_nodal_stress_MPa``, what the studies report). The next round
    halves the element size in a disc of ``region_factor`` local element sizes around it. A
    peak that keeps rising sits on a stress singularity of the polygonal outline: a re-entrant
    corner, which is named with its interior angle (a facet of a sampled arc turns by a degree
    or two; a fillet or a finer sampling of the curve removes it).

    Parameters
    ----------
    outline : shapely Polygon, mm
    thickness_mm : float, mm
    material : Material
    clamp, drive : as :func:`fea.plane_stress.solve_plane_stress` (drive ``steps`` is used for
        the nonlinear solve)
    max_edge_mm : float, mm — the plane mesh size; refine : (geometry, size mm) regions
    stress_ignore : shapely geometry, optional — left out of the peak (rigid pads, hubs)
    kinematics : "linear" or "nonlinear"
    rtol : float — convergence: |peak_k - peak_(k-1)| <= rtol peak_k
    min_rounds : int — meshes solved at least (3: two halvings; a weak singularity such as a
        1.4 degree facet moves the peak by < 1 % per halving and only the trend shows it)
    max_rounds : int — meshes solved at most
    region_factor : float — radius of the refined disc in local element sizes
    warm_start : bool — nonlinear: each refined round's Newton starts from the last round's
        first converged row interpolated onto its mesh
        (:func:`fea.plane_stress.interpolate_displacement`), the first round's from the
        second-order perturbation solution (:meth:`fea.plane_stress.PlaneStressModel.
        series_predictor`), instead of from the linearised step at rest. The same
        equilibrium to Newton's tolerance (``rtol_residual``), in fewer iterations: the meshes
        differ only in the refined disc (docs/solid3d.md, "Peak stress under mesh
        refinement"). Where Newton fails from it, the row is solved from rest as without it
        (:meth:`fea.plane_stress.PlaneStressModel.solve`).

    Returns
    -------
    dict
        ``converged`` (bool), ``status`` ("converged", "converged, at a re-entrant vertex
        ...", "not converged (re-entrant corner)" or "not converged"), ``last_two_MPa``
        [previous, last], ``peaks_MPa`` and ``local_edge_mm`` per round, ``peak_xy_mm``
        (last), ``corner`` (the re-entrant vertex near the peak, or None), ``triangles`` per
        round, ``newton_iterations`` per round (all rows), ``guess`` per round ("none",
        "used" or "failed: <why>"), ``cholesky_failures`` per round (tangents Cholesky
        refused: 0 on a stable path), ``time_s``.
    """
    from flexopt.fea.plane_stress import (
        MeshNumbering,
        PlaneStressModel,
        interpolate_displacement,
    )

    t0 = time.perf_counter()
    regions = list(refine or [])
    # Every round's mesh tests its triangles against every region (mesh_polygon's size field):
    # prepared (GEOS's indexed form, made once here, in place) the same exact predicate takes
    # about half the time (~0.6 s CPU of a refined SEA mesh's ~1.2 s); the meshes are the same.
    shapely.prepare([g for g, _ in regions if isinstance(g, BaseGeometry)])
    peaks, sizes, tris, iterations, guesses, refused = [], [], [], [], [], []
    xy = np.zeros(2)
    converged = False
    warm = warm_start and kinematics == "nonlinear"
    # (the last model's numbering, its first converged row (N,) mm): the next round's start;
    # the model itself (tables, matrices, factor: ~0.4 GB on the SEA spring's meshes) is freed
    last = None
    for _ in range(max(3, int(min_rounds), int(max_rounds))):
        mesh = mesh_polygon(outline, max_edge_mm, refine=regions or None)
        model = PlaneStressModel(mesh, material, thickness_mm, clamp, drive,
                                 stress_ignore=stress_ignore)  # fmt: skip
        guess = None
        if last is not None:
            guess = interpolate_displacement(*last, model)
        elif warm:  # the first round: the second-order perturbation solution of the first row
            odd, even = model.series_predictor(_first_row_value(drive))
            guess = odd + even
        last = None
        res = model.solve(kinematics, guess=guess, keep_states=warm)
        if not res.ok:
            raise FeaError(f"peak-stress convergence: the solve failed ({res.message})")
        if warm and res.row_dofs is not None:
            last = (MeshNumbering.of(model), res.row_dofs[1])
        del model
        iterations.append(int(res.iterations.sum()))
        guesses.append(str(res.extra.get("guess", "none")))
        refused.append(int(res.extra.get("cholesky_failures", 0)))
        peaks.append(float(res.peak_nodal_stress_MPa[-1]))
        xy = np.asarray(res.peak_nodal_stress_xy_mm[-1], dtype=float)
        tris.append(mesh.n_triangles)
        # Local element size: the longest edge of the triangles at the peak's vertex.
        k = int(np.argmin(np.linalg.norm(mesh.points - xy, axis=1)))
        at = np.any(mesh.triangles == k, axis=1)
        h = float(mesh.edge_lengths_mm[at].max())
        sizes.append(h)
        if len(peaks) >= max(3, min_rounds):
            d_last, d_prev = abs(peaks[-1] - peaks[-2]), abs(peaks[-2] - peaks[-3])
            # Small and shrinking: a converging P2 sequence moves ~4x less per halving; a
            # singular one moves by about the same fraction every time (see _williams_growth).
            if d_last <= rtol * abs(peaks[-1]) and (
                d_last <= 0.5 * d_prev or d_last <= 0.1 * rtol * abs(peaks[-1])
            ):
                converged = True
                break
            # A finely sampled curve: the peak sits on a facet vertex turning by a fraction of
            # a degree, whose (Williams) creep per halving is a fraction of rtol. Two moves in
            # a row below half of rtol and no more than that creep (+ a quarter of rtol for the
            # smooth field's own, shrinking, error) is the smooth part's value to rtol.
            near = _reentrant_corner(outline, xy, 2.0 * h + 1e-9)
            creep = _williams_growth(near["interior_angle_deg"]) / 100.0 if near else 0.0
            if (
                near is not None
                and creep <= 0.5 * rtol
                and max(d_last, d_prev) <= (creep + 0.25 * rtol) * abs(peaks[-1])
            ):
                converged = True
                break
        disc = shapely.Point(*xy).buffer(region_factor * h)
        shapely.prepare(disc)
        regions.append((disc, 0.5 * h))
    held = shapely.union(clamp.region, drive.region)
    corner = _reentrant_corner(outline, xy, 2.0 * sizes[-1] + 1e-9, held)
    if corner is not None and not corner["held"]:
        corner["growth_per_halving_percent"] = _williams_growth(corner["interior_angle_deg"])
    if corner is not None and not converged:
        if corner["interior_angle_deg"] < 185.0:
            corner["fix"] = (
                "a facet vertex of a sampled curve: sample the curve so that no facet turns by "
                "more than ~0.5 deg there (the peak then converges)"
            )
        else:
            # resolved by the unrefined mesh, so the study's own mesh sees a finite peak
            corner["fix"] = (
                f"a sharp corner: round it with a fillet of radius >= {2.0 * sizes[0]:.2g} mm "
                "(two element sizes of the unrefined mesh there)"
            )
    if converged and corner is None:
        status = "converged"
    elif converged:
        # A corner a little over 180 degrees is a weak singularity: the peak rises by a
        # fraction of a percent per halving, without bound, so "converged" is per halving only.
        growth = corner.get("growth_per_halving_percent", 0.0)
        status = (
            f"converged to {rtol:.0%} per halving, at a re-entrant vertex (interior angle "
            f"{corner['interior_angle_deg']:.2f} deg): a weak singularity, the value creeps "
            f"up by ~{growth:.2f} % per further halving; a smoother outline there removes it"
        )
    elif corner is not None:
        status = "not converged (re-entrant corner)"
    else:
        status = "not converged"
    return {
        "converged": converged,
        "status": status,
        "last_two_MPa": peaks[-2:],
        "peaks_MPa": peaks,
        "local_edge_mm": sizes,
        "triangles": tris,
        "newton_iterations": iterations,
        "guess": guesses,
        "cholesky_failures": refused,
        "peak_xy_mm": [float(v) for v in xy],
        "corner": corner,
        "time_s": time.perf_counter() - t0,
    }


# --------------------------------------------------------------------------------------------
# Correcting a plane-stress design for its 3D stiffness (issue 15 item 2)


def band_reachable(stiffnesses: Sequence[float], tolerance_percent: float) -> dict:
    """Whether some common scale puts every stiffness within ``±tolerance`` of one target.

    A thickness change scales every direction's stiffness alike (plane stress: exactly; 3D:
    with the slowly varying 3D/2D ratio), so their spread is fixed: all fit within the band
    iff ``k_max / k_min <= (1 + tol) / (1 - tol)``, and the scale that leaves the most room
    puts their mean ``(k_max + k_min) / 2`` on the target.

    Parameters
    ----------
    stiffnesses : (n,) float, any unit — one per load direction.
    tolerance_percent : float, percent.

    Returns
    -------
    dict — ``reachable`` (bool), ``spread_percent`` ``(k_max / k_min - 1) 100``,
    ``max_spread_percent`` (the largest spread the band admits), ``half_spread_percent``
    (each direction's error once the mean is on target, percent).
    """
    k = np.asarray(stiffnesses, dtype=float)
    tol = float(tolerance_percent) / 100.0
    if k.size == 0 or not np.all(np.isfinite(k)) or np.any(k <= 0) or not 0 < tol < 1:
        raise FeaError("band_reachable needs positive finite stiffnesses and 0 < tolerance < 100 %")
    spread = float(k.max() / k.min())
    limit = (1.0 + tol) / (1.0 - tol)
    return {
        "reachable": bool(spread <= limit),
        "spread_percent": (spread - 1.0) * 100.0,
        "max_spread_percent": (limit - 1.0) * 100.0,
        "half_spread_percent": float((k.max() - k.min()) / (k.max() + k.min())) * 100.0,
    }


def correction_needed(
    stiffness_ratio: float, tolerance_percent: float, max_fraction_of_tolerance: float
) -> bool:
    """True when the 3D/2D stiffness ratio is off 1 by more than the set share of the band."""
    if not (stiffness_ratio > 0 and tolerance_percent > 0 and max_fraction_of_tolerance > 0):
        raise FeaError("correction_needed needs a positive ratio, tolerance and fraction")
    return abs(stiffness_ratio - 1.0) > max_fraction_of_tolerance * tolerance_percent / 100.0


def corrected_thickness_mm(
    thickness_mm: float, stiffnesses_3d: Sequence[float], target: float
) -> float:
    """The thickness whose 3D stiffness (mean of the directions) is the target.

    ``ST × target / mean(K_3D)``: in plane stress the stiffness is proportional to the
    thickness, and the 3D/2D ratio (measured at ``thickness_mm``) is taken as constant over the
    step; it grows slowly with the depth (docs/solid3d.md), so a re-check in 3D measures what
    is left. Units: mm, and the stiffnesses in the target's unit.
    """
    k = np.asarray(stiffnesses_3d, dtype=float)
    if not (thickness_mm > 0 and target > 0 and k.size and np.all(k > 0)):
        raise FeaError("corrected_thickness_mm needs a positive thickness, target and stiffnesses")
    return float(thickness_mm) * float(target) / float(k.mean())


def correct_thickness_3d(
    check: Callable[[float], dict],
    thickness_mm: float,
    target: float,
    tolerance_percent: float,
    max_fraction_of_tolerance: float = 0.25,
    max_checks: int = 3,
) -> dict:
    """Calibrate a design's thickness on 3D checks until each direction meets the band in 3D.

    The first check (at ``thickness_mm``, the plane-stress answer) measures the 3D/2D
    stiffness ratio. When it is off 1 by more than ``max_fraction_of_tolerance`` of the band
    (:func:`correction_needed`), the thickness becomes :func:`corrected_thickness_mm` and is
    checked in 3D again; a further step follows from the last check while a direction is out of
    the band or the mean is off the target by more than that share, the band is reachable
    (:func:`band_reachable`) and fewer than ``max_checks`` checks were made. The answer is
    always the last *checked* thickness.

    Parameters
    ----------
    check : callable(thickness_mm) -> dict with ``stiffness_3d`` (direction -> 3D stiffness,
        in the target's unit) and ``stiffness_ratio_3d_2d``; anything else it holds is kept.
    thickness_mm : float, mm — the plane-stress design's thickness.
    target : float — the stiffness target; tolerance_percent : float, percent.
    max_fraction_of_tolerance : float — see above (0.25: correct a ratio off 1 by > 0.5 % of
        a ±2 % band).
    max_checks : int — 3D checks at most (>= 2: the calibration and its re-check).

    Returns
    -------
    dict — ``corrected`` (bool), ``thickness_before_mm``, ``thickness_after_mm``, ``checks``
    (each check's dict with ``thickness_mm``, ``stiffness_error_percent`` per direction,
    ``mean_error_percent`` and ``in_band``), ``in_band`` (the last check), ``band``
    (:func:`band_reachable` of the last check), ``stopped`` (why the loop ended).
    """
    if max_checks < 2:
        raise FeaError(f"max_checks = {max_checks}: need at least 2 (calibration and re-check)")
    tol = float(tolerance_percent)
    share = float(max_fraction_of_tolerance) * tol

    def run(st: float) -> dict:
        c = dict(check(st))
        k = {d: float(v) for d, v in c["stiffness_3d"].items()}
        err = {d: (v / target - 1.0) * 100.0 for d, v in k.items()}
        mean = float(np.mean(list(k.values())))
        c.update(
            thickness_mm=float(st),
            stiffness_error_percent=err,
            mean_error_percent=(mean / target - 1.0) * 100.0,
            in_band=bool(all(abs(e) <= tol for e in err.values())),
        )
        return c

    st = float(thickness_mm)
    checks = [run(st)]
    needed = correction_needed(checks[0]["stiffness_ratio_3d_2d"], tol, max_fraction_of_tolerance)
    stopped = "ratio within the set share of the band: no correction"
    while needed:
        last = checks[-1]
        band = band_reachable(list(last["stiffness_3d"].values()), tol)
        if len(checks) > 1:
            if last["in_band"] and abs(last["mean_error_percent"]) <= share:
                stopped = "in the band and centred"
                break
            if not band["reachable"]:
                stopped = (
                    f"the directions' spread ({band['spread_percent']:.2f} %) exceeds what the "
                    f"±{tol:g} % band admits ({band['max_spread_percent']:.2f} %): no thickness "
                    "meets it; centred as well as it can be"
                )
                break
        if len(checks) >= max_checks:
            stopped = f"max_checks = {max_checks} reached"
            break
        st = corrected_thickness_mm(st, list(last["stiffness_3d"].values()), target)
        checks.append(run(st))
    last = checks[-1]
    return {
        "corrected": bool(needed),
        "thickness_before_mm": float(thickness_mm),
        "thickness_after_mm": float(last["thickness_mm"]),
        "checks": checks,
        "in_band": bool(last["in_band"]),
        "band": band_reachable(list(last["stiffness_3d"].values()), tol),
        "stopped": stopped,
    }
