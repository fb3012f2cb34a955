"""The arm spring's fillets on the fine outline (sampled by angle, issue 22) and at the envelope
(trimmed to it, the slits between pieces closed: issue 27's cliff)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.materials import get_material
from flexopt.fea.plane_stress import Clamp, Rotate
from flexopt.fea.solid3d import converge_peak_stress
from flexopt.geometry import arm_spring
from flexopt.geometry.arm_spring import (
    FINE_FILLET_STEP_DEG,
    arm_clearances,
    build_arm_spring,
    spiral_params,
)
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.sea_spring import SpringFrame
from shapely.geometry import Point

# the sea-spring example's frame (fillet_mm 0.3 at 4 segments, root fillets 1.5 mm)
FRAME = SpringFrame(fillet_mm=0.3, fillet_segments=4)
# sea-spring.yaml's recorded design (2 arms)
RECORDED = {"sweep": 479.8427, "R_pad": 32.0660, "F1": 0.4630, "F2": 0.5173, "W1": 5.1975,
            "W2": 3.8465, "W3": 4.4704, "W4": 2.8678, "ST": 19.1911}  # fmt: skip
# Pads on the 72 mm envelope (R_pad at its bound): random designs the generator refused before
# this change, 0.025-0.38 mm "beyond the envelope at a junction fillet" (n_arms, design).
AT_ENVELOPE = [
    (2, {"sweep": 334.9571, "R_pad": 32.5, "F1": 0.3477, "F2": 0.7545, "W1": 4.1325,
         "W2": 5.7954, "W3": 2.847, "W4": 3.7631, "ST": 15.1271}),
    (2, {"sweep": 386.5277, "R_pad": 32.5, "F1": 0.4668, "F2": 0.159, "W1": 2.232,
         "W2": 3.8719, "W3": 2.9709, "W4": 5.9601, "ST": 19.0849}),
    (3, {"sweep": 165.1758, "R_pad": 32.5, "F1": 0.2151, "F2": 0.5296, "W1": 3.2552,
         "W2": 5.7865, "W3": 5.7708, "W4": 4.9827, "ST": 16.0591}),
    (4, {"sweep": 178.0153, "R_pad": 32.5, "F1": 0.2283, "F2": 0.7869, "W1": 1.6338,
         "W2": 2.4838, "W3": 3.4642, "W4": 5.2473, "ST": 19.5828}),
    # a hybrid run's spring (an intermediate state of this change, issue 27), pads on the envelope
    (2, {"sweep": 453.9374082160497, "R_pad": 32.49999999448389, "F1": 0.5893750008821836,
         "F2": 0.4316122873356665, "W1": 4.421875000497162, "W2": 4.053925391198083,
         "W3": 4.259247503620234, "W4": 4.0781249995826645, "ST": 19.5}),
]  # fmt: skip


def _reentrant_turns_deg(outline) -> tuple[np.ndarray, np.ndarray]:
    """(v, 2) vertices of the outline's exterior and how far each turns back into the part
    (degrees, > 0 at a re-entrant vertex, < 0 at a convex one)."""
    ring = outline.exterior
    xy = np.asarray(ring.coords)[:-1]
    a, b = np.roll(xy, -1, axis=0) - xy, xy - np.roll(xy, 1, axis=0)
    turn = np.degrees(np.arctan2(b[:, 0] * a[:, 1] - b[:, 1] * a[:, 0], np.sum(a * b, axis=1)))
    # on a counter-clockwise exterior a left turn is convex
    return xy, (-turn if ring.is_ccw else turn)


def test_fine_outline_samples_the_root_fillets_by_angle():
    p = spiral_params(RECORDED, 2, FRAME, root_fillet_mm=1.5)
    coarse = build_arm_spring(p, FRAME)
    fine = build_arm_spring(p, FRAME, curve_step_mm=0.1)
    # the root fillets: where the arms leave the hub (r < hub + 2 root fillets)
    worst = {}
    for name, geom in (("coarse", coarse), ("fine", fine)):
        xy, turn = _reentrant_turns_deg(geom.fe_outline)
        root = np.hypot(xy[:, 0], xy[:, 1]) < FRAME.hub_radius_mm + 3.0
        worst[name] = float(turn[root].max())
    # the optimiser's outline keeps its facets (16 a quarter circle: 5.6 deg; the frame
    # fillets' 4: 22.5 deg), so its designs are what they were
    assert worst["coarse"] > 5.0
    # on the fine one every re-entrant vertex there turns by about the fine step at most (a
    # merged vertex of a union can add a few hundredths of a degree)
    assert worst["fine"] <= FINE_FILLET_STEP_DEG + 0.1, worst
    # and no slit between the unions' pieces is left on it (a vertex turning ~180 deg)
    _, turn = _reentrant_turns_deg(fine.fe_outline)
    assert np.abs(turn).max() < 150.0


@pytest.mark.parametrize("n_arms, values", AT_ENVELOPE)
@pytest.mark.parametrize("curve_step_mm", [None, 0.1])
def test_pads_on_the_envelope_build_inside_it_whatever_the_rounding(n_arms, values, curve_step_mm):
    # The envelope check is the design's (arm_clearances: arms and pads), not the rounding of
    # the fillet polygons: the design at 4 to 9 decimals builds, every time inside Ø72.
    for decimals in (4, 5, 6, 7, 8, 9):
        v = {k: round(x, decimals) for k, x in values.items()}
        p = spiral_params(v, n_arms, FRAME, root_fillet_mm=1.5)
        assert arm_clearances(p, FRAME)["envelope_mm"] >= -1e-9
        geom = build_arm_spring(p, FRAME, curve_step_mm=curve_step_mm)
        xy = np.asarray(geom.outline.exterior.coords)
        outer = float(np.hypot(xy[:, 0], xy[:, 1]).max())
        assert outer <= FRAME.envelope_radius_mm + 1e-9, (decimals, outer)
        assert geom.checks["envelope_mm"] >= -1e-9
        # the spring is whole: every arm, pad and hole still there
        # (the hub holes as many as asked, whatever the arm count)
        assert geom.outline.is_valid and len(geom.outline.interiors) == 1 + FRAME.hub_holes + n_arms


def test_a_pad_beyond_the_envelope_is_still_refused():
    n_arms, values = AT_ENVELOPE[0]
    p = spiral_params(dict(values, R_pad=32.6), n_arms, FRAME, root_fillet_mm=1.5)
    assert arm_clearances(p, FRAME)["envelope_mm"] == pytest.approx(-0.1, abs=1e-9)
    with pytest.raises(GeometryError, match="envelope_mm fails by 0.1 mm"):
        build_arm_spring(p, FRAME)


def _root_peaks(monkeypatch, step_deg: float, rounds: int) -> tuple[list[float], np.ndarray]:
    """The refined peak von Mises (MPa) of the fine outline near the hub (r <= 13 mm), linear,
    hub turned 11.04 deg, per round, and where the last one is (mm); the fillets sampled at
    ``step_deg`` degrees."""
    monkeypatch.setattr(arm_spring, "FINE_FILLET_STEP_DEG", step_deg)
    # the recorded design with a narrower root: its peak is at a root fillet
    values = dict(RECORDED, W1=3.0)
    p = spiral_params(values, 2, FRAME, root_fillet_mm=1.5)
    g = build_arm_spring(p, FRAME, curve_step_mm=0.1)
    away = Point(0.0, 0.0).buffer(60.0).difference(Point(0.0, 0.0).buffer(13.0, quad_segs=64))
    r = converge_peak_stress(
        g.fe_outline, values["ST"], get_material("maraging-300"), Clamp(g.pad_region),
        Rotate(g.hub_region, (0.0, 0.0), math.radians(11.04), 1), 3.0,
        refine=g.mesh_regions(1.0, 3.0),
        stress_ignore=g.hub_region.union(g.pad_region).buffer(0.05).union(away),
        kinematics="linear", min_rounds=rounds, max_rounds=rounds,
    )  # fmt: skip
    return r["peaks_MPa"], np.asarray(r["peak_xy_mm"])


@pytest.mark.slow
def test_the_refined_peak_at_a_root_fillet_converges_on_the_fine_outline(monkeypatch):
    # Four meshes, the element size at the peak halved each time (fea.solid3d).
    fine, xy = _root_peaks(monkeypatch, FINE_FILLET_STEP_DEG, 4)
    assert FRAME.hub_radius_mm < math.hypot(*xy) < FRAME.hub_radius_mm + 3.0  # at the root
    steps = [abs(b - a) / b for a, b in zip(fine[:-1], fine[1:], strict=True)]
    assert max(steps) < 0.005, (fine, steps)
    # The same outline with the optimiser's root fillets (16 segments a quarter circle, 5.6
    # deg facets): the peak at a facet vertex keeps rising by > 1 % a halving.
    coarse, xy = _root_peaks(monkeypatch, 90.0 / 16, 4)
    assert FRAME.hub_radius_mm < math.hypot(*xy) < FRAME.hub_radius_mm + 3.0
    steps_c = [(b - a) / b for a, b in zip(coarse[:-1], coarse[1:], strict=True)]
    assert min(steps_c) > 0.01, (coarse, steps_c)
    # both sequences start from the same part: their first meshes agree to 2 %
    assert fine[0] == pytest.approx(coarse[0], rel=0.02)
