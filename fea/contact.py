r"""Cam–follower contact mechanics of the V2SOM torque generator (paper 000, Ayoubi et al. 2019):
the synthesis of the follower motion for a target torque, the torque of a plate by virtual work,
the Hertz pressure of the roller–cam line contact, and the stiffness-adjusting block (SAB) with
the Eq. 17 profile correction. The shapes (layout, profile, plate) are :mod:`geometry.cam`; its
frames are the ones used here. Moved from ``geometry/cam.py`` (issue #24: physics in fea/); the
errors are still :class:`geometry.errors.GeometryError`, as before the move. Line numbers (l. N)
refer to ``/work/shared/seeds/000_1c1b6cd1291b0c63.txt``.

:func:`synthesise_cam` finds the follower motion ``r(γ)`` that makes the cam produce a given
``T(γ)`` (Eqs. 5–12): turning the cam pushes the followers out from their rest radius ``r0`` to
``r(γ)`` against springs of force ``F_k(r)`` (Eq. 13); the cam's profile decides how the stored
energy grows with ``γ``, so any torque profile ``T(γ)`` can be built.

**Synthesis without the singularity at γ = 0.** Eq. 10 reads ``dγ/dr = 2F_k/T(γ) + μ/r``;
``T(0) = 0`` makes it infinite (preloaded springs) or 0/0 (springs relaxed at rest), and Eq. 12's
explicit step from ``γ0 = 0`` divides by zero. The cure is to integrate the *work*, not the angle.
Multiply Eq. 10 by ``T``: with ``u = W(γ) = ∫_0^γ T`` (the work the torque has done),

.. math:: \frac{du}{dr} = T\,\gamma' = n F_k(r) + \mu\,\frac{T(\gamma(u))}{r}, \qquad u(r_0) = 0,

which is regular at ``r0`` (its right side is ``n F_k(r0) >= 0``). Without friction it integrates
in closed form — the virtual-work identity of Eq. 6, ``W(γ) = n ∫_{r0}^{r} F_k = U(r)`` — and
``r(γ) = U⁻¹(W(γ))`` is found by bisection (``U`` increases because the springs pull). With
friction it is integrated numerically, ``γ(u) = W⁻¹(u)`` from a table of ``sqrt(W)`` (which is
linear in ``γ`` near 0, where ``W ~ T'(0) γ²/2``). The slope ``r' = T/(n F_k + μT/r)`` is then
algebraic; at ``γ = 0`` it is 0 for preloaded springs and, for relaxed ones, the limit of 0/0,

.. math:: r'(0) = 1/c, \qquad T'(0)\,c^2 - \mu T'(0)\,c/r_0 - n F_k'(r_0) = 0

(from ``u ≈ T'(0) c² (r-r0)²/2`` in the equation above), ``c = sqrt(n F_k'(r0)/T'(0))`` when
``μ = 0``.

**Profile correction (Eq. 17)** multiplies the target by ``a0 + a1 γ + a2 γ²``
(:class:`CorrectedCurve`); the paper lists its coefficients as ``[a1, a2, a3] =
[1.001, -0.0369, 2.588]`` (l. 210), an index slip for ``a0, a1, a2``. :func:`fit_correction` finds
them by linear least squares so that the joint torque after the stiffness-adjusting block follows
its ideal (constant-ratio) curve.

**Stiffness-adjusting block (Eqs. 15–16).** :func:`sab_ratio` is Eq. 15. At ``θ = 0``,
``δ = 0`` and Eq. 15 gives ``(R1/R2) (R/a - 1)⁻¹ = (R1/R2) a/(R - a)``: Eq. 16 as printed,
``a/(R-a)``, drops the factor ``R1/R2`` (:func:`sab_ratio_ideal` keeps it). The second-order
Taylor term, which the paper mentions but does not print, is derived in :func:`sab_ratio_series`:
``N(θ) ≈ N0 (1 - (1 + k) θ² / (2 (1 - k)²))``, ``k = a/R`` (the ratio falls off with ``θ``, the
"declining trend" the correction compensates).

Units: mm, N, N·mm, rad, MPa.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from flexopt.geometry.cam import (
    CamLayout,
    CamProfile,
    CamSettings,
    CamSprings,
    follower_radius_from_outline,
)
from flexopt.geometry.errors import GeometryError
from shapely.geometry import Polygon

__all__ = [
    "PAPER_CORRECTION",
    "CorrectedCurve",
    "TorqueCurve",
    "contact_pressure_MPa",
    "fit_correction",
    "onset_pressure_MPa",
    "sab_limits",
    "sab_ratio",
    "sab_ratio_ideal",
    "sab_ratio_series",
    "sab_rotation",
    "sab_table",
    "synthesise_cam",
    "torque_from_outline",
]

#: The synthesis' numerical settings unless given (frozen, so one instance serves every call).
DEFAULT_SETTINGS = CamSettings()

#: Eq. 17 coefficients (a0, a1, a2) of the prototype, printed as [a1, a2, a3] (l. 210).
PAPER_CORRECTION = (1.001, -0.0369, 2.588)


class TorqueCurve(Protocol):
    """What the synthesis needs of a target: ``T(γ)`` (N·mm) and ``W(γ) = ∫_0^γ T`` (N·mm), both
    vectorised over rotations in rad (``optimise.targets.TargetCurve`` is one)."""

    def __call__(self, x: Any) -> np.ndarray: ...

    def work(self, x: Any) -> np.ndarray: ...


# --------------------------------------------------------------------------------------------
# Synthesis


def _check_springs(springs: CamSprings, layout: CamLayout) -> None:
    r0 = layout.rest_radius_mm
    if float(springs.force_N(r0)) < -1e-12:
        length = math.hypot(r0, springs.offset_mm)
        raise GeometryError(
            f"the springs are slack at rest: sqrt(r0² + b²) = {length:g} mm < free_length_mm = "
            f"{springs.free_length_mm:g} mm, so they would push the followers off the cam; "
            "raise rest_radius_mm or offset_mm, or shorten free_length_mm"
        )


def _spring_work(springs: CamSprings, layout: CamLayout, r: np.ndarray) -> np.ndarray:
    """``U(r) = n ∫_{r0}^{r} F_k``, N·mm (all followers)."""
    n = layout.followers
    return n * (springs.primitive_Nmm(r) - springs.primitive_Nmm(layout.rest_radius_mm))


def _invert_spring_work(
    springs: CamSprings, layout: CamLayout, u: np.ndarray, settings: CamSettings
) -> np.ndarray:
    """``r`` with ``U(r) = u`` (u >= 0), by vectorised bisection (U increases for r > r0)."""
    r0 = layout.rest_radius_mm
    lo = np.full(u.shape, r0)
    span = max(r0, 1.0)
    hi = np.full(u.shape, r0 + span)
    for _ in range(200):  # grow the bracket: U grows at least like K (r - r0)^2
        short = _spring_work(springs, layout, hi) < u
        if not short.any():
            break
        hi = np.where(short, r0 + 2.0 * (hi - r0), hi)
    for _ in range(settings.bisection_steps):
        mid = 0.5 * (lo + hi)
        below = _spring_work(springs, layout, mid) < u
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def _slope_at_zero(curve: TorqueCurve, springs: CamSprings, layout: CamLayout) -> float:
    """``r'(0)``: 0 with preloaded springs, else the 0/0 limit derived in the module notes."""
    r0 = layout.rest_radius_mm
    n = layout.followers
    if float(springs.force_N(r0)) > 1e-12:
        return 0.0
    slope = getattr(curve, "slope", None)
    if callable(slope):
        t_slope = float(slope(np.array(0.0)))  # T'(0), N·mm/rad
    else:  # T(h)/h has the relative error h T''/(2 T'): 1e-9 rad makes it negligible
        h = 1e-9
        t_slope = float(curve(np.array(h))) / h
    k_s = float(springs.rate_N_per_mm(r0))
    if not t_slope > 0:
        raise GeometryError("the target torque must rise from 0 (T'(0) > 0) to synthesise a cam")
    mu = layout.friction
    c = 0.5 * (mu / r0 + math.sqrt((mu / r0) ** 2 + 4.0 * n * k_s / t_slope))
    return 1.0 / c


