r"""Cam–follower torque generator of the V2SOM safety joint (paper 000, Ayoubi et al. 2019): its
shapes.

A cam turns by ``γ`` about its centre O between ``n`` spring-loaded roller followers (radius
``r1``) that slide on radial guides (paper Fig. 6; ``n = 2``). :class:`CamLayout`,
:class:`CamSprings` and :class:`CamProfile` describe the mechanism and a synthesised follower
motion; :func:`cam_outline` turns the profile into a plate (shapely, mm), :func:`cam_stl` into a
printable solid, and :func:`follower_radius_from_outline` reads the follower motion back off a
plate. The synthesis itself (Eqs. 5–12), the torque by virtual work, the Hertz contact pressure,
the stiffness-adjusting block and the Eq. 17 correction are mechanics: :mod:`fea.contact`.

**Frames.** The carrier frame has one follower's guide along +x. A follower visits the cam-frame
polar angle ``φ = γ`` (so the cam turns by ``-γ`` relative to the carrier); its centre traces the
*pitch curve* ``r(|φ|)``. With ``r' = dr/dγ`` the contact normal makes the angle ``α`` of Eq. 4
with the guide's normal: ``tan α = r / r' = r γ'`` (Eq. 10, first line), and the contact point sits
at ``(r - r1 sin α, r1 cos α)`` in the carrier frame, i.e. at polar ``(ρ, β)`` of Eq. 5.

Units: mm, N, N·mm, rad, MPa.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from flexopt.geometry.errors import GeometryError
from shapely.geometry import MultiPolygon, Point, Polygon

__all__ = [
    "CamLayout",
    "CamProfile",
    "CamSettings",
    "CamSprings",
    "cam_outline",
    "cam_stl",
    "follower_radius_from_outline",
]


@dataclass(frozen=True)
class CamSettings:
    """Numerical settings of the synthesis, each with its reason."""

    # Bisection steps for r = U^-1(W): 100 halvings of a bracket of < 1e4 mm reach the float
    # resolution of r, so the virtual-work identity holds to rounding.
    bisection_steps: int = 100
    # Points of the W(γ) table used to invert W with friction; the sqrt(W) table is linear near
    # 0, so 4000 points keep the interpolation error below 1e-7 rad for the paper's s = 50.
    work_table_points: int = 4000
    # solve_ivp tolerances of the friction ODE du/dr (u in N·mm).
    rtol: float = 1e-10
    atol_Nmm: float = 1e-9
    # Points per unit of cam angle where the pitch curve is sampled for the outline; the erosion
    # by the roller is then exact to the polygon's chords (< 1 µm at r ~ 20 mm for 2000/rad).
    outline_points_per_rad: int = 2000
    # Segments per quarter circle of the roller in the erosion (shapely buffer): 64 keeps the
    # rounding of the roller's arcs below 0.03 % of r1.
    quad_segs: int = 64


@dataclass(frozen=True)
class CamSprings:
    """The follower springs of Eq. 13 (paper Fig. 7): ``F_k = count r K (1 - l0/sqrt(r² + b²))``.

    ``count`` extension springs of rate ``K`` and initial length ``l0`` pull each follower
    towards the axis; each is anchored at a lateral offset ``b`` from the guide, so its radial
    component is ``K (L - l0) r/L`` with ``L = sqrt(r² + b²)``. ``F_k`` acts on *each* follower.

    Attributes
    ----------
    stiffness_N_per_mm : float, N/mm — K, one spring.
    free_length_mm : float, mm — l0.
    offset_mm : float, mm — b (0: springs along the guide, a linear spring ``count K (r - l0)``).
    count : int — springs per follower (the paper: 4).
    """

    stiffness_N_per_mm: float
    free_length_mm: float
    offset_mm: float = 0.0
    count: int = 4

    def __post_init__(self) -> None:
        if not (math.isfinite(self.stiffness_N_per_mm) and self.stiffness_N_per_mm > 0):
            raise GeometryError(f"stiffness_N_per_mm = {self.stiffness_N_per_mm} must be > 0")
        if not (math.isfinite(self.free_length_mm) and self.free_length_mm >= 0):
            raise GeometryError(f"free_length_mm = {self.free_length_mm} must be >= 0")
        if not (math.isfinite(self.offset_mm) and self.offset_mm >= 0):
            raise GeometryError(f"offset_mm = {self.offset_mm} must be >= 0")
        if self.count < 1:
            raise GeometryError(f"count = {self.count} must be >= 1 spring per follower")

    def force_N(self, r_mm: Any) -> np.ndarray:
        """Radial spring force on one follower, N (Eq. 13), at follower radii ``r_mm`` (mm)."""
        r = np.asarray(r_mm, dtype=float)
        return (
            self.count
            * self.stiffness_N_per_mm
            * r
            * (1.0 - self.free_length_mm / np.hypot(r, self.offset_mm))
        )

    def rate_N_per_mm(self, r_mm: Any) -> np.ndarray:
        """``dF_k/dr``, N/mm."""
        r = np.asarray(r_mm, dtype=float)
        b2 = self.offset_mm**2
        return (
            self.count
            * self.stiffness_N_per_mm
            * (1.0 - self.free_length_mm * b2 / (r**2 + b2) ** 1.5)
        )

    def primitive_Nmm(self, r_mm: Any) -> np.ndarray:
        """A primitive of ``F_k``: ``count K (r²/2 - l0 sqrt(r² + b²))``, N·mm."""
        r = np.asarray(r_mm, dtype=float)
        return (
            self.count
            * self.stiffness_N_per_mm
            * (0.5 * r**2 - self.free_length_mm * np.hypot(r, self.offset_mm))
        )


@dataclass(frozen=True)
class CamLayout:
    """Where the followers run and what the plate looks like.

    Attributes
    ----------
    rest_radius_mm : float, mm — r0, follower centre at γ = 0.
    roller_radius_mm : float, mm — r1.
    followers : int — n, evenly spaced (paper: 2). Each covers a sector of 2π/n of the cam.
    max_rotation_rad : float, rad — γ_max, the synthesised range (≤ π/n; paper ±90° with n = 2).
        Beyond it the pitch curve dwells at r(γ_max) (zero torque): a stop, not a spring.
    friction : float — μ, Coulomb friction of the follower guides (Eq. 3).
    thickness_mm : float, mm — plate thickness (the extrusion height and the contact width).
    bore_diameter_mm : float, mm — shaft bore (0: none).
    """

    rest_radius_mm: float
    roller_radius_mm: float
    followers: int = 2
    max_rotation_rad: float = math.pi / 2
    friction: float = 0.0
    thickness_mm: float = 8.0
    bore_diameter_mm: float = 6.0

    def __post_init__(self) -> None:
        if self.followers < 2:
            raise GeometryError(
                f"followers = {self.followers}; use at least 2 (one follower loads the shaft "
                "sideways and the paper's Eq. 1 assumes the radial forces cancel)"
            )
        if not self.rest_radius_mm > self.roller_radius_mm > 0:
            raise GeometryError(
                f"rest_radius_mm = {self.rest_radius_mm} must exceed roller_radius_mm = "
                f"{self.roller_radius_mm} > 0 (the roller would reach past the cam's centre)"
            )
        limit = math.pi / self.followers
        if not 0 < self.max_rotation_rad <= limit + 1e-12:
            raise GeometryError(
                f"max_rotation = {math.degrees(self.max_rotation_rad):g}° must lie in (0, "
                f"{math.degrees(limit):g}°]: with {self.followers} followers each owns "
                f"{math.degrees(2 * limit):g}° of the cam"
            )
        if not 0 <= self.friction < 1:
            raise GeometryError(f"friction = {self.friction} must lie in [0, 1)")
        if not self.thickness_mm > 0:
            raise GeometryError(f"thickness_mm = {self.thickness_mm} must be > 0")
        if not 0 <= self.bore_diameter_mm < 2 * (self.rest_radius_mm - self.roller_radius_mm):
            raise GeometryError(
                f"bore_diameter_mm = {self.bore_diameter_mm} must be >= 0 and smaller than the "
                f"cam's smallest diameter 2 (r0 - r1) = "
                f"{2 * (self.rest_radius_mm - self.roller_radius_mm):g} mm"
            )


@dataclass(frozen=True, eq=False)
class CamProfile:
    """A synthesised cam: the follower motion and contact geometry on a grid of cam rotations.

    Attributes
    ----------
    rotation_rad : (m,) float, rad — γ from 0 to γ_max.
    torque_Nmm : (m,) float, N·mm — the target T(γ) the cam was made for (loading direction).
    follower_radius_mm : (m,) float, mm — r(γ), the pitch curve.
    slope_mm_per_rad : (m,) float, mm/rad — r' = dr/dγ.
    alpha_rad : (m,) float, rad — α of Eq. 4 (90° = radial contact normal).
    pressure_angle_rad : (m,) float, rad — π/2 - α, between the contact normal and the guide.
    beta_rad, rho_mm : (m,) float — the contact point in polar coordinates of the carrier frame
        (Eq. 5); in the cam frame it is at polar (ρ, γ + β).
    spring_force_N : (m,) float, N — F_k(r) on one follower.
    contact_force_N : (m,) float, N — F_r = F_k / (sin α - μ cos α) (Eqs. 2–3).
    pitch_curvature_per_mm : (m,) float, 1/mm — signed curvature of the pitch curve (> 0 convex).
    springs, layout : the inputs.
    """

    rotation_rad: np.ndarray
    torque_Nmm: np.ndarray
    follower_radius_mm: np.ndarray
    slope_mm_per_rad: np.ndarray
    alpha_rad: np.ndarray
    pressure_angle_rad: np.ndarray
    beta_rad: np.ndarray
    rho_mm: np.ndarray
    spring_force_N: np.ndarray
    contact_force_N: np.ndarray
    pitch_curvature_per_mm: np.ndarray
    springs: CamSprings
    layout: CamLayout
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def contact_points_mm(self) -> np.ndarray:
        """(m, 2) float, mm — contact points of follower 0 in the cam frame (polar ρ, γ + β)."""
        ang = self.rotation_rad + self.beta_rad
        return np.column_stack([self.rho_mm * np.cos(ang), self.rho_mm * np.sin(ang)])

    @property
    def profile_radius_mm(self) -> np.ndarray:
        """(m,) float, mm — signed radius of curvature of the cam surface at the contact
        (``1/κ - r1``; > 0 convex, < 0 concave, inf where the pitch curve is straight). A convex
        pitch radius below r1 means undercut: the roller cannot follow the pitch curve there."""
        kappa = self.pitch_curvature_per_mm
        with np.errstate(divide="ignore"):
            return np.where(kappa != 0, 1.0 / kappa, np.inf) - self.layout.roller_radius_mm

    @property
    def max_radius_mm(self) -> float:
        """Largest follower-centre radius, mm (the cam's largest radius is this minus r1)."""
        return float(np.max(self.follower_radius_mm))

    @property
    def undercut(self) -> bool:
        """The roller is wider than a convex bend of the pitch curve somewhere in the range."""
        kappa = self.pitch_curvature_per_mm
        return bool(np.any(kappa * self.layout.roller_radius_mm > 1.0))


# --------------------------------------------------------------------------------------------
# Outline, solid and checks


def _pitch_polygon(profile: CamProfile, settings: CamSettings) -> Polygon:
    """The region inside the pitch curves of all followers, with dwell arcs between them."""
    lay = profile.layout
    n = lay.followers
    gmax = lay.max_rotation_rad
    m = max(int(settings.outline_points_per_rad * gmax), 50)
    g = np.linspace(0.0, gmax, m)
    # cubic Hermite with the exact slopes: linear interpolation of the synthesis grid would put
    # kinks into the pitch curve that show as torque errors of ~0.3 % where r'' is large
    # (scipy.interpolate imported here: importing this module, as every constant-force study
    # does through fea.contact, need not load it)
    from scipy.interpolate import CubicHermiteSpline

    r = CubicHermiteSpline(
        profile.rotation_rad, profile.follower_radius_mm, profile.slope_mm_per_rad
    )(g)
    sector = 2 * math.pi / n
    dwell = sector - 2 * gmax
    pts: list[np.ndarray] = []
    for j in range(n):
        centre = j * sector
        phi = np.concatenate([centre - g[::-1], centre + g[1:]])
        rr = np.concatenate([r[::-1], r[1:]])
        pts.append(np.column_stack([rr * np.cos(phi), rr * np.sin(phi)]))
        if dwell > 1e-9:
            k = max(int(settings.outline_points_per_rad * dwell), 8)
            phi_d = centre + gmax + np.linspace(0, dwell, k + 1)[1:-1]
            pts.append(np.column_stack([r[-1] * np.cos(phi_d), r[-1] * np.sin(phi_d)]))
    poly = Polygon(np.concatenate(pts))
    if not poly.is_valid:
        poly = poly.buffer(0)
    return poly


def cam_outline(profile: CamProfile, settings: CamSettings = CamSettings()) -> Polygon:
    """The cam plate: the pitch region eroded by the roller, minus the bore (mm).

    The erosion keeps exactly the points the roller never reaches while its centre runs along
    the pitch curve, so it is the cam (and it rounds any undercut bend the roller cannot follow).

    Raises
    ------
    GeometryError
        When the roller is so large that the plate falls apart or vanishes.
    """
    lay = profile.layout
    pitch = _pitch_polygon(profile, settings)
    cam = pitch.buffer(-lay.roller_radius_mm, quad_segs=settings.quad_segs)
    if lay.bore_diameter_mm > 0:
        cam = cam.difference(Point(0.0, 0.0).buffer(0.5 * lay.bore_diameter_mm, quad_segs=32))
    if isinstance(cam, MultiPolygon) or cam.is_empty or not isinstance(cam, Polygon):
        raise GeometryError(
            f"the roller (r1 = {lay.roller_radius_mm:g} mm) erodes the cam into pieces or away; "
            "use a smaller roller_radius_mm or a larger rest_radius_mm"
        )
    return cam


def cam_stl(profile: CamProfile, settings: CamSettings = CamSettings()) -> bytes:
    """Binary STL of the cam plate extruded by ``layout.thickness_mm`` (mm)."""
    from flexopt.geometry.solid import extrude, stl_bytes

    return stl_bytes(extrude(cam_outline(profile, settings), profile.layout.thickness_mm))


def follower_radius_from_outline(
    outline: Polygon, roller_radius_mm: float, rotation_rad: Any, spacing_mm: float = 0.005
) -> np.ndarray:
    """Follower-centre radius on the guide at cam-frame angle ``γ``, from the plate alone.

    The roller (radius ``r1``) rests on the plate: its centre on the ray at angle ``γ`` is the
    smallest radius where it does not overlap the plate, ``max(p_x + sqrt(r1² - p_y²))`` over
    boundary points ``p`` (in the ray's frame) with ``|p_y| < r1`` — exact up to the boundary's
    sampling (``spacing_mm``).

    Parameters
    ----------
    outline : shapely Polygon, mm
    roller_radius_mm : float, mm
    rotation_rad : (k,) float, rad
    spacing_mm : float, mm — densification of the boundary.

    Returns
    -------
    (k,) float, mm
    """
    ring = shapely.segmentize(outline.exterior, spacing_mm)
    p = np.asarray(ring.coords, dtype=float)
    out = []
    for g in np.atleast_1d(np.asarray(rotation_rad, dtype=float)):
        c, s = math.cos(g), math.sin(g)
        x = c * p[:, 0] + s * p[:, 1]
        y = -s * p[:, 0] + c * p[:, 1]
        near = (np.abs(y) < roller_radius_mm) & (x > 0)
        out.append(np.max(x[near] + np.sqrt(roller_radius_mm**2 - y[near] ** 2)))
    return np.asarray(out)
