"""The ``spec:`` block of a ``constant_force`` study: a user's force, stroke, envelope and width
limit (the material is the study's ``material:``), mapped onto the kind's frame, targets and
design space, and judged by the closed-form estimate (:mod:`fea.constant_force_estimate`)
before any optimisation. Reference: docs/constant_force.md, section 7.

YAML::

    material: PETG
    spec:
      force_N: 5.0                 # the force to hold (-> target.force_N)
      stroke_mm: 15.0              # the drive (-> boundary.stroke_mm)
      envelope: {length_mm: 90, height_mm: 60}   # the part's box: x (work direction) by y
      width_max_mm: 10.0           # out-of-plane width limit (-> design_space.B upper bound)

The mapping (filled into the study as it is read, so the resolved study.yaml records it):

* the frame: paper 003's PRB slider-crank (x_in 100, e 60, r1 54 mm, theta10 0.542 rad) scaled
  by ``spec.frame_scale`` (derived: the largest scale whose part, pads included, fits the
  envelope; the three flexure lengths stay 10.8 mm, as in :func:`geometry.constant_force.
  beam_profile`), so the beam keeps the paper's shape and 31 degree inclination;
* ``target.force_N`` and ``boundary.stroke_mm`` from the spec (a different explicit value is
  refused), an envelope requirement ``{envelope_mm: [length, height]}``;
* ``design_space``: the twelve thicknesses over ``[min_feature_mm, max(1.5 t_strain, 1.25
  t_req)]`` and B over ``[max(min_feature_mm, B(t_hi) / 2), width_max_mm]`` (names the study
  sets itself are kept); ``design:`` the estimate's uniform beam (Table 3's a1..a10, every
  thickness t_req, B its width) and ``initial: design``, unless the study sets them.
"""

from __future__ import annotations

import math
import sys
from functools import lru_cache
from typing import Any

import numpy as np
from flexopt.fea.constant_force_estimate import (
    MARGINAL_RATIO,
    TAPER_GAIN,
    SpecEstimate,
    estimate_spec,
)
from flexopt.fea.materials import get_material
from flexopt.geometry.constant_force import (
    DESIGN_VARIABLE_NAMES,
    TABLE1,
    TABLE3_OPTIMUM,
    PRBParams,
    design_to_vector,
    outline,
    reference_points,
)
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.study import STUDY_CONFIG
from pydantic import BaseModel, Field

__all__ = [
    "SpecEnvelope",
    "ConstantForceSpec",
    "MIN_SCALE",
    "frame",
    "study_frame",
    "chord",
    "part_box_mm",
    "fit_scale",
    "spec_estimate",
    "fill_from_spec",
    "check_spec",
]

#: Smallest frame scale: the crank r1 = 54 s must stay longer than the 10.8 mm flexure.
MIN_SCALE = 0.25
_MAX_SCALE = 20.0
_THICKNESSES = ("T1", *(f"t{j}" for j in range(1, 11)), "T6")


class SpecEnvelope(BaseModel):
    """``spec.envelope``: the box the printed part (beam and pads) must fit, mm."""

    model_config = STUDY_CONFIG

    length_mm: float = Field(gt=0, le=5000, description="along the work direction (x), mm")
    height_mm: float = Field(gt=0, le=5000, description="across it (y), mm")


class ConstantForceSpec(BaseModel):
    """The ``spec:`` block: what a user asks of a constant-force beam (module docstring)."""

    model_config = STUDY_CONFIG

    force_N: float = Field(gt=0, description="force to hold, N (-> target.force_N)")
    stroke_mm: float = Field(gt=0, le=100, description="drive, mm (-> boundary.stroke_mm)")
    envelope: SpecEnvelope = Field(description="{length_mm, height_mm}: the part's box, mm")
    width_max_mm: float = Field(
        gt=0, description="largest out-of-plane width B, mm (-> design_space.B upper bound)"
    )
    frame_scale: float | None = Field(
        None,
        ge=MIN_SCALE,
        le=_MAX_SCALE,
        description="scale of paper 003's PRB frame; default: the largest whose part fits the "
        "envelope (filled in)",
    )


# --------------------------------------------------------------------------------------------
# The frame


def frame(scale: float) -> PRBParams:
    """Paper 003's Table-1 slider-crank scaled by ``scale`` (x_in, e, r1; the angles kept)."""
    s = float(scale)
    return PRBParams(
        TABLE1.r1_mm * s, TABLE1.theta10_rad, TABLE1.K1_Nmm, TABLE1.K2_Nmm, TABLE1.K3_Nmm,
        TABLE1.x_in_mm * s, TABLE1.e_mm * s,
    )  # fmt: skip


