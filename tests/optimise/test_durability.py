"""Fatigue life over a study's duty cycle (optimise/durability.py, the verdict's hook).

Every expected value is computed by hand in the test: the root stress of a cantilever from its
tip force (6 F L / (b h^2)), Basquin's line of the material (S = a N^b through the static
strength at N = 1 and 0.25 x of it at 10^6 cycles, the printed-ABS estimate), Goodman's and
SWT's mean-stress corrections and Miner's sum.
"""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest
from flexopt.optimise.durability import DutyCycleSpec, life_of_table
from flexopt.optimise.errors import OptimiseError
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.evaluate import solve_study
from flexopt.pipeline.study import validate_study

L_MM, H_MM, B_MM = 60.0, 1.5, 8.0
SUT_ABS = 42.5  # ABS static strength, MPa (fea/materials.py, paper 003)


def cantilever(**extra) -> dict:
    """The cantilever example: ABS, 60 x 1.5 x 8 mm, tip pushed 20 mm in 20 steps."""
    raw = {
        "name": "cantilever-life",
        "geometry": {
            "kind": "polyline_beam",
            "points_mm": [[0, 0], [30, 0], [60, 0]],
            "thickness_mm": [H_MM] * 3,
            "width_mm": B_MM,
            "elements": 30,
        },
        "material": "ABS",
        "boundary": {
            "start": "clamped",
            "end": {
                "control": "displacement",
                "direction": [0, 1],
                "max_mm": 20.0,
                "steps": 20,
                "rotation": "free",
                "transverse": "free",
            },
        },
    }
    raw.update(copy.deepcopy(extra))
    return raw


def basquin_abs_cycles(s_ar: float) -> float:
    """Cycles to failure of printed ABS at a fully reversed amplitude (MPa), by hand."""
    b = math.log10(0.25) / 6.0
    a = 0.25 * SUT_ABS / 1.0e6**b
    return (s_ar / a) ** (1.0 / b)


@pytest.fixture(scope="module")
def one_level():
    """The cantilever with a one-sided 0 -> 2 mm duty cycle, solved once."""
    study = validate_study(
        cantilever(duty_cycle={"rate_hz": 2.0, "levels": [{"drive": 2.0, "cycles": 1}]})
    )
    return study, solve_study(study)


def root_stress(result, drive_mm: float) -> float:
    """6 F L / (b h^2) at the table's row of ``drive_mm`` (MPa): small deflection, tip load F."""
    row = int(np.flatnonzero(np.isclose(result.table["displacement_mm"], drive_mm))[0])
    force = float(result.table["force_N"][row])
    assert float(result.table["peak_stress_s_mm"][row]) == pytest.approx(0.0, abs=1e-9)
    return 6.0 * force * L_MM / (B_MM * H_MM**2)


def test_constant_amplitude_tip_load_against_basquin_goodman(one_level):
    study, result = one_level
    s_max = root_stress(result, 2.0)
    # one-sided 0 -> s_max: amplitude = mean = s_max / 2; Goodman: s_a / (1 - s_m / Sut)
    s_a = s_m = 0.5 * s_max
    n_hand = basquin_abs_cycles(s_a / (1.0 - s_m / SUT_ABS))
    summary = result.summary
    # the solver's peak (a beam with its axial stretch, at the root's node) is within 0.1 % of
    # the small-deflection formula; Basquin amplifies it by |1/b| ~ 10 in the life
    rel = 1.0e-3 / abs(math.log10(0.25) / 6.0)
    assert summary["life_cycles"] == pytest.approx(n_hand, rel=rel)
    assert summary["fatigue_damage_per_cycle_block"] == pytest.approx(1.0 / n_hand, rel=rel)
    assert summary["life_hours"] == pytest.approx(n_hand / 2.0 / 3600.0, rel=rel)
    assert summary["life_in_range"] is True
    assert "goodman" in summary["life_method"] and "peak stress" in summary["life_method"]
    assert "estimate" in summary["fatigue_data_source"]
    level = result.info["fatigue"]["levels"][0]
    assert level["stress_max_MPa"] == pytest.approx(s_max, rel=1e-3)
    assert level["amplitude_MPa"] == pytest.approx(s_a, rel=1e-3)
    # the same chain on the solver's own stress: exact
    s_a = s_m = 0.5 * level["stress_max_MPa"]
    exact = basquin_abs_cycles(s_a / (1.0 - s_m / SUT_ABS))
    assert summary["life_cycles"] == pytest.approx(exact, rel=1e-12)


