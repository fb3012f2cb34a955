"""``report.html`` of a run folder: every evaluated design to explore, in one offline file.

report.md tells the best design; this page lets an engineer explore all of them, as optiSLang or
HyperStudy would: parallel coordinates and a scatter matrix coloured by feasibility, a Spearman
rank-correlation sensitivity of each objective to each variable, the ten best designs, the Pareto
front (several objectives), the best design's response with its target band and a rotatable 3D
view of the part.

The page is one self-contained HTML file: plotly.js is embedded once (~3.5–4.5 MB), so it opens
without a network (a report is read on a workshop laptop or archived with the part). Each figure's
plotly JSON sits in a ``<script type="application/json" id="fig-…">`` element that a small inline
script draws, so a test (or a script) can read the figures back with ``json.loads``. Every axis
and column is labelled in words with its unit from :mod:`pipeline.labels`; the target of a
response (a constant, a curve or a range, with its band) comes from the kind's plot spec through
:mod:`pipeline.plot_targets`, as in the PNGs.

``flexopt evaluate`` writes a page of the same make for its one design
(:func:`render_evaluate_html`): the verdict, a summary, the response with its target and the part
in 3D, without the design-exploration views.
"""

from __future__ import annotations

import html
import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import DesignDetail, DesignProblem
from flexopt.optimise.requirements import Verdict, overall, verdict_rows
from flexopt.pipeline import figure_json as fj
from flexopt.pipeline import labels
from flexopt.pipeline.html_templates import WHITE, finish_template
from flexopt.pipeline.plot_targets import plot_spec
from flexopt.pipeline.sensitivity_report import sensitivity_html

__all__ = [
    "EVALUATE_SECTIONS",
    "EvaluateHtmlData",
    "HtmlData",
    "SECTIONS",
    "evaluate_html",
    "evaluate_part",
    "render_evaluate_html",
    "render_html",
    "sensitivity",
    "top_designs",
]

#: The sections of the page, by element id, in order (a section without data says why).
SECTIONS = (
    "verdict",
    "variables",
    "top-designs",
    "parallel-coordinates",
    "scatter-matrix",
    "sensitivity",
    "pareto-front",
    "response",
    "part-3d",
    "run",
)

#: At most this many variables in the scatter matrix (the most influential ones): a 23 × 23 matrix
#: of 529 panels is unreadable and slow to draw.
MAX_SPLOM_VARIABLES = 6
#: Rows of the top-designs table.
TOP_N = 10

_FEASIBLE = "#1f77b4"
_INFEASIBLE = "#d62728"
_CONFIG = {"displaylogo": False, "responsive": True}


@dataclass(frozen=True)
class HtmlData:
    """What report.html shows.

    Attributes
    ----------
    study_name, kind : the study's name and kind.
    problem : the design problem (names and bounds of variables, objectives, constraints).
    evaluations : every evaluated design of the run.
    best : the chosen design; ``front`` the non-dominated ones (several objectives).
    detail : the best design's detail (response table, plot spec, outline), or None.
    verdicts : the best design against the study's requirements.
    record : run.json (its ``parallel.description`` names the backend).
    """

    study_name: str
    kind: str
    problem: DesignProblem
    evaluations: Sequence[Evaluation]
    best: Evaluation
    front: Sequence[Evaluation] = ()
    detail: DesignDetail | None = None
    verdicts: Sequence[Verdict] = ()
    record: Mapping[str, Any] = field(default_factory=dict)
    #: best.json's robustness record (with its band); else run.json's, without the band
    robustness: Mapping[str, Any] | None = None
    #: the best design's fatigue, creep hold and contact (pipeline.durability_report); empty:
    #: no durability section
    durability: Mapping[str, Any] = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# Numbers


def _rank_key(ev: Evaluation) -> tuple[int, float, float]:
    """Order of the top-designs table, as :func:`optimise.ga.best_of` chooses: feasible designs by
    their first objective, then solved infeasible ones by violation, failed designs last."""
    f0 = float(ev.f[0]) if len(ev.f) and math.isfinite(float(ev.f[0])) else math.inf
    if ev.feasible:
        return (0, 0.0, f0)
    if not ev.reason:
        return (1, ev.violation, f0)
    return (2, math.inf, f0)


def top_designs(evaluations: Sequence[Evaluation], n: int = TOP_N) -> list[Evaluation]:
    """The ``n`` best designs, best first (the ordering that chose the best design)."""
    return sorted(evaluations, key=_rank_key)[:n]


def _finite_rows(evaluations: Sequence[Evaluation]) -> list[Evaluation]:
    """Designs that were solved: every objective and constraint a finite number."""
    return [
        ev
        for ev in evaluations
        if not ev.reason and np.all(np.isfinite(ev.f)) and np.all(np.isfinite(ev.g))
    ]


def sensitivity(
    evaluations: Sequence[Evaluation], n_var: int, n_obj: int
) -> tuple[np.ndarray, str]:
    """Spearman rank correlation of each objective (rows) with each variable (columns).

    Over the feasible designs, or over every solved design when fewer than five are feasible (the
    returned text says which). A rank correlation needs no model and no sampling plan: it says
    how monotonically an objective follows a variable across what the optimiser tried. A constant
    column gives NaN (nothing to correlate).
    """
    solved = _finite_rows(evaluations)
    feasible = [ev for ev in solved if ev.feasible]
    rows, basis = (
        (feasible, f"the {len(feasible)} feasible designs")
        if len(feasible) >= 5
        else (solved, f"all {len(solved)} solved designs (only {len(feasible)} feasible)")
    )
    rho = np.full((n_obj, n_var), np.nan)
    if len(rows) < 3:
        return rho, f"too few designs ({len(rows)}) for a rank correlation"
    x = np.array([ev.x for ev in rows], dtype=float)
    f = np.array([ev.f for ev in rows], dtype=float)
    for i in range(n_obj):
        for j in range(n_var):
            if np.ptp(x[:, j]) == 0 or np.ptp(f[:, i]) == 0:
                continue
            rho[i, j] = _spearman(x[:, j], f[:, i])
    return rho, basis


def _average_ranks(a: np.ndarray) -> np.ndarray:
    """(n,) ranks 1..n of ``a``, ties given their average rank (scipy.stats.rankdata's
    'average', here so that the report does not import scipy.stats, ~0.7 s)."""
    order = np.argsort(a, kind="mergesort")
    inverse = np.empty(a.size, dtype=np.intp)
    inverse[order] = np.arange(a.size)
    s = a[order]
    first = np.r_[True, s[1:] != s[:-1]]
    dense = np.cumsum(first)[inverse]  # 1-based group of each value
    starts = np.r_[np.flatnonzero(first), a.size]
    return 0.5 * (starts[dense] + starts[dense - 1] + 1)


