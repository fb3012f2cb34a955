"""Contact of a mechanism's rigid bodies and a beam's self contact (fea/body_contact.py) against
answers computed here:

* the penalty's force and tangent are the exact gradient and Hessian of its energy (central
  differences) for every pair kind: a body's corner on a stop's face, a stop's corner, a wall
  and a point on a body's face, body on body, a beam's node on a body's face, a body's corner
  on a beam's curve, a beam's node on its own curve;
* a block on a cantilever's tip pressed by a dead load onto a flat stop (small deflection): the
  first contact of its leading corner, then the face seated flat — the stop's force and its
  point (the moment) from the Timoshenko cantilever's exact end stiffness at the deflection and
  rotation reached;
* two blocks on two cantilevers pressed together, a block's corner on a cantilever's middle and
  a cantilever's tip on a block's face: the superposed Timoshenko flexibilities;
* a hook curled by an end moment until its tip meets its own leg: the gap before contact from
  the exact pure-bending shape (arcs), the contact force and the tip after contact from the
  Reissner elastica (extension and shear, as the beam model) integrated by scipy from the
  contact point with the force and its place solved for; no net reaction force (the self
  contact's forces cancel); penetration within the tolerance;
* refusals: a body overlapping a stop undeformed, a declared body without an outline.
"""

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel, BeamSettings
from flexopt.fea.body_contact import MechanismContacts
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mechanism import (
    LoadCase,
    Mechanism,
    MechBeam,
    MechBody,
    MechDrive,
    MechJoint,
    MechOutput,
    solve_mechanism,
)
from flexopt.fea.stops import ContactSettings, RigidStop
from flexopt.geometry.profile import BeamProfile
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve, minimize_scalar

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)


def section(t, w):
    """EI (N mm^2), kGA (N), EA (N) of a t x w rectangle."""
    return MAT.E_MPa * w * t**3 / 12.0, 5.0 / 6.0 * MAT.G_MPa * w * t, MAT.E_MPa * w * t


def tip_flexibility(length, t, w):
    """Tip deflection per unit tip force (mm/N) of a Timoshenko cantilever: L^3/3EI + L/kGA."""
    ei, kga, _ = section(t, w)
    return length**3 / (3 * ei) + length / kga


# ------------------------------------------------------------------ the derivatives


def _square(cx, cy, a):
    return np.array([[cx - a, cy - a], [cx + a, cy - a], [cx + a, cy + a], [cx - a, cy + a]])


def _contacts(stops=(), declared=(), bodies=(), beams=()):
    models = [
        BeamModel(BeamProfile(np.array(p), np.full(len(p), t), 2.0, kap), MAT, "clamped",
                  BeamSettings(n_elements=n))
        for p, t, n, kap in beams
    ]  # fmt: skip
    offsets = np.concatenate([[0], np.cumsum([m.n_dofs for m in models])])
    names = [f"b{i}" for i in range(len(models))]
    c = MechanismContacts(models, offsets, bodies, int(offsets[-1]), stops, declared, set(),
                          ContactSettings(element_length="mean"), names)  # fmt: skip
    return c, int(offsets[-1]) + 3 * len(bodies)


def _energy(c, z):
    return sum(0.5 * t.k * t.gap**2 for t in c.terms(z))


def _force_tangent(c, z):
    r = np.zeros(z.size)
    rows, cols, vals = [], [], []
    c.add(z, r, rows, cols, vals)
    K = np.zeros((z.size, z.size))
    if vals:
        np.add.at(K, (np.concatenate(rows), np.concatenate(cols)), np.concatenate(vals))
    return r, K


def _check_derivatives(c, z, kinds):
    terms = c.terms(z)
    found = {t.key[0] if isinstance(t.key[0], str) else "stop" for t in terms}
    assert set(kinds) <= found | {type(t.group).__name__ for t in terms}, found
    assert all(t.gap < 0.0 for t in terms) and terms
    r, K = _force_tangent(c, z)
    rng = np.random.default_rng(7)
    h = 1e-7
    for _ in range(4):
        d = rng.standard_normal(z.size)
        de = (_energy(c, z + h * d) - _energy(c, z - h * d)) / (2 * h)
        assert de == pytest.approx(r @ d, rel=1e-6)
        dr = (_force_tangent(c, z + h * d)[0] - _force_tangent(c, z - h * d)[0]) / (2 * h)
        np.testing.assert_allclose(dr, K @ d, rtol=1e-5, atol=1e-6 * np.abs(K @ d).max())


