"""best.step's child: forked when a run starts (or when its report starts), it imports the STEP
writer while a core is idle and makes the part it is sent.

Since session 29 the STEP writer is :mod:`geometry.step_writer` (a SEA spring's best.step in
~0.2 s CPU instead of OpenCascade's ~17 s) and its import is light; build123d is imported only
for an outline the direct writer refuses (:func:`geometry.solid.step_bytes`)."""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from flexopt.pipeline.fork import fork_context, make_here, quiet_child
from flexopt.pipeline.parallel import one_line as _one_line
from flexopt.pipeline.run.export import part_bytes

if TYPE_CHECKING:  # geometry.solid (manifold3d, trimesh) is imported when a part is made
    from flexopt.geometry.solid import FlatPart

log = logging.getLogger(__name__)


#: The nice level of best.step's child while the workers solve: the lowest priority, so its
#: import of build123d takes only the CPU time the workers and this process leave idle.
EARLY_STEP_NICE = 19


class EarlyStep:
    """best.step made in a child forked before the part is known: when the run starts, at the
    lowest priority (:data:`EARLY_STEP_NICE`), or else when the report starts.

    The STEP writer's import (build123d and OpenCascade, ~3 s) needs nothing of the run, so the
    child does it while the best design's detail is solved, but only once a core is idle
    (:func:`_wait_for_idle_core`): the SEA spring's 3D checks keep one core busy and its peak
    convergence the other for their first ~10 s, and an import beside them would slow the
    checks. When the part arrives (:meth:`send`) the child imports at once if it has not yet,
    makes the file and sends it back (:meth:`results`, as :class:`ForkedMakes`). Where fork is
    not available or the child cannot start, :meth:`start` gives None and the file is made as
    before (a "step" group).
    """

    items = (("best.step", None),)  # what it makes, for a dead child's notes

    def __init__(self, conn: Any, process: Any, nice: int = 0) -> None:
        self.conn, self.process = conn, process
        self.nice = nice  # > 0: the child runs lowered (and on SCHED_IDLE) until it has the part
        self._sent = False

    @classmethod
    def start(cls, nice: int = 0) -> EarlyStep | None:
        """Fork the child; with ``nice`` > 0 it runs at that lower priority and imports at once
        (it only takes CPU time no other process wants)."""
        ctx = fork_context()
        if ctx is None:
            return None
        try:
            ours, theirs = ctx.Pipe(duplex=True)
            process = ctx.Process(
                target=_early_step_main,
                args=(theirs, nice, ours),
                name="flexopt-step",
                daemon=True,
            )
            process.start()
            theirs.close()
        except Exception as exc:
            log.info("best.step made later: %s", _one_line(str(exc)))
            return None
        return cls(ours, process, nice)

    def send(self, part: FlatPart) -> bool:
        """Hand the child the part; False when it is gone (then make the file another way)."""
        try:
            self.conn.send(part)
        except (OSError, ValueError, EOFError):
            return False
        self._sent = True
        if self.nice > 0:
            self._restore_priority()
        return True

    def _restore_priority(self) -> None:
        """The child back at this process's priority now that the report waits for it.

        The child does so itself once its import is done, but a child on SCHED_IDLE gets no CPU
        time while every core is wanted: on a busy machine its import, and so the run's end,
        waited for minutes (a constant-force run at load 40 on 2 cores: over 10 minutes, the
        report done). Where this process may not (no CAP_SYS_NICE, RLIMIT_NICE), the child's
        own restore stands as before.
        """
        pid = self.process.pid
        with contextlib.suppress(OSError, AttributeError, ValueError):
            os.sched_setscheduler(pid, os.SCHED_OTHER, os.sched_param(0))
            os.setpriority(os.PRIO_PROCESS, pid, os.getpriority(os.PRIO_PROCESS, 0))

    def results(self) -> list[tuple[str, str | bytes | None, str | None]]:
        try:
            return self.conn.recv()
        except (EOFError, OSError):
            self.process.join(5)
            code = self.process.exitcode
            how = f"signal {-code}" if code is not None and code < 0 else f"exit code {code}"
            return [("best.step", None, f"the process making it died ({how})")]

    def abort(self) -> None:
        """End the child at once (the run stopped before its report: there is nothing to make,
        and no reason to wait for an import); nothing when it has ended already."""
        with contextlib.suppress(OSError, ValueError):
            self.process.kill()
        self.process.join(5)
        self.conn.close()

    def close(self) -> None:
        """End the child: told there is no part when it has none, else its answer was read."""
        if not self._sent:
            with contextlib.suppress(OSError, ValueError):
                self.conn.send(None)
        self.conn.close()
        self.process.join(5)
        if self.process.is_alive():  # stuck in OpenCascade: a file is not worth a hung run
            self.process.kill()
            self.process.join(5)


