"""The print-to-part subcommands of ``flexopt``: ``coupon``, ``calibrate``, ``compare``, ``retrim``.

Each handler returns the exit code: 0 done, 2 bad input (one line on stderr: what, and how to fix
it), 1 a file that cannot be written. docs/print_to_part.md is the guide.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

__all__ = ["add_print_commands"]

EXIT_OK, EXIT_WRITE, EXIT_USAGE = 0, 1, 2


def _path(text: str) -> Path:
    if not text.strip():
        raise argparse.ArgumentTypeError("is empty; give a path")
    return Path(text)


def _thickness(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"'{text[:40]}' is not a comma-separated list of thicknesses in mm, e.g. 0.8,1.2,1.6"
        ) from None
    return values


def add_print_commands(commands: Any) -> None:
    """Add the four subcommands to ``flexopt``'s subparsers."""
    coupon = commands.add_parser(
        "coupon",
        help="a test coupon for a material and printer: STL, predicted curves, test protocol",
        description=(
            "Write a calibration coupon for MATERIAL (a library name or one of a materials.yaml): "
            "coupon.stl (a clamp block with strips of several thicknesses), its predicted "
            "force-displacement curves, a one-page test protocol, a CSV template for the "
            "measurement and coupon.json, which flexopt calibrate reads."
        ),
    )
    coupon.add_argument("material", metavar="MATERIAL", help="the spool's material, e.g. PETG")
    coupon.add_argument(
        "--out", type=_path, metavar="DIR", help="folder (default ./coupon-MATERIAL)"
    )
    coupon.add_argument(
        "--thicknesses",
        type=_thickness,
        metavar="T1,T2,...",
        help="strip thicknesses in mm, at least two different (default 0.8,1.2,1.6)",
    )
    coupon.add_argument("--length", type=float, metavar="MM", help="free strip length (default 40)")
    coupon.add_argument("--width", type=float, metavar="MM", help="strip height (default 10)")
    coupon.set_defaults(handler=_coupon)

    cal = commands.add_parser(
        "calibrate",
        help="fit E and the printer's thickness offset to a measured coupon curve",
        description=(
            "Fit Young's modulus and the printer's wall-thickness offset to the measured curve of "
            "a coupon (columns thickness_mm, displacement_mm, force_N) by nonlinear least squares "
            "on the same beam solve, with 95 %% intervals; write calibration.json and "
            "calibration.png, and with --name the material into materials.yaml. Two CSVs of "
            "coupons printed in two orientations (an orientation column, x or y, or "
            "--orientation per CSV) fit E along x and along y and the shared offset: the "
            "in-plane anisotropy. A hold test of the coupon (columns time_h and force_N: "
            "relaxation at a held displacement; or time_h and displacement_mm: creep under a "
            "held force) fits a Findley creep law instead (tau, n with 95 %% intervals, "
            "--stress-ratio required, no --coupon), written into --name's creep: block."
        ),
    )
    cal.add_argument("measured", type=_path, nargs="+", metavar="MEASURED.csv")
    cal.add_argument(
        "--coupon",
        type=_path,
        action="append",
        metavar="COUPON",
        help="coupon.json or its folder; once for every CSV, or once per CSV in their order "
        "(a coupon curve; not for a hold test)",
    )
    cal.add_argument(
        "--stress-ratio",
        type=float,
        metavar="R",
        help="hold test: the coupon's peak stress over the material's strength during the hold, "
        "(0, 1]; the creep law's limit",
    )
    cal.add_argument(
        "--temperature",
        type=float,
        default=23.0,
        metavar="C",
        help="hold test: its temperature in C (default 23), the law's reference",
    )
    cal.add_argument(
        "--orientation",
        action="append",
        choices=("x", "y"),
        help="print orientation of each CSV in their order (the strips' long axis along the "
        "printer's x or y axis), for CSVs without an orientation column",
    )
    cal.add_argument("--name", metavar="NAME", help="name of the calibrated material to write")
    cal.add_argument(
        "--materials",
        type=_path,
        metavar="FILE",
        help="materials file to add it to (default materials.yaml beside MEASURED.csv)",
    )
    cal.add_argument("--out", type=_path, metavar="DIR", help="folder for the fit's files")
    cal.set_defaults(handler=_calibrate)

    cmp = commands.add_parser(
        "compare",
        help="overlay a measured curve of the printed part on its run's prediction",
        description=(
            "Compare a measured curve of the printed part (two columns named like the "
            "prediction's, e.g. displacement_mm,force_N) with the run's (or evaluate folder's) "
            "prediction: force and stiffness error in %%, RMS, and the run's requirements that "
            "read this curve (the constant-force band) judged on the measured curve, MET or NOT "
            "MET beside the predicted verdict; writes compare.json and compare.png into RUN_DIR."
        ),
    )
    cmp.add_argument("run_dir", type=_path, metavar="RUN_DIR")
    cmp.add_argument("measured", type=_path, metavar="MEASURED.csv")
    cmp.set_defaults(handler=_compare)

    trim = commands.add_parser(
        "retrim",
        help="correct the part's width from a measured curve so the next print meets its target",
        description=(
            "Scale the design's out-of-plane width (every force is proportional to it) so the "
            "measured curve lands on the prediction, and write the corrected design as a study."
        ),
    )
    trim.add_argument("run_dir", type=_path, metavar="RUN_DIR")
    trim.add_argument("measured", type=_path, metavar="MEASURED.csv")
    trim.add_argument(
        "--key",
        metavar="KEY",
        help="the width's key in the design's study (default: the kind's, e.g. design.B for "
        "constant-force)",
    )
    trim.add_argument(
        "--out", type=_path, metavar="FILE", help="study to write (default RUN_DIR/retrimmed.yaml)"
    )
    trim.set_defaults(handler=_retrim)


