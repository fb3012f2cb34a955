"""The ``flexure_pivot`` and ``leaf_spring_joint`` study kinds: schema errors with key paths, the
design-problem contract, and the shipped examples run end to end (quick)."""

from __future__ import annotations

import copy
import json
import math
import pickle
from pathlib import Path

import flexopt.pipeline as pipeline
import numpy as np
import pytest
import trimesh
import yaml
from flexopt.fea.closed_forms import pivot_closed_form
from flexopt.fea.leaf_joint import length_range_mm
from flexopt.optimise import DesignProblem
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.problems import study_result
from flexopt.pipeline.studies import get_kind
from flexopt.pipeline.studies.flexure_pivot import FlexurePivotProblem, build_flexure
from flexopt.pipeline.studies.leaf_spring_joint import LeafJointProblem
from flexopt.pipeline.study import load_study, validate_study

EXAMPLES = Path(pipeline.__file__).parent / "examples"
PIVOT = yaml.safe_load((EXAMPLES / "flexure-pivot.yaml").read_text())
JOINT = yaml.safe_load((EXAMPLES / "leaf-spring-joint.yaml").read_text())


def edited(raw: dict, changes: dict) -> dict:
    out = copy.deepcopy(raw)
    for path, value in changes.items():
        *parents, last = path.split(".")
        node = out
        for p in parents:
            node = node.setdefault(p, {})
        if value is None:
            node.pop(last, None)
        else:
            node[last] = value
    return out


@pytest.mark.parametrize(
    ("raw", "changes", "path", "words"),
    [
        (PIVOT, {"target.stiffness_Nm_per_rad": 0.3}, "target", ["exactly one"]),
        (PIVOT, {"target.stiffness_Nmm_per_rad": None}, "target", ["neither"]),
        (
            PIVOT,
            {"target.stifness_Nmm_per_rad": 3.0},
            "target.stifness_Nmm_per_rad",
            ["unknown key", "stiffness_Nmm_per_rad"],
        ),
        (PIVOT, {"geometry.candidates": ["leaf", "leaf"]}, "geometry", ["twice"]),
        (PIVOT, {"geometry.candidates": ["hinge"]}, "geometry.candidates[0]", ["leaf"]),
        (
            PIVOT,
            {"design_space.thickness_mm": [0.4, 2.0]},
            "design_space.thickness_mm",
            ["min_feature_mm"],
        ),
        (PIVOT, {"design_space.length_mm": [20.0, 2.0]}, "design_space.length_mm", ["swap"]),
        (
            PIVOT,
            {"design.type": "cross_axis", "geometry.candidates": ["leaf"]},
            "design.type",
            ["candidates"],
        ),
        (PIVOT, {"design.thickness_mm": 0.5}, "design.thickness_mm", ["min_feature_mm"]),
        (
            JOINT,
            {"geometry.effective_lengths_mm": [28.0, 60.0]},
            "geometry",
            ["effective_lengths_mm[1]", "arm_mm"],
        ),
        (JOINT, {"target.stiffness_range_Nm_per_rad": [20.0, 4.0]}, "target", ["lowest < highest"]),
        (
            JOINT,
            {"geometry.structures": ["sliding", "pinned"]},
            "geometry.structures[1]",
            ["sliding", "fixed"],
        ),
        (JOINT, {"design_space.width_mm": [16.0, 6.0]}, "design_space.width_mm", ["swap"]),
        (JOINT, {"boundary.max_deflection_deg": 95.0}, "boundary.max_deflection_deg", ["90"]),
    ],
)
def test_bad_studies_name_the_key_path(raw, changes, path, words):
    with pytest.raises(StudyError) as info:
        validate_study(edited(raw, changes))
    assert info.value.path == path, str(info.value)
    for word in words:
        assert word in str(info.value), str(info.value)


def test_allowable_defaults_to_the_material_yield():
    study = validate_study(edited(PIVOT, {"target.allowable_stress_MPa": None}))
    assert study.target.allowable_stress_MPa == 50.0  # PETG
    study = validate_study(edited(JOINT, {"target.allowable_stress_MPa": None}))
    assert study.target.allowable_stress_MPa == 785.0  # 65Mn


# ---- flexure_pivot ----------------------------------------------------------------------------