def _spearman(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman's rank correlation: Pearson's correlation of the average ranks."""
    rx, ry = _average_ranks(x), _average_ranks(y)
    rx, ry = rx - rx.mean(), ry - ry.mean()
    return float(rx @ ry / np.sqrt((rx @ rx) * (ry @ ry)))


# --------------------------------------------------------------------------------------------
# Figures


def _axis(title: str, **more: Any) -> dict[str, Any]:
    return {"title": {"text": title}, **more}


def _layout(title: str, **more: Any) -> dict[str, Any]:
    return {
        "title": {"text": title},
        "template": WHITE,  # "plotly_white", put in at embed (pipeline/html_templates.py)
        "margin": {"l": 70, "r": 30, "t": 60, "b": 60},
        **more,
    }


def _feasibility_colours(rows: Sequence[Evaluation]) -> list[int]:
    return [1 if ev.feasible else 0 for ev in rows]


def _parcoords(data: HtmlData, rows: Sequence[Evaluation]) -> Any:

    p = data.problem
    dims = [
        {
            "label": labels.label(n),
            "values": np.array([ev.x[j] for ev in rows], dtype=float),
            "range": [float(p.space.lower[j]), float(p.space.upper[j])],
        }
        for j, n in enumerate(p.space.names)
    ]
    dims += [
        {"label": labels.label(n), "values": np.array([ev.f[i] for ev in rows], dtype=float)}
        for i, n in enumerate(p.objective_names)
    ]
    dims += [
        {"label": labels.label(n), "values": np.array([ev.g[k] for ev in rows], dtype=float)}
        for k, n in enumerate(p.constraint_names)
    ]
    colour = _feasibility_colours(rows)
    fig = fj.Figure(
        fj.Parcoords(
            dimensions=dims,
            line={
                "color": colour,
                "colorscale": [[0, _INFEASIBLE], [1, _FEASIBLE]],
                "cmin": 0,
                "cmax": 1,
                "showscale": True,
                "colorbar": {
                    "title": {"text": "feasible"},
                    "tickvals": [0, 1],
                    "ticktext": ["no", "yes"],
                },
            },
        )
    )
    fig.data[0]["labelangle"] = -35  # long labels in words would overlap when level
    fig.update_layout(
        _layout(
            "All solved designs: variables, objectives and constraints (blue feasible, red not)",
            height=620,
            margin={"l": 80, "r": 280, "t": 230, "b": 40},
        )
    )
    return fig


def _splom(data: HtmlData, rows: Sequence[Evaluation], rho: np.ndarray) -> Any:

    p = data.problem
    names = list(p.space.names)
    # the most influential variables first (largest |rho| over the objectives)
    strength = np.nan_to_num(np.nanmax(np.abs(rho), axis=0, initial=0.0), nan=0.0)
    order = sorted(range(len(names)), key=lambda j: -strength[j])[:MAX_SPLOM_VARIABLES]
    order.sort()
    dims = [
        {"label": labels.label(names[j]), "values": [float(ev.x[j]) for ev in rows]} for j in order
    ]
    dims += [
        {"label": labels.label(n), "values": np.array([ev.f[i] for ev in rows], dtype=float)}
        for i, n in enumerate(p.objective_names)
    ]
    fig = fj.Figure()
    if len(dims) <= 2:
        # One panel: plotly's splom with two dimensions and no upper half or diagonal throws
        # ("reading 'makeCalcdata'") and draws nothing; a plain scatter is the same panel.
        return _scatter_panel(dims, rows), [names[j] for j in order]
    for feasible, colour, word in (
        (False, _INFEASIBLE, "infeasible"),
        (True, _FEASIBLE, "feasible"),
    ):
        subset = [k for k, ev in enumerate(rows) if ev.feasible is feasible]
        fig.add_trace(
            fj.Splom(
                dimensions=[{**d, "values": [d["values"][k] for k in subset]} for d in dims],
                name=f"{word} ({len(subset)})",
                marker={"color": colour, "size": 4, "opacity": 0.7},
                diagonal={"visible": False},
                showupperhalf=False,
            )
        )
    size = 170 * len(dims) + 120
    fig.update_layout(
        _layout(
            "Scatter matrix of the most influential variables and the objectives",
            height=max(size, 450),
            width=max(size, 450),
            showlegend=True,
            font={"size": 10},
        )
    )
    return fig, [names[j] for j in order]


def _scatter_panel(dims: Sequence[Mapping[str, Any]], rows: Sequence[Evaluation]) -> Any:
    """The scatter matrix of one variable and one objective: its one panel, as a scatter
    (x the first dimension, y the second; one dimension alone against the design's number)."""

    if len(dims) == 2:
        x_dim, y_dim = dims
        x_title = x_dim["label"]
    else:
        x_dim = {"label": "design (order solved)", "values": list(range(len(rows)))}
        y_dim, x_title = dims[0], "design (order solved)"
    fig = fj.Figure()
    for feasible, colour, word in (
        (False, _INFEASIBLE, "infeasible"),
        (True, _FEASIBLE, "feasible"),
    ):
        subset = [k for k, ev in enumerate(rows) if ev.feasible is feasible]
        fig.add_trace(
            fj.Scatter(
                x=[float(x_dim["values"][k]) for k in subset],
                y=_plain([y_dim["values"][k] for k in subset]),
                mode="markers",
                name=f"{word} ({len(subset)})",
                marker={"color": colour, "size": 6, "opacity": 0.7},
            )
        )
    fig.update_layout(
        _layout(
            "Scatter matrix of the variable and the objective",
            height=480,
            xaxis=_axis(x_title),
            yaxis=_axis(y_dim["label"]),
            showlegend=True,
        )
    )
    return fig


def _sensitivity_fig(data: HtmlData, rho: np.ndarray, basis: str) -> Any:

    p = data.problem
    text = [["–" if not math.isfinite(v) else f"{v:+.2f}" for v in row] for row in rho]
    fig = fj.Figure(
        fj.Heatmap(
            z=np.where(np.isfinite(rho), rho, None).tolist(),
            x=[labels.label(n) for n in p.space.names],
            y=[labels.label(n) for n in p.objective_names],
            text=text,
            texttemplate="%{text}",
            zmin=-1,
            zmax=1,
            colorscale=fj.RDBU,
            reversescale=True,
            colorbar={"title": {"text": "Spearman ρ (–)"}},
            hovertemplate="variable: %{x}<br>objective: %{y}<br>ρ = %{z:.3f}<extra></extra>",
        )
    )
    fig.update_layout(
        _layout(
            f"Sensitivity: Spearman rank correlation of each objective with each variable "
            f"(over {basis})",
            height=260 + 40 * len(p.objective_names),
            xaxis=_axis("design variable", tickangle=-45),
            yaxis=_axis("objective (minimised)"),
            margin={"l": 220, "r": 30, "t": 70, "b": 160},
        )
    )
    return fig


def _front_fig(data: HtmlData, rows: Sequence[Evaluation]) -> Any:

    names = data.problem.objective_names
    feasible = [ev for ev in rows if ev.feasible]
    front = list(data.front)
    if len(names) == 2:
        fig = fj.Figure()
        fig.add_trace(
            fj.Scatter(
                x=[float(ev.f[0]) for ev in feasible],
                y=[float(ev.f[1]) for ev in feasible],
                mode="markers",
                name="feasible designs",
                marker={"color": "#999999", "size": 5},
            )
        )
        fig.add_trace(
            fj.Scatter(
                x=[float(ev.f[0]) for ev in front],
                y=[float(ev.f[1]) for ev in front],
                mode="lines+markers",
                name=f"Pareto front ({len(front)})",
                marker={"color": _FEASIBLE, "size": 7},
            )
        )
        fig.add_trace(
            fj.Scatter(
                x=[float(data.best.f[0])],
                y=[float(data.best.f[1])],
                mode="markers",
                name="chosen design",
                marker={"color": _INFEASIBLE, "size": 14, "symbol": "star"},
            )
        )
        fig.update_layout(
            _layout(
                "Pareto front (objectives minimised)",
                height=480,
                xaxis=_axis(labels.label(names[0])),
                yaxis=_axis(labels.label(names[1])),
            )
        )
        return fig
    # three or more objectives: the front among the feasible designs, pairwise
    dims = [{"label": labels.label(n)} for n in names]
    fig = fj.Figure()
    for subset, word, colour in (
        (feasible, "feasible designs", "#999999"),
        (front, f"Pareto front ({len(front)})", _FEASIBLE),
    ):
        fig.add_trace(
            fj.Splom(
                dimensions=[
                    {**d, "values": [float(ev.f[i]) for ev in subset]} for i, d in enumerate(dims)
                ],
                name=word,
                marker={"color": colour, "size": 5},
                diagonal={"visible": False},
                showupperhalf=False,
            )
        )
    fig.update_layout(_layout("Pareto front, objectives pairwise (minimised)", height=600))
    return fig


def _float(value: Any) -> float | None:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


def _plain(values: Any) -> list[float | None]:
    """Floats for plotly's strict JSON: NaN and ±inf become None (a gap)."""
    return [None if not math.isfinite(v) else float(v) for v in np.asarray(values, dtype=float)]


def _response_fig(
    spec: Mapping[str, Any],
    table: Mapping[str, Any],
    y: str,
    kind: str,
    whose: str,
    limit: tuple[float, Verdict] | None = None,
) -> tuple[Any, str]:
    """One response plot: every curve of ``y``'s quantity against x (:func:`labels.siblings`),
    with the target and its band (:func:`pipeline.plot_targets.target_overlay`: a constant, a
    target curve or a range), or the allowable line for stress. Returns the figure and a
    sentence on what is drawn as target."""
    from flexopt.pipeline.plot_targets import target_overlay

    spec = plot_spec(spec)
    x = spec["x"]
    xs = np.asarray(table[x], dtype=float)
    converged = np.asarray(table.get("converged", np.ones(len(xs), bool)), dtype=bool)
    fig = fj.Figure()
    curves = labels.siblings(table, y)
    for column in curves:
        ys = np.asarray(table[column], dtype=float)
        ys = np.where(converged & np.isfinite(ys), ys, np.nan)
        sparse = np.isfinite(ys).sum() < 0.5 * converged.sum()  # a check at a few rows
        given = spec.get("y_label")
        name = labels.words(column)
        if kind != "stress" and given and len(curves) == 1:  # the kind's words name it too
            name = labels.strip_unit(given)
        fig.add_trace(
            fj.Scatter(
                x=xs.tolist(),
                y=_plain(ys),
                mode="markers" if sparse else "lines+markers",
                name=name,
                marker={"size": 7 if sparse else 4, "symbol": "square" if sparse else "circle"},
            )
        )
    lo, hi = (float(np.nanmin(xs)), float(np.nanmax(xs))) if len(xs) else (0.0, 1.0)
    target_text: str
    if kind == "stress":
        # the line is the allowable the verdict judges (yield / safety factor of a stress
        # requirement); the kind's own figure only where no requirement bounds the stress
        value = limit[0] if limit is not None else _float(spec.get("allowable_MPa"))
        if value is not None:
            if limit is not None:
                word = "allowable"
                name = f"allowable {value:.4g} MPa ({limit[1].name}: {limit[1].bound})"
                said = f"the allowable {value:.4g} MPa of requirement {limit[1].name} "
            else:
                word = spec.get("allowable_label") or "allowable"
                name = f"{word} {value:.4g} MPa"
                said = f"{word} stress {value:.4g} MPa (no stress requirement) "
            fig.add_trace(
                fj.Scatter(
                    x=[lo, hi],
                    y=[value, value],
                    mode="lines",
                    name=name,
                    line={"color": "black", "dash": "dash"},
                )
            )
            target_text = f"{said}drawn as a dashed line"
        else:
            target_text = "no allowable stress given by the study kind"
        ylabel = spec.get("stress_label") or labels.curves_label(y, curves)
    else:
        unit = labels.unit_of(y) or ""
        overlay = target_overlay({**spec, "y": y}, table, y, unit)
        if overlay is not None:
            if overlay.lower is not None and overlay.upper is not None:
                band_x = [*overlay.x.tolist(), *overlay.x[::-1].tolist()]
                band_y = [*_plain(overlay.lower), *_plain(overlay.upper[::-1])]
                fig.add_trace(
                    fj.Scatter(
                        x=band_x,
                        y=band_y,
                        fill="toself",
                        mode="lines",
                        line={"width": 0},
                        fillcolor="rgba(44,160,44,0.18)",
                        name=overlay.label if overlay.y is None else "target band",
                    )
                )
            if overlay.y is not None:
                fig.add_trace(
                    fj.Scatter(
                        x=overlay.x.tolist(),
                        y=_plain(overlay.y),
                        mode="lines",
                        name=overlay.label,
                        line={"color": "#2ca02c", "dash": "dash"},
                    )
                )
            target_text = f"{overlay.label} drawn in green"
        else:
            target_text = "no target given by the study kind for this response"
        given = spec.get("y_label")
        ylabel = labels.label(y, given) if given else labels.curves_label(y, curves)
    xlabel = labels.label(x, spec.get("x_label"))
    fig.update_layout(
        _layout(
            f"{_no_unit(ylabel)} against {_no_unit(xlabel)} ({whose})",
            height=440,
            xaxis=_axis(xlabel),
            yaxis=_axis(ylabel),
            legend={"orientation": "h", "y": -0.22},
        )
    )
    return fig, target_text


def _no_unit(text: str) -> str:
    """A label without its trailing ``(unit)``, for a title."""
    return re.sub(r"\s*\([^()]*\)$", "", text)


def _part_mesh(detail: DesignDetail) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices, faces) of the printable part: the outline extruded, as best.stl is built."""
    if detail.outline is None or not detail.height_mm:
        return None
    from flexopt.geometry.solid import extrude

    mesh = extrude(detail.outline, float(detail.height_mm))
    return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=int)


def _part_fig(vertices: np.ndarray, faces: np.ndarray, whose: str = "best") -> fj.Figure:
    """The printable part as a plotly mesh."""
    v, f = vertices, faces
    size = np.maximum(v.max(axis=0) - v.min(axis=0), 1e-9)
    fig = fj.Figure(
        fj.Mesh3d(
            x=v[:, 0].round(4).tolist(),
            y=v[:, 1].round(4).tolist(),
            z=v[:, 2].round(4).tolist(),
            i=f[:, 0].tolist(),
            j=f[:, 1].tolist(),
            k=f[:, 2].tolist(),
            color="#8fb3d9",
            flatshading=True,
            name=f"{whose} design",
            lighting={"ambient": 0.45, "diffuse": 0.8, "specular": 0.2},
        )
    )
    fig.update_layout(
        _layout(
            f"The {whose} design as printed: drag to rotate, scroll to zoom",
            height=560,
            scene={
                # true proportions (a 0.5 mm leaf must look thin), the longest side 1 so that
                # the camera below sees the whole part
                "aspectmode": "manual",
                "aspectratio": dict(zip("xyz", (size / size.max()).round(4).tolist(), strict=True)),
                "camera": {"eye": {"x": 0.55, "y": -0.85, "z": 0.65}},
                "xaxis": _axis("x (mm)"),
                "yaxis": _axis("y (mm)"),
                "zaxis": _axis("z (mm)"),
            },
        )
    )
    return fig


def _stress_fig(fmap: Mapping[str, Any], whose: str = "best") -> fj.Figure:
    """The von Mises field of ``fmap`` (a DesignDetail's ``field_map`` with
    ``displacement_mm``) on the deformed part, as a plotly mesh seen from above, the undeformed
    outline in grey; the scale as stress_deformed.png draws it
    (:func:`pipeline.plots.deformation_scale`)."""
    from flexopt.pipeline.plots import boundary_edges, deformation_scale

    p = np.asarray(fmap["points_mm"], dtype=float).reshape(-1, 2)
    u = np.asarray(fmap["displacement_mm"], dtype=float).reshape(-1, 2)
    v = np.asarray(fmap["values"], dtype=float).reshape(-1)
    t = np.asarray(fmap["triangles"], dtype=int).reshape(-1, 3)
    label = str(fmap.get("label", "von Mises stress (MPa)"))
    limit = _float(fmap.get("limit"))
    scale = deformation_scale(p, u)
    q = p + scale * u
    edges = boundary_edges(t)
    # the outline as one polyline with gaps (None) between its edges
    ex = np.column_stack([p[edges[:, 0], 0], p[edges[:, 1], 0], np.full(len(edges), np.nan)])
    ey = np.column_stack([p[edges[:, 0], 1], p[edges[:, 1], 1], np.full(len(edges), np.nan)])
    bar = label if limit is None else f"{label}<br>allowable {limit:g} MPa"
    fig = fj.Figure(
        [
            fj.Scatter3d(
                x=_plain(ex.ravel().round(4)),
                y=_plain(ey.ravel().round(4)),
                z=[0.0] * ex.size,
                mode="lines",
                line={"color": "#9e9e9e", "width": 2},
                name="undeformed",
                hoverinfo="skip",
            ),
            fj.Mesh3d(
                x=q[:, 0].round(4).tolist(),
                y=q[:, 1].round(4).tolist(),
                z=[0.0] * len(q),
                i=t[:, 0].tolist(),
                j=t[:, 1].tolist(),
                k=t[:, 2].tolist(),
                intensity=v.round(3).tolist(),
                colorscale=fj.VIRIDIS,
                cmin=0.0,
                cmax=max(float(np.nanmax(v)), limit or 0.0),
                colorbar={"title": {"text": bar}},
                name="von Mises (MPa)",
                hovertemplate="x %{x} mm<br>y %{y} mm<br>%{intensity:.4g} MPa<extra></extra>",
            ),
        ]
    )
    umax = float(np.nanmax(np.hypot(u[:, 0], u[:, 1]))) if len(u) else 0.0
    how = "true scale" if scale == 1.0 else f"displacement magnified {scale:g}×"
    size = np.maximum(q.max(axis=0) - q.min(axis=0), 1e-9)
    fig.update_layout(
        _layout(
            f"Von Mises stress of the {whose} design on the deformed part, {how} "
            f"(max |u| {umax:.3g} mm)",
            height=560,
            scene={
                "aspectmode": "manual",
                # true proportions; seen from above in an orthographic view, where the
                # aspect ratio (not the eye's distance) sets how large the part is drawn
                "aspectratio": {
                    "x": float(2.2 * size[0] / size.max()),
                    "y": float(2.2 * size[1] / size.max()),
                    "z": 0.05,
                },
                "camera": {"eye": {"x": 0.0, "y": 0.0, "z": 2.0}, "up": {"x": 0, "y": 1, "z": 0},
                           "projection": {"type": "orthographic"}},
                "xaxis": _axis("x (mm)"),
                "yaxis": _axis("y (mm)"),
                "zaxis": {**_axis(""), "visible": False},
            },
        )
    )  # fmt: skip
    return fig


def _stress_block(fmap: Mapping[str, Any] | None, figures: _Figures, whose: str) -> str:
    """The stress field on the deformed part where the design's field (a ``field_map``)
    carries its displacement (the same field as stress_deformed.png), else nothing."""
    fmap = fmap or {}
    if fmap.get("displacement_mm") is None:
        return ""
    try:
        fig = _stress_fig(fmap, whose)
    except Exception as exc:  # a field that cannot be drawn must not cost the page
        return f"<p>No stress view: {_e(type(exc).__name__)}: {_e(exc)}.</p>"
    return (
        "<h3>Stress on the deformed part</h3><p class='note'>The plane-stress von Mises field "
        f"({_e(fmap.get('label', 'von Mises stress (MPa)'))}) on the part deformed by the same "
        "solve, seen from above; the grey line is the undeformed outline "
        "(also stress_deformed.png).</p>" + figures.embed(fig, "stress-deformed")
    )


# --------------------------------------------------------------------------------------------
# The page


def _e(text: Any) -> str:
    return html.escape(str(text), quote=True)


def _cell(value: Any) -> str:
    from flexopt.pipeline.report import format_value

    return _e(format_value(value))


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]], cls: str = "") -> str:
    head = "".join(f"<th>{_e(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{_cell(v)}</td>" for v in r) + "</tr>" for r in rows)
    attr = f' class="{cls}"' if cls else ""
    return f"<table{attr}><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


class _Figures:
    """Figures of the page: each one's JSON in a script element, drawn by one loader."""

    def __init__(self) -> None:
        self.count = 0

    def embed(self, fig: fj.Figure, name: str) -> str:
        """The figure's element: its JSON (pipeline/figure_json.py) with its template put in
        (pipeline/html_templates.py) in a script element, and the div plotly.js draws it in."""
        self.count += 1
        spec = fig.to_plotly_json()
        finish_template(spec)
        text = script_json(fj.dumps(spec))
        return (
            f'<div class="figure" id="plot-{name}"></div>'
            f'<script type="application/json" class="plotly-figure" id="fig-{name}" '
            f'data-target="plot-{name}">{text}</script>'
        )


def script_json(text: str) -> str:
    """JSON text safe inside a ``<script>`` element: ``<``, ``>`` and ``&`` as ``\\u003c``,
    ``\\u003e``, ``\\u0026`` (the same JSON value).

    Escaping ``</`` alone is not enough: ``<!--`` followed by ``<script`` puts the HTML parser
    in its "double-escaped" state, where the element's own ``</script>`` no longer ends it and
    every figure after it is swallowed (a variable named ``<!--<script>x`` blanked the page).
    With no ``<`` left in the text, no label can change how the element is parsed.
    """
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


#: Draws each figure on its own: a figure that plotly.js cannot draw (it throws, or its promise
#: is rejected) gets a message in its place, and the figures after it are still drawn.
_LOADER = """
<script>
// Draw every embedded figure once plotly.js (above, inline) is loaded: no network needed.
(function () {
  function failed(el, err) {
    var div = document.getElementById(el.dataset.target);
    var note = document.createElement('p');
    note.className = 'figure-error';
    note.textContent = 'This figure could not be drawn (' + (err && err.message || err) +
      '); the numbers are in the files of the run folder.';
    if (div) { div.appendChild(note); }
    console.error('flexopt report: figure ' + el.id + ' not drawn: ' + (err && err.message || err));
  }
  document.querySelectorAll('script.plotly-figure').forEach(function (el) {
    try {
      var spec = JSON.parse(el.textContent);
      var done = Plotly.newPlot(el.dataset.target, spec.data, spec.layout || {}, %s);
      if (done && done.catch) { done.catch(function (err) { failed(el, err); }); }
    } catch (err) {
      failed(el, err);
    }
  });
})();
</script>
"""

_STYLE = """
<style>
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1250px; color: #222; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; }
table { border-collapse: collapse; margin: .6em 0 1em; font-size: .9em; }
th, td { border: 1px solid #ccc; padding: .25em .55em; text-align: left; vertical-align: top; }
th { background: #f2f4f7; }
td.num, table.num td { font-variant-numeric: tabular-nums; }
.met { color: #1a7f37; font-weight: bold; } .notmet { color: #c62828; font-weight: bold; }
.note { color: #555; font-size: .92em; } .figure { margin: .5em 0 1.5em; }
.figure-error { color: #c62828; border: 1px solid #c62828; padding: .5em; }
.scroll { overflow-x: auto; }
nav a { margin-right: .8em; }
</style>
"""


def render_html(data: HtmlData) -> str:
    """The text of report.html (one file, plotly.js inline, no link to the network)."""

    p = data.problem
    figures = _Figures()
    evaluations = list(data.evaluations)
    solved = _finite_rows(evaluations)
    n_feasible = sum(ev.feasible for ev in evaluations)
    verdicts = list(data.verdicts) or list(data.detail.verdicts if data.detail else ())
    word = overall(verdicts)
    parts: list[str] = []

    robust = data.robustness or data.record.get("robustness")
    ids = _with_durability(_with_robustness(SECTIONS, robust), data.durability)
    nav = " ".join(f'<a href="#{s}">{_e(s.replace("-", " "))}</a>' for s in ids)
    parts.append(
        f"<h1>{_e(data.study_name)} — flexopt run</h1>"
        f"<p>Study kind <code>{_e(data.kind)}</code>; {len(evaluations)} designs evaluated, "
        f"{len(solved)} solved, {n_feasible} feasible. The Markdown report is "
        f'<a href="report.md">report.md</a>; every design is in '
        f'<a href="evaluations.csv">evaluations.csv</a>.</p><nav>{nav}</nav>'
    )

    # -- verdict
    cls = "met" if word == "MET" else "notmet"
    body = (
        f'<p><span class="{cls}">{_e(word)}</span> — {sum(v.met for v in verdicts)} of '
        f"{len(verdicts)} requirements met by the best design.</p>"
    )
    if verdicts:
        body += _table(
            ["requirement", "value", "bound", "margin", "verdict"], verdict_rows(verdicts)
        )
    else:
        body += "<p>No requirement was stated, so nothing is claimed.</p>"
    parts.append(_section("verdict", "Verdict", body))

    # -- variables and their meanings
    body = _table(
        ["variable", "meaning", "unit", "bounds", "best design"],
        labels.variable_rows(data.kind, p, data.best.x),
    )
    body += (
        "<p class='note'>Objectives (minimised): "
        + ", ".join(f"<code>{_e(n)}</code> = {_e(labels.label(n))}" for n in p.objective_names)
        + ". Constraints (met when ≤ 0): "
        + (
            ", ".join(f"<code>{_e(n)}</code> = {_e(labels.label(n))}" for n in p.constraint_names)
            or "none"
        )
        + ".</p>"
    )
    parts.append(_section("variables", "Design variables and what they mean", body))

    # -- top designs
    top = top_designs(evaluations)
    # physical values: objectives as stated (maximised ones too), constraints as the quantity
    # their requirement bounds (labels.design_columns)
    physical, values = labels.design_columns(p.objective_names, p.constraint_names, verdicts)
    header = ["rank", "feasible", *physical, *map(labels.label, p.space.names), "reason"]
    rows = [
        [k + 1, ev.feasible, *values(ev), *map(float, ev.x), ev.reason or "–"]
        for k, ev in enumerate(top)
    ]
    body = (
        f"<p class='note'>The {len(top)} best of {len(evaluations)} designs: feasible ones by "
        "their first objective, then the least constraint violation (the ordering that chose "
        "the best design).</p><div class='scroll'>" + _table(header, rows, "num") + "</div>"
    )
    parts.append(_section("top-designs", f"Top {TOP_N} designs", body))

    # -- exploration of every solved design
    rho, basis = sensitivity(evaluations, len(p.space.names), len(p.objective_names))
    if len(solved) >= 2:
        parts.append(
            _section(
                "parallel-coordinates",
                "Parallel coordinates",
                "<p class='note'>One line per solved design; drag along an axis to filter. "
                f"{len(evaluations) - len(solved)} failed designs (no numbers) are left out.</p>"
                + figures.embed(_parcoords(data, solved), "parallel-coordinates"),
            )
        )
        fig, shown = _splom(data, solved, rho)
        parts.append(
            _section(
                "scatter-matrix",
                "Scatter matrix",
                f"<p class='note'>Variables shown: {_e(', '.join(shown))} (at most "
                f"{MAX_SPLOM_VARIABLES}, the ones whose rank correlation with an objective is "
                "largest), against the objectives; blue feasible, red infeasible.</p>"
                + figures.embed(fig, "scatter-matrix"),
            )
        )
    else:
        for sid, title in (
            ("parallel-coordinates", "Parallel coordinates"),
            ("scatter-matrix", "Scatter matrix"),
        ):
            parts.append(_section(sid, title, "<p>Fewer than two solved designs.</p>"))
    parts.append(
        _section(
            "sensitivity",
            "Sensitivity of the objectives to the variables",
            f"<p class='note'>Spearman rank correlation ρ over {_e(basis)}: +1 the objective grows "
            "with the variable, −1 it falls, 0 no monotonic relation. It is a screening measure, "
            "not a variance decomposition: a variable can matter non-monotonically with ρ ≈ 0.</p>"
            + figures.embed(_sensitivity_fig(data, rho, basis), "sensitivity")
            + sensitivity_html(data.problem, data.best, figures.embed),
        )
    )

    # -- Pareto front
    if len(p.objective_names) >= 2 and data.front:
        body = figures.embed(_front_fig(data, solved), "pareto-front")
        body += _table(
            ["design", *map(labels.label, p.objective_names)],
            [[k + 1, *map(float, ev.f)] for k, ev in enumerate(data.front[:60])],
            "num",
        )
    else:
        body = (
            f"<p>One objective (<code>{_e(p.objective_names[0])}</code>): no Pareto front; "
            "the best design is the feasible one with the smallest objective.</p>"
        )
    parts.append(_section("pareto-front", "Pareto front", body))

    # -- response
    parts.append(
        _section(
            "response",
            "Response of the best design",
            _response_section(data.detail, figures, "best design", verdicts),
        )
    )
    if data.durability:
        parts.append(_durability_section(data.durability))
    if robust:
        table = data.detail.table if data.detail else {}
        spec = data.detail.plot if data.detail else {}
        parts.append(_robustness_section(robust, table, spec, figures, "best design"))

    # -- 3D part
    why = None if data.detail is not None else "the best design's detail failed"
    parts.append(
        _section("part-3d", "The part in 3D", _part_section(data.detail, figures, "best", why))
    )

    # -- the run
    record = data.record
    parallel = record.get("parallel") or {}
    opt = record.get("optimiser") or {}
    rows = [
        ["evaluation backend", parallel.get("description") or parallel.get("backend") or "–"],
        ["algorithm", opt.get("algorithm")],
        ["population × generations", f"{opt.get('pop_size')} × {opt.get('n_gen')}"],
        ["seed", opt.get("seed")],
        ["quick", bool(record.get("quick"))],
        ["CPUs", (record.get("host") or {}).get("cpu_count")],
        ["started", record.get("started")],
    ]
    parts.append(_section("run", "The run", _table(["item", "value"], rows)))

    return _page(data.study_name, parts)


def _page(title: str, parts: Sequence[str]) -> str:
    """One HTML file: the sections, plotly.js inline once (the page opens offline), the loader."""
    from plotly.offline import get_plotlyjs

    config = json.dumps(_CONFIG)
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>{_e(title)} — flexopt report</title>{_STYLE}"
        # plotly.js inline, once: the page opens offline
        f"<script type='text/javascript'>{get_plotlyjs()}</script></head><body>"
        + "\n".join(parts)
        + (_LOADER % config)
        + "</body></html>\n"
    )


