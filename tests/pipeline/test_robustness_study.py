"""The robustness: block of a study: samples through the backend, shares, band, key-path errors.

The numbers are earned from the cantilever's closed form: at a small tip deflection the tip force
is F = 3 E I d / L^3 with I = w t^3 / 12, so each sample's force scales as E t^3 w, and a
requirement that holds F within ±1 % of the nominal is met by the nominal sample only.
"""

from __future__ import annotations

import json
import math

import flexopt_toys  # noqa: F401 - registers the toy kind for the run test
import numpy as np
import pytest
from flexopt.fea.materials import get_material
from flexopt.optimise.robustness import corner_samples
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.evaluate import evaluate_study
from flexopt.pipeline.robustness import perturb_study, scatter_design
from flexopt.pipeline.study import load_study, validate_study

L_MM, T_MM, W_MM, D_MM = 60.0, 1.5, 8.0, 0.3
SCATTER = {"E_percent": 10.0, "thickness_mm": 0.1, "width_mm": 0.2}


def tip_force_N(E_MPa: float, t_mm: float, w_mm: float) -> float:
    """Euler-Bernoulli cantilever, tip load: F = 3 E I d / L^3."""
    return 3.0 * E_MPa * (w_mm * t_mm**3 / 12.0) * D_MM / L_MM**3


def cantilever(robustness: dict | None = None, **extra) -> dict:
    F0 = tip_force_N(get_material("ABS").E_MPa, T_MM, W_MM)
    raw = {
        "name": "cantilever-robust",
        "geometry": {
            "kind": "polyline_beam",
            "points_mm": [[0, 0], [L_MM / 2, 0], [L_MM, 0]],
            "thickness_mm": [T_MM] * 3,
            "width_mm": W_MM,
            "elements": 20,
        },
        "material": "ABS",
        "boundary": {
            "start": "clamped",
            # the clamp row judged on a stated Kt (docs/beam.md "The clamp as made"): every
            # sample's verdict then turns on the tip force alone (its stress is far below)
            "clamp_kt": 1.5,
            "end": {
                "control": "displacement",
                "direction": [0, 1],
                "max_mm": D_MM,
                "steps": 3,
                "rotation": "free",
                "transverse": "free",
            },
        },
        # met near the nominal only: every corner moves F by more than 1 %
        "requirements": [
            {"quantity": "max_abs_force_N", "name": "tip force", "min": 0.99 * F0, "max": 1.01 * F0}
        ],
        "parallel": {"backend": "serial"},
        **extra,
    }
    if robustness is not None:
        raw["robustness"] = robustness
    return raw


def test_corners_of_a_cantilever_share_and_band(tmp_path):
    study = validate_study(cantilever(SCATTER))
    outcome = evaluate_study(study, out=tmp_path / "ev")
    record = json.loads((tmp_path / "ev" / "evaluation.json").read_text())["robustness"]
    assert record == json.loads(json.dumps(outcome.record["robustness"]))
    assert record["method"] == "corners" and record["n_samples"] == 2**3 + 1
    assert (tmp_path / "ev" / "robustness.png").stat().st_size > 1000
    joined = " ".join(record["perturbed"])
    for key in ("material.E_MPa", "geometry.thickness_mm[0]", "geometry.thickness_mm[2]"):
        assert key in joined
    assert "geometry.width_mm" in joined

    E = get_material("ABS").E_MPa
    rows = corner_samples(**SCATTER)
    forces = [tip_force_N(E * e, T_MM + dt, W_MM + dw) for e, dt, dw in rows]
    F0 = forces[0]
    inside = [abs(f / F0 - 1.0) <= 0.01 for f in forces]
    assert inside[0] and not any(inside[1:])  # the test's premise, from the closed form
    tip = next(r for r in record["requirements"] if r["name"] == "tip force")
    assert tip["share_percent"] == pytest.approx(100.0 / 9.0)
    assert tip["met_robustly"] is False and tip["nominal_verdict"] == "MET"
    # every sample's verdict: only the nominal (row 0) meets the tip force
    assert [s["met"] == s["of"] for s in record["samples"]] == inside

    # the band of the force at the last row: the extreme corners, within the beam's accuracy
    band = record["band"]
    assert band["force_N"]["low"][-1] == pytest.approx(min(forces), rel=0.01)
    assert band["force_N"]["high"][-1] == pytest.approx(max(forces), rel=0.01)
    # the driven displacement is the same in every sample: its band has no width
    np.testing.assert_allclose(band["displacement_mm"]["low"], band["displacement_mm"]["high"])