def test_pivot_problem_contract_and_closed_form_seeds():
    study = load_study("flexure-pivot")
    prob = FlexurePivotProblem(study)
    assert isinstance(prob, DesignProblem)
    assert pickle.loads(pickle.dumps(prob)).space.names == prob.space.names
    seeds = prob.initial_designs()
    assert seeds is not None and seeds.shape[1] == 4
    target = study.target.stiffness_Nmm_per_rad
    for x in seeds:
        kind, flex = prob.flexure(x)
        K = pivot_closed_form(flex, prob.material.E_MPa).stiffness_Nmm_per_rad
        assert K == pytest.approx(target, rel=1e-4)
        assert flex.min_thickness_mm >= study.geometry.min_feature_mm
    # the leaf seed is evaluated by the beam model, which agrees with the closed form
    leaf = next(x for x in seeds if prob.flexure(x)[0] == "leaf")
    ev = prob.evaluate(leaf)
    assert ev.feasible and ev.metrics["model"] == "beam"
    assert ev.metrics["stiffness_Nmm_per_rad"] == pytest.approx(target, rel=1e-6)
    theta = math.radians(study.target.range_of_motion_deg)
    _, flex = prob.flexure(leaf)
    # under a pure moment M = K theta (the leaf with its root fillets' flare: the drawn
    # profile's compliance integral), the narrow section's 6 M / (b t^2) times the roots' Kt
    b, t = flex.width_mm, flex.thickness_mm
    sigma = flex.root_kt * 6.0 * target * theta / (b * t**2)
    assert flex.root_kt > 1.0 and ev.metrics["peak_stress_MPa"] == pytest.approx(sigma, rel=2e-3)


def test_pivot_designs_that_cannot_be_built_are_infeasible_not_errors():
    prob = FlexurePivotProblem(load_study("flexure-pivot"))
    # a corner-filleted notch whose fillets take the whole length still builds; a huge notch
    # breaks the envelope; nothing raises
    for x in ([4.5, 2.0, 3.2, 1.0], [2.5, 30.0, 3.2, 0.0], [5.9, 30.0, 0.8, 0.0]):
        ev = prob.evaluate(np.array(x))
        assert ev.f.shape == (1,) and ev.g.shape == (4,)
    ev = prob.evaluate(np.array([2.5, 30.0, 3.2, 0.0]))
    assert not ev.feasible


def test_type_index_maps_to_every_candidate():
    study = load_study("flexure-pivot")
    prob = FlexurePivotProblem(study)
    kinds = [prob.flexure(np.array([i + 0.5, 10.0, 1.0, 0.5]))[0] for i in range(6)]
    assert kinds == list(study.geometry.candidates)
    assert prob.flexure(np.array([6.0, 10.0, 1.0, 0.5]))[0] == "cross_axis"  # upper bound
    f = build_flexure("elliptical_notch", 8.0, 1.0, 1.0, study.geometry)
    assert f.depth_mm == pytest.approx(0.25 * 4.0 * 8.0)


