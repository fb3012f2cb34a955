"""Study kind ``cam``: the cam–follower torque generator of paper 000 (V2SOM) for a target curve.

The study names a torque target (``target:``, any :class:`optimise.targets.TargetSpec` of torque;
the paper's threshold ``T = Tmax (1 - exp(-s γ))`` by default), the followers' springs and the
layout. ``flexopt evaluate`` synthesises the cam (:func:`fea.contact.synthesise_cam`), builds the
plate, and checks it by virtual work: the torque of the *plate* (follower motion read off its
outline) against the target, with the contact pressure along the way. ``flexopt run`` sizes the
springs and the rest radius for the smallest mechanism within the pressure-angle and
contact-pressure limits, and writes the plate as ``best.stl``.

YAML (units in the key names; see docs/threshold_torque.md)::

    geometry: {kind: cam, rest_radius_mm: 20, roller_radius_mm: 5, followers: 2,
               max_rotation_deg: 90, thickness_mm: 10, bore_diameter_mm: 6}
    material: PLA                              # the plate
    springs: {stiffness_N_per_mm: 4, free_length_mm: 18, offset_mm: 10, count: 4}
    friction: 0.0
    target: {kind: threshold, max_torque_Nm: 2.05, rate_per_rad: 50, measure: max_normalised,
             window_deg: [1, 85]}
    correction: {coefficients: [1.001, -0.0369, 2.588]}     # Eq. 17, optional (or fit: true)
    sab: {a_mm: 15, R_mm: 30, R1_over_R2: 7.5}             # Eqs. 15-16, optional
    limits: {max_pressure_angle_deg: 45}
    design_space: {rest_radius_mm: [12, 30], stiffness_N_per_mm: [0.5, 10]}
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from flexopt.fea.contact import (
    contact_pressure_MPa,
    sab_limits,
    sab_table,
    torque_from_outline,
)
from flexopt.geometry.cam import CamProfile, cam_outline
from flexopt.geometry.errors import GeometryError
from flexopt.optimise.curve_objectives import (
    cam_constraints,
    cam_metrics,
    cam_target_errors,
    sab_joint_errors,
)
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import DesignDetail, DesignProblem, DesignResult
from flexopt.optimise.space import DesignSpace
from flexopt.optimise.targets import (
    TargetCurve,
    ThresholdTarget,
)
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import StudyKind, _builtin, register
from flexopt.pipeline.studies._cam import (
    CAM_LIFE_REFUSAL,
    CAM_VARIABLES,
    CamGeometry,
    CamStudyFields,
    SpringsSpec,
    build_cam,
    refuse_duty_cycle,
)
from flexopt.pipeline.study import material_record
from flexopt.pipeline.verdict import envelope_values

__all__ = [
    "CamGeometry",
    "CamStudy",
    "CamProblem",
    "SpringsSpec",
    "build_cam",
]

# --------------------------------------------------------------------------------------------
# The study file (its blocks and fields: pipeline/studies/_cam.py, shared with collision)


class CamStudy(CamStudyFields):
    """A whole ``cam`` study file."""


def check(study: CamStudy) -> None:
    """Build the target, the cam and its plate once, so that every refusal names its key."""
    refuse_duty_cycle(study)  # no stress that fatigues: _cam.CAM_LIFE_REFUSAL
    for name, (lo, hi) in study.design_space.items():
        if name not in CAM_VARIABLES:
            raise StudyError(
                f"design_space.{name}", f"unknown variable; use one of {', '.join(CAM_VARIABLES)}"
            )
        if not lo < hi:
            raise StudyError(
                f"design_space.{name}", f"[{lo:g}, {hi:g}] needs lower < upper; swap or widen them"
            )
    if study.correction is not None and study.correction.fit and study.sab is None:
        raise StudyError("correction.fit", "fitting Eq. 17 needs the sab: block (a_mm, R_mm, ...)")
    if study.sab is not None:
        try:
            sab_limits(study.sab.a_mm, study.sab.R_mm, study.sab.R1_over_R2)
        except GeometryError as exc:
            raise StudyError("sab.a_mm", str(exc)) from exc
    _, _, profile, _ = build_cam(study)
    try:
        cam_outline(profile)
    except GeometryError as exc:
        raise StudyError("geometry.roller_radius_mm", str(exc)) from exc


# --------------------------------------------------------------------------------------------
# Evaluate


def _table(
    study: CamStudy, target: TargetCurve, curve: Any, profile: CamProfile
) -> dict[str, np.ndarray]:
    lay = profile.layout
    gamma = np.linspace(0.0, lay.max_rotation_rad, study.rows)
    plate = cam_outline(profile)
    vw = torque_from_outline(plate, profile.springs, lay, gamma)
    pressure = contact_pressure_MPa(
        profile, study.material.E_MPa, study.material.nu, **_roller(study)
    )

    def at(values: np.ndarray) -> np.ndarray:
        return np.interp(gamma, profile.rotation_rad, values)

    table = {
        "rotation_deg": np.degrees(gamma),
        "target_torque_Nm": target(gamma) / 1000.0,
        "cam_torque_Nm": np.asarray(curve(gamma)) / 1000.0,
        "virtual_work_torque_Nm": vw / 1000.0,
        "follower_radius_mm": at(profile.follower_radius_mm),
        "pressure_angle_deg": np.degrees(at(profile.pressure_angle_rad)),
        "spring_force_N": at(profile.spring_force_N),
        "contact_force_N": at(profile.contact_force_N),
        "contact_pressure_MPa": at(np.where(np.isfinite(pressure), pressure, 1e9)),
    }
    if isinstance(target, ThresholdTarget):
        table["mode"] = target.mode(gamma)
    table["converged"] = np.ones(gamma.size, dtype=bool)
    return table


def _roller(study: CamStudy) -> dict[str, float]:
    return {"roller_E_MPa": study.roller.E_MPa, "roller_nu": study.roller.nu}


def _metrics(study: CamStudy, profile: CamProfile) -> dict[str, Any]:
    m = study.material
    return cam_metrics(profile, m.E_MPa, m.nu, m.yield_MPa, study.roller.E_MPa, study.roller.nu)


def _summary(
    study: CamStudy,
    target: TargetCurve,
    curve: Any,
    table: dict[str, np.ndarray],
    profile: CamProfile,
) -> dict[str, Any]:
    """Scalar results: the plate's torque (by virtual work) against the target with the study's
    measure (``target_<measure>``; with a correction the cam is cut for ``T_cor``, so this one
    shows the correction, and ``virtual_work_*`` compares the plate with what it was cut for),
    the cam's size, angles, forces and contact pressure, and the SAB check."""
    window = study.target.window
    if window is None:  # the plate's torque drops where the follower rolls over the lobe
        window = (0.0, math.radians(study.geometry.max_rotation_deg) * 0.95)
    try:
        summary = cam_target_errors(
            target,
            table["rotation_deg"],
            table["cam_torque_Nm"],
            table["virtual_work_torque_Nm"],
            study.target.measure,
            window,
        )
    except OptimiseError as exc:
        raise StudyError("target.window_deg", str(exc)) from exc
    summary.update(_metrics(study, profile))
    if study.sab is not None:
        summary.update(_joint_errors(study, target, curve))
    area = cam_outline(profile).area
    summary["plate_area_mm2"] = area
    density = study.material.density_kg_m3
    summary["plate_mass_g"] = (
        area * study.geometry.thickness_mm * density * 1e-6 if density else None
    )
    if isinstance(target, ThresholdTarget):
        summary.update(
            {
                "mode_split_deg": math.degrees(target.split_x),
                "mode_split_torque_Nm": target.split_y / 1000.0,
                "equivalent_stiffness_Nm_per_rad": target.equivalent_stiffness / 1000.0,
                "initial_stiffness_Nm_per_rad": target.max_value * target.rate / 1000.0,
            }
        )
    return summary


