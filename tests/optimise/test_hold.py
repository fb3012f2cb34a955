"""A study's ``hold:`` block: creep and relaxation of a held part (optimise/hold.py, the
verdict's hook in pipeline/verdict.py).

Every expected value is computed by hand in the test. The law is Findley's with n = 1/2, whose
relaxation ratio has a closed form: E_R(t)/E0 = E_1/2(-Gamma(3/2) sqrt(t/tau)) =
exp(x^2) erfc(x) with x = Gamma(3/2) sqrt(t/tau) (scipy.special.erfcx), so the held force of a
displacement-held cantilever is checked against F(t) = 3 E_R(t) I delta / L^3 (small
deflection) without the Mittag-Leffler code under test.
"""

from __future__ import annotations

import copy
import math
from dataclasses import replace

import numpy as np
import pytest
import yaml
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.hold import HoldSpec, hold_of_table
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.evaluate import solve_study
from flexopt.pipeline.study import load_study, study_to_yaml, validate_study
from flexopt.pipeline.verdict import judge_result
from scipy import special

L_MM, H_MM, B_MM, E_MPA = 60.0, 1.5, 8.0, 1800.0
I_MM4 = B_MM * H_MM**3 / 12.0
TAU_H, N = 200.0, 0.5


def retention_by_hand(t_h: float) -> float:
    """E_R(t)/E0 of the n = 1/2 Findley law: erfcx(Gamma(3/2) sqrt(t/tau))."""
    return float(special.erfcx(math.gamma(1.5) * math.sqrt(t_h / TAU_H)))


def material(**creep) -> dict:
    law = {"tau_h": TAU_H, "n": N, "max_stress_ratio": 0.3, "source": "test law"}
    law.update(creep)
    return {
        "name": "abs-test", "E_MPa": E_MPA, "nu": 0.35, "yield_MPa": 42.5,
        "density_kg_m3": 1040.0, "source": "test", "creep": law,
    }  # fmt: skip


def cantilever(max_mm: float = 1.0, steps: int = 4, mat=None, **extra) -> dict:
    """ABS-like cantilever 60 x 1.5 x 8 mm, tip pushed ``max_mm`` (+y)."""
    raw = {
        "name": "cantilever-hold",
        "geometry": {
            "kind": "polyline_beam",
            "points_mm": [[0, 0], [30, 0], [60, 0]],
            "thickness_mm": [H_MM] * 3,
            "width_mm": B_MM,
            "elements": 30,
        },
        "material": material() if mat is None else mat,
        "boundary": {
            "start": "clamped",
            "end": {
                "control": "displacement",
                "direction": [0, 1],
                "max_mm": max_mm,
                "steps": steps,
                "rotation": "free",
                "transverse": "free",
            },  # fmt: skip
        },
    }
    raw.update(copy.deepcopy(extra))
    return raw


@pytest.fixture(scope="module")
def small():
    """Tip held at 0.5 mm (of 1 mm traced) for 24 h: small deflection (delta/L < 1 %)."""
    study = validate_study(
        cantilever(
            hold={"time_h": 24.0, "at": "displacement", "level": 0.5},
            requirements=[
                {"quantity": "held_force_N", "min": 0.001},
                {"quantity": "force_retention", "min": 0.99},
            ],
        )
    )
    return study, solve_study(study)


