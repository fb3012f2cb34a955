"""``flexopt export --format stl|dxf|step`` on a run folder and on an evaluate folder, and
``best.dxf`` beside ``best.stl`` in a run, on an analytic toy kind whose part lies at 31 degrees
(and, with ``sheet: true``, is a 0.5 mm sheet standing on its edge)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal

import numpy as np
import pytest
import trimesh
from flexopt.geometry.dxf import dxf_polygon
from flexopt.geometry.solid import SHEET_HINT
from flexopt.optimise import DesignDetail, DesignSpace, Evaluation
from flexopt.pipeline.cli import main
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.studies import EvaluationResult, StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study, validate_study
from pydantic import BaseModel, Field
from shapely import affinity
from shapely.geometry import Point, Polygon, box

KIND = "toy_export_part"


class PartGeometry(BaseModel):
    model_config = STUDY_CONFIG

    kind: Literal["toy_export_part"]
    a_mm: float = Field(20.0, gt=0)  # length
    b_mm: float = Field(8.0, gt=0)  # width
    height_mm: float = Field(3.0, gt=0)
    sheet: bool = False  # the part is a 0.5 mm sheet drawn on its edge, extruded by b


class PartStudy(Study):
    geometry: PartGeometry
    optimiser: OptimiserSpec = OptimiserSpec()


class PartProblem:
    objective_names = ("error_mm",)
    constraint_names = ()

    def __init__(self, study: PartStudy) -> None:
        self.geometry = study.geometry
        self.space = DesignSpace(("a_mm", "b_mm"), np.array([10.0, 4.0]), np.array([40.0, 12.0]))

    def evaluate(self, x: np.ndarray) -> Evaluation:
        a, b = x
        return Evaluation(np.array(x), np.array([(a - 30.0) ** 2 + (b - 6.0) ** 2]), np.zeros(0))

    def detail(self, x: np.ndarray) -> DesignDetail:
        a, b = (float(v) for v in x)
        if self.geometry.sheet:
            edge = affinity.rotate(box(0.0, 0.0, a, 0.5), 90.0)  # standing on its edge
            return DesignDetail(self.evaluate(x), outline=edge, height_mm=b, info={SHEET_HINT: 1})
        plate = box(0.0, 0.0, a, b).difference(box(2.0, 1.0, 4.0, 3.0))
        tilted = affinity.rotate(plate, 31.0, origin=(0.0, 0.0))
        return DesignDetail(self.evaluate(x), outline=tilted, height_mm=self.geometry.height_mm)


def _evaluate(study: PartStudy, repeat: int = 1) -> EvaluationResult:
    d = np.linspace(0.0, 1.0, 3)
    table = {"displacement_mm": d, "force_N": d, "peak_stress_MPa": d}
    return EvaluationResult(table, {"area_mm2": 1.0}, True, "", (0.01,) * repeat)


register(StudyKind(KIND, PartStudy, lambda s: None, _evaluate, PartProblem))  # type: ignore[arg-type]

STUDY = {
    "name": "part",
    "geometry": {"kind": KIND},
    "material": "PLA",
    "optimiser": {"pop_size": 6, "n_gen": 2, "seed": 1},
}


def _run(tmp_path: Path, **geometry: object) -> Path:
    data = json.loads(json.dumps(STUDY))
    data["geometry"].update(geometry)
    outcome = run_study(prepare_run(validate_study(data)), out=tmp_path / "run")
    return outcome.run_dir


def _toy_plate(a: float, b: float) -> object:
    """The toy kind's outline in its own (design) frame: the plate turned 31 deg about (0, 0)."""
    return affinity.rotate(box(0.0, 0.0, a, b).difference(box(2.0, 1.0, 4.0, 3.0)), 31.0, (0, 0))


