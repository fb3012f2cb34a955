"""Bad study files: one line on stderr naming the key path, exit code 2, nothing written."""

from __future__ import annotations

import copy
from pathlib import Path

import flexopt.pipeline as pipeline
import pytest
import yaml
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.study import load_study, parse_study_text, validate_study

EXAMPLE = yaml.safe_load(
    (Path(pipeline.__file__).parent / "examples" / "cantilever.yaml").read_text()
)


def _set(path: str, value):
    """A mutation that sets (or, with value ``...``, deletes) a dotted key of the example."""

    def mutate(study: dict) -> None:
        *parents, last = path.split(".")
        node = study
        for key in parents:
            node = node[key]
        if value is ...:
            del node[last]
        else:
            node[last] = value

    return mutate


def _force_with_max_mm(study: dict) -> None:
    study["boundary"]["end"]["control"] = "force"  # keeps max_mm: 20


# (id, mutation, key path the message must name, a word the message must contain)
BAD_STUDIES = [
    ("unknown top key", _set("nmae", "x"), "nmae", "unknown key"),
    (
        "misspelt key",
        _set("geometry.thicknes_mm", [1, 1, 1]),
        "geometry.thicknes_mm",
        "thickness_mm",
    ),
    ("missing name", _set("name", ...), "name", "missing"),
    ("name not a folder name", _set("name", "my study/1"), "name", "my_study_1"),
    ("wrong type", _set("geometry.width_mm", "wide"), "geometry.width_mm", "number"),
    ("thickness count", _set("geometry.thickness_mm", [1.5, 1.5]), "geometry.thickness_mm", "3"),
    (
        "zero-length segment",
        _set("geometry.points_mm", [[0, 0], [0, 0], [60, 0]]),
        "geometry.points_mm",
        "zero-length",
    ),
    (
        "non-positive thickness",
        _set("geometry.thickness_mm", [1.5, 0, 1.5]),
        "geometry.thickness_mm[1]",
        "greater than 0",
    ),
    ("zero width", _set("geometry.width_mm", 0), "geometry.width_mm", "greater than 0"),
    (
        "nan thickness",
        _set("geometry.thickness_mm", [1.5, float("nan"), 1.5]),
        "geometry.thickness_mm[1]",
        "finite",
    ),
    (
        "a point with 3 coordinates",
        _set("geometry.points_mm", [[0, 0], [30, 0, 0], [60, 0]]),
        "geometry.points_mm[1]",
        "2",
    ),
    (
        "curvature count",
        _set("geometry.curvature_per_mm", [0.0]),
        "geometry.curvature_per_mm",
        "segment",
    ),
    (
        "curvature too large for the chord",
        _set("geometry.curvature_per_mm", [0.1, 0.0]),
        "geometry.curvature_per_mm[0]",
        "2/chord",
    ),
    (
        "elements not an integer",
        _set("geometry.elements", 2.5),
        "geometry.elements",
        "whole number",
    ),
    ("unknown kind", _set("geometry.kind", "blob"), "geometry.kind", "polyline_beam"),
    ("missing kind", _set("geometry.kind", ...), "geometry.kind", "polyline_beam"),
    ("unknown material", _set("material", "unobtainium"), "material", "PLA"),
    (
        "custom material missing nu",
        _set("material", {"E_MPa": 2000, "yield_MPa": 40}),
        "material.nu",
        "missing",
    ),
    (
        "nu out of range",
        _set("material", {"E_MPa": 2000, "nu": 0.6, "yield_MPa": 40}),
        "material.nu",
        "0.5",
    ),
    ("material not a name or mapping", _set("material", 42), "material", "library name"),
    ("start support unknown", _set("boundary.start", "welded"), "boundary.start", "clamped"),
    ("max_mm with control force", _force_with_max_mm, "boundary.end.max_mm", "max_N"),
    (
        "max_N with control displacement",
        _set("boundary.end.max_N", 3.0),
        "boundary.end.max_N",
        "max_mm",
    ),
    (
        "displacement control without max_mm",
        _set("boundary.end.max_mm", ...),
        "boundary.end.max_mm",
        "add it",
    ),
    ("negative max_mm", _set("boundary.end.max_mm", -5), "boundary.end.max_mm", "direction"),
    (
        "direction of zero length",
        _set("boundary.end.direction", [0, 0]),
        "boundary.end.direction",
        "no length",
    ),
    ("zero steps", _set("boundary.end.steps", 0), "boundary.end.steps", "greater than or equal"),
    (
        "rotation misspelt",
        _set("boundary.end.rotation", "clamped"),
        "boundary.end.rotation",
        "'fixed' or 'free'",
    ),
    ("boundary missing", _set("boundary", ...), "boundary", "missing"),
]


