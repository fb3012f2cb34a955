"""Requirements and verdicts: a design just inside and just outside each bound."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from flexopt.optimise.requirements import (
    AllowableStress,
    Envelope,
    Flag,
    MaxValue,
    MinFeature,
    MinValue,
    Range,
    RequirementSpec,
    TargetBand,
    curves_from_table,
    overall,
    to_records,
    unit_of,
    verdict_lines,
    verdict_record,
)
from flexopt.optimise.targets import ConstantTarget, LinearTarget
from pydantic import ValidationError

EPS = 1e-3


def test_max_value_inside_and_outside():
    req = MaxValue("max_peak_stress_MPa", maximum=40.0)
    inside = req.check({"max_peak_stress_MPa": 40.0 - EPS})
    outside = req.check({"max_peak_stress_MPa": 40.0 + EPS})
    assert inside.met and inside.word == "MET"
    assert not outside.met and outside.word == "NOT MET"
    assert inside.margin == pytest.approx(EPS)
    assert outside.margin == pytest.approx(-EPS)
    assert outside.margin_rel == pytest.approx(-EPS / 40.0)
    assert inside.unit == "MPa" and inside.bound == "<= 40 MPa"
    assert req.constraint({"max_peak_stress_MPa": 40.0 + EPS}) == pytest.approx(EPS / 40.0)


def test_min_value_and_min_feature():
    req = MinValue("stroke_mm", minimum=10.0)
    assert req.check({"stroke_mm": 10.0 + EPS}).margin == pytest.approx(EPS)
    below = req.check({"stroke_mm": 10.0 - EPS})
    assert not below.met and below.margin == pytest.approx(-EPS)
    feature = MinFeature("min_feature_mm", minimum=0.8)
    assert feature.check({"min_feature_mm": 0.8 + EPS}).met
    thin = feature.check({"min_feature_mm": 0.8 - EPS})
    assert not thin.met and thin.margin == pytest.approx(-EPS)
    assert "printable" in thin.bound


@pytest.mark.parametrize(
    ("value", "met", "margin"),
    [
        (270.0 + EPS, True, EPS),  # just inside the low end
        (290.0 - EPS, True, EPS),  # just inside the high end
        (270.0 - EPS, False, -EPS),
        (290.0 + EPS, False, -EPS),
        (280.0, True, 10.0),  # the middle: 10 to either end
    ],
)
def test_range_margin_is_the_distance_to_the_nearer_end(value, met, margin):
    v = Range("stiffness_Nm_per_rad", minimum=270.0, maximum=290.0).check(
        {"stiffness_Nm_per_rad": value}
    )
    assert v.met is met
    assert v.margin == pytest.approx(margin)
    assert v.unit == "N·m/rad"


def test_allowable_stress_with_a_safety_factor():
    req = AllowableStress("max_peak_stress_MPa", yield_MPa=42.5, safety_factor=1.5)
    allowable = 42.5 / 1.5
    assert req.check({"max_peak_stress_MPa": allowable - EPS}).met
    v = req.check({"max_peak_stress_MPa": allowable + EPS})
    assert not v.met and v.margin == pytest.approx(-EPS)
    assert v.margin_rel == pytest.approx(-EPS / allowable)
    assert "28.33 MPa" in v.bound and "SF 1.5" in v.bound


def test_flag_stable():
    req = Flag("stable", expected=True)
    assert req.check({"stable": True}).met
    v = req.check({"stable": False, "stable_message": "past a bifurcation at row 12"})
    assert not v.met and v.margin == -1.0 and "bifurcation" in v.detail


def test_envelope():
    req = Envelope(max_width_mm=80.0, max_height_mm=40.0)
    inside = req.check({"envelope_width_mm": 80.0 - EPS, "envelope_height_mm": 30.0})
    assert inside.met and inside.margin == pytest.approx(EPS)
    outside = req.check({"envelope_width_mm": 70.0, "envelope_height_mm": 40.0 + EPS})
    assert not outside.met and outside.margin == pytest.approx(-EPS)
    assert outside.value == pytest.approx(40.0 + EPS)
    assert not req.check({}).met  # no outline: not shown, so NOT MET


def test_missing_value_is_not_met_and_says_why():
    v = MaxValue("max_peak_stress_MPa", maximum=40.0).check({"max_peak_stress_MPa": None})
    assert not v.met and math.isnan(v.value) and "not computed" in v.detail
    assert to_records([v])[0]["value"] is None  # JSON: no NaN


def test_target_band_absolute_and_relative():
    target = ConstantTarget("force", 1.5)
    x = np.linspace(0.0, 30.0, 61)
    tol = 0.02 * 1.5
    band = TargetBand("force_N", x="displacement_mm", target=target, over=(0.5, 30.0),
                      tolerance_rel=0.02)  # fmt: skip
    y_in = np.full_like(x, 1.5 + tol - EPS)
    y_out = y_in.copy()
    y_out[40] = 1.5 - tol - EPS  # one row at x = 20 mm falls out of the band, below
    inside = band.check({}, {"force_N": (x, y_in)})
    outside = band.check({}, {"force_N": (x, y_out)})
    assert inside.met and inside.margin == pytest.approx(EPS)
    assert not outside.met and outside.margin == pytest.approx(-EPS)
    assert outside.value == pytest.approx(tol + EPS)
    assert "at 20 mm" in outside.detail and "below" in outside.detail
    assert "±2 % of 1.5 N over 0.5–30 mm" in outside.bound
    # rows below 0.5 mm do not count: a response that starts at 0 N is fine there
    y_start = y_in.copy()
    y_start[0] = 0.0
    assert band.check({}, {"force_N": (x, y_start)}).margin == pytest.approx(EPS)
    absolute = TargetBand("force_N", x="displacement_mm", target=target, tolerance=0.1)
    assert absolute.check({}, {"force_N": (x, np.full_like(x, 1.6 - EPS))}).met
    assert not absolute.check({}, {"force_N": (x, np.full_like(x, 1.6 + EPS))}).met


def test_target_band_must_reach_the_whole_range():
    band = TargetBand("force_N", x="displacement_mm", target=ConstantTarget("force", 1.5),
                      over=(0.5, 30.0), tolerance_rel=0.02)  # fmt: skip
    x = np.linspace(0.0, 20.0, 41)  # the trace stopped at 20 mm
    v = band.check({}, {"force_N": (x, np.full_like(x, 1.5))})
    assert not v.met and "covers only 0–20 mm of 0.5–30 mm" in v.detail


def test_a_5N_target_that_ends_flat_at_3_76N_is_not_met():
    """The issue's case: a 5 N constant-force study whose design holds a flat 3.76 N."""
    target_N, flat_N, tol_rel = 5.0, 3.76, 0.05
    x = np.linspace(0.0, 15.0, 31)
    band = TargetBand("force_N", x="displacement_mm", target=ConstantTarget("force", target_N),
                      over=(0.5, 15.0), tolerance_rel=tol_rel)  # fmt: skip
    v = band.check({}, {"force_N": (x, np.full_like(x, flat_N))})
    assert not v.met and overall([v]) == "NOT MET"
    assert v.value == pytest.approx(target_N - flat_N)
    assert v.margin == pytest.approx(tol_rel * target_N - (target_N - flat_N))
    assert v.margin_rel == pytest.approx(v.margin / target_N)  # a share of the target level


