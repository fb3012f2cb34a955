"""The mechanism kind's verdict against the part as made (issue 22): responses read on the
path the printed part follows (a bistable switch with a small imperfection), and stiffness and
stress judged on the highest-fidelity model of the exported outline (plane stress, 3D solid).

The references are computed here with the engines directly (fea.mechanism on the imperfect
mechanism), never pasted from the study's own output.
"""

from __future__ import annotations

from pathlib import Path

import flexopt.pipeline as pipeline
import numpy as np
import pytest
import yaml
from flexopt.fea import mechanism as fm
from flexopt.fea.mechanism_design import as_made_stress
from flexopt.pipeline.problems import study_result
from flexopt.pipeline.studies import mechanism as mk
from flexopt.pipeline.studies._mechanism_schema import build_load_case, build_outline
from flexopt.pipeline.study import validate_study

EXAMPLES = Path(pipeline.__file__).parent / "examples"


def _raw(name: str) -> dict:
    return yaml.safe_load((EXAMPLES / f"{name}.yaml").read_text())


#: gripper-amplifier's recorded design of session 25, where the drawn and the as-made pairings
#: differ; since session 26 the example records the hybrid's optimum (hinge 0.83322, link
#: 0.8025 mm at 6.075 mm), where both pairings judge the same as-made Kt figure
S25_GRIPPER = {"hinge_thickness_mm": 1.1622, "link_thickness_mm": 0.87972, "link_height_mm": 8.9526}


def _gripper_s25() -> dict:
    raw = _raw("gripper-amplifier")
    for variable in raw["variables"]:
        variable["initial"] = S25_GRIPPER[variable["name"]]
    return raw


def _verdict(result, name: str):
    return next(v for v in result.verdicts if v.name == name)


def _first_peak(force: np.ndarray) -> float | None:
    f = force[np.isfinite(force)]
    for k in range(1, len(f) - 1):
        if f[k] >= f[k - 1] and f[k] > f[k + 1]:
            return float(f[k])
    return None


def _perfect_and_imperfect(study, amplitude_mm: float):
    """The shipped design's snap case, solved as drawn and with the imperfection, in the test."""
    x0 = mk._variables(study).initial
    geometry = mk._geometry_of(study, x0)
    _, outline = build_outline(geometry)
    mech = mk._mechanism(study, geometry, made=outline.beams)  # the part as made
    case = build_load_case(study, "snap")
    out = [fm.MechOutput("F", "reaction")]
    perfect = fm.solve_mechanism(mech, case, out)
    imperfect = fm.solve_mechanism(fm.imperfect_mechanism(mech, perfect, amplitude_mm), case, out)
    return geometry, perfect, imperfect, outline


@pytest.mark.slow
def test_bistable_switch_verdict_is_the_imperfect_parts_snap():
    # the beam model's verdict (the check of the outline, tested below on the parallel guide,
    # scales the forces by its ratio: off here, so the figures are the beam's own)
    raw = _raw("bistable-switch")
    raw["fidelity"] = {"enabled": False}
    study = validate_study(raw)
    geometry, perfect, imperfect, outline = _perfect_and_imperfect(study, study.imperfection_mm)
    # the part as drawn loses stability on its way to the second stable position (after its
    # force peak: the optimiser moved away from designs that bifurcate before it, whose snap
    # force the imperfection lowers); the made part follows the imperfect branch
    assert fm.first_unstable_row(perfect) is not None
    assert imperfect.ok and fm.first_unstable_row(imperfect) is None, imperfect.message
    result = study_result(study)
    width = result.summary["width_mm"]
    scale = width / geometry.width_mm  # forces are linear in the width
    snap = _first_peak(imperfect.outputs["F"]) * scale
    v = _verdict(result, "snap_force")
    assert v.value == pytest.approx(snap, rel=1e-9) and v.met
    assert 7.6 <= snap <= 8.4
    # inside the band for imperfections from 0 to 0.05 mm (the snap is before the bifurcation)
    for a in (1e-4, 0.05):
        other = _perfect_and_imperfect(study, a)[2]
        assert 7.6 <= _first_peak(other.outputs["F"]) * scale <= 8.4
    # peak stress along the followed branch (with the filleted roots' Kt, as the kind takes
    # it), and the stable positions on it
    stress = np.nanmax(as_made_stress(imperfect, outline.beams))
    assert result.summary["max_peak_stress_MPa"] == pytest.approx(stress, rel=1e-9)
    count, _ = fm.stable_positions(imperfect.drive, imperfect.outputs["F"])
    assert count == 2 and _verdict(result, "second_stable_position").met
    assert "imperfection" in result.message


