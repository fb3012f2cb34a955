"""A leaf pivot's sharp roots (pipeline/studies/_pivot_roots.py, #22 class): the exported leaf
meets its blocks in 90° steps whose stress does not converge under refinement, while a
corner-filleted root of the same web does; the verdict of a leaf design is therefore NOT MET
on its peak stress, with the reason, and a filleted design is judged as before."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.materials import get_material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Rotate
from flexopt.geometry.flexures import CornerFilleted, Leaf
from flexopt.optimise.requirements import AllowableStress
from flexopt.pipeline.studies._pivot_roots import SHARP_ROOTS, RootStress

PETG = get_material("PETG")
B, T = 6.0, 2.15  # width and web thickness, mm (the flexure-pivot example's leaf)
TURN = np.radians(2.0)  # rad: small, so the linear solve is the exact small-strain state


def peak_and_torque(flexure, per_thickness: int) -> tuple[float, float]:
    """The linear plane-stress peak nodal von Mises (MPa) over the whole outline (no element left
    out) and the torque (N·mm), the moving block turned ``TURN`` about the nominal centre, with
    ``per_thickness`` elements through the local thickness of the compliant part."""
    fine = T / per_thickness

    def size(xy: np.ndarray) -> np.ndarray:
        local = flexure.local_thickness_mm(xy[:, 0]) / per_thickness
        return np.where(np.isfinite(local), np.clip(local, fine, T / 2), T / 2)

    mesh = mesh_polygon(flexure.outline(), T / 2, refine=size)
    model = PlaneStressModel(
        mesh,
        PETG,
        B,
        Clamp(flexure.ground_block().buffer(1e-6)),
        Rotate(
            flexure.moving_block().buffer(1e-6),
            centre_mm=tuple(flexure.centre_mm),
            max_rad=TURN,
            steps=1,
        ),
        stress_ignore=None,
    )
    res = model.solve("linear")
    return float(res.peak_nodal_stress_MPa[-1]), float(res.torque_Nmm[-1])


def test_sharp_leaf_root_does_not_converge_but_a_filleted_one_does():
    leaf = Leaf(width_mm=B, block_length_mm=5.0, length_mm=25.0, thickness_mm=T)
    # coarse: the peak is the leaf's nominal bending stress 6 M / (b t^2), M the torque it
    # carries (a leaf turned at its end is in pure bending, the closed form exact)
    s8, m8 = peak_and_torque(leaf, 8)
    assert s8 == pytest.approx(6.0 * m8 / (B * T**2), rel=0.01)
    # refined at the 90-degree roots: the singular corner shows, and it keeps rising
    s16, _ = peak_and_torque(leaf, 16)
    s32, _ = peak_and_torque(leaf, 32)
    assert s16 > 1.1 * s8
    assert s32 > 1.03 * s16
    # the same web with 1.5 mm fillets into the blocks: converged to 0.5 % over 8 .. 32
    hinge = CornerFilleted(
        width_mm=B, block_length_mm=5.0, length_mm=22.0, fillet_radius_mm=1.5, thickness_mm=T
    )
    filleted = [peak_and_torque(hinge, n)[0] for n in (8, 16, 32)]
    assert max(filleted) / min(filleted) - 1.0 < 5e-3


def test_leaf_design_is_not_met_with_the_reason():
    req = RootStress("peak_stress_MPa", "peak stress", "constraint", 50.0)
    plain = AllowableStress("peak_stress_MPa", "peak stress", "constraint", 50.0)
    sharp = req.check({"peak_stress_MPa": 23.28, "unbounded_stress": True})
    assert not sharp.met
    assert SHARP_ROOTS in sharp.detail
    assert "leaf roots sharp" in sharp.bound
    assert math.isnan(sharp.margin) and sharp.value == 23.28
    # a filleted design (or a notch) is judged exactly as the plain allowable stress
    for metrics in (
        {"peak_stress_MPa": 23.28, "unbounded_stress": False},
        {"peak_stress_MPa": 60.0},
    ):
        assert req.check(metrics) == plain.check(metrics)


def test_leaf_life_is_not_computed_and_its_row_says_why():
    import dataclasses

    from flexopt.pipeline.problems import study_result
    from flexopt.pipeline.stroke_verdict import UNBOUNDED_LIFE
    from flexopt.pipeline.study import load_study
    from flexopt.pipeline.verdict import judge_result, life_of_result, with_life

    study = load_study("flexure-pivot-life")  # a leaf, made sharp (leaf_root_fillet_mm 0)
    sharp = study.geometry.model_copy(update={"leaf_root_fillet_mm": 0.0})
    study = study.model_copy(update={"geometry": sharp})
    result = study_result(study, 1)
    assert result.summary["unbounded_stress"] is True
    assert life_of_result(study, result) == UNBOUNDED_LIFE
    # as flexopt evaluate judges it: the life (here its reason) in the summary first
    life = {v.name: v for v in judge_result(study, with_life(study, result))}["service life"]
    assert not life.met and UNBOUNDED_LIFE in life.detail
    # the same response without the flag: the life is computed from the nominal stress
    nominal = dataclasses.replace(result, summary={**result.summary, "unbounded_stress": False})
    computed = life_of_result(study, nominal)
    assert computed is not None and not isinstance(computed, str)
    assert math.isfinite(computed.values()["life_cycles"])