def _fail(args: Any, exc: BaseException) -> int:
    from flexopt.pipeline.errors import printable

    print(f"flexopt {args.command}: error: {printable(str(exc))}", file=sys.stderr)
    return EXIT_USAGE


def _write(folder: Path, files: dict[str, bytes]) -> list[Path]:
    from flexopt.pipeline.runfolder import regular_target, write_atomic

    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name, data in files.items():
        target = regular_target(folder / name)
        write_atomic(target, data)
        out.append(target)
    return out


def _coupon(args: Any) -> int:
    import dataclasses

    from flexopt.fea.coupon import CouponSpec
    from flexopt.fea.errors import FeaError
    from flexopt.fea.materials import Material
    from flexopt.optimise.calibration import CalibrationError
    from flexopt.pipeline.errors import StudyError
    from flexopt.pipeline.print_to_part import coupon_files
    from flexopt.pipeline.study import MaterialSpec, resolve_material

    try:
        record = resolve_material(args.material, str(Path.cwd() / "study.yaml"))
        spec_m = MaterialSpec.model_validate(record)
        material = Material(
            spec_m.name,
            spec_m.E_MPa,
            spec_m.nu,
            spec_m.yield_MPa,
            float("nan") if spec_m.density_kg_m3 is None else spec_m.density_kg_m3,
            spec_m.source,
        )
        spec = CouponSpec()
        changes = {
            k: v
            for k, v in (
                ("thicknesses_mm", args.thicknesses),
                ("length_mm", args.length),
                ("width_mm", args.width),
            )
            if v is not None
        }
        spec = dataclasses.replace(spec, **changes)
        files = coupon_files(material, spec)
        out = args.out or Path(
            f"coupon-{''.join(c for c in args.material if c.isalnum() or c in '-_')}"
        )
    except (StudyError, CalibrationError, FeaError, ValueError) as exc:
        return _fail(args, exc)
    try:
        written = _write(out, files)
    except (OSError, StudyError) as exc:
        print(f"flexopt coupon: error: cannot write {out}: {exc}", file=sys.stderr)
        return EXIT_WRITE
    print(f"wrote {len(written)} files into {out}: print coupon.stl, then follow protocol.md")
    return EXIT_OK