def synthesise_cam(
    curve: TorqueCurve,
    springs: CamSprings,
    layout: CamLayout,
    points: int = 361,
    settings: CamSettings = DEFAULT_SETTINGS,
) -> CamProfile:
    """The follower motion ``r(γ)`` and contact geometry of the cam that produces ``T(γ)``.

    Parameters
    ----------
    curve : TorqueCurve
        Target torque ``T(γ)`` (N·mm) with its work ``W(γ)`` (N·mm), γ in rad, loading direction;
        ``T > 0`` for ``γ > 0``. Wrap it in :class:`CorrectedCurve` for Eq. 17.
    springs : CamSprings
    layout : CamLayout
    points : int
        Grid points from γ = 0 to γ_max.
    settings : CamSettings

    Returns
    -------
    CamProfile

    Raises
    ------
    GeometryError
        When the springs are slack at rest or the target does not rise.
    """
    _check_springs(springs, layout)
    if points < 3:
        raise GeometryError(f"points = {points} must be >= 3")
    n = layout.followers
    r0 = layout.rest_radius_mm
    mu = layout.friction
    gamma = np.linspace(0.0, layout.max_rotation_rad, points)
    torque = np.asarray(curve(gamma), dtype=float)
    if np.any(torque[1:] <= 0) or not np.all(np.isfinite(torque)):
        raise GeometryError(
            "the target torque must be finite and > 0 for every γ in (0, max_rotation]; a cam "
            "with springs that only pull cannot give zero or negative torque while turning on"
        )
    work = np.asarray(curve.work(gamma), dtype=float)
    if mu == 0.0:
        # Eq. 6 without friction is algebraic: n ∫ F_k dr = W(γ).
        r = _invert_spring_work(springs, layout, work, settings)
    else:
        r = _friction_radius(curve, springs, layout, gamma, work, settings)
    fk = springs.force_N(r)
    # r' = T / (n F_k + μ T / r), from Eq. 10; regular wherever F_k(r) > 0.
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = torque / (n * fk + mu * torque / r)
    slope[0] = _slope_at_zero(curve, springs, layout)
    bad = ~np.isfinite(slope)
    if bad.any():  # relaxed springs give 0/0 only at γ = 0, handled above
        slope[bad] = np.interp(gamma[bad], gamma[~bad], slope[~bad])
    alpha = np.arctan2(r, slope)
    # Eq. 10 gives r γ' = tan α = μ + n F_k r / T >= μ: the synthesised cam never self-locks
    # (sin α - μ cos α > 0 below); strong friction shows as large pressure angles instead.
    beta = np.arctan2(
        layout.roller_radius_mm * np.cos(alpha), r - layout.roller_radius_mm * np.sin(alpha)
    )
    rho = np.hypot(
        r - layout.roller_radius_mm * np.sin(alpha), layout.roller_radius_mm * np.cos(alpha)
    )
    contact = fk / (np.sin(alpha) - mu * np.cos(alpha))
    # curvature of the polar curve r(φ): (r² + 2r'² - r r'') / (r² + r'²)^1.5
    second = np.gradient(slope, gamma, edge_order=2)
    kappa = (r**2 + 2 * slope**2 - r * second) / (r**2 + slope**2) ** 1.5
    notes = []
    if float(springs.force_N(r0)) <= 1e-12:
        notes.append(
            "springs relaxed at rest: the pitch curve has a V-notch at γ = 0 (slope "
            f"{slope[0]:.4g} mm/rad), the follower sits on both flanks there"
        )
    return CamProfile(
        rotation_rad=gamma,
        torque_Nmm=torque,
        follower_radius_mm=r,
        slope_mm_per_rad=slope,
        alpha_rad=alpha,
        pressure_angle_rad=0.5 * math.pi - alpha,
        beta_rad=beta,
        rho_mm=rho,
        spring_force_N=fk,
        contact_force_N=contact,
        pitch_curvature_per_mm=kappa,
        springs=springs,
        layout=layout,
        notes=tuple(notes),
    )


