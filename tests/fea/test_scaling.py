"""The closed-form thickness / width laws of fea/scaling.py (Eq. 12 of paper 003 and the
thickness-proportional response)."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.scaling import (
    at_thickness,
    flexure_stiffness_Nmm,
    flexure_thickness_mm,
    flexure_width_mm,
)
from flexopt.geometry.errors import GeometryError


def test_flexure_laws_invert_each_other():
    # K = E h^3 b / (12 L); Table 2's first pivot in ABS (E = 1800 MPa)
    K = flexure_stiffness_Nmm(1800.0, 2.478, 0.908, 10.8)
    assert K == pytest.approx(1800.0 * 0.908**3 * 2.478 / 12.0 / 10.8, rel=1e-15)
    assert flexure_width_mm(K, 1800.0, 0.908, 10.8) == pytest.approx(2.478, rel=1e-13)
    assert flexure_thickness_mm(K, 1800.0, 2.478, 10.8) == pytest.approx(0.908, rel=1e-13)


def test_flexure_laws_broadcast_and_refuse_non_positive_inputs():
    K = flexure_stiffness_Nmm(1800.0, np.array([1.0, 2.0]), 1.0, 10.0)
    assert K.shape == (2,) and K[1] == pytest.approx(2 * K[0], rel=1e-15)
    with pytest.raises(GeometryError, match="width_mm"):
        flexure_stiffness_Nmm(1800.0, 0.0, 1.0, 10.0)
    with pytest.raises(GeometryError, match="K_Nmm"):
        flexure_width_mm(-1.0, 1800.0, 1.0, 10.0)


def test_at_thickness_scales_in_proportion():
    torque = np.array([0.0, 1.0, 2.5])
    assert np.array_equal(at_thickness(torque, 10.0, 5.0), torque * (5.0 / 10.0))
    assert np.array_equal(at_thickness(torque, 4.0, 4.0), torque)
