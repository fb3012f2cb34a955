"""Parametric generators: beam profiles, outlines and solids (mm).

Public names are re-exported lazily (PEP 562): ``from geometry import BeamProfile`` works, and
importing the package does not import the heavy libraries behind modules you do not use.
"""

from importlib import import_module
from typing import Any

_EXPORTS = {
    "GeometryError": "errors",
    "BeamProfile": "profile",
    "check_printable": "solid",
    "extrude": "solid",
    "stl_bytes": "solid",
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
