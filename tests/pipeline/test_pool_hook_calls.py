"""The process pool answers the problem's hook calls (the hybrid's Jacobians and checks) beside
designs, as one batch (ProcessPool.run, Evaluator.map_calls): the answers are those of the same
hook called in this process, a hook that raises or kills its worker answers with the error (the
hybrid then does without it, as in this process), and the per-design time limit does not apply
to a call (a Jacobian costs several evaluations)."""

from __future__ import annotations

import flexopt_toys  # importable by workers (tests/pipeline on sys.path)
import numpy as np
from flexopt.optimise.hook_call import call_hook
from flexopt.pipeline.parallel import MAX_ATTEMPTS, ProcessPool, SerialBackend, evaluate_one
from flexopt.pipeline.run.evaluator import Evaluator
from flexopt.pipeline.study import validate_study

X = np.array([[0.1, 0.2, 0.3], [0.7, 0.1, 0.0], [0.4, 0.4, 0.4], [0.2, 0.9, 0.1]])


def problem(**geometry):
    study = validate_study(flexopt_toys.study(**geometry))
    return flexopt_toys.HookProblem(study.geometry)


def calls():
    return [("jacobian", X[0]), ("check", X[1]), ("jacobian", X[2]), ("check", X[3])]


def same(a, b) -> None:
    """Two hook answers' values equal to the bit."""
    if hasattr(a, "f"):  # a DesignJacobian
        for name in ("x", "f", "g"):
            assert np.asarray(getattr(a, name)).tobytes() == np.asarray(getattr(b, name)).tobytes()
    else:  # a ConstraintCheck
        assert (a.factors, a.met, a.info) == (b.factors, b.met, b.info)


def test_the_pool_answers_hook_calls_beside_designs_as_this_process_does():
    toy = problem()
    pool = ProcessPool(toy, 2)
    try:
        evaluations, answers = pool.run(toy, X, calls())
    finally:
        pool.close()
    for ev, x in zip(evaluations, X, strict=True):
        here = evaluate_one(toy, x)
        assert ev.f.tobytes() == here.f.tobytes() and ev.g.tobytes() == here.g.tobytes()
    assert len(answers) == 4 and not any(a.error for a in answers)
    for answer, (kind, x) in zip(answers, calls(), strict=True):
        same(answer.value, call_hook(toy, kind, x).value)
    # the exact derivatives of (a - 0.6)^2 + (b - 0.3)^2 + c^2 at X[0], computed here
    np.testing.assert_array_equal(answers[0].value.f, [[2 * (0.1 - 0.6), 2 * (0.2 - 0.3), 0.6]])
    assert answers[1].value.met is True and answers[3].value.met is False  # 0.7 + 0.17; 0.2 + 1.08


def test_a_hook_that_raises_or_kills_its_worker_answers_with_the_error():
    toy = problem(jacobian_raise_above=0.6, jacobian_exit_above=0.35)
    pool = ProcessPool(toy, 2)
    try:
        evaluations, answers = pool.run(
            toy, X, [("jacobian", X[1]), ("jacobian", X[2]), ("jacobian", X[0])]
        )
    finally:
        pool.close()
    assert not any(ev.reason for ev in evaluations)  # the designs beside them are solved
    assert answers[0].value is None and "RuntimeError: no derivatives" in answers[0].error
    assert answers[1].value is None and answers[1].error.startswith("WorkerDied")
    assert f"{MAX_ATTEMPTS} times" in answers[1].error
    assert answers[2].value is not None and not answers[2].error  # a = 0.1: below both
    assert pool.n_replaced >= MAX_ATTEMPTS


def test_the_time_limit_is_the_designs_not_the_calls():
    toy = problem(jacobian_sleep_s=0.6)
    pool = ProcessPool(toy, 2, timeout_s=0.3)
    try:
        evaluations, answers = pool.run(toy, X[:2], [("jacobian", X[0])])
    finally:
        pool.close()
    assert not any(ev.reason for ev in evaluations)
    assert answers[0].value is not None and answers[0].time_s >= 0.6
    assert pool.n_replaced == 0


def test_the_evaluator_answers_calls_in_this_process_on_the_serial_backend():
    toy = problem()
    serial = Evaluator(toy, SerialBackend())
    evaluations, answers = serial.map_calls(X, calls())
    assert [e.x.tobytes() for e in evaluations] == [x.tobytes() for x in X]
    for answer, (kind, x) in zip(answers, calls(), strict=True):
        same(answer.value, call_hook(toy, kind, x).value)
    # a call is not an evaluation: nothing cached or stored for it
    assert len(serial.solved) == len(X) and serial.n_backend == len(X)
    again, _ = serial.map_calls(X[:1], [("check", X[0])])
    assert again[0] is evaluations[0] and serial.n_cache_hits == 1


