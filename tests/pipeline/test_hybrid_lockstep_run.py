"""The constant-force study's hybrid run with its starts in lockstep, their exact Jacobians and
plane-stress checks on the pool's two workers, against the same run with the starts one after
the other and every hook in the run's process (the stage as it ran before session 28): every
start asks for the same designs, to the bit, and the run ends on the same best design, report
and verdict (issue 27: the gradient stage on both cores)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from flexopt.optimise import hybrid
from flexopt.pipeline.parallel import ParallelSettings
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.study import HybridSpec, load_study

ROOT = Path(__file__).resolve().parents[2]


def small_study():
    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    optimiser = study.optimiser.model_copy(
        update={
            "method": "hybrid",
            "hybrid": HybridSpec(ga_n_gen=2, starts=2, max_iter=5),
            "pop_size": 16,
            "seed": 1,
        }
    )
    return study.model_copy(update={"optimiser": optimiser})


@pytest.mark.slow
def test_lockstep_on_the_pool_asks_for_the_designs_the_sequential_stage_does(tmp_path, monkeypatch):
    seen: dict[int, list[bytes]] = {}
    ask = hybrid._Start.batch

    def batch(self, U):
        evaluations = yield from ask(self, U)
        seen.setdefault(id(self), []).extend(e.x.tobytes() for e in evaluations)
        return evaluations

    monkeypatch.setattr(hybrid._Start, "batch", batch)
    import flexopt.pipeline.run.runner as runner

    stage = runner.run_hybrid
    pool = run_study(
        prepare_run(small_study()), out=tmp_path / "pool", parallel=ParallelSettings("processes", 2)
    )
    concurrent = list(seen.values())
    seen.clear()

    def one_after_the_other(*args, **kwargs):
        kwargs.pop("requests")  # every hook in this process
        return stage(*args, **kwargs, lockstep=False)

    monkeypatch.setattr(runner, "run_hybrid", one_after_the_other)
    alone = run_study(
        prepare_run(small_study()), out=tmp_path / "serial", parallel=ParallelSettings("serial")
    )
    sequential = list(seen.values())
    a, b = pool.record["hybrid"], alone.record["hybrid"]
    assert a["jacobians"]["exact"] > 2 and a["checks"]["count"] >= 2  # the hooks did run
    assert len(concurrent) == 2 and concurrent == sequential
    assert pool.result.best.x.tobytes() == alone.result.best.x.tobytes()
    assert pool.result.best.f.tobytes() == alone.result.best.f.tobytes()
    a["checks"].pop("time_s"), b["checks"].pop("time_s")
    assert a == b
    # fewer batches than designs: the two starts' requests went to the pool together
    assert len(pool.result.generations) < len(alone.result.generations)
    verdicts = [
        json.loads((tmp_path / d / "best.json").read_text())["verdict"] for d in ("pool", "serial")
    ]
    assert verdicts[0] == verdicts[1]
