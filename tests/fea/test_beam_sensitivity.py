"""Exact sensitivities of a traced beam path (fea/beam_sensitivity.py) against finite differences.

Every reference derivative is a central finite difference of the full nonlinear solve (the
default kernel, re-traced from the undeformed state for each perturbed design). The stencil is
the fourth-order one, ``(8 (f(h) - f(-h)) - (f(2h) - f(-2h))) / 12 h``: its truncation error is
O(h^4), so a step of 1e-2 of the thickness (or 1e-2 mm of a coordinate) leaves ~1e-8 of
truncation (measured: the derivatives at steps 1e-2 and 3e-2 agree to ~1e-7), while the noise
of the solve (its rows polished to equilibrium, see :func:`_responses`) divided by the step stays
~1e-8. At a step of 1e-3 that noise reaches ~1e-6 under force control (a soft cantilever's tip
moves ~1e-9 mm for the round-off of a residual of EA ~ 6000 N); a second-order stencil would
need that small a step for the same truncation. The stresses checked are smooth ones: the KS
aggregate over the signed outer-fibre stresses, and one fibre's signed stress (the solver's
|N|/A + |M| c/I has a kink where the small axial strain of a sampling point changes sign). The KS
stress is differenced with a smaller step, see STRESS_KEYS.

"Relative error" is |analytic - FD| over the largest |FD| of that response and variable along the
path (a pointwise ratio is meaningless where a derivative crosses zero, at the undeformed row).
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive
from flexopt.fea.beam_sensitivity import beam_sensitivities, ks_aggregate
from flexopt.fea.materials import Material, get_material
from flexopt.geometry.profile import BeamProfile

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
#: tight Newton tolerance, so that the finite differences of the solve are not its noise
TIGHT = BeamSettings(n_elements=20, rtol=1e-11)
TOL = 1e-6


def _tapered(points=((0.0, 0.0), (50.0, 0.0), (100.0, 0.0)), t=(1.5, 1.0, 0.6), b=2.0):
    """A straight tapered cantilever, 100 mm long, 1.5 -> 0.6 mm thick (three vertices)."""
    return BeamProfile(np.array(points, dtype=float), np.array(t, dtype=float), b)


#: tip pushed across to 0.6 L, end free to turn and to move along the beam: 80 degrees of rotation
CANTILEVER = EndDrive("displacement", (0.0, 1.0), 60.0, 10, "free", "free")


def _constant_force_profile() -> BeamProfile:
    """Paper 003's constant-force beam (Table 3 optimum), as the constant_force study builds it."""
    from flexopt.geometry.constant_force import TABLE3_OPTIMUM, beam_profile

    return beam_profile(TABLE3_OPTIMUM, end_flexures="centred")


def _responses(profile, material, drive, settings, keys, sample=None, start="clamped"):
    """(n_rows, n_keys) responses of the full solve of ``profile``, read at its rows polished to
    equilibrium at round-off (:func:`beam_sensitivities` with no variable): the solve stops once a
    Newton correction is below dtol = 1e-12 L, which leaves up to K x 1e-10 mm ~ 1e-9 N in a
    force, and divided by a step of 1e-3 mm that noise alone would be ~1e-6."""
    model = BeamModel(profile, material, start, settings)
    response = model.solve(drive)
    assert response.ok, response.message
    states = beam_sensitivities(model, drive, response, variables=())
    cols = []
    for k in keys:
        if k == "ks_stress_MPa":
            cols.append(states.values[k])
        elif k == "stress_at_sample":  # the top fibre's (signed, smooth) stress
            cols.append(states.fibre_stress_MPa[:, sample, 0])
        else:
            cols.append(states.values[k])
    return np.array(cols).T


def _fd(fun, h):
    """Fourth-order central difference of ``fun(step)`` at 0."""
    return (8.0 * (fun(h) - fun(-h)) - (fun(2 * h) - fun(-2 * h))) / (12.0 * h)


def _relative_error(analytic, fd):
    """(n_keys,) max over rows of |analytic - fd| / max over rows |fd|."""
    scale = np.abs(fd).max(axis=0)
    assert np.all(scale > 0), "a reference derivative that is zero on every row tests nothing"
    return np.abs(analytic - fd).max(axis=0) / scale


