"""The ``stops:`` block of the ``mechanism`` kind (issue #25 item 3): a cantilever modelled in
the kind pushed onto a stop at mid-span against the propped cantilever in closed form (derived
here), the example ``parallel-guide-stop`` (the stop's columns, summary and verdict rows, first
contact where a guided leaf's middle meets the block), a body meeting a stop (modelled contact), a
study without stops unchanged, and the refusals."""

from __future__ import annotations

import copy
from pathlib import Path

import flexopt.pipeline as pipeline
import numpy as np
import pytest
import yaml
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.evaluate import solve_study
from flexopt.pipeline.study import validate_study

EXAMPLE = yaml.safe_load(
    (Path(pipeline.__file__).parent / "examples" / "parallel-guide-stop.yaml").read_text()
)


def propped(L, a, EI, kGA, tip_mm, gap_mm):
    """Tip force P and stop reaction R (N) of a Timoshenko cantilever (clamped at 0, length L
    mm) whose tip is moved ``tip_mm`` towards a stop at x = a it meets after ``gap_mm`` (small
    deflection; superposition of the clamped beam's deflections under a point load Q at c,
    w(x <= c) = Q (x^2 (3c - x) / 6EI + x / kGA)):
      tip:  P (L^3 / 3EI + L / kGA) - R (a^2 (3L - a) / 6EI + a / kGA) = tip_mm
      stop: P (a^2 (3L - a) / 6EI + a / kGA) - R (a^3 / 3EI + a / kGA) = gap_mm."""
    c_tip = L**3 / (3 * EI) + L / kGA
    c_cross = a**2 * (3 * L - a) / (6 * EI) + a / kGA
    c_stop = a**3 / (3 * EI) + a / kGA
    P, R = np.linalg.solve(np.array([[c_tip, -c_cross], [c_cross, -c_stop]]), [tip_mm, gap_mm])
    return float(P), float(R)


L, T, W, GAP = 60.0, 1.0, 5.0, 0.05  # mm

CANTILEVER = {
    "name": "cantilever-mechanism-stop",
    "geometry": {
        "kind": "mechanism",
        "width_mm": W,
        # a tiny fillet: the root's flare (the beam as made) is 0.01 mm long, so the beam is
        # the uniform cantilever of the closed form
        "fillet_mm": 0.01,
        "beams": {"leaf": {"points_mm": [[0, 0], [L, 0]], "thickness_mm": T, "elements": 30}},
        "joints": [{"a": "leaf.start", "b": "ground"}],
    },
    "material": "PA12",
    "stops": [{"name": "pin", "points_mm": [[L / 2, -(T / 2 + GAP)]]}],
    "load_cases": {
        "push": {
            "drive": {"part": "leaf.end", "control": "displacement", "direction": [0, -1],
                      "max_mm": 0.3, "steps": 12},
        }
    },
    "outputs": {"tip_force_N": {"quantity": "reaction"}},
    "fidelity": {"enabled": False},
}  # fmt: skip


def _study(raw):
    return validate_study(copy.deepcopy(raw))


@pytest.fixture(scope="module")
def example():
    study = _study(EXAMPLE)
    return study, solve_study(study)


def test_cantilever_in_the_kind_is_the_propped_cantilever():
    study = _study(CANTILEVER)
    result = solve_study(study)
    m = study.material.to_material()
    EI, kGA = m.E_MPa * W * T**3 / 12.0, 5.0 / 6.0 * m.G_MPa * W * T
    t = result.table
    P, R = propped(L, L / 2, EI, kGA, 0.3, GAP)
    # small deflection (0.5 % of the span): the reaction split to 1e-3
    assert t["tip_force_N"][-1] == pytest.approx(P, rel=1e-3)
    assert t["stop_pin_force_N"][-1] == pytest.approx(R, rel=1e-3)
    # first contact: the mid-span moves a^2 (3L - a) / 2L^3 = 5/16 of the tip
    s = result.summary
    assert s["first_contact_mm"] == pytest.approx(GAP * 16 / 5, rel=2e-3)
    assert s["stop_pin_first_contact_mm"] == s["first_contact_mm"]
    assert s["max_stop_force_N"] == pytest.approx(R, rel=1e-3)
    # before contact: the plain cantilever, the gap closing linearly
    clear = ~t["stop_pin_in_contact"]
    drive = t["drive_mm"]
    assert np.all(t["stop_pin_force_N"][clear] == 0.0)
    np.testing.assert_allclose(t["stop_pin_gap_mm"][clear], GAP * (1 - drive[clear] / (GAP * 3.2)),
                               atol=2e-5)  # fmt: skip


