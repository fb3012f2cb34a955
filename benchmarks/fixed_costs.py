"""Where the fixed costs of a short study go: start-up, ``load_study``, the final re-solves, the
report's files (issue 27 item 4).

    nice python benchmarks/fixed_costs.py [--study constant-force] [--repeat 3]
        [--parts startup evaluate run timeline] [--workers N] [--quick] [--timed-only]
        [--ab OTHER_PYTHON] [--record PATH]

Three parts, each repeated ``--repeat`` times in fresh processes (medians printed, with the
load average before and after each part, since the machine is shared), and a fourth,
``timeline``, run once:

``startup``
    ``python -c pass``, ``python -c "import flexopt.pipeline.cli"`` and ``flexopt --version``
    as subprocesses: wall and CPU (s, the children's user + system time), and the ten largest
    cumulative imports of the CLI module from ``python -X importtime`` (one run).
``evaluate`` / ``run``
    The whole command (``flexopt evaluate STUDY`` / ``flexopt run STUDY``) as a subprocess, then
    the same command in a child process of this script that calls ``flexopt.pipeline.cli.main``
    with timers wrapped around the functions where the time goes: ``load_study``, the optimiser
    (``run_ga`` / ``run_hybrid``), the best design's ``detail`` (the final re-solve, with the
    plane-stress check inside it), the verdict, ``render_report`` (report.md), ``render_html``
    (report.html, with the plotly figures' building and their serialisation ``_Figures.embed``
    and plotly.js's text), each result file's maker (the PNG plots, VTU, STL/DXF/3MF/STEP,
    best_cad.py, print_sheet.md), the PNG plots and the evaluate's own solve. Timed makers that
    run in a forked child (the plots, best.step) are recorded by that child (their wall overlaps
    the main process's). The numba kernels' first call (cache load) is timed on its own: the
    study's nominal design evaluated twice in a fresh process after ``load_study``.

``timeline``
    ``flexopt run STUDY`` once in a child with every design and hook call (a Jacobian, a
    check) timed where it runs (a worker: wall and CPU), each batch the optimiser hands the
    pool, and the report's preload thread (when it ran, its CPU). Per stage (the GA's
    generations, the hybrid's gradient batches): the designs' and calls' CPU, the shortest
    time two workers could solve each batch in (the batch's items dealt largest first to the
    less loaded worker, its CPU as their time) and the core-seconds that schedule leaves idle:
    where a thread of the run process can work without taking a core from a worker. A hook
    call is labelled by its kind (``call:jacobian``, ``call:check``, a check's parts
    ``call:check:0`` / ``call:check:1``), counted by kind with its mean CPU, and the gradient
    rounds that hold a check are summed apart (their 2-worker s: the checks' share of the
    stage's critical path); ``--record PATH`` keeps
    the timed rows (JSON lines: label, t0, t1 in perf_counter s, cpu s, pid) for a closer look.

``--ab OTHER_PYTHON``
    Instead of the breakdown: the plain commands with another install's ``flexopt`` (A, e.g.
    main's venv) and this one's (B), alternating, medians of wall and CPU.
``--quick``
    ``flexopt run --quick`` (the study's ``quick_pop_size`` x ``quick_n_gen`` designs): a run
    that is nearly all fixed costs.
``--timed-only``
    The timed child alone (no plain command): for a study too long to run twice (sea-spring).

Times are wall (``time.perf_counter``) and CPU of the process that ran the code
(``time.process_time``, all its threads), s. Nested timers are inclusive (``detail`` contains
``plane_stress_check``). Numbers only; the run and evaluate folders go to a temporary folder
that is removed.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

FLEXOPT = Path(sys.executable).with_name("flexopt")

#: (module, attribute, label): functions timed in the breakdown. A class attribute is given as
#: "Class.method". Every flexopt module that imported the function by name gets the timed one.
TIMED: tuple[tuple[str, str, str], ...] = (
    ("flexopt.pipeline.study", "load_study", "load_study"),
    ("flexopt.pipeline.run.setup", "prepare_run", "prepare_run"),
    ("flexopt.pipeline.run.runner", "start_early_step", "best.step's child: fork"),
    ("flexopt.pipeline.backends", "_warm_up_kernels", "pool: kernels loaded before the fork"),
    ("flexopt.pipeline.parallel", "ProcessPool.__init__", "pool: the workers forked"),
    ("flexopt.optimise.ga", "run_ga", "optimiser (GA)"),
    ("flexopt.optimise.hybrid", "run_hybrid", "optimiser (hybrid)"),
    ("flexopt.pipeline.run.state", "RunState.finish", "report phase: RunState.finish"),
    ("flexopt.pipeline.run.state", "RunState.judge", "verdict (judge)"),
    ("flexopt.pipeline.run.state", "RunState.robustness", "robustness"),
    ("flexopt.pipeline.run.state", "RunState.collect_groups", "wait for forked files"),
    ("flexopt.pipeline.run.runner", "_preload_report", "start preload thread"),
    ("flexopt.fea.fidelity", "plane_stress_check", "plane-stress check"),
    ("flexopt.pipeline.report", "render_report", "report.md (render_report)"),
    ("flexopt.pipeline.report_html", "render_html", "report.html (render_html)"),
    ("flexopt.pipeline.report_html", "evaluate_html", "report.html (evaluate_html)"),
    ("flexopt.pipeline.report_html", "evaluate_part", "  evaluate_part (re-solve)"),
    ("flexopt.pipeline.report_html", "_Figures.embed", "  figure JSON + template"),
    ("plotly.offline", "get_plotlyjs", "  plotly.js text"),
    ("flexopt.pipeline.evaluate", "solve_study", "evaluate: solve_study"),
    ("flexopt.pipeline.evaluate", "_design_vtu", "evaluate: VTU files"),
    ("flexopt.pipeline.evaluate", "_stress_deformed", "evaluate: stress_deformed.png"),
    ("flexopt.pipeline.robustness", "run_robustness", "robustness samples"),
    ("flexopt.pipeline.plots", "plot_response", "evaluate: force_displacement.png"),
    ("flexopt.pipeline.plots", "plot_cases", "plot_cases"),
    ("flexopt.pipeline.screening", "taguchi_stage", "SEA stage 1 (Taguchi)"),
    ("flexopt.fea.solid3d", "check_solid3d", "3D check (check_solid3d)"),
    ("flexopt.fea.solid3d", "solve_solid3d", "  3D solve (solve_solid3d)"),
    ("flexopt.fea.solid3d", "converge_peak_stress", "3D peak convergence"),
)

#: modules imported before the timers go in (their import is timed as one phase)
PRELOAD = (
    "flexopt.pipeline.run",
    "flexopt.pipeline.run.state",
    "flexopt.pipeline.run.runner",
    "flexopt.pipeline.report",
    "flexopt.pipeline.report_html",
    "flexopt.pipeline.plots",
    "flexopt.pipeline.robustness",
    "flexopt.fea.fidelity",
    "flexopt.optimise.hybrid",
)


def _load() -> str:
    one, five, fifteen = os.getloadavg()
    return f"{one:.2f} {five:.2f} {fifteen:.2f}"


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _timed_subprocess(cmd: list[str], env: dict[str, str] | None = None) -> tuple[float, float]:
    """(wall, CPU) of a command, s; CPU counts every waited-for descendant."""
    cpu0, t0 = _children_cpu(), time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({done.returncode}): {done.stderr[-800:]}")
    return wall, cpu


# -- the child: one command with timers ------------------------------------------------------------


class _Recorder:
    """Appends one JSON line per timed call to a file (O_APPEND: forked children write too)."""

    def __init__(self, path: str) -> None:
        self.fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
        self.main_pid = os.getpid()

    def add(self, label: str, wall: float, cpu: float) -> None:
        where = "main" if os.getpid() == self.main_pid else "child"
        line = json.dumps({"label": label, "wall": wall, "cpu": cpu, "where": where}) + "\n"
        os.write(self.fd, line.encode())

    def add_span(self, label: str, t0: float, t1: float, cpu: float) -> None:
        """One timed span: from ``t0`` to ``t1`` (perf_counter, s) and its thread's CPU (s)."""
        row = {"label": label, "t0": t0, "t1": t1, "cpu": cpu, "pid": os.getpid()}
        os.write(self.fd, (json.dumps(row) + "\n").encode())


