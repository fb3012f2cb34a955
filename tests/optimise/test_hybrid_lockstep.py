"""The hybrid's starts in lockstep (run_hybrid(lockstep=True), the default for Gauss-Newton
without a budget): each round one batch of every live start's request, the Jacobians and checks
beside the designs (``requests``). Each start's designs, its report entry and the best design
must be those of one start after the other (lockstep=False, the stage as it ran before), to the
bit; only the order of the batches differs."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise import hybrid
from flexopt.optimise.ga import GAConfig
from flexopt.optimise.hook_call import HookAnswer, hook_answer
from flexopt.optimise.hybrid import HybridConfig, run_hybrid
from test_hybrid import SPACE, Counting, rosenbrock
from test_hybrid_calibration import Checks
from test_hybrid_calibration import evaluate as calibration_evaluate
from test_hybrid_calibration import jacobian as calibration_jacobian
from test_hybrid_exact_jacobian import rosenbrock_jacobian


def config(**options) -> HybridConfig:
    return HybridConfig(GAConfig("ga", 10, 2, seed=3), local="gauss_newton", **options)


@pytest.fixture
def per_start(monkeypatch):
    """Every start's designs in the order it asked for them (by start, in start order)."""
    seen: dict[int, list[bytes]] = {}
    ask = hybrid._Start.batch

    def batch(self, U):
        evaluations = yield from ask(self, U)
        seen.setdefault(id(self), []).extend(e.x.tobytes() for e in evaluations)
        return evaluations

    monkeypatch.setattr(hybrid._Start, "batch", batch)

    def run(**kwargs):
        seen.clear()
        result = run_hybrid(**kwargs)
        return result, list(seen.values())

    return run


def gradient_designs(result) -> list[bytes]:
    n_ga = result.report["ga"]["generations"]
    return [e.x.tobytes() for g in result.generations[n_ga:] for e in g.evaluations]


def batches(result) -> list[list[bytes]]:
    """Every generation's designs, in order."""
    return [[e.x.tobytes() for e in g.evaluations] for g in result.generations]


def without_time(report: dict) -> dict:
    out = dict(report)
    if "checks" in out:
        out["checks"] = {k: v for k, v in out["checks"].items() if k != "time_s"}
    return out


CASES = {
    "finite differences": dict(evaluate=rosenbrock, config=config(starts=3, max_iter=100)),
    "exact Jacobian": dict(
        evaluate=rosenbrock, config=config(starts=3, max_iter=100), jacobian=rosenbrock_jacobian
    ),
    "calibrated": dict(
        evaluate=calibration_evaluate,
        config=config(starts=3, max_iter=100),
        jacobian=calibration_jacobian,
        check=Checks(),
    ),
}


@pytest.mark.parametrize("case", CASES)
def test_lockstep_starts_ask_for_the_designs_one_after_the_other_does(per_start, case):
    kwargs = dict(space=SPACE, n_obj=1, n_con=1, **CASES[case])
    one_by_one, alone = per_start(**kwargs, lockstep=False)
    together, concurrent = per_start(**kwargs)
    assert len(alone) == len(concurrent) == 3
    # one after the other: the stage's designs are the starts' (each start's gradient method
    # in consecutive batches; the calibrations after every start's method, the lowest first)
    assert sorted(sum(alone, [])) == sorted(gradient_designs(one_by_one))
    assert concurrent == alone  # every start's sequence of designs, to the bit
    assert together.best.x.tobytes() == one_by_one.best.x.tobytes()
    assert together.best.f.tobytes() == one_by_one.best.f.tobytes()
    assert without_time(together.report) == without_time(one_by_one.report)
    # the same designs in fewer batches: the starts did run at the same time
    assert sorted(gradient_designs(together)) == sorted(gradient_designs(one_by_one))
    assert len(together.generations) < len(one_by_one.generations)


def test_a_budget_runs_the_starts_one_after_the_other():
    evaluate = Counting(rosenbrock)
    cfg = config(starts=3, max_iter=100, max_evaluations=25)
    result = run_hybrid(SPACE, evaluate, 1, 1, cfg, jacobian=rosenbrock_jacobian)
    alone = run_hybrid(SPACE, rosenbrock, 1, 1, cfg, jacobian=rosenbrock_jacobian, lockstep=False)
    assert result.report == alone.report and set(evaluate.batches[2:]) == {1}
    assert result.report["stop"].startswith("reached the gradient stage's max_evaluations")
    assert result.report["n_evaluations"]["gradient"] <= 25


def test_requests_get_the_designs_and_the_hook_calls_of_a_round_as_one_batch():
    """``requests`` (a pool's evaluator) is given every live start's request of a round at
    once; answering the calls elsewhere (here: recorded, then called) changes nothing."""
    rounds: list[tuple[int, list[str]]] = []

    def requests(X, calls):
        rounds.append((len(X), [kind for kind, _ in calls]))
        return rosenbrock(X) if len(X) else [], [
            hook_answer(rosenbrock_jacobian, x) for _, x in calls
        ]

    cfg = config(starts=2, max_iter=100)
    result = run_hybrid(
        SPACE, rosenbrock, 1, 1, cfg, jacobian=rosenbrock_jacobian, requests=requests
    )
    here = run_hybrid(SPACE, rosenbrock, 1, 1, cfg, jacobian=rosenbrock_jacobian)
    assert result.report == here.report and result.best.x.tobytes() == here.best.x.tobytes()
    assert rounds and all(n + len(kinds) <= 2 for n, kinds in rounds)  # one request per start
    assert any(n == 1 and kinds == ["jacobian"] for n, kinds in rounds)  # a design beside a call
    assert any(kinds == ["jacobian", "jacobian"] for _, kinds in rounds)  # two Jacobians at once


