"""report.html's plotly templates, put into each figure's JSON as it is embedded.

report.html's figures are plain JSON (pipeline/figure_json.py): no plotly class applies a
template to them. A figure names :data:`WHITE` (``report_html._layout``: "plotly_white") or no
template; :func:`finish_template` puts the template's JSON first in its layout, the value plotly
wrote for the same figure built with its classes: "plotly_white" where it names :data:`WHITE`,
and where it names none plotly's default template (``plotly.io.templates.default``: "plotly"
unless a program set another), which plotly applies to every new figure. The JSON is read once
per process from the file plotly's own template registry loads
(``plotly/package_data/templates/NAME.json``), without plotly's classes (loading them cost
~0.3 s CPU, issue 27 item 4); a template a program registered itself goes through plotly.
"""

from __future__ import annotations

import functools
import importlib.util
import json
import sys
from pathlib import Path
from typing import Any

#: the template report.html's figures name (report_html._layout)
WHITE_NAME = "plotly_white"
#: what ``_layout`` names instead: a marker that :func:`finish_template` replaces by the JSON
#: of :data:`WHITE_NAME`
WHITE: dict[str, Any] = {"layout": {"meta": "flexopt:" + WHITE_NAME}}


def _templates_folder() -> Path | None:
    """plotly's folder of template files, found without importing plotly; None if absent."""
    spec = importlib.util.find_spec("plotly")
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(next(iter(spec.submodule_search_locations))) / "package_data" / "templates"


@functools.lru_cache(maxsize=8)
def _json_text(name: str) -> str:
    """The JSON text of plotly's template ``name``: its file, or (a template registered by a
    program, no file) what plotly writes for a figure naming it."""
    folder = _templates_folder()
    path = folder / f"{name}.json" if folder is not None and name.isidentifier() else None
    if path is not None and path.is_file():
        return json.dumps(json.loads(path.read_text(encoding="utf-8")))
    return json.dumps(_template_json(name, from_plotly=True))


def _template_json(template: Any, from_plotly: bool = False) -> dict[str, Any] | None:
    """The JSON a figure with ``template`` (a registered name or a Template) carries, or None;
    ``from_plotly``: made by plotly's classes even for a name with a file."""
    if template is None:
        return None
    if isinstance(template, str) and not from_plotly:
        return json.loads(_json_text(template))  # a fresh copy: the caller may edit it
    import plotly.graph_objects as go

    fig = go.Figure(layout={"template": template})
    return json.loads(fig.to_json())["layout"].get("template")


def default_template() -> Any:
    """plotly's default template for a new figure: ``plotly.io.templates.default`` where a
    program has imported plotly.io (and may have set it), else plotly's own default."""
    pio = sys.modules.get("plotly.io")
    templates = getattr(pio, "templates", None)
    return templates.default if templates is not None else "plotly"


def finish_template(spec: dict[str, Any]) -> None:
    """Put the template into a figure's JSON (``{"data", "layout"}``), in place: the
    "plotly_white" one where the figure names :data:`WHITE`, plotly's default
    (:func:`default_template`) where it names none."""
    layout = spec.get("layout") or {}
    template = layout.get("template")
    if template == WHITE:
        full = _template_json(WHITE_NAME)
    elif template is None:
        full = _template_json(default_template())
    else:
        return
    rest = {k: v for k, v in layout.items() if k != "template"}
    # the first key, where plotly writes a template it applies at creation
    spec["layout"] = {"template": full, **rest} if full is not None else rest


def warm_up() -> None:
    """Load what report.html's figures first need, ahead of the report (a run's preload
    thread, while the workers solve): the module that reads plotly.js and the templates' JSON.
    Nothing here changes a figure; a failure is the caller's to log."""
    from plotly.offline import get_plotlyjs  # noqa: F401  (the module; the text is read later)

    _json_text(WHITE_NAME)
    default = default_template()
    if isinstance(default, str):
        _json_text(default)
