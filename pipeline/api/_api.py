"""The functions of ``import flexopt``: load a study, evaluate it, optimise it, read a run back.

They take the same code paths as the command line (``flexopt evaluate``, ``flexopt run``,
``flexopt list``) and return values instead of printing. Every bad input is a
:class:`~flexopt.pipeline.errors.StudyError` (a ``ValueError``) naming where: a study key path
(``geometry.width_mm``), an argument (``workers``) or the run folder (``run_dir``).
"""

from __future__ import annotations

import os
import statistics
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from flexopt.pipeline.errors import StudyError

from ._result import BestDesign, Result, RunResult, finite_or_nan, readonly_table

if TYPE_CHECKING:
    from flexopt.optimise.requirements import Verdict
    from flexopt.pipeline.study import Study

__all__ = [
    "KindInfo",
    "StudyInfo",
    "evaluate",
    "list_kinds",
    "list_studies",
    "load_study",
    "open_run",
    "run",
]

StudyLike = Any  # a Study, a file path, a built-in study name or a mapping


class StudyInfo(NamedTuple):
    """A built-in study (``flexopt list``): its name, its kind and what it designs."""

    name: str
    kind: str
    summary: str


class KindInfo(NamedTuple):
    """A study kind (``flexopt list``): its name (``geometry.kind``), ``built-in`` or
    ``plugin``, and what it designs."""

    name: str
    origin: str
    summary: str


def list_studies() -> list[StudyInfo]:
    """Every built-in study, as ``flexopt list`` shows them (load one with :func:`load_study`)."""
    from flexopt.pipeline.init_study import catalogue

    return [StudyInfo(*row) for row in catalogue().studies]


def list_kinds() -> list[KindInfo]:
    """Every available study kind, built-in and from plugins, as ``flexopt list`` shows them."""
    from flexopt.pipeline.init_study import catalogue

    return [KindInfo(*row) for row in catalogue().kinds]


# --------------------------------------------------------------------------------------------
# Studies


def load_study(study: StudyLike, source: str | None = None) -> Study:
    """A validated, frozen study from a file, a built-in study's name or a mapping.

    Parameters
    ----------
    study : str, os.PathLike, mapping or Study
        The path of a study YAML file; the name of a built-in study (``flexopt list``:
        ``"cantilever"``, ``"constant-force"``, ...); or the study as a mapping, as the YAML file
        would hold it. A Study is returned as it is.
    source : str, optional
        Names the study in error messages (default: the file's path).

    Returns
    -------
    Study
        Change it with ``study.replace(name=...)`` or ``study.with_values({path: value})``, each
        returning a new validated study.

    Raises
    ------
    StudyError
        For a file that is missing or not a study, and for an invalid study, naming the key
        path and the fix (``geometry.thickness_mm: needs one value per point ...``).
    """
    return _study_and_source(study, source)[0]


def _study_and_source(study: StudyLike, source: str | None = None) -> tuple[Study, str]:
    from flexopt.pipeline import study as studies

    if isinstance(study, studies.Study):
        return study, source or ""
    if isinstance(study, Mapping):
        from flexopt.pipeline.study_edit import plain

        studies.check_data_limits(study, source or "")  # a YAML file's limits, before a copy
        return studies.validate_study(plain(study), source=source), source or ""
    if isinstance(study, str | os.PathLike):
        path = studies.resolve_study_path(os.fspath(study))
        where = source or str(path)
        text = studies.read_study_file(path)
        return studies.validate_study(studies.parse_study_text(text, where), where), str(path)
    raise StudyError(
        "",
        f"a study is a file path, a built-in study name or a mapping, not {type(study).__name__}"
        "; e.g. flexopt.load_study('cantilever')",
        source=source,
    )


