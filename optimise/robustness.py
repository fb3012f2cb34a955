r"""Robustness of a design to manufacturing scatter: samples, shares and bands.

A printed or cut part is not the nominal design: printed E varies 10–30 % from spool to spool
and with the print settings, every printed thickness is off by the printer's tolerance (about
±0.1 mm for FDM), and so is the out-of-plane width. A study's optional ``robustness:`` block
(:class:`RobustnessSpec`) states that scatter; the pipeline evaluates the design at each
*sample* of it, judges every sample against the same requirements as the verdict, and reports
for each requirement the **share** of samples that meet it, and the **band** of the response
(per row, the lowest and highest value of each column over the samples).

A sample is one row ``(E_factor, thickness_delta_mm, width_delta_mm)``: Young's modulus times
``E_factor`` (1.1 = +10 %), every thickness plus ``thickness_delta_mm`` and the width plus
``width_delta_mm`` (mm). Row 0 is always the nominal design ``(1, 0, 0)``.

API
---
:func:`corner_samples`
    The nominal, then every combination of the ± extremes of the k scatters that are not zero:
    ``2**k + 1`` rows.
:func:`monte_carlo_samples`
    The nominal, then ``n`` rows drawn uniformly within the ± band, reproducible by ``seed``.
:func:`share_met`, :func:`met_robustly`
    The share (percent) of samples meeting each requirement, and whether that reaches
    ``share_percent``.
:func:`response_band`
    Per-row min and max of each numeric column over the samples' response tables.

Everything here takes values and returns values; how a sample changes a design, and running the
samples, is the pipeline's business (:mod:`pipeline.robustness`).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
from flexopt.optimise.errors import OptimiseError
from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = [
    "SAMPLE_COLUMNS",
    "RobustnessSpec",
    "corner_samples",
    "met_robustly",
    "monte_carlo_samples",
    "response_band",
    "samples_of",
    "share_met",
]

#: The columns of a sample matrix, in order (units in the names; E is a factor).
SAMPLE_COLUMNS = ("E_factor", "thickness_delta_mm", "width_delta_mm")

#: Most samples of a Monte Carlo run: each one is a full nonlinear solve of the design.
MAX_SAMPLES = 10_000


def _amplitudes(E_percent: float, thickness_mm: float, width_mm: float) -> np.ndarray:
    """(3,) half-widths of the scatter in the sample columns' units (E as a fraction)."""
    amp = np.array([E_percent / 100.0, thickness_mm, width_mm], dtype=float)
    if not np.all(np.isfinite(amp)) or np.any(amp < 0):
        raise OptimiseError(
            f"scatter half-widths must be finite and >= 0, got E_percent={E_percent}, "
            f"thickness_mm={thickness_mm}, width_mm={width_mm}"
        )
    if amp[0] >= 1.0:
        raise OptimiseError(
            f"E_percent = {E_percent:g} would make Young's modulus zero or negative; give less "
            "than 100"
        )
    return amp


def corner_samples(E_percent: float, thickness_mm: float, width_mm: float) -> np.ndarray:
    """The nominal design, then every corner of the scatter box.

    Parameters
    ----------
    E_percent : float, %
        ± scatter of Young's modulus (10: E from 0.9 to 1.1 times nominal).
    thickness_mm, width_mm : float, mm
        ± scatter of every thickness and of the out-of-plane width.

    Returns
    -------
    (2**k + 1, 3) float
        Rows ``(E_factor, thickness_delta_mm, width_delta_mm)``; row 0 is ``(1, 0, 0)``; k is the
        number of scatters that are not zero (a zero scatter adds no corner).
    """
    amp = _amplitudes(E_percent, thickness_mm, width_mm)
    active = np.flatnonzero(amp > 0)
    rows = [np.zeros(3)]
    for signs in itertools.product((-1.0, 1.0), repeat=len(active)):
        row = np.zeros(3)
        row[active] = np.asarray(signs) * amp[active]
        rows.append(row)
    out = np.array(rows)
    out[:, 0] += 1.0  # the E column is a factor
    return out


def monte_carlo_samples(
    E_percent: float, thickness_mm: float, width_mm: float, n: int, seed: int
) -> np.ndarray:
    """The nominal design, then ``n`` samples uniform within the ± band (seeded).

    Returns
    -------
    (n + 1, 3) float
        Rows ``(E_factor, thickness_delta_mm, width_delta_mm)``; row 0 is ``(1, 0, 0)``. The same
        ``seed`` gives the same rows.
    """
    if not (isinstance(n, int | np.integer) and 1 <= n <= MAX_SAMPLES):
        raise OptimiseError(f"samples = {n} must be a whole number in [1, {MAX_SAMPLES}]")
    amp = _amplitudes(E_percent, thickness_mm, width_mm)
    rng = np.random.default_rng(seed)
    draws = rng.uniform(-1.0, 1.0, size=(n, 3)) * amp
    out = np.vstack([np.zeros((1, 3)), draws])
    out[:, 0] += 1.0
    return out


def share_met(met: np.ndarray) -> np.ndarray:
    """Percent of samples meeting each requirement.

    Parameters
    ----------
    met : (n_samples, n_requirements) bool
        ``met[i, j]``: sample i meets requirement j (a sample that could not be evaluated meets
        nothing).

    Returns
    -------
    (n_requirements,) float, %
    """
    met = np.asarray(met, dtype=bool)
    if met.ndim != 2 or met.shape[0] == 0:
        raise OptimiseError(f"met must be (n_samples >= 1, n_requirements), got {met.shape}")
    return 100.0 * met.sum(axis=0) / met.shape[0]


