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
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
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
    fit_coupons,
    read_coupon_csv,
    write_materials_file,
)
from flexopt.optimise.requirements import overall, to_records
from flexopt.pipeline.errors import FlexoptError

__all__ = [
    "COUPON_JSON",
    "CalibrateOutcome",
    "CompareOutcome",
    "RetrimOutcome",
    "calibrate",
    "compare_run",
    "coupon_files",
    "measured_verdicts",
    "read_coupon_record",
    "retrim_run",
]

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
    measured_csv: Path | Sequence[Path],
    coupon: Path | Sequence[Path],
    name: str | None = None,
    materials_path: Path | None = None,
    orientations: Sequence[str] | None = None,
) -> CalibrateOutcome:
    """Fit E and the thickness offset to measured coupon curves; with tests in two print
    orientations, E along each one (the in-plane anisotropy) and the shared offset.

    Parameters
    ----------
    measured_csv : the measured points (``thickness_mm, displacement_mm, force_N`` and an
        optional ``orientation`` column, x or y), one CSV or several (one per orientation).
    coupon : ``coupon.json`` of ``flexopt coupon`` (or its folder): one for every CSV, or one
        per CSV in the same order.
    name : the material's name in the materials file; nothing is written when None.
    materials_path : the materials file (default: ``materials.yaml`` beside the first CSV).
    orientations : each CSV's print orientation (``x`` or ``y``, in the order of the CSVs),
        for CSVs without an ``orientation`` column.

    Returns
    -------
    CalibrateOutcome with ``files``: ``calibration.json`` (the fit) and ``calibration.png`` (the
    measured points, the fitted curves and the residuals).

    Raises
    ------
    CalibrationError
        On bad data (:mod:`optimise.calibration`), a bad coupon record or an unreadable CSV; for
        several CSVs without each one's orientation; for counts of coupons or orientations that
        do not match the CSVs.
    """
    csvs = [measured_csv] if isinstance(measured_csv, Path) else list(measured_csv)
    coupons = [coupon] if isinstance(coupon, Path) else list(coupon)
    if not csvs:
        raise CalibrationError("give at least one measured CSV")
    if len(coupons) not in (1, len(csvs)):
        raise CalibrationError(
            f"{len(coupons)} coupons for {len(csvs)} measured CSVs: give one coupon for all, or "
            "one per CSV in the same order"
        )
    given = list(orientations or [])
    if given and len(given) != len(csvs):
        raise CalibrationError(
            f"{len(given)} orientations for {len(csvs)} measured CSVs: give one per CSV (x or y)"
        )
    records = [read_coupon_record(c) for c in coupons]
    base = records[0][1]
    tests = []
    for i, path in enumerate(csvs):
        spec = records[i if len(records) > 1 else 0][0]
        measured = read_coupon_csv(_read_text(path), str(path), given[i] if given else "")
        tests.append((measured, spec))
    if len(tests) > 1 and not all(m.orientation for m, _ in tests):
        unnamed = ", ".join(str(csvs[i]) for i, (m, _) in enumerate(tests) if not m.orientation)
        raise CalibrationError(
            f"several measured CSVs: say each one's print orientation (x or y, the strips' long "
            f"axis along the printer's x or y axis) with an orientation column or --orientation; "
            f"not known for {unnamed}"
        )
    result = fit_coupons(tests, base)
    written = None
    if name:
        written = materials_path or csvs[0].parent / "materials.yaml"
        write_materials_file(written, name, result)
    files = {
        "calibration.json": (json.dumps(result.record(), indent=2) + "\n").encode(),
        "calibration.png": _plot([m for m, _ in tests], result),
    }
    return CalibrateOutcome(result, written, files)


def _read_text(path: Path) -> str:
    try:
        if not path.is_file():
            raise CalibrationError(f"{path}: not a file")
        raw = path.read_bytes()
    except OSError as err:
        raise CalibrationError(f"{path}: cannot be read ({err.strerror or err})") from None
    if len(raw) > MAX_CSV_BYTES:
        raise CalibrationError(f"{path}: larger than {MAX_CSV_BYTES >> 20} MiB")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise CalibrationError(f"{path}: not UTF-8 text") from None


