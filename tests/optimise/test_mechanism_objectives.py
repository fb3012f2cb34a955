"""optimise/mechanism_objectives.py on hand-made columns: the statistics a metric is named by,
the objectives of a target band, the no-interference verdict and the constraint rows."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.optimise.evaluation import INFEASIBLE_VALUE
from flexopt.optimise.mechanism_objectives import (
    constraint_rows,
    curves_table,
    interference_verdict,
    objective_name,
    statistic,
    target_objective,
)
from flexopt.optimise.requirements import TargetBand
from flexopt.optimise.targets import ConstantTarget


def test_statistics_over_the_finite_rows():
    y = np.array([0.0, 2.0, 1.0, 3.0, np.nan])
    assert statistic(y, "max") == 3.0
    assert statistic(y, "first_peak") == 2.0  # the snap-through force
    assert statistic(y, "end") is None  # the last row did not converge
    assert statistic(y, "start") == 0.0
    assert statistic(np.array([-4.0, 1.0]), "max_abs") == 4.0
    assert statistic(np.array([np.nan]), "mean") is None


def _band(**kw) -> TargetBand:
    return TargetBand("force_N", "flat", x="displacement_mm", target=ConstantTarget("force", 1.0),
                      tolerance=0.1, **kw)  # fmt: skip


def test_a_curve_on_its_target_has_no_error_and_holds_the_band_throughout():
    x = np.linspace(0.0, 2.0, 21)
    y = np.ones_like(x)
    assert target_objective(_band(), x, y, "target_error") == pytest.approx(0.0, abs=1e-12)
    assert target_objective(_band(), x, y, "band_stroke") == pytest.approx(-2.0)
    off = target_objective(_band(), x, y + 0.5, "target_error")
    assert off == pytest.approx(0.5)
    assert target_objective(_band(over=(0.0, 3.0)), x, y, "target_error") == INFEASIBLE_VALUE
    assert target_objective(_band(), None, y, "target_error") == INFEASIBLE_VALUE


def test_objective_names_carry_the_unit():
    labels = {"flat": _band()}
    assert objective_name("minimise", "mass_g", labels) == "mass_g"
    assert objective_name("maximise", "width_mm", labels) == "negative_width_mm"
    assert objective_name("target_error", "flat", labels) == "flat_rms_error_N"
    assert objective_name("band_stroke", "flat", labels) == "negative_flat_band_stroke_mm"


def test_interference_is_not_met_and_pushes_the_constraint_row_up():
    clear = {"min_clearance_mm": 0.4, "clearance_at": "row 3", "interference_at": ""}
    ok = interference_verdict({"interference_mm2": 0.0}, clear)
    assert ok.met and "0.4 mm at row 3" in ok.detail
    hit = interference_verdict({"interference_mm2": 2.0}, {**clear, "interference_at": "row 5"})
    assert not hit.met and hit.detail.startswith("row 5")
    assert constraint_rows([], [], {"interference_mm2": 0.0, "min_clearance_mm": 0.4}) == [-0.4]
    assert constraint_rows([], [], {"interference_mm2": 2.0, "min_clearance_mm": 0.0}) == [2.0]


def test_curves_are_prefixed_by_case_and_blank_where_not_converged():
    table = {"step": np.arange(2), "converged": np.array([True, False]),
             "stable": np.ones(2, bool), "force_N": np.array([1.0, 2.0])}  # fmt: skip
    out = curves_table({"a": table}, {"a": "a."})
    assert set(out) == {"a.force_N"}
    assert out["a.force_N"][0] == 1.0 and math.isnan(out["a.force_N"][1])