#: the KS stress is smooth but on the scale 1/rho (0.5 MPa for the default rho = 100 / yield):
#: its FD step must move the stresses by much less than that (rho h dsigma/dt ~ 1 at a 1e-2 step
#: of t, which left 1e-5 of truncation on paper 003's beam; 2e-3 left 2e-6, 1e-3 leaves 1e-7,
#: falling as h^4)
STRESS_KEYS = ("ks_stress_MPa", "stress_at_sample")


def _thickness_fd(
    profile, material, drive, settings, j, keys, sample=None, stress_step=1e-3, start="clamped"
):
    """FD of ``keys`` by t_j: relative step 1e-2 for the end quantities, ``stress_step`` (1e-3)
    for the stresses."""
    stress = [k for k in keys if k in STRESS_KEYS]
    other = [k for k in keys if k not in STRESS_KEYS]
    fd = {}
    for group, rel in ((other, 1e-2), (stress, stress_step)):
        if group:
            cols = _thickness_fd_step(
                profile, material, drive, settings, j, group, sample, rel, start
            )
            fd.update(zip(group, cols.T, strict=True))
    return np.array([fd[k] for k in keys]).T


def _thickness_fd_step(profile, material, drive, settings, j, keys, sample, rel, start="clamped"):
    t0 = np.array(profile.thickness_mm)
    h = rel * t0[j]

    def fun(step):
        t = t0.copy()
        t[j] += step
        prof = BeamProfile(profile.points_mm, t, profile.width_mm, profile.curvature_per_mm)
        return _responses(prof, material, drive, settings, keys, sample, start)

    return _fd(fun, h)


def _analytic(sens, keys, v, sample=None):
    cols = []
    for k in keys:
        if k == "stress_at_sample":
            cols.append(sens.d_fibre_stress[:, sample, 0, v])
        else:
            cols.append(sens.derivatives[k][:, v])
    return np.array(cols).T


def test_tapered_cantilever_thickness_at_large_deflection():
    """d/dt_i of the driven force, the tip's transverse motion and rotation, the KS stress and the
    stress at the sampling point of the last row's peak, on every row: <= 1e-6."""
    profile = _tapered()
    model = BeamModel(profile, MAT, settings=TIGHT)
    response = model.solve(CANTILEVER)
    assert response.ok and response.end_rotation_rad[-1] > 1.2  # large deflection
    sens = beam_sensitivities(model, CANTILEVER, response, ("thickness",))
    assert sens.variables == ("t[0]", "t[1]", "t[2]")
    sample = int(np.argmax(sens.stress_MPa[-1]))
    keys = (
        "force_N",
        "transverse_displacement_mm",
        "end_rotation_rad",
        "ks_stress_MPa",
        "stress_at_sample",
    )
    for j in range(3):
        fd = _thickness_fd(profile, MAT, CANTILEVER, TIGHT, j, keys, sample)
        err = _relative_error(_analytic(sens, keys, j, sample), fd)
        assert err.max() <= TOL, (j, dict(zip(keys, err, strict=True)))


def test_tapered_cantilever_under_force_control():
    """Under a dead tip load the response is the displacement: d(tip motion)/dt_i."""
    profile = _tapered()
    ei = MAT.E_MPa * 2.0 * 1.0**3 / 12.0
    drive = EndDrive("force", (0.0, 1.0), 5.0 * ei / 100.0**2, 8, "free", "free")
    model = BeamModel(profile, MAT, settings=TIGHT)
    response = model.solve(drive)
    assert response.ok
    sens = beam_sensitivities(model, drive, response, ("thickness", "width"))
    keys = ("displacement_mm", "transverse_displacement_mm", "end_rotation_rad", "ks_stress_MPa")
    for j in range(3):
        # a dead load on a soft cantilever: the states carry ~1e-9 mm of round-off, which a KS
        # step of 1e-3 turns into 1e-6 (measured; 1e-4 gives 9e-6); 3e-3 balances it against
        # the truncation (2e-7 at 4e-3)
        fd = _thickness_fd(profile, MAT, drive, TIGHT, j, keys, stress_step=3e-3)
        err = _relative_error(_analytic(sens, keys, j), fd)
        assert err.max() <= TOL, (j, dict(zip(keys, err, strict=True)))
    # the load is prescribed: its derivative is zero
    assert np.all(sens.derivatives["force_N"][1:] == 0.0)