def test_run_writes_a_bed_stl_and_a_design_frame_dxf(tmp_path, capsys):
    run_dir = _run(tmp_path)
    best = json.loads((run_dir / "best.json").read_text())
    a, b = best["parameters"]["a_mm"], best["parameters"]["b_mm"]
    part = best["info"]["part"]
    assert part["footprint_mm"] == pytest.approx([a, b], abs=1e-3)
    assert part["rotated_deg"] == pytest.approx(-31.0) and part["flat_sheet_profile"] is False
    assert part["frames"] == {"best.stl": "bed", "best.dxf": "design", "best.step": "design"}
    mesh = trimesh.load(run_dir / "best.stl")
    assert mesh.bounds[0] == pytest.approx([0, 0, 0], abs=1e-4)
    assert mesh.bounds[1] == pytest.approx([a, b, 3.0], abs=1e-4)  # lying flat, aligned
    # the DXF is the kind's outline where the kind draws it (31 deg, corner at the origin)
    outline = dxf_polygon((run_dir / "best.dxf").read_bytes())
    assert outline.symmetric_difference(_toy_plate(a, b)).area < 1e-9
    assert len(outline.interiors) == 1 and outline.area == pytest.approx(a * b - 4.0)
    assert "best.dxf" in json.loads((run_dir / "run.json").read_text())["files"]
    assert "footprint_mm" in (run_dir / "report.md").read_text()

    # export in each format; the STL and DXF are those of the run
    assert main(["export", str(run_dir), "--format", "dxf", "--out", str(tmp_path / "p.dxf")]) == 0
    out = capsys.readouterr().out
    assert "in the design frame" in out
    again = dxf_polygon((tmp_path / "p.dxf").read_bytes())  # (the DXF's time stamps differ)
    assert again.equals_exact(outline, 0.0)
    # --frame bed: laid flat, turned -31 deg, in the first quadrant
    assert main(["export", str(run_dir), "--frame", "bed", "--out", str(tmp_path / "b.dxf")]) == 0
    out = capsys.readouterr().out
    assert "footprint" in out and f"{a:.4g} x {b:.4g} mm" in out and "-31 deg" in out
    flat = dxf_polygon((tmp_path / "b.dxf").read_bytes())
    assert flat.bounds == pytest.approx((0, 0, a, b), abs=1e-6)
    assert main(["export", str(run_dir), "--out", str(tmp_path / "p.stl")]) == 0
    assert (tmp_path / "p.stl").read_bytes() == (run_dir / "best.stl").read_bytes()
    # --frame design for the STL: the plate where the kind draws it, z from 0 to 3 mm
    assert (
        main(["export", str(run_dir), "--frame", "design", "--out", str(tmp_path / "d.stl")]) == 0
    )
    design = trimesh.load(tmp_path / "d.stl")
    x0, y0, x1, y1 = _toy_plate(a, b).bounds
    np.testing.assert_allclose(design.bounds, [[x0, y0, 0.0], [x1, y1, 3.0]], atol=1e-4)
    assert main(["export", str(run_dir), "--design", "2", "--format", "dxf"]) == 0
    assert dxf_polygon((run_dir / "design-2.dxf").read_bytes()).area > 0
    assert main(["export", str(run_dir), "--frame", "tilted"]) == 2
    assert "invalid choice: 'tilted'" in capsys.readouterr().err
    if _has_build123d():
        import build123d as bd

        assert (run_dir / "best.step").read_bytes().startswith(b"ISO-10303-21;")
        solid = bd.import_step(str(run_dir / "best.step"))
        box3 = solid.bounding_box()
        assert (box3.min.X, box3.min.Y, box3.max.X, box3.max.Y) == pytest.approx(
            (x0, y0, x1, y1), abs=1e-5
        )
        assert main(["export", str(run_dir), "--format", "step"]) == 0


def _has_build123d() -> bool:
    import importlib.util

    return importlib.util.find_spec("build123d") is not None


def test_a_sheet_part_is_exported_as_its_flat_profile(tmp_path, capsys):
    run_dir = _run(tmp_path, sheet=True)
    best = json.loads((run_dir / "best.json").read_text())
    a, b = best["parameters"]["a_mm"], best["parameters"]["b_mm"]
    mesh = trimesh.load(run_dir / "best.stl")
    assert mesh.bounds[1] - mesh.bounds[0] == pytest.approx([a, b, 0.5], abs=1e-4)
    assert best["info"]["part"]["flat_sheet_profile"] is True
    assert main(["export", str(run_dir), "--format", "dxf"]) == 0
    assert "flat profile of the sheet" in capsys.readouterr().out


