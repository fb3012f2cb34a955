"""Cam synthesis of paper 000: virtual work, the regular start at γ = 0, the plate and the SAB."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
import shapely
import trimesh
from flexopt.fea.contact import (
    CorrectedCurve,
    contact_pressure_MPa,
    fit_correction,
    sab_limits,
    sab_ratio,
    sab_ratio_ideal,
    sab_ratio_series,
    synthesise_cam,
    torque_from_outline,
)
from flexopt.geometry.cam import (
    CamLayout,
    CamSprings,
    cam_outline,
    cam_stl,
    follower_radius_from_outline,
)
from flexopt.geometry.errors import GeometryError
from scipy.integrate import quad


class Threshold:
    """Eq. 14 in N·mm over rad, with its work (kept local: geometry tests need no optimise)."""

    def __init__(self, t_max: float, s: float) -> None:
        self.t_max, self.s = t_max, s

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        return np.sign(x) * self.t_max * -np.expm1(-self.s * np.abs(x))

    def work(self, x):
        ax = np.abs(np.asarray(x, dtype=float))
        return self.t_max * (ax + np.expm1(-self.s * ax) / self.s)


PROTOTYPE = Threshold(2050.0, 50.0)  # paper: Tmax = 2.05 N·m, s = 50 /rad
SPRINGS = CamSprings(stiffness_N_per_mm=4.0, free_length_mm=18.0, offset_mm=10.0)
LAYOUT = CamLayout(rest_radius_mm=20.0, roller_radius_mm=5.0)
# relaxed at rest: sqrt(r0² + b²) = l0, so F_k(r0) = 0 and Eq. 10 is 0/0 at γ = 0
RELAXED = CamSprings(stiffness_N_per_mm=4.0, free_length_mm=math.hypot(20.0, 10.0), offset_mm=10.0)


@pytest.fixture(scope="module")
def profile():
    return synthesise_cam(PROTOTYPE, SPRINGS, LAYOUT)


@pytest.fixture(scope="module")
def plate(profile):
    return cam_outline(profile)


def spring_work(springs, layout, r):
    return layout.followers * np.array(
        [quad(lambda y: float(springs.force_N(y)), layout.rest_radius_mm, ri)[0] for ri in r]
    )


def test_synthesis_satisfies_the_virtual_work_identity_eq6(profile):
    # ∫_0^γ T dγ = 2 ∫_{r0}^{r} F_k dr at every grid point (frictionless Eq. 6)
    g = profile.rotation_rad[::40]
    r = profile.follower_radius_mm[::40]
    np.testing.assert_allclose(spring_work(SPRINGS, LAYOUT, r), PROTOTYPE.work(g), rtol=1e-9)
    # and its derivative, Eq. 9: T = 2 F_k dr/dγ
    i = slice(8, -5)  # np.gradient's O(h²) error is large only where r'' is, near γ = 0
    dr = np.gradient(profile.follower_radius_mm, profile.rotation_rad)[i]
    torque = 2 * SPRINGS.force_N(profile.follower_radius_mm[i]) * dr
    np.testing.assert_allclose(torque, PROTOTYPE(profile.rotation_rad[i]), rtol=2e-3)
    # Eq. 10: tan α = r γ' with γ' = 2 F_k / T
    gp = 2 * profile.spring_force_N[1:] / profile.torque_Nmm[1:]
    np.testing.assert_allclose(
        np.tan(profile.alpha_rad[1:]), profile.follower_radius_mm[1:] * gp, rtol=1e-9
    )
    assert profile.slope_mm_per_rad[0] == 0.0  # preloaded: α = 90° at rest, no 1/0


@pytest.mark.parametrize("springs", [SPRINGS, RELAXED], ids=["preloaded", "relaxed"])
def test_the_plate_produces_the_target_torque_by_virtual_work(springs):
    prof = synthesise_cam(PROTOTYPE, springs, LAYOUT)
    plate = cam_outline(prof)
    g = np.radians([2.0, 5.0, 10.0, 30.0, 60.0, 85.0])
    torque = torque_from_outline(plate, springs, LAYOUT, g)
    np.testing.assert_allclose(torque, PROTOTYPE(g), rtol=2e-3)
    # at rest the followers sit symmetric: no torque
    assert abs(torque_from_outline(plate, springs, LAYOUT, [0.0])[0]) < 1.0


def test_relaxed_springs_start_with_the_series_slope():
    prof = synthesise_cam(PROTOTYPE, RELAXED, LAYOUT)
    # r'(0) = sqrt(T'(0) / (n F_k'(r0))) from u = T'(0) γ²/2 = n k (r - r0)²/2
    expected = math.sqrt(2050.0 * 50.0 / (2 * float(RELAXED.rate_N_per_mm(20.0))))
    assert prof.slope_mm_per_rad[0] == pytest.approx(expected, rel=1e-7)  # T'(0) from T(h)/h
    fd = (prof.follower_radius_mm[1] - prof.follower_radius_mm[0]) / prof.rotation_rad[1]
    assert fd == pytest.approx(expected, rel=0.1)  # r'' is large there; the series fixes γ = 0
    assert any("V-notch" in note for note in prof.notes)


def test_friction_solves_eq10_and_tends_to_the_frictionless_cam(profile):
    mu = 0.1
    prof = synthesise_cam(PROTOTYPE, SPRINGS, CamLayout(20.0, 5.0, friction=mu))
    r, g = prof.follower_radius_mm, prof.rotation_rad
    i = slice(20, -20)
    dg_dr = 1.0 / np.gradient(r, g)[i]
    eq10 = 2 * SPRINGS.force_N(r[i]) / PROTOTYPE(g[i]) + mu / r[i]
    np.testing.assert_allclose(dg_dr, eq10, rtol=3e-3)
    assert np.all(r[1:] < profile.follower_radius_mm[1:])  # friction takes work: less stroke
    # Eq. 10: tan α = r γ' = μ + 2 F_k r / T >= μ, so the guides never self-lock
    assert np.all(np.tan(prof.alpha_rad) >= mu)
    tiny = synthesise_cam(PROTOTYPE, SPRINGS, CamLayout(20.0, 5.0, friction=1e-9))
    np.testing.assert_allclose(tiny.follower_radius_mm, profile.follower_radius_mm, atol=2e-4)


def test_eq5_contact_points_lie_on_the_plate(profile, plate):
    # up to 85°: at the lobe (90°) the plate is rounded where the roller cannot reach
    keep = profile.rotation_rad <= math.radians(85)
    points = shapely.points(profile.contact_points_mm[keep])
    distance = shapely.distance(plate.exterior, points)
    assert np.max(distance) < 2e-3  # mm, the polygonised roller arcs
    assert not profile.undercut
    r = follower_radius_from_outline(plate, 5.0, profile.rotation_rad[10:-10:30])
    np.testing.assert_allclose(r, profile.follower_radius_mm[10:-10:30], atol=1e-3)


def test_stl_is_one_watertight_plate_of_the_outline_volume(profile, plate):
    mesh = trimesh.load(io.BytesIO(cam_stl(profile)), file_type="stl")
    assert mesh.is_watertight and mesh.body_count == 1
    assert mesh.volume == pytest.approx(plate.area * LAYOUT.thickness_mm, rel=1e-6)
    assert len(plate.interiors) == 1  # the bore


def test_contact_pressure_is_hertz_line_contact(profile):
    p = contact_pressure_MPa(profile, 2300.0, 0.35)
    i = 200
    e_star = 1 / ((1 - 0.35**2) / 2300.0 + (1 - 0.3**2) / 210_000.0)
    radius = profile.profile_radius_mm[i]
    inv_r = 1 / 5.0 + 1 / radius
    line_load = profile.contact_force_N[i] / LAYOUT.thickness_mm
    expected = math.sqrt(line_load * e_star * inv_r / math.pi)
    assert p[i] == pytest.approx(expected, rel=1e-12)


def test_corrected_curve_eq17_and_its_work():
    corr = CorrectedCurve(PROTOTYPE, (1.001, -0.0369, 2.588))
    assert float(corr(0.3)) == pytest.approx(
        float(PROTOTYPE(0.3)) * (1.001 - 0.0369 * 0.3 + 2.588 * 0.09)
    )
    exact, _ = quad(lambda u: float(corr(u)), 0, 1.2, epsrel=1e-12, limit=200)
    assert float(corr.work(1.2)) == pytest.approx(exact, rel=1e-7)


def test_sab_ratio_eq15_its_limit_eq16_with_r1_over_r2_and_the_series():
    a, R, q = 15.0, 30.0, 7.5
    assert float(sab_ratio(0.0, a, R, q)) == pytest.approx(q * a / (R - a), rel=1e-14)
    assert sab_ratio_ideal(a, R, q) == pytest.approx(7.5)  # Eq. 16 as printed gives 1.0
    th = np.array([0.01, 0.02, 0.04])
    err = np.abs(sab_ratio(th, a, R, q) - sab_ratio_series(th, a, R, q))
    assert np.all(err / th**4 < 2 * err[0] / th[0] ** 4 + 1e-9)  # O(θ⁴): the θ² term is right
    assert err[-1] < 1e-3 * sab_ratio_ideal(a, R, q)
    assert sab_limits(a, R, q) > 0
    with pytest.raises(GeometryError, match="Eq. 15a"):
        sab_ratio(0.0, 1.0, R, q)


def test_fit_correction_flattens_the_joint_torque():
    coef, info = fit_correction(PROTOTYPE, 15.0, 30.0, 7.5, math.radians(12))
    assert info["max_relative_error_corrected"] < 0.2 * info["max_relative_error_uncorrected"]
    assert coef[0] == pytest.approx(1.0, abs=0.01)  # mode I untouched, as the paper intends


def test_slack_springs_and_bad_layouts_are_refused_with_the_fix():
    with pytest.raises(GeometryError, match="slack at rest.*raise rest_radius_mm"):
        synthesise_cam(PROTOTYPE, CamSprings(4.0, 30.0, 10.0), LAYOUT)
    with pytest.raises(GeometryError, match="at most|must lie in"):
        CamLayout(20.0, 5.0, followers=3, max_rotation_rad=math.radians(90))
    with pytest.raises(GeometryError, match="roller would reach"):
        CamLayout(5.0, 6.0)