def study_frame(study: Any) -> PRBParams:
    """The frame a study's beam is laid out on: Table 1 without ``spec:`` (the paper's)."""
    spec = getattr(study, "spec", None)
    if spec is None:
        return TABLE1
    scale = spec.frame_scale or fit_scale(
        spec.envelope.length_mm, spec.envelope.height_mm, _geometry_key(study.geometry)
    )
    return frame(scale)


def chord(prb: PRBParams, end_flexures: str) -> tuple[float, float]:
    """Length (mm) of the chord S1 -> S6 and its angle to x (rad)."""
    s = reference_points(prb, end_flexures=end_flexures)  # type: ignore[arg-type]
    v = s[-1] - s[0]
    return float(np.hypot(*v)), float(math.atan2(v[1], v[0]))


def _geometry_key(g: Any) -> tuple[str, float, float]:
    return (str(g.end_flexures), float(g.pad_length_mm), float(g.pad_thickness_mm))


@lru_cache(maxsize=64)
def part_box_mm(scale: float, geometry: tuple[str, float, float]) -> tuple[float, float]:
    """Bounding box (x, y), mm, of the part (Table 3's design, pads included) in the frame
    scaled by ``scale``; ``geometry`` = (end_flexures, pad_length_mm, pad_thickness_mm). The
    pads and the chord set it: a design's thicknesses move it by well under 0.1 mm."""
    end_flexures, pad_length, pad_thickness = geometry
    shape = outline(TABLE3_OPTIMUM, frame(scale), pad_length, pad_thickness, end_flexures)  # type: ignore[arg-type]
    x0, y0, x1, y1 = shape.bounds
    return float(x1 - x0), float(y1 - y0)


@lru_cache(maxsize=64)
def fit_scale(length_mm: float, height_mm: float, geometry: tuple[str, float, float]) -> float:
    """Largest frame scale whose part fits ``length_mm x height_mm`` (bisection to 1e-6), or
    :data:`MIN_SCALE` when even that does not fit (:func:`check_spec` refuses it)."""

    def fits(s: float) -> bool:
        w, h = part_box_mm(s, geometry)
        return w <= length_mm and h <= height_mm

    if not fits(MIN_SCALE):
        return MIN_SCALE
    lo, hi = MIN_SCALE, _MAX_SCALE
    if fits(hi):
        return hi
    while hi - lo > 1e-6:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    return round(lo, 6)


def _envelope_for_length(length_mm: float, geometry: tuple[str, float, float]) -> tuple:
    """The part's box (x, y), mm, in the frame whose chord is ``length_mm`` (chord is affine
    in the scale: the flexures keep their length)."""
    l1, _ = chord(frame(1.0), geometry[0])
    l2, _ = chord(frame(2.0), geometry[0])
    s = 1.0 + (length_mm - l1) / (l2 - l1)
    return part_box_mm(round(max(s, MIN_SCALE), 6), geometry)


# --------------------------------------------------------------------------------------------
# The estimate and the mapping


def spec_estimate(
    spec: ConstantForceSpec, geometry: Any, E_MPa: float, allowable_MPa: float
) -> SpecEstimate:
    """:func:`fea.constant_force_estimate.estimate_spec` for ``spec`` in its frame."""
    scale = spec.frame_scale or fit_scale(
        spec.envelope.length_mm, spec.envelope.height_mm, _geometry_key(geometry)
    )
    length, angle = chord(frame(scale), geometry.end_flexures)
    return estimate_spec(
        spec.force_N, spec.stroke_mm, length, angle, E_MPa, allowable_MPa, spec.width_max_mm,
        geometry.min_feature_mm,
    )  # fmt: skip


def _material_figures(raw: Any, allowable: Any) -> tuple[float, float]:
    if isinstance(raw, str):
        m = get_material(raw)
        E, yield_MPa = m.E_MPa, m.yield_MPa
    else:
        E, yield_MPa = float(raw["E_MPa"]), float(raw["yield_MPa"])
    return float(E), float(allowable if allowable is not None else yield_MPa)


def _bounds(est: SpecEstimate, t_min: float, pad_mm: float) -> dict[str, list[float]]:
    # the pads hold the beam's ends, so no thickness may pass them (check() refuses it)
    t_hi = min(max(1.5 * est.max_thickness_mm, 1.25 * est.thickness_mm), pad_mm)
    width_hi = (
        3.0
        * est.force_N
        * est.length_mm**2
        / (math.pi**2 * est.E_MPa * t_hi**3 * math.cos(est.angle_rad))
    )
    b_lo = min(max(t_min, 0.5 * width_hi), 0.5 * est.width_max_mm)
    out = {name: [round(t_min, 4), round(t_hi, 4)] for name in _THICKNESSES}
    out["B"] = [round(b_lo, 4), round(est.width_max_mm, 4)]
    return out


