"""The constant-force part's kinks (docs/constant_force.md, "The plane-stress peak under
refinement"): the outline blends each design vertex's kink with a curve tangent to both edges,
within the deviation computed here; the plane-stress peak of the blended part converges under
refinement where the mitred part's keeps rising (its kink is a re-entrant corner); the verdict
judges the larger of the study mesh's peak and the locally refined re-solve's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from flexopt.fea.fidelity import plane_stress_check
from flexopt.geometry.constant_force import BLEND_CHORDS, WORK_DIRECTION, outline
from flexopt.pipeline.studies import constant_force as cf
from flexopt.pipeline.studies._constant_force_clamp import CHECKED_PEAK, checked_peak_figures
from flexopt.pipeline.studies._constant_force_kinks import REFINED_PEAK
from flexopt.pipeline.study import load_study
from shapely.geometry import Point, Polygon

EXAMPLE = Path(__file__).resolve().parents[2] / "pipeline" / "examples" / "constant-force.yaml"

#: The design session 26 recorded (the GA's, 4 digits): its kinks are the ones these tests were
#: written on (largest 1.09 deg; the mitred peak sits at a kink). The example's design (the
#: hybrid's, session 28) has kinks up to 2.6 deg: its blend moves the outline by 11.5 um
#: (the computed bound still holds) and its blended peak converges too (test below).
SESSION_26 = dict(
    a1=0.203, a2=0.7976, a3=0.5906, a4=0.8004, a5=0.3493, a6=0.768, a7=0.6089, a8=0.7685,
    a9=0.1678, a10=0.7629, t1=0.9472, t2=0.8651, t3=1.077, t4=0.802, t5=0.8282, t6=0.8103,
    t7=0.85, t8=1.033, t9=0.8582, t10=1.043, T1=1.175, T6=1.227, B=6.97,
)  # fmt: skip


def _study(design=None, **geometry):
    study = load_study(EXAMPLE)
    update = {"geometry": study.geometry.model_copy(update=geometry)}
    return study.model_copy(update=update if design is None else {**update, "design": design})


def _sharp_problem():
    return cf.problem(_study(SESSION_26, pad_fillet_mm=0.0))


def _turns(ring: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """(k,) rad: the turning angle at the ring's vertices where ``keep`` (n,) is true."""
    a = ring - np.roll(ring, 1, axis=0)
    b = np.roll(ring, -1, axis=0) - ring
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return np.abs(np.arctan2(cross, np.einsum("ij,ij->i", a, b)))[keep]


def test_the_blend_is_tangent_and_within_its_computed_deviation():
    """Sharp pads (no fillet chords), session 26's design: every kink blended. The largest turn
    left between two drawn edges is the largest kink / BLEND_CHORDS (a quadratic Bezier's chord
    has the direction of its tangent at the middle parameter, which turns evenly for small
    kinks); the outline moves by at most max(a sin(kink / 2) / 2), the Bezier's distance from
    its control point at u = 1/2, with a = min(blend, a quarter of the shorter segment)."""
    prob = _sharp_problem()
    design = prob._design(prob.nominal_design())
    g = prob.study.geometry
    args = (design, prob.frame, g.pad_length_mm, g.pad_thickness_mm, g.end_flexures, 0.0)
    mitred, blended = outline(*args, 0.0), outline(*args, 1.0)
    pts = prob._beam(design).profile.points_mm
    for shape in (mitred, blended):
        assert shape.is_valid

    def pad(end, inward):
        # the pad rectangle beyond an end, grown by 0.05 mm: its corners are left out
        out = -inward / np.linalg.norm(inward)
        n = np.array([-out[1], out[0]]) * (0.5 * g.pad_thickness_mm + 0.05)
        far = end + out * (g.pad_length_mm + 0.05)
        return Polygon([end - n - 0.05 * out, far - n, far + n, end + n - 0.05 * out])

    pads = pad(pts[0], pts[1] - pts[0]).union(pad(pts[-1], pts[-2] - pts[-1]))

    def beam_turns(shape):
        ring = np.asarray(shape.exterior.coords)[:-1]
        return _turns(ring, np.array([not pads.contains(Point(p)) for p in ring]))

    kinks = beam_turns(mitred)
    assert kinks.max() > np.radians(0.5)  # the design has kinks to blend
    assert beam_turns(blended).max() <= 1.05 * kinks.max() / BLEND_CHORDS
    # the deviation bound, from the mitred sides' kinks and the centreline's segments
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    a = np.minimum(1.0, np.minimum(seg[:-1], seg[1:]) / 4)
    bound = float(np.max(a) * np.sin(kinks.max() / 2) / 2)
    moved = mitred.hausdorff_distance(blended)
    assert 0 < moved <= bound + 1e-9
    assert moved < 0.01  # mm: far under a printer's tolerance
    # the area between a quadratic Bezier and its control polygon is 2/3 of the triangle
    # (a^2 sin(kink) / 2), per interior vertex and side
    area_bound = 2 * (len(pts) - 2) * np.max(a) ** 2 * np.sin(kinks.max()) / 3
    assert 0 < abs(blended.area - mitred.area) <= area_bound


