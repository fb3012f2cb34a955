"""Plane-stress FE against exact solutions computed here: beams, a twisted annulus, the elastica."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import (
    Clamp,
    PlaneStressSettings,
    Rotate,
    Translate,
    plane_stress_lame,
    solve_plane_stress,
)
from scipy.integrate import quad
from scipy.optimize import brentq
from shapely.geometry import LineString, Point, Polygon, box

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)


def strip(L: float, h: float):
    """A strip along x from 0 to L, y in [0, h], with its end faces as clamp and drive lines."""
    return box(0.0, 0.0, L, h), LineString([(0, 0), (0, h)]), LineString([(L, 0), (L, h)])


def guided_timoshenko_stiffness(L: float, h: float, b: float, mat: Material) -> float:
    """Transverse stiffness of a clamped-guided beam (both ends held against rotation), N/mm.

    Bending: the guided beam is two cantilevers of length L/2 in series, d = P L^3 / (12 E I).
    Shear: the shear force is P all along, d = P L / (k G A) with k = 5/6 for a rectangle.
    Plane stress, so the beam modulus is E (not E / (1 - nu^2)).
    """
    I = b * h**3 / 12.0
    A = b * h
    return 1.0 / (L**3 / (12.0 * mat.E_MPa * I) + L / (5.0 / 6.0 * mat.G_MPa * A))


def guided_elastica_force(delta: float, L: float, EI: float) -> float:
    """Exact inextensible elastica: transverse force of a guided beam pushed sideways by delta.

    The axial motion of the guided end is free, so the beam carries a transverse force P only
    and is two cantilevers of length l = L/2 meeting at the inflection point. In each, with theta
    the slope and theta0 its value at the inflection point, EI theta'' = -P cos(theta) integrates
    to (EI / 2) theta'^2 = P (sin theta0 - sin theta), so with c = sqrt(EI / (2 P))

        l = c * int_0^theta0 dtheta / sqrt(sin theta0 - sin theta)
        y = c * int_0^theta0 sin(theta) dtheta / sqrt(sin theta0 - sin theta)

    and delta = 2 y. Both integrands are (theta0 - theta)^(-1/2) times a smooth function, which
    quad integrates exactly with the algebraic weight.
    """

    def smooth(t0: float):
        def g(t: float) -> float:
            gap = np.sin(t0) - np.sin(t)
            return np.sqrt((t0 - t) / gap) if gap > 0 else 1.0 / np.sqrt(np.cos(t0))

        return g

    def integrals(t0: float) -> tuple[float, float]:
        g = smooth(t0)
        i1 = quad(g, 0.0, t0, weight="alg", wvar=(0.0, -0.5), epsabs=0, epsrel=1e-12)[0]
        i2 = quad(
            lambda t: np.sin(t) * g(t),
            0.0,
            t0,
            weight="alg",
            wvar=(0.0, -0.5),
            epsabs=0,
            epsrel=1e-12,
        )[0]
        return i1, i2

    def deflection(t0: float) -> float:
        i1, i2 = integrals(t0)
        return 2.0 * (L / 2.0) * i2 / i1  # c = l / i1

    t0 = brentq(lambda t: deflection(t) - delta, 1e-8, 1.5, xtol=1e-14)
    i1, _ = integrals(t0)
    return 2.0 * EI * i1**2 / L**2  # P = EI i1^2 / (2 l^2)


# ---- (a) slender strip against Timoshenko beam theory ---------------------------------------


def test_guided_strip_matches_timoshenko_and_converges():
    L, h, b, delta = 50.0, 2.0, 3.0, 0.05
    poly, left, right = strip(L, h)
    k_exact = guided_timoshenko_stiffness(L, h, b, MAT)
    stiffness = []
    for size in (1.0, 0.5, 0.25):
        res = solve_plane_stress(
            mesh_polygon(poly, size), MAT, b, Clamp(left),
            Translate(right, direction=(0.0, 1.0), max_mm=delta, steps=1), kinematics="linear",
        )  # fmt: skip
        assert res.ok, res.message
        stiffness.append(res.force_N[-1] / delta)
        # Equilibrium: what the clamp takes is what the pad gives, and the pad holds the guided
        # end level with the end moment P L / 2 (clockwise when pushing up).
        np.testing.assert_allclose(res.clamp_reaction_N[-1], -res.reaction_N[-1], atol=1e-9)
        assert res.torque_Nmm[-1] == pytest.approx(-res.force_N[-1] * L / 2.0, rel=2e-3)
    err = np.abs(np.array(stiffness) / k_exact - 1.0)
    # The 2D solution differs from Timoshenko only by end effects at the rigid clamps (O(h/L)^2).
    assert err[-1] < 5e-3, err
    # Mesh convergence: successive differences shrink (P2: O(size^2) in energy).
    d1, d2 = abs(stiffness[0] - stiffness[1]), abs(stiffness[1] - stiffness[2])
    assert d2 < 0.5 * d1, (d1, d2)


def test_bending_stress_away_from_clamps_matches_beam_theory():
    L, h, b, delta = 50.0, 2.0, 3.0, 0.05
    poly, left, right = strip(L, h)
    x0 = 2.0 * h  # skip the pads: clamp corners are stress singularities of 2D elasticity
    ignore = box(-1, -1, x0, h + 1).union(box(L - x0, -1, L + 1, h + 1))
    res = solve_plane_stress(
        mesh_polygon(poly, 0.5), MAT, b, Clamp(left),
        Translate(right, direction=(0.0, 1.0), max_mm=delta, steps=1), kinematics="linear",
        stress_ignore=ignore,
    )  # fmt: skip
    P = res.force_N[-1]

    def beam_stress(x: float) -> float:
        """Guided beam: M(x) = P (L/2 - x) (antisymmetric); sigma = M c / I at the surface."""
        return abs(P * (L / 2.0 - x)) * (h / 2.0) / (b * h**3 / 12.0)

    # The peak sits on a surface, next to the ignored pads where |M| is largest.
    x, y = res.peak_nodal_stress_xy_mm[-1]
    assert y in (0.0, h)
    assert min(abs(x - x0), abs(x - (L - x0))) < 1.0
    assert res.peak_nodal_stress_MPa[-1] == pytest.approx(beam_stress(x), rel=1e-2)
    # Quadrature points sit inside the elements, below the surface value.
    assert 0.85 * beam_stress(x0) < res.peak_stress_MPa[-1] < beam_stress(x0)


# ---- (b) annulus in torsion: exact plane-stress shear solution ------------------------------


def annulus_torque(a: float, c: float, b: float, mu: float, theta: float) -> float:
    """Torque to turn the hub r = a by a small theta inside a clamped rim r = c, N*mm.

    Axisymmetric torsion is pure shear, u_theta(r) = A r + B / r (A r is rigid rotation) with
    tau(r) = mu (du/dr - u/r) = -2 mu B / r^2. u(c) = 0 and u(a) = theta a give
    B = theta a^2 c^2 / (c^2 - a^2), and
    T = |tau| 2 pi r^2 b = 4 pi mu b theta a^2 c^2 / (c^2 - a^2),
    independent of r (equilibrium) and of nu.
    """
    return 4.0 * np.pi * mu * b * theta * a**2 * c**2 / (c**2 - a**2)


def annulus(a: float, c: float, quad_segs: int = 64) -> Polygon:
    return (
        Point(0, 0)
        .buffer(c, quad_segs=quad_segs)
        .difference(Point(0, 0).buffer(a, quad_segs=quad_segs))
    )


def equivalent_radius(ring) -> float:
    """Radius of the circle with the polygonal ring's area (the exact formula needs circles)."""
    return float(np.sqrt(Polygon(ring).area / np.pi))


