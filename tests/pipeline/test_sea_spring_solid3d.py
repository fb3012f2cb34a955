"""The sea_spring kind's 3D hook (issue 15): check, thickness correction, verdict rows, and the
old ``check_3d`` key refused with its replacement. A coarse four-arm spiral keeps it quick."""

from __future__ import annotations

import math

import flexopt.pipeline.studies.sea_spring as ss
import numpy as np
import pytest
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.study import validate_study
from flexopt.pipeline.verdict import judge

STUDY = {
    "name": "sea-3d",
    "geometry": {"kind": "sea_spring", "topology": "spiral", "n_sets": 4},
    "material": "maraging-300",
    "taguchi": {"enabled": False},
    "mesh": {"max_edge_mm": 6.0, "elements_through": 0.5, "fillet_segments": 1},
    "design": {"sweep": 300.0, "R_pad": 30.0, "F1": 1 / 3, "F2": 0.5,
               "W1": 3.0, "W2": 2.5, "W3": 2.5, "W4": 3.0},
    # one prism layer: the check's arithmetic, not its accuracy, is under test (seconds, not
    # minutes: the 3D model has a quarter of the default's unknowns)
    "solid_3d": {"converge_peak": False, "max_checks": 2, "layers": 1},
}  # fmt: skip


def test_old_check_3d_key_names_its_replacement():
    with pytest.raises(StudyError, match=r"check_3d.*solid_3d: \{check: false\}"):
        validate_study({**STUDY, "check_3d": False})


def test_solid_3d_corrects_the_thickness_and_feeds_the_verdict():
    study = validate_study(STUDY)
    prob = ss.SeaSpringProblem(study, stage1={})
    x = np.delete(ss.design_vector(study), prob.names.index("ST"))
    _, geom, r, st = prob.solve(x, 1)
    out = prob.solid_3d(geom, r)
    assert "problem" not in out, out
    first, last = out["checks"][0], out["checks"][-1]
    assert first["ST_mm"] == pytest.approx(st) and out["ST_before_mm"] == pytest.approx(st)
    # the 2D answers at ST are the solved target; the 3D ones are that times the ratio
    k2 = 0.5 * (first["stiffness_ccw_2d_Nm_per_rad"] + first["stiffness_cw_2d_Nm_per_rad"])
    assert k2 == pytest.approx(275.0, rel=1e-9)
    ratio = first["stiffness_ratio_3d_2d"]
    assert ratio > 1.0  # restrained lateral contraction: stiffer as a solid
    assert first["stiffness_ccw_3d_Nm_per_rad"] == pytest.approx(
        ratio * first["stiffness_ccw_2d_Nm_per_rad"], rel=1e-12
    )
    if out["corrected"]:
        assert len(out["checks"]) >= 2
        # the first step: ST x target / mean 3D stiffness of the calibration
        k3 = 0.5 * (first["stiffness_ccw_3d_Nm_per_rad"] + first["stiffness_cw_3d_Nm_per_rad"])
        assert out["checks"][1]["ST_mm"] == pytest.approx(st * 275.0 / k3, rel=1e-12)
        mean = 0.5 * (last["stiffness_ccw_3d_Nm_per_rad"] + last["stiffness_cw_3d_Nm_per_rad"])
        assert abs(mean / 275.0 - 1.0) < abs(k3 / 275.0 - 1.0)
    else:
        assert abs(ratio - 1.0) <= 0.25 * 0.02 and out["ST_after_mm"] == st
    assert out["ST_after_mm"] == pytest.approx(last["ST_mm"])
    values = {**ss.solid_3d_scalars(out), "stiffness_ccw_Nm_per_rad": r.stiffness_Nm_per_rad}
    verdicts = {v.name: v for v in judge(study, values)}
    ccw = verdicts["3D stiffness ccw within 2 %"]
    assert ccw.value == pytest.approx(out["stiffness_ccw_3d_Nm_per_rad"])
    assert ccw.met == (abs(out["stiffness_error_ccw_3d_percent"]) <= 2.0)
    spread = verdicts["3D cw/ccw spread the band admits"]
    assert spread.met == out["band_reachable"]
    assert "3D peak stress ≤ allowable" in verdicts
    assert math.isfinite(out["peak_stress_3d_MPa"])
