"""Issue 27 item 4, the report's fixed costs: cuts that must not change a file."""

from __future__ import annotations

import json
import os

import pytest
from flexopt.pipeline.run.split_makes import SplitMakes


def _make(name: str) -> bytes:
    if name == "bad":
        raise ValueError("no such plot")
    # the process that made it, so that the test sees two children did the work
    return f"{name}:{os.getpid()}".encode()


def test_split_makes_returns_every_file_in_queued_order():
    names = ["a", "b", "bad", "d", "e"]
    items = [(n, lambda n=n: _make(n)) for n in names]
    out = SplitMakes(items).results()
    assert [name for name, _, _ in out] == names
    assert out[2] == ("bad", None, "ValueError: no such plot")
    made = {name: data.decode().split(":") for name, data, _ in out if data is not None}
    assert all(made[n][0] == n for n in made)
    pids = {made[n][1] for n in made}
    if hasattr(os, "fork"):  # every other file in each of two children, none here
        assert len(pids) == 2 and str(os.getpid()) not in pids
        assert made["a"][1] == made["e"][1] != made["b"][1] == made["d"][1]


def test_templates_put_in_after_building_give_the_same_figure_json():
    """A figure built inside templates_at_embed with the WHITE marker, finished by
    finish_template, is the JSON plotly gives the figure built with the template named, and a
    figure naming none gets the default in force outside the block, as plotly applies it."""
    go = pytest.importorskip("plotly.graph_objects")
    import plotly.io as pio
    from flexopt.pipeline.html_templates import WHITE, finish_template, templates_at_embed

    def white(template):
        fig = go.Figure(go.Scatter(x=[0.0, 1.5], y=[2.0, -1.0], name="a"))
        fig.update_layout({"title": {"text": "t"}, "template": template, "height": 300})
        return fig

    def plain():
        fig = go.Figure(go.Bar(x=["u", "v"], y=[1.0, 2.0]))
        fig.update_layout(title="b", barmode="group")
        return fig

    expected = [white("plotly_white").to_json(), plain().to_json()]
    default = pio.templates.default
    with templates_at_embed():
        assert pio.templates.default is None
        specs = [json.loads(white(WHITE).to_json()), json.loads(plain().to_json())]
        for spec in specs:
            finish_template(spec)
    assert pio.templates.default == default  # restored
    for spec, want in zip(specs, expected, strict=True):
        assert json.dumps(spec, separators=(",", ":")) == json.dumps(
            json.loads(want), separators=(",", ":")
        )
