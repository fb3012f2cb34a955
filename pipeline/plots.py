"""Plots for run folders (matplotlib, off-screen: no pyplot, no display needed)."""

from __future__ import annotations

import io
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from flexopt.pipeline import labels as _labels

if TYPE_CHECKING:  # matplotlib is imported when the first figure is made (~0.3 s)
    from matplotlib.figure import Figure

__all__ = [
    "cases_figure",
    "collision_impact_png",
    "collision_sweeps_png",
    "plot_cases",
    "quantity_name",
    "plot_convergence",
    "curve_figure",
    "plot_curve",
    "plot_field",
    "plot_field_deformed",
    "deformation_scale",
    "plot_front",
    "plot_taguchi",
    "plot_response",
    "response_figure",
    "plot_shapes",
    "plot_stress",
]


def _new_figure(**kwargs: Any) -> Figure:
    """An off-screen figure with its Agg canvas. matplotlib is imported here, not with this
    module: a run imports this module at its start but makes its plots at the end, in a forked
    child (pipeline/fork.py), so the import stays off the run's critical path."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def _png(fig: Figure) -> bytes:
    return _png_at(fig, 120)


def _png_at(fig: Figure, dpi: int) -> bytes:
    """The figure (with its Agg canvas, :func:`_new_figure`) as PNG bytes at ``dpi``: what
    ``fig.savefig(buffer, format="png", dpi=dpi)`` writes, byte for byte, laid out once.

    Why: savefig draws a figure that has a layout engine (every plot here: constrained
    layout) twice, a first draw only to lay it out and then the draw it saves, which lays it
    out again; constrained layout is most of a plot's CPU. The Agg canvas's ``print_png`` is
    that second draw alone (the figure's own face and edge colours, the same metadata): ~18 %
    less CPU a plot, the same file (tests/pipeline/test_plots_png.py compares the bytes).
    """
    buffer = io.BytesIO()
    fig.set_dpi(dpi)
    fig.canvas.print_png(buffer)
    return buffer.getvalue()


def _converged(table: Mapping[str, np.ndarray], x: str) -> np.ndarray:
    n = len(np.asarray(table[x]))
    return np.asarray(table.get("converged", np.ones(n, bool)), dtype=bool)


def _label(name: str, given: str | None) -> str:
    # words with the unit from the one table of labels (pipeline/labels.py), not the raw name
    return _labels.label(name, given)


#: Unit suffixes of column names (``force_N``, ``time_ms``), dropped to name the quantity.
_UNITS = {"mm", "m", "deg", "rad", "s", "ms", "g", "kg", "pct", "percent"}


def quantity_name(column: str) -> str:
    """The quantity a column names, without its unit: ``contact_force_N`` → ``contact force``,
    ``stiffness_N_per_mm`` → ``stiffness``, ``torque_Nm_1`` → ``torque``."""
    parts = column.split("_")
    for i, part in enumerate(parts[1:], 1):
        if part in _UNITS or any(ch.isupper() for ch in part):
            return " ".join(parts[:i])
    return " ".join(parts)


def plot_response(
    table: Mapping[str, np.ndarray],
    x: str = "displacement_mm",
    left: str = "force_N",
    right: str | None = "peak_stress_MPa",
    allowable_MPa: float | None = None,
    title: str = "",
    labels: Mapping[str, str] | None = None,
) -> bytes:
    """:func:`response_figure` as a PNG file (bytes)."""
    return _png(response_figure(table, x, left, right, allowable_MPa, title, labels))


def _draw_curves(ax, table, x: str, column: str, ok: np.ndarray, colour: str) -> list[str]:
    """``column`` and its siblings (:func:`pipeline.labels.siblings`: the other curves of a
    multi-curve kind, a reference or closed form) against ``x``; returns the columns drawn."""
    xs = np.asarray(table[x], dtype=float)
    curves = _labels.siblings(table, column)
    style = "o-" if ok.sum() <= 80 else "-"  # markers hide a curve of hundreds of rows
    for k, c in enumerate(curves):
        ys = np.asarray(table[c], dtype=float)
        good = ok & np.isfinite(ys)
        sparse = good.sum() < 0.5 * ok.sum()  # a check at a few rows (plane stress): markers
        ax.plot(
            xs[good],
            ys[good],
            "s" if sparse else style,
            ms=3 if not sparse else 5,
            color=colour if k == 0 and len(curves) == 1 else None,
            label=_labels.words(c),  # shown when there is a legend (curves, a target)
        )
    return curves


def _draw_target(ax, overlay) -> None:
    """A target curve (dashed) with its band (shaded), or a range (shaded), in the legend."""
    if overlay.lower is not None and overlay.upper is not None:
        ax.fill_between(
            overlay.x,
            overlay.lower,
            overlay.upper,
            color="tab:green",
            alpha=0.2,
            label=overlay.label if overlay.y is None else None,
        )
    if overlay.y is not None:
        ax.plot(overlay.x, overlay.y, "--", color="tab:green", lw=1.4, label=overlay.label)


def response_figure(
    table: Mapping[str, np.ndarray],
    x: str = "displacement_mm",
    left: str = "force_N",
    right: str | None = "peak_stress_MPa",
    allowable_MPa: float | None = None,
    title: str = "",
    labels: Mapping[str, str] | None = None,
) -> Figure:
    """The figure of :func:`plot_response`: ``left`` (a spec's ``y``) and ``right`` (its
    ``stress``) against ``x``, each with every curve of its quantity (the six torque curves of
    the leaf-spring joint, a reference, a closed form), the target of ``left``
    (:func:`pipeline.plot_targets.target_overlay` of the spec) and the allowable line on
    ``right``.

    Only converged rows are drawn; a title note says when some are missing.

    Parameters
    ----------
    table : mapping of str to (n,) array
        Response columns, including ``x``, ``left``, ``right`` and ``converged``.
    allowable_MPa : float, MPa, optional
        Drawn as a dashed horizontal line on the right panel.
    labels : mapping, optional
        The kind's plot dict (read through :func:`pipeline.plot_targets.plot_spec`): its target
        keys (``target``, ``target_curve``, ``target_range``, ``tolerance``, ... see
        :mod:`pipeline.plot_targets`) and words: ``y_title`` and ``stress_title`` (panel titles,
        default "<left quantity> – <x quantity>", e.g. "torque – rotation"), ``x_label``,
        ``y_label``, ``stress_label`` (axes) and ``allowable_label`` (legend of the line,
        default "yield <value> MPa" for a stress column, "allowable <value> MPa" otherwise) or
        ``allowable_text`` (the whole legend: the verdict's bound).

    Returns
    -------
    matplotlib.figure.Figure
        Not attached to pyplot (a notebook shows it as the cell's value).
    """
    from flexopt.pipeline.plot_targets import plot_spec, target_overlay

    labels = plot_spec(labels)
    ok = np.asarray(table.get("converged", np.ones(len(table[x]), bool)), dtype=bool)
    two = right is not None and right in table
    fig = _new_figure(figsize=(10 if two else 5.5, 4), layout="constrained")
    axes = fig.subplots(1, 2) if two else [fig.subplots(1, 1)]
    x_label = labels.get("x_label") or _labels.label(x)
    ax_f = axes[0]
    curves = _draw_curves(ax_f, table, x, left, ok, "tab:blue")
    if labels.get("y_label") and len(curves) == 1:  # the kind's words name the curve too
        ax_f.lines[0].set_label(_labels.strip_unit(labels["y_label"]))
    overlay = target_overlay({**labels, "x": x, "y": left}, table, left, _labels.unit_of(left))
    if overlay is not None:
        _draw_target(ax_f, overlay)
    ax_f.set_xlabel(x_label)
    ax_f.set_ylabel(labels.get("y_label") or _curves_label(left, curves))
    ax_f.set_title(labels.get("y_title") or f"{quantity_name(left)} – {quantity_name(x)}")
    if len(curves) > 1 or overlay is not None:
        ax_f.legend(loc="best", fontsize="small")
    if two:
        assert right is not None
        ax_s = axes[1]
        stress_curves = _draw_curves(ax_s, table, x, right, ok, "tab:red")
        if allowable_MPa is not None:
            default = "yield" if "stress" in right else "allowable"
            word = labels.get("allowable_label") or default
            text = labels.get("allowable_text") or f"{word} {allowable_MPa:g} MPa"
            ax_s.axhline(allowable_MPa, ls="--", color="k", lw=1, label=text)
        if allowable_MPa is not None or len(stress_curves) > 1:
            ax_s.legend(loc="best", fontsize="small")
        ax_s.set_xlabel(x_label)
        ax_s.set_ylabel(labels.get("stress_label") or _curves_label(right, stress_curves))
        ax_s.set_title(labels.get("stress_title") or f"{quantity_name(right)} – {quantity_name(x)}")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    note = "" if ok.all() else f"  ({int((~ok).sum())} of {ok.size} rows not converged)"
    if title or note:
        fig.suptitle(title + note)
    return fig


def _curves_label(column: str, curves: list[str]) -> str:
    return _labels.curves_label(column, curves)


def plot_curve(
    table: Mapping[str, np.ndarray],
    x: str = "displacement_mm",
    y: str = "force_N",
    target: float | None = None,
    tolerance: float | None = None,
    band_x: tuple[float, float] | None = None,
    x_label: str | None = None,
    y_label: str | None = None,
    title: str = "",
    spec: Mapping[str, object] | None = None,
) -> bytes:
    """One response curve (force against displacement), with the target and its tolerance band.
    The PNG of :func:`curve_figure` (see there)."""
    return _png(curve_figure(table, x, y, target, tolerance, band_x, x_label, y_label, title, spec))


def curve_figure(
    table: Mapping[str, np.ndarray],
    x: str = "displacement_mm",
    y: str = "force_N",
    target: float | None = None,
    tolerance: float | None = None,
    band_x: tuple[float, float] | None = None,
    x_label: str | None = None,
    y_label: str | None = None,
    title: str = "",
    spec: Mapping[str, object] | None = None,
) -> Figure:
    """The figure of :func:`plot_curve`: ``y`` and its sibling curves against ``x``, with the
    target and its band.

    Parameters
    ----------
    table : mapping of str to (n,) array
        Response columns including ``x`` and ``y`` (and ``converged``, when some rows are not).
    target : float, optional
        Target value of ``y`` (same unit), drawn as a dashed line.
    tolerance : float, optional
        Half-width of the band around ``target`` (same unit as ``y``), shaded.
    band_x : (float, float), optional
        Range of ``x`` over which the target applies (default: the whole curve).
    spec : mapping, optional
        The kind's plot dict; its target (a constant, a target curve or a range, see
        :mod:`pipeline.plot_targets`) is drawn when ``target`` is not given.
    """
    from flexopt.pipeline.plot_targets import plot_spec, target_overlay

    ok = _converged(table, x)
    xs = np.asarray(table[x], dtype=float)
    fig = _new_figure(figsize=(6.4, 4.2), layout="constrained")
    ax = fig.subplots()
    curves = _draw_curves(ax, table, x, y, ok, "tab:blue")
    if y_label and len(curves) == 1:  # the kind's words name the curve too
        ax.lines[0].set_label(_labels.strip_unit(y_label))
    own: dict[str, object] = {"x": x, "y": y}
    if target is not None:
        own.update(target=target, tolerance=tolerance, band_x=band_x)
    elif spec is not None:
        own = {**plot_spec(spec), **own}
    overlay = target_overlay(own, table, y, _labels.unit_of(y)) if xs.size else None
    if overlay is not None:
        _draw_target(ax, overlay)
    if overlay is not None or len(curves) > 1:
        ax.legend(loc="best", fontsize="small")
    ax.set_xlabel(_label(x, x_label))
    ax.set_ylabel(y_label or _curves_label(y, curves))
    ax.grid(True, alpha=0.3)
    note = "" if ok.all() else f"  ({int((~ok).sum())} of {ok.size} rows not converged)"
    if title or note:
        ax.set_title(title + note)
    return fig


def plot_stress(
    table: Mapping[str, np.ndarray],
    x: str = "displacement_mm",
    stress: str = "peak_stress_MPa",
    allowable_MPa: float | None = None,
    x_label: str | None = None,
    title: str = "",
    allowable_label: str | None = None,
) -> bytes:
    """Peak stress along the stroke, with the allowable stress as a dashed line.

    Parameters
    ----------
    table : mapping of str to (n,) array
        Response columns including ``x`` and ``stress`` (MPa).
    allowable_MPa : float, MPa, optional
        The line: the allowable the verdict uses (:func:`pipeline.responses.stress_allowable`).
    allowable_label : str, optional
        Its legend (default ``allowable <value> MPa``).

    Returns
    -------
    bytes
        The PNG file.
    """
    ok = _converged(table, x)
    fig = _new_figure(figsize=(6.4, 4.2), layout="constrained")
    ax = fig.subplots()
    curves = _draw_curves(ax, table, x, stress, ok, "tab:red")
    if allowable_MPa is not None:
        ax.axhline(
            allowable_MPa,
            ls="--",
            color="k",
            lw=1,
            label=allowable_label or f"allowable {allowable_MPa:g} MPa",
        )
    if allowable_MPa is not None or len(curves) > 1:
        ax.legend(loc="best", fontsize="small")
    ax.set_xlabel(_label(x, x_label))
    ax.set_ylabel(_curves_label(stress, curves))
    ax.grid(True, alpha=0.3)
    if title:
        ax.set_title(title)
    return _png(fig)


#: What a row of :func:`cases_figure` shows: the kind's curve (with its target), the peak stress
#: (with the allowable the verdict uses) or the user's outputs, one row per unit.
CASE_ROWS = ("curve", "stress", "outputs")


def plot_cases(
    cases: Mapping[str, Any],
    rows: tuple[str, ...] = CASE_ROWS,
    allowables: Mapping[str, tuple[float, str] | None] | None = None,
    title: str = "",
) -> bytes:
    """:func:`cases_figure` as a PNG file (bytes)."""
    return _png(cases_figure(cases, rows, allowables, title))


def _unit_axis_label(unit: str, names: list[str]) -> str:
    shown = ", ".join(_labels.words(n, plain=True) for n in names)
    return f"{shown} ({unit or '–'})"


def cases_figure(
    cases: Mapping[str, Any],
    rows: tuple[str, ...] = CASE_ROWS,
    allowables: Mapping[str, tuple[float, str] | None] | None = None,
    title: str = "",
) -> Figure:
    """Every load case of a response side by side: one column per case, one row per quantity.

    Parameters
    ----------
    cases : mapping of case name to optimise.problem.CaseResponse
        :func:`pipeline.responses.case_responses` (a kind with one response: one case ``""``).
    rows : tuple of str
        ``curve`` (the kind's ``y`` against ``x`` with its target band), ``stress`` (the
        ``stress`` column with the allowable line) and ``outputs`` (the user's outputs, one row
        per unit: a ratio is not drawn on a force's axis). A row no case has is left out.
    allowables : mapping of case name to (MPa, label) or None
        The line on the stress row (:func:`pipeline.responses.stress_allowable`: the value the
        verdict uses).

    Returns
    -------
    matplotlib.figure.Figure
        Only converged rows are drawn; a stable row is a filled marker, an unstable one open.
    """
    from flexopt.pipeline.plot_targets import plot_spec, target_overlay
    from flexopt.pipeline.responses import output_units

    allowables = dict(allowables or {})
    specs = {name: plot_spec(c.plot) for name, c in cases.items()}
    units = output_units(cases) if "outputs" in rows else {}
    plan: list[tuple[str, str]] = []  # (row kind, unit of an outputs row)
    for row in rows:
        if row == "outputs":
            plan += [("outputs", unit) for unit in units]
        elif row == "curve" and any(
            specs[n]["x"] in c.table and specs[n]["y"] in c.table for n, c in cases.items()
        ):
            plan.append(("curve", ""))
        elif row == "stress" and any(specs[n]["stress"] in c.table for n, c in cases.items()):
            plan.append(("stress", ""))
    n_rows, n_cols = max(1, len(plan)), max(1, len(cases))
    fig = _new_figure(figsize=(5.2 * n_cols, 3.4 * n_rows + 0.6), layout="constrained")
    axes = fig.subplots(n_rows, n_cols, squeeze=False)
    for j, (name, case) in enumerate(cases.items()):
        table, spec = case.table, specs[name]
        x = spec["x"]
        if x not in table:
            continue
        ok = _converged(table, x)
        xs = np.asarray(table[x], dtype=float)
        stable = np.asarray(table.get("stable", np.ones(xs.size, bool)), dtype=bool)
        for i, (kind, unit) in enumerate(plan):
            ax = axes[i, j]
            ax.grid(True, alpha=0.3)
            ax.set_xlabel(_label(x, spec.get("x_label")), fontsize="small")
            if i == 0 and name:
                ax.set_title(f"load case {name}")
            if kind == "curve":
                y = spec["y"]
                if y not in table:
                    ax.set_axis_off()
                    continue
                curves = _draw_curves(ax, table, x, y, ok, "tab:blue")
                overlay = target_overlay({**spec, "x": x, "y": y}, table, y, _labels.unit_of(y))
                if overlay is not None:
                    _draw_target(ax, overlay)
                if overlay is not None or len(curves) > 1:
                    ax.legend(loc="best", fontsize="small")
                ax.set_ylabel(spec.get("y_label") or _curves_label(y, curves))
            elif kind == "stress":
                column = spec["stress"]
                if column not in table:
                    ax.set_axis_off()
                    continue
                _draw_curves(ax, table, x, column, ok, "tab:red")
                line = allowables.get(name)
                if line is not None:
                    ax.axhline(line[0], ls="--", color="k", lw=1, label=line[1])
                    ax.legend(loc="best", fontsize="small")
                ax.set_ylabel(_label(column, None))
            else:
                mine = [n for n in units[unit] if n in case.outputs and n in table]
                if not mine:
                    ax.set_axis_off()
                    none = f"no output in {unit or 'ratio'} in this case"
                    ax.text(0.5, 0.5, none, ha="center", va="center", transform=ax.transAxes,
                            color="0.5")  # fmt: skip
                    continue
                for k, column in enumerate(mine):
                    ys = np.asarray(table[column], dtype=float)
                    good = ok & np.isfinite(ys)
                    colour = f"C{k}"
                    ax.plot(xs[good], ys[good], "-", color=colour, lw=1.3,
                            label=_labels.words(column, plain=True))  # fmt: skip
                    ax.plot(xs[good & stable], ys[good & stable], "o", ms=3, color=colour)
                    ax.plot(xs[good & ~stable], ys[good & ~stable], "o", ms=3, mfc="none",
                            color=colour)  # fmt: skip
                    if spec.get("y") == column:  # the target band of a requirement on it
                        overlay = target_overlay({**spec, "x": x}, table, column, unit or None)
                        if overlay is not None:
                            _draw_target(ax, overlay)
                ax.legend(loc="best", fontsize="small")
                ax.set_ylabel(_unit_axis_label(unit, mine))
    unstable = any(
        not np.asarray(c.table.get("stable", [True]), dtype=bool).all() for c in cases.values()
    )
    note = "  (open markers: unstable rows)" if unstable and units else ""
    if title or note:
        fig.suptitle(title + note)
    return fig


def plot_convergence(
    generation: np.ndarray,
    best: np.ndarray,
    best_feasible: np.ndarray,
    feasible_fraction: np.ndarray,
    objective_names: tuple[str, ...],
    title: str = "",
) -> bytes:
    """Best objective(s) per generation and the fraction of feasible designs.

    Parameters
    ----------
    generation : (n_gen,) int
        Generation numbers (1-based).
    best : (n_gen, n_obj) float
        Objectives of the best design so far after each generation.
    best_feasible : (n_gen,) bool
        That design is feasible; generations without a feasible design are not drawn.
    feasible_fraction : (n_gen,) float in [0, 1]
        Share of the generation's designs that are feasible.
    objective_names : (n_obj,) str

    Returns
    -------
    bytes
        The PNG file.
    """
    generation = np.asarray(generation)
    best = np.asarray(best, dtype=float).reshape(len(generation), -1)
    ok = np.asarray(best_feasible, dtype=bool)
    n_obj = best.shape[1]
    fig = _new_figure(figsize=(6.4, 2.4 * (n_obj + 1)), layout="constrained")
    axes = fig.subplots(n_obj + 1, 1, sharex=True, squeeze=False)[:, 0]
    for k, ax in enumerate(axes[:n_obj]):
        values = np.where(ok, best[:, k], np.nan)
        ax.plot(generation, values, "o-", ms=3, color="tab:blue")
        finite = values[np.isfinite(values)]
        if finite.size and np.all(finite > 0) and finite.max() > 100 * finite.min():
            ax.set_yscale("log")
        if not ok.any():
            ax.text(0.5, 0.5, "no feasible design yet", transform=ax.transAxes, ha="center")
        ax.set_ylabel(f"best {_labels.label(objective_names[k])}")
        ax.grid(True, alpha=0.3)
    ax_f = axes[-1]
    ax_f.plot(
        generation, 100 * np.asarray(feasible_fraction, dtype=float), "s-", ms=3, color="tab:green"
    )
    ax_f.set_ylim(-5, 105)
    ax_f.set_ylabel("feasible designs (%)")
    ax_f.set_xlabel("generation")
    from matplotlib.ticker import MaxNLocator

    ax_f.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax_f.grid(True, alpha=0.3)
    if title:
        axes[0].set_title(title)
    return _png(fig)


def plot_shapes(
    shapes_mm: np.ndarray,
    values: np.ndarray | None = None,
    value_label: str = "",
    max_shapes: int = 6,
    title: str = "",
) -> bytes:
    """Deformed centrelines at several points of the stroke, undeformed first.

    Parameters
    ----------
    shapes_mm : (n_rows, n_nodes, 2) float, mm
        One centreline per response row.
    values : (n_rows,) float, optional
        The driven quantity of each row (e.g. displacement, mm), shown in the legend.
    value_label : str
        Name and unit of ``values``.
    max_shapes : int
        At most this many rows are drawn, evenly spread from the first to the last.

    Returns
    -------
    bytes
        The PNG file.
    """
    shapes = np.asarray(shapes_mm, dtype=float)
    if shapes.ndim != 3 or shapes.shape[2] != 2:
        raise ValueError(f"shapes_mm has shape {shapes.shape}; expected (n_rows, n_nodes, 2)")
    rows = np.unique(np.linspace(0, len(shapes) - 1, min(max_shapes, len(shapes))).round())
    fig = _new_figure(figsize=(6.4, 5.0), layout="constrained")
    ax = fig.subplots()
    import matplotlib

    colours = matplotlib.colormaps["viridis"](np.linspace(0, 0.9, len(rows)))
    for colour, row in zip(colours, rows.astype(int), strict=True):
        label = f"row {row}"
        if values is not None:
            value = float(np.asarray(values)[row])
            if value_label and " " not in value_label:  # a column name: words = value unit
                unit = _labels.unit_of(value_label)
                label = f"{_labels.words(value_label)} = {value:.3g}" + (f" {unit}" if unit else "")
            else:
                label = f"{value_label or 'value'} = {value:.3g}"
        ax.plot(shapes[row, :, 0], shapes[row, :, 1], "-", color=colour, lw=1.5, label=label)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    if title:
        ax.set_title(title)
    return _png(fig)


def plot_field(
    points_mm: np.ndarray,
    triangles: np.ndarray,
    values: np.ndarray,
    label: str = "von Mises stress (MPa)",
    limit: float | None = None,
    title: str = "",
) -> bytes:
    """A scalar field on a triangle mesh (e.g. the stress map of a plane-stress model).

    Parameters
    ----------
    points_mm : (n, 2) float, mm — mesh nodes.
    triangles : (m, 3) int — node indices.
    values : (n,) float — the field at the nodes (unit in ``label``).
    limit : float, optional — an allowable: the colour scale reaches at least it, and the nodes
        above it are outlined in red.

    Returns
    -------
    bytes
        The PNG file.
    """
    from matplotlib.tri import Triangulation

    p = np.asarray(points_mm, dtype=float)
    v = np.asarray(values, dtype=float)
    tri = Triangulation(p[:, 0], p[:, 1], np.asarray(triangles, dtype=int))
    fig = _new_figure(figsize=(6.8, 5.6), layout="constrained")
    ax = fig.subplots()
    vmax = max(float(np.nanmax(v)), limit or 0.0)
    cs = ax.tripcolor(tri, v, shading="gouraud", cmap="viridis", vmin=0.0, vmax=vmax)
    fig.colorbar(cs, ax=ax, label=label)
    i = int(np.nanargmax(v))
    ax.plot(p[i, 0], p[i, 1], "x", color="red", ms=9, label=f"peak {v[i]:.4g}")
    if limit is not None and np.any(v > limit):
        over = v > limit
        ax.plot(p[over, 0], p[over, 1], ".", color="red", ms=2, label=f"above {limit:g}")
    ax.legend(loc="upper right", fontsize="small")
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    if title:
        ax.set_title(title)
    return _png(fig)


#: Below this share of the part's size the largest displacement is magnified to be seen.
SMALL_DISPLACEMENT = 0.02
#: ... to about this share of the part's size (a round factor: 1, 2, 5 times a power of 10).
SHOWN_DISPLACEMENT = 0.1


def deformation_scale(points_mm: np.ndarray, displacement_mm: np.ndarray) -> float:
    """The factor a deformed mesh is drawn at: 1 (true scale) unless the largest displacement
    is under :data:`SMALL_DISPLACEMENT` of the part's size, then a round factor that makes it
    about :data:`SHOWN_DISPLACEMENT` of it.

    Parameters
    ----------
    points_mm : (n, 2) float, mm — the undeformed nodes.
    displacement_mm : (n, 2) float, mm — their displacement.
    """
    p = np.asarray(points_mm, dtype=float).reshape(-1, 2)
    u = np.asarray(displacement_mm, dtype=float).reshape(-1, 2)
    size = float(np.max(np.ptp(p, axis=0))) if len(p) else 0.0
    umax = float(np.nanmax(np.hypot(u[:, 0], u[:, 1]))) if len(u) else 0.0
    if not (size > 0 and np.isfinite(umax) and umax > 0) or umax >= SMALL_DISPLACEMENT * size:
        return 1.0
    raw = SHOWN_DISPLACEMENT * size / umax
    power = 10.0 ** np.floor(np.log10(raw))
    return float(max(m for m in (1.0, 2.0, 5.0) if m * power <= raw) * power)


def boundary_edges(triangles: np.ndarray) -> np.ndarray:
    """(k, 2) int: the edges of a triangle mesh (m, 3) that belong to one triangle only (its
    outline, holes included)."""
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    unique, count = np.unique(edges, axis=0, return_counts=True)
    return unique[count == 1]


def plot_field_deformed(
    points_mm: np.ndarray,
    triangles: np.ndarray,
    values: np.ndarray,
    displacement_mm: np.ndarray,
    label: str = "von Mises stress (MPa)",
    limit: float | None = None,
    title: str = "",
) -> bytes:
    """``stress_deformed.png``: a stress field's contours on the deformed mesh, the undeformed
    outline in grey behind it; true scale unless the displacement is too small to see
    (:func:`deformation_scale`), the scale in the title either way.

    Parameters
    ----------
    points_mm : (n, 2) float, mm — undeformed mesh nodes.
    triangles : (m, 3) int — node indices.
    values : (n,) float, MPa — the von Mises stress at the nodes (the unit in ``label``).
    displacement_mm : (n, 2) float, mm — the nodes' displacement in the same solve.
    limit : float, optional, MPa — the allowable: named in the colour bar's label and drawn on
        the bar as a red line; the colour scale reaches at least it.

    Returns
    -------
    bytes
        The PNG file.
    """
    from matplotlib.collections import LineCollection
    from matplotlib.tri import Triangulation

    p = np.asarray(points_mm, dtype=float).reshape(-1, 2)
    u = np.asarray(displacement_mm, dtype=float).reshape(-1, 2)
    v = np.asarray(values, dtype=float).reshape(-1)
    t = np.asarray(triangles, dtype=int).reshape(-1, 3)
    scale = deformation_scale(p, u)
    q = p + scale * u
    fig = _new_figure(figsize=(6.8, 5.6), layout="constrained")
    ax = fig.subplots()
    edges = boundary_edges(t)
    ax.add_collection(
        LineCollection(p[edges], colors="0.6", linewidths=0.8, label="undeformed", zorder=1)
    )
    vmax = max(float(np.nanmax(v)), limit or 0.0)
    cs = ax.tripcolor(
        Triangulation(q[:, 0], q[:, 1], t), v, shading="gouraud", cmap="viridis", vmin=0.0,
        vmax=vmax, zorder=2,
    )  # fmt: skip
    # two lines: a kind's label names its state and can be long
    bar_label = label if limit is None else f"{label}\nallowable {limit:g} MPa (red line)"
    bar = fig.colorbar(cs, ax=ax)
    bar.set_label(bar_label, fontsize="small")
    if limit is not None:
        bar.ax.axhline(limit, color="red", lw=2)
    i = int(np.nanargmax(v))
    ax.plot(q[i, 0], q[i, 1], "x", color="red", ms=9, label=f"peak {v[i]:.4g}", zorder=3)
    ax.legend(loc="upper right", fontsize="small")
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    umax = float(np.nanmax(np.hypot(u[:, 0], u[:, 1]))) if len(u) else 0.0
    how = "true scale" if scale == 1.0 else f"displacement magnified {scale:g}×"
    head = f"{title}\n" if title else ""
    ax.set_title(f"{head}deformed part, {how} (max |u| {umax:.3g} mm)", fontsize="medium")
    return _png(fig)


def plot_front(
    objectives: np.ndarray,
    front: np.ndarray,
    names: tuple[str, str],
    best: np.ndarray | None = None,
    title: str = "",
) -> bytes:
    """The first two objectives of every feasible design, with the Pareto front.

    Parameters
    ----------
    objectives : (k, >= 2) float — feasible designs (units in ``names``).
    front : (j, >= 2) float — the non-dominated designs.
    names : the two objective names, with units (``peak_stress_MPa``).
    best : (>= 2,) float, optional — the design the run chose.

    Returns
    -------
    bytes
        The PNG file.
    """
    f = np.asarray(objectives, dtype=float).reshape(-1, np.shape(front)[-1])
    pf = np.asarray(front, dtype=float)
    pf = pf[np.argsort(pf[:, 0])]
    fig = _new_figure(figsize=(6.4, 4.8), layout="constrained")
    ax = fig.subplots()
    if len(f):
        ax.plot(f[:, 0], f[:, 1], ".", color="0.6", ms=4, label="feasible designs")
    ax.plot(pf[:, 0], pf[:, 1], "o-", color="C0", ms=4, lw=1, label="Pareto front")
    if best is not None:
        b = np.asarray(best, dtype=float)
        ax.plot(b[0], b[1], "*", color="C3", ms=14, label="chosen")
    ax.set_xlabel(_labels.label(names[0]))
    ax.set_ylabel(_labels.label(names[1]))
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    if title:
        ax.set_title(title)
    return _png(fig)


def plot_taguchi(
    main_effects: Mapping[str, Mapping[str, list[float]]],
    anova_rows: list[Mapping[str, object]],
    title: str = "",
) -> bytes:
    """Main effects (mean S/N of each level of each factor) and percent contributions (ANOVA).

    Parameters
    ----------
    main_effects : factor name -> {"levels": (s,) level values, "sn_dB": (s,) mean S/N, dB}.
    anova_rows : rows of the ANOVA table with ``source``, ``percent`` and ``pooled``; the
        ``error`` and ``total`` rows are drawn as the error bar and left out.

    Returns
    -------
    bytes
        The PNG file.
    """
    names = list(main_effects)
    fig = _new_figure(figsize=(2.0 * len(names) + 1.0, 6.4), layout="constrained")
    grid = fig.add_gridspec(2, len(names))
    top = [fig.add_subplot(grid[0, i]) for i in range(len(names))]
    lows = [min(e["sn_dB"]) for e in main_effects.values()]
    highs = [max(e["sn_dB"]) for e in main_effects.values()]
    for ax, name in zip(top, names, strict=True):
        e = main_effects[name]
        ax.plot(range(1, len(e["sn_dB"]) + 1), e["sn_dB"], "o-")
        ax.set_xticks(range(1, len(e["levels"]) + 1))
        ax.set_xticklabels([f"{v:g}" for v in e["levels"]], fontsize="x-small", rotation=45)
        ax.set_title(name)
        ax.set_ylim(min(lows) - 1.0, max(highs) + 1.0)
        ax.grid(True, alpha=0.3)
    top[0].set_ylabel("mean S/N (dB)")
    bottom = fig.add_subplot(grid[1, :])
    rows = [r for r in anova_rows if r.get("source") not in ("total",)]
    labels = [str(r["source"]) for r in rows]
    values = [float(r.get("percent") or 0.0) for r in rows]  # type: ignore[arg-type]
    colours = ["0.6" if r.get("pooled") or r.get("source") == "error" else "C0" for r in rows]
    bottom.bar(labels, values, color=colours)
    bottom.set_ylabel("contribution (% of total SS)")
    bottom.set_title("ANOVA contributions (grey: pooled into the error)")
    bottom.grid(True, axis="y", alpha=0.3)
    if title:
        fig.suptitle(title)
    return _png(fig)


def plot_band(
    x_values: np.ndarray,
    nominal: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    x: str = "displacement_mm",
    y: str = "force_N",
    title: str = "",
    note: str = "",
    target: float | None = None,
    tolerance: float | None = None,
) -> bytes:
    """A response with its robustness band: the nominal curve and, shaded, the per-row min–max
    over the scatter samples (see :mod:`pipeline.robustness`).

    Parameters
    ----------
    x_values, nominal : (n,) float
        The nominal design's driving column and response, in the units their names carry.
    low, high : (m,) float
        Per-row min and max of the response over the samples (same unit as ``nominal``); rows
        are matched by index with ``x_values`` (the first ``min(n, m)``); NaN rows are left out.
    target, tolerance : float, optional
        A constant target of the response and its band half-width (unit of ``nominal``), drawn
        as dashed lines.
    """
    xs = np.asarray(x_values, dtype=float)
    ys = np.asarray(nominal, dtype=float)
    n = min(len(xs), len(low), len(high))
    lo, hi = np.asarray(low, dtype=float)[:n], np.asarray(high, dtype=float)[:n]
    ok = np.isfinite(xs[:n]) & np.isfinite(lo) & np.isfinite(hi)
    fig = _new_figure(figsize=(6.4, 4.2), layout="constrained")
    ax = fig.subplots()
    ax.fill_between(
        xs[:n][ok], lo[ok], hi[ok], color="tab:blue", alpha=0.25, lw=0, label="min–max of samples"
    )
    ax.plot(xs, ys, color="tab:blue", lw=1.8, label="nominal design")
    if target is not None:
        ax.axhline(target, color="k", ls="--", lw=1.0, label="target")
        for edge in (target - (tolerance or 0.0), target + (tolerance or 0.0)) if tolerance else ():
            ax.axhline(edge, color="tab:red", ls=":", lw=1.0)
    ax.set_xlabel(_label(x, None))
    ax.set_ylabel(_label(y, None))
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small", title=note or None, title_fontsize="small")
    if title:
        ax.set_title(title)
    return _png(fig)


# --------------------------------------------------------------------------------------------
# flexure / collision figures


def collision_sweeps_png(title: str, sweeps: Mapping[str, Mapping[str, Any]]) -> bytes:
    """Figs. 16–17 of paper 000: HIC15 and peak contact force of the spring and its
    constant-stiffness reference over each swept parameter (one column per sweep).

    Parameters
    ----------
    title : str — the figure's title.
    sweeps : mapping of parameter name (``rotor_inertia_kg_m2``, ``rotor_torque_Nm``) to its
        record: ``values`` (k,), and ``hic15`` / ``peak_force_N`` each a mapping of ``spring``
        and ``reference`` to (k,) float (s·g^2.5 and N), as ``evaluation.json`` holds them.
    """
    fig = _new_figure(figsize=(10, 7), layout="constrained")
    axes = fig.subplots(2, len(sweeps), squeeze=False)
    for col, (parameter, rec) in enumerate(sweeps.items()):
        x = np.asarray(rec["values"], dtype=float)
        for row, (key, label) in enumerate((("hic15", "HIC15"), ("peak_force_N", "ImpF (N)"))):
            ax = axes[row, col]
            for name, style in (("spring", "o-"), ("reference", "s--")):
                ax.plot(x, np.asarray(rec[key][name], dtype=float), style, ms=4, label=name)
            ax.set_xlabel(_label(parameter, None))  # words and unit, not the key
            ax.set_ylabel(label)
            ax.grid(True, alpha=0.3)
            ax.legend(loc="best")
    fig.suptitle(title)
    return _png_at(fig, 110)


def collision_impact_png(table: Mapping[str, np.ndarray]) -> bytes:
    """The nominal impact of paper 000 over time, spring and reference: contact force (N), head
    acceleration (g) and spring deflection (deg) against ``time_ms`` (the columns
    ``contact_force_N``, ``head_acceleration_g``, ``deflection_deg`` and their ``reference_``
    twins, each (n,))."""
    fig = _new_figure(figsize=(10, 4), layout="constrained")
    axes = fig.subplots(1, 3)
    for ax, key, label in zip(
        axes,
        ("contact_force_N", "head_acceleration_g", "deflection_deg"),
        ("contact force (N)", "head acceleration (g)", "spring deflection (deg)"),
        strict=True,
    ):
        ax.plot(table["time_ms"], table[key], label="spring")
        ax.plot(table["time_ms"], table[f"reference_{key}"], "--", label="reference")
        ax.set_xlabel("time (ms)")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best")
    return _png_at(fig, 110)


# constant-force / threshold figures
# (the kinds' own figures, moved from pipeline/studies/threshold_spring.py: issue #24, item 3)

__all__ += ["threshold_curve_png", "spring_shape_png"]


def threshold_curve_png(
    table: Mapping[str, np.ndarray],
    tolerance: float,
    allowable_MPa: float | None = None,
    title: str = "",
) -> bytes:
    """Torque (beam, plane stress, target with its band) and stress against rotation, PNG.

    Parameters
    ----------
    table : columns ``rotation_deg`` (m,), ``target_torque_Nm``, ``torque_Nm`` (N·m) and
        ``peak_stress_MPa`` (MPa); optionally ``plane_stress_torque_Nm`` and
        ``plane_stress_peak_stress_MPa`` (NaN between the plane-stress rows).
    tolerance : float — the band's half-width as a fraction of the target's largest |torque|.
    allowable_MPa : float, MPa, optional — drawn as a line on the stress axes.
    """
    t = table
    fig = _new_figure(figsize=(10, 4), layout="constrained")
    ax_t, ax_s = fig.subplots(1, 2)
    x = t["rotation_deg"]
    level = float(np.nanmax(np.abs(t["target_torque_Nm"])))
    ax_t.fill_between(
        x,
        t["target_torque_Nm"] - tolerance * level,
        t["target_torque_Nm"] + tolerance * level,
        color="0.85",
        label=f"target ± {tolerance * 100:g} % of max",
    )
    ax_t.plot(x, t["target_torque_Nm"], "k--", lw=1, label="target")
    ax_t.plot(x, t["torque_Nm"], "o-", ms=3, label="beam model")
    ax_s.plot(x, t["peak_stress_MPa"], "o-", ms=3, label="beam model")
    if "plane_stress_torque_Nm" in t:
        ok = np.isfinite(t["plane_stress_torque_Nm"])
        ax_t.plot(x[ok], t["plane_stress_torque_Nm"][ok], "s", label="plane stress")
        ax_s.plot(x[ok], t["plane_stress_peak_stress_MPa"][ok], "s", label="plane stress (vM)")
    if allowable_MPa:
        ax_s.axhline(
            allowable_MPa, ls="--", color="k", lw=1, label=f"allowable {allowable_MPa:g} MPa"
        )
    ax_t.set_xlabel("hub rotation (deg)")
    ax_t.set_ylabel("torque (N m)")
    ax_s.set_xlabel("hub rotation (deg)")
    ax_s.set_ylabel("peak stress (MPa)")
    for ax in (ax_t, ax_s):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best")
    if title:
        fig.suptitle(title)
    return _png_at(fig, 110)


def spring_shape_png(outline: Any, shapes_mm: np.ndarray | None) -> bytes:
    """A planar spring's outline (shapely Polygon, mm; holes white) with arm 0's undeformed and
    last deformed centreline (``shapes_mm`` (rows, n, 2), mm), PNG."""
    fig = _new_figure(figsize=(5.5, 5.5), layout="constrained")
    ax = fig.subplots(1, 1)
    if outline is not None:
        ring = np.asarray(outline.exterior.coords)
        ax.fill(ring[:, 0], ring[:, 1], color="0.8")
        for hole in outline.interiors:
            h = np.asarray(hole.coords)
            ax.fill(h[:, 0], h[:, 1], color="white")
    if shapes_mm is not None:
        ax.plot(*shapes_mm[0].T, "b-", lw=1, label="arm 0")
        ax.plot(*shapes_mm[-1].T, "r-", lw=1, label="arm 0 at the end of the range")
        ax.legend(loc="lower left")
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.grid(True, alpha=0.3)
    return _png_at(fig, 110)


# mechanism figures


def mechanism_shapes_png(
    responses: Mapping[str, Any],
    outline: Any,
    bodies: list[tuple[Any, Any]],
    drives: Mapping[str, tuple[str, str]],
    title: str,
    n_shapes: int = 4,
) -> bytes:
    """One panel per load case of a ``mechanism`` design: the part at a few rows, each beam
    drawn as its band at its own thickness along the deformed centreline
    (:func:`fea.mechanism_design.deformed_bands`), the bodies moved with their poses; grey: the
    part as exported (row 0).

    Parameters
    ----------
    responses : case -> :class:`fea.mechanism.MechanismResponse`
    outline : shapely Polygon, mm — the part as exported.
    bodies : per body of the mechanism, in its order: (ref (2,) mm, outline (k, 2) mm or None).
    drives : case -> (control, unit) of its drive (a rotation's rows are shown in deg).
    n_shapes : at most this many converged rows per case, evenly spread.

    Returns
    -------
    bytes
        The PNG file (110 dpi).
    """
    import math

    import matplotlib
    from flexopt.fea.mechanism_design import deformed_bands
    from matplotlib.patches import Polygon as Patch

    def draw(ax: Any, poly: Any, colour: str, alpha: float) -> None:
        geoms = getattr(poly, "geoms", [poly])
        for gm in geoms:
            if gm.is_empty:
                continue
            ax.add_patch(Patch(np.asarray(gm.exterior.coords), closed=True, fc=colour,
                               ec=colour, alpha=alpha, lw=0.5))  # fmt: skip

    fig = _new_figure(figsize=(5.5 * len(responses), 5.0), layout="constrained")
    axes = fig.subplots(1, len(responses), squeeze=False)[0]
    for ax, (case, response) in zip(axes, responses.items(), strict=True):
        ok = np.flatnonzero(np.asarray(response.converged, bool))
        rows = ok[
            np.unique(np.linspace(0, len(ok) - 1, min(n_shapes, len(ok))).round().astype(int))
        ]
        draw(ax, outline, "0.75", 0.6)
        cmap = matplotlib.colormaps["viridis"]
        for j, row in enumerate(rows):
            colour = cmap(j / max(1, len(rows) - 1))
            for i in range(len(response.shapes_mm)):
                pts = np.asarray(response.shapes_mm[i][row], dtype=float)
                t = np.asarray(response.thickness_at_nodes_mm[i], dtype=float)
                # the band the interference check uses (a disc per node would bulge at the
                # roots' flares, where the thickness changes fast)
                draw(ax, deformed_bands(pts[None], t)[0], colour, 0.55)
            for k, (ref_mm, outline_mm) in enumerate(bodies):
                if outline_mm is None:
                    continue
                x, y, th = response.body_poses[row, k]
                ref = np.array(ref_mm, dtype=float)
                rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
                corners = (np.array(outline_mm, float) - ref) @ rot.T + np.array([x, y])
                ax.add_patch(Patch(corners, closed=True, fc=colour, ec="k", alpha=0.35, lw=0.5))
        control, unit = drives[case]
        drive = np.asarray(response.drive, float)[rows]
        if control == "rotation":
            drive = np.degrees(drive)
        ax.set_title(f"{case}: drive " + ", ".join(f"{v:.3g}" for v in drive) + f" {unit}")
        ax.set_aspect("equal")
        ax.autoscale_view()
        ax.grid(True, alpha=0.3)
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
    fig.suptitle(title)
    return _png_at(fig, 110)  # the mechanism's figures are 110 dpi


# SEA spring figures (the sea_window kind's; moved from pipeline/studies/sea_window.py)


def plot_sea_peak_torque(curve: Any, window: Any, k: float | None) -> bytes:
    """Peak spring and gearbox torque after the collision against K (paper 004, Figs. 8–9),
    the limit, K_max and the checked K.

    Parameters
    ----------
    curve : :func:`fea.sea_window.peak_torque_curve`'s answer — (n,) stiffness_Nm_per_rad
        (N m/rad), peak_spring_torque_Nm, peak_gearbox_torque_Nm, rigid_frictionless_Nm (N m)
        and torque_limit_Nm.
    window : :func:`fea.sea_window.stiffness_window`'s answer (k_min / k_max_Nm_per_rad).
    k : float or None, N m/rad — the checked stiffness.

    Returns
    -------
    bytes — the PNG file.
    """
    import math

    fig = _new_figure(figsize=(6.6, 4.6), layout="constrained")
    ax = fig.subplots()
    ks = curve.stiffness_Nm_per_rad
    ax.plot(ks, curve.peak_spring_torque_Nm, "-", label="peak spring torque K θ2")
    ax.plot(ks, curve.peak_gearbox_torque_Nm, "--", label="peak gearbox torque G_k (θ1 − θ2)")
    ax.plot(ks, curve.rigid_frictionless_Nm, ":", color="0.4", label="rigid, frictionless estimate")
    limit = curve.torque_limit_Nm
    ax.axhline(limit, color="C3", lw=1, label=f"limit {limit:g} N·m")
    if math.isfinite(window.k_max_Nm_per_rad):
        ax.axvline(window.k_max_Nm_per_rad, color="C3", ls="--", lw=1,
                   label=f"K_max {window.k_max_Nm_per_rad:.4g}")  # fmt: skip
    ax.axvspan(window.k_min_Nm_per_rad, max(window.k_min_Nm_per_rad, window.k_max_Nm_per_rad),
               color="C2", alpha=0.12, label="window")  # fmt: skip
    if k is not None:
        ax.axvline(k, color="k", lw=1, label=f"K = {k:g}")
    ax.set_xscale("log")
    ax.set_xlabel("spring stiffness K (N·m/rad)")
    ax.set_ylabel("peak torque after the collision (N·m)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return _png(fig)


def plot_sea_bode(bodes: list[Any], required_bandwidth_Hz: float) -> bytes:
    """Bode magnitude of the locked-output torque transfer (paper 004, Fig. 11) for several K,
    with the required torque ratio and the required bandwidth (Hz).

    ``bodes``: :func:`fea.sea_window.bode_data`'s answers — (f,) frequency_Hz, magnitude_dB,
    and stiffness_Nm_per_rad, bandwidth_rad_per_s, required_ratio. Returns the PNG file.
    """
    import math

    fig = _new_figure(figsize=(6.6, 4.6), layout="constrained")
    ax = fig.subplots()
    for b in bodes:
        ax.semilogx(b.frequency_Hz, b.magnitude_dB,
                    label=f"K = {b.stiffness_Nm_per_rad:.4g} N·m/rad: "
                          f"{b.bandwidth_rad_per_s / (2 * math.pi):.3g} Hz")  # fmt: skip
    if bodes:
        ratio = bodes[0].required_ratio
        ratio_dB = 20 * math.log10(ratio)
        label = f"required ratio {ratio:.4g} ({ratio_dB:.1f} dB)"
        ax.axhline(ratio_dB, color="C3", lw=1, label=label)
    ax.axvline(required_bandwidth_Hz, color="k", ls="--", lw=1,
               label=f"required {required_bandwidth_Hz:g} Hz")  # fmt: skip
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("|T_out / T_sat| (dB)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return _png(fig)


# rigid stops (polyline_beam with a stops: block)

__all__ += ["stops_shapes_png"]


def stops_shapes_png(
    shapes_mm: np.ndarray,
    stops: Any,
    displacement_mm: np.ndarray,
    in_contact: np.ndarray,
    max_shapes: int = 6,
) -> bytes:
    """A beam's deformed centrelines and the rigid stops it meets, PNG.

    Parameters
    ----------
    shapes_mm : (n_rows, n_nodes, 2) float, mm — converged rows, undeformed first.
    stops : sequence of (name, outline (m, 2) mm, closed) — a point, a polyline or a polygon.
    displacement_mm : (n_rows,) float, mm — the end displacement of each row (the legend).
    in_contact : (n_rows,) bool — some stop touches the beam in that row (drawn solid; clear
        rows dashed).
    """
    import matplotlib

    shapes = np.asarray(shapes_mm, dtype=float)
    fig = _new_figure(figsize=(6.4, 5.0), layout="constrained")
    ax = fig.subplots()
    for name, outline, closed in stops:
        p = np.asarray(outline, dtype=float).reshape(-1, 2)
        if p.shape[0] == 1:
            ax.plot(p[:, 0], p[:, 1], "k^", ms=7, label=f"stop {name}")
        elif closed:
            ax.fill(p[:, 0], p[:, 1], color="0.6", alpha=0.7, label=f"stop {name}")
        else:
            ax.plot(p[:, 0], p[:, 1], "-", color="0.3", lw=3, label=f"stop {name}")
    n = len(shapes)
    rows = np.unique(np.linspace(0, n - 1, min(max_shapes, n)).round().astype(int)) if n else []
    colours = matplotlib.colormaps["viridis"](np.linspace(0, 0.9, max(len(rows), 1)))
    for colour, row in zip(colours, rows, strict=False):
        touching = bool(np.asarray(in_contact)[row])
        ax.plot(
            shapes[row, :, 0], shapes[row, :, 1], "-" if touching else "--", color=colour,
            lw=1.5, label=f"end displacement = {float(displacement_mm[row]):.3g} mm"
            + (" (in contact)" if touching else ""),
        )  # fmt: skip
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    ax.set_title("deformed shapes and rigid stops")
    return _png(fig)
