"""``flexopt run``: :func:`run_study` creates the run folder, runs the optimiser on the backend
and ends with the report; ``--resume`` passes a :class:`Resume`."""

from __future__ import annotations

import contextlib
import logging
import os
import platform
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass
from datetime import datetime
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.ga import GAConfig, GAResult, run_ga
from flexopt.optimise.hybrid import GradientStep, run_hybrid
from flexopt.optimise.problem import DesignDetail, DesignProblem
from flexopt.optimise.requirements import Verdict
from flexopt.pipeline.backends import open_backend
from flexopt.pipeline.checkpoint import CHECKPOINT_FILE, STORE_FILE, EvaluationStore, study_sha256
from flexopt.pipeline.errors import StudyError, Terminated
from flexopt.pipeline.evaluate import versions
from flexopt.pipeline.fork import limit_loaded_pools
from flexopt.pipeline.parallel import BackendError, BatchBackend, ParallelSettings, design_key
from flexopt.pipeline.parallel import one_line as _one_line
from flexopt.pipeline.problems import parallel_settings
from flexopt.pipeline.run.export import step_available
from flexopt.pipeline.run.setup import RunSetup
from flexopt.pipeline.run.state import GenerationReport, RunState
from flexopt.pipeline.run.step_child import EARLY_STEP_NICE, EarlyStep, can_restore_priority
from flexopt.pipeline.runfolder import (
    RunDirLock,
    check_out_dir,
    copy_inputs,
    grouped_files,
    lock_run_dir,
    make_run_dir,
    new_run_dir_path,
    probe_writable,
    study_sha256_with_inputs,
    to_json,
    write_atomic,
)
from flexopt.pipeline.sensitivity_report import known_jacobian
from flexopt.pipeline.study import study_to_yaml

log = logging.getLogger(__name__)


_EXTRA_DISTRIBUTIONS = {
    "pymoo": "pymoo",
    "shapely": "shapely",
    "trimesh": "trimesh",
    "manifold3d": "manifold3d",
}


@dataclass(frozen=True)
class RunOutcome:
    """Where a run went and what it found."""

    run_dir: Path
    result: GAResult
    detail: DesignDetail | None
    record: dict[str, Any]
    notes: tuple[str, ...] = ()
    verdicts: tuple[Verdict, ...] = ()  # the best design against the study's requirements


def all_versions() -> dict[str, str | None]:
    """Versions of Python, flexopt, the numerical stack and the optimiser/solid libraries."""
    found = versions()
    for key, dist in _EXTRA_DISTRIBUTIONS.items():
        try:
            found[key] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            found[key] = None
    return found


def _now() -> datetime:
    return datetime.now().astimezone()


def _stamp(moment: datetime) -> str:
    return moment.isoformat(timespec="seconds")


@dataclass(frozen=True)
class Resume:
    """What ``--resume`` carries into :func:`run_study`: the run's record and its store.

    Attributes
    ----------
    record : run.json of the interrupted run.
    restored : every evaluation its store (evaluations.jsonl) holds.
    """

    record: dict[str, Any]
    restored: tuple[Evaluation, ...]