# P1 is stiffer (about 1 % here); P2 is near exact on this mesh.
@pytest.mark.parametrize("element, rtol", [("P2", 2e-4), ("P1", 2e-2)])
def test_annulus_torsion_matches_exact_torque_and_shear(element, rtol):
    a, c, b, theta = 3.0, 8.0, 2.0, 1e-3
    ring = annulus(a, c)
    res = solve_plane_stress(
        mesh_polygon(ring, 1.0), MAT, b, Clamp(ring.exterior),
        Rotate(ring.interiors[0], centre_mm=(0.0, 0.0), max_rad=theta, steps=1),
        kinematics="linear", settings=PlaneStressSettings(element=element),
    )  # fmt: skip
    assert res.ok, res.message
    ae, ce = equivalent_radius(ring.interiors[0]), equivalent_radius(ring.exterior)
    T = annulus_torque(ae, ce, b, MAT.G_MPa, theta)
    assert res.torque_Nmm[-1] == pytest.approx(T, rel=rtol)
    # Pure torsion: no net force on the hub.
    assert np.linalg.norm(res.reaction_N[-1]) < 1e-3 * T / a
    if element == "P2":
        # Pure shear at the hub, tau(a) = T / (2 pi a^2 b); von Mises = sqrt(3) tau.
        vm = np.sqrt(3.0) * T / (2.0 * np.pi * a**2 * b)
        assert res.peak_nodal_stress_MPa[-1] == pytest.approx(vm, rel=2e-3)
        assert np.hypot(*res.peak_nodal_stress_xy_mm[-1]) == pytest.approx(a, rel=1e-2)