def test_centreline_coordinates_of_a_kinked_cantilever():
    """d/dx_i, d/dy_i of a cantilever with a kink at its middle vertex (semi-analytic: dR/dx at
    fixed DOFs by a central difference of the residual, no solve differenced)."""
    profile = _tapered(points=((0.0, 0.0), (50.0, 4.0), (100.0, 0.0)))  # 3 vertices
    model = BeamModel(profile, MAT, settings=TIGHT)
    response = model.solve(CANTILEVER)
    assert response.ok
    sens = beam_sensitivities(model, CANTILEVER, response, ("coordinates",))
    assert sens.counts["model_builds"] == 24  # 6 coordinates x the 4 points of the stencil
    keys = ("force_N", "transverse_displacement_mm", "end_rotation_rad", "ks_stress_MPa")
    for name in ("y[1]", "x[1]", "y[2]"):
        v = sens.variables.index(name)
        idx = (int(name[2]), "xy".index(name[0]))

        def fun(step, idx=idx):
            pts = np.array(profile.points_mm)
            pts[idx] += step
            prof = BeamProfile(pts, profile.thickness_mm, profile.width_mm)
            return _responses(prof, MAT, CANTILEVER, TIGHT, keys)

        fd = _fd(fun, 1e-2)
        err = _relative_error(_analytic(sens, keys, v), fd)
        assert err.max() <= TOL, (name, dict(zip(keys, err, strict=True)))


def test_circular_arcs_under_an_oblique_drive():
    """Two arc segments (the reference angle linear in s) and a drive at 45 degrees to the axes
    (the end node's DOFs in a rotated frame), transverse motion held: thickness and coordinates."""
    profile = BeamProfile(
        [[0.0, 0.0], [40.0, 0.0], [80.0, 10.0]],
        [1.2, 1.0, 0.8],
        3.0,
        curvature_per_mm=[0.01, -0.005],
    )
    drive = EndDrive("displacement", (-1.0, -1.0), 20.0, 8, "free", "fixed")
    model = BeamModel(profile, MAT, settings=TIGHT)
    response = model.solve(drive)
    assert response.ok and not response.unstable
    sens = beam_sensitivities(model, drive, response, ("thickness", "coordinates"))
    keys = ("force_N", "transverse_force_N", "end_rotation_rad", "ks_stress_MPa")
    fd = _thickness_fd(profile, MAT, drive, TIGHT, 1, keys)
    err = _relative_error(_analytic(sens, keys, sens.variables.index("t[1]")), fd)
    assert err.max() <= TOL, ("t[1]", dict(zip(keys, err, strict=True)))
    for name in ("y[1]", "x[2]"):
        idx = (int(name[2]), "xy".index(name[0]))

        def fun(step, idx=idx):
            pts = np.array(profile.points_mm)
            pts[idx] += step
            prof = BeamProfile(
                pts, profile.thickness_mm, profile.width_mm, profile.curvature_per_mm
            )
            return _responses(prof, MAT, drive, TIGHT, keys)

        err = _relative_error(_analytic(sens, keys, sens.variables.index(name)), _fd(fun, 1e-2))
        assert err.max() <= TOL, (name, dict(zip(keys, err, strict=True)))


def test_pinned_start():
    """A pinned start (its rotation free), the end guided: rotation held, pushed across."""
    profile = _tapered()
    drive = EndDrive("displacement", (0.0, 1.0), 40.0, 8, "fixed", "free")
    model = BeamModel(profile, MAT, start="pinned", settings=TIGHT)
    response = model.solve(drive)
    assert response.ok and not response.unstable
    sens = beam_sensitivities(model, drive, response, ("thickness",))
    keys = ("force_N", "moment_Nmm", "transverse_displacement_mm", "ks_stress_MPa")
    for j in (0, 2):
        fd = _thickness_fd(profile, MAT, drive, TIGHT, j, keys, start="pinned")
        err = _relative_error(_analytic(sens, keys, j), fd)
        assert err.max() <= TOL, (j, dict(zip(keys, err, strict=True)))