def _wrap(func: Any, label: str, rec: _Recorder) -> Any:
    import functools

    depth = {"n": 0}  # a recursive or re-entrant call is counted once, at its outermost

    @functools.wraps(func)
    def timed(*args: Any, **kwargs: Any) -> Any:
        if depth["n"]:
            return func(*args, **kwargs)
        depth["n"] += 1
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            return func(*args, **kwargs)
        finally:
            depth["n"] -= 1
            rec.add(label, time.perf_counter() - t0, time.process_time() - c0)

    timed.__fixed_costs_original__ = func  # type: ignore[attr-defined]
    return timed


def _install(rec: _Recorder) -> None:
    import importlib

    for module_name, attr, label in TIMED:
        try:
            module = importlib.import_module(module_name)
        except ImportError:
            continue
        owner: Any = module
        name = attr
        if "." in attr:
            owner_name, name = attr.split(".")
            owner = getattr(module, owner_name, None)
            if owner is None:
                continue
        original = getattr(owner, name, None)
        if original is None:
            continue
        timed = _wrap(original, label, rec)
        setattr(owner, name, timed)
        if owner is module:  # every module that imported it by name
            for other in list(sys.modules.values()):
                if getattr(other, "__name__", "").startswith("flexopt") and (
                    getattr(other, name, None) is original
                ):
                    setattr(other, name, timed)
    _time_artefacts(rec)
    _time_run_parts(rec)


