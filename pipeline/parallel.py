"""Evaluating designs: one function for one design, and the backends that run many.

:func:`evaluate_one` is the only place a design is solved. It turns every failure of the kind (an
exception, a NaN, a wrong shape, a time limit) into an infeasible Evaluation with a reason, so a
bad design never stops a run. The backends only decide *where* it runs:

- :func:`evaluate_batch` / :class:`SerialBackend` — in this process, one after the other (the time
  limit is an interval timer, POSIX main thread only);
- :class:`ProcessPool` — a local pool of worker processes that receive the pickled problem once,
  at start, and then only design vectors, in chunks. A watchdog terminates and replaces a worker
  whose design exceeds the time limit; a worker that dies has its unfinished designs resubmitted
  (the design it was solving at most :data:`MAX_ATTEMPTS` times in all);
- :class:`pipeline.cluster.DaskBackend` — the same on a Dask distributed cluster
  (:func:`pipeline.backends.open_backend` opens the one a run asks for).

Every backend reports each design as it finishes (``on_result(row, evaluation)``: the run persists
it at once) and returns the evaluations in the order of the designs, so results do not depend on
the backend or on which worker finished first.

This module is imported by every worker process: it imports nothing heavy (no pymoo, no pipeline
CLI), so a worker starts in the time it takes to import the problem's own module.
"""

from __future__ import annotations

import contextlib
import logging
import math
import multiprocessing
import os
import pickle
import signal
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from multiprocessing.connection import Connection, wait
from typing import Any, Literal, Protocol

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.hook_call import HookAnswer, call_hook
from flexopt.optimise.problem import DesignProblem
from flexopt.pipeline.errors import FlexoptError, one_line
from flexopt.pipeline.fork import limit_loaded_pools, pool_context, quiet_child

__all__ = [
    "MAX_ATTEMPTS",
    "BackendError",
    "THREAD_ENV_VARS",
    "BatchBackend",
    "EvaluationTimeout",
    "ParallelSettings",
    "ProcessPool",
    "SerialBackend",
    "chunk_rows",
    "design_key",
    "evaluate_batch",
    "evaluate_one",
    "one_line",
    "pin_threads",
    "timeout_reason",
]

log = logging.getLogger(__name__)

#: How often a design is tried when its worker process dies under it (os._exit, segfault, OOM
#: kill): a design that kills every worker it is given must end as a failed row, not a loop.
MAX_ATTEMPTS = 3

#: BLAS/OpenMP pools each start one thread per core: with one worker process per core that is
#: cores² threads fighting for the caches. One thread per worker is faster for these small solves.
THREAD_ENV_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)

#: How often an idle worker checks that the run that started it is still alive, s.
PARENT_CHECK_S = 1.0

#: Chunks per worker and batch. A chunk is one message (pool) or one task (Dask); the last chunks
#: of a batch leave workers idle while others finish, so chunks should be small - as small as the
#: per-chunk cost allows: ~0.15 ms a round trip in the pool (so ~32 chunks per worker cost nothing
#: against 10-150 ms solves), ~1-3 ms a task on Dask (4 per worker thread).
#: See benchmarks/runner_overhead.py. The pool keeps one chunk queued in a worker's pipe behind
#: the design it solves (:data:`POOL_QUEUED_DESIGNS`), so its chunks are half the size the same
#: idle tail at a batch's end allowed without that queue (16 chunks per worker).
POOL_CHUNKS_PER_WORKER = 32
DASK_CHUNKS_PER_WORKER = 4

#: The pool sends a worker its next chunk when at most this many of its designs are unreported
#: (the one it solves): the next design is then already in its pipe when it reports the last, and
#: it does not wait for the run process to wake up, handle its reports and answer. With one
#: chunk at a time the two workers of a constant-force run (2400 designs of ~5-10 ms, chunks of
#: 2) found no design waiting 449 times within the batches, 1.1 s of their time; with one queued,
#: 29 times (0.6 s: when this process itself was held up, e.g. by its report preload thread).
POOL_QUEUED_DESIGNS = 1