def test_constant_force_beam_after_its_buckling_onset():
    """Paper 003's beam buckles at ~0.03 mm of stroke (the branch guards pick the branch): the
    rows after the onset are smooth in the thicknesses and match the full solve's differences."""
    profile = _constant_force_profile()
    material = get_material("ABS")
    drive = EndDrive("displacement", (-1.0, 0.0), 30.0, 15, "fixed", "fixed")
    settings = BeamSettings(n_elements=60, rtol=1e-11)
    model = BeamModel(profile, material, settings=settings)
    response = model.solve(drive)
    assert response.ok and not response.unstable
    sens = beam_sensitivities(model, drive, response, ("thickness",))
    keys = ("force_N", "ks_stress_MPa")
    rows = slice(1, None)  # row 0 is the undeformed state, before the onset
    for j in (0, 5, 11):  # T1, t5, T6: the clamped end, the middle, the slider end
        fd = _thickness_fd(profile, material, drive, settings, j, keys)
        err = _relative_error(_analytic(sens, keys, j)[rows], fd[rows])
        assert err.max() <= TOL, (j, dict(zip(keys, err, strict=True)))


def test_unstable_rows_of_a_strut_pushed_past_its_critical_shortening():
    """A perfect clamped-clamped strut shortened 3 x past its critical shortening stays straight
    (flagged unstable): its tangent is indefinite there, so the LU path solves, and the force is
    EA times the strain, so the thickness derivatives of a uniform strut sum to F / t exactly."""
    L, t, b = 50.0, 1.0, 8.0
    d_crit = 4.0 * np.pi**2 * t**2 / 12.0 / L
    profile = BeamProfile([[0.0, 0.0], [L, 0.0]], [t, t], b)
    drive = EndDrive("displacement", (-1.0, 0.0), 3.0 * d_crit, 6, "fixed", "fixed")
    model = BeamModel(profile, MAT, settings=TIGHT)
    response = model.solve(drive)
    assert response.unstable and not response.stable[-1]
    sens = beam_sensitivities(model, drive, response, ("thickness",))
    assert sens.counts["lu_rows"] == int((~response.stable).sum())
    total = sens.derivatives["force_N"].sum(axis=1)
    np.testing.assert_allclose(
        total, sens.values["force_N"] / t, rtol=0, atol=1e-9 * np.abs(response.force_N).max()
    )


def test_width_scales_the_force_exactly():
    """F is proportional to b under displacement control: dF/db = F/b, the end moment likewise,
    and the stresses do not depend on b."""
    profile = _tapered()
    model = BeamModel(profile, MAT, settings=TIGHT)
    drive = EndDrive("displacement", (0.0, 1.0), 60.0, 10, "fixed", "free")
    response = model.solve(drive)
    sens = beam_sensitivities(model, drive, response, ("width",))
    b = profile.width_mm
    for k in ("force_N", "moment_Nmm"):
        np.testing.assert_allclose(
            sens.derivatives[k][:, 0],
            sens.values[k] / b,
            rtol=0,
            atol=1e-10 * np.abs(sens.values[k]).max(),
        )
    scale = np.abs(sens.stress_MPa).max()
    assert np.abs(sens.derivatives["ks_stress_MPa"]).max() <= 1e-10 * scale
    assert np.abs(sens.d_fibre_stress).max() <= 1e-10 * scale


def test_polished_rows_are_the_solves_rows():
    """The states differentiated are the compiled solve's rows, to the solve's own accuracy: at
    its default tolerances (rtol = 1e-8 of the force scale, which includes the axial reactions)
    the driven force of this cantilever is within ~2e-7 of equilibrium's."""
    profile = _tapered()
    model = BeamModel(profile, MAT, settings=BeamSettings(n_elements=20))
    assert model.kernel in ("numba", "numpy")
    response = model.solve(CANTILEVER)
    sens = beam_sensitivities(model, CANTILEVER, response, ("thickness",))
    assert sens.force_mismatch <= 1e-6
    for k in ("transverse_displacement_mm", "end_rotation_rad", "peak_stress_MPa"):
        ref = getattr(response, k)
        assert np.abs(sens.values[k] - ref).max() <= 1e-6 * np.abs(ref).max(), k


