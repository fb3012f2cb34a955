"""polyline_beam's clamps as made (#22, pipeline/studies/_polyline_clamp.py): the beam model
clamps the strip ideally (Kt 1), while a strip as made grows out of a base (or sits in a clamp)
with a corner there. Plane stress of a strip grown out of a block shows what the model cannot
see: at the sharp corner the peak rises without bound under refinement; a filleted corner
converges, to a Kt that ``boundary.clamp_kt`` can state. The row "peak stress at the clamp as
made" is NOT MET without the key (the shipped cantilever was MET on the ideal clamp's figure),
and judges clamp_kt x the beam's clamp stress with it."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.materials import get_material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Translate
from flexopt.pipeline.studies import polyline_beam as pb
from flexopt.pipeline.studies._polyline_clamp import CLAMP_ROW, CLAMP_STRESS
from flexopt.pipeline.study import load_study, validate_study
from flexopt.pipeline.verdict import judge_result
from shapely.geometry import LineString, Point, box

ABS = get_material("ABS")
T_MM, B_MM, L_MM = 2.0, 8.0, 20.0  # strip thickness, width and length, mm (L/t = 10)
D_MM = 1e-3 * L_MM  # transverse end motion, mm: small, the linear solve is the small-strain one


def strip(max_mm: float, start: str = "clamped", rotation: str = "fixed", **boundary) -> dict:
    return {
        "name": "strip",
        "material": "ABS",
        "geometry": {"kind": "polyline_beam", "points_mm": [[0, 0], [L_MM, 0]],
                     "thickness_mm": [T_MM, T_MM], "width_mm": B_MM, "elements": 40},
        "boundary": {"start": start, **boundary,
                     "end": {"control": "displacement", "direction": [0, 1], "max_mm": max_mm,
                             "steps": 1, "rotation": rotation, "transverse": "free"}},
    }  # fmt: skip


def rows(raw: dict):
    study = validate_study(raw)
    result = pb.evaluate(study)
    return result, {v.name: v for v in judge_result(study, result)}


def grown_out_of_a_block(fillet_mm: float, h_corner_mm: float) -> float:
    """MPa: the linear plane-stress peak (nodal von Mises) of the clamped-guided strip grown out
    of a block (4 t wide, 2 t deep, its back edge clamped), its end edge translated D_MM (the
    end's rotation held), at the corners where the strip meets the block (the driven end's
    zone left out): sharp (``fillet_mm`` 0) or filleted, elements of ``h_corner_mm`` there."""
    t = T_MM
    part = box(-2 * t, -2 * t, 0.0, 2 * t).union(box(-1e-9, -t / 2, L_MM, t / 2))
    if fillet_mm:
        # a closing rounds the two re-entrant corners with arcs of that radius, nothing else
        part = part.buffer(fillet_mm, quad_segs=64).buffer(-fillet_mm, quad_segs=64)
        part = part.intersection(box(-2 * t, -2 * t, L_MM, 2 * t))
    zone = max(fillet_mm, t / 4) + t / 4
    corners = [(Point(0.0, y).buffer(zone), h_corner_mm) for y in (t / 2, -t / 2)]
    mesh = mesh_polygon(part, t / 4, refine=corners)
    model = PlaneStressModel(
        mesh,
        ABS,
        B_MM,
        Clamp(LineString([(-2 * t, -2 * t), (-2 * t, 2 * t)]).buffer(1e-6)),
        Translate(LineString([(L_MM, -t / 2), (L_MM, t / 2)]).buffer(1e-6), (0.0, 1.0), D_MM,
                  1, "free"),
        stress_ignore=box(L_MM - 2 * t, -t, L_MM + 1, t),
    )  # fmt: skip
    return float(model.solve("linear").peak_nodal_stress_MPa[-1])


def test_the_beams_clamp_stress_is_the_exact_ideal_clamps():
    # clamped-guided, small motion, Timoshenko (k = 5/6): M = 6 E I d / (L^2 (1 + phi)) at
    # either end, phi = 12 E I / (k G A L^2), the fibre M c / I
    result, _ = rows(strip(D_MM))
    phi = ABS.E_MPa * T_MM**2 / (5 / 6 * ABS.G_MPa * L_MM**2)
    exact = 6.0 * ABS.E_MPa * D_MM * (T_MM / 2) / (L_MM**2 * (1 + phi))
    assert result.summary[CLAMP_STRESS] == pytest.approx(exact, rel=2e-3)


def test_the_part_as_made_has_a_corner_the_ideal_clamp_does_not_see():
    beam = rows(strip(D_MM))[0].summary[CLAMP_STRESS]
    sharp = [grown_out_of_a_block(0.0, T_MM / n) for n in (8, 32, 128)]
    # the sharp corner: above the ideal clamp's figure and rising without bound
    assert sharp[0] > 1.2 * beam
    assert sharp[1] > 1.25 * sharp[0] and sharp[2] > 1.25 * sharp[1]
    # filleted (r = t/2): converged, a Kt a study can state as boundary.clamp_kt
    filleted = [grown_out_of_a_block(T_MM / 2, T_MM / n) for n in (16, 32)]
    assert abs(filleted[1] / filleted[0] - 1) < 0.01
    kt = filleted[1] / beam
    assert 1.05 < kt < sharp[2] / beam
    _, judged = rows(strip(D_MM, clamp_kt=kt))
    row = judged[CLAMP_ROW]
    assert row.met and row.value == pytest.approx(filleted[1], rel=1e-9)
    assert f"clamp_kt {kt:g}" in row.detail


def test_the_cantilever_is_not_met_on_its_ideal_clamp_and_met_with_a_stated_kt():
    study = load_study("cantilever")
    result = pb.evaluate(study)
    judged = {v.name: v for v in judge_result(study, result)}
    row = judged[CLAMP_ROW]
    # every other row is MET: before the row the cantilever was MET on the ideal clamp
    assert all(v.met for name, v in judged.items() if name != CLAMP_ROW)
    assert not row.met and row.role == "check"
    assert "boundary.clamp_kt" in row.detail and "23.68 MPa on Kt 1" in row.detail
    # a cantilever's largest moment is at its clamp: the clamp stress is the peak
    assert result.summary[CLAMP_STRESS] == pytest.approx(result.summary["max_peak_stress_MPa"])
    raw = study.model_dump(mode="json", exclude_none=True)
    stress, allowable = result.summary[CLAMP_STRESS], ABS.yield_MPa
    for kt, met in ((1.5, True), (1.01 * allowable / stress, False)):
        raw["boundary"]["clamp_kt"] = kt
        again = validate_study(raw)
        row = {v.name: v for v in judge_result(again, pb.evaluate(again))}[CLAMP_ROW]
        assert row.met is met and row.value == pytest.approx(kt * stress, rel=1e-12)


def test_a_pinned_start_with_a_free_end_clamps_nothing_and_a_held_end_does():
    _, judged = rows(strip(1.0, start="pinned", rotation="free"))
    assert CLAMP_ROW not in judged
    result, judged = rows(strip(1.0, start="pinned", rotation="fixed"))
    assert "the end (its rotation fixed)" in judged[CLAMP_ROW].detail
    assert np.isfinite(result.summary[CLAMP_STRESS])
    with pytest.raises(Exception, match="clamp_kt"):
        validate_study(strip(1.0, clamp_kt=0.5))
