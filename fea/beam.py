"""Geometrically exact (Simo–Reissner) planar beam on scikit-fem.

The beam is a line mesh in arc length ``s`` (a scikit-fem :class:`~skfem.MeshLine`) carrying three
quadratic (P2) fields: the displacements ``u(s), v(s)`` of the centreline and the section rotation
``phi(s)``. With ``X'(s) = (cos theta0, sin theta0)`` the unit tangent of the reference centreline
and ``theta = theta0 + phi`` the current section angle, the strains are measured in the section
frame (Reissner 1972, Simo & Vu-Quoc 1986)::

    Gamma1 = cos(theta) x1' + sin(theta) x2' - 1      axial strain
    Gamma2 = -sin(theta) x1' + cos(theta) x2'         shear strain
    kappa  = phi'                                     change of curvature
    x' = X' + (u', v')

Because ``theta0`` enters only through ``X'``, a straight, a kinked-polyline (``phi`` continuous
across the kink keeps the kink angle) and a circular-arc reference (``theta0`` linear in ``s``) are
all exact, stress-free references. The stored energy is
``1/2 int (EA Gamma1^2 + k G A Gamma2^2 + EI kappa^2) ds`` with ``A = b t(s)``,
``I = b t(s)^3 / 12`` and the thickness ``t`` linear in arc length between profile points.

Discretisation and speed
------------------------
* P2 elements with the 2-point Gauss rule passed explicitly (uniform reduced integration: rank
  sufficient, 2 points x 3 strains = 6 = 9 DOFs - 3 rigid modes, and free of shear and membrane
  locking; a silently raised rule would lock).
* The reference-element tables (shape values and derivatives at the Gauss points and at the stress
  sampling points) come from scikit-fem once per process and are rescaled by the element lengths;
  the mesh is a :class:`skfem.MeshLine` in ``s``. DOFs are numbered node by node along ``s``
  (scikit-fem numbers the P2 interior DOFs after all vertex DOFs, which would destroy the band), so
  the tangent is banded with half-bandwidth 8 and is factorised by banded Cholesky (LAPACK
  ``dpbtrf``) where it is positive definite, by banded LU with partial pivoting (``dgbsv``)
  where it is not (see :func:`_solve_constrained`).
* Two implementations of the same formulation (``BeamSettings.kernel``, env FLEXOPT_BEAM_KERNEL):
  the compiled kernel (numba, fea/_beam_kernels.py, the default) runs the element integrals, the
  band assembly, the banded Cholesky solve (a port of LAPACK's dpbtf2/dpbtrs, also the stability
  check) with the banded LU with partial pivoting (dgbtf2/dgbtrs) as its fallback, and the whole
  tracing loop below as machine code; the numpy reference path batches the element integrals over
  elements x Gauss points, assembles with one ``np.bincount`` into band storage and calls LAPACK
  through scipy. Both make the same decisions
  and agree to round-off (tests/fea/test_beam_kernels.py); the numpy path is the fallback where
  numba does not import.

Loading
-------
The ``start`` end (first profile point) is clamped or pinned. The ``end`` (last point) is driven
along ``direction`` under displacement or force control; its motion perpendicular to ``direction``
and its rotation are each held or free. The end node's two translations are expressed in the
(direction, normal) frame, so the driven and the transverse components are plain DOFs. Under
displacement control the increment is imposed inside the linear solve (its column of the tangent
moves to the right-hand side), not by jumping the prescribed value and iterating.

Steps are adaptive: each requested step is reached through sub-steps that grow when Newton
converges fast and are cut back when it does not. After two converged states the predictor
extrapolates along the path (secant). Two branch guards keep buckling-type problems on the branch
the geometry selects instead of the mirror image: a converged sub-step is retried smaller when its
increment turned away from the predicted one, or when it led from a stable equilibrium (positive
definite tangent, by banded Cholesky) to an unstable one. Near a bifurcation the sub-steps thus
become as small as the turn of the path needs (the "very small first increments" of the classic
recipe, chosen automatically). A crossing that survives the smallest sub-step is genuine: a perfect
strut pushed past its Euler load stays straight here, on the unstable branch. Every accepted state
is therefore checked, and the rows past such a crossing are flagged (``BeamResponse.stable``,
``unstable``, ``unstable_message``, ``critical_value``), never returned as ordinary results.
Failure to converge is returned as data (``converged`` flags and ``message``), never raised.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from functools import cache, lru_cache
from types import ModuleType
from typing import Literal, NamedTuple, Protocol

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.geometry.profile import BeamProfile
from scipy.linalg.lapack import dgbsv, dpbtrf, dpbtrs
from skfem import CellBasis, ElementLineP2, MeshLine
from skfem.quadrature import get_quadrature
from skfem.refdom import RefLine

__all__ = [
    "EndDrive",
    "BeamSettings",
    "BeamResponse",
    "BeamModel",
    "BeamTables",
    "ContactTerms",
    "gauss_rule",
    "reference_tables",
    "solve_beam",
]

log = logging.getLogger(__name__)

#: environment variable choosing the kernel when ``BeamSettings.kernel`` is "auto"
KERNEL_ENV = "FLEXOPT_BEAM_KERNEL"


@dataclass(frozen=True)
class EndDrive:
    """How the ``end`` of the beam (last centreline point) is driven.

    Attributes
    ----------
    control : "displacement" (``max_value`` in mm) or "force" (``max_value`` in N).
    direction : (2,) float — the driven component is along it (normalised internally).
    max_value : float, mm or N — value reached at the last step.
    steps : int — number of response rows after the undeformed row; row k is at k*max/steps.
    rotation : "fixed" (end section rotation held at 0) or "free".
    transverse : "fixed" (end motion perpendicular to ``direction`` held at 0) or "free".
    """

    control: Literal["displacement", "force"] = "displacement"
    direction: tuple[float, float] = (1.0, 0.0)
    max_value: float = 1.0
    steps: int = 20
    rotation: Literal["fixed", "free"] = "fixed"
    transverse: Literal["fixed", "free"] = "fixed"

    def __post_init__(self) -> None:
        if self.control not in ("displacement", "force"):
            raise FeaError(f"control = {self.control!r}; use 'displacement' or 'force'")
        for name in ("rotation", "transverse"):
            if getattr(self, name) not in ("fixed", "free"):
                raise FeaError(f"{name} = {getattr(self, name)!r}; use 'fixed' or 'free'")
        d = np.asarray(self.direction, dtype=float)
        if d.shape != (2,) or not np.all(np.isfinite(d)) or np.hypot(*d) < 1e-12:
            raise FeaError(f"direction = {self.direction!r} must be a non-zero [dx, dy] pair")
        if int(self.steps) < 1:
            raise FeaError(f"steps = {self.steps} must be >= 1")
        if not np.isfinite(self.max_value):
            raise FeaError(f"max_value = {self.max_value} must be finite")


@dataclass(frozen=True)
class BeamSettings:
    """Discretisation and solver tolerances (one place for each number, with its reason).

    Attributes
    ----------
    n_elements : target number of P2 elements, spread over the segments by length (at least one
        per segment, so the count can exceed the target for profiles with many short segments).
    shear_factor : k of k G A; 5/6 for a rectangular section.
    rtol : Newton stops when the free-DOF residual norm is below rtol x the force scale (load or
        reactions); 1e-8 leaves the force error (~1e-8 relative) to the mesh, not the iteration.
    max_iterations : Newton iterations per sub-step before the sub-step is cut back; quadratic
        convergence needs 3-6, so 25 only tolerates a poor predictor.
    first_substep : first sub-step as a fraction of the first requested step. A whole step is
        safe: where the path turns sharply (a buckling-type start) the branch guards below reject
        the sub-step and the retries become as small as the turn needs, so the start follows the
        branch the geometry selects (tested on paper 003's beam, which buckles at 0.03 mm).
    min_substep : smallest sub-step as a fraction of a requested step before giving up.
    fast_iterations : a sub-step converged in at most this many iterations doubles the next one.
    dtol : a Newton correction below dtol x max(L, 1) is round-off: 1e-12 is 10^4 x machine
        epsilon, far below any mesh error.
    predictor : "secant" extrapolates the last two converged states (fewer iterations, stays on
        the branch); "tangent" solves the linearised problem from the last state.
    min_critical_substep : a sub-step that leads from a stable state (positive definite tangent)
        to an unstable one crossed a bifurcation or limit point; it is retried smaller until it is
        this fraction of a requested step, then the crossing is accepted as genuine.
    min_path_cosine : a converged sub-step whose increment makes an angle with the predicted
        increment whose cosine is below this is retried smaller (it jumped to another branch);
        0.8 (37 degrees) keeps sub-steps small where the path turns sharply, as at buckling.
    max_rotation_step : largest section rotation (rad) one Newton correction may apply; larger ones
        are scaled down (see _newton). 0.5 rad is a large step on any smooth path.
    kernel : "auto", "numba" or "numpy" — which implementation runs (same physics, same
        decisions, answers equal to round-off; docs/beam.md "Kernels"). "numba" is the compiled
        kernel (fea/_beam_kernels.py), "numpy" the pure-numpy reference; "auto" reads the
        environment variable FLEXOPT_BEAM_KERNEL (numba | numpy) and otherwise takes numba. When
        numba cannot be imported, numba falls back to numpy (logged at debug level);
        ``BeamModel.kernel`` says which one runs.
    """

    n_elements: int = 20
    shear_factor: float = 5.0 / 6.0
    rtol: float = 1e-8
    max_iterations: int = 25
    first_substep: float = 1.0
    min_substep: float = 1e-5
    fast_iterations: int = 5
    dtol: float = 1e-12
    max_rotation_step: float = 0.5
    predictor: Literal["secant", "tangent"] = "secant"
    min_critical_substep: float = 1e-3
    min_path_cosine: float = 0.8
    kernel: Literal["auto", "numba", "numpy"] = "auto"


@dataclass(frozen=True)
class BeamResponse:
    """One row per requested step (row 0 = undeformed). Arrays have shape (steps + 1,) unless noted.

    Attributes
    ----------
    displacement_mm : driven end displacement projected on ``direction``.
    force_N : force applied at the driven end, projected on ``direction``.
    transverse_displacement_mm, transverse_force_N : the same, along the normal (``direction``
        turned 90 degrees counter-clockwise).
    moment_Nmm : moment applied at the driven end (counter-clockwise positive).
    end_rotation_rad : rotation of the driven end section.
    peak_stress_MPa : max over the beam of |N|/A + |M| c / I.
    peak_stress_s_mm : arc length where it occurs.
    iterations : int — Newton iterations spent reaching each row (all sub-steps).
    converged : bool — the row is an equilibrium state.
    shapes_mm : (steps + 1, n_nodes, 2) float, mm — deformed positions of the mesh nodes (P2
        vertices and mid-points, ordered along ``s``).
    ok : every row converged.
    message : why not, when not ``ok``.
    extra : n_elements, n_dofs, substeps, kernel ("numba" or "numpy": which one ran).
    stable : bool — the row is a stable equilibrium: the tangent with the supports and the
        prescribed DOFs eliminated is positive definite there and at every sub-step since the
        previous row (False for rows that did not converge). None when not assessed (a stand-in
        response built without it).
    unstable : some converged row is not stable: the path passed a bifurcation or limit point (a
        straight strut pushed past its Euler load stays straight in the solver, on the unstable
        branch; the rows from there on are not what a real, imperfect beam does).
    unstable_message : names the step and the driven value (mm or N) where stability was lost, and
        how many rows are unstable; empty when ``unstable`` is False.
    critical_value : driven value (mm or N) at which stability was first lost, bracketed to
        ``min_critical_substep`` of a step; NaN when it never was.
    contact : the contact outputs (a :class:`fea.stops.ContactResponse`: force per stop, closing
        gap, rows in contact, contact points) of a solve with rigid stops
        (:func:`fea.stops.solve_with_stops`); None without stops.
    rotations_rad : (steps + 1, n_nodes) float, rad — the nodes' section rotation per row (NaN
        on rows that did not converge; with ``shapes_mm`` the whole state, which
        fea/beam_fields.py turns into fibre stresses per node); None from a stand-in response.
    """

    displacement_mm: np.ndarray
    force_N: np.ndarray
    transverse_displacement_mm: np.ndarray
    transverse_force_N: np.ndarray
    moment_Nmm: np.ndarray
    end_rotation_rad: np.ndarray
    peak_stress_MPa: np.ndarray
    peak_stress_s_mm: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    shapes_mm: np.ndarray
    ok: bool
    message: str = ""
    extra: dict = field(default_factory=dict)
    stable: np.ndarray | None = None
    unstable: bool = False
    unstable_message: str = ""
    critical_value: float = float("nan")
    contact: object | None = None
    rotations_rad: np.ndarray | None = None


class ContactTerms(Protocol):
    """Extra forces and tangent added to every assembly of a solve (rigid stops, fea/stops.py).

    ``add(u, frame, r, ab)``: ``u`` (n_dofs,) physical DOFs [mm, rad] (the end node's
    translations in x, y); ``frame`` (2, 2) the drive's (direction, normal) axes, the generalised
    numbering of the end node's translations; adds in place to ``r`` (n_dofs,) [N, N mm] and to
    ``ab`` (2 kl + ku + 1, n_dofs), ``A[i, j] = ab[kl + ku + i - j, j]`` (kl = ku = 8), both in
    generalised DOFs. The added tangent must be the derivative of the added force (symmetric: the
    Hessian of a potential) and couple no DOFs farther apart than the band.

    ``active``: a value that changes when the set of pairs acting in the last ``add`` changes
    (Newton backtracks a correction that changed it and raised the residual).
    """

    active: object

    def add(self, u: np.ndarray, frame: np.ndarray, r: np.ndarray, ab: np.ndarray) -> None: ...


# -- kernel selection -----------------------------------------------------------------------------


_KERNELS = ("numba", "numpy")


@cache
def _compiled() -> ModuleType | None:
    """fea._beam_kernels, or None when numba cannot be imported (the numpy path then runs)."""
    try:
        from flexopt.fea import _beam_kernels
    except Exception as exc:  # ImportError, or a numba that fails on this platform's LLVM
        log.debug("numba beam kernel unavailable (%s: %s); using numpy", type(exc).__name__, exc)
        return None
    return _beam_kernels


def resolve_kernel(setting: str) -> str:
    """The kernel that runs for ``BeamSettings.kernel`` = ``setting`` ("numba" or "numpy")."""
    choice = setting
    if setting == "auto":
        choice = os.environ.get(KERNEL_ENV, "").strip().lower() or "numba"
        if choice not in _KERNELS:
            raise FeaError(
                f"{KERNEL_ENV} = {os.environ[KERNEL_ENV]!r}; use one of {', '.join(_KERNELS)}"
            )
    elif setting not in _KERNELS:
        raise FeaError(f"kernel = {setting!r}; use 'auto', 'numba' or 'numpy'")
    if choice == "numba" and _compiled() is None:
        return "numpy"
    return choice


# -- reference element tables (computed by scikit-fem once per process) -------------------------

#: half-bandwidth of the node-by-node numbering: an element couples 3 nodes x 3 fields
_BAND = 8


@cache
def reference_tables(points: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Shape values and d/dxi of the P2 line element at reference points ``xi`` in [0, 1].

    Returns ``(N, dN)``, each (n_points, 3), local nodes ordered (start, middle, end) along ``s``.
    scikit-fem orders the local DOFs (vertex 0, vertex 1, interior); the reorder makes the local
    index equal the offset along ``s``.
    """
    xi = np.array([points])
    basis = CellBasis(
        MeshLine(np.array([0.0, 1.0])),
        ElementLineP2(),
        quadrature=(xi, np.full(xi.shape[1], 1.0 / xi.shape[1])),
    )
    order = (0, 2, 1)
    n = np.array([np.asarray(basis.basis[i][0])[0] for i in order]).T
    dn = np.array([basis.basis[i][0].grad[0, 0] for i in order]).T
    return n, dn


