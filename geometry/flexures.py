"""Flexure pivots: parametric leaves, notch hinges and the cross-axis pivot, as plain geometry.

Every flexure joins a *ground* block to a *moving* block. It gives

* ``outline()`` — one shapely polygon (mm) with both clamping blocks, for plane-stress FEA and
  for extrusion to STL (``width_mm`` is the extrusion height, the out-of-plane width);
* ``beams()`` — the :class:`~geometry.profile.BeamProfile` s of its compliant members, each from
  the ground block (start) to the moving block (end): one leaf, two crossed leaves, or for notch
  hinges the *equivalent beam* whose thickness follows the notch profile (the Euler–Bernoulli
  idealisation behind the Paros–Weisbord and Lobontiu formulas);
* ``centre_mm`` — the nominal rotation centre (where the closed forms put the pivot), and the
  ground and moving block polygons for boundary conditions.

The closed-form stiffness and stress of each type live in :mod:`fea.closed_forms` (the geometry
package does not know materials). Types, by their YAML name (:data:`FLEXURES`):

``leaf``
    Uniform leaf of length L between the blocks: small-length flexural pivot when L is short
    compared with the links it joins, a long leaf (cantilever) otherwise.
``variable_leaf``
    Leaf whose thickness is piecewise linear between equally spaced stations (default: thick
    ends, thin middle).
``circular_notch``
    Right-circular notch hinge: two semicircular cuts of radius R leaving a web of thickness t.
``elliptical_notch``
    Two semi-elliptical cuts, semi-axes a along the hinge and c deep, web t.
``corner_filleted``
    A straight web of length L and thickness t with corner fillets of radius r into the blocks.
``cross_axis``
    Cross-axis flexural pivot: two leaves of length L crossing at their middles at +-alpha to
    the blocks' faces (their planar projection; physically the leaves pass in separate layers).

Frames: for the leaf and notch types the hinge runs along +x from the ground block (x < 0) to the
moving block; the cross-axis pivot has the ground block below and the moving block above its
crossing point at the origin. Units: mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import shapely
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.profile import BeamProfile
from shapely.geometry import Polygon, box

__all__ = [
    "Flexure",
    "Leaf",
    "VariableLeaf",
    "CircularNotch",
    "EllipticalNotch",
    "CornerFilleted",
    "CrossAxis",
    "FLEXURES",
    "make_flexure",
]

#: Points of the equivalent beam of a notch hinge (stations along the notch). 41 stations keep
#: the beam's compliance within 0.1 % of the profile integral for web/notch ratios down to 1/50
#: (tests/geometry/test_flexures.py); the stations crowd at the thinnest section (see _stations).
NOTCH_BEAM_POINTS = 41
#: Least number of points per quarter circle when a curved cut is written into the outline ring
#: (48 keeps the polygon within 0.05 % of the radius, far below print resolution). Near a thin web
#: more are used, so that no polygon edge is longer than a quarter of the web (see _quarter_points):
#: a plane-stress mesh finer than the polygon would otherwise see its corners as stress raisers.
CURVE_POINTS = 48


def _positive(name: str, value: float) -> float:
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise GeometryError(f"{name} = {value:g} must be a finite number > 0 mm")
    return value


@dataclass(frozen=True)
class Flexure:
    """What every flexure shares.

    Attributes
    ----------
    width_mm : float, mm — out-of-plane width (extrusion height of the outline).
    block_length_mm : float, mm — length of each clamping block along the hinge.
    block_height_mm : float or None, mm — height of the blocks across the hinge; None picks the
        type's natural height (notches: the full notch depth; leaves: max(3 mm, 3 t)).
    """

    kind: ClassVar[str] = ""

    width_mm: float = 5.0
    block_length_mm: float = 5.0
    block_height_mm: float | None = None

    def __post_init__(self) -> None:
        _positive("width_mm", self.width_mm)
        _positive("block_length_mm", self.block_length_mm)
        if self.block_height_mm is not None:
            _positive("block_height_mm", self.block_height_mm)

    # -- interface every type implements -------------------------------------------------------

    @property
    def centre_mm(self) -> np.ndarray:
        """(2,) mm: nominal rotation centre."""
        raise NotImplementedError

    @property
    def min_thickness_mm(self) -> float:
        """Thinnest section of the compliant part, mm (the printed minimum feature)."""
        raise NotImplementedError

    def beams(self) -> tuple[BeamProfile, ...]:
        """Compliant members, each from the ground block (start) to the moving block (end)."""
        raise NotImplementedError

    def local_thickness_mm(self, x_mm: np.ndarray) -> np.ndarray:
        """Thickness of the compliant part at abscissae x (mm, outline frame); NaN outside it.

        Used to grade plane-stress meshes (a few elements through the local thickness)."""
        raise NotImplementedError

    def ground_block(self) -> Polygon:
        """The ground block, mm (clamped)."""
        raise NotImplementedError

    def moving_block(self) -> Polygon:
        """The moving block, mm (turned about ``centre_mm``)."""
        raise NotImplementedError

    def outline(self) -> Polygon:
        """One valid polygon, mm: blocks and compliant part."""
        raise NotImplementedError

    # -- shared --------------------------------------------------------------------------------

    @property
    def is_planar(self) -> bool:
        """Whether ``outline()`` extruded by ``width_mm`` is the part itself (False for the
        cross-axis pivot, whose leaves cross in separate layers)."""
        return True

    def envelope_mm(self) -> tuple[float, float]:
        """(length, height) of the outline's bounding box, mm."""
        x0, y0, x1, y1 = self.outline().bounds
        return x1 - x0, y1 - y0

    def params(self) -> dict[str, float | str | None]:
        """The generator's parameters by name (for reports)."""
        out: dict[str, float | str | None] = {"kind": self.kind}
        for name in self.__dataclass_fields__:
            out[name] = getattr(self, name)
        return out


