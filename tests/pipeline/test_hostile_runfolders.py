"""Hostile run folders: damaged files and two commands on one folder at once.

One real toy run is made per module; every case copies it, damages one file in one way, and runs
each command that reads that file (``status``, ``report``, ``export``, ``run --resume``) in this
process. Each must refuse in one line on stderr (exit 2, no traceback) that names the file, and
leave every byte of the folder as it was (``report`` and ``--resume`` write nothing when they
refuse). A command that does not read the damaged file is not affected by it.

The concurrency tests start two real ``flexopt`` processes on one folder: the folder's lock lets
exactly one of them run; the other is refused in one line, and no design is solved or stored
twice.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import flexopt_toys  # registers the toy_faults kind
import pytest
from flexopt.pipeline.checkpoint import EvaluationStore
from flexopt.pipeline.cli import main
from flexopt.pipeline.parallel import ParallelSettings, design_key
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.runfolder import LOCK_FILE
from flexopt.pipeline.study import validate_study

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
CLI = "import sys, flexopt_toys; from pipeline.cli import main; sys.exit(main(sys.argv[1:]))"
OPTIMISER = {"pop_size": 6, "n_gen": 3, "seed": 4}
SERIAL = ParallelSettings("serial", 1)


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    """A finished toy run (the folder every case copies)."""
    root = tmp_path_factory.mktemp("hostile")
    study = validate_study({**flexopt_toys.study(), "optimiser": OPTIMISER})
    outcome = run_study(prepare_run(study), out=root / "base", parallel=SERIAL)
    assert not (outcome.run_dir / LOCK_FILE).exists()  # a finished run leaves no lock file
    return outcome.run_dir


def copy_of(base: Path, tmp_path: Path, resumable: bool = False) -> Path:
    """A copy of the base run; ``resumable``: its run.json says it was interrupted."""
    run_dir = tmp_path / "run"
    shutil.copytree(base, run_dir)
    if resumable:
        record = json.loads((run_dir / "run.json").read_text())
        record["status"] = "interrupted"
        (run_dir / "run.json").write_text(json.dumps(record, indent=2))
    return run_dir


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every file's bytes (None for a folder), hidden files included."""
    return {
        str(p.relative_to(folder)): (None if p.is_dir() else p.read_bytes())
        for p in sorted(folder.rglob("*"))
    }


# --------------------------------------------------------------------------------------------
# The damages


def _json(name: str, change: Callable[[dict], object]) -> Callable[[Path], None]:
    """Change the JSON data of ``name`` in place."""

    def damage(run_dir: Path) -> None:
        data = json.loads((run_dir / name).read_text())
        change(data)
        (run_dir / name).write_text(json.dumps(data, indent=2))

    return damage


def _write(name: str, text: str) -> Callable[[Path], None]:
    return lambda run_dir: (run_dir / name).write_text(text)


