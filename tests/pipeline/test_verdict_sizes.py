"""Issue 22 items 5 and 6: solved sizes inside their range (NOT MET with the value and the
range, never MET) and the envelope of the part as exported, in the design frame."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.pipeline.problems import study_result
from flexopt.pipeline.studies.mechanism import MechanismProblem
from flexopt.pipeline.study import load_study, validate_study
from flexopt.pipeline.verdict import judge, quantities_of
from test_mechanism_study import E_PA12, _guide


def _verdicts(raw: dict, x: float = 1.2) -> dict:
    prob = MechanismProblem(validate_study(raw))
    solved = prob.solve(np.array([x]))
    return {v.name: v for v in prob.verdicts(solved)}, solved


# ---- the mechanism's solved width


def _stiffness(k_lo: float, k_hi: float, **solve) -> dict:
    return _guide(
        requirements=[
            {"name": "stiffness", "quantity": "mean_stiffness_N_per_mm", "min": k_lo, "max": k_hi}
        ],
        solve_width_from={"requirement": "stiffness", **solve},
    )


def test_a_width_solved_below_the_printable_feature_is_not_met():
    # 2 x 12 E I / L^3 per mm of width: the width that gives k is k / that (closed form)
    k_per_mm = 2 * 12 * E_PA12 * (1.2**3 / 12) / 40.0**3
    k = 1e-9 * k_per_mm  # a target that solves the width to ~1e-9 mm
    verdicts, solved = _verdicts(_stiffness(0.99 * k, 1.01 * k))
    assert solved.width_mm == pytest.approx(1e-9, rel=2e-2)
    assert verdicts["stiffness"].met  # the force requirement alone is met exactly
    width = verdicts["solved width printable"]
    assert not width.met and width.value == solved.width_mm
    assert width.bound == ">= 0.8 mm (printable feature)"  # geometry.min_feature_mm
    ev = MechanismProblem(validate_study(_stiffness(0.99 * k, 1.01 * k))).evaluate(np.array([1.2]))
    assert ev.metrics["verdict"] == "NOT MET"
    # a reasonable target: the same row is MET
    verdicts, solved = _verdicts(_stiffness(2.85, 3.15))
    assert verdicts["solved width printable"].met and solved.width_mm > 0.8


def test_a_width_solved_outside_its_stated_range_is_not_met_with_the_range():
    k_per_mm = 2 * 12 * E_PA12 * (1.2**3 / 12) / 40.0**3
    verdicts, solved = _verdicts(_stiffness(2.85, 3.15, range_mm=[1.0, 20.0]))
    assert solved.width_mm == pytest.approx(3.0 / k_per_mm, rel=1e-2)  # ~34 mm
    v = verdicts["solved width in its range"]
    assert not v.met and v.bound == "in [1, 20] mm" and v.detail == "above it"
    assert v.value == solved.width_mm
    verdicts, _ = _verdicts(_stiffness(2.85, 3.15, range_mm=[1.0, 50.0]))
    assert verdicts["solved width in its range"].met


def test_width_range_is_checked_when_loaded():
    from flexopt.pipeline.errors import StudyError

    with pytest.raises(StudyError) as err:
        validate_study(_stiffness(2.85, 3.15, range_mm=[5.0, 1.0]))
    assert "range_mm" in err.value.path + err.value.problem


# ---- the envelope of the part as exported


def test_envelope_of_a_mechanism_is_measured_on_the_exported_part():
    raw = _guide(
        requirements=[
            {"name": "fits", "envelope_mm": [60, 40]},
            {"name": "too low", "envelope_mm": [60, 20]},
            {"name": "too thin", "envelope_mm": [60, 40, 5]},
            {"name": "width", "quantity": "envelope_width_mm", "max": 60},
        ]
    )
    verdicts, solved = _verdicts(raw)
    # the part: pads 6 mm beyond the grounded ends (x = 0), the shuttle to x = 48, y +-13;
    # the extrusion is the 6 mm width
    x0, y0, x1, y1 = solved.outline.polygon.bounds
    assert (x0, x1, y0, y1) == pytest.approx((-6.0, 48.0, -13.0, 13.0))
    assert verdicts["fits"].met and verdicts["fits"].detail == "54 × 26 mm"
    low = verdicts["too low"]
    assert not low.met and low.value == pytest.approx(26.0) and low.margin == pytest.approx(-6.0)
    thin = verdicts["too thin"]
    assert not thin.met and thin.detail == "54 × 26 × 6 mm"
    assert verdicts["width"].met and verdicts["width"].value == pytest.approx(54.0)


def test_envelope_of_another_kind_from_flexopt_evaluate():
    import flexopt.pipeline.studies.constant_force as cf

    study = load_study("constant-force").with_values({"fidelity.enabled": False})
    assert "envelope_depth_mm" in quantities_of(study)
    result = study_result(study)
    design = cf.design_vector(study)
    prob = cf.ConstantForceProblem(study)
    shape = cf.outline(
        prob._design(design), prob.frame,
        study.geometry.pad_length_mm, study.geometry.pad_thickness_mm, study.geometry.end_flexures,
    )  # fmt: skip
    x0, y0, x1, y1 = shape.bounds
    assert result.summary["envelope_width_mm"] == pytest.approx(x1 - x0)
    assert result.summary["envelope_height_mm"] == pytest.approx(y1 - y0)
    assert result.summary["envelope_depth_mm"] == pytest.approx(study.design["B"])
    from flexopt.optimise.requirements import RequirementSpec

    w, h = x1 - x0, y1 - y0
    fits = RequirementSpec(envelope_mm=[w + 1, h + 1, 10]).to_requirement()
    tight = RequirementSpec(envelope_mm=[w + 1, h - 1]).to_requirement()
    v_fit, v_tight = judge(study, result.summary, result.table, [fits, tight])
    assert v_fit.met and not v_tight.met and v_tight.margin == pytest.approx(-1.0)


# ---- solved plate thicknesses of the springs


@pytest.mark.parametrize(("torque_Nm", "detail"), [(1e-4, "below the range"), (1e4, "above it")])
def test_threshold_spring_solved_st_outside_its_range_is_not_met(torque_Nm, detail):
    from flexopt.pipeline.studies import threshold_spring as ts

    base = load_study("threshold-spring").with_values({"solid_3d.check": False})
    study = base.with_values({"target.max_torque_Nm": torque_Nm})
    prob = ts.problem(study)
    x = prob.space.clip(ts.design_vector(study))
    ev, nominal = prob.evaluate(x), ts.problem(base).evaluate(x)
    # torque is linear in ST (plane stress): ST scales with the target torque
    assert ev.metrics["ST_mm"] == pytest.approx(nominal.metrics["ST_mm"] * torque_Nm / 1.5)
    verdicts = {v.name: v for v in judge(study, ev.metrics)}
    st = verdicts["plate thickness ST in thickness_range_mm"]
    assert not st.met and st.value == ev.metrics["ST_mm"] and st.bound == "in [2, 20] mm"
    assert st.detail == detail
    feature = verdicts["printable feature"]
    assert feature.met == (torque_Nm > 1)  # a 0.9 µm plate is thinner than 0.5 mm
    assert verdicts["target curve error"].met  # the curve's shape alone would say MET
    nominal_verdicts = {v.name: v for v in judge(base, nominal.metrics)}
    assert nominal_verdicts["plate thickness ST in thickness_range_mm"].met


def test_sea_spring_st_range_is_judged_on_the_exported_st():
    from flexopt.pipeline.verdict import study_requirements

    study = load_study("sea-spring")
    req = [r for r in study_requirements(study) if r.quantity == "ST_mm"]
    assert [r.label for r in req] == ["plate thickness ST in its range"]
    lo, hi = req[0].minimum, req[0].maximum
    (ok,) = judge(study, {"ST_mm": 0.5 * (lo + hi)}, None, req)
    (thin,) = judge(study, {"ST_mm": 1e-3}, None, req)
    assert ok.met and not thin.met and thin.value == 1e-3
    # the 3D correction's ST is the part made: judged on it, the plane-stress fit beside it
    (made,) = judge(study, {"ST_mm": 0.5 * (lo + hi), "ST_3d_mm": hi + 1.0}, None, req)
    assert not made.met and made.value == hi + 1.0 and made.model == "3D correction"
    # the thinnest printed size (member or plate) is a built-in requirement too
    (feature,) = [r for r in study_requirements(study) if r.quantity == "min_feature_mm"]
    (thin,) = judge(study, {"min_feature_mm": 0.3}, None, [feature])
    assert (
        not thin.met
        and thin.bound == f">= {study.geometry.min_feature_mm:g} mm (printable feature)"
    )


def test_envelope_of_a_cam_plate_from_flexopt_evaluate():
    import flexopt.pipeline.studies.cam as cam

    study = load_study("threshold-cam")
    result = study_result(study)
    *_, profile, _ = cam.build_cam(study)
    x0, y0, x1, y1 = cam.cam_outline(profile).bounds
    s = result.summary
    assert (s["envelope_width_mm"], s["envelope_height_mm"]) == pytest.approx((x1 - x0, y1 - y0))
    assert s["envelope_depth_mm"] == study.geometry.thickness_mm
    from flexopt.optimise.requirements import RequirementSpec

    reqs = [RequirementSpec(envelope_mm=[x1 - x0 + 1, y1 - y0 - 1]).to_requirement()]
    (v,) = judge(study, s, result.table, reqs)
    assert not v.met and v.margin == pytest.approx(-1.0)
