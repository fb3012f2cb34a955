"""Study files: read a YAML study once, validate it, and hand back a frozen :class:`Study`.

Every problem with a study file becomes one :class:`~pipeline.errors.StudyError` that names the
YAML key path (``geometry.thickness_mm``), what is wrong and how to fix it. Nothing here writes
files; the run folder is the caller's business.

The model of a whole study depends on its geometry ``kind``; each kind registers a subclass of
:class:`Study` in :mod:`pipeline.studies`. This module holds what every kind shares: the name, the
material and the reading and validation machinery.
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import asdict
from importlib import resources
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from fea.errors import FeaError
from fea.materials import MATERIALS, Material, get_material
from pipeline.errors import StudyError

__all__ = [
    "STUDY_CONFIG",
    "MaterialSpec",
    "OptimiserSpec",
    "ParallelSpec",
    "Study",
    "list_examples",
    "load_study",
    "parse_study_text",
    "resolve_study_path",
    "study_to_yaml",
    "validate_study",
]

#: Shared by every study model: unknown keys are errors, models are immutable, and NaN or inf are
#: refused at the door rather than poisoning a solve.
STUDY_CONFIG = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


#: Plausibility limits of a material (unit slips, not physics): diamond has E = 1.05e6 MPa, the
#: strongest bulk materials (wires, whiskers aside) reach ~1e4 MPa, the lightest printable solid
#: foams ~30 kg/m^3 (1 looks like g/cm^3), osmium is 22590 kg/m^3.
MAX_E_MPA = 2.0e6
MAX_YIELD_MPA = 2.0e4
MIN_DENSITY_KG_M3 = 10.0
MAX_DENSITY_KG_M3 = 25000.0


class MaterialSpec(BaseModel):
    """The ``material:`` block, always resolved to a full record.

    In YAML it is either a library name (``material: PLA``, case-insensitive) or a mapping with
    ``E_MPa``, ``nu``, ``yield_MPa`` and optionally ``density_kg_m3``. A library name is replaced by
    the library record at validation time, so a resolved study carries the numbers it was run with.
    """

    model_config = STUDY_CONFIG

    name: str = Field("custom", description="label of the material")
    E_MPa: float = Field(gt=0, description="Young's modulus, MPa")
    nu: float = Field(gt=-1.0, lt=0.5, description="Poisson's ratio, in (-1, 0.5)")
    yield_MPa: float = Field(gt=0, description="allowable stress (yield or strength), MPa")
    density_kg_m3: float | None = Field(None, gt=0, description="density, kg/m^3")
    source: str = Field("user", description="where the numbers come from")

    @model_validator(mode="after")
    def _plausible(self) -> MaterialSpec:
        # Unit slips are the common material error (Pa for MPa, g/cm^3 for kg/m^3); the numbers
        # then pass every sign check and the solve "works", so catch them here with the fix.
        e, y, rho = self.E_MPa, self.yield_MPa, self.density_kg_m3
        if e > MAX_E_MPA:
            raise ValueError(
                f"E_MPa = {e:g} is stiffer than any solid (diamond: about 1.05e6 MPa); did you "
                f"give Pa? In MPa that is E_MPa: {e / 1e6:g}"
            )
        if y > MAX_YIELD_MPA:
            raise ValueError(
                f"yield_MPa = {y:g} is stronger than any bulk material (about 1e4 MPa); did you "
                f"give Pa? In MPa that is yield_MPa: {y / 1e6:g}"
            )
        if y >= e:
            raise ValueError(
                f"yield_MPa = {y:g} is not below E_MPa = {e:g} (a yield strain of 100 % or more); "
                "check the units (both MPa) or swapped values"
            )
        if rho is not None and rho < MIN_DENSITY_KG_M3:
            raise ValueError(
                f"density_kg_m3 = {rho:g} is lighter than any printable solid; did you give "
                f"g/cm^3? In kg/m^3 that is density_kg_m3: {rho * 1000:g}"
            )
        if rho is not None and rho > MAX_DENSITY_KG_M3:
            raise ValueError(
                f"density_kg_m3 = {rho:g} is denser than any element (osmium: 22590 kg/m^3); "
                "check the units (kg/m^3)"
            )
        return self

    def to_material(self) -> Material:
        """The :class:`fea.materials.Material` this block describes."""
        density = math.nan if self.density_kg_m3 is None else self.density_kg_m3
        return Material(self.name, self.E_MPa, self.nu, self.yield_MPa, density, self.source)


def material_record(material: Material) -> dict[str, Any]:
    """A material as a plain mapping for YAML/JSON (NaN density becomes ``None``)."""
    record = asdict(material)
    if not math.isfinite(record["density_kg_m3"]):
        record["density_kg_m3"] = None
    return record


class OptimiserSpec(BaseModel):
    """The ``optimiser:`` block of a study that ``flexopt run`` optimises.

    ``--quick`` replaces ``pop_size`` and ``n_gen`` by ``quick_pop_size`` and ``quick_n_gen`` (a
    small smoke run for CI and first tries).
    """

    model_config = STUDY_CONFIG

    algorithm: Literal["ga", "nsga2"] = Field("ga", description="ga: one objective; nsga2: several")
    pop_size: int = Field(40, ge=2, le=10000, description="designs per generation")
    n_gen: int = Field(30, ge=1, le=100000, description="generations, the first included")
    seed: int = Field(1, ge=0, description="random seed; the same seed gives the same run")
    quick_pop_size: int = Field(8, ge=2, description="pop_size under --quick")
    quick_n_gen: int = Field(3, ge=1, description="n_gen under --quick")


class ParallelSpec(BaseModel):
    """The optional ``parallel:`` block: where ``flexopt run`` evaluates designs.

    Every kind accepts it (it is part of :class:`Study`). The command line's ``--workers``,
    ``--dask`` and ``--eval-timeout`` override it. It does not change results (the same seed gives
    the same designs on every backend), so it is left out of the study hash that ``--resume``
    compares: a run may be resumed on another machine or cluster.
    """

    model_config = STUDY_CONFIG

    backend: Literal["serial", "processes", "dask"] = Field(
        "processes",
        description="serial (this process), processes (local pool) or dask (a cluster)",
    )
    workers: int | None = Field(
        None, ge=1, le=4096, description="worker processes of the local pool (default: cores)"
    )
    address: str | None = Field(
        None, description="Dask scheduler address, tcp://host:8786 (backend: dask)"
    )
    eval_timeout_s: float | None = Field(
        None, gt=0, description="time limit of one evaluation, s (a design over it fails)"
    )
    chunk_size: int | None = Field(
        None, ge=1, le=100000, description="designs per message/task (default: small chunks)"
    )

    @field_validator("address")
    @classmethod
    def _address_has_a_scheme(cls, value: str | None) -> str | None:
        if value is not None and not re.match(r"^[a-z]+://\S+$", value):
            raise ValueError(
                f"'{value}' is not a scheduler address; give it as tcp://host:8786 (what "
                "`dask scheduler` prints)"
            )
        return value


class Study(BaseModel):
    """What every study shares; each geometry kind adds ``geometry`` and its own blocks.

    Attributes
    ----------
    name : str
        Names the run folder: letters, digits, ``.``, ``_`` and ``-``.
    material : MaterialSpec
    parallel : ParallelSpec or None
        Where ``flexopt run`` evaluates designs (default: a local process pool).
    """

    model_config = STUDY_CONFIG

    name: str = Field(description="study name; names the run folder")
    geometry: BaseModel
    material: MaterialSpec
    parallel: ParallelSpec | None = Field(
        None, description="where flexopt run evaluates designs (processes, dask, time limit)"
    )

    @field_validator("name")
    @classmethod
    def _name_is_a_folder_name(cls, value: str) -> str:
        if not _NAME_RE.match(value) or len(value) > 100:
            suggestion = re.sub(r"[^A-Za-z0-9_.-]+", "_", value).strip("_.-") or "my_study"
            raise ValueError(
                f"'{value}' cannot name a run folder; use letters, digits, '.', '_' and '-' "
                f"(at most 100), e.g. '{suggestion[:100]}'"
            )
        return value

    @field_validator("material", mode="before")
    @classmethod
    def _resolve_library_name(cls, value: Any) -> Any:
        if isinstance(value, str):
            try:
                return material_record(get_material(value))
            except FeaError:
                raise ValueError(
                    f"unknown material '{value}'; use one of {', '.join(MATERIALS)} or give "
                    "{E_MPa, nu, yield_MPa} for your own"
                ) from None
        if not isinstance(value, dict | MaterialSpec):
            raise ValueError(
                f"got {value!r}; give a library name ({', '.join(MATERIALS)}) or a mapping "
                "{E_MPa, nu, yield_MPa, density_kg_m3}"
            )
        return value

    @property
    def kind(self) -> str:
        """The geometry kind, the key of the study registry."""
        return str(self.geometry.kind)  # type: ignore[attr-defined]


# --------------------------------------------------------------------------------------------
# Reading YAML


class _StudyLoader(yaml.SafeLoader):
    """PyYAML's safe loader, plus YAML 1.2 exponent floats and an error on duplicate keys."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen: set[str] = set()
        for key_node, _ in node.value:
            if isinstance(key_node, yaml.ScalarNode) and key_node.value != "<<":
                if key_node.value in seen:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key '{key_node.value}'", key_node.start_mark
                    )
                seen.add(key_node.value)
        return super().construct_mapping(node, deep=deep)


