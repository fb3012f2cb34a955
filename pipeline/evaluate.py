"""``flexopt evaluate``: solve one study once and write its run folder."""

from __future__ import annotations

import logging
import platform
import re
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from datetime import datetime
from importlib import metadata
from pathlib import Path
from typing import Any

from flexopt.optimise.problem import DesignResult
from flexopt.optimise.requirements import verdict_record
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.fork import ForkedMakes, limit_loaded_pools
from flexopt.pipeline.plot_targets import plot_spec
from flexopt.pipeline.problems import can_evaluate, study_result
from flexopt.pipeline.responses import stacked_table, stress_allowable
from flexopt.pipeline.runfolder import (
    check_out_dir,
    copy_inputs,
    grouped_files,
    make_run_dir,
    new_run_dir_path,
    table_to_csv,
    to_json,
    write_atomic,
)
from flexopt.pipeline.studies import get_kind
from flexopt.pipeline.study import Study, study_to_yaml
from flexopt.pipeline.verdict import judge_result, with_hold, with_life

__all__ = [
    "EVALUATE_FILES",
    "MAX_REPEAT",
    "EvaluateOutcome",
    "case_plot_args",
    "evaluate_study",
    "response_plot_args",
    "response_table",
    "solve_study",
    "versions",
]

#: Most solves ``--repeat`` / ``evaluate(repeat=)`` may ask for: repeats only time the solve
#: (the median is recorded), and a typo of 10**9 must not start a day of solving.
MAX_REPEAT = 100

log = logging.getLogger(__name__)

#: The files an evaluate run folder holds; evaluation.json is written last, so its presence marks
#: a complete folder.
EVALUATE_FILES = ("response.csv", "study.yaml", "force_displacement.png", "evaluation.json")

_DISTRIBUTIONS = {
    "flexopt": "flexopt",
    "numpy": "numpy",
    "scipy": "scipy",
    "skfem": "scikit-fem",
    "pydantic": "pydantic",
    "matplotlib": "matplotlib",
}


@dataclass(frozen=True)
class EvaluateOutcome:
    """Where the results went and what they say."""

    run_dir: Path
    result: DesignResult
    record: dict[str, Any]


def versions() -> dict[str, str | None]:
    """Versions of Python, flexopt and the numerical stack (None when not installed)."""
    found: dict[str, str | None] = {"python": platform.python_version()}
    for key, dist in _DISTRIBUTIONS.items():
        try:
            found[key] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            found[key] = None  # e.g. flexopt run from a source checkout without installing
    return found


_FILE_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


def _extra_files(result: DesignResult) -> dict[str, bytes]:
    """The kind's own files (``DesignResult.files``), checked to be plain new file names."""
    files = {}
    for name, data in result.files.items():
        if not _FILE_NAME_RE.match(name) or name in EVALUATE_FILES:
            log.warning("the kind's file %r is not written: not a plain new file name", name)
            continue
        files[name] = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    return files


#: The VTU of an evaluate folder (the name ``flexopt export --format vtu`` gives it there too).
DESIGN_VTU = "design.vtu"


def _design_vtu(result: DesignResult) -> dict[str, bytes]:
    """design.vtu, design.pvd and design_steps/ of an evaluation that has beam shapes or a
    stress field (:func:`pipeline.vtu.vtu_files`; none without them, or, with a warning, when
    they cannot be made: the evaluation's other files still stand)."""
    from flexopt.pipeline.vtu import has_mesh, vtu_files

    if not has_mesh(result):
        return {}
    try:
        return vtu_files(result, DESIGN_VTU.removesuffix(".vtu"))
    except Exception as exc:
        log.warning("%s not written: %s: %s", DESIGN_VTU, type(exc).__name__, exc)
        return {}


#: The stress field on the deformed part, where the evaluation carries a field with its
#: displacement (:func:`pipeline.plots.plot_field_deformed`; the run folder's name too).
STRESS_DEFORMED = "stress_deformed.png"


def _stress_deformed(result: DesignResult, title: str) -> bytes | None:
    """stress_deformed.png of an evaluation whose ``field_map`` has ``displacement_mm`` (None
    without, or, with a warning, when it cannot be drawn)."""
    fmap = result.field_map or {}
    if fmap.get("displacement_mm") is None:
        return None
    from flexopt.pipeline.plots import plot_field_deformed

    try:
        limit = fmap.get("limit")
        return plot_field_deformed(
            fmap["points_mm"], fmap["triangles"], fmap["values"], fmap["displacement_mm"],
            label=fmap.get("label", "von Mises stress (MPa)"),
            limit=None if limit is None else float(limit), title=title,
        )  # fmt: skip
    except Exception as exc:
        log.warning("%s not written: %s: %s", STRESS_DEFORMED, type(exc).__name__, exc)
        return None


