"""Exact derivatives of plane-stress responses by the mesh's vertex coordinates
(fea/plane_stress_sensitivity.py; issue 27 item 1), against references computed here:

* central differences of the full nonlinear (and linear) solve on the same mesh topology with
  the vertices moved by ``± h V`` (``V`` a smooth velocity field), solved to ``rtol = 1e-13``;
* the exact scaling law: a mesh scaled by ``s`` about the rotation centre, turned by the same
  angle, has the same strains and stresses, forces ``s`` times and torques ``s^2`` times
  (plane stress at a fixed thickness, linear and St Venant–Kirchhoff alike), so along
  ``V = X - c`` the derivative of the torque is ``2 T``, of the force ``F`` and of every stress 0.

Error: |adjoint - FD| over the largest |FD| of that response along the path.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import TriMesh, mesh_polygon
from flexopt.fea.plane_stress import (
    Clamp,
    PlaneStressModel,
    PlaneStressSettings,
    Rotate,
    Translate,
)
from flexopt.fea.plane_stress_sensitivity import ks_rho, node_sensitivities
from shapely.geometry import box

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
TIGHT = PlaneStressSettings(rtol_residual=1e-13, atol_residual_N=1e-13)
STRIP = mesh_polygon(box(0.0, 0.0, 10.0, 2.0), 1.0)
# regions as boxes around the end faces: a vertex moved by 1e-5 mm stays selected
CLAMP = Clamp(box(-1.0, -1.0, 1e-3, 3.0))
END = box(10.0 - 1e-3, -1.0, 11.0, 3.0)
IGNORE = box(-1.0, -1.0, 0.5, 3.0)  # elements at the clamp: out of the stress search
RHO = 0.5  # 1/MPa: KS within ln(n)/rho = 8 MPa of a ~100-400 MPa peak
# the spring (torques ~5e4 N·mm, 10k DOFs): round-off floors the residual near 1e-12 of the force
SEA_TIGHT = PlaneStressSettings(rtol_residual=1e-10, atol_residual_N=1e-6)


def _drive(kind: str):
    if kind == "rotate":
        return Rotate(END, (10.0, 1.0), 0.4, 3)
    return Translate(END, (0.3, 1.0), 2.0, 3)  # torque about the end's centroid


def _solve(points: np.ndarray, kinematics: str, drive: str):
    model = PlaneStressModel(
        TriMesh(points, STRIP.triangles), MAT, 1.5, CLAMP, _drive(drive), TIGHT, IGNORE
    )
    return model, model.solve(kinematics, keep_states=True)


def _velocity(points: np.ndarray) -> np.ndarray:
    """A smooth vertex velocity field (n, 2), mm per unit: the strip widened unevenly (its
    stiffness changes at first order), sheared and bent."""
    x, y = points[:, 0], points[:, 1]
    vy = 0.15 * (y - 1.0) * (1.0 + np.cos(x / 4.0)) + 0.1 * np.sin(math.pi * x / 10.0)
    return np.column_stack([0.2 * np.sin(x / 3.0) * (y - 1.0), vy])


@pytest.mark.parametrize(
    ("kinematics", "drive"),
    [("nonlinear", "rotate"), ("linear", "rotate"), ("nonlinear", "translate")],
)
def test_vertex_derivatives_match_central_differences(kinematics: str, drive: str) -> None:
    model, r = _solve(STRIP.points, kinematics, drive)
    assert r.ok
    s = node_sensitivities(model, r, RHO)
    assert list(s.rows) == [1, 2, 3]
    # the responses the derivatives belong to are the solve's own
    np.testing.assert_allclose(s.torque_Nmm, r.torque_Nmm[1:], rtol=1e-12)
    np.testing.assert_allclose(s.force_N, r.reaction_N[1:], rtol=1e-12)
    np.testing.assert_allclose(s.peak_nodal_MPa, r.peak_nodal_stress_MPa[1:], rtol=1e-12)
    assert np.all(s.residual_N < 1e-9)
    V = _velocity(STRIP.points)
    h = 1e-5
    ends = []
    for sign in (1.0, -1.0):
        m2, r2 = _solve(STRIP.points + sign * h * V, kinematics, drive)
        assert np.array_equal(m2.drive_nodes, model.drive_nodes)
        assert np.array_equal(m2.clamp_nodes, model.clamp_nodes)
        ends.append(node_sensitivities(m2, r2, RHO))
    p, m = ends
    for name, der in (("torque_Nmm", "d_torque"), ("ks_MPa", "d_ks")):
        fd = (getattr(p, name) - getattr(m, name)) / (2 * h)
        exact = np.einsum("knj,nj->k", getattr(s, der), V)
        err = np.abs(exact - fd).max() / np.abs(fd).max()
        assert err <= 1e-6, (name, exact, fd, err)
    fd = (p.force_N - m.force_N) / (2 * h)
    exact = np.einsum("kcnj,nj->kc", s.d_force, V)
    assert np.abs(exact - fd).max() / np.abs(fd).max() <= 1e-6


@pytest.mark.parametrize("kinematics", ["nonlinear", "linear"])
def test_scaling_about_the_centre_is_exact(kinematics: str) -> None:
    """Along V = X - c: dT = 2 T, dF = F, dKS = 0 exactly (module docstring)."""
    model, r = _solve(STRIP.points, kinematics, "rotate")
    s = node_sensitivities(model, r, RHO)
    V = STRIP.points - np.array([10.0, 1.0])
    dT = np.einsum("knj,nj->k", s.d_torque, V)
    dF = np.einsum("kcnj,nj->kc", s.d_force, V)
    dks = np.einsum("knj,nj->k", s.d_ks, V)
    np.testing.assert_allclose(dT, 2.0 * s.torque_Nmm, rtol=1e-9)
    np.testing.assert_allclose(dF, s.force_N, rtol=1e-9, atol=1e-9 * np.abs(s.force_N).max())
    # a KS derivative of 1 MPa/mm along V would be ~10 MPa of a scaled-by-2 mesh
    assert np.abs(dks).max() <= 1e-9 * s.ks_MPa.max()


def test_ks_bounds_the_peak() -> None:
    model, r = _solve(STRIP.points, "nonlinear", "rotate")
    s = node_sensitivities(model, r, RHO)
    n = STRIP.n_points
    assert np.all(s.ks_MPa >= s.peak_nodal_MPa)
    assert np.all(s.ks_MPa <= s.peak_nodal_MPa + math.log(n) / RHO)
    assert ks_rho(2000.0) == pytest.approx(0.25)


def test_needs_the_rows_states() -> None:
    model = PlaneStressModel(STRIP, MAT, 1.5, CLAMP, _drive("rotate"), TIGHT, IGNORE)
    r = model.solve("nonlinear")
    with pytest.raises(FeaError, match="keep_states"):
        node_sensitivities(model, r, RHO)


def _sea_model(points: np.ndarray | None = None):
    """The quick SEA study's spiral spring (two arms; pipeline/examples/sea-spring-quick.yaml's
    design) on a coarse mesh (4 mm edges, one P2 element across an arm), hub turned, pads held,
    as :func:`fea.spring_analysis.analyse_spring` sets it up; ``points`` moves its vertices."""
    from flexopt.geometry.arm_spring import build_arm_spring, spiral_params
    from flexopt.geometry.sea_spring import SpringFrame

    values = {"sweep": 479.8427, "R_pad": 32.0660, "F1": 0.4630, "F2": 0.5173, "W1": 5.1975,
              "W2": 3.8465, "W3": 4.4704, "W4": 2.8678, "ST": 10.0}  # fmt: skip
    frame = SpringFrame()
    geom = build_arm_spring(spiral_params(values, 2, frame, 1.5), frame)
    mesh = mesh_polygon(geom.fe_outline, 4.0, refine=geom.mesh_regions(1.0, 4.0))
    if points is not None:
        mesh = TriMesh(points, mesh.triangles)
    model = PlaneStressModel(
        mesh, Material("maraging", E_MPa=190e3, nu=0.3, yield_MPa=2000.0), 10.0,
        Clamp(geom.pad_region), Rotate(geom.hub_region, (0.0, 0.0), 53.0 / 275.0, 2), SEA_TIGHT,
        geom.hub_region.union(geom.pad_region).buffer(0.05),
    )  # fmt: skip
    return mesh, model


@pytest.mark.slow
def test_sea_spring_coarse_mesh_matches_central_differences() -> None:
    """The SEA spring's torque rows and KS stress (rho = 500 / yield) on a coarse mesh, along a
    smooth velocity field of every vertex, against central differences of the nonlinear solve."""
    mesh, model = _sea_model()
    r = model.solve("nonlinear", keep_states=True)
    assert r.ok
    rho = ks_rho(2000.0)
    s = node_sensitivities(model, r, rho)
    x, y = mesh.points[:, 0], mesh.points[:, 1]
    V = np.column_stack([np.sin(y / 7.0), np.cos(x / 9.0) * np.sin(y / 11.0)])
    # the residual's round-off floor here is ~2e-7 N of ~1e3 N: h = 1e-4 mm keeps its noise in
    # the difference near 1e-8 (measured: 1.3e-8 torque, 6e-9 KS); at 1e-3 mm a vertex near a
    # pad's washer circle already leaves the clamp (the asserts below)
    h = 1e-4
    ends = []
    for sign in (1.0, -1.0):
        _, m2 = _sea_model(mesh.points + sign * h * V)
        assert np.array_equal(m2.drive_nodes, model.drive_nodes)
        assert np.array_equal(m2.clamp_nodes, model.clamp_nodes)
        assert np.array_equal(m2.stress_mask, model.stress_mask)
        ends.append(node_sensitivities(m2, m2.solve("nonlinear", keep_states=True), rho))
    p, m = ends
    for name, der in (("torque_Nmm", "d_torque"), ("ks_MPa", "d_ks")):
        fd = (getattr(p, name) - getattr(m, name)) / (2 * h)
        exact = np.einsum("knj,nj->k", getattr(s, der), V)
        err = np.abs(exact - fd).max() / np.abs(fd).max()
        assert err <= 1e-6, (name, exact, fd, err)
    # KS is an upper bound of the judged peak, close to it on this mesh
    assert np.all(s.ks_MPa >= s.peak_nodal_MPa)
