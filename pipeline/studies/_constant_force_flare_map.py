"""Derivatives of the constant-force beam with pad fillets (``geometry.pad_fillet_mm > 0``) by the
study's 23 design variables: the flared beam's profile and each end's Kt (issue 27; used by
:mod:`._constant_force_gradient` so that ``method: hybrid`` and the report's sensitivities
differentiate Kt x root stress, docs/constant_force.md "Fillets at the pads").

Two links:

* **The flared profile** (:func:`geometry.constant_force.filleted_beam`): the centreline S1,
  p1..p10, S6 with the fillets' arc points inserted at fixed arc lengths ``r (1 - cos psi)`` from
  each end and every point within ``r`` of an end thickened by ``2 r (1 - sin psi)``. The map is
  explicit and smooth wherever its point set does not change (no solve in it): its derivative is
  taken by central differences of the map itself, :data:`GEOMETRY_STEP` of each variable's span,
  truncation ~step^2 (1e-14) and round-off ~1e-16 / step (1e-9) relative; where the perturbed
  maps do not have the design's point count (an arc point crossing a vertex's 0.02 mm gap) the
  answer is None and the optimiser takes finite differences of the study instead. Only a1..a10,
  T1 and T6 go through the whole generator (they move points or a radius); t1..t10 are redrawn
  by :func:`geometry.constant_force.flared_thickness` on the design's centreline and radii (their
  20 perturbed flares at once: the points and the thickening drawn once), and B's columns are
  zero: the same numbers bit for bit, 24 whole-generator calls instead of 47
  (tests/pipeline/test_constant_force_fillet_gradient.py checks every column against the
  generator's own central differences).
* **Kt of each shoulder** (:func:`geometry.mechanism.shoulder_kt`, the Roark / Peterson fit):
  analytic, :func:`shoulder_kt_partials`, with ``D`` the pad thickness, ``d`` the beam's end
  thickness (T1 or T6) and ``r = min(pad_fillet_mm, (D - d) / 2, L / 4)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from flexopt.geometry.constant_force import (
    DESIGN_VARIABLE_NAMES,
    centreline_points,
    design_from_vector,
    filleted_beam,
    flared_thickness,
)
from flexopt.geometry.constant_force_map import profile_derivatives
from flexopt.geometry.errors import GeometryError

__all__ = ["FlareDerivatives", "GEOMETRY_STEP", "flare_derivatives", "shoulder_kt_partials"]

#: the central-difference step of the flared profile's map, a fraction of each variable's value
#: scale (1 for the fractions a_j, the value itself for thicknesses and the width)
GEOMETRY_STEP = 1e-6

# the Roark 7th ed. Table 17.1 coefficients as (constant, sqrt(q), q) per C1..C4, for q = h/r in
# [0.1, 2] and [2, 20] (geometry.mechanism.shoulder_kt holds the same numbers)
_LOW = np.array(
    [
        [1.007, 1.000, -0.031],
        [-0.270, -2.404, 0.749],
        [0.677, 1.133, -0.904],
        [-0.414, 0.271, 0.186],
    ]
)
_HIGH = np.array(
    [
        [1.042, 0.982, -0.036],
        [-3.599, 1.619, -0.431],
        [6.084, -5.607, 1.158],
        [-2.527, 3.006, -0.691],
    ]
)


def shoulder_kt_partials(
    wide_mm: float, narrow_mm: float, radius_mm: float
) -> tuple[float, float, float]:
    """``(Kt, dKt/d narrow, dKt/d radius)`` (1, 1/mm, 1/mm) of
    :func:`geometry.mechanism.shoulder_kt` at a fixed ``wide_mm`` (the pad), differentiating
    its fit: ``h = (D - d) / 2`` (capped at 20 r), ``q = h / r`` (held at 0.1 below it),
    ``Kt = sum_i C_i(q) x^i`` with ``x = 2 h / (d + 2 h)`` and ``C_i = c0 + c1 sqrt(q) + c2 q``.
    Zero where Kt is held (no shoulder, or the fit below 1); one-sided at the kinks (q = 0.1,
    2, 20)."""
    if not (radius_mm > 0 and narrow_mm > 0):
        raise GeometryError(f"a fillet of {radius_mm:g} mm on a {narrow_mm:g} mm beam has no Kt")
    h = 0.5 * (wide_mm - narrow_mm)
    if h <= 0:
        return 1.0, 0.0, 0.0
    # h and its partials (narrow, radius)
    if h > 20.0 * radius_mm:
        h, dh = 20.0 * radius_mm, (0.0, 20.0)
    else:
        dh = (-0.5, 0.0)
    q = h / radius_mm
    dq = (dh[0] / radius_mm, dh[1] / radius_mm - h / radius_mm**2)
    if q < 0.1:
        q, dq = 0.1, (0.0, 0.0)
    coef = _LOW if q <= 2.0 else _HIGH
    root = math.sqrt(q)
    c = coef @ np.array([1.0, root, q])  # (4,) C1..C4
    dc_dq = coef @ np.array([0.0, 0.5 / root, 1.0])
    wide = narrow_mm + 2.0 * h
    x = 2.0 * h / wide
    # x = 2 h / (d + 2 h): dx = (2 dh (d + 2 h) - 2 h (dd + 2 dh)) / wide^2
    #                        = 2 (d dh - h dd) / wide^2
    dx = (2.0 * (narrow_mm * dh[0] - h) / wide**2, 2.0 * narrow_mm * dh[1] / wide**2)
    powers = np.array([1.0, x, x * x, x**3])
    kt = float(c @ powers)
    if kt < 1.0:
        return 1.0, 0.0, 0.0
    dpow = np.array([0.0, 1.0, 2.0 * x, 3.0 * x * x])
    grads = tuple(float(dc_dq @ powers * dq[k] + c @ dpow * dx[k]) for k in range(2))
    return kt, grads[0], grads[1]


@dataclass(frozen=True)
class FlareDerivatives:
    """The flared beam's profile and Kt at one design and their derivatives by the 23 variables.

    Attributes
    ----------
    points : (23, m, 2) mm per unit — d(flared centreline point)/d(x_k), S1 first.
    thickness : (23, m) mm per unit — d(flared thickness)/d(x_k).
    width : (23,) — d(width)/d(x_k).
    kt : (2,) — Kt at S1 and at S6 (1 where the end has no fillet).
    d_kt : (2, 23) per unit — their derivatives.
    root_mm : (2,) mm — each flare's length (its fillet's radius; 0 without one).
    """

    points: np.ndarray
    thickness: np.ndarray
    width: np.ndarray
    kt: np.ndarray
    d_kt: np.ndarray
    root_mm: np.ndarray

    @property
    def moving(self) -> np.ndarray:
        """(k,) int: the variables that move a point (a1..a10; T1 / T6 too where the shoulder
        caps the fillet's radius)."""
        return np.flatnonzero(np.any(self.points != 0.0, axis=(1, 2)))


def _flared(problem: Any, x: np.ndarray) -> Any:
    g = problem.study.geometry
    design = design_from_vector(x)
    return filleted_beam(design, problem.frame, g.pad_thickness_mm, g.end_flexures, g.pad_fillet_mm)


def flare_derivatives(problem: Any, x: np.ndarray) -> FlareDerivatives | None:
    """The derivatives of the study's flared beam at ``x`` (23,) (module docstring), or None
    where a perturbed map changes the point count or cannot be built (the caller then gives no
    exact Jacobian)."""
    g = problem.study.geometry
    x = np.asarray(x, dtype=float)
    made = _flared(problem, x)
    n_pts = len(made.shape.points_mm)
    n = len(x)
    points = np.zeros((n, n_pts, 2))
    thickness = np.zeros((n, n_pts))
    scale = np.where(np.arange(n) < 10, 1.0, np.abs(x))  # a1..a10 are fractions
    # t1..t10 move neither a point nor a fillet's radius (r depends on T1, T6 and the length):
    # their perturbed maps are the design's centreline and radii with one vertex thickness
    # changed, redrawn by the flare alone (the same arithmetic as filleted_beam, so the same
    # numbers, without building a design and its centreline 20 times); their point columns are
    # the difference of two identical arrays, zero. B changes nothing here: its columns are zero.
    centre = centreline_points(design_from_vector(x), problem.frame, g.end_flexures)
    vertex_t = np.concatenate([[x[20]], x[10:20], [x[21]]])  # T1, t1..t10, T6
    radii = (made.start.root_mm, made.end.root_mm)
    # t1..t10's perturbed vertex thicknesses (x + sign h e_k, as design_from_vector reads it),
    # + then - for each, flared on the one centreline at once (flared_thickness: row by row
    # flared_ends' numbers, the points and the thickening drawn once instead of 20 times)
    vertex_ts = []
    for k in range(10, 20):
        for sign in (1.0, -1.0):
            t_k = vertex_t.copy()
            t_k[k - 9] = x[k] + sign * GEOMETRY_STEP * scale[k]
            vertex_ts.append(t_k)
    t_maps = flared_thickness(centre, np.array(vertex_ts), *radii)[1]
    for k in range(n):
        if DESIGN_VARIABLE_NAMES[k] == "B":
            continue
        h = GEOMETRY_STEP * scale[k]
        if 10 <= k < 20:
            thickness[k] = (t_maps[2 * (k - 10)] - t_maps[2 * (k - 10) + 1]) / (2.0 * h)
            continue
        try:
            plus, minus = (_flared(problem, x + sign * h * np.eye(n)[k]) for sign in (1.0, -1.0))
        except GeometryError:
            return None
        if len(plus.shape.points_mm) != n_pts or len(minus.shape.points_mm) != n_pts:
            return None
        points[k] = (plus.shape.points_mm - minus.shape.points_mm) / (2.0 * h)
        thickness[k] = (plus.shape.thickness_mm - minus.shape.thickness_mm) / (2.0 * h)
    width = np.zeros(n)
    width[DESIGN_VARIABLE_NAMES.index("B")] = 1.0
    # Kt: d = T1 / T6, r = min(pad_fillet_mm, (D - d) / 2, L / 4) as filleted_beam takes it
    pts = centreline_points(design_from_vector(x), problem.frame, g.end_flexures)
    seg = np.diff(pts, axis=0)
    length = float(np.sum(np.linalg.norm(seg, axis=1)))
    unit = seg / np.linalg.norm(seg, axis=1)[:, None]
    dvert = profile_derivatives(problem.frame, g.end_flexures).points  # (23, 12, 2)
    d_length = np.einsum("sk,vsk->v", unit, np.diff(dvert, axis=1))  # (23,)
    kt, d_kt, root = np.ones(2), np.zeros((2, n)), np.zeros(2)
    for e, (end, name) in enumerate(((made.start, "T1"), (made.end, "T6"))):
        if end.root_mm <= 0:
            continue
        j = DESIGN_VARIABLE_NAMES.index(name)
        d_end = float(x[j])
        shoulder = 0.5 * (g.pad_thickness_mm - d_end)
        radius = min(g.pad_fillet_mm, shoulder, 0.25 * length)
        d_radius = np.zeros(n)
        if radius == shoulder and shoulder < g.pad_fillet_mm:
            d_radius[j] = -0.5
        elif radius == 0.25 * length and radius < g.pad_fillet_mm:
            d_radius = 0.25 * d_length
        kt[e], k_d, k_r = shoulder_kt_partials(g.pad_thickness_mm, d_end, radius)
        d_kt[e] = k_r * d_radius
        d_kt[e, j] += k_d
        root[e] = end.root_mm
    return FlareDerivatives(points, thickness, width, kt, d_kt, root)
