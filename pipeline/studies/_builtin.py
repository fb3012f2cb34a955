"""Built-in requirements of every study kind and the names a ``requirements:`` item may judge.

Each kind passes its function here as ``StudyKind.requirements`` and its names as
``StudyKind.quantities`` (see :mod:`pipeline.verdict`). A built-in requirement is what the kind's
study already constrains or targets; its role is ``constraint`` where the optimiser holds it as a
``g <= 0`` row (or rejects designs that fail it) and ``check`` where it is only judged (a curve
the objective merely minimises, a study that is only evaluated). The quantity names are those
both ``flexopt evaluate`` (summary, response columns) and ``flexopt run`` (metrics, the best
design's detail) report, so the same requirement is judged by both commands.
"""

from __future__ import annotations

import math
from typing import Any

from flexopt.optimise.requirements import (
    BEAM,
    PLANE_STRESS,
    AllowableStress,
    Figure,
    Flag,
    MaxValue,
    MinFeature,
    MinValue,
    Range,
    Requirement,
    TargetBand,
)
from flexopt.optimise.targets import ConstantTarget, measure_key
from flexopt.pipeline.studies._constant_force_clamp import CHECKED_PEAK_MODEL
from flexopt.pipeline.studies._constant_force_fillet import pad_stress
from flexopt.pipeline.studies._pivot_roots import PartMax, PartRange, RootStress

# --------------------------------------------------------------------------------------------
# polyline_beam (flexopt evaluate cantilever, fixed_guided)


def polyline_beam(study: Any) -> list[Requirement]:
    """The peak stress within the yield (``stress_yield_ratio <= 1``) and a stable path."""
    return [
        MaxValue("stress_yield_ratio", "stress within yield", "check", 1.0),
        Flag("stable", "stable (no bifurcation)", "check", True),
    ]


POLYLINE_BEAM = (
    "rows_converged", "max_abs_force_N", "max_abs_displacement_mm", "initial_stiffness_N_per_mm",
    "max_abs_transverse_force_N", "max_abs_moment_Nmm", "max_abs_end_rotation_deg",
    "max_peak_stress_MPa", "stress_yield_ratio", "length_mm", "volume_mm3", "mass_g", "stable",
    "unstable_rows", "displacement_mm", "force_N", "transverse_displacement_mm",
    "transverse_force_N", "moment_Nmm", "end_rotation_deg", "peak_stress_MPa",
)  # fmt: skip


# --------------------------------------------------------------------------------------------
# constant_force (paper 003)


def constant_force(study: Any) -> list[Requirement]:
    """The force band over the drive (objective ``rms_error``) or the operative stroke, the
    allowable stress, stability and the printable feature."""
    t, b = study.target, study.boundary
    allowable = t.allowable_stress_MPa or study.material.yield_MPa
    reqs: list[Requirement] = []
    if study.objective == "rms_error":
        first = b.stroke_mm / b.rows  # row 0 is the unloaded state (0 N)
        reqs.append(
            TargetBand(
                "force_N", "force band", "check", x="displacement_mm",
                target=ConstantTarget("force", t.force_N), over=(first, b.stroke_mm),
                tolerance_rel=t.tolerance_percent / 100.0,
            )
        )  # fmt: skip
    if t.min_operative_stroke_mm > 0:
        reqs.append(
            MinValue("operative_stroke_mm", "operative stroke", "constraint",
                     t.min_operative_stroke_mm)
        )  # fmt: skip
    elif study.objective == "operative_stroke":
        reqs.append(
            MinValue("operative_stroke_mm", "operative stroke (force in band)", "check",
                     b.stroke_mm / b.rows)
        )  # fmt: skip
    reqs += [
        pad_stress(study, allowable),  # its bound says when the pad corners are sharp
        Flag("stable", "stable (no bifurcation)", "constraint", True),
        MinFeature("min_feature_mm", "printable feature", "constraint",
                   study.geometry.min_feature_mm),
    ]  # fmt: skip
    return reqs


#: The figures of a quantity by model (pipeline.verdict): the peak stress and the force band
#: are judged on the plane-stress check's figures where the run made one (constant_force's
#: fidelity check; the gripper runs the same study).
CONSTANT_FORCE_FIGURES = {
    "peak_stress_MPa": (
        Figure("peak_stress_MPa", "beam", BEAM),
        # the larger of plane stress and the beam at the pads (_constant_force_clamp.py)
        Figure("checked_peak_stress_MPa", CHECKED_PEAK_MODEL, PLANE_STRESS),
    ),
    "force_N": (
        Figure("force_N", "beam", BEAM),
        Figure("plane_stress_force_N", "plane stress", PLANE_STRESS),
    ),
}