def solve_study(study: Study, repeat: int = 1, source: str = "") -> DesignResult:
    """Solve the design ``study`` describes ``repeat`` times
    (:func:`pipeline.problems.study_result`) and judge the last solve.

    The result's ``verdicts`` are the kind's own, else the study's requirements judged on its
    values and table (:func:`pipeline.verdict.judge_result`). Nothing is written.

    Raises
    ------
    StudyError
        When the kind cannot be evaluated (it is only optimised: ``flexopt run``) or the solver
        refuses the inputs.
    """
    kind = get_kind(study.kind)
    if not can_evaluate(kind):
        raise StudyError(
            "geometry.kind",
            f"kind '{kind.name}' is only optimised, not evaluated on its own; "
            f"run it with `flexopt run {source or 'STUDY'}`",
            source=source or None,
        )
    log.info("evaluating %s (%s), %d repeat(s)", study.name, study.kind, repeat)
    # one BLAS/OpenMP thread for the solve, as in the pool's workers: its factorisations are
    # too small for a second thread to pay (fork.limit_loaded_pools); the caller's limits are
    # back afterwards (the API's caller's own numpy work keeps its threads)
    with limit_loaded_pools():
        result = study_result(study, repeat, source)
    result = with_hold(study, with_life(study, result))  # duty_cycle: its life; hold: creep
    return replace(result, verdicts=judge_result(study, result))


def response_plot_args(study: Study, result: DesignResult) -> dict[str, Any]:
    """The arguments of :func:`pipeline.plots.plot_response` (or ``response_figure``) beyond
    the table, for the response of ``result``: what force_displacement.png shows. The stress
    line is the allowable the verdict uses (:func:`pipeline.responses.stress_allowable`)."""
    labels = plot_spec(result.plot)
    line = stress_allowable(result.verdicts, "", labels.get("allowable_MPa"))
    if line is not None and line[1].startswith("allowable"):  # the verdict's own bound
        labels["allowable_text"] = line[1]
    return {
        "x": labels["x"],
        "left": labels["y"],
        "right": labels["stress"],
        "allowable_MPa": line[0] if line is not None else None,
        "title": f"{study.name} ({study.kind})",
        "labels": labels,
    }


def case_plot_args(study: Study, result: DesignResult) -> dict[str, Any]:
    """The arguments of :func:`pipeline.plots.cases_figure` beyond the rows, for a result with
    load cases (``result.cases``): every case with the allowable the verdict uses for it."""
    return {
        "cases": dict(result.cases),
        "allowables": {
            case: stress_allowable(result.verdicts, case, c.plot.get("allowable_MPa"))
            for case, c in result.cases.items()
        },
        "title": f"{study.name} ({study.kind})",
    }


def response_table(result: DesignResult) -> dict[str, Any]:
    """The response as one table: every load case's rows with a ``load_case`` column for a
    result with cases (:func:`pipeline.responses.stacked_table`), else ``result.table``."""
    return stacked_table(result.cases) if result.cases else dict(result.table)


