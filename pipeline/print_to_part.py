"""From print to part (issue #26): the coupon's files, and calibration from its measured curve.

``flexopt coupon`` → :func:`coupon_files` (STL, predicted curves, protocol, a CSV template and
``coupon.json``, which ``flexopt calibrate`` reads back); ``flexopt calibrate`` →
:func:`calibrate` (fit, plot, materials file). docs/print_to_part.md is the user's guide.

Units: mm, N, MPa.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from flexopt.fea.coupon import CouponSpec, coupon_curves
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.geometry.coupon import coupon_outline
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.solid import extrude, stl_bytes
from flexopt.optimise.calibration import (
    CSV_COLUMNS,
    CalibrationError,
    CalibrationResult,
    fit_coupon,
    read_coupon_csv,
    write_materials_file,
)

__all__ = ["COUPON_JSON", "coupon_files", "read_coupon_record", "calibrate", "CalibrateOutcome"]

#: the coupon's record in its folder: what ``flexopt calibrate --coupon`` reads
COUPON_JSON = "coupon.json"
#: largest measured CSV read (a test has hundreds of rows, not millions)
MAX_CSV_BYTES = 4 << 20


def _material_record(m: Material) -> dict[str, Any]:
    rec = asdict(m)
    if not math.isfinite(rec["density_kg_m3"]):
        rec["density_kg_m3"] = None
    return rec


def coupon_files(material: Material, spec: CouponSpec | None = None) -> dict[str, bytes]:
    """The files of a coupon for ``material``: ``coupon.stl``, ``coupon_prediction.csv``,
    ``coupon_measured_template.csv``, ``protocol.md`` and ``coupon.json``.

    Raises
    ------
    CalibrationError
        When the coupon cannot be drawn or solved for this material (the message says why).
    """
    spec = CouponSpec() if spec is None else spec
    try:
        stroke, curves = coupon_curves(spec, material)
        outline = coupon_outline(spec.thicknesses_mm, spec.length_mm)
        stl = stl_bytes(extrude(outline.polygon, spec.width_mm))
    except (FeaError, GeometryError) as err:
        raise CalibrationError(f"coupon: {err}") from err
    pred = io.StringIO()
    w = csv.writer(pred, lineterminator="\n")
    w.writerow(["thickness_mm", "displacement_mm", "force_N", "peak_stress_MPa"])
    for c in curves:
        for d, f, s in zip(c.displacement_mm, c.force_N, c.peak_stress_MPa, strict=True):
            w.writerow([f"{c.thickness_mm:.6g}", f"{d:.6g}", f"{f:.6g}", f"{s:.6g}"])
    template = io.StringIO()
    w = csv.writer(template, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for t in spec.thicknesses_mm:
        for k in range(1, 11):
            w.writerow([f"{t:g}", f"{stroke * k / 10:.3g}", ""])
    record = {
        "coupon": {**asdict(spec), "stroke_mm": stroke},
        "material": _material_record(material),
        "predicted_max_force_N": {f"{c.thickness_mm:g}": float(c.force_N[-1]) for c in curves},
    }
    return {
        "coupon.stl": stl,
        "coupon_prediction.csv": pred.getvalue().encode(),
        "coupon_measured_template.csv": template.getvalue().encode(),
        "protocol.md": _protocol(material, spec, stroke, curves).encode(),
        COUPON_JSON: (json.dumps(record, indent=2) + "\n").encode(),
    }


def _protocol(material: Material, spec: CouponSpec, stroke: float, curves: list) -> str:
    rows = "\n".join(
        f"| {c.thickness_mm:g} | {c.force_N[-1]:.3g} | {float(np.max(c.peak_stress_MPa)):.1f} |"
        for c in curves
    )
    lines = [
        f"# Calibration coupon — {material.name}",
        "",
        "## Print",
        f"- `coupon.stl`: a clamp block with {len(spec.thicknesses_mm)} strips "
        f"({', '.join(f'{t:g}' for t in spec.thicknesses_mm)} mm thick, {spec.length_mm:g} mm "
        f"free length, {spec.width_mm:g} mm high). Print it flat, in the same orientation, "
        "material, nozzle, layer height and wall settings as the part: the fit measures this "
        "printer with this spool.",
        "- The notches on the block's back face count the strips from the thinnest (1 notch).",
        "",
        "## Fixture and drive",
        "- Clamp the block in a vice up to its face (the strips' roots): the free length is the "
        "model's; a clamp that leaves the block loose shows as a soft, non-linear start.",
        "- Push each strip's tip perpendicular to the strip with a flat pusher on a force gauge "
        "(or a load cell on a slide), so the tip can rotate and slide along the pusher: the model "
        "is a tip load of fixed direction.",
        f"- Drive from 0 to {stroke:.3g} mm, slowly (quasi-static, ~1 mm/s), loading branch only. "
        f"The thickest strip then reaches {spec.stress_fraction:g} x the allowable "
        f"({material.yield_MPa:g} MPa); do not go further.",
        "",
        "## What to record",
        "A CSV with the columns `thickness_mm, displacement_mm, force_N` (mm and N), one row per "
        "reading, each strip's rows in order of increasing displacement; at least 5 readings per "
        "strip, 10 or more is better (`coupon_measured_template.csv` is a start). Zero the force "
        "with the pusher just touching the tip.",
        "",
        "## Expected",
        "| strip thickness mm | force at the stroke N | peak stress MPa |",
        "|---|---|---|",
        rows,
        "",
        "The whole predicted curves are in `coupon_prediction.csv` (the model with the spool's "
        "datasheet E and no thickness offset).",
        "",
        "## Then",
        "`flexopt calibrate measured.csv --coupon coupon.json --name my-material` fits E and "
        "the printer's thickness offset, with 95 % intervals, and writes `materials.yaml`.",
        "",
    ]
    return "\n".join(lines)


def read_coupon_record(path: Path) -> tuple[CouponSpec, Material]:
    """The coupon and its base material from ``coupon.json`` (or the folder holding it).

    Raises
    ------
    CalibrationError
        When the file is missing, too large, not JSON or not a coupon record.
    """
    p = path / COUPON_JSON if path.is_dir() else path
    where = str(p)
    try:
        if not p.is_file():
            raise CalibrationError(
                f"{where}: no coupon record; give the coupon.json of `flexopt coupon`"
            )
        data = p.read_bytes()[: 1 << 20]
        rec = json.loads(data.decode("utf-8"))
        spec_rec = dict(rec["coupon"])
        spec_rec["thicknesses_mm"] = tuple(spec_rec["thicknesses_mm"])
        spec = CouponSpec(**spec_rec)
        material = Material(**rec["material"])
    except CalibrationError:
        raise
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError, FeaError) as e:
        raise CalibrationError(
            f"{where}: not a coupon record of `flexopt coupon` ({type(e).__name__}: {e})"
        ) from None
    return spec, material


@dataclass(frozen=True)
class CalibrateOutcome:
    """What :func:`calibrate` did: the fit, the materials file written and the files made."""

    result: CalibrationResult
    materials_path: Path | None
    files: dict[str, bytes]


def calibrate(
    measured_csv: Path,
    coupon: Path,
    name: str | None = None,
    materials_path: Path | None = None,
) -> CalibrateOutcome:
    """Fit E and the thickness offset to a measured coupon curve.

    Parameters
    ----------
    measured_csv : the measured points (``thickness_mm, displacement_mm, force_N``).
    coupon : ``coupon.json`` of ``flexopt coupon`` (or its folder).
    name : the material's name in the materials file; nothing is written when None.
    materials_path : the materials file (default: ``materials.yaml`` beside the measured CSV).

    Returns
    -------
    CalibrateOutcome with ``files``: ``calibration.json`` (the fit) and ``calibration.png`` (the
    measured points, the fitted curves and the residuals).

    Raises
    ------
    CalibrationError
        On bad data (:mod:`optimise.calibration`), a bad coupon record or an unreadable CSV.
    """
    spec, base = read_coupon_record(coupon)
    try:
        if not measured_csv.is_file():
            raise CalibrationError(f"{measured_csv}: not a file")
        raw = measured_csv.read_bytes()
    except OSError as err:
        raise CalibrationError(f"{measured_csv}: cannot be read ({err.strerror or err})") from None
    if len(raw) > MAX_CSV_BYTES:
        raise CalibrationError(f"{measured_csv}: larger than {MAX_CSV_BYTES >> 20} MiB")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise CalibrationError(f"{measured_csv}: not UTF-8 text") from None
    measured = read_coupon_csv(text, str(measured_csv))
    result = fit_coupon(measured, spec, base)
    written = None
    if name:
        written = materials_path or measured_csv.parent / "materials.yaml"
        write_materials_file(written, name, result)
    files = {
        "calibration.json": (json.dumps(result.record(), indent=2) + "\n").encode(),
        "calibration.png": _plot(measured, result),
    }
    return CalibrateOutcome(result, written, files)


def _plot(measured: Any, result: CalibrationResult) -> bytes:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, axr) = plt.subplots(2, 1, figsize=(6.4, 6.0), sharex=True, height_ratios=[3, 1])
    for t in sorted(set(measured.thickness_mm.tolist())):
        sel = measured.thickness_mm == t
        d = measured.displacement_mm[sel]
        (line,) = ax.plot(d, result.model_N[sel], "-", label=f"fit, strip {t:g} mm")
        ax.plot(d, measured.force_N[sel], "o", ms=3, color=line.get_color(), label="measured")
        axr.plot(d, result.residual_N[sel], "o-", ms=3, color=line.get_color())
    ax.set_ylabel("Force (N)")
    ax.set_title(
        f"E = {result.E_MPa:.0f} ± {result.E_ci95_MPa:.0f} MPa, thickness offset "
        f"{result.offset_mm:+.3f} ± {result.offset_ci95_mm:.3f} mm (95 %)",
        fontsize=9,
    )
    ax.legend(fontsize=7)
    axr.axhline(0.0, color="0.5", lw=0.8)
    axr.set_xlabel("Tip displacement (mm)")
    axr.set_ylabel("Model − measured (N)")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()
