"""CPU and wall time of one SEA design solved in this process with the BLAS/OpenMP pools at one
thread against their default (issue 27 item 4).

What ``flexopt evaluate sea-spring-quick`` and a serial run (``--workers 1``) solve: the study's
design by its kind's problem (``problem.result``, as ``flexopt evaluate`` solves it) and
``--designs - 1`` random designs around it (seed 0, 8 % of each range, ``problem.evaluate``, as
the serial backend solves a generation). Both settings run interleaved in one process, round by
round with the order alternating (so a change of the machine's load falls on both alike); the
median per design of each is printed with the load average before and after. The pools are
sized here by threadpoolctl, not by environment variables, so "default" is what a user's
process gets (two threads on a 2-core machine)::

    python benchmarks/serial_threads.py
    python benchmarks/serial_threads.py --study sea-spring-quick --rounds 7 --designs 4
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from threadpoolctl import threadpool_info, threadpool_limits


def solves(study_name: str, n: int) -> list[Callable[[], Any]]:
    """One callable per design: the study's design as ``flexopt evaluate`` solves it, then
    ``n - 1`` random designs around it as a serial run's backend solves them."""
    from flexopt.pipeline.problems import kind_problem, nominal_design
    from flexopt.pipeline.study import load_study

    study = load_study(study_name)
    prob = kind_problem(study)
    x0 = nominal_design(prob, study)
    rng = np.random.default_rng(0)
    lo, hi = prob.space.lower, prob.space.upper
    xs = [np.clip(x0 + rng.normal(0, 0.08, x0.size) * (hi - lo), lo, hi) for _ in range(n - 1)]
    return [lambda: prob.result(x0)] + [lambda x=x: prob.evaluate(x) for x in xs]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--study", default="sea-spring-quick")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--designs", type=int, default=4)
    args = parser.parse_args()
    default = max((p["num_threads"] for p in threadpool_info()), default=1)
    jobs = solves(args.study, args.designs)
    with threadpool_limits(1):
        for job in jobs:  # kernels loaded, caches warm
            job()
    times: dict[str, dict[str, list[float]]] = {
        name: {"cpu": [], "wall": []} for name in ("one", "default")
    }
    load0 = os.getloadavg()
    for rnd in range(args.rounds):
        order = ("one", "default") if rnd % 2 == 0 else ("default", "one")
        for name in order:
            limit = threadpool_limits(1) if name == "one" else contextlib.nullcontext()
            with limit:
                for job in jobs:
                    c0, w0 = time.process_time(), time.perf_counter()
                    job()
                    times[name]["cpu"].append(time.process_time() - c0)
                    times[name]["wall"].append(time.perf_counter() - w0)
    load1 = os.getloadavg()
    print(f"study {args.study}: {args.designs} designs x {args.rounds} rounds per setting")
    cores = os.cpu_count()
    print(f"load average before {load0[0]:.2f} after {load1[0]:.2f} (1 min), cores {cores}")
    for name, label in (("one", "1 thread"), ("default", f"default ({default} threads)")):
        cpu, wall = statistics.median(times[name]["cpu"]), statistics.median(times[name]["wall"])
        print(f"{label:22s} CPU {cpu:.3f} s   wall {wall:.3f} s   per design (median)")
    ratio = statistics.median(times["default"]["cpu"]) / statistics.median(times["one"]["cpu"])
    print(f"CPU default / one thread: {ratio:.2f}")


if __name__ == "__main__":
    main()
