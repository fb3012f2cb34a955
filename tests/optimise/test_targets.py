"""Target curves, their work integrals, error measures and the study-file spec."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.targets import (
    ConstantTarget,
    LinearTarget,
    TableTarget,
    TargetSpec,
    ThresholdTarget,
    column_unit_factor,
    curve_error,
    measure_key,
)
from pydantic import ValidationError
from scipy.integrate import quad


def test_threshold_curve_matches_eq14_and_its_mode_split():
    t = ThresholdTarget("torque", 15_000.0, 37.0)
    x = np.array([-0.1, 0.0, 0.01, 0.05, 1.0])
    np.testing.assert_allclose(t(x), np.sign(x) * 15_000.0 * (1 - np.exp(-37.0 * np.abs(x))))
    # T1 = 80 % Tmax at x1 = ln 5 / s (paper Sec. 2.2, Fig. 8)
    assert t.split_x == pytest.approx(math.log(5) / 37.0, rel=1e-14)
    assert t.split_y == pytest.approx(12_000.0)
    assert t(t.split_x) == pytest.approx(12_000.0, rel=1e-12)
    assert t.equivalent_stiffness == pytest.approx(12_000.0 * 37.0 / math.log(5), rel=1e-12)
    np.testing.assert_array_equal(t.mode([0.0, t.split_x * 0.99, t.split_x * 1.01]), [1, 1, 2])
    y = np.array([-14_000.0, 100.0, 12_000.0])
    np.testing.assert_allclose(t(t.inverse(y)), y, rtol=1e-12)
    with pytest.raises(OptimiseError, match="only approaches"):
        t.inverse(15_000.0)


@pytest.mark.parametrize(
    "curve",
    [
        ThresholdTarget("torque", 2050.0, 50.0),
        ThresholdTarget("torque", 2050.0, 5000.0),  # exercises the small-s x series
        LinearTarget("torque", 276.0, 12.0),
        ConstantTarget("force", 1.5),
    ],
    ids=["threshold", "steep-threshold", "linear", "constant"],
)
def test_work_is_the_integral_of_the_curve(curve):
    for x in (1e-7, 1e-4, 0.03, 0.7, 1.5):
        exact, _ = quad(lambda u: float(curve(u)), 0.0, x, epsabs=0, epsrel=1e-13, limit=200)
        assert float(curve.work(x)) == pytest.approx(exact, rel=1e-9, abs=1e-300)
    h = 1e-6
    for x in (0.01, 0.5):
        slope = (float(curve(x + h)) - float(curve(x - h))) / (2 * h)
        assert float(curve.slope(x)) == pytest.approx(slope, rel=1e-6, abs=1e-3)


def test_table_is_linear_between_points_and_integrates_exactly():
    x = np.array([-1.0, 0.0, 0.5, 2.0])
    y = np.array([-3.0, 0.0, 2.0, 2.5])
    t = TableTarget("torque", x, y)
    assert float(t(0.25)) == pytest.approx(1.0)
    assert float(t.slope(1.0)) == pytest.approx(0.5 / 1.5)
    # ∫_0^2 = triangle 0.5*0.5*2 + trapezoid 1.5*(2 + 2.5)/2
    assert float(t.work(2.0)) == pytest.approx(0.5 + 3.375)
    assert float(t.work(-1.0)) == pytest.approx(1.5)  # ∫_0^-1 of a negative curve
    with pytest.raises(OptimiseError, match="covers"):
        t(2.5)
    with pytest.raises(OptimiseError, match=r"x\[1\] = 1 >= x\[2\] = 1"):
        TableTarget("torque", [0.0, 1.0, 1.0], [0.0, 1.0, 2.0])


def test_error_measures_over_a_window_and_a_batch():
    t = ConstantTarget("force", 2.0)
    x = np.linspace(0.0, 10.0, 11)
    y = np.vstack([np.full(11, 2.0), np.full(11, 2.2), 2.0 + 0.1 * (x > 5)])
    np.testing.assert_allclose(curve_error(t, x, y, "rms"), [0.0, 0.2, 0.1 * math.sqrt(5 / 11)])
    np.testing.assert_allclose(curve_error(t, x, y, "max_relative"), [0.0, 0.1, 0.05])
    np.testing.assert_allclose(curve_error(t, x, y, "max_abs", window=(0.0, 5.0)), [0, 0.2, 0])
    assert measure_key("rms", t) == "rms_error_N"
    assert measure_key("max_relative", t) == "max_relative_error"
    spring = ThresholdTarget("torque", 1000.0, 10.0)
    xs = np.linspace(0, 1, 51)
    with pytest.raises(OptimiseError, match="target, which is 0"):
        curve_error(spring, xs, spring(xs), "max_relative")
    # divided by the largest target in the window, 1000 (1 - e^-10)
    expected = 10.0 / (1000.0 * -math.expm1(-10.0))
    assert curve_error(spring, xs, spring(xs) + 10.0, "max_normalised") == pytest.approx(expected)
    with pytest.raises(OptimiseError, match="no response row"):
        curve_error(spring, xs, spring(xs), window=(2.0, 3.0))
    with pytest.raises(OptimiseError, match="unknown error measure"):
        curve_error(spring, xs, spring(xs), "mean")


def test_spec_converts_study_units_to_project_units():
    spec = TargetSpec(kind="threshold", max_torque_Nm=2.05, rate_per_rad=50, window_deg=(1, 85))
    curve = spec.to_curve()
    assert isinstance(curve, ThresholdTarget) and curve.max_value == pytest.approx(2050.0)
    assert curve.x_name == "rotation_rad" and curve.y_name == "torque_Nmm"
    assert spec.window == pytest.approx((math.radians(1), math.radians(85)))
    lin = TargetSpec(kind="linear", stiffness_Nm_per_rad=276).to_curve()
    assert lin.stiffness == pytest.approx(276_000.0)
    force = TargetSpec(kind="constant", force_N=1.5, window_mm=(3, 25)).to_curve()
    assert force.quantity == "force" and float(force(7.0)) == 1.5
    table = TargetSpec(
        kind="table", columns=("rotation_deg", "torque_Nm"), points=((0, 0), (90, 2))
    )
    tc = table.to_curve()
    assert float(tc(math.pi / 2)) == pytest.approx(2000.0)
    from_file = TargetSpec(kind="table", file="x.csv")
    with pytest.raises(OptimiseError, match="read the file first"):
        from_file.to_curve()
    tc2 = from_file.to_curve((np.array([0.0, 10.0]), np.array([0.0, 5.0])), ("x_mm", "force_N"))
    assert tc2.quantity == "force" and float(tc2(4.0)) == pytest.approx(2.0)
    assert column_unit_factor("torque_Nm") == ("y", "torque", 1000.0)


@pytest.mark.parametrize(
    "raw, message",
    [
        ({"kind": "threshold", "max_torque_Nm": 2}, "needs one of rate_per_rad, rate_per_mm"),
        ({"kind": "constant", "force_N": 1, "torque_Nm": 1}, "takes only one of"),
        ({"kind": "linear", "stiffness_Nm_per_rad": 1, "preload_N": 1}, "mixes torque keys"),
        ({"kind": "constant", "force_N": 1, "rate_per_mm": 2}, "does not use rate_per_mm"),
        ({"kind": "table", "points": [[0, 0], [1, 1]]}, "points need columns"),
        ({"kind": "table", "file": "a.csv", "columns": ["angle", "torque_Nm"]}, "no unit suffix"),
        ({"kind": "constant", "torque_Nm": 1, "window_mm": [0, 1]}, "windowed by window_deg"),
        ({"kind": "constant", "force_N": 1, "window_mm": [2, 1]}, "lower < upper"),
        ({"kind": "constant", "force_N": 1, "extra": 1}, "Extra inputs"),
    ],
)
def test_spec_errors_name_the_key_and_the_fix(raw, message):
    with pytest.raises(ValidationError, match=message):
        TargetSpec.model_validate(raw)
