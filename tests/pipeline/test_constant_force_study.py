"""The ``constant_force`` study kind: schema errors, paper numbers, the design problem contract."""

from __future__ import annotations

import copy
import pickle
from pathlib import Path

import flexopt.pipeline as pipeline
import flexopt.pipeline.studies.constant_force as cf
import numpy as np
import pytest
import yaml
from flexopt.geometry.constant_force import (
    DESIGN_VARIABLE_NAMES,
    TABLE3_OPTIMUM,
    beam_profile,
    design_to_vector,
    outline,
)
from flexopt.optimise import DesignProblem, GAConfig, run_ga
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.study import load_study, validate_study
from shapely.geometry import Polygon

EXAMPLE_PATH = Path(pipeline.__file__).parent / "examples" / "constant-force.yaml"
EXAMPLE = yaml.safe_load(EXAMPLE_PATH.read_text())
# sharp pads: the paper's beam, whose figures docs/constant_force.md sections 5-6 measured (the
# kind's default 0.5 mm pad fillets stiffen it by 0.2-1 %; tests of the fillets:
# test_constant_force_pad_fillet_key.py)
MINIMAL = {
    "name": "cf",
    "geometry": {"kind": "constant_force", "pad_fillet_mm": 0},
    "material": "ABS",
}
TABLE3 = design_to_vector(TABLE3_OPTIMUM)


def study_with(**changes):
    raw = copy.deepcopy(MINIMAL)
    raw.update(changes)
    return validate_study(raw)


# ---- schema -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("changes", "path", "words"),
    [
        ({"design_space": {"b": [4, 10]}}, "design_space.b", ["unknown design variable", "'B'"]),
        ({"design_space": {"tt3": [1, 2]}}, "design_space.tt3", ["unknown design variable"]),
        ({"design_space": {"B": [10, 4]}}, "design_space.B", ["swap", "[4, 10]"]),
        ({"design_space": {"t3": [1.2, 1.2]}}, "design_space.t3", ["equal bounds"]),
        ({"design_space": {"a1": [0.0, 0.4]}}, "design_space.a1", ["(0, 1)"]),
        ({"design_space": {"t1": [0.0, 1.0]}}, "design_space.t1", ["> 0"]),
        ({"design_space": {"a1": [0.2, 0.7]}}, "design_space.a1", ["a2", "folds"]),
        ({"design_space": {"B": [4]}}, "design_space.B", ["two bounds"]),
        ({"design_space": {"B": "wide"}}, "design_space.B", ["list"]),
        ({"objective": "flatness"}, "objective", ["rms_error", "operative_stroke"]),
        ({"target": {"forse_N": 1.5}}, "target.forse_N", ["unknown key", "force_N"]),
        ({"target": {"tolerance_percent": -1}}, "target.tolerance_percent", ["greater than 0"]),
        ({"boundary": {"transverse": "free"}}, "boundary.transverse", ["unknown key"]),
        ({"boundary": {"rotation": "loose"}}, "boundary.rotation", ["fixed", "free"]),
        ({"design": {"Bee": 5.0}}, "design.Bee", ["unknown design variable"]),
        ({"design": {"a1": 0.9}}, "design", ["a1 = 0.9 must be < a2"]),
        ({"design": {"a1": "x"}}, "design", ["a1: got 'x'", "number"]),
        ({"design": "paper"}, "design", ["table3"]),
        ({"initial": "paper"}, "initial", ["table3"]),
        (
            {"geometry": {"kind": "constant_force", "pad_thickness_mm": 0.9}},
            "geometry.pad_thickness_mm",
            ["thinner"],
        ),
        (
            {"target": {"min_operative_stroke_mm": 40}},
            "target.min_operative_stroke_mm",
            ["stroke_mm"],
        ),
    ],
)
def test_bad_studies_name_the_key_path(changes, path, words):
    with pytest.raises(StudyError) as info:
        study_with(**changes)
    assert info.value.path == path, str(info.value)
    for word in words:
        assert word in info.value.problem, info.value.problem


def test_defaults_are_the_papers_set_up():
    study = study_with()
    assert study.boundary.stroke_mm == 30.0 and study.boundary.rotation == "fixed"
    assert study.target.force_N == 1.5 and study.target.tolerance_percent == 2.0
    assert study.target.samples == 10 and study.objective == "rms_error"
    assert study.target.allowable_stress_MPa == 42.5  # ABS yield, written into the study
    assert study.geometry.min_feature_mm == 0.8 and study.geometry.end_flexures == "centred"
    space = cf.design_space(study)
    np.testing.assert_array_equal(space.lower[:10], design_from_bounds("lower")[:10])
    assert space.names[10] == "t1_mm" and space.names[0] == "a1" and space.n_var == 23
    # a custom material's yield becomes the default allowable
    custom = study_with(material={"E_MPa": 2000.0, "nu": 0.3, "yield_MPa": 30.0})
    assert custom.allowable_MPa == 30.0


