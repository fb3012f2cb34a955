"""What a run shows of a two-load-case mechanism, and its designs as studies (issue 22).

Item 8: every load case and every output wherever the first was shown (console, report.md,
plots, ``Result.table`` / ``.to_dataframe()`` / ``.plot()``, ``flexopt status``), the stress
line at the allowable the verdict uses, a maximised objective shown maximised, constraints in
physical units. Item 9: ``flexopt export RUN --format yaml`` and ``RunResult.best_study()``
write a study that ``flexopt evaluate`` solves to the run's numbers.

The run is a small two-load-case mechanism (the gripper amplifier: free jaw, blocked jaw) of 2
designs, run through the command line; the other kinds are checked without a run: a design off
the study's own is written as a study and evaluated, against the kind's problem evaluating it.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import re
from pathlib import Path
from typing import Any

import flexopt
import numpy as np
import pytest
from flexopt.pipeline.cli import main
from flexopt.pipeline.design_study import design_study
from flexopt.pipeline.problems import ExportError, build_base_problem, nominal_design
from flexopt.pipeline.study import study_to_yaml

TWO_CASES = {
    "load_cases.free.drive.steps": 4,
    "load_cases.blocked.drive.steps": 4,
    "geometry.beams.hinge.elements": 8,
    "geometry.beams.link.elements": 8,
    "optimiser.quick_pop_size": 2,
    "optimiser.quick_n_gen": 1,
}


def two_case_study() -> flexopt.Study:
    """gripper-amplifier (free and blocked jaw) on a coarse mesh: a fast two-case mechanism."""
    return flexopt.load_study("gripper-amplifier").with_values(TWO_CASES)


@pytest.fixture(scope="module")
def two_case_printed(tmp_path_factory: pytest.TempPathFactory) -> tuple[flexopt.RunResult, str]:
    """``flexopt run`` of the two-case study, and what it printed on stdout."""
    base = tmp_path_factory.mktemp("two-case")
    path = base / "two-case.yaml"
    path.write_text(study_to_yaml(two_case_study()), encoding="utf-8")
    printed = io.StringIO()
    with pytest.MonkeyPatch.context() as patch, contextlib.redirect_stdout(printed):
        # no best.step: its child imports OpenCascade at idle priority (a minute on a busy
        # machine); the STEP file is not what these tests are about
        for where in ("runner", "state"):  # the early child, the one at the report
            patch.setattr(f"flexopt.pipeline.run.{where}.step_available", lambda: False)
        command = ["run", str(path), "--quick", "--workers", "1", "--seed", "1", "--quiet"]
        assert main([*command, "--out", str(base / "run")]) == 0
    return flexopt.open_run(base / "run"), printed.getvalue()


@pytest.fixture(scope="module")
def two_case_run(two_case_printed: tuple[flexopt.RunResult, str]) -> flexopt.RunResult:
    return two_case_printed[0]


# --------------------------------------------------------------------------------------------
# Item 8: every load case and every output


def test_console_summary_shows_every_case_maximised_and_physical(
    two_case_printed: tuple[flexopt.RunResult, str],
) -> None:
    run, printed = two_case_printed
    assert "negative_" not in printed
    advantage = run.best.metrics["free.min_advantage"]
    assert advantage > 3  # the objective, maximised: a positive ratio
    assert re.search(rf"maximise free\.min_advantage\s*│\s*{advantage:.4g}", printed)
    force = run.best.metrics["free.end_input_force_N"]
    assert f"{force:.4g} N (<= 10 N)" in printed  # a constraint in N, with its bound
    # the load cases table: every case, every output
    for case, column in [("free", "advantage"), ("free", "jaw_x_mm"), ("blocked", "jaw_force_N"),
                         ("blocked", "drive_N"), ("blocked", "peak_stress_MPa")]:  # fmt: skip
        assert re.search(rf"│ {case}\s*│ {column}\s*│", printed), (case, column)


def test_report_md_shows_every_case_and_output(two_case_run: flexopt.RunResult) -> None:
    report = (two_case_run.run_dir / "report.md").read_text(encoding="utf-8")
    assert "negative_free.min_advantage |" not in report
    assert "maximise `free.min_advantage`" in report
    advantage = two_case_run.best.metrics["free.min_advantage"]
    assert f"| objective | maximise free.min_advantage | {advantage:.4g} |" in report
    cases = report.split("### Load cases", 1)[1].split("## Plots", 1)[0]
    free, blocked = cases.split("#### free", 1)[1].split("#### blocked", 1)
    for column in ("drive_mm", "input_force_N", "jaw_x_mm", "advantage", "peak_stress_MPa"):
        assert f"| {column} |" in free
    for column in ("drive_N", "input_force_N", "jaw_force_N", "peak_stress_MPa"):
        assert f"| {column} |" in blocked
    assert "| advantage |" not in blocked  # an output of the free case only
    jaw = two_case_run.best.metrics["blocked.end_jaw_force_N"]
    assert re.search(rf"\| jaw_force_N \| output \| N \| 0 \| {jaw:.6g} \|", blocked)
    for png in ("force_displacement.png", "stress.png", "outputs.png"):
        assert f"]({png})" in report


def _png_size(path: Path) -> tuple[int, int]:
    with path.open("rb") as handle:
        head = handle.read(24)
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def test_run_plots_have_a_panel_per_case(two_case_run: flexopt.RunResult) -> None:
    folder = two_case_run.run_dir
    for png in ("force_displacement.png", "stress.png"):
        width, height = _png_size(folder / png)
        assert width > 2 * height, png  # two panels side by side
    width, height = _png_size(folder / "outputs.png")
    # two columns of 5.2 in, one row of 3.4 in per unit (N, mm, ratio), at 120 dpi
    assert width >= 2 * 5.2 * 120 - 2 and height >= 3 * 3.4 * 120
    rows = _csv_rows(folder / "best_response.csv")
    assert [r["load_case"] for r in rows] == ["free"] * 5 + ["blocked"] * 5


def test_status_shows_the_objective_maximised(
    two_case_run: flexopt.RunResult, capsys: pytest.CaptureFixture
) -> None:
    assert main(["status", str(two_case_run.run_dir)]) == 0
    out = capsys.readouterr().out
    best = [line for line in out.splitlines() if line.startswith("best so far")][0]
    assert "maximise free.min_advantage = " in best and "negative" not in best
    assert "maximise free.min_advantage" in repr(two_case_run)


def test_result_table_and_plot_have_every_case() -> None:
    result = flexopt.evaluate(two_case_study())
    table = result.table
    cases = table["load_case"]
    assert list(cases) == ["free"] * 5 + ["blocked"] * 5
    assert set(result.cases) == {"free", "blocked"}
    free, blocked = cases == "free", cases == "blocked"
    # each case's own columns line up with its rows: the ratio output is jaw / input
    moving = free & (table["input_x_mm"] > 0)
    np.testing.assert_allclose(
        table["advantage"][moving], table["jaw_x_mm"][moving] / table["input_x_mm"][moving]
    )
    assert np.isnan(table["jaw_force_N"][free]).all() and np.isnan(table["drive_N"][free]).all()
    np.testing.assert_array_equal(table["drive_N"][blocked], result.cases["blocked"]["drive_N"])
    assert table["jaw_force_N"][blocked][-1] == result.summary["blocked.end_jaw_force_N"]
    assert table["step"].dtype.kind == "i"
    fig = result.plot()
    axes = [ax for ax in fig.axes if ax.axison]
    titles = {ax.get_title() for ax in fig.axes}
    assert {"load case free", "load case blocked"} <= titles
    labels = [ax.get_ylabel() for ax in axes]
    # every output on the axis of its unit: forces (N), motions (mm), the ratio (–)
    assert any(y.endswith("(N)") and "jaw force" in y for y in labels)
    assert any(y.endswith("(mm)") and "jaw x" in y for y in labels)
    assert any(y == "advantage (–)" for y in labels)
    # the stress line is the allowable the verdict uses, yield / 1.5, not the yield
    stress_lines = [
        line for ax in axes for line in ax.get_lines() if line.get_label().startswith("allowable")
    ]
    assert len(stress_lines) == 2  # one per case
    limit = next(v for v in result.verdict if v.quantity == "max_peak_stress_MPa")
    assert limit.bound.startswith("<= 32 MPa")
    assert all(line.get_ydata()[0] == pytest.approx(48.0 / 1.5) for line in stress_lines)
    pandas = pytest.importorskip("pandas")
    frame = result.to_dataframe()
    assert isinstance(frame, pandas.DataFrame)
    assert frame.groupby("load_case").size().to_dict() == {"free": 5, "blocked": 5}


def test_stress_allowable_is_the_verdicts() -> None:
    from flexopt.optimise.requirements import Verdict
    from flexopt.pipeline.responses import stress_allowable

    def verdict(quantity: str, bound: str) -> Verdict:
        return Verdict("s", quantity, 10.0, bound, 1.0, 0.1, True, "MPa")

    both = [verdict("max_peak_stress_MPa", "<= 32 MPa (yield 48 MPa / SF 1.5)"),
            verdict("blocked.max_peak_stress_MPa", "<= 20 MPa")]  # fmt: skip
    assert stress_allowable(both, "free") == (32.0, "allowable 32 MPa (yield 48 MPa / SF 1.5)")
    assert stress_allowable(both, "blocked") == (20.0, "allowable 20 MPa")
    assert stress_allowable([], "", 48.0) == (48.0, "limit 48 MPa (no requirement judges it)")
    assert stress_allowable([], "") is None


# --------------------------------------------------------------------------------------------
# Item 9: a design as a study


def _same(a: Any, b: Any, rel: float) -> bool:
    if a is None or b is None:
        return a is None and b is None
    if isinstance(a, bool) or isinstance(b, bool) or isinstance(a, str) or isinstance(b, str):
        return a == b
    a, b = float(a), float(b)
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return math.isclose(a, b, rel_tol=rel, abs_tol=1e-12)


def _differences(expected: dict[str, Any], got: dict[str, Any], rel: float) -> list[str]:
    missing = [k for k in expected if k not in got]
    assert not missing, f"evaluate does not give {missing}"
    return [
        f"{k}: {expected[k]} != {got[k]}" for k in expected if not _same(expected[k], got[k], rel)
    ]


def test_export_yaml_is_a_study_that_evaluates_to_best_json(
    two_case_run: flexopt.RunResult, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    run_dir = two_case_run.run_dir
    assert main(["export", str(run_dir), "--format", "yaml"]) == 0
    written = run_dir / "best.yaml"
    assert f"wrote {written}" in capsys.readouterr().out
    study = flexopt.load_study(written)
    best = json.loads((run_dir / "best.json").read_text(encoding="utf-8"))
    assert [v.initial for v in study.variables] == best["x"]
    assert main(["evaluate", str(written), "--out", str(tmp_path / "ev")]) == 0
    evaluation = json.loads((tmp_path / "ev" / "evaluation.json").read_text(encoding="utf-8"))
    # every number of best.json, both load cases, to the last digit (the same solve)
    assert len(best["metrics"]) > 40
    assert not _differences(best["metrics"], evaluation["summary"], 1e-12)
    # the verdict: the same rows and words, its numbers to 1e-12 as the metrics (a figure the
    # verdict derives, e.g. gripper-amplifier's actuator_force, can differ in its last bit:
    # 3.3597581482135332 against 3.359758148213533)
    ev_rows, best_rows = evaluation["verdict"]["requirements"], best["verdict"]["requirements"]
    assert len(ev_rows) == len(best_rows)
    for a, b in zip(ev_rows, best_rows, strict=True):
        assert set(a) == set(b), (a, b)
        for k in a:
            if isinstance(a[k], int | float) and isinstance(b[k], int | float):
                assert _same(b[k], a[k], 1e-12), (k, a, b)
            else:
                assert a[k] == b[k], (k, a, b)
    rest = {k: v for k, v in evaluation["verdict"].items() if k != "requirements"}
    assert rest == {k: v for k, v in best["verdict"].items() if k != "requirements"}
    # an evaluate folder's design as a study: its own study
    assert main(["export", str(tmp_path / "ev"), "--format", "yaml"]) == 0
    assert flexopt.load_study(tmp_path / "ev" / "design.yaml") == study


def _csv_rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as handle:
        return list(csv.DictReader(handle))


def _as_the_optimiser_solves(study: flexopt.Study) -> flexopt.Study:
    """``study`` solved as the optimiser solves each design: a mechanism's check of the exported
    outline (plane stress / 3D, run for the reported design only and tested in
    test_mechanism_fidelity.py) corrects the forces of ``flexopt evaluate``'s summary, not the
    optimiser's record (evaluations.csv, ``problem.evaluate``) this is compared with."""
    if study.kind == "mechanism":
        return study.with_values({"fidelity.enabled": False})
    return study


