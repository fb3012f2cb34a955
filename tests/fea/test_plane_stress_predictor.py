"""The plane-stress Newton's starting points (issue 13): PlaneStressModel.series_predictor and
the ``guess`` of PlaneStressModel.solve.

References computed here: the nonlinear equilibrium itself (solved to 1e-13 of the force), whose
expansion in the drive value the predictor's error must follow at the rates the derivation in
its docstring gives (v², v³ and v⁴ under halving the angle), and the solve without a guess.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import (
    Clamp,
    PlaneStressModel,
    PlaneStressSettings,
    Rotate,
    Translate,
)
from shapely.geometry import LineString, Point, box
from shapely.ops import unary_union

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
TIGHT = PlaneStressSettings(rtol_residual=1e-12, atol_residual_N=1e-12)


def slit_ring():
    """A slit ring (3 to 8 mm), its mesh, its clamp spot and its inner edge (the hub)."""
    poly = (
        Point(0, 0)
        .buffer(8.0, quad_segs=16)
        .difference(Point(0, 0).buffer(3.0, quad_segs=16))
        .difference(box(5.0, -0.5, 9.0, 0.5))
    )
    return mesh_polygon(poly, 1.0), Clamp(Point(-8.0, 0.0).buffer(1.0)), poly.interiors[0]


@pytest.fixture(scope="module")
def ring():
    return slit_ring()


def ring_model(ring, value: float, settings: PlaneStressSettings = TIGHT) -> PlaneStressModel:
    mesh, clamp, hub = ring
    return PlaneStressModel(mesh, MAT, 2.0, clamp, Rotate(hub, (0, 0), value, 1), settings)


def test_series_predictor_errors_fall_at_the_derived_orders(ring):
    # u(v) - u_odd = O(v²), u(v) - (u_odd + u_even) = O(v³), u(-v) - (2 u_even - u(v)) = O(v⁴):
    # halving the angle divides them by ~4, ~8 and ~16.
    errors = []
    for v in (0.05, 0.025, 0.0125):
        m = ring_model(ring, v)
        u_odd, u_even = m.series_predictor(v)
        fwd = m.solve("nonlinear")
        back = ring_model(ring, -v).solve("nonlinear")
        assert fwd.ok and back.ok

        def size(x):
            return float(np.abs(x).max())

        errors.append(
            [
                size(fwd.dofs - u_odd),
                size(fwd.dofs - u_odd - u_even),
                size(back.dofs - (2.0 * u_even - fwd.dofs)),
            ]
        )
    errors = np.array(errors)
    ratios = errors[1] / errors[2]
    np.testing.assert_allclose(ratios, [4.0, 8.0, 16.0], rtol=0.12)
    # and each level is a real improvement at these angles
    assert np.all(errors[:, 0] > errors[:, 1]) and np.all(errors[:, 1] > errors[:, 2])


def test_u_odd_is_the_linear_solution_of_a_translation(ring):
    # A translation's prescribed motion is linear in the drive: u_odd is the linear solve's
    # field exactly (same matrix, same right-hand side), and u_even answers only f2.
    mesh, clamp, hub = ring
    m = PlaneStressModel(mesh, MAT, 2.0, clamp, Translate(hub, (1.0, 0.0), 0.2, 1))
    lin = m.solve("linear")
    u_odd, u_even = m.series_predictor(0.2)
    np.testing.assert_allclose(u_odd, lin.dofs, rtol=0, atol=1e-12 * np.abs(lin.dofs).max())
    assert np.all(u_even[np.concatenate([m.drive_dofs_x, m.drive_dofs_y])] == 0.0)


def two_arm_spring(value: float, settings: PlaneStressSettings) -> PlaneStressModel:
    """A hub (radius 5 mm) with two 1.2 mm arms out to pads clamped at x = +-30 mm, turned by
    ``value`` rad: slender members turned through large angles, as in a SEA spring."""
    poly = unary_union([Point(0, 0).buffer(5.0, quad_segs=16), box(-30, -0.6, 30, 0.6)])
    hub = Point(0, 0).buffer(5.0, quad_segs=16)
    clamp = Clamp(unary_union([box(-31, -1, -29, 1), box(29, -1, 31, 1)]))
    mesh = mesh_polygon(poly, 0.6)
    return PlaneStressModel(mesh, MAT, 2.0, clamp, Rotate(hub, (0, 0), value, 1), settings)


@pytest.mark.parametrize("assembly", ["compiled", "vectorised"])
def test_a_guess_gives_the_same_answer_in_fewer_iterations(assembly):
    v = 0.2  # the torque is 1.8x the linear one here
    cfg = PlaneStressSettings(rtol_residual=1e-9, assembly=assembly)
    plain = two_arm_spring(v, cfg).solve("nonlinear")
    m = two_arm_spring(v, cfg)
    u_odd, u_even = m.series_predictor(v)
    guessed = m.solve("nonlinear", guess=u_odd + u_even)
    back_plain = two_arm_spring(-v, cfg).solve("nonlinear")
    back = two_arm_spring(-v, cfg).solve("nonlinear", guess=2.0 * u_even - guessed.dofs)
    for a, b in ((plain, guessed), (back_plain, back)):
        assert a.ok and b.ok and b.extra["guess"] == "used" and a.extra["guess"] == "none"
        # both stop at 1e-9 of the force: the torques agree to about that
        np.testing.assert_allclose(b.torque_Nmm, a.torque_Nmm, rtol=1e-8, atol=1e-9)
        np.testing.assert_allclose(b.dofs, a.dofs, rtol=0, atol=1e-8 * np.abs(a.dofs).max())
        assert b.iterations.sum() < a.iterations.sum()


def test_a_guess_whose_residual_explodes_is_dropped():
    # At 0.3 rad (torque 3x the linear one) the reflected guess is outside Newton's basin: its
    # first step meets an indefinite tangent and the residual grows 160-fold. The row is solved
    # from the linearised step, the same iterates as without a guess.
    v, cfg = 0.3, PlaneStressSettings(rtol_residual=1e-9)
    m = two_arm_spring(v, cfg)
    u_odd, u_even = m.series_predictor(v)
    fwd = m.solve("nonlinear", guess=u_odd + u_even)
    plain = two_arm_spring(-v, cfg).solve("nonlinear")
    back = two_arm_spring(-v, cfg).solve("nonlinear", guess=2.0 * u_even - fwd.dofs)
    assert fwd.ok and back.ok and back.extra["guess"].startswith("failed: ")
    assert np.array_equal(back.dofs, plain.dofs)
    assert back.iterations.sum() <= plain.iterations.sum() + 2


def test_a_failing_guess_falls_back_to_the_linearised_step(ring):
    v = 0.2
    plain = ring_model(ring, v).solve("nonlinear")
    m = ring_model(ring, v)
    u_odd, u_even = m.series_predictor(v)
    wild = 40.0 * (u_odd + u_even)  # turns elements inside out
    r = m.solve("nonlinear", guess=wild)
    assert r.ok and r.extra["guess"].startswith("failed: element inverted")
    # the row is then solved from the same state as without a guess: the same iterates
    assert np.array_equal(r.dofs, plain.dofs)
    assert np.array_equal(r.torque_Nmm, plain.torque_Nmm)
    assert r.iterations.sum() > plain.iterations.sum()  # the failed try is counted


def test_a_converged_guess_converges_at_once_and_prescribed_dofs_are_kept():
    # A strip pulled sideways with its drive free transversely: the shared sliding unknown is
    # read from the guess too (P is not a pure selection there).
    L, h = 20.0, 2.0
    mesh = mesh_polygon(box(0.0, 0.0, L, h), 0.5)
    clamp = Clamp(LineString([(0, 0), (0, h)]))
    drive = Translate(LineString([(L, 0), (L, h)]), (0.0, 1.0), 3.0, 1, transverse="free")

    def model():
        return PlaneStressModel(mesh, MAT, 1.0, clamp, drive, TIGHT)

    first = model().solve("nonlinear")
    again = model().solve("nonlinear", guess=first.dofs)
    assert first.ok and again.ok and again.extra["guess"] == "used"
    assert again.iterations[1] == 1  # the guess is already in equilibrium
    np.testing.assert_allclose(again.dofs, first.dofs, rtol=0, atol=1e-12)
    # a guess that moves the clamp does not move it
    m = model()
    off = first.dofs.copy()
    off[m.clamp_dofs] = 5.0
    r = m.solve("nonlinear", guess=off)
    assert r.ok and np.all(r.dofs[m.clamp_dofs] == 0.0)
    np.testing.assert_allclose(r.dofs, first.dofs, rtol=0, atol=1e-10)


def test_bad_guess_or_value_is_refused(ring):
    m = ring_model(ring, 0.1)
    with pytest.raises(FeaError, match="guess must be a finite"):
        m.solve("nonlinear", guess=np.zeros(3))
    bad = np.zeros(m.n_dofs)
    bad[0] = np.nan
    with pytest.raises(FeaError, match="guess must be a finite"):
        m.solve("nonlinear", guess=bad)
    with pytest.raises(FeaError, match="must be finite"):
        m.series_predictor(float("inf"))


def test_a_guessed_solve_assembles_no_tangent_at_rest():
    # session 32: with a guess, the rest state's tangent (unused unless the guess fails) is not
    # assembled: one tangent fewer than Newton's iterates, and the same answer to the bit as
    # the same guessed solve on a model whose rest tangent was already assembled (and so free).
    v, cfg = 0.2, PlaneStressSettings(rtol_residual=1e-9, assembly="compiled")
    m = two_arm_spring(v, cfg)
    u_odd, u_even = m.series_predictor(v)
    fresh = two_arm_spring(v, cfg)
    res = fresh.solve("nonlinear", guess=u_odd + u_even)
    assert res.ok and res.extra["guess"] == "used"
    # a tangent at each Newton iterate but the converged one (force only: the likely-converged
    # rule of _increment), and none at rest (before: 5 tangents for these 5 iterations)
    assert fresh.counters["tangents"] == int(res.iterations.sum()) - 1
    warm = two_arm_spring(v, cfg)
    warm.linear_stiffness()  # the rest tangent kept: solve's rest state is then free
    again = warm.solve("nonlinear", guess=u_odd + u_even)
    assert np.array_equal(again.dofs, res.dofs)
    assert np.array_equal(again.torque_Nmm, res.torque_Nmm)