def _flag(value: Any, name: str) -> bool:
    """A yes/no argument: ``True`` or ``False`` (numpy's too), never a string or a number
    (``quick='no'`` would be true)."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    raise StudyError(name, f"got {value!r}; give True or False")


# --------------------------------------------------------------------------------------------
# Evaluate


def _whole(value: Any, name: str, smallest: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < smallest:
        raise StudyError(name, f"got {value!r}; give a whole number >= {smallest}")
    return int(value)


def _out_path(out: Any) -> Path | None:
    if out is None:
        return None
    if not isinstance(out, str | os.PathLike) or not os.fspath(out).strip():
        raise StudyError("out", f"got {out!r}; give the folder's path (str or Path)")
    return Path(out)


def evaluate(study: StudyLike, repeat: int = 1, out: str | os.PathLike | None = None) -> Result:
    """Solve a study once with its kind's analysis, as ``flexopt evaluate`` does.

    The solve runs with the BLAS/OpenMP pools at one thread (its systems are too small for more
    to pay; :func:`pipeline.fork.limit_loaded_pools`); the caller's limits are back on return.

    Parameters
    ----------
    study : Study, or anything :func:`load_study` takes
    repeat : int
        Solve this many times; ``solve_time_s`` is the median (s).
    out : path, optional
        Also write the evaluate folder there, exactly as ``flexopt evaluate --out`` writes it
        (response.csv, evaluation.json, study.yaml, force_displacement.png); by default nothing
        is written.

    Returns
    -------
    Result
        ``.table`` (response columns), ``.summary``, ``.verdict``, ``.met``, ``.plot()``, ...

    Raises
    ------
    StudyError
        For an invalid study or argument, a kind that is only optimised (use :func:`run`) or
        inputs the solver refuses. A solve that does not converge is a result
        (``converged=False``), not an error.
    """
    from flexopt.pipeline.durability_report import durability_record
    from flexopt.pipeline.evaluate import (
        MAX_REPEAT,
        case_plot_args,
        evaluate_study,
        response_plot_args,
        response_table,
        solve_study,
    )

    repeat = _whole(repeat, "repeat", 1)
    if repeat > MAX_REPEAT:
        raise StudyError(
            "repeat", f"got {repeat}; give at most {MAX_REPEAT} (repeats only time the solve)"
        )
    folder = _out_path(out)
    study, source = _study_and_source(study)
    if folder is None:
        result, run_dir = solve_study(study, repeat, source), None
    else:
        outcome = evaluate_study(study, out=folder, repeat=repeat, source=source)
        result, run_dir = outcome.result, outcome.run_dir
    if result.cases:  # every load case: a load_case column, one panel per case
        plot_args = case_plot_args(study, result)
    else:
        plot_args = response_plot_args(study, result)
    return Result(
        study=study,
        table=readonly_table(response_table(result)),
        summary=dict(result.summary),
        verdict=tuple(result.verdicts),
        converged=bool(result.converged),
        message=result.message,
        solve_time_s=float(statistics.median(result.solve_times_s)),
        run_dir=run_dir,
        plot_args=plot_args,
        cases={name: readonly_table(c.table) for name, c in result.cases.items()},
        durability=durability_record(study, result),
    )


# --------------------------------------------------------------------------------------------
# Run


def run(
    study: StudyLike,
    *,
    workers: int | None = None,
    dask: str | None = None,
    quick: bool = False,
    seed: int | None = None,
    out: str | os.PathLike | None = None,
    progress: bool = False,
) -> RunResult:
    """Optimise a study as ``flexopt run`` does, into a run folder, and read the result back.

    With ``workers=1`` the designs are solved in this process with the BLAS/OpenMP pools at one
    thread, as in a pool's workers; the caller's limits are back for the report and on return.

    Parameters
    ----------
    study : Study, or anything :func:`load_study` takes
    workers : int, optional
        Worker processes (default: the study's ``parallel.workers``, else one per core; 1 solves
        in this process).
    dask : str, optional
        Evaluate on the Dask cluster whose scheduler is at this address (``tcp://host:8786``).
    quick : bool
        A small smoke run: ``optimiser.quick_pop_size`` designs for ``optimiser.quick_n_gen``
        generations.
    seed : int, optional
        Replaces ``optimiser.seed`` (the same seed gives the same run).
    out : path, optional
        The run folder (must not hold a run yet); default ``runs/<name>-run-<timestamp>``.
    progress : bool
        Show the run folder and one line per generation on stderr (default: quiet).

    Returns
    -------
    RunResult
        ``.best``, ``.front``, ``.evaluations``, ``.verdict``, ``.run_dir``, ...

    Raises
    ------
    StudyError
        For an invalid study or argument, a kind with nothing to optimise, or an ``out`` that
        holds a run already; nothing is written then.
    KeyboardInterrupt
        After the run folder records what was done (resume it with ``flexopt run --resume``).
    """
    from flexopt.pipeline.run import parallel_settings, prepare_run, run_study
    from flexopt.pipeline.study import workers_problem

    quick = _flag(quick, "quick")
    progress = _flag(progress, "progress")
    study, source = _study_and_source(study)
    if workers is not None:
        workers = _whole(workers, "workers", 1)
        problem = workers_problem(workers)
        if problem:
            raise StudyError("workers", problem)
    if dask is not None and not isinstance(dask, str):
        raise StudyError("dask", f"got {dask!r}; give the scheduler address, tcp://host:8786")
    if seed is not None:
        seed = _whole(seed, "seed", 0)
    folder = _out_path(out)
    setup = prepare_run(study, quick=bool(quick), seed=seed)
    settings = parallel_settings(study, workers, dask, None)
    given = {"workers": workers, "dask": dask, "quick": quick or None, "seed": seed, "out": out}
    arguments = ", ".join(f"{k}={v!r}" for k, v in given.items() if v is not None)
    callbacks: dict[str, Any] = {
        "command_line": f"flexopt.run({source or study.name!r}{', ' if arguments else ''}"
        f"{arguments})"
    }
    shown = None
    if progress:
        from flexopt.pipeline.progress import RunProgress

        shown = RunProgress(quiet=False)
        callbacks.update(
            on_start=shown.start, on_generation=shown.generation, on_result=shown.result
        )
    try:
        outcome = run_study(setup, out=folder, source=source, parallel=settings, **callbacks)
    finally:
        if shown is not None:
            shown.stop()
    return read_run(outcome.run_dir, verdicts=outcome.verdicts)


def open_run(run_dir: str | os.PathLike) -> RunResult:
    """Read a run folder of ``flexopt run`` (or :func:`run`) back: nothing is solved again.

    Raises
    ------
    StudyError
        At ``run_dir`` when it is not a run folder, the run has no best design yet (still
        running, or stopped: finish it with ``flexopt run --resume``), or run.json, best.json
        or evaluations.csv is damaged; the message names the file, what is wrong and the fix.
    """
    folder = _out_path(run_dir)
    if folder is None:
        raise StudyError("run_dir", "got None; give the path of a run folder")
    return read_run(folder)


# --------------------------------------------------------------------------------------------
# Reading a run folder

_OPTION = "run_dir"


def _best_fix(run_dir: Path) -> str:
    return f"restore it from a copy, or write it again with flexopt report {run_dir}"


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _numbers(
    value: Any, names: list[str] | None, key: str, where: str, fix: str
) -> dict[str, float]:
    """A best.json mapping of names to numbers (null: NaN), with the run's names if known."""
    ok = isinstance(value, dict) and all(v is None or _is_number(v) for v in value.values())
    if ok and names is not None and list(value) != names:
        ok = False
    if not ok:
        wanted = f" of {', '.join(names)}" if names is not None else ""
        raise StudyError(_OPTION, f"{where}: {key} is not a mapping of numbers{wanted}; {fix}")
    return {str(k): finite_or_nan(v) for k, v in value.items()}


def _verdicts(value: Any, where: str, fix: str) -> tuple[Verdict, ...]:
    """Verdicts from best.json's ``verdict`` record (``optimise.requirements.verdict_record``)."""
    from flexopt.optimise.requirements import Verdict

    if value is None:
        return ()
    items = value.get("requirements") if isinstance(value, dict) else None
    if not isinstance(items, list):
        raise StudyError(_OPTION, f"{where}: verdict has no list of requirements; {fix}")
    out = []
    for i, item in enumerate(items):
        try:
            if not isinstance(item, dict):
                raise TypeError("not a mapping")
            fields = {k: v for k, v in item.items() if k != "verdict"}
            for key in ("value", "margin"):
                fields[key] = finite_or_nan(fields.get(key))
            verdict = Verdict(**fields)
            if not isinstance(verdict.met, bool) or not isinstance(verdict.name, str):
                raise TypeError("met is not true/false or name not text")
        except (TypeError, ValueError) as exc:
            raise StudyError(
                _OPTION, f"{where}: verdict.requirements[{i}] is not a verdict ({exc}); {fix}"
            ) from None
        out.append(verdict)
    return tuple(out)


def _design(
    data: Any, record: Mapping[str, Any], where: str, fix: str, verdicts: Any = None
) -> BestDesign:
    if not isinstance(data, dict):
        raise StudyError(_OPTION, f"{where} is not a mapping; {fix}")
    names = record.get("variables")
    x = data.get("x")
    if (
        not isinstance(x, list)
        or not all(_is_number(v) for v in x)
        or (names is not None and len(x) != len(names))
    ):
        n = f"{len(names)} " if names is not None else ""
        raise StudyError(_OPTION, f"{where}: x is not a list of {n}numbers; {fix}")
    if names is None:
        names = list(_numbers(data.get("parameters"), None, "parameters", where, fix))
    objectives = _numbers(
        data.get("objectives"), record.get("objectives"), "objectives", where, fix
    )
    constraints = _numbers(
        data.get("constraints", {}), record.get("constraints"), "constraints", where, fix
    )
    metrics = data.get("metrics", {})
    feasible = data.get("feasible")
    if not isinstance(metrics, dict) or not isinstance(feasible, bool):
        raise StudyError(_OPTION, f"{where}: metrics or feasible is missing or damaged; {fix}")
    place = [data.get("generation"), data.get("index")]
    if not all(v is None or (isinstance(v, int) and not isinstance(v, bool)) for v in place):
        raise StudyError(_OPTION, f"{where}: generation or index is not a whole number; {fix}")
    info = data.get("info", {})
    durability = data.get("durability", {})
    return BestDesign(
        x=_frozen(np.array(x, dtype=float)),
        variables=dict(zip(names, map(float, x), strict=True)),
        objectives=objectives,
        constraints=constraints,
        metrics=dict(metrics),
        feasible=feasible,
        reason=str(data.get("reason") or ""),
        generation=place[0],
        index=place[1],
        verdict=tuple(verdicts)
        if verdicts is not None
        else _verdicts(data.get("verdict"), where, fix),
        info=dict(info) if isinstance(info, dict) else {},
        durability=dict(durability) if isinstance(durability, dict) else {},
    )


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


def _column(cells: list[str]) -> np.ndarray:
    """A column of evaluations.csv as an array: numbers (empty: NaN), booleans, else text."""
    filled = [c for c in cells if c != ""]
    if filled and all(c in ("true", "false") for c in filled):
        if len(filled) == len(cells):
            return np.array([c == "true" for c in cells], dtype=bool)
        return np.array([None if c == "" else c == "true" for c in cells], dtype=object)
    try:
        return np.array([float(c) if c != "" else np.nan for c in cells], dtype=float)
    except ValueError:
        return np.array(cells, dtype=object)


def _evaluation_table(run_dir: Path, record: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """evaluations.csv, checked as ``flexopt report`` checks it, as columns."""
    from types import SimpleNamespace

    from flexopt.pipeline.run.folder import Columns, evaluations_csv

    names = [record.get(key) for key in ("variables", "objectives", "constraints")]
    if any(n is None for n in names):
        raise StudyError(
            _OPTION,
            f"'{run_dir / 'run.json'}' does not name the variables, objectives and constraints "
            f"(written by an older flexopt?); start a new run with flexopt run "
            f"{run_dir / 'study.yaml'}",
        )
    problem = SimpleNamespace(
        space=SimpleNamespace(names=names[0]), objective_names=names[1], constraint_names=names[2]
    )
    columns = Columns.of(problem)  # type: ignore[arg-type]
    rows = evaluations_csv(run_dir, columns, _OPTION)
    if rows is None:
        raise StudyError(
            _OPTION,
            f"'{run_dir}' has no evaluations.csv; {_best_fix(run_dir)} (it reads the store "
            "evaluations.jsonl)",
        )
    header = list(rows[0]) if rows else columns.header()
    table = {}
    for name in header:
        cells = [row[name] for row in rows]
        if name in ("generation", "index"):
            table[name] = np.array([int(c) for c in cells], dtype=np.int64)
        else:
            table[name] = _column(cells)
    return {name: _frozen(col) for name, col in table.items()}


def read_run(run_dir: Path, verdicts: tuple[Verdict, ...] | None = None) -> RunResult:
    """The :class:`RunResult` of a run folder (``verdicts``: the best design's, when known)."""
    from flexopt.pipeline.runfolder import read_folder_json, read_run_json

    record = read_run_json(run_dir, _OPTION)
    path = run_dir / "best.json"
    fix = _best_fix(run_dir)
    best = read_folder_json(path, _OPTION, fix)
    if best is None:
        status = record.get("status", "?")
        if status == "running":
            problem = (
                f"the run is still running (flexopt status {run_dir}); open it when it has finished"
            )
        else:
            problem = (
                f"the run is {status} and has no best design yet (best.json); finish it with "
                f"flexopt run --resume {run_dir}, or write a report of what was done with "
                f"flexopt report {run_dir}"
            )
        raise StudyError(_OPTION, f"'{run_dir}': {problem}")
    where = f"'{path}'"
    design = _design(best, record, where, fix, verdicts)
    front_records = best.get("front", []) if isinstance(best, dict) else []
    if not isinstance(front_records, list):
        raise StudyError(_OPTION, f"{where}: front is not a list; {fix}")
    front = tuple(
        _design(item, record, f"{where} front[{i}]", fix, verdicts=())
        for i, item in enumerate(front_records)
    )
    if not front and len(record.get("objectives") or ()) > 1:
        front = (design,)  # several objectives, and the front is this one design
    return RunResult(run_dir, record, design, front, _evaluation_table(run_dir, record))