#: designs whose worker the pool remembers (:attr:`ProcessPool.solved_by`): a few per worker, as
#: many as a constant-force problem keeps solved paths (``_constant_force_solved.KEEP``, 4)
SOLVED_BY_KEPT = 8


class BatchBackend(Protocol):
    """Evaluates designs; reports each as it finishes through ``on_result(row, evaluation)``.

    Reporting as results arrive lets the evaluator keep every finished design when the run is
    interrupted mid-batch, and lets a parallel backend finish designs in any order.
    """

    def __call__(
        self,
        problem: DesignProblem,
        X: np.ndarray,
        on_result: Callable[[int, Evaluation], None] | None = None,
    ) -> list[Evaluation]: ...


class EvaluationTimeout(FlexoptError):  # noqa: N818 - the reason reads "EvaluationTimeout: ..."
    """A design took longer than the per-evaluation time limit."""


def timeout_reason(timeout_s: float) -> str:
    """The failure reason of a design that exceeded the time limit (the same on every backend)."""
    return (
        f"EvaluationTimeout: took longer than the time limit of {timeout_s:g} s "
        "(--eval-timeout / parallel.eval_timeout_s)"
    )


def design_key(x: np.ndarray) -> bytes:
    """Cache key of a design: the bytes of its float64 vector (bit-identical designs only)."""
    return np.ascontiguousarray(x, dtype=np.float64).tobytes()


# --------------------------------------------------------------------------------------------
# One design


@contextlib.contextmanager
def _alarm(timeout_s: float | None) -> Iterator[None]:
    """Raise :class:`EvaluationTimeout` in this thread after ``timeout_s`` (POSIX main thread).

    Elsewhere (Windows, a worker thread) the limit cannot interrupt the solve and is not applied.
    """
    usable = (
        timeout_s is not None
        and hasattr(signal, "setitimer")
        and threading.current_thread() is threading.main_thread()
    )
    if not usable:
        yield
        return

    def expire(signum: int, frame: Any) -> None:
        raise EvaluationTimeout(timeout_reason(timeout_s).split(": ", 1)[1])

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, timeout_s)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)


def evaluate_one(
    problem: DesignProblem, x: np.ndarray, timeout_s: float | None = None
) -> Evaluation:
    """Evaluate one design, turning every failure into an infeasible Evaluation with a reason.

    Parameters
    ----------
    problem : DesignProblem
    x : (n_var,) float
        The design vector, in the units of ``problem.space``.
    timeout_s : float, s, optional
        Time limit, enforced here with an interval timer (POSIX main thread only; the process
        pool and Dask backends enforce it themselves).

    Returns
    -------
    Evaluation
        The kind's Evaluation (``time_s`` filled in with the wall time when the kind left it 0);
        or ``Evaluation.failed`` when ``problem.evaluate`` raised (reason
        ``"<ExceptionType>: <message>"``), timed out, returned something that is not an
        Evaluation with ``n_obj`` objectives and ``n_con`` constraints, or returned a NaN/inf
        objective or constraint (pymoo cannot rank those; the kind's reason is kept if it gave
        one).
    """
    n_obj, n_con = len(problem.objective_names), len(problem.constraint_names)
    x = np.array(x, dtype=float)
    start = time.perf_counter()
    try:
        with _alarm(timeout_s):
            evaluation = problem.evaluate(x.copy())
    except Exception as exc:  # fault isolation: a bad design never stops the run
        elapsed = time.perf_counter() - start
        log.debug("design %s raised", x, exc_info=True)
        return Evaluation.failed(x, n_obj, n_con, one_line(f"{type(exc).__name__}: {exc}"), elapsed)
    elapsed = time.perf_counter() - start
    if not isinstance(evaluation, Evaluation):
        return Evaluation.failed(
            x,
            n_obj,
            n_con,
            f"TypeError: evaluate returned {type(evaluation).__name__}, not an Evaluation",
            elapsed,
        )
    f, g = np.asarray(evaluation.f, dtype=float), np.asarray(evaluation.g, dtype=float)
    if f.shape != (n_obj,) or g.shape != (n_con,):
        return Evaluation.failed(
            x,
            n_obj,
            n_con,
            f"ValueError: evaluate returned f of shape {f.shape} and g of shape {g.shape}; the "
            f"problem names {n_obj} objectives and {n_con} constraints",
            elapsed,
            evaluation.metrics,
        )
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(g))):
        reason = evaluation.reason or f"non-finite result (f = {f.tolist()}, g = {g.tolist()})"
        return Evaluation.failed(x, n_obj, n_con, one_line(reason), elapsed, evaluation.metrics)
    if evaluation.time_s <= 0.0:
        evaluation = replace(evaluation, time_s=elapsed)
    return evaluation


