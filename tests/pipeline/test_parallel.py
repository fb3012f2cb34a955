"""Parallel evaluation and fault isolation in this process and the local process pool.

A design that raises, returns NaN, fails to mesh, hangs past the time limit or kills its worker
must end as an infeasible row with its reason while the run goes on. The Dask backend and the
same-run-on-every-backend test are in test_runner_dask.py (its cluster's threads would make the
pool here start its workers by forkserver instead of fork, which is slower).
"""

from __future__ import annotations

import json
from pathlib import Path

import flexopt_toys  # registers the toy_faults kind; importable by workers
import numpy as np
import pytest
from flexopt.pipeline.backends import open_backend
from flexopt.pipeline.cli import main
from flexopt.pipeline.parallel import (
    BackendError,
    ParallelSettings,
    ProcessPool,
    SerialBackend,
    chunk_rows,
    evaluate_one,
    timeout_reason,
)
from flexopt.pipeline.plots import plot_response, quantity_name
from flexopt.pipeline.run import parallel_settings, prepare_run, run_study
from flexopt.pipeline.runfolder import read_records_csv
from flexopt.pipeline.study import validate_study


def toy_setup(**geometry):
    study = validate_study(flexopt_toys.study(**geometry))
    return prepare_run(study)


def run_toy(tmp_path: Path, name: str, settings: ParallelSettings, **geometry):
    return run_study(toy_setup(**geometry), out=tmp_path / name, parallel=settings)


def table(run_dir: Path, columns=("generation", "index", "a", "b", "c", "error", "sum_excess")):
    rows = read_records_csv(run_dir / "evaluations.csv")
    return [{k: r[k] for k in (*columns, "feasible", "reason")} for r in rows]


# --------------------------------------------------------------------------------------------
# Identical results on every backend


def test_settings_from_the_study_and_the_command_line(tmp_path):
    raw = flexopt_toys.study()
    raw["parallel"] = {"workers": 3, "eval_timeout_s": 2.5}
    study = validate_study(raw)
    assert parallel_settings(study) == ParallelSettings("processes", 3, None, 2.5)
    assert parallel_settings(study, workers=1).backend == "serial"
    dask = parallel_settings(study, dask="tcp://h:8786", eval_timeout_s=1.0)
    assert (dask.backend, dask.address, dask.eval_timeout_s) == ("dask", "tcp://h:8786", 1.0)
    default = parallel_settings(validate_study(flexopt_toys.study()))
    assert default.backend == "processes" and default.n_workers >= 1
    assert chunk_rows(40, 2) == 1 and chunk_rows(40, 2, per_worker=4) == 5
    assert chunk_rows(400, 2) == 7  # 32 chunks per worker: one more is queued in its pipe
    assert chunk_rows(3, 2) == 1 and chunk_rows(40, 2, 7) == 7

    raw["parallel"] = {"backend": "dask"}
    with pytest.raises(Exception, match="parallel.address"):
        parallel_settings(validate_study(raw))
    raw["parallel"] = {"backend": "dask", "address": "localhost"}
    with pytest.raises(Exception, match="tcp://host:8786"):
        validate_study(raw)


# --------------------------------------------------------------------------------------------
# Faults


def test_time_limit_in_this_process():
    problem = toy_setup(hang_above=0.5, hang_s=5.0).problem
    slow = evaluate_one(problem, np.array([0.9, 0.1, 0.1]), timeout_s=0.2)
    assert slow.reason == timeout_reason(0.2) and not slow.feasible
    assert 0.15 < slow.time_s < 2.0
    fast = evaluate_one(problem, np.array([0.1, 0.1, 0.1]), timeout_s=0.2)
    assert fast.reason == "" and fast.feasible
    out = SerialBackend(0.2)(problem, np.array([[0.9, 0.1, 0.1], [0.2, 0.2, 0.2]]))
    assert [bool(e.reason) for e in out] == [True, False]


def test_pool_watchdog_replaces_a_stuck_worker_and_resubmits_the_rest():
    problem = toy_setup(hang_above=0.5, hang_s=60.0).problem
    X = np.array([[0.1, 0.1, 0.0], [0.9, 0.1, 0.0], [0.2, 0.3, 0.0], [0.3, 0.2, 0.1]])
    seen = []
    with open_backend(
        ParallelSettings("processes", 2, eval_timeout_s=0.5, chunk_size=2), problem
    ) as pool:
        assert isinstance(pool, ProcessPool)
        out = pool(problem, X, on_result=lambda row, ev: seen.append(row))
        assert pool.n_replaced == 1 and len(pool.workers) == 2  # replaced, not lost
        again = pool(problem, X[:1])  # the pool still works
    assert sorted(seen) == [0, 1, 2, 3]
    assert [e.reason for e in out] == ["", timeout_reason(0.5), "", ""]
    assert again[0].f[0] == out[0].f[0]
    assert not any(p.is_alive() for p in (w.process for w in pool.workers))


