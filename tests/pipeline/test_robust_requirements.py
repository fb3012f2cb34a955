"""Robust requirements (``robust: {share_percent}``): the GA's constraint on fixed samples, the
verdict on fresh ones, what robustness cost.

The numbers are earned from a cantilever in closed form (tests/pipeline/flexopt_robust_toys.py):
its root stress is 6 F L / (b t^2), so a print of thickness t + dt meets ``stress <= S`` exactly
when dt >= t_nom - t with t_nom = sqrt(6 F L / (b S)), the nominal optimum of the lightest
cantilever. Holding k of the n fixed draws dt_i therefore needs t >= t_nom - (k-th largest
dt_i): the robust optimum of the GA's samples, computed here from the draws of numpy's
generator, not from the code under test. The statistics are checked against scipy's binomial
distribution.
"""

from __future__ import annotations

import json
import math

import flexopt_robust_toys as toys
import numpy as np
import pytest
from flexopt.optimise.robust_requirements import (
    RobustShareSpec,
    demonstrated_share,
    kth_constraint,
    required_count,
    scatter_draws,
    wilks_samples,
)
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.study import validate_study
from pydantic import ValidationError
from scipy.stats import binom

F_N, L_MM, B_MM, S_MPA, DT_MM = 2.0, 50.0, 6.0, 40.0, 0.1
T_NOM = math.sqrt(6 * F_N * L_MM / (B_MM * S_MPA))  # 1.5811 mm: the stress exactly S


def cantilever(robust: dict | None = None, role: str = "constraint", **geometry) -> dict:
    raw = toys.study(**geometry)
    raw["robustness"] = {"thickness_mm": DT_MM}
    item = {"name": "root stress", "quantity": "peak_stress_MPa", "max": S_MPA, "role": role}
    if robust is not None:
        item["robust"] = robust
    raw["requirements"] = [item]
    return raw


def thickness_draws(n: int, seed: int, stream: int) -> np.ndarray:
    """(n,) thickness shifts of the prints, mm: numpy's generator, as the docs state it."""
    rng = np.random.default_rng([seed, stream])
    return rng.uniform(-1.0, 1.0, size=(n, 3))[:, 1] * DT_MM


def robust_optimum(n: int, k: int, seed: int = 1) -> float:
    """The thinnest t whose k-th best print of the n fixed draws still meets the stress."""
    dt = np.sort(thickness_draws(n, seed, 0))[::-1]  # largest first
    return T_NOM - dt[k - 1]


# --------------------------------------------------------------------------------------------
# Statistics


def test_shares_demonstrated_by_n_samples_match_the_binomial():
    assert wilks_samples(95, 95) == 59 and wilks_samples(99, 95) == 299
    assert demonstrated_share(59, 59, 95) >= 95 > demonstrated_share(58, 58, 95)
    assert math.isclose(demonstrated_share(20, 20, 95), 100 * 0.05 ** (1 / 20))
    for n in (30, 100, 236):
        for k in (n - 9, n - 3, n):
            p = demonstrated_share(k, n, 95) / 100
            # the Clopper-Pearson lower bound: k or more successes at share p have probability 5 %
            assert math.isclose(binom.sf(k - 1, n, p), 0.05, rel_tol=1e-6)
        # the fewest met that demonstrate 95 %: the first k with P(X >= k; 0.95) <= 5 %
        brute = next((k for k in range(n + 1) if binom.sf(k - 1, n, 0.95) <= 0.05), n)
        assert required_count(95, 95, n) == brute
    assert required_count(95, 95, 20) == 20  # 20 of 20 demonstrate only 86.1 %: all of them


def test_kth_constraint_is_non_positive_exactly_when_k_samples_meet():
    g = np.array([0.3, -0.1, -0.2, 0.05, -0.4, np.nan])
    for k in range(1, 7):
        assert (kth_constraint(g, k) <= 0) == (k <= 3)
    with pytest.raises(Exception, match="k = 7"):
        kth_constraint(g, 7)


