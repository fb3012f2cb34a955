"""Frictionless contact of the beam with rigid stops (fea/stops.py) against answers derived here.

Exact references:

* the propped cantilever in small deflection, by superposition of two cantilever load cases
  (a tip force P and the stop's reaction R at x = a), with the Timoshenko shear compliance the
  model has (the beam is slender, so shear is ~1e-4 of the deflection, but it is included so that
  the comparison is at the level of the penalty and the geometric nonlinearity, ~1e-6);
* a cantilever under a large dead tip load pressed onto an inclined flat stop, against
  ``scipy.integrate.solve_bvp`` of the inextensible elastica with the contact force as an unknown
  parameter. The exact answer is a single contact point at the tip: the tip is moment free
  (curvature 0 there), the flat is straight, and the beam meets it at an angle (the tip's
  tangent at -49 degrees, the flat at -37: the beam behind the tip rises away from the flat), so
  the rest of the beam stays clear of it, not a wrapping region; the test checks that on the
  exact solution (every point of the elastica but the tip is above the flat).
"""

from dataclasses import replace

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.stops import BeamContact, ContactSettings, RigidStop, solve_with_stops
from flexopt.geometry.profile import BeamProfile
from scipy.integrate import solve_bvp

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
L, T, B = 100.0, 0.5, 2.0
EI = MAT.E_MPa * B * T**3 / 12.0  # N mm^2
KGA = 5.0 / 6.0 * MAT.G_MPa * B * T  # N


def model(kernel="auto", n=20, t_end=T):
    prof = BeamProfile([[0.0, 0.0], [L, 0.0]], [T if t_end == T else 0.8, t_end], B)
    return BeamModel(prof, MAT, settings=BeamSettings(n_elements=n, kernel=kernel))


def cantilever_deflection(x, a):
    """Downward deflection (mm) at x of a Timoshenko cantilever (clamped at 0) under a unit
    downward force at x = a: bending x^2 (3a - x) / 6EI (x <= a), a^2 (3x - a) / 6EI (x >= a),
    plus the shear term min(x, a) / kGA."""
    bend = x**2 * (3 * a - x) / 6 if x <= a else a**2 * (3 * x - a) / 6
    return bend / EI + min(x, a) / KGA


def propped(delta, a, g0):
    """Tip force P and stop reaction R (N) of the cantilever with its tip pushed down by delta
    (mm), a rigid stop at x = a a gap g0 (mm) below the beam: before contact R = 0 and
    P = delta / w_LL; after it, w(a) = g0 and w(L) = delta with w = P w_L - R w_a."""
    w_ll, w_al = cantilever_deflection(L, L), cantilever_deflection(a, L)
    w_la, w_aa = cantilever_deflection(L, a), cantilever_deflection(a, a)
    closing = g0 * w_ll / w_al
    if delta <= closing:
        return delta / w_ll, 0.0, closing
    P, R = np.linalg.solve([[w_al, -w_aa], [w_ll, -w_la]], [g0, delta])
    return P, R, closing


G0 = 0.02  # mm, the gap between the beam's surface and the stop
DRIVE = EndDrive("displacement", (0.0, -1.0), 0.2, steps=10, rotation="free", transverse="free")


def stop_at(a, kind):
    """A stop whose contact point is at (a, -(t/2 + g0)): a point, the upper right corner of a
    block, the right end of a thin wall."""
    y = -(T / 2 + G0)
    if kind == "point":
        return RigidStop.point((a, y), "pin")
    if kind == "polygon":
        return RigidStop.polygon([[a - 10, y - 5], [a, y - 5], [a, y], [a - 10, y]], "block")
    return RigidStop.segment((a - 10, y), (a, y), "wall")


