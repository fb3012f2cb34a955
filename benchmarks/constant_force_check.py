"""The constant-force calibration check's CPU, in one process (docs/benchmarks.md, "The
constant-force check's cost (session 32, checkcost)").

    nice python benchmarks/constant_force_check.py time [0|1|all] [REPEATS]
    nice python benchmarks/constant_force_check.py prof [0|1|all]
    nice python benchmarks/constant_force_check.py dump OUT.pkl
    python benchmarks/constant_force_check.py diff A.pkl B.pkl

``check_constraints(x, part)`` of the shipped study's problem at its ``design:`` (part 0, part 1
or the whole check), under one BLAS thread, each call with an empty CheckMemo (so it computes),
after one warm-up call (numba, imports). ``time``: CPU (``time.process_time``) medians, s;
``prof``: cProfile by cumulative and own time; ``dump``: the whole check's and both parts'
records (and the memo's kept record) pickled; ``diff``: the largest relative change of every
figure between two dumps (``time_s`` aside), e.g. main's install against this one's. Run it
with each install's python to compare them (alternating: the machine is shared).
"""

from __future__ import annotations

import cProfile
import os
import pickle
import pstats
import sys
import time

import numpy as np


def _problem():
    from flexopt.pipeline.problems import kind_problem, nominal_design
    from flexopt.pipeline.study import load_study

    study = load_study("constant-force")
    problem = kind_problem(study)
    return problem, nominal_design(problem, study)


def _run(problem, x, part):
    from flexopt.pipeline.studies._constant_force_reuse import CheckMemo

    problem.checks = CheckMemo()
    return problem.check_constraints(x, part=part)


def _walk(a, b, path, worst) -> None:
    """Largest relative change per key path (list indices folded) between records a and b."""
    if isinstance(a, dict):
        for k in a:
            if k != "time_s" and k in b:
                _walk(a[k], b[k], path + (k,), worst)
        return
    if hasattr(a, "__dataclass_fields__"):
        for k in a.__dataclass_fields__:
            if k not in ("time_s", "kept"):
                _walk(getattr(a, k), getattr(b, k), path + (k,), worst)
        return
    if isinstance(a, list | tuple) and a and isinstance(a[0], dict | list | tuple):
        for u, v in zip(a, b, strict=True):
            _walk(u, v, path, worst)
        return
    try:
        u, v = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    except (TypeError, ValueError):
        worst[path] = max(worst.get(path, 0.0), 0.0 if a == b else np.inf)
        return
    if u.shape != v.shape:
        worst[path] = np.inf
        return
    with np.errstate(all="ignore"):
        rel = np.where(u == v, 0.0, np.abs(u - v) / np.abs(u))
    worst[path] = max(worst.get(path, 0.0), float(np.max(rel)) if rel.size else 0.0)


def main(argv: list[str]) -> None:
    mode = argv[0]
    if mode == "diff":
        a, b = (pickle.load(open(p, "rb")) for p in argv[1:3])
        worst: dict = {}
        _walk(a, b, (), worst)
        for key, value in sorted(worst.items(), key=lambda kv: -kv[1]):
            print(f"{value:.3e}  {'/'.join(map(str, key))}")
        print(f"{len(worst)} figures compared; {sum(v > 0 for v in worst.values())} differ")
        return
    from threadpoolctl import threadpool_limits

    problem, x = _problem()
    part = None if len(argv) < 2 or argv[1] in ("all", "") or mode == "dump" else int(argv[1])
    print(f"python {sys.executable}; load {os.getloadavg()}")
    with threadpool_limits(1):
        _run(problem, x, part)  # warm-up: numba's cache, imports
        if mode == "time":
            times = []
            for _ in range(int(argv[2]) if len(argv) > 2 else 5):
                c0 = time.process_time()
                _run(problem, x, part)
                times.append(time.process_time() - c0)
            print(f"part {part}: CPU s median {np.median(times):.3f}, min {min(times):.3f}",
                  [round(t, 3) for t in times])  # fmt: skip
        elif mode == "prof":
            prof = cProfile.Profile()
            prof.enable()
            _run(problem, x, part)
            prof.disable()
            stats = pstats.Stats(prof)
            stats.sort_stats("cumulative").print_stats(40)
            stats.sort_stats("tottime").print_stats(25)
        elif mode == "dump":
            out = {p: _run(problem, x, p) for p in (0, 1)}
            out = {p: c.record for p, c in out.items()}
            out[None] = _run(problem, x, None)
            out["kept_record"] = next(iter(problem.checks.records.values()), None)
            with open(argv[1], "wb") as f:
                pickle.dump(out, f)
            print(f"wrote {argv[1]}")
        else:
            raise SystemExit(f"unknown mode {mode!r}: time, prof, dump or diff")


if __name__ == "__main__":
    main(sys.argv[1:])