def test_draws_are_reproducible_and_a_longer_sample_extends_a_shorter_one():
    a = scatter_draws(10, 0.1, 0.2, 30, 7, 0)
    b = scatter_draws(10, 0.1, 0.2, 50, 7, 0)
    np.testing.assert_array_equal(a, b[:30])
    assert not np.allclose(a, scatter_draws(10, 0.1, 0.2, 30, 7, 1))  # the verdict's stream
    np.testing.assert_allclose(a[:, 1], thickness_draws(30, 7, 0) * 1.0)
    assert np.all(np.abs(a[:, 0] - 1) <= 0.1) and np.all(np.abs(a[:, 2]) <= 0.2)


def test_spec_defaults_and_refusals():
    spec = RobustShareSpec()
    assert (spec.n_optimiser, spec.k_optimiser, spec.n_verdict) == (59, 59, 590)
    with pytest.raises(ValidationError, match="cannot demonstrate 95 %"):
        RobustShareSpec(verdict_samples=30)
    with pytest.raises(ValidationError, match="extra"):
        RobustShareSpec(share=95)


def test_a_robust_requirement_needs_the_scatter_and_refuses_worst():
    raw = cantilever({"share_percent": 90})
    raw.pop("robustness")
    with pytest.raises(StudyError) as err:
        validate_study(raw)
    assert err.value.path == "requirements[0].robust" and "robustness:" in err.value.problem
    raw = cantilever({"share_percent": 90})
    raw["robustness"]["objective"] = "worst"
    with pytest.raises(StudyError, match="objective: worst"):
        validate_study(raw)


def test_an_item_without_robust_dumps_as_before():
    study = validate_study(cantilever())
    assert "robust" not in study.model_dump(mode="json")["requirements"][0]
    study = validate_study(cantilever({"share_percent": 90}))
    assert study.model_dump(mode="json")["requirements"][0]["robust"]["share_percent"] == 90


# --------------------------------------------------------------------------------------------
# The optimiser's constraint


def test_the_constraint_changes_sign_at_the_robust_optimum_of_the_fixed_draws():
    from flexopt.pipeline.run import build_problem

    n = 40
    problem = build_problem(validate_study(cantilever({"share_percent": 90, "samples": n})))
    assert problem.constraint_names == ("req_root stress", "robust_root stress")
    k = problem.items[0][1].k_optimiser
    assert k == next(k for k in range(n + 1) if binom.sf(k - 1, n, 0.90) <= 0.05 or k == n)
    t_star = robust_optimum(n, k)
    assert T_NOM < t_star < T_NOM + DT_MM
    above = problem.evaluate(np.array([t_star + 1e-7]))
    below = problem.evaluate(np.array([t_star - 1e-7]))
    assert above.g[1] <= 0 < below.g[1]
    # the nominal row is the nominal design's: met on both sides of t*
    assert above.g[0] < 0 and below.g[0] < 0
    assert above.metrics["robust_root stress_share_percent"] >= 100 * k / n
    # the same design scores the same: common random numbers
    assert problem.evaluate(np.array([t_star - 1e-7])).g[1] == below.g[1]


def test_samples_that_fail_count_as_failing_with_the_reason():
    from flexopt.pipeline.run import build_problem

    # prints thinner than 1.95 mm cannot be solved: a 2.0 mm design loses the thin half of
    # its prints whatever their stress
    raw = cantilever({"share_percent": 90, "samples": 40}, fail_below_mm=1.95)
    problem = build_problem(validate_study(raw))
    ev = problem.evaluate(np.array([2.0]))
    dt = thickness_draws(40, 1, 0)
    n_fail = int(np.sum(2.0 + dt < 1.95))
    assert n_fail > 4
    assert ev.metrics["robust_failed_samples"] == n_fail
    failure = ev.metrics["robust_failure"]
    assert "SolverError" in failure and failure.startswith("sample ")
    assert ev.g[1] > 0  # more than k of n fail: the robust row is violated
    assert math.isclose(ev.metrics["robust_root stress_share_percent"], 100 * (40 - n_fail) / 40)


# --------------------------------------------------------------------------------------------
# The run: the GA holds it, the verdict judges fresh samples, the report says what it cost