def run_study(
    setup: RunSetup,
    out: Path | None = None,
    source: str = "",
    command_line: str = "",
    runs_root: Path = Path("runs"),
    on_start: Callable[[Path, GAConfig], None] | None = None,
    on_generation: Callable[[GenerationReport], None] | None = None,
    on_result: Callable[[], None] | None = None,
    parallel: ParallelSettings | None = None,
    resume: Resume | None = None,
    lock: RunDirLock | None = None,
    early_step: EarlyStep | None = None,
) -> RunOutcome:
    """Optimise a prepared study and write its run folder.

    Parameters
    ----------
    setup : RunSetup
        From :func:`prepare_run` (which refuses bad inputs before anything is written).
    out : Path, optional
        Run folder; default ``runs_root/<name>-run-<timestamp>``. A folder that already holds
        a run (run.json) is refused, unless resuming it.
    source : str
        Where the study came from, recorded in run.json.
    command_line : str
        The command as typed, recorded in run.json.
    on_start : callable(run_dir, config), optional
        Called once the folder exists, before the first design is solved.
    on_generation : callable(GenerationReport), optional
        Called after each generation.
    on_result : callable(), optional
        Called after each solved design (progress within a generation).
    parallel : ParallelSettings, optional
        Where designs are evaluated (default: :func:`parallel_settings` of the study, a local
        process pool unless the study says otherwise).
    resume : Resume, optional
        Continue the run in ``out`` (see :func:`resume_run`, which checks it may be).
    lock : RunDirLock, optional
        The lock of ``out``, already held (``--resume`` takes it before it reads the folder);
        otherwise the folder's lock is taken here, before the folder is checked or written. It
        is released when the run ends (a killed process's lock is released by the kernel).
    early_step : EarlyStep, optional
        best.step's child, already started by the caller (:func:`start_early_step`, which the
        CLI calls before it loads the study); the run takes it over and ends it. Without it
        the run starts one when its folder exists.

    Returns
    -------
    RunOutcome

    Raises
    ------
    StudyError
        When ``out`` cannot be a new run folder (it holds a run, or another flexopt process
        holds its lock), or the workers or the cluster cannot take the problem (at
        ``--workers`` / ``--dask``); nothing is written.
    BackendError
        When worker processes die before they can load the problem (mid-run).
    OSError
        When the run folder cannot be written; a folder that is read-only or full is found by a
        probe before anything else is done.
    KeyboardInterrupt
        After writing run.json with status ``interrupted`` (and every evaluation so far).
    """
    if out is not None:
        check_out_dir(out)
        if resume is None:
            _refuse_a_run_in(out)  # at once, before workers start (again under the lock below)
    if resume is not None and (out is None or lock is None):
        raise ValueError("resume needs the run folder as out, and its lock")
    study = setup.study
    settings = parallel or parallel_settings(study)
    started = _now()
    run_dir = out or new_run_dir_path(runs_root, study.name, "run", started)
    probe_writable(run_dir)  # a read-only or full disk now, not after hours of solving
    stack = contextlib.ExitStack()
    if lock is not None:
        stack.callback(lock.release)
    try:
        backend = stack.enter_context(open_backend(settings, setup.problem))
    except BackendError as exc:
        stack.close()
        where = "--dask" if settings.backend == "dask" else "--workers"
        raise StudyError(where, str(exc)) from None
    except BaseException:
        stack.close()
        raise
    with stack:
        run_dir = make_run_dir(run_dir)
        if lock is None:
            # Released first when the run ends (a callback after the backend's exit runs first).
            lock = stack.enter_context(_lock_new_run_dir(run_dir))
        lock.claim("run")
        return _run_in(
            setup,
            run_dir,
            settings,
            backend,
            started,
            source,
            command_line,
            on_start,
            on_generation,
            on_result,
            resume,
            early_step,
        )


def _refuse_a_run_in(out: Path) -> None:
    """Refuse an ``--out`` that already holds a run (its run.json)."""
    if (out / "run.json").exists():
        raise StudyError(
            "--out", f"'{out}' already holds a run (run.json); give a new folder or remove it"
        )


def _lock_new_run_dir(run_dir: Path) -> RunDirLock:
    """Lock the folder of a new run, then check (under the lock) that it holds no run yet."""
    lock = lock_run_dir(run_dir, "--out", "wait for it or give another folder with --out")
    try:
        _refuse_a_run_in(run_dir)
    except BaseException:
        lock.release()
        raise
    return lock


