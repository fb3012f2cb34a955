"""Whole studies end to end, and where their time goes: solve, runner, writes, report (issue 13).

Each run is ``flexopt run STUDY`` in a fresh child process (``flexopt.pipeline.cli.main``, the
command a user types, default workers: one per core), timed from the parent as wall time and CPU
time (the child and its workers, ``RUSAGE_CHILDREN``). Inside the child a few methods are wrapped
with timers, which changes nothing they do:

* **writes** — ``EvaluationStore.append`` / ``sync`` / ``close`` (the store) and
  ``RunState.generation_done`` (evaluations.csv, history.csv, checkpoint.json, run.json, the
  generation's console line);
* **solve** — the evaluations' own times (``time_s``, measured in the worker around
  ``problem.evaluate``) summed, and divided by the number of workers for its share of the wall;
* **runner** — the rest of the optimisation phase (``optimise_wall_s`` of run.json): the GA,
  pickling, scheduling, workers idle at the end of a generation;
* **report** — after the optimisation: the best design's detail (the constant-force study's
  plane-stress check), plots, best.stl, report.md;
* **start** — the child's wall before the optimisation: imports, loading and checking the study,
  starting the workers (their compiled kernels loaded once, before the pool forks).

Runs are interleaved round by round (``--repeat``) over the studies and store modes, so load
changes hit each alike. ``--store-modes grouped fsync-each`` adds, side by side, the store as it
was before issue 13 (an fsync per design, ``sync_interval_s = 0``, no per-generation sync needed).

    python benchmarks/study_speed.py               # constant-force and sea-spring-quick, once
    python benchmarks/study_speed.py --studies constant-force --repeat 3 \
        --store-modes grouped fsync-each
    python benchmarks/study_speed.py --studies sea-spring   # the full SEA study (minutes)

The issue's targets (2 idle cores): ``flexopt run constant-force`` <= 20 s wall including the
plane-stress check, report and STL; ``flexopt run sea-spring`` <= 120 s.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGETS_S = {"constant-force": 20.0, "sea-spring": 120.0}


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


# ---- the child: one run with timers ------------------------------------------------------------


def child(study: str, out: str, store_mode: str, extra: list[str]) -> None:
    """Run ``flexopt run STUDY --out OUT -q`` here, print one JSON line of timings."""
    t_start = time.perf_counter()
    sys.path.insert(0, str(ROOT))
    from flexopt.pipeline import checkpoint
    from flexopt.pipeline.cli import main
    from flexopt.pipeline.run import state

    timers: dict[str, float] = defaultdict(float)
    depth: dict[str, int] = defaultdict(int)

    def wrap(owner, name: str, key: str) -> None:
        inner = getattr(owner, name)

        def timed(*args, **kwargs):
            depth[key] += 1  # sync inside append is counted once
            t0 = time.perf_counter()
            try:
                return inner(*args, **kwargs)
            finally:
                depth[key] -= 1
                if depth[key] == 0:
                    timers[key] += time.perf_counter() - t0

        setattr(owner, name, timed)

    for name in ("append", "sync", "close"):
        if hasattr(checkpoint.EvaluationStore, name):
            wrap(checkpoint.EvaluationStore, name, "store")
    wrap(state.RunState, "generation_done", "generation")
    if store_mode == "fsync-each":  # the store before issue 13: one fsync per design
        init = checkpoint.EvaluationStore.__init__

        def fsync_each(self, path, sync_interval_s=0.0):
            init(self, path, sync_interval_s=0.0)

        checkpoint.EvaluationStore.__init__ = fsync_each
    code = main(["run", study, "--out", out, "-q", *extra])
    record = json.loads((Path(out) / "run.json").read_text())
    store = Path(out) / "evaluations.jsonl"
    times = [json.loads(line)["time_s"] for line in store.read_text().splitlines() if line]
    print(
        json.dumps(
            {
                "exit": code,
                "wall_child_s": time.perf_counter() - t_start,
                "run_wall_s": record.get("wall_s"),
                "optimise_wall_s": record.get("optimise_wall_s"),
                # "workers": null in run.json means one per core (the default)
                "workers": (
                    1
                    if (record.get("parallel") or {}).get("backend") == "serial"
                    else (record.get("parallel") or {}).get("workers") or os.cpu_count() or 1
                ),
                "n_solved": record.get("n_solved"),
                "solve_sum_s": float(sum(times)),
                "store_s": timers["store"],
                "generation_s": timers["generation"],
            }
        )
    )


# ---- the parent: interleaved runs, the table ---------------------------------------------------


def one(study: str, store_mode: str, extra: list[str]) -> dict:
    with tempfile.TemporaryDirectory(prefix="study_speed_") as tmp:
        out = str(Path(tmp) / "run")
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, __file__, "--child", study, "--out", out, "--store-mode", store_mode,
             "--", *extra],
            capture_output=True, text=True, cwd=tmp,
        )  # fmt: skip
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    lines = proc.stdout.strip().splitlines()
    if not lines or not lines[-1].startswith("{"):  # a finished run prints its timings
        sys.exit(f"{study}: child failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    data = json.loads(lines[-1])
    data["wall_s"] = wall
    data["cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return data


def split(d: dict) -> dict[str, float]:
    """Wall seconds per phase (see the module docstring)."""
    optimise = d["optimise_wall_s"] or 0.0
    writes = d["store_s"] + d["generation_s"]
    solve = d["solve_sum_s"] / max(1, d["workers"])
    return {
        "start": d["wall_s"] - (d["run_wall_s"] or 0.0),
        "solve": solve,
        "runner": max(0.0, optimise - solve - writes),
        "writes": writes,
        "report": (d["run_wall_s"] or 0.0) - optimise,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--studies", nargs="+", default=["constant-force", "sea-spring-quick"])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--store-modes", nargs="+", default=["grouped"],
                    choices=["grouped", "fsync-each"])  # fmt: skip
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    ap.add_argument("--store-mode", default="grouped", help=argparse.SUPPRESS)
    ap.add_argument("extra", nargs="*", help="more arguments for flexopt run (after --)")
    args = ap.parse_args()
    if args.child:
        child(args.child, args.out, args.store_mode, args.extra)
        return
    print(f"date      {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC")
    print(f"machine   {platform.machine()}, {os.cpu_count()} cores, {platform.system()}")
    # what the run can use: the plane-stress solver (CHOLMOD with the cholmod extra, else
    # QDLDL; FLEXOPT_PLANE_STRESS_SOLVER overrides) and best.step (the step extra) change the
    # figures
    import importlib.util

    extras = [
        f"{name} {'yes' if importlib.util.find_spec(mod) else 'no'}"
        for name, mod in (("cholmod (cvxopt)", "cvxopt"), ("step (build123d)", "build123d"))
    ]
    forced = os.environ.get("FLEXOPT_PLANE_STRESS_SOLVER", "").strip()
    if forced:
        extras.append(f"plane-stress solver forced to '{forced}' (FLEXOPT_PLANE_STRESS_SOLVER)")
    print(f"python    {sys.executable}; extras: {', '.join(extras)}")
    print(f"load avg  {load()} (1, 5, 15 min) at start")
    cases = [(s, m) for s in args.studies for m in args.store_modes]
    runs: dict[tuple[str, str], list[dict]] = {c: [] for c in cases}
    loads = []
    for r in range(args.repeat):
        for case in cases:
            runs[case].append(one(case[0], case[1], args.extra))
            loads.append(load())
            d = runs[case][-1]
            print(f"  round {r + 1} {case[0]} ({case[1]}): {d['wall_s']:.1f} s wall, "
                  f"{d['cpu_s']:.1f} s CPU, load {loads[-1]}", flush=True)  # fmt: skip
    print(
        f"\nmedians of {args.repeat} interleaved run(s); wall s per phase (share of the wall);"
        " CPU = child + its workers"
    )
    head = f"  {'study':18s} {'store':10s} {'wall':>6s} {'CPU':>6s} {'designs':>7s} "
    phases = ("start", "solve", "runner", "writes", "report")
    print(head + " ".join(f"{p:>13s}" for p in phases))
    for case, ds in runs.items():
        wall = statistics.median(d["wall_s"] for d in ds)
        cpu = statistics.median(d["cpu_s"] for d in ds)
        parts = {p: statistics.median(split(d)[p] for d in ds) for p in phases}
        cells = " ".join(f"{parts[p]:6.1f} ({parts[p] / wall:4.0%})" for p in phases)
        print(
            f"  {case[0]:18s} {case[1]:10s} {wall:6.1f} {cpu:6.1f} {ds[0]['n_solved']:7d} {cells}"
        )
        target = TARGETS_S.get(case[0])
        if target is not None:
            verdict = "met" if wall <= target else "NOT met"
            print(f"    target <= {target:.0f} s wall on 2 idle cores: {verdict} at this load")
    if len(args.store_modes) > 1:
        for study in args.studies:
            a = statistics.median(split(d)["writes"] for d in runs[(study, "fsync-each")])
            b = statistics.median(split(d)["writes"] for d in runs[(study, "grouped")])
            print(f"  {study}: writes fsync-each / grouped = {a:.2f} s / {b:.2f} s")
    print(f"load avg  {load()} (1, 5, 15 min) at end")


if __name__ == "__main__":
    main()
