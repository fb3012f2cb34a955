"""Compiled (numba) kernels of the planar beam in :mod:`fea.beam`: the same formulation, compiled.

:class:`fea.beam.BeamModel` runs one of two paths with the same physics and the same decisions:

* ``numpy`` (the reference): batched numpy element kernels, ``np.bincount`` assembly, LAPACK
  ``dgbsv`` / ``dpbtrf`` through scipy, the Newton / sub-step / branch-guard loop in Python;
* ``numba`` (this module): the element residual and tangent, the assembly into band storage, the
  banded factorisations and the whole tracing loop compiled once by numba. A Newton iteration on a
  60-element beam then costs tens of microseconds instead of ~320 µs of interpreter overhead.

Linear algebra
--------------
The tangent is symmetric (the Hessian of the strain energy: dead loads, prescribed displacements)
but indefinite past a bifurcation or limit point, and under displacement control the solve runs on
a matrix with identity rows for the held DOFs. Each solve therefore tries a banded Cholesky
factorisation first (a port of LAPACK's unblocked ``dpbtf2``, what ``dpbtrf`` runs for kd = 8, and
``dpbtrs``): it succeeds exactly when the held tangent is positive definite, which it is in most
Newton iterations of a stable path (~94 % of the solves of a constant-force design), and it is
about a third of the LU's work. When a pivot is not positive it stops, the right-hand side
untouched, and the solve is a line-by-line port of LAPACK's unblocked banded LU with partial
pivoting (``dgbtf2``, which is what ``dgbtrf`` runs for a half-bandwidth of 8 < its block size 32)
and ``dgbtrs`` / ``dtbsv``, in fea/_banded.py (fea/_constrained_kernels.py uses it too). A banded
LU *without* pivoting or an LDL^T without a pivoting strategy could break down (a zero or tiny
pivot) on the indefinite matrices, which is why the fallback pivots. The numpy path makes the same
choice by the same test with scipy's LAPACK, and the ports run the same operations in the same
order, so both paths agree to round-off. The stability check is the same Cholesky port; it only
answers "positive definite or not". Calling scipy's LAPACK from numba (through
``scipy.linalg.cython_lapack`` addresses) would embed raw function addresses in the compiled code,
which numba refuses to cache, so every worker would compile again; the ports cache.

Storage
-------
Band storage here is the C-ordered transpose of LAPACK's gbsv layout: ``abc[j, kv + i - j] =
A[i, j]`` with ``kl = ku = 8``, ``kv = kl + ku = 16`` and ``ldab = 2 kl + ku + 1 = 25`` entries per
column; rows ``0 .. kl-1`` of each column are the LU's fill-in workspace. ``abc.T`` is then exactly
the Fortran-ordered ``(ldab, n)`` array that :meth:`fea.beam.BeamModel._assemble` returns and that
``dgbsv`` reads.

Every function is ``@njit(cache=True, fastmath=False, error_model="numpy")``: compiled once per
install (the cache sits in ``fea/__pycache__``, or in ``NUMBA_CACHE_DIR``), IEEE arithmetic
without reassociation (so the answers do not depend on the compiler's vectoriser), and a division
by zero gives inf/NaN as in numpy instead of raising, so a singular or diverging state is detected
by the same tests as in the reference.
"""

from __future__ import annotations

import math

import numpy as np
from flexopt.fea._banded import BAND, KL, KU, KV, LDAB, gbsv
from numba import njit

# the band storage and its LU are fea/_banded.py's (shared with fea/_constrained_kernels.py)
KD = BAND  # superdiagonals of the symmetric (Cholesky) band

#: reason codes of a failed sub-step (the texts are in fea.beam._REASONS)
OK = 0
SINGULAR_PREDICTOR = 1
RESIDUAL_NAN = 2
DIVERGED = 3
SINGULAR = 4
MAX_ITERATIONS = 5
LEFT_PATH = 6
CRITICAL = 7

_jit = njit(cache=True, fastmath=False, error_model="numpy", nogil=True)