def fill_from_spec(data: Any, geometry_model: type[BaseModel]) -> Any:
    """The study's raw mapping with what ``spec:`` implies filled in (module docstring); the
    data as given when there is no spec or it cannot be read yet (the validators and
    :func:`check_spec` then report what is wrong, with its key path)."""
    if not isinstance(data, dict) or not isinstance(data.get("spec"), dict):
        return data
    try:
        spec = ConstantForceSpec.model_validate(data["spec"])
        geometry = geometry_model.model_validate(data.get("geometry"))
        target = dict(data.get("target") or {})
        E, allowable = _material_figures(data.get("material"), target.get("allowable_stress_MPa"))
        scale = spec.frame_scale or fit_scale(
            spec.envelope.length_mm, spec.envelope.height_mm, _geometry_key(geometry)
        )
        spec = spec.model_copy(update={"frame_scale": scale})
        est = spec_estimate(spec, geometry, E, allowable)
    except Exception:  # reported by validation or check_spec
        return data
    out = dict(data)
    out["spec"] = {**data["spec"], "frame_scale": scale}
    out["target"] = {"force_N": spec.force_N, **target}
    out["boundary"] = {"stroke_mm": spec.stroke_mm, **dict(data.get("boundary") or {})}
    if est.status != "infeasible" or math.isfinite(est.max_thickness_mm):
        space = _bounds(est, geometry.min_feature_mm, geometry.pad_thickness_mm)
        out["design_space"] = {**space, **dict(data.get("design_space") or {})}
    if "design" not in data:
        x = design_to_vector(TABLE3_OPTIMUM)
        for i, name in enumerate(DESIGN_VARIABLE_NAMES):
            if name in _THICKNESSES:
                x[i] = est.thickness_mm
        x[DESIGN_VARIABLE_NAMES.index("B")] = est.width_mm
        out["design"] = {
            n: round(float(v), 4) for n, v in zip(DESIGN_VARIABLE_NAMES, x, strict=True)
        }
        out.setdefault("initial", "design")
    reqs = list(data.get("requirements") or [])
    if not any(isinstance(r, dict) and "envelope_mm" in r for r in reqs):
        reqs.append({"envelope_mm": [spec.envelope.length_mm, spec.envelope.height_mm]})
        out["requirements"] = reqs
    return out


# --------------------------------------------------------------------------------------------
# The judgement before any optimisation

_WARNED: set[str] = set()


def _g(value: float | None, unit: str = "") -> str:
    return "-" if value is None else f"{value:.3g}{unit}"


def _remedies(est: SpecEstimate, geometry: Any) -> str:
    """What would make the spec feasible by the estimate: its figures recomputed at
    ``MARGINAL_RATIO`` of the allowable (the edge of ``feasible``), one change at a time."""
    key = _geometry_key(geometry)
    edge = estimate_spec(
        est.force_N, est.stroke_mm, est.length_mm, est.angle_rad, est.E_MPa,
        MARGINAL_RATIO * est.allowable_MPa, est.width_max_mm, est.min_thickness_mm,
    )  # fmt: skip
    out = []
    if edge.max_stroke_mm is not None:
        out.append(f"a stroke <= {_g(edge.max_stroke_mm)} mm")
    if edge.max_force_N is not None:
        out.append(f"a force <= {_g(edge.max_force_N)} N")
    if edge.min_width_mm is not None and est.thickness_mm > est.min_thickness_mm:
        out.append(f"width_max_mm >= {_g(edge.min_width_mm)}")
    if edge.min_length_mm is not None:
        w, h = _envelope_for_length(edge.min_length_mm, key)
        out.append(f"an envelope of >= {w:.0f} x {h:.0f} mm (a {edge.min_length_mm:.0f} mm beam)")
    return ", or ".join(out) if out else "a shorter stroke or a longer envelope"


def _figure(est: SpecEstimate, material: str) -> str:
    return (
        f"the {est.length_mm:.1f} mm beam the envelope leaves needs a {est.thickness_mm:.3g} mm "
        f"section for {est.force_N:g} N at {est.width_mm:.3g} mm width (thinnest printable "
        f"{est.min_thickness_mm:g} mm), which reaches {est.peak_stress_MPa:.3g} MPa at "
        f"{est.stroke_mm:g} mm in {material} (allowable {est.allowable_MPa:g} MPa, "
        f"{100 * est.stress_ratio:.0f} %; closed-form estimate, docs/constant_force.md "
        "section 7)"
    )