@pytest.mark.e2e
def test_run_finds_the_robust_optimum_and_judges_it_on_fresh_samples(tmp_path, capsys):
    robust = {"share_percent": 90, "samples": 40, "verdict_samples": 400}
    raw = cantilever(robust)
    raw["optimiser"] = {"pop_size": 12, "n_gen": 15, "seed": 3}
    path = tmp_path / "toy.json"
    path.write_text(json.dumps(raw))
    out = tmp_path / "run"
    # two workers: the pools of the chosen design and of the nominal optimum are two pools
    assert main(["run", str(path), "--out", str(out), "--workers", "2"]) == 0
    best = json.loads((out / "best.json").read_text())
    t = best["parameters"]["thickness_mm"]
    t_star = robust_optimum(40, 40)
    assert t_star - 1e-9 <= t <= t_star + 0.02  # feasible, and near the robust optimum

    rows = {r["name"]: r for r in best["verdict"]["requirements"]}
    row = rows["root stress (robust)"]
    record = best["robustness"]["robust_requirements"]["requirements"][0]
    # the fresh samples, counted here from numpy's generator (stream 1)
    met = int(np.sum(t + thickness_draws(400, 1, 1) >= T_NOM))
    assert record["met_samples"] == met and record["verdict_samples"] == 400
    shown = demonstrated_share(met, 400, 95)
    assert math.isclose(row["value"], shown) and row["met"] == (shown >= 90)
    assert record["optimiser"] == {
        "samples": 40, "required": 40, "demonstrates_percent": pytest.approx(100 * 0.05**(1/40))
    }  # fmt: skip

    # what robustness cost: the nominal optimum of this run is thinner and fails the share
    cost = best["robustness"]["robust_requirements"]["cost"]
    nominal = cost["nominal_optimum"]
    t_nominal = nominal["parameters"]["thickness_mm"]
    assert T_NOM - 1e-9 <= t_nominal < t and not cost["same_design"] and cost["robust_feasible"]
    ratio = cost["robust_optimum"]["metrics"]["mass_g"] / nominal["metrics"]["mass_g"]
    assert math.isclose(ratio, t / t_nominal, rel_tol=1e-9)
    assert nominal["robust"][0]["met_samples"] == int(
        np.sum(t_nominal + thickness_draws(400, 1, 1) >= T_NOM)
    )
    report = (out / "report.md").read_text()
    assert "### Robust requirements" in report and "### What robustness cost" in report
    assert "mass_g" in report
    html = (out / "report.html").read_text()
    assert "What robustness cost" in html
    run = json.loads((out / "run.json").read_text())
    assert run["robustness"]["robust_requirements"]["requirements"][0]["met_samples"] == met
    assert "root stress (robust)" in capsys.readouterr().out


def test_evaluate_judges_the_robust_requirement_on_the_design(tmp_path):
    from flexopt.pipeline.evaluate import evaluate_study

    # the study's 2.0 mm design: every print from 1.9 mm up holds 40 MPa (t_nom 1.58 mm)
    study = validate_study(cantilever({"share_percent": 95}, role="check"))
    outcome = evaluate_study(study, out=tmp_path / "ev")
    rows = {r["name"]: r for r in outcome.record["verdict"]["requirements"]}
    row = rows["root stress (robust)"]
    assert row["verdict"] == "MET" and math.isclose(row["value"], demonstrated_share(590, 590, 95))
    assert "590 of 590 fresh samples met" in row["detail"]
    record = outcome.record["robustness"]["robust_requirements"]["requirements"][0]
    assert record["optimiser"] is None  # role: check: the GA does not hold it


def test_a_run_without_a_robust_design_says_there_is_no_robust_optimum():
    from flexopt.pipeline.robustness import robust_tables

    figures = {"parameters": {"thickness_mm": 1.6}, "objectives": {"mass_g": 0.5}, "metrics": {}}
    record = {
        "robust_requirements": {
            "requirements": [],
            "cost": {
                "robust_optimum": figures,
                "nominal_optimum": figures,
                "same_design": True,
                "robust_feasible": False,
            },
        }
    }
    (_, _, _, note), (title, _, rows, what) = robust_tables(record)
    assert title == "What robustness cost" and rows == [["mass_g", "0.5", "0.5", "+0 (+0.0 %)"]]
    assert "least infeasible, not a robust optimum" in what and "cost nothing" not in what