def test_displacement_held_cantilever_force_against_the_law_by_hand(small):
    study, result = small
    r = retention_by_hand(24.0)
    # F = 3 E_R(t) I delta / L^3, with the shear flexibility L/(k G A) of the beam model
    # (Reissner beam, k = 5/6; G relaxes with E at constant nu): 5e-4 of the bending one here
    g_mpa = E_MPA / (2.0 * 1.35)
    flex = L_MM**3 / (3.0 * E_MPA * I_MM4) + L_MM / (5.0 / 6.0 * g_mpa * B_MM * H_MM)
    by_hand = r * 0.5 / flex
    assert by_hand == pytest.approx(3.0 * E_MPA * r * I_MM4 * 0.5 / L_MM**3, rel=6e-4)
    s = result.summary
    assert s["force_retention"] == pytest.approx(r, rel=1e-12)
    assert s["held_force_N"] == pytest.approx(by_hand, rel=2e-4)  # small-deflection theory
    assert s["hold_initial_force_N"] == pytest.approx(by_hand / r, rel=2e-4)
    # the whole held curve: the elastic one times E_R/E0 (force scales with E at fixed shape)
    held = np.asarray(result.table["held_force_N"])
    assert held == pytest.approx(np.asarray(result.table["force_N"]) * r, rel=1e-14)
    # stress ratio: the root stress 6 F L / (b h^2) of the elastic start over the strength
    ratio = 6.0 * s["hold_initial_force_N"] * L_MM / (B_MM * H_MM**2) / 42.5
    assert s["hold_stress_ratio"] == pytest.approx(ratio, rel=2e-3)
    assert s["hold_in_range"] is True and "quasi-elastic" in s["hold_method"]
    assert result.info["hold"]["law"]["n"] == N


def test_the_verdict_judges_the_held_values(small):
    study, result = small
    rows = {v.quantity: v for v in judge_result(study, result)}
    assert rows["held_force_N"].met
    assert not rows["force_retention"].met  # 0.82 of the force is left, not 0.99
    assert rows["force_retention"].value == pytest.approx(retention_by_hand(24.0), rel=1e-12)
    assert "test law" in rows["held_force_N"].detail
    assert "ASSUMED" not in rows["held_force_N"].bound
    without = replace(result, table={k: v for k, v in result.table.items() if k != "held_force_N"})
    assert {v.quantity: v.met for v in judge_result(study, replace(without, verdicts=()))} == {
        v.quantity: v.met for v in judge_result(study, result)
    }  # judge_result holds the design itself (a robustness sample has no with_hold)


def test_a_held_band_on_the_held_curve(small):
    """The constant-force style requirement after a hold: a target band on held_force_N."""
    study, result = small
    r = retention_by_hand(24.0)
    f_end = float(np.asarray(result.table["force_N"])[-1])
    raw = cantilever(
        hold={"time_h": 24.0, "level": 0.5},
        requirements=[
            {
                "quantity": "held_force_N",
                "x": "displacement_mm",
                "over": [0.9, 1.0],
                "target": {"kind": "constant", "force_N": f_end * r},
                "tolerance_rel": 0.15,
            }
        ],  # fmt: skip
    )
    band_study = validate_study(raw)
    fresh = replace(result, verdicts=())  # judged afresh (the result carries the first verdict)
    (row,) = [v for v in judge_result(band_study, fresh) if v.quantity == "held_force_N"]
    assert row.met, row
    assert row.value == pytest.approx(0.0, abs=0.15 * f_end * r)


def test_force_held_deflection_grows_by_the_compliance():
    """A linear response: the drive after a force hold is the elastic one x (1 + (t/tau)^n)."""
    table = {
        "displacement_mm": np.linspace(0.0, 10.0, 21),
        "force_N": np.linspace(0.0, 5.0, 21),
        "peak_stress_MPa": np.linspace(0.0, 10.0, 21),
    }
    from flexopt.fea.creep import CreepLaw

    law = CreepLaw(tau_h=TAU_H, n=N, max_stress_ratio=0.5, source="t")
    spec = HoldSpec(time_h=50.0, at="force", level=2.0)
    got = hold_of_table(spec, table, "displacement_mm", "force_N", law, 42.5)
    growth = 1.0 + math.sqrt(50.0 / TAU_H)
    assert got.drive == pytest.approx(4.0)
    assert got.held_drive == pytest.approx(4.0 * growth, rel=1e-12)
    assert got.values()["deflection_growth"] == pytest.approx(growth, rel=1e-12)
    assert got.values()["held_displacement_mm"] == pytest.approx(4.0 * growth, rel=1e-12)
    # the stress of a linear part under a held force stays: 4 MPa at 4 mm
    assert got.stress_MPa == pytest.approx(4.0, rel=1e-12)
    with pytest.raises(OptimiseError, match="beyond the traced curve"):
        hold_of_table(HoldSpec(time_h=1e5, at="force", level=4.9), table,
                      "displacement_mm", "force_N", law, 42.5)  # fmt: skip


