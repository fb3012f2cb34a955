"""`flexopt run` and `flexopt export` end to end, on an analytic toy kind registered here.

The toy kind ``toy_quadratic`` minimises (a - 1.2)^2 + (b - 0.7)^2 subject to a + b <= 1.5 over
[0, 2]^2 (optimum a = 1.0, b = 0.5, f = 0.08) and describes its best design with a synthetic
force table, deformed shapes and a rectangle outline, so every file of a run folder is exercised
in well under a second per run.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest
import trimesh
from flexopt.optimise import DesignDetail, DesignSpace, Evaluation
from flexopt.pipeline.cli import format_generation, main
from flexopt.pipeline.report import render_info
from flexopt.pipeline.run import (
    RUN_FILES,
    Evaluator,
    GenerationReport,
    evaluate_batch,
    evaluate_one,
    prepare_run,
    run_study,
    step_available,
)
from flexopt.pipeline.runfolder import read_records_csv
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study, validate_study
from pydantic import BaseModel, Field
from shapely.geometry import box

# --------------------------------------------------------------------------------------------
# The toy kind


class ToyGeometry(BaseModel):
    model_config = STUDY_CONFIG

    kind: Literal["toy_quadratic"]
    height_mm: float = Field(4.0, gt=0)
    fail_above_a: float | None = None  # evaluate raises for a > this
    interrupt_after: int | None = None  # evaluate raises KeyboardInterrupt at this call
    two_objectives: bool = False  # also minimise the area of the outline
    detail_fails: bool = False  # detail raises (a kind bug must not lose the run)
    seed_optimum: bool = False  # initial_designs() puts the optimum into the first population


class ToyStudy(Study):
    geometry: ToyGeometry
    optimiser: OptimiserSpec = OptimiserSpec()


@dataclass
class ToyProblem:
    geometry: ToyGeometry
    space: DesignSpace = field(
        default_factory=lambda: DesignSpace(("a_mm", "b_mm"), np.zeros(2), np.full(2, 2.0))
    )
    objective_names: tuple[str, ...] = ("error_N",)
    constraint_names: tuple[str, ...] = ("sum_excess_mm",)
    calls: int = 0

    @classmethod
    def from_study(cls, study: ToyStudy) -> ToyProblem:
        if study.geometry.two_objectives:
            return cls(study.geometry, objective_names=("error_N", "area_mm2"))
        return cls(study.geometry)

    def initial_designs(self) -> np.ndarray | None:
        return np.array([[1.0, 0.5]]) if self.geometry.seed_optimum else None

    def evaluate(self, x: np.ndarray) -> Evaluation:
        self.calls += 1
        if self.geometry.interrupt_after is not None and self.calls > self.geometry.interrupt_after:
            raise KeyboardInterrupt
        a, b = x
        if self.geometry.fail_above_a is not None and a > self.geometry.fail_above_a:
            raise RuntimeError(f"cannot build: a_mm = {a:.3f} too large")
        f = (a - 1.2) ** 2 + (b - 0.7) ** 2
        # "error_N" is also an objective name: the CSV must keep both columns apart
        metrics = {"sum_mm": a + b, "error_N": f, "label": "ok"}
        objectives = [f, (10 + 5 * a) * (3 + 2 * b)][: len(self.objective_names)]
        return Evaluation(np.array(x), np.array(objectives), np.array([a + b - 1.5]), metrics)

    def detail(self, x: np.ndarray) -> DesignDetail:
        if self.geometry.detail_fails:
            raise ZeroDivisionError("detail is broken")
        a, b = x
        d = np.linspace(0.0, 10.0, 11)
        table = {
            "displacement_mm": d,
            "force_N": 2.0 * (1.0 - np.exp(-d / (0.5 + a))),
            "peak_stress_MPa": 2.5 * d,
        }
        s = np.linspace(0.0, 20.0, 5)
        shapes = np.array([np.column_stack([s, k * 0.02 * s**2 / 20]) for k in d])
        info = {
            "fidelity_ratio": 1.01,
            "notes": "analytic toy problem, no physics",
            "checks": {"mesh_ok": True, "dofs": 123},
            "steps": [{"k": 0, "F_N": 0.0}, {"k": 1, "F_N": 1.5}],
            "warnings": ["first warning", "second warning"],
            "big": np.zeros((500, 3)),
        }
        return DesignDetail(
            self.evaluate(x),
            table,
            {
                "x": "displacement_mm",
                "y": "force_N",
                "stress": "peak_stress_MPa",
                "target": 2.0,
                "tolerance": 0.2,
                "band_x": [3.0, 10.0],
                "allowable_MPa": 20.0,
                "xlabel": "stroke (mm)",
            },
            shapes,
            box(0.0, 0.0, 10.0 + 5.0 * a, 3.0 + 2.0 * b),
            self.geometry.height_mm,
            info,
            field_map={
                "points_mm": [[0.0, 0.0], [10.0, 0.0], [10.0, 3.0], [0.0, 3.0]],
                "triangles": [[0, 1, 2], [0, 2, 3]],
                "values": [0.0, 5.0 * a, 25.0, 10.0 * b],
                "label": "toy stress (MPa)",
                "limit": 20.0,
            },
        )


register(
    StudyKind(
        "toy_quadratic",
        ToyStudy,
        check=lambda study: None,
        evaluate=None,
        problem=ToyProblem.from_study,  # type: ignore[arg-type]
    )
)

TOY = {
    "name": "toy",
    "geometry": {"kind": "toy_quadratic"},
    "material": "PLA",
    "optimiser": {"pop_size": 8, "n_gen": 4, "seed": 3, "quick_pop_size": 4, "quick_n_gen": 2},
}


def write_study(tmp_path: Path, **geometry: Any) -> Path:
    data = json.loads(json.dumps(TOY))
    data["geometry"].update(geometry)
    path = tmp_path / "toy.yaml"
    path.write_text(json.dumps(data))  # JSON is YAML
    return path


def run_toy(tmp_path: Path, name: str = "run", seed: int | None = None, **geometry: Any):
    study = validate_study(
        json.loads(json.dumps({**TOY, "geometry": {**TOY["geometry"], **geometry}}))
    )
    return run_study(prepare_run(study, seed=seed), out=tmp_path / name)


# --------------------------------------------------------------------------------------------
# Evaluating designs


def test_evaluator_never_solves_a_design_twice():
    problem = ToyProblem(ToyGeometry(kind="toy_quadratic"))
    evaluator = Evaluator(problem)
    X = np.array([[1.0, 0.5], [0.2, 0.3], [1.0, 0.5]])
    first = evaluator.map(X)
    assert problem.calls == 2 and evaluator.n_cache_hits == 1 and len(evaluator.solved) == 2
    assert first[0] is first[2]
    again = evaluator.map(X[:2])
    assert problem.calls == 2 and evaluator.n_cache_hits == 3
    assert [e.f[0] for e in again] == [e.f[0] for e in first[:2]]
    assert first[0].f[0] == pytest.approx(0.08) and first[0].feasible and first[0].time_s > 0


def test_failures_become_infeasible_evaluations_with_a_reason():
    class Broken:
        space = DesignSpace(("a",), np.zeros(1), np.ones(1))
        objective_names = ("f",)
        constraint_names = ("g1", "g2")

        def evaluate(self, x):
            if x[0] < 0.25:
                raise ValueError("mesh\nfailed")
            if x[0] < 0.5:
                return Evaluation(x, np.array([np.nan]), np.zeros(2))
            if x[0] < 0.75:
                return Evaluation(x, np.array([1.0]), np.zeros(3))
            return "not an evaluation"

        def detail(self, x):
            raise NotImplementedError

    out = evaluate_batch(Broken(), np.array([[0.1], [0.3], [0.6], [0.9]]))
    assert [e.reason.split(":")[0] for e in out] == [
        "ValueError",
        "non-finite result (f = [nan], g = [0.0, 0.0])",
        "ValueError",
        "TypeError",
    ]
    assert out[0].reason == "ValueError: mesh failed"  # one line
    assert all(not e.feasible and e.f.shape == (1,) and e.g.shape == (2,) for e in out)
    assert evaluate_one(Broken(), np.array([0.1])).reason == out[0].reason


# --------------------------------------------------------------------------------------------
# flexopt run


def test_run_writes_every_file(tmp_path, capsys):
    study = write_study(tmp_path)
    out = tmp_path / "run"
    assert main(["run", str(study), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert str(out) in captured.out and "a_mm" in captured.out
    gen_lines = [line for line in captured.err.splitlines() if line.startswith("gen ")]
    assert len(gen_lines) == 4 and gen_lines[-1].startswith("gen 4/4  best ")
    assert "eval/s" in gen_lines[-1] and "feasible" in gen_lines[-1]
    assert "warning" not in captured.err
    # every file (front.png only with several objectives, best.step only with the step extra,
    # stress_deformed.png only with a field that carries its displacement: this toy's has none);
    # no temp files either
    absent = {"front.png", "stress_deformed.png", "best_3d.vtu"}  # best_3d.vtu: no 3D check
    absent |= set() if step_available() else {"best.step"}
    files = sorted(p.name for p in out.iterdir() if p.name != "best_steps")
    assert files == sorted(set(RUN_FILES) - absent)
    steps = list((out / "best_steps").iterdir())  # best.pvd's load steps
    assert steps and all(p.suffix == ".vtu" for p in steps)

    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "finished" and record["error"] == ""
    assert record["seed"] == 3 and record["quick"] is False
    assert record["optimiser"] == {"algorithm": "ga", "pop_size": 8, "n_gen": 4, "seed": 3}
    assert record["command_line"].startswith("flexopt run ")
    assert record["evaluations_per_s"] > 0 and record["wall_s"] > 0
    assert {"pymoo", "numpy", "python"} <= set(record["versions"])
    assert record["started"] <= record["finished"]

    rows = read_records_csv(out / "evaluations.csv")
    header = list(rows[0])
    assert header[:4] == ["generation", "index", "a_mm", "b_mm"]
    assert header[4:7] == ["error_N", "sum_excess_mm", "feasible"]
    assert header[-2:] == ["reason", "time_s"]
    assert {"sum_mm", "metric_error_N", "label"} <= set(header)
    assert len(rows) == record["n_evaluations"] == 8 * 4 - record["n_cache_hits"]
    assert [int(r["index"]) for r in rows] == list(range(len(rows)))
    assert sorted({int(r["generation"]) for r in rows}) == [1, 2, 3, 4]
    for r in rows:
        a, b = float(r["a_mm"]), float(r["b_mm"])
        assert float(r["error_N"]) == pytest.approx((a - 1.2) ** 2 + (b - 0.7) ** 2, rel=1e-8)
        assert r["feasible"] == ("true" if a + b <= 1.5 else "false")

    history = read_records_csv(out / "history.csv")
    assert [int(h["generation"]) for h in history] == [1, 2, 3, 4]
    assert list(history[0]) == [
        "generation",
        "n_evaluations",
        "n_cache_hits",
        "best_error_N",
        "best_feasible",
        "feasible_fraction",
        "evaluations_per_s",
        "wall_s",
    ]
    best_per_gen = [float(h["best_error_N"]) for h in history if h["best_feasible"] == "true"]
    assert best_per_gen == sorted(best_per_gen, reverse=True)  # elitist: never worse

    best = json.loads((out / "best.json").read_text())
    assert set(best["parameters"]) == {"a_mm", "b_mm"} and best["feasible"] is True
    assert best["objectives"]["error_N"] == pytest.approx(min(best_per_gen))
    row = rows[best["index"]]
    assert float(row["a_mm"]) == best["parameters"]["a_mm"]  # full precision in the CSV
    assert best["info"]["checks"] == {"mesh_ok": True, "dofs": 123}

    response = read_records_csv(out / "best_response.csv")
    assert list(response[0]) == ["displacement_mm", "force_N", "peak_stress_MPa"]
    assert len(response) == 11
    for png in ("force_displacement.png", "stress.png", "convergence.png", "shapes.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    mesh = trimesh.load(out / "best.stl")
    assert mesh.is_watertight

    report = (out / "report.md").read_text()
    for needle in (
        "# toy — flexopt run",
        "![Force–displacement of the best design](force_displacement.png)",
        "(stress.png)",
        "(convergence.png)",
        "(shapes.png)",
        "| fidelity_ratio | 1.01 |",
        "analytic toy problem, no physics",
        "| mesh_ok | yes |",
        "| k | F_N |",
        "- second warning",
        "`big` (array of shape (500, 3)",
        "evaluations per second",
        "[best.stl](best.stl)",
        "| variable | a_mm |",
    ):
        assert needle in report, needle


@pytest.mark.slow
@pytest.mark.e2e
def test_same_seed_same_best_and_quick_and_seed_options(tmp_path):
    first = run_toy(tmp_path, "one")
    second = run_toy(tmp_path, "two")
    assert np.array_equal(first.result.best.x, second.result.best.x)
    rows = [read_records_csv(r.run_dir / "evaluations.csv") for r in (first, second)]
    for row in (*rows[0], *rows[1]):
        del row["time_s"]
    assert rows[0] == rows[1]  # bit-identical designs in the same order
    other = run_toy(tmp_path, "three", seed=11)
    assert not np.array_equal(first.result.best.x, other.result.best.x)
    assert "seed: 11" in (other.run_dir / "study.yaml").read_text()

    study = write_study(tmp_path)
    assert main(["run", str(study), "--out", str(tmp_path / "q"), "--quick", "-q"]) == 0
    record = json.loads((tmp_path / "q" / "run.json").read_text())
    assert record["quick"] is True and record["optimiser"]["pop_size"] == 4
    assert record["generations_done"] == 2


def test_initial_designs_of_the_problem_seed_the_first_population(tmp_path):
    outcome = run_toy(tmp_path, seed_optimum=True)
    rows = read_records_csv(outcome.run_dir / "evaluations.csv")
    assert (float(rows[0]["a_mm"]), float(rows[0]["b_mm"])) == (1.0, 0.5)
    assert outcome.result.best.f[0] == pytest.approx(0.08)


def test_a_design_that_raises_is_an_infeasible_row_and_the_run_finishes(tmp_path, capsys):
    outcome = run_toy(tmp_path, fail_above_a=1.0)
    rows = read_records_csv(outcome.run_dir / "evaluations.csv")
    failed = [r for r in rows if r["reason"]]
    assert failed and len(failed) == sum(float(r["a_mm"]) > 1.0 for r in rows)
    for r in failed:
        assert r["reason"].startswith("RuntimeError: cannot build: a_mm = ")
        assert r["feasible"] == "false" and r["sum_mm"] == ""
    assert outcome.record["status"] == "finished"
    assert outcome.record["n_failed"] == len(failed)
    assert outcome.result.best.x[0] <= 1.0
    assert "Most frequent failure reasons" in (outcome.run_dir / "report.md").read_text()


def test_two_objectives_need_nsga2_and_give_a_front(tmp_path, capsys):
    study = write_study(tmp_path, two_objectives=True)
    assert main(["run", str(study), "--out", str(tmp_path / "ga"), "-q"]) == 2
    assert "set algorithm: nsga2" in capsys.readouterr().err
    data = json.loads(study.read_text())
    data["optimiser"]["algorithm"] = "nsga2"
    study.write_text(json.dumps(data))
    out = tmp_path / "nsga2"
    assert main(["run", str(study), "--out", str(out), "-q"]) == 0
    best = json.loads((out / "best.json").read_text())
    assert len(best["front"]) > 1 and set(best["objectives"]) == {"error_N", "area_mm2"}
    assert "best_area_mm2" in read_records_csv(out / "history.csv")[0]
    report = (out / "report.md").read_text()
    assert "### Pareto front" in report and "![Pareto front](front.png)" in report
    assert (out / "front.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "![Stress map of the best design](stress_map.png)" in report
    assert "field_map" not in (out / "best.json").read_text()  # drawn, not stored


def test_a_failing_detail_is_a_note_not_the_loss_of_the_run(tmp_path, capsys):
    study = write_study(tmp_path, detail_fails=True)
    out = tmp_path / "run"
    assert main(["run", str(study), "--out", str(out), "-q"]) == 0
    assert "warning: the best design's detail failed: ZeroDivisionError" in capsys.readouterr().err
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "finished" and "detail failed" in record["notes"][0]
    assert {"best.json", "convergence.png", "report.md"} <= set(record["files"])
    assert not (out / "best.stl").exists()
    assert "## Notes" in (out / "report.md").read_text()


def test_ctrl_c_leaves_an_interrupted_run(tmp_path, capsys):
    study = write_study(tmp_path, interrupt_after=13)
    out = tmp_path / "run"
    # in this process: the toy counts its calls (a worker process would count its own)
    assert main(["run", str(study), "--out", str(out), "-q", "--workers", "1"]) == 130
    assert "interrupted" in capsys.readouterr().err
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "interrupted" and record["n_evaluations"] == 13
    rows = read_records_csv(out / "evaluations.csv")
    assert len(rows) == 13 and rows[-1]["generation"] == "2"
    assert not (out / "best.json").exists()


def test_bad_study_is_one_line_exit_2_and_nothing_is_written(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    data = json.loads(json.dumps(TOY))
    data["optimiser"]["pop_size"] = 1
    bad.write_text(json.dumps(data))
    out = tmp_path / "never"
    assert main(["run", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "optimiser.pop_size" in err
    assert not out.exists()

    assert main(["run", "cantilever", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "nothing to optimise" in err and "toy_quadratic" in err and not out.exists()

    good = write_study(tmp_path)
    assert main(["evaluate", str(good), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "flexopt run" in err and not out.exists()


def test_out_holding_a_run_is_refused(tmp_path, capsys):
    study = write_study(tmp_path)
    out = tmp_path / "run"
    out.mkdir()
    (out / "run.json").write_text("{}")
    assert main(["run", str(study), "--out", str(out), "-q"]) == 2
    assert "already holds a run" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["run.json"]


# --------------------------------------------------------------------------------------------
# flexopt export


def test_export_writes_a_watertight_stl(tmp_path, capsys):
    outcome = run_toy(tmp_path)
    run_dir = outcome.run_dir
    stl = tmp_path / "best.stl"
    assert main(["export", str(run_dir), "--out", str(stl)]) == 0
    assert str(stl) in capsys.readouterr().out
    mesh = trimesh.load(stl)
    a, b = outcome.result.best.x
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx((10 + 5 * a) * (3 + 2 * b) * 4.0, rel=1e-6)
    assert stl.read_bytes() == (run_dir / "best.stl").read_bytes()

    assert main(["export", str(run_dir), "--design", "3"]) == 0
    rows = read_records_csv(run_dir / "evaluations.csv")
    a3, b3 = float(rows[3]["a_mm"]), float(rows[3]["b_mm"])
    mesh3 = trimesh.load(run_dir / "design-3.stl")
    assert mesh3.volume == pytest.approx((10 + 5 * a3) * (3 + 2 * b3) * 4.0, rel=1e-6)

    capsys.readouterr()
    assert main(["export", str(run_dir), "--design", str(len(rows))]) == 2
    assert f"the run has {len(rows)}" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "nope")]) == 2
    assert main(["export", str(run_dir), "--design", "first"]) == 2


# --------------------------------------------------------------------------------------------
# Pieces


def test_generation_line():
    best = Evaluation(np.zeros(2), np.array([0.0123]), np.array([-1.0]))
    report = GenerationReport(3, 30, 24, 0, best, 0.85, 12.34, 2.0)
    assert format_generation(report) == "gen 3/30  best 0.0123  feasible 85%  12.3 eval/s"
    failed = Evaluation.failed(np.zeros(2), 1, 1, "x")
    line = format_generation(GenerationReport(1, 30, 8, 0, failed, 0.0, 1.0, 1.0))
    assert "best none feasible" in line


def test_info_rendering_keeps_scalars_and_small_tables():
    lines = "\n".join(
        render_info(
            {
                "n": 3,
                "ok": False,
                "ratios": [1.0, 2.5],
                "table": {"x_mm": [0.0, 1.0], "F_N": [0.5, 0.7]},
                "check": {"model": "m", "stroke_mm": [1, 2, 3], "F_N": [4, 5, 6], "band": [1, 2]},
                "deep": {"a": {"b": {"c": {"d": 1}}}},
                "obj": object(),
            }
        )
    )
    assert "| n | 3 |" in lines and "| ok | no |" in lines and "| ratios | [1, 2.5] |" in lines
    assert "| x_mm | F_N |" in lines and "| 1 | 0.7 |" in lines
    assert "`obj` (object)" in lines
    assert "| stroke_mm | F_N |\n|---|---|\n| 1 | 4 |" in lines and "| band | [1, 2] |" in lines


@pytest.mark.e2e
def test_constant_force_quick_smoke(tmp_path):
    """The shipped optimisable example runs end to end (`flexopt run constant-force --quick`)."""
    from flexopt.pipeline.studies import kinds
    from flexopt.pipeline.study import list_examples

    if "constant_force" not in kinds() or "constant-force" not in list_examples():
        pytest.skip("the constant_force kind or its example is not in this tree yet")
    out = tmp_path / "cf"
    assert main(["run", "constant-force", "--quick", "--out", str(out), "-q"]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "finished" and record["quick"] is True
    pop, n_gen = record["optimiser"]["pop_size"], record["optimiser"]["n_gen"]
    # the example runs the hybrid (its default since session 28): the GA stage at most pop x
    # n_gen designs, then one gradient start; a smoke run, its verdict not asserted (often
    # NOT MET after ~27 designs)
    assert record["optimiser"]["method"] == "hybrid"
    ga, gradient = (record["hybrid"]["n_evaluations"][k] for k in ("ga", "gradient"))
    assert 0 < ga <= pop * n_gen and gradient > 0
    assert ga < record["n_evaluations"] <= ga + gradient
    assert len(read_records_csv(out / "evaluations.csv")) == record["n_evaluations"]
    expected = {"best.json", "best_response.csv", "force_displacement.png", "convergence.png"}
    assert expected | {"stress.png", "shapes.png", "best.stl", "report.md"} <= set(record["files"])
    assert trimesh.load(out / "best.stl").is_watertight
    assert "## From the study kind" in (out / "report.md").read_text()


# --------------------------------------------------------------------------------------------
# The per-generation files, written by the writer thread (issue 13)


def test_generation_files_are_written_off_the_main_thread_in_order(tmp_path, monkeypatch):
    """evaluations.csv, history.csv, checkpoint.json and run.json of each generation are written
    by one writer thread, in that order, each generation after the previous one, and all of
    them are on disk, complete, before the run goes on to its report."""
    import threading

    from flexopt.pipeline.run import folder, runner, state

    writes: list[tuple[str, str]] = []
    real = folder.write_atomic

    def recording(path, data):
        writes.append((threading.current_thread().name, Path(path).name))
        real(path, data)

    for run_mod in (folder, runner, state):
        monkeypatch.setattr(run_mod, "write_atomic", recording)
    outcome = run_toy(tmp_path)
    per_generation = ["evaluations.csv", "history.csv", "checkpoint.json", "run.json"]
    threaded = [name for thread, name in writes if thread.startswith("flexopt-writes")]
    assert threaded == per_generation * 4  # n_gen = 4, in order
    # the main thread's first write after the optimisation comes after the last threaded one
    last = max(i for i, (thread, _) in enumerate(writes) if thread.startswith("flexopt-writes"))
    assert all(t.startswith("flexopt-writes") or i > last or n in ("study.yaml", "run.json")
               for i, (t, n) in enumerate(writes))  # fmt: skip
    rows = read_records_csv(outcome.run_dir / "evaluations.csv")
    assert len(rows) == outcome.record["n_evaluations"] == 8 * 4
    checkpoint = json.loads((outcome.run_dir / "checkpoint.json").read_text())
    assert checkpoint["generation"] == 4 and checkpoint["n_evaluations"] == len(rows)


def test_a_failed_generation_write_fails_the_run_with_its_reason(tmp_path, monkeypatch):
    """A write the writer thread could not make (a full disk) is not lost in the thread: the
    run stops with that error, and run.json says so."""
    from flexopt.pipeline.run import folder, runner, state

    real = folder.write_atomic
    count = {"checkpoint": 0}

    def failing(path, data):
        if Path(path).name == "checkpoint.json":
            count["checkpoint"] += 1
            if count["checkpoint"] == 2:
                raise OSError(28, "No space left on device")
        real(path, data)

    for run_mod in (folder, runner, state):
        monkeypatch.setattr(run_mod, "write_atomic", failing)
    with pytest.raises(OSError, match="No space left"):
        run_toy(tmp_path)
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    record = json.loads((run_dir / "run.json").read_text())
    assert record["status"] == "failed" and "No space left" in record["error"]


def test_report_files_are_written_on_their_thread_before_the_run_says_finished(
    tmp_path, monkeypatch
):
    """The report's files (best.json, the plots, the part's files, report.html) are written by
    their writer thread while the run's thread makes the next ones, each whole (write_atomic);
    every one is on disk before report.md and the finished run.json are written. A report file
    that cannot be written (a full disk) fails the run with its reason."""
    import threading

    from flexopt.pipeline.run import runner, state

    writes: list[tuple[str, str]] = []  # (thread, name) as each write ended; report.md: began
    real = state.write_atomic

    def recording(path, data):
        name = Path(path).name
        if name == "report.md":
            writes.append((threading.current_thread().name, name))
        real(path, data)
        if name != "report.md":
            writes.append((threading.current_thread().name, name))

    monkeypatch.setattr(state, "write_atomic", recording)
    monkeypatch.setattr(runner, "write_atomic", recording)
    outcome = run_toy(tmp_path)
    report = [name for thread, name in writes if thread.startswith("flexopt-report-writes")]
    assert {"best.json", "report.html", "convergence.png"} <= set(report)
    steps = [name for name in report if name.startswith("best_0")]  # best_steps/best_KKK.vtu
    assert set(report) - set(steps) <= set(outcome.record["files"])
    assert len(steps) == outcome.record.get("file_counts", {}).get("best_steps/", len(steps))
    done = writes.index((threading.current_thread().name, "report.md"))
    assert all(i < done for i, (t, _) in enumerate(writes) if t.startswith("flexopt-report"))
    assert all((outcome.run_dir / name).is_file() for name in set(report) - set(steps))
    assert json.loads((outcome.run_dir / "run.json").read_text())["status"] == "finished"

    def failing(path, data):
        if Path(path).name == "convergence.png":
            raise OSError(28, "No space left on device")
        real(path, data)

    monkeypatch.setattr(state, "write_atomic", failing)
    with pytest.raises(OSError, match="No space left"):
        run_toy(tmp_path, name="full")
    record = json.loads((tmp_path / "full" / "run.json").read_text())
    assert record["status"] == "failed" and "No space left" in record["error"]


def test_report_files_are_made_in_a_forked_child_and_its_failures_are_notes(monkeypatch):
    """ForkedMakes: the files come from another process, in order; a failing make is that
    file's note; a child that dies is a note for each of its files, not a crash of the run;
    without fork the files are made here."""
    import os

    from flexopt.pipeline import fork as run_mod

    if run_mod.fork_context() is None:
        pytest.skip("no fork on this platform")

    def boom() -> bytes:
        raise ValueError("no such column")

    items = [("a.png", lambda: str(os.getpid()).encode()), ("b.png", boom), ("c.png", lambda: None)]
    out = run_mod.ForkedMakes(items).results()
    assert [name for name, _, _ in out] == ["a.png", "b.png", "c.png"]
    assert out[0][1] != str(os.getpid()).encode() and out[0][2] is None  # another process
    assert out[1] == ("b.png", None, "ValueError: no such column")
    assert out[2] == ("c.png", None, None)

    dead = run_mod.ForkedMakes([("d.png", lambda: os._exit(3)), ("e.png", lambda: b"x")])
    assert [(n, d, e) for n, d, e in dead.results()] == [
        ("d.png", None, "the process making it died (exit code 3)"),
        ("e.png", None, "the process making it died (exit code 3)"),
    ]

    monkeypatch.setattr(run_mod, "fork_context", lambda: None)
    here = run_mod.ForkedMakes([("a.png", lambda: str(os.getpid()).encode())]).results()
    assert here == [("a.png", str(os.getpid()).encode(), None)]


def test_best_step_child_is_forked_early_and_makes_the_part_it_is_sent(monkeypatch):
    """EarlyStep: forked before the part is known, it makes best.step in another process once
    sent the part; without a part it ends when closed; a child that dies is a note."""
    import os
    import sys
    import time
    import types

    from flexopt.pipeline.run import step_child as run_mod

    if run_mod.fork_context() is None:
        pytest.skip("no fork on this platform")
    # the child's import of the STEP writer is instant here, and its "STEP" says who made it
    monkeypatch.setitem(sys.modules, "build123d", types.ModuleType("build123d"))
    monkeypatch.setattr(
        run_mod, "part_bytes", lambda part, fmt: f"{fmt} {part} {os.getpid()}".encode()
    )
    early = run_mod.EarlyStep.start()
    assert early is not None and early.send("plate")
    ((name, data, error),) = early.results()
    early.close()
    assert name == "best.step" and error is None
    fmt, part, pid = data.decode().split()
    assert (fmt, part) == ("step", "plate") and int(pid) != os.getpid()
    assert not early.process.is_alive()

    idle = run_mod.EarlyStep.start()  # no part (a kind without an outline): closed, it ends
    idle.close()
    assert not idle.process.is_alive() and idle.process.exitcode == 0

    monkeypatch.setattr(run_mod, "part_bytes", lambda part, fmt: os._exit(3))
    dead = run_mod.EarlyStep.start()
    assert dead.send("plate")
    assert dead.results() == [("best.step", None, "the process making it died (exit code 3)")]
    dead.close()

    # started with the run: at the lowest priority, importing at once (no wait for an idle core)
    monkeypatch.setattr(run_mod, "_wait_for_idle_core", lambda *a, **k: os._exit(4))
    monkeypatch.setattr(
        run_mod, "part_bytes", lambda part, fmt: str(os.getpriority(os.PRIO_PROCESS, 0)).encode()
    )
    low = run_mod.EarlyStep.start(nice=run_mod.EARLY_STEP_NICE)
    assert low.process.is_alive()
    lowered = min(19, os.getpriority(os.PRIO_PROCESS, 0) + run_mod.EARLY_STEP_NICE)
    deadline = time.monotonic() + 30.0  # it lowers its priority first thing
    while os.getpriority(os.PRIO_PROCESS, low.process.pid) != lowered:
        assert time.monotonic() < deadline, "the child did not lower its priority"
        time.sleep(0.01)
    assert low.send("plate")
    ((name, data, error),) = low.results()
    low.close()
    assert (name, error) == ("best.step", None)
    # with the part it goes back to the run's priority where it may (root), else stays low
    assert int(data) in (os.getpriority(os.PRIO_PROCESS, 0), lowered)


def test_waiting_for_an_idle_core_ends_on_work_or_at_its_limit(monkeypatch):
    """_wait_for_idle_core: at once when there is work, after one period when any idle share
    will do, at its time limit when the idle share asked for cannot happen. Counted in periods
    waited on a clock of the test's own (each wait moves it by its timeout), not in wall time."""
    import time
    import types

    from flexopt.pipeline.run.step_child import _wait_for_idle_core

    clock = [0.0]
    fake_time = types.SimpleNamespace(monotonic=lambda: clock[0])
    monkeypatch.setitem(_wait_for_idle_core.__globals__, "time", fake_time)
    waits: list[float] = []

    def work(timeout: float) -> bool:
        waits.append(timeout)
        return True

    _wait_for_idle_core(work, idle_cores=1e9)
    assert waits == [0.2]  # the first look finds work

    def no_work(timeout: float) -> bool:
        waits.append(timeout)
        clock[0] += timeout
        time.sleep(0.05)  # real time too: /proc/stat's counters move on
        return False

    waits.clear()
    _wait_for_idle_core(no_work, period_s=0.25, idle_cores=1e9, limit_s=1.0)
    assert waits == [0.25] * 4  # to its limit, not a period longer
    waits.clear()
    _wait_for_idle_core(no_work, period_s=0.25, idle_cores=0.0, limit_s=30.0)
    assert waits == [0.25]  # any idle share will do: one period


