"""What ``flexopt list``, ``flexopt init`` and ``flexopt schema`` print or write.

- :func:`catalogue`: every study kind (built-in and plugins) and every built-in study, one line
  each with what it designs;
- :func:`starter_study`: the text of a commented starter study of a kind, from the kind's shipped
  example (its comments kept) or, for a kind without one (a plugin's), from its schema;
- :func:`study_schema`: the JSON schema of a study of one kind, or of any kind.

Nothing here writes files or prints; the CLI does.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from importlib import resources
from typing import Any

import yaml
from flexopt.fea.materials import MATERIALS
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import (
    builtin_kind_names,
    get_kind,
    kind_summary,
    kinds,
    refused_plugins,
    unavailable_kinds,
)
from flexopt.pipeline.study import NAME_RE, list_examples, parse_study_text
from pydantic.json_schema import models_json_schema

__all__ = [
    "Catalogue",
    "catalogue",
    "check_study_name",
    "default_example",
    "example_kinds",
    "example_summary",
    "starter_study",
    "study_schema",
]

#: The kind ``flexopt init`` starts from without ``--kind``: a cantilever solves in a second.
DEFAULT_KIND = "polyline_beam"

#: The example ``flexopt init`` copies for a kind with several, where the rule in
#: :func:`default_example` would pick a less telling one.
_PREFERRED_EXAMPLE = {"polyline_beam": "cantilever", "mechanism": "parallel-guide"}

SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"


def _example_text(name: str) -> str:
    return (resources.files("flexopt.pipeline") / "examples" / f"{name}.yaml").read_text(
        encoding="utf-8"
    )


def example_kinds() -> dict[str, str]:
    """The geometry kind of every built-in study, by example name (read, not validated)."""
    out = {}
    for name in list_examples():
        data = yaml.safe_load(_example_text(name))
        geometry = data.get("geometry") if isinstance(data, dict) else None
        out[name] = str(geometry.get("kind")) if isinstance(geometry, dict) else "?"
    return out


def example_summary(name: str, limit: int = 90) -> str:
    """One line from the example's leading comment: its first sentence, cut to ``limit``."""
    lines = []
    for line in _example_text(name).splitlines():
        if not line.startswith("#"):
            break
        text = line.lstrip("#").strip()
        if not text:
            break  # the first paragraph only
        lines.append(text)
    text = " ".join(lines)
    # the first sentence: a full stop before a space and a capital letter or the end
    match = re.search(r"\.(?=\s+[A-Z(]|$)", text)
    text = text[: match.start()] if match else text
    if len(text) > limit:  # cut at a word, not inside one
        text = text[: limit - 3].rsplit(" ", 1)[0].rstrip(",;:") + "..."
    return text


def default_example(kind: str) -> str | None:
    """The built-in study ``flexopt init --kind`` copies: the one named after the kind, else a
    preferred one, else the shortest; None for a kind without an example (a plugin's)."""
    named = [name for name, k in example_kinds().items() if k == kind]
    if not named:
        return None
    for name in named:
        if name.replace("-", "_") == kind:
            return name
    if _PREFERRED_EXAMPLE.get(kind) in named:
        return _PREFERRED_EXAMPLE[kind]
    return min(named, key=lambda name: (len(_example_text(name)), name))


@dataclass(frozen=True)
class Catalogue:
    """What ``flexopt list`` shows.

    Attributes
    ----------
    kinds : list of (name, origin, summary)
        Available kinds; origin is ``built-in`` or ``plugin``.
    studies : list of (name, kind, summary)
        The built-in studies.
    unavailable : list of (name, reason)
        Plugin kinds that failed to load, and plugins refused for their name (name ``-``).
    """

    kinds: list[tuple[str, str, str]]
    studies: list[tuple[str, str, str]]
    unavailable: list[tuple[str, str]]


def catalogue() -> Catalogue:
    """Every kind and built-in study with a one-line summary, and the plugins that failed."""
    builtin = builtin_kind_names()
    rows = [
        (name, "built-in" if name in builtin else "plugin", kind_summary(kind))
        for name, kind in sorted(kinds().items())
    ]
    studies = [(name, kind, example_summary(name)) for name, kind in example_kinds().items()]
    unavailable = sorted(unavailable_kinds().items()) + [("-", line) for line in refused_plugins()]
    return Catalogue(rows, studies, unavailable)


def check_study_name(name: str) -> None:
    """Refuse a study name that cannot name a run folder (the rule of ``Study.name``).

    Raises
    ------
    StudyError
        At ``name``, with the fix.
    """
    if not NAME_RE.match(name) or len(name) > 100:
        suggestion = re.sub(r"[^A-Za-z0-9_.-]+", "_", name[:60]).strip("_.-") or "my_study"
        raise StudyError(
            "name",
            f"{name[:40]!r} cannot name a study (it names the run folder); use letters, digits, "
            f"'.', '_' and '-' (at most 100), e.g. '{suggestion}'",
        )


