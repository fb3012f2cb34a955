"""The one rule of names (issue 23 classes 2 and 7; docs/usage.md, "Names").

A generated corpus: names the rule refuses (control characters, a final newline, commas, quotes,
formula-leading characters, 200 000 characters, non-ASCII) are refused at load in one line that
names the key path and echoes no control character, for variables, requirements and a
mechanism's beams, bodies, load cases and outputs; names it admits (the longest, every allowed
character, the words flexopt's own CSV columns use) are written by a run and read back by
``flexopt report`` (without the store: from evaluations.csv), ``flexopt export --design INDEX``
and the Python API.
"""

from __future__ import annotations

import json
import random
import string
from pathlib import Path
from typing import Literal

import numpy as np
import pytest
from flexopt.optimise import DesignDetail, Evaluation
from flexopt.optimise.names import NAME_MAX_CHARS, NAME_RULE, check_name, name_problem
from flexopt.optimise.variables import VariableSpec, resolve_variables
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.parallel import ParallelSettings
from flexopt.pipeline.run import prepare_run, rebuild_report, run_study
from flexopt.pipeline.runfolder import read_records_csv
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study, load_study, validate_study
from pydantic import BaseModel
from shapely.geometry import box

ROOT = Path(__file__).resolve().parents[2]
ALLOWED = string.ascii_letters + string.digits + "_.-[]* "

# --------------------------------------------------------------------------------------------
# The corpus


def admitted(n: int = 200, seed: int = 23) -> list[str]:
    """Names the rule admits: the edge cases, then random ones of every allowed character."""
    rng = random.Random(seed)
    names = [
        "a", "Z", "feasible", "generation", "index", "reason", "time_s", "x_feasible", "error",
        "sum_excess", "tip force", "a[*]", "beams.leaf1.thickness_mm[*]", "x" * NAME_MAX_CHARS,
        "a-b", "a.b", "a  b", "T1_mm",
    ]  # fmt: skip
    while len(names) < n:
        size = rng.randint(1, NAME_MAX_CHARS)
        body = "".join(rng.choice(ALLOWED) for _ in range(size - 1))
        name = (rng.choice(string.ascii_letters) + body).rstrip(" ") or "a"
        names.append(name)
    return names


def refused(seed: int = 23) -> list[str]:
    """Names the rule refuses, one of each way to be wrong, and random control bytes."""
    rng = random.Random(seed)
    names = [
        "", "abc\n", "\nabc", "a\nb,c", "a,b", "a;b", 'a"b', "a'b", "a<b>", "a&b", "a\tb",
        "a\rb", "a\x00b", "\x1b]0;PWNED\x07\x1b[2J", "a\x1b[31mred", "a\x7f", "a\u202eb",
        "=HYPERLINK(\"http://x\",\"y\")", "+1", "-1", "@SUM(A1)", "1abc", "_a", " a", "a ",
        "x" * (NAME_MAX_CHARS + 1), "x" * 200_000, "σ_max", "Δx", "a/b", "a\\b", "a=b", "a%b",
        "a{b}", "a|b", "a\u00a0b", "a\u200bb",
    ]  # fmt: skip
    for _ in range(40):
        cut = rng.randint(1, 10)
        names.append("a" * cut + chr(rng.choice([*range(0, 32), 127, *range(128, 160)])) + "b")
    return names


@pytest.mark.parametrize("name", admitted())
def test_the_rule_admits(name):
    assert name_problem(name) is None
    assert check_name(name) == name
    assert NAME_RULE.fullmatch(name)


@pytest.mark.parametrize("name", refused(), ids=lambda n: repr(n)[:30])
def test_the_rule_refuses_in_one_printable_phrase(name):
    problem = name_problem(name)
    assert problem is not None
    with pytest.raises(ValueError) as info:
        check_name(name, "variable name")
    text = str(info.value)
    assert text.isprintable() and len(text) < 400, text
    suggestion = text.rsplit("e.g. '", 1)[1].rstrip("'")
    assert name_problem(suggestion) is None  # the fix offered obeys the rule


def test_a_final_newline_is_refused_as_any_other():
    # re.match(r"...$") matches before a final newline; the rule is a fullmatch
    assert name_problem("abc\n") is not None and name_problem("abc") is None


# --------------------------------------------------------------------------------------------
# At load: every kind of name, one line, the key path


def _mechanism() -> dict:
    import yaml

    return yaml.safe_load((ROOT / "pipeline/examples/parallel-guide.yaml").read_text())


def _rename_beam(study: dict, name: str) -> None:
    beams = study["geometry"]["beams"]
    beams[name] = beams.pop("upper")


def _rename_output(study: dict, name: str) -> None:
    study["outputs"][name] = study["outputs"].pop("shuttle_x_mm")


def _rename_case(study: dict, name: str) -> None:
    study["load_cases"][name] = study["load_cases"].pop("stroke")


