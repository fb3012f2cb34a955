"""Beam profiles: the plain data a planar beam analysis needs.

A :class:`BeamProfile` is a centreline through ``n`` points with a rectangular section whose
thickness varies linearly (in arc length) between consecutive points and a constant out-of-plane
width. Each segment between two points is straight or, when ``curvature_per_mm`` is non-zero, a
circular arc through both points (positive curvature turns left, i.e. counter-clockwise, when
walking from point ``i`` to point ``i + 1``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from flexopt.geometry.errors import GeometryError

__all__ = ["BeamProfile", "first_crossing"]


@dataclass(frozen=True)
class BeamProfile:
    """Centreline, thickness and width of a planar beam.

    Parameters
    ----------
    points_mm : (n, 2) float, mm
        Centreline vertices from the ``start`` end to the ``end`` end, n >= 2.
    thickness_mm : (n,) float, mm
        In-plane section thickness at each vertex; linear in arc length in between.
    width_mm : float, mm
        Out-of-plane width of the rectangular section.
    curvature_per_mm : (n - 1,) float, 1/mm, optional
        Signed curvature of each segment; 0 (default) makes the segment straight.
    """

    points_mm: np.ndarray
    thickness_mm: np.ndarray
    width_mm: float
    curvature_per_mm: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        pts = np.asarray(self.points_mm, dtype=float)
        t = np.asarray(self.thickness_mm, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 2:
            raise GeometryError(
                f"points_mm must be a list of at least 2 [x, y] pairs, got shape {pts.shape}"
            )
        if t.shape != (pts.shape[0],):
            raise GeometryError(
                f"thickness_mm needs one value per point: {pts.shape[0]} points but "
                f"{t.size} thickness values"
            )
        kappa = (
            np.zeros(pts.shape[0] - 1)
            if self.curvature_per_mm is None
            else np.asarray(self.curvature_per_mm, dtype=float)
        )
        if kappa.shape != (pts.shape[0] - 1,):
            raise GeometryError(
                f"curvature_per_mm needs one value per segment ({pts.shape[0] - 1}), "
                f"got {kappa.size}"
            )
        if not (np.all(np.isfinite(pts)) and np.all(np.isfinite(t)) and np.isfinite(self.width_mm)):
            raise GeometryError("points_mm, thickness_mm and width_mm must be finite numbers")
        chord = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        bad = np.flatnonzero(chord <= 1e-9)
        if bad.size:
            raise GeometryError(
                f"points_mm[{bad[0]}] and points_mm[{bad[0] + 1}] coincide (zero-length segment); "
                "remove the duplicate point"
            )
        bad = np.flatnonzero(t <= 0)
        if bad.size:
            raise GeometryError(f"thickness_mm[{bad[0]}] = {t[bad[0]]:g} must be > 0 mm")
        if not self.width_mm > 0:
            raise GeometryError(f"width_mm = {self.width_mm:g} must be > 0 mm")
        bad = np.flatnonzero(np.abs(kappa) * chord / 2 >= 1.0)
        if bad.size:
            raise GeometryError(
                f"curvature_per_mm[{bad[0]}] = {kappa[bad[0]]:g} is too large for a chord of "
                f"{chord[bad[0]]:g} mm (an arc needs |curvature| < 2/chord)"
            )
        for name, value in (("points_mm", pts), ("thickness_mm", t), ("curvature_per_mm", kappa)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "width_mm", float(self.width_mm))

    @property
    def n_points(self) -> int:
        return int(self.points_mm.shape[0])

    @property
    def segment_lengths_mm(self) -> np.ndarray:
        """(n - 1,) float, mm: arc length of each segment."""
        chord = np.linalg.norm(np.diff(self.points_mm, axis=0), axis=1)
        half = np.abs(self.curvature_per_mm) * chord / 2
        with np.errstate(invalid="ignore", divide="ignore"):
            arc = np.where(half > 1e-12, 2 * np.arcsin(half) / np.abs(self.curvature_per_mm), chord)
        return arc

    @property
    def length_mm(self) -> float:
        """Total arc length of the centreline, mm."""
        return float(self.segment_lengths_mm.sum())

    @property
    def arc_length_mm(self) -> np.ndarray:
        """(n,) float, mm: arc length at each vertex, starting at 0."""
        return np.concatenate([[0.0], np.cumsum(self.segment_lengths_mm)])

    def segment_start_angles_rad(self) -> np.ndarray:
        """(n - 1,) float, rad: tangent angle at the start of each segment."""
        d = np.diff(self.points_mm, axis=0)
        chord_angle = np.arctan2(d[:, 1], d[:, 0])
        return chord_angle - self.curvature_per_mm * self.segment_lengths_mm / 2


def first_crossing(
    points: tuple[tuple[float, float], ...],
) -> tuple[int, int, tuple[float, float]] | None:
    """The first two non-adjacent segments (chords) that touch, and where; None if none do.

    A beam that crosses itself cannot be built (or printed): the solver would not notice.
    """
    p = np.asarray(points, dtype=float)
    n = len(p) - 1
    for i in range(n - 1):  # adjacent segments meet only by folding straight back
        r1, r2 = p[i + 1] - p[i], p[i + 2] - p[i + 1]
        cross = r1[0] * r2[1] - r1[1] * r2[0]
        if abs(cross) <= 1e-9 * np.linalg.norm(r1) * np.linalg.norm(r2) and np.dot(r1, r2) < 0:
            return i, i + 1, (float(p[i + 1][0]), float(p[i + 1][1]))
    for i in range(n):
        a, b = p[i], p[i + 1]
        for j in range(i + 2, n):
            if i == 0 and j == n - 1 and np.allclose(p[0], p[-1]):
                continue  # a closed loop meets itself at its ends by design
            c, d = p[j], p[j + 1]
            r, q = b - a, d - c
            den = r[0] * q[1] - r[1] * q[0]
            if abs(den) < 1e-12:  # parallel: touching only if collinear and overlapping
                if abs((c - a)[0] * r[1] - (c - a)[1] * r[0]) > 1e-9:
                    continue
                t = [float(np.dot(e - a, r) / np.dot(r, r)) for e in (c, d)]
                if max(t) < 0 or min(t) > 1:
                    continue
                hit = a + r * min(max(min(t), 0.0), 1.0)
                return i, j, (float(hit[0]), float(hit[1]))
            t = ((c - a)[0] * q[1] - (c - a)[1] * q[0]) / den
            u = ((c - a)[0] * r[1] - (c - a)[1] * r[0]) / den
            if -1e-12 <= t <= 1 + 1e-12 and -1e-12 <= u <= 1 + 1e-12:
                hit = a + t * r
                return i, j, (float(hit[0]), float(hit[1]))
    return None