def test_mean_drive_with_swt_and_reversed(one_level):
    study, result = one_level
    s1, s2 = root_stress(result, 1.0), root_stress(result, 2.0)
    # 1 -> 2 mm with SWT: sqrt(s_max s_a); and a fully reversed +-2 mm (mean 0)
    spec = DutyCycleSpec.model_validate(
        {
            "correction": "swt",
            "levels": [
                {"drive": 2.0, "mean": 1.0, "cycles": 10},
                {"drive": 2.0, "reversed": True, "cycles": 1},
            ],
        }
    )
    life = life_of_table(spec, result.table, "displacement_mm", "ABS")
    s_a = 0.5 * (s2 - s1)
    n1 = basquin_abs_cycles(math.sqrt(s2 * s_a))
    n2 = basquin_abs_cycles(math.sqrt(s2 * s2))  # reversed: s_a = s_max = s2
    rel = 1.0e-3 / abs(math.log10(0.25) / 6.0)  # 0.1 % in stress, |1/b| x in life
    assert life.levels[0].cycles_to_failure == pytest.approx(n1, rel=rel)
    assert life.levels[1].cycles_to_failure == pytest.approx(n2, rel=rel)
    assert life.levels[1].mean_MPa == pytest.approx(0.0, abs=1e-9)
    d = 10.0 / n1 + 1.0 / n2
    assert life.damage_per_block == pytest.approx(d, rel=rel)
    assert life.life_cycles == pytest.approx(11.0 / d, rel=rel)


# a synthetic response: the peak stress 10 MPa per mm of drive, traced to 4 mm
TABLE = {"displacement_mm": np.linspace(0.0, 4.0, 9), "peak_stress_MPa": np.linspace(0, 40, 9)}


def test_two_level_block_against_miner_by_hand():
    spec = DutyCycleSpec.model_validate(
        {
            "rate_hz": 0.5,
            "levels": [{"drive": 2.0, "cycles": 1000}, {"fraction": 0.75, "cycles": 10}],
        }
    )
    life = life_of_table(spec, TABLE, "displacement_mm", "ABS")
    # level 1: 0 -> 20 MPa; level 2: 0 -> 30 MPa (0.75 of the 4 mm stroke)
    n = [
        basquin_abs_cycles(10.0 / (1 - 10.0 / SUT_ABS)),
        basquin_abs_cycles(15.0 / (1 - 15.0 / SUT_ABS)),
    ]
    d = 1000.0 / n[0] + 10.0 / n[1]
    assert life.damage_per_block == pytest.approx(d, rel=1e-12)
    assert life.life_cycles == pytest.approx(1010.0 / d, rel=1e-12)
    assert life.life_hours == pytest.approx(1010.0 / d / 0.5 / 3600.0, rel=1e-12)
    # as shares: the block is one cycle
    shares = DutyCycleSpec.model_validate(
        {"levels": [{"drive": 2.0, "share_percent": 75}, {"drive": 3.0, "share_percent": 25}]}
    )
    got = life_of_table(shares, TABLE, "displacement_mm", "ABS")
    assert got.damage_per_block == pytest.approx(0.75 / n[0] + 0.25 / n[1], rel=1e-12)
    assert got.life_hours is None  # no rate: no hours


