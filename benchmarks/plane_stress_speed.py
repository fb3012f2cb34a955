"""Speed of one plane-stress evaluation of a torsional SEA spring (docs/plane_stress.md, issue 13).

One evaluation of the ``sea_spring`` study: build the model on a meshed spring, a linear solve
(stiffness) and a geometrically nonlinear solve in one step to 11.04 degrees (torque at 53 N m for
275 N m/rad). Timed side by side in one process, interleaved round by round so that load changes
hit every case alike, as CPU time (``time.process_time``) and wall time, medians of ``--repeat``
rounds after one warm-up round (which loads the compiled kernels):

* ``cholmod compiled, series guess`` — the default path as a study runs it: the nonlinear solve
  starts from ``PlaneStressModel.series_predictor`` (docs/plane_stress.md, "Newton's starting
  point");
* ``cholmod compiled`` — compiled (numba) assembly, CHOLMOD sparse Cholesky
  with the analysis kept (cvxopt);
* ``qdldl compiled`` — the same with QDLDL's LDLᵀ (package qdldl, analysis kept): what a plain
  install runs, without the cholmod extra;
* ``superlu vectorised`` — the previous default: numpy assembly, SuperLU per tangent;
* ``superlu compiled``, ``cholmod vectorised`` — each change alone;
* ``pardiso compiled`` — when pypardiso and MKL import (optional);
* ``skfem superlu`` (``--old``) — scikit-fem's per-basis-pair assembly, the first path.

    python benchmarks/plane_stress_speed.py [--repeat 7] [--spring serpentine|spiral] [--old]

``--spring spiral`` times the spring of the default ``sea-spring`` study (spiral arms, its
``design:`` at the thickness it solved) instead of the Table 9 mid-range serpentine. The mesh is
made once (not timed): every case solves the same mesh. Each case's torque is printed with its
difference to the first case's, so a faster path that changed the answer would show.

BLAS threads are limited to one before numpy is imported (and MKL to its sequential layer): on a
shared 2-core machine OpenBLAS's threads spin against each other (a 30k-element dot product took
3 ms instead of 20 us), and the run's workers use one thread each too.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_THREADING_LAYER", "SEQUENTIAL")

import argparse  # noqa: E402
import datetime  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
from flexopt.fea.materials import get_material  # noqa: E402
from flexopt.fea.mesh import mesh_polygon  # noqa: E402
from flexopt.fea.plane_stress import Clamp, PlaneStressModel, PlaneStressSettings, Rotate  # noqa: E402
from flexopt.geometry.sea_spring import (  # noqa: E402
    TABLE9_BOUNDS,
    SpringFrame,
    build_spring,
    params_from_vector,
)

THETA = 53.0 / 275.0  # rad, 11.04 degrees
TARGET_CPU_S = 0.4  # issue 13: one SEA-spring evaluation (linear + nonlinear)


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def one(
    mesh, geom, settings: PlaneStressSettings, guess: bool = False
) -> tuple[float, float, float, dict]:
    """(cpu s, wall s, torque N m, counters) of model build + linear + nonlinear solve; with
    ``guess`` the nonlinear solve starts from ``series_predictor`` as analyse_spring's does."""
    c0, w0 = time.process_time(), time.perf_counter()
    model = PlaneStressModel(
        mesh,
        get_material("maraging-300"),
        geom.thickness_mm,
        Clamp(geom.pad_region),
        Rotate(geom.hub_region, (0.0, 0.0), THETA, 1),
        settings=settings,
    )
    model.solve("linear")
    if guess:
        u_odd, u_even = model.series_predictor(THETA)
        res = model.solve("nonlinear", guess=u_odd + u_even)
    else:
        res = model.solve("nonlinear")
    assert res.ok, res.message
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    info = dict(model.counters, solver=model.solver, assembly=model.assembly)
    return cpu, wall, float(res.torque_Nmm[-1]) * 1e-3, info


