"""The closed-form elastica against linear theory and an independent BVP solution."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from flexopt.fea.elastica import (
    _legendre_state,
    cantilever_load_for_deflection,
    cantilever_tip_load,
    fixed_guided,
)
from flexopt.fea.errors import FeaError
from scipy.integrate import solve_bvp


def _bvp_cantilever(alpha: float) -> tuple[float, float, float]:
    """(θ0, δ/L, x_tip/L) from x' = cos θ, y' = sin θ, θ' = m/EI, m' = -P cos θ on L = EI = 1.

    Clamped at s = 0 (x = y = θ = 0), moment-free at the tip (m(1) = 0). The load is raised in
    a few steps so the Newton iteration inside solve_bvp always starts near the answer.
    """
    s = np.linspace(0.0, 1.0, 201)

    def rhs(_s: np.ndarray, u: np.ndarray, p: float) -> np.ndarray:
        x, y, theta, m = u
        return np.vstack([np.cos(theta), np.sin(theta), m, -p * np.cos(theta)])

    # Linear solution as the first guess: θ = p (s - s²/2), m = p (1 - s).
    guess = np.vstack([s, np.zeros_like(s), np.zeros_like(s), np.zeros_like(s)])
    sol = None
    for p in np.linspace(alpha / 8.0, alpha, 8):
        sol = solve_bvp(
            lambda s_, u, p=p: rhs(s_, u, p),
            lambda ua, ub: np.array([ua[0], ua[1], ua[2], ub[3]]),
            s,
            guess,
            tol=1e-10,
            max_nodes=100_000,
        )
        assert sol.success, sol.message
        s, guess = sol.x, sol.y
    assert sol is not None
    x_tip, y_tip, theta0, _ = sol.y[:, -1]
    return float(theta0), float(y_tip), float(x_tip)


@pytest.mark.parametrize("alpha", [0.5, 2.0, 10.0])
def test_cantilever_matches_bvp(alpha: float) -> None:
    exact = cantilever_tip_load(alpha)
    theta0, delta, x_tip = _bvp_cantilever(alpha)
    assert exact.tip_angle_rad == pytest.approx(theta0, rel=1e-6)
    assert exact.deflection_over_L == pytest.approx(delta, rel=1e-6)
    assert exact.x_tip_over_L == pytest.approx(x_tip, rel=1e-6)


@pytest.mark.parametrize("alpha", [1e-12, 1e-6, 1e-3])
def test_cantilever_small_load_is_linear(alpha: float) -> None:
    # δ = P L³ / (3 EI), θ0 = P L² / (2 EI); the first nonlinear correction is relative
    # (4/35) alpha² for δ, so it is below 1.2e-7 here.
    exact = cantilever_tip_load(alpha)
    assert exact.deflection_over_L == pytest.approx(alpha / 3.0, rel=2e-7)
    assert exact.tip_angle_rad == pytest.approx(alpha / 2.0, rel=2e-7)
    assert exact.x_tip_over_L == pytest.approx(1.0 - alpha**2 / 15.0, rel=1e-12)


def test_cantilever_known_table_value() -> None:
    # Bisshopp & Drucker (1945), Q. Appl. Math. 3: alpha = 1 gives δ/L = 0.30172, x/L = 0.94357.
    exact = cantilever_tip_load(1.0)
    assert exact.deflection_over_L == pytest.approx(0.30172, abs=1e-5)
    assert exact.x_tip_over_L == pytest.approx(0.94357, abs=1e-5)


@pytest.mark.parametrize("alpha", [1e-3, 0.5, 2.0, 10.0, 50.0])
def test_carlson_form_agrees_with_legendre_form(alpha: float) -> None:
    # The docstring's Legendre formulas (ellipk/ellipkinc/ellipe/ellipeinc) evaluated at the
    # solved m must reproduce the same state; they lose digits only at the extremes.
    exact = cantilever_tip_load(alpha)
    alpha_l, delta_l, x_l = _legendre_state(exact.m)
    assert alpha_l == pytest.approx(alpha, rel=1e-9)
    assert delta_l == pytest.approx(exact.deflection_over_L, rel=1e-9)
    assert x_l == pytest.approx(exact.x_tip_over_L, rel=1e-9)


def test_cantilever_large_load_tends_upright() -> None:
    # For alpha -> inf the beam hangs along the force: x_tip ~ sqrt(2/alpha) L.
    exact = cantilever_tip_load(1e4)
    assert exact.tip_angle_rad == pytest.approx(math.pi / 2, abs=1e-12)
    assert exact.x_tip_over_L == pytest.approx(math.sqrt(2.0 / 1e4), rel=1e-12)
    assert 0.99 < exact.deflection_over_L < 1.0


@pytest.mark.parametrize("delta", [1e-9, 0.1, 0.6, 0.95])
def test_load_for_deflection_inverts(delta: float) -> None:
    state = cantilever_load_for_deflection(delta)
    assert state.deflection_over_L == pytest.approx(delta, rel=1e-13)
    assert cantilever_tip_load(state.alpha).deflection_over_L == pytest.approx(delta, rel=1e-12)


def test_fixed_guided_linear_limit() -> None:
    # P = 12 EI d / L³, M = 6 EI d / L²; the cubic S-curve y = d (3σ² - 2σ³) shortens by
    # ∫ y'² / 2 ds = (3/5) d² / L.
    d = 1e-5
    exact = fixed_guided(d)
    assert exact.load == pytest.approx(12.0 * d, rel=1e-9)
    assert exact.end_moment == pytest.approx(6.0 * d, rel=1e-9)
    assert exact.shortening_over_L == pytest.approx(0.6 * d * d, rel=1e-6)


def test_fixed_guided_is_two_half_cantilevers() -> None:
    exact = fixed_guided(0.8)
    half = cantilever_load_for_deflection(0.8)
    assert exact.load == pytest.approx(4.0 * half.alpha, rel=1e-14)
    assert exact.shortening_over_L == pytest.approx(1.0 - half.x_tip_over_L, rel=1e-14)


def test_fixed_guided_matches_bvp() -> None:
    # Independent check of the symmetry argument: integrate the full beam with θ(L) = 0 and
    # y(L) = d, no axial force, unknown transverse force P as a BVP parameter.
    d = 0.8
    s = np.linspace(0.0, 1.0, 201)

    def rhs(_s: np.ndarray, u: np.ndarray, p: np.ndarray) -> np.ndarray:
        _, _, theta, m = u
        return np.vstack([np.cos(theta), np.sin(theta), m, -p[0] * np.cos(theta)])

    def bc_for(target: float) -> Callable[..., np.ndarray]:
        return lambda ua, ub, p: np.array([ua[0], ua[1], ua[2], ub[2], ub[1] - target])

    sol = None
    guess = np.vstack([s, np.zeros_like(s), np.zeros_like(s), np.zeros_like(s)])
    load = np.array([0.0])
    # tol 1e-9: at 1e-10 the mesh refinement stalls on round-off near d/L = 0.8.
    for target in np.linspace(d / 8.0, d, 8):
        sol = solve_bvp(rhs, bc_for(target), s, guess, p=load, tol=1e-9, max_nodes=100_000)
        assert sol.success, sol.message
        s, guess, load = sol.x, sol.y, sol.p
    assert sol is not None
    exact = fixed_guided(d)
    assert exact.load == pytest.approx(sol.p[0], rel=1e-6)
    assert exact.shortening_over_L == pytest.approx(1.0 - sol.y[0, -1], rel=1e-6)
    assert exact.end_moment == pytest.approx(sol.y[3, 0], rel=1e-6)


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf")])
def test_bad_load_is_rejected(bad: float) -> None:
    with pytest.raises(FeaError, match="alpha"):
        cantilever_tip_load(bad)


@pytest.mark.parametrize("bad", [-0.1, 1.0, 1.5, float("nan")])
def test_bad_deflection_is_rejected(bad: float) -> None:
    with pytest.raises(FeaError, match="must lie in"):
        cantilever_load_for_deflection(bad)
    with pytest.raises(FeaError, match="must lie in"):
        fixed_guided(bad)
