"""best.vtu of a run, design.vtu of an evaluate folder and ``flexopt export --format vtu``
(:mod:`pipeline.vtu`, issue #26 item 5): read back by meshio.

A toy kind with analytic beam shapes and a two-triangle stress field checks the file exactly
and fast; the sea-spring-quick evaluate folder (0.7 s, its export rebuilds the design with its
plane-stress field) checks a real field against the peak stress the evaluation reports.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal

import meshio
import numpy as np
import pytest
from flexopt.optimise import DesignDetail, DesignSpace, Evaluation
from flexopt.pipeline.cli import main
from flexopt.pipeline.plots import deformation_scale
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.runfolder import read_run_json
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study, validate_study
from flexopt.pipeline.vtu import (
    DISPLACEMENT,
    GAP_BEAM_STRESS,
    GAP_FIELD_DISPLACEMENT,
    GAP_FIELD_STEPS,
    MODEL,
    MODELS,
    STRESS_COUNTED,
    UNITS,
    VON_MISES,
    step_name,
    vtu_bytes,
)
from pydantic import BaseModel
from shapely.geometry import box

KIND = "toy_vtu_part"
N_ROWS, N_NODES = 4, 6


class VtuGeometry(BaseModel):
    model_config = STUDY_CONFIG

    kind: Literal["toy_vtu_part"]
    a_mm: float = 20.0  # the design (flexopt evaluate's nominal design)
    shapes: bool = True  # the detail has beam shapes
    field: bool = True  # ... and a plane-stress field
    field_u: bool = False  # ... that carries its displacement


class VtuStudy(Study):
    geometry: VtuGeometry
    optimiser: OptimiserSpec = OptimiserSpec()


def toy_shapes(a: float) -> np.ndarray:
    """(N_ROWS, N_NODES, 2) mm: a straight beam of length a whose tip rises by the drive."""
    drive = np.linspace(0.0, 3.0, N_ROWS)
    x = np.linspace(0.0, a, N_NODES)
    return np.stack([np.column_stack([x + 0.1 * d * x / a, d * (x / a) ** 2]) for d in drive])


def toy_field(a: float, displacement: bool = False) -> dict:
    """A square of side a in two triangles, von Mises 0, a, 2a, 3a (MPa) at its corners; with
    ``displacement``, the corners' displacement (4, 2) mm of a shear by a / 10."""
    points = np.array([[0.0, 0.0], [a, 0.0], [a, a], [0.0, a]])
    out = {
        "points_mm": points,
        "triangles": np.array([[0, 1, 2], [0, 2, 3]]),
        "values": np.array([0.0, a, 2 * a, 3 * a]),
        "label": "von Mises stress (MPa)",
        "limit": 100.0,
    }
    if displacement:
        out["displacement_mm"] = toy_field_u(a)
    return out


def toy_field_u(a: float) -> np.ndarray:
    """(4, 2) mm: the toy field's displacement, a shear: u_x = y / 10, u_y = 0."""
    return np.array([[0.0, 0.0], [0.0, 0.0], [a / 10, 0.0], [a / 10, 0.0]])


class VtuProblem:
    objective_names = ("error_mm",)
    constraint_names = ()

    def __init__(self, study: VtuStudy) -> None:
        self.geometry = study.geometry
        self.space = DesignSpace(("a_mm",), np.array([10.0]), np.array([40.0]))

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return Evaluation(np.array(x), np.array([(x[0] - 30.0) ** 2]), np.zeros(0))

    def detail(self, x: np.ndarray) -> DesignDetail:
        a = float(x[0])
        drive = np.linspace(0.0, 3.0, N_ROWS)
        table = {"displacement_mm": drive, "force_N": 2 * drive, "peak_stress_MPa": a * drive}
        return DesignDetail(
            self.evaluate(x),
            table=table,
            plot={"x": "displacement_mm", "y": "force_N"},
            shapes_mm=toy_shapes(a) if self.geometry.shapes else None,
            field_map=toy_field(a, self.geometry.field_u) if self.geometry.field else None,
            outline=box(0.0, 0.0, a, 5.0),
            height_mm=3.0,
            info={"field_peak_MPa": 3 * a},
        )


