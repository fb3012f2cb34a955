"""Compiled (numba) kernels of :mod:`fea.constrained_beams`: the same Newton, compiled.

:class:`fea.constrained_beams.ConstrainedBeams` runs one of two paths with the same physics:

* ``numpy`` (the reference): the beams' tangents scattered into a scipy sparse matrix, the KKT
  system built with ``scipy.sparse.bmat`` and solved by SuperLU, the Newton loop in Python, the
  stability inertia by SuperLU without pivoting (dense ``dsytrf`` when that meets a zero pivot);
* ``numba`` (this module): the element residual and tangent and their band assembly are the beam
  kernel's own :func:`fea._beam_kernels.assemble` (one call per beam, on the beam's slice of the
  unknowns); the KKT system is solved by bordering (below); the Newton loop of a system without
  applied loads runs here whole, and with loads (a Python callable of the state) one iteration at
  a time; the inertia is a compiled envelope LDL^T of the same matrix the reference factorises.

The scipy path spent ~90 % of a flexure-pivot evaluation building sparse matrices (``bmat``,
``coo -> csc``, index-dtype checks) around factorisations of a few hundred unknowns.

The KKT solve by bordering
--------------------------
Unknowns ``[z_b, e, lam]``: the beams' DOFs z_b (node by node, so the beams' tangent is one band
of half-bandwidth 8), the extra unknowns e and the multipliers lam. A row of ``C`` is *local* when
its beam DOFs lie within one band width (a clamp, a tip on a line, a beam end tied to a block).
Adding ``C^T W (C dz + gap) = 0`` to the first block row, with W = rho on local rows and 0 on the
others, changes no solution (it is the same system) and puts ``rho c c^T`` of the supports into
the band, which makes the band block ``A = K_bb + rho sum_local c_b c_b^T`` regular wherever every
beam is held by local rows (each beam's rigid motions are otherwise its null space). Then::

    [ A   B1 ] [x_b]   [r_b]       S = D - B2 A^-1 B1   (n_extra + m square, dense)
    [ B2  D  ] [ y ] = [r_y]       S y = r_y - B2 A^-1 r_b,   x_b = A^-1 (r_b - B1 y)

with A factorised by the banded LU with partial pivoting of fea/_banded.py (the operations of LAPACK
``dgbtf2``; the beam kernel's own, here with a many-right-hand-side solve) and S by a dense LU with
partial pivoting. When A is (numerically) singular, or a Newton correction fails an a-posteriori
check of the full KKT residual, the sub-step is handed back (``FALLBACK``) and the caller runs the
reference for it: the bordering is a faster route to the same solution, never a different answer.

The inertia
-----------
``kkt_negatives_*`` count the negative eigenvalues of ``[[H + rho G^T G, G^T], [G, 0]]`` (rho =
max(|diag H|, 1)) as the reference does: an LDL^T without pivoting in the natural order, whose
pivot signs are the inertia (Sylvester); here with envelope (skyline) storage, so the fill stays
within the band of the beams and the few rows the constraints couple. A zero or non-finite pivot
returns -1 and the caller counts with the reference's dense Bunch-Kaufman.

Every function is ``@njit(cache=True, fastmath=False, error_model="numpy")`` as in
fea/_beam_kernels.py: compiled once per install, IEEE arithmetic without reassociation.
"""

from __future__ import annotations

import math

import numpy as np
from flexopt.fea import _beam_kernels as bk
from flexopt.fea._banded import BAND, KL, KU, KV, gbtrf, gbtrs
from numba import njit

#: status codes of a Newton sub-step (texts in fea.constrained_beams._REASONS)
OK = 0
SINGULAR = 1  # the KKT matrix is exactly singular (the reference's SuperLU RuntimeError)
STEP_NAN = 2  # the correction became NaN or inf
RESIDUAL_NAN = 3  # the internal force became NaN or inf
MAX_ITERATIONS = 4
FALLBACK = 5  # the bordered solve cannot take this system: the reference runs this sub-step