def test_the_report_is_preloaded_in_a_thread_only_with_worker_processes():
    """_preload_report: the problem's warm_up_detail runs in a background thread while worker
    processes solve; never in a serial run (it would compete with the solving thread); a
    failing preload is only logged."""
    import threading

    from flexopt.optimise.problem import DesignProblem
    from flexopt.pipeline.parallel import ParallelSettings
    from flexopt.pipeline.run.runner import _preload_report

    seen: list[str] = []

    class Problem(DesignProblem):
        def warm_up_detail(self) -> None:
            seen.append(threading.current_thread().name)

    class Failing(DesignProblem):
        def warm_up_detail(self) -> None:
            raise RuntimeError("no kernels here")

    assert _preload_report(Problem(), ParallelSettings(backend="serial")) is None
    assert seen == []
    thread = _preload_report(Problem(), ParallelSettings(backend="processes", workers=2))
    thread.join(60)
    assert seen == ["flexopt-preload"]
    failing = _preload_report(Failing(), ParallelSettings(backend="processes", workers=2))
    failing.join(60)
    assert not failing.is_alive()
    # held back (a hybrid run's GA stage): nothing runs until start(), which starts it once;
    # join() of a preload nobody started runs it (the report then has what it needs)
    seen.clear()
    held = _preload_report(Problem(), ParallelSettings(backend="processes", workers=2), False)
    assert seen == [] and held.thread.ident is None and not held.is_alive()
    held.start()
    held.start()
    held.join(60)
    assert seen == ["flexopt-preload"]
    never = _preload_report(Problem(), ParallelSettings(backend="processes", workers=2), False)
    never.join(60)
    assert seen == ["flexopt-preload"] * 2 and not never.is_alive()


