"""The compiled build of the 3D model (fea/_solid3d_kernels.py, ``assembly="compiled"``) against
the numpy reference path of fea/solid3d.py (scikit-fem's Basis, the global sort of node pairs),
on small meshes: the same numbering and tables, the same pattern, the same parts and reduced
lower triangle to round-off, the same answers.

Units: mm, N, MPa, N·mm, rad.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, Rotate, Translate
from flexopt.fea.solid3d import (
    _CORNERS,
    Solid3DModel,
    Solid3DSettings,
    _compiled,
    _gradients,
    _lame,
    _stiffness_parts,
    _von_mises,
    extrude_layers_mm,
    extrude_mesh,
    p2_tables,
)
from shapely.geometry import LineString, Point, box

STEEL = Material("steel", 200_000.0, 0.3, 1000.0)
KERNELS = _compiled()
pytestmark = pytest.mark.skipif(KERNELS is None, reason="numba does not import")


def _strip_mesh():
    return mesh_polygon(box(0.0, 0.0, 30.0, 3.0), 1.0)


def _tets(symmetric: bool):
    """The strip extruded through two layers (each side of z = 0 when not symmetric)."""
    settings = Solid3DSettings(layers=2, symmetric=symmetric)
    return extrude_mesh(_strip_mesh(), extrude_layers_mm(3.0, settings))


@pytest.mark.parametrize("symmetric", [True, False])
def test_p2_tables_are_scikit_fems(symmetric):
    """Numbering (vertices, then edges sorted by their vertices), node positions, gradients at
    the quadrature points and the corners, weights and points: scikit-fem's Basis."""
    from skfem import Basis, ElementTetP2

    tmesh = _tets(symmetric)
    dofs, n, doflocs, G, dx, Gc, xyz = p2_tables(tmesh, KERNELS)
    sb = Basis(tmesh, ElementTetP2(), intorder=2)
    cb = Basis(tmesh, sb.elem, quadrature=_CORNERS)
    assert n == sb.N
    np.testing.assert_array_equal(dofs, sb.element_dofs.T)
    np.testing.assert_allclose(doflocs, sb.doflocs.T, rtol=0, atol=1e-14)
    for mine, ref in ((G, _gradients(sb)), (Gc, _gradients(cb)), (dx, sb.dx),
                      (xyz, np.asarray(sb.global_coordinates()))):  # fmt: skip
        assert mine.shape == ref.shape
        np.testing.assert_allclose(mine, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_block_pattern_and_parts_equal_the_numpy_assembly():
    """The node-block pattern exactly, the twelve parts of every block to round-off (the same
    products summed in another order)."""
    tmesh = _tets(False)
    dofs, n, _, G, dx, _, _ = p2_tables(tmesh, KERNELS)
    lam, mu = _lame(STEEL)
    indptr, indices, parts = KERNELS.block_pattern_parts(dofs, n, G, dx, lam, mu)
    ref_indptr, ref_indices, ref_parts = _stiffness_parts(G, dx, dofs, n, lam, mu, 500)
    np.testing.assert_array_equal(indptr, ref_indptr)
    np.testing.assert_array_equal(indices, ref_indices)
    assert parts.shape == ref_parts.shape
    np.testing.assert_allclose(parts, ref_parts, rtol=0, atol=1e-12 * np.abs(ref_parts).max())
    # every block of K pairs two nodes sharing an element: at most 10 x 10 per element
    assert indices.size <= 100 * dofs.shape[0]


def _models(mesh, clamp, drive, settings, ignore=None):
    """The model of each assembly path."""
    made = {}
    for assembly in ("compiled", "numpy"):
        s = replace(settings, assembly=assembly)
        made[assembly] = Solid3DModel(mesh, STEEL, clamp, drive, s, stress_ignore=ignore)
    assert made["compiled"].assembly == "compiled" and made["numpy"].assembly == "numpy"
    return made["compiled"], made["numpy"]


def _annulus():
    outline = Point(0.0, 0.0).buffer(15.0, 32).difference(Point(0.0, 0.0).buffer(5.0, 16))
    mesh = mesh_polygon(outline, 2.0)
    clamp = Clamp(outline.exterior)
    drive = Rotate(outline.interiors[0], (0.0, 0.0), 1e-3, 1)
    return mesh, clamp, drive, Point(0.0, 0.0).buffer(6.0)


def test_stiffness_blocks_equal_the_table_product():
    """K(t)'s blocks from the parts: the compiled model's against the numpy model's (the
    parts times the (12, 9) table), at three thicknesses."""
    clamp = Clamp(LineString([(0.0, 0.0), (0.0, 3.0)]))
    drive = Translate(LineString([(30.0, 0.0), (30.0, 3.0)]), (0.0, 1.0), 0.1, 1)
    fast, ref = _models(_strip_mesh(), clamp, drive, Solid3DSettings(layers=2))
    for t in (0.5, 1.0, 7.3):
        a, b = fast.stiffness_matrix(t), ref.stiffness_matrix(t)
        np.testing.assert_array_equal(a.indices, b.indices)
        np.testing.assert_array_equal(a.indptr, b.indptr)
        np.testing.assert_allclose(a.data, b.data, rtol=0, atol=1e-13 * np.abs(b.data).max())


def test_reduced_lower_triangle_is_the_numpy_one_sorted_by_column():
    """The same entries (block positions, reduced rows and columns) as the numpy path, in
    compressed columns (rows ascending); the values K(t) gives them are the reduced matrix's."""
    clamp = Clamp(LineString([(0.0, 0.0), (0.0, 3.0)]))
    drive = Translate(LineString([(30.0, 0.0), (30.0, 3.0)]), (0.0, 1.0), 0.1, 1)
    fast, ref = _models(_strip_mesh(), clamp, drive, Solid3DSettings(layers=2))
    flat, rows, colptr = fast._lower
    cols = np.repeat(np.arange(colptr.size - 1), np.diff(colptr))
    rflat, rrows, rcols = ref._lower
    # sorted: columns non-decreasing, rows strictly increasing within a column, lower triangle
    assert np.all(np.diff(cols) >= 0) and np.all(rows >= cols)
    same_col = cols[1:] == cols[:-1]
    assert np.all(np.diff(rows)[same_col] > 0)
    order = np.lexsort((rrows, rcols))
    np.testing.assert_array_equal(rows, rrows[order])
    np.testing.assert_array_equal(cols, rcols[order])
    np.testing.assert_array_equal(flat, rflat[order])
    # the values there are the reduced matrix's, and every non-zero of its lower triangle is
    K = ref.stiffness_matrix(4.0)
    vals = K.data.ravel()[flat]
    P = ref._sup.P
    A = (P.T @ K.tocsr() @ P).tocsr()
    tol = 1e-12 * np.abs(vals).max()  # P^T K P sums products of P's ones: round-off apart
    np.testing.assert_allclose(vals, np.asarray(A[rows, cols]).ravel(), rtol=0, atol=tol)
    L = sp.tril(A).tocoo()
    assert np.count_nonzero(np.abs(L.data) > tol) == np.count_nonzero(np.abs(vals) > tol) > 0


def test_von_mises_kernel_equals_numpy():
    """The stress of a random displacement at the quadrature points, with a z stretch."""
    tmesh = _tets(True)
    dofs, n, _, G, _, _, _ = p2_tables(tmesh, KERNELS)
    u = np.random.default_rng(5).standard_normal(3 * n)
    lam, mu = _lame(STEEL)
    zs = 2.5
    gu = np.einsum("eac,eqaj->eqcj", u.reshape(-1, 3)[dofs], G)
    gu[..., 2] /= zs
    ref = _von_mises(gu, lam, mu)
    mine = KERNELS.von_mises(u, dofs, G, mu, zs)
    np.testing.assert_allclose(mine, ref, rtol=1e-12, atol=1e-12 * ref.max())


def test_compiled_model_answers_the_numpy_model():
    """The SEA spring's supports (Rotate, Clamp, stress_ignore): stiffness, peaks, where, and
    the reactions of both paths at two thicknesses (the second by PCG)."""
    mesh, clamp, drive, ignore = _annulus()
    fast, ref = _models(mesh, clamp, drive, Solid3DSettings(layers=1), ignore)
    for t in (8.0, 7.8):
        a, b = fast.solve(t), ref.solve(t)
        assert a.stiffness == pytest.approx(b.stiffness, rel=1e-9)
        assert a.peak_stress_MPa == pytest.approx(b.peak_stress_MPa, rel=1e-9)
        assert a.peak_nodal_stress_MPa == pytest.approx(b.peak_nodal_stress_MPa, rel=1e-9)
        np.testing.assert_allclose(a.peak_stress_xyz_mm, b.peak_stress_xyz_mm, atol=1e-12)
        np.testing.assert_allclose(a.peak_nodal_stress_xyz_mm, b.peak_nodal_stress_xyz_mm,
                                   atol=1e-12)  # fmt: skip
        scale = np.abs(b.clamp_reaction_N).max()
        np.testing.assert_allclose(a.clamp_reaction_N, b.clamp_reaction_N, rtol=0,
                                   atol=1e-9 * scale)  # fmt: skip
        assert a.n_dofs == b.n_dofs and a.iterations == b.iterations


def test_refuses_an_unknown_assembly():
    mesh = _strip_mesh()
    clamp = Clamp(LineString([(0.0, 0.0), (0.0, 3.0)]))
    drive = Translate(LineString([(30.0, 0.0), (30.0, 3.0)]), (0.0, 1.0), 0.1, 1)
    with pytest.raises(FeaError, match="assembly"):
        Solid3DModel(mesh, STEEL, clamp, drive, Solid3DSettings(assembly="fast"))  # type: ignore[arg-type]


@pytest.mark.parametrize("solver", ["qdldl", "superlu"])
def test_every_solver_gives_cholmods_answer(solver):
    """The 3D model on each factorisation (QDLDL what a plain install runs, SuperLU the last
    fallback), from the same compressed columns: CHOLMOD's answer to round-off, and a later
    thickness by PCG on that factor."""
    pytest.importorskip("cvxopt")
    mesh, clamp, drive, ignore = _annulus()
    ref_model = Solid3DModel(mesh, STEEL, clamp, drive, Solid3DSettings(layers=1),
                             stress_ignore=ignore)  # fmt: skip
    model = Solid3DModel(mesh, STEEL, clamp, drive, Solid3DSettings(layers=1, solver=solver),
                         stress_ignore=ignore)  # fmt: skip
    for t in (8.0, 7.5):
        ref, got = ref_model.solve(t), model.solve(t)
        assert got.solver.endswith(solver if t == 8.0 else f"({solver})")
        assert got.stiffness == pytest.approx(ref.stiffness, rel=1e-9)
        assert got.peak_nodal_stress_MPa == pytest.approx(ref.peak_nodal_stress_MPa, rel=1e-9)


def test_qdldl_refuses_an_indefinite_stiffness():
    """LDLᵀ without pivoting factorises an indefinite matrix too: SparseSolver reads D's signs and
    refuses it as CHOLMOD does, and solves a definite one."""
    from flexopt.fea.solid3d import SparseSolver

    A = sp.csc_matrix(np.array([[4.0, 1.0, 0.0], [1.0, -3.0, 1.0], [0.0, 1.0, 4.0]]))
    with pytest.raises(FeaError, match="not positive definite"):
        SparseSolver(A, "qdldl")
    B = sp.csc_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 4.0]]))
    x = SparseSolver(B, "qdldl").solve(np.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(B @ x, [1.0, 2.0, 3.0], rtol=1e-13)
