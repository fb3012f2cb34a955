r"""Closed-form stiffness and stress of flexure pivots, with the reference for each formula.

Every formula here is the Euler–Bernoulli idealisation its authors derived (plane sections, small
rotation of the compliant part, the blocks rigid); the FE in :mod:`fea.pivot` is the judge of
where they hold. Units: E in MPa (N/mm²), lengths in mm, stiffness in N·mm/rad, stress in MPa.

Pure-moment rotational compliance of a straight hinge of width ``b`` and thickness profile
``t(x)`` over its compliant length (Castigliano; the integral behind Paros & Weisbord 1965 and
every formula of Lobontiu 2003, Ch. 2)::

    C = theta / M = (12 / (E b)) * integral dx / t(x)^3,          K = 1 / C

Per type (the YAML names of :mod:`geometry.flexures`):

* ``leaf`` — ``K = E I / L``: the small-length flexural pivot, pivot at the middle (Howell 2001,
  Compliant Mechanisms, §5.2); exact for a uniform leaf under a pure moment. A long leaf under a
  tip force is Howell's PRB 1R model: characteristic radius ``gamma = 0.85``, stiffness
  coefficient ``K_Theta = 2.65``, ``K = gamma K_Theta E I / L``, pivot at ``(1 - gamma) L`` from
  the clamp (Howell 2001, §5.3; Howell, Midha & Norton 1996).
* ``variable_leaf`` — the integral for a thickness linear between stations: a segment of length
  ``h`` from ``t1`` to ``t2`` gives ``12 h (t1 + t2) / (2 E b t1^2 t2^2)``.
* ``circular_notch`` — Paros & Weisbord (1965), exact for the profile
  ``t + 2R - 2 sqrt(R^2 - x^2)``, with ``beta = t / (2R)``::

      C = 3 / (2 E b R^2 (2 beta + beta^2))
          * [ (3 + 4 beta + 2 beta^2) / ((1 + beta)(2 beta + beta^2))
              + 6 (1 + beta) / (2 beta + beta^2)^(3/2) * atan(sqrt((2 + beta) / beta)) ]

  and simplified for ``t << R``: ``C = 9 pi sqrt(R) / (2 E b t^(5/2))``.
* ``elliptical_notch`` — the profile integral for ``t + 2c (1 - sqrt(1 - x^2/a^2))`` (Smith et al.
  1997; Lobontiu 2003, §2.4) by adaptive quadrature, and its ``t << c`` limit
  ``C = 9 pi a / (2 E b t^(5/2) sqrt(c))`` (a = c gives Paros–Weisbord's simplified form).
* ``corner_filleted`` — ``C = 12 L / (E b t^3) + C_circular(r, t)``: the straight web plus two
  quarter-circle fillets, which together are one circular notch of radius r (Lobontiu, Paine,
  Garcia & Goldfarb 2001).
* ``cross_axis`` — ``K = 2 E I / L`` for two equal leaves crossing at their middles under a pure
  moment: each leaf turns with its ends about its own middle, so it carries the uniform moment
  ``E I theta / L`` and no shear (Wittrick 1948; Jensen & Howell 2002, whose PRB model reduces to
  it with no applied force).

Stress: the nominal bending stress at the thinnest section, ``sigma = 6 M / (b t_min^2)`` with
``M = K theta``; for leaves under a pure moment this is ``E t theta / (2 L)``. Notches add a
stress concentration at the web; the estimate used here is ``K_t = (1 + t / (2 rho))^(9/20)``
with ``rho`` the cut's radius of curvature at the web (Smith 2000, Flexures, a fit to Peterson's
notched-bar data; for a corner-filleted hinge ``rho`` is the fillet radius, where the fillets
start). tests/geometry/test_flexures.py measures how far these are from plane stress.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.geometry.flexures import (
    CircularNotch,
    CornerFilleted,
    CrossAxis,
    EllipticalNotch,
    Flexure,
    Leaf,
    VariableLeaf,
)
from scipy.integrate import quad

__all__ = [
    "PRB_GAMMA",
    "PRB_K_THETA",
    "PRB_C_THETA",
    "PivotClosedForm",
    "CLOSED_FORMS",
    "pivot_closed_form",
    "second_moment_mm4",
    "leaf_stiffness_Nmm",
    "leaf_stress_MPa",
    "prb_cantilever_stiffness_Nmm",
    "prb_cantilever_tip_mm",
    "prb_cantilever_load_for_angle_N",
    "variable_leaf_compliance",
    "profile_compliance",
    "circular_notch_compliance",
    "circular_notch_compliance_simplified",
    "elliptical_notch_compliance",
    "elliptical_notch_compliance_simplified",
    "corner_filleted_compliance",
    "cross_axis_stiffness_Nmm",
    "ArmSpringLinear",
    "arm_spring_linear",
    "notch_stress_concentration",
]

#: Howell's PRB 1R model of a cantilever with a tip force (n = 0): characteristic radius factor,
#: stiffness coefficient (2.61..2.67 over the load angles; 2.65 is Howell's average) and the
#: parametric angle coefficient (tip slope = c_theta x PRB angle).
PRB_GAMMA = 0.85
PRB_K_THETA = 2.65
PRB_C_THETA = 1.24


@dataclass(frozen=True)
class PivotClosedForm:
    """Closed-form pure-moment behaviour of one flexure.

    Attributes
    ----------
    stiffness_Nmm_per_rad : float, N·mm/rad — K = M / theta.
    stress_per_rad_MPa : float, MPa/rad — peak stress per radian of rotation (linear theory,
        stress concentration included for notches).
    nominal_stress_per_rad_MPa : float, MPa/rad — the same without stress concentration.
    stress_concentration : float — K_t used (1 for leaves).
    formula : str — the formula in words.
    reference : str — where it comes from.
    alternatives : dict — other closed forms of the same stiffness (e.g. the simplified one),
        N·mm/rad by name.
    """

    stiffness_Nmm_per_rad: float
    stress_per_rad_MPa: float
    nominal_stress_per_rad_MPa: float
    stress_concentration: float
    formula: str
    reference: str
    alternatives: dict[str, float] = field(default_factory=dict)

    def torque_Nmm(self, angle_rad: np.ndarray | float) -> np.ndarray:
        """Linear torque K theta, N·mm."""
        return self.stiffness_Nmm_per_rad * np.asarray(angle_rad, dtype=float)

    def stress_MPa(self, angle_rad: np.ndarray | float) -> np.ndarray:
        """Linear peak stress, MPa."""
        return self.stress_per_rad_MPa * np.abs(np.asarray(angle_rad, dtype=float))


# --------------------------------------------------------------------------------------------
# Leaves


def second_moment_mm4(width_mm: float, thickness_mm: float) -> float:
    """I = b t^3 / 12 of a rectangle, mm^4."""
    return width_mm * thickness_mm**3 / 12.0


def leaf_stiffness_Nmm(
    E_MPa: float, width_mm: float, thickness_mm: float, length_mm: float
) -> float:
    """Small-length flexural pivot K = E I / L, N·mm/rad (Howell 2001, §5.2)."""
    return E_MPa * second_moment_mm4(width_mm, thickness_mm) / length_mm


def leaf_stress_MPa(E_MPa: float, thickness_mm: float, length_mm: float, angle_rad: float) -> float:
    """Bending stress of a leaf under a pure moment, E t theta / (2 L), MPa."""
    return E_MPa * thickness_mm * abs(angle_rad) / (2.0 * length_mm)


def prb_cantilever_stiffness_Nmm(
    E_MPa: float, width_mm: float, thickness_mm: float, length_mm: float
) -> float:
    """PRB torsion spring of a long leaf under a tip force, gamma K_Theta E I / L, N·mm/rad
    (Howell 2001, §5.3)."""
    return PRB_GAMMA * PRB_K_THETA * E_MPa * second_moment_mm4(width_mm, thickness_mm) / length_mm


def prb_cantilever_tip_mm(length_mm: float, prb_angle_rad: np.ndarray | float) -> np.ndarray:
    """PRB tip position (x along the undeformed leaf, y across), mm, shape (..., 2).

    ``x = L (1 - gamma (1 - cos Theta))``, ``y = gamma L sin Theta`` (Howell 2001, Eq. 5.1-5.2).
    """
    th = np.asarray(prb_angle_rad, dtype=float)
    x = length_mm * (1.0 - PRB_GAMMA * (1.0 - np.cos(th)))
    y = PRB_GAMMA * length_mm * np.sin(th)
    return np.stack([x, y], axis=-1)


def prb_cantilever_load_for_angle_N(
    E_MPa: float, width_mm: float, thickness_mm: float, length_mm: float, prb_angle_rad: float
) -> float:
    """Tip force perpendicular to the undeformed leaf that turns the PRB link by Theta, N.

    Moment balance of the PRB link about its pivot: ``K Theta = P gamma L cos Theta``.
    """
    K = prb_cantilever_stiffness_Nmm(E_MPa, width_mm, thickness_mm, length_mm)
    th = float(prb_angle_rad)
    return K * th / (PRB_GAMMA * length_mm * math.cos(th))


def variable_leaf_compliance(
    E_MPa: float, width_mm: float, length_mm: float, thicknesses_mm: np.ndarray
) -> float:
    """theta / M of a leaf whose thickness is linear between k equally spaced stations, rad/(N·mm).

    Exact integral of 12 / (E b t^3) over each linear segment: ``12 h (t1 + t2) / (2 E b t1^2
    t2^2)`` (equal ends give ``12 h / (E b t^3)``).
    """
    t = np.asarray(thicknesses_mm, dtype=float)
    h = length_mm / (t.size - 1)
    t1, t2 = t[:-1], t[1:]
    return float(np.sum(12.0 * h * (t1 + t2) / (2.0 * E_MPa * width_mm * t1**2 * t2**2)))


# --------------------------------------------------------------------------------------------
# Notches


def profile_compliance(
    E_MPa: float,
    width_mm: float,
    thickness: Callable[[float], float],
    x0_mm: float,
    x1_mm: float,
    points: tuple[float, ...] = (),
) -> float:
    """theta / M = 12 / (E b) * integral_x0^x1 dx / t(x)^3, rad/(N·mm), by adaptive quadrature.

    ``points`` are abscissae where t(x) changes character (the web, fillet ends), handed to QUADPACK
    so the sharp peak of 1/t^3 at a thin web is resolved.
    """
    value, err = quad(
        lambda x: 1.0 / thickness(x) ** 3,
        x0_mm,
        x1_mm,
        points=list(points) or None,
        limit=400,
        epsabs=0.0,
        epsrel=1e-12,
    )
    return 12.0 * value / (E_MPa * width_mm)


def circular_notch_compliance(
    E_MPa: float, width_mm: float, radius_mm: float, thickness_mm: float
) -> float:
    """Paros & Weisbord (1965) exact theta / M of a right-circular hinge, rad/(N·mm).

    The closed form of ``12/(E b) int_{-R}^{R} dx / (t + 2R - 2 sqrt(R^2 - x^2))^3`` (derived in
    docs/flexures.md: x = R sin phi and the tangent half-angle substitution).
    """
    R, t = radius_mm, thickness_mm
    beta = t / (2.0 * R)
    q = 2.0 * beta + beta * beta
    g = math.atan(math.sqrt((2.0 + beta) / beta))
    bracket = (3.0 + 4.0 * beta + 2.0 * beta * beta) / ((1.0 + beta) * q) + 6.0 * (
        1.0 + beta
    ) * g / q**1.5
    return 3.0 * bracket / (2.0 * E_MPa * width_mm * R * R * q)


def circular_notch_compliance_simplified(
    E_MPa: float, width_mm: float, radius_mm: float, thickness_mm: float
) -> float:
    """Paros & Weisbord's simplified form for t << R: 9 pi sqrt(R) / (2 E b t^(5/2))."""
    return 9.0 * math.pi * math.sqrt(radius_mm) / (2.0 * E_MPa * width_mm * thickness_mm**2.5)


