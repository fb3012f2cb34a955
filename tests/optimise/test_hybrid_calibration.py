"""The hybrid's calibration of a constraint row by the problem's own check (run_hybrid(...,
check=), issue 27): a row the check finds under-reading the judged figure is tightened by the
measured factor and Gauss-Newton goes on, until the check is met; a replay asks the same designs.

The toy: least squares r = (x - 1, y - 1) (optimum (1, 1)) with the row g = x / 0.8 - 1 (the
"figure" x, its bound 0.8), so Gauss-Newton stops on x = 0.8. The "finer model" the verdict
judges reads ``x (1.1 + 0.05 x)``, more than the row sees and by a design-dependent ratio: the
design meeting it exactly has x = (-1.1 + sqrt(1.1^2 + 4 0.05 0.8)) / (2 0.05).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.optimise.design_jacobian import DesignJacobian
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.ga import GAConfig
from flexopt.optimise.hybrid import ConstraintCheck, HybridConfig, run_hybrid
from flexopt.optimise.space import DesignSpace

SPACE = DesignSpace(("x", "y"), np.array([-2.0, -1.0]), np.array([2.0, 3.0]))
BOUND = 0.8
#: the x at which the judged figure x (1.1 + 0.05 x) equals the bound, by the quadratic formula
X_MET = (-1.1 + math.sqrt(1.1**2 + 4 * 0.05 * BOUND)) / (2 * 0.05)


def judged(x: np.ndarray) -> float:
    return float(x[0] * (1.1 + 0.05 * x[0]))


def evaluate(X: np.ndarray) -> list[Evaluation]:
    out = []
    for x in np.atleast_2d(X):
        r = np.array([x[0] - 1.0, x[1] - 1.0])
        metrics = {f"residual_{i + 1}": float(v) for i, v in enumerate(r)}
        f = np.sqrt(np.mean(r**2))
        out.append(Evaluation(x.copy(), np.array([f]), np.array([x[0] / BOUND - 1.0]), metrics))
    return out


def jacobian(x: np.ndarray) -> DesignJacobian:
    r = np.array([x[0] - 1.0, x[1] - 1.0])
    f = max(float(np.sqrt(np.mean(r**2))), 1e-300)
    return DesignJacobian(x, (r / (2 * f))[None, :], np.array([[1.0 / BOUND, 0.0]]), np.eye(2))


class Checks:
    """The problem's check: the judged figure over the row's (x), and whether it is met."""

    def __init__(self) -> None:
        self.designs: list[np.ndarray] = []

    def __call__(self, x: np.ndarray) -> ConstraintCheck:
        self.designs.append(np.array(x, dtype=float))
        figure = judged(x)
        return ConstraintCheck({0: figure / x[0]}, figure <= BOUND, {"judged": figure})


def config() -> HybridConfig:
    return HybridConfig(GAConfig("ga", 10, 2, seed=3), local="gauss_newton", starts=2)


def test_without_a_check_the_best_design_breaks_the_judged_figure():
    result = run_hybrid(SPACE, evaluate, 1, 1, config(), jacobian=jacobian)
    assert result.best.feasible
    assert result.best.x[0] == pytest.approx(BOUND, abs=1e-6)
    assert judged(result.best.x) > BOUND  # the toy's point: the row alone is not enough
    assert "checks" not in result.report


def test_the_check_tightens_the_row_until_the_judged_figure_is_met():
    checks = Checks()
    result = run_hybrid(SPACE, evaluate, 1, 1, config(), jacobian=jacobian, check=checks)
    best = result.best
    assert judged(best.x) <= BOUND  # MET by the judged figure
    # the tightened row costs no more than needed: x between the exact boundary of the judged
    # figure and the one the first round's (larger-x) factor gives
    first = 1.1 + 0.05 * BOUND
    assert BOUND / first - 1e-6 <= best.x[0] <= X_MET + 1e-9
    assert best.x[1] == pytest.approx(1.0, abs=1e-6)
    report = result.report
    assert report["checks"]["best_verified"] is True
    assert report["checks"]["count"] == len(checks.designs) >= 2
    assert report["checks"]["met"] >= 1
    rounds = report["starts"][0]["calibration"]
    assert rounds[0]["round"] == 0 and rounds[0]["met"] is False  # x = 0.8: over
    assert rounds[0]["judged"] == pytest.approx(judged(np.array([BOUND])), rel=1e-6)
    assert rounds[-1]["met"] is True
    assert rounds[-1]["factors"]["0"] >= first - 1e-9  # never loosened
    # each checked design is one the stage evaluated (no design outside the store)
    seen = {e.x.tobytes() for g in result.generations for e in g.evaluations}
    assert all(x.tobytes() in seen for x in checks.designs)


def test_the_check_is_found_on_the_problem_the_jacobian_belongs_to():
    class Problem:
        def __init__(self) -> None:
            self.checks = Checks()

        def jacobian(self, x: np.ndarray) -> DesignJacobian:
            return jacobian(x)

        def check_constraints(self, x: np.ndarray) -> ConstraintCheck:
            return self.checks(x)

    problem = Problem()
    result = run_hybrid(SPACE, evaluate, 1, 1, config(), jacobian=problem.jacobian)
    assert judged(result.best.x) <= BOUND
    assert result.report["checks"]["count"] == len(problem.checks.designs) > 0


def test_a_replay_from_the_store_asks_the_same_designs_and_ends_the_same():
    """A resumed run answers every design from its store: the stage must ask exactly the
    designs it asked before (the checks are a deterministic function of the design)."""
    store: dict[bytes, Evaluation] = {}

    def stored(X: np.ndarray) -> list[Evaluation]:
        out = evaluate(X)
        store.update({e.x.tobytes(): e for e in out})
        return out

    def replay(X: np.ndarray) -> list[Evaluation]:
        return [store[np.asarray(x, dtype=float).tobytes()] for x in np.atleast_2d(X)]

    first = run_hybrid(SPACE, stored, 1, 1, config(), jacobian=jacobian, check=Checks())
    again = run_hybrid(SPACE, replay, 1, 1, config(), jacobian=jacobian, check=Checks())
    assert again.best.x.tobytes() == first.best.x.tobytes()
    without_time = [{k: v for k, v in r.report.items() if k != "checks"} for r in (first, again)]
    assert without_time[0] == without_time[1]
    assert {k: v for k, v in first.report["checks"].items() if k != "time_s"} == {
        k: v for k, v in again.report["checks"].items() if k != "time_s"
    }


def test_a_check_that_answers_none_leaves_the_stage_best():
    plain = run_hybrid(SPACE, evaluate, 1, 1, config(), jacobian=jacobian)
    result = run_hybrid(SPACE, evaluate, 1, 1, config(), jacobian=jacobian, check=lambda x: None)
    assert result.best.x.tobytes() == plain.best.x.tobytes()
    assert result.report["checks"]["best_verified"] is False
    assert result.report["starts"][0]["calibration"][0]["stop"] == "the check did not answer"


class Passing(Checks):
    """A check every design meets (its figure recorded as the toy's judged one)."""

    def __call__(self, x: np.ndarray) -> ConstraintCheck:
        self.designs.append(np.array(x, dtype=float))
        return ConstraintCheck({}, True, {"judged": judged(x)})


@pytest.mark.parametrize("lockstep", [True, False])
def test_a_start_whose_best_is_not_below_a_met_check_is_not_checked(lockstep):
    """Two starts stopped early (2 iterations: their ends differ). The lower one's design is
    checked first and met; the other start's best cannot become the result (the lowest design
    whose check was met), so it is not checked: one check, one spared, in lockstep or not."""
    cfg = HybridConfig(GAConfig("ga", 10, 2, seed=3), local="gauss_newton", starts=2, max_iter=2)
    checks = Passing()
    result = run_hybrid(
        SPACE, evaluate, 1, 1, cfg, jacobian=jacobian, check=checks, lockstep=lockstep
    )
    report = result.report
    ends = [s["f_end"] for s in report["starts"]]
    assert len(ends) == 2 and ends[0] != ends[1]
    low, high = int(np.argmin(ends)), int(np.argmax(ends))
    assert len(checks.designs) == 1
    np.testing.assert_array_equal(checks.designs[0], result.best.x)
    assert float(result.best.f[0]) == min(ends)
    assert {k: v for k, v in report["checks"].items() if k != "time_s"} == {
        "count": 1, "met": 1, "best_verified": True, "spared": 1
    }  # fmt: skip
    assert report["starts"][low]["calibration"][0]["met"] is True
    (spared,) = report["starts"][high]["calibration"]
    assert spared["f"] == ends[high] and spared["stop"].startswith("not checked")


def test_where_the_lowest_start_fails_its_check_every_start_is_checked():
    """The lowest start's first check is not met: nothing is spared, every start calibrates
    (the toy's check fails at the row's bound x = 0.8, where both starts end)."""
    checks = Checks()
    result = run_hybrid(SPACE, evaluate, 1, 1, config(), jacobian=jacobian, check=checks)
    report = result.report
    assert report["checks"]["spared"] == 0
    for start in report["starts"]:
        assert start["calibration"][0]["met"] is False
        assert start["calibration"][-1]["met"] is True
