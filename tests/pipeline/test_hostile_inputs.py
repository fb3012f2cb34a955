"""Hostile study files and command-line options, SIGTERM and noise (issue 11, classes 2, 5, 7).

The corpus is generated here (a 50 MB file and alias bombs are not worth shipping): each case
writes one hostile study, and ``flexopt run`` and ``flexopt evaluate`` must refuse it with exit 2
and one stderr line that names the problem, no traceback, nothing written (no default ``runs/``
in the working folder) and an existing run folder given as ``--out`` left byte for byte as it
was. Each refusal must come before anything is solved (asserted below: no FE solve); how
quickly it comes, against the minutes and gigabytes these files took before, is timed by
benchmarks/refusals.py ("well under a second" on an idle machine, docs/usage.md).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import flexopt_toys  # registers the toy_faults kind
import pytest
from flexopt.pipeline.cli import main
from flexopt.pipeline.parallel import ParallelSettings
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.study import (
    MAX_STUDY_BYTES,
    MAX_STUDY_DEPTH,
    MAX_STUDY_NODES,
    max_workers,
    validate_study,
)

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
CLI = "import sys, flexopt_toys; from pipeline.cli import main; sys.exit(main(sys.argv[1:]))"

CANTILEVER = """\
name: cantilever
geometry:
  kind: polyline_beam
  points_mm: [[0, 0], [30, 0], [60, 0]]
  thickness_mm: [1.5, 1.5, 1.5]
  width_mm: 8.0
  elements: 30
material: ABS
boundary:
  start: clamped
  end: {control: displacement, direction: [0, 1], max_mm: 20.0, steps: 20}