def _run(tmp_path: Path, text: str, capsys) -> tuple[int, list[str], Path]:
    study = tmp_path / "study.yaml"
    study.write_text(text)
    out = tmp_path / "out"
    code = main(["evaluate", str(study), "--out", str(out)])
    captured = capsys.readouterr()
    return code, captured.err.strip().splitlines(), out


@pytest.mark.parametrize(
    ("mutate", "key_path", "word"),
    [case[1:] for case in BAD_STUDIES],
    ids=[case[0] for case in BAD_STUDIES],
)
def test_bad_study_is_one_line_naming_the_key_path(mutate, key_path, word, tmp_path, capsys):
    study = copy.deepcopy(EXAMPLE)
    mutate(study)
    code, err, out = _run(tmp_path, yaml.safe_dump(study, sort_keys=False), capsys)
    assert code == 2
    assert len(err) == 1, err
    line = err[0]
    assert "Traceback" not in line
    assert f": {key_path}: " in line, line
    assert word in line, line
    assert not out.exists(), "a refused study must not leave a run folder"


BAD_FILES = [
    ("empty file", "", "empty"),
    ("only a comment", "# nothing here\n", "empty"),
    ("not YAML", "name: x\ngeometry: [unclosed\n", "not valid YAML at line"),
    ("tab indentation", "name: x\ngeometry:\n\tkind: polyline_beam\n", "not valid YAML"),
    ("top level is a list", "- name: x\n", "mapping"),
    ("duplicate key", "name: a\nname: b\n", "duplicate key 'name'"),
    ("geometry not a mapping", "name: a\ngeometry: polyline_beam\n", "geometry: must be a mapping"),
]


@pytest.mark.parametrize(
    ("text", "word"), [case[1:] for case in BAD_FILES], ids=[case[0] for case in BAD_FILES]
)
def test_unusable_file_is_one_line(text, word, tmp_path, capsys):
    code, err, out = _run(tmp_path, text, capsys)
    assert code == 2
    assert len(err) == 1 and "Traceback" not in err[0]
    assert word in err[0] and "study.yaml" in err[0], err[0]
    assert not out.exists()


def test_missing_file_names_the_examples(tmp_path, capsys):
    assert main(["evaluate", str(tmp_path / "nope.yaml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not found" in err[0] and "cantilever" in err[0]
    assert not (tmp_path / "out").exists()


def test_binary_file_is_one_line(tmp_path, capsys):
    study = tmp_path / "study.yaml"
    study.write_bytes(b"\xff\xfe\x00garbage\x80")
    assert main(["evaluate", str(study), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "UTF-8" in err[0]


def test_out_that_is_a_file_is_refused_before_solving(tmp_path, capsys):
    out = tmp_path / "out"
    out.write_text("keep me")
    assert main(["evaluate", "cantilever", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--out" in err[0]
    assert out.read_text() == "keep me"


def test_exponent_numbers_without_a_dot_are_numbers():
    """PyYAML reads `1e9` and `1.8e3` as strings (YAML 1.1); studies read them as YAML 1.2 does."""
    text = (Path(pipeline.__file__).parent / "examples" / "cantilever.yaml").read_text()
    text = text.replace("material: ABS", "material: {E_MPa: 1.8e3, nu: 0.35, yield_MPa: 425e-1}")
    text = text.replace("max_mm: 20.0", "max_mm: 2E1")
    study = validate_study(parse_study_text(text))
    assert study.material.E_MPa == 1800.0 and study.material.yield_MPa == 42.5
    assert study.boundary.end.max_mm == 20.0
    assert study.name == "cantilever"  # plain strings stay strings


def test_study_is_frozen():
    study = load_study("cantilever")
    with pytest.raises(Exception):  # noqa: B017 - pydantic's frozen error
        study.name = "other"


def test_study_error_str_is_source_path_problem():
    err = StudyError("geometry.width_mm", "must be\n > 0", source="s.yaml")
    assert str(err) == "s.yaml: geometry.width_mm: must be > 0"