# --------------------------------------------------------------------------------------------
# The page of an evaluate folder: one design


#: The sections of an evaluate folder's report.html, in order (no design exploration: one design).
EVALUATE_SECTIONS = ("verdict", "summary", "response", "part-3d")

#: The 3D view of an evaluate folder rebuilds the design (the kind's detail, as ``flexopt export``
#: does); it is made only when the evaluation itself solved within this time (s), so the page
#: never doubles a long solve (a SEA spring with its 3D check). Above it the page says how to get
#: the part instead.
PART_BUDGET_S = 5.0


@dataclass(frozen=True)
class EvaluateHtmlData:
    """What an evaluate folder's report.html shows.

    Attributes
    ----------
    study_name, kind : the study's name and kind.
    table : dict of str to (n,) array — the response (response.csv).
    plot : the kind's plot spec (columns, target, allowable; see :mod:`pipeline.plot_targets`).
    summary : scalar results; ``headline`` the keys worth a row (all when empty).
    verdicts : the design against the study's requirements.
    record : evaluation.json as far as it is written (solve time, convergence, message).
    part : the design's detail carrying its outline and height (None: no 3D view).
    part_note : why there is no 3D view, when ``part`` is None.
    """

    study_name: str
    kind: str
    table: Mapping[str, Any]
    plot: Mapping[str, Any]
    summary: Mapping[str, Any] = field(default_factory=dict)
    headline: Sequence[str] = ()
    verdicts: Sequence[Verdict] = ()
    record: Mapping[str, Any] = field(default_factory=dict)
    part: DesignDetail | None = None
    part_note: str | None = None
    #: evaluation.json's robustness record (default: ``record['robustness']``)
    robustness: Mapping[str, Any] | None = None
    #: the kind's files (``response_<case>.csv`` of each load case: every case is drawn)
    files: Mapping[str, bytes] = field(default_factory=dict)
    #: the evaluation's stress field (``DesignResult.field_map``), drawn on the deformed part
    #: even when the part is not rebuilt
    field_map: Mapping[str, Any] | None = None
    #: the design's fatigue, creep hold and contact (pipeline.durability_report); empty: none
    durability: Mapping[str, Any] = field(default_factory=dict)


