"""The Dask backend: evaluate designs on a ``dask.distributed`` cluster.

dask.distributed is the well-kept way to spread Python work over many machines: a scheduler, any
number of ``dask worker`` processes, a nanny that restarts a worker that dies and reschedules its
tasks, and plain TCP. flexopt needs nothing else from it: the design problem goes to every worker
once, as a worker plugin (re-installed on a worker the nanny restarts, which a scattered object is
not), and tasks carry only chunks of design vectors.

Fault handling: a design that raises is a failed Evaluation (inside the task, like everywhere); a
worker that dies has its tasks rescheduled by the scheduler; a chunk that keeps killing workers
(``KilledWorker``) is split into single designs, a single design that does is tried once more
alone at the end of the batch (the scheduler also blames tasks merely queued on a dying worker),
and if it kills workers even then it is a failed row (``WorkerDied``). The time limit runs each
design in a thread and stops waiting for it after the limit: Dask cannot kill a running task, so
the stuck thread runs on until its solve returns (run the workers with ``--lifetime`` to recycle
them if that happens often).
"""

from __future__ import annotations

import logging
import pickle
import threading
import uuid
from collections.abc import Callable
from typing import Any

import numpy as np
from distributed import Client, KilledWorker, as_completed, get_worker
from distributed.diagnostics.plugin import WorkerPlugin

from optimise.evaluation import Evaluation
from optimise.problem import DesignProblem
from pipeline.parallel import (
    DASK_CHUNKS_PER_WORKER,
    BackendError,
    chunk_rows,
    evaluate_one,
    timeout_reason,
)

__all__ = ["DaskBackend"]

log = logging.getLogger(__name__)

#: Seconds to wait for the scheduler and for a first worker.
CONNECT_TIMEOUT_S = 20.0


class ProblemPlugin(WorkerPlugin):
    """Holds the unpickled design problem on each worker (set up once per worker).

    Parameters
    ----------
    payload : bytes
        The pickled problem; unpickled in :meth:`setup`, on the worker.
    """

    def __init__(self, payload: bytes) -> None:
        self.payload = payload
        self.problem: DesignProblem | None = None

    def setup(self, worker: Any) -> None:
        self.problem = pickle.loads(self.payload)

    def teardown(self, worker: Any) -> None:
        self.problem = None


def _evaluate_with_limit(
    problem: DesignProblem, x: np.ndarray, timeout_s: float | None
) -> Evaluation:
    """:func:`evaluate_one` in a thread, abandoned after ``timeout_s`` (a task cannot be killed)."""
    if timeout_s is None:
        return evaluate_one(problem, x)
    box: list[Evaluation] = []
    thread = threading.Thread(
        target=lambda: box.append(evaluate_one(problem, x)), daemon=True, name="flexopt-eval"
    )
    thread.start()
    thread.join(timeout_s)
    if box:
        return box[0]
    n_obj, n_con = len(problem.objective_names), len(problem.constraint_names)
    return Evaluation.failed(x, n_obj, n_con, timeout_reason(timeout_s), timeout_s)


def evaluate_chunk(
    plugin: str, rows: list[int], X: np.ndarray, timeout_s: float | None
) -> list[tuple[int, Evaluation]]:
    """The Dask task: evaluate a chunk of designs with the worker's copy of the problem."""
    problem = get_worker().plugins[plugin].problem
    if problem is None:
        raise RuntimeError(f"worker plugin {plugin} holds no problem")
    pairs = zip(rows, X, strict=True)
    return [(row, _evaluate_with_limit(problem, x, timeout_s)) for row, x in pairs]


