"""The check of a mechanism's outline in plane stress and 3D (fea/mechanism_fidelity.py).

References computed here: a guided leaf (clamped to a ground pad, its other end in a rigid
shuttle) whose analysed length is its printed length: plane stress agrees with the Timoshenko
beam (the model difference: ~(t/L)^2 and the clamps' local flexibility); with nu = 0 the 3D
solid equals plane stress (nothing restrains the Poisson contraction, docs/solid3d.md); with
nu = 0.3 a deep leaf is stiffer in 3D by what docs/solid3d.md's strip measured; the figures
converge under mesh refinement.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.materials import Material
from flexopt.fea.mechanism import LoadCase, Mechanism, MechBeam, MechBody, MechDrive, MechJoint
from flexopt.fea.mechanism_fidelity import FidelitySettings, mechanism_fidelity_check
from shapely.geometry import box

L, T = 30.0, 1.5  # mm: leaf length and thickness (L / t = 20)


def _leaf(nu: float, width: float, rotation: str = "held"):
    mat = Material("m", E_MPa=2000.0, nu=nu, yield_MPa=50.0, density_kg_m3=1000.0)
    leaf = MechBeam("leaf", np.array([[0.0, 0.0], [L, 0.0]]), np.array([T, T]), width, 20)
    shuttle = MechBody("shuttle", np.array([L + 3.0, 0.0]))
    mech = Mechanism(
        (leaf,), (shuttle,),
        (MechJoint("leaf.start", "ground"), MechJoint("leaf.end", "shuttle")), mat,
    )  # fmt: skip
    case = LoadCase(
        "push", MechDrive("shuttle", "displacement", 1.0, 4, (0.0, 1.0), "free", rotation)
    )
    pad = box(-6.0, -3.0, 0.0, 3.0)  # the ground pad ends where the leaf starts
    body = box(L, -4.0, L + 6.0, 4.0)
    band = box(0.0, -T / 2, L, T / 2)
    outline = pad.union(band).union(body)
    return mech, case, outline, [pad], {"shuttle": body}, [band]


def test_a_leaf_clamped_where_it_is_analysed_agrees_with_the_beam_and_converges():
    mech, case, outline, ground, bodies, bands = _leaf(0.0, 2.0)
    ratios = []
    for n in (1.0, 2.0, 4.0):
        r = mechanism_fidelity_check(mech, case, outline, ground, bodies, bands, 2.0,
                                     FidelitySettings(elements_through=n))  # fmt: skip
        assert "skipped" not in r, r
        assert r["solid"] is None  # 2 mm deep against a 1.5 mm leaf: plane stress is enough
        ratios.append(r["plane_stress_ratio"])
    # the beam (Timoshenko, clamped at the pad face) and plane stress of the same leaf agree
    # to the model difference (0.2 %: the clamp's local flexibility in 2D elasticity); the
    # figure converges, the change per halving dropping ~5x (0.0050, then 0.0010: the roots'
    # singular corners are graded, FidelitySettings.root_refinement)
    assert ratios[-1] == pytest.approx(1.0, abs=5e-3)
    assert abs(ratios[2] - ratios[1]) < 0.3 * abs(ratios[1] - ratios[0])
    assert abs(ratios[2] - ratios[1]) < 2e-3
    # the beam's own figure: 12 EI / L^3 with its shear term
    E, G = 2000.0, 1000.0
    I, A = 2.0 * T**3 / 12.0, 2.0 * T
    k_exact = 1.0 / (L**3 / (12 * E * I) + L / (5 / 6 * G * A))
    assert r["beam_stiffness"] == pytest.approx(k_exact, rel=1e-5)


def test_3d_equals_plane_stress_without_poisson_and_is_stiffer_with_it():
    depth = 5.0 * T  # deep: the 3D check runs by the rule
    mech0, case, outline, ground, bodies, bands = _leaf(0.0, depth)
    r0 = mechanism_fidelity_check(mech0, case, outline, ground, bodies, bands, depth)
    assert r0["solid"] is not None, r0.get("solid_rule")
    # (the P2 tetrahedra of the split prisms and the P2 triangles differ by ~2e-4 here)
    assert r0["solid"][0]["stiffness"] == pytest.approx(r0["plane_stress_stiffness"], rel=5e-4)
    mech3 = _leaf(0.3, depth)[0]
    r3 = mechanism_fidelity_check(mech3, case, outline, ground, bodies, bands, depth)
    ratio = r3["solid"][0]["stiffness"] / r3["plane_stress_stiffness"]
    # docs/solid3d.md, a clamped-guided strip: 1.021 at depth / width 3.2, 1.045 at 6.4
    assert 1.02 < ratio < 1.05
    # two depths from one model: the 3D figure at each, against the beam at that width
    r2 = mechanism_fidelity_check(mech3, case, outline, ground, bodies, bands, [depth, 2 * depth])
    a, b = r2["solid"]
    assert a["stiffness"] == pytest.approx(r3["solid"][0]["stiffness"], rel=1e-9)
    assert b["beam_stiffness"] == pytest.approx(2 * a["beam_stiffness"], rel=1e-9)
    assert b["ratio"] > a["ratio"]  # deeper: more restraint


def test_a_turning_shuttle_and_refusals():
    mech, case, outline, ground, bodies, bands = _leaf(0.0, 2.0, rotation="free")
    free = mechanism_fidelity_check(mech, case, outline, ground, bodies, bands, 2.0)
    held = mechanism_fidelity_check(*_leaf(0.0, 2.0)[:6], 2.0)
    # a cantilever (3 EI / L^3 with the arm) is far softer than a guided leaf (12 EI / L^3)
    assert free["plane_stress_stiffness"] < 0.5 * held["plane_stress_stiffness"]
    assert free["plane_stress_ratio"] == pytest.approx(1.0, abs=0.06)
    force = LoadCase("f", MechDrive("shuttle", "force", 1.0, 2, (0.0, 1.0)))
    r = mechanism_fidelity_check(mech, force, outline, ground, bodies, bands, 2.0)
    assert "force-controlled" in r["skipped"]