@pytest.mark.parametrize("kind", ["point", "polygon", "segment"])
@pytest.mark.parametrize("kernel", ["numba", "numpy"])
def test_propped_cantilever_reaction_split_and_closing(kind, kernel):
    a = L / 2
    res = solve_with_stops(model(kernel), DRIVE, [stop_at(a, kind)])
    assert res.ok, res.message
    c = res.contact
    exact = [propped(d, a, G0) for d in res.displacement_mm]
    P = np.array([e[0] for e in exact])
    R = np.array([e[1] for e in exact])
    closing = exact[0][2]
    # tip force vs tip displacement and the reaction split; the penalty's penetration (~1e-6 of
    # the gap) and the geometric nonlinearity ((delta/L)^2 ~ 4e-6) are the differences
    np.testing.assert_allclose(res.force_N, P, rtol=2e-5, atol=1e-12)
    np.testing.assert_allclose(c.force_N[:, 0], R, rtol=2e-5, atol=1e-12)
    # the reaction at the clamp: force balance
    assert c.force_vector_N[-1, 0, 1] > 0.0  # the stop pushes the beam up
    assert abs(c.force_vector_N[-1, 0, 0]) < 1e-2 * c.force_N[-1, 0]  # nearly vertical
    # the gap closes where the cantilever's own deflection at a reaches g0
    assert c.initial_gap_mm[0] == pytest.approx(G0, rel=1e-12)
    assert c.closing_value[0] == pytest.approx(closing, rel=1e-4)
    assert np.array_equal(c.in_contact[:, 0], res.displacement_mm > closing)
    assert np.array_equal(c.rows_in_contact, c.in_contact[:, 0])
    # before contact the gap follows the cantilever's deflection at a
    before = res.displacement_mm < closing
    np.testing.assert_allclose(
        c.gap_mm[before, 0], G0 * (1 - res.displacement_mm[before] / closing), atol=1e-6
    )
    # the contact point is the stop's point, the penetration within the tolerance
    touching = c.in_contact[:, 0]
    np.testing.assert_allclose(c.point_mm[touching, 0], [[a, -(T / 2 + G0)]] * touching.sum())
    assert np.all(np.isnan(c.point_mm[~touching, 0]))
    assert c.penetration_ok and c.max_penetration_mm.max() < 1e-5
    # Newton converges fast (a consistent tangent) once the contact is established
    assert res.iterations[touching][1:].max() <= 3


def test_penalty_converges_to_the_lagrange_value():
    """Penetration ~ R / k -> 0 and the reaction -> the constrained (Lagrange) value as the
    penalty grows; the closed-form R (shear included) is the Lagrange value here, up to the
    geometric nonlinearity and the mesh (~1e-6)."""
    a = L / 2
    _, r_exact, _ = propped(DRIVE.max_value, a, G0)
    pen, err = [], []
    for factor in (1e-2, 1e-1, 1e0, 1e1, 1e2, 1e3):
        res = solve_with_stops(
            model(), DRIVE, [stop_at(a, "point")], ContactSettings(factor, max_raises=0)
        )
        assert res.ok, res.message
        c = res.contact
        k = c.penalty_N_per_mm[0]
        # the penalty law: force = k x penetration (the stop sits on an element end: one k)
        assert c.force_N[-1, 0] == pytest.approx(k * c.max_penetration_mm[-1], rel=1e-9)
        pen.append(c.max_penetration_mm[-1])
        err.append(abs(c.force_N[-1, 0] - r_exact) / r_exact)
    pen, err = np.array(pen), np.array(err)
    assert np.all(np.diff(pen) < 0) and np.all(np.diff(err) < 0)
    # first order in 1/k once the penalty is stiffer than the beam (factor >= 1): the
    # penetration and the force error fall 10x per decade, until the force error meets the
    # model's own floor (geometric nonlinearity, mesh: ~1e-6)
    np.testing.assert_allclose(pen[2:-1] / pen[3:], 10.0, rtol=0.02)
    np.testing.assert_allclose(err[2:4] / err[3:5], 10.0, rtol=0.15)
    assert err[-1] < 5e-6
    # the tolerance (1e-3 t = 5e-4 mm) is exceeded by the softest penalty (2.5e-2 mm) ...
    soft = ContactSettings(1e-2, penetration_tol=1e-3, max_raises=0)
    c = solve_with_stops(model(), DRIVE, [stop_at(a, "point")], soft).contact
    assert not c.penetration_ok and "penalty_factor" in c.message
    # ... and met after raising it 10x three times (5.1e-3, 5.7e-4, then 5.8e-5 mm)
    raised = replace(soft, max_raises=3)
    c = solve_with_stops(model(), DRIVE, [stop_at(a, "point")], raised).contact
    assert c.penetration_ok and c.extra["raises"] == 3 and c.extra["penalty_factor"] == 10.0


