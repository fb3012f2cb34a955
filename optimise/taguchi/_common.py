"""Checks of the inputs and small helpers shared by the parts of :mod:`optimise.taguchi`.

Designs are ``(runs, columns)`` tables of 0-based levels; responses ``(runs, replicates)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from flexopt.optimise.errors import OptimiseError

__all__ = [
    "as_design",
    "as_responses",
    "default_names",
    "factor_columns",
    "interaction_name",
    "level_counts",
    "level_means",
    "read_only",
]


def as_design(array: np.ndarray | Sequence[Sequence[int]], what: str = "array") -> np.ndarray:
    """``array`` as a (runs >= 2, columns >= 1) int table of 0-based levels; ``what`` names it in
    the refusal (OptimiseError)."""
    a = np.asarray(array)
    if a.ndim != 2 or a.shape[0] < 2 or a.shape[1] < 1:
        raise OptimiseError(
            f"{what} must be a (runs, columns) table of levels with >= 2 runs, got shape {a.shape}"
        )
    if not np.issubdtype(a.dtype, np.integer):
        if not np.all(np.isfinite(a)) or not np.array_equal(a, np.round(a)):
            raise OptimiseError(f"{what} must hold integer levels 0..s-1")
        a = a.astype(int)
    if a.min() < 0:
        r, c = np.argwhere(a < 0)[0]
        raise OptimiseError(
            f"{what}[{r}, {c}] = {a[r, c]}: levels are 0-based (0..s-1); subtract 1 from a "
            "Taguchi table printed with levels 1..s"
        )
    return a.astype(int, copy=False)


def level_counts(a: np.ndarray, what: str = "array") -> np.ndarray:
    """(n_columns,) number of levels per column; every level 0..s-1 must occur."""
    out = a.max(axis=0) + 1
    for c in range(a.shape[1]):
        missing = np.setdiff1d(np.arange(out[c]), a[:, c])
        if missing.size:
            raise OptimiseError(
                f"column {c} of the {what} never takes level {missing[0]} but has levels up to "
                f"{out[c] - 1}: levels must be 0..s-1 with each one used"
            )
    return out


def as_responses(responses: np.ndarray | Sequence[float], n_runs: int | None = None) -> np.ndarray:
    """(runs, replicates) float from (runs,) or (runs, replicates), every value finite and, with
    ``n_runs``, one row per run (else OptimiseError)."""
    y = np.asarray(responses, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2 or y.shape[0] < 1 or y.shape[1] < 1:
        raise OptimiseError(
            f"responses must be (runs,) or (runs, replicates), got shape {np.shape(responses)}"
        )
    if n_runs is not None and y.shape[0] != n_runs:
        raise OptimiseError(
            f"{y.shape[0]} response rows for an array of {n_runs} runs: give one row per run"
        )
    bad = np.argwhere(~np.isfinite(y))
    if bad.size:
        r, c = bad[0]
        raise OptimiseError(
            f"response of run {r} (replicate {c}) is {y[r, c]}: every run needs a finite "
            "response; for a failed design use the worst observed value (or a penalty) so the "
            "array stays balanced"
        )
    return y


def factor_columns(
    a: np.ndarray, factor_names: Sequence[str] | None, columns: Sequence[int] | None
) -> tuple[tuple[str, ...], tuple[int, ...]]:
    """(names, columns) of the factors of design ``a`` (runs, n_columns): the given columns, or
    the first ``len(factor_names)`` (all without names); names default to A, B, C, ..."""
    n_cols = a.shape[1]
    if columns is None:
        n = n_cols if factor_names is None else len(factor_names)
        if n > n_cols:
            raise OptimiseError(
                f"{n} factor names for an array of {n_cols} columns: name at most one factor "
                "per column"
            )
        columns = range(n)
    cols = tuple(int(c) for c in columns)
    for c in cols:
        if not 0 <= c < n_cols:
            raise OptimiseError(f"column {c} is outside the array (0..{n_cols - 1})")
    if len(set(cols)) != len(cols):
        raise OptimiseError(f"columns {list(cols)} repeat a column; one factor per column")
    names = (
        default_names(len(cols)) if factor_names is None else tuple(str(n) for n in factor_names)
    )
    if len(names) != len(cols):
        raise OptimiseError(f"{len(names)} factor names for {len(cols)} columns")
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise OptimiseError(f"factor name {dup!r} is given twice")
    if not cols:
        raise OptimiseError("no factor to analyse: give factor_names or columns")
    return names, cols


def level_means(col: np.ndarray, v: np.ndarray, s: int) -> np.ndarray:
    """Mean of ``v`` (runs, r) over the runs at each level of ``col``."""
    return np.bincount(col, weights=v.mean(axis=1), minlength=s) / np.bincount(col, minlength=s)


def read_only(x: np.ndarray) -> np.ndarray:
    """A read-only copy of ``x`` (the results are frozen dataclasses; so are their arrays)."""
    x = np.array(x)
    x.setflags(write=False)
    return x


def default_names(n: int) -> tuple[str, ...]:
    """Factor names A, B, ..., Z, then F27, F28, ..."""
    return tuple(chr(ord("A") + i) if i < 26 else f"F{i + 1}" for i in range(n))


def interaction_name(a: str, b: str) -> str:
    """The ANOVA source name of the interaction of factors ``a`` and ``b``: ``"A×B"``."""
    return f"{a}×{b}"
