"""The constant-force study's plane-stress checks, kept per problem so that the report reuses the
check the hybrid's calibration already made on the best design (issue 27 item 4, fixed costs).

``method: hybrid`` checks each start's best design by the verdict's own figure
(:mod:`._constant_force_calibration`: :func:`constant_force.fidelity_check`, ~1-2 s of CPU); the
run's best design is one of them, and the report's :meth:`ConstantForceProblem.detail` ran the
same check on it again. The check is a deterministic function of the design vector, the strokes
it compares over and the study (its geometry, material, drive and ``fidelity:`` settings: the
same mesh, the same Newton solves), so the record kept from the first call IS the figure the
second would compute. Keyed by all three (the whole study as its JSON); a record that was
skipped (a failure) is not kept, so the report retries it.

The memo lives on the problem (a shallow copy such as :meth:`with_residuals`'s shares it) and is
empty in a pickled copy. Where the hybrid's checks run in a pool's worker, the worker's
:class:`~optimise.hybrid.ConstraintCheck` carries its records (``kept``, :meth:`CheckMemo.
attach`) and the run's process adopts them (:meth:`CheckMemo.adopt`, called through the
problem's ``adopt_check`` by :meth:`pipeline.run.evaluator.Evaluator.map_calls`): the report
serves the figure on every backend that runs the checks in a worker or in the run's process.
"""

from __future__ import annotations

import copy
import dataclasses
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import numpy as np
from flexopt.pipeline.studies._constant_force_split import CHECK_PART

__all__ = ["CheckMemo", "adopt_check"]

#: records kept: the hybrid checks each start's best design (2 starts by default, a few
#: calibration rounds each); the report asks for the run's best, one of the last ones
KEPT = 8


class CheckMemo:
    """The last :data:`KEPT` fidelity records (dicts, :func:`constant_force.fidelity_check`) by
    design and check settings; ``solved`` / ``reused``: how many were computed / served."""

    def __init__(self) -> None:
        self.records: OrderedDict[tuple[Any, ...], dict[str, Any]] = OrderedDict()
        self.solved = 0
        self.reused = 0

    def __getstate__(self) -> dict[str, Any]:
        # a pickled problem (a worker's, a Dask task's) carries no records: they are ~MBs of
        # mesh fields, and the pickle must stay small (tests/pipeline/test_constant_force_study)
        return {"records": OrderedDict(), "solved": 0, "reused": 0}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)

    def record(
        self, problem: Any, x: np.ndarray, args: tuple[Any, ...], compute: Callable[[], dict]
    ) -> dict[str, Any]:
        """The fidelity record of design ``x`` (23,) checked with ``args`` (design, response,
        lo, hi: the strokes compared over, mm) under ``problem.study``: a copy of the kept one,
        else ``compute()`` (kept unless it was skipped)."""
        key = (
            np.asarray(x, dtype=float).tobytes(),
            float(args[2]),
            float(args[3]),
            problem.study.model_dump_json(),  # geometry, material, drive, fidelity: all of it
        )
        if isinstance(CHECK_PART.get(), int):  # one part of a check: not the verdict's record
            return compute()
        kept = self.records.get(key)
        if kept is not None:
            self.reused += 1
            self.records.move_to_end(key)
            return copy.deepcopy(kept)  # the caller may add to it; the kept record stays as made
        result = compute()
        parts = CHECK_PART.get()
        if isinstance(parts, tuple) and all(parts) and "skipped" not in result:
            # merged from parts made in workers: the check's wall is the longest part's too
            result["time_s"] = float(result.get("time_s", 0.0)) + max(
                float(part.get("time_s", 0.0)) for part in parts
            )
        self.solved += 1
        if "skipped" not in result:
            self.records[key] = copy.deepcopy(result)
            while len(self.records) > KEPT:
                self.records.popitem(last=False)
        return result

    def attach(self, x: np.ndarray, check: Any) -> Any:
        """``check`` (a ConstraintCheck or None) carrying, as ``kept``, the records of design
        ``x`` (23,) this memo holds: what a worker's check sends back to the run's process."""
        xb = np.asarray(x, dtype=float).tobytes()
        mine = [(key, rec) for key, rec in self.records.items() if key[0] == xb]
        if check is None or not mine:
            return check
        return dataclasses.replace(check, kept=copy.deepcopy(mine))

    def adopt(self, kept: Any) -> None:
        """Keep the records a worker's check carried (:meth:`attach`), as if made here."""
        for key, rec in kept or ():
            if key not in self.records:
                self.records[key] = copy.deepcopy(rec)
        while len(self.records) > KEPT:
            self.records.popitem(last=False)


def adopt_check(problem: Any, x: np.ndarray, check: Any) -> None:
    """The problem's ``adopt_check`` hook: keep the records a worker's check of ``x`` carried."""
    problem.checks.adopt(getattr(check, "kept", None))
