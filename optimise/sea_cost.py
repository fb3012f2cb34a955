"""The SEA spring's scoring (paper 004; the ``sea_spring`` study kind).

Moved here from ``pipeline/studies/sea_spring.py`` unchanged in its numbers:

- :func:`screening_plan` — the screening stage's runs: an orthogonal array and extra rows.
- :func:`taguchi_analysis` — the screening stage's Eq. 27 cost over an L25 array, its S/N
  analysis (pooled ANOVA, main effects, predicted optimum), the confirmation run and the
  additivity check; :func:`stage1_summary` the part a report shows.
- :func:`spring_scores` — the optimiser's objectives, constraints (``g <= 0``) and metrics of
  one solved design.
- :func:`solid_3d_scalars` — the 3D check's scalars the verdict judges.
- :func:`evaluation_summary` — the scalars ``flexopt evaluate`` records of one solved design;
  :func:`detail_values` the figures a report shows of it (stiffness per volume, mass, the
  linear-vs-nonlinear comparison, paper 004's Table 1 beside it).

Units: N m, N m/rad, MPa, mm, g, degrees as named.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from flexopt.fea.sea_design import published_comparison
from flexopt.fea.spring_analysis import SpringResponse
from flexopt.geometry.sea_spring import SpringGeometry

__all__ = [
    "EQ27",
    "detail_values",
    "evaluation_summary",
    "levels_to_values",
    "screening_plan",
    "solid_3d_scalars",
    "spring_scores",
    "stage1_summary",
    "taguchi_analysis",
]

#: The screening cost as the report states it (paper 004, Eq. 27).
EQ27 = "C = 0.5 sigma/max(sigma) + 0.5 |theta_T - theta|/max|theta_T - theta| (Eq. 27)"

#: One screening run: (stiffness N m/rad, peak stress per radian MPa/rad, why it failed or "").
Run = tuple[float, float, str]


def levels_to_values(
    levels: np.ndarray | Sequence[int], table: dict[str, tuple[float, ...]]
) -> dict[str, float]:
    """The factor values of a row of level indices (``table``: factor -> its level values)."""
    return {n: float(table[n][int(lv)]) for n, lv in zip(table, levels, strict=True)}


def screening_plan(
    table: dict[str, tuple[float, ...]], extra_runs: int, seed: int
) -> tuple[Any, np.ndarray, list[tuple[int, ...]]]:
    """The runs of the screening stage over the factors of ``table`` (five levels each).

    Returns
    -------
    (lay, extra, jobs) — the smallest catalogued array (:func:`optimise.taguchi.select_array`;
    L25 for six factors), the (extra_runs, n_factors) level rows off the array for the
    additivity check (drawn with ``seed`` before any result is known, so they can be solved
    beside the array), and every run's level tuple, the array's rows first.
    """
    from flexopt.optimise.taguchi import select_array

    lay = select_array({n: len(v) for n, v in table.items()})
    rng = np.random.default_rng(seed)
    extra = rng.integers(0, 5, size=(extra_runs, len(table)))
    jobs = [tuple(int(v) for v in row) for row in (*lay.design, *extra)]
    return lay, extra, jobs


def taguchi_analysis(
    lay: Any,
    table: dict[str, tuple[float, ...]],
    runs: list[Run],
    extra: np.ndarray,
    confirm_run: Callable[[tuple[int, ...]], Run],
    extra_runs: Callable[[], list[Run]],
    torque_Nm: float,
    theta_t_deg: float,
    pool_below_percent: float,
    min_error_dof: int,
    topology: str,
) -> dict[str, Any]:
    """The screening stage's analysis (paper 004 section 5, Tables 6-8) of the array's runs.

    Each run is linear: the screening torque ``torque_Nm`` gives ``theta = T / K`` and
    ``sigma = sigma'(theta)`` (``runs``: one :data:`Run` per row of ``lay.design``). Cost
    ``C = 0.5 sigma / max sigma + 0.5 |theta_T - theta| / max |theta_T - theta|`` (Eq. 27, each
    term divided by its largest value over the array; a run that cannot be built keeps the array
    balanced with the worst observed values), S/N smaller-the-better, pooled ANOVA. Then
    ``confirm_run(best_levels)`` is solved, and only after it ``extra_runs()`` (the (e, 6)
    ``extra`` level rows off the array, solved meanwhile elsewhere) for the additivity check.

    Returns
    -------
    dict
        Plain data: the runs (levels, values, theta, sigma, C, S/N), the pooled ANOVA, the best
        levels and predicted S/N, the confirmation, the additivity check and the chosen design
        (``chosen``: the better of the confirmed optimum and the best tested run).
    """
    from flexopt.optimise.taguchi import Pool, analyse, confirm

    k = np.array([r[0] for r in runs])
    sig_per_rad = np.array([r[1] for r in runs])
    theta = np.degrees(torque_Nm / k)
    sigma = sig_per_rad * np.radians(theta)
    failed = ~np.isfinite(theta)
    theta_err = np.abs(theta - theta_t_deg)
    if failed.any():
        theta_err[failed] = np.nanmax(theta_err)
        sigma[failed] = np.nanmax(sigma)
    s_max, e_max = float(sigma.max()), float(theta_err.max())

    def cost(sig: float, err: float) -> float:
        # Eq. 27 on values divided by their largest over the array (positive, so S/N is finite)
        return 0.5 * sig / s_max + 0.5 * err / e_max

    C = np.array([cost(s, e) for s, e in zip(sigma, theta_err, strict=True)])
    kw = dict(factor_names=lay.factor_names, columns=lay.columns)
    result = analyse(
        lay.array,
        C,
        "smaller",
        pool=Pool(below_percent=pool_below_percent, min_error_dof=min_error_dof),
        **kw,
    )
    best = tuple(int(v) for v in result.best_levels)

    def measure(run: Run) -> tuple[float, float, float, float]:
        kk, sp, _ = run
        if not math.isfinite(kk):
            return math.nan, math.nan, math.nan, float(C.max())
        th = math.degrees(torque_Nm / kk)
        sg = sp * math.radians(th)
        return kk, th, sg, cost(sg, abs(th - theta_t_deg))

    kb, thb, sgb, cb = measure(confirm_run(best))
    conf = confirm(result, responses=[cb])
    n_extra = len(extra)
    extra_c = np.array([measure(r)[3] for r in extra_runs()])
    additivity = (
        result.additivity(extra_levels=extra, extra_sn=-10.0 * np.log10(extra_c**2))
        if n_extra
        else result.additivity()
    )
    i_run = int(np.argmin(C))
    if cb <= C[i_run]:
        chosen_levels, chosen_from = best, "S/N optimum (confirmed run)"
    else:
        chosen_levels, chosen_from = tuple(int(v) for v in lay.design[i_run]), f"array run {i_run}"
    anova_rows = [
        {k2: (float(v) if isinstance(v, float | np.floating) else v) for k2, v in row.items()}
        for row in result.anova.rows()
    ]
    return {
        "array": lay.array_name,
        "topology": topology,
        "torque_Nm": torque_Nm,
        "target_rotation_deg": theta_t_deg,
        "cost": EQ27,
        "runs": {
            **{
                n: [float(table[n][lv]) for lv in lay.design[:, j]] for j, n in enumerate(table)
            },  # fmt: skip
            "stiffness_Nm_per_rad": k.tolist(),
            "rotation_deg": theta.tolist(),
            "stress_MPa": sigma.tolist(),
            "C": C.tolist(),
            "sn_dB": np.asarray(result.sn).tolist(),
            "failed": [r[2] for r in runs],
        },
        "anova": anova_rows,
        "main_effects": {
            me.name: {"levels": [float(v) for v in table[me.name]], "sn_dB": me.sn.tolist()}
            for me in result.main_effects
        },
        "best_levels": dict(zip(lay.factor_names, best, strict=True)),
        "best_values": levels_to_values(best, table),
        "predicted_sn_dB": float(result.predicted_sn),
        "confirmation": {
            "stiffness_Nm_per_rad": kb,
            "rotation_deg": thb,
            "stress_MPa": sgb,
            "C": cb,
            "measured_sn_dB": float(conf.measured_sn),
            "difference_dB": float(conf.difference),
            "half_width_dB": float(conf.half_width),
            "within": bool(conf.within),
        },
        "additivity": {
            "extra_levels": extra.tolist(),
            "extra_residuals_dB": np.asarray(additivity.extra_residuals).tolist(),
            "rms_extra_residual_dB": (
                float(np.sqrt(np.mean(np.square(additivity.extra_residuals)))) if n_extra else None
            ),
            "largest_pair": (
                f"{additivity.pairs[0].a}x{additivity.pairs[0].b}" if additivity.pairs else None
            ),
            "notes": list(additivity.notes),
        },
        "best_run": {
            "index": i_run,
            "C": float(C[i_run]),
            **levels_to_values(lay.design[i_run], table),
        },
        "chosen": {"from": chosen_from, **levels_to_values(chosen_levels, table)},
    }


def stage1_summary(stage1: dict[str, Any]) -> dict[str, Any]:
    """The entries of :func:`taguchi_analysis` (and its ``time_s``) a report shows."""
    keys = (
        "array", "topology", "torque_Nm", "target_rotation_deg", "cost", "runs", "anova",
        "main_effects", "best_values",
        "predicted_sn_dB", "confirmation", "additivity", "best_run", "chosen", "time_s",
    )  # fmt: skip
    return {k: stage1[k] for k in keys if k in stage1}


def spring_scores(
    r: SpringResponse,
    *,
    mass_g: float,
    st_mm: float,
    g_geo: np.ndarray,
    thinnest_index: int,
    min_feature_mm: float,
    target_Nm_per_rad: float,
    st_range_mm: tuple[float, float] | None,
    tolerance_percent: float,
    max_asymmetry_percent: float | None,
    min_slot_mm: float | None,
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Objectives, constraints and metrics of one solved spring (stage 2 of ``sea_spring``).

    Parameters
    ----------
    r : the response at the design thickness ``st_mm`` (mm); ``mass_g``: its mass, g.
    g_geo : (c,) float, mm — the geometric margins as ``g <= 0``; ``thinnest_index`` the row of
        the thinnest member's, ``min_feature_mm`` its limit (the member is ``-g + limit``).
    st_range_mm : (lower, upper) mm when ST is solved from the target (objectives stress and
        mass; constraints ST above and below its range); None when ST is a variable
        (objectives stress and the stiffness error ``|K/K_target - 1| 100``, constraint the
        error minus ``tolerance_percent``).
    max_asymmetry_percent, min_slot_mm : optional constraints on each direction's secant
        stiffness against their mean (percent) and the narrowest loaded slot (mm).

    Returns
    -------
    (f, g, metrics) — (2,) objectives (MPa, then g or percent), (c + 1..4,) constraints,
    the metrics by name (units in the names).
    """
    k_mean = r.mean_stiffness_Nm_per_rad
    err = abs(k_mean / target_Nm_per_rad - 1.0) * 100.0
    asym = abs(r.stiffness_Nm_per_rad / k_mean - 1.0) * 100.0
    peak = r.worst_peak_stress_MPa
    if st_range_mm is not None:
        f = np.array([peak, mass_g])
        g = np.append(g_geo, [st_mm - st_range_mm[1], st_range_mm[0] - st_mm])
    else:
        f = np.array([peak, err])
        g = np.append(g_geo, err - tolerance_percent)
    if max_asymmetry_percent is not None:
        g = np.append(g, asym - max_asymmetry_percent)
    deformed_gap = math.nan
    if r.slot_gaps_mm:
        # no slot found (inf) counts as plenty of room, kept finite for the optimiser
        deformed_gap = min(
            [min(v, 1e3) for k, v in r.slot_gaps_mm.items() if k != "undeformed"] or [1e3]
        )
    if min_slot_mm is not None:
        g = np.append(g, min_slot_mm - deformed_gap)
    # the thinnest printed size: the thinnest member (its margin + the limit) or the plate
    thinnest = float(-g_geo[thinnest_index]) + min_feature_mm
    metrics = {
        "ST_mm": st_mm,
        "min_feature_mm": min(thinnest, st_mm),
        "stiffness_Nm_per_rad": r.mean_stiffness_Nm_per_rad,
        "stiffness_ccw_Nm_per_rad": r.stiffness_Nm_per_rad,
        "stiffness_cw_Nm_per_rad": r.reverse_stiffness_Nm_per_rad,
        "asymmetry_percent": asym,
        "linear_stiffness_Nm_per_rad": r.linear_stiffness_Nm_per_rad,
        "torque_Nm": float(r.torque_Nm[-1]),
        "peak_stress_MPa": peak,
        "mass_g": mass_g,
        "n_dofs": r.n_dofs,
        "newton_iterations": r.iterations,
        "fe_time_s": r.solve_time_s,
        "deformed_slot_mm": deformed_gap,
    }
    return f, g, metrics