def _optimiser_summary(study: flexopt.Study, summary: dict) -> dict:
    """``summary`` of ``_as_the_optimiser_solves(study)`` as the optimiser records it: a
    mechanism's stresses times ``fidelity.beam_stress_factor`` (the optimiser's margin for the
    check of the reported design)."""
    factor = study.fidelity.beam_stress_factor if study.kind == "mechanism" else 1.0
    return {
        k: v * factor
        if isinstance(v, float) and k.endswith(("max_peak_stress_MPa", "stress_yield_ratio"))
        else v
        for k, v in summary.items()
    }


def test_every_evaluation_of_the_run_as_a_study(two_case_run: flexopt.RunResult) -> None:
    """A design other than the study's own (so the study written must differ from the run's)."""
    rows = _csv_rows(two_case_run.run_dir / "evaluations.csv")
    initial = np.array([v.initial for v in two_case_run.study.variables])
    names = two_case_run.record["variables"]
    others = [
        i for i, row in enumerate(rows) if not np.allclose([float(row[n]) for n in names], initial)
    ]
    assert others, "the run solved only the study's own design"
    index = int(rows[others[0]]["index"])
    study = two_case_run.best_study(index)
    assert [v.initial for v in study.variables] == [float(rows[others[0]][n]) for n in names]
    result = flexopt.evaluate(_as_the_optimiser_solves(study))
    best = json.loads((two_case_run.run_dir / "best.json").read_text(encoding="utf-8"))
    metrics = {
        k: (None if v == "" else v == "true" if v in ("true", "false") else float(v))
        for k, v in rows[others[0]].items()
        if k in best["metrics"] and k != "verdict"
    }
    assert len(metrics) > 40
    # evaluations.csv holds 10 significant digits
    assert not _differences(metrics, _optimiser_summary(study, result.summary), 1e-9)


