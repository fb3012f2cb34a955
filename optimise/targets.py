r"""Target curves: what a mechanism's response should be, and how far a response is from it.

A target is a curve ``y(x)`` of a driven quantity ``x`` (rotation, rad, or displacement, mm) to a
response ``y`` (torque, N·mm, or force, N) — project units throughout; the study file speaks
N·m and degrees and :class:`TargetSpec` converts at the door. Four kinds:

==============  ==========================================  ==================================
kind            curve                                        used by
==============  ==========================================  ==================================
``constant``    ``y = c``                                    constant-force mechanisms (003)
``linear``      ``y = y0 + k x``                             constant-stiffness springs (004)
``threshold``   ``y = y_max (1 - exp(-s x))``  (paper 000    the V2SOM safety profile: mode I
                Eq. 14), mode I/II split at 80 % of y_max    (stiff) below, mode II above
``table``       linear interpolation of ``(x_i, y_i)``       a measured or designed curve
==============  ==========================================  ==================================

Every curve gives its value, slope (stiffness) and work integral ``∫_0^x y dx`` (the strain
energy a spring must store, used by the cam synthesis of :mod:`geometry.cam`), vectorised over
arrays of ``x``. A response is scored against a target by :func:`curve_error` with one of the
:data:`MEASURES` (RMS, max absolute, max relative, ... over an optional window of ``x``),
vectorised over a batch of responses.

The curves are odd where that is what a spring does: ``threshold`` and ``linear`` (without
preload) are evaluated as ``sign(x) f(|x|)``, so a deflection to either side is covered.

This module takes values and returns values: reading a CSV file for a ``table`` target is the
pipeline's job (it hands the arrays to :meth:`TargetSpec.to_curve`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from flexopt.optimise.errors import OptimiseError
from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = [
    "MEASURES",
    "ConstantTarget",
    "LinearTarget",
    "TableTarget",
    "TargetCurve",
    "TargetSpec",
    "ThresholdTarget",
    "column_unit_factor",
    "curve_error",
    "measure_key",
]

Quantity = Literal["torque", "force"]

#: Column names of the driven and the response quantity, per quantity (project units).
AXIS_NAMES: dict[str, tuple[str, str]] = {
    "torque": ("rotation_rad", "torque_Nmm"),
    "force": ("displacement_mm", "force_N"),
}


def _as_array(x: Any) -> np.ndarray:
    return np.asarray(x, dtype=float)


# --------------------------------------------------------------------------------------------
# Curves


@dataclass(frozen=True)
class TargetCurve:
    """Base of the target curves (a frozen value; use a subclass).

    Attributes
    ----------
    quantity : {"torque", "force"}
        ``torque``: ``x`` is a rotation (rad) and ``y`` a torque (N·mm); ``force``: ``x`` is a
        displacement (mm) and ``y`` a force (N).
    """

    quantity: Quantity = "torque"

    @property
    def x_name(self) -> str:
        """Column name of ``x`` with its unit (``rotation_rad`` or ``displacement_mm``)."""
        return AXIS_NAMES[self.quantity][0]

    @property
    def y_name(self) -> str:
        """Column name of ``y`` with its unit (``torque_Nmm`` or ``force_N``)."""
        return AXIS_NAMES[self.quantity][1]

    @property
    def y_unit(self) -> str:
        """Unit of ``y`` as written in names (``Nmm`` or ``N``)."""
        return self.y_name.rsplit("_", 1)[1]

    def __call__(self, x: Any) -> np.ndarray:
        """Target value ``y(x)``; ``x`` any shape, result the same shape (y unit)."""
        raise NotImplementedError

    def slope(self, x: Any) -> np.ndarray:
        """``dy/dx`` (N·mm/rad or N/mm), same shape as ``x``."""
        raise NotImplementedError

    def work(self, x: Any) -> np.ndarray:
        """``∫_0^x y dx'`` (N·mm), same shape as ``x``: the energy a spring of this curve stores."""
        raise NotImplementedError


