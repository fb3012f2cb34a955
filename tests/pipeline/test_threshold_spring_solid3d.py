"""The threshold_spring kind's 3D check (issue 15 item 1): the chosen design as a solid beside
plane stress, its 3D curve error and peak in the detail and the verdict. The shipped example's
design on a coarse plane mesh with one prism layer keeps it quick."""

from __future__ import annotations

import math

import flexopt.pipeline.studies.threshold_spring as ts
import numpy as np
import pytest
from flexopt.optimise.targets import curve_error
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.study import load_study, validate_study
from flexopt.pipeline.verdict import judge_detail


def _study(**solid_3d):
    raw = load_study("threshold-spring").model_dump(mode="json", exclude_none=True)
    # coarse: the check's arithmetic, not its accuracy, is under test (seconds, not minutes)
    raw["fidelity"] = {"max_edge_mm": 6.0, "elements_through": 0.5, "fillet_segments": 1,
                       "steps": 2}  # fmt: skip
    raw["solid_3d"] = {"layers": 1, **solid_3d}
    return validate_study(raw)


def test_solid_3d_is_reported_beside_plane_stress_and_judged():
    study = _study()
    prob = ts.problem(study)
    d = prob.detail(prob.space.clip(ts.design_vector(study)))
    ps, s3 = d.info["plane_stress"], d.info["solid_3d"]
    assert "problem" not in s3, s3
    assert s3["ST_mm"] == pytest.approx(d.evaluation.metrics["ST_mm"]) == pytest.approx(d.height_mm)
    ratio = s3["stiffness_ratio_3d_2d"]
    assert ratio > 1.0  # nu = 0.39: restrained lateral contraction makes the solid stiffer
    assert s3["linear_stiffness_3d_Nm_per_rad"] == pytest.approx(
        ratio * s3["linear_stiffness_2d_Nm_per_rad"], rel=1e-12
    )
    # the 3D curve is the plane-stress curve times the ratio, its error measured the same way
    name = prob.error_name
    t3 = np.asarray(s3["torque_3d_Nm"])
    assert t3 == pytest.approx(ratio * np.asarray(ps["torque_Nm"]), rel=1e-12)
    rad = np.radians(ps["rotation_deg"])
    expect = curve_error(prob.curve, rad, t3 * 1e3, prob.measure, prob.window)
    assert s3[f"{name}_3d"] == pytest.approx(expect, rel=1e-12)
    assert s3[f"{name}_3d"] != pytest.approx(ps[name], rel=1e-6)
    assert s3["peak_stress_3d_MPa"] == pytest.approx(
        s3["peak_stress_ratio_3d_2d"] * ps["peak_stress_max_MPa"], rel=1e-12
    )
    # the ST that fits the 3D curve: its error is the 3D curve scaled to it, no worse than at ST
    st_fit, at_fit = s3["ST_fit_3d_mm"], s3[f"{name}_3d_at_ST_fit"]
    scaled = curve_error(prob.curve, rad, t3 * 1e3 * st_fit / s3["ST_mm"], prob.measure,
                         prob.window)  # fmt: skip
    assert at_fit == pytest.approx(scaled, rel=1e-9) and at_fit <= s3[f"{name}_3d"] + 1e-12
    assert st_fit < s3["ST_mm"]  # a stiffer solid needs a thinner plate
    # the verdict rows read the detail's info (best.json) and judge the 3D answers
    verdicts = {v.name: v for v in judge_detail(study, d, d.evaluation)}
    err = verdicts["3D target curve error"]
    assert err.value == pytest.approx(s3[f"{name}_3d"])
    assert err.met == (s3[f"{name}_3d"] <= study.tolerance)
    peak = verdicts["3D peak stress ≤ allowable"]
    assert peak.value == pytest.approx(s3["peak_stress_3d_MPa"])
    assert math.isfinite(s3["time_s"]) and s3["dofs"] > 0


def test_check_off_leaves_no_3d_answers_or_rows():
    study = _study(check=False)
    prob = ts.problem(study)
    d = prob.detail(prob.space.clip(ts.design_vector(study)))
    assert "solid_3d" not in d.info and "peak_stress_3d_MPa" not in d.info
    names = {v.name for v in judge_detail(study, d, d.evaluation)}
    assert "3D target curve error" not in names and "3D peak stress ≤ allowable" not in names


def test_sea_spring_keys_are_refused_for_the_threshold_spring():
    # no thickness correction here (reported only): the key is refused, not silently ignored
    with pytest.raises(StudyError, match="solid_3d.correct"):
        _study(correct=True)
