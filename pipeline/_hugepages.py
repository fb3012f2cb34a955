"""numpy's transparent-huge-page requests, off while a large model is built.

On Linux numpy asks the kernel for transparent huge pages (``madvise(MADV_HUGEPAGE)``) for every
array of 4 MB or more. Where the kernel's THP ``defrag`` setting is ``madvise`` (the default of
many distributions, and of the 2-core machine the benchmarks run on), each huge-page fault of such
an array compacts memory synchronously first. Measured there: a fresh 800 MB array filled in
9.5 s with the requests and 0.54 s without; the SEA spring's 3D model (408k DOFs) built in 20 s
and 6.6 s. Small arrays are unaffected, and no result changes (only where the pages come from).

``NUMPY_MADVISE_HUGEPAGE=0`` in the environment before numpy is imported does the same for a
whole process; :func:`without_numpy_hugepages` does it for a block of code and restores the
setting after.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

__all__ = ["without_numpy_hugepages", "no_numpy_hugepages"]

F = TypeVar("F", bound=Callable[..., Any])


def _setter() -> Callable[[bool], bool] | None:
    try:  # numpy >= 2
        from numpy._core.multiarray import _set_madvise_hugepage
    except ImportError:
        try:
            from numpy.core.multiarray import _set_madvise_hugepage  # type: ignore[no-redef]
        except ImportError:  # not on this numpy: nothing to switch
            return None
    return _set_madvise_hugepage


@contextmanager
def without_numpy_hugepages() -> Iterator[None]:
    """numpy requests no huge pages inside the block (child processes forked in it neither)."""
    setter = _setter()
    if setter is None:
        yield
        return
    old = bool(setter(False))  # returns the previous setting
    try:
        yield
    finally:
        setter(old)


def no_numpy_hugepages(func: F) -> F:
    """Decorator: ``func`` runs :func:`without_numpy_hugepages`."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with without_numpy_hugepages():
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
