"""Linear-elastic isotropic materials (units: MPa, kg/m^3)."""

from __future__ import annotations

from dataclasses import dataclass

from fea.errors import FeaError

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


MATERIALS: dict[str, Material] = {
    # Paper 003 (Bilancia et al. 2019) quotes these for its printed ABS.
    "ABS": Material("ABS", 1800.0, 0.35, 42.5, 1040.0, "paper 003, Sec. 2.2 (E, nu, flexural yield)"),
}


def get_material(name: str) -> Material:
    """Look a material up by name (case-insensitive)."""
    for key, mat in MATERIALS.items():
        if key.lower() == name.lower():
            return mat
    raise FeaError(f"unknown material '{name}'; choose one of {', '.join(MATERIALS)}")