# ---- (c) geometric nonlinearity ------------------------------------------------------------


def test_nonlinear_equals_linear_at_small_load():
    a, c, b = 3.0, 8.0, 2.0
    ring = annulus(a, c, quad_segs=16)
    mesh = mesh_polygon(ring, 1.0)
    kw = dict(clamp=Clamp(ring.exterior), drive=Rotate(ring.interiors[0], (0, 0), 1e-4, 1))
    lin = solve_plane_stress(mesh, MAT, b, kinematics="linear", **kw)
    nl = solve_plane_stress(mesh, MAT, b, kinematics="nonlinear", **kw)
    assert nl.ok and lin.ok
    assert nl.torque_Nmm[-1] == pytest.approx(lin.torque_Nmm[-1], rel=1e-3)
    assert nl.peak_stress_MPa[-1] == pytest.approx(lin.peak_stress_MPa[-1], rel=1e-3)

    L, h = 50.0, 1.0
    poly, left, right = strip(L, h)
    mesh = mesh_polygon(poly, 0.5)
    drive = Translate(right, direction=(0.0, 1.0), max_mm=1e-3, steps=1, transverse="free")
    lin = solve_plane_stress(mesh, MAT, 3.0, Clamp(left), drive, kinematics="linear")
    nl = solve_plane_stress(mesh, MAT, 3.0, Clamp(left), drive, kinematics="nonlinear")
    assert nl.force_N[-1] == pytest.approx(lin.force_N[-1], rel=1e-3)


def test_large_deflection_matches_exact_elastica():
    L, h, b = 50.0, 1.0, 3.0
    poly, left, right = strip(L, h)
    mesh = mesh_polygon(poly, 0.5)
    # Guided end pushed sideways up to 0.4 L, sliding freely along the beam axis.
    drive = Translate(right, direction=(0.0, 1.0), max_mm=20.0, steps=4, transverse="free")
    nl = solve_plane_stress(mesh, MAT, b, Clamp(left), drive, kinematics="nonlinear")
    lin = solve_plane_stress(mesh, MAT, b, Clamp(left), drive, kinematics="linear")
    assert nl.ok, nl.message
    EI = MAT.E_MPa * b * h**3 / 12.0
    exact = np.array([guided_elastica_force(d, L, EI) for d in nl.displacement_mm[1:]])
    # Beyond the elastica the 2D model has shear and axial strain: both O((h/L)^2) here.
    np.testing.assert_allclose(nl.force_N[1:], exact, rtol=3e-3)
    assert abs(lin.force_N[-1] / exact[-1] - 1.0) > 0.1  # linear theory is 17 % off at 0.4 L
    # The free end slides towards the clamp (foreshortening) and carries no axial force.
    assert nl.transverse_displacement_mm[-1] > 1.0
    assert np.all(np.abs(nl.transverse_force_N) < 1e-6 * np.abs(nl.force_N).max())
    assert np.all(nl.iterations[1:] <= 10)


