"""What ``flexopt run`` and ``flexopt status`` show of a hybrid run (issue #27): the GA stage's
generations as ``gen k/n``, the gradient stage's batches as ``gradient step k (evaluations m)``,
the "writing ..." line once at the real end; a GA run's lines as before."""

from __future__ import annotations

import json
import re

import flexopt_toys  # registers the toy_faults kind
from flexopt.pipeline.parallel import ParallelSettings
from flexopt.pipeline.progress import RunProgress
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.status import format_status, run_status
from flexopt.pipeline.study import validate_study

SERIAL = ParallelSettings("serial")
WRITING = "writing the best design's response, plots, STL and report"


def shown_lines(tmp_path, capsys, **optimiser):
    """The progress lines (stderr, not a terminal) of a toy run, rates masked, and its folder."""
    raw = flexopt_toys.study()
    raw["optimiser"] = {"pop_size": 8, "n_gen": 3, "seed": 5, **optimiser}
    progress = RunProgress(quiet=False)
    run_dir = tmp_path / "run"
    capsys.readouterr()
    run_study(
        prepare_run(validate_study(raw)),
        out=run_dir,
        parallel=SERIAL,
        on_start=progress.start,
        on_generation=progress.generation,
        on_result=progress.result,
    )
    progress.stop()
    text = capsys.readouterr().err
    text = re.sub(r"\S+ eval/s", "R eval/s", text)
    return text.splitlines()[1:], run_dir  # the first line names the (temporary) folder


def test_a_ga_runs_lines_are_unchanged(tmp_path, capsys):
    lines, run_dir = shown_lines(tmp_path, capsys)
    # as printed before the hybrid's stages were told apart (integration branch 1fd2ba6)
    assert lines == [
        "ga: 8 designs x 3 generations, seed 5, on serial (this process)",
        "gen 1/3  best 0.3702  feasible 38%  R eval/s",
        "gen 2/3  best 0.3683  feasible 62%  R eval/s",
        "gen 3/3  best 0.3683  feasible 88%  R eval/s",
        WRITING,
    ]
    shown = format_status(run_status(run_dir)).splitlines()
    assert "generation   3/3" in shown
    assert not any(line.startswith("gradient") for line in shown)
    record = json.loads((run_dir / "run.json").read_text())
    assert "gradient_steps" not in record and "stage" not in record


def test_a_hybrid_run_shows_its_stages_apart(tmp_path, capsys):
    lines, run_dir = shown_lines(
        tmp_path, capsys, method="hybrid", hybrid={"starts": 2, "max_iter": 20}
    )
    record = json.loads((run_dir / "run.json").read_text())
    assert lines[:4] == [
        "ga: 8 designs x 3 generations, seed 5, on serial (this process)",
        "gen 1/3  best 0.3702  feasible 38%  R eval/s",
        "gen 2/3  best 0.3683  feasible 62%  R eval/s",
        "gen 3/3  best 0.3683  feasible 88%  R eval/s",
    ]
    # no generation beyond the GA's n_gen; the gradient steps numbered 1, 2, ...; the
    # "writing ..." line once, after the last of them
    assert not any(re.match(r"gen \d+/3", line) for line in lines[4:])
    steps = lines[4:-1]
    assert len(steps) == record["gradient_steps"] == record["generations_done"] - 3 > 1
    evaluations = []
    for k, line in enumerate(steps, 1):
        match = re.match(rf"gradient step {k} \(evaluations (\d+)\)  best \S+  feasible", line)
        assert match, line
        evaluations.append(int(match.group(1)))
    assert evaluations == sorted(evaluations) and evaluations[-1] == record["n_evaluations"]
    assert lines[-1] == WRITING and lines.count(WRITING) == 1
    assert record["stage"] == "gradient" and record["ga_generations"] == 3
    shown = format_status(run_status(run_dir)).splitlines()
    assert "generation   3/3" in shown
    n = record["n_evaluations"]
    assert f"gradient     step {len(steps)} (evaluations {n})" in shown