# -- element kernels and assembly -----------------------------------------------------------------


@_jit
def physical(q: np.ndarray, frame: np.ndarray, u: np.ndarray) -> None:
    """Physical DOFs ``u`` (n,) from generalised ``q`` (n,): the end node's two translations are
    stored in the drive's (direction, normal) ``frame`` (2, 2), rows = axes in x, y."""
    n = q.shape[0]
    for i in range(n):
        u[i] = q[i]
    i = n - 3
    a, b = q[i], q[i + 1]
    # frame.T @ (a, b), in the order numpy's 2 x 2 product sums it
    u[i] = frame[0, 0] * a + frame[1, 0] * b
    u[i + 1] = frame[0, 1] * a + frame[1, 1] * b


@_jit
def assemble(
    q: np.ndarray, frame: np.ndarray, geo: tuple, u: np.ndarray, r: np.ndarray, abc: np.ndarray
) -> None:
    """Internal force ``r`` (n,) and tangent ``abc`` (n, LDAB) at generalised DOFs ``q`` (n,).

    ``geo`` is :meth:`fea.beam.BeamModel._kernel_geometry`: per element e and Gauss point g the
    shape-function derivatives ``dN`` (E, Q, 3) [1/mm], values ``N`` (Q, 3), weighted
    ``dNw = dN w``, ``Nw = N w`` (E, Q, 3) and products ``dd = dN_k dN_l w``, ``dn = dN_k N_l w``,
    ``nn = N_k N_l w`` (E, Q, 3, 3), the constant bending block ``kbend`` (E, 3, 3) [N mm],
    reference angle ``theta0`` and its cosine / sine (E, Q), and EA, kGA [N], EI [N mm^2]
    (E, Q). ``u`` (n,) is scratch for the physical DOFs. The physics is
    :meth:`fea.beam.BeamModel._element_arrays`; the end node's translations of the last element
    are rotated into (direction, normal) as in :meth:`fea.beam.BeamModel._assemble`.
    """
    dN, N, dNw, Nw, dd, dn, nn, kbend, theta0, c0, s0, ea, kga, ei = geo
    n_el, n_q = theta0.shape
    physical(q, frame, u)
    r[:] = 0.0
    abc[:, :] = 0.0
    re = np.empty(9)
    ke = np.empty((9, 9))
    dx, dy = frame[0, 0], frame[0, 1]
    for e in range(n_el):
        o = 6 * e
        re[:] = 0.0
        ke[:, :] = 0.0
        for g in range(n_q):
            gu = 0.0
            gv = 0.0
            gp = 0.0
            th = 0.0
            for a in range(3):
                gu += dN[e, g, a] * u[o + 3 * a]
                gv += dN[e, g, a] * u[o + 3 * a + 1]
                gp += dN[e, g, a] * u[o + 3 * a + 2]
                th += u[o + 3 * a + 2] * N[g, a]
            th = theta0[e, g] + th
            c = math.cos(th)
            s = math.sin(th)
            x1 = c0[e, g] + gu
            x2 = s0[e, g] + gv
            h1 = c * x1 + s * x2  # 1 + Gamma1
            g2 = c * x2 - s * x1  # Gamma2
            EA = ea[e, g]
            kGA = kga[e, g]
            dk = EA - kGA
            nf = EA * (h1 - 1.0)  # N
            qf = kGA * g2  # Q
            rs0 = nf * c - qf * s
            rs1 = nf * s + qf * c
            rs2 = ei[e, g] * gp
            rs3 = nf * g2 - qf * h1
            dkc2 = dk * (c * c)
            a_uu = kGA + dkc2
            a_uv = dk * (c * s)
            a_vv = EA - dkc2
            A = dk * g2
            B = EA - dk * h1
            c_u = c * A + s * B
            c_v = s * A - c * B
            p = g2 * A + h1 * B
            for k in range(3):
                re[3 * k] += rs0 * dNw[e, g, k]
                re[3 * k + 1] += rs1 * dNw[e, g, k]
                re[3 * k + 2] += rs2 * dNw[e, g, k] + rs3 * Nw[e, g, k]
                for m in range(3):
                    d2 = dd[e, g, k, m]
                    ke[3 * k, 3 * m] += a_uu * d2
                    ke[3 * k, 3 * m + 1] += a_uv * d2
                    ke[3 * k + 1, 3 * m] += a_uv * d2
                    ke[3 * k + 1, 3 * m + 1] += a_vv * d2
                    ke[3 * k, 3 * m + 2] += c_u * dn[e, g, k, m]
                    ke[3 * k + 2, 3 * m] += c_u * dn[e, g, m, k]
                    ke[3 * k + 1, 3 * m + 2] += c_v * dn[e, g, k, m]
                    ke[3 * k + 2, 3 * m + 1] += c_v * dn[e, g, m, k]
                    ke[3 * k + 2, 3 * m + 2] += p * nn[e, g, k, m]
        for k in range(3):
            for m in range(3):
                ke[3 * k + 2, 3 * m + 2] += kbend[e, k, m]
        if e == n_el - 1:
            # T = I with T[6:8, 6:8] = [[dx, -dy], [dy, dx]]: re <- T^T re, ke <- T^T ke T
            a6, a7 = re[6], re[7]
            re[6] = dx * a6 + dy * a7
            re[7] = -dy * a6 + dx * a7
            for i in range(9):
                a6, a7 = ke[i, 6], ke[i, 7]
                ke[i, 6] = a6 * dx + a7 * dy
                ke[i, 7] = a6 * (-dy) + a7 * dx
            for j in range(9):
                a6, a7 = ke[6, j], ke[7, j]
                ke[6, j] = dx * a6 + dy * a7
                ke[7, j] = -dy * a6 + dx * a7
        for i in range(9):
            r[o + i] += re[i]
        for j in range(9):
            col = o + j
            for i in range(9):
                abc[col, KV + i - j] += ke[i, j]


