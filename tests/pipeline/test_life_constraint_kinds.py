"""The fatigue life as an optimisation constraint in every kind with a design problem: the
generic way of pipeline.verdict.LifeConstraints (the life of each design from its detail, on
the best stress figure the design has), kind by kind against a hand-computed Basquin life.

Every expected life is computed here by hand: the polymers' Basquin line through the static
strength at N = 1 and S(10^6) (fea/materials.py FATIGUE_DATA: 0.25 x static for ABS/PLA/PETG,
15 MPa for PA12), N = (S / a)^(1/b) with a = static strength, b = log10(S(10^6)/static)/6, and
Goodman's mean-stress correction S_ar = S_a / (1 - S_m / S_ut) with S_ut = the static
strength; one one-sided level 0 -> stroke (amplitude = mean = half the peak at the stroke).
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
from flexopt.pipeline.studies._constant_force_clamp import CHECKED_PEAK
from flexopt.pipeline.study import validate_study
from flexopt.pipeline.verdict import result_values, with_requirement_constraints

ROOT = Path(__file__).resolve().parents[2]
N_REQUIRED = 1.0e5
ONE_SIDED = {"rate_hz": 1.0, "levels": [{"fraction": 1.0, "cycles": 1}]}
#: (static strength MPa, S(10^6) MPa) of the polymers, by hand from fea/materials.py's sources
POLYMERS = {"ABS": (42.5, 0.25 * 42.5), "PETG": (50.0, 0.25 * 50.0), "PA12": (48.0, 15.0)}


def polymer_cycles(material: str, peak_MPa: float) -> float:
    """Hand Basquin + Goodman life of one cycle 0 -> peak_MPa (one-sided)."""
    static, s6 = POLYMERS[material]
    b = math.log10(s6 / static) / 6.0
    amp = mean = 0.5 * peak_MPa
    s_ar = amp / (1.0 - mean / static)
    return (s_ar / static) ** (1.0 / b)


def example(name: str, **extra) -> dict:
    raw = yaml.safe_load((ROOT / f"pipeline/examples/{name}.yaml").read_text("utf-8"))
    raw.update(copy.deepcopy(extra))
    return raw


def with_life(
    raw: dict, role: str = "constraint", n_required: float = N_REQUIRED, fraction: float = 1.0
) -> dict:
    raw = copy.deepcopy(raw)
    raw["duty_cycle"] = copy.deepcopy(ONE_SIDED)
    raw["duty_cycle"]["levels"][0]["fraction"] = fraction
    raw["requirements"] = [
        *(raw.get("requirements") or []),
        {"quantity": "life_cycles", "min": n_required, "role": role, "name": "service life"},
    ]
    return raw


# -- the generic way on a one-variable toy: the optimum moves to the hand Basquin thickness ----


class DetailToy(DesignProblem):
    """A leaf of thickness h (mm) bent one way to a 10 mm stroke: root stress C h s (linear);
    the thicker the better (f = -h). No evaluate_response: its life comes from detail(), whose
    summary carries a 'plane-stress' peak K times the beam's (the best figure, judged on)."""

    C = 2.0  # MPa per mm thickness per mm stroke
    K = 1.25  # plane-stress peak over the beam's

    def __init__(self) -> None:
        self.space = DesignSpace(("h_mm",), np.array([0.2]), np.array([2.0]))
        self.objective_names = ("minus_h_mm",)
        self.constraint_names = ()
        self.details = 0

    def evaluate(self, x):
        h = float(np.asarray(x, dtype=float)[0])
        return Evaluation(np.asarray(x, dtype=float), np.array([-h]), np.zeros(0), {"h_mm": h})

    def detail(self, x):
        self.details += 1
        h = float(np.asarray(x, dtype=float)[0])
        s = np.linspace(0.0, 10.0, 6)
        table = {"displacement_mm": s, "force_N": s, "peak_stress_MPa": self.C * h * s}
        peak = float(table["peak_stress_MPa"].max())
        return DesignResult(
            evaluation=self.evaluate(x),
            table=table,
            plot={"x": "displacement_mm"},
            # what constant_force's detail carries: the plane-stress peak and the figure the
            # verdict judges, the larger of it and the beam's (K > 1: the plane-stress one)
            info={"plane_stress_peak_stress_MPa": self.K * peak, CHECKED_PEAK: self.K * peak},
        )


def toy_study(role: str = "constraint"):
    raw = with_life(example("constant-force", material="PETG"), role=role)
    raw["requirements"] = raw["requirements"][-1:]
    return validate_study(raw)


def h_star() -> float:
    """The thickness whose (plane-stress) peak at the stroke fails at N_REQUIRED, by hand: the
    one-sided Goodman-Basquin equation solved for the peak P: (P/2) / (1 - P/(2 Sut)) = S_N."""
    static, s6 = POLYMERS["PETG"]
    b = math.log10(s6 / static) / 6.0
    s_n = static * N_REQUIRED**b
    peak = 2.0 * s_n / (1.0 + s_n / static)
    return peak / (DetailToy.K * DetailToy.C * 10.0)


