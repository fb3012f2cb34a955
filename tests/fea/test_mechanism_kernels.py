"""The mechanism engine's compiled Newton (fea/_mechanism_kernels.py) against its reference.

``MechanismSettings.kernel`` = "numba" runs the Newton loop compiled (the KKT system by bordering
the beams' band); "numpy" is the reference (scipy sparse matrices and SuperLU every iteration).
They make the same decisions, so every row, flag and output agrees to round-off: here to 1e-9 of
each quantity's scale, on a snap-through, a bifurcating arch, a rotating lever (the nonlinear rows
and their Hessian), a force-controlled path up to its limit point (applied loads) and a system the
bordering cannot take (a beam no local row holds: the reference runs those sub-steps).
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea import mechanism as fm
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

kern = fm._kernels()
pytestmark = pytest.mark.skipif(kern is None, reason="numba is not available")

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0, density_kg_m3=1200.0)
W = 5.0  # mm


def _straight(name: str, a, b, t: float, elements: int = 12) -> MechBeam:
    return MechBeam(name, np.array([a, b], dtype=float), np.array([t, t]), W, elements)


def _arch() -> Mechanism:
    """A shallow sine arch cut at its apex and clamped to a shuttle there (bistable)."""
    S, h, t = 60.0, 2.0, 0.3
    x = np.linspace(0.0, S, 41)
    pts = np.stack([x, h * np.sin(np.pi * x / S)], axis=1)
    left = MechBeam("left", pts[:21], np.full(21, t), W, 16)
    right = MechBeam("right", pts[20:], np.full(21, t), W, 16)
    shuttle = MechBody("shuttle", np.array([S / 2, h + 1.0]))  # ref off the beams on purpose
    joints = (
        MechJoint("left.start", "ground", "pinned"),
        MechJoint("right.end", "ground", "pinned"),
        MechJoint("left.end", "shuttle"),
        MechJoint("right.start", "shuttle"),
    )
    return Mechanism((left, right), (shuttle,), joints, MAT)


def _lever() -> Mechanism:
    """A rigid arm pinned to the ground at (0, 0) and turned by a spring leaf pinned to it at
    (8, 0), whose far end is clamped to the ground: the arm's rotation enters the rows."""
    arm = MechBody("arm", np.array([0.0, 0.0]))
    spring = _straight("spring", (8.0, 0.0), (-22.0, 0.0), 0.6)
    joints = (
        MechJoint("arm", "ground", "pinned"),
        MechJoint("spring.start", "arm@8,0", "pinned"),
        MechJoint("spring.end", "ground"),
    )
    return Mechanism((spring,), (arm,), joints, MAT)


def _bridge() -> Mechanism:
    """Two cantilevers and a beam bridging their tips, numbered last: the bridge's ties are
    beam-end-to-beam-end rows far apart in the numbering (not local), so the bordering finds
    its band block singular and hands every sub-step to the reference."""
    a = _straight("a", (0.0, 0.0), (0.0, 20.0), 0.8, 8)
    c = _straight("c", (30.0, 0.0), (30.0, 20.0), 0.8, 8)
    b = _straight("b", (0.0, 20.0), (30.0, 20.0), 0.8, 8)
    joints = (
        MechJoint("a.start", "ground"),
        MechJoint("c.start", "ground"),
        MechJoint("b.start", "a.end"),
        MechJoint("b.end", "c.end", "pinned"),
    )
    return Mechanism((a, c, b), (), joints, MAT)


CASES = {
    "snap-through": (
        _arch(),
        LoadCase("s", MechDrive("shuttle", "displacement", 5.0, 10, (0, -1), "held", "held")),
        [
            MechOutput("F", "reaction"),
            MechOutput("Rx", "reaction_force", "left.start", (1, 0)),
            MechOutput("s", "peak_stress"),
        ],
    ),
    "bifurcation": (
        _arch(),
        LoadCase("s", MechDrive("shuttle", "displacement", 5.0, 10, (0, -1), "held", "free")),
        [MechOutput("F", "reaction"), MechOutput("s", "peak_stress", "left")],
    ),
    "lever": (
        _lever(),
        LoadCase("l", MechDrive("arm@-10,0", "displacement", 8.0, 6, (0, 1))),
        [
            MechOutput("F", "reaction"),
            MechOutput("pivot", "reaction_force", "arm", (0, 1)),
            MechOutput("out", "displacement", "arm@8,0", (0, 1)),
            MechOutput("turn", "rotation", "arm"),
        ],
    ),
    "force-to-the-limit": (
        _arch(),  # the guided path's peak force is about 0.050 N: the stiffness falls to ~0
        LoadCase("f", MechDrive("shuttle", "force", -0.0495, 8, (0, 1), "held", "held")),
        [MechOutput("d", "displacement", "shuttle", (0, -1)), MechOutput("s", "peak_stress")],
    ),
    "bridge (reference sub-steps)": (
        _bridge(),
        LoadCase("b", MechDrive("b.end", "displacement", 3.0, 3, (1, 0))),
        [MechOutput("F", "reaction"), MechOutput("M", "reaction_moment", "a.start")],
    ),
}


