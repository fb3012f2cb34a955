"""The ``constant_force`` study file: its pydantic models (the key reference is
``docs/constant_force.md``, section "Study"; units are in the key names: mm, N, MPa) and what they
say to the optimiser: the 23-variable design space (:func:`design_space`), the design ``flexopt
evaluate`` solves (:func:`design_vector`) and the refusals across keys before a run
(:func:`check`). The kind is pipeline/studies/constant_force.py.
"""

from __future__ import annotations

import difflib
import math
from typing import Any, ClassVar, Literal

import numpy as np
from flexopt.fea.materials import get_material
from flexopt.geometry.constant_force import (
    DESIGN_VARIABLE_NAMES,
    TABLE3_BOUNDS,
    TABLE3_OPTIMUM,
    design_from_vector,
    design_to_vector,
    outline,
)
from flexopt.geometry.errors import GeometryError
from flexopt.optimise.space import DesignSpace
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies._constant_force_fillet import DEFAULT_PAD_FILLET_MM
from flexopt.pipeline.studies._constant_force_spec import (
    ConstantForceSpec,
    check_spec,
    fill_from_spec,
)
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study
from pydantic import BaseModel, Field, field_validator, model_validator

__all__ = [
    "FRACTIONS",
    "ConstantForceGeometry",
    "ConstantForceBoundary",
    "ForceTarget",
    "PRBSpec",
    "FidelitySpec",
    "ConstantForceSpec",
    "ConstantForceStudy",
    "check",
    "design_space",
    "design_vector",
]

#: Variables that are fractions of an interval S_i -> S_{i+1} (Eq. 13); the rest are lengths, mm.
FRACTIONS = tuple(f"a{j}" for j in range(1, 11))


# --------------------------------------------------------------------------------------------
# The study file


class ConstantForceGeometry(BaseModel):
    """The ``geometry:`` block: layout, beam mesh, printability and clamping pads (mm)."""

    model_config = STUDY_CONFIG

    kind: Literal["constant_force"] = Field(description="constant_force")
    end_flexures: Literal["centred", "outboard"] = Field(
        "centred",
        description="layout of the ground and slider flexures: centred on the PRB joints (the "
        "paper's text) or outboard of them (a 10.8 mm longer beam)",
    )
    elements: int = Field(
        60, ge=11, le=5000, description="beam elements (at least one per segment: 11)"
    )
    min_feature_mm: float = Field(
        0.8,
        gt=0,
        description="thinnest printable section, mm; thinner designs are infeasible before FEA",
    )
    pad_length_mm: float = Field(8.0, gt=0, description="clamping pad length beyond S1 and S6, mm")
    pad_thickness_mm: float = Field(4.0, gt=0, description="clamping pad thickness, mm")
    pad_fillet_mm: float = Field(
        DEFAULT_PAD_FILLET_MM,
        ge=0,
        le=10,
        description="radius of the fillets where the beam meets each pad, mm (capped at the "
        "shoulder height (pad - T1 or T6) / 2); the beam is flared along them and Kt times its "
        "stress there joins the peak stress. 0: sharp corners, whose stress the model does not "
        "bound: the peak-stress row is then NOT MET",
    )


class ConstantForceBoundary(BaseModel):
    """The ``boundary:`` block. S1 is clamped and S6 is driven along the work direction with its
    transverse motion held (the paper's set-up, not options); its rotation is an option."""

    model_config = STUDY_CONFIG

    stroke_mm: float = Field(30.0, gt=0, le=100, description="drive of S6 along the work direction")
    rows: int = Field(
        60,
        ge=2,
        le=2000,
        description="rows of the traced response (metrics interpolate between them)",
    )
    rotation: Literal["fixed", "free"] = Field(
        "fixed", description="rotation of S6: fixed (the slider is guided) or free"
    )


