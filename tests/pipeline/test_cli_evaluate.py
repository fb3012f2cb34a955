"""`flexopt evaluate` end to end: run folder contents, exit codes, the console script."""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import flexopt.pipeline as pipeline
import numpy as np
import pytest
import yaml
from flexopt.fea.beam import BeamResponse
from flexopt.pipeline.cli import main
from flexopt.pipeline.evaluate import EVALUATE_FILES
from flexopt.pipeline.study import list_examples, load_study, study_to_yaml

COLUMNS = [
    "step",
    "displacement_mm",
    "force_N",
    "transverse_displacement_mm",
    "transverse_force_N",
    "moment_Nmm",
    "end_rotation_deg",
    "peak_stress_MPa",
    "peak_stress_s_mm",
    "iterations",
    "converged",
    "stable",
]
SRC_ROOT = Path(pipeline.__file__).resolve().parents[1]
# a polyline_beam evaluation draws its beam with its section (docs/print_to_part.md): the
# ParaView collection, its last step and one file per load step in design_steps/
CANTILEVER_VTU = ("design.vtu", "design.pvd", "design_steps")


def read_csv(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with path.open(newline="") as handle:
        reader = csv.DictReader(handle)
        return list(reader.fieldnames or []), list(reader)


def test_evaluate_cantilever_writes_the_run_folder(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["evaluate", "cantilever", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "max_abs_force_N" in captured.out and str(out) in captured.out
    assert captured.err == ""
    # no temp files left; report.html beside them (pipeline/report_html.py, evaluate page)
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [*EVALUATE_FILES, *CANTILEVER_VTU, "report.html"]
    )

    header, rows = read_csv(out / "response.csv")
    assert header == COLUMNS
    study = load_study("cantilever")
    assert len(rows) == study.boundary.end.steps + 1
    assert [int(r["step"]) for r in rows] == list(range(len(rows)))
    assert all(r["converged"] == "true" for r in rows)
    disp = np.array([float(r["displacement_mm"]) for r in rows])
    np.testing.assert_allclose(disp, np.linspace(0, study.boundary.end.max_mm, len(rows)))

    record = json.loads((out / "evaluation.json").read_text())
    assert record["converged"] is True and record["message"] == ""
    assert record["solve_time_s"] > 0 and len(record["solve_times_s"]) == 1
    assert record["columns"] == COLUMNS
    assert record["inputs"]["material"]["name"] == "ABS"
    assert record["inputs"]["material"]["source"]
    assert {"flexopt", "numpy", "scipy", "skfem", "python"} <= set(record["versions"])
    for key in ("max_abs_force_N", "max_peak_stress_MPa", "stress_yield_ratio", "mass_g"):
        assert record["summary"][key] > 0
    forces = [float(r["force_N"]) for r in rows]
    assert record["summary"]["max_abs_force_N"] == pytest.approx(max(map(abs, forces)), rel=1e-9)

    assert (out / "force_displacement.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    # The resolved study reads back into the same study, material record included.
    resolved = load_study(out / "study.yaml")
    assert resolved == study
    assert yaml.safe_load((out / "study.yaml").read_text())["material"]["E_MPa"] == 1800.0


def test_cantilever_example_matches_small_deflection_beam_theory(tmp_path):
    """First step (L/60 tip deflection) against 3 E I / L^3; shear and geometry add < 0.5 %."""
    out = tmp_path / "run"
    assert main(["evaluate", "cantilever", "--out", str(out)]) == 0
    study = load_study("cantilever")
    g, m = study.geometry, study.material
    inertia = g.width_mm * g.thickness_mm[0] ** 3 / 12
    length = g.points_mm[-1][0] - g.points_mm[0][0]
    summary = json.loads((out / "evaluation.json").read_text())["summary"]
    expected = 3 * m.E_MPa * inertia / length**3
    assert summary["initial_stiffness_N_per_mm"] == pytest.approx(expected, rel=5e-3)
    assert summary["max_peak_stress_s_mm"] == pytest.approx(0.0, abs=1e-6)  # at the clamp


def _without_3d(name: str, tmp_path: Path) -> str:
    """The example's name, or for a study with 3D checks (sea_spring's ``solid_3d``: three 3D
    solves of ~20 s and ~3 GB each, tested in test_sea_spring_solid3d.py) a copy without them."""
    study = load_study(name)
    s3 = getattr(study, "solid_3d", None)
    if s3 is None or not s3.check:
        return name
    path = tmp_path / f"{name}-2d.yaml"
    path.write_text(study_to_yaml(study.with_values({"solid_3d.check": False})), encoding="utf-8")
    return str(path)


@pytest.mark.slow
@pytest.mark.e2e
@pytest.mark.parametrize("name", list_examples())
def test_every_shipped_example_runs(name, tmp_path):
    out = tmp_path / name
    assert main(["evaluate", _without_3d(name, tmp_path), "--out", str(out)]) == 0
    record = json.loads((out / "evaluation.json").read_text())
    assert record["converged"] is True
    ratio = record["summary"].get("stress_yield_ratio")  # None: a kind with no stressed part
    assert ratio is None or ratio < 1.0, "a shipped example should not yield"
    for name in record["files"]:  # the kind's own files (EvaluationResult.files) included
        if name.endswith("/"):  # a folder (design_steps/) listed once, with its file count
            assert len(list((out / name).iterdir())) == record["file_counts"][name], name
        else:
            assert (out / name).is_file(), name


def test_accepts_a_path_and_an_example_name_with_suffix(tmp_path):
    path = tmp_path / "mine.yaml"
    shutil.copy(Path(pipeline.__file__).parent / "examples" / "fixed_guided.yaml", path)
    assert main(["evaluate", str(path), "--out", str(tmp_path / "a")]) == 0
    assert main(["evaluate", "fixed_guided.yaml", "--out", str(tmp_path / "b")]) == 0
    a = (tmp_path / "a" / "response.csv").read_text()
    assert a == (tmp_path / "b" / "response.csv").read_text()


def test_default_run_folder_is_under_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", "fixed_guided"]) == 0
    assert main(["evaluate", "fixed_guided"]) == 0  # same second: gets its own folder
    folders = sorted((tmp_path / "runs").iterdir())
    assert len(folders) == 2
    assert all(f.name.startswith("fixed_guided-evaluate-") for f in folders)
    assert all((f / "evaluation.json").is_file() for f in folders)


def test_repeat_records_every_time_and_the_median(tmp_path):
    out = tmp_path / "run"
    assert main(["evaluate", "fixed_guided", "--out", str(out), "--repeat", "3"]) == 0
    record = json.loads((out / "evaluation.json").read_text())
    assert record["repeat"] == 3 and len(record["solve_times_s"]) == 3
    assert record["solve_time_s"] == pytest.approx(float(np.median(record["solve_times_s"])))


@pytest.mark.parametrize("argv", [["evaluate"], ["evaluate", "cantilever", "--repeat", "0"], []])
def test_bad_command_lines_exit_2_with_one_line(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


class _NotConvergingModel:
    """Stands in for BeamModel: converges for two steps, then gives up."""

    def __init__(self, profile, material, start, settings) -> None:
        pass

    def solve(self, drive) -> BeamResponse:
        n = drive.steps + 1
        ok = np.arange(n) < 3
        u = np.where(ok, np.linspace(0, drive.max_value, n), np.nan)
        return BeamResponse(
            displacement_mm=u,
            force_N=0.1 * u,
            transverse_displacement_mm=0 * u,
            transverse_force_N=0 * u,
            moment_Nmm=0 * u,
            end_rotation_rad=0 * u,
            peak_stress_MPa=u,
            peak_stress_s_mm=0 * u,
            iterations=np.where(ok, 3, 0),
            converged=ok,
            shapes_mm=np.zeros((n, 2, 2)),
            ok=False,
            message="Newton diverged at step 3",
        )


def test_non_convergence_is_a_result_not_an_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("flexopt.pipeline.studies.polyline_beam.BeamModel", _NotConvergingModel)
    out = tmp_path / "run"
    assert main(["evaluate", "cantilever", "--out", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "warning" in err[0] and "Newton diverged at step 3" in err[0]
    record = json.loads((out / "evaluation.json").read_text())
    assert record["converged"] is False and record["message"] == "Newton diverged at step 3"
    assert record["summary"]["rows_converged"] == 3
    assert record["summary"]["max_abs_displacement_mm"] == pytest.approx(2.0)
    _, rows = read_csv(out / "response.csv")
    assert [r["converged"] for r in rows[2:4]] == ["true", "false"]
    assert rows[-1]["force_N"] == "nan"
    assert (out / "force_displacement.png").is_file()


def _env_with_source_tree() -> dict[str, str]:
    env = dict(os.environ)
    env["COLUMNS"] = "100"
    return env


@pytest.mark.e2e
def test_module_entry_point_in_a_subprocess(tmp_path):
    out = tmp_path / "run"
    ok = subprocess.run(
        [sys.executable, "-m", "flexopt.pipeline.cli", "evaluate", "cantilever", "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=_env_with_source_tree(),
        timeout=300,
    )
    assert ok.returncode == 0, ok.stderr
    assert "Traceback" not in ok.stderr
    assert (out / "evaluation.json").is_file()

    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\ngeometry: {kind: polyline_beam, points_mm: [[0, 0]]}\n")
    refused = subprocess.run(
        [
            sys.executable,
            "-m",
            "flexopt.pipeline.cli",
            "evaluate",
            str(bad),
            "--out",
            str(tmp_path / "n"),
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=_env_with_source_tree(),
        timeout=300,
    )
    assert refused.returncode == 2
    assert "Traceback" not in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1
    assert "geometry.points_mm" in refused.stderr
    assert not (tmp_path / "n").exists()


@pytest.mark.e2e
def test_installed_console_script(tmp_path):
    """The `flexopt` script next to this interpreter, when flexopt is installed (as in CI)."""
    script = Path(sys.executable).with_name("flexopt")
    if not script.exists():
        pytest.skip("flexopt is not installed in this environment (pip install . to test it)")
    out = tmp_path / "run"
    done = subprocess.run(
        [str(script), "evaluate", "cantilever", "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [*EVALUATE_FILES, *CANTILEVER_VTU, "report.html"]
    )


def test_a_buckled_strut_is_flagged_unstable_in_the_console_and_the_files(tmp_path, capsys):
    # A 60 x 1.5 x 8 mm ABS cantilever pushed along its axis with 100 N: the Euler load
    # pi^2 E I / (4 L^2) is computed here, and everything past it must be flagged, not reported
    # as a plain (safe-looking) straight strut.
    raw = yaml.safe_load((SRC_ROOT / "pipeline" / "examples" / "cantilever.yaml").read_text())
    raw["boundary"]["end"] = {
        "control": "force",
        "direction": [-1, 0],
        "max_N": 100.0,
        "steps": 10,
    }
    path = tmp_path / "strut.yaml"
    path.write_text(yaml.safe_dump(raw))
    study = load_study(path)
    E = study.material.E_MPa
    inertia = 8.0 * 1.5**3 / 12.0
    p_euler = np.pi**2 * E * inertia / (4.0 * 60.0**2)
    assert p_euler < 10.0  # the push is 35x past it
    out = tmp_path / "out"
    assert main(["evaluate", str(path), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "warning: unstable: passed a bifurcation" in err
    record = json.loads((out / "evaluation.json").read_text())
    assert record["summary"]["stable"] is False
    _, rows = read_csv(out / "response.csv")
    forces = np.array([float(r["force_N"]) for r in rows])
    stable = np.array([r["stable"] == "true" for r in rows])
    # every row with a push past the Euler load is unstable; the unloaded row is not
    assert stable[0] and not stable[np.abs(forces) > 1.01 * p_euler].any()