def test_export_of_an_evaluate_folder(tmp_path, capsys):
    study = tmp_path / "part.yaml"
    data = {**STUDY, "geometry": {"kind": KIND, "a_mm": 25.0, "b_mm": 7.0}}
    study.write_text(json.dumps(data))
    folder = tmp_path / "ev"
    assert main(["evaluate", str(study), "--out", str(folder)]) == 0
    capsys.readouterr()
    for fmt in ("stl", "dxf"):
        assert main(["export", str(folder), "--format", fmt]) == 0
        assert f"design.{fmt}" in capsys.readouterr().out
    outline = dxf_polygon((folder / "design.dxf").read_bytes())
    assert outline.symmetric_difference(_toy_plate(25.0, 7.0)).area < 1e-9  # the study's design
    assert trimesh.load(folder / "design.stl").is_watertight
    assert main(["export", str(folder), "--design", "3"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "holds one design; drop --design" in err


def test_step_without_the_extra_and_bad_formats_are_one_line_exit_2(tmp_path, capsys, monkeypatch):
    run_dir = _run(tmp_path)
    capsys.readouterr()
    monkeypatch.setattr("flexopt.pipeline.run.export.step_available", lambda: False)
    assert main(["export", str(run_dir), "--format", "step"]) == 2
    assert capsys.readouterr().err == (
        "flexopt export: error: --format step needs the optional extra: "
        "pip install 'flexopt[step]'\n"
    )
    assert not (run_dir / "best.step").exists() or _has_build123d()
    assert main(["export", str(run_dir), "--format", "iges"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "invalid choice: 'iges'" in err
    assert main(["export", str(run_dir), "--format", "stl", "--out", str(tmp_path / "a.dxf")]) == 2
    assert "ends in .dxf but --format is stl" in capsys.readouterr().err


@pytest.mark.e2e
@pytest.mark.parametrize("name", ["flexure-pivot", "sea-spring-quick", "constant-force"])
def test_export_of_a_shipped_study_evaluate_folder(name, tmp_path, capsys):
    # the design that `flexopt evaluate` solved is the one rebuilt (the kind's nominal_design)
    folder = tmp_path / "ev"
    assert main(["evaluate", name, "--out", str(folder)]) == 0
    capsys.readouterr()
    assert main(["export", str(folder), "--format", "dxf"]) == 0
    out = capsys.readouterr().out
    assert "design evaluated" in out and (folder / "design.dxf").is_file()


# ---- issue 22: the outline exported is the one whose peak stress converged -------------------

SEA_STUDY = {
    "name": "sea-export",
    "geometry": {"kind": "sea_spring", "topology": "spiral", "n_sets": 4},
    "material": "maraging-300",
    "taguchi": {"enabled": False},
    "mesh": {"max_edge_mm": 6.0, "elements_through": 0.5, "fillet_segments": 1},
    "design": {"sweep": 300.0, "R_pad": 30.0, "F1": 1 / 3, "F2": 0.5,
               "W1": 3.0, "W2": 2.5, "W3": 2.5, "W4": 3.0},
    "solid_3d": {"converge_peak": True, "correct": False, "layers": 1},
}  # fmt: skip


def _capture_meshed_outline(monkeypatch, path: Path) -> None:
    """Replace the peak convergence by one that keeps the outline it was given to mesh (in a
    file: the SEA spring runs it in a forked second process) and answers at once."""
    import flexopt.fea.solid3d as s3d
    import shapely

    def converge(polygon, *args, **kwargs):
        path.write_bytes(shapely.to_wkb(polygon))
        return {"converged": True, "status": "converged", "last_two_MPa": [100.0, 100.0],
                "peaks_MPa": [100.0, 100.0], "local_edge_mm": [1.0, 0.5],
                "peak_xy_mm": [0.0, 0.0], "corner": None, "time_s": 0.0}  # fmt: skip

    monkeypatch.setattr(s3d, "converge_peak_stress", converge)


def _assert_exported_is_meshed(detail, meshed, coarse) -> Polygon:
    """The design-frame DXF's outline equals the meshed one within COLLINEAR_TOL_MM (the
    meshed outline has no holes: bore and bolt holes are cut after; the exported part has
    them), and the optimiser's coarse outline does not (so the check can fail)."""
    from flexopt.geometry.solid import COLLINEAR_TOL_MM
    from flexopt.pipeline.run import part_bytes, part_of

    exported = dxf_polygon(part_bytes(part_of(detail, "design"), "dxf"))
    assert exported.exterior.hausdorff_distance(meshed.exterior) <= COLLINEAR_TOL_MM
    assert len(meshed.interiors) == 0
    solid = Polygon(exported.exterior)
    assert solid.symmetric_difference(meshed).area <= COLLINEAR_TOL_MM * meshed.length
    assert coarse.exterior.hausdorff_distance(meshed.exterior) > 100 * COLLINEAR_TOL_MM
    return exported


@pytest.mark.slow
def test_sea_spring_exports_the_outline_its_peak_converged_on_hub_bore_at_origin(
    tmp_path, monkeypatch
):
    import flexopt.pipeline.studies.sea_spring as ss
    import shapely
    from flexopt.pipeline.run import part_bytes, part_of

    wkb = tmp_path / "meshed.wkb"
    _capture_meshed_outline(monkeypatch, wkb)
    # no second process: the peak convergence (replaced above) runs here
    monkeypatch.setattr(ss.SideProcess, "start", classmethod(lambda cls: cls()))
    study = validate_study(SEA_STUDY)
    prob = ss.SeaSpringProblem(study, stage1={})
    x = np.delete(ss.design_vector(study), prob.names.index("ST"))
    d = prob.detail(x)
    assert "problem" not in d.info["solid_3d"]["peak_convergence"]
    meshed = shapely.from_wkb(wkb.read_bytes())
    _, coarse, _, _ = prob.solve(x, 1)
    exported = _assert_exported_is_meshed(d, meshed, coarse.outline)
    # issue 23: in the design frame the hub's bore is centred on the spring's axis, (0, 0)
    bore = [r for r in exported.interiors if Polygon(r).contains(Point(0.0, 0.0))]
    assert len(bore) == 1
    c = Polygon(bore[0]).centroid
    assert (c.x, c.y) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert Polygon(bore[0]).area == pytest.approx(
        np.pi * (0.5 * prob.frame.bore_diameter_mm) ** 2, rel=0.03
    )
    if _has_build123d():  # the STEP solid: the same outline, the bore through it at the axis
        import re

        data = part_bytes(part_of(d, "design"), "step")
        # its points (reading the file back with OpenCascade takes minutes at ~4000 faces)
        number = r"([-+0-9.Ee]+)"
        xyz = np.array(
            re.findall(
                rf"CARTESIAN_POINT\('[^']*',\({number},{number},{number}\)\)".encode(), data
            ),
            dtype=float,
        )
        x0, y0, x1, y1 = exported.bounds
        np.testing.assert_allclose(xyz.min(axis=0), [x0, y0, 0.0], atol=1e-6)
        np.testing.assert_allclose(xyz.max(axis=0), [x1, y1, d.height_mm], atol=1e-6)
        bore_xy = np.asarray(bore[0].coords)[:-1]
        on_bore = np.abs(np.hypot(xyz[:, 0], xyz[:, 1]) - np.hypot(*bore_xy[0])) < 1e-6
        assert on_bore.sum() >= 2 * len(bore_xy)  # the bore's ring at the bottom and the top


def test_threshold_spring_exports_the_outline_its_peak_converged_on(tmp_path, monkeypatch):
    import flexopt.pipeline.studies.threshold_spring as ts
    import shapely
    from flexopt.geometry.arm_spring import build_arm_spring
    from flexopt.pipeline.study import load_study

    wkb = tmp_path / "meshed.wkb"
    _capture_meshed_outline(monkeypatch, wkb)
    raw = load_study("threshold-spring").model_dump(mode="json", exclude_none=True)
    raw["fidelity"] = {"max_edge_mm": 6.0, "elements_through": 0.5, "fillet_segments": 1,
                       "steps": 2}  # fmt: skip
    raw["solid_3d"] = {"layers": 1, "correct": False}
    study = validate_study(raw)
    prob = ts.problem(study)
    x = prob.space.clip(ts.design_vector(study))
    d = prob.detail(x)
    assert "problem" not in d.info["solid_3d"]["peak_convergence"]
    meshed = shapely.from_wkb(wkb.read_bytes())
    coarse = build_arm_spring(prob.solve(x)[0], prob.frame).outline  # the optimiser's sampling
    _assert_exported_is_meshed(d, meshed, coarse)


# ---- issue 23: best.step for every built-in example that makes a part ------------------------

#: study keys that switch off the slow checks of a kind's detail; the outline does not depend on
#: them, except where the converged peak's outline is exported (sea_spring, threshold_spring:
#: that outline is rebuilt below, as the detail would with its checks on)
_CHECKS_OFF = {
    "sea_spring": {"solid_3d": {"check": False}, "taguchi": {"enabled": False}},
    "threshold_spring": {"fidelity": {"enabled": False}},
    "constant_force": {"fidelity": {"enabled": False}},
    "flexure_pivot": {"fidelity": {"plane_stress": False}},
}


def _example_names() -> list[str]:
    from flexopt.pipeline.init_study import example_kinds
    from flexopt.pipeline.studies import get_kind

    return sorted(name for name, kind in example_kinds().items() if get_kind(kind).problem)


def _part_as_exported(name: str):
    """The built-in example's design (its ``design:`` or the kind's nominal one, no GA run) and
    its detail's outline as a run with the study's own checks exports it."""
    from dataclasses import replace

    from flexopt.pipeline.problems import nominal_design
    from flexopt.pipeline.run import build_problem
    from flexopt.pipeline.study import load_study

    raw = load_study(name).model_dump(mode="json", exclude_none=True)
    full = validate_study(raw)
    kind = raw["geometry"]["kind"]
    for key, value in _CHECKS_OFF.get(kind, {}).items():
        raw[key] = {**raw.get(key, {}), **value}
    study = validate_study(raw)
    prob = build_problem(study)
    x = nominal_design(prob, study)
    d = prob.detail(x)
    converge = getattr(getattr(full, "solid_3d", None), "converge_peak", False)
    if kind == "sea_spring" and full.solid_3d.check and converge:
        import flexopt.pipeline.studies._sea_spring_peak as peak

        _, geom, _, _ = prob.solve(x, 1)
        d = replace(d, outline=peak.fine_geometry_of(prob, geom.params).outline)
    elif kind == "threshold_spring" and full.fidelity.enabled and full.solid_3d.check and converge:
        from flexopt.geometry.arm_spring import build_arm_spring

        p, _, st, _ = prob.solve(x)
        d = replace(d, outline=prob._fine_geometry(build_arm_spring(p, prob.frame), st).outline)
    return d


@pytest.mark.slow
@pytest.mark.e2e
@pytest.mark.parametrize("name", _example_names())
def test_every_built_in_example_makes_its_step_solid(name):
    pytest.importorskip("build123d", reason="STEP needs the step extra (in the test extra)")
    from flexopt.pipeline.run import part_bytes, part_of

    d = _part_as_exported(name)
    if d.outline is None or not d.height_mm:
        pytest.skip(f"{name}: its kind gives no part outline")
    # best.step's frame (the bed's is the same outline turned; the toy kind's tests cover it)
    part = part_of(d, "design")
    data = part_bytes(part, "step")
    assert data.startswith(b"ISO-10303-21;") and b"MANIFOLD_SOLID_BREP" in data
    # the file is written directly (geometry.step_writer): a face per outline edge, top and
    # bottom, two vertices per outline vertex, and OpenCascade reads it back as one solid of
    # area x height. Its reader takes ~n^2.8 (19 s CPU at 2 200 faces, docs/benchmarks.md):
    # parts of more edges (the SEA springs' finely sampled fillets) are checked by their
    # entities here; tests/geometry/test_step_writer.py reads the writer's files back
    import tempfile
    from pathlib import Path

    import build123d as bd

    rings = (part.outline.exterior, *part.outline.interiors)
    n_edges = sum(len(r.coords) - 1 for r in rings)
    assert data.count(b"ADVANCED_FACE(") == n_edges + 2
    assert data.count(b"VERTEX_POINT(") == 2 * n_edges
    if n_edges > 1500:
        return
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "part.step"
        path.write_bytes(data)
        solid = bd.import_step(str(path))
    assert len(solid.solids()) == 1
    assert len(solid.faces()) == n_edges + 2
    assert solid.volume == pytest.approx(part.outline.area * part.thickness_mm, rel=1e-9)
    box3 = solid.bounding_box()
    got = (box3.min.X, box3.min.Y, box3.min.Z, box3.max.X, box3.max.Y, box3.max.Z)
    x0, y0, x1, y1 = part.outline.bounds
    assert got == pytest.approx((x0, y0, 0.0, x1, y1, part.thickness_mm), abs=1e-6)


@pytest.mark.parametrize(
    "name, mesher",
    [("constant-force", "flexopt.fea.fidelity.mesh_polygon"),
     ("flexure-pivot", "flexopt.fea.mesh.mesh_polygon")],
)  # fmt: skip
def test_plane_stress_checks_mesh_the_outline_that_is_exported(name, mesher, monkeypatch):
    # these kinds resample nothing: their plane-stress check meshes the detail's own outline
    from flexopt.fea.errors import FeaError
    from flexopt.geometry.solid import COLLINEAR_TOL_MM
    from flexopt.pipeline.problems import nominal_design
    from flexopt.pipeline.run import build_problem, part_bytes, part_of
    from flexopt.pipeline.study import load_study

    meshed = []

    def capture(polygon, *args, **kwargs):
        meshed.append(polygon)
        raise FeaError("captured")  # the check is then skipped: no solve needed

    monkeypatch.setattr(mesher, capture)
    study = load_study(name)
    prob = build_problem(study)
    d = prob.detail(nominal_design(prob, study))
    assert len(meshed) >= 1
    exported = dxf_polygon(part_bytes(part_of(d, "design"), "dxf"))
    assert exported.boundary.hausdorff_distance(meshed[0].boundary) <= COLLINEAR_TOL_MM
    assert exported.symmetric_difference(meshed[0]).area <= COLLINEAR_TOL_MM * exported.length