def _joint_errors(study: CamStudy, target: TargetCurve, curve: Any) -> dict[str, Any]:
    sab = study.sab
    assert sab is not None
    top = None if sab.max_output_deg is None else math.radians(sab.max_output_deg)
    return sab_joint_errors(
        target, curve, sab.a_mm, sab.R_mm, sab.R1_over_R2, top, study.geometry.max_rotation_deg
    )


def _sab_info(study: CamStudy) -> dict[str, Any]:
    sab = study.sab
    return {} if sab is None else sab_table(sab.a_mm, sab.R_mm, sab.R1_over_R2)


# --------------------------------------------------------------------------------------------
# Optimise: size the springs and rest radius


class CamProblem(DesignProblem):
    """Smallest (or flattest) cam for the target within the pressure-angle and contact limits.

    Variables: the study's ``design_space`` (default: rest radius and spring rate, ±50 % around
    the study's values). Constraints ``g <= 0``: pressure angle / limit - 1, contact pressure /
    onset - 1, ``κ r1 - 0.9`` (roller 10 % inside every convex bend: no undercut), and the
    diameter limit when given.
    """

    life_refusal = CAM_LIFE_REFUSAL

    def __init__(self, study: CamStudy) -> None:
        self.study = study
        bounds = dict(study.design_space) or {
            "rest_radius_mm": (
                0.5 * study.geometry.rest_radius_mm,
                1.5 * study.geometry.rest_radius_mm,
            ),
            "stiffness_N_per_mm": (
                0.5 * study.springs.stiffness_N_per_mm,
                1.5 * study.springs.stiffness_N_per_mm,
            ),
        }
        names = tuple(n for n in CAM_VARIABLES if n in bounds)
        try:
            self.space = DesignSpace(
                names,
                np.array([bounds[n][0] for n in names]),
                np.array([bounds[n][1] for n in names]),
            )
        except OptimiseError as exc:
            raise StudyError("design_space", str(exc)) from exc
        self.objective_names = (
            ("mechanism_diameter_mm",)
            if study.objective == "diameter"
            else ("max_pressure_angle_deg",)
        )
        self.constraint_names = (
            "pressure_angle_ratio",
            "contact_pressure_ratio",
            "undercut_margin",
        ) + (("diameter_ratio",) if study.limits.max_diameter_mm else ())

    def _study(self, x: np.ndarray) -> CamStudy:
        values = dict(zip(self.space.names, (float(v) for v in x), strict=True))
        geometry = self.study.geometry
        if "rest_radius_mm" in values:
            geometry = geometry.model_copy(update={"rest_radius_mm": values.pop("rest_radius_mm")})
        springs = self.study.springs.model_copy(update=values)
        return self.study.model_copy(update={"geometry": geometry, "springs": springs})

    def evaluate(self, x: np.ndarray) -> Evaluation:
        t0 = time.perf_counter()
        n_obj, n_con = len(self.objective_names), len(self.constraint_names)
        try:
            study = self._study(x)
            _, _, profile, _ = build_cam(study)
            metrics = _metrics(study, profile)
        except (StudyError, GeometryError, OptimiseError) as exc:
            return Evaluation.failed(x, n_obj, n_con, str(exc), time.perf_counter() - t0)
        lim = study.limits
        f = [metrics[self.objective_names[0]]]
        g = cam_constraints(metrics, profile, lim.max_pressure_angle_deg, lim.max_diameter_mm)
        return Evaluation(
            np.asarray(x, float), np.array(f), np.array(g), metrics, "", time.perf_counter() - t0
        )

    def detail(self, x: np.ndarray) -> DesignDetail:
        study = self._study(x)
        target, curve, profile, correction = build_cam(study)
        table = _table(study, target, curve, profile)
        info = _summary(study, target, curve, table, profile)
        info["design"] = dict(zip(self.space.names, (float(v) for v in x), strict=True))
        if correction:
            info["correction"] = correction
        return DesignDetail(
            evaluation=self.evaluate(x),
            table=table,
            plot={
                "x": "rotation_deg",
                "y": "virtual_work_torque_Nm",
                "stress": "contact_pressure_MPa",
                "target_curve": "target_torque_Nm",
                "allowable_MPa": info["onset_pressure_MPa"],
                "x_label": "cam rotation γ (deg)",
                "y_label": "torque of the plate by virtual work (N·m)",
            },
            outline=cam_outline(profile),
            height_mm=study.geometry.thickness_mm,
            info=info,
        )

    def initial_designs(self) -> np.ndarray | None:
        """The study's own values, when they lie in the design space."""
        g, s = self.study.geometry, self.study.springs
        values = {
            "rest_radius_mm": g.rest_radius_mm,
            "stiffness_N_per_mm": s.stiffness_N_per_mm,
            "free_length_mm": s.free_length_mm,
            "offset_mm": s.offset_mm,
        }
        x = np.array([values[n] for n in self.space.names])
        if np.all(x >= self.space.lower) and np.all(x <= self.space.upper):
            return x[None, :]
        return None

    def nominal_design(self) -> np.ndarray:
        """(n_var,) the study's own values in the design space: what ``flexopt evaluate`` solves."""
        return design_of(self.study)[1]

    def result(self, x: np.ndarray, repeat: int = 1) -> DesignResult:
        """Synthesise the cam of design ``x`` (n_var,), build its plate and check it by virtual
        work (``repeat`` times)."""
        study = self._study(np.asarray(x, dtype=float))
        times = []
        for _ in range(max(1, repeat)):
            t0 = time.perf_counter()
            target, curve, profile, correction = build_cam(study)
            table = _table(study, target, curve, profile)
            times.append(time.perf_counter() - t0)
        summary = _summary(study, target, curve, table, profile)
        # the plate as exported (its outline extruded by the thickness), as flexopt run measures it
        summary.update(envelope_values(cam_outline(profile), study.geometry.thickness_mm))
        inputs: dict[str, Any] = {
            "material": material_record(study.material.to_material()),
            "target_curve": repr(target),
            "notes": list(profile.notes),
        }
        if correction:
            inputs["correction"] = correction
        if study.sab is not None:
            inputs["sab"] = _sab_info(study)
        return DesignResult(
            table=table,
            summary=summary,
            converged=True,
            message="",
            solve_times_s=tuple(times),
            inputs=inputs,
            diagnostics={"synthesis_points": study.geometry.points},
            plot={
                "x": "rotation_deg",
                "y": "virtual_work_torque_Nm",
                "stress": "contact_pressure_MPa",
                "allowable_MPa": summary["onset_pressure_MPa"],
                "allowable_label": "onset of yield, contact",
                "target_curve": "target_torque_Nm",  # drawn by pipeline.plot_targets
            },
            headline=tuple(
                k
                for k in summary
                if k.startswith("target_")
                or k
                in (
                    "virtual_work_max_relative_error",
                    "mechanism_diameter_mm",
                    "max_pressure_angle_deg",
                    "max_contact_pressure_MPa",
                    "stress_yield_ratio",
                    "undercut",
                    "sab_joint_max_relative_error",
                    "mode_split_deg",
                    "equivalent_stiffness_Nm_per_rad",
                )
            ),
        )


def problem(study: CamStudy) -> CamProblem:
    """The design problem ``flexopt run`` optimises."""
    return CamProblem(study)


def design_of(study: CamStudy) -> tuple[DesignSpace, np.ndarray]:
    """The design space and the study's own values in it (what ``flexopt evaluate`` solves),
    for the design-range row of the verdict (pipeline.verdict)."""
    prob = CamProblem(study)
    g, s = study.geometry, study.springs
    values = {
        "rest_radius_mm": g.rest_radius_mm,
        "stiffness_N_per_mm": s.stiffness_N_per_mm,
        "free_length_mm": s.free_length_mm,
        "offset_mm": s.offset_mm,
    }
    return prob.space, np.array([values[n] for n in prob.space.names], dtype=float)


register(
    StudyKind(
        "cam",
        CamStudy,
        check,
        None,  # flexopt evaluate: the nominal design's CamProblem.result
        problem,
        requirements=_builtin.cam,
        quantities=_builtin.CAM,
        design_space=design_of,
    )
)  # type: ignore[arg-type]