@cache
def gauss_rule() -> tuple[np.ndarray, np.ndarray]:
    """2-point Gauss rule on [0, 1], asked for explicitly (intorder 3 -> 2 points).

    Made once per process (scikit-fem computes it with numpy's leggauss, ~0.3 ms, which was
    paid by every model, i.e. every design of a run); read-only, as it is shared.
    """
    x, w = get_quadrature(RefLine, 3)
    assert x.shape[1] == 2, "the P2 beam needs exactly the 2-point rule (reduced integration)"
    x, w = np.array(x[0]), np.array(w)
    x.setflags(write=False)
    w.setflags(write=False)
    return x, w


# -- the model ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BeamTables:
    """The tables of a :class:`BeamModel` that do not depend on the deformation: what its solver
    integrates with, for code that builds its own operators on the same mesh (the sensitivities
    of fea/beam_sensitivity.py, the coupled beams of fea/mechanism.py). The model's own arrays,
    not copies: read them, never write them.

    E elements, Q = 2 Gauss points per element, 3 nodes per element (P2), 3 stress sampling
    points per element (both ends and the middle), 3 DOFs per node (u, v in mm, phi in rad).

    Attributes
    ----------
    N : (Q, 3) float — the shape functions at the Gauss points.
    NgT : (3, Q) float — ``N`` transposed, C-ordered (the rotation at the Gauss points is
        ``phi_e @ NgT``).
    dN : (E, Q, 3) float, 1/mm — their derivatives by arc length at the Gauss points.
    w : (E, Q) float, mm — the quadrature weights.
    theta0, cos_theta0, sin_theta0 : (E, Q) float, rad and 1 — the reference tangent angle at
        the Gauss points, its cosine and sine.
    EA, kGA, EI : (E, Q) float, N, N and N mm^2 — the section stiffnesses at the Gauss points.
    gauss_to_samples : (Q, 3) float — the linear extrapolation of Gauss-point values to the
        sampling points (``values_g @ gauss_to_samples``).
    dN_samples : (E, 3, 3) float, 1/mm — the shape functions' derivatives at the sampling
        points (sampling point, node).
    EI_samples : (E, 3) float, N mm^2 — the bending stiffness at the sampling points.
    section_modulus_samples : (E, 3) float, mm^3 — the section modulus b t^2 / 6 there.
    s_samples : (E, 3) float, mm — the arc length of the sampling points.
    edofs : (E, 9) int — the global DOFs of each element (node-major: u, v, phi per node).
    edofs3 : (E, 3, 3) int — the same as (element, node, field).
    """

    N: np.ndarray
    NgT: np.ndarray
    dN: np.ndarray
    w: np.ndarray
    theta0: np.ndarray
    cos_theta0: np.ndarray
    sin_theta0: np.ndarray
    EA: np.ndarray
    kGA: np.ndarray
    EI: np.ndarray
    gauss_to_samples: np.ndarray
    dN_samples: np.ndarray
    EI_samples: np.ndarray
    section_modulus_samples: np.ndarray
    s_samples: np.ndarray
    edofs: np.ndarray
    edofs3: np.ndarray


