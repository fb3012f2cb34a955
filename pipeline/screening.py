"""Two processes for a kind's own work: a screening shared with a forked child, a side process.

Execution layer (moved here from ``pipeline/studies/sea_spring.py`` unchanged in behaviour, so
that a study kind imports no process library):

- :class:`Screening` — a list of independent jobs (e.g. the ``sea_spring`` Taguchi stage's
  level tuples) solved by this process and one forked child beside it, both taking the next
  job from a shared counter; the results do not depend on which process solved a job.
- :class:`SideProcess` — one worker process that runs tasks sent to it (the report's work that
  needs no 3D answer), giving None when the caller must compute a task itself.
- :func:`fork_context_here` — multiprocessing's fork context where forking is safe here.
- :func:`one_blas_thread` — BLAS and OpenMP pools limited to one thread, for a block of work.
- :func:`taguchi_stage` — the ``sea_spring`` kind's stage 1 (an orthogonal array, its Eq. 27
  analysis and extra runs, :mod:`optimise.sea_cost`) solved by a :class:`Screening`.

Both children start as :mod:`pipeline.parallel`'s workers (one BLAS thread, Ctrl-C left to the
parent, SIGTERM ends them at once) and end when their parent is gone.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from typing import Any

from flexopt.fea.errors import FeaError
from flexopt.geometry.errors import GeometryError

__all__ = [
    "Screening",
    "SideProcess",
    "fork_context_here",
    "one_blas_thread",
    "screening_child",
    "side_main",
    "taguchi_stage",
]

log = logging.getLogger(__name__)


def fork_context_here() -> Any:
    """multiprocessing's fork context where forking is safe here, else None: the one fork helper
    (:func:`pipeline.fork.fork_context`) for a long child, from a single-threaded process only
    (a lock another thread holds at the fork stays held for ever in the child)."""
    from flexopt.pipeline.fork import fork_context

    return fork_context(single_threaded=True)


def one_blas_thread() -> Any:
    """A context manager limiting the loaded BLAS and OpenMP pools to one thread (as in the
    pool's workers) for the work inside it (:func:`threadpoolctl.threadpool_limits`)."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(1)


class Screening:
    """Independent ``jobs`` solved by ``solve_one`` in this process and, where fork is
    available, one forked child beside it.

    Both take the next unsolved job from a shared counter, so the two cores stay busy whatever
    each job costs (a row that cannot be built takes milliseconds, a spring ~0.1 s); the child
    sends back ``(index, result)`` through a pipe. Fork shares ``solve_one`` and what it holds,
    so nothing is pickled on the way in (results are pickled on the way back). :meth:`get`
    returns the results of the first jobs in order, solving here what is not taken yet (later
    jobs too, while the child finishes one of these) and then waiting for what the child took:
    a caller can solve its own extra job (:meth:`solve`) while the child goes on with the rest.
    Where fork is not available or the child cannot start, every job is solved here; a child
    that dies leaves its jobs to this process, and one that keeps a job much longer than the
    slowest job here took (stuck, or starved of CPU) has it solved here too. ``solve_one`` must
    give the same answer in either process.

    ``label`` starts the log lines (e.g. ``"stage 1"``), ``name`` names the child process.
    """

    def __init__(
        self, jobs: Sequence[Any], solve_one: Callable[[Any], Any], fork: bool = True,
        label: str = "screening", name: str = "flexopt-screening",
    ) -> None:  # fmt: skip
        self.jobs = list(jobs)
        self._solve_one = solve_one
        self.label = label
        self.name = name
        self.results: list[Any] = [None] * len(self.jobs)
        self.in_child = 0  # results of the child's that were used (for the log)
        self._slowest_s = 0.0  # the longest job solved here, s
        self._process: Any = None
        self._conn: Any = None
        self._gone = ""  # why the child is no longer of use ("" while it is)
        if fork and len(self.jobs) > 1:
            self._start()

    def solve(self, job: Any) -> Any:
        """One job, in this process: ``solve_one(job)``."""
        t0 = time.perf_counter()
        out = self._solve_one(job)
        self._slowest_s = max(self._slowest_s, time.perf_counter() - t0)
        return out

    def _start(self) -> None:
        import sys

        ctx = fork_context_here()
        if ctx is None:
            return
        try:
            from flexopt.fea.plane_stress import warm_up

            # the compiled kernels and the sparse Cholesky loaded once, here, for both (~0.4 s
            # CPU each process would spend on its first run; the pool's warm-up then finds them)
            warm_up()
            self._lock = ctx.Lock()
            self._next = ctx.RawValue("i", 0)
            receive, send = ctx.Pipe(duplex=False)
            # output buffered here would be written a second time by the child at its exit
            sys.stdout.flush()
            sys.stderr.flush()
            process = ctx.Process(target=screening_child, args=(self, receive, send),
                                  name=self.name, daemon=True)  # fmt: skip
            process.start()
            send.close()
        except Exception as exc:  # a daemonic process, no more processes: all solved here
            log.info("%s in this process only (%s)", self.label, exc)
            return
        self._process, self._conn = process, receive

    def claim(self, keep_trying: Callable[[], bool]) -> int | None:
        """The next job nobody has taken (``len(jobs)`` when all are), or None when the lock
        stays held elsewhere and ``keep_trying()`` is False (the other process died or hangs
        holding it: it is held for microseconds)."""
        from flexopt.pipeline.parallel import PARENT_CHECK_S

        while not self._lock.acquire(timeout=PARENT_CHECK_S):
            if not keep_trying():
                return None
        try:
            i = self._next.value
            if i < len(self.jobs):
                self._next.value = i + 1
            return i
        finally:
            self._lock.release()

    def get(self, n: int) -> list[Any]:
        """The results of jobs ``0 .. n-1``, as ``solve_one`` gives them."""
        while True:
            if self._process is not None:
                self._receive(0.0)
            missing = [i for i in range(n) if self.results[i] is None]
            if not missing:
                return self.results[:n]
            if self._process is not None and self._gone:
                self._drop()
            if self._process is None:
                self.results[missing[0]] = self.solve(self.jobs[missing[0]])
            elif self._next.value < len(self.jobs):
                # a job nobody has taken: solve it here, also when it is not one of these
                # (rather than wait for the child's last job of these, idle)
                i = self.claim(lambda: False)
                if i is None:  # the child holds the lock: dead or stuck
                    self._process.join(0.1)
                    code = self._process.exitcode
                    self._gone = "is stuck" if code is None else f"ended (exit code {code})"
                elif i < len(self.jobs):
                    self.results[i] = self.solve(self.jobs[i])
            elif not self._receive(2.0 * self._slowest_s + 0.05) and not self._gone:
                # the child has the rest of these, and has kept the first much longer than
                # the slowest job here took: solve it here (its answer would be the same)
                log.debug("%s: run %d taken over from the second process", self.label,
                          missing[0])  # fmt: skip
                self.results[missing[0]] = self.solve(self.jobs[missing[0]])

    def _receive(self, timeout_s: float) -> bool:
        """Take the child's results that have arrived, waiting up to ``timeout_s`` for one;
        whether one came. Sets ``_gone`` when the child has ended."""
        try:
            if not self._conn.poll(timeout_s):
                if not self._process.is_alive() and not self._conn.poll():
                    self._gone = f"ended (exit code {self._process.exitcode})"
                return False
            while self._conn.poll():
                i, result = self._conn.recv()
                if self.results[i] is None:  # else solved here meanwhile: the same answer
                    self.results[i] = result
                    self.in_child += 1
            return True
        except (EOFError, OSError):  # its end of the pipe closed: it has ended
            self._process.join(5.0)
            self._gone = f"ended (exit code {self._process.exitcode})"
            return True

    def _drop(self) -> None:
        log.warning("%s: the second process %s before it sent all its runs; they are "
                    "solved here", self.label, self._gone)  # fmt: skip
        self.close()

    def close(self) -> None:
        """Stop the child (at once when it is not done: its results are not needed) and reap
        it; idempotent."""
        if self._process is not None:
            log.info("%s: %d of %d runs solved in the second process", self.label,
                     self.in_child, len(self.jobs))  # fmt: skip
            if not self._gone and all(r is not None for r in self.results):
                self._process.join(0.5)  # it has found nothing left to take and is exiting
            if self._process.is_alive():
                self._process.terminate()
                self._process.join(5.0)
            if self._process.is_alive():
                self._process.kill()
                self._process.join()
            self._conn.close()
        self._process = self._conn = None


def _start_as_worker() -> None:
    """A child's start, as pipeline.parallel's workers: one BLAS thread beside the parent's
    (whatever its caller set), Ctrl-C left to the parent (it reaches the whole process group:
    the parent decides, and ends this one), SIGTERM ending it at once (a forked child inherits
    the CLI's handler, but is ended by its parent and must then end as a process normally does).
    """
    from flexopt.pipeline.fork import limit_loaded_pools, quiet_child
    from flexopt.pipeline.parallel import pin_threads

    pin_threads()
    limit_loaded_pools()
    quiet_child()


def screening_child(screening: Screening, receive: Any, send: Any) -> None:
    """The forked child of :class:`Screening`: takes jobs until none is left, sends each
    result; ends when its parent is gone."""
    import os

    receive.close()  # the parent's end: a send to a parent that died then fails at once
    _start_as_worker()
    parent = os.getppid()

    def parent_alive() -> bool:
        return os.getppid() == parent

    try:
        while parent_alive():
            i = screening.claim(parent_alive)
            if i is None or i >= len(screening.jobs):
                return
            send.send((i, screening.solve(screening.jobs[i])))
    except Exception:  # the parent is gone, or a job raised: the parent solves it again
        return  # (and raises it, where the error belongs)
    finally:
        send.close()


def side_main(conn: Any) -> None:
    """The side process: run the tasks ``(name, func, args)`` it is sent, one after the other,
    until told to stop (None), its pipe closes or its parent is gone; each answer goes back as
    ``(name, ("ok", value))`` or ``(name, ("error", exception))``."""
    import os

    from flexopt.pipeline.parallel import PARENT_CHECK_S

    _start_as_worker()  # one BLAS thread: the first process factorises beside it
    parent = os.getppid()
    while True:
        try:
            while not conn.poll(PARENT_CHECK_S):
                if os.getppid() != parent:  # orphaned (a forked copy of the pipe stays open)
                    return
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        name, func, args = task
        try:
            out: tuple[str, Any] = ("ok", func(*args))
        except Exception as exc:
            out = ("error", exc)
        try:
            conn.send((name, out))
        except Exception as exc:  # a result or an exception that does not pickle
            conn.send((name, ("error", RuntimeError(f"{type(exc).__name__}: {exc}"))))


class SideProcess:
    """One worker process for a report's work that needs no answer of this process's.

    In ``sea_spring`` the 3D checks keep this process busy (assembly, one factorisation,
    triangular solves); the peak convergence (nonlinear plane-stress solves on refined meshes,
    ~10 s CPU on the default study) and, where the 3D checks are the longer work (no CHOLMOD:
    ``_sea_spring_peak.solves_here``), the detail's two extra 2D solves depend only on the
    design, so they run beside them on the second core. A task is a module-level function and
    its arguments (pickled). Where a process cannot be started (a daemonic worker), or dies or
    fails on a task, :meth:`get` gives None and the caller computes it itself; FeaError and
    GeometryError of a task come back raised.
    """

    def __init__(self, process: Any = None, conn: Any = None) -> None:
        self._process, self._conn = process, conn
        self._sent: set[str] = set()
        self._results: dict[str, tuple[str, Any]] = {}

    @classmethod
    def start(cls) -> SideProcess:
        try:
            from flexopt.pipeline.fork import pool_context

            ctx = pool_context()
            conn, child_conn = ctx.Pipe()
            process = ctx.Process(target=side_main, args=(child_conn,), daemon=True,
                                  name="flexopt-report-side")  # fmt: skip
            process.start()
            child_conn.close()
            return cls(process, conn)
        except Exception as exc:  # no second process here: the callers compute in this one
            log.info("report work in this process only (%s)", exc)
            return cls()

    def submit(self, name: str, func: Callable[..., Any], *args: Any) -> None:
        if self._conn is None:
            return
        try:
            self._conn.send((name, func, args))
            self._sent.add(name)
        except Exception as exc:  # an argument that does not pickle: computed here
            log.info("report task %s stays in this process (%s)", name, exc)

    def get(self, name: str) -> Any:
        """The task's result, or None when the caller must compute it."""
        if name not in self._sent:
            return None
        self._sent.discard(name)
        from flexopt.pipeline.parallel import PARENT_CHECK_S

        try:
            while name not in self._results:
                if self._conn.poll(PARENT_CHECK_S):
                    done, out = self._conn.recv()
                    self._results[done] = out
                elif not self._process.is_alive():
                    raise RuntimeError(f"it ended (exit code {self._process.exitcode})")
        except Exception as exc:  # died (killed, out of memory) or a broken pipe
            log.warning("report task %s: the second process failed (%s); redone here", name,
                        exc)  # fmt: skip
            self.close()
            return None
        status, value = self._results.pop(name)
        if status == "ok":
            return value
        if isinstance(value, FeaError | GeometryError):
            raise value
        log.warning("report task %s failed in the second process (%s); redone here", name,
                    value)  # fmt: skip
        return None

    def close(self) -> None:
        """Stop the process (at once: a result not fetched is not needed)."""
        if self._process is not None:
            self._process.terminate()
            self._process.join(5.0)
            if self._process.is_alive():
                self._process.kill()
                self._process.join()
            self._conn.close()
        self._process = self._conn = None
        self._sent.clear()


def taguchi_stage(
    table: dict[str, tuple[float, ...]],
    solve_one: Callable[[tuple[int, ...]], Any],
    spec: Any,
    torque_Nm: float,
    theta_t_deg: float,
    topology: str,
    fork: bool = True,
) -> dict[str, Any]:
    """The screening stage over the factors of ``table`` (factor -> its five level values):
    the runs of :func:`optimise.sea_cost.screening_plan` solved by ``solve_one`` (a level
    tuple -> (stiffness N m/rad, peak stress per radian MPa/rad, reason)) in this process and,
    with ``fork``, a forked child beside it (:class:`Screening`), then analysed by
    :func:`optimise.sea_cost.taguchi_analysis` at the screening torque ``torque_Nm`` (N m) and
    target rotation ``theta_t_deg`` (degrees).

    ``spec``: the ``taguchi:`` block (``extra_runs``, ``seed``, ``pool_below_percent``,
    ``min_error_dof``); ``topology`` names the topology in the result. Returns
    :func:`optimise.sea_cost.taguchi_analysis`'s dict (plain data).
    """
    from flexopt.optimise.sea_cost import screening_plan, taguchi_analysis

    lay, extra, jobs = screening_plan(table, spec.extra_runs, spec.seed)
    n_array = len(lay.design)
    screening = Screening(jobs, solve_one, fork=fork, label="stage 1", name="flexopt-taguchi")
    try:
        runs = screening.get(n_array)
        # the confirmation run solved here while the child goes on with the extra runs
        return taguchi_analysis(
            lay, table, runs, extra, screening.solve,
            lambda: screening.get(len(screening.jobs))[n_array:], torque_Nm, theta_t_deg,
            spec.pool_below_percent, spec.min_error_dof, topology,
        )  # fmt: skip
    finally:
        screening.close()
