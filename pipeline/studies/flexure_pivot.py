"""Study kind ``flexure_pivot``: choose a flexure pivot type and its dimensions for a target
rotational stiffness, range of motion, material and envelope (see docs/flexures.md).

YAML (units in the key names)::

    geometry: {kind: flexure_pivot, candidates: [leaf, circular_notch, ...], width_mm: 6,
               block_length_mm: 5, min_feature_mm: 0.8, max_length_mm: 40, max_height_mm: 20}
    material: PETG
    target: {stiffness_Nmm_per_rad: 300, tolerance_percent: 5, range_of_motion_deg: 15,
             allowable_stress_MPa: 50, max_centre_shift_mm: null}
    design_space: {length_mm: [2, 30], thickness_mm: [0.8, 3], shape: [0, 1]}
    fidelity: {plane_stress: true, steps: 3}
    optimiser: {pop_size: 40, n_gen: 25}
    design: {type: leaf, length_mm: 12, thickness_mm: 1.2}      # what `flexopt evaluate` traces

The pivot type is a categorical design variable (``type_index``, floored into ``candidates``), so
one GA compares the types; the other three are the compliant length (``length_mm``), the thinnest
section (``thickness_mm``) and a type-specific ``shape`` in [0, 1], whose meaning per type is the
table of :func:`fea.flexure_design.flexure_of_type` (and of docs/flexures.md).

Each design is loaded the way rotational stiffness is defined: a pure moment on the moving block
(the stiffness target is the small-angle stiffness M / theta). The objective is the stress ratio
sigma_peak / sigma_allowable at the full range of motion (its inverse is the safety factor, which
the GA thus maximises); constraints keep the stiffness in its band, the stress allowable, the part
inside the envelope and, optionally, the centre shift small. Leaves and the cross-axis pivot are
solved with the large-deflection beam model in the GA (40 ms); notch hinges by their closed forms
(Paros–Weisbord, Lobontiu) with the stress concentration estimate, and the best design is checked
by plane stress in ``detail``.
"""

from __future__ import annotations

import math
import time
from typing import Any, ClassVar, Literal

import flexopt.pipeline.studies._pivot_band as pivot_band
import flexopt.pipeline.studies._pivot_roots as pivot_roots
import flexopt.pipeline.studies._pivot_stops as pivot_stops
import numpy as np
from flexopt.fea.beam_fields import members_field
from flexopt.fea.closed_forms import pivot_closed_form
from flexopt.fea.flexure_design import (
    BEAM_TYPES,
    PIVOT_TYPES,
    closed_form_seed,
    flexure_of_type,
    pivot_at_range,
    pivot_table,
)
from flexopt.fea.materials import Material, material_yield_MPa
from flexopt.fea.pivot import PivotResponse, beam_pivot
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.flexures import Flexure
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.joint_objectives import (
    PivotLimits,
    pivot_objective,
    pivot_plane_stress_figures,
)
from flexopt.optimise.problem import DesignDetail, DesignProblem, DesignResult
from flexopt.optimise.requirements import BEAM, PLANE_STRESS, Figure
from flexopt.optimise.space import DesignSpace
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.fields import pivot_plane_stress
from flexopt.pipeline.stroke_verdict import UNBOUNDED_STRESS
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.studies._pivot_schema import PivotDesign, PivotFidelity, PivotType
from flexopt.pipeline.studies._stops import StopsSpec
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study, material_record
from flexopt.pipeline.verdict import envelope_values
from pydantic import BaseModel, Field, model_validator

__all__ = [
    "PIVOT_TYPES",
    "BEAM_TYPES",
    "VARIABLES",
    "FlexurePivotGeometry",
    "PivotTarget",
    "PivotDesignSpace",
    "PivotFidelity",
    "PivotDesign",
    "FlexurePivotStudy",
    "FlexurePivotProblem",
    "build_flexure",
    "design_space",
    "check",
    "problem",
]

VARIABLES = ("type_index", "length_mm", "thickness_mm", "shape")


# --------------------------------------------------------------------------------------------
# The study file


