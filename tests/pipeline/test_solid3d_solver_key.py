"""The ``solid_3d: {solver: ...}`` key of the sea_spring and threshold_spring studies: the 3D
check's solver (fea.solid3d.Solid3DSettings.solver; docs/solid3d.md, "Memory"), validated
(an unknown value or "cholmod" without the cholmod extra is one line naming the key path,
exit 2) and passed to the 3D model. Small models only: one coarse threshold-spring check and
the SEA hook up to its model's settings.

Units: mm, N, MPa, N·mm, rad.
"""

from __future__ import annotations

import sys

import flexopt.pipeline.studies.sea_spring as ss
import flexopt.pipeline.studies.threshold_spring as ts
import numpy as np
import pytest
from flexopt.fea.errors import FeaError
from flexopt.fea.solid3d import cholmod_available
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.study import load_study, study_to_yaml, validate_study

SEA = {
    "name": "sea-3d-solver",
    "geometry": {"kind": "sea_spring", "topology": "spiral", "n_sets": 4},
    "material": "maraging-300",
    "taguchi": {"enabled": False},
    "mesh": {"max_edge_mm": 6.0, "elements_through": 0.5, "fillet_segments": 1},
    "design": {"sweep": 300.0, "R_pad": 30.0, "F1": 1 / 3, "F2": 0.5,
               "W1": 3.0, "W2": 2.5, "W3": 2.5, "W4": 3.0},
    "solid_3d": {"converge_peak": False, "max_checks": 2, "layers": 1},
}  # fmt: skip
CHOICES = "'auto', 'multigrid', 'cholmod', 'qdldl' or 'superlu'"


def _sea(**solid_3d):
    return validate_study({**SEA, "solid_3d": {**SEA["solid_3d"], **solid_3d}})


def _threshold(**solid_3d):
    raw = load_study("threshold-spring").model_dump(mode="json", exclude_none=True)
    # coarse (as tests/pipeline/test_threshold_spring_solid3d.py): seconds, not minutes
    raw["fidelity"] = {"max_edge_mm": 6.0, "elements_through": 0.5, "fillet_segments": 1,
                       "steps": 2}  # fmt: skip
    raw["solid_3d"] = {"layers": 1, "correct": False, "converge_peak": False, **solid_3d}
    return validate_study(raw)


@pytest.mark.parametrize("solver", ["auto", "multigrid", "qdldl", "superlu", "cholmod"])
def test_the_key_takes_each_solver_and_dumps_only_a_chosen_one(solver):
    if solver == "cholmod" and not cholmod_available():
        pytest.skip("the cholmod extra (cvxopt) is not installed")
    study = _sea(solver=solver)
    assert study.solid_3d.solver == solver
    dumped = study.model_dump(mode="json")["solid_3d"]
    # "auto" is the default and dumps as before the key existed: run folders stay the same
    assert dumped.get("solver") == (None if solver == "auto" else solver)
    assert ("solver:" in study_to_yaml(study)) == (solver != "auto")
    assert validate_study(study.model_dump(mode="json")).solid_3d.solver == solver


def test_the_default_is_auto_for_both_kinds():
    assert _sea().solid_3d.solver == "auto"
    assert load_study("threshold-spring").solid_3d.solver == "auto"
    assert load_study("sea-spring").solid_3d.solver == "auto"


@pytest.mark.parametrize("build", [_sea, _threshold])
def test_an_unknown_solver_names_the_key_and_the_choices(build):
    with pytest.raises(StudyError) as err:
        build(solver="fast")
    line = str(err.value)
    assert "\n" not in line
    assert line.startswith("solid_3d.solver: got 'fast'") and CHOICES in line


def test_an_unknown_solver_exits_2_with_one_line(tmp_path, monkeypatch, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text(
        "name: bad\ngeometry: {kind: sea_spring, topology: spiral, n_sets: 4}\n"
        "material: maraging-300\nsolid_3d: {solver: fast}\n"
    )
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "solid_3d.solver: got 'fast'" in err[0] and CHOICES in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.yaml"]  # nothing written


def test_cholmod_without_the_extra_says_to_install_it_or_pick_another(monkeypatch):
    monkeypatch.setitem(sys.modules, "cvxopt", None)  # a plain install: `import cvxopt` fails
    assert not cholmod_available()
    for build in (_sea, _threshold):
        with pytest.raises(StudyError) as err:
            build(solver="cholmod")
        line = str(err.value)
        assert line.startswith("solid_3d.solver: 'cholmod' needs CHOLMOD")
        assert "install the cholmod extra" in line and "multigrid" in line
    assert _sea(solver="multigrid").solid_3d.solver == "multigrid"  # the others still go


@pytest.mark.parametrize("solver", ["qdldl", "superlu"])
def test_threshold_spring_check_runs_the_chosen_solver(solver):
    """A real (coarse, one-layer) 3D check: the record names the solver that ran ("auto"
    would be CHOLMOD with the cholmod extra, else QDLDL at this size; the multigrid solve
    itself is tested in tests/fea/test_solid3d_multigrid.py)."""
    study = _threshold(solver=solver)
    prob = ts.problem(study)
    d = prob.detail(prob.space.clip(ts.design_vector(study)))
    s3 = d.info["solid_3d"]
    assert "problem" not in s3, s3
    assert [c["solver"] for c in s3["checks"]] == [solver]


def test_sea_spring_check_builds_its_model_with_the_chosen_solver(monkeypatch):
    """The SEA hook (fea.sea_design.correct_3d) hands the key to Solid3DSettings: the model's
    settings are caught, and the check stops there (its solve is tested in
    tests/pipeline/test_sea_spring_solid3d.py)."""
    import flexopt.fea.solid3d as s3d

    seen = []

    class Spy:
        def __init__(self, mesh, material, clamp, drive, settings, stress_ignore=None, **kw):
            seen.append(settings)
            raise FeaError("stopped by the test")

    monkeypatch.setattr(s3d, "Solid3DModel", Spy)
    study = _sea(solver="qdldl")
    prob = ss.SeaSpringProblem(study, stage1={})
    x = np.delete(ss.design_vector(study), prob.names.index("ST"))
    _, geom, r, _ = prob.solve(x, 1)
    out = prob.solid_3d(geom, r)
    assert out == {"problem": "3D check not made: stopped by the test"}
    assert [(s.solver, s.layers) for s in seen] == [("qdldl", 1)]
