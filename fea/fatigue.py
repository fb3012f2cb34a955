"""Uniaxial stress-life (S–N) fatigue: curve, mean-stress correction, Miner's sum, rainflow.

Units: stresses in MPa, lives in cycles (one cycle = one full load reversal pair), rates in Hz
(cycles per second), lives in hours. See docs/durability.md for the method, the data and the
limits.

The S–N curve is written in Shigley's form

    S = a N^b,    N = (S / a)^(1/b)            (b < 0)

with S the fully reversed stress amplitude (MPa) that fails the part in N cycles. It is Basquin's
law: sigma_a = sigma_f' (2N)^b with sigma_f' = a 2^-b. Steels and titanium have an endurance limit
Se at 10^6 cycles (infinite life at or below it); printed polymers have none (the line goes on).

A cycle with a mean stress is turned into the fully reversed amplitude of equal damage by one of

- ``"goodman"`` (the default): sigma_ar = sigma_a / (1 - sigma_m / Sut) for sigma_m > 0;
  compressive means are not credited (sigma_ar = sigma_a). Needs only the ultimate strength;
  conservative for ductile metals under tensile means.
- ``"swt"`` (Smith–Watson–Topper): sigma_ar = sqrt(sigma_max sigma_a) for sigma_max > 0, no
  damage when the cycle never opens (sigma_max <= 0). Credits compressive means; often closer to
  tests for steels under tensile means.
- ``"none"``: sigma_ar = sigma_a (fully reversed data used as is).

The counting is the ``rainflow`` package (MIT, ASTM E1049-85).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import rainflow
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import get_fatigue_data

__all__ = [
    "CORRECTIONS",
    "SURFACE_FACTORS",
    "LoadLevel",
    "MinerResult",
    "SNCurve",
    "count_cycles",
    "cycles_to_failure",
    "equivalent_amplitude",
    "levels_from_history",
    "material_sn_curve",
    "miner",
    "rainflow_cycles",
    "shigley_sn_curve",
    "size_factor_bending",
    "surface_factor",
]

CORRECTIONS = ("goodman", "swt", "none")

# Shigley Table 6-2 (Noll & Lipson 1946): ka = a Sut^b, Sut in MPa.
SURFACE_FACTORS: dict[str, tuple[float, float]] = {
    "ground": (1.58, -0.085),
    "machined": (4.51, -0.265),
    "cold-drawn": (4.51, -0.265),
    "hot-rolled": (57.7, -0.718),
    "as-forged": (272.0, -0.995),
}

LOW_CYCLE_LIMIT = 1.0e3  # below 10^3 cycles the stress-life method is out of its range
ENDURANCE_CYCLES = 1.0e6  # the knee of the steels' curve (Shigley)


def _positive(name: str, value: float, fix: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise FeaError(f"fatigue: {name} = {value!r} must be a finite number > 0; {fix}")
    return v


@dataclass(frozen=True)
class SNCurve:
    """Fully reversed stress-life curve S = a N^b with an optional endurance limit.

    Attributes
    ----------
    a_MPa : float, MPa
        Coefficient a (the curve's stress at N = 1).
    b : float
        Exponent b, < 0.
    ultimate_MPa : float, MPa
        Tensile strength Sut (Goodman's intercept).
    endurance_MPa : float or None, MPa
        Stress amplitude at or below which the life is infinite; None (polymers): no limit.
    source : str
        Where the curve comes from.
    estimate : bool
        True when the curve is a documented rule rather than a fit for this material.
    """

    a_MPa: float
    b: float
    ultimate_MPa: float
    endurance_MPa: float | None = None
    source: str = "user"
    estimate: bool = False

    def __post_init__(self) -> None:
        _positive("a_MPa", self.a_MPa, "give the S-N coefficient a of S = a N^b in MPa")
        if not (math.isfinite(self.b) and -1.0 < self.b < 0.0):
            raise FeaError(
                f"fatigue: b = {self.b!r} must lie in (-1, 0) (S = a N^b falls with N); "
                "check the sign of the Basquin exponent"
            )
        _positive("ultimate_MPa", self.ultimate_MPa, "give the tensile strength Sut in MPa")
        if self.endurance_MPa is not None:
            _positive(
                "endurance_MPa", self.endurance_MPa, "give the endurance limit in MPa or None"
            )

    @property
    def sigma_f_prime_MPa(self) -> float:
        """Basquin's sigma_f' = a 2^-b (sigma_a = sigma_f' (2N)^b), MPa."""
        return self.a_MPa * 2.0 ** (-self.b)

    def strength_MPa(self, cycles: float) -> float:
        """Fully reversed fatigue strength at ``cycles`` (MPa), not below the endurance limit."""
        n = _positive("cycles", cycles, "give a number of cycles > 0")
        s = self.a_MPa * n**self.b
        if self.endurance_MPa is not None:
            s = max(s, self.endurance_MPa)
        return s

    def cycles_to_failure(self, amplitude_MPa: float) -> float:
        """Cycles to failure at a fully reversed amplitude (MPa); ``inf`` at or below the endurance
        limit, ``inf`` at zero amplitude.

        Values below 10^3 cycles are returned as computed, but the stress-life method does not hold
        there (low-cycle fatigue): see :attr:`MinerResult.in_range`.
        """
        s = float(amplitude_MPa)
        if not (s >= 0.0):
            raise FeaError(
                f"fatigue: amplitude_MPa = {amplitude_MPa!r} must be >= 0 (a half range, MPa)"
            )
        if s == 0.0 or (self.endurance_MPa is not None and s <= self.endurance_MPa):
            return math.inf
        if math.isinf(s):
            return 0.0
        return (s / self.a_MPa) ** (1.0 / self.b)


def surface_factor(ultimate_MPa: float, surface: str) -> float:
    """Marin surface factor ka = a Sut^b (Shigley Table 6-2), at most 1.

    Parameters
    ----------
    ultimate_MPa : float, MPa
    surface : str
        One of ``SURFACE_FACTORS`` (``"ground"``, ``"machined"``, ``"cold-drawn"``,
        ``"hot-rolled"``, ``"as-forged"``).
    """
    sut = _positive("ultimate_MPa", ultimate_MPa, "give the tensile strength Sut in MPa")
    if surface not in SURFACE_FACTORS:
        raise FeaError(
            f"fatigue: surface = {surface!r} is unknown; choose one of {', '.join(SURFACE_FACTORS)}"
        )
    a, b = SURFACE_FACTORS[surface]
    return min(1.0, a * sut**b)


def size_factor_bending(diameter_mm: float) -> float:
    """Marin size factor kb in bending (Shigley Eq. 6-20, mm), 1 below 2.79 mm.

    For a non-rotating rectangular section b x h use the equivalent diameter 0.808 sqrt(b h)
    (Shigley Eq. 6-25). Thin flexures (< 2.79 mm, below the fit's range) take kb = 1; axial
    loading has no size effect (kb = 1).
    """
    d = _positive("diameter_mm", diameter_mm, "give the (equivalent) diameter in mm")
    if d <= 2.79:
        return 1.0
    if d <= 51.0:
        return 1.24 * d**-0.107
    if d <= 254.0:
        return 1.51 * d**-0.157
    raise FeaError(
        f"fatigue: diameter_mm = {diameter_mm!r} is beyond Shigley's size-factor fit (254 mm); "
        "give size_factor yourself"
    )


def shigley_sn_curve(
    ultimate_MPa: float,
    *,
    surface: str = "machined",
    size_factor: float = 1.0,
    source: str = "Shigley ch. 6",
    estimate: bool = True,
) -> SNCurve:
    """Steel S–N curve by Shigley's method (Budynas & Nisbett, ch. 6).

    Se' = 0.5 Sut (Sut <= 1400 MPa) else 700 MPa; Se = ka kb Se'; the fraction
    f = (sigma_F'/Sut) (2 10^3)^b_e with sigma_F' = Sut + 345 MPa and
    b_e = -log10(sigma_F'/Se') / log10(2 10^6) (f = 0.9 below Sut = 490 MPa); then
    a = (f Sut)^2 / Se and b = -log10(f Sut / Se) / 3 (Eqs. 6-14, 6-15), so that S(10^3) = f Sut
    and S(10^6) = Se, the endurance limit.

    Parameters
    ----------
    ultimate_MPa : float, MPa
    surface : str
        Surface finish for ka (see :func:`surface_factor`).
    size_factor : float
        kb in (0, 1] (see :func:`size_factor_bending`).
    """
    sut = _positive("ultimate_MPa", ultimate_MPa, "give the tensile strength Sut in MPa")
    kb = _positive("size_factor", size_factor, "give kb in (0, 1]")
    if kb > 1.0:
        raise FeaError(f"fatigue: size_factor = {size_factor!r} must be <= 1 (a knock-down)")
    se_prime = 0.5 * sut if sut <= 1400.0 else 700.0
    se = surface_factor(sut, surface) * kb * se_prime
    if sut < 490.0:
        f = 0.9
    else:
        sigma_f = sut + 345.0
        b_e = -math.log10(sigma_f / se_prime) / math.log10(2.0e6)
        f = sigma_f / sut * (2.0e3) ** b_e
    a = (f * sut) ** 2 / se
    b = -math.log10(f * sut / se) / 3.0
    return SNCurve(
        a_MPa=a, b=b, ultimate_MPa=sut, endurance_MPa=se, source=source, estimate=estimate
    )


def material_sn_curve(
    name: str, *, surface: str | None = None, size_factor: float = 1.0
) -> SNCurve:
    """The S–N curve of a built-in material (fea/materials.py ``FATIGUE_DATA``).

    Parameters
    ----------
    name : str
        Material name (as :func:`flexopt.fea.materials.get_material`).
    surface : str, optional
        Steels/titanium: the finish (default: the table's, ``"machined"``). Refused for polymers.
    size_factor : float
        Steels/titanium: kb. Refused (other than 1) for polymers, whose data are specimen data.
    """
    data = get_fatigue_data(name)
    if data.method == "shigley":
        return shigley_sn_curve(
            data.ultimate_MPa,
            surface=surface or data.surface,
            size_factor=size_factor,
            source=data.source,
            estimate=data.estimate,
        )
    if surface is not None or size_factor != 1.0:
        raise FeaError(
            f"fatigue: material '{name}' has printed-specimen S-N data; surface and size_factor "
            "apply to the steels only: leave them out"
        )
    b = data.basquin_b
    return SNCurve(
        a_MPa=data.strength_1e6_MPa / ENDURANCE_CYCLES**b,
        b=b,
        ultimate_MPa=data.ultimate_MPa,
        endurance_MPa=None,
        source=data.source,
        estimate=data.estimate,
    )


def equivalent_amplitude(
    amplitude_MPa: float, mean_MPa: float, ultimate_MPa: float, correction: str = "goodman"
) -> float:
    """Fully reversed amplitude of equal damage (MPa) for a cycle with a mean stress.

    Parameters
    ----------
    amplitude_MPa : float, MPa
        Half range, >= 0.
    mean_MPa : float, MPa
    ultimate_MPa : float, MPa
        Sut (Goodman only).
    correction : str
        ``"goodman"`` (default), ``"swt"`` or ``"none"`` (module docstring).

    Returns
    -------
    float, MPa
        ``inf`` when the Goodman mean reaches Sut (static failure); 0 for an SWT cycle that never
        opens (sigma_max <= 0).
    """
    sa = float(amplitude_MPa)
    sm = float(mean_MPa)
    if not (math.isfinite(sa) and sa >= 0.0):
        raise FeaError(f"fatigue: amplitude_MPa = {amplitude_MPa!r} must be finite and >= 0")
    if not math.isfinite(sm):
        raise FeaError(f"fatigue: mean_MPa = {mean_MPa!r} must be finite")
    if correction == "none":
        return sa
    if correction == "goodman":
        sut = _positive("ultimate_MPa", ultimate_MPa, "give the tensile strength Sut in MPa")
        if sm <= 0.0:
            return sa  # compressive means are not credited (conservative)
        if sm >= sut:
            return math.inf
        return sa / (1.0 - sm / sut)
    if correction == "swt":
        smax = sm + sa
        if smax <= 0.0:
            return 0.0
        return math.sqrt(smax * sa)
    raise FeaError(
        f"fatigue: correction = {correction!r} is unknown; choose one of {', '.join(CORRECTIONS)}"
    )


def cycles_to_failure(
    curve: SNCurve, amplitude_MPa: float, mean_MPa: float = 0.0, correction: str = "goodman"
) -> float:
    """Cycles to failure of a constant-amplitude cycle (amplitude and mean in MPa)."""
    s = equivalent_amplitude(amplitude_MPa, mean_MPa, curve.ultimate_MPa, correction)
    return curve.cycles_to_failure(s)


@dataclass(frozen=True)
class LoadLevel:
    """One level of a duty cycle: a stress cycle and how often it occurs.

    Give exactly one of ``cycles`` (count per block) or ``share`` (fraction of all cycles).

    Attributes
    ----------
    amplitude_MPa : float, MPa
        Stress amplitude (half range) at the critical location, >= 0.
    mean_MPa : float, MPa
        Mean stress there.
    cycles : float or None
        Cycles of this level in one block (rainflow gives halves: 0.5).
    share : float or None
        Fraction of the cycles (the shares of a duty cycle sum to 1).
    """

    amplitude_MPa: float
    mean_MPa: float = 0.0
    cycles: float | None = None
    share: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.amplitude_MPa) and self.amplitude_MPa >= 0.0):
            raise FeaError(
                f"fatigue: level amplitude_MPa = {self.amplitude_MPa!r} must be finite and >= 0 "
                "(a half range in MPa)"
            )
        if not math.isfinite(self.mean_MPa):
            raise FeaError(f"fatigue: level mean_MPa = {self.mean_MPa!r} must be finite")
        if (self.cycles is None) == (self.share is None):
            raise FeaError(
                "fatigue: a load level takes exactly one of cycles (count per block) or share "
                f"(fraction of cycles); got cycles={self.cycles!r}, share={self.share!r}"
            )
        if self.cycles is not None:
            _positive("level cycles", self.cycles, "give the cycles of this level per block")
        if self.share is not None and not (0.0 < self.share <= 1.0):
            raise FeaError(
                f"fatigue: level share = {self.share!r} must lie in (0, 1] (a fraction of cycles)"
            )


@dataclass(frozen=True)
class MinerResult:
    """Palmgren–Miner damage of a duty block and the life it gives.

    Attributes
    ----------
    equivalent_amplitude_MPa : tuple of float, MPa
        Fully reversed amplitude of each level after the mean-stress correction.
    cycles_to_failure : tuple of float, cycles
        N_i of each level (``inf`` below the endurance limit).
    damage_per_level : tuple of float
        n_i / N_i per block.
    damage_per_block : float
        Sum of ``damage_per_level``.
    block_cycles : float, cycles
        Cycles in one block (1 when the levels are given as shares).
    life_blocks : float
        1 / damage_per_block (``inf`` when no level damages).
    life_cycles : float, cycles
    life_hours : float, hours
        life_cycles / rate_hz / 3600.
    in_range : bool
        False when a damaging level fails in fewer than 10^3 cycles (low-cycle fatigue, outside
        the stress-life method: treat the life as NOT MET, not as a number to trust).
    correction : str
    """

    equivalent_amplitude_MPa: tuple[float, ...]
    cycles_to_failure: tuple[float, ...]
    damage_per_level: tuple[float, ...]
    damage_per_block: float
    block_cycles: float
    life_blocks: float
    life_cycles: float
    life_hours: float
    in_range: bool
    correction: str


def miner(
    curve: SNCurve,
    levels: Sequence[LoadLevel],
    *,
    rate_hz: float,
    correction: str = "goodman",
) -> MinerResult:
    """Miner's linear damage sum over a block of load levels.

    D = sum_i n_i / N_i per block; life = 1/D blocks = (sum_i n_i)/D cycles;
    hours = cycles / rate_hz / 3600. With shares, the block is one cycle (n_i = share_i).

    Parameters
    ----------
    curve : SNCurve
    levels : sequence of LoadLevel
        All with ``cycles`` or all with ``share`` (shares summing to 1).
    rate_hz : float, Hz
        Cycles per second in service (for a rainflow-counted history: its cycle count over its
        duration).
    correction : str
        Mean-stress correction (``"goodman"`` default, ``"swt"``, ``"none"``).
    """
    rate = _positive("rate_hz", rate_hz, "give the cycles per second in service")
    if correction not in CORRECTIONS:
        raise FeaError(
            f"fatigue: correction = {correction!r} is unknown; "
            f"choose one of {', '.join(CORRECTIONS)}"
        )
    levels = list(levels)
    if not levels:
        raise FeaError("fatigue: the duty cycle has no load level; give at least one")
    with_shares = [lv.share is not None for lv in levels]
    if any(with_shares) and not all(with_shares):
        raise FeaError(
            "fatigue: mix of levels with cycles and with share; give every level cycles per "
            "block, or every level a share"
        )
    if all(with_shares):
        total = sum(lv.share for lv in levels)
        if abs(total - 1.0) > 1e-6:
            raise FeaError(f"fatigue: the level shares sum to {total:.6g}, not 1; rescale them")
        counts = [float(lv.share) for lv in levels]
    else:
        counts = [float(lv.cycles) for lv in levels]
    s_eq = [
        equivalent_amplitude(lv.amplitude_MPa, lv.mean_MPa, curve.ultimate_MPa, correction)
        for lv in levels
    ]
    n_f = [curve.cycles_to_failure(s) for s in s_eq]
    damage = [n / nf if nf > 0.0 else math.inf for n, nf in zip(counts, n_f, strict=True)]
    d_block = float(sum(damage))
    block_cycles = float(sum(counts))
    life_blocks = math.inf if d_block == 0.0 else 1.0 / d_block
    life_cycles = life_blocks * block_cycles
    in_range = all(nf >= LOW_CYCLE_LIMIT for nf in n_f)
    return MinerResult(
        equivalent_amplitude_MPa=tuple(s_eq),
        cycles_to_failure=tuple(n_f),
        damage_per_level=tuple(damage),
        damage_per_block=d_block,
        block_cycles=block_cycles,
        life_blocks=life_blocks,
        life_cycles=life_cycles,
        life_hours=life_cycles / rate / 3600.0,
        in_range=in_range,
        correction=correction,
    )


def _history(history_MPa: Sequence[float] | np.ndarray) -> np.ndarray:
    h = np.asarray(history_MPa, dtype=float)
    if h.ndim != 1 or h.size < 2:
        raise FeaError(
            f"fatigue: the load history must be a 1-D sequence of >= 2 values; got shape {h.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(h))
    if bad.size:
        raise FeaError(
            f"fatigue: the load history holds {h[bad[0]]} at index {int(bad[0])} (NaN or inf); "
            "give finite values"
        )
    return h


def count_cycles(history: Sequence[float] | np.ndarray) -> list[tuple[float, float]]:
    """Rainflow count (ASTM E1049-85, the ``rainflow`` package): ``(range, cycles)`` pairs.

    Parameters
    ----------
    history : (n,) array_like
        Load or stress history (any unit; ranges come back in the same unit). Half cycles count 0.5.
    """
    return [(float(r), float(c)) for r, c in rainflow.count_cycles(_history(history))]


def levels_from_history(history_MPa: Sequence[float] | np.ndarray) -> list[LoadLevel]:
    """Rainflow-count a stress history (MPa) into load levels (amplitude, mean, cycles).

    One level per counted cycle or half cycle (``cycles`` 1.0 or 0.5); the history is one block.

    Parameters
    ----------
    history_MPa : (n,) array_like, MPa
        Stress at the critical location over one block, in time order.
    """
    h = _history(history_MPa)
    return [
        LoadLevel(amplitude_MPa=0.5 * float(rng), mean_MPa=float(mean), cycles=float(count))
        for rng, mean, count, _i, _j in rainflow.extract_cycles(h)
        if rng > 0.0
    ]


def rainflow_cycles(history: Sequence[float] | np.ndarray) -> list[tuple[float, float, float]]:
    """Rainflow count (ASTM E1049-85, the ``rainflow`` package) with each cycle's mean:
    ``(range, mean, cycles)`` per counted cycle or half cycle (``cycles`` 1.0 or 0.5).

    Parameters
    ----------
    history : (n,) array_like
        Load, drive or stress history in time order (any unit; ranges and means in the same).
    """
    return [
        (float(rng), float(mean), float(count))
        for rng, mean, count, _i, _j in rainflow.extract_cycles(_history(history))
    ]
