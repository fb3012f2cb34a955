"""report.html's plotly templates, put into each figure's JSON after the figure is built.

plotly validates and deep-copies a figure's template (~1,500 entries) when the figure is made
(the default one, "plotly") and again when a layout names one ("plotly_white"): 10-25 ms of
CPU per figure, about a fifth of report.html's figures' time. Here the figures are built with
no default template and a small marker for "plotly_white" (:data:`WHITE`), and
:func:`finish_template` puts the template's JSON in their JSON instead, taken once per process:
the page's text is the same, byte for byte (plotly writes the layout's keys sorted).
"""

from __future__ import annotations

import contextlib
import functools
import json
from collections.abc import Iterator
from typing import Any

#: the template report.html's figures name (report_html._layout)
WHITE_NAME = "plotly_white"
#: what ``_layout`` names instead: a template of one entry, cheap to validate, replaced by
#: :func:`finish_template` with the JSON of :data:`WHITE_NAME`
WHITE: dict[str, Any] = {"layout": {"meta": "flexopt:" + WHITE_NAME}}

#: the defaults in force outside the :func:`templates_at_embed` blocks now open (innermost last)
_OUTER: list[Any] = []


@contextlib.contextmanager
def templates_at_embed() -> Iterator[None]:
    """While the block runs, plotly applies no default template to new figures (plotly.io's
    ``templates.default`` is None); :func:`finish_template` puts the one that was in force
    into each figure's JSON. The default is restored on exit (figures built by other threads
    meanwhile get none: report.html is made by one thread)."""
    import plotly.io as pio

    outer = pio.templates.default
    _OUTER.append(outer)
    pio.templates.default = None
    try:
        yield
    finally:
        _OUTER.pop()
        pio.templates.default = outer


@functools.lru_cache(maxsize=8)
def _json_text(name: str, applied: bool) -> str:
    """The template's JSON text as a figure carries it: named in its layout, or (``applied``)
    applied at the figure's creation as plotly.io's default (the entries come in another
    order)."""
    import plotly.graph_objects as go
    import plotly.io as pio

    if not applied:
        fig = go.Figure(layout={"template": name})
    else:
        now, pio.templates.default = pio.templates.default, name
        try:
            fig = go.Figure()
        finally:
            pio.templates.default = now
    return json.dumps(json.loads(fig.to_json())["layout"].get("template"))


def _template_json(template: Any, applied: bool = False) -> dict[str, Any] | None:
    """The JSON a figure with ``template`` (a registered name or a Template) carries, or None."""
    if template is None:
        return None
    if isinstance(template, str):
        return json.loads(_json_text(template, applied))  # a fresh copy: the caller may edit it
    import plotly.graph_objects as go

    fig = go.Figure(layout={"template": template})
    return json.loads(fig.to_json())["layout"].get("template")


def finish_template(spec: dict[str, Any]) -> None:
    """Put the template into a figure's JSON (``fig.to_json()`` parsed), in place: the
    "plotly_white" one where the figure names :data:`WHITE`, and inside a
    :func:`templates_at_embed` block the default that was in force where it names none."""
    layout = spec.get("layout") or {}
    template = layout.get("template")
    if template == WHITE:
        full = _template_json(WHITE_NAME)
    elif template is None and _OUTER:
        full = _template_json(_OUTER[-1], applied=True)
    else:
        return
    if full is not None:  # the first key, where plotly puts a template it applies at creation
        spec["layout"] = {"template": full, **{k: v for k, v in layout.items() if k != "template"}}


def warm_up() -> None:
    """Load what report.html's figures first need, ahead of the report (run's preload thread,
    while the workers solve): plotly's figure classes and their validators, each loaded on a
    figure's first use (~0.2-0.4 s CPU), and the templates' JSON. Nothing here changes a figure;
    a failure is the caller's to log."""
    import plotly.graph_objects as go
    from plotly.offline import get_plotlyjs  # noqa: F401  (the module, ~1 ms; the text is read later)

    # one empty trace of each type report.html draws, in a figure with the page's layout keys
    fig = go.Figure(layout={"template": WHITE, "title": {"text": ""}, "margin": {"l": 1}})
    for trace in (go.Scatter, go.Bar, go.Heatmap, go.Parcoords, go.Splom, go.Mesh3d, go.Scatter3d):
        fig.add_trace(trace())
    fig.update_layout(xaxis={"title": {"text": ""}}, yaxis={"title": {"text": ""}}, height=400)
    fig.to_json()
    _json_text(WHITE_NAME, False)
    import plotly.io as pio

    if isinstance(pio.templates.default, str):
        _json_text(pio.templates.default, True)