def _friction_radius(
    curve: TorqueCurve,
    springs: CamSprings,
    layout: CamLayout,
    gamma: np.ndarray,
    work: np.ndarray,
    settings: CamSettings,
) -> np.ndarray:
    """``r(γ)`` with guide friction: integrate ``du/dr = n F_k + μ T(γ(u))/r`` from ``r0``."""
    n = layout.followers
    r0 = layout.rest_radius_mm
    mu = layout.friction
    g_table = np.linspace(0.0, layout.max_rotation_rad, settings.work_table_points)
    sqrt_w = np.sqrt(np.maximum(np.asarray(curve.work(g_table), dtype=float), 0.0))
    u_end = float(work[-1])

    def rhs(r: float, y: np.ndarray) -> np.ndarray:
        g = np.interp(math.sqrt(max(y[0], 0.0)), sqrt_w, g_table)
        return np.array([n * float(springs.force_N(r)) + mu * float(curve(np.array(g))) / r])

    def done(r: float, y: np.ndarray) -> float:
        return y[0] - u_end

    done.terminal = True  # type: ignore[attr-defined]
    # Without friction the work reaches u_end at r_free; friction only makes r grow slower, so
    # integrate until the event, bounded by a generous multiple of that distance.
    r_free = float(_invert_spring_work(springs, layout, np.array([u_end]), settings)[0])
    span = 4.0 * (r_free - r0) + 1.0
    # imported here: scipy.integrate is ~0.04 s CPU that importing a kind through this module
    # (load_study of every constant-force study) does not need
    from scipy.integrate import solve_ivp

    sol = solve_ivp(
        rhs,
        (r0, r0 + span),
        [0.0],
        events=done,
        dense_output=True,
        rtol=settings.rtol,
        atol=settings.atol_Nmm,
        max_step=(r_free - r0) / 200.0 if r_free > r0 else np.inf,
    )
    if not sol.t_events[0].size:
        raise GeometryError(
            "with this friction the springs cannot absorb the target's work within a sensible "
            "stroke; lower friction or stiffen the springs"
        )
    r_end = float(sol.t_events[0][0])
    rs = np.linspace(r0, r_end, 4001)
    us = np.maximum(sol.sol(rs)[0], 0.0)
    us = np.maximum.accumulate(us)  # u(r) increases; drop rounding wiggles before inverting
    return np.interp(np.sqrt(work), np.sqrt(us), rs)


