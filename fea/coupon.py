"""Test coupons for calibrating a printer and a spool: strips of several nominal thicknesses.

Why several thicknesses
-----------------------
A single strip bent as a cantilever measures only its bending stiffness ``E b t^3 / 12``: its
Young's modulus and its printed thickness cannot be told apart from one curve, at small or large
deflection alike (under displacement control the deformed shape of an elastica does not depend on
``E``, so the force is exactly proportional to ``E I``). A printer's walls, however, come out
thicker or thinner than drawn by an offset ``dt`` that is nearly the same for every wall (the
extrusion width error), and the force of a strip of nominal thickness ``t`` goes as
``E (t + dt)^3``. Strips of two or more thicknesses therefore separate ``E`` from ``dt``: their
force ratio depends on ``dt`` alone. The default coupon has three strips (0.8, 1.2, 1.6 mm: two,
three and four 0.4 mm lines), printed side by side on one clamp block, in the same orientation as
the part (the strip's thickness in the bed plane, its width = the printed height).

The test
--------
Each strip is a cantilever of free length ``length_mm`` clamped in its block; its tip (the drive
tab) is pushed perpendicular to the strip, displacement controlled, up to ``stroke_mm``, with the
tab free to rotate and to slide along the strip (a pin in a slot, or a roller on a flat pusher):
the force measured is then the tip force normal to the undeformed strip, the classic large-
deflection cantilever under a tip load of fixed direction. The stroke is sized so the thickest
strip stays below ``stress_fraction`` of the material's allowable (the curve must be elastic).

Units: mm, N, MPa.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from flexopt.fea.beam import BeamSettings, EndDrive, solve_beam
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.geometry.profile import BeamProfile

__all__ = ["CouponSpec", "StripCurve", "coupon_stroke_mm", "strip_curve", "coupon_curves"]


@dataclass(frozen=True)
class CouponSpec:
    """A calibration coupon: strips of several nominal thicknesses on one clamp block.

    Attributes
    ----------
    thicknesses_mm : (k,) float, mm — nominal (drawn) strip thicknesses, k >= 2 distinct values
        to separate E from the thickness offset (module docstring).
    length_mm : float, mm — free length of each strip (clamp face to the drive point).
    width_mm : float, mm — out-of-plane width of the strips (their printed height).
    stroke_mm : float, mm, optional — tip displacement at the end of the test; ``None`` sizes it
        with :func:`coupon_stroke_mm`.
    steps : int — rows of the predicted curve after the undeformed row.
    stress_fraction : float — the thickest strip's peak stress at the stroke stays below this
        fraction of the allowable (elastic test, margin for a stiffer-than-drawn print).
    max_stroke_fraction : float — the stroke never exceeds this fraction of ``length_mm`` (past it
        the tip slides far along the pusher and friction matters).
    n_elements : int — beam elements per strip (the curve converges to 1e-6 relative by 20,
        tests/fea/test_coupon.py).
    """

    thicknesses_mm: tuple[float, ...] = (0.8, 1.2, 1.6)
    length_mm: float = 40.0
    width_mm: float = 10.0
    stroke_mm: float | None = None
    steps: int = 40
    stress_fraction: float = 0.5
    max_stroke_fraction: float = 0.3
    n_elements: int = 20

    def __post_init__(self) -> None:
        t = tuple(float(v) for v in self.thicknesses_mm)
        object.__setattr__(self, "thicknesses_mm", t)
        if len(set(t)) < 2 or min(t) <= 0 or not all(math.isfinite(v) for v in t):
            raise FeaError(
                f"coupon thicknesses_mm = {list(t)}: give at least two different positive "
                "thicknesses (one strip cannot tell E from the printed thickness)"
            )
        for name in ("length_mm", "width_mm", "stress_fraction", "max_stroke_fraction"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0):
                raise FeaError(f"coupon {name} = {value} must be a positive number")
        if max(t) > 0.2 * self.length_mm:
            raise FeaError(
                f"coupon strips up to {max(t)} mm thick on a {self.length_mm} mm length are not "
                "slender beams; make length_mm at least 5 x the thickest strip"
            )
        if self.stroke_mm is not None and not (
            math.isfinite(self.stroke_mm) and 0 < self.stroke_mm <= self.length_mm
        ):
            raise FeaError(
                f"coupon stroke_mm = {self.stroke_mm} must lie in (0, length_mm = {self.length_mm}]"
            )
        if int(self.steps) < 5:
            raise FeaError(f"coupon steps = {self.steps}: at least 5 rows are needed")


@dataclass(frozen=True)
class StripCurve:
    """The predicted force-displacement curve of one strip.

    Attributes
    ----------
    thickness_mm : float, mm — the thickness the strip was solved with (nominal + offset).
    displacement_mm : (steps + 1,) float, mm — tip displacement normal to the strip.
    force_N : (steps + 1,) float, N — tip force along the same direction.
    peak_stress_MPa : (steps + 1,) float, MPa — largest |N|/A + |M|c/I along the strip.
    """

    thickness_mm: float
    displacement_mm: np.ndarray
    force_N: np.ndarray
    peak_stress_MPa: np.ndarray


def coupon_stroke_mm(spec: CouponSpec, material: Material) -> float:
    """The test stroke (mm): ``spec.stroke_mm`` when it is given; otherwise the tip displacement at
    which the thickest strip's solved peak stress reaches ``stress_fraction`` of the allowable,
    capped at ``max_stroke_fraction * length_mm``.

    The thickest strip is traced to the cap and the stroke read off its solved stress path (linear
    interpolation between rows, 0.1 % below): the small-deflection estimate
    ``delta = 2 L^2 sigma / (3 E t)`` is not safe here, because a cantilever under a tip load of
    fixed direction stiffens as it bends (its clamp moment grows faster than the tip displacement).
    """
    if spec.stroke_mm is not None:
        return float(spec.stroke_mm)
    cap = spec.max_stroke_fraction * spec.length_mm
    limit = spec.stress_fraction * material.yield_MPa
    path = strip_curve(spec, material, max(spec.thicknesses_mm), cap)
    over = np.nonzero(path.peak_stress_MPa > limit)[0]
    if over.size == 0:
        return float(cap)
    k = int(over[0])
    d0, d1 = path.displacement_mm[k - 1], path.displacement_mm[k]
    s0, s1 = path.peak_stress_MPa[k - 1], path.peak_stress_MPa[k]
    return float(0.999 * (d0 + (limit - s0) * (d1 - d0) / (s1 - s0)))


def strip_curve(
    spec: CouponSpec, material: Material, thickness_mm: float, stroke_mm: float
) -> StripCurve:
    """Solve one strip (geometrically exact beam, fea/beam.py) to ``stroke_mm``.

    Parameters
    ----------
    thickness_mm : float, mm — the strip's thickness as printed (nominal + offset), > 0.
    stroke_mm : float, mm — tip displacement of the last row.

    Raises
    ------
    FeaError
        When the thickness is not positive or a row does not converge (the message says which).
    """
    if not (math.isfinite(thickness_mm) and thickness_mm > 0):
        raise FeaError(f"strip thickness {thickness_mm} mm must be > 0")
    profile = BeamProfile(
        points_mm=np.array([[0.0, 0.0], [spec.length_mm, 0.0]]),
        thickness_mm=np.array([thickness_mm, thickness_mm]),
        width_mm=spec.width_mm,
    )
    # Tip pushed along +y (normal to the strip), free to rotate and to slide along x: the force
    # measured is the tip load of fixed direction of the classic large-deflection cantilever.
    drive = EndDrive(
        control="displacement",
        direction=(0.0, 1.0),
        max_value=float(stroke_mm),
        steps=int(spec.steps),
        rotation="free",
        transverse="free",
    )
    res = solve_beam(profile, material, drive, "clamped", BeamSettings(n_elements=spec.n_elements))
    if not res.ok:
        raise FeaError(f"coupon strip t = {thickness_mm:.4g} mm did not solve: {res.message}")
    return StripCurve(
        thickness_mm=float(thickness_mm),
        displacement_mm=np.asarray(res.displacement_mm, dtype=float),
        force_N=np.asarray(res.force_N, dtype=float),
        peak_stress_MPa=np.asarray(res.peak_stress_MPa, dtype=float),
    )


def coupon_curves(
    spec: CouponSpec, material: Material, offset_mm: float = 0.0
) -> tuple[float, list[StripCurve]]:
    """The predicted curves of every strip of the coupon.

    Parameters
    ----------
    offset_mm : float, mm — printed minus drawn thickness, added to every strip.

    Returns
    -------
    (stroke_mm, curves) : the stroke used and one :class:`StripCurve` per strip, in the order of
    ``spec.thicknesses_mm``.

    Raises
    ------
    FeaError
        When a strip would be over ``stress_fraction`` of the allowable at the stroke (the test
        would not be elastic): the message gives the stroke to use instead.
    """
    stroke = coupon_stroke_mm(spec, material)
    curves = [strip_curve(spec, material, t + offset_mm, stroke) for t in spec.thicknesses_mm]
    worst = max(float(np.max(c.peak_stress_MPa)) for c in curves)
    limit = spec.stress_fraction * material.yield_MPa
    if worst > limit * (1.0 + 1e-9):
        raise FeaError(
            f"coupon stroke {stroke:.3g} mm stresses the thickest strip to {worst:.1f} MPa, over "
            f"{spec.stress_fraction:g} x the allowable ({limit:.1f} MPa); give a smaller stroke_mm "
            f"(about {stroke * limit / worst:.3g} mm)"
        )
    return stroke, curves