def test_a_bodys_pairs_with_stops_are_exact():
    """A square body moved and turned into a block (its corner on the block's face, the block's
    corner on its face), a thin wall and a point stop."""
    body = MechBody("A", np.array([0.0, 0.0]), _square(0.0, 0.0, 1.0))
    stops = (
        RigidStop.polygon(np.array([[0.6, -3.0], [3.0, -3.0], [3.0, -1.05], [0.6, -1.05]]), "blk"),
        RigidStop.segment((-1.03, -2.0), (-1.03, 2.0), "wall"),
        RigidStop.point((-0.8, 1.06), "pin"),
    )
    c, n = _contacts(stops, (), (body,), [([[20.0, 0.0], [30.0, 0.0]], 0.5, 4, None)])
    z = np.zeros(n)
    z[-3:] = [-0.04, 0.0, -0.1]  # left and turned clockwise: into all four
    groups = {t.group for t in c.terms(z)}
    assert groups == {0, 1, 2}
    keys = {(t.group, t.key[2]) for t in c.terms(z)}
    assert (0, "A") in keys and (0, "blk") in keys  # both ways against the block
    _check_derivatives(c, z, ())


def test_body_body_body_beam_and_self_pairs_are_exact():
    a = MechBody("A", np.array([0.0, 0.0]), _square(0.0, 0.0, 1.0))
    b = MechBody("B", np.array([0.3, -2.0]), np.array([[-0.7, -3.0], [1.3, -3.0], [0.3, -1.02]]))
    beam = ([[-3.0, 1.3], [3.0, 1.3]], 0.5, 6, None)  # 0.05 mm above A
    hook = ([[10.0, 0.0], [14.0, 0.0], [14.0, 2.0], [12.0, 2.0], [12.0, 0.9]], 0.5, 12,
            [0.0, 0.5, 0.0, 0.0])  # fmt: skip
    declared = (("A", "B"), ("A", "b0"), ("b1", "b1"))
    c, n = _contacts((), declared, (a, b), [beam, hook])
    z = np.zeros(n)
    m0 = c.models[0]
    q = np.zeros((m0.n_nodes, 3))
    q[:, 1] = -0.08 * np.sin(np.linspace(0.3, 2.8, m0.n_nodes))  # the beam sags into A
    z[: m0.n_dofs] = q.ravel()
    m1 = c.models[1]
    q1 = np.zeros((m1.n_nodes, 3))
    q1[-3:, 1] = -0.7  # the hook's tip 0.05 mm into its leg
    z[m0.n_dofs : m0.n_dofs + m1.n_dofs] = q1.ravel()
    z[-6:] = [0.01, -0.02, 0.02, -0.01, 0.05, -0.03]
    groups = {t.group for t in c.terms(z)}
    assert groups == {"A/B", "A/b0", "b1/b1"}
    assert {t.key[0] for t in c.terms(z) if t.group == "A/b0"} == {"n", "c"}
    _check_derivatives(c, z, ())


# ------------------------------------------------------------------ a block on a stop

L, T, W = 50.0, 1.0, 5.0  # the cantilever, mm
A_HALF, G0 = 3.0, 0.05  # the block's half width and its gap to the floor, mm


def block_on_floor(p_max, steps):
    beam = MechBeam("b", np.array([[0.0, 0.0], [L, 0.0]]), np.array([T, T]), W, 20)
    outline = np.array([[L - A_HALF, -4.0], [L + A_HALF, -4.0], [L + A_HALF, 1.0],
                        [L - A_HALF, 1.0]])  # fmt: skip
    block = MechBody("block", np.array([L, 0.0]), outline)
    floor = RigidStop.polygon(
        np.array([[L - 10, -8.0], [L + 10, -8.0], [L + 10, -4.0 - G0], [L - 10, -4.0 - G0]]),
        "floor",
    )
    joints = (MechJoint("b.start", "ground"), MechJoint("b.end", "block"))
    mech = Mechanism((beam,), (block,), joints, MAT, (floor,))
    case = LoadCase("press", MechDrive("block", "force", p_max, steps, (0.0, -1.0)))
    outs = (MechOutput("v", "displacement", "block", (0.0, 1.0)),
            MechOutput("th", "rotation", "block"))  # fmt: skip
    return solve_mechanism(mech, case, outs)