#: A pivot of the band block below this x its largest diagonal entry means A is singular (a beam
#: no local row holds: round-off pivots ~1e-14); a held slender leaf's smallest pivot, its tip
#: stiffness against EA/h, is ~t^2 h / (4 L^3) > 1e-9 for any printable leaf.
PIVOT_TOL = 1e-12
#: Backward error |J x - b| / (|J| |x| + |b|) above this means the bordering lost accuracy.
BACKWARD_TOL = 1e-9

_jit = njit(cache=True, fastmath=False, error_model="numpy", nogil=True)


# -- assembly -------------------------------------------------------------------------------------


@_jit
def assemble_all(z, geo, eoff, offsets, frame, u, r, abc) -> None:
    """Internal force ``r`` (N,) and the beams' band tangent ``abc`` (N_b, LDAB) at ``z`` (N,).

    ``geo`` holds every beam's :meth:`fea.beam.BeamModel._kernel_geometry` tables concatenated
    along the elements (beam b owns elements ``eoff[b]:eoff[b+1]`` and DOFs
    ``offsets[b]:offsets[b+1]``); each beam is assembled by :func:`fea._beam_kernels.assemble`
    on its slices, so a beam's force and tangent are bit for bit the beam model's. ``u`` (N,) is
    scratch; the extra unknowns carry no force.
    """
    dN, N, dNw, Nw, dd, dn, nn, kbend, theta0, c0, s0, ea, kga, ei = geo
    nb = offsets[offsets.shape[0] - 1]
    for i in range(nb, r.shape[0]):
        r[i] = 0.0
    for b in range(offsets.shape[0] - 1):
        e0 = eoff[b]
        e1 = eoff[b + 1]
        a0 = offsets[b]
        a1 = offsets[b + 1]
        g = (
            dN[e0:e1],
            N,
            dNw[e0:e1],
            Nw[e0:e1],
            dd[e0:e1],
            dn[e0:e1],
            nn[e0:e1],
            kbend[e0:e1],
            theta0[e0:e1],
            c0[e0:e1],
            s0[e0:e1],
            ea[e0:e1],
            kga[e0:e1],
            ei[e0:e1],
        )
        bk.assemble(z[a0:a1], frame, g, u[a0:a1], r[a0:a1], abc[a0:a1])


@_jit
def constraint_rows(C, nb):
    """Row-compressed nonzeros of ``C`` (m, N) and which rows are local (beam DOFs within one band
    width): ``(ptr (m + 1,), idx, val, local (m,) bool)``."""
    m, n = C.shape
    count = 0
    for r in range(m):
        for j in range(n):
            if C[r, j] != 0.0:
                count += 1
    ptr = np.zeros(m + 1, dtype=np.int64)
    idx = np.empty(count, dtype=np.int64)
    val = np.empty(count)
    local = np.zeros(m, dtype=np.bool_)
    k = 0
    for r in range(m):
        lo = n
        hi = -1
        for j in range(n):
            v = C[r, j]
            if v != 0.0:
                idx[k] = j
                val[k] = v
                k += 1
                if j < nb:
                    lo = min(lo, j)
                    hi = max(hi, j)
        ptr[r + 1] = k
        local[r] = hi < 0 or hi - lo <= BAND
    return ptr, idx, val, local


# -- linear algebra -------------------------------------------------------------------------------


@_jit
def gesv(S, t) -> bool:
    """Solve the small dense system S y = t in place (``t`` becomes y) by LU with partial
    pivoting; False when a pivot is exactly zero (singular)."""
    n = S.shape[0]
    for j in range(n):
        p = j
        amax = abs(S[j, j])
        for i in range(j + 1, n):
            if abs(S[i, j]) > amax:
                amax = abs(S[i, j])
                p = i
        if S[p, j] == 0.0:
            return False
        if p != j:
            for c in range(n):
                tmp = S[p, c]
                S[p, c] = S[j, c]
                S[j, c] = tmp
            tmp = t[p]
            t[p] = t[j]
            t[j] = tmp
        rp = 1.0 / S[j, j]
        for i in range(j + 1, n):
            f = S[i, j] * rp
            if f != 0.0:
                for c in range(j + 1, n):
                    S[i, c] -= f * S[j, c]
                t[i] -= f * t[j]
    for j in range(n - 1, -1, -1):
        s = t[j]
        for c in range(j + 1, n):
            s -= S[j, c] * t[c]
        t[j] = s / S[j, j]
    return True