def _run_in(
    setup: RunSetup,
    run_dir: Path,
    settings: ParallelSettings,
    backend: BatchBackend,
    started: datetime,
    source: str,
    command_line: str,
    on_start: Callable[[Path, GAConfig], None] | None,
    on_generation: Callable[[GenerationReport], None] | None,
    on_result: Callable[[], None] | None,
    resume: Resume | None,
    early_step: EarlyStep | None = None,
) -> RunOutcome:
    """The body of :func:`run_study` once the folder can be written and the backend is up."""
    study, config = setup.study, setup.config
    session = {
        "status": "running",
        "error": "",
        "finished": None,
        "pid": os.getpid(),
        "hostname": socket.gethostname(),
        "parallel": {**asdict(settings), "description": settings.describe()},
        "versions": all_versions(),
        "host": {"platform": platform.platform(), "cpu_count": os.cpu_count()},
    }
    if resume is not None:
        record = dict(resume.record)
        record.update(session)
        record["resumed"] = [
            *record.get("resumed", []),
            {
                "at": _stamp(started),
                "command_line": command_line,
                "n_in_store": len(resume.restored),
            },
        ]
    else:
        record = {
            "study": study.name,
            "kind": study.kind,
            "command": "run",
            "command_line": command_line,
            "source": source,
            **session,
            "quick": setup.quick,
            "seed": config.seed,
            "study_sha256": study_sha256_with_inputs(study, study_sha256(study)),
            "optimiser": {
                "algorithm": config.algorithm,
                "pop_size": config.pop_size,
                "n_gen": config.n_gen,
                "seed": config.seed,
                # the hybrid's settings, only for it: a GA run's run.json stays as it was
                **(
                    {"method": "hybrid", "hybrid": setup.hybrid.record()}
                    if setup.hybrid is not None
                    else {}
                ),
            },
            "objectives": list(setup.problem.objective_names),
            "constraints": list(setup.problem.constraint_names),
            "variables": list(setup.problem.space.names),
            "started": _stamp(started),
            "generations_done": 0,
            "n_evaluations": 0,
            "n_cache_hits": 0,
            "n_restored": 0,
            "n_solved": 0,
            "wall_s": None,
            "optimise_wall_s": None,
            "evaluations_per_s": None,
        }
        rerun = f"flexopt run {run_dir / 'study.yaml'}" + (" --quick" if setup.quick else "")
        header = (
            f"Resolved study written by flexopt run on {record['started']}\n"
            f"from {source or 'memory'}; re-run with: {rerun}"
        )
        # the target tables the study reads, copied: the folder stands alone (report, export,
        # resume from anywhere), and a resume checks their bytes against the run's
        folder_study, inputs = copy_inputs(study, run_dir)
        if inputs:
            record["input_files"] = inputs
        write_atomic(run_dir / "study.yaml", study_to_yaml(folder_study, header))
    write_atomic(run_dir / "run.json", to_json(record))
    log.info("run folder %s; %s; %s", run_dir, config, settings.describe())
    # best.step's child now, while this process runs no other thread (forked later, a thread
    # could hold a lock the child needs): it imports the STEP writer (geometry/step_writer.py,
    # with build123d as its fallback) at the lowest priority, in the moments a core idles while
    # the workers solve (generation barriers), instead of on the report's critical path.
    early = early_step if early_step is not None else start_early_step()
    if on_start is not None:
        on_start(run_dir, config)

    store = EvaluationStore(run_dir / STORE_FILE)
    restored = resume.restored if resume is not None else ()
    run = RunState(setup, run_dir, record, on_generation, on_result, backend, store, restored)
    t_start = time.perf_counter()
    # The report's imports (~1.2 s CPU for constant-force) in a thread of this process. A GA's
    # generations keep both workers busy to their barriers, so the thread took a core from
    # them (benchmarks/fixed_costs.py: the hybrid's GA stage of 200 designs ~0.6 s longer);
    # the hybrid's gradient stage leaves a core idle most of its batches (one or two
    # Jacobians and designs a batch; a start that ends leaves one live), so a hybrid run starts
    # the thread after its first gradient batch (on_generation below), a GA run at once.
    hybrid = setup.hybrid is not None
    preload = _preload_report(setup.problem, settings, start=not hybrid)

    def generation_done(gen: Any) -> None:
        run.generation_done(gen)
        if preload is not None and isinstance(gen, GradientStep):
            preload.start()

    def close(status: str, error: str = "", write: bool = True) -> None:
        wall = time.perf_counter() - t_start
        solved = run.evaluator.solved
        n = len(solved)
        n_now = run.evaluator.n_backend
        # a run that stopped mid-generation solved its last designs after optimise_wall_s
        optimise_wall = (record.get("optimise_wall_s") or wall) if status == "finished" else wall
        failed = [ev for ev in solved if ev.reason]
        now_times = [ev.time_s for ev in solved[-n_now:]] if n_now else []
        record.update(
            status=status,
            error=error,
            finished=_stamp(_now()),
            wall_s=wall,
            n_evaluations=n,
            n_cache_hits=run.evaluator.n_cache_hits,
            n_restored=run.evaluator.n_restored,
            n_solved=n_now,
            n_failed=len(failed),
            n_feasible=sum(ev.feasible for ev in solved),
            evaluations_per_s=n_now / optimise_wall if optimise_wall > 0 and n_now else None,
            mean_evaluation_s=float(np.mean([ev.time_s for ev in solved])) if n else None,
            # the share of the wall time the workers spent solving (1 - overhead - idle)
            worker_utilisation=(
                sum(now_times) / (optimise_wall * _n_workers(settings))
                if now_times and optimise_wall > 0
                else None
            ),
            failure_reasons=dict(Counter(ev.reason for ev in failed).most_common(10)),
            notes=run.notes,
            files=sorted(
                set(run.files)
                | {"study.yaml", "run.json", "evaluations.csv", STORE_FILE}
                | ({CHECKPOINT_FILE} if run.generations else set())
            ),
        )
        # best_steps/ (one VTU per load step) as one entry with its count
        record["files"], counts = grouped_files(record["files"])
        if counts:
            record["file_counts"] = counts
        else:  # a resumed run's earlier count, of files this session did not write
            record.pop("file_counts", None)
        if write:
            write_atomic(run_dir / "run.json", to_json(record))

    def abandon(status: str, error: str) -> None:
        # Keep what was done; a folder that cannot be written any more must not hide the cause.
        with contextlib.suppress(OSError):
            run.collect(len(run.generations) + 1)  # the unfinished generation's designs
            run.write_tables()
            close(status, error)

    optimised = False
    try:
        try:
            # a serial run solves every design in this process: one BLAS/OpenMP thread for the
            # optimisation, as in the pool's workers (fork.limit_loaded_pools: the systems are
            # too small for a second thread to pay); so does a hybrid run, whose gradient stage
            # takes its exact Jacobians and steps here (small systems too, and with the caller's
            # threads the BLAS round-off changed a run's path: gripper-amplifier took 147 designs
            # with the default threads and 142 with one); the report after it (an SEA spring's
            # 3D check, one large sparse factorisation) keeps the caller's threads
            serial = settings.backend == "serial"
            one_thread = serial or setup.hybrid is not None
            with limit_loaded_pools() if one_thread else contextlib.nullcontext():
                if setup.hybrid is None:
                    result = run_ga(
                        setup.problem.space,
                        run.evaluator,
                        len(setup.problem.objective_names),
                        len(setup.problem.constraint_names),
                        config,
                        on_generation=run.generation_done,
                        initial=setup.initial,
                    )
                else:  # optimiser.method: hybrid (optimise/hybrid.py), on the same evaluator
                    result = run_hybrid(
                        setup.problem.space,
                        run.evaluator,
                        len(setup.problem.objective_names),
                        len(setup.problem.constraint_names),
                        setup.hybrid,
                        on_generation=generation_done,
                        initial=setup.initial,
                        jacobian=setup.problem.jacobian,  # exact derivatives where it has them
                        # its Jacobians and checks on the pool's workers, beside its designs
                        requests=run.evaluator.map_calls,
                        # a trial's Jacobian in its own round, on a worker that would idle
                        ahead=run.evaluator.calls_in_parallel,
                    )
                    record["hybrid"] = result.report
                    if result.jacobian is not None:  # the report's sensitivities reuse it
                        known_jacobian(setup.problem, result.jacobian)
                    log.info(
                        "hybrid: best from the %s stage, %s evaluations, %s",
                        result.report["best_stage"],
                        result.report["n_evaluations"],
                        result.report["stop"],
                    )
            optimised = True
        finally:
            try:
                store.close()
            finally:  # every generation's files on disk before anything else is written
                run.finish_writes(raise_errors=optimised)
        record["optimise_wall_s"] = time.perf_counter() - t_start
        run.files += ["evaluations.csv", "history.csv"]
        from flexopt.pipeline.report import ReportData, render_report  # see _preload_report

        if preload is not None:
            preload.join()
        early, handed = None, early
        detail = run.finish(result, handed)
        run.files.append("report.md")
        close("finished", write=False)  # the numbers the report shows
        report = ReportData(
            record=record,
            study=study,
            problem=setup.problem,
            best=result.best,
            best_where=run.where.get(design_key(result.best.x), (None, None)),
            front=result.front,
            detail=detail,
            files=tuple(run.files),
            notes=tuple(run.notes),
            stl=run.stl,
            verdicts=run.verdicts,
        )
        write_atomic(run_dir / "report.md", render_report(report))
        close("finished")
    except Terminated:
        abandon("stopped", "stopped by SIGTERM")
        raise
    except KeyboardInterrupt:
        abandon("interrupted", "interrupted by the user (Ctrl-C)")
        raise
    except BaseException as exc:
        abandon("failed", _one_line(f"{type(exc).__name__}: {exc}"))
        raise
    finally:
        if early is not None:  # the run ended before its report: the child has nothing to make
            early.close()
    log.info("finished %s in %.3g s", run_dir, record["wall_s"])
    return RunOutcome(run_dir, result, detail, record, tuple(run.notes), run.verdicts)


