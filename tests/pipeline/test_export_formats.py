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
from shapely.geometry import box

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
    monkeypatch.setattr("flexopt.pipeline.run.step_available", lambda: False)
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


@pytest.mark.parametrize("name", ["flexure-pivot", "sea-spring-quick", "constant-force"])
def test_export_of_a_shipped_study_evaluate_folder(name, tmp_path, capsys):
    # the design that `flexopt evaluate` solved is the one rebuilt (the kind's nominal_design)
    folder = tmp_path / "ev"
    assert main(["evaluate", name, "--out", str(folder)]) == 0
    capsys.readouterr()
    assert main(["export", str(folder), "--format", "dxf"]) == 0
    out = capsys.readouterr().out
    assert "design evaluated" in out and (folder / "design.dxf").is_file()
