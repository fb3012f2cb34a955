"""The ``stops:`` block of ``polyline_beam`` (issue #25 items 3-4): the example cantilever
pressed onto a rigid anvil at mid-span against the propped cantilever in closed form, the
contact columns, summary and verdict rows, and the refusals of bad ``stops:`` blocks."""

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
from flexopt.pipeline.verdict import judge_result

EXAMPLE = yaml.safe_load(
    (Path(pipeline.__file__).parent / "examples" / "cantilever-stop.yaml").read_text()
)


def propped(
    L: float, a: float, EI: float, kGA: float, tip_mm: float, gap_mm: float
) -> tuple[float, float]:
    """Tip force P and stop reaction R (N) of a cantilever (clamped at x = 0, length L mm,
    bending stiffness EI N mm^2, shear stiffness kGA N: fea.beam is a Timoshenko beam) whose
    tip is moved ``tip_mm`` towards a stop at x = a that it meets after ``gap_mm``: small
    deflection, by superposition of the clamped beam's deflections under a point load Q at
    x = c, w(x <= c) = Q (x^2 (3c - x) / 6EI + x / kGA):
      tip:  P (L^3 / 3EI + L / kGA) - R (a^2 (3L - a) / 6EI + a / kGA) = tip_mm
      stop: P (a^2 (3L - a) / 6EI + a / kGA) - R (a^3 / 3EI + a / kGA) = gap_mm.
    (The shear terms are ~0.2 % of the stop's compliance here, and the two equations nearly
    cancel in P: without them P would be off by ~0.3 %.)
    """
    c_tip = L**3 / (3 * EI) + L / kGA
    c_cross = a**2 * (3 * L - a) / (6 * EI) + a / kGA
    c_stop = a**3 / (3 * EI) + a / kGA
    P, R = np.linalg.solve(np.array([[c_tip, -c_cross], [c_cross, -c_stop]]), [tip_mm, gap_mm])
    return float(P), float(R)


def _study(raw: dict):
    return validate_study(copy.deepcopy(raw))


def _scaled(factor: float) -> dict:
    """The example with the drive and the anvil's gap scaled by ``factor`` (smaller deflection)."""
    raw = copy.deepcopy(EXAMPLE)
    raw["boundary"]["end"]["max_mm"] = 3.0 * factor
    apex = -(0.75 + 0.5 * factor)
    raw["stops"]["outlines"][0]["points_mm"] = [[28, -4], [32, -4], [30, apex]]
    return raw


@pytest.fixture(scope="module")
def example():
    study = _study(EXAMPLE)
    return study, solve_study(study)


def _stiffness(study) -> tuple[float, float]:
    """EI (N mm^2) and kGA (N, k = 5/6: fea.beam.BeamSettings.shear_factor) of the section."""
    material = study.material.to_material()
    t, w = study.geometry.thickness_mm[0], study.geometry.width_mm
    return material.E_MPa * w * t**3 / 12.0, 5.0 / 6.0 * material.G_MPa * w * t


def test_example_against_the_propped_cantilever(example):
    study, result = example
    P, R = propped(60.0, 30.0, *_stiffness(study), 3.0, 0.5)
    table = result.table
    # the tip moves 3 mm down: 5 % of the span, a 6 deg tip rotation, so 1 % for the nonlinearity
    assert abs(table["force_N"][-1]) == pytest.approx(P, rel=1e-2)
    assert table["anvil_contact_force_N"][-1] == pytest.approx(R, rel=1e-2)
    # first contact: the mid-span moves a^2 (3L - a) / 2L^3 = 5/16 of the tip
    assert result.summary["first_contact_displacement_mm"] == pytest.approx(0.5 * 16 / 5, rel=5e-3)
    assert result.summary["max_contact_force_N"] == pytest.approx(R, rel=1e-2)
    assert result.summary["contact_penetration_ok"] is True
    assert (
        0.0
        <= result.summary["max_penetration_mm"]
        < result.summary["contact_penetration_tolerance_mm"]
    )


def test_small_deflection_limit():
    """A tenth of the example's drive and gap: the closed form to 0.1 %."""
    study = _study(_scaled(0.1))
    result = solve_study(study)
    P, R = propped(60.0, 30.0, *_stiffness(study), 0.3, 0.05)
    assert abs(result.table["force_N"][-1]) == pytest.approx(P, rel=1e-3)
    assert result.table["anvil_contact_force_N"][-1] == pytest.approx(R, rel=1e-3)