@dataclass(frozen=True)
class ConstantTarget(TargetCurve):
    """``y = level`` (a constant force or torque over the stroke).

    Attributes
    ----------
    level : float
        The value to hold (N or N·mm).
    """

    level: float = 0.0

    def __post_init__(self) -> None:
        if not math.isfinite(self.level):
            raise OptimiseError(f"constant target level = {self.level} must be a finite number")

    def __call__(self, x: Any) -> np.ndarray:
        return np.full_like(_as_array(x), self.level)

    def slope(self, x: Any) -> np.ndarray:
        return np.zeros_like(_as_array(x))

    def work(self, x: Any) -> np.ndarray:
        return self.level * _as_array(x)


@dataclass(frozen=True)
class LinearTarget(TargetCurve):
    """``y = preload sign(x) + stiffness x`` (a constant-stiffness spring, odd in ``x``).

    Attributes
    ----------
    stiffness : float
        N·mm/rad (torque) or N/mm (force); > 0.
    preload : float
        Value at ``x -> 0+`` (N·mm or N), default 0.
    """

    stiffness: float = 1.0
    preload: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.stiffness) and self.stiffness > 0):
            raise OptimiseError(
                f"linear target stiffness = {self.stiffness} must be > 0; give the spring rate"
            )
        if not math.isfinite(self.preload):
            raise OptimiseError(f"linear target preload = {self.preload} must be finite")

    def __call__(self, x: Any) -> np.ndarray:
        x = _as_array(x)
        return self.preload * np.sign(x) + self.stiffness * x

    def slope(self, x: Any) -> np.ndarray:
        return np.full_like(_as_array(x), self.stiffness)

    def work(self, x: Any) -> np.ndarray:
        x = _as_array(x)
        return self.preload * np.abs(x) + 0.5 * self.stiffness * x**2


@dataclass(frozen=True)
class ThresholdTarget(TargetCurve):
    r"""The threshold profile of paper 000, Eq. 14: ``y = y_max (1 - exp(-s x))`` (odd in ``x``).

    Stiff near zero (slope ``y_max s``), it levels off at ``y_max``: mode I (normal work) while
    ``y < split y_max``, mode II (shock absorbing) beyond. The paper puts the split at 80 %.

    Attributes
    ----------
    max_value : float
        ``T_max`` (N·mm) or ``F_max`` (N); > 0.
    rate : float
        ``s``, 1/rad (torque) or 1/mm (force); > 0.
    split : float
        Mode I/II boundary as a fraction of ``max_value``, in (0, 1); default 0.8.
    """

    max_value: float = 1.0
    rate: float = 1.0
    split: float = 0.8

    def __post_init__(self) -> None:
        if not (math.isfinite(self.max_value) and self.max_value > 0):
            raise OptimiseError(f"threshold max_value = {self.max_value} must be > 0")
        if not (math.isfinite(self.rate) and self.rate > 0):
            raise OptimiseError(f"threshold rate s = {self.rate} must be > 0 (paper: s = 50 /rad)")
        if not 0 < self.split < 1:
            raise OptimiseError(
                f"threshold split = {self.split} must lie in (0, 1); the paper uses 0.8 (T1 = 80 % "
                "of Tmax)"
            )

    def __call__(self, x: Any) -> np.ndarray:
        x = _as_array(x)
        return np.sign(x) * self.max_value * -np.expm1(-self.rate * np.abs(x))

    def slope(self, x: Any) -> np.ndarray:
        return self.max_value * self.rate * np.exp(-self.rate * np.abs(_as_array(x)))

    def work(self, x: Any) -> np.ndarray:
        # y_max (x - (1 - e^{-sx})/s) cancels badly for s x << 1 (both terms ~ x): below 1e-3 use
        # the series y_max s x^2/2 (1 - sx/3 + (sx)^2/12), exact to 1e-13 relative there.
        ax = np.abs(_as_array(x))
        z = self.rate * ax
        small = z < 1e-3
        exact = ax + np.expm1(-z) / self.rate
        series = 0.5 * self.rate * ax**2 * (1.0 - z / 3.0 + z**2 / 12.0)
        return self.max_value * np.where(small, series, exact)

    @property
    def split_x(self) -> float:
        """Deflection at the mode I/II boundary, ``-ln(1 - split)/s`` (ln 5/s for 80 %)."""
        return -math.log1p(-self.split) / self.rate

    @property
    def split_y(self) -> float:
        """Value at the mode boundary, ``split * max_value`` (T1 = 0.8 Tmax)."""
        return self.split * self.max_value

    @property
    def equivalent_stiffness(self) -> float:
        """The constant stiffness with the same deflection at the split (the paper's CS spring,
        Sec. 4.3): ``split y_max / split_x``."""
        return self.split_y / self.split_x

    def mode(self, x: Any) -> np.ndarray:
        """1 (mode I, ``|x| <= split_x``) or 2 (mode II), as int, same shape as ``x``."""
        return np.where(np.abs(_as_array(x)) <= self.split_x, 1, 2)

    def inverse(self, y: Any) -> np.ndarray:
        """``x`` at which the curve reaches ``y`` (``|y| < max_value``), odd."""
        y = _as_array(y)
        ratio = np.abs(y) / self.max_value
        if np.any(ratio >= 1):
            raise OptimiseError(
                f"threshold inverse: |y| = {np.max(np.abs(y)):g} reaches max_value = "
                f"{self.max_value:g}, which the curve only approaches; ask for less"
            )
        return np.sign(y) * -np.log1p(-ratio) / self.rate


