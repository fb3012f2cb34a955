"""The Gauss-Newton step solved exactly (optimise/hybrid.py, ``least_squares_inequalities`` and
``_exact_step``, session 34): Lawson and Hanson's LSI -> LDP -> NNLS against solutions worked
out here, and the elastic fallback where the linearised rows cannot be met.

Each reference is independent of the solver: a projection onto a half-space (closed form), a
box (``scipy.optimize.lsq_linear``'s bounded-variable least squares), the KKT conditions of
random problems (multipliers from the active rows by NNLS), and inconsistent rows.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.hybrid import (
    ELASTIC_WEIGHT,
    STEP_DAMPING,
    _exact_step,
    _gauss_newton_step,
    least_squares_inequalities,
)
from scipy.optimize import lsq_linear, nnls


def test_projection_onto_a_half_space_is_the_closed_form():
    # min ||x - p|| s.t. a.x >= b: x = p + max(0, b - a.p) a / |a|^2
    rng = np.random.default_rng(3)
    for _ in range(20):
        n = int(rng.integers(2, 8))
        p, a = rng.normal(size=n), rng.normal(size=n)
        b = float(rng.normal())
        x = least_squares_inequalities(np.eye(n), p, a[None, :], np.array([b]))
        want = p + max(0.0, b - a @ p) * a / (a @ a)
        np.testing.assert_allclose(x, want, atol=1e-12)


def test_a_box_is_bounded_variable_least_squares():
    rng = np.random.default_rng(5)
    for _ in range(20):
        m, n = 12, 6
        E, f = rng.normal(size=(m, n)), rng.normal(size=m)
        lo, hi = -rng.random(n) * 0.3, rng.random(n) * 0.3
        G = np.vstack([np.eye(n), -np.eye(n)])
        h = np.concatenate([lo, -hi])
        x = least_squares_inequalities(E, f, G, h)
        want = lsq_linear(E, f, bounds=(lo, hi), method="bvls", tol=1e-14).x
        np.testing.assert_allclose(x, want, atol=1e-10)


@pytest.mark.parametrize("seed", range(10))
def test_random_problems_meet_their_kkt_conditions(seed):
    """x is feasible and E^T (E x - f) = G_A^T lam with lam >= 0 on the active rows A: the
    first-order conditions of a convex problem, sufficient for its optimum."""
    rng = np.random.default_rng(seed)
    m, n, k = 15, 8, 20
    E, f = rng.normal(size=(m, n)), rng.normal(size=m) * 3.0
    G = rng.normal(size=(k, n))
    h = G @ rng.normal(size=n) - rng.random(k)  # a point inside all rows: feasible
    x = least_squares_inequalities(E, f, G, h)
    assert x is not None
    slack = G @ x - h
    assert slack.min() > -1e-10
    active = slack < 1e-8
    gradient = E.T @ (E @ x - f)
    lam, residual = nnls(G[active].T, gradient) if active.any() else (np.zeros(0), 0.0)
    scale = 1.0 + np.linalg.norm(gradient)
    assert residual < 1e-8 * scale  # the gradient is a non-negative combination of them


def test_inconsistent_rows_are_refused():
    # x >= 1 and -x >= 0 (x <= 0): no x meets both
    G = np.array([[1.0], [-1.0]])
    assert least_squares_inequalities(np.eye(1), np.zeros(1), G, np.array([1.0, 0.0])) is None


def test_the_step_picks_the_shortest_of_equally_good_steps():
    # one residual, two variables: r + J d = 0 on a line; the damping takes its closest point
    r, J = np.array([-1.0]), np.array([[1.0, 1.0]])
    lower, upper = np.full(2, -2.0), np.full(2, 2.0)
    d = _exact_step(r, J, np.zeros((0, 2)), np.zeros(0), lower, upper)
    np.testing.assert_allclose(d, [0.5, 0.5], atol=1e-5)
    # the damping's cost: <= STEP_DAMPING |d|^2 on the scaled objective
    assert 0.5 * float((r + J @ d) @ (r + J @ d)) / float(r @ r) < STEP_DAMPING


def test_the_option_solves_the_step_exactly_and_the_default_by_slsqp():
    """``exact=True`` (``step_solver: exact``) returns the exact solve's step; the default
    SLSQP's, which on this problem stops within its tolerance of it."""
    rng = np.random.default_rng(2)
    J, r = rng.normal(size=(4, 6)), rng.normal(size=4)
    g, Jg = np.array([-0.01]), rng.normal(size=(1, 6))
    lower, upper = np.full(6, -0.2), np.full(6, 0.2)
    backoff = np.zeros(1)
    d = _gauss_newton_step(r, J, g, Jg, lower, upper, backoff, exact=True)
    aim = np.maximum(-backoff - 1e-8, g) - g  # a feasible design aims no further inside
    np.testing.assert_array_equal(d, _exact_step(r, J, Jg, aim, lower, upper))
    slsqp = _gauss_newton_step(r, J, g, Jg, lower, upper, backoff)
    assert not np.array_equal(d, slsqp)
    np.testing.assert_allclose(J @ slsqp, J @ d, atol=1e-3)


def test_rows_that_cannot_be_met_fall_back_to_the_elastic_step():
    """An infeasible design whose row cannot be met inside the trust region: the exact solve
    refuses, SLSQP's elastic problem lowers the violation as far as the region allows."""
    r, J = np.array([-1.0, 0.5]), np.eye(2)
    g, Jg = np.array([1.0]), np.array([[1.0, 0.0]])  # g + d_x <= 0 needs d_x <= -1
    lower, upper = np.full(2, -0.3), np.full(2, 0.3)
    assert _exact_step(r, J, Jg, -g - 1e-8, lower, upper) is None  # Jg d <= -g
    d = _gauss_newton_step(r, J, g, Jg, lower, upper, np.zeros(1), exact=True)
    assert d[0] == pytest.approx(-0.3, abs=1e-7)  # as far as the region goes
    assert ELASTIC_WEIGHT > 1.0  # the violation is priced above the objective


def test_the_exact_step_meets_the_rows_the_old_slsqp_step_aimed_at():
    """Against the elastic (SLSQP) solve of the same feasible problem: the exact step is at
    least as good on the objective and meets every row to 1e-10."""
    rng = np.random.default_rng(11)
    n, n_res, n_rows = 23, 10, 40
    for _ in range(5):
        J, r = rng.normal(size=(n_res, n)), rng.normal(size=n_res)
        H = rng.normal(size=(n_rows, n)) * 0.1
        h = -rng.random(n_rows) * 0.05
        lower, upper = np.full(n, -0.1), np.full(n, 0.1)
        d = _exact_step(r, J, H, -h, lower, upper)
        assert d is not None
        assert float(np.max(h + H @ d)) < 1e-10
        from scipy.optimize import minimize

        def objective(z, J=J, r=r):
            e = r + J @ z
            return 0.5 * float(e @ e)

        ref = minimize(
            objective,
            np.zeros(n),
            jac=lambda z, J=J, r=r: J.T @ (r + J @ z),
            bounds=list(zip(lower, upper, strict=True)),
            constraints=[{"type": "ineq", "fun": lambda z, H=H, h=h: -(h + H @ z)}],
            method="SLSQP",
            options={"maxiter": 500, "ftol": 1e-14},
        ).x
        # the damping may cost up to STEP_DAMPING |d|^2 of the objective scaled by |r|^2
        assert objective(d) <= objective(ref) + STEP_DAMPING * float(d @ d) * float(r @ r) + 1e-9
