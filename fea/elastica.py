r"""Exact large-deflection elastica by elliptic integrals: the reference the beam solver is checked
against.

The beam is inextensible and unshearable (Euler–Bernoulli), of length ``L`` and bending stiffness
``EI``, with a straight, stress-free reference shape. Everything here is dimensionless: loads as
:math:`\alpha = P L^2 / EI`, lengths as fractions of ``L``. Multiply by ``EI / L**2`` (N, when
``EI`` is in N·mm² and ``L`` in mm) or by ``L`` (mm) to get dimensional numbers.

scipy's Legendre elliptic integrals take the *parameter* :math:`m = k^2`, not the modulus ``k``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from flexopt.fea.errors import FeaError
from scipy.optimize import brentq
from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc, elliprd, elliprf, expit

__all__ = [
    "CantileverTipLoad",
    "FixedGuided",
    "cantilever_tip_load",
    "cantilever_load_for_deflection",
    "fixed_guided",
]

# The root is sought in rho = logit(sin θ0), from which both sin θ0 (small loads) and
# 1 - sin θ0 (the beam turned upright, k -> 1) are computed without cancellation. rho = +700
# gives 1 - sin θ0 ~ 1e-304: alpha ~ (ln 4e152)^2 ~ 1.2e5, the beam upright to machine precision.
# rho = -400 gives alpha ~ 4e-174; much lower and I_D ~ sin³ε underflows.
_RHO_MIN = -400.0
_RHO_MAX = 700.0
# Brent tolerances on rho; they leave the returned quantities exact to a few ulp.
_XTOL = 1e-15
_RTOL = 4.0 * 2.220446049250313e-16  # brentq's floor


@dataclass(frozen=True)
class CantileverTipLoad:
    """Exact state of a cantilever under a dead tip force perpendicular to its undeformed axis.

    Attributes
    ----------
    alpha : float, -
        Load parameter P L² / EI.
    tip_angle_rad : float, rad
        Tangent angle θ0 of the tip (0 undeformed, → π/2 as alpha → ∞).
    deflection_over_L : float, -
        Tip displacement along the force, δ / L.
    x_tip_over_L : float, -
        Tip position along the undeformed axis, x_tip / L (1 undeformed).
    m : float, -
        Elliptic parameter m = k² = (1 + sin θ0) / 2 of the solution.
    """

    alpha: float
    tip_angle_rad: float
    deflection_over_L: float
    x_tip_over_L: float
    m: float


@dataclass(frozen=True)
class FixedGuided:
    """Exact state of a fixed–guided beam pushed transversely at the guided end.

    Attributes
    ----------
    d_over_L : float, -
        Transverse displacement of the guided end, d / L.
    load : float, -
        Transverse end force P L² / EI (the only force: the guided end slides axially freely).
    end_moment : float, -
        Moment at either end, M L / EI (equal and opposite at the two ends).
    shortening_over_L : float, -
        Axial end shortening, (L - x_end) / L.
    """

    d_over_L: float
    load: float
    end_moment: float
    shortening_over_L: float


def _linear_state(alpha: float) -> CantileverTipLoad:
    """Small-load limit, exact in double precision below alpha ~ 1e-8 (next terms O(alpha³))."""
    return CantileverTipLoad(
        alpha=alpha,
        tip_angle_rad=alpha / 2.0,
        deflection_over_L=alpha / 3.0,
        x_tip_over_L=1.0 - alpha * alpha / 15.0,
        m=0.5 * (1.0 + alpha / 2.0),
    )


def _state_from_rho(rho: float) -> CantileverTipLoad:
    r"""The cantilever whose tip angle has sin θ0 = expit(rho), by Carlson's integrals.

    The Legendre form of :func:`cantilever_tip_load` is exact but, evaluated with ``ellipkinc`` /
    ``ellipeinc`` near ψ1 → π/2 (small loads), it subtracts nearly equal numbers and loses
    ~1e-16 / alpha**1.5 of relative accuracy (2e-6 at alpha = 1e-7). With φ = π/2 − ψ the same
    integrals run over [0, ε], tan ε = sqrt(sin θ0), where the integrand is
    1 / sqrt(p + m sin²φ), p = 1 − m. In Carlson's symmetric forms (homogeneity scales p in)

    .. math::

        \sqrt\alpha = c\,R_F(p\cos^2\varepsilon,\ \tfrac12,\ p), \qquad
        I_D = \int_0^\varepsilon \frac{\sin^2\varphi\,d\varphi}{\sqrt{p + m\sin^2\varphi}}
            = \tfrac{c^3}{3}\,p\,R_D(p\cos^2\varepsilon,\ \tfrac12,\ p),

    with c = sin ε and p + m c² = 1/2 identically. Then
    δ / L = sin θ0 − 2 m I_D / sqrt(alpha), with no cancellation worse than a factor 3.
    """
    s0 = float(expit(rho))  # sin θ0
    one_minus_s0 = float(expit(-rho))  # 1 - sin θ0, exact even when sin θ0 rounds to 1
    p = 0.5 * one_minus_s0  # 1 - m
    m = 0.5 * (1.0 + s0)
    sin2_eps = s0 / (1.0 + s0)
    cos2_eps = 1.0 / (1.0 + s0)
    c = math.sqrt(sin2_eps)
    root_alpha = c * float(elliprf(p * cos2_eps, 0.5, p))
    i_d = sin2_eps * c / 3.0 * p * float(elliprd(p * cos2_eps, 0.5, p))
    alpha = root_alpha * root_alpha
    return CantileverTipLoad(
        alpha=alpha,
        # cos θ0 = sqrt((1 - sin θ0)(1 + sin θ0)): no cancellation near θ0 = π/2.
        tip_angle_rad=math.atan2(s0, math.sqrt(one_minus_s0 * (1.0 + s0))),
        deflection_over_L=s0 - 2.0 * m * i_d / root_alpha,
        x_tip_over_L=math.sqrt(2.0 * s0 / alpha),
        m=m,
    )


def _legendre_state(m: float) -> tuple[float, float, float]:
    """(alpha, δ/L, x_tip/L) straight from the Legendre form in the docstring of
    :func:`cantilever_tip_load`; kept as an independent cross-check for the tests.
    """
    psi1 = math.asin(1.0 / math.sqrt(2.0 * m))
    root_alpha = float(ellipk(m)) - float(ellipkinc(psi1, m))
    delta = 1.0 - 2.0 / root_alpha * (float(ellipe(m)) - float(ellipeinc(psi1, m)))
    x_tip = math.sqrt(2.0 * (2.0 * m - 1.0)) / root_alpha
    return root_alpha * root_alpha, delta, x_tip


def _solve_rho(residual: Callable[[float], float]) -> CantileverTipLoad:
    rho = brentq(residual, _RHO_MIN, _RHO_MAX, xtol=_XTOL, rtol=_RTOL)
    return _state_from_rho(rho)


def cantilever_tip_load(alpha: float) -> CantileverTipLoad:
    r"""Exact cantilever under a dead tip force perpendicular to the undeformed axis.

    The beam is clamped at s = 0 with a horizontal tangent; the force P at s = L keeps its
    direction (vertical) while the beam deflects.

    Derivation. Let θ(s) be the tangent angle. The moment at s is M = P (x_L − x(s)) and
    M = EI θ', so differentiating with x' = cos θ gives

    .. math:: EI\,\theta'' = -P \cos\theta, \qquad \theta(0) = 0, \quad \theta'(L) = 0.

    Multiplying by θ' and integrating from s to L (θ(L) = θ0):
    :math:`\tfrac12 EI\,\theta'^2 = P(\sin\theta_0 - \sin\theta)`. Substitute

    .. math:: 1 + \sin\theta = 2k^2 \sin^2\psi, \qquad k^2 = \tfrac12 (1 + \sin\theta_0),

    so that θ = θ0 ↔ ψ = π/2 and θ = 0 ↔ :math:`\sin\psi_1 = 1/(\sqrt2 k)`. Then
    :math:`\sin\theta_0 - \sin\theta = 2k^2\cos^2\psi` and
    :math:`d\theta = 2k\cos\psi\,d\psi / \sqrt{1 - k^2\sin^2\psi}`, hence
    :math:`ds = d\theta/\theta' = (L/\sqrt\alpha)\,d\psi / \sqrt{1 - k^2 \sin^2\psi}` and

    .. math::

        \sqrt\alpha &= K(k) - F(k, \psi_1), \\
        \delta / L &= \frac{1}{\sqrt\alpha}\int_{\psi_1}^{\pi/2}
            \frac{2k^2\sin^2\psi - 1}{\sqrt{1 - k^2\sin^2\psi}}\,d\psi
            = 1 - \frac{2}{\sqrt\alpha}\,\bigl(E(k) - E(k, \psi_1)\bigr), \\
        x_\mathrm{tip} / L &= \frac{1}{\sqrt\alpha}\int_0^{\theta_0}
            \frac{\cos\theta\,d\theta}{\sqrt{2(\sin\theta_0 - \sin\theta)}}
            = \sqrt{2\sin\theta_0 / \alpha}.

    The first line is solved for k with Brent's method. The integrals are evaluated in the
    equivalent Carlson form of :func:`_state_from_rho` (complementary angle), which keeps full
    relative accuracy from alpha ~ 1e-300 up to alpha ~ 1e5 (where k → 1 and the beam is upright
    to machine precision); the Legendre form above loses ~1e-16 / alpha**1.5 at small loads.

    Parameters
    ----------
    alpha : float, -
        P L² / EI, >= 0 (P in N, L in mm, EI in N·mm²).

    Returns
    -------
    CantileverTipLoad
        Tip angle (rad), δ / L and x_tip / L.

    Examples
    --------
    >>> round(cantilever_tip_load(1.0).deflection_over_L, 5)  # Bisshopp & Drucker (1945)
    0.30172
    """
    alpha = float(alpha)
    if not (math.isfinite(alpha) and alpha >= 0.0):
        raise FeaError(f"alpha = P L^2 / EI = {alpha!r} must be a finite number >= 0")
    low, high = _state_from_rho(_RHO_MIN), _state_from_rho(_RHO_MAX)
    if alpha < low.alpha:
        return _linear_state(alpha)
    if alpha > high.alpha:
        raise FeaError(
            f"alpha = {alpha:g} exceeds {high.alpha:.3g}, the largest load double precision "
            "resolves: the beam is upright (delta/L -> 1, x_tip/L -> 0) to machine precision"
        )
    root_alpha = math.sqrt(alpha)
    # Residual in sqrt(alpha): the function the elliptic integral gives directly, and nearly
    # linear in rho for large loads (K ~ ln(4 / sqrt(1 - m))).
    return _solve_rho(lambda rho: math.sqrt(_state_from_rho(rho).alpha) - root_alpha)


def cantilever_load_for_deflection(delta_over_L: float) -> CantileverTipLoad:
    """Inverse of :func:`cantilever_tip_load`: the tip load that gives a tip deflection δ / L.

    Parameters
    ----------
    delta_over_L : float, -
        δ / L in [0, 1): the deflection along the (dead, perpendicular) tip force. δ / L → 1 only
        as the load grows without bound.

    Returns
    -------
    CantileverTipLoad
        The state, with ``alpha`` = P L² / EI.
    """
    target = float(delta_over_L)
    if not (math.isfinite(target) and 0.0 <= target < 1.0):
        raise FeaError(f"delta_over_L = {target!r} must lie in [0, 1) (the beam is inextensible)")
    low, high = _state_from_rho(_RHO_MIN), _state_from_rho(_RHO_MAX)
    if target < low.deflection_over_L:
        return _linear_state(3.0 * target)
    if target > high.deflection_over_L:
        raise FeaError(
            f"delta_over_L = {target!r} exceeds {high.deflection_over_L:.6g}, the largest "
            "deflection double precision resolves (it needs alpha > 1e5)"
        )
    return _solve_rho(lambda rho: _state_from_rho(rho).deflection_over_L - target)


def fixed_guided(d_over_L: float) -> FixedGuided:
    """Exact fixed–guided beam: clamped at s = 0, the other end held at zero rotation, free to
    slide axially, and pushed transversely by d.

    With no axial force the moment is linear in x and the shape is antisymmetric about the
    mid-point, where the moment (the curvature) vanishes. Each half is therefore a cantilever of
    length L/2 with tip force P, deflecting d/2: δ_half / (L/2) = d / L, and
    P L² / EI = 4 · α_half. The end moment is P times the axial length of one half.

    Parameters
    ----------
    d_over_L : float, -
        d / L in [0, 1).

    Returns
    -------
    FixedGuided
        P L² / EI, M L / EI and the axial end shortening / L.
    """
    d = float(d_over_L)
    if not (math.isfinite(d) and 0.0 <= d < 1.0):
        raise FeaError(f"d_over_L = {d!r} must lie in [0, 1) (the beam is inextensible)")
    half = cantilever_load_for_deflection(d)
    load = 4.0 * half.alpha
    # Axial length of one half as a fraction of L: (L/2) · x_tip_half / (L/2) / L.
    x_half = 0.5 * half.x_tip_over_L
    return FixedGuided(
        d_over_L=d,
        load=load,
        end_moment=load * x_half,
        shortening_over_L=1.0 - 2.0 * x_half,
    )