def test_rigid_rotation_of_the_whole_part_is_stress_free():
    # Frame indifference of the total Lagrangian model: a large rigid rotation about the clamp
    # point with nothing else held must cost no force. Clamping a single point and rotating the
    # rest about it is such a motion.
    poly = box(0.0, 0.0, 10.0, 2.0)
    mesh = mesh_polygon(poly, 1.0)
    res = solve_plane_stress(
        mesh, MAT, 1.0, Clamp(Point(0.0, 0.0)),
        Rotate(poly.exterior.difference(Point(0.0, 0.0).buffer(1e-3)), (0.0, 0.0), 1.0, 2),
    )  # fmt: skip
    assert res.ok, res.message
    assert np.abs(res.torque_Nmm).max() < 1e-9
    assert np.nanmax(res.peak_stress_MPa) < 1e-9


# ---- failure as data, and input errors ------------------------------------------------------


def test_non_convergence_is_returned_not_raised():
    ring = annulus(3.0, 8.0, quad_segs=4)
    res = solve_plane_stress(
        mesh_polygon(ring, 2.0), MAT, 1.0, Clamp(ring.exterior),
        Rotate(ring.interiors[0], (0.0, 0.0), 3.0, steps=2),
        settings=PlaneStressSettings(max_cutbacks=2),
    )  # fmt: skip
    assert not res.ok
    assert res.converged[0] and not res.converged[-1]
    assert "failed" in res.message
    assert np.isnan(res.torque_Nmm[-1])


def test_bad_inputs_raise_fea_error():
    poly, left, right = strip(10.0, 1.0)
    mesh = mesh_polygon(poly, 0.5)
    with pytest.raises(FeaError, match="selects no mesh node"):
        solve_plane_stress(mesh, MAT, 1.0, Clamp(Point(50.0, 50.0)), Translate(right))
    with pytest.raises(FeaError, match="both clamped and driven"):
        solve_plane_stress(mesh, MAT, 1.0, Clamp(poly), Translate(right))
    with pytest.raises(FeaError, match="thickness_mm"):
        solve_plane_stress(mesh, MAT, 0.0, Clamp(left), Translate(right))


def test_plane_stress_lame():
    lam, mu = plane_stress_lame(MAT.E_MPa, MAT.nu)
    assert mu == pytest.approx(MAT.G_MPa)
    # Uniaxial stress: E = 4 mu (lam* + mu) / (lam* + 2 mu) in plane stress.
    assert 4.0 * mu * (lam + mu) / (lam + 2.0 * mu) == pytest.approx(MAT.E_MPa)


# ---- the fast paths agree with the reference ------------------------------------------------


