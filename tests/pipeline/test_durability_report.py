"""The Durability section of report.md and report.html, best.json's ``durability`` and the API's
(pipeline/durability_report.py): present with a duty_cycle, a hold or stops, with the numbers
of the evaluation itself; absent without those blocks."""

from __future__ import annotations

import html
import json
import re
import sys
from pathlib import Path

import flexopt
import numpy as np
import pytest
import yaml
from flexopt.pipeline.durability_report import durability_markdown, durability_record
from flexopt.pipeline.report import format_value
from flexopt.pipeline.studies._constant_force_clamp import CHECKED_PEAK, CHECKED_PEAK_MODEL
from flexopt.pipeline.study import validate_study

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "pipeline" / "examples"
sys.path.insert(0, str(ROOT / "tests" / "optimise"))
from test_durability import cantilever  # noqa: E402  (the durability tests' cantilever)

TWO_LEVELS = {
    "rate_hz": 2.0,
    "levels": [{"drive": 2.0, "cycles": 1}, {"drive": 10.0, "cycles": 3, "reversed": True}],
}


def html_cells(text: str, section: str = "durability") -> list[str]:
    """The table cells of report.html's section ``section``, as shown (entities decoded)."""
    body = re.search(rf'<section id="{section}">(.*?)</section>', text, re.S)
    assert body is not None, f"no section {section}"
    return [html.unescape(c) for c in re.findall(r"<td>(.*?)</td>", body.group(1), re.S)]


