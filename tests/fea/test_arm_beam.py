"""The arm beam model of an arm spring (fea/arm_beam.py) against exact solutions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.arm_beam import arm_beam_torque
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import get_material
from flexopt.geometry.profile import BeamProfile

TI = get_material("Ti-6Al-4V")


def _spoke(a: float, b: float, w: float, st: float, angle_deg: float = 30.0) -> BeamProfile:
    """A straight radial arm from radius a to b along the direction angle_deg."""
    u = np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))])
    pts = np.outer(np.linspace(a, b, 5), u)
    return BeamProfile(pts, np.full(5, w), st)


def _timoshenko_hub_stiffness(a, L, w, st, n, mat) -> float:
    """Exact linear hub stiffness (N·mm/rad) of n straight radial spokes, hub radius a, length L.

    The spoke's root moves tangentially by a p and turns by p, its end is clamped: with the
    Timoshenko beam's end stiffnesses k11 = 12 EI / (L^3 (1 + P)), k12 = 6 EI / (L^2 (1 + P)),
    k22 = (4 + P) EI / (L (1 + P)), P = 12 EI / (k G A L^2), the root carries
    F = (k11 a + k12) p and M = (k12 a + k22) p, and the hub torque is n (M + a F).
    """
    E, G = mat.E_MPa, mat.E_MPa / (2 * (1 + mat.nu))
    ei = E * st * w**3 / 12
    phi = 12 * ei / (5 / 6 * G * st * w * L**2)
    k11 = 12 * ei / (L**3 * (1 + phi))
    k12 = 6 * ei / (L**2 * (1 + phi))
    k22 = (4 + phi) * ei / (L * (1 + phi))
    return n * (k22 + 2 * a * k12 + a**2 * k11)


@pytest.mark.parametrize("n_arms", [1, 3])
def test_small_rotation_matches_timoshenko_spokes(n_arms):
    a, b, w, st = 9.0, 41.0, 1.5, 8.0
    r = arm_beam_torque(_spoke(a, b, w, st), TI, n_arms, np.array([0.0, 1e-5]), n_elements=8)
    assert r.ok
    k = r.torque_Nmm[1] / 1e-5
    exact = _timoshenko_hub_stiffness(a, b - a, w, st, n_arms, TI)
    assert k == pytest.approx(exact, rel=2e-5)
    # and the orientation of the spoke does not matter (rotational invariance)
    r2 = arm_beam_torque(_spoke(a, b, w, st, 200.0), TI, n_arms, np.array([0.0, 1e-5]), 8)
    assert r2.torque_Nmm[1] == pytest.approx(r.torque_Nmm[1], rel=1e-9)


def test_torque_is_odd_for_a_radial_spoke_and_stiffens_in_tension():
    # A radial spoke turned either way is the same problem mirrored: T(-p) = -T(p). At large
    # rotation the clamped spoke is stretched (its chord grows), so the secant stiffness rises.
    prof = _spoke(9.0, 41.0, 1.5, 8.0, 0.0)
    p = np.radians([0.0, 4.0, 8.0, 12.0])
    fwd = arm_beam_torque(prof, TI, 3, p)
    back = arm_beam_torque(prof, TI, 3, -p)
    assert fwd.ok and back.ok
    np.testing.assert_allclose(back.torque_Nmm, -fwd.torque_Nmm, rtol=1e-7, atol=1e-9)
    secant = fwd.torque_Nmm[1:] / p[1:]
    assert np.all(np.diff(secant) > 0)


def _curved_arm() -> BeamProfile:
    """A circular-arc arm from the hub rim (9, 0) to a pad 38 mm out at 70 degrees, bowed
    outwards (counter-clockwise winding)."""
    end = 38.0 * np.array([math.cos(math.radians(70.0)), math.sin(math.radians(70.0))])
    return BeamProfile(np.array([[9.0, 0.0], end]), np.array([1.2, 1.2]), 10.0, np.array([0.01]))


def test_curved_arm_converges_under_refinement():
    p = np.radians(np.linspace(0.0, 10.0, 6))
    curves = [
        arm_beam_torque(_curved_arm(), TI, 3, p, n_elements=n).torque_Nmm for n in (6, 12, 24)
    ]
    d1 = np.max(np.abs(curves[1] - curves[0]))
    d2 = np.max(np.abs(curves[2] - curves[1]))
    assert d2 < d1 / 4  # at least second order (P2 elements converge faster)
    assert d2 < 5e-4 * np.max(np.abs(curves[2]))  # 12 -> 24 elements: 0.02 % of the torque


def test_compressed_curved_arm_softens():
    # Counter-clockwise hub rotation pushes the root along an arm that winds counter-clockwise:
    # the arm is a compressed curved strut, its secant stiffness falls with rotation; turned the
    # other way it is pulled straight and stiffens.
    p = np.radians(np.linspace(0.0, 10.0, 6))
    ccw = arm_beam_torque(_curved_arm(), TI, 3, p)
    cw = arm_beam_torque(_curved_arm(), TI, 3, -p)
    assert ccw.ok and cw.ok
    s_ccw = ccw.torque_Nmm[1:] / p[1:]
    s_cw = cw.torque_Nmm[1:] / -p[1:]
    assert s_ccw[-1] < 0.9 * s_ccw[0]
    assert s_cw[-1] > s_cw[0]
    # the same spring near 0: one linear stiffness both ways
    k = [arm_beam_torque(_curved_arm(), TI, 3, np.array([0.0, d])).torque_Nmm[1] / d
         for d in (1e-6, -1e-6)]  # fmt: skip
    assert k[0] == pytest.approx(k[1], rel=1e-4)
    assert s_ccw[0] < k[0] < s_cw[0]


def test_bad_arguments_raise():
    with pytest.raises(FeaError, match="n_arms"):
        arm_beam_torque(_curved_arm(), TI, 0, np.array([0.0, 0.1]))
    with pytest.raises(FeaError, match="rotation_rad"):
        arm_beam_torque(_curved_arm(), TI, 3, np.array([0.0, np.nan]))
