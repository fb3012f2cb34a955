"""Issue 22 item 5: every design variable a study gives (``design:``, a variable's ``initial:``)
or the optimiser moves is inside its stated range, as a requirement of every kind with a design
space: a design outside is NOT MET with the variable, its value and its range, never MET and
never clipped into the space unsaid."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.optimise.requirements import DesignRange
from flexopt.pipeline.study import load_study, validate_study
from flexopt.pipeline.verdict import (
    design_range_verdicts,
    judge,
    judge_detail,
    study_requirements,
)

ROW = "design variables in their ranges"


def _row(verdicts) -> object:
    (row,) = [v for v in verdicts if v.name == ROW]
    return row


# ---- the requirement itself


def test_design_range_names_the_variable_furthest_outside_with_its_value_and_range():
    req = DesignRange(name=ROW, names=("a_mm", "b_deg", "c"), lower=(1, 0, 0), upper=(3, 90, 1))
    inside = req.check(req.values([2.9, 45.0, 0.5]))
    # every variable inside: the one with the least spare as a fraction of its range (a_mm,
    # 0.1 of 2 mm = 5 %; b_deg 50 %; c 50 %)
    assert inside.met and inside.value == 2.9 and inside.bound == "a_mm in [1, 3] mm"
    assert inside.margin == pytest.approx(0.1) and inside.margin_rel == pytest.approx(0.05)
    # b_deg 9 deg over 90 (10 % of its range) is further out than a_mm 0.1 mm over 3 (5 %)
    out = req.check(req.values([3.1, 99.0, 0.5]))
    assert not out.met and out.value == 99.0 and out.unit == "deg"
    assert out.bound == "b_deg in [0, 90] deg" and out.margin == pytest.approx(-9.0)
    assert "b_deg = 99 deg is above its range [0, 90] deg" in out.detail
    assert "2 of 3 variables outside: a_mm, b_deg" in out.detail
    below = req.check(req.values([2.0, 45.0, -0.2]))
    assert not below.met and "c = -0.2 is below its range [0, 1]" in below.detail
    # a design the row cannot read is NOT MET, said
    assert not req.check({}).met and not math.isfinite(req.check({}).value)
    with pytest.raises(Exception, match="2 values"):
        req.values([1.0, 2.0])


# ---- constant_force: design: outside design_space


def test_constant_force_design_outside_its_space_is_not_met_when_evaluated():
    from flexopt.pipeline.evaluate import solve_study

    base = load_study("constant-force").with_values({"fidelity.enabled": False})
    (nominal,) = design_range_verdicts(base)
    assert nominal.met  # the shipped design is inside its design space
    study = base.with_values({"design.B": 30.0})  # design_space B: [4, 12]
    result = solve_study(study)
    row = _row(result.verdicts)
    assert not row.met and row.value == 30.0
    assert row.bound == "B_mm in [4, 12] mm" and row.margin == pytest.approx(-18.0)
    assert "above its range [4, 12] mm (design_space)" in row.detail
    # the part was solved as given (30 mm deep), so every other row is the 30 mm part's
    assert result.summary["envelope_depth_mm"] == 30.0
    assert not all(v.met for v in result.verdicts)


# ---- threshold_spring: no clipping of design:


def test_threshold_spring_evaluates_its_design_as_given_and_says_not_met():
    from flexopt.pipeline.evaluate import solve_study

    base = load_study("threshold-spring").with_values(
        {"fidelity.enabled": False, "solid_3d.check": False, "beam": {"elements": 12, "rows": 12}}
    )
    assert _row(judge(base, {}, None)).met  # the shipped design: inside the defaults
    sweep = base.design["sweep_deg"]  # 40.04 deg
    study = base.with_values({"design_space": {"sweep_deg": [50.0, 120.0]}})
    result = solve_study(study)
    # solved at the sweep given, not at 50 deg (the space's nearest point)
    assert result.inputs["design"]["sweep_deg"] == sweep
    row = _row(result.verdicts)
    assert not row.met and row.value == sweep and row.bound == "sweep_deg in [50, 120] deg"
    assert row.margin == pytest.approx(sweep - 50.0) and "below its range" in row.detail


# ---- sea_spring: the design space of the problem (ST solved: left out)


def test_sea_spring_design_outside_its_space_is_not_met_and_not_clipped():
    from flexopt.pipeline.studies.sea_spring import SeaSpringProblem, design_vector

    base = load_study("sea-spring-quick")
    assert _row(judge(base, {}, None)).met
    study = base.with_values({"design_space": {"sweep": [150.0, 470.0]}})  # design 479.84
    prob = SeaSpringProblem(study, stage1={})
    x = prob.nominal_design()  # what evaluate solves and export rebuilds: as given
    assert "ST" not in prob.space.names and x.shape == (prob.space.n_var,)
    assert x[prob.space.names.index("sweep_deg")] == study.design["sweep"]
    assert np.array_equal(x, np.delete(design_vector(study), prob.names.index("ST")))
    row = _row(judge(study, {}, None))
    assert not row.met and row.value == study.design["sweep"]
    assert row.bound == "sweep_deg in [150, 470] deg" and "above its range" in row.detail
    # a run's design (the problem's space) is judged by judge_detail on its own vector
    from flexopt.optimise.evaluation import Evaluation

    inside = prob.space.clip(x)
    ev = Evaluation(inside, np.zeros(2), np.zeros(len(prob.constraint_names)), {})
    assert _row(judge_detail(study, None, ev)).met


# ---- mechanism: the variables' bounds


def _guide_study(initial: float | None = None):
    from test_mechanism_study import _guide

    raw = _guide()
    if initial is not None:
        raw["variables"][0]["initial"] = initial
    return validate_study(raw)


@pytest.mark.e2e
def test_mechanism_variables_in_their_bounds_evaluated_and_run():
    from flexopt.pipeline.errors import StudyError
    from flexopt.pipeline.problems import study_result
    from flexopt.pipeline.studies.mechanism import MechanismProblem

    study = _guide_study(1.2)
    result = study_result(study)  # flexopt evaluate's result: the nominal design's
    row = _row(result.verdicts)
    assert row.met and row.value == 1.2 and row.bound == "beams.upper.thickness_mm in [0.8, 2] mm"
    assert result.summary["verdict"] == (
        "MET" if all(v.met for v in result.verdicts) else "NOT MET"
    )
    # an initial design outside the bounds is refused at load in one line, key and fix
    # (resolve_variables; robustness samples past a bound rely on it, docs/robustness.md)
    with pytest.raises(StudyError) as err:
        _guide_study(2.4)
    assert err.value.path == "variables[0].initial" and "[0.8, 2]" in err.value.problem
    # a design outside the bounds reaching the verdict (an API caller's detail) is NOT MET
    prob = MechanismProblem(study)
    detail = prob.detail(np.array([2.4]))
    row = _row(judge_detail(study, detail, detail.evaluation))
    assert not row.met and row.value == 2.4 and row.margin == pytest.approx(-0.4)
    assert "above its range [0.8, 2] mm (variables[i].bounds)" in row.detail


# ---- robustness samples: a part as made, not a design choice


def test_a_sample_judged_on_given_requirements_has_no_range_row():
    study = load_study("constant-force").with_values({"design.B": 30.0})
    reqs = study_requirements(study)
    assert all(r.quantity != DesignRange.quantity for r in reqs)
    # pipeline.robustness judges a sample so: the sample's thickness 0.1 mm under a bound is
    # the print's scatter, judged by the other rows, not a design outside its range
    assert all(v.name != ROW for v in judge(study, {}, None, reqs))
    assert not _row(judge(study, {}, None)).met  # the nominal design's verdict has it


# ---- the other kinds with a design space


@pytest.mark.parametrize(
    ("example", "changes", "bound", "value"),
    [
        ("threshold-cam", {"springs.stiffness_N_per_mm": 12.0},
         "stiffness_N_per_mm in [1, 10] N/mm", 12.0),
        ("flexure-pivot", {"design.length_mm": 40.0}, "length_mm in [2, 30] mm", 40.0),
    ],
)  # fmt: skip
def test_other_kinds_judge_their_design_in_its_space(example, changes, bound, value):
    base = load_study(example)
    (nominal,) = design_range_verdicts(base)
    assert nominal.met
    (row,) = design_range_verdicts(base.with_values(changes))
    assert not row.met and row.bound == bound and row.value == value
    assert "its range" in row.detail and "widen" in row.detail


def test_a_robustness_sample_under_a_bound_is_judged_without_the_range_row():
    from flexopt.pipeline.problems import build_base_problem, nominal_design
    from flexopt.pipeline.robustness import SampleProblem

    study = load_study("constant-force-robust")
    x = nominal_design(build_base_problem(study), study)
    i = build_base_problem(study).space.names.index("t4_mm")
    assert x[i] == pytest.approx(0.802)  # 2 um above its lower bound, 0.8 mm
    # the sample printed 0.1 mm thin: t4 = 0.702 mm, under the bound, as made
    ev = SampleProblem(study, "design", x).evaluate(np.array([1.0, -0.1, 0.0]))
    verdicts = ev.metrics["robustness"].verdicts
    assert verdicts and all(v.quantity != DesignRange.quantity for v in verdicts)
    assert ev.f[0] == sum(not v.met for v in verdicts)
    (nominal,) = design_range_verdicts(study, x)  # the nominal design's own row: MET
    assert nominal.met and nominal.bound == "t4_mm in [0.8, 1.6] mm"
