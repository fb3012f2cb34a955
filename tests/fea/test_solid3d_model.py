"""Solid3DModel (fea/solid3d.py), the 3D check's fast path for several thicknesses, against the
reference path computed here: the stiffness assembled at each thickness by ``_stiffness`` and
:func:`solve_solid3d` (assembled at the thickness, factorised afresh).

Units: mm, N, MPa, N·mm, rad.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, Rotate, Translate
from flexopt.fea.solid3d import (
    Solid3DModel,
    Solid3DSettings,
    _lame,
    _pcg,
    _stiffness,
    compare_with_plane_stress,
    extrude_layers_mm,
    extrude_mesh,
    solve_solid3d,
)
from shapely.geometry import LineString, Point, box

STEEL = Material("steel", 200_000.0, 0.3, 1000.0)
# agreement of two solves of the same model: round-off of a direct solve of a system whose
# condition number is ~1e8 leaves ~1e-10; PCG stops at a residual of 1e-12
RTOL = 1e-8


def _strip():
    """A 30 x 3 mm strip, root clamped, tip face pushed across it (a deep cantilever)."""
    mesh = mesh_polygon(box(0.0, 0.0, 30.0, 3.0), 1.0)
    clamp = Clamp(LineString([(0.0, 0.0), (0.0, 3.0)]))
    drive = Translate(LineString([(30.0, 0.0), (30.0, 3.0)]), (0.0, 1.0), 0.1, 1)
    return mesh, clamp, drive


def _annulus():
    """An annulus (radii 5 and 15 mm) turned at its inner rim, outer rim held: the SEA
    spring's supports (Rotate about the centre, a clamp), its inner region out of the peak."""
    outline = Point(0.0, 0.0).buffer(15.0, 32).difference(Point(0.0, 0.0).buffer(5.0, 16))
    mesh = mesh_polygon(outline, 2.0)
    clamp = Clamp(outline.exterior)
    drive = Rotate(outline.interiors[0], (0.0, 0.0), 1e-3, 1)
    return mesh, clamp, drive, Point(0.0, 0.0).buffer(6.0)


def _assert_same(fast, ref):
    assert fast.stiffness == pytest.approx(ref.stiffness, rel=RTOL)
    assert fast.peak_nodal_stress_MPa == pytest.approx(ref.peak_nodal_stress_MPa, rel=RTOL)
    assert fast.peak_stress_MPa == pytest.approx(ref.peak_stress_MPa, rel=RTOL)
    np.testing.assert_allclose(fast.peak_nodal_stress_xyz_mm, ref.peak_nodal_stress_xyz_mm,
                               atol=1e-9)  # fmt: skip
    np.testing.assert_allclose(fast.peak_stress_xyz_mm, ref.peak_stress_xyz_mm, atol=1e-9)
    scale = np.abs(ref.reaction_N).max()
    np.testing.assert_allclose(fast.reaction_N, ref.reaction_N, rtol=0, atol=RTOL * scale)
    np.testing.assert_allclose(fast.clamp_reaction_N, ref.clamp_reaction_N, rtol=0,
                               atol=RTOL * scale)  # fmt: skip
    assert (fast.n_dofs, fast.n_tets, fast.n_layers) == (ref.n_dofs, ref.n_tets, ref.n_layers)


@pytest.mark.parametrize("symmetric", [True, False])
def test_thickness_parts_reproduce_the_assembly_at_each_thickness(symmetric):
    """K(t) = t K_pp + K_pz + K_zz / t against the element-by-element assembly of the mesh
    extruded to t, entry by entry (both sum the same products; round-off apart)."""
    mesh, clamp, drive = _strip()
    settings = Solid3DSettings(layers=2, symmetric=symmetric)
    model = Solid3DModel(mesh, STEEL, clamp, drive, settings)
    from skfem import Basis, ElementTetP2

    for t in (1.0, 4.0, 19.2):
        sbasis = Basis(extrude_mesh(mesh, extrude_layers_mm(t, settings)), ElementTetP2(),
                       intorder=2)  # fmt: skip
        ref = _stiffness(sbasis, *_lame(STEEL), 1000)
        diff = (model.stiffness_matrix(t).tocsr() - ref).tocoo()
        assert np.abs(diff.data).max() <= 1e-12 * np.abs(ref.data).max()


def test_every_thickness_matches_the_reference_solve():
    """The first thickness factorised, the next ones by PCG on that factor (to 1e-12), and a
    model with later_solves = "direct": each the reference's answer at that thickness."""
    mesh, clamp, drive = _strip()
    settings = Solid3DSettings(layers=2)
    model = Solid3DModel(mesh, STEEL, clamp, drive, settings)
    direct_settings = Solid3DSettings(layers=2, later_solves="direct")
    direct = Solid3DModel(mesh, STEEL, clamp, drive, direct_settings)
    for k, t in enumerate((12.0, 11.7, 12.3, 9.0)):
        ref = solve_solid3d(mesh, STEEL, t, clamp, drive, settings)
        fast = model.solve(t)
        _assert_same(fast, ref)
        _assert_same(direct.solve(t), ref)
        # the later thicknesses really took the iterative path (a few iterations each)
        assert (fast.iterations > 0) == (k > 0) and fast.iterations < 30
        assert fast.solver == ("cholmod" if k == 0 else "pcg (cholmod)")


