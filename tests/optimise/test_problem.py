"""DesignProblem as a base class with documented hooks; a plugin's protocol-only problem runs
through :func:`optimise.problem.as_design_problem`; one DesignResult."""

from __future__ import annotations

import pickle
from dataclasses import replace

import numpy as np
import pytest
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import (
    DesignDetail,
    DesignProblem,
    DesignResult,
    ProblemWrapper,
    as_design_problem,
)
from flexopt.optimise.space import DesignSpace

SPACE = DesignSpace(("t_mm", "w_mm"), np.array([0.5, 2.0]), np.array([2.0, 8.0]))


class Plain:
    """A plugin's problem: the protocol's parts only, no base class, no hooks."""

    space = SPACE
    objective_names = ("f",)
    constraint_names = ()

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return Evaluation(np.asarray(x), np.array([float(np.sum(x))]), np.zeros(0), {"m": 1.0})

    def detail(self, x: np.ndarray) -> DesignResult:
        return DesignResult(self.evaluate(x), {"d_mm": np.arange(3.0)})


class WithHooks(Plain):
    """A plugin's problem with some hooks of its own (still no base class)."""

    variable_meanings = {"t_mm": "thickness (mm)"}
    held_scatter = {"ST": "width"}

    def nominal_design(self) -> np.ndarray:
        return np.array([1.0, 3.0])

    def initial_designs(self) -> np.ndarray:
        return np.array([[1.0, 4.0]])

    def held_state(self, evaluation: Evaluation) -> dict[str, float]:
        return {"ST_mm": 2.0}


class Sub(DesignProblem):
    space = SPACE
    objective_names = ("f",)
    constraint_names = ()

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return Plain().evaluate(x)


def test_a_subclass_has_every_hook_with_its_default():
    p = Sub()
    assert as_design_problem(p) is p
    assert p.nominal_design() is None and p.initial_designs() is None
    assert p.scatter_design(np.ones(2), 0.1, 0.2) is None
    assert p.held_state(p.evaluate(np.ones(2))) == {} and not p.held_scatter
    assert p.hold_solved({}, 0.1, 0.2) is None and p.study_values(np.ones(2)) is None
    assert p.study is None and p.variables is None and p.variable_meanings is None
    p.warm_up_detail()
    with pytest.raises(NotImplementedError):
        p.detail(np.ones(2))


def test_a_protocol_only_problem_is_adapted_with_the_defaults():
    p = as_design_problem(Plain())
    assert isinstance(p, DesignProblem) and p.space is SPACE
    assert p.objective_names == ("f",) and p.constraint_names == ()
    assert p.nominal_design() is None and p.initial_designs() is None
    assert p.scatter_design(np.ones(2), 0.1, 0.2) is None and not p.held_scatter
    assert p.evaluate(np.ones(2)).f[0] == 2.0
    assert list(p.detail(np.ones(2)).table) == ["d_mm"]
    back = pickle.loads(pickle.dumps(p))  # sent to worker processes
    assert back.evaluate(np.ones(2)).f[0] == 2.0


def test_a_protocol_only_problem_keeps_the_hooks_it_has():
    p = as_design_problem(WithHooks())
    np.testing.assert_array_equal(p.nominal_design(), [1.0, 3.0])
    np.testing.assert_array_equal(p.initial_designs(), [[1.0, 4.0]])
    assert p.variable_meanings == {"t_mm": "thickness (mm)"}
    assert dict(p.held_scatter) == {"ST": "width"}
    assert p.held_state(p.evaluate(np.ones(2))) == {"ST_mm": 2.0}
    assert p.study_values(np.ones(2)) is None  # the one it lacks: the default


def test_what_is_not_a_problem_is_refused():
    with pytest.raises(TypeError, match="evaluate, detail"):
        as_design_problem(object())


def test_a_wrapper_forwards_every_hook_to_its_inner_problem():
    inner = as_design_problem(WithHooks())
    w = ProblemWrapper(inner)
    np.testing.assert_array_equal(w.nominal_design(), [1.0, 3.0])
    assert w.variable_meanings == inner.variable_meanings and w.held_scatter == inner.held_scatter
    assert w.held_state(w.evaluate(np.ones(2))) == {"ST_mm": 2.0}
    assert pickle.loads(pickle.dumps(w)).evaluate(np.ones(2)).f[0] == 2.0


def test_one_result_type_for_a_detail_and_an_evaluation():
    ev = Plain().evaluate(np.ones(2))
    detail = DesignDetail(ev, {"d_mm": np.arange(2.0)}, {"x": "d_mm"}, info={"a": 1.0})
    assert type(detail) is DesignResult and detail.converged and detail.summary == {}
    assert detail.values() == {"a": 1.0, "m": 1.0}
    result = replace(detail, summary={"m": 2.0})
    assert result.values()["m"] == 2.0  # the summary wins