class DaskBackend:
    """Evaluate on the Dask cluster at ``address`` (or through an existing client).

    Parameters
    ----------
    problem : DesignProblem
        Sent once to every worker (a worker plugin).
    address : str
        Scheduler address, ``tcp://host:8786``.
    timeout_s : float, s, optional
        Time limit of one design.
    chunk_size : int, optional
        Designs per task (default: about four tasks per worker thread and batch).
    client : distributed.Client, optional
        Use this client instead of connecting to ``address`` (it is not closed here).

    Raises
    ------
    BackendError
        When the problem cannot be pickled, the scheduler cannot be reached, no worker joins,
        or the workers cannot load the problem (flexopt not installed there).
    """

    def __init__(
        self,
        problem: DesignProblem,
        address: str,
        timeout_s: float | None = None,
        chunk_size: int | None = None,
        client: Client | None = None,
    ) -> None:
        try:
            payload = pickle.dumps(problem, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:
            raise BackendError(
                f"the design problem cannot be sent to Dask workers ({type(exc).__name__}: {exc})"
            ) from exc
        self.timeout_s = timeout_s
        self.chunk_size = chunk_size
        self.token = uuid.uuid4().hex[:12]
        self.plugin = f"flexopt-problem-{self.token}"
        self._own_client = client is None
        try:
            self.client = client or Client(address, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:
            raise BackendError(
                f"cannot reach the Dask scheduler at '{address}' ({type(exc).__name__}: {exc}); "
                "start one with `dask scheduler` and give its tcp:// address"
            ) from None
        try:
            self.client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
            self.client.register_plugin(ProblemPlugin(payload), name=self.plugin)
        except TimeoutError:
            self.close()
            raise BackendError(
                f"no Dask worker joined the scheduler at '{address}' within "
                f"{CONNECT_TIMEOUT_S:g} s; start workers with `dask worker {address}`"
            ) from None
        except Exception as exc:
            self.close()
            raise BackendError(
                f"Dask workers cannot load the design problem ({type(exc).__name__}: {exc}); "
                "install flexopt (same version) on every worker"
            ) from None
        self.n_batches = 0

    @property
    def n_threads(self) -> int:
        """Worker threads in the cluster now (at least 1)."""
        workers = self.client.scheduler_info().get("workers", {})
        return max(1, sum(int(w.get("nthreads", 1)) for w in workers.values()))

    def close(self) -> None:
        """Remove the problem from the workers and disconnect (an own client only)."""
        client = getattr(self, "client", None)
        if client is None:
            return
        try:
            if client.status == "running":
                client.unregister_worker_plugin(self.plugin)
        except Exception:  # the plugin may not exist (failed set-up); closing must go on
            log.debug("unregistering %s failed", self.plugin, exc_info=True)
        if self._own_client:
            client.close()

    def __call__(
        self,
        problem: DesignProblem,
        X: np.ndarray,
        on_result: Callable[[int, Evaluation], None] | None = None,
    ) -> list[Evaluation]:
        """Evaluate (m, n_var) designs on the cluster; returns m Evaluations in order."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        n_obj, n_con = len(problem.objective_names), len(problem.constraint_names)
        results: list[Evaluation | None] = [None] * len(X)
        size = chunk_rows(len(X), self.n_threads, self.chunk_size, DASK_CHUNKS_PER_WORKER)
        self.n_batches += 1
        tasks: dict[Any, list[int]] = {}
        n_tasks = 0

        def submit(rows: list[int]) -> Any:
            nonlocal n_tasks
            n_tasks += 1
            future = self.client.submit(
                evaluate_chunk,
                self.plugin,
                rows,
                X[rows],
                self.timeout_s,
                pure=False,
                key=f"flexopt-{self.token}-{self.n_batches}-{n_tasks}",
            )
            tasks[future] = rows
            return future

        def record(done: list[tuple[int, Evaluation]]) -> None:
            for row, evaluation in done:
                if results[row] is None:
                    results[row] = evaluation
                    if on_result is not None:
                        on_result(row, evaluation)

        futures = [submit(list(range(s, min(s + size, len(X))))) for s in range(0, len(X), size)]
        pending = as_completed(futures)
        suspects: list[int] = []
        try:
            for future in pending:
                rows = tasks.pop(future)
                try:
                    record(future.result())
                except KilledWorker:
                    # The scheduler blames every task on a worker that dies, also those only
                    # queued there: split a chunk into single designs, and try a single one
                    # again alone at the end, where only the design that kills is blamed.
                    if len(rows) > 1:
                        log.warning("a chunk kept killing Dask workers; resubmitting its designs")
                        for row in rows:
                            pending.add(submit([row]))
                    else:
                        suspects.append(rows[0])
            for row in suspects:
                future = submit([row])
                try:
                    record(future.result())
                except KilledWorker as exc:
                    record(
                        [
                            (
                                row,
                                Evaluation.failed(
                                    X[row],
                                    n_obj,
                                    n_con,
                                    "WorkerDied: Dask workers died while evaluating this design "
                                    f"alone ({exc.__class__.__name__})",
                                ),
                            )
                        ]
                    )
                tasks.pop(future, None)
        except BaseException:
            self.client.cancel(list(tasks))  # Ctrl-C or a broken cluster: stop what is queued
            raise
        missing = [row for row, ev in enumerate(results) if ev is None]
        if missing:
            raise BackendError(f"the Dask cluster returned no result for designs {missing}")
        return [ev for ev in results if ev is not None]
