"""Changing a validated study: :meth:`Study.replace` and :meth:`Study.with_values`.

A study is frozen; a change returns a NEW study that went through :func:`validate_study` again,
so the kind's own model and checks run on the changed values exactly as on a study file. The
study is dumped to plain data (as ``study.yaml`` is written), the changes are set there, and the
result is validated: a bad value is refused with its key path, as in a file.

Paths use the grammar of design variables (:func:`optimise.variables.parse_path`):
``geometry.width_mm``, ``geometry.points_mm[1][0]``, ``geometry.thickness_mm[*]`` (every item
of the list).

A key that a design variable sets (its ``path`` or a ``tie``) is not a value the study keeps:
the variable's ``initial`` is what ``flexopt evaluate`` solves. Setting such a key therefore
moves the variable: its ``initial`` becomes the value (through the key's ``factor`` and
``offset``), so every key the variable sets follows, and a value outside the variable's bounds,
or two tied keys set to different values, is refused at the key with the variable named
(:func:`_move_variables`). Nothing is silently overridden.
"""

from __future__ import annotations

import copy
import difflib
import math
import types
import typing
from collections import abc
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from flexopt.optimise.variables import (
    PathPart,
    VariableError,
    VariableSpec,
    format_path,
    parse_path,
    resolve_variables,
)
from flexopt.pipeline.errors import StudyError
from pydantic import BaseModel

if TYPE_CHECKING:
    from flexopt.pipeline.study import Study

__all__ = ["replace_blocks", "set_values", "study_data"]


def study_data(study: Study) -> dict[str, Any]:
    """The study as plain data, as study.yaml holds it (unset keys left out): reads back as is."""
    return study.model_dump(mode="json", exclude_none=True)


def plain(value: Any) -> Any:
    """A value given in Python as the plain data a study file would hold."""
    if isinstance(value, BaseModel):
        return value.model_dump(mode="json", exclude_none=True)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    return value


#: ``pipeline.study.validate_study``, passed in by the caller: this module sits below
#: pipeline/study.py (whose Study methods call it), so it does not import it.
Validator = Callable[[dict[str, Any]], "Study"]