def solid_3d_scalars(s3: dict[str, Any]) -> dict[str, Any]:
    """The scalars of a 3D check (:func:`fea.sea_design.correct_3d`) the verdict judges."""
    keys = (
        "stiffness_ccw_3d_Nm_per_rad", "stiffness_cw_3d_Nm_per_rad", "peak_stress_3d_MPa",
        "stiffness_spread_3d_percent", "stiffness_ratio_3d_2d",
    )  # fmt: skip
    out = {k: s3[k] for k in keys if k in s3}
    if "ST_after_mm" in s3:
        out["ST_3d_mm"] = s3["ST_after_mm"]
    conv = s3.get("peak_convergence") or {}
    if "converged" in conv:
        out["peak_stress_converged"] = conv["converged"]
    if "peak_stress_2d_MPa" in conv:  # the 2D peak refined on the exported outline (MPa)
        out["peak_stress_2d_refined_MPa"] = conv["peak_stress_2d_MPa"]
    return out


def evaluation_summary(
    r: SpringResponse,
    *,
    st_mm: float,
    mass_g: float,
    outer_diameter_mm: float,
    thinnest_mm: float,
    target_Nm_per_rad: float,
    yield_MPa: float,
    allowable_MPa: float,
) -> dict[str, Any]:
    """The scalars ``flexopt evaluate`` records of one solved spring (units in the names).

    Parameters
    ----------
    r : the response at the plate thickness ``st_mm`` (mm); ``mass_g`` its mass, g;
        ``outer_diameter_mm`` its built outline's, mm.
    thinnest_mm : the thinnest member, mm (the printed size is it or the plate, the smaller).
    target_Nm_per_rad : the stiffness target; ``yield_MPa``, ``allowable_MPa`` the stress
        the ratios are of, MPa.
    """
    k_mean = r.mean_stiffness_Nm_per_rad
    summary = {
        "ST_mm": st_mm,
        "stiffness_Nm_per_rad": k_mean,
        "stiffness_ccw_Nm_per_rad": r.stiffness_Nm_per_rad,
        "stiffness_cw_Nm_per_rad": r.reverse_stiffness_Nm_per_rad,
        "linear_stiffness_Nm_per_rad": r.linear_stiffness_Nm_per_rad,
        "stiffness_error_percent": (k_mean / target_Nm_per_rad - 1) * 100,
        "asymmetry_percent": abs(r.stiffness_Nm_per_rad / k_mean - 1) * 100,
        "peak_stress_MPa": r.worst_peak_stress_MPa,
        "stress_yield_ratio": r.worst_peak_stress_MPa / yield_MPa,
        "stress_allowable_ratio": r.worst_peak_stress_MPa / allowable_MPa,
        "mass_g": mass_g,
        "outer_diameter_mm": outer_diameter_mm,
        # the thinnest printed size: the thinnest member or the plate (as flexopt run's metric)
        "min_feature_mm": min(thinnest_mm, st_mm),
    }
    if r.slot_gaps_mm:
        summary["slot_mm"] = r.slot_gaps_mm["undeformed"]
        summary["deformed_slot_mm"] = min(v for k, v in r.slot_gaps_mm.items() if k != "undeformed")
    return summary


