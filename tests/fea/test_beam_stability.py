"""Stability detection of the beam solver against Euler loads computed here.

A straight strut pushed along its axis stays straight in the solver (nothing in a perfect beam
breaks the symmetry), past its Euler load and onto the unstable branch. The solver must say so:
the tangent with the supports and the prescribed DOFs eliminated stops being positive definite at
the Euler load, and every row from there on is flagged (``BeamResponse.stable``). The critical
loads are the classic ones for a slender strut (t/L = 1/50; shear lowers them by P / kGA at most,
Engesser: 3e-4 for the cantilever, 4e-3 for the clamped-clamped strut, allowed for where it
matters):

* cantilever (clamped, end free to move and turn), force control: P = pi^2 EI / (4 L^2);
* clamped start, end sliding along the axis with its rotation and transverse motion held
  (clamped-clamped): P = 4 pi^2 EI / L^2;
* clamped start, end rotation held but free to sway (guided): P = pi^2 EI / L^2.

A straight strut is uniformly compressed, N = EA Gamma1 with Gamma1 = -d / L for an end
shortening d, so under displacement control the critical shortening is d = P L / EA.
"""

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive, _is_positive_definite, solve_beam
from flexopt.fea.materials import Material
from flexopt.geometry.profile import BeamProfile

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
L, T, B = 50.0, 1.0, 8.0  # mm
EI = MAT.E_MPa * B * T**3 / 12.0  # N mm^2
EA = MAT.E_MPa * B * T  # N
P_CANTILEVER = np.pi**2 * EI / (4.0 * L**2)  # N
P_CLAMPED = 4.0 * np.pi**2 * EI / L**2  # N
P_SWAY = np.pi**2 * EI / L**2  # N
SETTINGS = BeamSettings(n_elements=10)


def straight(length=L, t=T, b=B):
    return BeamProfile([[0.0, 0.0], [length, 0.0]], [t, t], b)


def axial_state(model: BeamModel, force_N: float, frame: np.ndarray) -> np.ndarray:
    """(n_dofs,) generalised DOFs of the straight strut under axial compression ``force_N``:
    u_x(s) = -force s / EA (exact for the model: uniform strain, no bending). The end node's
    translations are generalised ones, in the drive's ``frame`` (rows: direction, normal)."""
    q = np.zeros(model.n_dofs)
    q[0::3] = -force_N * model.s_nodes / EA
    q[-3:-1] = frame @ q[-3:-1]
    return q


def dense_reduced(ab: np.ndarray, free: np.ndarray) -> np.ndarray:
    """The (n_free, n_free) reduced tangent from LAPACK gbsv band storage (kl = ku = 8)."""
    n = ab.shape[1]
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    inside = np.abs(i - j) <= 8
    A = np.zeros((n, n))
    A[inside] = ab[16 + i[inside] - j[inside], j[inside]]
    return A[np.ix_(free, free)]


# ---- _is_positive_definite ---------------------------------------------------------------------


@pytest.mark.parametrize(
    "drive, p_cr",
    [
        (EndDrive("force", (-1.0, 0.0), 1.0, 1, "free", "free"), P_CANTILEVER),
        (EndDrive("displacement", (-1.0, 0.0), 1.0, 1, "fixed", "fixed"), P_CLAMPED),
        (EndDrive("displacement", (-1.0, 0.0), 1.0, 1, "fixed", "free"), P_SWAY),
    ],
    ids=["cantilever", "clamped-clamped", "guided-sway"],
)
def test_positive_definite_below_and_not_past_the_euler_load(drive, p_cr):
    model = BeamModel(straight(), MAT, "clamped", SETTINGS)
    frame = model._frame(drive)
    bc = model._constraints(drive)
    for ratio, expected in [(0.0, True), (0.5, True), (0.95, True), (1.05, False), (1.5, False)]:
        _, ab = model._assemble(axial_state(model, ratio * p_cr, frame), frame)
        # independent check of the band layout: the smallest eigenvalue of the dense reduced
        # tangent changes sign at the Euler load
        lowest = np.linalg.eigvalsh(dense_reduced(ab, bc.free))[0]
        assert (lowest > 0) == expected, (ratio, lowest)
        assert _is_positive_definite(ab, bc) is expected, ratio
        assert ab.flags.f_contiguous  # the check copies: the tangent is left as it was


