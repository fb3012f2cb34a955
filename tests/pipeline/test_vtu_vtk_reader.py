"""The hand-off VTK files read by VTK itself (the ``vtk`` wheel: the readers ParaView is built
on), not only by meshio: best.vtu, a best_steps/ file, best.pvd and best_3d.vtu of a real
design (issue #26 item 5). Skipped where ``vtk`` is not installed (it is not a requirement of
flexopt, nor of its test extra: ~100 MB; ``pip install vtk`` runs it).

VTK reads the arrays back and measures the cells itself (vtkCellSizeFilter): the triangles'
area is the plane mesh's, and the quadratic tetrahedra's volume is that area times half the
thickness (the half model), which only holds with the nodes in VTK's order. The peaks are the
check's figures for the same state. The VTK wheel has no reader of .pvd collections (ParaView's
vtkPVDReader is ParaView's own), so best.pvd is parsed with VTK's XML parser (vtkXMLDataParser)
and each of its data sets read with vtkXMLUnstructuredGridReader, as ParaView's reader does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from flexopt.pipeline.runfolder import write_atomic
from flexopt.pipeline.vtu import (
    DISPLACEMENT,
    SOLID_VERDICT,
    STRESS_COUNTED,
    VON_MISES,
    write_vtu_files,
)

vtk = pytest.importorskip("vtk")
from vtk.util.numpy_support import vtk_to_numpy  # noqa: E402  (after the skip)

VTK_LINE, VTK_TRIANGLE, VTK_QUADRATIC_TETRA = 3, 5, 24


def _read(path: Path):
    """The unstructured grid of a VTU file, read by VTK (a read error fails the test)."""
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    assert reader.GetErrorCode() == 0, path
    grid = reader.GetOutput()
    assert grid.GetNumberOfPoints() > 0, path
    return grid


def _points(grid, name: str) -> np.ndarray:
    array = grid.GetPointData().GetArray(name)
    assert array is not None, name
    return vtk_to_numpy(array)


def _sizes(grid, kind: str) -> np.ndarray:
    """Per cell area or volume, VTK's own measure of each cell (vtkCellSizeFilter)."""
    f = vtk.vtkCellSizeFilter()
    f.SetInputData(grid)
    f.Update()
    return vtk_to_numpy(f.GetOutput().GetCellData().GetArray(kind))


def _counted_peak(grid, cells: np.ndarray) -> float:
    """The largest von Mises on the vertices of ``cells`` that the check's peak counts."""
    vm, counted = _points(grid, VON_MISES), _points(grid, STRESS_COUNTED) == 1
    on = np.zeros(len(vm), dtype=bool)
    on[np.unique(cells)] = True
    return float(np.max(vm[on & counted]))


def _cells(grid, vtk_type: int) -> tuple[np.ndarray, np.ndarray]:
    """(the indices of the cells of ``vtk_type``, their point ids (k, nodes))."""
    types = np.array([grid.GetCellType(c) for c in range(grid.GetNumberOfCells())])
    which = np.flatnonzero(types == vtk_type)
    ids = vtk.vtkIdList()
    rows = []
    for c in which:
        grid.GetCellPoints(int(c), ids)
        rows.append([ids.GetId(j) for j in range(ids.GetNumberOfIds())])
    return which, np.asarray(rows, dtype=np.int64)