def _time_run_parts(rec: _Recorder) -> None:
    """The best design's ``detail`` (the final re-solve) and the wait for the first generation
    (the pool's start: the workers' imports, the problem and the kernels loaded in each)."""
    from flexopt.pipeline.run import state

    original_init = state.RunState.__init__
    original_done = state.RunState.generation_done

    def init(self: Any, setup: Any, *args: Any, **kwargs: Any) -> None:
        original_init(self, setup, *args, **kwargs)
        problem = setup.problem
        problem.detail = _wrap(problem.detail, "best design's detail (re-solve)", rec)
        self.__fixed_costs_t0__ = time.perf_counter()

    def generation_done(self: Any, gen: Any) -> None:
        # the first generation also waits for the pool (the workers' imports, the problem and
        # the kernels loaded in each); the later ones are the solves and the barrier
        now = time.perf_counter()
        label = "GA: first generation" if gen.index == 0 else "GA: later generations"
        rec.add(label, now - self.__fixed_costs_t0__, 0.0)
        self.__fixed_costs_t0__ = now
        return original_done(self, gen)

    state.RunState.__init__ = init  # type: ignore[method-assign]
    state.RunState.generation_done = generation_done  # type: ignore[method-assign]


def _time_artefacts(rec: _Recorder) -> None:
    """Each result file's maker in a run (RunState.artefact), timed where it runs."""
    from flexopt.pipeline.run import state

    original = state.RunState.artefact

    def artefact(self: Any, name: str, make: Any, group: str | None = None) -> None:
        label = "file best_steps/*.vtu" if name.startswith("best_steps/") else f"file {name}"
        return original(self, name, _wrap(make, label, rec), group)

    state.RunState.artefact = artefact  # type: ignore[method-assign]


def _numba_first_call(study_name: str, rec: _Recorder) -> None:
    """The study's nominal design solved twice in this fresh process: the first call loads the
    compiled kernels from numba's cache (or compiles them), the second does not."""
    from flexopt.pipeline.problems import nominal_design
    from flexopt.pipeline.studies import get_kind
    from flexopt.pipeline.study import load_study, resolve_study_path

    study = load_study(resolve_study_path(study_name))
    kind = get_kind(study.kind)
    if kind.problem is None:
        return
    problem = kind.problem(study)
    x = nominal_design(problem, study)
    times = []
    for _ in range(2):
        t0, c0 = time.perf_counter(), time.process_time()
        problem.evaluate(x)
        times.append((time.perf_counter() - t0, time.process_time() - c0))
    rec.add("numba: first evaluate", *times[0])
    rec.add("numba: second evaluate", *times[1])
    rec.add(
        "numba: first - second (cache load)", times[0][0] - times[1][0], times[0][1] - times[1][1]
    )


