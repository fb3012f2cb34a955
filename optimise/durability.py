"""Fatigue life of a design over a duty cycle, from its own response table.

Every kind's result carries a response table whose driven column (the plot's x:
``displacement_mm``, ``rotation_deg``, ...) and ``peak_stress_MPa`` column come from the same
nonlinear solve. A study's ``duty_cycle:`` block (:class:`DutyCycleSpec`) gives load levels in
that driven unit (or as a fraction of the traced stroke) with their cycle counts or shares, or a
drive history counted by rainflow. :func:`life_of_table` interpolates the peak stress at each
level's extreme drives, turns them into a stress amplitude and mean, and sums the damage with
Miner's rule on the material's S–N curve (:mod:`flexopt.fea.fatigue`).

Units: drives in the unit of the driven column, stresses in MPa, lives in cycles and hours,
rates in Hz. The method, its data and its limits: docs/durability.md.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.fea.fatigue import (
    CORRECTIONS,
    LoadLevel,
    SNCurve,
    material_sn_curve,
    miner,
    rainflow_cycles,
)
from flexopt.optimise.errors import OptimiseError
from pydantic import BaseModel, ConfigDict, Field, model_serializer, model_validator

__all__ = [
    "LIFE_QUANTITIES",
    "STRESS_SETTINGS",
    "DutyCycleSpec",
    "DutyLevel",
    "LevelLife",
    "LifeResult",
    "life_constraint",
    "life_of_table",
    "signed_peak_stress",
]

#: The quantities a ``requirements:`` item may judge when the study has a ``duty_cycle:``.
LIFE_QUANTITIES = ("life_cycles", "life_hours", "fatigue_damage_per_cycle_block")

#: The key of a result's ``info`` under which a kind whose response has one stress column per
#: setting (a variable-stiffness joint) names them: ``{setting name: stress column}``, several
#: names may share a column (aliases). The life then takes each level's stress from its
#: setting's column (:func:`life_of_table` ``settings=``).
STRESS_SETTINGS = "stress_settings"

_CONFIG = ConfigDict(extra="forbid", frozen=True)


def _without_unset_setting(model: BaseModel, handler: Any) -> dict[str, Any]:
    """The model's dump without ``setting`` when it is None: a study that names no setting
    dumps (evaluation.json's ``inputs.study``, best.json) as it did before the key existed."""
    data = handler(model)
    if isinstance(data, dict) and data.get("setting", 0) is None:
        data.pop("setting")
    return data


class DutyLevel(BaseModel):
    """One load level of a duty cycle.

    The drive cycles between ``mean`` (the level's minimum drive, default 0: one-sided
    0 -> drive) and ``drive``; ``reversed: true`` cycles between -drive and +drive. Exactly one
    of ``drive`` (unit of the driven column) or ``fraction`` (of the traced stroke, 0..1), and
    exactly one of ``cycles`` (per block) or ``share_percent`` (of all cycles).
    """

    model_config = _CONFIG

    drive: float | None = Field(None, description="peak drive, unit of the driven column")
    fraction: float | None = Field(
        None, gt=0.0, le=1.0, description="peak drive as a fraction of the traced stroke"
    )
    cycles: float | None = Field(None, gt=0.0, description="cycles of this level per block")
    share_percent: float | None = Field(
        None, gt=0.0, le=100.0, description="share of all cycles, percent"
    )
    mean: float | None = Field(
        None, description="the level's minimum drive (default 0), unit of the driven column"
    )
    reversed: bool = Field(False, description="fully reversed: -drive to +drive")
    setting: str | None = Field(
        None,
        min_length=1,
        description="the setting this level runs at, in a kind whose response has a stress per "
        "setting (leaf_spring_joint: stiff / soft); default: the worst setting",
    )

    @model_serializer(mode="wrap")
    def _dump(self, handler: Any) -> dict[str, Any]:
        return _without_unset_setting(self, handler)

    @model_validator(mode="after")
    def _one_of_each(self) -> DutyLevel:
        if (self.drive is None) == (self.fraction is None):
            raise ValueError("give exactly one of drive (driven unit) or fraction (of the stroke)")
        if (self.cycles is None) == (self.share_percent is None):
            raise ValueError("give exactly one of cycles (per block) or share_percent")
        if self.drive is not None and not math.isfinite(self.drive):
            raise ValueError(f"drive = {self.drive!r} must be finite")
        if self.reversed and self.mean is not None:
            raise ValueError("reversed: true cycles -drive..+drive; leave mean out")
        return self


class DutyCycleSpec(BaseModel):
    """The ``duty_cycle:`` block of a study: load levels or a drive history.

    In YAML a mapping ``{levels: [...], rate_hz: 1.0, correction: goodman}`` or
    ``{history: [0, 10, 2, 8, 0], rate_hz: ...}``; a bare list is the levels.
    """

    model_config = _CONFIG

    levels: tuple[DutyLevel, ...] | None = Field(
        None, min_length=1, max_length=1000, description="load levels of one block"
    )
    history: tuple[float, ...] | None = Field(
        None,
        min_length=2,
        max_length=100_000,
        description="drive history of one block (driven unit), counted by rainflow",
    )
    rate_hz: float | None = Field(None, gt=0.0, description="cycles per second in service")
    correction: Literal["goodman", "swt", "none"] = Field(
        "goodman", description="mean-stress correction (docs/durability.md)"
    )
    surface: str | None = Field(
        None, description="steels: surface finish of the S-N curve (default machined)"
    )
    setting: str | None = Field(
        None,
        min_length=1,
        description="the setting a history (or a level without its own) runs at, in a kind "
        "whose response has a stress per setting; default: the worst setting",
    )

    @model_serializer(mode="wrap")
    def _dump(self, handler: Any) -> dict[str, Any]:
        return _without_unset_setting(self, handler)

    @model_validator(mode="before")
    @classmethod
    def _list_is_levels(cls, value: Any) -> Any:
        if isinstance(value, list | tuple):
            return {"levels": list(value)}
        return value

    @model_validator(mode="after")
    def _levels_or_history(self) -> DutyCycleSpec:
        if (self.levels is None) == (self.history is None):
            raise ValueError("give exactly one of levels (a list) or history (drive values)")
        if self.history is not None and not all(math.isfinite(v) for v in self.history):
            raise ValueError("history holds a NaN or inf; give finite drive values")
        if self.levels:
            shares = [lv.share_percent is not None for lv in self.levels]
            if any(shares) and not all(shares):
                raise ValueError(
                    "levels mix cycles and share_percent; give every level cycles, or every "
                    "level a share_percent"
                )
            if all(shares):
                total = sum(float(lv.share_percent or 0.0) for lv in self.levels)
                if abs(total - 100.0) > 1e-6:
                    raise ValueError(f"the levels' share_percent sum to {total:.6g}, not 100")
        return self


@dataclass(frozen=True)
class LevelLife:
    """One counted level: its drives, stresses and damage.

    Attributes
    ----------
    drive_min, drive_max : float, unit of the driven column
    stress_min_MPa, stress_max_MPa : float, MPa — signed peak stress at the two drives.
    amplitude_MPa, mean_MPa : float, MPa
    cycles : float — cycles per block (a share as a fraction of one cycle).
    cycles_to_failure : float — N_i (``inf`` below the endurance limit).
    damage : float — n_i / N_i per block.
    setting : str — the setting whose stress the level took ("" in a kind with one response).
    """

    drive_min: float
    drive_max: float
    stress_min_MPa: float
    stress_max_MPa: float
    amplitude_MPa: float
    mean_MPa: float
    cycles: float
    cycles_to_failure: float
    damage: float
    setting: str = ""

    def record(self) -> dict[str, Any]:
        """JSON-ready (``inf`` as None; ``setting`` only where the kind has settings)."""
        out: dict[str, Any] = {
            k: (v if math.isfinite(v) else None) for k, v in self.__dict__.items() if k != "setting"
        }
        if self.setting:
            out["setting"] = self.setting
        return out


@dataclass(frozen=True)
class LifeResult:
    """Miner's life of a design over its duty cycle.

    Attributes
    ----------
    levels : tuple of LevelLife
    damage_per_block : float — sum of the levels' damage in one block.
    life_cycles : float, cycles (``inf`` when no level damages)
    life_hours : float or None, h — None without ``rate_hz``.
    in_range : bool — False when a level fails in under 10^3 cycles (low-cycle fatigue).
    method : str — the method, the correction and where the stress is taken.
    source : str — the S–N data's source.
    scale : float — the factor on the beam's peak stress (the verdict's highest-fidelity
        figure over the beam's), 1 when the kind has one model.
    stress_figure : str — the stress figure the amplitudes stand for (the model and the
        quantity: ``3D solid (peak_stress_3d_MPa)``); the table's own peak when empty.
    setting_note : str — in a kind with a stress per setting, which setting the levels ran at
        (the worst one, by name, where a level names none); "" in a kind with one response.
    """

    levels: tuple[LevelLife, ...]
    damage_per_block: float
    life_cycles: float
    life_hours: float | None
    in_range: bool
    method: str
    source: str
    scale: float
    stress_figure: str = ""
    setting_note: str = ""

    def summary(self) -> dict[str, Any]:
        """The scalars a result's summary carries (``inf`` as None: infinite life)."""

        def fin(v: float | None) -> float | None:
            return v if v is not None and math.isfinite(v) else None

        return {
            "life_cycles": fin(self.life_cycles),
            "life_hours": fin(self.life_hours),
            "fatigue_damage_per_cycle_block": self.damage_per_block,
            "life_in_range": self.in_range,
            "life_infinite": not math.isfinite(self.life_cycles),
            "life_method": self.method,
            "fatigue_data_source": self.source,
            "life_stress_figure": self.stress_figure or "the response table's peak_stress_MPa",
            # only in a kind with a stress per setting: other kinds' records stay as they were
            **({"life_setting": self.setting_note} if self.setting_note else {}),
        }

    def values(self) -> dict[str, Any]:
        """The scalars a requirement judges: infinite life as ``inf`` (it meets any minimum);
        a low-cycle level makes the life None (NOT MET: outside the method)."""
        if not self.in_range:
            return {"life_cycles": None, "life_hours": None,
                    "fatigue_damage_per_cycle_block": self.damage_per_block}  # fmt: skip
        return {
            "life_cycles": self.life_cycles,
            "life_hours": self.life_hours,
            "fatigue_damage_per_cycle_block": self.damage_per_block,
        }


def signed_peak_stress(
    drive: np.ndarray, peak_MPa: np.ndarray, at: float, scale: float = 1.0
) -> float:
    """The signed peak stress (MPa) at drive ``at``, interpolated in the response table.

    The table's peak is the solver's largest stress magnitude at each row, wherever it sits.
    For a drive of the sign the table traces it is interpolated there; a drive of the other
    sign is taken as the mirror (the peak of the same magnitude, of opposite sign: a response
    odd in the drive), which is what a reversed cycle of a symmetric part loads.

    Parameters
    ----------
    drive : (n_rows,) the driven column.
    peak_MPa : (n_rows,) MPa, the peak stress magnitude of each row.
    at : the drive, in the unit of ``drive``.
    scale : factor on the peak (the verdict's highest-fidelity figure over the beam's).

    Raises
    ------
    OptimiseError
        When ``at`` lies beyond the traced stroke (the table is not extrapolated).
    """
    x = np.asarray(drive, dtype=float)
    s = np.abs(np.asarray(peak_MPa, dtype=float))
    ok = np.isfinite(x) & np.isfinite(s)
    x, s = x[ok], s[ok]
    if at == 0.0:
        return 0.0
    sign = 1.0 if at > 0 else -1.0
    side = (x * sign) >= 0.0
    if np.count_nonzero(side & (x != 0.0)) == 0:
        side = (x * -sign) >= 0.0  # the mirror: the table traces the other sign only
    xs, ss = np.abs(x[side]), s[side]
    if xs.size == 0:
        raise OptimiseError("duty_cycle: the response table has no finite row to interpolate")
    order = np.argsort(xs, kind="stable")
    xs, ss = xs[order], ss[order]
    if abs(at) > xs[-1] * (1.0 + 1e-9):
        raise OptimiseError(
            f"duty_cycle: drive {at:g} lies beyond the traced stroke {xs[-1]:g}; give drives "
            "within it (or a fraction of it)"
        )
    if xs[0] > 0.0:  # the unloaded row: zero drive, zero stress
        xs, ss = np.concatenate([[0.0], xs]), np.concatenate([[0.0], ss])
    return sign * scale * float(np.interp(abs(at), xs, ss))


def _drive_cycles(
    spec: DutyCycleSpec, stroke: float
) -> list[tuple[float, float, float, bool, str | None]]:
    """``(drive_min, drive_max, count, share, setting)`` of every level or counted cycle
    (``setting``: the level's, else the block's, else None: the worst)."""
    out = []
    if spec.history is not None:
        for rng, mean, count in rainflow_cycles(spec.history):
            if rng > 0.0:
                out.append((mean - 0.5 * rng, mean + 0.5 * rng, count, False, spec.setting))
        return out
    for lv in spec.levels or ():
        top = float(lv.drive) if lv.drive is not None else float(lv.fraction or 0.0) * stroke
        low = -top if lv.reversed else float(lv.mean or 0.0)
        count = float(lv.cycles) if lv.cycles is not None else float(lv.share_percent) / 100.0
        setting = lv.setting if lv.setting is not None else spec.setting
        out.append((min(low, top), max(low, top), count, lv.share_percent is not None, setting))
    return out


def _distinct_settings(settings: Mapping[str, str]) -> dict[str, str]:
    """One name per stress column (the first given: aliases share a column), in order."""
    out: dict[str, str] = {}
    for name, column in settings.items():
        if column not in out.values():
            out[name] = column
    return out


def life_of_table(
    spec: DutyCycleSpec,
    table: Mapping[str, Sequence[float] | np.ndarray],
    x_column: str,
    material: str | SNCurve,
    *,
    stress_column: str = "peak_stress_MPa",
    scale: float = 1.0,
    scale_model: str = "",
    stress_figure: str = "",
    settings: Mapping[str, str] | None = None,
) -> LifeResult:
    """Miner's life over ``spec`` of a design whose response is ``table``.

    Parameters
    ----------
    spec : the duty cycle.
    table : response columns, each (n_rows,): ``x_column`` (the drive) and ``stress_column``
        (MPa, the solver's peak stress magnitude at each row, of the same solve).
    x_column : the driven column (the kind's plot x).
    material : a built-in material's name (its ``FATIGUE_DATA``) or an :class:`SNCurve`.
    scale : factor on the peak stress (the highest-fidelity figure over the beam's, >= 0).
    scale_model : the model that factor comes from, named in ``method``.
    stress_figure : the figure the scaled stresses stand for (model and quantity), recorded.
    settings : for a kind whose response has one stress column per setting (a variable-
        stiffness joint's stiffness settings, each its own nonlinear solve over the same
        driven column): setting name -> its stress column (MPa, (n_rows,)); several names may
        share a column (aliases). Each level takes the column of its ``setting``; the levels
        without one run at the **worst** setting: the one whose damage per block is largest
        when they all run there (named in ``setting_note``). ``stress_column`` is then unused.

    Raises
    ------
    OptimiseError
        When a column is missing, a drive lies beyond the traced stroke, the material has no
        fatigue data, a level names a setting the response does not have (or any setting,
        without ``settings``).
    """
    columns = [stress_column] if settings is None else list(dict.fromkeys(settings.values()))
    for col in (x_column, *columns):
        if col not in table:
            raise OptimiseError(
                f"duty_cycle: the response has no column '{col}' (it has {', '.join(table)})"
            )
    x = np.asarray(table[x_column], dtype=float)
    finite = np.abs(x[np.isfinite(x)])
    stroke = float(finite.max()) if finite.size else 0.0
    try:
        curve = (
            material
            if isinstance(material, SNCurve)
            else material_sn_curve(material, surface=spec.surface)
        )
    except FeaError as exc:
        raise OptimiseError(f"duty_cycle: {exc}") from None
    if spec.correction not in CORRECTIONS:  # the model's Literal holds it; a guard for callers
        raise OptimiseError(f"duty_cycle: correction {spec.correction!r} is unknown")
    cycles = _drive_cycles(spec, stroke)
    if not cycles:  # a flat history: nothing cycles
        raise OptimiseError("duty_cycle: the history holds no cycle (every value the same)")
    named = {c[4] for c in cycles if c[4] is not None}
    if settings is None and named:
        raise OptimiseError(
            f"duty_cycle: setting '{sorted(named)[0]}': this response has one stress per row, "
            "no settings; leave setting out"
        )
    unknown = sorted(named - set(settings or {}))
    if unknown:
        raise OptimiseError(
            f"duty_cycle: setting '{unknown[0]}' is not a setting of this response; use one of "
            + ", ".join(settings or {})
        )

    def count(worst: str | None) -> tuple[Any, list[tuple[Any, ...]]]:
        """Miner's sum with the unnamed levels at setting ``worst`` (None: no settings)."""
        loads, rows = [], []
        for lo, hi, n, share, setting in cycles:
            name = setting if setting is not None else worst
            peak = np.asarray(
                table[stress_column if settings is None else settings[str(name)]], dtype=float
            )
            s_lo = signed_peak_stress(x, peak, lo, scale)
            s_hi = signed_peak_stress(x, peak, hi, scale)
            amp, mean = 0.5 * abs(s_hi - s_lo), 0.5 * (s_hi + s_lo)
            loads.append(
                LoadLevel(
                    amplitude_MPa=amp,
                    mean_MPa=mean,
                    **({"share": n} if share else {"cycles": n}),
                )
            )
            rows.append((lo, hi, s_lo, s_hi, amp, mean, n, name or ""))
        out = miner(curve, loads, rate_hz=spec.rate_hz or 1.0, correction=spec.correction)
        return out, rows

    setting_note = ""
    if settings is None:
        result, rows = count(None)
    else:
        distinct = _distinct_settings(settings)
        if all(c[4] is not None for c in cycles):
            result, rows = count(None)
            setting_note = "every level at the setting it names"
        else:
            tried = {name: count(name) for name in distinct}
            # the largest damage per block; the first listed on a tie
            worst = max(tried, key=lambda k: (tried[k][0].damage_per_block, -list(tried).index(k)))
            result, rows = tried[worst]
            others = ", ".join(
                f"{k}: {tried[k][0].damage_per_block:.4g}" for k in tried if k != worst
            )
            unnamed = "every level" if not named else "the levels without a setting"
            setting_note = (
                f"{unnamed} at the worst setting, {worst} (damage per block "
                f"{result.damage_per_block:.4g}; at {others})"
            )
    levels = tuple(
        LevelLife(lo, hi, slo, shi, amp, mean, n, nf, d, name)
        for (lo, hi, slo, shi, amp, mean, n, name), nf, d in zip(
            rows, result.cycles_to_failure, result.damage_per_level, strict=True
        )
    )
    where = "the solver's peak stress at each level's drives (its location tracked per row)"
    if settings is not None:
        where += ", from the solve of the level's setting; " + setting_note
    if scale != 1.0:
        where += f", scaled by {scale:.4g} to the {scale_model or 'higher-fidelity'} peak"
    counting = "rainflow (ASTM E1049-85)" if spec.history is not None else "levels as given"
    method = (
        f"stress-life (Basquin S-N), {spec.correction} mean-stress correction, Miner's sum, "
        f"{counting}; stress: {where}"
    )
    estimate = curve.estimate and "estimate" not in curve.source.lower()
    source = curve.source + (" (estimate)" if estimate else "")
    if spec.surface is not None and not isinstance(material, SNCurve):
        # the data's source names its default finish; this curve is the one asked for
        source += f"; this curve: {spec.surface} surface (Se = {curve.strength_MPa(1e6):.4g} MPa)"
    return LifeResult(
        levels=levels,
        damage_per_block=result.damage_per_block,
        life_cycles=result.life_cycles,
        life_hours=result.life_hours if spec.rate_hz is not None else None,
        in_range=result.in_range,
        method=method,
        source=source,
        scale=scale,
        stress_figure=stress_figure,
        setting_note=setting_note,
    )


#: The g of a life requirement whose life could not be computed (or is zero), decades: a
#: large violation, finite so that an optimiser can still rank (as MISSING_CONSTRAINT).
_LIFE_G_CAP = 100.0


def life_constraint(requirement: Any, values: Mapping[str, Any]) -> float:
    """The ``g <= 0`` row of a requirement on a life quantity, in decades.

    A life spans decades (10^4 to 10^9 cycles for a tenth of the stress), so the row is the
    distance in log10 between the value and its bound: ``log10(min) - log10(value)`` for a
    minimum (``life_cycles``, ``life_hours``), ``log10(value) - log10(max)`` for a maximum
    (``fatigue_damage_per_cycle_block``); a range takes the worse end. An infinite life meets
    every minimum (``-_LIFE_G_CAP``); a life that was not computed or lies in low-cycle fatigue
    (None, NaN) is ``+_LIFE_G_CAP``.

    Parameters
    ----------
    requirement : a MinValue / MaxValue / Range on one of :data:`LIFE_QUANTITIES` (its
        ``minimum`` / ``maximum`` attributes in the quantity's unit, > 0).
    values : the life values (:meth:`LifeResult.values`).
    """
    raw = values.get(requirement.quantity)
    if raw is None or isinstance(raw, bool) or math.isnan(float(raw)):
        return _LIFE_G_CAP
    value = float(raw)  # +inf: an infinite life

    def log(v: float) -> float:
        if v <= 0.0:
            return -math.inf
        return math.log10(v)

    rows = []
    lo = getattr(requirement, "minimum", None)
    hi = getattr(requirement, "maximum", None)
    if lo is not None and float(lo) > 0.0:
        rows.append(log(float(lo)) - log(value))
    if hi is not None:
        rows.append(log(value) - log(float(hi)) if float(hi) > 0.0 else _LIFE_G_CAP)
    if not rows:  # a minimum <= 0: met by any life
        return -_LIFE_G_CAP
    g = max(rows)
    return float(min(max(g, -_LIFE_G_CAP), _LIFE_G_CAP))
