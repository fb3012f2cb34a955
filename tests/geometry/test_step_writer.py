"""The direct STEP writer (geometry.step_writer) against OpenCascade as the validator: the file
re-imported with build123d is one valid solid of the exact volume, a face per outline edge plus
top and bottom, the outline's vertices bit for bit, and the same solid OpenCascade makes."""

from __future__ import annotations

import re
import sys

import numpy as np
import pytest
import shapely
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.solid import FlatPart, StepUnavailable, clean_outline, step_bytes
from flexopt.geometry.step_writer import MIN_FEATURE_MM, PrismRefused, _real, prism_step
from shapely import affinity
from shapely.geometry import Point, Polygon, box
from shapely.geometry.polygon import orient


def plate_with_holes() -> Polygon:
    """40 x 10 mm plate with a square and a round hole (64 segments)."""
    return box(0, 0, 40, 10).difference(box(5, 3, 8, 6)).difference(Point(25, 5).buffer(2.5))


def wavy_ring_with_holes(n: int) -> Polygon:
    """A ring of ``n`` vertices, radius 30 + 2 sin(7 theta) mm, with three round holes: many
    short edges in every direction, none collinear."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    r = 30.0 + 2.0 * np.sin(7.0 * t)
    outer = Polygon(np.c_[r * np.cos(t), r * np.sin(t)])
    holes = [Point(12.0 * np.cos(a), 12.0 * np.sin(a)).buffer(4.0) for a in (0.3, 2.4, 4.5)]
    return outer.difference(shapely.union_all(holes))


def _rings(poly: Polygon) -> list[np.ndarray]:
    poly = orient(poly, sign=1.0)
    return [np.asarray(r.coords) for r in (poly.exterior, *poly.interiors)]


def _n_edges(poly: Polygon) -> int:
    return sum(len(r.coords) - 1 for r in (poly.exterior, *poly.interiors))


def _import(data: bytes, tmp_path):
    bd = pytest.importorskip("build123d")
    path = tmp_path / "part.step"
    path.write_bytes(data)
    return bd.import_step(str(path))


def _vertex_points(data: bytes) -> np.ndarray:
    """The CARTESIAN_POINTs of the file's VERTEX_POINTs, (m, 3) mm, parsed as written."""
    points = dict(re.findall(rb"#(\d+)=CARTESIAN_POINT\('',\(([^)]*)\)\)", data))
    refs = re.findall(rb"VERTEX_POINT\('',#(\d+)\)", data)
    return np.array([[float(v) for v in points[i].split(b",")] for i in refs])


@pytest.mark.parametrize("height", [2.0, 19.558533300932535])
def test_the_file_is_one_valid_solid_of_area_x_thickness(tmp_path, height):
    poly = orient(clean_outline(plate_with_holes()), sign=1.0)
    data = prism_step(_rings(poly), height)
    assert data.startswith(b"ISO-10303-21;") and b"SI_UNIT(.MILLI.,.METRE.)" in data
    solid = _import(data, tmp_path)
    assert len(solid.solids()) == 1 and solid.is_valid
    assert solid.volume == pytest.approx(poly.area * height, rel=1e-9)
    assert len(solid.faces()) == _n_edges(poly) + 2
    box3 = solid.bounding_box()
    x0, y0, x1, y1 = poly.bounds
    got = (box3.min.X, box3.min.Y, box3.min.Z, box3.max.X, box3.max.Y, box3.max.Z)
    assert got == pytest.approx((x0, y0, 0.0, x1, y1, height), abs=1e-6)
    # the faces point outwards: a point of the material is inside, one in a hole is not
    assert solid.is_inside((1.0, 1.0, height / 2))
    assert not solid.is_inside((25.0, 5.0, height / 2)) and not solid.is_inside((6.5, 4.5, 1.0))