def _peaks(prob, shape, edges):
    """Peak nodal von Mises (MPa) at the last row: the study mesh (0.5 mm), then 0.5 mm with
    each of ``edges`` within 1 mm of the 0.5 mm mesh's peak."""
    x = prob.nominal_design()
    design = prob._design(x)
    beam = prob._beam(design)
    _, response, reason = prob._solve(x)
    assert reason == ""
    g = prob.study.geometry
    last = np.array([len(response.displacement_mm) - 1])
    hi = float(response.displacement_mm[-1])
    args = (beam, shape, prob.material, design.B, g.pad_length_mm, g.pad_thickness_mm)
    coarse = plane_stress_check(*args, WORK_DIRECTION, response, last, hi, 0.5)
    field = coarse["field"]
    vm = np.asarray(field["steps"][0]["von_mises_MPa"])
    counted = np.asarray(field["stress_counted"], dtype=bool)
    at = np.asarray(field["points_mm"])[np.flatnonzero(counted)[np.argmax(vm[counted])]]
    out = [coarse["plane_stress_peak_nodal_von_mises_MPa"][0]]
    for edge in edges:
        fine = plane_stress_check(
            *args, WORK_DIRECTION, response, last, hi, 0.5, [(Point(at).buffer(1.0), edge)]
        )
        assert all(fine["converged"])
        out.append(fine["plane_stress_peak_nodal_von_mises_MPa"][0])
    return np.array(out)


@pytest.mark.timeout(900)
def test_the_blended_peak_converges_under_refinement_where_the_mitred_one_rises():
    """Session 26's design at 30 mm, the mesh halved three times within 1 mm of the peak. The
    part as exported (blended kinks): the peak moves by under 0.1 % per halving and 0.2 % in
    all. The mitred outline: it rises by more than 0.3 % at every halving, without the
    increments shrinking (a re-entrant corner, singular) - the comparison the study's verdict
    read before the blend."""
    edges = [0.25, 0.125, 0.0625]
    prob = cf.problem(_study(SESSION_26))
    design = prob._design(prob.nominal_design())
    blended = _peaks(prob, cf.pads.study_outline(prob, design), edges)
    steps = np.diff(blended) / blended[:-1]
    assert np.all(np.abs(steps) < 1e-3), blended
    assert abs(blended[-1] / blended[0] - 1) < 2e-3, blended
    g = prob.study.geometry
    mitred_shape = outline(
        design, prob.frame, g.pad_length_mm, g.pad_thickness_mm, g.end_flexures,
        g.pad_fillet_mm, 0.0,
    )  # fmt: skip
    mitred = _peaks(prob, mitred_shape, edges)
    rises = np.diff(mitred) / mitred[:-1]
    assert np.all(rises > 3e-3), mitred
    assert rises[-1] > 0.5 * rises[0], mitred  # not converging geometrically
    assert mitred[-1] > blended[-1] + 0.5  # MPa: the mitred kink's figure is the corner's