def evaluate_batch(
    problem: DesignProblem,
    X: np.ndarray,
    on_result: Callable[[int, Evaluation], None] | None = None,
) -> list[Evaluation]:
    """Evaluate designs one after the other in this process (the serial backend, no time limit).

    Parameters
    ----------
    problem : DesignProblem
    X : (m, n_var) float
        Design vectors.
    on_result : callable(row, evaluation), optional
        Called after each design with its row in ``X``.

    Returns
    -------
    list of Evaluation
        m evaluations in the order of ``X``; failures are infeasible Evaluations with a reason
        (see :func:`evaluate_one`), so this never raises for a bad design.
    """
    return SerialBackend()(problem, X, on_result)


@dataclass
class SerialBackend:
    """Evaluate in this process, in order, with an optional time limit per design (s)."""

    timeout_s: float | None = None

    def __call__(
        self,
        problem: DesignProblem,
        X: np.ndarray,
        on_result: Callable[[int, Evaluation], None] | None = None,
    ) -> list[Evaluation]:
        out = []
        for row, x in enumerate(np.atleast_2d(np.asarray(X, dtype=float))):
            out.append(evaluate_one(problem, x, self.timeout_s))
            if on_result is not None:
                on_result(row, out[-1])
        return out

    def close(self) -> None:
        """Nothing to release."""


# --------------------------------------------------------------------------------------------
# Settings


@dataclass(frozen=True)
class ParallelSettings:
    """Where and how designs are evaluated (the study's ``parallel:`` block with the command
    line's ``--workers`` / ``--dask`` / ``--eval-timeout`` applied).

    Attributes
    ----------
    backend : "serial" (in this process), "processes" (local pool) or "dask" (a cluster).
    workers : worker processes of the local pool (default: the machine's cores).
    address : the Dask scheduler, ``tcp://host:8786``.
    eval_timeout_s : s, time limit of one evaluation; None for none.
    chunk_size : designs per message or task (default :func:`chunk_rows`).
    """

    backend: Literal["serial", "processes", "dask"] = "processes"
    workers: int | None = None
    address: str | None = None
    eval_timeout_s: float | None = None
    chunk_size: int | None = None

    @property
    def n_workers(self) -> int:
        """Worker processes of the local pool (1 for serial)."""
        if self.backend == "serial":
            return 1
        return max(1, self.workers or os.cpu_count() or 1)

    def describe(self) -> str:
        """One line for the log and run.json: ``processes (2 workers)``."""
        limit = f", time limit {self.eval_timeout_s:g} s" if self.eval_timeout_s else ""
        if self.backend == "dask":
            return f"dask at {self.address}{limit}"
        if self.backend == "processes":
            return f"processes ({self.n_workers} workers){limit}"
        return f"serial (this process){limit}"