register(StudyKind(KIND, VtuStudy, lambda s: None, None, VtuProblem))  # type: ignore[arg-type]


def _study(**geometry: object) -> VtuStudy:
    data = {
        "name": "vtu",
        "geometry": {"kind": KIND, **geometry},
        "material": "PLA",
        "optimiser": {"pop_size": 4, "n_gen": 2, "seed": 1},
    }
    return validate_study(data)  # type: ignore[return-value]


@pytest.fixture
def no_step(monkeypatch: pytest.MonkeyPatch) -> None:
    """No best.step in the runs here: its child imports OpenCascade (slow on a busy machine),
    and the STEP file is not what these tests are about."""
    for where in ("runner", "state"):  # the early child, the one at the report
        monkeypatch.setattr(f"flexopt.pipeline.run.{where}.step_available", lambda: False)


def _read(path: Path) -> meshio.Mesh:
    return meshio.read(path, file_format="vtu")


def _pvd_steps(path: Path) -> list[tuple[float, Path]]:
    """(timestep, file) of a ParaView collection."""
    import xml.etree.ElementTree as ET

    return [
        (float(d.get("timestep")), path.parent / d.get("file"))
        for d in ET.parse(path).getroot().iter("DataSet")
    ]


def test_vtu_of_beam_shapes_and_a_field_reads_back(tmp_path: Path) -> None:
    a = 20.0
    detail = VtuProblem(_study()).detail(np.array([a]))
    data = vtu_bytes(detail)
    assert data is not None and data.startswith(b"<?xml") and b"<FieldData>" in data
    (tmp_path / "d.vtu").write_bytes(data)
    mesh = _read(tmp_path / "d.vtu")
    lines, tri = mesh.cells_dict["line"], mesh.cells_dict["triangle"]
    shapes = toy_shapes(a)
    # the beam: its rest centreline as lines, a displacement per step, the last one plain
    np.testing.assert_array_equal(mesh.points[:N_NODES, :2], shapes[0])
    assert lines.tolist() == [[i, i + 1] for i in range(N_NODES - 1)]
    beam = slice(0, N_NODES)
    for k, d in enumerate(np.linspace(0.0, 3.0, N_ROWS)):
        name = step_name(k, "displacement_mm", d)
        got = mesh.points[beam, :2] + mesh.point_data[name][beam, :2]
        np.testing.assert_allclose(got, shapes[k], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(
        mesh.point_data[DISPLACEMENT][beam],
        mesh.point_data[step_name(3, "displacement_mm", 3.0)][beam],
    )
    assert np.all(mesh.point_data[DISPLACEMENT][beam, 2] == 0)
    assert np.all(np.isnan(mesh.point_data[VON_MISES][beam]))  # no per-node beam stress
    # the plane stress: its triangles and von Mises; no displacement there
    np.testing.assert_array_equal(tri - N_NODES, toy_field(a)["triangles"])
    np.testing.assert_array_equal(mesh.points[N_NODES:, :2], toy_field(a)["points_mm"])
    np.testing.assert_array_equal(mesh.point_data[VON_MISES][N_NODES:], [0, a, 2 * a, 3 * a])
    assert np.all(np.isnan(mesh.point_data[DISPLACEMENT][N_NODES:]))
    model = mesh.cell_data_dict[MODEL]
    assert set(model["line"]) == {MODELS["beam"]} and set(model["triangle"]) == {1}
    # the units, the per-step table and the gaps are in the field data
    fields = mesh.field_data
    for name in (UNITS, GAP_BEAM_STRESS, GAP_FIELD_DISPLACEMENT):
        assert name in fields
    np.testing.assert_array_equal(
        fields["per load step: peak_stress_MPa"], a * np.linspace(0, 3, 4)
    )
    peak = [
        v for k, v in fields.items() if k.startswith(f"plane stress {VON_MISES}") and "peak" in k
    ]
    assert peak and peak[0][0] == 3 * a


def test_the_in_memory_vtu_is_the_files_byte_for_byte(monkeypatch: pytest.MonkeyPatch) -> None:
    """The VTU made in an anonymous in-memory file (Linux) is the one meshio writes to a real
    file in a temporary folder (the fallback elsewhere), byte for byte."""
    import os

    from flexopt.pipeline import vtu

    detail = VtuProblem(_study()).detail(np.array([20.0]))
    in_memory = vtu_bytes(detail)
    if getattr(os, "memfd_create", None) is None:
        pytest.skip("no memfd_create here: the temporary folder is the only way")
    assert vtu._in_memory_vtu(vtu.vtu_mesh(detail)) is not None  # the in-memory path ran
    monkeypatch.delattr(os, "memfd_create")
    assert vtu._in_memory_vtu(vtu.vtu_mesh(detail)) is None
    on_disk = vtu_bytes(detail)
    assert in_memory == on_disk and len(on_disk) > 1000


def test_nothing_to_write_is_none() -> None:
    detail = VtuProblem(_study(shapes=False, field=False)).detail(np.array([20.0]))
    assert vtu_bytes(detail) is None


@pytest.mark.usefixtures("no_step")
def test_best_vtu_of_a_run_and_its_export(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    run_dir = run_study(prepare_run(_study()), out=tmp_path / "run").run_dir
    best = json.loads((run_dir / "best.json").read_text())
    a = best["parameters"]["a_mm"]
    record = json.loads((run_dir / "run.json").read_text())
    assert "best.vtu" in record["files"]
    # best_steps/ is one entry with its count, in run.json, in report.md, and read back
    assert "best_steps/" in record["files"] and record["file_counts"] == {"best_steps/": N_ROWS}
    assert not any(n.startswith("best_steps/best_") for n in record["files"])
    assert len(list((run_dir / "best_steps").iterdir())) == N_ROWS
    report = (run_dir / "report.md").read_text(encoding="utf-8")
    assert report.count("best_steps/") == 2 and "best_steps/best_000" not in report  # [x](x)
    assert read_run_json(run_dir)["file_counts"] == {"best_steps/": N_ROWS}
    mesh = _read(run_dir / "best.vtu")
    # the mesh of the part, the peak stress of best.json, the last step's shape
    np.testing.assert_array_equal(mesh.cells_dict["triangle"] - N_NODES, toy_field(a)["triangles"])
    assert np.nanmax(mesh.point_data[VON_MISES]) == best["info"]["field_peak_MPa"]
    last = mesh.points[:N_NODES, :2] + mesh.point_data[DISPLACEMENT][:N_NODES, :2]
    np.testing.assert_allclose(last, toy_shapes(a)[-1], rtol=0, atol=1e-12)

    # best.pvd: one VTU per load step, its time the drive (displacement_mm), the step's shape
    steps = _pvd_steps(run_dir / "best.pvd")
    np.testing.assert_allclose([t for t, _ in steps], np.linspace(0.0, 3.0, N_ROWS))
    for k, (_, path) in enumerate(steps):
        step = _read(path)
        got = step.points[:N_NODES, :2] + step.point_data[DISPLACEMENT][:N_NODES, :2]
        np.testing.assert_allclose(got, toy_shapes(a)[k], rtol=0, atol=1e-12)

    out = tmp_path / "again.vtu"
    assert main(["export", str(run_dir), "--format", "vtu", "--out", str(out)]) == 0
    assert "VTU" in capsys.readouterr().out
    assert len(_pvd_steps(tmp_path / "again.pvd")) == N_ROWS  # beside it, with again_steps/
    again = _read(out)
    np.testing.assert_array_equal(again.points, mesh.points)
    assert sorted(again.point_data) == sorted(mesh.point_data)
    # the format from the name; a design index; --frame bed refused
    assert main(["export", str(run_dir), "--design", "1", "--out", str(tmp_path / "d.vtu")]) == 0
    assert (tmp_path / "d.vtu").is_file()
    assert main(["export", str(run_dir), "--format", "vtu", "--frame", "bed"]) == 2
    assert "design frame only" in capsys.readouterr().err


@pytest.mark.usefixtures("no_step")
def test_a_kind_without_shapes_gets_no_vtu(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    run = run_study(prepare_run(_study(shapes=False, field=False)), out=tmp_path / "run")
    assert not (run.run_dir / "best.vtu").exists()
    record = json.loads((run.run_dir / "run.json").read_text())
    assert "best.vtu" not in record["files"] and not any("vtu" in n for n in record["notes"])
    assert not (run.run_dir / "stress_deformed.png").exists()
    assert main(["export", str(run.run_dir), "--format", "vtu"]) == 1
    assert "no beam shapes and no stress field" in capsys.readouterr().err
    assert not (run.run_dir / "best.vtu").exists()


def test_evaluate_folder_has_design_vtu(tmp_path: Path) -> None:
    path = tmp_path / "vtu.yaml"
    path.write_text(
        f"name: vtu\ngeometry: {{kind: {KIND}, field: false}}\nmaterial: PLA\n", encoding="utf-8"
    )
    assert main(["evaluate", str(path), "--out", str(tmp_path / "ev")]) == 0
    record = json.loads((tmp_path / "ev" / "evaluation.json").read_text())
    assert "design.vtu" in record["files"]
    mesh = _read(tmp_path / "ev" / "design.vtu")
    assert "triangle" not in mesh.cells_dict and GAP_FIELD_DISPLACEMENT not in mesh.field_data
    assert "stress_deformed.png" not in record["files"]  # no field: no stress on the part
    assert len(mesh.cells_dict["line"]) == N_NODES - 1
    last = mesh.points[:, :2] + mesh.point_data[DISPLACEMENT][:, :2]
    np.testing.assert_allclose(last, toy_shapes(20.0)[-1], rtol=0, atol=1e-12)


def test_a_field_with_its_displacement(tmp_path: Path) -> None:
    """A field that carries its displacement: finite ``displacement_mm`` on the triangles,
    equal to the field's; the beam's per-step arrays NaN there (said as a gap)."""
    a = 20.0
    data = vtu_bytes(VtuProblem(_study(field_u=True)).detail(np.array([a])))
    assert data is not None
    (tmp_path / "d.vtu").write_bytes(data)
    mesh = _read(tmp_path / "d.vtu")
    u = mesh.point_data[DISPLACEMENT][N_NODES:]
    np.testing.assert_array_equal(u[:, :2], toy_field_u(a))
    assert np.all(u[:, 2] == 0)
    assert np.all(np.isnan(mesh.point_data[step_name(0, "displacement_mm", 0.0)][N_NODES:]))
    assert GAP_FIELD_DISPLACEMENT not in mesh.field_data and GAP_FIELD_STEPS in mesh.field_data
    assert mesh.field_data[f"plane stress {DISPLACEMENT}: max |u| (mm)"][0] == a / 10
    # without the beam: the field's displacement alone, no gap to say
    data = vtu_bytes(VtuProblem(_study(shapes=False, field_u=True)).detail(np.array([a])))
    assert data is not None
    (tmp_path / "f.vtu").write_bytes(data)
    mesh = _read(tmp_path / "f.vtu")
    np.testing.assert_array_equal(mesh.point_data[DISPLACEMENT][:, :2], toy_field_u(a))
    assert not any(k.startswith("gap") for k in mesh.field_data)


def test_deformation_scale_true_unless_tiny() -> None:
    p = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 50.0]])
    assert deformation_scale(p, np.full((3, 2), 3.0)) == 1.0  # 4.2 mm of 100: seen as it is
    assert deformation_scale(p, np.zeros((3, 2))) == 1.0
    u = np.zeros((3, 2))
    u[1, 1] = 0.01  # 0.01 mm of 100 mm: magnified to about 10 mm, by a round factor
    assert deformation_scale(p, u) == 1000.0


