"""report.html: one offline page to explore every design of a run (issue 14, item 5).

A toy kind with two objectives, a multi-curve response (two torque curves and their stresses, as
the leaf-spring joint has) and a printable outline is run in this process; the page is parsed with
the standard library's HTML parser and each embedded figure read back as JSON. When chromium is
installed the page is also drawn in it, headless and offline, and the drawn DOM checked.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path
from typing import Literal

import numpy as np
import pytest
from flexopt.optimise import DesignDetail, DesignSpace, Evaluation
from flexopt.pipeline.evaluate import evaluate_study, response_plot_args
from flexopt.pipeline.labels import (
    label,
    path_words,
    siblings,
    variable_meanings,
    variable_rows,
    words,
)
from flexopt.pipeline.plot_targets import measure_band, target_overlay
from flexopt.pipeline.plots import curve_figure, response_figure
from flexopt.pipeline.problems import study_result
from flexopt.pipeline.report_html import (
    EVALUATE_SECTIONS,
    SECTIONS,
    EvaluateHtmlData,
    render_evaluate_html,
    sensitivity,
    top_designs,
)
from flexopt.pipeline.run import parallel_settings, prepare_run, rebuild_report, run_study
from flexopt.pipeline.studies import StudyKind, get_kind, register
from flexopt.pipeline.study import (
    STUDY_CONFIG,
    OptimiserSpec,
    Study,
    load_study,
    validate_study,
)
from flexopt_figure_check import assert_plotly_reads_unchanged
from pydantic import BaseModel
from shapely.geometry import box

# --------------------------------------------------------------------------------------------
# A toy kind with what the page shows


class HtmlGeometry(BaseModel):
    model_config = STUDY_CONFIG

    kind: Literal["toy_html"]


class HtmlStudy(Study):
    geometry: HtmlGeometry
    optimiser: OptimiserSpec = OptimiserSpec()


MEANINGS = {"a3": "where p3 sits between S2 and S3 (fraction, –)"}


@dataclass
class HtmlProblem:
    space: DesignSpace = field(
        default_factory=lambda: DesignSpace(
            ("a3", "t3_mm", "B_mm"), np.array([0.0, 0.5, 4.0]), np.array([1.0, 1.5, 8.0])
        )
    )
    objective_names: tuple[str, ...] = ("rms_error_N", "mass_g")
    constraint_names: tuple[str, ...] = ("stress_ratio_minus_1",)
    variable_meanings: dict = field(default_factory=lambda: dict(MEANINGS))

    def evaluate(self, x: np.ndarray) -> Evaluation:
        a, t, b = (float(v) for v in x)
        error = (a - 0.4) ** 2 + (t - 1.0) ** 2  # does not depend on B
        mass = 2.0 * t * b  # grows with t and B
        return Evaluation(
            np.array(x), np.array([error, mass]), np.array([0.8 - t]), {"mass_g": mass}
        )

    def detail(self, x: np.ndarray) -> DesignDetail:
        a, t, b = (float(v) for v in x)
        d = np.linspace(0.0, 20.0, 11)
        table = {
            "deflection_deg": d,
            "torque_Nm_sliding_l28": 0.1 * t * d,
            "torque_Nm_fixed_l40": 0.07 * t * d,
            "stress_MPa_sliding_l28": 2.0 * d,
            "stress_MPa_fixed_l40": 1.5 * d,
            "converged": np.ones(11, bool),
        }
        plot = {
            "x": "deflection_deg",
            "y": "torque_Nm_sliding_l28",
            "stress": "stress_MPa_sliding_l28",
            "target": 1.5,
            "tolerance": 0.1,
            "band_x": [5.0, 20.0],
            "allowable_MPa": 30.0,
        }
        return DesignDetail(
            self.evaluate(x), table, plot, outline=box(0, 0, 30 + 10 * a, 5 * t), height_mm=b
        )


register(
    StudyKind(
        "toy_html",
        HtmlStudy,
        check=lambda study: None,
        evaluate=None,
        problem=lambda study: HtmlProblem(),  # type: ignore[arg-type]
    )
)

STUDY = {
    "name": "html-toy",
    "geometry": {"kind": "toy_html"},
    "material": "PLA",
    "optimiser": {"algorithm": "nsga2", "pop_size": 12, "n_gen": 4, "seed": 2},
}


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    study = validate_study(json.loads(json.dumps(STUDY)))
    out = tmp_path_factory.mktemp("html") / "run"
    run_study(prepare_run(study), out=out, parallel=parallel_settings(study, workers=1))
    return out


# --------------------------------------------------------------------------------------------
# Reading the page


class _Page(HTMLParser):
    """Ids of sections, script elements (attributes and text), table headers."""

    def __init__(self) -> None:
        super().__init__()
        self.sections: list[str] = []
        self.scripts: list[tuple[dict[str, str | None], str]] = []
        self.headers: list[str] = []
        self.links: list[str] = []
        self._script: dict[str, str | None] | None = None
        self._text: list[str] = []
        self._th = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "section":
            self.sections.append(a.get("id") or "")
        elif tag == "script":
            self._script, self._text = a, []
        elif tag == "th":
            self._th, self._text = True, []
        elif tag == "a" and a.get("href"):
            self.links.append(a["href"])
        elif tag in ("link", "img", "iframe") and (a.get("href") or a.get("src")):
            self.links.append(a.get("href") or a.get("src"))

    def handle_endtag(self, tag):
        if tag == "script" and self._script is not None:
            self.scripts.append((self._script, "".join(self._text)))
            self._script = None
        elif tag == "th" and self._th:
            self.headers.append("".join(self._text))
            self._th = False

    def handle_data(self, data):
        if self._script is not None or self._th:
            self._text.append(data)


def _page(run_dir: Path) -> tuple[_Page, dict[str, dict]]:
    page = _Page()
    page.feed((run_dir / "report.html").read_text(encoding="utf-8"))
    return page, _figures(page)


def _figures(page: _Page) -> dict[str, dict]:
    """The page's figures' JSON by element id, each checked as plotly's classes checked it
    when they built the figures (tests/pipeline/flexopt_figure_check.py)."""
    figures = {
        attrs["id"]: json.loads(text)
        for attrs, text in page.scripts
        if attrs.get("type") == "application/json"
    }
    for spec in figures.values():
        assert_plotly_reads_unchanged(spec)
    return figures


def _axis_title(axis: dict) -> str:
    return (axis.get("title") or {}).get("text", "")


# --------------------------------------------------------------------------------------------
# Tests


def test_labels_are_words_with_units():
    assert label("torque_Nm_sliding_l28") == "torque, sliding, l = 28 mm (N·m)"
    assert label("stiffness_Nm_per_rad_lmin").endswith("(N·m/rad)")
    assert label("stiffness_Nmm_per_rad") == "stiffness (N·mm/rad)"
    assert label("contact_force_N") == "contact force (N)"
    assert label("rotation_deg") == "rotation (°)"
    assert label("spring_rate_N_per_mm") == "spring rate (N/mm)"
    assert label("peak_stress_MPa", "given (MPa)") == "given (MPa)"  # the kind's label wins
    assert words("torque_Nm_fixed_l40") == "torque, fixed, l = 40 mm"
    meanings = variable_meanings("constant_force", ["a3", "t3_mm", "B_mm"])
    assert meanings["a3"].startswith("where p3 sits between S2 and S3")
    assert "(mm)" in meanings["t3_mm"] and "(mm)" in meanings["B_mm"]


def test_sensitivity_and_top_designs():
    rng = np.random.default_rng(0)
    evaluations = [
        Evaluation(x, np.array([x[0] ** 3, -x[1]]), np.array([x[0] - 0.9]))
        for x in rng.uniform(0, 1, (30, 3))
    ]
    rho, basis = sensitivity(evaluations, 3, 2)
    assert rho[0, 0] == pytest.approx(1.0) and rho[1, 1] == pytest.approx(-1.0)
    assert abs(rho[0, 2]) < 0.5 and "feasible" in basis
    top = top_designs(evaluations, 5)
    assert [ev.feasible for ev in top] == [True] * 5
    assert [float(ev.f[0]) for ev in top] == sorted(float(ev.f[0]) for ev in top)


def test_run_writes_a_self_contained_report_html(run_dir):
    record = json.loads((run_dir / "run.json").read_text())
    assert "report.html" in record["files"]
    report_md = (run_dir / "report.md").read_text()
    assert "[report.html](report.html)" in report_md.split("## Settings")[0]  # linked at the top
    assert "serial evaluation" not in report_md
    assert f"| evaluation backend | {record['parallel']['description']} |" in report_md
    # the variables table of report.md: meaning and unit from the kind, bounds, best value
    assert "| variable | meaning | unit | bounds | best value |" in report_md
    assert "| a3 | where p3 sits between S2 and S3 | fraction, – | 0 – 1 |" in report_md

    page, figures = _page(run_dir)
    assert page.sections == list(SECTIONS)
    # offline: no script, stylesheet or image from the network; plotly.js inline, once
    assert not any(attrs.get("src") for attrs, _ in page.scripts)
    assert not any(str(link).startswith(("http:", "https:", "//")) for link in page.links)
    big = [text for _, text in page.scripts if len(text) > 1_000_000]
    assert len(big) == 1 and "Plotly" in big[0]

    assert set(figures) == {
        "fig-parallel-coordinates",
        "fig-scatter-matrix",
        "fig-sensitivity",
        "fig-pareto-front",
        "fig-response",
        "fig-response-stress",
        "fig-part-3d",
    }
    # parallel coordinates: every variable, objective and constraint, in words with units
    (par,) = figures["fig-parallel-coordinates"]["data"]
    dims = [d["label"] for d in par["dimensions"]]
    assert dims[:3] == ["a3", "t3 (mm)", "B (mm)"]
    assert "RMS force error over the stroke (N)" in dims and "mass (g)" in dims
    assert set(par["line"]["color"]) <= {0, 1}  # coloured by feasibility
    # scatter matrix: a feasible and an infeasible trace
    names = [t["name"] for t in figures["fig-scatter-matrix"]["data"]]
    assert any(n.startswith("feasible") for n in names)
    assert any(n.startswith("infeasible") for n in names)
    # sensitivity: objectives × variables, ρ in [-1, 1]; mass grows with B, the error does not
    (heat,) = figures["fig-sensitivity"]["data"]
    z = np.array(heat["z"], dtype=float)
    assert z.shape == (2, 3) and np.nanmax(np.abs(z)) <= 1.0
    assert heat["x"] == ["a3", "t3 (mm)", "B (mm)"]
    assert z[1, 2] > 0.3
    # Pareto front: both objectives labelled with units
    front = figures["fig-pareto-front"]["layout"]
    assert _axis_title(front["xaxis"]).endswith("(N)") and _axis_title(front["yaxis"]) == "mass (g)"

    # the response: both curves of the multi-curve kind, the target band, labelled axes
    resp = figures["fig-response"]
    curves = [t["name"] for t in resp["data"] if t.get("mode") == "lines+markers"]
    assert curves == ["torque, sliding, l = 28 mm", "torque, fixed, l = 40 mm"]
    band = [t for t in resp["data"] if t.get("fill") == "toself"]
    assert band and min(band[0]["y"]) == pytest.approx(1.4) and max(band[0]["y"]) == 1.6
    assert any(t["name"].startswith("target 1.5 N·m") for t in resp["data"])
    assert _axis_title(resp["layout"]["xaxis"]) == "deflection (°)"
    assert _axis_title(resp["layout"]["yaxis"]) == "torque (N·m)"  # both curves: in the legend
    stress = figures["fig-response-stress"]
    assert len([t for t in stress["data"] if t.get("mode") == "lines+markers"]) == 2
    assert any("allowable 30 MPa" in t["name"] for t in stress["data"])

    # the part: a closed mesh whose extent is the outline × the height
    (mesh,) = figures["fig-part-3d"]["data"]
    assert mesh["type"] == "mesh3d" and len(mesh["i"]) >= 12
    best = json.loads((run_dir / "best.json").read_text())
    assert max(mesh["z"]) - min(mesh["z"]) == pytest.approx(best["parameters"]["B_mm"], rel=1e-3)

    # every table header and axis in words; the variable meaning from the kind
    text = (run_dir / "report.html").read_text(encoding="utf-8")
    assert "<td>where p3 sits between S2 and S3</td><td>fraction, –</td>" in text
    at = page.headers.index("variable")
    assert page.headers[at : at + 5] == ["variable", "meaning", "unit", "bounds", "best design"]
    assert "RMS force error over the stroke (N)" in page.headers
    for fig in figures.values():
        for key, axis in fig["layout"].items():
            if key.startswith(("xaxis", "yaxis")) and _axis_title(axis):
                assert "_" not in _axis_title(axis), _axis_title(axis)
    for value in figures.values():
        json.dumps(value, allow_nan=False)  # strict JSON: no NaN in a figure
        assert not any(isinstance(v, float) and math.isnan(v) for v in _floats(value))


def _floats(value):
    if isinstance(value, dict):
        for v in value.values():
            yield from _floats(v)
    elif isinstance(value, list):
        for v in value:
            yield from _floats(v)
    elif isinstance(value, float):
        yield value


def test_flexopt_report_rebuilds_report_html(run_dir):
    (run_dir / "report.html").unlink()
    outcome = rebuild_report(run_dir)
    assert "report.html" in outcome.files
    page, figures = _page(run_dir)
    assert page.sections == list(SECTIONS) and "fig-part-3d" in figures


@pytest.mark.browser
@pytest.mark.skipif(shutil.which("chromium") is None, reason="chromium is not installed")
def test_report_html_draws_offline_in_a_headless_browser(run_dir, tmp_path):
    """Every figure is drawn by the embedded plotly.js in a real browser, with no network."""
    result = subprocess.run(
        [
            "chromium",
            "--headless",
            "--no-sandbox",  # CI runs as root
            "--disable-gpu",
            "--enable-unsafe-swiftshader",  # software WebGL for the 3D view and splom
            f"--user-data-dir={tmp_path / 'profile'}",
            "--proxy-server=127.0.0.1:9",  # no network: the page must need none
            "--virtual-time-budget=20000",
            "--dump-dom",
            (run_dir / "report.html").resolve().as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    dom = result.stdout
    for name in (
        "parallel-coordinates",
        "scatter-matrix",
        "sensitivity",
        "pareto-front",
        "response",
        "part-3d",
    ):
        at = dom.index(f'id="plot-{name}"')
        tag = dom[dom.rindex("<div", 0, at) : dom.index(">", at)]
        assert "js-plotly-plot" in tag, name  # plotly.js drew into the div
    assert dom.count('class="main-svg"') >= 6


# --------------------------------------------------------------------------------------------
# Targets, curves and variable meanings of the shipped kinds (issue 14 item 5 leftovers)


def _lines(ax) -> dict[str, np.ndarray]:
    """The lines of a matplotlib axes by legend label: {label: (2, n) x and y}."""
    return {ln.get_label(): np.asarray(ln.get_data(), dtype=float) for ln in ax.lines}


def test_target_overlay_forms_against_numbers_computed_here():
    x = np.linspace(0.0, 20.0, 11)
    table = {"rotation_deg": x, "torque_Nmm": 3.0 * x, "target_Nmm": 2.0 * x + 1.0}
    k, tol = 300.0, 0.05  # a stiffness target as the line K theta with a ±5 % band
    line = {"x": x, "y": k * np.radians(x)}
    spec = {"x": "rotation_deg", "left": "torque_Nmm", "target_curve": line, "tolerance_rel": tol}
    o = target_overlay(spec, table, unit="N·mm")
    np.testing.assert_allclose(o.y, k * np.radians(x))
    np.testing.assert_allclose(o.lower, (1 - tol) * k * np.radians(x))
    np.testing.assert_allclose(o.upper, (1 + tol) * k * np.radians(x))
    assert o.label == "target ± 5 %"
    # a column of the table, its band a share of its largest value, limited to band_x
    spec = {
        "x": "rotation_deg",
        "y": "torque_Nmm",
        "target_curve": "target_Nmm",
        "tolerance_of_max": 0.1,
        "band_x": [4.0, 12.0],
    }
    o = target_overlay(spec, table)
    np.testing.assert_allclose(o.x, [4.0, 6.0, 8.0, 10.0, 12.0])
    np.testing.assert_allclose(o.upper - o.y, 0.1 * 41.0)  # max |2 x + 1| over 0..20 is 41
    # a constant from the band's start to its end; a range has no single value
    o = target_overlay(
        {
            "x": "rotation_deg",
            "y": "torque_Nmm",
            "target": 5.0,
            "tolerance": 0.5,
            "band_x": [2.0, 8.0],
        },
        table,
    )
    np.testing.assert_allclose([o.x, o.y, o.lower], [[2, 8], [5, 5], [4.5, 4.5]])
    o = target_overlay({"x": "rotation_deg", "y": "torque_Nmm", "target_range": [9, 4]}, table)
    assert o.y is None and list(o.lower) == [4, 4] and list(o.upper) == [9, 9]
    # no target, a target of another column, a missing target column: nothing drawn
    assert target_overlay({"x": "rotation_deg", "y": "torque_Nmm"}, table) is None
    assert target_overlay({**spec, "target_of": "force_N"}, table) is None
    assert target_overlay({**spec, "target_curve": "nothing_Nmm"}, table) is None
    # a tolerance on an error measure: normalised by the largest target, relative, absolute
    assert measure_band("max_normalised", 0.05) == {"tolerance_of_max": 0.05}
    assert measure_band("rms_relative", 0.02) == {"tolerance_rel": 0.02}
    assert measure_band("rms", 0.3) == {}


def test_siblings_are_the_curves_of_one_quantity_and_their_comparisons():
    n = np.zeros(3)
    table = {
        "deflection_deg": n,
        "torque_Nm_sliding_l28": n,
        "stress_MPa_sliding_l28": n,
        "torque_Nm_fixed_l40": n,
        "target_torque_Nm": n,
        "reference_torque_Nm": n,
        "torque_Nm": n,
        "closed_form_torque_Nmm": n,
        "torque_Nmm": n,
        "short_Nm": n[:2],
    }
    assert siblings(table, "torque_Nm_sliding_l28") == [
        "torque_Nm_sliding_l28",
        "torque_Nm_fixed_l40",
        "torque_Nm",
        "reference_torque_Nm",
    ]
    assert siblings(table, "torque_Nm") == [
        "torque_Nm",
        "torque_Nm_sliding_l28",
        "torque_Nm_fixed_l40",
        "reference_torque_Nm",
    ]  # the target is a target, never a curve; N·mm is another unit
    assert siblings(table, "torque_Nmm") == ["torque_Nmm", "closed_form_torque_Nmm"]


@pytest.fixture(scope="module")
def leaf_result():
    study = load_study("leaf-spring-joint")
    return study, study_result(study, 1)


def test_leaf_joint_png_and_html_show_all_six_curves(leaf_result):
    study, result = leaf_result
    curves = [c for c in result.table if c.startswith("torque_Nm_")]
    assert len(curves) == 6  # three effective lengths x two structures in the shipped study
    fig = response_figure(result.table, **response_plot_args(study, result))
    torque, stress = fig.axes[:2]
    drawn = _lines(torque)
    assert sorted(drawn) == sorted(words(c) for c in curves)
    for c in curves:
        np.testing.assert_array_equal(drawn[words(c)][1], result.table[c])
    assert len([k for k in _lines(stress) if k.startswith("stress")]) == 6
    assert torque.get_ylabel() == "torque (N·m)"  # the common quantity; curves in the legend
    assert torque.get_legend() is not None

    page = render_evaluate_html(EvaluateHtmlData(study.name, study.kind, result.table, result.plot))
    figures = _figures(_feed(page))
    traces = [t for t in figures["fig-response"]["data"] if t["mode"] == "lines+markers"]
    assert sorted(t["name"] for t in traces) == sorted(words(c) for c in curves)


def test_leaf_joint_run_plot_draws_both_settings_and_the_stiffness_range():
    study = load_study("leaf-spring-joint")
    problem = get_kind(study.kind).problem(study)
    detail = problem.detail(np.array([80.0, 0.5, 10.0]))  # arm, leaf thickness, width (mm)
    spec = detail.plot
    fig = curve_figure(detail.table, spec["x"], spec["y"], spec=spec)
    (ax,) = fig.axes
    assert {words("stiffness_Nm_per_rad_lmin"), words("stiffness_Nm_per_rad_lmax")} <= set(
        _lines(ax)
    )
    (band,) = ax.collections  # the target stiffness range, shaded
    lo, hi = study.target.stiffness_range_Nm_per_rad
    ys = band.get_paths()[0].vertices[:, 1]
    assert ys.min() == pytest.approx(lo) and ys.max() == pytest.approx(hi)
    assert "target stiffness range" in band.get_label()


def test_flexure_pivot_and_cam_plots_draw_their_targets(tmp_path):
    # flexure pivot: the target stiffness K (N·mm/rad) as the torque line K theta, ±tolerance
    study = load_study("flexure-pivot")
    result = study_result(study, 1)
    k, tol = study.target.stiffness_Nmm_per_rad, study.target.tolerance_percent / 100
    theta = np.radians(result.table["rotation_deg"])
    torque = response_figure(result.table, **response_plot_args(study, result)).axes[0]
    (target,) = [v for name, v in _lines(torque).items() if name.startswith("target")]
    np.testing.assert_allclose(target[1], k * theta)
    (band,) = torque.collections
    ys = band.get_paths()[0].vertices[:, 1]
    assert ys.max() == pytest.approx((1 + tol) * k * theta.max())
    assert torque.get_xlabel() == "rotation (°)" and torque.get_ylabel() == "torque (N·mm)"

    # cam (through flexopt evaluate): the target torque curve in the PNG and in report.html
    out = evaluate_study(load_study("threshold-cam"), out=tmp_path / "cam").run_dir
    with (out / "response.csv").open() as handle:
        rows = list(__import__("csv").DictReader(handle))
    wanted = np.array([float(r["target_torque_Nm"]) for r in rows])
    page = _feed((out / "report.html").read_text(encoding="utf-8"))
    assert page.sections == list(EVALUATE_SECTIONS)
    figures = _figures(page)
    (line,) = [t for t in figures["fig-response"]["data"] if t["name"] == "target"]
    np.testing.assert_allclose(line["y"], wanted, rtol=1e-9)
    assert {"fig-response", "fig-response-stress", "fig-part-3d"} <= set(figures)
    # the verdict table, as evaluation.json judges it
    record = json.loads((out / "evaluation.json").read_text())
    assert "report.html" in record["files"]
    assert page.headers[:5] == ["requirement", "value", "bound", "margin", "verdict"]
    text = (out / "report.html").read_text(encoding="utf-8")
    assert f">{record['verdict']['overall']}</span>" in text
    for fig in figures.values():
        for key, axis in fig["layout"].items():
            if key.startswith(("xaxis", "yaxis")) and _axis_title(axis):
                assert "_" not in _axis_title(axis), _axis_title(axis)


def _feed(text: str) -> _Page:
    page = _Page()
    page.feed(text)
    return page


def test_every_optimising_kind_says_what_its_variables_mean():
    import flexopt

    seen = set()
    for info in flexopt.list_studies():
        study = load_study(info.name)
        kind = get_kind(study.kind)
        if kind.problem is None:
            continue
        if study.kind == "sea_spring":  # without its Taguchi stage (~30 s): the same names
            from flexopt.pipeline.studies.sea_spring import SeaSpringProblem

            problem = SeaSpringProblem(study, stage1={})
        else:
            problem = kind.problem(study)
        rows = variable_rows(study.kind, problem, problem.space.lower)
        assert [r[0] for r in rows] == list(problem.space.names)
        for name, meaning, unit, bounds, _ in rows:
            # words of its own, not the name spelled out: a meaning from the kind
            assert meaning not in ("–", words(name), label(name)), (info.name, name)
            assert unit and " – " in bounds, (info.name, name)
        seen.add(study.kind)
    optimising = {
        "constant_force",
        "sea_spring",
        "threshold_spring",
        "flexure_pivot",
        "leaf_spring_joint",
        "cam",
        "gripper",
        "mechanism",
    }
    assert optimising <= seen
    assert path_words("geometry.beams.upper.points_mm[1][0]") == "x of point 1 of beam 'upper' (mm)"
    assert path_words("geometry.bodies.shuttle.ref_mm.0") == (
        "x of the reference point of body 'shuttle' (mm)"
    )


def test_a_mechanism_study_draws_its_target_band_requirement():
    # constant-force-mechanism.yaml: force_N within ±2 % of 1.5 N over a drive of 0.5..30 mm
    study = load_study("constant-force-mechanism")
    result = study_result(study, 1)
    fig = response_figure(result.table, **response_plot_args(study, result))
    force = fig.axes[0]
    (target,) = [v for name, v in _lines(force).items() if name.startswith("target")]
    drive = np.asarray(result.table["drive_mm"], dtype=float)
    inside = drive[(drive >= 0.5) & (drive <= 30.0)]
    np.testing.assert_allclose(target, [inside, np.full(inside.size, 1.5)])
    (band,) = force.collections
    ys = band.get_paths()[0].vertices[:, 1]
    assert ys.min() == pytest.approx(1.5 * 0.98) and ys.max() == pytest.approx(1.5 * 1.02)
    # the user's output named force_N in its own words, not the beam kinds' end force
    assert force.get_ylabel() == "force (N)"


def test_evaluate_report_html_draws_the_robustness_band_and_shares(tmp_path):
    """A cantilever under E ±10 % (corners: the nominal, E x0.9, E x1.1). Under displacement
    control the force is proportional to E row by row, so the band drawn in report.html is
    0.9 and 1.1 times the nominal curve; a tip force held within ±1 % of the closed form
    F = 3 E I d / L^3 is met by the nominal sample only (1 of 3: NOT MET at 95 %)."""
    from flexopt.fea.materials import get_material

    L, t, w, d = 60.0, 1.5, 8.0, 0.3
    F0 = 3.0 * get_material("ABS").E_MPa * (w * t**3 / 12.0) * d / L**3
    raw = {
        "name": "cantilever-robust-html",
        "geometry": {"kind": "polyline_beam", "points_mm": [[0, 0], [L / 2, 0], [L, 0]],
                     "thickness_mm": [t] * 3, "width_mm": w, "elements": 20},
        "material": "ABS",
        "boundary": {"start": "clamped",
                     "end": {"control": "displacement", "direction": [0, 1], "max_mm": d,
                             "steps": 3, "rotation": "free", "transverse": "free"}},
        "requirements": [{"quantity": "max_abs_force_N", "name": "tip force",
                          "min": 0.99 * F0, "max": 1.01 * F0}],
        "robustness": {"E_percent": 10.0},
        "parallel": {"backend": "serial"},
    }  # fmt: skip
    out = evaluate_study(validate_study(raw), out=tmp_path / "ev").run_dir
    text = (out / "report.html").read_text(encoding="utf-8")
    page = _feed(text)
    assert page.sections == ["verdict", "summary", "response", "robustness", "part-3d"]
    figures = _figures(page)
    band, nominal = figures["fig-robustness"]["data"]
    assert band["fill"] == "toself" and nominal["name"] == "nominal"
    n = len(nominal["x"])
    force = np.abs(np.asarray(nominal["y"], dtype=float))
    low, high = np.asarray(band["y"][:n]), np.asarray(band["y"][n:][::-1])
    np.testing.assert_allclose(np.abs(low), 0.9 * force, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.abs(high), 1.1 * force, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(band["x"][:n], nominal["x"])
    layout = figures["fig-robustness"]["layout"]
    assert "_" not in _axis_title(layout["yaxis"]) and "_" not in _axis_title(layout["xaxis"])
    # the table: requirement | nominal margin | share of samples MET | robust verdict
    section = text.split('<section id="robustness">')[1].split("</section>")[0]
    table = _feed(section)
    assert table.headers == [
        "requirement",
        "nominal margin",
        "share of samples MET",
        "robust verdict (at 95 %)",
    ]
    record = json.loads((out / "evaluation.json").read_text())["robustness"]
    (tip,) = [r for r in record["requirements"] if r["name"] == "tip force"]
    assert tip["share_percent"] == pytest.approx(100.0 / 3.0) and not tip["met_robustly"]
    assert "<td>tip force</td>" in section and "<td>33.3 %</td><td>NOT MET</td>" in section


def test_rank_correlation_is_scipys_spearman_with_ties():
    """The report's own Spearman (no scipy.stats import at report time) against scipy's, with
    ties, constant stretches and both signs."""
    from flexopt.pipeline.report_html import _spearman
    from scipy.stats import spearmanr

    rng = np.random.default_rng(5)
    for _ in range(20):
        n = int(rng.integers(3, 60))
        x = rng.integers(0, 6, n).astype(float)  # many ties
        y = np.where(rng.random(n) < 0.5, -x, x) + rng.integers(0, 3, n)
        if np.ptp(x) == 0 or np.ptp(y) == 0:
            continue
        assert _spearman(x, y) == pytest.approx(spearmanr(x, y).statistic, abs=1e-12)
    x = rng.random(40)
    assert _spearman(x, 3 * x + 1) == pytest.approx(1.0) and _spearman(x, -x) == pytest.approx(-1)


# --------------------------------------------------------------------------------------------
# Issue 23 class 1 and issue 22 item 8: names in the figures' JSON, every load case, the
# allowable the verdict uses (the drawing itself: test_report_html_browser.py)


def test_no_name_can_change_how_a_figure_element_is_parsed():
    from flexopt.pipeline.report_html import script_json

    for name in ("<!--<script>x", "</script><b>", "a]]>-->&amp;", "<\u2028>"):
        text = script_json(json.dumps({"label": name}))
        assert "<" not in text and ">" not in text and "&" not in text
        assert json.loads(text) == {"label": name}  # the same value, read back


def test_the_stress_line_is_the_allowable_the_verdict_uses():
    from flexopt.optimise.requirements import AllowableStress, MaxValue
    from flexopt.pipeline.report_html import stress_limit

    metrics = {"max_peak_stress_MPa": 20.0, "blocked.max_peak_stress_MPa": 30.0}
    allowable = AllowableStress("max_peak_stress_MPa", "stress", "check", 48.0, 1.5)
    looser = MaxValue("max_peak_stress_MPa", "loose", "check", 40.0)
    blocked = MaxValue("blocked.max_peak_stress_MPa", "blocked stress", "check", 31.0)
    verdicts = [r.check(metrics) for r in (looser, allowable, blocked)]
    limit, verdict = stress_limit(verdicts)
    assert limit == pytest.approx(48.0 / 1.5) and verdict.name == "stress"
    limit, verdict = stress_limit(verdicts, "blocked")  # the case's own, and the unprefixed
    assert limit == pytest.approx(31.0) and verdict.name == "blocked stress"
    assert stress_limit([]) is None


def test_every_load_case_of_a_mechanism_is_a_response_of_the_page(tmp_path):
    from flexopt.pipeline.report_html import case_tables
    from flexopt.pipeline.runfolder import table_to_csv

    d = np.linspace(0.0, 2.0, 5)
    free = {"drive_mm": d, "drive_reaction_N": 2 * d, "ratio": 3 + d, "converged": d >= 0}
    blocked = {"drive_deg": d, "drive_reaction_Nmm": 5 * d, "converged": d >= 0}
    files = {
        "outputs.png": b"png",
        "response_free.csv": table_to_csv(free).encode(),
        "response_blocked.csv": table_to_csv(blocked).encode(),
    }
    detail = DesignDetail(Evaluation(np.zeros(1), np.zeros(1), np.zeros(0)), free, {}, files=files)
    cases = case_tables(detail)
    assert [c for c, _ in cases] == ["free", "blocked"]
    np.testing.assert_allclose(cases[1][1]["drive_reaction_Nmm"], 5 * d)
    assert cases[1][1]["converged"].dtype == bool
    stacked = {**free, "case": np.array(["a", "a", "b", "b", "b"])}
    detail = DesignDetail(detail.evaluation, stacked, {})
    cases = case_tables(detail)
    assert [c for c, _ in cases] == ["a", "b"] and len(cases[1][1]["ratio"]) == 3
    one = DesignDetail(detail.evaluation, free, {})
    assert case_tables(one) == [(None, free)]


def test_evaluate_report_draws_the_results_own_part_without_a_second_solve(monkeypatch):
    # issue 24, one result per design: the constant-force result carries its outline and height,
    # so report.html's 3D view takes the part from it and never rebuilds the design
    import flexopt.pipeline.report_html as rh
    from flexopt.pipeline.problems import study_result
    from flexopt.pipeline.study import load_study

    def refuse(*args, **kwargs):
        raise AssertionError("the design was rebuilt for the 3D view")

    monkeypatch.setattr(rh, "evaluate_part", refuse)
    study = load_study("constant-force").with_values({"fidelity.enabled": False})
    result = study_result(study)
    assert result.outline is not None and result.height_mm == pytest.approx(study.design["B"])
    page = rh.evaluate_html(study, result, {"solve_time_s": 1e9})  # over any re-solve budget
    assert page is not None and 'id="part-3d"' in page and "No 3D view" not in page
