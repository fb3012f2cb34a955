"""Linear-elastic isotropic materials (units: MPa, kg/m^3)."""

from __future__ import annotations

from dataclasses import dataclass

from flexopt.fea.errors import FeaError

__all__ = ["Material", "MATERIALS", "get_material"]


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