def test_the_evaluator_sends_calls_to_the_pool_and_caches_only_designs():
    toy = problem()
    pool = ProcessPool(toy, 2)
    try:
        evaluator = Evaluator(toy, pool)
        first, _ = evaluator.map_calls(X[:2], [("jacobian", X[0])])
        # the designs served from the cache, the call still answered (by a worker)
        again, answers = evaluator.map_calls(X[:2], [("check", X[1])])
    finally:
        pool.close()
    assert again == first and evaluator.n_backend == 2 and evaluator.n_cache_hits == 2
    same(answers[0].value, call_hook(toy, "check", X[1]).value)


def test_a_backend_that_sends_designs_only_answers_calls_in_this_process(caplog):
    """The Dask backend has no ``run``: the hybrid's Jacobians and checks run in the run's
    process, as they did before the pool took them, and the log says so once."""
    toy = problem()

    def designs_only(problem, X, on_result=None):  # what DaskBackend's __call__ offers
        return SerialBackend()(problem, X, on_result)

    evaluator = Evaluator(toy, designs_only)
    with caplog.at_level("INFO", logger="flexopt.pipeline.run.evaluator"):
        _, answers = evaluator.map_calls(X[:1], [("jacobian", X[0])])
        evaluator.map_calls(X[1:2], [("check", X[1])])
    same(answers[0].value, call_hook(toy, "jacobian", X[0]).value)
    said = [r.message for r in caplog.records if "run in this process" in r.message]
    assert len(said) == 1 and "sent designs only" in said[0]


def test_a_batch_of_two_designs_goes_to_two_workers():
    """A hybrid round of two trial designs is a batch smaller than the workers' queues: each
    idle worker is given one before any is queued behind a busy one."""
    toy = problem(sleep_s=0.05)
    pool = ProcessPool(toy, 2)
    try:
        while not all(worker.ready for worker in pool.workers):  # both started
            pool.run(toy, X[:1])
        evaluations, _ = pool.run(toy, X[2:])
    finally:
        pool.close()
    assert len({ev.metrics["pid"] for ev in evaluations}) == 2


def test_a_call_at_a_design_of_the_batch_runs_behind_it_in_its_worker():
    """The hybrid's Jacobian taken ahead at a trial design (optimise.hybrid._Stage._ahead_calls)
    is queued right behind that design, in its message: the worker that solved the design
    answers it (a constant-force Jacobian then starts from the path that worker kept), while a
    call at another design goes to the other worker at once."""
    toy = problem(jacobian_sleep_s=0.03)
    pool = ProcessPool(toy, 2)
    try:
        while not all(worker.ready for worker in pool.workers):  # both started
            pool.run(toy, X[:1])
        # six rounds: calls sent first, as before, would meet their design's worker by chance
        for trial, other in [(X[i], X[j]) for i in range(4) for j in range(4) if i != j][:6]:
            evaluations, answers = pool.run(
                toy, trial[None, :], [("jacobian", other), ("jacobian", trial)]
            )
            solved_by = evaluations[0].metrics["pid"]
            assert answers[1].value.info["pid"] == solved_by
            assert answers[0].value.info["pid"] != solved_by
            same(answers[1].value, call_hook(toy, "jacobian", trial).value)
    finally:
        pool.close()


def test_a_call_goes_to_the_idle_worker_that_solved_its_design():
    """A Jacobian asked in a later batch at a design the pool solved goes to the worker that
    solved it when that worker is idle (a constant-force Jacobian then starts from the path it
    kept), whatever the order of the calls."""
    toy = problem(sleep_s=0.05)
    pool = ProcessPool(toy, 2)
    try:
        while not all(worker.ready for worker in pool.workers):  # both started
            pool.run(toy, X[:1])
        for pair in (X[2:4], X[0:2]):
            evaluations, _ = pool.run(toy, pair)
            assert len({ev.metrics["pid"] for ev in evaluations}) == 2
            for order in ((1, 0), (0, 1)):
                _, answers = pool.run(toy, X[:0], [("jacobian", pair[i]) for i in order])
                for i, answer in zip(order, answers, strict=True):
                    assert answer.value.info["pid"] == evaluations[i].metrics["pid"]
    finally:
        pool.close()
