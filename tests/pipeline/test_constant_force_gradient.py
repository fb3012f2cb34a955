"""Exact derivatives of the constant-force study's responses (pipeline/studies/
_constant_force_gradient.py, geometry/constant_force_map.py) against central finite differences
of the whole study response.

Every reference is computed here: the study's own ``evaluate`` (its Eq. 8 residuals and its
stress constraint) re-run for perturbed design vectors, or, for the KS aggregate, the
aggregate over every row and fibre of the study's solve built in this file. The study's beam is
solved at a tight Newton tolerance (rtol = 1e-11; the only change) so that the differences are
not the solver's noise. Stencil: fourth-order central, ``(8 (f(h) - f(-h)) - (f(2h) -
f(-2h))) / 12 h``. Relative error = |exact - FD| over the largest |FD| of that response group
for that variable (a pointwise ratio is meaningless where a derivative crosses zero).
The residual probes lie at 3..30 mm, all after the beam's buckling onset at ~0.03 mm: the
rows the solver's branch guards chose. The band row of ``method: hybrid`` (``force_band_excess``)
is checked against FD of evaluate's own row, and a quick hybrid run takes exact Jacobians.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel
from flexopt.fea.beam_sensitivity import beam_sensitivities, ks_aggregate
from flexopt.geometry.constant_force import beam_profile, design_from_vector
from flexopt.geometry.constant_force_map import profile_derivatives
from flexopt.pipeline.studies import _constant_force_gradient as gradient
from flexopt.pipeline.studies.constant_force import ConstantForceProblem
from flexopt.pipeline.study import load_study

ROOT = Path(__file__).resolve().parents[2]
TOL = 1e-6


class TightProblem(ConstantForceProblem):
    """The example's problem, its beam solved to rtol = 1e-11 (everything else the study's)."""

    def _beam(self, design):
        model = super()._beam(design)
        return BeamModel(
            model.profile, model.material, "clamped", replace(model.settings, rtol=1e-11)
        )


#: the constant-force example's recorded design until session 26 (an input here)
SESSION_25_DESIGN = {
    "a1": 0.159, "a2": 0.8071, "a3": 0.5057, "a4": 0.8453, "a5": 0.133, "a6": 0.8451,
    "a7": 0.4573, "a8": 0.7743, "a9": 0.2115, "a10": 0.8743, "t1": 1.059, "t2": 0.8668,
    "t3": 0.966, "t4": 0.8001, "t5": 0.8003, "t6": 0.8275, "t7": 0.8367, "t8": 0.9738,
    "t9": 0.9394, "t10": 1.049, "T1": 1.371, "T6": 1.278, "B": 6.826,
}  # fmt: skip


@pytest.fixture(scope="module")
def problem():
    # the design these steps and tolerances were tuned on: the example's until session 26 (its
    # recorded design since sits within a step of a mesh switch for a8)
    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml").with_values(
        {"design": SESSION_25_DESIGN}
    )
    # the example's design has t4 = 0.8 mm, at min_feature_mm: a lower limit, so that the
    # differences on either side are solved rather than refused as unprintable; sharp pads: the
    # exact derivatives are the sharp beam's (with a pad fillet the study has no Jacobian)
    geometry = study.geometry.model_copy(update={"min_feature_mm": 0.5, "pad_fillet_mm": 0.0})
    return TightProblem(study.model_copy(update={"geometry": geometry}))


def _fd(fun, h):
    return (8.0 * (fun(h) - fun(-h)) - (fun(2 * h) - fun(-2 * h))) / (12.0 * h)


def _step(problem, k):
    """FD step of variable k: 0.3 mm of vertex motion for a_j (its interval is ~40 mm long;
    the force moves ~1e-3 N per mm of it, so a smaller step leaves the solve's noise: at 0.01 mm
    the differences were up to 1e-5 off, at 0.1 mm 1e-6; a smaller one is taken where the
    designs would change the mesh, :func:`_same_mesh`), 1e-2 relative for a thickness or the
    width."""
    if k < 10:
        move = profile_derivatives(problem.frame).points[k]
        return 3e-1 / float(np.abs(move).max())
    return 1e-2 * problem.nominal_design()[k]


def _elements_per_segment(problem, x):
    """(n_seg,) the elements of each segment, by fea.beam's rule (rounded from its length)."""
    model = problem._beam(design_from_vector(x))
    seg = model.profile.segment_lengths_mm
    return np.maximum(1, np.rint(model.settings.n_elements * seg / seg.sum())).astype(int)