"""


POINTS = "points_mm: [[0, 0], [30, 0], [60, 0]]"
THICKNESS = "thickness_mm: [1.5, 1.5, 1.5]"


def _bomb(levels: int = 9, fan: int = 10) -> str:
    """A billion-laughs alias chain: ``fan**levels`` leaves from a few hundred bytes."""
    text = "a0: &a0 [" + ", ".join(['"lol"'] * fan) + "]\n"
    for i in range(1, levels):
        text += f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * fan) + "]\n"
    return text


def _nested(depth: int, mapping: bool) -> str:
    return "{a: " * depth + "1" + "}" * depth if mapping else "[" * depth + "]" * depth


def _cantilever_with(old: str, new: str) -> str:
    assert old in CANTILEVER
    return CANTILEVER.replace(old, new)


#: name -> (study text or a callable giving it, fragment of the one stderr line)
CASES: dict[str, tuple[object, str]] = {
    "bomb_as_material": (
        lambda: _bomb() + CANTILEVER.replace("material: ABS", "material: *a8"),
        f"expands to more than {MAX_STUDY_NODES} values",
    ),
    "bomb_as_name": (
        lambda: _bomb() + CANTILEVER.replace("name: cantilever", "name: *a8"),
        "expands to more than",
    ),
    "bomb_as_number": (
        lambda: _bomb() + _cantilever_with("width_mm: 8.0", "width_mm: *a8"),
        "expands to more than",
    ),
    "bomb_as_whole_geometry_list": (
        lambda: (
            _bomb() + _cantilever_with("points_mm: [[0, 0], [30, 0], [60, 0]]", "points_mm: *a8")
        ),
        "expands to more than",
    ),
    "bomb_of_mappings_via_merge_keys": (
        lambda: (
            "m0: &m0 {a: 1, b: 2}\n"
            + "".join(
                f"m{i}: &m{i} {{" + ", ".join(f"k{j}: *m{i - 1}" for j in range(10)) + "}\n"
                for i in range(1, 8)
            )
            + CANTILEVER.replace("material: ABS", "material: {<<: *m7}")
        ),
        "expands to more than",
    ),
    "recursive_alias": ("name: &a [*a]\n", "refers to itself"),
    "list_nested_5000_deep": (
        lambda: CANTILEVER.replace("material: ABS", "material: " + _nested(5000, False)),
        f"nested more than {MAX_STUDY_DEPTH} levels",
    ),
    "mapping_nested_3000_deep": (
        lambda: CANTILEVER.replace("material: ABS", "material: " + _nested(3000, True)),
        f"nested more than {MAX_STUDY_DEPTH} levels",
    ),
    "block_mappings_nested_100_deep": (
        lambda: (
            CANTILEVER
            + "extra:\n"
            + "".join("  " * (i + 1) + f"k{i}:\n" for i in range(100))
            + "  " * 101
            + "v: 1\n"
        ),
        f"nested more than {MAX_STUDY_DEPTH} levels",
    ),
    "file_just_over_the_size_limit": (
        lambda: CANTILEVER + "#" * (MAX_STUDY_BYTES + 1),
        f"larger than {MAX_STUDY_BYTES // 1024} KiB",
    ),
    "file_of_50_MB": (
        lambda: CANTILEVER + ("# padding " * 100 + "\n") * 52_000,
        f"larger than {MAX_STUDY_BYTES // 1024} KiB",
    ),
    "list_of_200k_numbers": (
        lambda: _cantilever_with(
            "thickness_mm: [1.5, 1.5, 1.5]", "thickness_mm: [" + "1," * 200_000 + "1]"
        ),
        "expands to more than",
    ),
    "name_of_900k_characters": (
        lambda: CANTILEVER.replace("name: cantilever", "name: " + "ab cd " * 150_000),
        "cannot name a run folder",
    ),
    "bool_as_width": (_cantilever_with("width_mm: 8.0", "width_mm: true"), "boolean"),
    "bool_as_thickness": (
        _cantilever_with("thickness_mm: [1.5, 1.5, 1.5]", "thickness_mm: [1.5, false, 1.5]"),
        "boolean",
    ),
    "bool_as_a_coordinate": (
        _cantilever_with("[60, 0]]", "[60, yes]]"),
        "geometry.points_mm[2][1]: got true; a boolean is not a number",
    ),
    "bool_as_whole_number": (_cantilever_with("elements: 30", "elements: true"), "boolean"),
    "bool_as_steps": (_cantilever_with("steps: 20", "steps: true"), "boolean"),
    "bool_in_material": (
        CANTILEVER.replace(
            "material: ABS", "material: {E_MPa: true, nu: 0.3, yield_MPa: 50, density_kg_m3: 1200}"
        ),
        "boolean",
    ),
    "quick_pop_size_20000": (
        lambda: json.dumps({**flexopt_toys.study(), "optimiser": {"quick_pop_size": 20000}}),
        "optimiser.quick_pop_size",
    ),
    "bool_as_pop_size": (
        lambda: json.dumps({**flexopt_toys.study(), "optimiser": {"pop_size": True}}),
        "optimiser.pop_size: got true; a boolean is not a number",
    ),
    "bool_as_seed": (
        lambda: json.dumps({**flexopt_toys.study(), "optimiser": {"seed": False}}),
        "optimiser.seed: got false",
    ),
    "bool_as_a_time_limit": (
        CANTILEVER + "parallel: {eval_timeout_s: true}\n",
        "parallel.eval_timeout_s: got true",
    ),
    "workers_5000_in_the_study": (
        CANTILEVER + "parallel: {workers: 5000}\n",
        "worker processes on a",
    ),
}


def _text(case: str) -> str:
    make, _ = CASES[case]
    return make() if callable(make) else str(make)


def snapshot_bytes(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.fixture(scope="module")
def existing_run(tmp_path_factory) -> Path:
    """A finished run folder that no refused command may touch."""
    study = validate_study({**flexopt_toys.study(), "optimiser": {"pop_size": 4, "n_gen": 2}})
    out = tmp_path_factory.mktemp("existing") / "run"
    run_study(prepare_run(study), out=out, parallel=ParallelSettings("serial"))
    return out


def one_line(err: str, fragment: str) -> str:
    lines = err.splitlines()
    assert len(lines) == 1, err[:2000]
    assert "Traceback" not in err
    assert fragment in lines[0], lines[0][:2000]
    assert len(lines[0]) < 1000, "an echoed value must be cut"
    return lines[0]


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_hostile_study_is_one_quick_line_and_changes_nothing(
    case, existing_run, tmp_path, monkeypatch, capsys, solve_log
):
    path = tmp_path / "hostile" / f"{case}.yaml"
    path.parent.mkdir()
    path.write_text(_text(case), encoding="utf-8")
    workdir = tmp_path / "cwd"
    workdir.mkdir()
    monkeypatch.chdir(workdir)  # where a default runs/ folder would appear
    before = snapshot_bytes(existing_run)
    _, fragment = CASES[case]
    for argv in (
        ["run", str(path), "-q", "--workers", "1"],
        ["run", str(path), "--out", str(existing_run), "-q", "--workers", "1"],
        ["evaluate", str(path)],
        ["evaluate", str(path), "--out", str(existing_run)],
    ):
        code = main(argv)
        err = capsys.readouterr().err
        assert code == 2, (argv, err[:500])
        one_line(err, fragment)
        assert solve_log.count == 0, f"{case}: refused after solving: {solve_log.calls}"
    assert list(workdir.iterdir()) == []
    assert snapshot_bytes(existing_run) == before


def test_the_limits_leave_every_shipped_study_alone():
    from flexopt.pipeline.study import list_examples, load_study

    for name in list_examples():
        load_study(name)  # raises on a false alarm


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["run", "cantilever", "--workers", "5000"], "worker processes on a"),
        (["run", "cantilever", "--workers", str(max_workers() + 1)], f"at most {max_workers()}"),
        (["run", "cantilever", "--workers", "0"], "must be >= 1"),
        (["run", "cantilever", "--workers", "true"], "not a whole number"),
        (["run", "cantilever", "--out", ""], "--out: is empty"),
        (["run", "cantilever", "--out", "   "], "--out: is empty"),
        (["evaluate", "cantilever", "--out", ""], "--out: is empty"),
        (["run", "--resume", ""], "--resume: is empty"),
        (["status", ""], "RUN_DIR: is empty"),
        (["report", ""], "RUN_DIR: is empty"),
        (["export", "", "--design", "best"], "RUN_DIR: is empty"),
        (["run", "cantilever", "--eval-timeout", "nan"], "must be a number > 0"),
        (["run", "cantilever", "--seed", "-1"], "must be >= 0"),
        (["evaluate", "cantilever", "--repeat", "x" * 100_000], "is not a whole number"),
    ],
)
def test_a_bad_option_is_one_line_and_writes_nothing(argv, fragment, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    line = one_line(err, fragment)
    assert line.startswith("flexopt ")
    assert list(tmp_path.iterdir()) == []


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(HERE)])}


@pytest.mark.slow
@pytest.mark.e2e
def test_sigterm_ends_a_run_like_ctrl_c_and_it_resumes(tmp_path):
    raw = flexopt_toys.study(sleep_s=0.05)
    raw["optimiser"] = {"pop_size": 6, "n_gen": 40, "seed": 3}
    study = tmp_path / "toy.yaml"
    study.write_text(json.dumps(raw))
    out = tmp_path / "run"
    argv = [sys.executable, "-c", CLI, "run", str(study), "--out", str(out), "-q"]
    proc = subprocess.Popen(
        [*argv, "--workers", "2"],
        env=_env(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    try:
        while (
            not (out / "history.csv").exists()
            or len((out / "history.csv").read_text().splitlines()) < 3
        ):
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            assert time.monotonic() < deadline, "the run did not get going"
            time.sleep(0.02)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    assert proc.returncode == 143, err
    assert "Traceback" not in err
    assert "stopped by SIGTERM" in err and f"flexopt run --resume {out}" in err
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "stopped"
    assert main(["run", "--resume", str(out), "-q", "--workers", "1"]) == 0
    assert json.loads((out / "run.json").read_text())["status"] == "finished"


@pytest.mark.slow
@pytest.mark.e2e
def test_an_all_infeasible_run_prints_no_traceback_and_keeps_its_files(tmp_path):
    # Every design raises, and so does the best design's detail (the report notes it): the
    # console shows warnings, never a traceback (logging's last resort printed one before).
    raw = flexopt_toys.study(raise_above=-1.0)
    raw["optimiser"] = {"pop_size": 4, "n_gen": 2, "seed": 1}
    study = tmp_path / "toy.yaml"
    study.write_text(json.dumps(raw))
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-c", CLI, "run", str(study), "--out", str(out), "-q", "--workers", "1"],
        env=_env(),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "no feasible design found" in proc.stderr
    assert "detail failed" in proc.stderr  # the note, as one warning line
    assert all(line.startswith("flexopt run: warning: ") for line in proc.stderr.splitlines())
    assert (out / "report.md").is_file() and (out / "best.json").is_file()
    # with -v the traceback is there for whoever asks for it
    verbose = subprocess.run(
        [sys.executable, "-c", CLI, "-v", "report", str(out)],
        env=_env(),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert "Traceback" in verbose.stderr