def test_above_the_fitted_stress_ratio_the_hold_is_not_met_with_the_reason():
    study = validate_study(
        cantilever(
            max_mm=20.0,
            steps=10,
            mat=material(max_stress_ratio=0.2),
            hold={"time_h": 1.0, "fraction": 1.0},
            requirements=[{"quantity": "held_force_N", "min": 0.1}],
        )  # fmt: skip
    )
    from flexopt.pipeline.verdict import with_hold

    result = with_hold(study, solve_study(study))
    assert result.summary["hold_in_range"] is False
    assert result.summary["held_force_N"] is None
    assert "out of range" in result.summary["hold_note"]
    assert "above the 0.2" in result.summary["hold_note"]
    (row,) = [v for v in judge_result(study, result) if v.quantity == "held_force_N"]
    assert not row.met and "out of range" in row.detail


@pytest.mark.parametrize(
    ("extra", "key", "fragment"),
    [
        ({"material": "ABS", "hold": {"time_h": 1, "level": 1}}, "hold", "no creep data for ABS"),
        ({"hold": {"time_h": 1, "level": 1, "temperature_C": 60}}, "hold.temperature_C",
         "time-temperature shift"),
        ({"hold": {"time_h": 1}}, "hold", "exactly one of level"),
        ({"hold": {"time_h": 0, "level": 1}}, "hold.time_h", ""),
        ({"hold": {"time_h": 1, "level": 1},
          "requirements": [{"quantity": "force_retention", "min": 0.5, "role": "constraint"}]},
         "requirements[0].role", "held value"),
        ({"requirements": [{"quantity": "held_force_N", "min": 0.5}]},
         "requirements[0].quantity", "reports no 'held_force_N'"),
    ],
)  # fmt: skip
def test_bad_holds_are_refused_naming_the_key(extra, key, fragment):
    with pytest.raises(StudyError) as err:
        validate_study(cantilever(**extra))
    text = str(err.value)
    assert len(text.splitlines()) == 1, text
    assert key in text and fragment in text, text


def test_an_assumed_law_is_labelled_in_the_verdict_line(small):
    study, result = small
    raw = cantilever(
        mat=material(assumed=True, source="assumed for illustration"),
        hold={"time_h": 24.0, "level": 0.5},
        requirements=[{"quantity": "held_force_N", "min": 0.001}],
    )
    labelled = validate_study(raw)
    fresh = replace(result, verdicts=())
    (row,) = [v for v in judge_result(labelled, fresh) if v.quantity == "held_force_N"]
    assert "[ASSUMED creep law]" in row.bound
    assert row.detail.startswith("ASSUMED, illustrative creep law")


def test_a_study_without_hold_or_creep_dumps_as_before():
    raw = cantilever()
    raw["material"] = "ABS"
    text = study_to_yaml(validate_study(raw))
    assert "\nhold:" not in text and "creep" not in text
    with_law = study_to_yaml(validate_study(cantilever(hold={"time_h": 2.0, "level": 0.5})))
    assert "\nhold:" in with_law and "creep:" in with_law


def test_a_user_material_carries_its_creep_law(tmp_path):
    (tmp_path / "materials.yaml").write_text(
        "my-abs:\n  E_MPa: 1800\n  nu: 0.35\n  yield_MPa: 42.5\n"
        "  creep: {tau_h: 200, n: 0.5, max_stress_ratio: 0.3, source: coupon hold test}\n"
    )
    raw = cantilever(hold={"time_h": 1.0, "level": 0.5})
    raw["material"] = "my-abs"
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(raw))
    study = load_study(path)
    assert study.material.creep.tau_h == 200.0
    assert study.material.creep.source == "coupon hold test"