@pytest.mark.usefixtures("no_step")
def test_stress_deformed_png_of_a_run_and_an_evaluation(tmp_path: Path) -> None:
    """stress_deformed.png and the report's stress view where the field carries its
    displacement; a field without it gets the undeformed stress_map.png only."""
    run_dir = run_study(prepare_run(_study(field_u=True)), out=tmp_path / "run").run_dir
    files = json.loads((run_dir / "run.json").read_text())["files"]
    assert "stress_deformed.png" in files and "stress_map.png" in files
    assert (run_dir / "stress_deformed.png").read_bytes().startswith(b"\x89PNG")
    assert 'id="fig-stress-deformed"' in (run_dir / "report.html").read_text(encoding="utf-8")
    run_dir = run_study(prepare_run(_study()), out=tmp_path / "run2").run_dir
    assert (run_dir / "stress_map.png").is_file()
    assert not (run_dir / "stress_deformed.png").exists()
    assert "fig-stress-deformed" not in (run_dir / "report.html").read_text(encoding="utf-8")

    path = tmp_path / "vtu.yaml"
    path.write_text(
        f"name: vtu\ngeometry: {{kind: {KIND}, field_u: true}}\nmaterial: PLA\n", encoding="utf-8"
    )
    assert main(["evaluate", str(path), "--out", str(tmp_path / "ev")]) == 0
    record = json.loads((tmp_path / "ev" / "evaluation.json").read_text())
    assert "stress_deformed.png" in record["files"]
    assert (tmp_path / "ev" / "stress_deformed.png").read_bytes().startswith(b"\x89PNG")
    html = (tmp_path / "ev" / "report.html").read_text(encoding="utf-8")
    assert 'id="fig-stress-deformed"' in html


