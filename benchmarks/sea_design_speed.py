"""CPU time of one GA design of the SEA-spring study (issue 13), and its answers for comparison.

``SeaSpringProblem.evaluate`` (build, mesh, model, linear + two nonlinear solves, slot gaps, ST)
on the study's ``design:`` and ``--designs - 1`` random designs around it inside the bounds
(seed 0, 8 % of each range), stage 1 left out (two arms, as it chooses). Each design is
evaluated ``--repeat`` times and its least CPU time kept; the median over the buildable designs
is printed. One BLAS thread, as in the pool's workers. ``--out`` writes every design's
objectives, constraints and metrics as JSON, and ``--compare`` reports the largest relative
difference against such a file, e.g. of the code before a change (run it from a checkout of
that code, or side by side with ``PYTHONPATH`` pointing at one)::

    python benchmarks/sea_design_speed.py --out after.json
    python benchmarks/sea_design_speed.py --designs 12 --repeat 3 --compare before.json
    FLEXOPT_PLANE_STRESS_SOLVER=direct python benchmarks/sea_design_speed.py   # SuperLU
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402


def records(study_name: str, n: int, repeat: int) -> tuple[list[dict], list[float]]:
    from flexopt.pipeline.studies.sea_spring import SeaSpringProblem
    from flexopt.pipeline.study import load_study

    study = load_study(study_name)
    study = study.model_copy(
        update={
            "geometry": study.geometry.model_copy(update={"n_sets": 2}),
            "taguchi": study.taguchi.model_copy(update={"enabled": False}),
        }
    )
    prob = SeaSpringProblem(study)
    x0 = prob.nominal_design()
    rng = np.random.default_rng(0)
    lo, hi = prob.space.lower, prob.space.upper
    xs = [x0] + [
        np.clip(x0 + rng.normal(0, 0.08, x0.size) * (hi - lo), lo, hi) for _ in range(n - 1)
    ]
    prob.evaluate(x0)  # kernels loaded, caches warm
    out, times = [], []
    for x in xs:
        cpu = []
        for _ in range(repeat):
            c0 = time.process_time()
            ev = prob.evaluate(x)
            cpu.append(time.process_time() - c0)
        metrics = {k: v for k, v in ev.metrics.items() if k != "fe_time_s"}
        out.append(
            {"f": ev.f.tolist(), "g": ev.g.tolist(), "reason": ev.reason, "metrics": metrics}
        )
        if not ev.reason and metrics.get("buildable", True):
            times.append(min(cpu))
    return out, times


def largest_difference(a: list[dict], b: list[dict]) -> float:
    worst = 0.0
    for x, y in zip(a, b, strict=True):
        if x["reason"] != y["reason"]:
            return math.inf
        pairs = [*zip(x["f"], y["f"], strict=True), *zip(x["g"], y["g"], strict=True)]
        pairs += [(v, y["metrics"][k]) for k, v in x["metrics"].items() if isinstance(v, float)]
        for u, v in pairs:
            if u != v and not (math.isnan(u) and math.isnan(v)):
                worst = max(worst, abs(u - v) / max(abs(u), abs(v)))
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", default="sea-spring")
    ap.add_argument("--designs", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--out")
    ap.add_argument("--compare")
    args = ap.parse_args()
    load = " ".join(f"{v:.2f}" for v in os.getloadavg())
    recs, times = records(args.study, args.designs, args.repeat)
    print(
        f"{args.study}: median {statistics.median(times):.3f} s CPU per design over {len(times)} "
        f"buildable of {len(recs)} (least of {args.repeat} each); load {load} at start"
    )
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(recs, fh)
    if args.compare:
        with open(args.compare) as fh:
            worst = largest_difference(json.load(fh), recs)
        print(f"largest relative difference against {args.compare}: {worst:.3g}")
        sys.exit(0 if worst <= 1e-9 else 1)


if __name__ == "__main__":
    main()
