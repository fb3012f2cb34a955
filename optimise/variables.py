"""Design variables on any numeric key of a nested geometry mapping, addressed by path.

A study names what the optimiser may change as key paths into its own (validated, then dumped to
plain data) mapping, with bounds, instead of a fixed list of parameters::

    variables:
      - path: geometry.beams.leaf1.points_mm[1][1]          # one coordinate, mm
        bounds: [2.0, 8.0]
        tie: [{path: geometry.beams.leaf2.points_mm[1][1], factor: -1.0}]   # mirrored y
      - path: geometry.beams.leaf1.thickness_mm[*]           # every thickness of the beam
        bounds: [0.8, 2.0]
        initial: 1.2                                          # the initial design (optional)
      - {path: geometry.width_mm, bounds: [4, 12], name: width_mm}

Path grammar: keys separated by ``.``, list items as ``[i]`` (0-based) and ``[*]`` for every item
of a list, or after a dot (``points_mm.1.1``, ``thickness_mm.*``: no quotes needed in YAML flow
mappings, where brackets must be quoted); the first key is the root (``geometry``). A path
ending in ``[*]`` (or passing through one) stands for every numeric leaf it reaches, all set to
the same value.

Each variable sets its own path(s) to ``factor * x + offset`` (default: ``x``) and each tie path
to its own ``factor * x + offset``, so two keys share one variable (symmetry), a mirrored
coordinate is ``factor: -1``, and a point that slides along a line is a variable ``a`` with the
line's direction as factors and its start as offsets. The initial design is each variable's
``initial`` or, without it, the value the mapping holds at its first path, ``(value - offset) /
factor``.

This module knows nothing of mechanisms; a study kind calls :func:`resolve_variables` once with
its raw mapping (errors are :class:`VariableError` with the key path of the variables block and
a fix, which the pipeline turns into a StudyError), then :meth:`DesignVariables.apply` per design.
"""

from __future__ import annotations

import copy
import difflib
import math
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from flexopt.geometry.errors import FlexoptError
from flexopt.optimise.names import NAME_MAX_CHARS, check_name
from flexopt.optimise.space import DesignSpace
from pydantic import BaseModel, ConfigDict, Field, field_validator

__all__ = [
    "PathPart",
    "TieSpec",
    "VariableError",
    "VariableSpec",
    "DesignVariables",
    "format_path",
    "numeric_leaves",
    "parse_path",
    "positive_key",
    "resolve_variables",
]

#: One step of a path: a mapping key (str), a list index (int) or every item (``"*"`` wrapped in
#: a one-item tuple so that it cannot be confused with a key named ``*``).
PathPart = str | int | tuple[str]
_STAR: tuple[str] = ("*",)

_CONFIG = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

#: Keys whose values are sizes of material, > 0 by nature (a thickness, a width, a radius):
#: a variable that may make one zero or negative is refused when the study is read, not left
#: for the solver to trip over.
POSITIVE_KEY_WORDS = ("thickness", "width", "radius", "diameter", "length")


class VariableError(FlexoptError, ValueError):
    """A variables block that cannot be used: ``path`` is where in the study, ``problem`` what
    is wrong and how to fix it (one line)."""

    def __init__(self, path: str, problem: str) -> None:
        self.path = path
        self.problem = " ".join(problem.split())
        super().__init__(f"{path}: {self.problem}")


class TieSpec(BaseModel):
    """One tied key: set to ``factor * x + offset`` of the variable it belongs to."""

    model_config = _CONFIG

    path: str = Field(
        description="key path of the tied value, e.g. geometry.beams.b.points_mm[1][1]"
    )
    factor: float = Field(1.0, description="multiplies the variable (-1 mirrors a coordinate)")
    offset: float = Field(0.0, description="added after the factor, in the key's unit")

    @field_validator("factor")
    @classmethod
    def _nonzero(cls, value: float) -> float:
        if value == 0:
            raise ValueError("factor 0 ties nothing (the key would be fixed at offset); remove it")
        return value


