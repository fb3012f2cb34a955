"""The curved-arm (spiral) spring generator: centreline, band, checks, fillets, symmetry, solid."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.geometry.arm_spring import (
    SPIRAL_BOUNDS,
    SPIRAL_LEVELS,
    SPIRAL_VARIABLES,
    ArmSpringParams,
    arm_centreline,
    arm_clearances,
    build_arm_spring,
    spiral_level_values,
    spiral_params,
)
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.sea_spring import SpringFrame
from flexopt.geometry.solid import extrude
from shapely import affinity
from shapely.geometry import Polygon

FRAME = SpringFrame()
SPIRAL = {"sweep": 300.0, "R_pad": 30.0, "F1": 1 / 3, "F2": 0.5,
          "W1": 2.5, "W2": 2.0, "W3": 2.0, "W4": 2.5, "ST": 12.0}  # fmt: skip


def test_centreline_of_a_circular_arc_has_the_arc_length_and_band_area():
    # constant radius: the centreline is an arc of length R beta, a uniform band of width w
    # around it is an annular sector of area (R + w/2)^2 - (R - w/2)^2) beta / 2 = w R beta
    r, beta, w = 20.0, 120.0, 1.5
    p = ArmSpringParams((r, r, r), (0.0, beta / 2, beta), (w,), 5.0, n_arms=1)
    xy, width = arm_centreline(p, max_step_mm=0.2)
    assert np.allclose(np.hypot(*xy.T), r, atol=1e-12)
    length = np.sum(np.hypot(*np.diff(xy, axis=0).T))
    assert length == pytest.approx(r * math.radians(beta), rel=2e-5)
    assert np.allclose(width, w)
    from flexopt.geometry.arm_spring import _band

    assert _band(xy, width).area == pytest.approx(w * r * math.radians(beta), rel=1e-4)


def test_spiral_radius_passes_its_control_points_and_grows():
    p = spiral_params(SPIRAL, 4, FRAME)
    assert p.radii_mm[0] == pytest.approx(FRAME.hub_radius_mm - 0.5 * SPIRAL["W1"] - 1.0)
    assert p.radii_mm[-1] == pytest.approx(SPIRAL["R_pad"])
    xy, w = arm_centreline(p)
    r = np.hypot(*xy.T)
    assert np.all(np.diff(r) > 0)  # PCHIP of increasing values increases
    phi = np.unwrap(np.arctan2(xy[:, 1], xy[:, 0]))
    assert phi[-1] - phi[0] == pytest.approx(math.radians(SPIRAL["sweep"]), rel=1e-9)
    assert w[0] == pytest.approx(SPIRAL["W1"]) and w[-1] == pytest.approx(SPIRAL["W4"])


@pytest.mark.parametrize("n_arms", [3, 4])
def test_spiral_spring_is_one_valid_polygon_with_n_fold_symmetry(n_arms):
    g = build_arm_spring(spiral_params(SPIRAL, n_arms, FRAME), FRAME)
    assert isinstance(g.outline, Polygon) and g.outline.is_valid
    # bore, hub holes (as many as asked, whatever the arm count) and pad holes
    assert len(g.outline.interiors) == 1 + FRAME.hub_holes + n_arms
    assert len(g.fe_outline.interiors) == 0
    assert g.checks["outer_radius_mm"] <= FRAME.envelope_radius_mm
    assert min(arm_clearances(g.params, FRAME).values()) >= 0
    turned = affinity.rotate(g.fe_outline, 360.0 / n_arms, origin=(0, 0))
    assert turned.symmetric_difference(g.fe_outline).area < 1e-3 * g.fe_outline.area
    assert g.fe_outline.buffer(1e-6).contains(g.hub_region)
    assert all(g.fe_outline.buffer(1e-6).contains(pad) for pad in g.pad_region.geoms)
    assert len(g.pad_centres_mm) == n_arms
    assert np.allclose(np.hypot(*g.pad_centres_mm.T), SPIRAL["R_pad"])


def test_checks_fail_with_the_fix_named():
    with pytest.raises(GeometryError, match="envelope_mm"):
        build_arm_spring(spiral_params({**SPIRAL, "R_pad": 34.0}, 4, FRAME), FRAME)
    with pytest.raises(GeometryError, match="slot_mm.*fewer arms"):
        build_arm_spring(spiral_params({**SPIRAL, "sweep": 450.0, "W2": 5.0}, 6, FRAME), FRAME)
    strict = SpringFrame(min_feature_mm=2.2)
    with pytest.raises(GeometryError, match="thinnest_mm"):
        build_arm_spring(spiral_params(SPIRAL, 4, strict), strict)
    with pytest.raises(GeometryError, match="F1"):
        spiral_params({**SPIRAL, "F1": 1.2}, 4, FRAME)
    with pytest.raises(GeometryError, match="same number"):
        ArmSpringParams((8.0, 20.0), (0.0,), (2.0,), 10.0)


def test_slot_margin_is_the_gap_between_neighbouring_arms():
    # Archimedean spiral, uniform width: neighbouring arms are (R_pad - r0) * pitch / sweep
    # apart radially; the pads (radius 3.5) come closer to the next arm than that.
    v = {**SPIRAL, "W1": 2.0, "W2": 2.0, "W3": 2.0, "W4": 2.0}
    p = spiral_params(v, 4, FRAME, root_fillet_mm=0.0)
    gap = arm_clearances(p, FRAME)["slot_mm"] + FRAME.min_slot_mm
    pitch = (v["R_pad"] - p.radii_mm[0]) * 90.0 / v["sweep"]
    assert 0 < gap < pitch - v["W1"]


def test_root_fillets_add_material_only_at_the_hub_and_pads():
    sharp = build_arm_spring(spiral_params(SPIRAL, 4, FRAME, root_fillet_mm=0.0), FRAME)
    round_ = build_arm_spring(spiral_params(SPIRAL, 4, FRAME, root_fillet_mm=1.5), FRAME)
    added = round_.fe_outline.difference(sharp.fe_outline)
    assert added.area > 4 * 1.5**2 * (1 - math.pi / 4)  # at least a right-angle fillet per arm
    # every added piece touches the hub rim or a pad boss
    near = sharp.boundaries["hub"].buffer(0.5).union(sharp.boundaries["pads"].buffer(0.5))
    # (up to the 2 um simplification of both outlines)
    assert added.difference(near.buffer(2 * 1.5)).area < 1e-3 * added.area


def test_solid_is_watertight_and_mass_is_area_times_thickness():
    g = build_arm_spring(spiral_params(SPIRAL, 4, FRAME), FRAME)
    mesh = extrude(g.outline, g.thickness_mm)
    assert mesh.is_watertight and mesh.body_count == 1
    assert mesh.volume == pytest.approx(g.volume_mm3, rel=1e-6)
    assert g.mass_kg(8000.0) == pytest.approx(g.volume_mm3 * 8e-6, rel=1e-12)


def test_mesh_regions_follow_the_arm_width():
    g = build_arm_spring(spiral_params(SPIRAL, 4, FRAME), FRAME)
    regions = g.mesh_regions(elements_through=2.0, max_mm=3.0)
    assert len(regions) == 4 * 12
    sizes = [s for _, s in regions]
    assert min(sizes) == pytest.approx(min(SPIRAL["W2"], SPIRAL["W3"]) / 2.0, rel=0.05)
    assert max(sizes) <= 3.0


def test_spiral_variables_levels_and_bounds_agree():
    assert set(SPIRAL_BOUNDS) == set(SPIRAL_VARIABLES)
    for name, levels in SPIRAL_LEVELS.items():
        assert len(levels) == 5 and list(levels) == sorted(levels), name
    v = spiral_level_values({k: lv[2] for k, lv in SPIRAL_LEVELS.items()})
    assert set(v) == set(SPIRAL_VARIABLES)
    for name in SPIRAL_VARIABLES:
        lo, hi = SPIRAL_BOUNDS[name]
        assert lo <= v[name] <= hi, name