@_jit
def peak_stress(u: np.ndarray, geo: tuple, sgeo: tuple, e_mpa: float) -> tuple[float, float]:
    """Peak ``|N|/A + |M| c / I`` (MPa) over the sampling points and its arc length (mm).

    ``u`` (n,) physical DOFs; ``sgeo`` = (``gauss_to_samples`` (Q, 3), ``dNs`` (E, 3, 3) [1/mm],
    ``EI_s`` (E, 3) [N mm^2], ``Z_s`` (E, 3) [mm^3], ``s_samp`` (E, 3) [mm]); see
    :meth:`fea.beam.BeamModel._stress`. Ties and NaN resolve as ``np.argmax`` does (first one).
    """
    dN, N = geo[0], geo[1]
    theta0, c0, s0 = geo[8], geo[9], geo[10]
    g2s, dNs, ei_s, z_s, s_samp = sgeo
    n_el, n_q = theta0.shape
    g1 = np.empty(n_q)
    best = -np.inf
    where = 0.0
    found_nan = False
    for e in range(n_el):
        o = 6 * e
        for g in range(n_q):
            gu = 0.0
            gv = 0.0
            th = 0.0
            for a in range(3):
                gu += dN[e, g, a] * u[o + 3 * a]
                gv += dN[e, g, a] * u[o + 3 * a + 1]
                th += u[o + 3 * a + 2] * N[g, a]
            th = theta0[e, g] + th
            g1[g] = math.cos(th) * (c0[e, g] + gu) + math.sin(th) * (s0[e, g] + gv) - 1.0
        for m in range(3):
            g1s = 0.0
            for g in range(n_q):
                g1s += g1[g] * g2s[g, m]
            kap = 0.0
            for a in range(3):
                kap += dNs[e, m, a] * u[o + 3 * a + 2]
            sig = e_mpa * abs(g1s) + abs(ei_s[e, m] * kap) / z_s[e, m]
            if not found_nan and (sig > best or math.isnan(sig)):
                best = sig
                where = s_samp[e, m]
                found_nan = math.isnan(sig)
    return best, where


