"""Test the source tree: put the repository root first on ``sys.path``.

Plain ``pytest`` does not put the working directory on ``sys.path``, so without this a checkout
that was never installed cannot import its packages (``tests/pipeline``, which has no
``__init__.py``, could even be picked up as a namespace package called ``pipeline``), and one that
was installed with ``pip install .`` would test the installed copy, stale after every edit. The
installed console script is still exercised by tests/pipeline/test_cli_evaluate.py when present.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

if sys.path[:1] != [str(ROOT)]:
    sys.path.insert(0, str(ROOT))

# The recorded results' numerics (tests/reference_numerics.py): set before numpy is imported, so
# the goldens hold to every digit on AVX-512 hosts too; subprocesses inherit them.
_NUMPY_FIRST = "numpy" in sys.modules
sys.path.insert(1, str(ROOT / "tests"))
import reference_numerics  # noqa: E402

reference_numerics.apply()
sys.path.remove(str(ROOT / "tests"))


class SolveLog:
    """Counts solves: one line per call in a file, so that calls in a child forked from the test
    count too (its memory does not come back, its appends to a file do). Worker processes of a
    pool come from a forkserver or spawn and do not have the patch: their solves are not counted
    (a refusal comes before any worker starts; for the rest use ``--workers 1``)."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def record(self, what: str) -> None:
        with open(self.path, "a", encoding="utf-8") as log:  # one short write: whole lines
            log.write(what + "\n")

    @property
    def calls(self) -> list[str]:
        """The solves so far, in order: ``"BeamModel.solve"``, ``"FaultProblem.evaluate"``, …"""
        if not self.path.exists():
            return []
        return self.path.read_text(encoding="utf-8").splitlines()

    @property
    def count(self) -> int:
        return len(self.calls)


#: (module, class, method) of every solve a design's answer goes through: the four FE models'
#: and the test suite's toy kind (tests/pipeline/flexopt_toys.py)
SOLVES = [
    ("flexopt.fea.beam", "BeamModel", "solve"),
    ("flexopt.fea.constrained_beams", "ConstrainedBeams", "solve"),
    ("flexopt.fea.plane_stress", "PlaneStressModel", "solve"),
    ("flexopt.fea.solid3d", "Solid3DModel", "solve"),
    ("flexopt_toys", "FaultProblem", "evaluate"),
    ("flexopt_toys", "FaultProblem", "detail"),
]


@pytest.fixture
def solve_log(tmp_path_factory, monkeypatch) -> SolveLog:
    """Counts the solves a test makes (see ``SOLVES``), to assert on work done instead of wall
    time: a refused input is refused before anything is solved (``solve_log.count == 0``)."""
    import importlib
    from functools import wraps

    log = SolveLog(tmp_path_factory.mktemp("solve_log") / "calls.txt")
    for module_name, class_name, method in SOLVES:
        try:
            cls = getattr(importlib.import_module(module_name), class_name)
        except ImportError:  # flexopt_toys is importable from tests/pipeline only
            continue
        original = getattr(cls, method)

        def counted(*args, __original=original, __name=f"{class_name}.{method}", **kwargs):
            log.record(__name)
            return __original(*args, **kwargs)

        monkeypatch.setattr(cls, method, wraps(original)(counted))
    return log