def test_no_stop_and_untouched_stop_give_the_plain_solve():
    for kernel in ("numba", "numpy"):
        m = model(kernel)
        plain = m.solve(DRIVE)
        same = solve_with_stops(m, DRIVE, [])
        assert same.contact is None
        for name in ("displacement_mm", "force_N", "moment_Nmm", "peak_stress_MPa", "shapes_mm"):
            assert np.array_equal(getattr(plain, name), getattr(same, name))
        far = solve_with_stops(m, DRIVE, [RigidStop.point((50.0, -5.0)), stop_at(150.0, "point")])
        c = far.contact
        assert not c.rows_in_contact.any() and np.all(c.force_N == 0.0)
        assert np.all(np.isnan(c.closing_value))
        for name in ("displacement_mm", "force_N", "moment_Nmm", "peak_stress_MPa", "shapes_mm"):
            got, want = getattr(far, name), getattr(plain, name)
            if kernel == "numpy":  # the same code adding exact zeros
                assert np.array_equal(got, want), name
            else:  # the Python loop against the compiled one: round-off (test_beam_kernels.py)
                np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-13)
        assert np.array_equal(far.iterations, plain.iterations)


def elastica_on_flat(P, A, n):
    """Inextensible cantilever (clamped at the origin along x) under a dead tip force P (N) down,
    its tip pressed on the flat n . (x - A) = t/2 (the beam's surface on the line): the contact
    force R n (N) acts at the tip. EI theta' = M, M' = F_x sin theta - F_y cos theta with
    F = (R n_x, R n_y - P); x(0) = y(0) = theta(0) = 0, M(L) = 0, the tip on the flat.
    Returns the solution (R = sol.p[0])."""

    def f(s, y, p):
        fx, fy = p[0] * n[0], p[0] * n[1] - P
        return np.vstack(
            [np.cos(y[2]), np.sin(y[2]), y[3], (fx * np.sin(y[2]) - fy * np.cos(y[2])) / EI]
        )

    def bc(y0, y1, p):
        return np.array([y0[0], y0[1], y0[2], y1[3], n @ (y1[:2] - A) - T / 2])

    s = np.linspace(0.0, L, 401)
    # start: a circular arc ending near the contact (the solver finds the rest)
    th = -0.85 * (s / L) * (2 - s / L)
    y = np.vstack([np.cumsum(np.cos(th)) * (s[1] - s[0]), np.cumsum(np.sin(th)) * (s[1] - s[0])])
    y = np.vstack([y, th, np.gradient(th, s)])
    sol = solve_bvp(f, bc, s, y, p=[0.01], tol=1e-10, max_nodes=100000)
    assert sol.status == 0, sol.message
    return sol


def test_large_deflection_on_an_inclined_flat_against_the_elastica():
    C, tau = np.array([80.0, -55.0]), np.array([0.8, -0.6])
    A, Bp = C - 60 * tau, C + 60 * tau
    n = np.array([-tau[1], tau[0]])  # the flat's normal, towards the beam
    P = 6.0 * EI / L**2
    drive = EndDrive("force", (0.0, -1.0), P, steps=12, rotation="free", transverse="free")
    res = solve_with_stops(model(n=40), drive, [RigidStop.segment(A, Bp, "flat")])
    assert res.ok, res.message
    c = res.contact
    sol = elastica_on_flat(P, A, n)
    R = sol.p[0]
    # t / L = 1/200: axial and shear compliance (absent in the elastica) ~1e-5 of the answers
    assert c.force_N[-1, 0] == pytest.approx(R, rel=2e-4)
    np.testing.assert_allclose(c.force_vector_N[-1, 0], R * n, rtol=2e-4)
    np.testing.assert_allclose(res.shapes_mm[-1, -1], sol.y[:2, -1], atol=2e-3)
    assert res.end_rotation_rad[-1] == pytest.approx(sol.y[2, -1], abs=1e-4)
    # the contact point: the tip's foot on the flat
    foot = sol.y[:2, -1] - (T / 2) * n
    np.testing.assert_allclose(c.point_mm[-1, 0], foot, atol=2e-3)
    # the exact answer is a single contact point at the tip: the elastica stays above the flat
    lam = (sol.y[:2].T - A) @ tau / np.hypot(*(Bp - A))
    on_face = (lam > 0) & (lam < 1)
    clearance = (sol.y[:2].T - A) @ n - T / 2
    assert np.all(clearance[on_face][:-1] > 0.0) and abs(clearance[-1]) < 1e-8
    # the free cantilever's tip reaches the flat inside the load range; before that no contact
    assert 0.3 * P < c.closing_value[0] < 0.5 * P
    assert not c.in_contact[res.force_N < c.closing_value[0] - 1e-12, 0].any()
    assert c.in_contact[-1, 0] and c.penetration_ok


