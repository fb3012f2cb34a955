"""optimise.sea_cost: the SEA spring's scoring moved out of the sea_spring kind (the Eq. 27
screening analysis, the stage-2 objectives and constraints, the 3D scalars)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.spring_analysis import SpringResponse
from flexopt.optimise.sea_cost import (
    levels_to_values,
    screening_plan,
    solid_3d_scalars,
    spring_scores,
    stage1_summary,
    taguchi_analysis,
)

LEVELS = {n: tuple(float(10 * i + j) for j in range(5)) for i, n in enumerate("ABCDEF")}


def _response(k_ccw: float, k_cw: float | None, gaps: dict | None = None) -> SpringResponse:
    rot = np.array([0.0, 11.0])
    return SpringResponse(
        rotation_deg=rot, torque_Nm=np.array([0.0, 53.0]), peak_stress_MPa=np.array([0.0, 700.0]),
        peak_stress_xy_mm=np.zeros((2, 2)), linear_stiffness_Nm_per_rad=280.0,
        stiffness_Nm_per_rad=k_ccw, linear_peak_stress_MPa=690.0, ok=True, message="",
        n_dofs=10, n_triangles=5, iterations=3, solve_time_s=0.1,
        reverse_torque_Nm=None if k_cw is None else np.array([0.0, 50.0]),
        reverse_peak_stress_MPa=None if k_cw is None else np.array([0.0, 750.0]),
        reverse_stiffness_Nm_per_rad=math.nan if k_cw is None else k_cw, slot_gaps_mm=gaps,
    )  # fmt: skip


def _scores(r: SpringResponse, **kw):
    args = dict(mass_g=40.0, st_mm=12.0, g_geo=np.array([-1.0, -0.3, -0.2, -2.0]),
                thinnest_index=1, min_feature_mm=0.5, target_Nm_per_rad=275.0,
                st_range_mm=(8.0, 20.0), tolerance_percent=2.0, max_asymmetry_percent=None,
                min_slot_mm=None)  # fmt: skip
    return spring_scores(r, **{**args, **kw})


def test_solved_thickness_objectives_stress_and_mass_constraints_the_st_range():
    f, g, m = _scores(_response(270.0, 280.0))
    assert f.tolist() == [750.0, 40.0]  # the worse direction's peak
    assert g.tolist() == [-1.0, -0.3, -0.2, -2.0, 12.0 - 20.0, 8.0 - 12.0]
    assert m["stiffness_Nm_per_rad"] == 275.0 and m["asymmetry_percent"] == pytest.approx(
        100 * 5 / 275
    )
    assert m["min_feature_mm"] == 0.3 + 0.5  # the member, thinner than the plate
    assert math.isnan(m["deformed_slot_mm"])


def test_searched_thickness_objective_the_stiffness_error_and_the_optional_constraints():
    gaps = {"undeformed": 0.8, "ccw": 0.5, "cw": math.inf}
    f, g, m = _scores(_response(280.5, None, gaps), st_range_mm=None, max_asymmetry_percent=1.0,
                      min_slot_mm=0.2)  # fmt: skip
    err = abs(280.5 / 275.0 - 1.0) * 100.0
    assert f.tolist() == [700.0, err]
    assert g[4:].tolist() == [err - 2.0, 0.0 - 1.0, 0.2 - 0.5]
    assert m["deformed_slot_mm"] == 0.5 and m["stiffness_cw_Nm_per_rad"] != 0  # nan: one way


def test_levels_to_values_and_summaries():
    assert levels_to_values((0, 4, 1, 0, 0, 2), LEVELS)["B"] == 14.0
    s3 = {"stiffness_ccw_3d_Nm_per_rad": 1.0, "ST_after_mm": 9.0, "checks": [],
          "peak_convergence": {"converged": True}}  # fmt: skip
    assert solid_3d_scalars(s3) == {"stiffness_ccw_3d_Nm_per_rad": 1.0, "ST_3d_mm": 9.0,
                                    "peak_stress_converged": True}  # fmt: skip
    assert stage1_summary({"array": "L25", "private": 1}) == {"array": "L25"}


def _run(levels) -> tuple[float, float, str]:
    """A made-up screening run: stiffness and stress per radian from the levels."""
    a, b, c, *_ = (int(v) for v in levels)
    if a == 4 and b == 4:
        return math.nan, math.nan, "cannot be built"
    return 100.0 + 40.0 * a + 5.0 * c, 2000.0 + 300.0 * b, ""


def test_taguchi_analysis_eq27_and_the_order_of_the_confirmation_and_extra_runs():
    lay, extra, jobs = screening_plan(LEVELS, 2, seed=1)
    assert lay.array_name.startswith("L25") and extra.shape == (2, 6) and len(jobs) == 27
    assert jobs[:25] == [tuple(int(v) for v in row) for row in lay.design]
    assert np.array_equal(screening_plan(LEVELS, 2, seed=1)[1], extra)  # drawn from the seed
    runs = [_run(row) for row in lay.design]
    extra = np.array([[1, 2, 3, 4, 0, 1], [4, 4, 0, 0, 0, 0]])
    order = []

    def confirm_run(levels):
        order.append("confirm")
        return _run(levels)

    def extra_runs():
        order.append("extra")
        return [_run(row) for row in extra]

    out = taguchi_analysis(lay, LEVELS, runs, extra, confirm_run, extra_runs, 10.0, 2.08, 5.0,
                           4, "spiral")  # fmt: skip
    assert order == ["confirm", "extra"]
    C = np.array(out["runs"]["C"])
    # each Eq. 27 term divided by its largest: C <= 1, and 1 only where both are largest
    assert np.all(C > 0) and np.all(C <= 1.0 + 1e-12)
    failed = [i for i, r in enumerate(runs) if r[2]]
    assert failed and all(out["runs"]["failed"][i] == "cannot be built" for i in failed)
    k = np.array([r[0] for r in runs])
    theta = np.degrees(10.0 / k)
    ok = np.isfinite(theta)
    sigma = np.array([r[1] for r in runs]) * np.radians(theta)
    err = np.abs(theta - 2.08)
    s_max, e_max = sigma[ok].max(), err[ok].max()
    i = int(np.flatnonzero(ok)[0])
    assert C[i] == pytest.approx(0.5 * sigma[i] / s_max + 0.5 * err[i] / e_max, rel=1e-14)
    assert out["topology"] == "spiral" and len(out["additivity"]["extra_residuals_dB"]) == 2
    assert set(out["chosen"]) == {"from", *LEVELS}
