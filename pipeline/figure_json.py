"""report.html's figures built as plotly's JSON in plain dicts, without plotly's figure classes.

Why (issue 27, item 4): plotly's classes check every property of every trace against its schema
as the figure is built. Loading them took ~0.3 s CPU (the run's preload thread, beside the busy
workers) and building a constant-force report's figures with them ~0.2 s more, on the report's
critical path; the JSON they wrote is what plotly.js reads, and that is all the page needs.
Here a trace is ``{"type": ..., **properties}`` and a figure two lists, so the call sites read
as they did with ``plotly.graph_objects`` (``fj.Figure``, ``fj.Scatter(...)``,
``add_trace``, ``update_layout``) and write the same JSON, with two rules the classes used to
apply for us:

- properties are named as plotly.js names them, nested dicts and all (``line={"color": c}``,
  ``title={"text": t}``): plotly's "magic underscores" (``line_color``) and its shorthand
  (a title as a bare string) are not expanded here;
- values are JSON: numpy arrays become plotly.js typed arrays (``{"dtype", "bdata"}``, int64
  narrowed to the smallest integer type that holds it) as plotly >= 6 writes them, numpy
  scalars Python numbers, and NaN or ±inf ``null`` (a gap), as plotly's encoder writes them.

What the classes checked is now checked by the tests: every figure of every report the tests
make is read back through ``plotly.graph_objects.Figure`` (which raises on a property or value
plotly.js does not know) and must come out unchanged (tests/pipeline/test_report_html.py), and
the browser tests draw them with the page's plotly.js.
"""

from __future__ import annotations

import base64
import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

#: numpy dtypes plotly.js reads as typed arrays, by their name there
_TYPED = {
    "int8": "i1",
    "uint8": "u1",
    "int16": "i2",
    "uint16": "u2",
    "int32": "i4",
    "uint32": "u4",
    "float32": "f4",
    "float64": "f8",
}


#: plotly's named colorscales report.html uses, as plotly's classes write them (a name alone
#: would be read by plotly.js, whose "RdBu" and "Viridis" are other colours than plotly.py's)
RDBU = [[0.0, "rgb(103,0,31)"], [0.1, "rgb(178,24,43)"], [0.2, "rgb(214,96,77)"],
        [0.3, "rgb(244,165,130)"], [0.4, "rgb(253,219,199)"], [0.5, "rgb(247,247,247)"],
        [0.6, "rgb(209,229,240)"], [0.7, "rgb(146,197,222)"], [0.8, "rgb(67,147,195)"],
        [0.9, "rgb(33,102,172)"], [1.0, "rgb(5,48,97)"]]  # fmt: skip
VIRIDIS = [[k / 9, c] for k, c in enumerate(
    ["#440154", "#482878", "#3e4989", "#31688e", "#26828e", "#1f9e89", "#35b779", "#6ece58",
     "#b5de2b", "#fde725"])]  # fmt: skip


class Figure:
    """A plotly figure as JSON data: ``data`` (list of trace dicts) and ``layout`` (dict).

    ``Figure(trace)``, ``Figure([trace, ...])`` or ``Figure()``; ``layout`` optional."""

    def __init__(self, data: Any = None, layout: Mapping[str, Any] | None = None) -> None:
        if data is None:
            data = []
        elif isinstance(data, Mapping):
            data = [data]
        self.data: list[dict[str, Any]] = [dict(trace) for trace in data]
        self.layout: dict[str, Any] = {}
        if layout:
            self.update_layout(layout)

    def add_trace(self, trace: Mapping[str, Any]) -> Figure:
        self.data.append(dict(trace))
        return self

    def update_layout(self, layout: Mapping[str, Any] | None = None, **more: Any) -> Figure:
        """Merge ``layout`` and ``more`` into the layout, as plotly's ``update_layout`` does:
        a dict merges into the dict already there, any other value replaces it."""
        for key, value in {**(layout or {}), **more}.items():
            _merge(self.layout, key, value)
        return self

    def to_plotly_json(self) -> dict[str, Any]:
        """``{"data": [...], "layout": {...}}``, the figure's own traces and a copy of its
        layout's top level (numpy values stay as they are: :func:`dumps` writes them)."""
        return {"data": self.data, "layout": dict(self.layout)}


def _merge(into: dict[str, Any], key: str, value: Any) -> None:
    old = into.get(key)
    if isinstance(value, Mapping) and isinstance(old, dict):
        for k, v in value.items():
            _merge(old, k, v)
    else:
        into[key] = dict(value) if isinstance(value, Mapping) else value


def _trace(kind: str) -> Any:
    def make(**properties: Any) -> dict[str, Any]:
        return {"type": kind, **properties}

    make.__name__ = make.__qualname__ = kind.capitalize()
    make.__doc__ = f"A {kind} trace of plotly.js: ``{{'type': '{kind}', **properties}}``."
    return make


Bar = _trace("bar")
Heatmap = _trace("heatmap")
Mesh3d = _trace("mesh3d")
Parcoords = _trace("parcoords")
Scatter = _trace("scatter")
Scatter3d = _trace("scatter3d")
Splom = _trace("splom")


def typed_array(values: np.ndarray) -> Any:
    """A numpy array as plotly.js's typed array ``{"dtype", "bdata"[, "shape"]}`` (int64 and
    uint64 narrowed to the smallest type holding every value), as plotly >= 6 writes it; an
    empty array or one of another dtype as a list (NaN, ±inf as None)."""
    v = np.asarray(values)
    if v.size and v.dtype.kind in "iu" and v.dtype.itemsize == 8:
        lo, hi = int(v.min()), int(v.max())
        for dtype in (
            ("int8", "int16", "int32") if v.dtype.kind == "i" else ("uint8", "uint16", "uint32")
        ):
            info = np.iinfo(dtype)
            if info.min <= lo and hi <= info.max:
                v = v.astype(dtype)
                break
    name = _TYPED.get(str(v.dtype))
    if not v.size or name is None:
        return _json(v.tolist())
    out = {"dtype": name, "bdata": base64.b64encode(np.ascontiguousarray(v)).decode("ascii")}
    if v.ndim > 1:
        out["shape"] = str(v.shape)[1:-1]
    return out


def _json(value: Any) -> Any:
    """``value`` as JSON data: dicts and lists walked, numpy arrays typed arrays, numpy
    scalars Python ones, non-finite floats None."""
    if isinstance(value, Mapping):
        return {str(k): _json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return typed_array(value)
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def dumps(value: Any) -> str:
    """``value`` (a figure's JSON data, numpy values allowed) as compact JSON text.

    Most figures hold no NaN: one pass of json's C encoder, numpy's arrays and scalars through
    its ``default``. One that holds NaN or ±inf (json refuses them with ``allow_nan=False``) is
    walked once in Python first (:func:`_json`: they become null, as plotly writes them).
    """
    try:
        return json.dumps(value, separators=(",", ":"), allow_nan=False, default=_default)
    except ValueError:
        return json.dumps(_json(value), separators=(",", ":"), allow_nan=False, default=_default)


def _default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return _json(typed_array(value))
    if isinstance(value, np.generic):
        return _json(value.item())
    raise TypeError(f"{type(value).__name__} is not JSON data")