def _truncate(name: str) -> Callable[[Path], None]:
    def damage(run_dir: Path) -> None:
        data = (run_dir / name).read_bytes()
        (run_dir / name).write_bytes(data[: len(data) // 2])

    return damage


def _bad_byte(name: str, line: int = 1) -> Callable[[Path], None]:
    """A byte that is not UTF-8 in the middle of line ``line`` (0-based)."""

    def damage(run_dir: Path) -> None:
        lines = (run_dir / name).read_bytes().split(b"\n")
        lines[line] = lines[line][:5] + b"\xff" + lines[line][5:]
        (run_dir / name).write_bytes(b"\n".join(lines))

    return damage


def _folder(name: str) -> Callable[[Path], None]:
    def damage(run_dir: Path) -> None:
        (run_dir / name).unlink()
        (run_dir / name).mkdir()
        (run_dir / name / "x").write_text("")

    return damage


def _remove(name: str) -> Callable[[Path], None]:
    return lambda run_dir: (run_dir / name).unlink()


def _store_line(line: str, at: int = 1) -> Callable[[Path], None]:
    """Replace line ``at`` of the store (a middle line: not a torn last line)."""

    def damage(run_dir: Path) -> None:
        lines = (run_dir / "evaluations.jsonl").read_text().splitlines()
        lines[at] = line
        (run_dir / "evaluations.jsonl").write_text("\n".join(lines) + "\n")

    return damage


def _store_field(key: str, value: object) -> Callable[[Path], None]:
    def damage(run_dir: Path) -> None:
        lines = (run_dir / "evaluations.jsonl").read_text().splitlines()
        record = json.loads(lines[2])
        record[key] = value
        lines[2] = json.dumps(record)
        (run_dir / "evaluations.jsonl").write_text("\n".join(lines) + "\n")

    return damage


def _csv(name: str, change: Callable[[list[list[str]]], None]) -> Callable[[Path], None]:
    def damage(run_dir: Path) -> None:
        rows = [line.split(",") for line in (run_dir / name).read_text().splitlines()]
        change(rows)
        (run_dir / name).write_text("\n".join(",".join(r) for r in rows) + "\n")

    return damage


def _cell(rows: list[list[str]], column: str, value: str, row: int = 2) -> None:
    rows[row][rows[0].index(column)] = value


def _drop_column(rows: list[list[str]], column: str) -> None:
    at = rows[0].index(column)
    for row in rows:
        del row[at]


STATUS, REPORT, EXPORT, RESUME = "status", "report", "export", "resume"
ALL = (STATUS, REPORT, EXPORT, RESUME)
STORE_READERS = (STATUS, REPORT, RESUME)
CSV_READERS = (REPORT, EXPORT)

#: name -> (file it damages, how, the commands that read that file and must refuse)
DAMAGES: dict[str, tuple[str, Callable[[Path], None], tuple[str, ...]]] = {
    # best.json: read by export --design best (report rebuilds it)
    "best-truncated": ("best.json", _truncate("best.json"), (EXPORT,)),
    "best-empty-list": ("best.json", _write("best.json", "[]"), (EXPORT,)),
    "best-not-utf8": ("best.json", _bad_byte("best.json", 2), (EXPORT,)),
    "best-value-text": (
        "best.json",
        _json("best.json", lambda d: d["parameters"].update(a="abc")),
        (EXPORT,),
    ),
    "best-value-missing": (
        "best.json",
        _json("best.json", lambda d: d["parameters"].pop("b")),
        (EXPORT,),
    ),
    "best-parameters-list": (
        "best.json",
        _json("best.json", lambda d: d.update(parameters=[1, 2])),
        (EXPORT,),
    ),
    "best-folder": ("best.json", _folder("best.json"), (EXPORT, REPORT)),
    # run.json: read by every command
    "run-truncated": ("run.json", _truncate("run.json"), ALL),
    "run-empty-list": ("run.json", _write("run.json", "[]"), ALL),
    "run-not-utf8": ("run.json", _bad_byte("run.json", 3), ALL),
    "run-folder": ("run.json", _folder("run.json"), ALL),
    "run-generations-text": (
        "run.json",
        _json("run.json", lambda d: d.update(generations_done="two")),
        ALL,
    ),
    "run-seed-text": ("run.json", _json("run.json", lambda d: d.update(seed="abc")), ALL),
    "run-n-gen-null": (
        "run.json",
        _json("run.json", lambda d: d["optimiser"].update(n_gen=None)),
        ALL,
    ),
    "run-resumed-numbers": ("run.json", _json("run.json", lambda d: d.update(resumed=[1])), ALL),
    "run-objectives-text": (
        "run.json",
        _json("run.json", lambda d: d.update(objectives="error")),
        ALL,
    ),
    "run-long-status": ("run.json", _json("run.json", lambda d: d.update(status="x" * 5000)), ALL),
    "run-not-a-run": ("run.json", _json("run.json", lambda d: d.update(command=7)), ALL),
    # the store: read by status, report and --resume
    "store-not-utf8": ("evaluations.jsonl", _bad_byte("evaluations.jsonl", 1), STORE_READERS),
    "store-bare-number": ("evaluations.jsonl", _store_line("42"), STORE_READERS),
    "store-bad-json": ("evaluations.jsonl", _store_line('{"x": [0.1'), STORE_READERS),
    "store-null": ("evaluations.jsonl", _store_line("null"), STORE_READERS),
    "store-folder": ("evaluations.jsonl", _folder("evaluations.jsonl"), STORE_READERS),
    "store-x-text": ("evaluations.jsonl", _store_field("x", "abc"), STORE_READERS),
    "store-x-short": ("evaluations.jsonl", _store_field("x", [0.5, 0.5]), STORE_READERS),
    "store-f-empty": ("evaluations.jsonl", _store_field("f", []), STORE_READERS),
    "store-g-booleans": ("evaluations.jsonl", _store_field("g", [True]), STORE_READERS),
    "store-x-huge": ("evaluations.jsonl", _store_field("x", [10**400, 0, 0]), STORE_READERS),
    "store-reason-number": ("evaluations.jsonl", _store_field("reason", 3), STORE_READERS),
    "store-long-line": ("evaluations.jsonl", _store_line("[" * 100_000), STORE_READERS),
    # evaluations.csv: read by report and export --design INDEX
    "csv-not-utf8": ("evaluations.csv", _bad_byte("evaluations.csv", 2), CSV_READERS),
    "csv-truncated": ("evaluations.csv", _truncate("evaluations.csv"), CSV_READERS),
    "csv-no-column": (
        "evaluations.csv",
        _csv("evaluations.csv", lambda rows: _drop_column(rows, "a")),
        CSV_READERS,
    ),
    "csv-cell-text": (
        "evaluations.csv",
        _csv("evaluations.csv", lambda rows: _cell(rows, "a", "abc")),
        CSV_READERS,
    ),
    "csv-index-text": (
        "evaluations.csv",
        _csv("evaluations.csv", lambda rows: _cell(rows, "index", "two")),
        CSV_READERS,
    ),
    "csv-empty": ("evaluations.csv", _write("evaluations.csv", ""), CSV_READERS),
    "csv-folder": ("evaluations.csv", _folder("evaluations.csv"), CSV_READERS),
    # history.csv: read by report
    "history-not-utf8": ("history.csv", _bad_byte("history.csv", 1), (REPORT,)),
    "history-cell-text": (
        "history.csv",
        _csv("history.csv", lambda rows: _cell(rows, "best_error", "abc", 1)),
        (REPORT,),
    ),
    "history-folder": ("history.csv", _folder("history.csv"), (REPORT,)),
    # study.yaml: read by report, export and --resume
    "study-not-utf8": ("study.yaml", _bad_byte("study.yaml", 3), (REPORT, EXPORT, RESUME)),
    "study-folder": ("study.yaml", _folder("study.yaml"), (REPORT, EXPORT, RESUME)),
    "study-missing": ("study.yaml", _remove("study.yaml"), (REPORT, EXPORT, RESUME)),
}

CASES = [
    pytest.param(name, command, id=f"{name}-{command}")
    for name, (_, _, commands) in DAMAGES.items()
    for command in commands
]


def argv(command: str, run_dir: Path, damaged: str) -> list[str]:
    if command == EXPORT:
        design = ["--design", "2"] if damaged == "evaluations.csv" else []
        return ["export", str(run_dir), *design]
    if command == RESUME:
        return ["run", "--resume", str(run_dir), "-q", "--workers", "1"]
    return [command, str(run_dir)]


@pytest.mark.parametrize(("damage", "command"), CASES)
def test_a_damaged_run_folder_is_refused_in_one_line(base, tmp_path, capsys, damage, command):
    damaged, make, _ = DAMAGES[damage]
    run_dir = copy_of(base, tmp_path, resumable=command == RESUME)
    make(run_dir)
    before = snapshot(run_dir)
    capsys.readouterr()
    code = main(argv(command, run_dir, damaged))
    captured = capsys.readouterr()
    err = captured.err
    assert code == 2, err
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert "Traceback" not in err and "error:" in err
    assert damaged in err or (damage == "study-missing" and "study.yaml" in err), err
    assert len(err.replace(str(run_dir), "D")) < 300, err  # echoed values are cut short
    assert snapshot(run_dir) == before  # not a byte written, no lock or temp file left


def test_the_messages_say_what_is_wrong_and_what_to_do(base, tmp_path, capsys):
    run_dir = copy_of(base, tmp_path)
    _truncate("best.json")(run_dir)
    assert main(["export", str(run_dir)]) == 2
    err = capsys.readouterr().err
    assert "best.json' is not valid JSON (truncated?" in err
    assert f"rebuild it with flexopt report {run_dir}" in err

    run_dir = copy_of(base, tmp_path / "2", resumable=True)
    _json("run.json", lambda d: d.update(seed="abc" * 100))(run_dir)
    assert main(["run", "--resume", str(run_dir)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("flexopt run: error: --resume: ") and "seed is 'abcabc" in err
    assert "not a whole number >= 0" in err and "…" in err
    assert len(err.replace(str(run_dir), "D")) < 250

    run_dir = copy_of(base, tmp_path / "3")
    _store_line("42")(run_dir)
    assert main(["status", str(run_dir)]) == 2
    err = capsys.readouterr().err
    assert "evaluations.jsonl' line 2 is not an evaluation (it is 42" in err
    assert "delete that line" in err


@pytest.mark.parametrize(
    "damage", [name for name, (_, _, commands) in DAMAGES.items() if STATUS not in commands]
)
def test_status_does_not_read_what_it_does_not_show(base, tmp_path, capsys, damage):
    run_dir = copy_of(base, tmp_path)
    DAMAGES[damage][1](run_dir)
    before = snapshot(run_dir)
    assert main(["status", str(run_dir)]) == 0
    assert "status       finished" in capsys.readouterr().out
    assert snapshot(run_dir) == before


def test_a_torn_last_store_line_is_read_around_and_never_rewritten_by_readers(
    base, tmp_path, capsys
):
    run_dir = copy_of(base, tmp_path, resumable=True)
    store = run_dir / "evaluations.jsonl"
    lines = store.read_bytes().splitlines(keepends=True)
    n = len(lines)
    store.write_bytes(b"".join(lines[:-1]) + lines[-1][:20])  # a kill in the middle of a line
    torn = store.read_bytes()

    assert main(["status", str(run_dir)]) == 0
    out = capsys.readouterr().out
    assert f"evaluations  {n - 1} " in out and f"line {n} is torn" in out
    assert main(["report", str(run_dir)]) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and f"line {n} is torn" in captured.err
    assert store.read_bytes() == torn  # report reads the store, it never rewrites it
    assert not (run_dir / LOCK_FILE).exists()

    # --resume solves the torn design again and repairs the line before its first append
    assert main(["run", "--resume", str(run_dir), "-q", "--workers", "1"]) == 0
    capsys.readouterr()
    repaired = EvaluationStore(store).load(3, 1, 1)
    assert len(repaired) == n and store.read_bytes().endswith(b"}\n")
    assert len({design_key(ev.x) for ev in repaired}) == n
    assert json.loads((run_dir / "run.json").read_text())["status"] == "finished"


def test_report_is_refused_while_a_run_holds_the_folder(base, tmp_path, capsys):
    from flexopt.pipeline.runfolder import lock_run_dir

    run_dir = copy_of(base, tmp_path)
    before = snapshot(run_dir)
    with lock_run_dir(run_dir, "--out", "") as lock:
        lock.claim("run")
        before_in_use = snapshot(run_dir)
        for command in (["report", str(run_dir)], ["run", "--resume", str(run_dir)]):
            assert main(command) == 2
            err = capsys.readouterr().err
            assert err.count("\n") == 1
            assert f"is in use by another flexopt run (pid {os.getpid()})" in err
            assert snapshot(run_dir) == before_in_use
        # reading is fine while a run writes: status and export take no lock
        assert main(["status", str(run_dir)]) == 0
        # (the toy kind has no solid: export gets as far as rebuilding the design, exit 1)
        assert main(["export", str(run_dir), "--out", str(tmp_path / "a.stl")]) == 1
        assert "in use" not in capsys.readouterr().err
    assert snapshot(run_dir) == before  # the released lock leaves no lock file
    capsys.readouterr()


# --------------------------------------------------------------------------------------------
# Two processes on one folder


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(HERE)])}


def _race(argvs: list[list[str]]) -> list[tuple[subprocess.Popen, str]]:
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", CLI, *args],
            env=_env(),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        for args in argvs
    ]
    out = []
    for proc in procs:
        try:
            _, err = proc.communicate(timeout=120)
        finally:
            if proc.poll() is None:
                proc.kill()
        out.append((proc, err))
    return out


