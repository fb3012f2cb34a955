"""The constant-force beam filleted into its pads (geometry/constant_force.py filleted_beam and
outline's pad_fillet_mm): sharp = today's beam, the flare's thickness on the arcs, the shoulder's
Kt from the Roark/Peterson fit written out here, and the outline's area against the exact area
of the fillets' chord polygons."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.geometry.constant_force import (
    TABLE3_OPTIMUM,
    ConstantForceDesign,
    beam_profile,
    centreline_points,
    filleted_beam,
    flared_ends,
    flared_thickness,
    outline,
)
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.mechanism import FILLET_CHORDS


def roark_kt(D: float, d: float, r: float) -> float:
    """Roark 7th ed. Table 17.1, square shoulder with fillet, in-plane bending (h/r in [0.1, 2]
    and [2, 20]), evaluated independently of geometry.mechanism."""
    h = (D - d) / 2
    q = h / r
    if q <= 2:
        c1 = 1.007 + 1.000 * math.sqrt(q) - 0.031 * q
        c2 = -0.270 - 2.404 * math.sqrt(q) + 0.749 * q
        c3 = 0.677 + 1.133 * math.sqrt(q) - 0.904 * q
        c4 = -0.414 + 0.271 * math.sqrt(q) + 0.186 * q
    else:
        c1 = 1.042 + 0.982 * math.sqrt(q) - 0.036 * q
        c2 = -3.599 + 1.619 * math.sqrt(q) - 0.431 * q
        c3 = 6.084 - 5.607 * math.sqrt(q) + 1.158 * q
        c4 = -2.527 + 3.006 * math.sqrt(q) - 0.691 * q
    x = 2 * h / D
    return c1 + c2 * x + c3 * x**2 + c4 * x**3


def test_sharp_is_the_beam_and_outline_of_today():
    made = filleted_beam(TABLE3_OPTIMUM)
    profile = beam_profile(TABLE3_OPTIMUM)
    assert np.array_equal(made.shape.points_mm, profile.points_mm)
    assert np.array_equal(made.shape.thickness_mm, profile.thickness_mm)
    assert made.start.kt == made.end.kt == 1.0 and made.start.root_mm == made.end.root_mm == 0
    assert outline(TABLE3_OPTIMUM).equals_exact(outline(TABLE3_OPTIMUM, pad_fillet_mm=0.0), 0)


@pytest.mark.parametrize("r", [0.2, 0.5, 1.0])
def test_flare_thickness_follows_the_arcs_and_kt_the_fit(r):
    d = TABLE3_OPTIMUM
    made = filleted_beam(d, pad_fillet_mm=r)
    p, t = made.shape.points_mm, made.shape.thickness_mm
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    # the centreline is today's: every vertex kept, points only added on it
    ref = centreline_points(d)
    for v in ref:
        assert np.min(np.linalg.norm(p - v, axis=1)) < 1e-12
    ref_s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ref, axis=0), axis=1))])
    own = np.interp(s, ref_s, d.vertex_thickness_mm)
    for end, t_end, s_end in ((made.start, d.T1, s), (made.end, d.T6, s[-1] - s)):
        assert end.fillet_mm == end.root_mm == r
        assert end.kt == pytest.approx(roark_kt(4.0, t_end, r), rel=1e-12)
        psi = np.linspace(0, np.pi / 2, FILLET_CHORDS + 1)
        for a in psi:  # every chord end of the arc is a point with the arc's height
            k = int(np.argmin(np.abs(s_end - r * (1 - np.cos(a)))))
            assert s_end[k] == pytest.approx(r * (1 - np.cos(a)), abs=1e-9)
            assert t[k] - own[k] == pytest.approx(2 * r * (1 - np.sin(a)), abs=1e-9)
    between = (s > r + 1e-9) & (s[-1] - s > r + 1e-9)  # outside both flares: the beam's own t
    assert t[between] == pytest.approx(own[between], abs=1e-12)
    # the arc's shoulder ends on the pad's edge only when r is the shoulder height
    assert t[0] == pytest.approx(d.T1 + 2 * r)


def test_fillet_capped_at_the_shoulder_height():
    d = TABLE3_OPTIMUM
    made = filleted_beam(d, pad_thickness_mm=4.0, pad_fillet_mm=5.0)
    assert made.start.fillet_mm == pytest.approx((4.0 - d.T1) / 2)
    assert made.end.fillet_mm == pytest.approx((4.0 - d.T6) / 2)
    assert made.shape.thickness_mm[0] == pytest.approx(4.0)
    shape = outline(d, pad_fillet_mm=5.0)
    assert shape.is_valid


@pytest.mark.parametrize("r", [0.5, 1.0])
def test_outline_area_adds_the_chord_polygons_of_four_fillets(r):
    # each fillet adds the square r x r minus the quarter disc, plus the n circular segments
    # between the arc and its chords: r^2 (1 - pi/4) + n r^2 (theta - sin theta) / 2
    n = FILLET_CHORDS
    theta = np.pi / 2 / n
    one = r * r * (1 - np.pi / 4) + n * r * r * (theta - np.sin(theta)) / 2
    added = outline(TABLE3_OPTIMUM, pad_fillet_mm=r).area - outline(TABLE3_OPTIMUM).area
    # the centreline kinks by a few mrad inside the flare: a second-order error in the offsets
    assert added == pytest.approx(4 * one, abs=1e-4)


def test_negative_radius_refused():
    with pytest.raises(GeometryError, match="pad_fillet_mm"):
        filleted_beam(TABLE3_OPTIMUM, pad_fillet_mm=-0.1)


def test_no_micro_edge_where_a_toe_meets_a_vertex():
    # the shipped example's design (pipeline/examples/constant-force.yaml): with r at the
    # shoulder height its S6 toe fell 3 um from p10, a notch in the outline
    d = ConstantForceDesign(
        a=np.array([0.159, 0.8071, 0.5057, 0.8453, 0.133, 0.8451, 0.4573, 0.7743, 0.2115, 0.8743]),
        t=np.array([1.059, 0.8668, 0.966, 0.8001, 0.8003, 0.8275, 0.8367, 0.9738, 0.9394, 1.049]),
        T1=1.371,
        T6=1.278,
        B=6.826,
    )
    made = filleted_beam(d, pad_fillet_mm=2.0)
    p10 = centreline_points(d)[-2]
    toe = made.end.root_mm
    assert abs(np.linalg.norm(p10 - centreline_points(d)[-1]) - toe) < 0.02  # the case at hand
    ring = np.asarray(outline(d, pad_fillet_mm=2.0).exterior.coords)
    assert np.min(np.linalg.norm(np.diff(ring, axis=0), axis=1)) > 0.01
    seg = np.linalg.norm(np.diff(made.shape.points_mm, axis=0), axis=1)
    assert seg.min() > 0.01


@pytest.mark.parametrize("radii", [(0.5, 0.5), (1.361, 0.3), (0.0, 0.7), (0.4, 0.0)])
def test_many_thicknesses_flared_at_once_are_each_flared_alone(radii):
    """flared_thickness (the flared profile's derivatives by t1..t10 redraw it with 20 thickness
    vectors on one centreline) gives, row by row, flared_ends' points and thicknesses bit for
    bit, with one end sharp or both flared."""
    pts = centreline_points(TABLE3_OPTIMUM)
    rng = np.random.default_rng(2)
    many = TABLE3_OPTIMUM.vertex_thickness_mm + 0.1 * rng.random((5, 12))
    points, thick = flared_thickness(pts, many, *radii)
    assert thick.shape[0] == 5
    for row, t in zip(thick, many, strict=True):
        one_pts, one_t = flared_ends(pts, t, *radii)
        assert np.array_equal(points, one_pts)
        assert np.array_equal(row, one_t)
