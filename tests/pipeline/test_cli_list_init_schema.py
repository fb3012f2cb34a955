"""``flexopt list``, ``flexopt init`` and ``flexopt schema`` (issue 14, item 2).

- ``list``: every kind and every built-in study, one line each with what it designs;
- ``init``: a commented starter study that loads as written, for every kind and every built-in
  study; never overwrites a file;
- ``schema``: the JSON schema of a study; every shipped study is valid under its kind's schema
  and under the schema of any kind (checked with ``jsonschema`` where it is installed).

Every bad input is one line on stderr with exit 2. All in this process (the plugin side, through
real subprocesses, is tests/pipeline/test_plugins.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from flexopt.pipeline.cli import main
from flexopt.pipeline.init_study import default_example, example_kinds, starter_study, study_schema
from flexopt.pipeline.studies import builtin_kind_names, kinds
from flexopt.pipeline.study import list_examples, load_study, resolve_study_path

ROOT = Path(__file__).resolve().parents[2]
KINDS = sorted(builtin_kind_names())
EXAMPLES = list_examples()


def one_line_error(capsys, code: int, prog: str) -> str:
    """The error line of a refused command (exit 2, nothing on stdout, no traceback)."""
    captured = capsys.readouterr()
    assert code == 2, captured.err
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and captured.err.startswith(f"{prog}: error: ")
    assert "Traceback" not in captured.err
    return captured.err


# --------------------------------------------------------------------------------------------
# list


def test_list_names_every_kind_and_study_on_one_line(capsys):
    assert main(["list"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    lines = captured.out.splitlines()
    heading = next(i for i, line in enumerate(lines) if "Built-in studies" in line)
    rows = {line.split()[0]: line for line in lines[:heading] if line.startswith("  ")}
    for name in KINDS:
        words = rows[name].split()
        assert words[1] == "built-in" and len(words) > 4  # and what it designs
    assert "one planar beam along a polyline" in rows["polyline_beam"]
    # a study and a kind may share a name (gripper): look studies up below their heading
    study_rows = lines[heading:]
    for name in EXAMPLES:
        row = next(line for line in study_rows if line.split()[:1] == [name])
        assert row.split()[1] == example_kinds()[name] and len(row.split()) > 4
    assert "A straight ABS cantilever" in next(r for r in study_rows if "cantilever" in r)
    assert "Unavailable" not in captured.out  # no plugin is broken here


def test_every_builtin_kind_has_an_example():
    # init copies the kind's example with its comments: a kind without one would get a
    # starter generated from its schema, which need not load as written
    assert {kind for kind in example_kinds().values()} >= set(KINDS)
    assert default_example("polyline_beam") == "cantilever"
    assert default_example("constant_force") == "constant-force"


# --------------------------------------------------------------------------------------------
# init


@pytest.mark.parametrize("kind", KINDS)
def test_init_writes_a_study_of_each_kind_that_loads_as_written(kind, tmp_path, capsys):
    out = tmp_path / "mine.yaml"
    assert main(["init", "mine", "--kind", kind, "--out", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    text = out.read_text()
    assert text.startswith(f"# mine: a starter study of kind {kind}")
    assert f"flexopt evaluate {out}" in text and f"flexopt schema --kind {kind}" in text
    example = default_example(kind)
    # the example's own comments are kept
    first_comment = resolve_study_path(example).read_text().splitlines()[0]
    assert first_comment in text
    study = load_study(out)
    assert study.name == "mine" and study.kind == kind
    # the same study as the example, but for its name
    assert study.model_dump(exclude={"name"}) == load_study(example).model_dump(exclude={"name"})


@pytest.mark.parametrize("example", EXAMPLES)
def test_init_from_every_builtin_study(example, tmp_path):
    assert main(["init", "copy-1", "--example", example, "--out", str(tmp_path / "c.yaml")]) == 0
    study = load_study(tmp_path / "c.yaml")
    assert study.name == "copy-1" and study.kind == example_kinds()[example]


def test_init_default_kind_evaluates_from_the_cli(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["init", "my_beam"]) == 0
    assert capsys.readouterr().out == "wrote my_beam.yaml; try: flexopt evaluate my_beam.yaml\n"
    assert load_study("my_beam.yaml").kind == "polyline_beam"
    assert main(["evaluate", "my_beam.yaml", "--out", "ev"]) == 0
    record = json.loads((tmp_path / "ev" / "evaluation.json").read_text())
    assert record["study"] == "my_beam" and record["converged"]


def test_init_never_overwrites(tmp_path, capsys):
    out = tmp_path / "taken.yaml"
    out.write_text("mine, not flexopt's\n")
    err = one_line_error(capsys, main(["init", "x", "--out", str(out)]), "flexopt init")
    assert f"{out} exists" in err
    assert out.read_text() == "mine, not flexopt's\n"
    # a dangling symlink is refused too (writing through it would create its target)
    link = tmp_path / "link.yaml"
    link.symlink_to(tmp_path / "nowhere.yaml")
    one_line_error(capsys, main(["init", "x", "--out", str(link)]), "flexopt init")
    assert not (tmp_path / "nowhere.yaml").exists()


def test_init_makes_the_folder(tmp_path):
    out = tmp_path / "new" / "folder" / "s.yaml"
    assert main(["init", "s", "--out", str(out)]) == 0
    assert load_study(out).name == "s"
    # an existing folder as --out: NAME.yaml inside it
    assert main(["init", "t", "--out", str(out.parent)]) == 0
    assert load_study(out.parent / "t.yaml").name == "t"


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["init", "bad name"], "cannot name a study"),
        (["init", "../escape"], "cannot name a study"),
        (["init", "x" * 101], "cannot name a study"),
        (
            ["init", "x", "--kind", "no_such_kind"],
            "--kind: unknown kind 'no_such_kind'; use one of",
        ),
        (["init", "x", "--example", "no-such"], "no built-in study named 'no-such'"),
        (["init", "x", "--kind", "cam", "--example", "cantilever"], "not allowed with"),
        (["init", "x", "--out", ""], "is empty"),
        (["init"], "required: NAME"),
        (["schema", "--kind", "no_such_kind"], "--kind: unknown kind 'no_such_kind'"),
        (["schema", "--out", " "], "is empty"),
        (["schema", "extra"], "unrecognized arguments"),
        (["list", "extra"], "unrecognized arguments"),
    ],
)
def test_bad_input_is_one_line_exit_2(argv, words, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    # argparse reports words left over at the top parser, as "flexopt: error:"
    prog = "flexopt" if words == "unrecognized arguments" else f"flexopt {argv[0]}"
    err = one_line_error(capsys, main(argv), prog)
    assert words in err
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_starter_from_the_schema_for_a_kind_without_an_example():
    # what a plugin kind gets (tests/pipeline/flexopt_toys.py's toy kind stands in for one)
    import flexopt_toys  # noqa: F401  (registers toy_faults)

    text = starter_study("toy", "toy_faults")
    assert "from its schema" in text
    assert "  kind: toy_faults  # required" in text
    assert "  # hang_s: 30.0" in text  # optional keys commented out, with their defaults
    assert "material: PLA  # required: a library name" in text
    raw = yaml.safe_load(text)
    assert raw == {"name": "toy", "geometry": {"kind": "toy_faults"}, "material": "PLA"}


# --------------------------------------------------------------------------------------------
# schema


def test_schema_of_any_kind(capsys, tmp_path):
    assert main(["schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert len(schema["oneOf"]) == len(kinds())
    out = tmp_path / "s" / "flexopt.schema.json"
    assert main(["schema", "--out", str(out)]) == 0
    assert json.loads(out.read_text()) == schema
    assert capsys.readouterr().out == f"wrote {out}\n"


@pytest.mark.parametrize("kind", KINDS)
def test_schema_of_each_kind(kind, capsys):
    assert main(["schema", "--kind", kind]) == 0
    schema = json.loads(capsys.readouterr().out)
    geometry = schema["properties"]["geometry"]["$ref"].split("/")[-1]
    assert schema["$defs"][geometry]["properties"]["kind"]["const"] == kind
    material = schema["properties"]["material"]
    assert "PLA" in material["anyOf"][0]["enum"]  # a library name is a material too


def test_every_shipped_study_is_valid_under_the_schemas():
    jsonschema = pytest.importorskip("jsonschema")
    any_kind = jsonschema.Draft202012Validator(study_schema())
    jsonschema.Draft202012Validator.check_schema(study_schema())
    for name, kind in example_kinds().items():
        data = yaml.safe_load(resolve_study_path(name).read_text())
        of_kind = jsonschema.Draft202012Validator(study_schema(kind))
        assert [e.message for e in of_kind.iter_errors(data)] == [], name
        assert [e.message for e in any_kind.iter_errors(data)] == [], name
    wrong = {"name": "x", "geometry": {"kind": "polyline_beam", "width_mm": "wide"}}
    assert list(any_kind.iter_errors(wrong))


def test_usage_docs_show_the_editor_hook():
    usage = (ROOT / "docs" / "usage.md").read_text()
    assert "flexopt schema" in usage and "# yaml-language-server: $schema=" in usage
    assert "flexopt init" in usage and "flexopt list" in usage
    plugins = (ROOT / "docs" / "plugins.md").read_text()
    assert '[project.entry-points."flexopt.kinds"]' in plugins


def test_the_command_skips_the_teardown_but_not_the_exit_handlers(tmp_path):
    """cli.entry (the `flexopt` command) ends the process with os._exit after main: a plugin's
    atexit handler still runs and the printed output is complete; a non-daemon thread still
    running gets the normal exit, which waits for it."""
    import subprocess
    import sys

    code = (
        "import atexit, sys, threading, time\n"
        "atexit.register(lambda: print('handler ran', flush=True))\n"
        "if sys.argv[1] == 'thread':\n"
        "    threading.Thread(target=lambda: (time.sleep(0.5), print('thread done'))).start()\n"
        "sys.argv = ['flexopt', 'list']\n"
        "from flexopt.pipeline.cli import entry\n"
        "entry()\n"
    )
    for mode in ("plain", "thread"):
        out = subprocess.run(
            [sys.executable, "-c", code, mode], capture_output=True, text=True, timeout=120
        )
        assert out.returncode == 0, out.stderr
        assert "constant-force" in out.stdout and "handler ran" in out.stdout
        assert ("thread done" in out.stdout) == (mode == "thread")
    bad = subprocess.run(
        [sys.executable, "-m", "flexopt.pipeline.cli", "run", "no-such-study"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert bad.returncode == 2 and "no-such-study" in bad.stderr