def detail_values(
    r: SpringResponse,
    small: SpringResponse,
    geom: SpringGeometry,
    *,
    thickness_mm: float,
    density_kg_m3: float,
    target_Nm_per_rad: float,
    torque_Nm: float,
    allowable_MPa: float,
    envelope_diameter_mm: float,
) -> dict[str, Any]:
    """The figures a report shows of one solved spring (units in the names).

    Parameters
    ----------
    r : the response at the design rotation and the plate thickness ``thickness_mm`` (mm);
        ``small`` the same design's at 1 degree (the linear-vs-nonlinear row).
    geom : the built spring (outline, volume mm^3, checks); ``density_kg_m3`` its material's.
    target_Nm_per_rad, torque_Nm, allowable_MPa : the study's target, design torque and
        allowable stress; ``envelope_diameter_mm`` the disc the spring fits (the per-disc
        figures of paper 004's Table 1 are of that disc, ``thickness_mm`` thick).
    """
    volume = geom.volume_mm3
    mass = geom.mass_kg(density_kg_m3)
    disc_cm3 = math.pi * (0.5 * envelope_diameter_mm) ** 2 * thickness_mm
    disc_cm3 *= 1e-3
    k_mean = r.mean_stiffness_Nm_per_rad
    return {
        "stiffness_Nm_per_rad": k_mean,
        "stiffness_ccw_Nm_per_rad": r.stiffness_Nm_per_rad,
        "stiffness_cw_Nm_per_rad": r.reverse_stiffness_Nm_per_rad,
        "stiffness_error_percent": (k_mean / target_Nm_per_rad - 1) * 100,
        "peak_stress_MPa": r.worst_peak_stress_MPa,
        "peak_stress_ccw_xy_mm": r.peak_stress_xy_mm[-1].tolist(),
        "allowable_stress_MPa": allowable_MPa,
        "stress_ok": bool(r.worst_peak_stress_MPa <= allowable_MPa),
        "linear_vs_nonlinear": {
            "at_1_deg_percent": (small.stiffness_Nm_per_rad / small.linear_stiffness_Nm_per_rad - 1)
            * 100,
            "at_design_percent": (r.stiffness_Nm_per_rad / r.linear_stiffness_Nm_per_rad - 1) * 100,
        },  # fmt: skip
        "outer_diameter_mm": 2 * geom.checks["outer_radius_mm"],
        "thickness_mm": thickness_mm,
        "mass_g": mass * 1e3,
        "volume_mm3": volume,
        "stiffness_per_volume_Nm_per_rad_cm3": k_mean / (volume * 1e-3),
        "stiffness_per_disc_volume_Nm_per_rad_cm3": k_mean / disc_cm3,
        "torque_per_disc_volume_Nm_per_cm3": torque_Nm / disc_cm3,
        "max_torque_per_mass_Nm_per_kg": torque_Nm / mass,
        "checks": geom.checks,
        "slot_gaps_mm": r.slot_gaps_mm,
        "mesh": {"dofs": r.n_dofs, "triangles": r.n_triangles},
        "published_springs": published_comparison(),
    }
