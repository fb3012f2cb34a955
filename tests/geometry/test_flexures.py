"""Flexure pivots: generators, closed forms and the FE that judges them.

The closed forms are written out here again (not imported) where a test checks them, so a typo in
fea/closed_forms.py cannot pass by agreeing with itself. Leaves are checked against the beam model
(pure moment through fea.constrained_beams, tip force through fea.beam), notch hinges against
plane stress; the measured differences are the numbers docs/flexures.md quotes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive, solve_beam
from flexopt.fea.closed_forms import (
    PRB_GAMMA,
    circular_notch_compliance,
    circular_notch_compliance_simplified,
    elliptical_notch_compliance,
    elliptical_notch_compliance_simplified,
    pivot_closed_form,
)
from flexopt.fea.constrained_beams import ConstrainedBeams
from flexopt.fea.materials import Material
from flexopt.fea.pivot import beam_pivot, plane_stress_pivot, pure_moment_centre
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.flexures import (
    FLEXURES,
    CircularNotch,
    CornerFilleted,
    CrossAxis,
    EllipticalNotch,
    Leaf,
    VariableLeaf,
    make_flexure,
)
from flexopt.geometry.profile import BeamProfile
from flexopt.geometry.solid import extrude, min_feature_mm
from scipy.integrate import quad
from scipy.optimize import brentq

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
E = MAT.E_MPa


def ei(b: float, t: float) -> float:
    return E * b * t**3 / 12.0


# ---- the constrained beam solver ----------------------------------------------------------


def pure_moment_leaf(L=20.0, t=0.5, b=10.0, n=20):
    model = BeamModel(
        BeamProfile([[0.0, 0.0], [L, 0.0]], [t, t], b), MAT, "clamped", BeamSettings(n_elements=n)
    )

    def constraints(theta):
        C = system.rows(4)
        row = system.clamp_start(C, 0, 0)
        C[row, system.dof(0, -1, 2)] = 1.0
        return C, np.array([0.0, 0.0, 0.0, theta])

    system = ConstrainedBeams([model], 0, constraints)
    return system


def test_pure_moment_bends_a_leaf_into_the_exact_circle():
    # A pure moment gives uniform curvature theta / L: M = E I theta / L and the end on the arc
    # (L sin(theta) / theta, L (1 - cos(theta)) / theta), at any rotation.
    L, t, b = 20.0, 0.5, 10.0
    system = pure_moment_leaf(L, t, b)
    theta = np.linspace(0.0, 1.5, 4)
    res = system.solve(theta)
    assert res.ok
    th = theta[1:]
    np.testing.assert_allclose(res.end_force(0)[1:, 2], ei(b, t) * th / L, rtol=1e-9)
    end = np.array([L, 0.0]) + res.end(0)[1:, :2]
    np.testing.assert_allclose(end[:, 0], L * np.sin(th) / th, rtol=1e-7)
    np.testing.assert_allclose(end[:, 1], L * (1 - np.cos(th)) / th, rtol=1e-7)
    # the end node's force is the multiplier of its rotation row: a couple, no force
    np.testing.assert_allclose(res.multipliers[1:, 3], res.end_force(0)[1:, 2], rtol=1e-12)
    assert np.abs(res.end_force(0)[1:, :2]).max() < 1e-8


def test_constrained_tangent_matches_finite_differences():
    system = pure_moment_leaf(n=6)
    z = system.solve([0.0, 0.8]).states[-1]
    r, K = system._assemble(z)
    K = K.toarray()
    h = 1e-7
    fd = np.empty_like(K)
    for j in range(system.n):
        dz = np.zeros(system.n)
        dz[j] = h
        fd[:, j] = (system._assemble(z + dz)[0] - system._assemble(z - dz)[0]) / (2 * h)
    assert np.abs(fd - K).max() <= 1e-6 * np.abs(K).max()


# ---- leaves ---------------------------------------------------------------------------------


def test_leaf_pivot_is_EI_over_L_with_the_leaf_stress():
    f = Leaf(length_mm=12.0, thickness_mm=0.6, width_mm=5.0)
    res = beam_pivot(f, MAT, math.radians(40.0), 4)
    K = ei(5.0, 0.6) / 12.0  # Howell's small-length flexural pivot
    assert res.ok
    assert res.small_angle_stiffness_Nmm_per_rad == pytest.approx(K, rel=1e-9)
    np.testing.assert_allclose(res.torque_Nmm[1:], K * res.rotation_rad[1:], rtol=1e-9)
    sigma = E * 0.6 * res.rotation_rad / (2 * 12.0)
    np.testing.assert_allclose(res.peak_stress_MPa[1:], sigma[1:], rtol=2e-3)
    # the block turns about a point that wanders: the centre shift of a circular arc, about
    # L theta^2 / 12 along the leaf (second order)
    th = res.rotation_rad[-1]
    x = 12.0 * np.sin(th) / th - 6.0 * np.cos(th)
    y = 12.0 * (1 - np.cos(th)) / th - 6.0 * np.sin(th)
    assert res.centre_shift_mm[-1] == pytest.approx(math.hypot(x - 6.0, y), rel=1e-6)
    assert pivot_closed_form(f, E).stiffness_Nmm_per_rad == pytest.approx(K, rel=1e-14)


def test_long_leaf_prb_model_against_the_beam():
    # Howell's 1R PRB model of a cantilever with a tip force perpendicular to it: the tip runs on
    # a circle of radius gamma L about a pivot (1 - gamma) L from the clamp, gamma = 0.85, and the
    # torsion spring is gamma K_Theta E I / L, K_Theta = 2.65 (an average: 3 gamma = 2.55 at
    # small angles, rising with the angle).
    L, t, b = 50.0, 0.25, 5.0
    alpha = 8.0
    P = alpha * ei(b, t) / L**2
    res = solve_beam(
        BeamProfile([[0.0, 0.0], [L, 0.0]], [t, t], b),
        MAT,
        EndDrive("force", (0.0, 1.0), P, steps=16, rotation="free", transverse="free"),
        settings=BeamSettings(n_elements=40),
    )
    assert res.ok
    y = res.displacement_mm
    x = L - res.transverse_displacement_mm  # the transverse axis is (-1, 0)
    pivot = (1.0 - PRB_GAMMA) * L
    theta = np.arctan2(y, x - pivot)
    k = (theta > math.radians(25)) & (theta < math.radians(62))
    assert k.sum() >= 5
    # the path: distance from the PRB pivot stays gamma L within 0.5 % of L
    radius = np.hypot(x - pivot, y)
    assert np.abs(radius[k] - PRB_GAMMA * L).max() < 5e-3 * L
    # the spring: the tip force's moment about the pivot over the PRB angle
    with np.errstate(invalid="ignore"):  # row 0: 0 / 0
        K_theta = res.force_N * (x - pivot) / theta * L / (PRB_GAMMA * ei(b, t))
    assert np.all((K_theta[k] > 2.58) & (K_theta[k] < 2.78))
    assert abs(np.mean(K_theta[k]) / 2.65 - 1.0) < 0.03
    small = res.force_N[1] * (x[1] - pivot) / theta[1] * L / (PRB_GAMMA * ei(b, t))
    assert small == pytest.approx(3 * PRB_GAMMA, rel=0.01)


def test_variable_leaf_compliance_integral_and_beam():
    # theta / M = int 12 ds / (E b t(s)^3) for a thickness linear between stations: each segment
    # of length h from t1 to t2 gives 12 h (t1 + t2) / (2 E b t1^2 t2^2).
    f = VariableLeaf(length_mm=16.0, thicknesses_mm=(1.2, 0.6, 0.9, 1.5), width_mm=4.0)
    t = np.array([1.2, 0.6, 0.9, 1.5])
    h = 16.0 / 3
    C = np.sum(12 * h * (t[:-1] + t[1:]) / (2 * E * 4.0 * t[:-1] ** 2 * t[1:] ** 2))
    numeric = quad(
        lambda s: 12.0 / (E * 4.0 * np.interp(s, [0, h, 2 * h, 3 * h], t) ** 3),
        0,
        16.0,
        points=[h, 2 * h],
        epsrel=1e-12,
    )[0]
    assert C == pytest.approx(numeric, rel=1e-10)
    cf = pivot_closed_form(f, E)
    assert cf.stiffness_Nmm_per_rad == pytest.approx(1.0 / C, rel=1e-12)
    res = beam_pivot(f, MAT, math.radians(10.0), 2, n_elements=60)
    # the beam adds shear compliance, O((t/L)^2)
    assert res.small_angle_stiffness_Nmm_per_rad == pytest.approx(1.0 / C, rel=2e-3)


# ---- notch hinges: closed forms ---------------------------------------------------------------


@pytest.mark.parametrize(("R", "t"), [(2.0, 0.5), (5.0, 0.2), (1.0, 1.0), (3.0, 0.05)])
def test_paros_weisbord_exact_is_the_profile_integral(R, t):
    b = 5.0

    def thickness(x):
        return t + 2 * R - 2 * math.sqrt(max(R * R - x * x, 0.0))

    integral = (
        12
        / (E * b)
        * quad(lambda x: thickness(x) ** -3, -R, R, points=[0.0], epsrel=1e-13, limit=200)[0]
    )
    assert circular_notch_compliance(E, b, R, t) == pytest.approx(integral, rel=1e-11)
    simplified = 9 * math.pi * math.sqrt(R) / (2 * E * b * t**2.5)
    assert circular_notch_compliance_simplified(E, b, R, t) == pytest.approx(simplified, rel=1e-14)


def test_paros_weisbord_simplified_tends_to_exact_for_thin_webs():
    ratios = [
        circular_notch_compliance_simplified(E, 5, 5.0, t) / circular_notch_compliance(E, 5, 5.0, t)
        for t in (2.0, 0.5, 0.05, 0.005)
    ]
    assert ratios[0] > ratios[1] > ratios[2] > ratios[3] > 1.0
    assert ratios[-1] - 1.0 < 1e-3


def test_elliptical_notch_reduces_to_circular_and_its_thin_limit():
    assert elliptical_notch_compliance(E, 5, 2.0, 2.0, 0.4) == pytest.approx(
        circular_notch_compliance(E, 5, 2.0, 0.4), rel=1e-10
    )
    a, c = 6.0, 1.5
    ratio = elliptical_notch_compliance_simplified(E, 5, a, c, 0.01) / elliptical_notch_compliance(
        E, 5, a, c, 0.01
    )
    assert ratio == pytest.approx(1.0, abs=5e-3)


def test_corner_filleted_is_web_plus_one_circular_notch_and_tends_to_a_leaf():
    f = CornerFilleted(length_mm=6.0, fillet_radius_mm=1.5, thickness_mm=0.7, width_mm=5.0)
    C = 12 * 6.0 / (E * 5.0 * 0.7**3) + circular_notch_compliance(E, 5.0, 1.5, 0.7)
    assert 1.0 / pivot_closed_form(f, E).stiffness_Nmm_per_rad == pytest.approx(C, rel=1e-12)
    tiny = CornerFilleted(length_mm=6.0, fillet_radius_mm=1e-4, thickness_mm=0.7, width_mm=5.0)
    leaf = ei(5.0, 0.7) / 6.0
    assert pivot_closed_form(tiny, E).stiffness_Nmm_per_rad == pytest.approx(leaf, rel=1e-3)


@pytest.mark.parametrize(
    "flexure",
    [
        CircularNotch(radius_mm=3.0, thickness_mm=0.6, width_mm=5.0),
        EllipticalNotch(half_length_mm=4.0, depth_mm=1.5, thickness_mm=0.6, width_mm=5.0),
        CornerFilleted(length_mm=4.0, fillet_radius_mm=1.0, thickness_mm=0.6, width_mm=5.0),
    ],
    ids=lambda f: f.kind,
)
def test_notch_equivalent_beam_reproduces_the_profile_integral(flexure):
    # The piecewise-linear equivalent beam sits slightly outside the convex profile (chords), so
    # it is a little stiffer; the Reissner beam adds shear.
    res = beam_pivot(flexure, MAT, 0.05, 1)
    cf = pivot_closed_form(flexure, E)
    assert res.small_angle_stiffness_Nmm_per_rad / cf.stiffness_Nmm_per_rad == pytest.approx(
        1.0, abs=6e-3
    )


# ---- notch hinges: plane stress ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("flexure", "k_range", "kt_tol"),
    [
        # Paros-Weisbord is stiffer than 2D elasticity, more so for thicker webs (t/R = 0.27: -8 %)
        (CircularNotch(radius_mm=3.0, thickness_mm=0.8, width_mm=5.0), (0.90, 0.94), 0.03),
        (
            EllipticalNotch(half_length_mm=4.0, depth_mm=2.0, thickness_mm=0.8, width_mm=5.0),
            (0.94, 0.99),
            0.03,
        ),
        # the fillet K_t estimate (circular-notch fit at rho = r) is conservative here (+4 %)
        (
            CornerFilleted(length_mm=4.0, fillet_radius_mm=1.0, thickness_mm=0.8, width_mm=5.0),
            (0.95, 0.99),
            0.07,
        ),
    ],
    ids=lambda v: getattr(v, "kind", ""),
)
def test_notch_closed_forms_against_plane_stress(flexure, k_range, kt_tol):
    res = plane_stress_pivot(flexure, MAT, 0.01, 1, kinematics="linear")
    cf = pivot_closed_form(flexure, E)
    K = res.small_angle_stiffness_Nmm_per_rad
    assert k_range[0] < K / cf.stiffness_Nmm_per_rad < k_range[1]
    # stress per unit moment: the nominal 6 M / (b t^2) times K_t, against the surface peak
    nominal = 6 * res.torque_Nmm[-1] / (flexure.width_mm * flexure.thickness_mm**2)
    kt_fe = res.peak_stress_MPa[-1] / nominal
    assert kt_fe == pytest.approx(cf.stress_concentration, abs=kt_tol)
    # turning about the nominal centre needs (almost) no force: it is where the hinge turns
    assert res.centre_force_N[-1] * flexure.notch_length < 2e-2 * res.torque_Nmm[-1]


def test_plane_stress_leaf_about_the_beam_centre_is_a_pure_moment():
    # Turned about the nominal centre by 20 deg a long leaf is stretched (its free rotation
    # centre wanders by L theta^2 / 12): three times the torque, 38 N on the centre (measured).
    # Turned about the point that reproduces the beam's pure moment it carries the beam's torque
    # with almost no force.
    f = Leaf(length_mm=16.0, thickness_mm=1.0, width_mm=4.0)
    rom = math.radians(20.0)
    beam = beam_pivot(f, MAT, rom, 2)
    centre = pure_moment_centre(f.centre_mm, rom, beam.centre_displacement_mm[-1])
    ps = plane_stress_pivot(f, MAT, rom, 2, "nonlinear", centre_mm=centre)
    assert ps.ok
    assert ps.torque_Nmm[-1] / beam.torque_Nmm[-1] == pytest.approx(1.0, abs=0.02)
    # force x length against torque: 6 % here, and 4500 % about the nominal centre
    assert ps.centre_force_N[-1] * f.length_mm < 0.1 * ps.torque_Nmm[-1]
    # the surface stress is the beam's plus the root corners' concentration
    assert ps.peak_stress_MPa[-1] / beam.peak_stress_MPa[-1] == pytest.approx(1.04, abs=0.03)


# ---- cross-axis pivot -------------------------------------------------------------------------


def test_cross_axis_pivot_stiffness_and_centre():
    # Wittrick / Jensen & Howell with no force: K = 2 E I / L, each leaf in pure bending.
    f = CrossAxis(length_mm=14.0, thickness_mm=0.6, width_mm=5.0)
    res = beam_pivot(f, MAT, math.radians(15.0), 3)
    K = 2 * ei(5.0, 0.6) / 14.0
    assert res.small_angle_stiffness_Nmm_per_rad == pytest.approx(K, rel=1e-6)
    assert pivot_closed_form(f, E).stiffness_Nmm_per_rad == pytest.approx(K, rel=1e-14)
    # Centre shift, second order: a leaf bent into an arc moves the block point at its middle by
    # L theta^2 / 12 along the leaf (see test_leaf_pivot...). The leaves barely stretch, so the
    # crossing moves by s with s . d_i = L theta^2 / 12 for both leaf directions
    # d_i = (+-cos a, sin a): s = (0, L theta^2 / (12 sin a)) -- sqrt(2) times a single leaf of
    # the same length, 2 sqrt(2) times a single leaf of the same stiffness (L / 2).
    th = res.rotation_rad[1:]
    expected = 14.0 * th**2 / (12 * math.sin(math.radians(45.0)))
    np.testing.assert_allclose(res.centre_shift_mm[1:], expected, rtol=0.02)
    # sideways it moves only at third order (the leaves' L theta^3 / 24 across themselves)
    sideways = np.abs(res.centre_displacement_mm[1:, 0]) / th**3
    assert sideways.max() / sideways.min() < 1.02
    with pytest.raises(Exception, match="separate layers"):
        plane_stress_pivot(f, MAT, 0.01, 1)


# ---- generators ---------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", sorted(FLEXURES))
def test_every_planar_outline_extrudes_watertight_with_its_web(kind):
    f = make_flexure(kind, thickness_mm=0.9, width_mm=4.0)
    outline = f.outline()
    assert outline.is_valid
    (profile,) = f.beams()[:1]
    assert profile.width_mm == 4.0
    if not f.is_planar:
        assert len(f.beams()) == 2
        return
    solid = extrude(outline, f.width_mm)
    assert solid.is_watertight
    assert min_feature_mm(outline) == pytest.approx(f.min_thickness_mm, abs=0.02)
    # the blocks are inside the outline and apart
    assert outline.buffer(1e-6).contains(f.ground_block())
    assert outline.buffer(1e-6).contains(f.moving_block())
    assert f.ground_block().distance(f.moving_block()) > 0


def test_notch_profiles_follow_their_formulas():
    c = CircularNotch(radius_mm=2.0, thickness_mm=0.5)
    x = np.array([0.0, 1.0, 2.0])
    np.testing.assert_allclose(c.thickness_at(x), 0.5 + 4.0 - 2 * np.sqrt(4.0 - x**2))
    e = EllipticalNotch(half_length_mm=3.0, depth_mm=1.0, thickness_mm=0.5)
    np.testing.assert_allclose(e.thickness_at(np.array([0.0, 3.0])), [0.5, 2.5])
    assert e.root_radius_mm == pytest.approx(9.0)
    f = CornerFilleted(length_mm=4.0, fillet_radius_mm=1.0, thickness_mm=0.5)
    np.testing.assert_allclose(f.thickness_at(np.array([0.0, 2.0, 3.0])), [0.5, 0.5, 2.5])
    assert f.notch_length == 6.0 and f.natural_height == 2.5


@pytest.mark.parametrize(
    ("kind", "params", "words"),
    [
        ("leaf", {"thickness_mm": -1.0}, "thickness_mm = -1"),
        ("circular_notch", {"radius_mm": 0.0}, "radius_mm"),
        ("cross_axis", {"half_angle_deg": 85.0}, "half_angle_deg"),
        ("variable_leaf", {"thicknesses_mm": (1.0,)}, "at least 2"),
        ("leaf", {"block_height_mm": 0.2, "thickness_mm": 0.5}, "block_height_mm"),
        ("spiral", {}, "unknown flexure kind"),
        ("leaf", {"radius_mm": 2.0}, "no parameter 'radius_mm'"),
    ],
)
def test_bad_parameters_name_themselves(kind, params, words):
    with pytest.raises(GeometryError, match=words):
        make_flexure(kind, **params)


def test_closed_form_centre_is_the_geometric_middle():
    for f in (Leaf(length_mm=8.0), CircularNotch(radius_mm=2.0), CrossAxis()):
        x0, _, x1, _ = f.outline().bounds
        if f.is_planar:
            B = f.block_length_mm
            assert f.centre_mm[0] == pytest.approx(0.5 * (x0 + B + x1 - B))
        else:
            assert np.allclose(f.centre_mm, 0.0)


def test_prb_load_for_angle_inverts_the_spring():
    from flexopt.fea.closed_forms import (
        prb_cantilever_load_for_angle_N,
        prb_cantilever_stiffness_Nmm,
    )

    P = prb_cantilever_load_for_angle_N(E, 5.0, 0.3, 40.0, 0.6)
    K = prb_cantilever_stiffness_Nmm(E, 5.0, 0.3, 40.0)
    assert brentq(lambda th: K * th - P * PRB_GAMMA * 40.0 * math.cos(th), 0, 1.5) == (
        pytest.approx(0.6, rel=1e-10)
    )
