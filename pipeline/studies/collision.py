"""Study kind ``collision``: head impact of a robot arm through a series spring (paper 000, Sec. 4).

``flexopt evaluate`` simulates the impact of Fig. 14 (:mod:`fea.collision`) once with the study's
spring and once with the constant-stiffness (CS) reference spring, then sweeps the rotor inertia
and the rotor torque (the paper's Figs. 16–17) for both. The response table is the nominal impact
over time for both springs; the sweeps go to ``evaluation.json`` (``inputs.sweeps``) and, through
:func:`extra_files` (figures of :mod:`pipeline.plots`), to ``sweeps.png``. An optional ``cam:``
block realises the threshold spring as the V2SOM cam behind an ideal reducer and checks it
against the impact (:func:`fea.collision.cam_impact_check`): whether the impact drives the cam
past its range, and the contact pressure at the largest cam torque.

YAML (SI in the impact block, as the paper; see docs/threshold_torque.md)::

    geometry: {kind: collision}
    spring: {kind: threshold, max_torque_Nm: 15, rate_per_rad: 37}
    reference: equal_deflection   # or e.g. {kind: linear, stiffness_Nm_per_rad: 276}
    impact: {rotor_inertia_kg_m2: 0.175, rotor_torque_Nm: 15, initial_spring: unloaded}
    sweeps: {rotor_inertia_kg_m2: [0.05, 0.1, 0.175, 0.3, 0.5], rotor_torque_Nm: [7.5, 15, 30]}
    cam: {ratio: 7.5, geometry: {...cam kind's geometry...}, springs: {...}}
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any, Literal

import numpy as np
from flexopt.fea.collision import (
    CollisionResponse,
    LinearSpring,
    TabulatedSpring,
    ThresholdSpring,
    cam_impact_check,
    equivalent_linear_spring,
    metrics_until,
    simulate_cases,
    sweep_record,
    sweep_result,
)
from flexopt.fea.contact import contact_pressure_MPa, onset_pressure_MPa
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import get_material
from flexopt.optimise.targets import (
    LinearTarget,
    TableTarget,
    TargetCurve,
    TargetSpec,
    ThresholdTarget,
)
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import EvaluationResult, StudyKind, _builtin, register
from flexopt.pipeline.studies._blocks import ImpactSpec
from flexopt.pipeline.studies._cam import (
    CamGeometry,
    CamStudyFields,
    SpringsSpec,
    build_cam,
)
from flexopt.pipeline.study import STUDY_CONFIG, MaterialSpec, Study, material_record
from flexopt.pipeline.targets import resolve_target
from pydantic import BaseModel, Field

__all__ = [
    "CollisionGeometry",
    "CollisionStudy",
    "ImpactSpec",
    "build_springs",
    "evaluate",
    "extra_files",
]


class CollisionGeometry(BaseModel):
    """The ``geometry:`` block (the impact's numbers are in ``impact:``)."""

    model_config = STUDY_CONFIG

    kind: Literal["collision"] = Field(description="collision")


class SweepSpec(BaseModel):
    """The ``sweeps:`` block: values of the rotor inertia and torque to sweep (Figs. 16–17)."""

    model_config = STUDY_CONFIG

    rotor_inertia_kg_m2: tuple[float, ...] = Field(
        (0.05, 0.1, 0.175, 0.3, 0.5, 1.0), description="kg m^2 (at impact.rotor_torque_Nm)"
    )
    rotor_torque_Nm: tuple[float, ...] = Field(
        (7.5, 11.25, 15.0, 22.5, 30.0), description="N m (at impact.rotor_inertia_kg_m2)"
    )


class CamCheckSpec(BaseModel):
    """The ``cam:`` block: the spring realised as a V2SOM cam behind an ideal reducer."""

    model_config = STUDY_CONFIG

    ratio: float = Field(
        gt=0, description="joint torque / cam torque = cam rotation / joint rotation"
    )
    geometry: CamGeometry = Field(description="the cam kind's geometry block (kind: cam)")
    springs: SpringsSpec = Field(description="the cam kind's springs block")
    friction: float = Field(0.0, ge=0, lt=1, description="μ of the follower guides")


def _default_material() -> MaterialSpec:
    return MaterialSpec(**material_record(get_material("PLA")))


class CollisionStudy(Study):
    """A whole ``collision`` study file."""

    geometry: CollisionGeometry = Field(description="kind: collision")
    material: MaterialSpec = Field(
        default_factory=_default_material, description="cam plate material (for cam:), PLA"
    )
    spring: TargetSpec = Field(
        default_factory=lambda: TargetSpec(kind="threshold", max_torque_Nm=15.0, rate_per_rad=37.0),
        description="the spring between rotor and arm (a torque target: threshold, linear, table)",
    )
    reference: Literal["equal_deflection"] | TargetSpec = Field(
        "equal_deflection",
        description="the CS spring: equal_deflection (same deflection at the split torque) or a "
        "linear torque target",
    )
    split: float = Field(
        0.8, gt=0, lt=1, description="fraction of the spring's top torque for equal_deflection"
    )
    impact: ImpactSpec = Field(default_factory=ImpactSpec, description="Fig. 14's parameters")
    sweeps: SweepSpec = Field(default_factory=SweepSpec, description="rotor inertia and torque")
    early_window_ms: float = Field(
        50.0,
        gt=0,
        description="also report HIC and force over the first this many ms (the first impact)",
    )
    cam: CamCheckSpec | None = Field(None, description="realise the spring as a cam and check it")


# --------------------------------------------------------------------------------------------
# Build


def _spring_of(curve: TargetCurve, key: str) -> Any:
    if curve.quantity != "torque":
        raise StudyError(
            key, "needs a torque-rotation spring (N·m keys, or table [rotation, torque])"
        )
    if isinstance(curve, ThresholdTarget):
        return ThresholdSpring(curve.max_value / 1000.0, curve.rate)
    if isinstance(curve, LinearTarget):
        if curve.preload != 0.0:
            raise StudyError(key, "a preloaded spring is not modelled; drop preload_Nm")
        return LinearSpring(curve.stiffness / 1000.0)
    if isinstance(curve, TableTarget):
        try:
            return TabulatedSpring(curve.x, curve.y / 1000.0)
        except FeaError as exc:
            raise StudyError(key, str(exc)) from exc
    raise StudyError(
        key, f"kind {type(curve).__name__} is not a spring; use threshold, linear or table"
    )


def build_springs(study: CollisionStudy) -> tuple[Any, LinearSpring, TargetCurve]:
    """The study's spring, its CS reference (N·m, rad) and the spring's target curve."""
    curve = resolve_target(study.spring, "spring")
    spring = _spring_of(curve, "spring")
    if study.reference == "equal_deflection":
        top = spring.sup_torque_Nm
        if not math.isfinite(top):
            raise StudyError(
                "reference",
                "equal_deflection needs a spring with a top torque (threshold or table); give "
                "reference: {kind: linear, stiffness_Nm_per_rad: ...}",
            )
        try:
            reference = equivalent_linear_spring(spring, study.split * top)
        except FeaError as exc:
            raise StudyError("reference", str(exc)) from exc
    else:
        ref_curve = resolve_target(study.reference, "reference")
        reference = _spring_of(ref_curve, "reference")
        if not isinstance(reference, LinearSpring):
            raise StudyError("reference", "the reference must be kind: linear (a CS spring)")
    return spring, reference, curve


def _cam_study(study: CollisionStudy, curve: TargetCurve) -> CamStudyFields:
    """The cam kind's study for the cam side of the reducer: ``T_γ(γ) = T(γ/N)/N``."""
    cam = study.cam
    assert cam is not None
    n = cam.ratio
    if isinstance(curve, ThresholdTarget):
        target = TargetSpec(
            kind="threshold",
            max_torque_Nm=curve.max_value / 1000.0 / n,
            rate_per_rad=curve.rate / n,
        )
    elif isinstance(curve, LinearTarget):
        target = TargetSpec(kind="linear", stiffness_Nm_per_rad=curve.stiffness / 1000.0 / n**2)
    else:
        raise StudyError("cam", "the cam check handles threshold and linear springs")
    return CamStudyFields(
        name=f"{study.name}-cam",
        geometry=cam.geometry,
        material=study.material,
        springs=cam.springs,
        friction=cam.friction,
        target=target,
    )


def check(study: CollisionStudy) -> None:
    """Build the springs (and the cam), and check the initial condition is possible."""
    spring, reference, curve = build_springs(study)
    model = study.impact.model()
    from flexopt.fea.collision import initial_deflection_rad

    for label, sp in (("spring", spring), ("reference", reference)):
        try:
            initial_deflection_rad(sp, model)
        except FeaError as exc:
            raise StudyError("impact.initial_spring", f"{label}: {exc}") from exc
    if study.cam is not None:
        build_cam(_cam_study(study, curve))


# --------------------------------------------------------------------------------------------
# Evaluate


def _series(r: CollisionResponse, prefix: str) -> dict[str, np.ndarray]:
    return {
        f"{prefix}head_acceleration_g": r.head_acceleration_m_per_s2 / 9.80665,
        f"{prefix}contact_force_N": r.contact_force_N,
        f"{prefix}deflection_deg": np.degrees(r.deflection_rad),
        f"{prefix}spring_torque_Nm": r.spring_torque_Nm,
    }


def _cam_check(
    study: CollisionStudy, curve: TargetCurve, response: CollisionResponse
) -> dict[str, Any]:
    cam = study.cam
    assert cam is not None
    _, _, profile, _ = build_cam(_cam_study(study, curve))
    pressure = contact_pressure_MPa(profile, study.material.E_MPa, study.material.nu)
    onset = onset_pressure_MPa(study.material.yield_MPa)
    return cam_impact_check(profile, cam.ratio, response.max_deflection_rad, pressure, onset)


def _range(values: list[float]) -> list[float | None]:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    return [min(finite), max(finite)] if finite else [None, None]


def evaluate(study: CollisionStudy, repeat: int = 1) -> EvaluationResult:
    """Nominal impact for both springs, then the inertia and torque sweeps."""
    spring, reference, curve = build_springs(study)
    model = study.impact.model()
    settings = study.impact.settings()
    # One integration per spring covers the nominal case and both sweeps (a batch costs about
    # what one case does): case 0 is nominal, then the inertia sweep, then the torque sweep.
    inertia_values = np.asarray(study.sweeps.rotor_inertia_kg_m2, dtype=float)
    torque_values = np.asarray(study.sweeps.rotor_torque_Nm, dtype=float)
    inertia = np.concatenate(
        [
            [model.rotor_inertia_kg_m2],
            inertia_values,
            np.full(torque_values.size, model.rotor_inertia_kg_m2),
        ]
    )
    torque = np.concatenate(
        [
            [model.rotor_torque_Nm],
            np.full(inertia_values.size, model.rotor_torque_Nm),
            torque_values,
        ]
    )
    early_s = study.early_window_ms / 1000.0
    times = []
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        runs = {
            label: simulate_cases(sp, model, inertia, torque, settings)
            for label, sp in (("spring", spring), ("reference", reference))
        }
        times.append(time.perf_counter() - t0)
    mine, ref = runs["spring"][0], runs["reference"][0]
    if mine is None or ref is None:  # check() refuses this; keep the message for API callers
        raise StudyError("impact.initial_spring", "the spring cannot carry the initial torque")
    sweeps = {}
    start = 1
    for parameter, values in (
        ("rotor_inertia_kg_m2", inertia_values),
        ("rotor_torque_Nm", torque_values),
    ):
        part = slice(start, start + values.size)
        start += values.size
        if values.size:
            part_runs = {k: v[part] for k, v in runs.items()}
            sweeps[parameter] = sweep_record(
                sweep_result(parameter, values, part_runs), part_runs, early_s
            )
    table = {"time_ms": mine.time_s * 1000.0}
    table.update(_series(mine, ""))
    table.update(_series(ref, "reference_"))
    table["converged"] = np.ones(mine.time_s.size, dtype=bool)
    summary: dict[str, Any] = {
        "hic15": mine.hic15,
        "reference_hic15": ref.hic15,
        "hic_reduction": 1.0 - mine.hic15 / ref.hic15,
        "peak_force_N": mine.peak_force_N,
        "reference_peak_force_N": ref.peak_force_N,
        "force_reduction": 1.0 - mine.peak_force_N / ref.peak_force_N,
        "peak_force_time_ms": mine.peak_force_time_s * 1000.0,
        "reference_peak_force_time_ms": ref.peak_force_time_s * 1000.0,
        "hic_window_ms": [1000.0 * t for t in mine.hic_window_s],
        "max_deflection_deg": math.degrees(mine.max_deflection_rad),
        "reference_max_deflection_deg": math.degrees(ref.max_deflection_rad),
        "initial_deflection_deg": math.degrees(mine.initial_deflection_rad),
        "reference_stiffness_Nm_per_rad": reference.stiffness_Nm_per_rad,
        "initial_spring": model.initial_spring,
    }
    early_mine = metrics_until(mine, early_s)
    early_ref = metrics_until(ref, early_s)
    summary.update(
        {
            "early_hic15": early_mine[0],
            "reference_early_hic15": early_ref[0],
            "early_hic_reduction": 1.0 - early_mine[0] / early_ref[0],
            "early_peak_force_N": early_mine[1],
            "reference_early_peak_force_N": early_ref[1],
            "early_force_reduction": 1.0 - early_mine[1] / early_ref[1],
            "reference_hic_window_ms": [1000.0 * t for t in ref.hic_window_s],
        }
    )
    for parameter, record in sweeps.items():
        short = "inertia_sweep" if parameter == "rotor_inertia_kg_m2" else "torque_sweep"
        for what in ("hic_reduction", "force_reduction"):
            lo, hi = _range(record[what])
            summary[f"{what}_min_{short}"] = lo
            summary[f"{what}_max_{short}"] = hi
    if isinstance(spring, TabulatedSpring):
        summary["beyond_table"] = mine.max_deflection_rad > spring.max_rotation_rad
    inputs: dict[str, Any] = {
        "sweeps": sweeps,
        "spring": repr(spring),
        "reference": repr(reference),
    }
    if study.cam is not None:
        check = _cam_check(study, curve, mine)
        inputs["cam_check"] = check
        summary["cam_range_exceeded"] = check["range_exceeded"]
        summary["cam_contact_pressure_MPa"] = check["max_contact_pressure_MPa"]
        summary["stress_yield_ratio"] = check["stress_yield_ratio"]
    return EvaluationResult(
        table=table,
        summary=summary,
        converged=True,
        message="",
        solve_times_s=tuple(times),
        inputs=inputs,
        diagnostics={"dt_s": settings.dt_s, "samples": int(mine.time_s.size)},
        plot={"x": "time_ms", "y": "contact_force_N", "stress": "head_acceleration_g"},
        headline=(
            "hic15",
            "reference_hic15",
            "hic_reduction",
            "peak_force_N",
            "reference_peak_force_N",
            "force_reduction",
            "early_hic_reduction",
            "early_force_reduction",
            "max_deflection_deg",
            "hic_reduction_min_inertia_sweep",
            "hic_reduction_max_inertia_sweep",
            "force_reduction_min_inertia_sweep",
            "force_reduction_max_inertia_sweep",
            "hic_reduction_min_torque_sweep",
            "hic_reduction_max_torque_sweep",
            "force_reduction_min_torque_sweep",
            "force_reduction_max_torque_sweep",
            "cam_range_exceeded",
            "stress_yield_ratio",
        ),
    )


def extra_files(study: CollisionStudy, result: EvaluationResult) -> dict[str, bytes]:
    """Files beyond the standard run folder: ``sweeps.png`` (Figs. 16–17) and ``impact.png``
    (both springs over time). For a pipeline hook that writes kind-specific files."""
    from flexopt.pipeline.plots import collision_impact_png, collision_sweeps_png

    files = {}
    sweeps = result.inputs.get("sweeps", {})
    if sweeps:
        title = f"{study.name}: spring vs constant stiffness ({study.impact.initial_spring})"
        files["sweeps.png"] = collision_sweeps_png(title, sweeps)
    files["impact.png"] = collision_impact_png(result.table)
    return files


def evaluate_with_files(study: CollisionStudy, repeat: int = 1) -> EvaluationResult:
    """:func:`evaluate`, with :func:`extra_files` for ``flexopt evaluate`` to write."""
    result = evaluate(study, repeat)
    return dataclasses.replace(result, files={**result.files, **extra_files(study, result)})


register(
    StudyKind(
        "collision",
        CollisionStudy,
        check,
        evaluate_with_files,
        requirements=_builtin.collision,
        quantities=_builtin.COLLISION,
    )
)  # type: ignore[arg-type]
