"""The one plot vocabulary (pipeline/plot_targets.py's plot_spec): the old names a plugin may give
are read as the new ones, in one place."""

from __future__ import annotations

import numpy as np
from flexopt.pipeline.plot_targets import (
    OLD_PLOT_KEYS,
    PLOT_DEFAULTS,
    plot_spec,
    response_column,
    target_overlay,
)


def test_old_names_are_read_as_the_one_vocabulary():
    old = {
        "x": "rotation_deg",
        "left": "torque_Nm",
        "right": "peak_stress_MPa",
        "xlabel": "rotation (deg)",
        "left_label": "torque (N m)",
        "right_label": "stress (MPa)",
        "left_title": "torque",
        "right_title": "stress",
        "allowable_MPa": 40.0,
        "target": 1.0,
    }
    assert plot_spec(old) == {
        "x": "rotation_deg",
        "y": "torque_Nm",
        "stress": "peak_stress_MPa",
        "x_label": "rotation (deg)",
        "y_label": "torque (N m)",
        "stress_label": "stress (MPa)",
        "y_title": "torque",
        "stress_title": "stress",
        "allowable_MPa": 40.0,
        "target": 1.0,
    }
    assert not set(plot_spec(old)) & set(OLD_PLOT_KEYS)
    assert "left" in old  # the input is not changed


def test_the_new_name_wins_and_the_columns_have_defaults():
    assert plot_spec({"y": "force_N", "left": "other_N", "ylabel": "a", "y_label": "b"}) == {
        "y": "force_N",
        "y_label": "b",
        "x": "displacement_mm",
        "stress": "peak_stress_MPa",
    }
    assert plot_spec(None) == dict(PLOT_DEFAULTS)
    # a column given as None is none (no stress panel), not the default
    assert plot_spec({"right": None})["stress"] is None


def test_a_target_is_drawn_on_the_response_column_of_either_vocabulary():
    table = {"d_mm": np.array([0.0, 1.0, 2.0]), "f_N": np.array([0.0, 1.0, 2.0])}
    for spec in (
        {"x": "d_mm", "y": "f_N", "target": 1.0},
        {"x": "d_mm", "left": "f_N", "target": 1.0},
    ):
        assert response_column(spec) == "f_N"
        overlay = target_overlay(spec, table)
        assert overlay is not None and overlay.column == "f_N"
        np.testing.assert_array_equal(overlay.x, [0.0, 2.0])
