"""Design spaces: named, bounded, continuous design variables."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from flexopt.optimise.errors import OptimiseError

__all__ = ["DesignSpace"]


@dataclass(frozen=True)
class DesignSpace:
    """Box-bounded continuous design variables.

    A space without variables (``names=()``) is the one design a study fixes (a ``mechanism``
    study without ``variables:``): ``flexopt evaluate`` solves it, ``flexopt run`` refuses it.

    Attributes
    ----------
    names : tuple of str — one per variable (none: the study's own design only).
    lower, upper : (n_var,) float — bounds in the variables' own units (named by the study).
    """

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray

    def __post_init__(self) -> None:
        names = tuple(self.names)
        lo = np.asarray(self.lower, dtype=float).ravel()
        hi = np.asarray(self.upper, dtype=float).ravel()
        if len(set(names)) != len(names):
            dup = next(n for n in names if names.count(n) > 1)
            raise OptimiseError(f"design variable '{dup}' is given twice")
        if lo.shape != (len(names),) or hi.shape != (len(names),):
            raise OptimiseError(
                f"{len(names)} variables but {lo.size} lower and {hi.size} upper bounds"
            )
        for i, name in enumerate(names):
            if not (np.isfinite(lo[i]) and np.isfinite(hi[i])):
                raise OptimiseError(f"bounds of '{name}' must be finite numbers")
            if lo[i] > hi[i]:
                raise OptimiseError(
                    f"lower bound {lo[i]:g} > upper bound {hi[i]:g} for '{name}' "
                    f"(variable {i}); did you swap the bounds?"
                )
            if lo[i] == hi[i]:
                raise OptimiseError(
                    f"'{name}' has equal bounds {lo[i]:g}; fix it in the study instead of "
                    "optimising it, or widen its range"
                )
        lo.setflags(write=False)
        hi.setflags(write=False)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)

    @classmethod
    def from_bounds(cls, bounds: Mapping[str, Sequence[float]]) -> DesignSpace:
        """Build from ``{name: [lower, upper]}`` in insertion order."""
        names = tuple(bounds)
        return cls(
            names,
            np.array([bounds[n][0] for n in names], dtype=float),
            np.array([bounds[n][1] for n in names], dtype=float),
        )

    @property
    def n_var(self) -> int:
        return len(self.names)

    def to_params(self, x: np.ndarray) -> dict[str, float]:
        """``{name: value}`` for a design vector ``x`` (n_var,)."""
        x = np.asarray(x, dtype=float).ravel()
        if x.shape != (self.n_var,):
            raise OptimiseError(f"design vector has {x.size} values, the space {self.n_var}")
        return {n: float(v) for n, v in zip(self.names, x, strict=True)}

    def contains(self, x: np.ndarray) -> bool:
        x = np.asarray(x, dtype=float)
        return bool(np.all(x >= self.lower) and np.all(x <= self.upper))

    def clip(self, x: np.ndarray) -> np.ndarray:
        return np.clip(np.asarray(x, dtype=float), self.lower, self.upper)

    def sample(self, n: int, seed: int) -> np.ndarray:
        """(n, n_var) Latin-hypercube sample, reproducible from ``seed``."""
        rng = np.random.default_rng(seed)
        u = (np.argsort(rng.random((n, self.n_var)), axis=0) + rng.random((n, self.n_var))) / n
        return self.lower + u * (self.upper - self.lower)
