"""Evaluations per second and the runner's overhead: serial, process pool and Dask.

Solves the same constant-force designs (random points of the shipped example's design space,
fixed seed) serially in this process, on the local process pool with 1 and 2 workers, and on a
Dask cluster (a LocalCluster of 2 worker processes with 1 thread each, or ``--dask ADDRESS``).

For each backend it prints the designs solved per second and the overhead share::

    overhead = 1 - (sum of the in-worker solve times) / (workers x wall time of the batch)

the part of the workers' time not spent solving: pickling, messages, scheduling, idle workers at
the end of a batch. Worker start-up (once per run) is timed apart. It also times the round trip
of a design through the pool with a problem that does nothing, which is the per-design cost of the
runner itself.

    python benchmarks/runner_overhead.py                 # 48 designs
    python benchmarks/runner_overhead.py --designs 96 --dask tcp://127.0.0.1:8786

The numbers depend on the machine and on what else runs on it; docs/parallel.md quotes a run.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from flexopt.optimise import DesignSpace, Evaluation  # noqa: E402
from flexopt.pipeline.parallel import ProcessPool, SerialBackend  # noqa: E402
from flexopt.pipeline.run import prepare_run  # noqa: E402
from flexopt.pipeline.study import load_study  # noqa: E402


@dataclass
class NoOp:
    """A problem that returns at once: what is left of a batch's time is the runner's."""

    space: DesignSpace
    objective_names: tuple[str, ...] = ("f",)
    constraint_names: tuple[str, ...] = ()

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return Evaluation(x, np.array([float(x[0])]), np.zeros(0))

    def detail(self, x: np.ndarray) -> None:
        raise NotImplementedError


def measure(make, problem, X: np.ndarray, workers: int) -> dict:
    """Start a backend (``make()``), warm it up on a few designs, then time one batch of X."""
    t0 = time.perf_counter()
    backend = make()
    try:
        backend(problem, X[: 2 * workers])  # workers started and the problem loaded
        startup = time.perf_counter() - t0
        t1 = time.perf_counter()
        out = backend(problem, X)
        wall = time.perf_counter() - t1
    finally:
        backend.close()
    solve = sum(ev.time_s for ev in out)
    return {
        "startup_s": startup,
        "wall_s": wall,
        "rate": len(X) / wall,
        "mean_solve_ms": 1000 * solve / len(X),
        "overhead": 1.0 - solve / (workers * wall),
        "failed": sum(bool(ev.reason) for ev in out),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--designs", type=int, default=48, help="designs per batch (default 48)")
    parser.add_argument("--dask", metavar="ADDRESS", help="use this Dask scheduler")
    parser.add_argument("--no-dask", action="store_true", help="skip the Dask backend")
    args = parser.parse_args()

    study = load_study("constant-force")
    problem = prepare_run(study).problem
    rng = np.random.default_rng(2024)
    space = problem.space
    X = space.lower + rng.random((args.designs, space.n_var)) * (space.upper - space.lower)

    rows: list[tuple[str, dict]] = []
    rows.append(("serial (this process)", measure(SerialBackend, problem, X, 1)))
    for n in (1, 2):  # the pool with 1 worker too, to see the pool's own cost
        result = measure(lambda n=n: ProcessPool(problem, n), problem, X, n)
        rows.append((f"process pool, {n} worker{'s' if n > 1 else ''}", result))

    if not args.no_dask:
        try:
            import distributed
            from flexopt.pipeline.cluster import DaskBackend
        except ImportError:
            print("(dask.distributed not installed: pip install 'flexopt[dask]')")
        else:
            cluster = None
            address = args.dask
            if address is None:
                cluster = distributed.LocalCluster(
                    n_workers=2,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=40,
                )
                address = cluster.scheduler_address
            try:
                result = measure(lambda: DaskBackend(problem, address), problem, X, 2)
                where = "LocalCluster" if cluster is not None else address
                rows.append((f"dask ({where}), 2 workers", result))
            finally:
                if cluster is not None:
                    cluster.close()

    noop = NoOp(space)
    Y = np.tile(X, (20, 1))
    pool = ProcessPool(noop, 2)
    try:
        pool(noop, Y[:8])
        t0 = time.perf_counter()
        pool(noop, Y)
        per_design_ms = 1000 * (time.perf_counter() - t0) / len(Y)
    finally:
        pool.close()

    print(
        f"constant-force designs: {len(X)} random points of the example's space; "
        f"{os.cpu_count()} cores; load average {os.getloadavg()[0]:.2f} at the end\n"
    )
    header = f"{'backend':36s} {'eval/s':>7s} {'mean solve':>11s} {'overhead':>9s} {'start-up':>9s}"
    print(header)
    print("-" * len(header))
    for name, r in rows:
        print(
            f"{name:36s} {r['rate']:7.2f} {r['mean_solve_ms']:8.1f} ms {100 * r['overhead']:8.1f}% "
            f"{r['startup_s']:7.2f} s"
        )
    print(
        f"\nround trip of one design through the 2-worker pool with a no-op problem: "
        f"{per_design_ms:.3f} ms ({100 * per_design_ms / rows[0][1]['mean_solve_ms']:.2f} % of a "
        "serial constant-force solve)"
    )


if __name__ == "__main__":
    main()
