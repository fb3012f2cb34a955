"""The Dask backend, and the same run on every backend (serial, process pool, Dask).

For a fixed seed the evaluations.csv design and objective columns and the best design must be
identical whatever evaluated the designs. One Dask LocalCluster (2 worker processes, 1 thread
each) serves the whole module; it is named to run after the other runner tests, whose process
pools fork faster while no cluster thread is alive.
"""

from __future__ import annotations

import json
from pathlib import Path

import flexopt_toys  # registers the toy_faults kind; importable by workers
import numpy as np
import pytest

from pipeline.cli import main
from pipeline.parallel import ParallelSettings, open_backend, timeout_reason
from pipeline.run import prepare_run, run_study
from pipeline.runfolder import read_records_csv
from pipeline.study import validate_study

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def cluster():
    """One LocalCluster for the module (a cluster takes seconds to start)."""
    import dask

    # a design that kills its worker is given up after 2 deaths, not 4 (the default 3 retries)
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        cluster = distributed.LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=40,
        )
        try:
            yield cluster
        finally:
            cluster.close()


def toy_setup(**geometry):
    study = validate_study(flexopt_toys.study(**geometry))
    return prepare_run(study)


def run_toy(tmp_path: Path, name: str, settings: ParallelSettings, **geometry):
    return run_study(toy_setup(**geometry), out=tmp_path / name, parallel=settings)


def table(run_dir: Path, columns=("generation", "index", "a", "b", "c", "error", "sum_excess")):
    rows = read_records_csv(run_dir / "evaluations.csv")
    return [{k: r[k] for k in (*columns, "feasible", "reason")} for r in rows]


FAULTS = {"raise_above": 0.9, "nan_above": 0.8, "mesh_fail_above": 0.7}


def test_serial_processes_and_dask_give_the_same_run(tmp_path, cluster):
    serial = run_toy(tmp_path, "serial", ParallelSettings("serial"), **FAULTS)
    pool = run_toy(tmp_path, "pool", ParallelSettings("processes", workers=2), **FAULTS)
    dask = run_toy(
        tmp_path,
        "dask",
        ParallelSettings("dask", address=cluster.scheduler_address, chunk_size=3),
        **FAULTS,
    )
    reference = table(serial.run_dir)
    assert any(r["reason"] for r in reference)  # the faults are in the comparison
    for other in (pool, dask):
        assert table(other.run_dir) == reference
        assert np.array_equal(other.result.best.x, serial.result.best.x)
        assert other.record["n_evaluations"] == serial.record["n_evaluations"]
        assert other.record["status"] == "finished"
    assert pool.record["parallel"]["description"] == "processes (2 workers)"
    assert dask.record["parallel"]["backend"] == "dask"
    reasons = {r["reason"].split(":")[0] for r in reference if r["reason"]}
    assert reasons <= {"RuntimeError", "non-finite result (f = [nan], g = [0.0])", "MeshError"}
    assert "RuntimeError" in reasons and "MeshError" in reasons


def test_an_unreachable_scheduler_is_one_line_and_nothing_is_written(tmp_path, capsys):
    path = tmp_path / "toy.yaml"
    path.write_text(json.dumps(flexopt_toys.study()))
    out = tmp_path / "run"
    argv = ["run", str(path), "--out", str(out), "--dask", "tcp://127.0.0.1:9", "-q"]
    import pipeline.cluster as cluster_module

    old = cluster_module.CONNECT_TIMEOUT_S
    cluster_module.CONNECT_TIMEOUT_S = 2.0
    try:
        assert main(argv) == 2
    finally:
        cluster_module.CONNECT_TIMEOUT_S = old
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--dask" in err and "dask scheduler" in err
    assert not out.exists()


def test_dask_time_limit_and_a_design_that_kills_workers(tmp_path, cluster):
    # limits with room for a loaded machine: 1 s against a fast design of microseconds
    problem = toy_setup(hang_above=0.8, hang_s=4.0, exit_above=0.95).problem
    X = np.array([[0.1, 0.1, 0.0], [0.9, 0.1, 0.0], [0.97, 0.0, 0.0], [0.3, 0.2, 0.1]])
    settings = ParallelSettings(
        "dask", address=cluster.scheduler_address, eval_timeout_s=1.0, chunk_size=2
    )
    with open_backend(settings, problem) as backend:
        out = backend(problem, X)
    assert out[0].reason == "" and out[3].reason == ""
    assert out[1].reason == timeout_reason(1.0)
    assert out[2].reason.startswith("WorkerDied")


def test_flexopt_run_on_dask_from_the_command_line(tmp_path, cluster, capsys):
    path = tmp_path / "toy.yaml"
    path.write_text(json.dumps(flexopt_toys.study(**FAULTS)))
    out = tmp_path / "run"
    address = cluster.scheduler_address
    assert main(["run", str(path), "--out", str(out), "--dask", address]) == 0
    err = capsys.readouterr().err
    assert f"on dask at {address}" in err
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "finished" and record["parallel"]["address"] == address
    assert record["n_failed"] > 0 and record["n_evaluations"] == len(table(out))
