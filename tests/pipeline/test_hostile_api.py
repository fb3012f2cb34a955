"""Unbounded or unchecked inputs (issue 23, class 8): the API gets a study file's limits, counts
are capped, flags are type-checked, outputs cannot refer to each other in a loop, and numpy's
RuntimeWarnings stay off stderr without ``-v``.
"""

from __future__ import annotations

import subprocess
import sys

import flexopt
import numpy as np
import pytest
import yaml
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.evaluate import MAX_REPEAT
from flexopt.pipeline.study import MAX_STUDY_DEPTH, load_study, resolve_study_path


def _cantilever() -> dict:
    return yaml.safe_load(resolve_study_path("cantilever").read_text(encoding="utf-8"))


def _self_containing() -> dict:
    raw = _cantilever()
    raw["geometry"]["extra"] = raw
    return raw


def _deep_list(depth: int = 100_000) -> dict:
    nested: list = []
    cur = nested
    for _ in range(depth):
        nxt: list = []
        cur.append(nxt)
        cur = nxt
    raw = _cantilever()
    raw["geometry"]["points_mm"] = nested
    return raw


def _points(n: int, array: bool = False) -> dict:
    raw = _cantilever()
    pts = [[float(i), 0.0] for i in range(n)]
    raw["geometry"]["points_mm"] = np.array(pts) if array else pts
    return raw


CASES = {
    "contains_itself": (_self_containing, "contains itself"),
    "nested_100000_deep": (_deep_list, f"nested more than {MAX_STUDY_DEPTH} levels"),
    "nested_just_over": (lambda: _deep_list(MAX_STUDY_DEPTH + 1), "nested more than"),
    "a_million_points": (lambda: _points(1_000_000), "more than 20000 values"),
    "a_million_points_as_an_array": (lambda: _points(1_000_000, True), "more than 20000 values"),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES))
def test_api_study_data_has_the_limits_of_a_study_file(case, tmp_path, monkeypatch, solve_log):
    monkeypatch.chdir(tmp_path)
    make, fragment = CASES[case]
    raw = make()
    for call in (flexopt.load_study, flexopt.evaluate):
        with pytest.raises(StudyError, match=fragment) as caught:
            call(raw)
        assert solve_log.count == 0, solve_log.calls  # how quickly: benchmarks/refusals.py
        assert "\n" not in str(caught.value)
    assert list(tmp_path.iterdir()) == []


def test_api_limits_leave_ordinary_data_alone():
    raw = _cantilever()
    raw["geometry"]["points_mm"] = np.array(raw["geometry"]["points_mm"], dtype=float)
    assert flexopt.load_study(raw).kind == "polyline_beam"


@pytest.mark.parametrize("repeat", [MAX_REPEAT + 1, 10**12])
def test_repeat_is_capped_in_the_api_and_the_cli(repeat, tmp_path, monkeypatch, capsys, solve_log):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(StudyError, match=f"at most {MAX_REPEAT}"):
        flexopt.evaluate("cantilever", repeat=repeat)
    assert main(["evaluate", "cantilever", "--repeat", str(repeat)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"more than {MAX_REPEAT}" in err and "--repeat" in err
    assert solve_log.count == 0, "solved before the cap was checked"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [({"quick": "no"}, "quick"), ({"quick": 1}, "quick"), ({"progress": "yes"}, "progress")],
)
def test_flags_are_true_or_false(kwargs, key, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(StudyError, match=rf"^{key}: got .*; give True or False$"):
        flexopt.run("constant-force", **kwargs)
    assert list(tmp_path.iterdir()) == []


LOOP = "  a_N: {quantity: slope, of: b_N}\n  b_N: {quantity: slope, of: a_N}\n"


def test_outputs_that_refer_to_each_other_in_a_loop_are_refused_at_load(tmp_path):
    text = resolve_study_path("parallel-guide").read_text(encoding="utf-8")
    anchor = "  stiffness_N_per_mm: {quantity: slope, of: force_N}\n"
    assert anchor in text
    path = tmp_path / "loop.yaml"
    path.write_text(text.replace(anchor, anchor + LOOP))
    with pytest.raises(
        StudyError, match=r"outputs\.a_N\.of: outputs refer to each other in a loop"
    ):
        load_study(path)
    # a chain that ends in a measured output is fine (stiffness_N_per_mm of force_N)
    chained = tmp_path / "chain.yaml"
    chained.write_text(
        text.replace(anchor, anchor + "  k2_N: {quantity: slope, of: stiffness_N_per_mm}\n")
    )
    load_study(chained)


@pytest.mark.slow
def test_numpy_runtime_warnings_stay_off_stderr_without_v():
    code = (
        "import sys, numpy as np; from flexopt.pipeline import cli; original = cli._list\n"
        "def noisy(args):\n"
        "    np.float64(0.0) / np.float64(0.0)\n"
        "    np.log(np.array([-1.0]))\n"
        "    return original(args)\n"
        "cli._list = noisy\n"
        "sys.exit(cli.main(sys.argv[1:]))\n"
    )
    quiet = subprocess.run(
        [sys.executable, "-c", code, "list"], capture_output=True, text=True, timeout=120
    )
    assert quiet.returncode == 0 and quiet.stderr == "", quiet.stderr
    verbose = subprocess.run(
        [sys.executable, "-c", code, "-v", "list"], capture_output=True, text=True, timeout=120
    )
    assert verbose.returncode == 0 and "RuntimeWarning" in verbose.stderr


@pytest.mark.parametrize("case", ["contains_itself", "a_million_points"])
def test_study_changes_from_python_have_the_limits_too(case, solve_log):
    study = flexopt.load_study("cantilever")
    raw = CASES[case][0]()
    value = raw if case == "contains_itself" else raw["geometry"]["points_mm"]
    with pytest.raises(StudyError, match=CASES[case][1]):
        study.with_values({"geometry.points_mm": value})
    with pytest.raises(StudyError, match=CASES[case][1]):
        study.replace(geometry={"kind": "polyline_beam", "points_mm": value})
    assert solve_log.count == 0  # how quickly: benchmarks/refusals.py