# --------------------------------------------------------------------------------------------
# Leaves


def _block_pair(x0: float, x1: float, length: float, height: float) -> tuple[Polygon, Polygon]:
    h = 0.5 * height
    return box(x0 - length, -h, x0, h), box(x1, -h, x1 + length, h)


@dataclass(frozen=True)
class Leaf(Flexure):
    """Uniform leaf between two blocks.

    Attributes
    ----------
    length_mm : float, mm — free length L between the blocks.
    thickness_mm : float, mm — in-plane thickness t.
    """

    kind: ClassVar[str] = "leaf"

    length_mm: float = 10.0
    thickness_mm: float = 0.5
    root_fillet_mm: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        _positive("length_mm", self.length_mm)
        _positive("thickness_mm", self.thickness_mm)
        if self.block_height < self.thickness_mm:
            raise GeometryError(
                f"block_height_mm = {self.block_height:g} is thinner than the leaf "
                f"(thickness_mm = {self.thickness_mm:g}); make the blocks at least as high"
            )
        if not (math.isfinite(self.root_fillet_mm) and self.root_fillet_mm >= 0.0):
            raise GeometryError(f"root_fillet_mm = {self.root_fillet_mm:g} must be >= 0 mm")

    @property
    def block_height(self) -> float:
        if self.block_height_mm is not None:
            return float(self.block_height_mm)
        return max(3.0, 3.0 * self.thickness_mm)

    @property
    def centre_mm(self) -> np.ndarray:
        return np.array([0.5 * self.length_mm, 0.0])

    @property
    def min_thickness_mm(self) -> float:
        return float(self.thickness_mm)

    def stations(self) -> tuple[np.ndarray, np.ndarray]:
        """(x (k,), thickness (k,)) mm along the leaf."""
        return np.array([0.0, self.length_mm]), np.full(2, self.thickness_mm)

    def beams(self) -> tuple[BeamProfile, ...]:
        # with root fillets the beam carries their flare (it stiffens the pivot), read off the
        # drawn outline so that the beam and the exported part are one shape
        x, t = self.profile()
        return (BeamProfile(np.column_stack([x, np.zeros_like(x)]), t, self.width_mm),)

    def profile(self) -> tuple[np.ndarray, np.ndarray]:
        """(x (k,), thickness (k,)) mm of the leaf as drawn: :meth:`stations`, and with
        ``root_fillet_mm`` > 0 the flare of each root fillet (the outline's lower edge, the
        leaf being symmetric about its centreline)."""
        if self.root_fillet_mm <= 0.0:
            return self.stations()
        bottom = self._bottom_edge()
        return bottom[:, 0], -2.0 * bottom[:, 1]

    @property
    def root_kt(self) -> float:
        """Kt of the root fillets in in-plane bending (1 for sharp roots, whose stress is not
        bounded: pipeline/studies/_pivot_roots.py): the larger of the two roots'
        :func:`geometry.mechanism.shoulder_kt` (the block's height the wide side, the leaf's
        end thickness the narrow one; for a tapered end the fit of a uniform bar)."""
        if self.root_fillet_mm <= 0.0:
            return 1.0
        from flexopt.geometry.mechanism import shoulder_kt  # geometry.mechanism is heavier

        _, t = self.stations()
        return max(
            shoulder_kt(self.block_height, float(e), self.root_fillet_mm) for e in t[[0, -1]]
        )

    def _bottom_edge(self) -> np.ndarray:
        """(k, 2) mm: the outline's lower edge from the ground block's face (x = 0) to the
        moving block's (x = L), root fillets drawn (each tangent to the block face and to the
        leaf's surface, its radius ``root_fillet_mm``).

        Raises
        ------
        GeometryError
            When a fillet does not fit on the block face or on the leaf.
        """
        x, t = self.stations()
        H, L, r = 0.5 * self.block_height, self.length_mm, self.root_fillet_mm
        pts = [
            np.array([0.0, -H]),
            *(np.array([xi, -0.5 * ti]) for xi, ti in zip(x, t, strict=True)),
            np.array([L, -H]),
        ]
        if r <= 0.0:
            return np.array(pts[1:-1])
        left = _fillet(pts[0], pts[1], pts[2], r, self)
        right = _fillet(pts[-3], pts[-2], pts[-1], r, self)
        if left[-1][0] >= right[0][0] or left[-1][0] > x[1] or right[0][0] < x[-2]:
            raise GeometryError(
                f"root_fillet_mm = {r:g} does not fit on a {L:g} mm leaf of "
                f"{self.kind}; make the fillet smaller or the leaf longer"
            )
        inner = [p for p in pts[2:-2]]
        return np.array([*left, *inner, *right])

    def local_thickness_mm(self, x_mm: np.ndarray) -> np.ndarray:
        x, t = self.profile()
        xq = np.asarray(x_mm, dtype=float)
        return np.where((xq >= 0.0) & (xq <= self.length_mm), np.interp(xq, x, t), np.nan)

    def ground_block(self) -> Polygon:
        return _block_pair(0.0, self.length_mm, self.block_length_mm, self.block_height)[0]

    def moving_block(self) -> Polygon:
        return _block_pair(0.0, self.length_mm, self.block_length_mm, self.block_height)[1]

    def outline(self) -> Polygon:
        # One ring (no boolean union), so no micro-edges where pieces would meet; the leaf is
        # symmetric about its centreline, so the upper edge mirrors the lower one.
        L, B, H = self.length_mm, self.block_length_mm, 0.5 * self.block_height
        edge = self._bottom_edge()
        bottom = [(float(p[0]), float(p[1])) for p in edge]
        top = [(float(p[0]), -float(p[1])) for p in edge[::-1]]
        ring = [(-B, -H), (0.0, -H), *bottom, (L, -H), (L + B, -H), (L + B, H), (L, H), *top]
        ring += [(0.0, H), (-B, H)]
        return _valid(Polygon(ring), self)


