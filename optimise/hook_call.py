"""Calling a problem's derivative and check hooks where a design is evaluated (the hybrid's
gradient stage sends them to the pool's workers beside its designs, :mod:`optimise.hybrid`).

Light on purpose: every worker process imports it (no SciPy, no pymoo).
"""

from __future__ import annotations

import functools
import logging
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["HOOKS", "HookAnswer", "call_hook", "hook_answer"]

log = logging.getLogger(__name__)

#: the hooks a worker may be asked to call, by request kind: the problem's method names
HOOKS = {"jacobian": "jacobian", "check": "check_constraints"}


@dataclass(frozen=True)
class HookAnswer:
    """What one call of a problem's hook gave.

    Attributes
    ----------
    value : the hook's answer (a DesignJacobian, a ConstraintCheck, or None); None when it
        failed.
    error : ``"<ExceptionType>: <message>"`` when the hook raised or the process calling it
        died; empty otherwise.
    time_s : s, wall time of the call where it ran.
    """

    value: Any = None
    error: str = ""
    time_s: float = 0.0


def hook_answer(hook: Any, x: np.ndarray) -> HookAnswer:
    """``hook(x)`` as a :class:`HookAnswer`: an exception becomes ``error`` (an aid's failure
    must not end a run; the caller decides what replaces the answer)."""
    start = time.perf_counter()
    try:
        value = hook(np.array(x, dtype=float))
    except Exception as exc:
        log.debug("hook %r raised at %s", hook, x, exc_info=True)
        text = " ".join(f"{type(exc).__name__}: {exc}".split())
        return HookAnswer(None, text, time.perf_counter() - start)
    return HookAnswer(value, "", time.perf_counter() - start)


def call_hook(problem: Any, kind: str, x: np.ndarray) -> HookAnswer:
    """The problem's hook of request ``kind`` (:data:`HOOKS`) at the design ``x`` (n_var,);
    a problem without it answers None. ``"check:p"`` is part ``p`` (an int) of the check:
    ``check_constraints(x, part=p)`` (a problem whose ``check_parts`` is 2 or more splits its
    check over the pool's workers, :meth:`optimise.hybrid._Stage.serve`)."""
    name, _, part = kind.partition(":")
    hook = getattr(problem, HOOKS[name], None)
    if hook is None:
        return HookAnswer()
    if part:
        return hook_answer(functools.partial(hook, part=int(part)), x)
    return hook_answer(hook, x)
