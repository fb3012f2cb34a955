"""``optimiser: {method: hybrid}`` through ``flexopt run``: the runner, store, tables, run.json,
resume of an interrupted hybrid run, and a GA study's files unchanged by the new keys."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import flexopt_toys  # registers the toy_faults kind
import numpy as np
import pytest
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.parallel import ParallelSettings
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.run.resume import resume_run
from flexopt.pipeline.runfolder import read_records_csv
from flexopt.pipeline.study import study_to_yaml, validate_study

SERIAL = ParallelSettings("serial")
HYBRID = {
    "pop_size": 8,
    "n_gen": 3,
    "seed": 5,
    "method": "hybrid",
    "hybrid": {"starts": 2, "max_iter": 20},
}


def hybrid_study(**options):
    raw = flexopt_toys.study()
    raw["optimiser"] = {**HYBRID, **options}
    return validate_study(raw)


def columns(run_dir: Path) -> list[dict[str, str]]:
    rows = read_records_csv(run_dir / "evaluations.csv")
    for row in rows:
        del row["time_s"]
    return rows


def test_a_hybrid_run_records_its_stages(tmp_path):
    outcome = run_study(prepare_run(hybrid_study()), out=tmp_path / "run", parallel=SERIAL)
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert record["status"] == "finished"
    assert record["optimiser"]["method"] == "hybrid"
    assert record["optimiser"]["hybrid"]["local"] == "slsqp"  # the toy gives no residuals
    hybrid = record["hybrid"]
    assert hybrid["best_stage"] == "gradient"
    assert hybrid["n_evaluations"]["ga"] == 24
    # every design of both stages is in the store and the tables
    rows = columns(tmp_path / "run")
    stored = (tmp_path / "run" / "evaluations.jsonl").read_text().splitlines()
    assert len(rows) == len(stored) == record["n_evaluations"]
    assert record["n_evaluations"] <= 24 + hybrid["n_evaluations"]["gradient"]
    assert all(start["stop"] for start in hybrid["starts"])
    # the toy's optimum: (a, b, c) = (0.6, 0.3, 0), error 0
    np.testing.assert_allclose(outcome.result.best.x, [0.6, 0.3, 0.0], atol=1e-3)
    assert record["generations_done"] > 3  # the gradient stage's batches are generations too
    best = json.loads((tmp_path / "run" / "best.json").read_text())
    assert best["verdict"]["overall"]


def test_a_killed_hybrid_run_resumes_to_the_same_end(tmp_path):
    reference = run_study(prepare_run(hybrid_study()), out=tmp_path / "ref", parallel=SERIAL)
    n = reference.record["n_evaluations"]
    ga = reference.record["hybrid"]["n_evaluations"]["ga"]
    # the run as if killed in its gradient stage: its store holds the first designs only
    killed = tmp_path / "killed"
    shutil.copytree(tmp_path / "ref", killed)
    stored = (killed / "evaluations.jsonl").read_text().splitlines(keepends=True)
    keep = ga + (n - ga) // 2
    (killed / "evaluations.jsonl").write_text("".join(stored[:keep]))
    record = json.loads((killed / "run.json").read_text())
    record["status"] = "running"
    (killed / "run.json").write_text(json.dumps(record))

    resumed = resume_run(killed, parallel=SERIAL)
    assert resumed.record["status"] == "finished"
    assert resumed.record["n_restored"] == keep
    assert resumed.record["n_solved"] == n - keep  # nothing solved twice
    assert columns(killed) == columns(tmp_path / "ref")
    assert resumed.record["hybrid"] == reference.record["hybrid"]
    np.testing.assert_array_equal(resumed.result.best.x, reference.result.best.x)


def test_gauss_newton_needs_residuals_and_one_objective():
    with pytest.raises(StudyError, match="gauss_newton needs a least-squares objective"):
        prepare_run(hybrid_study(hybrid={"local": "gauss_newton"}))
    with pytest.raises(StudyError, match="optimiser.method"):
        prepare_run(hybrid_study(algorithm="nsga2"))
    quick = prepare_run(hybrid_study(), quick=True)
    assert quick.hybrid is not None and quick.hybrid.starts == 1
    assert quick.config.n_gen == quick.study.optimiser.quick_n_gen


def test_a_ga_study_dumps_without_the_new_keys():
    raw = flexopt_toys.study()
    text = study_to_yaml(validate_study(raw))
    assert "method" not in text and "hybrid" not in text
    # evaluation.json dumps the study without exclude_none: the keys stay out there too
    dumped = validate_study(raw).model_dump(mode="json")["optimiser"]
    assert "method" not in dumped and "hybrid" not in dumped
    setup = prepare_run(validate_study(raw))
    assert setup.hybrid is None
    text = study_to_yaml(hybrid_study())
    assert "method: hybrid" in text and "starts: 2" in text


def test_the_example_runs_the_hybrid_and_a_study_without_method_the_ga():
    """The shipped constant-force example names ``method: hybrid`` (issue 27: the default
    ``flexopt run constant-force`` is the calibrated hybrid, docs/constant_force.md): the GA then
    Gauss-Newton (the defaults starts 2, patience 6; max_iter 30, the example's own since
    session 33, with ``retry_inside``; each step's QP solved exactly, ``step_solver: exact``,
    since session 34; the GA stage its first population, ``ga_n_gen`` 1, since session 35)
    with the band row
    ``force_band_excess``. A constant_force study that names no ``method`` keeps the GA alone
    with main's problem (no band row): the kind's schema default is unchanged, so a study
    written before the hybrid, and its run folder's hash, optimise as they did."""
    from flexopt.pipeline.study import load_study

    study = load_study("constant-force")
    assert study.optimiser.method == "hybrid"
    assert study.optimiser.hybrid is not None and study.optimiser.hybrid.max_iter == 30
    setup = prepare_run(study)
    assert setup.hybrid is not None and setup.hybrid.local == "gauss_newton"
    assert (setup.hybrid.ga_n_gen, setup.hybrid.starts, setup.hybrid.patience) == (1, 2, 6)
    assert setup.hybrid.max_iter == 30 and setup.hybrid.retry_inside
    assert setup.hybrid.record()["retry_inside"] is True
    assert setup.hybrid.step_solver == "exact"
    assert setup.hybrid.record()["step_solver"] == "exact"
    assert setup.config.n_gen == study.optimiser.n_gen  # the GA stage's most generations
    assert setup.problem.constraint_names == ("stress_ratio_minus_1", "force_band_excess")
    unset = study.model_copy(
        update={"optimiser": study.optimiser.model_copy(update={"method": None})}
    )
    setup = prepare_run(unset)
    assert setup.hybrid is None
    # a hybrid study that names no step_solver keeps SLSQP (its run.json as it was)
    plain = prepare_run(hybrid_study())
    assert plain.hybrid.step_solver == "slsqp" and "step_solver" not in plain.hybrid.record()
    assert setup.problem.constraint_names == ("stress_ratio_minus_1",)
    assert prepare_run(validate_study(flexopt_toys.study())).hybrid is None


