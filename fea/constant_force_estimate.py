"""Closed-form feasibility estimate of a constant-force beam spec (force, stroke, length, material).

The constant-force beam of paper 003 (``pipeline/studies/constant_force.py``) is, once it has
buckled, a clamped–clamped column: S1 clamped, S6 driven along the work direction x with its
rotation and transverse motion held, the chord S1 -> S6 of length ``L`` at an angle ``phi`` to x
(31.0 degrees in the paper's frame). Its long-stroke optimum is close to a *uniform* beam of the
thinnest printable section with the width that restores the force (docs/constant_force.md,
"Why the widened box wins"). This module sizes that uniform beam in closed form and says whether
the spec is inside what the material can give, before any optimisation.

Derivation (units mm, N, MPa; ``E`` Young's modulus, ``b`` the out-of-plane width, ``t`` the
in-plane thickness, ``I = b t^3 / 12``)
---------------------------------------------------------------------------------------------

1. **Kinematics of the drive.** S6 moves ``d`` (the stroke) along -x with its transverse motion
   held, so the chord goes from ``L (cos phi, sin phi)`` to ``(L cos phi - d, L sin phi)``::

       c = sqrt(L^2 - 2 L d cos phi + d^2),    shortening Delta = L - c

   (the chord also turns by ``psi = atan2(L sin phi, L cos phi - d) - phi``; the nonlinear beam
   solve shows it adds < 2 % to the peak curvature, so it is left out).

2. **Post-buckled clamped–clamped elastica** (inflection points at L/4 and 3L/4; the middle half
   is Euler's pinned–pinned elastica of length L/2, the quarters at the ends are its halves). With
   ``K(m)``, ``E(m)`` the complete elliptic integrals of parameter ``m = k^2``, ``k = sin(a/2)``
   (``a`` the slope at the inflection points)::

       c / L     = 2 E(m) / K(m) - 1                       (chord of the buckled column)
       P         = 16 K(m)^2 E I / L^2                     (axial force; 4 pi^2 E I / L^2 at m = 0)
       kappa_max = 8 k K(m) / L                            (at the clamps and at mid-length)

   ``m`` follows from ``c / L`` by a scalar root (the right side falls monotonically from 1 at
   m = 0). For small amplitudes ``m ~ Delta / L`` and ``kappa_max ~ 4 pi sqrt(Delta / L) / L``.

3. **Strain at the stroke.** A section of thickness ``t`` bent to ``kappa`` has the outer-fibre
   strain ``t kappa / 2``; it must stay below the allowable strain ``sigma_allow / E``::

       sigma = E t kappa_max(d, L, phi) / 2 <= sigma_allow
       => t <= t_strain = 2 sigma_allow / (E kappa_max)

4. **Force level.** The force along x stays near the buckling load's x component (the elastica's
   ``P`` grows with ``m`` by ``(2 K / pi)^2`` while the chord turns away from x by ``psi``; the two
   nearly cancel, which is why the beam is constant-force)::

       F = 4 pi^2 E I cos(phi) / L^2 = pi^2 E b t^3 cos(phi) / (3 L^2)
       => t_force(b) = (3 F L^2 / (pi^2 E b cos phi))^(1/3)

5. **Feasibility.** The section the spec needs is the thinnest printable one that gives ``F``
   within the width allowed: ``t_req = max(t_min, t_force(b_max))``. The spec's peak stress is
   ``sigma(t_req)``; the figures that would make it feasible are

   * the strain-limited thickness ``t_strain`` and the largest force ``F_max`` at the stroke
     (``t_strain`` at ``b_max``; none when ``t_strain < t_min``: the stroke alone breaks the
     thinnest printable beam),
   * the longest stroke ``d_max`` with ``sigma(t_req) = sigma_allow``,
   * the shortest beam ``L_min`` with ``sigma(t_req(L)) = sigma_allow`` (``t_force`` grows as
     ``L^(2/3)``, ``kappa_max`` falls as ``L^(-3/2)``: the stress falls as ``L^(-5/6)``, or as
     ``L^(-3/2)`` where ``t_min`` binds), and
   * the width ``b`` at which ``t_force(b) = t_strain``.

   To leading order (small amplitude, ``Delta ~ d cos phi``) the stress and the shortest beam are
   closed forms::

       sigma ~ 2 pi E t sqrt(d cos phi) / L^(3/2)
       L_min ~ (2 pi E t_min sqrt(d cos phi) / sigma_allow)^(2/3)                 (t_min binds)
       L_min ~ (2 pi E sqrt(d cos phi) (3 F / (pi^2 E b_max cos phi))^(1/3) / sigma_allow)^(6/5)

   The module solves the exact relations of steps 1–2 instead (a few % apart at the paper's
   ``Delta / L = 0.19``).

Checked against the nonlinear beam solve (``fea.beam``) of uniform beams in the paper's frame and
scaled frames (``tests/fea/test_constant_force_estimate.py``): the peak stress within 3 % (the
estimate ~1 % low: the axial stress and the chord's turn are left out), the force within 3 %.

The verdict. A tapered beam can spread the curvature more evenly than the uniform elastica:
the least peak curvature any clamped–clamped shape with the same shortening can have is that of
a slope that zig-zags at constant ``|kappa|`` (``Delta = kappa^2 L^3 / 96``), ``sqrt(96) / (4 pi)
= 0.780`` of the elastica's. So a spec is refused (``infeasible``) only when the uniform estimate
exceeds the allowable by more than ``1 / 0.780`` (even a perfectly spread curvature would not
make it); it is ``marginal`` from ``MARGINAL_RATIO`` (0.9) of the allowable up to there (the
optimiser must find a tapered beam, or does not find any), ``feasible`` below.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, Literal

from scipy.special import ellipe, ellipk

__all__ = [
    "TAPER_GAIN",
    "MARGINAL_RATIO",
    "SpecEstimate",
    "chord_after_stroke_mm",
    "elastica_parameter",
    "peak_curvature_per_mm",
    "plateau_force_N",
    "thickness_for_force_mm",
    "peak_stress_MPa",
    "strain_limited_thickness_mm",
    "estimate_spec",
]

#: Least peak curvature of any clamped–clamped shape with a given end shortening (a slope that
#: zig-zags at constant |kappa|: Delta = kappa^2 L^3 / 96) over the uniform elastica's
#: (4 pi sqrt(Delta / L) / L): sqrt(96) / (4 pi).
TAPER_GAIN = math.sqrt(96.0) / (4.0 * math.pi)

#: Stress ratio (uniform estimate / allowable) from which a spec is called marginal: the estimate
#: runs ~1 % low, the plane-stress peak ~2 % above the beam's, and the optimiser needs room.
MARGINAL_RATIO = 0.9

# The elastica's chord falls to 0 at m = 0.8261 (the column's ends meet) and to -0.27 L at
# m = 0.95: far beyond any stroke a printed beam survives; K(m) is finite up to there.
_M_MAX = 0.95


def chord_after_stroke_mm(length_mm: float, angle_rad: float, stroke_mm: float) -> float:
    """Chord S1 -> S6 (mm) after S6 moved ``stroke_mm`` along -x, transverse motion held, for a
    chord of ``length_mm`` at ``angle_rad`` to x."""
    L, d = float(length_mm), float(stroke_mm)
    return math.sqrt(max(L * L - 2.0 * L * d * math.cos(angle_rad) + d * d, 0.0))


def elastica_parameter(chord_ratio: float) -> float:
    """``m = k^2`` of the clamped–clamped elastica whose chord is ``chord_ratio`` = c / L of its
    length (``c / L = 2 E(m) / K(m) - 1``); 0 for an unbuckled column (``chord_ratio >= 1``).

    Raises
    ------
    ValueError
        When the chord is shorter than the elastica reaches for m <= 0.95 (c / L < -0.27).
    """
    r = float(chord_ratio)
    if r >= 1.0:
        return 0.0

    def f(m: float) -> float:
        return 2.0 * ellipe(m) / ellipk(m) - 1.0 - r

    if f(_M_MAX) > 0:
        raise ValueError(f"chord / length = {r:.4g} is beyond the buckled column's reach")
    from scipy.optimize import brentq  # here: ~0.1 s CPU that importing a kind need not pay

    return float(brentq(f, 0.0, _M_MAX, xtol=1e-14, rtol=1e-12))


def peak_curvature_per_mm(length_mm: float, angle_rad: float, stroke_mm: float) -> float:
    """Largest curvature (1/mm) of the uniform clamped–clamped elastica of length ``length_mm``
    (mm) whose end S6 is driven ``stroke_mm`` (mm) along -x, chord at ``angle_rad`` to x:
    ``8 k K(m) / L`` (module docstring, steps 1–2)."""
    L = float(length_mm)
    m = elastica_parameter(chord_after_stroke_mm(L, angle_rad, stroke_mm) / L)
    return 8.0 * math.sqrt(m) * float(ellipk(m)) / L


def plateau_force_N(
    E_MPa: float, width_mm: float, thickness_mm: float, length_mm: float, angle_rad: float
) -> float:
    """Force (N) along x of the post-buckled uniform beam: ``pi^2 E b t^3 cos(phi) / (3 L^2)``."""
    b, t, L = float(width_mm), float(thickness_mm), float(length_mm)
    return math.pi**2 * E_MPa * b * t**3 * math.cos(angle_rad) / (3.0 * L * L)


def thickness_for_force_mm(
    force_N: float, E_MPa: float, width_mm: float, length_mm: float, angle_rad: float
) -> float:
    """Thickness (mm) of the uniform beam that gives ``force_N`` at width ``width_mm``."""
    L = float(length_mm)
    return (3.0 * force_N * L * L / (math.pi**2 * E_MPa * width_mm * math.cos(angle_rad))) ** (
        1.0 / 3.0
    )


def peak_stress_MPa(
    E_MPa: float, thickness_mm: float, length_mm: float, angle_rad: float, stroke_mm: float
) -> float:
    """Peak bending stress (MPa) of the uniform beam at the stroke: ``E t kappa_max / 2``."""
    return 0.5 * E_MPa * thickness_mm * peak_curvature_per_mm(length_mm, angle_rad, stroke_mm)


def strain_limited_thickness_mm(
    E_MPa: float, allowable_MPa: float, length_mm: float, angle_rad: float, stroke_mm: float
) -> float:
    """Thickest uniform section (mm) that stays at the allowable stress over the stroke:
    ``2 sigma_allow / (E kappa_max)``."""
    kappa = peak_curvature_per_mm(length_mm, angle_rad, stroke_mm)
    return math.inf if kappa <= 0 else 2.0 * allowable_MPa / (E_MPa * kappa)


@dataclass(frozen=True)
class SpecEstimate:
    """What the closed-form estimate says about a spec (module docstring). Lengths mm, forces N,
    stresses MPa; None where a figure does not exist.

    Attributes
    ----------
    status : ``feasible``, ``marginal`` or ``infeasible``.
    limit : what limits it: ``stroke`` (the stroke alone needs more strain than the thinnest
        printable section has), ``force`` (the force needs a section the stroke breaks),
        ``geometry`` (the stroke is longer than the beam can be driven), ``small_force`` (below
        the force of the thinnest, narrowest printable beam) or ``none``.
    thickness_mm, width_mm : the uniform beam the estimate sizes (t_req, and its width).
    peak_stress_MPa, stress_ratio : its peak stress at the stroke and that over the allowable.
    max_thickness_mm : t_strain. max_force_N : F at t_strain and width_max (None below t_min).
    max_stroke_mm : the stroke at which the sized beam reaches the allowable.
    min_length_mm : the shortest beam whose sized section stays at the allowable.
    min_width_mm : the width at which the force's section is t_strain (None below t_min).
    min_force_N : the force of the thinnest, narrowest printable beam (t_min x t_min).
    """

    status: Literal["feasible", "marginal", "infeasible"]
    limit: str
    force_N: float
    stroke_mm: float
    length_mm: float
    angle_rad: float
    E_MPa: float
    allowable_MPa: float
    width_max_mm: float
    min_thickness_mm: float
    thickness_mm: float
    width_mm: float
    peak_stress_MPa: float
    stress_ratio: float
    max_thickness_mm: float
    max_force_N: float | None
    max_stroke_mm: float | None
    min_length_mm: float | None
    min_width_mm: float | None
    min_force_N: float

    def as_dict(self) -> dict[str, Any]:
        """The figures as plain numbers (JSON)."""
        return asdict(self)


def _sized_thickness(force, E, b_max, t_min, L, phi) -> float:  # type: ignore[no-untyped-def]
    return max(t_min, thickness_for_force_mm(force, E, b_max, L, phi))


def estimate_spec(
    force_N: float,
    stroke_mm: float,
    length_mm: float,
    angle_rad: float,
    E_MPa: float,
    allowable_MPa: float,
    width_max_mm: float,
    min_thickness_mm: float,
) -> SpecEstimate:
    """Size the uniform constant-force beam for a spec and judge it (module docstring).

    Parameters
    ----------
    force_N : the force to hold, N. stroke_mm : the drive, mm.
    length_mm : the beam's chord S1 -> S6, mm. angle_rad : its angle to the work direction, rad.
    E_MPa, allowable_MPa : Young's modulus and the allowable stress, MPa.
    width_max_mm : the largest out-of-plane width, mm. min_thickness_mm : the thinnest printable
        section, mm (also the narrowest width).

    Returns
    -------
    SpecEstimate
    """
    F, d, L, phi = float(force_N), float(stroke_mm), float(length_mm), float(angle_rad)
    E, allow, b_max, t_min = (
        float(E_MPa),
        float(allowable_MPa),
        float(width_max_mm),
        float(min_thickness_mm),
    )
    min_force = plateau_force_N(E, t_min, t_min, L, phi)
    common = dict(
        force_N=F, stroke_mm=d, length_mm=L, angle_rad=phi, E_MPa=E, allowable_MPa=allow,
        width_max_mm=b_max, min_thickness_mm=t_min, min_force_N=min_force,
    )  # fmt: skip
    if d >= 0.8 * L * math.cos(phi):  # S6 would reach the clamp's abscissa: not a column any more
        t = _sized_thickness(F, E, b_max, t_min, L, phi)
        return SpecEstimate(
            "infeasible", "geometry", thickness_mm=t, width_mm=b_max, peak_stress_MPa=math.inf,
            stress_ratio=math.inf, max_thickness_mm=0.0, max_force_N=None, max_stroke_mm=None,
            min_length_mm=d / (0.8 * math.cos(phi)), min_width_mm=None, **common,
        )  # fmt: skip
    t_force = thickness_for_force_mm(F, E, b_max, L, phi)
    t = max(t_min, t_force)
    width = b_max if t_force >= t_min else b_max * (t_force / t_min) ** 3
    sigma = peak_stress_MPa(E, t, L, phi, d)
    ratio = sigma / allow
    t_strain = strain_limited_thickness_mm(E, allow, L, phi, d)
    printable = t_strain >= t_min
    max_force = plateau_force_N(E, b_max, t_strain, L, phi) if printable else None
    min_width = (
        3.0 * F * L * L / (math.pi**2 * E * t_strain**3 * math.cos(phi)) if printable else None
    )

    from scipy.optimize import brentq  # here: ~0.1 s CPU that importing a kind need not pay

    def over_stroke(s: float) -> float:
        return peak_stress_MPa(E, t, L, phi, s) - allow

    s_top = 0.8 * L * math.cos(phi)
    max_stroke = (
        None if over_stroke(1e-9) >= 0 else (
            s_top if over_stroke(s_top) <= 0 else float(brentq(over_stroke, 1e-9, s_top))
        )
    )  # fmt: skip

    def over_length(length: float) -> float:
        t_len = _sized_thickness(F, E, b_max, t_min, length, phi)
        return peak_stress_MPa(E, t_len, length, phi, d) - allow

    lo = d / (0.8 * math.cos(phi))
    hi = max(10.0 * L, 10.0 * lo)
    if over_length(lo) <= 0:
        min_length: float | None = lo
    elif over_length(hi) > 0:
        min_length = None
    else:
        min_length = float(brentq(over_length, lo, hi, xtol=1e-6))
    if ratio * TAPER_GAIN > 1.0:
        status, limit = "infeasible", ("force" if printable else "stroke")
    elif F < min_force:
        status, limit = "infeasible", "small_force"
    elif ratio > MARGINAL_RATIO:
        status, limit = "marginal", ("force" if printable else "stroke")
    else:
        status, limit = "feasible", "none"
    return SpecEstimate(
        status, limit, thickness_mm=t, width_mm=width, peak_stress_MPa=sigma, stress_ratio=ratio,
        max_thickness_mm=t_strain, max_force_N=max_force, max_stroke_mm=max_stroke,
        min_length_mm=min_length, min_width_mm=min_width, **common,
    )  # fmt: skip
