"""The fatigue life as an optimisation constraint (pipeline.verdict.LifeConstraints) and the
life judged on the best stress figure a design has (pipeline.verdict.life_of_result).

Every expected life is computed by hand in the test: Shigley's S-N line of maraging 300
(machined) from its static strength, and Basquin's law N = (S / a)^(1/b) at the amplitude of
the level (a reversed level: the amplitude is the peak, the mean 0).
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import DesignProblem, DesignResult
from flexopt.optimise.space import DesignSpace
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.study import validate_study
from flexopt.pipeline.verdict import life_of_result, with_requirement_constraints

ROOT = Path(__file__).resolve().parents[2]
SUT = 2050.0  # maraging 300, MPa (fea/materials.py)


def maraging_machined() -> tuple[float, float, float]:
    """(a MPa, b, endurance limit MPa) of maraging 300, machined, by Shigley's rule
    (docs/durability.md)."""
    se_prime = 700.0  # Sut > 1400 MPa
    ka = 4.51 * SUT**-0.265
    se = ka * se_prime
    sigma_f = SUT + 345.0
    b_e = -math.log10(sigma_f / se_prime) / math.log10(2.0e6)
    f = sigma_f / SUT * (2.0e3) ** b_e
    return (f * SUT) ** 2 / se, -math.log10(f * SUT / se) / 3.0, se


def cycles(amplitude: float, mean: float = 0.0) -> float:
    """Basquin with Goodman (a tensile mean), by hand; infinite at or below the endurance
    limit."""
    a, b, se = maraging_machined()
    s_ar = amplitude / (1.0 - mean / SUT) if mean > 0 else amplitude
    return math.inf if s_ar <= se else (s_ar / a) ** (1.0 / b)


def sea_quick(**extra) -> dict:
    raw = yaml.safe_load((ROOT / "pipeline/examples/sea-spring-quick.yaml").read_text("utf-8"))
    raw.update(copy.deepcopy(extra))
    return raw


REVERSED = {"rate_hz": 1.0, "levels": [{"fraction": 1.0, "reversed": True, "cycles": 1}]}
N_REQUIRED = 1.0e5


def life_study(n_required: float = N_REQUIRED, role: str = "constraint"):
    return validate_study(
        sea_quick(
            duty_cycle=REVERSED,
            requirements=[
                {"quantity": "life_cycles", "min": n_required, "role": role, "name": "service life"}
            ],
        )  # fmt: skip
    )


class LeafToy(DesignProblem):
    """A 1-variable stand-in: a leaf of thickness h (mm) turned by up to 11.04 degrees, its
    root stress C h theta (linear, displacement-controlled); the stiffer (thicker) the better
    (f = -h). Its response table is the life constraint's input."""

    C = 1200.0 / (3.0 * 11.04)  # MPa per mm per degree: 1200 MPa at h = 3 mm, 11.04 deg

    def __init__(self) -> None:
        self.space = DesignSpace(("h_mm",), np.array([0.5]), np.array([3.0]))
        self.objective_names = ("minus_h_mm",)
        self.constraint_names = ()

    def table(self, h: float) -> dict[str, np.ndarray]:
        rot = np.array([-11.04, -5.52, 0.0, 5.52, 11.04])
        return {"rotation_deg": rot, "peak_stress_MPa": self.C * h * np.abs(rot)}

    def evaluate_response(self, x):
        h = float(np.asarray(x, dtype=float)[0])
        ev = Evaluation(np.asarray(x, dtype=float), np.array([-h]), np.zeros(0), {"h_mm": h})
        return ev, self.table(h), "rotation_deg"

    def evaluate(self, x):
        return self.evaluate_response(x)[0]


def h_star(n_required: float = N_REQUIRED) -> float:
    """The thickness whose reversed peak fails at ``n_required`` cycles, by hand."""
    a, b, _ = maraging_machined()
    return a * n_required**b / (LeafToy.C * 11.04)


def test_the_g_row_is_log10_of_the_hand_basquin_life_against_its_bound():
    problem = with_requirement_constraints(life_study(), LeafToy())
    assert problem.constraint_names[-1] == "req_service life"
    for h in (1.5, 2.0, 2.5):
        ev = problem.evaluate(np.array([h]))
        life = cycles(LeafToy.C * h * 11.04)
        assert ev.metrics["life_cycles"] == pytest.approx(life, rel=1e-12)
        assert ev.g[-1] == pytest.approx(math.log10(N_REQUIRED) - math.log10(life), abs=1e-12)
        assert (ev.g[-1] <= 0.0) == (life >= N_REQUIRED)
    below = problem.evaluate(np.array([1.0]))  # 400 MPa: under the endurance limit
    assert cycles(LeafToy.C * 1.0 * 11.04) == math.inf
    assert below.metrics["life_cycles"] is None and below.g[-1] == -100.0
    assert problem.evaluate(np.array([h_star()])).g[-1] == pytest.approx(0.0, abs=1e-12)