def design_from_bounds(which: str) -> np.ndarray:
    from flexopt.geometry.constant_force import TABLE3_BOUNDS

    return np.asarray(getattr(TABLE3_BOUNDS, which))


def test_design_space_override_keeps_the_other_table3_bounds():
    study = study_with(design_space={"B": [4.0, 12.0], "t3": [0.8, 1.6]})
    space = cf.design_space(study)
    i_b, i_t3 = DESIGN_VARIABLE_NAMES.index("B"), DESIGN_VARIABLE_NAMES.index("t3")
    assert (space.lower[i_b], space.upper[i_b]) == (4.0, 12.0)
    assert (space.lower[i_t3], space.upper[i_t3]) == (0.8, 1.6)
    others = np.ones(23, dtype=bool)
    others[[i_b, i_t3]] = False
    np.testing.assert_array_equal(space.lower[others], design_from_bounds("lower")[others])


# ---- the paper's Table 3 design -----------------------------------------------------------


def test_table3_design_is_quasi_constant_but_above_the_target_in_the_centred_layout():
    study = study_with()
    prob = cf.problem(study)
    ev = prob.evaluate(TABLE3)
    assert not ev.reason
    m = ev.metrics
    # docs/constant_force.md: 1.80 N, flat to 0.52 % of its mean from 0.5 mm until the stress
    # reaches 42.5 MPa at ~16 mm
    assert m["plateau_mean_force_N"] == pytest.approx(1.80, abs=0.01)
    assert m["plateau_flatness_percent"] < 1.0
    assert m["stress_limit_stroke_mm"] == pytest.approx(16.0, abs=1.0)
    assert m["operative_stroke_mm"] == 0.0  # 1.8 N is outside 1.5 N +- 2 %
    assert m["min_feature_mm"] == pytest.approx(0.920)
    assert not ev.feasible  # peak stress over the 30 mm drive is above 42.5 MPa
    # quasi-constant within +-1 % of its own mean over 0.5-18 mm (physical branch)
    _, response, _ = prob._solve(TABLE3)
    s, f = response.displacement_mm, response.force_N
    win = (s >= 0.5) & (s <= 18.0)
    assert np.max(np.abs(f[win] / f[win].mean() - 1)) < 0.01


def test_table3_outboard_layout_is_near_the_papers_level():
    outboard = {"kind": "constant_force", "end_flexures": "outboard", "pad_fillet_mm": 0}
    study = study_with(geometry=outboard)
    m = cf.problem(study).evaluate(TABLE3).metrics
    assert m["plateau_mean_force_N"] == pytest.approx(1.548, abs=0.01)
    assert m["stress_limit_stroke_mm"] == pytest.approx(20.0, abs=1.5)


# ---- the optimum this study found ---------------------------------------------------------


def test_shipped_optimum_holds_the_target_over_at_least_24_mm():
    study = load_study("constant-force")
    prob = cf.problem(study)
    x = cf.design_vector(study)
    assert prob.space.contains(x)
    ev = prob.evaluate(x)
    assert ev.feasible, ev.reason
    m = ev.metrics
    assert m["operative_stroke_mm"] >= 24.0
    assert abs(m["mean_force_N"] / 1.5 - 1) < 0.02
    assert m["peak_stress_MPa"] <= 42.5
    assert m["min_feature_mm"] >= 0.8
    # a finer beam mesh does not change the verdict (the stress is the mesh-sensitive part)
    fine = study_with(**{**EXAMPLE, "geometry": {**EXAMPLE["geometry"], "elements": 240}})
    m_fine = cf.problem(fine).evaluate(x).metrics
    assert m_fine["operative_stroke_mm"] >= 24.0
    assert m_fine["peak_stress_MPa"] <= 42.5


# ---- the DesignProblem contract -----------------------------------------------------------


def test_too_thin_design_is_infeasible_before_any_solve(monkeypatch):
    prob = cf.problem(study_with(design_space={"t6": [0.5, 1.15]}))

    def no_solve(*args, **kwargs):
        raise AssertionError("the beam was solved for an unprintable design")

    monkeypatch.setattr(cf.BeamModel, "solve", no_solve)
    x = TABLE3.copy()
    x[DESIGN_VARIABLE_NAMES.index("t6")] = 0.7
    ev = prob.evaluate(x)  # no_solve above: not one beam solve (speed: benchmarks/refusals.py)
    assert not ev.feasible
    assert ev.reason.startswith("not printable: t6 = 0.7 mm")
    assert "min_feature_mm = 0.8" in ev.reason


