"""Meshing outlines: exact areas, element quality and size, holes, local refinement, selection."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from flexopt.fea.errors import FeaError
from flexopt.fea.mesh import (
    MeshSettings,
    TriMesh,
    mesh_polygon,
    select_boundary_edges,
    select_nodes,
    to_skfem,
)
from shapely.geometry import LineString, MultiPolygon, Point, Polygon, box
from skfem import Basis, ElementTriP2, Functional


def plate_with_hole() -> Polygon:
    return box(0.0, 0.0, 20.0, 10.0).difference(Point(8.0, 5.0).buffer(3.0, quad_segs=16))


def test_rectangle_area_quality_and_size():
    mesh = mesh_polygon(box(0.0, 0.0, 10.0, 2.0), 0.5)
    assert mesh.area_mm2 == pytest.approx(20.0, rel=1e-12)
    assert mesh.min_angle_deg >= MeshSettings().min_angle_deg - 1e-6
    assert np.all(mesh.areas_mm2 > 0)  # counter-clockwise
    # Boundary edges are split to the target length before meshing.
    p = mesh.points[mesh.boundary_edges]
    assert np.linalg.norm(p[:, 1] - p[:, 0], axis=1).max() <= 0.5 + 1e-12
    # The area bound is the equilateral one; 30-degree triangles stretch edges by at most sqrt 3.
    assert mesh.edge_lengths_mm.max() <= np.sqrt(3.0) * 0.5
    assert mesh.n_triangles >= 20.0 / (np.sqrt(3.0) / 4.0 * 0.5**2)


def test_hole_is_left_empty_and_bounded():
    poly = plate_with_hole()
    mesh = mesh_polygon(poly, 1.0)
    assert mesh.area_mm2 == pytest.approx(poly.area, rel=1e-9)
    centroids = mesh.points[mesh.triangles].mean(axis=1)
    assert not np.any(shapely.contains_xy(Polygon(poly.interiors[0]), *centroids.T))
    hole_nodes = select_nodes(mesh, poly.interiors[0], boundary_only=True)
    r = np.hypot(*(mesh.points[hole_nodes] - [8.0, 5.0]).T)
    assert np.all(np.abs(r - 3.0) < 0.02)  # on the (polygonal) circle
    # Boundary edges have the material on their left: their signed area sum is the polygon's.
    e = mesh.points[mesh.boundary_edges]
    shoelace = 0.5 * np.sum(e[:, 0, 0] * e[:, 1, 1] - e[:, 1, 0] * e[:, 0, 1])
    assert shoelace == pytest.approx(poly.area, rel=1e-9)


def test_region_refinement_is_local():
    poly = plate_with_hole()
    coarse = mesh_polygon(poly, 2.0)
    notch = Point(11.0, 5.0).buffer(1.0)  # the right side of the hole
    fine = mesh_polygon(poly, 2.0, refine=[(notch, 0.2)])
    tris = shapely.polygons(fine.points[fine.triangles])
    near = shapely.intersects(notch, tris)
    assert fine.edge_lengths_mm[near].max() <= np.sqrt(3.0) * 0.2 * np.sqrt(1.05)
    far = ~shapely.intersects(notch.buffer(6.0), tris)
    assert far.any() and fine.edge_lengths_mm[far].min() > 0.5  # untouched away from it
    assert fine.n_triangles > 1.5 * coarse.n_triangles
    assert fine.area_mm2 == pytest.approx(poly.area, rel=1e-9)
    assert fine.min_angle_deg >= 30.0 - 1e-6


def test_size_field_refinement():
    poly = box(0.0, 0.0, 20.0, 4.0)

    def size(xy: np.ndarray) -> np.ndarray:
        return 0.1 + 0.1 * xy[:, 0]  # graded from 0.1 mm at x = 0 to 2.1 mm at x = 20

    mesh = mesh_polygon(poly, 1.0, refine=size)
    c = mesh.points[mesh.triangles].mean(axis=1)
    h = mesh.edge_lengths_mm.max(axis=1)
    assert h[c[:, 0] < 0.5].max() < 0.3
    assert h[c[:, 0] > 15.0].min() > 0.3


def test_to_skfem_integrates_exactly():
    poly = plate_with_hole()
    mesh = mesh_polygon(poly, 1.0)
    basis = Basis(to_skfem(mesh), ElementTriP2())

    @Functional
    def second_moment(w):
        return w.x[1] ** 2

    # Straight-sided triangles integrate polynomials exactly: compare with the polygon's
    # second moment about y = 0 from the shoelace-type formula over its rings.
    def ring_iy(ring) -> float:
        x, y = np.asarray(ring.coords).T
        cross = x[:-1] * y[1:] - x[1:] * y[:-1]
        return float(np.sum(cross * (y[:-1] ** 2 + y[:-1] * y[1:] + y[1:] ** 2)) / 12.0)

    poly = shapely.geometry.polygon.orient(poly)
    exact = ring_iy(poly.exterior) + sum(ring_iy(r) for r in poly.interiors)
    assert second_moment.assemble(basis) == pytest.approx(exact, rel=1e-10)


def test_to_skfem_named_boundaries():
    mesh = mesh_polygon(box(0.0, 0.0, 10.0, 2.0), 0.5)
    right = LineString([(10.0, 0.0), (10.0, 2.0)])
    skmesh = to_skfem(mesh, boundaries={"drive": right, "clamp": box(-1, -1, 0, 3)})
    basis = Basis(skmesh, ElementTriP2())
    for name, x in (("drive", 10.0), ("clamp", 0.0)):
        dofs = basis.get_dofs(name).all()
        assert np.allclose(basis.doflocs[0, dofs], x)
        assert len(dofs) == 2 * 4 + 1  # 4 edges of 0.5 mm: 5 vertices + 4 midpoints
    with pytest.raises(FeaError, match="selects no boundary facet"):
        to_skfem(mesh, boundaries={"nowhere": Point(5.0, 1.0)})


def test_select_boundary_edges_on_a_line():
    mesh = mesh_polygon(box(0.0, 0.0, 10.0, 2.0), 0.5)
    right = LineString([(10.0, 0.0), (10.0, 2.0)])
    edges = select_boundary_edges(mesh, right)
    p = mesh.points[mesh.boundary_edges[edges]]
    assert np.allclose(p[..., 0], 10.0)
    assert np.sum(np.linalg.norm(p[:, 1] - p[:, 0], axis=1)) == pytest.approx(2.0)
    assert set(select_nodes(mesh, right)) == set(np.unique(mesh.boundary_edges[edges]))
    pad = box(9.0, 0.0, 10.0, 2.0)  # a region selects interior nodes too
    assert len(select_nodes(mesh, pad)) > len(select_nodes(mesh, pad, boundary_only=True))


def test_trimesh_fixes_orientation_and_is_read_only():
    mesh = TriMesh(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), np.array([[0, 2, 1]]))
    assert mesh.areas_mm2[0] == pytest.approx(0.5)
    with pytest.raises(ValueError):
        mesh.points[0, 0] = 1.0


@pytest.mark.parametrize(
    "poly, size, match",
    [
        (MultiPolygon([box(0, 0, 1, 1), box(2, 0, 3, 1)]), 0.5, "one shapely Polygon"),
        (Polygon([(0, 0), (1, 1), (1, 0), (0, 1)]), 0.5, "invalid polygon"),
        (Polygon(), 0.5, "empty"),
        (box(0, 0, 1, 1), 0.0, "max_edge_mm"),
        (box(0, 0, 1000, 1000), 1e-3, "units are mm"),
    ],
)
def test_bad_input_raises(poly, size, match):
    with pytest.raises(FeaError, match=match):
        mesh_polygon(poly, size)


def test_lines_lie_on_element_edges_so_a_selected_disc_is_exact():
    """A ring meshed as ``lines``: the triangles whose three nodes lie on or inside it tile
    exactly the ring's polygon (its area to round-off, computed here from the ring); without it
    the node set inside the disc covers a jagged patch that is not the disc."""
    disc = Point(7.3, 4.1).buffer(2.75, quad_segs=16)
    outline = box(0.0, 0.0, 20.0, 10.0)

    def held_area(mesh: TriMesh) -> float:
        inside = select_nodes(mesh, disc)
        mask = np.zeros(mesh.n_points, dtype=bool)
        mask[inside] = True
        return float(mesh.areas_mm2[mask[mesh.triangles].all(axis=1)].sum())

    with_line = mesh_polygon(outline, 1.0, lines=[disc.exterior])
    assert held_area(with_line) == pytest.approx(disc.area, rel=1e-12)
    assert with_line.min_angle_deg >= MeshSettings().min_angle_deg - 1e-6
    assert with_line.area_mm2 == pytest.approx(outline.area, rel=1e-12)
    without = mesh_polygon(outline, 1.0)
    assert abs(held_area(without) - disc.area) > 0.05 * disc.area


def test_lines_must_lie_strictly_inside():
    outline = box(0.0, 0.0, 20.0, 10.0)
    with pytest.raises(FeaError, match="strictly inside"):
        mesh_polygon(outline, 1.0, lines=[Point(1.0, 5.0).buffer(2.0).exterior])
