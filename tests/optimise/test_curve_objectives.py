"""The curve kinds' scores moved to optimise/curve_objectives.py: objective and constraint rows
of the constant-force beam, the rows its checks compare at, and the threshold spring's rows."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.curve_metrics import curve_metrics
from flexopt.optimise.curve_objectives import (
    check_rows,
    compared_over,
    force_band_constraints,
    force_band_metrics,
    force_band_objective,
    force_band_ratio,
    plane_stress_force_column,
    plane_stress_peak_figures,
    threshold_constraints,
)

# A force curve that rises to 1.5 N at 5 mm and holds it to the end of a 30 mm drive (the 2 %
# band starts at 1.47 N, 4.9 mm).
STROKE = np.linspace(0.0, 30.0, 31)
FORCE = np.minimum(STROKE * 0.3, 1.5)
STRESS = STROKE * 1.0  # MPa, reaches 20 MPa at 20 mm


def _m(allowable=100.0):
    return curve_metrics(STROKE, FORCE, STRESS, 1.5, 0.02, allowable, 10)


def test_objectives_and_constraints_of_both_objectives():
    m = _m()
    assert force_band_objective("rms_error", m, 30.0, 1.5) == m.rms_error_N
    window = force_band_objective("operative_stroke", m, 30.0, 1.5)
    assert window == pytest.approx(-m.operative_stroke_mm + 30.0 * m.rms_error_N / 1.5)
    assert m.operative_stroke_mm == pytest.approx(25.1)
    (g,) = force_band_constraints("rms_error", m, 100.0, 1.0, 0.0)
    assert g == pytest.approx(30.0 / 100.0 - 1.0)  # the whole drive's peak
    g = force_band_constraints("operative_stroke", m, 100.0, 1.1, 27.0)
    assert g[0] == pytest.approx(m.window_peak_stress_MPa * 1.1 / 100.0 - 1.0)
    assert g[1] == pytest.approx(27.0 - m.operative_stroke_mm)
    metrics = force_band_metrics(m)
    assert metrics["operative_start_mm"] == pytest.approx(4.9)
    assert metrics["operative_end_mm"] == pytest.approx(30.0)


def test_compared_over_falls_back_to_the_whole_drive_for_a_short_window():
    assert compared_over(_m(), 30.0) == pytest.approx((4.9, 30.0))
    short = curve_metrics(STROKE, FORCE, STRESS, 1.5, 0.02, 7.0, 10)  # stress stops it at 7 mm
    assert short.operative_stroke_mm < 7.5
    assert compared_over(short, 30.0) == (0.0, 30.0)


def test_check_rows_spread_over_the_window_and_keep_the_peak_stress_row():
    converged = np.ones(STROKE.size, bool)
    peak = np.zeros(STROKE.size)
    peak[3] = 50.0  # the worst row lies outside the window: it is checked all the same
    rows = check_rows(STROKE, converged, peak, 10.0, 20.0, 4)
    assert rows.tolist() == [3, 12, 15, 17, 20]  # 12.5 and 17.5 mm: a tie takes the first row
    converged[3] = False  # an unconverged row's stress does not count
    assert 3 not in check_rows(STROKE, converged, peak, 10.0, 20.0, 4)


def test_plane_stress_figures_need_every_checked_stroke_converged():
    check = {
        "stroke_mm": [10.0, 20.0],
        "converged": [True, True],
        "relative_difference": [0.1, 0.2],
        "plane_stress_peak_nodal_von_mises_MPa": [30.0, 40.0],
    }
    assert plane_stress_peak_figures(check) == {"plane_stress_peak_stress_MPa": 40.0}
    table = {"displacement_mm": STROKE, "force_N": FORCE}
    column = plane_stress_force_column(table, check)
    assert column[15] == pytest.approx(FORCE[15] * 1.15) and column[0] == FORCE[0] * 1.1
    check["converged"] = [True, False]
    assert plane_stress_peak_figures(check) == {}
    assert plane_stress_force_column(table, check) is None


def test_threshold_constraint_rows():
    g = threshold_constraints(0.07, 0.05, 30.0, 40.0, 25.0, (2.0, 20.0), np.array([-1.0, 0.5]))
    assert g == pytest.approx([0.02, -0.25, 5.0, -23.0, -1.0, 0.5])


def test_force_band_ratio_is_the_worst_judged_row_over_the_held_share():
    """By hand on FORCE (0.3 N/mm to 1.5 N at 5 mm, then flat): judged from 1 mm the worst row
    is 1 mm at 0.3 N, 1.2 N off; from 5 mm every row is on target; the band of 0.03 N held at
    80 % is 0.024 N; the row is the excess over it as a fraction of 1.5 N."""
    assert force_band_ratio(STROKE, FORCE, 1.5, 0.02, 1.0) == pytest.approx((1.2 - 0.024) / 1.5)
    assert force_band_ratio(STROKE, FORCE, 1.5, 0.02, 5.0) == pytest.approx(-0.024 / 1.5)
    assert force_band_ratio(STROKE, FORCE, 1.5, 0.02, 4.0, share=1.0) == pytest.approx(
        (0.3 - 0.03) / 1.5
    )
    bumped = FORCE.copy()
    bumped[-1] = 1.53  # 0.03 N over at the last row: on the band's edge, beyond 80 % of it
    assert force_band_ratio(STROKE, bumped, 1.5, 0.02, 5.0, share=1.0) == pytest.approx(0.0)
    assert force_band_ratio(STROKE, bumped, 1.5, 0.02, 5.0) == pytest.approx(0.006 / 1.5)
    nan = FORCE.copy()
    nan[10] = np.nan
    assert force_band_ratio(STROKE, nan, 1.5, 0.02, 5.0) > 1e9  # as a failed design
    assert force_band_ratio(STROKE, FORCE, 1.5, 0.02, 31.0) > 1e9  # no row to judge


def test_force_band_ratio_lets_a_far_design_be_off_by_reach_times_its_rms():
    """Above 0.024 N / 3 = 0.008 N of RMS error the worst row may be 3 x the RMS error off: an
    RMS error of 0.1 N allows 0.3 N, so the 1 mm row (1.2 N off) exceeds it by 0.9 N, and the
    4 mm row (0.3 N off) sits on it; below 0.008 N the band alone."""
    assert force_band_ratio(STROKE, FORCE, 1.5, 0.02, 1.0, rms_error_N=0.1) == pytest.approx(
        0.9 / 1.5
    )
    assert force_band_ratio(STROKE, FORCE, 1.5, 0.02, 4.0, rms_error_N=0.1) == pytest.approx(0.0)
    for rms in (0.0, 0.005, 0.008):
        assert force_band_ratio(STROKE, FORCE, 1.5, 0.02, 4.0, rms_error_N=rms) == pytest.approx(
            (0.3 - 0.024) / 1.5
        )
