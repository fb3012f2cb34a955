"""The bad-input corpus: every broken study in tests/data/bad_studies is refused cleanly.

For each file, ``flexopt run`` and ``flexopt evaluate`` must exit with 2 and print exactly one
line on stderr that names the key path (``<file>: <key>: <problem>``) and contains the expected
fragment from ``cases.yaml``; no traceback; nothing written (no default ``runs/``), and an
existing run folder given as ``--out`` left exactly as it was (names, sizes, mtimes).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import flexopt_toys
import pytest
import yaml
from flexopt.pipeline.cli import main
from flexopt.pipeline.parallel import ParallelSettings
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.study import validate_study

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data" / "bad_studies"
CASES = yaml.safe_load((DATA / "cases.yaml").read_text(encoding="utf-8"))
FILES = sorted(p.name for p in DATA.iterdir() if p.name != "cases.yaml")


def snapshot(folder: Path) -> dict[str, tuple[int, int]]:
    return {p.name: (p.stat().st_mtime_ns, p.stat().st_size) for p in sorted(folder.iterdir())}


@pytest.fixture(scope="module")
def existing_run(tmp_path_factory) -> Path:
    """A finished run folder that no refused command may touch."""
    study = validate_study({**flexopt_toys.study(), "optimiser": {"pop_size": 4, "n_gen": 2}})
    out = tmp_path_factory.mktemp("existing") / "run"
    run_study(prepare_run(study), out=out, parallel=ParallelSettings("serial"))
    return out


def test_the_corpus_is_complete():
    assert len(FILES) >= 30
    assert set(FILES) == set(CASES), "every file needs a case in cases.yaml, and every case a file"


def check_line(name: str, err: str) -> None:
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    case = CASES[name]
    line = lines[0]
    where = f"{name}: {case['key']}: " if case["key"] else f"{name}: "
    assert where in line, line
    assert case["message"] in line, line


@pytest.mark.parametrize("name", FILES)
def test_a_bad_study_is_one_line_and_changes_nothing(
    name, existing_run, tmp_path, monkeypatch, capsys
):
    path = str(DATA / name)
    before = snapshot(existing_run)
    monkeypatch.chdir(tmp_path)  # where a default runs/ folder would appear
    for argv in (
        ["run", path, "-q", "--workers", "1"],
        ["run", path, "--out", str(existing_run), "-q", "--workers", "1"],
        ["evaluate", path],
        ["evaluate", path, "--out", str(existing_run)],
    ):
        assert main(argv) == 2, argv
        check_line(name, capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []
    assert snapshot(existing_run) == before


@pytest.mark.parametrize(
    "name", ["binary.yaml", "empty.yaml", "E_in_pascal.yaml", "self_intersecting_polyline.yaml"]
)
def test_the_real_command_prints_no_traceback(name, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run(
        [sys.executable, "-m", "flexopt.pipeline.cli", "run", str(DATA / name)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    check_line(name, done.stderr)
    assert done.stdout == "" and list(tmp_path.iterdir()) == []
