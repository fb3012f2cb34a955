"""Compact planar torsional spring for series elastic actuators (paper 004, Ardakanian et al.).

A rotationally symmetric flat spring with no outer ring: an inner **hub** (bolted to the gearbox
output, turned by the drive), and ``RP`` identical **sets** around it. Each set is a serpentine of
``n`` concentric **arcs** (n odd) joined alternately at their two ends by radial **links**, starting
at the hub with a radial **hub spoke** and ending at an outer **mounting pad** (a round boss with a
bolt hole, held by the output link) through a **neck**. The outline is extruded by the spring
thickness ``ST``. Units: mm and degrees (angles in the parameters), rad inside.

Layout of set k (its frame turned by ``k * 360/RP`` degrees; angles below are within the set)::

    angle 0 (start)                                     alpha (end)     pad        next set
      | hub spoke P1 : hub rim -> arc 1                   |
      | arc 1 at R1, radial thickness S1, spans [0, alpha] | link W1 (arc 1 -> arc 2) at alpha
      | link W2 (arc 2 -> arc 3) at 0                      |
      | ...                                                | link W3 at alpha, ...
      | arc n (outermost) continues past alpha -> neck of radial width P2 -> pad boss (R_pad)
      |<---------------------------- 360/RP per set ------------------------------------->|

Links are straight bars of width W (measured across the bar) whose outer side lies on the radial
ray at the end they close, so every U-turn is flush with that ray. The slots between neighbouring
arcs are open at the end without a link. Concave corners (U-turn slot ends, spoke roots, neck and
pad junctions) are filleted by a morphological closing of radius ``fillet_mm``
(``buffer(+r).buffer(-r)``), which is why a slot must stay wider than ``2 fillet_mm``.

The paper's figures (13, 16, 17) are missing; the shape is reconstructed from the text, Table 6 and
Table 9, and each choice is argued in docs/sea_spring.md. In short:

**GA parameterisation (Table 9, 18 variables)**, :class:`SpringParams`:
R1..R5 arc centre radii, S1..S5 arc radial thicknesses, W1..W4 link widths (arc i -> i+1),
P1 the hub-spoke width, P2 the neck (last arc -> pad) radial width, alpha the angular span of the
arcs, ST the out-of-plane thickness. Table 9 has five radii, four link widths and two more
"P" widths: exactly the members of a five-arc serpentine from hub to pad. RP is not a GA
variable: it is fixed by the Taguchi stage.

**Taguchi parameterisation (Table 6, 6 factors)**, :func:`taguchi_params`:
RP number of sets around the circumference; RR number of loops along the radius (a loop is one
out-and-back of the serpentine, so ``n = 2 RR + 1`` arcs: RR = 2 gives the GA's five arcs);
ST thickness; A the angle between neighbouring sets (the clearance between one set's pad and
the next set's start, degrees); RT the loop thickness along the circumference (the arcs' radial
thickness S: Table 6's 0.5-1.1 mm sits in Table 9's S range 0.8-2); D the loop thickness along
the radius (the radial links' width W, and P1 / P2: Table 6's 1-3.9 mm sits in Table 9's W
range 1-6). The arcs are spread evenly between fixed inner and outer radii and span whatever
the set's share of the circle leaves after the pad and A.

:func:`build_spring` returns a :class:`SpringGeometry`: the printable outline (with bore and bolt
holes), the FE outline (holes inside the rigid bolted footprints left out), the rigid **hub**
footprint (rotated) and **pad** footprints (held), named boundary parts for scikit-fem, mesh
refinement regions, and the checks (envelope, thinnest member, narrowest slot).
:func:`clearances` gives the same checks as signed margins without building the polygon, for
the optimiser's constraints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import shapely
from flexopt.geometry.errors import GeometryError
from shapely import affinity
from shapely.geometry import MultiPolygon, Point, Polygon
from shapely.geometry.base import BaseGeometry

__all__ = [
    "GA_VARIABLES",
    "TABLE6_LEVELS",
    "TABLE9_BOUNDS",
    "SpringFrame",
    "SpringParams",
    "SpringGeometry",
    "build_spring",
    "clearances",
    "mounting_holes",
    "refuse_holes_outside_footprints",
    "ga_bounds",
    "ga_variables",
    "params_from_vector",
    "params_to_vector",
    "taguchi_params",
]

#: Paper 004, Table 6: the five levels of each Taguchi factor (RP, RR counts; ST mm; A degrees;
#: RT, D mm). Levels repeat (RP 2, 3, 3, 4, 4) because the counts have only three values.
TABLE6_LEVELS: dict[str, tuple[float, ...]] = {
    "RP": (2, 3, 3, 4, 4),
    "RR": (1, 2, 2, 3, 3),
    "ST": (5.0, 8.75, 12.5, 16.25, 20.0),
    "A": (2.0, 3.5, 5.0, 6.5, 8.0),
    "RT": (0.5, 0.65, 0.8, 0.95, 1.1),
    "D": (1.0, 1.725, 2.45, 3.175, 3.9),
}

#: Names of the 18 GA variables in vector order (paper 004, Table 9).
GA_VARIABLES: tuple[str, ...] = (
    *(f"R{i}" for i in range(1, 6)),
    *(f"S{i}" for i in range(1, 6)),
    *(f"W{i}" for i in range(1, 5)),
    "P1",
    "P2",
    "alpha",
    "ST",
)

#: Paper 004, Table 9: bounds of the GA variables (mm; alpha in degrees).
TABLE9_BOUNDS: dict[str, tuple[float, float]] = {
    "R1": (11.8, 14.4),
    "R2": (18.0, 21.0),
    "R3": (23.0, 25.0),
    "R4": (28.0, 30.0),
    "R5": (33.0, 34.0),
    "S1": (0.8, 2.0),
    "S2": (0.8, 2.0),
    "S3": (0.8, 2.0),
    "S4": (0.8, 2.0),
    "S5": (0.8, 1.6),
    "W1": (1.0, 6.0),
    "W2": (1.0, 6.0),
    "W3": (1.0, 6.0),
    "W4": (1.0, 6.0),
    "P1": (1.5, 6.0),
    "P2": (1.5, 6.0),
    "alpha": (50.0, 82.0),
    "ST": (8.0, 20.0),
}


@dataclass(frozen=True)
class SpringFrame:
    """Fixed choices around the optimised members: envelope, mounting, manufacturing (mm).

    Attributes
    ----------
    envelope_diameter_mm : the whole spring must fit in this circle (paper: 72 mm).
    hub_radius_mm : outer radius of the hub disc (Table 9's R1 >= 11.8 leaves a slot above 9).
    bore_diameter_mm : central bore of the hub.
    hub_holes : number of bolt holes in the hub.
    hub_hole_diameter_mm, hub_hole_circle_diameter_mm : the hub bolt holes (M2.5 clearance on a
        12 mm circle leaves 1.6 mm walls to the bore and the rim).
    hub_clamp_radius_mm : the flange footprint that turns the hub rigidly in the FE model; a
        little inside the hub rim so the rim-to-spoke fillets are elastic, not clamped.
    pad_radius_mm : radius of the round mounting boss at the end of each set.
    pad_hole_diameter_mm : its bolt hole (M3 clearance).
    pad_clamp_radius_mm : the bolt-head / washer footprint held in the FE model.
    inner_radius_mm, outer_radius_mm : arc centre radii of the first and last arc in the Taguchi
        parameterisation (evenly spread in between); near the middles of Table 9's R1 and R5.
    fillet_mm : radius of the fillets at concave corners (closing radius).
    fillet_segments : polygon segments per quarter circle of a fillet (each segment is a mesh
        edge, so this sets the element size in the fillets: 0.3 mm fillets at 2 segments give
        0.23 mm edges and about a third fewer DOFs than at 4, for a peak stress 1 % lower).
    min_slot_mm : narrowest gap between members (wire-EDM / laser cut with fillets that fit).
    min_feature_mm : thinnest member (machining; a 0.5 mm arc is Table 6's RT level 1).
    arc_step_deg, arc_step_mm : polygon resolution of the arcs: segments at most this many
        degrees and this long (a 1 mm chord at R = 12 mm deviates 10 um from the circle, under
        1 % of an arc's thickness).
    """

    envelope_diameter_mm: float = 72.0
    hub_radius_mm: float = 9.0
    bore_diameter_mm: float = 6.0
    hub_holes: int = 4
    hub_hole_diameter_mm: float = 2.7
    hub_hole_circle_diameter_mm: float = 12.0
    hub_clamp_radius_mm: float = 8.0
    pad_radius_mm: float = 3.5
    pad_hole_diameter_mm: float = 3.2
    pad_clamp_radius_mm: float = 2.75
    inner_radius_mm: float = 12.5
    outer_radius_mm: float = 33.5
    fillet_mm: float = 0.3
    fillet_segments: int = 4
    min_slot_mm: float = 0.8
    min_feature_mm: float = 0.5
    arc_step_deg: float = 2.0
    arc_step_mm: float = 1.0

    def __post_init__(self) -> None:
        positive = (
            "envelope_diameter_mm",
            "hub_radius_mm",
            "pad_radius_mm",
            "hub_clamp_radius_mm",
            "pad_clamp_radius_mm",
            "min_slot_mm",
            "min_feature_mm",
            "arc_step_deg",
            "arc_step_mm",
        )
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise GeometryError(f"SpringFrame.{name} = {value} must be a positive number")
        if not 0 <= self.fillet_mm < 0.5 * self.min_slot_mm:
            raise GeometryError(
                f"fillet_mm = {self.fillet_mm} must lie in [0, min_slot_mm / 2 = "
                f"{0.5 * self.min_slot_mm:g}): a closing of radius r bridges slots narrower "
                "than 2 r"
            )
        if self.hub_clamp_radius_mm > self.hub_radius_mm:
            raise GeometryError(
                f"hub_clamp_radius_mm = {self.hub_clamp_radius_mm} exceeds hub_radius_mm = "
                f"{self.hub_radius_mm}; the flange footprint must lie on the hub"
            )
        if self.pad_clamp_radius_mm > self.pad_radius_mm:
            raise GeometryError(
                f"pad_clamp_radius_mm = {self.pad_clamp_radius_mm} exceeds pad_radius_mm = "
                f"{self.pad_radius_mm}; the washer footprint must lie on the pad"
            )
        if self.pad_hole_diameter_mm >= 2 * self.pad_radius_mm:
            raise GeometryError(
                f"pad_hole_diameter_mm = {self.pad_hole_diameter_mm} leaves no wall in a pad of "
                f"radius {self.pad_radius_mm}; make the pad larger or the hole smaller"
            )
        if self.bore_diameter_mm >= 2 * self.hub_radius_mm:
            raise GeometryError(
                f"bore_diameter_mm = {self.bore_diameter_mm} leaves no hub of radius "
                f"{self.hub_radius_mm}"
            )

    @property
    def envelope_radius_mm(self) -> float:
        return 0.5 * self.envelope_diameter_mm


@dataclass(frozen=True)
class SpringParams:
    """The members of one set (the GA parameterisation, generalised to any odd number of arcs).

    Attributes
    ----------
    radii_mm : (n,) float, mm — centre radius of each arc, increasing (R1..R5); n odd.
    arc_thickness_mm : (n,) float, mm — radial thickness of each arc (S1..S5).
    link_width_mm : (n - 1,) float, mm — width of the link joining arc i to arc i + 1 (W1..W4);
        odd links (W1, W3, ...) close the set's end (alpha), even ones its start (0).
    hub_link_mm : float, mm — width of the hub spoke (P1).
    pad_link_mm : float, mm — radial width of the neck from the last arc to the pad (P2).
    span_deg : float, degrees — angular span of the arcs (alpha).
    thickness_mm : float, mm — out-of-plane thickness, the extrusion (ST).
    n_sets : int — number of sets around the hub (RP).
    """

    radii_mm: tuple[float, ...]
    arc_thickness_mm: tuple[float, ...]
    link_width_mm: tuple[float, ...]
    hub_link_mm: float
    pad_link_mm: float
    span_deg: float
    thickness_mm: float
    n_sets: int = 4

    def __post_init__(self) -> None:
        r = tuple(float(v) for v in self.radii_mm)
        s = tuple(float(v) for v in self.arc_thickness_mm)
        w = tuple(float(v) for v in self.link_width_mm)
        object.__setattr__(self, "radii_mm", r)
        object.__setattr__(self, "arc_thickness_mm", s)
        object.__setattr__(self, "link_width_mm", w)
        n = len(r)
        if n < 1 or n % 2 == 0:
            raise GeometryError(
                f"{n} arcs: a set needs an odd number of arcs (hub spoke at the start, pad at the "
                "end, so the serpentine must end at the far side); use 2 RR + 1 arcs"
            )
        if len(s) != n or len(w) != n - 1:
            raise GeometryError(
                f"{n} radii need {n} arc thicknesses and {n - 1} link widths, got {len(s)} and "
                f"{len(w)}"
            )
        values = {
            "radii_mm": r,
            "arc_thickness_mm": s,
            "link_width_mm": w,
            "hub_link_mm": (self.hub_link_mm,),
            "pad_link_mm": (self.pad_link_mm,),
            "span_deg": (self.span_deg,),
            "thickness_mm": (self.thickness_mm,),
        }
        for name, vals in values.items():
            if not all(math.isfinite(v) and v > 0 for v in vals):
                raise GeometryError(f"SpringParams.{name} = {vals} must be positive numbers")
        if any(b <= a for a, b in zip(r, r[1:], strict=False)):
            raise GeometryError(f"radii_mm = {r} must increase from the hub outwards")
        if int(self.n_sets) != self.n_sets or self.n_sets < 1:
            raise GeometryError(f"n_sets = {self.n_sets} must be a whole number >= 1")

    @property
    def n_arcs(self) -> int:
        return len(self.radii_mm)

    @property
    def pitch_deg(self) -> float:
        """Angle between neighbouring sets, 360 / RP."""
        return 360.0 / self.n_sets


def ga_variables(n_arcs: int = 5) -> tuple[str, ...]:
    """Names of the GA variables for ``n_arcs`` arcs: R1..Rn, S1..Sn, W1..W(n-1), P1, P2,
    alpha, ST (Table 9's 18 for n = 5).

    Raises
    ------
    GeometryError
        ``n_arcs`` not odd and >= 1.
    """
    if int(n_arcs) != n_arcs or n_arcs < 1 or n_arcs % 2 == 0:
        raise GeometryError(f"n_arcs = {n_arcs} must be odd and >= 1 (2 RR + 1)")
    n = int(n_arcs)
    return (
        *(f"R{i}" for i in range(1, n + 1)),
        *(f"S{i}" for i in range(1, n + 1)),
        *(f"W{i}" for i in range(1, n)),
        "P1",
        "P2",
        "alpha",
        "ST",
    )


def ga_bounds(n_arcs: int = 5) -> dict[str, tuple[float, float]]:
    """Bounds of the GA variables (mm, degrees): Table 9 for five arcs; for another count the
    radius bands are spread evenly between Table 9's first and last band, each as wide as
    Table 9's middle one allows for the pitch, with Table 9's S, W, P1, alpha and ST ranges (the
    outermost arc keeps S5's 1.6 mm cap, which keeps it inside the envelope) and the neck P2
    narrowed to 1-2.4 mm above five arcs."""
    names = ga_variables(n_arcs)
    if n_arcs == 5:
        return dict(TABLE9_BOUNDS)
    n = int(n_arcs)
    lo, hi = TABLE9_BOUNDS["R1"], TABLE9_BOUNDS["R5"]
    centres = np.linspace(0.5 * sum(lo), 0.5 * sum(hi), n)
    pitch = (centres[-1] - centres[0]) / max(n - 1, 1)
    half = min(1.0, 0.2 * pitch)
    out: dict[str, tuple[float, float]] = {}
    for i in range(n):
        c = float(centres[i])
        r_lo, r_hi = c - half, c + half
        if i == 0:
            r_lo, r_hi = lo
        if i == n - 1:
            r_lo, r_hi = hi
        out[f"R{i + 1}"] = (round(float(r_lo), 3), round(float(r_hi), 3))
    for i in range(n):
        out[f"S{i + 1}"] = TABLE9_BOUNDS["S5"] if i == n - 1 else TABLE9_BOUNDS["S1"]
    for i in range(n - 1):
        out[f"W{i + 1}"] = TABLE9_BOUNDS["W1"]
    for k in ("P1", "alpha", "ST"):
        out[k] = TABLE9_BOUNDS[k]
    # The neck runs at the pad's radius, inside the last arc: with more arcs the one before the
    # last comes closer, so a wide neck would close that slot (clearances: slot_mm).
    out["P2"] = TABLE9_BOUNDS["P2"] if n < 5 else (1.0, 2.4)
    out = {k: out[k] for k in names}
    assert tuple(out) == names
    return out


def params_from_vector(x: np.ndarray, n_sets: int, n_arcs: int = 5) -> SpringParams:
    """SpringParams from the GA variables in :func:`ga_variables` order (mm, degrees); five
    arcs is Table 9's 18-variable vector (:data:`GA_VARIABLES`).

    Raises
    ------
    GeometryError
        Wrong length or values (see :class:`SpringParams`).
    """
    names = ga_variables(n_arcs)
    n = int(n_arcs)
    x = np.asarray(x, dtype=float).ravel()
    if x.shape != (len(names),):
        raise GeometryError(f"{x.size} values; the GA vector of {n} arcs has {len(names)}: {names}")
    return SpringParams(
        radii_mm=tuple(x[0:n]),
        arc_thickness_mm=tuple(x[n : 2 * n]),
        link_width_mm=tuple(x[2 * n : 3 * n - 1]),
        hub_link_mm=float(x[3 * n - 1]),
        pad_link_mm=float(x[3 * n]),
        span_deg=float(x[3 * n + 1]),
        thickness_mm=float(x[3 * n + 2]),
        n_sets=int(n_sets),
    )


def params_to_vector(p: SpringParams) -> np.ndarray:
    """(3 n + 3,) GA vector of a SpringParams (Table 9's 18 for five arcs)."""
    return np.array(
        [
            *p.radii_mm,
            *p.arc_thickness_mm,
            *p.link_width_mm,
            p.hub_link_mm,
            p.pad_link_mm,
            p.span_deg,
            p.thickness_mm,
        ],
        dtype=float,
    )


def _pad_centre_radius(p: SpringParams, frame: SpringFrame) -> float:
    # The boss sits on the last arc's circle, pulled in just enough to stay in the envelope.
    return min(p.radii_mm[-1], frame.envelope_radius_mm - frame.pad_radius_mm)


def _pad_angle_deg(p: SpringParams, frame: SpringFrame) -> float:
    """Angle of the pad centre within its set: past the arc ends by a slot plus the boss radius."""
    rp = _pad_centre_radius(p, frame)
    return p.span_deg + math.degrees((frame.min_slot_mm + frame.pad_radius_mm) / rp)


def taguchi_params(
    RP: float,
    RR: float,
    ST: float,
    A: float,
    RT: float,
    D: float,
    frame: SpringFrame = SpringFrame(),
) -> SpringParams:
    """The spring of one Taguchi run (paper 004, Table 6 factors).

    Parameters
    ----------
    RP : int — sets around the circumference.
    RR : int — loops along the radius; ``2 RR + 1`` arcs.
    ST : float, mm — thickness.
    A : float, degrees — clearance angle between one set's pad and the next set.
    RT : float, mm — radial thickness of every arc.
    D : float, mm — width of every link, of the hub spoke and of the neck.
    frame : SpringFrame — the arcs are spread evenly over
        ``[inner_radius_mm, outer_radius_mm]``.

    Returns
    -------
    SpringParams
        With ``span_deg = 360/RP - A - (pad footprint)``.

    Raises
    ------
    GeometryError
        Counts that are not whole numbers >= 1, or a set with no room left for its arcs.
    """
    if int(RP) != RP or RP < 1 or int(RR) != RR or RR < 0:
        raise GeometryError(f"RP = {RP} and RR = {RR} must be whole numbers (RP >= 1, RR >= 0)")
    n = 2 * int(RR) + 1
    radii = (
        tuple(np.linspace(frame.inner_radius_mm, frame.outer_radius_mm, n))
        if n > 1
        else (0.5 * (frame.inner_radius_mm + frame.outer_radius_mm),)
    )
    probe = SpringParams(radii, (RT,) * n, (D,) * (n - 1), D, max(D, RT), 1.0, ST, int(RP))
    rp = _pad_centre_radius(probe, frame)
    pad_deg = math.degrees((frame.min_slot_mm + 2.0 * frame.pad_radius_mm) / rp)
    span = 360.0 / RP - A - pad_deg
    if span <= 5.0:
        raise GeometryError(
            f"RP = {RP} sets with A = {A} degrees leave {span:.3g} degrees for the arcs after the "
            f"pads ({pad_deg:.3g} degrees); use fewer sets or a smaller A"
        )
    return SpringParams(radii, (RT,) * n, (D,) * (n - 1), D, max(D, RT), span, ST, int(RP))


# --------------------------------------------------------------------------------------------
# Checks as signed margins (positive = satisfied), cheap and continuous for the optimiser


def clearances(p: SpringParams, frame: SpringFrame = SpringFrame()) -> dict[str, float]:
    """Signed margins of the buildability checks, mm (> 0 satisfied), without building anything.

    Keys
    ----
    envelope_mm : envelope radius minus the outermost material radius (last arc, pad boss).
    thinnest_mm : thinnest member (arcs, links, spoke, neck) minus ``min_feature_mm``.
    slot_mm : narrowest slot (hub to arc 1, between arcs, pad to its own links, pad to the next
        set) minus ``min_slot_mm``.
    link_reach_mm : how far the shortest link stays inside its arcs' span (a link wider than
        the arc it closes would poke past the set's other end).
    """
    R = np.asarray(p.radii_mm)
    S = np.asarray(p.arc_thickness_mm)
    W = np.asarray(p.link_width_mm)
    env = frame.envelope_radius_mm
    rp = _pad_centre_radius(p, frame)
    outer = max(R[-1] + 0.5 * S[-1], rp + frame.pad_radius_mm)
    thinnest = min(S.min(), W.min() if W.size else np.inf, p.hub_link_mm, p.pad_link_mm)
    slots = [R[0] - 0.5 * S[0] - frame.hub_radius_mm]
    slots += list(R[1:] - 0.5 * S[1:] - R[:-1] - 0.5 * S[:-1])
    # The pad's inner side against the previous arc (n-1), which ends at alpha: the neck runs at
    # the pad radius, so the radial clearance between the neck and arc n-1 matters too.
    if R.size > 1:
        slots.append(rp - 0.5 * p.pad_link_mm - (R[-2] + 0.5 * S[-2]))
    # Pad boss against the next set's start ray (its links there), along the circle.
    gap = math.radians(p.pitch_deg - _pad_angle_deg(p, frame)) * rp - frame.pad_radius_mm
    slots.append(gap)
    span = math.radians(p.span_deg)
    reach = min(
        [span * (R[0] - 0.5 * S[0]) - p.hub_link_mm]
        + [span * (R[i] - 0.5 * S[i]) - W[i] for i in range(W.size)]
    )
    return {
        "envelope_mm": float(env - outer),
        "thinnest_mm": float(thinnest - frame.min_feature_mm),
        "slot_mm": float(min(slots) - frame.min_slot_mm),
        "link_reach_mm": float(reach),
    }


# --------------------------------------------------------------------------------------------
# Building the outline


def _arc_angles(r: float, a0: float, a1: float, step: tuple[float, float]) -> np.ndarray:
    """Sample angles of an arc of radius r: at most ``step[0]`` rad and ``step[1]`` mm apart."""
    h = min(step[0], step[1] / max(r, 1e-9))
    return np.linspace(a0, a1, max(2, math.ceil((a1 - a0) / h) + 1))


def _annular_sector(
    r0: float, r1: float, a0: float, a1: float, step: tuple[float, float]
) -> Polygon:
    """Polygon between radii r0 < r1 and angles a0 < a1 (rad); ``step`` = (rad, mm) resolution
    of the arcs (each arc is sampled separately, so the inner one is not over-resolved)."""
    to, ti = _arc_angles(r1, a0, a1, step), _arc_angles(r0, a0, a1, step)[::-1]
    outer = np.column_stack([r1 * np.cos(to), r1 * np.sin(to)])
    inner = np.column_stack([r0 * np.cos(ti), r0 * np.sin(ti)])
    return Polygon(np.vstack([outer, inner]))


def _bar(r0: float, r1: float, angle: float, width: float, side: int) -> Polygon:
    """Straight radial bar from radius r0 to r1 whose edge lies on the ray at ``angle`` (rad);
    it extends ``width`` to the counter-clockwise (side = +1) or clockwise (-1) side of the ray."""
    c, s = math.cos(angle), math.sin(angle)
    e = np.array([c, s])
    n = np.array([-s, c]) * side * width
    pts = [r0 * e, r1 * e, r1 * e + n, r0 * e + n]
    return Polygon(pts)


def _rotate(geom: BaseGeometry, angle_deg: float) -> BaseGeometry:
    return affinity.rotate(geom, angle_deg, origin=(0.0, 0.0))


def _one_set(p: SpringParams, frame: SpringFrame) -> tuple[BaseGeometry, Point]:
    """The members of set 0 (unfilleted, overlapping) and its pad centre."""
    R, S, W = p.radii_mm, p.arc_thickness_mm, p.link_width_mm
    step = (math.radians(frame.arc_step_deg), frame.arc_step_mm)
    span = math.radians(p.span_deg)
    parts: list[BaseGeometry] = []
    for i in range(p.n_arcs):
        parts.append(_annular_sector(R[i] - 0.5 * S[i], R[i] + 0.5 * S[i], 0.0, span, step))
    # Links overlap both arcs they join over the arcs' full thickness, so the union is clean.
    for i, w in enumerate(W):
        r0, r1 = R[i] - 0.5 * S[i], R[i + 1] + 0.5 * S[i + 1]
        if i % 2 == 0:  # W1, W3, ...: at the end (alpha), extending back into the span
            parts.append(_bar(r0, r1, span, w, -1))
        else:  # W2, W4, ...: at the start (0), extending into the span
            parts.append(_bar(r0, r1, 0.0, w, +1))
    # Hub spoke from inside the hub rim (overlap) to the outside of arc 1.
    parts.append(_bar(0.5 * frame.hub_radius_mm, R[0] + 0.5 * S[0], 0.0, p.hub_link_mm, +1))
    # Neck: the last arc carried on past alpha to the pad, radial width P2 centred on the pad.
    rp = _pad_centre_radius(p, frame)
    pad_angle = math.radians(_pad_angle_deg(p, frame))
    rn0 = rp - 0.5 * p.pad_link_mm
    rn1 = min(rp + 0.5 * p.pad_link_mm, frame.envelope_radius_mm)
    # The last arc itself continues at its own thickness over the neck's length, so a neck
    # narrower than S_n or off-centre still joins arc and pad without a step.
    parts.append(_annular_sector(R[-1] - 0.5 * S[-1], R[-1] + 0.5 * S[-1], span, pad_angle, step))
    parts.append(_annular_sector(rn0, rn1, span - 0.5 * step[0], pad_angle, step))
    centre = Point(rp * math.cos(pad_angle), rp * math.sin(pad_angle))
    parts.append(centre.buffer(frame.pad_radius_mm, quad_segs=16))
    return shapely.union_all(parts), centre


@dataclass(frozen=True)
class SpringGeometry:
    """A built spring (mm). See :func:`build_spring`.

    Attributes
    ----------
    params : SpringParams
    frame : SpringFrame
    outline : Polygon — the printable / machinable outline with bore and bolt holes.
    fe_outline : Polygon — the outline without the holes (they lie inside the rigid bolted
        footprints, where they change nothing in the FE model).
    hub_region : Polygon — the flange footprint the drive turns rigidly.
    pad_region : MultiPolygon — the washer footprints held fixed (one per set).
    boundaries : dict name -> geometry — named boundary parts for :func:`fea.mesh.to_skfem`:
        ``"hub"`` (the hub rim and its holes) and ``"pads"`` (the pad bosses and their holes).
    pad_centres_mm : (RP, 2) float, mm.
    refine : list of (geometry, size_mm) — where the mesh should be finer: each arc, link, spoke
        and neck at a third of its thickness, set by :func:`mesh_regions`.
    checks : dict — :func:`clearances` plus the built outline's outer radius, area and the
        number of its pieces.
    """

    params: SpringParams
    frame: SpringFrame
    outline: Polygon
    fe_outline: Polygon
    hub_region: Polygon
    pad_region: MultiPolygon
    boundaries: dict[str, BaseGeometry]
    pad_centres_mm: np.ndarray
    checks: dict[str, float] = field(default_factory=dict)

    @property
    def thickness_mm(self) -> float:
        return self.params.thickness_mm

    @property
    def area_mm2(self) -> float:
        return float(self.outline.area)

    @property
    def volume_mm3(self) -> float:
        return self.area_mm2 * self.params.thickness_mm

    def mass_kg(self, density_kg_m3: float) -> float:
        """Mass of the extruded outline, kg."""
        return self.volume_mm3 * 1e-9 * density_kg_m3

    def mesh_regions(self, elements_through: float = 2.0, max_mm: float = 2.0) -> list:
        """Refinement regions for :func:`fea.mesh.mesh_polygon`: every slender member at its
        thickness / ``elements_through`` (P2 triangles resolve bending with 2-3 across).

        Returns
        -------
        list of (shapely geometry, size mm)
        """
        p, frame = self.params, self.frame
        step = (math.radians(frame.arc_step_deg), frame.arc_step_mm)
        span = math.radians(p.span_deg)
        out = []
        for k in range(p.n_sets):
            turn = k * p.pitch_deg
            for i in range(p.n_arcs):
                r, s = p.radii_mm[i], p.arc_thickness_mm[i]
                band = _annular_sector(r - 0.5 * s, r + 0.5 * s, 0.0, span, step)
                out.append((_rotate(band, turn), min(max_mm, s / elements_through)))
            for i, w in enumerate(p.link_width_mm):
                r0 = p.radii_mm[i] - 0.5 * p.arc_thickness_mm[i]
                r1 = p.radii_mm[i + 1] + 0.5 * p.arc_thickness_mm[i + 1]
                bar = _bar(r0, r1, span if i % 2 == 0 else 0.0, w, -1 if i % 2 == 0 else 1)
                out.append((_rotate(bar, turn), min(max_mm, w / elements_through)))
            spoke = _bar(frame.hub_radius_mm, p.radii_mm[0], 0.0, p.hub_link_mm, +1)
            out.append((_rotate(spoke, turn), min(max_mm, p.hub_link_mm / elements_through)))
        return out


def _hub(p: SpringParams, frame: SpringFrame) -> Polygon:
    return Point(0.0, 0.0).buffer(frame.hub_radius_mm, quad_segs=32)


def refuse_holes_outside_footprints(frame: SpringFrame) -> None:
    """Raise GeometryError when a mounting hole of ``frame`` reaches past the rigid footprint
    it sits in, or the hub's bolt holes are closer than ``min_feature_mm`` to each other.

    The FE models (plane stress, 3D, the peak convergence) mesh the outline *without* its
    holes and hold the hub's flange footprint (radius ``hub_clamp_radius_mm``) rigid and the
    pads' washers (``pad_clamp_radius_mm``) fixed: that is the exported part only while every
    hole lies inside one of those footprints, where a hole changes nothing. A hole reaching
    past one would let the models count material the part lacks, so it is refused with the
    fix (the footprints are polygons of 128 and 64 sides: the holes are judged against their
    inscribed radii)."""
    hub_r = frame.hub_clamp_radius_mm * math.cos(math.pi / 128)
    pad_r = frame.pad_clamp_radius_mm * math.cos(math.pi / 64)
    if frame.bore_diameter_mm > 0 and 0.5 * frame.bore_diameter_mm > hub_r + 1e-9:
        raise GeometryError(
            f"the bore (diameter {frame.bore_diameter_mm:g} mm) reaches past the hub's "
            f"flange footprint (radius {frame.hub_clamp_radius_mm:g} mm), which the models "
            "hold rigid in its place; make the bore smaller"
        )
    k = frame.hub_holes if frame.hub_hole_diameter_mm > 0 else 0
    if k > 0:
        rc, rh = 0.5 * frame.hub_hole_circle_diameter_mm, 0.5 * frame.hub_hole_diameter_mm
        if rc + rh > hub_r + 1e-9:
            raise GeometryError(
                f"the hub bolt holes reach {rc + rh:g} mm from the axis, past the hub's flange "
                f"footprint (radius {frame.hub_clamp_radius_mm:g} mm), which the models hold "
                "rigid in their place; bring the bolt circle in or make the holes smaller"
            )
        wall = 2.0 * rc * math.sin(math.pi / k) - 2.0 * rh if k > 1 else math.inf
        if wall < frame.min_feature_mm - 1e-9:
            raise GeometryError(
                f"the hub's {k} bolt holes leave {wall:.3g} mm between neighbours, under "
                f"min_feature_mm = {frame.min_feature_mm:g}; fewer or smaller holes or a "
                "larger bolt circle"
            )
    if frame.pad_hole_diameter_mm > 0 and 0.5 * frame.pad_hole_diameter_mm > pad_r + 1e-9:
        raise GeometryError(
            f"the pad bolt hole (diameter {frame.pad_hole_diameter_mm:g} mm) reaches past "
            f"the washer footprint (radius {frame.pad_clamp_radius_mm:g} mm), which the "
            "models hold fixed in its place; make the hole smaller"
        )


def mounting_holes(frame: SpringFrame, pads: list[Point]) -> BaseGeometry:
    """The bore, the hub bolt holes (half a pitch off the first set or arm) and a bolt hole in
    every pad centre (``pads``: shapely points, mm), as one geometry (empty when none).
    Raises GeometryError for a hole outside its rigid footprint
    (:func:`refuse_holes_outside_footprints`)."""
    refuse_holes_outside_footprints(frame)
    holes = []
    if frame.bore_diameter_mm > 0:
        holes.append(Point(0.0, 0.0).buffer(0.5 * frame.bore_diameter_mm, quad_segs=16))
    if frame.hub_holes > 0 and frame.hub_hole_diameter_mm > 0:
        rc = 0.5 * frame.hub_hole_circle_diameter_mm
        for j in range(frame.hub_holes):
            # Offset by half a pitch from the spokes so a hole never sits under a spoke root.
            t = 2 * math.pi * (j + 0.5) / frame.hub_holes
            holes.append(
                Point(rc * math.cos(t), rc * math.sin(t)).buffer(
                    0.5 * frame.hub_hole_diameter_mm, quad_segs=12
                )
            )
    if frame.pad_hole_diameter_mm > 0:
        holes += [c.buffer(0.5 * frame.pad_hole_diameter_mm, quad_segs=12) for c in pads]
    return shapely.union_all(holes) if holes else Polygon()


def build_spring(p: SpringParams, frame: SpringFrame = SpringFrame()) -> SpringGeometry:
    """Build the outline of a spring and check it.

    Parameters
    ----------
    p : SpringParams
    frame : SpringFrame

    Returns
    -------
    SpringGeometry

    Raises
    ------
    GeometryError
        A member thinner than ``min_feature_mm``, a slot narrower than ``min_slot_mm``, material
        outside the envelope, a link wider than the span it closes, or an outline that is not one
        valid polygon; the message names the check, the value and the fix.
    """
    margins = clearances(p, frame)
    fixes = {
        "envelope_mm": "reduce the outer radius (last arc, pad) or enlarge the envelope",
        "thinnest_mm": "thicken the thinnest arc / link or lower min_feature_mm",
        "slot_mm": "spread the radii, thin the arcs, narrow the neck or reduce alpha",
        "link_reach_mm": "narrow the link or widen alpha",
    }
    for key, margin in margins.items():
        if margin < -1e-9:
            raise GeometryError(
                f"spring check {key} fails by {-margin:.3g} mm; {fixes[key]} "
                f"(see geometry.sea_spring.clearances)"
            )
    one, pad0 = _one_set(p, frame)
    sets = [_rotate(one, k * p.pitch_deg) for k in range(p.n_sets)]
    pads = [_rotate(pad0, k * p.pitch_deg) for k in range(p.n_sets)]
    body = shapely.union_all([_hub(p, frame), *sets])
    if frame.fillet_mm > 0:
        # Closing fills every concave corner with a fillet of radius r and leaves convex corners
        # and slots wider than 2 r alone. Mitre joins on the way out keep convex corners sharp
        # without adding vertices; the round joins on the way back make the fillets.
        r = frame.fillet_mm
        body = body.buffer(r, join_style="mitre", mitre_limit=20.0).buffer(
            -r, quad_segs=frame.fillet_segments
        )
    # The way back also splits every vertex of a concave arc into two a few micrometres apart;
    # such segments would force micrometre triangles on the mesher. A 2 um tolerance removes
    # them and keeps the fillets (their chords deviate 6 um from the circle at r = 0.3 mm).
    body = shapely.simplify(body, 2e-3, preserve_topology=True)
    if not isinstance(body, Polygon) or not body.is_valid:
        raise GeometryError(
            f"the spring outline is not one valid polygon ({body.geom_type}, "
            f"{shapely.is_valid_reason(body)}); check the slots and link widths"
        )
    if len(body.interiors) != 0:
        raise GeometryError(
            f"the spring outline closed {len(body.interiors)} slot(s) into holes: a slot is "
            f"narrower than 2 fillet_mm = {2 * frame.fillet_mm:g} mm somewhere; widen it"
        )
    holes = mounting_holes(frame, pads)
    outline = body.difference(holes)
    if not isinstance(outline, Polygon) or not outline.is_valid:
        raise GeometryError("the mounting holes cut the spring apart; make them smaller")
    hub_region = Point(0.0, 0.0).buffer(frame.hub_clamp_radius_mm, quad_segs=32)
    pad_region = MultiPolygon([c.buffer(frame.pad_clamp_radius_mm, quad_segs=16) for c in pads])
    boundaries = {
        "hub": Point(0.0, 0.0).buffer(frame.hub_radius_mm + 1e-6, quad_segs=64),
        "pads": shapely.union_all(
            [c.buffer(frame.pad_radius_mm + 1e-6, quad_segs=32) for c in pads]
        ),
    }
    xy = np.asarray(outline.exterior.coords)
    checks = dict(margins)
    checks.update(
        {
            "outer_radius_mm": float(np.hypot(xy[:, 0], xy[:, 1]).max()),
            "area_mm2": float(outline.area),
        }
    )
    centres = np.array([[c.x, c.y] for c in pads])
    return SpringGeometry(
        params=p,
        frame=frame,
        outline=outline,
        fe_outline=body,
        hub_region=hub_region,
        pad_region=pad_region,
        boundaries=boundaries,
        pad_centres_mm=centres,
        checks=checks,
    )
