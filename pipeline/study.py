"""Study files: read a YAML study once, validate it, and hand back a frozen :class:`Study`.

Every problem with a study file becomes one :class:`~pipeline.errors.StudyError` that names the
YAML key path (``geometry.thickness_mm``), what is wrong and how to fix it. Nothing here writes
files; the run folder is the caller's business.

The model of a whole study depends on its geometry ``kind``; each kind registers a subclass of
:class:`Study` in :mod:`pipeline.studies`. This module holds what every kind shares: the name, the
material and the reading and validation machinery.
"""

from __future__ import annotations

import collections.abc
import difflib
import math
import os
import re
import reprlib
import types
import typing
from dataclasses import asdict
from importlib import resources
from pathlib import Path
from typing import Any, ClassVar, Literal

import yaml
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import MATERIALS, Material, get_material
from flexopt.optimise import hybrid_defaults
from flexopt.optimise.durability import DutyCycleSpec
from flexopt.optimise.hold import CreepSpec, HoldSpec
from flexopt.optimise.requirements import RequirementSpec
from flexopt.optimise.robustness import RobustnessSpec
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import get_kind
from flexopt.pipeline.study_edit import annotation_at as _annotation_at
from flexopt.pipeline.study_edit import replace_blocks, set_values
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_serializer,
    model_validator,
)

__all__ = [
    "STUDY_CONFIG",
    "MaterialSpec",
    "HybridSpec",
    "OptimiserSpec",
    "ParallelSpec",
    "Study",
    "check_data_limits",
    "check_hold",
    "list_examples",
    "load_study",
    "parse_study_text",
    "read_study_file",
    "short_repr",
    "resolve_study_path",
    "study_to_yaml",
    "validate_study",
]

#: Shared by every study model: unknown keys are errors, models are immutable, and NaN or inf are
#: refused at the door rather than poisoning a solve.
STUDY_CONFIG = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


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
    thickness_offset_mm: float | None = Field(
        None,
        ge=-1.0,
        le=1.0,
        description="printed minus drawn wall thickness, mm, measured by flexopt calibrate: "
        "every printed section is analysed at its drawn thickness plus this offset "
        "(docs/print_to_part.md)",
    )
    creep: CreepSpec | None = Field(
        None,
        description="Findley creep law {tau_h, n, max_stress_ratio, source} for hold: "
        "(docs/durability.md, Creep)",
    )

    @model_serializer(mode="wrap")
    def _without_unset_optional(self, handler: Any) -> Any:
        # a material without a measured offset or a creep law dumps as it did before those
        # keys existed (run folders stay the same)
        data = handler(self)
        if isinstance(data, dict):
            for key in ("thickness_offset_mm", "creep"):
                if key in data and data[key] is None:
                    del data[key]
        return data

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


class HybridSpec(BaseModel):
    """The ``optimiser.hybrid:`` options of ``method: hybrid`` (optimise/hybrid.py): the GA's
    global search for ``ga_n_gen`` generations, then a gradient method from ``starts`` distinct
    good GA designs until the stop rule (docs/usage.md, "The hybrid optimiser")."""

    model_config = STUDY_CONFIG

    ga_n_gen: int | None = Field(
        5,
        ge=1,
        le=100000,
        description="GA generations before the gradient stage (without exact derivatives "
        "more until the GA's best is feasible, n_gen at most; null: n_gen)",
    )
    local: Literal["auto", "gauss_newton", "slsqp"] = Field(
        "auto",
        description="gradient method: auto (Gauss-Newton where the problem gives residuals, "
        "else SLSQP), gauss_newton or slsqp",
    )
    starts: int = Field(2, ge=1, le=100, description="distinct GA designs to start from")
    min_distance: float = Field(
        hybrid_defaults.MIN_DISTANCE,
        ge=0.0,
        le=1.0,
        description="least distance of two starts, in bound-normalised units",
    )
    tolerance: float = Field(
        hybrid_defaults.TOLERANCE,
        ge=0.0,
        lt=1.0,
        description="relative improvement an iteration must beat",
    )
    patience: int = Field(
        hybrid_defaults.PATIENCE,
        ge=1,
        le=1000,
        description="iterations without such an improvement that stop a start",
    )
    max_iter: int = Field(
        hybrid_defaults.MAX_ITER, ge=1, le=10000, description="iterations per start at most"
    )
    fd_step: float = Field(
        hybrid_defaults.FD_STEP,
        gt=0.0,
        lt=0.1,
        description="forward-difference step, in bound-normalised units",
    )
    max_evaluations: int | None = Field(
        None, ge=1, description="designs of the gradient stage at most (none: no limit)"
    )
    retry_inside: bool | None = Field(
        None,
        description="Gauss-Newton: after a trial breaks a constraint row, the retry from the "
        "same design aims inside it by the error seen (none: off)",
    )
    step_solver: Literal["slsqp", "exact"] | None = Field(
        None,
        description="Gauss-Newton: each step's QP by SLSQP, or exactly (least squares with "
        "inequalities; SLSQP where the rows cannot be met) (none: slsqp)",
    )