# --------------------------------------------------------------------------------------------
# Starter studies

_NAME_LINE = re.compile(r"""^name:[ \t]*(?:"[^"\n]*"|'[^'\n]*'|[^\s#]+)""", re.MULTILINE)


def starter_study(
    name: str, kind: str | None = None, example: str | None = None, file: str | None = None
) -> str:
    """A commented starter study named ``name``, as YAML text that loads as it is.

    From ``example`` (a built-in study) when given, else from the kind's shipped example (its
    comments kept, its name replaced), else generated from the kind's schema (required keys with
    placeholder values, optional keys commented out with their defaults, each with its
    description and unit). ``file`` is where it will be written (named in the header's hints).

    Raises
    ------
    StudyError
        For a bad name, an unknown or unavailable kind, or an unknown example.
    """
    check_study_name(name)
    file = file or f"{name}.yaml"
    if example is not None:
        if example.endswith(".yaml"):
            example = example[: -len(".yaml")]
        if example not in list_examples():
            raise StudyError(
                "",
                f"no built-in study named {example[:40]!r}; use one of "
                + ", ".join(list_examples()),
            )
        kind = example_kinds()[example]
    else:
        kind = kind or DEFAULT_KIND
        _known_kind(kind)
        example = default_example(kind)
    schema_hint = f"flexopt schema --kind {kind} --out {kind}.schema.json"
    origin = "its schema" if example is None else f"the built-in study '{example}'"
    header = [
        f"# {name}: a starter study of kind {kind}, written by flexopt init from {origin}.",
        f"# Try it: flexopt evaluate {file}   (or: flexopt run {file} --quick)",
        f"# Every key with its unit and limits: {schema_hint}",
        "# (docs/usage.md, 'Editor completion': hook that schema into your editor)",
        "",
    ]
    if example is None:
        body = _from_schema(name, kind)
    else:
        body, count = _NAME_LINE.subn(f"name: {name}", _example_text(example), count=1)
        if not count:  # every shipped study has a top-level name; keep the file valid if not
            body = f"name: {name}\n" + body
    text = "\n".join(header) + "\n" + body
    parsed = parse_study_text(text, f"{name}.yaml")  # the promise: it reads back with this name
    if parsed.get("name") != name:
        raise StudyError("name", f"the starter study did not keep the name {name!r} (a bug)")
    return text


def _known_kind(kind: str) -> None:
    """Raise StudyError at ``--kind`` for an unknown or unavailable kind."""
    try:
        get_kind(kind)
    except StudyError as exc:
        raise StudyError("--kind", exc.problem) from None


def _resolve(schema: dict[str, Any], node: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in node:
        node = {**schema["$defs"][node["$ref"].split("/")[-1]], **{
            k: v for k, v in node.items() if k != "$ref"
        }}  # fmt: skip
    return node


def _options(schema: dict[str, Any], node: dict[str, Any]) -> list[dict[str, Any]]:
    """The non-null alternatives of a node (``X | None`` is ``anyOf [X, null]``)."""
    node = _resolve(schema, node)
    if "anyOf" in node or "oneOf" in node:
        out = []
        for option in node.get("anyOf", node.get("oneOf")):
            option = _resolve(schema, option)
            if option.get("type") != "null":
                out.append(option)
        return out or [node]
    return [node]


def _placeholder(schema: dict[str, Any], node: dict[str, Any]) -> Any:
    """A value that passes the node's own bounds: a start, not a design."""
    node = _options(schema, node)[0]
    if "const" in node:
        return node["const"]
    if "enum" in node:
        return node["enum"][0]
    kind = node.get("type")
    if kind in ("number", "integer"):
        lo = node.get("minimum", node.get("exclusiveMinimum"))
        hi = node.get("maximum", node.get("exclusiveMaximum"))
        if lo is not None and hi is not None:
            value = (lo + hi) / 2
        elif lo is not None:
            value = lo + 1
        elif hi is not None:
            value = hi - 1
        else:
            value = 1.0
        if kind == "integer":
            value = math.ceil(value) if lo is not None else math.floor(value)
        return value
    if kind == "boolean":
        return False
    if kind == "string":
        return "TODO"
    if kind == "array":
        if "prefixItems" in node:
            return [_placeholder(schema, item) for item in node["prefixItems"]]
        return [_placeholder(schema, node.get("items", {}))] * int(node.get("minItems", 1))
    if kind == "object" and "properties" in node:
        return {
            key: _placeholder(schema, sub)
            for key, sub in node["properties"].items()
            if key in node.get("required", ())
        }
    return None


def _comment(node: dict[str, Any], required: bool) -> str:
    words = " ".join(str(node.get("description", "")).split())
    if required:
        return "required" + (f": {words}" if words else "")
    return words


#: Plain words YAML would not read as a string (booleans, null): these are quoted.
_YAML_WORDS = {"true", "false", "yes", "no", "on", "off", "null", "y", "n", "~"}


#: Comments of the study-wide keys whose fields carry no description.
_TOP_COMMENTS = {
    "material": "required: a library name (PLA, ABS, PETG, PA12, 65Mn, ...) or a mapping "
    "{E_MPa, nu, yield_MPa, density_kg_m3}",
}


def _flow(value: Any) -> str:
    """A value on one line of YAML: a plain word bare, anything else as JSON (YAML's flow)."""
    if (
        isinstance(value, str)
        and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.-]*", value)
        and value.lower() not in _YAML_WORDS
    ):
        return value
    return json.dumps(value, ensure_ascii=False)