def test_a_block_pressed_onto_a_flat_stop_seats_with_the_cantilevers_end_force_and_moment():
    """Small deflection (0.1 % of L). The block (6 mm wide, its bottom face 4 mm below the tip)
    hangs on the tip. Before contact the tip is a cantilever's under P: its bottom right corner
    drops v + a theta = P (L^3/3EI + L/kGA + a L^2/2EI) and meets the floor at that = G0. Once
    seated, the beam's end force and moment on the block follow from the end's deflection v and
    rotation theta through the Timoshenko cantilever's exact end stiffness
    EI/((1 + Phi) L^3) [[12, -6L], [-6L, (4 + Phi) L^2]], Phi = 12 EI/(kGA L^2); the floor
    carries P + V (V the beam's force on the block, upward) at the point where its moment about
    the tip balances the beam's."""
    ei, kga, _ = section(T, W)
    corner = L**3 / (3 * ei) + L / kga + A_HALF * L**2 / (2 * ei)
    p_first = G0 / corner
    onset = block_on_floor(0.002, 8)  # rows 0.27 p_first apart: it closes in row 4
    c = onset.contact
    assert c.closing_value[0] == pytest.approx(p_first, rel=1e-4)
    assert c.initial_gap_mm[0] == pytest.approx(G0, rel=1e-9)
    open_ = onset.drive < p_first
    assert not c.in_contact[open_, 0].any() and c.in_contact[~open_, 0].all()
    # the corner, 4 mm below the tip, also rises 4 (1 - cos theta) ~ 4e-6 mm (second order)
    np.testing.assert_allclose(c.gap_mm[open_, 0], G0 - onset.drive[open_] * corner,
                               atol=5e-6)  # fmt: skip
    res = block_on_floor(0.1, 10)
    assert res.ok, res.message
    c = res.contact
    phi = 12 * ei / (kga * L**2)
    stiff = ei / ((1 + phi) * L**3) * np.array([[12, -6 * L], [-6 * L, (4 + phi) * L**2]])
    # both corners down: the block does not turn (to the penalty's 1e-7 rad)
    seated = np.flatnonzero(c.in_contact[:, 0] & (np.abs(res.outputs["th"]) < 1e-5))
    assert seated.size >= 5
    for k in seated:
        v, th = res.outputs["v"][k], res.outputs["th"][k]
        force_on_beam, moment_on_beam = stiff @ [v, th]  # what the block applies to the tip
        floor = res.drive[k] + force_on_beam  # the block: floor - P - force_on_beam = 0
        assert c.force_vector_N[k, 0, 1] == pytest.approx(floor, rel=1e-6)
        assert abs(c.force_vector_N[k, 0, 0]) < 1e-9 * floor  # frictionless, a flat floor
        # the block's moments about the tip: the floor's (x_c - x_tip) floor against the
        # beam's -moment_on_beam
        arm = c.point_mm[k, 0, 0] - res.body_poses[k, 0, 0]
        assert arm * floor == pytest.approx(moment_on_beam, rel=1e-5)
        assert c.point_mm[k, 0, 1] == pytest.approx(-4.0 - G0, abs=1e-12)  # on the floor
    assert c.penetration_ok and c.max_penetration_mm.max() < 1e-5


# ------------------------------------------------------------------ superposed flexibilities

H = 6.0  # mm between the two cantilevers
G1 = 0.005  # mm between the two parts: deflections of 1e-4 L keep the rotations' effects out