@pytest.mark.parametrize("hybrid", [False, True], ids=["ga", "hybrid"])
def test_the_report_preload_starts_after_the_ga_stage_of_a_hybrid_run(
    tmp_path, monkeypatch, hybrid
):
    """A GA's generations keep every worker busy, so a hybrid run starts the report's preload
    thread after its first gradient batch (a core idles in most of that stage's batches); a GA
    run starts it with the optimisation, as before. Both runs preload before the report."""
    import flexopt_toys
    from flexopt.optimise.hybrid import GradientStep
    from flexopt.pipeline.parallel import ParallelSettings
    from flexopt.pipeline.run import runner
    from flexopt.pipeline.run.state import RunState

    batches: list[str] = []  # every generation_done, in order: "ga" or "gradient"
    events: list[tuple[str, int]] = []  # (what, batches done then)
    done = RunState.generation_done

    def generation_done(self, gen):
        batches.append("gradient" if isinstance(gen, GradientStep) else "ga")
        return done(self, gen)

    start, join = runner.ReportPreload.start, runner.ReportPreload.join

    def started(self):
        if self.thread.ident is None:
            events.append(("start", len(batches)))
        return start(self)

    def joined(self, timeout=None):
        events.append(("join", len(batches)))
        return join(self, timeout)

    monkeypatch.setattr(RunState, "generation_done", generation_done)
    monkeypatch.setattr(runner.ReportPreload, "start", started)
    monkeypatch.setattr(runner.ReportPreload, "join", joined)
    raw = flexopt_toys.study()
    raw["optimiser"] = {"pop_size": 8, "n_gen": 3, "seed": 5}
    if hybrid:
        raw["optimiser"].update(method="hybrid", hybrid={"starts": 2, "max_iter": 20})
    run_study(
        prepare_run(validate_study(raw)),
        out=tmp_path / "run",
        parallel=ParallelSettings("processes", 2),
    )
    n_ga = batches.count("ga")
    assert n_ga == 3 and (batches.count("gradient") > 1) == hybrid
    # the GA run's preload starts before its first generation; the hybrid's after the GA
    # stage and its first gradient batch
    assert events[0] == ("start", n_ga + 1 if hybrid else 0)
    assert events[1] == ("join", len(batches))