@dataclass(frozen=True)
class VariableLeaf(Leaf):
    """Leaf whose thickness is piecewise linear between equally spaced stations.

    Attributes
    ----------
    thicknesses_mm : tuple of float, mm — thickness at k >= 2 equally spaced stations from the
        ground block to the moving block; default: the ``end_thickness_mm`` / ``thickness_mm`` /
        ``end_thickness_mm`` hourglass.
    end_thickness_mm : float, mm — thickness at both ends of the default hourglass.
    """

    kind: ClassVar[str] = "variable_leaf"

    end_thickness_mm: float = 1.0
    thicknesses_mm: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        _positive("end_thickness_mm", self.end_thickness_mm)
        t = self.station_thicknesses
        if t.size < 2:
            raise GeometryError(
                f"thicknesses_mm needs at least 2 stations (got {t.size}); give one per station"
            )
        bad = np.flatnonzero(~(np.isfinite(t) & (t > 0)))
        if bad.size:
            raise GeometryError(f"thicknesses_mm[{bad[0]}] = {t[bad[0]]:g} must be > 0 mm")
        super().__post_init__()

    @property
    def station_thicknesses(self) -> np.ndarray:
        if self.thicknesses_mm is not None:
            return np.asarray(self.thicknesses_mm, dtype=float)
        e, m = self.end_thickness_mm, self.thickness_mm
        return np.array([e, m, e], dtype=float)

    @property
    def block_height(self) -> float:
        if self.block_height_mm is not None:
            return float(self.block_height_mm)
        return max(3.0, 3.0 * float(self.station_thicknesses.max()))

    @property
    def min_thickness_mm(self) -> float:
        return float(self.station_thicknesses.min())

    def stations(self) -> tuple[np.ndarray, np.ndarray]:
        t = self.station_thicknesses
        return np.linspace(0.0, self.length_mm, t.size), t