@dataclass(frozen=True)
class CorrectedCurve:
    """Eq. 17: ``T_cor(γ) = T(γ) (a0 + a1|γ| + a2 γ²)``, with its work by quadrature.

    Attributes
    ----------
    base : TorqueCurve — the uncorrected target (N·mm over rad).
    coefficients : (a0, a1, a2) — the polynomial factor (1/rad, 1/rad²).
    max_rotation_rad : float, rad — upper end of the work table (the cam's γ_max).
    """

    base: TorqueCurve
    coefficients: tuple[float, float, float]
    max_rotation_rad: float = math.pi / 2

    def factor(self, x: Any) -> np.ndarray:
        a0, a1, a2 = self.coefficients
        ax = np.abs(np.asarray(x, dtype=float))
        return a0 + a1 * ax + a2 * ax**2

    def __call__(self, x: Any) -> np.ndarray:
        return np.asarray(self.base(x), dtype=float) * self.factor(x)

    def work(self, x: Any) -> np.ndarray:
        # W_cor = ∫ T p = p W - ∫ W p' (parts), p' = a1 + 2 a2 γ; the remaining integral is smooth
        # (W ~ γ² near 0), so a fine trapezoid table is accurate to ~1e-10 relative.
        x = np.asarray(x, dtype=float)
        ax = np.abs(x)
        top = max(self.max_rotation_rad, float(np.max(ax)) if ax.size else 0.0)
        g = np.linspace(0.0, top, 20001)
        _, a1, a2 = self.coefficients
        wp = np.asarray(self.base.work(g), dtype=float) * (a1 + 2 * a2 * g)
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (wp[1:] + wp[:-1]) * np.diff(g))])
        return self.factor(ax) * np.asarray(self.base.work(ax), dtype=float) - np.interp(ax, g, cum)


