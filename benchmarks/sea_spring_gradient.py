"""Figures of the SEA spring's plane-stress sensitivities (issue 27 item 1, docs/sensitivities.md
"Plane stress"): the kind's Jacobian against central differences of the morphed solve (every
variable, every figure), the KS aggregate against the judged peak, the morphed mesh against the
re-meshed design under refinement, and the cost against an evaluation.

    OMP_NUM_THREADS=1 nice python benchmarks/sea_spring_gradient.py [--quick | --cost]

On pipeline/examples/sea-spring-quick.yaml's design (``--quick``: the accuracy of three
variables and no refinement study; ``--cost``: only the cost, on the quick and the full
study's design and meshes).
"""

from __future__ import annotations

import os
import statistics
import sys
import time

import numpy as np

FIGURES = (
    "ST_mm", "stiffness_ccw_Nm_per_rad", "stiffness_cw_Nm_per_rad", "torque_ccw_Nm",
    "torque_cw_Nm", "ks_MPa", "mass_g", "asymmetry_percent",
)  # fmt: skip


def main() -> None:
    from flexopt.pipeline.studies import sea_spring as ss
    from flexopt.pipeline.studies._sea_spring_gradient import (
        morphed_responses,
        spring_sensitivities,
    )
    from flexopt.pipeline.study import load_study

    quick = "--quick" in sys.argv
    if "--cost" in sys.argv:
        print(f"load avg {' '.join(f'{v:.2f}' for v in os.getloadavg())} at start")
        return _cost(ss, load_study)
    print(f"load avg {' '.join(f'{v:.2f}' for v in os.getloadavg())} at start")
    base = load_study("sea-spring-quick")
    prob = ss.SeaSpringProblem(base, stage1={})
    x = prob.nominal_design()
    sens = spring_sensitivities(prob, x)
    v = sens["values"]
    over = v["ks_MPa"] / v["peak_stress_MPa"] - 1
    print(
        f"design: ST {v['ST_mm']:.4f} mm, peak {v['peak_stress_MPa']:.2f} MPa, KS "
        f"{v['ks_MPa']:.2f} MPa (rho {sens['rho_per_MPa']:.3g} /MPa, +{over:.2%}), "
        f"{sens['n_vertices']} vertices, {sens['unmapped_vertices']} boundary vertices unmapped"
    )

    print("accuracy: exact against central differences of the morphed solve (1e-5 of range)")
    names = prob.space.names if not quick else ("W2_mm", "F1_fraction", "sweep_deg")
    worst = {}
    for name in names:
        i = prob.space.names.index(name)
        h = 1e-5 * (prob.space.upper[i] - prob.space.lower[i])
        ends = []
        for s in (h, -h):
            xs = x.copy()
            xs[i] += s
            ends.append(morphed_responses(prob, x, xs))
        errs = []
        for key in FIGURES:
            fd = (np.asarray(ends[0][key]) - np.asarray(ends[1][key])) / (2 * h)
            ex = np.asarray(sens["gradients"][key])[..., i]
            err = float(np.max(np.abs(ex - fd)) / np.max(np.abs(fd)))
            errs.append(err)
            worst[key] = max(worst.get(key, 0.0), err)
        dst = sens["gradients"]["ST_mm"][i]
        print(f"  {name:12s} max rel. error {max(errs):.2e}  (dST/dx {dst:+.5g})")
    print("  worst per figure: " + ", ".join(f"{k} {e:.1e}" for k, e in worst.items()))

    _cost(ss, load_study)
    if quick:
        return
    print("morphed mesh against the re-meshed design, W4 3 % down (ST, mm; peak, MPa)")
    for edge, through in ((4.0, 1.0), (2.0, 2.0), (1.0, 4.0)):
        study = base.model_copy(
            update={"mesh": base.mesh.model_copy(
                update={"max_edge_mm": edge, "elements_through": through})}
        )  # fmt: skip
        p = ss.SeaSpringProblem(study, stage1={})
        x1 = x.copy()
        x1[p.space.names.index("W4_mm")] *= 0.97
        m = morphed_responses(p, x, x1)
        r = morphed_responses(p, x1, x1)
        b = morphed_responses(p, x, x)
        print(
            f"  {edge:g} mm, {through:g} across: dST morphed {m['ST_mm'] - b['ST_mm']:+.6f} "
            f"re-meshed {r['ST_mm'] - b['ST_mm']:+.6f} gap {abs(m['ST_mm'] - r['ST_mm']):.2e}; "
            f"peak gap {abs(m['peak_stress_MPa'] - r['peak_stress_MPa']):.3f}"
        )


def _cost(ss, load_study) -> None:
    """CPU of one Jacobian against one evaluation, medians of 5, on the quick and the full
    study's nominal design (their own meshes)."""
    print("cost (CPU, medians of 5): one Jacobian against one evaluation")
    for name in ("sea-spring-quick", "sea-spring"):
        prob = ss.SeaSpringProblem(load_study(name), stage1={})
        x = prob.nominal_design()
        jac, ev = [], []
        for _ in range(5):
            t = time.process_time()
            e = prob.evaluate(x)
            ev.append(time.process_time() - t)
            t = time.process_time()
            j = prob.jacobian(x)
            jac.append(time.process_time() - t)
        mj, me = statistics.median(jac), statistics.median(ev)
        print(
            f"  {name}: {e.metrics['n_dofs']} DOFs, jacobian {mj:.3f} s (its solves "
            f"{j.info['solve_cpu_s']:.3f} s), evaluation {me:.3f} s: {mj / me:.2f} evaluations "
            f"for {x.size} columns; {j.info['unmapped_vertices']} boundary vertices unmapped"
        )


if __name__ == "__main__":
    main()
