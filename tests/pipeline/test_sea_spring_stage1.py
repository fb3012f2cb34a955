"""Stage 1 of the sea_spring kind on two cores: a forked child solves a share of the screening
runs; the result is the serial one bit for bit, also when the child dies; no process is left."""

from __future__ import annotations

import logging
import multiprocessing
import os
import pickle
import sys
import threading
import time
from pathlib import Path

import flexopt.pipeline.screening as screening_mod
import flexopt.pipeline.studies.sea_spring as ss
import pytest
from flexopt.pipeline.study import validate_study

# a coarse spiral study without fillets or hub holes: 25 array rows (13 cannot be built) +
# confirmation + 2 extra runs in ~2 s
STUDY = {
    "name": "sea-stage1",
    "geometry": {"kind": "sea_spring", "topology": "spiral", "fillet_mm": 0.0,
                 "root_fillet_mm": 0.0, "hub_holes": 0},
    "material": "maraging-300",
    "mesh": {"max_edge_mm": 10.0, "fillet_segments": 1, "elements_through": 0.5},
    "taguchi": {"enabled": True, "extra_runs": 2},
}  # fmt: skip
FORK = multiprocessing.get_context("fork") if sys.platform == "linux" else None
needs_fork = pytest.mark.skipif(FORK is None, reason="stage 1 forks only on Linux")


@pytest.fixture(autouse=True)
def _fork_beside_the_timeout_thread(monkeypatch):
    # Stage 1 does not fork from a process that runs other threads; pytest-timeout's thread
    # (timeout_method = "thread") only waits for the test to end, so the tests let it fork.
    real = screening_mod.fork_context_here
    monkeypatch.setattr(screening_mod, "fork_context_here", lambda: FORK)
    return real


def test_no_fork_beside_another_thread(_fork_beside_the_timeout_thread):
    stop = threading.Event()
    thread = threading.Thread(target=stop.wait)
    thread.start()
    try:
        assert _fork_beside_the_timeout_thread() is None
    finally:
        stop.set()
        thread.join()


def _children() -> set[int]:
    """Processes whose parent is this one, zombies included (Linux /proc)."""
    me, out = os.getpid(), set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # ended meanwhile
            continue
        if int(fields[1]) == me:
            out.add(int(stat.parent.name))
    return out


def _stage1(fork: bool, monkeypatch: pytest.MonkeyPatch) -> tuple[bytes, dict]:
    monkeypatch.setattr(ss, "TAGUCHI_FORK", fork)
    stage1 = ss.run_taguchi(validate_study(STUDY))
    assert stage1["time_s"] > 0.0
    # every other key bit for bit (pickle: NaN of failed rows compares equal to itself)
    return pickle.dumps({k: v for k, v in stage1.items() if k != "time_s"}), stage1


def _solved_in_child(caplog: pytest.LogCaptureFixture) -> int:
    msgs = [r.getMessage() for r in caplog.records if "solved in the second process" in r.message]
    assert len(msgs) == 1, msgs
    return int(msgs[0].split()[2])


@needs_fork
def test_forked_stage1_equals_the_serial_one_and_leaves_no_process(monkeypatch, caplog):
    before = _children()
    with caplog.at_level(logging.INFO, logger=screening_mod.__name__):
        serial, _ = _stage1(False, monkeypatch)
        assert not any("second process" in r.message for r in caplog.records)
        forked, stage1 = _stage1(True, monkeypatch)
    n_runs = 25 + 1 + STUDY["taguchi"]["extra_runs"]
    # both processes worked (else the comparison would not test the split)
    assert 0 < _solved_in_child(caplog) < n_runs - 1
    assert forked == serial
    assert not [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(stage1["additivity"]["extra_residuals_dB"]) == 2
    assert _children() == before  # the child ended and was reaped: no zombie


def _dies_after_taking_a_run(screening, receive, send) -> None:
    screening.claim(lambda: True)
    os._exit(3)  # a crash: the run it took is never sent


def _dies_holding_the_lock(screening, receive, send) -> None:
    screening._lock.acquire()
    os._exit(3)


def _hangs_after_taking_a_run(screening, receive, send) -> None:
    screening.claim(lambda: True)
    time.sleep(600)


def _hangs_holding_the_lock(screening, receive, send) -> None:
    screening._lock.acquire()
    time.sleep(600)


@needs_fork
@pytest.mark.parametrize(
    ("child", "note"),
    [
        (_dies_after_taking_a_run, "ended (exit code 3)"),
        (_dies_holding_the_lock, "ended (exit code 3)"),
        (_hangs_after_taking_a_run, None),  # its run is taken over, the child ended at close
        (_hangs_holding_the_lock, "is stuck"),
    ],
)
def test_a_child_that_dies_or_hangs_leaves_its_runs_to_this_process(
    child, note, monkeypatch, caplog
):
    study = validate_study(STUDY)
    frame, material = ss.spring_frame(study), study.material.to_material()
    # three springs and a row that cannot be built (its slots close)
    jobs = [(0, 0, 0, 0, 0, 0), (1, 2, 3, 4, 0, 1), (0, 1, 2, 3, 4, 0), (1, 1, 1, 1, 1, 1)]
    serial = [ss._screen_one(levels, frame, material, study) for levels in jobs]
    before = _children()
    monkeypatch.setattr(screening_mod, "screening_child", child)
    screening = screening_mod.Screening(
        jobs, lambda levels: ss._screen_one(levels, frame, material, study), fork=True,
        label="stage 1",
    )  # fmt: skip
    assert screening._process is not None
    with caplog.at_level(logging.INFO, logger=screening_mod.__name__):
        try:
            got = screening.get(len(jobs))
        finally:
            screening.close()
    assert pickle.dumps(got) == pickle.dumps(serial)
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    if note is None:
        assert warnings == []
    else:
        assert len(warnings) == 1 and note in warnings[0], warnings
    assert screening.in_child == 0
    assert _children() == before  # ended and reaped, also when it hung
