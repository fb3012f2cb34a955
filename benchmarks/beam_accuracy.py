"""Accuracy of flexopt's beam against the exact elastica and under mesh refinement.

Run from the repository root::

    python benchmarks/beam_accuracy.py

Prints three tables (quoted in docs/beam.md):

1. cantilever with a dead tip force, alpha = P L^2 / EI in {0.25 .. 10}, 20 elements:
   tip deflection against the exact elastica (fea.elastica);
2. fixed-guided beam pushed to d / L = 0.2 .. 0.8 under displacement control, 20 elements:
   end force against the exact elastica;
3. mesh refinement (cantilever, alpha = 3): error of the tip deflection against a 512-element
   solution of the same model and the observed order.

The section is t / L = 1 / 1000 so that axial and shear compliance, which the elastica ignores,
move the answers by < 1e-5 (cantilever) and ~4e-5 (fixed-guided at d/L = 0.8).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from flexopt.fea.beam import BeamSettings, EndDrive, solve_beam  # noqa: E402
from flexopt.fea.elastica import cantilever_tip_load, fixed_guided  # noqa: E402
from flexopt.fea.materials import Material  # noqa: E402
from flexopt.geometry.profile import BeamProfile  # noqa: E402

L, T, B = 100.0, 0.1, 5.0
MAT = Material("ABS", 1800.0, 0.35, 42.5)
EI = MAT.E_MPa * B * T**3 / 12.0
BEAM = BeamProfile([[0.0, 0.0], [L, 0.0]], [T, T], B)


def cantilever(alpha: float, n: int, steps: int = 20):
    drive = EndDrive("force", (0.0, 1.0), alpha * EI / L**2, steps, "free", "free")
    t0 = time.perf_counter()
    r = solve_beam(BEAM, MAT, drive, settings=BeamSettings(n))
    return r, time.perf_counter() - t0


def main() -> None:
    print("1. cantilever, dead tip force, 20 elements, 20 load steps")
    print(
        f"{'alpha':>6} {'tip angle deg':>14} {'delta/L exact':>14} {'delta/L flexopt':>16}"
        f" {'rel. error':>11} {'Newton it.':>10} {'ms':>7}"
    )
    for alpha in (0.25, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0):
        ex = cantilever_tip_load(alpha)
        r, dt = cantilever(alpha, 20)
        d = r.displacement_mm[-1] / L
        print(
            f"{alpha:6.2f} {np.degrees(ex.tip_angle_rad):14.2f} {ex.deflection_over_L:14.8f}"
            f" {d:16.8f} {(d - ex.deflection_over_L) / ex.deflection_over_L:11.2e}"
            f" {r.iterations.sum():10d} {dt * 1e3:7.1f}"
        )

    print("\n2. fixed-guided, displacement control, 20 elements, 20 steps")
    print(f"{'d/L':>5} {'PL^2/EI exact':>14} {'flexopt':>12} {'rel. error':>11}")
    for dl in (0.2, 0.4, 0.6, 0.8):
        ex = fixed_guided(dl)
        drive = EndDrive("displacement", (0.0, 1.0), dl * L, 20, "fixed", "free")
        r = solve_beam(BEAM, MAT, drive, settings=BeamSettings(20))
        p = r.force_N[-1] * L**2 / EI
        print(f"{dl:5.2f} {ex.load:14.8f} {p:12.8f} {(p - ex.load) / ex.load:11.2e}")

    print("\n3. mesh refinement, cantilever alpha = 3 (reference: 512 elements, same model)")
    ref = cantilever(3.0, 512, steps=10)[0].displacement_mm[-1]
    prev = None
    print(f"{'elements':>8} {'|error| mm':>12} {'order':>6}")
    for n in (2, 4, 8, 16, 32):
        err = abs(cantilever(3.0, n, steps=10)[0].displacement_mm[-1] - ref)
        order = "" if prev is None else f"{np.log2(prev / err):6.2f}"
        print(f"{n:8d} {err:12.3e} {order:>6}")
        prev = err


if __name__ == "__main__":
    main()