class OptimiserSpec(BaseModel):
    """The ``optimiser:`` block of a study that ``flexopt run`` optimises.

    ``--quick`` replaces ``pop_size`` and ``n_gen`` by ``quick_pop_size`` and ``quick_n_gen`` (a
    small smoke run for CI and first tries). ``method: hybrid`` follows the GA with a gradient
    stage (``hybrid:`` its options); ``method`` and ``hybrid`` are left out of a dump when
    unset, so a GA study's resolved YAML and hash are what they were before they existed.
    """

    model_config = STUDY_CONFIG

    algorithm: Literal["ga", "nsga2"] = Field("ga", description="ga: one objective; nsga2: several")
    pop_size: int = Field(40, ge=2, le=10000, description="designs per generation")
    n_gen: int = Field(30, ge=1, le=100000, description="generations, the first included")
    seed: int = Field(1, ge=0, description="random seed; the same seed gives the same run")
    quick_pop_size: int = Field(8, ge=2, le=10000, description="pop_size under --quick")
    quick_n_gen: int = Field(3, ge=1, le=100000, description="n_gen under --quick")
    method: Literal["ga", "hybrid"] | None = Field(
        None, description="ga (unset: the GA alone) or hybrid (the GA, then a gradient stage)"
    )
    hybrid: HybridSpec | None = Field(None, description="options of method: hybrid")

    @model_serializer(mode="wrap")
    def _without_unset_method(self, handler: Any) -> Any:
        # added after studies were first written: a GA study dumps (evaluation.json, the run
        # folder's study.yaml, the study hash) as it did before they existed
        data = handler(self)
        if isinstance(data, dict):
            for key in ("method", "hybrid"):
                if key in data and data[key] is None:
                    del data[key]
        return data


#: Local worker processes allowed per core: a pool larger than the cores only adds memory and
#: start-up time (each worker holds the problem and its own BLAS), and thousands of processes
#: can take a machine down; 4 per core leaves room for solves that wait on I/O or a time limit.
MAX_WORKERS_PER_CORE = 4


def max_workers() -> int:
    """Most local worker processes on this machine: :data:`MAX_WORKERS_PER_CORE` per core."""
    return MAX_WORKERS_PER_CORE * (os.cpu_count() or 1)


