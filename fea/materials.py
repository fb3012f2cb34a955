"""Linear-elastic isotropic materials (units: MPa, kg/m^3)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from flexopt.fea.errors import FeaError

__all__ = [
    "Material",
    "MATERIALS",
    "get_material",
    "material_yield_MPa",
    "FatigueData",
    "FATIGUE_DATA",
    "get_fatigue_data",
    "CREEP_DATA",
    "get_creep_data",
]


@dataclass(frozen=True)
class Material:
    """An isotropic linear-elastic material.

    Attributes
    ----------
    name : str
    E_MPa : float, MPa — Young's modulus.
    nu : float — Poisson's ratio.
    yield_MPa : float, MPa — allowable stress (yield, or flexural strength for polymers).
    density_kg_m3 : float, kg/m^3.
    source : str — where the numbers come from.
    """

    name: str
    E_MPa: float
    nu: float
    yield_MPa: float
    density_kg_m3: float = float("nan")
    source: str = "user"

    def __post_init__(self) -> None:
        if not self.E_MPa > 0:
            raise FeaError(f"material E_MPa = {self.E_MPa} must be > 0")
        if not -1.0 < self.nu < 0.5:
            raise FeaError(f"material nu = {self.nu} must lie in (-1, 0.5)")
        if not self.yield_MPa > 0:
            raise FeaError(f"material yield_MPa = {self.yield_MPa} must be > 0")

    @property
    def G_MPa(self) -> float:
        """Shear modulus E / (2 (1 + nu)), MPa."""
        return self.E_MPa / (2.0 * (1.0 + self.nu))


# Typical room-temperature values. Printed and sintered polymer parts vary with process, raster and
# humidity by 10-30 %, so treat yield_MPa as an allowable to check against, not a guarantee. Where a
# datasheet gives no Poisson's ratio, the typical value of the polymer family is used and the source
# says so.
MATERIALS: dict[str, Material] = {
    # Paper 003 (Bilancia et al. 2019) quotes these for its printed ABS.
    "ABS": Material(
        "ABS", 1800.0, 0.35, 42.5, 1040.0, "paper 003, Sec. 2.2 (E, nu, flexural yield)"
    ),
    "PLA": Material(
        name="PLA",
        E_MPa=2346.5,
        nu=0.36,
        yield_MPa=49.5,
        density_kg_m3=1240.0,
        source=(
            "Ultimaker PLA technical data sheet (ISO 527 tensile modulus, tensile stress at yield; "
            "density); nu typical for PLA (MatWeb)"
        ),
    ),
    "PETG": Material(
        name="PETG",
        E_MPa=1500.0,
        nu=0.38,
        yield_MPa=50.0,
        density_kg_m3=1270.0,
        source=(
            "Prusament PETG technical data sheet (ISO 527 tensile modulus, yield strength; "
            "density); nu typical for PETG (MatWeb)"
        ),
    ),
    "PA12": Material(
        name="PA12",
        E_MPa=1650.0,
        nu=0.39,
        yield_MPa=48.0,
        density_kg_m3=930.0,
        source=(
            "EOS PA 2200 (SLS PA12) material data sheet (ISO 527 tensile modulus, tensile strength "
            "used as allowable; part density); nu typical for PA12 (MatWeb)"
        ),
    ),
    "65Mn": Material(
        name="65Mn",
        E_MPa=206000.0,
        nu=0.29,
        yield_MPa=785.0,
        density_kg_m3=7820.0,
        source=(
            "GB/T 1222 65Mn spring steel, quenched and tempered (minimum yield strength); E, nu, "
            "density: MatWeb / ASM Handbook Vol. 1, carbon spring steel"
        ),
    ),
    "17-4PH-H900": Material(
        name="17-4PH-H900",
        E_MPa=196500.0,
        nu=0.272,
        yield_MPa=1170.0,
        density_kg_m3=7780.0,
        source=(
            "ASTM A564 condition H900 (minimum 0.2 % yield strength); E, nu, density: AK Steel "
            "17-4 PH product data bulletin / ASM Handbook"
        ),
    ),
    "maraging-300": Material(
        name="maraging-300",
        E_MPa=190000.0,
        nu=0.30,
        yield_MPa=2000.0,
        density_kg_m3=8000.0,
        source=(
            "18Ni(300) maraging steel aged 480 C / 3 h: MatWeb / ASM Handbook Vol. 1 "
            "(0.2 % yield strength, E, nu, density)"
        ),
    ),
    "Ti-6Al-4V": Material(
        name="Ti-6Al-4V",
        E_MPa=113800.0,
        nu=0.342,
        yield_MPa=880.0,
        density_kg_m3=4430.0,
        source=(
            "Ti-6Al-4V (Grade 5) annealed: ASM Aerospace Specification Metals datasheet via MatWeb "
            "(0.2 % yield strength, E, nu, density)"
        ),
    ),
}


def _key(name: str) -> str:
    # "Ti-6Al-4V", "ti6al4v" and "TI_6AL_4V" name the same material.
    return "".join(ch for ch in name.lower() if ch.isalnum())


def get_material(name: str) -> Material:
    """Look a material up by name, ignoring case, spaces, ``-`` and ``_``.

    Raises
    ------
    FeaError
        When no library material has that name; the message lists them.
    """
    for key, mat in MATERIALS.items():
        if _key(key) == _key(name):
            return mat
    raise FeaError(f"unknown material '{name}'; choose one of {', '.join(MATERIALS)}")


def material_yield_MPa(entry: Any) -> float | None:
    """The yield stress, MPa, of a study file's ``material:`` entry as written: a library name,
    or a mapping with a numeric ``yield_MPa``; None for anything else (an unknown name too), so
    that the study's own validation reports it."""
    try:
        if isinstance(entry, str):
            return float(get_material(entry).yield_MPa)
        if isinstance(entry, dict) and isinstance(entry.get("yield_MPa"), int | float):
            return float(entry["yield_MPa"])
    except FeaError:
        return None
    return None