def _install_timeline(rec: _Recorder) -> None:
    """Every design and hook call where it runs (``item``: wall from, wall to, CPU of the
    thread; a forked worker records its own), every batch the evaluator hands the backend
    (``batch``) and the report's preload thread (``preload``: when it started and ended, the
    thread's CPU). Times are ``time.perf_counter`` (CLOCK_MONOTONIC: one clock for every
    process on the machine)."""
    import threading

    from flexopt.pipeline import parallel
    from flexopt.pipeline.run import evaluator, runner

    def spans(func: Any, label: str) -> Any:
        def timed(*args: Any, **kwargs: Any) -> Any:
            t0, c0 = time.perf_counter(), time.thread_time()
            try:
                return func(*args, **kwargs)
            finally:
                rec.add_span(label, t0, time.perf_counter(), time.thread_time() - c0)

        return timed

    parallel.evaluate_one = spans(parallel.evaluate_one, "design")
    call_hook = parallel.call_hook

    def hook(problem: Any, kind: str, x: Any) -> Any:  # the kind in the label: call:jacobian
        return spans(call_hook, f"call:{kind}")(problem, kind, x)

    parallel.call_hook = hook
    evaluator.Evaluator.map_calls = spans(evaluator.Evaluator.map_calls, "batch")
    preload_report = getattr(runner, "_preload_report", None)
    if preload_report is None:
        return

    def preload(*args: Any, **kwargs: Any) -> Any:
        made = preload_report(*args, **kwargs)
        thread = getattr(made, "thread", made)  # a ReportPreload, or (older) the thread
        if thread is None:
            return made

        def watch() -> None:  # the thread's CPU clock, read until it ends
            while thread.ident is None:
                time.sleep(0.002)
            t0, cpu = time.perf_counter(), 0.0
            clock = time.pthread_getcpuclockid(thread.ident)
            while thread.is_alive():
                with contextlib.suppress(OSError):
                    cpu = time.clock_gettime(clock)
                time.sleep(0.002)
            rec.add_span("preload", t0, time.perf_counter(), cpu)

        threading.Thread(target=watch, daemon=True).start()
        return made

    runner._preload_report = preload


def _timeline_table(rows: list[dict[str, Any]]) -> None:
    """Per stage: batches, items, their CPU, the two-worker schedule's time and idle share."""
    batches = sorted((r for r in rows if r["label"] == "batch"), key=lambda r: r["t0"])
    items = [r for r in rows if r["label"] == "design" or r["label"].startswith("call")]
    t_first = batches[0]["t0"] if batches else 0.0
    stages: dict[str, list[float]] = {}
    checks = [0, 0.0]  # gradient rounds holding a check (or a part of one), their 2-worker s
    calls: dict[str, list[float]] = {}  # hook calls by kind: CPU s of each
    for batch in batches:
        inside = [r for r in items if batch["t0"] <= r["t0"] and r["t1"] <= batch["t1"] + 1e-3]
        n_designs = sum(r["label"] == "design" for r in inside)
        # the GA's generations are batches of designs only, the first the largest; a gradient
        # batch asks for a few designs, or hook calls
        stage = "GA" if n_designs == len(inside) and n_designs >= 8 else "gradient"
        loads = [0.0, 0.0]
        for cpu in sorted((r["cpu"] for r in inside), reverse=True):
            loads[loads.index(min(loads))] += cpu
        s = stages.setdefault(stage, [0, 0, 0, 0.0, 0.0, 0.0, 0.0])
        s[0] += 1
        s[1] += n_designs
        s[2] += len(inside) - n_designs
        s[3] += sum(loads)
        s[4] += max(loads)
        s[5] += 2 * max(loads) - sum(loads)
        s[6] += batch["t1"] - batch["t0"]
        if stage == "gradient" and any(r["label"].startswith("call:check") for r in inside):
            checks[0] += 1
            checks[1] += max(loads)
        for r in inside:
            if r["label"].startswith("call"):
                calls.setdefault(r["label"].removeprefix("call:"), []).append(r["cpu"])
    print("  batches by stage (CPU s of the items; 2-worker schedule: items largest first)")
    print(
        f"    {'stage':9s} {'batches':>7s} {'designs':>7s} {'calls':>5s} {'CPU s':>7s} "
        f"{'2-worker s':>10s} {'idle core-s':>11s} {'wall s':>7s}"
    )
    for stage, (nb, nd, nc, cpu, span, idle, wall) in stages.items():
        print(
            f"    {stage:9s} {nb:7d} {nd:7d} {nc:5d} {cpu:7.3f} {span:10.3f} {idle:11.3f} "
            f"{wall:7.3f}"
        )
    if calls:
        kinds = ", ".join(
            f"{kind} {len(cpu)} (mean {1e3 * sum(cpu) / len(cpu):.1f} ms)"
            for kind, cpu in sorted(calls.items())
        )
        print(f"  hook calls (CPU): {kinds}")
        print(
            f"  gradient rounds holding a check: {checks[0]}, their 2-worker s {checks[1]:.3f} "
            "(the checks' share of the stage's critical path)"
        )
    for r in rows:
        if r["label"] == "preload":
            print(
                f"  report preload thread: {r['cpu']:.3f} s CPU, from {r['t0'] - t_first:.2f} s "
                f"to {r['t1'] - t_first:.2f} s after the first batch began"
            )


