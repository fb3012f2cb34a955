"""``flexopt calibrate`` of a hold test: a Findley creep law fitted to a coupon held at a
displacement (relaxation) or under a force (creep), written into a material's ``creep:`` block.

The record is a CSV with two columns, units in the names:

- relaxation test: ``time_h, force_N`` — the force of the coupon held at a displacement, from
  the moment the displacement is reached (t = 0, or the first reading);
- creep test: ``time_h, displacement_mm`` — the deflection of the coupon under a held force.

The law is ``J(t) = (1 + (t/tau)^n) / E0`` (:mod:`fea.creep`): a relaxation record is fitted to
``F(t) = F0 E_n(-Gamma(1+n) (t/tau)^n)`` (:func:`fea.creep.fit_relaxation`), a creep record to
``d(t) = d0 (1 + (t/tau)^n)`` (:func:`fea.creep.fit_creep`); both give tau and n with 95 %
intervals (linearised least squares, Student's t on n - 3 degrees of freedom). The law holds
below the stress ratio of the test (``max_stress_ratio``: the coupon's peak stress over the
material's strength during the hold), which the user states: flexopt does not know the
coupon's stress from two columns.

The named material must already be in the materials file (``flexopt calibrate`` of its coupon
curve, or written by hand); its ``creep:`` block is replaced, keeping everything else, with the
data and the fit recorded under ``creep.fit``. A ``hold:`` study naming the material then uses
the law (docs/durability.md, Creep; docs/print_to_part.md).
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from flexopt.fea.creep import CreepFit, fit_creep, fit_relaxation
from flexopt.fea.errors import FeaError
from flexopt.optimise.calibration import CalibrationError

__all__ = ["HoldCalibration", "calibrate_hold", "is_hold_csv", "read_hold_csv"]

#: the value column of each test, by test
VALUE_COLUMNS = {"relaxation": "force_N", "creep": "displacement_mm"}
#: the fewest points a hold record must have (three parameters and their intervals)
MIN_POINTS = 6
#: a hold record is a few kB; a larger file is refused before it is parsed
MAX_BYTES = 1 << 20


@dataclass(frozen=True)
class HoldCalibration:
    """What :func:`calibrate_hold` did.

    Attributes
    ----------
    test : ``"relaxation"`` or ``"creep"``.
    fit : the Findley fit with its 95 % intervals.
    creep : the ``creep:`` block written (or that would be written).
    materials_path : the materials file written, or None.
    files : ``creep_fit.json`` (the block and the fit) by file name.
    """

    test: str
    fit: CreepFit
    creep: dict[str, Any]
    materials_path: Path | None
    files: dict[str, bytes]


def _rows(path: Path) -> list[list[str]]:
    try:
        if not path.is_file():
            raise CalibrationError(f"{path}: not a file")
        raw = path.read_bytes()[: MAX_BYTES + 1]
    except OSError as err:
        raise CalibrationError(f"{path}: cannot be read ({err.strerror or err})") from None
    if len(raw) > MAX_BYTES:
        raise CalibrationError(f"{path}: larger than {MAX_BYTES >> 10} KiB; not a hold record")
    try:
        text = raw.decode("utf-8-sig")
        return [r for r in csv.reader(io.StringIO(text)) if r and not r[0].startswith("#")]
    except (UnicodeDecodeError, csv.Error):
        raise CalibrationError(f"{path}: not a UTF-8 CSV file") from None


def is_hold_csv(path: Path) -> bool:
    """Whether ``path`` is a hold record (its header names a time column), not a coupon curve;
    False for a file that cannot be read (the coupon reader then says why)."""
    try:
        rows = _rows(path)
    except CalibrationError:
        return False
    return bool(rows) and any(h.strip().lower().startswith("time") for h in rows[0])


def read_hold_csv(path: Path) -> tuple[str, np.ndarray, np.ndarray]:
    """``(test, time_h, value)`` of a hold record: the test (``relaxation`` / ``creep``), the
    times (n_points,) h and the force (N) or displacement (mm) (n_points,).

    Raises
    ------
    CalibrationError
        One line naming the file and the fix: another time unit than hours, no force_N or
        displacement_mm column (or both), a cell that is not a number, fewer than
        :data:`MIN_POINTS` points, times not strictly increasing, a negative time, a value of
        changing sign or zero.
    """
    rows = _rows(path)
    if len(rows) < 2:
        raise CalibrationError(
            f"{path}: no data rows (columns time_h and force_N or displacement_mm)"
        )
    header = [h.strip() for h in rows[0]]
    times = [h for h in header if h.lower().startswith("time")]
    if times != ["time_h"]:
        found = ", ".join(times) or "none"
        raise CalibrationError(
            f"{path}: give the hold time in hours in one column named time_h (found {found})"
        )
    values = [c for c in VALUE_COLUMNS.values() if c in header]
    if len(values) != 1:
        others = [h for h in header if h != "time_h"]
        raise CalibrationError(
            f"{path}: give one of force_N (a relaxation test: the coupon held at a displacement) "
            f"or displacement_mm (a creep test: held at a force) beside time_h; found "
            f"{', '.join(others) or 'nothing'}"
        )
    test = next(k for k, c in VALUE_COLUMNS.items() if c == values[0])
    it, iv = header.index("time_h"), header.index(values[0])
    t, y = [], []
    for n, row in enumerate(rows[1:], start=2):
        try:
            t.append(float(row[it]))
            y.append(float(row[iv]))
        except (IndexError, ValueError):
            raise CalibrationError(
                f"{path}: row {n} has no number in time_h or {values[0]}"
            ) from None
    time_h, value = np.array(t), np.array(y)
    if time_h.size < MIN_POINTS:
        raise CalibrationError(
            f"{path}: {time_h.size} points; a hold record needs at least {MIN_POINTS} "
            "(three parameters and their intervals)"
        )
    if not (np.all(np.isfinite(time_h)) and np.all(np.isfinite(value))):
        raise CalibrationError(f"{path}: a time or value is not finite")
    if np.any(time_h < 0.0):
        raise CalibrationError(f"{path}: a negative time; time_h counts from the start of the hold")
    if np.any(np.diff(time_h) <= 0.0):
        k = int(np.argmax(np.diff(time_h) <= 0.0)) + 3
        raise CalibrationError(
            f"{path}: time_h is not strictly increasing (row {k}); give one reading per time, in "
            "order"
        )
    if not (np.all(value > 0.0) or np.all(value < 0.0)):
        raise CalibrationError(
            f"{path}: {values[0]} changes sign or is zero; a hold record keeps one sign"
        )
    return test, time_h, value


def calibrate_hold(
    measured_csv: Path,
    max_stress_ratio: float,
    name: str | None = None,
    materials_path: Path | None = None,
    temperature_C: float = 23.0,
    source: str | None = None,
) -> HoldCalibration:
    """Fit Findley's law to a hold record and write it into material ``name``'s ``creep:``.

    Parameters
    ----------
    measured_csv : the record (``time_h`` and ``force_N`` or ``displacement_mm``).
    max_stress_ratio : the coupon's peak stress over the material's strength during the test,
        in (0, 1]: the law's limit (a hold above it is judged out of range).
    name : the material in the materials file; nothing is written when None.
    materials_path : the materials file (default: ``materials.yaml`` beside the CSV).
    temperature_C : deg C, the test's temperature (the law's reference).
    source : words for the law's source (default: the file and the test).

    Raises
    ------
    CalibrationError
        Bad data (:func:`read_hold_csv`), a record that does not relax or creep, a stress ratio
        outside (0, 1], a material not in the materials file.
    """
    if not (isinstance(max_stress_ratio, int | float) and 0.0 < max_stress_ratio <= 1.0):
        raise CalibrationError(
            f"--stress-ratio {max_stress_ratio!r}: give the coupon's peak stress over the "
            "material's strength during the hold, in (0, 1]"
        )
    if not (math.isfinite(temperature_C) and -100.0 <= temperature_C <= 300.0):
        raise CalibrationError(f"--temperature {temperature_C!r}: give the test's temperature in C")
    test, t, y = read_hold_csv(measured_csv)
    try:
        fit = fit_relaxation(t, y) if test == "relaxation" else fit_creep(t, y)
    except FeaError as exc:
        raise CalibrationError(f"{measured_csv}: {str(exc).removeprefix('creep: ')}") from None
    unit = VALUE_COLUMNS[test].rsplit("_", 1)[1]
    words = source or (
        f"{test} test {measured_csv.name}, {t.size} points over {t.max():g} h at "
        f"{temperature_C:g} C, fitted by flexopt calibrate"
    )
    creep = {
        "tau_h": float(fit.tau_h),
        "n": float(fit.n),
        "max_stress_ratio": float(max_stress_ratio),
        "source": words,
        "reference_temperature_C": float(temperature_C),
        "fit": {
            "test": test,
            "method": (
                "F(t) = F0 E_n(-Gamma(1+n) (t/tau)^n)"
                if test == "relaxation"
                else "d(t) = d0 (1 + (t/tau)^n)"
            )
            + ", least squares; 95 % intervals linearised, Student's t on n - 3 dof",
            **fit.record(),
            "initial_unit": unit,
            "data": {"time_h": t.tolist(), VALUE_COLUMNS[test]: y.tolist()},
        },
    }
    from flexopt.optimise.hold import CreepSpec

    try:
        CreepSpec(**creep)
    except ValueError as exc:  # pydantic: a fitted n at its bound 1, a tau that is no time
        raise CalibrationError(f"{measured_csv}: the fit is no creep law ({exc})") from None
    written = None
    if name:
        written = materials_path or measured_csv.parent / "materials.yaml"
        _write_creep(written, name, creep)
    files = {"creep_fit.json": (json.dumps(creep, indent=2) + "\n").encode()}
    return HoldCalibration(test, fit, creep, written, files)


def _write_creep(path: Path, name: str, creep: dict[str, Any]) -> None:
    """Replace the ``creep:`` block of material ``name`` in the materials file ``path``,
    keeping every other key and material.

    Raises
    ------
    CalibrationError
        When the file is missing or not a mapping, or has no material ``name``.
    """
    import yaml
    from flexopt.pipeline.runfolder import write_atomic

    try:
        loaded = yaml.safe_load(path.read_text(encoding="utf-8")) if path.is_file() else None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise CalibrationError(f"{path}: cannot be read as a materials file ({exc})") from None
    if not isinstance(loaded, dict) or not isinstance(loaded.get(name), dict):
        raise CalibrationError(
            f"{path}: has no material '{name}'; calibrate its coupon first (flexopt calibrate "
            f"CURVE.csv --coupon COUPON --name {name}) or add it by hand, then its hold test"
        )
    loaded[name] = {**loaded[name], "creep": creep}
    # atomic (a reader sees the old file or the whole new one), as every file flexopt writes
    write_atomic(path, yaml.safe_dump(loaded, sort_keys=False))