@pytest.mark.parametrize("t_end", [T, 0.4])
@pytest.mark.parametrize("kind", ["point", "polygon", "segment"])
def test_contact_tangent_is_the_derivative_of_the_contact_force(kind, t_end):
    """Central differences of the forces :meth:`BeamContact.add` adds against its tangent, in
    the generalised DOFs of a rotated drive frame (the end node's translations), on a state in
    which the beam penetrates the stop somewhere inside an element and at the driven end; a
    uniform beam and a tapered one (0.8 -> 0.4 mm: the closest point moves off the centreline's
    foot, the taper term of the vertex pair)."""
    m = model("numpy", n=4, t_end=t_end)
    frame = np.array([[0.6, -0.8], [0.8, 0.6]])
    # a bent state: the beam dips below y = -1 around x = 60 and at its end
    x_nodes = m.reference_nodes_mm[:, 0]
    q = np.zeros(m.n_dofs)
    q[1::3] = -1.2 * np.sin(np.pi * x_nodes / 120.0) ** 2
    q[2::3] = 0.03 * np.cos(x_nodes / 30.0)
    q[0::3] = 0.01 * x_nodes
    # node positions (x, y): (50.5, -1.12), (63.1, -1.19), (75.8, -1.02), (88.4, -0.68), (101, -0.3)
    stops = {
        # inside the fourth element, and past the driven end (its rounded end)
        "point": [RigidStop.point((69.0, -1.3)), RigidStop.point((101.1, -0.45))],
        # a node on the top face, both top corners on the beam
        "polygon": [RigidStop.polygon([[55, -6], [70, -6], [70, -1.3], [55, -1.3]])],
        # nodes on it, nodes across it (pushed back), the driven end on it
        "segment": [RigidStop.segment((40.0, -1.4), (110.0, -0.35))],
    }[kind]
    contact = BeamContact(m, stops, ContactSettings(penalty_factor=1.0))

    def forces(qg):
        u = qg.copy()
        u[-3:-1] = frame.T @ qg[-3:-1]
        r = np.zeros(m.n_dofs)
        ab = np.zeros((25, m.n_dofs), order="F")
        contact.add(u, frame, r, ab)
        return r, ab

    # generalised end-node translations of the physical state
    qg = q.copy()
    qg[-3:-1] = frame @ q[-3:-1]
    r0, ab = forces(qg)
    pairs = contact.pairs(m.reference_nodes_mm + q.reshape(-1, 3)[:, :2])
    assert len(pairs) >= 2
    assert kind == "polygon" or any(m.n_nodes - 1 in p.nodes for p in pairs)
    K = np.zeros((m.n_dofs, m.n_dofs))
    for j in range(m.n_dofs):
        for i in range(max(0, j - 8), min(m.n_dofs, j + 9)):
            K[i, j] = ab[16 + i - j, j]
    h = 1e-6
    fd = np.zeros_like(K)
    for j in range(m.n_dofs):
        e = np.zeros(m.n_dofs)
        e[j] = h
        fd[:, j] = (forces(qg + e)[0] - forces(qg - e)[0]) / (2 * h)
    scale = np.abs(K).max()
    np.testing.assert_allclose(K, fd, atol=1e-6 * scale)
    np.testing.assert_allclose(K, K.T, atol=1e-12 * scale)