def _earlier_switch() -> dict:
    """The bistable switch the example shipped before issue 22 (0.9861 mm beams clamped at
    x = -8.084 mm): its guided path bifurcates before its force peak."""
    raw = _raw("bistable-switch")
    raw["fidelity"] = {"enabled": False}
    raw["variables"][0]["initial"] = 0.9861
    raw["variables"][1]["initial"] = -8.084
    return raw


def test_met_on_the_unstable_path_is_not_met_on_the_followed_branch():
    raw = _earlier_switch()
    study = validate_study(raw)
    geometry, perfect, imperfect, _ = _perfect_and_imperfect(study, study.imperfection_mm)
    assert perfect.critical_drive < perfect.drive[np.nanargmax(perfect.outputs["F"])]
    unstable_peak = _first_peak(perfect.outputs["F"])
    branch_peak = _first_peak(imperfect.outputs["F"])
    assert branch_peak < 0.97 * unstable_peak
    raw.pop("solve_width_from")
    raw["geometry"]["width_mm"] = geometry.width_mm
    raw["requirements"][0] = {
        "name": "snap_force",
        "quantity": "first_peak_force_N",
        "min": 0.98 * unstable_peak,
        "max": 1.02 * unstable_peak,
    }  # MET by the unstable path's first peak
    result = study_result(validate_study(raw))
    v = _verdict(result, "snap_force")
    assert not v.met and v.value == pytest.approx(branch_peak, rel=1e-9)
    # with no imperfection the curve stops at the first unstable row: no peak is read past it
    raw["imperfection_mm"] = 0.0
    stopped = study_result(validate_study(raw))
    row = fm.first_unstable_row(perfect)
    assert not _verdict(stopped, "snap_force").met
    assert not _verdict(stopped, "second_stable_position").met
    assert np.isnan(stopped.table["drive_reaction_N"][row:]).all()
    assert np.isfinite(stopped.table["drive_reaction_N"][:row]).all()
    assert f"the curve stops at row {row}" in stopped.message


# ------------------------------------------------------------------ the check of the outline


def _guide_check(study, width_mm: float) -> dict:
    """The parallel guide's exported outline at ``width_mm``, solved here by the project's
    plane-stress and 3D models (fea.mechanism_fidelity) in its load case."""
    from flexopt.fea.mechanism_fidelity import FidelitySettings, mechanism_fidelity_check

    x0 = mk._variables(study).initial
    geometry = mk._geometry_of(study, x0)
    _, outline = build_outline(geometry)
    return mechanism_fidelity_check(
        mk._mechanism(study, geometry, width_mm, outline.beams), build_load_case(study, "stroke"),
        outline.polygon, list(outline.pads.values()), outline.bodies,
        list(outline.bands.values()), width_mm,
        FidelitySettings(elements_through=study.fidelity.elements_through), None, outline.beams,
    )  # fmt: skip


def _quick_guide(**changes) -> dict:
    raw = _raw("parallel-guide")
    raw["fidelity"] = {"elements_through": 1.0}  # stiffness within 0.2 % of 2 and 3
    raw.update(changes)
    return raw