# --------------------------------------------------------------------------------------------
# Notch hinges


def _quarter_points(arc_mm: float, web_mm: float) -> int:
    """Points per quarter of a cut whose quarter arc is ``arc_mm`` long, next to a web of
    ``web_mm``: at least CURVE_POINTS, and edges no longer than a quarter of the web."""
    return max(CURVE_POINTS, int(math.ceil(arc_mm / (0.25 * web_mm))))


def _stations(half: float, n: int) -> np.ndarray:
    """n stations on [-half, half], crowded at 0 (x = half * u |u|, u uniform), where a notch's
    compliance concentrates."""
    u = np.linspace(-1.0, 1.0, n)
    return half * u * np.abs(u)


@dataclass(frozen=True)
class _Notch(Flexure):
    """A symmetric notch hinge: web ``thickness_mm`` at the middle, a cut profile on both sides."""

    thickness_mm: float = 0.5

    def __post_init__(self) -> None:
        super().__post_init__()
        _positive("thickness_mm", self.thickness_mm)
        if self.block_height_mm is not None and self.block_height_mm < self.natural_height:
            raise GeometryError(
                f"block_height_mm = {self.block_height_mm:g} is lower than the notch needs "
                f"({self.natural_height:g} mm = web + two cut depths); leave it unset or raise it"
            )

    # subclasses: notch_length, depth, thickness_at(x) for x measured from the notch middle
    @property
    def notch_length(self) -> float:
        raise NotImplementedError

    @property
    def depth(self) -> float:
        """Depth of each cut, mm."""
        raise NotImplementedError

    def thickness_at(self, x: np.ndarray) -> np.ndarray:
        """Web thickness (mm) at x (mm) measured from the notch middle, |x| <= notch_length/2."""
        raise NotImplementedError

    @property
    def natural_height(self) -> float:
        return self.thickness_mm + 2.0 * self.depth

    @property
    def block_height(self) -> float:
        return (
            float(self.block_height_mm) if self.block_height_mm is not None else self.natural_height
        )

    @property
    def centre_mm(self) -> np.ndarray:
        return np.array([0.5 * self.notch_length, 0.0])

    @property
    def min_thickness_mm(self) -> float:
        return float(self.thickness_mm)

    def beams(self) -> tuple[BeamProfile, ...]:
        half = 0.5 * self.notch_length
        xm = _stations(half, NOTCH_BEAM_POINTS)
        t = self.thickness_at(xm)
        x = xm + half
        return (BeamProfile(np.column_stack([x, np.zeros_like(x)]), t, self.width_mm),)

    def local_thickness_mm(self, x_mm: np.ndarray) -> np.ndarray:
        xm = np.asarray(x_mm, dtype=float) - 0.5 * self.notch_length
        inside = np.abs(xm) <= 0.5 * self.notch_length
        return np.where(inside, self.thickness_at(xm), np.nan)

    def ground_block(self) -> Polygon:
        return _block_pair(0.0, self.notch_length, self.block_length_mm, self.block_height)[0]

    def moving_block(self) -> Polygon:
        return _block_pair(0.0, self.notch_length, self.block_length_mm, self.block_height)[1]

    def _profile(self) -> tuple[np.ndarray, np.ndarray]:
        """(x (k,), thickness (k,)) of the cut for the outline ring, x from the notch middle,
        left to right. Computed from the cut's angle, not through thickness_at: the sqrt there
        turns a rounding error at the cut's end (where it meets the block face) into a 1e-8 mm
        step, and such micro-edges make the extruded solid non-manifold."""
        raise NotImplementedError

    def outline(self) -> Polygon:
        half = 0.5 * self.notch_length
        xm, t = self._profile()
        x = xm + half
        L, B, H = self.notch_length, self.block_length_mm, 0.5 * self.block_height
        bottom = [(xi, -0.5 * ti) for xi, ti in zip(x, t, strict=True)]
        top = [(xi, 0.5 * ti) for xi, ti in zip(x[::-1], t[::-1], strict=True)]
        # Where the cut meets the block face at full height the ring point would repeat; drop it.
        ring = [(-B, -H), *_dedupe([(0.0, -H), *bottom, (L, -H)]), (L + B, -H), (L + B, H)]
        ring += [*_dedupe([(L, H), *top, (0.0, H)]), (-B, H)]
        return _valid(Polygon(_dedupe(ring)), self)


