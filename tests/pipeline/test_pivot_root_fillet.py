"""Leaf root fillets (``geometry.leaf_root_fillet_mm``, pipeline/studies/_pivot_roots.py): the
outline draws a fillet of that radius where the leaf meets each block, the beam carries its
flare, and the stress the GA, the verdict and the life read is the roots' shoulder Kt
(geometry/mechanism.py ``shoulder_kt``) times the nominal stress; a converged plane-stress peak
of the filleted leaf checks that figure."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.materials import get_material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Rotate
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.flexures import Leaf, VariableLeaf
from flexopt.geometry.mechanism import shoulder_kt

# the same model as tests/pipeline/test_pivot_sharp_roots.py (the sharp leaf that does not converge)
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


R = 1.0  # mm, the study key's default


def leaf(r: float = R, **kw) -> Leaf:
    return Leaf(width_mm=B, block_length_mm=5.0, length_mm=25.0, thickness_mm=T,
                root_fillet_mm=r, **kw)  # fmt: skip


def test_outline_draws_tangent_quarter_circles_at_the_four_roots():
    f, sharp = leaf(), leaf(0.0)
    # four quarter-circle fillets add 4 r^2 (1 - pi/4) of material (the chords lie on the
    # void side of the arcs: a little more)
    added = f.outline().area - sharp.outline().area
    exact = 4.0 * R**2 * (1.0 - math.pi / 4.0)
    assert added == pytest.approx(exact, rel=2e-3) and added > exact
    # the drawn lower edge near the ground block: every point r from the centre (r, -(t/2 + r))
    x, t = f.profile()
    near = x <= R
    centre = np.array([R, -(0.5 * T + R)])
    dist = np.hypot(x[near] - centre[0], -0.5 * t[near] - centre[1])
    assert dist == pytest.approx(np.full(dist.shape, R), abs=1e-12)
    # tangent to the block face (thickness t + 2r at x = 0) and to the leaf (t from x = r on)
    assert t[0] == pytest.approx(T + 2.0 * R, abs=1e-12)
    assert t[-1] == pytest.approx(T + 2.0 * R, abs=1e-12)
    assert np.all(t[(x >= R) & (x <= 25.0 - R)] == pytest.approx(T, abs=1e-12))
    # the beam is that shape
    beam = f.beams()[0]
    assert np.allclose(beam.thickness_mm, t) and np.allclose(beam.points_mm[:, 0], x)
    # the sharp leaf is drawn exactly as before the key existed
    assert sharp.root_kt == 1.0 and list(sharp.profile()[1]) == [T, T]


def test_root_kt_is_the_shoulder_fit_with_the_block_as_the_wide_side():
    f = leaf()
    assert f.root_kt == shoulder_kt(f.block_height, T, R)
    v = VariableLeaf(width_mm=B, block_length_mm=5.0, length_mm=25.0, thickness_mm=1.5,
                     thicknesses_mm=(2.0, 1.5, 2.5), root_fillet_mm=R)  # fmt: skip
    assert v.root_kt == max(shoulder_kt(v.block_height, e, R) for e in (2.0, 2.5))
    assert v.outline().is_valid


def test_a_fillet_that_does_not_fit_is_refused():
    with pytest.raises(GeometryError, match="root_fillet_mm"):
        leaf(13.0).outline()  # two 13 mm fillets on a 25 mm leaf
    with pytest.raises(GeometryError, match="root_fillet_mm"):
        leaf(3.0).outline()  # the step on the block face is (6.45 - 2.15) / 2 = 2.15 mm
    with pytest.raises(GeometryError, match="root_fillet_mm"):
        leaf(-1.0)


def test_kt_times_nominal_is_the_converged_plane_stress_peak():
    # linear plane stress, 2 degrees, every element counted (the root fillets too), 8 / 16 / 32
    # elements through the thickness: the peak converges, and equals Kt x 6 M / (b t^2), M the
    # torque the leaf carries, within the fit's accuracy (Roark's shoulder fits: a few %)
    f = leaf()
    rows = [peak_and_torque(f, n) for n in (8, 16, 32)]
    peaks = [s for s, _ in rows]
    assert max(peaks) / min(peaks) - 1.0 < 5e-3
    assert abs(peaks[2] / peaks[1] - 1.0) < 1e-3
    s, m = rows[-1]
    nominal = 6.0 * m / (B * T**2)
    assert s / nominal == pytest.approx(f.root_kt, rel=0.02)  # measured 1.2392 vs 1.2436
    assert s / nominal > 1.15  # the fillet's concentration is there, not the nominal stress


def _study(fillet: float):
    from flexopt.pipeline.study import load_study

    study = load_study("flexure-pivot")
    geometry = study.geometry.model_copy(update={"leaf_root_fillet_mm": fillet})
    return study.model_copy(update={"geometry": geometry})


def test_the_ga_and_the_verdict_read_kt_times_the_beam_stress():
    from flexopt.pipeline.studies.flexure_pivot import FlexurePivotProblem

    filleted, sharp = FlexurePivotProblem(_study(R)), FlexurePivotProblem(_study(0.0))
    x = filleted.nominal_design()
    kind, flex = filleted.flexure(x)
    assert kind == "leaf" and flex.root_fillet_mm == R
    ev, ev0 = filleted.evaluate(x), sharp.evaluate(x)
    res = filleted._beam(flex, filleted.study.fidelity.ga_steps)
    beam = float(np.nanmax(res.peak_stress_MPa))
    assert ev.metrics["peak_stress_MPa"] == pytest.approx(flex.root_kt * beam, rel=1e-12)
    # the flare stiffens the leaf a little; the sharp leaf's stress has no Kt
    assert ev.metrics["stiffness_Nmm_per_rad"] > ev0.metrics["stiffness_Nmm_per_rad"]
    assert ev.metrics["peak_stress_MPa"] > 1.2 * ev0.metrics["peak_stress_MPa"]


def test_the_closed_form_stiffness_is_the_drawn_profiles_compliance_integral():
    from flexopt.fea.closed_forms import drawn_leaf_compliance, pivot_closed_form
    from flexopt.fea.pivot import beam_pivot
    from scipy.integrate import quad

    E = PETG.E_MPa
    # a uniform leaf: 12 L / (E b t^3) exactly
    assert drawn_leaf_compliance(E, B, np.array([0.0, 25.0]), np.array([T, T])) == pytest.approx(
        12.0 * 25.0 / (E * B * T**3), rel=1e-14
    )
    f = leaf()
    K = pivot_closed_form(f, E).stiffness_Nmm_per_rad

    # against quadrature of the true circular flare (the drawn chords: within 1e-4)
    def thickness(x: float) -> float:
        d = R - min(x, 25.0 - x, R)  # how far into a fillet
        return T + 2.0 * (R - math.sqrt(R * R - d * d))

    exact = 12.0 * quad(lambda x: thickness(x) ** -3, 0.0, 25.0, points=[R, 25.0 - R])[0]
    assert K == pytest.approx(E * B / exact, rel=1e-4)
    assert K > E * B * T**3 / (12.0 * 25.0)  # the flare stiffens the leaf
    # the beam model of the same profile, turned 1 degree
    res = beam_pivot(f, PETG, math.radians(1.0), 2, n_elements=40)
    assert res.small_angle_stiffness_Nmm_per_rad == pytest.approx(K, rel=1e-6)


def test_only_sharp_roots_keep_the_not_met_rule():
    from flexopt.pipeline.problems import study_result
    from flexopt.pipeline.studies._pivot_roots import SHARP_ROOTS, sharp
    from flexopt.pipeline.verdict import judge_result

    rows = {}
    for r in (R, 0.0):
        study = _study(r)
        study = study.model_copy(
            update={"fidelity": study.fidelity.model_copy(update={"plane_stress": False})}
        )
        assert sharp("leaf", study) is (r == 0.0) and not sharp("circular_notch", study)
        result = study_result(study, 1)
        assert result.summary["unbounded_stress"] is (r == 0.0)
        rows[r] = {v.name: v for v in judge_result(study, result)}["peak stress"]
    assert rows[R].met and SHARP_ROOTS not in (rows[R].detail or "")
    assert not rows[0.0].met and SHARP_ROOTS in rows[0.0].detail
