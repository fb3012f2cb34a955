"""The print-to-part loop on a simulated printer (docs/print_to_part.md): the figures it prints.

    python benchmarks/print_to_part_loop.py [--noise 0.005] [--seed 3]

A simulated printer has a hidden E (the spool's) and a hidden wall-thickness offset; its
"measurements" are the model's curves with that E and offset and Gaussian noise on the force.
Steps: coupon -> calibrate; two coupons printed along the printer's x and y (a hidden E_x, E_y)
-> the anisotropic fit; the default constant-force part designed in the datasheet PETG, in the
calibrated PETG (fitted E and offset, analysed as printed) and "printed" by the hidden printer ->
compare, with the force band judged on the measured curve; the default part printed in a spool
10 % softer than the study's ABS -> compare -> re-trim of its width -> the second print's
verdicts and its band on the measured curve.
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
    from flexopt.fea.coupon import CouponSpec, coupon_curves
    from flexopt.fea.materials import get_material
    from flexopt.optimise.calibration import fit_coupon, fit_coupons
    from flexopt.pipeline.print_to_part import compare_run, retrim_run

    rng = np.random.default_rng(args.seed)
    base = get_material("PETG")
    spec = CouponSpec()
    stroke, _ = coupon_curves(spec, base)
    hidden_E, hidden_dt = 1830.0, -0.06
    hidden = dataclasses.replace(base, E_MPa=hidden_E)
    r = fit_coupon(simulated(spec, hidden, hidden_dt, stroke, rng, args.noise), spec, base)
    print(
        f"coupon: {len(spec.thicknesses_mm)} strips, stroke {stroke:.2f} mm, {r.n_points} points, "
        f"noise {100 * args.noise:g} %"
    )
    print(f"  E      hidden {hidden_E:.1f}  fitted {r.E_MPa:.1f} ± {r.E_ci95_MPa:.1f} MPa (95 %)")
    print(
        f"  offset hidden {hidden_dt:+.4f}  fitted {r.offset_mm:+.4f} ± {r.offset_ci95_mm:.4f} mm"
    )

    # two orientations: the strips along the printer's x and along its y, one wall offset
    hidden_xy = {"x": 1900.0, "y": 1700.0}
    tests = []
    for o, E in hidden_xy.items():
        m = simulated(spec, dataclasses.replace(base, E_MPa=E), hidden_dt, stroke, rng, args.noise)
        tests.append((dataclasses.replace(m, orientation=o, source=f"sim-{o}"), spec))
    a = fit_coupons(tests, base)
    print("two coupons, strips along the printer's x and along its y:")
    for m in a.moduli:
        print(
            f"  E_{m.orientation}    hidden {hidden_xy[m.orientation]:.1f}  fitted "
            f"{m.E_MPa:.1f} ± {m.E_ci95_MPa:.1f} MPa (95 %)"
        )
    print(
        f"  E_y/E_x hidden {hidden_xy['y'] / hidden_xy['x']:.4f}  fitted "
        f"{a.anisotropy_ratio:.4f} ± {a.anisotropy_ratio_ci95:.4f}; offset fitted "
        f"{a.offset_mm:+.4f} ± {a.offset_ci95_mm:.4f} mm"
    )

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        as_printed(tmp, r, hidden_E, hidden_dt, rng)
        design = flexopt.evaluate("constant-force", out=tmp / "design")
        soft = 0.9 * design.study.material.E_MPa
        first = flexopt.evaluate(design.study.with_values({"material.E_MPa": soft}))
        rows = np.arange(1, first.table["displacement_mm"].size)
        f = first.table["force_N"][rows] * (1 + 0.001 * rng.standard_normal(rows.size))
        lines = ["displacement_mm,force_N"] + [
            f"{d:.5f},{v:.6f}" for d, v in zip(first.table["displacement_mm"][rows], f, strict=True)
        ]
        (tmp / "measured.csv").write_text("\n".join(lines) + "\n")
        cmp = compare_run(tmp / "design", tmp / "measured.csv")
        c = cmp.comparison
        print("constant-force part printed in a spool 10 % softer than the study's ABS:")
        print(
            f"  first print: force error {c.force_error_percent:+.2f} %, stiffness error "
            f"{c.stiffness_error_percent:+.2f} %; verdicts: "
            + ", ".join(f"{v.name} {'MET' if v.met else 'NOT MET'}" for v in first.verdict)
        )
        print("  on the measured curve: " + band_words(cmp))
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
        write_measured(tmp / "second.csv", second.table, rng, 0.001)
        print(
            "  second print on the measured curve: "
            + band_words(compare_run(tmp / "design", tmp / "second.csv"))
        )


def simulated(spec, material, dt, stroke, rng, noise):
    """The coupon "measured" on the simulated printer: every 4th row of each strip's curve."""
    from flexopt.fea.coupon import strip_curve
    from flexopt.optimise.calibration import CouponMeasurement

    T, D, F = [], [], []
    for t in spec.thicknesses_mm:
        c = strip_curve(spec, material, t + dt, stroke)
        rows = np.arange(4, len(c.force_N), 4)
        T += [t] * rows.size
        D += list(c.displacement_mm[rows])
        F += list(c.force_N[rows] * (1 + noise * rng.standard_normal(rows.size)))
    return CouponMeasurement(np.array(T), np.array(D), np.array(F), "sim")