def test_sea_spring_quick_field_has_the_peak_stress_of_the_evaluation(tmp_path: Path) -> None:
    """A real plane-stress field: the evaluate folder's design.vtu and stress_deformed.png, and
    the export, which rebuilds the design with it, the same file. The counted vertices peak at
    the evaluation's figure exactly (the solver's own nodal average, pipeline/fields.py). The
    field's displacement is the solve's: the hub's rigid rotation, the pads held."""
    ev = tmp_path / "ev"
    assert main(["evaluate", "sea-spring-quick", "--out", str(ev)]) == 0
    assert (ev / "stress_deformed.png").is_file()
    evaluated = _read(ev / "design.vtu")
    assert main(["export", str(ev), "--format", "vtu", "--out", str(tmp_path / "x.vtu")]) == 0
    mesh = _read(tmp_path / "x.vtu")
    np.testing.assert_array_equal(mesh.points, evaluated.points)
    for name in (VON_MISES, DISPLACEMENT):
        np.testing.assert_array_equal(mesh.point_data[name], evaluated.point_data[name])
    summary = json.loads((ev / "evaluation.json").read_text())["summary"]
    assert len(mesh.cells_dict["triangle"]) > 1000 and "line" not in mesh.cells_dict
    counted = mesh.point_data[STRESS_COUNTED] == 1
    assert np.max(mesh.point_data[VON_MISES][counted]) == summary["peak_stress_MPa"]
    assert GAP_FIELD_DISPLACEMENT not in mesh.field_data  # it carries its displacement
    # ... the solve's: the hub turned rigidly by the last row's rotation about the centre, the
    # pads held (the angle is read back from response.csv's 10 digits, hence the tolerance)
    rows = (ev / "response.csv").read_text().splitlines()
    col = rows[0].split(",").index("rotation_deg")
    theta = np.radians(float(rows[-1].split(",")[col]))
    p, u = mesh.points[:, :2], mesh.point_data[DISPLACEMENT]
    assert np.all(np.isfinite(u)) and np.all(u[:, 2] == 0)
    rot = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    hub = np.hypot(*(u[:, :2] - (p @ rot.T - p)).T) < 1e-4
    held = np.hypot(u[:, 0], u[:, 1]) == 0
    assert hub.sum() > 50 and held.sum() > 20
    umax = mesh.field_data[f"plane stress {DISPLACEMENT}: max |u| (mm)"][0]
    assert umax == pytest.approx(np.max(np.hypot(u[:, 0], u[:, 1])), rel=1e-12)


def test_an_evaluation_without_its_part_still_shows_its_stress() -> None:
    """report.html of an evaluation whose part is not rebuilt (too slow, as the 86 s
    threshold-spring) draws the evaluation's own field on the deformed part."""
    from flexopt.pipeline.report_html import EvaluateHtmlData, render_evaluate_html

    d = np.linspace(0.0, 1.0, 3)
    data = EvaluateHtmlData(
        "vtu", KIND, {"d_mm": d, "f_N": d}, {"x": "d_mm", "y": "f_N"},
        part_note="too slow to rebuild", field_map=toy_field(20.0, displacement=True),
    )  # fmt: skip
    html = render_evaluate_html(data)
    assert "No 3D view: too slow to rebuild" in html and 'id="fig-stress-deformed"' in html
