"""Design spaces, evaluations, optimisers (pymoo GA / NSGA-II by ask-and-tell), Taguchi arrays
and target curves.

Public names are re-exported lazily (PEP 562): ``from optimise import run_ga`` works, and
importing the package does not import the heavy libraries behind modules you do not use.
"""

from importlib import import_module
from typing import Any

_EXPORTS = {
    "OptimiseError": "errors",
    "INFEASIBLE_VALUE": "evaluation",
    "Evaluation": "evaluation",
    "GAConfig": "ga",
    "GAResult": "ga",
    "Generation": "ga",
    "best_of": "ga",
    "run_ga": "ga",
    "DesignDetail": "problem",
    "DesignProblem": "problem",
    "DesignResult": "problem",
    "as_design_problem": "problem",
    "DesignSpace": "space",
    "analyse": "taguchi",
    "get_array": "taguchi",
    "is_orthogonal": "taguchi",
    "orthogonal_array": "taguchi",
    "sn_ratio": "taguchi",
    "TargetSpec": "targets",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
