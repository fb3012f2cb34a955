"""The chosen design's sensitivities in the report (issue 27 item 3): d(objective)/d(variable) at
the best design, normalised by the variable's range, as a table in report.md and a bar chart in
report.html.

``normalised_i = d f / d x_i * (upper_i - lower_i)``: the change of the objective across the
whole range of ``x_i`` to first order, comparable between variables of different units. Where
the problem differentiates itself (:meth:`optimise.problem.DesignProblem.jacobian`, e.g. the
constant-force study) the derivatives are its exact ones, at the cost of about one solve and no
design evaluated.

Otherwise :func:`design_sensitivity` can take central differences of ``evaluate`` (step
:data:`FD_STEP` of each range, one-sided at a bound; only when ``2 n_var x`` the best design's
evaluation time is at most :data:`FD_BUDGET_S`), but the run's report does not ask for them:
those ``2 n_var`` designs would be solved in the report's process, outside the run's store
(evaluations.csv), its cache and its workers' isolation of a design that crashes or hangs the
solver, and a run's solve count would no longer be its evaluations plus the best's detail. The
report says so instead.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import DesignProblem
from flexopt.pipeline.fork import limit_loaded_pools

__all__ = [
    "FD_BUDGET_S",
    "FD_STEP",
    "DesignSensitivity",
    "design_sensitivity",
    "known_jacobian",
    "sensitivity_figure",
    "sensitivity_html",
    "sensitivity_markdown",
]

#: central-difference step, as a fraction of each variable's range
FD_STEP = 1e-3
#: the central differences are made only when their estimated time is at most this (s)
FD_BUDGET_S = 2.0


@dataclass(frozen=True)
class DesignSensitivity:
    """The objectives' derivatives at one design.

    Attributes
    ----------
    variables : (n_var,) names; ``objectives`` (n_obj,) names.
    gradient : (n_obj, n_var) d(objective)/d(variable), the objective's unit per the variable's.
    normalised : (n_obj, n_var) ``gradient * (upper - lower)``: the objective's unit.
    method : "exact" (the problem's Jacobian) or "central differences".
    evaluations : designs solved for it (0 for exact).
    """

    variables: tuple[str, ...]
    objectives: tuple[str, ...]
    gradient: np.ndarray
    normalised: np.ndarray
    method: str
    evaluations: int


#: the last result, so report.md and report.html (made in the same process) share one computation
_LAST: dict[str, Any] = {}
#: an exact Jacobian the run already has (:func:`known_jacobian`): (problem, its study, x bytes,
#: the DesignJacobian)
_KNOWN: list[tuple[Any, Any, bytes, Any]] = []


def known_jacobian(problem: DesignProblem, jacobian: Any) -> None:
    """Keep ``problem``'s exact DesignJacobian ``jacobian`` (at ``jacobian.x``), which the run
    already took (the hybrid's gradient stage at its best design, ``HybridResult.jacobian``):
    the report's sensitivities at that design use it instead of computing it again (0.15-0.26
    s for a constant-force design). It is the problem's own hook's answer at that design, taken
    with one BLAS thread as here, so the figures are the same."""
    _KNOWN[:] = [(problem, getattr(problem, "study", None), _x_bytes(jacobian.x), jacobian)]


def _x_bytes(x: Any) -> bytes:
    return np.ascontiguousarray(x, dtype=float).tobytes()


def _known(problem: DesignProblem, x: np.ndarray) -> Any:
    """The kept Jacobian of ``problem`` (or a copy of it with the same class and study, e.g.
    the run's residual-carrying one) at ``x``, or None."""
    for kept, study, key, jacobian in _KNOWN:
        same = kept is problem or (
            type(kept) is type(problem)
            and study is not None
            and study is getattr(problem, "study", None)
        )
        if same and key == _x_bytes(x):
            return jacobian
    return None


def design_sensitivity(
    problem: DesignProblem, best: Evaluation, central_differences: bool = False
) -> DesignSensitivity | str:
    """The sensitivities of ``problem``'s objectives at ``best``, or the reason there are none.

    Without the problem's exact derivatives, and with ``central_differences``, they are central
    differences of ``problem.evaluate`` when those are cheap (priced by ``best.time_s``, the
    time its own evaluation took; unknown: not made)."""
    x = np.asarray(best.x, dtype=float)
    time_s = float(best.time_s) if best.time_s and best.time_s > 0 else None
    key = (id(problem), x.tobytes(), time_s, central_differences)
    if _LAST.get("key") == key and _LAST.get("problem") is problem:
        return _LAST["value"]
    value = _compute(problem, best, x, time_s, central_differences)
    _LAST.update(key=key, problem=problem, value=value)
    return value


def _compute(
    problem: DesignProblem,
    best: Evaluation,
    x: np.ndarray,
    time_s: float | None,
    central_differences: bool,
) -> DesignSensitivity | str:
    space = problem.space
    n_var, n_obj = len(space.names), len(problem.objective_names)
    if n_var == 0:
        return "the study has no design variables"
    if best.reason:
        return f"the best design did not solve ({best.reason})"
    span = np.asarray(space.upper, dtype=float) - np.asarray(space.lower, dtype=float)
    try:
        # one BLAS thread, as the gradient stage takes its Jacobians (pipeline/run/runner.py):
        # the report's figures are then the stage's to the bit
        jac = _known(problem, x)
        if jac is None:
            with limit_loaded_pools():
                jac = problem.jacobian(x)
    except Exception as exc:  # the report is never fatal: fall back, and say so
        jac, why = None, f"its Jacobian raised {type(exc).__name__}: {exc}"
    else:
        why = "the study kind gives no exact derivatives"
    if jac is not None and np.shape(jac.f) == (n_obj, n_var):
        grad = np.asarray(jac.f, dtype=float)
        return DesignSensitivity(
            tuple(space.names), tuple(problem.objective_names), grad, grad * span, "exact", 0
        )
    if not central_differences:
        return (
            f"{why}; central differences ({2 * n_var} designs) are not made for the report (they "
            "would be solved outside the run's store and its workers)"
        )
    cost = None if time_s is None else 2 * n_var * time_s
    if cost is None or cost > FD_BUDGET_S:
        priced = "unknown" if cost is None else f"about {cost:.3g} s"
        return (
            f"{why}, and central differences ({2 * n_var} designs, {priced}) cost more than the "
            f"report allows ({FD_BUDGET_S:g} s)"
        )
    grad = np.full((n_obj, n_var), np.nan)
    lower, upper = np.asarray(space.lower, float), np.asarray(space.upper, float)
    f0 = np.asarray(best.f, dtype=float)
    n = 0
    for i in range(n_var):
        h = FD_STEP * span[i]
        hi, lo = min(x[i] + h, upper[i]), max(x[i] - h, lower[i])  # one-sided at a bound
        values = []
        for v in (hi, lo):
            if v == x[i]:
                values.append(f0)
                continue
            xv = x.copy()
            xv[i] = v
            ev = problem.evaluate(xv)
            n += 1
            values.append(None if ev.reason else np.asarray(ev.f, dtype=float))
        if values[0] is not None and values[1] is not None and hi > lo:
            grad[:, i] = (values[0] - values[1]) / (hi - lo)
    return DesignSensitivity(
        tuple(space.names),
        tuple(problem.objective_names),
        grad,
        grad * span,
        "central differences",
        n,
    )


def _order(s: DesignSensitivity) -> np.ndarray:
    """Variables by the largest |normalised| over the objectives, largest first (NaN last)."""
    size = np.nan_to_num(np.abs(s.normalised), nan=-1.0).max(axis=0)
    return np.argsort(-size, kind="stable")


def _method_text(s: DesignSensitivity) -> str:
    if s.method == "exact":
        return "exact derivatives from the study kind's Jacobian (no design solved for them)"
    return (
        f"central differences of the objective, step {FD_STEP:g} of each range (one-sided at a "
        f"bound): {s.evaluations} designs solved for the report only, not in evaluations.csv"
    )


def sensitivity_markdown(problem: DesignProblem, best: Evaluation) -> list[str]:
    """report.md's section: a table of d f / d x_i and d f / d x_i x (upper_i - lower_i)."""
    s = design_sensitivity(problem, best)
    lines = ["## Sensitivity of the best design", ""]
    if isinstance(s, str):
        return [*lines, f"Not computed: {s}.", ""]
    lines += [
        "d(objective)/d(variable) at the best design, and times the variable's range (upper − "
        "lower): the objective's change across the range to first order, comparable between "
        f"variables. By {_method_text(s)}. Largest first.",
        "",
    ]
    header = ["variable"]
    for name in s.objectives:
        header += [f"d `{name}` / d x", f"× range ({name})"]
    lines.append("| " + " | ".join(header) + " |")
    lines.append("|" + "---|" * len(header))
    for i in _order(s):
        row = [f"`{s.variables[i]}`"]
        for j in range(len(s.objectives)):
            row += [f"{s.gradient[j, i]:.6g}", f"{s.normalised[j, i]:.6g}"]
        lines.append("| " + " | ".join(row) + " |")
    return [*lines, ""]


def sensitivity_figure(s: DesignSensitivity) -> Any:
    """report.html's plotly bar chart of the normalised derivatives (one trace per objective)."""
    from flexopt.pipeline import figure_json as fj

    order = _order(s)
    fig = fj.Figure()
    for j, name in enumerate(s.objectives):
        fig.add_trace(
            fj.Bar(
                x=[s.variables[i] for i in order],
                y=[None if np.isnan(v) else float(v) for v in s.normalised[j, order]],
                name=name,
            )
        )
    fig.update_layout(
        title={
            "text": f"d(objective)/d(variable) × (upper − lower) at the best design ({s.method})"
        },
        xaxis={"title": {"text": "design variable"}},
        yaxis={"title": {"text": "change of the objective across the range (first order)"}},
        barmode="group",
        height=420,
    )
    return fig


def sensitivity_html(problem: DesignProblem, best: Evaluation, embed: Any) -> str:
    """report.html's part: the bar chart (``embed(fig, name)`` puts it on the page) or why not."""
    s = design_sensitivity(problem, best)
    if isinstance(s, str):
        return f"<p class='note'>Gradient at the best design not computed: {_html(s)}.</p>"
    return (
        "<p class='note'>Gradient at the best design, times each variable's range (upper − "
        f"lower), by {_html(_method_text(s))}; the table is in report.md.</p>"
        + embed(sensitivity_figure(s), "gradient")
    )


def _html(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