def test_parallel_guide_beam_only_design_is_judged_on_its_3d_figure():
    """The design the beam model alone passed (width solved to 3.0 N/mm on the beam): its
    exported outline, checked against the beam model of the same part as made (pads at the
    leaves' ends, filleted roots), agrees with it within 2 % in plane stress and is stiffer as
    a solid; its verdicts read the 3D figure, each computed here from the beam-only figure."""
    raw = _quick_guide()
    beam_only = study_result(validate_study({**raw, "fidelity": {"enabled": False}}))
    width = beam_only.summary["width_mm"]
    assert _verdict(beam_only, "stiffness").met
    raw.pop("solve_width_from")
    raw["geometry"]["width_mm"] = width
    study = validate_study(raw)
    check = _guide_check(study, width)
    # the same part in two models: the beam model as made carries the flares' stiffness, so
    # plane stress sits within 2 % of it; a solid this deep lies between plane stress and the
    # plane-strain limit E / (1 - nu^2) of a wide plate
    ps = check["plane_stress_ratio"]
    assert abs(ps - 1.0) < 0.02
    solid = check["solid"][0]
    nu = study.material.nu
    assert solid["depth_mm"] == width and ps < solid["ratio"] < ps / (1.0 - nu**2)
    result = study_result(study)
    for name, limit in (("stiffness", None), ("max_stiffness_N_per_mm", 3.15)):
        v = _verdict(result, name)
        expected = _verdict(beam_only, name).value * solid["ratio"]
        assert v.value == pytest.approx(expected, rel=1e-6)
        assert "3D solid" in v.detail and "beam model" in v.detail
        if limit is not None:
            assert v.met == (expected <= limit)


def test_parallel_guide_verdict_is_judged_on_its_3d_figure():
    study = validate_study(_quick_guide())
    result = study_result(study)
    width = result.summary["width_mm"]
    fid = result.inputs["fidelity"]
    assert fid["width_mm"]["solved"] == width < fid["width_mm"]["beam_model"]
    check = _guide_check(study, width)  # the part as exported, at its exported width
    solid = check["solid"][0]
    # the beam's mean stiffness scales with the width; the verdict's is the 3D figure
    beam_mean = fid["beam_model"]["mean_stiffness_N_per_mm"]
    expected = beam_mean * width / fid["width_mm"]["beam_model"] * solid["ratio"]
    v = _verdict(result, "stiffness")
    assert v.value == pytest.approx(expected, rel=1e-6) and v.met
    assert 2.85 <= v.value <= 3.15
    assert _verdict(result, "min_stiffness_N_per_mm").met
    assert _verdict(result, "max_stiffness_N_per_mm").met
    assert "larger of the beam model" in _verdict(result, "max_peak_stress_MPa").detail
    # the check solves the width again; everything else of the part as made stays: the roots'
    # Kt in the stress (a guided leaf's stress does not depend on the width), the interference
    # over the stroke and the envelope at the exported width
    beam_only = study_result(validate_study({**_quick_guide(), "fidelity": {"enabled": False}}))
    stress = _verdict(result, "max_peak_stress_MPa").value
    assert stress == pytest.approx(_verdict(beam_only, "max_peak_stress_MPa").value, rel=1e-9)
    assert _verdict(result, "no_interference").met
    assert result.summary["interference_mm2"] == 0.0
    assert result.summary["envelope_depth_mm"] == pytest.approx(width, rel=1e-12)


def _check_both_ways(study, case: str):
    """The study's initial design checked with the beam model of the drawn centrelines and
    with the beam model of the part as made (its beams clipped and flared into their roots'
    fillets, the roots' Kt in its peak), solved here; and the as-made solve of ``case``."""
    from flexopt.fea.mechanism_fidelity import FidelitySettings, mechanism_fidelity_check

    x0 = mk._variables(study).initial
    geometry = mk._geometry_of(study, x0)
    _, outline = build_outline(geometry)
    width = geometry.width_mm
    settings = FidelitySettings(elements_through=study.fidelity.elements_through)
    checks = {}
    for tag, made in (("drawn", None), ("made", outline.beams)):
        checks[tag] = mechanism_fidelity_check(
            mk._mechanism(study, geometry, width, made), build_load_case(study, case),
            outline.polygon, list(outline.pads.values()), outline.bodies,
            list(outline.bands.values()), width, settings, None, made,
        )  # fmt: skip
    mech = mk._mechanism(study, geometry, made=outline.beams)
    response = mk._solve_printed_path(study, mech, case)
    return checks, response, outline