class ForceTarget(BaseModel):
    """The ``target:`` block: the force to hold and the stress not to pass."""

    model_config = STUDY_CONFIG

    force_N: float = Field(1.5, gt=0, description="force to hold, N")
    tolerance_percent: float = Field(
        2.0, gt=0, lt=100, description="band around force_N, percent of force_N"
    )
    samples: int = Field(
        10, ge=1, le=1000, description="r: strokes stroke_mm*i/r of the RMS objective (Eq. 8)"
    )
    allowable_stress_MPa: float | None = Field(
        None, gt=0, description="peak stress allowed, MPa (default: the material's yield)"
    )
    min_operative_stroke_mm: float = Field(
        0.0,
        ge=0,
        description="if > 0, a constraint: the operative stroke must be at least this long, mm",
    )


class PRBSpec(BaseModel):
    """The ``prb:`` block: re-synthesise the PRB slider-crank (paper Sec. 2) for a target."""

    model_config = STUDY_CONFIG

    target_force_N: float | None = Field(None, gt=0, description="default: target.force_N")
    stroke_mm: float | None = Field(None, gt=0, le=60, description="default: boundary.stroke_mm")
    x_in_mm: float = Field(100.0, gt=0, description="slider abscissa of the stretched state, mm")
    e_mm: float = Field(60.0, gt=0, description="eccentricity of the slider axis, mm")


class FidelitySpec(BaseModel):
    """The ``fidelity:`` block: the plane-stress check of the best design."""

    model_config = STUDY_CONFIG

    enabled: bool = Field(
        True,
        description="run the plane-stress check of the best design (and of flexopt evaluate's "
        "design); its peak stress is the one the verdict judges",
    )
    points: int = Field(
        4,
        ge=1,
        le=20,
        description="strokes compared over the operative window (the beam's peak-stress row "
        "is always one of them)",
    )
    max_edge_mm: float = Field(
        0.5, gt=0.05, le=5, description="triangle edge length of the plane-stress mesh, mm"
    )
    beam_stress_factor: float = Field(
        1.0,
        ge=1.0,
        le=2.0,
        description="the GA holds beam peak stress x this <= the allowable: the plane-stress / "
        "beam peak-stress ratio measured on this study's designs, so that the best design "
        "meets the allowable in plane stress too (the verdict re-checks it there)",
    )