CONSTANT_FORCE = (
    "mean_force_N", "flatness_percent", "operative_stroke_mm", "operative_start_mm",
    "operative_end_mm", "peak_stress_MPa", "window_peak_stress_MPa", "stress_limit_stroke_mm",
    "rms_error_N", "plateau_mean_force_N", "plateau_flatness_percent", "min_feature_mm",
    "stable", "unstable_rows", "stress_yield_ratio", "displacement_mm", "force_N",
    "force_error_percent", "transverse_force_N", "moment_Nmm", "end_rotation_deg",
)  # fmt: skip


# --------------------------------------------------------------------------------------------
# gripper (paper 002 on the constant-force beam)


def gripper(study: Any) -> list[Requirement]:
    """The peak stress within the yield and a stable path."""
    return [
        AllowableStress("peak_stress_MPa", "peak stress", "constraint", study.material.yield_MPa),
        Flag("stable", "stable (no bifurcation)", "check", True),
    ]


GRIPPER = (
    "finger_force_N", "target_force_N", "stroke_mm", "overtravel_mm", "beam_width_mm",
    "beam_plateau_force_N", "beam_max_deviation_percent", "beam_peak_stress_MPa",
    "stress_yield_ratio", "mean_force_N", "flatness_percent", "operative_stroke_mm",
    "peak_stress_MPa", "rms_error_N", "plateau_mean_force_N", "plateau_flatness_percent",
    "min_feature_mm", "stable", "displacement_mm", "force_N", "force_error_percent",
)  # fmt: skip


# --------------------------------------------------------------------------------------------
# flexure_pivot


def flexure_pivot(study: Any) -> list[Requirement]:
    """The small-angle stiffness in its band, the stress at the range of motion, the envelope
    and (when set) the centre shift."""
    t, g = study.target, study.geometry
    k = t.stiffness_Nmm_per_rad or 1000.0 * t.stiffness_Nm_per_rad
    tol = t.tolerance_percent / 100.0
    # NOT MET for a leaf's sharp roots and for a cross_axis design (no part exported), with the
    # reason (_pivot_roots.py)
    reqs: list[Requirement] = [
        PartRange("stiffness_Nmm_per_rad", "stiffness band", "constraint", k * (1 - tol),
                  k * (1 + tol)),
        RootStress("peak_stress_MPa", "peak stress", "constraint",
                   t.allowable_stress_MPa or study.material.yield_MPa),
        PartMax("envelope_length_mm", "envelope length", "constraint", g.max_length_mm),
        PartMax("envelope_height_mm", "envelope height", "constraint", g.max_height_mm),
    ]  # fmt: skip
    if t.max_centre_shift_mm is not None:
        reqs.append(PartMax("centre_shift_mm", "centre shift", "constraint", t.max_centre_shift_mm))
    return reqs


FLEXURE_PIVOT = (
    "stiffness_Nmm_per_rad", "small_angle_stiffness_Nmm_per_rad",
    "closed_form_stiffness_Nmm_per_rad", "peak_stress_MPa", "stress_yield_ratio",
    "safety_factor", "centre_shift_mm", "centre_shift_at_range_mm", "envelope_length_mm",
    "envelope_height_mm", "plane_stress_stiffness_Nmm_per_rad", "plane_stress_safety_factor",
    "rotation_deg", "torque_Nmm", "secant_stiffness_Nmm_per_rad", "beam_stress_MPa",
)  # fmt: skip


# --------------------------------------------------------------------------------------------
# leaf_spring_joint


def leaf_spring_joint(study: Any) -> list[Requirement]:
    """The peak stress of the design within the allowable."""
    allowable = study.target.allowable_stress_MPa or study.material.yield_MPa
    return [AllowableStress("peak_stress_MPa", "peak stress", "constraint", allowable)]


LEAF_SPRING_JOINT = (
    "peak_stress_MPa", "max_peak_stress_MPa", "stress_yield_ratio", "allowable_stress_MPa",
    "safety_factor", "stiffness_at_max_deflection_Nm_per_rad", "l_min_mm", "l_max_mm",
)  # fmt: skip


# --------------------------------------------------------------------------------------------
# sea_spring