class FlexurePivotGeometry(BaseModel):
    """The ``geometry:`` block: candidate types, the fixed dimensions and the envelope (mm)."""

    model_config = STUDY_CONFIG

    kind: Literal["flexure_pivot"] = Field(description="flexure_pivot")
    candidates: tuple[PivotType, ...] = Field(
        PIVOT_TYPES, min_length=1, description="pivot types the optimiser may choose"
    )
    width_mm: float = Field(6.0, gt=0, description="out-of-plane width (print height), mm")
    block_length_mm: float = Field(5.0, gt=0, description="length of each clamping block, mm")
    block_height_mm: float | None = Field(
        None, gt=0, description="height of the leaf types' blocks, mm (default max(3, 3 t))"
    )
    min_feature_mm: float = Field(0.8, gt=0, description="thinnest printable section, mm")
    max_length_mm: float = Field(40.0, gt=0, description="envelope: overall length, mm")
    max_height_mm: float = Field(20.0, gt=0, description="envelope: overall height, mm")
    elements: int = Field(40, ge=4, le=2000, description="beam elements per member")
    leaf_root_fillet_mm: float = Field(1.0, ge=0, le=10, description=pivot_roots.FILLET_KEY)

    @model_validator(mode="after")
    def _unique_candidates(self) -> FlexurePivotGeometry:
        seen = [c for i, c in enumerate(self.candidates) if c in self.candidates[:i]]
        if seen:
            raise ValueError(f"candidates lists '{seen[0]}' twice; give each type once")
        return self


class PivotTarget(BaseModel):
    """The ``target:`` block: stiffness band, range of motion, stress and centre limits."""

    model_config = STUDY_CONFIG

    stiffness_Nmm_per_rad: float | None = Field(
        None, gt=0, description="target small-angle stiffness M/theta, N·mm/rad"
    )
    stiffness_Nm_per_rad: float | None = Field(
        None, gt=0, description="the same in N·m/rad (give one of the two)"
    )
    tolerance_percent: float = Field(5.0, gt=0, lt=100, description="stiffness band, percent")
    range_of_motion_deg: float = Field(
        15.0, gt=0, le=90, description="rotation at which the stress is checked, deg"
    )
    allowable_stress_MPa: float | None = Field(
        None, gt=0, description="allowable stress, MPa (default: the material's yield)"
    )
    max_centre_shift_mm: float | None = Field(
        None, gt=0, description="if set, a constraint on the centre shift at full range, mm"
    )

    @model_validator(mode="after")
    def _one_stiffness(self) -> PivotTarget:
        given = [k for k in ("stiffness_Nmm_per_rad", "stiffness_Nm_per_rad") if getattr(self, k)]
        if len(given) != 1:
            raise ValueError(
                "give exactly one of stiffness_Nmm_per_rad or stiffness_Nm_per_rad "
                f"(got {', '.join(given) or 'neither'})"
            )
        return self

    @property
    def stiffness_Nmm(self) -> float:
        """Target stiffness, N·mm/rad."""
        if self.stiffness_Nmm_per_rad is not None:
            return float(self.stiffness_Nmm_per_rad)
        return 1000.0 * float(self.stiffness_Nm_per_rad)  # type: ignore[arg-type]


class PivotDesignSpace(BaseModel):
    """The ``design_space:`` block: bounds of the shared variables (see the module docstring)."""

    model_config = STUDY_CONFIG

    length_mm: tuple[float, float] | None = Field(
        None, description="[lower, upper] compliant length, mm (default [2, envelope])"
    )
    thickness_mm: tuple[float, float] | None = Field(
        None, description="[lower, upper] thinnest section, mm (default [min_feature, 4x])"
    )
    shape: tuple[float, float] = Field((0.0, 1.0), description="[lower, upper] in [0, 1]")


