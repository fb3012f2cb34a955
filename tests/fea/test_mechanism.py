"""The mechanism engine (fea/mechanism.py) against exact answers computed here.

References: Timoshenko-beam closed forms at small deflection (12EI/L^3 per guided leaf, 192EI/L^3
for a clamped-clamped beam, 3EI/L^3 for a cantilever, each with its shear term), the elliptic-
integral elastica of fea.elastica at large deflection, a Reissner-beam boundary-value problem
(scipy's solve_bvp: the same extensible, shearable beam the FE discretises) for the stiffening of
a clamped-clamped beam, pure bending (a circle, exact), and rigid-lever kinematics.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.constrained_beams import kkt_negative_count
from flexopt.fea.elastica import fixed_guided
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
    check_mechanism,
    mass_g,
    solve_mechanism,
)
from scipy.integrate import solve_bvp
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0, density_kg_m3=1200.0)
W = 5.0  # mm, out-of-plane width


def _ei(t: float) -> float:
    return MAT.E_MPa * W * t**3 / 12.0  # N mm^2


def _kga(t: float) -> float:
    return 5.0 / 6.0 * MAT.G_MPa * W * t  # N


def _straight(name: str, a, b, t: float, elements: int = 0) -> MechBeam:
    return MechBeam(name, np.array([a, b], dtype=float), np.array([t, t]), W, elements)


def _guided_leaf(L: float, t: float, elements: int = 0) -> Mechanism:
    """A leaf clamped to the ground at (0, 0) and to a shuttle body at (L, 0)."""
    leaf = _straight("leaf", (0.0, 0.0), (L, 0.0), t, elements)
    shuttle = MechBody("shuttle", np.array([L + 5.0, 2.0]))  # ref off the leaf on purpose
    joints = (MechJoint("leaf.start", "ground"), MechJoint("leaf.end", "shuttle"))
    return Mechanism((leaf,), (shuttle,), joints, MAT)


def _push(part: str, d: float, steps: int, rotation: str = "held") -> LoadCase:
    return LoadCase("push", MechDrive(part, "displacement", d, steps, (0.0, 1.0), "free", rotation))


# ---------------------------------------------------------------- guided leaf, parallel guide


@pytest.mark.parametrize("part", ["shuttle", "leaf.end"])
def test_guided_leaf_small_deflection_is_12EI_over_L3(part: str) -> None:
    L, t = 50.0, 0.5
    resp = solve_mechanism(
        _guided_leaf(L, t),
        _push(part, 0.02, 2),
        [MechOutput("F", "reaction"), MechOutput("Fg", "reaction_force", "leaf.start", (0, 1))],
    )
    assert resp.ok and resp.stable.all()
    # Timoshenko guided leaf: d = F L^3 / (12 EI) + F L / kGA
    k = 1.0 / (L**3 / (12.0 * _ei(t)) + L / _kga(t))
    np.testing.assert_allclose(resp.outputs["F"][1:] / resp.drive[1:], k, rtol=1e-6)
    # the ground holds the leaf with the opposite force
    np.testing.assert_allclose(resp.outputs["Fg"], -resp.outputs["F"], rtol=1e-9, atol=1e-15)


def test_guided_leaf_large_deflection_matches_elastica_and_converges() -> None:
    L, t = 50.0, 0.2  # slender: shear and stretch are O((t/L)^2) = 1.6e-5 of the force
    d = np.array([1.0, 2.0, 3.0]) / 3.0 * 0.4 * L
    ref = np.array([fixed_guided(x / L).load for x in d]) * _ei(t) / L**2
    ref_short = np.array([fixed_guided(x / L).shortening_over_L for x in d]) * L
    forces = []
    for n_el in (6, 12, 24):
        resp = solve_mechanism(
            _guided_leaf(L, t, n_el),
            LoadCase("p", MechDrive("shuttle", "displacement", d[-1], 3, (0, 1), "free", "held")),
            [
                MechOutput("F", "reaction"),
                MechOutput("x", "displacement", "shuttle", (1, 0)),
                MechOutput("rot", "rotation", "shuttle"),
            ],
        )
        assert resp.ok, resp.message
        assert resp.stable.all()
        np.testing.assert_allclose(resp.drive[1:], d, rtol=1e-12)
        forces.append(resp.outputs["F"][1:])
        assert np.abs(resp.outputs["rot"]).max() < 1e-12  # rotation held
    # mesh convergence: P2 elements converge fast (the change per halving drops > 8x) ...
    change = [np.abs(forces[i + 1] / forces[i] - 1).max() for i in range(2)]
    assert change[1] < change[0] / 8
    # ... to within the model difference of the elastica (the FE beam stretches and shears:
    # about 6e-5 here, of order (t / L)^2 E / kG)
    np.testing.assert_allclose(forces[-1], ref, rtol=1e-4)
    np.testing.assert_allclose(-resp.outputs["x"][1:], ref_short, rtol=2e-3)


def test_guided_leaf_elastica_all_rows() -> None:
    L, t = 50.0, 0.2
    d_max = 0.4 * L
    resp = solve_mechanism(
        _guided_leaf(L, t, 24),
        LoadCase("p", MechDrive("leaf.end", "displacement", d_max, 4, (0, 1), "free", "held")),
        [MechOutput("F", "reaction"), MechOutput("s", "peak_stress", "leaf")],
    )
    assert resp.ok
    ref = np.array([fixed_guided(x / L).load for x in resp.drive]) * _ei(t) / L**2
    np.testing.assert_allclose(resp.outputs["F"][1:], ref[1:], rtol=3e-4)
    # peak stress: the end moment M = m EI / L over the section modulus (bending dominates)
    m = fixed_guided(d_max / L).end_moment * _ei(t) / L
    assert resp.outputs["s"][-1] == pytest.approx(m * 6.0 / (W * t**2), rel=5e-3)
    np.testing.assert_allclose(resp.peak_stress_MPa[:, 0], resp.outputs["s"])


def _parallel_guide(L: float, t: float, H: float, n_el: int = 0) -> Mechanism:
    top = _straight("top", (0.0, H), (L, H), t, n_el)
    bottom = _straight("bottom", (0.0, 0.0), (L, 0.0), t, n_el)
    shuttle = MechBody("shuttle", np.array([L, H / 2.0]))
    joints = (
        MechJoint("top.start", "ground"),
        MechJoint("bottom.start", "ground"),
        MechJoint("top.end", "shuttle"),
        MechJoint("bottom.end", "shuttle"),
    )
    return Mechanism((top, bottom), (shuttle,), joints, MAT)


def test_parallel_guide_small_deflection_free_rotation() -> None:
    L, t, H = 40.0, 0.4, 20.0
    resp = solve_mechanism(
        _parallel_guide(L, t, H),
        LoadCase("p", MechDrive("shuttle", "force", 1e-4, 2, (0, 1), "free", "free")),
        [
            MechOutput("d", "displacement", "shuttle", (0, 1)),
            MechOutput("rot", "rotation", "shuttle"),
        ],
    )
    assert resp.ok and resp.stable.all() and resp.stable_released.all()
    # Linear theory of the two leaves (Timoshenko tip stiffness with phi = 12 EI / (kGA L^2)) and
    # the shuttle's rotation th, resisted by the leaves' bending and by their axial stiffness
    # (one leaf shortens, the other stretches by th H / 2):
    #   moment: 2 (k_vt d + k_tt th) + EA H^2 / (2 L) th = 0,  force: F = 2 (k_vv d + k_vt th)
    ei, phi = _ei(t), 12.0 * _ei(t) / (_kga(t) * L**2)
    k_vv = 12.0 * ei / ((1 + phi) * L**3)
    k_vt = -6.0 * ei / ((1 + phi) * L**2)
    k_tt = (4.0 + phi) * ei / ((1 + phi) * L)
    k_rot = 2.0 * k_tt + MAT.E_MPa * W * t * H**2 / (2.0 * L)
    k = 2.0 * (k_vv - 2.0 * k_vt**2 / k_rot)
    np.testing.assert_allclose(resp.drive[1:] / resp.outputs["d"][1:], k, rtol=1e-6)
    # the rotation correction is (t / H)^2 = 4e-4 of the stiffness: the check above sees it
    assert abs(k / (2 * k_vv) - 1) > 100 * 1e-6
    np.testing.assert_allclose(
        resp.outputs["rot"][1:], -2.0 * k_vt * resp.outputs["d"][1:] / k_rot, rtol=1e-5
    )


def test_parallel_guide_large_deflection_is_two_elastica_leaves() -> None:
    L, t, H = 40.0, 0.2, 20.0
    d = 0.3 * L
    resp = solve_mechanism(
        _parallel_guide(L, t, H, 20),
        LoadCase("p", MechDrive("shuttle", "displacement", d, 3, (0, 1), "free", "held")),
        [MechOutput("F", "reaction"), MechOutput("x", "displacement", "shuttle", (1, 0))],
    )
    assert resp.ok and resp.stable.all()
    ref = 2.0 * fixed_guided(d / L).load * _ei(t) / L**2
    assert resp.outputs["F"][-1] == pytest.approx(ref, rel=3e-4)
    short = fixed_guided(d / L).shortening_over_L * L
    assert -resp.outputs["x"][-1] == pytest.approx(short, rel=2e-3)
    # both leaves bend alike
    np.testing.assert_allclose(resp.peak_stress_MPa[:, 0], resp.peak_stress_MPa[:, 1], rtol=1e-3)


# ---------------------------------------------------------------- clamped-clamped beam


def _clamped_clamped(L: float, t: float, n_el: int = 0) -> Mechanism:
    """Two halves welded at the centre (a clamped beam-to-beam joint), both outer ends clamped."""
    left = _straight("left", (0.0, 0.0), (L / 2, 0.0), t, n_el)
    right = _straight("right", (L / 2, 0.0), (L, 0.0), t, n_el)
    joints = (
        MechJoint("left.start", "ground"),
        MechJoint("right.end", "ground"),
        MechJoint("left.end", "right.start", "clamped"),
    )
    return Mechanism((left, right), (), joints, MAT)


def _reissner_centre(a: float, t: float, fys: np.ndarray) -> np.ndarray:
    """Centre deflections (mm) of a clamped-clamped Reissner beam of span 2a under central forces
    2 fys (N): the half 0 <= s <= a, clamped at 0, with theta(a) = 0 and x(a) = a (symmetry),
    carrying the section force (fx, fy) from the other half (fx unknown: the tension)::

        x' = (1 + N/EA) cos th - (Q/kGA) sin th,   y' = (1 + N/EA) sin th + (Q/kGA) cos th
        th' = M / EI,   M' = -(x' fy - y' fx),
        N = fx cos th + fy sin th,   Q = -fx sin th + fy cos th

    The loads are raised in small steps, each solve starting from the last (solve_bvp's Newton
    needs a start near the answer).
    """
    ei, ea, kga = _ei(t), MAT.E_MPa * W * t, _kga(t)
    s = np.linspace(0.0, a, 101)

    def rhs(_s, u, p, fy):
        x, y, th, m = u
        fx = p[0]
        c, sn = np.cos(th), np.sin(th)
        n = fx * c + fy * sn
        q = -fx * sn + fy * c
        dx = (1 + n / ea) * c - q / kga * sn
        dy = (1 + n / ea) * sn + q / kga * c
        return np.vstack([dx, dy, m / ei, -(dx * fy - dy * fx)])

    def bc(ua, ub, p):
        return np.array([ua[0], ua[1], ua[2], ub[2], ub[0] - a])

    guess = np.vstack([s, np.zeros_like(s), np.zeros_like(s), np.zeros_like(s)])
    p = np.array([0.0])
    out = []
    for fy in fys:
        for f in np.linspace(fy / 3 if not out else out[-1][0], fy, 3)[1 if out else 0 :]:
            sol = solve_bvp(
                lambda s_, u, p_, f=f: rhs(s_, u, p_, f),
                bc,
                s,
                guess,
                p,
                tol=1e-8,
                max_nodes=100_000,
            )
            assert sol.success, sol.message
            s, guess, p = sol.x, sol.y, sol.p
        out.append((fy, float(sol.y[1, -1])))
    return np.array([d for _, d in out])


def test_clamped_clamped_small_deflection_is_192EI_over_L3() -> None:
    L, t, F = 80.0, 0.5, 1e-6  # d / t = 5e-5: membrane stiffening ~ (d / t)^2 is negligible
    resp = solve_mechanism(
        _clamped_clamped(L, t),
        LoadCase("c", MechDrive("left.end", "force", F, 1, (0, 1))),
        [
            MechOutput("d", "displacement", "right.start", (0, 1)),
            MechOutput("Fg", "reaction_force", "left.start", (0, 1)),
            MechOutput("Mg", "reaction_moment", "left.start"),
            MechOutput("Fd", "reaction_force", "", (0, 1)),
            MechOutput("slope", "rotation", "left.end"),
        ],
    )
    assert resp.ok and resp.stable.all()
    d_ref = F * L**3 / (192.0 * _ei(t)) + F * L / (4.0 * _kga(t))
    assert resp.outputs["d"][-1] == pytest.approx(d_ref, rel=1e-6)
    assert resp.outputs["Fg"][-1] == pytest.approx(-F / 2, rel=1e-6)
    # the ground turns the clamped end against the upward bow: clockwise, F L / 8
    assert resp.outputs["Mg"][-1] == pytest.approx(-F * L / 8, rel=1e-5)
    assert resp.outputs["Fd"][-1] == pytest.approx(F, rel=1e-12)
    assert abs(resp.outputs["slope"][-1]) < 1e-9 * d_ref / L + 1e-15  # symmetric: flat centre


def test_clamped_clamped_large_deflection_stiffens_like_the_reissner_bvp() -> None:
    L, t = 80.0, 0.5
    F = 3.0  # N: the centre moves ~3 thicknesses; the linear beam would move 10x more
    errors = []
    for n_el in (8, 16):
        resp = solve_mechanism(
            _clamped_clamped(L, t, n_el),
            LoadCase("c", MechDrive("left.end", "force", F, 3, (0, 1))),
            [MechOutput("d", "displacement", "left.end", (0, 1))],
        )
        assert resp.ok and resp.stable.all(), resp.message
        errors.append(resp.outputs["d"])
    ref = _reissner_centre(L / 2, t, resp.drive[1:] / 2)
    linear = resp.drive[1:] * (L**3 / (192.0 * _ei(t)) + L / (4.0 * _kga(t)))
    assert np.all(ref < 0.5 * linear)  # the test is about the stretching, far from linear
    err = [np.abs(e[1:] / ref - 1).max() for e in errors]
    assert err[1] < 3e-6  # 8 -> 16 elements per half: 4.4e-6 -> 7e-7
    assert err[1] < err[0]


# ---------------------------------------------------------------- lever, moment, rotation


def _lever(a: float, b: float, Ls: float, t: float) -> Mechanism:
    """A rigid arm pinned to the ground at its reference point (0, 0); a spring leaf, clamped to
    the ground at its far end, pinned to the arm at (b, 0) and lying along the arm."""
    arm = MechBody("arm", np.array([0.0, 0.0]), np.array([[b, -2], [a, -2], [a, 2], [b, 2]]))
    spring = _straight("spring", (b, 0.0), (b - np.sign(b) * Ls, 0.0), t)
    joints = (
        MechJoint("arm", "ground", "pinned"),
        MechJoint("spring.start", f"arm@{b},0", "pinned"),
        MechJoint("spring.end", "ground"),
    )
    return Mechanism((spring,), (arm,), joints, MAT)


def test_lever_geometric_advantage_and_input_stiffness() -> None:
    a, b, Ls, t = 20.0, -40.0, 30.0, 0.5
    mech = _lever(a, b, Ls, t)
    outs = [
        MechOutput("F", "reaction"),
        MechOutput("out", "displacement", "spring.start", (0, 1)),
        MechOutput("out_arm", "displacement", f"arm@{b},0", (0, 1)),
        MechOutput("rot", "rotation", "arm"),
        MechOutput("pivot", "reaction_force", "arm", (0, 1)),
    ]
    # small stroke: hand-derived lever, input stiffness (b/a)^2 k_cantilever (Timoshenko)
    small = solve_mechanism(
        mech, LoadCase("s", MechDrive(f"arm@{a},0", "displacement", 1e-4, 1, (0, 1))), outs
    )
    assert small.ok and small.stable.all()
    k = 1.0 / (Ls**3 / (3.0 * _ei(t)) + Ls / _kga(t))
    assert small.outputs["F"][-1] / small.drive[-1] == pytest.approx((b / a) ** 2 * k, rel=1e-5)
    # the pivot carries the rest: F_in + F_spring_on_arm + F_pivot = 0, F_spring = -(a/b) F_in
    assert small.outputs["pivot"][-1] == pytest.approx(
        -small.outputs["F"][-1] * (1 - a / b), rel=1e-5
    )
    # large stroke: the arm is rigid, so the kinematics are exact: a sin(th) = d, y_out = b sin(th)
    big = solve_mechanism(
        mech, LoadCase("b", MechDrive(f"arm@{a},0", "displacement", 10.0, 4, (0, 1))), outs
    )
    assert big.ok, big.message
    np.testing.assert_allclose(big.outputs["rot"], np.arcsin(big.drive / a), atol=1e-12)
    np.testing.assert_allclose(big.outputs["out"], b / a * big.drive, atol=1e-10)
    np.testing.assert_allclose(big.outputs["out_arm"], b / a * big.drive, atol=1e-10)
    # the drive keeps doing positive work on a stiffening spring
    assert np.all(np.diff(big.outputs["F"]) > 0)
    np.testing.assert_allclose(big.body_poses[:, 0, :2], 0.0, atol=1e-12)  # pinned ref


@pytest.mark.parametrize("control", ["moment", "rotation"])
def test_pure_bending_of_a_cantilever_by_a_body(control: str) -> None:
    """A moment on a body clamped to a cantilever's end bends the leaf into a circle:
    phi = M L / EI, tip (sin phi, 1 - cos phi) L / phi, the body turns rigidly with it."""
    L, t = 40.0, 0.4
    ei = _ei(t)
    phi = 2.0
    value = phi * ei / L if control == "moment" else phi
    tips = []
    for n_el in (5, 10, 20):
        leaf = _straight("leaf", (0.0, 0.0), (L, 0.0), t, n_el)
        body = MechBody("block", np.array([L + 4.0, 3.0]))
        mech = Mechanism(
            (leaf,),
            (body,),
            (MechJoint("leaf.start", "ground"), MechJoint("leaf.end", "block")),
            MAT,
        )
        resp = solve_mechanism(
            mech,
            LoadCase("m", MechDrive("block", control, value, 4)),
            [
                MechOutput("M", "reaction"),
                MechOutput("rot", "rotation", "leaf.end"),
                MechOutput("Md", "reaction_moment", ""),
            ],
        )
        assert resp.ok and resp.stable.all(), resp.message
        M = resp.outputs["M"]
        np.testing.assert_allclose(resp.outputs["rot"], M * L / ei, rtol=1e-9, atol=1e-14)
        np.testing.assert_allclose(resp.outputs["Md"], M, rtol=1e-9, atol=1e-14)
        tip = resp.shapes_mm[0][-1, -1]
        tips.append(tip)
        # the body is carried rigidly: ref = tip + R(phi) (ref0 - tip0)
        c, s = np.cos(phi), np.sin(phi)
        ref = tip + np.array([[c, -s], [s, c]]) @ np.array([4.0, 3.0])
        np.testing.assert_allclose(resp.body_poses[-1, 0, :2], ref, atol=1e-9)
        assert resp.body_poses[-1, 0, 2] == pytest.approx(phi, rel=1e-9)
    exact = np.array([np.sin(phi), 1 - np.cos(phi)]) * L / phi
    err = [np.hypot(*(tp - exact)) for tp in tips]
    assert err[-1] < 1e-4 * L
    assert err[0] / err[1] > 3.0 and err[1] / err[2] > 3.0  # converges with the mesh


def test_moment_on_an_arc_beam_end_bends_it_to_a_new_circle() -> None:
    """A quarter-circle beam (an exact arc, curvature_per_mm) clamped at its start, a moment on
    its free end: the curvature rises by M / EI everywhere, so the end is on a known circle."""
    R, t = 20.0, 0.4
    ei = _ei(t)
    L = np.pi * R / 2
    arc = MechBeam(
        "arc", np.array([[R, 0.0], [0.0, R]]), np.array([t, t]), W, 24, np.array([1 / R])
    )
    mech = Mechanism((arc,), (), (MechJoint("arc.start", "ground"),), MAT)
    M = 1.5 * ei / L  # turns the end by 1.5 rad more
    resp = solve_mechanism(
        mech,
        LoadCase("m", MechDrive("arc.end", "moment", M, 3)),
        [MechOutput("rot", "rotation", "arc.end")],
    )
    assert resp.ok and resp.stable.all()
    np.testing.assert_allclose(resp.outputs["rot"], resp.drive * L / ei, rtol=1e-9, atol=1e-14)
    kappa = 1 / R + M / ei
    th0 = np.pi / 2
    end = (
        np.array([R, 0.0])
        + np.array([np.sin(th0 + kappa * L) - np.sin(th0), np.cos(th0) - np.cos(th0 + kappa * L)])
        / kappa
    )
    np.testing.assert_allclose(resp.shapes_mm[0][-1, -1], end, atol=1e-4 * R)
    np.testing.assert_allclose(resp.shapes_mm[0][0, -1], [0.0, R], atol=1e-12)
    np.testing.assert_allclose(resp.thickness_at_nodes_mm[0], t)
    # the reference nodes lie on the arc
    np.testing.assert_allclose(np.hypot(*resp.shapes_mm[0][0].T), R, rtol=1e-12)


def test_case_support_blocks_a_jaw() -> None:
    """A blocked-force case: leaf 1 carries body A from the ground, leaf 2 carries a jaw B from
    A. Holding B to the ground in this case only (a support), A driven across: each leaf is a
    guided leaf, so the drive feels 2k and the support holds B against k (k = Timoshenko)."""
    # d / t = 2.5e-4: the two leaves, in series along x between ground and the held jaw,
    # stretch as A moves across; that membrane stiffening ~ (d / t)^2 is negligible
    L, t, d = 30.0, 0.4, 1e-4
    leaf1 = _straight("leaf1", (0.0, 0.0), (L, 0.0), t)
    leaf2 = _straight("leaf2", (L + 4.0, 0.0), (2 * L + 4.0, 0.0), t)
    a = MechBody("A", np.array([L + 2.0, 0.0]))
    # the jaw's reference on the leaf's line: the leaves' (second-order) tension has no arm
    jaw = MechBody("jaw", np.array([2 * L + 6.0, 0.0]))
    joints = (
        MechJoint("leaf1.start", "ground"),
        MechJoint("leaf1.end", "A"),
        MechJoint("leaf2.start", "A"),
        MechJoint("leaf2.end", "jaw"),
    )
    mech = Mechanism((leaf1, leaf2), (a, jaw), joints, MAT)
    drive = MechDrive("A", "displacement", d, 1, (0, 1), "free", "held")
    outs = [
        MechOutput("F", "reaction"),
        MechOutput("blocked", "reaction_force", "jaw", (0, 1)),
        MechOutput("M", "reaction_moment", "jaw"),
    ]
    resp = solve_mechanism(
        mech, LoadCase("blocked", drive, (MechJoint("jaw", "ground", "clamped"),)), outs
    )
    assert resp.ok and resp.stable.all()
    k = 1.0 / (L**3 / (12.0 * _ei(t)) + L / _kga(t))
    assert resp.outputs["F"][-1] == pytest.approx(2 * k * d, rel=1e-6)
    assert resp.outputs["blocked"][-1] == pytest.approx(-k * d, rel=1e-6)
    # moment about the jaw's reference: the leaf pulls the jaw up by k d at its end, 2 mm before
    # the reference, and turns it clockwise by the guided leaf's end moment k d L / 2; the
    # ground balances both
    assert resp.outputs["M"][-1] == pytest.approx(k * d * L / 2 + 2.0 * k * d, rel=1e-5)
    # without the support the jaw just rides along: the case needs its drive to hold A only
    free = solve_mechanism(mech, LoadCase("free", drive), [MechOutput("F", "reaction")])
    assert free.outputs["F"][-1] == pytest.approx(k * d, rel=1e-6)
    assert free.body_poses[-1, 1, 1] == pytest.approx(d, rel=1e-9)


def test_min_value_starts_the_path_elsewhere() -> None:
    """Row 0 is min_value, reached from the undeformed state first; a symmetric leaf answers
    F(-d) = -F(d)."""
    resp = solve_mechanism(
        _guided_leaf(50.0, 0.5),
        LoadCase("p", MechDrive("shuttle", "displacement", 5.0, 4, (0, 1), "free", "held", -5.0)),
        [MechOutput("F", "reaction")],
    )
    assert resp.ok
    np.testing.assert_allclose(resp.drive, [-5, -2.5, 0, 2.5, 5])
    np.testing.assert_allclose(resp.outputs["F"], -resp.outputs["F"][::-1], rtol=1e-8, atol=1e-12)


# ---------------------------------------------------------------- bistable, stability


def _bistable_arch() -> Mechanism:
    """A shallow sine arch, pinned to the ground at both ends, cut at its apex and clamped to a
    shuttle body there (h / t = 6.7: bistable)."""
    S, h, t = 60.0, 2.0, 0.3
    x = np.linspace(0.0, S, 41)
    pts = np.stack([x, h * np.sin(np.pi * x / S)], axis=1)
    left = MechBeam("left", pts[:21], np.full(21, t), W)
    right = MechBeam("right", pts[20:], np.full(21, t), W)
    shuttle = MechBody("shuttle", np.array([S / 2, h]))
    joints = (
        MechJoint("left.start", "ground", "pinned"),
        MechJoint("right.end", "ground", "pinned"),
        MechJoint("left.end", "shuttle"),
        MechJoint("right.start", "shuttle"),
    )
    return Mechanism((left, right), (shuttle,), joints, MAT)


def test_bistable_snap_through_under_displacement_control() -> None:
    mech = _bistable_arch()
    guided = LoadCase(
        "snap", MechDrive("shuttle", "displacement", 5.0, 25, (0, -1), "held", "held")
    )
    resp = solve_mechanism(mech, guided, [MechOutput("F", "reaction")])
    assert resp.ok, resp.message
    F = resp.outputs["F"]
    assert F.max() > 0 and F.min() < 0  # the force changes sign: a second stable state
    # The actuator holds the shuttle: the guided path is stable in the constrained sense.
    assert resp.stable.all()
    # Released to a dead load (force control) it is stable exactly where dF/dd > 0: the Schur
    # complement of the drive row is the path's tangent stiffness. Compare away from the extrema.
    dF = np.diff(F)
    rising_both = (dF[:-1] > 0) & (dF[1:] > 0)
    falling_both = (dF[:-1] < 0) & (dF[1:] < 0)
    inner = resp.stable_released[1:-1]
    assert np.all(inner[rising_both]) and not np.any(inner[falling_both])
    assert falling_both.sum() >= 5

    # With the shuttle free to turn, the perfectly symmetric arch bifurcates into its
    # asymmetric mode on the way down: the symmetric path the solver keeps is flagged there.
    free = LoadCase("snap", MechDrive("shuttle", "displacement", 5.0, 25, (0, -1), "held", "free"))
    resp_free = solve_mechanism(mech, free, [MechOutput("F", "reaction")])
    assert resp_free.ok
    np.testing.assert_allclose(resp_free.outputs["F"], F, rtol=1e-6, atol=1e-9)
    assert not resp_free.stable.all() and resp_free.stable[:5].all()
    assert "unstable from row" in resp_free.message


def test_a_strut_pushed_past_euler_is_flagged_at_the_euler_load() -> None:
    """A perfect clamped-guided strut shortened past P = 4 pi^2 EI / L^2 stays straight in the
    solver (no imperfection selects a side) but is flagged unstable from the Euler load on."""
    L, t = 50.0, 0.5
    strut = _straight("strut", (0.0, 0.0), (0.0, L), t, 20)
    mech = Mechanism((strut,), (), (MechJoint("strut.start", "ground"),), MAT)
    p_cr = 4.0 * np.pi**2 * _ei(t) / L**2
    d_cr = p_cr * L / (MAT.E_MPa * W * t)  # the shortening that carries P_cr
    case = LoadCase(
        "c", MechDrive("strut.end", "displacement", 2.0 * d_cr, 8, (0, -1), "held", "held")
    )
    resp = solve_mechanism(mech, case, [MechOutput("F", "reaction")])
    assert resp.ok
    # shear (Engesser) and stretching lower the Reissner column's load by ~ P_cr / kGA = 1e-3
    assert resp.critical_drive == pytest.approx(d_cr, rel=3e-3)
    np.testing.assert_array_equal(resp.stable, resp.drive < resp.critical_drive)
    assert "unstable from row 4" in resp.message
    np.testing.assert_allclose(resp.outputs["F"], resp.drive * MAT.E_MPa * W * t / L, rtol=1e-9)


@pytest.mark.parametrize("kink", [1e-5, -1e-5])
def test_an_imperfect_strut_buckles_to_its_side_and_follows_the_elastica(kink: float) -> None:
    """The physical-branch start: a strut with a kink of 1e-5 L at mid-length, shortened 20x
    past its Euler shortening in 5 rows, buckles to the side of the kink and stays on the stable
    post-buckled branch. Reference: the clamped-clamped elastica is four quarter-length
    cantilevers, P = 16 EI K(m)^2 / L^2 and shortening 2 L (1 - E(m) / K(m)); the FE column also
    shears and stretches, which lowers its load by the factor (1 + P/kGA)(1 - P/EA) (Engesser,
    to first order) and adds P L / EA to the shortening."""
    L, t = 50.0, 0.5
    pts = np.array([[0.0, 0.0], [kink * L, L / 2], [0.0, L]])
    strut = MechBeam("strut", pts, np.full(3, t), W, 20)
    mech = Mechanism((strut,), (), (MechJoint("strut.start", "ground"),), MAT)
    case = LoadCase(
        "c", MechDrive("strut.end", "displacement", 0.1 * L, 5, (0, -1), "held", "held")
    )
    resp = solve_mechanism(mech, case, [MechOutput("P", "reaction")])
    assert resp.ok and resp.stable.all(), resp.message
    lateral = resp.shapes_mm[0][1:, 20, 0]  # the mid-length node
    assert np.all(np.sign(lateral) == np.sign(kink)) and np.abs(lateral).min() > 4.0
    ei, ea, kga = _ei(t), MAT.E_MPa * W * t, _kga(t)
    for d, P in zip(resp.drive[1:], resp.outputs["P"][1:], strict=True):
        bent = d - P * L / ea
        m = brentq(lambda m, bent=bent: 2 * L * (1 - ellipe(m) / ellipk(m)) - bent, 1e-12, 0.9)
        p_ref = 16 * ei * ellipk(m) ** 2 / L**2 / ((1 + P / kga) * (1 - P / ea))
        assert P == pytest.approx(p_ref, rel=1.5e-4)  # 6e-5 seen


def test_force_control_past_the_limit_is_data_not_an_exception() -> None:
    mech = _bistable_arch()
    peak = 0.0507  # N, just above the guided path's peak force (about 0.0506 N)
    case = LoadCase("f", MechDrive("shuttle", "force", -peak * 1.2, 12, (0, 1), "held", "held"))
    resp = solve_mechanism(mech, case, [MechOutput("d", "displacement", "shuttle", (0, -1))])
    assert not resp.ok and resp.message
    assert resp.converged[0] and not resp.converged[-1]
    last = np.flatnonzero(resp.converged)[-1]
    assert abs(resp.drive[last]) < peak
    assert resp.stable[: last + 1].all()
    assert np.isnan(resp.outputs["d"][-1])


def test_kkt_inertia_count_matches_eigenvalues() -> None:
    """The sparse no-pivot count (and the dense fallback) against a dense eigenvalue count, for
    a KKT matrix whose primal block is singular (a body's DOFs) and indefinite."""
    import scipy.sparse as sp

    rng = np.random.default_rng(3)
    n, m = 12, 4
    for n_negative in (0, 1, 3):
        q, _ = np.linalg.qr(rng.normal(size=(n, n)))
        ev = rng.uniform(1.0, 3.0, n)
        ev[:2] = 0.0  # singular H (like bodies)
        ev[2 : 2 + n_negative] *= -1
        H = q @ np.diag(ev) @ q.T
        G = rng.normal(size=(m, n))
        kkt = np.block([[H, G.T], [G, np.zeros((m, m))]])
        expect = int((np.linalg.eigvalsh(kkt) < 0).sum())
        assert kkt_negative_count(sp.csr_matrix(H), sp.csr_matrix(G)) == expect


# ---------------------------------------------------------------- refusals and helpers


def test_free_rigid_body_motion_is_refused_naming_the_part() -> None:
    spring = _straight("spring", (10.0, 0.0), (40.0, 0.0), 0.5)
    arm = MechBody("arm", np.array([0.0, 0.0]))
    # the arm hangs on one pin: it can turn about it
    mech = Mechanism(
        (spring,),
        (arm,),
        (MechJoint("spring.start", "ground"), MechJoint("spring.end", "arm", "pinned")),
        MAT,
    )
    case = LoadCase("c", MechDrive("spring.end", "force", 1.0, 2, (0, 1)))
    with pytest.raises(FeaError, match=r"free rigid-body motion.*body 'arm' \(turns about \(40, 0"):
        solve_mechanism(mech, case)
    with pytest.raises(FeaError, match="body 'arm'"):
        check_mechanism(mech, case)
    check_mechanism(mech)  # without a case the free-motion test waits for the supports
    # ... but a rotation drive on the arm holds that motion: solvable
    held = LoadCase("r", MechDrive("arm", "rotation", 0.01, 1))
    check_mechanism(mech, held)
    # a beam pinned at one end only turns about the pin
    lonely = Mechanism((spring,), (), (MechJoint("spring.start", "ground", "pinned"),), MAT)
    with pytest.raises(FeaError, match=r"beam 'spring' \(turns about \(10, 0"):
        check_mechanism(lonely, LoadCase("c", MechDrive("spring.end", "force", 1.0, 2, (0, 1))))
    # a body attached to nothing
    floating = Mechanism(
        (spring,),
        (arm, MechBody("block", np.array([5.0, 5.0]))),
        (MechJoint("spring.start", "ground"), MechJoint("spring.end", "arm")),
        MAT,
    )
    with pytest.raises(FeaError, match=r"3 degree\(s\).*body 'block'"):
        check_mechanism(floating, LoadCase("c", MechDrive("arm", "force", 1.0, 2)))


@pytest.mark.parametrize(
    ("joints", "match"),
    [
        ((MechJoint("leaf.start", "ground"), MechJoint("leaf.start", "ground")), "redundant"),
        ((MechJoint("leaf.begin", "ground"),), "unknown part 'leaf.begin'"),
        ((MechJoint("leaf.start", "nowhere"),), "unknown part 'nowhere'"),
        ((MechJoint("leaf.start", "ground", "welded"),), "clamped' or 'pinned"),
        ((MechJoint("leaf.start", "leaf.end"),), "mm apart"),
    ],
)
def test_bad_joints_are_refused(joints, match: str) -> None:
    leaf = _straight("leaf", (0.0, 0.0), (10.0, 0.0), 0.5)
    with pytest.raises(FeaError, match=match):
        check_mechanism(
            Mechanism((leaf,), (), joints, MAT),
            LoadCase("c", MechDrive("leaf.end", "force", 1.0, 1)),
        )


def test_bad_names_and_outputs_are_refused() -> None:
    leaf = _straight("leaf", (0.0, 0.0), (10.0, 0.0), 0.5)
    with pytest.raises(FeaError, match="duplicate part names"):
        check_mechanism(Mechanism((leaf,), (MechBody("leaf", np.zeros(2)),), (), MAT))
    mech = Mechanism((leaf,), (), (MechJoint("leaf.start", "ground"),), MAT)
    case = LoadCase("c", MechDrive("leaf.end", "force", 1e-3, 1, (0, 1)))
    with pytest.raises(FeaError, match="not held to the ground"):
        solve_mechanism(mech, case, [MechOutput("R", "reaction_force", "leaf.end")])
    with pytest.raises(FeaError, match="beam name"):
        solve_mechanism(mech, case, [MechOutput("s", "peak_stress", "leaf.end")])
    with pytest.raises(FeaError, match="duplicate output"):
        solve_mechanism(mech, case, [MechOutput("a", "rotation", "leaf.end")] * 2)


def test_mass_of_beams_and_bodies() -> None:
    rho = MAT.density_kg_m3 * 1e-6  # g/mm^3
    taper = MechBeam(
        "taper", np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]]), np.array([1.0, 0.5, 1.0]), 4.0
    )
    square = MechBody("sq", np.zeros(2), np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float))
    mech = Mechanism((taper,), (square,), (), MAT)
    beam = 2 * 10.0 * 0.75 * 4.0
    assert mass_g(mech) == pytest.approx(beam * rho)
    assert mass_g(mech, body_thickness_mm=3.0) == pytest.approx((beam + 300.0) * rho)


