"""report.html drawn in a real headless browser (issue 23 class 1).

Pages are rendered here from synthetic runs (no optimisation: :func:`render_html` of designs
drawn in the test) for 1, 2 and 25 design variables, for hostile variable names (markup, script
tags, ``<!--``, quotes, non-ASCII) and for a mechanism-like best design with two load cases and
user outputs. Each page is opened in Chromium through Playwright (the system ``chromium``, as
Debian packages it; ``.ci/run`` installs it) and every figure must be drawn by plotly.js
(an svg or canvas inside its div, plotly's own data attached) with no console error and no page
exception; a figure that throws must leave a message in its place and the others drawn.

Skipped, with the reason, where Playwright or a Chromium binary is missing.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from flexopt.optimise import DesignDetail, DesignSpace, Evaluation
from flexopt.optimise.requirements import Verdict
from flexopt.pipeline.report_html import HtmlData, render_html
from shapely.geometry import box


def _chromium() -> str | None:
    for name in (os.environ.get("FLEXOPT_CHROMIUM"), "chromium", "chromium-browser"):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


try:
    from playwright.sync_api import sync_playwright
except ImportError:  # the test extra brings it; a bare install may not have it
    sync_playwright = None

CHROMIUM = _chromium()
pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(
        sync_playwright is None,
        reason="playwright is not installed (pip install 'flexopt[test]'); report.html is not "
        "drawn in a browser",
    ),
    pytest.mark.skipif(
        CHROMIUM is None,
        reason="no chromium binary (apt-get install chromium, or FLEXOPT_CHROMIUM=PATH); "
        "report.html is not drawn in a browser",
    ),
]


# --------------------------------------------------------------------------------------------
# Synthetic runs


@dataclass
class _Problem:
    """A stand-in with the DesignProblem protocol; the report reads its names, never solves."""

    space: DesignSpace
    objective_names: tuple[str, ...]
    constraint_names: tuple[str, ...] = ("stress_ratio_minus_1",)
    variable_meanings: dict = field(default_factory=dict)

    def evaluate(self, x):
        raise AssertionError("the report never solves a design")

    def detail(self, x):
        raise AssertionError("the report never solves a design")


def _data(
    names: list[str],
    n_obj: int = 1,
    n_eval: int = 40,
    detail: DesignDetail | None = None,
    verdicts: tuple[Verdict, ...] = (),
) -> HtmlData:
    """A run of ``n_eval`` designs over variables ``names`` in [0, 1] (some infeasible)."""
    rng = np.random.default_rng(len(names) + 7 * n_obj)
    space = DesignSpace(tuple(names), np.zeros(len(names)), np.ones(len(names)))
    objectives = ("rms_error_N", "mass_g", "max_peak_stress_MPa")[:n_obj]
    problem = _Problem(space, objectives)
    evaluations = []
    for x in rng.uniform(0, 1, (n_eval, len(names))):
        f = np.array([np.sum((x - 0.4) ** 2), 2.0 + x[0], 10.0 * x[-1]])[:n_obj]
        evaluations.append(Evaluation(x, f, np.array([x[0] - 0.8]), {"mass_g": 2.0 + x[0]}))
    feasible = [ev for ev in evaluations if ev.feasible]
    best = min(feasible, key=lambda ev: float(ev.f[0]))
    if detail is None:
        d = np.linspace(0.0, 5.0, 11)
        detail = DesignDetail(
            best,
            {"displacement_mm": d, "force_N": 0.5 * d, "peak_stress_MPa": 4.0 * d},
            {"x": "displacement_mm", "y": "force_N", "target": 2.0, "tolerance": 0.2,
             "allowable_MPa": 40.0},
            outline=box(0, 0, 30, 5),
            height_mm=4.0,
        )  # fmt: skip
    front = tuple(sorted(feasible, key=lambda ev: float(ev.f[0]))[:5]) if n_obj > 1 else ()
    return HtmlData(
        "browser-toy", "toy_html", problem, evaluations, best, front, detail, verdicts,
        {"parallel": {"description": "serial"}},
    )  # fmt: skip


HOSTILE = [
    "<!--<script>x",
    "</script><script>alert(1)</script>",
    "a\"b'c&amp;d",
    "<b>bold</b> & <i>",
    "x]]>-->",
    "σ_max Δ",
    "{{x}} %s ${x}",
]


def _mechanism_detail() -> tuple[DesignDetail, tuple[Verdict, ...]]:
    """A best design with two load cases (the second in its own response CSV, as the mechanism
    kind writes them) and user outputs in two units."""
    d = np.linspace(0.0, 5.0, 11)
    tables = {
        "free": {
            "step": np.arange(11), "drive_mm": d, "drive_reaction_N": 0.8 * d,
            "stroke_ratio": 3.0 + 0.01 * d, "jaw_mm": 3.0 * d, "peak_stress_MPa": 5.0 * d,
            "converged": np.ones(11, bool), "stable": np.ones(11, bool),
        },
        "blocked": {
            "step": np.arange(11), "drive_mm": d, "drive_reaction_N": 1.5 * d,
            "blocked_force_N": 0.4 * d, "peak_stress_MPa": 6.0 * d,
            "converged": np.ones(11, bool), "stable": np.ones(11, bool),
        },
    }  # fmt: skip
    from flexopt.pipeline.runfolder import table_to_csv

    files = {f"response_{c}.csv": table_to_csv(t).encode() for c, t in tables.items()}
    ev = Evaluation(np.array([0.5]), np.array([1.0]), np.array([-1.0]))
    detail = DesignDetail(
        ev,
        tables["free"],
        {"x": "drive_mm", "y": "drive_reaction_N", "stress": "peak_stress_MPa",
         "allowable_MPa": 48.0},
        outline=box(0, 0, 30, 5),
        height_mm=4.0,
        files=files,
    )  # fmt: skip
    verdicts = (
        Verdict("max_peak_stress_MPa", "max_peak_stress_MPa", 30.0,
                "<= 32 MPa (yield 48 MPa / SF 1.5)", 2.0, 0.0625, True, "MPa"),
    )  # fmt: skip
    return detail, verdicts


# --------------------------------------------------------------------------------------------
# The browser


@pytest.fixture(scope="module")
def browser():
    with sync_playwright() as p:
        try:
            b = p.chromium.launch(
                executable_path=CHROMIUM,
                args=[
                    "--no-sandbox",  # CI runs as root
                    "--enable-unsafe-swiftshader",  # software WebGL: the 3D view, the splom
                    "--proxy-server=127.0.0.1:9",  # no network: the page must need none
                ],
            )
        except Exception as exc:  # a binary that cannot start is no browser either
            pytest.skip(f"{CHROMIUM} could not be started ({type(exc).__name__}: {exc})"[:300])
        yield b
        b.close()


_DRAWN = """() => Array.from(document.querySelectorAll('div.figure')).map(d => ({
  id: d.id,
  plotly: d.classList.contains('js-plotly-plot'),
  drawn: d.querySelectorAll('svg.main-svg, canvas').length,
  traces: (d._fullData || []).length,
  error: d.querySelector('.figure-error') ? d.querySelector('.figure-error').textContent : null,
}))"""


def _open(browser, html: str, tmp_path: Path) -> tuple[list[dict], list[str], str]:
    """The figures of the page as drawn, its console errors and page exceptions, its title."""
    path = tmp_path / "report.html"
    path.write_text(html, encoding="utf-8")
    page = browser.new_page(viewport={"width": 1300, "height": 900})
    problems: list[str] = []
    page.on(
        "console", lambda m: problems.append(f"console {m.type}: {m.text}") if m.type == "error"
        else None,
    )  # fmt: skip
    page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
    page.on("dialog", lambda d: (problems.append(f"dialog: {d.message}"), d.dismiss()))
    try:
        page.goto(path.as_uri(), wait_until="load", timeout=60_000)
        # every figure drawn (or failed with its note), however slow the machine
        page.wait_for_function(
            """() => Array.from(document.querySelectorAll('div.figure')).every(d =>
                 d.querySelector('.figure-error') ||
                 (d._fullData && d.querySelectorAll('svg.main-svg, canvas').length))""",
            timeout=60_000,
        )
        figures = page.evaluate(_DRAWN)
        title = page.title()
        if os.environ.get("FLEXOPT_SCREENSHOTS"):  # to look at the page: a folder for PNGs
            shot = Path(os.environ["FLEXOPT_SCREENSHOTS"]) / f"{tmp_path.name}.png"
            page.screenshot(path=str(shot), full_page=True)
    finally:
        page.close()
    return figures, problems, title


def _all_drawn(figures: list[dict], problems: list[str]) -> None:
    assert figures, "the page has no figure"
    for fig in figures:
        assert fig["error"] is None, f"{fig['id']}: {fig['error']}"
        assert fig["plotly"] and fig["drawn"] > 0 and fig["traces"] > 0, fig
    assert not problems, problems


# --------------------------------------------------------------------------------------------
# Tests


@pytest.mark.parametrize(("n_var", "n_obj"), [(1, 1), (2, 2), (25, 3)])
def test_every_figure_is_drawn_for_1_2_and_25_variables(browser, tmp_path, n_var, n_obj):
    names = [f"x{k}_mm" for k in range(n_var)]
    data = _data(names, n_obj=n_obj)
    figures, problems, _ = _open(browser, render_html(data), tmp_path)
    _all_drawn(figures, problems)
    ids = {f["id"] for f in figures}
    assert {"plot-parallel-coordinates", "plot-scatter-matrix", "plot-sensitivity",
            "plot-response", "plot-part-3d"} <= ids  # fmt: skip
    assert ("plot-pareto-front" in ids) is (n_obj > 1)


def test_hostile_variable_names_change_nothing_but_their_labels(browser, tmp_path):
    data = _data(HOSTILE, n_obj=3)
    html = render_html(data)
    figures, problems, title = _open(browser, html, tmp_path)
    _all_drawn(figures, problems)
    assert len(figures) == 7 and title.startswith("browser-toy")


def test_one_failing_figure_leaves_a_message_and_the_others_drawn(browser, tmp_path):
    html = render_html(_data(["a_mm", "b_mm"], n_obj=2))
    # a figure plotly.js throws on: the two-dimension splom that blanked pages of one variable
    bad = (
        '{"data":[{"type":"splom","dimensions":[{"label":"a","values":[1,2]},'
        '{"label":"b","values":[3,4]}],"diagonal":{"visible":false},"showupperhalf":false}],'
        '"layout":{}}'
    )
    at = html.index('id="fig-sensitivity"')
    start = html.index(">", at) + 1
    html = html[:start] + bad + html[html.index("</script>", start) :]
    figures, problems, _ = _open(browser, html, tmp_path)
    by_id = {f["id"]: f for f in figures}
    assert by_id["plot-sensitivity"]["error"].startswith("This figure could not be drawn")
    others = [f for f in figures if f["id"] != "plot-sensitivity"]
    _all_drawn(others, [])
    assert len(problems) == 1 and "fig-sensitivity not drawn" in problems[0], problems


def test_every_load_case_and_output_is_drawn(browser, tmp_path):
    detail, verdicts = _mechanism_detail()
    figures, problems, _ = _open(
        browser, render_html(_data(["a_mm"], detail=detail, verdicts=verdicts)), tmp_path
    )
    _all_drawn(figures, problems)
    ids = {f["id"] for f in figures}
    for case in ("free", "blocked"):
        assert {f"plot-response-{case}", f"plot-response-stress-{case}"} <= ids, ids
    assert any(i.startswith("plot-outputs-free") for i in ids), ids
    assert any(i.startswith("plot-outputs-blocked") for i in ids), ids


def test_the_stress_field_on_the_deformed_part_is_drawn(browser, tmp_path):
    """A best design whose field carries its displacement: the stress view under the part."""
    detail = _stress_detail()
    figures, problems, _ = _open(browser, render_html(_data(["a_mm"], detail=detail)), tmp_path)
    _all_drawn(figures, problems)
    assert "plot-stress-deformed" in {f["id"] for f in figures}


def _stress_detail() -> DesignDetail:
    """A best design whose plane-stress field carries its displacement (the stress view)."""
    d = np.linspace(0.0, 5.0, 11)
    xs, ys = np.meshgrid(np.linspace(0, 30, 7), np.linspace(0, 5, 3))
    points = np.column_stack([xs.ravel(), ys.ravel()])
    tri = np.array(
        [[j * 7 + i, j * 7 + i + 1, (j + 1) * 7 + i + 1] for j in range(2) for i in range(6)]
        + [[j * 7 + i, (j + 1) * 7 + i + 1, (j + 1) * 7 + i] for j in range(2) for i in range(6)]
    )
    return DesignDetail(
        Evaluation(np.zeros(1), np.zeros(1), np.zeros(1)),
        {"displacement_mm": d, "force_N": 0.5 * d, "peak_stress_MPa": 4.0 * d},
        {"x": "displacement_mm", "y": "force_N"},
        outline=box(0, 0, 30, 5),
        height_mm=4.0,
        field_map={
            "points_mm": points,
            "triangles": tri,
            "values": points[:, 0],
            "displacement_mm": np.column_stack([np.zeros(21), (points[:, 0] / 30) ** 2]),
            "label": "von Mises stress (MPa)",
            "limit": 25.0,
        },
    )