@_jit
def _put(A, B1, B2, D, nb, i, j, v) -> bool:
    """Add v to entry (i, j) of [[A, B1], [B2, D]] restricted to the z block (i, j < N); False
    when it is a beam-beam entry outside the band."""
    if i < nb and j < nb:
        if abs(i - j) > BAND:
            return False
        A[j, KV + i - j] += v
    elif i < nb:
        B1[i, j - nb] += v
    elif j < nb:
        B2[i - nb, j] += v
    else:
        D[i - nb, j - nb] += v
    return True


@_jit
def kkt_solve(abc, n, ptr, idx, val, local, rho, kf_r, kf_c, kf_v, rhs, x) -> int:
    """Solve ``[[K - Kf, -C^T], [C, 0]] x = rhs`` by bordering (see the module docstring).

    ``abc`` (N_b, LDAB) the beams' band tangent (not modified); ``n`` = N (beam DOFs + extras);
    C as :func:`constraint_rows`; ``rho`` the weight of the local rows; ``Kf`` as COO
    (``kf_r``, ``kf_c``, ``kf_v``); ``rhs`` (N + m,). Writes ``x`` (N + m,). Returns OK,
    SINGULAR or FALLBACK.
    """
    nb = abc.shape[0]
    m = ptr.shape[0] - 1
    ne = n - nb
    nbd = ne + m
    A = abc.copy()
    B1 = np.zeros((nb, nbd + 1))  # the last column is the right-hand side r_b
    B2 = np.zeros((nbd, nb))
    D = np.zeros((nbd, nbd))
    t = np.empty(nbd)
    for i in range(nb):
        B1[i, nbd] = rhs[i]
    for k in range(ne):
        t[k] = rhs[nb + k]
    for r in range(m):
        t[ne + r] = rhs[n + r]
    for q in range(kf_r.shape[0]):
        if not _put(A, B1, B2, D, nb, kf_r[q], kf_c[q], -kf_v[q]):
            return FALLBACK
    for r in range(m):
        if local[r]:
            gap = -rhs[n + r]
            for a in range(ptr[r], ptr[r + 1]):
                i = idx[a]
                wi = rho * val[a]
                if i < nb:
                    B1[i, nbd] -= wi * gap
                else:
                    t[i - nb] -= wi * gap
                for b in range(ptr[r], ptr[r + 1]):
                    _put(A, B1, B2, D, nb, i, idx[b], wi * val[b])
        for a in range(ptr[r], ptr[r + 1]):
            j = idx[a]
            v = val[a]
            if j < nb:
                B1[j, ne + r] -= v
                B2[ne + r, j] += v
            else:
                D[j - nb, ne + r] -= v
                D[ne + r, j - nb] += v
    amax = 0.0
    for j in range(nb):
        amax = max(amax, abs(A[j, KV]))
    ipiv = np.empty(nb, dtype=np.int64)
    if gbtrf(A, ipiv) != 0:
        return FALLBACK
    for j in range(nb):
        if not abs(A[j, KV]) > PIVOT_TOL * amax:
            return FALLBACK
    gbtrs(A, ipiv, B1)  # B1 <- A^-1 [B1 | r_b]
    for k in range(nbd):
        for j in range(nb):
            v = B2[k, j]
            if v != 0.0:
                for c in range(nbd):
                    D[k, c] -= v * B1[j, c]
                t[k] -= v * B1[j, nbd]
    if nbd > 0 and not gesv(D, t):
        return SINGULAR
    for i in range(nb):
        s = B1[i, nbd]
        for c in range(nbd):
            s -= B1[i, c] * t[c]
        x[i] = s
    for k in range(ne):
        x[nb + k] = t[k]
    for r in range(m):
        x[n + r] = t[ne + r]
    return OK


