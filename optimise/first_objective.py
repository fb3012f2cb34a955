"""A multi-objective problem seen by its first objective alone, for the hybrid optimiser
(``optimiser: {algorithm: nsga2, method: hybrid}``, issue 27 item 2; the ``sea_spring`` kind).

Why the first objective: a run reports, of its feasible designs, the one with the smallest first
objective (:func:`optimise.ga.best_of`, which NSGA-II's run uses too; the SEA spring's peak
stress). Minimising that objective subject to the constraints is the kind's own choice rule as a
one-objective problem, which a gradient method (SLSQP) can solve. The other objectives are not
lost: each evaluation keeps them as metrics (``mass_g`` of the SEA spring is one already), so
the run's tables still carry them; what a hybrid run has no longer is a Pareto front (its report
shows the one-objective history instead of the front).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from flexopt.optimise.design_jacobian import DesignJacobian
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import DesignResult, ProblemWrapper

__all__ = ["FirstObjective"]


class FirstObjective(ProblemWrapper):
    """``inner`` with its first objective only; the others go to each evaluation's metrics
    (under their own names, unless a metric of that name exists already). Picklable.

    The exact Jacobian (:meth:`jacobian`) is the inner one's first row of ``f``; a constraint row
    the inner problem does not differentiate (NaN, e.g. the SEA spring's loaded slot gap) is
    given a zero derivative: the gradient method treats it as locally constant, and a design that
    breaks it is still evaluated, and judged infeasible, like any other.
    """

    def __init__(self, inner: Any, residual: bool = False) -> None:
        super().__init__(inner)
        self.dropped_objectives = tuple(inner.objective_names[1:])
        self.objective_names = tuple(inner.objective_names[:1])
        self.residual = residual

    def with_residuals(self) -> FirstObjective:
        """This problem with the objective as its own one residual, ``residual_1 = f[0]``, so
        that the hybrid's trust-region Gauss-Newton step (:mod:`optimise.hybrid`) minimises it:
        for a positive objective ``f = sqrt(mean(r**2)) = |r|`` holds, and the Gauss-Newton
        model of ``f**2``, ``(f + grad f . d)**2``, in a trust region is a sequential linear
        step on ``f`` whose trust region, elastic constraints and backoff keep the steps on
        buildable, feasible designs (SLSQP's full quasi-Newton steps from the GA's designs left
        the SEA spring's buildable range; docs/sea_spring.md). A design whose objective is not
        positive carries no residual (the step to it is rejected)."""
        return FirstObjective(self.inner, residual=True)

    def _trim(self, ev: Evaluation | None) -> Evaluation | None:
        if ev is None:
            return None
        f = np.asarray(ev.f, dtype=float)
        if f.size == len(self.objective_names) and not self.residual:
            return ev
        metrics = dict(ev.metrics)
        for name, value in zip(self.dropped_objectives, f[1:], strict=False):
            metrics.setdefault(name, float(value))
        if self.residual and not ev.reason and np.isfinite(f[0]) and f[0] > 0.0:
            metrics["residual_1"] = float(f[0])
        return replace(ev, f=f[:1].copy(), metrics=metrics)

    def evaluate(self, x: np.ndarray) -> Evaluation:
        ev = self._trim(self.inner.evaluate(x))
        assert ev is not None
        return ev

    def detail(self, x: np.ndarray) -> DesignResult:
        result = self.inner.detail(x)
        return replace(result, evaluation=self._trim(result.evaluation))

    def jacobian(self, x: np.ndarray) -> DesignJacobian | None:
        jac = self.inner.jacobian(x)
        if jac is None:
            return None
        g = np.asarray(jac.g, dtype=float)
        values = dict(jac.values)
        if "f" in values:
            values["f"] = np.asarray(values["f"], dtype=float)[:1]
        info = dict(jac.info)
        missing = [i for i in range(g.shape[0]) if not np.all(np.isfinite(g[i]))]
        if missing:
            g = np.where(np.isfinite(g), g, 0.0)
            info["zero_rows"] = [self.constraint_names[i] for i in missing]
        f = np.asarray(jac.f, dtype=float)[:1]
        residuals = f.copy() if self.residual else jac.residuals
        if self.residual and "f" in values:
            values["residuals"] = values["f"]
        return replace(jac, f=f, g=g, residuals=residuals, values=values, info=info)