def test_the_file_holds_the_outline_vertices_bit_for_bit():
    # MET means the part as exported: no vertex moved, none dropped, none added
    poly = affinity.rotate(wavy_ring_with_holes(997), 17.0, origin=(0.1, 0.2))
    poly = orient(clean_outline(poly), sign=1.0)
    height = 3.0 + 1e-12
    pts = _vertex_points(prism_step(_rings(poly), height))
    xy = np.concatenate([r[:-1] for r in _rings(poly)])
    bottom, top = pts[pts[:, 2] == 0.0], pts[pts[:, 2] == height]
    assert len(bottom) == len(top) == len(xy) and len(pts) == 2 * len(xy)
    want = {tuple(p) for p in xy.tolist()}
    assert len(want) == len(xy)
    assert {tuple(p) for p in bottom[:, :2].tolist()} == want
    assert {tuple(p) for p in top[:, :2].tolist()} == want


def test_reals_are_written_as_step_reals_and_read_back_exactly():
    for x in (0.0, -0.0, 1.0, 10.0, 0.1, 1e-05, -2.5e-07, 1.5e20, 123456789.125, 1 / 3):
        s = _real(x)
        assert re.fullmatch(r"[+-]?\d+\.\d*(E[+-]?\d+)?", s), s
        assert float(s) == x
    assert _real(1e-05) == "1.E-05" and _real(1.5e-07) == "1.5E-07"


def test_a_part_with_small_and_offset_coordinates(tmp_path):
    # coordinates written with exponents (1e-05 mm and such) must read back as numbers
    poly = orient(Polygon([(1e-5, 2e-5), (3.0, 1e-5), (3.0, 2.0), (2e-5, 2.0)]), sign=1.0)
    solid = _import(prism_step(_rings(poly), 0.5), tmp_path)
    assert solid.volume == pytest.approx(poly.area * 0.5, rel=1e-9)
    assert solid.bounding_box().min.X == pytest.approx(1e-5, abs=1e-9)


def test_the_same_solid_as_opencascade_makes(tmp_path):
    # the old path (build123d's extrude and export_step) as the reference: same faces, edges,
    # vertices, volume and box
    from flexopt.geometry.solid import _occ_step_bytes

    poly = orient(clean_outline(wavy_ring_with_holes(401)), sign=1.0)
    ours = _import(prism_step(_rings(poly), 4.0), tmp_path)
    (tmp_path / "occ").mkdir()
    theirs = _import(_occ_step_bytes(poly, 4.0), tmp_path / "occ")
    for what in ("solids", "faces", "edges", "vertices"):
        assert len(getattr(ours, what)()) == len(getattr(theirs, what)()), what
    assert len(ours.faces()) == _n_edges(poly) + 2 and len(ours.edges()) == 3 * _n_edges(poly)
    assert ours.volume == pytest.approx(theirs.volume, rel=1e-12)
    assert ours.volume == pytest.approx(poly.area * 4.0, rel=1e-9)
    a, b = ours.bounding_box(), theirs.bounding_box()
    assert (a.min.X, a.min.Y, a.max.X, a.max.Y) == pytest.approx(
        (b.min.X, b.min.Y, b.max.X, b.max.Y), abs=1e-7
    )
    assert ours.is_valid
    assert abs((ours - theirs).volume) < 1e-9 * ours.volume  # nothing of one outside the other
    assert abs((theirs - ours).volume) < 1e-9 * ours.volume


def test_what_it_cannot_write_is_refused_with_the_reason():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    with pytest.raises(PrismRefused, match="clockwise"):
        prism_step([square[::-1]], 1.0)  # the exterior clockwise
    with pytest.raises(PrismRefused, match="clockwise"):
        prism_step([square * 4, square + 1], 1.0)  # a hole counter-clockwise
    short = np.insert(square, 1, [MIN_FEATURE_MM / 2, 0.0], axis=0)
    with pytest.raises(PrismRefused, match="shorter than"):
        prism_step([short], 1.0)
    with pytest.raises(PrismRefused, match="non-finite"):
        prism_step([np.where(square == 1.0, np.inf, square)], 1.0)
    with pytest.raises(PrismRefused, match="thickness"):
        prism_step([square], 0.0)
    with pytest.raises(PrismRefused, match="n >= 3"):
        prism_step([square[:2]], 1.0)