def test_export_yaml_refuses_bad_arguments(
    two_case_run: flexopt.RunResult, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    run_dir = str(two_case_run.run_dir)
    assert main(["export", run_dir, "--format", "yaml", "--out", str(tmp_path / "a.stl")]) == 2
    assert "does not end in .yaml" in capsys.readouterr().err
    assert main(["export", run_dir, "--format", "yaml", "--design", "99"]) == 2
    assert "no evaluation 99" in capsys.readouterr().err
    assert main(["export", run_dir, "--out", str(tmp_path / "no" / "b.yaml")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert not (tmp_path / "a.stl").exists()
    with pytest.raises(flexopt.StudyError):
        two_case_run.best_study(99)


def _off_nominal(problem: Any, study: flexopt.Study) -> np.ndarray:
    """A design 15 % of the way from the study's own towards the middle of the bounds."""
    x0 = nominal_design(problem, study)
    middle = 0.5 * (problem.space.lower + problem.space.upper)
    return x0 + 0.15 * (middle - x0)


@pytest.mark.parametrize("name", ["threshold-cam", "gripper", "parallel-guide", "sea-spring-quick"])
def test_a_design_as_a_study_evaluates_to_the_designs_numbers(name: str) -> None:
    """Kinds that keep their design in other places: keys of the variable's name (cam), another
    kind's study (gripper: its resolved constant_force beam, a design: block), variables, a
    design: block naming them without their unit (sea_spring: F1 for F1_fraction)."""
    study = flexopt.load_study(name)
    problem = build_base_problem(study)
    x = _off_nominal(problem, study)
    assert not np.allclose(x, nominal_design(problem, study))
    metrics = problem.evaluate(x).metrics
    written = design_study(study, problem, x)
    np.testing.assert_allclose(nominal_design(build_base_problem(written), written), x, rtol=1e-12)
    result = flexopt.evaluate(_as_the_optimiser_solves(written))
    # what both report (the SEA spring's evaluate leaves out its FE counters and timings)
    common = {k: v for k, v in metrics.items() if k in result.summary and "time_s" not in k}
    assert len(common) >= 5
    assert not _differences(common, _optimiser_summary(written, result.summary), 1e-9)


def test_a_kind_that_keeps_no_design_is_refused() -> None:
    import flexopt_toys  # registers toy_faults

    study = flexopt.load_study(flexopt_toys.study())
    problem = build_base_problem(study)
    with pytest.raises(ExportError, match="keeps no single key for a, b, c"):
        design_study(study, problem, np.array([0.1, 0.2, 0.3]))


def test_progress_line_and_top_designs_show_physical_values() -> None:
    """The generation line and report.html's top-10 columns: a maximised objective as X (its
    metric), a requirement's constraint as the quantity it bounds, in its unit."""
    from flexopt.optimise.evaluation import Evaluation
    from flexopt.optimise.requirements import Verdict
    from flexopt.pipeline import labels
    from flexopt.pipeline.cli import format_generation
    from flexopt.pipeline.run import GenerationReport

    metrics = {"free.min_advantage": 4.25, "free.end_input_force_N": 7.5}
    ev = Evaluation(np.zeros(1), np.array([-4.25]), np.array([-0.25, -0.1]), metrics)
    report = GenerationReport(2, 6, 8, 0, ev, 0.5, 1.0, 1.0, ("negative_free.min_advantage",))
    assert "best 4.25 (max)" in format_generation(report)
    force = Verdict("actuator_force", "free.end_input_force_N", 7.5, "<= 10 N", 2.5, 0.25, True,
                    "N")  # fmt: skip
    headers, row = labels.design_columns(
        ("negative_free.min_advantage",), ("req_actuator_force", "stress_ratio_minus_1"), [force]
    )
    assert headers == [
        "maximise free.min_advantage",
        "actuator_force: free.end_input_force_N (N)",
        "stress_ratio_minus_1 (g ≤ 0 is met)",
    ]
    assert row(ev) == [4.25, 7.5, -0.1]
