"""Creep and relaxation of a design held for a time, from its own response table.

A study's ``hold:`` block (:class:`HoldSpec`) holds the part at one point of its response for
``time_h`` hours (at ``temperature_C``): at a displacement (the kind's driven column,
``displacement_mm`` or ``rotation_deg``) or at a force (its force column, ``force_N``,
``torque_Nm`` ...). The material's creep law (:class:`flexopt.fea.creep.CreepLaw`: Findley's
power law; a built-in material's ``CREEP_DATA`` or the ``creep:`` entry of a material)
gives, by the quasi-elastic method (docs/durability.md, "Creep"):

- displacement held: the force after the hold = the elastic force x ``E_R(t)/E0``
  (``held_<force column>``, ``force_retention``; the whole held curve as the table column
  ``held_<force column>``, so a target band can judge it);
- force held: the drive after the hold = the elastic drive at the held force x ``E0 J(t)``
  (``held_<driven column>``, ``deflection_growth``).

The law holds below the stress ratio it was fitted to: above it the held values are not
given (a requirement on them is NOT MET, the reason in ``hold_note``).

Units: time in h, temperatures in deg C, forces and drives in the units of their columns.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from flexopt.fea.creep import CreepLaw, crept_drive, relaxed_force
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import get_creep_data
from flexopt.optimise.errors import OptimiseError
from pydantic import BaseModel, ConfigDict, Field, model_serializer, model_validator

__all__ = [
    "HOLD_SCALARS",
    "CreepSpec",
    "HoldResult",
    "HoldSpec",
    "creep_law_of",
    "hold_of_table",
    "hold_quantities",
]

#: Scalars every hold reports that a requirement may judge (besides ``held_<column>``).
HOLD_SCALARS = ("force_retention", "deflection_growth", "hold_stress_ratio")

#: Columns whose held value a requirement may name as ``held_<column>``: forces, moments and
#: reactions (a displacement hold) and drives (a force hold).
_HELD_COLUMN = re.compile(
    r"^(force|torque|moment|reaction|drive_reaction|displacement|rotation|deflection|angle)"
)

_CONFIG = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class CreepSpec(BaseModel):
    """The ``creep:`` entry of a material (materials.yaml or a material mapping): a Findley
    power law ``J(t) = (1/E0)(1 + (t/tau)^n)`` (:class:`flexopt.fea.creep.CreepLaw`)."""

    model_config = _CONFIG

    tau_h: float = Field(gt=0, description="time at which creep strain = elastic strain, h")
    n: float = Field(gt=0, le=1, description="Findley's time exponent, 0 < n <= 1")
    max_stress_ratio: float = Field(
        gt=0, le=1, description="largest stress / strength the law was fitted at"
    )
    source: str = Field(min_length=1, max_length=500, description="where the numbers come from")
    E0_MPa: float | None = Field(None, gt=0, description="instantaneous modulus of the fit, MPa")
    reference_temperature_C: float = Field(23.0, description="temperature of the fit, deg C")
    activation_energy_kJ_mol: float | None = Field(
        None, gt=0, description="Arrhenius time-temperature shift, kJ/mol"
    )
    wlf_C1: float | None = Field(None, description="WLF shift constant C1")
    wlf_C2: float | None = Field(None, gt=0, description="WLF shift constant C2, K")
    assumed: bool = Field(
        False, description="true: an assumed, illustrative law (said in every verdict)"
    )
    fit: dict[str, Any] | None = Field(
        None,
        description="the hold test and its fit (flexopt calibrate): data, intervals, residual",
    )

    @model_serializer(mode="wrap")
    def _without_unset_fit(self, handler: Any) -> Any:
        # a law without a recorded fit dumps as it did before ``fit`` existed (run folders
        # stay the same)
        data = handler(self)
        if isinstance(data, dict) and data.get("fit", 0) is None:
            del data["fit"]
        return data

    @model_validator(mode="after")
    def _law(self) -> CreepSpec:
        try:
            self.to_law()
        except FeaError as exc:
            raise ValueError(str(exc).removeprefix("creep: ")) from None
        return self

    def to_law(self) -> CreepLaw:
        """The :class:`~flexopt.fea.creep.CreepLaw` of this entry."""
        return CreepLaw(**{k: v for k, v in self.model_dump().items() if k != "fit"})


class HoldSpec(BaseModel):
    """The ``hold:`` block of a study: hold the part ``time_h`` hours at a displacement or a
    force, and report what is left of the force (or how far it crept).

    Exactly one of ``level`` (the held value: the driven column's unit for
    ``at: displacement``, the force column's for ``at: force``) or ``fraction`` (of the traced
    stroke, or of the largest force traced).
    """

    model_config = _CONFIG

    time_h: float = Field(gt=0, le=1.0e6, description="hold time, h")
    temperature_C: float | None = Field(
        None, ge=-100, le=300, description="hold temperature, deg C (default: the law's)"
    )
    at: Literal["displacement", "force"] = Field(
        "displacement", description="what is held: the driven displacement, or the force"
    )
    level: float | None = Field(None, description="held value, unit of the held column")
    fraction: float | None = Field(
        None, gt=0, le=1, description="held value as a fraction of the traced stroke / force"
    )
    column: str | None = Field(
        None, max_length=100, description="the force column (default: the kind's plotted one)"
    )

    @model_validator(mode="after")
    def _one_level(self) -> HoldSpec:
        if (self.level is None) == (self.fraction is None):
            raise ValueError(
                "give exactly one of level (the held value, unit of the held column) or "
                "fraction (of the traced stroke or force)"
            )
        if self.level is not None and self.level == 0.0:
            raise ValueError("level 0 holds nothing; give the held displacement or force")
        return self


def creep_law_of(material: Any) -> CreepLaw:
    """The creep law of a study's ``material`` block: its ``creep:`` entry, else the built-in
    table's (:data:`flexopt.fea.materials.CREEP_DATA`).

    Raises
    ------
    OptimiseError
        When neither has one: the message says how to give it.
    """
    spec = getattr(material, "creep", None)
    if spec is not None:
        return spec.to_law() if isinstance(spec, CreepSpec) else CreepSpec(**spec).to_law()
    name = str(getattr(material, "name", material))
    try:
        return get_creep_data(name)
    except FeaError as exc:
        raise OptimiseError(str(exc)) from None


def hold_quantities(names: Iterable[str]) -> tuple[str, ...]:
    """The names a requirement may judge with a ``hold:`` block, given the kind's quantities:
    :data:`HOLD_SCALARS` and ``held_<column>`` of every force or drive column."""
    held = {f"held_{n}" for n in names if _HELD_COLUMN.match(n) and not n.startswith("held_")}
    return tuple(sorted(held | set(HOLD_SCALARS)))


@dataclass(frozen=True)
class HoldResult:
    """A design held for a time.

    Attributes
    ----------
    at : ``"displacement"`` or ``"force"``.
    time_h : float, h — the hold time; ``reduced_time_h`` the same at the law's reference
        temperature (``t / a_T``).
    temperature_C : float or None, deg C.
    drive_column, force_column : str — the table's driven and force columns.
    drive, force : float — the held state at t = 0 (units of the columns).
    held_drive, held_force : float — the state after the hold.
    retention : float — ``E_R(t)/E0`` (force kept by a displacement hold).
    growth : float — ``E0 J(t)`` (a force hold's strain growth; ``held_drive / drive`` is the
        structure's, equal to it for linear geometry).
    stress_MPa : float, MPa — the largest peak stress of the hold (the elastic one at the
        start of a displacement hold; the larger of start and end of a force hold).
    stress_ratio : float — ``stress_MPa`` over the material's strength.
    in_range : bool — ``stress_ratio <= law.max_stress_ratio``.
    law : CreepLaw
    method : str
    note : str — why the held values are not given (out of range), else "".
    held_curve : (n_rows,) or None — a displacement hold's whole held force column.
    """

    at: str
    time_h: float
    reduced_time_h: float
    temperature_C: float | None
    drive_column: str
    force_column: str
    drive: float
    force: float
    held_drive: float
    held_force: float
    retention: float
    growth: float
    stress_MPa: float
    stress_ratio: float
    in_range: bool
    law: CreepLaw
    method: str
    note: str
    held_curve: np.ndarray | None = None

    @property
    def held_name(self) -> str:
        """The summary name of the held value: ``held_<force column>`` (displacement hold) or
        ``held_<driven column>`` (force hold)."""
        return f"held_{self.force_column if self.at == 'displacement' else self.drive_column}"

    def values(self) -> dict[str, Any]:
        """The scalars a requirement judges; None (NOT MET) when out of the law's range."""
        ok = self.in_range
        out: dict[str, Any] = {"hold_stress_ratio": self.stress_ratio}
        if self.at == "displacement":
            out[self.held_name] = self.held_force if ok else None
            out["force_retention"] = self.retention if ok else None
        else:
            out[self.held_name] = self.held_drive if ok else None
            growth = self.held_drive / self.drive if self.drive != 0.0 else math.nan
            out["deflection_growth"] = growth if ok else None
        return out

    def summary(self) -> dict[str, Any]:
        """The scalars a result's summary carries."""
        start = {
            f"hold_initial_{self.force_column}": self.force,
            f"hold_{self.drive_column}": self.drive,
        }
        return {
            **self.values(),
            **start,
            "hold_time_h": self.time_h,
            "hold_temperature_C": self.temperature_C,
            "hold_in_range": self.in_range,
            "hold_method": self.method,
            "creep_data_source": self.law.label,
            **({"hold_note": self.note} if self.note else {}),
        }

    def record(self) -> dict[str, Any]:
        """JSON-ready detail (``info["hold"]``)."""
        law = self.law
        return {
            **self.summary(),
            "at": self.at,
            "reduced_time_h": self.reduced_time_h,
            "held_drive": self.held_drive,
            "held_force": self.held_force,
            "relaxation_ratio": self.retention,
            "compliance_ratio": self.growth,
            "stress_MPa": self.stress_MPa,
            "law": {
                "tau_h": law.tau_h, "n": law.n, "max_stress_ratio": law.max_stress_ratio,
                "reference_temperature_C": law.reference_temperature_C,
                "assumed": law.assumed, "source": law.source,
            },
        }  # fmt: skip


def _interp(x: np.ndarray, y: np.ndarray, at: float, what: str) -> float:
    """``y`` at ``x = at`` on the branch of ``at``'s sign, from the unloaded state."""
    sign = 1.0 if at >= 0.0 else -1.0
    side = (x * sign) >= 0.0
    xs, ys = np.abs(x[side]), y[side]
    order = np.argsort(xs, kind="stable")
    xs, ys = xs[order], ys[order]
    if xs.size == 0 or abs(at) > xs[-1] * (1.0 + 1e-9):
        top = float(xs[-1]) if xs.size else 0.0
        raise OptimiseError(
            f"hold: the held {what} {at:g} lies beyond the traced stroke {sign * top:g}; hold "
            "within it (or give a fraction)"
        )
    if xs[0] > 0.0:
        xs, ys = np.concatenate([[0.0], xs]), np.concatenate([[0.0], ys])
    return float(np.interp(abs(at), xs, ys))


def hold_of_table(
    spec: HoldSpec,
    table: Mapping[str, Sequence[float] | np.ndarray],
    x_column: str,
    force_column: str,
    law: CreepLaw,
    strength_MPa: float,
    *,
    stress_column: str = "peak_stress_MPa",
    scale: float = 1.0,
    scale_model: str = "",
) -> HoldResult:
    """The design of ``table`` held as ``spec`` says, with the creep ``law``.

    Parameters
    ----------
    table : response columns, each (n_rows,): ``x_column`` (the drive from the unloaded
        state), ``force_column`` and ``stress_column`` (MPa, the solver's peak stress magnitude
        at each row), of one elastic solve with the material's E (= E0).
    law : the creep law; ``strength_MPa`` the material's strength (its ``yield_MPa``) the
        stress ratio is taken against.
    scale : factor on the table's peak stress (the verdict's highest-fidelity figure over the
        table's, as for the fatigue life), ``scale_model`` that figure's model.

    Raises
    ------
    OptimiseError
        A missing column, a held value beyond the traced curve, a force that is not rising up
        to the crept force (force hold), a temperature the law cannot be shifted to.
    """
    for col in (x_column, force_column, stress_column):
        if col not in table:
            raise OptimiseError(
                f"hold: the response has no column '{col}' (it has {', '.join(table)})"
            )
    x = np.asarray(table[x_column], dtype=float)
    f = np.asarray(table[force_column], dtype=float)
    peak = np.abs(np.asarray(table[stress_column], dtype=float)) * scale
    ok = np.isfinite(x) & np.isfinite(f) & np.isfinite(peak)
    x, f, peak = x[ok], f[ok], peak[ok]
    try:
        t_red = law.reduced_time(spec.time_h, spec.temperature_C)
    except FeaError as exc:
        raise OptimiseError(f"hold.temperature_C: {str(exc).removeprefix('creep: ')}") from None
    retention = float(law.relaxation_ratio(t_red))
    growth = float(law.compliance_ratio(t_red))
    curve = None
    if spec.at == "displacement":
        stroke = float(x[np.argmax(np.abs(x))]) if x.size else 0.0  # signed: its branch
        drive = float(spec.level) if spec.level is not None else float(spec.fraction) * stroke
        force = _interp(x, f, drive, x_column)
        stress = _interp(x, peak, drive, x_column)
        held_drive, held_force = drive, float(relaxed_force([force], retention)[0])
        curve = relaxed_force(np.asarray(table[force_column], dtype=float), retention)
        how = (
            f"displacement held at {x_column} = {drive:g} for {spec.time_h:g} h: "
            f"force x E_R(t)/E0 = {retention:.4g}"
        )
    else:
        fmax = float(f[np.argmax(np.abs(f))]) if f.size else 0.0  # signed: its branch
        force = float(spec.level) if spec.level is not None else float(spec.fraction) * fmax
        try:
            drive, held_drive = crept_drive(x, f, force, growth)
        except FeaError as exc:
            raise OptimiseError(f"hold: {str(exc).removeprefix('creep: ')}") from None
        held_force = force
        # the stress at the crept drive with E = 1/J: the elastic stress there over E0 J
        stress = max(
            _interp(x, peak, drive, x_column), _interp(x, peak, held_drive, x_column) / growth
        )
        how = (
            f"force held at {force_column} = {force:g} for {spec.time_h:g} h: the drive at "
            f"force x E0 J(t) = {growth:.4g}"
        )
    ratio = stress / strength_MPa if strength_MPa > 0 else math.inf
    in_range = ratio <= law.max_stress_ratio * (1.0 + 1e-12)
    note = ""
    if not in_range:
        note = (
            f"out of range: the part's stress {stress:.4g} MPa is {ratio:.3f} of the strength "
            f"{strength_MPa:g} MPa, above the {law.max_stress_ratio:g} the creep law was fitted "
            "to; the linear creep law does not hold there (printed polymers creep faster)"
        )
    temp = "" if spec.temperature_C is None else f" at {spec.temperature_C:g} C"
    shifted = f" (reduced time {t_red:.4g} h)" if t_red != spec.time_h else ""
    where = f", stress scaled by {scale:.4g} to the {scale_model} peak" if scale != 1.0 else ""
    method = (
        f"Findley power-law creep, quasi-elastic: {how}{temp}{shifted}; exact for linear "
        f"geometry, quasi-elastic at large deflection{where}"
    )
    return HoldResult(
        at=spec.at, time_h=spec.time_h, reduced_time_h=t_red, temperature_C=spec.temperature_C,
        drive_column=x_column, force_column=force_column, drive=drive, force=force,
        held_drive=held_drive, held_force=held_force, retention=retention, growth=growth,
        stress_MPa=stress, stress_ratio=ratio, in_range=in_range, law=law, method=method,
        note=note, held_curve=curve,
    )  # fmt: skip