def met_robustly(share_percent: np.ndarray, required_percent: float) -> np.ndarray:
    """(n,) bool: each share reaches ``required_percent`` (a small tolerance absorbs rounding:
    19 of 20 samples is 95 %, not 94.99999)."""
    return np.asarray(share_percent, dtype=float) >= float(required_percent) - 1e-9


def response_band(
    tables: Sequence[Mapping[str, Any] | None],
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per-row min and max of each numeric response column over the samples.

    Rows are matched by index: a response has one row per requested step (at k·max/steps of the
    driven quantity), the same for every sample. A table that stops early (a solve that did not
    converge to the end) contributes to the rows it has; a row no sample reached is NaN.

    Parameters
    ----------
    tables : sequence of dict of str to (n_rows,) array, or None
        One response table per sample (None for a sample that gave none).

    Returns
    -------
    dict of str to ((n,), (n,)) float
        ``{column: (low, high)}`` for every numeric (not boolean) column that some sample has;
        n is the longest table's length.
    """
    columns: dict[str, list[np.ndarray]] = {}
    for table in tables:
        for name, values in (table or {}).items():
            arr = np.asarray(values)
            if arr.ndim == 1 and arr.dtype.kind in "fiu":
                columns.setdefault(str(name), []).append(arr.astype(float))
    band = {}
    for name, arrays in columns.items():
        n = max(len(a) for a in arrays)
        stack = np.full((len(arrays), n), np.nan)
        for i, a in enumerate(arrays):
            stack[i, : len(a)] = a
        finite = np.isfinite(stack)
        low = np.where(finite, stack, np.inf).min(axis=0)
        high = np.where(finite, stack, -np.inf).max(axis=0)
        none = ~finite.any(axis=0)
        low[none] = np.nan
        high[none] = np.nan
        band[name] = (low, high)
    return band


# --------------------------------------------------------------------------------------------
# The study-file block

_SPEC_CONFIG = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class RobustnessSpec(BaseModel):
    """The optional ``robustness:`` block of a study (every kind).

    Example (YAML)::

        robustness:
          method: corners        # the nominal + every combination of the ± extremes
          E_percent: 10          # ± scatter of Young's modulus, %
          thickness_mm: 0.1      # ± on every thickness, mm (the printer's tolerance)
          width_mm: 0.1          # ± on the out-of-plane width, mm
          share_percent: 95      # MET robustly when at least this share of samples meets it

    ``method: monte_carlo`` draws ``samples`` designs uniformly within the band (``seed``).
    """

    model_config = _SPEC_CONFIG

    method: Literal["corners", "monte_carlo"] = Field(
        "corners",
        description="corners (nominal + every ± combination, 2^k+1 samples) or monte_carlo",
    )
    samples: int | None = Field(
        None, ge=1, le=MAX_SAMPLES, description="monte_carlo: samples drawn besides the nominal"
    )
    seed: int = Field(1, ge=0, description="monte_carlo: random seed (same seed, same samples)")
    E_percent: float = Field(
        0.0, ge=0, lt=100, description="± scatter of Young's modulus, % (printed E: 10-30 %)"
    )
    thickness_mm: float = Field(
        0.0, ge=0, le=10, description="± on every thickness, mm (the printer's tolerance)"
    )
    width_mm: float = Field(0.0, ge=0, le=100, description="± on the out-of-plane width, mm")
    share_percent: float = Field(
        95.0, gt=0, le=100, description="a requirement is MET robustly at this share of samples, %"
    )
    objective: Literal["nominal", "worst"] = Field(
        "nominal",
        description="nominal, or worst: the optimiser scores each design by its worst sample",
    )

    @model_validator(mode="after")
    def _consistent(self) -> RobustnessSpec:
        if self.E_percent == 0 and self.thickness_mm == 0 and self.width_mm == 0:
            raise ValueError(
                "states no scatter; give at least one of E_percent, thickness_mm, width_mm > 0"
            )
        if self.method == "monte_carlo" and self.samples is None:
            raise ValueError("method monte_carlo needs samples: how many designs to draw (e.g. 64)")
        if self.method == "corners" and self.samples is not None:
            raise ValueError(
                "samples goes with method: monte_carlo (corners are 2^k+1 fixed samples); drop "
                "samples or set method: monte_carlo"
            )
        return self

    @property
    def n_samples(self) -> int:
        """Samples evaluated, the nominal included."""
        if self.method == "monte_carlo":
            return int(self.samples or 0) + 1
        k = sum(v > 0 for v in (self.E_percent, self.thickness_mm, self.width_mm))
        return 2**k + 1


def samples_of(spec: RobustnessSpec) -> np.ndarray:
    """(n_samples, 3) the sample rows a ``robustness:`` block asks for (row 0 the nominal)."""
    if spec.method == "monte_carlo":
        return monte_carlo_samples(
            spec.E_percent, spec.thickness_mm, spec.width_mm, int(spec.samples or 0), spec.seed
        )
    return corner_samples(spec.E_percent, spec.thickness_mm, spec.width_mm)