def _calibrate(args: Any) -> int:
    from flexopt.optimise.calibration import CalibrationError
    from flexopt.pipeline.errors import StudyError
    from flexopt.pipeline.hold_calibration import is_hold_csv
    from flexopt.pipeline.print_to_part import calibrate

    if any(is_hold_csv(p) for p in args.measured):
        return _calibrate_hold(args)
    if not args.coupon:
        return _fail(
            args, CalibrationError("give --coupon COUPON (the coupon.json of flexopt coupon)")
        )
    try:
        outcome = calibrate(args.measured, args.coupon, args.name, args.materials, args.orientation)
    except (CalibrationError, StudyError) as exc:
        return _fail(args, exc)
    except OSError as exc:
        print(f"flexopt calibrate: error: cannot write: {exc}", file=sys.stderr)
        return EXIT_WRITE
    r = outcome.result
    out = args.out or args.measured[0].parent
    try:
        _write(out, outcome.files)
    except (OSError, StudyError) as exc:
        print(f"flexopt calibrate: error: cannot write {out}: {exc}", file=sys.stderr)
        return EXIT_WRITE
    if r.anisotropic:
        moduli = ", ".join(
            f"E along {m.orientation} = {m.E_MPa:.1f} ± {m.E_ci95_MPa:.1f} MPa" for m in r.moduli
        )
        first, second = (m.orientation for m in r.moduli)
        moduli += (
            f" (E_{second}/E_{first} = {r.anisotropy_ratio:.4f} ± {r.anisotropy_ratio_ci95:.4f})"
        )
    else:
        moduli = f"E = {r.E_MPa:.1f} ± {r.E_ci95_MPa:.1f} MPa"
    print(
        f"{moduli}, thickness offset {r.offset_mm:+.4f} ± {r.offset_ci95_mm:.4f} mm (95 %), "
        f"RMS residual {r.rms_N:.3g} N over {r.n_points} points"
    )
    if outcome.materials_path is not None:
        print(f"wrote material '{args.name}' into {outcome.materials_path}")
        if r.anisotropic:
            print(
                f"a study names the direction its beams are printed along: material: "
                f"{args.name}@x or {args.name}@y"
            )
    print(f"wrote calibration.json and calibration.png into {out}")
    return EXIT_OK


def _calibrate_hold(args: Any) -> int:
    """``flexopt calibrate HOLD.csv --stress-ratio R [--name NAME]``: the creep law of a hold
    test (:mod:`pipeline.hold_calibration`)."""
    from flexopt.optimise.calibration import CalibrationError
    from flexopt.pipeline.hold_calibration import calibrate_hold

    if len(args.measured) != 1 or args.coupon:
        why = "one hold record at a time" if len(args.measured) != 1 else "no --coupon"
        return _fail(args, CalibrationError(f"a hold test (time_h column) takes {why}"))
    if args.stress_ratio is None:
        return _fail(
            args,
            CalibrationError(
                "a hold test needs --stress-ratio R: the coupon's peak stress over the "
                "material's strength during the hold (the creep law's limit)"
            ),
        )
    try:
        outcome = calibrate_hold(
            args.measured[0], args.stress_ratio, args.name, args.materials, args.temperature
        )
    except CalibrationError as exc:
        return _fail(args, exc)
    except OSError as exc:
        print(f"flexopt calibrate: error: cannot write: {exc}", file=sys.stderr)
        return EXIT_WRITE
    out = args.out or args.measured[0].parent
    try:
        _write(out, outcome.files)
    except OSError as exc:
        print(f"flexopt calibrate: error: cannot write {out}: {exc}", file=sys.stderr)
        return EXIT_WRITE
    f = outcome.fit
    print(
        f"{outcome.test} test: Findley tau = {f.tau_h:.4g} h (95 %: {f.tau_h_ci95[0]:.4g} .. "
        f"{f.tau_h_ci95[1]:.4g}), n = {f.n:.4f} ± {f.n_ci95:.4f}, RMS residual {f.rms:.3g} over "
        f"{f.n_points} points; valid up to stress ratio {args.stress_ratio:g}"
    )
    if outcome.materials_path is not None:
        print(f"wrote the creep law of '{args.name}' into {outcome.materials_path}")
    print(f"wrote creep_fit.json into {out}")
    return EXIT_OK