# -- banded linear algebra (the LU is fea/_banded.py's; here LAPACK dpbtf2 / dpbtrs) -------------


@_jit
def hold(abc: np.ndarray, fixed: np.ndarray) -> None:
    """Replace the rows and columns of the ``fixed`` DOFs by identity rows (in band storage)."""
    n = abc.shape[0]
    for c in fixed:
        for j in range(max(0, c - KU), min(n, c + KL + 1)):
            abc[j, KV + c - j] = 0.0  # row c
            abc[c, KV + j - c] = 0.0  # column c
    for c in fixed:
        abc[c, KV] = 1.0


@_jit
def _cholesky_band(up: np.ndarray) -> bool:
    """Banded Cholesky factorisation A = U^T U in place, upper band storage ``up`` (n, KD + 1)
    with ``up[j, KD + i - j] = A[i, j]`` for ``j - KD <= i <= j``. Returns False at the first
    pivot that is not positive (``up`` then holds a partial factor). Port of LAPACK's ``dpbtf2``
    (upper): per column a scaling of row j of U and a rank-1 (``dsyr``) update of the trailing
    KD x KD triangle, in LAPACK's order. The full-band columns (all but the last KD) keep row j
    of U in eight scalars and their 36 updates unrolled: the same operations in the same order,
    which the compiler then schedules without reloading them (~15-20 % of the factorisation)."""
    n = up.shape[0]
    x = np.empty(KD + 1)  # row j of U in the last KD columns, gathered once
    for j in range(n):
        ajj = up[j, KD]
        if not ajj > 0.0:  # also NaN
            return False
        ajj = math.sqrt(ajj)
        up[j, KD] = ajj
        kn = min(KD, n - 1 - j)
        rinv = 1.0 / ajj
        if kn == KD:
            x1 = up[j + 1, KD - 1] * rinv
            up[j + 1, KD - 1] = x1
            x2 = up[j + 2, KD - 2] * rinv
            up[j + 2, KD - 2] = x2
            x3 = up[j + 3, KD - 3] * rinv
            up[j + 3, KD - 3] = x3
            x4 = up[j + 4, KD - 4] * rinv
            up[j + 4, KD - 4] = x4
            x5 = up[j + 5, KD - 5] * rinv
            up[j + 5, KD - 5] = x5
            x6 = up[j + 6, KD - 6] * rinv
            up[j + 6, KD - 6] = x6
            x7 = up[j + 7, KD - 7] * rinv
            up[j + 7, KD - 7] = x7
            x8 = up[j + 8, KD - 8] * rinv
            up[j + 8, KD - 8] = x8
            if x1 != 0.0:
                t = -x1
                up[j + 1, KD + 0] += x1 * t
            if x2 != 0.0:
                t = -x2
                up[j + 2, KD + -1] += x1 * t
                up[j + 2, KD + 0] += x2 * t
            if x3 != 0.0:
                t = -x3
                up[j + 3, KD + -2] += x1 * t
                up[j + 3, KD + -1] += x2 * t
                up[j + 3, KD + 0] += x3 * t
            if x4 != 0.0:
                t = -x4
                up[j + 4, KD + -3] += x1 * t
                up[j + 4, KD + -2] += x2 * t
                up[j + 4, KD + -1] += x3 * t
                up[j + 4, KD + 0] += x4 * t
            if x5 != 0.0:
                t = -x5
                up[j + 5, KD + -4] += x1 * t
                up[j + 5, KD + -3] += x2 * t
                up[j + 5, KD + -2] += x3 * t
                up[j + 5, KD + -1] += x4 * t
                up[j + 5, KD + 0] += x5 * t
            if x6 != 0.0:
                t = -x6
                up[j + 6, KD + -5] += x1 * t
                up[j + 6, KD + -4] += x2 * t
                up[j + 6, KD + -3] += x3 * t
                up[j + 6, KD + -2] += x4 * t
                up[j + 6, KD + -1] += x5 * t
                up[j + 6, KD + 0] += x6 * t
            if x7 != 0.0:
                t = -x7
                up[j + 7, KD + -6] += x1 * t
                up[j + 7, KD + -5] += x2 * t
                up[j + 7, KD + -4] += x3 * t
                up[j + 7, KD + -3] += x4 * t
                up[j + 7, KD + -2] += x5 * t
                up[j + 7, KD + -1] += x6 * t
                up[j + 7, KD + 0] += x7 * t
            if x8 != 0.0:
                t = -x8
                up[j + 8, KD + -7] += x1 * t
                up[j + 8, KD + -6] += x2 * t
                up[j + 8, KD + -5] += x3 * t
                up[j + 8, KD + -4] += x4 * t
                up[j + 8, KD + -3] += x5 * t
                up[j + 8, KD + -2] += x6 * t
                up[j + 8, KD + -1] += x7 * t
                up[j + 8, KD + 0] += x8 * t
        elif kn > 0:
            for m in range(1, kn + 1):
                up[j + m, KD - m] *= rinv
                x[m] = up[j + m, KD - m]
            for bc in range(1, kn + 1):
                xb = x[bc]
                if xb != 0.0:
                    t = -xb
                    for a in range(1, bc + 1):
                        up[j + bc, KD + a - bc] += x[a] * t
    return True