def child(argv: list[str]) -> None:
    """``--child RECORD numba|evaluate|run|timeline STUDY OUT [--workers N]``."""
    record, what, study, out, *more = argv
    rec = _Recorder(record)
    t0, c0 = time.perf_counter(), time.process_time()
    import flexopt.pipeline.cli as cli

    rec.add("import flexopt.pipeline.cli", time.perf_counter() - t0, time.process_time() - c0)
    if what == "numba":
        _numba_first_call(study, rec)
        return
    if what == "timeline":
        _install_timeline(rec)
        code = cli.main(["run", study, "--out", out, "--quiet", *more])
        raise SystemExit(code)
    import importlib

    import yaml
    from flexopt.pipeline.study import resolve_study_path

    t1, c1 = time.perf_counter(), time.process_time()
    for name in PRELOAD:
        importlib.import_module(name)
    # the study's kind module: its functions imported by name are timed too (stage 1)
    kind = yaml.safe_load(resolve_study_path(study).read_text()).get("kind", "")
    with contextlib.suppress(ImportError):
        importlib.import_module(f"flexopt.pipeline.studies.{kind}")
    rec.add("import run/report modules", time.perf_counter() - t1, time.process_time() - c1)
    _install(rec)
    t2, c2 = time.perf_counter(), time.process_time()
    code = cli.main([what, study, "--out", out, *(["--quiet"] if what == "run" else []), *more])
    rec.add(f"cli.main({what})", time.perf_counter() - t2, time.process_time() - c2)
    rec.add("child total (after interpreter start)", time.perf_counter() - t0, time.process_time())
    if code != 0:
        raise SystemExit(code)


# -- the parent ------------------------------------------------------------------------------------


def _median_table(rounds: list[list[dict[str, Any]]]) -> list[tuple[str, str, float, float, int]]:
    """(label, where, median wall, median CPU, calls per round) over the rounds, in first-seen
    order; a label's figures in one round are summed over its calls."""
    order: list[tuple[str, str]] = []
    per_round: list[dict[tuple[str, str], list[float]]] = []
    for rows in rounds:
        sums: dict[tuple[str, str], list[float]] = defaultdict(lambda: [0.0, 0.0, 0])
        for row in rows:
            key = (row["label"], row["where"])
            if key not in order:
                order.append(key)
            sums[key][0] += row["wall"]
            sums[key][1] += row["cpu"]
            sums[key][2] += 1
        per_round.append(sums)
    table = []
    for key in order:
        walls = [r[key][0] for r in per_round if key in r]
        cpus = [r[key][1] for r in per_round if key in r]
        calls = max(int(r[key][2]) for r in per_round if key in r)
        table.append((*key, statistics.median(walls), statistics.median(cpus), calls))
    return table


def _print_table(title: str, table: list[tuple[str, str, float, float, int]]) -> None:
    print(f"  {title}")
    print(f"    {'phase':48s} {'where':5s} {'wall s':>8s} {'CPU s':>8s} {'calls':>5s}")
    for label, where, wall, cpu, calls in table:
        print(f"    {label:48s} {where:5s} {wall:8.3f} {cpu:8.3f} {calls:5d}")


