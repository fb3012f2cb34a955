"""The threshold-torque spring's parameterisation: named variables -> an arm spring and its beam.

The spring is a :mod:`geometry.arm_spring` spring (``n`` identical curved arms from the hub to
outer pads). Its arm is free to wind around the hub and to bend back: the centreline runs through
four polar control points at ``t = 0, 1/3, 2/3, 1``::

    r   = (r0, r0 + F1 (R_pad - r0), r0 + F2 (R_pad - r0), R_pad),   r0 = hub - W1/2
    phi = (0,  G1 sweep,             G2 sweep,             sweep)

with F1, F2, G1, G2 fractions in [0, 1] *not* ordered (an arm may overshoot outwards and come back,
or sweep ahead and return, which is what makes it a curved strut rather than a spiral), and the
in-plane width through W1..W4 at the same four points. The thickness (ST, the extrusion) is not a
shape variable: the study solves it from the torque target (the torque is proportional to ST).

A positive sweep winds the arm counter-clockwise from the hub, so a counter-clockwise hub rotation
pushes the arm's root along it: the arm is a compressed, curved strut whose force levels off as it
bows out (the softening a threshold profile needs). Units: mm and degrees in the variables.

:func:`arm_profile` cuts the arm's centreline to its elastic part, from the hub rim to the pad
boss, as the :class:`geometry.profile.BeamProfile` the beam model of :mod:`fea.arm_beam` takes.
"""

from __future__ import annotations

import math

import numpy as np
from flexopt.geometry.arm_spring import ArmSpringParams, arm_centreline
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.profile import BeamProfile
from flexopt.geometry.sea_spring import SpringFrame

__all__ = [
    "THRESHOLD_VARIABLES",
    "THRESHOLD_BOUNDS",
    "threshold_params",
    "arm_profile",
    "fold_margin_mm",
]

#: Shape variables of the threshold spring (units in the names; F, G fractions).
THRESHOLD_VARIABLES: tuple[str, ...] = (
    "sweep_deg", "pad_radius_mm", "F1", "F2", "G1", "G2", "W1_mm", "W2_mm", "W3_mm", "W4_mm",
)  # fmt: skip

#: Default bounds (the pad radius's upper bound is also limited by the envelope at build time).
THRESHOLD_BOUNDS: dict[str, tuple[float, float]] = {
    "sweep_deg": (10.0, 330.0),
    "pad_radius_mm": (18.0, 46.5),
    "F1": (0.0, 1.0),
    "F2": (0.0, 1.0),
    "G1": (0.0, 1.0),
    "G2": (0.0, 1.0),
    "W1_mm": (0.5, 6.0),
    "W2_mm": (0.5, 6.0),
    "W3_mm": (0.5, 6.0),
    "W4_mm": (0.5, 6.0),
}


def threshold_params(
    values: dict[str, float],
    n_arms: int,
    thickness_mm: float,
    frame: SpringFrame | None = None,
    root_fillet_mm: float = 1.0,
) -> ArmSpringParams:
    """The arm spring of the named variables of :data:`THRESHOLD_VARIABLES`.

    Raises
    ------
    GeometryError
        For a missing variable or values ArmSpringParams refuses.
    """
    missing = [k for k in THRESHOLD_VARIABLES if k not in values]
    if missing:
        raise GeometryError(f"threshold spring needs {', '.join(missing)}")
    frame = frame or SpringFrame()
    v = {k: float(values[k]) for k in THRESHOLD_VARIABLES}
    w = (v["W1_mm"], v["W2_mm"], v["W3_mm"], v["W4_mm"])
    r0 = frame.hub_radius_mm - 0.5 * w[0]
    r1 = v["pad_radius_mm"]
    sweep = v["sweep_deg"]
    return ArmSpringParams(
        radii_mm=(r0, r0 + v["F1"] * (r1 - r0), r0 + v["F2"] * (r1 - r0), r1),
        angles_deg=(0.0, v["G1"] * sweep, v["G2"] * sweep, sweep),
        widths_mm=w,
        thickness_mm=float(thickness_mm),
        n_arms=int(n_arms),
        root_fillet_mm=root_fillet_mm,
    )


def arm_profile(
    p: ArmSpringParams, frame: SpringFrame | None = None, segment_mm: float = 2.0
) -> BeamProfile:
    """Arm 0's elastic part, from where it leaves the hub rim to where it enters its pad boss.

    Parameters
    ----------
    p : ArmSpringParams
    frame : SpringFrame — hub radius and pad (boss) radius.
    segment_mm : float, mm — spacing of the profile's vertices (the beam model's elements
        follow them; 2 mm keeps the PCHIP centreline's chord error below 1 um per mm of radius).

    Returns
    -------
    BeamProfile — points (n, 2) mm, in-plane width per point as ``thickness_mm``, the spring's
    thickness as ``width_mm``.

    Raises
    ------
    GeometryError
        When the arm never leaves the hub or has too little length outside hub and pad.
    """
    frame = frame or SpringFrame()
    xy, w = arm_centreline(p, max_step_mm=0.25)
    r = np.hypot(xy[:, 0], xy[:, 1])
    to_pad = np.hypot(xy[:, 0] - xy[-1, 0], xy[:, 1] - xy[-1, 1])
    outside = r >= frame.hub_radius_mm
    if not outside.any():
        raise GeometryError("the arm never leaves the hub; make the pad radius larger")
    i0 = int(np.argmax(outside))  # first sample outside the hub rim
    beyond = np.flatnonzero(to_pad[i0:] <= frame.pad_radius_mm)
    i1 = i0 + int(beyond[0]) if beyond.size else len(xy) - 1
    pts, ww = xy[i0 : i1 + 1], w[i0 : i1 + 1]
    length = float(np.sum(np.hypot(*np.diff(pts, axis=0).T))) if len(pts) > 1 else 0.0
    if len(pts) < 3 or length < 2.0 * max(ww.max(), 1.0):
        raise GeometryError(
            f"the arm is {length:.3g} mm long between hub rim and pad boss; it needs at least "
            "two widths (a longer sweep or a larger pad radius)"
        )
    n = max(4, int(math.ceil(length / segment_mm)) + 1)
    idx = np.unique(np.rint(np.linspace(0, len(pts) - 1, n)).astype(int))
    return BeamProfile(pts[idx], ww[idx], p.thickness_mm)


def fold_margin_mm(p: ArmSpringParams, max_step_mm: float = 0.25) -> float:
    """How far the arm is from folding: min over the centreline of (radius of curvature - w/2).

    Non-monotone polar control values can give the PCHIP centreline a cusp (r and phi both
    turning back at one control point): the drawn band then folds into a solid wedge while a beam
    along the centreline would be a hairpin, so the two models describe different parts. A band
    whose every radius of curvature exceeds half its width has offset curves that do not fold.

    Returns
    -------
    float, mm — >= 0 when the band does not fold (the curvature radius is measured from three
    consecutive samples, ``max_step_mm`` apart).
    """
    xy, w = arm_centreline(p, max_step_mm=max_step_mm)
    d = np.diff(xy, axis=0)
    ds = np.hypot(d[:, 0], d[:, 1])
    heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    turn = np.abs(np.diff(heading))  # at the interior samples
    with np.errstate(divide="ignore", invalid="ignore"):  # repeated points: no curvature
        kappa = turn / (0.5 * (ds[:-1] + ds[1:]))
    with np.errstate(divide="ignore"):
        radius = np.where(kappa > 1e-12, 1.0 / kappa, np.inf)
    return float(np.min(radius - 0.5 * w[1:-1]))
