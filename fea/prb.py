"""The pseudo-rigid-body (PRB) model of the long-stroke constant-force mechanism (Bilancia,
Geraci, Berselli, SMASIS 2019): the mechanics of the linkage whose shape
:mod:`geometry.constant_force` lays out.

Two layers of the paper's design flow, in the PRB frame of :mod:`geometry.constant_force` (crank
pivot O at the origin, slider on ``y = e``, stroke ``dx = x0 - x >= 0`` along ``(-1, 0)``; the
derivation is in ``docs/constant_force.md``):

1. **PRB eccentric slider-crank** (paper Eqs. 1–11): position analysis, spring energy, output
   force from the energy derivative, the paper's virtual-work terms (Eqs. 3–5, corrected) and the
   Table-1 force curve; :func:`optimise_prb` re-synthesises Table-1-like parameters for any target
   force and stroke.
2. **Lumped compliance** (Eq. 12): small-length flexural pivots ``K = E I / L`` (sized both ways
   in :mod:`fea.scaling`), with the pivot bending stress ``sigma = E h |Psi| / (2 L)`` and the
   stroke at which it reaches the allowable stress; :func:`prb_report` is the paper's first stage
   for any target (a fit plus lumped flexures).

**Output force** ``F = dU/d(dx) = -dU/dx`` with ``U = 1/2 sum K_i Psi_i^2``: the force with which
the slider pushes back against the compression, positive like a compression spring (the paper
plots +1.5 N). The paper's Eqs. 3–5, once the bracket of Eq. 5 is fixed, sum to ``+dU/dx``: the
x-component of the force one applies to the slider, which is negative in compression. So the
output force is ``-(F1 + F2 + F3)``.

Moved from ``geometry/constant_force.py`` (issue #24: physics in fea/); the errors are still
:class:`geometry.errors.GeometryError`, as before the move. Units: mm, N, N·mm, rad, MPa.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from flexopt.fea.scaling import (
    flexure_stiffness_Nmm,
    flexure_thickness_mm,
    flexure_width_mm,
    require_positive,
)
from flexopt.geometry.constant_force import (
    TABLE1,
    PRBParams,
    rod_angle_rad,
    slider_x_mm,
)
from flexopt.geometry.errors import GeometryError

__all__ = [
    "PRBState",
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
    "prb_report",
    "prb_report_once",
    "prb_frame_comparison",
]

# ----------------------------------------------------------------------------------------------
# 1. PRB eccentric slider-crank
# ----------------------------------------------------------------------------------------------


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
    x0 = float(slider_x_mm(r1, r2, e, theta10))
    theta30 = float(rod_angle_rad(r1, r2, e, theta10))
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
    # imported here: scipy.optimize (~0.1 s CPU) is not needed to import this module (every
    # constant-force study does), only to re-synthesise the PRB parameters
    from scipy.optimize import minimize

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


def pivot_stress_MPa(
    E_MPa: float, thickness_mm: np.ndarray, length_mm: np.ndarray, psi_rad: np.ndarray
) -> np.ndarray:
    """Peak bending stress of a flexural pivot bent uniformly through ``psi``:
    ``sigma = M c / I = (E I psi / L)(h / 2) / I = E h |psi| / (2 L)``. Broadcasts.

    Returns
    -------
    float or array, MPa
    """
    h = require_positive("thickness_mm", thickness_mm)
    L = require_positive("length_mm", length_mm)
    E = require_positive("E_MPa", E_MPa)
    return E * h * np.abs(np.asarray(psi_rad, dtype=float)) / (2.0 * L)


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
# The paper's first stage for a study (moved from pipeline/studies/constant_force.py)
# ----------------------------------------------------------------------------------------------


def prb_report(
    target_force_N: float,
    stroke_mm: float,
    E_MPa: float = 1800.0,
    allowable_MPa: float = 42.5,
    flexure_thickness_mm: float = 0.8,
    x_in_mm: float = 100.0,
    e_mm: float = 60.0,
) -> dict[str, Any]:
    """The paper's first stage for any target: Table-1-like PRB parameters and lumped flexures.

    :func:`optimise_prb` finds ``r1, theta10, K1..K3`` whose force stays
    at ``target_force_N`` over ``stroke_mm`` (Eq. 8, ~1 s). The flexures that realise the K are
    sized at ``flexure_thickness_mm`` (the printable minimum gives the narrowest pivots and so the
    longest stroke before a pivot reaches ``allowable_MPa``, as ``sigma = E h |Psi| / (2 L)``)
    and the paper's 10.8 mm length: ``b = 12 K L / (E h^3)`` (Eq. 12).

    Parameters
    ----------
    target_force_N : float, N
    stroke_mm : float, mm
    E_MPa : float, MPa — Young's modulus of the flexures (ABS: 1800).
    allowable_MPa : float, MPa
    flexure_thickness_mm : float, mm
    x_in_mm, e_mm : float, mm — the fixed slider position (Eq. 10; paper: 100 and 60).

    Returns
    -------
    dict
        ``r1_mm``, ``theta10_rad``, ``K_Nmm_per_rad``, ``r2_mm``, ``rms_error_N``,
        ``relative_rms_error``, ``force_range_N``, ``lumped_flexures`` (thickness, length, widths,
        ``stress_limited_stroke_mm``), the paper's ``table1`` for comparison; or ``skipped``.
    """
    t0 = time.perf_counter()
    try:
        fit = optimise_prb(target_force_N, stroke_mm, x_in_mm, e_mm)
    except GeometryError as exc:
        return {"skipped": str(exc)}
    p = fit.params
    h, length = flexure_thickness_mm, 10.8
    K = p.stiffness_Nmm
    widths = [float(flexure_width_mm(k, E_MPa, h, length)) if k > 0 else 0.0 for k in K]
    limit = stress_limited_stroke_mm(p, E_MPa, allowable_MPa, h, length, max_stroke_mm=60.0)
    return {
        "target_force_N": float(target_force_N),
        "stroke_mm": float(stroke_mm),
        "r1_mm": p.r1_mm,
        "theta10_rad": p.theta10_rad,
        "K_Nmm_per_rad": K.tolist(),
        "r2_mm": p.r2_mm,
        "rms_error_N": fit.rms_error_N,
        "relative_rms_error": fit.relative_rms_error,
        "force_range_N": [float(fit.force_N.min()), float(fit.force_N.max())],
        "lumped_flexures": {
            "thickness_mm": h,
            "length_mm": length,
            "width_mm": widths,
            "stress_limited_stroke_mm": None if math.isinf(limit) else limit,
        },
        "table1": {
            "r1_mm": TABLE1.r1_mm,
            "theta10_rad": TABLE1.theta10_rad,
            "K_Nmm_per_rad": TABLE1.stiffness_Nmm.tolist(),
        },
        "time_s": time.perf_counter() - t0,
    }


#: prb_report's answers by their arguments, in this process (:func:`prb_report_once`)
_REPORTS: dict[tuple[float, ...], dict[str, Any]] = {}


def prb_report_once(
    target_force_N: float,
    stroke_mm: float,
    E_MPa: float = 1800.0,
    allowable_MPa: float = 42.5,
    flexure_thickness_mm: float = 0.8,
    x_in_mm: float = 100.0,
    e_mm: float = 60.0,
) -> dict[str, Any]:
    """:func:`prb_report` made once per process for the same arguments; a copy each call.

    The synthesis depends on the arguments alone (a deterministic least-squares fit), not on a
    design, and costs ~0.2 s CPU: a run's report thread makes it while the workers solve
    (``ConstantForceProblem.warm_up_detail``), so the report does not make it on its critical path.
    ``time_s`` is the first call's.
    """
    key = (
        float(target_force_N),
        float(stroke_mm),
        float(E_MPa),
        float(allowable_MPa),
        float(flexure_thickness_mm),
        float(x_in_mm),
        float(e_mm),
    )
    if key not in _REPORTS:
        _REPORTS[key] = prb_report(*key)
    return copy.deepcopy(_REPORTS[key])


def prb_frame_comparison(
    stroke_mm: np.ndarray, force_N: np.ndarray, lo: float, hi: float
) -> dict[str, Any]:
    """A beam's force curve against the PRB model whose joints it is laid out on (Table 1): the
    beam is the paper's 'smoothed' PRB mechanism, so this shows how far the smoothing moved the
    force. Compared at four strokes spread over ``(lo, hi]`` (mm; ``hi`` alone when the range is
    empty), the beam's force (N) interpolated on its rows ``stroke_mm`` (m,), ``force_N`` (m,).

    Moved from ``pipeline/studies/constant_force.py``.
    """
    strokes = np.linspace(lo, hi, 5)[1:] if hi > lo else np.array([hi])
    prb = prb_force_N(TABLE1, strokes)
    beam = np.interp(strokes, stroke_mm, force_N)
    return {
        "model": "PRB slider-crank of paper Table 1 (r1 = 54 mm, theta10 = 0.542 rad)",
        "stroke_mm": strokes.tolist(),
        "prb_force_N": prb.tolist(),
        "beam_force_N": beam.tolist(),
        "beam_over_prb": (beam / prb).tolist(),
    }