def test_target_band_converts_column_units():
    # torque_Nm against rotation_deg: the curve is in N·mm and rad
    target = LinearTarget("torque", stiffness=276_000.0)  # 276 N·m/rad
    deg = np.linspace(0.0, 10.0, 11)
    torque_Nm = 276.0 * np.radians(deg)
    band = TargetBand("torque_Nm", x="rotation_deg", target=target, over=(1.0, 10.0),
                      tolerance_rel=0.02)  # fmt: skip
    v = band.check({}, {"torque_Nm": (deg, torque_Nm * 1.01)})
    assert v.met
    assert v.margin == pytest.approx(0.01 * 276.0 * math.radians(1.0))  # tightest at 1 deg


def test_overall_lines_and_records():
    ok = MaxValue("a_MPa", maximum=1.0).check({"a_MPa": 0.5})
    bad = MinValue("b_mm", minimum=1.0, role="constraint").check({"b_mm": 0.5})
    assert overall([ok]) == "MET"
    assert overall([ok, bad]) == "NOT MET"
    assert overall([]) == "NOT MET"  # nothing required: nothing claimed
    lines = verdict_lines([ok, bad])
    assert lines[0].split() == ["requirement", "value", "bound", "margin", "verdict"]
    assert lines[1].endswith("MET") and "NOT MET (constraint)" in lines[2]
    assert lines[-1] == "overall: NOT MET (1 of 2 requirements met)"
    record = verdict_record([ok, bad])
    assert record["overall"] == "NOT MET"
    assert [r["verdict"] for r in record["requirements"]] == ["MET", "NOT MET"]
    assert list(record["requirements"][0])[:3] == ["verdict", "name", "quantity"]


