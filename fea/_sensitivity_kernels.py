"""Compiled (numba) kernel of :mod:`fea.beam_sensitivity`: the fibre stresses from statics and
their derivatives over every differentiated row (``stress="statics"``, the constant-force
study's Jacobian).

:func:`fea.beam_sensitivity._statics_terms_rows` is the numpy reference: the same formulas in
the same order, one array operation at a time over (rows, elements, 3 points, variables), ~30
temporaries of ~1.4 MB each on the example's design (33 rows, 72 elements, 24 variables), which
made it the largest single cost of a Jacobian. Here each (row, point) is one pass over the
variables, no temporaries. ``@njit(cache=True, fastmath=False, error_model="numpy",
nogil=True)`` as fea/_beam_kernels.py: compiled once per install (the cache in
``fea/__pycache__`` or ``NUMBA_CACHE_DIR``), IEEE arithmetic without reassociation or
contraction, so the numbers are the reference's to round-off (the tests compare them).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_jit = njit(cache=True, fastmath=False, error_model="numpy", nogil=True)


@_jit
def statics_fibres(
    U: np.ndarray,
    dU: np.ndarray,
    R: np.ndarray,
    dr: np.ndarray,
    frame: np.ndarray,
    ref: np.ndarray,
    theta0: np.ndarray,
    b: float,
    t: np.ndarray,
    Z: np.ndarray,
    dt: np.ndarray,
    db: np.ndarray,
    xarm: np.ndarray,
    xtheta: np.ndarray,
    fibre: np.ndarray,
    d_fibre: np.ndarray,
) -> None:
    """Signed fibre stresses ``a + c``, ``a - c`` from statics and their derivatives, written
    into ``fibre`` (K, 3 E, 2) MPa and ``d_fibre`` (K, 3 E, 2, n_var) MPa per unit.

    ``a = N / (b t)``, ``c = M / Z`` at the sampling points (element e, point j: node 2 e + j),
    ``M = M_end + (r_end - r) x F``, ``N = F . (cos theta, sin theta)``. Per row k: ``U`` (K, n)
    physical DOFs, ``dU`` (K, n, n_var) their derivatives, ``R`` (K, n) the forces (end force
    along the rows of ``frame`` (2, 2), moment last) and ``dr`` (K, n, n_var). Per design:
    ``ref`` (n_nodes, 2) mm the reference nodes, ``theta0`` (E, 3) rad, ``b`` mm, ``t`` and
    ``Z`` (E, 3) mm and mm^3 (b t^2 / 6), ``dt`` (E, 3, n_var) and ``db`` (n_var,) the explicit
    derivatives of the thickness and width, ``xarm`` (E, 3, 2, n_var) and ``xtheta`` (E, 3,
    n_var) those of the lever arm and the reference angle (the vertex moves; zero otherwise).
    """
    n_rows, n = U.shape
    n_var = dU.shape[2]
    n_el = theta0.shape[0]
    end = n // 3 - 1
    ia, it, ir = n - 3, n - 2, n - 1
    f00, f01, f10, f11 = frame[0, 0], frame[0, 1], frame[1, 0], frame[1, 1]
    for k in range(n_rows):
        F0 = R[k, ia] * f00 + R[k, it] * f10
        F1 = R[k, ia] * f01 + R[k, it] * f11
        pe0 = ref[end, 0] + U[k, 3 * end]
        pe1 = ref[end, 1] + U[k, 3 * end + 1]
        for e in range(n_el):
            for j in range(3):
                node = 2 * e + j
                s = 3 * e + j
                arm0 = pe0 - (ref[node, 0] + U[k, 3 * node])
                arm1 = pe1 - (ref[node, 1] + U[k, 3 * node + 1])
                theta = theta0[e, j] + U[k, 3 * node + 2]
                cos, sin = math.cos(theta), math.sin(theta)
                M = R[k, ir] + arm0 * F1 - arm1 * F0
                N = F0 * cos + F1 * sin
                bt = b * t[e, j]
                a = N / bt
                c = M / Z[e, j]
                fibre[k, s, 0] = a + c
                fibre[k, s, 1] = a - c
                rot = -F0 * sin + F1 * cos
                for v in range(n_var):
                    dF0 = f00 * dr[k, ia, v] + f10 * dr[k, it, v]
                    dF1 = f01 * dr[k, ia, v] + f11 * dr[k, it, v]
                    darm0 = dU[k, 3 * end, v] - dU[k, 3 * node, v] + xarm[e, j, 0, v]
                    darm1 = dU[k, 3 * end + 1, v] - dU[k, 3 * node + 1, v] + xarm[e, j, 1, v]
                    dtheta = dU[k, 3 * node + 2, v] + xtheta[e, j, v]
                    dM = dr[k, ir, v] + darm0 * F1 + arm0 * dF1 - darm1 * F0 - arm1 * dF0
                    dN = cos * dF0 + sin * dF1 + rot * dtheta
                    da = dN / bt - a * (db[v] / b + dt[e, j, v] / t[e, j])
                    dc = dM / Z[e, j] - c * (db[v] / b + 2.0 * dt[e, j, v] / t[e, j])
                    d_fibre[k, s, 0, v] = da + dc
                    d_fibre[k, s, 1, v] = da - dc


@_jit
def pbtrs_many(ab: np.ndarray, B: np.ndarray) -> None:
    """Solve ``U^T U X = B`` in place for the m columns of ``B`` (n, m), ``U`` the banded
    Cholesky factor from LAPACK ``dpbtrf`` (``lower=0``): ``ab`` (kd + 1, n), ``U[i, j] =
    ab[kd + i - j, j]``. LAPACK's ``dpbtrs`` solves column by column (two ``dtbsv`` per
    right-hand side: ~25 us each on the beam's 435 DOFs, 0.6 ms for a row's 24 variables); here
    each step of the two triangular sweeps runs over every column at once, the sweeps in
    ``dtbsv``'s order (the transposed one by dot products, the other by columns)."""
    kd = ab.shape[0] - 1
    n, m = B.shape
    for j in range(n):  # U^T y = b
        for i in range(max(0, j - kd), j):
            u = ab[kd + i - j, j]
            for v in range(m):
                B[j, v] -= u * B[i, v]
        d = ab[kd, j]
        for v in range(m):
            B[j, v] /= d
    for j in range(n - 1, -1, -1):  # U x = y
        d = ab[kd, j]
        for v in range(m):
            B[j, v] /= d
        for i in range(max(0, j - kd), j):
            u = ab[kd + i - j, j]
            for v in range(m):
                B[i, v] -= u * B[j, v]


