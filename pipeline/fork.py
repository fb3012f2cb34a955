"""Child processes: the one place flexopt decides whether and how it forks.

- :func:`fork_context`: fork where forking is safe (not on macOS or Windows; with
  ``single_threaded`` only from a process that runs no other thread), else None: the report's
  children (:class:`ForkedMakes`), best.step's early child (:mod:`pipeline.run.step_child`) and
  the Taguchi stage's screening child.
- :func:`pool_context`: the start method of long-lived worker processes (the local pool of
  :mod:`pipeline.parallel`, a report's side process): fork where safe, else forkserver, else
  spawn.
- :func:`quiet_child` and :func:`limit_loaded_pools`: what every child does first (signals, one
  BLAS thread); the latter also scoped (``with``) where this process solves many small systems
  itself: ``flexopt evaluate``, a serial run, the API.
- :class:`ForkedMakes` (:func:`make_in_child`, :func:`make_here`): make some result files in a
  quiet forked child while this process goes on.

It imports nothing heavy (no numpy even): every worker process imports it.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import signal
import sys
import threading
from collections.abc import Callable
from typing import Any

from flexopt.pipeline.errors import one_line as _one_line

__all__ = [
    "ForkedMakes",
    "fork_context",
    "limit_loaded_pools",
    "make_here",
    "make_in_child",
    "pool_context",
    "quiet_child",
]

log = logging.getLogger(__name__)


def fork_context(single_threaded: bool = False) -> Any:
    """multiprocessing's fork context where forking is safe (Linux and the like), else None.

    With ``single_threaded`` also None while this process runs another thread (a lock another
    thread holds at the fork stays held for ever in the child): for a child that runs long or
    imports (the Taguchi stage's screening child); a short child that only draws files forks
    from a process whose threads hold no lock it needs.
    """
    if sys.platform in ("darwin", "win32") or "fork" not in multiprocessing.get_all_start_methods():
        return None
    if single_threaded and threading.active_count() != 1:
        return None
    return multiprocessing.get_context("fork")


def pool_context() -> multiprocessing.context.BaseContext:
    """The start method of long-lived worker processes (the local pool, a side process)."""
    # fork is instant and the worker inherits the imported modules, but forking a process that
    # runs other threads (a progress bar, a Dask client) can deadlock the child, and macOS
    # libraries do not survive it: fork only on Linux from a single-threaded process (the pool
    # starts its workers before the progress bar). Otherwise forkserver, which forks from a clean
    # single-threaded server without re-running the user's __main__ each time as spawn does;
    # spawn where there is no forkserver (Windows).
    if sys.platform == "linux" and threading.active_count() == 1:
        return multiprocessing.get_context("fork")
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        # the server imports numpy and this module once; each worker forks with them loaded
        ctx.set_forkserver_preload(["flexopt.pipeline.parallel"])
        return ctx
    return multiprocessing.get_context("spawn")


def limit_loaded_pools() -> contextlib.AbstractContextManager[Any]:
    """One thread for the BLAS/OpenMP pools already loaded, from now on; the returned object,
    used as a context manager, gives the caller's limits back on exit.

    Called bare in a worker process (a forked worker inherits the parent's pools, sized before
    the variables were set). Used as ``with limit_loaded_pools():`` wherever this process
    solves many small systems itself (``flexopt evaluate``, the serial backend, the API): a
    banded or sparse factorisation of a few thousand rows is latency-bound, so a second BLAS
    thread only spins (an SEA design took ~1.9x the CPU with two threads; docs/benchmarks.md,
    benchmarks/serial_threads.py), and the scope keeps a caller's own numpy work unslowed.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # optional: the environment variables cover freshly started workers
        return contextlib.nullcontext()
    return threadpool_limits(1)


class ForkedMakes:
    """Make some result files in a forked child process while this one goes on.

    ``items`` are (name, make) pairs; the child runs each ``make`` in order and sends back
    (name, data, None) or (name, None, error text). Forking shares everything already imported
    and computed (matplotlib, the detail), so nothing is pickled on the way in. Where fork is not
    available (Windows, macOS) or the child cannot start, the files are made here, in order. A
    child that dies without an answer (a crash in a native library) gives each of its files a
    note instead of bringing the run down with it.
    """

    def __init__(self, items: list[tuple[str, Callable[[], str | bytes | None]]]) -> None:
        self.items = items
        self.conn: Any = None
        self.process: Any = None
        ctx = fork_context()
        if ctx is None:
            return
        try:
            receive, send = ctx.Pipe(duplex=False)
            self.process = ctx.Process(
                target=make_in_child,
                args=(send, items, receive),
                name="flexopt-report",
                daemon=True,
            )
            self.process.start()
            send.close()
            self.conn = receive
        except Exception as exc:  # no fork here: make them in this process
            log.info("report files made in this process: %s", _one_line(str(exc)))
            self.conn = self.process = None

    def results(self) -> list[tuple[str, str | bytes | None, str | None]]:
        if self.conn is None:
            return make_here(self.items)
        try:
            return self.conn.recv()
        except (EOFError, OSError):
            self.process.join(5)
            code = self.process.exitcode
            how = f"signal {-code}" if code is not None and code < 0 else f"exit code {code}"
            return [(name, None, f"the process making it died ({how})") for name, _ in self.items]
        finally:
            self.conn.close()
            self.process.join(5)


def make_here(
    items: list[tuple[str, Callable[[], str | bytes | None]]],
) -> list[tuple[str, str | bytes | None, str | None]]:
    """Make each (name, make) here, in order: (name, data, None), or (name, None, the error in
    one line) for a make that raises."""
    out: list[tuple[str, str | bytes | None, str | None]] = []
    for name, make in items:
        try:
            out.append((name, make(), None))
        except Exception as exc:
            out.append((name, None, _one_line(f"{type(exc).__name__}: {exc}")))
    return out


def quiet_child() -> None:
    """Signals in a child (a report child, a pool worker): Ctrl-C reaches the whole process
    group, and a forked child inherits the CLI's SIGTERM handler (which raises
    :class:`Terminated`); the parent decides what stops and says it in one line, so the child
    ignores Ctrl-C and dies of SIGTERM at once, without a traceback of its own."""
    with contextlib.suppress(ValueError, OSError):  # not the main thread: nothing to change
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def make_in_child(
    conn: Any, items: list[tuple[str, Callable[[], str | bytes | None]]], theirs: Any = None
) -> None:
    """:class:`ForkedMakes`' child: make ``items`` (:func:`make_here`) and send the list back on
    ``conn``; ``theirs`` is the parent's end of the pipe, closed here."""
    quiet_child()
    if theirs is not None:  # the parent's end, inherited: closed, so that a parent that gives
        theirs.close()  # up makes the answer fail at once instead of blocking on a full pipe
    try:
        conn.send(make_here(items))
    except BaseException:  # noqa: BLE001 - the parent stopped (SIGTERM, a full disk) or closed
        # the pipe: it reports what happened in its own line; a child's traceback after that
        # line would bury it (the parent notes a child that died without an answer)
        pass
    finally:
        with contextlib.suppress(Exception):
            conn.close()