def part_startup(repeat: int) -> None:
    print(f"startup (load {_load()})")
    commands = {
        "python -c pass": [sys.executable, "-c", "pass"],
        "import flexopt.pipeline.cli": [sys.executable, "-c", "import flexopt.pipeline.cli"],
        "flexopt --version": [str(FLEXOPT), "--version"],
    }
    results: dict[str, list[tuple[float, float]]] = {k: [] for k in commands}
    for _ in range(repeat):  # interleaved: a change of load hits every command alike
        for name, cmd in commands.items():
            results[name].append(_timed_subprocess(cmd))
    for name, runs in results.items():
        wall = statistics.median(w for w, _ in runs)
        cpu = statistics.median(c for _, c in runs)
        print(f"    {name:48s} wall {wall:6.3f} s  CPU {cpu:6.3f} s  (median of {repeat})")
    done = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", "import flexopt.pipeline.cli"],
        capture_output=True,
        text=True,
    )
    rows = []
    for line in done.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _, cumulative_us, name = line[len("import time:") :].split("|", 2)
        rows.append((int(cumulative_us), name.rstrip()))
    print("    largest cumulative imports of flexopt.pipeline.cli (python -X importtime, us):")
    for cumulative, name in sorted(rows, reverse=True)[:12]:
        print(f"      {cumulative:9d} {name}")
    print(f"  load after: {_load()}")


def part_command(
    what: str,
    study: str,
    repeat: int,
    workers: int | None,
    timed_only: bool = False,
    quick: bool = False,
) -> None:
    more = ["--workers", str(workers)] if workers is not None and what == "run" else []
    more += ["--quick"] if quick and what == "run" else []
    print(f"{what} {study} {' '.join(more)} (load {_load()})")
    whole: list[tuple[float, float]] = []
    rounds: list[list[dict[str, Any]]] = []
    numba: list[list[dict[str, Any]]] = []
    with tempfile.TemporaryDirectory(prefix="fixed-costs-") as tmp:
        for i in range(repeat):  # the plain command and the timed child, interleaved
            out = Path(tmp) / f"plain-{i}"
            quiet = ["--quiet"] if what == "run" else []
            if timed_only:  # a long study: the timed child alone
                whole.append((float("nan"), float("nan")))
            else:
                whole.append(
                    _timed_subprocess([str(FLEXOPT), what, study, "--out", str(out), *quiet, *more])
                )
                shutil.rmtree(out, ignore_errors=True)
            for kind, store in (("numba", numba), (what, rounds)):
                if kind == "numba" and what != "evaluate":
                    continue  # once per part is enough: the evaluate part measures it
                record = Path(tmp) / f"record-{kind}-{i}.jsonl"
                out = Path(tmp) / f"timed-{kind}-{i}"
                cmd = [
                    sys.executable,
                    __file__,
                    "--child",
                    str(record),
                    kind,
                    study,
                    str(out),
                    *more,
                ]
                cpu0, t0 = _children_cpu(), time.perf_counter()
                done = subprocess.run(cmd, capture_output=True, text=True)
                tree = {"wall": time.perf_counter() - t0, "cpu": _children_cpu() - cpu0}
                if done.returncode != 0:
                    raise SystemExit(f"{' '.join(cmd)} failed: {done.stderr[-1500:]}")
                rows = [json.loads(line) for line in record.read_text().splitlines()]
                label = "timed child, whole (CPU: with its workers)"
                store.append([*rows, {"label": label, "where": "tree", **tree}])
                shutil.rmtree(out, ignore_errors=True)
            print(
                f"    round {i + 1}: {whole[-1][0]:.2f} s wall, {whole[-1][1]:.2f} s CPU, "
                f"load {_load()}"
            )
    wall = statistics.median(w for w, _ in whole)
    cpu = statistics.median(c for _, c in whole)
    print(f"  flexopt {what} {study}: wall {wall:.2f} s, CPU {cpu:.2f} s (median of {repeat})")
    _print_table(
        "breakdown (timed child, medians; 'child' = a forked child's share)", _median_table(rounds)
    )
    if numba:
        _print_table(
            "numba kernels: the nominal design solved twice in a fresh process",
            _median_table(numba),
        )
    print(f"  load after: {_load()}")