def test_both_kernels_give_the_same_sensitivities():
    """The compiled and the numpy reference path trace the same rows (to round-off), so the
    derivatives from either agree."""
    profile = _tapered(points=((0.0, 0.0), (50.0, 4.0), (100.0, 0.0)))
    out = []
    for kernel in ("numba", "numpy"):
        settings = BeamSettings(n_elements=20, rtol=1e-11, kernel=kernel)
        model = BeamModel(profile, MAT, settings=settings)
        response = model.solve(CANTILEVER)
        out.append(beam_sensitivities(model, CANTILEVER, response, ("thickness", "coordinates")))
    for k in ("force_N", "end_rotation_rad", "ks_stress_MPa"):
        a, b = out[0].derivatives[k], out[1].derivatives[k]
        assert np.abs(a - b).max() <= 1e-9 * np.abs(b).max(), k


def test_sensitivities_cost_less_than_one_solve_per_variable():
    """Counted, not timed: per converged row one factorised tangent (after a few polishing
    iterations) and one back-substitution per variable, where finite differences would need one
    (forward) or two (central) solves per variable."""
    profile = _constant_force_profile()
    drive = EndDrive("displacement", (-1.0, 0.0), 30.0, 30, "fixed", "fixed")
    model = BeamModel(profile, get_material("ABS"), settings=BeamSettings(n_elements=60))
    response = model.solve(drive)
    sens = beam_sensitivities(model, drive, response, ("thickness", "width"))
    n_var = len(sens.variables)
    n_rows = int(response.converged.sum())
    solve_iterations = int(response.iterations.sum())  # one assembly + one solve each
    c = sens.counts
    assert n_var == 13
    assert c["back_substitutions"] == n_rows * n_var  # one per variable per row
    # polishing each row: a Newton correction and the final tangent (measured: 122 for the 61
    # rows, against the solve's 193 iterations); a few more would be tolerable
    assert c["assemblies"] == c["factorisations"] <= 5 * n_rows
    # all 13 variables together: fewer assemblies and factorisations than two solves, i.e. far
    # less than one solve per variable (forward differences) or two (central)
    assert c["assemblies"] < 2 * solve_iterations


def test_ks_aggregate_bounds_the_max():
    sigma = np.array([10.0, 30.0, 29.0, 5.0])
    for rho in (0.1, 1.0, 10.0):
        ks, w = ks_aggregate(sigma, rho)
        assert sigma.max() <= ks <= sigma.max() + np.log(sigma.size) / rho
        assert w.sum() == pytest.approx(1.0)
        h = 1e-6
        for j in range(sigma.size):
            d = np.zeros(sigma.size)
            d[j] = h
            fd = (ks_aggregate(sigma + d, rho)[0] - ks_aggregate(sigma - d, rho)[0]) / (2 * h)
            assert w[j] == pytest.approx(fd, rel=1e-6, abs=1e-8)


def test_vertex_moves_are_the_coordinates_projected():
    """A move (vertex velocities) is the directional derivative: the same as the coordinates'
    derivatives dotted with it, and only the moved vertex's neighbour elements are evaluated."""
    profile = _tapered(points=((0.0, 0.0), (50.0, 4.0), (100.0, 0.0)))
    model = BeamModel(profile, MAT, settings=TIGHT)
    response = model.solve(CANTILEVER)
    coords = beam_sensitivities(model, CANTILEVER, response, ("coordinates",))
    moves = np.zeros((2, 3, 2))
    moves[0, 1] = (3.0, -4.0)  # vertex 1 along (3, -4) mm per unit
    moves[1, 2] = (0.0, 2.0)  # vertex 2 up, 2 mm per unit
    sens = beam_sensitivities(
        model, CANTILEVER, response, ("moves",), vertex_moves=moves, move_names=("m1", "m2")
    )
    assert sens.variables == ("m1", "m2") and sens.counts["model_builds"] == 8
    for k in ("force_N", "end_rotation_rad", "ks_stress_MPa"):
        d = coords.derivatives[k]
        expected = np.stack([3.0 * d[:, 2] - 4.0 * d[:, 3], 2.0 * d[:, 5]], axis=1)
        np.testing.assert_allclose(
            sens.derivatives[k], expected, rtol=0, atol=1e-8 * np.abs(expected).max()
        )