@dataclass(frozen=True)
class FatigueData:
    """Stress-life (S–N) data of one built-in material; :mod:`flexopt.fea.fatigue` builds the curve.

    Two kinds of entry:

    - ``method="shigley"`` (steels, titanium): only the ultimate strength is stored; the curve
      follows Budynas & Nisbett, *Shigley's Mechanical Engineering Design*, ch. 6 (endurance
      limit Se' = 0.5 Sut up to 1400 MPa, else 700 MPa; Marin surface and size factors; the
      fraction f at 10^3 cycles; Basquin S = a N^b between 10^3 and 10^6 cycles; an endurance
      limit below which the life is infinite).
    - ``method="basquin"`` (printed polymers): the fully reversed fatigue strength at 10^6
      cycles and the Basquin exponent; no endurance limit (polymers have none).

    Attributes
    ----------
    ultimate_MPa : float, MPa
        Tensile (ultimate) strength Sut: the Goodman intercept and the Shigley method's input.
    method : str
        ``"shigley"`` or ``"basquin"``.
    surface : str
        Shigley surface finish of the default curve (``"ground"``, ``"machined"``,
        ``"hot-rolled"``, ``"as-forged"``); ``""`` for polymers (the as-printed surface is in the
        specimen data).
    strength_1e6_MPa : float, MPa
        Polymers: fully reversed fatigue strength at 10^6 cycles (NaN for ``"shigley"``).
    basquin_b : float
        Polymers: exponent b of S = a N^b (NaN for ``"shigley"``).
    estimate : bool
        True where the number is a documented rule, not a measured fit for this material.
    source : str
        Where the numbers come from.
    """

    ultimate_MPa: float
    method: str
    surface: str = ""
    strength_1e6_MPa: float = float("nan")
    basquin_b: float = float("nan")
    estimate: bool = True
    source: str = ""


# Polymers without a fit we could check: the straight line in log-log from the static strength at
# one cycle to POLYMER_FATIGUE_RATIO x the static strength at 10^6 cycles (an "estimate" knock-down;
# the one measured printed-polymer value we have, SLS PA12 at ~15 MPa of 48 MPa, is 0.31).
POLYMER_FATIGUE_RATIO = 0.25
_POLY_B = float(math.log10(POLYMER_FATIGUE_RATIO) / 6.0)


def _polymer_estimate(name: str) -> FatigueData:
    static = MATERIALS[name].yield_MPa
    return FatigueData(
        ultimate_MPa=static,
        method="basquin",
        strength_1e6_MPa=POLYMER_FATIGUE_RATIO * static,
        basquin_b=_POLY_B,
        estimate=True,
        source=(
            f"estimate: S(10^6) = {POLYMER_FATIGUE_RATIO} x static strength "
            f"({MATERIALS[name].source}), Basquin line through the static strength at N = 1 "
            f"(b = log10({POLYMER_FATIGUE_RATIO})/6); no fit for printed {name} was checked"
        ),
    )


_SHIGLEY = (
    "Budynas & Nisbett, Shigley's Mechanical Engineering Design, ch. 6 (Se', ka, f, Eqs. 6-14/15)"
)

