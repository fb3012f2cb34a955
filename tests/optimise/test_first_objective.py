"""A multi-objective problem seen by its first objective (optimise/first_objective.py): the
evaluations, the exact Jacobian and the one-residual Gauss-Newton form, and the hybrid on it
finding a known constrained optimum."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.design_jacobian import DesignJacobian
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.first_objective import FirstObjective
from flexopt.optimise.ga import GAConfig
from flexopt.optimise.hybrid import HybridConfig, residuals_of, run_hybrid
from flexopt.optimise.problem import DesignProblem
from flexopt.optimise.space import DesignSpace


class TwoObjectives(DesignProblem):
    """f1 = 1 + (x - 0.2)^2 + (y - 0.9)^2 (positive), f2 = x + y, subject to x + y >= 1.5 and a
    second row without a derivative (NaN in the Jacobian), g2 = x - 5 (never active). The
    constrained minimum of f1 is the projection of (0.2, 0.9) on x + y = 1.5: (0.4, 1.1), f1 =
    1.08."""

    def __init__(self) -> None:
        self.space = DesignSpace(("x", "y"), np.array([-1.0, -1.0]), np.array([2.0, 2.0]))
        self.objective_names = ("f1", "f2")
        self.constraint_names = ("sum", "far")

    def evaluate(self, x: np.ndarray) -> Evaluation:
        x = np.asarray(x, dtype=float)
        f1 = 1.0 + (x[0] - 0.2) ** 2 + (x[1] - 0.9) ** 2
        g = np.array([1.5 - x[0] - x[1], x[0] - 5.0])
        return Evaluation(x.copy(), np.array([f1, x[0] + x[1]]), g, {"other": 1.0})

    def detail(self, x: np.ndarray):  # not used here
        raise NotImplementedError

    def jacobian(self, x: np.ndarray) -> DesignJacobian:
        x = np.asarray(x, dtype=float)
        f = np.array([[2.0 * (x[0] - 0.2), 2.0 * (x[1] - 0.9)], [1.0, 1.0]])
        g = np.array([[-1.0, -1.0], [np.nan, np.nan]])
        ev = self.evaluate(x)
        return DesignJacobian(x, f, g, values={"f": ev.f, "g": ev.g})


def test_the_first_objective_and_the_others_as_metrics():
    inner = TwoObjectives()
    p = FirstObjective(inner)
    assert p.objective_names == ("f1",) and p.constraint_names == inner.constraint_names
    x = np.array([1.0, 0.0])
    ev, full = p.evaluate(x), inner.evaluate(x)
    assert ev.f.shape == (1,) and ev.f[0] == full.f[0]
    assert ev.metrics["f2"] == full.f[1] and ev.metrics["other"] == 1.0
    np.testing.assert_array_equal(ev.g, full.g)
    assert residuals_of(ev) is None  # no residual unless asked for


def test_jacobian_first_row_and_undifferentiated_rows_zero():
    p = FirstObjective(TwoObjectives())
    jac = p.jacobian(np.array([1.0, 0.0]))
    np.testing.assert_allclose(jac.f, [[1.6, -1.8]])
    np.testing.assert_array_equal(jac.g, [[-1.0, -1.0], [0.0, 0.0]])
    assert jac.info["zero_rows"] == ["far"]
    assert jac.residuals is None


def test_residual_form_is_the_objective():
    p = FirstObjective(TwoObjectives()).with_residuals()
    x = np.array([1.0, 0.0])
    ev = p.evaluate(x)
    r = residuals_of(ev)
    assert r is not None and r.shape == (1,) and r[0] == ev.f[0]
    jac = p.jacobian(x)
    np.testing.assert_allclose(jac.residuals, jac.f)


@pytest.mark.parametrize("local", ["gauss_newton", "slsqp"])
def test_hybrid_finds_the_constrained_minimum_of_the_first_objective(local: str):
    p = FirstObjective(TwoObjectives())
    if local == "gauss_newton":
        p = p.with_residuals()
    config = HybridConfig(GAConfig("ga", 8, 2, seed=2), ga_n_gen=1, local=local, starts=1)
    result = run_hybrid(
        p.space,
        lambda X: [p.evaluate(x) for x in np.atleast_2d(X)],
        1,
        2,
        config,
        jacobian=p.jacobian,
    )
    assert result.best.feasible
    assert result.best.f[0] == pytest.approx(1.08, abs=2e-3)
    np.testing.assert_allclose(result.best.x, [0.4, 1.1], atol=0.03)
    assert result.report["jacobians"]["exact"] >= 1