def test_positive_definite_does_not_touch_the_tangent():
    model = BeamModel(straight(), MAT, "clamped", SETTINGS)
    drive = EndDrive("force", (-1.0, 0.0), 1.0, 1, "free", "free")
    _, ab = model._assemble(np.zeros(model.n_dofs), model._frame(drive))
    before = ab.copy()
    assert _is_positive_definite(ab, model._constraints(drive))
    np.testing.assert_array_equal(ab, before)


def test_a_pinned_strut_swings_about_its_pin_under_any_compression():
    # pinned start, end free to move across and turn: at rest the beam can swing about the pin
    # (zero stiffness, a mechanism); any compression makes that rigid rotation lower the energy
    model = BeamModel(straight(), MAT, "pinned", SETTINGS)
    drive = EndDrive("force", (-1.0, 0.0), 1.0, 1, "free", "free")
    frame = model._frame(drive)
    _, ab = model._assemble(axial_state(model, 1e-3 * P_CANTILEVER, frame), frame)
    assert not _is_positive_definite(ab, model._constraints(drive))


# ---- the traced path ---------------------------------------------------------------------------


def test_cantilever_pushed_35_times_past_its_euler_load_is_flagged():
    # the case: an ABS cantilever 60 x 1.5 x 8 mm pushed with 100 N (~36 x Euler)
    length, t, b = 60.0, 1.5, 8.0
    E = 1800.0
    p_cr = np.pi**2 * E * b * t**3 / 12.0 / (4.0 * length**2)
    assert 100.0 > 30 * p_cr
    res = solve_beam(
        straight(length, t, b),
        Material("abs", E, 0.35, 42.5),
        EndDrive("force", (-1.0, 0.0), 100.0, 20, "free", "free"),
        settings=SETTINGS,
    )
    assert res.ok and res.converged.all()  # it converges, on the straight (unstable) branch
    assert res.unstable
    assert res.stable[0] and not res.stable[1:].any()
    assert res.critical_value == pytest.approx(p_cr, rel=2e-3)
    assert "step 1" in res.unstable_message and "unstable" in res.unstable_message


def test_force_control_flags_exactly_the_rows_past_the_euler_load():
    steps = 10
    p_cr = P_CANTILEVER
    res = solve_beam(
        straight(),
        MAT,
        EndDrive("force", (-1.0, 0.0), 1.5 * p_cr, steps, "free", "free"),
        settings=SETTINGS,
    )
    assert res.ok and res.unstable
    np.testing.assert_array_equal(res.stable, res.force_N < p_cr)
    # the crossing is bracketed to min_critical_substep (1e-3) of a step; shear lowers P by 3e-4
    assert res.critical_value == pytest.approx(p_cr, abs=2e-3 * 1.5 * p_cr / steps + 1e-3 * p_cr)
    first = int(np.argmin(res.stable))
    assert f"step {first}" in res.unstable_message


@pytest.mark.parametrize(
    "transverse, p_cr",
    [("fixed", P_CLAMPED), ("free", P_SWAY)],
    ids=["clamped-clamped", "guided-sway"],
)
def test_guided_strip_driven_axially_past_its_euler_load_is_flagged(transverse, p_cr):
    d_cr = p_cr * L / EA  # mm, end shortening at the Euler load
    steps = 10
    res = solve_beam(
        straight(),
        MAT,
        EndDrive("displacement", (-1.0, 0.0), 3.0 * d_cr, steps, "fixed", transverse),
        settings=SETTINGS,
    )
    assert res.ok and res.unstable
    # the straight strut carries EA d / L, three times what it can: the flag is what says so
    assert res.force_N[-1] == pytest.approx(3.0 * p_cr, rel=1e-6)
    np.testing.assert_array_equal(res.stable, res.displacement_mm < d_cr)
    # Shear lowers the critical load of the (Reissner) strut, at most to Engesser's
    # P / (1 + P / kGA) (0.4 % here for clamped-clamped); the crossing is bracketed to 1e-3 of a
    # step
    kga = 5.0 / 6.0 * MAT.G_MPa * B * T
    lower = p_cr / (1.0 + p_cr / kga) * L / EA
    assert lower * (1 - 1e-3) <= res.critical_value <= d_cr * (1 + 1e-3)


