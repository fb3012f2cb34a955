"""Registry of study kinds, keyed by the YAML ``geometry.kind``.

A kind is one module in this package that calls :func:`register` with a :class:`StudyKind`: the
pydantic model of its whole study, a ``check`` that builds the geometry and material once, and an
``evaluate`` that solves one design. The CLI and the runner know only this registry, so a new kind
is a new module here and touches no other file (modules are discovered on first use; names
starting with ``_`` are skipped so they can hold shared helpers).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optimise.problem import DesignProblem
from optimise.requirements import Requirement, Verdict
from pipeline.errors import StudyError
from pipeline.study import Study

__all__ = ["EvaluationResult", "StudyKind", "get_kind", "kinds", "register"]


@dataclass(frozen=True)
class EvaluationResult:
    """What one evaluation of a study returns; the pipeline turns it into a run folder.

    Attributes
    ----------
    table : dict of str to (n_rows,) array
        Response columns in output order; names carry units (``force_N``).
    summary : dict
        Scalar metrics (names carry units); ``None`` where a metric is undefined.
    converged : bool
        Every row converged.
    message : str
        Why not, when not converged.
    solve_times_s : tuple of float, s
        Wall time of building the model and solving, one per repeat.
    inputs : dict
        Resolved inputs beyond the study itself (material record, settings, derived geometry).
    diagnostics : dict
        What the solver reports about itself (element and DOF counts, sub-steps, ...).
    plot : dict
        Names of the columns to plot: ``x``, ``left``, ``right`` and the ``allowable_MPa`` line;
        optional words: ``left_title``, ``right_title``, ``x_label``, ``left_label``,
        ``right_label``, ``allowable_label`` (see :func:`pipeline.plots.plot_response`).
    headline : tuple of str
        The summary keys worth a line in the CLI's table (all of them when empty).
    files : dict of str to bytes
        Files of the kind beyond the standard ones (``sweeps.png``, a resolved study), by plain
        file name; ``flexopt evaluate`` writes them into the run folder, atomically.
    verdicts : tuple of optimise.requirements.Verdict
        The kind's own verdicts when it judges itself; empty (the default) lets
        ``flexopt evaluate`` judge ``summary`` and ``table`` against the study's requirements
        (:func:`pipeline.verdict.judge`), which is what every shipped kind does.
    """

    table: dict[str, np.ndarray]
    summary: dict[str, Any]
    converged: bool
    message: str
    solve_times_s: tuple[float, ...]
    inputs: dict[str, Any] = field(default_factory=dict)
    diagnostics: dict[str, Any] = field(default_factory=dict)
    plot: dict[str, Any] = field(default_factory=dict)
    headline: tuple[str, ...] = ()
    files: dict[str, bytes] = field(default_factory=dict)
    verdicts: tuple[Verdict, ...] = ()


@dataclass(frozen=True)
class StudyKind:
    """One study kind.

    Attributes
    ----------
    name : str
        The YAML ``geometry.kind``.
    model : type of Study
        The pydantic model of the whole study file.
    check : callable(study) -> None
        Builds geometry and material once; raises :class:`StudyError` naming the key path.
    evaluate : callable(study, repeat) -> EvaluationResult
        Solves the study ``repeat`` times (for timing) and summarises the last solve.
    problem : callable(study) -> optimise.DesignProblem, optional
        For kinds that ``flexopt run`` optimises: the picklable problem built once from the study
        (its ``optimiser:`` block is an :class:`pipeline.study.OptimiserSpec` at
        ``study.optimiser``).
    requirements : callable(study) -> sequence of optimise.requirements.Requirement, optional
        The kind's BUILT-IN requirements: what its study already constrains or targets (an
        allowable stress, a force band, a stiffness window, stability), judged MET / NOT MET
        in every verdict before the study's own ``requirements:``.
    quantities : tuple of str or callable(study) -> iterable of str, optional
        The names a ``requirements:`` item may judge: summary / metrics keys and response
        columns (units in the names). The built-in requirements' names are always included.
    """

    name: str
    model: type[Study]
    check: Callable[[Study], None]
    evaluate: Callable[[Study, int], EvaluationResult] | None = None
    problem: Callable[[Study], DesignProblem] | None = None
    requirements: Callable[[Study], Sequence[Requirement]] | None = None
    quantities: tuple[str, ...] | Callable[[Study], Iterable[str]] | None = None


_KINDS: dict[str, StudyKind] = {}
_discovered = False


def register(kind: StudyKind) -> StudyKind:
    """Add a kind to the registry (called by each kind module at import)."""
    if kind.name in _KINDS and _KINDS[kind.name] is not kind:
        raise ValueError(f"study kind '{kind.name}' registered twice")
    _KINDS[kind.name] = kind
    return kind


def _discover() -> None:
    global _discovered
    if not _discovered:
        for info in pkgutil.iter_modules(__path__):
            if not info.name.startswith("_"):
                importlib.import_module(f"{__name__}.{info.name}")
        _discovered = True


def kinds() -> dict[str, StudyKind]:
    """All registered kinds by name."""
    _discover()
    return dict(_KINDS)


def get_kind(name: Any) -> StudyKind:
    """The kind registered under ``name``.

    Raises
    ------
    StudyError
        At ``geometry.kind`` when the name is missing or unknown.
    """
    available = ", ".join(sorted(kinds()))
    if name is None:
        raise StudyError("geometry.kind", f"required key is missing; add kind: one of {available}")
    if not isinstance(name, str) or name not in _KINDS:
        raise StudyError("geometry.kind", f"unknown kind {name!r}; use one of {available}")
    return _KINDS[name]
