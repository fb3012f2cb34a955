"""The SEA spring kind's slot contact: do the windings touch in the working range, and what
happens past first contact (the overload curve).

Two things, both on the design as solved by the kind (:class:`pipeline.studies.sea_spring.
SeaSpringProblem`), in ``flexopt evaluate`` and a run's best design (never in the GA loop):

* **The working range without contact.** The kind's plane-stress model has no contact: past
  first contact its windings pass through each other. The signed gap across the slots
  (:func:`fea.plane_stress_contact.nearest`, node to segment on the deformed outline) at
  +-theta_T says whether they do inside the working range. If they do and the study has no
  ``contact:`` block, the verdict gets a NOT MET row saying so (the stiffness and stress rows
  are of a part that passes through itself); a spring whose slots stay open keeps its verdict
  and numbers as before.
* **The overload curve** (with ``contact: {overload_deg: ...}``): the hub turned to
  +-overload_deg with frictionless self-contact across the slots
  (:class:`fea.plane_stress_contact.ContactPlaneStressModel`, the kind's mesh, the design's
  ST): per direction the angle and torque at first contact, the torque, contact force and
  peak stress per row, the windings' peak stress with contact. Summary values
  ``first_contact_<dir>_deg``, ``first_contact_<dir>_torque_Nm``, ``overload_<dir>_torque_Nm``,
  ``overload_peak_stress_MPa``, ``slots_clear_in_working_range``; the curve as
  ``overload.csv``; the record as ``info["slot_contact"]`` (the Durability section's
  contact part reads it, :mod:`pipeline.durability_report`).

Units: degrees and N m at the edges (as named), mm, N, MPa inside.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
from flexopt.fea.plane_stress import Clamp, PlaneStressSettings, Rotate
from flexopt.fea.plane_stress_contact import (
    ContactPlaneStressModel,
    ContactSettings,
    SelfContact,
    build_surfaces,
    nearest,
)
from flexopt.optimise.problem import DesignResult
from flexopt.optimise.requirements import Flag, MaxValue, Requirement

__all__ = ["METHOD", "finish", "first_contact", "overload", "requirements", "working_gaps"]

METHOD = (
    "frictionless node-to-segment penalty self-contact across the slots inside the "
    "plane-stress Newton solve (fea/plane_stress_contact.py; docs/plane_stress.md, Contact)"
)

#: The summary flag the working-range row judges (and its message).
CLEAR = "slots_clear_in_working_range"


def requirements(study: Any) -> list[Requirement]:
    """The rows a ``contact:`` block adds (none without one): the slots clear of each other
    in the working range, and the overload peak stress when ``max_stress_MPa`` is set."""
    spec = getattr(study, "contact", None)
    if spec is None:
        return []
    rows: list[Requirement] = [Flag(CLEAR, "slots clear in the working range", "check", True)]
    if spec.max_stress_MPa is not None:
        rows.append(MaxValue("overload_peak_stress_MPa", "peak stress with contact to the "
                             "overload angle", "check", spec.max_stress_MPa))  # fmt: skip
    return rows


def first_contact(
    rows_deg: np.ndarray, torque_Nm: np.ndarray, min_gap_mm: np.ndarray, in_contact: np.ndarray
) -> dict[str, float | None]:
    """The angle and torque at first contact from a solve's rows (one direction).

    The gap closes smoothly until contact, so the first contact angle is the zero of the
    straight line through the gap of the last two rows before the first row in contact (or of
    the last open row and the first closed one when only one open row precedes it), kept
    between those rows; the torque is the line through the same rows' torques there (the
    curve before contact, which is the plain model's).

    Parameters
    ----------
    rows_deg, torque_Nm, min_gap_mm : (k,) degrees, N m, mm — one direction's rows (signed).
    in_contact : (k,) bool.

    Returns
    -------
    dict — ``angle_deg`` and ``torque_Nm`` (magnitudes; None when no row is in contact),
    ``row`` (the first row in contact, or None).
    """
    rows = np.abs(np.asarray(rows_deg, dtype=float))
    torque = np.abs(np.asarray(torque_Nm, dtype=float))
    gap = np.asarray(min_gap_mm, dtype=float)
    hit = np.flatnonzero(np.asarray(in_contact, dtype=bool))
    if hit.size == 0:
        return {"angle_deg": None, "torque_Nm": None, "row": None}
    k = int(hit[0])
    if k == 0:
        return {"angle_deg": 0.0, "torque_Nm": float(torque[0]), "row": 0}
    i, j = (k - 2, k - 1) if k >= 2 and np.isfinite(gap[k - 2]) else (k - 1, k)
    slope = (gap[j] - gap[i]) / (rows[j] - rows[i])
    angle = rows[j] - gap[j] / slope if slope < 0 else rows[k - 1]
    angle = float(np.clip(angle, rows[k - 1], rows[k]))
    t = torque[i] + (torque[j] - torque[i]) * (angle - rows[i]) / (rows[j] - rows[i])
    return {"angle_deg": angle, "torque_Nm": float(t), "row": k}


def working_gaps(r: Any, reach_mm: float) -> dict[str, float]:
    """The signed gap across the slots (mm, < 0: the windings pass through each other) of the
    kind's solve without contact at +theta_T (``ccw``) and -theta_T (``cw``, when solved);
    empty when the model was not kept."""
    model = getattr(r, "model", None)
    if model is None or r.u is None:
        return {}
    surf = build_surfaces(model, SelfContact(reach_mm=reach_mm))  # once for both states
    states = {"ccw": r.u, "cw": r.reverse_u}
    return {k: nearest(surf, surf.X + u[surf.dofs])[4] for k, u in states.items() if u is not None}


def overload(prob: Any, geom: Any, r: Any, st_mm: float) -> dict[str, Any]:
    """The overload curve of a solved design with contact across its slots, each direction.

    Parameters
    ----------
    prob : SeaSpringProblem (its study's ``contact:``, material, angle theta).
    geom : SpringGeometry of the design; r : its SpringResponse with the model kept (its mesh
        is reused); st_mm : float, mm — the design's plate thickness ST.

    Returns
    -------
    dict — ``overload_deg``, ``penalty_factor``, ``reach_mm``, ``method``, ``directions``:
    per "ccw" / "cw" ``first_contact_deg``, ``first_contact_torque_Nm``,
    ``peak_stress_at_first_contact_MPa`` (the plain curve there, interpolated),
    ``overload_torque_Nm`` and ``overload_peak_stress_MPa`` (the last converged row),
    ``max_contact_force_N``, ``min_gap_mm``, ``rows_in_contact``, ``converged``, ``message``
    and ``rows`` (``rotation_deg``, ``torque_Nm``, ``peak_stress_MPa``, ``contact_force_N``,
    ``min_gap_mm``, ``in_contact``: lists, magnitudes of angle and torque).
    """
    spec = prob.study.contact
    plain = r.model
    ignore = geom.hub_region.union(geom.pad_region).buffer(0.05)  # as analyse_spring's
    # analyse_spring's tolerance; more Newton iterations and rises than a plain solve allows:
    # a contact that closes at a corner takes 10-20 iterations with the line search
    cfg = PlaneStressSettings(rtol_residual=1e-7, max_newton_iter=40, diverging_iterations=8)
    signs = {"ccw": 1.0}
    if prob.study.target.directions == "both":
        signs["cw"] = -1.0
    out: dict[str, Any] = {}
    for name, sign in signs.items():
        model = ContactPlaneStressModel(
            plain.mesh, plain.material, st_mm, Clamp(geom.pad_region),
            Rotate(geom.hub_region, (0.0, 0.0), sign * math.radians(spec.overload_deg),
                   spec.steps),
            SelfContact(reach_mm=spec.reach_mm), cfg, ignore,
            ContactSettings(penalty_factor=spec.penalty_factor),
        )  # fmt: skip
        res = model.solve("nonlinear")
        c = res.extra["contact"]
        rows = np.degrees(np.abs(res.drive_value))
        torque = np.abs(res.torque_Nmm) * 1e-3
        stress = np.asarray(res.peak_nodal_stress_MPa)
        fc = first_contact(rows, torque, c["min_gap_mm"], c["in_contact"])
        ok = np.asarray(res.converged)
        last = int(np.flatnonzero(ok)[-1])
        at_first = None
        if fc["row"] is not None:
            # the plain curve's peak there: the line through the same rows as the torque's
            at_first = first_contact(rows, stress, c["min_gap_mm"], c["in_contact"])["torque_Nm"]
        out[name] = {
            "first_contact_deg": fc["angle_deg"],
            "first_contact_torque_Nm": fc["torque_Nm"],
            "peak_stress_at_first_contact_MPa": at_first,
            "overload_deg": float(rows[last]),
            "overload_torque_Nm": float(torque[last]),
            "overload_peak_stress_MPa": float(np.nanmax(stress[ok])),
            "max_contact_force_N": float(np.nanmax(c["force_N"][ok])),
            "max_contact_pressure_MPa": float(np.nanmax(c["max_pressure_MPa"][ok])),
            "min_gap_mm": float(np.nanmin(c["min_gap_mm"][ok])),
            "rows_in_contact": int(np.count_nonzero(c["in_contact"])),
            "converged": bool(res.ok),
            "message": res.message,
            "rows": {
                "rotation_deg": rows[ok].tolist(),
                "torque_Nm": torque[ok].tolist(),
                "peak_stress_MPa": stress[ok].tolist(),
                "contact_force_N": np.asarray(c["force_N"])[ok].tolist(),
                "min_gap_mm": np.asarray(c["min_gap_mm"])[ok].tolist(),
                "in_contact": np.asarray(c["in_contact"])[ok].tolist(),
            },
        }
    return {
        "overload_deg": spec.overload_deg,
        "penalty_factor": spec.penalty_factor,
        "reach_mm": spec.reach_mm,
        "method": METHOD,
        "directions": out,
    }


def _csv(record: dict[str, Any]) -> bytes:
    """overload.csv: one row per direction and angle (units in the column names)."""
    cols = ("rotation_deg", "torque_Nm", "peak_stress_MPa", "contact_force_N", "min_gap_mm",
            "in_contact")  # fmt: skip
    lines = ["direction," + ",".join(cols)]
    for name, d in record["directions"].items():
        rows = d["rows"]
        for i in range(len(rows["rotation_deg"])):
            lines.append(name + "," + ",".join(repr(rows[c][i]) for c in cols))
    return ("\n".join(lines) + "\n").encode()


def finish(prob: Any, geom: Any, r: Any, st_mm: float, result: DesignResult) -> DesignResult:
    """``result`` (the kind's evaluate or detail of the design) with its slot contact.

    Without a ``contact:`` block: unchanged unless the windings pass through each other at
    +-theta_T, in which case its verdicts carry a NOT MET row saying so (the contact that
    happens is not modelled). With one: the overload record, its summary values, the
    working-range row's flag and ``overload.csv``.
    """
    spec = getattr(prob.study, "contact", None)
    if r is None or not r.ok or getattr(r, "model", None) is None:
        return result
    gaps = working_gaps(r, spec.reach_mm if spec is not None else SelfContact().reach_mm)
    touching = {k: v for k, v in gaps.items() if v <= 0.0}
    theta = math.degrees(prob.theta)
    if spec is None:
        if not touching:
            return result
        from flexopt.pipeline.verdict import judge_result, study_requirements

        why = (
            f"the slots close inside the working range: at {theta:.4g} deg "
            + ", ".join(f"{k} the windings pass {-v:.3g} mm into each other"
                        for k, v in touching.items())
            + " in the model without contact, so its stiffness and stress rows are of a part "
            "that passes through itself; add contact: {overload_deg: ...} to the study to "
            "model the contact"
        )  # fmt: skip
        row = Flag(CLEAR, "slots clear in the working range", "check", True).check(
            {CLEAR: False, f"{CLEAR}_message": why}
        )
        # judged without the design-range row: the caller adds it for the design it judges
        rows = judge_result(prob.study, result, requirements=study_requirements(prob.study))
        return replace(result, verdicts=(*rows, row))
    record = overload(prob, geom, r, st_mm)
    record["working_range_gap_mm"] = gaps
    record["theta_T_deg"] = theta
    values: dict[str, Any] = {CLEAR: not touching}
    notes: dict[str, str] = {}
    if touching:
        notes[f"{CLEAR}_message"] = (
            f"the slots touch inside the working range ({theta:.4g} deg): the stiffness and "
            "stress rows are of the model without contact; the overload curve (with contact) "
            "is in overload.csv"
        )
    peaks = []
    for name, d in record["directions"].items():
        values[f"first_contact_{name}_deg"] = d["first_contact_deg"]
        values[f"first_contact_{name}_torque_Nm"] = d["first_contact_torque_Nm"]
        values[f"overload_{name}_torque_Nm"] = d["overload_torque_Nm"]
        peaks.append(d["overload_peak_stress_MPa"])
        if not d["converged"]:
            notes[f"overload_{name}_message"] = d["message"]
    values["overload_peak_stress_MPa"] = max(peaks)
    # messages in info (a verdict reads them there too), scalars where the result keeps its
    # scalars: the evaluate summary (and its headline), else the detail's info
    info = {**result.info, **notes, "slot_contact": record}
    files = {**result.files, "overload.csv": _csv(record)}
    if result.summary:
        head = (*result.headline, *values) if result.headline else ()
        return replace(result, summary={**result.summary, **values}, info=info, files=files,
                       headline=head)  # fmt: skip
    return replace(result, info={**info, **values}, files=files)