def test_newton_jacobian_matches_finite_differences() -> None:
    """The KKT Jacobian with the constraint-Hessian term, at a random state with a body turned,
    against central differences of [r - f - G^T lam, g] (what keeps Newton quadratic)."""
    import scipy.sparse as sp
    from flexopt.fea.mechanism import MechanismSettings, _Model

    leaf = _straight("leaf", (0.0, 0.0), (40.0, 0.0), 0.4, 3)
    body = MechBody("block", np.array([44.0, 3.0]))
    mech = Mechanism(
        (leaf,),
        (body,),
        (MechJoint("leaf.start", "ground"), MechJoint("leaf.end", "block@50,1")),
        MAT,
    )
    case = LoadCase("m", MechDrive("block@30,-2", "displacement", 3.0, 3, (0.3, 1.0)))
    md = _Model(mech, case, MechanismSettings())
    rng = np.random.default_rng(0)
    z, lam, p = 0.1 * rng.normal(size=md.n), rng.normal(size=md.m), 0.7

    def kkt_residual(x: np.ndarray) -> np.ndarray:
        r, _ = md.assemble(x[: md.n])
        g, G, _ = md.constraints(x[: md.n], p)
        return np.concatenate([r - md.loads(p) - G.T @ x[md.n :], g])

    _, K = md.assemble(z)
    _, G, d2g = md.constraints(z, p)
    J = sp.bmat([[md.hessian(K, lam, d2g), -G.T], [G, None]]).toarray()
    x0 = np.concatenate([z, lam])
    eps = 1e-6
    Jn = np.column_stack(
        [
            (kkt_residual(x0 + eps * e) - kkt_residual(x0 - eps * e)) / (2 * eps)
            for e in np.eye(x0.size)
        ]
    )
    assert np.abs(J - Jn).max() < 1e-8 * np.abs(J).max()
    assert np.abs(d2g).max() > 0  # the nonlinear rows are really there