class VariableSpec(BaseModel):
    """One item of a study's ``variables:`` list."""

    model_config = _CONFIG

    path: str = Field(description="key path, e.g. geometry.beams.leaf1.thickness_mm[*]")
    bounds: tuple[float, float] = Field(description="[lower, upper] in the key's unit")
    tie: tuple[TieSpec | str, ...] = Field(
        (), description="more keys set from this variable: paths or {path, factor, offset}"
    )
    factor: float = Field(
        1.0, description="the key at path is set to factor * x + offset (default: x itself)"
    )
    offset: float = Field(0.0, description="added after the factor, in the key's unit")
    initial: float | None = Field(
        None,
        description="the initial design's value (default: from the value at path, "
        "(value - offset) / factor)",
    )
    name: str | None = Field(
        None, max_length=NAME_MAX_CHARS, description="name in reports (default: the path)"
    )

    @field_validator("name")
    @classmethod
    def _name_rule(cls, value: str | None) -> str | None:  # the one rule of names (docs/usage.md)
        return value if value is None else check_name(value, "variable name")

    @field_validator("factor")
    @classmethod
    def _factor_nonzero(cls, value: float) -> float:
        if value == 0:
            raise ValueError("factor 0 would fix the key at offset; remove the variable")
        return value

    @field_validator("path")
    @classmethod
    def _path_parses(cls, value: str) -> str:
        parse_path(value)
        return value

    @field_validator("bounds")
    @classmethod
    def _ordered(cls, value: tuple[float, float]) -> tuple[float, float]:
        lo, hi = value
        if lo > hi:
            raise ValueError(
                f"lower bound {lo:g} > upper bound {hi:g}; did you swap them? [{hi:g}, {lo:g}]"
            )
        if lo == hi:
            raise ValueError(
                f"equal bounds [{lo:g}, {hi:g}]; give a range, or set the value in the geometry "
                "and drop the variable"
            )
        return value

    @property
    def ties(self) -> tuple[TieSpec, ...]:
        return tuple(TieSpec(path=t) if isinstance(t, str) else t for t in self.tie)


# --------------------------------------------------------------------------------------------
# Paths

_TOKEN = re.compile(r"\.?([A-Za-z_][A-Za-z0-9_\-]*)|\[(\d+|\*)\]|\.(\d+|\*)(?![A-Za-z_])")


def parse_path(text: str) -> tuple[PathPart, ...]:
    """``'geometry.beams.b1.points_mm[1][0]'`` → ``('geometry', 'beams', 'b1', 'points_mm', 1,
    0)``; ``[*]`` becomes ``('*',)``. List items may also be written after a dot
    (``points_mm.1.0``, ``thickness_mm.*``): brackets are flow indicators in YAML, so a path
    with them must be quoted inside ``{...}``, while the dotted form never needs quotes.

    Raises
    ------
    ValueError
        For an empty path or characters the grammar does not have (one line, with an example).
    """
    if not isinstance(text, str) or not text.strip():
        raise ValueError("the path is empty; give e.g. geometry.beams.leaf1.thickness_mm[0]")
    parts: list[PathPart] = []
    pos = 0
    text = text.strip()
    while pos < len(text):
        match = _TOKEN.match(text, pos)
        if match is None or (pos == 0 and text[0] == ".") or (pos > 0 and text[pos] not in ".["):
            raise ValueError(
                f"cannot read the path '{text}' at character {pos + 1}; write keys with '.', "
                "list items as [i] or [*], e.g. geometry.beams.leaf1.points_mm[1][0]"
            )
        key, index, dotted = match.groups()
        index = index if index is not None else dotted
        if key is not None:
            parts.append(key)
        elif index == "*":
            parts.append(_STAR)
        else:
            parts.append(int(index))
        pos = match.end()
    if not isinstance(parts[0], str):
        raise ValueError(f"the path '{text}' must start with a key such as geometry")
    return tuple(parts)


def format_path(parts: Sequence[PathPart]) -> str:
    """Inverse of :func:`parse_path`."""
    out = ""
    for part in parts:
        if isinstance(part, tuple):
            out += "[*]"
        elif isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else part
    return out


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def numeric_leaves(data: Any, prefix: tuple[PathPart, ...] = ()) -> Iterator[tuple[PathPart, ...]]:
    """Every path to a number under ``data`` (mappings and lists walked), in document order."""
    stack: list[tuple[Any, tuple[PathPart, ...]]] = [(data, prefix)]
    while stack:
        item, where = stack.pop()
        if _is_number(item):
            yield where
        elif isinstance(item, Mapping):
            stack.extend((v, (*where, str(k))) for k, v in reversed(list(item.items())))
        elif isinstance(item, list | tuple):
            stack.extend((v, (*where, i)) for i, v in reversed(list(enumerate(item))))


def _nearest(text: str, root: Mapping[str, Any], prefix: tuple[PathPart, ...]) -> str:
    """The valid numeric path nearest to ``text`` (by spelling), for the error's fix."""
    candidates = [format_path(p) for p in numeric_leaves(root)]
    lists = set()
    for p in numeric_leaves(root):  # a whole list of numbers is addressable as [*]
        if p and isinstance(p[-1], int):
            lists.add(format_path((*p[:-1], _STAR)))
    candidates += sorted(lists)
    close = difflib.get_close_matches(text, candidates, n=1, cutoff=0.0)
    if close:
        return close[0]
    return format_path(prefix) if prefix else "geometry"


