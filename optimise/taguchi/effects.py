"""Main effects, two-way interaction tables and the additivity check of an orthogonal-array
experiment (the data of the main-effects and interaction plots).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.taguchi._common import (
    as_design,
    as_responses,
    factor_columns,
    level_counts,
    level_means,
    read_only,
)

__all__ = [
    "additivity_check",
    "AdditivityCheck",
    "Interaction",
    "interaction",
    "main_effects",
    "MainEffect",
]


@dataclass(frozen=True)
class MainEffect:
    """Level means of one factor (the data of a main-effects plot).

    Attributes
    ----------
    name : str
    column : int — its column in the array.
    sn : (n_levels,) float — mean S/N at each level, dB.
    response : (n_levels,) float — mean response at each level (over runs and replicates).
    """

    name: str
    column: int
    sn: np.ndarray
    response: np.ndarray

    @property
    def n_levels(self) -> int:
        return int(self.sn.size)

    @property
    def delta(self) -> float:
        """Range of the level means of S/N, dB (Taguchi's response-table "delta")."""
        return float(self.sn.max() - self.sn.min())

    @property
    def best_level(self) -> int:
        """Level with the largest mean S/N (the first one on ties)."""
        return int(np.argmax(self.sn))


def main_effects(
    array: np.ndarray,
    sn: np.ndarray | Sequence[float],
    responses: np.ndarray | Sequence[float] | None = None,
    factor_names: Sequence[str] | None = None,
    *,
    columns: Sequence[int] | None = None,
) -> tuple[MainEffect, ...]:
    """Mean S/N and mean response at every level of every factor.

    Parameters
    ----------
    array : (runs, n_columns) int — the design, levels 0..s-1.
    sn : (runs,) float — S/N of each run, dB.
    responses : (runs,) or (runs, replicates) float, optional — defaults to ``sn``.
    factor_names : sequence of str, optional — names of the factors in ``columns`` (or in the
        first ``len(factor_names)`` columns); default A, B, C, ... for every column.
    columns : sequence of int, optional — the column of each factor.
    """
    a = as_design(array)
    s = level_counts(a)
    names, cols = factor_columns(a, factor_names, columns)
    v = as_responses(sn, a.shape[0])
    y = v if responses is None else as_responses(responses, a.shape[0])
    return tuple(
        MainEffect(
            n, c, read_only(level_means(a[:, c], v, s[c])), read_only(level_means(a[:, c], y, s[c]))
        )
        for n, c in zip(names, cols, strict=True)
    )


@dataclass(frozen=True)
class Interaction:
    """Two-way table of means of a pair of factors and its interaction sum of squares.

    Attributes
    ----------
    a, b : str — the factor names.
    table : (n_levels_a, n_levels_b) float — mean value in each level cell.
    counts : (n_levels_a, n_levels_b) int — runs in each cell.
    ss : float — ``SS_cells - SS_a - SS_b``: the part of the cell-mean variation the two main
        effects do not explain.
    dof : int — ``(s_a - 1)(s_b - 1)``.
    percent : float — ``100 ss / SS_total``.
    aliased_columns : tuple of int — other columns not balanced within the cells: their effects are
        inside ``ss`` (in a Rao-Hamming array the interaction columns of the pair).
    """

    a: str
    b: str
    table: np.ndarray
    counts: np.ndarray
    ss: float
    dof: int
    percent: float
    aliased_columns: tuple[int, ...]


def interaction(
    array: np.ndarray,
    values: np.ndarray | Sequence[float],
    a: str,
    b: str,
    factor_names: Sequence[str] | None = None,
    *,
    columns: Sequence[int] | None = None,
) -> Interaction:
    """The two-way table of two factors and the interaction sum of squares it shows.

    In a fractional array the interaction is confounded with the columns the pair determines
    (:attr:`Interaction.aliased_columns`; in L8 the A×B of columns 1 and 2 *is* column 3).  The SS
    is the interaction's only when those columns hold no factor; otherwise it also holds that
    factor's effect.

    Parameters
    ----------
    array : (runs, n_columns) int — the whole array (for the aliasing check), levels 0..s-1.
    values : (runs,) or (runs, replicates) float — S/N or responses.
    a, b : str — factor names.
    factor_names, columns — which columns are factors (see :func:`main_effects`).
    """
    arr = as_design(array)
    s = level_counts(arr)
    names, cols = factor_columns(arr, factor_names, columns)
    for x in (a, b):
        if x not in names:
            raise OptimiseError(f"factor {x!r} is not one of {list(names)}")
    if a == b:
        raise OptimiseError(f"an interaction needs two different factors, got {a!r} twice")
    y = as_responses(values, arr.shape[0])
    n, r = y.shape
    ca, cb = cols[names.index(a)], cols[names.index(b)]
    sa, sb = int(s[ca]), int(s[cb])
    cell = arr[:, ca] * sb + arr[:, cb]
    counts = np.bincount(cell, minlength=sa * sb)
    if np.any(counts != counts[0]):
        raise OptimiseError(
            f"factors '{a}' and '{b}' do not show every level pair equally often (cell counts "
            f"{counts.tolist()}): the two-way table needs an orthogonal pair of columns"
        )
    sums = np.bincount(cell, weights=y.mean(axis=1), minlength=sa * sb)
    table = (sums / counts).reshape(sa, sb)
    grand = float(y.mean())
    ss_total = float(np.sum((y - grand) ** 2))
    ss_cells = r * float(np.sum(counts * (table.ravel() - grand) ** 2))
    ss_a = r * float(
        np.sum(np.bincount(arr[:, ca]) * (level_means(arr[:, ca], y, sa) - grand) ** 2)
    )
    ss_b = r * float(
        np.sum(np.bincount(arr[:, cb]) * (level_means(arr[:, cb], y, sb) - grand) ** 2)
    )
    ss = max(ss_cells - ss_a - ss_b, 0.0)
    aliased = []
    for c in range(arr.shape[1]):
        if c in (ca, cb):
            continue
        joint = np.bincount(cell * s[c] + arr[:, c], minlength=sa * sb * int(s[c]))
        joint = joint.reshape(sa * sb, int(s[c]))
        if np.any(joint != joint[:, :1]):
            aliased.append(c)
    return Interaction(
        a,
        b,
        read_only(table),
        read_only(counts.reshape(sa, sb)),
        ss,
        (sa - 1) * (sb - 1),
        100.0 * ss / ss_total if ss_total > 0 else np.nan,
        tuple(aliased),
    )


@dataclass(frozen=True)
class AdditivityCheck:
    """How far the values are from the additive (main-effects-only) model.

    Attributes
    ----------
    fitted : (runs,) float — ``mean + sum_f (level mean_f - mean)`` at each run.
    residuals : (runs,) float — value minus fitted (run means when replicated).
    ss_residual : float — sum of squared residuals times replicates: the SS left unexplained by
        the main effects (interactions, empty columns, replicate noise).
    dof_residual : int — its degrees of freedom (0 for a saturated array: then no interaction
        can show here, only in ``extra_*``).
    ss_total : float
    unexplained_percent : float — ``100 ss_residual / ss_total``.
    pairs : tuple of Interaction — every pair of factors, largest interaction SS first.
    extra_predicted, extra_measured, extra_residuals : (m,) float — additive prediction, measured
        value and measured minus predicted at extra level combinations (e.g. confirmation runs).
    notes : tuple of str
    """

    fitted: np.ndarray
    residuals: np.ndarray
    ss_residual: float
    dof_residual: int
    ss_total: float
    unexplained_percent: float
    pairs: tuple[Interaction, ...]
    extra_predicted: np.ndarray
    extra_measured: np.ndarray
    extra_residuals: np.ndarray
    notes: tuple[str, ...] = ()


def additivity_check(
    array: np.ndarray,
    values: np.ndarray | Sequence[float],
    factor_names: Sequence[str] | None = None,
    *,
    columns: Sequence[int] | None = None,
    extra_levels: np.ndarray | Sequence[Sequence[int]] | None = None,
    extra_values: np.ndarray | Sequence[float] | None = None,
) -> AdditivityCheck:
    """Quantify non-additivity: residuals of the main-effects model and the pair interactions.

    Taguchi's prediction assumes the factor effects add up.  When they do not (the SEA-spring
    screening of paper 004 predicted 29.6 dB and measured 22.2 dB), this shows where: the residual
    SS over the array runs, the two-way interaction SS of every pair and, at level combinations not
    in the array, the gap between the additive prediction and the measured value.

    Parameters
    ----------
    array : (runs, n_columns) int — the design, levels 0..s-1.
    values : (runs,) or (runs, replicates) float — S/N or responses.
    factor_names, columns — which columns are factors (see :func:`main_effects`).
    extra_levels : (m, n_factors) int, optional — level of each factor in extra runs.
    extra_values : (m,) float, optional — the value measured in each extra run.

    Returns
    -------
    AdditivityCheck
    """
    a = as_design(array)
    s = level_counts(a)
    names, cols = factor_columns(a, factor_names, columns)
    y = as_responses(values, a.shape[0])
    n, r = y.shape
    grand = float(y.mean())
    means = [level_means(a[:, c], y, s[c]) for c in cols]
    fitted = grand + sum(m[a[:, c]] - grand for m, c in zip(means, cols, strict=True))
    resid = y.mean(axis=1) - fitted
    ss_total = float(np.sum((y - grand) ** 2))
    ss_res = float(r * np.sum(resid**2) + np.sum((y - y.mean(axis=1, keepdims=True)) ** 2))
    dof_res = n * r - 1 - sum(int(s[c]) - 1 for c in cols)
    notes = []
    if dof_res == 0:
        notes.append(
            "the main effects use every degree of freedom (saturated array, one value per run): "
            "the residuals are zero by construction and interactions are aliased with the factor "
            "columns; check additivity with extra runs (extra_levels, extra_values) instead"
        )
    pairs = tuple(
        sorted(
            (
                interaction(a, y, fa, fb, factor_names=names, columns=cols)
                for fa, fb in combinations(names, 2)
            ),
            key=lambda it: -it.ss,
        )
    )
    if (extra_levels is None) != (extra_values is None):
        raise OptimiseError("give both extra_levels and extra_values, or neither")
    if extra_levels is not None:
        lv = np.atleast_2d(np.asarray(extra_levels, dtype=int))
        mv = np.asarray(extra_values, dtype=float).ravel()
        if lv.shape != (mv.size, len(cols)):
            raise OptimiseError(
                f"extra_levels has shape {lv.shape}; expected ({mv.size}, {len(cols)}): one row of "
                "factor levels per extra value"
            )
        pred = np.array([_additive(grand, means, row) for row in lv])
    else:
        mv = np.zeros(0)
        pred = np.zeros(0)
    return AdditivityCheck(
        fitted=read_only(fitted),
        residuals=read_only(resid),
        ss_residual=ss_res,
        dof_residual=dof_res,
        ss_total=ss_total,
        unexplained_percent=100.0 * ss_res / ss_total if ss_total > 0 else np.nan,
        pairs=pairs,
        extra_predicted=read_only(pred),
        extra_measured=read_only(mv),
        extra_residuals=read_only(mv - pred),
        notes=tuple(notes),
    )


def _additive(grand: float, means: Sequence[np.ndarray], levels: Sequence[int]) -> float:
    out = grand
    for m, lv in zip(means, levels, strict=True):
        if not 0 <= lv < m.size:
            raise OptimiseError(f"level {lv} is outside 0..{m.size - 1}")
        out += float(m[lv]) - grand
    return out
