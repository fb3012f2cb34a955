"""The peak convergence's warm start (fea/solid3d.converge_peak_stress, issue 27 item 3): the
displacement carried from one mesh to the next (fea/plane_stress.interpolate_displacement) and
the refined solves started from it land on the equilibrium the cold solves find.

Units: mm, N, MPa, rad.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Rotate, interpolate_displacement
from flexopt.fea.solid3d import converge_peak_stress
from shapely.geometry import LineString, Point, box

STEEL = Material("steel", 200_000.0, 0.3, 2000.0)


def _model(mesh):
    return PlaneStressModel(
        mesh, STEEL, 1.0, Clamp(LineString([(0, 0), (0, 10)])),
        Rotate(LineString([(40, 0), (40, 10)]), (40.0, 5.0), 0.01, 1),
    )  # fmt: skip


def _quadratic(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A field of degree 2 in x and y (mm), any coefficients."""
    x, y = xy[:, 0], xy[:, 1]
    return 0.3 + 0.02 * x - 0.05 * y + 1e-3 * x * x - 2e-3 * x * y + 4e-3 * y * y, (
        -0.1 + 0.01 * x + 0.03 * y - 3e-3 * x * x + 1e-3 * x * y - 5e-4 * y * y
    )


def test_interpolation_reproduces_a_quadratic_field_on_another_mesh():
    """P2 holds any quadratic exactly, so its values at every node of another mesh of the same
    plate-with-a-hole (vertices, mid-edges, the boundary's nodes included) are the field's,
    to round-off; a wrong triangle or shape function would be off by the field's curvature."""
    plate = box(0, 0, 40, 10).difference(Point(20, 5).buffer(3.0, quad_segs=16))
    src = _model(mesh_polygon(plate, 2.0))
    dst = _model(mesh_polygon(plate, 0.7, refine=[(Point(20, 5).buffer(5.0), 0.2)]))
    assert dst.n_dofs > 3 * src.n_dofs
    u = np.zeros(src.n_dofs)
    u[src.ix], u[src.iy] = _quadratic(src.xy)
    v = interpolate_displacement(src, u, dst)
    ex, ey = _quadratic(dst.xy)
    assert np.max(np.abs(v[dst.ix] - ex)) < 1e-12
    assert np.max(np.abs(v[dst.iy] - ey)) < 1e-12


def test_warm_started_peak_convergence_is_the_cold_one_to_the_newton_tolerance():
    """A slender strip clamped at one end, its other end turned by 0.3 rad about its centre
    (large rotation and stretch: 7 Newton iterations from rest). Every round of the
    warm-started convergence (the first from the perturbation predictor, the refined ones from
    the last mesh's answer interpolated) lands on the cold solves' equilibrium: the same
    meshes, the same peak location and the peaks within 1e-9 (Newton stops at a residual of
    1e-9 of the force; a different equilibrium, a buckled or reflected state, moves the peak
    by percent), in fewer iterations."""
    args = (
        box(0, 0, 80, 2), 1.0, STEEL, Clamp(LineString([(0, 0), (0, 2)])),
        Rotate(LineString([(80, 0), (80, 2)]), (80.0, 1.0), 0.3, 1), 1.0,
    )  # fmt: skip
    ends = box(-1, -1, 1, 3).union(box(79, -1, 81, 3))  # the held ends' corners: singular
    kw = dict(stress_ignore=ends, kinematics="nonlinear", max_rounds=3)
    cold = converge_peak_stress(*args, warm_start=False, **kw)
    warm = converge_peak_stress(*args, **kw)
    assert cold["guess"] == ["none"] * 3
    assert warm["guess"] == ["used"] * 3
    assert warm["triangles"] == cold["triangles"]
    # a stable path: every tangent positive definite, cold and warm (no branch to jump to)
    assert cold["cholesky_failures"] == warm["cholesky_failures"] == [0, 0, 0]
    assert warm["peak_xy_mm"] == pytest.approx(cold["peak_xy_mm"], abs=1e-12)
    assert warm["peaks_MPa"] == pytest.approx(cold["peaks_MPa"], rel=1e-9)
    # the refinement is real (the peaks move by more than the tolerance between rounds)
    assert abs(cold["peaks_MPa"][1] / cold["peaks_MPa"][0] - 1.0) > 1e-6
    assert min(cold["newton_iterations"]) >= 4
    pairs = zip(warm["newton_iterations"], cold["newton_iterations"], strict=True)
    assert all(w < c for w, c in pairs)


def test_linear_peak_convergence_has_no_warm_start():
    """Linear kinematics solve once, with no Newton iteration to spare: no guess is made."""
    r = converge_peak_stress(
        box(0, 0, 40, 4), 1.0, STEEL, Clamp(LineString([(0, 0), (0, 4)])),
        Rotate(LineString([(40, 0), (40, 4)]), (40.0, 2.0), 0.01, 1), 1.0,
        stress_ignore=box(-1, -1, 1, 5), max_rounds=3,
    )  # fmt: skip
    assert r["guess"] == ["none"] * len(r["peaks_MPa"])