def test_robust_evaluations_round_trip_through_the_runs_store(tmp_path):
    """What resume restores is what the GA saw: the robust rows and their metrics, exactly."""
    from flexopt.pipeline.checkpoint import EvaluationStore
    from flexopt.pipeline.run import prepare_run

    raw = cantilever({"share_percent": 90, "samples": 40}, fail_below_mm=1.95)
    setup = prepare_run(validate_study(raw))
    evaluations = [setup.problem.evaluate(np.array([t])) for t in (1.7, 2.0, 2.4)]
    assert evaluations[1].metrics["robust_failure"]  # a failed sample, named
    store = EvaluationStore(tmp_path / "evaluations.jsonl")
    for ev in evaluations:
        store.append(ev)
    store.close()
    for a, b in zip(evaluations, store.load(), strict=True):
        assert a.g.tobytes() == b.g.tobytes() and a.metrics == b.metrics


def test_a_print_solved_part_way_meets_nothing_with_the_reason(tmp_path):
    """A print whose solve stops part-way (#27) is judged on no rows: its stress over the rows
    it reached (half the load: half the stress) would meet the bound, the whole load's may not."""
    from flexopt.pipeline.evaluate import evaluate_study

    raw = cantilever({"share_percent": 95}, role="check", stall_below_mm=1.95)
    # the corners too: nominal 2.0 mm, prints 1.9 mm (stalls) and 2.1 mm
    study = validate_study(raw)
    outcome = evaluate_study(study, out=tmp_path / "ev")
    rows = {r["name"]: r for r in outcome.record["verdict"]["requirements"]}
    row = rows["root stress (robust)"]
    # the fresh prints that stall, counted here from numpy's generator (stream 1)
    n_stall = int(np.sum(2.0 + thickness_draws(590, 1, 1) < 1.95))
    assert 100 < n_stall < 200  # about a quarter of the prints
    record = outcome.record["robustness"]["robust_requirements"]["requirements"][0]
    assert record["met_samples"] == 590 - n_stall and record["n_failed"] == n_stall
    assert "not solved through its stroke (no convergence at row 3)" in record["failure"]
    assert row["verdict"] == "NOT MET"
    assert math.isclose(row["value"], demonstrated_share(590 - n_stall, 590, 95))
    assert f"{n_stall} sample(s) failed" in row["detail"]
    assert record["worst_margin"] is None  # a stalled print has no margin over its stroke

    # the corner samples: the thin corner meets nothing, named with the reason
    corners = outcome.record["robustness"]
    thin = next(s for s in corners["samples"] if s["thickness_delta_mm"] < 0)
    assert thin["met"] == 0 and thin["reason"].startswith("not solved through its stroke")
    req = corners["requirements"][0]
    assert math.isclose(req["share_percent"], 100 * 2 / 3) and not req["met_robustly"]
    assert corners["n_failed"] == 1


def test_a_sample_of_a_sea_spring_is_not_judged_on_the_3d_row_its_sampler_switched_off():
    """The sampler turns the SEA spring's 3D check off in every sample (SAMPLE_SWITCHES); the
    "checked in 3D" row that a 3D-off study gets (NOT MET whatever the design) is left out of a
    sample's requirements, and nothing else is."""
    from flexopt.pipeline.robustness import CHECKED_3D, sample_requirements
    from flexopt.pipeline.study import load_study
    from flexopt.pipeline.verdict import study_requirements

    study = load_study("sea-spring-quick")  # its 3D check is off: the row is there
    full = study_requirements(study)
    assert any(getattr(r, "quantity", None) == CHECKED_3D for r in full)
    kept = sample_requirements(study)
    assert [r for r in full if getattr(r, "quantity", None) != CHECKED_3D] == kept
    assert len(kept) == len(full) - 1
