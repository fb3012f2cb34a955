"""The 3D check's lean factorisation (issue 27 item 5; fea/solid3d.py, docs/solid3d.md
"Memory"): the model drops its stiffness parts, reduced-triangle pattern and P2 gradients while
the factor is made and makes them again from the mesh afterwards; K is not held through the
factorisation. The answers must be those of the model that keeps everything, bit for bit
(the same kernels on the same input), at the first thickness, at a PCG thickness and at a
thickness factorised again.

Units: mm, N, MPa, N·mm, rad.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, Rotate
from flexopt.fea.solid3d import Solid3DModel, Solid3DSettings
from shapely.geometry import Point

STEEL = Material("steel", 200_000.0, 0.3, 1000.0)


def _annulus():
    """An annulus (radii 5 and 15 mm) turned at its inner rim, outer rim held: the SEA
    spring's supports, its inner region out of the peak."""
    outline = Point(0.0, 0.0).buffer(15.0, 32).difference(Point(0.0, 0.0).buffer(5.0, 16))
    mesh = mesh_polygon(outline, 2.0)
    clamp = Clamp(outline.exterior)
    drive = Rotate(outline.interiors[0], (0.0, 0.0), 1e-3, 1)
    return mesh, clamp, drive, Point(0.0, 0.0).buffer(6.0)


def _answers(r) -> list:
    return [r.stiffness, r.torque_Nmm, r.peak_stress_MPa, r.peak_nodal_stress_MPa,
            *r.reaction_N, *r.clamp_reaction_N, *r.peak_stress_xyz_mm,
            *r.peak_nodal_stress_xyz_mm, r.iterations]  # fmt: skip


@pytest.mark.parametrize("pcg_max_iterations", [40, 1])
def test_lean_factorisation_gives_the_same_answers_bit_for_bit(pcg_max_iterations):
    """First thickness (factorised), a nearby one (PCG; with 1 iteration allowed: factorised
    again, the lean path a second time) against the model that keeps its arrays."""
    pytest.importorskip("numba")
    mesh, clamp, drive, ignore = _annulus()
    out = {}
    for lean in (True, False):
        settings = Solid3DSettings(layers=2, lean_factorisation=lean,
                                   pcg_max_iterations=pcg_max_iterations)  # fmt: skip
        model = Solid3DModel(mesh, STEEL, clamp, drive, settings, stress_ignore=ignore)
        assert model.assembly == "compiled"
        out[lean] = [_answers(model.solve(t)) for t in (4.0, 4.1, 3.9)]
        # the arrays made again are the ones built with the model
        if lean:
            parts, lower = model._parts.copy(), [a.copy() for a in model._lower]
        else:
            np.testing.assert_array_equal(model._parts, parts)
            for a, b in zip(model._lower, lower, strict=True):
                np.testing.assert_array_equal(a, b)
    assert out[True] == out[False]
    if pcg_max_iterations == 1:
        assert out[True][1][-1] == 0  # factorised again, not PCG


def test_numpy_assembly_keeps_its_arrays_and_the_answers():
    """The numpy reference assembly has no lean path (nothing to make again cheaply); it
    still releases K through the factorisation and gives the compiled path's answers."""
    pytest.importorskip("numba")
    mesh, clamp, drive, ignore = _annulus()
    res = {}
    for assembly in ("compiled", "numpy"):
        settings = Solid3DSettings(layers=2, assembly=assembly)
        model = Solid3DModel(mesh, STEEL, clamp, drive, settings, stress_ignore=ignore)
        res[assembly] = model.solve(4.0)
        if assembly == "numpy":
            assert model._parts is not None and model._G is not None
    a, b = res["compiled"], res["numpy"]
    assert a.stiffness == pytest.approx(b.stiffness, rel=1e-9)
    assert a.peak_nodal_stress_MPa == pytest.approx(b.peak_nodal_stress_MPa, rel=1e-9)