def render_evaluate_html(data: EvaluateHtmlData) -> str:
    """The text of an evaluate folder's report.html: the verdict, the summary, the response with
    its target and the part in 3D (one file, plotly.js inline, no link to the network)."""
    figures = _Figures()
    record = data.record
    verdicts = list(data.verdicts)
    word = overall(verdicts)
    robust = data.robustness or record.get("robustness")
    ids = _with_durability(_with_robustness(EVALUATE_SECTIONS, robust), data.durability)
    nav = " ".join(f'<a href="#{s}">{_e(s.replace("-", " "))}</a>' for s in ids)
    solve = _float(record.get("solve_time_s"))
    converged = record.get("converged")
    parts = [
        f"<h1>{_e(data.study_name)} — flexopt evaluate</h1>"
        f"<p>Study kind <code>{_e(data.kind)}</code>; one design solved"
        + (f" in {solve:.3g} s" if solve is not None else "")
        + (
            ""
            if converged is None
            else ("; every row converged" if converged else "; <b>not every row converged</b>")
        )
        + (f" ({_e(record.get('message'))})" if record.get("message") else "")
        + ". The numbers are in <a href='response.csv'>response.csv</a> and "
        f"<a href='evaluation.json'>evaluation.json</a>.</p><nav>{nav}</nav>"
    ]
    cls = "met" if word == "MET" else "notmet"
    body = (
        f'<p><span class="{cls}">{_e(word)}</span> — {sum(v.met for v in verdicts)} of '
        f"{len(verdicts)} requirements met by this design.</p>"
    )
    if verdicts:
        body += _table(
            ["requirement", "value", "bound", "margin", "verdict"], verdict_rows(verdicts)
        )
    else:
        body += "<p>No requirement was stated, so nothing is claimed.</p>"
    parts.append(_section("verdict", "Verdict", body))

    keys = [k for k in (data.headline or data.summary) if k in data.summary]
    rows = [[labels.label(k), k, _summary_value(data.summary[k])] for k in keys]
    body = (
        _table(["quantity", "name", "value"], rows, "num")
        if rows
        else "<p>The kind gives no summary.</p>"
    )
    parts.append(_section("summary", "Summary", body))

    detail = DesignDetail(Evaluation(np.zeros(0), np.zeros(0), np.zeros(0)), dict(data.table),
                          dict(data.plot), files=dict(data.files))  # fmt: skip
    parts.append(
        _section(
            "response",
            "Response of the design",
            _response_section(detail, figures, "this design", verdicts),
        )
    )
    if data.durability:
        parts.append(_durability_section(data.durability))
    if robust:
        parts.append(_robustness_section(robust, data.table, data.plot, figures, "this design"))
    parts.append(
        _section(
            "part-3d",
            "The part in 3D",
            _part_section(data.part, figures, "evaluated", data.part_note, None, data.field_map),
        )
    )
    return _page(data.study_name, parts)


