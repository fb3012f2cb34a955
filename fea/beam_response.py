"""A planar beam's response (:class:`fea.beam.BeamResponse`) as the ``polyline_beam`` study kind
reports it: its rows as named columns (:func:`response_table`), whether the path it traced stayed
on stable equilibria (:func:`stability_summary`), and its scalar figures over the converged rows
(:func:`summarise`: maxima, the initial stiffness, the beam's volume and mass), and, when it was
traced against rigid stops (:func:`fea.stops.solve_with_stops`), each stop's contact force, gap
and contact flag as columns and their figures (:func:`contact_summary`).

Units: mm, N, N·mm, deg (the end rotation's column), MPa, mm³, g.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from flexopt.fea.beam import BeamResponse
from flexopt.fea.materials import Material
from flexopt.geometry.profile import BeamProfile

__all__ = ["contact_summary", "response_table", "stability_summary", "summarise"]


def response_table(response: BeamResponse) -> dict[str, np.ndarray]:
    """The response as named columns, one row per requested step (row 0 undeformed).

    Returns
    -------
    dict of str to (steps + 1,) array
        ``step, displacement_mm, force_N, transverse_displacement_mm, transverse_force_N,
        moment_Nmm, end_rotation_deg, peak_stress_MPa, peak_stress_s_mm, iterations, converged,
        stable`` (``stable`` false on a row past a bifurcation or limit point: not a safe state);
        with stops (``response.contact`` set) also, per stop ``<name>``,
        ``<name>_contact_force_N`` (N, the magnitude of the force the stop exerts on the beam;
        0 when clear), ``<name>_gap_mm`` (mm, clearance > 0, penetration < 0) and
        ``<name>_in_contact`` (bool); NaN / false on rows that did not converge.
    """
    n = len(response.displacement_mm)
    stable = (
        np.ones(n, dtype=bool)
        if response.stable is None
        else np.asarray(response.stable, dtype=bool)
    )
    return {
        "step": np.arange(n),
        "displacement_mm": np.asarray(response.displacement_mm, dtype=float),
        "force_N": np.asarray(response.force_N, dtype=float),
        "transverse_displacement_mm": np.asarray(response.transverse_displacement_mm, dtype=float),
        "transverse_force_N": np.asarray(response.transverse_force_N, dtype=float),
        "moment_Nmm": np.asarray(response.moment_Nmm, dtype=float),
        "end_rotation_deg": np.degrees(np.asarray(response.end_rotation_rad, dtype=float)),
        "peak_stress_MPa": np.asarray(response.peak_stress_MPa, dtype=float),
        "peak_stress_s_mm": np.asarray(response.peak_stress_s_mm, dtype=float),
        "iterations": np.asarray(response.iterations, dtype=int),
        "converged": np.asarray(response.converged, dtype=bool),
        "stable": stable,
    } | _contact_columns(response)


def _contact_columns(response: BeamResponse) -> dict[str, np.ndarray]:
    """The per-stop columns of :func:`response_table` (empty without stops)."""
    contact = getattr(response, "contact", None)
    if contact is None:
        return {}
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(contact.names):
        out[f"{name}_contact_force_N"] = np.asarray(contact.force_N[:, j], dtype=float)
        out[f"{name}_gap_mm"] = np.asarray(contact.gap_mm[:, j], dtype=float)
        out[f"{name}_in_contact"] = np.asarray(contact.in_contact[:, j], dtype=bool)
    return out


def contact_summary(response: BeamResponse, control: str) -> dict[str, Any]:
    """The contact figures of a response traced against rigid stops (empty without stops).

    Parameters
    ----------
    response : traced by :func:`fea.stops.solve_with_stops` (``response.contact`` set).
    control : the drive's control, ``displacement`` or ``force`` (names the driven value).

    Returns
    -------
    dict
        ``first_contact_displacement_mm`` (or ``first_contact_force_N`` under force control):
        the driven value at which the first stop closes (``ContactResponse.closing_value``,
        None when none closes); per stop ``<name>_first_contact_...``,
        ``<name>_max_contact_force_N`` (N) and ``<name>_min_gap_mm`` (mm);
        ``max_contact_force_N`` (N, over every stop and converged row); ``max_penetration_mm``
        (mm, >= 0); ``contact_penetration_tolerance_mm`` (mm); ``contact_penetration_ok``
        (bool); ``contact_penalty_factor`` (the one used, after any raise) and
        ``contact_penalty_raises`` (int); ``contact_rows`` (rows in contact);
        ``contact_message`` (why not ok; empty when ok).
    """
    contact = getattr(response, "contact", None)
    if contact is None:
        return {}
    driven = (
        "first_contact_displacement_mm" if control == "displacement" else "first_contact_force_N"
    )
    unit = driven.removeprefix("first_contact_")
    ok = np.asarray(response.converged, dtype=bool)
    closing = np.asarray(contact.closing_value, dtype=float)
    out: dict[str, Any] = {}
    for j, name in enumerate(contact.names):
        force = np.asarray(contact.force_N[ok, j], dtype=float)
        gap = np.asarray(contact.gap_mm[ok, j], dtype=float)
        out[f"{name}_first_contact_{unit}"] = float(closing[j]) if np.isfinite(closing[j]) else None
        out[f"{name}_max_contact_force_N"] = float(np.nanmax(force)) if force.size else None
        out[f"{name}_min_gap_mm"] = float(np.nanmin(gap)) if np.isfinite(gap).any() else None
    finite = closing[np.isfinite(closing)]
    # the first stop to close along the drive: the smallest |driven value| (the drive is monotone
    # in its direction, and the driven value is measured along it)
    out[driven] = float(finite[np.argmin(np.abs(finite))]) if finite.size else None
    forces = np.asarray(contact.force_N, dtype=float)[ok]
    out["max_contact_force_N"] = float(np.nanmax(forces)) if np.isfinite(forces).any() else 0.0
    pen = np.asarray(contact.max_penetration_mm, dtype=float)[ok]
    out["max_penetration_mm"] = float(pen.max()) if pen.size else 0.0
    out["contact_penetration_tolerance_mm"] = float(contact.extra.get("tolerance_mm", math.nan))
    out["contact_penetration_ok"] = bool(contact.penetration_ok)
    out["contact_penalty_factor"] = contact.extra.get("penalty_factor")
    out["contact_penalty_raises"] = contact.extra.get("raises")
    out["contact_rows"] = int(np.sum(np.asarray(contact.rows_in_contact, dtype=bool) & ok))
    out["contact_message"] = contact.message
    return out


def _max_abs(values: np.ndarray) -> float | None:
    finite = values[np.isfinite(values)]
    return float(np.max(np.abs(finite))) if finite.size else None


def stability_summary(response: BeamResponse) -> dict[str, Any]:
    """Whether the traced path stayed on stable equilibria (see :class:`fea.beam.BeamResponse`).

    Returns
    -------
    dict
        ``stable`` (bool): no converged row passed a bifurcation or limit point (every row's
        constrained tangent is positive definite); ``unstable_rows`` (int): converged rows that
        are not stable; ``first_unstable_step`` (int or None); ``unstable_message`` (str): the
        solver's message naming the step and the driven value where stability was lost, empty
        when stable. A response that was not assessed (``stable`` None) counts as stable.
    """
    if response.stable is None:
        return {
            "stable": True,
            "unstable_rows": 0,
            "first_unstable_step": None,
            "unstable_message": "",
        }
    bad = np.flatnonzero(np.asarray(response.converged, bool) & ~np.asarray(response.stable, bool))
    return {
        "stable": bool(bad.size == 0 and not response.unstable),
        "unstable_rows": int(bad.size),
        "first_unstable_step": int(bad[0]) if bad.size else None,
        "unstable_message": response.unstable_message,
    }


def summarise(
    table: dict[str, np.ndarray], material: Material, profile: BeamProfile
) -> dict[str, Any]:
    """Scalar metrics of a response table, over its converged rows.

    Returns
    -------
    dict
        Maxima of |force| (N), |displacement| (mm), |moment| (N mm), |end rotation| (deg) and peak
        stress (MPa, with where and when), stress/yield ratio, initial stiffness (N/mm, from the
        first step), rows converged, Newton iterations, length (mm), volume (mm^3), mass (g).
        The stability keys come from :func:`stability_summary` (``evaluate`` adds them).
    """
    ok = table["converged"]
    rows = {key: np.asarray(col)[ok] for key, col in table.items()}
    stress = rows["peak_stress_MPa"]
    i_peak = int(np.nanargmax(stress)) if np.isfinite(stress).any() else None
    peak = float(stress[i_peak]) if i_peak is not None else None

    stiffness = None
    if ok.size > 1 and ok[0] and ok[1]:
        du = table["displacement_mm"][1] - table["displacement_mm"][0]
        if abs(du) > 0:
            stiffness = float((table["force_N"][1] - table["force_N"][0]) / du)

    seg = profile.segment_lengths_mm
    t = profile.thickness_mm
    volume = float(np.sum(0.5 * (t[:-1] + t[1:]) * seg) * profile.width_mm)
    density = material.density_kg_m3
    return {
        "rows_converged": int(ok.sum()),
        "rows": int(ok.size),
        "max_abs_force_N": _max_abs(rows["force_N"]),
        "max_abs_displacement_mm": _max_abs(rows["displacement_mm"]),
        "initial_stiffness_N_per_mm": stiffness,
        "max_abs_transverse_force_N": _max_abs(rows["transverse_force_N"]),
        "max_abs_moment_Nmm": _max_abs(rows["moment_Nmm"]),
        "max_abs_end_rotation_deg": _max_abs(rows["end_rotation_deg"]),
        "max_peak_stress_MPa": peak,
        "max_peak_stress_s_mm": None if i_peak is None else float(rows["peak_stress_s_mm"][i_peak]),
        "max_peak_stress_step": None if i_peak is None else int(rows["step"][i_peak]),
        "yield_MPa": material.yield_MPa,
        "stress_yield_ratio": peak / material.yield_MPa if peak is not None else None,
        "total_iterations": int(np.sum(table["iterations"])),
        "length_mm": profile.length_mm,
        "volume_mm3": volume,
        "mass_g": volume * density * 1e-6 if math.isfinite(density) else None,
    }