def start_early_step() -> EarlyStep | None:
    """best.step's child (:class:`EarlyStep`), forked now at the lowest priority, where it can
    be: the STEP writer installed, no other thread running in this process (a lock another
    thread holds at the fork stays held in the child) and the child's priority restorable
    (:func:`can_restore_priority`); else None.

    Its import of build123d (~3 s CPU) takes only the CPU time no other process wants. The CLI
    starts it before it loads the study: while this process imports the kind and loads the
    compiled kernels (~1 s on one core) the other core is idle, and that import uses it instead
    of competing with the report at the end of a short run.
    """
    if threading.active_count() == 1 and step_available() and can_restore_priority():
        return EarlyStep.start(nice=EARLY_STEP_NICE)
    return None


class ReportPreload:
    """The report's preload thread (:func:`_preload_report`): started at once, or later by
    :meth:`start` (a hybrid run starts it when its gradient stage begins, see ``_run_in``).

    Attributes
    ----------
    thread : threading.Thread
        The thread; it runs ``load`` once, when started.
    """

    def __init__(self, load: Callable[[], None]) -> None:
        self.thread = threading.Thread(target=load, name="flexopt-preload", daemon=True)

    def start(self) -> None:
        """Start the thread unless it was started already."""
        if self.thread.ident is None:
            self.thread.start()

    def join(self, timeout: float | None = None) -> None:
        """Wait for the preload: started here first if nothing started it (it then runs while
        this thread waits, as the report would have loaded it anyway)."""
        self.start()
        self.thread.join(timeout)

    def is_alive(self) -> bool:
        return self.thread.is_alive()


