"""The public Python API, ``import flexopt`` (docs/api.md): load, change, evaluate, run, read.

Every result is checked against what the command line writes for the same study (the same code
path must give the same numbers), and the cantilever's first step against the small-deflection
closed form 3EI/L^3 computed here.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import flexopt
import numpy as np
import pytest
from flexopt.fea.materials import get_material
from flexopt.optimise.requirements import to_records, verdict_record
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.evaluate import EVALUATE_FILES
from flexopt.pipeline.study import list_examples, study_to_yaml

# --------------------------------------------------------------------------------------------
# Loading


def test_load_by_name_path_and_dict_give_the_same_study(tmp_path: Path) -> None:
    by_name = flexopt.load_study("cantilever")
    path = tmp_path / "beam.yaml"
    path.write_text(study_to_yaml(by_name), encoding="utf-8")
    by_path = flexopt.load_study(path)
    by_text = flexopt.load_study(str(path))
    by_dict = flexopt.load_study(by_name.model_dump(mode="json", exclude_none=True))
    assert isinstance(by_name, flexopt.Study)
    assert by_name == by_path == by_text == by_dict
    assert by_name.geometry.points_mm == ((0.0, 0.0), (30.0, 0.0), (60.0, 0.0))
    assert flexopt.load_study(by_name) is by_name


@pytest.mark.parametrize(
    ("given", "path", "words"),
    [
        ("no-such-study", "", "no built-in example"),
        (42, "", "not int"),
        ({"name": "b"}, "geometry", "required key is missing"),
    ],
)
def test_load_refuses_what_is_not_a_study(given: object, path: str, words: str) -> None:
    with pytest.raises(flexopt.StudyError) as info:
        flexopt.load_study(given)
    assert info.value.path == path
    assert words in str(info.value)
    assert isinstance(info.value, ValueError)


def test_load_a_dict_names_the_key_path_and_the_source() -> None:
    data = flexopt.load_study("cantilever").model_dump(mode="json", exclude_none=True)
    data["geometry"]["thickness_mm"] = [1.5, 1.5]
    with pytest.raises(flexopt.StudyError) as info:
        flexopt.load_study(data, source="my notebook")
    assert info.value.path == "geometry.thickness_mm"
    assert "3 points but 2 thickness values" in str(info.value)
    assert str(info.value).startswith("my notebook: geometry.thickness_mm: ")


# --------------------------------------------------------------------------------------------
# Changing a study


def test_with_values_returns_a_new_validated_study() -> None:
    study = flexopt.load_study("cantilever")
    changed = study.with_values({"geometry.width_mm": 6.0, "geometry.points_mm[1][0]": 30.5})
    assert changed.geometry.width_mm == 6.0
    assert changed.geometry.points_mm[1] == (30.5, 0.0)
    assert study.geometry.width_mm == 8.0 and study.geometry.points_mm[1] == (30.0, 0.0)
    assert type(changed) is type(study)
    every = study.with_values({"geometry.thickness_mm[*]": 2.0})
    assert every.geometry.thickness_mm == (2.0, 2.0, 2.0)
    # an optional block left unset is started by a key inside it
    assert study.parallel is None
    assert study.with_values({"parallel.workers": 1}).parallel.workers == 1
    # a whole block, and numpy numbers, as values
    block = study.with_values({"geometry.thickness_mm": np.array([1.0, 1.2, 1.4])})
    assert block.geometry.thickness_mm == (1.0, 1.2, 1.4)


@pytest.mark.parametrize(
    ("values", "path", "words"),
    [
        ({"geometry.widht_mm": 6.0}, "geometry.widht_mm", "did you mean geometry.width_mm?"),
        ({"geomtry.width_mm": 6.0}, "geomtry.width_mm", "did you mean geometry.width_mm?"),
        ({"parallel.wrkers": 2}, "parallel.wrkers", "did you mean parallel.workers?"),
        ({"geometry.points_mm[3][0]": 1.0}, "geometry.points_mm[3][0]", "has 3 items"),
        ({"geometry.width_mm[0]": 1.0}, "geometry.width_mm[0]", "is not a list"),
        ({"geometry..width_mm": 1.0}, "geometry..width_mm", "cannot read the path"),
        # values: the kind's model and its own checks run again
        ({"geometry.width_mm": -1.0}, "geometry.width_mm", "greater than 0"),
        ({"geometry.width_mm": True}, "geometry.width_mm", "a boolean is not a number"),
        ({"geometry.thickness_mm": [1.0, 1.0]}, "geometry.thickness_mm", "one value per point"),
        ({"material": "unobtainium"}, "material", "unknown material"),
    ],
)
def test_with_values_refuses_bad_paths_and_values(values: dict, path: str, words: str) -> None:
    study = flexopt.load_study("cantilever")
    with pytest.raises(flexopt.StudyError) as info:
        study.with_values(values)
    assert info.value.path == path
    assert words in info.value.problem


def test_replace_top_level_blocks() -> None:
    study = flexopt.load_study("cantilever")
    renamed = study.replace(name="beam-b")
    assert renamed.name == "beam-b" and study.name == "cantilever"
    assert renamed.geometry == study.geometry
    pla = study.replace(material="PLA")
    assert pla.material.E_MPa == get_material("PLA").E_MPa
    assert study.replace(parallel={"workers": 1}).parallel.workers == 1
    with pytest.raises(flexopt.StudyError) as info:
        study.replace(nme="x")
    assert info.value.path == "nme" and "did you mean 'name'?" in info.value.problem
    with pytest.raises(flexopt.StudyError) as info:
        study.replace(name="a b")
    assert info.value.path == "name"
    with pytest.raises(flexopt.StudyError) as info:
        study.replace(geometry=None)  # a required block cannot go back to a default
    assert info.value.path == "geometry"


# --------------------------------------------------------------------------------------------
# Evaluate


@pytest.fixture(scope="module")
def cantilever_cli(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``flexopt evaluate cantilever --out DIR``: the folder the API must agree with."""
    out = tmp_path_factory.mktemp("cli") / "ev"
    assert main(["evaluate", "cantilever", "--out", str(out)]) == 0
    return out