def _close(a: np.ndarray, b: np.ndarray, what: str) -> None:
    """a == b to 1e-9 of a's scale (its largest finite magnitude), NaN where a is NaN."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert a.shape == b.shape, what
    np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=what)
    ok = np.isfinite(a)
    scale = float(np.abs(a[ok]).max(initial=0.0))
    assert scale > 0.0, f"{what}: nothing to compare"
    err = float(np.abs(a[ok] - b[ok]).max(initial=0.0))
    assert err <= 1e-9 * scale, f"{what}: differs by {err:.3g} (scale {scale:.3g})"


def _solve(name: str, kernel: str, monkeypatch) -> tuple[fm.MechanismResponse, list[int]]:
    """Solve a case on one path; the compiled Newton's status codes, in call order."""
    mech, case, outs = CASES[name]
    statuses: list[int] = []
    compiled = kern.newton

    def newton(*args):
        out = compiled(*args)
        statuses.append(int(out[0]))
        return out

    with monkeypatch.context() as mp:
        mp.setattr(kern, "newton", newton)
        resp = solve_mechanism(mech, case, outs, MechanismSettings(kernel=kernel))
    return resp, statuses


@pytest.mark.parametrize("name", list(CASES))
def test_compiled_newton_agrees_with_the_reference(name: str, monkeypatch) -> None:
    ref, none = _solve(name, "numpy", monkeypatch)
    fast, statuses = _solve(name, "numba", monkeypatch)
    assert none == [] and statuses, "each path must run its own Newton"
    if name.startswith("bridge"):
        assert set(statuses) == {kern.FALLBACK}
    else:
        assert kern.FALLBACK not in statuses
    np.testing.assert_array_equal(fast.converged, ref.converged)
    np.testing.assert_array_equal(fast.stable, ref.stable)
    np.testing.assert_array_equal(fast.stable_released, ref.stable_released)
    assert fast.ok == ref.ok and fast.message == ref.message
    step = abs(ref.drive[1] - ref.drive[0])
    if np.isnan(ref.critical_drive):
        assert np.isnan(fast.critical_drive)
    else:
        assert abs(fast.critical_drive - ref.critical_drive) <= 1e-9 * step
    for key in ref.outputs:
        _close(ref.outputs[key], fast.outputs[key], key)
    _close(ref.peak_stress_MPa, fast.peak_stress_MPa, "peak stress")
    for i, (sa, sb) in enumerate(zip(ref.shapes_mm, fast.shapes_mm, strict=True)):
        _close(sa - sa[0], sb - sb[0], f"displacements of beam {i}")
    if ref.body_poses.size:
        _close(ref.body_poses - ref.body_poses[0], fast.body_poses - fast.body_poses[0], "bodies")


def test_the_cases_exercise_what_they_claim(monkeypatch) -> None:
    """The cases above are not trivial: the arch snaps (the guided reaction changes sign, the
    released path is unstable somewhere), the free arch bifurcates, the lever turns by more than
    0.3 rad and the force-controlled path softens towards its limit point."""
    snap, _ = _solve("snap-through", "numba", monkeypatch)
    assert snap.ok and snap.outputs["F"].min() < 0.0 < snap.outputs["F"].max()
    assert not snap.stable_released.all()
    free, _ = _solve("bifurcation", "numba", monkeypatch)
    assert np.isfinite(free.critical_drive)
    lever, _ = _solve("lever", "numba", monkeypatch)
    assert lever.ok and abs(lever.outputs["turn"][-1]) > 0.3
    force, _ = _solve("force-to-the-limit", "numba", monkeypatch)
    d = force.outputs["d"]
    assert force.ok and d[-1] - d[-2] > 3.0 * (d[1] - d[0])  # softening towards the limit