def _expand(
    root: Mapping[str, Any], parts: tuple[PathPart, ...], text: str, where: str
) -> list[tuple[PathPart, ...]]:
    """Concrete paths (no ``[*]``) to the numbers ``parts`` addresses in ``root``.

    Raises
    ------
    VariableError
        At ``where`` when a key or index does not exist or the path ends on something that is
        not a number, naming the nearest valid path.
    """
    found: list[tuple[PathPart, ...]] = []
    stack: list[tuple[Any, int, tuple[PathPart, ...]]] = [(root, 0, ())]
    while stack:
        item, k, done = stack.pop()
        if k == len(parts):
            if _is_number(item):
                found.append(done)
                continue
            if isinstance(item, list | tuple) and item and all(_is_number(v) for v in item):
                fix = f"address one item ({text}[0]) or all of them ({text}[*])"
            else:
                fix = f"the nearest number is at {_nearest(text, root, done)}"
            kind = "a list" if isinstance(item, list | tuple) else type(item).__name__
            raise VariableError(where, f"'{format_path(done)}' is {kind}, not a number; {fix}")
        part = parts[k]
        if isinstance(part, tuple):
            if not isinstance(item, list | tuple):
                raise VariableError(
                    where,
                    f"'{format_path(done)}' is not a list, so [*] does not apply; the nearest "
                    f"valid path is {_nearest(text, root, done)}",
                )
            stack.extend((v, k + 1, (*done, i)) for i, v in reversed(list(enumerate(item))))
        elif isinstance(part, int):
            if not isinstance(item, list | tuple) or part >= len(item):
                size = (
                    f"has {len(item)} items (0..{len(item) - 1})"
                    if isinstance(item, list | tuple)
                    else "is not a list"
                )
                raise VariableError(
                    where,
                    f"'{format_path((*done, part))}' does not exist: {format_path(done)} {size}; "
                    f"the nearest valid path is {_nearest(text, root, done)}",
                )
            stack.append((item[part], k + 1, (*done, part)))
        else:
            if not isinstance(item, Mapping) or part not in item:
                raise VariableError(
                    where,
                    f"'{format_path((*done, part))}' does not exist; the nearest valid path is "
                    f"{_nearest(text, root, done)}",
                )
            stack.append((item[part], k + 1, (*done, part)))
    if not found:
        raise VariableError(where, f"'{text}' addresses no number (an empty list?); fix the path")
    return found


def _get(root: Any, path: tuple[PathPart, ...]) -> Any:
    for part in path:
        root = root[part]  # type: ignore[index]
    return root


def _set(root: Any, path: tuple[PathPart, ...], value: float) -> None:
    for part in path[:-1]:
        root = root[part]  # type: ignore[index]
    root[path[-1]] = value  # type: ignore[index]


def positive_key(path: tuple[PathPart, ...]) -> bool:
    """Whether the last mapping key on ``path`` names a size that must be > 0
    (:data:`POSITIVE_KEY_WORDS`; coordinates such as ``points_mm`` may be any sign)."""
    keys = [p for p in path if isinstance(p, str)]
    last = keys[-1].lower() if keys else ""
    return any(word in last for word in POSITIVE_KEY_WORDS)


# --------------------------------------------------------------------------------------------
# Resolved variables


@dataclass(frozen=True)
class _Target:
    path: tuple[PathPart, ...]
    factor: float
    offset: float


@dataclass(frozen=True)
class DesignVariables:
    """Variables resolved against one mapping: names, bounds, what each sets, the initial design.

    Attributes
    ----------
    names : (n_var,) str — report names (the path without its root unless named).
    lower, upper : (n_var,) float — bounds in the keys' own units.
    targets : per variable, ((path, factor, offset), ...) — concrete paths it sets.
    initial : (n_var,) float — the initial design vector.
    paths : (n_var,) str — the variables' own paths as written.
    """

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    targets: tuple[tuple[_Target, ...], ...]
    initial: np.ndarray
    paths: tuple[str, ...]

    @property
    def n_var(self) -> int:
        return len(self.names)

    @property
    def space(self) -> DesignSpace:
        """The optimiser's :class:`~optimise.space.DesignSpace`."""
        return DesignSpace(self.names, self.lower, self.upper)

    def apply(self, root: Mapping[str, Any], x: np.ndarray) -> dict[str, Any]:
        """A deep copy of ``root`` with every variable's paths set from the design ``x`` (n_var,).

        ``root`` is the mapping the variables were resolved against (its shape must not have
        changed); values are plain floats, so the result dumps to YAML/JSON.
        """
        x = np.asarray(x, dtype=float).ravel()
        if x.shape != (self.n_var,):
            raise ValueError(f"design vector has {x.size} values, the variables {self.n_var}")
        out = copy.deepcopy(dict(root))
        for value, targets in zip(x, self.targets, strict=True):
            for t in targets:
                _set(out, t.path, float(t.factor * value + t.offset))
        return out

    def values(self, x: np.ndarray) -> dict[str, float]:
        """``{name: value}`` of a design vector."""
        return {n: float(v) for n, v in zip(self.names, np.asarray(x, float).ravel(), strict=True)}


