"""The mechanism kind's per-design ``verdict`` word and ``hold:`` requirements (session 25, the
check asked after the life fix of tests/pipeline/test_life_verdict_word.py).

The word could only disagree with the pipeline's verdict on a requirement the kind judges
without its figure; the hold's figures (here ``held_drive_reaction_N``, ``force_retention``) are the
pipeline's (pipeline/verdict.py ``with_hold``), and the mechanism kind refuses a requirement on
them when the study is read (it reports no such quantity), so no design gets a word from a hold
row judged without the hold. A ``hold:`` with no requirement on it leaves the word the kind's
own: the word equals the verdict the pipeline gives. If the kind ever accepts hold
requirements, the first test fails and the word must take the hold as ``with_life`` does.
"""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.evaluate import solve_study
from flexopt.pipeline.study import validate_study

ROOT = Path(__file__).resolve().parents[2]
RAW = yaml.safe_load((ROOT / "pipeline/examples/parallel-guide.yaml").read_text("utf-8"))
CREEPING = {  # PA12's stiffness with an assumed creep law, so that hold: is accepted
    "name": "PA12-assumed-creep", "E_MPa": 1700.0, "nu": 0.4, "yield_MPa": 48.0,
    "density_kg_m3": 1010.0, "source": "test",
    "creep": {"tau_h": 5000.0, "n": 0.25, "max_stress_ratio": 0.9, "assumed": True,
              "source": "assumed for the test"},
}  # fmt: skip


def _held(requirements):
    raw = copy.deepcopy(RAW)
    raw["material"] = CREEPING
    raw["hold"] = {"time_h": 100.0, "at": "displacement", "level": 3.0}
    raw["requirements"] = requirements
    del raw["solve_width_from"], raw["variables"]
    return raw


@pytest.mark.parametrize("quantity", ["held_drive_reaction_N", "force_retention"])
def test_a_requirement_on_the_hold_is_refused_by_the_mechanism_kind(quantity):
    with pytest.raises(StudyError) as info:
        validate_study(_held([{"quantity": quantity, "min": 0.01}]))
    assert info.value.path == "requirements[0].quantity"
    assert f"reports no '{quantity}'" in str(info.value)


@pytest.mark.parametrize("sf", [1.0, 1.0e3])
def test_with_a_hold_the_word_is_the_pipelines_verdict(sf):
    result = solve_study(validate_study(_held([
        {"quantity": "max_peak_stress_MPa", "safety_factor": sf}])))  # fmt: skip
    assert result.summary["held_drive_reaction_N"] > 0.0  # the hold was computed
    word = "MET" if all(v.met for v in result.verdicts) else "NOT MET"
    assert result.summary["verdict"] == word
    assert word == ("MET" if sf == 1.0 else "NOT MET")