class ConstantForceStudy(Study):
    """A whole ``constant_force`` study file."""

    geometry: ConstantForceGeometry = Field(description="kind: constant_force and its options")
    boundary: ConstantForceBoundary = Field(
        default_factory=ConstantForceBoundary, description="stroke_mm, rows, rotation"
    )
    target: ForceTarget = Field(
        default_factory=ForceTarget,
        description="force_N, tolerance_percent, samples, allowable_stress_MPa",
    )
    objective: Literal["rms_error", "operative_stroke"] = Field(
        "rms_error",
        description="rms_error: the paper's RMS(F - target) over the samples, stress checked "
        "over the whole stroke; operative_stroke: maximise the stroke held in the band",
    )
    design_space: dict[str, list[float]] = Field(
        default_factory=dict,
        description="bounds [lower, upper] by variable name (a1..a10, t1..t10, T1, T6, B); "
        "unlisted variables keep the paper's Table 3 bounds",
    )
    initial: Literal["table3", "design", "none"] = Field(
        "table3",
        description="seed the first population with the paper's Table 3 optimum, with the "
        "study's design, or not at all",
    )
    design: str | dict[str, float] = Field(
        "table3",
        description="the design flexopt evaluate analyses: table3, or values by variable name "
        "(unlisted ones from Table 3)",
    )
    optimiser: OptimiserSpec = Field(
        default_factory=lambda: OptimiserSpec(pop_size=40, n_gen=60, quick_pop_size=8),
        description="algorithm, pop_size, n_gen, seed, quick_pop_size, quick_n_gen",
    )
    prb: PRBSpec | None = Field(None, description="PRB synthesis reported beside the best design")
    fidelity: FidelitySpec = Field(
        default_factory=FidelitySpec, description="plane-stress check of the best design"
    )
    spec: ConstantForceSpec | None = Field(
        None,
        description="a user's {force_N, stroke_mm, envelope: {length_mm, height_mm}, "
        "width_max_mm}: sets the frame, target, stroke and design space, judged before the run "
        "(docs/constant_force.md, section 7)",
    )

    #: ``spec`` is left out of a dump when unset: studies without it dump as before it existed.
    OPTIONAL_BLOCKS: ClassVar[tuple[str, ...]] = (*Study.OPTIONAL_BLOCKS, "spec")

    @model_validator(mode="before")
    @classmethod
    def _spec_fills_the_study(cls, data: Any) -> Any:
        # The resolved study records what the spec set (frame scale, target, stroke, design
        # space, design, envelope requirement); conflicts are left for check() to refuse.
        return fill_from_spec(data, ConstantForceGeometry)

    @model_validator(mode="before")
    @classmethod
    def _allowable_defaults_to_yield(cls, data: Any) -> Any:
        # A resolved study carries the number it was run with, so the default is filled in here
        # (from the material's yield) rather than left as null. An unusable material is left for
        # the material validator to report.
        if not isinstance(data, dict):
            return data
        target = data.get("target", {})
        if target is None:
            target = {}
        if not isinstance(target, dict) or target.get("allowable_stress_MPa") is not None:
            return data
        yield_MPa = _yield_of(data.get("material"))
        if yield_MPa is None:
            return data
        return {**data, "target": {**target, "allowable_stress_MPa": yield_MPa}}

    @field_validator("design", mode="before")
    @classmethod
    def _design_is_table3_or_numbers(cls, value: Any) -> Any:
        # Checked by hand: pydantic would report a union mismatch at a path like
        # design.literal['table3'], which names no key of the file.
        if isinstance(value, str):
            if value != "table3":
                raise ValueError(
                    f"got '{value}'; use table3 or values by variable name, e.g. {{B: 5.5}}"
                )
            return value
        if not isinstance(value, dict):
            raise ValueError(f"got {value!r}; use table3 or a mapping {{variable: value}}")
        for name, v in value.items():
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ValueError(
                    f"{name}: got {v!r}; give a number (mm, or a fraction for a1..a10)"
                )
        return {str(k): float(v) for k, v in value.items()}

    @property
    def allowable_MPa(self) -> float:
        """The allowable stress, MPa (always set after validation)."""
        value = self.target.allowable_stress_MPa
        return float(value if value is not None else self.material.yield_MPa)


def _yield_of(material: Any) -> float | None:
    try:
        if isinstance(material, str):
            return float(get_material(material).yield_MPa)
        if isinstance(material, dict) and isinstance(material.get("yield_MPa"), int | float):
            return float(material["yield_MPa"])
    except Exception:  # an unknown name: reported by the material validator
        return None
    return None


# --------------------------------------------------------------------------------------------
# From the study to the optimiser's inputs


