"""Choosing the array of a screening: the smallest catalogued array that holds the factors, with
the factors assigned to columns and the columns of requested interactions kept free.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.taguchi._common import default_names
from flexopt.optimise.taguchi.arrays import (
    CATALOGUE,
    ArraySpec,
    get_array,
    interaction_columns,
    list_arrays,
)

__all__ = [
    "Layout",
    "select_array",
]


@dataclass(frozen=True)
class Layout:
    """Factors assigned to the columns of an orthogonal array.

    Attributes
    ----------
    array_name : str — canonical name of the array.
    array : (runs, n_columns) int — the whole array, levels 0..s-1.
    factor_names : tuple of str — one per factor.
    columns : tuple of int — the column of each factor (0-based).
    interactions : tuple of (str, str, tuple of int) — requested interactions and the columns
        reserved for them (left empty so their sum of squares is the interaction's).
    """

    array_name: str
    array: np.ndarray
    factor_names: tuple[str, ...]
    columns: tuple[int, ...]
    interactions: tuple[tuple[str, str, tuple[int, ...]], ...] = ()

    @property
    def design(self) -> np.ndarray:
        """(runs, n_factors) int — the level of every factor in every run."""
        return self.array[:, list(self.columns)]

    @property
    def empty_columns(self) -> tuple[int, ...]:
        """Columns holding neither a factor nor a reserved interaction."""
        used = set(self.columns) | {c for *_, cols in self.interactions for c in cols}
        return tuple(c for c in range(self.array.shape[1]) if c not in used)

    @property
    def n_error_dof(self) -> int:
        """Degrees of freedom left for error by one response per run (before pooling)."""
        s = self.array.max(axis=0) + 1
        used = sum(int(s[c]) - 1 for c in self.columns)
        used += sum(
            (int(s[self.columns[self.factor_names.index(a)]]) - 1)
            * (int(s[self.columns[self.factor_names.index(b)]]) - 1)
            for a, b, _ in self.interactions
        )
        return self.array.shape[0] - 1 - used


def _assign_rao_hamming(
    spec: ArraySpec, levels: Sequence[int], pairs: Sequence[tuple[int, int]]
) -> tuple[list[int], list[tuple[int, ...]]] | None:
    """Depth-first assignment of factors to columns keeping requested interactions clean.

    Hard rule: the columns of a requested interaction hold no factor and no other requested
    interaction.  Preference: columns that are not the interaction column of two assigned factors,
    and whose interactions with them do not land on assigned factors (so a 4-factor L8 gets the
    resolution-IV columns 1, 2, 4, 7).
    """
    n_cols = spec.n_columns
    inter = {}

    def cols_of(a: int, b: int) -> tuple[int, ...]:
        key = (min(a, b), max(a, b))
        if key not in inter:
            inter[key] = interaction_columns(spec.name, *key)
        return inter[key]

    chosen: list[int] = []
    budget = [20000]

    def reserved(upto: list[int]) -> list[set[int]]:
        return [set(cols_of(upto[a], upto[b])) for a, b in pairs if a < len(upto) and b < len(upto)]

    def ok(cand: list[int]) -> bool:
        sets = reserved(cand)
        taken = set(cand)
        for i, r in enumerate(sets):
            if r & taken or any(r & o for o in sets[i + 1 :]):
                return False
        return True

    def score(c: int) -> int:
        bad = sum(c in cols_of(x, y) for x, y in combinations(chosen, 2))
        bad += sum(bool(set(cols_of(c, x)) & set(chosen)) for x in chosen)
        return bad

    def dfs(f: int) -> bool:
        if f == len(levels):
            return True
        budget[0] -= 1
        if budget[0] < 0:
            return False
        cands = [c for c in range(n_cols) if c not in chosen and spec.levels[c] == levels[f]]
        for c in sorted(cands, key=lambda c: (score(c), c)):
            chosen.append(c)
            if ok(chosen) and dfs(f + 1):
                return True
            chosen.pop()
        return False

    if not dfs(0):
        return None
    return list(chosen), [cols_of(chosen[a], chosen[b]) for a, b in pairs]


def select_array(
    factor_levels: Sequence[int] | Mapping[str, int],
    interactions: Sequence[tuple[str, str]] = (),
    *,
    min_error_dof: int = 0,
) -> Layout:
    """The smallest catalogued array that holds the factors, with the factors assigned to columns.

    A factor with ``s`` levels goes to a column with ``s`` levels (no dummy levels or merged
    columns).  In Rao-Hamming arrays the columns of each requested interaction are kept free of
    factors (the linear graph, computed); other arrays accept no interactions.

    Parameters
    ----------
    factor_levels : sequence of int, or mapping name -> int — levels of each factor; a sequence
        names them A, B, C, ...
    interactions : sequence of (str, str) — pairs of factor names whose interaction is to be
        estimated.
    min_error_dof : int — degrees of freedom to leave for error in empty columns (0: saturated
        arrays allowed; the ANOVA then needs pooling).

    Returns
    -------
    Layout

    Raises
    ------
    OptimiseError
        No catalogued array fits; the message lists the largest ones.
    """
    if isinstance(factor_levels, Mapping):
        names = tuple(str(n) for n in factor_levels)
        levels = [int(v) for v in factor_levels.values()]
    else:
        levels = [int(v) for v in factor_levels]
        names = default_names(len(levels))
    if not levels:
        raise OptimiseError("select_array needs at least one factor")
    for n, s in zip(names, levels, strict=True):
        if s < 2:
            raise OptimiseError(f"factor '{n}' has {s} levels; a factor needs at least 2")
    pairs = []
    for a, b in interactions:
        for x in (a, b):
            if x not in names:
                raise OptimiseError(f"interaction ({a!r}, {b!r}) names unknown factor {x!r}")
        if a == b:
            raise OptimiseError(f"interaction ({a!r}, {b!r}) needs two different factors")
        pairs.append((names.index(a), names.index(b)))
    need = sum(s - 1 for s in levels) + sum((levels[a] - 1) * (levels[b] - 1) for a, b in pairs)
    for spec in CATALOGUE:
        if spec.runs - 1 - need < min_error_dof:
            continue
        if any(spec.levels.count(s) < levels.count(s) for s in set(levels)):
            continue
        if spec.construction == "rao_hamming":
            found = _assign_rao_hamming(spec, levels, pairs)
            if found is None:
                continue
            cols, icols = found
        else:
            if pairs:
                continue
            free = list(range(spec.n_columns))
            cols = []
            for s in levels:
                c = next(c for c in free if spec.levels[c] == s)
                free.remove(c)
                cols.append(c)
            icols = []
        return Layout(
            spec.name,
            get_array(spec.name),
            names,
            tuple(cols),
            tuple((names[a], names[b], ic) for (a, b), ic in zip(pairs, icols, strict=True)),
        )
    raise OptimiseError(
        f"no catalogued array holds factors with levels {levels}"
        + (f" and interactions {list(interactions)}" if pairs else "")
        + (f" leaving {min_error_dof} error dof" if min_error_dof else "")
        + f"; the largest are {', '.join(list_arrays()[-4:])}. Split the screening, drop factors, "
        "or give all factors the same number of levels"
    )