def elliptical_notch_compliance(
    E_MPa: float, width_mm: float, half_length_mm: float, depth_mm: float, thickness_mm: float
) -> float:
    """theta / M of an elliptical notch hinge by the profile integral, rad/(N·mm)."""
    a, c, t = half_length_mm, depth_mm, thickness_mm

    def th(x: float) -> float:
        u = min(abs(x) / a, 1.0)
        return t + 2.0 * c * (1.0 - math.sqrt(1.0 - u * u))

    # symmetric: twice the half integral, with the web at the end point
    return 2.0 * profile_compliance(E_MPa, width_mm, th, 0.0, a)


def elliptical_notch_compliance_simplified(
    E_MPa: float, width_mm: float, half_length_mm: float, depth_mm: float, thickness_mm: float
) -> float:
    """t << c limit of the elliptical integral: 9 pi a / (2 E b t^(5/2) sqrt(c)).

    Near the web t(x) ~ t + c x^2 / a^2, and int dx / (t + c x^2/a^2)^3 over the line is
    (3 pi / 8) a / (t^(5/2) sqrt(c)).
    """
    a, c, t = half_length_mm, depth_mm, thickness_mm
    return 9.0 * math.pi * a / (2.0 * E_MPa * width_mm * t**2.5 * math.sqrt(c))


