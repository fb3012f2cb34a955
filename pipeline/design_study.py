"""A design of a run as a study: the run's study with the design's values written into it.

``flexopt export RUN --format yaml`` and :meth:`flexopt.RunResult.best_study` write the study that
``flexopt evaluate`` solves as the run's design, so a best design can be evaluated, changed
(``with_values``) and run again without copying numbers from best.json by hand.

Where a kind keeps the design it evaluates (the inverse of
:func:`pipeline.problems.nominal_design`):

- design variables on key paths (``variables:``, the ``mechanism`` kind): each variable's
  ``initial`` is set to the design's value (``flexopt evaluate`` solves the initial design), and
  the keys it sets (its path and ties) to their values, so the geometry reads as the design;
- a ``design:`` block (``constant_force``, ``sea_spring``, ``threshold_spring``,
  ``flexure_pivot``): the design's values by variable name (``flexure_pivot``'s ``type_index``
  as the ``type`` it picks from ``geometry.candidates``);
- otherwise a key of the variable's name found once in the study (``gripper``, ``cam``,
  ``leaf_spring_joint``): set there;
- a problem with a ``study_values(x)`` method (a plugin kind) gives ``{key path: value}`` itself;
- a kind whose problem optimises another kind's study (``gripper``: the constant_force study it
  resolves, with the gripper's force, stroke and material) writes that study.

Every study written is read back and its design compared with the run's (the kind's
``nominal_design`` of the new study must be the design, to 1e-9): a kind that does not keep a
variable in its study is refused (:class:`~pipeline.problems.ExportError`) rather than written
wrong.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

import numpy as np
from flexopt.optimise.problem import DesignProblem, as_design_problem
from flexopt.optimise.variables import (
    VariableError,
    VariableSpec,
    format_path,
    resolve_variables,
)
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.problems import ExportError, nominal_design
from flexopt.pipeline.study import Study, validate_study
from flexopt.pipeline.study_edit import study_data

__all__ = ["design_study", "design_values"]

#: A unit (or ``fraction``) suffix that a ``design:`` block may leave out of a variable's name
#: (constant_force: ``t1`` for ``t1_mm``; sea_spring: ``F1`` for ``F1_fraction``).
_BARE = re.compile(r"_(mm|deg|rad|N|Nm|Nmm|MPa|fraction)$")

#: A variable that picks one of a list (floored to an index): equal when the pick is the same.
_CATEGORICAL = ("type_index",)


def _found_once(data: Any, names: set[str]) -> dict[str, list[str]]:
    """Key paths of every key named in ``names`` anywhere in plain study data."""
    found: dict[str, list[str]] = {}

    def walk(node: Any, where: tuple[str | int, ...]) -> None:
        if isinstance(node, Mapping):
            for key, value in node.items():
                here = (*where, str(key))
                if key in names and isinstance(value, int | float) and not isinstance(value, bool):
                    found.setdefault(str(key), []).append(format_path(here))
                walk(value, here)

    walk({k: v for k, v in data.items() if k != "design"}, ())
    return found


def design_values(study: Study, problem: DesignProblem, x: np.ndarray) -> dict[str, Any]:
    """``{key path: value}`` that make ``study`` describe the design ``x`` (n_var,).

    Raises
    ------
    ExportError
        When the kind keeps no place in its study for a variable.
    """
    names = tuple(problem.space.names)
    values = {name: float(v) for name, v in zip(names, np.asarray(x, float).ravel(), strict=True)}
    own = as_design_problem(problem).study_values(np.asarray(x, dtype=float))
    if own is not None:
        return dict(own)
    specs = getattr(study, "variables", None)
    if specs and all(isinstance(s, VariableSpec) for s in specs):
        return {f"variables[{i}].initial": values[n] for i, n in enumerate(names)}
    if "design" in type(study).model_fields:
        design = getattr(study, "design", None)
        kept = dict(design) if isinstance(design, Mapping) else {}
        if "type_index" in values:  # flexure_pivot: the type is the candidate it floors to
            candidates = list(getattr(study.geometry, "candidates", ()))
            if not candidates:
                raise ExportError(f"kind '{study.kind}': type_index with no geometry.candidates")
            pick = min(max(int(math.floor(values.pop("type_index"))), 0), len(candidates) - 1)
            kept["type"] = candidates[pick]
        return {"design": {**kept, **values}}  # (retried without unit suffixes, see below)
    found = _found_once(study_data(study), set(names))
    unclear = [n for n in names if len(found.get(n, ())) != 1]
    if unclear:
        raise ExportError(
            f"kind '{study.kind}' keeps no single key for {', '.join(unclear[:3])} in its study, "
            "so the design cannot be written as a study; export it as STL, DXF or STEP"
        )
    return {found[n][0]: values[n] for n in names}


def _same(name: str, a: float, b: float) -> bool:
    if name in _CATEGORICAL:
        return math.floor(a) == math.floor(b)
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)


def design_study(
    study: Study, problem: DesignProblem, x: np.ndarray, name: str | None = None
) -> Study:
    """``study`` describing the design ``x`` (n_var,) of ``problem``: what ``flexopt evaluate``
    of the result solves is ``x`` (checked).

    Parameters
    ----------
    name : str, optional
        The new study's name (default: the study's).

    Raises
    ------
    ExportError
        When the kind keeps no place for a variable, or the study written back does not give
        the design (naming the variable and both values).
    """
    x = np.asarray(x, dtype=float).ravel()
    problem = as_design_problem(problem)
    inner = problem.study
    if isinstance(inner, Study) and inner.kind != study.kind:
        # a kind that optimises another kind's study (gripper: its resolved constant_force
        # study): the design lives in that study, which is what the run optimised
        study = inner
    specs = getattr(study, "variables", None)
    if (
        specs
        and all(isinstance(s, VariableSpec) for s in specs)
        and problem.study_values(x) is None
    ):
        return _checked(study, problem, x, _with_variables(study, x), name)
    changes = design_values(study, problem, x)
    design = changes.get("design")
    if isinstance(design, dict) and len(changes) == 1:
        # a design: block may name the variables without their unit (_BARE); try that when
        # the names as they are are refused
        bare = {_BARE.sub("", k): v for k, v in design.items()}
        if bare != design:  # (a kept bare key is overwritten by the design's value: later)
            try:
                study.with_values(changes)
            except StudyError as exc:
                if exc.path.startswith("design"):
                    changes = {"design": bare}
    try:
        new = study.with_values(changes)
    except StudyError as exc:
        raise ExportError(f"the design does not make a valid {study.kind} study: {exc}") from exc
    return _checked(study, problem, x, new, name)


def _with_variables(study: Study, x: np.ndarray) -> Study:
    """``study`` with every variable's ``initial`` at ``x`` and the keys the variables set
    (paths and ties) at their values too, so the geometry reads as the design it is.

    Raises
    ------
    ExportError
        When the result is not a valid study.
    """
    data = study_data(study)
    try:
        resolved = resolve_variables(study.variables, data)  # type: ignore[attr-defined]
        data = resolved.apply(data, x)
    except (VariableError, ValueError) as exc:
        raise ExportError(f"the design does not fit the study's variables: {exc}") from exc
    for item, value in zip(data["variables"], x, strict=True):
        item["initial"] = float(value)
    try:
        return validate_study(data)
    except StudyError as exc:
        raise ExportError(f"the design does not make a valid {study.kind} study: {exc}") from exc


def _checked(
    study: Study, problem: DesignProblem, x: np.ndarray, new: Study, name: str | None
) -> Study:
    """``new`` once its design (the kind's own reading of it) is ``x``; renamed to ``name``."""
    from flexopt.pipeline.problems import build_base_problem

    try:
        if name is not None and name != new.name:
            new = new.replace(name=name)
        again = nominal_design(build_base_problem(new), new)
    except StudyError as exc:
        raise ExportError(f"the design does not make a valid {study.kind} study: {exc}") from exc
    names = problem.space.names
    if again.shape != x.shape:
        raise ExportError(f"kind '{study.kind}': the written study has {again.size} variables")
    for n, a, b in zip(names, x, again, strict=True):
        if not _same(n, float(a), float(b)):
            raise ExportError(
                f"kind '{study.kind}' does not keep {n} in its study (the design has {a:.10g}, "
                f"the written study gives {b:.10g}); export it as STL, DXF or STEP"
            )
    return new
