"""The whole Taguchi analysis (:func:`analyse`), the additive prediction at a level combination and
the confirmation run's confidence interval.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from itertools import product

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.taguchi._common import (
    as_design,
    as_responses,
    factor_columns,
    interaction_name,
    level_counts,
    read_only,
)
from flexopt.optimise.taguchi.anova import AnovaTable, Pool, anova
from flexopt.optimise.taguchi.effects import (
    AdditivityCheck,
    Interaction,
    MainEffect,
    additivity_check,
    interaction,
    main_effects,
)
from flexopt.optimise.taguchi.sn import sn_kind, sn_ratio
from scipy import stats

__all__ = [
    "analyse",
    "confirm",
    "Confirmation",
    "predict",
    "TaguchiResult",
]


@dataclass(frozen=True)
class TaguchiResult:
    """Result of :func:`analyse`.

    Attributes
    ----------
    array : (runs, n_columns) int — the design as given, levels 0..s-1.
    responses : (runs, replicates) float — as given.
    kind : str — canonical S/N kind (``smaller``, ``larger``, ``nominal``, ``nominal-variance``).
    target : float or None — the nominal target, if any.
    sn : (runs,) float — S/N of every run, dB.
    factor_names : tuple of str
    columns : tuple of int — column of each factor.
    main_effects : tuple of MainEffect — one per factor.
    anova : AnovaTable
    interactions : tuple of (str, str) — interactions with ANOVA rows.
    best_levels : tuple of int — best level of each factor (max predicted S/N), 0-based.
    predicted_sn : float — predicted S/N at ``best_levels`` from the significant sources, dB.
    predicted_response : float — additive prediction of the mean response at ``best_levels``
        from the same factors.
    mean_sn : float — mean S/N over the runs, dB.
    notes : tuple of str
    """

    array: np.ndarray
    responses: np.ndarray
    kind: str
    target: float | None
    sn: np.ndarray
    factor_names: tuple[str, ...]
    columns: tuple[int, ...]
    main_effects: tuple[MainEffect, ...]
    anova: AnovaTable
    interactions: tuple[tuple[str, str], ...]
    best_levels: tuple[int, ...]
    predicted_sn: float
    predicted_response: float
    mean_sn: float
    notes: tuple[str, ...] = ()

    @property
    def significant(self) -> tuple[str, ...]:
        """Sources the prediction uses: the unpooled factors and interactions."""
        return self.anova.significant

    @property
    def best_levels_by_name(self) -> dict[str, int]:
        return dict(zip(self.factor_names, self.best_levels, strict=True))

    def effect(self, name: str) -> MainEffect:
        """The main effect of factor ``name``."""
        for e in self.main_effects:
            if e.name == name:
                return e
        raise OptimiseError(f"no factor {name!r}; factors are {list(self.factor_names)}")

    def predict(
        self,
        levels: Sequence[int] | Mapping[str, int] | None = None,
        sources: Sequence[str] | None = None,
        on: str = "sn",
    ) -> float:
        """Shortcut for :func:`predict` on this result."""
        return predict(self, levels, sources, on=on)

    def interaction(self, a: str, b: str, on: str = "sn") -> Interaction:
        """Two-way table and interaction SS of factors ``a`` and ``b`` (on S/N or response)."""
        v = self.sn if on == "sn" else self.responses
        return interaction(self.array, v, a, b, self.factor_names, columns=self.columns)

    def additivity(
        self,
        extra_levels: np.ndarray | Sequence[Sequence[int]] | None = None,
        extra_sn: np.ndarray | Sequence[float] | None = None,
    ) -> AdditivityCheck:
        """:func:`additivity_check` of the S/N, optionally against measured extra runs."""
        return additivity_check(
            self.array,
            self.sn,
            self.factor_names,
            columns=self.columns,
            extra_levels=extra_levels,
            extra_values=extra_sn,
        )


def _levels_vector(
    result: TaguchiResult, levels: Sequence[int] | Mapping[str, int] | None
) -> tuple[int, ...]:
    if levels is None:
        return result.best_levels
    if isinstance(levels, Mapping):
        unknown = set(levels) - set(result.factor_names)
        if unknown:
            raise OptimiseError(
                f"levels name unknown factors {sorted(unknown)}; factors are "
                f"{list(result.factor_names)}"
            )
        missing = [n for n in result.factor_names if n not in levels]
        if missing:
            raise OptimiseError(f"levels miss factors {missing}: give a level for every factor")
        vec = tuple(int(levels[n]) for n in result.factor_names)
    else:
        vec = tuple(int(v) for v in levels)
        if len(vec) != len(result.factor_names):
            raise OptimiseError(
                f"{len(vec)} levels for {len(result.factor_names)} factors "
                f"{list(result.factor_names)}"
            )
    for name, e, lv in zip(result.factor_names, result.main_effects, vec, strict=True):
        if not 0 <= lv < e.n_levels:
            raise OptimiseError(
                f"level {lv} of factor '{name}' is outside 0..{e.n_levels - 1} (levels are 0-based)"
            )
    return vec


def _predict_raw(
    names: Sequence[str],
    sn_means: Sequence[np.ndarray],
    tables: Mapping[str, tuple[int, int, np.ndarray]],
    grand: float,
    levels: Sequence[int],
    sources: Sequence[str],
) -> float:
    out = grand
    for src in sources:
        if src in tables:
            ia, ib, tab = tables[src]
            ma, mb = sn_means[ia], sn_means[ib]
            out += float(tab[levels[ia], levels[ib]] - ma[levels[ia]] - mb[levels[ib]] + grand)
        else:
            i = list(names).index(src)
            out += float(sn_means[i][levels[i]]) - grand
    return out


def predict(
    result: TaguchiResult,
    levels: Sequence[int] | Mapping[str, int] | None = None,
    sources: Sequence[str] | None = None,
    *,
    on: str = "sn",
) -> float:
    """Additive prediction ``mean + sum (level mean - mean)`` at a level combination.

    Parameters
    ----------
    result : TaguchiResult
    levels : sequence of int or mapping name -> level, optional — 0-based; default the best levels.
    sources : sequence of str, optional — factors (and ``"A×B"`` interactions with an ANOVA row)
        to include; default the significant (unpooled) ones.  An interaction adds
        ``cell mean - level mean_A - level mean_B + mean``.
    on : str — ``"sn"`` (dB) or ``"response"`` (mean response; interactions are not used).

    Returns
    -------
    float
    """
    if on not in ("sn", "response"):
        raise OptimiseError(f"on = {on!r}: predict on 'sn' or 'response'")
    lv = _levels_vector(result, levels)
    srcs = tuple(result.significant if sources is None else sources)
    valid = set(result.factor_names) | {interaction_name(a, b) for a, b in result.interactions}
    for src in srcs:
        if src not in valid:
            raise OptimiseError(
                f"source {src!r} is not a factor or analysed interaction: {sorted(valid)}"
            )
    if on == "response":
        grand = float(result.responses.mean())
        means = [e.response for e in result.main_effects]
        srcs = tuple(x for x in srcs if x in result.factor_names)
        return _predict_raw(result.factor_names, means, {}, grand, lv, srcs)
    return _predict_raw(
        result.factor_names,
        [e.sn for e in result.main_effects],
        _interaction_tables(result),
        result.mean_sn,
        lv,
        srcs,
    )


def _interaction_tables(result: TaguchiResult) -> dict[str, tuple[int, int, np.ndarray]]:
    out = {}
    for a, b in result.interactions:
        it = interaction(result.array, result.sn, a, b, result.factor_names, columns=result.columns)
        out[interaction_name(a, b)] = (
            result.factor_names.index(a),
            result.factor_names.index(b),
            it.table,
        )
    return out


def analyse(
    array: np.ndarray,
    responses: np.ndarray | Sequence[float],
    kind: str = "smaller",
    factor_names: Sequence[str] | None = None,
    pool: Pool | None = None,
    *,
    columns: Sequence[int] | None = None,
    target: float | None = None,
    interactions: Sequence[tuple[str, str]] = (),
    anova_on: str = "sn",
) -> TaguchiResult:
    """Taguchi analysis of an orthogonal-array experiment.

    S/N of every run (:func:`sn_ratio`), main effects, ANOVA with pooling, best levels (max mean
    S/N per factor; jointly over factors tied by a significant interaction) and the predicted S/N
    ``mean + sum over significant sources (level mean - mean)``.

    Parameters
    ----------
    array : (runs, n_columns) int — the design, levels 0..s-1 (e.g. :func:`get_array` or
        :attr:`Layout.array`).
    responses : (runs,) or (runs, replicates) float — one row per run.
    kind : str — S/N kind: ``"smaller"``, ``"larger"``, ``"nominal"``, ``"nominal_variance"``.
    factor_names : sequence of str, optional — names of the factors in ``columns`` (or in the
        first ``len(factor_names)`` columns; the rest are empty and feed the error).  Default
        A, B, C, ... for every column.
    pool : Pool, optional — pooling rule for the ANOVA; None pools nothing (and a saturated array
        then has no F or p, see the notes).
    columns : sequence of int, optional — the column of each factor (``Layout.columns``).
    target : float, optional — nominal value for ``kind="nominal"``.
    interactions : sequence of (str, str) — interactions to give ANOVA rows (their columns must
        be empty).
    anova_on : str — ``"sn"`` (one value per run) or ``"response"`` (all replicates; the
        replicate scatter is then error).

    Returns
    -------
    TaguchiResult
    """
    a = as_design(array)
    level_counts(a)
    y = as_responses(responses, a.shape[0])
    k = sn_kind(kind)
    names, cols = factor_columns(a, factor_names, columns)
    if anova_on not in ("sn", "response"):
        raise OptimiseError(f"anova_on = {anova_on!r}: analyse variance of 'sn' or 'response'")
    sn = sn_ratio(y, k, target)
    effects = main_effects(a, sn, y, names, columns=cols)
    pairs = tuple((str(x), str(z)) for x, z in interactions)
    table = anova(
        a,
        sn if anova_on == "sn" else y,
        names,
        columns=cols,
        interactions=pairs,
        pool=pool,
        analysed=anova_on,
    )
    mean_sn = float(sn.mean())
    stub = TaguchiResult(
        array=read_only(a),
        responses=read_only(y),
        kind=k,
        target=None if target is None else float(target),
        sn=read_only(sn),
        factor_names=names,
        columns=cols,
        main_effects=effects,
        anova=table,
        interactions=pairs,
        best_levels=tuple(e.best_level for e in effects),
        predicted_sn=np.nan,
        predicted_response=np.nan,
        mean_sn=mean_sn,
        notes=table.notes,
    )
    best = _best_levels(stub)
    stub = replace(stub, best_levels=best)
    return replace(
        stub,
        predicted_sn=predict(stub, best),
        predicted_response=predict(stub, best, on="response"),
    )


def _best_levels(result: TaguchiResult) -> tuple[int, ...]:
    """Per-factor argmax of S/N, except jointly over the factors of significant interactions."""
    best = list(e.best_level for e in result.main_effects)
    inter = [(a, b) for a, b in result.interactions if interaction_name(a, b) in result.significant]
    if not inter:
        return tuple(best)
    tied = sorted({result.factor_names.index(x) for ab in inter for x in ab})
    n_combos = math.prod(result.main_effects[i].n_levels for i in tied)
    if n_combos > 200_000:  # > 7 five-level factors tied together: keep the per-factor argmax
        return tuple(best)
    tables = _interaction_tables(result)
    sn_means = [e.sn for e in result.main_effects]
    top, top_val = tuple(best), -np.inf
    for combo in product(*(range(result.main_effects[i].n_levels) for i in tied)):
        trial = list(best)
        for i, lv in zip(tied, combo, strict=True):
            trial[i] = lv
        val = _predict_raw(
            result.factor_names, sn_means, tables, result.mean_sn, trial, result.significant
        )
        if val > top_val + 1e-12:  # first of (numerically) tied maxima
            top, top_val = tuple(trial), val
    return top


@dataclass(frozen=True)
class Confirmation:
    """Predicted against measured S/N of a confirmation run.

    Attributes
    ----------
    levels : tuple of int — the confirmed level combination (0-based).
    predicted_sn, measured_sn : float — dB.
    difference : float — measured minus predicted, dB.
    half_width : float — half-width of the confidence interval of the confirmation,
        ``sqrt(F(1 - alpha; 1, dof_e) V_e (1/n_eff + 1/n_confirm))`` with
        ``n_eff = runs / (1 + sum of the dof of the sources used)``, dB; nan when the S/N ANOVA
        has no error dof or the ANOVA was on the response.
    alpha : float
    """

    levels: tuple[int, ...]
    predicted_sn: float
    measured_sn: float
    difference: float
    half_width: float
    alpha: float

    @property
    def within(self) -> bool:
        """True when the measured S/N lies inside the confidence interval of the prediction."""
        return bool(np.isfinite(self.half_width) and abs(self.difference) <= self.half_width)


def confirm(
    result: TaguchiResult,
    measured_sn: float | None = None,
    levels: Sequence[int] | Mapping[str, int] | None = None,
    *,
    responses: np.ndarray | Sequence[float] | None = None,
    alpha: float = 0.05,
    n_confirm: int = 1,
) -> Confirmation:
    """Compare the predicted S/N with a confirmation run.

    Parameters
    ----------
    result : TaguchiResult
    measured_sn : float, optional — S/N of the confirmation run, dB.
    levels : sequence of int or mapping, optional — its level combination; default the best levels.
    responses : (replicates,) float, optional — the confirmation responses instead of
        ``measured_sn`` (converted with the result's kind and target).
    alpha : float — 1 - confidence level of the interval.
    n_confirm : int — number of confirmation runs averaged into ``measured_sn``.

    Returns
    -------
    Confirmation
    """
    if (measured_sn is None) == (responses is None):
        raise OptimiseError("give the confirmation's measured_sn or its responses (one of them)")
    if not 0.0 < alpha < 1.0:
        raise OptimiseError(f"alpha = {alpha} must be in (0, 1), e.g. 0.05 for 95 % confidence")
    if n_confirm < 1:
        raise OptimiseError(f"n_confirm = {n_confirm} must be >= 1")
    if responses is not None:
        measured = float(
            sn_ratio(np.atleast_2d(np.asarray(responses, float)), result.kind, result.target)[0]
        )
    else:
        measured = float(measured_sn)
        if not np.isfinite(measured):
            raise OptimiseError(f"measured_sn = {measured_sn} must be a finite number of dB")
    lv = _levels_vector(result, levels)
    pred = predict(result, lv)
    tab = result.anova
    half = np.nan
    if tab.analysed == "sn" and tab.error_dof > 0:
        used = sum(int(tab.dof[tab.source.index(s)]) for s in result.significant)
        n_eff = result.sn.size / (1 + used)
        fq = float(stats.f.ppf(1.0 - alpha, 1, tab.error_dof))
        half = math.sqrt(fq * tab.error_ms * (1.0 / n_eff + 1.0 / n_confirm))
    return Confirmation(lv, pred, measured, measured - pred, half, alpha)