def _same_mesh(problem, x, k, h):
    """The FD designs x +- h, +- 2h e_k have x's elements per segment (the element count of a
    segment is rounded from its length: a difference across a change of it measures the mesh)."""
    ref = _elements_per_segment(problem, x)
    for step in (-2 * h, -h, h, 2 * h):
        v = x.copy()
        v[k] += step
        if not np.array_equal(_elements_per_segment(problem, v), ref):
            return False
    return True


def _residuals(problem, x):
    ev = problem.with_residuals().evaluate(x)
    assert not ev.reason, ev.reason
    n = problem.study.target.samples
    return np.array([ev.metrics[f"residual_{i + 1}"] for i in range(n)])


def test_the_profile_map_is_the_generator_s_derivative(problem):
    """beam_profile is linear in x: its central difference equals the map for every variable."""
    x = problem.nominal_design()
    maps = profile_derivatives(problem.frame, problem.study.geometry.end_flexures)
    for k in range(23):
        h = 1e-3

        def prof(step, k=k):
            v = x.copy()
            v[k] += step
            p = beam_profile(design_from_vector(v), problem.frame, "centred")
            return p.points_mm, p.thickness_mm, p.width_mm

        (pp, tp, bp), (pm, tm, bm) = prof(h), prof(-h)
        np.testing.assert_allclose((pp - pm) / (2 * h), maps.points[k], atol=1e-9)
        np.testing.assert_allclose((tp - tm) / (2 * h), maps.thickness[k], atol=1e-9)
        assert abs((bp - bm) / (2 * h) - maps.width[k]) < 1e-9
    assert list(maps.moving) == list(range(10))


def test_interpolation_matrix_is_np_interp():
    s = np.linspace(0.0, 30.0, 61)
    probes = 30.0 * np.arange(1, 11) / 10 - 0.7  # off the rows too
    rng = np.random.default_rng(3)
    for _ in range(3):
        f = rng.normal(size=61)
        np.testing.assert_allclose(
            gradient.interpolation_matrix(s, probes) @ f, np.interp(probes, s, f), atol=1e-14
        )


@pytest.fixture(scope="module")
def exact(problem):
    x = problem.nominal_design()
    out = gradient.study_sensitivities(problem, x, problem._beam, problem._drive)
    assert out is not None
    return x, out


def test_residuals_are_the_study_s_own(problem, exact):
    """The derivatives belong to the residuals the study's evaluate reports (same rows)."""
    x, out = exact
    r = _residuals(problem, x)
    np.testing.assert_allclose(out["residuals_N"], r, rtol=0, atol=1e-9)
    assert out["rms_error_N"] == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-8)


