"""A run's design as a study (issue 22, item 9): ``flexopt export RUN --format yaml`` and
``RunResult.best_study()`` write a study that ``flexopt evaluate`` solves to the run's numbers.

The run is a small two-load-case mechanism (the gripper amplifier: free jaw, blocked jaw) of 2
designs; the other kinds are checked without a run: a design off the study's own is written as
a study and evaluated, against the kind's problem evaluating that design.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import flexopt
import numpy as np
import pytest
from flexopt.pipeline.cli import main
from flexopt.pipeline.design_study import design_study
from flexopt.pipeline.problems import ExportError, build_base_problem, nominal_design

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
def two_case_run(tmp_path_factory: pytest.TempPathFactory) -> flexopt.RunResult:
    folder = tmp_path_factory.mktemp("two-case") / "run"
    with pytest.MonkeyPatch.context() as patch:
        # no best.step: its child imports OpenCascade at idle priority (a minute on a busy
        # machine); the STEP file is not what these tests are about
        patch.setattr("flexopt.pipeline.run.step_available", lambda: False)
        return flexopt.run(two_case_study(), quick=True, workers=1, seed=1, out=folder)


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
    assert evaluation["verdict"] == best["verdict"]


def _csv_rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as handle:
        return list(csv.DictReader(handle))


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
    result = flexopt.evaluate(study)
    best = json.loads((two_case_run.run_dir / "best.json").read_text(encoding="utf-8"))
    metrics = {
        k: (None if v == "" else v == "true" if v in ("true", "false") else float(v))
        for k, v in rows[others[0]].items()
        if k in best["metrics"] and k != "verdict"
    }
    assert len(metrics) > 40
    # evaluations.csv holds 10 significant digits
    assert not _differences(metrics, result.summary, 1e-9)


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


@pytest.mark.parametrize("name", ["threshold-cam", "gripper", "parallel-guide"])
def test_a_design_as_a_study_evaluates_to_the_designs_numbers(name: str) -> None:
    """Kinds that keep their design in other places: keys of the variable's name (cam), another
    kind's study (gripper: its resolved constant_force beam, a design: block), variables."""
    study = flexopt.load_study(name)
    problem = build_base_problem(study)
    x = _off_nominal(problem, study)
    assert not np.allclose(x, nominal_design(problem, study))
    metrics = problem.evaluate(x).metrics
    written = design_study(study, problem, x)
    np.testing.assert_allclose(nominal_design(build_base_problem(written), written), x, rtol=1e-12)
    result = flexopt.evaluate(written)
    assert not _differences(dict(metrics), result.summary, 1e-9)


def test_a_kind_that_keeps_no_design_is_refused() -> None:
    import flexopt_toys  # registers toy_faults

    study = flexopt.load_study(flexopt_toys.study())
    problem = build_base_problem(study)
    with pytest.raises(ExportError, match="keeps no single key for a, b, c"):
        design_study(study, problem, np.array([0.1, 0.2, 0.3]))
