"""Contact of the ``mechanism`` kind's bodies (issue #25 item 3, fea/body_contact.py) through
the kind:

* the example ``parallel-guide-landing``: the shuttle lands on a floor under a force; the load
  at first contact against the two guided Timoshenko leaves' stiffness times the gap (small
  deflection, derived here), the shuttle held by the floor after it, the floor's force and the
  guide's in equilibrium with the load, every row MET, the interference row MET;
* a body driven by displacement into a stop (a path no part can follow) is NOT MET: penetration
  and interference;
* two blocks on two cantilevers, declared in ``contact:``, pressed together: the superposed
  flexibilities (derived here); the same study without the declaration passes one block
  through the other: interference NOT MET;
* a hook declared in contact with itself (``contact: [[hook, hook]]``) curls onto its leg: the
  gap before contact and the contact force after it against the exact pure-bending shape and
  the Reissner elastica of tests/fea/test_mechanism_body_contact.py (PA12), penetration within
  the tolerance;
* refusals at ``contact[i]``: an unknown part, a body without an outline.
"""

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

LANDING = yaml.safe_load(
    (Path(pipeline.__file__).parent / "examples" / "parallel-guide-landing.yaml").read_text()
)


@pytest.fixture(scope="module")
def landing():
    study = validate_study(copy.deepcopy(LANDING))
    return study, solve_study(study)


def test_the_shuttle_lands_on_the_floor_at_the_guides_stiffness_times_the_gap(landing):
    study, result = landing
    m = study.material.to_material()
    t, s = result.table, result.summary
    # two clamped-guided Timoshenko leaves (58 x 2.4 x 11 mm): k = 2 / (L^3/12EI + L/kGA)
    ei = m.E_MPa * 11.0 * 2.4**3 / 12.0
    kga = 5.0 / 6.0 * m.G_MPa * 11.0 * 2.4
    k = 2.0 / (58.0**3 / (12.0 * ei) + 58.0 / kga)
    # the beams as made (their roots' fillet flares) are a little stiffer than the uniform
    # leaves, and the shuttle tilts 0.065 deg (its right corner lands): 0.8 % measured
    assert s["first_contact_N"] == pytest.approx(2.0 * k, rel=1e-2)
    touching = np.asarray(t["stop_floor_in_contact"], dtype=bool)
    assert not touching[: int(2.0 * k / 0.5) + 1].any() and touching[-1]
    assert t["stop_floor_gap_mm"][0] == pytest.approx(2.0, abs=1e-12)
    clear = ~touching
    np.testing.assert_allclose(t["stop_floor_gap_mm"][clear], 2.0 - t["travel_mm"][clear],
                               atol=0.01)  # fmt: skip  # the shuttle's 0.06 deg tilt
    # once landed the floor holds the shuttle: its travel stays at the gap (its right corner,
    # 4 mm from the reference point, down 2 mm; the penalty's penetration ~1e-6 mm)
    drop = t["travel_mm"] + 4.0 * np.sin(np.radians(-t["shuttle_rotation_deg"]))
    np.testing.assert_allclose(drop[touching], 2.0, atol=2e-5)
    # the load beyond the landing goes into the floor: what the guide carries hardly changes
    floor = np.asarray(t["stop_floor_force_N"])
    guide = t["drive_N"] - floor
    assert np.ptp(guide[touching]) < 0.01 * guide[touching].mean()
    assert guide[touching].mean() == pytest.approx(2.0 * k, rel=2e-2)
    assert s["max_stop_force_N"] == pytest.approx(floor.max())
    verdicts = {v["name"]: v for v in result.inputs["verdicts"]}
    assert all(v["verdict"] == "MET" for v in verdicts.values()), verdicts
    assert "moving bodies" in verdicts["no_interference"]["bound"]
    assert s["max_penetration_mm"] < 1e-3 * 2.4


