"""Exact sensitivities of the mechanism engine (fea/mechanism_sensitivity.py) against central
finite differences of the full nonlinear solve, computed here (issue 27, item 1).

Reference: the fourth-order stencil ``(8 (f(h) - f(-h)) - (f(2h) - f(-2h))) / 12h`` of
:func:`fea.mechanism.solve_mechanism` re-traced per perturbed design at ``rtol = 1e-12``.
Error: |exact - FD| over the largest |FD| of that response and variable along the path.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.beam_sensitivity import ks_aggregate
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import get_material
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
from flexopt.fea.mechanism_sensitivity import mechanism_sensitivities

PA12 = get_material("PA12")
TIGHT = MechanismSettings(rtol=1e-12)
OUTPUTS = (
    MechOutput("F", "reaction"),
    MechOutput("rot", "rotation", "shuttle"),
    MechOutput("sx", "displacement", "shuttle", (1.0, 0.0)),
    MechOutput("Fg", "reaction_force", "upper.start", (0.0, 1.0)),
    MechOutput("Mg", "reaction_moment", "lower.start"),
)


def guide(x: np.ndarray, elements: int = 12) -> Mechanism:
    """Two leaves 20 mm apart clamped to the ground and to a shuttle; x = (thickness mm,
    leaf length mm: moves the leaves' ends and the shuttle's reference point, width mm)."""
    t, length, b = x
    beams = tuple(
        MechBeam(n, np.array([[0.0, y], [length, y]]), np.array([t, 0.8 * t]), b, elements)
        for n, y in (("upper", 10.0), ("lower", -10.0))
    )
    bodies = (MechBody("shuttle", np.array([length + 4.0, 0.0])),)
    joints = (
        MechJoint("upper.start", "ground"),
        MechJoint("lower.start", "ground"),
        MechJoint("upper.end", "shuttle"),
        MechJoint("lower.end", "shuttle"),
    )
    return Mechanism(beams, bodies, joints, PA12)


CASE = LoadCase("stroke", MechDrive("shuttle", "displacement", 6.0, 6, (0.0, 1.0)))
X = np.array([1.6, 36.0, 8.0])


def fd(fun, x: np.ndarray, i: int, h: float):
    """Fourth-order central difference of fun (x -> array) along variable i."""

    def at(s: float):
        xs = x.copy()
        xs[i] += s * h
        return np.asarray(fun(xs), dtype=float)

    return (8.0 * (at(1) - at(-1)) - (at(2) - at(-2))) / (12.0 * h)


def rel(exact: np.ndarray, ref: np.ndarray) -> float:
    return float(np.abs(exact - ref).max() / np.abs(ref).max())


@pytest.fixture(scope="module")
def guide_sens():
    return mechanism_sensitivities(guide, X, CASE, OUTPUTS)


@pytest.mark.parametrize(("i", "h"), [(0, 1e-3), (1, 1e-2)])
def test_guide_outputs_against_central_differences(guide_sens, i, h):
    """Thickness and leaf length (which also moves the shuttle's reference point, i.e. the
    nonlinear constraint rows' offsets): every output, each beam's peak stress and the
    shuttle's pose within 1e-6 of the FD of the re-traced path (measured: <= 2.4e-10 at
    these steps; benchmarks/mechanism_gradient.py has the step study)."""
    sens = guide_sens
    solved: dict[float, object] = {}

    def resp(xs):
        key = float(xs[i])
        if key not in solved:
            solved[key] = solve_mechanism(guide(xs), CASE, OUTPUTS, TIGHT)
        return solved[key]

    for name in ("F", "rot", "sx", "Fg", "Mg"):
        ref = fd(lambda xs, n=name: resp(xs).outputs[n], X, i, h)
        assert rel(sens.derivatives[name][:, i], ref) < 1e-6, name
    ref = fd(lambda xs: resp(xs).peak_stress_MPa, X, i, h)
    assert rel(sens.derivatives["peak_stress_MPa"][..., i], ref) < 1e-6
    ref = fd(lambda xs: resp(xs).body_poses, X, i, h)
    assert rel(sens.derivatives["body_poses"][..., i], ref) < 1e-6
    assert sens.force_mismatch < 1e-8


def test_width_scales_forces_only(guide_sens):
    """Every stiffness is proportional to the width: at a fixed drive the state does not move,
    the forces scale (dF/db = F/b) and the stresses do not change."""
    sens, b = guide_sens, X[2]
    for name in ("F", "Fg", "Mg"):
        v = sens.values[name]
        assert np.abs(sens.derivatives[name][:, 2] - v / b).max() <= 1e-9 * np.abs(v).max()
    assert np.abs(sens.dz[..., 2]).max() < 1e-12
    assert np.abs(sens.derivatives["fibre_MPa"][..., 2]).max() < 1e-8


def test_ks_aggregate_bounds_convergence_and_derivative(guide_sens):
    """KS over the path of the signed fibre stresses: max <= KS <= max + ln(n)/rho for every
    rho, the gap to the max falling to 0 as rho grows; the max of the signed values is the
    solver's peak; dKS/dt against the FD of the KS of polished perturbed paths."""
    sens = guide_sens
    values = sens.values["fibre_MPa"]
    peak = sens.values["peak_stress_MPa"].max()
    assert values.max() == pytest.approx(peak, rel=1e-12)
    gaps = []
    for rho in (0.01, 0.1, 1.0, 10.0, 100.0):
        ks, _ = ks_aggregate(values.ravel(), rho)
        assert peak - 1e-9 <= ks <= peak + np.log(values.size) / rho + 1e-9
        gaps.append(ks - peak)
    assert all(a > b for a, b in zip(gaps, gaps[1:], strict=False))
    assert gaps[-1] < 0.05  # MPa
    h = 1e-3

    def ks_of(xs):
        s = mechanism_sensitivities(guide, xs, CASE, OUTPUTS, TIGHT, rho=sens.rho)
        return s.ks_MPa

    ref = fd(ks_of, X, 0, h)
    assert abs(sens.d_ks[0] - ref) < 1e-6 * abs(ref)


