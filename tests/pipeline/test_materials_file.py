"""User materials from a materials.yaml beside the study or the user's file (issue #26)."""

import subprocess
import sys

import pytest
import yaml
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.materials_file import ENV_VAR, read_materials_file
from flexopt.pipeline.study import load_study

MY_PETG = {
    "my-petg": {
        "E_MPa": 1823.7,
        "nu": 0.38,
        "yield_MPa": 50.0,
        "density_kg_m3": 1270.0,
        "thickness_offset_mm": -0.057,
        "source": "calibrated from coupon.csv",
    }
}


@pytest.fixture(autouse=True)
def _no_user_file(monkeypatch, tmp_path_factory):
    # the developer's own ~/.config/flexopt/materials.yaml must not leak into the tests
    monkeypatch.setenv(ENV_VAR, str(tmp_path_factory.mktemp("nouser") / "none.yaml"))


def _valid_study_text():
    # the cantilever example's layout, so STUDY stays a study the current schema accepts
    from flexopt.pipeline.study import resolve_study_path

    return resolve_study_path("cantilever").read_text()


def test_material_beside_the_study_is_used(tmp_path):
    path = tmp_path / "study.yaml"
    text = _valid_study_text()
    raw = yaml.safe_load(text)
    raw["material"] = "My_PETG"  # case, '-' and '_' ignored, as for library names
    path.write_text(yaml.safe_dump(raw))
    (tmp_path / "materials.yaml").write_text(yaml.safe_dump(MY_PETG))
    study = load_study(path)
    assert study.material.E_MPa == 1823.7
    assert study.material.name == "my-petg"
    assert "materials.yaml" in study.material.source
    # the offset is named, and what is done with it: the study analyses the part as printed
    assert "applied to every printed section" in study.material.source
    assert study.material.thickness_offset_mm == -0.057


def test_user_file_from_the_environment(tmp_path, monkeypatch):
    user = tmp_path / "mine.yaml"
    user.write_text(yaml.safe_dump(MY_PETG))
    monkeypatch.setenv(ENV_VAR, str(user))
    raw = yaml.safe_load(_valid_study_text())
    raw["material"] = "my-petg"
    (tmp_path / "s").mkdir()
    path = tmp_path / "s" / "study.yaml"
    path.write_text(yaml.safe_dump(raw))
    assert load_study(path).material.E_MPa == 1823.7


def test_library_names_win_and_cannot_be_taken(tmp_path):
    bad = tmp_path / "materials.yaml"
    bad.write_text(yaml.safe_dump({"pla": {"E_MPa": 1.0, "nu": 0.3, "yield_MPa": 0.5}}))
    with pytest.raises(StudyError, match="built-in material 'PLA'"):
        read_materials_file(bad)
    # a study naming a library material never reads the file (a damaged file beside it is fine)
    bad.write_text("{{{ not yaml")
    raw = yaml.safe_load(_valid_study_text())
    raw["material"] = "PLA"
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(raw))
    assert load_study(path).material.name == "PLA"


@pytest.mark.parametrize(
    "content, match",
    [
        ("{{{ not yaml", "not valid UTF-8 YAML"),
        ("- a list", "mapping of material names"),
        ("m: {E_MPa: 1000, nu: 0.3}", r"m\.yield_MPa.*missing"),
        ("m: {E_MPa: big, nu: 0.3, yield_MPa: 10}", r"m\.E_MPa.*number"),
        ("m: {E_MPa: 1000, nu: 0.3, yield_MPa: 10, colour: red}", r"m\.colour.*unknown key"),
        ("m: {E_MPa: .nan, nu: 0.3, yield_MPa: 10}", "finite"),
        ("m: {nu: 0.3, yield_MPa: 10}", r"m\.E_MPa.*missing.*E_x_MPa and E_y_MPa"),
        ("m: {E_x_MPa: 1000, nu: 0.3, yield_MPa: 10}", r"m\.E_x_MPa.*both"),
        ("m: {E_x_MPa: 1000, E_y_MPa: big, nu: 0.3, yield_MPa: 10}", r"m\.E_y_MPa.*number"),
        ("m: {E_MPa: 1000, nu: 0.3, yield_MPa: 10, thickness_offset_mm: 3}", "thickness_offset"),
    ],
)
def test_damaged_materials_file_is_one_clear_error(tmp_path, content, match):
    (tmp_path / "materials.yaml").write_text(content)
    raw = yaml.safe_load(_valid_study_text())
    raw["material"] = "m"
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(StudyError, match=match) as info:
        load_study(path)
    assert "materials.yaml" in str(info.value)


def test_unknown_material_names_the_materials_file(tmp_path):
    raw = yaml.safe_load(_valid_study_text())
    raw["material"] = "my-petg"
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(StudyError, match="materials.yaml"):
        load_study(path)


def test_cli_exit_2_one_line_for_a_damaged_materials_file(tmp_path):
    (tmp_path / "materials.yaml").write_text("m: {E_MPa: 1000, nu: 0.3}")
    raw = yaml.safe_load(_valid_study_text())
    raw["material"] = "m"
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(raw))
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "flexopt.pipeline.cli",
            "evaluate",
            str(path),
            "--out",
            str(tmp_path / "out"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "yield_MPa" in lines[0] and "Traceback" not in proc.stderr
