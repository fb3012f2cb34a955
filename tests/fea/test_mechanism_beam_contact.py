"""Beam-beam contact in the mechanism engine (``Mechanism.beam_contacts``, fea.stops.
BeamPairContact) against answers computed here:

* the gap's gradient and Hessian (the penalty's force and tangent) against finite differences;
* a cantilever A pushed down at its tip onto the tip of a stiffer cantilever B under its middle
  (small deflection): the superposition of the two Timoshenko cantilevers' flexibilities
  (A loaded at its tip and at the contact, B at its tip), derived below — the drive's reaction
  and the contact force;
* an undeclared pair passes through (no force), a declared pair of beams joined at an end is
  refused.
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
    MechDrive,
    MechJoint,
    MechOutput,
    solve_mechanism,
)
from flexopt.fea.stops import BeamPairContact, ContactSettings

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
L, T, W = 100.0, 0.5, 2.0  # beam A, mm
LB, TB = 50.0, 1.0  # beam B: half as long, twice as thick (8x EI)
G0 = 0.02  # mm between A's lower surface and B's tip at rest
A_AT = L / 2  # where B's tip is under A


def flexibility(x, c, t):
    """Downward deflection (mm) at x of a Timoshenko cantilever (thickness t, width W) clamped
    at 0 under a unit downward force at c: x^2 (3c - x) / 6EI (x <= c), c^2 (3x - c) / 6EI
    (x >= c), plus min(x, c) / kGA."""
    ei = MAT.E_MPa * W * t**3 / 12.0
    kga = 5.0 / 6.0 * MAT.G_MPa * W * t
    bend = x**2 * (3 * c - x) / 6 if x <= c else c**2 * (3 * x - c) / 6
    return bend / ei + min(x, c) / kga


def pressed(delta):
    """Tip force P on A and the contact force R (N) with A's tip moved down ``delta`` mm:
    A: w(x) = P f_A(x, L) - R f_A(x, a); B's tip: w_B = R f_B(LB, LB); after contact
    w(a) - G0 = w_B and w(L) = delta."""
    fll, fal = flexibility(L, L, T), flexibility(A_AT, L, T)
    fla, faa = flexibility(L, A_AT, T), flexibility(A_AT, A_AT, T)
    fb = flexibility(LB, LB, TB)
    closing = G0 * fll / fal
    if delta <= closing:
        return delta / fll, 0.0, closing
    P, R = np.linalg.solve([[fal, -(faa + fb)], [fll, -fla]], [G0, delta])
    return P, R, closing


def two_cantilevers(declared=True, joined=False):
    yb = -(T / 2 + TB / 2 + G0)
    a = MechBeam("A", np.array([[0.0, 0.0], [L, 0.0]]), np.array([T, T]), W, 20)
    b_pts = [[A_AT - LB, yb], [A_AT, yb]] if not joined else [[L, 0.0], [L, -LB]]
    b = MechBeam("B", np.array(b_pts), np.array([TB, TB]), W, 10)
    joints = (MechJoint("A.start", "ground"), MechJoint("B.start", "ground"))
    pairs = (("A", "B"),) if declared else ()
    mech = Mechanism((a, b), (), joints, MAT, (), pairs)
    drive = MechDrive("A.end", "displacement", 0.2, 10, (0.0, -1.0))
    case = LoadCase("push", drive)
    return solve_mechanism(mech, case, (MechOutput("P", "reaction"),), MechanismSettings())


def test_the_gap_derivatives_are_exact():
    """The penalty's force and tangent are the gap's gradient and Hessian: against central
    differences of the gap (and of the gradient) over the node and the other beam's element."""
    from flexopt.fea.beam import BeamModel, BeamSettings
    from flexopt.geometry.profile import BeamProfile

    def beam(points, t0, t1):
        prof = BeamProfile(np.array(points), np.array([t0, t1]), W)
        return BeamModel(prof, MAT, settings=BeamSettings(n_elements=1))

    pair = BeamPairContact(
        beam([[4.0, 3.0], [4.0, 0.8]], 0.4, 0.4),  # a: its end node over b, 0.6 mm above
        beam([[0.0, 0.0], [10.0, 0.5]], 0.6, 0.4),  # b: tapered
        ContactSettings(),
    )
    xa = pair.sides[0].model.reference_nodes_mm.copy()
    xb = pair.sides[1].model.reference_nodes_mm.copy()
    xb[1] += [0.0, 0.6]  # b's middle node moved up: its curve rises 0.48 mm under a's node

    def first(xa, xb):  # the pair of a's end node (node 2) against b's element 0
        return next(p for p in pair.pairs(xa, xb, active_only=False) if p[:3] == (0, 2, 0))

    p0 = first(xa, xb)
    assert p0[3] < 0.0  # in contact: a's disk overlaps b's
    rng = np.random.default_rng(3)
    h = 1e-6
    for _ in range(3):
        d = rng.standard_normal(8)

        def shifted(step, d=d):
            ya, yb = xa.copy(), xb.copy()
            ya[2] += step * d[:2]
            yb[:3] += step * d[2:].reshape(3, 2)
            return first(ya, yb)

        plus, minus = shifted(h), shifted(-h)
        assert (plus[3] - minus[3]) / (2 * h) == pytest.approx(p0[4] @ d, rel=1e-6)
        # entries ~5e-2: 1e-7 is the differences' own error (h^2 and round-off / h)
        np.testing.assert_allclose((plus[4] - minus[4]) / (2 * h), p0[5] @ d, rtol=1e-5,
                                   atol=1e-7)  # fmt: skip


def test_a_cantilever_pressed_on_another_is_the_superposition_of_their_flexibilities():
    res = two_cantilevers()
    assert res.ok, res.message
    c = res.beam_contact["A/B"]
    exact = np.array([pressed(d) for d in res.drive])
    np.testing.assert_allclose(res.outputs["P"], exact[:, 0], rtol=1e-4, atol=1e-12)
    np.testing.assert_allclose(c["force_N"], exact[:, 1], rtol=1e-4, atol=1e-12)
    assert np.array_equal(c["in_contact"], res.drive > exact[0, 2])
    assert c["gap_mm"][0] == pytest.approx(G0, rel=1e-9)
    before = res.drive < exact[0, 2]
    np.testing.assert_allclose(c["gap_mm"][before], G0 * (1 - res.drive[before] / exact[0, 2]),
                               atol=1e-6)  # fmt: skip
    assert -c["gap_mm"].min() < 1e-3 * T  # the penetration, within the tolerance
    assert res.stable.all()


def test_an_undeclared_pair_passes_through_and_a_joined_pair_is_refused():
    free = two_cantilevers(declared=False)
    assert free.beam_contact is None
    # A alone: the plain cantilever all the way (B's tip passes through it)
    np.testing.assert_allclose(free.outputs["P"], free.drive / flexibility(L, L, T), rtol=1e-4)
    with pytest.raises(FeaError, match=r"beam contact \[A, B\]: the beams overlap undeformed"):
        two_cantilevers(joined=True)