def resolve_variables(
    specs: Sequence[VariableSpec],
    root: Mapping[str, Any],
    where: str = "variables",
    positive: Callable[[tuple[PathPart, ...]], bool] = positive_key,
) -> DesignVariables:
    """Check a study's variables against its mapping and resolve every path.

    Parameters
    ----------
    specs : the validated ``variables:`` items.
    root : the study as plain data, with the paths' first key at its top (``{"geometry": ...}``).
    where : key path of the variables block in the study (for errors).
    positive : which concrete paths hold sizes that must stay > 0 (default :func:`positive_key`).

    Returns
    -------
    DesignVariables

    Raises
    ------
    VariableError
        At ``variables[i].path`` (or ``.tie[j].path``) for a path that does not exist, that
        addresses no number, a whole number (a count), or a key already set by another variable;
        at ``variables[i].bounds`` for bounds that let a size reach 0 or below, or an initial
        value outside the bounds.
    """
    if not specs:
        raise VariableError(where, "no variables; give at least one {path, bounds}")
    names: list[str] = []
    targets: list[tuple[_Target, ...]] = []
    initial: list[float] = []
    owner: dict[tuple[PathPart, ...], str] = {}
    for i, spec in enumerate(specs):
        here = f"{where}[{i}]"
        lo, hi = spec.bounds
        mine: list[_Target] = []
        entries = [(spec.path, spec.factor, spec.offset, f"{here}.path")]
        entries += [
            (t.path, t.factor, t.offset, f"{here}.tie[{j}].path") for j, t in enumerate(spec.ties)
        ]
        for text, factor, offset, at in entries:
            try:
                parts = parse_path(text)
            except ValueError as exc:
                raise VariableError(at, str(exc)) from None
            for path in _expand(root, parts, text, at):
                value = _get(root, path)
                shown = format_path(path)
                if isinstance(value, int):
                    raise VariableError(
                        at,
                        f"'{shown}' is a whole number (a count such as elements or steps); "
                        "design variables are continuous: fix it in the geometry",
                    )
                if path in owner:
                    raise VariableError(
                        at,
                        f"'{shown}' is already set by {owner[path]}; a key takes one variable "
                        "(tie it there instead)",
                    )
                owner[path] = at
                if positive(path):
                    smallest = min(factor * lo + offset, factor * hi + offset)
                    if not smallest > 0:
                        raise VariableError(
                            f"{here}.bounds",
                            f"[{lo:g}, {hi:g}] lets '{shown}' reach {smallest:g}, but a size "
                            "must be > 0; raise the lower bound above 0 (at least the printable "
                            "minimum)",
                        )
                mine.append(_Target(path, float(factor), float(offset)))
        first = _get(root, mine[0].path)
        if spec.initial is not None:
            x0 = float(spec.initial)
        else:
            x0 = (float(first) - spec.offset) / spec.factor
        if not lo <= x0 <= hi:
            given = "initial" if spec.initial is not None else f"the value at {spec.path}"
            raise VariableError(
                f"{here}.{'initial' if spec.initial is not None else 'bounds'}",
                f"{given} ({x0:g}) lies outside the bounds [{lo:g}, {hi:g}]; widen the bounds "
                "or give initial: inside them",
            )
        names.append(spec.name or _default_name(spec.path))
        targets.append(tuple(mine))
        initial.append(x0)
    seen: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in seen:
            raise VariableError(
                f"{where}[{i}].name",
                f"the name '{name}' is also variables[{seen[name]}]'s; give each a distinct name",
            )
        seen[name] = i
    lo_arr = np.array([s.bounds[0] for s in specs], dtype=float)
    hi_arr = np.array([s.bounds[1] for s in specs], dtype=float)
    for arr in (lo_arr, hi_arr):
        arr.setflags(write=False)
    x0_arr = np.array(initial, dtype=float)
    x0_arr.setflags(write=False)
    if not all(math.isfinite(v) for v in x0_arr):
        raise VariableError(where, "an initial value is not finite; give numbers")
    return DesignVariables(
        tuple(names), lo_arr, hi_arr, tuple(targets), x0_arr, tuple(s.path for s in specs)
    )


def _default_name(path: str) -> str:
    """The path without its root (``geometry.``): short, and still carries the key's unit."""
    return path.split(".", 1)[1] if "." in path else path