def test_a_scatter_that_changes_nothing_keeps_every_requirement(tmp_path):
    # thickness scatter on a study with no thickness key moves nothing: 100 % everywhere
    raw = cantilever({"E_percent": 0.5})
    study = validate_study(raw)
    record = evaluate_study(study, out=tmp_path / "ev").record["robustness"]
    assert record["n_samples"] == 3
    tip = record["requirements"][-1]
    # E +-0.5 % moves F by 0.5 %, inside +-1 %: every sample meets it
    assert tip["share_percent"] == 100.0 and tip["met_robustly"] is True


def test_monte_carlo_is_reproducible(tmp_path):
    block = {"method": "monte_carlo", "samples": 4, "seed": 3, "E_percent": 20.0}
    first = evaluate_study(validate_study(cantilever(block)), out=tmp_path / "a").record
    second = evaluate_study(validate_study(cantilever(block)), out=tmp_path / "b").record
    assert first["robustness"]["n_samples"] == 5
    assert first["robustness"]["samples"] == second["robustness"]["samples"]
    E = [s["E_factor"] for s in first["robustness"]["samples"]]
    assert E[0] == 1.0 and all(0.8 <= e <= 1.2 for e in E)


def test_perturb_study_shifts_printed_sizes_only():
    raw = cantilever(SCATTER)
    raw["requirements"].append({"envelope_mm": [100.0, 20.0]})
    study = validate_study(raw)
    sample, changed = perturb_study(study, 1.1, 0.1, -0.2)
    assert sample.material.E_MPa == pytest.approx(1.1 * study.material.E_MPa)
    assert sample.geometry.thickness_mm == pytest.approx((T_MM + 0.1,) * 3)
    assert sample.geometry.width_mm == pytest.approx(W_MM - 0.2)
    assert sample.requirements == study.requirements  # limits are not printed
    assert sample.robustness is None  # a sample does not sample itself
    assert set(changed) == {
        "material.E_MPa",
        "geometry.thickness_mm[0]",
        "geometry.thickness_mm[1]",
        "geometry.thickness_mm[2]",
        "geometry.width_mm",
    }
    with pytest.raises(StudyError, match=r"geometry\.thickness_mm"):
        perturb_study(study, 1.0, -T_MM, 0.0)  # printed away: the sample's study is refused


def test_design_vectors_shift_by_name_or_by_the_kind():
    from flexopt.optimise.problem import DesignProblem

    class ByName(DesignProblem):  # no scatter_design of its own: the rule by name
        class space:  # noqa: N801 - a stand-in for a DesignSpace
            names = ("leaf_thickness_mm", "length_mm", "width_mm")

    x = np.array([1.0, 20.0, 6.0])
    np.testing.assert_allclose(scatter_design(ByName(), x, 0.1, -0.2), [1.1, 20.0, 5.8])

    from flexopt.pipeline.run import build_problem

    problem = build_problem(load_study("constant-force"))
    x = problem.nominal_design()
    shifted = scatter_design(problem, x, 0.1, -0.2)
    names = problem.space.names
    for name, a, b in zip(names, x, shifted, strict=True):
        expected = 0.0 if name.startswith("a") else (-0.2 if name == "B_mm" else 0.1)
        assert b - a == pytest.approx(expected), name

    # variables on key paths (the mechanism kind): the key a variable sets moves by the delta
    mechanism = build_problem(load_study("parallel-guide"))
    x = mechanism.nominal_design()
    shifted = scatter_design(mechanism, x, 0.1, -0.2)
    for i, targets in enumerate(mechanism.variables.targets):
        key = [p for p in targets[0].path if isinstance(p, str)][-1]
        moved = (shifted[i] - x[i]) * targets[0].factor
        assert moved == pytest.approx(0.1 if key.endswith("thickness_mm") else 0.0), key


def test_a_study_without_a_material_is_sampled_without_E():
    study = load_study("sea-window")
    same, changed = perturb_study(study, 1.1, 0.1, 0.1)
    assert changed == () and same == study


