"""Run-folder helpers: atomic writes, CSV cells, strict JSON, folder names."""

from __future__ import annotations

import json
import multiprocessing
import os
import sys
import time
from datetime import datetime

import numpy as np
import pytest
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.runfolder import (
    LOCK_FILE,
    check_out_dir,
    echo,
    lock_run_dir,
    new_run_dir_path,
    table_to_csv,
    to_json,
    write_atomic,
)


def test_write_atomic_replaces_and_leaves_no_temp_file(tmp_path):
    target = tmp_path / "a.txt"
    write_atomic(target, "old")
    write_atomic(target, b"new")
    assert target.read_text() == "new"
    assert os.listdir(tmp_path) == ["a.txt"]
    assert target.stat().st_mode & 0o777 == 0o644


def test_write_atomic_failure_keeps_the_old_file(tmp_path):
    target = tmp_path / "a.txt"
    write_atomic(target, "old")
    with pytest.raises(TypeError):
        write_atomic(target, 42)  # type: ignore[arg-type]
    assert target.read_text() == "old"
    assert os.listdir(tmp_path) == ["a.txt"]


def test_csv_cells():
    text = table_to_csv(
        {
            "step": np.arange(2),
            "x_mm": np.array([0.1, np.nan]),
            "converged": np.array([True, False]),
        }
    )
    assert text == "step,x_mm,converged\n0,0.1,true\n1,nan,false\n"


def test_json_is_strict():
    text = to_json({"a": np.float64(np.nan), "b": [np.int64(3), float("inf")], "c": (1.5,)})
    assert json.loads(text) == {"a": None, "b": [3, None], "c": [1.5]}


def test_run_dir_names_do_not_collide(tmp_path):
    now = datetime(2026, 1, 2, 3, 4, 5)
    first = new_run_dir_path(tmp_path, "beam", "evaluate", now)
    assert first.name == "beam-evaluate-20260102-030405"
    first.mkdir()
    assert new_run_dir_path(tmp_path, "beam", "evaluate", now).name.endswith("030405-2")


def test_out_dir_must_be_a_folder(tmp_path):
    check_out_dir(tmp_path / "new")  # fine: created later
    check_out_dir(tmp_path)
    (tmp_path / "f").write_text("")
    with pytest.raises(StudyError, match="--out"):
        check_out_dir(tmp_path / "f")


def test_echo_cuts_long_values():
    assert echo("two") == "'two'"
    long = echo("x" * 1000)
    assert len(long) == 60 and long.endswith("…")


@pytest.mark.skipif(sys.platform == "win32", reason="flock is POSIX")
def test_a_held_lock_refuses_a_second_taker_and_is_gone_when_released(tmp_path):
    first = lock_run_dir(tmp_path, "--out", "wait for it")
    assert first.held and first.created and (tmp_path / LOCK_FILE).is_file()
    first.claim("run")
    assert (tmp_path / LOCK_FILE).read_text().split()[0] == str(os.getpid())
    # another open file of the same lock (also in this process) is refused, without waiting
    with pytest.raises(StudyError, match=rf"in use by another flexopt run \(pid {os.getpid()}\)"):
        lock_run_dir(tmp_path, "--resume", "wait for it")
    first.release()
    first.release()  # idempotent
    assert not (tmp_path / LOCK_FILE).exists()
    with lock_run_dir(tmp_path, "--out", "") as again:
        assert again.held
    assert os.listdir(tmp_path) == []


@pytest.mark.skipif(sys.platform == "win32", reason="flock is POSIX")
def test_the_lock_file_of_a_killed_run_is_taken_over(tmp_path):
    """A killed holder's lock is dropped by the kernel; its lock file stays and is reused. A
    taker that writes nothing leaves it as it was; one that claims the folder removes it."""
    stale = tmp_path / LOCK_FILE
    stale.write_text("999999 elsewhere run\n")
    with lock_run_dir(tmp_path, "--resume", "") as lock:
        assert not lock.created
    assert stale.read_text() == "999999 elsewhere run\n"
    with lock_run_dir(tmp_path, "--resume", "") as lock:
        lock.claim("run")
    assert not stale.exists()


def _solve_for_a_while(started) -> None:
    started.set()
    time.sleep(3.0)


@pytest.mark.skipif(sys.platform != "linux", reason="workers fork on Linux")
def test_a_forked_worker_does_not_keep_the_folder_locked(tmp_path):
    (tmp_path / LOCK_FILE).write_text("")  # left by a killed run: kept, so the same file is locked
    lock = lock_run_dir(tmp_path, "--out", "")
    assert not lock.created
    ctx = multiprocessing.get_context("fork")
    started = ctx.Event()
    worker = ctx.Process(target=_solve_for_a_while, args=(started,))
    worker.start()
    try:
        assert started.wait(30)  # the worker runs (the fork's hooks are done)
        lock.release()  # the run ends (or is killed) while its worker still solves
        with lock_run_dir(tmp_path, "--resume", "") as again:
            assert again.held
    finally:
        worker.terminate()
        worker.join()


def test_to_json_fast_paths_match_the_general_conversion():
    """to_json's exact-type fast paths (floats, lists, numeric arrays) give the text of the
    general conversion: numpy scalars as Python ones, NaN and inf as null, arrays as lists."""
    import json
    import math
    from collections.abc import Mapping

    import numpy as np
    from flexopt.pipeline.runfolder import to_json

    def general(value):  # the conversion before the fast paths, as the reference
        if isinstance(value, Mapping):
            return {str(k): general(v) for k, v in value.items()}
        if isinstance(value, list | tuple | np.ndarray):
            return [general(v) for v in value]
        if isinstance(value, np.generic):
            value = value.item()
        if isinstance(value, float) and not math.isfinite(value):
            return None
        return value

    rng = np.random.default_rng(3)
    data = {
        "population": [[float(v) for v in row] for row in rng.random((4, 3))],
        "array": rng.random((2, 3)),
        "with_nan": np.array([np.nan, 1.0, -np.inf]),
        "ints": np.array([1, 2], dtype=np.int32),
        "flags": np.array([True, False]),
        "scalars": [np.float32(1.5), np.int64(7), np.float64("nan"), True, None, "x", 3],
        "nested": {1: (float("inf"), [np.array([0.25])])},
        "words": np.array(["a", "b"]),
        "empty": np.empty((0, 2)),
    }
    expected = json.dumps(general(data), indent=2, allow_nan=False, default=str) + "\n"
    assert to_json(data) == expected
