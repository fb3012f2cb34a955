"""Fatigue life of the leaf-spring joint (issue 25): a duty cycle whose levels name the stiffness
setting they run at, each level's stress from its setting's own nonlinear solve, Miner's sum
over the settings; the levels naming none run at the worst setting, which the verdict names.

Every expected life is computed here by hand: 65Mn's Shigley line from Sut = 980 MPa (Budynas
& Nisbett ch. 6: Se' = 0.5 Sut, machined ka = 4.51 Sut^-0.265, f from sigma_F' = Sut + 345,
a = (f Sut)^2 / Se, b = -log10(f Sut / Se) / 3), Goodman's correction
S_ar = S_a / (1 - S_m / Sut) for a tensile mean, N = (S_ar / a)^(1/b) (infinite at or below
Se), and D = sum n_i / N_i; the stresses are read from the design's own response table (the
solver's peak at each level's drive, a table row).
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

import flexopt.pipeline as pipeline
import numpy as np
import pytest
import yaml
from flexopt.optimise.durability import DutyCycleSpec, life_of_table
from flexopt.optimise.errors import OptimiseError
from flexopt.pipeline.durability_report import durability_markdown, durability_record
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.study import validate_study
from flexopt.pipeline.verdict import judge_result

RAW = yaml.safe_load(
    (Path(pipeline.__file__).parent / "examples" / "leaf-spring-joint.yaml").read_text()
)
SUT = 980.0  # MPa, 65Mn (GB/T 1222), fea/materials.py FATIGUE_DATA
N_REQUIRED = 1.0e3


def shigley_65mn() -> tuple[float, float, float]:
    """(a MPa, b, Se MPa) of 65Mn, machined, by hand."""
    se = 4.51 * SUT**-0.265 * 0.5 * SUT
    sigma_f = SUT + 345.0
    b_e = -math.log10(sigma_f / (0.5 * SUT)) / math.log10(2.0e6)
    f = sigma_f / SUT * (2.0e3) ** b_e
    return (f * SUT) ** 2 / se, -math.log10(f * SUT / se) / 3.0, se


def hand_cycles(s_min: float, s_max: float) -> float:
    """Hand Basquin + Goodman cycles to failure of one stress cycle s_min -> s_max (MPa)."""
    a, b, se = shigley_65mn()
    amp, mean = 0.5 * abs(s_max - s_min), 0.5 * (s_max + s_min)
    s_ar = amp / (1.0 - mean / SUT) if mean > 0 else amp
    return math.inf if s_ar <= se else (s_ar / a) ** (1.0 / b)


def test_the_library_line_is_the_hand_line():
    from flexopt.fea.fatigue import material_sn_curve

    a, b, se = shigley_65mn()
    curve = material_sn_curve("65Mn")
    assert (curve.a_MPa, curve.b, curve.endurance_MPa) == pytest.approx((a, b, se), rel=1e-12)


# -- the arithmetic on a table with two settings (no solve) ------------------------------------

X = np.linspace(0.0, 8.0, 9)  # deg
TABLE = {"deflection_deg": X, "s_stiff": 160.0 * X, "s_soft": 90.0 * X}  # MPa
SETTINGS = {"stiff": "s_stiff", "soft": "s_soft", "lmin": "s_stiff"}


def test_each_level_takes_its_settings_stress_and_miner_sums_them():
    spec = DutyCycleSpec.model_validate(
        {"levels": [{"drive": 4.0, "cycles": 10, "setting": "stiff"},
                    {"drive": 8.0, "reversed": True, "cycles": 100, "setting": "soft"}]}
    )  # fmt: skip
    life = life_of_table(spec, TABLE, "deflection_deg", "65Mn", settings=SETTINGS)
    n1, n2 = hand_cycles(0.0, 640.0), hand_cycles(-720.0, 720.0)
    assert [lv.setting for lv in life.levels] == ["stiff", "soft"]
    assert [lv.cycles_to_failure for lv in life.levels] == pytest.approx([n1, n2], rel=1e-12)
    damage = 10 / n1 + 100 / n2
    assert life.damage_per_block == pytest.approx(damage, rel=1e-12)
    assert life.life_cycles == pytest.approx(110 / damage, rel=1e-12)
    assert life.setting_note == "every level at the setting it names"


def test_a_level_naming_no_setting_runs_at_the_worst_one_by_name():
    spec = DutyCycleSpec.model_validate({"levels": [{"drive": 6.0, "reversed": True, "cycles": 1}]})
    life = life_of_table(spec, TABLE, "deflection_deg", "65Mn", settings=SETTINGS)
    # the stiff setting's 960 MPa does more damage than the soft one's 540 MPa
    assert life.life_cycles == pytest.approx(hand_cycles(-960.0, 960.0), rel=1e-12)
    assert life.levels[0].setting == "stiff"
    assert life.setting_note.startswith("every level at the worst setting, stiff")
    assert f"at soft: {1.0 / hand_cycles(-540.0, 540.0):.4g})" in life.setting_note
    # lmin is an alias of stiff: tried once
    assert "lmin" not in life.setting_note
    assert life.summary()["life_setting"] == life.setting_note
    flipped = {"deflection_deg": X, "s_stiff": TABLE["s_soft"], "s_soft": TABLE["s_stiff"]}
    assert (
        life_of_table(spec, flipped, "deflection_deg", "65Mn", settings=SETTINGS).levels[0].setting
        == "soft"
    )


def test_a_history_runs_at_the_blocks_setting():
    spec = DutyCycleSpec.model_validate({"history": [0.0, 8.0, 2.0, 6.0, 0.0], "setting": "soft"})
    life = life_of_table(spec, TABLE, "deflection_deg", "65Mn", settings=SETTINGS)
    # rainflow of 0, 8, 2, 6, 0: the cycle 2 -> 6 -> 2 and the half-cycles 0 -> 8 and 8 -> 0
    assert sorted((lv.drive_min, lv.drive_max, lv.cycles) for lv in life.levels) == [
        (0.0, 8.0, 0.5), (0.0, 8.0, 0.5), (2.0, 6.0, 1.0)
    ]  # fmt: skip
    assert {lv.setting for lv in life.levels} == {"soft"}
    n_big, n_small = hand_cycles(0.0, 720.0), hand_cycles(180.0, 540.0)
    assert life.damage_per_block == pytest.approx(1 / n_big + 1 / n_small, rel=1e-12)


def test_settings_the_response_has_not_are_refused():
    spec = DutyCycleSpec.model_validate({"levels": [{"drive": 6.0, "cycles": 1, "setting": "x"}]})
    with pytest.raises(OptimiseError, match="setting 'x' is not a setting.*stiff, soft, lmin"):
        life_of_table(spec, TABLE, "deflection_deg", "65Mn", settings=SETTINGS)
    one = {"deflection_deg": X, "peak_stress_MPa": TABLE["s_soft"]}
    with pytest.raises(OptimiseError, match="one stress per row, no settings"):
        life_of_table(spec, one, "deflection_deg", "65Mn")
    plain = DutyCycleSpec.model_validate({"levels": [{"drive": 6.0, "cycles": 1}]})
    record = life_of_table(plain, one, "deflection_deg", "65Mn").levels[0].record()
    assert "setting" not in record  # other kinds' records are as they were


# -- the kind: a run's design (two settings) and flexopt evaluate ------------------------------


def leaf_raw(levels: list[dict], role: str = "check") -> dict:
    raw = copy.deepcopy(RAW)
    raw["target"]["max_deflection_deg"] = 8.0
    raw["boundary"] = {"max_deflection_deg": 8.0, "steps": 20, "check_deflection_deg": None}
    raw["geometry"]["effective_lengths_mm"] = [28.0, 48.0]
    raw["geometry"]["structures"] = ["sliding"]
    raw["duty_cycle"] = {"rate_hz": 2.0, "levels": levels}
    raw["requirements"] = [
        {"quantity": "life_cycles", "min": N_REQUIRED, "role": role, "name": "service life"}
    ]
    return raw


TWO = [
    {"fraction": 0.5, "cycles": 1, "setting": "stiff"},  # one-sided 0 -> 4 deg at l_min
    {"fraction": 1.0, "reversed": True, "cycles": 5, "setting": "soft"},  # +-8 deg at l_max
]


def at(detail, column: str, deg: float) -> float:
    """The table's stress at a deflection that is one of its rows (MPa)."""
    x = np.asarray(detail.table["deflection_deg"])
    row = int(np.argmin(np.abs(x - deg)))
    assert x[row] == pytest.approx(deg, abs=1e-9)
    return float(detail.table[column][row])