@pytest.mark.parametrize(
    ("block", "where", "words"),
    [
        ({"E_percent": 10, "sample": 4}, "robustness.sample", "did you mean 'samples'"),
        ({"method": "monte_carlo", "E_percent": 10}, "robustness", "needs samples"),
        ({"method": "corners", "samples": 8, "E_percent": 10}, "robustness", "monte_carlo"),
        ({}, "robustness", "no scatter"),
        ({"E_percent": 120}, "robustness.E_percent", "100"),
        ({"thickness_mm": -0.1}, "robustness.thickness_mm", "0"),
        ({"E_percent": 10, "objective": "worst"}, "robustness.objective", "only evaluated"),
        ({"E_percent": 10, "method": "latin"}, "robustness.method", "corners"),
    ],
)
def test_bad_blocks_name_the_key(block, where, words, tmp_path, capsys):
    with pytest.raises(StudyError) as caught:
        validate_study(cantilever(block))
    assert caught.value.path == where, str(caught.value)
    assert words in str(caught.value)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(cantilever(block)))
    assert main(["evaluate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and where in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


@pytest.mark.e2e
def test_run_reports_the_chosen_designs_robustness(tmp_path, capsys):
    raw = flexopt_toys.study("toy-robust")
    raw["optimiser"] = {"pop_size": 4, "n_gen": 2, "seed": 1}
    raw["robustness"] = {"E_percent": 10.0, "thickness_mm": 0.1}
    path = tmp_path / "toy.json"
    path.write_text(json.dumps(raw))
    out = tmp_path / "run"
    assert main(["run", str(path), "--out", str(out), "--workers", "1"]) == 0
    best = json.loads((out / "best.json").read_text())
    record = best["robustness"]
    assert record["n_samples"] == 5 and record["method"] == "corners"
    # the toy has no thickness: the record says so rather than pretending
    assert any("no thickness found" in p for p in record["perturbed"])
    assert math.isclose(record["samples"][0]["E_factor"], 1.0)
    report = (out / "report.md").read_text()
    assert "## Robustness" in report and "share of samples MET" in report
    assert "robustness (corners, 5 samples" in capsys.readouterr().out
    run = json.loads((out / "run.json").read_text())
    assert run["robustness"]["n_samples"] == 5 and "band" not in run["robustness"]


def test_worst_objective_is_the_largest_over_the_samples():
    """objective: worst scores a design by the largest objective and constraint over the
    samples, each sample evaluated here on its own (its study, its shifted design vector)."""
    import pickle

    from flexopt.pipeline.robustness import WorstCaseProblem
    from flexopt.pipeline.run import build_problem

    raw = yaml_of("constant-force")
    raw["robustness"] = {"E_percent": 5.0, "width_mm": 0.1, "objective": "worst"}
    study = validate_study(raw)
    problem = build_problem(study)
    assert isinstance(problem, WorstCaseProblem)
    assert problem.objective_names == ("worst_rms_error_N",)
    problem = pickle.loads(pickle.dumps(problem))  # as a worker receives it
    x = problem.nominal_design()
    worst = problem.evaluate(x)

    f, g = [], []
    for e, dt, dw in corner_samples(5.0, 0.0, 0.1):
        sample, _ = perturb_study(study, e, dt, dw)
        one = build_problem(sample)
        ev = one.evaluate(scatter_design(one, x, dt, dw))
        f.append(ev.f)
        g.append(ev.g)
    np.testing.assert_allclose(worst.f, np.max(f, axis=0))
    np.testing.assert_allclose(worst.g, np.max(g, axis=0))
    # E +5 % and B +0.1 mm both raise the force: the nominal's RMS error is not the worst
    assert worst.f[0] > f[0][0]
    assert worst.metrics["worst_sample"] == int(np.argmax([v[0] for v in f]))


def yaml_of(name: str) -> dict:
    import yaml
    from flexopt.pipeline.study import resolve_study_path

    return yaml.safe_load(resolve_study_path(name).read_text(encoding="utf-8"))


def _spring_samples(name: str, extra: dict) -> tuple:
    """The nominal evaluation of a spring study and a function that evaluates one sample the
    way pipeline/robustness does (perturbed study, held ST, moved design vector)."""
    from flexopt.pipeline.problems import build_base_problem, nominal_design
    from flexopt.pipeline.robustness import held_state, hold_solved

    raw = {**yaml_of(name), **extra, "parallel": {"backend": "serial"}}
    study = validate_study(raw)
    problem = build_base_problem(study)
    x = nominal_design(problem, study)
    nominal = problem.evaluate(x)
    held = held_state(problem, nominal)

    def sample(e: float, dt: float, dw: float):
        one = build_base_problem(perturb_study(study, e, dt, dw)[0])
        hold_solved(one, held, dt, dw)
        xs = scatter_design(one, x, dt, dw)
        return xs, one.evaluate(xs)

    return study, problem, x, nominal, held, sample


def test_sea_spring_scatter_moves_the_arms_and_holds_the_solved_plate():
    """sea_spring (thickness: solve): the thickness scatter moves the in-plane arm widths
    W1..W4 by exactly the delta, ST is solved for the nominal design and then held, the width
    scatter moves it; wider arms are stiffer, and the plane-stress torque is proportional to ST
    (so the width sample's stiffness is K_target (ST + dw) / ST to solver precision)."""
    from flexopt.pipeline.robustness import _describe

    study, problem, x, nominal, held, sample = _spring_samples(
        "sea-spring-quick", {"solid_3d": {"check": False}, "robustness": {"thickness_mm": 0.2}}
    )
    k_target = study.target.stiffness_Nm_per_rad
    assert nominal.reason == ""
    st = nominal.metrics["ST_mm"]
    assert held == {"ST_mm": st}
    assert nominal.metrics["stiffness_Nm_per_rad"] == pytest.approx(k_target, rel=1e-9)
    is_arm = np.array([n.startswith("W") for n in problem.space.names])
    assert is_arm.sum() == 4

    x_wide, wide = sample(1.0, 0.2, 0.0)
    x_thin, thin = sample(1.0, -0.2, 0.0)
    np.testing.assert_allclose(x_wide - x, np.where(is_arm, 0.2, 0.0), atol=1e-12)
    np.testing.assert_allclose(x_thin - x, np.where(is_arm, -0.2, 0.0), atol=1e-12)
    assert wide.metrics["ST_mm"] == thin.metrics["ST_mm"] == st  # held, not re-solved
    # wider arms -> stiffer (not re-solved to the target, which would hide the scatter)
    assert thin.metrics["stiffness_Nm_per_rad"] < k_target < wide.metrics["stiffness_Nm_per_rad"]

    x_plate, plate = sample(1.0, 0.0, 0.3)
    np.testing.assert_array_equal(x_plate, x)
    assert plate.metrics["ST_mm"] == pytest.approx(st + 0.3, rel=1e-12)
    assert plate.metrics["stiffness_Nm_per_rad"] == pytest.approx(
        k_target * (st + 0.3) / st, rel=1e-6
    )

    spec = validate_study({**yaml_of("sea-spring-quick"), "robustness": SCATTER}).robustness
    words = _describe(study, spec, problem, x)
    assert any(w.startswith("thickness") and "design variable W1_mm" in w for w in words)
    assert any(w.startswith("width") and "ST (solved for the nominal design" in w for w in words)


def test_threshold_spring_scatter_moves_the_arms_and_holds_the_solved_plate():
    """threshold_spring: W1_mm..W4_mm move by the thickness scatter; ST is fitted to the target
    for the nominal design and held (a fit per sample would hide the scatter); wider arms give
    more torque, and the torque is proportional to ST."""
    _, problem, x, nominal, held, sample = _spring_samples("threshold-spring", {})
    st = nominal.metrics["ST_mm"]
    assert held == {"ST_mm": st}
    is_arm = np.array([n.startswith("W") for n in problem.space.names])
    assert is_arm.sum() == 4
    x_wide, wide = sample(1.0, 0.1, 0.0)
    np.testing.assert_allclose(x_wide - x, np.where(is_arm, 0.1, 0.0), atol=1e-12)
    assert wide.metrics["ST_mm"] == st
    assert wide.metrics["torque_at_range_Nm"] > nominal.metrics["torque_at_range_Nm"]
    error = problem.error_name
    assert wide.metrics[error] > nominal.metrics[error]  # off the fitted optimum
    _, plate = sample(1.0, 0.0, 0.5)
    assert plate.metrics["torque_at_range_Nm"] == pytest.approx(
        nominal.metrics["torque_at_range_Nm"] * (st + 0.5) / st, rel=1e-9
    )
