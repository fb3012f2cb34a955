"""Head impact model of paper 000 (Fig. 14): HIC against exact values, the integrator against the
exact linear solution, and the paper's comparison (regression numbers, see docs)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from flexopt.fea.collision import (
    G_M_PER_S2,
    CollisionModel,
    CollisionSettings,
    LinearSpring,
    TabulatedSpring,
    ThresholdSpring,
    cam_impact_check,
    equivalent_linear_spring,
    hic,
    initial_deflection_rad,
    metrics_until,
    score_spring_curve,
    simulate_cases,
    simulate_collision,
    simulate_collisions,
    sweep,
    sweep_record,
    sweep_result,
)
from flexopt.fea.errors import FeaError
from scipy.linalg import expm
from scipy.optimize import minimize_scalar

V2SOM = ThresholdSpring(max_torque_Nm=15.0, rate_per_rad=37.0)  # (Tmax, T1) = (15, 12) N·m
CS = equivalent_linear_spring(V2SOM, 12.0)


def half_sine_hic(amplitude_g: float, duration_s: float, limit_s: float = 0.015) -> float:
    """HIC of ``A sin(π t / T)`` from the closed-form integral over a centred window of width w:
    ``∫ = (2 A T / π) sin(π w / (2 T))``, maximised over ``0 < w <= min(T, limit)``."""

    def minus_hic(w: float) -> float:
        mean = (
            2 * amplitude_g * duration_s / (math.pi * w) * math.sin(math.pi * w / (2 * duration_s))
        )
        return -(mean**2.5) * w

    top = min(duration_s, limit_s)
    res = minimize_scalar(
        minus_hic, bounds=(1e-6 * top, top), method="bounded", options={"xatol": 1e-12}
    )
    return max(-res.fun, -minus_hic(top))


@pytest.mark.parametrize("duration_ms", [6.0, 10.0, 30.0])
def test_hic_of_a_half_sine_pulse(duration_ms):
    amplitude, duration = 60.0, duration_ms / 1000.0
    t = np.arange(0.0, 0.05, 1e-5)
    a = np.where(t <= duration, amplitude * np.sin(np.pi * np.minimum(t, duration) / duration), 0.0)
    result = hic(t, np.maximum(a, 0.0))
    assert result.hic == pytest.approx(half_sine_hic(amplitude, duration), rel=2e-4)
    assert 0.5 * (result.t1_s + result.t2_s) == pytest.approx(duration / 2, abs=2e-5)  # centred
    assert result.t2_s - result.t1_s <= 0.015 + 1e-12


def test_hic_of_a_constant_plateau_uses_the_whole_window():
    t = np.linspace(0.0, 0.1, 1001)
    result = hic(t, np.full(t.size, 40.0))
    assert result.hic == pytest.approx(40.0**2.5 * 0.015, rel=1e-12)
    with pytest.raises(FeaError, match="magnitudes"):
        hic(t, -np.ones(t.size))


def linear_solution(model: CollisionModel, stiffness: float, times: np.ndarray) -> np.ndarray:
    """Exact state of the impact with a linear spring while the contact pushes (expm)."""
    m, l = model, model.arm_length_m
    kc, dc, kn, dn = (
        m.contact_stiffness_N_per_m,
        m.contact_damping_N_s_per_m,
        m.neck_stiffness_N_per_m,
        m.neck_damping_N_s_per_m,
    )
    ir, ia, mh = m.rotor_inertia_kg_m2, m.arm_inertia_kg_m2, m.head_mass_kg
    a = np.zeros((7, 7))  # θ1, θ2, x, ω1, ω2, v, 1 (for the constant rotor torque)
    a[0, 3] = a[1, 4] = a[2, 5] = 1.0
    a[3, [0, 1, 6]] = [-stiffness / ir, stiffness / ir, m.rotor_torque_Nm / ir]
    a[4, [0, 1, 2, 4, 5]] = [
        stiffness / ia,
        (-stiffness - l * kc * l) / ia,
        l * kc / ia,
        -l * dc * l / ia,
        l * dc / ia,
    ]
    a[5, [1, 2, 4, 5]] = [kc * l / mh, (-kc - kn) / mh, dc * l / mh, (-dc - dn) / mh]
    y = np.array([0.0, 0.0, 0.0, m.speed_rad_per_s, m.speed_rad_per_s, 0.0, 1.0])
    step = expm(a * (times[1] - times[0]))  # a uniform grid from 0: powers of one exponential
    out = [y]
    for _ in times[1:]:
        y = step @ y
        out.append(y)
    return np.array(out)


def test_integrator_matches_the_exact_linear_solution_during_contact():
    model = CollisionModel()
    response = simulate_collision(CS, model, CollisionSettings(duration_s=0.03))
    keep = response.time_s <= 0.03
    exact = linear_solution(model, CS.stiffness_Nm_per_rad, response.time_s[keep])
    l = model.arm_length_m
    force = model.contact_stiffness_N_per_m * (l * exact[:, 1] - exact[:, 2]) + (
        model.contact_damping_N_s_per_m * (l * exact[:, 4] - exact[:, 5])
    )
    assert np.all(force > 0)  # the contact pushes all along: the model is linear there
    np.testing.assert_allclose(response.contact_force_N[keep], force, rtol=1e-8)
    np.testing.assert_allclose(response.head_position_m[keep], exact[:, 2], rtol=1e-7, atol=1e-13)


def test_halving_the_step_changes_hic_and_force_by_little():
    coarse = simulate_collision(V2SOM, settings=CollisionSettings(duration_s=0.1))
    fine = simulate_collision(V2SOM, settings=CollisionSettings(dt_s=1e-4, duration_s=0.1))
    assert coarse.hic15 == pytest.approx(fine.hic15, rel=1e-4)
    assert coarse.peak_force_N == pytest.approx(fine.peak_force_N, rel=1e-6)


def test_equal_deflection_reference_and_initial_conditions():
    assert CS.stiffness_Nm_per_rad == pytest.approx(12.0 * 37.0 / math.log(5), rel=1e-12)
    held = CollisionModel(rotor_torque_Nm=7.5, initial_spring="held")
    assert float(V2SOM(initial_deflection_rad(V2SOM, held))) == pytest.approx(7.5)
    acc = CollisionModel(initial_spring="accelerating")
    share = 15.0 * 0.14 / (0.14 + 0.175)
    assert float(CS(initial_deflection_rad(CS, acc))) == pytest.approx(share)
    with pytest.raises(FeaError, match="never reaches 15"):
        initial_deflection_rad(V2SOM, CollisionModel(initial_spring="held"))


def test_paper_comparison_at_the_nominal_point():
    """Regression numbers of docs/threshold_torque.md (unloaded spring, I_r = 0.175, τ = 15)."""
    mine, ref = simulate_collision(V2SOM), simulate_collision(CS)
    assert 1 - mine.hic15 / ref.hic15 == pytest.approx(0.908, abs=2e-3)  # paper: > 80 %
    assert 1 - mine.peak_force_N / ref.peak_force_N == pytest.approx(0.442, abs=2e-3)
    # ... but over the first 50 ms (the first impact) HIC is the same within 10 %
    early = metrics_until(mine, 0.05)[0] / metrics_until(ref, 0.05)[0]
    assert early == pytest.approx(1.08, abs=0.01)
    assert ref.hic_window_s[0] > 0.2  # the CS HIC comes from the late rebound


def test_sweep_batches_and_marks_impossible_starts():
    held = CollisionModel(initial_spring="held")
    result = sweep(V2SOM, CS, "rotor_torque_Nm", [7.5, 20.0], held)
    assert np.isfinite(result.hic15["spring"][0]) and np.isnan(result.hic15["spring"][1])
    assert np.all(np.isfinite(result.hic15["reference"]))
    batch = simulate_collisions(V2SOM, rotor_inertia_kg_m2=[0.1, 0.5])
    single = simulate_collision(V2SOM, CollisionModel(rotor_inertia_kg_m2=0.5))
    assert batch[1].hic15 == pytest.approx(single.hic15, rel=1e-12)


def test_score_spring_curve_hook_on_a_tabulated_threshold():
    theta = np.linspace(0.0, 2.5, 2001)
    quick = CollisionSettings(duration_s=0.1)
    score = score_spring_curve(theta, V2SOM(theta), settings=quick)
    direct = simulate_collision(V2SOM, settings=quick)
    assert score.hic15 == pytest.approx(direct.hic15, rel=2e-3)
    assert score.reference_stiffness_Nm_per_rad == pytest.approx(CS.stiffness_Nm_per_rad, rel=1e-3)
    assert not score.beyond_table
    short = score_spring_curve(theta[:200], V2SOM(theta[:200]), settings=quick)
    assert short.beyond_table
    spring = TabulatedSpring.from_Nmm([0.0, 0.1], [0.0, 5000.0])
    assert float(spring(np.array(-0.05))) == pytest.approx(-2.5)
    with pytest.raises(FeaError, match="start at"):
        TabulatedSpring(np.array([0.1, 0.2]), np.array([1.0, 2.0]))
    with pytest.raises(FeaError, match="falls"):
        TabulatedSpring(np.array([0.0, 0.1, 0.2]), np.array([0.0, 2.0, 1.0]))
    assert LinearSpring(10.0).deflection_at(5.0) == 0.5
    assert G_M_PER_S2 == 9.80665


def test_sweep_record_lists_full_and_early_measures_per_spring():
    quick = CollisionSettings(duration_s=0.1)
    model = CollisionModel()
    inertia = np.array([0.1, 0.3])
    runs = {
        label: simulate_cases(sp, model, inertia, model.rotor_torque_Nm, quick)
        for label, sp in (("spring", V2SOM), ("reference", CS))
    }
    result = sweep_result("rotor_inertia_kg_m2", inertia, runs)
    rec = sweep_record(result, runs, 0.05)
    assert rec["parameter"] == "rotor_inertia_kg_m2" and rec["values"] == [0.1, 0.3]
    assert rec["early_window_ms"] == pytest.approx(50.0)
    for label in ("spring", "reference"):
        r = runs[label][1]
        assert rec["hic15"][label][1] == r.hic15
        assert rec["max_deflection_deg"][label][1] == pytest.approx(
            math.degrees(r.max_deflection_rad)
        )
        assert (rec["early_hic15"][label][1], rec["early_peak_force_N"][label][1]) == (
            metrics_until(r, 0.05)
        )
    hic_s, hic_r = rec["early_hic15"]["spring"][0], rec["early_hic15"]["reference"][0]
    assert rec["early_hic_reduction"][0] == pytest.approx(1.0 - hic_s / hic_r)
    assert rec["hic_reduction"] == result.hic_reduction.tolist()


def test_cam_impact_check_range_and_pressure_within_the_reached_rotation():
    rotation = np.linspace(0.0, 1.0, 11)
    profile = SimpleNamespace(
        rotation_rad=rotation,
        torque_Nmm=2000.0 * rotation,
        max_radius_mm=20.0,
        layout=SimpleNamespace(max_rotation_rad=1.0, roller_radius_mm=3.0),
    )
    pressure = 100.0 + 10.0 * np.arange(11)
    # joint deflection 0.05 rad behind a ratio of 10: the cam turns 0.5 rad, within its range
    check = cam_impact_check(profile, 10.0, 0.05, pressure, 200.0)
    assert not check["range_exceeded"]
    assert check["max_contact_pressure_MPa"] == 150.0  # rows up to 0.5 rad
    assert check["stress_yield_ratio"] == 0.75
    assert check["cam_max_torque_Nm"] == 2.0 and check["mechanism_diameter_mm"] == 46.0
    assert check["joint_range_deg"] == pytest.approx(math.degrees(0.1))
    past = cam_impact_check(profile, 10.0, 0.2, pressure, 200.0)
    assert past["range_exceeded"] and past["max_contact_pressure_MPa"] == 200.0
