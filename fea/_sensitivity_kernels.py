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
    at: np.ndarray,
) -> None:
    """Signed fibre stresses ``a + c``, ``a - c`` from statics and their derivatives, written
    into rows ``at`` (K,) of ``fibre`` (n_rows, 3 E, 2) MPa and ``d_fibre`` (n_rows, 3 E, 2,
    n_var) MPa per unit (row k's into row ``at[k]``: straight into the returned arrays).

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
        out = at[k]
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
                fibre[out, s, 0] = a + c
                fibre[out, s, 1] = a - c
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
                    d_fibre[out, s, 0, v] = da + dc
                    d_fibre[out, s, 1, v] = da - dc


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
    fibres: bool = True,
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
    ``g2s`` (Q, 3): the reference tables; ``e_mpa``: Young's modulus. ``fibres`` False: ``da``
    and ``dc`` are not touched (the stress from statics does not read them).
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
            if not fibres:
                continue
            e = elem[v]
            for m in range(3):
                g1s = 0.0
                for q in range(n_q):
                    g1s += (h1[q] - 1.0) * g2s[q, m]
                kap = dNs[v, m, 0] * qe[0, 2] + dNs[v, m, 1] * qe[1, 2] + dNs[v, m, 2] * qe[2, 2]
                da[k, e, m, cv] += e_mpa * g1s * wv
                dc[k, e, m, cv] += ratio[v, m] * kap * wv


@_jit
def thickness_terms(
    U: np.ndarray,
    edofs3: np.ndarray,
    edofs: np.ndarray,
    dN: np.ndarray,
    Nq: np.ndarray,
    theta0: np.ndarray,
    cos0: np.ndarray,
    sin0: np.ndarray,
    rmap: np.ndarray,
    psi_g: np.ndarray,
    t_g: np.ndarray,
    e_b: float,
    kg_b: float,
    dNs: np.ndarray,
    psi_s: np.ndarray,
    e_mpa: float,
    frame: np.ndarray,
    col: int,
    dR: np.ndarray,
    dc: np.ndarray,
    fibres: bool = True,
) -> None:
    """:func:`fea.beam_sensitivity._thickness_terms_rows` compiled and assembled: dR/dt_i at
    fixed DOFs and the bending term's explicit derivative, added into columns ``col`` ..
    ``col + n_pts - 1`` of ``dR`` (K, n, n_var) (generalised DOFs: the end node's force rows in
    ``frame``'s axes, as the reference turns them) and of ``dc`` (K, E, 3, n_var) MPa/mm.

    Why compiled: the reference forms (K, E, Q, 4, n_pts) products with the vertices' hat
    functions, of which each Gauss point has at most two nonzero (~24 MB of temporaries on the
    constant-force beam, 12 ms of a Jacobian); here each element touches only the vertices
    whose hats are nonzero on it, one pass, no temporaries. The same formulas: the element
    scalars' derivatives by (EA, kGA, EI) times ``e_b`` (E b), ``kg_b`` (k G b) and
    ``E b t^2 / 4``, times the hat, mapped by ``rmap`` (E, Q * 4, 9) (the model's residual
    map); sums in another order than the reference's matmul (round-off apart; the tests
    compare them).

    ``U`` (K, n) physical DOFs; ``edofs3`` (E, 3, 3) and ``edofs`` (E, 9) the element DOFs;
    ``dN`` (E, Q, 3), ``Nq`` (Q, 3), ``theta0``, ``cos0``, ``sin0``, ``t_g`` (E, Q) the model's
    tables (t_g mm); ``psi_g`` (E, Q, n_pts) and ``psi_s`` (E, 3, n_pts) the hats at the Gauss
    and sampling points; ``dNs`` (E, 3, 3); ``e_mpa`` Young's modulus; ``frame`` (2, 2).
    ``fibres`` False: ``dc`` is not touched (the stress from statics does not read it).
    """
    n_rows = U.shape[0]
    n_el, n_q = theta0.shape
    n_pts = psi_g.shape[2]
    # the vertices whose hats are nonzero on each element (a contiguous range: hats in s)
    jlo = np.empty(n_el, np.int64)
    jhi = np.empty(n_el, np.int64)
    for e in range(n_el):
        lo, hi = n_pts, -1
        for j in range(n_pts):
            nz = False
            for q in range(n_q):
                if psi_g[e, q, j] != 0.0:
                    nz = True
            for m in range(3):
                if psi_s[e, m, j] != 0.0:
                    nz = True
            if nz:
                lo = min(lo, j)
                hi = max(hi, j)
        jlo[e] = lo
        jhi[e] = hi
    qe = np.empty((3, 3))
    re = np.empty((9, n_pts))
    base = np.empty(4)
    for k in range(n_rows):
        for e in range(n_el):
            lo, hi = jlo[e], jhi[e] + 1
            for a in range(3):
                for f in range(3):
                    qe[a, f] = U[k, edofs3[e, a, f]]
            for i in range(9):
                for j in range(lo, hi):
                    re[i, j] = 0.0
            for q in range(n_q):
                g0 = dN[e, q, 0] * qe[0, 0] + dN[e, q, 1] * qe[1, 0] + dN[e, q, 2] * qe[2, 0]
                g1_ = dN[e, q, 0] * qe[0, 1] + dN[e, q, 1] * qe[1, 1] + dN[e, q, 2] * qe[2, 1]
                kap = dN[e, q, 0] * qe[0, 2] + dN[e, q, 1] * qe[1, 2] + dN[e, q, 2] * qe[2, 2]
                theta = theta0[e, q] + (
                    qe[0, 2] * Nq[q, 0] + qe[1, 2] * Nq[q, 1] + qe[2, 2] * Nq[q, 2]
                )
                c, s = math.cos(theta), math.sin(theta)
                x1 = cos0[e, q] + g0
                x2 = sin0[e, q] + g1_
                h1 = c * x1 + s * x2
                g2 = c * x2 - s * x1
                gam1 = h1 - 1.0
                ei = e_b * t_g[e, q] ** 2 / 4.0
                base[0] = gam1 * c * e_b + (-g2 * s) * kg_b
                base[1] = gam1 * s * e_b + g2 * c * kg_b
                base[2] = kap * ei
                base[3] = gam1 * g2 * e_b + (-g2 * h1) * kg_b
                for cc in range(4):
                    row = 4 * q + cc
                    for j in range(lo, hi):
                        p = psi_g[e, q, j]
                        if p == 0.0:
                            continue
                        v = base[cc] * p
                        for i in range(9):
                            re[i, j] += rmap[e, row, i] * v
            if e == n_el - 1:  # the end node's force rows in the drive's axes
                for j in range(lo, hi):
                    r6, r7 = re[6, j], re[7, j]
                    re[6, j] = frame[0, 0] * r6 + frame[0, 1] * r7
                    re[7, j] = frame[1, 0] * r6 + frame[1, 1] * r7
            for i in range(9):
                d = edofs[e, i]
                for j in range(lo, hi):
                    dR[k, d, col + j] += re[i, j]
            for m in range(3 if fibres else 0):
                kap_s = dNs[e, m, 0] * qe[0, 2] + dNs[e, m, 1] * qe[1, 2] + dNs[e, m, 2] * qe[2, 2]
                b = 0.5 * e_mpa * kap_s
                for j in range(lo, hi):
                    dc[k, e, m, col + j] += b * psi_s[e, m, j]
