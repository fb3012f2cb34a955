"""The mechanism kind's default optimiser is the hybrid (pipeline/studies/_mechanism_optimiser.py,
issue 27 item 2), and a default run's report carries the best design's gradient: report.md's
table and report.html's bar chart against central differences of the run's own objective,
computed here (issue 27 item 2's "bar chart of d(objective)/d(variable) at the optimum,
normalised by the bounds")."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from flexopt.pipeline.run import prepare_run
from flexopt.pipeline.study import load_study, validate_study
from flexopt_figure_check import assert_plotly_reads_unchanged

EXAMPLES = Path(__file__).resolve().parents[2] / "pipeline" / "examples"


def raw_of(name: str) -> dict:
    return yaml.safe_load((EXAMPLES / f"{name}.yaml").read_text(encoding="utf-8"))


@pytest.mark.parametrize("name", ["parallel-guide", "gripper-amplifier", "bistable-switch"])
def test_the_examples_with_variables_run_the_hybrid(name):
    """These examples name no method: each (variables, one objective) runs the hybrid, and its
    resolved study says so (dumped and read again: the same)."""
    assert "method" not in raw_of(name).get("optimiser", {})
    study = load_study(EXAMPLES / f"{name}.yaml")
    assert study.optimiser.method == "hybrid"
    dumped = study.model_dump(mode="json", exclude_none=True)
    assert dumped["optimiser"]["method"] == "hybrid"
    assert validate_study(dumped) == study
    setup = prepare_run(study)
    assert setup.hybrid is not None and setup.hybrid.local == "slsqp"


def test_method_ga_keeps_the_ga_alone():
    """constant-force-mechanism names method: ga (its 23-variable hybrid is too slow for its
    full-run golden); parallel-guide with method: ga runs the GA alone."""
    cfm = load_study(EXAMPLES / "constant-force-mechanism.yaml")
    assert cfm.optimiser.method == "ga" and prepare_run(cfm).hybrid is None
    raw = raw_of("parallel-guide")
    raw["optimiser"]["method"] = "ga"
    study = validate_study(raw)
    assert study.optimiser.method == "ga"
    assert prepare_run(study).hybrid is None


def test_nsga2_and_studies_without_variables_are_left_alone():
    """Several objectives (nsga2): the hybrid does not apply; a study with nothing to optimise
    (parallel-guide-stop) keeps no method, so its resolved study dumps as before."""
    raw = raw_of("gripper-amplifier")
    raw["objectives"] = [{"maximise": "free.min_advantage"}, {"minimise": "max_peak_stress_MPa"}]
    raw["optimiser"]["algorithm"] = "nsga2"
    assert validate_study(raw).optimiser.method is None
    stop = load_study(EXAMPLES / "parallel-guide-stop.yaml")
    assert stop.optimiser.method is None
    assert "method" not in stop.model_dump(mode="json", exclude_none=True)["optimiser"]
    # the kind's default optimiser block gets the default method too
    raw = raw_of("parallel-guide")
    del raw["optimiser"]
    assert validate_study(raw).optimiser.method == "hybrid"


def _table(report_md: str) -> dict[str, tuple[float, float]]:
    """{variable: (d f / d x, x range)} from report.md's sensitivity table (one objective)."""
    section = report_md.split("## Sensitivity of the best design", 1)[1]
    out = {}
    for line in section.splitlines():
        m = re.match(r"\| `([^`]+)` \| (\S+) \| (\S+) \|$", line)
        if m:
            out[m.group(1)] = (float(m.group(2)), float(m.group(3)))
    return out


def _figure(report_html: str, name: str) -> dict:
    m = re.search(
        rf'<script type="application/json" class="plotly-figure" id="fig-{name}"[^>]*>(.*?)'
        r"</script>",
        report_html,
        re.S,
    )
    assert m, f"no figure {name} in report.html"
    spec = json.loads(m.group(1))
    assert_plotly_reads_unchanged(spec)  # tests/pipeline/flexopt_figure_check.py
    return spec


def test_a_default_run_reports_the_gradient_of_its_best_design(tmp_path):
    """parallel-guide as shipped but small (GA 4 x 1, one start, 2 iterations; no plane-stress
    check): the run is a hybrid run with exact Jacobians; report.md's table and report.html's
    bar chart hold d(max_peak_stress_MPa)/dx and that times the range at the best design, equal
    to fourth-order central differences of the run problem's evaluate there (steps 1e-3 of the
    range; the peak stress is smooth in both variables where one root carries the max)."""
    from flexopt.pipeline.parallel import ParallelSettings
    from flexopt.pipeline.run import run_study

    raw = raw_of("parallel-guide")
    raw["optimiser"] = {
        "pop_size": 4,
        "n_gen": 2,
        "seed": 1,
        "hybrid": {"ga_n_gen": 1, "starts": 1, "max_iter": 2, "max_evaluations": 6},
    }
    raw["fidelity"] = {"enabled": False}
    study = validate_study(raw)
    setup = prepare_run(study)
    out = tmp_path / "run"
    run_study(setup, out=out, parallel=ParallelSettings("serial"))
    record = json.loads((out / "run.json").read_text())
    assert record["hybrid"]["method"] == "hybrid"
    assert record["hybrid"]["jacobians"]["finite_differences"] == 0
    best = json.loads((out / "best.json").read_text())
    x = np.asarray(best["x"], dtype=float)

    problem = prepare_run(study).problem
    span = problem.space.upper - problem.space.lower
    fd = np.zeros(x.size)
    for i in range(x.size):
        h = 1e-3 * span[i]

        def f(s, i=i):
            v = x.copy()
            v[i] += s
            ev = problem.evaluate(v)
            assert not ev.reason, ev.reason
            return float(ev.f[0])

        fd[i] = (8.0 * (f(h) - f(-h)) - (f(2 * h) - f(-2 * h))) / (12.0 * h)
    assert np.all(np.abs(fd) > 0.0)

    table = _table((out / "report.md").read_text(encoding="utf-8"))
    assert set(table) == set(problem.space.names)
    figure = _figure((out / "report.html").read_text(encoding="utf-8"), "gradient")
    (bar,) = figure["data"]
    bars = dict(zip(bar["x"], bar["y"], strict=True))
    assert "exact" in figure["layout"]["title"]["text"]
    for i, name in enumerate(problem.space.names):
        # report.md prints 6 significant digits
        assert table[name][0] == pytest.approx(fd[i], rel=2e-5)
        assert table[name][1] == pytest.approx(fd[i] * span[i], rel=2e-5)
        assert bars[name] == pytest.approx(fd[i] * span[i], rel=2e-5)
    # largest first
    assert np.all(np.diff(np.abs(bar["y"])) <= 0)