def test_newton_with_contact_converges_quadratically():
    """Full Newton (the beam's tangent plus the contact's) on a propped cantilever at large
    deflection (tip 10 mm down in 1 mm steps, the pin pressing on the beam at mid-span from the
    start): the residual falls quadratically, e_{k+1} ~ e_k^2, to round-off. (The pin starts in
    contact so that no step closes a gap: there, plain Newton can cycle between the pair on and
    off, which the tracing loop resolves by cutting the step, tested above.)"""
    m = model("numpy")
    drive = EndDrive("displacement", (0.0, -1.0), 10.0, rotation="free", transverse="free")
    # 1e-4 mm of interference: the pair is active from the first iteration on
    contact = BeamContact(m, [RigidStop.point((L / 2, -(T / 2 - 1e-4)))])
    frame = m._frame(drive)
    fixed = m._fixed_dofs(drive)
    free = np.setdiff1d(np.arange(m.n_dofs), fixed)
    ia = m.n_dofs - 3

    def dense(ab):
        n = ab.shape[1]
        K = np.zeros((n, n))
        for j in range(n):
            for i in range(max(0, j - 8), min(n, j + 9)):
                K[i, j] = ab[16 + i - j, j]
        return K

    q = np.zeros(m.n_dofs)
    q_old = q.copy()
    for step in range(1, 11):
        # secant predictor (as the tracing loop's), the prescribed tip displacement exact
        q, q_old = 2.0 * q - q_old, q.copy()
        q[ia] = step * 1.0  # mm
        norms = []
        for _ in range(30):
            r, ab = m._assemble(q, frame, contact)
            norms.append(np.linalg.norm(r[free]))
            if norms[-1] < 1e-10 * norms[0]:  # the round-off floor is ~1e-11 of the first
                break
            K = dense(ab)
            q[free] += np.linalg.solve(K[np.ix_(free, free)], -r[free])
        assert norms[-1] < 1e-10 * norms[0], (step, norms)
    assert contact.pairs(m.reference_nodes_mm + q.reshape(-1, 3)[:, :2])  # in contact
    # the last step's convergence: each error about the square of the previous one (relative to
    # the first), e.g. 1e-3 -> 1e-5 -> 1e-10; a tangent missing a term would converge linearly
    e = np.array(norms) / norms[0]
    assert e.size >= 4
    assert np.log(e[-1]) / np.log(e[-2]) > 1.8
    assert np.all(e[2:] < 100.0 * e[1:-1] ** 2)


def test_bad_stops_are_refused_with_the_fix():
    with pytest.raises(FeaError, match="overlaps the undeformed beam by 0.1 mm"):
        solve_with_stops(model(), DRIVE, [RigidStop.point((50.0, -(T / 2 - 0.1)), "pin")])
    with pytest.raises(FeaError, match="closed outline needs at least 3"):
        RigidStop([[0, 0], [1, 1]], closed=True)
    with pytest.raises(FeaError, match="repeated"):
        RigidStop.segment((0, 0), (0, 0))
    with pytest.raises(FeaError, match="penalty_factor"):
        ContactSettings(penalty_factor=0.0)
    # touching is fine: the stop carries force from the first step on
    res = solve_with_stops(model(), DRIVE, [RigidStop.point((50.0, -T / 2))])
    assert res.ok and res.contact.initial_gap_mm[0] == pytest.approx(0.0, abs=1e-12)
    assert res.contact.in_contact[1:, 0].all() and not res.contact.in_contact[0, 0]


def elastica_over_corner(P, V):
    """Inextensible cantilever (clamped at the origin along x) under a dead tip force P (N)
    down, bent over a rigid corner V (2,) mm that touches its lower surface at an unknown arc
    length s_c, where the frictionless contact force R acts along the beam's normal
    nu = (-sin th_c, cos th_c) (th_c the section angle there): two spans in sigma in [0, 1]
    (s = sigma s_c, s = s_c + sigma (L - s_c)), states (x, y, theta, kappa) of each, parameters
    (s_c, R, th_c); EI kappa' = F_x sin theta - F_y cos theta with F the load beyond s:
    (0, -P) + R nu on the first span, (0, -P) on the second. Conditions: clamped, x, y, theta,
    kappa continuous at s_c, moment-free tip, theta(s_c) = th_c and the lower surface on the
    corner, x(s_c) = V + t/2 nu. Started from a straight beam pointing at the corner."""

    def f(sig, y, p):
        sc, R, thc = p
        nu = np.array([-np.sin(thc), np.cos(thc)])
        out = []
        for j, F, ds in ((0, (R * nu[0], R * nu[1] - P), sc), (4, (0.0, -P), L - sc)):
            th, k = y[j + 2], y[j + 3]
            out += [ds * np.cos(th), ds * np.sin(th), ds * k]
            out.append(ds * (F[0] * np.sin(th) - F[1] * np.cos(th)) / EI)
        return np.vstack(out)

    def bc(a, b, p):
        sc, R, thc = p
        xc = V + (T / 2) * np.array([-np.sin(thc), np.cos(thc)])
        return np.array(
            [a[0], a[1], a[2], b[0] - a[4], b[1] - a[5], b[2] - a[6], b[3] - a[7], b[7]]
            + [b[2] - thc, b[0] - xc[0], b[1] - xc[1]]
        )

    ang, sc = np.arctan2(V[1], V[0]), np.hypot(*V)
    sig = np.linspace(0.0, 1.0, 201)
    s1, s2, z = sig * sc, sc + sig * (L - sc), np.zeros_like(sig)
    y = np.vstack([s1 * np.cos(ang), s1 * np.sin(ang), z + ang, z])
    y = np.vstack([y, s2 * np.cos(ang), s2 * np.sin(ang), z + ang, z])
    sol = solve_bvp(f, bc, sig, y, p=[sc, P, ang], tol=1e-10, max_nodes=200000)
    assert sol.status == 0, sol.message
    return sol