def test_residuals_and_rms_against_central_differences_of_evaluate(problem, exact):
    """d(residual_i)/dx_k and d(rms_error_N)/dx_k for all 23 variables (a1..a10 through the
    vertex moves, t1..t10, T1, T6, B) against FD of the study's evaluate."""
    x, out = exact
    n = len(out["residuals_N"])
    span = problem.space.upper - problem.space.lower
    fds, steps = [], []
    for k in range(23):
        # the largest step of the ladder whose designs keep the mesh
        h = next(
            (h for h in _step(problem, k) * LADDER if _same_mesh(problem, x, k, h)),
            None,
        )
        assert h is not None, problem.space.names[k]

        def fun(step, k=k):
            v = x.copy()
            v[k] += step
            return _residuals(problem, v)

        def half_mean_square(step, k=k):
            r = fun(step)
            return 0.5 * np.mean(r**2)

        # the RMS is curved on the scale of the RMS itself (0.006 N; a 1e-2 step of t moves a
        # residual by 0.005 N: its difference was 4e-3 off at the residuals' step); mean(r^2) / 2
        # = rms^2 / 2 is smooth on the scale of r, and
        # d(rms^2 / 2) = rms d rms. Its fifth derivative (10 r2 r3 + ..., r_i the i-th
        # derivative of a residual) is not small where F ~ t^3: a third of the step
        fds.append(np.append(_fd(fun, h), _fd(half_mean_square, h / 3)))
        steps.append(h / _step(problem, k))
    fd = np.array(fds).T  # (n + 1, 23)
    analytic = np.vstack([out["d_residuals"], out["rms_error_N"] * out["d_rms"]])
    err = np.abs(analytic - fd)
    # per variable: over the largest |FD| of the residuals for that variable; d(rms^2 / 2) =
    # r . dr / n sums terms of both signs, so its error is over its bound |r|_2 |dr|_2 / n
    per_var_r = err[:n].max(axis=0) / np.abs(fd[:n]).max(axis=0)
    r_norm = np.linalg.norm(out["residuals_N"])
    per_var_f = err[n] / (r_norm * np.linalg.norm(fd[:n], axis=0) / n)
    # the Jacobian as the optimiser uses it (bound-normalised: d/du = d/dx (upper - lower)):
    # over its largest entry
    jac = err[:n].max(axis=0) * span / np.abs(fd[:n] * span).max()
    names = problem.space.names
    resolved = np.array(steps) >= 1.0 / 3.0  # >= 0.1 mm of vertex motion for a_j
    assert resolved.sum() >= 21  # on this design a8 and a9 only get 0.05 mm
    bad = {
        names[k]: (per_var_r[k], per_var_f[k])
        for k in range(23)
        if resolved[k] and max(per_var_r[k], per_var_f[k]) > TOL
    }
    assert not bad, bad
    assert jac.max() <= TOL, dict(zip(names, jac, strict=True))


#: FD step ladder (fractions of :func:`_step`): the largest that keeps the mesh is taken (on the
#: example's design no a_j keeps it at 0.3 mm: each moves a segment's length across a rounding
#: of its element count within 0.6 mm). Below ~0.1 mm of vertex motion the solve's noise
#: exceeds 1e-6 of an a_j column (measured: the error falls as 1/h, 2.4e-5 at 0.01 mm, 8e-6 at
#: 0.03 mm, 6.7e-6 for a8 at 0.05 mm, <= 4.4e-7 at >= 0.1 mm), so the per-variable bound is
#: asserted where the step is >= 0.1 mm, the Jacobian's (bound-normalised) at every step
LADDER = np.array([1.0, 2.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0, 1.0 / 10.0])


def _path_ks(problem, x, rho):
    """KS over every row and fibre of the study's solve of x, computed from scratch (the
    fibre stresses from statics, the study's)."""
    model = problem._beam(design_from_vector(x))
    drive = problem._drive(problem.study.boundary.stroke_mm, problem.study.boundary.rows)
    response = model.solve(drive)
    states = beam_sensitivities(model, drive, response, variables=(), stress="statics")
    fibre = states.fibre_stress_MPa.reshape(-1)
    return ks_aggregate(np.concatenate([fibre, -fibre]), rho)[0]


