"""The ``stops:`` block of the ``leaf_spring_joint`` kind (issue #25 item 3, the constrained-beam
engine): the example's joint (sliding structure, one effective length) with a pin over the
middle of the leaf. Before contact the leaf is a cantilever whose tip is moved l_j sin(theta)
across it with a free slope, so its middle moves 5/16 of that (small deflection, derived here):
the pin closes where that equals its gap. Columns, summary, verdict rows, the refusals."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import flexopt.pipeline as pipeline
import numpy as np
import pytest
import yaml
from flexopt.pipeline.durability_report import durability_record
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.evaluate import solve_study
from flexopt.pipeline.study import validate_study
from flexopt.pipeline.verdict import judge_result

RAW = yaml.safe_load(
    (Path(pipeline.__file__).parent / "examples" / "leaf-spring-joint.yaml").read_text()
)
ARM, LENGTH, T, GAP = 56.0, 38.0, 0.5, 0.1  # mm
PIN = (ARM - LENGTH / 2, T / 2 + GAP)  # over the leaf's middle, in the joint's frame (O at 0)


def _raw():
    raw = copy.deepcopy(RAW)
    raw["geometry"]["effective_lengths_mm"] = [LENGTH]
    raw["geometry"]["structures"] = ["sliding"]
    raw["boundary"] = {"max_deflection_deg": 1.0, "steps": 10, "check_deflection_deg": None}
    raw["stops"] = [{"name": "pin", "points_mm": [list(PIN)]}]
    raw["requirements"] = [{"name": "pin force", "quantity": "max_contact_force_N", "max": 15.0}]
    return raw


@pytest.fixture(scope="module")
def solved():
    study = validate_study(_raw())
    return study, solve_study(study)


def test_the_pin_closes_where_the_leaf_middle_meets_it(solved):
    study, result = solved
    t, s = result.table, result.summary
    curve = f"sliding_l{LENGTH:g}"
    # the middle of a cantilever with a transverse tip motion d and a free tip slope moves
    # a^2 (3L - a) / (2 L^3) d = 5/16 d; shear adds < 1e-3 of it for this leaf
    exact = math.degrees(math.asin(GAP * 16 / 5 / ARM))
    assert s["first_contact_deflection_deg"] == pytest.approx(exact, rel=5e-3)
    assert s[f"{curve}_first_contact_deflection_deg"] == s["first_contact_deflection_deg"]
    touching = t[f"pin_in_contact_{curve}"]
    assert np.array_equal(touching, t["deflection_deg"] > exact)
    force = t[f"pin_contact_force_N_{curve}"]
    assert np.all(force[~touching] == 0.0) and np.all(force[touching] > 0.0)
    assert s["max_contact_force_N"] == pytest.approx(force.max())
    assert t[f"pin_gap_mm_{curve}"][0] == pytest.approx(GAP, abs=1e-12)
    assert s["contact_penetration_ok"] and s["max_penetration_mm"] < 1e-3 * T
    verdicts = {v.name: v for v in judge_result(study, result)}
    assert verdicts["pin force"].met and verdicts["pin force"].value == s["max_contact_force_N"]
    assert verdicts["contact penetration within tolerance"].met
    record = durability_record(study, result)["contact"]
    assert record["first_contact_column"] == "first_contact_deflection_deg"
    # the pin props the leaf: the joint stiffens past contact
    k = t[f"stiffness_Nm_per_rad_{curve}"]
    assert np.nanmin(k[touching][1:]) > 1.5 * np.nanmax(k[~touching])


def test_stops_with_the_fixed_structure_are_refused():
    raw = _raw()
    raw["geometry"]["structures"] = ["sliding", "fixed"]
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == "stops" and "sliding structure only" in str(info.value)


def test_a_stop_across_the_leaf_is_refused_at_its_key():
    raw = _raw()
    raw["stops"][0]["points_mm"] = [[PIN[0], 0.0]]
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == "stops.outlines[0]", str(info.value)
    assert "overlaps the undeformed leaf by 0.25 mm" in str(info.value)
