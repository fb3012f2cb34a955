"""The ``mechanism`` kind's default optimiser (issue 27 item 2): the hybrid (the GA's global
search, then SLSQP on the kind's exact Jacobian, optimise/hybrid.py) wherever it applies.

A mechanism study whose ``optimiser:`` block does not name a ``method`` runs ``method: hybrid``
when the hybrid can run it: ``algorithm: ga`` (one objective; the kind's default objective when
``objectives:`` is empty is one) and at least one design variable. ``method: ga`` keeps the GA
alone; ``algorithm: nsga2`` (several objectives) stays the GA's. The choice is written into the
study as it is validated, so the resolved study.yaml and run.json say ``method: hybrid``, and
resolving it again gives the same study.

Why the hybrid: on every shipped mechanism example with an optimiser it ends at least as low as
the GA, in fewer evaluations, MET (docs/benchmarks.md, "The mechanism kind's default: the
hybrid", ``benchmarks/hybrid.py``). Where the kind's Jacobian hook answers None (a path solved
again with an imperfection, stops or contact) the hybrid's gradient stage takes forward
differences, evaluated in parallel like a generation.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from flexopt.pipeline.study import OptimiserSpec

__all__ = ["default_method"]


def default_method(
    spec: OptimiserSpec, variables: Sequence[Any], objectives: Sequence[Any]
) -> OptimiserSpec:
    """``spec`` with ``method: hybrid`` where it names no method and the hybrid applies
    (``algorithm: ga``, at most one objective listed, at least one variable), else ``spec``
    unchanged."""
    if spec.method is not None or spec.algorithm != "ga":
        return spec
    if not variables or len(objectives) > 1:
        return spec
    return spec.model_copy(update={"method": "hybrid"})
