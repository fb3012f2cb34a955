"""Rigid stops in the constrained-beam engine (fea/constrained_beams.py with fea/stops.py)
against answers computed here:

* small deflection: a cantilever (start clamped, tip pushed down by a prescribed displacement,
  tip free to slide and turn) onto a stop at mid-span is the propped Timoshenko cantilever (the
  reaction split by superposition of the two cantilever flexibilities, derived below);
* large deflection: the same cantilever pushed down by 40 % of its length onto the corner of a
  flat stop, against scipy's ``solve_bvp`` of the elastica with a contact point (two segments
  joined at the unknown contact arc length, the stop's force normal to the beam there);
* no stop, or a stop never touched, gives the solve without stops.
"""

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel, BeamSettings
from flexopt.fea.constrained_beams import ConstrainedBeams
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.stops import RigidStop
from flexopt.geometry.profile import BeamProfile
from scipy.integrate import solve_bvp

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
L, T, B = 100.0, 0.5, 2.0
EI = MAT.E_MPa * B * T**3 / 12.0  # N mm^2
KGA = 5.0 / 6.0 * MAT.G_MPa * B * T  # N


def cantilever_system(stops=(), n=20, kernel="auto", contact=None):
    """A cantilever along x, start clamped, its tip's v held at -p (p the path parameter, mm);
    the tip's u and rotation free, so the only tip load is the vertical force P."""
    from flexopt.fea.constrained_beams import ConstrainedSettings

    profile = BeamProfile(np.array([[0.0, 0.0], [L, 0.0]]), np.array([T, T]), B)
    model = BeamModel(profile, MAT, settings=BeamSettings(n_elements=n))

    def constraints(p):
        C = system.rows(4)
        d = np.zeros(4)
        row = system.clamp_start(C, 0, 0)
        C[row, system.dof(0, -1, 1)] = 1.0
        d[row] = -p
        return C, d

    settings = ConstrainedSettings(kernel=kernel)
    system = ConstrainedBeams(
        [model], 0, constraints, settings=settings, stops=stops, contact=contact
    )
    return system


def tip_force(res):
    """(rows,) the downward force P (N) on the tip: minus the multiplier of its v row."""
    return -res.multipliers[:, 3]


# ---------------------------------------------------------------------------- small deflection


def cantilever_deflection(x, a):
    """Downward deflection (mm) at x of a Timoshenko cantilever clamped at 0 under a unit
    downward force at a: x^2 (3a - x) / 6EI (x <= a), a^2 (3x - a) / 6EI (x >= a), plus the
    shear term min(x, a) / kGA."""
    bend = x**2 * (3 * a - x) / 6 if x <= a else a**2 * (3 * x - a) / 6
    return bend / EI + min(x, a) / KGA


def propped(delta, a, g0):
    """Tip force P, stop reaction R (N) and the closing tip displacement (mm) with the tip pushed
    down by ``delta`` (mm) onto a stop a gap ``g0`` (mm) below the beam at x = a: before contact
    R = 0, P = delta / w_LL; after it w(a) = g0 and w(L) = delta, w = P w_L - R w_a."""
    w_ll, w_al = cantilever_deflection(L, L), cantilever_deflection(a, L)
    w_la, w_aa = cantilever_deflection(L, a), cantilever_deflection(a, a)
    closing = g0 * w_ll / w_al
    if delta <= closing:
        return delta / w_ll, 0.0, closing
    P, R = np.linalg.solve([[w_al, -w_aa], [w_ll, -w_la]], [g0, delta])
    return P, R, closing


def stop_at(a, g0, kind):
    y = -(T / 2 + g0)
    if kind == "point":
        return RigidStop.point((a, y), "pin")
    if kind == "polygon":
        return RigidStop.polygon([[a - 10, y - 5], [a, y - 5], [a, y], [a - 10, y]], "block")
    return RigidStop.segment((a - 10, y), (a, y), "wall")


