r"""Requirements of a design, separate from its objectives, and the verdict on each.

A study states what its design must meet; every evaluation is then judged against each
requirement with one word, **MET** or **NOT MET**, its value, its bound and its margin. Being
*feasible* (every optimiser constraint ``g <= 0``) is not the same thing: a constraint may be
missing, or the objective may be only minimised (an RMS error of 1.2 N is a fine minimum of a
5 N target that ends at 3.8 N); the verdict is what says whether the design does its job.

API (stable; other modules and kinds build on it)
-------------------------------------------------
:class:`Verdict`
    ``name, quantity, value, bound, margin, margin_rel, met, unit, role, detail``; ``margin`` is
    positive when met, in the quantity's unit (``margin_rel`` a fraction of the bound's scale,
    None where there is none); ``bound`` is human text with the unit (``<= 42.5 MPa``).
:class:`Requirement` and its kinds
    :class:`MaxValue`, :class:`MinValue`, :class:`Range`, :class:`AllowableStress` (yield over a
    safety factor), :class:`TargetBand` (a curve ``y(x)`` within a tolerance band of a target
    curve of :mod:`optimise.targets` over an x-range), :class:`Envelope` (bounding box within
    ``w x h``), :class:`MinFeature`, :class:`Flag` (a yes/no metric such as ``stable``),
    :class:`DesignRange` (every design variable inside its stated range). Each
    has ``check(metrics, curves) -> Verdict`` and ``constraint(metrics, curves) -> float`` (a
    ``g <= 0`` row, dimensionless: ``-margin / scale``).

    ``metrics`` maps quantity names (units in the names: ``max_peak_stress_MPa``) to floats
    (bools for :class:`Flag`; None or a missing key is "not computed" and NOT MET). ``curves``
    maps a response quantity (``force_N``) to ``(x, y)``, two (n,) arrays: ``x`` in the unit of
    the requirement's ``x`` column, ``y`` in the quantity's unit; :func:`curves_from_table`
    builds it from a response table.
:class:`Figure` and :func:`judge_best`
    A quantity may have several figures, one per model (the beam's peak stress, the
    plane-stress check's, the 3D solid's): ``judge_best`` judges a requirement on the
    highest-ranked figure the design has and names the model in the verdict (``model``,
    ``figures``, ``detail``), the lower-fidelity figures beside it.
:func:`verdict_lines`, :func:`overall`, :func:`to_records`, :func:`verdict_record`
    Console / Markdown lines, the overall word (MET only when there is at least one requirement
    and every one is met), JSON records.
:class:`RequirementSpec`
    One item of a study's ``requirements:`` list (pydantic, units in the keys), turned into a
    requirement by :meth:`RequirementSpec.to_requirement`.

Everything here takes values and returns values; which names a study kind reports, and reading
a target table from CSV, are the pipeline's business.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any, Literal

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.names import NAME_MAX_CHARS, check_name
from flexopt.optimise.robust_requirements import RobustShareSpec
from flexopt.optimise.targets import TargetCurve, TargetSpec, column_unit_factor
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    field_validator,
    model_serializer,
    model_validator,
)

__all__ = [
    "AllowableStress",
    "BEAM",
    "DesignRange",
    "Envelope",
    "Figure",
    "Flag",
    "MaxValue",
    "MinFeature",
    "MinValue",
    "PLANE_STRESS",
    "Range",
    "Requirement",
    "RequirementSpec",
    "SOLID_3D",
    "TargetBand",
    "Verdict",
    "curves_from_table",
    "judge_best",
    "overall",
    "to_records",
    "unit_of",
    "verdict_lines",
    "verdict_record",
]

Role = Literal["constraint", "check"]

#: Constraint value of a requirement whose quantity was not computed (finite: pymoo ranks by it).
MISSING_CONSTRAINT = 1.0e6

#: Unit suffixes of quantity names and how they read (longest first).
_UNITS: tuple[tuple[str, str], ...] = (
    ("_Nm_per_rad", "N·m/rad"),
    ("_Nmm_per_rad", "N·mm/rad"),
    ("_N_per_mm", "N/mm"),
    ("_per_rad", "1/rad"),
    ("_per_mm", "1/mm"),
    ("_kg_m3", "kg/m³"),
    ("_percent", "%"),
    ("_MPa", "MPa"),
    ("_Nmm", "N·mm"),
    ("_Nm", "N·m"),
    ("_mm3", "mm³"),
    ("_mm2", "mm²"),
    ("_mm", "mm"),
    ("_deg", "deg"),
    ("_rad", "rad"),
    ("_Hz", "Hz"),
    ("_kg", "kg"),
    ("_N", "N"),
    ("_g", "g"),
    ("_s", "s"),
    ("_J", "J"),
)


def unit_of(quantity: str) -> str:
    """The unit a quantity name carries (``max_peak_stress_MPa`` -> ``MPa``; ``""`` for ratios)."""
    for suffix, unit in _UNITS:
        if quantity.endswith(suffix):
            return unit
    return ""


def _num(value: float, unit: str = "") -> str:
    """``42.5 MPa``: 4 significant digits, the unit after a space (``%`` too)."""
    if value is None or not math.isfinite(value):
        text = "n/a" if value is None or math.isnan(value) else str(value)
    else:
        text = f"{value:.4g}"
    return f"{text} {unit}" if unit else text


def _nan_if_none(value: Any) -> float:
    return math.nan if value is None else float(value)


def _value_of(metrics: Mapping[str, Any], quantity: str) -> float | None:
    value = metrics.get(quantity)
    if value is None or isinstance(value, str):
        return None
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


# --------------------------------------------------------------------------------------------
# The verdict


@dataclass(frozen=True)
class Verdict:
    """The judgement of one design against one requirement.

    Attributes
    ----------
    name : label of the requirement (unique within a study).
    quantity : the metric or response column judged (units in the name).
    value : its value for this design, in ``unit`` (NaN when not computed); for a curve the
        worst deviation from the target, for an envelope the larger overshoot-relevant size.
    bound : what it must meet, human text with the unit (``<= 42.5 MPa``,
        ``within ±2 % of 1.5 N over 0.5–30 mm``).
    margin : distance to the bound in ``unit``; positive (or 0) when met, negative when not,
        NaN when not computed.
    margin_rel : ``margin`` as a fraction of the bound's scale (0.1 = 10 % to spare; for a target
        band, of the target level), or None.
    met : the requirement is met.
    unit : unit of ``value`` and ``margin`` (``MPa``, ``N``, ``""`` for a ratio).
    role : ``constraint`` (also a constraint of the optimisation) or ``check`` (only judged).
    detail : one line on where the bound is hit or why the value is missing; for a verdict
        judged on one of several figures, which model gave the judged one and the others.
    model : the model whose figure was judged (``plane stress``, ``3D solid``), ``""`` when the
        quantity has one figure only (see :class:`Figure`).
    figures : every figure of the quantity the design has, highest fidelity first, as
        ``(model, metric name, value)`` (value in ``unit``); empty when there is one figure.
    """

    name: str
    quantity: str
    value: float
    bound: str
    margin: float
    margin_rel: float | None
    met: bool
    unit: str
    role: Role = "check"
    detail: str = ""
    model: str = ""
    figures: tuple[tuple[str, str, float], ...] = ()

    def __post_init__(self) -> None:
        # a verdict read back from JSON carries its figures as {model, quantity, value} records
        figures = tuple(
            (str(f["model"]), str(f["quantity"]), _nan_if_none(f.get("value")))
            if isinstance(f, Mapping)
            else (str(f[0]), str(f[1]), _nan_if_none(f[2]))
            for f in (self.figures or ())
        )
        object.__setattr__(self, "figures", figures)

    @property
    def word(self) -> str:
        """``MET`` or ``NOT MET``."""
        return "MET" if self.met else "NOT MET"


def overall(verdicts: Sequence[Verdict]) -> Literal["MET", "NOT MET"]:
    """``MET`` when there is at least one verdict and every one is met; else ``NOT MET``.

    No requirement at all is NOT MET: nothing was shown, so nothing is claimed.
    """
    return "MET" if verdicts and all(v.met for v in verdicts) else "NOT MET"


def _margin_text(v: Verdict) -> str:
    if not math.isfinite(v.margin):
        return "n/a"
    text = f"{v.margin:+.4g}" + (f" {v.unit}" if v.unit else "")
    if v.margin_rel is not None and math.isfinite(v.margin_rel):
        text += f" ({100 * v.margin_rel:+.3g} %)"
    return text


def verdict_rows(verdicts: Sequence[Verdict]) -> list[list[str]]:
    """One row per verdict: requirement, value, bound, margin, MET/NOT MET (strings)."""
    return [
        [v.name, _value_text(v), v.bound, _margin_text(v), v.word + _role_mark(v)] for v in verdicts
    ]


def _value_text(v: Verdict) -> str:
    if v.bound.startswith("= ") and math.isfinite(v.value):  # a yes/no quantity (Flag)
        return "yes" if v.value else "no"
    return _num(v.value, v.unit)


def _role_mark(v: Verdict) -> str:
    return "" if v.role == "check" else " (constraint)"


def verdict_lines(verdicts: Sequence[Verdict]) -> list[str]:
    """Plain aligned lines: a header, one line per requirement, then ``overall: MET``.

    ``requirement  value  bound  margin  verdict``; a requirement that is NOT MET carries its
    ``detail`` on the next line, indented.
    """
    header = ["requirement", "value", "bound", "margin", "verdict"]
    rows = verdict_rows(verdicts)
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(header, widths, strict=True)).rstrip()]
    for v, row in zip(verdicts, rows, strict=True):
        lines.append("  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip())
        if v.detail and (not v.met or v.figures):  # which model gave the judged figure
            lines.append(f"    {v.detail}")
    if not verdicts:
        lines.append("(no requirement stated)")
    met = sum(v.met for v in verdicts)
    lines.append(f"overall: {overall(verdicts)} ({met} of {len(verdicts)} requirements met)")
    return lines


def _json_float(value: float | None) -> float | None:
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def to_records(verdicts: Iterable[Verdict]) -> list[dict[str, Any]]:
    """One JSON-ready mapping per verdict (NaN as None, the word as ``verdict``)."""
    out = []
    for v in verdicts:
        record = asdict(v)
        record["value"] = _json_float(v.value)
        record["margin"] = _json_float(v.margin)
        record["margin_rel"] = _json_float(v.margin_rel)
        record["figures"] = [
            {"model": m, "quantity": q, "value": _json_float(x)} for m, q, x in v.figures
        ]
        out.append({"verdict": v.word, **record})
    return out


def verdict_record(verdicts: Sequence[Verdict]) -> dict[str, Any]:
    """``{"overall": "MET"|"NOT MET", "met": k, "of": n, "requirements": [...]}`` for JSON."""
    return {
        "overall": overall(verdicts),
        "met": sum(v.met for v in verdicts),
        "of": len(verdicts),
        "requirements": to_records(verdicts),
    }


# --------------------------------------------------------------------------------------------
# Requirements


@dataclass(frozen=True)
class Requirement:
    """Base of the requirements (a frozen, picklable value; use a subclass).

    Attributes
    ----------
    quantity : the metric (or response column) judged, units in the name.
    name : label; default ``quantity``.
    role : ``constraint`` or ``check``.
    """

    quantity: str
    name: str = ""
    role: Role = "check"

    @property
    def label(self) -> str:
        return self.name or self.quantity

    @property
    def unit(self) -> str:
        return unit_of(self.quantity)

    @property
    def needs_curve(self) -> bool:
        """The requirement reads ``curves`` (a response), not only ``metrics``."""
        return False

    def check(
        self,
        metrics: Mapping[str, Any],
        curves: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
    ) -> Verdict:
        """The verdict for one design (see the module docstring for the arguments)."""
        raise NotImplementedError

    def scale(self) -> float:
        """Magnitude that makes the margin a fraction (for ``margin_rel`` and the constraint)."""
        return 1.0

    def constraint(
        self,
        metrics: Mapping[str, Any],
        curves: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
    ) -> float:
        """A ``g <= 0`` row for an optimiser: ``-margin / scale`` (dimensionless); a value that
        was not computed gives :data:`MISSING_CONSTRAINT`."""
        v = self.check(metrics, curves)
        if not math.isfinite(v.margin):
            return MISSING_CONSTRAINT
        return -v.margin / self.scale()

    def missing(self, bound: str, why: str = "") -> Verdict:
        """The NOT MET verdict of a design that has no value for this requirement: the bound
        text ``bound`` and ``why`` (default: the quantity was not computed)."""
        return Verdict(
            self.label,
            self.quantity,
            math.nan,
            bound,
            math.nan,
            None,
            False,
            self.unit,
            self.role,
            why or f"{self.quantity} was not computed for this design",
        )

    def relative_to(self) -> float:
        """What ``margin_rel`` is a fraction of (default :meth:`scale`)."""
        return self.scale()

    def _verdict(self, value: float, bound: str, margin: float, detail: str = "") -> Verdict:
        s = self.relative_to()
        rel = margin / s if s > 0 and math.isfinite(margin) else None
        return Verdict(
            self.label, self.quantity, value, bound, margin, rel, margin >= 0.0, self.unit,
            self.role, detail,
        )  # fmt: skip


def _finite(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise OptimiseError(f"{name} = {value} must be a finite number")
    return value


@dataclass(frozen=True)
class MaxValue(Requirement):
    """``value <= maximum`` (unit of the quantity)."""

    maximum: float = 0.0

    def __post_init__(self) -> None:
        _finite("maximum", self.maximum)

    def scale(self) -> float:
        return abs(self.maximum) or 1.0

    def bound_text(self) -> str:
        return f"<= {_num(self.maximum, self.unit)}"

    def check(self, metrics, curves=None) -> Verdict:  # type: ignore[no-untyped-def]
        value = _value_of(metrics, self.quantity)
        if value is None:
            return self.missing(self.bound_text())
        return self._verdict(value, self.bound_text(), self.maximum - value)


@dataclass(frozen=True)
class MinValue(Requirement):
    """``value >= minimum`` (unit of the quantity)."""

    minimum: float = 0.0

    def __post_init__(self) -> None:
        _finite("minimum", self.minimum)

    def scale(self) -> float:
        return abs(self.minimum) or 1.0

    def bound_text(self) -> str:
        return f">= {_num(self.minimum, self.unit)}"

    def check(self, metrics, curves=None) -> Verdict:  # type: ignore[no-untyped-def]
        value = _value_of(metrics, self.quantity)
        if value is None:
            return self.missing(self.bound_text())
        return self._verdict(value, self.bound_text(), value - self.minimum)


@dataclass(frozen=True)
class MinFeature(MinValue):
    """The thinnest printed feature (``min_feature_mm``-like quantity) is at least ``minimum``."""

    def bound_text(self) -> str:
        return f">= {_num(self.minimum, self.unit)} (printable feature)"


@dataclass(frozen=True)
class Range(Requirement):
    """``minimum <= value <= maximum``; the margin is the distance to the nearer end."""

    minimum: float = 0.0
    maximum: float = 0.0

    def __post_init__(self) -> None:
        _finite("minimum", self.minimum)
        _finite("maximum", self.maximum)
        if not self.minimum <= self.maximum:
            raise OptimiseError(
                f"range [{self.minimum:g}, {self.maximum:g}] of {self.quantity} is empty; give "
                "[min, max] with min <= max"
            )

    def scale(self) -> float:
        return max(abs(self.minimum), abs(self.maximum)) or 1.0

    def bound_text(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        return f"in [{self.minimum:.4g}, {self.maximum:.4g}]{unit}"

    def check(self, metrics, curves=None) -> Verdict:  # type: ignore[no-untyped-def]
        value = _value_of(metrics, self.quantity)
        if value is None:
            return self.missing(self.bound_text())
        low, high = value - self.minimum, self.maximum - value
        detail = "" if min(low, high) >= 0 else ("below the range" if low < 0 else "above it")
        return self._verdict(value, self.bound_text(), min(low, high), detail)


@dataclass(frozen=True)
class AllowableStress(Requirement):
    """A stress (MPa) at most ``yield_MPa / safety_factor``."""

    yield_MPa: float = 0.0
    safety_factor: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.yield_MPa) and self.yield_MPa > 0):
            raise OptimiseError(f"yield_MPa = {self.yield_MPa} must be > 0")
        if not (math.isfinite(self.safety_factor) and self.safety_factor > 0):
            raise OptimiseError(
                f"safety_factor = {self.safety_factor} must be > 0 (1.0: the yield itself)"
            )

    @property
    def allowable_MPa(self) -> float:
        return self.yield_MPa / self.safety_factor

    @property
    def unit(self) -> str:
        return "MPa"

    def scale(self) -> float:
        return self.allowable_MPa

    def bound_text(self) -> str:
        text = f"<= {_num(self.allowable_MPa, 'MPa')}"
        if self.safety_factor != 1.0:
            text += f" (yield {self.yield_MPa:.4g} MPa / SF {self.safety_factor:.3g})"
        return text

    def check(self, metrics, curves=None) -> Verdict:  # type: ignore[no-untyped-def]
        value = _value_of(metrics, self.quantity)
        if value is None:
            return self.missing(self.bound_text())
        return self._verdict(value, self.bound_text(), self.allowable_MPa - value)


@dataclass(frozen=True)
class Flag(Requirement):
    """A yes/no metric must be ``expected`` (``stable`` must be true). Value 1 (yes) or 0 (no);
    margin +1 when met, -1 when not."""

    expected: bool = True

    def bound_text(self) -> str:
        return "= " + ("yes" if self.expected else "no")

    def check(self, metrics, curves=None) -> Verdict:  # type: ignore[no-untyped-def]
        raw = metrics.get(self.quantity)
        if raw is None or isinstance(raw, str):
            return self.missing(self.bound_text())
        value = bool(raw)
        met = value is self.expected
        detail = "" if met else str(metrics.get(f"{self.quantity}_message") or "")
        return Verdict(
            self.label, self.quantity, float(value), self.bound_text(), 1.0 if met else -1.0,
            None, met, "", self.role, detail,
        )  # fmt: skip


@dataclass(frozen=True)
class Envelope(Requirement):
    """The bounding box of the part fits ``max_width_mm x max_height_mm`` (x max_depth_mm, the
    out-of-plane size, when given), in the design frame (no turning).

    Reads ``width_key``, ``height_key`` (and ``depth_key``) from the metrics (mm): the part as
    exported, measured by the pipeline. The value is the size with the least spare; the margin
    that spare (mm); the detail the measured box.
    """

    quantity: str = "envelope_mm"
    max_width_mm: float = 0.0
    max_height_mm: float = 0.0
    width_key: str = "envelope_width_mm"
    height_key: str = "envelope_height_mm"
    max_depth_mm: float | None = None
    depth_key: str = "envelope_depth_mm"

    def __post_init__(self) -> None:
        for key in ("max_width_mm", "max_height_mm", "max_depth_mm"):
            value = getattr(self, key)
            if key == "max_depth_mm" and value is None:
                continue
            if not (math.isfinite(value) and value > 0):
                raise OptimiseError(f"envelope {key} = {value} must be > 0")

    @property
    def unit(self) -> str:
        return "mm"

    def _limits(self) -> list[tuple[str, float]]:
        out = [(self.width_key, self.max_width_mm), (self.height_key, self.max_height_mm)]
        if self.max_depth_mm is not None:
            out.append((self.depth_key, self.max_depth_mm))
        return out

    def scale(self) -> float:
        return min(limit for _, limit in self._limits())

    def bound_text(self) -> str:
        return "within " + " × ".join(f"{limit:.4g}" for _, limit in self._limits()) + " mm"

    def check(self, metrics, curves=None) -> Verdict:  # type: ignore[no-untyped-def]
        sizes = [(_value_of(metrics, key), limit) for key, limit in self._limits()]
        if any(size is None for size, _ in sizes):
            missing = "the design has no outline to measure"
            if sizes[0][0] is not None and sizes[1][0] is not None:
                missing = "the design has no out-of-plane depth to measure"
            return self.missing(self.bound_text(), missing)
        spares = [limit - size for size, limit in sizes]  # type: ignore[operator]
        k = int(np.argmin(spares))
        box = " × ".join(f"{size:.4g}" for size, _ in sizes) + " mm"
        return self._verdict(sizes[k][0], self.bound_text(), spares[k], box)  # type: ignore[arg-type]


@dataclass(frozen=True)
class DesignRange(Requirement):
    """Every design variable inside its stated range (``design_space:``, a variable's
    ``bounds``): the design a study gives or the optimiser moves is a design choice, and one
    outside the range the study states is NOT MET, never clipped into it or MET.

    Reads ``metrics[key(name)]`` (``design.<name>``, the variable's own unit) for every variable
    (:meth:`values` makes them from a design vector). The verdict names the variable furthest
    outside its range (relative to the range's width), or, when every one is inside, the one
    with the least spare: its value, ``<name> in [lower, upper]`` and the margin in its unit.

    Attributes
    ----------
    names : the variables, in the order of the design vector.
    lower, upper : their ranges, each (n_var,), in the variables' own units.
    where : the key of the study that states the ranges (for the detail: ``design_space``).
    """

    quantity: str = "design_variables"
    names: tuple[str, ...] = ()
    lower: tuple[float, ...] = ()
    upper: tuple[float, ...] = ()
    where: str = "design_space"

    def __post_init__(self) -> None:
        object.__setattr__(self, "names", tuple(str(n) for n in self.names))
        object.__setattr__(self, "lower", tuple(float(v) for v in self.lower))
        object.__setattr__(self, "upper", tuple(float(v) for v in self.upper))
        if not (len(self.names) == len(self.lower) == len(self.upper)):
            raise OptimiseError(
                f"{len(self.names)} design variables but {len(self.lower)} lower and "
                f"{len(self.upper)} upper bounds"
            )

    @staticmethod
    def key(name: str) -> str:
        """The metric holding variable ``name``'s value (``design.B``)."""
        return f"design.{name}"

    def values(self, x: Any) -> dict[str, float]:
        """``{key(name): value}`` of a design vector ``x`` (n_var,), in the variables' units.

        Raises
        ------
        OptimiseError
            When ``x`` does not have one value per variable.
        """
        arr = np.asarray(x, dtype=float).ravel()
        if arr.shape != (len(self.names),):
            raise OptimiseError(
                f"the design has {arr.size} values, its design space {len(self.names)} variables"
            )
        return {self.key(n): float(v) for n, v in zip(self.names, arr, strict=True)}

    def _bound(self, i: int) -> str:
        unit = unit_of(self.names[i])
        return f"{self.names[i]} in [{self.lower[i]:.6g}, {self.upper[i]:.6g}]" + (
            f" {unit}" if unit else ""
        )

    def check(self, metrics, curves=None) -> Verdict:  # type: ignore[no-untyped-def]
        if not self.names:
            return self.missing("in their ranges", "the design has no variable")
        values = [_value_of(metrics, self.key(n)) for n in self.names]
        missing = [n for n, v in zip(self.names, values, strict=True) if v is None]
        if missing:
            return self.missing(
                f"every variable in its range ({self.where})",
                f"the design's {', '.join(missing[:3])} {'is' if len(missing) == 1 else 'are'} "
                "not known",
            )
        spare = [
            min(v - lo, hi - v)  # type: ignore[operator]
            for v, lo, hi in zip(values, self.lower, self.upper, strict=True)
        ]
        width = [max(hi - lo, 1e-300) for lo, hi in zip(self.lower, self.upper, strict=True)]
        rel = [s / w for s, w in zip(spare, width, strict=True)]
        k = int(np.argmin(rel))
        value, unit = float(values[k]), unit_of(self.names[k])  # type: ignore[arg-type]
        outside = [n for n, s in zip(self.names, spare, strict=True) if s < 0]
        detail = ""
        if outside:
            side = "below" if value < self.lower[k] else "above"
            detail = (
                f"{self.names[k]} = {_num(value, unit)} is {side} its range "
                f"[{self.lower[k]:.6g}, {self.upper[k]:.6g}]{' ' + unit if unit else ''} "
                f"({self.where}); {len(outside)} of {len(self.names)} variables outside: "
                + ", ".join(outside[:6])
                + (" …" if len(outside) > 6 else "")
                + f"; bring the design inside or widen {self.where}"
            )
        return Verdict(
            self.label, self.quantity, value, self._bound(k), float(spare[k]), float(rel[k]),
            not outside, unit, self.role, detail,
        )  # fmt: skip


def _unit_factor(name: str) -> float:
    """Factor from a column's unit to project units (rad, mm, N·mm, N); 1 when unknown."""
    try:
        return column_unit_factor(name)[2]
    except OptimiseError:
        return 1.0


@dataclass(frozen=True, eq=False)
class TargetBand(Requirement):
    """A response ``y(x)`` within a tolerance band of a target curve over ``x`` in ``over``.

    Attributes
    ----------
    quantity : the response column ``y`` (``force_N``, ``torque_Nm``).
    x : the driving column (``displacement_mm``, ``rotation_deg``).
    target : a :class:`optimise.targets.TargetCurve` (project units: rad, mm, N·mm, N); the
        response is converted by its column units (``torque_Nm`` x 1000, ``rotation_deg`` to rad).
    over : (lo, hi) in the unit of ``x``, or None for the whole response. The response must
        reach both ends (a trace that stops early is NOT MET).
    tolerance : half-width of the band in the unit of ``quantity`` (absolute), or
    tolerance_rel : half-width as a fraction of ``|target(x)|`` (0.02 = ±2 %). Exactly one.

    ``check`` reports the worst deviation ``max |y - target|`` (unit of ``quantity``) and the
    margin ``min (band - |y - target|)`` over the rows in ``over`` (both ends interpolated).
    """

    x: str = "displacement_mm"
    target: TargetCurve | None = None
    over: tuple[float, float] | None = None
    tolerance: float | None = None
    tolerance_rel: float | None = None
    target_text: str = ""

    def __post_init__(self) -> None:
        if self.target is None:
            raise OptimiseError("a target band needs a target curve")
        if (self.tolerance is None) == (self.tolerance_rel is None):
            raise OptimiseError("a target band needs one of tolerance (absolute) or tolerance_rel")
        tol = self.tolerance if self.tolerance is not None else self.tolerance_rel
        if not (math.isfinite(tol) and tol > 0):  # type: ignore[arg-type]
            raise OptimiseError(f"tolerance = {tol} must be > 0")
        if self.over is not None and not self.over[0] < self.over[1]:
            raise OptimiseError(f"over = {list(self.over)} must be [lower, upper], lower < upper")

    @property
    def needs_curve(self) -> bool:
        return True

    def _fy(self) -> float:
        return _unit_factor(self.quantity)

    def target_at(self, x: np.ndarray) -> np.ndarray:
        """The target (n,) at ``x`` (n,) (unit of the x column), in the unit of ``quantity``.

        Raises
        ------
        OptimiseError
            When ``x`` lies outside the target's table.
        """
        return np.asarray(self.target(x * _unit_factor(self.x)), dtype=float) / self._fy()  # type: ignore[misc]

    def scale(self) -> float:
        if self.tolerance is not None:
            return float(self.tolerance)
        if self.over is not None:
            xs = np.linspace(self.over[0], self.over[1], 33)
            try:
                level = float(np.max(np.abs(self.target_at(xs))))
            except OptimiseError:
                level = 0.0
            if level > 0:
                return float(self.tolerance_rel) * level  # type: ignore[arg-type]
        return 1.0

    def relative_to(self) -> float:
        # The margin as a share of the target level (a 1.5 N target missed by 1.33 N is -89 %),
        # not of the tolerance, which would read -4450 %; the constraint row keeps the tolerance.
        if self.over is not None:
            xs = np.linspace(self.over[0], self.over[1], 33)
            try:
                level = float(np.max(np.abs(self.target_at(xs))))
            except OptimiseError:
                level = 0.0
            if level > 0:
                return level
        return self.scale()

    def bound_text(self) -> str:
        what = self.target_text or describe_target(self.target, self.quantity)  # type: ignore[arg-type]
        if self.tolerance is not None:
            band = f"within ±{_num(self.tolerance, self.unit)} of {what}"
        else:
            band = f"within ±{100 * self.tolerance_rel:.3g} % of {what}"  # type: ignore[operator]
        if self.over is not None:
            xu = unit_of(self.x)
            band += f" over {self.over[0]:.4g}–{self.over[1]:.4g}" + (f" {xu}" if xu else "")
        return band

    def check(self, metrics, curves=None) -> Verdict:  # type: ignore[no-untyped-def]
        bound = self.bound_text()
        curve = (curves or {}).get(self.quantity)
        if curve is None:
            return self.missing(bound, f"no response {self.quantity}({self.x}) for this design")
        x = np.asarray(curve[0], dtype=float).ravel()
        y = np.asarray(curve[1], dtype=float).ravel()
        keep = np.isfinite(x) & np.isfinite(y)
        x, y = x[keep], y[keep]
        if x.size == 0:
            return self.missing(bound, "the response has no finite row")
        order = np.argsort(x, kind="stable")
        x, y = x[order], y[order]
        lo, hi = (x[0], x[-1]) if self.over is None else self.over
        xu = unit_of(self.x)
        span = 1e-9 * max(1.0, abs(lo), abs(hi))
        if x[0] > lo + span or x[-1] < hi - span:
            reach = f"{x[0]:.4g}–{x[-1]:.4g} {xu}".strip()
            return Verdict(
                self.label, self.quantity, math.nan, bound, math.nan, None, False, self.unit,
                self.role, f"the response covers only {reach} of {lo:.4g}–{hi:.4g} {xu}".strip(),
            )  # fmt: skip
        inside = (x > lo) & (x < hi)
        xs = np.concatenate([[lo], x[inside], [hi]])
        ys = np.concatenate([[np.interp(lo, x, y)], y[inside], [np.interp(hi, x, y)]])
        try:
            t = self.target_at(xs)
        except OptimiseError as exc:
            return self.missing(bound, str(exc))
        dev = np.abs(ys - t)
        band = (
            np.full_like(t, float(self.tolerance))
            if self.tolerance is not None
            else float(self.tolerance_rel) * np.abs(t)  # type: ignore[arg-type]
        )
        spare = band - dev
        k = int(np.argmin(spare))
        margin = float(spare[k])
        side = "above" if ys[k] > t[k] else "below"
        detail = (
            ""
            if margin >= 0
            else f"at {xs[k]:.4g} {xu} the response is {ys[k]:.4g} {self.unit}, {side} "
            f"{t[k]:.4g} {self.unit} by more than ±{band[k]:.4g} {self.unit}".replace("  ", " ")
        )
        return self._verdict(float(np.max(dev)), bound, margin, detail)


def curves_from_table(
    table: Mapping[str, Any],
    requirements: Iterable[Requirement],
    figures: Mapping[str, Sequence[Figure]] | None = None,
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{quantity: (x, y)}`` for every :class:`TargetBand` whose columns are in ``table``, and
    for every other figure of its quantity (``figures``, see :func:`judge_best`) in it."""
    curves = {}
    for req in requirements:
        if not isinstance(req, TargetBand) or req.x not in table:
            continue
        names = [req.quantity, *(f.quantity for f in (figures or {}).get(req.quantity, ()))]
        for name in names:
            if name in table:
                curves[name] = (
                    np.asarray(table[req.x], dtype=float),
                    np.asarray(table[name], dtype=float),
                )
    return curves


# --------------------------------------------------------------------------------------------
# Figures of several fidelities

#: Fidelity ranks of the project's models (higher: judged first).
BEAM, PLANE_STRESS, SOLID_3D = 0, 1, 2


@dataclass(frozen=True)
class Figure:
    """One model's figure of a quantity that requirements bound.

    Attributes
    ----------
    quantity : the metric holding the figure (``plane_stress_peak_stress_MPa``), in the unit of
        the quantity it stands for.
    model : the model that gives it, as the verdict names it (``beam``, ``plane stress``).
    rank : its fidelity (:data:`BEAM`, :data:`PLANE_STRESS`, :data:`SOLID_3D`); the highest
        the design has is judged.
    """

    quantity: str
    model: str
    rank: int = BEAM


def judge_best(
    requirement: Requirement,
    metrics: Mapping[str, Any],
    curves: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
    figures: Sequence[Figure] = (),
    taken: Iterable[str] = (),
) -> Verdict:
    """``requirement`` judged on the highest-fidelity figure of its quantity the design has.

    Parameters
    ----------
    requirement : a requirement on a scalar quantity (a curve requirement is judged as is).
    metrics, curves : as for :meth:`Requirement.check`.
    figures : the figures of ``requirement.quantity`` (its own one included, e.g. the beam's),
        in any order; a figure whose metric is missing or not finite is left out.
    taken : metric names another requirement judges directly (a 3D row of its own): they are
        not borrowed, so one figure is not judged twice.

    Returns
    -------
    Verdict
        ``requirement.check`` of the best figure; with more than one figure, ``model`` names
        the judged one, ``figures`` lists them all (best first) and ``detail`` says which model
        gave which value.
    """
    if not figures:
        return requirement.check(metrics, curves)
    skip = set(taken) - {requirement.quantity}
    if requirement.needs_curve:
        return _judge_best_curve(requirement, metrics, curves or {}, figures, skip)
    have = [
        (f, metrics[f.quantity])
        for f in figures
        if f.quantity not in skip and _value_of(metrics, f.quantity) is not None
    ]
    if not have or (len(have) == 1 and have[0][0].quantity == requirement.quantity):
        return requirement.check(metrics, curves)
    have.sort(key=lambda item: -item[0].rank)  # stable: the first listed of a rank wins
    best, raw = have[0]
    v = requirement.check({**metrics, requirement.quantity: raw}, curves)

    def text(value: Any) -> str:
        if isinstance(value, bool) or isinstance(requirement, Flag):
            return "yes" if value else "no"
        return _num(float(value), v.unit)

    others = ", ".join(f"{f.model} {text(x)}" for f, x in have[1:])
    note = f"judged on {best.model}: {text(raw)}" + (f" ({others})" if others else "")
    return replace(
        v,
        model=best.model,
        figures=tuple((f.model, f.quantity, float(x)) for f, x in have),
        detail=note + (f"; {v.detail}" if v.detail else ""),
    )


def _judge_best_curve(
    requirement: Requirement,
    metrics: Mapping[str, Any],
    curves: Mapping[str, tuple[np.ndarray, np.ndarray]],
    figures: Sequence[Figure],
    skip: set[str],
) -> Verdict:
    """:func:`judge_best` of a curve requirement: ``curves`` holds each figure's curve under
    its own name; the best is judged, each other figure's worst deviation shown beside it."""
    have = [f for f in figures if f.quantity not in skip and f.quantity in curves]
    if not have or (len(have) == 1 and have[0].quantity == requirement.quantity):
        return requirement.check(metrics, curves)
    have.sort(key=lambda f: -f.rank)
    judged = [
        requirement.check(metrics, {**curves, requirement.quantity: curves[f.quantity]})
        for f in have
    ]
    v = judged[0]
    pairs = list(zip(have, judged, strict=True))
    others = ", ".join(f"{f.model} {_num(o.value, o.unit)}" for f, o in pairs[1:])
    note = f"judged on {have[0].model}: {_num(v.value, v.unit)}" + (
        f" ({others})" if others else ""
    )
    return replace(
        v,
        model=have[0].model,
        figures=tuple((f.model, f.quantity, float(o.value)) for f, o in pairs),
        detail=note + (f"; {v.detail}" if v.detail else ""),
    )


# --------------------------------------------------------------------------------------------
# The study-file spec

_SPEC_CONFIG = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class RequirementSpec(BaseModel):
    """One item of a study's ``requirements:`` list. Values are in the unit of ``quantity``.

    Examples (YAML)::

        - {quantity: max_peak_stress_MPa, max: 40.0}                  # MaxValue
        - {quantity: stroke_mm, min: 10.0, role: constraint}          # MinValue, optimised
        - {quantity: stiffness_Nm_per_rad, min: 270, max: 290}        # Range
        - {quantity: max_peak_stress_MPa, safety_factor: 1.5}         # AllowableStress
        - {quantity: min_feature_mm, min: 0.8}                        # MinFeature
        - {quantity: stable, equals: true}                            # Flag
        - {envelope_mm: [80, 40]}                                     # Envelope
        - {quantity: force_N, x: displacement_mm, over: [0.5, 15.0],  # TargetBand
           target: {kind: constant, force_N: 5.0}, tolerance_rel: 0.05}

    ``role: constraint`` makes it also a constraint of the optimisation (kinds that optimise);
    ``check`` (default) only judges the result.
    ``robust: {share_percent: 95}`` also requires it of 95 % of the prints under the study's
    ``robustness:`` scatter (:mod:`optimise.robust_requirements`): a constraint on the
    optimiser's samples with ``role: constraint``, and a row of the verdict judged on fresh
    samples.
    """

    model_config = _SPEC_CONFIG

    quantity: str | None = Field(
        None,
        max_length=100,
        description="the metric or response column judged, units in the name (force_N)",
    )
    name: str | None = Field(
        None, max_length=NAME_MAX_CHARS, description="label in the verdict (docs/usage.md, Names)"
    )
    role: Role = Field("check", description="constraint (also optimised) or check (only judged)")
    max: float | None = Field(None, description="upper bound, unit of the quantity")
    min: float | None = Field(None, description="lower bound, unit of the quantity")
    safety_factor: float | None = Field(
        None, gt=0, description="allowable stress = yield_MPa / safety_factor (quantity in MPa)"
    )
    yield_MPa: float | None = Field(
        None, gt=0, description="yield for safety_factor, MPa (default: the material's)"
    )
    equals: bool | None = Field(None, description="a yes/no quantity must be this (stable: true)")
    envelope_mm: tuple[float, float] | tuple[float, float, float] | None = Field(
        None,
        description="[width, height] (or [width, height, depth]) the part's bounding box as "
        "exported must fit, in the design frame, mm",
    )
    target: TargetSpec | None = Field(
        None, description="target curve of the response (kinds of optimise/targets.py)"
    )
    x: str | None = Field(
        None, max_length=100, description="target: the driving column (displacement_mm)"
    )
    over: tuple[float, float] | None = Field(
        None, description="target: [lower, upper] range of x, unit of x (default: all rows)"
    )
    tolerance: float | None = Field(
        None, gt=0, description="target: band half-width, unit of the quantity"
    )
    tolerance_rel: float | None = Field(
        None, gt=0, lt=10, description="target: band half-width as a fraction (0.02 = ±2 %)"
    )
    tolerance_percent: float | None = Field(
        None, gt=0, lt=1000, description="target: band half-width in percent (2 = ±2 %)"
    )
    robust: RobustShareSpec | None = Field(
        None,
        description="met in a share of the prints under the study's robustness: scatter "
        "({share_percent: 95}); docs/robustness.md",
    )

    @model_serializer(mode="wrap")
    def _without_unset_robust(self, handler: Any) -> Any:
        # robust: came after requirements were first written: an item without it dumps
        # (evaluation.json, a run folder's study.yaml) as it did before it existed
        data = handler(self)
        if isinstance(data, dict) and data.get("robust", 0) is None:
            del data["robust"]
        return data

    @field_validator("name")
    @classmethod
    def _name_rule(cls, value: str | None) -> str | None:  # the one rule of names (docs/usage.md)
        return value if value is None else check_name(value, "requirement name")

    @model_validator(mode="before")
    @classmethod
    def _tolerance_inside_target(cls, data: Any) -> Any:
        # `target: {kind: constant, force_N: 5, tolerance_rel: 0.05}` reads naturally: lift the
        # band keys out of the target mapping (TargetSpec knows nothing of bands).
        if isinstance(data, dict) and isinstance(data.get("target"), dict):
            target = dict(data["target"])
            lifted = {
                k: target.pop(k)
                for k in ("tolerance", "tolerance_rel", "tolerance_percent", "over")
                if k in target
            }
            clash = sorted(k for k in lifted if k in data)
            if clash:
                raise ValueError(f"{', '.join(clash)} given both in target and beside it; keep one")
            data = {**data, "target": target, **lifted}
        return data

    @model_validator(mode="after")
    def _one_shape(self) -> RequirementSpec:
        shapes = {
            "max/min": self.max is not None or self.min is not None,
            "safety_factor": self.safety_factor is not None,
            "equals": self.equals is not None,
            "envelope_mm": self.envelope_mm is not None,
            "target": self.target is not None,
        }
        given = [k for k, v in shapes.items() if v]
        if len(given) != 1:
            what = "has none of" if not given else f"mixes {' and '.join(given)}; give one of"
            raise ValueError(
                f"{what} max/min (bounds), safety_factor (allowable stress), equals (yes/no), "
                "envelope_mm ([w, h]) or target (a curve)"
            )
        kind = given[0]
        if kind != "envelope_mm" and self.quantity is None:
            raise ValueError("needs quantity: the metric or response column it judges")
        if kind == "envelope_mm":
            if self.envelope_mm is None or min(self.envelope_mm) <= 0:
                raise ValueError(
                    "envelope_mm must be [width, height] or [width, height, depth], all > 0 mm"
                )
        if kind == "max/min" and self.min is not None and self.max is not None:
            if self.min > self.max:
                raise ValueError(f"min = {self.min:g} is above max = {self.max:g}; swap them")
        if self.yield_MPa is not None and kind != "safety_factor":
            raise ValueError("yield_MPa goes with safety_factor (an allowable stress)")
        target_keys = ("x", "over", "tolerance", "tolerance_rel", "tolerance_percent")
        stray = [k for k in target_keys if getattr(self, k) is not None]
        if kind != "target" and stray:
            raise ValueError(
                f"{', '.join(stray)} go with target (a curve); add target or drop them"
            )
        if kind == "target":
            tol = [k for k in target_keys[2:] if getattr(self, k) is not None]
            if len(tol) != 1:
                raise ValueError(
                    "a target needs one band: tolerance (unit of the quantity), tolerance_rel "
                    "(0.02 = ±2 %) or tolerance_percent"
                )
            if self.x is None:
                raise ValueError("a target needs x: the driving column (e.g. displacement_mm)")
            if self.over is not None and not self.over[0] < self.over[1]:
                raise ValueError(f"over = {list(self.over)} must be [lower, upper], lower < upper")
        if kind == "safety_factor" and self.quantity and unit_of(self.quantity) != "MPa":
            raise ValueError(
                f"safety_factor judges a stress in MPa, but {self.quantity} is not one; use "
                "max: for a ratio (stress_yield_ratio: max 1/SF)"
            )
        return self

    @property
    def judged(self) -> tuple[str, ...]:
        """The names this requirement reads (the quantity, and x for a target)."""
        if self.envelope_mm is not None:
            depth = ("envelope_depth_mm",) if len(self.envelope_mm) == 3 else ()
            return ("envelope_width_mm", "envelope_height_mm", *depth)
        return tuple(n for n in (self.quantity, self.x) if n)

    def to_requirement(
        self,
        yield_MPa: float | None = None,
        table: tuple[np.ndarray, np.ndarray] | None = None,
        columns: tuple[str, str] | None = None,
    ) -> Requirement:
        """The requirement this item states.

        Parameters
        ----------
        yield_MPa : the material's yield, MPa (for ``safety_factor`` without ``yield_MPa``).
        table, columns : a ``kind: table`` target's CSV columns (see
            :meth:`optimise.targets.TargetSpec.to_curve`).

        Raises
        ------
        OptimiseError
            When an allowable stress has no yield, or the target refuses its values.
        """
        q, name, role = self.quantity or "", self.name or "", self.role
        if self.envelope_mm is not None:
            w, h, *d = self.envelope_mm
            return Envelope(
                name=name, role=role, max_width_mm=w, max_height_mm=h,
                max_depth_mm=d[0] if d else None,
            )  # fmt: skip
        if self.safety_factor is not None:
            y = self.yield_MPa if self.yield_MPa is not None else yield_MPa
            if y is None:
                raise OptimiseError("an allowable stress needs yield_MPa (or a material)")
            return AllowableStress(q, name, role, y, self.safety_factor)
        if self.equals is not None:
            return Flag(q, name, role, self.equals)
        if self.target is not None:
            curve = self.target.to_curve(table, columns)
            rel = self.tolerance_rel
            if self.tolerance_percent is not None:
                rel = self.tolerance_percent / 100.0
            return TargetBand(
                q, name or f"{q} target", role, x=self.x or "", target=curve, over=self.over,
                tolerance=self.tolerance, tolerance_rel=rel, target_text=describe_target(curve, q),
            )  # fmt: skip
        if self.min is not None and self.max is not None:
            return Range(q, name, role, self.min, self.max)
        if self.max is not None:
            return MaxValue(q, name, role, self.max)
        cls = MinFeature if "feature" in q else MinValue
        return cls(q, name, role, float(self.min))  # type: ignore[arg-type]


def describe_target(curve: TargetCurve, quantity: str = "") -> str:
    """Short words for a target curve in the unit of ``quantity`` (``1.5 N``, ``276 N·m/rad``)."""
    from flexopt.optimise.targets import ConstantTarget, LinearTarget, ThresholdTarget

    fy = _unit_factor(quantity) if quantity else 1.0
    unit = unit_of(quantity) if quantity else curve.y_unit
    if isinstance(curve, ConstantTarget):
        return _num(curve.level / fy, unit)
    if isinstance(curve, LinearTarget):
        per = "rad" if curve.quantity == "torque" else "mm"
        return f"a {_num(curve.stiffness / fy, f'{unit}/{per}')} line"
    if isinstance(curve, ThresholdTarget):
        return f"the threshold curve to {_num(curve.max_value / fy, unit)}"
    return "the target table"
