"""optimise/joint_objectives.py: what the GA and the verdict see of a joint design."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.joint_objectives import (
    PivotLimits,
    leaf_joint_layout_constraints,
    leaf_joint_objective,
    leaf_joint_unreachable,
    pivot_objective,
    pivot_plane_stress_figures,
    plateau_mean_N,
)


def test_pivot_objective_rows_follow_the_constraint_names():
    limits = PivotLimits(300.0, 0.05, 50.0, 40.0, 20.0)
    assert limits.constraint_names == (
        "stiffness_band",
        "stress",
        "envelope_length",
        "envelope_height",
    )
    ratio, g = pivot_objective(limits, 330.0, 25.0, (20.0, 30.0), float("nan"))
    assert ratio == 0.5
    assert g == pytest.approx([0.1 - 0.05, -0.5, -0.5, 0.5])
    shifted = PivotLimits(300.0, 0.05, 50.0, 40.0, 20.0, max_centre_shift_mm=0.2)
    assert shifted.constraint_names[-1] == "centre_shift"
    _, g = pivot_objective(shifted, 300.0, 25.0, (20.0, 10.0), 0.1)
    assert g.shape == (5,) and g[-1] == pytest.approx(-0.5) and g[0] == pytest.approx(-0.05)


def test_pivot_plane_stress_figures_only_what_the_check_reached():
    ps = {"linear_stiffness_Nmm_per_rad": 310.0, "peak_von_mises_at_range_MPa": 40.0, "ok": True}
    assert pivot_plane_stress_figures(ps) == {
        "plane_stress_stiffness_Nmm_per_rad": 310.0,
        "plane_stress_peak_stress_MPa": 40.0,
    }
    assert pivot_plane_stress_figures({**ps, "ok": False}) == {
        "plane_stress_stiffness_Nmm_per_rad": 310.0
    }
    assert pivot_plane_stress_figures({"skipped": "no mesh"}) == {}


def test_leaf_joint_constraints_penalty_and_objective():
    g_len, g_hub = leaf_joint_layout_constraints(20.0, 40.0, 56.0, 10.0, 8.0)
    assert g_len == pytest.approx(-0.5) and g_hub == pytest.approx(48.0 / 56.0 - 1.0)
    f, g = leaf_joint_unreachable(-0.5, 0.25)
    assert f.tolist() == [10.25] and g.tolist() == [-0.5, 0.25, 10.25]
    ratio, g = leaf_joint_objective(300.0, 600.0, -0.5, -0.1)
    assert ratio == 0.5 and g.tolist() == [-0.5, -0.1, -0.5]


def test_plateau_mean_is_the_integral_of_the_piecewise_linear_curve():
    s = np.array([0.0, 1.0, 2.0, 4.0])
    f = np.array([0.0, 2.0, 2.0, 4.0])
    assert plateau_mean_N(s, f, 1.0, 2.0) == pytest.approx(2.0)
    # over [0.5, 3]: 0.5 * (1 + 2) / 2 + 1 * 2 + 1 * (2 + 3) / 2 = 5.25, over 2.5
    assert plateau_mean_N(s, f, 0.5, 3.0) == pytest.approx(5.25 / 2.5)
