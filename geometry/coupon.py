"""The printable calibration coupon: a clamp block with strips of several thicknesses (issue #26).

The physics and the test are in :mod:`flexopt.fea.coupon`; this module draws the part. The strips
leave one long face of the block side by side, ``pitch_mm`` apart, each ``length_mm`` long (the
free length the model solves), so the block clamps all of them at once in a vice and each strip is
tested in turn by pushing its tip. The block carries one engraved notch per strip counted from the
thinnest (1 notch) so the strips can be told apart after printing.

Units: mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from flexopt.geometry.errors import GeometryError
from shapely.geometry import Polygon, box
from shapely.ops import unary_union

__all__ = ["CouponOutline", "coupon_outline"]


@dataclass(frozen=True)
class CouponOutline:
    """The coupon's outline in the print plane.

    Attributes
    ----------
    polygon : shapely Polygon, mm — block and strips; extruded by the strip width (print height).
    strip_roots_mm : (k, 2) float, mm — where each strip leaves the block (the clamp face).
    strip_tips_mm : (k, 2) float, mm — each strip's free end (the drive point).
    thicknesses_mm : (k,) float, mm — the strips' drawn thicknesses, in the same order.
    """

    polygon: Polygon
    strip_roots_mm: np.ndarray
    strip_tips_mm: np.ndarray
    thicknesses_mm: np.ndarray


def coupon_outline(
    thicknesses_mm: tuple[float, ...],
    length_mm: float,
    block_mm: float = 15.0,
    pitch_mm: float = 10.0,
    notch_mm: float = 1.0,
) -> CouponOutline:
    """Draw the coupon: a ``block_mm``-deep clamp block, strips along +x from its face at x = 0.

    Parameters
    ----------
    thicknesses_mm : (k,) float, mm — the strips' drawn thicknesses, thinnest first.
    length_mm : float, mm — free length of each strip (clamp face to tip).
    block_mm : float, mm — depth of the clamp block along x (what the vice grips).
    pitch_mm : float, mm — distance between strip centrelines (room for the pusher).
    notch_mm : float, mm — size of the identification notches on the block's back face.

    Raises
    ------
    GeometryError
        When a strip is thicker than the pitch leaves room for, or a size is not positive.
    """
    t = np.asarray(thicknesses_mm, dtype=float)
    if t.ndim != 1 or t.size < 1 or not np.all(np.isfinite(t)) or np.any(t <= 0):
        raise GeometryError(f"coupon thicknesses {list(t)} must be positive numbers")
    for name, value in (("length_mm", length_mm), ("block_mm", block_mm), ("pitch_mm", pitch_mm)):
        if not (np.isfinite(value) and value > 0):
            raise GeometryError(f"coupon {name} = {value} must be > 0")
    if np.max(t) > 0.5 * pitch_mm:
        raise GeometryError(
            f"a {np.max(t):g} mm strip needs a pitch of at least {2 * np.max(t):g} mm "
            f"(pitch_mm = {pitch_mm:g})"
        )
    k = t.size
    height = pitch_mm * k
    ys = pitch_mm * (np.arange(k) + 0.5)
    pieces = [box(-block_mm, 0.0, 0.0, height)]
    pieces += [box(0.0, y - ti / 2, length_mm, y + ti / 2) for y, ti in zip(ys, t, strict=True)]
    shape = unary_union(pieces)
    # identification: strip i (thinnest = 0) gets i + 1 notches on the back face behind it
    cuts = []
    for i, y in enumerate(ys):
        for j in range(i + 1):
            yc = y + (j - i / 2) * 2 * notch_mm
            cuts.append(box(-block_mm, yc - notch_mm / 2, -block_mm + notch_mm, yc + notch_mm / 2))
    polygon = shape.difference(unary_union(cuts)) if cuts else shape
    if not isinstance(polygon, Polygon) or not polygon.is_valid:
        raise GeometryError("the coupon outline is not one polygon; use a larger pitch_mm")
    roots = np.column_stack([np.zeros(k), ys])
    tips = np.column_stack([np.full(k, length_mm), ys])
    return CouponOutline(polygon, roots, tips, t)
