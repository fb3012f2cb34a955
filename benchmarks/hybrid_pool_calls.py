"""The hybrid's requests on the process pool (session 28, issue 27): how long one round of the
gradient stage takes with one request and with two (the two starts in lockstep), and the CPU a
Jacobian costs in a worker against the run's process.

On the constant-force example's problem (``method: hybrid``, with residuals) and ``--designs``
designs (the last of a hybrid run's store when ``--store`` is given, else the GA's random
ones, seed 0): a 2-worker :class:`pipeline.parallel.ProcessPool` answers, round by round in the
same minutes (the kinds alternating), one exact Jacobian, two Jacobians, one design and two
designs, ``--rounds`` times each (after one warm-up round of each: the workers load the
gradient kernels once). Printed per kind: the median wall time of a round and the workers' CPU
time per request (from /proc, utime + stime), then one Jacobian's CPU time in this process
(the sequential stage's place for it), and the load average before and after. With two free
cores a round of two takes the time of one; a loaded machine shares its cores with the other
jobs, so the ratio says what the lockstep gains there::

    nice python benchmarks/hybrid_pool_calls.py
    nice python benchmarks/hybrid_pool_calls.py --rounds 9 --store RUN_DIR/evaluations.jsonl
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def cpu_of(pids: list[int]) -> float:
    """s, user + system CPU time of the processes ``pids`` so far (/proc/PID/stat)."""
    tick = os.sysconf("SC_CLK_TCK")
    total = 0
    for pid in pids:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        total += int(fields[11]) + int(fields[12])  # utime, stime (fields 14, 15 of stat)
    return total / tick


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--designs", type=int, default=4)
    parser.add_argument("--store", type=Path, default=None, help="a run's evaluations.jsonl")
    args = parser.parse_args()
    from flexopt.pipeline.parallel import ProcessPool
    from flexopt.pipeline.run import prepare_run
    from flexopt.pipeline.study import HybridSpec, load_study

    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    optimiser = study.optimiser.model_copy(update={"method": "hybrid", "hybrid": HybridSpec()})
    problem = prepare_run(study.model_copy(update={"optimiser": optimiser})).problem
    if args.store is not None:
        rows = [json.loads(line) for line in args.store.read_text().splitlines()]
        X = np.array([r["x"] for r in rows[-args.designs :]])
    else:
        rng = np.random.default_rng(0)
        space = problem.space
        X = space.lower + rng.random((args.designs, space.n_var)) * (space.upper - space.lower)
    print(f"load avg  {load()} (1, 5, 15 min) at start; {os.cpu_count()} cores")
    kinds: dict[str, tuple[list[Any], np.ndarray]] = {
        "1 Jacobian": ([("jacobian", X[0])], X[:0]),
        "2 Jacobians": ([("jacobian", X[0]), ("jacobian", X[1])], X[:0]),
        "1 design": ([], X[2:3]),
        "2 designs": ([], X[2:4]),
    }
    wall: dict[str, list[float]] = {k: [] for k in kinds}
    cpu: dict[str, list[float]] = {k: [] for k in kinds}
    pool = ProcessPool(problem, 2)
    try:
        for _ in range(2):  # both workers started and their kernels loaded
            pool.run(problem, X[2:4], [("jacobian", X[0]), ("jacobian", X[1])])
        pids = [w.process.pid for w in pool.workers]
        for r in range(args.rounds):
            order = list(kinds) if r % 2 == 0 else list(reversed(kinds))
            for kind in order:
                calls, designs = kinds[kind]
                c0, t0 = cpu_of(pids), time.perf_counter()
                pool.run(problem, designs, calls)
                wall[kind].append(time.perf_counter() - t0)
                cpu[kind].append((cpu_of(pids) - c0) / (len(calls) + len(designs)))
    finally:
        pool.close()
    for kind in kinds:
        print(
            f"  {kind:12s} round wall median {1000 * statistics.median(wall[kind]):7.1f} ms  "
            f"worker CPU per request median {1000 * statistics.median(cpu[kind]):6.1f} ms  "
            f"({args.rounds} rounds)"
        )
    from threadpoolctl import threadpool_limits

    here = []
    with threadpool_limits(1):  # as the run's process during its optimisation
        problem.jacobian(X[0])
        for _ in range(args.rounds):
            c0 = time.process_time()
            problem.jacobian(X[0])
            here.append(time.process_time() - c0)
    print(f"  1 Jacobian in this process: CPU median {1000 * statistics.median(here):6.1f} ms")
    ratio = statistics.median(wall["2 Jacobians"]) / statistics.median(wall["1 Jacobian"])
    print(f"  a round of 2 Jacobians takes {ratio:.2f}x a round of 1 (1.0: two free cores)")
    print(f"load avg  {load()} (1, 5, 15 min) at end")


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    main()
