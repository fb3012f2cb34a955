"""``flexopt run --resume``: finish an interrupted or killed run by replaying it."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

from flexopt.optimise.ga import GAConfig
from flexopt.pipeline.checkpoint import STORE_FILE, EvaluationStore, study_sha256
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.parallel import ParallelSettings
from flexopt.pipeline.problems import parallel_settings
from flexopt.pipeline.run.folder import read_run_record, run_folder_study
from flexopt.pipeline.run.runner import Resume, RunOutcome, run_study
from flexopt.pipeline.run.setup import prepare_run
from flexopt.pipeline.run.state import GenerationReport
from flexopt.pipeline.runfolder import (
    echo,
    input_files,
    input_hashes,
    lock_run_dir,
    study_sha256_with_inputs,
)
from flexopt.pipeline.study import OptimiserSpec, Study, load_study

log = logging.getLogger(__name__)


def _refuse_changed_inputs(run_dir: Path, record: dict[str, Any], study: Study) -> None:
    """Name a target table whose bytes changed since the run started, when that is what makes
    the study differ (the message says which file and how to go on)."""
    recorded = record.get("input_files")
    if not isinstance(recorded, dict):
        return
    now = input_hashes(study)
    for key, file in input_files(study):
        entry = recorded.get(key)
        if isinstance(entry, dict) and entry.get("sha256") not in (None, now.get(key)):
            raise StudyError(
                "--resume",
                f"{key}: the file {echo(file)} differs from the one this run started with "
                f"(sha256 {now[key][:12]} is not {str(entry['sha256'])[:12]}): a resumed run "
                f"would mix designs made for two targets; resume with the run's own copy "
                f"(flexopt run --resume {run_dir}, no STUDY) or start a new run",
            )


def resume_run(
    run_dir: Path,
    study_path: str | Path | None = None,
    parallel: ParallelSettings | None = None,
    workers: int | None = None,
    dask: str | None = None,
    eval_timeout_s: float | None = None,
    command_line: str = "",
    on_start: Callable[[Path, GAConfig], None] | None = None,
    on_generation: Callable[[GenerationReport], None] | None = None,
    on_result: Callable[[], None] | None = None,
) -> RunOutcome:
    """Finish an interrupted or killed run by replaying it from its seed and its store.

    Every evaluation in ``evaluations.jsonl`` is served from there (none is solved again); the
    optimiser, seeded as before, asks for the same designs, so the run ends as an uninterrupted
    run with the same seed would.

    Parameters
    ----------
    run_dir : Path
        The run folder of the run to continue.
    study_path : path, optional
        The study to check against the run's (default: the run folder's study.yaml). Its hash
        (sha256 of the resolved YAML, the ``parallel:`` block left out) must match.
    parallel, workers, dask, eval_timeout_s :
        Where to evaluate (``parallel`` as is, or the study's block with these options applied);
        a run may be resumed on other workers.

    Raises
    ------
    StudyError
        At ``--resume`` when the folder is not a resumable run (finished, in use by another
        flexopt process, no hash, a damaged run.json or store) or the study changed; nothing is
        written then. The folder's lock is taken before anything is read and held to the end.
    """
    if not run_dir.is_dir():
        raise StudyError(
            "--resume", f"'{run_dir}' is not a folder; give a run folder of flexopt run"
        )
    # The lock first: two resumes of one folder must not both get past the checks below.
    with lock_run_dir(
        run_dir, "--resume", f"wait for it to finish (flexopt status {run_dir} shows it)"
    ) as lock:
        record = read_run_record(run_dir, "--resume")
        if record.get("status") == "finished":
            raise StudyError(
                "--resume",
                f"the run in '{run_dir}' has finished; nothing to resume (flexopt report "
                f"{run_dir} rebuilds its report)",
            )
        # No process holds the lock, so a status "running" is a run that was killed.
        expected = record.get("study_sha256")
        if not expected:
            raise StudyError(
                "--resume",
                f"'{run_dir}' was written without a study hash (an older flexopt); start a new run",
            )
        study = (
            load_study(study_path)
            if study_path is not None
            else run_folder_study(run_dir, "--resume")
        )
        quick = bool(record.get("quick", False))
        spec = getattr(study, "optimiser", None) or OptimiserSpec()
        seed = record.get("seed")
        setup = prepare_run(study, quick=quick, seed=None if seed == spec.seed else seed)
        found = study_sha256_with_inputs(setup.study, study_sha256(setup.study))
        if found != expected:
            _refuse_changed_inputs(run_dir, record, setup.study)
            raise StudyError(
                "--resume",
                f"the study differs from the one this run started with (sha256 {found[:12]} is "
                f"not {expected[:12]}); resume with the run's own study (flexopt run --resume "
                f"{run_dir}) or start a new run",
            )
        problem = setup.problem
        store = EvaluationStore(run_dir / STORE_FILE)
        restored = store.load(
            problem.space.n_var,
            len(problem.objective_names),
            len(problem.constraint_names),
            option="--resume",
        )
        settings = parallel or parallel_settings(setup.study, workers, dask, eval_timeout_s)
        log.info("resuming %s with %d evaluations from its store", run_dir, len(restored))
        return run_study(
            setup,
            out=run_dir,
            source=str(record.get("source", "")),
            command_line=command_line,
            on_start=on_start,
            on_generation=on_generation,
            on_result=on_result,
            parallel=settings,
            resume=Resume(record, tuple(restored)),
            lock=lock,
        )
