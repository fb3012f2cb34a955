"""A calibrated material's thickness offset: every printed section analysed as made (#26).

The reference of each test is the same study with the uncalibrated material and every printed
thickness drawn ``dt`` thicker, written out in the test: the calibrated study must give the same
forces, while its design vector, its study and its exported outline stay as drawn.
"""

import numpy as np
import pytest
import yaml
from flexopt.pipeline.as_printed import (
    THICKNESS_KEYS,
    UNPERTURBED_BLOCKS,
    AsPrintedProblem,
    printed_design,
)
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.materials_file import ENV_VAR
from flexopt.pipeline.problems import kind_problem, nominal_design
from flexopt.pipeline.study import load_study, resolve_study_path, study_to_yaml, validate_study
from flexopt.pipeline.verdict import judge_result

DT = 0.05
ABS = {"E_MPa": 1800.0, "nu": 0.35, "yield_MPa": 42.5}


@pytest.fixture(autouse=True)
def _no_user_file(monkeypatch, tmp_path_factory):
    monkeypatch.setenv(ENV_VAR, str(tmp_path_factory.mktemp("nouser") / "none.yaml"))


def _calibrated(tmp_path, example, dt=DT, **changes):
    """The example with ``material: my-abs`` (ABS with a measured offset ``dt``) and
    ``changes`` (top-level blocks), loaded from a folder holding the materials file."""
    (tmp_path / "materials.yaml").write_text(
        yaml.safe_dump({"my-abs": {**ABS, "thickness_offset_mm": dt}})
    )
    raw = yaml.safe_load(resolve_study_path(example).read_text())
    raw.update(changes)
    raw["material"] = "my-abs"
    path = tmp_path / f"{example}.yaml"
    path.write_text(yaml.safe_dump(raw))
    return load_study(path)


def _reference(study, shift):
    """The study as plain data with the calibrated material's offset taken out; ``shift`` moves
    the printed thicknesses of that data by hand."""
    data = study.model_dump(mode="json", exclude_none=True)
    assert data["material"].pop("thickness_offset_mm") == DT
    shift(data)
    return validate_study(data)


def test_the_rule_is_the_scatter_samples_rule():
    from flexopt.pipeline import robustness

    assert THICKNESS_KEYS == robustness.THICKNESS_KEYS
    assert UNPERTURBED_BLOCKS == robustness.UNPERTURBED_BLOCKS


def test_polyline_beam_calibrated_equals_drawn_thicker(tmp_path):
    import flexopt

    study = _calibrated(tmp_path, "cantilever")
    assert study.material.thickness_offset_mm == DT

    def thicker(data):
        data["geometry"]["thickness_mm"] = [t + DT for t in data["geometry"]["thickness_mm"]]

    reference = _reference(study, thicker)
    got, want = flexopt.evaluate(study), flexopt.evaluate(reference)
    np.testing.assert_array_equal(got.table["force_N"], want.table["force_N"])
    np.testing.assert_array_equal(got.table["peak_stress_MPa"], want.table["peak_stress_MPa"])
    # the model is not the drawn one: the offset changes the force, about (1 + dt/t)^3
    drawn = flexopt.evaluate(study.with_values({"material.thickness_offset_mm": None}))
    ratio = got.table["force_N"][-1] / drawn.table["force_N"][-1]
    assert ratio == pytest.approx((1 + DT / 1.5) ** 3, rel=0.02)
    # the verdict and the result say so; the study is the drawing
    assert got.summary["thickness_offset_mm"] == DT
    assert all("judged as printed" in v.detail and "+0.05 mm" in v.detail for v in got.verdict)
    assert got.study.geometry.thickness_mm == (1.5, 1.5, 1.5)
    assert "thickness_offset_mm: 0.05" in study_to_yaml(study)


