"""Long-stroke constant-force compliant mechanism (Bilancia, Geraci, Berselli, SMASIS 2019).

Three layers of the paper's design flow, all in the PRB frame described below:

1. **PRB eccentric slider-crank** (paper Eqs. 1–11): position analysis, spring energy, output
   force from the energy derivative, the paper's virtual-work terms (Eqs. 3–5, corrected) and the
   Table-1 force curve; :func:`optimise_prb` re-synthesises Table-1-like parameters for any target
   force and stroke.
2. **Lumped compliance** (Eq. 12): small-length flexural pivots ``K = E I / L``, ``I = h^3 b / 12``,
   sized both ways, with the pivot bending stress ``sigma = E h |Psi| / (2 L)`` and the stroke at
   which it reaches the allowable stress.
3. **Beam-based design** (Eq. 13, Table 3): the 23-variable tapered beam through the reference
   points S1..S6 (ends of the three flexures) and the design points p1..p10, as a
   :class:`~geometry.profile.BeamProfile` for the beam solver and as a printable shapely outline.

Frame and conventions (see ``docs/constant_force.md`` for the derivation)
-------------------------------------------------------------------------
* Crank pivot O at the origin; the slider pin C moves on the line ``y = e``; ``x`` is its abscissa.
  Crank angle ``theta1`` is measured from the slider axis (+x) to O->A, counter-clockwise. The rod
  angle ``theta3`` is the direction of C->A (that is what Eqs. 6–7 encode: ``A - C = r2 (cos
  theta3, sin theta3)``), so it is near ``pi + atan(e/x)``.
* ``r2 = sqrt(x_in^2 + e^2) - r1`` (Eq. 11): O, A, C collinear ("stretched") with C at
  ``(x_in, e)``. The spring-free state is ``theta1 = theta10``; its slider abscissa ``x0`` follows
  from Eq. 7 and equals ``x_in`` when ``theta10 = atan(e / x_in)`` (Table 1: ``x0 - x_in =
  -1.5e-4 mm``).
* **Stroke** ``dx = x0 - x >= 0``: the slider moves along the work direction ``(-1, 0)``, towards
  the crank pivot, compressing the mechanism. With ``theta10 > atan(e/x_in)`` the crank is already
  past the toggle, so compressing turns it counter-clockwise (``theta1`` grows) and the crank pin A
  stays on the left of O->C.
* **Output force** ``F = dU/d(dx) = -dU/dx`` with ``U = 1/2 sum K_i Psi_i^2``: the force with which
  the slider pushes back against the compression, positive like a compression spring (the paper
  plots +1.5 N). The paper's Eqs. 3–5, once the bracket of Eq. 5 is fixed, sum to ``+dU/dx``: the
  x-component of the force one applies to the slider, which is negative in compression. So the
  output force is ``-(F1 + F2 + F3)``.

Units: mm, N, N·mm, rad, MPa.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np
import shapely
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.profile import BeamProfile
from scipy.optimize import minimize
from shapely.geometry import Polygon

__all__ = [
    "PRBParams",
    "PRBState",
    "TABLE1",
    "prb_state",
    "prb_energy_Nmm",
    "prb_force_N",
    "prb_force_terms_paper",
    "stroke_samples_mm",
    "prb_force_curve",
    "table1_force_curve",
    "PRBFit",
    "prb_bounds",
    "optimise_prb",
    "flexure_stiffness_Nmm",
    "flexure_thickness_mm",
    "flexure_width_mm",
    "TABLE2_WIDTH_MM",
    "TABLE2_THICKNESS_MM",
    "TABLE2_LENGTH_MM",
    "pivot_stress_MPa",
    "prb_pivot_stresses_MPa",
    "stress_limited_stroke_mm",
    "FLEXURE_LENGTH_MM",
    "WORK_DIRECTION",
    "DESIGN_VARIABLE_NAMES",
    "ConstantForceDesign",
    "DesignBounds",
    "TABLE3_OPTIMUM",
    "TABLE3_BOUNDS",
    "design_from_vector",
    "design_to_vector",
    "joint_points",
    "reference_points",
    "design_points",
    "centreline_points",
    "beam_profile",
    "outline",
    "min_feature_mm",
]

# ----------------------------------------------------------------------------------------------
# 1. PRB eccentric slider-crank
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PRBParams:
    """Parameters of the PRB eccentric slider-crank (paper Table 1 and Eq. 10).

    Attributes
    ----------
    r1_mm : float, mm
        Crank length O->A.
    theta10_rad : float, rad
        Spring-free crank angle, from the slider axis (+x), counter-clockwise. Must be at least
        ``atan(e / x_in)`` (the stretched configuration; the paper's lower bound) and below pi.
    K1_Nmm, K2_Nmm, K3_Nmm : float, N·mm/rad
        Torsional springs at the ground pivot O, the crank–rod pin A and the rod–slider pin C.
    x_in_mm : float, mm
        Slider abscissa of the stretched configuration (Eq. 11).
    e_mm : float, mm
        Eccentricity: the slider axis is the line ``y = e``.
    """

    r1_mm: float
    theta10_rad: float
    K1_Nmm: float
    K2_Nmm: float
    K3_Nmm: float
    x_in_mm: float = 100.0
    e_mm: float = 60.0

    def __post_init__(self) -> None:
        for name in ("r1_mm", "theta10_rad", "K1_Nmm", "K2_Nmm", "K3_Nmm", "x_in_mm", "e_mm"):
            value = float(getattr(self, name))
            if not np.isfinite(value):
                raise GeometryError(f"PRBParams.{name} = {value} must be a finite number")
            object.__setattr__(self, name, value)
        if not self.e_mm > 0 or not self.x_in_mm > 0:
            raise GeometryError(
                f"x_in_mm = {self.x_in_mm:g} and e_mm = {self.e_mm:g} must both be > 0 "
                "(the slider starts up and to the right of the crank pivot)"
            )
        reach = float(np.hypot(self.x_in_mm, self.e_mm))
        if not 0 < self.r1_mm < reach:
            raise GeometryError(
                f"r1_mm = {self.r1_mm:g} must lie in (0, sqrt(x_in^2 + e^2) = {reach:g}) so that "
                "the rod length r2 = sqrt(x_in^2 + e^2) - r1 (Eq. 11) is positive"
            )
        alpha0 = float(np.arctan2(self.e_mm, self.x_in_mm))
        if not alpha0 - 1e-12 <= self.theta10_rad < np.pi:
            raise GeometryError(
                f"theta10_rad = {self.theta10_rad:.6g} must lie in [atan(e/x_in) = {alpha0:.6g}, "
                "pi): below atan(e/x_in) the crank pin starts on the other side of the line O-C "
                "and the mechanism would open before it compresses"
            )
        for name in ("K1_Nmm", "K2_Nmm", "K3_Nmm"):
            if getattr(self, name) < 0:
                raise GeometryError(f"PRBParams.{name} = {getattr(self, name):g} must be >= 0")

    @property
    def r2_mm(self) -> float:
        """Rod length A->C, mm (Eq. 11)."""
        return float(np.hypot(self.x_in_mm, self.e_mm) - self.r1_mm)

    @property
    def stiffness_Nmm(self) -> np.ndarray:
        """(3,) float, N·mm/rad: ``[K1, K2, K3]``."""
        return np.array([self.K1_Nmm, self.K2_Nmm, self.K3_Nmm])

    @property
    def theta30_rad(self) -> float:
        """Spring-free rod angle (direction C->A), rad (Eq. 6 at theta10)."""
        return float(_theta3(self.r1_mm, self.r2_mm, self.e_mm, self.theta10_rad))

    @property
    def x0_mm(self) -> float:
        """Spring-free slider abscissa, mm (Eq. 7 at theta10); ``= x_in`` when stretched."""
        return float(_slider_x(self.r1_mm, self.r2_mm, self.e_mm, self.theta10_rad))

    def with_stiffness(self, K_Nmm: np.ndarray) -> PRBParams:
        """A copy with ``[K1, K2, K3]`` replaced, N·mm/rad."""
        k1, k2, k3 = (float(v) for v in np.asarray(K_Nmm, dtype=float).reshape(3))
        return PRBParams(self.r1_mm, self.theta10_rad, k1, k2, k3, self.x_in_mm, self.e_mm)


#: Paper Table 1: optimum for 1.5 N over 35 mm with x_in = 100 mm, e = 60 mm.
TABLE1 = PRBParams(r1_mm=54.0, theta10_rad=0.542, K1_Nmm=28.303, K2_Nmm=35.379, K3_Nmm=35.379)


def _theta3(r1: float, r2: float, e: float, theta1: np.ndarray) -> np.ndarray:
    # Eq. 6 solved with atan2 instead of asin: identical while A lies left of C (the paper's
    # range), and it stays continuous if a long stroke carries C past A.
    x = _slider_x(r1, r2, e, theta1)
    return np.pi - np.arctan2(r1 * np.sin(theta1) - e, x - r1 * np.cos(theta1))


def _slider_x(r1: float, r2: float, e: float, theta1: np.ndarray) -> np.ndarray:
    # Eq. 7 with cos(theta3) = -sqrt(1 - sin^2) from Eq. 6 (rod pointing back from C to A).
    s = (r1 * np.sin(theta1) - e) / r2
    return r1 * np.cos(theta1) + r2 * np.sqrt(np.clip(1.0 - s * s, 0.0, None))


@dataclass(frozen=True)
class PRBState:
    """Configuration of the PRB slider-crank at a set of strokes; every array has shape (m,).

    Attributes
    ----------
    stroke_mm : mm — ``dx = x0 - x``.
    x_mm : mm — slider abscissa.
    theta1_rad, theta3_rad : rad — crank angle (O->A) and rod angle (C->A), from +x.
    psi_rad : (3, m), rad — spring rotations ``Psi1 = theta1 - theta10``,
        ``Psi2 = Psi3 - Psi1``, ``Psi3 = theta3 - theta30`` (Eq. 1).
    dtheta1_dx, dtheta3_dx : 1/mm — exact derivatives along the slider axis.
    """

    stroke_mm: np.ndarray
    x_mm: np.ndarray
    theta1_rad: np.ndarray
    theta3_rad: np.ndarray
    psi_rad: np.ndarray
    dtheta1_dx: np.ndarray
    dtheta3_dx: np.ndarray

    @property
    def dpsi_dx(self) -> np.ndarray:
        """(3, m), rad/mm: ``d Psi_i / dx``."""
        return np.stack([self.dtheta1_dx, self.dtheta3_dx - self.dtheta1_dx, self.dtheta3_dx])


def _state(
    r1: float, theta10: float, x_in: float, e: float, stroke: np.ndarray
) -> tuple[PRBState, np.ndarray]:
    """Kinematics without validation; returns the state and a (m,) reachable mask."""
    r2 = float(np.hypot(x_in, e) - r1)
    x0 = float(_slider_x(r1, r2, e, theta10))
    theta30 = float(_theta3(r1, r2, e, theta10))
    x = x0 - stroke
    d = np.hypot(x, e)
    alpha = np.arctan2(e, x)
    # Crank pin A from the two circles |OA| = r1, |CA| = r2; beta is the angle at O of triangle
    # O-A-C. "+ beta" is the branch with A left of O->C, the one theta10 >= atan(e/x_in) starts on.
    cos_beta = (r1 * r1 + d * d - r2 * r2) / (2.0 * r1 * d)
    reachable = np.abs(cos_beta) <= 1.0 + 1e-12
    theta1 = alpha + np.arccos(np.clip(cos_beta, -1.0, 1.0))
    theta3 = np.pi - np.arctan2(r1 * np.sin(theta1) - e, x - r1 * np.cos(theta1))
    # Differentiating the loop closure r1 sin(theta1) - r2 sin(theta3) = e and Eq. 7:
    #   dx = r1 sin(theta3 - theta1) / cos(theta3) dtheta1,  r1 cos(theta1) dtheta1 = r2 cos(theta3)
    # dtheta3. The common denominator r2 sin(theta3 - theta1) = x sin(theta1) - e cos(theta1)
    # vanishes only at the toggle (O, A, C collinear).
    den = x * np.sin(theta1) - e * np.cos(theta1)
    with np.errstate(divide="ignore", invalid="ignore"):
        dtheta1_dx = r2 * np.cos(theta3) / (r1 * den)
        dtheta3_dx = np.cos(theta1) / den
    psi1 = theta1 - theta10
    psi3 = theta3 - theta30
    psi = np.stack([psi1, psi3 - psi1, psi3])
    state = PRBState(stroke, x, theta1, theta3, psi, dtheta1_dx, dtheta3_dx)
    return state, reachable


def _as_stroke(stroke_mm: np.ndarray | float) -> np.ndarray:
    stroke = np.atleast_1d(np.asarray(stroke_mm, dtype=float))
    if stroke.ndim != 1 or not np.all(np.isfinite(stroke)):
        raise GeometryError(
            f"stroke_mm must be a finite number or a 1-D array of them, got shape {stroke.shape}"
        )
    return stroke


def prb_state(params: PRBParams, stroke_mm: np.ndarray | float) -> PRBState:
    """Position analysis of the slider-crank at the given strokes.

    Parameters
    ----------
    params : PRBParams
    stroke_mm : (m,) float, mm
        Slider displacement ``dx = x0 - x`` along the work direction (towards the crank pivot).

    Returns
    -------
    PRBState
        Angles, spring rotations and their exact x-derivatives, each (m,) or (3, m).

    Raises
    ------
    GeometryError
        When a stroke is beyond the reach of the linkage (the rod cannot reach the slider axis).
    """
    stroke = _as_stroke(stroke_mm)
    state, ok = _state(params.r1_mm, params.theta10_rad, params.x_in_mm, params.e_mm, stroke)
    if not np.all(ok):
        bad = stroke[~ok][0]
        raise GeometryError(
            f"stroke_mm = {bad:g} is beyond the reach of the slider-crank (r1 = "
            f"{params.r1_mm:g} mm, r2 = {params.r2_mm:g} mm, e = {params.e_mm:g} mm): the rod "
            "cannot reach the slider axis; use a shorter stroke or a longer crank"
        )
    return state


def prb_energy_Nmm(params: PRBParams, stroke_mm: np.ndarray | float) -> np.ndarray:
    """Strain energy ``U = 1/2 sum K_i Psi_i^2`` of the three springs.

    Parameters
    ----------
    params : PRBParams
    stroke_mm : (m,) float, mm

    Returns
    -------
    (m,) float, N·mm
    """
    psi = prb_state(params, stroke_mm).psi_rad
    return 0.5 * params.stiffness_Nmm @ (psi * psi)


def _force_basis(state: PRBState) -> np.ndarray:
    """(m, 3): output force per unit K_i, N/(N·mm) — the force is linear in K."""
    with np.errstate(invalid="ignore"):
        basis = -(state.psi_rad * state.dpsi_dx).T
    # At the exact toggle with Psi = 0 (stroke 0 and theta10 = atan(e/x_in)) the product is
    # 0 * inf; the mechanism is unloaded there, so the force is 0.
    return np.where(np.isnan(basis) & (state.psi_rad.T == 0.0), 0.0, basis)


def prb_force_N(params: PRBParams, stroke_mm: np.ndarray | float) -> np.ndarray:
    """Output force of the PRB mechanism, positive in compression.

    ``F = dU/d(dx) = -dU/dx = -sum_i K_i Psi_i dPsi_i/dx`` with ``dtheta1/dx = cos(theta3) /
    (r1 sin(theta3 - theta1))`` and ``dtheta3/dx = cos(theta1) / (r2 sin(theta3 - theta1))``,
    both from differentiating Eqs. 6–7. ``F`` is the force the slider exerts on whatever pushes it
    towards the crank pivot (the work direction ``(-1, 0)``).

    Parameters
    ----------
    params : PRBParams
    stroke_mm : (m,) float, mm
        Slider displacement from the spring-free position along the work direction.

    Returns
    -------
    (m,) float, N
    """
    return _force_basis(prb_state(params, stroke_mm)) @ params.stiffness_Nmm


def prb_force_terms_paper(
    params: PRBParams, stroke_mm: np.ndarray | float, as_printed: bool = False
) -> np.ndarray:
    """The paper's virtual-work terms F1, F2, F3 (Eqs. 3–5).

    With ``as_printed=False`` (the corrected form) the terms are::

        F1 = K1 Psi1 cos(theta3) / (r1 sin(theta3 - theta1))       = K1 Psi1 dPsi1/dx
        F2 = K2 Psi2 cos(alpha)  / (r1 sin(theta1 - alpha))        = K2 Psi2 dPsi2/dx
        F3 = K3 Psi3 cos(theta1) / (x sin(theta1) - e cos(theta1)) = K3 Psi3 dPsi3/dx

    with ``alpha = atan(e / x)``. Eq. 5 needs the bracket around its denominator; Eq. 4 holds
    because ``cos(alpha) / (r1 sin(theta1 - alpha))`` is the x-derivative of the interior angle of
    triangle O-A-C at A, which equals ``theta3 - theta1`` on the branch used here. Their sum is
    ``+dU/dx``, the x-component of the force applied to the slider (negative in compression); the
    output force of :func:`prb_force_N` is ``-(F1 + F2 + F3)``.

    With ``as_printed=True`` Eq. 5 is evaluated as typeset, ``K3 Psi3 cos(theta1) / (x
    sin(theta1)) - e cos(theta1)`` (dimensionally inconsistent: N minus mm), to show it is wrong.

    Parameters
    ----------
    params : PRBParams
    stroke_mm : (m,) float, mm
    as_printed : bool
        Evaluate Eq. 5 without the bracket fix.

    Returns
    -------
    (3, m) float, N
        Rows F1, F2, F3.
    """
    state = prb_state(params, stroke_mm)
    th1, th3, x = state.theta1_rad, state.theta3_rad, state.x_mm
    r1, e = params.r1_mm, params.e_mm
    alpha = np.arctan(e / x)
    k_psi = params.stiffness_Nmm[:, None] * state.psi_rad
    with np.errstate(divide="ignore", invalid="ignore"):
        f1 = k_psi[0] * np.cos(th3) / (r1 * np.sin(th3 - th1))
        f2 = k_psi[1] * np.cos(alpha) / (r1 * np.sin(th1 - alpha))
        if as_printed:
            f3 = k_psi[2] * np.cos(th1) / (x * np.sin(th1)) - e * np.cos(th1)
        else:
            f3 = k_psi[2] * np.cos(th1) / (x * np.sin(th1) - e * np.cos(th1))
    return np.stack([f1, f2, f3])


def stroke_samples_mm(stroke_mm: float, n_samples: int = 100) -> np.ndarray:
    """Evenly spaced strokes ``stroke * i / Q`` for ``i = 1..Q`` (the unloaded ``0`` excluded).

    Returns
    -------
    (n_samples,) float, mm
    """
    if not stroke_mm > 0:
        raise GeometryError(f"stroke_mm = {stroke_mm:g} must be > 0")
    if n_samples < 1:
        raise GeometryError(f"n_samples = {n_samples} must be >= 1")
    return stroke_mm * np.arange(1, n_samples + 1) / n_samples


def prb_force_curve(
    params: PRBParams, stroke_mm: float, n_samples: int = 100
) -> tuple[np.ndarray, np.ndarray]:
    """Force–stroke curve of the PRB mechanism, including the unloaded point.

    Returns
    -------
    stroke : (n_samples + 1,) float, mm — ``0, stroke/Q, ..., stroke``.
    force : (n_samples + 1,) float, N — output force, positive in compression.
    """
    stroke = np.concatenate([[0.0], stroke_samples_mm(stroke_mm, n_samples)])
    return stroke, prb_force_N(params, stroke)


def table1_force_curve(
    stroke_mm: float = 35.0, n_samples: int = 100
) -> tuple[np.ndarray, np.ndarray]:
    """The paper's Table-1 optimum (r1 = 54 mm, theta10 = 0.542 rad, K = 28.303, 35.379,
    35.379 N·mm, x_in = 100 mm, e = 60 mm) evaluated by :func:`prb_force_curve`."""
    return prb_force_curve(TABLE1, stroke_mm, n_samples)


@dataclass(frozen=True)
class PRBFit:
    """Result of :func:`optimise_prb`.

    Attributes
    ----------
    params : PRBParams — the optimum.
    rms_error_N : float, N — Eq. 8 over the samples.
    target_force_N : float, N
    stroke_mm : (Q,) float, mm — the sampled strokes.
    force_N : (Q,) float, N — the optimum's force at those strokes.
    n_evaluations : int — objective evaluations (each solves the linear K sub-problem).
    """

    params: PRBParams
    rms_error_N: float
    target_force_N: float
    stroke_mm: np.ndarray
    force_N: np.ndarray
    n_evaluations: int

    @property
    def relative_rms_error(self) -> float:
        """``rms_error / target`` (dimensionless)."""
        return self.rms_error_N / self.target_force_N


def prb_bounds(
    x_in_mm: float = 100.0, e_mm: float = 60.0, k_max_Nmm: float = 1000.0
) -> tuple[np.ndarray, np.ndarray]:
    """Table-1 bounds on ``(r1, theta10, K1, K2, K3)``.

    ``r1 in [e/5, 0.9 e]``, ``theta10 in [asin(e / sqrt(e^2 + x_in^2)), pi/2]``,
    ``K_i in [0, k_max]``.

    Returns
    -------
    lower, upper : (5,) float — mm, rad, N·mm, N·mm, N·mm.
    """
    alpha0 = float(np.arcsin(e_mm / np.hypot(e_mm, x_in_mm)))
    lower = np.array([e_mm / 5.0, alpha0, 0.0, 0.0, 0.0])
    upper = np.array([0.9 * e_mm, np.pi / 2, k_max_Nmm, k_max_Nmm, k_max_Nmm])
    return lower, upper


def _box_lsq(A: np.ndarray, b: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Exact box-constrained linear least squares for a batch of small problems.

    ``x_j = argmin ||A_j x - b_j||`` subject to ``lower <= x <= upper``, for every j. Where the
    unconstrained minimiser lies in the box it is the answer (as in ``lsq_linear``); otherwise
    the active sets are enumerated: each unknown free, at its lower or at its upper bound
    (``3^p`` cases, 27 for the three stiffnesses), and of the cases whose free unknowns lie in
    the box the one with the smallest residual is the minimiser. Why that is exact: the
    minimiser's own active set is one of the cases, the minimiser is the unconstrained one on
    that face, and no case in the box does better. A case whose free columns are dependent is
    skipped: some minimiser then sits on a face whose free columns are independent. Every case
    is solved on the QR factor of ``A_j``, so the accuracy is ``cond(A) * eps`` (the normal
    equations would square the condition number).

    Replaces ``scipy.optimize.lsq_linear`` in :func:`optimise_prb` (why: its trust-region
    iteration cost ~1.2 ms a problem, 0.5-1.9 s per synthesis): the same minimiser, exact where
    lsq_linear stops at its tolerance; batched over a grid ~15 us a problem, alone 0.1-0.9 ms.

    Parameters
    ----------
    A : (n, m, p) float — n problems of m >= p equations in p unknowns (p small).
    b : (n, m) float — right-hand sides.
    lower, upper : (p,) float — finite bounds, ``lower <= upper``.

    Returns
    -------
    (n, p) float — the minimisers, within the bounds.
    """
    n, _, p = A.shape
    Q, R = np.linalg.qr(A)  # (n, m, p), (n, p, p)
    d = np.einsum("nmk,nm->nk", Q, b)  # ||A x - b||^2 = ||R x - d||^2 + const
    # Columns whose pivot is below 1e-13 of the largest entry count as dependent.
    tiny = 1e-13 * np.max(np.abs(R), axis=(1, 2), initial=0.0)  # (n,)
    slack = 1e-12 * float(np.max(upper - lower, initial=1.0))  # round-off on "inside the box"

    def solve(Rf: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rf (n, p, f), rhs (n, p, c) -> least-squares x (n, f, c) and (n,) solvable."""
        Qf, Tf = np.linalg.qr(Rf)
        solvable = np.all(np.abs(np.diagonal(Tf, axis1=1, axis2=2)) > tiny[:, None], axis=1)
        Tf = np.where(solvable[:, None, None], Tf, np.eye(Tf.shape[-1]))
        return np.linalg.solve(Tf, np.swapaxes(Qf, 1, 2) @ rhs), solvable

    def inside(x: np.ndarray, idx: list[int]) -> np.ndarray:
        """x (..., p): are the unknowns idx within the bounds (up to round-off)? (...,)"""
        v = x[..., idx]
        return np.all((v >= lower[idx] - slack) & (v <= upper[idx] + slack), axis=-1)

    everything = list(range(p))
    x_free, ok = solve(R, d[:, :, None])
    best = x_free[:, :, 0]
    todo = np.flatnonzero(~(ok & inside(best, everything)))
    if todo.size:
        R, d, tiny = R[todo], d[todo], tiny[todo]
        n_left = todo.size
        best_x = np.full((n_left, p), np.nan)
        best_cost = np.full(n_left, np.inf)
        for mask in range(1 << p):
            free = [i for i in everything if mask >> i & 1]
            fixed = [i for i in everything if not mask >> i & 1]
            # Every lower/upper assignment of the fixed unknowns, (c, len(fixed)).
            combos = np.array(
                [
                    [upper[i] if c >> j & 1 else lower[i] for j, i in enumerate(fixed)]
                    for c in range(1 << len(fixed))
                ],
                dtype=float,
            ).reshape(1 << len(fixed), len(fixed))
            x = np.empty((n_left, combos.shape[0], p))
            x[:, :, fixed] = combos
            feasible = np.ones((n_left, combos.shape[0]), dtype=bool)
            if free:
                rhs = d[:, :, None] - R[:, :, fixed] @ combos.T  # (n_left, p, c)
                xf, ok = solve(R[:, :, free], rhs)
                x[:, :, free] = np.swapaxes(xf, 1, 2)
                feasible = ok[:, None] & inside(x, free)
            r = np.einsum("nkp,ncp->nck", R, x) - d[:, None, :]
            cost = np.where(feasible, np.einsum("nck,nck->nc", r, r), np.inf)
            j = np.argmin(cost, axis=1)
            c = cost[np.arange(n_left), j]
            better = c < best_cost
            best_x[better] = x[better, j[better]]
            best_cost[better] = c[better]
        best = best.copy()
        best[todo] = best_x
    return np.clip(best, lower, upper)


def _grid_rms(
    grid: list[np.ndarray],
    to_geometry: Callable[[np.ndarray], tuple[float, float]],
    x_in_mm: float,
    e_mm: float,
    samples: np.ndarray,
    target: np.ndarray,
    k_lower: np.ndarray,
    k_upper: np.ndarray,
) -> np.ndarray:
    """(len(grid),) RMS error, N, of the best stiffnesses at each grid point (inf: unreachable).

    The bounded least-squares problems of all reachable points are solved in one batch.
    """
    scores = np.full(len(grid), np.inf)
    bases, where = [], []
    for i, z in enumerate(grid):
        r1, th10 = to_geometry(z)
        state, ok = _state(r1, th10, x_in_mm, e_mm, samples)
        basis = _force_basis(state)
        if np.all(ok) and np.all(np.isfinite(basis)):
            bases.append(basis)
            where.append(i)
    if bases:
        A = np.stack(bases)  # (n, Q, 3)
        b = np.broadcast_to(target, A.shape[:2])
        k = _box_lsq(A, b, k_lower, k_upper)
        err = np.einsum("nqk,nk->nq", A, k) - b
        scores[where] = np.sqrt(np.mean(err**2, axis=1))
    return scores


def optimise_prb(
    target_force_N: float,
    stroke_mm: float,
    x_in_mm: float = 100.0,
    e_mm: float = 60.0,
    n_samples: int = 100,
    k_max_Nmm: float = 1000.0,
    n_grid: tuple[int, int] = (16, 24),
    n_polish: int = 4,
) -> PRBFit:
    """Find PRB parameters whose force stays at ``target_force_N`` over ``stroke_mm`` (Eq. 8).

    Minimises ``e_F = sqrt(mean_i (F(dx_i) - F_t)^2)`` over ``dx_i = stroke * i / Q``, i = 1..Q
    (the paper sampled Q steps of theta1; sampling the stroke weights the curve evenly where it is
    used), within the Table-1 bounds of :func:`prb_bounds`.

    The force is linear in ``(K1, K2, K3)``, so for each geometry ``(r1, theta10)`` the best
    stiffnesses come from a bounded linear least-squares problem (:func:`_box_lsq`: exact, solved
    for all grid points at once; it replaced ``scipy.optimize.lsq_linear``, same minimiser, ~6x
    less time per synthesis), leaving a 2-variable search: a grid over ``r1`` x
    ``log(theta10 - atan(e/x_in))`` (the optimum sits within a few mrad of the stretched
    configuration, which a linear grid would miss) and Nelder–Mead polishing of the best
    ``n_polish`` grid points. Deterministic, no seed needed.

    Parameters
    ----------
    target_force_N : float, N
    stroke_mm : float, mm
    x_in_mm, e_mm : float, mm — fixed slider position (Eq. 10).
    n_samples : int — Q.
    k_max_Nmm : float, N·mm — upper bound of each K.
    n_grid : (int, int) — grid points in r1 and in log(theta10 - atan(e/x_in)).
    n_polish : int — grid points refined by Nelder–Mead.

    Returns
    -------
    PRBFit
    """
    if not target_force_N > 0:
        raise GeometryError(f"target_force_N = {target_force_N:g} must be > 0")
    samples = stroke_samples_mm(stroke_mm, n_samples)
    lower, upper = prb_bounds(x_in_mm, e_mm, k_max_Nmm)
    alpha0 = lower[1]
    target = np.full(samples.size, float(target_force_N))
    # log-offset of theta10 above the stretched angle; 1e-6 rad is "at the toggle" for all
    # practical purposes and keeps the log finite.
    u_lo, u_hi = np.log(1e-6), np.log(upper[1] - alpha0)
    n_eval = 0

    def to_geometry(z: np.ndarray) -> tuple[float, float]:
        r1 = float(np.clip(z[0], lower[0], upper[0]))
        th10 = alpha0 + float(np.exp(np.clip(z[1], u_lo, u_hi)))
        return r1, th10

    def solve_k(z: np.ndarray) -> tuple[float, np.ndarray]:
        nonlocal n_eval
        n_eval += 1
        r1, th10 = to_geometry(z)
        state, ok = _state(r1, th10, x_in_mm, e_mm, samples)
        basis = _force_basis(state)
        if not np.all(ok) or not np.all(np.isfinite(basis)):
            return np.inf, np.zeros(3)
        k = _box_lsq(basis[None], target[None], lower[2:], upper[2:])[0]
        rms = float(np.sqrt(np.mean((basis @ k - target) ** 2)))
        return rms, k

    grid = [
        np.array([r, u])
        for r in np.linspace(lower[0], upper[0], n_grid[0])
        for u in np.linspace(u_lo, u_hi, n_grid[1])
    ]
    scores = _grid_rms(grid, to_geometry, x_in_mm, e_mm, samples, target, lower[2:], upper[2:])
    n_eval += len(grid)
    best_z, best_rms = grid[int(np.argmin(scores))], float(np.min(scores))
    for i in np.argsort(scores)[:n_polish]:
        if not np.isfinite(scores[i]):
            break
        res = minimize(
            lambda z: solve_k(z)[0],
            grid[i],
            method="Nelder-Mead",
            bounds=[(lower[0], upper[0]), (u_lo, u_hi)],
            options={"xatol": 1e-6, "fatol": 1e-9 * target_force_N, "maxiter": 400},
        )
        if res.fun < best_rms:
            best_z, best_rms = res.x, float(res.fun)
    if not np.isfinite(best_rms):
        raise GeometryError(
            f"no PRB geometry within the Table-1 bounds reaches stroke_mm = {stroke_mm:g} with "
            f"x_in = {x_in_mm:g} mm, e = {e_mm:g} mm; shorten the stroke"
        )
    rms, k = solve_k(best_z)
    r1, th10 = to_geometry(best_z)
    params = PRBParams(r1, th10, *(float(v) for v in k), x_in_mm, e_mm)
    return PRBFit(params, rms, float(target_force_N), samples, prb_force_N(params, samples), n_eval)


# ----------------------------------------------------------------------------------------------
# 2. Lumped compliance: small-length flexural pivots
# ----------------------------------------------------------------------------------------------

#: Paper Table 2, flexures at joints K1, K2, K3: width b, thickness h, length L (mm).
TABLE2_WIDTH_MM = np.array([2.478, 2.621, 2.621])
TABLE2_THICKNESS_MM = np.array([0.908, 0.960, 0.960])
TABLE2_LENGTH_MM = np.array([10.8, 10.8, 10.8])
for _a in (TABLE2_WIDTH_MM, TABLE2_THICKNESS_MM, TABLE2_LENGTH_MM):
    _a.setflags(write=False)


def _positive(name: str, value: np.ndarray | float) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise GeometryError(f"{name} = {value} must be finite and > 0")
    return arr


def flexure_stiffness_Nmm(
    E_MPa: float, width_mm: np.ndarray, thickness_mm: np.ndarray, length_mm: np.ndarray
) -> np.ndarray:
    """Rotational stiffness of a small-length flexural pivot, ``K = E I / L``, ``I = h^3 b / 12``
    (Eq. 12). Broadcasts over its array arguments.

    Parameters
    ----------
    E_MPa : float, MPa
    width_mm, thickness_mm, length_mm : float or (k,), mm — b, h, L.

    Returns
    -------
    float or (k,) float, N·mm/rad
    """
    b = _positive("width_mm", width_mm)
    h = _positive("thickness_mm", thickness_mm)
    L = _positive("length_mm", length_mm)
    return _positive("E_MPa", E_MPa) * h**3 * b / 12.0 / L


def flexure_thickness_mm(
    K_Nmm: np.ndarray, E_MPa: float, width_mm: np.ndarray, length_mm: np.ndarray
) -> np.ndarray:
    """Thickness giving stiffness ``K``: ``h = (12 K L / (E b))^(1/3)`` (Eq. 12 inverted).

    Returns
    -------
    float or (k,) float, mm
    """
    K = _positive("K_Nmm", K_Nmm)
    b = _positive("width_mm", width_mm)
    L = _positive("length_mm", length_mm)
    return np.cbrt(12.0 * K * L / (_positive("E_MPa", E_MPa) * b))


def flexure_width_mm(
    K_Nmm: np.ndarray, E_MPa: float, thickness_mm: np.ndarray, length_mm: np.ndarray
) -> np.ndarray:
    """Width giving stiffness ``K``: ``b = 12 K L / (E h^3)`` (Eq. 12 inverted).

    Returns
    -------
    float or (k,) float, mm
    """
    K = _positive("K_Nmm", K_Nmm)
    h = _positive("thickness_mm", thickness_mm)
    L = _positive("length_mm", length_mm)
    return 12.0 * K * L / (_positive("E_MPa", E_MPa) * h**3)


def pivot_stress_MPa(
    E_MPa: float, thickness_mm: np.ndarray, length_mm: np.ndarray, psi_rad: np.ndarray
) -> np.ndarray:
    """Peak bending stress of a flexural pivot bent uniformly through ``psi``:
    ``sigma = M c / I = (E I psi / L)(h / 2) / I = E h |psi| / (2 L)``. Broadcasts.

    Returns
    -------
    float or array, MPa
    """
    h = _positive("thickness_mm", thickness_mm)
    L = _positive("length_mm", length_mm)
    return _positive("E_MPa", E_MPa) * h * np.abs(np.asarray(psi_rad, dtype=float)) / (2.0 * L)


def prb_pivot_stresses_MPa(
    params: PRBParams,
    stroke_mm: np.ndarray | float,
    E_MPa: float,
    thickness_mm: np.ndarray = TABLE2_THICKNESS_MM,
    length_mm: np.ndarray = TABLE2_LENGTH_MM,
) -> np.ndarray:
    """Bending stress in each of the three pivots along the stroke.

    Parameters
    ----------
    params : PRBParams
    stroke_mm : (m,) float, mm
    E_MPa : float, MPa
    thickness_mm, length_mm : (3,) float, mm — pivot h and L (default: Table 2).

    Returns
    -------
    (3, m) float, MPa
    """
    psi = prb_state(params, stroke_mm).psi_rad
    h = np.broadcast_to(np.asarray(thickness_mm, dtype=float), (3,))[:, None]
    L = np.broadcast_to(np.asarray(length_mm, dtype=float), (3,))[:, None]
    return pivot_stress_MPa(E_MPa, h, L, psi)


def stress_limited_stroke_mm(
    params: PRBParams,
    E_MPa: float,
    allowable_MPa: float,
    thickness_mm: np.ndarray = TABLE2_THICKNESS_MM,
    length_mm: np.ndarray = TABLE2_LENGTH_MM,
    max_stroke_mm: float = 60.0,
    resolution_mm: float = 1e-4,
) -> float:
    """Smallest stroke at which the most stressed pivot reaches ``allowable_MPa``.

    Scans ``[0, max_stroke_mm]`` and bisects the first crossing down to ``resolution_mm``.

    Returns
    -------
    float, mm — ``inf`` when the allowable is not reached within ``max_stroke_mm``.
    """

    def excess(s: np.ndarray) -> np.ndarray:
        state, ok = _state(params.r1_mm, params.theta10_rad, params.x_in_mm, params.e_mm, s)
        h = np.broadcast_to(np.asarray(thickness_mm, dtype=float), (3,))[:, None]
        L = np.broadcast_to(np.asarray(length_mm, dtype=float), (3,))[:, None]
        sigma = pivot_stress_MPa(E_MPa, h, L, state.psi_rad).max(axis=0)
        # Beyond the reach of the linkage the mechanism is jammed: count it as failed.
        return np.where(ok, sigma - allowable_MPa, np.inf)

    scan = np.linspace(0.0, max_stroke_mm, 2001)
    over = np.flatnonzero(excess(scan) >= 0)
    if over.size == 0:
        return float("inf")
    if over[0] == 0:
        return 0.0
    lo, hi = scan[over[0] - 1], scan[over[0]]
    while hi - lo > resolution_mm:
        mid = 0.5 * (lo + hi)
        if excess(np.array([mid]))[0] >= 0:
            hi = mid
        else:
            lo = mid
    return float(0.5 * (lo + hi))


# ----------------------------------------------------------------------------------------------
# 3. Beam-based design (Eq. 13, Table 3)
# ----------------------------------------------------------------------------------------------

#: Length of each of the three flexural pivots (Table 2), mm; their ends are S1..S6.
FLEXURE_LENGTH_MM = 10.8

#: Direction in which the driven end S6 moves (the slider moves towards the crank pivot).
WORK_DIRECTION = (-1.0, 0.0)

#: Order of the 23 design variables in a design vector (paper Sec. 3).
DESIGN_VARIABLE_NAMES: tuple[str, ...] = (
    *(f"a{j}" for j in range(1, 11)),
    *(f"t{j}" for j in range(1, 11)),
    "T1",
    "T6",
    "B",
)


@dataclass(frozen=True)
class ConstantForceDesign:
    """The paper's 23 beam-design variables.

    Attributes
    ----------
    a : (10,) float
        Position coefficients of p1..p10: ``p_j = S_i + a_j (S_{i+1} - S_i)`` (Eq. 13), two per
        interval S_i->S_{i+1} (p1, p2 in S1->S2, ..., p9, p10 in S5->S6); each in (0, 1) and
        increasing within its interval so the centreline does not fold back.
    t : (10,) float, mm
        In-plane thickness at p1..p10.
    T1, T6 : float, mm
        Thickness at the clamped end S1 and at the driven end S6.
    B : float, mm
        Out-of-plane width (constant).
    """

    a: np.ndarray
    t: np.ndarray
    T1: float
    T6: float
    B: float

    def __post_init__(self) -> None:
        a = np.asarray(self.a, dtype=float)
        t = np.asarray(self.t, dtype=float)
        if a.shape != (10,) or t.shape != (10,):
            raise GeometryError(
                f"a and t need 10 values each (p1..p10), got shapes {a.shape} and {t.shape}"
            )
        scalars = {"T1": self.T1, "T6": self.T6, "B": self.B}
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(t))) or not all(
            np.isfinite(float(v)) for v in scalars.values()
        ):
            raise GeometryError("a, t, T1, T6 and B must be finite numbers")
        bad = np.flatnonzero((a <= 0) | (a >= 1))
        if bad.size:
            raise GeometryError(
                f"a{bad[0] + 1} = {a[bad[0]]:g} must lie strictly inside (0, 1): at 0 or 1 the "
                "design point coincides with a reference point"
            )
        bad = np.flatnonzero(a[0::2] >= a[1::2])
        if bad.size:
            j = 2 * bad[0] + 1
            raise GeometryError(
                f"a{j} = {a[j - 1]:g} must be < a{j + 1} = {a[j]:g} (both lie on S{bad[0] + 1}->"
                f"S{bad[0] + 2}; otherwise the centreline folds back); swap them"
            )
        bad = np.flatnonzero(t <= 0)
        if bad.size:
            raise GeometryError(f"t{bad[0] + 1} = {t[bad[0]]:g} must be > 0 mm")
        for name, value in scalars.items():
            if not float(value) > 0:
                raise GeometryError(f"{name} = {float(value):g} must be > 0 mm")
            object.__setattr__(self, name, float(value))
        for name, value in (("a", a), ("t", t)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def vertex_thickness_mm(self) -> np.ndarray:
        """(12,) float, mm: thickness at S1, p1..p10, S6."""
        return np.concatenate([[self.T1], self.t, [self.T6]])


class DesignBounds(NamedTuple):
    """Box bounds of a design vector, each (23,) in :data:`DESIGN_VARIABLE_NAMES` order."""

    lower: np.ndarray
    upper: np.ndarray


def design_from_vector(x: np.ndarray) -> ConstantForceDesign:
    """Design from a (23,) vector ordered as :data:`DESIGN_VARIABLE_NAMES` (a, t, T1, T6, B)."""
    v = np.asarray(x, dtype=float)
    if v.shape != (23,):
        raise GeometryError(
            f"a constant-force design vector has 23 entries (a1..a10, t1..t10, T1, T6, B), "
            f"got shape {v.shape}"
        )
    return ConstantForceDesign(a=v[:10].copy(), t=v[10:20].copy(), T1=v[20], T6=v[21], B=v[22])


def design_to_vector(design: ConstantForceDesign) -> np.ndarray:
    """(23,) vector ordered as :data:`DESIGN_VARIABLE_NAMES`."""
    return np.concatenate([design.a, design.t, [design.T1, design.T6, design.B]])


#: Paper Table 3, optimal beam-based design (mm for t, T1, T6, B).
TABLE3_OPTIMUM = ConstantForceDesign(
    a=np.array([0.285, 0.803, 0.582, 0.851, 0.245, 0.842, 0.578, 0.798, 0.231, 0.765]),
    t=np.array([0.997, 0.929, 1.356, 1.339, 0.996, 0.920, 1.440, 1.434, 0.968, 1.046]),
    T1=0.927,
    T6=0.947,
    B=5.138,
)


def _table3_bounds() -> DesignBounds:
    a_rng = [
        (0.125, 0.500), (0.625, 0.875), (0.500, 0.625), (0.750, 0.875), (0.125, 0.375),
        (0.625, 0.875), (0.375, 0.625), (0.750, 0.875), (0.125, 0.375), (0.750, 0.875),
    ]  # fmt: skip
    t_rng = [
        (0.850, 1.100), (0.850, 1.100), (1.200, 1.400), (1.200, 1.400), (0.800, 1.150),
        # The paper prints "[0.800, 1/150]" for t6: a typo for 1.150 (t5 has the same range and
        # the optimum 0.920 lies inside it).
        (0.800, 1.150), (1.300, 1.600), (1.300, 1.600), (0.900, 1.100), (0.900, 1.100),
    ]  # fmt: skip
    rest = [(0.850, 1.100), (0.900, 1.100), (5.000, 8.000)]  # T1, T6, B
    rng = np.array(a_rng + t_rng + rest)
    lower, upper = rng[:, 0].copy(), rng[:, 1].copy()
    lower.setflags(write=False)
    upper.setflags(write=False)
    return DesignBounds(lower, upper)


#: Paper Table 3 ranges (t6 upper bound read as 1.150, see above).
TABLE3_BOUNDS = _table3_bounds()


def joint_points(prb_params: PRBParams = TABLE1) -> np.ndarray:
    """PRB joints in the spring-free configuration.

    Returns
    -------
    (3, 2) float, mm
        Crank pivot O = (0, 0), crank–rod pin A = r1 (cos theta10, sin theta10) and slider pin
        C = (x0, e) (x0 = x_in up to 1.5e-4 mm for Table 1).
    """
    p = prb_params
    a_pin = p.r1_mm * np.array([np.cos(p.theta10_rad), np.sin(p.theta10_rad)])
    return np.array([[0.0, 0.0], a_pin, [p.x0_mm, p.e_mm]])


def reference_points(
    prb_params: PRBParams = TABLE1,
    flexure_length_mm: float = FLEXURE_LENGTH_MM,
    end_flexures: Literal["centred", "outboard"] = "centred",
) -> np.ndarray:
    """Reference points S1..S6: the ends of the three flexural pivots of the lumped design.

    Each flexure's halves lie along the links that meet at its joint; the ground and the slider
    have no direction of their own, so the flexures there continue the crank and the rod. With
    ``u1`` the unit vector O->A, ``u2`` the unit vector A->C and ``L`` the flexure length:

    ``end_flexures="centred"`` (default; the paper's text: "the PRB rigid pairs are located at
    the center of the related small length flexural pivots")::

        S1 = O - L/2 u1,  S2 = O + L/2 u1        (ground pivot, along the crank)
        S3 = A - L/2 u1,  S4 = A + L/2 u2        (crank–rod pin: half on the crank, half on the rod)
        S5 = C - L/2 u2,  S6 = C + L/2 u2        (slider pin, along the rod)

    ``end_flexures="outboard"`` (a hypothesis, see ``docs/constant_force.md``): the ground and
    slider flexures lie outside the PRB link lengths, ``S1 = O - L u1, S2 = O`` and ``S5 = C,
    S6 = C + L u2`` (S3, S4 unchanged). The beam is then L longer (138.2 mm instead of 127.4 mm
    for Table 1), which brings the beam-solver force of the Table-3 design from 1.80 N to 1.55 N,
    near the paper's 1.5 N.

    In both layouts the rigid links S2->S3 (crank) and S4->S5 (rod) lie exactly on the PRB link
    lines; the flexure at A is the chord S3->S4 (the crank and the rod meet at A at an angle of
    only 0.0029 rad for Table 1, so the chord passes 0.008 mm from A).

    Parameters
    ----------
    prb_params : PRBParams
    flexure_length_mm : float, mm — L (Table 2: 10.8).
    end_flexures : "centred" or "outboard"

    Returns
    -------
    (6, 2) float, mm
    """
    L = float(flexure_length_mm)
    if not L > 0:
        raise GeometryError(f"flexure_length_mm = {L:g} must be > 0")
    if end_flexures not in ("centred", "outboard"):
        raise GeometryError(
            f"end_flexures = {end_flexures!r} is not a layout; use 'centred' or 'outboard'"
        )
    o, a_pin, c = joint_points(prb_params)
    r1, r2 = prb_params.r1_mm, prb_params.r2_mm
    # Each link keeps a rigid part only if it is longer than the flexure halves on it.
    link_min = L if end_flexures == "centred" else 0.5 * L
    if not (r1 > link_min and r2 > link_min):
        raise GeometryError(
            f"flexure_length_mm = {L:g} is too long for the crank (r1 = {r1:g} mm) or the rod "
            f"(r2 = {r2:g} mm): each link needs > {link_min:g} mm so that a rigid part remains "
            "between the flexures; use shorter flexures"
        )
    u1 = a_pin / r1
    u2 = (c - a_pin) / np.linalg.norm(c - a_pin)
    h = 0.5 * L
    if end_flexures == "centred":
        ground = (o - h * u1, o + h * u1)
        slider = (c - h * u2, c + h * u2)
    else:
        ground = (o - L * u1, o)
        slider = (c, c + L * u2)
    return np.array([*ground, a_pin - h * u1, a_pin + h * u2, *slider])


def design_points(
    design: ConstantForceDesign,
    prb_params: PRBParams = TABLE1,
    end_flexures: Literal["centred", "outboard"] = "centred",
) -> np.ndarray:
    """Design points p1..p10 by Eq. 13, two per interval S_i->S_{i+1} of
    :func:`reference_points`.

    Returns
    -------
    (10, 2) float, mm
    """
    s = reference_points(prb_params, end_flexures=end_flexures)
    start = np.repeat(s[:-1], 2, axis=0)
    end = np.repeat(s[1:], 2, axis=0)
    return start + design.a[:, None] * (end - start)


def centreline_points(
    design: ConstantForceDesign,
    prb_params: PRBParams = TABLE1,
    end_flexures: Literal["centred", "outboard"] = "centred",
) -> np.ndarray:
    """Centreline vertices S1, p1..p10, S6 (clamped end first).

    Returns
    -------
    (12, 2) float, mm
    """
    s = reference_points(prb_params, end_flexures=end_flexures)
    return np.vstack([s[:1], design_points(design, prb_params, end_flexures), s[-1:]])


def beam_profile(
    design: ConstantForceDesign,
    prb_params: PRBParams = TABLE1,
    end_flexures: Literal["centred", "outboard"] = "centred",
) -> BeamProfile:
    """The tapered beam the paper optimised: straight segments through S1, p1..p10, S6 with
    thickness T1, t1..t10, T6 varying linearly in between, width B.

    The start (S1) is the clamped end; the end (S6) is the slider, driven along
    :data:`WORK_DIRECTION` with rotation and transverse motion held.

    ``end_flexures`` selects the layout of S1..S6, see :func:`reference_points`.

    Returns
    -------
    BeamProfile
        12 points, in the PRB frame (crank pivot at the origin, slider axis along x), mm.
    """
    return BeamProfile(
        points_mm=centreline_points(design, prb_params, end_flexures),
        thickness_mm=design.vertex_thickness_mm,
        width_mm=design.B,
    )


#: Largest miter factor 1/cos(kink/2) accepted at a centreline vertex (a kink of 120 degrees);
#: the centreline of any design lies close to the line S1->S6, with kinks of a few mrad.
_MAX_MITER = 2.0


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _side_offsets(points: np.ndarray, thickness: np.ndarray) -> np.ndarray:
    """(n, 2) mm: offset ``+t/2`` to the left of the centreline, mitred at interior vertices.

    At a vertex the offset point lies on the bisector of the two segment normals, at ``t / 2 /
    cos(kink / 2)`` from the vertex, so that for constant thickness each offset edge is exactly
    parallel to its segment (the area is ``int t ds`` to second order in the kink).
    """
    d = np.diff(points, axis=0)
    d /= np.linalg.norm(d, axis=1)[:, None]
    normals = np.column_stack([-d[:, 1], d[:, 0]])  # left of each segment
    vertex_n = np.vstack([normals[:1], normals[:-1] + normals[1:], normals[-1:]])
    vertex_n /= np.linalg.norm(vertex_n, axis=1)[:, None]
    # cos(kink / 2) between the bisector and either adjacent normal.
    cos_half = np.concatenate([[1.0], np.einsum("ij,ij->i", vertex_n[1:-1], normals[1:]), [1.0]])
    if np.any(cos_half < 1.0 / _MAX_MITER):
        i = int(np.argmin(cos_half))
        raise GeometryError(
            f"the centreline turns by {np.degrees(2 * np.arccos(cos_half[i])):.0f} degrees at "
            f"vertex {i}; the outline supports kinks up to 120 degrees"
        )
    return points + (0.5 * thickness / cos_half)[:, None] * vertex_n


def outline(
    design: ConstantForceDesign,
    prb_params: PRBParams = TABLE1,
    pad_length_mm: float = 8.0,
    pad_thickness_mm: float = 4.0,
    end_flexures: Literal["centred", "outboard"] = "centred",
) -> Polygon:
    """Printable planar outline: the tapered beam plus a clamping pad at each end.

    The beam's two sides are the centreline offset by ``+-t/2`` (``t`` linear between the vertex
    thicknesses), mitred at the vertices; each pad is a ``pad_length_mm x pad_thickness_mm``
    rectangle continuing the end segment outward from S1 and from S6, centred on the centreline.
    The polygon is built as one ring, not as a union of pieces: a boolean union of per-segment
    trapezoids leaves micro-notches (edges of 1e-6 to 1e-3 mm where the pieces meet at a
    near-straight vertex) that a plane-stress mesh resolves into spurious stress peaks twice the
    real ones.

    Parameters
    ----------
    design : ConstantForceDesign
    prb_params : PRBParams
    pad_length_mm, pad_thickness_mm : float, mm
        The pads must be at least as thick as the beam ends (T1, T6) so they hold the whole end
        section.
    end_flexures : "centred" or "outboard" — see :func:`reference_points`.

    Returns
    -------
    shapely.Polygon
        One valid polygon, mm, in the PRB frame; area ``int t ds + 2 pad_length pad_thickness``.
    """
    if not pad_length_mm > 0 or not pad_thickness_mm > 0:
        raise GeometryError(
            f"pad_length_mm = {pad_length_mm:g} and pad_thickness_mm = {pad_thickness_mm:g} "
            "must both be > 0"
        )
    if pad_thickness_mm < max(design.T1, design.T6):
        raise GeometryError(
            f"pad_thickness_mm = {pad_thickness_mm:g} is thinner than the beam end it holds "
            f"(T1 = {design.T1:g}, T6 = {design.T6:g} mm); use a pad at least "
            f"{max(design.T1, design.T6):g} mm thick"
        )
    pts = centreline_points(design, prb_params, end_flexures)
    t = design.vertex_thickness_mm
    left = _side_offsets(pts, t)
    right = _side_offsets(pts, -t)
    half = 0.5 * pad_thickness_mm

    def pad(end: np.ndarray, outward: np.ndarray) -> list[np.ndarray]:
        # Corners of the pad, counter-clockwise when walked from the beam's right side.
        n = np.array([-outward[1], outward[0]])
        far = end + outward * pad_length_mm
        return [end + half * n, far + half * n, far - half * n, end - half * n]

    # Counter-clockwise: right side S1 -> S6, the S6 pad, left side S6 -> S1, the S1 pad. A pad's
    # corners come out of pad() starting on the left of its outward direction, so they are
    # reversed to continue from the side the ring arrives on.
    end_pad = pad(pts[-1], _unit(pts[-1] - pts[-2]))[::-1]
    start_pad = pad(pts[0], _unit(pts[0] - pts[1]))[::-1]
    shape = Polygon([*right, *end_pad, *left[::-1], *start_pad])
    if not shape.is_valid:
        raise GeometryError(
            f"the outline is not a valid polygon ({shapely.is_valid_reason(shape)}); check that "
            "the centreline does not cross itself and that the pads clear the beam"
        )
    return shape


def min_feature_mm(design: ConstantForceDesign) -> float:
    """Thinnest in-plane section of the beam, mm (thickness is linear between vertices, so the
    minimum is at a vertex); compare with the printer's minimum wall."""
    return float(design.vertex_thickness_mm.min())