@dataclass(frozen=True)
class CircularNotch(_Notch):
    """Right-circular notch hinge (Paros & Weisbord 1965).

    Attributes
    ----------
    radius_mm : float, mm — radius R of both cuts; the notch is 2R long and t + 2R high.
    thickness_mm : float, mm — web t at the middle.
    """

    kind: ClassVar[str] = "circular_notch"

    radius_mm: float = 2.0

    def __post_init__(self) -> None:
        _positive("radius_mm", self.radius_mm)
        super().__post_init__()

    @property
    def notch_length(self) -> float:
        return 2.0 * self.radius_mm

    @property
    def depth(self) -> float:
        return float(self.radius_mm)

    def thickness_at(self, x: np.ndarray) -> np.ndarray:
        R = self.radius_mm
        x = np.clip(np.asarray(x, dtype=float), -R, R)
        return self.thickness_mm + 2.0 * (R - np.sqrt(np.maximum(R * R - x * x, 0.0)))

    def _profile(self) -> tuple[np.ndarray, np.ndarray]:
        # Uniform in the angle of the circle: even chord lengths on the arc.
        R = self.radius_mm
        n = _quarter_points(0.5 * np.pi * R, self.thickness_mm)
        phi = np.linspace(-0.5 * np.pi, 0.5 * np.pi, 2 * n + 1)
        return R * np.sin(phi), self.thickness_mm + 2.0 * R * (1.0 - np.cos(phi))


