"""The QDLDL (sparse LDLᵀ) path of the plane-stress solver, a plain install's default (issue 13).

References computed here: the SuperLU path of the same solves, dense eigenvalues and dense
solves of the same matrices, and (when cvxopt is installed) CHOLMOD's verdict on every tangent.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest
import scipy.sparse as sp
from flexopt.fea import fidelity
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import (
    SOLVER_ENV,
    Clamp,
    PlaneStressModel,
    PlaneStressSettings,
    Rotate,
    Translate,
    _Qdldl,
    solve_plane_stress,
)
from shapely.geometry import LineString, Point, box

pytest.importorskip("qdldl")

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)

try:
    import cvxopt  # noqa: F401

    HAS_CHOLMOD = True
except ImportError:
    HAS_CHOLMOD = False


def twisted_ring():
    """A slit ring (3 to 8 mm) clamped at one spot and turned by 0.15 rad at its hub."""
    poly = (
        Point(0, 0)
        .buffer(8.0, quad_segs=16)
        .difference(Point(0, 0).buffer(3.0, quad_segs=16))
        .difference(box(5.0, -0.5, 9.0, 0.5))
    )
    inner = poly.interiors[0] if poly.interiors else Point(0, 0).buffer(3.0).exterior
    kw = dict(clamp=Clamp(Point(-8.0, 0.0).buffer(1.0)), drive=Rotate(inner, (0, 0), 0.15, 2))
    return mesh_polygon(poly, 1.0), kw


def squeezed_strut(steps: int = 3):
    """A clamped-clamped 50 x 1 mm strut squeezed 0.3 mm: ~4.5x its Euler load, so the straight
    equilibrium is unstable and its tangent indefinite (the mesh and drive, and the model)."""
    L, h = 50.0, 1.0
    mesh = mesh_polygon(box(0.0, 0.0, L, h), 0.5)
    clamp = Clamp(LineString([(0, 0), (0, h)]))
    drive = Translate(LineString([(L, 0), (L, h)]), direction=(-1.0, 0.0), max_mm=0.3, steps=steps)
    return mesh, clamp, drive


def spd_and_indefinite(model: PlaneStressModel):
    """The model's reduced linear stiffness (positive definite) and the same shifted down past
    its lowest eigenvalues (indefinite), as sorted CSR matrices of one pattern, with their dense
    eigenvalues."""
    K = model._reduced(model.state(np.zeros(model.n_dofs), "linear").K).tocsr()
    K.sort_indices()
    dense = np.linalg.eigvalsh(K.toarray())
    shift = 0.5 * (dense[2] + dense[3])  # between two eigenvalues: three negative after the shift
    K_indef = K.copy()
    K_indef.data = K.data.copy()
    K_indef.setdiag(K.diagonal() - shift)  # the diagonal is stored, so the pattern is kept
    assert np.array_equal(K_indef.indices, K.indices)
    return K, K_indef, dense, dense - shift


def test_qdldl_and_superlu_paths_agree_on_a_nonlinear_solve():
    mesh, kw = twisted_ring()
    runs = {
        s: solve_plane_stress(mesh, MAT, 2.0, settings=PlaneStressSettings(solver=s), **kw)
        for s in ("qdldl", "direct")
    }
    qd, lu = runs["qdldl"], runs["direct"]
    assert qd.ok and lu.ok
    assert qd.extra["solver"] == "qdldl" and lu.extra["solver"] == "direct"
    assert qd.extra["cholesky_failures"] == 0  # positive definite all the way
    assert abs(qd.torque_Nmm[-1]) > 0  # the ring was twisted: the comparison means something
    np.testing.assert_allclose(qd.torque_Nmm, lu.torque_Nmm, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(qd.dofs, lu.dofs, rtol=0, atol=1e-9 * np.abs(lu.dofs).max())
    np.testing.assert_array_equal(qd.iterations, lu.iterations)


def small_strip(solver: str) -> PlaneStressModel:
    """A 20 x 1 mm strip, left end clamped, right end driven along -x (a column), ~600 DOFs."""
    return PlaneStressModel(
        mesh_polygon(box(0.0, 0.0, 20.0, 1.0), 0.8),
        MAT,
        5.0,
        Clamp(box(-0.01, -0.01, 0.01, 1.01)),
        Translate(box(19.99, -0.01, 20.01, 1.01), (-1.0, 0.0)),
        PlaneStressSettings(solver=solver),
    )


def residual(K: sp.csr_matrix, x: np.ndarray, rhs: np.ndarray) -> float:
    """Backward error of a solve: |K x - rhs| / (|K| |x| + |rhs|), 2-norms (|K|: Frobenius)."""
    return float(
        np.linalg.norm(K @ x - rhs) / (sp.linalg.norm(K) * np.linalg.norm(x) + np.linalg.norm(rhs))
    )


def test_factorise_says_whether_the_matrix_is_positive_definite():
    K, K_indef, eig, eig_indef = spd_and_indefinite(small_strip("direct"))
    assert eig.min() > 0 and (eig_indef < 0).sum() == 3  # the cases are what they claim to be
    rhs = np.random.default_rng(1).standard_normal(K.shape[0])
    exact = np.linalg.solve(K.toarray(), rhs)
    # forward error allowed: the condition number times a few hundred round-offs
    tol = 1e-13 * eig.max() / eig.min() * np.abs(exact).max()

    qd = _Qdldl()
    assert qd.factorise(K) is True  # analysis and first factorisation
    x = qd.solve(rhs)
    assert residual(K, x, rhs) < 1e-14
    np.testing.assert_allclose(x, exact, rtol=0, atol=tol)
    assert qd.factorise(K_indef) is False  # same pattern: the refactorisation path
    assert qd.factorise(2.0 * K) is True  # and back: a refusal leaves the handle usable
    np.testing.assert_allclose(qd.solve(rhs), exact / 2, rtol=0, atol=tol)
    assert _Qdldl().factorise(K_indef) is False  # the analysis path refuses it too

    # A zero on the diagonal: e_i^T K e_i = 0, not positive definite, whatever the ordering
    # (QDLDL raises on a zero pivot when it builds, and leaves zero pivots when it updates).
    K_zero = K.copy()
    K_zero.data = K.data.copy()
    diag = K.diagonal()
    diag[K.shape[0] // 2] = 0.0
    K_zero.setdiag(diag)
    assert np.array_equal(K_zero.indices, K.indices)
    assert _Qdldl().factorise(K_zero) is False
    assert qd.factorise(K_zero) is False
    assert qd.factorise(K) is True


def test_indefinite_tangents_fall_back_to_lu_and_are_counted():
    mesh, clamp, drive = squeezed_strut()
    runs = {
        s: solve_plane_stress(mesh, MAT, 1.0, clamp, drive, settings=PlaneStressSettings(solver=s))
        for s in ("qdldl", "direct") + (("cholmod",) if HAS_CHOLMOD else ())
    }
    qd, lu = runs["qdldl"], runs["direct"]
    assert qd.ok and lu.ok, (qd.message, lu.message)
    assert qd.extra["cholesky_failures"] > 0  # the stability signal
    assert lu.extra["cholesky_failures"] == 0
    assert qd.force_N[1] > 4 * np.pi**2 * MAT.E_MPa * 1.0**3 / 12.0 / 50.0**2  # past Euler
    np.testing.assert_allclose(qd.force_N, lu.force_N, rtol=1e-9)
    np.testing.assert_array_equal(qd.iterations, lu.iterations)
    if HAS_CHOLMOD:  # QDLDL's pivots and CHOLMOD's refusal agree on every tangent
        assert qd.extra["cholesky_failures"] == runs["cholmod"].extra["cholesky_failures"]

    # One system at a time through the model: LU's answer and one failure for the indefinite
    # one; the factor's own answer and no failure for the definite one.
    model = small_strip("qdldl")
    K = model.state(np.zeros(model.n_dofs), "linear").K
    shift = 0.01 * K.diagonal().mean()
    K_indef = (K - shift * sp.identity(K.shape[0], format="csr")).tocsr()
    K_indef.sort_indices()
    Kr, Kr_indef = model._reduced(K), model._reduced(K_indef)
    assert np.linalg.eigvalsh(Kr.toarray()).min() > 0
    assert np.linalg.eigvalsh(Kr_indef.toarray()).min() < 0
    rhs = np.random.default_rng(0).standard_normal(model.free.size)
    x = model._reduced_solve(K_indef, rhs)
    assert residual(Kr_indef, x, rhs) < 1e-14
    assert model.counters["cholesky_failures"] == 1 and model._chol_lu is not None
    x = model._reduced_solve(K, rhs)
    assert residual(Kr, x, rhs) < 1e-14
    assert model.counters["cholesky_failures"] == 1 and model._chol_lu is None
    assert model.counters["factorisations"] == 3  # two tangents, the first also by LU


@pytest.mark.parametrize("strain", [0.0, 0.05])
def test_fidelity_eigenvalue_on_the_qdldl_factor(strain):
    # The constant-force report's stability check (fea.fidelity) shift-inverts with the model's
    # factor; 5 % shortening of the strip buckles it (indefinite: the LU stand-in is used).
    model = small_strip("qdldl")
    u = np.zeros(model.n_dofs)
    u[model.ix] = -strain * model.xy[:, 0]
    K = model.state(u, "nonlinear").K
    dense = np.linalg.eigvalsh(model._reduced(K).toarray())
    nearest = dense[np.argmin(np.abs(dense))]
    assert (dense < 0).any() == (strain > 0)
    eig = fidelity._eigenvalue_nearest_zero(model, K)
    assert eig == pytest.approx(nearest, rel=1e-8, abs=1e-10 * np.abs(dense).max())
    assert model.counters["cholesky_failures"] == (1 if strain > 0 else 0)


def test_auto_picks_qdldl_without_cvxopt(monkeypatch):
    mesh = mesh_polygon(box(0.0, 0.0, 10.0, 1.0), 0.5)
    kw = dict(
        clamp=Clamp(LineString([(0, 0), (0, 1)])), drive=Translate(LineString([(10, 0), (10, 1)]))
    )
    monkeypatch.delenv(SOLVER_ENV, raising=False)
    cvxopt_module = sys.modules.get("cvxopt")
    monkeypatch.setitem(sys.modules, "cvxopt", None)  # `import cvxopt` raises ImportError
    assert PlaneStressModel(mesh, MAT, 1.0, **kw).solver == "qdldl"
    monkeypatch.setenv(SOLVER_ENV, "qdldl")
    assert PlaneStressModel(mesh, MAT, 1.0, **kw).solver == "qdldl"
    monkeypatch.delenv(SOLVER_ENV)
    # Neither: PARDISO when it loads, else SuperLU.
    monkeypatch.setitem(sys.modules, "qdldl", None)
    monkeypatch.setitem(sys.modules, "pypardiso", None)
    assert PlaneStressModel(mesh, MAT, 1.0, **kw).solver == "direct"
    with pytest.raises(FeaError, match="solver 'qdldl' needs the package qdldl"):
        PlaneStressModel(mesh, MAT, 1.0, settings=PlaneStressSettings(solver="qdldl"), **kw)
    if HAS_CHOLMOD:
        monkeypatch.setitem(sys.modules, "cvxopt", cvxopt_module)
        assert PlaneStressModel(mesh, MAT, 1.0, **kw).solver == "cholmod"  # cvxopt first


def test_plane_stress_check_is_the_same_through_qdldl_and_superlu(monkeypatch):
    # fea.fidelity's check (the constant-force report): Newton started from the beam's shape
    # and the stability eigenvalue on the model's factor, here a fixed-guided beam pushed 3 mm.
    from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive
    from flexopt.geometry.profile import BeamProfile

    length, thick, width, pad = 30.0, 1.2, 5.0, 3.0
    mat = Material("ABS-like", E_MPa=1800.0, nu=0.35, yield_MPa=42.5)
    profile = BeamProfile(np.array([[0.0, 0.0], [length, 0.0]]), np.full(2, thick), width)
    beam = BeamModel(profile, mat, settings=BeamSettings(n_elements=20))
    response = beam.solve(EndDrive("displacement", (0.0, 1.0), 3.0, 3, "fixed", "fixed"))
    shape = (
        box(0.0, -0.5 * thick, length, 0.5 * thick)
        .union(box(-pad, -0.5 * pad, 0.0, 0.5 * pad))
        .union(box(length, -0.5 * pad, length + pad, 0.5 * pad))
    )
    checks = {}
    for solver in ("direct", "qdldl"):
        monkeypatch.setenv(SOLVER_ENV, solver)
        checks[solver] = fidelity.plane_stress_check(
            beam, shape, mat, width, pad, pad, (0.0, 1.0), response, np.array([1, 3]), 3.0, 0.6
        )
    lu, qd = checks["direct"], checks["qdldl"]
    assert "skipped" not in lu and "skipped" not in qd, (lu, qd)
    assert all(lu["converged"]) and all(qd["converged"])
    assert qd["newton_iterations"] == lu["newton_iterations"]
    assert qd["stable"] == lu["stable"] == [True, True]
    for key in (
        "plane_stress_force_N",
        "plane_stress_peak_nodal_von_mises_MPa",
        "max_shape_change_mm",
    ):
        np.testing.assert_allclose(qd[key], lu[key], rtol=1e-7, err_msg=key)
    np.testing.assert_allclose(
        qd["min_tangent_eigenvalue_N_per_mm"], lu["min_tangent_eigenvalue_N_per_mm"], rtol=1e-6
    )