class BeamModel:
    """A meshed planar beam, ready to trace responses under different drives.

    Everything that does not depend on the deformation (mesh, section properties at the Gauss
    points, reference angles, assembly indices) is computed here once.

    Parameters
    ----------
    profile : BeamProfile — centreline, thickness (mm) and width (mm).
    material : Material — E_MPa, nu (yield_MPa is not used by the solver).
    start : "clamped" or "pinned" — support of the first profile point.
    settings : BeamSettings.
    """

    def __init__(
        self,
        profile: BeamProfile,
        material: Material,
        start: Literal["clamped", "pinned"] = "clamped",
        settings: BeamSettings = BeamSettings(),
    ) -> None:
        if start not in ("clamped", "pinned"):
            raise FeaError(f"start = {start!r}; use 'clamped' or 'pinned'")
        if int(settings.n_elements) < 1:
            raise FeaError(f"n_elements = {settings.n_elements} must be >= 1")
        #: "numba" (compiled, fea/_beam_kernels.py) or "numpy" (the reference): which one runs
        self.kernel = resolve_kernel(settings.kernel)
        self.profile = profile
        self.material = material
        self.start = start
        self.settings = settings

        seg_len = profile.segment_lengths_mm
        s_pts = profile.arc_length_mm
        n_seg = np.maximum(1, np.rint(settings.n_elements * seg_len / seg_len.sum())).astype(int)
        s_vert = np.concatenate(
            [np.linspace(s_pts[i], s_pts[i + 1], n_seg[i] + 1)[:-1] for i in range(len(seg_len))]
            + [s_pts[-1:]]
        )
        self.mesh = MeshLine(s_vert)
        seg_of_el = np.repeat(np.arange(len(seg_len)), n_seg)
        n_el = len(seg_of_el)
        self.n_elements = n_el
        self.n_nodes = 2 * n_el + 1
        self.n_dofs = 3 * self.n_nodes
        h = np.diff(s_vert)
        self._h = h

        xg, wg = gauss_rule()
        ng, dng = reference_tables(tuple(xg))
        self._N = ng  # (Q, 3)
        self._dN = dng[None, :, :] / h[:, None, None]  # (E, Q, 3), 1/mm
        self._w = wg[None, :] * h[:, None]  # (E, Q), mm
        s_gauss = s_vert[:-1, None] + xg[None, :] * h[:, None]  # (E, Q), mm

        # Reference tangent angle at the Gauss points: constant on straight segments, linear on arcs
        theta_seg = profile.segment_start_angles_rad()
        kappa_seg = profile.curvature_per_mm
        self._theta0 = theta_seg[seg_of_el, None] + kappa_seg[seg_of_el, None] * (
            s_gauss - s_pts[seg_of_el, None]
        )
        self._c0 = np.cos(self._theta0)
        self._s0 = np.sin(self._theta0)

        b = profile.width_mm
        t_g = np.interp(s_gauss, s_pts, profile.thickness_mm)
        E, G = material.E_MPa, material.G_MPa
        self._D = np.stack(
            [E * b * t_g, settings.shear_factor * G * b * t_g, E * b * t_g**3 / 12.0], axis=-1
        )  # (E, Q, 3): EA [N], kGA [N], EI [N mm^2]
        length = profile.length_mm
        # Force below which residuals are meaningless: a tiny fraction of the bending force level
        # EI/L^2, and the round-off of the axial force EA * strain (1e3 machine epsilons).
        self._force_floor = max(
            1e-9 * float(self._D[..., 2].max()) / length**2,
            2e-13 * float(self._D[..., 0].max()),
        )
        # DOF scale for the correction test: translations ~ L, rotations ~ 1 (max of both).
        self._length_scale = max(length, 1.0)
        self._ea, self._kga, self._ei = (np.ascontiguousarray(self._D[..., i]) for i in range(3))
        self._dk = self._ea - self._kga
        if self.kernel == "numpy":
            self._precompute_kernels(ng)

        # Stress sampling at both element ends and the middle (the bending moment is largest at
        # supports and kinks, which are element ends; Gauss points alone would miss the peak).
        xs = np.array([0.0, 0.5, 1.0])
        _, dns = reference_tables(tuple(xs))
        # linear extrapolation from the two Gauss points to the sampling points, (Q, 3)
        xa, xb = xg
        self._gauss_to_samples = np.array([(xs - xb) / (xa - xb), (xs - xa) / (xb - xa)])
        self._dNs = dns[None, :, :] / h[:, None, None]
        s_samp = s_vert[:-1, None] + xs[None, :] * h[:, None]
        self._s_samp = s_samp
        t_s = np.interp(s_samp, s_pts, profile.thickness_mm)
        self._EI_s = E * b * t_s**3 / 12.0
        self._section_modulus_s = b * t_s**2 / 6.0

        # Node positions along s (vertices and mid-points) on the reference centreline.
        s_nodes = np.empty(self.n_nodes)
        s_nodes[0::2] = s_vert
        s_nodes[1::2] = 0.5 * (s_vert[:-1] + s_vert[1:])
        self.s_nodes = s_nodes
        self.reference_nodes_mm = _centreline_points(profile, s_nodes)

        # Assembly indices: element e owns DOFs 6e .. 6e+8 (3 nodes x (u, v, phi)).
        self._edofs = 6 * np.arange(n_el)[:, None] + np.arange(9)[None, :]  # (E, 9)
        self._edofs3 = self._edofs.reshape(n_el, 3, 3)
        kl = ku = _BAND
        self._ldab = 2 * kl + ku + 1
        rows = self._edofs[:, :, None]
        cols = self._edofs[:, None, :]
        # Band storage is kept Fortran-ordered (what LAPACK reads, so f2py does not copy it): the
        # flat index of A[i, j] = ab[kl + ku + i - j, j] is j * ldab + kl + ku + i - j.
        self._band_index = (cols * self._ldab + kl + ku + rows - cols).ravel()
        if self.kernel == "numba":
            self._geo, self._sgeo = self._kernel_geometry()

    # ---------------------------------------------------------------- public tables and operators

    @property
    def tables(self) -> BeamTables:
        """The mesh tables the solver integrates with (:class:`BeamTables`; the model's own
        arrays, read-only by contract)."""
        return BeamTables(
            N=self._N,
            NgT=self._NgT if hasattr(self, "_NgT") else np.ascontiguousarray(self._N.T),
            dN=self._dN,
            w=self._w,
            theta0=self._theta0,
            cos_theta0=self._c0,
            sin_theta0=self._s0,
            EA=self._ea,
            kGA=self._kga,
            EI=self._ei,
            gauss_to_samples=self._gauss_to_samples,
            dN_samples=self._dNs,
            EI_samples=self._EI_s,
            section_modulus_samples=self._section_modulus_s,
            s_samples=self._s_samp,
            edofs=self._edofs,
            edofs3=self._edofs3,
        )

    @property
    def residual_map(self) -> np.ndarray:
        """(E, Q * 4, 9) float: the element residual (E, 9) is ``scalars (E, 1, Q * 4) @ map``,
        the four residual scalars per Gauss point of :meth:`_element_arrays` weighted by the
        shape functions and quadrature weights (built on first use for a compiled model)."""
        if not hasattr(self, "_Rmap"):
            self._precompute_kernels(self._N)
        return self._Rmap

    @property
    def force_floor(self) -> float:
        """N: the force below which a residual is round-off (the Newton solver's floor)."""
        return self._force_floor

    def physical(self, q: np.ndarray, frame: np.ndarray) -> np.ndarray:
        """Physical DOFs (n_dofs,) [mm, rad] from generalised ones ``q`` (n_dofs,), whose end-node
        translations are along the rows of ``frame`` (2, 2) (direction, normal)."""
        return self._physical(q, frame)

    def assemble(
        self, q: np.ndarray, frame: np.ndarray, contact: ContactTerms | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Internal force (n_dofs,) [N, N mm] and tangent in LAPACK band storage at generalised
        DOFs ``q`` (n_dofs,): see :meth:`_assemble` for the storage."""
        return self._assemble(q, frame, contact)

    def peak_stress(self, q: np.ndarray) -> tuple[float, float]:
        """Peak |N|/A + |M| c/I (MPa) over the sampling points at physical DOFs ``q``
        (n_dofs,) and its arc length (mm): the stress the solver reports."""
        return self._stress(q)

    def fixed_dofs(self, drive: EndDrive) -> np.ndarray:
        """(n_fixed,) int64, sorted: the held and prescribed DOFs of ``drive`` (generalised
        numbering)."""
        return self._fixed_dofs(drive)

    # ---------------------------------------------------------------- element kernels (batched)

    def _precompute_kernels(self, n_gauss: np.ndarray) -> None:
        """Maps from the per-Gauss-point scalars to element residuals and tangents.

        Every strain row of the B matrix has the form ``a_f dN_k + b_f N_k`` (field f, node k), so
        an element tangent is a sum over Gauss points of products of shape functions weighted by
        six deformation-dependent scalars (see :meth:`_element_arrays`) plus the constant bending
        part ``EI dN_k dN_l``. The weighted products are fixed for a mesh: they are built here once,
        and each call needs one batched matrix product.

        Sets ``_Kmap`` (E, Q * 6, 81), ``_Kbend`` (E, 81), ``_Rmap`` (E, Q * 4, 9) and the work
        buffers of :meth:`_element_arrays` (the numpy path only; the compiled kernel uses
        :meth:`_kernel_geometry`).
        """
        dN, w = self._dN, self._w
        n_el, n_q, _ = dN.shape
        self._rbuf = np.empty((n_el, n_q, 4))
        self._kbuf = np.empty((n_el, n_q, 6))
        N = np.broadcast_to(n_gauss[None], dN.shape)
        dd = dN[..., :, None] * dN[..., None, :] * w[..., None, None]  # (E, Q, k, l)
        dn = dN[..., :, None] * N[..., None, :] * w[..., None, None]
        nn = N[..., :, None] * N[..., None, :] * w[..., None, None]
        U, V, P = 0, 1, 2
        K = np.zeros((n_el, n_q, 6, 3, 3, 3, 3))  # (E, Q, scalar, k, f, l, g)
        K[:, :, 0, :, U, :, U] = dd  # a_uu
        K[:, :, 1, :, U, :, V] = dd  # a_uv
        K[:, :, 1, :, V, :, U] = dd
        K[:, :, 2, :, V, :, V] = dd  # a_vv
        K[:, :, 3, :, U, :, P] = dn  # c_u
        K[:, :, 3, :, P, :, U] = dn.transpose(0, 1, 3, 2)
        K[:, :, 4, :, V, :, P] = dn  # c_v
        K[:, :, 4, :, P, :, V] = dn.transpose(0, 1, 3, 2)
        K[:, :, 5, :, P, :, P] = nn  # p
        self._Kmap = K.reshape(n_el, n_q * 6, 81)
        kb = np.zeros((n_el, 3, 3, 3, 3))
        kb[:, :, P, :, P] = np.einsum("eq,eqkl->ekl", self._D[..., 2], dd)
        self._Kbend = kb.reshape(n_el, 81)
        R = np.zeros((n_el, n_q, 4, 3, 3))  # (E, Q, scalar, k, f)
        R[:, :, 0, :, U] = dN * w[..., None]
        R[:, :, 1, :, V] = dN * w[..., None]
        R[:, :, 2, :, P] = dN * w[..., None]
        R[:, :, 3, :, P] = N * w[..., None]
        self._Rmap = R.reshape(n_el, n_q * 4, 9)
        self._NgT = np.ascontiguousarray(n_gauss.T)  # (3, Q)

    def _kernel_geometry(self) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        """The mesh tables of the compiled kernel (fea/_beam_kernels.py), all float64 C-ordered.

        ``geo``: dN (E, Q, 3) [1/mm], N (Q, 3), dN w and N w (E, Q, 3), the weighted products
        dN_k dN_l w, dN_k N_l w, N_k N_l w (E, Q, 3, 3) [1/mm, 1, mm], the bending block
        sum_Q EI dN_k dN_l w (E, 3, 3) [N mm], theta0, cos theta0, sin theta0 (E, Q), EA, kGA [N]
        and EI [N mm^2] (E, Q): the same numbers :meth:`_precompute_kernels` folds into its maps.
        ``sgeo``: gauss_to_samples (Q, 3), dN at the sampling points (E, 3, 3) [1/mm], EI (E, 3),
        section modulus (E, 3) [mm^3] and arc length (E, 3) [mm] there (see :meth:`_stress`).
        """
        dN, w = self._dN, self._w
        N = np.broadcast_to(self._N[None], dN.shape)
        dd = dN[..., :, None] * dN[..., None, :] * w[..., None, None]
        dn = dN[..., :, None] * N[..., None, :] * w[..., None, None]
        nn = N[..., :, None] * N[..., None, :] * w[..., None, None]
        kbend = np.einsum("eq,eqkl->ekl", self._D[..., 2], dd)
        geo = (
            dN,
            self._N,
            dN * w[..., None],
            N * w[..., None],
            dd,
            dn,
            nn,
            kbend,
            self._theta0,
            self._c0,
            self._s0,
            self._ea,
            self._kga,
            self._ei,
        )
        sgeo = (
            self._gauss_to_samples,
            self._dNs,
            self._EI_s,
            self._section_modulus_s,
            self._s_samp,
        )

        def c(a: np.ndarray) -> np.ndarray:
            # one layout and dtype, so that every model hits the same cached compiled code
            return np.ascontiguousarray(a, dtype=np.float64)

        return tuple(c(a) for a in geo), tuple(c(a) for a in sgeo)

    def _element_arrays(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Element residuals (E, 9) and tangents (E, 9, 9) for physical DOFs ``q`` (n_dofs,).

        With N = EA Gamma1, Q = kGA Gamma2, M = EI kappa and h = 1 + Gamma1, the residual scalars
        are (N c - Q s, N s + Q c) against dN for (u, v), M against dN and N Gamma2 - Q h against
        N for phi; the tangent scalars are the material part B^T D B plus the geometric part
        N d2Gamma1 + Q d2Gamma2::

            a_uu = EA c^2 + kGA s^2,  a_uv = (EA - kGA) c s,  a_vv = EA s^2 + kGA c^2
            c_u  = EA c Gamma2 + kGA s h - N s - Q c
            c_v  = EA s Gamma2 - kGA c h + N c - Q s
            p    = EA Gamma2^2 + kGA h^2 - N h - Q Gamma2
        """
        if not hasattr(self, "_Kmap"):  # a numba model asked for the numpy arrays
            self._precompute_kernels(self._N)
        qe = q[self._edofs3]  # (E, node, field)
        grad = self._dN @ qe  # (E, Q, field): u', v', phi'
        theta = self._theta0 + qe[:, :, 2] @ self._NgT
        c, s = np.cos(theta), np.sin(theta)
        x1 = self._c0 + grad[..., 0]
        x2 = self._s0 + grad[..., 1]
        h1 = c * x1 + s * x2  # 1 + Gamma1
        g2 = c * x2 - s * x1  # Gamma2
        ea, dk = self._ea, self._dk  # EA and EA - kGA
        nf = ea * (h1 - 1.0)  # N
        qf = self._kga * g2  # Q
        rs, ks = self._rbuf, self._kbuf  # (E, Q, 4), (E, Q, 6) work buffers
        np.subtract(nf * c, qf * s, out=rs[..., 0])
        np.add(nf * s, qf * c, out=rs[..., 1])
        np.multiply(self._ei, grad[..., 2], out=rs[..., 2])
        np.subtract(nf * g2, qf * h1, out=rs[..., 3])
        # Tangent scalars, factored with A = EA Gamma2 - Q = (EA - kGA) Gamma2 and
        # B = kGA h - N = EA - (EA - kGA) h; see the docstring.
        dkc2 = dk * (c * c)
        np.add(self._kga, dkc2, out=ks[..., 0])
        np.multiply(dk, c * s, out=ks[..., 1])
        np.subtract(ea, dkc2, out=ks[..., 2])
        A = dk * g2
        B = ea - dk * h1
        np.add(c * A, s * B, out=ks[..., 3])
        np.subtract(s * A, c * B, out=ks[..., 4])
        np.add(g2 * A, h1 * B, out=ks[..., 5])
        n_el = theta.shape[0]
        re = (rs.reshape(n_el, 1, -1) @ self._Rmap).reshape(n_el, 9)
        ke = (ks.reshape(n_el, 1, -1) @ self._Kmap).reshape(n_el, 81)
        ke += self._Kbend
        return re, ke.reshape(n_el, 9, 9)

    # ---------------------------------------------------------------- global operators

    def _physical(self, q: np.ndarray, frame: np.ndarray) -> np.ndarray:
        """Physical DOFs from generalised ones (end-node translations are in ``frame``)."""
        u = q.copy()
        i = self.n_dofs - 3
        u[i : i + 2] = frame.T @ q[i : i + 2]
        return u

    def _assemble(
        self, q: np.ndarray, frame: np.ndarray, contact: ContactTerms | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Internal force (n_dofs,) and tangent in LAPACK band storage, generalised DOFs.

        ``q`` (n_dofs,) generalised DOFs [mm, rad]; ``frame`` (2, 2) the end node's axes. Returns
        ``r`` (n_dofs,) [N, N mm] and ``ab`` (2 kl + ku + 1, n_dofs), Fortran-ordered,
        ``A[i, j] = ab[kl + ku + i - j, j]`` (kl = ku = 8), rows 0..kl-1 zero. ``contact``
        (rigid stops, fea/stops.py) adds its penalty forces and tangent in place.
        """
        if self.kernel == "numba":
            kern = _compiled()
            q = np.ascontiguousarray(q, dtype=np.float64)
            r = np.empty(self.n_dofs)
            abc = np.empty((self.n_dofs, self._ldab))
            u = np.empty(self.n_dofs)
            kern.assemble(q, np.ascontiguousarray(frame, dtype=np.float64), self._geo, u, r, abc)
            if contact is not None:
                contact.add(self._physical(q, frame), frame, r, abc.T)
            return r, abc.T
        re, ke = self._element_arrays(self._physical(q, frame))
        # Rotate the end node's translations of the last element into (direction, normal).
        T = _end_rotation(frame[0, 0], frame[0, 1])
        re[-1] = T.T @ re[-1]
        ke[-1] = T.T @ ke[-1] @ T
        r = np.bincount(self._edofs.ravel(), re.ravel(), minlength=self.n_dofs)
        ab = np.bincount(self._band_index, ke.ravel(), minlength=self._ldab * self.n_dofs)
        ab = ab.reshape(self.n_dofs, self._ldab).T
        if contact is not None:
            contact.add(self._physical(q, frame), frame, r, ab)
        return r, ab

    def _stress(self, q: np.ndarray) -> tuple[float, float]:
        """Peak |N|/A + |M| c/I (MPa) over the sampling points and its arc length (mm).

        The curvature phi' is linear in a P2 element and exact at the sampling points. The axial
        strain is taken at the Gauss points, where reduced integration makes it accurate, and
        extrapolated linearly to the sampling points: evaluated directly at the element ends it
        carries an interpolation artefact (+2.5 % of the stress at 1.5 rad with 20 elements).

        ``q`` (n_dofs,) physical DOFs [mm, rad].
        """
        if self.kernel == "numba":
            sigma, where = _compiled().peak_stress(
                np.ascontiguousarray(q, dtype=np.float64),
                self._geo,
                self._sgeo,
                float(self.material.E_MPa),
            )
            return float(sigma), float(where)
        if not hasattr(self, "_NgT"):  # a numba model asked for the numpy path's tables
            self._precompute_kernels(self._N)
        qe = q[self._edofs3]
        grad = self._dN @ qe
        theta = self._theta0 + qe[:, :, 2] @ self._NgT
        g1 = (
            np.cos(theta) * (self._c0 + grad[..., 0])
            + np.sin(theta) * (self._s0 + grad[..., 1])
            - 1.0
        )
        g1_s = g1 @ self._gauss_to_samples  # (E, 3)
        kappa = np.einsum("eqk,ek->eq", self._dNs, qe[:, :, 2])
        sigma = self.material.E_MPa * np.abs(g1_s) + np.abs(self._EI_s * kappa) / (
            self._section_modulus_s
        )
        k = int(np.argmax(sigma))
        return float(sigma.flat[k]), float(self._s_samp.flat[k])

    # ---------------------------------------------------------------- tracing

    def _frame(self, drive: EndDrive) -> np.ndarray:
        """(2, 2) rows: the generalised end-node axes (direction, normal) in physical x, y."""
        d = np.asarray(drive.direction, dtype=float)
        d = d / np.hypot(*d)
        return np.array([d, [-d[1], d[0]]])

    def _fixed_dofs(self, drive: EndDrive) -> np.ndarray:
        """(n_fixed,) int64, sorted: the held and prescribed DOFs (generalised numbering)."""
        n = self.n_dofs
        fixed = [0, 1] + ([2] if self.start == "clamped" else [])
        if drive.control == "displacement":
            fixed.append(n - 3)
        if drive.transverse == "fixed":
            fixed.append(n - 2)
        if drive.rotation == "fixed":
            fixed.append(n - 1)
        return np.array(sorted(fixed), dtype=np.int64)

    def _constraints(self, drive: EndDrive) -> _Constraints:
        """The held and prescribed DOFs of the supports and of ``drive`` (generalised numbering),
        with the band indices the numpy path zeroes (the compiled path needs only the DOFs)."""
        n = self.n_dofs
        ia = n - 3
        is_disp = drive.control == "displacement"
        fixed = self._fixed_dofs(drive)
        return _Constraints(
            fixed=fixed,
            free=np.setdiff1d(np.arange(n), fixed),
            zero_idx=_band_zero_index(fixed, n, _BAND, _BAND),
            diag_idx=fixed * (3 * _BAND + 1) + 2 * _BAND,
            zero_idx_sym=_sym_band_zero_index(fixed, n, _BAND),
            driven=ia if is_disp else -1,
            loaded=-1 if is_disp else ia,
        )

    def solve(self, drive: EndDrive, contact: ContactTerms | None = None) -> BeamResponse:
        """Trace the response under ``drive``; see :class:`BeamResponse` for the rows.

        ``contact`` (rigid stops: :func:`fea.stops.solve_with_stops` builds it) adds penalty
        contact forces to every assembly; such a solve runs the Python tracing loop below (with
        the compiled element kernel when that is the kernel). Without it, nothing changes.
        """
        if self.kernel == "numba" and contact is None:
            return self._solve_compiled(drive)
        st = self.settings
        n = self.n_dofs
        frame = self._frame(drive)
        ia, it, ir = n - 3, n - 2, n - 1
        is_disp = drive.control == "displacement"
        bc = self._constraints(drive)

        steps = int(drive.steps)
        targets = drive.max_value * np.arange(steps + 1) / steps
        rows = _Rows(steps + 1, self.n_nodes)
        q = np.zeros(n)
        r, ab = self._assemble(q, frame, contact)
        rows.store(0, self, q, r, frame, 0, ia, it, ir)
        stable = _is_positive_definite(ab, bc)
        rows.stable[0] = stable
        # Stability bookkeeping: whether every accepted state since the last row was stable, and
        # the first stable -> unstable crossing (the driven value bracketed by the two states).
        row_stable = stable
        lost: tuple[int, float, float] | None = None  # (row, last stable value, first unstable)

        value = 0.0
        history: list[tuple[float, np.ndarray]] = [(0.0, q.copy())]
        step_size = abs(targets[1] - targets[0])
        h = st.first_substep * step_size
        substeps = 0
        message = ""
        ok = True
        for k in range(1, steps + 1):
            target = targets[k]
            iters_row = 0
            row_stable = True
            direction_sign = np.sign(target - value) or 1.0
            while abs(target - value) > 1e-12 * max(1.0, abs(drive.max_value)):
                inc = direction_sign * min(h, abs(target - value))
                sub = self._newton(q, r, ab, value, value + inc, history, bc, frame, contact)
                iters_row += sub.iterations
                substeps += 1
                is_stable = False
                if sub.converged:
                    is_stable = _is_positive_definite(sub.ab, bc)
                    if stable and not is_stable and abs(inc) > st.min_critical_substep * step_size:
                        # A stable state led to an unstable one: the sub-step crossed a
                        # bifurcation or limit point. Along a displacement-controlled path through
                        # an imperfect structure this means Newton jumped onto the unstable
                        # (perfect) path; retry smaller so the physical path is followed around
                        # its turn. Only a genuine critical point survives the smallest step; the
                        # states past it are flagged unstable (BeamResponse.stable).
                        sub = sub._replace(converged=False, reason="crossed a critical point")
                if sub.converged:
                    if stable and not is_stable and lost is None:
                        lost = (k, value, value + inc)
                    q, r, ab = sub.q, sub.r, sub.ab
                    value += inc
                    stable = is_stable
                    row_stable = row_stable and is_stable
                    history = [*history[-1:], (value, q.copy())]
                    if sub.iterations <= st.fast_iterations:
                        h = min(2.0 * h, step_size)
                    continue
                h = abs(inc) / 4.0
                if h < st.min_substep * step_size:
                    quantity = "displacement_mm" if is_disp else "force_N"
                    message = (
                        f"no convergence at {quantity} = {value + inc:.6g} (last converged "
                        f"{value:.6g}) after cutting the sub-step to {abs(inc):.3g}: {sub.reason}"
                    )
                    ok = False
                    break
                # Restart the secant predictor from the current state after a failure.
                history = history[-1:]
            if not ok:
                break
            rows.store(k, self, q, r, frame, iters_row, ia, it, ir)
            rows.stable[k] = row_stable

        extra = {
            "n_elements": self.n_elements,
            "n_dofs": self.n_dofs,
            "substeps": substeps,
            "kernel": self.kernel,
        }
        return rows.response(ok, message, extra, _stability(rows, lost, is_disp))

    def _solve_compiled(self, drive: EndDrive) -> BeamResponse:
        """:meth:`solve` by the compiled kernel: the whole loop (sub-steps, Newton, branch guards,
        stability checks, row stresses) runs in :func:`fea._beam_kernels.trace`; only the rows'
        bookkeeping and the messages are made here, as :meth:`solve` makes them."""
        st = self.settings
        n = self.n_dofs
        frame = np.ascontiguousarray(self._frame(drive))
        is_disp = drive.control == "displacement"
        ia = n - 3
        steps = int(drive.steps)
        targets = drive.max_value * np.arange(steps + 1) / steps
        fpar = np.array(
            [
                st.rtol,
                st.first_substep,
                st.min_substep,
                st.dtol,
                st.max_rotation_step,
                st.min_critical_substep,
                st.min_path_cosine,
                self._force_floor,
                self._length_scale,
            ],
            dtype=np.float64,
        )
        ipar = np.array(
            [st.max_iterations, st.fast_iterations, 1 if st.predictor == "secant" else 0, 1],
            dtype=np.int64,
        )
        out = _compiled().trace(
            self._geo,
            self._sgeo,
            float(self.material.E_MPa),
            frame,
            self._fixed_dofs(drive),
            ia if is_disp else -1,
            -1 if is_disp else ia,
            targets.astype(np.float64),
            fpar,
            ipar,
        )
        q_rows, r_end, stress, stress_s, iterations, converged, stable, ints, floats = out
        ok = bool(ints[0])
        rows = _Rows(steps + 1, self.n_nodes)
        a = rows.a
        a["displacement_mm"][:] = q_rows[:, n - 3]
        a["transverse_displacement_mm"][:] = q_rows[:, n - 2]
        a["end_rotation_rad"][:] = q_rows[:, n - 1]
        a["force_N"][:] = r_end[:, 0]
        a["transverse_force_N"][:] = r_end[:, 1]
        a["moment_Nmm"][:] = r_end[:, 2]
        a["peak_stress_MPa"][:] = stress
        a["peak_stress_s_mm"][:] = stress_s
        rows.iterations[:] = iterations
        rows.converged[:] = converged
        rows.stable[:] = stable
        # deformed node positions: the end node's translations back to x, y (frame.T @ q_end)
        u = q_rows.copy()
        u[:, n - 3 : n - 1] = q_rows[:, n - 3 : n - 1] @ frame
        done = converged
        rows.shapes[done] = self.reference_nodes_mm + u[done].reshape(-1, self.n_nodes, 3)[..., :2]
        rows.rotations[done] = u[done].reshape(-1, self.n_nodes, 3)[..., 2]
        message = ""
        if not ok:
            value, inc = float(floats[0]), float(floats[1])
            quantity = "displacement_mm" if is_disp else "force_N"
            reason = _REASONS[int(ints[1])].format(max_iterations=st.max_iterations)
            message = (
                f"no convergence at {quantity} = {value + inc:.6g} (last converged "
                f"{value:.6g}) after cutting the sub-step to {abs(inc):.3g}: {reason}"
            )
        lost = None if ints[3] < 0 else (int(ints[3]), float(floats[2]), float(floats[3]))
        extra = {
            "n_elements": self.n_elements,
            "n_dofs": n,
            "substeps": int(ints[2]),
            "kernel": "numba",
        }
        return rows.response(ok, message, extra, _stability(rows, lost, is_disp))

    def _checked(self, q0: np.ndarray, q_pred: np.ndarray, sub: _SubStep) -> _SubStep:
        """Reject a converged sub-step whose increment turned away from the predicted one.

        Near a bifurcation Newton may converge onto the mirror-image branch: the lateral motion,
        which dominates the increment there, then has the opposite sign to the predictor's (set
        by the imperfection or by the path so far). A smaller sub-step keeps to the branch.
        """
        dp = q_pred - q0
        dc = sub.q - q0
        if dp @ dc < self.settings.min_path_cosine * np.sqrt((dp @ dp) * (dc @ dc)):
            return sub._replace(converged=False, reason="the sub-step left the path")
        return sub

    def _is_sane(self, delta: np.ndarray) -> bool:
        """False for a correction only a (numerically) singular tangent produces."""
        # NaN compares False, so one comparison also rejects non-finite corrections
        return bool(np.abs(delta).max() < 1e3 * self._length_scale)

    def _newton(
        self,
        q0: np.ndarray,
        r0: np.ndarray,
        ab0: np.ndarray,
        value0: float,
        value: float,
        history: list[tuple[float, np.ndarray]],
        bc: _Constraints,
        frame: np.ndarray,
        contact: ContactTerms | None = None,
    ) -> _SubStep:
        """One sub-step from the converged state ``q0`` at ``value0`` to ``value``."""
        st = self.settings
        inc = value - value0
        f_ext = np.zeros(self.n_dofs)
        load = 0.0
        if bc.loaded >= 0:
            f_ext[bc.loaded] = value
            load = abs(value)
        fail = _SubStep(q0, None, None, 0, False, "")

        if st.predictor == "secant" and len(history) >= 2 and history[-1][0] != history[-2][0]:
            # Secant predictor along the path.
            (v1, q1), (v2, q2) = history[-2], history[-1]
            q = q2 + (q2 - q1) * (inc / (v2 - v1))
            iters = 0
        else:
            # Tangent predictor: the prescribed increment is imposed inside the linear solve.
            rhs = f_ext - r0
            ab = ab0.copy(order="F")
            if bc.driven >= 0:
                rows, col = _band_column(ab, bc.driven, self.n_dofs, _BAND, _BAND)
                rhs[rows] -= col * inc
            delta, info = _solve_constrained(ab, rhs, bc, inc)
            if info != 0 or not self._is_sane(delta):
                return fail._replace(iterations=1, reason="singular tangent (check the supports)")
            q = q0 + delta
            iters = 1
        q_pred = q
        r, ab = self._assemble(q, frame, contact)

        ref = None
        for _ in range(st.max_iterations):
            res = r - f_ext
            res_free = res[bc.free]
            norm = float(np.sqrt(res_free @ res_free))
            if not np.isfinite(norm):
                return fail._replace(iterations=iters, reason="the residual became NaN or inf")
            # force scale: the reactions, and the applied load under force control (N)
            scale = max(float(np.sqrt(r[bc.fixed] @ r[bc.fixed])), load, self._force_floor)
            if ref is None:
                ref = norm
            if iters > 3 and norm > 1e6 * max(ref, st.rtol * scale):
                return fail._replace(iterations=iters, reason="Newton diverged")
            converged = norm <= st.rtol * scale
            if converged and iters > 0:
                return self._checked(q0, q_pred, _SubStep(q, r, ab, iters, True, ""))
            delta, info = _solve_constrained(ab, -res, bc, 0.0)
            if info != 0 or not self._is_sane(delta):
                return fail._replace(
                    iterations=iters, reason="singular tangent (a mechanism or a limit point)"
                )
            # Damp corrections that turn a section by more than max_rotation_step: far from
            # equilibrium (a poor predictor in a slender beam, EA L^2 / EI ~ 1e5..1e7) a full
            # Newton step can turn sections by radians, towards an equivalent angle 2 pi away or
            # onto another branch; a smooth path never needs such a correction.
            big = np.abs(delta[2::3]).max() / st.max_rotation_step
            if big > 1.0:
                delta = delta / big
            active = None if contact is None else contact.active
            q = q + delta
            iters += 1
            r, ab = self._assemble(q, frame, contact)
            if contact is not None and contact.active != active:
                q, r, ab, delta = self._backtrack(q, r, ab, delta, norm, f_ext, bc, frame, contact)
            # A correction at round-off level means equilibrium to machine precision even when the
            # load is so small that the residual test sits below the round-off of EA * strain.
            if converged or np.abs(delta).max() <= st.dtol * self._length_scale:
                return self._checked(q0, q_pred, _SubStep(q, r, ab, iters, True, ""))
        return fail._replace(
            iterations=iters, reason=f"Newton did not converge in {st.max_iterations} iterations"
        )

    def _backtrack(self, q, r, ab, delta, norm, f_ext, bc, frame, contact):
        """Halve a Newton correction while it raises the free residual norm above ``norm`` (N),
        at most 8 times (then the last one is kept). Only where a correction changed the set of
        active contact pairs: a pair that switches off between two iterates (the linearised gap
        said touching, the new state is just clear) drops the stop's force, and the next full
        correction falls deep into the stop; plain Newton can then cycle on and off. Returns
        ``(q, r, ab, delta)``."""
        for _ in range(8):
            res = (r - f_ext)[bc.free]
            if np.sqrt(res @ res) <= norm:
                break
            delta = 0.5 * delta
            q = q - delta
            r, ab = self._assemble(q, frame, contact)
        return q, r, ab, delta


#: the reasons of a failed sub-step, by the compiled kernel's codes (fea/_beam_kernels.py)
_REASONS = (
    "",
    "singular tangent (check the supports)",
    "the residual became NaN or inf",
    "Newton diverged",
    "singular tangent (a mechanism or a limit point)",
    "Newton did not converge in {max_iterations} iterations",
    "the sub-step left the path",
    "crossed a critical point",
)


class _Constraints(NamedTuple):
    """Constrained DOFs of one solve (generalised numbering)."""

    fixed: np.ndarray  # (n_fixed,) int, held or prescribed DOFs
    free: np.ndarray  # (n_free,) int
    zero_idx: np.ndarray  # flat band indices of the fixed rows and columns
    diag_idx: np.ndarray  # flat band indices of their diagonal entries
    zero_idx_sym: np.ndarray  # the same in upper symmetric band storage
    driven: int  # DOF under displacement control, or -1
    loaded: int  # DOF under force control, or -1


class _SubStep(NamedTuple):
    """Outcome of one Newton sub-step."""

    q: np.ndarray
    r: np.ndarray | None  # internal force at q
    ab: np.ndarray | None  # band tangent at q
    iterations: int
    converged: bool
    reason: str


class _Rows:
    """Collects the response rows."""

    def __init__(self, n_rows: int, n_nodes: int) -> None:
        nan = np.full(n_rows, np.nan)
        self.a = {
            k: nan.copy()
            for k in (
                "displacement_mm",
                "force_N",
                "transverse_displacement_mm",
                "transverse_force_N",
                "moment_Nmm",
                "end_rotation_rad",
                "peak_stress_MPa",
                "peak_stress_s_mm",
            )
        }
        self.iterations = np.zeros(n_rows, dtype=int)
        self.converged = np.zeros(n_rows, dtype=bool)
        self.stable = np.zeros(n_rows, dtype=bool)
        self.shapes = np.full((n_rows, n_nodes, 2), np.nan)
        self.rotations = np.full((n_rows, n_nodes), np.nan)

    def store(self, k, model: BeamModel, q, r, frame, iters, ia, it, ir) -> None:
        a = self.a
        a["displacement_mm"][k] = q[ia]
        a["transverse_displacement_mm"][k] = q[it]
        a["end_rotation_rad"][k] = q[ir]
        a["force_N"][k] = r[ia]
        a["transverse_force_N"][k] = r[it]
        a["moment_Nmm"][k] = r[ir]
        u = model._physical(q, frame)
        a["peak_stress_MPa"][k], a["peak_stress_s_mm"][k] = model._stress(u)
        self.iterations[k] = iters
        self.converged[k] = True
        self.shapes[k] = model.reference_nodes_mm + u.reshape(-1, 3)[:, :2]
        self.rotations[k] = u.reshape(-1, 3)[:, 2]

    def response(
        self, ok: bool, message: str, extra: dict, stability: tuple[bool, str, float]
    ) -> BeamResponse:
        unstable, unstable_message, critical = stability
        return BeamResponse(
            **self.a,
            iterations=self.iterations,
            converged=self.converged,
            shapes_mm=self.shapes,
            ok=ok,
            message=message,
            extra=extra,
            stable=self.stable & self.converged,
            unstable=unstable,
            unstable_message=unstable_message,
            critical_value=critical,
            rotations_rad=self.rotations,
        )


def _stability(
    rows: _Rows, lost: tuple[int, float, float] | None, is_disp: bool
) -> tuple[bool, str, float]:
    """``(unstable, message, critical value)`` of a traced path (see :class:`BeamResponse`).

    ``lost`` is the first stable -> unstable crossing: the row it happened on and the driven values
    (mm or N) of the last stable and the first unstable state.
    """
    bad = np.flatnonzero(rows.converged & ~rows.stable)
    if bad.size == 0:
        return False, "", float("nan")
    quantity, unit = ("displacement_mm", "mm") if is_disp else ("force_N", "N")
    n_bad = f"{bad.size} of {int(rows.converged.sum())} converged rows"
    if lost is None:  # unstable from the start: never a crossing, the supports allow a mechanism
        return (
            True,
            f"unstable from the undeformed state (the constrained tangent is not positive "
            f"definite: a mechanism?); {n_bad} unstable",
            float("nan"),
        )
    k, before, after = lost
    critical = 0.5 * (before + after)
    return (
        True,
        f"unstable: passed a bifurcation or limit point at step {k} ({quantity} between "
        f"{before:.6g} and {after:.6g} {unit}: the constrained tangent stopped being positive "
        f"definite); {n_bad} unstable, on a branch that buckles under any imperfection",
        critical,
    )


# -- band-storage helpers (LAPACK gbsv layout: A[i, j] = ab[kl + ku + i - j, j]) ---------------


def _band_zero_index(dofs: np.ndarray, n: int, kl: int, ku: int) -> np.ndarray:
    """Flat (Fortran-order) indices of the band entries in the rows and columns of ``dofs``."""
    ldab = 2 * kl + ku + 1
    idx = []
    for c in dofs:
        j = np.arange(max(0, c - ku), min(n, c + kl + 1))
        idx.append(j * ldab + kl + ku + c - j)  # row c
        idx.append(c * ldab + kl + ku + j - c)  # column c
    return np.unique(np.concatenate(idx))


def _sym_band_zero_index(dofs: np.ndarray, n: int, k: int) -> np.ndarray:
    """Flat (Fortran-order) indices, in upper symmetric band storage, of rows/columns ``dofs``."""
    ldab = k + 1
    idx = []
    for c in dofs:
        i = np.arange(max(0, c - k), c + 1)  # column c: A[i, c], i <= c
        idx.append(c * ldab + k + i - c)
        j = np.arange(c, min(n, c + k + 1))  # row c: A[c, j], j >= c
        idx.append(j * ldab + k + c - j)
    return np.unique(np.concatenate(idx))


def _band_column(ab: np.ndarray, c: int, n: int, kl: int, ku: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows and values of column ``c`` of the banded matrix."""
    i = np.arange(max(0, c - ku), min(n, c + kl + 1))
    return i, ab[kl + ku + i - c, c].copy()


def _solve_constrained(
    ab: np.ndarray, rhs: np.ndarray, bc: _Constraints, increment: float
) -> tuple[np.ndarray, int]:
    """Solve the banded system with the fixed DOFs held (the driven one moved by ``increment``).

    ``ab`` is overwritten. The column of a prescribed non-zero increment must already have been
    moved to ``rhs`` by the caller. Returns the solution and LAPACK's info.
    """
    assert ab.flags.f_contiguous, "band storage must be Fortran-ordered (zeroing works on a view)"
    flat = ab.T.reshape(-1)  # a view: ab is Fortran-ordered
    flat[bc.zero_idx] = 0.0
    flat[bc.diag_idx] = 1.0
    rhs = rhs.copy()
    rhs[bc.fixed] = 0.0
    if bc.driven >= 0:
        rhs[bc.driven] = increment
    # Banded Cholesky when the held tangent is positive definite (a stable state: most Newton
    # iterations), about a third of the LU's work; the pivoting LU otherwise (past a bifurcation
    # or limit point, or far from equilibrium, where the tangent is indefinite). The tangent is
    # symmetric (the Hessian of the strain energy under dead loads and prescribed displacements),
    # so both solve the same system. The compiled kernel makes the same choice by the same test.
    up = np.array(ab[_BAND : 2 * _BAND + 1], order="F")  # the upper band (kd + 1, n)
    factor, info = dpbtrf(up, lower=0, overwrite_ab=1)
    if info == 0:
        x, info = dpbtrs(factor, rhs[:, None], lower=0, overwrite_b=1)
        return x[:, 0], info
    _, _, x, info = dgbsv(_BAND, _BAND, ab, rhs, overwrite_ab=1, overwrite_b=1)
    return x, info


def _is_positive_definite(ab: np.ndarray, bc: _Constraints) -> bool:
    """Is the constrained tangent positive definite (a stable equilibrium)?

    Parameters
    ----------
    ab : (2 kl + ku + 1, n) float — the tangent in LAPACK gbsv storage (kl = ku = ``_BAND``),
        ``A[i, j] = ab[kl + ku + i - j, j]``; rows 0..kl-1 are gbsv's fill-in workspace.
    bc : the constraints; their rows and columns are replaced by identity rows, so the matrix
        factorised is the reduced tangent on the free DOFs (plus a decoupled identity block),
        which is positive definite exactly when the reduced one is.

    The tangent is symmetric, so its upper half is LAPACK's upper symmetric band storage with
    ``kd = _BAND`` superdiagonals, ``A[i, j] = up[kd + i - j, j]`` for ``i <= j``: these are the
    ``kd + 1`` rows ``kl .. kl + ku`` of the gbsv storage (the diagonal is row ``kl + ku``). The
    rows below the diagonal must not be passed: ``dpbtrf`` takes ``kd`` from the row count, and
    with them it would read a subdiagonal as the diagonal. A banded Cholesky factorisation
    (``dpbtrf``, O(n kd^2)) then answers: ``info == 0`` exactly when it is positive definite.
    """
    up = np.array(ab[_BAND : 2 * _BAND + 1], order="F")  # (kd + 1, n), diagonal in the last row
    flat = up.T.reshape(-1)  # a view: up is Fortran-ordered
    flat[bc.zero_idx_sym] = 0.0
    flat[bc.fixed * (_BAND + 1) + _BAND] = 1.0
    _, info = dpbtrf(up, lower=0, overwrite_ab=1)
    return info == 0


@lru_cache(maxsize=64)
def _end_rotation(dx: float, dy: float) -> np.ndarray:
    """(9, 9) map from (physical, with the end node in (direction, normal)) to physical DOFs."""
    T = np.eye(9)
    T[6:8, 6:8] = np.array([[dx, -dy], [dy, dx]])
    return T


def _centreline_points(profile: BeamProfile, s: np.ndarray) -> np.ndarray:
    """(m, 2) positions (mm) on the reference centreline at arc lengths ``s`` (m,)."""
    s_pts = profile.arc_length_mm
    seg = np.clip(np.searchsorted(s_pts, s, side="right") - 1, 0, profile.n_points - 2)
    sigma = s - s_pts[seg]
    th = profile.segment_start_angles_rad()[seg]
    kap = profile.curvature_per_mm[seg]
    p0 = profile.points_mm[seg]
    straight = np.abs(kap) < 1e-14
    safe = np.where(straight, 1.0, kap)
    dx = np.where(straight, sigma * np.cos(th), (np.sin(th + kap * sigma) - np.sin(th)) / safe)
    dy = np.where(straight, sigma * np.sin(th), (np.cos(th) - np.cos(th + kap * sigma)) / safe)
    return p0 + np.stack([dx, dy], axis=-1)


def solve_beam(
    profile: BeamProfile,
    material: Material,
    drive: EndDrive,
    start: Literal["clamped", "pinned"] = "clamped",
    settings: BeamSettings = BeamSettings(),
) -> BeamResponse:
    """Build a :class:`BeamModel` and trace the response under ``drive``."""
    return BeamModel(profile, material, start, settings).solve(drive)


def warm_up() -> str:
    """Compile (first call in an install) or load from numba's cache the beam kernel, now.

    A process pool calls this before it forks its workers: forked workers inherit the compiled
    code, instead of each compiling it (~14 s CPU in a fresh install) or loading it from the cache
    (~0.5 s) on its first design. Two tiny solves (a displacement and a force drive) touch every
    compiled function the tracing loop uses. Costs nothing measurable once compiled.

    Returns
    -------
    str
        The kernel that runs: "numba", or "numpy" when numba is unavailable (nothing to do).
    """
    kernel = resolve_kernel("auto")
    if kernel != "numba":
        return kernel
    profile = BeamProfile(np.array([[0.0, 0.0], [10.0, 0.0]]), np.array([1.0, 1.0]), 1.0)
    material = Material("warm-up", E_MPa=1000.0, nu=0.3, yield_MPa=10.0)
    model = BeamModel(profile, material, settings=BeamSettings(n_elements=2))
    model.solve(EndDrive("displacement", (0.0, 1.0), 0.1, steps=1))
    model.solve(EndDrive("force", (0.0, 1.0), 0.01, steps=1))
    return kernel
