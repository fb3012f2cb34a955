"""Long-stroke constant-force compliant mechanism (Bilancia, Geraci, Berselli, SMASIS 2019): its
shapes.

* **The PRB linkage's layout**: :class:`PRBParams` (paper Table 1 and Eq. 10), the spring-free
  joints and the position closures of Eqs. 6–7 (:func:`slider_x_mm`, :func:`rod_angle_rad`). Its
  mechanics (energy, force, the fit of Eq. 8, the lumped flexures of Eq. 12) is
  :mod:`fea.prb`.
* **Beam-based design** (Eq. 13, Table 3): the 23-variable tapered beam through the reference
  points S1..S6 (ends of the three flexures) and the design points p1..p10, as a
  :class:`~geometry.profile.BeamProfile` for the beam solver and as a printable shapely outline.

Frame and conventions (see ``docs/constant_force.md`` for the derivation)
-------------------------------------------------------------------------
* Crank pivot O at the origin; the slider pin C moves on the line ``y = e``; ``x`` is its abscissa.
  Crank angle ``theta1`` is measured from the slider axis (+x) to O->A, counter-clockwise. The rod
  angle ``theta3`` is the direction of C->A (that is what Eqs. 6–7 encode: ``A - C = r2 (cos
  theta3, sin theta3)``), so it is near ``pi + atan(e/x)``.
* ``r2 = sqrt(x_in^2 + e^2) - r1`` (Eq. 11): O, A, C collinear ("stretched") with C at
  ``(x_in, e)``. The spring-free state is ``theta1 = theta10``; its slider abscissa ``x0`` follows
  from Eq. 7 and equals ``x_in`` when ``theta10 = atan(e / x_in)`` (Table 1: ``x0 - x_in =
  -1.5e-4 mm``).
* **Stroke** ``dx = x0 - x >= 0``: the slider moves along the work direction ``(-1, 0)``, towards
  the crank pivot, compressing the mechanism. With ``theta10 > atan(e/x_in)`` the crank is already
  past the toggle, so compressing turns it counter-clockwise (``theta1`` grows) and the crank pin A
  stays on the left of O->C.

(Its output force and energy: :mod:`fea.prb`.)

Units: mm, N, N·mm, rad, MPa.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np
import shapely
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.mechanism import (
    FILLET_CHORDS,
    AsMadeBeam,
    BeamShape,
    EndJunction,
    shoulder_kt,
)
from flexopt.geometry.profile import BeamProfile
from shapely.geometry import Polygon

__all__ = [
    "PRBParams",
    "TABLE1",
    "slider_x_mm",
    "rod_angle_rad",
    "FLEXURE_LENGTH_MM",
    "WORK_DIRECTION",
    "DESIGN_VARIABLE_NAMES",
    "ConstantForceDesign",
    "DesignBounds",
    "TABLE3_OPTIMUM",
    "TABLE3_BOUNDS",
    "design_from_vector",
    "design_to_vector",
    "joint_points",
    "reference_points",
    "design_points",
    "centreline_points",
    "beam_profile",
    "outline",
    "filleted_beam",
    "flared_ends",
    "flared_thickness",
    "min_feature_mm",
    "BLEND_CHORDS",
    "MIN_BLEND_MM",
]

# ----------------------------------------------------------------------------------------------
# 1. The PRB eccentric slider-crank's layout
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PRBParams:
    """Parameters of the PRB eccentric slider-crank (paper Table 1 and Eq. 10).

    Attributes
    ----------
    r1_mm : float, mm
        Crank length O->A.
    theta10_rad : float, rad
        Spring-free crank angle, from the slider axis (+x), counter-clockwise. Must be at least
        ``atan(e / x_in)`` (the stretched configuration; the paper's lower bound) and below pi.
    K1_Nmm, K2_Nmm, K3_Nmm : float, N·mm/rad
        Torsional springs at the ground pivot O, the crank–rod pin A and the rod–slider pin C.
    x_in_mm : float, mm
        Slider abscissa of the stretched configuration (Eq. 11).
    e_mm : float, mm
        Eccentricity: the slider axis is the line ``y = e``.
    """

    r1_mm: float
    theta10_rad: float
    K1_Nmm: float
    K2_Nmm: float
    K3_Nmm: float
    x_in_mm: float = 100.0
    e_mm: float = 60.0

    def __post_init__(self) -> None:
        for name in ("r1_mm", "theta10_rad", "K1_Nmm", "K2_Nmm", "K3_Nmm", "x_in_mm", "e_mm"):
            value = float(getattr(self, name))
            if not np.isfinite(value):
                raise GeometryError(f"PRBParams.{name} = {value} must be a finite number")
            object.__setattr__(self, name, value)
        if not self.e_mm > 0 or not self.x_in_mm > 0:
            raise GeometryError(
                f"x_in_mm = {self.x_in_mm:g} and e_mm = {self.e_mm:g} must both be > 0 "
                "(the slider starts up and to the right of the crank pivot)"
            )
        reach = float(np.hypot(self.x_in_mm, self.e_mm))
        if not 0 < self.r1_mm < reach:
            raise GeometryError(
                f"r1_mm = {self.r1_mm:g} must lie in (0, sqrt(x_in^2 + e^2) = {reach:g}) so that "
                "the rod length r2 = sqrt(x_in^2 + e^2) - r1 (Eq. 11) is positive"
            )
        alpha0 = float(np.arctan2(self.e_mm, self.x_in_mm))
        if not alpha0 - 1e-12 <= self.theta10_rad < np.pi:
            raise GeometryError(
                f"theta10_rad = {self.theta10_rad:.6g} must lie in [atan(e/x_in) = {alpha0:.6g}, "
                "pi): below atan(e/x_in) the crank pin starts on the other side of the line O-C "
                "and the mechanism would open before it compresses"
            )
        for name in ("K1_Nmm", "K2_Nmm", "K3_Nmm"):
            if getattr(self, name) < 0:
                raise GeometryError(f"PRBParams.{name} = {getattr(self, name):g} must be >= 0")

    @property
    def r2_mm(self) -> float:
        """Rod length A->C, mm (Eq. 11)."""
        return float(np.hypot(self.x_in_mm, self.e_mm) - self.r1_mm)

    @property
    def stiffness_Nmm(self) -> np.ndarray:
        """(3,) float, N·mm/rad: ``[K1, K2, K3]``."""
        return np.array([self.K1_Nmm, self.K2_Nmm, self.K3_Nmm])

    @property
    def theta30_rad(self) -> float:
        """Spring-free rod angle (direction C->A), rad (Eq. 6 at theta10)."""
        return float(rod_angle_rad(self.r1_mm, self.r2_mm, self.e_mm, self.theta10_rad))

    @property
    def x0_mm(self) -> float:
        """Spring-free slider abscissa, mm (Eq. 7 at theta10); ``= x_in`` when stretched."""
        return float(slider_x_mm(self.r1_mm, self.r2_mm, self.e_mm, self.theta10_rad))

    def with_stiffness(self, K_Nmm: np.ndarray) -> PRBParams:
        """A copy with ``[K1, K2, K3]`` replaced, N·mm/rad."""
        k1, k2, k3 = (float(v) for v in np.asarray(K_Nmm, dtype=float).reshape(3))
        return PRBParams(self.r1_mm, self.theta10_rad, k1, k2, k3, self.x_in_mm, self.e_mm)


#: Paper Table 1: optimum for 1.5 N over 35 mm with x_in = 100 mm, e = 60 mm.
TABLE1 = PRBParams(r1_mm=54.0, theta10_rad=0.542, K1_Nmm=28.303, K2_Nmm=35.379, K3_Nmm=35.379)


def rod_angle_rad(r1: float, r2: float, e: float, theta1: np.ndarray) -> np.ndarray:
    """Rod angle ``theta3`` (direction C->A), rad, at crank angles ``theta1`` (rad; any shape):
    Eq. 6 with crank ``r1``, rod ``r2`` and eccentricity ``e`` (mm)."""
    # Eq. 6 solved with atan2 instead of asin: identical while A lies left of C (the paper's
    # range), and it stays continuous if a long stroke carries C past A.
    x = slider_x_mm(r1, r2, e, theta1)
    return np.pi - np.arctan2(r1 * np.sin(theta1) - e, x - r1 * np.cos(theta1))


def slider_x_mm(r1: float, r2: float, e: float, theta1: np.ndarray) -> np.ndarray:
    """Slider abscissa ``x``, mm, at crank angles ``theta1`` (rad; any shape): Eq. 7 with crank
    ``r1``, rod ``r2`` and eccentricity ``e`` (mm)."""
    # Eq. 7 with cos(theta3) = -sqrt(1 - sin^2) from Eq. 6 (rod pointing back from C to A).
    s = (r1 * np.sin(theta1) - e) / r2
    return r1 * np.cos(theta1) + r2 * np.sqrt(np.clip(1.0 - s * s, 0.0, None))


# ----------------------------------------------------------------------------------------------
# 2. Beam-based design (Eq. 13, Table 3)
# ----------------------------------------------------------------------------------------------

#: Length of each of the three flexural pivots (Table 2), mm; their ends are S1..S6.
FLEXURE_LENGTH_MM = 10.8

#: Direction in which the driven end S6 moves (the slider moves towards the crank pivot).
WORK_DIRECTION = (-1.0, 0.0)

#: Order of the 23 design variables in a design vector (paper Sec. 3).
DESIGN_VARIABLE_NAMES: tuple[str, ...] = (
    *(f"a{j}" for j in range(1, 11)),
    *(f"t{j}" for j in range(1, 11)),
    "T1",
    "T6",
    "B",
)


@dataclass(frozen=True)
class ConstantForceDesign:
    """The paper's 23 beam-design variables.

    Attributes
    ----------
    a : (10,) float
        Position coefficients of p1..p10: ``p_j = S_i + a_j (S_{i+1} - S_i)`` (Eq. 13), two per
        interval S_i->S_{i+1} (p1, p2 in S1->S2, ..., p9, p10 in S5->S6); each in (0, 1) and
        increasing within its interval so the centreline does not fold back.
    t : (10,) float, mm
        In-plane thickness at p1..p10.
    T1, T6 : float, mm
        Thickness at the clamped end S1 and at the driven end S6.
    B : float, mm
        Out-of-plane width (constant).
    """

    a: np.ndarray
    t: np.ndarray
    T1: float
    T6: float
    B: float

    def __post_init__(self) -> None:
        a = np.asarray(self.a, dtype=float)
        t = np.asarray(self.t, dtype=float)
        if a.shape != (10,) or t.shape != (10,):
            raise GeometryError(
                f"a and t need 10 values each (p1..p10), got shapes {a.shape} and {t.shape}"
            )
        scalars = {"T1": self.T1, "T6": self.T6, "B": self.B}
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(t))) or not all(
            np.isfinite(float(v)) for v in scalars.values()
        ):
            raise GeometryError("a, t, T1, T6 and B must be finite numbers")
        bad = np.flatnonzero((a <= 0) | (a >= 1))
        if bad.size:
            raise GeometryError(
                f"a{bad[0] + 1} = {a[bad[0]]:g} must lie strictly inside (0, 1): at 0 or 1 the "
                "design point coincides with a reference point"
            )
        bad = np.flatnonzero(a[0::2] >= a[1::2])
        if bad.size:
            j = 2 * bad[0] + 1
            raise GeometryError(
                f"a{j} = {a[j - 1]:g} must be < a{j + 1} = {a[j]:g} (both lie on S{bad[0] + 1}->"
                f"S{bad[0] + 2}; otherwise the centreline folds back); swap them"
            )
        bad = np.flatnonzero(t <= 0)
        if bad.size:
            raise GeometryError(f"t{bad[0] + 1} = {t[bad[0]]:g} must be > 0 mm")
        for name, value in scalars.items():
            if not float(value) > 0:
                raise GeometryError(f"{name} = {float(value):g} must be > 0 mm")
            object.__setattr__(self, name, float(value))
        for name, value in (("a", a), ("t", t)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def vertex_thickness_mm(self) -> np.ndarray:
        """(12,) float, mm: thickness at S1, p1..p10, S6."""
        return np.concatenate([[self.T1], self.t, [self.T6]])


class DesignBounds(NamedTuple):
    """Box bounds of a design vector, each (23,) in :data:`DESIGN_VARIABLE_NAMES` order."""

    lower: np.ndarray
    upper: np.ndarray


def design_from_vector(x: np.ndarray) -> ConstantForceDesign:
    """Design from a (23,) vector ordered as :data:`DESIGN_VARIABLE_NAMES` (a, t, T1, T6, B)."""
    v = np.asarray(x, dtype=float)
    if v.shape != (23,):
        raise GeometryError(
            f"a constant-force design vector has 23 entries (a1..a10, t1..t10, T1, T6, B), "
            f"got shape {v.shape}"
        )
    return ConstantForceDesign(a=v[:10].copy(), t=v[10:20].copy(), T1=v[20], T6=v[21], B=v[22])


def design_to_vector(design: ConstantForceDesign) -> np.ndarray:
    """(23,) vector ordered as :data:`DESIGN_VARIABLE_NAMES`."""
    return np.concatenate([design.a, design.t, [design.T1, design.T6, design.B]])


#: Paper Table 3, optimal beam-based design (mm for t, T1, T6, B).
TABLE3_OPTIMUM = ConstantForceDesign(
    a=np.array([0.285, 0.803, 0.582, 0.851, 0.245, 0.842, 0.578, 0.798, 0.231, 0.765]),
    t=np.array([0.997, 0.929, 1.356, 1.339, 0.996, 0.920, 1.440, 1.434, 0.968, 1.046]),
    T1=0.927,
    T6=0.947,
    B=5.138,
)


def _table3_bounds() -> DesignBounds:
    a_rng = [
        (0.125, 0.500), (0.625, 0.875), (0.500, 0.625), (0.750, 0.875), (0.125, 0.375),
        (0.625, 0.875), (0.375, 0.625), (0.750, 0.875), (0.125, 0.375), (0.750, 0.875),
    ]  # fmt: skip
    t_rng = [
        (0.850, 1.100), (0.850, 1.100), (1.200, 1.400), (1.200, 1.400), (0.800, 1.150),
        # The paper prints "[0.800, 1/150]" for t6: a typo for 1.150 (t5 has the same range and
        # the optimum 0.920 lies inside it).
        (0.800, 1.150), (1.300, 1.600), (1.300, 1.600), (0.900, 1.100), (0.900, 1.100),
    ]  # fmt: skip
    rest = [(0.850, 1.100), (0.900, 1.100), (5.000, 8.000)]  # T1, T6, B
    rng = np.array(a_rng + t_rng + rest)
    lower, upper = rng[:, 0].copy(), rng[:, 1].copy()
    lower.setflags(write=False)
    upper.setflags(write=False)
    return DesignBounds(lower, upper)


#: Paper Table 3 ranges (t6 upper bound read as 1.150, see above).
TABLE3_BOUNDS = _table3_bounds()


def joint_points(prb_params: PRBParams = TABLE1) -> np.ndarray:
    """PRB joints in the spring-free configuration.

    Returns
    -------
    (3, 2) float, mm
        Crank pivot O = (0, 0), crank–rod pin A = r1 (cos theta10, sin theta10) and slider pin
        C = (x0, e) (x0 = x_in up to 1.5e-4 mm for Table 1).
    """
    p = prb_params
    a_pin = p.r1_mm * np.array([np.cos(p.theta10_rad), np.sin(p.theta10_rad)])
    return np.array([[0.0, 0.0], a_pin, [p.x0_mm, p.e_mm]])


def reference_points(
    prb_params: PRBParams = TABLE1,
    flexure_length_mm: float = FLEXURE_LENGTH_MM,
    end_flexures: Literal["centred", "outboard"] = "centred",
) -> np.ndarray:
    """Reference points S1..S6: the ends of the three flexural pivots of the lumped design.

    Each flexure's halves lie along the links that meet at its joint; the ground and the slider
    have no direction of their own, so the flexures there continue the crank and the rod. With
    ``u1`` the unit vector O->A, ``u2`` the unit vector A->C and ``L`` the flexure length:

    ``end_flexures="centred"`` (default; the paper's text: "the PRB rigid pairs are located at
    the center of the related small length flexural pivots")::

        S1 = O - L/2 u1,  S2 = O + L/2 u1        (ground pivot, along the crank)
        S3 = A - L/2 u1,  S4 = A + L/2 u2        (crank–rod pin: half on the crank, half on the rod)
        S5 = C - L/2 u2,  S6 = C + L/2 u2        (slider pin, along the rod)

    ``end_flexures="outboard"`` (a hypothesis, see ``docs/constant_force.md``): the ground and
    slider flexures lie outside the PRB link lengths, ``S1 = O - L u1, S2 = O`` and ``S5 = C,
    S6 = C + L u2`` (S3, S4 unchanged). The beam is then L longer (138.2 mm instead of 127.4 mm
    for Table 1), which brings the beam-solver force of the Table-3 design from 1.80 N to 1.55 N,
    near the paper's 1.5 N.

    In both layouts the rigid links S2->S3 (crank) and S4->S5 (rod) lie exactly on the PRB link
    lines; the flexure at A is the chord S3->S4 (the crank and the rod meet at A at an angle of
    only 0.0029 rad for Table 1, so the chord passes 0.008 mm from A).

    Parameters
    ----------
    prb_params : PRBParams
    flexure_length_mm : float, mm — L (Table 2: 10.8).
    end_flexures : "centred" or "outboard"

    Returns
    -------
    (6, 2) float, mm (a new array: the caller may write to it)
    """
    return _reference_points(prb_params, float(flexure_length_mm), end_flexures).copy()


@functools.lru_cache(maxsize=32)
def _reference_points(
    prb_params: PRBParams, flexure_length_mm: float, end_flexures: str
) -> np.ndarray:
    """:func:`reference_points`, kept per (frame, length, layout): a study asks for the same six
    points at every design (each evaluation, and ~50 times per exact Jacobian through the flared
    profile's map), and they depend on the frame alone. Same formulas, so the same numbers."""
    L = flexure_length_mm
    if not L > 0:
        raise GeometryError(f"flexure_length_mm = {L:g} must be > 0")
    if end_flexures not in ("centred", "outboard"):
        raise GeometryError(
            f"end_flexures = {end_flexures!r} is not a layout; use 'centred' or 'outboard'"
        )
    o, a_pin, c = joint_points(prb_params)
    r1, r2 = prb_params.r1_mm, prb_params.r2_mm
    # Each link keeps a rigid part only if it is longer than the flexure halves on it.
    link_min = L if end_flexures == "centred" else 0.5 * L
    if not (r1 > link_min and r2 > link_min):
        raise GeometryError(
            f"flexure_length_mm = {L:g} is too long for the crank (r1 = {r1:g} mm) or the rod "
            f"(r2 = {r2:g} mm): each link needs > {link_min:g} mm so that a rigid part remains "
            "between the flexures; use shorter flexures"
        )
    u1 = a_pin / r1
    u2 = (c - a_pin) / np.linalg.norm(c - a_pin)
    h = 0.5 * L
    if end_flexures == "centred":
        ground = (o - h * u1, o + h * u1)
        slider = (c - h * u2, c + h * u2)
    else:
        ground = (o - L * u1, o)
        slider = (c, c + L * u2)
    out = np.array([*ground, a_pin - h * u1, a_pin + h * u2, *slider])
    out.setflags(write=False)  # the cached copy: reference_points hands out copies of it
    return out


def design_points(
    design: ConstantForceDesign,
    prb_params: PRBParams = TABLE1,
    end_flexures: Literal["centred", "outboard"] = "centred",
) -> np.ndarray:
    """Design points p1..p10 by Eq. 13, two per interval S_i->S_{i+1} of
    :func:`reference_points`.

    Returns
    -------
    (10, 2) float, mm
    """
    s = reference_points(prb_params, end_flexures=end_flexures)
    start = np.repeat(s[:-1], 2, axis=0)
    end = np.repeat(s[1:], 2, axis=0)
    return start + design.a[:, None] * (end - start)


def centreline_points(
    design: ConstantForceDesign,
    prb_params: PRBParams = TABLE1,
    end_flexures: Literal["centred", "outboard"] = "centred",
) -> np.ndarray:
    """Centreline vertices S1, p1..p10, S6 (clamped end first).

    Returns
    -------
    (12, 2) float, mm
    """
    s = reference_points(prb_params, end_flexures=end_flexures)
    return np.vstack([s[:1], design_points(design, prb_params, end_flexures), s[-1:]])


def beam_profile(
    design: ConstantForceDesign,
    prb_params: PRBParams = TABLE1,
    end_flexures: Literal["centred", "outboard"] = "centred",
) -> BeamProfile:
    """The tapered beam the paper optimised: straight segments through S1, p1..p10, S6 with
    thickness T1, t1..t10, T6 varying linearly in between, width B.

    The start (S1) is the clamped end; the end (S6) is the slider, driven along
    :data:`WORK_DIRECTION` with rotation and transverse motion held.

    ``end_flexures`` selects the layout of S1..S6, see :func:`reference_points`.

    Returns
    -------
    BeamProfile
        12 points, in the PRB frame (crank pivot at the origin, slider axis along x), mm.
    """
    return BeamProfile(
        points_mm=centreline_points(design, prb_params, end_flexures),
        thickness_mm=design.vertex_thickness_mm,
        width_mm=design.B,
    )


#: Largest miter factor 1/cos(kink/2) accepted at a centreline vertex (a kink of 120 degrees);
#: the centreline of any design lies close to the line S1->S6, with kinks of a few mrad.
_MAX_MITER = 2.0


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _side_offsets(points: np.ndarray, thickness: np.ndarray) -> np.ndarray:
    """(n, 2) mm: offset ``+t/2`` to the left of the centreline, mitred at interior vertices.

    At a vertex the offset point lies on the bisector of the two segment normals, at ``t / 2 /
    cos(kink / 2)`` from the vertex, so that for constant thickness each offset edge is exactly
    parallel to its segment (the area is ``int t ds`` to second order in the kink).
    """
    d = np.diff(points, axis=0)
    d /= np.linalg.norm(d, axis=1)[:, None]
    normals = np.column_stack([-d[:, 1], d[:, 0]])  # left of each segment
    vertex_n = np.vstack([normals[:1], normals[:-1] + normals[1:], normals[-1:]])
    vertex_n /= np.linalg.norm(vertex_n, axis=1)[:, None]
    # cos(kink / 2) between the bisector and either adjacent normal.
    cos_half = np.concatenate([[1.0], np.einsum("ij,ij->i", vertex_n[1:-1], normals[1:]), [1.0]])
    if np.any(cos_half < 1.0 / _MAX_MITER):
        i = int(np.argmin(cos_half))
        raise GeometryError(
            f"the centreline turns by {np.degrees(2 * np.arccos(cos_half[i])):.0f} degrees at "
            f"vertex {i}; the outline supports kinks up to 120 degrees"
        )
    return points + (0.5 * thickness / cos_half)[:, None] * vertex_n


#: Shortest chord a fillet's flare adds next to a centreline vertex, mm: far below a printer's
#: resolution, far above the micro-edges that a plane-stress mesh resolves into notches.
_MIN_CHORD_MM = 0.02


def _flare_along(points: np.ndarray, thickness: np.ndarray, radius_mm: float):
    """The polyline ``points`` (n, 2) mm with thickness ``thickness`` (n,) mm flared at its start
    into two fillets of ``radius_mm``: points added at ``s = r (1 - cos psi)`` for the
    ``FILLET_CHORDS + 1`` angles psi from 0 to 90 deg (the arc's chord ends), and every point
    with ``s <= r`` thickened by ``2 r (1 - sin psi)``. Unlike the mechanism kind's flare the
    arc may run past a vertex (this beam's end segments are ~1.4 mm, its kinks a few mrad), so
    the centreline is kept exactly. Returns (m, 2) points and (m,) thickness, mm."""
    xy, s, s_vertex, inside, bump = _flare_plan(points, radius_mm)
    t = np.interp(s, s_vertex, thickness)
    t[inside] += bump
    return xy, t


def _flare_plan(points: np.ndarray, radius_mm: float):
    """What :func:`_flare_along` draws that does not depend on the thickness: the flared points
    (m, 2) mm, their arc lengths ``s`` (m,) and the vertices' (n,) mm, the mask (m,) of the
    points within the radius and their thickening (k,) mm. Apart so that many thickness
    vectors can be flared on one centreline by the same arithmetic (:func:`flared_thickness`)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s_vertex = np.concatenate([[0.0], np.cumsum(seg)])
    psi = np.linspace(0.0, 0.5 * np.pi, FILLET_CHORDS + 1)
    s_arc = radius_mm * (1.0 - np.cos(psi))
    # an arc point within _MIN_CHORD_MM of a vertex is left out (the vertex, thickened on the
    # arc, stands for it): a micro-edge there is a notch in the outline (the shipped design's
    # S6 flare at r = 1.361 mm ended 3 um past p10, and plane stress read 45.6 MPa there
    # against 28.5 MPa at the other toes; benchmarks/pad_fillet.py) and a beam element of no
    # length. Not at the end itself: there the arc runs across the beam (s ~ r psi^2 / 2) and
    # its first chords are short in s only; psi = 0 is the end vertex.
    gap = np.abs(s_arc[:, None] - s_vertex[None, 1:])
    far = (np.min(gap, axis=1) > _MIN_CHORD_MM) & (s_arc > 1e-9)
    s = np.union1d(s_vertex, s_arc[far])
    xy = np.column_stack([np.interp(s, s_vertex, points[:, k]) for k in range(2)])
    inside = s < radius_mm
    # cos psi = 1 - s / r on the arc; psi = 90 deg (no thickening) at the toe and beyond
    bump = 2.0 * radius_mm * (1.0 - np.sin(np.arccos(1.0 - s[inside] / radius_mm)))
    return xy, s, s_vertex, inside, bump


#: mm: the shortest blend drawn at a kink; shorter ones (a fillet's chords, 0.02-0.13 mm) are
#: left as drawn (the fillet's Kt covers them).
MIN_BLEND_MM = 0.1

#: Chords of a kink's blend (:func:`_blend_kinks`): each joint between them turns by 1/16 of
#: the kink, whose elastic singularity (exponent ~ 2 x turn / pi) is then 16x weaker still.
#: Why 16, not 8: with 8 the chords' joints showed under refinement on session 28's hybrid
#: design (kinks up to 2.6 deg; peak at 30 mm 42.355 / 42.353 / 42.408 / 43.195 MPa at edges
#: 0.25 / 0.125 / 0.0625 / 0.03125 mm within 1 mm of the peak); with 16 it reads 42.397 /
#: 42.398 / 42.400 MPa at 0.125 / 0.0625 / 0.03125 (32 chords: 42.390 / 42.390 / 42.390) for
#: ~25 % more triangles in the check (docs/constant_force.md, "16 chords, not 8";
#: benchmarks/cf_blend_chords.py).
BLEND_CHORDS = 16


def _blend_kinks(side: np.ndarray, tangent_mm: np.ndarray) -> np.ndarray:
    """The side polyline ``side`` (n, 2) mm with each interior vertex i replaced by a quadratic
    Bezier from ``tangent_mm[i]`` before it to ``tangent_mm[i]`` after it along its two edges
    (control point: the vertex), drawn as :data:`BLEND_CHORDS` chords; a vertex with
    ``tangent_mm[i] <= 0`` (and both ends) is kept sharp. Why: a kink of the outline, where the
    taper changes, is a re-entrant corner on the side where it turns inward, whose stress is
    singular in elasticity (weakly: ~ r^(-2 kink / pi)); no mesh converges on it (the shipped
    design's plane-stress peak rose 0.3 MPa per halving of the edge there). The blend is
    tangent to both edges, so the curve has no corner; it moves the outline by at most
    ``tangent x tan(kink / 2) / 2`` (~ tangent x kink / 4) at the vertex. Returns (m, 2) mm."""
    out = [side[0]]
    u = np.linspace(0.0, 1.0, BLEND_CHORDS + 1)[:, None]
    for i in range(1, len(side) - 1):
        a = float(tangent_mm[i])
        if a <= 0.0:
            out.append(side[i])
            continue
        p = side[i]
        start = p + a * _unit(side[i - 1] - p)
        end = p + a * _unit(side[i + 1] - p)
        out.extend((1 - u) ** 2 * start + 2 * u * (1 - u) * p + u**2 * end)
    out.append(side[-1])
    return np.asarray(out)


def filleted_beam(
    design: ConstantForceDesign,
    prb_params: PRBParams = TABLE1,
    pad_thickness_mm: float = 4.0,
    end_flexures: Literal["centred", "outboard"] = "centred",
    pad_fillet_mm: float = 0.0,
) -> AsMadeBeam:
    """The beam as made where it meets its two pads with fillets of ``pad_fillet_mm`` (mm).

    At each end the radius is ``r = min(pad_fillet_mm, shoulder height (pad_thickness -
    t_end) / 2)`` (a quarter arc cannot rise above the pad's edge), the beam is flared along
    the two arcs (``FILLET_CHORDS`` chords each; thickness ``t(s) + 2 r (1 - sin psi)`` at
    ``s = r (1 - cos psi)``), and ``start`` / ``end`` carry the root's radius, the square
    shoulder's Kt (:func:`geometry.mechanism.shoulder_kt` with ``D = t_end + 2 h``) and the
    flare's length ``root_mm = r``, as the mechanism kind's roots do. Why one shape for both:
    the outline and the beam model must hold the same fillet, and Kt multiplies the beam's
    stress over the flare (its toe is the nominal section). ``pad_fillet_mm = 0`` is the sharp
    step: the beam of :func:`beam_profile`, Kt 1.

    Returns
    -------
    AsMadeBeam
        ``shape.points_mm`` (n, 2) mm and ``shape.thickness_mm`` (n,) mm, S1 first.
    """
    if not pad_fillet_mm >= 0 or not np.isfinite(pad_fillet_mm):
        raise GeometryError(f"pad_fillet_mm = {pad_fillet_mm:g} must be a number >= 0 mm")
    pts = centreline_points(design, prb_params, end_flexures)
    t = design.vertex_thickness_mm.copy()
    length = float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
    ends, radii = [], []
    for t_end in (design.T1, design.T6):  # S1, then S6 with the beam walked backwards
        shoulder = 0.5 * (pad_thickness_mm - t_end)
        r = min(pad_fillet_mm, shoulder, 0.25 * length)
        radii.append(r)
        if r > 1e-6:
            ends.append(EndJunction(0.0, r, shoulder_kt(t_end + 2.0 * shoulder, t_end, r), r))
        else:
            ends.append(EndJunction())
    pts, t = flared_ends(pts, t, radii[0], radii[1])
    return AsMadeBeam(BeamShape("beam", pts, t), ends[0], ends[1])


def flared_ends(
    points: np.ndarray, thickness: np.ndarray, start_mm: float, end_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """The centreline ``points`` (n, 2) mm with vertex thicknesses ``thickness`` (n,) mm flared
    into fillets of radius ``start_mm`` at its start and ``end_mm`` at its end (an end with a
    radius <= 1e-6 mm is left sharp), as :func:`filleted_beam` draws them: (m, 2) points and
    (m,) thickness, mm, start first. Public so that the flared profile's derivatives
    (pipeline/studies/_constant_force_flare_map.py) can redraw it at perturbed thicknesses with
    the radii held, by the same arithmetic."""
    pts, t = points, thickness
    for r in (start_mm, end_mm):  # S1, then S6 with the beam walked backwards
        if r > 1e-6:
            pts, t = _flare_along(pts, t, r)
        pts, t = pts[::-1], t[::-1]
    return pts, t


def flared_thickness(
    points: np.ndarray, thickness: np.ndarray, start_mm: float, end_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`flared_ends` for many thickness vectors on one centreline: ``thickness`` (B, n) mm,
    returns the flared points (m, 2) mm and thicknesses (B, m) mm, row b bit for bit
    ``flared_ends(points, thickness[b], start_mm, end_mm)`` (the same arithmetic; the points
    and the thickening do not depend on the thickness, so they are drawn once). Why: the
    flared profile's derivatives by t1..t10 redraw it 20 times."""
    pts, t = points, np.array(thickness, dtype=float, ndmin=2)
    for r in (start_mm, end_mm):  # S1, then S6 with the beam walked backwards
        if r > 1e-6:
            pts, s, s_vertex, inside, bump = _flare_plan(pts, r)
            t = np.stack([np.interp(s, s_vertex, row) for row in t])
            t[:, inside] += bump
        pts, t = pts[::-1], t[:, ::-1]
    return pts, t


def outline(
    design: ConstantForceDesign,
    prb_params: PRBParams = TABLE1,
    pad_length_mm: float = 8.0,
    pad_thickness_mm: float = 4.0,
    end_flexures: Literal["centred", "outboard"] = "centred",
    pad_fillet_mm: float = 0.0,
    blend_mm: float = 0.0,
) -> Polygon:
    """Printable planar outline: the tapered beam plus a clamping pad at each end.

    The beam's two sides are the centreline offset by ``+-t/2`` (``t`` linear between the vertex
    thicknesses), mitred at the vertices; each pad is a ``pad_length_mm x pad_thickness_mm``
    rectangle continuing the end segment outward from S1 and from S6, centred on the centreline.
    The polygon is built as one ring, not as a union of pieces: a boolean union of per-segment
    trapezoids leaves micro-notches (edges of 1e-6 to 1e-3 mm where the pieces meet at a
    near-straight vertex) that a plane-stress mesh resolves into spurious stress peaks twice the
    real ones.

    Parameters
    ----------
    design : ConstantForceDesign
    prb_params : PRBParams
    pad_length_mm, pad_thickness_mm : float, mm
        The pads must be at least as thick as the beam ends (T1, T6) so they hold the whole end
        section.
    end_flexures : "centred" or "outboard" — see :func:`reference_points`.
    pad_fillet_mm : float, mm
        Radius of the fillets where the beam meets each pad (:func:`filleted_beam`: the beam's
        end segments flared along the arcs, drawn as their chords); 0 (default): a sharp step.
    blend_mm : float, mm
        Each design vertex's kink blended along ``min(blend_mm, a quarter of the shorter
        adjacent segment)`` of both sides' edges (:func:`_blend_kinks`); vertices whose
        segments are shorter than ``4 x MIN_BLEND_MM`` (the fillets' chords) stay as drawn.
        0 (default): mitred corners.

    Returns
    -------
    shapely.Polygon
        One valid polygon, mm, in the PRB frame; area ``int t ds + 2 pad_length pad_thickness``
        (``t`` the flared thickness with fillets).
    """
    if not pad_length_mm > 0 or not pad_thickness_mm > 0:
        raise GeometryError(
            f"pad_length_mm = {pad_length_mm:g} and pad_thickness_mm = {pad_thickness_mm:g} "
            "must both be > 0"
        )
    if pad_thickness_mm < max(design.T1, design.T6):
        raise GeometryError(
            f"pad_thickness_mm = {pad_thickness_mm:g} is thinner than the beam end it holds "
            f"(T1 = {design.T1:g}, T6 = {design.T6:g} mm); use a pad at least "
            f"{max(design.T1, design.T6):g} mm thick"
        )
    made = filleted_beam(design, prb_params, pad_thickness_mm, end_flexures, pad_fillet_mm)
    pts, t = made.shape.points_mm, made.shape.thickness_mm
    left = _side_offsets(pts, t)
    right = _side_offsets(pts, -t)
    if blend_mm > 0:
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        tangent = np.concatenate([[0.0], np.minimum(seg[:-1], seg[1:]) / 4.0, [0.0]])
        tangent = np.where(tangent >= MIN_BLEND_MM, np.minimum(tangent, blend_mm), 0.0)
        left, right = _blend_kinks(left, tangent), _blend_kinks(right, tangent)
    half = 0.5 * pad_thickness_mm

    def pad(end: np.ndarray, outward: np.ndarray) -> list[np.ndarray]:
        # Corners of the pad, counter-clockwise when walked from the beam's right side.
        n = np.array([-outward[1], outward[0]])
        far = end + outward * pad_length_mm
        return [end + half * n, far + half * n, far - half * n, end - half * n]

    # Counter-clockwise: right side S1 -> S6, the S6 pad, left side S6 -> S1, the S1 pad. A pad's
    # corners come out of pad() starting on the left of its outward direction, so they are
    # reversed to continue from the side the ring arrives on.
    end_pad = pad(pts[-1], _unit(pts[-1] - pts[-2]))[::-1]
    start_pad = pad(pts[0], _unit(pts[0] - pts[1]))[::-1]
    ring = np.array([*right, *end_pad, *left[::-1], *start_pad])
    # a fillet as high as the shoulder ends on the pad's corner: drop the repeated point
    keep = np.linalg.norm(ring - np.roll(ring, 1, axis=0), axis=1) > 1e-9
    shape = Polygon(ring[keep])
    if not shape.is_valid:
        raise GeometryError(
            f"the outline is not a valid polygon ({shapely.is_valid_reason(shape)}); check that "
            "the centreline does not cross itself and that the pads clear the beam"
        )
    return shape


def min_feature_mm(design: ConstantForceDesign) -> float:
    """Thinnest in-plane section of the beam, mm (thickness is linear between vertices, so the
    minimum is at a vertex); compare with the printer's minimum wall."""
    return float(design.vertex_thickness_mm.min())
