"""The closed-form constant-force estimate (fea/constant_force_estimate.py) against its own
limits and against the nonlinear beam solve of uniform beams computed here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive
from flexopt.fea.constant_force_estimate import (
    MARGINAL_RATIO,
    TAPER_GAIN,
    chord_after_stroke_mm,
    elastica_parameter,
    estimate_spec,
    peak_curvature_per_mm,
    peak_stress_MPa,
    plateau_force_N,
    strain_limited_thickness_mm,
    thickness_for_force_mm,
)
from flexopt.fea.materials import get_material
from flexopt.geometry.constant_force import (
    DESIGN_VARIABLE_NAMES,
    TABLE3_OPTIMUM,
    WORK_DIRECTION,
    PRBParams,
    beam_profile,
    design_from_vector,
    design_to_vector,
    reference_points,
)
from scipy.special import ellipk

PHI = math.atan2(60.0, 100.0)  # about the paper frame's chord angle (31 degrees)


def test_elastica_small_amplitude_limits():
    # c / L = 2E/K - 1 ~ 1 - m for small m; kappa_max ~ 4 pi sqrt(Delta / L) / L
    for ratio in (1e-4, 1e-3):
        m = elastica_parameter(1.0 - ratio)
        assert m == pytest.approx(ratio, rel=2e-3)
    L, d = 200.0, 0.05
    delta = L - chord_after_stroke_mm(L, PHI, d)
    assert delta == pytest.approx(d * math.cos(PHI), rel=1e-3)
    kappa = peak_curvature_per_mm(L, PHI, d)
    assert kappa == pytest.approx(4 * math.pi * math.sqrt(delta / L) / L, rel=2e-3)
    assert elastica_parameter(1.0) == 0.0 and peak_curvature_per_mm(L, PHI, 0.0) == 0.0
    # the axial force 16 K^2 EI / L^2 is Euler's 4 pi^2 EI / L^2 at m = 0
    assert 16 * float(ellipk(0.0)) ** 2 == pytest.approx(4 * math.pi**2)
    assert TAPER_GAIN == pytest.approx(0.7797, abs=1e-4)


def test_inverse_figures_are_consistent():
    E, allow, b, tmin = 1500.0, 50.0, 10.0, 0.8
    L, F, d = 110.0, 5.0, 15.0
    t = thickness_for_force_mm(F, E, b, L, PHI)
    assert plateau_force_N(E, b, t, L, PHI) == pytest.approx(F, rel=1e-12)
    ts = strain_limited_thickness_mm(E, allow, L, PHI, d)
    assert peak_stress_MPa(E, ts, L, PHI, d) == pytest.approx(allow, rel=1e-12)
    est = estimate_spec(F, d, L, PHI, E, allow, b, tmin)
    assert est.status == "feasible" and est.thickness_mm == pytest.approx(t)
    assert peak_stress_MPa(E, t, L, PHI, est.max_stroke_mm) == pytest.approx(allow, rel=1e-9)
    t_min_len = max(tmin, thickness_for_force_mm(F, E, b, est.min_length_mm, PHI))
    assert peak_stress_MPa(E, t_min_len, est.min_length_mm, PHI, d) == pytest.approx(allow, 1e-6)
    assert est.max_force_N == pytest.approx(plateau_force_N(E, b, ts, L, PHI))
    assert thickness_for_force_mm(F, E, est.min_width_mm, L, PHI) == pytest.approx(ts)


def test_status_thresholds():
    E, allow, b, tmin, L = 1800.0, 42.5, 12.0, 0.8, 127.4
    assert estimate_spec(1.5, 30, L, PHI, E, allow, b, tmin).status == "feasible"
    # raise the force until the sized section's stress passes 0.9 and then 1/0.78 of the allowable
    marginal = estimate_spec(6.0, 30, L, PHI, E, allow, b, tmin)
    assert MARGINAL_RATIO < marginal.stress_ratio <= 1 / TAPER_GAIN
    assert marginal.status == "marginal" and marginal.limit == "force"
    too_much = estimate_spec(40.0, 30, L, PHI, E, allow, b, tmin)
    assert too_much.status == "infeasible" and too_much.limit == "force"
    assert too_much.max_force_N < 6.0 and too_much.min_length_mm > L
    # a stroke that breaks even the thinnest printable section, whatever the force
    stroke = estimate_spec(0.5, 60, 100.0, PHI, E, allow, b, tmin)
    assert stroke.status == "infeasible" and stroke.limit == "stroke"
    assert stroke.max_force_N is None and stroke.max_thickness_mm < tmin
    tiny = estimate_spec(0.01, 10, 300.0, PHI, E, allow, b, tmin)
    assert tiny.status == "infeasible" and tiny.limit == "small_force"


def _uniform(scale: float, t: float, B: float):
    prb = PRBParams(54 * scale, 0.542, 1, 1, 1, 100 * scale, 60 * scale)
    x = design_to_vector(TABLE3_OPTIMUM)
    for i, name in enumerate(DESIGN_VARIABLE_NAMES):
        x[i] = B if name == "B" else (t if name[0] in "tT" else x[i])
    s = reference_points(prb)
    chord = s[-1] - s[0]
    return (
        beam_profile(design_from_vector(x), prb),
        float(np.hypot(*chord)),
        float(math.atan2(chord[1], chord[0])),
    )


@pytest.mark.parametrize(
    ("scale", "material", "t", "B", "stroke"),
    [(1.0, "ABS", 0.8, 9.35, 30.0), (0.65, "PETG", 0.96, 10.0, 15.0), (1.5, "ABS", 1.2, 5, 40)],
)
def test_estimate_against_the_nonlinear_beam_solve(scale, material, t, B, stroke):
    """A uniform beam in the paper's frame scaled by ``scale``: the estimate's peak stress at the
    stroke and plateau force against fea.beam's (60 elements, the study's defaults)."""
    profile, L, phi = _uniform(scale, t, B)
    mat = get_material(material)
    drive = EndDrive("displacement", WORK_DIRECTION, stroke, 30, "fixed", "fixed")
    r = BeamModel(profile, mat, "clamped", BeamSettings(n_elements=60)).solve(drive)
    assert r.ok
    force = np.asarray(r.force_N)[1:]
    sigma = float(np.max(r.peak_stress_MPa))
    est_sigma = peak_stress_MPa(mat.E_MPa, t, L, phi, stroke)
    est_force = plateau_force_N(mat.E_MPa, B, t, L, phi)
    assert est_sigma == pytest.approx(sigma, rel=0.03)
    assert est_sigma < sigma  # ~1 % low: axial stress and the chord's turn are left out
    assert abs(force / est_force - 1).max() < 0.03
    assert float(np.mean(force)) == pytest.approx(est_force, rel=0.015)