def two_bodies(kind, p_max=2.1e-4, steps=7):
    """Cantilever A (its block on its tip) pushed down by a dead load P on the block onto
    ``kind``: "blocks" B's wedge on B's tip (B a cantilever under A), "corner" (A's block a
    wedge) on cantilever B's middle, "tip" (A's block flat) on a cantilever B's tip."""
    a = MechBeam("A", np.array([[0.0, 0.0], [L, 0.0]]), np.array([T, T]), W, 20)
    joints = [MechJoint("A.start", "ground"), MechJoint("A.end", "blkA")]
    flat = np.array([[L - 2, -2.0], [L + 2, -2.0], [L + 2, 0.8], [L - 2, 0.8]])
    wedge_down = np.array([[L - 2, 0.8], [L, -2.0], [L + 2, 0.8]])
    bodies = [MechBody("blkA", np.array([L, 0.0]), wedge_down if kind == "corner" else flat)]
    if kind == "blocks":
        b = MechBeam("B", np.array([[0.0, -H], [L, -H]]), np.array([T, T]), W, 20)
        wedge_up = np.array([[L - 2, -H - 0.8], [L + 2, -H - 0.8], [L, -2.0 - G1]])
        bodies.append(MechBody("blkB", np.array([L, -H]), wedge_up))
        joints += [MechJoint("B.start", "ground"), MechJoint("B.end", "blkB")]
        pair = ("blkA", "blkB")
    elif kind == "corner":  # B from x = L + 25 back to L - 25: A's corner over its middle
        yb = -2.0 - G1 - T / 2
        b = MechBeam("B", np.array([[L + 25.0, yb], [L - 25.0, yb]]), np.array([T, T]), W, 20)
        joints.append(MechJoint("B.start", "ground"))
        pair = ("blkA", "B")
    else:  # B upright under the block's face, its rounded tip G1 below it
        b = MechBeam("B", np.array([[L, -20.0], [L, -2.0 - G1 - T / 2]]), np.array([T, T]), W,
                     10)  # fmt: skip
        joints.append(MechJoint("B.start", "ground"))
        pair = ("B", "blkA")
    mech = Mechanism((a, b), tuple(bodies), tuple(joints), MAT, (), (pair,))
    case = LoadCase("press", MechDrive("blkA", "force", p_max, steps, (0.0, -1.0)))
    outs = (MechOutput("vA", "displacement", "blkA", (0.0, -1.0)),)
    return solve_mechanism(mech, case, outs), "/".join(pair)


@pytest.mark.parametrize("kind", ["blocks", "corner", "tip"])
def test_two_parts_pressed_together_superpose_their_flexibilities(kind):
    """A's tip under P less the contact force F, the other part under F: the gap closes when
    P c_A = G1 and then ``(P - F) c_A - F c_B = G1 - pen`` (``pen`` the penalty's penetration,
    the computed gap), i.e. F = (P c_A - G1 + pen) / (c_A + c_B), with c_B the other part's
    flexibility where it is pressed: a cantilever's tip (L^3/3EI + L/kGA), its middle
    ((L/2)^3/3EI + (L/2)/kGA, a cantilever of half the length), an upright bar's end (l/EA)."""
    res, label = two_bodies(kind)
    assert res.ok, res.message
    c_a = tip_flexibility(L, T, W)
    _, _, ea = section(T, W)
    c_b = {"blocks": c_a, "corner": tip_flexibility(25.0, T, W),
           "tip": (20.0 - 2.0 - G0 - T / 2) / ea}[kind]  # fmt: skip
    pair = res.beam_contact[label]
    pen = np.minimum(pair["gap_mm"], 0.0)
    expected = np.maximum((res.drive * c_a - G1 - pen) / (c_a + c_b), 0.0)
    touching = res.drive * c_a > G1
    assert np.array_equal(pair["in_contact"], touching) and 0 < touching.sum() < touching.size
    np.testing.assert_allclose(pair["force_N"][touching], expected[touching], rtol=2e-4)
    np.testing.assert_allclose(res.outputs["vA"][touching],
                               (res.drive - expected)[touching] * c_a, rtol=2e-4)  # fmt: skip
    before = ~touching
    np.testing.assert_allclose(pair["gap_mm"][before], G1 - res.drive[before] * c_a,
                               atol=2e-4 * G1)  # fmt: skip
    assert -pen.min() < 1e-3 * T


# ------------------------------------------------------------------ a hook meeting itself

