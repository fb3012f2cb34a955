"""Analyses: the nonlinear planar beam, plane stress, meshing, materials and closed forms.

Public names are re-exported lazily (PEP 562): ``from fea import BeamModel`` works, and
importing the package does not import the heavy libraries behind modules you do not use.
"""

from importlib import import_module
from typing import Any

_EXPORTS = {
    "BeamModel": "beam",
    "BeamResponse": "beam",
    "BeamSettings": "beam",
    "EndDrive": "beam",
    "solve_beam": "beam",
    "cantilever_tip_load": "elastica",
    "cantilever_load_for_deflection": "elastica",
    "fixed_guided": "elastica",
    "FeaError": "errors",
    "MATERIALS": "materials",
    "Material": "materials",
    "get_material": "materials",
    "TriMesh": "mesh",
    "mesh_polygon": "mesh",
    "to_skfem": "mesh",
    "Clamp": "plane_stress",
    "PlaneStressModel": "plane_stress",
    "PlaneStressResponse": "plane_stress",
    "PlaneStressSettings": "plane_stress",
    "Rotate": "plane_stress",
    "Translate": "plane_stress",
    "solve_plane_stress": "plane_stress",
    "RigidStop": "stops",
    "ContactSettings": "stops",
    "ContactResponse": "stops",
    "solve_with_stops": "stops",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