def test_constant_force_calibrated_equals_drawn_thicker(tmp_path):
    study = _calibrated(tmp_path, "constant-force", fidelity={"enabled": False})
    names = ("T1", "T6", *(f"t{j}" for j in range(1, 11)))

    def thicker(data):
        data["geometry"]["pad_thickness_mm"] += DT  # the clamping pads are printed walls too
        for name in names:
            data["design"][name] += DT

    reference = _reference(study, thicker)
    problem, plain = kind_problem(study), kind_problem(reference)
    assert isinstance(problem, AsPrintedProblem)
    x, x_ref = nominal_design(problem, study), nominal_design(plain, reference)
    moved = np.flatnonzero(x != x_ref)
    assert len(moved) == len(names) and np.allclose(x_ref[moved] - x[moved], DT)
    got, want = problem.evaluate(x), plain.evaluate(x_ref)
    np.testing.assert_array_equal(got.x, x)  # the design vector stays the drawn one
    np.testing.assert_array_equal(got.f, want.f)
    np.testing.assert_array_equal(got.g, want.g)
    assert got.metrics == want.metrics
    detail, detail_ref = problem.detail(x), plain.detail(x_ref)
    np.testing.assert_array_equal(detail.table["force_N"], detail_ref.table["force_N"])
    # the exported outline is the drawing's, not the print's
    drawn = kind_problem(validate_study({**study.model_dump(mode="json"), "material": "ABS"}))
    assert detail.outline.equals(drawn.detail(x).outline)
    assert not detail.outline.equals(detail_ref.outline)
    record = detail.info["as printed"]
    assert record["thickness_offset_mm"] == DT and record["exported geometry"] == "as drawn"
    assert sorted(record["design variables moved"]) == sorted(f"{n}_mm" for n in names)
    # the printable minimum is a rule on the drawing: a design drawn under it is refused although
    # its print would be thick enough; the verdict reads the printed thinnest wall
    (printable,) = [v for v in judge_result(study, detail, x) if v.name == "printable feature"]
    assert printable.value == pytest.approx(min(x[moved]) + DT)
    thin = x.copy()
    thin[moved[0]] = study.geometry.min_feature_mm - DT / 2
    assert "not printable" in problem.evaluate(thin).reason
    assert plain.evaluate(printed_design(problem.drawn, thin, DT)).reason == ""


def test_flexure_pivot_calibrated_equals_drawn_thicker(tmp_path):
    import flexopt

    fidelity = {"steps": 10, "ga_steps": 3, "plane_stress": False}
    study = _calibrated(tmp_path, "flexure-pivot", fidelity=fidelity)

    def thicker(data):
        data["design"]["thickness_mm"] += DT

    got, want = flexopt.evaluate(study), flexopt.evaluate(_reference(study, thicker))
    assert set(got.table) == set(want.table)
    for column in got.table:
        np.testing.assert_array_equal(got.table[column], want.table[column], err_msg=column)


def test_a_thinner_print_moves_the_printable_minimum_and_refuses_a_vanishing_section(tmp_path):
    study = _calibrated(tmp_path, "constant-force", dt=-0.05, fidelity={"enabled": False})
    problem = kind_problem(study)
    assert "geometry.min_feature_mm" in problem.changed
    assert problem.evaluate(nominal_design(problem, study)).reason == ""
    from flexopt.pipeline.problems import study_result

    geometry = yaml.safe_load(resolve_study_path("cantilever").read_text())["geometry"]
    thin = _calibrated(
        tmp_path, "cantilever", dt=-0.9, geometry={**geometry, "thickness_mm": [0.8] * 3}
    )
    with pytest.raises(StudyError, match="material.thickness_offset_mm"):
        study_result(thin)