def _preload_report(
    problem: DesignProblem, settings: ParallelSettings, start: bool = True
) -> ReportPreload | None:
    """Import and load what the report will need, in a thread, while the workers solve.

    The report runs in this process after the optimisation, on the run's critical path; what it
    first has to import and load (matplotlib for the plots, ezdxf, trimesh, the module reading
    plotly.js and the problem's ``warm_up_detail``: ~0.9 s CPU for the constant-force study) is
    loaded here
    instead, while this process mostly waits for its workers. Only with worker processes: a
    serial run solves in this process, where the thread would compete. A failure is only
    logged: the report then loads what it needs itself. Returns the preload (started unless
    ``start`` is False: then :meth:`ReportPreload.start` starts it) or None.
    """
    if settings.backend == "serial":
        return None
    warm = problem.warm_up_detail

    def load() -> None:
        try:
            import matplotlib.backends.backend_agg  # noqa: F401  (the plots' first import)
            import matplotlib.figure  # noqa: F401

            warm()
            # the part's STL (trimesh, ~0.5 s) and DXF (ezdxf). Not build123d for best.step
            # (~2.6 s): the STEP file is made in a forked child that imports it and exits
            # without the ~1 s of interpreter teardown OpenCascade adds to a process.
            import flexopt.geometry.dxf  # noqa: F401
            import flexopt.geometry.solid  # noqa: F401

            # the report's modules (not imported before the pool forks: run/state.py) and the
            # part's solid libraries
            import flexopt.pipeline.durability_report  # noqa: F401
            import flexopt.pipeline.report  # noqa: F401
            import flexopt.pipeline.report_html  # noqa: F401
            import flexopt.pipeline.run.figures  # noqa: F401
            import flexopt.pipeline.vtu  # noqa: F401
            import manifold3d  # noqa: F401  (geometry.solid imports them where a solid is made)
            import scipy.optimize  # noqa: F401  (e.g. the constant-force detail's PRB synthesis)
            import trimesh  # noqa: F401

            # what reads plotly.js, and the templates' JSON (report.html's figures are plain
            # JSON: no plotly classes to load, pipeline/figure_json.py)
            from flexopt.pipeline.html_templates import warm_up as warm_up_html

            warm_up_html()
        except Exception as exc:  # the report loads it again, and says what fails
            log.info("preloading the report failed: %s", _one_line(f"{type(exc).__name__}: {exc}"))

    preload = ReportPreload(load)
    if start:
        preload.start()
    return preload


def _n_workers(settings: ParallelSettings) -> int:
    return 1 if settings.backend == "serial" else settings.n_workers