def _summary_value(value: Any) -> Any:
    """A summary value for a table cell: numbers as they are, lists and mappings short."""
    if isinstance(value, Mapping):
        return ", ".join(f"{k}: {v}" for k, v in list(value.items())[:6])
    if isinstance(value, list | tuple):
        return ", ".join(f"{v:.4g}" if isinstance(v, float) else str(v) for v in value[:8])
    return value


def evaluate_part(study: Any, solve_time_s: float | None) -> tuple[DesignDetail | None, str]:
    """The evaluated design's detail (its outline and height, for the 3D view), rebuilt as
    ``flexopt export`` of an evaluate folder rebuilds it, or None and why not.

    Only when the kind is optimisable (it has a problem with a ``detail``) and the evaluation
    solved within :data:`PART_BUDGET_S`; never raises.
    """
    from flexopt.pipeline.studies import get_kind

    hint = "flexopt export of this folder writes the part as STL, DXF or STEP"
    try:
        kind = get_kind(study.kind)
        if kind.problem is None:
            return None, "the study kind builds no part (it is not optimised)"
        if solve_time_s is not None and solve_time_s > PART_BUDGET_S:
            return None, (
                f"the design took {solve_time_s:.3g} s to solve, and the 3D view would solve it "
                f"again (more than {PART_BUDGET_S:g} s); {hint}"
            )
        from flexopt.pipeline.problems import nominal_design

        problem = kind.problem(study)
        detail = problem.detail(nominal_design(problem, study))
    except Exception as exc:  # the page must not cost the evaluation
        return None, f"the part could not be rebuilt: {type(exc).__name__}: {exc}"
    if detail.outline is None or not detail.height_mm:
        return None, "the study kind gives no outline and height for this design"
    return detail, ""