def write_measured(path, table, rng, noise):
    """A measured curve of a printed part: the table's rows 1.. with relative force noise."""
    rows = np.arange(1, table["displacement_mm"].size)
    f = table["force_N"][rows] * (1 + noise * rng.standard_normal(rows.size))
    lines = ["displacement_mm,force_N"] + [
        f"{d:.5f},{v:.6f}" for d, v in zip(table["displacement_mm"][rows], f, strict=True)
    ]
    path.write_text("\n".join(lines) + "\n")


def band_words(cmp):
    """The band verdicts on the measured curve beside the predicted ones, in words."""
    return ", ".join(
        f"{v.name} measured {'MET' if v.met else 'NOT MET'} ({v.value:.4g} {v.unit}; predicted "
        f"{cmp.predicted.get(v.name, {}).get('verdict', '?')})"
        for v in cmp.measured_verdicts
    )


def as_printed(tmp, fit, hidden_E, hidden_dt, rng):
    """The default constant-force part in PETG: the datasheet model, the calibrated model (the
    fitted E and offset, analysed as printed) and the hidden printer's part ("printed")."""
    import flexopt
    import yaml
    from flexopt.optimise.calibration import write_materials_file
    from flexopt.pipeline.print_to_part import compare_run
    from flexopt.pipeline.study import load_study, resolve_study_path

    write_materials_file(tmp / "materials.yaml", "my-petg", fit)
    data = yaml.safe_load((tmp / "materials.yaml").read_text())
    data["printer"] = {**data["my-petg"], "E_MPa": hidden_E, "thickness_offset_mm": hidden_dt}
    data["printer"].pop("calibration")
    (tmp / "materials.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
    raw = yaml.safe_load(resolve_study_path("constant-force").read_text())
    results = {}
    for material in ("PETG", "my-petg", "printer"):
        raw["material"] = material
        # the ABS study's allowable would judge PETG's stress on ABS's number: the material's
        raw["target"].pop("allowable_stress_MPa", None)
        (tmp / f"{material}.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
        results[material] = flexopt.evaluate(
            load_study(tmp / f"{material}.yaml"), out=tmp / material
        )
    write_measured(tmp / "petg-part.csv", results["printer"].table, rng, 0.001)
    print(
        "default constant-force part in PETG (the hidden printer: E "
        f"{hidden_E:g} MPa, walls {hidden_dt:+.3f} mm):"
    )
    for material, label in (
        ("PETG", "datasheet PETG, as drawn"),
        ("my-petg", "calibrated, as printed"),
    ):
        cmp = compare_run(tmp / material, tmp / "petg-part.csv")
        table = results[material].table
        mean = float(np.interp(15.0, table["displacement_mm"], table["force_N"]))
        print(
            f"  {label}: predicted force at 15 mm {mean:.4f} N; the print measured against "
            f"it: force error {cmp.comparison.force_error_percent:+.2f} %; " + band_words(cmp)
        )
    dt = results["my-petg"].summary.get("thickness_offset_mm")
    print(f"  (the calibrated study applied the offset {dt:+.4f} mm; its STL is the drawing)")


if __name__ == "__main__":
    main()