def sea_spring(study: Any) -> list[Requirement]:
    """Each direction's secant stiffness within ±tolerance of the target, the peak stress, and
    (when set) the asymmetry and the loaded slot gap."""
    t = study.target
    reqs: list[Requirement] = []
    k = t.stiffness_Nm_per_rad
    if k is not None:
        tol = t.tolerance_percent / 100.0
        lo, hi = k * (1 - tol), k * (1 + tol)
        reqs.append(Range("stiffness_ccw_Nm_per_rad", "stiffness, counter-clockwise",
                          "check", lo, hi))  # fmt: skip
        if getattr(t, "directions", "both") == "both":
            reqs.append(Range("stiffness_cw_Nm_per_rad", "stiffness, clockwise", "check", lo, hi))
    reqs.append(AllowableStress("peak_stress_MPa", "peak stress", "check", t.allowable_stress_MPa))
    s3 = getattr(study, "solid_3d", None)
    if s3 is not None and s3.check:
        # the part as made (issue 15): each direction's 3D stiffness at the corrected ST, the
        # spread the band admits (a thickness scales both directions alike), the 3D peak
        if k is not None:
            pct = f"{t.tolerance_percent:g} %"
            reqs.append(Range("stiffness_ccw_3d_Nm_per_rad", f"3D stiffness ccw within {pct}",
                              "check", lo, hi))  # fmt: skip
            if getattr(t, "directions", "both") == "both":
                reqs.append(Range("stiffness_cw_3d_Nm_per_rad", f"3D stiffness cw within {pct}",
                                  "check", lo, hi))  # fmt: skip
                reqs.append(MaxValue("stiffness_spread_3d_percent",
                                     "3D cw/ccw spread the band admits", "check",
                                     ((1 + tol) / (1 - tol) - 1) * 100))  # fmt: skip
        reqs.append(AllowableStress("peak_stress_3d_MPa", "3D peak stress ≤ allowable", "check",
                                    t.allowable_stress_MPa))  # fmt: skip
        if s3.converge_peak:
            reqs.append(Flag("peak_stress_converged", "peak stress mesh-converged", "check", True))
    else:  # the part as made is not judged: NOT MET with the reason (#27)
        from flexopt.pipeline.studies._sea_spring_3d_off import unchecked_3d_rows

        reqs += unchecked_3d_rows(study)
    if t.max_asymmetry_percent is not None:
        reqs.append(MaxValue("asymmetry_percent", "asymmetry", "constraint",
                             t.max_asymmetry_percent))  # fmt: skip
    gap = getattr(study.geometry, "min_deformed_slot_mm", None)
    if gap is not None:
        reqs.append(MinValue("deformed_slot_mm", "loaded slot gap", "constraint", gap))
    return reqs


SEA_SPRING = (
    "ST_mm", "stiffness_Nm_per_rad", "stiffness_ccw_Nm_per_rad", "stiffness_cw_Nm_per_rad",
    "linear_stiffness_Nm_per_rad", "asymmetry_percent", "peak_stress_MPa", "mass_g",
    "deformed_slot_mm", "torque_Nm", "rotation_deg", "torque_linear_Nm",
    "stiffness_ccw_3d_Nm_per_rad", "stiffness_cw_3d_Nm_per_rad", "peak_stress_3d_MPa",
    "stiffness_spread_3d_percent", "stiffness_ratio_3d_2d", "ST_3d_mm", "peak_stress_converged",
)  # fmt: skip


# --------------------------------------------------------------------------------------------
# threshold_spring


def threshold_spring(study: Any) -> list[Requirement]:
    """The error measure against the target curve within the tolerance, the peak stress."""
    curve = study.target.to_curve() if study.target.kind != "table" else None
    measure = getattr(study, "measure", None) or getattr(study.target, "measure", "rms")
    name = measure_key(measure, curve) if curve is not None else f"{measure}_error"
    allowable = study.allowable_stress_MPa or 0.9 * study.material.yield_MPa
    lo, hi = study.geometry.thickness_range_mm
    reqs: list[Requirement] = [
        MaxValue(name, "target curve error", "constraint", study.tolerance),
        AllowableStress("peak_stress_MPa", "peak stress", "constraint", allowable),
        # the sizes the study solves, inside their stated range and printable (issue 22)
        Range("ST_mm", "plate thickness ST in thickness_range_mm", "constraint", lo, hi),
        MinFeature("min_feature_mm", "printable feature", "constraint",
                   study.geometry.min_feature_mm),
    ]  # fmt: skip
    s3 = getattr(study, "solid_3d", None)
    if s3 is not None and s3.check and getattr(study.fidelity, "enabled", True):
        # the part as made (issue 15): the plane-stress curve times the 3D/2D stiffness ratio,
        # and the 3D peak; checks only (the GA's metrics have no 3D answers)
        reqs += [
            MaxValue(f"{name}_3d", "3D target curve error", "check", study.tolerance),
            AllowableStress("peak_stress_3d_MPa", "3D peak stress ≤ allowable", "check", allowable),
        ]
        if getattr(s3, "converge_peak", False):
            reqs.append(Flag("peak_stress_converged", "peak stress mesh-converged", "check", True))
    elif s3 is not None:  # the part as made is not judged: NOT MET with the reason (#27)
        from flexopt.pipeline.studies._sea_spring_3d_off import THRESHOLD_REASON, Unchecked3D

        reqs.append(Unchecked3D(reason=THRESHOLD_REASON))
    return reqs


