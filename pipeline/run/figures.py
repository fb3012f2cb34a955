"""The run's own figures: the best design's curve and the convergence of the optimiser."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from flexopt.pipeline import plots
from flexopt.pipeline.plot_targets import plot_spec
from flexopt.pipeline.run.folder import Columns


def spec_label(spec: Mapping[str, Any], axis: str) -> str | None:
    """Axis label of a DesignDetail.plot: its ``x_label`` / ``y_label``
    (:func:`pipeline.plot_targets.plot_spec`, which also reads the old ``xlabel`` ...)."""
    return plot_spec(spec).get(f"{axis}_label")


def float_or_none(value: Any) -> float | None:
    return None if value is None else float(value)


def curve_png(table: Mapping[str, np.ndarray], spec: Mapping[str, Any], title: str) -> bytes:
    spec = plot_spec(spec)
    target = float_or_none(spec.get("target"))
    tolerance = float_or_none(spec.get("tolerance"))
    if tolerance is None and target is not None and spec.get("tolerance_rel") is not None:
        tolerance = abs(target) * float(spec["tolerance_rel"])
    band = spec.get("band_x")
    return plots.plot_curve(
        table,
        spec["x"],
        spec["y"],
        target=target,
        tolerance=tolerance,
        band_x=(float(band[0]), float(band[1])) if band is not None else None,
        x_label=spec_label(spec, "x"),
        y_label=spec_label(spec, "y"),
        title=title,
        spec=spec,  # a target curve or range of the kind (pipeline.plot_targets)
    )


def convergence_png(history: list[dict[str, Any]], columns: Columns) -> bytes:
    from flexopt.pipeline.labels import MAXIMISED

    best = np.array([[h[f"best_{name}"] for name in columns.objectives] for h in history])
    # a maximised objective drawn as the study states it: X rising, not its negative falling
    sign = np.array([-1.0 if n.startswith(MAXIMISED) else 1.0 for n in columns.objectives])
    names = tuple(n.removeprefix(MAXIMISED) for n in columns.objectives)  # "best": the largest
    return plots.plot_convergence(
        np.array([h["generation"] for h in history]),
        best.reshape(len(history), len(names)) * sign,
        np.array([h["best_feasible"] for h in history]),
        np.array([h["feasible_fraction"] for h in history]),
        names,
    )
