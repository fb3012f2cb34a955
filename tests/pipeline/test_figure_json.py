"""report.html's figures are plain JSON (pipeline/figure_json.py): what plotly's classes
checked as they built them is checked here, on every figure of the synthetic pages the browser
tests draw (tests/pipeline/test_report_html_browser.py: 1, 2 and 25 variables with 1-3
objectives, hostile names, a mechanism with two load cases and outputs, a stress field on the
deformed part): plotly's ``Figure`` accepts each and writes it back unchanged
(tests/pipeline/flexopt_figure_check.py). No browser needed."""

from __future__ import annotations

import json
import re

import pytest
from flexopt.pipeline.report_html import render_html
from flexopt_figure_check import assert_plotly_reads_unchanged, first_difference
from test_report_html_browser import HOSTILE, _data, _mechanism_detail, _stress_detail

pytest.importorskip("plotly.graph_objects")

_FIGURE = re.compile(
    r'<script type="application/json" class="plotly-figure" id="([^"]+)"[^>]*>(.*?)</script>', re.S
)


def _pages() -> dict[str, str]:
    detail, verdicts = _mechanism_detail()
    return {
        "1 variable, 1 objective": render_html(_data(["x0_mm"], n_obj=1)),
        "2 variables, 2 objectives": render_html(_data(["x0_mm", "x1_mm"], n_obj=2)),
        "25 variables, 3 objectives": render_html(_data([f"x{k}_mm" for k in range(25)], n_obj=3)),
        "hostile names": render_html(_data(HOSTILE, n_obj=3)),
        "mechanism": render_html(_data(["a_mm"], detail=detail, verdicts=verdicts)),
        "stress field": render_html(_data(["a_mm"], detail=_stress_detail())),
    }


def test_plotly_reads_every_figure_unchanged():
    seen = set()
    for page, html in _pages().items():
        figures = _FIGURE.findall(html)
        assert figures, page
        for name, text in figures:
            assert_plotly_reads_unchanged(json.loads(text))
            seen.add(re.sub(r"-(free|blocked).*$", "", name))
    # every kind of figure the page draws was among them
    assert {"fig-parallel-coordinates", "fig-scatter-matrix", "fig-sensitivity",
            "fig-pareto-front", "fig-response", "fig-response-stress", "fig-part-3d",
            "fig-stress-deformed", "fig-outputs"} <= seen, seen  # fmt: skip


def test_the_check_finds_what_plotly_would_change():
    """The check can fail: a bare-string title (plotly writes ``{"text": ...}``), a colorscale
    by name (plotly writes its colours) and an unknown property are all caught."""
    for bad in (
        {"data": [{"type": "scatter", "x": [1]}], "layout": {"title": "t"}},
        {"data": [{"type": "heatmap", "z": [[1]], "colorscale": "RdBu"}], "layout": {}},
    ):
        with pytest.raises(AssertionError, match="otherwise at"):
            assert_plotly_reads_unchanged(bad)
    with pytest.raises(ValueError):
        assert_plotly_reads_unchanged({"data": [{"type": "scatter", "colour": "red"}]})
    assert (
        first_difference({"a": [1, {"b": 2}]}, {"a": [1, {"b": 3}]})
        == "/a[1]/b: '2' on the page, '3' by plotly"
    )
