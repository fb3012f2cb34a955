"""The exact bounded least-squares solver behind optimise_prb (fea.prb._box_lsq).

Every reference is computed here: scipy's lsq_linear (its exact active-set method "bvls" at a
tight tolerance), the KKT conditions of the box-constrained problem, and optimise_prb run with
lsq_linear in place of _box_lsq (the implementation it replaced).
"""

import numpy as np
import pytest
from flexopt.fea import prb as cf
from scipy.optimize import lsq_linear

LOWER, UPPER = np.zeros(3), np.full(3, 1000.0)


def _random_problems(n, seed=0):
    """n well-posed problems (100 x 3, column scales 0.1-10) whose minimisers hit the bounds."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, 100, 3)) * rng.uniform(0.1, 10.0, size=(n, 1, 3))
    # Unconstrained solutions spread around the box [0, 1000]^3, so that each unknown is
    # often below 0, inside, or above 1000.
    x_true = rng.uniform(-600.0, 1600.0, size=(n, 3))
    b = np.einsum("nmp,np->nm", A, x_true) + 50.0 * rng.normal(size=(n, 100))
    return A, b


def test_same_minimiser_as_lsq_linear_on_random_problems_with_active_bounds():
    A, b = _random_problems(300)
    x = cf._box_lsq(A, b, LOWER, UPPER)
    at_lower = at_upper = inside = 0
    for j in range(len(A)):
        ref = lsq_linear(A[j], b[j], bounds=(LOWER, UPPER), method="bvls", tol=1e-14).x
        np.testing.assert_allclose(x[j], ref, rtol=1e-9, atol=1e-9 * UPPER[0])
        at_lower += np.any(ref <= LOWER)
        at_upper += np.any(ref >= UPPER)
        inside += np.all((ref > LOWER) & (ref < UPPER))
    # the sample exercises every branch: bounds at 0, at k_max, and the unconstrained fast path
    assert at_lower > 30 and at_upper > 30 and inside > 10, (at_lower, at_upper, inside)


def test_minimiser_satisfies_kkt_conditions():
    # Independent of scipy: g = A^T (A x - b) is >= 0 where x sits on its lower bound, <= 0 on
    # its upper bound and 0 where it is free (up to round-off of the gradient's size).
    A, b = _random_problems(200, seed=1)
    x = cf._box_lsq(A, b, LOWER, UPPER)
    assert np.all((x >= LOWER) & (x <= UPPER))
    g = np.einsum("nmp,nm->np", A, np.einsum("nmp,np->nm", A, x) - b)
    tol = 1e-9 * np.einsum("nmp,nm->np", np.abs(A), np.abs(b))
    free = (x > LOWER) & (x < UPPER)
    assert np.all(np.abs(g[free]) <= tol[free])
    assert np.all(g[x == LOWER] >= -tol[x == LOWER])
    assert np.all(g[x == UPPER] <= tol[x == UPPER])
    assert (~free).sum() > 50  # the bound cases are there


def test_batch_equals_one_problem_at_a_time():
    A, b = _random_problems(40, seed=2)
    batch = cf._box_lsq(A, b, LOWER, UPPER)
    for j in range(len(A)):
        np.testing.assert_allclose(
            cf._box_lsq(A[j : j + 1], b[j : j + 1], LOWER, UPPER)[0], batch[j], rtol=1e-12
        )


def test_dependent_columns_still_give_a_minimiser():
    # Column 3 = column 1: the minimiser is not unique, its residual is.
    rng = np.random.default_rng(3)
    a = rng.normal(size=(50, 2))
    A = np.column_stack([a, a[:, 0]])[None]
    for x_true in ([300.0, 200.0, 400.0], [900.0, -50.0, 800.0]):
        b = A[0] @ np.array(x_true)
        x = cf._box_lsq(A, b[None], LOWER, UPPER)[0]
        ref = lsq_linear(A[0], b, bounds=(LOWER, UPPER), method="bvls", tol=1e-14).x
        assert np.all((x >= LOWER) & (x <= UPPER))
        cost = np.sum((A[0] @ x - b) ** 2)
        cost_ref = np.sum((A[0] @ ref - b) ** 2)
        assert cost <= cost_ref + 1e-12 * np.sum(b**2)


def _lsq_linear_box(A, b, lower, upper):
    """The solver optimise_prb used before _box_lsq, one problem at a time."""
    return np.array([lsq_linear(A[j], b[j], bounds=(lower, upper)).x for j in range(len(A))])


@pytest.mark.parametrize("target, stroke", [(1.5, 35.0), (3.0, 25.0)])
def test_optimise_prb_same_fit_as_with_lsq_linear(monkeypatch, target, stroke):
    # (1.5 N, 35 mm): the paper's Table-1 problem; (3 N, 25 mm): its grid has active bounds.
    fit = cf.optimise_prb(target, stroke)
    monkeypatch.setattr(cf, "_box_lsq", _lsq_linear_box)
    old = cf.optimise_prb(target, stroke)
    new_x = [fit.params.r1_mm, fit.params.theta10_rad, *fit.params.stiffness_Nmm]
    old_x = [old.params.r1_mm, old.params.theta10_rad, *old.params.stiffness_Nmm]
    np.testing.assert_allclose(new_x, old_x, rtol=1e-6)
    assert fit.rms_error_N == pytest.approx(old.rms_error_N, rel=1e-6)
    np.testing.assert_allclose(fit.force_N, old.force_N, rtol=1e-6)


def test_grid_scores_equal_the_one_point_route():
    # _grid_rms batches what optimise_prb's solve_k does per point; unreachable points are inf.
    samples = cf.stroke_samples_mm(35.0, 100)
    target = np.full(samples.size, 1.5)
    lower, upper = cf.prb_bounds()
    grid = [np.array([r1, th]) for r1 in (12.0, 30.0, 54.0) for th in (0.5405, 0.56, 0.9, 1.5)]
    scores = cf._grid_rms(
        grid, lambda z: (z[0], z[1]), 100.0, 60.0, samples, target, lower[2:], upper[2:]
    )
    assert np.isinf(scores).any() and np.isfinite(scores).any()
    for z, score in zip(grid, scores, strict=True):
        state, ok = cf._state(z[0], z[1], 100.0, 60.0, samples)
        basis = cf._force_basis(state)
        if not (np.all(ok) and np.all(np.isfinite(basis))):
            assert np.isinf(score)
            continue
        k = lsq_linear(basis, target, bounds=(lower[2:], upper[2:]), method="bvls", tol=1e-14).x
        assert score == pytest.approx(np.sqrt(np.mean((basis @ k - target) ** 2)), rel=1e-9)
