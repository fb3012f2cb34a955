"""The best design's sensitivities in the report (pipeline/sensitivity_report.py): the numbers
of report.md's table and report.html's bar chart against central differences of the objective
computed here."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from flexopt.optimise import DesignProblem, DesignSpace, Evaluation
from flexopt.pipeline.figure_json import dumps
from flexopt.pipeline.sensitivity_report import (
    FD_STEP,
    design_sensitivity,
    sensitivity_html,
    sensitivity_markdown,
)
from test_constant_force_gradient import TightProblem, _fd, _step
from test_constant_force_gradient import problem as problem  # noqa: F401  (the fixture)


def _table_numbers(lines: list[str]) -> dict[str, tuple[float, float]]:
    """{variable: (d f / d x, x range)} from report.md's table (one objective)."""
    out = {}
    for line in lines:
        m = re.match(r"\| `([^`]+)` \| (\S+) \| (\S+) \|$", line)
        if m:
            out[m.group(1)] = (float(m.group(2)), float(m.group(3)))
    return out


def test_constant_force_chart_is_the_objective_s_central_difference(problem):  # noqa: F811
    """The exact normalised gradient of rms_error_N equals the central difference of the
    study's evaluate (x the range), for every variable; report.md's table and report.html's
    bars carry those numbers."""
    assert isinstance(problem, TightProblem)
    x = problem.nominal_design()
    best = problem.evaluate(x)
    s = design_sensitivity(problem, best)
    assert not isinstance(s, str) and s.method == "exact" and s.evaluations == 0
    span = problem.space.upper - problem.space.lower
    fd = np.zeros(23)
    for k in range(23):

        def f(step, k=k):
            v = x.copy()
            v[k] += step
            return problem.evaluate(v).f[0]

        # the RMS (0.006 N) is curved on its own scale (see test_constant_force_gradient): a
        # step 1/100 of the residuals' (at 1/30, B's difference was 5e-5 off: F ~ B, so each
        # residual moves 5e-4 N per step, 8 % of the RMS)
        fd[k] = _fd(f, _step(problem, k) / 100)
    np.testing.assert_allclose(
        s.normalised[0], fd * span, rtol=0, atol=1e-5 * np.abs(fd * span).max()
    )

    table = _table_numbers(sensitivity_markdown(problem, best))
    assert len(table) == 23
    for k, name in enumerate(problem.space.names):
        assert table[name][1] == pytest.approx(fd[k] * span[k], rel=1e-5, abs=1e-7)
    figures = []

    def embed(fig, name):
        figures.append(json.loads(dumps(fig.to_plotly_json())))
        return f"<div id='plot-{name}'></div>"

    html = sensitivity_html(problem, best, embed)
    assert "plot-gradient" in html and "exact derivatives" in html
    (bar,) = figures[0]["data"]
    bars = dict(zip(bar["x"], bar["y"], strict=True))
    for k, name in enumerate(problem.space.names):
        assert bars[name] == pytest.approx(fd[k] * span[k], rel=1e-5, abs=1e-7)
    # largest first
    assert np.all(np.diff(np.abs(bar["y"])) <= 0)


class Bowl(DesignProblem):
    """f = (a - 0.2)^2 + 3 (b - 0.5) b + c over [0, 1] x [0, 2] x [-1, 1]: no Jacobian hook."""

    space = DesignSpace(("a", "b", "c"), np.array([0.0, 0.0, -1.0]), np.array([1.0, 2.0, 1.0]))
    objective_names = ("f",)
    constraint_names = ()

    def evaluate(self, x):
        a, b, c = x
        f = (a - 0.2) ** 2 + 3.0 * (b - 0.5) * b + c
        return Evaluation(np.array(x, dtype=float), np.array([f]), np.zeros(0), time_s=0.001)

    def detail(self, x):
        raise NotImplementedError


def test_without_a_jacobian_the_report_says_why():
    best = Bowl().evaluate(np.array([0.7, 1.0, 0.0]))
    (text,) = [line for line in sensitivity_markdown(Bowl(), best) if line.startswith("Not")]
    assert "no exact derivatives" in text and "6 designs" in text


def test_central_differences_when_asked_and_cheap():
    """Central differences of a quadratic are exact: (2 (a - 0.2), 6 b - 1.5, 1) x range; at a
    bound the difference is one-sided (b = 2: O(h) off, 3 h)."""
    x = np.array([0.7, 1.0, 0.0])
    s = design_sensitivity(Bowl(), Bowl().evaluate(x), central_differences=True)
    assert s.method == "central differences" and s.evaluations == 6
    np.testing.assert_allclose(s.gradient[0], [1.0, 4.5, 1.0], rtol=1e-9)
    np.testing.assert_allclose(s.normalised[0], [1.0, 9.0, 2.0], rtol=1e-9)
    at_bound = design_sensitivity(
        Bowl(), Bowl().evaluate(np.array([0.7, 2.0, 0.0])), central_differences=True
    )
    h = FD_STEP * 2.0
    assert at_bound.gradient[0, 1] == pytest.approx(6 * 2.0 - 1.5 - 3.0 * h, rel=1e-9)
    slow = Evaluation(x, np.array([0.0]), np.zeros(0), time_s=1.0)
    assert "cost more" in design_sensitivity(Bowl(), slow, central_differences=True)


class ExactBowl(Bowl):
    """Bowl with its exact gradient as a Jacobian hook, counting the calls."""

    def __init__(self):
        self.calls = 0

    def jacobian(self, x):
        from flexopt.optimise.design_jacobian import DesignJacobian

        self.calls += 1
        a, b, _ = x
        return DesignJacobian(
            np.array(x), np.array([[2 * (a - 0.2), 6 * b - 1.5, 1.0]]), np.zeros((0, 3))
        )


def test_a_jacobian_the_run_took_at_the_best_is_not_taken_again():
    """The hybrid's Jacobian at its best (HybridResult.jacobian, kept by the runner with
    known_jacobian) is the report's: the hook is not called again at that design; at another
    design, or for another problem, it is."""
    from flexopt.pipeline import sensitivity_report

    bowl, other = ExactBowl(), ExactBowl()
    x = np.array([0.7, 1.0, 0.0])
    sensitivity_report.known_jacobian(bowl, bowl.jacobian(x))
    assert bowl.calls == 1
    s = design_sensitivity(bowl, bowl.evaluate(x))
    assert bowl.calls == 1 and s.method == "exact"
    np.testing.assert_allclose(
        s.gradient[0], [1.0, 4.5, 1.0], rtol=1e-15
    )  # 2 (a - 0.2), 6 b - 1.5, 1
    design_sensitivity(bowl, bowl.evaluate(np.array([0.5, 1.0, 0.0])))
    assert bowl.calls == 2
    design_sensitivity(other, other.evaluate(x))
    assert other.calls == 1
