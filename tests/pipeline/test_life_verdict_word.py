"""The mechanism kind states a ``verdict`` word per design (the run's evaluations table, the
summary of ``flexopt evaluate``). With a life requirement it must agree with the verdict the
pipeline gives (session 24 found it NOT MET while the final verdict said MET: the kind judged the
life row without the life, which only the pipeline computes).
"""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml
from flexopt.pipeline.problems import build_base_problem, nominal_design
from flexopt.pipeline.study import validate_study
from flexopt.pipeline.verdict import LIFE_PROVISIONAL, judge_result, with_life

ROOT = Path(__file__).resolve().parents[2]
RAW = yaml.safe_load((ROOT / "pipeline/examples/parallel-guide.yaml").read_text("utf-8"))


def study_with_life(minimum: float, role: str = "check"):
    raw = copy.deepcopy(RAW)
    raw["duty_cycle"] = {"rate_hz": 1.0, "levels": [{"fraction": 1.0, "cycles": 1}]}
    raw["requirements"] = [
        *raw["requirements"],
        {"quantity": "life_cycles", "min": minimum, "role": role, "name": "service life"},
    ]
    return validate_study(raw)


@pytest.fixture(scope="module")
def raw_result():
    """The nominal design's result as the kind gives it (before the pipeline's life)."""
    study = study_with_life(1.0e3)
    problem = build_base_problem(study)
    return problem.result(nominal_design(problem, study))


@pytest.mark.parametrize("minimum", [1.0e3, 1.0e30])
def test_the_evaluate_summary_word_agrees_with_the_verdict(raw_result, minimum):
    study = study_with_life(minimum)
    result = with_life(study, raw_result)
    verdicts = judge_result(study, result)
    life = next(v for v in verdicts if v.name == "service life")
    assert life.met == (minimum < result.summary["life_cycles"])
    # every other row of the nominal parallel guide is met: the word follows the life row
    assert all(v.met for v in verdicts if v.name != "service life")
    assert result.summary["verdict"] == ("MET" if life.met else "NOT MET")
    # the kind's own rows no longer carry a life judged without the life
    assert raw_result.verdicts and all(v.quantity != "life_cycles" for v in raw_result.verdicts)


def test_a_designs_word_takes_the_life_it_was_given_or_says_it_has_none():
    met = study_with_life(1.0e3, role="constraint")
    problem = build_base_problem(met)
    x = nominal_design(problem, met)
    ev = problem.evaluate(x)  # LifeConstraints: the life of this design, from its detail
    assert ev.metrics["life_cycles"] > 1.0e3 and ev.metrics["verdict"] == "MET"
    check = study_with_life(1.0e3)
    ev = build_base_problem(check).evaluate(x)  # a check: not computed per design
    assert "life_cycles" not in ev.metrics
    assert ev.metrics["verdict"] == "MET" + LIFE_PROVISIONAL
