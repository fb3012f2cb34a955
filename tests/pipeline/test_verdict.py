"""The verdict: every study kind's requirements judged MET / NOT MET, first in every output."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from flexopt.pipeline.cli import main
from flexopt.pipeline.evaluate import evaluate_study
from flexopt.pipeline.run import build_problem
from flexopt.pipeline.studies._constant_force_clamp import CHECKED_PEAK, CHECKED_PEAK_MODEL
from flexopt.pipeline.study import list_examples, load_study, resolve_study_path, validate_study


def _raw(name: str) -> dict:
    return yaml.safe_load(resolve_study_path(name).read_text(encoding="utf-8"))


def _without_3d(study):
    """The study without its 3D checks (sea_spring's ``solid_3d``: three 3D solves of ~20 s and
    ~3 GB each, checked on their own in test_sea_spring_solid3d.py); the rest as shipped."""
    s3 = getattr(study, "solid_3d", None)
    return study.with_values({"solid_3d.check": False}) if s3 is not None and s3.check else study


@pytest.mark.slow
@pytest.mark.e2e
@pytest.mark.parametrize("example", list_examples())
def test_every_example_writes_a_verdict_first(example, tmp_path):
    """Every shipped example's evaluation.json opens with a verdict of at least one requirement,
    each with its value, bound, margin and word."""
    outcome = evaluate_study(_without_3d(load_study(example)), out=tmp_path / "run")
    record = json.loads((tmp_path / "run" / "evaluation.json").read_text(encoding="utf-8"))
    assert next(iter(record)) == "verdict"
    verdict = record["verdict"]
    assert verdict["of"] >= 1 and verdict["overall"] in ("MET", "NOT MET")
    for item in verdict["requirements"]:
        assert item["verdict"] in ("MET", "NOT MET")
        assert {"name", "quantity", "value", "bound", "margin", "met", "unit", "role"} <= set(item)
        if item["margin"] is not None:
            assert (item["margin"] >= 0) == item["met"]
    assert verdict["overall"] == ("MET" if all(i["met"] for i in verdict["requirements"])
                                  else "NOT MET")  # fmt: skip
    assert len(outcome.result.verdicts) == verdict["of"]


def _cf_study(tmp_path: Path, target_N: float, extra: dict | None = None) -> Path:
    raw = _raw("constant-force")
    raw["target"]["force_N"] = target_N
    raw["target"]["tolerance_percent"] = 5.0
    raw.update(extra or {})
    path = tmp_path / "cf.yaml"
    path.write_text(yaml.safe_dump(raw), encoding="utf-8")
    return path


def test_a_constant_force_design_far_below_its_target_is_not_met(tmp_path, capsys):
    """Issue 12: a 5 N study whose design ends at a flat 3.76 N was reported as 'feasible'.

    The shipped design holds about 1.5 N; asking it for 1.5 N x 5 / 3.76 puts it as far below
    its target as 3.76 N is below 5 N. Its stress is fine (the optimiser's constraints hold),
    but the force band is NOT MET, by the margin computed here from response.csv.
    """
    target = 1.5 * 5.0 / 3.76
    path = _cf_study(tmp_path, target)
    assert main(["evaluate", str(path), "--out", str(tmp_path / "run")]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].endswith("requirements")  # the verdict comes first
    assert "overall: NOT MET" in out
    record = json.loads((tmp_path / "run" / "evaluation.json").read_text(encoding="utf-8"))
    band = next(r for r in record["verdict"]["requirements"] if r["name"] == "force band")
    with open(tmp_path / "run" / "response.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    s = np.array([float(r["displacement_mm"]) for r in rows])
    f = np.array([float(r["force_N"]) for r in rows])
    study = load_study(path)
    lo = study.boundary.stroke_mm / study.boundary.rows
    inside = (s >= lo - 1e-9) & (s <= study.boundary.stroke_mm + 1e-9)
    worst = float(np.max(np.abs(f[inside] - target)))
    assert band["verdict"] == "NOT MET" and not band["met"]
    # response.csv is the beam model's curve: its worst deviation is the beam figure; the band
    # is judged on the plane-stress figure the run also computed (issue 22), shown beside it
    beam = next(f for f in band["figures"] if f["model"] == "beam")
    assert beam["value"] == pytest.approx(worst, rel=1e-6)
    assert band["model"] == "plane stress"
    judged = band["value"]
    assert band["margin"] == pytest.approx(0.05 * target - judged, rel=1e-6)
    assert judged == pytest.approx(worst, rel=0.02)  # the two models agree to ~2 % here
    assert worst > 0.2 * target  # about 25 % low, like 3.76 N of 5 N
    stress = next(r for r in record["verdict"]["requirements"] if r["name"] == "peak stress")
    assert stress["met"]  # 'feasible' alone would have said yes
    assert record["verdict"]["overall"] == "NOT MET"


def test_a_user_requirement_is_judged_after_the_built_in_ones(tmp_path):
    reqs = [
        {"quantity": "peak_stress_MPa", "max": 30.0, "name": "tighter stress"},
        {"quantity": "force_N", "x": "displacement_mm", "over": [0.5, 30.0],
         "target": {"kind": "constant", "force_N": 1.5, "tolerance_rel": 0.05}},
    ]  # fmt: skip
    outcome = evaluate_study(
        load_study(_cf_study(tmp_path, 1.5, {"requirements": reqs})), out=tmp_path / "run"
    )
    names = [v.name for v in outcome.result.verdicts]
    assert names[-2:] == ["tighter stress", "force_N target"]
    tight = outcome.result.verdicts[-2]
    # judged, as the built-in row, on the best figure: the larger of the plane-stress check's
    # (issue 22) and the beam's at the pads (docs/constant_force.md, "Stress at the clamp")
    peak = outcome.result.summary[CHECKED_PEAK]
    assert tight.model == CHECKED_PEAK_MODEL
    assert tight.margin == pytest.approx(30.0 - peak) and tight.met is (peak <= 30.0)


def test_an_unknown_quantity_is_refused_at_load_time(tmp_path, capsys):
    raw = _raw("cantilever")
    raw["requirements"] = [{"quantity": "max_peak_stres_MPa", "max": 40.0}]
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(raw), encoding="utf-8")
    assert main(["evaluate", str(path), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "requirements[0].quantity" in err and "max_peak_stress_MPa" in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    ("item", "where", "words"),
    [
        ({"quantity": "max_peak_stress_MPa", "max": 40, "role": "constraint"}, "role",
         "not optimised"),
        ({"quantity": "max_peak_stress_MPa"}, "requirements[0]", "has none of"),
        ({"quantity": "max_peak_stress_MPa", "max": "high"}, "requirements[0].max", "number"),
    ],
)  # fmt: skip
def test_bad_requirements_name_their_key(item, where, words):
    from flexopt.pipeline.errors import StudyError

    raw = _raw("cantilever")
    raw["requirements"] = [item]
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert where in str(info.value) and words in str(info.value)


def test_a_constraint_requirement_becomes_a_row_of_the_problem():
    raw = _raw("flexure-pivot")
    raw["requirements"] = [
        {"quantity": "peak_stress_MPa", "max": 10.0, "role": "constraint", "name": "stress10"}
    ]
    problem = build_problem(validate_study(raw))
    assert problem.constraint_names[-1] == "req_stress10"
    x = (problem.space.lower + problem.space.upper) / 2
    ev = problem.evaluate(x)
    peak = ev.metrics["peak_stress_MPa"]
    assert ev.g[-1] == pytest.approx((peak - 10.0) / 10.0)


@pytest.mark.e2e
def test_a_run_opens_best_json_report_and_console_with_the_verdict(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "flexure-pivot", "--quick", "--out", str(out), "--workers", "1"]) == 0
    console = capsys.readouterr().out
    assert console.splitlines()[0].endswith("best design: requirements")
    assert "overall: " in console
    best = json.loads((out / "best.json").read_text(encoding="utf-8"))
    assert next(iter(best)) == "verdict" and best["verdict"]["of"] >= 1
    report = (out / "report.md").read_text(encoding="utf-8")
    assert report.splitlines()[2] == "## Verdict"
    assert "The design is feasible" not in report