def test_a_guided_strip_below_its_euler_load_is_not_flagged():
    d_cr = P_CLAMPED * L / EA
    res = solve_beam(
        straight(),
        MAT,
        EndDrive("displacement", (-1.0, 0.0), 0.9 * d_cr, 5, "fixed", "fixed"),
        settings=SETTINGS,
    )
    assert res.ok and not res.unstable and res.stable.all()
    assert res.unstable_message == "" and np.isnan(res.critical_value)


def test_a_bowed_strip_follows_its_stable_buckled_branch_under_displacement_control():
    # a shallow arc (rise 0.05 mm over 50 mm) driven 15 x its straight critical shortening: the
    # imperfection selects the buckled branch, which is stable with the drive prescribed, and the
    # force levels off just below the Euler load of the perfect strip
    rise = 0.05
    radius = (L**2 / 4.0 + rise**2) / (2.0 * rise)
    profile = BeamProfile([[0.0, 0.0], [L, 0.0]], [T, T], B, curvature_per_mm=[-1.0 / radius])
    d_cr = P_CLAMPED * L / EA
    res = solve_beam(
        profile,
        MAT,
        EndDrive("displacement", (-1.0, 0.0), 15.0 * d_cr, 10, "fixed", "fixed"),
        settings=BeamSettings(n_elements=20),
    )
    assert res.ok and not res.unstable and res.stable.all()
    assert res.force_N[-1] == pytest.approx(P_CLAMPED, rel=0.02)
    assert res.force_N[-1] < P_CLAMPED


@pytest.mark.parametrize("control, value", [("force", 20.0 * P_CANTILEVER), ("displacement", 30.0)])
def test_a_laterally_loaded_cantilever_is_not_flagged(control, value):
    # ordinary (large) bending: the tip goes far sideways, nothing buckles
    res = solve_beam(
        straight(),
        MAT,
        EndDrive(control, (0.0, 1.0), value, 10, "free", "free"),
        settings=SETTINGS,
    )
    assert res.ok and not res.unstable and res.stable.all()
    assert res.displacement_mm[-1] > 0.5 * L


# ---- the study level ---------------------------------------------------------------------------


def _push_study(tmp_path, max_N: float):
    from flexopt.pipeline.study import load_study

    path = tmp_path / "push.yaml"
    path.write_text(
        f"""name: push
geometry:
  kind: polyline_beam
  points_mm: [[0, 0], [{L}, 0]]
  thickness_mm: [{T}, {T}]
  width_mm: {B}
  elements: 10
material: {{name: test, E_MPa: {MAT.E_MPa}, nu: {MAT.nu}, yield_MPa: {MAT.yield_MPa}}}
boundary:
  start: clamped
  end: {{control: force, direction: [-1, 0], max_N: {max_N}, steps: 10, rotation: free,
        transverse: free}}
"""
    )
    return load_study(path)


def test_polyline_beam_study_reports_a_buckled_strut_as_unstable(tmp_path):
    from flexopt.pipeline.studies.polyline_beam import evaluate

    result = evaluate(_push_study(tmp_path, 3.0 * P_CANTILEVER))
    s = result.summary
    assert result.converged  # every row is an equilibrium ...
    assert s["stable"] is False  # ... but not a stable one
    assert s["unstable_rows"] == int(np.sum(result.table["force_N"] > P_CANTILEVER))
    assert s["first_unstable_step"] == 4  # row k carries 0.3 k P_cr: 1.2 P_cr at row 4
    assert s["unstable_message"].startswith("unstable: passed a bifurcation")
    assert s["unstable_message"] in result.message


def test_polyline_beam_study_below_the_euler_load_is_stable(tmp_path):
    from flexopt.pipeline.studies.polyline_beam import evaluate

    result = evaluate(_push_study(tmp_path, 0.9 * P_CANTILEVER))
    assert result.summary["stable"] is True and result.summary["unstable_rows"] == 0
    assert result.summary["unstable_message"] == "" and result.message == ""
