"""Speed of the constrained-beam engine: compiled Newton against the scipy reference (issue 13).

Three evaluations of built-in studies, each timed on both paths of
:mod:`fea.constrained_beams` side by side in one process, interleaved round by round (so that
load changes hit both alike), as CPU time (``time.process_time``) and wall time, medians of
``--repeat`` rounds after one warm-up round:

* ``flexure-pivot`` — one GA evaluation of the study's design (a leaf pivot, 2 x 40 elements:
  the small-angle solve and 10 rows to the range of motion);
* ``leaf-spring-joint`` — ``flexopt evaluate``'s solves: both structures at three lengths, each
  traced and its elastic limit found (the follower-load path for structure b);
* ``bistable-switch`` — one GA evaluation of the mechanism study's design (fea.mechanism: its
  own Newton, compiled in fea/_mechanism_kernels.py; the reference column switches that off too).

``reference`` is the engine as it was before the compiled path: scipy sparse matrices, SuperLU,
the Newton loop in Python (the beams' own kernel stays compiled in both columns). The first-call
compile time is measured in fresh subprocesses with an empty numba cache (``NUMBA_CACHE_DIR`` in a
temporary folder): the beam kernel's warm-up, then the constrained kernels' on top of it, then a
second process loading both from that cache. Each case's answer is printed with its difference
between the paths.

    python benchmarks/constrained_speed.py [--repeat 7] [--no-compile-time]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import flexopt.fea.constrained_beams as cb  # noqa: E402
import flexopt.fea.mechanism as fm  # noqa: E402
import numpy as np  # noqa: E402
from flexopt.pipeline.studies import get_kind  # noqa: E402
from flexopt.pipeline.study import load_study  # noqa: E402

_KERNELS = cb._kernels
_MECH_KERNELS = fm._kernels


def _path(name: str) -> None:
    """Select the engine's path: "compiled" (default) or "reference" (as if numba were absent;
    the beams' kernel is untouched)."""
    cb._kernels = _KERNELS if name == "compiled" else (lambda: None)
    fm._kernels = _MECH_KERNELS if name == "compiled" else (lambda: None)


def _pivot():
    from flexopt.pipeline.studies.flexure_pivot import FlexurePivotProblem, design_vector

    study = load_study("flexure-pivot")
    prob = FlexurePivotProblem(study)
    x = design_vector(study, prob)

    def run() -> float:
        return float(prob.evaluate(x).metrics["stiffness_Nmm_per_rad"])

    return run, "stiffness N mm/rad"


def _leaf():
    study = load_study("leaf-spring-joint")
    kind = get_kind(study.geometry.kind)

    def run() -> float:
        res = kind.evaluate(study)
        cols = [v for k, v in res.table.items() if k.startswith("torque_Nm")]
        return float(np.nansum([np.nansum(np.asarray(c, float)) for c in cols]))

    return run, "sum of torques N m"


def _mechanism():
    study = load_study("bistable-switch")
    kind = get_kind(study.geometry.kind)
    prob = kind.problem(study)
    x = prob.nominal_design()

    def run() -> float:
        return float(prob.evaluate(x).f[0])

    return run, "objective"


CASES = {"flexure-pivot": _pivot, "leaf-spring-joint": _leaf, "bistable-switch": _mechanism}

_COMPILE = """
import time
t0 = time.process_time(); w0 = time.perf_counter()
from flexopt.fea.beam import warm_up as beam
beam()
t1 = time.process_time(); w1 = time.perf_counter()
from flexopt.fea.constrained_beams import warm_up
warm_up()
t2 = time.process_time(); w2 = time.perf_counter()
print(t1 - t0, w1 - w0, t2 - t1, w2 - w1)
"""


def compile_times() -> None:
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(ROOT))
        for label in ("first call, empty cache", "next process, from the cache"):
            out = subprocess.run(
                [sys.executable, "-c", _COMPILE], env=env, capture_output=True, text=True
            )
            if out.returncode != 0:
                print(f"  {label}: failed\n{out.stderr}")
                return
            bc, bw, cc, cw = (float(v) for v in out.stdout.split())
            print(
                f"  {label:30s} beam kernel {bc:6.2f} s CPU {bw:6.2f} s wall;"
                f" constrained kernels on top {cc:6.2f} s CPU {cw:6.2f} s wall"
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7, help="timed rounds (medians)")
    ap.add_argument("--no-compile-time", action="store_true", help="skip the first-call timing")
    args = ap.parse_args()
    print(
        f"constrained_speed  {datetime.datetime.now():%Y-%m-%d %H:%M}  {platform.node()}  "
        f"python {platform.python_version()}  load average {os.getloadavg()[0]:.2f} "
        f"{os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}  ({os.cpu_count()} cores)"
    )
    if not args.no_compile_time:
        print("first-call compile time (fresh processes, NUMBA_CACHE_DIR empty, then reused):")
        compile_times()
    cb.warm_up()
    runs = {name: make() for name, make in CASES.items()}
    paths = ("reference", "compiled")
    cpu = {(c, p): [] for c in runs for p in paths}
    wall = {(c, p): [] for c in runs for p in paths}
    answer = {}
    for rnd in range(args.repeat + 1):
        for case, (run, _) in runs.items():
            for p in paths:
                _path(p)
                t0, w0 = time.process_time(), time.perf_counter()
                answer[case, p] = run()
                if rnd:  # round 0 warms up (caches, first allocations)
                    cpu[case, p].append(time.process_time() - t0)
                    wall[case, p].append(time.perf_counter() - w0)
    _path("compiled")
    print(f"\nmedians of {args.repeat} interleaved rounds (after one warm-up round)")
    print(
        f"{'case':20s} {'reference CPU':>14s} {'compiled CPU':>13s} {'ratio':>6s}"
        f" {'ref. wall':>10s} {'comp. wall':>10s} {'ratio':>6s}  answer (relative difference)"
    )
    for case, (_, what) in runs.items():
        rc, cc = (statistics.median(cpu[case, p]) for p in paths)
        rw, cw = (statistics.median(wall[case, p]) for p in paths)
        a_ref, a_fast = answer[case, "reference"], answer[case, "compiled"]
        rel = abs(a_fast - a_ref) / max(abs(a_ref), 1e-300)
        print(
            f"{case:20s} {rc * 1e3:11.1f} ms {cc * 1e3:10.1f} ms {rc / cc:5.1f}x"
            f" {rw * 1e3:7.1f} ms {cw * 1e3:7.1f} ms {rw / cw:5.1f}x"
            f"  {what} {a_fast:.10g} ({rel:.1e})"
        )
    print(f"load average at the end {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