def test_history_counted_by_rainflow_and_steel_endurance():
    # drives 0 -> 3 -> 1 -> 3 -> 0: one full 1..3 cycle and the half cycles 0..3, 3..0
    spec = DutyCycleSpec.model_validate({"history": [0, 3, 1, 3, 0], "correction": "none"})
    life = life_of_table(spec, TABLE, "displacement_mm", "ABS")
    by_hand = 0.5 / basquin_abs_cycles(15.0) * 2 + 1.0 / basquin_abs_cycles(10.0)
    assert life.damage_per_block == pytest.approx(by_hand, rel=1e-12)
    assert "rainflow" in life.method
    # 65Mn's endurance limit (356 MPa) is far above 40 MPa: infinite life, met by any minimum
    steel = life_of_table(spec, TABLE, "displacement_mm", "65Mn")
    assert steel.life_cycles == math.inf and steel.summary()["life_cycles"] is None
    assert steel.summary()["life_infinite"] is True


def test_a_drive_beyond_the_stroke_is_not_a_life():
    spec = DutyCycleSpec.model_validate([{"drive": 5.0, "cycles": 1}])  # a bare list: levels
    with pytest.raises(OptimiseError, match="beyond the traced stroke 4"):
        life_of_table(spec, TABLE, "displacement_mm", "ABS")


@pytest.mark.parametrize(
    ("duty", "key", "fragment"),
    [
        ([{"drive": 1.0, "fraction": 0.5, "cycles": 1}], "duty_cycle.levels[0]", "exactly one of"),
        ([{"drive": 1.0}], "duty_cycle.levels[0]", "cycles (per block) or share_percent"),
        ([{"fraction": 1.5, "cycles": 1}], "duty_cycle.levels[0].fraction", "1"),
        ([{"drive": 1.0, "cycles": -3}], "duty_cycle.levels[0].cycles", "0"),
        (
            [{"drive": 1.0, "share_percent": 50}, {"drive": 2.0, "share_percent": 40}],
            "duty_cycle",
            "sum to 90",
        ),
        (
            [{"drive": 1.0, "share_percent": 50}, {"drive": 2.0, "cycles": 4}],
            "duty_cycle",
            "mix",
        ),
        ([{"drive": 1.0, "cycles": 1, "reversed": True, "mean": 0.5}], "duty_cycle", "mean"),
        ({"levels": [{"drive": 1, "cycles": 1}], "history": [0, 1]}, "duty_cycle", "exactly one"),
        ({"history": [1]}, "duty_cycle.history", "2"),
        ({"levels": [{"drive": 1, "cycles": 1}], "rate_hz": 0}, "duty_cycle.rate_hz", "0"),
        ({"levels": [{"drive": 1, "cycles": 1}], "correction": "gerber"}, "duty_cycle", "goodman"),
        ({"levels": [{"drive": 1, "cycles": 1}], "surface": "polished"}, "duty_cycle.surface", ""),
    ],
)
def test_bad_duty_cycles_are_refused_naming_the_key(duty, key, fragment):
    with pytest.raises(StudyError) as err:
        validate_study(cantilever(duty_cycle=duty))
    text = str(err.value)
    assert len(text.splitlines()) == 1, text
    assert key in text and fragment in text, text


def test_life_requirements_are_refused_where_they_cannot_be_judged():
    dc = {"levels": [{"drive": 1, "cycles": 1}]}
    with pytest.raises(StudyError, match=r"requirements\[0\].quantity.*duty_cycle.rate_hz"):
        validate_study(
            cantilever(duty_cycle=dc, requirements=[{"quantity": "life_hours", "min": 1}])
        )
    with pytest.raises(StudyError, match=r"requirements\[0\].quantity.*no 'life_cycles'"):
        validate_study(cantilever(requirements=[{"quantity": "life_cycles", "min": 1}]))
    own = {"name": "mine", "E_MPa": 2000.0, "nu": 0.35, "yield_MPa": 40.0}
    with pytest.raises(StudyError, match="duty_cycle.*no fatigue data for material 'mine'"):
        validate_study(cantilever(duty_cycle=dc, material=own))


