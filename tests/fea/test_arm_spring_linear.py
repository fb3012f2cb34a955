"""Linear curved-arm spring theory (fea.closed_forms.arm_spring_linear) against exact beam
results, and the plane-stress model of spiral springs against it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.closed_forms import arm_spring_linear
from flexopt.fea.materials import get_material
from flexopt.geometry.arm_spring import arm_centreline, build_arm_spring, spiral_params
from flexopt.geometry.sea_spring import SpringFrame

E, B = 190_000.0, 10.0  # MPa, mm


def test_straight_radial_spoke_matches_the_beam_stiffness_matrix():
    # A spoke from (a, 0) to (b, 0), clamped at b; the hub end moves by v = a theta and turns by
    # theta. The cantilever stiffness matrix gives F = EI/L^3 (12 v + 6 L theta) and
    # M = EI/L^3 (6 L v + 4 L^2 theta), so T / theta = EI/L^3 (4 L^2 + 12 L a + 12 a^2) per spoke.
    a, b, w, n = 9.0, 30.0, 2.0, 3
    L = b - a
    EI = E * B * w**3 / 12.0
    xy = np.column_stack([np.linspace(a, b, 2001), np.zeros(2001)])
    lin = arm_spring_linear(xy, np.full(2001, w), E, B, n)
    exact = n * EI / L**3 * (4 * L**2 + 12 * L * a + 12 * a**2)
    assert lin.stiffness_Nmm_per_rad == pytest.approx(exact, rel=1e-6)
    fx, fy, m = lin.end_load_per_rad
    assert fx == pytest.approx(0.0, abs=1e-9 * abs(fy))
    assert fy == pytest.approx(EI / L**3 * (12 * a + 6 * L), rel=1e-6)
    assert m == pytest.approx(EI / L**3 * (6 * L * a + 4 * L**2), rel=1e-6)


def test_full_circle_arm_carries_a_pure_uniform_moment():
    # A closed circular arm concentric with the axis has its elastic centre on the axis: no end
    # force, a uniform moment EI theta / (2 pi R), stiffness n EI / (2 pi R).
    R, w, n = 20.0, 1.5, 2
    phi = np.linspace(0.0, 2 * np.pi, 4001)
    xy = R * np.column_stack([np.cos(phi), np.sin(phi)])
    lin = arm_spring_linear(xy, np.full(phi.size, w), E, B, n)
    EI = E * B * w**3 / 12.0
    assert lin.stiffness_Nmm_per_rad == pytest.approx(n * EI / (2 * np.pi * R), rel=1e-6)
    assert np.allclose(lin.moment_Nmm_per_rad, EI / (2 * np.pi * R), rtol=1e-6)
    assert np.abs(lin.end_load_per_rad[:2]).max() < 1e-6 * EI / R**2


def _free_arm(p, frame):
    """The part of the centreline that is a free beam: off the hub (band clear of the rim) and
    outside the pad boss."""
    xy, w = arm_centreline(p, 0.2)
    off_hub = np.hypot(*xy.T) - 0.5 * w >= frame.hub_radius_mm
    off_pad = np.hypot(*(xy - xy[-1]).T) >= frame.pad_radius_mm
    keep = off_hub & off_pad
    return xy[keep], w[keep]


@pytest.mark.parametrize("w", [1.0, 1.5])
def test_plane_stress_spiral_converges_to_the_slender_arm_theory(w):
    # Plane stress (linear, 1 degree) of an Archimedean three-arm spiral with sharp roots against
    # the linear arm theory over the free length. The difference is the root and pad junctions
    # (a slender-beam effect of order w / L): within 2 % at w/L ~ 1 %, and decreasing with w.
    from flexopt.fea.spring_analysis import SpringMesh, analyse_spring

    frame = SpringFrame()
    mat = get_material("maraging-300")
    v = dict(sweep=300.0, R_pad=30.0, F1=1 / 3, F2=0.5, W1=w, W2=w, W3=w, W4=w, ST=B)
    p = spiral_params(v, 3, frame, root_fillet_mm=0.0)
    r = analyse_spring(build_arm_spring(p, frame), mat, math.radians(1.0), SpringMesh(),
                       nonlinear=False)  # fmt: skip
    xy, ww = _free_arm(p, frame)
    lin = arm_spring_linear(xy, ww, mat.E_MPa, B, 3)
    ratio = r.linear_stiffness_Nm_per_rad / (lin.stiffness_Nmm_per_rad * 1e-3)
    assert abs(ratio - 1.0) < 0.02, ratio
