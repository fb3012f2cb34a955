"""Speed of one plane-stress evaluation of a torsional SEA spring (docs/plane_stress.md).

One evaluation of the ``sea_spring`` study: mesh the spring, build the model, a linear solve
(stiffness) and a geometrically nonlinear solve in one step to 11.04 degrees (torque at 53 N m for
275 N m/rad). Timed for the current path (vectorised assembly, SuperLU per Newton iteration, and the
CG variant) and, in the same process, the old path (scikit-fem's per-basis-pair assembly), so the
two see the same machine load. Prints the median of ``--repeat`` runs of each.

    python benchmarks/plane_stress_speed.py [--repeat 3] [--fillet-segments 2] [--spring spiral]

``--spring spiral`` times the spring of the default ``sea-spring`` study (spiral arms, its
``design:`` at the thickness it solved) instead of the Table 9 mid-range serpentine.

BLAS threads are limited to one before numpy is imported (and MKL to its sequential layer): on a
shared 2-core machine OpenBLAS's threads spin against each other (a 30k-element dot product took
3 ms instead of 20 us).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_THREADING_LAYER", "SEQUENTIAL")

import argparse  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from fea.materials import get_material  # noqa: E402
from fea.mesh import mesh_polygon  # noqa: E402
from fea.plane_stress import Clamp, PlaneStressModel, PlaneStressSettings, Rotate  # noqa: E402
from geometry.sea_spring import (  # noqa: E402
    TABLE9_BOUNDS,
    SpringFrame,
    build_spring,
    params_from_vector,
)

THETA = 53.0 / 275.0  # rad, 11.04 degrees


def one(mesh, geom, settings: PlaneStressSettings, kinematics: str) -> tuple[float, float, dict]:
    t0 = time.perf_counter()
    model = PlaneStressModel(
        mesh,
        get_material("maraging-300"),
        geom.thickness_mm,
        Clamp(geom.pad_region),
        Rotate(geom.hub_region, (0.0, 0.0), THETA, 1),
        settings=settings,
    )
    res = model.solve("linear")
    if kinematics == "nonlinear":
        res = model.solve("nonlinear")
        assert res.ok, res.message
    return time.perf_counter() - t0, float(res.torque_Nmm[-1]) * 1e-3, dict(model.counters)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--fillet-segments", type=int, default=4)
    ap.add_argument("--spring", choices=("serpentine", "spiral"), default="serpentine")
    args = ap.parse_args()
    frame = SpringFrame(fillet_segments=args.fillet_segments)
    if args.spring == "spiral":
        from geometry.arm_spring import build_arm_spring, spiral_params
        from pipeline.study import load_study

        study = load_study("sea-spring")
        values = {**study.design, "ST": study.design.get("ST", 10.0)}
        p = spiral_params(values, int(study.geometry.n_sets or 2), frame,
                          study.geometry.root_fillet_mm)  # fmt: skip
        geom = build_arm_spring(p, frame)
        label = f"sea-spring study's spiral, {p.n_arms} arms"
    else:
        x = np.array([0.5 * (lo + hi) for lo, hi in TABLE9_BOUNDS.values()])
        geom = build_spring(params_from_vector(x, 4), frame)
        label = "Table 9 mid-range, 4 sets"
    t0 = time.perf_counter()
    mesh = mesh_polygon(geom.fe_outline, 3.0, refine=geom.mesh_regions(1.0, 3.0))
    t_mesh = time.perf_counter() - t0
    print(f"spring: {label}, {mesh.n_triangles} P2 triangles, mesh {t_mesh:.2f} s")
    nl = dict(rtol_residual=1e-7)  # what the sea_spring study uses
    cases = [
        ("linear     vectorised SuperLU", PlaneStressSettings(solver="direct"), "linear"),
        ("linear     skfem SuperLU (old)", PlaneStressSettings(assembly="skfem", solver="direct"),
         "linear"),
        ("lin+nonlin vectorised SuperLU", PlaneStressSettings(solver="direct", **nl), "nonlinear"),
        ("lin+nonlin vectorised CG", PlaneStressSettings(solver="krylov", krylov_rtol=1e-4,
                                                         krylov_max_iter=15, **nl), "nonlinear"),
        ("lin+nonlin skfem SuperLU (old)",
         PlaneStressSettings(assembly="skfem", solver="direct", **nl), "nonlinear"),
    ]  # fmt: skip
    try:
        import pypardiso  # noqa: F401

        cases[1:1] = [("linear     vectorised PARDISO", PlaneStressSettings(solver="pardiso"),
                       "linear")]  # fmt: skip
        cases.insert(4, ("lin+nonlin vectorised PARDISO",
                         PlaneStressSettings(solver="pardiso", **nl), "nonlinear"))  # fmt: skip
    except ImportError:
        print("pypardiso not importable: PARDISO cases skipped (pip install pypardiso mkl)")
    times: dict[str, list[float]] = {name: [] for name, _, _ in cases}
    info = {}
    for _ in range(args.repeat):  # interleaved, so load changes hit every case alike
        for name, settings, kin in cases:
            t, torque, counters = one(mesh, geom, settings, kin)
            times[name].append(t)
            info[name] = (torque, counters)
    n_dofs = PlaneStressModel(
        mesh, get_material("maraging-300"), geom.thickness_mm, Clamp(geom.pad_region),
        Rotate(geom.hub_region, (0.0, 0.0), THETA, 1),
    ).n_dofs  # fmt: skip
    print(f"{n_dofs} DOF; median of {args.repeat} (min, max), model build included, mesh not")
    for name, ts in times.items():
        torque, counters = info[name]
        print(
            f"  {name:32s} {statistics.median(ts):6.2f} s ({min(ts):.2f}, {max(ts):.2f})  "
            f"torque {torque:.4f} N m  {counters}"
        )
    print(f"theta = {math.degrees(THETA):.2f} deg")


if __name__ == "__main__":
    main()
