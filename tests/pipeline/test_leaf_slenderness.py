"""leaf_spring_joint's "slender enough for the beam model" row (polyline_beam's bound, reused).

The kind's bounds allow a leaf shorter than six thicknesses (an effective length of 5 mm at
t = 1 mm, or a design space up to t = 3 mm beside a 10 mm shortest free length), where the beam
model's end zones cover most of the leaf (pipeline/studies/_polyline_slenderness.py): its row
is then NOT MET with the reason. L/t is the shortest free length over the leaf thickness.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from flexopt.pipeline.problems import study_result
from flexopt.pipeline.studies._polyline_slenderness import MIN_SLENDERNESS
from flexopt.pipeline.studies.leaf_spring_joint import LeafJointProblem
from flexopt.pipeline.study import validate_study
from flexopt.pipeline.verdict import judge_result

EXAMPLES = Path(__file__).resolve().parents[2] / "pipeline" / "examples"
JOINT = yaml.safe_load((EXAMPLES / "leaf-spring-joint.yaml").read_text())
ROW = "slender enough for the beam model"


def _study(lengths, thickness):
    raw = {**JOINT}
    raw["geometry"] = {**JOINT["geometry"], "effective_lengths_mm": lengths}
    raw["geometry"]["thickness_mm"] = thickness
    raw["geometry"]["structures"] = ["sliding"]
    raw["boundary"] = {**JOINT["boundary"], "steps": 2, "check_deflection_deg": None}
    raw.pop("duty_cycle", None)
    return validate_study(raw)


@pytest.mark.parametrize(
    ("lengths", "thickness", "met"),
    [([5.0, 38.0], 1.0, False), ([6.1, 38.0], 1.0, True), ([28.0, 38.0], 0.5, True)],
)
def test_evaluate_judges_the_shortest_leaf_over_its_thickness(lengths, thickness, met):
    study = _study(lengths, thickness)
    result = study_result(study, 1)
    row = next(v for v in judge_result(study, result) if v.name == ROW)
    assert row.value == pytest.approx(min(lengths) / thickness, rel=1e-12)
    assert row.met is met
    if not met:
        assert f"below {MIN_SLENDERNESS:g}" in row.detail


def test_a_design_is_judged_at_its_stiff_setting():
    study = validate_study(JOINT)
    problem = LeafJointProblem(study)
    x = np.array([90.0, 0.54, 16.0])
    l_min, _ = problem.lengths(x)
    ev = problem.evaluate(x)
    assert ev.metrics["slenderness_ratio"] == pytest.approx(l_min / 0.54, rel=1e-12)
    verdicts = judge_result(study, problem.detail(x), design=x)
    assert next(v for v in verdicts if v.name == ROW).met
