"""The result of evaluating one design: plain data an optimiser and a run folder both use."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Evaluation", "INFEASIBLE_VALUE"]

#: objective and constraint value given to a design that could not be evaluated: finite (pymoo
#: ranks by it) and larger than any real value, so every evaluated design beats it
INFEASIBLE_VALUE = 1.0e12


@dataclass(frozen=True)
class Evaluation:
    """One evaluated design.

    Attributes
    ----------
    x : (n_var,) float — the design vector.
    f : (n_obj,) float — objectives, minimised.
    g : (n_con,) float — constraints, feasible when every g <= 0.
    metrics : dict — scalar results with units in their names (``mean_force_N``).
    reason : str — empty when the design was built and solved; otherwise why it could not be
        (not printable, failed to build, did not converge, raised, timed out).
    time_s : float, s — wall time of the evaluation.
    """

    x: np.ndarray
    f: np.ndarray
    g: np.ndarray
    metrics: dict[str, Any] = field(default_factory=dict)
    reason: str = ""
    time_s: float = 0.0

    @property
    def feasible(self) -> bool:
        return not self.reason and bool(np.all(np.isfinite(self.f))) and bool(np.all(self.g <= 0.0))

    @property
    def violation(self) -> float:
        """Sum of positive constraint values (0 when feasible)."""
        return float(np.sum(np.maximum(self.g, 0.0)))

    @classmethod
    def failed(
        cls,
        x: np.ndarray,
        n_obj: int,
        n_con: int,
        reason: str,
        time_s: float = 0.0,
        metrics: dict[str, Any] | None = None,
    ) -> Evaluation:
        """A design that could not be evaluated: worst objectives and constraints, with a reason."""
        return cls(
            np.asarray(x, dtype=float),
            np.full(n_obj, INFEASIBLE_VALUE),
            np.full(n_con, INFEASIBLE_VALUE),
            dict(metrics or {}),
            reason or "failed",
            time_s,
        )

    def to_record(self, names: tuple[str, ...]) -> dict[str, Any]:
        """Flat dict for a CSV row / JSON: design variables by name, f_i, g_i, metrics, reason."""
        row: dict[str, Any] = {n: float(v) for n, v in zip(names, self.x, strict=True)}
        row.update({f"f{i}": float(v) for i, v in enumerate(self.f)})
        row.update({f"g{i}": float(v) for i, v in enumerate(self.g)})
        row["feasible"] = self.feasible
        row.update(self.metrics)
        row["reason"] = self.reason
        row["time_s"] = self.time_s
        return row