def test_step_bytes_writes_without_opencascade_and_falls_back_to_it(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "build123d", None)  # import fails as if not installed
    part = FlatPart(plate_with_holes(), 2.0, (40.0, 10.0))
    data = step_bytes(part)  # the direct writer: no OpenCascade needed
    assert data.count(b"ADVANCED_FACE(") == _n_edges(clean_outline(part.outline)) + 2
    # a hole touching the outside at a point: the direct writer refuses (its two vertices
    # there would be one in a reader), OpenCascade is asked, and here it is missing
    touching = Polygon([(0, 0), (10, 0), (10, 10), (0, 10)], [[(0, 5), (3, 4), (3, 6)]])
    assert touching.is_valid
    with pytest.raises(StepUnavailable):
        step_bytes(FlatPart(touching, 2.0, (10.0, 10.0)))
    with pytest.raises(GeometryError, match="not a valid polygon"):  # before either writer
        step_bytes(FlatPart(Polygon([(0, 0), (10, 10), (10, 0), (0, 10)]), 2.0, (10.0, 10.0)))


def test_step_bytes_of_many_edges_is_fast():
    # ~9 300 edges (a SEA spring's outline): OpenCascade's writer took ~17 s; this one well
    # under a second of CPU. A bound of 5 s CPU leaves room for a slow or busy machine.
    import time

    part = FlatPart(wavy_ring_with_holes(9280), 19.56, (64.0, 64.0))
    t0 = time.process_time()
    data = step_bytes(part)
    assert time.process_time() - t0 < 5.0
    assert data.count(b"ADVANCED_FACE(") == _n_edges(clean_outline(part.outline)) + 2


def _closed_shell_problems(data: bytes) -> list[str]:
    """What makes the file's shell not a closed 2-manifold: an edge not used exactly twice in
    opposite senses by the faces' loops, or a loop whose oriented edges do not join head to
    tail. Parsed from the file alone (OpenCascade's reader is too slow for ten thousand
    faces)."""
    ents = dict(re.findall(rb"#(\d+)=([A-Z_]+\(.*?\));", data.replace(b"\n", b"")))
    edge = {}  # EDGE_CURVE id -> (start vertex, end vertex)
    oriented = {}  # ORIENTED_EDGE id -> (edge, sense)
    for i, text in ents.items():
        if text.startswith(b"EDGE_CURVE("):
            a, b = re.findall(rb"#(\d+)", text)[:2]
            edge[i] = (a, b)
        elif text.startswith(b"ORIENTED_EDGE("):
            e, sense = re.fullmatch(rb"ORIENTED_EDGE\('',\*,\*,#(\d+),\.(T|F)\.\)", text).groups()
            oriented[i] = (e, sense == b"T")
    uses: dict[bytes, list[bool]] = {e: [] for e in edge}
    problems = []
    for i, text in ents.items():
        if not text.startswith(b"EDGE_LOOP("):
            continue
        loop = [oriented[j] for j in re.findall(rb"#(\d+)", text)]
        ends = [(edge[e] if s else edge[e][::-1]) for e, s in loop]
        for k, (_, head) in enumerate(ends):
            if head != ends[(k + 1) % len(ends)][0]:
                problems.append(f"loop #{i.decode()} breaks after its edge {k}")
        for e, s in loop:
            uses[e].append(s)
    problems += [f"edge #{e.decode()} used {u}" for e, u in uses.items() if sorted(u) != [0, 1]]
    return problems


def test_ten_thousand_faces_make_a_closed_shell():
    # the SEA spring's size: every edge in two faces, once each way, every loop closed
    poly = orient(clean_outline(wavy_ring_with_holes(9280)), sign=1.0)
    data = prism_step(_rings(poly), 19.56)
    assert data.count(b"ADVANCED_FACE(") == _n_edges(poly) + 2
    assert data.count(b"EDGE_CURVE(") == 3 * _n_edges(poly)
    assert _closed_shell_problems(data) == []
    # and the check sees a broken file: one side face's loop reversed in one edge
    first = re.search(rb"ORIENTED_EDGE\('',\*,\*,#\d+,\.T\.\)", data)
    broken = data[: first.end() - 3] + b"F" + data[first.end() - 2 :]
    assert broken != data and len(_closed_shell_problems(broken)) >= 2