def evaluate_html(
    study: Any, result: Any, record: Mapping[str, Any], evaluation_wall_s: float | None = None
) -> str | None:
    """report.html of ``flexopt evaluate`` (None, with a warning logged, when it fails: the
    folder's other files are what the evaluation promised). ``evaluation_wall_s``: what the
    whole evaluation took, s (the part is rebuilt only when that is within the budget)."""
    import logging

    from flexopt.pipeline.durability_report import durability_record

    try:
        if getattr(result, "outline", None) is not None and getattr(result, "height_mm", None):
            part, why = result, ""  # the one result per design carries its part: not solved again
        else:
            costs = [_float(record.get("solve_time_s")), evaluation_wall_s]
            known = [c for c in costs if c is not None]
            part, why = evaluate_part(study, max(known) if known else None)
        return render_evaluate_html(
            EvaluateHtmlData(
                study.name,
                study.kind,
                result.table,
                result.plot,
                result.summary,
                tuple(result.headline),
                tuple(result.verdicts),
                record,
                part,
                why or None,
                files=dict(getattr(result, "files", None) or {}),
                field_map=getattr(result, "field_map", None),
                durability=durability_record(study, result),
            )
        )
    except Exception as exc:
        logging.getLogger(__name__).warning(
            "report.html not written: %s: %s", type(exc).__name__, exc
        )
        return None


