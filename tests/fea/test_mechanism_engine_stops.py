"""Rigid stops in the mechanism engine (fea/mechanism.py with fea/stops.py) against answers
derived here: a cantilever modelled as a mechanism (one beam clamped to the ground, its end
driven) pushed onto a stop at mid-span, against the propped Timoshenko cantilever in small
deflection (the same superposition fea/stops.py's tests use for the plain beam, derived again
here); an untouched stop gives the plain solve; a stop on a rigid body's path (the body does
not touch it) and on a parallel guide's leaf.
"""

import numpy as np
import pytest
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mechanism import (
    LoadCase,
    Mechanism,
    MechanismSettings,
    MechBeam,
    MechBody,
    MechDrive,
    MechJoint,
    MechOutput,
    solve_mechanism,
)
from flexopt.fea.stops import ContactSettings, RigidStop

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
L, T, B = 100.0, 0.5, 2.0
EI = MAT.E_MPa * B * T**3 / 12.0  # N mm^2
KGA = 5.0 / 6.0 * MAT.G_MPa * B * T  # N
G0 = 0.02  # mm, between the beam's lower surface and the stop
A = L / 2  # mm, where the stop is


def cantilever_deflection(x, a):
    """Downward deflection (mm) at x of a Timoshenko cantilever clamped at 0 under a unit
    downward force at a: x^2 (3a - x) / 6EI (x <= a), a^2 (3x - a) / 6EI (x >= a), plus the
    shear term min(x, a) / kGA."""
    bend = x**2 * (3 * a - x) / 6 if x <= a else a**2 * (3 * x - a) / 6
    return bend / EI + min(x, a) / KGA


def propped(delta, a, g0):
    """Tip force P, stop reaction R (N) and the closing tip displacement (mm) of the cantilever
    with its tip pushed down by ``delta`` (mm) onto a stop a gap ``g0`` (mm) below the beam at x
    = a: before contact R = 0, P = delta / w_LL; after it w(a) = g0 and w(L) = delta, with
    w = P w_L - R w_a (superposition)."""
    w_ll, w_al = cantilever_deflection(L, L), cantilever_deflection(a, L)
    w_la, w_aa = cantilever_deflection(L, a), cantilever_deflection(a, a)
    closing = g0 * w_ll / w_al
    if delta <= closing:
        return delta / w_ll, 0.0, closing
    P, R = np.linalg.solve([[w_al, -w_aa], [w_ll, -w_la]], [g0, delta])
    return P, R, closing


def cantilever(stops=(), kernel="auto", n=20):
    beam = MechBeam("leaf", np.array([[0.0, 0.0], [L, 0.0]]), np.array([T, T]), B, n)
    mech = Mechanism((beam,), (), (MechJoint("leaf.start", "ground"),), MAT, tuple(stops))
    drive = MechDrive("leaf.end", "displacement", 0.2, 10, (0.0, -1.0))
    case = LoadCase("push", drive)
    outs = (MechOutput("P", "reaction"), MechOutput("tip_mm", "displacement", "leaf.end"))
    return solve_mechanism(mech, case, outs, MechanismSettings(kernel=kernel))


def stop_at(a, kind):
    y = -(T / 2 + G0)
    if kind == "point":
        return RigidStop.point((a, y), "pin")
    if kind == "polygon":
        return RigidStop.polygon([[a - 10, y - 5], [a, y - 5], [a, y], [a - 10, y]], "block")
    return RigidStop.segment((a - 10, y), (a, y), "wall")


@pytest.mark.parametrize("kind", ["point", "polygon", "segment"])
def test_mechanism_cantilever_on_a_stop_is_the_propped_cantilever(kind):
    res = cantilever([stop_at(A, kind)])
    assert res.ok, res.message
    c = res.contact
    exact = [propped(d, A, G0) for d in res.drive]
    P = np.array([e[0] for e in exact])
    R = np.array([e[1] for e in exact])
    closing = exact[0][2]
    # the drive's reaction and the stop's force: the reaction split of the propped beam
    np.testing.assert_allclose(res.outputs["P"], P, rtol=2e-5, atol=1e-12)
    np.testing.assert_allclose(c.force_N[:, 0], R, rtol=2e-5, atol=1e-12)
    assert c.force_vector_N[-1, 0, 1] > 0.0  # the stop pushes the beam up
    np.testing.assert_allclose(c.extra["force_by_beam_N"][:, 0, 0], c.force_N[:, 0])
    assert c.names == (stop_at(A, kind).name,)
    assert c.initial_gap_mm[0] == pytest.approx(G0, rel=1e-12)
    assert c.closing_value[0] == pytest.approx(closing, rel=1e-4)
    assert np.array_equal(c.in_contact[:, 0], res.drive > closing)
    before = res.drive < closing
    np.testing.assert_allclose(
        c.gap_mm[before, 0], G0 * (1 - res.drive[before] / closing), atol=1e-6
    )
    touching = c.in_contact[:, 0]
    np.testing.assert_allclose(c.point_mm[touching, 0], [[A, -(T / 2 + G0)]] * touching.sum())
    assert np.all(np.isnan(c.point_mm[~touching, 0]))
    assert c.penetration_ok and c.max_penetration_mm.max() < 1e-5
    assert c.extra["raises"] == 0 and c.extra["penalty_factor"] == 1e3
    assert res.stable.all()  # the stop stiffens: still stable