def _compare(args: Any) -> int:
    from flexopt.optimise.calibration import CalibrationError
    from flexopt.pipeline.errors import StudyError
    from flexopt.pipeline.print_to_part import compare_run

    try:
        outcome = compare_run(args.run_dir, args.measured)
    except (CalibrationError, StudyError) as exc:
        return _fail(args, exc)
    c = outcome.comparison
    try:
        _write(args.run_dir, outcome.files)
    except (OSError, StudyError) as exc:
        print(f"flexopt compare: error: cannot write into {args.run_dir}: {exc}", file=sys.stderr)
        return EXIT_WRITE
    print(
        f"{outcome.y_column} against {outcome.x_column}: force error "
        f"{c.force_error_percent:+.2f} %, stiffness error {c.stiffness_error_percent:+.2f} %, "
        f"RMS {c.rms_error:.4g}, max {c.max_error:.4g} over {c.x.size} points"
        + (f" ({c.dropped} outside the prediction, not compared)" if c.dropped else "")
    )
    for line in _measured_verdict_lines(outcome):
        print(line)
    print(f"wrote compare.json and compare.png into {args.run_dir}")
    return EXIT_OK


def _measured_verdict_lines(outcome: Any) -> list[str]:
    """One line per requirement judged on the measured curve, beside the run's prediction."""

    def word(met: Any, value: Any, unit: str) -> str:
        text = "MET" if met else "NOT MET"
        if isinstance(value, int | float) and value == value:
            text += f" ({value:.4g} {unit})".replace(" )", ")")
        return text

    lines = []
    for v in outcome.measured_verdicts:
        pred = outcome.predicted.get(v.name)
        before = (
            word(pred.get("met"), pred.get("value"), str(pred.get("unit", "")))
            if pred
            else "not in the run's verdict"
        )
        lines.append(
            f"{v.name} ({v.bound}): predicted {before}, measured {word(v.met, v.value, v.unit)}"
        )
    lines += [f"not judged on the measured curve: {n}" for n in outcome.not_judged]
    return lines


def _retrim(args: Any) -> int:
    from flexopt.optimise.calibration import CalibrationError
    from flexopt.pipeline.errors import StudyError
    from flexopt.pipeline.print_to_part import retrim_run
    from flexopt.pipeline.runfolder import regular_target, write_atomic
    from flexopt.pipeline.study import study_to_yaml

    try:
        t = retrim_run(args.run_dir, args.measured, args.key)
        target = regular_target(args.out or args.run_dir / "retrimmed.yaml")
    except (CalibrationError, StudyError) as exc:
        return _fail(args, exc)
    header = (
        f"{args.run_dir}'s design re-trimmed from {args.measured}: {t.key} "
        f"{t.old_mm:.4g} -> {t.new_mm:.4g} (x {t.scale:.4f});\n"
        f"print it and measure again: flexopt evaluate {target}"
    )
    try:
        write_atomic(target, study_to_yaml(t.study, header))
    except OSError as exc:
        print(f"flexopt retrim: error: cannot write {target}: {exc}", file=sys.stderr)
        return EXIT_WRITE
    print(
        f"{t.key}: {t.old_mm:.4g} -> {t.new_mm:.4g} (x {t.scale:.4f}; measured force error "
        f"{t.comparison.comparison.force_error_percent:+.2f} %); wrote {target}"
    )
    return EXIT_OK