# PyYAML follows YAML 1.1, where `1e9` and `1.8e3` are strings (a float there needs a dot and a
# signed exponent). Users write them as numbers, so read them as YAML 1.2 does.
_StudyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"^(?:[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+|[-+]?\.[0-9_]+[eE][-+]?[0-9]+)$"
    ),
    list("-+0123456789."),
)


def list_examples() -> list[str]:
    """Names of the studies shipped in ``pipeline/examples`` (without ``.yaml``)."""
    folder = resources.files("pipeline") / "examples"
    return sorted(p.name[: -len(".yaml")] for p in folder.iterdir() if p.name.endswith(".yaml"))


def resolve_study_path(study: str | Path) -> Path:
    """Turn the ``STUDY`` argument into a file: an existing path, else a built-in example name.

    Raises
    ------
    StudyError
        When it is neither.
    """
    path = Path(study)
    if path.is_file():
        return path
    name = str(study)
    name = name[: -len(".yaml")] if name.endswith(".yaml") else name
    if name in list_examples():
        return Path(str(resources.files("pipeline") / "examples" / f"{name}.yaml"))
    if path.exists():
        raise StudyError("", f"'{study}' is not a file; give the path of a study YAML file")
    raise StudyError(
        "",
        f"study file '{study}' not found, and there is no built-in example of that name; "
        f"check the path or use one of: {', '.join(list_examples())}",
    )


