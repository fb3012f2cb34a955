"""One result per design: ``flexopt evaluate`` (and the API) of a kind with a design problem and
no ``evaluate`` is the nominal design's :meth:`DesignProblem.result`, judged once
(:func:`pipeline.verdict.judge_result`); a plugin's problem that only has the protocol's parts
(no base class, no hooks) still runs that way."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import flexopt
import numpy as np
import pytest
from flexopt.optimise import DesignDetail, DesignProblem, DesignSpace, Evaluation
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.evaluate import solve_study
from flexopt.pipeline.problems import build_base_problem, kind_problem, study_result
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, Study, validate_study
from flexopt.pipeline.verdict import judge_result
from pydantic import BaseModel


class ResultGeometry(BaseModel):
    model_config = STUDY_CONFIG

    kind: Literal["toy_result_plain", "toy_result_sub"]
    t_mm: float | None = None  # the design the study describes (None: none)


class ResultStudy(Study):
    geometry: ResultGeometry


@dataclass
class PlainProblem:
    """A plugin's problem: the protocol's parts only."""

    space: DesignSpace = field(
        default_factory=lambda: DesignSpace(("t_mm",), np.array([0.5]), np.array([3.0]))
    )
    objective_names: tuple[str, ...] = ("peak_stress_MPa",)
    constraint_names: tuple[str, ...] = ()

    def evaluate(self, x: np.ndarray) -> Evaluation:
        stress = 10.0 / float(x[0])
        return Evaluation(np.asarray(x), np.array([stress]), np.zeros(0), {"stress_MPa": stress})

    def detail(self, x: np.ndarray) -> DesignDetail:
        d = np.linspace(0.0, 1.0, 3)
        table = {"displacement_mm": d, "force_N": float(x[0]) * d}
        return DesignDetail(self.evaluate(x), table, {"x": "displacement_mm", "y": "force_N"})


class SubProblem(PlainProblem, DesignProblem):
    """The same problem as a subclass: the base class's result() and hooks."""


register(
    StudyKind(
        "toy_result_plain",
        ResultStudy,
        check=lambda study: None,
        problem=lambda study: PlainProblem(),  # type: ignore[arg-type]
    )
)
register(
    StudyKind(
        "toy_result_sub",
        ResultStudy,
        check=lambda study: None,
        problem=lambda study: SubProblem(),  # type: ignore[arg-type]
    )
)


def _study(kind: str, **geometry: float) -> Study:
    return validate_study({"name": "r", "geometry": {"kind": kind, **geometry}, "material": "PLA"})


@pytest.mark.parametrize("kind", ["toy_result_plain", "toy_result_sub"])
def test_evaluate_of_a_problem_kind_is_its_nominal_designs_result(kind):
    study = _study(kind, t_mm=2.0)
    assert isinstance(kind_problem(study), DesignProblem)  # the plain one adapted
    assert isinstance(build_base_problem(study), DesignProblem)
    result = study_result(study, repeat=2)
    assert result.summary["stress_MPa"] == pytest.approx(5.0) and result.converged
    assert len(result.solve_times_s) == 2
    np.testing.assert_allclose(result.table["force_N"], [0.0, 1.0, 2.0])
    judged = solve_study(study)
    assert judged.verdicts == judge_result(study, result)
    api = flexopt.evaluate(study)  # the API takes the same path
    assert api.summary["stress_MPa"] == pytest.approx(5.0)


def test_a_problem_kind_whose_study_names_no_design_is_only_optimised():
    with pytest.raises(StudyError, match="only optimised.*flexopt run"):
        solve_study(_study("toy_result_plain"))
