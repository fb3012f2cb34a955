"""Wall time of the sea-spring study's stage 1 (``run_taguchi``): serial against two processes.

Run from the repository root::

    python benchmarks/taguchi_stage1_speed.py [--study sea-spring] [--rounds 5]

Each measurement is a fresh process that loads the study and runs stage 1 once under
``threadpool_limits(1)``, as ``SeaSpringProblem`` does at the start of ``flexopt run`` (so the
first-run costs, ~0.4 s of loading the compiled kernels, are in it; ``--warm``: a second stage 1
in the process is timed instead, without them). Rounds interleave the serial
path (``TAGUCHI_FORK = False``) and the forked one; the medians of wall time and of CPU time
(the process and its children) are printed with the load average at start and end. The machine
is shared: compare the two columns of one invocation, not runs made at different loads.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

CHILD = """
import json, resource, sys, time
from threadpoolctl import threadpool_limits
import flexopt.pipeline.studies.sea_spring as ss
from flexopt.pipeline.study import load_study

ss.TAGUCHI_FORK = sys.argv[2] == "fork"
study = load_study(sys.argv[1])
if sys.argv[3] == "warm":
    with threadpool_limits(1):
        ss.run_taguchi(study)  # kernels loaded, caches filled: the second stage 1 of a process
k0 = resource.getrusage(resource.RUSAGE_CHILDREN)
t0, c0 = time.perf_counter(), time.process_time()
with threadpool_limits(1):
    stage1 = ss.run_taguchi(study)
wall = time.perf_counter() - t0
k1 = resource.getrusage(resource.RUSAGE_CHILDREN)
kids = k1.ru_utime + k1.ru_stime - k0.ru_utime - k0.ru_stime
print(json.dumps({"wall_s": wall, "cpu_s": time.process_time() - c0, "child_cpu_s": kids,
                  "time_s": stage1["time_s"]}))
"""


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", default="sea-spring", help="built-in study or YAML file")
    parser.add_argument("--rounds", type=int, default=5, help="measurements of each path")
    parser.add_argument("--warm", action="store_true", help="time a second stage 1 in each process")
    args = parser.parse_args()
    print(f"stage 1 of {args.study}; load avg {load()} (1, 5, 15 min) at start")
    out: dict[str, list[dict[str, float]]] = {"serial": [], "fork": []}
    for r in range(args.rounds):
        for mode in out:
            proc = subprocess.run(
                [sys.executable, "-c", CHILD, args.study, mode, "warm" if args.warm else "cold"],
                capture_output=True, text=True, check=True,
            )  # fmt: skip
            m = json.loads(proc.stdout.strip().splitlines()[-1])
            out[mode].append(m)
            print(f"  round {r + 1} {mode:6s} wall {m['wall_s']:.2f} s, CPU {m['cpu_s']:.2f} s "
                  f"+ child {m['child_cpu_s']:.2f} s; load {os.getloadavg()[0]:.2f}")  # fmt: skip
    for mode, ms in out.items():
        walls = [m["wall_s"] for m in ms]
        cpu = statistics.median(m["cpu_s"] + m["child_cpu_s"] for m in ms)
        print(f"{mode:6s} median wall {statistics.median(walls):.2f} s (min {min(walls):.2f}, "
              f"max {max(walls):.2f}), CPU {cpu:.2f} s over {len(ms)}")  # fmt: skip
    print(f"load avg {load()} at end")


if __name__ == "__main__":
    main()
