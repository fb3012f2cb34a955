"""The fast paths of fea.fidelity.plane_stress_check: the model's own factoriser (CHOLMOD with a
SuperLU stand-in, or SuperLU alone), the shift-invert eigenvalue on that factor, and the beam's
shape carried onto the mesh with the nodes located once.

References are computed here: dense eigenvalues of the same reduced tangent, a rigid motion of a
straight beam, and the same check run through the SuperLU-only solver path.
"""

import numpy as np
import pytest
from flexopt.fea import fidelity
from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import (
    SOLVER_ENV,
    Clamp,
    PlaneStressModel,
    PlaneStressSettings,
    Translate,
)
from flexopt.geometry.profile import BeamProfile
from shapely.geometry import box

MATERIAL = Material("ABS-like", E_MPa=1800.0, nu=0.35, yield_MPa=42.5)
LENGTH_MM, THICK_MM, WIDTH_MM = 30.0, 1.2, 5.0
PAD_LENGTH_MM, PAD_THICK_MM = 3.0, 3.0


def _cholmod_available() -> bool:
    try:
        import cvxopt  # noqa: F401
    except ImportError:
        return False
    return True


SOLVERS = ["direct"] + (["cholmod"] if _cholmod_available() else [])


def _strip_model(solver: str) -> PlaneStressModel:
    """A 20 x 1 mm strip, left end clamped, right end driven along -x (a column), ~600 DOFs."""
    length, thick = 20.0, 1.0
    return PlaneStressModel(
        mesh_polygon(box(0.0, 0.0, length, thick), 0.8),
        MATERIAL,
        WIDTH_MM,
        Clamp(box(-0.01, -0.01, 0.01, thick + 0.01)),
        Translate(box(length - 0.01, -0.01, length + 0.01, thick + 0.01), (-1.0, 0.0)),
        PlaneStressSettings(solver=solver),
    )


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("strain", [0.0, 0.05])
def test_eigenvalue_nearest_zero_matches_dense_eigenvalues(solver, strain):
    # strain 0: the linear stiffness, positive definite. 5 % uniform shortening is ~6x the
    # clamped column's Euler strain pi^2 (h/L)^2 / 3: the tangent there is indefinite, Cholesky
    # fails and the SuperLU stand-in is the shift-invert operator.
    model = _strip_model(solver)
    u = np.zeros(model.n_dofs)
    u[model.ix] = -strain * model.xy[:, 0]
    K = model.state(u, "nonlinear").K
    dense = np.linalg.eigvalsh(model._reduced(K).toarray())
    nearest = dense[np.argmin(np.abs(dense))]
    assert (dense < 0).any() == (strain > 0)  # the two cases are what they claim to be
    eig = fidelity._eigenvalue_nearest_zero(model, K)
    assert eig == pytest.approx(nearest, rel=1e-8, abs=1e-10 * np.abs(dense).max())
    if solver == "cholmod":
        assert model.counters["cholesky_failures"] == (1 if strain > 0 else 0)
    # a function of K alone: the same bits on a second call (ARPACK's own start vector ran on
    # between calls, so the last digits moved before session 31)
    assert all(fidelity._eigenvalue_nearest_zero(model, K) == eig for _ in range(3))


def test_beam_shape_carried_onto_the_mesh_under_a_rigid_motion():
    # A rigid rotation and translation of a straight beam moves every point beside it rigidly.
    profile = BeamProfile(np.array([[0.0, 0.0], [LENGTH_MM, 0.0]]), np.full(2, THICK_MM), WIDTH_MM)
    beam = BeamModel(profile, MATERIAL, settings=BeamSettings(n_elements=10))
    angle, shift = 0.4, np.array([1.5, -2.0])
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    shape = beam.reference_nodes_mm @ rot.T + shift
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(0.5, LENGTH_MM - 0.5, 50), rng.uniform(-0.6, 0.6, 50)])
    moved = fidelity.beam_to_mesh(beam, shape, points)
    np.testing.assert_allclose(moved, points @ rot.T + shift - points, atol=1e-9)
    s, eta = fidelity._locate(beam, points)
    np.testing.assert_allclose(s, points[:, 0], atol=1e-12)
    np.testing.assert_allclose(eta, points[:, 1], atol=1e-12)


@pytest.fixture(scope="module")
def fixed_guided():
    """A straight fixed-guided beam pushed 3 mm sideways, its outline with pads, its response."""
    profile = BeamProfile(np.array([[0.0, 0.0], [LENGTH_MM, 0.0]]), np.full(2, THICK_MM), WIDTH_MM)
    beam = BeamModel(profile, MATERIAL, settings=BeamSettings(n_elements=20))
    response = beam.solve(EndDrive("displacement", (0.0, 1.0), 3.0, 3, "fixed", "fixed"))
    half = 0.5 * PAD_THICK_MM
    shape = (
        box(0.0, -0.5 * THICK_MM, LENGTH_MM, 0.5 * THICK_MM)
        .union(box(-PAD_LENGTH_MM, -half, 0.0, half))
        .union(box(LENGTH_MM, -half, LENGTH_MM + PAD_LENGTH_MM, half))
    )
    return beam, shape, response


