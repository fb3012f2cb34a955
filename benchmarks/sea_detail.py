"""The SEA spring's report detail (``SeaSpringProblem.detail`` of the best design: the
plane-stress re-solve, the 3D checks, their peak convergence, taguchi.png) in fresh processes,
as ``flexopt run`` makes it after its optimiser (issue 27 items 3-5).

    nice python benchmarks/sea_detail.py [--study sea-spring] [--repeat 3]
        [--ab OTHER_PYTHON] [--no-cvxopt]

Each round a fresh process loads the study, runs stage 1 (Taguchi: the detail draws its plot),
warms the kernels with one evaluation of the study's ``design:`` and then times ``detail`` of
that design: wall (``time.perf_counter``), the CPU of its process (``time.process_time``) and
of the children it waited for (the side processes: peak convergence, the extra 2D solves,
taguchi.png), the peak RSS of each, and the figures the verdict reads (3D stiffness each way,
ST after, 3D peak; printed with every digit, to compare installs). ``--ab OTHER_PYTHON``: the
same with another install's interpreter (A, e.g. main's venv) and this one's (B), alternating,
the order swapped every round; medians and the load average printed. ``--no-cvxopt``: cvxopt
made unimportable first (a plain install's path: the 3D check by multigrid, QDLDL's 2D solves).
``--peak``: the peak convergence alone (``_sea_spring_peak.peak_of`` of the design at its
solved ST, the worse direction: what the detail's second process runs), its CPU and wall, the
peaks of every round with every digit and, where the install reports them, the Newton
iterations and guesses per round.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time

FIGURES = (
    "stiffness_ccw_3d_Nm_per_rad", "stiffness_cw_3d_Nm_per_rad", "ST_after_mm",
    "peak_stress_3d_MPa", "peak_stress_2d_MPa", "stiffness_ratio_3d_2d",
)  # fmt: skip


def child(study_name: str) -> None:
    """One detail in this process; prints one JSON line."""
    import numpy as np
    from flexopt.pipeline.studies.sea_spring import SeaSpringProblem
    from flexopt.pipeline.study import load_study, resolve_study_path

    study = load_study(resolve_study_path(study_name))
    prob = SeaSpringProblem(study)
    prob.stage1  # noqa: B018  (stage 1 runs on first use, as in a run before its optimiser)
    import matplotlib.backends.backend_agg  # noqa: F401  (the run's preload thread imports it)

    x = prob.nominal_design()
    prob.warm_up()
    prob.evaluate(x)
    c0, t0 = time.process_time(), time.perf_counter()
    d = prob.detail(np.asarray(x, dtype=float))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    s3 = d.info.get("solid_3d", {})
    out = {
        "wall_s": wall,
        "cpu_s": cpu,
        "children_cpu_s": kids.ru_utime + kids.ru_stime,
        "rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
        "children_rss_gb": kids.ru_maxrss / 2**20,
        "figures": {k: s3.get(k) for k in FIGURES},
        "checks": [(c["solver"], c["iterations"]) for c in s3.get("checks", [])],
        "peak_wait_s": s3.get("peak_convergence", {}).get("wait_s"),
        "taguchi_png": len(d.files.get("taguchi.png", b"")),
    }
    print(json.dumps(out))


def peak_child(study_name: str) -> None:
    """The peak convergence of the study's design in this process; prints one JSON line."""
    import numpy as np
    from flexopt.fea.sea_design import worse_direction
    from flexopt.pipeline.studies import _sea_spring_peak as peak
    from flexopt.pipeline.studies.sea_spring import SeaSpringProblem
    from flexopt.pipeline.study import load_study, resolve_study_path

    study = load_study(resolve_study_path(study_name))
    prob = SeaSpringProblem(study)
    x = np.asarray(prob.nominal_design(), dtype=float)
    prob.warm_up()
    _, solved = prob._evaluate(x, study.mesh.curve_steps, keep_model=True)
    _, geom, r, _ = solved
    c0, t0 = time.process_time(), time.perf_counter()
    c = peak.peak_of(prob, geom.params, worse_direction(r))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    out = {
        "wall_s": wall,
        "cpu_s": cpu,
        "children_cpu_s": 0.0,
        "rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
        "children_rss_gb": 0.0,
        "figures": {
            "peaks_MPa": c["peaks_MPa"],
            "triangles": c["triangles"],
            "newton_iterations": c.get("newton_iterations"),
            "cholesky_failures": c.get("cholesky_failures"),
            "guess": c.get("guess"),
        },
        "checks": [],
        "peak_wait_s": None,
    }
    print(json.dumps(out))


def _round(python: str, study: str, no_cvxopt: bool, peak: bool = False) -> dict:
    cmd = [python, os.path.abspath(__file__), "--peak-child" if peak else "--child", study]
    cmd += ["--no-cvxopt"] if no_cvxopt else []
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed: {done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> None:
    if "--no-cvxopt" in sys.argv:  # before anything imports it: what a plain install runs
        sys.modules["cvxopt"] = None  # type: ignore[assignment]
        sys.modules["cvxopt.cholmod"] = None  # type: ignore[assignment]
    if len(sys.argv) > 2 and sys.argv[1] == "--child":
        child(sys.argv[2])
        return
    if len(sys.argv) > 2 and sys.argv[1] == "--peak-child":
        peak_child(sys.argv[2])
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--study", default="sea-spring")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--ab", metavar="OTHER_PYTHON")
    ap.add_argument("--no-cvxopt", action="store_true")
    ap.add_argument("--peak", action="store_true", help="the peak convergence alone")
    args = ap.parse_args()
    if args.repeat < 1:
        ap.exit(2, "sea_detail.py: error: --repeat must be at least 1\n")
    print(f"date {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; cores {os.cpu_count()}")
    what = "the peak convergence" if args.peak else "the detail"
    print(f"study {args.study}; {what}; no cvxopt: {args.no_cvxopt}; load {_load()}")
    pythons = {"B": sys.executable}
    if args.ab:
        pythons = {"A": args.ab, "B": sys.executable}
    runs: dict[str, list[dict]] = {k: [] for k in pythons}
    for i in range(args.repeat):
        order = list(pythons) if i % 2 == 0 else list(pythons)[::-1]
        for name in order:
            r = _round(pythons[name], args.study, args.no_cvxopt, args.peak)
            runs[name].append(r)
            print(
                f"  round {i + 1} {name}: {r['wall_s']:.2f} s wall, {r['cpu_s']:.2f} s CPU "
                f"+ children {r['children_cpu_s']:.2f} s, RSS {r['rss_gb']:.2f} / "
                f"{r['children_rss_gb']:.2f} GB, peak wait {r['peak_wait_s']}, "
                f"checks {r['checks']}; load {_load()}"
            )
    for name, rs in runs.items():
        keys = ("wall_s", "cpu_s", "children_cpu_s", "rss_gb", "children_rss_gb")
        med = {k: statistics.median(r[k] for r in rs) for k in keys}
        text = ", ".join(f"{k} {v:.2f}" for k, v in med.items())
        print(f"{name} ({pythons[name]}): medians of {len(rs)}: {text}")
        for r in rs:
            print(f"    figures {json.dumps(r['figures'])}")
    print(f"load after {_load()}")


if __name__ == "__main__":
    main()