def _plot(tests: Sequence[Any], result: CalibrationResult) -> bytes:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, axr) = plt.subplots(2, 1, figsize=(6.4, 6.0), sharex=True, height_ratios=[3, 1])
    start = 0
    for measured in tests:
        n = measured.force_N.size
        model, residual = result.model_N[start : start + n], result.residual_N[start : start + n]
        start += n
        along = f", {measured.orientation}" if measured.orientation else ""
        for t in sorted(set(measured.thickness_mm.tolist())):
            sel = measured.thickness_mm == t
            d = measured.displacement_mm[sel]
            (line,) = ax.plot(d, model[sel], "-", label=f"fit, strip {t:g} mm{along}")
            ax.plot(d, measured.force_N[sel], "o", ms=3, color=line.get_color(), label="measured")
            axr.plot(d, residual[sel], "o-", ms=3, color=line.get_color())
    ax.set_ylabel("Force (N)")
    if result.anisotropic:
        moduli = ", ".join(
            f"E_{m.orientation} = {m.E_MPa:.0f} ± {m.E_ci95_MPa:.0f}" for m in result.moduli
        )
        title = f"{moduli} MPa, thickness offset "
    else:
        title = f"E = {result.E_MPa:.0f} ± {result.E_ci95_MPa:.0f} MPa, thickness offset "
    ax.set_title(
        title + f"{result.offset_mm:+.3f} ± {result.offset_ci95_mm:.3f} mm (95 %)", fontsize=9
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


# -- compare a printed part with its run, and re-trim it -----------------------------------------

#: the response table of a run folder's best design, or of an evaluate folder
RESPONSE_FILES = ("best_response.csv", "response.csv")


def _read_csv(path: Path, what: str) -> tuple[list[str], np.ndarray]:
    try:
        if not path.is_file():
            raise CalibrationError(f"{path}: not a file ({what})")
        raw = path.read_bytes()
    except OSError as err:
        raise CalibrationError(f"{path}: cannot be read ({err.strerror or err})") from None
    if len(raw) > MAX_CSV_BYTES:
        raise CalibrationError(f"{path}: larger than {MAX_CSV_BYTES >> 20} MiB")
    try:
        rows = list(csv.reader(io.StringIO(raw.decode("utf-8-sig"))))
    except (UnicodeDecodeError, csv.Error):
        raise CalibrationError(f"{path}: not a UTF-8 CSV file") from None
    if len(rows) < 2:
        raise CalibrationError(f"{path}: no data rows")
    header = [h.strip() for h in rows[0]]

    def number(text: str) -> float:
        t = text.strip().lower()
        if t in ("true", "false"):
            return float(t == "true")
        try:
            return float(t) if t else math.nan
        except ValueError:
            return math.nan

    data = np.array(
        [[number(v) for v in r] + [math.nan] * (len(header) - len(r)) for r in rows[1:]]
    )
    return header, data


@dataclass(frozen=True)
class CompareOutcome:
    """A measured curve against a run's prediction (:func:`compare_run`).

    Attributes
    ----------
    comparison : the numbers (:class:`optimise.calibration.CurveComparison`).
    x_column, y_column : the compared columns (names with units).
    files : ``compare.json`` and ``compare.png``, for the run folder.
    measured_verdicts : the run's requirements that read this curve (the constant-force band),
        judged on the measured curve (:func:`measured_verdicts`).
    predicted : the run's own verdict of each of them by name, as its folder records it
        (``verdict`` ``MET``/``NOT MET``, ``value``, ``unit``), where it has one.
    not_judged : one line per requirement or reason the measured curve could not be judged.
    """

    comparison: Any
    x_column: str
    y_column: str
    files: dict[str, bytes]
    measured_verdicts: tuple[Any, ...] = ()
    predicted: dict[str, dict[str, Any]] = field(default_factory=dict)
    not_judged: tuple[str, ...] = ()


def compare_run(run_dir: Path, measured_csv: Path) -> CompareOutcome:
    """Overlay a measured curve of the printed part on its run's prediction.

    The measured CSV has two columns named like the prediction's (``displacement_mm, force_N``;
    ``angle_deg, torque_Nm`` ...): the first is the abscissa.

    Raises
    ------
    CalibrationError
        For a folder without a response table, a measured CSV whose columns the prediction does
        not have, or too few points in the predicted range.
    """
    from flexopt.optimise.calibration import compare_curves

    table = next((run_dir / n for n in RESPONSE_FILES if (run_dir / n).is_file()), None)
    if table is None:
        raise CalibrationError(
            f"{run_dir}: no {' or '.join(RESPONSE_FILES)}; give a folder of flexopt run or evaluate"
        )
    p_head, p_data = _read_csv(table, "the prediction")
    m_head, m_data = _read_csv(measured_csv, "the measured curve")
    if len(m_head) < 2 or any(h not in p_head for h in m_head[:2]):
        raise CalibrationError(
            f"{measured_csv}: the first two columns must be named like the prediction's, e.g. "
            f"{p_head[0]},{p_head[1]} (found {','.join(m_head[:2]) or 'none'})"
        )
    xc, yc = m_head[0], m_head[1]
    px, py = p_data[:, p_head.index(xc)], p_data[:, p_head.index(yc)]
    ok = np.isfinite(px) & np.isfinite(py)
    px, py = px[ok], py[ok]
    order = np.argsort(px, kind="stable")
    px, py = px[order], py[order]
    keep = np.concatenate([[True], np.diff(px) > 0])
    c = compare_curves(px[keep], py[keep], m_data[:, 0], m_data[:, 1], (xc, yc))
    verdicts, predicted, not_judged = measured_verdicts(run_dir, xc, yc, m_data[:, 0], m_data[:, 1])
    record = {
        "run": str(run_dir),
        "measured": str(measured_csv),
        "x_column": xc,
        "y_column": yc,
        "points_compared": int(c.x.size),
        "points_outside_prediction": c.dropped,
        "rms_error": c.rms_error,
        "max_error": c.max_error,
        "force_error_percent": c.force_error_percent,
        "stiffness_error_percent": c.stiffness_error_percent,
        "requirements_on_measured": [
            {
                **rec,
                "predicted": predicted.get(rec["name"], {}).get("verdict"),
                "predicted_value": predicted.get(rec["name"], {}).get("value"),
            }
            for rec in to_records(verdicts)
        ],
        "overall_on_measured": overall(verdicts) if verdicts else None,
        "not_judged_on_measured": list(not_judged),
    }
    files = {
        "compare.json": (json.dumps(record, indent=2, allow_nan=False) + "\n").encode(),
        "compare.png": _compare_png(px[keep], py[keep], c, xc, yc),
    }
    return CompareOutcome(c, xc, yc, files, verdicts, predicted, not_judged)


def measured_verdicts(
    run_dir: Path, x_column: str, y_column: str, x: np.ndarray, y: np.ndarray
) -> tuple[tuple[Any, ...], dict[str, dict[str, Any]], tuple[str, ...]]:
    """The run's requirements that read the curve ``y_column(x_column)`` judged on the measured
    points ``x``, ``y`` ((m,) each, the columns' units): the band verdict of the printed part.

    A requirement reads the curve when it judges a response (``needs_curve``: a target band,
    such as the constant-force kind's force band) of the quantity ``y_column`` over
    ``x_column``; it is judged exactly as the run judged the prediction, on the measured points
    alone (a measured curve that does not reach the band's ends is NOT MET, as a prediction
    would be). Requirements on scalars (peak stress, a solved stiffness) are not judged: a force
    curve does not measure them.

    Returns
    -------
    (verdicts, predicted, not_judged): the verdicts on the measured curve; the run's own
    verdict record of each by name (from best.json or evaluation.json); one line per
    requirement on another curve, or why none could be judged.
    """
    from flexopt.pipeline.run import design_study_of
    from flexopt.pipeline.verdict import study_requirements

    try:
        study, _, _ = design_study_of(run_dir, "best")
        requirements = study_requirements(study)
    except (FlexoptError, ValueError) as exc:
        return (), {}, (f"the run's requirements could not be read: {exc}",)
    keep = np.isfinite(x) & np.isfinite(y)
    curves = {y_column: (np.asarray(x, float)[keep], np.asarray(y, float)[keep])}
    verdicts, not_judged = [], []
    for req in requirements:
        if not req.needs_curve:
            continue
        if req.quantity == y_column and getattr(req, "x", x_column) == x_column:
            verdicts.append(req.check({}, curves))
        else:
            on = f"{req.quantity}({getattr(req, 'x', '?')})"
            not_judged.append(
                f"{req.label}: reads {on}, the measured curve is {y_column}({x_column})"
            )
    if not verdicts and not not_judged:
        not_judged.append(f"no requirement of the run reads the curve {y_column}({x_column})")
    predicted: dict[str, dict[str, Any]] = {}
    for name in ("best.json", "evaluation.json"):
        try:
            data = json.loads((run_dir / name).read_text(encoding="utf-8"))
            rows = data["verdict"]["requirements"]
            predicted = {str(r["name"]): dict(r) for r in rows if isinstance(r, dict)}
            break
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return tuple(verdicts), predicted, tuple(not_judged)


def _label(column: str) -> str:
    name, _, unit = column.rpartition("_")
    units = {"mm": "mm", "N": "N", "Nm": "N·m", "Nmm": "N·mm", "deg": "°", "rad": "rad"}
    if name and unit in units:
        return f"{name.replace('_', ' ').capitalize()} ({units[unit]})"
    return column.replace("_", " ")


def _compare_png(px: np.ndarray, py: np.ndarray, c: Any, xc: str, yc: str) -> bytes:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.plot(px, py, "-", label="predicted")
    ax.plot(c.x, c.measured, "o", ms=3, label="measured")
    ax.set_xlabel(_label(xc))
    ax.set_ylabel(_label(yc))
    ax.set_title(
        f"force error {c.force_error_percent:+.2f} %, stiffness error "
        f"{c.stiffness_error_percent:+.2f} %, RMS {c.rms_error:.3g}",
        fontsize=9,
    )
    ax.legend(fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


@dataclass(frozen=True)
class RetrimOutcome:
    """What :func:`retrim_run` computed: the width key, its old and new value and the study."""

    key: str
    old_mm: float
    new_mm: float
    scale: float
    study: Any
    comparison: Any


def retrim_run(run_dir: Path, measured_csv: Path, key: str | None = None) -> RetrimOutcome:
    """The run's design with its out-of-plane width (at study key ``key``, mm; default the
    kind's ``width_key``) scaled so the measured curve lands on the prediction
    (:func:`optimise.calibration.width_scale`).

    Raises
    ------
    CalibrationError
        As :func:`compare_run`, when ``key`` is not a number in the design's study, or when no
        ``key`` is given and the kind declares no width key.
    StudyError
        When the corrected value is refused by the study (outside its design range).
    """
    from flexopt.optimise.calibration import width_scale
    from flexopt.pipeline.run import design_study_of
    from flexopt.pipeline.study_edit import study_data

    cmp = compare_run(run_dir, measured_csv)
    study, _, _ = design_study_of(run_dir, "best")
    if key is None:
        from flexopt.pipeline.studies import get_kind

        key = get_kind(study.kind).width_key
        if callable(key):  # a width exact for some of the kind's studies only
            key = key(study)
        if key is None:
            raise CalibrationError(
                f"the {study.kind} kind declares no out-of-plane width that scales every force "
                "of this study (docs/print_to_part.md, section 4); give the study key to scale "
                "with --key"
            )
    node: Any = study_data(study)
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            raise CalibrationError(f"--key {key}: the design's study has no such key")
        node = node[part]
    if isinstance(node, bool) or not isinstance(node, int | float):
        raise CalibrationError(f"--key {key}: not a number in the design's study ({node!r})")
    scale = width_scale(cmp.comparison)
    new = float(node) * scale
    return RetrimOutcome(key, float(node), new, scale, study.with_values({key: new}), cmp)