@pytest.fixture(scope="module")
def run_design():
    from flexopt.pipeline.problems import build_base_problem, nominal_design

    study = validate_study(leaf_raw(TWO, role="constraint"))
    problem = build_base_problem(study)
    x = nominal_design(problem, study)
    return study, problem, x, problem.detail(x)


def test_a_runs_design_has_the_hand_life_of_its_two_settings(run_design):
    study, problem, x, detail = run_design
    stiff = at(detail, "stress_MPa_lmin", 4.0)
    soft = at(detail, "stress_MPa_lmax", 8.0)
    n1, n2 = hand_cycles(0.0, stiff), hand_cycles(-soft, soft)
    assert math.isfinite(n1) and math.isfinite(n2) and min(n1, n2) > 1e3  # both damage
    damage = 1 / n1 + 5 / n2
    life = 6 / damage
    assert detail.summary["life_cycles"] == pytest.approx(life, rel=1e-9)
    assert detail.summary["life_hours"] == pytest.approx(life / 2.0 / 3600.0, rel=1e-9)
    levels = detail.info["fatigue"]["levels"]
    assert [lv["setting"] for lv in levels] == ["stiff", "soft"]
    # the GA's row: decades short of the requirement, on the same life
    i = list(problem.constraint_names).index("req_service life")
    ev = problem.evaluate(x)
    assert ev.g[i] == pytest.approx(math.log10(N_REQUIRED) - math.log10(life), abs=1e-9)
    assert ev.metrics["life_cycles"] == pytest.approx(life, rel=1e-9)
    # the verdict, report.md / report.html, best.json (durability record) say the same
    verdict = {v.name: v for v in judge_result(study, detail, x)}["service life"]
    assert verdict.value == pytest.approx(life, rel=1e-9)
    assert verdict.detail == "every level at the setting it names"
    record = durability_record(study, detail)
    assert [r["setting"] for r in record["fatigue"]["levels"]] == ["stiff", "soft"]
    text = "\n".join(durability_markdown(record))
    assert "| level | setting | drive min |" in text and "| 1 | stiff |" in text
    assert "Settings: every level at the setting it names." in text