def workers_problem(n: int) -> str | None:
    """Why ``n`` local workers is refused on this machine (None when it is fine)."""
    limit = max_workers()
    if n > limit:
        return (
            f"{n} worker processes on a {os.cpu_count() or 1}-core machine is too many; give "
            f"at most {limit} ({MAX_WORKERS_PER_CORE} per core; more cores need a Dask cluster)"
        )
    return None


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
        None,
        ge=1,
        description="worker processes of the local pool (default: cores; at most "
        "MAX_WORKERS_PER_CORE per core)",
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

    @field_validator("workers")
    @classmethod
    def _workers_fit_the_machine(cls, value: int | None) -> int | None:
        if value is not None:
            problem = workers_problem(value)
            if problem:
                raise ValueError(problem)
        return value

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
    requirements : tuple of RequirementSpec or None
        What the design must meet beyond the kind's built-in requirements, each judged MET or
        NOT MET in every verdict (``role: constraint`` also constrains the optimisation); see
        :mod:`optimise.requirements` and docs/usage.md, "Requirements and the verdict".
    duty_cycle : DutyCycleSpec or None
        Load levels (or a drive history) the part sees in service: the fatigue life over them
        is reported and ``life_cycles`` / ``life_hours`` may be required (docs/durability.md).
    hold : HoldSpec or None
        The part held for a time at a displacement or a force: the force left (or the crept
        deflection) by the material's creep law is reported and may be required
        (docs/durability.md, Creep).
    """

    model_config = STUDY_CONFIG

    name: str = Field(description="study name; names the run folder")
    geometry: BaseModel
    material: MaterialSpec
    parallel: ParallelSpec | None = Field(
        None, description="where flexopt run evaluates designs (processes, dask, time limit)"
    )
    requirements: tuple[RequirementSpec, ...] | None = Field(
        None,
        max_length=200,
        description="what the design must meet: a list of {quantity, max/min/target/...}",
    )
    robustness: RobustnessSpec | None = Field(
        None,
        description="scatter of E, thickness and width: the share of samples meeting each "
        "requirement and the band of the response (docs/robustness.md)",
    )
    duty_cycle: DutyCycleSpec | None = Field(
        None,
        description="service load levels {drive or fraction, cycles or share_percent} or a "
        "drive history, for the fatigue life (docs/durability.md)",
    )
    hold: HoldSpec | None = Field(
        None,
        description="hold {time_h, temperature_C, at: displacement|force, level or fraction}: "
        "the force after creep and relaxation (docs/durability.md, Creep)",
    )

    #: Blocks added after studies were first written, left out of a dump when unset: a study
    #: without them dumps (evaluation.json, the run folder's study.yaml) as it did before they
    #: existed. A kind adds its own (``polyline_beam``: ``stops``); one serializer serves all.
    OPTIONAL_BLOCKS: ClassVar[tuple[str, ...]] = ("duty_cycle", "hold")

    @model_serializer(mode="wrap")
    def _without_unset_optional_blocks(self, handler: Any) -> Any:
        data = handler(self)
        if isinstance(data, dict):
            for key in type(self).OPTIONAL_BLOCKS:
                if key in data and data[key] is None:
                    del data[key]
        return data

    @field_validator("name")
    @classmethod
    def _name_is_a_folder_name(cls, value: str) -> str:
        if not NAME_RE.fullmatch(value) or len(value) > 100:  # fullmatch: no final newline
            head = value[:200]
            suggestion = re.sub(r"[^A-Za-z0-9_.-]+", "_", head).strip("_.-") or "my_study"
            raise ValueError(
                f"{short_repr(value)} cannot name a run folder; use letters, digits, '.', '_' "
                f"and '-' (at most 100), e.g. '{suggestion[:60]}'"
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
                    f"unknown material '{value}'; use one of {', '.join(MATERIALS)}, a material "
                    "of a materials.yaml beside the study (flexopt calibrate writes one) or give "
                    "{E_MPa, nu, yield_MPa} for your own"
                ) from None
        if not isinstance(value, dict | MaterialSpec):
            raise ValueError(
                f"got {short_repr(value)}; give a library name ({', '.join(MATERIALS)}) or a "
                "mapping {E_MPa, nu, yield_MPa, density_kg_m3}"
            )
        return value

    @property
    def kind(self) -> str:
        """The geometry kind, the key of the study registry."""
        return str(self.geometry.kind)  # type: ignore[attr-defined]

    def replace(self, **changes: Any) -> Study:
        """A NEW validated study with top-level blocks replaced: ``study.replace(name="b",
        material="PLA")``; a block given as None goes back to its default (see
        :func:`pipeline.study_edit.replace_blocks`).

        Raises
        ------
        StudyError
            Naming the key path of an unknown block or of the first value refused.
        """
        check_data_limits(changes)
        return replace_blocks(self, changes, validate_study)

    def with_values(self, values: collections.abc.Mapping[str, Any]) -> Study:
        """A NEW validated study with values set at key paths: ``study.with_values(
        {"geometry.width_mm": 6.0, "geometry.points_mm[1][0]": 30})`` (``[*]``: every item; see
        :func:`pipeline.study_edit.set_values`).

        Raises
        ------
        StudyError
            At a path that does not exist (naming the closest one) or the first value refused.
        """
        check_data_limits(values)  # a value given in Python has a study file's limits
        return set_values(self, values, validate_study)


# --------------------------------------------------------------------------------------------
# Reading YAML


#: libyaml's parser where PyYAML was built with it (the wheels are): the same safe constructor,
#: 20-50x faster at reading, so even a file at the size limit is read in a fraction of a second.
_SafeBase: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _StudyLoader(_SafeBase):  # type: ignore[misc, valid-type]
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
    folder = resources.files("flexopt.pipeline") / "examples"
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
        return Path(str(resources.files("flexopt.pipeline") / "examples" / f"{name}.yaml"))
    if path.exists():
        raise StudyError("", f"'{study}' is not a file; give the path of a study YAML file")
    raise StudyError(
        "",
        f"study file '{study}' not found, and there is no built-in example of that name; "
        f"check the path or use one of: {', '.join(list_examples())}",
    )


#: Limits of a study file, each far beyond any real study and far below what would take a
#: second to read: a study is a few kB (the largest shipped one is under 4 kB).
MAX_STUDY_BYTES = 1024 * 1024
#: Deepest nesting of lists and mappings (a study needs about 6 levels).
MAX_STUDY_DEPTH = 64
#: Most values (nodes), also once every YAML alias is expanded: guards against alias bombs, where
#: a few hundred bytes expand to 10^9 values, and against huge inline tables (a real study has a
#: few hundred values; a long table belongs in a CSV file the study names).
MAX_STUDY_NODES = 20_000


def _check_node_graph(node: yaml.Node, source: str) -> None:
    """Refuse a composed YAML document that nests too deeply or expands too far.

    Walks the node graph once, iteratively (no recursion limit) and memoising shared nodes (an
    alias is the same node object), so the cost is that of the distinct nodes, not of the
    expansion that an alias bomb would produce.

    Raises
    ------
    StudyError
        Naming the limit that was passed.
    """
    size: dict[int, int] = {}  # id(node) -> values under it, aliases expanded
    depth: dict[int, int] = {}  # id(node) -> levels under it
    stack: list[tuple[yaml.Node, int, bool]] = [(node, 0, False)]
    on_path: set[int] = set()
    while stack:
        current, level, done = stack.pop()
        key = id(current)
        if level > MAX_STUDY_DEPTH:
            raise _nesting_error(source)
        if isinstance(current, yaml.ScalarNode):
            size[key], depth[key] = 1, 0
            continue
        if isinstance(current, yaml.MappingNode):
            children = [n for pair in current.value for n in pair]
        else:
            children = list(current.value)
        if done:
            on_path.discard(key)
            size[key] = 1 + sum(size[id(c)] for c in children)
            depth[key] = 1 + max((depth[id(c)] for c in children), default=0)
            if size[key] > MAX_STUDY_NODES:
                raise _too_many_values(source)
            continue
        if key in size:
            continue
        if key in on_path:  # a recursive alias (&a [*a]) would expand forever
            raise StudyError(
                "",
                "holds an alias that refers to itself; remove the recursive alias",
                source=source,
            )
        on_path.add(key)
        stack.append((current, level, True))
        stack.extend((c, level + 1, False) for c in children if id(c) not in size)


def _nesting_error(source: str) -> StudyError:
    return StudyError(
        "",
        f"lists and mappings are nested more than {MAX_STUDY_DEPTH} levels deep; a study "
        "needs a few (see docs/usage.md)",
        source=source,
    )


_OPEN_TOKENS = (
    yaml.FlowSequenceStartToken,
    yaml.FlowMappingStartToken,
    yaml.BlockSequenceStartToken,
    yaml.BlockMappingStartToken,
)
_CLOSE_TOKENS = (yaml.FlowSequenceEndToken, yaml.FlowMappingEndToken, yaml.BlockEndToken)
_VALUE_TOKENS = (yaml.ScalarToken, yaml.AliasToken)


def _too_many_values(source: str) -> StudyError:
    return StudyError(
        "",
        f"expands to more than {MAX_STUDY_NODES} values (YAML aliases '*name' repeating anchors "
        "'&name', or a huge inline table); write the study out without nested aliases and keep "
        "long tables in a CSV file",
        source=source,
    )


def check_data_limits(data: Any, source: str = "") -> None:
    """Apply a study file's limits to a study (or values) given as Python data (docs/usage.md,
    "Limits of a study file"): nesting up to ``MAX_STUDY_DEPTH`` levels, up to
    ``MAX_STUDY_NODES`` values (a numpy array counts its elements), and no container inside
    itself.

    Walked iteratively, and stopped at the first limit passed, so a list nested 100 000 deep, a
    dict that contains itself or a million points is refused in milliseconds (a recursive copy
    of them raised ``RecursionError`` or took minutes).

    Raises
    ------
    StudyError
        Naming the limit, as for a YAML file.
    """
    count = 0
    on_path: set[int] = set()
    stack: list[tuple[Any, int, bool]] = [(data, 0, False)]
    while stack:
        value, level, leaving = stack.pop()
        if leaving:
            on_path.discard(id(value))
            continue
        if level > MAX_STUDY_DEPTH:
            raise _nesting_error(source)  # the YAML file's own words
        if type(value).__name__ == "ndarray":  # numpy, not imported here: its elements count
            count += max(int(getattr(value, "size", 1)), 1)
        else:
            count += 1
        if count > MAX_STUDY_NODES:
            raise _too_many_values(source)
        if isinstance(value, collections.abc.Mapping):
            width = 2 * len(value)
        elif isinstance(value, list | tuple | set | frozenset):
            width = len(value)
        else:
            continue
        if count + width > MAX_STUDY_NODES:  # before a million children are listed
            raise _too_many_values(source)
        children = (
            [*value.keys(), *value.values()]
            if isinstance(value, collections.abc.Mapping)
            else list(value)
        )
        if id(value) in on_path:
            raise StudyError(
                "", "holds a list or mapping that contains itself; give plain data", source=source
            )
        on_path.add(id(value))
        stack.append((value, level, True))
        stack.extend((child, level + 1, False) for child in children)


def _check_nesting(text: str, source: str) -> None:
    """Refuse nesting past :data:`MAX_STUDY_DEPTH` from the token stream, before composing.

    PyYAML's scanner is iterative but its composer recurses once per level, so 5000 nested
    lists would end in a RecursionError after a second of work; the tokens say it at once.
    Syntax errors are left to the parser, which reports them with their line.
    """
    depth = values = 0
    try:
        for token in yaml.scan(text, Loader=_StudyLoader):
            if isinstance(token, _VALUE_TOKENS):
                values += 1
                if values > MAX_STUDY_NODES:  # stop reading: composing would cost far more
                    raise _too_many_values(source)
            elif isinstance(token, _OPEN_TOKENS):
                depth += 1
                if depth > MAX_STUDY_DEPTH + 1:  # +1: the top-level mapping
                    raise _nesting_error(source)
            elif isinstance(token, _CLOSE_TOKENS):
                depth -= 1
    except yaml.YAMLError as exc:
        if "nesting depth" in str(exc):  # libyaml stops at 1000 levels, before we count them
            raise _nesting_error(source) from None
        return


def read_study_file(path: Path) -> str:
    """The text of a study file, refused when it is too large, not text or unreadable.

    Raises
    ------
    StudyError
        Naming the file and the fix.
    """
    try:
        with path.open("rb") as handle:
            data = handle.read(MAX_STUDY_BYTES + 1)
    except OSError as exc:
        raise StudyError(
            "",
            f"cannot be read ({exc.strerror or exc}); check the path and permissions",
            source=str(path),
        ) from None
    if len(data) > MAX_STUDY_BYTES:
        raise StudyError(
            "",
            f"is larger than {MAX_STUDY_BYTES // 1024} KiB; a study is a few kB of YAML (keep "
            "long tables in a CSV file the study names)",
            source=str(path),
        )
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise StudyError(
            "", "is not UTF-8 text; save the study as a YAML text file", source=str(path)
        ) from None


def parse_study_text(text: str, source: str = "<study>") -> dict[str, Any]:
    """Parse YAML text into the raw mapping of a study.

    The text is composed into YAML nodes first and checked against :data:`MAX_STUDY_BYTES`,
    :data:`MAX_STUDY_DEPTH` and :data:`MAX_STUDY_NODES` before any Python object is built, so a
    hostile file (an alias bomb, 5000 nested lists) is refused in milliseconds.

    Raises
    ------
    StudyError
        For invalid YAML, an empty document, a top level that is not a mapping, or a file past
        one of the limits.
    """
    if len(text) > MAX_STUDY_BYTES:
        raise StudyError(
            "",
            f"is larger than {MAX_STUDY_BYTES // 1024} KiB; a study is a few kB of YAML",
            source=source,
        )
    _check_nesting(text, source)
    loader = _StudyLoader(text)
    try:
        node = loader.get_single_node()
        if node is not None:
            _check_node_graph(node, source)
        data = None if node is None else loader.construct_document(node)
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
    except RecursionError:  # PyYAML's composer recurses once per level (_check_nesting's net)
        raise _nesting_error(source) from None
    finally:
        loader.dispose()
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


def check_robustness(study: Study) -> None:
    """Refuse a ``robustness:`` block the study's kind cannot use.

    Raises
    ------
    StudyError
        At ``robustness.objective`` for ``worst`` on a kind that ``flexopt run`` does not
        optimise (there is no optimiser to score designs by their worst sample).
    """
    spec: RobustnessSpec | None = getattr(study, "robustness", None)
    if spec is None or spec.objective != "worst":
        return
    from flexopt.pipeline.studies import get_kind  # the registry imports this module lazily

    if get_kind(study.kind).problem is None:
        raise StudyError(
            "robustness.objective",
            f"worst scores the designs of an optimisation, but kind {study.kind} is only "
            "evaluated; use objective: nominal (the samples are reported all the same)",
        )


def check_duty_cycle(study: Study) -> None:
    """Refuse a ``duty_cycle:`` block the study cannot use (its material has no fatigue data,
    its steel finish is unknown).

    Raises
    ------
    StudyError
        At ``duty_cycle`` (or ``duty_cycle.surface``) with the fix.
    """
    spec: DutyCycleSpec | None = getattr(study, "duty_cycle", None)
    if spec is None:
        return
    from flexopt.fea.fatigue import material_sn_curve

    try:
        material_sn_curve(study.material.name, surface=spec.surface)
    except FeaError as exc:
        key = "duty_cycle.surface" if spec.surface is not None else "duty_cycle"
        raise StudyError(key, str(exc).removeprefix("fatigue: ")) from None


def check_hold(study: Study) -> None:
    """Refuse a ``hold:`` block the study cannot use: its material has no creep law (neither
    built in nor a ``creep:`` entry), or the hold's temperature is not the law's and the law
    has no time-temperature shift.

    Raises
    ------
    StudyError
        At ``hold`` (or ``hold.temperature_C``) with the fix.
    """
    spec: HoldSpec | None = getattr(study, "hold", None)
    if spec is None:
        return
    from flexopt.optimise.errors import OptimiseError
    from flexopt.optimise.hold import creep_law_of

    try:
        law = creep_law_of(study.material)
        law.reduced_time(spec.time_h, spec.temperature_C)
    except OptimiseError as exc:
        raise StudyError("hold", str(exc)) from None
    except FeaError as exc:
        raise StudyError("hold.temperature_C", str(exc).removeprefix("creep: ")) from None


def validate_study(raw: dict[str, Any], source: str | None = None) -> Study:
    """Validate a raw mapping into the frozen study model of its geometry kind.

    Also builds the geometry and material once, so that everything a constructor refuses is
    reported here, before any run folder exists.

    Raises
    ------
    StudyError
        Naming the first offending key path.
    """
    geometry = raw.get("geometry")
    if not isinstance(geometry, dict):
        problem = (
            "required key is missing; add a geometry block with its kind (see docs/usage.md)"
            if geometry is None
            else f"must be a mapping with a kind, not {type(geometry).__name__}"
        )
        raise StudyError("geometry", problem, source=source)
    raw = _with_user_material(raw, source)
    try:
        kind = get_kind(geometry.get("kind"))
        check_no_bool_numbers(raw, kind.model)  # before pydantic reads `true` as 1
        study = kind.model.model_validate(raw)
        check_no_bool_numbers(raw, study)
        check_lengths(study.model_dump(mode="json", exclude_none=True))
        kind.check(study)
        from flexopt.pipeline.verdict import check_requirement_names

        check_requirement_names(study)
        check_robustness(study)
        check_duty_cycle(study)
        check_hold(study)
    except ValidationError as exc:
        raise validation_error_to_study_error(exc, kind.model, source) from None
    except StudyError as exc:
        exc.source = exc.source or source
        raise
    return study


def resolve_material(name: str, source: str | None = None) -> dict[str, Any]:
    """The record of material ``name``: a library material, else one of a materials file
    (:mod:`pipeline.materials_file`; ``source`` is the study file whose folder is searched).

    Raises
    ------
    StudyError
        At ``material`` when no library or materials file has it, or a materials file is damaged.
    """
    try:
        return material_record(get_material(name))
    except FeaError:
        pass
    from flexopt.pipeline.materials_file import user_material

    record = user_material(name, source)
    if record is None:
        raise StudyError(
            "material",
            f"unknown material '{name}'; use one of {', '.join(MATERIALS)} or a material of a "
            "materials.yaml (flexopt calibrate writes one)",
        )
    return record


def _with_user_material(raw: dict[str, Any], source: str | None) -> dict[str, Any]:
    """``raw`` with ``material: <name>`` replaced by the record of a user material of that name
    (a ``materials.yaml`` beside the study or the user's own file, :mod:`pipeline.materials_file`)
    when the library has no such material; ``raw`` itself otherwise."""
    name = raw.get("material")
    if not isinstance(name, str):
        return raw
    try:
        get_material(name)
        return raw  # a library name: resolved by MaterialSpec as before
    except FeaError:
        pass
    from flexopt.pipeline.materials_file import user_material

    record = user_material(name, source)
    return raw if record is None else {**raw, "material": record}


def _bools(data: Any, path: tuple[int | str, ...]) -> Any:
    """(path, value) of every boolean in a raw study mapping (iteratively: no recursion limit)."""
    stack: list[tuple[Any, tuple[int | str, ...]]] = [(data, path)]
    while stack:
        item, where = stack.pop()
        if isinstance(item, bool):
            yield where, item
        elif isinstance(item, dict):
            stack.extend((v, (*where, k)) for k, v in item.items())
        elif isinstance(item, list | tuple):
            stack.extend((v, (*where, i)) for i, v in enumerate(item))


_MISSING = object()


def _value_at(model: Any, path: tuple[int | str, ...]) -> Any:
    """The validated value at a raw key path (``_MISSING`` where the model reshaped it)."""
    current = model
    for part in path:
        if isinstance(current, BaseModel):
            current = getattr(current, str(part), _MISSING)
        elif isinstance(current, dict):
            current = current.get(part, _MISSING)
        elif isinstance(current, list | tuple) and isinstance(part, int):
            current = current[part] if 0 <= part < len(current) else _MISSING
        else:
            return _MISSING
        if current is _MISSING:
            return _MISSING
    return current


def _number_types(annotation: Any) -> tuple[set[type], bool]:
    """(leaf types a value of ``annotation`` may have, whether anything goes there)."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _number_types(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        found: set[type] = set()
        for arm in typing.get_args(annotation):
            arm_types, anything = _number_types(arm)
            if anything:
                return set(), True
            found |= arm_types
        return found, False
    if annotation is Any or not isinstance(annotation, type):
        return set(), origin is None  # a Literal, a container: not a number leaf
    return {annotation}, False


def check_no_bool_numbers(raw: dict[str, Any], study: BaseModel | type[BaseModel]) -> None:
    """Refuse ``true``/``false`` where the study wants a number.

    pydantic's lax mode reads ``width_mm: true`` as 1.0 mm; YAML users who type ``yes`` or
    ``true`` there meant something else (or slipped), so a boolean is never a number.

    Raises
    ------
    StudyError
        At the key path of the first boolean that became a number.
    """
    model = study if isinstance(study, type) else type(study)
    for path, value in _bools(raw, ()):
        leaf_types, anything = _number_types(_annotation_at(model, path))
        numbers_only = (
            bool(leaf_types)
            and not anything
            and all(issubclass(t, int | float) and t is not bool for t in leaf_types)
        )
        validated = _MISSING if isinstance(study, type) else _value_at(study, path)
        became_number = isinstance(validated, int | float) and not isinstance(validated, bool)
        if numbers_only or became_number:
            raise StudyError(
                format_loc(path),
                f"got {str(value).lower()}; a boolean is not a number here; give the number "
                "in the key's unit (e.g. 5.0)",
            )


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
    return validate_study(parse_study_text(read_study_file(path), str(path)), source=str(path))


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
        arms = [a for a in typing.get_args(current) if a is not type(None)]
        if typing.get_origin(current) in (typing.Union, types.UnionType) and len(arms) == 1:
            current = arms[0]  # an optional block (`parallel:`, `robustness:`): its model
    return current if isinstance(current, type) and issubclass(current, BaseModel) else None


_REPR = reprlib.Repr()  # keyword arguments need Python 3.12
_REPR.maxlevel, _REPR.maxdict, _REPR.maxlist, _REPR.maxtuple, _REPR.maxset = 2, 4, 4, 4, 4
_REPR.maxstring = _REPR.maxother = 40


def short_repr(value: Any, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters, without building the whole repr first.

    A value echoed in an error message can be anything a study file holds, including a shared
    structure that would repr to gigabytes; :mod:`reprlib` stops after a few items and levels.
    """
    if isinstance(value, str) and len(value) > limit:
        value = value[:limit]  # reprlib would copy the whole string first
    text = _REPR.repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


_short = short_repr


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