def corner_filleted_compliance(
    E_MPa: float, width_mm: float, length_mm: float, fillet_radius_mm: float, thickness_mm: float
) -> float:
    """theta / M of a corner-filleted hinge: web 12 L / (E b t^3) plus one circular notch of the
    fillet radius (the two quarter-circle fillets), rad/(N·mm)."""
    web = 12.0 * length_mm / (E_MPa * width_mm * thickness_mm**3)
    return web + circular_notch_compliance(E_MPa, width_mm, fillet_radius_mm, thickness_mm)


def cross_axis_stiffness_Nmm(
    E_MPa: float, width_mm: float, thickness_mm: float, length_mm: float
) -> float:
    """Pure-moment stiffness of a symmetric cross-axis pivot, 2 E I / L, N·mm/rad."""
    return 2.0 * leaf_stiffness_Nmm(E_MPa, width_mm, thickness_mm, length_mm)


def notch_stress_concentration(thickness_mm: float, root_radius_mm: float) -> float:
    """K_t = (1 + t / (2 rho))^(9/20) at the web of a notch of root radius rho (Smith 2000)."""
    return (1.0 + thickness_mm / (2.0 * root_radius_mm)) ** 0.45


# --------------------------------------------------------------------------------------------
# Registry: one function per flexure type