def _block(schema: dict[str, Any], node: dict[str, Any], indent: int, top: dict) -> list[str]:
    """YAML lines of a model: required keys set, optional keys commented out with defaults."""
    pad = "  " * indent
    lines = []
    required = set(node.get("required", ()))
    for key, sub in node.get("properties", {}).items():
        options = _options(schema, sub)
        is_model = len(options) == 1 and "properties" in options[0]
        comment = _TOP_COMMENTS.get(key) if indent == 0 and key in _TOP_COMMENTS else None
        comment = comment or _comment(sub, key in required)
        tail = f"  # {comment}" if comment else ""
        if key in top:
            lines.append(f"{pad}{key}: {_flow(top[key])}{tail}")
        elif key in required and is_model:
            lines.append(f"{pad}{key}:{tail}")
            lines += _block(schema, options[0], indent + 1, {})
        elif key in required:
            lines.append(f"{pad}{key}: {_flow(_placeholder(schema, sub))}{tail}")
        else:
            default = sub.get("default")
            shown = "" if default is None else " " + _flow(default)
            if len(shown) > 60:
                shown = " {...}  (a block; see flexopt schema)"
            lines.append(f"{pad}# {key}:{shown}{tail}")
    return lines


def _from_schema(name: str, kind: str) -> str:
    """A starter study generated from the kind's JSON schema."""
    schema = get_kind(kind).model.model_json_schema()
    top = {"name": name, "material": "PLA"}  # a library material: any kind accepts a name
    lines = _block(schema, schema, 0, top)
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# JSON schema


def study_schema(kind: str | None = None) -> dict[str, Any]:
    """The JSON schema (draft 2020-12) of a study file of ``kind``; without a kind, of a study
    of any available kind (``oneOf`` the kinds' studies, told apart by ``geometry.kind``).

    Raises
    ------
    StudyError
        At ``--kind`` for an unknown or unavailable kind.
    """
    if kind is not None:
        _known_kind(kind)
        schema = get_kind(kind).model.model_json_schema()
        _material_by_name(schema)
        _material_by_name_in(schema.get("$defs", {}))
        return {"$schema": SCHEMA_DIALECT, **schema}
    available = kinds()
    names = sorted(available)
    refs, defs = models_json_schema(
        [(available[name].model, "validation") for name in names], title="flexopt study"
    )
    _material_by_name_in(defs.get("$defs", {}))
    return {
        "$schema": SCHEMA_DIALECT,
        "title": "flexopt study",
        "description": "A flexopt study file of any kind, told apart by geometry.kind: "
        + ", ".join(names),
        "oneOf": [refs[(available[name].model, "validation")] for name in names],
        "$defs": defs.get("$defs", {}),
    }


def _material_by_name_in(defs: dict[str, Any]) -> None:
    for node in defs.values():
        _material_by_name(node)


def _material_by_name(node: dict[str, Any]) -> None:
    """Let ``material:`` be a library name too, as the study model does: pydantic's schema
    shows only the mapping, because the name is resolved by a before-validator."""
    material = node.get("properties", {}).get("material")
    if not isinstance(material, dict):
        return
    options = material.get("anyOf", [material])  # an optional material is anyOf [it, null]
    ref = next((o["$ref"] for o in options if o.get("$ref", "").endswith("/MaterialSpec")), None)
    if ref is None:
        return
    names = list(MATERIALS)
    by_name = {"type": "string", "enum": names}
    rest = [o for o in options if o.get("$ref") != ref]
    node["properties"]["material"] = {
        **{k: v for k, v in material.items() if k not in ("$ref", "anyOf")},
        "description": "a library material by name (case, '-' and '_' do not matter: "
        + ", ".join(names)
        + ") or your own {E_MPa, nu, yield_MPa, density_kg_m3}"
        + (f"; {material['description']}" if material.get("description") else ""),
        "anyOf": [by_name, {"$ref": ref}, *rest],
    }
