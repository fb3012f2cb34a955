"""The beam's stress from statics (fea/beam_statics.py) against closed forms, and its
convergence on the constant-force design whose clamp stress the elements' curvature missed
(docs/constant_force.md, "Stress at the clamp")."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive
from flexopt.fea.beam_statics import statics_stress
from flexopt.fea.materials import Material
from flexopt.geometry.profile import BeamProfile
from flexopt.pipeline.study import load_study
from scipy.integrate import quad

ROOT = Path(__file__).resolve().parents[2]
MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
UP = np.array([0.0, 1.0])


def _guided(profile, elements, delta, shear_factor=5.0 / 6.0):
    """Clamped at s = 0; the end pushed across by ``delta`` mm with its rotation held and free
    to move along the beam (no stretching): the clamped-guided beam."""
    settings = BeamSettings(n_elements=elements, rtol=1e-11, shear_factor=shear_factor)
    model = BeamModel(profile, MAT, "clamped", settings)
    response = model.solve(EndDrive("displacement", tuple(UP), delta, 2, "fixed", "free"))
    assert response.ok
    return model, response


def test_uniform_clamped_guided_beam_has_the_exact_m_c_over_i_at_the_clamp():
    """M(0) = F L / 2 with F = 12 EI delta / (L^3 (1 + Phi)), Phi = 12 EI / (k G A L^2) (the
    Timoshenko beam's closed form); sigma = M c / I = 6 M / (b t^2). delta / L = 2e-4: the
    geometric terms are ~(delta / L)^2, 4e-8."""
    L, t, b, delta = 50.0, 1.0, 5.0, 0.01
    profile = BeamProfile(np.array([[0.0, 0.0], [L, 0.0]]), np.array([t, t]), b)
    model, response = _guided(profile, 4, delta)
    EI = MAT.E_MPa * b * t**3 / 12.0
    phi = 12.0 * EI / (5.0 / 6.0 * MAT.G_MPa * b * t * L**2)
    F = 12.0 * EI * delta / (L**3 * (1.0 + phi))
    sigma = 6.0 * (F * L / 2.0) / (b * t**2)
    st = statics_stress(model, response, UP)
    assert st.peak_stress_MPa[-1] == pytest.approx(sigma, rel=1e-6)
    assert st.peak_stress_s_mm[-1] in (0.0, L)  # antisymmetric: the clamp or the guided end
    assert np.abs(st.bending_MPa[-1, 0]) == pytest.approx(sigma, rel=1e-6)


def test_tapered_clamped_guided_beam_against_the_closed_form_where_the_curvature_misses():
    """t linear 0.5 -> 1.5 mm over 100 mm (EI x 27), Euler-Bernoulli (a stiff shear term):
    from v'' = (M0 - F s) / EI, v'(0) = v(0) = v'(L) = 0, v(L) = delta:
    F = delta / (I2 - I1^2 / I0), M0 = F I1 / I0 with Ik = int s^k / EI ds (quad). The moment
    from statics is within 2e-5 of it on 24 elements (measured 9.6e-6; 2.4e-3 on 6, 1.7e-4 on
    12: the end load converges like the force); the elements' own curvature there is 1.2 %
    low (12.7 % on 6, 4.2 % on 12, h^2): checked >= 100 x worse, the flaw this module fixes."""
    L, b, delta = 100.0, 5.0, 0.02
    t0, t1 = 0.5, 1.5
    profile = BeamProfile(np.array([[0.0, 0.0], [L, 0.0]]), np.array([t0, t1]), b)
    model, response = _guided(profile, 24, delta, shear_factor=1e4)

    def ei(s):
        return MAT.E_MPa * b * (t0 + (t1 - t0) * s / L) ** 3 / 12.0

    I0, I1, I2 = (
        quad(lambda s, k=k: s**k / ei(s), 0.0, L, epsabs=0, epsrel=1e-13)[0] for k in range(3)
    )
    F = delta / (I2 - I1**2 / I0)
    M0 = F * I1 / I0
    exact = 6.0 * abs(M0) / (b * t0**2)
    st = statics_stress(model, response, UP)
    got = abs(st.bending_MPa[-1, 0])
    err_statics = abs(got / exact - 1.0)
    assert err_statics <= 2e-5, (got, exact)
    # the elements' curvature at the clamp: M = EI phi' at the first sample
    tab = model.tables
    phi = response.rotations_rad[-1]
    kappa0 = tab.dN_samples[0, 0] @ phi[:3]
    err_curvature = abs(abs(tab.EI_samples[0, 0] * kappa0) * 6.0 / (b * t0**2) / exact - 1.0)
    assert err_curvature >= 100.0 * max(err_statics, 1e-7), (err_curvature, err_statics)


#: the hybrid optimiser's seed-1 design of session 24's constant-force study (its input here):
#: 40.98 MPa by the elements' curvature on 60 elements, MET in its run, over 42.5 MPa at the
#: clamp on refined beams (docs/constant_force.md, "Stress at the clamp")
HYBRID_DESIGN = [
    0.454760, 0.713370, 0.601540, 0.856254, 0.172064, 0.724847, 0.586230, 0.764384, 0.298205,
    0.805398, 1.213754, 0.830331, 0.969504, 0.894687, 0.8, 0.8, 1.007123, 1.411341, 0.806999,
    0.8, 0.812236, 0.805945, 7.230742,
]  # fmt: skip


def _study(elements):
    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    # sharp pads: the nominal clamp stress at s = 0 and its exact gradient are the sharp beam's
    # (the default 0.5 mm pad fillets flare it and add Kt x root, which has no exact Jacobian)
    geometry = study.geometry.model_copy(update={"elements": elements, "pad_fillet_mm": 0.0})
    return study.model_copy(update={"geometry": geometry})


def test_the_hybrid_design_s_clamp_stress_converges_and_is_not_met():
    """The study's stress (from statics) on 60 elements equals the 480-element one to 2e-4 and
    the elements' curvature's on 960 elements to 5e-4 (both models converge to it); it lies
    over the 42.5 MPa allowable, so the GA's constraint is violated and the figure the verdict
    judges (the larger of plane stress and the beam at the pads) is over the allowable."""
    from flexopt.pipeline.studies import constant_force as cf

    x = np.array(HYBRID_DESIGN)
    peaks = {}
    for n in (60, 480):
        prob = cf.problem(_study(n))
        _, response, reason = prob._solve(x)
        assert not reason
        peaks[n] = float(np.max(response.peak_stress_MPa))
    assert peaks[60] == pytest.approx(peaks[480], rel=2e-4)
    prob = cf.problem(_study(960))
    design = prob._design(x)
    model = prob._beam(design)
    curvature = model.solve(prob._drive(30.0, 60))
    assert float(np.max(curvature.peak_stress_MPa)) == pytest.approx(peaks[60], rel=5e-4)

    prob = cf.problem(_study(60))
    assert peaks[60] > prob.allowable_MPa
    assert prob.evaluate(x).g[0] > 0.0  # stress_ratio_minus_1: infeasible for the GA
    result = prob.result(x)
    judged = result.summary["checked_peak_stress_MPa"]
    assert judged == max(result.summary["plane_stress_peak_stress_MPa"], peaks[60])
    assert judged > prob.allowable_MPa


@pytest.mark.parametrize("k", [2, 11, 20, 22])
def test_the_exact_gradient_of_the_clamp_stress_against_central_differences(k):
    """The hybrid's exact Jacobian reads the stress from statics: on the design above, whose peak
    sits at the clamp (s = 0, every term of M(0) = M_end + (r_end - r(0)) x F in play), the
    derivative of the peak by a3 (a vertex move), t2, T1 and B against central differences of
    the study's own solve: within 1e-5 of the gradient's largest component (measured 6e-7)."""
    from flexopt.pipeline.studies import constant_force as cf
    from flexopt.pipeline.studies._constant_force_gradient import study_sensitivities

    study = _study(60)
    geometry = study.geometry.model_copy(update={"min_feature_mm": 0.5})
    prob = cf.problem(study.model_copy(update={"geometry": geometry}))
    x = np.array(HYBRID_DESIGN)
    out = study_sensitivities(prob, x, prob._beam, prob._drive)
    _, response, _ = prob._solve(x)
    assert response.peak_stress_s_mm[int(np.argmax(response.peak_stress_MPa))] == 0.0
    h = 1e-4 * max(abs(x[k]), 0.1)
    peaks = []
    for sign in (1.0, -1.0):
        v = x.copy()
        v[k] += sign * h
        _, response, reason = prob._solve(v)
        assert not reason
        peaks.append(float(np.max(response.peak_stress_MPa)))
    fd = (peaks[0] - peaks[1]) / (2.0 * h)
    assert abs(out["d_peak"][k] - fd) <= 1e-5 * np.abs(out["d_peak"]).max(), (out["d_peak"][k], fd)