def test_rotated_hub_with_ignored_region_matches_the_reference():
    """The SEA spring's supports (Rotate, Clamp, stress_ignore), one layer; and
    compare_with_plane_stress from the model equals the function's. The model solves plane
    stress at its first thickness only and scales it to a later one: the same figures as the
    function's solve at that thickness to round-off."""
    mesh, clamp, drive, ignore = _annulus()
    settings = Solid3DSettings(layers=1)
    model = Solid3DModel(mesh, STEEL, clamp, drive, settings, stress_ignore=ignore)
    for k, t in enumerate((8.0, 7.8, 8.3)):
        fast = model.compare_with_plane_stress(t)
        ref = compare_with_plane_stress(mesh, STEEL, t, clamp, drive, settings, ignore)
        for key in ("stiffness_3d", "stiffness_ratio", "peak_stress_ratio",
                    "peak_nodal_stress_3d_MPa", "peak_stress_qp_3d_MPa"):  # fmt: skip
            assert fast[key] == pytest.approx(ref[key], rel=RTOL), key
        if k == 0:
            assert fast["stiffness_2d"] == ref["stiffness_2d"]  # the same 2D solve
            assert fast["time_2d_s"] > 0
        else:  # scaled, not solved: the 2D figures of a solve at t to round-off
            assert fast["time_2d_s"] == 0.0
            for key in ("stiffness_2d", "peak_nodal_stress_2d_MPa", "peak_stress_qp_2d_MPa"):
                assert fast[key] == pytest.approx(ref[key], rel=1e-12), key
            assert fast["n_dofs_2d"] == ref["n_dofs_2d"]


def test_a_far_thickness_is_factorised_again():
    """PCG that does not converge within pcg_max_iterations hands over to a new
    factorisation: the answer is still the reference's."""
    mesh, clamp, drive = _strip()
    settings = Solid3DSettings(layers=2, pcg_max_iterations=1)
    model = Solid3DModel(mesh, STEEL, clamp, drive, settings)
    model.solve(12.0)
    fast = model.solve(6.0)
    assert fast.iterations == 0 and fast.solver == "cholmod"
    _assert_same(fast, solve_solid3d(mesh, STEEL, 6.0, clamp, drive, settings))


@pytest.mark.parametrize("solver", ["superlu", "cholmod"])
def test_transverse_slide_and_superlu_match_the_reference(solver):
    """A drive free to slide across its direction (one shared unknown: P is no selection, the
    reduced matrix is P^T K P) and the SuperLU fallback (reads the lower triangle)."""
    mesh, clamp, _ = _strip()
    drive = Translate(LineString([(30.0, 0.0), (30.0, 3.0)]), (1.0, 0.0), 0.01, 1,
                      transverse="free")  # fmt: skip
    settings = Solid3DSettings(layers=1, solver=solver)
    model = Solid3DModel(mesh, STEEL, clamp, drive, settings)
    for t in (6.0, 6.2):
        _assert_same(model.solve(t), solve_solid3d(mesh, STEEL, t, clamp, drive, settings))


def test_pcg_solves_a_small_spd_system_exactly():
    """_pcg against numpy's dense solve; with the exact inverse as preconditioner it takes one
    iteration, with a rough one more, never a wrong answer."""
    rng = np.random.default_rng(3)
    A = rng.standard_normal((40, 40))
    A = A @ A.T + 40.0 * np.eye(40)
    b = rng.standard_normal(40)
    x_ref = np.linalg.solve(A, b)
    x, its, ok = _pcg(lambda v: A @ v, b, lambda r: np.linalg.solve(A, r), np.zeros(40),
                      1e-12, 10)  # fmt: skip
    assert ok and its == 1
    np.testing.assert_allclose(x, x_ref, rtol=1e-10)
    D = np.diag(A)
    x, its, ok = _pcg(lambda v: A @ v, b, lambda r: r / D, np.zeros(40), 1e-12, 200)
    assert ok and 1 < its <= 40
    np.testing.assert_allclose(x, x_ref, rtol=1e-9)
    assert np.linalg.norm(A @ x - b) <= 1e-12 * np.linalg.norm(b) * 1.0001
    _, _, ok = _pcg(lambda v: A @ v, b, lambda r: r / D, np.zeros(40), 1e-12, 2)
    assert not ok


def test_refuses_a_bad_thickness_and_setting():
    mesh, clamp, drive = _strip()
    model = Solid3DModel(mesh, STEEL, clamp, drive, Solid3DSettings(layers=1))
    with pytest.raises(FeaError, match="thickness_mm"):
        model.solve(0.0)
    with pytest.raises(FeaError, match="later_solves"):
        Solid3DModel(mesh, STEEL, clamp, drive, Solid3DSettings(later_solves="cg"))  # type: ignore[arg-type]
