"""The mechanism kind's beam joints as made (#22, pipeline/studies/_mechanism_joints.py): a
clamped joint of two beam ends that meet at an angle (or with a step in thickness) has a sharp
re-entrant corner in the exported outline, which the beam model (two sections tied at a point,
Kt 1) does not see; a pinned beam end is printed solid. Each is NOT MET with the reason where
the old verdict was MET; two ends that continue each other are one strip (no row)."""

from __future__ import annotations

import pytest
import shapely
from flexopt.fea.materials import get_material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Translate
from flexopt.pipeline.problems import kind_problem, nominal_design
from flexopt.pipeline.studies._mechanism_joints import BEAM_JOINT, PINNED_JOINT, joint_turn
from flexopt.pipeline.study import validate_study
from shapely.geometry import Point

T_MM = 1.5


def spring(corner: bool = True, t_b: float = T_MM, joint: str = "clamped") -> dict:
    """Two beams joined end to end, the first grounded, the second into a tip block moved
    0.01 mm (its rotation and sideways motion held): along x for an L (the second beam turns
    90 deg up), along y for a straight strip."""
    b_end = [20, 20] if corner else [40, 0]
    tip = ([[16, 20], [24, 20], [24, 26], [16, 26]] if corner else
           [[40, -4], [46, -4], [46, 4], [40, 4]])  # fmt: skip
    return {
        "name": "joined",
        "material": "PA12",
        "geometry": {
            "kind": "mechanism", "width_mm": 8.0,
            "beams": {"a": {"points_mm": [[0, 0], [20, 0]], "thickness_mm": T_MM},
                      "b": {"points_mm": [[20, 0], b_end], "thickness_mm": t_b}},
            "bodies": {"tip": {"ref_mm": [20, 23] if corner else [43, 0], "outline_mm": tip}},
            "joints": [{"a": "a.start", "b": "ground"},
                       {"a": "a.end", "b": "b.start", "type": joint},
                       {"a": "b.end", "b": "tip"}],
        },
        "load_cases": {"push": {"drive": {"part": "tip", "control": "displacement",
                                          "direction": [1, 0] if corner else [0, 1],
                                          "max_mm": 0.01, "steps": 1, "rotation": "held",
                                          "transverse": "held"}}},
        "outputs": {"force_N": {"quantity": "reaction"}},
        "requirements": [{"quantity": "max_peak_stress_MPa", "safety_factor": 1.5}],
        "fidelity": {"enabled": False},
    }  # fmt: skip


def solved_rows(raw: dict):
    study = validate_study(raw)
    problem = kind_problem(study)
    solved = problem.solve(nominal_design(problem, study))
    assert not isinstance(solved, tuple), solved
    return solved, {v.name: v for v in problem.judge(solved)}


def corner_peak(outline, h_corner_mm: float) -> tuple[float, float]:
    """MPa: the linear plane-stress peak (nodal von Mises) and its distance from the L's inner
    corner (mm) of the exported outline, its pad
    clamped, the tip block moved 0.01 mm along x, elements of ``h_corner_mm`` at the L's inner
    corner, the pad and the block left out of the peak."""
    pad = shapely.union_all(list(outline.pads.values()))
    tip = outline.bodies["tip"]
    inner = Point(20 - T_MM / 2, T_MM / 2)
    mesh = mesh_polygon(outline.polygon, T_MM / 4, refine=[(inner.buffer(T_MM / 2), h_corner_mm)])
    model = PlaneStressModel(
        mesh, get_material("PA12"), 8.0, Clamp(pad.buffer(1e-6)),
        Translate(tip.buffer(1e-6), (1.0, 0.0), 0.01, 1, "fixed"),
        stress_ignore=shapely.union_all([pad, tip]).buffer(T_MM / 4),
    )  # fmt: skip
    res = model.solve("linear")
    return float(res.peak_nodal_stress_MPa[-1]), Point(res.peak_nodal_stress_xy_mm[-1]).distance(
        inner
    )


def test_an_angled_beam_joint_is_not_met_where_it_was_met_and_its_corner_is_unbounded():
    solved, judged = solved_rows(spring())
    row = judged[f"{BEAM_JOINT} (a.end | b.start)"]
    assert not row.met and row.role == "check"
    assert "turning 90 deg" in row.detail and "sharp re-entrant corner" in row.detail
    # before the row this design was MET: every other row is
    assert all(v.met for name, v in judged.items() if name != row.name)
    # the exported outline has the corner: its peak rises without bound under refinement
    # (the same drive as the beam model's: it reads 0.163 MPa, its roots' Kt included)
    runs = [corner_peak(solved.outline, T_MM / n) for n in (8, 32, 128)]
    peaks, where = [p for p, _ in runs], [d for _, d in runs]
    assert max(where) < 1e-6  # at the corner itself
    assert peaks[0] > solved.metrics["max_peak_stress_MPa"]
    assert peaks[1] > 1.2 * peaks[0] and peaks[2] > 1.2 * peaks[1]


def test_ends_that_continue_each_other_are_one_strip_and_a_step_is_a_corner():
    _, judged = solved_rows(spring(corner=False))
    assert not any(name.startswith(BEAM_JOINT) for name in judged)
    assert all(v.met for v in judged.values())
    _, judged = solved_rows(spring(corner=False, t_b=1.2))
    row = judged[f"{BEAM_JOINT} (a.end | b.start)"]
    assert not row.met and "in line with a 0.3 mm step in thickness" in row.detail


def test_a_pinned_beam_end_is_not_met_printed_solid():
    _, judged = solved_rows(spring(joint="pinned"))
    row = judged[f"{PINNED_JOINT} (a.end | b.start)"]
    assert not row.met and "prints the joint solid" in row.detail
    assert not any(name.startswith(BEAM_JOINT) for name in judged)


@pytest.mark.parametrize("k", [0.02, -0.02])
def test_the_turn_of_arcs_is_their_tangents_not_their_chords(k):
    # two equal arcs on one line, bulging the same way: their chords continue each other,
    # their tangents turn (a cusp)
    import math

    from flexopt.pipeline.studies._mechanism_schema import BeamSpec

    beams = {
        "a": BeamSpec(points_mm=[[0, 0], [10, 0]], thickness_mm=1.0, curvature_per_mm=[k]),
        "b": BeamSpec(points_mm=[[10, 0], [20, 0]], thickness_mm=1.0, curvature_per_mm=[k]),
    }
    turn, step = joint_turn(beams, "a.end", "b.start")
    assert step == 0.0
    # each tangent is its chord turned by half the arc's angle, asin(|k| c / 2): two of them
    assert turn == pytest.approx(2 * math.degrees(math.asin(abs(k) * 10 / 2)), rel=1e-12)
