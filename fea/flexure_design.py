"""Flexure pivots sized from a stiffness target, and the checks of a chosen pivot.

* :func:`flexure_of_type` — the pivot of one type for the ``flexure_pivot`` study's shared
  variables (compliant length, thinnest section, a shape parameter in [0, 1]; the table is in
  pipeline/studies/flexure_pivot.py and docs/flexures.md).
* :func:`pivot_at_range` — the small-angle stiffness, the design stress and the centre shift of
  a pivot at its range of motion: by the large-deflection beam model for the leaf types, by the
  closed forms (with the notch's stress concentration) for the notch hinges.
* :func:`closed_form_seed` — the pivot dimensions that meet a target stiffness by the closed
  forms of :mod:`fea.closed_forms`: on a small grid of thickness and shape, the compliant length
  is the root of ``ln(K(L) / K_target)`` (Brent's method); of the roots inside the envelope the
  one with the largest closed-form safety factor at the range of motion wins. These are the
  seeds of the ``flexure_pivot`` study's GA (docs/flexures.md).
* :func:`pivot_table` — one row per beam row: the beam response, the design stress (beam stress
  times the notch's ``K_t``) and the closed forms beside it.
* :func:`plane_stress_check` — the plane-stress stiffness (linear) and the state at the range of
  motion (nonlinear) of a planar pivot, the reference the beam model and closed forms are judged
  against.

Units: mm, N, MPa, N·mm, rad (the table's ``rotation_deg`` in degrees).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from flexopt.fea.closed_forms import PivotClosedForm, pivot_closed_form
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.pivot import PivotResponse, beam_pivot, plane_stress_pivot, pure_moment_centre
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.flexures import (
    CircularNotch,
    CornerFilleted,
    CrossAxis,
    EllipticalNotch,
    Flexure,
    Leaf,
    VariableLeaf,
)
from scipy.optimize import brentq

__all__ = [
    "BEAM_TYPES",
    "PIVOT_TYPES",
    "FlexureBuilder",
    "PivotAtRange",
    "closed_form_seed",
    "flexure_of_type",
    "pivot_at_range",
    "pivot_table",
    "plane_stress_check",
    "plane_stress_stiffness",
]

PIVOT_TYPES: tuple[str, ...] = (
    "leaf",
    "variable_leaf",
    "circular_notch",
    "elliptical_notch",
    "corner_filleted",
    "cross_axis",
)
#: Types solved with the beam model inside the GA (the rest by closed forms).
BEAM_TYPES = ("leaf", "variable_leaf", "cross_axis")

#: ``build(length_mm, thickness_mm, shape) -> Flexure`` for one pivot type; may raise
#: :class:`GeometryError` for dimensions its generator refuses.
FlexureBuilder = Callable[[float, float, float], Flexure]


def flexure_of_type(
    kind: str,
    length: float,
    thickness: float,
    shape: float,
    width_mm: float,
    block_length_mm: float,
    block_height_mm: float | None = None,
    root_fillet_mm: float = 0.0,
) -> Flexure:
    """The flexure of type ``kind`` for the shared variables (mm; ``shape`` clipped to [0, 1]);
    ``root_fillet_mm`` (mm) rounds the leaf types' roots (0: sharp).

    ==================  =======================  ===============  ============================
    type                length                   thickness        shape
    ==================  =======================  ===============  ============================
    leaf                leaf length L            t                unused
    variable_leaf       leaf length L            t in the middle  end thickness t (1 + 2 shape)
    circular_notch      notch length 2R          web t            unused
    elliptical_notch    notch length 2a          web t            depth c = a / 4 x 8^shape
    corner_filleted     notch length L + 2r      web t            r = (length / 2)(0.1 + 0.8
                                                                  shape)
    cross_axis          leaf length L (at 90)    t                unused
    ==================  =======================  ===============  ============================

    Raises
    ------
    GeometryError
        When the generator refuses the dimensions, or for an unknown type.
    """
    common = {"width_mm": width_mm, "block_length_mm": block_length_mm}
    shape = min(max(float(shape), 0.0), 1.0)
    if kind == "leaf":
        return Leaf(
            length_mm=length,
            thickness_mm=thickness,
            block_height_mm=block_height_mm,
            root_fillet_mm=root_fillet_mm,
            **common,
        )
    if kind == "variable_leaf":
        return VariableLeaf(
            length_mm=length,
            thickness_mm=thickness,
            end_thickness_mm=thickness * (1.0 + 2.0 * shape),
            block_height_mm=block_height_mm,
            root_fillet_mm=root_fillet_mm,
            **common,
        )
    if kind == "circular_notch":
        return CircularNotch(radius_mm=0.5 * length, thickness_mm=thickness, **common)
    if kind == "elliptical_notch":
        a = 0.5 * length
        return EllipticalNotch(
            half_length_mm=a, depth_mm=0.25 * a * 8.0**shape, thickness_mm=thickness, **common
        )
    if kind == "corner_filleted":
        r = 0.5 * length * (0.1 + 0.8 * shape)
        return CornerFilleted(
            length_mm=length - 2.0 * r, fillet_radius_mm=r, thickness_mm=thickness, **common
        )
    if kind == "cross_axis":
        return CrossAxis(
            length_mm=length, thickness_mm=thickness, block_height_mm=block_height_mm, **common
        )
    raise GeometryError(f"unknown pivot type '{kind}'; use one of {', '.join(PIVOT_TYPES)}")


@dataclass(frozen=True)
class PivotAtRange:
    """What a pivot does at its range of motion, by the model its type is solved with.

    Attributes
    ----------
    model : str — ``beam`` or ``closed form``.
    closed_form : PivotClosedForm — of the pivot (also beside a beam solve).
    stiffness_Nmm_per_rad : float, N·mm/rad — small-angle stiffness M / theta.
    stress_MPa : float, MPa — design stress: beam peak x K_t, or the closed form's.
    centre_shift_mm : float, mm — at the range; NaN when not traced, inf when the trace failed.
    failure : str — why the design has no figures ("" when it has): the beam model failed, or
        the members pass a bifurcation within the range.
    """

    model: str
    closed_form: PivotClosedForm
    stiffness_Nmm_per_rad: float = math.nan
    stress_MPa: float = math.nan
    centre_shift_mm: float = math.nan
    failure: str = ""


def pivot_at_range(
    flex: Flexure,
    material: Material,
    range_rad: float,
    steps: int,
    n_elements: int,
    beam_model: bool,
    trace_centre_shift: bool,
    **stops: Any,
) -> PivotAtRange:
    """The figures of ``flex`` at ``range_rad`` the optimiser judges it on.

    Parameters
    ----------
    flex : Flexure.
    material : Material.
    range_rad : float, rad — the range of motion.
    steps : int — rows of the beam sweep; n_elements : int — beam elements per member.
    beam_model : bool — stiffness and stress by the beam model (leaf types); else by the closed
        forms (notch hinges).
    trace_centre_shift : bool — for a closed-form type, also trace the beam model for the
        centre shift (a beam type always has it).
    stops : ``stops=`` and ``contact=`` of :func:`fea.pivot.beam_pivot` (rigid stops), if any.

    Returns
    -------
    PivotAtRange
        With ``failure`` set (and NaN figures) when the beam model fails or the members buckle.
    """
    cf = pivot_closed_form(flex, material.E_MPa)
    if not beam_model:
        shift = math.nan
        if trace_centre_shift:
            res = beam_pivot(flex, material, range_rad, steps, n_elements=n_elements, **stops)
            shift = float(res.centre_shift_mm[-1]) if res.ok else math.inf
        return PivotAtRange(
            "closed form",
            cf,
            cf.stiffness_Nmm_per_rad,
            float(cf.stress_MPa(range_rad)),
            shift,
        )
    res = beam_pivot(flex, material, range_rad, steps, n_elements=n_elements, **stops)
    if not res.ok:
        return PivotAtRange("beam", cf, failure=f"beam model: {res.message}")
    if res.stable is not None and not res.stable[res.converged].all():
        # a pivot whose members buckle within its range is never a safe design
        k = int(np.flatnonzero(res.converged & ~res.stable)[0])
        return PivotAtRange(
            "beam",
            cf,
            failure=f"unstable: the members pass a bifurcation (buckle) by "
            f"{np.degrees(res.rotation_rad[k]):.3g} deg of the range of motion",
        )
    return PivotAtRange(
        "beam",
        cf,
        res.small_angle_stiffness_Nmm_per_rad,
        float(np.nanmax(res.peak_stress_MPa)) * cf.stress_concentration,
        float(res.centre_shift_mm[-1]),
    )


def closed_form_seed(
    build: FlexureBuilder,
    E_MPa: float,
    target_Nmm_per_rad: float,
    allowable_MPa: float,
    range_rad: float,
    lower: np.ndarray,
    upper: np.ndarray,
    max_length_mm: float,
    max_height_mm: float,
) -> list[float] | None:
    """[length_mm, thickness_mm, shape] of the pivot type ``build`` that meets the target
    stiffness by its closed form, with the largest closed-form safety factor inside the envelope.

    Parameters
    ----------
    build : FlexureBuilder — the pivot type's generator.
    E_MPa : float, MPa — Young's modulus.
    target_Nmm_per_rad : float, N·mm/rad — small-angle stiffness to meet.
    allowable_MPa : float, MPa — allowable stress (the safety factor's numerator).
    range_rad : float, rad — rotation at which the stress is taken.
    lower, upper : (4,) float — bounds of (type_index, length_mm, thickness_mm, shape); the
        length is solved within ``[lower[1], upper[1]]``, the thickness takes 9 and the shape 3
        evenly spaced values within their bounds.
    max_length_mm, max_height_mm : float, mm — the envelope.

    Returns
    -------
    list of float or None
        None when no grid point has a root inside the length bounds and the envelope.
    """
    best: tuple[float, list[float]] | None = None
    for t in np.linspace(lower[2], upper[2], 9):
        for s in np.linspace(lower[3], upper[3], 3):

            def gap(length: float, t: float = t, s: float = s) -> float:
                f = build(length, t, s)
                K = pivot_closed_form(f, E_MPa).stiffness_Nmm_per_rad
                return math.log(K / target_Nmm_per_rad)

            try:
                g_lo, g_hi = gap(lower[1]), gap(upper[1])
                if not g_lo >= 0.0 >= g_hi:
                    continue
                length = brentq(gap, lower[1], upper[1], xtol=1e-6)
                f = build(length, t, s)
                envelope = f.envelope_mm()
            except (GeometryError, ValueError):
                continue
            if envelope[0] > max_length_mm or envelope[1] > max_height_mm:
                continue
            cf = pivot_closed_form(f, E_MPa)
            sf = allowable_MPa / float(cf.stress_MPa(range_rad))
            if best is None or sf > best[0]:
                best = (sf, [float(length), float(t), float(s)])
    return None if best is None else best[1]


def pivot_table(res: PivotResponse, cf: PivotClosedForm) -> dict[str, np.ndarray]:
    """One row per beam row: beam response, design stress (x K_t) and the closed forms.

    Returns
    -------
    dict of str to (rows,) array
        ``rotation_deg`` (deg), ``torque_Nmm``, ``stiffness_Nmm_per_rad`` (tangent),
        ``secant_stiffness_Nmm_per_rad``, ``peak_stress_MPa`` (beam x K_t), ``beam_stress_MPa``,
        ``centre_shift_mm``, ``closed_form_torque_Nmm``, ``closed_form_stress_MPa``,
        ``converged`` and ``stable`` (bool).
    """
    angle = res.rotation_rad
    with np.errstate(invalid="ignore", divide="ignore"):
        secant = np.where(angle != 0, res.torque_Nmm / angle, res.small_angle_stiffness_Nmm_per_rad)
    return {
        "rotation_deg": np.degrees(angle),
        "torque_Nmm": res.torque_Nmm,
        "stiffness_Nmm_per_rad": res.stiffness_Nmm_per_rad,
        "secant_stiffness_Nmm_per_rad": secant,
        "peak_stress_MPa": res.peak_stress_MPa * cf.stress_concentration,
        "beam_stress_MPa": res.peak_stress_MPa,
        "centre_shift_mm": res.centre_shift_mm,
        "closed_form_torque_Nmm": cf.torque_Nmm(angle),
        "closed_form_stress_MPa": cf.stress_MPa(angle),
        "converged": res.converged,
        # False on a row past a bifurcation (members buckling): never a plain, safe result
        "stable": (
            np.ones(angle.shape, dtype=bool)
            if res.stable is None
            else np.asarray(res.stable, dtype=bool)
        ),
    }


def _linear_plane_stress(
    flex: Flexure, material: Material, range_rad: float, web_elements: float
) -> PivotResponse:
    # the linear solve of the check (one row at a tenth of the range, about the nominal centre)
    web = flex.min_thickness_mm / web_elements
    return plane_stress_pivot(flex, material, range_rad / 10.0, 1, "linear", web_edge_mm=web)


def plane_stress_stiffness(
    flex: Flexure, material: Material, range_rad: float, web_elements: float
) -> float:
    """The linear plane-stress stiffness of a planar pivot, N·mm/rad: the figure
    :func:`plane_stress_check` reports as ``linear_stiffness_Nmm_per_rad`` (the same solve, the
    same mesh), which the verdict judges the stiffness band on.

    Raises
    ------
    FeaError, GeometryError
        When the plane-stress model cannot be built or solved.
    """
    lin = _linear_plane_stress(flex, material, range_rad, web_elements)
    return float(lin.small_angle_stiffness_Nmm_per_rad)


def plane_stress_check(
    flex: Flexure,
    material: Material,
    range_rad: float,
    steps: int,
    web_elements: float,
    cf: PivotClosedForm,
    beam: PivotResponse,
    allowable_MPa: float,
) -> dict[str, Any]:
    """Plane-stress stiffness (linear, about the nominal centre) and the state at the range of
    motion (nonlinear), the moving block turned about the point that puts it where the beam
    model's pure moment does (so that a wandering rotation centre does not stretch the part).

    Parameters
    ----------
    flex : Flexure — a planar pivot.
    material : Material.
    range_rad : float, rad — the range of motion.
    steps : int — rows of the nonlinear solve.
    web_elements : float — elements through the thinnest section (sets the mesh edge).
    cf : PivotClosedForm — of ``flex`` (the linear stiffness is reported over it).
    beam : PivotResponse — the beam model's sweep to ``range_rad``.
    allowable_MPa : float, MPa — for the safety factor.

    Returns
    -------
    dict
        The record ``detail`` reports under ``plane_stress`` (``skipped`` with the reason when
        the model cannot be built).
    """
    web = flex.min_thickness_mm / web_elements
    t0 = time.perf_counter()
    try:
        lin = _linear_plane_stress(flex, material, range_rad, web_elements)
        centre = flex.centre_mm
        if beam.ok:
            centre = pure_moment_centre(flex.centre_mm, range_rad, beam.centre_displacement_mm[-1])
        non = plane_stress_pivot(
            flex,
            material,
            range_rad,
            steps,
            "nonlinear",
            web_edge_mm=web,
            centre_mm=centre,
        )
    except (FeaError, GeometryError) as exc:
        return {"skipped": f"could not build the plane-stress model: {exc}"}
    K = lin.small_angle_stiffness_Nmm_per_rad
    out: dict[str, Any] = {
        "model": "plane stress, P2 triangles; ground block clamped, moving block turned as a "
        "rigid body (linear: about the nominal centre; nonlinear: about the point that reproduces "
        "the beam model's pure-moment motion at the range of motion)",
        "linear_stiffness_Nmm_per_rad": K,
        "over_closed_form": K / cf.stiffness_Nmm_per_rad,
        "turned_about_mm": [float(v) for v in centre],
        "torque_at_range_Nmm": float(non.torque_Nmm[-1]),
        "beam_torque_at_range_Nmm": float(beam.torque_Nmm[-1]),
        "peak_von_mises_at_range_MPa": float(non.peak_stress_MPa[-1]),
        # every row's peak, and the largest: the verdict judges the largest. The rows before the
        # range are turned about the range's pure-moment centre (not each its own pure-moment
        # state), so an earlier row can read more than the last (13.3 deg: 25.93 against
        # 25.70 MPa at 20 deg on the flexure-pivot example): the largest is the safe figure
        "peak_von_mises_by_row_MPa": [float(v) for v in non.peak_stress_MPa],
        "peak_von_mises_MPa": float(np.nanmax(non.peak_stress_MPa))
        if np.any(np.isfinite(non.peak_stress_MPa))
        else float("nan"),
        "centre_force_at_range_N": float(non.centre_force_N[-1]),
        "ok": non.ok,
        "message": non.message,
        "dofs": non.extra.get("dofs"),
        "time_s": time.perf_counter() - t0,
    }
    if non.ok:
        out["safety_factor"] = allowable_MPa / out["peak_von_mises_MPa"]
    if non.field is not None:  # large arrays: the kind takes them out (pipeline/fields.py)
        out["field"] = non.field
    return out