@pytest.mark.parametrize("kind", ["point", "polygon", "segment"])
def test_cantilever_on_a_stop_is_the_propped_cantilever(kind):
    g0, a = 0.02, L / 2
    system = cantilever_system([stop_at(a, g0, kind)])
    assert system.kernel == "numpy"  # the contact terms run in the reference loop
    drive = np.linspace(0.0, 0.2, 11)
    res = system.solve(drive)
    assert res.ok, res.message
    c = res.contact
    exact = np.array([propped(d, a, g0) for d in drive])
    np.testing.assert_allclose(tip_force(res), exact[:, 0], rtol=2e-5, atol=1e-12)
    np.testing.assert_allclose(c.force_N[:, 0], exact[:, 1], rtol=2e-5, atol=1e-12)
    assert c.force_vector_N[-1, 0, 1] > 0.0  # the stop pushes the beam up
    closing = exact[0, 2]
    assert c.closing_value[0] == pytest.approx(closing, rel=1e-4)
    assert np.array_equal(c.in_contact[:, 0], drive > closing)
    assert c.initial_gap_mm[0] == pytest.approx(g0, rel=1e-12)
    touching = c.in_contact[:, 0]
    np.testing.assert_allclose(c.point_mm[touching, 0], [[a, -(T / 2 + g0)]] * touching.sum())
    assert c.penetration_ok and c.max_penetration_mm.max() < 1e-5
    assert c.extra["raises"] == 0 and c.extra["penalty_factor"] == 1e3
    np.testing.assert_allclose(c.extra["force_by_beam_N"][:, 0, 0], c.force_N[:, 0])
    assert res.stable.all()


def test_no_stop_and_an_untouched_stop_give_the_solve_without_stops():
    drive = np.linspace(0.0, 0.2, 5)
    plain = cantilever_system(kernel="numpy").solve(drive)
    assert plain.contact is None
    far = cantilever_system([RigidStop.point((50.0, -5.0)), stop_at(150.0, 0.02, "point")])
    res = far.solve(drive)
    assert not res.contact.rows_in_contact.any() and np.all(res.contact.force_N == 0.0)
    assert np.all(np.isnan(res.contact.closing_value))
    assert np.array_equal(res.states, plain.states)  # the same loop adding exact zeros


def test_a_stop_overlapping_the_beam_is_refused_by_name():
    with pytest.raises(FeaError, match="stop 'wall' overlaps the undeformed beam 0 by 0.1 mm"):
        cantilever_system([RigidStop.segment((40.0, -0.15), (60.0, -0.15), "wall")])


def test_a_penetration_beyond_the_tolerance_raises_the_penalty():
    from flexopt.fea.stops import ContactSettings

    g0, a = 0.02, L / 2
    # a penalty 1e5 times too soft: the first trace sinks into the stop, the raises recover
    soft = ContactSettings(penalty_factor=1e-2, max_raises=6)
    res = cantilever_system([stop_at(a, g0, "point")], contact=soft).solve([0.0, 0.1, 0.2])
    c = res.contact
    assert c.extra["raises"] >= 1 and c.penetration_ok
    assert c.extra["penalty_factor"] == pytest.approx(1e-2 * 10.0 ** c.extra["raises"])
    # the stiffer penalty's answer is the propped cantilever's
    np.testing.assert_allclose(c.force_N[-1, 0], propped(0.2, a, g0)[1], rtol=2e-3)


# ---------------------------------------------------------------------------- large deflection

EA = MAT.E_MPa * B * T  # N


def elastica_on_a_corner(delta, corner, guess=None):
    """The cantilever (clamped at 0, tip pushed down by ``delta`` mm, tip free to slide and
    turn) touching the point ``corner`` (2,) mm with its surface, as a two-segment BVP of the
    Reissner elastica (extension N / EA and shear V / kGA, like the beam model), by solve_bvp.

    States on tau in [0, 1]: (x, y, theta, M) of the segment [0, s_c] then of [s_c, L]
    (s = s_c tau, s_c + (L - s_c) tau); parameters (P the tip force (N, down), R the stop's
    force (N), s_c (mm), psi the centreline's angle at the contact). The force beyond s is
    (0, -P), plus R (sin psi, -cos psi) reversed (normal to the centreline, up) before s_c;
    M' = -(x' x F) per unit length with x' the section's direction, theta' = M / EI. The
    contact: corner = x(s_c) + t/2 n (n the centreline's normal towards the corner) and psi the
    centreline's angle there. Returns the solution (``p`` = (P, R, s_c, psi), ``y[4:, -1]`` the
    tip's x, y, theta, M)."""

    def rhs(tau, Y, prm):
        P, R, sc, psi = prm
        out = np.empty_like(Y)
        for seg, ln in enumerate((sc, L - sc)):
            th, M = Y[4 * seg + 2], Y[4 * seg + 3]
            Fx, Fy = (-R * np.sin(psi), R * np.cos(psi) - P) if seg == 0 else (0.0, -P)
            e = (np.cos(th) * Fx + np.sin(th) * Fy) / EA  # axial strain
            g = (-np.sin(th) * Fx + np.cos(th) * Fy) / KGA  # shear strain
            out[4 * seg] = ln * ((1 + e) * np.cos(th) - g * np.sin(th))
            out[4 * seg + 1] = ln * ((1 + e) * np.sin(th) + g * np.cos(th))
            out[4 * seg + 2] = ln * M / EI
            out[4 * seg + 3] = -ln * (np.cos(th) * Fy - np.sin(th) * Fx)
        return out

    def bc(ya, yb, prm):
        psi = prm[3]
        touch = yb[:2] + (T / 2) * np.array([np.sin(psi), -np.cos(psi)]) - corner
        tangent = rhs(1.0, yb[:, None], prm)[:2, 0]
        return np.array([
            ya[0], ya[1], ya[2],  # clamped
            *(ya[4:] - yb[:4]),  # the two segments join at s_c
            yb[7], yb[5] + delta,  # no tip moment; the tip's v prescribed
            *touch, np.arctan2(tangent[1], tangent[0]) - psi,
        ])  # fmt: skip

    if guess is None:  # the straight beam touching at the corner's abscissa
        tau = np.linspace(0.0, 1.0, 41)
        Y = np.zeros((8, tau.size))
        Y[0], Y[4] = corner[0] * tau, corner[0] + (L - corner[0]) * tau
        guess = (tau, Y, np.array([0.01, 0.02, corner[0], 0.0]))
    sol = solve_bvp(rhs, bc, guess[0], guess[1], p=guess[2], tol=1e-10, max_nodes=100000)
    assert sol.success, sol.message
    return sol


