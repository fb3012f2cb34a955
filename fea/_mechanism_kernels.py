"""Compiled (numba) Newton of :mod:`fea.mechanism`: the reference's loop, as machine code.

:class:`fea.mechanism._Solver` runs one of two paths with the same physics and the same decisions:

* ``numpy`` (the reference): the beams' tangents scattered into a scipy sparse matrix, the
  constraint Jacobian and the Hessian of the Lagrangian built in scipy, the KKT system built with
  ``scipy.sparse.bmat`` and solved by SuperLU every iteration, the Newton loop in Python;
* ``numba`` (this module): the whole Newton loop of one sub-step. The beams are assembled by the
  beam kernel (:func:`fea._constrained_kernels.assemble_all`, bit for bit the beam model's), the
  constraint rows ``g = A z + h(z) - b0 - p bp`` and their Jacobian ``G`` (dense, m x N: m is a
  few tens) here, and the KKT system ``[[K - Kf, -G^T], [G, 0]]`` is solved by the constrained
  engine's bordering (:func:`fea._constrained_kernels.kkt_solve`: a banded LU of the beams' band,
  made regular by the local rows, and a small dense Schur complement over the bodies' DOFs and
  the multipliers). ``Kf`` is the constraint-Hessian term: ``lam_i d2g_i/dtheta2`` on the
  rotation DOF of the body a nonlinear row turns with (a diagonal entry among the extra unknowns).

Where the bordering cannot take a system (a beam that no local row holds, an exactly singular
band, a correction that fails the a-posteriori backward-error check) the kernel returns
``FALLBACK`` and the caller runs the reference for that sub-step: a faster route to the same
solution, never a different answer.

Every function is ``@njit(cache=True, fastmath=False, error_model="numpy", nogil=True)`` as in
fea/_beam_kernels.py: compiled once per install, IEEE arithmetic without reassociation.
"""

from __future__ import annotations

import math

import numpy as np
from flexopt.fea._beam_kernels import KV
from flexopt.fea._constrained_kernels import (
    BACKWARD_TOL,
    FALLBACK,
    MAX_ITERATIONS,
    OK,
    RESIDUAL_NAN,
    SINGULAR,
    STEP_NAN,
    assemble_all,
    backward_error,
    constraint_rows,
    kkt_negatives_band,
    kkt_solve,
)
from numba import njit

#: status codes of a sub-step (the constrained engine's, and DIVERGED; texts in fea.mechanism)
__all__ = [
    "DIVERGED",
    "FALLBACK",
    "MAX_ITERATIONS",
    "OK",
    "RESIDUAL_NAN",
    "SINGULAR",
    "STEP_NAN",
    "constraints",
    "kkt_negatives_band",
    "newton",
]

#: the residual grew by 1e6 over its first value (far off the path: the reference's "diverged")
DIVERGED = 6

_jit = njit(cache=True, fastmath=False, error_model="numpy", nogil=True)


@_jit
def constraints(z, p, A, b0, bp, nl_row, nl_theta, nl_off, nl_w, g, G, ro) -> None:
    """Constraint values ``g`` (m,), Jacobian ``G`` (m, N) and ``ro`` (k,) = d2g/dtheta2 of the
    k nonlinear terms at (z, p), as :meth:`fea.mechanism._Model.constraints`.

    ``A`` (m, N) dense linear part; the nonlinear term k adds ``w . (R(theta) o - o)`` to row
    ``nl_row[k]`` with theta = z[nl_theta[k]], offset o = nl_off[k] (mm), weights w = nl_w[k].
    """
    m, n = A.shape
    for q in range(m):
        s = 0.0
        for j in range(n):
            a = A[q, j]
            G[q, j] = a
            if a != 0.0:
                s += a * z[j]
        g[q] = s - b0[q] - p * bp[q]
    for k in range(nl_row.shape[0]):
        th = z[nl_theta[k]]
        c = math.cos(th)
        s = math.sin(th)
        ox = nl_off[k, 0]
        oy = nl_off[k, 1]
        wx = nl_w[k, 0]
        wy = nl_w[k, 1]
        # w . R(theta) o, w . R'(theta) o; and R'' = -R
        wro = wx * (c * ox - s * oy) + wy * (s * ox + c * oy)
        wdro = wx * (-s * ox - c * oy) + wy * (c * ox - s * oy)
        g[nl_row[k]] += wro - (wx * ox + wy * oy)
        G[nl_row[k], nl_theta[k]] += wdro
        ro[k] = -wro


@_jit
def _hessian_term(lam, nl_row, ro, kf_v) -> None:
    """kf_v (k,) = lam_i d2g_i/dtheta2 per nonlinear term: H = K - diag on the theta DOFs."""
    for k in range(nl_row.shape[0]):
        kf_v[k] = lam[nl_row[k]] * ro[k]


