"""The ``contact:`` declaration of the ``mechanism`` kind (beam-beam contact, issue #25 item 3):
a cantilever A pushed down at its tip onto the tip of a cantilever B under its middle (B rises
at 45 deg from its root, far below A), against the superposition of the two cantilevers'
flexibilities (small deflection, derived here: A Timoshenko in bending; B's tip along the
vertical cos^2 45 x bending and shear + sin^2 45 x axial); the same study without the
declaration is interference (NOT MET)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from flexopt.pipeline.evaluate import solve_study
from flexopt.pipeline.study import validate_study

L, T, W = 100.0, 1.0, 2.0  # beam A, mm
LB, TB, GAP, AT = 40.0, 2.0, 0.05, 50.0  # beam B (8x A's EI), the gap, where B's tip is
YB = -(T / 2 + TB / 2 + GAP)
C45 = np.sqrt(0.5)
ROOT_B = [AT - LB * C45, YB - LB * C45]

STUDY = {
    "name": "two-cantilevers-contact",
    "geometry": {
        "kind": "mechanism",
        "width_mm": W,
        "fillet_mm": 0.01,
        "beams": {
            "A": {"points_mm": [[0, 0], [L, 0]], "thickness_mm": T, "elements": 20},
            "B": {"points_mm": [ROOT_B, [AT, YB]], "thickness_mm": TB, "elements": 10},
        },
        "joints": [{"a": "A.start", "b": "ground"}, {"a": "B.start", "b": "ground"}],
        # an L-shaped frame holding both pads: one part
        "ground_outlines_mm": [[[-6, 1], [-1, 1], [-1, -31], [25, -31], [25, -36], [-6, -36]]],
    },
    "material": "PA12",
    "contact": [["A", "B"]],
    "load_cases": {
        "push": {
            "drive": {"part": "A.end", "control": "displacement", "direction": [0, -1],
                      "max_mm": 0.4, "steps": 10},
        }
    },
    "outputs": {"tip_force_N": {"quantity": "reaction"}},
    "fidelity": {"enabled": False},
}  # fmt: skip


def flexibility(m, x, c, t):
    """Downward deflection (mm) at x of a Timoshenko cantilever (thickness t, width W) clamped at
    0 under a unit force at c (bending x^2 (3c - x) / 6EI before c, c^2 (3x - c) / 6EI after,
    shear min(x, c) / kGA)."""
    ei, kga = m.E_MPa * W * t**3 / 12.0, 5.0 / 6.0 * m.G_MPa * W * t
    bend = x**2 * (3 * c - x) / 6 if x <= c else c**2 * (3 * x - c) / 6
    return bend / ei + min(x, c) / kga


def test_a_declared_pair_is_the_superposition_of_the_two_flexibilities():
    study = validate_study(copy.deepcopy(STUDY))
    result = solve_study(study)
    m = study.material.to_material()
    fll, fal = flexibility(m, L, L, T), flexibility(m, AT, L, T)
    fla, faa = flexibility(m, L, AT, T), flexibility(m, AT, AT, T)
    # B's tip under a vertical force: its transverse and axial compliances, each projected
    fb = 0.5 * flexibility(m, LB, LB, TB) + 0.5 * LB / (m.E_MPa * W * TB)
    P, R = np.linalg.solve([[fal, -(faa + fb)], [fll, -fla]], [GAP, 0.4])
    t = result.table
    # the kind solves the beams as made (0.01 mm fillet flares at the roots, its own mesh):
    # 1.0e-3 measured on both forces (the engine alone, tests/fea: 1e-4)
    assert t["tip_force_N"][-1] == pytest.approx(P, rel=2e-3)
    assert t["contact_A_B_force_N"][-1] == pytest.approx(R, rel=2e-3)
    touching = t["contact_A_B_in_contact"]
    assert not touching[0] and touching[-1]
    # before contact the gap closes as A's middle comes down (fal / fll of the tip's travel)
    closing = GAP * fll / fal
    drive, gap = t["drive_mm"], t["contact_A_B_gap_mm"]
    clear = drive < closing
    np.testing.assert_allclose(gap[clear], GAP * (1 - drive[clear] / closing), atol=1e-5)
    s = result.summary
    assert s["contact_A_B_max_force_N"] == pytest.approx(t["contact_A_B_force_N"][-1])
    verdicts = {v["name"]: v for v in result.inputs["verdicts"]}
    assert verdicts["no_interference"]["verdict"] == "MET"
    assert "pairs A-B" in verdicts["no_interference"]["bound"]
    assert verdicts["contact penetration within tolerance"]["verdict"] == "MET"


def test_without_the_declaration_the_beams_pass_through_and_interfere():
    raw = copy.deepcopy(STUDY)
    del raw["contact"]
    # far enough for A's band to cross B's square end (the contact's disk is rounder): 2 mm
    raw["load_cases"]["push"]["drive"]["max_mm"] = 2.0
    result = solve_study(validate_study(raw))
    assert not any(c.startswith("contact_") for c in result.table)
    verdicts = {v["name"]: v for v in result.inputs["verdicts"]}
    assert verdicts["no_interference"]["verdict"] == "NOT MET"
    assert "beam A" in verdicts["no_interference"]["detail"]


def test_a_pair_of_unknown_beams_is_refused_at_its_key():
    from flexopt.pipeline.errors import StudyError

    raw = copy.deepcopy(STUDY)
    raw["contact"] = [["A", "C"]]
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == "contact[0]", str(info.value)
    assert "'C' is not a beam" in str(info.value)