@dataclass(frozen=True, eq=False)
class TableTarget(TargetCurve):
    """A tabulated curve, linear between its points; ``x`` strictly increasing.

    Outside ``[x[0], x[-1]]`` the curve is not defined: :meth:`__call__` raises rather than
    extrapolate (score a response only where the table is; see ``window`` of
    :func:`curve_error`).

    Attributes
    ----------
    x : (n,) float
        Driven quantity (rad or mm), strictly increasing, n >= 2.
    y : (n,) float
        Response (N·mm or N).
    """

    x: np.ndarray = field(default_factory=lambda: np.zeros(0))
    y: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        x = np.array(self.x, dtype=float).ravel()
        y = np.array(self.y, dtype=float).ravel()
        if x.size < 2 or x.shape != y.shape:
            raise OptimiseError(
                f"a table target needs at least 2 points and as many y as x values; got "
                f"{x.size} x and {y.size} y"
            )
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
            raise OptimiseError("a table target has a NaN or infinite value; clean the table")
        bad = np.flatnonzero(np.diff(x) <= 0)
        if bad.size:
            i = int(bad[0])
            raise OptimiseError(
                f"table x must be strictly increasing but x[{i}] = {x[i]:g} >= x[{i + 1}] = "
                f"{x[i + 1]:g}; sort the rows and drop repeated x"
            )
        x.setflags(write=False)
        y.setflags(write=False)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)

    def _check_range(self, x: np.ndarray) -> None:
        lo, hi = self.x[0], self.x[-1]
        tol = 1e-12 * max(1.0, abs(lo), abs(hi))
        if x.size and (np.min(x) < lo - tol or np.max(x) > hi + tol):
            raise OptimiseError(
                f"table target asked at x in [{np.min(x):g}, {np.max(x):g}] but the table covers "
                f"[{lo:g}, {hi:g}] ({self.x_name}); extend the table or narrow the window"
            )

    def __call__(self, x: Any) -> np.ndarray:
        x = _as_array(x)
        self._check_range(x)
        return np.interp(x, self.x, self.y)

    def slope(self, x: Any) -> np.ndarray:
        x = _as_array(x)
        self._check_range(x)
        k = np.clip(np.searchsorted(self.x, x, side="right") - 1, 0, self.x.size - 2)
        return (self.y[k + 1] - self.y[k]) / (self.x[k + 1] - self.x[k])

    def work(self, x: Any) -> np.ndarray:
        """``∫_0^x y`` (0 must lie in the table's range)."""
        x = _as_array(x)
        self._check_range(np.append(x.ravel(), 0.0))
        # cumulative trapezoid from x[0], then subtract the value at 0: exact for the
        # piecewise-linear curve (the integral of a linear segment is its trapezoid).
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (self.y[1:] + self.y[:-1]) * np.diff(self.x))])

        def primitive(u: np.ndarray) -> np.ndarray:
            k = np.clip(np.searchsorted(self.x, u, side="right") - 1, 0, self.x.size - 2)
            x0 = self.x[k]
            y0 = self.y[k]
            yu = np.interp(u, self.x, self.y)
            return cum[k] + 0.5 * (y0 + yu) * (u - x0)

        return primitive(x) - primitive(np.zeros(()))


