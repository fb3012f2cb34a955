"""Faults while the report's forked children work (issue 23, class 9): SIGTERM to the process
group, or a parent that gives up (a full disk) and closes the pipe, end the child quietly: no
traceback of its own after the run's one line, and the parent notes a child that died.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from flexopt.pipeline.fork import fork_context

pytestmark = pytest.mark.skipif(
    fork_context() is None or not Path("/proc/self/stat").exists(),
    reason="no fork or no /proc on this platform",
)

PRELUDE = """
import os, signal, sys, time
from flexopt.pipeline import cli
from flexopt.pipeline.fork import ForkedMakes
from flexopt.pipeline.run.step_child import EarlyStep
cli._stop_on_sigterm()  # the CLI's handler, which a forked child inherits

def slow():
    time.sleep(3)
    return b"x"
"""


def _child_run(body: str) -> subprocess.CompletedProcess:
    code = textwrap.dedent(PRELUDE) + textwrap.dedent(body)
    return subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=60,
        start_new_session=True,  # its own process group: killpg reaches only it
    )


def test_sigterm_to_the_group_ends_the_report_child_quietly():
    done = _child_run(
        """
        makes = ForkedMakes([("a.png", slow)])
        time.sleep(0.5)
        try:
            os.killpg(0, signal.SIGTERM)  # a scheduler's stop: parent and child at once
            time.sleep(5)
        except KeyboardInterrupt:
            pass
        print(makes.results(), file=sys.stderr)
        """
    )
    assert "Traceback" not in done.stderr, done.stderr
    assert "the process making it died (signal 15)" in done.stderr


def test_a_parent_that_gives_up_leaves_a_quiet_child():
    # the parent stops listening (its disk is full, it failed): the child's answer meets a
    # closed pipe and it ends without a word
    done = _child_run(
        """
        makes = ForkedMakes([("a.png", lambda: time.sleep(0.5) or b"x" * 10_000_000)])
        makes.conn.close()
        makes.process.join(30)
        print("exit", makes.process.exitcode, file=sys.stderr)
        """
    )
    assert done.stderr.strip() == "exit 0", done.stderr


def test_the_early_step_child_ends_quietly_on_sigterm():
    done = _child_run(
        """
        early = EarlyStep.start()
        time.sleep(0.3)
        os.kill(early.process.pid, signal.SIGTERM)
        early.process.join(10)
        print("exit", early.process.exitcode, file=sys.stderr)
        """
    )
    assert done.stderr.strip() == "exit -15", done.stderr


def test_the_early_step_child_ends_when_its_parent_dies():
    # the parent is killed (no close, no None sent): the child must see the end of its pipe
    # and exit, not wait for a part forever
    done = _child_run(
        """
        early = EarlyStep.start()
        pid = os.fork()
        if pid == 0:  # a watcher outside the parent: does the child end once the parent dies?
            early.conn.close()  # (the watcher's copy of the parent's end)
            time.sleep(1.0)
            for _ in range(300):
                try:  # gone, or a zombie nobody reaps (PID 1 of a container may not)
                    with open(f"/proc/{early.process.pid}/stat") as stat:
                        state = stat.read().rsplit(")", 1)[1].split()[0]
                except OSError:
                    state = "Z"
                if state == "Z":
                    os.write(2, b"the child ended\\n")
                    os._exit(0)
                time.sleep(0.1)
            os.write(2, b"the child still waits\\n")
            os._exit(1)
        time.sleep(0.3)
        os._exit(0)  # dies as if killed: nothing closed
        """
    )
    assert done.stderr.strip() == "the child ended", done.stderr
