"""The mechanism kind's row "slender enough for the beam model (BEAM)" per member (#22,
pipeline/studies/_mechanism_slenderness.py): the polyline beam's bound L/t >= 6
(pipeline/studies/_polyline_slenderness.py, measured against plane stress in
tests/pipeline/test_polyline_slenderness.py) on each beam as made."""

from __future__ import annotations

import pytest
from flexopt.pipeline.problems import kind_problem, nominal_design
from flexopt.pipeline.studies._mechanism_slenderness import member_slenderness
from flexopt.pipeline.studies._polyline_slenderness import MIN_SLENDERNESS, SLENDER_ROW
from flexopt.pipeline.study import validate_study

T_MM = 2.5


def guide(length_mm: float) -> dict:
    """A parallel guide of two leaves ``length_mm`` long, T_MM thick, from their grounded pads
    to a shuttle that starts at the leaves' ends, moved 0.1 mm sideways."""
    L = length_mm
    return {
        "name": "stubby-guide",
        "material": "PA12",
        "geometry": {
            "kind": "mechanism", "width_mm": 10.0,
            "beams": {"upper": {"points_mm": [[0, 10], [L, 10]], "thickness_mm": T_MM},
                      "lower": {"points_mm": [[0, -10], [L, -10]], "thickness_mm": T_MM}},
            "bodies": {"shuttle": {"ref_mm": [L + 4, 0],
                                   "outline_mm": [[L, -13], [L + 8, -13], [L + 8, 13],
                                                  [L, 13]]}},
            "joints": [{"a": "upper.start", "b": "ground"}, {"a": "lower.start", "b": "ground"},
                       {"a": "upper.end", "b": "shuttle"}, {"a": "lower.end", "b": "shuttle"}],
        },
        "load_cases": {"stroke": {"drive": {"part": "shuttle", "control": "displacement",
                                            "direction": [0, 1], "max_mm": 0.1, "steps": 2}}},
        "outputs": {"force_N": {"quantity": "reaction"}},
        "requirements": [{"quantity": "max_peak_stress_MPa", "safety_factor": 1.5}],
        "fidelity": {"enabled": False},
    }  # fmt: skip


def rows(length_mm: float):
    study = validate_study(guide(length_mm))
    problem = kind_problem(study)
    solved = problem.solve(nominal_design(problem, study))
    assert not isinstance(solved, tuple), solved
    return member_slenderness(solved), {v.name: v for v in problem.judge(solved)}


def test_a_stubby_member_is_not_met_with_the_reason_where_every_other_row_is_met():
    ratios, judged = rows(5.0 * T_MM)
    # the flexible length as made: from the pad's face to the shuttle's, 12.5 mm over 2.5 mm
    assert ratios == {"upper": pytest.approx(5.0), "lower": pytest.approx(5.0)}
    for beam in ("upper", "lower"):
        row = judged[f"{SLENDER_ROW} ({beam})"]
        assert not row.met and row.value == pytest.approx(5.0) and row.role == "check"
        assert "L/t = 5 below 6" in row.detail and "docs/mechanism.md" in row.detail
    # before the row, this design was MET: every other row is
    others = [v for name, v in judged.items() if not name.startswith(SLENDER_ROW)]
    assert others and all(v.met for v in others)


def test_a_slender_member_is_met_and_the_length_is_the_one_as_made():
    ratios, judged = rows(MIN_SLENDERNESS * T_MM * 1.02)
    assert ratios["upper"] == pytest.approx(MIN_SLENDERNESS * 1.02)
    assert all(v.met for v in judged.values())
    # a beam run 5 mm into its body is clipped there: its flexible length is what is judged
    raw = guide(20.0)
    raw["geometry"]["beams"]["upper"]["points_mm"] = [[0, 10], [25, 10]]
    study = validate_study(raw)
    problem = kind_problem(study)
    solved = problem.solve(nominal_design(problem, study))
    assert member_slenderness(solved)["upper"] == pytest.approx(20.0 / T_MM, rel=1e-9)