@dataclass(frozen=True)
class EllipticalNotch(_Notch):
    """Elliptical notch hinge (Smith et al. 1997; Lobontiu 2003, Ch. 2).

    Attributes
    ----------
    half_length_mm : float, mm — semi-axis a along the hinge; the notch is 2a long.
    depth_mm : float, mm — semi-axis c across it; the notch is t + 2c high.
    thickness_mm : float, mm — web t at the middle.
    """

    kind: ClassVar[str] = "elliptical_notch"

    half_length_mm: float = 3.0
    depth_mm: float = 1.5

    def __post_init__(self) -> None:
        _positive("half_length_mm", self.half_length_mm)
        _positive("depth_mm", self.depth_mm)
        super().__post_init__()

    @property
    def notch_length(self) -> float:
        return 2.0 * self.half_length_mm

    @property
    def depth(self) -> float:
        return float(self.depth_mm)

    def thickness_at(self, x: np.ndarray) -> np.ndarray:
        a, c = self.half_length_mm, self.depth_mm
        u = np.clip(np.asarray(x, dtype=float) / a, -1.0, 1.0)
        return self.thickness_mm + 2.0 * c * (1.0 - np.sqrt(np.maximum(1.0 - u * u, 0.0)))

    def _profile(self) -> tuple[np.ndarray, np.ndarray]:
        a, c = self.half_length_mm, self.depth_mm
        n = _quarter_points(0.5 * np.pi * max(a, c), self.thickness_mm)  # bounds the quarter arc
        phi = np.linspace(-0.5 * np.pi, 0.5 * np.pi, 2 * n + 1)
        return a * np.sin(phi), self.thickness_mm + 2.0 * c * (1.0 - np.cos(phi))

    @property
    def root_radius_mm(self) -> float:
        """Radius of curvature of the cut at the web, a^2 / c, mm."""
        return self.half_length_mm**2 / self.depth_mm


@dataclass(frozen=True)
class CornerFilleted(_Notch):
    """Corner-filleted notch hinge (Lobontiu, Paine, Garcia, Goldfarb 2001).

    Attributes
    ----------
    length_mm : float, mm — straight web length L (between the fillets).
    fillet_radius_mm : float, mm — fillet radius r; the notch is L + 2r long and t + 2r high.
    thickness_mm : float, mm — web t.
    """

    kind: ClassVar[str] = "corner_filleted"

    length_mm: float = 5.0
    fillet_radius_mm: float = 1.0

    def __post_init__(self) -> None:
        _positive("length_mm", self.length_mm)
        _positive("fillet_radius_mm", self.fillet_radius_mm)
        super().__post_init__()

    @property
    def notch_length(self) -> float:
        return self.length_mm + 2.0 * self.fillet_radius_mm

    @property
    def depth(self) -> float:
        return float(self.fillet_radius_mm)

    def thickness_at(self, x: np.ndarray) -> np.ndarray:
        r, half = self.fillet_radius_mm, 0.5 * self.length_mm
        d = np.clip(np.abs(np.asarray(x, dtype=float)) - half, 0.0, r)  # into the fillet
        return self.thickness_mm + 2.0 * (r - np.sqrt(np.maximum(r * r - d * d, 0.0)))

    def _profile(self) -> tuple[np.ndarray, np.ndarray]:
        r, half = self.fillet_radius_mm, 0.5 * self.length_mm
        n = _quarter_points(0.5 * np.pi * r, self.thickness_mm)
        phi = np.linspace(0.0, 0.5 * np.pi, n + 1)
        right = half + r * np.sin(phi)
        t = self.thickness_mm + 2.0 * r * (1.0 - np.cos(phi))
        return np.concatenate([-right[::-1], right]), np.concatenate([t[::-1], t])

    def beams(self) -> tuple[BeamProfile, ...]:
        # The straight web is uniform: two stations suffice there; the fillets get the crowded
        # stations of a circular notch of radius r.
        r, half = self.fillet_radius_mm, 0.5 * self.length_mm
        f = _stations(r, NOTCH_BEAM_POINTS)
        fillet = f[f >= 0.0]  # 0 .. r, crowded at 0
        xm = np.concatenate([-(half + fillet[::-1]), half + fillet])
        t = self.thickness_at(xm)
        x = xm + 0.5 * self.notch_length
        return (BeamProfile(np.column_stack([x, np.zeros_like(x)]), t, self.width_mm),)