def _part_section(
    detail: DesignDetail | None,
    figures: _Figures,
    whose: str,
    why: str | None = None,
    stl: str | None = "best.stl",
    field_map: Mapping[str, Any] | None = None,
) -> str:
    """The rotatable 3D view of a design's part (its outline extruded), or why there is none;
    ``stl`` the file of the run folder that holds it (None: ``flexopt export`` writes it). Below
    it the stress on the deformed part (:func:`_stress_block`) of ``field_map``, by default the
    detail's."""
    mesh = None
    why = why or "the study kind gives no outline and height for this design"
    if detail is not None:
        try:
            mesh = _part_mesh(detail)
        except Exception as exc:  # a part that cannot be extruded must not cost the page
            why = f"the part could not be built: {type(exc).__name__}: {exc}"
    stress = _stress_block(field_map or getattr(detail, "field_map", None), figures, whose)
    if mesh is None:
        return f"<p>No 3D view: {_e(why)}.</p>" + stress
    v, _ = mesh
    size = v.max(axis=0) - v.min(axis=0)
    return (
        f"<p class='note'>{len(mesh[1])} triangles, size "
        + " × ".join(f"{s:.4g}" for s in size)
        + (
            f" mm (the extruded outline as in <a href='{stl}'>{stl}</a>).</p>"
            if stl
            else " mm (the extruded outline; <code>flexopt export</code> of this folder writes "
            "it as STL, DXF or STEP).</p>"
        )
        + figures.embed(_part_fig(*mesh, whose), "part-3d")
        + stress
    )


def _section(sid: str, title: str, body: str) -> str:
    return f'<section id="{sid}"><h2>{_e(title)}</h2>{body}</section>'


#: Columns of a response table that are bookkeeping, not responses to draw.
_BOOKKEEPING = frozenset({"step", "row", "index", "converged", "stable", "case"})
#: Keys of a plot spec that describe the axes and the stress line, not a target: what a load
#: case other than the first keeps (the target band of the spec was measured on the first).
_AXIS_KEYS = ("x_label", "y_label", "stress_label", "allowable_MPa", "allowable_label")


def _csv_table(data: bytes) -> dict[str, np.ndarray]:
    """A response CSV written by :func:`pipeline.runfolder.table_to_csv` as columns: numbers
    (empty and ``nan`` as NaN), ``true``/``false`` as booleans; a column of text is left out."""
    import csv
    import io

    rows = list(csv.reader(io.StringIO(data.decode("utf-8", errors="replace"), newline="")))
    if len(rows) < 2:
        return {}
    header, body = rows[0], [r for r in rows[1:] if len(r) == len(rows[0])]
    table: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        cells = [r[j] for r in body]
        if cells and all(c in ("true", "false") for c in cells):
            table[name] = np.array([c == "true" for c in cells], dtype=bool)
            continue
        try:
            table[name] = np.array([float(c) if c else math.nan for c in cells], dtype=float)
        except ValueError:
            continue
    return table


def case_tables(detail: DesignDetail) -> list[tuple[str | None, dict[str, Any]]]:
    """The response of every load case of a design: ``[(case, table), ...]``.

    A kind with several load cases gives its first case as ``detail.table`` and each case as a
    file ``response_<case>.csv`` of ``detail.files`` (the mechanism kind), or stacks them in
    ``detail.table`` with a ``case`` column; either is split here. One case: ``[(None, table)]``.
    """
    table = dict(detail.table)
    if "case" in table:
        column = np.asarray(table["case"]).astype(str)
        cases = list(dict.fromkeys(column.tolist()))
        if len(cases) > 1:
            return [
                (c, {k: np.asarray(v)[column == c] for k, v in table.items() if k != "case"})
                for c in cases
            ]
    found = []
    for name, data in (detail.files or {}).items():
        match = re.fullmatch(r"response_(.+)\.csv", name)
        if match and isinstance(data, bytes | bytearray):
            parsed = _csv_table(bytes(data))
            if parsed:
                found.append((match.group(1), parsed))
    if len(found) > 1:
        return found  # type: ignore[return-value]
    return [(None, table)]


def _column_like(table: Mapping[str, Any], given: str, prefix: str, but: str = "") -> str | None:
    """``given`` when the table has it, else its first column starting with ``prefix`` (and not
    ``but``): a load case driven otherwise names its drive column by its own unit."""
    if given in table:
        return given
    for name in table:
        if name.startswith(prefix) and not (but and name.startswith(but)):
            return name
    return None


def stress_limit(
    verdicts: Sequence[Verdict], case: str | None = None
) -> tuple[float, Verdict] | None:
    """The allowable stress the verdict uses (MPa) and its verdict: the tightest ``<=`` bound of
    a stress requirement (with ``case``: also those of ``case.``-prefixed quantities), or None."""
    found: tuple[float, Verdict] | None = None
    for v in verdicts:
        q = v.quantity or ""
        if v.unit != "MPa" or "stress" not in q or not v.bound.lstrip().startswith("<="):
            continue
        if "." in q and (case is None or not q.startswith(f"{case}.")):
            continue  # another load case's (quantities of several cases carry "case.")
        limit = v.value + v.margin if math.isfinite(v.value + v.margin) else None
        if limit is None:
            match = re.match(r"\s*<=\s*([-+0-9.eE]+)", v.bound)
            limit = _float(match.group(1)) if match else None
        if limit is not None and (found is None or limit < found[0]):
            found = (limit, v)
    return found


def _outputs_fig(
    table: Mapping[str, Any], x: str, columns: Sequence[str], unit: str, title: str,
    xlabel: str,
) -> Any:  # fmt: skip
    """Outputs of one unit against x: one curve each (converged rows; unstable rows open)."""

    xs = np.asarray(table[x], dtype=float)
    n = len(xs)
    converged = np.asarray(table.get("converged", np.ones(n, bool)), dtype=bool)
    stable = np.asarray(table.get("stable", np.ones(n, bool)), dtype=bool)
    fig = fj.Figure()
    for column in columns:
        ys = np.asarray(table[column], dtype=float)
        ys = np.where(converged & np.isfinite(ys), ys, np.nan)
        fig.add_trace(
            fj.Scatter(
                x=xs.tolist(),
                y=_plain(ys),
                mode="lines+markers",
                name=labels.words(column),
                marker={
                    "size": 5,
                    "symbol": ["circle" if s else "circle-open" for s in stable.tolist()],
                },
            )
        )
    ylabel = f"{'value' if len(columns) > 1 else labels.words(columns[0])}" + (
        f" ({unit})" if unit else " (–)"
    )
    fig.update_layout(
        _layout(title, height=400, xaxis=_axis(xlabel), yaxis=_axis(ylabel),
                legend={"orientation": "h", "y": -0.25})
    )  # fmt: skip
    return fig


