"""ConstantForceProblem.check_constraints (the hybrid's calibration, issue 27): the verdict's own
peak-stress figure at a design, the stress row's factor, deterministic in the design."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from flexopt.pipeline.run import prepare_run
from flexopt.pipeline.studies._constant_force_clamp import CHECKED_PEAK
from flexopt.pipeline.study import load_study

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def problem():
    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    return prepare_run(study).problem


def test_the_check_is_the_verdicts_figure_and_the_rows_factor(problem):
    x = problem.nominal_design()
    check = problem.check_constraints(x)
    # what flexopt evaluate judges (its own fidelity check of the same design)
    summary = problem.result(x).summary
    judged = summary[CHECKED_PEAK]
    assert check.info[CHECKED_PEAK] == pytest.approx(judged, rel=1e-12)
    # the row's figure: (g + 1) x allowable of the evaluation the optimiser sees
    g = problem.evaluate(x).g[0]
    row = (g + 1.0) * problem.allowable_MPa
    assert check.info["beam_row_stress_MPa"] == pytest.approx(row, rel=1e-12)
    assert check.factors == {0: pytest.approx(judged / row, rel=1e-12)}
    assert check.met == (judged <= problem.allowable_MPa)
    # a deterministic function of the design: a resumed run makes the same check
    again = problem.check_constraints(np.array(x))
    assert again.factors == check.factors and again.info == check.info


def test_no_check_without_the_fidelity_check(problem):
    study = problem.study.model_copy(
        update={"fidelity": problem.study.fidelity.model_copy(update={"enabled": False})}
    )
    other = prepare_run(study).problem
    assert other.check_constraints(other.nominal_design()) is None
