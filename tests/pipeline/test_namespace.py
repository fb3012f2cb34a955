"""flexopt installs as ONE namespace (issue 14, "Done when"): a user can install it beside
packages named ``geometry``, ``pipeline``, ``fea`` and ``optimise`` (PyPI has the first three)
and both work.

In a fresh interpreter whose path starts with a folder of such packages, every module of
flexopt is imported and a built-in study is evaluated through the public API; the packages of
that folder must still be the ones imported. And the installed distribution must put nothing at
top level but ``flexopt``.
"""

from __future__ import annotations

import ast
import importlib.metadata
import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LAYERS = ("geometry", "pipeline", "fea", "optimise")

#: Optional dependencies (extras); a module that needs one that is not installed is skipped,
#: but only when the ImportError names that dependency.
OPTIONAL = ("distributed", "dask", "build123d", "OCP", "cvxopt", "pypardiso", "pandas")

WALK = r"""
import importlib, json, pkgutil, sys
LAYERS, OPTIONAL = {layers!r}, {optional!r}

import flexopt

imported, skipped = [], []

def load(name):
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        missing = (exc.name or "").split(".")[0]
        if missing in OPTIONAL:
            skipped.append(f"{{name}} (needs {{missing}})")
            return None
        raise

packages = [flexopt] + [importlib.import_module(f"flexopt.{{layer}}") for layer in LAYERS]
for package in packages:
    for info in pkgutil.walk_packages(package.__path__, package.__name__ + ".", onerror=load):
        # an editable install maps flexopt.pipeline to pipeline/, whose api/ is flexopt itself
        if info.name == "flexopt.pipeline.api" or info.name.startswith("flexopt.pipeline.api."):
            continue
        if load(info.name) is not None:
            imported.append(info.name)

# with the clamp's Kt stated, every row of the cantilever is judged (docs/beam.md)
study = flexopt.load_study("cantilever").with_values({{"boundary.clamp_kt": 1.5}})
result = flexopt.evaluate(study)
fakes = {{layer: getattr(importlib.import_module(layer), "MARKER", None) for layer in LAYERS}}
strays = sorted(m for m in sys.modules if m.split(".")[0] in LAYERS and m not in LAYERS)
print(json.dumps({{
    "imported": imported, "skipped": skipped, "fakes": fakes, "strays": strays,
    "met": result.met, "rows": len(result.table["force_N"]),
}}))
"""


def test_flexopt_works_beside_packages_named_like_its_layers(tmp_path: Path) -> None:
    fakes = tmp_path / "site"
    for layer in LAYERS:
        (fakes / layer).mkdir(parents=True)
        (fakes / layer / "__init__.py").write_text(f'MARKER = "fake {layer}"\n', encoding="utf-8")
    script = tmp_path / "walk.py"
    script.write_text(WALK.format(layers=LAYERS, optional=OPTIONAL), encoding="utf-8")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(fakes), os.environ.get("PYTHONPATH", "")) if p
    )
    done = subprocess.run(
        [sys.executable, str(script)],
        cwd=tmp_path,  # not the repository: its geometry/ ... must not be found by the cwd
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    found = json.loads(done.stdout.strip().splitlines()[-1])
    assert found["fakes"] == {layer: f"fake {layer}" for layer in LAYERS}
    assert found["strays"] == []  # no geometry.solid, pipeline.run, ... from anywhere
    assert found["met"] is True and found["rows"] == 21
    imported = set(found["imported"])
    # every module of the source tree was imported (or skipped for a missing extra)
    expected = {"flexopt._api", "flexopt._result"}
    for layer in LAYERS:
        for path in (ROOT / layer).rglob("*.py"):
            rel = path.relative_to(ROOT / layer).with_suffix("")
            if rel.parts[0] == "api" or "__pycache__" in rel.parts:
                continue
            parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
            if rel.name != "__init__" or parts:
                expected.add(".".join(("flexopt", layer, *parts)))
    skipped = {entry.split(" ")[0] for entry in found["skipped"]}
    assert expected - imported - skipped == set()
    assert len(imported) > 60


def test_the_distribution_installs_nothing_but_flexopt_at_top_level() -> None:
    # the installed distribution, not the flexopt.egg-info a build leaves in the source tree
    # (the repository root is on sys.path here: tests/conftest.py)
    paths = [p for p in sys.path if Path(p or ".").resolve() != ROOT]
    found = list(importlib.metadata.distributions(name="flexopt", path=paths))
    if not found:
        pytest.skip("flexopt is not installed (a source checkout run in place)")
    dist = found[0]
    top_level = dist.read_text("top_level.txt")
    if top_level is not None:
        assert top_level.split() == ["flexopt"]
    tops = set()
    editable = False
    for file in dist.files or ():
        first = file.parts[0]
        if first == ".." or first == "__pycache__" or first.endswith((".dist-info", ".egg-info")):
            continue  # the console script in bin/, caches, the metadata
        if first.startswith("__editable__"):  # the editable install's .pth and finder
            editable = True
            continue
        tops.add(first.removesuffix(".py"))
    if editable:
        # an editable install maps names to the source tree: only flexopt and its layers
        finder = next(
            f for f in dist.files if f.name.startswith("__editable__") and f.suffix == ".py"
        )
        mapping = _editable_mapping(Path(dist.locate_file(finder)))
        assert {name.split(".")[0] for name in mapping} == {"flexopt"}
        assert tops <= {"flexopt"}
    else:
        assert tops == {"flexopt"}


def _editable_mapping(finder: Path) -> dict[str, str]:
    """The MAPPING of setuptools' editable finder module (names -> source folders)."""
    for line in finder.read_text(encoding="utf-8").splitlines():
        if line.startswith("MAPPING"):
            return ast.literal_eval(line.split("=", 1)[1].strip())  # written by setuptools
    raise AssertionError(f"{finder} has no MAPPING")


def test_the_wheel_maps_every_package_under_flexopt() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    setuptools = config["tool"]["setuptools"]
    assert all(p == "flexopt" or p.startswith("flexopt.") for p in setuptools["packages"])
    assert all(p.startswith("flexopt") for p in setuptools["package-dir"])
    # every package folder of the source tree is listed (else the wheel would leave it out)
    listed = set(setuptools["packages"])
    for layer in LAYERS:
        for init in (ROOT / layer).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / layer).parts
            if rel[:1] == ("api",):
                rel = rel[1:]
                name = ".".join(("flexopt", *rel))
            else:
                name = ".".join(("flexopt", layer, *rel))
            assert name in listed, f"{init.parent} is not in pyproject's packages"
