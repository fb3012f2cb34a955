"""The contract between a study kind and the optimisers / the run pipeline.

A :class:`DesignProblem` is built once from a validated study and then called for every design.
It must be picklable (it is sent once to each worker process or Dask worker, not with every
design) and deterministic (the same ``x`` gives the same :class:`~optimise.Evaluation`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.requirements import Verdict
from flexopt.optimise.space import DesignSpace

__all__ = ["CaseResponse", "DesignProblem", "DesignDetail"]


@dataclass(frozen=True)
class CaseResponse:
    """One load case of a design's response, for a kind with several (a mechanism's free and
    blocked jaw); the pipeline shows every case wherever it shows a response
    (:func:`pipeline.responses.case_responses`).

    Attributes
    ----------
    table : dict of str to (n_rows,) array — the case's response columns, units in the names.
    plot : dict — how to plot it, as :attr:`DesignDetail.plot` (``x``, ``y``, ``stress``,
        ``allowable_MPa``, a target band, ``x_label``).
    outputs : tuple of str — the columns the user defined for this case (``advantage``,
        ``jaw_force_N``), each drawn on the axis of its unit.
    """

    table: dict[str, np.ndarray]
    plot: dict[str, Any] = field(default_factory=dict)
    outputs: tuple[str, ...] = ()


@dataclass(frozen=True)
class DesignDetail:
    """Everything a report needs about one design (computed for the best design, not every one).

    Attributes
    ----------
    evaluation : the design's Evaluation.
    table : dict of str to (n_rows,) array — response columns, units in the names
        (``displacement_mm``, ``force_N``, ``peak_stress_MPa``); written as CSV.
    plot : dict — how to plot ``table``: ``x`` and ``y`` column names, optional ``stress``
        column, ``target`` value with ``tolerance`` (absolute, unit of ``y``) or
        ``tolerance_rel`` (band), ``band_x`` (x-range of the band), ``allowable_MPa`` line,
        ``xlabel`` / ``ylabel``.
    shapes_mm : (n_rows, n_nodes, 2) float, mm, optional — deformed centrelines to draw.
    outline : shapely Polygon, optional — the printable outline (mm), extruded by ``height_mm``.
    height_mm : float, optional — extrusion height of the outline (the out-of-plane width).
    info : dict — anything else worth reporting (derived geometry, checks, notes).
    field_map : dict, optional — a scalar field on a triangle mesh to draw (a stress map):
        ``points_mm`` (n, 2) mm, ``triangles`` (m, 3) int, ``values`` (n,), ``label`` (name and
        unit of the values), optional ``limit`` (an allowable in the same unit). Drawn as
        ``stress_map.png``; not written into best.json (it is large).
    files : dict of str to bytes — more files of the kind (``taguchi.png``), by plain file name;
        ``flexopt run`` writes them into the run folder.
    verdicts : tuple of Verdict — the kind's own verdicts on this design; empty (the default)
        lets ``flexopt run`` judge ``evaluation.metrics``, ``info`` and ``table`` against the
        study's requirements (:func:`pipeline.verdict.judge_detail`).
    cases : dict of str to CaseResponse — every load case by name, for a kind with several
        (``table`` and ``plot`` are then the first one's); empty for a kind with one.
    """

    evaluation: Evaluation
    table: dict[str, np.ndarray] = field(default_factory=dict)
    plot: dict[str, Any] = field(default_factory=dict)
    shapes_mm: np.ndarray | None = None
    outline: Any = None
    height_mm: float | None = None
    info: dict[str, Any] = field(default_factory=dict)
    field_map: dict[str, Any] | None = None
    files: dict[str, bytes] = field(default_factory=dict)
    verdicts: tuple[Verdict, ...] = ()
    cases: dict[str, CaseResponse] = field(default_factory=dict)


@runtime_checkable
class DesignProblem(Protocol):
    """What a study kind hands to ``flexopt run``.

    Attributes
    ----------
    space : the design space (variable names carry units where they have one).
    objective_names : (n_obj,) names of the minimised objectives, with units.
    constraint_names : (n_con,) names of the constraints g <= 0, with units.
    """

    space: DesignSpace
    objective_names: tuple[str, ...]
    constraint_names: tuple[str, ...]

    def evaluate(self, x: np.ndarray) -> Evaluation:
        """Evaluate one design vector (n_var,). Never raises for a bad design: a design that
        cannot be built, meshed or solved comes back as ``Evaluation.failed(..., reason)``."""
        ...

    def detail(self, x: np.ndarray) -> DesignDetail:
        """Full response of one design for plots, report and STL."""
        ...

    # Optional: ``initial_designs() -> (k, n_var) array | None`` seeds the first population
    # (e.g. a published optimum); ``flexopt run`` calls it when the problem has it.