def pin_threads() -> None:
    """Set the BLAS/OpenMP thread variables to 1 in this process's environment.

    Called before worker processes start, so that they (and a forkserver they are forked from)
    read them when their numerical libraries load.
    """
    for var in THREAD_ENV_VARS:
        os.environ[var] = "1"


def chunk_rows(
    n: int,
    n_workers: int,
    chunk_size: int | None = None,
    per_worker: int = POOL_CHUNKS_PER_WORKER,
) -> int:
    """Designs per chunk for ``n`` designs on ``n_workers`` workers (``chunk_size`` if given)."""
    if chunk_size:
        return max(1, int(chunk_size))
    return max(1, math.ceil(n / (per_worker * max(1, n_workers))))


class BackendError(FlexoptError, RuntimeError):
    """The backend cannot run at all (not a design's fault): the message says what to do."""


# --------------------------------------------------------------------------------------------
# The local process pool


def _worker_main(conn: Connection, payload: bytes) -> None:
    """A worker process: load the problem once, then evaluate the chunks it is sent.

    Messages to the parent: ``("ready", pid)`` once the problem is loaded, ``("done", row,
    evaluation)`` per design, ``("fatal", message)`` when the problem cannot be loaded.
    """
    pin_threads()  # for libraries this worker loads itself
    limit_loaded_pools()
    # Ctrl-C reaches the whole process group; the parent decides what stops, and stops us. A
    # forked worker inherits the CLI's SIGTERM handler (which stops a run cleanly); a worker is
    # stopped by its parent, so it ends at once on SIGTERM as a process normally does.
    quiet_child()
    try:
        problem = pickle.loads(payload)
    except BaseException as exc:
        conn.send(("fatal", one_line(f"{type(exc).__name__}: {exc}")))
        return
    conn.send(("ready", os.getpid()))
    parent = os.getppid()
    while True:
        try:
            # A killed parent does not always close this pipe (a forked sibling may hold a copy
            # of its end): notice that we were orphaned instead of waiting forever.
            while not conn.poll(PARENT_CHECK_S):
                if os.getppid() != parent:
                    return
            task = conn.recv()
        except (EOFError, OSError):  # the parent is gone
            return
        if task is None:
            return
        for row, x in task:
            # Designs wait queued in the pipe (POOL_QUEUED_DESIGNS): an orphan solves none of
            # them, only the one it was solving when the run was killed.
            if os.getppid() != parent:
                return
            # No timer here: the parent's watchdog owns the time limit (it also stops a worker
            # stuck in C code, which a signal cannot interrupt). A hook call (kind, x) is the
            # problem's Jacobian or check at x (ProcessPool.run).
            if isinstance(x, tuple):
                conn.send(("done", row, call_hook(problem, x[0], x[1])))
            else:
                conn.send(("done", row, evaluate_one(problem, x)))


@dataclass
class _Worker:
    process: multiprocessing.process.BaseProcess
    conn: Connection
    ready: bool = False
    task: deque[tuple[int, Any]] | None = None  # designs (and hook calls) sent, not reported
    started: float = 0.0  # when the design at the head of ``task`` started (perf_counter)


