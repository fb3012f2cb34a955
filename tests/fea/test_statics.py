"""Finger force of paper 001: Eq. 14 where it is exact, the vector form where it is not."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.errors import FeaError
from flexopt.fea.statics import (
    STANDARD_GRAVITY_M_PER_S2,
    FingerGeometry,
    JawLoad,
    actuator_force_N,
    finger_force,
    finger_force_paper_N,
    normal_force_for_friction_N,
    overtravel_mm,
)

FINGER = FingerGeometry(
    lever_mm=20.0, jaw_mm=30.0, alpha_rad=math.radians(10), beta_rad=math.radians(20)
)
PSI = math.radians(30)  # α + β


def test_paper_lower_finger_vector_form_equals_eq14():
    load = JawLoad(mass_kg=0.02, normal_force_N=0.8)  # N and G both down on the lower jaw
    req = finger_force(load, FINGER)
    g = 0.02 * STANDARD_GRAVITY_M_PER_S2
    eq14 = (g + 0.8) * math.cos(PSI) * 30.0 / 20.0
    assert req.finger_force_N == pytest.approx(eq14, rel=1e-14)
    assert req.paper_finger_force_N == pytest.approx(eq14, rel=1e-14)
    assert req.relative_difference == pytest.approx(0.0, abs=1e-14)
    assert req.jaw_force_N == pytest.approx(req.paper_jaw_force_N, rel=1e-14)  # Eq. 6 exact here
    assert finger_force_paper_N(load, FINGER) == pytest.approx(eq14)


def test_upper_finger_subtracts_what_the_paper_adds():
    # mirrored finger (jaw arm at -ψ), workpiece pushing the jaw up, no weight on it
    upper = FingerGeometry(20.0, 30.0, -math.radians(10), -math.radians(20))
    req = finger_force(JawLoad(0.02, 0.8, normal_angle_rad=math.pi / 2, weight_share=0.0), upper)
    assert req.finger_force_N == pytest.approx(0.8 * math.cos(PSI) * 1.5, rel=1e-14)
    # a jaw pressing up while carrying the weight: |N - G|, where Eq. 6 says N + G
    both = finger_force(JawLoad(0.02, 0.8, normal_angle_rad=math.pi / 2), upper)
    g = 0.02 * STANDARD_GRAVITY_M_PER_S2
    assert both.jaw_force_N == pytest.approx(0.8 - g)
    assert both.finger_force_N == pytest.approx((0.8 - g) * math.cos(PSI) * 1.5, rel=1e-12)


def test_side_grip_moment_by_the_cross_product():
    # fingers closing horizontally: N along -x on the jaw, half the weight by friction, down
    load = JawLoad(0.02, 0.8, normal_angle_rad=math.pi, weight_share=0.5)
    req = finger_force(load, FINGER)
    g = 0.02 * STANDARD_GRAVITY_M_PER_S2
    # M = l2 (cos ψ F_y - sin ψ F_x), F = (-N, -G/2)
    moment = 30.0 * (math.cos(PSI) * (-g / 2) - math.sin(PSI) * (-0.8))
    assert req.moment_Nmm == pytest.approx(moment, rel=1e-14)
    assert req.finger_force_N == pytest.approx(abs(moment) / 20.0, rel=1e-14)
    assert req.jaw_force_N == pytest.approx(math.hypot(0.8, g / 2))
    assert req.paper_finger_force_N / req.finger_force_N > 2.5  # Eq. 14 overstates it here


def test_friction_normal_force_actuator_force_and_overtravel():
    n = normal_force_for_friction_N(0.1, friction=0.5, contacts=2, safety=2.0)
    assert n == pytest.approx(2.0 * 0.1 * STANDARD_GRAVITY_M_PER_S2 / (2 * 0.5))
    assert actuator_force_N(1.2, 0.3) == pytest.approx(1.5)  # Eq. 13
    assert overtravel_mm(20.0, np.radians([5.0, 15.0])) == pytest.approx(
        20.0 * (math.tan(math.radians(15)) - math.tan(math.radians(5)))
    )
    with pytest.raises(FeaError, match="friction"):
        normal_force_for_friction_N(0.1, friction=0.0)
    with pytest.raises(FeaError, match="lever_mm"):
        FingerGeometry(0.0, 30.0, 0.0, 0.0)
