"""The hybrid optimiser with the problem's exact Jacobian (run_hybrid(..., jacobian=)): the same
optima as with finite differences, no perturbed designs evaluated, FD where it answers None."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.design_jacobian import DesignJacobian
from flexopt.optimise.ga import GAConfig
from flexopt.optimise.hybrid import HybridConfig, run_hybrid
from test_hybrid import SPACE, Counting, constrained_bowl, rosenbrock


def rosenbrock_jacobian(x: np.ndarray) -> DesignJacobian:
    """Rosenbrock's derivatives by hand: r = (10 (y - x^2), 1 - x), f = sqrt(mean(r^2)),
    g = x + y - 2.5."""
    r = np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])
    dr = np.array([[-20.0 * x[0], 10.0], [-1.0, 0.0]])
    f = np.sqrt(np.mean(r**2))
    return DesignJacobian(x, (r @ dr / (2 * f))[None, :], np.array([[1.0, 1.0]]), dr)


def bowl_jacobian(x: np.ndarray) -> DesignJacobian:
    """(x - 0.3)^2 + (y - 0.7)^2 + 0.1 and 1.2 - x - y: their gradients by hand."""
    df = np.array([[2.0 * (x[0] - 0.3), 2.0 * (x[1] - 0.7)]])
    return DesignJacobian(x, df, np.array([[-1.0, -1.0]]))


def config(local: str, **options) -> HybridConfig:
    return HybridConfig(GAConfig("ga", 10, 2, seed=3), local=local, **options)


def test_gauss_newton_with_the_exact_jacobian_evaluates_no_perturbed_design():
    evaluate = Counting(rosenbrock)
    calls = []

    def jacobian(x):
        calls.append(x.copy())
        return rosenbrock_jacobian(x)

    cfg = config("gauss_newton", starts=2, max_iter=100)
    result = run_hybrid(SPACE, evaluate, 1, 1, cfg, jacobian=jacobian)
    assert result.best.feasible
    np.testing.assert_allclose(result.best.x, [1.0, 1.0], atol=1e-3)
    assert result.best.f[0] < 1e-4
    # after the GA's two generations of 10, every batch is one trial step of each live start
    # (the two starts in lockstep: a batch of two while both run)
    assert evaluate.batches[:2] == [10, 10] and set(evaluate.batches[2:]) == {1, 2}
    jac = result.report["jacobians"]
    assert jac["exact"] == len(calls) > 0 and jac["finite_differences"] == 0
    # each Jacobian is taken at a design the stage evaluated
    seen = {e.x.tobytes() for g in result.generations for e in g.evaluations}
    assert all(x.tobytes() in seen for x in calls)
    fd = Counting(rosenbrock)
    run_hybrid(SPACE, fd, 1, 1, cfg)
    assert sum(evaluate.batches) < sum(fd.batches)


def test_exact_jacobian_false_takes_finite_differences():
    evaluate = Counting(rosenbrock)
    cfg = config("gauss_newton", starts=1, max_iter=100, exact_jacobian=False)
    result = run_hybrid(SPACE, evaluate, 1, 1, cfg, jacobian=rosenbrock_jacobian)
    jac = result.report["jacobians"]
    assert jac["exact"] == 0 and jac["finite_differences"] > 0
    assert SPACE.n_var in evaluate.batches[2:]


def test_a_jacobian_that_answers_none_falls_back_to_finite_differences():
    evaluate = Counting(rosenbrock)
    cfg = config("gauss_newton", starts=1, max_iter=100)
    result = run_hybrid(SPACE, evaluate, 1, 1, cfg, jacobian=lambda x: None)
    np.testing.assert_allclose(result.best.x, [1.0, 1.0], atol=1e-3)
    assert result.report["jacobians"]["exact"] == 0
    assert result.report["jacobians"]["finite_differences"] > 0


def test_slsqp_with_the_exact_gradient_finds_the_constrained_optimum():
    """With exact gradients of a linear constraint SLSQP's iterates lie on it, where round-off
    (1e-16) decides g <= 0: the optimum is the last design the stage evaluated, feasible to
    round-off."""
    evaluate = Counting(constrained_bowl)
    cfg = config("slsqp", starts=1, max_iter=50)
    result = run_hybrid(SPACE, evaluate, 1, 1, cfg, jacobian=bowl_jacobian)
    last = result.generations[-1].evaluations[-1]
    np.testing.assert_allclose(last.x, [0.4, 0.8], atol=1e-6)
    assert last.f[0] == pytest.approx(0.12, abs=1e-9) and last.g[0] <= 1e-12
    assert set(evaluate.batches[2:]) == {1}
    assert result.report["jacobians"]["finite_differences"] == 0


def test_a_jacobian_that_raises_falls_back_to_finite_differences():
    def broken(x):
        raise RuntimeError("cannot differentiate here")

    cfg = config("gauss_newton", starts=1, max_iter=100)
    result = run_hybrid(SPACE, rosenbrock, 1, 1, cfg, jacobian=broken)
    np.testing.assert_allclose(result.best.x, [1.0, 1.0], atol=1e-3)
    assert result.report["jacobians"]["exact"] == 0
    assert result.report["jacobians"]["finite_differences"] > 0
