"""The constant-force paths this process solved last, for an exact Jacobian asked at one of them
(issue 27: the hybrid's gradient stage evaluates a trial design, then asks for the Jacobian at
the design it accepted; when the same process, the run's or a pool worker, evaluated it, the
Jacobian starts from that solve instead of solving the path again, ~8 ms CPU of ~100).

A memo of the last :data:`KEEP` successful solves, keyed by the exact bytes of the design vector
and held to the problem's class and study object (a subclass may build its beam otherwise, e.g.
the tests' tighter rtol; another study is another problem). What is kept is what
:meth:`ConstantForceProblem._solve` made: the design, the :class:`fea.beam.BeamModel` and the
solved path with the study's stress (``_constant_force_fillet.with_root_stress``), exactly what
:func:`._constant_force_gradient.study_sensitivities` builds and solves the same way, so the
Jacobian is the same bit for bit (tests/pipeline/test_constant_force_gradient.py checks it). A
worker keeps its own; nothing here is pickled with the problem. Light on purpose: imported with
the kind at start-up.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Any

import numpy as np

__all__ = ["KEEP", "clear", "kept", "keep"]

#: solves kept per process: the two starts' trial designs of a round and their Jacobians' designs
KEEP = 4

_lock = threading.Lock()  # the run's process solves in a thread too (the report's warm-up)
_kept: OrderedDict[bytes, tuple[Any, ...]] = OrderedDict()


def keep(problem: Any, x: np.ndarray, design: Any, model: Any, response: Any) -> tuple:
    """Keep a converged solve of ``x`` (23,) by ``problem`` (``design``, its ``model`` and
    ``response`` with the study's stress); returns ``(design, response, "")``, what
    :meth:`ConstantForceProblem._solve` returns for it."""
    key = np.asarray(x, dtype=float).tobytes()
    with _lock:
        _kept[key] = (type(problem), problem.study, design, model, response)
        _kept.move_to_end(key)
        while len(_kept) > KEEP:
            _kept.popitem(last=False)
    return design, response, ""


def kept(problem: Any, x: np.ndarray) -> tuple[Any, Any, Any] | None:
    """``(design, model, response)`` of the kept solve of ``x`` (23,) by a problem of
    ``problem``'s class and study, or None."""
    key = np.asarray(x, dtype=float).tobytes()
    with _lock:
        entry = _kept.get(key)
    if entry is None or entry[0] is not type(problem) or entry[1] is not problem.study:
        return None
    return entry[2], entry[3], entry[4]


def clear() -> None:
    """Forget every kept solve (the tests and benchmarks that time a Jacobian's own solve)."""
    with _lock:
        _kept.clear()