def test_a_run_s_best_detail_carries_the_hold():
    """flexopt run's best design: the problem's detail has info["hold"] (best.json) and the
    held force; the constant-force kind's force band, after the hold, is its curve x E_R/E0."""
    from pathlib import Path

    from flexopt.pipeline.problems import build_base_problem, nominal_design

    root = Path(__file__).resolve().parents[2]
    raw = yaml.safe_load((root / "pipeline/examples/constant-force.yaml").read_text("utf-8"))
    base = validate_study(raw)
    mat = {**base.material.model_dump(), "creep": material(max_stress_ratio=1.0)["creep"]}
    study = validate_study({**raw, "material": mat, "hold": {"time_h": 100.0, "fraction": 0.5}})
    problem = build_base_problem(study)
    assert type(problem).__name__ == "HoldDetail"
    detail = problem.detail(nominal_design(problem, study))
    hold = detail.info["hold"]
    r = retention_by_hand(100.0)
    assert hold["relaxation_ratio"] == pytest.approx(r, rel=1e-12)
    assert hold["hold_in_range"] and hold["force_retention"] == hold["relaxation_ratio"]
    assert detail.summary["held_force_N"] == pytest.approx(hold["hold_initial_force_N"] * r)
    held = np.asarray(detail.table["held_force_N"])
    assert held == pytest.approx(np.asarray(detail.table["force_N"]) * r, rel=1e-14)


def test_flexopt_evaluate_states_the_example_s_held_force(tmp_path, capsys):
    from flexopt.pipeline.cli import main

    assert main(["evaluate", "cantilever-hold", "--out", str(tmp_path / "run")]) == 0
    out = capsys.readouterr().out
    assert "held_force_N" in out and "[ASSUMED creep law]" in out
    record = yaml.safe_load((tmp_path / "run" / "evaluation.json").read_text("utf-8"))
    s = record["summary"]
    assert s["held_force_N"] == pytest.approx(s["hold_initial_force_N"] * s["force_retention"])
    assert s["creep_data_source"].startswith("ASSUMED")


def test_the_held_curve_is_the_solve_with_the_relaxed_modulus_at_large_deflection():
    """Why the held curve is the curve x E_R/E0: the nonlinear beam's forces scale with E at
    fixed geometry (E I, E A and k G A with G = E/(2(1+nu)) all scale), so a solve with E
    replaced by E_R(t) at 20 mm tip deflection (33 % of L, 29 deg tip rotation) is the elastic
    solve's force column times E_R/E0, row by row, to the solver's tolerance."""
    r = retention_by_hand(1000.0)
    held_raw = cantilever(max_mm=20.0, steps=10, hold={"time_h": 1000.0, "fraction": 1.0})
    held_raw["material"] = material(max_stress_ratio=1.0)
    relaxed = copy.deepcopy(held_raw)
    relaxed["material"]["E_MPa"] = E_MPA * r
    del relaxed["hold"]
    from flexopt.pipeline.verdict import with_hold

    held = with_hold(validate_study(held_raw), solve_study(validate_study(held_raw)))
    solved = solve_study(validate_study(relaxed))
    f_held = np.asarray(held.table["held_force_N"])
    f_relaxed = np.asarray(solved.table["force_N"])
    assert f_held == pytest.approx(f_relaxed, rel=1e-8, abs=1e-12)
    assert held.summary["held_force_N"] == pytest.approx(f_relaxed[-1], rel=1e-8)
    # and the shape is the same: the tip rotation does not depend on E at a held displacement
    assert np.asarray(held.table["end_rotation_deg"]) == pytest.approx(
        np.asarray(solved.table["end_rotation_deg"]), rel=1e-8, abs=1e-12
    )
