"""A stranger's spec for the constant_force kind (``spec:``): its mapping onto the study, and
the refusal (or warning) before any run when the material cannot give it."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import pytest
import yaml
from flexopt.fea.constant_force_estimate import estimate_spec
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies._constant_force_spec import (
    check_spec,
    chord,
    part_box_mm,
    spec_estimate,
    study_frame,
)
from flexopt.pipeline.study import load_study, validate_study

EXAMPLE = Path(__file__).resolve().parents[2] / "pipeline" / "examples"

BASE = {
    "name": "cf-stranger",
    "geometry": {"kind": "constant_force"},
    "material": "PETG",
    "spec": {
        "force_N": 5.0,
        "stroke_mm": 15.0,
        "envelope": {"length_mm": 90.0, "height_mm": 60.0},
        "width_max_mm": 10.0,
    },
}


def _with(**spec):
    raw = copy.deepcopy(BASE)
    raw["spec"].update(spec)
    return raw


def test_spec_maps_onto_the_kinds_keys_and_round_trips():
    study = validate_study(copy.deepcopy(BASE))
    assert study.target.force_N == 5.0 and study.boundary.stroke_mm == 15.0
    assert study.design_space["B"][1] == 10.0
    assert study.initial == "design" and isinstance(study.design, dict)
    assert study.spec.frame_scale is not None
    assert study.requirements[-1].envelope_mm == (90.0, 60.0)
    # the frame is the largest paper frame whose part fits the envelope
    g = study.geometry
    key = (g.end_flexures, g.pad_length_mm, g.pad_thickness_mm)
    w, h = part_box_mm(study.spec.frame_scale, key)
    assert w <= 90.0 and h <= 60.0 and max(w / 90.0, h / 60.0) > 0.999
    assert study_frame(study).x_in_mm == pytest.approx(100 * study.spec.frame_scale)
    # the resolved study (what study.yaml records) reads back to the same study
    dumped = study.model_dump(mode="json", exclude_none=True)
    assert validate_study(copy.deepcopy(dumped)).model_dump(mode="json") == study.model_dump(
        mode="json"
    )


def test_a_study_without_spec_dumps_no_spec_key():
    study = load_study(EXAMPLE / "constant-force.yaml")
    assert study.spec is None and "spec" not in study.model_dump(mode="json")
    assert check_spec(study) is None


def test_the_example_spec_is_feasible_by_the_estimate():
    study = load_study(EXAMPLE / "constant-force-custom.yaml")
    est = spec_estimate(study.spec, study.geometry, study.material.E_MPa, study.allowable_MPa)
    assert est.status == "feasible"
    assert study.material.name == "PETG" and study.target.force_N == study.spec.force_N


@pytest.mark.parametrize(
    ("change", "path", "words"),
    [
        ({"target": {"force_N": 4.0}}, "target.force_N", "differs from spec.force_N"),
        ({"boundary": {"stroke_mm": 10.0}}, "boundary.stroke_mm", "differs from spec.stroke_mm"),
        ({"design_space": {"B": [2.0, 12.0]}}, "design_space.B", "exceeds spec.width_max_mm"),
    ],
)
def test_conflicting_keys_are_refused(change, path, words):
    raw = copy.deepcopy(BASE)
    raw.update(change)
    with pytest.raises(StudyError) as err:
        validate_study(raw)
    assert err.value.path == path and words in err.value.problem


def test_an_envelope_too_small_for_any_frame_is_refused():
    with pytest.raises(StudyError) as err:
        validate_study(_with(envelope={"length_mm": 20.0, "height_mm": 15.0}))
    assert err.value.path == "spec.envelope" and "cannot hold the part" in err.value.problem


def test_infeasible_spec_is_refused_with_the_figure_before_any_run(tmp_path, capsys):
    """50 N over 15 mm in PETG within 90 x 60 x 10 mm: the section the force needs breaks at the
    stroke. `flexopt run` exits 2 with one line: the key path, the stress figure, the remedies;
    no run folder is made."""
    study_file = tmp_path / "stranger.yaml"
    study_file.write_text(yaml.safe_dump(_with(force_N=50.0)))
    out = tmp_path / "runs"
    code = main(["run", str(study_file), "--out", str(out), "--quick"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1
    assert "spec.force_N: 50 N over 15 mm is more than PETG gives" in err
    assert "allowable 50 MPa" in err and "feasible (<= 90 %) with a stroke <=" in err
    assert "a force <=" in err and "width_max_mm >=" in err and "an envelope of >=" in err
    assert not out.exists() or not any(out.iterdir())
    # the figures are the estimate's for the refused spec
    study = validate_study(copy.deepcopy(BASE))
    length, angle = chord(study_frame(study), "centred")
    refused = estimate_spec(50.0, 15.0, length, angle, 1500.0, 50.0, 10.0, 0.8)
    assert refused.status == "infeasible" and refused.limit == "force"
    assert f"reaches {refused.peak_stress_MPa:.3g} MPa" in err
    # what would make it feasible: the figures at 90 % of the allowable (the edge of feasible)
    edge = estimate_spec(50.0, 15.0, length, angle, 1500.0, 0.9 * 50.0, 10.0, 0.8)
    assert f"a force <= {edge.max_force_N:.3g} N" in err
    assert f"a stroke <= {edge.max_stroke_mm:.3g} mm" in err
    assert estimate_spec(
        0.999 * edge.max_force_N, 15.0, length, angle, 1500.0, 50, 10, 0.8
    ).status == ("feasible")


def test_a_stroke_the_thinnest_section_cannot_make_is_refused_at_the_stroke(tmp_path):
    with pytest.raises(StudyError) as err:
        validate_study(
            _with(force_N=0.5, stroke_mm=40.0, envelope={"length_mm": 70, "height_mm": 45})
        )
    assert err.value.path == "spec.stroke_mm"
    assert "needs more strain than PETG gives" in err.value.problem
    assert "a force <=" not in err.value.problem  # no force helps: the stroke alone breaks it


def test_marginal_spec_warns_once_and_loads(capsys):
    raw = _with(force_N=5.0, stroke_mm=21.0)
    study = validate_study(raw)
    est = check_spec(study)
    assert est is not None and est.status == "marginal"
    assert 0.9 < est.stress_ratio < 1 / 0.78
    err = capsys.readouterr().err
    assert err.count("spec: marginal:") == 1 and "flexopt: warning:" in err
    assert math.isfinite(est.peak_stress_MPa)
