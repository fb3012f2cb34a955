"""Study kinds from plugin packages (the ``flexopt.kinds`` entry points, docs/plugins.md).

The end-to-end test builds two tiny packages in a temporary folder, installs them with pip
(offline, ``--no-build-isolation``, into a ``--target`` folder: entry points are found from the
``*.dist-info`` folders on ``sys.path``, so a folder on ``PYTHONPATH`` is enough and no venv is
needed) and runs the ``flexopt`` command on them in a subprocess:

- ``flexopt-toy-plugin``, the example of docs/plugins.md (built from its code blocks, so the
  docs cannot drift from what works), names two kinds, one per form of the contract:
  ``toy_spring`` (a module that registers its kind when imported) and ``toy_factory`` (a
  function returning a kind);
- ``flexopt-broken-plugin`` names a kind whose module fails to import and one that takes the
  name of a built-in kind (``cam``).

The contract's other cases (a callable returning the wrong thing, a wrong name, two plugins with
one name) are tested in this process with fake entry points.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import flexopt.pipeline.studies as studies
import pytest
from flexopt.pipeline.cli import main
from flexopt.pipeline.study import load_study, validate_study

# --------------------------------------------------------------------------------------------
# The plugin packages

DOCS = Path(__file__).resolve().parents[2] / "docs" / "plugins.md"


def docs_package() -> dict[str, str]:
    """The example plugin of docs/plugins.md: its code blocks titled with a file name."""
    blocks = re.findall(r'^```\w+ title="([^"]+)"\n(.*?)^```$', DOCS.read_text(), re.M | re.S)
    files = dict(blocks)
    assert set(files) == {
        "pyproject.toml",
        "flexopt_toy_plugin/__init__.py",
        "flexopt_toy_plugin/factory.py",
    }
    return files


BROKEN_PYPROJECT = """\
[build-system]
requires = ["setuptools>=61"]
build-backend = "setuptools.build_meta"

[project]
name = "flexopt-broken-plugin"
version = "0.2.0"

[project.entry-points."flexopt.kinds"]
broken_kind = "flexopt_broken_plugin"
cam = "flexopt_broken_plugin.clash"