def test_large_deflection_over_a_ledge_corner_against_the_elastica():
    """A cantilever bent down over the corner of a rigid block (a ledge under its middle) by a
    large tip load (8 EI/L^2, tip rotation 58 degrees): the corner presses on the beam between
    nodes and the contact point slides along the beam as the load grows. Exact answer: one
    contact point at the corner (the elastica stays above the ledge's top face, checked)."""
    V = np.array([60.0, -20.0])
    ledge = RigidStop.polygon([[20, -40], [60, -40], V, [20, -20]], "ledge")
    P = 8.0 * EI / L**2
    drive = EndDrive("force", (0.0, -1.0), P, steps=12, rotation="free", transverse="free")
    res = solve_with_stops(model(n=30), drive, [ledge])
    assert res.ok, res.message
    c = res.contact
    sol = elastica_over_corner(P, V)
    sc, R, thc = sol.p
    # t / L = 1/200: axial and shear compliance (absent in the elastica) ~1e-5 of the answers
    assert c.force_N[-1, 0] == pytest.approx(R, rel=1e-4)
    np.testing.assert_allclose(
        c.force_vector_N[-1, 0], R * np.array([-np.sin(thc), np.cos(thc)]), rtol=1e-3, atol=1e-4 * R
    )
    np.testing.assert_allclose(res.shapes_mm[-1, -1], sol.y[4:6, -1], atol=2e-3)
    assert res.end_rotation_rad[-1] == pytest.approx(sol.y[6, -1], abs=1e-4)
    np.testing.assert_allclose(c.point_mm[-1, 0], V, atol=1e-12)
    # the exact answer touches the ledge at its corner only: the first span stays above the top
    # face (y > -20 + t/2 where x in [20, 60)) and the second span is past the block (x > 60)
    x1, y1 = sol.sol(np.linspace(0.0, 0.999, 400))[:2]
    top = (x1 >= 20.0) & (x1 < 60.0)
    assert np.all(y1[top] > V[1] + T / 2)
    assert np.all(sol.y[4] >= V[0] - 1e-9)
    # clear at the start, in contact at the end, within the penetration tolerance
    assert c.rows_in_contact[-1] and not c.rows_in_contact[0] and c.penetration_ok


@pytest.mark.parametrize(
    "stop",
    [
        RigidStop.point((50.0, 0.0), "pin"),  # on a vertex node
        RigidStop.point((52.5, 0.0), "pin"),  # between two nodes
        RigidStop.segment((52.5, 0.0), (52.5, -5.0), "pin"),  # a wall's end
        RigidStop.point((0.0, 0.0), "pin"),  # the clamped end
    ],
)
def test_a_stop_corner_exactly_on_the_centreline_is_refused_by_name(stop):
    """A point or corner at distance 0 from the undeformed centreline (no normal there: it used
    to divide by zero and give a NaN gap the overlap check let through) overlaps the beam by
    t/2, and the solve refuses it by name."""
    import warnings

    m = model()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no division by zero on the way
        contact = BeamContact(m, [stop])
        _, gap, _, _ = contact.state(m.reference_nodes_mm)
        assert gap[0] == pytest.approx(-T / 2, abs=1e-12)
        with pytest.raises(FeaError, match="stop 'pin' overlaps the undeformed beam by 0.25 mm"):
            solve_with_stops(m, DRIVE, [stop])
