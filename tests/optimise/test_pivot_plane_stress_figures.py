"""The flexure pivot's plane-stress figures: the verdict judges the largest row's peak."""

from flexopt.optimise.joint_objectives import pivot_plane_stress_figures


def test_the_largest_row_is_judged_not_the_last():
    ps = {
        "ok": True,
        "linear_stiffness_Nmm_per_rad": 290.0,
        "peak_von_mises_at_range_MPa": 25.70,
        "peak_von_mises_by_row_MPa": [0.0, 12.0, 25.93, 25.70],
        "peak_von_mises_MPa": 25.93,
    }
    out = pivot_plane_stress_figures(ps)
    assert out["plane_stress_peak_stress_MPa"] == 25.93
    assert out["plane_stress_stiffness_Nmm_per_rad"] == 290.0


def test_a_solve_that_did_not_reach_the_range_gives_no_peak():
    ps = {"ok": False, "linear_stiffness_Nmm_per_rad": 290.0, "peak_von_mises_at_range_MPa": 9.0}
    assert "plane_stress_peak_stress_MPa" not in pivot_plane_stress_figures(ps)