def check_spec(study: Any) -> SpecEstimate | None:
    """Refuse a ``spec:`` the material cannot give, warn about a marginal one (on stderr, once
    per spec and process), before any run folder exists. None without a spec.

    Raises
    ------
    StudyError
        One line: the key path, the estimate's figure and what would make the spec feasible.
    """
    spec = getattr(study, "spec", None)
    if spec is None:
        return None
    if study.target.force_N != spec.force_N:
        raise StudyError(
            "target.force_N",
            f"{study.target.force_N:g} N differs from spec.force_N = {spec.force_N:g} N; give "
            "the force once (spec.force_N sets target.force_N)",
        )
    if study.boundary.stroke_mm != spec.stroke_mm:
        raise StudyError(
            "boundary.stroke_mm",
            f"{study.boundary.stroke_mm:g} mm differs from spec.stroke_mm = {spec.stroke_mm:g} "
            "mm; give the stroke once (spec.stroke_mm sets boundary.stroke_mm)",
        )
    g = study.geometry
    if spec.width_max_mm < g.min_feature_mm:
        raise StudyError(
            "spec.width_max_mm",
            f"{spec.width_max_mm:g} mm is below geometry.min_feature_mm = {g.min_feature_mm:g}: "
            "no printable beam fits; allow a wider part",
        )
    b_hi = study.design_space.get("B", [0.0, spec.width_max_mm])[1]
    if b_hi > spec.width_max_mm:
        raise StudyError(
            "design_space.B",
            f"upper bound {b_hi:g} mm exceeds spec.width_max_mm = {spec.width_max_mm:g} mm; "
            "lower it or leave B out (the spec sets it)",
        )
    key = _geometry_key(g)
    scale = spec.frame_scale or fit_scale(spec.envelope.length_mm, spec.envelope.height_mm, key)
    w, h = part_box_mm(scale, key)
    fitted = fit_scale(spec.envelope.length_mm, spec.envelope.height_mm, key)
    if w > spec.envelope.length_mm * (1 + 1e-6) or h > spec.envelope.height_mm * (1 + 1e-6):
        raise StudyError(
            "spec.envelope",
            f"{spec.envelope.length_mm:g} x {spec.envelope.height_mm:g} mm cannot hold the "
            f"part: at frame_scale {scale:g} it is {w:.1f} x {h:.1f} mm (the smallest frame, "
            f"scale {MIN_SCALE:g}, is {part_box_mm(MIN_SCALE, key)[0]:.1f} x "
            f"{part_box_mm(MIN_SCALE, key)[1]:.1f} mm); "
            + (
                f"give a larger envelope, or spec.frame_scale <= {fitted:g} (or none)"
                if spec.frame_scale is not None and fitted > MIN_SCALE
                else "give a larger envelope"
            ),
        )
    est = spec_estimate(spec, g, study.material.E_MPa, study.allowable_MPa)
    material = getattr(study.material, "name", None) or "this material"
    if est.status == "infeasible":
        if est.limit == "geometry":
            raise StudyError(
                "spec.stroke_mm",
                f"{spec.stroke_mm:g} mm is too long for the {est.length_mm:.1f} mm beam the "
                f"envelope leaves (at most 0.8 x its reach along x); give a longer envelope "
                f"(a beam of >= {est.min_length_mm:.0f} mm) or a shorter stroke",
            )
        if est.limit == "small_force":
            raise StudyError(
                "spec.force_N",
                f"{spec.force_N:g} N is below the {est.min_force_N:.3g} N of the thinnest and "
                f"narrowest printable beam ({est.min_thickness_mm:g} x {est.min_thickness_mm:g} "
                f"mm) over the {est.length_mm:.1f} mm the envelope leaves; the force falls "
                "with the square of the length: give a smaller envelope or a larger force",
            )
        path = "spec.stroke_mm" if est.limit == "stroke" else "spec.force_N"
        what = (
            f"{spec.stroke_mm:g} mm needs more strain than {material} gives"
            if est.limit == "stroke"
            else f"{spec.force_N:g} N over {spec.stroke_mm:g} mm is more than {material} gives"
        )
        raise StudyError(
            path,
            f"{what}: {_figure(est, material)}; beyond what even a tapered beam can spread "
            f"(x {TAPER_GAIN:.2f}); feasible (<= {100 * MARGINAL_RATIO:.0f} %) with "
            f"{_remedies(est, g)}",
        )
    if est.status == "marginal":
        note = (
            f"spec: marginal: {_figure(est, material)}; above {100 * MARGINAL_RATIO:.0f} % "
            "a uniform beam has no margin and only a tapered one can do better (to "
            f"{100 * TAPER_GAIN:.0f} %): the optimiser may find no feasible design; feasible "
            f"(<= {100 * MARGINAL_RATIO:.0f} %) with {_remedies(est, g)}"
        )
        if note not in _WARNED:
            _WARNED.add(note)
            print(f"flexopt: warning: {note}", file=sys.stderr)
    return est