@pytest.mark.parametrize("stress", ["sampled", "statics"])
@pytest.mark.parametrize("kernel", ["numba", "numpy"])
def test_batched_rows_are_the_reference_loop(stress, kernel):
    """The batched pass over the rows (the default; with the compiled statics kernel where the
    model runs the compiled kernel) gives the reference loop's numbers, one row at a time, to
    1e-10 of each array's largest entry: every value, derivative and fibre stress, on the
    constant-force beam (arcs: no; a buckled, unstable-free path) with thicknesses, the width and
    two vertex moves, differentiating a subset of the rows."""
    profile = _constant_force_profile()
    drive = EndDrive("displacement", (-1.0, 0.0), 30.0, 30, "fixed", "fixed")
    settings = BeamSettings(n_elements=60, kernel=kernel)
    model = BeamModel(profile, get_material("ABS"), settings=settings)
    response = model.solve(drive)
    assert response.ok
    moves = np.zeros((2, profile.n_points, 2))
    moves[0, 2] = (1.0, 0.5)
    moves[1, 4] = (-0.3, 1.0)
    rows = np.arange(1, len(response.force_N), 3)
    out = [
        beam_sensitivities(
            model,
            drive,
            response,
            ("thickness", "width", "moves"),
            vertex_moves=moves,
            rows=rows,
            stress=stress,
            batched=batched,
        )
        for batched in (True, False)
    ]
    fast, ref = out
    assert fast.variables == ref.variables
    pairs = [
        (fast.fibre_stress_MPa, ref.fibre_stress_MPa),
        (fast.d_fibre_stress, ref.d_fibre_stress),
    ]
    pairs += [(fast.values[k], ref.values[k]) for k in ref.values]
    pairs += [(fast.derivatives[k], ref.derivatives[k]) for k in ref.derivatives]
    for a, b in pairs:
        assert np.array_equal(np.isnan(a), np.isnan(b))
        done = np.isfinite(b)
        assert done.any()
        np.testing.assert_allclose(a[done], b[done], rtol=0, atol=1e-10 * np.abs(b[done]).max())
    assert fast.counts == ref.counts


def test_perturbed_tables_are_the_models():
    """The element tables of a moved profile, computed without building its model
    (:func:`fea.beam_sensitivity._perturbed_tables`), are bit for bit those of the model
    built from it: straight and arc segments, on the elements either side of the moved vertex;
    a move that changes the mesh answers None."""
    from flexopt.fea.beam_sensitivity import _perturbed_tables, _segment_of_elements

    profile = BeamProfile(
        [[0.0, 0.0], [40.0, 0.0], [80.0, 10.0], [120.0, 5.0]],
        [1.2, 1.0, 0.8, 0.9],
        3.0,
        curvature_per_mm=[0.01, -0.005, 0.0],
    )
    model = BeamModel(profile, MAT, settings=BeamSettings(n_elements=23))
    seg = _segment_of_elements(model)
    for vertex, step in ((1, (1e-4, -2e-4)), (2, (-3e-5, 1e-5)), (3, (2e-4, 0.0))):
        pts = np.array(profile.points_mm)
        pts[vertex] += step
        moved = BeamProfile(pts, profile.thickness_mm, 3.0, profile.curvature_per_mm)
        els = np.flatnonzero(np.isin(seg, (vertex - 1, vertex)))
        tables = _perturbed_tables(model, moved, els, seg)
        built = BeamModel(moved, MAT, settings=model.settings)
        own = built.tables
        for key in ("dN", "w", "theta0", "cos_theta0", "sin_theta0", "EA", "kGA", "EI"):
            assert np.array_equal(tables[key], getattr(own, key)[els]), key
        assert np.array_equal(tables["dN_samples"], own.dN_samples[els])
        ratio = (own.EI_samples / own.section_modulus_samples)[els]
        assert np.array_equal(tables["ratio"], ratio)
        xref = built.reference_nodes_mm[2 * els[:, None] + np.arange(3)]
        assert np.array_equal(tables["xref"], xref)
    pts = np.array(profile.points_mm)
    pts[1, 0] += 6.0  # 40 -> 46 mm: the first segments get another element count
    moved = BeamProfile(pts, profile.thickness_mm, 3.0, profile.curvature_per_mm)
    assert _perturbed_tables(model, moved, np.arange(3), seg) is None