@_jit
def coordinate_terms(
    U: np.ndarray,
    frame: np.ndarray,
    vdofs: np.ndarray,
    dN: np.ndarray,
    theta0: np.ndarray,
    cos0: np.ndarray,
    sin0: np.ndarray,
    EA: np.ndarray,
    kGA: np.ndarray,
    EI: np.ndarray,
    w: np.ndarray,
    N: np.ndarray,
    g2s: np.ndarray,
    dNs: np.ndarray,
    ratio: np.ndarray,
    e_mpa: float,
    weight: np.ndarray,
    col: np.ndarray,
    elem: np.ndarray,
    last: np.ndarray,
    dR: np.ndarray,
    da: np.ndarray,
    dc: np.ndarray,
) -> None:
    """:meth:`fea.beam_sensitivity._CoordinateBatch.terms_rows` compiled: the residual and the
    fibre terms of every virtual element (a perturbed model's element, V of them) at each row's
    state, times its stencil weight, summed into its variable's column in the reference's
    order of the elements (the sums within an element in the kernel's: round-off apart).

    Per row k of ``U`` (K, n) physical DOFs: ``dR`` (K, n, n_coord), ``da`` and ``dc`` (K, E, 3,
    n_coord), zero on entry, accumulate. Per virtual element v: ``vdofs`` (V, 9) its DOFs,
    ``dN`` (V, Q, 3), ``theta0``, ``cos0``, ``sin0``, ``EA``, ``kGA``, ``EI``, ``w`` (V, Q) its
    perturbed model's tables, ``dNs`` (V, 3, 3), ``ratio`` (V, 3), ``weight`` (V,) the stencil's
    weight / step, ``col`` (V,) its variable, ``elem`` (V,) the element it stands for, ``last``
    (V,) whether that is the end element (its end node's rows in ``frame``'s axes). ``N`` (Q, 3),
    ``g2s`` (Q, 3): the reference tables; ``e_mpa``: Young's modulus.
    """
    n_rows = U.shape[0]
    n_v, n_q = w.shape
    qe = np.empty((3, 3))
    re = np.empty((3, 3))
    grad = np.empty((n_q, 3))
    h1 = np.empty(n_q)
    for k in range(n_rows):
        for v in range(n_v):
            for a in range(3):
                for f in range(3):
                    qe[a, f] = U[k, vdofs[v, 3 * a + f]]
                    re[a, f] = 0.0
            for q in range(n_q):
                for f in range(3):
                    grad[q, f] = (
                        dN[v, q, 0] * qe[0, f] + dN[v, q, 1] * qe[1, f] + dN[v, q, 2] * qe[2, f]
                    )
                theta = theta0[v, q] + (
                    qe[0, 2] * N[q, 0] + qe[1, 2] * N[q, 1] + qe[2, 2] * N[q, 2]
                )
                c, s = math.cos(theta), math.sin(theta)
                x1 = cos0[v, q] + grad[q, 0]
                x2 = sin0[v, q] + grad[q, 1]
                h = c * x1 + s * x2
                g2 = c * x2 - s * x1
                h1[q] = h
                nf = EA[v, q] * (h - 1.0)
                qf = kGA[v, q] * g2
                s0 = nf * c - qf * s
                s1 = nf * s + qf * c
                s2 = EI[v, q] * grad[q, 2]
                s3 = nf * g2 - qf * h
                for a in range(3):
                    wd = w[v, q] * dN[v, q, a]
                    wn = w[v, q] * N[q, a]
                    re[a, 0] += wd * s0
                    re[a, 1] += wd * s1
                    re[a, 2] += wd * s2 + wn * s3
            if last[v]:  # the end node's force in the drive's axes (direction, normal)
                r0, r1 = re[2, 0], re[2, 1]
                re[2, 0] = r0 * frame[0, 0] + r1 * frame[0, 1]
                re[2, 1] = r0 * frame[1, 0] + r1 * frame[1, 1]
            wv = weight[v]
            cv = col[v]
            for a in range(3):
                for f in range(3):
                    dR[k, vdofs[v, 3 * a + f], cv] += re[a, f] * wv
            e = elem[v]
            for m in range(3):
                g1s = 0.0
                for q in range(n_q):
                    g1s += (h1[q] - 1.0) * g2s[q, m]
                kap = dNs[v, m, 0] * qe[0, 2] + dNs[v, m, 1] * qe[1, 2] + dNs[v, m, 2] * qe[2, 2]
                da[k, e, m, cv] += e_mpa * g1s * wv
                dc[k, e, m, cv] += ratio[v, m] * kap * wv
