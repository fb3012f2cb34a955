"""The ``mechanism`` study kind: paths, ties, invalid designs, bad input, the solved width, and
the constant-force equivalence with the ``constant_force`` kind."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import flexopt.pipeline as pipeline
import numpy as np
import pytest
import yaml
from flexopt.geometry.constant_force import DESIGN_VARIABLE_NAMES
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.problems import study_result
from flexopt.pipeline.studies.mechanism import MechanismProblem
from flexopt.pipeline.study import load_study, validate_study

EXAMPLES = Path(pipeline.__file__).parent / "examples"
E_PA12 = 1650.0  # MPa, the library's PA12 (fea/materials.py)


def _guide(**changes) -> dict:
    """A small parallel guide (two 40 mm leaves, 1.2 mm thick, a shuttle), as raw YAML data."""
    raw = {
        "name": "guide",
        "geometry": {
            "kind": "mechanism",
            "width_mm": 6.0,
            # fillets of 10 um: the closed forms below are for leaves of one thickness to their
            # clamps (a 1 mm fillet makes these leaves 7 % stiffer, and that is analysed)
            "fillet_mm": 0.01,
            "beams": {
                "upper": {"points_mm": [[0, 10], [40, 10]], "thickness_mm": 1.2, "elements": 12},
                "lower": {"points_mm": [[0, -10], [40, -10]], "thickness_mm": 1.2, "elements": 12},
            },
            "bodies": {
                "shuttle": {
                    "ref_mm": [44, 0],
                    "outline_mm": [[40, -13], [48, -13], [48, 13], [40, 13]],
                }
            },
            "joints": [
                {"a": "upper.start", "b": "ground"},
                {"a": "lower.start", "b": "ground"},
                {"a": "upper.end", "b": "shuttle"},
                {"a": "lower.end", "b": "shuttle"},
            ],
        },
        "material": "PA12",
        "load_cases": {
            "push": {
                "drive": {
                    "part": "shuttle",
                    "control": "displacement",
                    "direction": [0, 1],
                    "max_mm": 0.4,
                    "steps": 2,
                }
            }
        },
        "outputs": {
            "force_N": {"quantity": "reaction"},
            "stiffness_N_per_mm": {"quantity": "slope", "of": "force_N"},
        },
        "variables": [
            {
                "path": "geometry.beams.upper.thickness_mm",
                "bounds": [0.8, 2.0],
                "tie": ["geometry.beams.lower.thickness_mm"],
            }
        ],
    }
    for key, value in changes.items():
        raw[key] = value
    return raw


def _refused(raw: dict) -> StudyError:
    with pytest.raises(StudyError) as err:
        validate_study(raw)
    assert "\n" not in str(err.value)  # one line
    return err.value


# ---- design variables, ties, invalid designs


def test_tied_thickness_sets_both_leaves_and_matches_12EI_per_leaf():
    study = validate_study(_guide())
    prob = MechanismProblem(study)
    assert prob.space.names == ("beams.upper.thickness_mm",)
    assert prob.variables.initial.tolist() == [1.2]
    for t in (1.0, 1.6):
        ev = prob.evaluate(np.array([t]))
        assert ev.reason == "" and ev.feasible
        # two clamped-guided leaves at small deflection (0.2 mm of 40 mm): 2 x 12 E I / L^3, with
        # Timoshenko's shear term 1 / (1 + 12 E I / (k G A L^2)) (0.2-0.3 % here); the rest of
        # the 1 % allowed is the free shuttle (its rotation and the leaves' axial strain)
        k = 2 * 12 * E_PA12 * (6.0 * t**3 / 12) / 40.0**3
        g = E_PA12 / (2 * (1 + 0.39))
        k /= 1 + 12 * E_PA12 * (t**2 / 12) / (5 / 6 * g * 40.0**2)
        assert ev.metrics["start_stiffness_N_per_mm"] == pytest.approx(k, rel=1e-2)


def test_a_study_without_variables_is_one_design_evaluated_and_not_run(tmp_path, capsys):
    # one path for flexopt evaluate: the problem's nominal design, here of a space without
    # variables; flexopt run refuses it before it writes anything, with the message it always had
    raw = _guide()
    del raw["variables"]
    study = validate_study(raw)
    prob = MechanismProblem(study)
    assert prob.space.n_var == 0 and prob.nominal_design().shape == (0,)
    fixed = study_result(study, 1)
    assert fixed.inputs["design"] is None and fixed.summary["verdict"] in ("MET", "NOT MET")
    assert fixed.plot["y"] == "drive_reaction_N" and "left" not in fixed.plot
    varied = study_result(validate_study(_guide()), 1)  # the variable at its initial 1.2 mm
    np.testing.assert_allclose(fixed.table["force_N"], varied.table["force_N"], rtol=1e-12)
    path = tmp_path / "fixed.yaml"
    path.write_text(yaml.safe_dump(raw))
    out = tmp_path / "run"
    assert main(["run", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "variables" in err
    assert "flexopt run needs design variables; add variables: [{path, bounds}]" in err
    assert not out.exists()


def test_a_study_without_variables_has_its_robustness_samples(tmp_path):
    # the samples of the one design (main refused them with flexopt run's message)
    from flexopt.pipeline.evaluate import evaluate_study

    raw = _guide(parallel={"workers": 1})
    del raw["variables"]
    raw["robustness"] = {"method": "corners", "E_percent": 10, "thickness_mm": 0.1}
    outcome = evaluate_study(validate_study(raw), out=tmp_path / "out")
    robust = outcome.record["robustness"]
    assert robust["n_samples"] == 5 and robust["n_failed"] == 0


def test_a_design_that_crosses_beams_is_infeasible_with_the_reason():
    raw = _guide(
        variables=[
            {
                "path": "geometry.beams.upper.points_mm[0][1]",
                "bounds": [-15.0, 12.0],
            }
        ]
    )
    prob = MechanismProblem(validate_study(raw))
    ev = prob.evaluate(np.array([-15.0]))  # the upper leaf's root crosses the lower leaf
    assert not ev.feasible
    assert "beams 'upper' and 'lower' cross or overlap" in ev.reason


def test_a_design_below_the_printable_minimum_is_infeasible_with_the_reason():
    raw = _guide()
    raw["variables"][0]["bounds"] = [0.5, 2.0]
    prob = MechanismProblem(validate_study(raw))
    ev = prob.evaluate(np.array([0.6]))
    assert not ev.feasible
    assert "beam 'upper' is 0.6 mm thick" in ev.reason and "printable minimum 0.8" in ev.reason
    assert prob.evaluate(np.array([1.0])).feasible


# ---- bad input: one line with the key path and the fix, exit 2


def test_a_joint_naming_a_missing_beam():
    raw = _guide()
    raw["geometry"]["joints"][2] = {"a": "uper.end", "b": "shuttle"}
    err = _refused(raw)
    assert err.path == "geometry.joints[2].a"
    assert "'uper.end' names no part" in err.problem and "upper.start" in err.problem


def test_a_free_body_is_refused_with_its_name_and_exit_2(tmp_path, capsys):
    raw = _guide()
    raw["geometry"]["bodies"]["float"] = {"ref_mm": [44, 30]}
    raw["geometry"]["beams"]["arm"] = {"points_mm": [[44, 13], [44, 30]], "thickness_mm": 1.0}
    raw["geometry"]["joints"] += [
        {"a": "arm.start", "b": "shuttle"},
        {"a": "arm.end", "b": "float", "type": "pinned"},
    ]
    path = tmp_path / "free.yaml"
    path.write_text(yaml.safe_dump(raw))
    assert main(["evaluate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "body 'float'" in err and "geometry.joints" in err and "add a joint" in err


def test_a_variable_path_that_does_not_exist_names_the_nearest(tmp_path, capsys):
    raw = _guide()
    raw["variables"][0]["path"] = "geometry.beams.upper.thicknes_mm"
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(raw))
    assert main(["evaluate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "variables[0].path" in err
    assert "nearest valid path is geometry.beams.upper.thickness_mm" in err


def test_bounds_outside_the_physical_range():
    raw = _guide()
    raw["variables"][0]["bounds"] = [-0.5, 2.0]
    err = _refused(raw)
    assert err.path == "variables[0].bounds" and "must be > 0" in err.problem


def test_an_output_without_its_unit_and_an_unknown_requirement_quantity():
    raw = _guide(outputs={"force": {"quantity": "reaction"}})
    err = _refused(raw)
    assert err.path == "outputs.force" and "force_N" in err.problem
    raw = _guide(requirements=[{"quantity": "max_forc_N", "max": 5}])
    err = _refused(raw)
    assert err.path == "requirements[0].quantity" and "max_force_N" in err.problem


# ---- the width solved from the target


def test_width_solved_from_a_stiffness_requirement():
    raw = _guide(
        requirements=[
            {"name": "stiffness", "quantity": "mean_stiffness_N_per_mm", "min": 2.85, "max": 3.15}
        ],
        solve_width_from={"requirement": "stiffness"},
    )
    prob = MechanismProblem(validate_study(raw))
    ev = prob.evaluate(np.array([1.2]))
    assert ev.feasible and ev.metrics["verdict"] == "MET"
    assert ev.metrics["mean_stiffness_N_per_mm"] == pytest.approx(3.0, rel=1e-9)
    # forces scale with the width, stresses do not: the width is the reference width times the
    # target over the reference stiffness (exactly), and near the closed form 2 x 12 E I / L^3
    plain = MechanismProblem(validate_study(_guide())).evaluate(np.array([1.2]))
    expected = 6.0 * 3.0 / plain.metrics["mean_stiffness_N_per_mm"]
    assert ev.metrics["width_mm"] == pytest.approx(expected, rel=1e-9)
    k_per_mm_width = 2 * 12 * E_PA12 * (1.2**3 / 12) / 40.0**3
    assert ev.metrics["width_mm"] == pytest.approx(3.0 / k_per_mm_width, rel=1e-2)
    assert ev.metrics["max_peak_stress_MPa"] == pytest.approx(
        plain.metrics["max_peak_stress_MPa"], rel=1e-9
    )
    # a stress cannot give the width
    raw["requirements"].append({"name": "stress", "quantity": "max_peak_stress_MPa", "min": 1,
                                "max": 5})  # fmt: skip
    raw["solve_width_from"] = {"requirement": "stress"}
    err = _refused(raw)
    assert err.path == "solve_width_from.requirement" and "does not scale" in err.problem


# ---- the constant-force beam, both ways


def test_constant_force_mechanism_matches_the_constant_force_kind():
    mech = load_study("constant-force-mechanism")
    # the constant_force kind's beam runs at its own thickness into its clamp: a root fillet of
    # 0.1 um here (the example's default 1 mm fillet makes the beam 0.9 % stiffer)
    mech = mech.model_copy(
        update={"geometry": mech.geometry.model_copy(update={"fillet_mm": 1e-4})}
    )
    prob = MechanismProblem(mech)
    values = prob.variables.values(prob.variables.initial)
    design = {n: values[n if n.startswith("a") else f"{n}_mm"] for n in DESIGN_VARIABLE_NAMES}
    raw = yaml.safe_load((EXAMPLES / "constant-force.yaml").read_text())
    raw = copy.deepcopy(raw)
    raw["design"] = design
    raw["geometry"]["pad_fillet_mm"] = 0  # the mechanism's root fillet is 0.1 um here
    cf = validate_study(raw)
    assert cf.boundary.stroke_mm == 30.0 and cf.geometry.elements == 60
    ref = study_result(cf, 1)
    got = study_result(mech, 1)
    np.testing.assert_allclose(got.table["drive_mm"], ref.table["displacement_mm"], atol=1e-12)
    f_ref, f_got = ref.table["force_N"][1:], got.table["force_N"][1:]
    assert np.max(np.abs(f_got / f_ref - 1.0)) < 1e-3
    # the stress as made adds the sharp root's concentration factor, never less than the beam's
    s_ref, s_got = ref.table["peak_stress_MPa"][1:], got.table["peak_stress_MPa"][1:]
    assert np.all(s_got >= s_ref * (1 - 1e-3))


def test_gripper_amplifier_requires_the_gripper_studys_finger_force():
    from flexopt.pipeline.studies.gripper import requirement

    f1 = requirement(load_study("gripper"))["finger_force_N"]
    study = load_study("gripper-amplifier")
    jaw = next(r for r in study.requirements if r.name == "jaw_force")
    assert jaw.min >= f1 and jaw.min == pytest.approx(f1, rel=1e-3)
    assert math.isfinite(f1)


def test_warm_up_loads_the_mechanism_kernel_before_any_design():
    # A pool calls problem.warm_up() before it forks: the mechanism Newton kernel must be among
    # what the workers inherit (in a fresh interpreter, nothing is loaded before the warm-up).
    import json
    import subprocess
    import sys

    pytest.importorskip("numba")
    code = (
        "import json\n"
        "from flexopt.fea import _mechanism_kernels as k\n"
        "from flexopt.pipeline.studies.mechanism import MechanismProblem\n"
        "from flexopt.pipeline.study import load_study\n"
        "prob = MechanismProblem(load_study('bistable-switch'))\n"
        "before = len(k.newton.signatures)\n"
        "prob.warm_up()\n"
        "print(json.dumps([before, len(k.newton.signatures)]))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    before, after = json.loads(out.stdout.strip().splitlines()[-1])
    assert before == 0 and after >= 1