def test_vectorised_assembly_and_krylov_solver_match_the_skfem_reference():
    # A twisted, non-symmetric outline at a large rotation exercises the geometric terms.
    poly = annulus(3.0, 8.0, quad_segs=16).difference(box(5.0, -0.5, 9.0, 0.5))
    mesh = mesh_polygon(poly, 1.0)
    inner = poly.interiors[0] if poly.interiors else Point(0, 0).buffer(3.0).exterior
    kw = dict(clamp=Clamp(Point(-8.0, 0.0).buffer(1.0)), drive=Rotate(inner, (0, 0), 0.15, 2))
    ref = solve_plane_stress(mesh, MAT, 2.0, settings=PlaneStressSettings(assembly="skfem"), **kw)
    fast = solve_plane_stress(mesh, MAT, 2.0, **kw)
    cg = solve_plane_stress(mesh, MAT, 2.0, settings=PlaneStressSettings(solver="krylov"), **kw)
    assert ref.ok and fast.ok and cg.ok
    np.testing.assert_allclose(fast.torque_Nmm, ref.torque_Nmm, rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(cg.torque_Nmm, ref.torque_Nmm, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(fast.peak_nodal_stress_MPa, ref.peak_nodal_stress_MPa, rtol=1e-8)
    for kin in ("linear",):
        a = solve_plane_stress(mesh, MAT, 2.0, kinematics=kin, **kw)
        b = solve_plane_stress(
            mesh, MAT, 2.0, kinematics=kin, settings=PlaneStressSettings(assembly="skfem"), **kw
        )
        np.testing.assert_allclose(a.torque_Nmm, b.torque_Nmm, rtol=1e-10, atol=1e-9)


# ---- the Cholesky path, the compiled assembly and the SuperLU fallback (issue 13) ------------

try:
    import cvxopt  # noqa: F401

    HAS_CHOLMOD = True
except ImportError:
    HAS_CHOLMOD = False
needs_cholmod = pytest.mark.skipif(not HAS_CHOLMOD, reason="cvxopt (CHOLMOD) not installed")


def twisted_ring():
    """The outline and drive of the reference test above: a slit ring turned by 0.15 rad."""
    poly = annulus(3.0, 8.0, quad_segs=16).difference(box(5.0, -0.5, 9.0, 0.5))
    inner = poly.interiors[0] if poly.interiors else Point(0, 0).buffer(3.0).exterior
    kw = dict(clamp=Clamp(Point(-8.0, 0.0).buffer(1.0)), drive=Rotate(inner, (0, 0), 0.15, 2))
    return mesh_polygon(poly, 1.0), kw


@needs_cholmod
@pytest.mark.parametrize("kinematics", ["linear", "nonlinear"])
def test_cholesky_and_superlu_paths_agree(kinematics):
    mesh, kw = twisted_ring()
    runs = {
        solver: solve_plane_stress(
            mesh,
            MAT,
            2.0,
            kinematics=kinematics,
            settings=PlaneStressSettings(solver=solver, assembly="vectorised"),
            **kw,
        )  # fmt: skip
        for solver in ("cholmod", "direct")
    }
    chol, lu = runs["cholmod"], runs["direct"]
    assert chol.ok and lu.ok
    assert chol.extra["solver"] == "cholmod" and lu.extra["solver"] == "direct"
    assert chol.extra["cholesky_failures"] == 0  # positive definite all the way
    scale = np.abs(lu.dofs).max()
    np.testing.assert_allclose(chol.dofs, lu.dofs, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(chol.torque_Nmm, lu.torque_Nmm, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(chol.iterations, lu.iterations)


def test_compiled_assembly_matches_the_numpy_one():
    from flexopt.fea.plane_stress import PlaneStressModel, _compiled

    if _compiled() is None:
        pytest.skip("numba not importable")
    mesh, kw = twisted_ring()
    models = {
        a: PlaneStressModel(mesh, MAT, 2.0, settings=PlaneStressSettings(assembly=a), **kw)
        for a in ("compiled", "vectorised")
    }
    u = solve_plane_stress(mesh, MAT, 2.0, **kw).dofs  # a state with 0.15 rad of twist
    for kin in ("linear", "nonlinear"):
        c, v = (models[a].state(u, kin) for a in ("compiled", "vectorised"))
        np.testing.assert_allclose(c.f, v.f, rtol=0, atol=1e-12 * np.abs(v.f).max())
        np.testing.assert_array_equal(c.K.indices, v.K.indices)
        np.testing.assert_allclose(c.K.data, v.K.data, rtol=0, atol=1e-12 * np.abs(v.K.data).max())
        assert c.min_det_F == pytest.approx(v.min_det_F, rel=1e-12)
        Kc, Kv = (models[a]._reduced(K) for a, K in (("compiled", c.K), ("vectorised", v.K)))
        np.testing.assert_allclose(
            Kc.toarray(), Kv.toarray(), rtol=0, atol=1e-12 * np.abs(v.K.data).max()
        )


@needs_cholmod
def test_indefinite_tangent_falls_back_to_lu():
    # A clamped-clamped strut squeezed to 4.5x its Euler load (4 pi^2 EI / L^2 = 2.6 N): the
    # straight state is an equilibrium, but an unstable one, and its tangent is indefinite.
    # Cholesky stops there; SuperLU solves those systems, and the path is the same.
    L, h = 50.0, 1.0
    mesh = mesh_polygon(box(0.0, 0.0, L, h), 0.5)
    clamp = Clamp(LineString([(0, 0), (0, h)]))
    drive = Translate(LineString([(L, 0), (L, h)]), direction=(-1.0, 0.0), max_mm=0.3, steps=3)
    runs = {
        s: solve_plane_stress(mesh, MAT, 1.0, clamp, drive, settings=PlaneStressSettings(solver=s))
        for s in ("cholmod", "direct")
    }
    chol, lu = runs["cholmod"], runs["direct"]
    assert chol.ok and lu.ok, (chol.message, lu.message)
    assert chol.extra["cholesky_failures"] > 0  # the stability signal
    assert chol.force_N[1] > 4 * np.pi**2 * MAT.E_MPa * h**3 / 12.0 / L**2
    np.testing.assert_allclose(chol.force_N, lu.force_N, rtol=1e-9)
    np.testing.assert_array_equal(chol.iterations, lu.iterations)

    # And one indefinite system on its own: the answer is LU's, the failure counted.
    from flexopt.fea.plane_stress import PlaneStressModel
    from scipy.sparse.linalg import splu

    model = PlaneStressModel(mesh, MAT, 1.0, clamp, drive, PlaneStressSettings(solver="cholmod"))
    K = model.state(np.zeros(model.n_dofs), "linear").K
    shift = 0.01 * K.diagonal().mean()
    K_indef = (K - shift * sp.identity(K.shape[0], format="csr")).tocsr()
    K_indef.sort_indices()
    rhs = np.random.default_rng(0).standard_normal(model.free.size)
    x = model._reduced_solve(K_indef, rhs)
    Kr = model._reduced(K_indef)
    np.testing.assert_allclose(x, splu(Kr.tocsc()).solve(rhs), rtol=1e-9, atol=1e-12)
    assert model.counters["cholesky_failures"] == 1


def test_solver_and_assembly_picked_by_settings_and_environment(monkeypatch):
    from flexopt.fea.plane_stress import PlaneStressModel

    mesh = mesh_polygon(box(0.0, 0.0, 10.0, 1.0), 0.5)
    kw = dict(
        clamp=Clamp(LineString([(0, 0), (0, 1)])), drive=Translate(LineString([(10, 0), (10, 1)]))
    )
    monkeypatch.setenv("FLEXOPT_PLANE_STRESS_SOLVER", "direct")
    monkeypatch.setenv("FLEXOPT_PLANE_STRESS_ASSEMBLY", "vectorised")
    m = PlaneStressModel(mesh, MAT, 1.0, **kw)
    assert (m.solver, m.assembly) == ("direct", "vectorised")
    m = PlaneStressModel(mesh, MAT, 1.0, settings=PlaneStressSettings(solver="krylov"), **kw)
    assert m.solver == "krylov"  # an explicit setting wins over the environment
    monkeypatch.setenv("FLEXOPT_PLANE_STRESS_SOLVER", "superlu")
    with pytest.raises(FeaError, match="FLEXOPT_PLANE_STRESS_SOLVER"):
        PlaneStressModel(mesh, MAT, 1.0, **kw)
    monkeypatch.delenv("FLEXOPT_PLANE_STRESS_SOLVER")
    monkeypatch.delenv("FLEXOPT_PLANE_STRESS_ASSEMBLY")
    m = PlaneStressModel(mesh, MAT, 1.0, **kw)
    assert m.solver == ("cholmod" if HAS_CHOLMOD else m.solver)