def test_compiled_thickness_terms_are_the_reference():
    """The compiled thickness terms (fea/_sensitivity_kernels.py ``thickness_terms``, which
    visits only the vertices whose hats are nonzero on each element and assembles in place)
    equal the numpy reference (:func:`_thickness_terms_rows` assembled) to round-off, on an
    arc-and-kink profile turned through large rotations, with the end node's rows in an oblique
    drive's axes, added into a column block of a wider array."""
    from flexopt.fea.beam_sensitivity import (
        _compiled_thickness,
        _frame,
        _thickness_columns,
        _Twin,
    )

    profile = BeamProfile(
        [[0.0, 0.0], [40.0, 0.0], [80.0, 10.0], [120.0, 5.0]],
        [1.2, 1.0, 0.8, 0.9],
        3.0,
        curvature_per_mm=[0.01, -0.005, 0.0],
    )
    drive = EndDrive("displacement", (0.6, 0.8), 30.0, 6, "free", "free")
    model = BeamModel(profile, MAT, settings=BeamSettings(n_elements=23))
    response = model.solve(drive)
    assert response.ok
    twin = _Twin(model)
    frame = _frame(drive)
    rng = np.random.default_rng(5)
    U = 0.3 * rng.standard_normal((4, model.n_dofs))  # any states: the terms are explicit
    ref_dR, ref_dc = _thickness_columns(twin, U, frame)
    n_pts = profile.n_points
    dR = np.zeros((4, model.n_dofs, n_pts + 3))
    dc = np.zeros((4, model.n_elements, 3, n_pts + 3))
    _compiled_thickness(twin, U, frame, 2, dR, dc)
    assert np.abs(ref_dR).max() > 0 and np.abs(ref_dc).max() > 0
    np.testing.assert_allclose(
        dR[..., 2 : 2 + n_pts], ref_dR, rtol=0, atol=1e-13 * np.abs(ref_dR).max()
    )
    np.testing.assert_allclose(
        dc[..., 2 : 2 + n_pts], ref_dc, rtol=0, atol=1e-13 * np.abs(ref_dc).max()
    )
    for other in (dR[..., :2], dR[..., 2 + n_pts :], dc[..., :2], dc[..., 2 + n_pts :]):
        assert not other.any()


def test_perturbed_tables_of_many_copies_are_each_copys():
    """The tables of many moved copies at once (:func:`_perturbed_tables_many`, what
    :class:`_CoordinateBatch` builds its virtual elements from) are bit for bit those of each
    copy on its own (:func:`_perturbed_tables`), copy by copy in order, on straight and arc
    segments; a copy that changes the mesh is named."""
    from flexopt.fea.beam_sensitivity import (
        _perturbed_tables,
        _perturbed_tables_many,
        _segment_of_elements,
    )

    profile = BeamProfile(
        [[0.0, 0.0], [40.0, 0.0], [80.0, 10.0], [120.0, 5.0]],
        [1.2, 1.0, 0.8, 0.9],
        3.0,
        curvature_per_mm=[0.01, -0.005, 0.0],
    )
    model = BeamModel(profile, MAT, settings=BeamSettings(n_elements=23))
    seg = _segment_of_elements(model)
    copies, els_of = [], []
    for vertex, step in ((1, (1e-4, -2e-4)), (2, (-3e-5, 1e-5)), (3, (2e-4, 0.0)), (0, (0, 1e-4))):
        for sign in (1.0, -1.0, 2.0):
            pts = np.array(profile.points_mm)
            pts[vertex] += sign * np.array(step)
            copies.append(pts)
            els_of.append(np.flatnonzero(np.isin(seg, (vertex - 1, vertex))))
    many, bad = _perturbed_tables_many(model, profile, np.array(copies), els_of, seg)
    assert bad == -1
    one = [
        _perturbed_tables(
            model, BeamProfile(p, profile.thickness_mm, 3.0, profile.curvature_per_mm), e, seg
        )
        for p, e in zip(copies, els_of, strict=True)
    ]
    for key in many:
        assert np.array_equal(many[key], np.concatenate([o[key] for o in one])), key
    far = np.array(copies)
    far[2, 1, 0] += 6.0  # 40 -> 46 mm: the first segments get another element count
    assert _perturbed_tables_many(model, profile, far, els_of, seg) == (None, 2)