def test_pool_resubmits_the_designs_of_a_worker_that_died(tmp_path):
    markers = tmp_path / "markers"
    markers.mkdir()
    problem = toy_setup(exit_once_above=0.6, marker_dir=str(markers)).problem
    rng = np.random.default_rng(1)
    X = rng.random((12, 3))
    expected = SerialBackend()(toy_setup().problem, X)
    with open_backend(ParallelSettings("processes", 2, chunk_size=3), problem) as pool:
        out = pool(problem, X)
        n_replaced = pool.n_replaced
    assert n_replaced == sum(X[:, 0] > 0.6) > 0  # each such design killed one worker once
    assert [e.f[0] for e in out] == [e.f[0] for e in expected]
    assert not any(e.reason for e in out)


def test_a_worker_whose_pipe_breaks_as_designs_are_sent_is_replaced(monkeypatch):
    """A worker can die between the pool's wait and its next send: the send raises
    BrokenPipeError (seen in CI), and that worker's designs, the chunk being sent too, go to
    a new worker instead of crashing the run."""
    from multiprocessing.connection import Connection

    problem = toy_setup().problem
    X = np.random.default_rng(2).random((12, 3))
    expected = SerialBackend()(problem, X)
    send = Connection.send
    failed = []

    def send_once_broken(self, obj):
        if isinstance(obj, list) and obj and not failed:  # the first chunk of designs
            failed.append(True)
            raise BrokenPipeError(32, "Broken pipe")
        return send(self, obj)

    with open_backend(ParallelSettings("processes", 2, chunk_size=3), problem) as pool:
        monkeypatch.setattr(Connection, "send", send_once_broken)
        out = pool(problem, X)
        monkeypatch.setattr(Connection, "send", send)
        n_replaced = pool.n_replaced
    assert failed and n_replaced == 1
    assert [e.f[0] for e in out] == [e.f[0] for e in expected]
    assert not any(e.reason for e in out)


def test_a_design_that_always_kills_its_worker_is_a_failed_row(tmp_path, capsys):
    """os._exit in evaluate: tried MAX_ATTEMPTS times, then WorkerDied, and the run finishes."""
    outcome = run_toy(
        tmp_path, "run", ParallelSettings("processes", 2, chunk_size=2), exit_above=0.85
    )
    rows = read_records_csv(outcome.run_dir / "evaluations.csv")
    died = [r for r in rows if r["reason"].startswith("WorkerDied")]
    assert died and all(float(r["a"]) > 0.85 for r in died)
    assert "exit code 3" in died[0]["reason"] and "3 times" in died[0]["reason"]
    assert len(died) == sum(float(r["a"]) > 0.85 for r in rows)
    assert outcome.record["status"] == "finished" and outcome.result.best.feasible


@pytest.mark.e2e
def test_cli_time_limit_marks_slow_designs_and_the_run_goes_on(tmp_path, capsys):
    path = tmp_path / "toy.yaml"
    path.write_text(json.dumps(flexopt_toys.study(hang_above=0.8, hang_s=30.0)))
    out = tmp_path / "run"
    argv = ["run", str(path), "--out", str(out), "-q", "--workers", "2", "--eval-timeout", "0.8"]
    assert main(argv) == 0
    rows = read_records_csv(out / "evaluations.csv")
    slow = [r for r in rows if float(r["a"]) > 0.8]
    assert slow and all(r["reason"] == timeout_reason(0.8) for r in slow)
    assert all(r["reason"] == "" for r in rows if float(r["a"]) <= 0.8)
    record = json.loads((out / "run.json").read_text())
    assert record["parallel"]["eval_timeout_s"] == 0.8
    assert record["failure_reasons"] == {timeout_reason(0.8): len(slow)}


def test_a_problem_that_cannot_be_pickled_is_a_clear_error():
    class Local:  # a class defined in a function cannot be pickled
        space = toy_setup().problem.space
        objective_names = ("f",)
        constraint_names = ()

        def evaluate(self, x):
            raise NotImplementedError

    with pytest.raises(BackendError, match="--workers 1"):
        ProcessPool(Local(), 2)


# --------------------------------------------------------------------------------------------
# Plot words from the kind (shared-pipeline request)


def test_response_plot_words_come_from_the_kind():
    assert quantity_name("contact_force_N") == "contact force"
    assert quantity_name("torque_Nm_1") == "torque"
    assert quantity_name("stiffness_N_per_mm") == "stiffness"
    assert quantity_name("rotation_deg") == "rotation" and quantity_name("time_ms") == "time"
    t = {"rotation_deg": np.linspace(0, 10, 5), "torque_Nmm": np.arange(5.0)}
    png = plot_response(t, "rotation_deg", "torque_Nmm", "peak_stress_MPa", 30.0)  # one panel
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