# --------------------------------------------------------------------------------------------
# Virtual work and contact pressure


def torque_from_outline(
    outline: Polygon,
    springs: CamSprings,
    layout: CamLayout,
    rotation_rad: Any,
    step_rad: float = 2e-3,
) -> np.ndarray:
    """Torque of the plate by virtual work (Eq. 6, frictionless): ``T = n F_k(r) dr/dγ``.

    ``r(γ)`` comes from the plate's geometry (:func:`follower_radius_from_outline`), not from the
    synthesis, so this checks the whole chain target → r(γ) → profile → plate.

    Returns
    -------
    (k,) float, N·mm
    """
    g = np.atleast_1d(np.asarray(rotation_rad, dtype=float))
    r1 = layout.roller_radius_mm
    r = follower_radius_from_outline(outline, r1, g)
    r_plus = follower_radius_from_outline(outline, r1, g + step_rad)
    r_minus = follower_radius_from_outline(outline, r1, g - step_rad)
    slope = (r_plus - r_minus) / (2.0 * step_rad)
    return layout.followers * springs.force_N(r) * slope


def onset_pressure_MPa(yield_MPa: float) -> float:
    """Peak Hertz pressure at which a line contact starts to yield: ``1.67 σ_y``.

    Johnson, *Contact Mechanics* (1985), §4.2: below the surface of a cylinder contact the
    largest shear stress is ``0.30 p0``; Tresca yield (``k = σ_y/2``) gives ``p0 = 3.3 k =
    1.67 σ_y`` (von Mises would allow 1.79 σ_y; Tresca is the safe side).
    """
    return 1.67 * yield_MPa


def contact_pressure_MPa(
    profile: CamProfile,
    cam_E_MPa: float,
    cam_nu: float,
    roller_E_MPa: float = 210_000.0,
    roller_nu: float = 0.3,
) -> np.ndarray:
    """Peak Hertz pressure of the roller–cam line contact along the profile, MPa.

    ``p0 = sqrt(F' E* / (π R*))`` with ``F' = F_r / thickness`` (N/mm), ``1/E* = (1-ν1²)/E1 +
    (1-ν2²)/E2`` and ``1/R* = 1/r1 + 1/R_cam`` (``R_cam`` signed: a concave cam flank spreads the
    load). Where the pitch curve is undercut the contact is a corner (``inf``).

    Returns
    -------
    (m,) float, MPa
    """
    lay = profile.layout
    e_star = 1.0 / ((1 - cam_nu**2) / cam_E_MPa + (1 - roller_nu**2) / roller_E_MPa)
    kappa = profile.pitch_curvature_per_mm
    r1 = lay.roller_radius_mm
    # 1/R* = 1/r1 + 1/R_cam with R_cam = 1/κ - r1, i.e. κ / (r1 (1 - κ r1)); straight pitch (κ = 0)
    # leaves 1/r1, a concave flank (κ < 0) less than that.
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / r1 + kappa / (1.0 - kappa * r1)
        p0 = np.sqrt(
            np.maximum(profile.contact_force_N, 0.0) / lay.thickness_mm * e_star * inv / math.pi
        )
    return np.where(kappa * r1 >= 1.0, np.inf, p0)


# --------------------------------------------------------------------------------------------
# Stiffness-adjusting block (Eqs. 15–16) and the Eq. 17 correction