def test_the_constraint_moves_the_optimum_to_the_hand_basquin_thickness():
    from flexopt.optimise.ga import GAConfig, run_ga

    def best(problem) -> float:
        n_con = len(problem.constraint_names)
        res = run_ga(
            problem.space, lambda xs: [problem.evaluate(x) for x in xs], 1, n_con,
            GAConfig(pop_size=16, n_gen=25, seed=3),
        )  # fmt: skip
        assert res.best.feasible
        return float(res.best.x[0])

    free = best(LeafToy())
    held = best(with_requirement_constraints(life_study(), LeafToy()))
    assert free == pytest.approx(3.0, rel=1e-3)  # no life: the thickest leaf
    assert h_star() == pytest.approx(1.51, abs=0.01)  # the bound lies inside the range
    assert 0.98 * h_star() <= held <= h_star() * (1 + 1e-12)


def test_a_problem_that_names_why_it_has_no_life_refuses_the_life_constraint():
    class NoLife(LeafToy):
        life_refusal = "its response has no stress per row (a toy)"

    with pytest.raises(StudyError, match=r"cannot give the life of every design: its response"):
        with_requirement_constraints(life_study(), NoLife())


def test_a_cam_refuses_the_duty_cycle_as_a_constraint_and_as_a_check():
    """The cam has no stress that fatigues with sourced data (docs/durability.md, The cam)."""
    raw = yaml.safe_load((ROOT / "pipeline/examples/threshold-cam.yaml").read_text("utf-8"))
    raw["duty_cycle"] = [{"fraction": 1.0, "cycles": 1}]
    raw["requirements"] = [{"quantity": "life_cycles", "min": 1e5, "role": "constraint"}]
    with pytest.raises(StudyError, match=r"duty_cycle.*Hertz contact pressure"):
        validate_study(raw)
    raw["requirements"][0]["role"] = "check"
    with pytest.raises(StudyError, match=r"duty_cycle.*Hertz contact pressure"):
        validate_study(raw)


def test_the_sea_spring_problem_holds_the_life_of_each_design():
    from flexopt.pipeline.problems import build_base_problem, nominal_design

    study = life_study()
    problem = build_base_problem(study)
    x = nominal_design(problem, study)
    ev, table, x_col = problem.evaluate_response(x)
    assert x_col == "rotation_deg" and not ev.reason
    rot, peak = table["rotation_deg"], np.abs(table["peak_stress_MPa"])
    s_hi, s_lo = float(peak[np.argmax(rot)]), -float(peak[np.argmin(rot)])
    amp, mean = 0.5 * (s_hi - s_lo), 0.5 * (s_hi + s_lo)
    life = cycles(amp, mean)
    assert ev.metrics["life_cycles"] == pytest.approx(life, rel=1e-9)
    assert ev.g[-1] == pytest.approx(math.log10(N_REQUIRED) - math.log10(life), abs=1e-9)
    assert problem.evaluate(x).g[-1] == ev.g[-1]  # evaluate is the same solve's row


def test_the_life_is_judged_on_the_3d_peak_where_the_design_has_one():
    study = life_study(role="check")
    rot = np.array([-11.04, 0.0, 11.04])
    table = {"rotation_deg": rot, "torque_Nm": rot, "peak_stress_MPa": np.array([740, 0, 743.0])}
    plane = DesignResult(table=table, plot={"x": "rotation_deg"}, summary={})
    solid = DesignResult(
        table=table, plot={"x": "rotation_deg"}, summary={"peak_stress_3d_MPa": 790.0}
    )
    life2d, life3d = life_of_result(study, plane), life_of_result(study, solid)
    assert life2d.scale == 1.0 and "3D" not in life2d.summary()["life_stress_figure"]
    scale = 790.0 / 743.0
    assert life3d.scale == pytest.approx(scale, rel=1e-12)
    assert "3D solid" in life3d.summary()["life_stress_figure"]
    amp, mean = 0.5 * scale * (743.0 + 740.0), 0.5 * scale * (743.0 - 740.0)
    assert life3d.life_cycles == pytest.approx(cycles(amp, mean), rel=1e-12)
