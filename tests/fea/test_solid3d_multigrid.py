"""The 3D check's multigrid solver (``Solid3DSettings(solver="multigrid")``, issue 27 item 5;
fea/solid3d.py, docs/solid3d.md "Memory"): conjugate gradients preconditioned by a two-grid
cycle, no factor of the whole model. Checked against the exact in-plane Lamé solution of a
twisted annulus, against the direct factorisation on a bending-dominated deep strip (the SEA
spring's arms) at two thicknesses, and its error shrinking with its tolerance.

Units: mm, N, MPa, N·mm, rad.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, Rotate, Translate
from flexopt.fea.solid3d import Solid3DModel, Solid3DSettings, solve_solid3d
from shapely.geometry import LineString, Point, box

pytest.importorskip("numba")  # the multigrid solver runs on the compiled assembly

E = 200_000.0  # MPa
STEEL = Material("steel", E, 0.3, 1000.0)


def _answers(r) -> np.ndarray:
    return np.array([r.stiffness, r.peak_stress_MPa, r.peak_nodal_stress_MPa,
                     *r.reaction_N[:2], *r.clamp_reaction_N[:2]])  # fmt: skip


def _strip():
    """60 x 3 mm strip, root clamped, tip translated across it without turning: the arms'
    in-plane bending, where a P1 coarse grid is stiffest (the hard case for the cycle)."""
    mesh = mesh_polygon(box(0.0, 0.0, 60.0, 3.0), 1.0)
    clamp = Clamp(LineString([(0.0, 0.0), (0.0, 3.0)]))
    drive = Translate(LineString([(60.0, 0.0), (60.0, 3.0)]), (0.0, 1.0), 0.1, 1)
    return mesh, clamp, drive


def test_multigrid_annulus_torsion_matches_the_closed_form():
    """Inner rim turned by theta, outer held: u_theta = B (1/r - r/b^2) with
    B = theta a^2 b^2 / (b^2 - a^2), tau = -2 mu B / r^2, torque = 4 pi mu h B."""
    a, b, h, theta = 5.0, 15.0, 4.0, 1e-3
    ring = Point(0, 0).buffer(b, quad_segs=32).difference(Point(0, 0).buffer(a, quad_segs=32))
    mesh = mesh_polygon(ring, 3.0)
    r = solve_solid3d(mesh, STEEL, h, Clamp(ring.exterior),
                      Rotate(ring.interiors[0], (0, 0), theta),
                      Solid3DSettings(layers=1, solver="multigrid"))  # fmt: skip
    assert r.solver.startswith("multigrid") and r.iterations > 0
    B = theta * a**2 * b**2 / (b**2 - a**2)
    torque = 4.0 * math.pi * STEEL.G_MPa * h * B
    assert r.torque_Nmm == pytest.approx(torque, rel=1e-3)
    # von Mises of pure shear: sqrt(3) |tau| at the inner rim
    assert r.peak_nodal_stress_MPa == pytest.approx(math.sqrt(3) * 2 * STEEL.G_MPa * B / a**2,
                                                    rel=0.01)  # fmt: skip


@pytest.mark.parametrize("lean", [True, False])
def test_multigrid_equals_the_direct_solve_at_two_thicknesses(lean):
    """The deep strip (19.2 mm, 4 graded layers) and a thickness 3 % off, solved by the
    direct factorisation and by multigrid in one model each: stiffness and peak stresses
    agree to 1e-8 (the stated 3D-check tolerance is 1e-4). The second thickness starts from
    the first's answer, so it needs fewer iterations."""
    mesh, clamp, drive = _strip()
    out = {}
    for solver in ("auto", "multigrid"):
        settings = Solid3DSettings(solver=solver, lean_factorisation=lean)
        model = Solid3DModel(mesh, STEEL, clamp, drive, settings)
        out[solver] = [model.solve(t) for t in (19.2, 18.6)]
    d1, d2 = out["auto"]
    m1, m2 = out["multigrid"]
    assert not d1.solver.startswith("multigrid")
    assert m1.solver.startswith("multigrid") and m2.solver.startswith("multigrid")
    assert 0 < m2.iterations < m1.iterations
    for d, m in ((d1, m1), (d2, m2)):
        # the reactions' components across the drive are near-cancelling sums (~1e-4 of
        # the force): compared to 1e-6 of the force
        np.testing.assert_allclose(_answers(m), _answers(d), rtol=1e-8,
                                   atol=1e-6 * np.linalg.norm(d.reaction_N))  # fmt: skip
        np.testing.assert_array_equal(m.peak_nodal_stress_xyz_mm, d.peak_nodal_stress_xyz_mm)