def test_the_life_constraint_leaves_objectives_and_other_rows_as_without_it(run_design):
    from flexopt.pipeline.problems import build_base_problem

    study, problem, x, _ = run_design
    plain = build_base_problem(validate_study(leaf_raw(TWO, role="check")))
    ev, ev0 = problem.evaluate(x), plain.evaluate(x)
    i = list(problem.constraint_names).index("req_service life")
    np.testing.assert_array_equal(ev.f, ev0.f)
    np.testing.assert_array_equal(np.delete(ev.g, i), ev0.g)


def test_evaluate_runs_unnamed_levels_at_the_worst_curve_and_says_which():
    from flexopt.pipeline.evaluate import solve_study

    study = validate_study(leaf_raw([{"fraction": 0.5, "reversed": True, "cycles": 1}]))
    result = solve_study(study)
    stiff = at(result, "stress_MPa_sliding_l28", 4.0)
    soft = at(result, "stress_MPa_sliding_l48", 4.0)
    assert stiff > soft
    assert result.summary["life_cycles"] == pytest.approx(hand_cycles(-stiff, stiff), rel=1e-9)
    verdict = {v.name: v for v in result.verdicts or judge_result(study, result)}["service life"]
    assert verdict.detail.startswith("every level at the worst setting, stiff")


def test_an_unknown_setting_is_refused_at_load_time():
    with pytest.raises(StudyError, match=r"duty_cycle.levels\[0\].setting.*'medium' is no setting"):
        validate_study(leaf_raw([{"fraction": 1.0, "cycles": 1, "setting": "medium"}]))
    validate_study(leaf_raw([{"fraction": 1.0, "cycles": 1, "setting": "sliding_l48"}]))
    raw = leaf_raw([{"fraction": 1.0, "cycles": 1}])
    raw["duty_cycle"]["setting"] = "fixed_l28"  # fixed is not analysed in this study
    with pytest.raises(StudyError, match=r"duty_cycle.setting.*sliding_l28, sliding_l48"):
        validate_study(raw)


@pytest.mark.parametrize("example", ["cantilever", "flexure-pivot"])
def test_a_kind_with_one_stress_per_row_refuses_a_setting_at_load_time(example):
    raw = yaml.safe_load(
        (Path(pipeline.__file__).parent / "examples" / f"{example}.yaml").read_text()
    )
    raw["duty_cycle"] = {"levels": [{"fraction": 1.0, "cycles": 1, "setting": "stiff"}]}
    with pytest.raises(StudyError, match=r"duty_cycle.levels\[0\].setting.*leave setting out"):
        validate_study(raw)
    raw["duty_cycle"] = {"history": [0.0, 1.0, 0.0], "setting": "stiff"}
    with pytest.raises(StudyError, match=r"duty_cycle.setting: kind"):
        validate_study(raw)
