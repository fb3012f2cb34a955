"""Study kinds of issue 7: cam and collision (paper 000), gripper (papers 001 + 003)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import yaml
from flexopt.fea.statics import STANDARD_GRAVITY_M_PER_S2
from flexopt.geometry.solid import extrude
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.problems import study_result
from flexopt.pipeline.studies import get_kind
from flexopt.pipeline.studies.cam import CamProblem
from flexopt.pipeline.studies.collision import extra_files as collision_files
from flexopt.pipeline.study import load_study, parse_study_text, resolve_study_path, validate_study


def raw_example(name: str) -> dict:
    return parse_study_text(resolve_study_path(name).read_text())


@pytest.fixture(scope="module")
def cam_result():
    study = load_study("threshold-cam")
    return study, study_result(study, 1)


@pytest.fixture(scope="module")
def collision_result():
    study = load_study("v2som-collision")
    return study, get_kind("collision").evaluate(study, 1)


@pytest.fixture(scope="module")
def gripper_result():
    study = load_study("gripper")
    return study, study_result(study, 1)  # the nominal design's GripperProblem.result


# ---- cam ------------------------------------------------------------------------------------


def test_cam_example_plate_makes_the_threshold_torque(cam_result):
    study, result = cam_result
    s = result.summary
    assert s["target_max_normalised_error"] < 0.005  # plate torque by virtual work vs Eq. 14
    assert s["stress_yield_ratio"] < 1.0 and not s["undercut"]
    assert s["max_pressure_angle_deg"] < study.limits.max_pressure_angle_deg
    assert s["mode_split_deg"] == pytest.approx(math.degrees(math.log(5) / 50.0))
    t = result.table
    assert list(t)[:4] == [
        "rotation_deg",
        "target_torque_Nm",
        "cam_torque_Nm",
        "virtual_work_torque_Nm",
    ]
    np.testing.assert_array_equal(np.unique(t["mode"]), [1, 2])


def test_cam_from_a_csv_table_and_with_the_paper_correction(tmp_path, monkeypatch):
    deg = np.linspace(0.0, 90.0, 901)
    torque = 2.05 * (1 - np.exp(-50.0 * np.radians(deg)))
    lines = ["rotation_deg,torque_Nm"] + [
        f"{a:.6f},{b:.9f}" for a, b in zip(deg, torque, strict=True)
    ]
    (tmp_path / "curve.csv").write_text("\n".join(lines) + "\n")
    monkeypatch.chdir(tmp_path)
    raw = raw_example("threshold-cam")
    raw["target"] = {
        "kind": "table",
        "file": "curve.csv",
        "measure": "max_normalised",
        "window_deg": [3, 85],
    }
    result = study_result(validate_study(raw), 1)
    assert result.summary["target_max_normalised_error"] < 0.01  # the table's chords near 0
    raw = raw_example("threshold-cam")
    raw["correction"] = {"coefficients": [1.001, -0.0369, 2.588]}
    result = study_result(validate_study(raw), 1)
    t = result.table
    np.testing.assert_allclose(
        t["cam_torque_Nm"][1:80] / t["virtual_work_torque_Nm"][1:80], 1.0, rtol=5e-3
    )
    assert result.inputs["correction"]["coefficients"] == [1.001, -0.0369, 2.588]


@pytest.mark.parametrize(
    "change, path",
    [
        ({"target": {"kind": "constant", "force_N": 1.5}}, "target"),
        ({"springs": {"stiffness_N_per_mm": 4, "free_length_mm": 40, "offset_mm": 10}}, "springs"),
        ({"design_space": {"roller_radius_mm": [1, 2]}}, "design_space.roller_radius_mm"),
        ({"correction": {"fit": True}, "sab": None}, "correction.fit"),
        ({"target": {"kind": "table", "file": "missing.csv"}}, "target.file"),
    ],
)
def test_cam_study_errors_name_the_key(change, path):
    raw = raw_example("threshold-cam")
    raw.update(change)
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == path


def test_cam_problem_sizes_the_springs_and_gives_a_printable_plate():
    study = load_study("threshold-cam")
    problem = CamProblem(study)
    x0 = problem.initial_designs()[0]
    evaluation = problem.evaluate(x0)
    assert evaluation.feasible, evaluation.g
    detail = problem.detail(x0)
    mesh = extrude(detail.outline, detail.height_mm)
    assert mesh.is_watertight
    assert detail.table["virtual_work_torque_Nm"].shape == (study.rows,)


# ---- collision ------------------------------------------------------------------------------


def test_collision_example_reproduces_the_comparison_and_flags_the_cam(collision_result):
    study, result = collision_result
    s = result.summary
    assert s["hic_reduction"] == pytest.approx(0.908, abs=2e-3)
    assert s["force_reduction"] == pytest.approx(0.442, abs=2e-3)
    assert s["hic_reduction_min_torque_sweep"] > 0.8  # paper: > 80 % over 7.5-30 N·m
    assert s["early_hic_reduction"] < 0.0  # the first impact alone shows no HIC gain
    assert s["cam_range_exceeded"] and s["stress_yield_ratio"] < 1.0
    assert s["reference_stiffness_Nm_per_rad"] == pytest.approx(12 * 37 / math.log(5))
    sweeps = result.inputs["sweeps"]
    assert sweeps["rotor_torque_Nm"]["values"] == list(study.sweeps.rotor_torque_Nm)
    files = collision_files(study, result)
    assert all(v[:8] == b"\x89PNG\r\n\x1a\n" for v in files.values())
    assert set(files) == {"sweeps.png", "impact.png"}


def test_collision_initial_conditions_and_table_springs():
    raw = raw_example("v2som-collision")
    raw["impact"] = {**raw["impact"], "initial_spring": "held"}
    with pytest.raises(StudyError) as info:
        validate_study(raw)
    assert info.value.path == "impact.initial_spring"
    raw = raw_example("v2som-collision")
    raw.pop("cam")
    raw["spring"] = {
        "kind": "table",
        "columns": ["rotation_deg", "torque_Nm"],
        "points": [[0, 0], [2, 10], [10, 14], [200, 15]],
    }
    raw["impact"] = {**raw["impact"], "duration_s": 0.1}
    raw["sweeps"] = {"rotor_inertia_kg_m2": [0.175], "rotor_torque_Nm": []}
    result = get_kind("collision").evaluate(validate_study(raw), 1)
    assert result.summary["beyond_table"] is False
    assert result.summary["reference_stiffness_Nm_per_rad"] > 0


# ---- gripper --------------------------------------------------------------------------------


def test_gripper_requirement_is_eq14_for_the_paper_finger_and_feeds_the_beam(gripper_result):
    study, result = gripper_result
    s = result.summary
    g = 0.02 * STANDARD_GRAVITY_M_PER_S2
    eq14 = (g + 0.8) * math.cos(math.radians(5 + 20)) * 30.0 / 20.0  # largest at α = 5°
    assert s["target_force_N"] == pytest.approx(eq14, rel=1e-12)
    assert s["paper_over_vector"] == pytest.approx(1.0)
    assert s["finger_force_jaw"] == "lower"
    assert s["overtravel_mm"] == pytest.approx(
        20 * (math.tan(math.radians(15)) - math.tan(math.radians(5)))
    )
    assert s["beam_plateau_force_N"] == pytest.approx(eq14, rel=1e-9)  # force is linear in B
    assert s["stress_yield_ratio"] < 1.0
    resolved = result.inputs["constant_force_study"]
    assert resolved["target"]["force_N"] == pytest.approx(eq14)
    assert resolved["boundary"]["stroke_mm"] == pytest.approx(s["stroke_mm"])
    assert resolved["initial"] == "design"


def test_gripper_writes_a_constant_force_study_that_reads_back(gripper_result):
    study, result = gripper_result
    text = result.files["constant-force.yaml"].decode()
    again = validate_study(yaml.safe_load(text))
    assert again.kind == "constant_force"
    assert again.target.force_N == pytest.approx(result.summary["target_force_N"])
    problem = get_kind("gripper").problem(study)
    assert problem.space.n_var == 23


def test_gripper_side_grip_by_friction_differs_from_eq14():
    raw = copy.deepcopy(raw_example("gripper"))
    raw["workpiece"] = {"mass_kg": 0.05, "friction": {"mu": 0.5, "contacts": 2, "safety": 2.0}}
    raw["jaws"] = [{"name": "side", "normal_deg": 180.0, "weight_share": 0.5}]
    study = validate_study(raw)
    from flexopt.pipeline.studies.gripper import requirement

    req = requirement(study)
    assert req["normal_force_N"] == pytest.approx(2.0 * 0.05 * STANDARD_GRAVITY_M_PER_S2 / 1.0)
    assert req["paper_over_vector"] > 1.2
