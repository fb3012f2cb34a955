"""The calibration coupon's predicted curve against the elastica computed here (solve_bvp)."""

import dataclasses

import numpy as np
import pytest
from flexopt.fea.coupon import CouponSpec, coupon_curves, coupon_stroke_mm, strip_curve
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import get_material
from scipy.integrate import solve_bvp


def elastica_tip_deflection(P_N, EI_Nmm2, L_mm):
    """Tip deflection (mm) of an inextensible, shear-rigid cantilever under a tip load P normal to
    the undeformed strip, of fixed direction: EI theta'' = -P cos(theta), theta(0) = 0,
    theta'(L) = 0; deflection = int_0^L sin(theta) ds (Bisshopp & Drucker 1945)."""
    lam = P_N / EI_Nmm2

    def rhs(s, y):  # y = [theta, theta', v]
        return np.vstack([y[1], -lam * np.cos(y[0]), np.sin(y[0])])

    def bc(ya, yb):
        return np.array([ya[0], yb[1], ya[2]])

    s = np.linspace(0.0, L_mm, 201)
    # start from the small-deflection shape
    th = lam * (L_mm * s - s**2 / 2)
    y0 = np.vstack([th, lam * (L_mm - s), lam * (L_mm * s**2 / 2 - s**3 / 6)])
    sol = solve_bvp(rhs, bc, s, y0, tol=1e-10, max_nodes=100000)
    assert sol.success, sol.message
    return float(sol.sol(L_mm)[2])


def test_strip_curve_matches_the_elastica():
    spec = CouponSpec(thicknesses_mm=(0.8, 1.6), length_mm=40.0, width_mm=10.0)
    mat = get_material("PETG")
    t = 0.8
    c = strip_curve(spec, mat, t, stroke_mm=12.0)  # 0.3 L: clearly nonlinear
    EI = mat.E_MPa * spec.width_mm * t**3 / 12.0
    # the force at the stroke is well above the linear estimate 3 EI d / L^3 (the lever arm of a
    # tip load of fixed direction shortens as the strip bends), so the case is large-deflection
    linear = 3 * EI * 12.0 / spec.length_mm**3
    assert c.force_N[-1] > 1.05 * linear
    for k in (5, 20, len(c.force_N) - 1):
        d = elastica_tip_deflection(c.force_N[k], EI, spec.length_mm)
        # the beam model adds shear and axial strain, O((t/L)^2) = 4e-4 here
        assert d == pytest.approx(c.displacement_mm[k], rel=1e-3)


def test_strip_curve_converges_under_refinement():
    mat = get_material("ABS")
    f = []
    for n in (10, 20, 40):
        spec = CouponSpec(length_mm=40.0, n_elements=n)
        f.append(strip_curve(spec, mat, 1.2, 10.0).force_N[-1])
    assert abs(f[2] - f[1]) < abs(f[1] - f[0]) or abs(f[2] - f[1]) < 1e-9 * f[2]
    assert f[2] == pytest.approx(f[1], rel=1e-6)


def test_force_is_linear_in_E_at_fixed_displacement():
    spec = CouponSpec()
    mat = get_material("PLA")
    a = strip_curve(spec, mat, 1.0, 8.0)
    b = strip_curve(spec, dataclasses.replace(mat, E_MPa=2 * mat.E_MPa), 1.0, 8.0)
    np.testing.assert_allclose(b.force_N, 2 * a.force_N, rtol=1e-9, atol=1e-12)


def test_stroke_keeps_the_thickest_strip_elastic():
    spec = CouponSpec()
    mat = get_material("ABS")
    stroke, curves = coupon_curves(spec, mat)
    assert stroke == coupon_stroke_mm(spec, mat)
    assert stroke <= spec.max_stroke_fraction * spec.length_mm
    assert max(c.peak_stress_MPa.max() for c in curves) <= spec.stress_fraction * mat.yield_MPa
    # a stroke given too large is refused with the stroke to use
    with pytest.raises(FeaError, match="smaller stroke_mm"):
        coupon_curves(dataclasses.replace(spec, stroke_mm=12.0), mat)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"thicknesses_mm": (1.0,)}, "two different"),
        ({"thicknesses_mm": (1.0, 1.0)}, "two different"),
        ({"thicknesses_mm": (1.0, -1.0)}, "two different"),
        ({"length_mm": 5.0}, "slender"),
        ({"stroke_mm": 0.0}, "stroke_mm"),
        ({"steps": 2}, "steps"),
    ],
)
def test_bad_coupon_specs_are_refused(kwargs, match):
    with pytest.raises(FeaError, match=match):
        CouponSpec(**kwargs)