[tool.setuptools]
packages = ["flexopt_broken_plugin"]
"""

BROKEN_MODULE = """\
import libfoo_that_is_not_installed  # noqa: F401
"""

CLASH_MODULE = """\
raise RuntimeError("flexopt must not import a plugin that takes a built-in kind's name")
"""


def _package(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


@pytest.fixture(scope="module")
def plugin_path(tmp_path_factory) -> Path:
    """A folder holding both plugin packages, installed by pip (skip when pip cannot build)."""
    root = tmp_path_factory.mktemp("plugins")
    toy = _package(root / "toy", docs_package())
    broken = _package(
        root / "broken",
        {
            "pyproject.toml": BROKEN_PYPROJECT,
            "flexopt_broken_plugin/__init__.py": BROKEN_MODULE,
            "flexopt_broken_plugin/clash.py": CLASH_MODULE,
        },
    )
    target = root / "site"
    pip = [sys.executable, "-m", "pip", "install", "--no-index", "--no-deps"]
    pip += ["--no-build-isolation", "--disable-pip-version-check", "--target", str(target)]
    done = subprocess.run(
        [*pip, str(toy), str(broken)], capture_output=True, text=True, timeout=600
    )
    if done.returncode != 0:  # no setuptools, no pip: not flexopt's failure
        # the line that says why ("invalid command 'bdist_wheel'": setuptools < 70.1 without
        # the wheel package), not pip's closing hint
        lines = [line.strip() for line in done.stderr.splitlines() if "error" in line.lower()]
        why = next((line for line in lines if "invalid command" in line or "No module" in line),
                   lines[0] if lines else "(no output)")  # fmt: skip
        pytest.skip(f"pip cannot build the plugin packages offline here: {why}")
    return target


def flexopt(plugin_path: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess:
    """The ``flexopt`` command, with the plugins' folder on ``PYTHONPATH``."""
    env = {**os.environ, "PYTHONPATH": str(plugin_path)}
    script = Path(sys.executable).with_name("flexopt")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "flexopt.pipeline.cli"]
    return subprocess.run(
        [*command, *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=600
    )


@pytest.mark.slow
@pytest.mark.e2e
def test_plugin_kinds_run_from_the_cli(plugin_path, tmp_path):
    listed = flexopt(plugin_path, tmp_path, "list")
    assert listed.returncode == 0, listed.stderr
    lines = listed.stdout.splitlines()
    toy = next(line for line in lines if line.split()[:1] == ["toy_spring"])
    assert "plugin" in toy and "a toy spring of a given rate (the plugin example" in toy
    assert any(line.split()[:2] == ["toy_factory", "plugin"] for line in lines)
    broken = next(line for line in lines if line.split()[:1] == ["broken_kind"])
    assert "flexopt-broken-plugin" in broken and "ModuleNotFoundError" in broken
    assert "libfoo_that_is_not_installed" in broken
    clash = next(line for line in lines if "'cam = flexopt_broken_plugin.clash'" in line)
    assert "built-in kind" in clash
    cam = next(line for line in lines if line.split()[:1] == ["cam"])
    assert "built-in" in cam  # the built-in cam is untouched
    assert listed.stderr == ""  # a broken plugin says nothing until it is asked for

    # a starter study of the plugin's kind, from its schema, loads and solves as written
    made = flexopt(plugin_path, tmp_path, "init", "spring", "--kind", "toy_spring")
    assert made.returncode == 0, made.stderr
    text = (tmp_path / "spring.yaml").read_text()
    assert "rate_N_per_mm" in text and "spring rate, N/mm" in text
    evaluated = flexopt(plugin_path, tmp_path, "evaluate", "spring.yaml", "--out", "ev")
    assert evaluated.returncode == 0, evaluated.stderr
    record = json.loads((tmp_path / "ev" / "evaluation.json").read_text())
    assert record["kind"] == "toy_spring" and record["summary"]["end_force_N"] == 10.0

    # flexopt run optimises it, on two worker processes (they import the plugin too)
    ran = flexopt(
        plugin_path, tmp_path, "run", "spring.yaml", "--quick", "--workers", "2", "--out", "rn"
    )
    assert ran.returncode == 0, ran.stderr
    best = json.loads((tmp_path / "rn" / "best.json").read_text())
    assert best["kind"] == "toy_spring"
    assert best["parameters"]["rate_N_per_mm"] == pytest.approx(3.0, abs=2.0)

    # the factory form
    (tmp_path / "factory.yaml").write_text(
        "name: f\ngeometry: {kind: toy_factory, rate_N_per_mm: 4}\nmaterial: PLA\n"
    )
    evaluated = flexopt(plugin_path, tmp_path, "evaluate", "factory.yaml", "--out", "f")
    assert evaluated.returncode == 0, evaluated.stderr
    assert "end_force_N" in evaluated.stdout

    # the schema of the plugin kind, and the plugin kinds in the schema of any study
    schema = flexopt(plugin_path, tmp_path, "schema", "--kind", "toy_spring")
    assert schema.returncode == 0, schema.stderr
    assert "rate_N_per_mm" in json.loads(schema.stdout)["$defs"]["ToyGeometry"]["properties"]
    assert (
        "toy_spring" in json.loads(flexopt(plugin_path, tmp_path, "schema").stdout)["description"]
    )


@pytest.mark.slow
def test_a_broken_plugin_is_one_line_only_when_asked_for(plugin_path, tmp_path):
    (tmp_path / "b.yaml").write_text("name: b\ngeometry: {kind: broken_kind}\nmaterial: PLA\n")
    done = flexopt(plugin_path, tmp_path, "evaluate", "b.yaml")
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert "geometry.kind: kind 'broken_kind' is unavailable" in done.stderr
    assert "libfoo_that_is_not_installed" in done.stderr
    assert not (tmp_path / "runs").exists()

    for args in (["init", "x", "--kind", "broken_kind"], ["schema", "--kind", "broken_kind"]):
        refused = flexopt(plugin_path, tmp_path, *args)
        assert refused.returncode == 2 and refused.stderr.count("\n") == 1, refused.stderr
        assert "unavailable" in refused.stderr

    # every other kind still works beside it
    ok = flexopt(plugin_path, tmp_path, "evaluate", "cantilever", "--out", "c")
    assert ok.returncode == 0, ok.stderr
    assert ok.stderr == ""


# --------------------------------------------------------------------------------------------
# The contract, with fake entry points in this process

FAKES = {
    "fake_module_kind": """\
from typing import Literal
from pydantic import BaseModel
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, Study


class G(BaseModel):
    model_config = STUDY_CONFIG
    kind: Literal["fake_module"]


class FakeStudy(Study):
    geometry: G


KIND = StudyKind("fake_module", FakeStudy, lambda study: None, summary="a fake")
register(KIND)
""",
    "fake_objects": """\
from fake_module_kind import FakeStudy
from flexopt.pipeline.studies import StudyKind

KIND = StudyKind("fake_object", FakeStudy, lambda study: None)
NOT_A_KIND = 42


def make():
    return StudyKind("fake_factory", FakeStudy, lambda study: None)


def misnamed():
    return StudyKind("some_other_name", FakeStudy, lambda study: None)


def steals_a_builtin():
    return StudyKind("polyline_beam", FakeStudy, lambda study: None)
""",
    "fake_registers_builtin": """\
from fake_module_kind import FakeStudy
from flexopt.pipeline.studies import StudyKind, register

register(StudyKind("mechanism", FakeStudy, lambda study: None))
""",
    "fake_exits": "raise SystemExit(3)\n",
    # issue 23, class 5: what a hostile or careless plugin does at import and later
    "fake_ctrl_c": "raise KeyboardInterrupt\n",
    "fake_base_exception": "class Boom(BaseException):\n    pass\n\n\nraise Boom('at import')\n",
    "fake_blocks": "import time\n\ntime.sleep(30)\n",
    "fake_not_pydantic": """\
from flexopt.pipeline.studies import StudyKind, register

register(StudyKind("fake_not_pydantic", dict, lambda study: None))
""",
    "fake_faulty": """\
from typing import Literal
from pydantic import BaseModel
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, Study


class G(BaseModel):
    model_config = STUDY_CONFIG
    kind: Literal["fake_faulty"]
    raise_in_check: bool = False


class FaultyStudy(Study):
    geometry: G


def check(study):
    if study.geometry.raise_in_check:
        raise ZeroDivisionError("division by zero in the plugin")


register(StudyKind("fake_faulty", FaultyStudy, check, evaluate=lambda study, repeat: None))
""",
}


@pytest.fixture
def fake_registry(tmp_path, monkeypatch):
    """A copy of the registry and importable fake plugin modules; returns a loader."""
    for name, text in FAKES.items():
        (tmp_path / f"{name}.py").write_text(textwrap.dedent(text))
    monkeypatch.syspath_prepend(str(tmp_path))
    builtin = studies.kinds()
    monkeypatch.setattr(studies, "_KINDS", dict(builtin))
    monkeypatch.setattr(studies, "_UNAVAILABLE", {})
    monkeypatch.setattr(studies, "_REFUSED", [])
    monkeypatch.setattr(studies, "_ORIGINAL", {})

    def load(pairs: list[tuple[str, str]]) -> None:
        eps = [importlib.metadata.EntryPoint(n, v, studies.ENTRY_POINT_GROUP) for n, v in pairs]
        monkeypatch.setattr(studies, "_entry_points", lambda: eps)
        studies._load_plugins()

    yield load
    for name in FAKES:
        sys.modules.pop(name, None)


def test_entry_point_contract(fake_registry):
    fake_registry(
        [
            ("fake_module", "fake_module_kind"),  # a module that registers
            ("fake_object", "fake_objects:KIND"),  # a StudyKind
            ("fake_factory", "fake_objects:make"),  # a callable returning one
            ("not_a_kind", "fake_objects:NOT_A_KIND"),
            ("misnamed", "fake_objects:misnamed"),
            ("no_such_kind", "fake_module_kind"),  # imported, but registers another name
            ("stealer", "fake_objects:steals_a_builtin"),
            ("sneaky", "fake_registers_builtin"),
            ("exits", "fake_exits"),
            ("missing", "no_module_of_this_name"),
            ("sea_spring", "fake_objects:make"),  # a built-in's name: refused, never loaded
            ("fake_module", "fake_objects:make"),  # a second plugin with a taken name
        ]
    )
    kinds = studies.kinds()
    assert {"fake_module", "fake_object", "fake_factory"} <= set(kinds)
    assert studies.kind_summary(kinds["fake_module"]) == "a fake"
    assert kinds["polyline_beam"].model.__name__ == "PolylineBeamStudy"  # not replaced
    assert kinds["mechanism"].model.__name__ == "MechanismStudy"
    bad = studies.unavailable_kinds()
    assert set(bad) == {"not_a_kind", "misnamed", "no_such_kind", "stealer", "sneaky", "exits",
                        "missing"}  # fmt: skip
    assert "gave int, not a StudyKind" in bad["not_a_kind"]
    assert "gave the kind 'some_other_name'" in bad["misnamed"]
    assert "imported but registered no kind named 'no_such_kind';" in bad["no_such_kind"]
    assert "taken by a built-in kind" in bad["stealer"]
    assert "taken by a built-in kind" in bad["sneaky"]
    assert "SystemExit" in bad["exits"]
    assert "ModuleNotFoundError" in bad["missing"]
    assert all("\n" not in reason for reason in bad.values())
    refused = studies.refused_plugins()
    assert len(refused) == 2
    assert "'sea_spring' is a built-in kind" in refused[0]
    assert "another plugin took the kind name 'fake_module'" in refused[1]

    # asked for: one line at geometry.kind; a good plugin kind validates like a built-in one
    with pytest.raises(studies.StudyError, match="kind 'exits' is unavailable: plugin"):
        studies.get_kind("exits")
    study = validate_study({"name": "f", "geometry": {"kind": "fake_module"}, "material": "PLA"})
    assert study.kind == "fake_module"


def test_list_shows_unavailable_plugins(fake_registry, capsys):
    fake_registry([("missing", "no_module_of_this_name"), ("cam", "fake_objects:make")])
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "Unavailable plugin kinds:" in out
    assert any(line.split()[:1] == ["missing"] and "ModuleNotFoundError" in line
               for line in out.splitlines())  # fmt: skip
    assert "'cam = fake_objects:make' refused: 'cam' is a built-in kind" in out


def test_unknown_kind_still_lists_every_kind(fake_registry):
    fake_registry([("fake_object", "fake_objects:KIND")])
    with pytest.raises(studies.StudyError, match="unknown kind 'nope'; use one of .*fake_object"):
        studies.get_kind("nope")


def test_shipped_examples_unaffected(fake_registry):
    fake_registry([("missing", "no_module_of_this_name")])
    assert load_study("cantilever").kind == "polyline_beam"


def test_a_builtin_kind_is_found_without_importing_the_other_kinds():
    # get_kind of a built-in name imports that kind's module only (the start of every run and
    # evaluate); the full discovery afterwards still lists every kind, the same object included,
    # and an unknown name still gets the list of all kinds.
    code = textwrap.dedent(
        """
        import sys
        from flexopt.pipeline.errors import StudyError
        from flexopt.pipeline.studies import builtin_kind_names, get_kind, kinds
        pre = "flexopt.pipeline.studies."
        kind = get_kind("constant_force")
        loaded = sorted(m[len(pre):] for m in sys.modules if m.startswith(pre))
        assert [m for m in loaded if not m.startswith("_")] == ["constant_force"], loaded
        assert kinds()["constant_force"] is kind
        assert {"constant_force", "sea_spring", "mechanism"} <= builtin_kind_names()
        try:
            get_kind("no_such_kind")
        except StudyError as exc:
            assert "sea_spring" in str(exc) and "constant_force" in str(exc), exc
        else:
            raise AssertionError("an unknown kind was accepted")
        print("ok")
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


# --------------------------------------------------------------------------------------------
# Hostile plugins (issue 23, class 5): each disables itself in one line; built-ins always work


def test_a_plugin_raising_any_base_exception_or_blocking_at_import_is_unavailable(
    fake_registry, monkeypatch, capsys
):
    monkeypatch.setattr(studies, "PLUGIN_IMPORT_TIMEOUT_S", 0.5)
    monkeypatch.delenv("FLEXOPT_PLUGIN_TIMEOUT_S", raising=False)
    fake_registry(
        [
            ("fake_ctrl_c", "fake_ctrl_c"),
            ("fake_base_exception", "fake_base_exception"),
            ("fake_blocks", "fake_blocks"),
            ("fake_not_pydantic", "fake_not_pydantic"),
            ("fake_module", "fake_module_kind"),  # a good plugin beside them still loads
        ]
    )
    bad = studies.unavailable_kinds()
    assert "KeyboardInterrupt" in bad["fake_ctrl_c"]
    assert "Boom: at import" in bad["fake_base_exception"]
    # not hung: the plugin that sleeps 30 s at import was given up on at its 0.5 s limit
    assert "did not finish importing within 0.5 s" in bad["fake_blocks"]
    assert "not a pydantic subclass of pipeline.study.Study" in bad["fake_not_pydantic"]
    assert all("\n" not in reason for reason in bad.values())
    assert "fake_module" in studies.kinds() and "fake_not_pydantic" not in studies.kinds()

    # list, schema and init work, the broken ones named in list only
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "fake_blocks" in out and "fake_module" in out
    assert main(["schema"]) == 0 and main(["schema", "--kind", "fake_module"]) == 0
    assert main(["schema", "--kind", "fake_not_pydantic"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unavailable" in err and "Traceback" not in err
    # built-in kinds are untouched
    assert load_study("cantilever").kind == "polyline_beam"


def test_a_plugin_kind_failing_in_check_or_evaluate_is_one_line(
    fake_registry, tmp_path, monkeypatch, capsys
):
    fake_registry([("fake_faulty", "fake_faulty")])
    assert "fake_faulty" in studies.kinds()
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    raising = work / "raising.yaml"
    raising.write_text(
        "name: r\ngeometry: {kind: fake_faulty, raise_in_check: true}\nmaterial: PLA\n"
    )
    none = work / "none.yaml"
    none.write_text("name: n\ngeometry: {kind: fake_faulty}\nmaterial: PLA\n")
    for path, fragment in (
        (raising, "failed in its check: ZeroDivisionError: division by zero in the plugin"),
        (none, "evaluate returned NoneType, not an EvaluationResult"),
    ):
        assert main(["evaluate", str(path)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err, err
        assert "geometry.kind" in err and fragment in err, err
    assert sorted(p.name for p in work.iterdir()) == ["none.yaml", "raising.yaml"]
