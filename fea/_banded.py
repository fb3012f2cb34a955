"""Banded LU with partial pivoting, compiled (numba): the one copy the beam kernels share.

Ports of LAPACK's unblocked banded LU ``dgbtf2`` (what ``dgbtrf`` runs for a half-bandwidth of
8 < its block size 32) and its solve ``dgbtrs`` / ``dtbsv``, operation for operation, so that
:mod:`fea._beam_kernels` (one right-hand side, :func:`gbsv`) and :mod:`fea._constrained_kernels`
(the band block of a bordered KKT solve, :func:`gbtrf` then :func:`gbtrs` on many right-hand
sides) agree to round-off with scipy's ``dgbsv`` on their numpy reference paths. Calling scipy's
LAPACK from numba (through ``scipy.linalg.cython_lapack`` addresses) would embed raw function
addresses in the compiled code, which numba refuses to cache; the ports cache.

Storage
-------
The C-ordered transpose of LAPACK's gbsv layout: ``abc[j, KV + i - j] = A[i, j]`` with
``KL = KU = BAND = 8``, ``KV = KL + KU = 16`` and ``LDAB = 2 KL + KU + 1 = 25`` entries per
column; entries ``0 .. KL-1`` of each column are the LU's fill-in workspace. ``abc.T`` is then
exactly the Fortran-ordered ``(LDAB, n)`` array that ``dgbsv`` reads. The bandwidth is a
compile-time constant: the full-band columns run with their eight multipliers unrolled.

Every function is ``@njit(cache=True, fastmath=False, error_model="numpy", nogil=True)``, as the
callers' kernels: compiled once per install (the cache sits in ``fea/__pycache__``, or in
``NUMBA_CACHE_DIR``), IEEE arithmetic without reassociation, a division by zero gives inf/NaN
instead of raising. A caller in another module compiles these into its own cached code. numba's
cache of a caller is keyed on the caller's file only: after an edit here, clear
``fea/__pycache__/_*kernels*.nb*`` (or ``NUMBA_CACHE_DIR``) so that the callers recompile.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: half-bandwidth of the beams' node-by-node DOF numbering (3 nodes x 3 fields per element)
BAND = 8
KL = BAND
KU = BAND
KV = KL + KU  # row of the diagonal in the gbsv layout
LDAB = 2 * KL + KU + 1

_jit = njit(cache=True, fastmath=False, error_model="numpy", nogil=True)


@_jit
def gbtrf(abc: np.ndarray, ipiv: np.ndarray) -> int:
    """Banded LU with partial pivoting of ``abc`` in place (LAPACK ``dgbtf2``).

    Parameters
    ----------
    abc : (n, LDAB) float — the matrix in the storage above; overwritten by the factors (the
        multipliers below the diagonal, U with its KL extra superdiagonals of fill-in).
    ipiv : (n,) int64 — written: the row interchanged with row j at step j.

    Returns
    -------
    info : int — 0, or j + 1 when the pivot of column j is exactly zero (singular: the factors
        are then incomplete).
    """
    n = abc.shape[0]
    # fill-in entries of the first columns (dgbtf2 zeroes them before the elimination)
    for j in range(KU + 1, min(KV, n)):
        for i in range(KV - j, KL):
            abc[j, i] = 0.0
    ju = 0
    for j in range(n):
        if j + KV < n:
            for i in range(KL):
                abc[j + KV, i] = 0.0
        km = min(KL, n - 1 - j)
        jp = 0
        amax = abs(abc[j, KV])
        for i in range(1, km + 1):
            v = abs(abc[j, KV + i])
            if v > amax:
                jp = i
                amax = v
        ipiv[j] = j + jp
        if abc[j, KV + jp] == 0.0:
            return j + 1
        ju = max(ju, min(j + KU + jp, n - 1))
        if jp != 0:
            for c in range(j, ju + 1):
                t = abc[c, KV + j + jp - c]
                abc[c, KV + j + jp - c] = abc[c, KV + j - c]
                abc[c, KV + j - c] = t
        if km == KL:
            # the full-band case (all but the last KL columns) with the multipliers in
            # registers: the same operations as below, which the compiler cannot keep out of
            # memory there (it cannot tell that column j and column c do not overlap)
            rp = 1.0 / abc[j, KV]
            l1 = abc[j, KV + 1] * rp
            l2 = abc[j, KV + 2] * rp
            l3 = abc[j, KV + 3] * rp
            l4 = abc[j, KV + 4] * rp
            l5 = abc[j, KV + 5] * rp
            l6 = abc[j, KV + 6] * rp
            l7 = abc[j, KV + 7] * rp
            l8 = abc[j, KV + 8] * rp
            abc[j, KV + 1] = l1
            abc[j, KV + 2] = l2
            abc[j, KV + 3] = l3
            abc[j, KV + 4] = l4
            abc[j, KV + 5] = l5
            abc[j, KV + 6] = l6
            abc[j, KV + 7] = l7
            abc[j, KV + 8] = l8
            for c in range(j + 1, ju + 1):
                o = KV + j - c
                y = abc[c, o]
                if y != 0.0:
                    t = -y
                    abc[c, o + 1] += l1 * t
                    abc[c, o + 2] += l2 * t
                    abc[c, o + 3] += l3 * t
                    abc[c, o + 4] += l4 * t
                    abc[c, o + 5] += l5 * t
                    abc[c, o + 6] += l6 * t
                    abc[c, o + 7] += l7 * t
                    abc[c, o + 8] += l8 * t
        elif km > 0:
            rp = 1.0 / abc[j, KV]
            for i in range(1, km + 1):
                abc[j, KV + i] *= rp
            for c in range(j + 1, ju + 1):
                y = abc[c, KV + j - c]
                if y != 0.0:
                    t = -y
                    for i in range(1, km + 1):
                        abc[c, KV + j + i - c] += abc[j, KV + i] * t
    return 0


@_jit
def gbtrs1(abc: np.ndarray, ipiv: np.ndarray, b: np.ndarray) -> None:
    """Solve A x = b in place (``b`` (n,) becomes x) with the factors of :func:`gbtrf`
    (LAPACK ``dgbtrs``: L with the row interchanges, then ``dtbsv`` upper with KV
    superdiagonals)."""
    n = abc.shape[0]
    for j in range(n - 1):
        lm = min(KL, n - 1 - j)
        p = ipiv[j]
        if p != j:
            t = b[p]
            b[p] = b[j]
            b[j] = t
        bj = b[j]
        if bj != 0.0:
            t = -bj
            for i in range(1, lm + 1):
                b[j + i] += abc[j, KV + i] * t
    for j in range(n - 1, -1, -1):
        if b[j] != 0.0:
            b[j] = b[j] / abc[j, KV]
            t = b[j]
            # each b[i] gets one update per j: the order over i is free (forward vectorises)
            for i in range(max(0, j - KV), j):
                b[i] -= t * abc[j, KV + i - j]


@_jit
def gbtrs(abc: np.ndarray, ipiv: np.ndarray, X: np.ndarray) -> None:
    """Solve A X = X in place for every column of ``X`` (n, k) with the factors of
    :func:`gbtrf` (``dgbtrs``; the columns innermost, so the loops run over contiguous memory).
    Each column gets :func:`gbtrs1`'s answer (``x - l y`` here is ``x + l (-y)`` there); the
    zeros skipped differ, which only shows when the factors hold inf or NaN."""
    n = abc.shape[0]
    k = X.shape[1]
    for j in range(n - 1):
        lm = min(KL, n - 1 - j)
        p = ipiv[j]
        if p != j:
            for c in range(k):
                t = X[p, c]
                X[p, c] = X[j, c]
                X[j, c] = t
        for i in range(1, lm + 1):
            lij = abc[j, KV + i]
            if lij != 0.0:
                for c in range(k):
                    X[j + i, c] -= lij * X[j, c]
    for j in range(n - 1, -1, -1):
        piv = abc[j, KV]
        for c in range(k):
            X[j, c] = X[j, c] / piv
        for i in range(j - 1, max(0, j - KV) - 1, -1):
            uij = abc[j, KV + i - j]
            if uij != 0.0:
                for c in range(k):
                    X[i, c] -= uij * X[j, c]


@_jit
def gbsv(abc: np.ndarray, b: np.ndarray, ipiv: np.ndarray) -> int:
    """Solve A x = b in place (``b`` (n,) becomes x) by banded LU with partial pivoting.

    ``abc`` (n, LDAB) is overwritten by the factors; ``ipiv`` (n,) int64 scratch. Returns
    LAPACK's ``info``: 0, or j + 1 when the pivot of column j is exactly zero (singular; ``b``
    is then untouched, not a solution). ``dgbsv``: :func:`gbtrf` then :func:`gbtrs1`.
    """
    info = gbtrf(abc, ipiv)
    if info != 0:
        return info
    gbtrs1(abc, ipiv, b)
    return 0