def test_the_check_compares_the_exported_outline_with_the_beam_model_as_made():
    """The gripper's hinge (issue 22 / s25 fidmade): the exported outline has the roots'
    fillets, the beam model solved and judged is the part as made (flares, roots' Kt). Checked
    against the drawn centrelines the ratios mix two parts: the plane-stress stiffness is 11 %
    off the drawn beam's but within 3 % of the as-made beam's (the same part in two models),
    and the stress verdict read the drawn-centreline ratio times the as-made beam's peak (on the
    session-25 design, :data:`S25_GRIPPER`)."""
    study = validate_study(_gripper_s25())
    checks, response, outline = _check_both_ways(study, "free")
    drawn, made = checks["drawn"], checks["made"]
    assert abs(made["plane_stress_ratio"] - 1.0) < 0.03 < abs(drawn["plane_stress_ratio"] - 1.0)
    # the as-made beam's peak per unit drive, computed here from a small solve of the as-made
    # mechanism: the check divides by it
    x0 = mk._variables(study).initial
    geometry = mk._geometry_of(study, x0)
    mech = mk._mechanism(study, geometry, made=outline.beams)
    case = build_load_case(study, "free")
    d = case.drive
    value = 1e-4 * abs(d.max_value - d.min_value)
    small = fm.MechDrive(d.part, d.control, value, 1, d.direction, d.transverse, d.rotation, 0.0)
    r = fm.solve_mechanism(mech, fm.LoadCase("free", small, case.supports), [])
    per_drive = float(np.nanmax(as_made_stress(r, outline.beams)[-1])) / value
    assert made["beam_peak_stress_MPa"] == pytest.approx(per_drive, rel=1e-9)
    # the judged figure of each pairing, from the solve's rows
    raw = np.nanmax(np.asarray(response.peak_stress_MPa, float), axis=1)
    kt = np.nanmax(as_made_stress(response, outline.beams), axis=1)
    old = float(np.nanmax(np.fmax(kt, raw * drawn["solid"][0]["stress_ratio"])))
    new = float(np.nanmax(kt * max(1.0, made["solid"][0]["stress_ratio"])))
    assert old > new * 1.02  # the pairings differ on this design
    result = study_result(study)
    ratio = result.inputs["fidelity"]["checks"]["free"]["solid"][0]["stress_ratio"]
    assert ratio == pytest.approx(made["solid"][0]["stress_ratio"], rel=1e-6)
    # the verdict: the larger of both cases' as-made peak and the check's figure (the blocked
    # case has supports: the check skips it, the beam model as made is judged)
    blocked = mk._solve_printed_path(study, mech, "blocked")
    expected = max(new, float(np.nanmax(as_made_stress(blocked, outline.beams))))
    v = _verdict(result, "max_peak_stress_MPa")
    assert v.value == pytest.approx(expected, rel=1e-9)
    assert "larger of the beam model" in v.detail


def test_stress_is_judged_on_the_larger_of_the_beam_and_the_check():
    """The gripper's hinge: the check of the exported outline puts the peak above the beam
    model's (the roots' Kt included); the verdict reads the larger figure, and the optimiser
    holds the beam's stress times ``fidelity.beam_stress_factor``."""
    study = validate_study(_raw("gripper-amplifier"))
    result = study_result(study)
    ratio = result.inputs["fidelity"]["checks"]["free"]["solid"][0]["stress_ratio"]
    # the beam model's stresses as made (the roots' Kt), solved here
    x0 = mk._variables(study).initial
    geometry = mk._geometry_of(study, x0)
    _, outline = build_outline(geometry)
    mech = mk._mechanism(study, geometry, made=outline.beams)
    made = {}
    for case in ("free", "blocked"):
        r = mk._solve_printed_path(study, mech, case)
        made[case] = float(np.nanmax(as_made_stress(r, outline.beams)))
    # the blocked case has supports: the check skips it (beam model); the free case's figure
    # is the as-made peak times the check's ratio to that same peak where it is above 1
    expected = max(made["free"] * max(1.0, ratio), made["blocked"])
    v = _verdict(result, "max_peak_stress_MPa")
    assert v.value == pytest.approx(expected, rel=1e-9)
    assert "larger of the beam model" in v.detail
    # the blocked case (a held jaw) is one the check skips: its verdicts say so, never silently
    jaw = _verdict(result, "jaw_force")
    assert "beam model only" in jaw.detail and "blocked" in jaw.detail
    assert "beam model only" not in _verdict(result, "no_interference").detail
    # the optimiser's figure: the beam model's, as made, times the study's factor
    factor = study.fidelity.beam_stress_factor
    assert factor > 1.0
    ev = mk.MechanismProblem(study).evaluate(np.asarray(x0, dtype=float))
    assert ev.metrics["max_peak_stress_MPa"] == pytest.approx(factor * max(made.values()), rel=1e-9)