def can_restore_priority(nice: int = EARLY_STEP_NICE) -> bool:
    """Whether a child lowered by ``nice`` (and put on SCHED_IDLE) may come back to this
    process's priority: root, or an RLIMIT_NICE that allows it (Linux's rule for leaving
    SCHED_IDLE is the same). An ordinary user's limit is 0: a child there would build best.step
    at the lowest priority, starved while the report's processes keep the cores busy, so the
    run then starts the child when the report starts instead (the path before issue 13's
    early child)."""
    try:
        if os.geteuid() == 0:
            return True
        import resource

        limit = resource.getrlimit(resource.RLIMIT_NICE)[0]
        here = os.getpriority(os.PRIO_PROCESS, 0)
    except (AttributeError, OSError, ValueError, ImportError):
        return False
    # RLIMIT_NICE r lets a process lower its nice value down to 20 - r
    return limit == resource.RLIM_INFINITY or 20 - limit <= here


def _early_step_main(conn: Any, nice: int = 0, ours: Any = None) -> None:
    """:class:`EarlyStep`'s child: import the STEP writer when a core is idle (at once when
    ``nice`` > 0: at that priority it only gets idle CPU time), then make the part it is sent
    (None: nothing to make)."""
    # Ctrl-C reaches the whole process group and a forked child inherits the CLI's SIGTERM
    # handler: the run decides what stops, and closes this child (as a pool worker).
    quiet_child()
    if ours is not None:  # the parent's end, inherited: closed, so a parent that dies is an
        ours.close()  # end of file here instead of a child waiting for a part forever
    try:
        priority = None
        if nice > 0:
            with contextlib.suppress(OSError, AttributeError):
                priority = os.getpriority(os.PRIO_PROCESS, 0)
                os.nice(nice)
                # Linux: SCHED_IDLE runs only when no other task wants the core (a worker that
                # wakes takes it back at once); the nice level alone still slowed the workers
                os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
        else:
            _wait_for_idle_core(conn.poll)
        # the parent may already be gone (or have no part): read that before a long import
        early = conn.recv() if conn.poll(0) else ...
        if early is None:
            return
        with contextlib.suppress(Exception):  # step_bytes says what fails, as a note
            # the direct STEP writer (shapely, numpy: ~0.1 s), not build123d (~3 s): step_bytes
            # imports OpenCascade only for an outline the direct writer refuses
            import flexopt.geometry.solid  # noqa: F401
            import flexopt.geometry.step_writer  # noqa: F401
        part = conn.recv() if early is ... else early
        if priority is not None:  # the report waits for the part now: back to the run's
            # priority where the system allows it (root, RLIMIT_NICE); else it stays low
            with contextlib.suppress(OSError, AttributeError):
                os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
                os.setpriority(os.PRIO_PROCESS, 0, priority)
        if part is not None:
            conn.send(make_here([("best.step", lambda: part_bytes(part, "step"))]))
    except BaseException:  # noqa: BLE001 - the parent is gone or closed the pipe, or stopped:
        pass  # it says why in one line; this child ends quietly
    finally:
        with contextlib.suppress(Exception):
            conn.close()


def _wait_for_idle_core(ready: Callable[[float], bool], period_s: float = 0.2,
                        idle_cores: float = 0.6, limit_s: float = 600.0) -> None:  # fmt: skip
    """Return once the machine has ``idle_cores`` of idle CPU over a ``period_s`` (from
    /proc/stat), or ``ready(period_s)`` says there is work, or after ``limit_s``.

    Where /proc/stat cannot be read (not Linux) it returns at once."""

    def idle_total() -> tuple[float, float]:
        with open("/proc/stat") as fh:
            v = [float(x) for x in fh.readline().split()[1:]]
        return v[3] + v[4], sum(v[:8])  # idle + iowait; user .. steal

    try:
        last = idle_total()
    except (OSError, ValueError, IndexError):
        return
    n_cpu = os.cpu_count() or 1
    t_end = time.monotonic() + limit_s
    while time.monotonic() < t_end:
        if ready(period_s):
            return
        try:
            now = idle_total()
        except (OSError, ValueError, IndexError):
            return
        d_idle, d_total = now[0] - last[0], now[1] - last[1]
        last = now
        if d_total > 0 and d_idle / d_total * n_cpu >= idle_cores:
            return