def _csv_columns(path: Path) -> dict[str, list[str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    return {name: [row[name] for row in rows] for name in rows[0]}


def test_evaluate_agrees_with_flexopt_evaluate(cantilever_cli: Path) -> None:
    result = flexopt.evaluate("cantilever")
    record = json.loads((cantilever_cli / "evaluation.json").read_text(encoding="utf-8"))
    assert result.run_dir is None
    assert verdict_record(result.verdict) == record["verdict"]
    assert result.met is (record["verdict"]["overall"] == "MET")
    assert result.converged is record["converged"] and result.message == record["message"]
    assert list(result.table) == record["columns"]
    for key, value in record["summary"].items():
        if isinstance(value, float):
            assert result.summary[key] == pytest.approx(value, rel=1e-12)
        else:
            assert result.summary[key] == value
    columns = _csv_columns(cantilever_cli / "response.csv")
    for name, cells in columns.items():
        column = result.table[name]
        if column.dtype == bool:
            assert [("true" if v else "false") for v in column] == cells
        else:
            np.testing.assert_allclose(column, np.array(cells, dtype=float), rtol=1e-9)
    assert result.solve_time_s > 0
    # NOT MET on the clamp as made (no boundary.clamp_kt: docs/beam.md "The clamp as made")
    assert "cantilever (polyline_beam): NOT MET (3 of 4), converged, 21 rows x 12" in repr(result)


def test_evaluate_result_is_physics_not_just_numbers() -> None:
    study = flexopt.load_study("cantilever")
    result = flexopt.evaluate(study)
    g = study.geometry
    length = g.points_mm[-1][0] - g.points_mm[0][0]
    inertia = g.width_mm * g.thickness_mm[0] ** 3 / 12.0
    k_linear = 3.0 * study.material.E_MPa * inertia / length**3  # N/mm, tip force per deflection
    # the first step pushes the tip 1/60 of the length: within 0.1 % of the linear beam
    first = result.table["force_N"][1] / result.table["displacement_mm"][1]
    assert first == pytest.approx(k_linear, rel=1e-3)
    # a narrower beam is softer in proportion to its width (the same study, one value changed)
    narrow = flexopt.evaluate(study.with_values({"geometry.width_mm": 4.0}))
    np.testing.assert_allclose(narrow.table["force_N"], result.table["force_N"] / 2, rtol=1e-9)


def test_evaluate_result_is_frozen_and_plots_the_response() -> None:
    result = flexopt.evaluate("cantilever")
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.converged = False  # type: ignore[misc]
    with pytest.raises(ValueError):
        result.table["force_N"][0] = 1.0
    figure = result.plot()
    force, stress = figure.axes[:2]
    x, y = force.lines[0].get_data()
    np.testing.assert_array_equal(x, result.table["displacement_mm"])
    np.testing.assert_array_equal(y, result.table["force_N"])
    np.testing.assert_array_equal(stress.lines[0].get_ydata(), result.table["peak_stress_MPa"])
    # the yield line, as in force_displacement.png
    assert stress.lines[1].get_ydata()[0] == flexopt.load_study("cantilever").material.yield_MPa
    frame = result.to_dataframe()
    assert list(frame.columns) == list(result.table)
    np.testing.assert_array_equal(frame["force_N"].to_numpy(), result.table["force_N"])


def test_evaluate_out_writes_the_evaluate_folder(tmp_path: Path, cantilever_cli: Path) -> None:
    result = flexopt.evaluate(flexopt.load_study("cantilever"), repeat=2, out=tmp_path / "ev")
    assert result.run_dir == tmp_path / "ev"
    for name in EVALUATE_FILES:
        assert (result.run_dir / name).is_file()
    record = json.loads((result.run_dir / "evaluation.json").read_text(encoding="utf-8"))
    assert record["repeat"] == 2
    assert record["solve_time_s"] == pytest.approx(result.solve_time_s)
    cli = json.loads((cantilever_cli / "evaluation.json").read_text(encoding="utf-8"))
    assert record["verdict"] == cli["verdict"] and record["columns"] == cli["columns"]


@pytest.mark.parametrize(("kwargs", "path"), [({"repeat": 0}, "repeat"), ({"out": ""}, "out")])
def test_evaluate_refuses_bad_arguments(kwargs: dict, path: str) -> None:
    with pytest.raises(flexopt.StudyError) as info:
        flexopt.evaluate("cantilever", **kwargs)
    assert info.value.path == path


def test_to_dataframe_without_pandas_says_how_to_install_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    result = flexopt.evaluate("cantilever")
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas now raises ImportError
    with pytest.raises(ImportError, match=r"pip install 'flexopt\[dataframe\]'"):
        result.to_dataframe()


# --------------------------------------------------------------------------------------------
# Run


def _small(study: flexopt.Study) -> flexopt.Study:
    # 4 designs x 2 generations under quick: the run's files, not its optimum, are tested here
    # (constant-force runs the hybrid: then one gradient start, whose designs are rows too)
    return study.with_values({"optimiser.quick_pop_size": 4, "optimiser.quick_n_gen": 2})


def _printed(call: Callable[[], object], folder: Path) -> tuple[object, str]:
    """``call()`` and what it wrote to the process's stdout and stderr (file descriptors 1, 2)."""
    sink = folder / "printed.txt"
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    with sink.open("wb") as handle:
        os.dup2(handle.fileno(), 1)
        os.dup2(handle.fileno(), 2)
        try:
            value = call()
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
    return value, sink.read_text(encoding="utf-8", errors="replace")


@pytest.fixture(scope="module")
def quick_run_printed(tmp_path_factory: pytest.TempPathFactory) -> tuple[flexopt.RunResult, str]:
    study = _small(flexopt.load_study("constant-force"))
    folder = tmp_path_factory.mktemp("run")
    return _printed(
        lambda: flexopt.run(study, quick=True, workers=1, seed=3, out=folder / "cf"), folder
    )  # type: ignore[return-value]


@pytest.fixture(scope="module")
def quick_run(quick_run_printed: tuple[flexopt.RunResult, str]) -> flexopt.RunResult:
    return quick_run_printed[0]


def test_run_best_is_the_run_folders_best(quick_run: flexopt.RunResult) -> None:
    run = quick_run
    best = json.loads((run.run_dir / "best.json").read_text(encoding="utf-8"))
    record = json.loads((run.run_dir / "run.json").read_text(encoding="utf-8"))
    assert run.status == "finished" and run.record == record
    assert record["seed"] == 3 and record["optimiser"]["pop_size"] == 4
    assert run.best.x.tolist() == best["x"]
    assert run.best.variables == best["parameters"]
    assert run.best.objectives == best["objectives"]
    assert run.best.feasible is best["feasible"]
    assert (run.best.generation, run.best.index) == (best["generation"], best["index"])
    assert to_records(run.verdict) == best["verdict"]["requirements"]
    assert run.met is (best["verdict"]["overall"] == "MET")
    assert run.front == ()  # one objective
    assert run.study.name == "constant-force"


def test_run_evaluations_are_the_csv(quick_run: flexopt.RunResult) -> None:
    frame = quick_run.evaluations
    columns = _csv_columns(quick_run.run_dir / "evaluations.csv")
    assert list(frame.columns) == list(columns)
    record = quick_run.record
    assert len(frame) == record["n_evaluations"]
    # the GA stage's 4 x 2, then the gradient stage's designs (method: hybrid, the example's)
    assert record["hybrid"]["n_evaluations"]["ga"] == 8 < len(frame)
    assert len(frame) == 8 + record["hybrid"]["n_evaluations"]["gradient"]
    names = quick_run.record["variables"]
    for name in names:
        np.testing.assert_array_equal(frame[name].to_numpy(), np.array(columns[name], float))
    assert frame["feasible"].dtype == bool
    best = quick_run.best
    row = frame[(frame["generation"] == best.generation) & (frame["index"] == best.index)]
    np.testing.assert_array_equal(row[names].to_numpy()[0], best.x)  # written with every digit


def test_best_study_evaluates_to_the_runs_best(quick_run: flexopt.RunResult) -> None:
    """The best design as a study (a constant_force design: block) gives best.json's numbers."""
    best = json.loads((quick_run.run_dir / "best.json").read_text(encoding="utf-8"))
    study = quick_run.best_study()
    assert study.kind == "constant_force" and isinstance(study.design, dict)
    result = flexopt.evaluate(study)
    residuals = {k: v for k, v in best["metrics"].items() if k.startswith("residual_")}
    for name, value in best["metrics"].items():
        if isinstance(value, float) and name not in residuals:
            assert result.summary[name] == pytest.approx(value, rel=1e-9, nan_ok=True), name
    # the hybrid's Gauss-Newton terms (method: hybrid): F - target at Eq. 8's strokes, which
    # evaluate's summary does not list; from its traced rows here, and their RMS the objective
    assert len(residuals) == study.target.samples
    s, f = result.table["displacement_mm"], result.table["force_N"]
    probes = s[-1] * np.arange(1, study.target.samples + 1) / study.target.samples
    want = np.interp(probes, s, f) - study.target.force_N
    got = [residuals[f"residual_{i}"] for i in range(1, study.target.samples + 1)]
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    assert np.sqrt(np.mean(want**2)) == pytest.approx(best["metrics"]["rms_error_N"], rel=1e-9)
    assert to_records(result.verdict) == best["verdict"]["requirements"]


def test_open_run_reads_the_same_result(quick_run: flexopt.RunResult) -> None:
    again = flexopt.open_run(quick_run.run_dir)
    np.testing.assert_array_equal(again.best.x, quick_run.best.x)
    assert again.best.objectives == quick_run.best.objectives
    assert to_records(again.verdict) == to_records(quick_run.verdict)
    assert again.evaluations.equals(quick_run.evaluations)
    assert repr(again) == repr(quick_run)


def test_run_is_quiet_unless_asked(
    quick_run_printed: tuple[flexopt.RunResult, str], tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    assert quick_run_printed[1] == ""  # the module's run: nothing on stdout or stderr
    study = _small(flexopt.load_study("constant-force"))
    flexopt.run(study, quick=True, workers=1, out=tmp_path / "loud", progress=True)
    err = capfd.readouterr().err
    assert "gen 1/2" in err and "gen 2/2" in err and str(tmp_path / "loud") in err


@pytest.mark.parametrize(
    ("kwargs", "path"),
    [({"workers": 0}, "workers"), ({"workers": 10**6}, "workers"), ({"seed": -1}, "seed")],
)
def test_run_refuses_bad_arguments(kwargs: dict, path: str, tmp_path: Path) -> None:
    with pytest.raises(flexopt.StudyError) as info:
        flexopt.run("constant-force", out=tmp_path / "r", **kwargs)
    assert info.value.path == path
    assert not (tmp_path / "r").exists()


def test_run_refuses_a_kind_with_nothing_to_optimise(tmp_path: Path) -> None:
    with pytest.raises(flexopt.StudyError) as info:
        flexopt.run("cantilever", out=tmp_path / "r")
    assert info.value.path == "geometry.kind" and "flexopt evaluate" in info.value.problem


def test_run_refuses_a_folder_that_holds_a_run(quick_run: flexopt.RunResult) -> None:
    with pytest.raises(flexopt.StudyError) as info:
        flexopt.run("constant-force", quick=True, out=quick_run.run_dir)
    assert "already holds a run" in info.value.problem


# --------------------------------------------------------------------------------------------
# open_run on damaged folders


@pytest.fixture
def copy_of_run(quick_run: flexopt.RunResult, tmp_path: Path) -> Path:
    folder = tmp_path / "copy"
    shutil.copytree(quick_run.run_dir, folder)
    return folder


def _damage_best(folder: Path) -> None:
    text = (folder / "best.json").read_text(encoding="utf-8")
    (folder / "best.json").write_text(text[: len(text) // 2], encoding="utf-8")


def _drop_best(folder: Path) -> None:
    (folder / "best.json").unlink()
    record = json.loads((folder / "run.json").read_text(encoding="utf-8"))
    record["status"] = "interrupted"
    (folder / "run.json").write_text(json.dumps(record), encoding="utf-8")


def _short_x(folder: Path) -> None:
    best = json.loads((folder / "best.json").read_text(encoding="utf-8"))
    best["x"] = best["x"][:-1]
    (folder / "best.json").write_text(json.dumps(best), encoding="utf-8")


def _bad_verdict(folder: Path) -> None:
    best = json.loads((folder / "best.json").read_text(encoding="utf-8"))
    best["verdict"]["requirements"][0]["met"] = "yes"
    (folder / "best.json").write_text(json.dumps(best), encoding="utf-8")


def _cut_csv(folder: Path) -> None:
    lines = (folder / "evaluations.csv").read_text(encoding="utf-8").splitlines()
    lines[3] = lines[3][: len(lines[3]) // 2]
    (folder / "evaluations.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")


def _no_run_json(folder: Path) -> None:
    (folder / "run.json").unlink()


@pytest.mark.parametrize(
    ("damage", "words"),
    [
        (_damage_best, "best.json' is not valid JSON"),
        (_drop_best, "the run is interrupted and has no best design yet"),
        (_short_x, "x is not a list of 23 numbers"),
        (_bad_verdict, "verdict.requirements[0] is not a verdict"),
        (_cut_csv, "evaluations.csv' line 4 has"),
        (_no_run_json, "has no run.json"),
    ],
)
def test_open_run_on_a_damaged_folder_says_what_and_how(
    copy_of_run: Path, damage: object, words: str
) -> None:
    damage(copy_of_run)  # type: ignore[operator]
    with pytest.raises(flexopt.StudyError) as info:
        flexopt.open_run(copy_of_run)
    message = str(info.value)
    assert info.value.path == "run_dir"
    assert words in message
    assert "\n" not in message


def test_open_run_of_what_is_not_a_run_folder(tmp_path: Path, cantilever_cli: Path) -> None:
    with pytest.raises(flexopt.StudyError, match="is not a folder"):
        flexopt.open_run(tmp_path / "missing")
    with pytest.raises(flexopt.StudyError, match="has no run.json"):
        flexopt.open_run(cantilever_cli)  # an evaluate folder


def test_open_run_reads_a_pareto_front(copy_of_run: Path) -> None:
    # best.json of a study with several objectives carries its front (pipeline/run.py); here
    # the recorded best and one other row of the run stand for it
    best = json.loads((copy_of_run / "best.json").read_text(encoding="utf-8"))
    rows = _csv_columns(copy_of_run / "evaluations.csv")
    names = json.loads((copy_of_run / "run.json").read_text(encoding="utf-8"))["variables"]
    other = {**best, "x": [float(rows[n][0]) for n in names], "generation": 1, "index": 0}
    other.pop("verdict")
    best["front"] = [dict(best), other]
    (copy_of_run / "best.json").write_text(json.dumps(best), encoding="utf-8")
    run = flexopt.open_run(copy_of_run)
    assert len(run.front) == 2
    assert run.front[1].x.tolist() == other["x"] and run.front[1].verdict == ()
    assert run.front[0].x.tolist() == best["x"]


# --------------------------------------------------------------------------------------------
# The package


def test_listing_is_what_flexopt_list_shows() -> None:
    from flexopt.pipeline.studies import kinds

    assert [s.name for s in flexopt.list_studies()] == list_examples()
    assert [k.name for k in flexopt.list_kinds()] == sorted(kinds())
    cantilever = {s.name: s for s in flexopt.list_studies()}["cantilever"]
    assert cantilever.kind == "polyline_beam" and cantilever.summary


def test_public_names_and_a_quick_import() -> None:
    assert set(flexopt.__all__) == {"__version__", *flexopt._LAZY}
    for name in flexopt.__all__:
        assert getattr(flexopt, name) is not None, name
    assert flexopt.StudyError is StudyError
    assert flexopt.__version__
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        flexopt.nope  # noqa: B018
    # `import flexopt` itself loads no solver, pydantic or pymoo: they come on first use
    code = (
        "import sys, flexopt; heavy = [m for m in ('pydantic', 'pymoo', 'scipy', 'numba', "
        "'matplotlib', 'flexopt.pipeline.study') if m in sys.modules]; print(heavy)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=os.environ, check=True
    )
    assert out.stdout.strip() == "[]"


# --------------------------------------------------------------------------------------------
# A key a design variable sets (issue 22, item 7)


def test_with_values_on_a_variables_key_moves_the_variable() -> None:
    """A thickness sweep of parallel-guide sees its answer change: the leaf thickness is a
    variable with ``initial:``, so setting the key moves the variable (nothing is ignored)."""
    study = flexopt.load_study("parallel-guide").with_values(
        {"load_cases.stroke.drive.steps": 4, "fidelity.enabled": False}  # the beam model's
    )
    stress = {}
    for t in (1.6, 2.0):
        changed = study.with_values({"geometry.beams.upper.thickness_mm": t})
        assert changed.variables[0].initial == t
        result = flexopt.evaluate(changed)
        assert result.converged
        stress[t] = result.summary["max_peak_stress_MPa"]
    # guided leaves at one stroke: sigma = 3 E t delta / L^2, so the nominal stress scales with
    # t; the verdict's stress is Kt times it at the filleted roots, and Kt (Roark Table 17.1)
    # grows with t at a fixed fillet radius, so the ratio is t's ratio or a few % above it
    ratio = stress[2.0] / stress[1.6]
    assert 2.0 / 1.6 <= ratio <= 1.08 * 2.0 / 1.6
    # a tied key moves the variable too, and every key it sets follows
    tied = study.with_values({"geometry.beams.lower.thickness_mm": 1.7})
    assert tied.variables[0].initial == 1.7
    # an offset tie: the shuttle's reference sits 4 mm beyond the leaf ends
    assert study.with_values({"geometry.bodies.shuttle.ref_mm[0]": 60}).variables[1].initial == 56
    # a whole block given back unchanged keeps the variable; changed, it moves it
    geometry = study.model_dump(mode="json", exclude_none=True)["geometry"]
    assert study.replace(geometry=geometry).variables[0].initial == study.variables[0].initial
    geometry["beams"]["upper"]["thickness_mm"] = 1.1
    assert study.replace(geometry=geometry).variables[0].initial == 1.1


@pytest.mark.parametrize(
    ("values", "path", "words"),
    [
        (
            {"geometry.beams.upper.thickness_mm": 3.0},
            "geometry.beams.upper.thickness_mm",
            "design variable 'leaf_thickness_mm' (variables[0]), and 3 lies outside its "
            "bounds [0.8, 2.5]",
        ),
        (
            {"geometry.bodies.shuttle.ref_mm[0]": 200},
            "geometry.bodies.shuttle.ref_mm[0]",
            "200 puts it at 196, which lies outside its bounds [30, 70]",
        ),
        (
            {"geometry.beams.upper.thickness_mm": 2.0, "geometry.beams.lower.thickness_mm": 2.1},
            "geometry.beams.lower.thickness_mm",
            "cannot be 2 and 2.1 at once",
        ),
        (
            {"geometry.beams.upper.thickness_mm": 2.0, "variables[0].initial": 2.1},
            "geometry.beams.upper.thickness_mm",
            "whose initial is also given",
        ),
    ],
)
def test_with_values_on_a_variables_key_refuses_what_it_cannot_do(
    values: dict, path: str, words: str
) -> None:
    with pytest.raises(flexopt.StudyError) as info:
        flexopt.load_study("parallel-guide").with_values(values)
    assert info.value.path == path
    assert words in info.value.problem


def test_with_values_widens_the_bounds_and_moves_the_variable_at_once() -> None:
    study = flexopt.load_study("parallel-guide").with_values(
        {"geometry.beams.upper.thickness_mm": 3.0, "variables[0].bounds": [0.8, 3.2]}
    )
    assert study.variables[0].initial == 3.0 and study.variables[0].bounds == (0.8, 3.2)
