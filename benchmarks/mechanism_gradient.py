"""Figures of the mechanism engine's exact sensitivities (issue 27 items 1-2,
docs/sensitivities.md "The mechanism engine"): the step study of the finite-difference
reference, the kind's Jacobian against central differences of ``evaluate``, the KS aggregate
against the max, and the cost against an evaluation.

    OMP_NUM_THREADS=1 nice python benchmarks/mechanism_gradient.py

Uses the tests' own functions (tests/fea/test_mechanism_sensitivity.py,
tests/pipeline/test_mechanism_gradient.py).
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    sys.path[:0] = [str(ROOT / "tests" / "fea"), str(ROOT / "tests" / "pipeline")]
    from flexopt.fea.beam_sensitivity import ks_aggregate
    from flexopt.fea.mechanism import solve_mechanism
    from flexopt.fea.mechanism_sensitivity import mechanism_sensitivities
    from test_mechanism_gradient import central, problem_of
    from test_mechanism_sensitivity import CASE, OUTPUTS, TIGHT, X, fd, guide, rel

    print(f"load avg {' '.join(f'{v:.2f}' for v in os.getloadavg())} at start")
    sens = mechanism_sensitivities(guide, X, CASE, OUTPUTS)
    print("step study: guide of the tests, exact against the 4th-order FD of the re-traced path")
    for i, name in ((0, "thickness"), (1, "leaf length")):
        for h in (1e-1, 3e-2, 1e-2, 1e-3, 1e-4, 1e-5):
            cache: dict[float, object] = {}

            def resp(xs, cache=cache, i=i):
                key = float(xs[i])
                if key not in cache:
                    cache[key] = solve_mechanism(guide(xs), CASE, OUTPUTS, TIGHT)
                return cache[key]

            errs = [
                rel(sens.derivatives[n][:, i], fd(lambda xs, n=n: resp(xs).outputs[n], X, i, h))
                for n in ("F", "rot", "sx", "Fg", "Mg")
            ]
            peak = rel(
                sens.derivatives["peak_stress_MPa"][..., i],
                fd(lambda xs: resp(xs).peak_stress_MPa, X, i, h),
            )
            print(f"  {name:12s} h {h:7.0e}  outputs {max(errs):.1e}  peak stress {peak:.1e}")
    values = sens.values["fibre_MPa"].ravel()
    peak = sens.values["peak_stress_MPa"].max()
    print(f"KS over the guide's path ({values.size} signed values), max {peak:.4f} MPa:")
    for rho in (0.021, 0.21, 2.1, 21.0):
        ks, _ = ks_aggregate(values, rho)
        gap, bound = ks - peak, np.log(values.size) / rho
        print(f"  rho {rho:6.3f} /MPa  KS - max {gap:.3e} MPa  bound {bound:.3f} MPa")
    for name in ("parallel-guide", "gripper-amplifier"):
        problem = problem_of(name)
        x = problem.nominal_design()
        jac = problem.jacobian(x)
        span = problem.space.upper - problem.space.lower
        cols = [central(problem, x, i, 1e-3 * span[i]) for i in range(x.size)]
        F = np.column_stack([c[0] for c in cols])
        W = np.array([c[2][0] for c in cols])
        G = np.column_stack([c[1] for c in cols])
        worst = []
        for exact, ref in ((jac.f, F), (jac.g, G)):
            for row in range(ref.shape[0]):
                scale = np.abs(ref[row]).max()
                if scale > 0.0:
                    worst.append(np.abs(exact[row] - ref[row]).max() / scale)
        if np.abs(W).max() > 0.0:
            worst.append(np.abs(jac.info["width_gradient"] - W).max() / np.abs(W).max())
        tj, te = [], []
        for _ in range(5):
            c = time.process_time()
            problem.jacobian(x)
            tj.append(time.process_time() - c)
            c = time.process_time()
            problem.evaluate(x)
            te.append(time.process_time() - c)
        j, e = statistics.median(tj), statistics.median(te)
        print(
            f"{name}: {x.size} variables, f and {G.shape[0]} g rows, worst relative error "
            f"{max(worst):.1e}; KS {jac.info['ks_MPa']} MPa; Jacobian {1e3 * j:.0f} ms CPU, "
            f"evaluation {1e3 * e:.1f} ms ({j / e:.1f} evaluations; forward differences: "
            f"{x.size})"
        )
    print(f"load avg {' '.join(f'{v:.2f}' for v in os.getloadavg())} at end")


if __name__ == "__main__":
    main()