@pytest.mark.parametrize("k", [0, 4, 9, 10, 15, 19, 20, 21, 22])
def test_ks_stress_against_central_differences(problem, exact, k):
    """d(KS over the whole path)/dx_k (the stress constraint's smooth aggregate). The KS is
    smooth on the scale 1/rho: a smaller step (1e-3 relative, 1e-3 mm of vertex motion)."""
    x, out = exact
    rho = out["rho"]
    h = _step(problem, k) / 10

    def fun(step):
        v = x.copy()
        v[k] += step
        return _path_ks(problem, v, rho)

    assert _path_ks(problem, x, rho) == pytest.approx(out["ks_stress_MPa"], rel=1e-12)
    fd = _fd(fun, h)
    scale = np.abs(out["d_ks"]).max()  # the gradient's size: a near-zero component tests nothing
    assert abs(out["d_ks"][k] - fd) <= TOL * scale, (out["d_ks"][k], fd)


@pytest.mark.parametrize("k", [2, 11, 14, 20])
def test_the_peak_stress_gradient_where_the_max_is_smooth(problem, exact, k):
    """The max's derivative (its active point's) against FD of evaluate's stress constraint,
    where one point holds the max (the last row's; checked); and KS lies within its bound."""
    x, out = exact
    jac = problem.jacobian(x)
    scale = problem.study.fidelity.beam_stress_factor / problem.allowable_MPa
    h = _step(problem, k) / 10

    def fun(step):
        v = x.copy()
        v[k] += step
        return problem.evaluate(v).g[0]

    fd = _fd(fun, h)
    grad = jac.info["peak_stress_gradient"]
    assert abs(grad[k] - fd) <= TOL * np.abs(grad).max(), (grad[k], fd)
    n = 12 * problem.study.geometry.elements * (problem.study.boundary.rows + 1)
    assert (
        out["peak_stress_MPa"]
        <= out["ks_stress_MPa"]
        <= out["peak_stress_MPa"] + np.log(n) / out["rho"]
    )
    np.testing.assert_allclose(jac.g[0], scale * out["d_ks"], rtol=1e-12)


def test_the_hook_answers_none_for_what_it_cannot_differentiate(problem):
    """The operative_stroke objective (a window of the band: piecewise), also under ``method:
    hybrid`` (no band row then), and a design that cannot be built get no Jacobian: the
    optimiser falls back to finite differences."""
    study = problem.study.model_copy(update={"objective": "operative_stroke"})
    assert ConstantForceProblem(study).jacobian(problem.nominal_design()) is None
    optimiser = study.optimiser.model_copy(update={"method": "hybrid"})
    hybrid = ConstantForceProblem(study.model_copy(update={"optimiser": optimiser}))
    assert hybrid.jacobian(problem.nominal_design()) is None
    x = problem.nominal_design()
    x[0] = x[1] + 0.01  # a1 > a2: the centreline folds back
    assert problem.jacobian(x) is None


def test_a_design_at_a_switch_of_the_mesh(problem):
    """a1 placed where segment 1's element count rounds differently (found by bisection): at
    the switch every difference step of the vertex move straddles it and the hook answers None;
    near it the hook takes a smaller step. It never raises (a run would end)."""
    x = problem.nominal_design()

    def counts(a1):
        v = x.copy()
        v[0] = a1
        return _elements_per_segment(problem, v)

    lo, hi = problem.space.lower[0], problem.space.upper[0]
    assert not np.array_equal(counts(lo), counts(hi))  # a switch lies in between
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.array_equal(counts(mid), counts(lo)) else (lo, mid)
    # at the switch (1e-15 of a1): every step straddles it, no Jacobian (FD instead)
    x[0] = lo
    assert problem.jacobian(x) is None
    # 3e-5 mm of vertex motion (p1 moves 10.8 mm per unit a1) from it: the default step
    # (1.3e-4 mm) straddles it, the next (1.3e-5 mm) does not
    x[0] = lo - 3e-5 / 10.8
    jac = problem.jacobian(x)
    assert jac is not None and np.all(np.isfinite(jac.residuals))


# ---- the band row (``optimiser: {method: hybrid}`` only) ------------------------------------


@pytest.fixture(scope="module")
def hybrid_problem(problem):
    """The example's problem under ``method: hybrid``: its second constraint row is the band's
    (``force_band_excess``); the beam solved to rtol = 1e-11 as :class:`TightProblem`."""
    optimiser = problem.study.optimiser.model_copy(update={"method": "hybrid"})
    return TightProblem(problem.study.model_copy(update={"optimiser": optimiser}))