def _unknown_variable(name: str, path: str) -> StudyError:
    close = [n for n in DESIGN_VARIABLE_NAMES if n.lower() == name.lower()]
    close = close or difflib.get_close_matches(name, DESIGN_VARIABLE_NAMES, n=1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    return StudyError(
        f"{path}.{name}",
        f"unknown design variable '{name}'; {hint}use a1..a10, t1..t10, T1, T6 or B "
        "(names are case-sensitive: T1/T6 are the end thicknesses, t1..t10 the design points)",
    )


def design_space(study: ConstantForceStudy) -> DesignSpace:
    """The 23-variable design space: Table 3 bounds, overridden by ``design_space:``.

    Raises
    ------
    StudyError
        At ``design_space.<name>`` for an unknown name, swapped or equal bounds, a position
        fraction outside (0, 1), a non-positive length, or position ranges of one interval that
        overlap (a design in the overlap would fold back on itself).
    """
    lower = np.array(TABLE3_BOUNDS.lower, dtype=float)
    upper = np.array(TABLE3_BOUNDS.upper, dtype=float)
    for name, bounds in study.design_space.items():
        path = f"design_space.{name}"
        if name not in DESIGN_VARIABLE_NAMES:
            raise _unknown_variable(name, "design_space")
        if len(bounds) != 2:
            raise StudyError(
                path, f"got {list(bounds)}; give two bounds [lower, upper], e.g. [4.0, 12.0]"
            )
        lo, hi = bounds
        if lo > hi:
            raise StudyError(
                path,
                f"lower bound {lo:g} > upper bound {hi:g}; did you swap them? [{hi:g}, {lo:g}]",
            )
        if lo == hi:
            raise StudyError(
                path,
                f"equal bounds [{lo:g}, {hi:g}]; give a range, or fix the value with "
                "a narrow range such as "
                f"[{lo * 0.999:g}, {lo * 1.001:g}]",
            )
        if name in FRACTIONS and not (0 < lo and hi < 1):
            raise StudyError(
                path,
                f"[{lo:g}, {hi:g}] leaves (0, 1): {name} is the position of a design point as a "
                "fraction of its interval S_i -> S_i+1 (Eq. 13); keep both bounds inside (0, 1)",
            )
        if name not in FRACTIONS and not lo > 0:
            raise StudyError(path, f"lower bound {lo:g} must be > 0 mm (a thickness or width)")
        i = DESIGN_VARIABLE_NAMES.index(name)
        lower[i], upper[i] = lo, hi
    for k in range(5):  # a_{2k+1} < a_{2k+2} for every design: the two ranges must not overlap
        first, second = 2 * k, 2 * k + 1
        if upper[first] >= lower[second]:
            n1, n2 = DESIGN_VARIABLE_NAMES[first], DESIGN_VARIABLE_NAMES[second]
            raise StudyError(
                f"design_space.{n1 if n1 in study.design_space else n2}",
                f"{n1} may reach {upper[first]:g} but {n2} may go down to {lower[second]:g}: both "
                f"lie on S{k + 1}->S{k + 2} and {n1} must stay below {n2}, or the beam folds "
                f"back; make {n1}'s upper bound smaller than {n2}'s lower bound",
            )
    names = tuple(n if n in FRACTIONS else f"{n}_mm" for n in DESIGN_VARIABLE_NAMES)
    return DesignSpace(names, lower, upper)


def design_vector(study: ConstantForceStudy) -> np.ndarray:
    """(23,) the study's ``design:`` (Table 3 for ``table3``; unlisted names from Table 3).

    Raises
    ------
    StudyError
        At ``design.<name>`` for an unknown variable name.
    """
    x = design_to_vector(TABLE3_OPTIMUM)
    if isinstance(study.design, dict):
        for name, value in study.design.items():
            if name not in DESIGN_VARIABLE_NAMES:
                raise _unknown_variable(name, "design")
            x[DESIGN_VARIABLE_NAMES.index(name)] = value
    return x


def check(study: ConstantForceStudy) -> None:
    """Build the design space, the study's design and its beam once, so that every refusal is
    reported (with its key path) before any run folder exists."""
    check_spec(study)  # a user's spec the material cannot give: refused with the figure first
    space = design_space(study)
    x = design_vector(study)
    try:
        design = design_from_vector(x)
    except GeometryError as exc:
        raise StudyError("design", f"{exc}") from exc
    try:
        outline(
            design,
            pad_length_mm=study.geometry.pad_length_mm,
            pad_thickness_mm=study.geometry.pad_thickness_mm,
            end_flexures=study.geometry.end_flexures,
            pad_fillet_mm=study.geometry.pad_fillet_mm,
        )
    except GeometryError as exc:
        raise StudyError("geometry.pad_thickness_mm", str(exc)) from exc
    upper_t = space.upper[[DESIGN_VARIABLE_NAMES.index("T1"), DESIGN_VARIABLE_NAMES.index("T6")]]
    if study.geometry.pad_thickness_mm < upper_t.max():
        raise StudyError(
            "geometry.pad_thickness_mm",
            f"{study.geometry.pad_thickness_mm:g} mm is thinner than the beam ends may be "
            f"(T1/T6 up to {upper_t.max():g} mm); make the pads at least that thick",
        )
    if study.target.min_operative_stroke_mm > study.boundary.stroke_mm:
        raise StudyError(
            "target.min_operative_stroke_mm",
            f"{study.target.min_operative_stroke_mm:g} mm is longer than the drive "
            f"(boundary.stroke_mm = {study.boundary.stroke_mm:g}); lengthen the stroke or lower it",
        )