THRESHOLD_SPRING = (
    "ST_mm", "max_normalised_error", "rms_normalised_error", "max_relative_error",
    "rms_relative_error", "peak_stress_MPa", "torque_at_range_Nm",
    "initial_stiffness_Nm_per_rad", "rotation_deg", "torque_Nm", "target_torque_Nm",
    "stiffness_ratio_3d_2d", "linear_stiffness_3d_Nm_per_rad", "max_normalised_error_3d",
    "rms_normalised_error_3d", "max_relative_error_3d", "rms_relative_error_3d",
    "peak_stress_3d_MPa", "peak_stress_ratio_3d_2d", "peak_stress_converged", "min_feature_mm",
    "ST_after_mm",
)  # fmt: skip


# --------------------------------------------------------------------------------------------
# cam


def cam(study: Any) -> list[Requirement]:
    """Pressure angle, contact pressure below the onset of damage, no undercut, the diameter."""
    lim = study.limits
    reqs: list[Requirement] = [
        MaxValue("max_pressure_angle_deg", "pressure angle", "constraint",
                 lim.max_pressure_angle_deg),
        MaxValue("stress_yield_ratio", "contact pressure within onset", "constraint", 1.0),
        Flag("undercut", "undercut", "constraint", False),
    ]  # fmt: skip
    if lim.max_diameter_mm:
        reqs.append(MaxValue("mechanism_diameter_mm", "diameter", "constraint",
                             lim.max_diameter_mm))  # fmt: skip
    return reqs


CAM = (
    "target_max_normalised_error", "max_follower_radius_mm", "follower_stroke_mm",
    "mechanism_diameter_mm", "max_pressure_angle_deg", "max_contact_force_N",
    "max_spring_force_N", "preload_N", "min_convex_profile_radius_mm", "undercut",
    "max_contact_pressure_MPa", "onset_pressure_MPa", "stress_yield_ratio", "plate_mass_g",
    "rotation_deg", "target_torque_Nm", "cam_torque_Nm", "pressure_angle_deg",
    "contact_pressure_MPa", "spring_force_N", "contact_force_N",
)  # fmt: skip


# --------------------------------------------------------------------------------------------
# collision (evaluate only)


def collision(study: Any) -> list[Requirement]:
    """The spring lowers HIC15 and the peak force against the reference; with a cam, the cam
    stays within its range."""
    reqs: list[Requirement] = [
        MinValue("hic_reduction", "HIC15 below the reference", "check", 0.0),
        MinValue("force_reduction", "peak force below the reference", "check", 0.0),
    ]
    if getattr(study, "cam", None) is not None:
        reqs.append(Flag("cam_range_exceeded", "cam range exceeded", "check", False))
    return reqs


COLLISION = (
    "hic15", "reference_hic15", "hic_reduction", "peak_force_N", "reference_peak_force_N",
    "force_reduction", "max_deflection_deg", "reference_max_deflection_deg",
    "cam_contact_pressure_MPa", "cam_range_exceeded",
)  # fmt: skip


# --------------------------------------------------------------------------------------------
# sea_window (evaluate only)


def sea_window(study: Any) -> list[Requirement]:
    """A stiffness window exists; a given stiffness lies in it and meets the bandwidth."""
    reqs: list[Requirement] = [Flag("window_empty", "stiffness window empty", "check", False)]
    if study.stiffness_Nm_per_rad is not None:
        reqs += [
            Flag("in_window", "stiffness in the window", "check", True),
            MinValue("bandwidth_Hz", "bandwidth", "check", study.required_bandwidth_Hz),
        ]
    return reqs


SEA_WINDOW = (
    "k_min_Nm_per_rad", "k_max_Nm_per_rad", "window_empty", "torque_limit_Nm",
    "saturation_torque_Nm", "stiffness_Nm_per_rad", "in_window", "bandwidth_Hz",
    "peak_spring_torque_Nm", "peak_gearbox_torque_Nm", "deflection_deg",
)  # fmt: skip


def finite_or_none(value: Any) -> float | None:
    """A float, or None when it is not a finite number."""
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None
