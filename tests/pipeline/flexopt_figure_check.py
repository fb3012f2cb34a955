"""What plotly's figure classes checked as report.html's figures were built, checked in the
tests instead (the figures are plain JSON now: pipeline/figure_json.py).

:func:`assert_plotly_reads_unchanged` builds ``plotly.graph_objects.Figure`` from a figure's
JSON as the page holds it: plotly raises on a property or a value plotly.js does not know
(a misspelt key, a colour it cannot read, a number out of range), and it must write the same
JSON back, so that nothing was left for its coercions (a title as a bare string, a magic
underscore) to change: the page holds what plotly would have written.
"""

from __future__ import annotations

import base64
import json
from typing import Any

import numpy as np

_DTYPES = {"i1": "int8", "u1": "uint8", "i2": "int16", "u2": "uint16", "i4": "int32",
           "u4": "uint32", "f4": "float32", "f8": "float64"}  # fmt: skip


def decoded(node: Any) -> Any:
    """A figure's JSON with every typed array (``{"dtype", "bdata"}``) as a plain list (NaN as
    None), so that two writings of the same values compare equal."""
    if isinstance(node, dict):
        if "bdata" in node and "dtype" in node:
            values = np.frombuffer(base64.b64decode(node["bdata"]), dtype=_DTYPES[node["dtype"]])
            if "shape" in node:
                values = values.reshape([int(n) for n in str(node["shape"]).split(",")])
            out = values.tolist()
            return json.loads(json.dumps(out).replace("NaN", "null"))
        return {key: decoded(value) for key, value in node.items()}
    if isinstance(node, list):
        return [decoded(value) for value in node]
    return node


def assert_plotly_reads_unchanged(spec: dict[str, Any]) -> None:
    """plotly's classes accept the figure ``spec`` (its JSON, as on the page) and write it back
    unchanged (typed arrays compared by value)."""
    go = __import__("plotly.graph_objects", fromlist=["Figure"])
    fig = go.Figure(spec)  # validates every property (raises ValueError on one it does not know)
    again = json.loads(fig.to_json())
    where = first_difference(decoded(spec), decoded(again))
    assert where is None, f"plotly writes the figure otherwise at {where}"


def first_difference(a: Any, b: Any, path: str = "") -> str | None:
    """Where two JSON values first differ (a path and both values), or None."""
    if isinstance(a, dict) and isinstance(b, dict):
        for key in [*a, *(k for k in b if k not in a)]:
            if key not in a or key not in b:
                return f"{path}/{key}: {'missing' if key not in a else 'extra'} on the page"
            found = first_difference(a[key], b[key], f"{path}/{key}")
            if found:
                return found
        return None
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for k, (u, v) in enumerate(zip(a, b, strict=True)):
            found = first_difference(u, v, f"{path}[{k}]")
            if found:
                return found
        return None
    return None if a == b else f"{path}: {str(a)[:80]!r} on the page, {str(b)[:80]!r} by plotly"
