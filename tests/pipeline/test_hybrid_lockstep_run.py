"""The constant-force study's hybrid run with its starts in lockstep, their exact Jacobians and
plane-stress checks on the pool's two workers, against the same run with the starts one after
the other and every hook in the run's process (the stage as it ran before session 28; each check
on the pool split into its two parts, session 31): every
start asks for the same designs, to the bit, and the run ends on the same best design, report
and verdict (issue 27: the gradient stage on both cores). A run killed in its gradient stage
resumes on the pool to the same tables and end."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from flexopt.optimise import hybrid
from flexopt.pipeline.parallel import ParallelSettings
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.run.resume import resume_run
from flexopt.pipeline.runfolder import read_records_csv
from flexopt.pipeline.study import HybridSpec, load_study

ROOT = Path(__file__).resolve().parents[2]


def small_study():
    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    optimiser = study.optimiser.model_copy(
        update={
            "method": "hybrid",
            # 6 iterations: both starts restored (session 33: start 1 needs its 6th)
            "hybrid": HybridSpec(ga_n_gen=2, starts=2, max_iter=6),
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
    sent: list[str] = []  # the calls the pool was sent
    split = hybrid._Stage._split

    def spy(self, calls):
        out = split(self, calls)
        sent.extend(kind for kind, _ in out[0])
        return out

    monkeypatch.setattr(hybrid._Stage, "_split", spy)
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
    assert a["jacobians"]["exact"] > 2 and a["checks"]["count"] >= 1  # the hooks did run
    # every start checked, or spared its check by the lower start's met one (optimise/hybrid.py)
    assert a["checks"]["count"] + a["checks"]["spared"] == 2
    assert len(concurrent) == 2 and concurrent == sequential
    # each check went to the workers as its two parts (pipeline/studies/_constant_force_split.py)
    assert "check" not in sent
    assert sent.count("check:0") == sent.count("check:1") == a["checks"]["count"]
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


def table(run_dir: Path) -> list[dict[str, str]]:
    rows = read_records_csv(run_dir / "evaluations.csv")
    for row in rows:
        del row["time_s"]
    return rows


@pytest.mark.slow
def test_a_lockstep_run_killed_in_its_gradient_stage_resumes_to_the_same_end(tmp_path):
    two = ParallelSettings("processes", 2)
    reference = run_study(prepare_run(small_study()), out=tmp_path / "ref", parallel=two)
    n = reference.record["n_evaluations"]
    ga = reference.record["hybrid"]["n_evaluations"]["ga"]
    killed = tmp_path / "killed"
    shutil.copytree(tmp_path / "ref", killed)
    stored = (killed / "evaluations.jsonl").read_text().splitlines(keepends=True)
    keep = ga + (n - ga) // 2  # killed half way through the gradient stage
    (killed / "evaluations.jsonl").write_text("".join(stored[:keep]))
    record = json.loads((killed / "run.json").read_text())
    record["status"] = "running"
    (killed / "run.json").write_text(json.dumps(record))

    resumed = resume_run(killed, parallel=two)
    assert resumed.record["status"] == "finished"
    assert resumed.record["n_restored"] == keep
    assert resumed.record["n_solved"] == n - keep  # nothing solved twice
    assert table(killed) == table(tmp_path / "ref")
    a, b = resumed.record["hybrid"], reference.record["hybrid"]
    a["checks"].pop("time_s"), b["checks"].pop("time_s")
    assert a == b
    assert resumed.result.best.x.tobytes() == reference.result.best.x.tobytes()
