"""DXF of an outline (round trip, holes, units) and laying parts flat on the bed."""

from __future__ import annotations

import io
import sys

import ezdxf
import numpy as np
import pytest
from flexopt.geometry.dxf import HOLES_LAYER, INSUNITS_MM, OUTLINE_LAYER, dxf_bytes, dxf_polygon
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.solid import (
    FlatPart,
    StepUnavailable,
    extrude,
    flat_part,
    lay_flat,
    sheet_profile,
    step_bytes,
)
from shapely import affinity
from shapely.geometry import Point, Polygon, box


def plate_with_holes() -> Polygon:
    """40 x 10 mm plate with a square and a round hole."""
    return box(0, 0, 40, 10).difference(box(5, 3, 8, 6)).difference(Point(25, 5).buffer(2.5))


def test_round_trip_keeps_outline_holes_layers_and_mm():
    part = plate_with_holes()
    data = dxf_bytes(part, "a plate\nwith two holes")
    doc = ezdxf.read(io.StringIO(data.decode()))
    assert doc.units == INSUNITS_MM == 4 and doc.header["$MEASUREMENT"] == 1
    polylines = list(doc.modelspace().query("LWPOLYLINE"))
    assert all(p.closed for p in polylines)
    layers = sorted(p.dxf.layer for p in polylines)
    assert layers == [HOLES_LAYER, HOLES_LAYER, OUTLINE_LAYER]
    counts = sorted(len(p) for p in polylines)
    expected = sorted(len(r.coords) - 1 for r in (part.exterior, *part.interiors))
    assert counts == expected
    back = dxf_polygon(data)
    assert back.area == pytest.approx(part.area, rel=1e-12)
    assert len(back.interiors) == 2
    assert back.symmetric_difference(part).area < 1e-9


def test_bad_outlines_and_files_are_refused():
    with pytest.raises(GeometryError, match="valid"):
        dxf_bytes(Polygon())
    with pytest.raises(GeometryError, match="readable"):
        dxf_polygon(b"\xff\xfe not a dxf")
    doc = ezdxf.new("R2010")
    doc.units = 1  # inches
    stream = io.StringIO()
    doc.write(stream)
    with pytest.raises(GeometryError, match="INSUNITS"):
        dxf_polygon(stream.getvalue().encode())


def test_a_part_at_31_degrees_comes_back_aligned_with_its_footprint():
    tilted = affinity.rotate(plate_with_holes(), 31.0, origin=(7.0, -3.0))
    flat, angle, offset = lay_flat(tilted)
    assert angle == pytest.approx(-31.0, abs=1e-6)
    x0, y0, x1, y1 = flat.bounds
    assert (x0, y0) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert (x1, y1) == pytest.approx((40.0, 10.0), abs=1e-6)
    assert flat.area == pytest.approx(tilted.area) and len(flat.interiors) == 2
    again = affinity.translate(affinity.rotate(tilted, angle, origin=(0, 0)), *offset)
    assert again.symmetric_difference(flat).area < 1e-6  # the transform reported is the one made

    part = flat_part(tilted, 3.0)
    assert part.footprint_mm == pytest.approx((40.0, 10.0), abs=1e-6)
    assert part.thickness_mm == 3.0 and not part.sheet
    assert part.record()["footprint_mm"] == [40.0, 10.0]
    mesh = extrude(part.outline, part.thickness_mm)
    assert mesh.bounds[0] == pytest.approx([0, 0, 0], abs=1e-5)
    assert mesh.bounds[1] == pytest.approx([40, 10, 3], abs=1e-5)
    assert dxf_polygon(dxf_bytes(part.outline)).bounds == pytest.approx((0, 0, 40, 10), abs=1e-6)


def test_upright_and_round_parts_are_not_turned():
    flat, angle, _ = lay_flat(box(2, 3, 12, 40))  # taller than wide: stays as drawn
    assert angle == 0.0 and flat.bounds == (0.0, 0.0, 10.0, 37.0)
    disk = Point(5, 5).buffer(20.0, quad_segs=64)
    _, angle, _ = lay_flat(disk)
    assert angle == 0.0


def test_a_sheet_on_its_edge_becomes_its_flat_profile():
    # the leaf-spring joint's leaf: 68 mm long, 0.5 mm thick on edge, extruded by its 11 mm width
    edge = affinity.rotate(box(-10, -0.25, 58, 0.25), 12.0)
    profile, thickness = sheet_profile(edge, 11.0)
    assert thickness == pytest.approx(0.5) and profile.bounds == pytest.approx((0, 0, 68, 11))
    part = flat_part(edge, 11.0, sheet=True)
    assert part.sheet and part.thickness_mm == pytest.approx(0.5)
    assert part.footprint_mm == pytest.approx((68.0, 11.0))
    with pytest.raises(GeometryError, match="rectangular edge view"):
        sheet_profile(plate_with_holes(), 11.0)


