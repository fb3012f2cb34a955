"""A run folder's files: the CSV columns, the tables written each generation and read back,
run.json and study.yaml of a folder."""

from __future__ import annotations

import os
import socket
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import DesignProblem
from flexopt.optimise.space import DesignSpace
from flexopt.pipeline.checkpoint import STORE_FILE, EvaluationStore
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.runfolder import (
    cell_float,
    echo,
    load_folder_study,
    read_folder_csv,
    read_run_json,
    write_atomic,
)
from flexopt.pipeline.study import Study

#: Files a finished run folder can hold (plots, STL and the response only when the kind gives what
#: they need). run.json is written first and last: its ``status`` says whether the run finished.
RUN_FILES = (
    "study.yaml",
    "run.json",
    "evaluations.csv",
    "evaluations.jsonl",
    "checkpoint.json",
    "history.csv",
    "best.json",
    "best_response.csv",
    "force_displacement.png",
    "stress.png",
    "convergence.png",
    "shapes.png",
    "stress_map.png",
    "stress_deformed.png",
    "front.png",
    "best.stl",
    "best.dxf",
    "best.step",
    "best.vtu",
    "best.pvd",  # its load steps in the folder best_steps/ (pipeline/vtu.py)
    "best_3d.vtu",
    "best_cad.py",
    "best.3mf",
    "print_sheet.md",
    "report.md",
    "report.html",
)


@dataclass
class Columns:
    """CSV column names of the variables, objectives, constraints and metrics, made unique."""

    variables: tuple[str, ...] = ()
    objectives: tuple[str, ...] = ()
    constraints: tuple[str, ...] = ()
    metric_names: dict[str, str] = field(default_factory=dict)
    used: set[str] = field(
        default_factory=lambda: {"generation", "index", "feasible", "reason", "time_s"}
    )

    def _unique(self, name: str, prefix: str) -> str:
        column = name if name not in self.used else f"{prefix}_{name}"
        while column in self.used:
            column = f"{prefix}_{column}"
        self.used.add(column)
        return column

    @classmethod
    def of(cls, problem: DesignProblem) -> Columns:
        columns = cls()
        columns.variables = tuple(columns._unique(n, "x") for n in problem.space.names)
        columns.objectives = tuple(columns._unique(n, "objective") for n in problem.objective_names)
        columns.constraints = tuple(
            columns._unique(n, "constraint") for n in problem.constraint_names
        )
        return columns

    @classmethod
    def of_space(cls, space: DesignSpace) -> Columns:
        """The variables' columns alone (as :meth:`of` names them: they come first)."""
        columns = cls()
        columns.variables = tuple(columns._unique(n, "x") for n in space.names)
        return columns

    def metric(self, key: str) -> str:
        if key not in self.metric_names:
            self.metric_names[key] = self._unique(key, "metric")
        return self.metric_names[key]

    def row(self, generation: int, index: int, ev: Evaluation) -> dict[str, Any]:
        row: dict[str, Any] = {"generation": generation, "index": index}
        row.update(zip(self.variables, map(float, ev.x), strict=True))
        row.update(zip(self.objectives, map(float, ev.f), strict=True))
        row.update(zip(self.constraints, map(float, ev.g), strict=True))
        row["feasible"] = ev.feasible
        for key, value in ev.metrics.items():
            row[self.metric(str(key))] = value
        row["reason"] = ev.reason
        row["time_s"] = float(ev.time_s)
        return row

    def header(self) -> list[str]:
        return [
            "generation",
            "index",
            *self.variables,
            *self.objectives,
            *self.constraints,
            "feasible",
            *self.metric_names.values(),
            "reason",
            "time_s",
        ]


def write_files(run_dir: Path, files: Iterable[Any]) -> None:
    """Write each (name, text) into ``run_dir`` atomically, in order; an item may also be a
    callable that returns such pairs (formatted here, on the writer thread)."""
    for item in files:
        for name, text in item() if callable(item) else (item,):
            write_atomic(run_dir / name, text)


def _pid_alive(pid: Any) -> bool:
    try:
        os.kill(int(pid), 0)
    except (OSError, TypeError, ValueError):
        return False
    return True


def run_is_live(record: Mapping[str, Any]) -> bool:
    """Whether the process that wrote ``record`` (status running) still runs on this host."""
    return (
        record.get("status") == "running"
        and record.get("hostname") == socket.gethostname()
        and record.get("pid") != os.getpid()
        and _pid_alive(record.get("pid"))
    )


