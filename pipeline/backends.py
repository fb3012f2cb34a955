"""Opening the backend a run asks for: serial, the local process pool, or a Dask cluster.

Kept apart from :mod:`flexopt.pipeline.parallel` (which the Dask backend in
:mod:`flexopt.pipeline.cluster` builds on) so that neither of those two imports the other's
importer: ``parallel`` ← ``cluster`` ← ``backends``, no cycle.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
from typing import Any

from flexopt.optimise.problem import DesignProblem, as_design_problem
from flexopt.pipeline.parallel import (
    BackendError,
    BatchBackend,
    ParallelSettings,
    ProcessPool,
    SerialBackend,
)

__all__ = ["open_backend"]

log = logging.getLogger(__name__)


@contextlib.contextmanager
def open_backend(settings: ParallelSettings, problem: DesignProblem) -> Iterator[BatchBackend]:
    """The backend ``settings`` ask for, released (workers stopped, client closed) on exit.

    Raises
    ------
    BackendError
        When the problem cannot be sent to workers or the cluster cannot be reached.
    """
    backend: Any
    if settings.backend == "dask":
        try:
            from flexopt.pipeline.cluster import (
                DaskBackend,  # distributed is imported only when used
            )
        except ImportError as exc:
            raise BackendError(
                f"the Dask backend needs dask.distributed ({exc}); pip install 'flexopt[dask]'"
            ) from None
        # DaskBackend turns every failure to connect (also MemoryError, a hung peer) into a
        # BackendError within its connect limit: the caller prints one line, nothing is written
        backend = DaskBackend(
            problem, settings.address or "", settings.eval_timeout_s, settings.chunk_size
        )
    elif settings.backend == "processes" and settings.n_workers > 1:
        _warm_up_kernels(problem)
        backend = ProcessPool(
            problem, settings.n_workers, settings.eval_timeout_s, settings.chunk_size
        )
    else:
        backend = SerialBackend(settings.eval_timeout_s)
    try:
        yield backend
    finally:
        backend.close()


def _warm_up_kernels(problem: DesignProblem) -> None:
    """Compile or load the compiled kernels the problem uses once, before the pool forks.

    Forked workers inherit them; otherwise each would compile them on its first design (in a
    fresh install ~14 s CPU each, all at once) or load them from numba's cache. A problem names
    its kernels by :meth:`~optimise.problem.DesignProblem.warm_up` (the constrained-beam kinds
    load the constrained engine's too, ~18 s CPU once per install; the default loads the beam
    kernel, which most kinds use). A failure here is not the run's: the workers then compile or
    fall back on their own.
    """
    try:
        as_design_problem(problem).warm_up()
    except Exception:  # noqa: BLE001 - only an optimisation
        log.debug("kernel warm-up failed", exc_info=True)