HT, HW = 0.5, 2.0
# the hook: a leg along x, a half turn of radius 2 up, back along the top, a quarter turn of
# radius 1 down and a straight tip pointing at the leg, 0.5 mm clear of it
HOOK_SEG = [(10.0, 0.0), (np.pi, 0.5), (np.pi, 0.5), (6.0, 0.0), (np.pi / 2, 1.0), (2.0, 0.0)]
HOOK_S = np.concatenate([[0.0], np.cumsum([s for s, _ in HOOK_SEG])])


def _kappa0(s):
    i = min(int(np.searchsorted(HOOK_S, s, side="right")) - 1, len(HOOK_SEG) - 1)
    return HOOK_SEG[i][1]


def _theta0(s):
    return sum(
        k * min(max(s - a, 0.0), ell) for (ell, k), a in zip(HOOK_SEG, HOOK_S[:-1], strict=True)
    )


def _bent(m, s_end, ei):
    """Position (2,) and angle of the hook at arc length ``s_end`` under a pure moment m:
    N = V = 0, so the curvature is kappa0 + m/EI exactly and every segment an arc."""
    x = np.zeros(2)
    knots = [0.0] + [v for v in HOOK_S if 0.0 < v < s_end] + [s_end]
    for a, b in zip(knots[:-1], knots[1:], strict=True):
        k = _kappa0(0.5 * (a + b)) + m / ei
        ta, ell = _theta0(a) + m * a / ei, b - a
        if abs(k) < 1e-14:
            x = x + ell * np.array([np.cos(ta), np.sin(ta)])
        else:
            chord = [np.sin(ta + k * ell) - np.sin(ta), np.cos(ta) - np.cos(ta + k * ell)]
            x = x + np.array(chord) / k
    return x, _theta0(s_end) + m * s_end / ei


def hook_gap(m):
    """The exact gap (mm) between the tip's rounded end and the leg under a pure moment m."""
    ei, _, _ = section(HT, HW)
    tip, _ = _bent(m, HOOK_S[-1], ei)
    ss = np.linspace(0.0, HOOK_S[-1] - 3.0, 2001)
    d = [np.hypot(*(tip - _bent(m, s, ei)[0])) for s in ss]
    j = int(np.argmin(d))
    lo, hi = ss[max(j - 1, 0)], ss[min(j + 1, ss.size - 1)]
    best = minimize_scalar(lambda s: np.hypot(*(tip - _bent(m, s, ei)[0])), bounds=(lo, hi),
                           method="bounded", options={"xatol": 1e-12})  # fmt: skip
    return best.fun - HT


def hook_pressed(m, guess):
    """The hook under the end moment m pressing its tip on its leg at arc length s_c with force
    f (the leg's normal there, on the tip). The leg from 0 to s_c carries m alone (the contact
    forces on the leg and on the tip are collinear through the tip's centre: no net moment), so
    it is the exact pure-bending shape; from s_c the Reissner elastica with the internal force
    F = f n(s_c) and moment m(s) (m(s_c) = m, dm/ds = -x' x F), x' = R(theta)(1 + N/EA, V/kGA),
    theta' = kappa0 + m/EI, is integrated to the tip, and (f, s_c) solved so that the tip's
    centre lies on the leg's normal at s_c, one thickness from its centreline (the two disks
    of radius t/2 touching). Returns (f N, s_c mm, tip (2,) mm)."""
    ei, kga, ea = section(HT, HW)

    def shoot(p):
        f, sc = p
        xc, thc = _bent(m, sc, ei)
        force = f * np.array([-np.sin(thc), np.cos(thc)])

        def rhs(s, y):
            c, si = np.cos(y[2]), np.sin(y[2])
            n_ax = (c * force[0] + si * force[1]) / ea
            shear = (-si * force[0] + c * force[1]) / kga
            dx = np.array([c * (1 + n_ax) - si * shear, si * (1 + n_ax) + c * shear])
            return [dx[0], dx[1], _kappa0(s) + y[3] / ei, -(dx[0] * force[1] - dx[1] * force[0])]

        y = [xc[0], xc[1], thc, m]
        knots = [sc] + [v for v in HOOK_S if sc < v < HOOK_S[-1]] + [HOOK_S[-1]]
        for a, b in zip(knots[:-1], knots[1:], strict=True):
            y = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=1e-12, atol=1e-13).y[:, -1]
        d = np.array(y[:2]) - xc
        return [d @ np.array([np.cos(thc), np.sin(thc)]), np.hypot(*d) - HT], np.array(y[:2])

    sol = fsolve(lambda p: shoot(p)[0], guess, xtol=1e-13)
    return sol[0], sol[1], shoot(sol)[1]