class ProcessPool:
    """A local pool of worker processes with a per-design watchdog.

    Parameters
    ----------
    problem : DesignProblem
        Pickled once here and sent once to each worker as it starts.
    n_workers : int
        Worker processes (started at the first batch, kept for the whole run).
    timeout_s : float, s, optional
        Time limit of one design: the worker solving it longer is terminated and replaced, and
        the design becomes a failed Evaluation (:func:`timeout_reason`).
    chunk_size : int, optional
        Designs per message (default :func:`chunk_rows`).

    Attributes
    ----------
    n_replaced : int
        Workers replaced after they died or were stopped by the watchdog.

    Raises
    ------
    BackendError
        When the problem cannot be pickled, or workers cannot load it.
    """

    def __init__(
        self,
        problem: DesignProblem,
        n_workers: int,
        timeout_s: float | None = None,
        chunk_size: int | None = None,
    ) -> None:
        try:
            self.payload = pickle.dumps(problem, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:
            raise BackendError(
                f"the design problem cannot be sent to worker processes ({type(exc).__name__}: "
                f"{exc}); run in this process with --workers 1"
            ) from exc
        self.n_workers = max(1, int(n_workers))
        self.timeout_s = timeout_s
        self.chunk_size = chunk_size
        self.workers: list[_Worker] = []
        #: the worker that solved each of the last designs (design_key): a hook call at one of
        #: them goes to it when it is idle (its problem kept the solved path: a constant-force
        #: Jacobian starts from it, pipeline/studies/_constant_force_solved.py)
        self.solved_by: OrderedDict[bytes, _Worker] = OrderedDict()
        self.n_replaced = 0
        self._failed_starts = 0
        for _ in range(self.n_workers):  # now, while this process may still fork safely
            self._start()

    # -- workers -------------------------------------------------------------------------------

    def _start(self) -> _Worker:
        pin_threads()  # before the first worker (and the forkserver) starts
        ctx = pool_context()
        parent, child = ctx.Pipe(duplex=True)
        process = ctx.Process(
            target=_worker_main,
            args=(child, self.payload),
            name="flexopt-worker",
            daemon=True,
        )
        process.start()
        child.close()
        worker = _Worker(process, parent)
        self.workers.append(worker)
        return worker

    def _stop(self, worker: _Worker) -> None:
        """Kill a worker now (stuck or dead) and forget it."""
        with contextlib.suppress(Exception):
            worker.process.kill()
        worker.process.join(5)
        worker.conn.close()
        self.workers.remove(worker)

    def close(self) -> None:
        """Ask every worker to stop; kill those that do not within a second."""
        for worker in self.workers:
            with contextlib.suppress(Exception):
                worker.conn.send(None)
        deadline = time.monotonic() + 1.0
        for worker in list(self.workers):
            worker.process.join(max(0.0, deadline - time.monotonic()))
            if worker.process.is_alive():
                worker.process.kill()
                worker.process.join(5)
            worker.conn.close()
        self.workers.clear()

    # -- a batch -------------------------------------------------------------------------------

    def __call__(
        self,
        problem: DesignProblem,
        X: np.ndarray,
        on_result: Callable[[int, Evaluation], None] | None = None,
    ) -> list[Evaluation]:
        """Evaluate (m, n_var) designs on the pool; returns m Evaluations in order."""
        return self.run(problem, X, (), on_result)[0]

    def run(
        self,
        problem: DesignProblem,
        X: np.ndarray,
        calls: Sequence[tuple[str, np.ndarray]] = (),
        on_result: Callable[[int, Evaluation], None] | None = None,
    ) -> tuple[list[Evaluation], list[HookAnswer]]:
        """Evaluate (m, n_var) designs and answer the problem's hook ``calls`` ((kind, x):
        :data:`optimise.hook_call.HOOKS`, the hybrid's Jacobians and checks) on the pool, as one
        batch; returns (m Evaluations, one HookAnswer per call), in order.

        The calls go first, one per message (each costs several designs' time: started first,
        they do not leave a worker alone with one at the batch's end). They are not under the
        time limit (a Jacobian costs several evaluations; in the run process they had none): a
        call whose worker dies is tried :data:`MAX_ATTEMPTS` times, then answers with the error
        (the hybrid then does without it, as when the hook raises).
        """
        X = np.atleast_2d(np.asarray(X, dtype=float)) if len(X) else np.zeros((0, 0))
        n_obj, n_con = len(problem.objective_names), len(problem.constraint_names)
        m = len(X)
        results: list[Any] = [None] * (m + len(calls))
        size = chunk_rows(m, self.n_workers, self.chunk_size)
        # a call at a design of this batch goes right behind that design, in its message: the
        # worker that solved it answers the call from the path it has just solved (the hybrid's
        # Jacobian taken ahead at a trial design, optimise.hybrid._Stage._ahead_calls)
        rows_of = {design_key(X[row]): row for row in range(m)}
        behind: dict[int, tuple[int, Any]] = {}
        queue: deque[tuple[int, Any]] = deque()
        for i, (kind, x) in enumerate(calls):
            item = (m + i, (kind, np.asarray(x, dtype=float)))
            row = rows_of.get(design_key(item[1][1]))
            if row is not None and row not in behind:
                behind[row] = item
            else:
                queue.append(item)
        for row in range(m):
            queue.append((row, X[row]))
            if row in behind:
                queue.append(behind[row])
        follows = {item[0] for item in behind.values()}
        attempts = [0] * len(results)
        n_left = len(results)

        def finish(row: int, evaluation: Any) -> None:
            nonlocal n_left
            if results[row] is None:
                results[row] = evaluation
                n_left -= 1
                if on_result is not None and row < m:
                    on_result(row, evaluation)

        def died(row: int, x: Any, why: str) -> Any:
            """The answer of a design or call whose worker died under it ``attempts`` times."""
            times = f"({why}), {attempts[row]} times"
            if row >= m:  # a hook call: its answer is the error
                return HookAnswer(None, f"WorkerDied: the worker died calling {x[0]} {times}")
            return Evaluation.failed(
                x,
                n_obj,
                n_con,
                f"WorkerDied: the worker process died while evaluating this design {times}",
            )

        def lost(worker: _Worker, why: str) -> None:
            """The worker died: resubmit its designs, the one it was solving up to a limit."""
            pending = list(worker.task or ())
            self._stop(worker)
            self.n_replaced += 1
            if not worker.ready:
                self._failed_starts += 1
                if self._failed_starts >= 2 * self.n_workers:
                    raise BackendError(
                        f"worker processes die before they load the design problem ({why}); "
                        "run in this process with --workers 1 to see why"
                    )
            self._start()
            if pending:
                row, x = pending[0]
                attempts[row] += 1
                if attempts[row] >= MAX_ATTEMPTS:
                    finish(row, died(row, x, why))
                    pending = pending[1:]
                log.warning("a worker died (%s); resubmitting %d designs", why, len(pending))
                queue.extendleft(reversed(pending))

        while n_left:
            # Keep n_workers alive, and give every ready worker a chunk whenever at most
            # POOL_QUEUED_DESIGNS of its designs are unreported (one queued behind the one it
            # solves: it goes on without waiting for this process).
            while len(self.workers) < self.n_workers:
                self._start()
            now = time.perf_counter()
            broken: list[_Worker] = []
            # a call at a design an idle worker solved goes to that worker first (one queued
            # behind its design of this batch stays there)
            for item in [q for q in queue if q[0] >= m and q[0] not in follows] if calls else ():
                worker = self.solved_by.get(design_key(item[1][1]))
                if worker in self.workers and worker.ready and not worker.task:
                    queue.remove(item)
                    worker.task, worker.started = deque([item]), now
                    try:
                        worker.conn.send([item])
                    except OSError:  # it died since the last wait (BrokenPipeError)
                        broken.append(worker)
            # every idle worker a chunk first, then one more queued behind each busy one: a
            # batch smaller than the workers' queues (a hybrid round of two trial designs)
            # would otherwise go to one worker while the other idles
            for idle_only in (True, False):
                for worker in self.workers:
                    while (
                        worker not in broken
                        and worker.ready
                        and queue
                        and len(worker.task or ()) <= POOL_QUEUED_DESIGNS
                    ):
                        if worker.task and (
                            idle_only or worker.task[0][0] >= m or queue[0][0] >= m
                        ):
                            # a hook call only to an idle worker, and nothing queued behind one:
                            # another worker may be free long before it ends
                            break
                        if queue[0][0] >= m:  # a hook call: a message of its own
                            chunk = [queue.popleft()]
                        else:  # designs, up to a call queued behind one (it ends the chunk)
                            chunk = []
                            while queue and len(chunk) < size and queue[0][0] < m:
                                chunk.append(queue.popleft())
                                if queue and queue[0][0] >= m and chunk[-1][0] in behind:
                                    chunk.append(queue.popleft())
                                    break
                        if not worker.task:  # idle: its first design starts now
                            worker.task = deque()
                            worker.started = now
                        worker.task.extend(chunk)
                        try:
                            worker.conn.send(chunk)
                        except OSError:  # it died since the last wait (BrokenPipeError)
                            broken.append(worker)
                            break
            for worker in broken:  # its designs, this chunk too, go to the others
                worker.process.join(1)
                lost(worker, _exit_text(worker.process.exitcode))
            if broken:
                continue
            timeout = None
            if self.timeout_s is not None:  # hook calls have no time limit (see run)
                busy = [w.started for w in self.workers if w.task and w.task[0][0] < m]
                if busy:
                    timeout = max(0.0, min(busy) + self.timeout_s - now) + 0.01
            ready = wait(
                [w.conn for w in self.workers] + [w.process.sentinel for w in self.workers],
                timeout,
            )
            for worker in list(self.workers):
                dead = worker.process.sentinel in ready
                try:
                    # drain what a dying worker sent before it died
                    while (worker.conn in ready or dead) and worker.conn.poll():
                        message = worker.conn.recv()
                        self._handle(worker, message, finish)
                except (EOFError, OSError):
                    dead = True
                if dead or not worker.process.is_alive():
                    code = worker.process.exitcode
                    worker.process.join(1)
                    code = worker.process.exitcode if code is None else code
                    lost(worker, _exit_text(code))
            if self.timeout_s is not None:
                now = time.perf_counter()
                for worker in list(self.workers):
                    if (
                        worker.task
                        and worker.task[0][0] < m
                        and now - worker.started > self.timeout_s
                    ):
                        row, x = worker.task.popleft()
                        log.warning(
                            "design %d exceeded %g s: replacing its worker", row, self.timeout_s
                        )
                        finish(
                            row,
                            Evaluation.failed(
                                x, n_obj, n_con, timeout_reason(self.timeout_s), self.timeout_s
                            ),
                        )
                        # the rest of its chunk goes back to the queue, untouched
                        queue.extendleft(reversed(list(worker.task)))
                        worker.task = None
                        self._stop(worker)
                        self.n_replaced += 1
                        self._start()
        return results[:m], results[m:]

    def _handle(
        self,
        worker: _Worker,
        message: tuple[Any, ...],
        finish: Callable[[int, Evaluation], None],
    ) -> None:
        kind = message[0]
        if kind == "ready":
            worker.ready = True
            self._failed_starts = 0
        elif kind == "done":
            _, row, evaluation = message
            if worker.task and worker.task[0][0] == row:
                _, x = worker.task.popleft()
                if not isinstance(x, tuple):  # a design, not a hook call
                    self.solved_by[design_key(x)] = worker
                    self.solved_by.move_to_end(design_key(x))
                    while len(self.solved_by) > SOLVED_BY_KEPT:
                        self.solved_by.popitem(last=False)
            worker.started = time.perf_counter()  # the next design of the chunk starts now
            finish(row, evaluation)
        elif kind == "fatal":
            self.close()
            raise BackendError(
                f"worker processes cannot load the design problem ({message[1]}); is the kind's "
                "module importable outside this process? Run with --workers 1 to stay in it"
            )


def _exit_text(code: int | None) -> str:
    if code is None:
        return "no exit code"
    if code < 0:
        with contextlib.suppress(ValueError):
            return f"killed by {signal.Signals(-code).name}"
        return f"killed by signal {-code}"
    return f"exit code {code}"