def test_a_body_driven_into_a_stop_is_not_met():
    raw = copy.deepcopy(LANDING)
    raw["load_cases"]["overload"]["drive"] = {
        "part": "shuttle", "control": "displacement", "direction": [0, -1], "max_mm": 3.0,
        "steps": 6,
    }  # fmt: skip
    raw["requirements"] = []
    result = solve_study(validate_study(raw))
    verdicts = {v["name"]: v for v in result.inputs["verdicts"]}
    assert verdicts["contact penetration within tolerance"]["verdict"] == "NOT MET"
    bad = verdicts["no_interference"]
    assert bad["verdict"] == "NOT MET"
    assert "body shuttle passes through stop floor" in bad["detail"]
    assert "deeper than the contact's penetration" in bad["detail"]


# ------------------------------------------------------------------ two blocks

L, T, W, G = 50.0, 1.0, 5.0, 0.01  # the cantilevers and the gap between the blocks, mm
E = 2.0  # mm: where the blocks touch, right of the tips

BLOCKS = {
    "name": "two-blocks-contact",
    "geometry": {
        "kind": "mechanism",
        "width_mm": W,
        "fillet_mm": 0.01,
        "beams": {
            "A": {"points_mm": [[0, 0], [L, 0]], "thickness_mm": T, "elements": 20},
            "B": {"points_mm": [[0, -6], [L, -6]], "thickness_mm": T, "elements": 20},
        },
        "bodies": {
            # A's block: a flat face 2 mm under A's tip, right of it; B's block: a wedge, its
            # apex under the middle of that face (E = 2 mm right of the tips)
            "blkA": {"ref_mm": [L, 0], "outline_mm": [[L, -2], [L + 4, -2], [L + 4, 0.8],
                                                      [L, 0.8]]},
            "blkB": {"ref_mm": [L, -6], "outline_mm": [[L, -6.8], [L + 4, -6.8], [L + 4, -5.2],
                                                       [L + 2, -2 - G], [L, -5.2]]},
        },
        "joints": [{"a": "A.start", "b": "ground"}, {"a": "B.start", "b": "ground"},
                   {"a": "A.end", "b": "blkA"}, {"a": "B.end", "b": "blkB"}],
        "ground_outlines_mm": [[[-6, 1], [-1, 1], [-1, -7], [-6, -7]]],
    },
    "material": "PA12",
    "contact": [["blkA", "blkB"]],
    "load_cases": {
        "press": {"drive": {"part": "blkA", "control": "force", "direction": [0, -1],
                            "max_N": 0.0008, "steps": 8}},
    },
    "outputs": {"travel_mm": {"quantity": "displacement", "part": "blkA",
                              "direction": [0, -1]}},
    "fidelity": {"enabled": False},
}  # fmt: skip


def test_two_declared_blocks_pressed_together_superpose_the_cantilevers():
    """A's block under a dead load P at A's tip; the blocks touch E right of the tips. A
    cantilever's point E beyond its tip moves, under a tip force Q, Q (c + E L^2/2EI)
    (c = L^3/3EI + L/kGA; the tip's rotation Q L^2/2EI times E), and under a force F at that
    point (a tip force and a moment F E) F c_E, c_E = c + E L^2/EI + E^2 L/EI. The gap closes
    at P (c + E L^2/2EI) = G, then P (c + E L^2/2EI) - F c_E - F c_E = G - pen: both equal
    cantilevers in series (small deflection: 2e-4 L)."""
    study = validate_study(copy.deepcopy(BLOCKS))
    result = solve_study(study)
    m = study.material.to_material()
    ei, kga = m.E_MPa * W * T**3 / 12.0, 5.0 / 6.0 * m.G_MPa * W * T
    c = L**3 / (3 * ei) + L / kga
    c_p = c + E * L**2 / (2 * ei)
    c_e = c + E * L**2 / ei + E**2 * L / ei
    t = result.table
    pen = np.minimum(t["contact_blkA_blkB_gap_mm"], 0.0)
    touching = t["drive_N"] * c_p > G
    assert np.array_equal(t["contact_blkA_blkB_in_contact"], touching)
    assert 0 < touching.sum() < touching.size
    force = (t["drive_N"] * c_p - G - pen) / (2 * c_e)
    # the beams as made (0.01 mm fillet flares) and the kind's mesh: 1e-3
    np.testing.assert_allclose(t["contact_blkA_blkB_force_N"][touching], force[touching],
                               rtol=1e-3)  # fmt: skip
    verdicts = {v["name"]: v for v in result.inputs["verdicts"]}
    assert verdicts["no_interference"]["verdict"] == "MET"
    assert "pairs blkA-blkB" in verdicts["no_interference"]["bound"]
    assert result.summary["contact_blkA_blkB_max_force_N"] == pytest.approx(
        np.nanmax(t["contact_blkA_blkB_force_N"])
    )


