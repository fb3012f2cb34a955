"""The geometrically exact beam against exact solutions computed here.

Exact references: the inextensible elastica by elliptic integrals (scipy.special) for the
cantilever and the fixed-guided beam, and ``scipy.integrate.solve_bvp`` on the same Reissner
equations for a tapered and a circular-arc beam. The beams are slender (t/L = 1/200 or less) where
the model is compared with the inextensible, unshearable elastica, so that axial and shear
compliance (which the elastica ignores) stay below 1e-4 of the compared quantity.
"""

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive, solve_beam
from flexopt.fea.materials import Material
from flexopt.geometry.profile import BeamProfile
from scipy.integrate import solve_bvp
from scipy.optimize import brentq
from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)


def straight(L=100.0, t=0.5, b=2.0):
    return BeamProfile([[0.0, 0.0], [L, 0.0]], [t, t], b)


def ei_of(t, b, E=MAT.E_MPa):
    return E * b * t**3 / 12.0


def elastica_cantilever(alpha):
    """Inextensible cantilever, dead tip force perpendicular to the axis, alpha = P L^2 / EI.

    EI theta'' = -P cos(theta), theta'(L) = 0; with 1 + sin(theta) = 2 k^2 sin^2(psi):
    sqrt(alpha) = K(k) - F(k, psi1), delta/L = 1 - 2 (E(k) - E(k, psi1)) / sqrt(alpha),
    x/L = sqrt(2 sin(theta_tip) / alpha), sin(psi1) = 1 / (sqrt(2) k). Returns (delta/L, x/L).
    """

    def psi1(k):
        return np.arcsin(1.0 / (np.sqrt(2.0) * k))

    def gap(k):
        m = k * k
        return ellipk(m) - ellipkinc(psi1(k), m) - np.sqrt(alpha)

    k = brentq(gap, 1.0 / np.sqrt(2.0) + 1e-15, 1.0 - 1e-15, xtol=1e-15)
    m = k * k
    delta = 1.0 - 2.0 * (ellipe(m) - ellipeinc(psi1(k), m)) / np.sqrt(alpha)
    sin_tip = 2.0 * m - 1.0
    return delta, np.sqrt(2.0 * sin_tip / alpha)


@pytest.mark.slow
@pytest.mark.parametrize("alpha", [0.25, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0])
def test_cantilever_tip_force_matches_elastica_with_20_elements(alpha):
    L, t, b = 100.0, 0.25, 2.0
    P = alpha * ei_of(t, b) / L**2
    res = solve_beam(
        straight(L, t, b),
        MAT,
        EndDrive("force", (0.0, 1.0), P, steps=20, rotation="free", transverse="free"),
        settings=BeamSettings(n_elements=20),
    )
    assert res.ok, res.message
    delta, x_tip = elastica_cantilever(alpha)
    assert res.displacement_mm[-1] / L == pytest.approx(delta, rel=5e-4)
    # transverse axis is direction turned +90 deg = -x: end x = L - transverse displacement
    assert (L - res.transverse_displacement_mm[-1]) / L == pytest.approx(x_tip, rel=5e-4)
    assert res.force_N[-1] == pytest.approx(P, rel=1e-6)


