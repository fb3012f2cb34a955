"""The hand-off files of a part (issue #26 item 5): best_cad.py (a parametric build123d script),
best.3mf (the part with its print settings) and print_sheet.md, from a run, a report and
``flexopt export --format cad|3mf|sheet``.

A toy kind (a tilted plate with a hole and a web, two design variables) checks each file fast;
the constant-force example checks that its script, run by Python as a user would, builds a solid
of best.step's volume, and the other examples whose part is an extrusion of their outline check
the script's outline against the exported one.
"""

from __future__ import annotations

import json
import runpy
import subprocess
import sys
from pathlib import Path
from typing import Literal

import numpy as np
import pytest
import trimesh
from flexopt.optimise import DesignDetail, DesignSpace, Evaluation
from flexopt.pipeline.cli import main
from flexopt.pipeline.print_sheet import PrintSettings, layers, print_sheet, sections
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.studies import EvaluationResult, StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study, validate_study
from flexopt.pipeline.threemf import CORE, NAMESPACE, read_threemf, threemf_bytes
from pydantic import BaseModel, Field
from shapely import affinity
from shapely.geometry import Polygon, box

KIND = "toy_handoff_part"
HEIGHT_MM = 3.1  # 15.5 layers of 0.2 mm: the sheet warns of the half layer


class HandoffGeometry(BaseModel):
    model_config = STUDY_CONFIG

    kind: Literal["toy_handoff_part"]
    hole_mm: float = Field(2.0, gt=0)  # a fixed dimension: the hole's side
    height_mm: float = Field(HEIGHT_MM, gt=0)
    outline: bool = True  # the kind draws a part


class HandoffStudy(Study):
    geometry: HandoffGeometry
    optimiser: OptimiserSpec = OptimiserSpec()


def toy_outline(a: float, web: float, hole: float) -> Polygon:
    """A plate a x 8 mm with a square hole, a web of thickness ``web`` on top, turned 31 deg."""
    plate = box(0.0, 0.0, a, 8.0).difference(box(2.0, 1.0, 2.0 + hole, 1.0 + hole))
    part = plate.union(box(0.0, 8.0, web, 14.0))
    return affinity.rotate(part, 31.0, origin=(0.0, 0.0))


class HandoffProblem:
    objective_names = ("error_mm",)
    constraint_names = ()
    variable_meanings = {
        "a_mm": "length of the plate (mm)",
        "web_mm": "in-plane thickness of the web (mm)",
    }

    def __init__(self, study: HandoffStudy) -> None:
        self.geometry = study.geometry
        self.space = DesignSpace(("a_mm", "web_mm"), np.array([10.0, 0.8]), np.array([40.0, 2.0]))

    def evaluate(self, x: np.ndarray) -> Evaluation:
        a, web = x
        f = np.array([(a - 30.0) ** 2 + (web - 1.0) ** 2])
        return Evaluation(np.array(x), f, np.zeros(0), metrics={"min_feature_mm": float(web)})

    def detail(self, x: np.ndarray) -> DesignDetail:
        a, web = (float(v) for v in x)
        d = np.linspace(0.0, 2.0, 5)
        table = {"displacement_mm": d, "force_N": 3 * d, "peak_stress_MPa": d}
        if not self.geometry.outline:
            return DesignDetail(self.evaluate(x), table=table)
        shape = toy_outline(a, web, self.geometry.hole_mm)
        return DesignDetail(
            self.evaluate(x), table=table, outline=shape, height_mm=self.geometry.height_mm
        )


def _evaluate(study: HandoffStudy, repeat: int = 1) -> EvaluationResult:
    d = np.linspace(0.0, 1.0, 3)
    table = {"displacement_mm": d, "force_N": d, "peak_stress_MPa": d}
    return EvaluationResult(table, {"area_mm2": 1.0}, True, "", (0.01,) * repeat)


register(StudyKind(KIND, HandoffStudy, lambda s: None, _evaluate, HandoffProblem))  # type: ignore[arg-type]