def evaluate_study(
    study: Study,
    out: Path | None = None,
    repeat: int = 1,
    source: str = "",
    runs_root: Path = Path("runs"),
) -> EvaluateOutcome:
    """Solve ``study`` and write response.csv, study.yaml, the plot and evaluation.json.

    evaluation.json opens with ``verdict``: every requirement of the study (the kind's built-in
    ones, then ``requirements:``) with its value, bound, margin and MET / NOT MET, and the
    overall word (:func:`optimise.requirements.verdict_record`).

    Nothing is written unless the solve returns (converged or not), so a refused input leaves no
    folder behind.

    Parameters
    ----------
    study : Study
        A validated study (see :func:`pipeline.study.load_study`).
    out : Path, optional
        Run folder; default ``runs_root/<name>-evaluate-<timestamp>``.
    repeat : int
        Solve this many times; ``solve_time_s`` is the median (s).
    source : str
        Where the study came from, recorded in evaluation.json.

    Raises
    ------
    StudyError
        When ``out`` cannot be a folder, the kind has no ``evaluate`` (it is only optimised:
        ``flexopt run``) or the solver refuses the inputs.
    """
    # here, not at the top: the CLI imports this module for every command (--version, list)
    from flexopt.pipeline.plots import plot_cases, plot_response
    from flexopt.pipeline.report_html import evaluate_html
    from flexopt.pipeline.robustness import run_robustness

    if out is not None:
        check_out_dir(out)
    from flexopt.pipeline import report_preload

    preload = report_preload.start()  # matplotlib and plotly load while the design solves
    started = datetime.now().astimezone()
    started_s = time.perf_counter()
    result = solve_study(study, repeat, source)
    # the whole evaluation (a kind's extra checks, e.g. the SEA spring's 3D ones, included):
    # what rebuilding the part for report.html would cost again
    evaluation_wall_s = (time.perf_counter() - started_s) / max(repeat, 1)
    verdicts = result.verdicts
    with limit_loaded_pools():  # its scatter samples: small solves too (solve_study)
        robust = run_robustness(study, plot=result.plot)  # before the folder: it may refuse
    if robust is not None and robust.robust_verdicts:  # robust: requirements, fresh samples
        verdicts = robust.with_robust_rows(verdicts)
        result = replace(result, verdicts=verdicts)
    run_dir = make_run_dir(out or new_run_dir_path(runs_root, study.name, "evaluate", started))
    record = {
        "verdict": verdict_record(verdicts),  # first: what the design meets, and what not
        "study": study.name,
        "kind": study.kind,
        "command": "evaluate",
        "source": source,
        "started": started.isoformat(timespec="seconds"),
        "converged": result.converged,
        "message": result.message,
        "solve_time_s": statistics.median(result.solve_times_s),
        "solve_times_s": list(result.solve_times_s),
        "repeat": len(result.solve_times_s),
        "summary": result.summary,
        "inputs": {"study": study.model_dump(mode="json"), **result.inputs},
        "solver": result.diagnostics,
        "columns": list(result.table),
        "versions": versions(),
    }
    header = (
        f"Resolved study written by flexopt evaluate on {record['started']}\n"
        f"from {source or 'memory'}; re-run with: flexopt evaluate {run_dir / 'study.yaml'}"
    )
    write_atomic(run_dir / "response.csv", table_to_csv(response_table(result)))
    folder_study, input_files = copy_inputs(study, run_dir)  # the folder stands alone
    if input_files:
        record["input_files"] = input_files
    write_atomic(run_dir / "study.yaml", study_to_yaml(folder_study, header))
    extra = _extra_files(result)
    preload.join()
    makes: dict[str, Callable[[], Any]] = {}
    if result.cases:  # every load case, one column each; every output on its unit's axis
        args = case_plot_args(study, result)
        makes["force_displacement.png"] = lambda: plot_cases(rows=("curve", "stress"), **args)
        if any(c.outputs for c in result.cases.values()):
            makes["outputs.png"] = lambda: plot_cases(rows=("outputs",), **args)
    else:
        makes["force_displacement.png"] = lambda: plot_response(
            result.table, **response_plot_args(study, result)
        )
    if robust is not None:
        makes["robustness.png"] = lambda: robust.png(f"{study.name}: robustness")
    makes["design.vtu"] = lambda: _design_vtu(result)  # design.vtu, design.pvd, design_steps/
    makes[STRESS_DEFORMED] = lambda: _stress_deformed(result, study.name)
    # The plots and the VTU files (~0.6 s CPU for constant-force) are made in a forked child
    # while this process writes report.html (ForkedMakes: made here, in order, where fork is
    # not available)
    child = ForkedMakes(list(makes.items()))
    if robust is not None:  # before report.html, which draws its band
        record["robustness"] = robust.record()
    # report.html: the verdict, the response with its target, the part in 3D (one offline file)
    with limit_loaded_pools():  # it solves the design again for its 3D view (a short solve)
        html = evaluate_html(study, result, record, evaluation_wall_s)
    made = {}
    for name, data, error in child.results():
        # A file the child could not make (its make raised, or the child died) is made here
        # again, as before the child: a plot that raises ends the evaluate with its own error
        made[name] = makes[name]() if error is not None else data
    write_atomic(run_dir / "force_displacement.png", made["force_displacement.png"])
    if "outputs.png" in made:
        extra["outputs.png"] = made["outputs.png"]
    if html is not None:
        extra["report.html"] = html.encode("utf-8")
    if made.get("robustness.png") is not None:
        extra["robustness.png"] = made["robustness.png"]
    extra.update(made["design.vtu"])
    if made[STRESS_DEFORMED] is not None:
        extra[STRESS_DEFORMED] = made[STRESS_DEFORMED]
    for name, data in extra.items():
        (run_dir / name).parent.mkdir(exist_ok=True)  # design_steps/ of design.pvd
        write_atomic(run_dir / name, data)
    # design_steps/ (one VTU per load step) as one entry, with its count
    record["files"], counts = grouped_files([*EVALUATE_FILES, *extra])
    record.update({"file_counts": counts} if counts else {})
    write_atomic(run_dir / "evaluation.json", to_json(record))
    log.info("wrote %s", run_dir)
    return EvaluateOutcome(run_dir, result, record)
