"""Child processes: the one place flexopt decides whether and how it forks."""

from __future__ import annotations

import contextlib
import logging
import signal
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from flexopt.pipeline.parallel import one_line as _one_line

if TYPE_CHECKING:  # geometry.solid (manifold3d, trimesh) is imported when a part is made
    pass

log = logging.getLogger(__name__)


class _ForkedMakes:
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
        ctx = _fork_context()
        if ctx is None:
            return
        try:
            receive, send = ctx.Pipe(duplex=False)
            self.process = ctx.Process(
                target=_make_in_child,
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
            return _make_here(self.items)
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


def _fork_context() -> Any:
    """multiprocessing's fork context where forking is safe (Linux and the like), else None."""
    import multiprocessing as mp

    if sys.platform in ("darwin", "win32") or "fork" not in mp.get_all_start_methods():
        return None
    return mp.get_context("fork")


def _make_here(
    items: list[tuple[str, Callable[[], str | bytes | None]]],
) -> list[tuple[str, str | bytes | None, str | None]]:
    out: list[tuple[str, str | bytes | None, str | None]] = []
    for name, make in items:
        try:
            out.append((name, make(), None))
        except Exception as exc:
            out.append((name, None, _one_line(f"{type(exc).__name__}: {exc}")))
    return out


def _quiet_child() -> None:
    """Signals in a forked report child: Ctrl-C reaches the whole process group, and a child
    inherits the CLI's SIGTERM handler (which raises :class:`Terminated`); the run decides what
    stops and says it in one line, so the child ignores Ctrl-C and dies of SIGTERM at once,
    without a traceback of its own."""
    with contextlib.suppress(ValueError, OSError):  # not the main thread: nothing to change
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _make_in_child(
    conn: Any, items: list[tuple[str, Callable[[], str | bytes | None]]], theirs: Any = None
) -> None:
    _quiet_child()
    if theirs is not None:  # the parent's end, inherited: closed, so that a parent that gives
        theirs.close()  # up makes the answer fail at once instead of blocking on a full pipe
    try:
        conn.send(_make_here(items))
    except BaseException:  # noqa: BLE001 - the parent stopped (SIGTERM, a full disk) or closed
        # the pipe: it reports what happened in its own line; a child's traceback after that
        # line would bury it (the parent notes a child that died without an answer)
        pass
    finally:
        with contextlib.suppress(Exception):
            conn.close()