def test_no_stop_and_an_untouched_stop_give_the_plain_solve():
    plain = cantilever()
    assert plain.contact is None
    for kernel in ("numpy", "auto"):
        ref = cantilever(kernel=kernel)
        far = cantilever([RigidStop.point((50.0, -5.0)), stop_at(150.0, "point")], kernel)
        c = far.contact
        assert not c.rows_in_contact.any() and np.all(c.force_N == 0.0)
        assert np.all(np.isnan(c.closing_value))
        for name in ("P", "tip_mm"):
            if kernel == "numpy":  # the same loop adding exact zeros
                assert np.array_equal(far.outputs[name], ref.outputs[name])
            else:  # the reference loop against the compiled one: round-off
                np.testing.assert_allclose(far.outputs[name], ref.outputs[name], rtol=1e-8)
        if kernel == "numpy":
            assert np.array_equal(far.shapes_mm[0], ref.shapes_mm[0])
        np.testing.assert_allclose(far.shapes_mm[0], ref.shapes_mm[0], rtol=0, atol=1e-10)


def test_a_stop_overlapping_a_beam_is_refused():
    with pytest.raises(FeaError, match="overlaps beam 'leaf'"):
        cantilever([RigidStop.point((50.3, -0.1), "inside")])


def test_penetration_beyond_the_tolerance_raises_the_penalty():
    beam = MechBeam("leaf", np.array([[0.0, 0.0], [L, 0.0]]), np.array([T, T]), B, 20)
    mech = Mechanism((beam,), (), (MechJoint("leaf.start", "ground"),), MAT, (stop_at(A, "point"),))
    case = LoadCase("push", MechDrive("leaf.end", "displacement", 0.2, 10, (0.0, -1.0)))
    soft = MechanismSettings(contact=ContactSettings(1e-2, max_raises=0))
    c = solve_mechanism(mech, case, (), soft).contact
    assert not c.penetration_ok and "penalty_factor" in c.message
    raised = MechanismSettings(contact=ContactSettings(1e-2, max_raises=3))
    c = solve_mechanism(mech, case, (), raised).contact
    assert c.penetration_ok and c.extra["raises"] == 3 and c.extra["penalty_factor"] == 10.0


def test_parallel_guide_leaf_on_an_overtravel_stop():
    """Two leaves and a shuttle: a pin under the lower leaf's middle. A guided leaf's middle
    moves half the shuttle's travel (antisymmetric S-shape), so the gap closes at twice the
    gap; before that the solve is the guide's without the stop, after it the stop carries
    force and the drive needs more."""
    Lg, t = 40.0, 1.0
    beams = tuple(
        MechBeam(n, np.array([[0.0, y], [Lg, y]]), np.array([t, t]), 5.0, 20)
        for n, y in (("upper", 10.0), ("lower", -10.0))
    )
    body = MechBody("shuttle", np.array([44.0, 0.0]))
    joints = (
        MechJoint("upper.start", "ground"),
        MechJoint("lower.start", "ground"),
        MechJoint("upper.end", "shuttle"),
        MechJoint("lower.end", "shuttle"),
    )
    gap = 0.3
    stop = RigidStop.point((Lg / 2, -10.0 - t / 2 - gap), "overtravel")
    case = LoadCase("stroke", MechDrive("shuttle", "displacement", -1.0, 20, (0.0, 1.0)))
    outs = (MechOutput("F", "reaction"),)
    free = solve_mechanism(Mechanism(beams, (body,), joints, MAT), case, outs)
    res = solve_mechanism(Mechanism(beams, (body,), joints, MAT, (stop,)), case, outs)
    assert res.ok, res.message
    c = res.contact
    # a guided leaf's middle moves half the shuttle's travel: contact at -2 x gap
    assert c.closing_value[0] == pytest.approx(-2 * gap, rel=2e-3)
    clear = ~c.rows_in_contact
    np.testing.assert_allclose(res.outputs["F"][clear], free.outputs["F"][clear], rtol=1e-8)
    # beyond contact the stop carries force and the guide is stiffer
    assert c.force_N[-1, 0] > 0.0 and res.outputs["F"][-1] < free.outputs["F"][-1]
