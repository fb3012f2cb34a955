"""The buckling mode at a lost stability and the imperfect mechanism built on it
(fea.mechanism: ``critical_mode``, :func:`imperfect_mechanism`, :func:`first_unstable_row`).

References computed here: the first buckling mode of a clamped-clamped column,
w = (1 - cos 2 pi y / L) / 2; the clamped-clamped elastica (four quarter cantilevers) for the
post-buckled load; and the imperfection sensitivity of a clamped arch whose guided path
bifurcates: the imperfect peak lies below the force at the bifurcation and tends to it as the
imperfection vanishes.
"""

from __future__ import annotations

from dataclasses import replace as replace_beam
from dataclasses import replace as replace_response

import numpy as np
import pytest
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
    first_unstable_row,
    imperfect_mechanism,
    solve_mechanism,
)
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0, density_kg_m3=1200.0)
W = 5.0  # mm


def _strut(L: float, t: float) -> Mechanism:
    strut = MechBeam("strut", np.array([[0.0, 0.0], [0.0, L]]), np.array([t, t]), W, 20)
    return Mechanism((strut,), (), (MechJoint("strut.start", "ground"),), MAT)


def test_the_mode_of_a_strut_past_euler_is_the_clamped_clamped_mode_and_its_branch_is_stable():
    L, t = 50.0, 0.5
    mech = _strut(L, t)
    ei, ea, kga = MAT.E_MPa * W * t**3 / 12, MAT.E_MPa * W * t, 5 / 6 * MAT.G_MPa * W * t
    d_cr = 4 * np.pi**2 * ei / L**2 * L / ea
    case = LoadCase(
        "c", MechDrive("strut.end", "displacement", 0.1 * L, 5, (0, -1), "held", "held")
    )
    perfect = solve_mechanism(mech, case, [MechOutput("P", "reaction")])
    assert first_unstable_row(perfect) == 1  # straight past Euler: flagged from row 1
    nodes = perfect.reference_nodes_mm[0]
    mode = perfect.critical_mode[0]
    exact = 0.5 * (1.0 - np.cos(2.0 * np.pi * nodes[:, 1] / L))
    # the mode is lateral (x). It is taken at the first state past the critical point (the
    # crossing is bracketed to 1e-3 of a row step: here ~6 % past Euler), where the lowest
    # eigenvalue is slightly negative, not zero: the shape is the buckling mode to ~0.5 %
    np.testing.assert_allclose(np.abs(mode[:, 0]), exact, atol=4e-3)
    assert np.abs(mode[:, 1]).max() < 1e-2
    # the imperfect strut (1e-5 L along the mode) buckles onto the post-buckled branch: stable,
    # and its load is the elastica's (an initial bow a0 lowers it by ~a0 / deflection: 1e-4)
    imperfect = imperfect_mechanism(mech, perfect, 1e-5 * L)
    resp = solve_mechanism(imperfect, case, [MechOutput("P", "reaction")])
    assert resp.ok and resp.stable.all() and first_unstable_row(resp) is None, resp.message
    for d, P in zip(resp.drive[2:], resp.outputs["P"][2:], strict=True):
        bent = d - P * L / ea
        m = brentq(lambda m, bent=bent: 2 * L * (1 - ellipe(m) / ellipk(m)) - bent, 1e-12, 0.9)
        p_ref = 16 * ei * ellipk(m) ** 2 / L**2 / ((1 + P / kga) * (1 - P / ea))
        assert P == pytest.approx(p_ref, rel=3e-4)
    assert resp.drive[1] > d_cr  # (row 1 is past Euler already)


def _guided_arch() -> tuple[Mechanism, LoadCase]:
    """A cosine-shaped clamped-clamped arch (rise 4 mm, 0.3 mm thick, 60 mm span) cut at its
    apex and clamped to a shuttle pushed down guided (rotation and sideways motion held), as the
    bistable-switch example: its path bifurcates before the symmetric force peak."""
    S, h, t = 60.0, 4.0, 0.3
    x = np.linspace(0.0, S, 41)
    pts = np.stack([x, 0.5 * h * (1.0 - np.cos(2.0 * np.pi * x / S))], axis=1)
    left = MechBeam("left", pts[:21], np.full(21, t), W, 20)
    right = MechBeam("right", pts[20:], np.full(21, t), W, 20)
    shuttle = MechBody("shuttle", np.array([S / 2, h]), np.array([[29, 4], [31, 4], [31, 6]]))
    joints = (
        MechJoint("left.start", "ground"),
        MechJoint("right.end", "ground"),
        MechJoint("left.end", "shuttle"),
        MechJoint("right.start", "shuttle"),
    )
    case = LoadCase("snap", MechDrive("shuttle", "displacement", 2.0, 40, (0, -1), "held", "held"))
    return Mechanism((left, right), (shuttle,), joints, MAT), case