def _nominal_stress_per_rad(K: float, width_mm: float, t_min: float) -> float:
    return 6.0 * K / (width_mm * t_min**2)


def drawn_leaf_compliance(
    E_MPa: float, width_mm: float, x_mm: np.ndarray, t_mm: np.ndarray
) -> float:
    """theta / M of a leaf whose thickness is linear between stations ``x_mm`` (k,) mm of
    thickness ``t_mm`` (k,) mm (any spacing; a leaf with root fillets as drawn), rad/(N·mm): the
    Euler-Bernoulli integral, exact per segment, sum 12 h (t1 + t2) / (2 E b t1^2 t2^2)."""
    h, t1, t2 = np.diff(x_mm), t_mm[:-1], t_mm[1:]
    return float(np.sum(12.0 * h * (t1 + t2) / (2.0 * E_MPa * width_mm * t1**2 * t2**2)))


def _leaf(f: Leaf, E: float) -> PivotClosedForm:
    b, t, L = f.width_mm, f.thickness_mm, f.length_mm
    K = leaf_stiffness_Nmm(E, b, t, L)
    if f.root_fillet_mm > 0:  # the fillets' flare stiffens the leaf (E I / L without it)
        K = 1.0 / drawn_leaf_compliance(E, b, *f.profile())
    s = leaf_stress_MPa(E, t, L, 1.0)
    return PivotClosedForm(
        K,
        s * f.root_kt,  # root fillets: their shoulder Kt (1 for sharp roots, not bounded)
        s,
        f.root_kt,
        "K = E I / L, sigma = E t theta / (2 L); pivot at the middle",
        "Howell (2001) Compliant Mechanisms, §5.2 (small-length flexural pivot)",
        {"prb_long_leaf_tip_force_Nmm_per_rad": prb_cantilever_stiffness_Nmm(E, b, t, L)},
    )


def _variable_leaf(f: VariableLeaf, E: float) -> PivotClosedForm:
    C = variable_leaf_compliance(E, f.width_mm, f.length_mm, f.station_thicknesses)
    if f.root_fillet_mm > 0:  # with the fillets' flare
        C = drawn_leaf_compliance(E, f.width_mm, *f.profile())
    K = 1.0 / C
    s = _nominal_stress_per_rad(K, f.width_mm, f.min_thickness_mm)
    return PivotClosedForm(
        K,
        s * f.root_kt,  # the roots' Kt on the thinnest section's stress: an upper bound
        s,
        f.root_kt,
        "C = sum 12 h (t1 + t2) / (2 E b t1^2 t2^2) over the linear segments; "
        "sigma = 6 K theta / (b t_min^2)",
        "Euler-Bernoulli compliance integral (Castigliano), e.g. Lobontiu (2003) Compliant "
        "Mechanisms: Design of Flexure Hinges, Ch. 2",
    )