@_jit
def backward_error(abc, n, ptr, idx, val, kf_r, kf_c, kf_v, rhs, x) -> float:
    """|J x - rhs|_inf / (|J|_inf |x|_inf + |rhs|_inf) of the KKT system of :func:`kkt_solve`
    (NaN when x is not finite)."""
    nb = abc.shape[0]
    m = ptr.shape[0] - 1
    res = np.zeros(n + m)
    rowsum = np.zeros(n + m)
    for i in range(n + m):
        res[i] = -rhs[i]
    for j in range(nb):
        for i in range(max(0, j - KU), min(nb, j + KL + 1)):
            a = abc[j, KV + i - j]
            res[i] += a * x[j]
            rowsum[i] += abs(a)
    for q in range(kf_r.shape[0]):
        res[kf_r[q]] -= kf_v[q] * x[kf_c[q]]
        rowsum[kf_r[q]] += abs(kf_v[q])
    for r in range(m):
        for a in range(ptr[r], ptr[r + 1]):
            j = idx[a]
            v = val[a]
            res[j] -= v * x[n + r]
            res[n + r] += v * x[j]
            rowsum[j] += abs(v)
            rowsum[n + r] += abs(v)
    rn = 0.0
    jn = 0.0
    xn = 0.0
    bn = 0.0
    for i in range(n + m):
        rn = max(rn, abs(res[i]))
        jn = max(jn, rowsum[i])
        xn = max(xn, abs(x[i]))
        bn = max(bn, abs(rhs[i]))
    if not (math.isfinite(rn) and math.isfinite(xn)):
        return math.nan
    den = jn * xn + bn
    return rn / den if den > 0.0 else 0.0


# -- Newton ---------------------------------------------------------------------------------------


@_jit
def _ct_lam(ptr, idx, val, lam, out) -> None:
    """out (N,) = C^T lam."""
    out[:] = 0.0
    for r in range(ptr.shape[0] - 1):
        for a in range(ptr[r], ptr[r + 1]):
            out[idx[a]] += val[a] * lam[r]


@_jit
def _norm(x) -> float:
    s = 0.0
    for v in x:
        s += v * v
    return math.sqrt(s)


@_jit
def iterate(
    z, lam, r, abc, f, kf_r, kf_c, kf_v, d, ptr, idx, val, local, rho, geo, eoff, offsets,
    frame, rot, max_rotation_step, u, work,
) -> tuple[int, float]:  # fmt: skip
    """One Newton iteration of :meth:`fea.constrained_beams.ConstrainedBeams._newton` on (z, lam)
    in place, r and abc reassembled at the new z. Returns (status, max |dz|).

    ``work`` (N,) is scratch; ``f`` (N,) the applied loads and Kf their derivative (COO) at z.
    """
    n = z.shape[0]
    m = lam.shape[0]
    rhs = np.empty(n + m)
    _ct_lam(ptr, idx, val, lam, work)
    for i in range(n):
        rhs[i] = -(r[i] - f[i] - work[i])
    for q in range(m):
        s = 0.0
        for a in range(ptr[q], ptr[q + 1]):
            s += val[a] * z[idx[a]]
        rhs[n + q] = -(s - d[q])
    x = np.empty(n + m)
    code = kkt_solve(abc, n, ptr, idx, val, local, rho, kf_r, kf_c, kf_v, rhs, x)
    if code != OK:
        return code, 0.0
    for v in x:
        if not math.isfinite(v):
            return STEP_NAN, 0.0
    if not backward_error(abc, n, ptr, idx, val, kf_r, kf_c, kf_v, rhs, x) <= BACKWARD_TOL:
        return FALLBACK, 0.0
    # Damp corrections that turn a section by more than max_rotation_step (see the settings).
    big = 0.0
    for i in rot:
        big = max(big, abs(x[i]))
    big = big / max_rotation_step
    if big > 1.0:
        for i in range(n + m):
            x[i] = x[i] / big
    dmax = 0.0
    for i in range(n):
        z[i] = z[i] + x[i]
        dmax = max(dmax, abs(x[i]))
    for q in range(m):
        lam[q] = lam[q] + x[n + q]
    assemble_all(z, geo, eoff, offsets, frame, u, r, abc)
    for v in r:
        if not math.isfinite(v):
            return RESIDUAL_NAN, dmax
    return OK, dmax