def replace_blocks(study: Study, changes: Mapping[str, Any], validate: Validator) -> Study:
    """``study`` with top-level blocks replaced (``name``, ``material``, ``geometry``, ...).

    Raises
    ------
    StudyError
        At the key for a block the study's kind does not have (with the closest name), or at
        the key path of the first value the kind's model or checks refuse.
    """
    fields = list(type(study).model_fields)
    old = study_data(study)
    data = copy.deepcopy(old)
    for key, value in changes.items():
        if key not in fields:
            close = difflib.get_close_matches(key, fields, n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise StudyError(
                key,
                f"a {study.kind} study has no block '{key}'; {hint}replace one of "
                f"{', '.join(fields)} (use with_values for a key inside a block)",
            )
        if value is None:
            data.pop(key, None)  # back to the kind's default (a required block is then missing)
        else:
            data[key] = plain(value)
    _move_variables(study, old, data, [(key, (key,)) for key in changes])
    return validate(data)


def _paths(data: Any) -> list[str]:
    """Every key path in plain study data (mappings and list items, inner nodes too)."""
    found: list[str] = []
    stack: list[tuple[Any, tuple[PathPart, ...]]] = [(data, ())]
    while stack:
        item, where = stack.pop()
        if where:
            found.append(format_path(where))
        if isinstance(item, Mapping):
            stack.extend((v, (*where, str(k))) for k, v in item.items())
        elif isinstance(item, list):
            stack.extend((v, (*where, i)) for i, v in enumerate(item))
    return found


def _closest(text: str, data: Any, more: Sequence[str] = ()) -> str:
    close = difflib.get_close_matches(text, [*_paths(data), *more], n=1, cutoff=0.5)
    return f"; did you mean {close[0]}?" if close else ""


def annotation_at(model: type[BaseModel], path: tuple[int | str, ...]) -> Any:
    """The type annotation a raw key path leads to in a study model (None when unknown)."""
    current: Any = model
    for part in path:
        while typing.get_origin(current) is typing.Annotated:
            current = typing.get_args(current)[0]
        origin = typing.get_origin(current)
        if origin in (typing.Union, types.UnionType):
            arms = [a for a in typing.get_args(current) if a is not type(None)]
            if len(arms) != 1:
                return None  # several shapes: the validated value decides (second check)
            current = arms[0]
            origin = typing.get_origin(current)
        if isinstance(current, type) and issubclass(current, BaseModel):
            field = current.model_fields.get(str(part))
            if field is None:
                return None
            current = field.annotation
        elif origin in (list, tuple, abc.Sequence) and isinstance(part, int):
            args = typing.get_args(current)
            if origin is tuple and args and args[-1] is not Ellipsis:
                current = args[part] if part < len(args) else None
            else:
                current = args[0] if args else None
        elif origin is dict:
            args = typing.get_args(current)
            current = args[1] if len(args) == 2 else None
        else:
            return None
    return current


def _model_at(model: type[BaseModel], path: Sequence[PathPart]) -> type[BaseModel] | None:
    """The pydantic model a key path leads to in a study model (None when it is not one)."""
    current = model if not path else annotation_at(model, tuple(path))
    while True:
        origin = typing.get_origin(current)
        if origin is typing.Annotated:
            current = typing.get_args(current)[0]
        elif origin in (typing.Union, types.UnionType):
            arms = [a for a in typing.get_args(current) if a is not type(None)]
            if len(arms) != 1:
                return None
            current = arms[0]
        else:
            break
    return current if isinstance(current, type) and issubclass(current, BaseModel) else None


def _set_path(
    data: dict[str, Any], model: type[BaseModel], text: str, value: Any, kind: str
) -> None:
    """Set ``value`` at the path ``text`` in ``data`` (in place); ``[*]`` sets every item.

    A key the data does not hold is added only where the model has that field (an optional block
    left unset, such as ``parallel``); anything else is an unknown path.
    """
    try:
        parts = parse_path(text)
    except ValueError as exc:
        raise StudyError(text, str(exc)) from None
    holders: list[tuple[Any, tuple[PathPart, ...]]] = [(data, ())]
    for k, part in enumerate(parts):
        last = k == len(parts) - 1
        following: list[tuple[Any, tuple[PathPart, ...]]] = []
        for holder, done in holders:
            here = format_path(done) or "the study"
            if isinstance(part, tuple):  # [*]: every item of a list
                if not isinstance(holder, list):
                    raise StudyError(
                        text, f"{here} is not a list, so [*] does not apply{_closest(text, data)}"
                    )
                indices: Sequence[PathPart] = range(len(holder))
            elif isinstance(part, int):
                if not isinstance(holder, list):
                    raise StudyError(
                        text,
                        f"{here} is not a list, so [{part}] does not apply{_closest(text, data)}",
                    )
                if part >= len(holder):
                    raise StudyError(
                        text,
                        f"{here} has {len(holder)} items ([0]..[{len(holder) - 1}]); there is no "
                        f"[{part}] (to change the length, set the whole list: "
                        f"{{'{format_path(done)}': [...]}})",
                    )
                indices = (part,)
            else:
                if not isinstance(holder, dict):
                    raise StudyError(text, f"{here} is not a block of keys{_closest(text, data)}")
                if part not in holder:
                    block = _model_at(model, done)
                    if block is None or part not in block.model_fields:
                        allowed = sorted(block.model_fields if block else holder)
                        more = [format_path((*done, key)) for key in allowed]
                        raise StudyError(
                            text,
                            f"a {kind} study has no key '{format_path((*done, part))}'"
                            f"{_closest(text, data, more)} (keys of {here}: {', '.join(allowed)})",
                        )
                    if not last:
                        holder[part] = {}  # an optional block left unset: start it empty
                indices = (part,)
            for index in indices:
                if last:
                    holder[index] = plain(value)  # type: ignore[index]
                else:
                    following.append((holder[index], (*done, index)))  # type: ignore[index]
        holders = following


def set_values(study: Study, values: Mapping[str, Any], validate: Validator) -> Study:
    """``study`` with the values at the given key paths changed, validated again.

    Parameters
    ----------
    values : mapping of key path to value
        ``{"geometry.width_mm": 6.0, "geometry.points_mm[1][0]": 30}``; a value may be a number,
        text, a list or a mapping (a whole block), in the key's unit.

    Raises
    ------
    StudyError
        At the path for one that does not exist (naming the closest path that does), or at the
        key path of the first value the kind's model or checks refuse.
    """
    if not isinstance(values, Mapping):
        raise StudyError(
            "", f"with_values takes a mapping of key paths to values, not {type(values).__name__}"
        )
    old = study_data(study)
    data = copy.deepcopy(old)
    given: list[tuple[str, tuple[PathPart, ...]]] = []
    for text, value in values.items():
        if not isinstance(text, str):
            raise StudyError(str(text), "a key path is text, e.g. 'geometry.width_mm'")
        _set_path(data, type(study), text, value, study.kind)
        given.append((text, parse_path(text)))
    _move_variables(study, old, data, given)
    return validate(data)


def _covers(given: tuple[PathPart, ...], path: tuple[PathPart, ...]) -> bool:
    """Whether the key path ``given`` (``[*]`` for every item) is ``path`` or a block holding it."""
    if len(given) > len(path):
        return False
    return all(
        g == p or (isinstance(g, tuple) and isinstance(p, int))
        for g, p in zip(given, path, strict=False)
    )


def _leaf(data: Any, path: tuple[PathPart, ...]) -> float | None:
    """The number at ``path`` in plain data (None where there is none, e.g. a changed shape)."""
    for part in path:
        try:
            data = data[part]  # type: ignore[index]
        except (KeyError, IndexError, TypeError):
            return None
    if isinstance(data, bool) or not isinstance(data, int | float):
        return None
    return float(data)


def _move_variables(
    study: Study,
    old: dict[str, Any],
    data: dict[str, Any],
    given: Sequence[tuple[str, tuple[PathPart, ...]]],
) -> None:
    """Move the design variables whose keys the change sets (in ``data``, in place).

    A key a variable sets (``path`` or ``tie``) named by a given path is the value the user
    wants, so the variable's ``initial`` becomes ``(value - offset) / factor``; a key inside a
    whole block or list that was given moves it only where its value changed (a block copied
    back unchanged keeps the variable where it was). The change is refused at the given path
    when the value lies outside the variable's bounds (as they are after the change) or two of
    the variable's keys ask for different values. A change of ``variables`` itself is left as
    given (the user writes the variables then).

    Raises
    ------
    StudyError
        At the given key path, naming the variable that holds the key and the fix.
    """
    specs = getattr(study, "variables", None)
    if not specs or not all(isinstance(s, VariableSpec) for s in specs):
        return  # a kind without path variables: every key is the study's own
    own = [parts for _, parts in given if parts[:1] == ("variables",)]
    if any(len(p) < 3 or p[2] not in ("bounds", "initial", "name") for p in own):
        return  # the variables themselves are rewritten: they are what the user gives
    initial_given = {p[1] for p in own if p[2] == "initial"}
    try:
        resolved = resolve_variables(specs, old)
    except VariableError:
        return  # (the study was validated: its variables resolve; be safe all the same)
    items = data.get("variables")
    if not isinstance(items, list) or len(items) != len(specs):
        return
    for i, targets in enumerate(resolved.targets):
        name, here = resolved.names[i], f"variables[{i}]"
        wanted: list[tuple[float, str, str, float]] = []  # (x, given path, key, value)
        for target in targets:
            exact = [t for t, parts in given if parts == target.path]
            inside = [t for t, parts in given if _covers(parts, target.path)]
            if not inside:
                continue
            value = _leaf(data, target.path)
            if value is None or not math.isfinite(value):
                continue  # not a number: the kind's model refuses it at its key
            if not exact and value == _leaf(old, target.path):
                continue  # a whole block given with this key as it was
            text = (exact or inside)[-1]
            x = (value - target.offset) / target.factor
            wanted.append((x, text, format_path(target.path), value))
        if not wanted:
            continue
        x, text, key, value = wanted[0]
        if i in initial_given or any(isinstance(p[1], tuple) for p in own):
            raise StudyError(
                text,
                f"'{key}' is set by design variable '{name}' ({here}), whose initial is also "
                "given in this change; give one of them (setting the key moves the initial)",
            )
        for x2, text2, key2, value2 in wanted[1:]:
            if not math.isclose(x2, x, rel_tol=1e-9, abs_tol=1e-12):
                raise StudyError(
                    text2,
                    f"'{key2}' and '{key}' are both set by design variable '{name}' ({here}), "
                    f"which cannot be {x:g} and {x2:g} at once (given {value:g} and "
                    f"{value2:g}); set one of them, or change {here} (its tie) itself",
                )
        bounds = items[i].get("bounds") if isinstance(items[i], dict) else None
        try:
            lo, hi = (float(b) for b in bounds)  # type: ignore[union-attr]
        except (TypeError, ValueError):
            lo, hi = float(resolved.lower[i]), float(resolved.upper[i])
        if not lo <= x <= hi:
            what = "this key" if key == format_path(parse_path(text)) else f"'{key}'"
            moved = f"{value:g}" if x == value else f"{value:g} puts it at {x:g}, which"
            raise StudyError(
                text,
                f"{what} is set by design variable '{name}' ({here}), and {moved} lies outside "
                f"its bounds [{lo:g}, {hi:g}]; give a value inside them, or widen them in the "
                f"same change ({{'{here}.bounds': [{min(lo, x):g}, {max(hi, x):g}]}})",
            )
        items[i]["initial"] = float(x)
