"""Study kind ``sea_window``: the SEA stiffness window of paper 004, section 4 (evaluate only).

The upper bound of the spring stiffness comes from a collision of the actuator output with a
rigid wall while the motor keeps driving (Eqs. 9–16: the peak spring or gearbox torque must stay
under the gearbox's momentary limit); the lower bound from the torque bandwidth of the
locked-output model (Eqs. 17–25: the motor at its saturation torque must still give the required
torque at the required frequency). :mod:`fea.sea_window` does the numerics; this kind sweeps the
stiffness, writes the table and two figures — the peak torques against K (the paper's Figs. 8–9,
``peak_torque.png``) and the Bode magnitude of the torque transfer for K_min, the checked K and
K_max (Fig. 11, ``bode.png``) — and reports whether a given spring stiffness lies in the window.
The same window feeds the spring study's target (``sea_spring``'s ``stiffness_window:`` block).

YAML (SI, as the data sheets; the drive defaults are the paper's Tables 3–4)::

    geometry: {kind: sea_window}
    required_torque_Nm: 53
    required_bandwidth_Hz: 4
    impact_speed_rpm: 46.86            # knee's largest walking speed
    impact_spring_torque_Nm: 0
    criterion: spring                  # or gearbox (peak torque on the gearbox, stricter)
    stiffness_Nm_per_rad: 275          # the spring to check
    sweep_Nm_per_rad: [25, 1000]
    motor: {rotor_inertia_kg_m2: 3.17e-4}    # overrides of fea.sea_window.Motor
    gearbox: {stiffness_Nm_per_rad: 1.3e4}   # overrides of fea.sea_window.Gearbox
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any, Literal

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.fea.sea_window import (
    Gearbox,
    Motor,
    bode_data,
    peak_torque_curve,
    rpm_to_rad_per_s,
    simulate_impact,
    stiffness_window,
    torque_bandwidth_rad_per_s,
)
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.plots import plot_sea_bode, plot_sea_peak_torque
from flexopt.pipeline.studies import EvaluationResult, StudyKind, _builtin, register
from flexopt.pipeline.study import STUDY_CONFIG, MaterialSpec, Study
from pydantic import BaseModel, Field, model_validator

__all__ = ["SeaWindowStudy", "evaluate", "check", "drive"]


class SeaWindowGeometry(BaseModel):
    """The ``geometry:`` block (nothing is built: the kind is a drive analysis)."""

    model_config = STUDY_CONFIG

    kind: Literal["sea_window"] = Field(description="sea_window")


class SeaWindowStudy(Study):
    """A whole ``sea_window`` study file (SI units, named in every key)."""

    geometry: SeaWindowGeometry = Field(description="kind: sea_window")
    material: MaterialSpec | None = Field(None, description="not used (no part is built)")
    required_torque_Nm: float = Field(53.0, gt=0, description="output torque to deliver")
    required_bandwidth_Hz: float = Field(4.0, gt=0, description="at required_torque_Nm")
    impact_speed_rpm: float = Field(46.86, gt=0, description="output speed at the collision")
    impact_spring_torque_Nm: float = Field(0.0, ge=0, description="spring torque at collision")
    criterion: Literal["spring", "gearbox"] = Field(
        "spring", description="K_max from the peak spring torque or the peak gearbox torque"
    )
    stiffness_Nm_per_rad: float | None = Field(
        275.0, gt=0, description="a spring stiffness to check against the window (null: none)"
    )
    sweep_Nm_per_rad: list[float] = Field(
        default_factory=lambda: [25.0, 1000.0], description="[lowest, highest] K of the sweep"
    )
    points: int = Field(30, ge=3, le=400, description="stiffnesses in the sweep (log-spaced)")
    motor: dict[str, float] = Field(
        default_factory=dict, description="overrides of fea.sea_window.Motor (Table 3)"
    )
    gearbox: dict[str, float] = Field(
        default_factory=dict, description="overrides of fea.sea_window.Gearbox (Table 4)"
    )

    @model_validator(mode="after")
    def _sweep(self) -> SeaWindowStudy:
        lo_hi = self.sweep_Nm_per_rad
        if len(lo_hi) != 2 or not 0 < lo_hi[0] < lo_hi[1]:
            raise ValueError(
                f"sweep_Nm_per_rad = {lo_hi}: give [lowest, highest] with 0 < lowest < highest"
            )
        return self


def _replace(default: Any, overrides: dict[str, float], key: str) -> Any:
    names = [f.name for f in dataclasses.fields(default) if f.name != "name"]
    for name, value in overrides.items():
        if name not in names:
            raise StudyError(f"{key}.{name}", f"unknown field; use one of {', '.join(names)}")
        if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
            raise StudyError(f"{key}.{name}", f"{value!r} must be a finite number >= 0")
    try:
        return dataclasses.replace(default, **overrides)
    except FeaError as exc:
        raise StudyError(key, str(exc)) from exc


def drive(study: SeaWindowStudy) -> tuple[Motor, Gearbox]:
    """The motor and gearbox of the study (paper defaults with the study's overrides)."""
    return (
        _replace(Motor(), study.motor, "motor"),
        _replace(Gearbox(), study.gearbox, "gearbox"),
    )


def check(study: SeaWindowStudy) -> None:
    """Refuse unknown drive fields before anything is computed."""
    drive(study)


def _window(study: SeaWindowStudy):
    motor, gearbox = drive(study)
    return stiffness_window(
        motor,
        gearbox,
        required_torque_Nm=study.required_torque_Nm,
        impact_speed_rad_per_s=rpm_to_rad_per_s(study.impact_speed_rpm),
        required_bandwidth_Hz=study.required_bandwidth_Hz,
        impact_spring_torque_Nm=study.impact_spring_torque_Nm,
        criterion=study.criterion,
    )


def evaluate(study: SeaWindowStudy, repeat: int = 1) -> EvaluationResult:
    """``flexopt evaluate``: the window, the sweep over K, the check of ``stiffness_Nm_per_rad``."""
    motor, gearbox = drive(study)
    speed = rpm_to_rad_per_s(study.impact_speed_rpm)
    times = []
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        try:
            window = _window(study)
            ks = np.geomspace(*study.sweep_Nm_per_rad, study.points)
            curve = peak_torque_curve(ks, motor, gearbox, speed, study.impact_spring_torque_Nm)
        except FeaError as exc:
            raise StudyError("geometry", f"the drive analysis failed: {exc}") from exc
        bw_Hz = np.asarray(
            torque_bandwidth_rad_per_s(ks, motor, gearbox, study.required_torque_Nm)
        ) / (2 * math.pi)
        times.append(time.perf_counter() - t0)
    d = window.details
    summary: dict[str, Any] = {
        "k_min_Nm_per_rad": window.k_min_Nm_per_rad,
        "k_max_Nm_per_rad": window.k_max_Nm_per_rad,
        "window_empty": window.is_empty,
        "k_max_spring_criterion_Nm_per_rad": d.k_max_spring_criterion_Nm_per_rad,
        "k_max_gearbox_criterion_Nm_per_rad": d.k_max_gearbox_criterion_Nm_per_rad,
        "torque_limit_Nm": d.torque_limit_Nm,
        "saturation_torque_Nm": d.saturation_torque_Nm,
        "torque_ratio": d.torque_ratio,
        "deflection_at_k_min_deg": math.degrees(d.deflection_at_k_min_rad),
        "deflection_at_k_max_deg": math.degrees(d.deflection_at_k_max_rad),
    }
    k = study.stiffness_Nm_per_rad
    bode_ks = [window.k_min_Nm_per_rad, window.k_max_Nm_per_rad]
    if k is not None:
        hit = simulate_impact(k, motor, gearbox, speed, study.impact_spring_torque_Nm)
        bw = float(torque_bandwidth_rad_per_s(k, motor, gearbox, study.required_torque_Nm))
        summary.update(
            {
                "stiffness_Nm_per_rad": k,
                "in_window": window.contains(k),
                "bandwidth_Hz": bw / (2 * math.pi),
                "peak_spring_torque_Nm": hit.peak_spring_torque_Nm,
                "peak_gearbox_torque_Nm": hit.peak_gearbox_torque_Nm,
                "deflection_deg": math.degrees(study.required_torque_Nm / k),
            }
        )
        bode_ks.insert(1, k)
    table = {
        "stiffness_Nm_per_rad": ks,
        "peak_spring_torque_Nm": curve.peak_spring_torque_Nm,
        "peak_gearbox_torque_Nm": curve.peak_gearbox_torque_Nm,
        "rigid_estimate_Nm": curve.rigid_frictionless_Nm,
        "bandwidth_Hz": bw_Hz,
        "converged": np.asarray(curve.converged, dtype=bool),
    }
    files = {
        "peak_torque.png": plot_sea_peak_torque(curve, window, k),
        "bode.png": plot_sea_bode(
            [
                bode_data(kk, motor, gearbox, study.required_torque_Nm)
                for kk in sorted(bode_ks)
                if 0 < kk < math.inf
            ],
            study.required_bandwidth_Hz,
        ),  # fmt: skip
    }
    return EvaluationResult(
        table=table,
        summary=summary,
        converged=bool(np.all(curve.converged)),
        message="" if np.all(curve.converged) else "some impact simulations did not converge",
        solve_times_s=tuple(times),
        inputs={
            "motor": dataclasses.asdict(motor),
            "gearbox": dataclasses.asdict(gearbox),
            "impact_speed_rad_per_s": speed,
            "required_bandwidth_Hz": study.required_bandwidth_Hz,
        },
        plot={
            "x": "stiffness_Nm_per_rad",
            "y": "peak_spring_torque_Nm",
            "stress": "bandwidth_Hz",
            "y_title": "peak spring torque after the collision",
            "stress_title": "torque bandwidth at the required torque",
        },
        headline=tuple(summary),
        files=files,
    )


register(
    StudyKind(
        "sea_window",
        SeaWindowStudy,
        check,
        evaluate,
        requirements=_builtin.sea_window,
        quantities=_builtin.SEA_WINDOW,
    )
)  # type: ignore[arg-type]