#: FD steps of the band row (fractions of :func:`_step`): the largest whose designs keep the
#: mesh and the worst row is taken. From a tenth (1e-3 relative, 0.03 mm of vertex motion), as
#: the stress tests: row 1 (0.5 mm) is near the buckling onset, and its force is smooth in t2
#: only within ~4e-3 mm of the example's design (its second difference jumps from 0.22 to
#: ~1e3 /mm^2 beyond; the row stays the worst): at a third (2.9e-3 mm, +-2 h reaching
#: 5.8e-3 mm) t2's difference was 3e-3 off, at 1e-3 mm it agrees to 2e-7
BAND_LADDER = np.array([1.0 / 10.0, 1.0 / 30.0, 1.0 / 100.0])

#: the band row's derivative against FD of evaluate's: relative to the largest |FD| of the row
#: (its gradient's size: a near-zero component tests nothing), asserted per variable
BAND_TOL = 1e-5


def _band(problem, x):
    """evaluate's band row and its active (worst judged) row at x."""
    ev = problem.evaluate(x)
    assert not ev.reason, ev.reason
    _, response, _ = problem._solve(x)
    return ev.g[1], gradient._band_row(problem.study, response)


def _band_fd(problem, x, jac, variables):
    """FD of evaluate's band row by each of ``variables`` at the ladder's largest step whose
    designs keep the mesh and the worst row (else NaN, with the reason in ``skipped``)."""
    fd = np.full(23, np.nan)
    skipped = {}
    for k in variables:
        for h in _step(problem, k) * BAND_LADDER:
            if not _same_mesh(problem, x, k, h):
                continue
            values, active = {}, set()
            for step in (-2 * h, -h, h, 2 * h):
                v = x.copy()
                v[k] += step
                values[step], row = _band(problem, v)
                active.add(row)
            if active == {jac.info["band_row"]}:
                fd[k] = _fd(lambda s, values=values: values[s], h)
                break
        else:
            skipped[problem.space.names[k]] = "every step changes the mesh or the worst row"
    return fd, skipped


def test_the_band_row_against_central_differences_of_evaluate(hybrid_problem):
    """d(force_band_excess)/dx_k for all 23 variables against FD of the problem's own
    ``evaluate`` (its g[1]) at the example's design. The row is a max over the judged rows: on
    this design its worst row is row 1 (0.5 mm, 0.016 N under 1.5 N) and the held share of the
    band (0.024 N) is the larger allowance (3 x RMS = 0.019 N), so dg = -dF_1 / 1.5. A variable
    is skipped where every step of the ladder changes the mesh or the worst row (checked on
    every FD design): none is on this design, every one is checked at the ladder's first step
    (measured: <= 2.5e-9 of the row's largest |FD|)."""
    problem = hybrid_problem
    assert problem.constraint_names == ("stress_ratio_minus_1", "force_band_excess")
    x = problem.nominal_design()
    jac = problem.jacobian(x)
    assert jac is not None and jac.g.shape == (2, 23)
    ev = problem.evaluate(x)
    np.testing.assert_allclose(jac.values["g"], ev.g, rtol=0, atol=1e-9)
    assert jac.info["band_row"] == 1 and not jac.info["band_reach_active"]
    # the stress row is the GA problem's, unchanged by the band
    np.testing.assert_allclose(jac.g[0], _ga_jacobian(problem, x).g[0])
    fd, skipped = _band_fd(problem, x, jac, range(23))
    assert not skipped, skipped
    names = problem.space.names
    err = np.abs(jac.g[1] - fd)
    scale = np.abs(fd).max()
    bad = {names[k]: err[k] / scale for k in range(23) if err[k] > BAND_TOL * scale}
    assert not bad, bad
    span = problem.space.upper - problem.space.lower
    jac_err = err * span / np.abs(fd * span).max()  # the optimiser's normalised columns
    assert jac_err.max() <= BAND_TOL, dict(zip(names, jac_err, strict=True))