def test_an_imperfect_arch_snaps_below_its_bifurcation_and_tends_to_it():
    mech, case = _guided_arch()
    out = [MechOutput("F", "reaction")]
    perfect = solve_mechanism(mech, case, out)
    row = first_unstable_row(perfect)
    assert row is not None and perfect.critical_mode is not None
    # the perfect path's force where it bifurcates (the rows bracket it; the force is smooth)
    F = perfect.outputs["F"]
    f_cr = float(np.interp(perfect.critical_drive, perfect.drive, F))
    assert np.nanmax(F) > 1.2 * f_cr  # the unstable path's peak would overstate the snap by 30 %
    peaks, curves = [], []
    for a in (1e-6, 1e-5, 1e-3, 3e-2):
        resp = solve_mechanism(imperfect_mechanism(mech, perfect, a), case, out)
        assert resp.ok and resp.stable.all(), resp.message
        curves.append(resp.outputs["F"])
        peaks.append(float(np.nanmax(resp.outputs["F"])))
    # the larger the imperfection, the lower the snap; never above the bifurcation's force
    assert peaks[0] >= peaks[1] > peaks[2] > peaks[3]
    assert peaks[0] <= f_cr * (1 + 1e-3)
    # as the imperfection vanishes the part follows the perfect path up to the bifurcation
    # (rows before it agree) and the bifurcated branch after it (the curves converge: 1e-5 and
    # 1e-6 differ by < 1e-4 of the force), whose peak is the bifurcation's force: between the
    # forces of the rows that bracket it
    np.testing.assert_allclose(curves[0][:row], F[:row], rtol=1e-4, atol=1e-9)
    np.testing.assert_allclose(curves[1], curves[0], rtol=0, atol=1e-4 * f_cr)
    assert F[row - 1] <= peaks[0]
    # with no imperfection the rebuilt mechanism (drawn through the FE nodes) is the same one
    same = solve_mechanism(imperfect_mechanism(mech, perfect, 0.0), case, out)
    np.testing.assert_allclose(same.outputs["F"][:row], F[:row], rtol=2e-3, atol=1e-6)


def test_no_mode_without_an_instability():
    mech, case = _guided_arch()
    short = LoadCase("g", MechDrive("shuttle", "displacement", 0.2, 2, (0, -1), "held", "held"))
    resp = solve_mechanism(mech, short, [])
    assert first_unstable_row(resp) is None and resp.critical_mode is None
    with pytest.raises(FeaError, match="no buckling mode"):
        imperfect_mechanism(mech, resp, 0.01)
    del case


def _flared_arch() -> tuple[Mechanism, LoadCase]:
    """The guided arch with each grounded end flared (twice as thick at the ground, tapering to
    the beam's thickness over the first segment) and that segment as its root: the beam's
    largest stress near the ground is at the flare's toe, not at the end section."""
    mech, case = _guided_arch()
    left, right = mech.beams
    flare = float(np.hypot(*(left.points_mm[1] - left.points_mm[0])))  # mm, one segment
    t_left = np.asarray(left.thickness_mm, dtype=float).copy()
    t_right = np.asarray(right.thickness_mm, dtype=float).copy()
    t_left[0] *= 2.0
    t_right[-1] *= 2.0
    beams = (
        replace_beam(left, thickness_mm=t_left, root_mm=(flare, 0.0)),
        replace_beam(right, thickness_mm=t_right, root_mm=(0.0, flare)),
    )
    return Mechanism(beams, mech.bodies, mech.joints, MAT), case