def test_a_problem_without_evaluate_response_gets_its_life_from_detail_on_the_best_figure():
    toy = DetailToy()
    problem = with_requirement_constraints(toy_study(), toy)
    assert problem.constraint_names[-1] == "req_service life"
    for h in (0.4, 0.6, 0.8):
        ev = problem.evaluate(np.array([h]))
        life = polymer_cycles("PETG", DetailToy.K * DetailToy.C * h * 10.0)
        assert ev.metrics["life_cycles"] == pytest.approx(life, rel=1e-10)
        assert ev.g[-1] == pytest.approx(math.log10(N_REQUIRED) - math.log10(life), abs=1e-10)
        assert ev.f[0] == -h  # the objective is the plain evaluation's
    assert problem.evaluate(np.array([h_star()])).g[-1] == pytest.approx(0.0, abs=1e-10)
    # the best design's detail carries the same life as its GA row (one figure, one number)
    d = problem.detail(np.array([0.6]))
    assert d.evaluation.metrics["life_cycles"] == pytest.approx(
        polymer_cycles("PETG", DetailToy.K * DetailToy.C * 0.6 * 10.0), rel=1e-10
    )


def test_the_generic_life_constraint_moves_the_optimum_to_the_hand_thickness():
    from flexopt.optimise.ga import GAConfig, run_ga

    def best(problem) -> float:
        n_con = len(problem.constraint_names)
        res = run_ga(
            problem.space, lambda xs: [problem.evaluate(x) for x in xs], 1, n_con,
            GAConfig(pop_size=16, n_gen=25, seed=3),
        )  # fmt: skip
        assert res.best.feasible
        return float(res.best.x[0])

    assert best(DetailToy()) == pytest.approx(2.0, rel=1e-3)  # no life: the thickest leaf
    h = h_star()
    assert 0.3 < h < 1.9  # the bound lies inside the range
    held = best(with_requirement_constraints(toy_study(), DetailToy()))
    assert 0.98 * h <= held <= h * (1 + 1e-9)


def test_a_design_the_evaluation_rejects_is_not_detailed():
    class Failing(DetailToy):
        def evaluate(self, x):
            return Evaluation.failed(np.asarray(x, dtype=float), 1, 0, "cannot build: toy")

    toy = Failing()
    problem = with_requirement_constraints(toy_study(), toy)
    ev = problem.evaluate(np.array([1.0]))
    assert ev.reason and toy.details == 0 and ev.g[-1] >= 1.0


# -- kind by kind: the row is the hand life of the design's own detail -------------------------


def kind_problems(raw: dict, fraction: float):
    """(plain problem, problem with the life constraint, the life study)."""
    from flexopt.pipeline.problems import build_base_problem

    study = validate_study(with_life(raw, fraction=fraction))
    plain = validate_study(with_life(raw, role="check", fraction=fraction))
    return build_base_problem(plain), build_base_problem(study), study


def hand_row(
    material: str, detail: DesignResult, figure: str | None, fraction: float
) -> tuple[float, float]:
    """(hand life, its g row) of one design from its detail's table: the peak at ``fraction``
    of the stroke (linear between rows), scaled by the named higher-fidelity figure over the
    table's largest peak."""
    x_col = detail.plot["x"]
    x = np.abs(np.asarray(detail.table[x_col], dtype=float))
    peak = np.abs(np.asarray(detail.table["peak_stress_MPa"], dtype=float))
    order = np.argsort(x)
    at = float(np.interp(fraction * x.max(), x[order], peak[order]))
    scale = 1.0
    if figure is not None:
        scale = float(result_values(detail)[figure]) / float(np.nanmax(peak))
    life = polymer_cycles(material, scale * at)
    assert life > 1.0e3  # inside the stress-life method's range (else the row is its cap)
    return life, math.log10(N_REQUIRED) - math.log10(life)


@pytest.mark.parametrize(
    ("name", "material", "figure", "patch", "fraction"),
    [
        ("gripper", "ABS", CHECKED_PEAK, {}, 1.0),  # constant_force family
        ("flexure-pivot", "PETG", "plane_stress_peak_stress_MPa", {}, 1.0),
        ("threshold-spring", "PA12", None, {"fidelity": {"enabled": False}}, 0.5),
        ("parallel-guide", "PA12", None, {}, 1.0),  # mechanism
    ],
)
def test_each_kind_holds_the_hand_life_of_its_design(name, material, figure, patch, fraction):
    from flexopt.pipeline.problems import nominal_design

    raw = example(name)
    for key, value in patch.items():
        raw[key] = {**(raw.get(key) or {}), **value}
    plain, problem, study = kind_problems(raw, fraction)
    x = nominal_design(problem, study)
    ev, ev0 = problem.evaluate(x), plain.evaluate(x)
    assert not ev.reason
    i = list(problem.constraint_names).index("req_service life")
    life, g = hand_row(material, plain.detail(x), figure, fraction)
    assert ev.metrics["life_cycles"] == pytest.approx(life, rel=1e-9)
    assert ev.g[i] == pytest.approx(g, abs=1e-9)
    # the objectives and the other rows are the plain run's
    np.testing.assert_array_equal(ev.f, ev0.f)
    np.testing.assert_array_equal(np.delete(ev.g, i), ev0.g)


# the leaf-spring joint gives it per stiffness setting: tests/pipeline/test_leaf_joint_life.py


@pytest.mark.parametrize("role", ["constraint", "check"])
def test_a_cam_refuses_a_duty_cycle_with_the_reason(role):
    """A cam has no stress that fatigues with data to judge it (docs/durability.md, The cam):
    the duty cycle is refused at load time, as a constraint or a check, saying what to judge."""
    with pytest.raises(StudyError, match=r"duty_cycle.*Hertz contact pressure.*pitting.*no wire"):
        validate_study(with_life(example("threshold-cam"), role=role))
