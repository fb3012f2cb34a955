"""fea/mechanism_design.py on hand-made responses: the width a force scales with, the columns
of a case (slopes, ratios, units, the width scale) and the width solved from a target.

The references are written out here (a force linear in the width, np.gradient of a line), never
taken from the functions' own output.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from flexopt.fea.mechanism_design import (
    OutputColumn,
    case_table,
    width_exponent,
    width_for_range,
    width_for_target,
)

READS = {
    "force_N": ("reaction", ()),
    "x_mm": ("displacement", ()),
    "k_N_per_mm": ("slope", ("force_N",)),
    "lever": ("ratio", ("force_N", "force_N")),
    "per_mm": ("ratio", ("force_N", "x_mm")),
    "a": ("slope", ("b",)),
    "b": ("slope", ("a",)),
}


@pytest.mark.parametrize(
    ("name", "power"),
    [("force_N", 1), ("x_mm", 0), ("k_N_per_mm", 1), ("lever", 0), ("per_mm", 1), ("a", 0)],
)
def test_each_output_scales_with_the_width_to_its_power(name, power):
    assert width_exponent(READS, name) == power


def _response(rows: int = 5):
    drive = np.linspace(0.0, 4.0, rows)  # mm
    return SimpleNamespace(
        drive=drive,
        outputs={
            "__drive_reaction": 3.0 * drive,  # N: 3 N/mm
            "turn_deg": np.radians(10.0) * drive,  # the solver's rad
        },
        peak_stress_MPa=np.column_stack([drive, 2.0 * drive]),  # (rows, 2 beams)
        converged=np.ones(rows, bool),
        stable=np.ones(rows, bool),
    )


def test_a_case_table_scales_forces_and_derives_slopes_and_ratios():
    columns = [
        OutputColumn("k_N_per_mm", "slope", ("f_N",), exponent=1),  # before what it reads
        OutputColumn("f_N", "reaction", exponent=1),
        OutputColumn("turn_deg", "rotation", degrees=True),
        OutputColumn("per_turn", "ratio", ("f_N", "turn_deg"), exponent=1),
    ]
    response = _response()
    response.outputs["f_N"] = 3.0 * response.drive
    table = case_table("displacement", columns, response, scale=2.0)
    drive = np.linspace(0.0, 4.0, 5)
    np.testing.assert_allclose(table["drive_mm"], drive)
    np.testing.assert_allclose(table["drive_reaction_N"], 6.0 * drive)  # twice as wide
    np.testing.assert_allclose(table["f_N"], 6.0 * drive)
    np.testing.assert_allclose(table["k_N_per_mm"], 6.0)
    np.testing.assert_allclose(table["turn_deg"], 10.0 * drive)
    np.testing.assert_allclose(table["per_turn"][1:], 0.6)
    assert math.isnan(table["per_turn"][0])  # 0 / 0
    np.testing.assert_allclose(table["peak_stress_MPa"], 2.0 * drive)  # the larger beam's


def test_a_force_drive_keeps_its_reaction_unscaled():
    table = case_table("force", [], _response(), scale=2.0)
    np.testing.assert_allclose(table["drive_reaction_N"], 3.0 * np.linspace(0.0, 4.0, 5))


def test_the_width_of_a_range_puts_the_value_in_its_middle():
    assert width_for_range("f_N", 2.0, 3.0, 5.0, 6.0) == (pytest.approx(12.0), "")
    width, why = width_for_range("f_N", None, 3.0, 5.0, 6.0)
    assert math.isnan(width) and "not computed" in why
    width, why = width_for_range("f_N", -2.0, 3.0, 5.0, 6.0)
    assert math.isnan(width) and "opposite sign" in why


@pytest.mark.parametrize("relative", [True, False])
def test_the_width_of_a_target_fits_the_curve(relative):
    x = np.linspace(0.0, 5.0, 11)
    y = 2.0 * x  # N at 4 mm wide; the target is twice that
    width, why = width_for_target("f_N", x, y, lambda s: 4.0 * s, None, relative, 4.0)
    assert why == "" and width == pytest.approx(8.0)
    width, why = width_for_target("f_N", x, -y, lambda s: 4.0 * s, None, relative, 4.0)
    assert math.isnan(width) and "wrong sign" in why