def _response_section(
    detail: DesignDetail | None,
    figures: _Figures,
    whose: str = "best design",
    verdicts: Sequence[Verdict] = (),
) -> str:
    """The response of every load case (the kind's response and stress, with the target and
    the allowable the verdict uses) and every other output of the table, by unit."""
    if detail is None or not detail.table:
        return f"<p>No response: the {whose}'s detail failed or the kind gives no table.</p>"
    spec = plot_spec(detail.plot)
    cases = case_tables(detail)
    several = len(cases) > 1
    body = (
        f"<p class='note'>{len(cases)} load cases: "
        + ", ".join(f"<code>{_e(c)}</code>" for c, _ in cases)
        + ".</p>"
        if several
        else ""
    )
    for k, (case, table) in enumerate(cases):
        here = dict(spec) if k == 0 else {key: spec[key] for key in _AXIS_KEYS if key in spec}
        x = _column_like(table, spec["x"], "drive_", "drive_reaction_")
        y = _column_like(table, spec["y"], "drive_reaction_")
        stress = spec["stress"]
        suffix = f"-{re.sub(r'[^A-Za-z0-9_-]', '_', case)}" if several and case else ""
        tag = f"load case {case}: " if several else ""
        whose_here = f"{whose}, load case {case}" if several else whose
        if several:
            body += f"<h3>Load case <code>{_e(case)}</code></h3>"
        if x is None:
            body += f"<p>No response plot: the table has no column '{_e(spec.get('x'))}'.</p>"
            continue
        here["x"] = x
        limit = stress_limit(verdicts, case if several else None)
        drawn = {x}
        for column, kind, name in ((y, "response", "response"),
                                   (stress, "stress", "response-stress")):  # fmt: skip
            if column is None or column not in table:
                continue
            fig, target = _response_fig(here, table, column, kind, whose_here, limit)
            curves = labels.siblings(table, column)
            drawn.update(curves)
            body += (
                f"<p class='note'>{_e(tag)}{len(curves)} curve{'s' if len(curves) > 1 else ''}; "
                f"{_e(target)}.</p>" + figures.embed(fig, name + suffix)
            )
        # every other output of the case (a mechanism's user outputs), one figure per unit
        by_unit: dict[str, list[str]] = {}
        for column, values in table.items():
            if column in drawn or column in _BOOKKEEPING or column.startswith("target_"):
                continue
            arr = np.asarray(values)
            if arr.dtype.kind not in "fiu" or not np.isfinite(arr.astype(float)).any():
                continue
            by_unit.setdefault(labels.unit_of(column) or "", []).append(column)
        xlabel = labels.label(x, spec.get("x_label"))
        for j, (unit, columns) in enumerate(by_unit.items()):
            what = (
                f"Outputs in {unit or 'no unit'}" if len(columns) > 1 else labels.words(columns[0])
            )
            title = f"{what} against {_no_unit(xlabel)} ({whose_here})"
            body += figures.embed(
                _outputs_fig(table, x, columns, unit, title, xlabel),
                f"outputs{suffix}-{j + 1}",
            )
    return body or "<p>The response table has none of the plotted columns.</p>"


# --------------------------------------------------------------------------------------------
# Robustness (docs/robustness.md): the band of the response over the samples, the shares

#: The id of the robustness section: after the response, only when there is a record.
ROBUSTNESS_SECTION = "robustness"


def _with_robustness(sections: Sequence[str], record: Any) -> tuple[str, ...]:
    ids = tuple(sections)
    if not record or "response" not in ids:
        return ids
    i = ids.index("response") + 1
    return (*ids[:i], ROBUSTNESS_SECTION, *ids[i:])


def _robustness_section(
    record: Mapping[str, Any],
    table: Mapping[str, Any],
    spec: Mapping[str, Any],
    figures: _Figures,
    whose: str,
) -> str:
    """The response's band (min-max over the samples, shaded) around the nominal curve, and
    per requirement its nominal margin, share of samples MET and robust verdict."""
    from flexopt.pipeline.robustness import scatter_text

    required = float(record.get("share_percent_required", 100.0))
    method = record.get("method")
    how = f"Monte Carlo, seed {record.get('seed')}" if method == "monte_carlo" else "corners"
    body = (
        f"<p>{_e(record.get('n_samples'))} samples ({_e(how)}, the nominal included) of "
        f"{_e(scatter_text(record))}; a requirement is MET robustly when at least "
        f"{required:g} % of the samples meet it. Perturbed: "
        f"{_e('; '.join(record.get('perturbed') or ['nothing']))}.</p>"
    )

    def margin(value: Any, unit: str) -> str:
        return "n/a" if value is None else f"{value:+.4g}" + (f" {unit}" if unit else "")

    rows = [
        [
            r["name"],
            margin(r.get("nominal_margin"), r.get("unit", "")),
            f"{r['share_percent']:.1f} %",
            "MET" if r["met_robustly"] else "NOT MET",
        ]
        for r in record.get("requirements") or []
    ]
    header = ["requirement", "nominal margin", "share of samples MET",
              f"robust verdict (at {required:g} %)"]  # fmt: skip
    body += _table(header, rows) if rows else "<p>No requirement to judge.</p>"
    from flexopt.pipeline.robustness import fidelity_text, robust_tables

    if record.get("fidelity"):  # how the samples were judged on the verdict's figures (#22)
        body += f"<p>{_e(fidelity_text(record['fidelity']))}.</p>"

    for title, head, cells, note in robust_tables(record):
        body += f"<h3>{_e(title)}</h3>" + _table(head, cells) + f"<p>{_e(note)}</p>"
    band = record.get("band") or {}
    spec = plot_spec(spec)
    x = spec["x"]
    y = next((c for c in band if c != x), None)
    if y is None:
        return _section(
            ROBUSTNESS_SECTION,
            "Robustness",
            body + "<p class='note'>No band in this record (run.json keeps none: it is in "
            "best.json and robustness.png).</p>",
        )
    low = np.array([np.nan if v is None else v for v in band[y]["low"]], dtype=float)
    high = np.array([np.nan if v is None else v for v in band[y]["high"]], dtype=float)
    xs = np.asarray(table[x], dtype=float) if x in table else None
    if xs is None or len(xs) != len(low):
        xs = np.array([np.nan if v is None else v for v in band[x]["low"]], dtype=float)
    ok = np.isfinite(xs) & np.isfinite(low) & np.isfinite(high)
    fig = fj.Figure()
    fig.add_trace(
        fj.Scatter(
            x=[*xs[ok].tolist(), *xs[ok][::-1].tolist()],
            y=[*low[ok].tolist(), *high[ok][::-1].tolist()],
            fill="toself",
            mode="lines",
            line={"width": 0},
            fillcolor="rgba(255,127,14,0.25)",
            name=f"band over the {record.get('n_samples')} samples (min-max)",
        )
    )
    if y in table and len(table[y]) == len(xs):
        fig.add_trace(
            fj.Scatter(
                x=xs.tolist(),
                y=_plain(np.asarray(table[y], dtype=float)),
                mode="lines+markers",
                name="nominal",
                marker={"size": 4},
                line={"color": "#1f77b4"},
            )
        )
    xlabel = labels.label(x, spec.get("x_label"))
    ylabel = labels.label(y)
    fig.update_layout(
        _layout(
            f"{_no_unit(ylabel)} under scatter ({whose})",
            height=420,
            xaxis=_axis(xlabel),
            yaxis=_axis(ylabel),
            legend={"orientation": "h", "y": -0.22},
        )
    )
    return _section(ROBUSTNESS_SECTION, "Robustness", body + figures.embed(fig, "robustness"))


# --------------------------------------------------------------------------------------------
# Durability: fatigue, creep hold and contact (pipeline.durability_report)

#: The element id of the durability section (only when the study has a duty_cycle, hold or stops).
DURABILITY_SECTION = "durability"


def _with_durability(sections: Sequence[str], record: Mapping[str, Any]) -> tuple[str, ...]:
    """The section ids with ``durability`` after the response, when there is a record."""
    ids = tuple(sections)
    if not record or "response" not in ids:
        return ids
    at = ids.index("response") + 1
    return (*ids[:at], DURABILITY_SECTION, *ids[at:])


def _durability_section(record: Mapping[str, Any]) -> str:
    from flexopt.pipeline.durability_report import durability_html

    intro = (
        "<p class='note'>Fatigue, creep and contact of the design under the study's "
        "duty_cycle, hold and stops (docs/durability.md); the same records are in "
        "best.json's <code>durability</code> and the API's <code>durability</code>.</p>"
    )
    return _section(DURABILITY_SECTION, "Durability", intro + durability_html(record))
