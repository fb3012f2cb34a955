"""progress._where: the "on processes (2 workers)" decoration never raises."""

from __future__ import annotations

import json

import pytest
from flexopt.pipeline.progress import _where


@pytest.mark.parametrize(
    "record",
    [
        [1, 2],
        "text",
        {"parallel": "2 workers"},
        {"parallel": {"description": "2 workers"}, "resumed": "abc"},
        {"parallel": {"description": "2 workers"}, "resumed": [3]},
    ],
)
def test_a_damaged_run_json_leaves_the_decoration_out(tmp_path, record):
    (tmp_path / "run.json").write_text(json.dumps(record), encoding="utf-8")
    assert _where(tmp_path) == ""


def test_the_decoration_from_a_good_record(tmp_path):
    record = {"parallel": {"description": "processes (2 workers)"}, "resumed": [{"n_in_store": 40}]}
    (tmp_path / "run.json").write_text(json.dumps(record), encoding="utf-8")
    assert _where(tmp_path) == ", on processes (2 workers); resuming with 40 designs from the store"
    record["resumed"] = []  # never resumed
    (tmp_path / "run.json").write_text(json.dumps(record), encoding="utf-8")
    assert _where(tmp_path) == ", on processes (2 workers)"
    (tmp_path / "run.json").write_text("{not json", encoding="utf-8")
    assert _where(tmp_path) == ""
    assert _where(tmp_path / "missing") == ""
