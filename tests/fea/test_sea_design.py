"""fea.sea_design: the SEA spring's physics moved out of the sea_spring kind (the thickness from
the stiffness target, the screening seed and run, both topologies behind one interface)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from flexopt.fea.materials import Material
from flexopt.fea.sea_design import (
    PUBLISHED_SPRINGS,
    SpringTopology,
    build_any,
    published_comparison,
    screen_spring,
    solve_for_stiffness,
    spring_margins,
    taguchi_seed,
    worse_direction,
)
from flexopt.fea.spring_analysis import SpringMesh, SpringResponse, analyse_spring
from flexopt.geometry.arm_spring import SPIRAL_VARIABLES
from flexopt.geometry.sea_spring import TABLE6_LEVELS, SpringFrame, ga_variables

STEEL = Material("maraging-300", E_MPa=190_000.0, nu=0.3, yield_MPa=2000.0, density_kg_m3=8000.0)
COARSE = SpringMesh(max_edge_mm=8.0, elements_through=0.5)
FRAME = SpringFrame(fillet_mm=0.0, hub_holes=0, fillet_segments=1)
SPIRAL = SpringTopology("spiral", root_fillet_mm=0.0)


def _spiral_geometry():
    """A two-arm spiral at the middle of its bounds (mm, degrees)."""
    x = np.array([0.5 * (lo + hi) for lo, hi in (SPIRAL.bounds[n] for n in SPIRAL.variables)])
    return build_any(SPIRAL.params(x, 2, FRAME), FRAME)


def test_solve_for_stiffness_scales_the_thickness_and_a_held_one_wins():
    scale, st = solve_for_stiffness(10.0, 200.0, 275.0)
    assert scale == 275.0 / 200.0 and st == 10.0 * scale
    scale, st = solve_for_stiffness(10.0, 200.0, 275.0, held_thickness_mm=12.5)
    assert scale == 1.25 and st == 12.5


def test_the_solved_thickness_gives_the_target_stiffness():
    # plane stress under a driven rotation: torque proportional to ST, so one solve suffices
    geom = _spiral_geometry()
    theta = math.radians(11.0)
    r = analyse_spring(geom, STEEL, theta, COARSE, steps=1)
    assert r.ok, r.message
    scale, st = solve_for_stiffness(geom.thickness_mm, r.stiffness_Nm_per_rad, 275.0)
    again = analyse_spring(replace(geom, params=replace(geom.params, thickness_mm=st)), STEEL,
                           theta, COARSE, steps=1)  # fmt: skip
    assert again.stiffness_Nm_per_rad == pytest.approx(275.0, rel=1e-6)
    assert r.scaled(scale).stiffness_Nm_per_rad == pytest.approx(275.0, rel=1e-12)
    assert again.peak_stress_MPa[-1] == pytest.approx(r.peak_stress_MPa[-1], rel=1e-6)


def test_topologies_name_their_variables_bounds_and_constraints():
    serp = SpringTopology("serpentine", arcs=7)
    assert serp.variables == ga_variables(7) and set(serp.bounds) == set(serp.variables)
    assert SPIRAL.variables == SPIRAL_VARIABLES and set(SPIRAL.bounds) == set(SPIRAL_VARIABLES)
    assert SpringTopology().levels is TABLE6_LEVELS
    geom = _spiral_geometry()
    margins = spring_margins(geom.params, FRAME)
    assert set(SPIRAL.constraints) <= set(margins)


def test_taguchi_seed_is_a_full_vector_of_the_topology():
    chosen = {n: v[2] for n, v in TABLE6_LEVELS.items()}
    x = taguchi_seed(chosen, FRAME, n_arcs=5)
    assert x.shape == (len(ga_variables(5)),) and x[-1] == chosen["ST"]  # ST last, as given
    spiral_chosen = {n: v[2] for n, v in SPIRAL.levels.items()}
    assert taguchi_seed(spiral_chosen, FRAME, topology="spiral").shape == (len(SPIRAL_VARIABLES),)


def test_screen_spring_gives_linear_stiffness_and_stress_per_radian_or_the_reason():
    values = {n: v[2] for n, v in SPIRAL.levels.items()}
    k, s, why = screen_spring(values, SPIRAL, FRAME, STEEL, COARSE)
    assert why == "" and k > 0 and s > 0
    geom = build_any(SPIRAL.screen_params(values, FRAME), FRAME)
    r = analyse_spring(geom, STEEL, math.radians(1.0), COARSE, nonlinear=False)
    assert k == r.linear_stiffness_Nm_per_rad
    bad = {**values, "RP": 12.0}  # twelve arms leave no slot: not buildable
    k, s, why = screen_spring(bad, SPIRAL, FRAME, STEEL, COARSE)
    assert "slot_mm fails" in why and math.isnan(k) and math.isnan(s)


def _response(peak_ccw: float, peak_cw: float | None) -> SpringResponse:
    one = np.array([0.0, 1.0])
    return SpringResponse(
        rotation_deg=one, torque_Nm=one, peak_stress_MPa=np.array([0.0, peak_ccw]),
        peak_stress_xy_mm=np.zeros((2, 2)), linear_stiffness_Nm_per_rad=1.0,
        stiffness_Nm_per_rad=1.0, linear_peak_stress_MPa=1.0, ok=True, message="", n_dofs=1,
        n_triangles=1, iterations=1, solve_time_s=0.0,
        reverse_peak_stress_MPa=None if peak_cw is None else np.array([0.0, peak_cw]),
    )  # fmt: skip


def test_worse_direction():
    assert worse_direction(_response(10.0, None)) == 1.0
    assert worse_direction(_response(10.0, 11.0)) == -1.0
    assert worse_direction(_response(10.0, 10.0)) == 1.0


def test_published_comparison_per_disc_volume():
    rows = published_comparison()
    assert len(rows) == len(PUBLISHED_SPRINGS)
    t = next(r for r in rows if r["ref"].startswith("t "))
    vol_cm3 = math.pi * 45.0**2 * 11.0 * 1e-3
    assert t["stiffness_per_disc_volume_Nm_per_rad_cm3"] == pytest.approx(500.0 / vol_cm3)
    assert (
        next(r for r in rows if r["ref"].startswith("ch "))["torque_per_disc_volume_Nm_per_cm3"]
        is None
    )