def test_step_without_build123d_is_a_clear_error(monkeypatch):
    # the direct writer (geometry.step_writer) needs no build123d; an outline it refuses (a
    # hole touching the outside at a point) needs OpenCascade, and says so
    monkeypatch.setitem(sys.modules, "build123d", None)  # import fails as if not installed
    touching = Polygon([(0, 0), (10, 0), (10, 10), (0, 10)], [[(0, 5), (3, 4), (3, 6)]])
    part = flat_part(touching, 2.0)
    with pytest.raises(StepUnavailable):
        step_bytes(part)
    assert step_bytes(flat_part(box(0, 0, 10, 5), 2.0)).startswith(b"ISO-10303-21;")


def test_step_writes_a_solid_in_mm():
    pytest.importorskip("build123d")
    import build123d as bd

    part = flat_part(plate_with_holes(), 2.0)
    data = step_bytes(part)
    assert data.startswith(b"ISO-10303-21;") and b"SI_UNIT(.MILLI.,.METRE.)" in data
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "part.step"
        path.write_bytes(data)
        solid = bd.import_step(str(path))
    assert solid.volume == pytest.approx(part.outline.area * 2.0, rel=1e-6)
    assert isinstance(part, FlatPart) and np.isfinite(solid.volume)


def test_step_refuses_an_outline_that_is_not_a_valid_polygon():
    # step_bytes checks the outline with shapely instead of OpenCascade's shape analyser: a
    # self-crossing ring (a bow tie) must still be refused, before any solid is made
    pytest.importorskip("build123d")
    bow_tie = Polygon([(0, 0), (10, 10), (10, 0), (0, 10)])
    assert not bow_tie.is_valid
    with pytest.raises(GeometryError, match="not a valid polygon"):
        step_bytes(FlatPart(bow_tie, 2.0, (10.0, 10.0)))


def test_step_face_count_check_ignores_repeated_vertices():
    # a repeated vertex is no edge of the solid: the count of side faces must not include it
    pytest.importorskip("build123d")
    ring = [(0, 0), (10, 0), (10, 0), (10, 5), (0, 5)]
    data = step_bytes(FlatPart(Polygon(ring), 2.0, (10.0, 5.0)))
    assert data.startswith(b"ISO-10303-21;")


def test_step_of_an_outline_with_collinear_vertices_has_a_face_per_edge():
    # issue 23: OpenCascade merged the side faces of collinear edges and the face count refused
    # the solid ("22 faces, expected 28"); the outline is cleaned first
    pytest.importorskip("build123d")
    import tempfile
    from pathlib import Path

    import build123d as bd

    ring = [(0, 0), (5, 0), (10, 0), (10, 2), (10, 5), (4, 5), (0, 5)]
    hole = [(2, 1), (3, 1), (4, 1), (4, 3), (2, 3)]
    part = FlatPart(Polygon(ring, [hole]), 2.0, (10.0, 5.0))
    data = step_bytes(part)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "part.step"
        path.write_bytes(data)
        solid = bd.import_step(str(path))
    assert len(solid.faces()) == 4 + 4 + 2  # four sides outside, four in the hole, top, bottom
    assert solid.volume == pytest.approx((50.0 - 4.0) * 2.0, rel=1e-9)


def test_the_design_frame_keeps_the_kinds_coordinates():
    tilted = affinity.rotate(plate_with_holes(), 31.0, origin=(7.0, -3.0))
    part = flat_part(tilted, 3.0, frame="design")
    assert part.frame == "design" and part.rotation_deg == 0.0 and part.offset_mm == (0.0, 0.0)
    assert part.outline.symmetric_difference(tilted).area < 1e-9
    assert dxf_polygon(dxf_bytes(part.outline)).symmetric_difference(tilted).area < 1e-9
    # a sheet in the design frame stays its edge view, extruded by the strip's width
    edge = affinity.rotate(box(-10, -0.25, 58, 0.25), 12.0)
    sheet = flat_part(edge, 11.0, sheet=True, frame="design")
    assert not sheet.sheet and sheet.thickness_mm == 11.0
    assert sheet.outline.symmetric_difference(edge).area < 1e-9
    with pytest.raises(GeometryError, match="frame"):
        flat_part(tilted, 3.0, frame="tilted")