# --------------------------------------------------------------------------------------------
# Error measures


def _window_mask(x: np.ndarray, window: tuple[float, float] | None) -> np.ndarray:
    if window is None:
        return np.ones(x.shape, dtype=bool)
    lo, hi = window
    if not lo < hi:
        raise OptimiseError(
            f"window ({lo:g}, {hi:g}) is empty; give (lower, upper) with lower < upper"
        )
    return (x >= lo) & (x <= hi)


def _nonzero(t: np.ndarray, what: str) -> np.ndarray:
    if np.any(t == 0):
        raise OptimiseError(
            f"{what} divides by the target, which is 0 inside the window (e.g. at x = 0 of a "
            "spring curve); start the window above 0, or use a *_normalised measure"
        )
    return t


def _rms(e: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(e**2, axis=-1))


def _max_abs(e: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.max(np.abs(e), axis=-1)


def _rms_relative(e: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean((e / _nonzero(t, "rms_relative")) ** 2, axis=-1))


def _max_relative(e: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.max(np.abs(e / _nonzero(t, "max_relative")), axis=-1)


def _scale(t: np.ndarray) -> np.ndarray:
    scale = np.max(np.abs(t), axis=-1)
    if np.any(scale == 0):
        raise OptimiseError("a *_normalised measure needs a target that is not 0 everywhere")
    return scale


def _rms_normalised(e: np.ndarray, t: np.ndarray) -> np.ndarray:
    return _rms(e, t) / _scale(t)


def _max_normalised(e: np.ndarray, t: np.ndarray) -> np.ndarray:
    return _max_abs(e, t) / _scale(t)


#: Error measures by name: ``f(error, target) -> value`` over the last axis. ``rms`` and
#: ``max_abs`` are in the unit of ``y``; the others are fractions (0.02 = 2 %). ``*_relative``
#: divides point by point by the target (undefined where it is 0); ``*_normalised`` divides by the
#: largest |target| in the window (defined for spring curves through 0).
MEASURES: dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]] = {
    "rms": _rms,
    "max_abs": _max_abs,
    "rms_relative": _rms_relative,
    "max_relative": _max_relative,
    "rms_normalised": _rms_normalised,
    "max_normalised": _max_normalised,
}

Measure = Literal[
    "rms", "max_abs", "rms_relative", "max_relative", "rms_normalised", "max_normalised"
]


def measure_key(measure: str, curve: TargetCurve) -> str:
    """Name of a measure's value with its unit: ``rms_error_N``, ``max_relative_error``, ..."""
    if measure in ("rms", "max_abs"):
        return f"{measure}_error_{curve.y_unit}"
    return f"{measure}_error"


def curve_error(
    curve: TargetCurve,
    x: Any,
    y: Any,
    measure: str = "rms",
    window: tuple[float, float] | None = None,
) -> np.ndarray | float:
    """How far a response ``y(x)`` is from the target, by one of :data:`MEASURES`.

    Parameters
    ----------
    curve : TargetCurve
    x : (n,) float
        Driven quantity of the response rows (rad or mm, the curve's ``x_name``).
    y : (..., n) float
        Response at ``x`` (N·mm or N); leading axes are a batch of responses.
    measure : str
        A key of :data:`MEASURES`.
    window : (float, float), optional
        Only rows with ``window[0] <= x <= window[1]`` count (same unit as ``x``).

    Returns
    -------
    float or (...,) float
        The measure per response (y unit for ``rms``/``max_abs``, a fraction otherwise).

    Raises
    ------
    OptimiseError
        For an unknown measure, shapes that do not match, an empty window, or a relative
        measure where the target is 0.
    """
    if measure not in MEASURES:
        raise OptimiseError(f"unknown error measure '{measure}'; use one of {', '.join(MEASURES)}")
    x = _as_array(x)
    y = _as_array(y)
    if x.ndim != 1 or y.shape[-1:] != x.shape:
        raise OptimiseError(
            f"x has shape {x.shape} and y {y.shape}; y needs (..., {x.size}) values, one per x"
        )
    mask = _window_mask(x, window)
    if not mask.any():
        raise OptimiseError(
            f"no response row lies in the window {window} ({curve.x_name}); widen the window"
        )
    t = curve(x[mask])
    value = MEASURES[measure](y[..., mask] - t, np.broadcast_to(t, y[..., mask].shape))
    return float(value) if np.ndim(value) == 0 else value


