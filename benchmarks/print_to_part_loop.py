"""The print-to-part loop on a simulated printer (docs/print_to_part.md): the figures it prints.

    python benchmarks/print_to_part_loop.py [--noise 0.005] [--seed 3]

A simulated printer has a hidden E (the spool's, 10 % below the datasheet's PETG or ABS) and a
hidden wall-thickness offset; its "measurements" are the model's curves with that E and offset and
Gaussian noise on the force. Steps: coupon -> calibrate -> compare of the default constant-force
part printed in a spool 10 % softer than the study assumes -> re-trim of its width -> the second
print's verdicts.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--noise", type=float, default=0.005, help="relative force noise (default 0.5 %%)"
    )
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args()

    import flexopt
    from flexopt.fea.coupon import CouponSpec, coupon_curves, strip_curve
    from flexopt.fea.materials import get_material
    from flexopt.optimise.calibration import CouponMeasurement, fit_coupon
    from flexopt.pipeline.print_to_part import compare_run, retrim_run

    rng = np.random.default_rng(args.seed)
    base = get_material("PETG")
    spec = CouponSpec()
    stroke, _ = coupon_curves(spec, base)
    hidden_E, hidden_dt = 1830.0, -0.06
    hidden = dataclasses.replace(base, E_MPa=hidden_E)
    T, D, F = [], [], []
    for t in spec.thicknesses_mm:
        c = strip_curve(spec, hidden, t + hidden_dt, stroke)
        rows = np.arange(4, len(c.force_N), 4)
        T += [t] * rows.size
        D += list(c.displacement_mm[rows])
        F += list(c.force_N[rows] * (1 + args.noise * rng.standard_normal(rows.size)))
    r = fit_coupon(CouponMeasurement(np.array(T), np.array(D), np.array(F), "sim"), spec, base)
    print(
        f"coupon: {len(spec.thicknesses_mm)} strips, stroke {stroke:.2f} mm, {r.n_points} points, "
        f"noise {100 * args.noise:g} %"
    )
    print(f"  E      hidden {hidden_E:.1f}  fitted {r.E_MPa:.1f} ± {r.E_ci95_MPa:.1f} MPa (95 %)")
    print(
        f"  offset hidden {hidden_dt:+.4f}  fitted {r.offset_mm:+.4f} ± {r.offset_ci95_mm:.4f} mm"
    )

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        design = flexopt.evaluate("constant-force", out=tmp / "design")
        soft = 0.9 * design.study.material.E_MPa
        first = flexopt.evaluate(design.study.with_values({"material.E_MPa": soft}))
        rows = np.arange(1, first.table["displacement_mm"].size)
        f = first.table["force_N"][rows] * (1 + 0.001 * rng.standard_normal(rows.size))
        lines = ["displacement_mm,force_N"] + [
            f"{d:.5f},{v:.6f}" for d, v in zip(first.table["displacement_mm"][rows], f, strict=True)
        ]
        (tmp / "measured.csv").write_text("\n".join(lines) + "\n")
        c = compare_run(tmp / "design", tmp / "measured.csv").comparison
        print("constant-force part printed in a spool 10 % softer than the study's ABS:")
        print(
            f"  first print: force error {c.force_error_percent:+.2f} %, stiffness error "
            f"{c.stiffness_error_percent:+.2f} %; verdicts: "
            + ", ".join(f"{v.name} {'MET' if v.met else 'NOT MET'}" for v in first.verdict)
        )
        t = retrim_run(tmp / "design", tmp / "measured.csv", "design.B")
        second = flexopt.evaluate(t.study.with_values({"material.E_MPa": soft}))
        print(f"  re-trim: B {t.old_mm:.4f} -> {t.new_mm:.4f} mm (x {t.scale:.4f})")
        print(
            "  second print: "
            + ", ".join(
                f"{v.name} {'MET' if v.met else 'NOT MET'} ({v.value:.4g} {v.unit})"
                for v in second.verdict
            )
        )


if __name__ == "__main__":
    main()