def _check_sab(a_mm: float, R_mm: float, R1_over_R2: float) -> None:
    if not (R_mm > 0 and R1_over_R2 > 1):
        raise GeometryError(
            f"SAB needs R_mm > 0 and R1_over_R2 > 1 (a reducer); got R = {R_mm:g}, "
            f"R1/R2 = {R1_over_R2:g}"
        )
    lo = R_mm * math.sin(math.pi / (2 * R1_over_R2))
    if not lo <= a_mm < R_mm:
        raise GeometryError(
            f"a = {a_mm:g} mm is outside Eq. 15a: R sin(π R2/(2 R1)) = {lo:.4g} <= a < R = "
            f"{R_mm:g} mm (a = R makes the ideal ratio infinite)"
        )


def sab_limits(a_mm: float, R_mm: float, R1_over_R2: float) -> float:
    """Largest output deflection |θ| of Eq. 15b, rad."""
    _check_sab(a_mm, R_mm, R1_over_R2)
    q = 1.0 / R1_over_R2
    return 0.5 * math.pi * (1 - q) - math.acos(R_mm / a_mm * math.sin(0.5 * math.pi * q))


def sab_ratio(theta_rad: Any, a_mm: float, R_mm: float, R1_over_R2: float) -> np.ndarray:
    """Torque ratio ``T_θ/T_γ`` of the stiffness-adjusting block, Eq. 15 (even in θ).

    ``(R1/R2) (-1 + cos δ / sqrt((a/R)² - sin² δ))⁻¹``, ``δ = atan(a sin θ / (R - a cos θ))``.
    """
    _check_sab(a_mm, R_mm, R1_over_R2)
    th = np.asarray(theta_rad, dtype=float)
    delta = np.arctan2(a_mm * np.sin(th), R_mm - a_mm * np.cos(th))
    k = a_mm / R_mm
    return R1_over_R2 / (-1.0 + np.cos(delta) / np.sqrt(k**2 - np.sin(delta) ** 2))


def sab_ratio_ideal(a_mm: float, R_mm: float, R1_over_R2: float) -> float:
    """Eq. 15 at θ = 0: ``(R1/R2) a/(R - a)`` (Eq. 16 as printed drops ``R1/R2``)."""
    _check_sab(a_mm, R_mm, R1_over_R2)
    return R1_over_R2 * a_mm / (R_mm - a_mm)


def sab_ratio_series(theta_rad: Any, a_mm: float, R_mm: float, R1_over_R2: float) -> np.ndarray:
    r"""Second-order Taylor polynomial of Eq. 15 in θ (the paper's "F_ideal" before truncation).

    With ``k = a/R``: ``δ = kθ/(1-k) + O(θ³)``, ``cos δ/sqrt(k² - sin²δ) = (1/k)(1 + (1-k²)
    δ²/(2k²)) + O(δ⁴)``, so ``N(θ)⁻¹ (R1/R2) = (1-k)/k + (1-k²) δ²/(2k³)`` and

    .. math:: N(θ) ≈ \frac{R_1}{R_2}\frac{k}{1-k}\Bigl(1 - \frac{(1+k)\,θ^2}{2(1-k)^2}\Bigr).
    """
    n0 = sab_ratio_ideal(a_mm, R_mm, R1_over_R2)
    k = a_mm / R_mm
    th = np.asarray(theta_rad, dtype=float)
    return n0 * (1.0 - (1.0 + k) * th**2 / (2.0 * (1.0 - k) ** 2))


def sab_rotation(theta_rad: Any, a_mm: float, R_mm: float, R1_over_R2: float) -> np.ndarray:
    """Cam rotation ``γ(θ) = ∫_0^θ N dθ'`` (power balance ``T_θ dθ = T_γ dγ``), rad."""
    th = np.asarray(theta_rad, dtype=float)
    top = float(np.max(np.abs(th))) if th.size else 0.0
    grid = np.linspace(0.0, max(top, 1e-12), 4001)
    ratio = sab_ratio(grid, a_mm, R_mm, R1_over_R2)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (ratio[1:] + ratio[:-1]) * np.diff(grid))])
    return np.sign(th) * np.interp(np.abs(th), grid, cum)