def md_section(text: str) -> str:
    """report.md's ``## Durability`` section."""
    match = re.search(r"^## Durability\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    assert match is not None, "no ## Durability section"
    return match.group(1)


def shown(value: float) -> str:
    return format_value(value)


@pytest.fixture(scope="module")
def fatigue_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("life") / "ev"
    return flexopt.evaluate(cantilever(duty_cycle=TWO_LEVELS), out=out), out


def test_fatigue_in_the_evaluate_report_html_and_the_api(fatigue_folder):
    result, out = fatigue_folder
    fat = result.durability["fatigue"]
    assert set(result.durability) == {"fatigue"}
    assert fat["miner_sum"] == pytest.approx(result.summary["fatigue_damage_per_cycle_block"])
    assert fat["life_cycles"] == result.summary["life_cycles"]
    assert fat["life_hours"] == result.summary["life_hours"]
    # Miner: the block's 1 + 3 cycles over the damage of one block
    assert fat["life_cycles"] == pytest.approx(4.0 / fat["miner_sum"], rel=1e-12)
    assert fat["life_hours"] == pytest.approx(fat["life_cycles"] / 2.0 / 3600.0, rel=1e-12)
    assert fat["correction"] == "goodman" and fat["source"] == result.summary["fatigue_data_source"]
    assert fat["sn_curve"]["a_MPa"] > 0 and fat["sn_curve"]["b"] < 0
    text = (out / "report.html").read_text(encoding="utf-8")
    assert '<a href="#durability">' in text
    cells = html_cells(text)
    for level in fat["levels"]:
        for key in ("amplitude_MPa", "mean_MPa", "cycles", "damage"):
            assert shown(level[key]) in cells, key
    # the reversed level: mean 0, amplitude the peak at 10 mm; damage n / N per level
    assert fat["levels"][1]["mean_MPa"] == pytest.approx(0.0, abs=1e-12)
    assert fat["levels"][1]["damage"] == pytest.approx(3.0 / fat["levels"][1]["cycles_to_failure"])
    assert shown(fat["miner_sum"]) in cells and shown(fat["life_cycles"]) in cells
    assert shown(fat["life_hours"]) in cells and "goodman" in cells
    assert any(fat["source"] in c for c in cells)  # the S-N data's source, named
    assert any(c.startswith("level 2 at displacement_mm = 10") for c in cells)  # critical
    # report.md's writer gives the same section from the same record
    md = "\n".join(durability_markdown(result.durability))
    assert f"| {shown(fat['miner_sum'])} |" in md and "### Fatigue (duty_cycle)" in md
    # evaluation.json is as before: the summary's scalars, no new key
    assert "durability" not in json.loads((out / "evaluation.json").read_text(encoding="utf-8"))


def test_creep_hold_of_the_example():
    result = flexopt.evaluate(EXAMPLES / "cantilever-hold.yaml")
    hold = result.durability["hold"]
    assert set(result.durability) == {"hold"}
    assert hold["held_name"] == "held_force_N"
    assert hold["held_value"] == result.summary["held_force_N"]
    assert hold["retention"] == result.summary["force_retention"]
    assert hold["stress_ratio"] == result.summary["hold_stress_ratio"]
    assert hold["initial_value"] == result.summary["hold_initial_force_N"]
    assert hold["time_h"] == 1000.0 and hold["max_stress_ratio"] == 0.3 and hold["assumed"]
    assert hold["law"]["tau_h"] == 5000.0 and hold["law"]["n"] == 0.25
    # the held force is the elastic force at the held displacement times the retention
    assert hold["held_value"] == pytest.approx(hold["initial_value"] * hold["retention"])
    md = md_section("\n".join(durability_markdown(result.durability)))
    assert "ASSUMED" in md and shown(hold["held_value"]) in md
    assert f"{shown(hold['stress_ratio'])} / 0.3 (within)" in md


def test_creep_hold_in_the_evaluate_report_html(tmp_path):
    result = flexopt.evaluate(EXAMPLES / "cantilever-hold.yaml", out=tmp_path / "ev")
    cells = html_cells((tmp_path / "ev" / "report.html").read_text(encoding="utf-8"))
    hold = result.durability["hold"]
    assert any("ASSUMED, illustrative creep law" in c for c in cells)
    for key in ("held_value", "retention", "initial_value", "stress_MPa"):
        assert shown(hold[key]) in cells, key
    assert "the displacement for 1000 h at the law's 23 C" in cells


def test_contact_of_the_stop_example(tmp_path):
    result = flexopt.evaluate(EXAMPLES / "cantilever-stop.yaml", out=tmp_path / "ev")
    contact = result.durability["contact"]
    assert set(result.durability) == {"contact"}
    (stop,) = contact["stops"]
    s = result.summary
    assert stop["stop"] == "anvil"
    assert stop["max_contact_force_N"] == s["anvil_max_contact_force_N"]
    assert stop["first_contact_displacement_mm"] == s["anvil_first_contact_displacement_mm"]
    assert stop["min_gap_mm"] == s["anvil_min_gap_mm"]
    assert contact["max_penetration_mm"] == s["max_penetration_mm"]
    assert contact["penalty_factor"] == s["contact_penalty_factor"]
    # the force the anvil carries is the contact column's largest, first contact near 1.6 mm
    force = np.asarray(result.table["anvil_contact_force_N"], dtype=float)
    assert stop["max_contact_force_N"] == pytest.approx(float(np.nanmax(force)))
    assert stop["first_contact_displacement_mm"] == pytest.approx(1.6, abs=0.05)
    cells = html_cells((tmp_path / "ev" / "report.html").read_text(encoding="utf-8"))
    for key in ("max_contact_force_N", "first_contact_displacement_mm", "min_gap_mm"):
        assert shown(stop[key]) in cells, key
    assert any(c.startswith(shown(contact["max_penetration_mm"])) for c in cells)
    assert any(c.startswith(shown(contact["penalty_factor"])) for c in cells)


def test_absent_without_the_blocks(tmp_path):
    result = flexopt.evaluate(cantilever(), out=tmp_path / "ev")
    assert result.durability == {}
    text = (tmp_path / "ev" / "report.html").read_text(encoding="utf-8")
    assert 'id="durability"' not in text and "#durability" not in text
    assert durability_markdown(result.durability) == []


def test_report_md_of_a_run_detail():
    """render_report (report.md of a run folder) shows the section from the best design's
    detail, with its numbers; without a duty_cycle there is none."""
    from flexopt.pipeline.problems import build_base_problem, nominal_design
    from flexopt.pipeline.report import ReportData, render_report

    raw = yaml.safe_load((EXAMPLES / "constant-force.yaml").read_text("utf-8"))

    def report(study):
        problem = build_base_problem(study)
        detail = problem.detail(nominal_design(problem, study))
        record = {"optimiser": {}, "status": "finished"}
        data = ReportData(record, study, problem, detail.evaluation, detail=detail)
        return render_report(data), detail

    study = validate_study({**raw, "duty_cycle": [{"fraction": 0.5, "cycles": 1}]})
    text, detail = report(study)
    section = md_section(text)
    fat = durability_record(study, detail)["fatigue"]
    assert fat["life_cycles"] == detail.summary["life_cycles"]
    level = fat["levels"][0]
    row = (
        f"| 1 | {shown(level['drive_min'])} | {shown(level['drive_max'])} | "
        f"{shown(level['amplitude_MPa'])} | {shown(level['mean_MPa'])} | 1 | "
        f"{shown(level['cycles_to_failure'])} | {shown(level['damage'])} |"
    )
    assert row in section
    assert f"| life, cycles | {shown(fat['life_cycles'])} |" in section
    # the stress figure the life used: the beam's peak scaled to the figure the verdict judges
    # (the larger of plane stress and the beam at the pads, docs/constant_force.md)
    assert fat["stress_model"] == CHECKED_PEAK_MODEL
    figure = f"| stress figure | {CHECKED_PEAK_MODEL}: {CHECKED_PEAK_MODEL} ({CHECKED_PEAK}"
    assert figure in section
    plain, _ = report(validate_study(raw))
    assert "## Durability" not in plain


def test_a_run_writes_best_json_durability_as_report_md(tmp_path):
    """flexopt run: best.json's durability, BestDesign.durability, report.md and report.html
    tell the same record (a quick leaf-spring run; its level's 10 deg lie beyond the 5 deg the
    design is traced to, so the record says why the life is not computed)."""
    raw = yaml.safe_load((EXAMPLES / "leaf-spring-joint.yaml").read_text("utf-8"))
    raw["duty_cycle"] = [{"drive": 10.0, "cycles": 1}]
    raw["optimiser"] = {**raw.get("optimiser", {}), "pop_size": 4, "n_gen": 1}
    run = flexopt.run(raw, out=tmp_path / "run")
    best = json.loads((tmp_path / "run" / "best.json").read_text(encoding="utf-8"))
    assert best["durability"] == run.best.durability
    note = run.best.durability["fatigue"]["note"]
    assert "drive 10 lies beyond the traced stroke 5" in note
    assert note in md_section((tmp_path / "run" / "report.md").read_text(encoding="utf-8"))
    text = (tmp_path / "run" / "report.html").read_text(encoding="utf-8")
    assert html.escape(note, quote=True) in text and '<a href="#durability">' in text


def test_a_level_below_the_endurance_limit_reads_infinite():
    """A level that does not damage (N = inf, None in JSON) reads ``infinite``, not a dash."""
    level = {"level": 1, "drive_min": 0.0, "drive_max": 1.0, "amplitude_MPa": 1.0,
             "mean_MPa": 1.0, "cycles": 5.0, "cycles_to_failure": None, "damage": 0.0}  # fmt: skip
    record = {"fatigue": {"levels": [level], "miner_sum": 0.0, "life_cycles": None,
                          "life_hours": None, "life_infinite": True, "rate_hz": 1.0}}  # fmt: skip
    md = "\n".join(durability_markdown(record))
    assert "| 1 | 0 | 1 | 1 | 1 | 5 | infinite | 0 |" in md
    assert "| life, cycles | infinite (every level below the endurance limit) |" in md


def test_a_block_that_cannot_be_reported_says_why():
    """A record that fails is a note (the run's report goes on), not an exception."""
    study = validate_study(cantilever(duty_cycle=TWO_LEVELS))

    class Broken:  # a result whose info is not a mapping
        summary: dict = {}
        info = property(lambda self: 1 / 0)

    record = durability_record(study, Broken())
    assert record["fatigue"]["note"].startswith("not reported: ZeroDivisionError")
    assert "not reported: ZeroDivisionError" in "\n".join(durability_markdown(record))