def test_the_early_step_child_is_lowered_only_where_it_can_come_back(monkeypatch):
    """can_restore_priority: root may; an ordinary user with RLIMIT_NICE 0 may not (the child
    would stay SCHED_IDLE and starve while the report runs), so the run starts it at the report
    instead; a limit that reaches the run's nice value may."""
    import os
    import resource

    from flexopt.pipeline.run import step_child as run_mod

    monkeypatch.setattr(os, "geteuid", lambda: 0)
    assert run_mod.can_restore_priority()
    monkeypatch.setattr(os, "geteuid", lambda: 1000)
    monkeypatch.setattr(os, "getpriority", lambda *a: 0)
    monkeypatch.setattr(resource, "getrlimit", lambda what: (0, 0))
    assert not run_mod.can_restore_priority()
    monkeypatch.setattr(resource, "getrlimit", lambda what: (20, 20))  # down to nice 0
    assert run_mod.can_restore_priority()
    monkeypatch.setattr(os, "getpriority", lambda *a: -5)  # a run at nice -5 needs 25
    assert not run_mod.can_restore_priority()
    monkeypatch.setattr(
        resource, "getrlimit", lambda what: (resource.RLIM_INFINITY, resource.RLIM_INFINITY)
    )
    assert run_mod.can_restore_priority()