class FlexurePivotStudy(Study):
    """A whole ``flexure_pivot`` study file."""

    geometry: FlexurePivotGeometry = Field(description="kind: flexure_pivot and its options")
    target: PivotTarget = Field(description="stiffness_Nmm_per_rad, range_of_motion_deg, ...")
    design_space: PivotDesignSpace = Field(
        default_factory=PivotDesignSpace, description="length_mm, thickness_mm, shape bounds"
    )
    fidelity: PivotFidelity = Field(
        default_factory=PivotFidelity, description="report checks: steps, plane_stress, ..."
    )
    optimiser: OptimiserSpec = Field(
        default_factory=lambda: OptimiserSpec(pop_size=40, n_gen=25, quick_pop_size=12),
        description="algorithm, pop_size, n_gen, seed, quick_pop_size, quick_n_gen",
    )
    design: PivotDesign | None = Field(
        None, description="the design flexopt evaluate traces (default: the best closed-form seed)"
    )
    stops: StopsSpec | None = pivot_stops.FIELD  # rigid stops (pipeline/studies/_pivot_stops.py)
    # a study without stops dumps as it did before the block existed (Study's serializer)
    OPTIONAL_BLOCKS: ClassVar[tuple[str, ...]] = (*Study.OPTIONAL_BLOCKS, "stops")

    @model_validator(mode="before")
    @classmethod
    def _allowable_defaults_to_yield(cls, data: Any) -> Any:
        # The resolved study carries the allowable it was run with, not null.
        if not isinstance(data, dict):
            return data
        target = data.get("target")
        if not isinstance(target, dict) or target.get("allowable_stress_MPa") is not None:
            return data
        yield_MPa = material_yield_MPa(data.get("material"))
        if yield_MPa is None:
            return data
        return {**data, "target": {**target, "allowable_stress_MPa": yield_MPa}}

    @property
    def allowable_MPa(self) -> float:
        value = self.target.allowable_stress_MPa
        return float(value if value is not None else self.material.yield_MPa)


# --------------------------------------------------------------------------------------------
# From a design vector to a flexure


def build_flexure(
    kind: str, length: float, thickness: float, shape: float, geometry: FlexurePivotGeometry
) -> Flexure:
    """The flexure of type ``kind`` for the shared variables (see the module docstring and
    :func:`fea.flexure_design.flexure_of_type`).

    Raises
    ------
    GeometryError
        When the generator refuses the dimensions.
    """
    g = geometry
    return flexure_of_type(
        kind, length, thickness, shape, g.width_mm, g.block_length_mm, g.block_height_mm,
        g.leaf_root_fillet_mm,
    )  # fmt: skip


def design_space(study: FlexurePivotStudy) -> DesignSpace:
    """(type_index, length_mm, thickness_mm, shape) with the study's bounds.

    Raises
    ------
    StudyError
        At ``design_space.<name>`` for swapped or equal bounds, a thickness below the printable
        minimum, or a shape outside [0, 1].
    """
    g, ds = study.geometry, study.design_space
    length = ds.length_mm or (2.0, max(g.max_length_mm - 2.0 * g.block_length_mm, 3.0))
    thickness = ds.thickness_mm or (g.min_feature_mm, 4.0 * g.min_feature_mm)
    for name, (lo, hi) in (("length_mm", length), ("thickness_mm", thickness), ("shape", ds.shape)):
        path = f"design_space.{name}"
        if lo > hi:
            raise StudyError(
                path, f"lower bound {lo:g} > upper {hi:g}; swap them: [{hi:g}, {lo:g}]"
            )
        if lo == hi:
            raise StudyError(path, f"equal bounds [{lo:g}, {hi:g}]; give a range")
        if name != "shape" and not lo > 0:
            raise StudyError(path, f"lower bound {lo:g} must be > 0 mm")
    if thickness[0] < g.min_feature_mm:
        raise StudyError(
            "design_space.thickness_mm",
            f"lower bound {thickness[0]:g} mm is thinner than geometry.min_feature_mm = "
            f"{g.min_feature_mm:g}; raise it to at least {g.min_feature_mm:g}",
        )
    if not (0.0 <= ds.shape[0] and ds.shape[1] <= 1.0):
        raise StudyError("design_space.shape", f"{list(ds.shape)} must lie within [0, 1]")
    n = len(g.candidates)
    return DesignSpace(
        VARIABLES,
        np.array([0.0, length[0], thickness[0], ds.shape[0]]),
        np.array([float(n), length[1], thickness[1], ds.shape[1]]),
    )


def type_of(study: FlexurePivotStudy, index: float) -> str:
    """The candidate type a (continuous) type_index falls in."""
    n = len(study.geometry.candidates)
    return study.geometry.candidates[min(max(int(math.floor(index)), 0), n - 1)]


