"""polyline_beam's slenderness bound (#27): the beam model measured against plane stress of the
same strip, and the row that makes a stubby strip NOT MET (pipeline/studies/
_polyline_slenderness.py)."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.materials import get_material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Translate
from flexopt.pipeline.studies import polyline_beam as pb
from flexopt.pipeline.studies._polyline_slenderness import MIN_SLENDERNESS
from flexopt.pipeline.study import validate_study
from flexopt.pipeline.verdict import judge_result
from shapely.geometry import LineString, Polygon

T_MM, B_MM = 2.0, 8.0


def strip(L: float, max_mm: float, rotation: str = "fixed", t: float = T_MM) -> dict:
    return {
        "name": "strip",
        "material": "ABS",
        "geometry": {"kind": "polyline_beam", "points_mm": [[0, 0], [L, 0]],
                     "thickness_mm": [t, t], "width_mm": B_MM, "elements": 40},
        "boundary": {"start": "clamped", "end": {"control": "displacement", "direction": [0, 1],
                     "max_mm": max_mm, "steps": 1, "rotation": rotation, "transverse": "free"}},
    }  # fmt: skip


def beam_stiffness(L: float) -> float:
    """N/mm: the beam model's clamped-guided strip, 1e-4 L of transverse end motion."""
    r = pb.evaluate(validate_study(strip(L, 1e-4 * L)))
    return float(r.table["force_N"][-1] / r.table["displacement_mm"][-1])


def plane_stress_stiffness(L: float, h: float) -> float:
    """N/mm: the same strip in plane stress (P2, elements of ``h`` mm), its start clamped, its
    end edge translated rigidly (rotation held), sliding free along the strip."""
    t = T_MM
    mesh = mesh_polygon(Polygon([(0, -t / 2), (L, -t / 2), (L, t / 2), (0, t / 2)]), h)
    d = 1e-4 * L
    model = PlaneStressModel(
        mesh,
        get_material("ABS"),
        B_MM,
        Clamp(LineString([(0, -t / 2), (0, t / 2)])),
        Translate(LineString([(L, -t / 2), (L, t / 2)]), (0.0, 1.0), d, 1, "free"),
    )
    return float(model.solve("linear").force_N[-1] / d)


@pytest.mark.parametrize(
    ("ratio", "low", "high"),
    [(2.0, 0.02, 0.035), (MIN_SLENDERNESS, 0.0, 0.01)],  # measured 2.73 %, 0.90 %
)
def test_the_beam_stiffness_error_against_plane_stress_sets_the_bound(ratio, low, high):
    L = ratio * T_MM
    coarse, fine = plane_stress_stiffness(L, T_MM / 4), plane_stress_stiffness(L, T_MM / 8)
    assert abs(coarse / fine - 1) < 0.003  # plane stress converged to well under the error
    error = abs(beam_stiffness(L) / fine - 1)
    # at the bound the beam is within 1 % of plane stress; at L/t = 2 it is not
    assert low < error < high


def test_a_stubby_strip_is_not_met_with_the_reason_and_a_slender_one_is_met():
    def verdict(L: float):
        study = validate_study(strip(L, 0.01 * L, rotation="free"))
        rows = {v.name: v for v in judge_result(study, pb.evaluate(study))}
        return rows["slender enough for the beam model"]

    stubby = verdict(2 * T_MM)
    assert not stubby.met and stubby.value == pytest.approx(2.0)
    assert "L/t = 2 below 6" in stubby.detail
    slender = verdict(MIN_SLENDERNESS * T_MM * 1.01)
    assert slender.met and slender.value == pytest.approx(MIN_SLENDERNESS * 1.01)


def test_the_ratio_is_the_arc_length_over_the_thickest_point():
    raw = strip(30.0, 0.3)
    raw["geometry"].update(points_mm=[[0, 0], [10, 0], [30, 0]], thickness_mm=[1.0, 2.5, 1.5])
    r = pb.evaluate(validate_study(raw))
    assert r.summary["slenderness_ratio"] == pytest.approx(30.0 / 2.5, rel=1e-12)
    assert np.isfinite(r.summary["slenderness_ratio"])