def test_mesh_change_refused():
    """A beam whose element count follows its length cannot be stepped at a fixed state."""

    def varying(x):
        return guide(x, elements=int(round(x[1] / 3.0)))

    with pytest.raises(FeaError, match="mesh changes"):
        mechanism_sensitivities(varying, np.array([1.6, 37.5, 8.0]), CASE, OUTPUTS)


def arch(x: np.ndarray) -> Mechanism:
    """A snap-through arch: two inclined, initially curved leaves (a 3 mm rise over 28 mm)
    clamped to the ground and to a shuttle pushed down through them; x = (thickness mm, rise
    mm)."""
    t, rise = x
    s = np.linspace(0.0, 1.0, 9)
    y = rise * 0.5 * (1.0 - np.cos(np.pi * s))
    left = np.column_stack([28.0 * s, y])
    right = np.column_stack([60.0 - 28.0 * s, y])
    thick = np.full(9, t)
    beams = (MechBeam("left", left, thick, 10.0, 16), MechBeam("right", right, thick, 10.0, 16))
    bodies = (MechBody("shuttle", np.array([30.0, rise])),)
    joints = (
        MechJoint("left.start", "ground"),
        MechJoint("right.start", "ground"),
        MechJoint("left.end", "shuttle"),
        MechJoint("right.end", "shuttle"),
    )
    return Mechanism(beams, bodies, joints, get_material("PETG"))


ARCH_CASE = LoadCase(
    "snap",
    MechDrive("shuttle", "displacement", 6.0, 24, (0.0, -1.0), "held", "held"),
)
ARCH_OUT = (MechOutput("F", "reaction"),)


def test_snap_rows_near_the_limit_point():
    """The arch's force passes a maximum (the limit point under force control) and turns
    negative (snap-through); under displacement control the rows around the maximum are
    regular KKT points. Rows before, at and after the force maximum and after the zero
    crossing: dF/dt and dF/d(rise) within 1e-6 of the FD of the re-traced path (measured:
    1.5e-10, 1.2e-10)."""
    x = np.array([1.0, 3.0])
    base = solve_mechanism(arch(x), ARCH_CASE, ARCH_OUT, TIGHT)
    assert base.ok
    force = base.outputs["F"]
    k = int(np.argmax(force))
    assert 0 < k < force.size - 1  # the maximum inside the stroke
    crossing = k + int(np.flatnonzero(force[k:] < -1e-3 * force[k])[0])  # the snap: F < 0
    rows = [k - 1, k, k + 1, crossing + 1]
    # the rows straddle the loss of stability (an asymmetric mode past the maximum's row):
    # the stable ones factorise a definite reduced tangent, the unstable ones an indefinite one
    assert base.stable[k - 1] and not base.stable[k + 1]
    sens = mechanism_sensitivities(arch, x, ARCH_CASE, ARCH_OUT, response=base, rows=rows)
    for i, h in ((0, 1e-3), (1, 1e-3)):
        ref = fd(
            lambda xs: solve_mechanism(arch(xs), ARCH_CASE, ARCH_OUT, TIGHT).outputs["F"][rows],
            x,
            i,
            h,
        )
        assert rel(sens.derivatives["F"][:, i], ref) < 1e-6, i
