"""A new built-in study kind is one new module in pipeline/studies/ and touches no other file, as
pipeline/studies/__init__.py promises.

The proof: a kind module written to a temporary folder that joins the package's search path
(``flexopt.pipeline.studies.__path__``: the package itself is not written to), and every command
a user would run on its study, in a fresh process: ``list`` shows it among the built-in kinds,
``schema`` and ``init`` write its study, ``evaluate`` solves the study's design and ``run
--quick`` optimises it, each with the files of its folder. The module holds only what a kind is:
its schema, its problem and its requirements.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = [pytest.mark.e2e, pytest.mark.slow]

KIND_MODULE = '''
"""Study kind ``toy_builtin``: a linear spring of a given rate (a new built-in kind's test)."""

from typing import Literal

import numpy as np
from pydantic import BaseModel, Field

from flexopt.optimise import DesignProblem, DesignResult, DesignSpace, Evaluation
from flexopt.optimise.requirements import MaxValue
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study


class ToyGeometry(BaseModel):
    """The ``geometry:`` block of a ``toy_builtin`` study."""

    model_config = STUDY_CONFIG

    kind: Literal["toy_builtin"]
    rate_N_per_mm: float = Field(2.0, gt=0, description="spring rate, N/mm")
    stroke_mm: float = Field(5.0, gt=0, description="stroke, mm")


class ToyStudy(Study):
    geometry: ToyGeometry
    optimiser: OptimiserSpec = OptimiserSpec(pop_size=6, n_gen=2, seed=3)


class ToyProblem(DesignProblem):
    objective_names = ("rate_error",)
    constraint_names = ()
    space = DesignSpace(("rate_N_per_mm",), np.array([0.5]), np.array([5.0]))

    def __init__(self, study):
        self.study = study

    def evaluate(self, x):
        rate = float(x[0])
        end = rate * self.study.geometry.stroke_mm
        return Evaluation(np.array(x), np.array([(rate - 3.0) ** 2]), np.zeros(0),
                          {"end_force_N": end})

    def detail(self, x):
        d = np.linspace(0.0, self.study.geometry.stroke_mm, 6)
        table = {"displacement_mm": d, "force_N": float(x[0]) * d}
        return DesignResult(self.evaluate(x), table, {"x": "displacement_mm", "y": "force_N"})


def check(study):
    pass


register(
    StudyKind(
        "toy_builtin",
        ToyStudy,
        check,
        problem=ToyProblem,
        requirements=lambda study: [MaxValue("end_force_N", "end force", "check", 100.0)],
        quantities=("end_force_N", "force_N", "displacement_mm"),
    )
)
'''

#: Runs the CLI with the folder ``argv[1]`` on the package's search path, as if the module were
#: in pipeline/studies/ (fork start method: the run's workers inherit the path).
RUNNER = textwrap.dedent(
    """
    import sys
    import flexopt.pipeline.studies as studies
    studies.__path__.append(sys.argv[1])
    from flexopt.pipeline.cli import main
    sys.exit(main(sys.argv[2:]))
    """
)


def flexopt(kind_dir: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", RUNNER, str(kind_dir), *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_a_new_builtin_kind_is_one_module(tmp_path: Path) -> None:
    kind_dir = tmp_path / "kinds"
    kind_dir.mkdir()
    (kind_dir / "toy_builtin.py").write_text(KIND_MODULE, encoding="utf-8")
    work = tmp_path / "work"
    work.mkdir()

    listed = flexopt(kind_dir, work, "list")
    assert listed.returncode == 0, listed.stderr
    builtin = listed.stdout.split("Built-in studies")[0]
    assert "toy_builtin" in builtin and "linear spring of a given rate" in builtin
    assert "plugin" not in listed.stdout.split("toy_builtin")[1].splitlines()[0]

    schema = flexopt(kind_dir, work, "schema", "--kind", "toy_builtin", "--out", "s.json")
    assert schema.returncode == 0, schema.stderr
    assert "rate_N_per_mm" in json.dumps(json.loads((work / "s.json").read_text()))

    init = flexopt(kind_dir, work, "init", "spring", "--kind", "toy_builtin")
    assert init.returncode == 0, init.stderr
    assert "kind: toy_builtin" in (work / "spring.yaml").read_text()

    ev = flexopt(kind_dir, work, "evaluate", "spring.yaml", "--out", "ev")
    assert ev.returncode == 0, ev.stderr
    record = json.loads((work / "ev" / "evaluation.json").read_text())
    assert record["verdict"]["overall"] == "MET", record["verdict"]
    assert record["summary"]["end_force_N"] == pytest.approx(10.0)  # the study's rate 2 N/mm
    assert (work / "ev" / "force_displacement.png").stat().st_size > 0

    run = flexopt(kind_dir, work, "run", "spring.yaml", "--quick", "--workers", "1", "--out", "rn")
    assert run.returncode == 0, run.stderr
    best = json.loads((work / "rn" / "best.json").read_text())
    assert best["verdict"]["overall"] == "MET"
    for name in ("report.md", "report.html", "force_displacement.png", "best_response.csv"):
        assert (work / "rn" / name).exists(), name
