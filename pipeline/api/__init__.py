"""flexopt: shape optimisation of compliant mechanisms, driven by nonlinear finite elements.

The public Python API (docs/api.md)::

    import flexopt

    study = flexopt.load_study("cantilever")            # a built-in study, a file or a dict
    study = study.with_values({"geometry.width_mm": 6.0})  # a new, validated study
    result = flexopt.evaluate(study)                      # .table, .summary, .verdict, .plot()
    run = flexopt.run("constant-force", quick=True)       # .best, .front, .evaluations, .run_dir

The repository keeps its four layers at top level (``geometry/``, ``fea/``, ``optimise/``,
``pipeline/``); the wheel installs them as ``flexopt.geometry``, ``flexopt.fea``,
``flexopt.optimise`` and ``flexopt.pipeline`` (``pyproject.toml``'s ``package-dir``), and this
package from ``pipeline/api/``. Names are imported on first use, so ``import flexopt`` stays
quick (the solvers, pydantic and pymoo load when a study is first loaded or run).
"""

from __future__ import annotations

import importlib
import logging
from importlib import metadata
from typing import TYPE_CHECKING, Any

try:
    __version__ = metadata.version("flexopt")
except metadata.PackageNotFoundError:  # pragma: no cover - running from an unpacked tree
    __version__ = "0+unknown"

# A library logs, it does not print: without this, Python's last-resort handler would print
# flexopt's warnings to stderr in every notebook (a program that wants them adds a handler).
logging.getLogger(__name__).addHandler(logging.NullHandler())

#: Public name -> the module that defines it (imported on first access).
_LAZY = {
    "load_study": "flexopt._api",
    "evaluate": "flexopt._api",
    "run": "flexopt._api",
    "open_run": "flexopt._api",
    "list_studies": "flexopt._api",
    "list_kinds": "flexopt._api",
    "StudyInfo": "flexopt._api",
    "KindInfo": "flexopt._api",
    "Result": "flexopt._result",
    "RunResult": "flexopt._result",
    "BestDesign": "flexopt._result",
    "Study": "flexopt.pipeline.study",
    "StudyError": "flexopt.pipeline.errors",
    "FlexoptError": "flexopt.pipeline.errors",
    "Verdict": "flexopt.optimise.requirements",
}

__all__ = [
    "__version__",
    "load_study",
    "evaluate",
    "run",
    "open_run",
    "list_studies",
    "list_kinds",
    "StudyInfo",
    "KindInfo",
    "Result",
    "RunResult",
    "BestDesign",
    "Study",
    "StudyError",
    "FlexoptError",
    "Verdict",
]

if TYPE_CHECKING:  # for editors and type checkers; at run time __getattr__ imports on use
    from flexopt._api import (
        KindInfo,
        StudyInfo,
        evaluate,
        list_kinds,
        list_studies,
        load_study,
        open_run,
        run,
    )
    from flexopt._result import BestDesign, Result, RunResult
    from flexopt.optimise.requirements import Verdict
    from flexopt.pipeline.errors import FlexoptError, StudyError
    from flexopt.pipeline.study import Study


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'flexopt' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # once: later lookups do not come here
    return value


def __dir__() -> list[str]:
    return sorted({*__all__, "__doc__", "__file__", "__name__", "__path__", "__spec__"})