def test_multigrid_error_shrinks_with_its_tolerance():
    """Convergence of the iteration: the stiffness's distance to the direct answer falls as
    multigrid_rtol falls (and is inside the tolerance's order at each)."""
    mesh, clamp, drive = _strip()
    direct = solve_solid3d(mesh, STEEL, 19.2, clamp, drive, Solid3DSettings(layers=2))
    errors, iterations = [], []
    for rtol in (1e-4, 1e-7, 1e-10):
        settings = Solid3DSettings(layers=2, solver="multigrid", multigrid_rtol=rtol)
        r = solve_solid3d(mesh, STEEL, 19.2, clamp, drive, settings)
        errors.append(abs(r.stiffness / direct.stiffness - 1.0))
        iterations.append(r.iterations)
    assert iterations[0] < iterations[1] < iterations[2]
    assert errors[0] > errors[1] > errors[2] or errors[2] < 1e-12
    assert errors[1] < 1e-5 and errors[2] < 1e-8


def test_multigrid_that_does_not_converge_is_an_error():
    mesh, clamp, drive = _strip()
    settings = Solid3DSettings(layers=2, solver="multigrid", multigrid_max_iterations=2)
    with pytest.raises(FeaError, match="did not reach"):
        solve_solid3d(mesh, STEEL, 19.2, clamp, drive, settings)


def test_multigrid_where_it_cannot_run_uses_a_direct_solver():
    """A Translate with transverse = "free" adds an unknown that is not a DOF: the direct
    solvers run, as documented, and say so."""
    mesh, clamp, _ = _strip()
    drive = Translate(LineString([(60.0, 0.0), (60.0, 3.0)]), (1.0, 0.0), 0.1, 1,
                      transverse="free")  # fmt: skip
    r = solve_solid3d(mesh, STEEL, 19.2, clamp, drive,
                      Solid3DSettings(layers=2, solver="multigrid"))  # fmt: skip
    ref = solve_solid3d(mesh, STEEL, 19.2, clamp, drive, Solid3DSettings(layers=2))
    assert not r.solver.startswith("multigrid")
    assert r.stiffness == ref.stiffness


def test_multigrid_without_cvxopt_factorises_the_coarse_grid_with_qdldl(monkeypatch):
    """A plain install (no `cholmod` extra): the P1 grid goes to QDLDL and the answer is the
    direct QDLDL solve's."""
    pytest.importorskip("qdldl")
    import sys

    monkeypatch.setitem(sys.modules, "cvxopt", None)  # `import cvxopt` raises ImportError
    mesh, clamp, drive = _strip()
    m = solve_solid3d(mesh, STEEL, 19.2, clamp, drive,
                      Solid3DSettings(layers=2, solver="multigrid"))  # fmt: skip
    d = solve_solid3d(mesh, STEEL, 19.2, clamp, drive, Solid3DSettings(layers=2))
    assert m.solver == "multigrid (pcg, P1 coarse: qdldl)" and d.solver == "qdldl"
    np.testing.assert_allclose(_answers(m), _answers(d), rtol=1e-8,
                               atol=1e-6 * np.linalg.norm(d.reaction_N))  # fmt: skip


@pytest.mark.parametrize("install", ["cholmod", "plain"])
def test_auto_takes_cholmod_else_multigrid_from_multigrid_from_dofs_on(install, monkeypatch):
    """The "auto" solver: CHOLMOD wherever it imports (~3x faster than multigrid, at twice its
    memory), at every size; on a plain install (no `cholmod` extra, simulated by making
    `import cvxopt` fail) QDLDL below ``multigrid_from_dofs`` (by default 150k DOFs, below the
    SEA spring's 408k) and multigrid from it on (less memory and less time than QDLDL). The
    same model below and above a lowered threshold."""
    import sys

    from flexopt.fea.solid3d import cholmod_available

    if install == "cholmod":
        pytest.importorskip("cvxopt")
        expect_below = expect_above = "cholmod"
    else:
        pytest.importorskip("qdldl")
        monkeypatch.setitem(sys.modules, "cvxopt", None)  # `import cvxopt` raises ImportError
        expect_below, expect_above = "qdldl", "multigrid (pcg, P1 coarse: qdldl)"
    assert cholmod_available() == (install == "cholmod")
    mesh, clamp, drive = _strip()
    below = solve_solid3d(mesh, STEEL, 19.2, clamp, drive, Solid3DSettings(layers=2))
    above = solve_solid3d(mesh, STEEL, 19.2, clamp, drive,
                          Solid3DSettings(layers=2, multigrid_from_dofs=below.n_dofs))  # fmt: skip
    assert below.solver == expect_below and above.solver == expect_above
    assert above.stiffness == pytest.approx(below.stiffness, rel=1e-8)