def test_the_band_row_where_the_rms_allowance_is_active(hybrid_problem):
    """The other piece of the allowance: a target of 1.45 N puts the example's design ~0.05 N
    off, so 3 x RMS exceeds the held share of the band and dg = (sign dF_k - 3 d rms) / 1.45;
    checked against FD of evaluate for a position, two thicknesses and the width."""
    study = hybrid_problem.study
    target = study.target.model_copy(update={"force_N": 1.45})
    problem = TightProblem(study.model_copy(update={"target": target}))
    x = problem.nominal_design()
    jac = problem.jacobian(x)
    assert jac is not None and jac.info["band_reach_active"]
    np.testing.assert_allclose(jac.values["g"], problem.evaluate(x).g, rtol=0, atol=1e-9)
    variables = [2, 11, 14, 22]
    fd, skipped = _band_fd(problem, x, jac, variables)
    assert not skipped, skipped
    err = np.abs(jac.g[1] - fd)[variables]
    assert err.max() <= BAND_TOL * np.abs(fd[variables]).max(), (jac.g[1][variables], fd)
    # and the reach term is in it: without it the derivative would be off
    d_rms = 3.0 * jac.f[0][variables] / 1.45
    assert np.abs(d_rms).max() > 100 * err.max()


def _ga_jacobian(problem, x):
    """The same design's Jacobian of the one-constraint (GA) problem."""
    optimiser = problem.study.optimiser.model_copy(update={"method": "ga"})
    ga = TightProblem(problem.study.model_copy(update={"optimiser": optimiser}))
    assert ga.constraint_names == ("stress_ratio_minus_1",)
    return ga.jacobian(x)


def test_a_quick_hybrid_run_takes_exact_jacobians(tmp_path):
    """A quick constant-force run under ``method: hybrid`` (its problem has the band row) takes
    the study's exact Jacobians at every gradient iteration, no forward differences (~10 s: 24
    GA designs, one start of two iterations, the report)."""
    from flexopt.pipeline.parallel import ParallelSettings
    from flexopt.pipeline.run import prepare_run, run_study
    from flexopt.pipeline.study import HybridSpec

    study = load_study("constant-force")
    hybrid = HybridSpec(starts=1, max_iter=2, ga_n_gen=2)
    optimiser = study.optimiser.model_copy(update={"method": "hybrid", "hybrid": hybrid})
    fidelity = study.fidelity.model_copy(update={"enabled": False})
    sharp = study.geometry.model_copy(update={"pad_fillet_mm": 0.0})  # hybrid: no pad fillet
    study = study.model_copy(
        update={"optimiser": optimiser, "fidelity": fidelity, "geometry": sharp}
    )
    setup = prepare_run(study, quick=True)
    assert setup.problem.constraint_names == ("stress_ratio_minus_1", "force_band_excess")
    outcome = run_study(setup, out=tmp_path / "run", parallel=ParallelSettings("serial"))
    jacobians = outcome.result.report["jacobians"]
    assert jacobians["exact"] >= 1 and jacobians["finite_differences"] == 0, jacobians


def _jacobian_arrays(jac):
    return [jac.f, jac.g, jac.residuals, *jac.values.values(), jac.info["peak_stress_gradient"]]