@_jit
def is_positive_definite(abc: np.ndarray, fixed: np.ndarray, up: np.ndarray) -> bool:
    """Is the tangent ``abc`` (n, LDAB) with the ``fixed`` rows and columns eliminated positive
    definite? ``up`` (n, KD + 1) is scratch. See :func:`fea.beam._is_positive_definite`.

    The upper band (``A[i, j]`` for ``j - KD <= i <= j``, rows ``KL .. KV`` of each column) is
    copied, the fixed rows and columns become identity rows, and a port of LAPACK's unblocked
    banded Cholesky ``dpbtf2`` (upper) runs until a pivot is not positive.
    """
    n = abc.shape[0]
    for j in range(n):
        for m in range(KD + 1):
            up[j, m] = abc[j, KL + m]
    for c in fixed:
        for i in range(max(0, c - KD), c + 1):
            up[c, KD + i - c] = 0.0  # column c above the diagonal
        for j in range(c, min(n, c + KD + 1)):
            up[j, KD + c - j] = 0.0  # row c right of the diagonal
        up[c, KD] = 1.0
    return _cholesky_band(up)


# -- the traced path ------------------------------------------------------------------------------


@_jit
def _max_abs(x: np.ndarray, start: int, stride: int) -> float:
    """max |x[start::stride]| with NaN propagating like ``np.abs(x).max()``."""
    m = 0.0
    for i in range(start, x.shape[0], stride):
        v = abs(x[i])
        if math.isnan(v):
            return v
        if v > m:
            m = v
    return m


@_jit
def pbsv(abc: np.ndarray, b: np.ndarray, up: np.ndarray) -> bool:
    """Solve A x = b in place by banded Cholesky, if the symmetric ``abc`` is positive definite.

    ``abc`` (n, LDAB) in gbsv layout, read only (its upper band, rows ``KL .. KV`` of each
    column); ``up`` (n, KD + 1) scratch for the factor. Returns False, with ``b`` untouched,
    when a pivot is not positive (then the caller solves by LU). Port of LAPACK's ``dpbtf2``
    (what ``dpbtrf`` runs for kd = 8 < its block size) and ``dpbtrs`` (``dtbsv`` with U^T, then
    with U), operation for operation, as :func:`fea.beam._solve_constrained` runs them.
    """
    n = abc.shape[0]
    for j in range(n):
        for m in range(KD + 1):
            up[j, m] = abc[j, KL + m]
    if not _cholesky_band(up):
        return False
    # U^T y = b (dtbsv upper, transpose): column j of U is up[j, KD - (j - i)], i < j
    for j in range(n):
        t = b[j]
        for i in range(max(0, j - KD), j):
            t -= up[j, KD + i - j] * b[i]
        b[j] = t / up[j, KD]
    # U x = y (dtbsv upper, no transpose)
    for j in range(n - 1, -1, -1):
        if b[j] != 0.0:
            b[j] = b[j] / up[j, KD]
            t = b[j]
            for i in range(max(0, j - KD), j):
                b[i] -= t * up[j, KD + i - j]
    return True