# --------------------------------------------------------------------------------------------
# Cross-axis pivot


@dataclass(frozen=True)
class CrossAxis(Flexure):
    """Cross-axis flexural pivot: two leaves crossing at their middles (Wittrick 1948; Jensen &
    Howell 2002).

    Leaf 1 runs from the ground block at ``-L/2 (cos a, sin a)`` to the moving block at
    ``+L/2 (cos a, sin a)``; leaf 2 is its mirror image in the y axis. The crossing point is the
    origin.

    Attributes
    ----------
    length_mm : float, mm — leaf length L between the blocks.
    thickness_mm : float, mm — leaf thickness t.
    half_angle_deg : float, deg — angle a of each leaf to the blocks' faces (45: leaves at 90
        degrees to each other).
    """

    kind: ClassVar[str] = "cross_axis"

    length_mm: float = 10.0
    thickness_mm: float = 0.5
    half_angle_deg: float = 45.0

    def __post_init__(self) -> None:
        super().__post_init__()
        _positive("length_mm", self.length_mm)
        _positive("thickness_mm", self.thickness_mm)
        if not 10.0 <= self.half_angle_deg <= 80.0:
            raise GeometryError(
                f"half_angle_deg = {self.half_angle_deg:g} must lie in [10, 80] degrees (the "
                "leaves would lie along the blocks); 45 crosses them at a right angle"
            )

    @property
    def is_planar(self) -> bool:
        return False

    @property
    def _dirs(self) -> tuple[np.ndarray, np.ndarray]:
        a = math.radians(self.half_angle_deg)
        return np.array([math.cos(a), math.sin(a)]), np.array([-math.cos(a), math.sin(a)])

    @property
    def centre_mm(self) -> np.ndarray:
        return np.zeros(2)

    @property
    def min_thickness_mm(self) -> float:
        return float(self.thickness_mm)

    def beams(self) -> tuple[BeamProfile, ...]:
        half = 0.5 * self.length_mm
        t = np.full(2, self.thickness_mm)
        return tuple(
            BeamProfile(np.array([-half * d, half * d]), t, self.width_mm) for d in self._dirs
        )

    @property
    def _span(self) -> tuple[float, float]:
        """(half width of the blocks, y of the block faces), mm."""
        d1, _ = self._dirs
        half = 0.5 * self.length_mm
        reach = half * d1[0] + self.thickness_mm / (2.0 * d1[1]) + self.thickness_mm
        return max(reach, 0.5 * self.block_length_mm), half * d1[1]

    def ground_block(self) -> Polygon:
        w, y = self._span
        h = self.block_height_mm or max(3.0, 3.0 * self.thickness_mm)
        return box(-w, -y - h, w, -y)

    def moving_block(self) -> Polygon:
        w, y = self._span
        h = self.block_height_mm or max(3.0, 3.0 * self.thickness_mm)
        return box(-w, y, w, y + h)

    def outline(self) -> Polygon:
        """The planar projection: both leaves and blocks (the leaves merge where they cross,
        which a real cross-axis pivot avoids by putting them in separate layers)."""
        half = 0.5 * self.length_mm
        t = self.thickness_mm
        leaves = []
        for d in self._dirs:
            n = np.array([-d[1], d[0]]) * 0.5 * t
            # Run each leaf a little into both blocks so the union has no slivers at the faces.
            a, b = -(half + t) * d, (half + t) * d
            leaves.append(Polygon([a - n, b - n, b + n, a + n]))
        shape = shapely.union_all([self.ground_block(), self.moving_block(), *leaves])
        return _valid(shape, self)