def test_a_failed_call_is_a_jacobian_or_check_that_did_not_answer():
    """A hook answer with an error (it raised, or its worker died) is handled as a hook that
    raised in this process: forward differences instead of the Jacobian, and "the check did not
    answer" for a check."""

    def requests(X, calls):
        return calibration_evaluate(X) if len(X) else [], [
            HookAnswer(None, "WorkerDied: the worker died calling " + kind) for kind, _ in calls
        ]

    def raising(x):
        raise RuntimeError("no")

    cfg = config(starts=2, max_iter=30)
    kwargs = dict(jacobian=calibration_jacobian, check=Checks())
    failed = run_hybrid(SPACE, calibration_evaluate, 1, 1, cfg, requests=requests, **kwargs)
    here = run_hybrid(SPACE, calibration_evaluate, 1, 1, cfg, jacobian=raising, check=raising)
    assert (
        failed.report["jacobians"]["exact"] == 0
        and failed.report["jacobians"]["finite_differences"]
        == here.report["jacobians"]["finite_differences"]
        > 0
    )
    for start in failed.report["starts"]:
        assert start["calibration"][-1]["stop"] == "the check did not answer"
    assert without_time(failed.report) == without_time(here.report)
    np.testing.assert_array_equal(failed.best.x, here.best.x)


@pytest.mark.parametrize("case", ["exact Jacobian", "calibrated"])
def test_a_trials_jacobian_taken_ahead_changes_no_start_and_saves_rounds(per_start, case):
    """``ahead``: in a round where one start asks for a Jacobian or a check and another for one
    trial design, the trial's Jacobian is asked in that round too; a start that accepts its
    trial is answered from it without a round. Each start's designs, the report and the best
    are those of one start after the other, to the bit; the rounds are fewer than in lockstep
    without it, and the same on a second run (they depend on the requests only)."""
    rounds: list[tuple[int, list[str]]] = []
    used: list[bytes] = []
    taken = hybrid._Stage.taken

    def spy(self, request):
        answer = taken(self, request)
        if answer is not None:
            used.append(request.x.tobytes())
        return answer

    def requests(X, calls):
        rounds.append((len(X), [kind for kind, _ in calls]))
        evaluate = CASES[case]["evaluate"]
        hooks = {"jacobian": CASES[case]["jacobian"], "check": CASES[case].get("check")}
        return evaluate(X) if len(X) else [], [hook_answer(hooks[kind], x) for kind, x in calls]

    kwargs = dict(space=SPACE, n_obj=1, n_con=1, **CASES[case])
    one_by_one, alone = per_start(**kwargs, lockstep=False)
    plain, _ = per_start(**kwargs, requests=requests)
    n_plain = len(rounds)
    rounds.clear()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(hybrid._Stage, "taken", spy)
        early, concurrent = per_start(**kwargs, requests=requests, ahead=True)
        first = batches(early)
        again, _ = per_start(**kwargs, requests=requests, ahead=True)
    assert concurrent == alone  # every start's sequence of designs, to the bit
    assert early.best.x.tobytes() == one_by_one.best.x.tobytes()
    assert without_time(early.report) == without_time(one_by_one.report)
    assert used  # a trial's Jacobian taken ahead answered its start
    # a Jacobian is taken ahead only beside another start's call, at a design of the round
    assert any(n >= 1 and len(kinds) >= 2 for n, kinds in rounds)
    assert len(rounds) // 2 < n_plain  # (two runs recorded) fewer rounds than without it
    assert batches(again) == first
    if case == "exact Jacobian":  # the same designs, in other rounds
        # (calibrated: the checks come after every start's method, the lowest start's
        # first and alone, so there the batches of designs may coincide; the rounds are
        # fewer all the same, above)
        assert batches(plain) != first


def test_no_jacobian_is_taken_ahead_without_parallel_calls():
    """Without ``requests`` (the hooks then run in this process, one after another) a
    Jacobian taken ahead would only cost time: ``ahead`` is ignored."""
    cfg = config(starts=2, max_iter=100)
    kwargs = dict(jacobian=rosenbrock_jacobian)
    result = run_hybrid(SPACE, rosenbrock, 1, 1, cfg, ahead=True, **kwargs)
    plain = run_hybrid(SPACE, rosenbrock, 1, 1, cfg, **kwargs)
    assert batches(result) == batches(plain)


def test_the_result_carries_the_stages_jacobian_at_its_best():
    """A checked design's Jacobian is taken in its check's round (ahead): the best, a checked
    design, comes with the problem's Jacobian there (the report's sensitivities reuse it)."""
    case = CASES["calibrated"]

    def requests(X, calls):
        hooks = {"jacobian": case["jacobian"], "check": case["check"]}
        return case["evaluate"](X) if len(X) else [], [
            hook_answer(hooks[kind], x) for kind, x in calls
        ]

    result = run_hybrid(SPACE, n_obj=1, n_con=1, requests=requests, ahead=True, **case)
    assert result.report["checks"]["best_verified"]
    assert result.jacobian is not None
    assert result.jacobian.x.tobytes() == result.best.x.tobytes()
    here = case["jacobian"](result.best.x)
    assert result.jacobian.f.tobytes() == here.f.tobytes()
