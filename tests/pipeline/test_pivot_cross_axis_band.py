"""Two flexure-pivot verdicts made true for the part as made (issue 27, session 27):

* a ``cross_axis`` design has no exported part (its leaves cross in separate layers, which the
  planar outline does not draw: no STL, no plane-stress check) and oblique sharp roots with no
  Kt model: its peak-stress row is NOT MET with that reason, its stiffness band and envelope
  rows NOT MET (they would judge a part of which no file is written), its life not computed,
  and the GA counts it infeasible (pipeline/studies/_pivot_roots.py);
* the GA judges a planar design's stiffness band on the verdict's own figure, the linear
  plane-stress stiffness of the check (pipeline/studies/_pivot_band.py): a design in the band by
  the beam but out of it by plane stress is infeasible.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.pipeline.studies import get_kind
from flexopt.pipeline.studies._pivot_band import DOUBT, KEY
from flexopt.pipeline.studies._pivot_roots import (
    CROSS_AXIS,
    NO_PART,
    NO_PART_ROW,
    PartMax,
    PartRange,
    RootStress,
)
from flexopt.pipeline.study import load_study

#: a cross_axis pivot near the flexure-pivot example's target (its closed-form seed: 2 E I / L
#: = 300 N·mm/rad at L = 13.72 mm, t = 1.4 mm in PETG, 6 mm wide)
CROSS = {"type": "cross_axis", "length_mm": 13.72, "thickness_mm": 1.4, "shape": 0.5}


def _study(design=None, **fidelity):
    study = load_study("flexure-pivot")
    update = {}
    if design is not None:
        update["design"] = study.design.model_copy(update=design)
    if fidelity:
        update["fidelity"] = study.fidelity.model_copy(update=fidelity)
    return study.model_copy(update=update)


def _x(study, design):
    return np.array(
        [
            study.geometry.candidates.index(design["type"]) + 0.5,
            design["length_mm"],
            design["thickness_mm"],
            design["shape"],
        ]
    )


def test_part_rows_are_not_met_without_a_part_and_unchanged_with_one():
    band = PartRange("stiffness_Nmm_per_rad", "stiffness band", "constraint", 285.0, 315.0)
    length = PartMax("envelope_length_mm", "envelope length", "constraint", 40.0)
    inside = {"stiffness_Nmm_per_rad": 300.0, "envelope_length_mm": 20.0}
    for req in (band, length):
        assert req.check({**inside, NO_PART: False}).met
        row = req.check({**inside, NO_PART: True})
        assert not row.met and NO_PART_ROW in row.detail
    stress = RootStress("peak_stress_MPa", "peak stress", "constraint", 50.0)
    row = stress.check({"peak_stress_MPa": 20.0, "unbounded_stress": True, NO_PART: True})
    assert not row.met and CROSS_AXIS in row.detail and "cross_axis" in row.bound


def test_a_cross_axis_design_is_not_met_and_says_why():
    from flexopt.pipeline.problems import study_result
    from flexopt.pipeline.verdict import judge_result

    study = _study(CROSS)
    result = study_result(study, 1)
    assert result.summary["unbounded_stress"] is True and result.summary[NO_PART] is True
    # its nominal figures would pass: the closed form's stress E t theta / (2 L) at 20 deg
    E, t, L = study.material.to_material().E_MPa, 1.4, 13.72
    assert E * t * math.radians(20.0) / (2.0 * L) < 50.0
    rows = {v.name: v for v in judge_result(study, result)}
    assert not rows["peak stress"].met and CROSS_AXIS in rows["peak stress"].detail
    for name in ("stiffness band", "envelope length", "envelope height"):
        assert not rows[name].met and NO_PART_ROW in rows[name].detail
    # the GA: infeasible on the stress row, though its nominal stress is under the allowable
    prob = get_kind("flexure_pivot").problem(study)
    ev = prob.evaluate(_x(study, CROSS))
    assert ev.f[0] < 1.0 and ev.g[1] >= 1.0 and not ev.feasible


def test_the_ga_judges_the_band_on_the_verdicts_plane_stress_stiffness():
    from flexopt.fea.closed_forms import pivot_closed_form
    from flexopt.fea.flexure_design import plane_stress_check

    # the 30 x 2.238 mm leaf session 26's run chose: in the band by the beam, under it by plane
    # stress (the verdict's figure)
    leaf = {"type": "leaf", "length_mm": 30.0, "thickness_mm": 2.238, "shape": 0.0731}
    study = _study(leaf)
    prob = get_kind("flexure_pivot").problem(study)
    x = _x(study, leaf)
    ev = prob.evaluate(x)
    kind, flex = prob.flexure(x)
    cf = pivot_closed_form(flex, prob.material.E_MPa)
    res = prob._beam(flex, 2)
    check = plane_stress_check(flex, prob.material, prob.rom_rad, 1, 4.0, cf, res, 50.0)
    K_ps = check["linear_stiffness_Nmm_per_rad"]
    assert ev.metrics[KEY] == pytest.approx(K_ps, rel=1e-12)
    assert ev.g[0] == pytest.approx(abs(K_ps / 300.0 - 1.0) - 0.05, rel=1e-9)
    beam = ev.metrics["stiffness_Nmm_per_rad"]
    assert 285.0 <= beam <= 315.0 and K_ps < 285.0 and not ev.feasible
    # without the plane-stress check the verdict judges the beam: so does the GA
    plain = get_kind("flexure_pivot").problem(_study(leaf, plane_stress=False))
    ev_beam = plain.evaluate(x)
    assert KEY not in ev_beam.metrics
    assert ev_beam.g[0] == pytest.approx(abs(beam / 300.0 - 1.0) - 0.05, rel=1e-12)
    # a design the beam puts far outside the band keeps the beam's figure (no solve): infeasible
    far = prob.evaluate(_x(study, {**leaf, "thickness_mm": 1.2}))
    assert far.metrics["stiffness_Nmm_per_rad"] < 285.0 * (1.0 - DOUBT) and KEY not in far.metrics
    assert far.g[0] > 0.0
