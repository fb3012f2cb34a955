"""User materials: ``material: my-petg`` from a ``materials.yaml`` file (issue #26).

``flexopt calibrate`` writes a calibrated material into a materials file; a study names it like a
library material. Where flexopt looks, first match wins:

1. ``materials.yaml`` in the folder of the study file;
2. the file named by the environment variable ``FLEXOPT_MATERIALS``, else
   ``~/.config/flexopt/materials.yaml``;
3. the built-in library (:data:`flexopt.fea.materials.MATERIALS`).

A user material may not take a built-in name (it would change what ``material: PLA`` means in
every study of that folder). The file is a mapping of names to records::

    my-petg:
      E_MPa: 1823.7
      nu: 0.38
      yield_MPa: 50.0
      density_kg_m3: 1270.0          # optional
      thickness_offset_mm: -0.057    # optional: printed minus drawn wall thickness (calibration)
      source: calibrated from ...    # optional
      calibration: {...}             # optional: the fit that produced it
      creep: {tau_h: 120, n: 0.25, max_stress_ratio: 0.4, source: hold test ...}  # optional:
                                     # a Findley creep law for hold: (docs/durability.md)

The resolved study carries the numbers (as for a library material), so a run folder does not
depend on the file afterwards. ``thickness_offset_mm`` is recorded in the material's ``source``;
the models solve the drawn thickness (docs/print_to_part.md says how to use the offset).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import yaml
from flexopt.fea.materials import MATERIALS
from flexopt.pipeline.errors import StudyError

__all__ = ["MATERIALS_FILE", "ENV_VAR", "material_files", "read_materials_file", "user_material"]

#: the file name flexopt looks for beside a study
MATERIALS_FILE = "materials.yaml"
#: environment variable naming the user's own materials file
ENV_VAR = "FLEXOPT_MATERIALS"
#: a materials file is a few kB; a larger one is refused before it is parsed
MAX_BYTES = 1 << 20

_KEYS = {
    "E_MPa",
    "nu",
    "yield_MPa",
    "density_kg_m3",
    "thickness_offset_mm",
    "source",
    "calibration",
    "name",
    "creep",
}
_REQUIRED = ("E_MPa", "nu", "yield_MPa")


def _key(name: str) -> str:
    return "".join(ch for ch in str(name).lower() if ch.isalnum())


def material_files(study_source: str | None) -> list[Path]:
    """The materials files that exist, in lookup order (module docstring)."""
    out: list[Path] = []
    if study_source:
        beside = Path(study_source).resolve().parent / MATERIALS_FILE
        out.append(beside)
    env = os.environ.get(ENV_VAR)
    out.append(Path(env) if env else Path.home() / ".config" / "flexopt" / MATERIALS_FILE)
    return [p for p in out if p.is_file()]


def read_materials_file(path: Path) -> dict[str, dict[str, Any]]:
    """The records of one materials file, checked.

    Raises
    ------
    StudyError
        Naming the file and the key path of what is wrong (too large, not YAML, not a mapping, a
        built-in name, a missing or non-numeric value).
    """
    where = str(path)
    try:
        if not path.is_file():
            raise StudyError("", "is not a regular file", source=where)
        with path.open("rb") as handle:
            data = handle.read(MAX_BYTES + 1)
    except OSError as exc:
        raise StudyError("", f"cannot be read ({exc.strerror or exc})", source=where) from None
    if len(data) > MAX_BYTES:
        raise StudyError("", f"is larger than {MAX_BYTES >> 10} KiB; not a materials file", where)
    try:
        loaded = yaml.safe_load(data.decode("utf-8"))
    except (UnicodeDecodeError, yaml.YAMLError) as exc:
        line = getattr(getattr(exc, "problem_mark", None), "line", None)
        at = f" (line {line + 1})" if line is not None else ""
        raise StudyError("", f"is not valid UTF-8 YAML{at}", source=where) from None
    if loaded is None:
        return {}
    if not isinstance(loaded, dict):
        raise StudyError("", "must be a mapping of material names to records", source=where)
    builtin = {_key(n): n for n in MATERIALS}
    out: dict[str, dict[str, Any]] = {}
    for name, record in loaded.items():
        if not isinstance(name, str) or not name.strip():
            raise StudyError(str(name), "a material name must be a non-empty string", where)
        if _key(name) in builtin:
            raise StudyError(
                name,
                f"is the built-in material '{builtin[_key(name)]}'; give your material its own "
                "name (e.g. 'my-" + name.lower() + "')",
                source=where,
            )
        if not isinstance(record, dict):
            raise StudyError(name, "must be a mapping with E_MPa, nu and yield_MPa", where)
        unknown = sorted(set(map(str, record)) - _KEYS)
        if unknown:
            raise StudyError(
                f"{name}.{unknown[0]}",
                f"unknown key; a material has {', '.join(sorted(_KEYS - {'name'}))}",
                source=where,
            )
        for key in _REQUIRED:
            if key not in record:
                raise StudyError(f"{name}.{key}", "required key is missing", source=where)
        for key in ("E_MPa", "nu", "yield_MPa", "density_kg_m3", "thickness_offset_mm"):
            value = record.get(key)
            if value is None and key in ("density_kg_m3", "thickness_offset_mm"):
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise StudyError(f"{name}.{key}", f"must be a number, got {value!r}", where)
            if not math.isfinite(value):
                raise StudyError(f"{name}.{key}", "must be finite", source=where)
        out[name] = dict(record)
    return out


def user_material(name: str, study_source: str | None) -> dict[str, Any] | None:
    """The material record (``name, E_MPa, nu, yield_MPa, density_kg_m3, source``) of a user
    material called ``name`` (case, spaces, ``-`` and ``_`` ignored), or None when no materials
    file has it.

    Raises
    ------
    StudyError
        When a materials file that exists is damaged (:func:`read_materials_file`).
    """
    for path in material_files(study_source):
        for entry, record in read_materials_file(path).items():
            if _key(entry) != _key(name):
                continue
            source = str(record.get("source") or "user materials file")
            offset = record.get("thickness_offset_mm")
            if offset is not None:
                source += (
                    f"; measured thickness offset {offset:+.3f} mm (printed minus drawn) is not "
                    "applied by the model"
                )
            return {
                "name": entry,
                "E_MPa": float(record["E_MPa"]),
                "nu": float(record["nu"]),
                "yield_MPa": float(record["yield_MPa"]),
                "density_kg_m3": record.get("density_kg_m3"),
                "source": f"{path}: {source}",
                **({"creep": record["creep"]} if record.get("creep") is not None else {}),
            }
    return None