def test_undeclared_blocks_pass_through_each_other_and_are_not_met():
    raw = copy.deepcopy(BLOCKS)
    del raw["contact"]
    result = solve_study(validate_study(raw))
    bad = {v["name"]: v for v in result.inputs["verdicts"]}["no_interference"]
    assert bad["verdict"] == "NOT MET"
    assert "body blkA passes through body blkB" in bad["detail"]


# ------------------------------------------------------------------ a hook on itself


def _hook_answers(material):
    """tests/fea/test_mechanism_body_contact.py (its hook's exact gap and elastica) with its
    material set to ``material``."""
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "fea" / "test_mechanism_body_contact.py"
    spec = importlib.util.spec_from_file_location("_hook_answers", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.MAT = material
    return module


def test_a_hook_declared_with_itself_curls_onto_its_leg():
    raw = {
        "name": "hook-self-contact",
        "geometry": {
            "kind": "mechanism",
            "width_mm": 2.0,
            "min_feature_mm": 0.4,
            "fillet_mm": 0.01,
            "beams": {"hook": {
                "points_mm": [[0, 0], [10, 0], [12, 2], [10, 4], [4, 4], [3, 3], [3, 1.0]],
                "curvature_per_mm": [0, 0.5, 0.5, 0, 1.0, 0], "thickness_mm": 0.5,
                "elements": 40}},
            "joints": [{"a": "hook.start", "b": "ground"}],
        },
        "material": "PA12",
        "contact": [["hook", "hook"]],
        "load_cases": {"curl": {"drive": {"part": "hook.end", "control": "moment",
                                          "max_Nmm": 0.4, "steps": 4}}},
        "outputs": {"tip_turn_deg": {"quantity": "rotation", "part": "hook.end"}},
        "fidelity": {"enabled": False},
    }  # fmt: skip
    study = validate_study(raw)
    result = solve_study(study)
    t = result.table
    force = np.asarray(t["contact_hook_hook_force_N"])
    assert force[0] == 0.0 and force[-1] > 0.0
    # the exact answers of tests/fea/test_mechanism_body_contact.py (pure bending before
    # contact, the Reissner elastica from the contact point after it), for PA12
    exact = _hook_answers(study.material.to_material())
    for k, m in enumerate(t["drive_Nmm"]):
        if force[k] > 0.0:
            f, _, _ = exact.hook_pressed(m, [force[k], 3.2])
            assert force[k] == pytest.approx(f, rel=1e-3)  # 1.6e-4 measured (as made)
        else:
            assert t["contact_hook_hook_gap_mm"][k] == pytest.approx(exact.hook_gap(m), abs=2e-5)
    assert result.summary["max_penetration_mm"] < 1e-3 * 0.5
    verdicts = {v["name"]: v for v in result.inputs["verdicts"]}
    assert verdicts["contact penetration within tolerance"]["verdict"] == "MET"


# ------------------------------------------------------------------ refusals


@pytest.mark.parametrize(
    ("pair", "message"),
    [(["blkA", "nope"], "'nope' is not a beam or a body"),
     (["blkA", "bare"], "body 'bare' has no outline_mm")],
)  # fmt: skip
def test_bad_contact_pairs_are_refused_at_their_key(pair, message):
    raw = copy.deepcopy(BLOCKS)
    raw["geometry"]["bodies"]["bare"] = {"ref_mm": [20, 20]}
    raw["geometry"]["joints"].append({"a": "bare", "b": "ground"})
    raw["contact"] = [pair]
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == "contact[0]", str(info.value)
    assert message in str(info.value)