def _circular(f: CircularNotch, E: float) -> PivotClosedForm:
    b, R, t = f.width_mm, f.radius_mm, f.thickness_mm
    K = 1.0 / circular_notch_compliance(E, b, R, t)
    kt = notch_stress_concentration(t, R)
    s = _nominal_stress_per_rad(K, b, t)
    return PivotClosedForm(
        K,
        kt * s,
        s,
        kt,
        "Paros-Weisbord exact compliance; sigma = K_t 6 K theta / (b t^2), "
        "K_t = (1 + t/(2R))^(9/20)",
        "Paros & Weisbord (1965) Machine Design 37(27):151-156; K_t: Smith (2000) Flexures",
        {
            "paros_weisbord_simplified_Nmm_per_rad": 1.0
            / circular_notch_compliance_simplified(E, b, R, t),
        },
    )


def _elliptical(f: EllipticalNotch, E: float) -> PivotClosedForm:
    b, a, c, t = f.width_mm, f.half_length_mm, f.depth_mm, f.thickness_mm
    K = 1.0 / elliptical_notch_compliance(E, b, a, c, t)
    kt = notch_stress_concentration(t, f.root_radius_mm)
    s = _nominal_stress_per_rad(K, b, t)
    return PivotClosedForm(
        K,
        kt * s,
        s,
        kt,
        "profile integral 12/(E b) int dx / t(x)^3; sigma = K_t 6 K theta / (b t^2), "
        "K_t = (1 + t c / (2 a^2))^(9/20)",
        "Smith, Badami, Dale & Xu (1997) Rev. Sci. Instrum. 68:1474; Lobontiu (2003) §2.4",
        {"thin_web_limit_Nmm_per_rad": 1.0 / elliptical_notch_compliance_simplified(E, b, a, c, t)},
    )


def _corner_filleted(f: CornerFilleted, E: float) -> PivotClosedForm:
    b, L, r, t = f.width_mm, f.length_mm, f.fillet_radius_mm, f.thickness_mm
    K = 1.0 / corner_filleted_compliance(E, b, L, r, t)
    # The peak sits where the fillets start: the circular-notch fit at the fillet radius is used
    # as the estimate (conservative by 4-8 % against plane stress at r/t = 0.5-1.25).
    kt = notch_stress_concentration(t, r)
    s = _nominal_stress_per_rad(K, b, t)
    return PivotClosedForm(
        K,
        kt * s,
        s,
        kt,
        "C = 12 L / (E b t^3) + C_circular(r, t); sigma = K_t 6 K theta / (b t^2), "
        "K_t = (1 + t/(2r))^(9/20)",
        "Lobontiu, Paine, Garcia & Goldfarb (2001) J. Mech. Des. 123:346-352; K_t: Smith (2000)",
    )


def _cross_axis(f: CrossAxis, E: float) -> PivotClosedForm:
    b, t, L = f.width_mm, f.thickness_mm, f.length_mm
    K = cross_axis_stiffness_Nmm(E, b, t, L)
    s = leaf_stress_MPa(E, t, L, 1.0)
    return PivotClosedForm(
        K,
        s,
        s,
        1.0,
        "K = 2 E I / L, sigma = E t theta / (2 L); pivot at the crossing",
        "Wittrick (1948) Aeronaut. Q. 1:121; Jensen & Howell (2002) Mech. Mach. Theory 37:461",
    )


CLOSED_FORMS: dict[str, Callable[[Flexure, float], PivotClosedForm]] = {
    "leaf": _leaf,  # type: ignore[dict-item]
    "variable_leaf": _variable_leaf,  # type: ignore[dict-item]
    "circular_notch": _circular,  # type: ignore[dict-item]
    "elliptical_notch": _elliptical,  # type: ignore[dict-item]
    "corner_filleted": _corner_filleted,  # type: ignore[dict-item]
    "cross_axis": _cross_axis,  # type: ignore[dict-item]
}
"""Closed form of each flexure type by its YAML name."""


def pivot_closed_form(flexure: Flexure, E_MPa: float) -> PivotClosedForm:
    """The closed-form pure-moment stiffness and stress of ``flexure``.

    Raises
    ------
    FeaError
        For a flexure type without a closed form (the message lists those with one).
    """
    fn = CLOSED_FORMS.get(flexure.kind)
    if fn is None:
        raise FeaError(
            f"no closed form for flexure kind '{flexure.kind}'; known: {', '.join(CLOSED_FORMS)}"
        )
    if not (math.isfinite(E_MPa) and E_MPa > 0):
        raise FeaError(f"E_MPa = {E_MPa!r} must be > 0")
    return fn(flexure, float(E_MPa))


