"""Evaluating designs: one function, one cache (:class:`Evaluator`)."""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, MutableMapping, Sequence

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.hook_call import HookAnswer, call_hook
from flexopt.optimise.problem import DesignProblem
from flexopt.pipeline.checkpoint import EvaluationStore
from flexopt.pipeline.parallel import BatchBackend, design_key, evaluate_batch

log = logging.getLogger(__name__)

# --------------------------------------------------------------------------------------------
# Evaluating designs: one function, one cache


class Evaluator:
    """Evaluates batches of designs through a backend; a design is never solved twice.

    Parameters
    ----------
    problem : DesignProblem
    backend : BatchBackend
        How designs not in the cache are solved (default :func:`evaluate_batch`, serial).
    cache : mutable mapping of bytes to Evaluation, optional
        Evaluations by :func:`design_key`; give a persistent mapping to share it between runs.
    on_result : callable, optional
        Called once per design the backend finishes.
    store : EvaluationStore, optional
        Every design the backend finishes is appended here at once (fsynced by
        :meth:`RunState.generation_done` before the generation is reported, and by the store's
        own interval).
    restored : iterable of Evaluation, optional
        Evaluations finished by an earlier session of this run (``--resume``): served instead of
        solved, and counted as that session counted them, so the replayed run's tables are those
        of an uninterrupted run.

    Attributes
    ----------
    solved : list of Evaluation
        Every design evaluated for this run, restored ones included, in the order the optimiser
        first asked for them (whatever order the backend finished them in).
    n_cache_hits : int
        Designs served from the cache (repeats across generations and within a batch).
    n_restored : int
        Designs served from ``restored``.
    n_backend : int
        Designs the backend solved in this session.
    """

    def __init__(
        self,
        problem: DesignProblem,
        backend: BatchBackend = evaluate_batch,
        cache: MutableMapping[bytes, Evaluation] | None = None,
        on_result: Callable[[], None] | None = None,
        store: EvaluationStore | None = None,
        restored: Iterable[Evaluation] = (),
    ) -> None:
        self.problem = problem
        self.backend = backend
        self.cache: MutableMapping[bytes, Evaluation] = {} if cache is None else cache
        self.on_result = on_result
        self.store = store
        self.restored = {design_key(ev.x): ev for ev in restored}
        self.solved: list[Evaluation] = []
        self.n_cache_hits = 0
        self.n_restored = 0
        self.n_backend = 0
        self.calls_here = False  # the hook calls' place logged (map_calls)

    def map(self, X: np.ndarray) -> list[Evaluation]:
        """Evaluate (m, n_var) designs; returns m Evaluations in order."""
        return self.map_calls(X, ())[0]

    def map_calls(
        self, X: np.ndarray, calls: Sequence[tuple[str, np.ndarray]]
    ) -> tuple[list[Evaluation], list[HookAnswer]]:
        """Evaluate (m, n_var) designs as :meth:`map` does and answer the problem's hook
        ``calls`` ((kind, x (n_var,)): the hybrid's Jacobians and checks,
        :data:`optimise.hook_call.HOOKS`) as one batch: on a process pool's workers beside the
        designs (:meth:`pipeline.parallel.ProcessPool.run`), else in this process after them
        (serial; Dask, whose backend sends designs only). Returns (m Evaluations, one
        :class:`~optimise.hook_call.HookAnswer` per call), in order. A call is not an
        evaluation: nothing cached, stored or counted."""
        X = np.atleast_2d(np.asarray(X, dtype=float)) if len(X) else np.zeros((0, 0))
        pool = getattr(self.backend, "run", None) if calls else None
        if calls and pool is None and not self.calls_here:
            self.calls_here = True
            log.info(
                "the hybrid's Jacobians and checks run in this process: the %s backend is sent "
                "designs only",
                type(self.backend).__name__,
            )
        keys = [design_key(x) for x in X]
        new: dict[bytes, int] = {}  # first appearance in this batch -> its row
        for row, key in enumerate(keys):
            if key not in self.cache and key not in new:
                new[key] = row
        self.n_cache_hits += len(keys) - len(new)
        todo = [key for key in new if key not in self.restored]
        for key in new:
            if key in self.restored:
                self.cache[key] = self.restored.pop(key)
                self.n_restored += 1
        finished: dict[bytes, Evaluation] = {}

        def keep(row: int, evaluation: Evaluation) -> None:
            key = todo[row]
            if key not in finished:  # a backend may report and also return it
                finished[key] = evaluation
                self.cache[key] = evaluation
                self.n_backend += 1
                if self.store is not None:
                    self.store.append(evaluation)
                if self.on_result is not None:
                    self.on_result()

        answers: list[HookAnswer] = []
        try:
            rows = [new[key] for key in todo]
            if pool is not None:
                results, answers = pool(self.problem, X[rows], calls, on_result=keep)
            elif todo:
                results = self.backend(self.problem, X[rows], on_result=keep)
            else:
                results = []
            if len(results) != len(todo) or len(answers) != (len(calls) if pool else 0):
                raise RuntimeError(f"backend: {len(results)} results for {len(todo)} designs")
            for row, evaluation in enumerate(results):
                keep(row, evaluation)
        finally:
            # In the order asked, not the order finished: the same tables on every backend. An
            # interrupted batch keeps what did finish.
            self.solved.extend(self.cache[key] for key in new if key in self.cache)
        if calls and pool is None:
            answers = [call_hook(self.problem, kind, x) for kind, x in calls]
        elif calls:
            self._adopt_checks(calls, answers)
        return [self.cache[key] for key in keys], answers

    def _adopt_checks(
        self, calls: Sequence[tuple[str, np.ndarray]], answers: Sequence[HookAnswer]
    ) -> None:
        """Hand every check a worker made to this process's problem (its ``adopt_check(x,
        check)``, where it has one): the problem keeps what the check computed, and its
        report's detail of the same design serves it instead of solving it again."""
        adopt = getattr(self.problem, "adopt_check", None)
        if adopt is None:
            return
        for (kind, x), answer in zip(calls, answers, strict=True):
            if kind == "check" and getattr(answer.value, "kept", None) is not None:
                adopt(np.asarray(x, dtype=float), answer.value)

    @property
    def calls_in_parallel(self) -> bool:
        """True when :meth:`map_calls` runs hook calls on two or more pool workers at once
        (the hybrid may then take a Jacobian ahead: ``optimise.hybrid.run_hybrid(ahead=)``)."""
        return hasattr(self.backend, "run") and getattr(self.backend, "n_workers", 1) >= 2

    __call__ = map  # run_ga calls the evaluator like a function
