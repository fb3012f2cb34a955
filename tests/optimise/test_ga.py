"""The GA driver: reproducible from its seed, finds known optima, reports failures as data."""

import numpy as np
import pytest
from flexopt.optimise import DesignSpace, Evaluation, GAConfig, OptimiseError, run_ga


def sphere_with_constraint(X):
    """min sum((x - 0.3)^2) s.t. x0 >= 0.5: optimum x = (0.5, 0.3, 0.3), f = 0.04."""
    out = []
    for x in X:
        f = np.array([np.sum((x - 0.3) ** 2)])
        g = np.array([0.5 - x[0]])
        out.append(Evaluation(x.copy(), f, g))
    return out


SPACE = DesignSpace(("a", "b", "c"), np.zeros(3), np.ones(3))


def test_same_seed_same_run_and_the_constrained_optimum_is_found():
    cfg = GAConfig(pop_size=30, n_gen=40, seed=7)
    r1 = run_ga(SPACE, sphere_with_constraint, 1, 1, cfg)
    r2 = run_ga(SPACE, sphere_with_constraint, 1, 1, cfg)
    assert np.array_equal(r1.best.x, r2.best.x)
    assert r1.best.feasible
    assert r1.best.f[0] == pytest.approx(0.04, abs=5e-3)
    assert r1.best.x[0] == pytest.approx(0.5, abs=0.02)
    assert len(r1.generations) == 40


def test_failed_designs_are_infeasible_data_and_the_run_goes_on():
    def sometimes_fails(X):
        out = sphere_with_constraint(X)
        return [
            Evaluation.failed(x, 1, 1, "mesh failed") if x[1] > 0.8 else e
            for x, e in zip(X, out, strict=True)
        ]

    r = run_ga(SPACE, sometimes_fails, 1, 1, GAConfig(pop_size=20, n_gen=10, seed=3))
    assert r.best.feasible and r.best.x[1] <= 0.8
    failed = [e for g in r.generations for e in g.evaluations if e.reason]
    assert failed and not any(e.feasible for e in failed)


def test_nsga2_returns_a_non_dominated_front():
    def two(X):
        return [
            Evaluation(x.copy(), np.array([x[0], 1 - x[0] + x[1] ** 2]), np.zeros(0)) for x in X
        ]

    r = run_ga(SPACE, two, 2, 0, GAConfig("nsga2", pop_size=20, n_gen=15, seed=1))
    F = np.array([e.f for e in r.front])
    assert len(F) > 5
    for a in F:
        assert not np.any(np.all(F <= a, axis=1) & np.any(F < a, axis=1))


def test_initial_designs_are_evaluated_first():
    seen = []

    def record(X):
        seen.append(X.copy())
        return sphere_with_constraint(X)

    x0 = np.array([[0.5, 0.3, 0.3]])
    run_ga(SPACE, record, 1, 1, GAConfig(pop_size=10, n_gen=1, seed=1), initial=x0)
    assert np.allclose(seen[0][0], x0[0])


def test_swapped_bounds_are_named():
    with pytest.raises(OptimiseError, match="swap"):
        DesignSpace(("t1",), np.array([2.0]), np.array([1.0]))


def test_a_design_with_a_reason_is_never_ranked_feasible():
    """Values that come with a failure reason are not trusted (pymoo sees the worst values)."""

    def lying(X):
        return [
            Evaluation(x.copy(), np.array([-1.0]), np.array([-1.0]), reason="timed out")
            if x[2] > 0.5
            else e
            for x, e in zip(X, sphere_with_constraint(X), strict=True)
        ]

    r = run_ga(SPACE, lying, 1, 1, GAConfig(pop_size=20, n_gen=8, seed=2))
    assert r.best.feasible and not r.best.reason and r.best.x[2] <= 0.5


def test_each_generations_best_is_the_best_of_every_design_so_far():
    """The best is carried from generation to generation (not re-chosen from every design each
    time): it must be the very design best_of picks from all evaluations so far, with failed
    designs, a stretch with no feasible design, and ties (the earliest of equal ones)."""
    from flexopt.optimise.ga import best_of

    def coarse(X):
        out = []
        for x in X:
            if x[2] > 0.85:
                out.append(Evaluation.failed(x, 1, 1, "mesh failed"))
                continue
            f = np.array([np.round(np.sum((x - 0.3) ** 2), 1)])  # ties are common
            g = np.array([1.1 - x[0] - 0.2 * x[1]])  # feasible only in a corner
            out.append(Evaluation(x.copy(), f, g))
        return out

    r = run_ga(SPACE, coarse, 1, 1, GAConfig(pop_size=12, n_gen=12, seed=5))
    seen = []
    kinds = set()
    for gen in r.generations:
        seen.extend(gen.evaluations)
        assert gen.best is best_of(seen)
        kinds.add((gen.best.feasible, bool(gen.best.reason)))
    assert r.best is best_of(seen)
    assert (True, False) in kinds and (False, False) in kinds  # both regimes were crossed