def test_cantilever_pressed_on_a_flat_stop_at_large_deflection_is_the_elastica():
    # a flat stop 2 mm below the beam's surface, ending at x = 50 (its corner is the contact):
    # the tip pushed down by 40 % of the length, the contact point slides 0.7 mm along the beam
    corner = np.array([50.0, -(T / 2 + 2.0)])
    stop = RigidStop.segment((30.0, corner[1]), tuple(corner), "flat")
    drive = np.array([0.0, 8.0, 16.0, 24.0, 32.0, 40.0])
    res = cantilever_system([stop], n=40).solve(drive)
    assert res.ok, res.message
    c = res.contact
    P, tip = tip_force(res), res.end(0)
    guess = None
    for k in range(1, drive.size):
        sol = elastica_on_a_corner(drive[k], corner, guess)
        guess = (sol.x, sol.y, sol.p)
        P_e, R_e, s_c, _ = sol.p
        assert c.in_contact[k, 0]
        assert P[k] == pytest.approx(P_e, rel=2e-4)
        assert c.force_N[k, 0] == pytest.approx(R_e, rel=2e-4)
        assert L + tip[k, 0] == pytest.approx(sol.y[4, -1], abs=1e-3)  # the tip's x, mm
        assert tip[k, 2] == pytest.approx(sol.y[6, -1], abs=1e-4)  # its rotation, rad
        np.testing.assert_allclose(c.point_mm[k, 0], corner, atol=1e-12)
    assert s_c - corner[0] > 0.5  # the contact slid along the beam: large deflection
    assert drive[-1] / L == 0.4 and c.penetration_ok


# ---------------------------------------------------------------------------- the leaf joint


def test_sliding_leaf_joint_on_a_stop_is_the_propped_cantilever():
    """fea.leaf_joint.sliding_response with a pin over the leaf's middle: in small deflection
    the leaf is a cantilever whose tip is moved l_j sin(theta) across it, tip slope free, so the
    arm's force and the pin's are the propped cantilever's (to O(theta^2), 4e-6 here)."""
    from flexopt.fea.leaf_joint import sliding_response
    from flexopt.geometry.leaf_joint import LeafJoint

    joint = LeafJoint(arm_mm=150.0, effective_length_mm=L, thickness_mm=T, width_mm=B,
                      n_leaves=2, structure="sliding", clamp_mm=10.0, overhang_mm=30.0)  # fmt: skip
    g0, a = 0.02, L / 2
    pin = RigidStop.point((a, T / 2 + g0), "pin")  # above: the leaf bends up (+y) for theta > 0
    res = sliding_response(joint, MAT, 2e-3, steps=8, n_elements=20, stops=(pin,))
    assert res.ok, res.message
    exact = np.array([propped(150.0 * np.sin(th), a, g0) for th in res.deflection_rad])
    np.testing.assert_allclose(res.leaf_force_N, exact[:, 0], rtol=1e-4, atol=1e-12)
    np.testing.assert_allclose(res.contact.force_N[:, 0], exact[:, 1], rtol=1e-4, atol=1e-12)
    closing = np.arcsin(exact[0, 2] / 150.0)  # the deflection at which the pin closes, rad
    assert res.contact.closing_value[0] == pytest.approx(closing, rel=1e-3)
    assert res.contact.in_contact[-1, 0] and not res.contact.in_contact[1, 0]