def spring(kind: str, fillet_segments: int):
    frame = SpringFrame(fillet_segments=fillet_segments)
    if kind == "spiral":
        from flexopt.geometry.arm_spring import build_arm_spring, spiral_params
        from flexopt.pipeline.study import load_study

        study = load_study("sea-spring")
        values = {**study.design, "ST": study.design.get("ST", 10.0)}
        p = spiral_params(values, int(study.geometry.n_sets or 2), frame,
                          study.geometry.root_fillet_mm)  # fmt: skip
        return build_arm_spring(p, frame), f"sea-spring study's spiral, {p.n_arms} arms"
    x = np.array([0.5 * (lo + hi) for lo, hi in TABLE9_BOUNDS.values()])
    return build_spring(params_from_vector(x, 4), frame), "Table 9 mid-range, 4 sets"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--fillet-segments", type=int, default=4)
    ap.add_argument("--spring", choices=("serpentine", "spiral"), default="serpentine")
    ap.add_argument("--old", action="store_true", help="also time scikit-fem's assembly (slow)")
    args = ap.parse_args()
    print(f"date      {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC")
    print(f"machine   {platform.machine()}, {os.cpu_count()} cores, {platform.system()}")
    print(f"load avg  {load()} (1, 5, 15 min) at start")
    geom, label = spring(args.spring, args.fillet_segments)
    t0 = time.perf_counter()
    mesh = mesh_polygon(geom.fe_outline, 3.0, refine=geom.mesh_regions(1.0, 3.0))
    t_mesh = time.perf_counter() - t0
    print(f"spring    {label}, {mesh.n_triangles} P2 triangles, mesh {t_mesh:.2f} s (not timed)")
    nl = dict(rtol_residual=1e-7)  # what the sea_spring study uses
    try:
        import cvxopt  # noqa: F401

        has_cholmod = True
    except ImportError:  # a plain install: no cholmod extra
        has_cholmod = False
        print("cvxopt not importable: CHOLMOD cases skipped (pip install '.[cholmod]')")
    # name -> (settings, start the nonlinear solve from series_predictor as analyse_spring does)
    cases: dict[str, tuple[PlaneStressSettings, bool]] = {}
    if has_cholmod:
        cases["cholmod  compiled, series guess"] = (
            PlaneStressSettings(solver="cholmod", assembly="compiled", **nl),
            True,
        )
        cases["cholmod  compiled"] = (
            PlaneStressSettings(solver="cholmod", assembly="compiled", **nl),
            False,
        )
    cases["qdldl    compiled, series guess"] = (
        PlaneStressSettings(solver="qdldl", assembly="compiled", **nl),
        True,
    )
    cases["qdldl    compiled"] = (
        PlaneStressSettings(solver="qdldl", assembly="compiled", **nl),
        False,
    )
    cases["superlu  vectorised (previous)"] = (
        PlaneStressSettings(solver="direct", assembly="vectorised", **nl),
        False,
    )
    cases["superlu  compiled"] = (
        PlaneStressSettings(solver="direct", assembly="compiled", **nl),
        False,
    )
    if has_cholmod:
        cases["cholmod  vectorised"] = (
            PlaneStressSettings(solver="cholmod", assembly="vectorised", **nl),
            False,
        )
    try:
        import pypardiso  # noqa: F401

        cases["pardiso  compiled"] = (
            PlaneStressSettings(solver="pardiso", assembly="compiled", **nl),
            False,
        )
    except ImportError:
        print("pypardiso not importable: PARDISO case skipped (pip install '.[fast]')")
    if args.old:
        cases["superlu  skfem (first path)"] = (
            PlaneStressSettings(solver="direct", assembly="skfem", **nl),
            False,
        )
    for settings, guess in cases.values():  # warm-up: numba loads its cache, CHOLMOD its library
        one(mesh, geom, settings, guess)
    cpu: dict[str, list[float]] = {name: [] for name in cases}
    wall: dict[str, list[float]] = {name: [] for name in cases}
    info = {}
    for _ in range(args.repeat):  # interleaved, so load changes hit every case alike
        for name, (settings, guess) in cases.items():
            c, w, torque, counters = one(mesh, geom, settings, guess)
            cpu[name].append(c)
            wall[name].append(w)
            info[name] = (torque, counters)
    n_dofs = PlaneStressModel(
        mesh, get_material("maraging-300"), geom.thickness_mm, Clamp(geom.pad_region),
        Rotate(geom.hub_region, (0.0, 0.0), THETA, 1),
    ).n_dofs  # fmt: skip
    first = next(iter(cases))
    base = "superlu  vectorised (previous)"
    ref_torque = info[first][0]
    print(
        f"\n{n_dofs} DOF, theta = {math.degrees(THETA):.2f} deg; one evaluation = model build + "
        f"linear + nonlinear solve;\nmedians of {args.repeat} interleaved rounds, CPU s (wall s); "
        f"'x prev' = previous path's time / this path's time (CPU, wall)"
    )
    print(f"  {'path':32s} {'CPU s':>6s} {'(wall)':>8s}  {'x prev':>11s}  torque N m (diff)")
    for name in cases:
        c, w = statistics.median(cpu[name]), statistics.median(wall[name])
        cb, wb = statistics.median(cpu[base]), statistics.median(wall[base])
        torque, counters = info[name]
        print(
            f"  {name:32s} {c:6.3f} ({w:6.3f})  {cb / c:4.1f} ({wb / w:4.1f})  {torque:.6f} "
            f"({torque - ref_torque:+.1e})  factorisations {counters['factorisations']}, "
            f"tangents {counters['tangents']}, cholesky failures {counters['cholesky_failures']}"
        )
    c = statistics.median(cpu[first])
    verdict = "met" if c <= TARGET_CPU_S else "NOT met"
    print(f"target: one evaluation <= {TARGET_CPU_S} s CPU -> {c:.3f} s: {verdict} at this load")
    print(f"load avg  {load()} (1, 5, 15 min) at end")


if __name__ == "__main__":
    main()
