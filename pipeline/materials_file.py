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
depend on the file afterwards. ``thickness_offset_mm`` goes into the study's material: every
printed section is then analysed at its drawn thickness plus the offset, the part as made
(:mod:`pipeline.as_printed`); the exported geometry stays as drawn.

In-plane anisotropy: a material calibrated from coupons printed in two orientations
(``flexopt calibrate A.csv B.csv``) has ``E_x_MPa`` and ``E_y_MPa`` (the modulus along the
printer's x and y axes) instead of ``E_MPa``. A study names the direction its beams are printed
along: ``material: my-petg@x`` uses ``E_x_MPa``, ``my-petg@y`` ``E_y_MPa``; ``material: my-petg``
alone is refused, as flexopt does not know how the part lies on the bed::

    my-petg:
      E_x_MPa: 1850.2
      E_y_MPa: 1702.9
      nu: 0.38
      yield_MPa: 50.0
      thickness_offset_mm: -0.058
"""

from __future__ import annotations

import math
import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import yaml
from flexopt.fea.materials import MATERIALS
from flexopt.optimise.requirements import Verdict
from flexopt.pipeline.errors import StudyError

__all__ = [
    "DIRECTIONS",
    "ENV_VAR",
    "MATERIALS_FILE",
    "as_printed_note",
    "material_files",
    "read_materials_file",
    "thickness_offset_mm",
    "user_material",
    "with_as_printed_verdicts",
]

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
    "E_x_MPa",
    "E_y_MPa",
    "source",
    "calibration",
    "name",
    "creep",
}
_REQUIRED = ("nu", "yield_MPa")
#: the largest thickness offset a materials file may give, mm (the study's bound too)
MAX_OFFSET_MM = 1.0
#: the print directions of an anisotropic material (``name@x``): the key of each one's modulus
DIRECTIONS = {"x": "E_x_MPa", "y": "E_y_MPa"}


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
        directional = [k for k in DIRECTIONS.values() if k in record]
        if directional and len(directional) < len(DIRECTIONS):
            raise StudyError(
                f"{name}.{directional[0]}", "give both E_x_MPa and E_y_MPa, or neither", where
            )
        if "E_MPa" not in record and not directional:
            raise StudyError(
                f"{name}.E_MPa",
                "required key is missing (or E_x_MPa and E_y_MPa, for a material calibrated in "
                "two print orientations)",
                source=where,
            )
        optional = ("density_kg_m3", "thickness_offset_mm", "E_MPa", *DIRECTIONS.values())
        for key in ("E_MPa", "nu", "yield_MPa", *optional):
            value = record.get(key)
            if value is None and key in optional:
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise StudyError(f"{name}.{key}", f"must be a number, got {value!r}", where)
            if not math.isfinite(value):
                raise StudyError(f"{name}.{key}", "must be finite", source=where)
            if key == "thickness_offset_mm" and not abs(value) <= MAX_OFFSET_MM:
                raise StudyError(
                    f"{name}.{key}",
                    f"{value:g} mm is not a printer's wall error (at most ±{MAX_OFFSET_MM:g} mm); "
                    "check the units (mm)",
                    source=where,
                )
        out[name] = dict(record)
    return out


def user_material(name: str, study_source: str | None) -> dict[str, Any] | None:
    """The material record (``name, E_MPa, nu, yield_MPa, density_kg_m3, source`` and, when
    measured, ``thickness_offset_mm``) of a user material called ``name`` (case, spaces, ``-``
    and ``_`` ignored), or None when no materials file has it. ``name@x`` / ``name@y`` picks the
    modulus along the printer's x / y axis of a material calibrated in two orientations.

    Raises
    ------
    StudyError
        When a materials file that exists is damaged (:func:`read_materials_file`), or at
        ``material`` when an anisotropic material is named without its print direction (or a
        direction is given for an isotropic one).
    """
    base, at, direction = str(name).partition("@")
    direction = direction.strip().lower()
    for path in material_files(study_source):
        for entry, record in read_materials_file(path).items():
            if _key(entry) != _key(base):
                continue
            source = str(record.get("source") or "user materials file")
            offset = record.get("thickness_offset_mm")
            E = _modulus(entry, record, at, direction, path)
            if at:
                source += f"; E along the printer's {direction} axis ({DIRECTIONS[direction]})"
            if offset is not None:
                source += (
                    f"; measured thickness offset {offset:+.4f} mm (printed minus drawn), applied "
                    "to every printed section"
                )
            out = {
                "name": f"{entry}@{direction}" if at else entry,
                "E_MPa": E,
                "nu": float(record["nu"]),
                "yield_MPa": float(record["yield_MPa"]),
                "density_kg_m3": record.get("density_kg_m3"),
                "source": f"{path}: {source}",
                **({"creep": record["creep"]} if record.get("creep") is not None else {}),
            }
            if offset is not None and float(offset) != 0.0:
                out["thickness_offset_mm"] = float(offset)
            return out
    return None


def _modulus(entry: str, record: dict[str, Any], at: str, direction: str, path: Path) -> float:
    """E (MPa) of a materials-file record, for the print direction ``direction`` when ``at``."""
    anisotropic = all(k in record and record[k] is not None for k in DIRECTIONS.values())
    if not at:
        if anisotropic:
            values = ", ".join(f"{record[k]:.6g} MPa along {d}" for d, k in DIRECTIONS.items())
            raise StudyError(
                "material",
                f"'{entry}' ({path}) was calibrated in two print orientations ({values}); say "
                f"which the part's beams are printed along: material: {entry}@x or {entry}@y "
                "(docs/print_to_part.md)",
            )
        return float(record["E_MPa"])
    if direction not in DIRECTIONS:
        raise StudyError(
            "material",
            f"'{entry}@{direction}': the print direction is x or y ({entry}@x, {entry}@y)",
        )
    if not anisotropic:
        raise StudyError(
            "material",
            f"'{entry}' ({path}) has one E for every direction (no E_x_MPa, E_y_MPa); name it "
            f"without @{direction}",
        )
    return float(record[DIRECTIONS[direction]])


# -- the part as made (pipeline.as_printed applies the offset; these say so) ----------------


def thickness_offset_mm(study: Any) -> float:
    """The printer's measured thickness offset of the study's material, mm (0 when none)."""
    value = getattr(getattr(study, "material", None), "thickness_offset_mm", None)
    return float(value) if value else 0.0


def as_printed_note(study: Any, applied: bool = True) -> str:
    """One line: the offset the analysis applied (or that it could apply it to nothing), and
    that the drawing is unchanged."""
    dt = thickness_offset_mm(study)
    name = study.material.name
    if not applied:
        return (
            f"the measured thickness offset {dt:+.4g} mm of material {name} is not applied: no "
            "section of this study moves with it (docs/print_to_part.md)"
        )
    return (
        f"judged as printed: every printed section at its drawn thickness {dt:+.4g} mm (the "
        f"measured offset of material {name}); exported geometry as drawn"
    )


def with_as_printed_verdicts(
    study: Any, verdicts: tuple[Verdict, ...], record: Any = None
) -> tuple[Verdict, ...]:
    """``verdicts`` with :func:`as_printed_note` in each one's ``detail``; ``record`` is the
    result's ``info["as printed"]`` (:mod:`pipeline.as_printed`), which says whether anything
    moved. Unchanged when the study's material has no offset, when there is no record (a result
    that was not analysed as printed claims nothing), or when the note is there already."""
    if not thickness_offset_mm(study) or not isinstance(record, dict):
        return tuple(verdicts)
    note = as_printed_note(study, bool(record.get("applied", True)))
    return tuple(
        v if note in v.detail else replace(v, detail=f"{v.detail}; {note}" if v.detail else note)
        for v in verdicts
    )