@_jit
def _solve_held(abc, rhs, fixed, driven, increment, ipiv, up) -> int:
    """:func:`fea.beam._solve_constrained`: hold ``fixed``, prescribe ``driven``, solve in place.

    Banded Cholesky when the held tangent is positive definite (a stable state, most Newton
    iterations), the pivoting LU otherwise (past a bifurcation or limit point, or far from
    equilibrium): the same choice, by the same test, as the numpy path.
    """
    hold(abc, fixed)
    for c in fixed:
        rhs[c] = 0.0
    if driven >= 0:
        rhs[driven] = increment
    if pbsv(abc, rhs, up):
        return 0
    return gbsv(abc, rhs, ipiv)


@_jit
def newton(
    q0,
    r0,
    ab0,
    value0,
    value,
    n_hist,
    v1,
    q1,
    v2,
    q2,
    geo,
    frame,
    fixed,
    is_fixed,
    driven,
    loaded,
    fpar,
    ipar,
    q,
    r,
    ab,
    work,
    ipiv,
    up,
    u,
) -> tuple[bool, int, int]:
    """One sub-step from the converged state (``q0``, ``r0``, ``ab0``) at ``value0`` to ``value``.

    Port of :meth:`fea.beam.BeamModel._newton` followed by ``_checked``. Writes the converged
    state into ``q``, ``r``, ``ab``; ``work`` (n,) and ``ipiv`` (n,) are scratch. Returns
    ``(converged, iterations, reason code)``.
    """
    rtol, dtol, max_rot, min_cos, force_floor, length_scale = (
        fpar[0],
        fpar[3],
        fpar[4],
        fpar[6],
        fpar[7],
        fpar[8],
    )
    max_iterations, secant = ipar[0], ipar[2]
    n = q0.shape[0]
    inc = value - value0
    load = 0.0
    if loaded >= 0:
        load = abs(value)
    sane_limit = 1e3 * length_scale
    # strides as run-time integers: a literal argument would compile a second specialisation
    one = ipar[3]
    zero = one - one
    two = one + one
    three = two + one

    if secant == 1 and n_hist >= 2 and v2 != v1:
        f = inc / (v2 - v1)
        for i in range(n):
            q[i] = q2[i] + (q2[i] - q1[i]) * f
        iters = 0
    else:
        # tangent predictor: the prescribed increment is imposed inside the linear solve
        for i in range(n):
            work[i] = -r0[i]
        if loaded >= 0:
            work[loaded] = value - r0[loaded]
        ab[:, :] = ab0
        if driven >= 0:
            c = driven
            for i in range(max(0, c - KU), min(n, c + KL + 1)):
                work[i] -= ab0[c, KV + i - c] * inc
        info = _solve_held(ab, work, fixed, driven, inc, ipiv, up)
        if info != 0 or not (_max_abs(work, zero, one) < sane_limit):
            return False, 1, SINGULAR_PREDICTOR
        for i in range(n):
            q[i] = q0[i] + work[i]
        iters = 1
    q_pred = q.copy()
    assemble(q, frame, geo, u, r, ab)

    ref = -1.0
    for _ in range(max_iterations):
        norm2 = 0.0
        react2 = 0.0
        for i in range(n):
            res = r[i] - (value if i == loaded else 0.0)
            work[i] = res
            if is_fixed[i]:
                react2 += r[i] * r[i]
            else:
                norm2 += res * res
        norm = math.sqrt(norm2)
        if not math.isfinite(norm):
            return False, iters, RESIDUAL_NAN
        scale = max(math.sqrt(react2), load, force_floor)
        if ref < 0.0:
            ref = norm
        if iters > 3 and norm > 1e6 * max(ref, rtol * scale):
            return False, iters, DIVERGED
        converged = norm <= rtol * scale
        if converged and iters > 0:
            return _checked(q0, q_pred, q, min_cos), iters, _left(q0, q_pred, q, min_cos)
        for i in range(n):
            work[i] = -work[i]
        info = _solve_held(ab, work, fixed, driven, 0.0, ipiv, up)
        if info != 0 or not (_max_abs(work, zero, one) < sane_limit):
            return False, iters, SINGULAR
        # Damp corrections that turn a section by more than max_rotation_step (see _newton).
        big = _max_abs(work, two, three) / max_rot
        if big > 1.0:
            for i in range(n):
                work[i] = work[i] / big
        for i in range(n):
            q[i] = q[i] + work[i]
        iters += 1
        assemble(q, frame, geo, u, r, ab)
        if converged or _max_abs(work, zero, one) <= dtol * length_scale:
            return _checked(q0, q_pred, q, min_cos), iters, _left(q0, q_pred, q, min_cos)
    return False, iters, MAX_ITERATIONS