def _one_ran_one_refused(results, refusals: tuple[str, ...]) -> tuple[int, str]:
    codes = sorted(proc.returncode for proc, _ in results)
    assert codes == [0, 2], [err for _, err in results]
    (winner, _), (_, err) = sorted(results, key=lambda r: r[0].returncode)
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert any(refusal in err for refusal in refusals), err
    return winner.pid, err


def _no_design_twice(run_dir: Path) -> None:
    record = json.loads((run_dir / "run.json").read_text())
    assert record["status"] == "finished"
    store = EvaluationStore(run_dir / "evaluations.jsonl").load(3, 1, 1)
    assert len(store) == record["n_evaluations"] == len({design_key(ev.x) for ev in store})
    assert not (run_dir / LOCK_FILE).exists()


SLOW = {"sleep_s": 0.06}  # ~3 s of solving left after the first generation: the two overlap


@pytest.mark.slow
@pytest.mark.e2e
def test_two_resumes_at_once_one_runs_and_the_other_is_refused(tmp_path):
    raw = {**flexopt_toys.study(**SLOW), "optimiser": {"pop_size": 8, "n_gen": 8, "seed": 2}}
    run_dir = tmp_path / "run"

    def stop(report) -> None:
        if report.generation == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_study(
            prepare_run(validate_study(raw)), out=run_dir, parallel=SERIAL, on_generation=stop
        )
    assert json.loads((run_dir / "run.json").read_text())["status"] == "interrupted"
    resume = ["run", "--resume", str(run_dir), "-q", "--workers", "1"]
    results = _race([resume, resume])
    winner, err = _one_ran_one_refused(results, ("is in use by another flexopt run",))
    assert f"(pid {winner})" in err and err.startswith("flexopt run: error: --resume: ")
    _no_design_twice(run_dir)
    assert len(json.loads((run_dir / "run.json").read_text())["resumed"]) == 1


@pytest.mark.slow
@pytest.mark.e2e
def test_two_runs_into_one_new_folder_one_runs_and_the_other_is_refused(tmp_path):
    study = tmp_path / "toy.yaml"
    raw = {**flexopt_toys.study(**SLOW), "optimiser": {"pop_size": 8, "n_gen": 4, "seed": 2}}
    study.write_text(json.dumps(raw))
    run_dir = tmp_path / "run"
    run = ["run", str(study), "--out", str(run_dir), "-q", "--workers", "1"]
    results = _race([run, run])
    # the loser meets the lock, or (started later) the run.json of the winner
    _one_ran_one_refused(results, ("is in use by another flexopt run", "already holds a run"))
    _no_design_twice(run_dir)