def read_run_record(run_dir: Path, option: str = "RUN_DIR") -> dict[str, Any]:
    """run.json of a run folder, every field a command relies on checked
    (:func:`pipeline.runfolder.read_run_json`).

    Raises
    ------
    StudyError
        At ``option`` when the folder is not a run folder of ``flexopt run`` or its run.json is
        damaged (the message names the file, what is wrong and what to do).
    """
    return read_run_json(run_dir, option)


def run_folder_study(run_dir: Path, option: str) -> Study:
    """The study.yaml of a run folder (a missing one is named as such, not as an example)."""
    path = run_dir / "study.yaml"
    if not path.exists():
        raise StudyError(
            option, f"'{run_dir}' has no study.yaml; give a run folder written by flexopt run"
        )
    if not path.is_file():
        raise StudyError(
            option,
            f"'{path}' is not a file; restore the run's study.yaml (the resolved study the run "
            "started with) from a copy",
        )
    return load_folder_study(run_dir, path)


def csv_fix(run_dir: Path) -> str:
    return (
        "was it edited or cut short? restore it from a copy, or move it away (flexopt report "
        "works from the store evaluations.jsonl without it)"
    )


def evaluations_csv(run_dir: Path, columns: Columns, option: str) -> list[dict[str, str]] | None:
    """evaluations.csv, checked: its columns are the study's, its indices and designs numbers."""
    path = run_dir / "evaluations.csv"
    fix = csv_fix(run_dir)
    required = ["generation", "index", *columns.variables, *columns.objectives]
    rows = read_folder_csv(path, option, fix, [*required, *columns.constraints])
    if rows is None:
        return None
    for number, row in enumerate(rows, 2):
        where = f"'{path}' line {number}"
        for column in ("generation", "index"):
            if not row[column].isdigit():
                raise StudyError(
                    option,
                    f"{where}, column {column}: {echo(row[column])} is not a whole number; {fix}",
                )
        for column in required[2:] + list(columns.constraints):
            cell_float(row, column, where, option, fix)
        time_s = row.get("time_s", "")
        if time_s:
            cell_float(row, "time_s", where, option, fix)
    return rows


def evaluations_in(
    run_dir: Path, problem: DesignProblem, option: str = "RUN_DIR"
) -> tuple[list[Evaluation], list[str]]:
    """The run's evaluations (the lossless store, or evaluations.csv in a folder without one)
    and notes on what was skipped (a torn last line of the store). Nothing is written.

    Raises
    ------
    StudyError
        For a damaged store or evaluations.csv (naming the file, the line and the fix).
    """
    store = EvaluationStore(run_dir / STORE_FILE)
    n_var, n_obj = problem.space.n_var, len(problem.objective_names)
    n_con = len(problem.constraint_names)
    if store.path.exists() or store.path.is_symlink():  # a folder there is refused by load
        return store.load(n_var, n_obj, n_con, option=option), list(store.notes)
    columns = Columns.of(problem)
    rows = evaluations_csv(run_dir, columns, option)
    out = []
    for row in rows or []:
        out.append(
            Evaluation(
                np.array([float(row[c]) for c in columns.variables]),
                np.array([float(row[c]) for c in columns.objectives]),
                np.array([float(row[c]) for c in columns.constraints]),
                {},
                row.get("reason", ""),
                float(row.get("time_s") or 0.0),
            )
        )
    return out, []


def history_in(run_dir: Path, columns: Columns | None = None) -> list[dict[str, Any]]:
    """history.csv with its numbers and booleans read back (checked when ``columns`` are given:
    the columns the convergence plot reads are there and hold numbers)."""
    path = run_dir / "history.csv"
    fix = (
        "was it edited or cut short? restore it from a copy, or delete it (the report then has "
        "no convergence plot)"
    )
    numeric = ["generation", "feasible_fraction"]
    if columns is not None:
        numeric += [f"best_{name}" for name in columns.objectives]
    required = [*numeric, "best_feasible"] if columns is not None else []
    rows = read_folder_csv(path, "RUN_DIR", fix, required)
    if rows is None:
        return []
    for number, row in enumerate(rows, 2):
        where = f"'{path}' line {number}"
        for column in numeric if columns is not None else ():
            cell_float(row, column, where, "RUN_DIR", fix)
        if columns is not None and row["best_feasible"] not in ("true", "false"):
            raise StudyError(
                "RUN_DIR",
                f"{where}, column best_feasible: {echo(row['best_feasible'])} is not true or "
                f"false; {fix}",
            )

    def value(text: str) -> Any:
        if text in ("true", "false"):
            return text == "true"
        try:
            return float(text)
        except ValueError:
            return text

    return [{k: value(v) for k, v in row.items()} for row in rows]
