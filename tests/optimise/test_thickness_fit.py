"""optimise.thickness_fit: the thickness that scales a torque curve onto its target."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.targets import ThresholdTarget, curve_error
from flexopt.optimise.thickness_fit import fit_thickness


def test_thickness_fit_recovers_a_known_scale():
    # A curve that is the target divided by 7 (per mm) needs ST = 7 mm, with zero error.
    target = ThresholdTarget("torque", 15000.0, 37.0)
    x = np.radians(np.linspace(0.0, 8.0, 25))
    st, err = fit_thickness(x, target(x) / 7.0, target, "max_normalised", (0.0, x[-1]))
    assert st == pytest.approx(7.0, rel=1e-5)
    assert err < 1e-5
    # and for a linear curve the best scale balances the largest errors (minimax)
    y = x * 1000.0
    st, err = fit_thickness(x, y, target, "max_normalised", (0.0, x[-1]))
    assert err == pytest.approx(
        float(curve_error(target, x, st * y, "max_normalised", (0, x[-1]))), rel=1e-9
    )
    for c in (0.97 * st, 1.03 * st):
        assert float(curve_error(target, x, c * y, "max_normalised", (0, x[-1]))) > err