@pytest.mark.slow
@pytest.mark.e2e
def test_flexure_pivot_quick_run_writes_plots_and_a_watertight_stl(tmp_path):
    # the planar candidates only: with the leaves' root fillets' Kt the quick GA's best is
    # otherwise the cross-axis seed, which has no STL
    import yaml
    from flexopt.pipeline.study import resolve_study_path

    raw = yaml.safe_load(resolve_study_path("flexure-pivot").read_text())
    raw["geometry"]["candidates"] = [c for c in raw["geometry"]["candidates"] if c != "cross_axis"]
    study = tmp_path / "flexure-pivot.yaml"
    study.write_text(yaml.safe_dump(raw))
    out = tmp_path / "pivot"
    assert main(["run", str(study), "--quick", "--out", str(out), "-q"]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "finished" and record["quick"] is True
    files = set(record["files"])
    assert {"force_displacement.png", "stress.png", "shapes.png", "best.stl", "report.md"} <= files
    assert trimesh.load(out / "best.stl").is_watertight
    best = json.loads((out / "best.json").read_text())
    info = best["info"]
    assert best["feasible"] is True
    assert info["stiffness_Nmm_per_rad"]["closed_form"] == pytest.approx(300.0, rel=0.05)
    assert "plane_stress" in info and info["plane_stress"]["ok"] is True
    assert "## From the study kind" in (out / "report.md").read_text()


# ---- leaf_spring_joint ------------------------------------------------------------------------


def test_leaf_joint_length_range_gives_the_stiffness_range():
    E, arm, t, b = 206000.0, 70.0, 0.5, 11.0
    lo, hi = length_range_mm(E, arm, t, b, 2, (4000.0, 20000.0))
    EI = E * b * t**3 / 12
    assert 2 * 3 * EI * arm**2 / hi**3 == pytest.approx(4000.0)
    assert 2 * 3 * EI * arm**2 / lo**3 == pytest.approx(20000.0)


def test_leaf_joint_problem_contract():
    prob = LeafJointProblem(load_study("leaf-spring-joint"))
    assert isinstance(prob, DesignProblem)
    assert pickle.loads(pickle.dumps(prob)).space.names == ("arm_mm", "thickness_mm", "width_mm")
    cramped = prob.evaluate(np.array([30.0, 1.0, 16.0]))  # l_max does not fit: no solve
    assert not cramped.feasible and "skipped" in cramped.metrics
    ev = prob.evaluate(np.array([90.0, 0.54, 16.0]))
    assert ev.feasible, ev.g
    l_min, _ = prob.lengths(np.array([90.0, 0.54, 16.0]))
    # stress ~ 3 E t l_j theta / (2 l_min^2) at 5 deg (small deflection)
    sigma = 3 * 206000.0 * 0.54 * 90.0 * math.radians(5.0) / (2 * l_min**2)
    assert ev.metrics["peak_stress_MPa"] == pytest.approx(sigma, rel=0.02)


def test_leaf_spring_joint_evaluate_summary(tmp_path):
    raw = edited(
        JOINT,
        {
            "boundary.steps": 4,
            "boundary.check_deflection_deg": 30.0,
            "geometry.effective_lengths_mm": [28.0],
        },
    )
    path = tmp_path / "joint.yaml"
    path.write_text(yaml.safe_dump(raw))
    out = tmp_path / "eval"
    assert main(["evaluate", str(path), "--out", str(out)]) == 0
    record = json.loads((out / "evaluation.json").read_text())
    s = record["summary"]
    assert record["converged"] is True and s["stress_yield_ratio"] < 1.0
    assert s["sliding_l28_elastic_limit_deg"] == pytest.approx(4.06, abs=0.02)
    assert s["sliding_l28_at_30deg_stress_MPa"] > 8 * 785.0
    lo, hi = s["fixed_elastic_stiffness_range_Nm_per_rad"]
    assert hi == pytest.approx(20.23, rel=1e-3) and lo < hi
    header = (out / "response.csv").read_text().splitlines()[0].split(",")
    assert {"torque_Nm_sliding_l28", "stiffness_Nm_per_rad_fixed_l28"} <= set(header)


def test_leaf_spring_joint_evaluate_is_the_problems_result_of_its_nominal_joint():
    # one path: flexopt evaluate (study_result) is the problem's result of the study's joint,
    # the analysis of every structure and length; another design is analysed as that joint
    raw = edited(
        JOINT,
        {
            "boundary.steps": 2,
            "boundary.check_deflection_deg": None,
            "geometry.effective_lengths_mm": [28.0],
            "geometry.structures": ["sliding"],
        },
    )
    study = validate_study(raw)
    kind = get_kind("leaf_spring_joint")
    assert kind.evaluate is None
    prob = kind.problem(study)
    g = study.geometry
    x = prob.nominal_design()
    assert x.tolist() == [g.arm_mm, g.thickness_mm, g.width_mm]
    got = study_result(study, 1)
    assert got.plot["y"] == "torque_Nm_sliding_l28" and "left" not in got.plot
    thicker = prob.result(x + [0.0, 0.1, 0.0], 1)
    assert thicker.inputs["second_moment_mm4"] == pytest.approx(g.width_mm * 0.6**3 / 12)
    # the torque at small deflection goes with t^3
    ratio = thicker.table["torque_Nm_sliding_l28"][1] / got.table["torque_Nm_sliding_l28"][1]
    assert ratio == pytest.approx((0.6 / 0.5) ** 3, rel=0.05)


@pytest.mark.slow
@pytest.mark.e2e
def test_leaf_spring_joint_quick_run_writes_plots_and_a_watertight_stl(tmp_path):
    out = tmp_path / "joint"
    assert main(["run", "leaf-spring-joint", "--quick", "--out", str(out), "-q"]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "finished"
    assert {"force_displacement.png", "stress.png", "best.stl"} <= set(record["files"])
    assert trimesh.load(out / "best.stl").is_watertight
    info = json.loads((out / "best.json").read_text())["info"]
    lo, hi = info["fe_initial_stiffness_range_Nm_per_rad"]
    assert lo == pytest.approx(4.0, rel=0.02) and hi == pytest.approx(20.0, rel=0.02)
