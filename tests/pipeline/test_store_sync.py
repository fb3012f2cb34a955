"""The evaluation store's grouped fsync (issue 13): lines written at once, fsynced in groups."""

from __future__ import annotations

import os

import numpy as np
import pytest
from flexopt.optimise.evaluation import Evaluation
from flexopt.pipeline.checkpoint import EvaluationStore


def evaluation(i: int) -> Evaluation:
    return Evaluation(np.array([0.1 * i, 1.0 / 3.0]), np.array([float(i)]), np.zeros(1))


@pytest.fixture
def fsyncs(monkeypatch):
    """Count os.fsync calls made by the store."""
    calls: list[int] = []
    real = os.fsync

    def counted(fd: int) -> None:
        calls.append(fd)
        real(fd)

    monkeypatch.setattr("flexopt.pipeline.checkpoint.os.fsync", counted)
    return calls


def test_append_writes_at_once_and_syncs_in_groups(tmp_path, fsyncs):
    store = EvaluationStore(tmp_path / "evaluations.jsonl", sync_interval_s=3600.0)
    for i in range(5):
        store.append(evaluation(i))
        # Each line is in the file (the kernel has it) as soon as append returns: a SIGKILL of
        # this process cannot lose it. A second reader sees every line.
        assert len(EvaluationStore(store.path).load()) == i + 1
    assert fsyncs == []  # none yet: the interval has not passed
    store.sync()
    assert len(fsyncs) == 1 and store.n_synced == 5
    store.sync()  # nothing new: no fsync
    assert len(fsyncs) == 1
    store.append(evaluation(5))
    store.close()  # closing syncs what is left
    assert len(fsyncs) == 2 and store.n_synced == 6
    back = EvaluationStore(store.path).load()
    assert [ev.f[0] for ev in back] == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    np.testing.assert_array_equal(back[3].x, evaluation(3).x)  # same bits


def test_interval_zero_fsyncs_every_line(tmp_path, fsyncs):
    store = EvaluationStore(tmp_path / "evaluations.jsonl", sync_interval_s=0.0)
    for i in range(3):
        store.append(evaluation(i))
    assert len(fsyncs) == 3
    store.close()
    assert len(fsyncs) == 3  # nothing left to sync


def test_append_syncs_by_itself_when_the_last_sync_is_old(tmp_path, fsyncs, monkeypatch):
    now = [1000.0]
    monkeypatch.setattr("flexopt.pipeline.checkpoint.time.monotonic", lambda: now[0])
    store = EvaluationStore(tmp_path / "evaluations.jsonl", sync_interval_s=5.0)
    store.append(evaluation(0))
    now[0] += 4.0
    store.append(evaluation(1))
    assert fsyncs == []
    now[0] += 1.0  # 5 s since the store was opened / last synced
    store.append(evaluation(2))
    assert len(fsyncs) == 1 and store.n_synced == 3
    store.close()