def check(study: FlexurePivotStudy) -> None:
    """Build the design space, the material and the study's design once, so every refusal names
    its key path before a run folder exists."""
    design_space(study)
    material, f = study.material.to_material(), None
    if study.design is not None:
        d = study.design
        if d.type not in study.geometry.candidates:
            raise StudyError(
                "design.type",
                f"'{d.type}' is not among geometry.candidates "
                f"({', '.join(study.geometry.candidates)}); add it there",
            )
        try:
            f = build_flexure(d.type, d.length_mm, d.thickness_mm, d.shape, study.geometry)
            f.outline()
        except GeometryError as exc:
            raise StudyError("design", str(exc)) from exc
        if d.thickness_mm < study.geometry.min_feature_mm:
            raise StudyError(
                "design.thickness_mm",
                f"{d.thickness_mm:g} mm is thinner than geometry.min_feature_mm = "
                f"{study.geometry.min_feature_mm:g}",
            )
    pivot_stops.check(study, f)  # with stops: no notch candidates, clear of the design
    if not material.E_MPa > 0:  # pragma: no cover - the material model guarantees it
        raise StudyError("material.E_MPa", "must be > 0")


# --------------------------------------------------------------------------------------------
# The design problem


class FlexurePivotProblem(DesignProblem):
    """The :class:`optimise.DesignProblem` of a ``flexure_pivot`` study (picklable)."""

    objective_names = ("stress_ratio",)

    def warm_up(self) -> None:
        """Load the compiled beam and constrained-beam kernels (a pool calls this before it
        forks its workers, :func:`pipeline.backends.open_backend`)."""
        from flexopt.fea.constrained_beams import warm_up

        warm_up()

    def __init__(self, study: FlexurePivotStudy) -> None:
        self.study = study
        self.space = design_space(study)
        self.material: Material = study.material.to_material()
        self.allowable_MPa = study.allowable_MPa
        self.target_Nmm = study.target.stiffness_Nmm
        self.tolerance = study.target.tolerance_percent / 100.0
        self.rom_rad = math.radians(study.target.range_of_motion_deg)
        g = study.geometry
        self.limits = PivotLimits(
            self.target_Nmm,
            self.tolerance,
            self.allowable_MPa,
            g.max_length_mm,
            g.max_height_mm,
            study.target.max_centre_shift_mm,
        )
        self.constraint_names = self.limits.constraint_names

    # -- helpers -------------------------------------------------------------------------------

    def flexure(self, x: np.ndarray) -> tuple[str, Flexure]:
        """(type, flexure) of a design vector (4,)."""
        x = np.asarray(x, dtype=float)
        kind = type_of(self.study, x[0])
        return kind, build_flexure(kind, x[1], x[2], x[3], self.study.geometry)

    def _beam(self, flexure: Flexure, steps: int) -> PivotResponse:
        n, stops = self.study.geometry.elements, pivot_stops.solve_args(self.study)
        return beam_pivot(flexure, self.material, self.rom_rad, steps, n_elements=n, **stops)

    def _fail(self, x: np.ndarray, reason: str, t0: float) -> Evaluation:
        return Evaluation.failed(x, 1, len(self.constraint_names), reason, time.perf_counter() - t0)

    # -- protocol ------------------------------------------------------------------------------

    def evaluate(self, x: np.ndarray) -> Evaluation:
        t0 = time.perf_counter()
        x = np.asarray(x, dtype=float)
        try:
            kind, flex = self.flexure(x)
            length, height = flex.envelope_mm()
        except GeometryError as exc:
            return self._fail(x, f"cannot build: {exc}", t0)
        study = self.study
        if why := pivot_stops.overlap(study, flex):  # a stop across a member: no such pivot
            return self._fail(x, why, t0)
        at = pivot_at_range(
            flex,
            self.material,
            self.rom_rad,
            study.fidelity.ga_steps,
            study.geometry.elements,
            kind in BEAM_TYPES,
            study.target.max_centre_shift_mm is not None,
            **pivot_stops.solve_args(study),
        )
        if at.failure:
            return self._fail(x, at.failure, t0)
        K, sigma, shift = at.stiffness_Nmm_per_rad, at.stress_MPa, at.centre_shift_mm
        K_band, extra = pivot_band.band_stiffness(self, flex, K)  # the verdict's figure
        ratio, g = pivot_objective(self.limits, K_band, sigma, (length, height), shift)
        g = pivot_roots.ga_stress_row(kind, study, g, 1)  # an unbounded stress: infeasible
        metrics = {
            "type": kind,
            "model": at.model,
            "stiffness_Nmm_per_rad": K,
            "closed_form_stiffness_Nmm_per_rad": at.closed_form.stiffness_Nmm_per_rad,
            "peak_stress_MPa": sigma,
            "safety_factor": 1.0 / ratio if ratio > 0 else float("inf"),
            "centre_shift_mm": shift,
            "envelope_length_mm": length,
            "envelope_height_mm": height,
            **extra,
        }
        return Evaluation(x, np.array([ratio]), g, metrics, "", time.perf_counter() - t0)

    def nominal_design(self) -> np.ndarray:
        """(4,) the study's ``design:`` (or its closed-form seed): what ``flexopt evaluate``
        solves, so ``flexopt export`` of an evaluate folder rebuilds it."""
        return design_vector(self.study, self)

    def initial_designs(self) -> np.ndarray | None:
        """One closed-form design per candidate type that meets the target stiffness (the
        thickness and shape on a small grid, the length solved from the closed form), the one
        with the largest closed-form safety factor inside the envelope; types that cannot meet
        the target inside the bounds are left out."""
        seeds = []
        for i, kind in enumerate(self.study.geometry.candidates):
            best = self._closed_form_seed(kind)
            if best is not None:
                seeds.append([i + 0.5, *best])
        return np.array(seeds) if seeds else None

    def _closed_form_seed(self, kind: str) -> list[float] | None:
        g = self.study.geometry
        return closed_form_seed(
            lambda length, t, s: build_flexure(kind, length, t, s, g),
            self.material.E_MPa,
            self.target_Nmm,
            self.allowable_MPa,
            self.rom_rad,
            self.space.lower,
            self.space.upper,
            g.max_length_mm,
            g.max_height_mm,
        )

    def detail(self, x: np.ndarray) -> DesignDetail:
        evaluation = self.evaluate(x)
        study = self.study
        kind, flex = self.flexure(x)
        cf = pivot_closed_form(flex, self.material.E_MPa)
        steps = study.fidelity.steps
        res = self._beam(flex, steps)
        table = {**pivot_table(res, cf), **pivot_stops.columns(study, res)}
        info: dict[str, Any] = {
            "type": kind,
            "parameters": {k: v for k, v in flex.params().items() if v is not None},
            "design_vector": {n: float(v) for n, v in zip(VARIABLES, x, strict=True)},
            "target_stiffness_Nmm_per_rad": self.target_Nmm,
            "allowable_stress_MPa": self.allowable_MPa,
            "range_of_motion_deg": study.target.range_of_motion_deg,
            "stiffness_Nmm_per_rad": {
                "beam_small_angle": res.small_angle_stiffness_Nmm_per_rad,
                "beam_secant_at_range": float(res.torque_Nmm[-1] / res.rotation_rad[-1])
                if res.ok
                else None,
                "closed_form": cf.stiffness_Nmm_per_rad,
                **{f"closed_form_{k}": v for k, v in cf.alternatives.items()},
            },
            "closed_form": {
                "formula": cf.formula,
                "reference": cf.reference,
                "stress_concentration": cf.stress_concentration,
            },
            "stress_at_range_MPa": {
                "beam_times_Kt": float(np.nanmax(table["peak_stress_MPa"])),
                "closed_form": float(cf.stress_MPa(self.rom_rad)),
            },
            "safety_factor": evaluation.metrics.get("safety_factor"),
            "centre_shift_at_range_mm": float(res.centre_shift_mm[-1]) if res.ok else None,
            "envelope_mm": list(flex.envelope_mm()),
            "beam": {"ok": res.ok, "message": res.message, **res.extra},
        }
        if study.stops is not None:  # first contact, forces, penetration (_pivot_stops)
            info["contact"] = pivot_stops.summary(study, res)
        notes, field_map = [], None
        outline = flex.outline()
        if flex.is_planar:
            try:
                from flexopt.geometry.solid import min_feature_mm

                info["outline_min_feature_mm"] = min_feature_mm(outline)
            except (GeometryError, ValueError) as exc:  # pragma: no cover - defensive
                notes.append(f"min feature check failed: {exc}")
            if study.fidelity.plane_stress and study.stops is not None:
                notes.append(pivot_stops.PLANE_STRESS_NOTE)  # that solve has no contact
            elif study.fidelity.plane_stress:  # the record, its figures and its field
                field_map = pivot_plane_stress(info, self, flex, cf, res)
        else:
            notes.append(
                "cross_axis: the leaves of a cross-axis pivot pass each other in separate layers, "
                "so one extrusion of the planar outline (which joins them at the crossing) is not "
                "this pivot; no STL is written and no plane-stress check is made"
            )
        if kind not in BEAM_TYPES:
            notes.append(
                "notch hinge: the GA used the closed form; the table is the equivalent "
                "variable-thickness beam (its stress times K_t), the plane-stress check is the "
                "reference"
            )
        if notes:
            info["notes"] = notes
        plot = {
            "x": "rotation_deg",
            "y": "stiffness_Nmm_per_rad",
            "stress": "peak_stress_MPa",
            "target": self.target_Nmm,
            "tolerance": self.target_Nmm * self.tolerance,
            "allowable_MPa": self.allowable_MPa,
            "x_label": "rotation of the moving block (deg)",
            "y_label": "tangent stiffness dM/dtheta (N·mm/rad)",
        }
        return DesignDetail(
            evaluation=evaluation,
            table=table,
            plot=plot,
            shapes_mm=res.shapes_mm,
            outline=outline if flex.is_planar else None,
            height_mm=flex.width_mm if flex.is_planar else None,
            info=info,
            field_map=field_map,  # stress_deformed.png, report.html's stress view, best.vtu
            beam_field=members_field(res.members, stress_factor=cf.stress_concentration),
        )

    def result(self, x: np.ndarray, repeat: int = 1) -> DesignResult:
        """``flexopt evaluate``: the design ``x`` (4,) (the study's design or the best closed-form
        seed: :meth:`nominal_design`) turned to its range of motion by the beam model, with the
        closed forms beside it."""
        prob = self
        x = np.asarray(x, dtype=float)
        times = []
        detail = None
        for _ in range(max(1, repeat)):
            t0 = time.perf_counter()
            detail = prob.detail(x)
            times.append(time.perf_counter() - t0)
        assert detail is not None
        ev = detail.evaluation
        table = dict(detail.table)
        summary: dict[str, Any] = {
            "type": detail.info["type"],
            UNBOUNDED_STRESS: pivot_roots.sharp(detail.info["type"], prob.study),  # _pivot_roots
            pivot_roots.NO_PART: pivot_roots.no_part(detail.info["type"]),  # cross_axis
            "small_angle_stiffness_Nmm_per_rad": detail.info["stiffness_Nmm_per_rad"][
                "beam_small_angle"
            ],
            "closed_form_stiffness_Nmm_per_rad": detail.info["stiffness_Nmm_per_rad"][
                "closed_form"
            ],
            "target_stiffness_Nmm_per_rad": prob.target_Nmm,
            "peak_stress_MPa": ev.metrics.get("peak_stress_MPa"),
            "stress_yield_ratio": float(ev.metrics.get("peak_stress_MPa", np.nan))
            / prob.material.yield_MPa,
            "safety_factor": ev.metrics.get("safety_factor"),
            "centre_shift_at_range_mm": detail.info["centre_shift_at_range_mm"],
            "feasible": ev.feasible,
            "stable": bool(np.all(table["stable"][table["converged"]])),
        }
        for key in ("stiffness_Nmm_per_rad", "centre_shift_mm", "envelope_length_mm",
                    "envelope_height_mm"):  # fmt: skip
            summary.setdefault(key, ev.metrics.get(key))  # the names flexopt run judges too
        summary.update(detail.info.get("contact", {}))  # with stops: first contact, forces ...
        # the part as exported (its planar outline extruded), as flexopt run measures it
        summary.update(envelope_values(detail.outline, detail.height_mm))
        ps = detail.info.get("plane_stress")
        if isinstance(ps, dict) and "linear_stiffness_Nmm_per_rad" in ps:
            summary["plane_stress_stiffness_Nmm_per_rad"] = ps["linear_stiffness_Nmm_per_rad"]
            summary["plane_stress_safety_factor"] = ps.get("safety_factor")
            summary.update(pivot_plane_stress_figures(ps))
        converged = bool(np.all(table["converged"]))
        return DesignResult(
            table=table,
            summary=summary,
            converged=converged,
            message=detail.info["beam"]["message"],
            solve_times_s=tuple(times),
            inputs={
                "material": material_record(prob.material),
                "design": {n: float(v) for n, v in zip(VARIABLES, x, strict=True)},
                "flexure": detail.info["parameters"],
                "closed_form": detail.info["closed_form"],
            },
            diagnostics=dict(detail.info["beam"]),
            field_map=detail.field_map,  # its plane-stress field (stress_deformed.png, VTU)
            **{"shapes_mm": detail.shapes_mm, "beam_field": detail.beam_field},  # design.vtu
            plot={
                "x": "rotation_deg",
                "y": "torque_Nmm",
                "stress": "peak_stress_MPa",
                "allowable_MPa": prob.allowable_MPa,
                # the target stiffness as a torque line K theta, with the stiffness band
                "target_curve": {
                    "x": table["rotation_deg"],
                    "y": prob.target_Nmm * np.radians(table["rotation_deg"]),
                },
                "tolerance_rel": prob.tolerance,
                "target_label": f"target K θ, K = {prob.target_Nmm:g} N·mm/rad",
            },
            headline=(
                "type",
                "small_angle_stiffness_Nmm_per_rad",
                "closed_form_stiffness_Nmm_per_rad",
                "plane_stress_stiffness_Nmm_per_rad",
                "peak_stress_MPa",
                "safety_factor",
                "centre_shift_at_range_mm",
                *pivot_stops.headline(prob.study),
            ),
        )