@_jit
def converged(z, lam, r, f, d, ptr, idx, val, dmax, rtol, ctol, dtol, length, force_floor, work):
    """The reference's convergence test after an iteration: constraints met and (residual small
    or correction at round-off)."""
    n = z.shape[0]
    _ct_lam(ptr, idx, val, lam, work)
    ct = _norm(work)
    res2 = 0.0
    for i in range(n):
        v = r[i] - f[i] - work[i]
        res2 += v * v
    scale = max(ct, _norm(f), force_floor)
    gmax = 0.0
    for q in range(lam.shape[0]):
        s = 0.0
        for a in range(ptr[q], ptr[q + 1]):
            s += val[a] * z[idx[a]]
        g = abs(s - d[q])
        if math.isnan(g):
            gmax = g
            break
        gmax = max(gmax, g)
    gap_ok = gmax <= ctol * length
    res_ok = math.sqrt(res2) <= rtol * scale
    tiny = dmax <= dtol * length
    return gap_ok and (res_ok or tiny)


@_jit
def newton(z, lam, C, d, geo, eoff, offsets, frame, rot, fpar, max_iterations, r, abc):
    """Equilibrium at one path parameter without applied loads, from (z, lam) in place: the
    reference's Newton loop whole. ``fpar`` = (rtol, ctol, dtol, max_rotation_step, length [mm],
    force floor [N]). Returns (status, iterations); r (N,) and abc (N_b, LDAB) are left at z."""
    rtol, ctol, dtol, max_rot, length, force_floor = (
        fpar[0],
        fpar[1],
        fpar[2],
        fpar[3],
        fpar[4],
        fpar[5],
    )
    n = z.shape[0]
    nb = abc.shape[0]
    ptr, idx, val, local = constraint_rows(C, nb)
    u = np.empty(n)
    work = np.empty(n)
    f = np.zeros(n)
    kf_r = np.zeros(0, dtype=np.int64)
    kf_v = np.zeros(0)
    assemble_all(z, geo, eoff, offsets, frame, u, r, abc)
    rho = 1.0
    for j in range(nb):
        rho = max(rho, abs(abc[j, KV]))
    for it in range(1, max_iterations + 1):
        code, dmax = iterate(
            z, lam, r, abc, f, kf_r, kf_r, kf_v, d, ptr, idx, val, local, rho, geo, eoff,
            offsets, frame, rot, max_rot, u, work,
        )  # fmt: skip
        if code != OK:
            return code, it
        if converged(
            z, lam, r, f, d, ptr, idx, val, dmax, rtol, ctol, dtol, length, force_floor, work
        ):
            return OK, it
    return MAX_ITERATIONS, max_iterations


# -- inertia --------------------------------------------------------------------------------------