# --------------------------------------------------------------------------------------------
# The study-file spec

#: Factors from a unit suffix of a column/key name to project units (rad, mm, N·mm, N).
_UNIT_FACTORS: dict[str, tuple[str, float]] = {
    "deg": ("x", math.pi / 180.0),
    "rad": ("x", 1.0),
    "mm": ("x", 1.0),
    "m": ("x", 1000.0),
    "Nm": ("y", 1000.0),
    "Nmm": ("y", 1.0),
    "N": ("y", 1.0),
}
_X_QUANTITY = {"deg": "torque", "rad": "torque", "mm": "force", "m": "force"}
_Y_QUANTITY = {"Nm": "torque", "Nmm": "torque", "N": "force"}


def column_unit_factor(name: str) -> tuple[str, str, float]:
    """``(axis, quantity, factor)`` of a column name by its unit suffix.

    ``rotation_deg`` -> ``("x", "torque", pi/180)``; ``torque_Nm`` -> ``("y", "torque", 1000)``;
    ``force_N`` -> ``("y", "force", 1)``. The factor converts to project units.

    Raises
    ------
    OptimiseError
        When the name does not end in one of ``_deg _rad _mm _m _Nm _Nmm _N``.
    """
    suffix = name.rsplit("_", 1)[-1] if "_" in name else ""
    if suffix not in _UNIT_FACTORS:
        raise OptimiseError(
            f"column '{name}' has no unit suffix; name it like rotation_deg, rotation_rad, "
            "displacement_mm, torque_Nm, torque_Nmm or force_N"
        )
    axis, factor = _UNIT_FACTORS[suffix]
    quantity = _X_QUANTITY.get(suffix) or _Y_QUANTITY[suffix]
    return axis, quantity, factor


_SPEC_CONFIG = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

#: The keys each kind needs (one of each tuple) and allows.
_KIND_KEYS: dict[str, tuple[tuple[str, ...], ...]] = {
    "constant": (("force_N", "torque_Nm"),),
    "linear": (("stiffness_N_per_mm", "stiffness_Nm_per_rad"),),
    "threshold": (("max_torque_Nm", "max_force_N"), ("rate_per_rad", "rate_per_mm")),
    "table": (("points", "file"),),
}
_KIND_OPTIONAL: dict[str, tuple[str, ...]] = {
    "constant": (),
    "linear": ("preload_N", "preload_Nm"),
    "threshold": ("split",),
    "table": ("columns",),
}
_VALUE_KEYS = (
    "force_N",
    "torque_Nm",
    "stiffness_N_per_mm",
    "stiffness_Nm_per_rad",
    "preload_N",
    "preload_Nm",
    "max_torque_Nm",
    "max_force_N",
    "rate_per_rad",
    "rate_per_mm",
    "split",
    "points",
    "file",
    "columns",
)
_TORQUE_KEYS = {
    "torque_Nm",
    "stiffness_Nm_per_rad",
    "preload_Nm",
    "max_torque_Nm",
    "rate_per_rad",
}
_FORCE_KEYS = {"force_N", "stiffness_N_per_mm", "preload_N", "max_force_N", "rate_per_mm"}