@_jit
def newton(
    z, lam, p, f, has_predictor, A, b0, bp, nl_row, nl_theta, nl_off, nl_w, geo, eoff,
    offsets, frame, rot, fpar, max_iterations, r, abc, G, kf_v, z_pred,
) -> tuple[int, int]:  # fmt: skip
    """:meth:`fea.mechanism._Solver.newton`'s loop at drive value ``p`` from (z, lam) in place.

    ``z`` (N,) and ``lam`` (m,) are the start (the secant predictor when ``has_predictor``);
    ``f`` (N,) the applied loads (N, N mm); ``fpar`` = (rtol, ctol, dtol, max_rotation_step,
    length [mm], force floor [N]). On OK, ``z``, ``lam`` are the equilibrium, ``r`` (N,) its
    internal force, ``abc`` (N_b, LDAB) the beams' band tangent, ``G`` (m, N) the constraint
    Jacobian and ``kf_v`` (k,) the constraint-Hessian term there; ``z_pred`` (N,) is the
    predicted state (the predictor, or the first Newton iterate). Returns (status, iterations)
    with the reference's iteration count.
    """
    rtol, ctol, dtol, max_rot, length, force_floor = (
        fpar[0],
        fpar[1],
        fpar[2],
        fpar[3],
        fpar[4],
        fpar[5],
    )
    n = z.shape[0]
    m = lam.shape[0]
    nb = abc.shape[0]
    u = np.empty(n)
    work = np.empty(n)
    g = np.empty(m)
    ro = np.empty(nl_row.shape[0])
    rhs = np.empty(n + m)
    x = np.empty(n + m)
    fnorm = 0.0
    for v in f:
        fnorm += v * v
    fnorm = math.sqrt(fnorm)
    pred_set = has_predictor
    if has_predictor:
        z_pred[:] = z
    first = -1.0
    rho = -1.0
    for it in range(1, max_iterations + 1):
        assemble_all(z, geo, eoff, offsets, frame, u, r, abc)
        for v in r:
            if not math.isfinite(v):
                return RESIDUAL_NAN, it
        if rho < 0.0:
            # the weight of the local rows in the bordering: any positive value gives the same
            # solution; the band's scale keeps the band block well conditioned
            rho = 1.0
            for j in range(nb):
                rho = max(rho, abs(abc[j, KV]))
        constraints(z, p, A, b0, bp, nl_row, nl_theta, nl_off, nl_w, g, G, ro)
        _hessian_term(lam, nl_row, ro, kf_v)
        for i in range(n):
            work[i] = 0.0
        for q in range(m):
            lq = lam[q]
            for j in range(n):
                gv = G[q, j]
                if gv != 0.0:
                    work[j] += gv * lq
        ct = 0.0
        res2 = 0.0
        for i in range(n):
            ct += work[i] * work[i]
            v = r[i] - f[i] - work[i]
            rhs[i] = -v
            res2 += v * v
        scale = max(math.sqrt(ct), fnorm, force_floor)
        norm = math.sqrt(res2)
        res_ok = norm <= rtol * scale
        if first < 0.0:
            first = norm
        if it > 4 and norm > 1e6 * max(first, rtol * scale):
            return DIVERGED, it
        gmax = 0.0
        for q in range(m):
            rhs[n + q] = -g[q]
            a = abs(g[q])
            if math.isnan(a):
                gmax = a
                break
            gmax = max(gmax, a)
        if res_ok and gmax <= ctol * length and (it > 1 or has_predictor):
            return OK, it - 1
        ptr, idx, val, local = constraint_rows(G, nb)
        code = kkt_solve(abc, n, ptr, idx, val, local, rho, nl_theta, nl_theta, kf_v, rhs, x)
        if code != OK:
            return code, it
        dmax = 0.0
        for i in range(n + m):
            if not math.isfinite(x[i]):
                return STEP_NAN, it
            if i < n:
                dmax = max(dmax, abs(x[i]))
        if not backward_error(abc, n, ptr, idx, val, nl_theta, nl_theta, kf_v, rhs, x) <= (
            BACKWARD_TOL
        ):
            return FALLBACK, it
        if dmax > 1e3 * length:
            return STEP_NAN, it
        # Damp corrections that turn a section or a body by more than max_rotation_step.
        big = 0.0
        for i in rot:
            big = max(big, abs(x[i]))
        big = big / max_rot
        if big > 1.0:
            dmax = 0.0
            for i in range(n + m):
                x[i] = x[i] / big
                if i < n:
                    dmax = max(dmax, abs(x[i]))
        for i in range(n):
            z[i] = z[i] + x[i]
        for q in range(m):
            lam[q] = lam[q] + x[n + q]
        if not pred_set:
            z_pred[:] = z  # the linearised predictor (first Newton iterate from the last state)
            pred_set = True
        if dmax <= dtol * length:
            assemble_all(z, geo, eoff, offsets, frame, u, r, abc)
            constraints(z, p, A, b0, bp, nl_row, nl_theta, nl_off, nl_w, g, G, ro)
            _hessian_term(lam, nl_row, ro, kf_v)
            gmax = 0.0
            for q in range(m):
                a = abs(g[q])
                if math.isnan(a):
                    gmax = a
                    break
                gmax = max(gmax, a)
            if gmax <= ctol * length:
                return OK, it
    return MAX_ITERATIONS, max_iterations
