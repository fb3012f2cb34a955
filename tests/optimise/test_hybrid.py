"""The hybrid optimiser (optimise/hybrid.py): known optima, the stop rule, the budget, starts."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.ga import GAConfig
from flexopt.optimise.hybrid import (
    HybridConfig,
    StallRule,
    pick_starts,
    residuals_of,
    run_hybrid,
)
from flexopt.optimise.space import DesignSpace

SPACE = DesignSpace(("x", "y"), np.array([-2.0, -1.0]), np.array([2.0, 3.0]))


def rosenbrock(X: np.ndarray) -> list[Evaluation]:
    """Rosenbrock as least squares: r = (10 (y - x^2), 1 - x), f = sqrt(mean(r^2)), minimum 0
    at (1, 1); the constraint x + y <= 2.5 is inactive there."""
    out = []
    for x in np.atleast_2d(X):
        r = np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])
        metrics = {f"residual_{i + 1}": float(v) for i, v in enumerate(r)}
        f = np.sqrt(np.mean(r**2))
        out.append(Evaluation(x.copy(), np.array([f]), np.array([x[0] + x[1] - 2.5]), metrics))
    return out


def constrained_bowl(X: np.ndarray) -> list[Evaluation]:
    """(x - 0.3)^2 + (y - 0.7)^2 + 0.1 subject to x + y >= 1.2: the optimum (0.4, 0.8), 0.12."""
    out = []
    for x in np.atleast_2d(X):
        f = (x[0] - 0.3) ** 2 + (x[1] - 0.7) ** 2 + 0.1
        out.append(Evaluation(x.copy(), np.array([f]), np.array([1.2 - x[0] - x[1]])))
    return out


def config(local: str, **options) -> HybridConfig:
    return HybridConfig(GAConfig("ga", 10, 2, seed=3), local=local, **options)


class Counting:
    """An evaluate that records every batch it is given."""

    def __init__(self, evaluate) -> None:
        self.evaluate = evaluate
        self.batches: list[int] = []

    def __call__(self, X: np.ndarray) -> list[Evaluation]:
        self.batches.append(len(X))
        return self.evaluate(X)


def test_gauss_newton_finds_the_least_squares_optimum():
    evaluate = Counting(rosenbrock)
    result = run_hybrid(SPACE, evaluate, 1, 1, config("gauss_newton", starts=2, max_iter=100))
    assert result.best.feasible
    np.testing.assert_allclose(result.best.x, [1.0, 1.0], atol=1e-3)
    assert result.best.f[0] < 1e-4
    report = result.report
    assert report["best_stage"] == "gradient" and report["local"] == "gauss_newton"
    assert report["n_evaluations"]["ga"] == 20
    assert report["n_evaluations"]["gradient"] == sum(evaluate.batches) - 20
    assert len(report["starts"]) == 2
    # the Jacobian's columns are one batch each (parallel like a generation)
    assert SPACE.n_var in evaluate.batches[2:]
    # every batch of the gradient stage is a generation of the run
    assert len(result.generations) == len(evaluate.batches)
    assert result.generations[-1].n_evaluations == sum(evaluate.batches)


def test_slsqp_finds_the_constrained_optimum():
    result = run_hybrid(SPACE, constrained_bowl, 1, 1, config("slsqp", starts=1, max_iter=50))
    assert result.best.feasible
    np.testing.assert_allclose(result.best.x, [0.4, 0.8], atol=1e-3)
    assert result.best.f[0] == pytest.approx(0.12, abs=1e-5)
    assert result.report["best_stage"] == "gradient"


def test_the_stop_rule_counts_iterations_without_a_relative_improvement():
    rule = StallRule(1.0, tolerance=0.01, patience=2)
    assert rule.update(0.5) is None  # improved
    assert rule.update(0.499) is None  # 0.2 %: not beyond 1 %
    assert rule.update(0.3) is None  # improved: the count starts again
    assert rule.update(0.3) is None
    assert rule.update(0.299) == "no improvement beyond 0.01 (relative) over 2 iterations"


def test_the_stop_rule_ends_a_start_that_creeps():
    # r = 1 + 1e-5 x: every step improves, by far less than the tolerance (1e-3 relative)
    def creeping(X):
        out = []
        for x in np.atleast_2d(X):
            r = 1.0 + 1e-5 * x[0]
            out.append(Evaluation(x.copy(), np.array([r]), np.array([-1.0]), {"residual_1": r}))
        return out

    result = run_hybrid(
        SPACE, creeping, 1, 1, config("gauss_newton", starts=2, patience=2, max_iter=50)
    )
    for start in result.report["starts"]:
        assert start["stop"] == "no improvement beyond 0.001 (relative) over 2 iterations"
        assert start["iterations"] == 2
        assert start["f_end"] < start["f_start"]  # it did improve, a little


def test_the_stop_rule_fires_on_a_converged_gauss_newton_run():
    result = run_hybrid(
        SPACE, rosenbrock, 1, 1, config("gauss_newton", starts=1, max_iter=500, patience=3)
    )
    (start,) = result.report["starts"]
    assert start["iterations"] < 500
    assert "no improvement" in start["stop"] or "trust region" in start["stop"]


def test_the_budget_ends_the_gradient_stage():
    result = run_hybrid(
        SPACE, rosenbrock, 1, 1, config("gauss_newton", starts=3, max_evaluations=15)
    )
    assert result.report["n_evaluations"]["gradient"] <= 15
    assert "max_evaluations (15)" in result.report["stop"]


def test_the_same_evaluations_give_the_same_run():
    a = run_hybrid(SPACE, rosenbrock, 1, 1, config("gauss_newton", starts=2))
    b = run_hybrid(SPACE, rosenbrock, 1, 1, config("gauss_newton", starts=2))
    xa = [e.x for g in a.generations for e in g.evaluations]
    xb = [e.x for g in b.generations for e in g.evaluations]
    assert len(xa) == len(xb) and all(np.array_equal(p, q) for p, q in zip(xa, xb, strict=True))


def test_starts_are_distinct_and_ranked():
    evs = rosenbrock(np.array([[1.0, 1.0], [1.01, 1.0], [0.0, 0.0], [-1.0, 1.0]]))
    chosen = pick_starts(SPACE, evs, 3, 0.1)
    assert [tuple(e.x) for e in chosen] == [(1.0, 1.0), (0.0, 0.0), (-1.0, 1.0)]


def test_residuals_are_read_from_the_metrics():
    (ev,) = rosenbrock(np.array([[0.5, 0.5]]))
    np.testing.assert_allclose(residuals_of(ev), [2.5, 0.5])
    failed = Evaluation.failed(np.zeros(2), 1, 1, "no")
    assert residuals_of(failed) is None
    assert residuals_of(constrained_bowl(np.zeros(2))[0]) is None


def test_the_constant_force_problem_gives_eq8_residuals_only_when_asked():
    from pathlib import Path

    import flexopt.pipeline as pipeline
    from flexopt.pipeline.run.setup import build_problem
    from flexopt.pipeline.study import load_study

    study = load_study(Path(pipeline.__file__).parent / "examples" / "constant-force.yaml")
    problem = build_problem(study)
    x = problem.nominal_design()
    plain = problem.evaluate(x)
    with_r = problem.with_residuals()
    assert with_r is not None and with_r is not problem
    ev = with_r.evaluate(x)
    r = residuals_of(ev)
    assert r is not None and r.shape == (study.target.samples,)
    assert float(np.sqrt(np.mean(r**2))) == pytest.approx(ev.f[0], rel=1e-12)
    # the same objectives, constraints and metrics; the plain problem's evaluations unchanged
    np.testing.assert_array_equal(ev.f, plain.f)
    np.testing.assert_array_equal(ev.g, plain.g)
    assert residuals_of(plain) is None
    assert {k: v for k, v in ev.metrics.items() if not k.startswith("residual_")} == plain.metrics
    assert problem.evaluate(x).metrics == plain.metrics
    operative = study.model_copy(update={"objective": "operative_stroke"})
    assert build_problem(operative).with_residuals() is None


def test_the_ga_stage_is_the_first_generations_of_the_full_ga():
    # _ga_stage stops the GA from its callback: what it asked must be what a GA of fewer
    # generations asks, or a resume (replay) and the documentation would be wrong
    from flexopt.optimise.ga import run_ga

    short = run_ga(SPACE, constrained_bowl, 1, 1, GAConfig("ga", 10, 3, seed=4))
    hybrid = run_hybrid(
        SPACE,
        constrained_bowl,
        1,
        1,
        HybridConfig(GAConfig("ga", 10, 12, seed=4), ga_n_gen=3, local="slsqp", starts=1),
    )
    assert hybrid.report["ga"]["generations"] == 3
    first = [e.x for g in short.generations for e in g.evaluations]
    again = [e.x for g in hybrid.generations[:3] for e in g.evaluations]
    assert all(np.array_equal(p, q) for p, q in zip(first, again, strict=True))
