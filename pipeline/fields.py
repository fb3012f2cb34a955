"""A plane-stress check's field as a DesignResult's ``field_map`` (issue #26 item 5).

The checks of fea/fidelity.py (constant_force) and fea/flexure_design.py (flexure_pivot) return
their mesh and states under ``field`` in their record; the record is written into best.json and
evaluation.json, which must not carry the mesh, so :func:`take_field` takes it out and makes the
``field_map`` that stress_deformed.png, report.html's stress view and best.vtu draw. The springs'
solves (fea/spring_analysis.py, the model and every row's state kept for the detailed design)
become one with :func:`spring_field_map`; the 3D checks' states with :func:`take_solid_field`.

A ``field_map`` (optimise.problem.DesignResult) is one state at its top level (the last checked
one: the end of the check's range) and, under ``steps``, every state the check solved, each with
its drive value, for best.pvd's load steps (:mod:`pipeline.vtu`). Units: mm, MPa.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["mechanism_field_map", "spring_field_map", "take_field"]


def take_field(
    record: Any, label: str, limit: float | None, drive: str | None, drive_scale: float = 1.0
) -> dict[str, Any] | None:
    """Remove ``record['field']`` (a check's mesh and states) and return it as a ``field_map``.

    Parameters
    ----------
    record : dict or anything else — a check's record (``skipped`` ones have no field).
    label : the values' name and unit, for the plots (``von Mises stress ... (MPa)``).
    limit : float, MPa, optional — the allowable stress drawn on the colour bar.
    drive : the drive column the states' ``drive_value`` is in (``displacement_mm``,
        ``rotation_deg``), or None.
    drive_scale : the check's drive unit in the column's (``180 / pi`` for a check in rad and a
        ``rotation_deg`` column).

    Returns
    -------
    dict or None (None without a field or without a state)
        ``points_mm`` (n, 2) mm, ``triangles`` (m, 3) int, ``values`` (n,) MPa (von Mises of the
        last state), ``displacement_mm`` (n, 2) mm (of that state), ``label``, ``limit``,
        ``stress_counted`` (n,) bool (the vertices the check's peak stress counts), ``drive``
        and ``steps``: a list of ``{drive_value, values (n,) MPa, displacement_mm (n, 2) mm}``,
        one per state, in the order solved.
    """
    if not isinstance(record, dict):
        return None
    field = record.pop("field", None)
    if not field or not field.get("steps"):
        return None
    steps = [
        {
            "drive_value": float(s["drive_value"]) * drive_scale,
            "values": np.asarray(s["von_mises_MPa"], dtype=float),
            "displacement_mm": np.asarray(s["displacement_mm"], dtype=float),
        }
        for s in field["steps"]
    ]
    last = steps[-1]
    return {
        "points_mm": np.asarray(field["points_mm"], dtype=float),
        "triangles": np.asarray(field["triangles"], dtype=np.int64),
        "values": last["values"],
        "displacement_mm": last["displacement_mm"],
        "label": label,
        "limit": limit,
        "stress_counted": np.asarray(field.get("stress_counted"), dtype=bool),
        "drive": drive,
        "steps": steps,
    }


#: The label of flexure_pivot's field (its check's nonlinear state at the range of motion).
PIVOT_LABEL = "von Mises stress at the range of motion, plane stress (MPa)"


def pivot_plane_stress(
    info: dict[str, Any], problem: Any, flex: Any, cf: Any, res: Any
) -> dict[str, Any] | None:
    """flexure_pivot's plane-stress check of a planar design (moved here from its detail, which
    is at the kind files' line limit): the record as ``info['plane_stress']``, its figures into
    ``info`` and its field as the returned ``field_map`` (None without one).

    Parameters
    ----------
    info : the detail's info (updated in place).
    problem : the FlexurePivotProblem (``material``, ``rom_rad`` in rad, ``allowable_MPa`` in
        MPa, ``study.fidelity``).
    flex : the planar Flexure; cf : its PivotClosedForm; res : the beam model's PivotResponse.
    """
    from flexopt.fea.flexure_design import plane_stress_check
    from flexopt.optimise.joint_objectives import pivot_plane_stress_figures

    fidelity = problem.study.fidelity
    info["plane_stress"] = plane_stress_check(
        flex,
        problem.material,
        problem.rom_rad,
        fidelity.plane_stress_steps,
        fidelity.web_elements,
        cf,
        res,
        problem.allowable_MPa,
    )
    field_map = take_field(
        info["plane_stress"], PIVOT_LABEL, problem.allowable_MPa, "rotation_deg", 180.0 / np.pi
    )
    info.update(pivot_plane_stress_figures(info["plane_stress"]))
    return field_map


#: The label of constant_force's field (its check's state at the largest checked stroke).
CONSTANT_FORCE_LABEL = "von Mises stress at the largest checked stroke, plane stress (MPa)"


def constant_force_fields(record: Any, model: Any, response: Any, problem: Any) -> dict[str, Any]:
    """constant_force's fields as DesignResult keywords: ``field_map`` (its plane-stress check's
    states, taken out of ``record``: :func:`take_field`) and ``beam_field`` (the section and
    fibre stresses of ``response`` traced by the BeamModel ``model``:
    :func:`fea.beam_fields.beam_field`); ``problem`` gives the allowable stress (MPa)."""
    from flexopt.fea.beam_fields import beam_field
    from flexopt.fea.beam_statics import statics_fibres
    from flexopt.geometry.constant_force import WORK_DIRECTION

    return {
        "field_map": take_field(
            record, CONSTANT_FORCE_LABEL, problem.allowable_MPa, "displacement_mm"
        ),
        # the stresses from statics, the verdict's (fea/beam_statics.py, docs/constant_force.md)
        "beam_field": None
        if response is None
        else statics_fibres(beam_field(model, response), model, response, WORK_DIRECTION),
    }


def take_solid_field(record: Any) -> dict[str, Any] | None:
    """Remove ``record['field']`` (the 3D check's state: fea.sea_design.correct_3d,
    optimise.curve_objectives.threshold_solid_3d) and return it (None without one): the
    DesignResult's ``solid_field``, best_3d.vtu's arrays. The record's ``peak_stress_3d_MPa``
    (the figure the verdict reads: the nonlinear, where converged refined, 2D peak times the
    linear 3D / 2D ratio; not the linear state's own peak) goes with it as ``verdict_peak_MPa``
    (MPa), for the file to say both."""
    if not isinstance(record, dict):
        return None
    field = record.pop("field", None)
    if field is not None and isinstance(record.get("peak_stress_3d_MPa"), int | float):
        field["verdict_peak_MPa"] = float(record["peak_stress_3d_MPa"])
    return field


def spring_field_map(response: Any, label: str, limit: float | None) -> dict[str, Any] | None:
    """The ``field_map`` of a spring's plane-stress solve kept with its model
    (:class:`fea.spring_analysis.SpringResponse` with ``keep_model``: sea_spring's curve and
    threshold_spring's check): the last counter-clockwise state at the top level (``label``
    names it) and, under ``steps``, every converged row's state, the clockwise rows first (their
    ``drive_value`` negative, from the largest clockwise turn to the smallest) then the
    counter-clockwise ones from rest: the order of the kinds' response tables
    (:func:`fea.spring_analysis.curve_table`). None without the model.

    Each state is :func:`fea.plane_stress_fields.state_field` of that row's DOFs: its von Mises
    stress at the vertices the model's peak counts (``stress_counted``) peaks at the row's
    ``peak_stress_MPa`` (the same nodal average), so each step's VTU peaks at the figure the
    verdict reads for that row.

    Returns
    -------
    dict or None
        as :func:`take_field`: ``points_mm`` (n, 2) mm, ``triangles`` (m, 3) int, ``values``
        (n,) MPa, ``displacement_mm`` (n, 2) mm, ``label``, ``limit`` (MPa), ``stress_counted``
        (n,) bool, ``drive`` ("rotation_deg") and ``steps`` (``drive_value`` in degrees).
    """
    from flexopt.fea.plane_stress_fields import mesh_arrays, state_field

    model = getattr(response, "model", None)
    if model is None or getattr(response, "u", None) is None:
        return None
    kinematics = "nonlinear" if response.iterations > 0 else "linear"
    rot_deg = np.asarray(response.rotation_deg, dtype=float)
    rows: list[tuple[float, np.ndarray]] = []
    back = getattr(response, "reverse_row_u", None) or ()
    for k in range(len(back) - 1, 0, -1):  # row 0 (rest) is the counter-clockwise solve's
        if back[k] is not None:
            rows.append((-float(rot_deg[k]), back[k]))
    for k, u in enumerate(getattr(response, "row_u", None) or ()):
        if u is not None:
            rows.append((float(rot_deg[k]), u))
    steps = []
    for value, u in rows:
        f = state_field(model, u, kinematics)
        steps.append(
            {
                "drive_value": value,
                "values": f["von_mises_MPa"],
                "displacement_mm": f["displacement_mm"],
            }
        )
    last = state_field(model, response.u, kinematics)
    return mesh_arrays(model) | {
        "values": last["von_mises_MPa"],
        "displacement_mm": last["displacement_mm"],
        "label": label,
        "limit": limit,
        "drive": "rotation_deg",
        "steps": steps,
    }


#: The label of the mechanism kind's field (its check's linear state, scaled to each row).
MECHANISM_LABEL = "von Mises stress, plane-stress check, linear (MPa)"


def mechanism_field_map(
    check: Any, drive: np.ndarray, column: str, drive_scale: float = 1.0
) -> dict[str, Any] | None:
    """The mechanism kind's plane-stress check (fea/mechanism_fidelity.py, ``keep_field``) as a
    ``field_map``: its state per unit drive scaled to every row's drive (the check is linear:
    displacement times the drive, von Mises times its magnitude), so each row's largest counted
    vertex value is the check's ``plane_stress_peak_nodal_MPa`` times the row's drive.

    Parameters
    ----------
    check : the case's check record; its ``field`` is removed (best.json must not carry it).
    drive : (n_rows,) the rows' drive in the check's unit (mm or rad); NaN rows are left out.
    column : the table's drive column (``drive_mm``, ``drive_deg``); drive_scale : its unit
        per the check's (``180 / pi`` for rad and ``drive_deg``).

    Returns
    -------
    dict or None — :func:`take_field`'s ``field_map`` (None without a field).
    """
    if not isinstance(check, dict) or not isinstance(check.get("field"), dict):
        return None
    field = check["field"]
    vm = np.asarray(field.pop("von_mises_MPa"), dtype=float)
    u = np.asarray(field.pop("displacement_mm"), dtype=float)
    rows = [float(d) for d in np.asarray(drive, dtype=float) if np.isfinite(d)]
    field["steps"] = [
        {"drive_value": d, "von_mises_MPa": abs(d) * vm, "displacement_mm": d * u} for d in rows
    ]
    return take_field(check, MECHANISM_LABEL, None, column, drive_scale)
