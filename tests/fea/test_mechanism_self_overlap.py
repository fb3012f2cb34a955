"""A beam's overlap with itself (fea/mechanism_design.py ``self_overlap``, the mechanism kind's
interference check of a beam against itself) against the exact answer of pure bending:

a straight cantilever whose free end is turned by phi (rotation control, its translation free:
a pure end moment, N = V = 0) is bent into a circle of radius R = L / phi exactly. Below a full
turn the band (thickness t) does not meet itself: the overlap is 0 (the two end faces are
radial, (2 pi - phi) R apart along the circle); beyond a full turn the band lies on itself over
the angle phi - 2 pi of an annulus of radii R +- t/2, whose area is exactly (phi - 2 pi) R t.
The pairs within ``default_skip_mm`` of arc length (the self contact's rule) are left out, so
the gently curved parts of the beam never count.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.body_contact import default_skip_mm
from flexopt.fea.materials import Material
from flexopt.fea.mechanism import (
    LoadCase,
    Mechanism,
    MechBeam,
    MechDrive,
    MechJoint,
    solve_mechanism,
)
from flexopt.fea.mechanism_design import INTERFERENCE_MM2, self_overlap

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
L, T, W = 20.0, 0.4, 2.0  # mm


def _curled(elements: int, phi_max: float, steps: int):
    beam = MechBeam("b", np.array([[0.0, 0.0], [L, 0.0]]), np.full(2, T), W, elements)
    mech = Mechanism((beam,), (), (MechJoint("b.start", "ground"),), MAT)
    case = LoadCase("curl", MechDrive("b.end", "rotation", phi_max, steps, transverse="free"))
    res = solve_mechanism(mech, case, ())
    assert res.converged.all(), res.message
    return res


@pytest.fixture(scope="module")
def curled():
    return _curled(60, 2.3 * np.pi, 12)  # no row at exactly one turn


def _overlap(res):
    model = res.beam_models[0]
    return self_overlap(
        res.shapes_mm[0], res.thickness_at_nodes_mm[0], model.s_nodes, default_skip_mm(model)
    )


def test_a_beam_curled_past_a_full_turn_overlaps_itself_by_the_annulus(curled):
    area, where = _overlap(curled)
    phi = np.asarray(curled.drive, dtype=float)  # rad, the end's turn
    exact = np.maximum(phi - 2.0 * np.pi, 0.0) * (L / np.maximum(phi, 1e-300)) * T
    below = phi < 2.0 * np.pi
    assert below.sum() >= 10 and (~below).sum() >= 2
    # below a full turn: nothing (the gently curved beam: no false alarm), not even round-off
    assert np.all(area[below] == 0.0)
    assert np.all(np.isnan(where[below]))
    # beyond: the annulus' area; the chords of the P2 nodes (~0.17 mm on R ~ 2.7 mm) cost
    # ~(h / R)^2 / 12 of it
    np.testing.assert_allclose(area[~below], exact[~below], rtol=2e-3)
    assert np.all(area[~below] > 100 * INTERFERENCE_MM2)
    # where: two parts one full circle (2 pi R) apart along the beam
    r = L / phi[~below]
    gap = where[~below, 1] - where[~below, 0]
    h = np.diff(curled.beam_models[0].s_nodes).max()
    assert np.all(np.abs(gap - 2.0 * np.pi * r) <= 2.0 * h + 1e-9)


def test_the_overlap_converges_under_refinement():
    """The error against (phi - 2 pi) R t at phi = 2.4 pi falls by 3x or more from 30 to 60
    elements (the chord error, second order in the node spacing)."""
    errors = []
    for n in (30, 60):
        res = _curled(n, 2.4 * np.pi, 6)
        area, _ = _overlap(res)
        errors.append(abs(area[-1] - 0.4 * np.pi * (L / (2.4 * np.pi)) * T))
    assert errors[1] < errors[0] / 3


def test_the_skip_leaves_the_neighbouring_parts_out():
    """A hairpin bent tighter than the skip (a radius of t / 2: the inner edges meet) is not
    compared with itself within ``skip_mm``; with no skip its neighbouring segments do meet."""
    s = np.linspace(0.0, np.pi * 0.3, 31)  # a half turn of radius 0.3 mm, t = 0.6 mm
    pts = np.stack([0.3 * np.cos(s / 0.3), 0.3 * np.sin(s / 0.3)], axis=1)[None]
    t = np.full(31, 0.6)
    area, _ = self_overlap(pts, t, s, np.pi * 0.6)
    assert area[0] == 0.0  # the whole hairpin lies within pi t of arc length
    area, _ = self_overlap(pts, t, s, 0.0)
    assert area[0] > 0.0
