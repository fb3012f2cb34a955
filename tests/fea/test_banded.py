"""The one banded LU (fea/_banded.py) against dense and banded references (numpy, scipy).

Its callers, the beam kernel (one right-hand side) and the constrained kernel (many), are tested
against their numpy reference paths in test_beam_kernels.py and test_constrained_kernels.py;
here the LU alone: random banded matrices (half-bandwidth 8, both sides), nonsymmetric (the LU
pivots) and symmetric positive definite, of sizes below, at and above the band's width (the short
columns at the end run the general loop, the others the unrolled one), solved to the accuracy of
a dense solve, and a singular matrix reported as LAPACK does.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

pytest.importorskip("numba", reason="the compiled kernels need numba")

from flexopt.fea import _banded as bd  # noqa: E402

SIZES = [1, 5, 9, 17, 25, 60]


def _random_band(n: int, rng: np.random.Generator, spd: bool) -> np.ndarray:
    """Dense (n, n) matrix with KL sub- and KU superdiagonals: symmetric positive definite
    (a symmetric band made diagonally dominant: Gershgorin), or general with a small diagonal
    against its column (so that the LU pivots)."""
    a = np.triu(np.tril(rng.normal(size=(n, n)), bd.KU), -bd.KL)
    if spd:
        s = a + a.T
        return s + (np.abs(s).sum(axis=1).max() + 1.0) * np.eye(n)
    return a - np.diag(np.diag(a)) + 0.1 * np.diag(rng.normal(size=n))


def _storage(a: np.ndarray) -> np.ndarray:
    """Dense -> the kernel's storage (n, LDAB), ``abc[j, KV + i - j] = A[i, j]``. Every entry
    outside the band (the LU's fill-in workspace) or outside the matrix is NaN: the LU must
    clear the first and never read the second."""
    n = a.shape[0]
    abc = np.full((n, bd.LDAB), np.nan)
    for j in range(n):
        for i in range(max(0, j - bd.KU), min(n, j + bd.KL + 1)):
            abc[j, bd.KV + i - j] = a[i, j]
    return abc


def _lapack_storage(a: np.ndarray, rows: int, diagonal: int) -> np.ndarray:
    """Dense -> LAPACK band storage (rows, n), ``ab[diagonal + i - j, j] = A[i, j]``."""
    n = a.shape[0]
    ab = np.zeros((rows, n))
    for j in range(n):
        for i in range(max(0, j - bd.KU), min(n, j + bd.KL + 1)):
            ab[diagonal + i - j, j] = a[i, j]
    return ab


@pytest.mark.parametrize("spd", [False, True], ids=["nonsymmetric", "spd"])
@pytest.mark.parametrize("n", SIZES)
def test_gbsv_solves_like_a_dense_solve(n, spd):
    rng = np.random.default_rng(1000 * n + spd)
    a = _random_band(n, rng, spd)
    b = rng.normal(size=n)
    exact = np.linalg.solve(a, b)
    x = b.copy()
    ipiv = np.empty(n, np.int64)
    assert bd.gbsv(_storage(a), x, ipiv) == 0
    # backward-stable LU: error within cond(A) x machine epsilon of the dense solution
    tol = 50 * np.finfo(float).eps * np.linalg.cond(a) * np.abs(exact).max()
    np.testing.assert_allclose(x, exact, rtol=0, atol=tol)
    # and scipy's banded LAPACK solve agrees as closely
    ab = _lapack_storage(a, bd.KL + bd.KU + 1, bd.KU)
    ref = scipy.linalg.solve_banded((bd.KL, bd.KU), ab, b)
    np.testing.assert_allclose(x, ref, rtol=0, atol=tol)
    if not spd and n > 1:
        assert np.any(ipiv != np.arange(n))  # the case is what it is named for: rows swapped


@pytest.mark.parametrize("n", [9, 60])
def test_many_right_hand_sides_are_the_single_solve_column_by_column(n):
    """gbtrf + gbtrs on k columns: bit for bit gbsv's answer for each column."""
    rng = np.random.default_rng(n)
    a = _random_band(n, rng, False)
    B = rng.normal(size=(n, 4))
    B[:, 1] = 0.0  # a zero column: the single solve skips its zeros, the many-column one not
    abc = _storage(a)
    ipiv = np.empty(n, np.int64)
    assert bd.gbtrf(abc, ipiv) == 0
    X = B.copy()
    bd.gbtrs(abc, ipiv, X)
    for c in range(B.shape[1]):
        x = B[:, c].copy()
        assert bd.gbsv(_storage(a), x, np.empty(n, np.int64)) == 0
        np.testing.assert_array_equal(X[:, c], x)
    np.testing.assert_allclose(a @ X, B, rtol=0, atol=1e-10 * np.abs(B).max())


def test_a_singular_matrix_is_reported_at_its_zero_pivot():
    """A zero column j: LAPACK's info = j + 1, and the right-hand side is left as it was."""
    n, j = 20, 7
    rng = np.random.default_rng(3)
    a = _random_band(n, rng, True)
    a[:, j] = 0.0
    b = rng.normal(size=n)
    x = b.copy()
    assert bd.gbsv(_storage(a), x, np.empty(n, np.int64)) == j + 1
    np.testing.assert_array_equal(x, b)
    # scipy's LAPACK says the same
    ab = _lapack_storage(a, bd.LDAB, bd.KV)
    *_, info = scipy.linalg.lapack.dgbsv(bd.KL, bd.KU, ab, b.copy())
    assert info == j + 1


def test_the_lu_is_the_factor_lapack_computes():
    """The factors and pivots equal LAPACK dgbtrf's (scipy) to round-off: the same algorithm,
    not only the same solution."""
    n = 40
    rng = np.random.default_rng(11)
    a = _random_band(n, rng, False)
    lu, piv, info = scipy.linalg.lapack.dgbtrf(_lapack_storage(a, bd.LDAB, bd.KV), bd.KL, bd.KU)
    assert info == 0
    abc = _storage(a)
    ipiv = np.empty(n, np.int64)
    assert bd.gbtrf(abc, ipiv) == 0
    np.testing.assert_array_equal(ipiv, piv)
    # the entries of the factors inside the matrix (LAPACK leaves the others unreferenced)
    row, col = np.indices(lu.shape)
    inside = (col + row - bd.KV >= 0) & (col + row - bd.KV < n)
    assert np.isfinite(abc.T[inside]).all()
    np.testing.assert_allclose(abc.T[inside], lu[inside], rtol=0, atol=1e-12 * np.abs(lu).max())