@pytest.mark.slow
def test_vtk_reads_the_hand_off_files_of_a_threshold_spring(tmp_path: Path) -> None:
    """The shipped threshold spring on a coarse mesh (beam rows, plane-stress rows, a 3D check
    of one layer): every file through VTK's readers, arrays, cells and peaks as written."""
    import flexopt.pipeline.studies.threshold_spring as ts
    from flexopt.geometry.arm_spring import build_arm_spring
    from flexopt.pipeline.study import load_study, validate_study

    raw = load_study("threshold-spring").model_dump(mode="json", exclude_none=True)
    raw["fidelity"] = {"max_edge_mm": 6.0, "elements_through": 0.5, "fillet_segments": 1,
                       "steps": 3}  # fmt: skip
    raw["solid_3d"] = {"layers": 1, "converge_peak": False}
    study = validate_study(raw)
    prob = ts.problem(study)
    x = prob.space.clip(ts.design_vector(study))
    d = prob.detail(x)
    ps, s3 = d.info["plane_stress"], d.info["solid_3d"]
    names = write_vtu_files(tmp_path, d, "best", write_atomic)
    assert {"best.vtu", "best.pvd", "best_3d.vtu"} <= set(names)

    # best.vtu: the beam's lines and the plane-stress triangles, the last state's arrays
    grid = _read(tmp_path / "best.vtu")
    lines, _ = _cells(grid, VTK_LINE)
    tri_ids, tris = _cells(grid, VTK_TRIANGLE)
    assert len(lines) == d.shapes_mm.shape[1] - 1 and len(tris) == len(d.field_map["triangles"])
    assert _points(grid, DISPLACEMENT).shape == (grid.GetNumberOfPoints(), 3)
    assert _counted_peak(grid, tris) == ps["peak_stress_MPa"][-1]
    # the part's area (its outline, shapely), as VTK measures the triangles
    exact = build_arm_spring(prob.solve(x)[0], prob.frame).fe_outline.area
    assert _sizes(grid, "Area")[tri_ids].sum() == pytest.approx(exact, rel=1e-9)
    assert grid.GetFieldData().GetNumberOfArrays() > 3  # units, gaps, per-step columns

    # best.pvd, parsed by VTK's XML parser: a collection of every step, each read by VTK
    parser = vtk.vtkXMLDataParser()
    parser.SetFileName(str(tmp_path / "best.pvd"))
    assert parser.Parse() == 1
    root = parser.GetRootElement()
    assert root.GetName() == "VTKFile" and root.GetAttribute("type") == "Collection"
    collection = root.GetNestedElement(0)
    n = collection.GetNumberOfNestedElements()
    entries = [collection.GetNestedElement(k) for k in range(n)]
    times = [float(e.GetAttribute("timestep")) for e in entries]
    assert len(entries) == len(names) - 3 and np.all(np.diff(times) > 0)
    # the plane-stress rows among them (the beam's rows hold only lines at other angles)
    with_field = []
    for e in entries:
        step = _read(tmp_path / e.GetAttribute("file"))
        which, cells = _cells(step, VTK_TRIANGLE)
        if len(which):
            with_field.append((float(e.GetAttribute("timestep")), step, cells))
    np.testing.assert_allclose([t for t, _, _ in with_field], ps["rotation_deg"], atol=1e-12)
    for (_, step, cells), peak in zip(with_field, ps["peak_stress_MPa"], strict=True):
        assert _counted_peak(step, cells) == peak
    # ParaView's Warp By Vector on the last step: points + displacement_mm
    _, step, _ = with_field[-1]
    warp = vtk.vtkWarpVector()
    warp.SetInputData(step)
    step.GetPointData().SetActiveVectors(DISPLACEMENT)
    warp.Update()
    moved = vtk_to_numpy(warp.GetOutput().GetPoints().GetData())
    base = vtk_to_numpy(step.GetPoints().GetData())
    np.testing.assert_allclose(moved, base + _points(step, DISPLACEMENT), rtol=0, atol=1e-12)

    # best_3d.vtu: quadratic tetrahedra of the half model, volume = area x ST / 2
    solid = _read(tmp_path / "best_3d.vtu")
    tet_ids, tets = _cells(solid, VTK_QUADRATIC_TETRA)
    assert len(tet_ids) == solid.GetNumberOfCells() and tets.shape[1] == 10
    volume = _sizes(solid, "Volume").sum()
    assert volume == pytest.approx(exact * s3["ST_mm"] / 2, rel=1e-9)
    assert _points(solid, DISPLACEMENT).shape == (solid.GetNumberOfPoints(), 3)
    peak3d = _counted_peak(solid, tets[:, :4])
    sf = d.solid_field
    counted = np.asarray(sf["stress_counted"], dtype=bool)
    assert peak3d == float(np.max(np.asarray(sf["von_mises_MPa"])[counted]))
    # the figure best.json carries (the 2D nonlinear peak times the 3D / 2D ratio), in the
    # file's field data beside this linear state's own peak
    fd = solid.GetFieldData()
    assert fd.GetArray(SOLID_VERDICT).GetValue(0) == s3["peak_stress_3d_MPa"]
    assert s3["peak_stress_3d_MPa"] == pytest.approx(
        s3["peak_stress_ratio_3d_2d"] * ps["peak_stress_max_MPa"], rel=1e-12
    )