def sab_table(a_mm: float, R_mm: float, R1_over_R2: float) -> dict[str, Any]:
    """The SAB's torque ratio at a glance (moved from ``pipeline/studies/cam.py``): Eq. 15 at
    θ = 0, the ideal ratio with ``R1/R2`` and Eq. 16 as printed (without it), Eq. 15b's largest
    output (deg), and Eq. 15 beside its second-order series at nine outputs ``theta_deg`` from 0
    to that limit."""
    theta_max = sab_limits(a_mm, R_mm, R1_over_R2)
    theta = np.linspace(0.0, theta_max, 9)
    return {
        "ratio_at_zero_eq15": float(sab_ratio(0.0, a_mm, R_mm, R1_over_R2)),
        "ratio_ideal_with_R1_over_R2": sab_ratio_ideal(a_mm, R_mm, R1_over_R2),
        "ratio_eq16_as_printed": a_mm / (R_mm - a_mm),
        "max_output_deg_eq15b": math.degrees(theta_max),
        "theta_deg": np.degrees(theta).tolist(),
        "ratio_eq15": sab_ratio(theta, a_mm, R_mm, R1_over_R2).tolist(),
        "ratio_series_2nd_order": sab_ratio_series(theta, a_mm, R_mm, R1_over_R2).tolist(),
    }


def fit_correction(
    curve: TorqueCurve,
    a_mm: float,
    R_mm: float,
    R1_over_R2: float,
    max_output_rad: float | None = None,
    samples: int = 200,
) -> tuple[tuple[float, float, float], dict[str, Any]]:
    """Eq. 17 coefficients that make the joint follow its ideal curve through the real SAB.

    The joint torque through the SAB is ``T_θ(θ) = N(θ) T_cor(γ(θ))`` (Eq. 15, γ from
    :func:`sab_rotation`); ideally it would be ``N0 T(N0 θ)`` (constant ratio, Eq. 16). With
    ``T_cor = T (a0 + a1 γ + a2 γ²)`` the mismatch is linear in ``(a0, a1, a2)``, so linear least
    squares over ``θ`` in ``(0, max_output]`` gives them (the paper's "simple optimization based
    on the least squares method", l. 201).

    Returns
    -------
    (a0, a1, a2), dict
        The coefficients and the fit's data: ``theta_rad``, ``joint_torque_Nmm`` without and with
        the correction, ``ideal_torque_Nmm``, ``max_relative_error`` before and after.
    """
    top = sab_limits(a_mm, R_mm, R1_over_R2) if max_output_rad is None else max_output_rad
    theta = np.linspace(top / samples, top, samples)
    ratio = sab_ratio(theta, a_mm, R_mm, R1_over_R2)
    gamma = sab_rotation(theta, a_mm, R_mm, R1_over_R2)
    n0 = sab_ratio_ideal(a_mm, R_mm, R1_over_R2)
    base = ratio * np.asarray(curve(gamma), dtype=float)
    ideal = n0 * np.asarray(curve(n0 * theta), dtype=float)
    design = base[:, None] * np.column_stack([np.ones_like(gamma), gamma, gamma**2])
    coef, *_ = np.linalg.lstsq(design, ideal, rcond=None)
    corrected = design @ coef
    info = {
        "theta_rad": theta,
        "cam_rotation_rad": gamma,
        "joint_torque_Nmm": base,
        "corrected_joint_torque_Nmm": corrected,
        "ideal_torque_Nmm": ideal,
        "max_relative_error_uncorrected": float(np.max(np.abs(base / ideal - 1))),
        "max_relative_error_corrected": float(np.max(np.abs(corrected / ideal - 1))),
    }
    return (float(coef[0]), float(coef[1]), float(coef[2])), info
