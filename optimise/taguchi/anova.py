"""Analysis of variance of an orthogonal-array experiment, with Taguchi's pooling rule."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.taguchi._common import (
    as_design,
    as_responses,
    factor_columns,
    interaction_name,
    level_counts,
    level_means,
    read_only,
)
from flexopt.optimise.taguchi.arrays import non_orthogonal_pairs
from flexopt.optimise.taguchi.effects import interaction
from scipy import stats

__all__ = [
    "anova",
    "AnovaTable",
    "Pool",
]


@dataclass(frozen=True)
class Pool:
    """The pooling rule: which factor sums of squares join the error.

    Factors are pooled from the smallest sum of squares upwards, so the pooled set is always the
    ``k`` smallest (plus any named ones):

    1. every factor in ``factors``;
    2. every factor whose contribution ``100 SS / SS_total`` is below ``below_percent``;
    3. then the smallest remaining, one at a time, until the error has ``min_error_dof`` dof.

    At least one factor always stays unpooled.  Taguchi's rule of thumb is to pool about half the
    factor degrees of freedom (``min_error_dof`` ~ half the runs); with a saturated array (no empty
    column, one response per run) the error has 0 dof and pooling is the only way to F and p.

    Attributes
    ----------
    below_percent : float — pool factors contributing less than this, % (0: none).
    min_error_dof : int — pool the smallest until the error has at least this many dof.
    factors : tuple of str — pool these whatever their size.
    """

    below_percent: float = 0.0
    min_error_dof: int = 0
    factors: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not 0.0 <= float(self.below_percent) < 100.0:
            raise OptimiseError(
                f"Pool.below_percent = {self.below_percent} must be in [0, 100), a percentage"
            )
        if int(self.min_error_dof) != self.min_error_dof or self.min_error_dof < 0:
            raise OptimiseError(
                f"Pool.min_error_dof = {self.min_error_dof} must be a non-negative integer"
            )
        object.__setattr__(self, "factors", tuple(str(f) for f in self.factors))


@dataclass(frozen=True)
class AnovaTable:
    """Analysis of variance, one row per source (factors, interactions, then error and total).

    Attributes
    ----------
    source : tuple of str — factor names, ``"A×B"`` interactions, ``"error"``, ``"total"``.
    ss : (n_rows,) float — sums of squares (pooled factors also appear inside ``error``).
    dof : (n_rows,) int — degrees of freedom.
    ms : (n_rows,) float — mean squares ``ss / dof`` (nan for 0 dof).
    f : (n_rows,) float — ``ms / ms_error`` for unpooled sources (nan if pooled or 0 error dof).
    p : (n_rows,) float — ``P(F(dof, dof_error) > f)`` (scipy.stats.f.sf).
    percent : (n_rows,) float — contribution ``100 ss / ss_total``.
    percent_pure : (n_rows,) float — Taguchi's pure contribution
        ``100 (ss - dof ms_error) / ss_total`` for unpooled sources, the remainder on the error
        row (nan with 0 error dof).
    pooled : (n_rows,) bool — the source was pooled into the error.
    analysed : str — ``"sn"`` or ``"response"``.
    notes : tuple of str — what to know before reading F and p.
    """

    source: tuple[str, ...]
    ss: np.ndarray
    dof: np.ndarray
    ms: np.ndarray
    f: np.ndarray
    p: np.ndarray
    percent: np.ndarray
    percent_pure: np.ndarray
    pooled: np.ndarray
    analysed: str = "sn"
    notes: tuple[str, ...] = ()

    def rows(self) -> list[dict[str, float | int | str | bool]]:
        """The table as a list of plain dicts (for reports and YAML/JSON)."""
        return [self.row(s) for s in self.source]

    def row(self, source: str) -> dict[str, float | int | str | bool]:
        """One row by source name."""
        if source not in self.source:
            raise OptimiseError(f"no ANOVA row {source!r}; rows are {list(self.source)}")
        i = self.source.index(source)
        return {
            "source": source,
            "ss": float(self.ss[i]),
            "dof": int(self.dof[i]),
            "ms": float(self.ms[i]),
            "f": float(self.f[i]),
            "p": float(self.p[i]),
            "percent": float(self.percent[i]),
            "percent_pure": float(self.percent_pure[i]),
            "pooled": bool(self.pooled[i]),
        }

    @property
    def error_dof(self) -> int:
        return int(self.dof[self.source.index("error")])

    @property
    def error_ms(self) -> float:
        return float(self.ms[self.source.index("error")])

    @property
    def significant(self) -> tuple[str, ...]:
        """Unpooled factor and interaction sources (the ones a prediction uses)."""
        return tuple(s for s, pl in zip(self.source[:-2], self.pooled[:-2], strict=True) if not pl)


def anova(
    array: np.ndarray,
    values: np.ndarray | Sequence[float],
    factor_names: Sequence[str] | None = None,
    *,
    columns: Sequence[int] | None = None,
    interactions: Sequence[tuple[str, str]] = (),
    pool: Pool | None = None,
    analysed: str = "sn",
) -> AnovaTable:
    """ANOVA of an orthogonal-array experiment, with optional pooling.

    ``SS_total = sum (y - ybar)^2`` over all runs and replicates; a factor at ``s`` levels has
    ``SS = r sum_l n_l (ybar_l - ybar)^2`` with ``n_l`` runs at level ``l`` and ``r`` replicates,
    and ``s - 1`` dof; an interaction ``A×B`` has ``SS = SS_AB-cells - SS_A - SS_B`` and
    ``(s_A - 1)(s_B - 1)`` dof.  The error is what is left: empty columns, the hidden dof of mixed
    arrays (2 in the L18) and replicates; then the pooled factors join it.

    Parameters
    ----------
    array : (runs, n_columns) int — the design, levels 0..s-1; the analysed columns must be
        orthogonal (strength 2), else the sums of squares would not add up.
    values : (runs,) or (runs, replicates) float — S/N (one per run) or raw responses.
    factor_names, columns — which columns are factors (see :func:`main_effects`).
    interactions : sequence of (str, str) — interactions to give rows; their columns must be empty
        (not hold a factor), see :func:`select_array`.
    pool : Pool, optional — the pooling rule; None pools nothing.
    analysed : str — label for the table, ``"sn"`` or ``"response"``.

    Returns
    -------
    AnovaTable
    """
    a = as_design(array)
    s = level_counts(a)
    names, cols = factor_columns(a, factor_names, columns)
    bad = non_orthogonal_pairs(a[:, list(cols)])
    if bad:
        i, j = bad[0]
        raise OptimiseError(
            f"columns {cols[i]} ({names[i]}) and {cols[j]} ({names[j]}) are not orthogonal: "
            "every level pair must occur equally often for the ANOVA sums of squares to add up; "
            "use an array from get_array/select_array with all its runs"
        )
    y = as_responses(values, a.shape[0])
    n, r = y.shape
    grand = float(y.mean())
    ss_total = float(np.sum((y - grand) ** 2))
    dof_total = n * r - 1
    if ss_total <= 0.0:
        raise OptimiseError(
            "every run has the same value: there is no variation to analyse; check that the "
            "responses depend on the factors"
        )
    sources: list[str] = []
    ss: list[float] = []
    dof: list[int] = []
    for name, c in zip(names, cols, strict=True):
        counts = np.bincount(a[:, c], minlength=s[c])
        means = level_means(a[:, c], y, s[c])
        sources.append(name)
        ss.append(float(r * np.sum(counts * (means - grand) ** 2)))
        dof.append(int(s[c]) - 1)
    for fa, fb in interactions:
        for x in (fa, fb):
            if x not in names:
                raise OptimiseError(f"interaction ({fa!r}, {fb!r}) names unknown factor {x!r}")
        ca, cb = cols[names.index(fa)], cols[names.index(fb)]
        table = interaction(a, y, fa, fb, factor_names=names, columns=cols)
        clash = [c for c in table.aliased_columns if c in cols]
        if clash:
            other = names[cols.index(clash[0])]
            raise OptimiseError(
                f"interaction {fa}×{fb} is aliased with factor '{other}' (column {clash[0]}): "
                "its SS would hold that factor's effect; reassign with "
                f"select_array(..., interactions=[({fa!r}, {fb!r})]) or drop the interaction"
            )
        sources.append(interaction_name(fa, fb))
        ss.append(table.ss)
        dof.append((int(s[ca]) - 1) * (int(s[cb]) - 1))
    n_src = len(sources)
    ss_arr = np.array(ss)
    dof_arr = np.array(dof)
    ss_err = ss_total - float(ss_arr.sum())
    dof_err = dof_total - int(dof_arr.sum())
    tol = 1e-9 * ss_total
    if dof_err < 0 or ss_err < -tol:
        raise OptimiseError(
            f"the sources use {int(dof_arr.sum())} dof and SS {ss_arr.sum():.6g} of the "
            f"{dof_total} dof and SS {ss_total:.6g} available: an interaction shares its columns "
            "with a factor (aliased); reassign with select_array(..., interactions=...) or drop it"
        )
    ss_err = max(ss_err, 0.0)
    pooled = np.zeros(n_src, dtype=bool)
    notes: list[str] = []
    if pool is not None:
        for fname in pool.factors:
            if fname not in sources:
                raise OptimiseError(f"Pool.factors names {fname!r}, not a source {sources}")
            pooled[sources.index(fname)] = True
        percent = 100.0 * ss_arr / ss_total
        pooled |= percent < pool.below_percent
        order = [i for i in np.argsort(ss_arr, kind="stable")]
        e_dof = dof_err + int(dof_arr[pooled].sum())
        for i in order:
            if e_dof >= pool.min_error_dof:
                break
            if not pooled[i]:
                pooled[i] = True
                e_dof += int(dof_arr[i])
        if pooled.all():
            keep = int(np.argmax(ss_arr))
            pooled[keep] = False
            notes.append(
                f"the pooling rule would pool every source; '{sources[keep]}' (largest SS) is kept"
            )
        e_dof = dof_err + int(dof_arr[pooled].sum())
        if e_dof < pool.min_error_dof:
            raise OptimiseError(
                f"Pool.min_error_dof = {pool.min_error_dof} cannot be reached: pooling all but "
                f"the largest source leaves {e_dof} error dof; lower min_error_dof or use a "
                "larger array"
            )
    ss_e = ss_err + float(ss_arr[pooled].sum())
    dof_e = dof_err + int(dof_arr[pooled].sum())
    ms_e = ss_e / dof_e if dof_e > 0 else np.nan
    with np.errstate(divide="ignore", invalid="ignore"):
        ms = np.where(dof_arr > 0, ss_arr / np.maximum(dof_arr, 1), np.nan)
        f = np.where(pooled | (dof_e == 0), np.nan, ms / ms_e)
    p = np.where(np.isnan(f), np.nan, stats.f.sf(np.nan_to_num(f, nan=0.0), dof_arr, max(dof_e, 1)))
    if dof_e == 0:
        notes.append(
            "the error has 0 degrees of freedom (saturated array: no empty column, no replicates): "
            "F and p need pooling, e.g. pool=Pool(min_error_dof=2) or Pool(below_percent=5)"
        )
    percent = 100.0 * ss_arr / ss_total
    if dof_e > 0:
        pure = np.where(pooled, np.nan, 100.0 * (ss_arr - dof_arr * ms_e) / ss_total)
        pure_err = 100.0 * (ss_e + int(dof_arr[~pooled].sum()) * ms_e) / ss_total
    else:
        pure = np.full(n_src, np.nan)
        pure_err = np.nan
    out = AnovaTable(
        source=tuple(sources) + ("error", "total"),
        ss=read_only(np.append(ss_arr, [ss_e, ss_total])),
        dof=read_only(np.append(dof_arr, [dof_e, dof_total]).astype(int)),
        ms=read_only(np.append(ms, [ms_e, ss_total / dof_total])),
        f=read_only(np.append(f, [np.nan, np.nan])),
        p=read_only(np.append(p, [np.nan, np.nan])),
        percent=read_only(np.append(percent, [100.0 * ss_e / ss_total, 100.0])),
        percent_pure=read_only(np.append(pure, [pure_err, 100.0])),
        pooled=read_only(np.append(pooled, [False, False])),
        analysed=analysed,
        notes=tuple(notes),
    )
    return out