def test_a_study_with_nothing_to_move_says_the_offset_is_not_applied(tmp_path):
    """sea_window has no printed section (a stiffness window): the offset moves nothing, and
    its verdicts say it is not applied rather than "judged as printed"."""
    from flexopt.optimise.requirements import Verdict
    from flexopt.pipeline.materials_file import with_as_printed_verdicts

    study = _calibrated(tmp_path, "cantilever")
    v = Verdict("stress within yield", "stress_yield_ratio", 0.5, "<= 1", 0.5, 0.5, True, "")
    (moved,) = with_as_printed_verdicts(study, (v,), {"applied": True})
    (still,) = with_as_printed_verdicts(study, (v,), {"applied": False})
    assert "judged as printed" in moved.detail
    assert "is not applied" in still.detail and "+0.05 mm" in still.detail
    assert with_as_printed_verdicts(study, (v,), None) == (v,)  # no record: nothing claimed
    from flexopt.pipeline.as_printed import printed_study

    window = _calibrated(tmp_path, "sea-window")
    assert printed_study(window)[1] == ()


def test_gripper_calibrated_equals_its_beam_drawn_thicker(tmp_path):
    """The gripper's beam is the constant-force study it resolves: the calibrated material's
    offset travels into that study, whose width B is rescaled to the grip force from the
    printed beam. Reference: the plain material and a constant-force study written with every
    printed thickness dt thicker."""
    import flexopt

    base = yaml.safe_load(resolve_study_path("constant-force").read_text())
    names = ("T1", "T6", *(f"t{j}" for j in range(1, 11)))
    thicker = yaml.safe_load(resolve_study_path("constant-force").read_text())
    for name in names:
        thicker["design"][name] += DT
    thicker["geometry"]["pad_thickness_mm"] += DT
    thicker["geometry"]["min_feature_mm"] += DT  # the printable minimum moves with the print
    (tmp_path / "cf-drawn.yaml").write_text(yaml.safe_dump(base))
    (tmp_path / "cf-thicker.yaml").write_text(yaml.safe_dump(thicker))
    link = yaml.safe_load(resolve_study_path("gripper").read_text())["constant_force"]
    study = _calibrated(
        tmp_path, "gripper", constant_force={**link, "study": str(tmp_path / "cf-drawn.yaml")}
    )
    reference = validate_study(
        {
            **study.model_dump(mode="json", exclude_none=True),
            "material": "ABS",
            "constant_force": {**link, "study": str(tmp_path / "cf-thicker.yaml")},
        }
    )
    assert reference.material.E_MPa == ABS["E_MPa"] and reference.material.nu == ABS["nu"]
    got, want = flexopt.evaluate(study), flexopt.evaluate(reference)
    assert set(got.table) == set(want.table)
    for column in got.table:
        np.testing.assert_array_equal(got.table[column], want.table[column], err_msg=column)
    # the width B the gripper resolves is the printed beam's (it holds the force as printed)
    assert got.summary["beam_width_mm"] == want.summary["beam_width_mm"]
    plain = flexopt.evaluate(study.with_values({"material.thickness_offset_mm": None}))
    assert got.summary["beam_width_mm"] < plain.summary["beam_width_mm"]  # thicker: narrower
    # the drawing: the resolved study's design is the drawn one, with the printed B
    from flexopt.pipeline.problems import study_result

    detail = study_result(study)
    design = detail.inputs["constant_force_study"]["design"]
    assert [design[n] for n in names] == [base["design"][n] for n in names]
    assert design["B"] == got.summary["beam_width_mm"]
    # the result and every verdict say it was judged as printed
    assert got.summary["thickness_offset_mm"] == DT
    record = detail.info["as printed"]
    assert record["applied"] and "geometry.pad_thickness_mm" in record["study keys moved"]
    assert sorted(record["design variables moved"]) == sorted(f"{n}_mm" for n in names)
    assert got.verdict and all("judged as printed" in v.detail for v in got.verdict)
    # the design vector and the exported outline are the drawing's: the resolved study's design
    # with the uncalibrated material
    problem = kind_problem(study)
    x = nominal_design(problem, study)
    drawn_study = validate_study({**detail.inputs["constant_force_study"], "material": "ABS"})
    drawn = kind_problem(drawn_study)
    np.testing.assert_array_equal(x, nominal_design(drawn, drawn_study))
    assert problem.detail(x).outline.equals(drawn.detail(x).outline)
