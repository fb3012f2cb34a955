"""``flexopt run``, ``flexopt report`` and ``flexopt export``: optimise a study's design problem
into a run folder, rebuild its report, export one of its designs.

A run is: validate the study, build the kind's :class:`~optimise.DesignProblem` once, create the
run folder, then let :func:`optimise.run_ga` ask for populations that an :class:`Evaluator`
answers. The evaluator is the one place designs are solved: it serves repeated designs from a cache
keyed by the design vector's bytes and hands the rest to a *backend* (``evaluate_batch``: serial, in
this process), which turns any exception of the kind into an infeasible Evaluation with a reason.
A process pool, Dask or a persisted cache replace the backend or the cache mapping; nothing else
changes.

Every file is written atomically; ``evaluations.csv``, ``history.csv`` and ``run.json`` are
rewritten after each generation, so a killed run leaves a consistent folder of what was done.

The modules, one job each: :mod:`.setup` (refuse bad inputs, build the problem),
:mod:`.evaluator` (one cache), :mod:`.runner` (the run folder and the optimiser),
:mod:`.state` (one run's tables and its end: best.json, plots, parts, report),
:mod:`.figures`, :mod:`.folder` (a run folder's files read back), :mod:`.resume`,
:mod:`.rebuild` (``flexopt report``), :mod:`.export`, :mod:`.step_child` (best.step's early
child). This package re-exports their public names.
"""

from __future__ import annotations

from flexopt.pipeline.parallel import evaluate_batch, evaluate_one
from flexopt.pipeline.problems import ExportError, parallel_settings
from flexopt.pipeline.run.evaluator import Evaluator
from flexopt.pipeline.run.export import (
    DEFAULT_FRAMES,
    EXPORT_FORMATS,
    STEP_EXTRA_FIX,
    STUDY_SUFFIXES,
    ExportOutcome,
    StudyExportOutcome,
    design_study_of,
    export_design,
    export_frame,
    export_study,
    is_evaluate_folder,
    part_bytes,
    part_of,
    step_available,
)
from flexopt.pipeline.run.folder import RUN_FILES, read_run_record, run_is_live
from flexopt.pipeline.run.rebuild import ReportOutcome, rebuild_report
from flexopt.pipeline.run.resume import resume_run
from flexopt.pipeline.run.runner import Resume, RunOutcome, all_versions, run_study
from flexopt.pipeline.run.setup import RunSetup, build_problem, initial_designs, prepare_run
from flexopt.pipeline.run.state import GenerationReport
from flexopt.pipeline.run.step_child import EARLY_STEP_NICE

__all__ = [
    "DEFAULT_FRAMES",
    "EARLY_STEP_NICE",
    "EXPORT_FORMATS",
    "RUN_FILES",
    "STEP_EXTRA_FIX",
    "STUDY_SUFFIXES",
    "Evaluator",
    "ExportError",
    "ExportOutcome",
    "GenerationReport",
    "ReportOutcome",
    "Resume",
    "RunOutcome",
    "RunSetup",
    "StudyExportOutcome",
    "all_versions",
    "build_problem",
    "design_study_of",
    "evaluate_batch",
    "evaluate_one",
    "export_design",
    "export_frame",
    "export_study",
    "initial_designs",
    "is_evaluate_folder",
    "parallel_settings",
    "part_bytes",
    "part_of",
    "prepare_run",
    "read_run_record",
    "rebuild_report",
    "resume_run",
    "run_is_live",
    "run_study",
    "step_available",
]
