"""A run folder stands alone (issue 23, class 4): the files its study reads (target tables) are
copied into ``inputs/``, hashed by their bytes, and a resume whose inputs changed is refused.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path
from typing import Literal

import flexopt_toys
import pytest
from flexopt.optimise.targets import TargetSpec
from flexopt.pipeline.cli import main
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study
from flexopt.pipeline.targets import resolve_target
from pydantic import BaseModel

TABLE = "displacement_mm,force_N\n0,0\n1,1\n"


class _TableGeometry(BaseModel):
    model_config = STUDY_CONFIG

    kind: Literal["toy_table"]


class _TableStudy(Study):
    geometry: _TableGeometry
    target: TargetSpec
    optimiser: OptimiserSpec = OptimiserSpec(pop_size=4, n_gen=2, seed=3)


def _check(study: _TableStudy) -> None:
    resolve_target(study.target)  # the kind reads its table at load, as cam does


register(
    StudyKind(
        "toy_table",
        _TableStudy,
        check=_check,  # type: ignore[arg-type]
        problem=lambda study: flexopt_toys.FaultProblem(
            flexopt_toys.FaultGeometry(kind="toy_faults")
        ),
    )
)


def _study(folder: Path) -> Path:
    (folder / "curve.csv").write_text(TABLE)
    raw = {
        "name": "tabled",
        "geometry": {"kind": "toy_table"},
        "material": "PLA",
        "target": {"kind": "table", "file": "curve.csv"},
    }
    path = folder / "study.yaml"
    path.write_text(json.dumps(raw))
    return path


@pytest.fixture
def finished(tmp_path, monkeypatch) -> Path:
    """A finished run of a study whose target table is a relative file in the working folder."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    study = _study(work)
    assert main(["run", str(study), "--out", "run", "-q", "--workers", "1"]) == 0
    return work / "run"


def test_the_run_folder_holds_a_copy_of_the_table_and_its_hash(finished):
    copy = finished / "inputs" / "curve.csv"
    assert copy.read_text() == TABLE
    record = json.loads((finished / "run.json").read_text())
    entry = record["input_files"]["target.file"]
    assert entry == {
        "file": "inputs/curve.csv",
        "source": "curve.csv",
        "sha256": hashlib.sha256(TABLE.encode()).hexdigest(),
    }
    assert "file: inputs/curve.csv" in (finished / "study.yaml").read_text()


def test_report_works_from_another_folder_and_after_the_original_is_gone(
    finished, tmp_path, monkeypatch, capsys
):
    (finished.parent / "curve.csv").unlink()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    moved = tmp_path / "moved"
    shutil.move(finished, moved)
    assert main(["report", str(moved)]) == 0, capsys.readouterr().err
    import flexopt

    assert flexopt.open_run(moved).study.target.file == str(moved / "inputs" / "curve.csv")
    assert list(elsewhere.iterdir()) == []


def _interrupted(run_dir: Path) -> None:
    record = json.loads((run_dir / "run.json").read_text())
    record["status"] = "interrupted"
    (run_dir / "run.json").write_text(json.dumps(record, indent=2))


def _snapshot(folder: Path) -> dict[str, bytes | str]:
    """Every regular file's bytes; a folder or FIFO by its kind (reading a FIFO would block)."""
    return {
        str(p.relative_to(folder)): (
            p.read_bytes() if p.is_file() else "folder" if p.is_dir() else "other"
        )
        for p in sorted(folder.rglob("*"))
    }


def test_a_resume_against_a_changed_table_is_refused_in_one_line(finished, capsys):
    _interrupted(finished)
    study = finished.parent / "study.yaml"
    (finished.parent / "curve.csv").write_text(TABLE.replace("1,1", "1,2"))  # same name
    before = _snapshot(finished)
    capsys.readouterr()
    assert main(["run", str(study), "--resume", str(finished), "-q", "--workers", "1"]) == 2
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "target.file" in lines[0] and "differs from the one this run started with" in lines[0]
    assert _snapshot(finished) == before


def test_a_resume_with_the_same_bytes_goes_on(finished, capsys):
    _interrupted(finished)
    study = finished.parent / "study.yaml"
    assert main(["run", str(study), "--resume", str(finished), "-q", "--workers", "1"]) == 0, (
        capsys.readouterr().err
    )
    _interrupted(finished)
    # without STUDY: the run's own study.yaml and its copy of the table
    assert main(["run", "--resume", str(finished), "-q", "--workers", "1"]) == 0


def test_an_edited_copy_in_the_run_folder_is_refused_too(finished, capsys):
    _interrupted(finished)
    (finished / "inputs" / "curve.csv").write_text(TABLE + "2,2\n")
    capsys.readouterr()
    assert main(["run", "--resume", str(finished), "-q", "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "target.file" in err, err


def test_evaluate_folders_copy_their_tables_too(tmp_path, monkeypatch):
    from flexopt.pipeline.runfolder import copy_inputs
    from flexopt.pipeline.study import load_study

    monkeypatch.chdir(tmp_path)
    study = load_study(_study(tmp_path))
    out = tmp_path / "out"
    out.mkdir()
    copied, record = copy_inputs(study, out)
    assert copied.target.file == "inputs/curve.csv"
    assert (out / "inputs" / "curve.csv").read_text() == TABLE
    assert set(record) == {"target.file"}


@pytest.mark.parametrize("damage", ["removed", "fifo", "folder"])
def test_a_damaged_copy_is_one_line_for_report_and_resume(finished, capsys, damage, solve_log):
    import os

    copy = finished / "inputs" / "curve.csv"
    copy.unlink()
    if damage == "fifo":
        if not hasattr(os, "mkfifo"):
            pytest.skip("no FIFOs here")
        os.mkfifo(copy)
    elif damage == "folder":
        copy.mkdir()
    (finished.parent / "curve.csv").unlink()  # nothing to fall back on in the working folder
    before = _snapshot(finished)
    capsys.readouterr()
    for argv in (["report", str(finished)], ["run", "--resume", str(finished), "-q"]):
        if argv[0] == "run":
            _interrupted(finished)
            before = _snapshot(finished)
        solves = solve_log.count
        assert main(argv) == 2
        assert solve_log.count == solves, "refused after solving"  # speed: benchmarks/refusals.py
        err = capsys.readouterr().err
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert "target.file" in err and "inputs/curve.csv" in err, err
        assert _snapshot(finished) == before