# --------------------------------------------------------------------------------------------
# Registry and helpers

FLEXURES: dict[str, type[Flexure]] = {
    cls.kind: cls
    for cls in (Leaf, VariableLeaf, CircularNotch, EllipticalNotch, CornerFilleted, CrossAxis)
}
"""Flexure generators by YAML name."""


def make_flexure(kind: str, **params: float) -> Flexure:
    """Build a flexure by its YAML name.

    Raises
    ------
    GeometryError
        For an unknown kind (the message lists the known ones) or unknown parameter names.
    """
    cls = FLEXURES.get(kind)
    if cls is None:
        raise GeometryError(f"unknown flexure kind '{kind}'; use one of {', '.join(FLEXURES)}")
    known = set(cls.__dataclass_fields__)
    unknown = sorted(set(params) - known)
    if unknown:
        raise GeometryError(
            f"flexure '{kind}' has no parameter {unknown[0]!r}; its parameters are "
            f"{', '.join(sorted(known))}"
        )
    return cls(**params)


#: Ring points closer than this are one point, mm: far below any printed feature, far above the
#: rounding of the cut formulas.
_SAME_POINT_MM = 1e-6


def _dedupe(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    out: list[tuple[float, float]] = []
    for p in points:
        if not out or math.dist(out[-1], p) > _SAME_POINT_MM:
            out.append(p)
    if len(out) > 1 and math.dist(out[0], out[-1]) <= _SAME_POINT_MM:
        out.pop()
    return out


def _fillet(a: np.ndarray, p: np.ndarray, b: np.ndarray, r: float, flexure: Flexure) -> list:
    """The arc of radius ``r`` (mm) that rounds the corner ``p`` of the path a -> p -> b (each
    (2,) mm), tangent to both edges: its points from the tangent point on p-a to the one on
    p-b, one every 90° / CURVE_POINTS at least.

    Raises
    ------
    GeometryError
        When a tangent point falls beyond the end of its edge.
    """
    u, v = a - p, b - p
    la, lb = float(np.hypot(*u)), float(np.hypot(*v))
    u, v = u / la, v / lb
    theta = math.acos(min(max(float(u @ v), -1.0), 1.0))  # the corner's interior angle
    d = r / math.tan(0.5 * theta)  # corner to each tangent point
    if d > la or d > lb:
        raise GeometryError(
            f"root_fillet_mm = {r:g} does not fit the {flexure.kind}'s root (it needs {d:.3g} mm "
            f"of edge, {min(la, lb):.3g} mm there); make the fillet smaller or the blocks higher"
        )
    w = (u + v) / np.hypot(*(u + v))
    centre = p + w * (r / math.sin(0.5 * theta))
    t1, t2 = p + d * u, p + d * v
    a1 = math.atan2(*(t1 - centre)[::-1])
    a2 = math.atan2(*(t2 - centre)[::-1])
    sweep = (a2 - a1 + math.pi) % (2.0 * math.pi) - math.pi  # the short way round
    n = max(2, int(math.ceil(abs(sweep) / (0.5 * math.pi) * CURVE_POINTS)))
    ang = a1 + sweep * np.linspace(0.0, 1.0, n + 1)
    return [centre + r * np.array([math.cos(q), math.sin(q)]) for q in ang]


def _valid(shape, flexure: Flexure) -> Polygon:
    if not isinstance(shape, Polygon) or not shape.is_valid or shape.is_empty:
        raise GeometryError(
            f"the {flexure.kind} outline is not one valid polygon for {flexure.params()}; check "
            "that the blocks are larger than the compliant part"
        )
    return shape