def _rename_body(study: dict, name: str) -> None:
    study["geometry"]["bodies"][name] = study["geometry"]["bodies"].pop("shuttle")


PLACES = {
    "variables[0].name": lambda s, n: s["variables"][0].__setitem__("name", n),
    "requirements[0].name": lambda s, n: s["requirements"][0].__setitem__("name", n),
    "geometry.beams": _rename_beam,
    "geometry.bodies": _rename_body,
    "outputs": _rename_output,
    "load_cases": _rename_case,
}
HOSTILE = ["abc\n", "a\nb,c", "\x1b]0;PWNED\x07\x1b[2J", "=HYPERLINK(\"http://x\",\"y\")",
           "x" * 200_000, "a,b", "-1"]  # fmt: skip


@pytest.mark.parametrize("place", list(PLACES))
@pytest.mark.parametrize("name", HOSTILE, ids=lambda n: repr(n)[:20])
def test_a_hostile_name_is_refused_at_load_in_one_line(tmp_path, capsys, place, name):
    study = _mechanism()
    PLACES[place](study, name)
    if len(name) > 1024 and not place.endswith("name"):
        # YAML itself refuses a mapping key over 1024 characters (the parser's message);
        # the Python API passes the mapping as it is
        with pytest.raises(StudyError) as info:
            validate_study(study)
        assert str(info.value).startswith(place) and len(str(info.value)) < 700
        return
    path = tmp_path / "study.json"
    path.write_text(json.dumps(study))
    out = tmp_path / "out"
    assert main(["evaluate", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.isprintable() is False  # one line (its newline)
    line = err.rstrip("\n")
    assert line.isprintable(), repr(line)  # no control character echoed
    assert place.split("[")[0] in line and "Traceback" not in line
    assert len(line) < 700
    assert not out.exists()  # nothing written


def test_the_examples_names_obey_the_rule():
    from flexopt.pipeline.study import list_examples

    for name in list_examples():
        load_study(ROOT / "pipeline" / "examples" / f"{name}.yaml")  # raises when refused


# --------------------------------------------------------------------------------------------
# Writer and reader agree on every name the rule admits


class NamesGeometry(BaseModel):
    model_config = STUDY_CONFIG

    kind: Literal["toy_names"]
    values: dict[str, float]


class NamesStudy(Study):
    geometry: NamesGeometry
    variables: tuple[VariableSpec, ...]
    optimiser: OptimiserSpec = OptimiserSpec(pop_size=6, n_gen=2, seed=3)


class NamesProblem:
    """Minimise the squared distance to 0.3 of every variable; a metric per variable, of the
    variable's own name (it collides with the variable's column on purpose)."""

    def __init__(self, study: NamesStudy) -> None:
        variables = resolve_variables(study.variables, study.model_dump(mode="json"))
        self.space = variables.space
        self.objective_names = ("error",)
        self.constraint_names = ("feasible",)  # a constraint named as flexopt's own column

    def evaluate(self, x: np.ndarray) -> Evaluation:
        f = float(np.sum((np.asarray(x) - 0.3) ** 2))
        metrics = {name: float(v) for name, v in zip(self.space.names, x, strict=True)}
        return Evaluation(np.array(x), np.array([f]), np.array([x[0] - 0.9]), metrics)

    def detail(self, x: np.ndarray) -> DesignDetail:
        d = np.linspace(0.0, 1.0, 5)
        table = {"displacement_mm": d, "force_N": float(x[0]) * d}
        return DesignDetail(
            self.evaluate(x),
            table,
            {"x": "displacement_mm", "y": "force_N"},
            outline=box(0, 0, 10 + 10 * float(x[0]), 5),
            height_mm=3.0,
        )


register(
    StudyKind(
        "toy_names",
        NamesStudy,
        check=lambda study: None,
        problem=lambda study: NamesProblem(study),  # type: ignore[arg-type]
    )
)

RUN_NAMES = ["feasible", "generation", "x_feasible", "error", "reason", "time_s", "index",
             "tip force", "a[*].b-c", "y" * NAME_MAX_CHARS]  # fmt: skip


def _names_study(names: list[str]) -> dict:
    values = {f"v{k}": 0.5 for k in range(len(names))}
    return {
        "name": "names-toy",
        "geometry": {"kind": "toy_names", "values": values},
        "material": "PLA",
        "variables": [
            {"path": f"geometry.values.v{k}", "bounds": [0.0, 1.0], "name": n}
            for k, n in enumerate(names)
        ],
    }


@pytest.fixture(scope="module")
def names_run(tmp_path_factory) -> Path:
    study = validate_study(_names_study(RUN_NAMES))
    out = tmp_path_factory.mktemp("names") / "run"
    run_study(prepare_run(study), out=out, parallel=ParallelSettings("serial", 1))
    return out


def test_a_run_of_admitted_names_is_read_back_by_report_export_and_the_api(
    names_run, tmp_path, capsys
):
    import shutil

    import flexopt

    run_dir = tmp_path / "run"
    shutil.copytree(names_run, run_dir)
    rows = read_records_csv(run_dir / "evaluations.csv")
    best = json.loads((run_dir / "best.json").read_text())
    assert list(best["parameters"]) == RUN_NAMES  # best.json keys are the names themselves
    # report from evaluations.csv alone (the store moved away): every column read back
    (run_dir / "evaluations.jsonl").unlink()
    outcome = rebuild_report(run_dir)
    assert outcome.n_evaluations == len(rows)
    assert json.loads((run_dir / "best.json").read_text())["parameters"] == best["parameters"]
    # export of a row by its index: the variables' values of that row
    for index in (0, len(rows) - 1):
        out = tmp_path / f"design{index}.stl"
        assert main(["export", str(run_dir), "--design", str(index), "--out", str(out)]) == 0
        assert out.stat().st_size > 0, capsys.readouterr().err
    # the API reads the same table
    result = flexopt.open_run(run_dir)
    assert len(result.evaluations["index"]) == len(rows)


def test_evaluations_csv_keeps_every_admitted_name_as_one_column(names_run):
    header = (names_run / "evaluations.csv").read_text(encoding="utf-8").splitlines()[0]
    rows = read_records_csv(names_run / "evaluations.csv")
    assert len(set(rows[0])) == len(rows[0])  # no column twice
    for name in RUN_NAMES:
        assert name in rows[0] or f"x_{name}" in rows[0], (name, header)
    # no cell of the file can be read as a formula
    for row in rows:
        for cell in [*row.keys(), *row.values()]:
            assert not cell.startswith(("=", "+", "@", "\t", "\r")) or _number(cell), cell


def _number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def test_a_study_error_echoes_no_control_character(tmp_path, capsys):
    study = _mechanism()
    study["\x1b]0;PWNED\x07\x1b[2Jfoo"] = 1  # an unknown key made of escape bytes
    path = tmp_path / "study.json"
    path.write_text(json.dumps(study))
    assert main(["evaluate", str(path), "--out", str(tmp_path / "o")]) == 2
    line = capsys.readouterr().err.rstrip("\n")
    assert "\x1b" not in line and "\x07" not in line and line.isprintable(), repr(line)
    assert "\\x1b" in line  # escaped, still recognisable
    with pytest.raises(StudyError) as info:
        raise StudyError("a\x1b[2Jb", "c\x07d")
    assert str(info.value).isprintable()


def test_a_text_cell_a_spreadsheet_would_run_is_written_as_text():
    from flexopt.pipeline.runfolder import records_to_csv, text_cell

    rows = [
        {"reason": '=HYPERLINK("http://x","y")', "a": -1.5},
        {"reason": "@SUM(A1)", "a": 2.0},
        {"reason": "+1+1", "a": 0.0},
        {"reason": "-2.5", "a": 0.0},  # a number stays a number
        {"reason": "MeshError: the outline could not be meshed", "a": 1.0},
    ]
    text = records_to_csv(rows, ["a", "reason"])
    cells = [line.split(",", 1)[1] for line in text.splitlines()[1:]]
    assert cells[0].startswith("\"'=HYPERLINK") and cells[1] == "'@SUM(A1)"
    assert cells[2] == "'+1+1" and cells[3] == "-2.5" and cells[4].startswith("MeshError")
    assert text.splitlines()[1].startswith("-1.5,")  # numbers as they are
    for lead in ("=", "+", "-", "@", "\t", "\r"):
        assert text_cell(lead + "x").startswith("'")


def test_every_line_the_cli_prints_escapes_control_characters():
    import io
    import logging

    from flexopt.pipeline import cli
    from flexopt.pipeline.errors import printable

    assert printable("a\x1b[2Jb\x07c\u202ed\x9b") == "a\\x1b[2Jb\\x07c\\u202ed\\x9b"
    assert printable("one\ntwo\x1b", keep_newlines=True) == "one\ntwo\\x1b"
    buffer = io.StringIO()
    cli.print("flexopt: warning:", "\x1b]0;PWNED\x07 note", file=buffer)
    assert buffer.getvalue() == "flexopt: warning: \\x1b]0;PWNED\\x07 note\n"
    record = logging.LogRecord("x", logging.WARNING, "f", 1, "bad %s", ("\x1b[2J",), None)
    assert "\x1b" not in cli._PrintableFormatter("%(message)s").format(record)


@pytest.mark.parametrize("name", ["abc\n", "abc\r\n", "a" * 101, "a b"])
def test_the_study_name_is_matched_whole(name):
    study = {**_mechanism(), "name": name}
    with pytest.raises(StudyError) as info:
        validate_study(study)
    assert str(info.value).startswith("name:") and str(info.value).isprintable()