def hook(elements, m_max=0.4, steps=8):
    pts = np.array([[0, 0], [10, 0], [12, 2], [10, 4], [4, 4], [3, 3], [3, 1.0]], dtype=float)
    kap = np.array([0.0, 0.5, 0.5, 0.0, 1.0, 0.0])
    beam = MechBeam("hook", pts, np.full(len(pts), HT), HW, elements, kap)
    mech = Mechanism((beam,), (), (MechJoint("hook.start", "ground"),), MAT, (),
                     (("hook", "hook"),))  # fmt: skip
    case = LoadCase("curl", MechDrive("hook.end", "moment", m_max, steps))
    outs = tuple(MechOutput(f"R{k}", "reaction_force", "hook.start", d)
                 for k, d in (("x", (1.0, 0.0)), ("y", (0.0, 1.0))))  # fmt: skip
    return solve_mechanism(mech, case, outs)


def test_a_hook_curled_onto_itself_against_the_elastica():
    res = hook(40)
    assert res.ok, res.message
    pair = res.beam_contact["hook/hook"]
    touching = pair["force_N"] > 0.0
    assert not touching[:5].any() and touching[5:].all()  # first contact at m = 0.21 N mm
    for k in np.flatnonzero(~touching):
        assert pair["gap_mm"][k] == pytest.approx(hook_gap(res.drive[k]), abs=2e-5)
    for k in np.flatnonzero(touching):
        f, _, tip = hook_pressed(res.drive[k], [pair["force_N"][k], 3.2])
        assert pair["force_N"][k] == pytest.approx(f, rel=5e-4)
        np.testing.assert_allclose(res.shapes_mm[0][k][-1], tip, atol=2e-5)
    # the self contact's forces cancel: the ground holds the moment alone
    assert np.abs(res.outputs["Rx"]).max() < 1e-12 and np.abs(res.outputs["Ry"]).max() < 1e-12
    assert -pair["gap_mm"].min() < 1e-3 * HT


def test_the_hooks_contact_force_converges_under_refinement():
    """The error of the contact force at m = 0.4 N mm against the elastica falls by 4x or more
    from 20 to 40 elements (P2 elements on a curved reference)."""
    errors = []
    for n in (20, 40):
        res = hook(n, 0.4, 2)
        f = res.beam_contact["hook/hook"]["force_N"][-1]
        errors.append(abs(f - hook_pressed(0.4, [f, 3.2])[0]))
    assert errors[1] < errors[0] / 4


# ------------------------------------------------------------------ refusals


def test_a_body_overlapping_a_stop_and_a_declared_body_without_outline_are_refused():
    beam = MechBeam("b", np.array([[0.0, 0.0], [L, 0.0]]), np.array([T, T]), W, 10)
    joints = (MechJoint("b.start", "ground"), MechJoint("b.end", "blk"))
    blk = MechBody("blk", np.array([L, 0.0]), _square(L, -2.0, 1.5))
    stop = RigidStop.polygon(_square(L, -4.0, 1.0), "floor")  # 0.5 mm into the block
    case = LoadCase("c", MechDrive("blk", "force", 0.01, 2, (0.0, -1.0)))
    with pytest.raises(FeaError, match=r"stop 'floor' overlaps body 'blk' undeformed by 0.5 mm"):
        solve_mechanism(Mechanism((beam,), (blk,), joints, MAT, (stop,)), case)
    bare = MechBody("blk", np.array([L, 0.0]))
    with pytest.raises(FeaError, match=r"beam contact \[blk, b\]: body 'blk' has no outline_mm"):
        solve_mechanism(Mechanism((beam,), (bare,), joints, MAT, (), (("blk", "b"),)), case)
