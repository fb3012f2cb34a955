"""The ``geometry.pad_fillet_mm`` key of the constant-force study: the flared beam solved, Kt x
the beam's stress over each flare folded into the peak stress, the fillets drawn in the outline,
the refusals (docs/constant_force.md, "Fillets at the pads"). Kt comes from the Roark fit and the
stress over the flare from statics, both computed here on a beam built here."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel, BeamSettings
from flexopt.fea.beam_statics import statics_stress
from flexopt.geometry.constant_force import (
    DESIGN_VARIABLE_NAMES,
    FILLET_CHORDS,
    WORK_DIRECTION,
    centreline_points,
    filleted_beam,
    outline,
)
from flexopt.geometry.profile import BeamProfile
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import constant_force as cf
from flexopt.pipeline.study import load_study
from pydantic import ValidationError

EXAMPLE = Path(__file__).resolve().parents[2] / "pipeline" / "examples" / "constant-force.yaml"


def roark_kt(D: float, d: float, r: float) -> float:
    """Roark 7th ed. Table 17.1, square shoulder with a fillet, in-plane bending."""
    h = (D - d) / 2
    q = h / r
    assert 0.1 <= q <= 20
    sq = math.sqrt(q)
    if q <= 2:
        c = (1.007 + sq - 0.031 * q, -0.270 - 2.404 * sq + 0.749 * q,
             0.677 + 1.133 * sq - 0.904 * q, -0.414 + 0.271 * sq + 0.186 * q)  # fmt: skip
    else:
        c = (1.042 + 0.982 * sq - 0.036 * q, -3.599 + 1.619 * sq - 0.431 * q,
             6.084 - 5.607 * sq + 1.158 * q, -2.527 + 3.006 * sq - 0.691 * q)  # fmt: skip
    x = 2 * h / D
    return c[0] + c[1] * x + c[2] * x**2 + c[3] * x**3


#: The design session 26 recorded (the GA's, 4 digits): T1 / T6 = 1.175 / 1.227 mm, so r = 0.1
#: mm on 5 mm pads is h / r = 19.1 / 18.9, inside the Roark fit (h / r <= 20). The example's
#: design (session 28's hybrid) has T6 = 0.93 mm: h / r = 20.3 there, outside the fit.
SESSION_26 = dict(
    a1=0.203, a2=0.7976, a3=0.5906, a4=0.8004, a5=0.3493, a6=0.768, a7=0.6089, a8=0.7685,
    a9=0.1678, a10=0.7629, t1=0.9472, t2=0.8651, t3=1.077, t4=0.802, t5=0.8282, t6=0.8103,
    t7=0.85, t8=1.033, t9=0.8582, t10=1.043, T1=1.175, T6=1.227, B=6.97,
)  # fmt: skip


def _study(design=None, **geometry):
    study = load_study(EXAMPLE)
    update = {"geometry": study.geometry.model_copy(update=geometry)}
    return study.model_copy(update=update if design is None else {**update, "design": design})


def _expected(prob, design):
    """(R,) MPa per row: the statics peak of the flared beam built here, Kt x its largest
    |axial| + |bending| over each flare (s <= r from S1, s >= L - r from S6), and the larger."""
    g = prob.study.geometry
    made = filleted_beam(design, prob.frame, g.pad_thickness_mm, g.end_flexures, g.pad_fillet_mm)
    profile = BeamProfile(made.shape.points_mm, made.shape.thickness_mm, design.B)
    model = BeamModel(profile, prob.material, "clamped", BeamSettings(n_elements=g.elements))
    response = model.solve(prob._drive(prob.study.boundary.stroke_mm, prob.study.boundary.rows))
    assert response.ok
    st = statics_stress(model, response, np.asarray(WORK_DIRECTION))
    sigma = np.abs(st.axial_MPa) + np.abs(st.bending_MPa)
    s, total = st.s_mm, float(st.s_mm[-1])
    r1, r6 = made.start.root_mm, made.end.root_mm
    kt1 = roark_kt(g.pad_thickness_mm, design.T1, r1)
    kt6 = roark_kt(g.pad_thickness_mm, design.T6, r6)
    root = np.fmax(
        kt1 * np.max(sigma[:, s <= r1 + 1e-9], axis=1),
        kt6 * np.max(sigma[:, s >= total - r6 - 1e-9], axis=1),
    )
    return st.peak_stress_MPa, root, (kt1, kt6)


@pytest.mark.timeout(300)
@pytest.mark.parametrize("recorded", [SESSION_26, None], ids=["session-26", "example"])
def test_shipped_design_with_half_mm_fillets_judges_the_beam_peak_and_kt_root(recorded):
    """The benchmark's r = 0.5 mm row (session 26's design: Kt from the fit 1.321 / 1.301 in the
    docs' table, Kt x root under the mid-beam peak) and the example's design (the hybrid's, whose
    Kt x root and mid-beam peak it balanced: 41.26211 / 41.26210 MPa): the evaluation's peak the
    larger of the two per row."""
    prob = cf.problem(_study(recorded, pad_fillet_mm=0.5))
    x = prob.nominal_design()
    design = prob._design(x)
    beam_peak, root, kts = _expected(prob, design)
    made = filleted_beam(design, prob.frame, 4.0, "centred", 0.5)
    assert (made.start.kt, made.end.kt) == pytest.approx(kts, rel=1e-12)
    _, response, reason = prob._solve(x)
    assert reason == ""
    want = np.fmax(beam_peak, root)
    np.testing.assert_allclose(response.peak_stress_MPa[1:], want[1:], rtol=1e-9)
    if recorded is SESSION_26:  # the pads are not this design's critical section
        assert np.max(root) < np.max(beam_peak)
    ev = prob.evaluate(x)
    assert ev.metrics["peak_stress_MPa"] == pytest.approx(np.max(want), rel=1e-9)
    # the sharp study's peak (no fold, the sharp beam) is lower: the flare stiffens the clamp
    _, sharp, _ = cf.problem(_study(pad_fillet_mm=0.0))._solve(x)
    assert np.max(sharp.peak_stress_MPa) < np.max(response.peak_stress_MPa)


@pytest.mark.timeout(300)
def test_a_small_fillet_on_tall_pads_makes_kt_root_the_peak():
    """r = 0.1 mm on 5 mm pads (h / r = 19, in the fit; session 26's design): Kt x root passes
    the mid-beam peak, and the peak the verdict and the GA see is Kt x root, at a pad end (s = 0
    or the length)."""
    prob = cf.problem(_study(SESSION_26, pad_fillet_mm=0.1, pad_thickness_mm=5.0))
    x = prob.nominal_design()
    beam_peak, root, _ = _expected(prob, prob._design(x))
    _, response, reason = prob._solve(x)
    assert reason == ""
    assert np.max(root) > np.max(beam_peak)
    np.testing.assert_allclose(
        response.peak_stress_MPa[1:], np.fmax(beam_peak, root)[1:], rtol=1e-9
    )
    k = int(np.argmax(response.peak_stress_MPa))
    total = float(prob._beam(prob._design(x)).profile.length_mm)
    assert min(abs(response.peak_stress_s_mm[k]), abs(response.peak_stress_s_mm[k] - total)) < 1e-9


def test_the_outline_draws_the_fillets_as_chords():
    """The outline's extra area is, per end, the chord polygon of the two quarter arcs: the
    trapezoid sum of 2 r (1 - sin psi) over s = r (1 - cos psi) at FILLET_CHORDS + 1 angles
    (the taper is linear, so the flare adds exactly that); close to 4 (1 - pi / 4) r^2. The
    outlines are mitred (blend 0): the study's blends of the design vertices' kinks depend on
    the segments next to them, which the flare splits (test_constant_force_kinks.py)."""
    r = 0.5
    sharp = cf.problem(_study(pad_fillet_mm=0.0))
    fil = cf.problem(_study(pad_fillet_mm=r))
    design = sharp._design(sharp.nominal_design())
    g = sharp.study.geometry
    args = (design, sharp.frame, g.pad_length_mm, g.pad_thickness_mm, g.end_flexures)
    a0 = outline(*args, 0.0, 0.0).area
    a1 = outline(*args, r, 0.0).area
    psi = np.linspace(0.0, 0.5 * np.pi, FILLET_CHORDS + 1)
    s, extra = r * (1 - np.cos(psi)), 2 * r * (1 - np.sin(psi))
    per_end = float(np.sum(0.5 * (extra[1:] + extra[:-1]) * np.diff(s)))
    assert a1 - a0 == pytest.approx(2 * per_end, rel=1e-6)
    assert a1 - a0 == pytest.approx(2 * 2 * (1 - math.pi / 4) * r**2, rel=0.05)
    # the default study (no key) draws the default fillet, 0.5 mm: the same outline as r above
    assert cf.pads.DEFAULT_PAD_FILLET_MM == r
    drawn = cf.pads.study_outline(fil, design).area
    assert drawn == pytest.approx(cf.pads.study_outline(_problem_default(), design).area, abs=0)


def _problem_default():
    return cf.problem(load_study(EXAMPLE))


#: the example's design before session 26 (an input here): its S6 end segment is 1.36 mm
SESSION_25_DESIGN = {
    "a1": 0.159, "a2": 0.8071, "a3": 0.5057, "a4": 0.8453, "a5": 0.133, "a6": 0.8451,
    "a7": 0.4573, "a8": 0.7743, "a9": 0.2115, "a10": 0.8743, "t1": 1.059, "t2": 0.8668,
    "t3": 0.966, "t4": 0.8001, "t5": 0.8003, "t6": 0.8275, "t7": 0.8367, "t8": 0.9738,
    "t9": 0.9394, "t10": 1.049, "T1": 1.371, "T6": 1.278, "B": 6.826,
}  # fmt: skip


def test_toe_on_a_design_point_is_refused_with_one_line():
    """r = 2 mm is capped at the S6 shoulder (1.36 mm) of the session-25 design, whose toe
    lands 3 um from p10."""
    prob = cf.problem(_study(pad_fillet_mm=2.0))
    x = np.array([SESSION_25_DESIGN[n] for n in DESIGN_VARIABLE_NAMES])
    design = prob._design(x)
    pts = centreline_points(design, prob.frame, "centred")
    assert abs(np.linalg.norm(pts[-1] - pts[-2]) - 0.5 * (4.0 - design.T6)) < cf.pads.TOE_CLEAR_MM
    with pytest.raises(StudyError, match="p10") as err:
        prob.result(x)
    assert "\n" not in str(err.value)
    assert not prob.evaluate(x).feasible


def test_hybrid_with_a_fillet_is_taken_and_differentiates_kt_x_root():
    """Since the exact Jacobian differentiates Kt x root (tests/pipeline/
    test_constant_force_fillet_gradient.py), method: hybrid takes a fillet."""
    study = _study(pad_fillet_mm=0.5)
    hybrid = study.model_copy(
        update={"optimiser": study.optimiser.model_copy(update={"method": "hybrid"})}
    )
    cf.check(hybrid)
    prob = cf.problem(study)
    assert prob.jacobian(prob.nominal_design()) is not None


@pytest.mark.parametrize("bad", [-0.1, 10.5, float("nan")])
def test_pad_fillet_bounds_and_default(bad):
    data = {"kind": "constant_force", "pad_fillet_mm": bad}
    with pytest.raises(ValidationError):
        cf.ConstantForceGeometry(**data)
    default = cf.ConstantForceGeometry(kind="constant_force").pad_fillet_mm
    assert default == cf.pads.DEFAULT_PAD_FILLET_MM == 0.5


def _row(study):
    from flexopt.pipeline.studies._builtin import constant_force

    return next(r for r in constant_force(study) if r.quantity == "peak_stress_MPa")


@pytest.mark.parametrize("value", [41.31, 44.0])
def test_sharp_pad_corners_are_not_met_whatever_the_figure(value):
    """pad_fillet_mm: 0 judges the row NOT MET with the reason, under the allowable or over it;
    with a fillet the same figure is judged against the allowable alone. The margin (and so
    the GA's constraint row) is the nominal one either way: only the verdict refuses MET."""
    sharp, filleted = _row(_study(pad_fillet_mm=0.0)), _row(_study(pad_fillet_mm=0.5))
    assert sharp.allowable_MPa == filleted.allowable_MPa == 42.5
    metrics = {"peak_stress_MPa": value}
    vs, vf = sharp.check(metrics), filleted.check(metrics)
    assert vf.met is (value <= 42.5) and vf.bound == "<= 42.5 MPa"
    assert vs.met is False and vs.word == "NOT MET"
    assert vs.margin == vf.margin == pytest.approx(42.5 - value, rel=1e-12)
    assert sharp.constraint(metrics) == filleted.constraint(metrics)
    assert "sharp" in vs.bound and "pad_fillet_mm = 0" in vs.bound
    assert "not bound" in vs.detail or "no figure" in vs.detail
    assert "pad_fillet_mm > 0" in vs.detail and "\n" not in vs.detail


def test_the_key_dumps_and_reads_back_both_ways():
    """The default is written into the resolved study, and an explicit 0 reads back as 0 (not as
    the default): run folders and the study hash tell a sharp study from a filleted one."""
    default = load_study(EXAMPLE)
    assert default.geometry.pad_fillet_mm == 0.5
    assert default.model_dump()["geometry"]["pad_fillet_mm"] == 0.5
    sharp = _study(pad_fillet_mm=0.0)
    dumped = sharp.model_dump()["geometry"]
    assert dumped["pad_fillet_mm"] == 0.0
    assert cf.ConstantForceGeometry(**dumped).pad_fillet_mm == 0.0


def _write_variant(tmp_path, fillet):
    """The shipped example with the plane-stress check off (the verdict judges the beam) and
    ``pad_fillet_mm`` set, or absent when ``fillet`` is None."""
    import yaml

    data = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    data["fidelity"] = {"enabled": False}
    if fillet is not None:
        data["geometry"]["pad_fillet_mm"] = fillet
    path = tmp_path / f"cf-{fillet}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


@pytest.mark.timeout(600)
@pytest.mark.parametrize(("fillet", "word"), [(None, "MET"), (0, "NOT MET")])
def test_the_cli_verdict_line_with_and_without_fillets(fillet, word, tmp_path, capsys):
    """``flexopt evaluate``: the shipped design with the default fillet is MET; with
    ``pad_fillet_mm: 0`` the peak-stress row and the overall verdict are NOT MET, with the
    reason on the row's line; exit code 0 either way (evaluate reports, it does not refuse)."""
    import json

    from flexopt.pipeline.cli import main

    out = tmp_path / "eval"
    code = main(["evaluate", str(_write_variant(tmp_path, fillet)), "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0
    rows = [line for line in text.splitlines() if line.startswith("peak stress ")]
    assert len(rows) == 1 and rows[0].rstrip().endswith(f"{word} (constraint)"), rows
    assert f"overall: {word} (" in text
    record = json.loads((out / "evaluation.json").read_text(encoding="utf-8"))
    row = next(r for r in record["verdict"]["requirements"] if r["name"] == "peak stress")
    assert row["verdict"] == word
    if fillet == 0:
        assert "sharp 90 degree corners" in text and "sharp" in row["bound"]
        assert row["value"] < 42.5  # under the allowable, and still NOT MET
