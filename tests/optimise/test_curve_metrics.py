"""optimise.curve_metrics: the constant-force window, found exactly on the interpolant."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.curve_metrics import curve_metrics


def test_curve_metrics_find_the_window_exactly_on_the_interpolant():
    s = np.linspace(0.0, 10.0, 11)
    f = np.array([0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.1, 1.0, 1.0, 1.0])
    sigma = np.linspace(0.0, 50.0, 11)  # 5 MPa per mm
    m = curve_metrics(s, f, sigma, 1.0, 0.02, 42.5, samples=10)
    # band [0.98, 1.02]: the bump at 7 mm leaves it at 6.2 and re-enters at 7.8; the stress
    # reaches 42.5 MPa at 8.5 mm. Row 0 -> 1 (the buckling rise) is not searched.
    assert m.window_mm == pytest.approx((1.0, 6.2))
    assert m.operative_stroke_mm == pytest.approx(5.2)
    assert m.stress_limit_stroke_mm == pytest.approx(8.5)
    # over the window: 1.0 N, then the rise to 1.02 N between 6.0 and 6.2 mm
    mean = (5.0 * 1.0 + 0.2 * 1.01) / 5.2
    assert m.mean_force_N == pytest.approx(mean)
    assert m.flatness_percent == pytest.approx((1.02 - mean) / mean * 100)
    assert m.rms_error_N == pytest.approx(np.sqrt(0.1**2 / 10))
    assert m.peak_stress_MPa == 50.0 and m.window_peak_stress_MPa == pytest.approx(31.0)
    none = curve_metrics(s, 2 * f, sigma, 1.0, 0.02, 42.5, samples=10)
    assert none.operative_stroke_mm == 0.0 and none.mean_force_N is None
