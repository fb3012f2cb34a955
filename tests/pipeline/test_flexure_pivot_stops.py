"""The ``stops:`` block of the ``flexure_pivot`` kind (issue #25 item 3, the constrained-beam
engine): the example ``flexure-pivot-stop`` (a leaf pivot turned onto a pin above its leaf)
against answers computed here — before contact the leaf under a pure moment is a circular arc
of curvature theta / L (exact for the beam model: no shear or axial force), so the rotation at
first contact is where that arc comes within t/2 of the pin; the stop's columns, summary and
verdict rows, the Durability record; a study without stops unchanged; the refusals."""

from __future__ import annotations

import copy
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
from scipy.optimize import brentq

EXAMPLE = yaml.safe_load(
    (Path(pipeline.__file__).parent / "examples" / "flexure-pivot-stop.yaml").read_text()
)


def _study(raw):
    return validate_study(copy.deepcopy(raw))


def arc_first_contact_deg(length, t, pin):
    """The block's rotation (deg) at which a leaf of ``length`` (mm) from (0, 0) along x, bent
    into the arc of radius R = length / theta centred at (0, R), comes within t/2 of ``pin``."""
    x, y = pin

    def gap(theta):
        radius = length / theta
        return radius - np.hypot(x, radius - y) - t / 2

    return float(np.degrees(brentq(gap, 1e-3, 1.0, xtol=1e-14)))


@pytest.fixture(scope="module")
def example():
    # sharp roots: the arc of a uniform leaf is exact only without the root fillets' flare
    raw = copy.deepcopy(EXAMPLE)
    raw["geometry"]["leaf_root_fillet_mm"] = 0.0
    study = _study(raw)
    return study, solve_study(study)


def test_example_first_contact_is_the_arc_meeting_the_pin(example):
    study, result = example
    t, s = result.table, result.summary
    d = study.design
    exact = arc_first_contact_deg(d.length_mm, d.thickness_mm, (12.5, 1.675))
    # the closing rotation: extrapolated from the two open rows before it (1 deg apart)
    assert s["first_contact_rotation_deg"] == pytest.approx(exact, rel=5e-4)
    assert s["pin_first_contact_rotation_deg"] == s["first_contact_rotation_deg"]
    touching = t["pin_in_contact"]
    assert np.array_equal(touching, t["rotation_deg"] > exact)
    assert np.all(t["pin_contact_force_N"][~touching] == 0.0)
    assert np.all(t["pin_contact_force_N"][touching] > 0.0)
    assert t["pin_gap_mm"][0] == pytest.approx(0.6, abs=1e-12)
    # before contact the gap is the arc's: R - |pin - centre| - t/2
    clear = ~touching & (t["rotation_deg"] > 0)
    theta = np.radians(t["rotation_deg"][clear])
    radius = d.length_mm / theta
    arc_gap = radius - np.hypot(12.5, radius - 1.675) - d.thickness_mm / 2
    np.testing.assert_allclose(t["pin_gap_mm"][clear], arc_gap, atol=1e-6)
    assert s["max_contact_force_N"] == pytest.approx(np.nanmax(t["pin_contact_force_N"]))
    assert s["contact_rows"] == int(touching.sum())
    assert s["contact_penetration_ok"] and s["max_penetration_mm"] < 1e-3 * d.thickness_mm
    verdicts = {v.name: v for v in judge_result(study, result)}
    assert verdicts["pin force"].met and verdicts["pin force"].value == s["max_contact_force_N"]
    assert verdicts["contact penetration within tolerance"].met
    # the pin props the leaf: the torque beyond contact rises above the free leaf's line
    k = t["stiffness_Nmm_per_rad"]
    assert np.nanmin(k[touching][1:]) > 1.5 * np.nanmax(k[~touching])
    # with stops the outline's plane-stress check (no contact) is not made, and said so
    assert "plane_stress_stiffness_Nmm_per_rad" not in s
    record = durability_record(study, result)["contact"]
    assert record["first_contact_column"] == "first_contact_rotation_deg"
    assert record["stops"][0]["max_contact_force_N"] == s["max_contact_force_N"]


def test_without_stops_nothing_changes_before_contact(example):
    _, with_stop = example
    raw = copy.deepcopy(EXAMPLE)
    raw["geometry"]["leaf_root_fillet_mm"] = 0.0  # the fixture's leaf
    del raw["stops"]
    raw["requirements"] = []
    raw["fidelity"]["plane_stress"] = False
    result = solve_study(_study(raw))
    assert not any("pin" in c for c in result.table)
    assert "max_contact_force_N" not in result.summary
    names = [v.name for v in judge_result(_study(raw), result)]
    assert "contact penetration within tolerance" not in names
    assert "stops" not in _study(raw).model_dump(mode="json")
    clear = ~with_stop.table["pin_in_contact"]
    # the reference loop (with stops) against the compiled one: round-off
    np.testing.assert_allclose(
        with_stop.table["torque_Nmm"][clear],
        result.table["torque_Nmm"][clear],
        rtol=1e-8,
        atol=1e-12,
    )


def test_a_stop_overlapping_the_leaf_is_refused_at_its_key():
    raw = copy.deepcopy(EXAMPLE)
    raw["stops"]["outlines"][0]["points_mm"] = [[12.5, 0.5]]
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == "stops.outlines[0]", str(info.value)
    assert "stop 'pin' overlaps member 0 of the undeformed pivot by 0.575 mm" in str(info.value)


def test_stops_with_a_notch_candidate_are_refused():
    raw = copy.deepcopy(EXAMPLE)
    raw["geometry"]["candidates"] = ["leaf", "circular_notch"]
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == "stops"
    assert "circular_notch" in str(info.value) and "closed forms" in str(info.value)


def test_requirement_names_know_the_stops():
    raw = copy.deepcopy(EXAMPLE)
    raw["requirements"] = [{"quantity": "pin_contact_forc_N", "max": 1.0}]
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == "requirements[0].quantity"
    assert "pin_contact_force_N" in str(info.value)


def test_a_ga_design_whose_leaf_crosses_a_stop_fails_with_the_reason():
    from flexopt.pipeline.studies.flexure_pivot import problem

    study = _study(EXAMPLE)
    # a leaf 3.6 mm thick reaches 1.8 mm above its centreline: past the pin at 1.675 mm
    ev = problem(study).evaluate(np.array([0.5, 25.0, 3.6, 0.5]))
    assert not ev.feasible
    assert "stop 'pin' overlaps member 0" in ev.reason