@_jit
def _checked(q0, q_pred, q, min_cos) -> bool:
    """False when the increment turned away from the predicted one (see ``_checked``)."""
    pp = 0.0
    pc = 0.0
    cc = 0.0
    for i in range(q0.shape[0]):
        dp = q_pred[i] - q0[i]
        dc = q[i] - q0[i]
        pp += dp * dp
        pc += dp * dc
        cc += dc * dc
    return not (pc < min_cos * math.sqrt(pp * cc))


@_jit
def _left(q0, q_pred, q, min_cos) -> int:
    return OK if _checked(q0, q_pred, q, min_cos) else LEFT_PATH


@_jit
def _store(k, q, r, frame, geo, sgeo, e_mpa, u, q_rows, r_end, stress, stress_s) -> None:
    n = q.shape[0]
    for i in range(n):
        q_rows[k, i] = q[i]
    for i in range(3):
        r_end[k, i] = r[n - 3 + i]
    physical(q, frame, u)
    stress[k], stress_s[k] = peak_stress(u, geo, sgeo, e_mpa)


@_jit
def trace(geo, sgeo, e_mpa, frame, fixed, driven, loaded, targets, fpar, ipar):
    """Trace the response: port of :meth:`fea.beam.BeamModel.solve` (same sub-steps, guards and
    stability bookkeeping).

    Parameters
    ----------
    geo, sgeo, e_mpa : see :func:`assemble` and :func:`peak_stress`.
    frame : (2, 2) rows = the drive's (direction, normal) in x, y.
    fixed : (n_fixed,) int64 — held or prescribed DOFs (generalised numbering).
    driven, loaded : DOF under displacement / force control, or -1.
    targets : (steps + 1,) driven value of each row, mm or N.
    fpar : (rtol, first_substep, min_substep, dtol, max_rotation_step, min_critical_substep,
        min_path_cosine, force_floor [N], length_scale [mm]).
    ipar : (max_iterations, fast_iterations, secant predictor 1/0, 1).

    Returns
    -------
    q_rows (rows, n) generalised DOFs of each stored row; r_end (rows, 3) internal force of the
    end node's three DOFs [N, N, N mm]; stress, stress_s (rows,) [MPa, mm]; iterations (rows,);
    converged, stable (rows,) bool; ints = (ok, reason, substeps, lost row or -1); floats =
    (last converged value, failed increment, last stable value, first unstable value).
    """
    dN = geo[0]
    n = 3 * (2 * dN.shape[0] + 1)
    first_substep, min_substep, min_crit = fpar[1], fpar[2], fpar[5]
    fast_iterations = ipar[1]
    n_rows = targets.shape[0]
    steps = n_rows - 1
    max_value = targets[steps]

    q_rows = np.full((n_rows, n), np.nan)
    r_end = np.full((n_rows, 3), np.nan)
    stress = np.full(n_rows, np.nan)
    stress_s = np.full(n_rows, np.nan)
    iterations = np.zeros(n_rows, dtype=np.int64)
    converged_rows = np.zeros(n_rows, dtype=np.bool_)
    stable_rows = np.zeros(n_rows, dtype=np.bool_)
    ints = np.zeros(4, dtype=np.int64)
    floats = np.full(4, np.nan)

    is_fixed = np.zeros(n, dtype=np.bool_)
    for c in fixed:
        is_fixed[c] = True
    u = np.empty(n)
    work = np.empty(n)
    ipiv = np.empty(n, dtype=np.int64)
    up = np.empty((n, KD + 1))
    q = np.zeros(n)
    r = np.empty(n)
    ab = np.empty((n, LDAB))
    q_new = np.empty(n)
    r_new = np.empty(n)
    ab_new = np.empty((n, LDAB))
    q1 = np.zeros(n)  # secant history: (v1, q1) older, (v2, q2) newer
    q2 = np.zeros(n)
    v1 = 0.0
    v2 = 0.0
    # np.int64(...): run-time integers, not literals (a literal argument compiles a callee twice)
    n_hist = np.int64(1)

    assemble(q, frame, geo, u, r, ab)
    _store(np.int64(0), q, r, frame, geo, sgeo, e_mpa, u, q_rows, r_end, stress, stress_s)
    converged_rows[0] = True
    stable = is_positive_definite(ab, fixed, up)
    stable_rows[0] = stable
    lost_k = -1

    value = 0.0
    step_size = abs(targets[1] - targets[0]) if n_rows > 1 else 0.0
    h = first_substep * step_size
    substeps = 0
    ok = True
    for k in range(1, steps + 1):
        target = targets[k]
        iters_row = 0
        row_stable = True
        direction_sign = 1.0 if target - value >= 0.0 else -1.0  # np.sign(...) or 1.0
        while abs(target - value) > 1e-12 * max(1.0, abs(max_value)):
            inc = direction_sign * min(h, abs(target - value))
            conv, its, reason = newton(
                q,
                r,
                ab,
                value,
                value + inc,
                n_hist,
                v1,
                q1,
                v2,
                q2,
                geo,
                frame,
                fixed,
                is_fixed,
                driven,
                loaded,
                fpar,
                ipar,
                q_new,
                r_new,
                ab_new,
                work,
                ipiv,
                up,
                u,
            )
            iters_row += its
            substeps += 1
            is_stable = False
            if conv:
                is_stable = is_positive_definite(ab_new, fixed, up)
                if stable and not is_stable and abs(inc) > min_crit * step_size:
                    conv = False
                    reason = CRITICAL
            if conv:
                if stable and not is_stable and lost_k < 0:
                    lost_k = k
                    floats[2] = value
                    floats[3] = value + inc
                q, q_new = q_new, q
                r, r_new = r_new, r
                ab, ab_new = ab_new, ab
                value += inc
                stable = is_stable
                row_stable = row_stable and is_stable
                # history = [history[-1], (value, q)]
                q1, q2 = q2, q1
                v1 = v2
                for i in range(n):
                    q2[i] = q[i]
                v2 = value
                n_hist = min(n_hist + 1, np.int64(2))
                if its <= fast_iterations:
                    h = min(2.0 * h, step_size)
                continue
            h = abs(inc) / 4.0
            if h < min_substep * step_size:
                ok = False
                ints[1] = reason
                floats[0] = value
                floats[1] = inc
                break
            n_hist = np.int64(1)  # restart the secant predictor from the current state
        if not ok:
            break
        _store(k, q, r, frame, geo, sgeo, e_mpa, u, q_rows, r_end, stress, stress_s)
        iterations[k] = iters_row
        converged_rows[k] = True
        stable_rows[k] = row_stable
    ints[0] = 1 if ok else 0
    ints[2] = substeps
    ints[3] = lost_k
    return q_rows, r_end, stress, stress_s, iterations, converged_rows, stable_rows, ints, floats
