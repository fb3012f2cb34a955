"""Calibration of a material and a printer from a measured coupon curve (issue #26).

What is fitted
--------------
The coupon (:mod:`flexopt.fea.coupon`) has strips of several nominal thicknesses ``t_s``. Its
model is the geometrically exact cantilever of each strip, printed ``dt`` thicker than drawn, in a
material of modulus ``E``::

    F_model(d; E, dt, t_s) = E * f(d; t_s + dt)

where ``f`` is the force of the same strip with ``E = 1 MPa``: under displacement control the
deformed shape of an elastic beam does not depend on ``E``, so the force is exactly linear in it
(the ``E`` column of the Jacobian is ``f`` itself, no finite difference). ``(E, dt)`` minimise the
sum of squared force residuals over every measured point (nonlinear least squares,
``scipy.optimize.least_squares``, trust-region reflective, the ``dt`` column by central
differences of the nonlinear solve).

Confidence intervals
--------------------
From the Jacobian at the optimum, the usual linearised (asymptotic) covariance of nonlinear least
squares: ``cov = s^2 (J^T J)^-1`` with ``s^2 = RSS / (n - 2)``; the 95 % interval is
``+- t_{0.975, n-2} sqrt(diag cov)`` (Student's t). It assumes independent, equal-variance force
errors and a model that is right; systematic errors (a clamp that yields, friction at the drive)
are not in it — the residual curve shows them.

Refusals (never a silent fit)
-----------------------------
Too few points (fewer than ``MIN_POINTS_PER_STRIP`` per strip, or fewer than two strips of
different thickness), a displacement column that is not increasing within a strip, negative or
non-finite numbers, a curve whose force does not rise with the displacement, a fit that lands on a
bound or gives an ``E`` outside ``E_RANGE`` times the base material's (units wrong, wrong coupon),
or one the model cannot follow (RMS residual over ``MAX_RELATIVE_RMS`` of the force range): each
raises :class:`CalibrationError` naming what is wrong and how to fix it.

Units: mm, N, MPa.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from flexopt.fea.coupon import CouponSpec, strip_curve
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.optimise.errors import OptimiseError
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares
from scipy.stats import t as student_t

__all__ = [
    "CalibrationError",
    "CouponMeasurement",
    "CalibrationResult",
    "read_coupon_csv",
    "fit_coupon",
    "fit_coupons",
    "DirectionalModulus",
    "ORIENTATIONS",
    "MIN_POINTS_PER_STRIP",
    "MAX_RELATIVE_RMS",
    "E_RANGE",
    "CSV_COLUMNS",
    "write_materials_file",
    "CurveComparison",
    "compare_curves",
    "width_scale",
]

#: a strip needs this many measured points (beyond the origin) for its curve to count
MIN_POINTS_PER_STRIP = 5
#: the fit is refused when its RMS residual exceeds this share of the measured force range
MAX_RELATIVE_RMS = 0.05
#: a fitted E outside (lo, hi) x the base material's E means units or coupon are wrong
E_RANGE = (0.2, 5.0)
#: the thickness offset is searched in (lo, hi) x the thinnest strip
OFFSET_RANGE = (-0.6, 0.6)

CSV_COLUMNS = ("thickness_mm", "displacement_mm", "force_N")
#: the optional column naming each row's print orientation
ORIENTATION_COLUMN = "orientation"
#: print orientations of a coupon: its strips' long axis along the printer's x or y axis
ORIENTATIONS = ("x", "y")


class CalibrationError(OptimiseError):
    """Measured data that cannot be calibrated from; the message says what and how to fix it."""


@dataclass(frozen=True)
class CouponMeasurement:
    """Measured points of a coupon test.

    Attributes
    ----------
    thickness_mm : (n,) float, mm — the NOMINAL thickness of the strip each point belongs to.
    displacement_mm : (n,) float, mm — tip displacement.
    force_N : (n,) float, N — tip force.
    source : str — where the points come from (a file name).
    orientation : str — ``x`` or ``y``: the strips' long axis along the printer's x or y axis
        (the direction a part's beam printed that way has this E along); ``""`` when not given.
    """

    thickness_mm: np.ndarray
    displacement_mm: np.ndarray
    force_N: np.ndarray
    source: str = ""
    orientation: str = ""

    def strips(self) -> list[tuple[float, np.ndarray, np.ndarray]]:
        """``(nominal thickness, displacement (m,), force (m,))`` per strip, thinnest first."""
        out = []
        for t in sorted(set(self.thickness_mm.tolist())):
            sel = self.thickness_mm == t
            out.append((float(t), self.displacement_mm[sel], self.force_N[sel]))
        return out


@dataclass(frozen=True)
class DirectionalModulus:
    """E along one print orientation: ``orientation`` (``x``, ``y`` or ``""``), ``E_MPa`` and
    the half-width of its 95 % interval ``E_ci95_MPa`` (MPa)."""

    orientation: str
    E_MPa: float
    E_ci95_MPa: float


@dataclass(frozen=True)
class CalibrationResult:
    """A fitted material and thickness offset.

    Attributes
    ----------
    E_MPa, E_ci95_MPa : fitted Young's modulus and the half-width of its 95 % interval, MPa.
    offset_mm, offset_ci95_mm : printed minus drawn thickness and its 95 % half-width, mm.
    rms_N : RMS force residual, N.
    n_points : number of measured points used.
    correlation : correlation of the E and offset estimates (from the covariance).
    residual_N : (n,) float, N — model minus measured force at each point, in input order.
    model_N : (n,) float, N — the fitted model's force at each measured point.
    material : the calibrated :class:`Material` (the base's nu, allowable and density, fitted E).
    coupon : the coupon the data came from.
    base : name of the base material.
    moduli : E per print orientation when the tests name theirs (two for an anisotropic fit;
        ``E_MPa`` is then the first one's), else empty.
    anisotropy_ratio, anisotropy_ratio_ci95 : ``E_y / E_x`` (the second orientation's over the
        first's) and the half-width of its 95 % interval, for two orientations; else None.
    """

    E_MPa: float
    E_ci95_MPa: float
    offset_mm: float
    offset_ci95_mm: float
    rms_N: float
    n_points: int
    correlation: float
    residual_N: np.ndarray
    model_N: np.ndarray
    material: Material
    coupon: CouponSpec
    base: str
    notes: tuple[str, ...] = field(default_factory=tuple)
    moduli: tuple[DirectionalModulus, ...] = ()
    anisotropy_ratio: float | None = None
    anisotropy_ratio_ci95: float | None = None

    @property
    def anisotropic(self) -> bool:
        """E was fitted along two print orientations."""
        return len(self.moduli) > 1

    def record(self) -> dict[str, Any]:
        """The fit as plain data (for a materials file and a report), units in the keys."""
        out: dict[str, Any] = {}
        if self.moduli:
            out["E_by_orientation"] = {
                m.orientation: {"E_MPa": m.E_MPa, "E_ci95_MPa": m.E_ci95_MPa} for m in self.moduli
            }
        if self.anisotropy_ratio is not None:
            first, second = (m.orientation for m in self.moduli)
            out[f"E_{second}_over_E_{first}"] = self.anisotropy_ratio
            out[f"E_{second}_over_E_{first}_ci95"] = self.anisotropy_ratio_ci95
        if self.anisotropic:
            return {**out, **self._record()}
        return {"E_MPa": self.E_MPa, "E_ci95_MPa": self.E_ci95_MPa, **out, **self._record()}

    def _record(self) -> dict[str, Any]:
        return {
            "thickness_offset_mm": self.offset_mm,
            "thickness_offset_ci95_mm": self.offset_ci95_mm,
            "rms_residual_N": self.rms_N,
            "points": self.n_points,
            "correlation_E_offset": self.correlation,
            "base_material": self.base,
            "coupon": {
                "thicknesses_mm": list(self.coupon.thicknesses_mm),
                "length_mm": self.coupon.length_mm,
                "width_mm": self.coupon.width_mm,
            },
        }


def read_coupon_csv(text: str, source: str = "", orientation: str = "") -> CouponMeasurement:
    """Parse a coupon CSV with the columns ``thickness_mm, displacement_mm, force_N`` and,
    optionally, ``orientation`` (``x`` or ``y``, the same on every row: the strips' long axis
    along the printer's x or y axis); ``orientation`` gives it for a CSV without the column.

    Raises
    ------
    CalibrationError
        On a missing column (the message names the columns expected and found, e.g. a ``force_kN``
        column is refused with the unit to use), a non-number or a negative value, an orientation
        that is not x or y, two orientations in one file, or a column that contradicts
        ``orientation``.
    """
    where = source or "the measured CSV"
    reader = csv.DictReader(io.StringIO(text))
    header = [h.strip() for h in (reader.fieldnames or [])]
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        raise CalibrationError(
            f"{where}: missing column(s) {', '.join(missing)}; the columns are "
            f"{', '.join(CSV_COLUMNS)} (mm and N), found {', '.join(header) or 'none'}"
        )
    rows: list[tuple[float, float, float]] = []
    for line, row in enumerate(reader, start=2):
        try:
            values = tuple(float(row[c]) for c in CSV_COLUMNS)
        except (TypeError, ValueError):
            raise CalibrationError(
                f"{where}, line {line}: {', '.join(CSV_COLUMNS)} must be numbers"
            ) from None
        if not all(math.isfinite(v) for v in values):
            raise CalibrationError(f"{where}, line {line}: a value is not finite")
        rows.append(values)  # type: ignore[arg-type]
    if not rows:
        raise CalibrationError(f"{where}: no data rows")
    a = np.asarray(rows, dtype=float)
    return CouponMeasurement(
        a[:, 0], a[:, 1], a[:, 2], source=source, orientation=_orientation(text, where, orientation)
    )


def _orientation(text: str, where: str, given: str) -> str:
    """The one print orientation of a coupon CSV (``""`` when neither column nor ``given``)."""
    ok = " or ".join(ORIENTATIONS)
    given = given.strip().lower()
    if given and given not in ORIENTATIONS:
        raise CalibrationError(f"{where}: orientation '{given[:20]}' must be {ok}")
    reader = csv.DictReader(io.StringIO(text))
    header = [h.strip() for h in (reader.fieldnames or [])]
    if ORIENTATION_COLUMN not in header:
        return given
    key = (reader.fieldnames or [])[header.index(ORIENTATION_COLUMN)]
    found = {str(row.get(key) or "").strip().lower() for row in reader}
    bad = sorted(found - set(ORIENTATIONS))
    if bad:
        raise CalibrationError(
            f"{where}: column {ORIENTATION_COLUMN} has '{bad[0][:20]}'; each row's print "
            f"orientation is {ok} (the strips' long axis along the printer's x or y axis)"
        )
    if len(found) > 1:
        raise CalibrationError(
            f"{where}: rows of orientations {' and '.join(sorted(found))} in one file; give "
            "each orientation's test in its own CSV"
        )
    (value,) = found
    if given and given != value:
        raise CalibrationError(
            f"{where}: its {ORIENTATION_COLUMN} column says {value}, the command line {given}"
        )
    return value


def _check(measured: CouponMeasurement, spec: CouponSpec) -> None:
    where = measured.source or "the measured curve"
    strips = measured.strips()
    nominal = set(spec.thicknesses_mm)
    for t, d, f in strips:
        if not any(abs(t - n) <= 1e-6 for n in nominal):
            raise CalibrationError(
                f"{where}: thickness_mm {t:g} is not a strip of the coupon "
                f"({', '.join(f'{n:g}' for n in spec.thicknesses_mm)} mm)"
            )
        pts = int(np.count_nonzero(d > 0))
        if pts < MIN_POINTS_PER_STRIP:
            raise CalibrationError(
                f"{where}: strip {t:g} mm has {pts} point(s) with displacement > 0; record at "
                f"least {MIN_POINTS_PER_STRIP} over the stroke"
            )
        if np.any(np.diff(d) <= 0):
            raise CalibrationError(
                f"{where}: strip {t:g} mm: displacement_mm must increase from row to row (record "
                "the loading branch only, in order)"
            )
        if np.any(d < 0) or np.any(f < -1e-9 * max(1.0, float(np.max(np.abs(f))))):
            raise CalibrationError(
                f"{where}: strip {t:g} mm has negative displacement or force; push the tab in the "
                "positive direction and record magnitudes"
            )
        # the force of an elastic strip rises with displacement: a falling trend is a wrong column
        # order or a broken strip
        if f[-1] <= f[0] or np.corrcoef(d, f)[0, 1] < 0.9:
            raise CalibrationError(
                f"{where}: strip {t:g} mm: force_N does not rise with displacement_mm (columns "
                "swapped, a slipping clamp or a broken strip)"
            )
    if len(strips) < 2:
        raise CalibrationError(
            f"{where}: only one strip thickness; E and the thickness offset need at least two "
            "strips of different thickness (the coupon has "
            f"{', '.join(f'{n:g}' for n in spec.thicknesses_mm)} mm)"
        )


class _Model:
    """``f(d; t + dt)`` of every strip at the measured displacements (E = 1 MPa)."""

    def __init__(self, measured: CouponMeasurement, spec: CouponSpec, base: Material) -> None:
        self.spec = spec
        self.unit = Material("unit-E", 1.0, base.nu, 1.0)
        self.measured = measured
        self.strips = measured.strips()

    def f(self, offset_mm: float) -> np.ndarray:
        """(n,) force per MPa of E at each measured point, in input order."""
        out = np.empty_like(self.measured.force_N)
        for t, d, _ in self.strips:
            stroke = float(d[-1]) * 1.0001  # the spline must cover the last measured point
            c = strip_curve(self.spec, self.unit, t + offset_mm, stroke)
            spline = CubicSpline(c.displacement_mm, c.force_N)
            out[self.measured.thickness_mm == t] = spline(d)
        return out


def fit_coupon(measured: CouponMeasurement, spec: CouponSpec, base: Material) -> CalibrationResult:
    """Fit ``E`` and the thickness offset to a measured coupon (module docstring).

    Parameters
    ----------
    measured : the measured points (:func:`read_coupon_csv`).
    spec : the coupon that was printed and tested.
    base : the material the spool is sold as (its E is the start value; its nu, allowable and
        density are kept).

    Raises
    ------
    CalibrationError
        On data that cannot be calibrated from (module docstring).
    """
    return fit_coupons([(measured, spec)], base)


def fit_coupons(
    tests: Sequence[tuple[CouponMeasurement, CouponSpec]], base: Material
) -> CalibrationResult:
    """Fit one ``E`` per print orientation and one shared thickness offset to coupon tests.

    Each test is a measured coupon and the coupon it is (two orientations may be two prints of
    the same coupon, or two coupons). Tests with the same ``orientation`` share their E; the
    offset is the printer's, the same for every orientation. With one orientation this is
    :func:`fit_coupon`. With two (``x`` and ``y``: the strips' long axis along the printer's x
    or y axis), the in-plane anisotropy: ``E_x`` and ``E_y`` with their 95 % intervals, and the
    ratio ``E_y / E_x`` with its interval (linearised, from the same covariance).

    Model and intervals: the module docstring, with the parameters ``(E_1, ..., E_k, dt)``:
    ``F = E_o f_s(d; t + dt)`` for a point of orientation ``o``; ``cov = s^2 (J^T J)^-1`` with
    ``s^2 = RSS / (n - k - 1)``.

    Raises
    ------
    CalibrationError
        On data that cannot be calibrated from (module docstring), each test checked on its own;
        or tests of more than one orientation of which one has no orientation named.
    """
    if not tests:
        raise CalibrationError("no measured coupon curve given")
    labels = [m.orientation for m, _ in tests]
    if len(set(labels)) > 1 and not all(labels):
        raise CalibrationError(
            "coupon tests of several orientations need every test's orientation (x or y: the "
            "direction of the strips' long axis on the printer's bed)"
        )
    for measured, spec in tests:
        _check(measured, spec)
    rank = {o: i for i, o in enumerate(ORIENTATIONS)}
    orientations = sorted(set(labels), key=lambda o: (rank.get(o, len(rank)), o))  # x, then y
    where = ", ".join(dict.fromkeys(m.source or "the measured curve" for m, _ in tests))
    models = [_Model(m, spec, base) for m, spec in tests]
    group = np.concatenate(
        [np.full(m.force_N.size, orientations.index(m.orientation)) for m, _ in tests]
    )
    F = np.concatenate([m.force_N for m, _ in tests])
    k = len(orientations)
    t_min = min(min(spec.thicknesses_mm) for _, spec in tests)
    lo, hi = OFFSET_RANGE[0] * t_min, OFFSET_RANGE[1] * t_min
    cache: dict[float, np.ndarray] = {}

    def f_of(o: float) -> np.ndarray:
        """(n,) force per MPa of E of every point, tests in order, at offset ``o``."""
        if o not in cache:
            try:
                cache[o] = np.concatenate([model.f(o) for model in models])
            except FeaError as err:
                raise CalibrationError(
                    f"{where}: the coupon model failed at offset {o:g} mm: {err}"
                ) from err
        return cache[o]

    onehot = np.zeros((F.size, k))
    onehot[np.arange(F.size), group] = 1.0
    # E of each orientation for a given offset is linear least squares: the start values
    f0 = f_of(0.0)
    E0 = np.array(
        [
            float(f0[group == g] @ F[group == g] / (f0[group == g] @ f0[group == g]))
            for g in range(k)
        ]
    )
    scale_F = float(np.max(np.abs(F))) or 1.0

    def residual(x: np.ndarray) -> np.ndarray:
        E_pt = onehot @ (x[:k] * E0)
        return (E_pt * f_of(float(x[k])) - F) / scale_F

    def jac(x: np.ndarray) -> np.ndarray:
        o = float(x[k])
        h = 1e-4 * t_min
        df = (f_of(o + h) - f_of(o - h)) / (2.0 * h)
        E_pt = onehot @ (x[:k] * E0)
        return np.column_stack([onehot * (f_of(o)[:, None] * E0[None, :]), E_pt * df]) / scale_F

    sol = least_squares(
        residual,
        x0=np.array([*np.ones(k), 0.0]),
        jac=jac,
        bounds=([*np.full(k, 1e-6), lo], [*np.full(k, np.inf), hi]),
        x_scale=np.array([*np.ones(k), t_min]),
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        method="trf",
    )
    E = sol.x[:k] * E0
    offset = float(sol.x[k])
    if offset <= lo + 1e-6 * t_min or offset >= hi - 1e-6 * t_min:
        raise CalibrationError(
            f"{where}: the thickness offset ran to its bound ({offset:+.3f} mm); the strips' "
            "forces do not scale as (t + dt)^3 with one offset: check the nominal thickness_mm "
            "of each strip"
        )
    lo_E, hi_E = E_RANGE
    for label, value in zip(orientations, E, strict=True):
        if not lo_E * base.E_MPa < value < hi_E * base.E_MPa:
            along = f" along {label}" if label else ""
            raise CalibrationError(
                f"{where}: fitted E{along} = {value:.4g} MPa is {value / base.E_MPa:.3g} x "
                f"{base.name}'s {base.E_MPa:g} MPa: units wrong (force_N in N, displacement_mm "
                "in mm?) or not this coupon / material"
            )
    model_F = (onehot @ E) * f_of(offset)
    r = model_F - F
    n = F.size
    rss = float(r @ r)
    rms = math.sqrt(rss / n)
    for g, label in enumerate(orientations):
        sel = group == g
        force_range = float(np.max(F[sel]) - np.min(F[sel]))
        rms_g = math.sqrt(float(r[sel] @ r[sel]) / int(np.count_nonzero(sel)))
        if rms_g > MAX_RELATIVE_RMS * force_range:
            along = f" (orientation {label})" if label else ""
            raise CalibrationError(
                f"{where}{along}: the coupon model cannot follow the curve (RMS residual "
                f"{rms_g:.3g} N is {100 * rms_g / force_range:.1f} % of the force range, limit "
                f"{100 * MAX_RELATIVE_RMS:g} %): check the clamp, the drive and the columns"
            )
    # linearised covariance in physical units (module docstring)
    h = 1e-4 * t_min
    df = (f_of(offset + h) - f_of(offset - h)) / (2.0 * h)
    J = np.column_stack([onehot * f_of(offset)[:, None], (onehot @ E) * df])
    dof = max(n - (k + 1), 1)
    s2 = rss / dof
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        raise CalibrationError(
            f"{where}: E and the offset cannot be separated by these strips (singular Jacobian); "
            "test strips of more different thickness"
        ) from None
    q = float(student_t.ppf(0.975, dof))
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    corr = float(cov[0, k] / (sd[0] * sd[k])) if sd[0] > 0 and sd[k] > 0 else 0.0
    moduli = tuple(
        DirectionalModulus(label, float(E[g]), q * float(sd[g]))
        for g, label in enumerate(orientations)
    )
    ratio = ratio_ci = None
    if k == 2:
        # E_1 / E_0 and its linearised interval (gradient of the ratio through the covariance)
        ratio = float(E[1] / E[0])
        grad = np.zeros(k + 1)
        grad[0], grad[1] = -E[1] / E[0] ** 2, 1.0 / E[0]
        ratio_ci = q * math.sqrt(max(float(grad @ cov @ grad), 0.0))
    sources = ", ".join(dict.fromkeys(m.source or "a coupon test" for m, _ in tests))
    strips = sum(len(model.strips) for model in models)
    what = f"E along {' and '.join(orientations)} and the offset" if k > 1 else "E"
    material = Material(
        name=f"{base.name} (calibrated)",
        E_MPa=float(E[0]),
        nu=base.nu,
        yield_MPa=base.yield_MPa,
        density_kg_m3=base.density_kg_m3,
        source=(
            f"calibrated from {sources}: {what} fitted by nonlinear least squares on {n} points "
            f"of {strips} coupon strips; nu, allowable and density from {base.name} "
            f"({base.source})"
        ),
    )
    return CalibrationResult(
        E_MPa=float(E[0]),
        E_ci95_MPa=q * float(sd[0]),
        offset_mm=offset,
        offset_ci95_mm=q * float(sd[k]),
        rms_N=rms,
        n_points=n,
        correlation=corr,
        residual_N=r,
        model_N=model_F,
        material=material,
        coupon=tests[0][1],
        base=base.name,
        moduli=moduli if k > 1 or orientations[0] else (),
        anisotropy_ratio=ratio,
        anisotropy_ratio_ci95=ratio_ci,
    )


def write_materials_file(path: Path, name: str, result: CalibrationResult) -> None:
    """Add (or replace) material ``name`` in the YAML materials file ``path``, keeping the others.

    The entry holds what a study needs (``E_MPa``, or ``E_x_MPa`` and ``E_y_MPa`` for a fit
    in two print orientations; ``nu``, ``yield_MPa``, ``density_kg_m3``,
    ``thickness_offset_mm``) and the fit that produced it (``calibration``).
    """
    import yaml

    data: dict[str, Any] = {}
    if path.exists():
        loaded = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
        if not isinstance(loaded, dict):
            raise CalibrationError(f"{path}: not a materials file (a mapping of names)")
        data = loaded
    m = result.material
    if result.anisotropic:
        # E along each print orientation; a study names the one its beams are printed along
        # (``material: NAME@x``), so no single E_MPa is written (pipeline/materials_file.py)
        moduli = {f"E_{d.orientation}_MPa": float(d.E_MPa) for d in result.moduli}
    else:
        moduli = {"E_MPa": float(m.E_MPa)}
    data[name] = {
        **moduli,
        "nu": float(m.nu),
        "yield_MPa": float(m.yield_MPa),
        "density_kg_m3": None if math.isnan(m.density_kg_m3) else float(m.density_kg_m3),
        "thickness_offset_mm": float(result.offset_mm),
        "source": m.source,
        "calibration": result.record(),
    }
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    tmp.replace(path)


# -- compare a printed part with its prediction, and re-trim it ----------------------------------


@dataclass(frozen=True)
class CurveComparison:
    """A measured curve of a printed part against the prediction of its design.

    Attributes
    ----------
    x : (m,) float — the measured abscissae inside the predicted range (mm or rad).
    measured, predicted : (m,) float — the measured values and the prediction interpolated at
        ``x`` (N or N·mm).
    rms_error : float — RMS of measured minus predicted, same unit.
    max_error : float — largest |measured - predicted|, same unit.
    force_error_percent : float — the mean of measured / predicted - 1 over the points, in %
        (how much stronger or weaker the part is; the figure the literature quotes as "force
        error" for a constant-force part).
    stiffness_error_percent : float — (k_measured / k_predicted - 1) in %, with each k the least-
        squares slope through the origin over the compared range (the figure quoted for springs).
    dropped : int — measured points outside the predicted range (not compared).
    """

    x: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    rms_error: float
    max_error: float
    force_error_percent: float
    stiffness_error_percent: float
    dropped: int


def compare_curves(
    pred_x: np.ndarray,
    pred_y: np.ndarray,
    meas_x: np.ndarray,
    meas_y: np.ndarray,
    columns: tuple[str, str] | None = None,
) -> CurveComparison:
    """Compare a measured curve with a predicted one (:class:`CurveComparison`).

    Parameters
    ----------
    pred_x, pred_y : (n,) float — the prediction (e.g. ``displacement_mm``, ``force_N`` of
        best_response.csv), ``pred_x`` increasing.
    meas_x, meas_y : (m,) float — the measured points, same units.
    columns : (x, y) names with units (``displacement_mm``, ``force_N``; ``angle_deg``,
        ``torque_Nm``), named in a refusal; None: the refusal names no unit.

    Raises
    ------
    CalibrationError
        When fewer than ``MIN_POINTS_PER_STRIP`` measured points away from the unloaded state
        (x != 0: a drive may run to negative x) fall inside the predicted range, or the
        prediction's abscissa is not increasing.
    """
    px, py = np.asarray(pred_x, float), np.asarray(pred_y, float)
    mx, my = np.asarray(meas_x, float), np.asarray(meas_y, float)
    if px.ndim != 1 or px.shape != py.shape or np.any(np.diff(px) <= 0):
        raise CalibrationError("the predicted curve's abscissa must increase from row to row")
    if mx.shape != my.shape:
        raise CalibrationError("measured x and y must have the same length")
    inside = (mx >= px[0]) & (mx <= px[-1]) & np.isfinite(mx) & np.isfinite(my)
    # the unloaded point (x = 0) tells no error; every other one does, on either side of it
    loaded = int(np.count_nonzero(inside & (mx != 0)))
    if loaded < MIN_POINTS_PER_STRIP:
        units = f"{columns[0]}, {columns[1]}" if columns else "its columns' units"
        raise CalibrationError(
            f"only {loaded} measured point(s) away from x = 0 lie in the predicted range "
            f"{px[0]:g}..{px[-1]:g}; record at least {MIN_POINTS_PER_STRIP} over the stroke "
            f"(same units as the prediction: {units})"
        )
    x, y = mx[inside], my[inside]
    p = CubicSpline(px, py)(x)
    err = y - p
    nz = np.abs(p) > 1e-9 * max(float(np.max(np.abs(py))), 1e-300)
    k_meas = float(x @ y / (x @ x))
    k_pred = float(x @ p / (x @ x))
    return CurveComparison(
        x=x,
        measured=y,
        predicted=p,
        rms_error=float(np.sqrt(np.mean(err**2))),
        max_error=float(np.max(np.abs(err))),
        force_error_percent=float(100.0 * np.mean(y[nz] / p[nz] - 1.0)),
        stiffness_error_percent=float(100.0 * (k_meas / k_pred - 1.0)),
        dropped=int(np.count_nonzero(~inside)),
    )


def width_scale(comparison: CurveComparison) -> float:
    """The factor on the out-of-plane width that brings the measured curve onto the prediction.

    Every force of a planar part (beam or plane stress) is proportional to its out-of-plane width
    at a given in-plane motion (the section's A, I and the plane-stress thickness all scale with
    it, and the in-plane deformation does not change), so a part printed ``s`` times wider gives
    ``s`` times the measured force. ``s`` minimises ``sum (s y_i - p_i)^2``:
    ``s = <y, p> / <y, y>``. Exact when the print's error is a common factor on the forces (E, a
    uniform width error); a thickness error also changes the curve's shape, which a width cannot
    undo (the re-trimmed print is then measured again).
    """
    y, p = comparison.measured, comparison.predicted
    return float(y @ p / (y @ y))