STUDY = {
    "name": "handoff",
    "geometry": {"kind": KIND},
    "material": "PETG",
    "optimiser": {"pop_size": 6, "n_gen": 2, "seed": 1},
}


def _run(tmp_path: Path, **geometry: object) -> Path:
    data = json.loads(json.dumps(STUDY))
    data["geometry"].update(geometry)
    return run_study(prepare_run(validate_study(data)), out=tmp_path / "run").run_dir


@pytest.fixture(scope="module")
def toy_run(tmp_path_factory) -> Path:
    """One run of the toy kind (a run takes seconds: every test reads or copies this one)."""
    return _run(tmp_path_factory.mktemp("handoff"))


@pytest.fixture
def run_copy(toy_run, tmp_path) -> Path:
    """A copy of the toy run to write into."""
    import shutil

    return Path(shutil.copytree(toy_run, tmp_path / "run"))


def _best(run_dir: Path) -> tuple[float, float]:
    p = json.loads((run_dir / "best.json").read_text())["parameters"]
    return float(p["a_mm"]), float(p["web_mm"])


def _has(module: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(module) is not None


# ---- a run writes the three files ----------------------------------------------------------


def test_a_run_writes_the_handoff_files(toy_run):
    run_dir = toy_run
    files = json.loads((run_dir / "run.json").read_text())["files"]
    for name in ("best_cad.py", "best.3mf", "print_sheet.md"):
        assert (run_dir / name).is_file() and name in files
    a, web = _best(run_dir)

    # best.3mf: best.stl's mesh (laid flat), the same volume and triangles, and the settings
    stl = trimesh.load(run_dir / "best.stl")
    v, f, meta, slicer = read_threemf((run_dir / "best.3mf").read_bytes())
    mesh = trimesh.Trimesh(v, f, process=False)
    assert len(f) == len(stl.faces) and mesh.is_watertight
    assert mesh.volume == pytest.approx(stl.volume, rel=1e-12)
    # (manifold3d's vertices are float32: the STL's and the 3MF's volume is area x height to ~1e-8)
    assert mesh.volume == pytest.approx(toy_outline(a, web, 2.0).area * HEIGHT_MM, rel=1e-6)
    assert mesh.bounds[0] == pytest.approx([0, 0, 0], abs=1e-6)  # on the bed
    assert meta["Title"] == "handoff: best design" and meta["flexopt:material"] == "PETG"
    assert meta["flexopt:layer_height_mm"] == "0.2" and meta["flexopt:line_width_mm"] == "0.4"
    assert meta["flexopt:infill_percent"] == "100" and "flat" in meta["flexopt:orientation"]
    assert float(meta["flexopt:thinnest_section_mm"]) == pytest.approx(web, abs=1e-4)
    assert slicer["fill_density"] == "100%" and slicer["layer_height"] == "0.2"
    assert slicer["perimeters"] == str(PrintSettings().perimeters(web))

    # print_sheet.md: what to print, the web in lines, what to measure (the CSV columns)
    sheet = (run_dir / "print_sheet.md").read_text()
    assert "best.3mf" in sheet and "PETG" in sheet and "100 %" in sheet
    assert f"{web:.4g}" in sheet and f"{web / 0.4:.2f}" in sheet
    assert "15.50 layers" in sheet and "WARNING: over 0.5 %" in sheet  # 3.1 mm: 15.5 layers
    assert "`displacement_mm,force_N`" in sheet and "flexopt compare" in sheet
    assert "flexopt retrim" in sheet


@pytest.mark.skipif(not (_has("lxml") and _has("networkx")), reason="trimesh's 3MF reader")
def test_trimesh_reads_the_3mf_back(toy_run):
    run_dir = toy_run
    stl = trimesh.load(run_dir / "best.stl")
    back = trimesh.load(run_dir / "best.3mf", force="mesh")
    assert len(back.faces) == len(stl.faces)
    assert back.volume == pytest.approx(stl.volume, rel=1e-12)


def test_the_3mf_is_the_core_spec():
    import io
    import xml.etree.ElementTree as ET
    import zipfile

    mesh = trimesh.creation.box((1.0, 2.0, 3.0))
    data = threemf_bytes(mesh.vertices, mesh.faces, "a <box>", {"layer_height_mm": "0.2"})
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        assert {"[Content_Types].xml", "_rels/.rels", "3D/3dmodel.model"} <= set(zf.namelist())
        root = ET.fromstring(zf.read("3D/3dmodel.model"))
    assert root.tag == f"{{{CORE}}}model" and root.get("unit") == "millimeter"
    names = [m.get("name") for m in root.iter(f"{{{CORE}}}metadata")]
    assert "Title" in names and "flexopt:layer_height_mm" in names
    assert NAMESPACE.startswith("urn:")
    v, f, meta, slicer = read_threemf(data)
    assert meta["Title"] == "a <box>" and slicer == {}
    assert trimesh.Trimesh(v, f).volume == pytest.approx(6.0, rel=1e-12)
    # the same part gives the same bytes (the zip's time stamps are fixed)
    assert data == threemf_bytes(mesh.vertices, mesh.faces, "a <box>", {"layer_height_mm": "0.2"})
    with pytest.raises(ValueError, match="vertex that is not there"):
        threemf_bytes(mesh.vertices, mesh.faces + 100, "x", {})


# ---- the print sheet's arithmetic ----------------------------------------------------------


def test_walls_per_section_and_layers():
    s = PrintSettings()
    assert s.is_whole(0.8) and s.is_whole(0.8001) and s.is_whole(1.2)
    assert not s.is_whole(1.0) and not s.is_whole(0.2)  # 2.5 lines; less than one line
    assert s.perimeters(0.8) == 1 and s.perimeters(1.6) == 2 and s.perimeters(1.0) == 1
    assert s.perimeters(12.0) == 3  # a thick wall: perimeters and 100 % infill
    meanings = {
        "t_mm": "in-plane thickness of the beam (mm)",
        "B_mm": "out-of-plane width of the part (mm)",  # z: layers, not lines
        "a": "where p1 sits (–)",
    }
    rows = sections(("t_mm", "B_mm", "a"), np.array([1.0, 6.0, 0.5]), meanings, 0.8)
    assert [r.name for r in rows] == ["thinnest section", "t_mm"]
    assert rows[0].whole and rows[0].note(s) == "2 lines"
    assert not rows[1].whole and rows[1].lines == pytest.approx(2.5)
    assert rows[1].note(s).startswith("WARNING: 2.50 lines, not whole")
    assert layers(6.0) == (30, pytest.approx(0.0))
    n, err = layers(6.826)
    assert n == 34 and err == pytest.approx(100 * (6.8 / 6.826 - 1))


def test_a_metal_part_gets_no_print_settings():
    from flexopt.fea.materials import get_material
    from flexopt.geometry.solid import flat_part

    part = flat_part(box(0, 0, 10, 5), 2.0)
    text = print_sheet(
        title="t",
        run_dir="r",
        material=get_material("65Mn"),
        part=part,
        section_list=[],
        response={},
        files={
            "stl": "best.stl",
            "3mf": "best.3mf",
            "cad": "best_cad.py",
            "step": "best.step",
            "dxf": "best.dxf",
        },
    )
    assert "is not an FDM filament" in text and "no response table" in text
    assert "best.dxf" in text and "Measure after making" in text
    assert "layer height" not in text and "lines" not in text  # no print settings


# ---- the parametric CAD script -------------------------------------------------------------


def _script(run_dir: Path, name: str = "best_cad.py") -> dict:
    """The script's module namespace, not run as __main__ (nothing written)."""
    return runpy.run_path(str(run_dir / name), run_name="cad_script_under_test")


def test_the_cad_script_names_the_dimensions_and_rebuilds_the_part(run_copy, capsys):
    pytest.importorskip("build123d", reason="the CAD script needs the step extra")
    run_dir = run_copy
    a, web = _best(run_dir)
    text = (run_dir / "best_cad.py").read_text()
    assert text.startswith("#!/usr/bin/env python3") and "DESIGN = {" in text
    assert "length of the plate (mm); range 10 … 40" in text
    ns = _script(run_dir)
    assert ns["DESIGN"] == {"a_mm": a, "web_mm": web}
    assert 'STUDY_YAML = """\\\nname: handoff\n' in text  # the study reads as YAML
    assert ns["STUDY_YAML"].startswith("name: handoff\n")
    assert ns["FIXED"] == {"hole_mm": 2.0, "height_mm": HEIGHT_MM}

    # the solid is best.step's: the same volume, the design frame (turned 31 deg as drawn)
    assert main(["export", str(run_dir), "--format", "step"]) == 0
    import build123d as bd

    step = bd.import_step(str(run_dir / "best.step"))
    solid = ns["build"]()
    assert solid.volume == pytest.approx(step.volume, rel=1e-9)
    assert solid.volume == pytest.approx(toy_outline(a, web, 2.0).area * HEIGHT_MM, rel=1e-9)
    box_a, box_b = solid.bounding_box(), step.bounding_box()
    assert tuple(box_a.min) == pytest.approx(tuple(box_b.min), abs=1e-6)
    assert tuple(box_a.max) == pytest.approx(tuple(box_b.max), abs=1e-6)

    # change a design variable and a fixed dimension: the part the kind draws of them
    ns["DESIGN"]["a_mm"] = a + 5.0
    ns["FIXED"]["hole_mm"] = 3.0
    ns["FIXED"]["height_mm"] = 4.0
    changed = ns["build"]()
    assert changed.volume == pytest.approx(toy_outline(a + 5.0, web, 3.0).area * 4.0, rel=1e-9)

    # a name that is not a variable is refused, not ignored
    ns["DESIGN"]["typo_mm"] = 1.0
    with pytest.raises(KeyError, match="not variables: typo_mm"):
        ns["build"]()


def test_the_cad_script_without_flexopt_builds_the_part_as_exported(toy_run, monkeypatch):
    pytest.importorskip("build123d", reason="the CAD script needs the step extra")
    run_dir = toy_run
    a, web = _best(run_dir)
    ns = _script(run_dir)
    monkeypatch.setitem(sys.modules, "flexopt.pipeline.cad_script", None)  # not installed
    solid = ns["build"]()
    assert solid.volume == pytest.approx(toy_outline(a, web, 2.0).area * HEIGHT_MM, rel=1e-9)
    ns["DESIGN"]["a_mm"] = a + 1.0
    with pytest.raises(SystemExit, match="changed dimensions need flexopt"):
        ns["build"]()


def test_the_unedited_script_builds_the_exported_outline_without_drawing_it(run_copy, monkeypatch):
    """Unedited, the script builds the outline kept in it (no solve: the threshold spring's and
    a mechanism's outlines take minutes to draw); a changed dimension, a changed study or
    ``--redraw`` draw it again through flexopt."""
    pytest.importorskip("build123d", reason="the CAD script needs the step extra")
    import flexopt.pipeline.cad_script as cad

    run_dir = run_copy
    a, web = _best(run_dir)
    ns = _script(run_dir)
    drawn = []
    real = cad.outline_of

    def counted(*args, **kwargs):
        drawn.append(args[1])
        return real(*args, **kwargs)

    monkeypatch.setattr(cad, "outline_of", counted)
    rings, thickness = ns["outline"]()
    assert drawn == [] and ns["as_exported"]()
    assert rings == ns["OUTLINE_AS_EXPORTED"] and thickness == HEIGHT_MM
    assert Polygon(rings[0], rings[1:]).area == pytest.approx(
        toy_outline(a, web, 2.0).area, rel=1e-12
    )
    # --redraw: the same outline, drawn by the kind
    again, _ = ns["outline"](redraw=True)
    assert len(drawn) == 1
    assert (
        Polygon(again[0], again[1:]).symmetric_difference(Polygon(rings[0], rings[1:])).area < 1e-9
    )
    # a fixed dimension back at its recorded value is unedited; another value is drawn
    ns["FIXED"]["hole_mm"] = 2.0
    ns["outline"]()
    assert len(drawn) == 1
    ns["FIXED"]["hole_mm"] = 3.0
    changed, _ = ns["outline"]()
    assert len(drawn) == 2 and Polygon(changed[0], changed[1:]).area == pytest.approx(
        toy_outline(a, web, 3.0).area, rel=1e-9
    )
    ns["FIXED"]["hole_mm"] = 2.0
    # an edit of the embedded study (a number only it holds) is a change too
    module = ns["outline"].__globals__
    module["STUDY_YAML"] = module["STUDY_YAML"].replace("name: handoff", "name: handoff-b")
    assert not ns["as_exported"]()
    ns["outline"]()
    assert len(drawn) == 3


#: FreeCAD's own document reader, run by freecadcmd: the spreadsheet's rows and the part's volume
READ_FCSTD = """\
import FreeCAD as App
doc = App.openDocument({path!r})
sheet = doc.getObject("Dimensions")
i = 1
while sheet.getContents(f"A{{i}}"):
    print("ROW", *(sheet.getContents(f"{{c}}{{i}}") for c in "ABC"))
    i += 1
print("VOLUME", repr(doc.getObject("Part").Shape.Volume), doc.getObject("Part").Shape.isValid())
"""


def test_freecad_runs_the_script_as_a_macro(run_copy, tmp_path):
    """``freecadcmd best_cad.py``: FreeCAD's Python (no flexopt, no build123d) builds the part
    from the outline the script keeps, writes best_cad.step of best.step's volume and a .FCStd
    whose spreadsheet names every dimension; a changed dimension is refused there."""
    import shutil

    freecad = shutil.which("freecadcmd")
    if freecad is None:
        pytest.skip("FreeCAD is not installed (apt-get install freecad-python3)")
    pytest.importorskip("build123d", reason="best.step is read back with build123d")
    import build123d as bd

    run_dir = run_copy
    a, web = _best(run_dir)
    assert main(["export", str(run_dir), "--format", "step"]) == 0
    folder = tmp_path / "fc"
    folder.mkdir()
    shutil.copy(run_dir / "best_cad.py", folder / "best_cad.py")
    done = subprocess.run(
        [freecad, "best_cad.py"], cwd=folder, capture_output=True, text=True, timeout=300
    )
    assert "wrote" in done.stdout, done.stdout[-2000:] + done.stderr[-2000:]
    rebuilt = bd.import_step(str(folder / "best_cad.step")).volume
    exported = bd.import_step(str(run_dir / "best.step")).volume
    assert rebuilt == pytest.approx(exported, rel=1e-9)
    assert rebuilt == pytest.approx(toy_outline(a, web, 2.0).area * HEIGHT_MM, rel=1e-9)
    # the document: every dimension by name, and the part as a valid solid
    (folder / "read_doc.py").write_text(READ_FCSTD.format(path=str(folder / "best_cad.FCStd")))
    read = subprocess.run(
        [freecad, "read_doc.py"], cwd=folder, capture_output=True, text=True, timeout=300
    )
    rows = [line.split()[1:] for line in read.stdout.splitlines() if line.startswith("ROW ")]
    named = {r[0]: (float(r[1]), " ".join(r[2:])) for r in rows[1:]}
    want = {
        "a_mm": (a, "design variable"),
        "web_mm": (web, "design variable"),
        "hole_mm": (2.0, "fixed"),
        "height_mm": (HEIGHT_MM, "fixed"),
        "thickness_mm": (HEIGHT_MM, "extrusion along z"),
    }
    assert list(named) == list(want)
    for name, (value, group) in want.items():  # the sheet keeps 16 significant digits
        assert named[name] == (pytest.approx(value, rel=1e-15), group), name
    (volume,) = [line.split() for line in read.stdout.splitlines() if line.startswith("VOLUME ")]
    assert float(volume[1]) == pytest.approx(exported, rel=1e-9) and volume[2] == "True"
    # a changed dimension: FreeCAD's Python has no flexopt to draw it, so no part is written
    text = (folder / "best_cad.py").read_text()
    (folder / "edited.py").write_text(text.replace("'hole_mm': 2.0,", "'hole_mm': 3.0,", 1))
    done = subprocess.run(
        [freecad, "edited.py"], cwd=folder, capture_output=True, text=True, timeout=300
    )
    assert "changed dimensions need flexopt" in done.stdout + done.stderr
    assert not (folder / "edited.step").exists()


# ---- flexopt export --format cad|3mf|sheet -------------------------------------------------


def test_export_writes_each_handoff_file(toy_run, run_copy, tmp_path, capsys):
    run_dir = run_copy
    expected = {"cad": "best_cad.py", "3mf": "best.3mf", "sheet": "print_sheet.md"}
    for fmt, name in expected.items():
        # the same file as the run's (the sheet names the folder of its commands: the copy's)
        before = (run_dir / name).read_bytes()
        before = before.replace(bytes(toy_run.resolve()), bytes(run_dir.resolve()))
        (run_dir / name).unlink()
        assert main(["export", str(run_dir), "--format", fmt]) == 0
        out = capsys.readouterr().out
        assert out.startswith(f"wrote {run_dir / name} (design best, ")
        if fmt != "3mf":  # (the 3MF records the day it was written)
            assert (run_dir / name).read_bytes() == before
    # another design: its own names; the format from the file's ending
    assert main(["export", str(run_dir), "--design", "0", "--format", "cad"]) == 0
    assert (run_dir / "design-0_cad.py").is_file()
    assert main(["export", str(run_dir), "--out", str(tmp_path / "p.3mf")]) == 0
    assert read_threemf((tmp_path / "p.3mf").read_bytes())[2]["Title"] == "handoff: best design"
    assert main(["export", str(run_dir), "--design", "1", "--format", "sheet"]) == 0
    assert (run_dir / "design-1_print_sheet.md").is_file()
    capsys.readouterr()
    # refused in one line: a frame (the formats choose theirs), a clash of ending and format
    assert main(["export", str(run_dir), "--format", "cad", "--frame", "bed"]) == 2
    assert "chooses its own frame" in capsys.readouterr().err
    assert main(["export", str(run_dir), "--format", "cad", "--out", str(tmp_path / "x.3mf")]) == 2
    assert "name the file .py" in capsys.readouterr().err


def test_a_kind_without_an_outline_says_so_in_one_line(tmp_path, capsys):
    run_dir = _run(tmp_path, outline=False)
    assert not (run_dir / "best_cad.py").exists() and not (run_dir / "best.3mf").exists()
    capsys.readouterr()
    assert main(["export", str(run_dir), "--format", "cad"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"kind '{KIND}' gives no outline and height_mm: no parametric CAD script" in err


# ---- the shipped examples ------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.e2e
def test_the_constant_force_script_run_by_python_builds_best_step(tmp_path):
    # the constant-force part as a run exports it (its plane-stress check on: the script
    # switches it off, FAST_CHECKS), its best.step and best_cad.py; the script run as a user
    # runs it, in a folder of its own
    pytest.importorskip("build123d", reason="the CAD script needs the step extra")
    import build123d as bd
    from flexopt.pipeline.cad_script import cad_script
    from flexopt.pipeline.problems import nominal_design
    from flexopt.pipeline.run import build_problem, part_bytes, part_of
    from flexopt.pipeline.study import load_study

    study = load_study("constant-force")
    assert study.fidelity.enabled
    problem = build_problem(study)
    x = nominal_design(problem, study)
    part = part_of(problem.detail(x), "design")
    (tmp_path / "best.step").write_bytes(part_bytes(part, "step"))
    (tmp_path / "best_cad.py").write_text(cad_script(study, problem, x, part))
    done = subprocess.run(
        [sys.executable, "best_cad.py"], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    assert "wrote" in done.stdout and (tmp_path / "best_cad.step").is_file()
    exported = bd.import_step(str(tmp_path / "best.step")).volume
    rebuilt = bd.import_step(str(tmp_path / "best_cad.step")).volume
    assert rebuilt == pytest.approx(exported, rel=1e-9)
    assert exported == pytest.approx(part.outline.area * part.thickness_mm, rel=1e-6)


#: Examples of other kinds whose detail (with the study's own checks) takes seconds, among them
#: the SEA spring's quick study (its script keeps the 3D check that moves its outline); the
#: mechanism studies whose detail takes a minute (bistable-switch, gripper-amplifier,
#: parallel-guide) were checked once by hand (docs/print_to_part.md), not here.
QUICK_EXAMPLES = (
    "constant-force-mechanism",
    "flexure-pivot",
    "leaf-spring-joint",
    "sea-spring-quick",
    "threshold-cam",
)


@pytest.mark.slow
@pytest.mark.e2e
@pytest.mark.parametrize("name", QUICK_EXAMPLES)
def test_the_script_outline_is_the_exported_one(name):
    # the outline the script draws (outline_of, its checks switched off where FAST_CHECKS says
    # so) is the one best.step is made of (the detail with the study's own checks)
    from flexopt.pipeline.cad_script import outline_of
    from flexopt.pipeline.problems import nominal_design
    from flexopt.pipeline.run import build_problem, part_of
    from flexopt.pipeline.study import load_study, study_to_yaml

    study = load_study(name)
    problem = build_problem(study)
    x = nominal_design(problem, study)
    detail = problem.detail(x)
    if detail.outline is None or not detail.height_mm:
        pytest.skip(f"{name}: its kind gives no part outline")
    part = part_of(detail, "design")
    values = dict(zip(problem.space.names, x, strict=True))
    rings, thickness = outline_of(study_to_yaml(study), values)
    drawn = Polygon(rings[0], rings[1:])
    assert thickness == part.thickness_mm
    assert drawn.symmetric_difference(part.outline).area <= 1e-9 * part.outline.area


@pytest.mark.slow
@pytest.mark.e2e
def test_a_mechanism_script_rebuilds_best_step_in_seconds_without_a_solve(tmp_path):
    """A mechanism's outline comes from a solve (its fidelity check re-solves the width); the
    unedited script builds best.step's solid from the outline it keeps, run by Python with
    flexopt's outline drawing switched off (it would exit), in seconds."""
    pytest.importorskip("build123d", reason="the CAD script needs the step extra")
    import resource

    import build123d as bd
    from flexopt.pipeline.cad_script import cad_script
    from flexopt.pipeline.problems import nominal_design
    from flexopt.pipeline.run import build_problem, part_bytes, part_of
    from flexopt.pipeline.study import load_study

    study = load_study("parallel-guide-stop")
    assert study.kind == "mechanism"
    problem = build_problem(study)
    x = nominal_design(problem, study)
    part = part_of(problem.detail(x), "design")
    (tmp_path / "best.step").write_bytes(part_bytes(part, "step"))
    (tmp_path / "best_cad.py").write_text(cad_script(study, problem, x, part))
    blocked = (
        "import runpy, sys, flexopt.pipeline.cad_script as c\n"
        "def refuse(*a, **k):\n    sys.exit('the script drew the outline again')\n"
        "c.outline_of = refuse\n"
        "runpy.run_path('best_cad.py', run_name='__main__')\n"
    )
    # the child's CPU time, not the wall clock: the machine may be loaded
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(
        [sys.executable, "-c", blocked], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    assert done.returncode == 0, done.stderr
    assert cpu_s < 10.0, cpu_s  # ~4 s: Python, flexopt's and build123d's imports, the STEP
    exported = bd.import_step(str(tmp_path / "best.step")).volume
    rebuilt = bd.import_step(str(tmp_path / "best_cad.step")).volume
    assert rebuilt == pytest.approx(exported, rel=1e-9)
    assert exported == pytest.approx(part.outline.area * part.thickness_mm, rel=1e-6)
    # a changed dimension reaches the refusal: the outline is drawn again, not the old one kept
    text = (tmp_path / "best_cad.py").read_text()
    (tmp_path / "best_cad.py").write_text(
        text.replace("'pad_length_mm': 6.0,", "'pad_length_mm': 7.0,", 1)
    )
    done = subprocess.run(
        [sys.executable, "-c", blocked], cwd=tmp_path, capture_output=True, text=True, timeout=120
    )
    assert done.returncode != 0 and "drew the outline again" in done.stderr