@dataclass(frozen=True)
class ArmSpringLinear:
    """Linear (Euler-Bernoulli, Castigliano) response of a hub carried by curved arms.

    Attributes
    ----------
    stiffness_Nmm_per_rad : float, N·mm/rad — hub torque per hub rotation, all arms.
    moment_Nmm_per_rad : (s,) float, N·mm/rad — bending moment along one arm per hub rotation.
    end_load_per_rad : (3,) float — (Fx N, Fy N, M N·mm) the hub applies to one arm, per rad.
    stress_MPa_per_rad : (s,) float, MPa/rad — outer-fibre bending stress 6|M|/(b w^2).
    """

    stiffness_Nmm_per_rad: float
    moment_Nmm_per_rad: np.ndarray
    end_load_per_rad: np.ndarray
    stress_MPa_per_rad: np.ndarray


def arm_spring_linear(
    xy_mm: np.ndarray, width_mm: np.ndarray, E_MPa: float, thickness_mm: float, n_arms: int
) -> ArmSpringLinear:
    r"""Small-rotation stiffness and moment of ``n_arms`` identical curved arms between a hub
    turning about the origin and clamped outer ends (the elastic-centre / Castigliano method).

    Arm 0 runs from the hub end A = ``xy_mm[0]`` (fixed to the hub) to the clamped end
    ``xy_mm[-1]``. A load (Fx, Fy, M) applied by the hub at A gives the bending moment
    ``M(s) = M + (x_A - x(s)) Fy - (y_A - y(s)) Fx`` and the complementary energy
    ``U* = \int M^2 / (2 E I) + N^2 / (2 E A) ds`` with the axial force ``N = F . t(s)`` (the
    axial term is second order for a curved slender arm but makes a straight spoke determinate;
    shear is left out). Its gradient is the displacement of A, ``C [Fx, Fy, M]`` with
    ``C = \int g g^T / (E I) + h h^T / (E A) ds``, ``g = [-(y_A - y), x_A - x, 1]``,
    ``h = [t_x, t_y, 0]``. A rigid hub rotation theta
    moves A by ``theta (-y_A, x_A)`` and turns it by theta, so ``[Fx, Fy, M] = theta C^{-1}
    [-y_A, x_A, 1]``, and the hub torque is ``n (M + x_A Fy - y_A Fx)``. When the arm's elastic
    centre (the 1/EI-weighted centroid of its centreline) is the origin, Fx = Fy = 0 and the arm
    carries a uniform moment: the lower bound of the peak stress for a given stiffness.

    Parameters
    ----------
    xy_mm : (s, 2) float, mm — centreline from the hub end to the clamped end.
    width_mm : (s,) float, mm — in-plane width w (bending depth) at those points.
    E_MPa : float, MPa.
    thickness_mm : float, mm — out-of-plane thickness b.
    n_arms : int.

    Returns
    -------
    ArmSpringLinear
    """
    xy = np.asarray(xy_mm, dtype=float)
    w = np.asarray(width_mm, dtype=float)
    seg = np.hypot(*np.diff(xy, axis=0).T)
    ds = np.zeros(len(xy))  # trapezoid weights
    ds[:-1] += 0.5 * seg
    ds[1:] += 0.5 * seg
    a = xy[0]
    g = np.column_stack([-(a[1] - xy[:, 1]), a[0] - xy[:, 0], np.ones(len(xy))])
    ei = E_MPa * thickness_mm * w**3 / 12.0
    ea = E_MPa * thickness_mm * w
    tangent = np.gradient(xy, axis=0)
    tangent /= np.hypot(tangent[:, 0], tangent[:, 1])[:, None]
    h = np.column_stack([tangent, np.zeros(len(xy))])  # axial force N = F . t
    C = np.einsum("si,sj,s->ij", g, g, ds / ei) + np.einsum("si,sj,s->ij", h, h, ds / ea)
    load = np.linalg.solve(C, np.array([-a[1], a[0], 1.0]))
    torque = float(n_arms * (load[2] + a[0] * load[1] - a[1] * load[0]))
    moment = g @ load
    return ArmSpringLinear(
        stiffness_Nmm_per_rad=torque,
        moment_Nmm_per_rad=moment,
        end_load_per_rad=load,
        stress_MPa_per_rad=6.0 * np.abs(moment) / (thickness_mm * w**2),
    )