def test_example_reports_the_stop_and_its_verdict(example):
    study, result = example
    t, s = result.table, result.summary
    for col in ("stop_block_force_N", "stop_block_gap_mm", "stop_block_in_contact"):
        assert len(t[col]) == len(t["step"])
    touching = t["stop_block_in_contact"]
    assert not touching[0] and touching[-1]
    assert t["stop_block_gap_mm"][0] == pytest.approx(2.5, abs=1e-9)
    # a guided leaf's middle moves half the shuttle's travel: the block's corner (at the
    # middle, 2.5 mm below the leaf) is met at -5 mm (small deflection; 0.2 % here)
    assert s["first_contact_mm"] == pytest.approx(-5.0, rel=5e-3)
    assert s["max_stop_force_N"] == pytest.approx(np.nanmax(t["stop_block_force_N"]))
    assert s["stop_block_max_force_N"] == s["max_stop_force_N"] > 0.0
    assert s["contact_rows"] == int(touching.sum())
    assert 0.0 <= s["max_penetration_mm"] < 1e-3 * 2.4
    verdicts = {v["name"]: v for v in result.inputs["verdicts"]}
    assert verdicts["stop force"]["verdict"] == "MET"
    assert verdicts["stop engages at the end of the stroke"]["verdict"] == "MET"
    assert verdicts["contact penetration within tolerance"]["verdict"] == "MET"
    assert verdicts["no_interference"]["verdict"] == "MET"
    assert "declared stops" in verdicts["no_interference"]["bound"]
    assert "contact_shapes.png" in result.files
    assert "stops" in result.inputs["fidelity"]["skipped"]
    # the stop stiffens the guide: the drive's stiffness after contact is well above before
    k = t["stiffness_N_per_mm"]
    assert np.nanmin(k[touching][1:]) > 2.0 * np.nanmax(k[~touching])


def test_without_stops_nothing_changes_before_contact(example):
    _, with_stop = example
    raw = copy.deepcopy(EXAMPLE)
    del raw["stops"]
    raw["requirements"] = []
    # with stops the check of the exported outline is skipped (it has no contact): compare
    # with the beam model's figures
    raw["fidelity"] = {"enabled": False}
    study = _study(raw)
    result = solve_study(study)
    assert not any("stop" in c for c in result.table)
    assert "max_stop_force_N" not in result.summary
    names = [v["name"] for v in result.inputs["verdicts"]]
    assert "contact penetration within tolerance" not in names
    clear = ~with_stop.table["stop_block_in_contact"]
    # the reference loop (with stops) against the compiled one: round-off
    np.testing.assert_allclose(
        with_stop.table["force_N"][clear], result.table["force_N"][clear], rtol=1e-8, atol=1e-12
    )


def test_a_body_driven_onto_a_stop_meets_it_and_the_path_stops_there():
    """The shuttle meets a stop under it (modelled contact, fea/body_contact.py: it was
    interference before bodies met stops); the displacement drive then pushes it into a rigid
    stop, a path no part can follow: the rows beyond do not converge, and the study is not
    converged (tests/pipeline/test_mechanism_kind_body_contact.py drives a body by force onto a
    floor instead)."""
    raw = copy.deepcopy(EXAMPLE)
    # a block under the shuttle (x 58..66, bottom at y = -13, moving 6 mm down)
    raw["stops"]["outlines"].append(
        {"name": "floor", "points_mm": [[59, -18], [65, -18], [65, -17], [59, -17]],
         "closed": True}
    )  # fmt: skip
    result = solve_study(_study(raw))
    t = result.table
    ok = np.asarray(t["converged"], dtype=bool)
    assert ok[0] and not ok.all() and not result.converged
    last = int(np.flatnonzero(ok)[-1])
    # the last converged row: the shuttle 4 mm down, on the floor, which pushes back
    assert t["drive_mm"][last] == pytest.approx(-4.0)
    assert t["stop_floor_in_contact"][last] and t["stop_floor_force_N"][last] > 0.0
    assert not t["stop_floor_in_contact"][: last - 1].any()


def test_a_stop_overlapping_a_beam_is_refused_at_its_key():
    raw = copy.deepcopy(EXAMPLE)
    raw["stops"]["outlines"][0]["points_mm"] = [[22, -20], [29, -20], [29, -9.9], [22, -9.9]]
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == "stops.outlines[0]", str(info.value)
    assert "overlaps beam 'lower'" in str(info.value)


def test_requirement_names_know_the_stops():
    raw = copy.deepcopy(EXAMPLE)
    raw["requirements"] = [{"quantity": "stop_blok_force_N", "max": 1.0}]
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == "requirements[0].quantity"
    assert "stop_block_force_N" in str(info.value)


def test_first_contact_of_a_rotation_drive_is_in_degrees():
    """The end section turned (clockwise: the tip bends down) onto the pin: the first contact
    is reported in the drive's unit (deg), between the last open and the first closed row."""
    raw = copy.deepcopy(CANTILEVER)
    raw["load_cases"]["push"]["drive"] = {
        "part": "leaf.end", "control": "rotation", "max_deg": -1.0, "steps": 10,
        "transverse": "free",
    }  # fmt: skip
    raw["outputs"] = {"tip_moment_Nmm": {"quantity": "reaction"}}
    result = solve_study(_study(raw))
    t, s = result.table, result.summary
    touching = t["stop_pin_in_contact"]
    assert touching[-1] and not touching[0]
    k = int(np.argmax(touching))
    lo, hi = sorted((t["drive_deg"][k - 1], t["drive_deg"][k]))
    assert lo <= s["first_contact_deg"] <= hi
    assert s["stop_pin_max_force_N"] > 0.0
