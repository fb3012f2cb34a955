"""fea/flexure_design.py: the pivot types by the shared variables, the closed-form seed, the
figures at the range of motion and the report table."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.closed_forms import pivot_closed_form
from flexopt.fea.flexure_design import (
    BEAM_TYPES,
    PIVOT_TYPES,
    closed_form_seed,
    flexure_of_type,
    pivot_at_range,
    pivot_table,
)
from flexopt.fea.materials import Material
from flexopt.fea.pivot import beam_pivot
from flexopt.geometry.errors import GeometryError

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)


def test_each_type_reads_the_shared_variables_as_its_table_says():
    f = {k: flexure_of_type(k, 10.0, 1.0, 0.5, 6.0, 5.0) for k in PIVOT_TYPES}
    assert f["leaf"].length_mm == 10.0 and f["leaf"].thickness_mm == 1.0
    assert f["variable_leaf"].end_thickness_mm == pytest.approx(2.0)  # t (1 + 2 shape)
    assert f["circular_notch"].radius_mm == 5.0  # length = 2R
    assert f["elliptical_notch"].half_length_mm == 5.0
    assert f["elliptical_notch"].depth_mm == pytest.approx(0.25 * 5.0 * 8.0**0.5)
    r = 5.0 * (0.1 + 0.8 * 0.5)
    assert f["corner_filleted"].fillet_radius_mm == pytest.approx(r)
    assert f["corner_filleted"].length_mm == pytest.approx(10.0 - 2 * r)
    assert all(x.width_mm == 6.0 for x in f.values())
    # the shape is clipped to [0, 1]
    assert flexure_of_type("variable_leaf", 10.0, 1.0, 3.0, 6.0, 5.0).end_thickness_mm == 3.0
    with pytest.raises(GeometryError, match="unknown pivot type"):
        flexure_of_type("hinge", 10.0, 1.0, 0.5, 6.0, 5.0)


def test_closed_form_seed_meets_the_target_inside_the_envelope():
    def build(length: float, t: float, s: float):
        return flexure_of_type("circular_notch", length, t, s, 6.0, 5.0)

    lower, upper = np.array([0.0, 2.0, 0.8, 0.0]), np.array([1.0, 30.0, 3.2, 1.0])
    seed = closed_form_seed(build, MAT.E_MPa, 300.0, 50.0, math.radians(15), lower, upper, 40, 20)
    assert seed is not None
    length, t, s = seed
    K = pivot_closed_form(build(length, t, s), MAT.E_MPa).stiffness_Nmm_per_rad
    assert K == pytest.approx(300.0, rel=1e-4)
    assert lower[2] <= t <= upper[2]
    # a target no length in the bounds reaches: no seed
    assert closed_form_seed(build, MAT.E_MPa, 1e9, 50.0, 0.2, lower, upper, 40, 20) is None


def test_pivot_at_range_by_closed_form_and_by_beam():
    notch = flexure_of_type("circular_notch", 8.0, 1.0, 0.5, 6.0, 5.0)
    cf = pivot_closed_form(notch, MAT.E_MPa)
    at = pivot_at_range(notch, MAT, 0.2, 3, 40, beam_model=False, trace_centre_shift=False)
    assert at.model == "closed form" and not at.failure
    assert at.stiffness_Nmm_per_rad == cf.stiffness_Nmm_per_rad
    assert at.stress_MPa == float(cf.stress_MPa(0.2)) and math.isnan(at.centre_shift_mm)
    traced = pivot_at_range(notch, MAT, 0.2, 3, 40, beam_model=False, trace_centre_shift=True)
    assert np.isfinite(traced.centre_shift_mm)
    leaf = flexure_of_type("leaf", 10.0, 1.0, 0.5, 6.0, 5.0)
    assert "leaf" in BEAM_TYPES
    at = pivot_at_range(leaf, MAT, 0.2, 3, 40, beam_model=True, trace_centre_shift=False)
    res = beam_pivot(leaf, MAT, 0.2, 3, n_elements=40)
    assert at.model == "beam" and not at.failure
    assert at.stiffness_Nmm_per_rad == res.small_angle_stiffness_Nmm_per_rad
    assert at.centre_shift_mm == float(res.centre_shift_mm[-1])
    # a leaf under a pure moment: K = E I / L
    assert at.stiffness_Nmm_per_rad == pytest.approx(MAT.E_MPa * 6.0 / 12.0 / 10.0, rel=1e-6)


def test_pivot_table_rows_and_the_notch_stress_concentration():
    notch = flexure_of_type("circular_notch", 8.0, 1.0, 0.5, 6.0, 5.0)
    cf = pivot_closed_form(notch, MAT.E_MPa)
    res = beam_pivot(notch, MAT, 0.2, 4, n_elements=40)
    table = pivot_table(res, cf)
    n = res.rotation_rad.size
    assert all(np.shape(v) == (n,) for v in table.values())
    assert np.allclose(table["peak_stress_MPa"], res.peak_stress_MPa * cf.stress_concentration)
    assert table["secant_stiffness_Nmm_per_rad"][0] == res.small_angle_stiffness_Nmm_per_rad
    assert table["stable"].dtype == bool
