"""Taguchi signal-to-noise ratios (dB, larger is always better)."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.taguchi._common import as_responses

__all__ = [
    "sn_kind",
    "sn_ratio",
]

_KIND_ALIASES = {
    "smaller": "smaller",
    "smaller-the-better": "smaller",
    "stb": "smaller",
    "larger": "larger",
    "larger-the-better": "larger",
    "ltb": "larger",
    "nominal": "nominal",
    "nominal-the-best": "nominal",
    "ntb": "nominal",
    "nominal-variance": "nominal-variance",
    "nominal-the-best-variance": "nominal-variance",
}


def sn_kind(kind: str) -> str:
    """The canonical S/N kind (``smaller``, ``larger``, ``nominal``, ``nominal-variance``) of
    ``kind`` or one of its aliases (``"smaller-the-better"``, ``"ntb"``, ...)."""
    key = str(kind).strip().lower().replace("_", "-").replace(" ", "-")
    if key not in _KIND_ALIASES:
        raise OptimiseError(
            f"S/N kind {kind!r} is unknown; use 'smaller', 'larger', 'nominal' or "
            "'nominal_variance' (or 'smaller-the-better', 'larger-the-better', 'nominal-the-best')"
        )
    return _KIND_ALIASES[key]


def _sn_smaller(y: np.ndarray, target: float | None) -> np.ndarray:
    return -10.0 * np.log10(np.mean(y**2, axis=1))


def _sn_larger(y: np.ndarray, target: float | None) -> np.ndarray:
    return -10.0 * np.log10(np.mean(1.0 / y**2, axis=1))


def _sn_nominal(y: np.ndarray, target: float | None) -> np.ndarray:
    if target is not None:
        return -10.0 * np.log10(np.mean((y - target) ** 2, axis=1))
    return 10.0 * np.log10(np.mean(y, axis=1) ** 2 / np.var(y, axis=1, ddof=1))


def _sn_nominal_variance(y: np.ndarray, target: float | None) -> np.ndarray:
    return -10.0 * np.log10(np.var(y, axis=1, ddof=1))


_SN: dict[str, Callable[[np.ndarray, float | None], np.ndarray]] = {
    "smaller": _sn_smaller,
    "larger": _sn_larger,
    "nominal": _sn_nominal,
    "nominal-variance": _sn_nominal_variance,
}


def sn_ratio(
    responses: np.ndarray | Sequence[float], kind: str = "smaller", target: float | None = None
) -> np.ndarray:
    """Taguchi signal-to-noise ratio of each run, in dB (larger is always better).

    ============================  ==================================  =========================
    kind                          S/N                                 replicates
    ============================  ==================================  =========================
    ``smaller``                   ``-10 log10(mean(y^2))``            >= 1
    ``larger``                    ``-10 log10(mean(1/y^2))``          >= 1
    ``nominal`` (no target)       ``10 log10(ybar^2 / s^2)``          >= 2 (s^2 with ddof = 1)
    ``nominal`` with ``target``   ``-10 log10(mean((y - target)^2))`` >= 1
    ``nominal_variance``          ``-10 log10(s^2)``                  >= 2
    ============================  ==================================  =========================

    With a single (deterministic, e.g. FE) response per run there is no variance, so
    nominal-the-best needs the target and becomes the mean squared deviation from it.

    Parameters
    ----------
    responses : (runs,) or (runs, replicates) float — measured or computed responses.
    kind : str — see the table; aliases such as ``"smaller-the-better"`` are accepted.
    target : float, optional — the nominal value, for ``kind="nominal"`` only.

    Returns
    -------
    (runs,) float, dB.

    Raises
    ------
    OptimiseError
        Unknown kind; a target with another kind; too few replicates; an S/N that is infinite
        (a zero response for smaller-/larger-the-better, zero variance or an exact hit on the
        target).
    """
    k = sn_kind(kind)
    y = as_responses(responses)
    if target is not None and k != "nominal":
        raise OptimiseError(
            f"target = {target} is only used by kind='nominal'; drop it or use kind='nominal'"
        )
    if target is not None and not np.isfinite(target):
        raise OptimiseError(f"target = {target} must be a finite number")
    if k in ("nominal", "nominal-variance") and target is None and y.shape[1] < 2:
        raise OptimiseError(
            f"kind={kind!r} needs >= 2 replicates per run to estimate the variance, got one "
            "response per run; give a target (kind='nominal', target=...) to use "
            "-10 log10((y - target)^2), or replicate the runs"
        )
    with np.errstate(divide="ignore", invalid="ignore"):
        sn = _SN[k](y, target)
    bad = np.flatnonzero(~np.isfinite(sn))
    if bad.size:
        r = int(bad[0])
        raise OptimiseError(
            f"the {k} S/N of run {r} is {sn[r]} (responses {y[r].tolist()}): a zero response, "
            "zero variance or an exact hit on the target gives an infinite ratio; add a small "
            "floor to the response (e.g. the FE tolerance) or pick another kind"
        )
    return sn