def test_columns_and_verdict_rows(example):
    study, result = example
    t = result.table
    for col in ("anvil_contact_force_N", "anvil_gap_mm", "anvil_in_contact"):
        assert len(t[col]) == len(t["step"])
    touching = t["anvil_in_contact"]
    assert not touching[0] and touching[-1]
    assert np.all(t["anvil_contact_force_N"][~touching] == 0.0)
    assert t["anvil_gap_mm"][0] == pytest.approx(0.5)
    verdicts = {v.name: v for v in judge_result(study, result)}
    pen = verdicts["contact penetration within tolerance"]
    assert pen.met and pen.quantity == "max_penetration_mm"
    user = verdicts["anvil_contact_force_N"]  # max: 0.5 N in the example, R ~ 0.9 N
    assert not user.met and user.value == pytest.approx(t["anvil_contact_force_N"].max())
    assert "contact_shapes.png" in result.files


def test_penetration_not_met_says_why():
    """A penalty far too soft (1e-3, raised twice to 0.1): NOT MET, with the reason."""
    raw = copy.deepcopy(EXAMPLE)
    raw["stops"]["penalty_factor"] = 1e-3
    raw["requirements"] = []
    from flexopt.fea.stops import ContactSettings

    # max_raises is fea's (not a study key): a soft penalty with the default 2 raises stays soft
    soft = _study(raw)
    assert ContactSettings().max_raises == 2
    result = solve_study(soft)
    verdicts = {v.name: v for v in judge_result(soft, result)}
    pen = verdicts["contact penetration within tolerance"]
    assert not pen.met
    assert "penalty_factor 0.1" in pen.detail and "raised 2" in pen.detail
    assert result.summary["contact_penetration_ok"] is False
    assert "penetration" in result.message


def test_without_stops_nothing_changes():
    raw = copy.deepcopy(EXAMPLE)
    del raw["stops"]
    raw["requirements"] = []
    study = _study(raw)
    result = solve_study(study)
    assert not any("contact" in c or "anvil" in c for c in result.table)
    assert "max_penetration_mm" not in result.summary
    names = [v.name for v in judge_result(study, result)]
    assert "contact penetration within tolerance" not in names


def test_a_plain_list_is_the_outlines():
    raw = copy.deepcopy(EXAMPLE)
    raw["stops"] = raw["stops"]["outlines"]
    study = _study(raw)
    assert study.stops.outlines[0].name == "anvil"
    assert study.stops.penalty_factor == 1e3


def _with_stops(stops) -> dict:
    raw = copy.deepcopy(EXAMPLE)
    raw["stops"] = stops
    raw["requirements"] = []
    return raw


WALL = {"name": "wall", "points_mm": [[10, -2], [50, -2]]}

# (id, stops block, key path the message must name, words the message must contain)
BAD_STOPS = [
    (
        "overlaps the beam",
        # a block from y = -1 to 0.5 across the beam: the centreline 0.5 mm inside, plus t/2
        [{"name": "block", "points_mm": [[25, -1], [35, -1], [35, 0.5], [25, 0.5]],
          "closed": True}],
        "stops.outlines[0]",
        "overlaps the undeformed beam by 1.25 mm",
    ),
    (
        "wall through the beam",
        [WALL, {"name": "cut", "points_mm": [[45, -3], [45, 3]]}],
        "stops.outlines[1]",
        "overlaps the undeformed beam",
    ),
    ("closed with two points", [{"name": "s", "points_mm": [[0, -3], [9, -3]], "closed": True}],
     "stops.outlines[0]", "at least 3 points"),
    ("repeated point", [{"name": "s", "points_mm": [[0, -3], [0, -3], [9, -3]]}],
     "stops.outlines[0].points_mm", "coincide"),
    ("bad name", [{"name": "my stop", "points_mm": [[30, -3]]}], "stops.outlines[0].name",
     "not a stop name"),
    ("same name twice", [WALL, WALL], "stops.outlines", "already the name of [0]"),
    ("no outline", [], "stops.outlines", "at least 1"),
    ("missing points", [{"name": "s"}], "stops.outlines[0].points_mm", "missing"),
    ("a point is a pair", [{"name": "s", "points_mm": [[30, -3, 0]]}],
     "stops.outlines[0].points_mm[0]", "at most 2 items"),
    ("penalty not positive", {"outlines": [WALL], "penalty_factor": 0}, "stops.penalty_factor",
     "greater than 0"),
    ("unknown key", {"outlines": [WALL], "penalty": 10}, "stops.penalty", "penalty_factor"),
]  # fmt: skip


@pytest.mark.parametrize(("stops", "path", "words"), [b[1:] for b in BAD_STOPS],
                         ids=[b[0] for b in BAD_STOPS])  # fmt: skip
def test_bad_stops_are_refused(stops, path, words):
    with pytest.raises(StudyError) as info:
        validate_study(_with_stops(stops))
    err = info.value
    assert err.path == path, str(err)
    assert words in str(err), str(err)
    assert "\n" not in str(err)


def test_requirement_names_know_the_stops():
    raw = copy.deepcopy(EXAMPLE)
    raw["requirements"] = [{"quantity": "anvl_contact_force_N", "max": 1.0}]
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == "requirements[0].quantity"
    assert "anvil_contact_force_N" in str(info.value)
