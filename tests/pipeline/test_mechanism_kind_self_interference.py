"""The ``mechanism`` kind's interference check of a beam against itself (issue #25, the
FALSE-MET found in session 25: a beam was never compared with itself):

* the hook of tests/fea/test_mechanism_body_contact.py (PA12) curled by an end moment of
  0.4 N mm with no contact declared: its straight tip passes through its own leg (the exact
  pure-bending shape puts the tip's centre inside the leg's band, computed here) -> the
  no-interference row NOT MET, saying the beam, where along it and how much;
* the same hook with ``contact: [[hook, hook]]``: the self contact is modelled, the tip rests on
  the leg, no interference (the overlap of the contact's penetration, ~1e-6 mm, is far below
  the threshold) and the row MET.

The gently curved and straight beam (no false alarm) and the overlap's exact area are in
tests/fea/test_mechanism_self_overlap.py.
"""

from __future__ import annotations

import copy
import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest
from flexopt.pipeline.evaluate import solve_study
from flexopt.pipeline.study import validate_study

HOOK = {
    "name": "hook-self-interference",
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


def _exact(material):
    """tests/fea/test_mechanism_body_contact.py (the hook's exact pure-bending shape) with its
    material set to ``material``."""
    path = Path(__file__).resolve().parents[1] / "fea" / "test_mechanism_body_contact.py"
    spec = importlib.util.spec_from_file_location("_hook_exact", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.MAT = material
    return module


def _row(result):
    return {v["name"]: v for v in result.inputs["verdicts"]}["no_interference"]


@pytest.mark.parametrize("declared", [False, True])
def test_a_hook_curled_past_its_leg(declared):
    raw = copy.deepcopy(HOOK)
    if not declared:
        del raw["contact"]
    study = validate_study(raw)
    result = solve_study(study)
    row = _row(result)
    if declared:
        assert result.table["contact_hook_hook_force_N"][-1] > 0.0  # modelled, pressing
        assert row["verdict"] == "MET", row["detail"]
        assert result.summary["interference_mm2"] == 0.0
        return
    # free of contact the hook is pure bending exactly: its tip's centre at m = 0.4 N mm lies
    # inside its leg's band (distance to the leg's centreline under half the thickness)
    exact = _exact(study.material.to_material())
    ei = exact.section(exact.HT, exact.HW)[0]
    tip, _ = exact._bent(0.4, exact.HOOK_S[-1], ei)
    legs = np.array([exact._bent(0.4, s, ei)[0] for s in np.linspace(0.0, 10.0, 2001)])
    assert np.hypot(*(legs - tip).T).min() < 0.5 * exact.HT
    assert row["verdict"] == "NOT MET"
    detail = row["detail"]
    assert "row 4 (drive 0.4 Nmm): beam hook passes through itself" in detail, detail
    assert "self contact not declared" in detail
    s = [float(v) for v in re.findall(r"s = ([0-9.]+) mm", detail)]
    assert s[0] < 10.0 and s[1] > exact.HOOK_S[-1] - 2.0  # the leg and the straight tip
    assert result.summary["interference_mm2"] > 1e-3
    assert result.summary["verdict"] == "NOT MET"