@pytest.mark.parametrize("fillet_mm", [0.0, 0.5])
def test_a_jacobian_at_a_design_this_process_just_solved_starts_from_that_solve(fillet_mm):
    """The hybrid asks for the Jacobian at the design it just evaluated: the path kept by
    ``_solve`` (pipeline/studies/_constant_force_solved.py) is reused, the same model and
    response, so the Jacobian is the same bit for bit as with the path solved again; a problem
    of another class (its own beam) or another study never reads another's kept path."""
    from flexopt.pipeline.studies import _constant_force_solved as kept

    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    geometry = study.geometry.model_copy(update={"pad_fillet_mm": fillet_mm})
    prob = ConstantForceProblem(study.model_copy(update={"geometry": geometry}))
    x = prob.nominal_design()
    kept.clear()
    fresh = prob.jacobian(x)
    assert kept.kept(prob, x) is None  # the Jacobian keeps nothing itself
    assert np.all(np.isfinite(prob.evaluate(x).f))  # evaluated: its solve is kept
    design, model, response = kept.kept(prob, x)
    assert response.ok and np.array_equal(design.a, x[:10])
    assert kept.kept(prob.with_residuals(), x) is not None  # a copy: the same study and beam
    assert kept.kept(TightProblem(prob.study), x) is None  # another beam builder
    other = ConstantForceProblem(prob.study.model_copy())
    assert kept.kept(other, x) is None  # another study object
    assert kept.kept(prob, x + 1e-12) is None  # the exact design only
    reused = prob.jacobian(x)
    for a, b in zip(_jacobian_arrays(fresh), _jacobian_arrays(reused), strict=True):
        np.testing.assert_array_equal(a, b)
    # reused, not solved again: no solve of the beam in the second Jacobian
    calls = []
    solve = BeamModel.solve
    BeamModel.solve = lambda self, *a, **k: calls.append(1) or solve(self, *a, **k)
    try:
        prob.jacobian(x)
        kept.clear()
        prob.jacobian(x)
    finally:
        BeamModel.solve = solve
    assert len(calls) == 1  # only the Jacobian with nothing kept solved
    for k in range(1, kept.KEEP + 1):  # KEEP newer solves: x, the oldest, is forgotten
        assert np.all(np.isfinite(prob.evaluate(x + k * 1e-6).f))
    assert kept.kept(prob, x) is None


@pytest.mark.parametrize("seed", [None, 0, 1, 2])
def test_the_gauss_newton_copys_jacobian_is_the_full_ones_but_for_the_ks_row(seed):
    """The ``with_residuals`` copy (the hybrid's Gauss-Newton problem) differentiates only the
    stress rows near the peak (``window``, session 34): its residuals, objective, stress pieces,
    peak's and band row's derivatives are the full Jacobian's to the bit (the step reads those),
    and its KS row (which the step does not read) is the KS over fewer rows: within 1e-5 of the
    full one's size on these designs (the example's recorded one and random ones, with the
    example's 0.5 mm pad fillets)."""
    from flexopt.pipeline.run.setup import prepare_run

    gn = prepare_run(load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")).problem
    assert gn.residual_metrics  # the run's problem is the Gauss-Newton copy
    space = gn.space
    if seed is None:
        x = gn.nominal_design()
    else:
        rng = np.random.default_rng(seed)
        x = space.lower + rng.random(space.n_var) * (space.upper - space.lower)
    full = gradient.jacobian(gn, x, gn._beam, gn._drive, window=False)
    lean = gn.jacobian(x)
    assert full is not None and lean is not None
    assert lean.info["stress_aggregate"] == "KS near the peak"
    assert full.info["stress_aggregate"] == "KS"
    np.testing.assert_array_equal(lean.residuals, full.residuals)
    np.testing.assert_array_equal(lean.f, full.f)
    np.testing.assert_array_equal(lean.g[1:], full.g[1:])
    np.testing.assert_array_equal(lean.values["g"], full.values["g"])
    np.testing.assert_array_equal(
        lean.info["peak_stress_gradient"], full.info["peak_stress_gradient"]
    )
    assert lean.info["g_pieces"].keys() == full.info["g_pieces"].keys()
    for c, piece in full.info["g_pieces"].items():
        for key in ("values", "gradients"):
            np.testing.assert_array_equal(lean.info["g_pieces"][c][key], piece[key])
    scale = np.abs(full.g[0]).max()
    assert np.abs(lean.g[0] - full.g[0]).max() <= 1e-5 * scale