@_jit
def _skyline_negatives(n, m, hr, hc, hv, gptr, gidx, gval) -> int:
    """Negative pivots of the natural-order LDL^T of [[sym(H) + rho G^T G, G^T], [G, 0]]
    (rho = max(|diag H|, 1)) in envelope storage; -1 at a zero or non-finite pivot.

    H (n, n) as COO (``hr``, ``hc``, ``hv``; duplicates add up), G (m, n) row-compressed.
    """
    nt = n + m
    first = np.arange(nt)
    diag = np.zeros(n)
    for q in range(hr.shape[0]):
        i, j = hr[q], hc[q]
        hi, lo = max(i, j), min(i, j)
        first[hi] = min(first[hi], lo)
        if i == j:
            diag[i] += hv[q]
    rho = 1.0
    for i in range(n):
        rho = max(rho, abs(diag[i]))
    for r in range(m):
        for a in range(gptr[r], gptr[r + 1]):
            ja = gidx[a]
            first[n + r] = min(first[n + r], ja)
            for b in range(gptr[r], gptr[r + 1]):
                jb = gidx[b]
                if jb < ja:
                    first[ja] = min(first[ja], jb)
    ptr = np.empty(nt + 1, dtype=np.int64)
    ptr[0] = 0
    for i in range(nt):
        ptr[i + 1] = ptr[i] + i - first[i] + 1
    v = np.zeros(ptr[nt])
    for q in range(hr.shape[0]):
        i, j = hr[q], hc[q]
        if i == j:
            v[ptr[i] + i - first[i]] += hv[q]
        else:
            hi, lo = max(i, j), min(i, j)
            v[ptr[hi] + lo - first[hi]] += 0.5 * hv[q]
    for r in range(m):
        for a in range(gptr[r], gptr[r + 1]):
            ja = gidx[a]
            ga = gval[a]
            v[ptr[n + r] + ja - first[n + r]] += ga
            for b in range(gptr[r], gptr[r + 1]):
                jb = gidx[b]
                if jb <= ja:
                    v[ptr[ja] + jb - first[ja]] += rho * ga * gval[b]
    dvec = np.empty(nt)
    neg = 0
    for i in range(nt):
        fi = first[i]
        pi = ptr[i]
        for j in range(fi, i):
            fj = first[j]
            pj = ptr[j]
            s = v[pi + j - fi]
            for k in range(max(fi, fj), j):
                s -= v[pi + k - fi] * v[pj + k - fj]
            v[pi + j - fi] = s  # L[i, j] D[j], turned into L[i, j] below
        dsum = v[pi + i - fi]
        for j in range(fi, i):
            g = v[pi + j - fi]
            lij = g / dvec[j]
            v[pi + j - fi] = lij
            dsum -= g * lij
        if dsum == 0.0 or not math.isfinite(dsum):
            return -1
        dvec[i] = dsum
        if dsum < 0.0:
            neg += 1
    return neg


@_jit
def kkt_negatives_coo(n, hr, hc, hv, gptr, gidx, gval) -> int:
    """:func:`_skyline_negatives` for H as COO and G row-compressed (scipy's CSR arrays)."""
    return _skyline_negatives(n, gptr.shape[0] - 1, hr, hc, hv, gptr, gidx, gval)


@_jit
def kkt_negatives_band(abc, n, kf_r, kf_c, kf_v, C) -> int:
    """:func:`_skyline_negatives` for H = sym(K - Kf): K the beams' band tangent ``abc``
    (N_b, LDAB), Kf as COO, N = ``n``; G = C (m, N) dense."""
    nb = abc.shape[0]
    cnt = 0
    for j in range(nb):
        for i in range(max(0, j - KU), min(nb, j + KL + 1)):
            if abc[j, KV + i - j] != 0.0:
                cnt += 1
    nk = kf_r.shape[0]
    hr = np.empty(cnt + nk, dtype=np.int64)
    hc = np.empty(cnt + nk, dtype=np.int64)
    hv = np.empty(cnt + nk)
    q = 0
    for j in range(nb):
        for i in range(max(0, j - KU), min(nb, j + KL + 1)):
            a = abc[j, KV + i - j]
            if a != 0.0:  # both triangles: the skyline takes their mean, sym(K) as the reference
                hr[q] = i
                hc[q] = j
                hv[q] = a
                q += 1
    for k in range(nk):
        hr[q] = kf_r[k]
        hc[q] = kf_c[k]
        hv[q] = -kf_v[k]
        q += 1
    ptr, idx, val, _ = constraint_rows(C, nb)
    return _skyline_negatives(n, C.shape[0], hr, hc, hv, ptr, idx, val)
