"""ConstantForceProblem.check_constraints (the hybrid's calibration, issue 27): the verdict's own
peak-stress figure at a design, the stress row's factor, deterministic in the design."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
from flexopt.pipeline.run import prepare_run
from flexopt.pipeline.studies import constant_force as cf
from flexopt.pipeline.studies._constant_force_clamp import CHECKED_PEAK
from flexopt.pipeline.study import load_study

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def problem():
    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    return prepare_run(study).problem


def test_the_check_is_the_verdicts_figure_and_the_rows_factor(problem):
    x = problem.nominal_design()
    check = problem.check_constraints(x)
    # what flexopt evaluate judges (its own fidelity check of the same design)
    summary = problem.result(x).summary
    judged = summary[CHECKED_PEAK]
    assert check.info[CHECKED_PEAK] == pytest.approx(judged, rel=1e-12)
    # the row's figure: (g + 1) x allowable of the evaluation the optimiser sees
    g = problem.evaluate(x).g[0]
    row = (g + 1.0) * problem.allowable_MPa
    assert check.info["beam_row_stress_MPa"] == pytest.approx(row, rel=1e-12)
    assert check.factors == {0: pytest.approx(judged / row, rel=1e-12)}
    assert check.met == (judged <= problem.allowable_MPa)
    # a deterministic function of the design: a resumed run (a new problem) makes the same check
    again = prepare_run(problem.study).problem.check_constraints(np.array(x))
    assert again.factors == check.factors and again.info == check.info


def test_no_check_without_the_fidelity_check(problem):
    study = problem.study.model_copy(
        update={"fidelity": problem.study.fidelity.model_copy(update={"enabled": False})}
    )
    other = prepare_run(study).problem
    assert other.check_constraints(other.nominal_design()) is None


def test_the_report_reuses_the_check_the_calibration_made(monkeypatch):
    """The run's best design was checked by the calibration: detail (the report) serves that
    record instead of solving it again - the same figure, exactly, as a fresh problem's detail
    computes, and no second solve. Another design, other strokes or another study solve."""
    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    problem = prepare_run(study).problem  # the run's (with_residuals' copy of the kind's)
    x = problem.nominal_design()
    check = problem.check_constraints(x)
    solves = []
    real = cf.kinks.refined_check
    monkeypatch.setattr(
        cf.kinks, "refined_check", lambda *a, **k: solves.append(1) or real(*a, **k)
    )
    detail = problem.detail(np.array(x))  # a copy of x: the key is the design's value
    assert solves == []  # served, not solved
    assert (problem.checks.solved, problem.checks.reused) == (1, 1)
    assert detail.info[CHECKED_PEAK] == check.info[CHECKED_PEAK]
    fresh = prepare_run(study).problem.detail(x)  # no calibration before it: solved
    assert solves == [1]
    assert fresh.info[CHECKED_PEAK] == detail.info[CHECKED_PEAK]  # exactly the same figure
    kept, made = detail.info["fidelity"], fresh.info["fidelity"]
    for name in ("plane_stress_peak_nodal_von_mises_MPa", "plane_stress_force_N", "refined"):
        assert kept[name] == made[name], name
    # the served record is a copy: the report adding to it leaves the kept one as made
    detail.info["fidelity"]["added_by_the_report"] = True
    assert "added_by_the_report" not in problem.detail(x).info["fidelity"]
    assert solves == [1]
    # another design is solved
    other = np.array(x)
    other[-1] += 0.01  # B, mm
    problem.detail(other)
    assert solves == [1, 1]
    # a pickled problem (a worker's) carries no records
    clone = pickle.loads(pickle.dumps(problem))
    assert clone.checks.records == {} and len(problem.checks.records) == 2


def test_a_workers_check_is_adopted_by_the_run_process(monkeypatch):
    """The hybrid's checks run in a pool's worker (session 28, lockstep): the worker's problem is
    a pickled copy, so its records would stay there and the report would solve the check again.
    The ConstraintCheck carries them (``kept``) through a real pickle, the run's problem adopts
    them through the Evaluator (its ``adopt_check``), and its detail serves the worker's figure
    without a solve; a check of another design is not served by them."""
    from flexopt.optimise.hook_call import HookAnswer
    from flexopt.pipeline.run.evaluator import Evaluator

    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    run_problem = prepare_run(study).problem
    worker = pickle.loads(pickle.dumps(run_problem))  # what a pool's worker holds
    x = run_problem.nominal_design()
    sent = pickle.loads(pickle.dumps(worker.check_constraints(np.array(x))))  # back over a pipe
    assert sent.kept and run_problem.checks.records == {}
    solves = []
    real = cf.kinks.refined_check
    monkeypatch.setattr(
        cf.kinks, "refined_check", lambda *a, **k: solves.append(1) or real(*a, **k)
    )
    evaluator = Evaluator.__new__(Evaluator)  # only its problem is used by the adoption
    evaluator.problem = run_problem
    evaluator._adopt_checks(
        [("jacobian", np.array(x)), ("check", np.array(x))], [HookAnswer(), HookAnswer(sent)]
    )
    detail = run_problem.detail(np.array(x))
    assert solves == []  # served from the worker's record
    assert detail.info[CHECKED_PEAK] == sent.info[CHECKED_PEAK]
    other = np.array(x)
    other[-1] += 0.01  # B, mm: not the checked design
    run_problem.detail(other)
    assert solves == [1]


def test_a_check_at_a_design_this_process_solved_reuses_that_solve(monkeypatch):
    """Session 32: the check's beam path at x is the one the process kept when it evaluated x
    (``_constant_force_solved``, as the exact Jacobian's), not solved again; the same check to
    the bit as from a fresh solve, whole and in parts."""
    from flexopt.pipeline.studies import _constant_force_solved as solved
    from flexopt.pipeline.studies._constant_force_reuse import CheckMemo

    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    problem = prepare_run(study).problem
    x = problem.nominal_design()
    solved.clear()
    fresh = {p: problem.check_constraints(np.array(x), part=p) for p in (0, 1)}
    problem.checks = CheckMemo()
    fresh[None] = problem.check_constraints(np.array(x))
    problem.checks = CheckMemo()
    problem.evaluate(np.array(x))  # keeps its solve in this process
    assert solved.kept(problem, x) is not None
    calls = []
    real = problem._solve
    monkeypatch.setattr(problem, "_solve", lambda z: calls.append(1) or real(z))
    reused = {p: problem.check_constraints(np.array(x), part=p) for p in (0, 1)}
    reused[None] = problem.check_constraints(np.array(x))
    assert calls == []  # every check served by the kept solve
    for p in (0, 1):
        assert reused[p].rows == fresh[p].rows
        assert _same(reused[p].record, fresh[p].record, ("time_s",))
    assert reused[None].factors == fresh[None].factors
    assert reused[None].info == fresh[None].info and reused[None].met == fresh[None].met
    solved.clear()


def _same(a, b, skip) -> bool:
    """Records a and b equal to the bit (dicts, lists, arrays, numbers), keys in ``skip`` aside."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k], skip) for k in a if k not in skip)
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(_same(u, v, skip) for u, v in zip(a, b, strict=True))
    if isinstance(a, np.ndarray):
        return np.array_equal(a, b)
    return a == b