class TargetSpec(BaseModel):
    """The ``target:`` block a study kind embeds (units in the key names, N·m and degrees).

    Examples (YAML)::

        target: {kind: threshold, max_torque_Nm: 2.05, rate_per_rad: 50}      # paper 000, Eq. 14
        target: {kind: linear, stiffness_Nm_per_rad: 276}
        target: {kind: constant, force_N: 1.5, measure: max_relative, window_mm: [5, 25]}
        target: {kind: table, file: spring.csv, columns: [rotation_deg, torque_Nm]}
        target: {kind: table, columns: [rotation_deg, torque_Nm], points: [[0, 0], [10, 5]]}

    A torque target (keys in N·m, per rad) is a torque–rotation curve; a force target (N, per mm)
    a force–displacement curve. ``window_deg`` / ``window_mm`` and ``measure`` say how a response
    is scored (:func:`curve_error`).
    """

    model_config = _SPEC_CONFIG

    kind: Literal["constant", "linear", "threshold", "table"] = Field(
        description="constant, linear, threshold (T = Tmax (1 - exp(-s x))) or table"
    )
    force_N: float | None = Field(None, description="constant: the force to hold, N")
    torque_Nm: float | None = Field(None, description="constant: the torque to hold, N·m")
    stiffness_N_per_mm: float | None = Field(None, gt=0, description="linear: N/mm")
    stiffness_Nm_per_rad: float | None = Field(None, gt=0, description="linear: N·m/rad")
    preload_N: float | None = Field(None, description="linear: force at 0+, N")
    preload_Nm: float | None = Field(None, description="linear: torque at 0+, N·m")
    max_torque_Nm: float | None = Field(None, gt=0, description="threshold: Tmax, N·m")
    max_force_N: float | None = Field(None, gt=0, description="threshold: Fmax, N")
    rate_per_rad: float | None = Field(None, gt=0, description="threshold: s, 1/rad")
    rate_per_mm: float | None = Field(None, gt=0, description="threshold: s, 1/mm")
    split: float | None = Field(
        None, gt=0, lt=1, description="threshold: mode I/II split, fraction of Tmax (0.8)"
    )
    file: str | None = Field(None, description="table: CSV file with a header row")
    columns: tuple[str, str] | None = Field(
        None,
        description="table: [x column, y column] with units in the names, e.g. "
        "[rotation_deg, torque_Nm] (default: the file's first two columns)",
    )
    points: tuple[tuple[float, float], ...] | None = Field(
        None, min_length=2, description="table: [[x, y], ...] in the units of columns"
    )
    measure: Measure = Field(
        "rms",
        description="error measure: rms, max_abs, rms_relative, max_relative, rms_normalised, "
        "max_normalised",
    )
    window_deg: tuple[float, float] | None = Field(
        None, description="score only rotations in [lower, upper], degrees"
    )
    window_mm: tuple[float, float] | None = Field(
        None, description="score only displacements in [lower, upper], mm"
    )

    @model_validator(mode="after")
    def _keys_fit_the_kind(self) -> TargetSpec:
        given = {k for k in _VALUE_KEYS if getattr(self, k) is not None}
        allowed = {k for group in _KIND_KEYS[self.kind] for k in group}
        allowed |= set(_KIND_OPTIONAL[self.kind])
        extra = sorted(given - allowed)
        if extra:
            raise ValueError(
                f"kind: {self.kind} does not use {', '.join(extra)}; it takes "
                f"{', '.join(sorted(allowed))}"
            )
        for group in _KIND_KEYS[self.kind]:
            present = [k for k in group if k in given]
            if len(present) != 1:
                what = "needs one of" if not present else "takes only one of"
                raise ValueError(f"kind: {self.kind} {what} {', '.join(group)}")
        if self.kind != "table":
            torque = given & _TORQUE_KEYS
            force = given & _FORCE_KEYS
            if torque and force:
                raise ValueError(
                    f"mixes torque keys ({', '.join(sorted(torque))}) with force keys "
                    f"({', '.join(sorted(force))}); a target is either torque-rotation (N·m, "
                    "per rad) or force-displacement (N, per mm)"
                )
        if self.kind == "table":
            if self.points is not None and self.columns is None:
                raise ValueError(
                    "points need columns naming their units, e.g. columns: [rotation_deg, "
                    "torque_Nm]"
                )
            if self.columns is not None:
                for name in self.columns:
                    try:
                        column_unit_factor(name)
                    except OptimiseError as exc:
                        raise ValueError(str(exc)) from None
                xa, xq, _ = column_unit_factor(self.columns[0])
                ya, yq, _ = column_unit_factor(self.columns[1])
                if (xa, ya) != ("x", "y") or xq != yq:
                    raise ValueError(
                        f"columns {list(self.columns)} must be [x, y] of one quantity: "
                        "[rotation_deg|rotation_rad, torque_Nm|torque_Nmm] or "
                        "[displacement_mm, force_N]"
                    )
        if self.window_deg is not None and self.window_mm is not None:
            raise ValueError("give window_deg (rotation) or window_mm (displacement), not both")
        for key in ("window_deg", "window_mm"):
            window = getattr(self, key)
            if window is not None and not window[0] < window[1]:
                raise ValueError(
                    f"{key} = {list(window)} must be [lower, upper] with lower < upper"
                )
        if self.quantity is not None:
            wrong = "window_mm" if self.quantity == "torque" else "window_deg"
            if getattr(self, wrong) is not None:
                right = "window_deg" if wrong == "window_mm" else "window_mm"
                raise ValueError(f"a {self.quantity} target is windowed by {right}, not {wrong}")
        return self

    @property
    def quantity(self) -> Quantity | None:
        """``torque`` or ``force`` (None for a table whose columns come from its file)."""
        if self.kind == "table":
            if self.columns is None:
                return None
            return column_unit_factor(self.columns[0])[1]  # type: ignore[return-value]
        given = {k for k in _VALUE_KEYS if getattr(self, k) is not None}
        return "torque" if given & _TORQUE_KEYS else "force"

    @property
    def window(self) -> tuple[float, float] | None:
        """The scoring window in project units (rad or mm), or None."""
        if self.window_deg is not None:
            return (math.radians(self.window_deg[0]), math.radians(self.window_deg[1]))
        return self.window_mm

    def to_curve(
        self,
        table: tuple[np.ndarray, np.ndarray] | None = None,
        columns: tuple[str, str] | None = None,
    ) -> TargetCurve:
        """The target curve in project units.

        Parameters
        ----------
        table : ((n,) float, (n,) float), optional
            For ``kind: table`` with ``file``: the two columns as read (in the units of their
            names). Inline ``points`` need nothing.
        columns : (str, str), optional
            Names of the columns read, when ``columns`` was not given in the spec.

        Raises
        ------
        OptimiseError
            For a file table without its arrays, or values a curve refuses.
        """
        k = self.kind
        if k == "constant":
            if self.torque_Nm is not None:
                return ConstantTarget("torque", self.torque_Nm * 1000.0)
            return ConstantTarget("force", float(self.force_N))  # type: ignore[arg-type]
        if k == "linear":
            if self.stiffness_Nm_per_rad is not None:
                return LinearTarget(
                    "torque", self.stiffness_Nm_per_rad * 1000.0, (self.preload_Nm or 0.0) * 1e3
                )
            return LinearTarget(
                "force",
                float(self.stiffness_N_per_mm),  # type: ignore[arg-type]
                self.preload_N or 0.0,
            )
        if k == "threshold":
            split = 0.8 if self.split is None else self.split
            if self.max_torque_Nm is not None:
                if self.rate_per_rad is None:
                    raise OptimiseError("a torque threshold needs rate_per_rad (s, 1/rad)")
                return ThresholdTarget(
                    "torque", self.max_torque_Nm * 1000.0, self.rate_per_rad, split
                )
            if self.rate_per_mm is None:
                raise OptimiseError("a force threshold needs rate_per_mm (s, 1/mm)")
            return ThresholdTarget("force", float(self.max_force_N), self.rate_per_mm, split)  # type: ignore[arg-type]
        names = self.columns or columns
        if self.points is not None:
            arr = np.asarray(self.points, dtype=float)
            xs, ys = arr[:, 0], arr[:, 1]
        elif table is not None:
            xs, ys = (np.asarray(c, dtype=float) for c in table)
        else:
            raise OptimiseError(
                f"table target from file '{self.file}': read the file first and pass its columns "
                "as table=(x, y)"
            )
        if names is None:
            raise OptimiseError("a table target needs the names of its columns (with units)")
        _, quantity, fx = column_unit_factor(names[0])
        _, _, fy = column_unit_factor(names[1])
        return TableTarget(quantity, xs * fx, ys * fy)  # type: ignore[arg-type]
