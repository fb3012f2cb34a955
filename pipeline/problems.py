"""Setting up a study's design problem and its evaluation: the kind's problem, the parallel
settings, the design a study file describes.

Below :mod:`pipeline.run`, so that what else needs a study's problem (the robustness samples,
the HTML report of an evaluate folder, the API) does not import the runner.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.problem import DesignProblem, DesignResult, as_design_problem
from flexopt.optimise.space import DesignSpace
from flexopt.pipeline.errors import FlexoptError, StudyError
from flexopt.pipeline.materials_file import thickness_offset_mm
from flexopt.pipeline.parallel import ParallelSettings
from flexopt.pipeline.studies import get_kind, kinds
from flexopt.pipeline.study import ParallelSpec, Study

__all__ = [
    "ExportError",
    "build_base_problem",
    "can_evaluate",
    "kind_problem",
    "nominal_design",
    "parallel_settings",
    "study_result",
]


class ExportError(FlexoptError, RuntimeError):
    """A design could not be rebuilt or turned into a solid (the message says why)."""


def _optimisable() -> str:
    names = sorted(name for name, kind in kinds().items() if kind.problem is not None)
    return ", ".join(names) if names else "(none yet)"


def build_base_problem(study: Study) -> DesignProblem:
    """The kind's design problem for ``study``, with the study's ``role: constraint``
    requirements as g rows (what each scatter sample of ``robustness:`` solves).

    Raises
    ------
    StudyError
        When the kind cannot be optimised, or refuses the study while building the problem.
    """
    from flexopt.pipeline.verdict import with_requirement_constraints

    return with_requirement_constraints(study, kind_problem(study))


def kind_problem(study: Study) -> DesignProblem:
    """The kind's design problem for ``study`` as the kind builds it (a plugin's protocol-only
    problem adapted, :func:`optimise.problem.as_design_problem`).

    Raises
    ------
    StudyError
        When the kind cannot be optimised, or refuses the study while building the problem.
    """
    kind = get_kind(study.kind)
    if kind.problem is not None and thickness_offset_mm(study):
        from flexopt.pipeline.as_printed import as_printed_problem  # the part as made (#26)

        return as_printed_problem(study, kind_problem)
    if kind.problem is None:
        raise StudyError(
            "geometry.kind",
            f"kind '{kind.name}' has nothing to optimise; solve it with `flexopt evaluate`, or "
            f"use a kind that `flexopt run` optimises: {_optimisable()}",
        )
    try:
        problem = kind.problem(study)
    except StudyError:
        raise
    except (ValueError, OptimiseError) as exc:  # geometry/fea/optimise refusals are ValueErrors
        raise StudyError(
            "", f"the design problem cannot be set up: {type(exc).__name__}: {exc}"
        ) from exc
    try:  # a plugin's problem with only the protocol's parts takes the hooks' defaults
        problem = as_design_problem(problem)
    except TypeError:
        raise TypeError(
            f"kind '{kind.name}' returned {type(problem).__name__}, which is not a DesignProblem "
            "(space, objective_names, constraint_names, evaluate, detail)"
        ) from None
    if not isinstance(problem.space, DesignSpace):
        raise TypeError(f"kind '{kind.name}' returned a problem whose space is no DesignSpace")
    return problem


def can_evaluate(study_kind: Any) -> bool:
    """Whether ``flexopt evaluate`` can solve a study of this kind (a StudyKind): it has a
    ``evaluate(study)`` of its own or a design problem (:func:`study_result`)."""
    return study_kind.evaluate is not None or study_kind.problem is not None


def study_result(study: Study, repeat: int = 1, source: str = "") -> DesignResult:
    """The result of the design ``study`` describes, solved ``repeat`` times: what
    ``flexopt evaluate``, the API and a robustness sample of a study show. Nothing is judged
    (:func:`pipeline.verdict.judge_result`) and nothing written.

    One path for every kind with a design problem: the nominal design's result from the kind's
    problem (:func:`nominal_design`, :meth:`optimise.problem.DesignProblem.result`, which a
    kind overrides where its answer for a design is more than its detail: the leaf-spring
    joint's analysis of every structure and length, the gripper's requirement). A kind without
    a design problem (``collision``, ``sea_window``, ``polyline_beam``, a plugin's) has
    ``StudyKind.evaluate(study, repeat)`` instead, the one hook for a study's result without a
    problem; no built-in kind has both (tests/test_layering.py).

    ``source``: where the study came from, named in the hint of a refusal.

    Raises
    ------
    StudyError
        When the kind has neither or its study names no design (it is only optimised), or the
        kind refuses the study.
    """
    kind = get_kind(study.kind)
    if kind.evaluate is not None:
        if thickness_offset_mm(study):
            from flexopt.pipeline.as_printed import as_printed_evaluate  # the part as made (#26)

            return as_printed_evaluate(study, kind.evaluate, repeat)
        return kind.evaluate(study, repeat)
    problem = kind_problem(study) if kind.problem is not None else None
    try:
        if problem is None:
            raise ExportError("it has no design problem")
        x = nominal_design(problem, study)
    except ExportError as exc:
        raise StudyError(
            "geometry.kind",
            f"kind '{kind.name}' is only optimised, not evaluated on its own ({exc}); "
            f"run it with `flexopt run {source or 'STUDY'}`",
            source=source or None,
        ) from None
    return problem.result(x, repeat)


def parallel_settings(
    study: Study,
    workers: int | None = None,
    dask: str | None = None,
    eval_timeout_s: float | None = None,
) -> ParallelSettings:
    """The study's ``parallel:`` block with the command line's options applied.

    ``workers`` 1 means serial in this process; ``dask`` selects the Dask backend at that address.

    Raises
    ------
    StudyError
        When the Dask backend is asked for without a scheduler address.
    """
    spec = getattr(study, "parallel", None) or ParallelSpec()
    backend, address = spec.backend, spec.address
    n_workers = workers if workers is not None else spec.workers
    if dask is not None:
        backend, address = "dask", dask
    elif workers is not None:
        backend = "serial" if workers == 1 else "processes"
    elif backend == "processes" and n_workers == 1:
        backend = "serial"
    if backend == "dask" and not address:
        raise StudyError(
            "parallel.address",
            "backend dask needs the scheduler's address; add address: tcp://host:8786 or give "
            "--dask tcp://host:8786",
        )
    timeout = eval_timeout_s if eval_timeout_s is not None else spec.eval_timeout_s
    return ParallelSettings(backend, n_workers, address, timeout, spec.chunk_size)


def nominal_design(problem: DesignProblem, study: Study) -> np.ndarray:
    """The design a study file describes, the one ``flexopt evaluate`` solves.

    The problem's :meth:`~optimise.problem.DesignProblem.nominal_design` when it gives one;
    else each design variable read from the study by its name (the ``design:`` block first,
    then a key of that name found once anywhere in the study).

    Raises
    ------
    ExportError
        When neither says what the design is.
    """
    problem = as_design_problem(problem)
    names = problem.space.names
    own = problem.nominal_design()
    if own is not None:
        x = np.asarray(own, dtype=float).ravel()
        if x.shape != (len(names),) or not np.all(np.isfinite(x)):
            raise ExportError(
                f"kind '{study.kind}': nominal_design() gave shape {x.shape}, expected "
                f"({len(names)},) finite values"
            )
        return x
    data = study.model_dump(mode="python")
    found: dict[str, list[float]] = {}

    def walk(node: Any) -> None:
        if isinstance(node, Mapping):
            for key, value in node.items():
                if key in names and isinstance(value, int | float) and not isinstance(value, bool):
                    found.setdefault(key, []).append(float(value))
                walk(value)

    design = data.get("design")
    walk({k: v for k, v in data.items() if k != "design"})
    if isinstance(design, Mapping):  # the design: block wins
        for key, value in design.items():
            if key in names and isinstance(value, int | float) and not isinstance(value, bool):
                found[key] = [float(value)]
    unclear = [n for n in names if len(found.get(n, ())) != 1]
    if unclear:
        shown = ", ".join(unclear[:3]) + (" …" if len(unclear) > 3 else "")
        raise ExportError(
            f"kind '{study.kind}' does not say which design its study.yaml describes (no "
            f"nominal_design(), and {shown} are not keys found once in the study); export a "
            "design of a flexopt run of this study instead"
        )
    return np.array([found[n][0] for n in names], dtype=float)