def test_requirements_pickle():
    band = TargetBand("force_N", x="displacement_mm", target=ConstantTarget("force", 1.5),
                      tolerance=0.1)  # fmt: skip
    assert (
        pickle.loads(pickle.dumps(band))
        .check({}, {"force_N": (np.array([0.0, 1.0]), np.array([1.5, 1.5]))})
        .met
    )


def test_units_from_names():
    assert unit_of("max_peak_stress_MPa") == "MPa"
    assert unit_of("stiffness_Nm_per_rad") == "N·m/rad"
    assert unit_of("torque_Nmm") == "N·mm"
    assert unit_of("stress_yield_ratio") == ""
    assert unit_of("stiffness_error_percent") == "%"


# --- the study-file spec ---------------------------------------------------------------------


def test_spec_shapes():
    r = RequirementSpec.model_validate({"quantity": "max_peak_stress_MPa", "max": 40.0})
    assert isinstance(r.to_requirement(), MaxValue) and r.role == "check"
    r = RequirementSpec.model_validate({"quantity": "s_MPa", "min": 1, "max": 2})
    assert isinstance(r.to_requirement(), Range)
    r = RequirementSpec.model_validate({"quantity": "max_peak_stress_MPa", "safety_factor": 2})
    req = r.to_requirement(yield_MPa=42.5)
    assert isinstance(req, AllowableStress) and req.allowable_MPa == pytest.approx(21.25)
    r = RequirementSpec.model_validate({"envelope_mm": [80, 40], "role": "constraint"})
    assert isinstance(r.to_requirement(), Envelope) and r.judged[0] == "envelope_width_mm"
    r = RequirementSpec.model_validate({"quantity": "min_feature_mm", "min": 0.8})
    assert isinstance(r.to_requirement(), MinFeature)
    r = RequirementSpec.model_validate({"quantity": "stable", "equals": True})
    assert isinstance(r.to_requirement(), Flag)


def test_spec_target_with_the_band_inside_the_target():
    r = RequirementSpec.model_validate(
        {
            "quantity": "force_N",
            "x": "displacement_mm",
            "over": [0.5, 15.0],
            "target": {"kind": "constant", "force_N": 5.0, "tolerance_rel": 0.05},
        }
    )
    req = r.to_requirement()
    assert isinstance(req, TargetBand) and req.tolerance_rel == 0.05
    table = {"displacement_mm": np.linspace(0, 15, 31), "force_N": np.full(31, 3.76)}
    assert not req.check({}, curves_from_table(table, [req])).met
    pct = RequirementSpec.model_validate(
        {
            "quantity": "force_N",
            "x": "displacement_mm",
            "tolerance_percent": 2,
            "target": {"kind": "constant", "force_N": 1.5},
        }  # fmt: skip
    )
    assert pct.to_requirement().tolerance_rel == pytest.approx(0.02)


@pytest.mark.parametrize(
    ("raw", "words"),
    [
        ({"quantity": "a_MPa"}, "has none of"),
        ({"quantity": "a_MPa", "max": 1, "equals": True}, "mixes"),
        ({"max": 1.0}, "needs quantity"),
        ({"quantity": "a_MPa", "min": 2, "max": 1}, "swap"),
        ({"quantity": "ratio", "safety_factor": 1.5}, "not one"),
        ({"quantity": "force_N", "target": {"kind": "constant", "force_N": 1}}, "one band"),
        (
            {"quantity": "force_N", "tolerance": 0.1, "target": {"kind": "constant", "force_N": 1}},
            "needs x",
        ),
        ({"quantity": "a_MPa", "max": 1, "over": [0, 1]}, "go with target"),
        ({"quantity": "a_MPa", "max": 1, "role": "soft"}, "constraint"),
    ],
)
def test_spec_refuses(raw, words):
    with pytest.raises(ValidationError) as info:
        RequirementSpec.model_validate(raw)
    assert words in str(info.value)