def test_bad_designs_come_back_as_data_not_exceptions(monkeypatch):
    prob = cf.problem(study_with())
    folded = TABLE3.copy()
    folded[[0, 1]] = [0.9, 0.2]
    ev = prob.evaluate(folded)
    assert ev.reason.startswith("cannot build") and not ev.feasible

    def boom(*args, **kwargs):
        raise RuntimeError("solver exploded")

    monkeypatch.setattr(cf.BeamModel, "solve", boom)
    ev = prob.evaluate(TABLE3)
    assert ev.reason == "raised RuntimeError: solver exploded"
    assert ev.f.shape == (1,) and ev.g.shape == (1,)


def test_problem_pickles_and_round_trips():
    prob = cf.problem(study_with(objective="operative_stroke", target={"samples": 5}))
    assert isinstance(prob, DesignProblem)
    clone = pickle.loads(pickle.dumps(prob))
    a, b = prob.evaluate(TABLE3), clone.evaluate(TABLE3)
    np.testing.assert_array_equal(a.f, b.f)
    np.testing.assert_array_equal(a.g, b.g)
    assert a.metrics == b.metrics
    assert clone.objective_names == ("negative_operative_stroke_mm",)
    assert len(pickle.dumps(prob)) < 20_000  # the study and numbers, no meshes


def test_min_operative_stroke_adds_a_constraint():
    prob = cf.problem(study_with(target={"min_operative_stroke_mm": 18.0}))
    assert prob.constraint_names == ("stress_ratio_minus_1", "operative_stroke_shortfall_mm")
    ev = prob.evaluate(TABLE3)
    assert ev.g[1] == pytest.approx(18.0)  # Table 3 holds no stroke at 1.5 N +- 2 %


def test_the_band_row_holds_every_judged_row():
    """rms_error under ``method: hybrid``: the last constraint row is the worst |F - 1.5 N| over
    the rows from the first (0.5 mm) to 30 mm less 80 % of the 0.03 N half-width (or 3 x the RMS
    error when larger), over 1.5 N, computed here from the traced rows; operative_stroke has no
    band requirement and no row."""
    hybrid = {"method": "hybrid"}
    prob = cf.problem(study_with(fidelity={"enabled": False}, optimiser=hybrid))
    assert prob.constraint_names == ("stress_ratio_minus_1", "force_band_excess")
    x = prob.nominal_design()
    ev = prob.evaluate(x)
    _, response, reason = prob._solve(x)
    assert not reason
    s, f = np.asarray(response.displacement_mm), np.asarray(response.force_N)
    assert s[0] == 0.0 and s[1] == pytest.approx(0.5)
    worst = np.max(np.abs(f[1:] - 1.5))  # row 0 (unloaded, 0 N) is not judged
    allowed = max(0.8 * 0.03, 3.0 * ev.f[0])  # the band, or 3 x the RMS error when larger
    assert ev.g[1] == pytest.approx((worst - allowed) / 1.5, rel=1e-12)
    other = cf.problem(study_with(objective="operative_stroke", optimiser=hybrid))
    assert other.constraint_names == ("stress_ratio_minus_1",)


def test_the_ga_alone_has_no_band_row():
    """The kind's default (no ``optimiser.method``) and ``method: ga``: main's problem, the peak
    stress row alone, so the GA's runs and ``flexopt evaluate`` of a study that names no method
    (no ``force_band_excess`` in its summary) are unchanged by the hybrid's band row. The
    shipped example names ``method: hybrid`` (the default ``flexopt run constant-force``) and
    has the band row (test_the_band_row_holds_every_judged_row)."""
    assert load_study("constant-force").optimiser.method == "hybrid"
    assert cf.problem(load_study("constant-force")).constraint_names[-1] == "force_band_excess"
    for study in (study_with(), study_with(optimiser={"method": "ga"})):
        assert study.optimiser.method != "hybrid"
        prob = cf.problem(study)
        assert prob.constraint_names == ("stress_ratio_minus_1",)
        assert prob.evaluate(TABLE3).g.shape == (1,)


def test_quick_ga_run_on_the_shipped_study():
    study = load_study("constant-force")
    prob = cf.problem(study)
    o = study.optimiser
    seed = prob.initial_designs()
    np.testing.assert_allclose(seed[0], prob.space.clip(TABLE3))
    result = run_ga(
        prob.space,
        lambda X: [prob.evaluate(x) for x in X],
        1,
        len(prob.constraint_names),
        GAConfig(o.algorithm, o.quick_pop_size, o.quick_n_gen, o.seed),
        initial=seed,
    )
    assert result.generations[-1].n_evaluations == o.quick_pop_size * o.quick_n_gen