def parse_study_text(text: str, source: str = "<study>") -> dict[str, Any]:
    """Parse YAML text into the raw mapping of a study.

    Raises
    ------
    StudyError
        For invalid YAML, an empty document or a top level that is not a mapping.
    """
    try:
        data = yaml.load(text, Loader=_StudyLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        fix = (
            "keep only one of them"
            if problem.startswith("duplicate key")
            else "fix the syntax (indent with spaces, 'key: value')"
        )
        raise StudyError("", f"not valid YAML{where}: {problem}; {fix}", source=source) from None
    if data is None:
        raise StudyError(
            "",
            "the file is empty; a study needs name, geometry, material and boundary "
            "(start from `flexopt evaluate cantilever` or docs/usage.md)",
            source=source,
        )
    if not isinstance(data, dict):
        raise StudyError(
            "",
            f"the top level must be a mapping of keys (name, geometry, material, ...), "
            f"not a {type(data).__name__}",
            source=source,
        )
    return data


def validate_study(raw: dict[str, Any], source: str | None = None) -> Study:
    """Validate a raw mapping into the frozen study model of its geometry kind.

    Also builds the geometry and material once, so that everything a constructor refuses is
    reported here, before any run folder exists.

    Raises
    ------
    StudyError
        Naming the first offending key path.
    """
    from pipeline.studies import get_kind  # the registry imports this module

    geometry = raw.get("geometry")
    if not isinstance(geometry, dict):
        problem = (
            "required key is missing; add a geometry block with its kind (see docs/usage.md)"
            if geometry is None
            else f"must be a mapping with a kind, not {type(geometry).__name__}"
        )
        raise StudyError("geometry", problem, source=source)
    try:
        kind = get_kind(geometry.get("kind"))
        study = kind.model.model_validate(raw)
        check_lengths(study.model_dump(mode="json", exclude_none=True))
        kind.check(study)
    except ValidationError as exc:
        raise validation_error_to_study_error(exc, kind.model, source) from None
    except StudyError as exc:
        exc.source = exc.source or source
        raise
    return study


#: Longest plausible length in a study, mm (100 m): past it a number was almost surely given in µm.
MAX_LENGTH_MM = 1.0e5


def _lengths(data: Any, path: tuple[int | str, ...], is_mm: bool) -> Any:
    """(path, value) of every number under a key ending in ``_mm``."""
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _lengths(value, (*path, key), is_mm or str(key).endswith("_mm"))
    elif isinstance(data, list | tuple):
        for i, value in enumerate(data):
            yield from _lengths(value, (*path, i), is_mm)
    elif is_mm and isinstance(data, int | float) and not isinstance(data, bool):
        yield path, float(data)


def check_lengths(data: dict[str, Any]) -> None:
    """Refuse lengths no compliant mechanism has: a unit slip (µm or m given as mm).

    Raises
    ------
    StudyError
        At the first ``*_mm`` value beyond :data:`MAX_LENGTH_MM`, with the value in mm.
    """
    for path, value in _lengths(data, (), False):
        if abs(value) > MAX_LENGTH_MM:
            raise StudyError(
                format_loc(path),
                f"{value:g} mm is longer than {MAX_LENGTH_MM / 1000:g} m; did you give µm? In mm "
                f"that is {value / 1000:g}",
            )


def load_study(study: str | Path) -> Study:
    """Read and validate a study from a path or the name of a built-in example.

    Raises
    ------
    StudyError
        For a missing or unreadable file, invalid YAML, or an invalid study.
    """
    path = resolve_study_path(study)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise StudyError(
            "", "is not UTF-8 text; save the study as a YAML text file", source=str(path)
        ) from None
    except OSError as exc:
        raise StudyError(
            "", f"cannot be read ({exc.strerror}); check the path and permissions", source=str(path)
        ) from None
    return validate_study(parse_study_text(text, str(path)), source=str(path))


class _StudyDumper(yaml.SafeDumper):
    """Block mappings, but ``[x, y]`` lists of numbers on one line, as people write them."""


def _represent_list(dumper: yaml.SafeDumper, data: list) -> yaml.Node:
    flat = all(isinstance(item, int | float | str | bool) for item in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flat)


_StudyDumper.add_representer(list, _represent_list)


def study_to_yaml(study: Study, header: str = "") -> str:
    """The resolved study (defaults filled in, material record expanded) as YAML text.

    Keys left unset (``None``) are omitted, so the text reads back into the same study.
    """
    body = yaml.dump(
        study.model_dump(mode="json", exclude_none=True),
        Dumper=_StudyDumper,
        sort_keys=False,
        default_flow_style=False,
        allow_unicode=True,
        width=100,
    )
    comment = "".join(f"# {line}\n" for line in header.splitlines())
    return comment + body


# --------------------------------------------------------------------------------------------
# From pydantic's errors to one line


def format_loc(loc: tuple[int | str, ...]) -> str:
    """``('geometry', 'thickness_mm', 2)`` → ``geometry.thickness_mm[2]``."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _model_at(model: type[BaseModel], loc: tuple[int | str, ...]) -> type[BaseModel] | None:
    """The nested model class reached by following ``loc`` from ``model`` (or None)."""
    current: Any = model
    for part in loc:
        if not (isinstance(current, type) and issubclass(current, BaseModel)):
            return None
        field = current.model_fields.get(str(part))
        if field is None:
            return None
        current = field.annotation
    return current if isinstance(current, type) and issubclass(current, BaseModel) else None


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def validation_error_to_study_error(
    exc: ValidationError, model: type[BaseModel], source: str | None = None
) -> StudyError:
    """Map the most telling error of a pydantic ``ValidationError`` to one :class:`StudyError`.

    A misspelt key shows up as a missing key plus an unknown key; the unknown key explains both,
    so it is reported first.
    """
    errors = exc.errors(include_url=False)
    errors.sort(key=lambda e: e["type"] != "extra_forbidden")  # stable: otherwise file order
    err = errors[0]
    loc = tuple(err["loc"])
    path = format_loc(loc)
    kind, msg = err["type"], err["msg"]
    parent = _model_at(model, loc[:-1]) if loc else None
    field = parent.model_fields.get(str(loc[-1])) if parent and loc else None

    if kind == "extra_forbidden":
        allowed = list(parent.model_fields) if parent else []
        close = difflib.get_close_matches(str(loc[-1]), allowed, n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        problem = f"unknown key; {hint}remove or rename it (allowed here: {', '.join(allowed)})"
    elif kind == "missing":
        what = f" ({field.description})" if field and field.description else ""
        problem = f"required key is missing; add {loc[-1]}{what}"
    elif kind in ("value_error", "assertion_error"):
        problem = msg.split(", ", 1)[1] if msg.startswith(("Value error, ", "Assertion")) else msg
    else:
        ctx = err.get("ctx", {})
        nested = _model_at(model, loc)
        should = {
            "int_from_float": "it should be a whole number",
            "int_parsing": "it should be a whole number",
            "float_parsing": "it should be a number",
            "too_long": f"it should have at most {ctx.get('max_length')} items",
            "too_short": f"it should have at least {ctx.get('min_length')} items",
            "model_type": "it should be a mapping of keys ("
            + ", ".join(nested.model_fields if nested else [])
            + ")",
        }.get(kind)
        if should is None:
            should = "it" + msg[len("Input") :] if msg.startswith("Input") else msg
        what = f" ({field.description})" if field and field.description else ""
        problem = f"got {_short(err.get('input'))}; {should}{what}"
    return StudyError(path, problem, source=source)
