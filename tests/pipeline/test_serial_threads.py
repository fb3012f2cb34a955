"""Serial paths solve with one BLAS/OpenMP thread and give the caller's limits back (issue 27).

``flexopt evaluate`` / the API's ``evaluate`` and a serial run (``--workers 1``, ``run(workers=1)``)
solve many small systems in this process, where a second BLAS thread only spins: the pools are
limited to one thread inside the solve (:func:`pipeline.fork.limit_loaded_pools`) and restored
after it, so a caller's own numpy work keeps its threads; a run's report (the SEA spring's 3D
check) runs with the caller's threads. Seen from inside the toy kind's solve by threadpoolctl's
``threadpool_info()``; nothing is timed.
"""

from __future__ import annotations

import flexopt
import flexopt_toys  # registers the toy_faults kind
import numpy as np
import pytest
from flexopt.pipeline.fork import limit_loaded_pools
from threadpoolctl import threadpool_info, threadpool_limits

#: what the caller sets before calling flexopt (not the machine's cores: any value but 1 shows
#: that the solve's 1 is flexopt's, and that the caller's value comes back). A pool built for one
#: thread (e.g. cvxopt's OpenBLAS, once a test loaded it) stays at 1 whatever is set.
CALLERS = 2


def _threads() -> dict[str, int]:
    """The thread count of every loaded BLAS/OpenMP pool, by its library's file."""
    return {pool["filepath"]: pool["num_threads"] for pool in threadpool_info()}


def _callers() -> dict[str, int]:
    """The pools as the caller's ``threadpool_limits(CALLERS)`` left them (inside its block)."""
    return _threads()


def _same(seen: dict[str, int], callers: dict[str, int]) -> bool:
    """The pools the caller had are at the caller's counts (a pool loaded since is ignored)."""
    return all(seen.get(path) == n for path, n in callers.items())


@pytest.fixture
def seen(monkeypatch: pytest.MonkeyPatch) -> dict[str, list[dict[str, int]]]:
    """The pools' thread counts inside every ``evaluate`` (a design's solve) and ``detail`` (a
    design's full analysis: what ``flexopt evaluate`` solves and what a run's report draws) of
    the toy kind."""
    if not threadpool_info():
        pytest.skip("no BLAS/OpenMP pool loaded that threadpoolctl can see")
    calls: dict[str, list[dict[str, int]]] = {"evaluate": [], "detail": []}
    problem = flexopt_toys.FaultProblem
    evaluate, detail = problem.evaluate, problem.detail

    def evaluate_seen(self, x: np.ndarray):  # noqa: ANN001, ANN202 - the toy's own signature
        calls["evaluate"].append(_threads())
        return evaluate(self, x)

    def detail_seen(self, x: np.ndarray):  # noqa: ANN001, ANN202
        calls["detail"].append(_threads())
        return detail(self, x)

    monkeypatch.setattr(problem, "evaluate", evaluate_seen)
    monkeypatch.setattr(problem, "detail", detail_seen)
    # the design `flexopt evaluate` solves (the toy study names none)
    monkeypatch.setattr(problem, "nominal_design", lambda self: np.array([0.5, 0.3, 0.1]))
    return calls


def _study() -> dict:
    return flexopt_toys.study("threads")


def _one(seen: dict[str, int]) -> bool:
    return set(seen.values()) == {1}


def test_limit_loaded_pools_is_scoped() -> None:
    if not threadpool_info():
        pytest.skip("no BLAS/OpenMP pool loaded that threadpoolctl can see")
    with threadpool_limits(CALLERS):
        callers = _callers()
        with limit_loaded_pools():
            assert _one(_threads())
        assert _threads() == callers


def test_evaluate_solves_with_one_thread_and_restores(seen: dict, tmp_path) -> None:
    with threadpool_limits(CALLERS):
        callers = _callers()
        flexopt.evaluate(_study())
        assert _same(_threads(), callers)  # the caller's numpy keeps its threads
        flexopt.evaluate(_study(), out=tmp_path / "evaluate")  # flexopt evaluate's path
        assert _same(_threads(), callers)
    assert seen["detail"] and all(_one(t) for t in seen["detail"])
    assert all(_one(t) for t in seen["evaluate"])


def test_serial_run_solves_with_one_thread_and_restores(seen: dict, tmp_path) -> None:
    with threadpool_limits(CALLERS):
        callers = _callers()
        flexopt.run(_study(), workers=1, quick=True, out=tmp_path / "run")
        assert _same(_threads(), callers)
    # every design of the optimisation (the last evaluate call is the report's, in its detail)
    assert len(seen["evaluate"]) > 1 and all(_one(t) for t in seen["evaluate"][:-1])
    # the report's analysis of the best design (an SEA spring's 3D check: one large sparse
    # factorisation) runs after the optimisation, with the caller's threads
    assert seen["detail"] and _same(seen["detail"][-1], callers)


def test_hybrid_gradient_stage_runs_with_one_thread(
    seen: dict, tmp_path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A hybrid run with a pool: its gradient stage takes the problem's Jacobians in this
    process, with one thread (the BLAS round-off of more changed a run's path), and the caller's
    threads come back after the run."""
    jacobians: list[dict[str, int]] = []

    def jacobian_seen(self, x: np.ndarray):  # noqa: ANN001, ANN202 - the hook's signature
        jacobians.append(_threads())
        return None  # forward differences instead

    monkeypatch.setattr(flexopt_toys.FaultProblem, "jacobian", jacobian_seen)
    study = _study()
    study["optimiser"] = {**study["optimiser"], "method": "hybrid"}
    with threadpool_limits(CALLERS):
        callers = _callers()
        flexopt.run(study, workers=2, quick=True, out=tmp_path / "run")
        assert _same(_threads(), callers)
    assert jacobians and all(_one(t) for t in jacobians)