@pytest.mark.timeout(900)
def test_the_examples_blended_peak_converges_under_refinement():
    """The example's design at 30 mm, the mesh halved four times within 1 mm of the peak, down
    to 0.03125 mm: the increments shrink (each at most half the one before, or under 1e-4),
    the last is under 1e-4 (converged), and the verdict's figure (the larger of the 0.5 mm mesh
    and the 0.125 mm re-solve) is not under the converged peak by more than 0.1 %. Session 28's
    design (its peak on the blend of a 2.4 deg kink) moved by under 0.01 % per halving; session
    35's converges from above, 41.814 -> 41.736 -> 41.715 -> 41.712 -> 41.712 MPa (the verdict
    reads 41.81, 0.25 % on the safe side). With 8 chords per blend it did not converge:
    42.353 -> 42.408 -> 43.195 MPa at 0.125 / 0.0625 / 0.03125 mm, the chords' joints resolved
    (geometry.constant_force.BLEND_CHORDS)."""
    prob = cf.problem(load_study(EXAMPLE))
    design = prob._design(prob.nominal_design())
    blended = _peaks(prob, cf.pads.study_outline(prob, design), [0.25, 0.125, 0.0625, 0.03125])
    steps = np.abs(np.diff(blended) / blended[:-1])
    assert np.all((steps[1:] <= 0.5 * steps[:-1]) | (steps[1:] < 1e-4)), blended
    assert steps[-1] < 1e-4, blended
    verdict = max(blended[0], blended[2])  # the study mesh, and the 0.125 mm re-solve
    assert verdict >= blended[-1] * (1 - 1e-3), blended


def test_the_verdict_judges_the_larger_of_the_study_mesh_and_the_refined_peak():
    record = {"plane_stress_peak_nodal_von_mises_MPa": [30.0, 41.0], "converged": [True, True]}
    beam = np.array([np.nan, 20.0, 40.5])
    assert checked_peak_figures(record, beam)[CHECKED_PEAK] == 41.0
    up = checked_peak_figures({**record, REFINED_PEAK: 41.4}, beam)
    assert up[CHECKED_PEAK] == up["plane_stress_peak_stress_MPa"] == 41.4
    down = checked_peak_figures({**record, REFINED_PEAK: 40.9}, beam)
    assert down[CHECKED_PEAK] == 41.0 and down[REFINED_PEAK] == 40.9
    assert (
        checked_peak_figures({**record, REFINED_PEAK: 39.0}, np.array([42.0]))[CHECKED_PEAK] == 42.0
    )


@pytest.mark.timeout(600)
def test_the_study_check_re_solves_its_peak_row_refined():
    """``fidelity_check`` of the recorded design: the row of the largest peak re-solved at a
    quarter of the mesh within 1 mm of that peak, its figure recorded and judged."""
    prob = cf.problem(load_study(EXAMPLE))
    x = prob.nominal_design()
    design = prob._design(x)
    _, response, _ = prob._solve(x)
    check = cf.fidelity_check(prob, design, response, 0.5, 30.0)
    refined = check["refined"]
    peaks = check["plane_stress_peak_nodal_von_mises_MPa"]
    assert refined["coarse_peak_MPa"] == max(peaks)
    assert refined["max_edge_mm"] == prob.study.fidelity.max_edge_mm / 4
    assert check[REFINED_PEAK] == refined["peak_MPa"]
    # the two figures close (the previous test: the peak converges within 0.25 % of the study
    # mesh's on the recorded design)
    assert abs(refined["peak_MPa"] / max(peaks) - 1) < 5e-3
    figures = checked_peak_figures(check, response.peak_stress_MPa)
    assert figures[CHECKED_PEAK] == max(
        max(peaks), refined["peak_MPa"], np.nanmax(response.peak_stress_MPa)
    )
