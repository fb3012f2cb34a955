"""The outline of a generic mechanism: bands, pads, one body, printability and crossings."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.mechanism import (
    Attachment,
    BeamShape,
    BodyShape,
    beam_band,
    curve_points,
    end_pad,
    mechanism_outline,
)
from flexopt.geometry.solid import extrude, min_feature_mm


def _parallel_guide(t: float = 1.0, y: float = 10.0):
    beams = [
        BeamShape("upper", [[0, y], [40, y]], [t, t]),
        BeamShape("lower", [[0, -y], [40, -y]], [t, t]),
    ]
    bodies = [BodyShape("shuttle", [[40, -y - 3], [48, -y - 3], [48, y + 3], [40, y + 3]])]
    attachments = [
        Attachment("upper", "start", "ground"),
        Attachment("lower", "start", "ground"),
        Attachment("upper", "end", "shuttle"),
        Attachment("lower", "end", "shuttle"),
    ]
    return beams, bodies, attachments


def test_band_area_is_the_integral_of_the_thickness():
    # a tapered straight beam: area = L (t0 + t1) / 2 exactly
    band = beam_band(BeamShape("b", [[0, 0], [30, 0]], [1.0, 2.0]))
    assert band.area == pytest.approx(30 * 1.5, rel=1e-12)
    # a bent beam: the inner overlap and the outer disc wedge cancel to first order
    arc = curve_points([0, 0], [40, 0], "arc", 8.0, 81)
    band = beam_band(BeamShape("arc", arc, np.full(81, 1.0)))
    length = float(np.sum(np.hypot(*np.diff(arc, axis=0).T)))
    assert band.area == pytest.approx(length * 1.0, rel=2e-3)


def test_curve_points_shapes():
    cos = curve_points([0, 0], [50, 0], "cosine", 4.0, 51)
    assert cos[25] == pytest.approx([25.0, 4.0])
    assert cos[0] == pytest.approx([0, 0]) and cos[-1] == pytest.approx([50, 0])
    # slope zero at the clamped ends: the first-mode shape
    assert (cos[1, 1] - cos[0, 1]) / (cos[1, 0] - cos[0, 0]) == pytest.approx(0.0, abs=0.02)
    arc = curve_points([0, 0], [40, 0], "arc", -5.0, 41)
    radius = (25 + 400) / 10  # (h^2 + (c/2)^2) / 2h
    centre = np.array([20.0, -5.0 + radius])
    np.testing.assert_allclose(np.hypot(*(arc - centre).T), radius, rtol=1e-12)
    assert arc[20] == pytest.approx([20.0, -5.0])
    with pytest.raises(GeometryError, match="half circle"):
        curve_points([0, 0], [10, 0], "arc", 5.0)


def test_parallel_guide_is_one_printable_body():
    beams, bodies, attachments = _parallel_guide()
    out = mechanism_outline(beams, bodies, attachments, min_feature_mm=0.8)
    assert set(out.pads) == {"upper.start", "lower.start"}
    pad = end_pad(beams[0], "start", 6.0, 4.0)
    # the pad starts at the beam's end face (1 um of overlap, below any printer's resolution):
    # the printed leaf is as long as the analysed one
    assert pad.bounds == pytest.approx((-6.0, 8.0, 0.001, 12.0))
    # 8 fillets of r = 1 mm (a pad's shoulder is 1.5 mm, a body's unbounded): r^2 (1 - pi/4)
    # each, drawn with 6 chords, which add a circular segment r^2/2 (a - sin a), a = 15 deg, each
    r = 1.0
    a = math.radians(15.0)
    fillets = 8 * r**2 * (1 - math.pi / 4)
    # pads 6.001 x 4 mm less their 0.001 mm overlap with the flares, 3 mm wide there
    expected = 2 * 40 * 1.0 + 8 * 26 + 2 * (6.001 * 4 - 0.001 * 3) + fillets
    chords = 8 * 6 * 0.5 * r**2 * (a - math.sin(a))
    assert out.area_mm2 == pytest.approx(expected + chords, abs=1e-4)  # the 1e-6 mm grid
    for made in out.beams.values():
        assert made.start.fillet_mm == made.end.fillet_mm == 1.0
        assert made.start.clipped_mm == made.end.clipped_mm == 0.0
        # the flexible beam still runs from the pad's face to the body's edge
        assert made.shape.points_mm[[0, -1], 0] == pytest.approx([0.0, 40.0], abs=1e-12)
    mesh = extrude(out.polygon, 5.0)
    assert mesh.is_watertight and mesh.volume == pytest.approx(out.area_mm2 * 5.0, rel=1e-6)
    assert min_feature_mm(out.polygon) == pytest.approx(1.0, abs=0.02)


def test_a_beam_thinner_than_the_printable_minimum():
    beams, bodies, attachments = _parallel_guide(t=0.6)
    with pytest.raises(GeometryError, match=r"beam 'upper' is 0.6 mm thick at point \[0\]"):
        mechanism_outline(beams, bodies, attachments, min_feature_mm=0.8)


def test_crossing_beams_are_refused_joined_ends_are_not():
    beams = [
        BeamShape("a", [[0, 0], [40, 20]], [1, 1]),
        BeamShape("b", [[0, 20], [40, 0]], [1, 1]),
    ]
    attachments = [Attachment("a", "start", "ground"), Attachment("b", "start", "ground")]
    with pytest.raises(GeometryError, match=r"beams 'a' and 'b' cross or overlap near \(20"):
        mechanism_outline(beams, (), attachments)
    # a V of two beams joined end to end at an angle: overlap at the joint only
    beams = [
        BeamShape("a", [[0, 0], [20, 10]], [1, 1]),
        BeamShape("b", [[20, 10], [40, 0]], [1, 1]),
    ]
    attachments = [
        Attachment("a", "start", "ground"),
        Attachment("b", "start", "a.end"),
        Attachment("b", "end", "ground"),
    ]
    out = mechanism_outline(beams, (), attachments)
    assert out.polygon.is_valid


def test_a_part_in_pieces_names_them():
    beams, bodies, attachments = _parallel_guide()
    beams[1] = BeamShape("lower", [[0, -10], [35, -10]], [1, 1])  # stops short of the shuttle
    with pytest.raises(GeometryError, match=r"2 separate pieces: .*beam lower"):
        mechanism_outline(beams, bodies, attachments[:3])


def test_a_beam_through_a_body_it_is_not_attached_to():
    beams, bodies, attachments = _parallel_guide()
    beams.append(BeamShape("stray", [[30, 0], [60, 0]], [1, 1]))
    attachments.append(Attachment("stray", "start", "ground"))
    with pytest.raises(GeometryError, match="beam 'stray' runs into body 'shuttle'"):
        mechanism_outline(beams, bodies, attachments)


def test_a_sliver_wall_is_caught_by_the_thin_wall_test():
    beams, bodies, attachments = _parallel_guide()
    # a body with a 0.4 mm tab: no beam is thin, the outline is
    tab = [[40, -13], [48, -13], [48, 13], [44.2, 13], [44.2, 20], [43.8, 20], [43.8, 13], [40, 13]]
    with pytest.raises(GeometryError, match="thinner than the printable minimum 0.8"):
        mechanism_outline(beams, [BodyShape("shuttle", tab)], attachments, min_feature_mm=0.8)
    assert math.isfinite(mechanism_outline(beams, bodies, attachments).area_mm2)