def test_a_study_without_a_duty_cycle_dumps_as_before():
    study = validate_study(cantilever())
    assert "duty_cycle" not in study.model_dump(mode="json")
    with_dc = validate_study(cantilever(duty_cycle=[{"drive": 1, "cycles": 1}]))
    assert with_dc.model_dump(mode="json")["duty_cycle"]["levels"][0]["drive"] == 1


def test_flexopt_evaluate_states_the_life_in_the_verdict(tmp_path, capsys):
    import yaml

    raw = cantilever(
        duty_cycle={"rate_hz": 1.0, "levels": [{"fraction": 1.0, "cycles": 1}]},
        requirements=[
            {"quantity": "life_cycles", "min": 1.0e3, "name": "lives_1e3_cycles"},
            {"quantity": "life_cycles", "min": 1.0e5, "name": "lives_1e5_cycles"},
        ],
    )
    path = tmp_path / "cantilever-life.yaml"
    path.write_text(yaml.safe_dump(raw), encoding="utf-8")
    out = tmp_path / "ev"
    assert main(["evaluate", str(path), "--out", str(out)]) == 0
    record = json.loads((out / "evaluation.json").read_text(encoding="utf-8"))
    rows = {r["name"]: r for r in record["verdict"]["requirements"]}
    life = record["summary"]["life_cycles"]
    assert 1.0e3 < life < 1.0e5
    assert rows["lives_1e3_cycles"]["verdict"] == "MET"
    assert rows["lives_1e5_cycles"]["verdict"] == "NOT MET"
    assert rows["lives_1e3_cycles"]["value"] == pytest.approx(life, rel=1e-12)
    assert record["verdict"]["overall"] == "NOT MET"
    assert record["summary"]["fatigue_damage_per_cycle_block"] == pytest.approx(1 / life)
    assert "lives_1e5_cycles" in capsys.readouterr().out


def test_the_stress_is_scaled_to_the_figure_the_verdict_judges():
    from pathlib import Path

    import yaml

    root = Path(__file__).resolve().parents[2]
    raw = yaml.safe_load((root / "pipeline/examples/constant-force.yaml").read_text("utf-8"))
    raw["duty_cycle"] = {"levels": [{"fraction": 0.5, "cycles": 1}], "correction": "none"}
    result = solve_study(validate_study(raw))
    peak = np.asarray(result.table["peak_stress_MPa"], dtype=float)
    scale = result.summary["plane_stress_peak_stress_MPa"] / float(np.nanmax(np.abs(peak)))
    assert result.info["fatigue"]["scale"] == pytest.approx(scale, rel=1e-12)
    assert "plane stress" in result.summary["life_method"]
    x = np.asarray(result.table["displacement_mm"], dtype=float)
    half = 0.5 * float(np.nanmax(np.abs(x)))
    s_max = scale * float(np.interp(half, x, np.abs(peak)))  # the table rises from 0 to stroke
    level = result.info["fatigue"]["levels"][0]
    assert level["stress_max_MPa"] == pytest.approx(s_max, rel=1e-12)
    assert level["cycles_to_failure"] == pytest.approx(basquin_abs_cycles(0.5 * s_max), rel=1e-12)


def test_a_run_s_best_detail_carries_the_life():
    from pathlib import Path

    import yaml
    from flexopt.pipeline.problems import build_base_problem, nominal_design

    root = Path(__file__).resolve().parents[2]
    raw = yaml.safe_load((root / "pipeline/examples/constant-force.yaml").read_text("utf-8"))
    study = validate_study({**raw, "duty_cycle": [{"fraction": 0.5, "cycles": 1}]})
    problem = build_base_problem(study)
    detail = problem.detail(nominal_design(problem, study))
    fatigue = detail.info["fatigue"]  # best.json writes the detail's info
    assert fatigue["life_cycles"] == pytest.approx(1.0 / fatigue["fatigue_damage_per_cycle_block"])
    assert detail.summary["life_cycles"] == fatigue["life_cycles"]
    # without the block the problem is the kind's, unwrapped
    plain = build_base_problem(validate_study(raw))
    assert type(plain).__name__ != "LifeDetail"