def test_history_names_the_design_the_hybrid_chose(tmp_path, monkeypatch):
    """A calibrated hybrid's best is the lowest design whose check was met, which can be above
    the lowest row: history.csv's last row, best.json and the report then name that design,
    not the lowest row's objective (here the stage's best is replaced by the GA's first design,
    as a check that was not met below it would)."""
    import dataclasses

    import flexopt.pipeline.run.runner as runner

    stage = runner.run_hybrid
    chosen = {}

    def a_higher_best(*args, **kwargs):
        result = stage(*args, **kwargs)
        higher = max(
            (e for e in result.generations[0].evaluations if e.feasible), key=lambda e: e.f[0]
        )
        assert higher.f[0] > result.best.f[0]
        chosen["f"] = float(higher.f[0])
        return dataclasses.replace(result, best=higher, front=(higher,))

    monkeypatch.setattr(runner, "run_hybrid", a_higher_best)
    run_study(prepare_run(hybrid_study()), out=tmp_path / "run", parallel=SERIAL)
    history = read_records_csv(tmp_path / "run" / "history.csv")
    best = json.loads((tmp_path / "run" / "best.json").read_text())
    assert best["objectives"]["error"] == chosen["f"]
    # the table's 8 significant digits
    assert float(history[-1]["best_error"]) == pytest.approx(chosen["f"], rel=1e-7)
    assert history[-1]["best_feasible"] in ("true", "True", True)
    # the rows before it keep the lowest of the optimiser's rows so far
    assert float(history[-2]["best_error"]) < chosen["f"]
