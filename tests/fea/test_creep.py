"""Findley power-law creep and its relaxation (fea/creep.py).

Every expected value is computed in the test: the Mittag-Leffler function against its closed
forms (E_1(-x) = exp(-x), E_1/2(-x) = exp(x^2) erfc(x)), its power series and its large-x
asymptote; the interconversion of the creep compliance and the relaxation modulus against the
Volterra identity int_0^t E_R(t - s) dJ(s) = 1 and its Laplace transform s^2 J(s) E(s) = 1,
both evaluated numerically here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.creep import (
    CreepLaw,
    crept_drive,
    fit_creep,
    fit_relaxation,
    mittag_leffler,
    relaxed_force,
)
from flexopt.fea.errors import FeaError
from scipy import integrate, special


def law(n: float = 0.3, tau_h: float = 50.0, **kw) -> CreepLaw:
    return CreepLaw(tau_h=tau_h, n=n, max_stress_ratio=0.5, source="test", **kw)


@pytest.mark.parametrize("x", [0.0, 1e-6, 0.2, 0.5, 0.51, 1.0, 3.0, 10.0, 1e3, 1e6])
def test_mittag_leffler_half_is_the_scaled_complementary_error_function(x):
    assert mittag_leffler(0.5, -x) == pytest.approx(special.erfcx(x), rel=1e-12, abs=1e-300)


@pytest.mark.parametrize("x", [0.0, 0.3, 2.0, 40.0])
def test_mittag_leffler_one_is_the_exponential(x):
    assert mittag_leffler(1.0, -x) == pytest.approx(math.exp(-x), rel=1e-14)
    # and the order just below 1 tends to it (the integral branch, a peaked spectrum) while
    # the power-law tail x^-1/Gamma(1 - alpha), 1e-4/x here, is below exp(-x)
    if x <= 2.0:
        assert mittag_leffler(0.9999, -x) == pytest.approx(math.exp(-x), rel=2e-3)


@pytest.mark.parametrize("alpha", [0.15, 0.3, 0.6, 0.9])
@pytest.mark.parametrize("x", [0.6, 1.0])
def test_mittag_leffler_integral_equals_the_series_where_both_hold(alpha, x):
    series = sum(
        (-1) ** k * math.exp(k * math.log(x) - math.lgamma(alpha * k + 1.0)) for k in range(400)
    )
    assert mittag_leffler(alpha, -x) == pytest.approx(series, rel=1e-10)


@pytest.mark.parametrize("alpha", [0.2, 0.5, 0.8])
def test_mittag_leffler_large_argument_asymptote(alpha):
    # E_a(-x) = x^-1/Gamma(1-a) - x^-2/Gamma(1-2a) + O(x^-3)
    x = 1.0e4
    two = special.rgamma(1 - alpha) / x - special.rgamma(1 - 2 * alpha) / (x * x)
    assert mittag_leffler(alpha, -x) == pytest.approx(two, rel=1e-7)


def test_mittag_leffler_is_vectorised_and_refuses_what_it_does_not_do():
    z = -np.array([[0.1, 1.0], [5.0, 50.0]])
    out = mittag_leffler(0.4, z)
    assert out.shape == (2, 2)
    assert np.all(np.diff(out.ravel()) < 0)  # completely monotone: decreasing in -z
    with pytest.raises(FeaError, match="order"):
        mittag_leffler(1.5, -1.0)
    with pytest.raises(FeaError, match="z <= 0"):
        mittag_leffler(0.5, 1.0)


def test_small_time_relaxation_follows_the_series():
    # E_R/E0 = 1 - (t/tau)^n + Gamma(1+n)^2/Gamma(1+2n) (t/tau)^(2n) - ...
    c = law(n=0.4, tau_h=10.0)
    for t in (1e-6, 1e-4):
        u = (t / c.tau_h) ** c.n
        two = 1.0 - u + math.gamma(1.4) ** 2 / math.gamma(1.8) * u * u
        assert c.relaxation_ratio(t) == pytest.approx(two, abs=5 * u**3)
        assert c.compliance_ratio(t) == pytest.approx(1.0 + u, rel=1e-15)


def test_n_one_is_the_maxwell_like_law():
    c = law(n=1.0, tau_h=5.0)
    for t in (0.0, 1.0, 5.0, 20.0):
        assert c.relaxation_ratio(t) == pytest.approx(math.exp(-t / 5.0), rel=1e-14)
        assert c.compliance_ratio(t) == pytest.approx(1.0 + t / 5.0, rel=1e-15)


@pytest.mark.parametrize("n", [0.2, 0.5, 0.8])
@pytest.mark.parametrize("t", [0.3, 40.0, 2000.0])
def test_volterra_identity_of_the_interconversion(n, t):
    """int_0^t E_R(t-s) dJ(s) = 1 with the jump J(0) = 1/E0: in ratios,
    r(t) + int_0^t r(t-s) n s^(n-1) / tau^n ds = 1 (r = E_R/E0)."""
    c = law(n=n, tau_h=50.0)

    def r_of(s: float) -> float:
        return float(c.relaxation_ratio(t - s)) * n / c.tau_h**n

    # the weight s^(n-1) integrated exactly (QAWS), the rest smooth
    val, _ = integrate.quad(r_of, 0.0, t, weight="alg", wvar=(n - 1.0, 0.0), limit=200)
    assert float(c.relaxation_ratio(t)) + val == pytest.approx(1.0, abs=2e-9)


def test_laplace_identity_of_the_interconversion():
    """s^2 J(s) E(s) = 1 (the transform of the Volterra identity; s J(s) and s E(s) are the
    Carson transforms, whose product is 1): J(s) = (1/E0)(1/s + Gamma(1+n) tau^-n s^-(n+1))
    by hand, E(s) the transform of E0 r(t) by quadrature."""
    c = law(n=0.35, tau_h=20.0)
    for s in (0.01, 0.5):

        def weighted(t: float, s: float = s) -> float:
            return math.exp(-s * t) * float(c.relaxation_ratio(t))

        parts = ((0.0, 1.0), (1.0, 100.0), (100.0, 1e4), (1e4, np.inf))
        e_bar = sum(integrate.quad(weighted, a, b, limit=200, epsabs=1e-13)[0] for a, b in parts)
        j_bar = 1.0 / s + math.gamma(1.35) * c.tau_h**-0.35 * s**-1.35
        assert s * s * j_bar * e_bar == pytest.approx(1.0, abs=1e-7)


def test_temperature_shift_arrhenius_and_wlf():
    ea = law(activation_energy_kJ_mol=100.0)
    log_a = 100e3 / (8.314462618 * math.log(10)) * (1 / (333.15) - 1 / (296.15))
    assert ea.reduced_time(2.0, 60.0) == pytest.approx(2.0 / 10**log_a, rel=1e-12)
    assert ea.reduced_time(2.0, 60.0) > 2.0  # warmer: faster
    wlf = law(wlf_C1=17.44, wlf_C2=51.6)
    assert wlf.reduced_time(1.0, 33.0) == pytest.approx(10 ** (17.44 * 10 / 61.6), rel=1e-12)
    assert law().reduced_time(3.0, 23.2) == 3.0  # at the reference
    with pytest.raises(FeaError, match="time-temperature shift"):
        law().reduced_time(1.0, 60.0)


def test_bad_laws_are_refused():
    with pytest.raises(FeaError, match="n = "):
        law(n=1.2)
    with pytest.raises(FeaError, match="tau_h"):
        law(tau_h=0.0)
    with pytest.raises(FeaError, match="both wlf"):
        law(wlf_C1=17.0)


def test_relaxed_force_and_crept_drive_of_a_linear_spring():
    # a linear spring F = k x: the held force scales by r; the crept drive by E0 J exactly
    x = np.linspace(0.0, 10.0, 11)
    f = 2.0 * x
    assert relaxed_force(f, 0.8) == pytest.approx(1.6 * x)
    x0, x1 = crept_drive(x, f, 6.0, 1.25)
    assert (x0, x1) == pytest.approx((3.0, 3.75))
    x0, x1 = crept_drive(-x, -f, -6.0, 1.25)  # the negative branch
    assert (x0, x1) == pytest.approx((-3.0, -3.75))
    with pytest.raises(FeaError, match="beyond the traced curve"):
        crept_drive(x, f, 18.0, 1.25)
    with pytest.raises(FeaError, match="not rising"):
        crept_drive(x, np.array([0, 2, 4, 3, 5, 6, 7, 8, 9, 10, 11.0]), 4.5, 1.0)


def test_a_relaxation_record_gives_back_its_law():
    true = law(n=0.3, tau_h=400.0)
    t = np.array([0.0, 0.01, 0.1, 0.5, 1, 2, 5, 10, 24, 48, 100])
    f = 2.5 * true.relaxation_ratio(t)
    fit = fit_relaxation(t, f)
    assert (fit.tau_h, fit.n, fit.initial) == pytest.approx((400.0, 0.3, 2.5), rel=1e-6)
    assert fit.rms < 1e-9
    assert fit.law(0.3, "coupon").relaxation_ratio(50.0) == pytest.approx(
        true.relaxation_ratio(50.0), rel=1e-6
    )
    with pytest.raises(FeaError, match="does not fall"):
        fit_relaxation(t, np.full(t.size, 2.0))


def test_a_creep_record_gives_back_its_law():
    t = np.array([0.0, 0.1, 0.5, 1, 2, 5, 10, 20, 50])
    eps0, m, n = 0.004, 0.0005, 0.28  # Findley: eps = eps0 + m t^n
    fit = fit_creep(t, eps0 + m * t**n)
    assert fit.n == pytest.approx(n, rel=1e-6)
    assert fit.initial == pytest.approx(eps0, rel=1e-6)
    assert fit.tau_h == pytest.approx((eps0 / m) ** (1 / n), rel=1e-5)
    with pytest.raises(FeaError, match="at least 4"):
        fit_creep([0, 1], [1, 2])
