"""The Gauss-Newton stage with a constraint row given as pieces (a max, like the constant-force
beam's peak stress that switches between the clamp and mid-beam) (optimise/hybrid.py).

The problem: residuals r = (x - 1, y - 1) (f = sqrt(mean(r^2))) subject to g = max(x - 0.5, y -
0.5) <= 0. Its optimum, by hand: the nearest point of the feasible quadrant to (1, 1) is (0.5,
0.5), where r = (-0.5, -0.5) and f = 0.5. The row's own derivative is the active piece's (as a
max's derivative is), so a step linearised on it alone does not see the other piece rise.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.design_jacobian import DesignJacobian
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.ga import GAConfig
from flexopt.optimise.hybrid import HybridConfig, pieces_of, run_hybrid
from flexopt.optimise.space import DesignSpace

SPACE = DesignSpace(("x", "y"), np.array([-2.0, -1.0]), np.array([2.0, 3.0]))


def corner(X: np.ndarray) -> list[Evaluation]:
    out = []
    for x in np.atleast_2d(X):
        r = x - 1.0
        g = max(x[0] - 0.5, x[1] - 0.5)
        metrics = {f"residual_{i + 1}": float(v) for i, v in enumerate(r)}
        out.append(Evaluation(x.copy(), np.array([np.sqrt(np.mean(r**2))]), np.array([g]), metrics))
    return out


def jacobian(with_pieces: bool):
    def jac(x: np.ndarray) -> DesignJacobian:
        r = x - 1.0
        f = np.sqrt(np.mean(r**2))
        pieces = np.array([x[0] - 0.5, x[1] - 0.5])
        grads = np.eye(2)
        active = grads[int(np.argmax(pieces))]
        info = {"g_pieces": {0: {"values": pieces, "gradients": grads}}} if with_pieces else {}
        return DesignJacobian(x, (r / (2 * f))[None, :], active[None, :], np.eye(2), info=info)

    return jac


def run(with_pieces: bool, **options):
    seen: list[Evaluation] = []

    def evaluate(X):
        evs = corner(X)
        seen.extend(evs)
        return evs

    cfg = HybridConfig(GAConfig("ga", 10, 2, seed=3), local="gauss_newton", **options)
    result = run_hybrid(SPACE, evaluate, 1, 1, cfg, jacobian=jacobian(with_pieces))
    n_ga = result.report["n_evaluations"]["ga"]
    return result, seen[n_ga:]


def test_pieces_find_the_corner_with_no_infeasible_trial():
    result, trials = run(True, starts=1, max_iter=60)
    assert result.best.feasible
    np.testing.assert_allclose(result.best.x, [0.5, 0.5], atol=1e-6)
    assert result.best.f[0] == pytest.approx(0.5, abs=1e-6)
    # the pieces are linear here, so their linearisation is exact: no trial breaks g
    assert trials and all(t.feasible or t.g[0] < 1e-9 for t in trials)
    # without the pieces the steps linearised on the active piece step past the other one
    _, blind = run(False, starts=1, max_iter=60)
    assert sum(not t.feasible for t in blind) > 0


def test_pieces_of_checks_what_a_problem_gives():
    x = np.array([0.2, 0.1])
    span = SPACE.upper - SPACE.lower
    jac = jacobian(True)(x)
    ((c, (values, grads)),) = pieces_of(jac, 1, span).items()
    assert c == 0
    np.testing.assert_allclose(values, [-0.3, -0.4])
    np.testing.assert_allclose(grads, np.diag(span))  # per normalised unit
    bad = DesignJacobian(
        x, jac.f, jac.g, info={"g_pieces": {0: {"values": [np.nan, 1.0], "gradients": np.eye(2)}}}
    )
    assert pieces_of(bad, 1, span) == {}
    assert pieces_of(jac, 0, span) == {}  # a row the problem does not have


def diamond(X: np.ndarray) -> list[Evaluation]:
    """r = (x - 1, y - 1) subject to |x - 0.3| + |y - 0.7| <= 0.01: a feasible set a GA of 10
    designs does not hit in its first generations. The optimum by hand: the diamond's point
    nearest (1, 1) in the RMS sense, on its edge x + y = 1.01 (x in [0.3, 0.31]): r = (x - 1,
    0.01 - x), minimised at x = 0.505 outside the edge, so at its end (0.31, 0.7), f =
    sqrt((0.69^2 + 0.3^2) / 2)."""
    out = []
    for x in np.atleast_2d(X):
        r = x - 1.0
        g = abs(x[0] - 0.3) + abs(x[1] - 0.7) - 0.01
        metrics = {f"residual_{i + 1}": float(v) for i, v in enumerate(r)}
        out.append(Evaluation(x.copy(), np.array([np.sqrt(np.mean(r**2))]), np.array([g]), metrics))
    return out


def diamond_jacobian(x: np.ndarray) -> DesignJacobian:
    r = x - 1.0
    f = np.sqrt(np.mean(r**2))
    dg = np.array([[np.sign(x[0] - 0.3), np.sign(x[1] - 0.7)]])
    return DesignJacobian(x, (r / (2 * f))[None, :], dg, np.eye(2))


def test_with_exact_derivatives_the_ga_stage_ends_at_ga_n_gen_even_if_infeasible():
    """With exact derivatives a restoring step costs one design, so the GA stage stops at
    ga_n_gen whatever its best; without, it goes on until its best is feasible."""
    cfg = HybridConfig(
        GAConfig("ga", 10, 8, seed=3), ga_n_gen=2, local="gauss_newton", starts=1, max_iter=60
    )
    exact = run_hybrid(SPACE, diamond, 1, 1, cfg, jacobian=diamond_jacobian)
    assert exact.report["ga"]["generations"] == 2
    ga_best = exact.generations[1].best
    assert not ga_best.feasible  # the GA stage ended infeasible ...
    assert exact.best.feasible  # ... and the gradient stage restored it
    # to the stop rule's 0.1 % (tolerance 1e-3)
    np.testing.assert_allclose(exact.best.x, [0.31, 0.7], atol=1e-3)
    assert exact.best.f[0] == pytest.approx(np.sqrt((0.69**2 + 0.3**2) / 2), rel=1e-3)
    fd = run_hybrid(SPACE, diamond, 1, 1, cfg)
    assert fd.report["ga"]["generations"] > 2 or fd.generations[1].best.feasible
