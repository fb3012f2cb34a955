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

__all__ = ["BeamProfile"]


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