def test_convergence_png_is_forked_before_the_detail_and_written_in_its_place(
    tmp_path, monkeypatch
):
    """convergence.png needs only the run's history: its child is forked before the best
    design's detail is solved (the core idles then), it is not made again with the other
    plots, and it is written in its queued place among them (after stress.png, before
    shapes.png), as when one child made the whole group."""
    from flexopt.pipeline.run import split_makes, state

    events: list[Any] = []
    written: list[str] = []

    class Recorded(state.ForkedMakes):
        def __init__(self, items):
            events.append(tuple(name for name, _ in items))
            super().__init__(items)

    real_detail, real_write = ToyProblem.detail, state.write_atomic

    def detail(self, x):
        events.append("detail")
        return real_detail(self, x)

    def write(path, data):
        written.append(Path(path).name)
        real_write(path, data)

    monkeypatch.setattr(state, "ForkedMakes", Recorded)
    monkeypatch.setattr(split_makes, "ForkedMakes", Recorded)
    monkeypatch.setattr(ToyProblem, "detail", detail)
    monkeypatch.setattr(state, "write_atomic", write)
    outcome = run_toy(tmp_path)
    assert events[0] == ("convergence.png",) and events[1] == "detail"
    later = [names for names in events[2:] if isinstance(names, tuple)]
    assert later and not any("convergence.png" in names for names in later)  # not made twice
    assert "convergence.png" in outcome.record["files"]
    assert (outcome.run_dir / "convergence.png").read_bytes()[:4] == b"\x89PNG"
    pngs = [name for name in written if name.endswith(".png")]
    assert pngs == [
        "force_displacement.png",
        "stress.png",
        "convergence.png",
        "shapes.png",
        "stress_map.png",
    ]
