"""``flexopt report``: rebuild a run folder's report from the evaluations it holds."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.ga import GAResult, best_of, pareto_front
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.parallel import design_key
from flexopt.pipeline.run.folder import (
    RUN_FILES,
    Columns,
    evaluations_csv,
    evaluations_in,
    history_in,
    read_run_record,
    run_folder_study,
)
from flexopt.pipeline.run.setup import prepare_run
from flexopt.pipeline.run.state import RunState
from flexopt.pipeline.runfolder import RunDirLock, lock_run_dir, probe_writable, write_atomic

# --------------------------------------------------------------------------------------------
# flexopt report


@dataclass(frozen=True)
class ReportOutcome:
    """What ``flexopt report`` rebuilt.

    Attributes
    ----------
    run_dir : the run folder.
    best : the best evaluation of every evaluation in the folder.
    n_evaluations : evaluations the report is built from.
    files : files (re)written.
    notes : what was skipped and why.
    """

    run_dir: Path
    best: Evaluation
    n_evaluations: int
    files: tuple[str, ...]
    notes: tuple[str, ...]


def rebuild_report(run_dir: Path) -> ReportOutcome:
    """Rebuild best.json, the best design's response, plots, STL and report.md from a run folder.

    Nothing is optimised again: the evaluations come from the folder (evaluations.jsonl, else
    evaluations.csv); only the best design's detail is solved again, for its response and shape.
    Works on a finished, interrupted or stopped (killed) run (a report of what is done so far);
    run.json, evaluations.csv and the store are only read. It takes the folder's lock, so it is
    refused while a run (or another report) is writing the folder.

    Raises
    ------
    StudyError
        When the folder is not a run folder, a file it reads is damaged (run.json, study.yaml,
        the store, evaluations.csv, history.csv), it holds no evaluation yet or another flexopt
        process holds its lock; nothing is written then.
    OSError
        When the folder cannot be written.
    """
    if not run_dir.is_dir():
        raise StudyError(
            "RUN_DIR", f"'{run_dir}' is not a folder; give a run folder of flexopt run"
        )
    with lock_run_dir(
        run_dir,
        "RUN_DIR",
        f"wait for it to finish (flexopt status {run_dir} shows it), then rebuild the report",
    ) as lock:
        return _rebuild_report(run_dir, lock)


def _rebuild_report(run_dir: Path, lock: RunDirLock) -> ReportOutcome:
    """:func:`rebuild_report` under the folder's lock: read and check everything, then write."""
    record = read_run_record(run_dir)
    study = run_folder_study(run_dir, "RUN_DIR")
    setup = prepare_run(study, quick=bool(record.get("quick", False)))
    problem = setup.problem
    evaluations, notes = evaluations_in(run_dir, problem)
    if not evaluations:
        raise StudyError("RUN_DIR", f"'{run_dir}' holds no evaluation yet; nothing to report")
    columns = Columns.of(problem)
    history = history_in(run_dir, columns)
    rows = evaluations_csv(run_dir, columns, "RUN_DIR") or []
    for name in RUN_FILES:  # what the report may write must not be a folder
        path = run_dir / name
        if path.exists() and not path.is_file():
            raise StudyError(
                "RUN_DIR", f"'{path}' is not a file; move it away so that the report can write it"
            )
    probe_writable(run_dir)
    lock.claim("report")
    run = RunState(setup, run_dir, record, None, None)
    run.notes.extend(notes)
    run.evaluator.solved = list(evaluations)
    run.history = history
    for row in rows:
        x = np.array([float(row[c]) for c in columns.variables])
        run.where.setdefault(design_key(x), (int(row["generation"]), int(row["index"])))
    best = best_of(evaluations)
    n_obj = len(problem.objective_names)
    front = pareto_front(evaluations) if n_obj > 1 else (best,)
    result = GAResult(best, front, ())
    detail = run.finish(result)
    files = list(run.files)
    from flexopt.pipeline.report import ReportData, render_report  # not at a run's start

    report = ReportData(
        record=record,
        study=setup.study,
        problem=problem,
        best=best,
        best_where=run.where.get(design_key(best.x), (None, None)),
        front=front,
        detail=detail,
        files=tuple([*record.get("files", []), *files]),
        notes=tuple(run.notes),
        stl=run.stl,
    )
    write_atomic(run_dir / "report.md", render_report(report))
    files.append("report.md")
    return ReportOutcome(run_dir, best, len(evaluations), tuple(files), tuple(run.notes))