def test_detail_gives_curve_outline_and_plot():
    study = study_with(fidelity={"enabled": False})
    prob = cf.problem(study)
    d = prob.detail(TABLE3)
    assert d.evaluation.metrics == prob.evaluate(TABLE3).metrics
    n = study.boundary.rows + 1
    for column in ("displacement_mm", "force_N", "peak_stress_MPa", "force_error_percent"):
        assert d.table[column].shape == (n,)
    assert d.shapes_mm.shape[0] == n and d.shapes_mm.shape[2] == 2
    assert d.plot["x"] in d.table and d.plot["y"] in d.table and d.plot["stress"] in d.table
    assert d.plot["target"] == 1.5 and d.plot["tolerance"] == pytest.approx(0.03)
    assert d.plot["allowable_MPa"] == 42.5
    assert isinstance(d.outline, Polygon) and d.outline.is_valid
    prof = beam_profile(TABLE3_OPTIMUM)
    t, ds = prof.thickness_mm, prof.segment_lengths_mm
    area = float(np.sum(ds * (t[:-1] + t[1:]) / 2)) + 2 * 8.0 * 4.0
    assert outline(TABLE3_OPTIMUM).area == pytest.approx(area, rel=1e-9)  # mitred
    # the part as exported blends the kinks (test_constant_force_kinks.py): the same part to
    # a few um, the same outline as the geometry's with the study's blend
    blended = outline(TABLE3_OPTIMUM, blend_mm=cf.pads.KINK_BLEND_MM)
    assert d.outline.equals_exact(blended, 0) and d.outline.area == pytest.approx(area, rel=1e-3)
    assert d.height_mm == TABLE3_OPTIMUM.B
    frame = d.info["prb_frame"]
    assert len(frame["stroke_mm"]) == 4 and frame["beam_over_prb"][0] == pytest.approx(1.2, 0.05)


def test_fidelity_check_agrees_with_the_beam_within_5_percent():
    # Table 3 over 0-16 mm (where its stress stays allowable), a coarse plane-stress mesh.
    study = study_with(fidelity={"points": 2, "max_edge_mm": 0.8})
    prob = cf.problem(study)
    _, response, _ = prob._solve(TABLE3)
    check = cf.fidelity_check(prob, TABLE3_OPTIMUM, response, 0.0, 16.0)
    assert "skipped" not in check, check
    # the two strokes of the window, and the beam's peak-stress row (the end of the drive): the
    # verdict's peak stress is the plane-stress one, which must not miss the worst row
    worst = float(response.displacement_mm[int(np.argmax(response.peak_stress_MPa))])
    assert worst == 30.0
    assert check["stroke_mm"] == pytest.approx([8.0, 16.0, 30.0])
    assert all(check["converged"]) and all(check["stable"])
    assert check["within_5_percent"], check["relative_difference"]
    assert check["plane_stress_force_N"][0] == pytest.approx(1.80, abs=0.03)
    assert max(check["max_shape_change_mm"]) < 0.5  # the same branch as the beam


def test_prb_report_finds_table1_like_parameters_for_any_target():
    report = cf.prb_report(3.0, 25.0)
    assert report["r1_mm"] == pytest.approx(54.0)  # on the bound r1 = 0.9 e, like Table 1
    assert report["relative_rms_error"] < 1e-3
    lo, hi = report["force_range_N"]
    assert 2.99 < lo <= hi < 3.01
    # lumped flexures at the printable 0.8 mm: stress-limited after a few mm (paper: 3-4 mm)
    assert 2.0 < report["lumped_flexures"]["stress_limited_stroke_mm"] < 10.0
    study = study_with(prb={"target_force_N": 3.0, "stroke_mm": 25.0})
    assert cf.prb_synthesis(study)["K_Nmm_per_rad"] == pytest.approx(report["K_Nmm_per_rad"])


def test_initial_and_design_keys():
    study = study_with(design={"B": 4.5}, initial="design", design_space={"B": [4.0, 12.0]})
    x = cf.design_vector(study)
    assert x[DESIGN_VARIABLE_NAMES.index("B")] == 4.5
    np.testing.assert_array_equal(np.delete(x, 22), np.delete(TABLE3, 22))
    np.testing.assert_array_equal(cf.problem(study).initial_designs(), x[None, :])
    assert cf.problem(study_with(initial="none")).initial_designs() is None
