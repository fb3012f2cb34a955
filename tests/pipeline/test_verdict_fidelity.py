"""Issue 22 item 4: a requirement is judged on the highest-fidelity figure the run computed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.optimise.requirements import (
    BEAM,
    PLANE_STRESS,
    SOLID_3D,
    AllowableStress,
    Figure,
    Flag,
    MaxValue,
    judge_best,
    to_records,
    verdict_lines,
)
from flexopt.pipeline.problems import study_result
from flexopt.pipeline.studies._constant_force_clamp import (
    CHECKED_PEAK,
    CHECKED_PEAK_MODEL,
    REFINED_PEAK,
)
from flexopt.pipeline.study import load_study
from flexopt.pipeline.verdict import builtin_requirements, judge, quantities_of

LADDER = (
    Figure("peak_stress_MPa", "beam", BEAM),
    Figure("plane_stress_peak_stress_MPa", "plane stress", PLANE_STRESS),
    Figure("peak_stress_3d_MPa", "3D solid", SOLID_3D),
)


def test_the_highest_figure_the_design_has_is_judged_and_the_others_shown():
    req = AllowableStress("peak_stress_MPa", "peak stress", "constraint", 42.5)
    metrics = {"peak_stress_MPa": 42.24, "plane_stress_peak_stress_MPa": 43.07}
    plain = req.check(metrics)
    assert plain.met and plain.value == 42.24  # the beam alone says MET
    v = judge_best(req, metrics, None, LADDER)
    assert not v.met and v.value == 43.07 and v.model == "plane stress"
    assert v.margin == pytest.approx(42.5 - 43.07)
    assert v.figures == (
        ("plane stress", "plane_stress_peak_stress_MPa", 43.07),
        ("beam", "peak_stress_MPa", 42.24),
    )
    assert v.detail.startswith("judged on plane stress: 43.07 MPa (beam 42.24 MPa)")
    record = to_records([v])[0]
    assert record["model"] == "plane stress"
    assert record["figures"][1] == {"model": "beam", "quantity": "peak_stress_MPa", "value": 42.24}
    # the line under a MET verdict too: which model gave the judged figure
    met = judge_best(req, {"peak_stress_MPa": 40.0, "plane_stress_peak_stress_MPa": 41.0}, None,
                     LADDER)  # fmt: skip
    assert met.met and "judged on plane stress: 41 MPa (beam 40 MPa)" in verdict_lines([met])[2]
    # the 3D figure outranks both; a NaN figure is no figure
    three = {**metrics, "peak_stress_3d_MPa": 41.0}
    assert judge_best(req, three, None, LADDER).model == "3D solid"
    nan = {**metrics, "peak_stress_3d_MPa": math.nan}
    assert judge_best(req, nan, None, LADDER).model == "plane stress"


def test_a_curve_requirement_is_judged_on_the_best_curve():
    from flexopt.optimise.requirements import TargetBand, curves_from_table
    from flexopt.optimise.targets import ConstantTarget

    band = TargetBand(
        "force_N", "force band", "check", x="displacement_mm",
        target=ConstantTarget("force", 1.5), over=(1.0, 3.0), tolerance_rel=0.02,
    )  # fmt: skip
    table = {
        "displacement_mm": np.array([0.0, 1.0, 2.0, 3.0]),
        "force_N": np.array([0.0, 1.50, 1.51, 1.52]),  # within ±0.03 N
        "plane_stress_force_N": np.array([0.0, 1.49, 1.50, 1.46]),  # 0.04 N below at 3 mm
    }
    ladder = {
        "force_N": (
            Figure("force_N", "beam", BEAM),
            Figure("plane_stress_force_N", "plane stress", PLANE_STRESS),
        )
    }
    curves = curves_from_table(table, [band], ladder)
    assert band.check({}, curves).met  # the beam curve alone
    v = judge_best(band, {}, curves, ladder["force_N"])
    assert not v.met and v.model == "plane stress" and v.value == pytest.approx(0.04)
    assert v.figures[1] == ("beam", "force_N", pytest.approx(0.02))
    assert "at 3 mm the response is 1.46 N" in v.detail


def test_one_figure_is_judged_as_before_and_a_taken_figure_is_not_borrowed():
    req = MaxValue("peak_stress_MPa", "peak stress", "check", 42.5)
    only = judge_best(req, {"peak_stress_MPa": 42.24}, None, LADDER)
    assert only == req.check({"peak_stress_MPa": 42.24}) and only.model == ""
    both = {"peak_stress_MPa": 40.0, "plane_stress_peak_stress_MPa": 41.0, "peak_stress_3d_MPa": 44}
    v = judge_best(req, both, None, LADDER, taken={"peak_stress_3d_MPa", "peak_stress_MPa"})
    assert v.model == "plane stress" and v.value == 41.0  # the 3D row judges its own figure
    flag = Flag("stable", "stable", "check", True)
    ladder = (Figure("stable", "beam", BEAM), Figure("ps_stable", "plane stress", PLANE_STRESS))
    v = judge_best(flag, {"stable": True, "ps_stable": False}, None, ladder)
    assert not v.met and v.detail.startswith("judged on plane stress: no (beam yes)")


def _cf_study(**values):
    study = load_study("constant-force")
    # the design the example recorded before issue 22: 42.24 MPa in the beam model
    old = {
        "a1": 0.4964, "a2": 0.8344, "a3": 0.5213, "a4": 0.8577, "a5": 0.1939, "a6": 0.7056,
        "a7": 0.5828, "a8": 0.7814, "a9": 0.2122, "a10": 0.8727, "t1": 1.593, "t2": 0.8504,
        "t3": 0.9289, "t4": 0.8017, "t5": 0.8064, "t6": 0.8151, "t7": 0.8366, "t8": 1.044,
        "t9": 0.9178, "t10": 1.084, "T1": 1.128, "T6": 1.031, "B": 6.611,
    }  # fmt: skip
    return study.with_values({"design": old, **values})


def test_constant_force_stress_requirement_is_the_plane_stress_figure():

    study = _cf_study()
    result = study_result(study)
    check = result.diagnostics["fidelity"]
    assert all(check["converged"])
    beam_peak = float(np.max(result.table["peak_stress_MPa"]))
    # the beam's worst row is one of the plane-stress strokes
    worst = float(result.table["displacement_mm"][int(np.argmax(result.table["peak_stress_MPa"]))])
    assert worst in check["stroke_mm"]
    # the study mesh's peaks and its peak row re-solved refined (_constant_force_kinks.py)
    plane = max(*check["plane_stress_peak_nodal_von_mises_MPa"], check[REFINED_PEAK])
    assert result.summary["plane_stress_peak_stress_MPa"] == plane
    # judged: the larger of plane stress and the beam's stress at the pads (which the
    # plane-stress check leaves out), docs/constant_force.md "Stress at the clamp"
    judged = max(plane, beam_peak)
    assert result.summary[CHECKED_PEAK] == judged
    verdicts = {v.name: v for v in judge(study, result.summary, result.table)}
    v = verdicts["peak stress"]
    assert v.value == judged and v.model == CHECKED_PEAK_MODEL
    assert ("beam", "peak_stress_MPa", pytest.approx(beam_peak)) in v.figures
    # this design meets 42.5 MPa in the beam model only: the part as made does not
    assert beam_peak <= 42.5 < plane == judged and not v.met
    assert CHECKED_PEAK in quantities_of(study)
    # the force band on the plane-stress curve: the beam's scaled by the measured ratio, which
    # passes through the plane-stress forces at the checked strokes
    col = result.table["plane_stress_force_N"]
    x = result.table["displacement_mm"]
    for stroke, force in zip(check["stroke_mm"], check["plane_stress_force_N"], strict=True):
        assert col[int(np.argmin(np.abs(x - stroke)))] == pytest.approx(force, rel=1e-12)
    band = verdicts["force band"]
    inside = x >= x[1] - 1e-12
    assert band.model == "plane stress"
    assert band.value == pytest.approx(float(np.max(np.abs(col[inside] - 1.5))), rel=1e-9)
    beam_dev = float(np.max(np.abs(result.table["force_N"][inside] - 1.5)))
    assert ("beam", "force_N", pytest.approx(beam_dev, rel=1e-9)) in band.figures


def test_constant_force_run_judges_its_best_design_on_the_plane_stress_figure():
    # flexopt run's path: the best design's detail (its plane-stress check in info), judged
    import flexopt.pipeline.studies.constant_force as cf
    from flexopt.pipeline.verdict import judge_detail

    study = _cf_study()
    prob = cf.problem(study)
    detail = prob.detail(cf.design_vector(study))
    check = detail.info["fidelity"]
    plane = max(*check["plane_stress_peak_nodal_von_mises_MPa"], check[REFINED_PEAK])
    v = {v.name: v for v in judge_detail(study, detail, detail.evaluation)}["peak stress"]
    assert v.value == plane == detail.info["plane_stress_peak_stress_MPa"]
    assert v.value == detail.info[CHECKED_PEAK]  # plane stress is the larger here
    assert v.model == CHECKED_PEAK_MODEL and not v.met
    assert detail.evaluation.metrics["peak_stress_MPa"] <= 42.5  # the beam figure alone: MET


def test_constant_force_without_the_check_is_judged_on_the_beam():

    study = _cf_study(**{"fidelity.enabled": False})
    result = study_result(study)
    assert "fidelity" not in result.diagnostics
    v = {v.name: v for v in judge(study, result.summary, result.table)}["peak stress"]
    beam_peak = float(np.max(result.table["peak_stress_MPa"]))
    assert v.model == "" and v.value == pytest.approx(beam_peak)


def test_a_user_row_on_a_figure_takes_nothing_from_the_built_in_row():
    from flexopt.optimise.requirements import RequirementSpec

    study = load_study("constant-force")
    values = {"peak_stress_MPa": 40.0, "plane_stress_peak_stress_MPa": 43.0, CHECKED_PEAK: 43.0}
    mine = RequirementSpec(quantity="plane_stress_peak_stress_MPa", max=45.0).to_requirement()
    builtin = [r for r in builtin_requirements(study) if r.quantity == "peak_stress_MPa"]
    v_builtin, v_mine = judge(study, values, None, [*builtin, mine])
    assert v_builtin.model == CHECKED_PEAK_MODEL and not v_builtin.met  # 43 > 42.5
    assert v_mine.met and v_mine.value == 43.0


def test_a_verdict_with_figures_reads_back_from_its_record():
    from flexopt.optimise.requirements import Verdict

    req = AllowableStress("peak_stress_MPa", "peak stress", "constraint", 42.5)
    v = judge_best(req, {"peak_stress_MPa": 40.0, "plane_stress_peak_stress_MPa": 41.0}, None,
                   LADDER)  # fmt: skip
    record = {k: x for k, x in to_records([v])[0].items() if k != "verdict"}
    again = Verdict(**record)
    assert again == v and to_records([again]) == to_records([v])


def test_flexure_pivot_is_judged_on_its_plane_stress_check():

    study = load_study("flexure-pivot")
    result = study_result(study, 1)
    s = result.summary
    verdicts = {v.name: v for v in judge(study, s, result.table)}
    k = verdicts["stiffness band"]
    assert k.model == "plane stress" and k.value == s["plane_stress_stiffness_Nmm_per_rad"]
    assert ("beam or closed form", "stiffness_Nmm_per_rad", s["stiffness_Nmm_per_rad"]) in k.figures
    peak = verdicts["peak stress"]
    assert peak.model == "plane stress" and peak.value == s["plane_stress_peak_stress_MPa"]
    assert peak.value != s["peak_stress_MPa"]


def test_threshold_spring_2d_rows_take_plane_stress_and_leave_3d_to_their_rows():
    study = load_study("threshold-spring")
    err = [r.quantity for r in builtin_requirements(study) if r.name == "target curve error"][0]
    values = {
        err: 0.01, f"plane_stress_{err}": 0.06, f"{err}_3d": 0.02,
        "peak_stress_MPa": 38.0, "plane_stress_peak_stress_MPa": 41.0, "peak_stress_3d_MPa": 44.0,
        "ST_mm": 12.8, "ST_after_mm": 12.5, "min_feature_mm": 0.76, "peak_stress_converged": True,
    }  # fmt: skip
    v = {v.name: v for v in judge(study, values)}
    assert v["target curve error"].model == "plane stress" and not v["target curve error"].met
    assert v["3D target curve error"].value == 0.02 and v["3D target curve error"].met
    assert v["peak stress"].value == 41.0 and v["peak stress"].met
    assert v["3D peak stress ≤ allowable"].value == 44.0 and not v["3D peak stress ≤ allowable"].met
    st = v["plate thickness ST in thickness_range_mm"]
    assert st.value == 12.5 and st.model == "3D correction"  # the thickness exported
