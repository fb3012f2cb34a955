"""The start of ``flexopt run`` in the main process, and a forked worker's first designs
(issue 27 item 4).

    nice python benchmarks/run_start.py [--study constant-force] [--rounds 3]
        [--ab OTHER_PYTHON]

Each round runs two fresh processes of this interpreter (and, with ``--ab``, of another
install's, alternating: A = the other, B = this one):

``start``
    CPU time (``time.process_time``, s) of what a run does in its main process before its
    workers fork, phase by phase: ``import flexopt.pipeline.cli``, ``import
    flexopt.pipeline.run`` (pymoo and the run's modules), ``load_study``, ``prepare_run`` and
    the kernels' warm-up (``DesignProblem.warm_up``: numba's import and cache load, done once
    before the pool forks so that the workers inherit them).
``worker``
    After the same start, a child forked as the pool forks its workers solves the study's
    nominal design three times: the CPU time (s) of each. The first is what a worker pays for
    starting (it inherits every module and kernel by fork; no import, no cache load).

Prints one line per process and the medians; the load average before and after.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

CHILD = r"""
import os, sys, time
t0 = time.process_time()
import flexopt.pipeline.cli
t1 = time.process_time()
import flexopt.pipeline.run
t2 = time.process_time()
from flexopt.pipeline.study import load_study, resolve_study_path
study = load_study(resolve_study_path(sys.argv[1]))
t3 = time.process_time()
from flexopt.pipeline.run import prepare_run
setup = prepare_run(study)
t4 = time.process_time()
from flexopt.optimise.problem import as_design_problem
problem = as_design_problem(setup.problem)
problem.warm_up()
t5 = time.process_time()
print("start", t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4, t5, flush=True)
from flexopt.pipeline.problems import nominal_design
x = nominal_design(setup.problem, study)
pid = os.fork()
if pid == 0:
    cpu = []
    for _ in range(3):
        c = time.process_time()
        setup.problem.evaluate(x.copy())
        cpu.append(time.process_time() - c)
    print("worker", *cpu, flush=True)
    os._exit(0)
os.waitpid(pid, 0)
"""

START = ("import cli", "import run", "load_study", "prepare_run", "warm_up", "total")
WORKER = ("1st design", "2nd design", "3rd design")


def _load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def _one(python: str, study: str) -> dict[str, list[float]]:
    done = subprocess.run([python, "-c", CHILD, study], capture_output=True, text=True, check=True)
    out = {}
    for line in done.stdout.splitlines():
        name, *values = line.split()
        out[name] = [float(v) for v in values]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--study", default="constant-force")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--ab", metavar="OTHER_PYTHON", help="alternate with this interpreter (A)")
    args = parser.parse_args()
    installs = {"B": sys.executable}
    if args.ab:
        installs = {"A": args.ab, "B": sys.executable}
    print(f"date      {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"load avg  {_load()} at start; study {args.study}; CPU s")
    results: dict[str, list[dict[str, list[float]]]] = {k: [] for k in installs}
    for i in range(args.rounds):
        order = list(installs.items())
        if i % 2:
            order.reverse()
        for name, python in order:
            results[name].append(_one(python, args.study))
            got = results[name][-1]
            start = " ".join(f"{k} {v:.3f}" for k, v in zip(START, got["start"], strict=True))
            worker = " ".join(f"{v:.4f}" for v in got["worker"])
            print(f"  round {i + 1} {name}: {start} | worker designs {worker}")
    for name, runs in results.items():
        start = [statistics.median(r["start"][j] for r in runs) for j in range(len(START))]
        worker = [statistics.median(r["worker"][j] for r in runs) for j in range(len(WORKER))]
        print(f"  {name} ({installs[name]}), medians of {len(runs)}:")
        print("    " + ", ".join(f"{k} {v:.3f}" for k, v in zip(START, start, strict=True)))
        pairs = zip(WORKER, worker, strict=True)
        print("    forked worker: " + ", ".join(f"{k} {v:.4f}" for k, v in pairs))
    print(f"load avg  {_load()} at the end")


if __name__ == "__main__":
    main()
