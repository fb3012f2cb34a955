"""Run-folder helpers: atomic writes, CSV cells, strict JSON, folder names."""

from __future__ import annotations

import json
import os
from datetime import datetime

import numpy as np
import pytest

from pipeline.errors import StudyError
from pipeline.runfolder import (
    check_out_dir,
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