def test_the_imperfect_mechanism_keeps_the_roots_so_it_is_judged_as_the_drawn_one():
    # the verdict's as-made stress multiplies each root's K_t with the largest stress within
    # the beam's root_mm (the flare): a copy that dropped root_mm would be judged at the end
    # section alone, which here is 4x stiffer in bending and far below the toe's stress
    mech, case = _flared_arch()
    out = [MechOutput("F", "reaction")]
    perfect = solve_mechanism(mech, case, out)
    row = first_unstable_row(perfect) or len(perfect.drive)
    assert row > 5 and perfect.converged[:row].all()
    # no imperfection: the copy is the drawn part redrawn through its FE nodes, whatever the
    # mode (the flared arch need not bifurcate for that)
    zero_mode = tuple(np.zeros_like(n) for n in perfect.reference_nodes_mm)
    same = imperfect_mechanism(
        mech,
        replace_response(perfect, critical_mode=zero_mode, critical_body_mode=np.zeros((1, 3))),
        0.0,
    )
    for drawn, copy in zip(mech.beams, same.beams, strict=True):
        assert copy.root_mm == drawn.root_mm and copy.width_mm == drawn.width_mm
        assert copy.name == drawn.name and copy.curvature_per_mm is None
    resp = solve_mechanism(same, case, out)
    assert resp.beam_roots_mm == perfect.beam_roots_mm
    roots, roots_ref = resp.root_stress_MPa[1:row], perfect.root_stress_MPa[1:row]
    # the grounded roots (left start, right end) agree with the drawn part's to the copy's mesh
    # (drawn through the FE nodes, 2 elements per drawn one): within 3 % of the largest, the
    # error largest where the root's moment changes sign and the flare's peak moves along it
    grounded = roots_ref[:, [0, 1], [0, 1]]
    scale = float(grounded.max())
    np.testing.assert_allclose(roots[:, [0, 1], [0, 1]], grounded, rtol=0, atol=0.03 * scale)
    # the end sections' stresses (root_mm 0, what a copy without its roots was judged by) are
    # far from it: the tolerance above tells the two apart
    ends = solve_mechanism(
        Mechanism(
            tuple(replace_beam(b, root_mm=(0.0, 0.0)) for b in mech.beams),
            mech.bodies,
            mech.joints,
            MAT,
        ),
        case,
        out,
    ).root_stress_MPa[1:row][:, [0, 1], [0, 1]]
    assert np.max(np.abs(grounded - ends)) > 0.5 * scale
    # the judged root stress is the largest beam stress within root_mm of the end: never above
    # the beam's peak
    assert np.all(roots.max(axis=2) <= resp.peak_stress_MPa[1:row] * (1 + 1e-12))


def test_an_imperfect_curved_beam_keeps_its_arcs():
    # a quarter circle (radius 20 mm) drawn as two exact arcs: the copy with no imperfection
    # lies on the same circle between its FE nodes (each piece keeps its drawn arc)
    R, L = 20.0, 5.0
    th = np.array([0.0, np.pi / 4, np.pi / 2])
    pts = np.stack([R * np.sin(th), R * (1 - np.cos(th))], axis=1)
    beam = MechBeam("arc", pts, np.full(3, 0.5), W, 6, np.full(2, 1.0 / R), (0.5, 0.0))
    mech = Mechanism((beam,), (), (MechJoint("arc.start", "ground"),), MAT)
    case = LoadCase("c", MechDrive("arc.end", "displacement", L, 10, (-1, 0), "held", "held"))
    resp = solve_mechanism(mech, case, [MechOutput("P", "reaction")])
    nodes = resp.reference_nodes_mm[0]
    np.testing.assert_allclose(np.hypot(nodes[:, 0], nodes[:, 1] - R), R, rtol=1e-12)
    fake = replace_response(
        resp, critical_mode=(np.zeros_like(nodes),), critical_body_mode=np.zeros((0, 3))
    )
    copy = imperfect_mechanism(mech, fake, 0.0).beams[0]
    np.testing.assert_allclose(copy.curvature_per_mm, 1.0 / R, rtol=1e-12)
    assert copy.root_mm == (0.5, 0.0)
    again = solve_mechanism(Mechanism((copy,), (), mech.joints, MAT), case, [])
    # the copy's nodes (its mesh halves each element) are on the same circle
    np.testing.assert_allclose(
        np.hypot(again.reference_nodes_mm[0][:, 0], again.reference_nodes_mm[0][:, 1] - R),
        R,
        rtol=1e-9,
    )