def test_fixed_guided_reaction_matches_elastica_at_80_percent():
    """Clamped; the other end keeps its rotation, slides axially, is pushed to d/L = 0.8.

    By symmetry the beam is two cantilevers of length L/2 meeting at an inflection point, each
    carrying the end force P and deflecting d/2, so P (L/2)^2 / EI solves delta(alpha) = 0.8.
    """
    L, t, b = 100.0, 0.25, 2.0
    alpha_half = brentq(lambda a: elastica_cantilever(a)[0] - 0.8, 0.1, 50.0, xtol=1e-14)
    P_exact = alpha_half * ei_of(t, b) / (L / 2) ** 2
    res = solve_beam(
        straight(L, t, b),
        MAT,
        EndDrive(
            "displacement", (0.0, 1.0), 0.8 * L, steps=20, rotation="fixed", transverse="free"
        ),
        settings=BeamSettings(n_elements=20),
    )
    assert res.ok, res.message
    assert res.displacement_mm[-1] == pytest.approx(0.8 * L)
    assert res.force_N[-1] == pytest.approx(P_exact, rel=1e-3)
    # about 80 degrees of rotation inside the beam: the inflection point's tangent angle
    mid = res.shapes_mm[-1][res.shapes_mm.shape[1] // 2 - 1 : res.shapes_mm.shape[1] // 2 + 2]
    angle = np.degrees(np.arctan2(*(mid[2] - mid[0])[::-1]))
    assert 70 < angle < 90


def test_mesh_refinement_converges_at_fourth_order():
    """P2 elements with the 2-point rule: nodal displacements converge as h^4 (superconvergent)."""
    L, t, b = 100.0, 0.5, 2.0
    P = 3.0 * ei_of(t, b) / L**2
    drive = EndDrive("force", (0.0, 1.0), P, steps=10, rotation="free", transverse="free")

    def tip(n):
        return solve_beam(straight(L, t, b), MAT, drive, settings=BeamSettings(n)).displacement_mm[
            -1
        ]

    ref = tip(256)
    errors = np.array([abs(tip(n) - ref) for n in (2, 4, 8)])
    rates = np.log2(errors[:-1] / errors[1:])
    assert np.all(rates > 3.5), rates


def test_tangent_equals_finite_difference_tangent():
    profile = BeamProfile(
        [[0.0, 0.0], [60.0, 30.0], [100.0, 0.0]],
        [1.0, 2.0, 1.5],
        3.0,
        curvature_per_mm=[0.01, -0.005],
    )
    model = BeamModel(profile, MAT, settings=BeamSettings(n_elements=5))
    rng = np.random.default_rng(1)
    q = rng.normal(size=model.n_dofs) * 0.2
    frame = np.array([[0.6, 0.8], [-0.8, 0.6]])
    r, ab = model._assemble(q, frame)
    n, band = model.n_dofs, 8
    K = np.zeros((n, n))
    for j in range(n):
        i = np.arange(max(0, j - band), min(n, j + band + 1))
        K[i, j] = ab[2 * band + i - j, j]
    eps = 1e-6
    K_fd = np.empty_like(K)
    for j in range(n):
        dq = np.zeros(n)
        dq[j] = eps
        K_fd[:, j] = (model._assemble(q + dq, frame)[0] - model._assemble(q - dq, frame)[0]) / (
            2 * eps
        )
    assert np.abs(K - K_fd).max() <= 1e-6 * np.abs(K).max()
    # band storage must hold every coupling: the full finite-difference tangent is banded
    far = np.abs(np.subtract.outer(np.arange(n), np.arange(n))) > band
    assert np.abs(K_fd[far]).max() <= 1e-9 * np.abs(K).max()


def _continued_bvp(profile, force, n=10):
    """Clamped (at s = 0) Reissner beam under a dead end force ``force`` (2,), N, by solve_bvp.

    Unknowns (x, y, theta, M) over s in [0, L]; N, Q are the components of the constant internal
    force F in the section frame, strains N/EA and Q/kGA, x' = R(theta) (1 + g1, g2),
    M' = -(x' x F), theta' = theta0'(s) + M / EI(s), M(L) = 0. Continued in load, because one
    solve from the undeformed guess may not converge. Returns the end position (2,), mm.
    """
    s_pts = profile.arc_length_mm
    L = profile.length_mm
    b, E, G = profile.width_mm, MAT.E_MPa, MAT.G_MPa
    kap = profile.curvature_per_mm
    theta_start = profile.segment_start_angles_rad()[0]

    def make_rhs(F):
        def rhs(s, y):
            t = np.interp(s, s_pts, profile.thickness_mm)
            seg = np.clip(np.searchsorted(s_pts, s, side="right") - 1, 0, len(kap) - 1)
            c, sn = np.cos(y[2]), np.sin(y[2])
            N = F[0] * c + F[1] * sn
            Q = -F[0] * sn + F[1] * c
            g1 = N / (E * b * t)
            g2 = Q / (5.0 / 6.0 * G * b * t)
            dx = (1 + g1) * c - g2 * sn
            dy = (1 + g1) * sn + g2 * c
            return np.vstack(
                [dx, dy, kap[seg] + y[3] / (E * b * t**3 / 12), -(dx * F[1] - dy * F[0])]
            )

        return rhs

    def bc(ya, yb):
        return np.array([ya[0], ya[1], ya[2] - theta_start, yb[3]])

    s = np.linspace(0, L, 801)
    # undeformed shape as the first guess
    y = np.zeros((4, s.size))
    y[2] = theta_start + np.cumsum(
        np.r_[0, np.diff(s)]
        * kap[np.clip(np.searchsorted(s_pts, s, side="right") - 1, 0, len(kap) - 1)]
    )
    y[0] = np.r_[0, np.cumsum(np.diff(s) * np.cos(y[2][:-1]))]
    y[1] = np.r_[0, np.cumsum(np.diff(s) * np.sin(y[2][:-1]))]
    for lam in np.linspace(1.0 / n, 1.0, n):
        sol = solve_bvp(make_rhs(lam * np.asarray(force)), bc, s, y, tol=1e-9, max_nodes=500000)
        assert sol.success, sol.message
        s, y = sol.x, sol.y
    return sol.sol(L)[:2]


def test_tapered_beam_matches_solve_bvp():
    L, b = 120.0, 3.0
    profile = BeamProfile([[0.0, 0.0], [L, 0.0]], [2.0, 0.6], b)
    F = np.array([-0.05, 0.2])  # N: a tip force pulling back and up; large rotation
    res = solve_beam(
        profile,
        MAT,
        EndDrive(
            "force",
            tuple(F / np.hypot(*F)),
            np.hypot(*F),
            steps=10,
            rotation="free",
            transverse="free",
        ),
        settings=BeamSettings(n_elements=40),
    )
    assert res.ok, res.message
    end = res.shapes_mm[-1][-1]
    exact = _continued_bvp(profile, F)
    assert np.degrees(res.end_rotation_rad[-1]) > 45  # genuinely nonlinear
    assert np.allclose(end, exact, rtol=0, atol=1e-4 * L)


def test_circular_arc_beam_matches_solve_bvp():
    R = 40.0
    kappa = 1.0 / R
    # quarter circle from (0, 0) heading +x, turning left, as 3 exact arc segments
    ang = np.linspace(0.0, np.pi / 2, 4)
    pts = np.stack([R * np.sin(ang), R * (1 - np.cos(ang))], axis=1)
    profile = BeamProfile(pts, [1.0] * 4, 2.0, curvature_per_mm=[kappa] * 3)
    assert profile.length_mm == pytest.approx(np.pi * R / 2)
    F = np.array([0.3, -0.2])  # opens the arc
    res = solve_beam(
        profile,
        MAT,
        EndDrive(
            "force",
            tuple(F / np.hypot(*F)),
            np.hypot(*F),
            steps=10,
            rotation="free",
            transverse="free",
        ),
        settings=BeamSettings(n_elements=30),
    )
    assert res.ok, res.message
    exact = _continued_bvp(profile, F)
    assert np.linalg.norm(exact - pts[-1]) > 10  # large displacement
    assert np.allclose(res.shapes_mm[-1][-1], exact, rtol=0, atol=1e-4 * profile.length_mm)


def test_axial_bar_force_is_exact_and_signed_along_direction():
    """Uniform stretch is exact in the Reissner model: N = EA d / L, along ``direction``."""
    L, t, b = 50.0, 2.0, 3.0
    for direction, d in (((1.0, 0.0), 0.5), ((-1.0, 0.0), -0.5)):
        res = solve_beam(straight(L, t, b), MAT, EndDrive("displacement", direction, d, steps=2))
        assert res.ok
        # pulling the bar (stretch of +0.5 mm) needs a force along +x
        expected = MAT.E_MPa * b * t * 0.5 / L
        assert res.force_N[-1] * np.sign(direction[0]) == pytest.approx(expected, rel=1e-9)
        assert res.peak_stress_MPa[-1] == pytest.approx(MAT.E_MPa * 0.5 / L, rel=1e-9)


def test_force_and_displacement_control_agree():
    L, t, b = 80.0, 0.8, 2.0
    P = 2.0 * ei_of(t, b) / L**2
    common = dict(rotation="free", transverse="free")
    by_force = solve_beam(straight(L, t, b), MAT, EndDrive("force", (0.0, 1.0), P, 8, **common))
    d = by_force.displacement_mm[-1]
    by_disp = solve_beam(
        straight(L, t, b), MAT, EndDrive("displacement", (0.0, 1.0), d, 8, **common)
    )
    assert by_force.ok and by_disp.ok
    assert by_disp.force_N[-1] == pytest.approx(P, rel=1e-7)
    assert by_disp.end_rotation_rad[-1] == pytest.approx(by_force.end_rotation_rad[-1], rel=1e-7)


def test_root_stress_of_a_lightly_loaded_cantilever():
    L, t, b = 100.0, 1.0, 4.0
    P = 1e-3 * ei_of(t, b) / L**2  # linear range
    res = solve_beam(
        straight(L, t, b),
        MAT,
        EndDrive("force", (0.0, 1.0), P, 1, rotation="free", transverse="free"),
    )
    assert res.peak_stress_s_mm[-1] == pytest.approx(0.0, abs=1e-12)
    assert res.peak_stress_MPa[-1] == pytest.approx(6 * P * L / (b * t**2), rel=1e-4)


def test_postbuckled_pinned_column_follows_the_elastica_on_the_imperfection_side():
    """Pinned-pinned column with a tiny initial bow, shortened by 20 % under displacement control.

    Exact perfect-column elastica: end shortening Delta/L = 2 (1 - E(k)/K(k)) and
    P / P_E = (2 K(k) / pi)^2 with P_E = pi^2 EI / L^2. The bow of L/5000 changes P by < 0.5 %.
    The column must buckle towards its bow (the physical branch) at every step: positive curvature
    turns left walking from start to end, so this bow lies at -y.
    """
    L, t, b = 100.0, 0.5, 2.0
    sagitta = L / 5000.0
    R = (L**2 / 4 + sagitta**2) / (2 * sagitta)
    profile = BeamProfile([[0.0, 0.0], [L, 0.0]], [t, t], b, curvature_per_mm=[1.0 / R])
    res = solve_beam(
        profile,
        MAT,
        EndDrive("displacement", (-1.0, 0.0), 0.2 * L, 20, rotation="free", transverse="fixed"),
        start="pinned",
        settings=BeamSettings(n_elements=30),
    )
    assert res.ok, res.message
    mid = res.shapes_mm[:, res.shapes_mm.shape[1] // 2, 1]
    assert mid[0] == pytest.approx(-sagitta)
    assert np.all(mid[1:] < mid[0])
    m = brentq(lambda m: 2 * (1 - ellipe(m) / ellipk(m)) - 0.2, 1e-9, 0.999)
    P_exact = (2 * ellipk(m) / np.pi) ** 2 * np.pi**2 * ei_of(t, b) / L**2
    assert res.force_N[-1] == pytest.approx(P_exact, rel=5e-3)


def test_a_mechanism_is_reported_as_data_not_raised():
    """Pinned start, free end rotation and transverse motion: rigid rotation is a mechanism."""
    res = solve_beam(
        straight(),
        MAT,
        EndDrive("force", (0.0, 1.0), 1.0, 4, rotation="free", transverse="free"),
        start="pinned",
    )
    assert not res.ok
    assert "singular" in res.message
    assert res.converged[0] and not res.converged[-1]
    assert np.isnan(res.force_N[-1])


@pytest.mark.parametrize("n", [20, 50, 100])
def test_displacement_controlled_thin_cantilever_force_on_fine_meshes(n):
    """Tip displacement driven to 0.6 L, tip free to rotate and slide: the force converges to the
    elastica at every mesh (regression: the Newton force scale once mixed in the driven mm)."""
    L, t, b = 100.0, 0.1, 5.0
    ei = ei_of(t, b)
    delta = 0.6
    alpha = brentq(lambda a: elastica_cantilever(a)[0] - delta, 0.1, 50.0, xtol=1e-14)
    res = solve_beam(
        straight(L, t, b),
        MAT,
        EndDrive("displacement", (0.0, 1.0), delta * L, 20, rotation="free", transverse="free"),
        settings=BeamSettings(n_elements=n),
    )
    assert res.ok, res.message
    assert res.force_N[-1] == pytest.approx(alpha * ei / L**2, rel=1e-4)


def test_root_stress_at_large_deflection_matches_the_elastica_moment():
    """Tip force P perpendicular to the undeformed axis, alpha = 10 (82 deg at the tip): the root
    carries no axial force and the moment P x_tip, so the peak stress is 6 P x_tip / (b t^2)."""
    L, t, b, alpha = 100.0, 0.5, 4.0, 10.0
    P = alpha * ei_of(t, b) / L**2
    res = solve_beam(
        straight(L, t, b),
        MAT,
        EndDrive("force", (0.0, 1.0), P, 20, rotation="free", transverse="free"),
        settings=BeamSettings(20),
    )
    _, x_tip = elastica_cantilever(alpha)
    assert res.peak_stress_s_mm[-1] == pytest.approx(0.0, abs=1e-9)
    assert res.peak_stress_MPa[-1] == pytest.approx(6 * P * x_tip * L / (b * t**2), rel=1e-3)