#: The figures of a quantity by model (pipeline.verdict): the stiffness band and the allowable
#: stress are judged on the plane-stress check's figures where the run made one.
FIGURES = {
    "stiffness_Nmm_per_rad": (
        Figure("stiffness_Nmm_per_rad", "beam or closed form", BEAM),
        Figure("plane_stress_stiffness_Nmm_per_rad", "plane stress", PLANE_STRESS),
    ),
    "peak_stress_MPa": (
        Figure("peak_stress_MPa", "beam or closed form", BEAM),
        Figure("plane_stress_peak_stress_MPa", "plane stress", PLANE_STRESS),
    ),
}


# --------------------------------------------------------------------------------------------
# Registry hooks


def problem(study: FlexurePivotStudy) -> FlexurePivotProblem:
    """The design problem ``flexopt run`` optimises."""
    return FlexurePivotProblem(study)


def design_vector(study: FlexurePivotStudy, prob: FlexurePivotProblem) -> np.ndarray:
    """(4,) the study's ``design:``, or the closed-form seed of the first candidate that has one.

    Raises
    ------
    StudyError
        At ``design`` when there is no design and no candidate meets the target in the bounds.
    """
    if study.design is not None:
        _, x = design_of(study)
        if x is None:
            raise StudyError(
                "design.type",
                f"'{study.design.type}' is not among geometry.candidates "
                f"({', '.join(study.geometry.candidates)}); add it",
            )
        return x
    seeds = prob.initial_designs()
    if seeds is None:
        raise StudyError(
            "design",
            "no design given, and no candidate meets target.stiffness within design_space by its "
            "closed form; give a design: {type, length_mm, thickness_mm} or widen the bounds",
        )
    ratios = [prob.evaluate(s).f[0] for s in seeds]
    return seeds[int(np.argmin(ratios))]


def design_of(study: FlexurePivotStudy) -> tuple[DesignSpace, np.ndarray | None]:
    """The design space and the study's ``design:`` in it (None without one: evaluate then
    takes a closed-form seed, inside the space), for the verdict's design-range row."""
    space = design_space(study)
    d, cands = study.design, study.geometry.candidates
    if d is None or d.type not in cands:
        return space, None
    return space, np.array([cands.index(d.type) + 0.5, d.length_mm, d.thickness_mm, d.shape])


register(
    StudyKind(
        "flexure_pivot",
        FlexurePivotStudy,
        check,  # type: ignore[arg-type]
        None,  # flexopt evaluate: the nominal design's FlexurePivotProblem.result
        problem,  # type: ignore[arg-type],
        requirements=pivot_stops.requirements,
        quantities=pivot_stops.quantities,
        figures=FIGURES,
        design_space=design_of,
        # beams and the plane-stress check: every torque (and the closed forms) scale with it
        width_key="geometry.width_mm",
    )
)