def _check(fixed_guided, monkeypatch, solver):
    beam, shape, response = fixed_guided
    monkeypatch.setenv(SOLVER_ENV, solver)
    return fidelity.plane_stress_check(
        beam, shape, MATERIAL, WIDTH_MM, PAD_LENGTH_MM, PAD_THICK_MM, (0.0, 1.0), response,
        np.array([1, 3]), 3.0, 0.6,
    )  # fmt: skip


@pytest.mark.skipif(len(SOLVERS) < 2, reason="needs cvxopt for the CHOLMOD path")
def test_check_is_the_same_through_cholmod_and_superlu(fixed_guided, monkeypatch):
    lu = _check(fixed_guided, monkeypatch, "direct")
    chol = _check(fixed_guided, monkeypatch, "cholmod")
    assert "skipped" not in lu and "skipped" not in chol, (lu, chol)
    assert all(lu["converged"]) and all(chol["converged"])
    assert chol["newton_iterations"] == lu["newton_iterations"]
    assert chol["stable"] == lu["stable"] == [True, True]
    for key in ("plane_stress_force_N", "plane_stress_transverse_force_N", "max_shape_change_mm"):
        np.testing.assert_allclose(chol[key], lu[key], rtol=1e-7, err_msg=key)
    np.testing.assert_allclose(
        chol["plane_stress_peak_nodal_von_mises_MPa"],
        lu["plane_stress_peak_nodal_von_mises_MPa"],
        rtol=1e-7,
    )
    np.testing.assert_allclose(
        chol["min_tangent_eigenvalue_N_per_mm"], lu["min_tangent_eigenvalue_N_per_mm"], rtol=1e-6
    )
    # and the check does its job: the plane-stress force is the beam's within a few %
    assert chol["max_abs_relative_difference"] < 0.05, chol["relative_difference"]


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("share", [0.0, 0.9, 3.0])
def test_eigenvalue_with_few_lanczos_vectors_is_the_default_basis_one(solver, share):
    # fidelity.EIGEN_NCV Lanczos vectors (session 32) against ARPACK's default basis (20
    # vectors for k = 1) on the same shift-invert operator: the same eigenvalue to round-off,
    # from a tangent far from buckling (share 0), near it (0.9 of the Euler strain: the
    # constant-force check's case, lambda_min small and dominant) and past it (3x, indefinite).
    import scipy.sparse.linalg as spla

    model = _strip_model(solver)
    euler = np.pi**2 * (1.0 / 20.0) ** 2 / 3.0
    u = np.zeros(model.n_dofs)
    u[model.ix] = -share * euler * model.xy[:, 0]
    K = model.state(u, "nonlinear").K
    eig = fidelity._eigenvalue_nearest_zero(model, K)
    reduced = model._reduced(K)
    v0 = np.random.default_rng(0).standard_normal(reduced.shape[0])
    factor = model.cholesky_factor(K)
    inverse = (
        spla.LinearOperator(reduced.shape, matvec=factor.solve, dtype=float)
        if factor is not None
        else None
    )
    sigma = 0.0 if factor is not None else -1e-9
    default = spla.eigsh(
        reduced, k=1, sigma=sigma, OPinv=inverse, which="LM", return_eigenvectors=False, v0=v0
    )[0]
    dense = np.linalg.eigvalsh(reduced.toarray())
    assert fidelity.EIGEN_NCV < 20
    assert eig == pytest.approx(default, rel=1e-12, abs=1e-12 * np.abs(dense).max())
    assert eig == pytest.approx(dense[np.argmin(np.abs(dense))], rel=1e-8)


def test_check_without_the_eigenvalue_has_the_same_figures(fixed_guided):
    # eigenvalue=False (the constant-force peak's refined re-solve, session 32) leaves out the
    # stability eigenvalue only: every other figure the same bits, stable / eigenvalue None
    beam, shape, response = fixed_guided
    args = (beam, shape, MATERIAL, WIDTH_MM, PAD_LENGTH_MM, PAD_THICK_MM, (0.0, 1.0), response)
    rows = np.array([1, 3])
    full = fidelity.plane_stress_check(*args, rows, 3.0, 0.6)
    bare = fidelity.plane_stress_check(*args, rows, 3.0, 0.6, eigenvalue=False)
    assert full["stable"] == [True, True]
    assert bare["stable"] == [None, None]
    assert bare["min_tangent_eigenvalue_N_per_mm"] == [None, None]
    for key, value in full.items():
        if key in ("stable", "min_tangent_eigenvalue_N_per_mm", "time_s", "field"):
            continue
        assert bare[key] == value, key
    for a, b in zip(full["field"]["steps"], bare["field"]["steps"], strict=True):
        for key in a:
            assert np.array_equal(a[key], b[key]), key