def part_timeline(study: str, workers: int | None, keep: str | None = None) -> None:
    """``flexopt run STUDY`` once with every design, hook call and batch timed (see the module
    docstring): where the workers idle, stage by stage. ``keep``: a path to copy the timed rows
    to (JSON lines: label, t0, t1 perf_counter s, cpu s, pid)."""
    more = ["--workers", str(workers)] if workers is not None else []
    print(f"timeline: run {study} {' '.join(more)} (load {_load()})")
    with tempfile.TemporaryDirectory(prefix="fixed-costs-") as tmp:
        record = Path(tmp) / "record-timeline.jsonl"
        cmd = [sys.executable, __file__, "--child", str(record), "timeline", study]
        t0 = time.perf_counter()
        done = subprocess.run([*cmd, str(Path(tmp) / "run"), *more], capture_output=True, text=True)
        if done.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed: {done.stderr[-1500:]}")
        rows = [json.loads(line) for line in record.read_text().splitlines()]
        if keep:
            shutil.copyfile(record, keep)
    print(f"  the run: {time.perf_counter() - t0:.2f} s wall")
    _timeline_table([r for r in rows if "t0" in r])
    print(f"  load after: {_load()}")


def part_ab(what: str, study: str, repeat: int, other: str, quick: bool = False) -> None:
    """The plain command with this interpreter's flexopt and another's (e.g. main's venv),
    alternating (the order swapped every round): medians of wall and CPU, s."""
    ours, theirs = str(FLEXOPT), str(Path(other).with_name("flexopt"))
    print(f"A/B {what} {study}: A = {theirs}, B = {ours} (load {_load()})")
    runs: dict[str, list[tuple[float, float]]] = {"A": [], "B": []}
    quiet = ["--quiet", *(["--quick"] if quick else [])] if what == "run" else []
    with tempfile.TemporaryDirectory(prefix="fixed-costs-ab-") as tmp:
        for i in range(repeat):
            order = [("A", theirs), ("B", ours)] if i % 2 == 0 else [("B", ours), ("A", theirs)]
            for name, exe in order:
                out = Path(tmp) / f"{name}-{i}"
                runs[name].append(_timed_subprocess([exe, what, study, "--out", str(out), *quiet]))
                shutil.rmtree(out, ignore_errors=True)
            print(
                f"    round {i + 1}: A {runs['A'][-1][0]:.2f} s wall {runs['A'][-1][1]:.2f} s CPU, "
                f"B {runs['B'][-1][0]:.2f} s wall {runs['B'][-1][1]:.2f} s CPU, load {_load()}"
            )
    for name in ("A", "B"):
        wall = statistics.median(w for w, _ in runs[name])
        cpu = statistics.median(c for _, c in runs[name])
        print(f"  {name}: wall {wall:.2f} s, CPU {cpu:.2f} s (median of {repeat})")


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(sys.argv[2:])
        return
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--study", default="constant-force")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument(
        "--parts",
        nargs="+",
        default=["startup", "evaluate", "run"],
        choices=["startup", "evaluate", "run", "timeline"],
    )
    parser.add_argument("--workers", type=int, default=None, help="flexopt run --workers")
    parser.add_argument("--quick", action="store_true", help="flexopt run --quick")
    parser.add_argument(
        "--timed-only",
        action="store_true",
        help="run only the timed child (one run per round, for a long study such as sea-spring)",
    )
    parser.add_argument(
        "--ab",
        metavar="OTHER_PYTHON",
        help="instead of the breakdown: the plain commands of --parts evaluate/run with this "
        "interpreter's flexopt (A) against ours (B), alternating",
    )
    parser.add_argument(
        "--record", metavar="PATH", help="timeline: keep its timed rows (JSON lines) at PATH"
    )
    args = parser.parse_args()
    if args.repeat < 1:
        parser.exit(2, "fixed_costs.py: error: --repeat must be at least 1\n")
    print(f"date      {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"python    {sys.executable}; cores {os.cpu_count()}")
    print(f"load avg  {_load()} (1, 5, 15 min) at start")
    if args.ab:
        for what in ("evaluate", "run"):
            if what in args.parts:
                part_ab(what, args.study, args.repeat, args.ab, args.quick)
        return
    if "startup" in args.parts:
        part_startup(max(args.repeat, 5))
    for what in ("evaluate", "run"):
        if what in args.parts:
            part_command(what, args.study, args.repeat, args.workers, args.timed_only, args.quick)
    if "timeline" in args.parts:
        part_timeline(args.study, args.workers, args.record)


if __name__ == "__main__":
    main()