# One table, one source per entry. Printed polymers' S-N data depend strongly on raster, infill,
# frequency (self-heating) and humidity: treat them as a first screen, not a qualification.
FATIGUE_DATA: dict[str, FatigueData] = {
    "ABS": _polymer_estimate("ABS"),
    "PLA": _polymer_estimate("PLA"),
    "PETG": _polymer_estimate("PETG"),
    "PA12": FatigueData(
        ultimate_MPa=MATERIALS["PA12"].yield_MPa,
        method="basquin",
        strength_1e6_MPa=15.0,
        basquin_b=float(math.log10(15.0 / MATERIALS["PA12"].yield_MPa) / 6.0),
        estimate=True,
        source=(
            "S(10^6) = 15 MPa: Munguia & Dalgarno, 'Fatigue behaviour of laser-sintered PA12 "
            "specimens under four-point rotating bending', Rapid Prototyping Journal (abstract: "
            "~15 MPa limit for all build orientations, lives > 10^6 below 20 MPa); the slope is an "
            "estimate (line through the static strength, 48 MPa, at N = 1)"
        ),
    ),
    "65Mn": FatigueData(
        ultimate_MPa=980.0,
        method="shigley",
        surface="machined",
        estimate=True,
        source=(
            "Sut 980 MPa: GB/T 1222 65Mn quenched and tempered (minimum tensile strength); "
            f"curve: {_SHIGLEY} (textbook estimate, machined surface)"
        ),
    ),
    "17-4PH-H900": FatigueData(
        ultimate_MPa=1310.0,
        method="shigley",
        surface="machined",
        estimate=True,
        source=(
            "Sut 1310 MPa: ASTM A564 condition H900 (minimum tensile strength); "
            f"curve: {_SHIGLEY} (textbook estimate, machined surface)"
        ),
    ),
    "maraging-300": FatigueData(
        ultimate_MPa=2050.0,
        method="shigley",
        surface="machined",
        estimate=True,
        source=(
            "Sut 2050 MPa: 18Ni(300) aged 480 C / 3 h, MatWeb / ASM Handbook Vol. 1 (typical); "
            f"curve: {_SHIGLEY}, Se' capped at 700 MPa (Sut > 1400 MPa); f extrapolated beyond "
            "Fig. 6-18's range (textbook estimate, machined surface)"
        ),
    ),
    "Ti-6Al-4V": FatigueData(
        ultimate_MPa=950.0,
        method="shigley",
        surface="machined",
        estimate=True,
        source=(
            "Sut 950 MPa: Ti-6Al-4V (Grade 5) annealed, ASM Aerospace Specification Metals "
            f"datasheet via MatWeb; curve: the steel rule of {_SHIGLEY} applied to titanium "
            "(estimate: Ti alloys also show a knee; not a measured Ti fit)"
        ),
    ),
}


def get_fatigue_data(name: str) -> FatigueData:
    """Fatigue data of a built-in material, looked up like :func:`get_material`.

    Raises
    ------
    FeaError
        When the material has no fatigue data (a user material): the message says how to give it.
    """
    for key, data in FATIGUE_DATA.items():
        if _key(key) == _key(name):
            return data
    raise FeaError(
        f"no fatigue data for material '{name}'; use one of {', '.join(FATIGUE_DATA)} or build "
        "an SNCurve (flexopt.fea.fatigue) from your own S-N data"
    )


# Creep laws (Findley power law, flexopt.fea.creep.CreepLaw) of the built-in materials: only
# numbers read in a source with its conditions may enter here. None could be verified for the
# printed polymers (see docs/durability.md, "Creep: data"): the FFF PETG creep study (Polymers
# 2025, 17(15), 2075) fits Prony series and a cubic nonlinear theory, not a power law, and its
# coefficients could not be read here; the FFF PLA tensile creep study (Polymers 2020, 12(12),
# 2962) optimises creep responses by response surfaces, with no creep law to transcribe. A
# material without an entry has no creep data: a `hold:` on it is refused with the fix (give
# `creep:` in a materials.yaml, e.g. from a hold test of a printed coupon).
CREEP_DATA: dict[str, Any] = {}


def get_creep_data(name: str) -> Any:
    """The creep law (:class:`flexopt.fea.creep.CreepLaw`) of a built-in material, looked up
    like :func:`get_material`.

    Raises
    ------
    FeaError
        When the material has none: the message says how to give one.
    """
    for key, law in CREEP_DATA.items():
        if _key(key) == _key(name):
            return law
    has = f"; built-in creep laws: {', '.join(CREEP_DATA)}" if CREEP_DATA else ""
    raise FeaError(
        f"no creep data for {name}: give creep: {{tau_h, n, max_stress_ratio, source}} (a "
        "Findley law J = (1 + (t/tau)^n)/E0) for a material in materials.yaml, e.g. from a hold "
        f"test of your coupon{has}"
    )
