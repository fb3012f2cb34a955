"""The verdict of a study: its requirements (built into the kind and stated in ``requirements:``)
judged on one design, for ``flexopt evaluate`` and ``flexopt run`` alike.

A kind states two things in its :class:`~pipeline.studies.StudyKind`:

``requirements(study) -> sequence of Requirement``
    What its study already constrains or targets (the allowable stress, the force band, the
    stiffness window, stability ...), judged on every evaluation.
``figures`` (optional)
    ``{quantity: (Figure, ...)}`` (or a callable ``(study) -> mapping``): the figures of a
    quantity by model and fidelity rank (:class:`~optimise.requirements.Figure`: the beam's
    peak stress, the plane-stress check's, the 3D solid's). Every requirement on the quantity
    is judged on the highest-ranked figure the design has, the others shown beside it
    (:func:`~optimise.requirements.judge_best`); a figure a built-in requirement judges on its
    own row (the springs' 3D rows) is not borrowed by another.
``design_space`` (optional)
    ``(study) -> (DesignSpace, x or None)``: the space the kind's problem moves in and the
    design ``flexopt evaluate`` solves. Every verdict of a design then has the row "design
    variables in their ranges" (:class:`~optimise.requirements.DesignRange`): a design
    outside the range the study states is NOT MET with the variable, its value and its range
    (:func:`design_range_verdicts`). It judges the design as chosen (the study's, or the one
    ``flexopt run`` found), so :func:`judge` adds it only when it judges the study's own
    requirements (``requirements=None``): a robustness sample, judged on the requirements it
    is given, is a part as made (a thickness 0.1 mm under a bound), not a design choice.
``quantities``
    The names a requirement may judge (summary and metrics keys, response-table columns), or a
    callable ``(study) -> iterable of str``. An unknown name in ``requirements:`` is refused at
    load time with this list.

:func:`judge_result` is the one place a design is judged: one
:class:`~optimise.problem.DesignResult` (``flexopt evaluate``'s, the API's, a run's best
design's, a robustness sample's) against the study's requirements, through :func:`judge`, which
turns scalar values and a response table into verdicts. A requirement added for every kind is
added to :func:`builtin_requirements` / ``requirements:`` and judged here once.
:class:`RequirementConstraints` adds the
``role: constraint`` items of ``requirements:`` to a kind's :class:`~optimise.DesignProblem` as
``g <= 0`` rows; :class:`LifeConstraints` those on the fatigue life, each computed per design:
from the response table of the same solve where the kind's problem has ``evaluate_response``
(sea_spring), else, in every other kind, from the design's :meth:`~optimise.DesignProblem.detail`
on the best stress figure it has (:func:`life_of_result`, what the verdict judges).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from flexopt.optimise.durability import (
    LIFE_QUANTITIES,
    STRESS_SETTINGS,
    LifeResult,
    life_constraint,
    life_of_table,
)
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.hold import HoldResult, creep_law_of, hold_of_table, hold_quantities
from flexopt.optimise.problem import (
    DesignDetail,
    DesignResult,
    ProblemWrapper,
    as_design_problem,
)
from flexopt.optimise.requirements import (
    DesignRange,
    Figure,
    Requirement,
    RequirementSpec,
    Verdict,
    curves_from_table,
    judge_best,
)
from flexopt.optimise.robust_requirements import RobustShareSpec
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.stroke_verdict import UNBOUNDED_LIFE, UNBOUNDED_STRESS

if TYPE_CHECKING:  # annotations only: study.validate_study calls check_requirement_names
    from flexopt.pipeline.study import Study

__all__ = [
    "GENERIC_QUANTITIES",
    "HoldDetail",
    "LifeConstraints",
    "LifeDetail",
    "RequirementConstraints",
    "builtin_requirements",
    "check_requirement_names",
    "design_range",
    "design_range_verdicts",
    "detail_values",
    "envelope_values",
    "figures_of",
    "judge",
    "judge_detail",
    "judge_result",
    "hold_of_result",
    "life_of_result",
    "life_values",
    "quantities_of",
    "result_values",
    "robust_items",
    "study_requirements",
    "user_requirements",
    "with_design_range",
    "with_hold",
    "with_life",
]

#: Names every kind offers (measured by the pipeline on the part as exported, when there is
#: one: its bounding box in the design frame, mm; depth is the extrusion, out of plane).
GENERIC_QUANTITIES = ("envelope_width_mm", "envelope_height_mm", "envelope_depth_mm")


def envelope_values(outline: Any, depth_mm: float | None = None) -> dict[str, float]:
    """The bounding box of a part as exported, in the design frame, mm.

    Parameters
    ----------
    outline : a shapely geometry (the printable outline), or None.
    depth_mm : its extrusion (out-of-plane size), mm, or None.

    Returns
    -------
    dict
        ``envelope_width_mm`` (x), ``envelope_height_mm`` (y) and, with a depth,
        ``envelope_depth_mm``; empty when there is no outline to measure.
    """
    out: dict[str, float] = {}
    try:
        x0, y0, x1, y1 = outline.bounds
    except (AttributeError, ValueError, TypeError):
        return out
    if not all(map(math.isfinite, (x0, y0, x1, y1))):
        return out
    out["envelope_width_mm"] = float(x1 - x0)
    out["envelope_height_mm"] = float(y1 - y0)
    if depth_mm is not None and math.isfinite(float(depth_mm)) and float(depth_mm) > 0:
        out["envelope_depth_mm"] = float(depth_mm)
    return out


def _kind(study: Study) -> Any:
    from flexopt.pipeline.studies import get_kind  # the registry imports this module's users

    return get_kind(study.kind)


def builtin_requirements(study: Study) -> tuple[Requirement, ...]:
    """What the kind of ``study`` always requires (empty when the kind states nothing)."""
    make = getattr(_kind(study), "requirements", None)
    return tuple(make(study)) if make is not None else ()


def user_requirements(study: Study) -> tuple[Requirement, ...]:
    """The ``requirements:`` block of ``study`` as requirements.

    Raises
    ------
    StudyError
        At ``requirements[i]...`` when a target table cannot be read or a curve refuses it.
    """
    specs: Sequence[RequirementSpec] = getattr(study, "requirements", None) or ()
    out = []
    for i, spec in enumerate(specs):
        key = f"requirements[{i}]"
        table = columns = None
        if spec.target is not None and spec.target.kind == "table" and spec.target.file:
            from flexopt.pipeline.targets import read_table_csv

            table, columns = read_table_csv(
                spec.target.file, spec.target.columns, f"{key}.target.file"
            )
        try:
            out.append(spec.to_requirement(study.material.yield_MPa, table, columns))
        except OptimiseError as exc:
            raise StudyError(key, str(exc)) from None
    return tuple(out)


def robust_items(study: Study) -> tuple[tuple[Requirement, RobustShareSpec], ...]:
    """The ``requirements:`` items with ``robust:``, as ``(requirement, robust spec)`` pairs in
    the order of the list (empty when there is none; docs/robustness.md)."""
    specs: Sequence[RequirementSpec] = getattr(study, "requirements", None) or ()
    if not any(spec.robust is not None for spec in specs):
        return ()
    reqs = user_requirements(study)
    return tuple(
        (req, spec.robust) for req, spec in zip(reqs, specs, strict=True) if spec.robust is not None
    )


def check_robust_item(study: Study, i: int, spec: RequirementSpec) -> None:
    """Refuse a ``robust:`` requirement the study cannot judge: no ``robustness:`` block (the
    scatter its share is of), or a constraint beside ``robustness.objective: worst`` (every
    sample held already; one of the two).

    Raises
    ------
    StudyError
        At ``requirements[i].robust``.
    """
    scatter = getattr(study, "robustness", None)
    if scatter is None:
        raise StudyError(
            f"requirements[{i}].robust",
            "needs the study's robustness: block, the scatter its share is of (E_percent, "
            "thickness_mm, width_mm; docs/robustness.md)",
        )
    if spec.role == "constraint" and scatter.objective == "worst":
        raise StudyError(
            f"requirements[{i}].robust",
            "robustness.objective: worst already holds every sample; a robust constraint holds "
            "a share of them: use one (objective: nominal, or role: check)",
        )


def figures_of(study: Study) -> dict[str, tuple[Figure, ...]]:
    """``{quantity: figures}`` the kind of ``study`` reports (empty when it has one model)."""
    figures = getattr(_kind(study), "figures", None)
    if callable(figures):
        figures = figures(study)
    return {str(q): tuple(f) for q, f in (figures or {}).items()}


def study_requirements(study: Study) -> tuple[Requirement, ...]:
    """Built-in requirements of the kind, then the study's own, in that order."""
    return (*builtin_requirements(study), *user_requirements(study))


def quantities_of(study: Study) -> tuple[str, ...]:
    """Every name a requirement of ``study`` may judge, sorted (see the module docstring)."""
    kind = _kind(study)
    names = getattr(kind, "quantities", None)
    if callable(names):
        names = names(study)
    found = set(names or ())
    for ladder in figures_of(study).values():
        found.update(f.quantity for f in ladder)
    for req in builtin_requirements(study):
        found.add(req.quantity)
        if hasattr(req, "x"):
            found.add(req.x)
    found.discard("envelope_mm")
    if getattr(study, "duty_cycle", None) is not None:
        found.update(LIFE_QUANTITIES)
    if getattr(study, "hold", None) is not None:
        found.update(hold_quantities(found))
    return tuple(sorted(found | set(GENERIC_QUANTITIES)))


def check_requirement_names(study: Study) -> None:
    """Refuse a ``requirements:`` item that judges a name the kind does not report.

    Raises
    ------
    StudyError
        At ``requirements[i].quantity`` (or ``.x``), listing the names the kind reports.
    """
    check_duty_cycle_settings(study)
    specs: Sequence[RequirementSpec] = getattr(study, "requirements", None) or ()
    if not specs:
        return
    valid = set(quantities_of(study))
    for i, spec in enumerate(specs):
        for key in ("quantity", "x"):
            name = getattr(spec, key)
            if name is not None and name not in valid:
                import difflib

                close = difflib.get_close_matches(name, sorted(valid), n=1)
                hint = f"did you mean '{close[0]}'? " if close else ""
                raise StudyError(
                    f"requirements[{i}].{key}",
                    f"kind {study.kind} reports no '{name}'; {hint}use one of "
                    + ", ".join(sorted(valid)),
                )
        if spec.quantity == "life_hours" and getattr(study, "duty_cycle", None) is not None:
            if study.duty_cycle.rate_hz is None:  # type: ignore[attr-defined]
                raise StudyError(
                    f"requirements[{i}].quantity",
                    "life_hours needs duty_cycle.rate_hz (cycles per second in service); give "
                    "it, or require life_cycles",
                )
        if spec.role == "constraint" and spec.quantity in _hold_names(study):
            raise StudyError(
                f"requirements[{i}].role",
                "cannot be a constraint: the held value is computed from the response table of "
                "the judged design; use role: check",
            )
        if spec.robust is not None:
            check_robust_item(study, i, spec)
        if spec.role == "constraint":
            why = ""
            if getattr(_kind(study), "problem", None) is None:
                why = f"kind {study.kind} is not optimised (flexopt evaluate only)"
            elif spec.target is not None or spec.envelope_mm is not None:
                why = "a target curve or an envelope is judged on the best design only"
            elif spec.quantity in LIFE_QUANTITIES:
                why = life_constraint_refusal(study)
            if why:
                raise StudyError(
                    f"requirements[{i}].role",
                    f"cannot be a constraint: {why}; use role: check",
                )
    user_requirements(study)  # a target table that cannot be read is refused here too


#: The method a kind's design problem may offer for a life constraint: ``evaluate_response(x)``
#: -> ``(Evaluation, table, x_column)``, the evaluation and the response table (each column
#: (n_rows,), the driven column ``x_column`` and ``peak_stress_MPa``) of the same solve, or
#: ``(Evaluation, None, "")`` when the design was not solved. A problem without it has its life
#: computed from its :meth:`~optimise.DesignProblem.detail` (:class:`LifeConstraints`).
RESPONSE_HOOK = "evaluate_response"
#: A design problem's attribute saying why its designs have no life ("" or absent: they have):
#: a kind whose response has no peak stress per row of a driven column (a cam's contact
#: pressure, a leaf joint's stress per stiffness setting) names it here and the life constraint
#: is refused at load time with that reason (:attr:`optimise.DesignProblem.life_refusal`).
LIFE_REFUSAL = "life_refusal"


#: A design problem's attribute naming the settings its response has a stress for (setting
#: -> stress column: a leaf joint's stiffness settings); a kind whose problem has none refuses a
#: duty cycle that names a setting (:func:`check_duty_cycle_settings`).
STRESS_SETTINGS_ATTR = "stress_settings"


def check_duty_cycle_settings(study: Study) -> None:
    """Refuse a ``duty_cycle:`` naming a ``setting`` in a kind with one stress per row (a kind
    with settings checks their names itself: pipeline/studies/_leaf_life.py).

    Raises
    ------
    StudyError
        At ``duty_cycle.setting`` or ``duty_cycle.levels[i].setting``.
    """
    spec = getattr(study, "duty_cycle", None)
    if spec is None or getattr(_problem_class(_kind(study)), STRESS_SETTINGS_ATTR, None):
        return
    named = [("duty_cycle.setting", spec.setting)]
    named += [
        (f"duty_cycle.levels[{i}].setting", lv.setting) for i, lv in enumerate(spec.levels or ())
    ]
    for path, name in named:
        if name is not None:
            raise StudyError(
                path, f"kind {study.kind} has one stress per row, no settings; leave setting out"
            )


def _problem_class(kind: Any) -> type | None:
    """The class a kind's ``problem(study)`` returns, from its annotation (None: unknown)."""
    import inspect
    import sys

    make = getattr(kind, "problem", None)
    if make is None:
        return None
    try:
        ann = inspect.signature(make).return_annotation
    except (TypeError, ValueError):
        return None
    if isinstance(ann, str):
        ann = vars(sys.modules.get(make.__module__, object())).get(ann)
    return ann if isinstance(ann, type) and ann is not Any else None


def life_constraint_refusal(study: Study, problem: Any = None) -> str:
    """Why a life requirement of ``study`` cannot be an optimisation constraint ("" when it
    can): the kind's design problem (``problem``, else the class its ``problem(study)``
    returns) says so in :data:`LIFE_REFUSAL` (its response has no peak stress per row of a
    driven column); a kind whose problem class cannot be known from its annotation is checked
    when the run builds it."""
    owner: Any = problem if problem is not None else _problem_class(_kind(study))
    why = str(getattr(owner, LIFE_REFUSAL, "") or "") if owner is not None else ""
    if not why:
        return ""
    return f"kind {study.kind} cannot give the life of every design: {why}"


def _scalars(*sources: Mapping[str, Any] | None) -> dict[str, Any]:
    """The scalar values of mappings (later ones win), numpy scalars as Python ones."""
    out: dict[str, Any] = {}
    for source in sources:
        for key, value in (source or {}).items():
            if isinstance(value, np.generic):
                value = value.item()
            if value is None or isinstance(value, bool | int | float):
                if value is None and key in out:
                    continue
                out[str(key)] = value
    return out


def design_range(study: Study) -> tuple[DesignRange, np.ndarray | None] | None:
    """The requirement "every design variable in its range" of ``study`` and the study's own
    design vector (None when it gives none), or None when the kind has no design space.

    Raises
    ------
    StudyError
        When the kind refuses the study's design space or design (naming the key).
    """
    hook = getattr(_kind(study), "design_space", None)
    got = hook(study) if callable(hook) else None
    if got is None:
        return None
    space, x = got[0], got[1]
    where = got[2] if len(got) > 2 else "design_space"
    req = DesignRange(
        name="design variables in their ranges", role="check", names=tuple(space.names),
        lower=tuple(space.lower), upper=tuple(space.upper), where=where,
    )  # fmt: skip
    return req, (None if x is None else np.asarray(x, dtype=float).ravel())


def design_range_verdicts(study: Study, x: Any = None) -> tuple[Verdict, ...]:
    """The verdict of "every design variable in its range" for the design ``x`` (n_var,) in
    the kind's design space (default: the study's own design); empty when the kind has no
    design space or the study no design to judge."""
    found = design_range(study)
    if found is None:
        return ()
    req, nominal = found
    design = nominal if x is None else x
    if design is None:
        return ()
    try:
        values = req.values(design)
    except OptimiseError as exc:  # a design of another space: NOT MET, said, never skipped
        return (req.missing(f"every variable in its range ({req.where})", str(exc)),)
    return (req.check(values),)


def with_design_range(
    study: Study, verdicts: Sequence[Verdict], design: Any = None
) -> tuple[Verdict, ...]:
    """``verdicts`` with the design-range row after the kind's built-in ones."""
    rows = design_range_verdicts(study, design)
    if not rows:
        return tuple(verdicts)
    n = len(builtin_requirements(study))
    return (*verdicts[:n], *rows, *verdicts[n:])


def judge(
    study: Study,
    values: Mapping[str, Any],
    table: Mapping[str, Any] | None = None,
    requirements: Sequence[Requirement] | None = None,
    design: Any = None,
) -> tuple[Verdict, ...]:
    """Verdicts of one design against the requirements of ``study`` (built-in, then its own).

    Parameters
    ----------
    values : scalar results by name (units in the names); non-scalars are ignored.
    table : response columns by name, each (n_rows,); feeds target bands.
    requirements : judge these instead of :func:`study_requirements` (and without the
        design-range row: a robustness sample is judged so, see the module docstring).
    design : (n_var,) the design vector judged, in the kind's design space (default: the
        study's own design, what ``flexopt evaluate`` solves): the design-range row's values.
    """
    if requirements is None:
        return with_design_range(
            study, judge(study, values, table, study_requirements(study)), design
        )
    reqs = tuple(requirements)
    scalars = _scalars(values)
    # a table column may also be judged by its worst value: max |column|
    for name, column in (table or {}).items():
        if name not in scalars:
            arr = np.asarray(column)
            if arr.dtype.kind == "b":
                scalars[name] = bool(np.all(arr)) if arr.size else None
            elif arr.dtype.kind in "fiu" and arr.size:
                finite = np.abs(arr[np.isfinite(arr)])
                scalars[name] = float(np.max(finite)) if finite.size else None
    ladders = figures_of(study)
    curves = curves_from_table(table or {}, reqs, ladders)
    # a figure a built-in row judges on its own (a spring's 3D rows) is not borrowed by another
    # row; a user's row naming a figure directly takes nothing from the built-in ones
    taken = {r.quantity for r in builtin_requirements(study)}
    return tuple(
        judge_best(req, scalars, curves, ladders.get(req.quantity, ()), taken) for req in reqs
    )


def result_values(result: DesignResult) -> dict[str, Any]:
    """Scalars of one design's result (as :meth:`~optimise.problem.DesignResult.values`: the
    detail's info, the evaluation's metrics, the summary; a later scalar wins, a later None or
    non-scalar does not hide an earlier value) and the outline's bounding box."""
    metrics = result.evaluation.metrics if result.evaluation is not None else None
    values = _scalars(result.info, metrics, result.summary)
    if result.outline is not None:
        values.update(envelope_values(result.outline, result.height_mm))
    return values


def judge_result(
    study: Study,
    result: DesignResult,
    design: Any = None,
    requirements: Sequence[Requirement] | None = None,
) -> tuple[Verdict, ...]:
    """Verdicts of one design's result: the one place a design is judged, for
    ``flexopt evaluate``, ``flexopt run``'s best design, the API and the robustness samples.

    The kind's own verdicts (``result.verdicts``) when it gives them, with the design-range
    row where they lack it; else :func:`judge` of :func:`result_values` and ``result.table``.

    Parameters
    ----------
    design : (n_var,) the design vector judged (default: the study's own design).
    requirements : judge these instead of the study's (a robustness sample: no design-range
        row, see the module docstring).
    """
    from flexopt.pipeline.materials_file import with_as_printed_verdicts  # says so (#26)
    from flexopt.pipeline.stroke_verdict import with_life_reason, with_stroke_row

    life = life_values(study, result)
    hold = hold_of_result(study, result)
    given = tuple(result.verdicts)
    if given:
        given = _with_life_rows(study, given, life)
        given = _with_hold_rows(study, given, hold)
        if requirements is None and all(v.quantity != DesignRange.quantity for v in given):
            given = with_design_range(study, given, design)
        given = with_stroke_row(given, result)  # a solve that stopped part-way: NOT MET
        return with_as_printed_verdicts(study, given, result.info.get("as printed"))
    values, table = {**result_values(result), **life}, result.table
    if hold is not None:
        values.update(_hold_values(study, hold))
        table = {**(table or {}), **_hold_columns(hold)}
    verdicts = _hold_details(study, judge(study, values, table, requirements, design), hold)
    verdicts = with_stroke_row(_life_setting_details(study, result, verdicts), result)
    verdicts = with_life_reason(verdicts, result, LIFE_QUANTITIES)  # why a life is missing
    return with_as_printed_verdicts(study, verdicts, result.info.get("as printed"))


def _life_setting_details(
    study: Study, result: DesignResult, verdicts: tuple[Verdict, ...]
) -> tuple[Verdict, ...]:
    """The life rows of a result with a stress per setting (a leaf joint) say in their detail
    which setting each level ran at (the worst, by name, where the duty cycle names none)."""
    from dataclasses import replace

    if not isinstance(result.info.get(STRESS_SETTINGS), Mapping):
        return verdicts
    life = life_of_settings(study, result) if getattr(study, "duty_cycle", None) else None
    if life is None:
        return verdicts
    note = life.setting_note if isinstance(life, LifeResult) else f"not computed: {life}"
    return tuple(
        replace(v, detail="; ".join(filter(None, (v.detail, note))))
        if v.quantity in LIFE_QUANTITIES
        else v
        for v in verdicts
    )


def life_of_result(study: Study, result: DesignResult) -> LifeResult | str | None:
    """The fatigue life of ``result`` over the study's ``duty_cycle:`` (None without one), or
    why it cannot be computed (a str: no response table, a drive beyond the stroke ...).

    The driven column is the kind's plot x (``result.plot["x"]``), the stress the
    ``peak_stress_MPa`` column of the same solve; where the kind reports a higher-fidelity
    figure of the peak stress (:func:`figures_of`: plane stress, 3D), the beam's peak is
    scaled by the ratio of the highest-ranked figure the design has to the table's maximum.
    """
    spec = getattr(study, "duty_cycle", None)
    if spec is None:
        return None
    table = result.table or {}
    x_col = (result.plot or {}).get("x")
    if isinstance(result.info.get(STRESS_SETTINGS), Mapping):
        return life_of_settings(study, result)  # a stress per setting (a leaf joint)
    if not x_col or x_col not in table or "peak_stress_MPa" not in table:
        return (
            "the response has no driven column with a peak_stress_MPa column "
            f"(columns: {', '.join(table) or 'none'})"
        )
    peak = np.abs(np.asarray(table["peak_stress_MPa"], dtype=float))
    peak = peak[np.isfinite(peak)]
    scale, model, figure = 1.0, "", ""
    values = result_values(result)
    if values.get(UNBOUNDED_STRESS):  # e.g. a pivot's sharp leaf roots: no life there
        return UNBOUNDED_LIFE
    # the best figure of the peak stress the design has: the highest-ranked one, also where a
    # built-in row judges it on its own (a spring's 3D peak): the life is judged on the best
    # stress the run computed, not on the stress verdict's choice of row
    ladder = [
        f
        for f in figures_of(study).get("peak_stress_MPa", ())
        if isinstance(values.get(f.quantity), int | float)
        and not isinstance(values.get(f.quantity), bool)
        and math.isfinite(float(values[f.quantity]))
    ]
    ladder.sort(key=lambda f: -f.rank)  # stable: the first listed of a rank wins
    if ladder and ladder[0].quantity != "peak_stress_MPa" and peak.size and peak.max() > 0.0:
        best = ladder[0]
        scale = float(values[best.quantity]) / float(peak.max())
        model = best.model
        figure = (
            f"{best.model} ({best.quantity} = {float(values[best.quantity]):.6g} MPa, over the "
            f"response table's peak {float(peak.max()):.6g} MPa)"
        )
    try:
        return life_of_table(
            spec, table, str(x_col), study.material.name, scale=scale, scale_model=model,
            stress_figure=figure,
        )  # fmt: skip
    except OptimiseError as exc:
        return str(exc)


def life_of_settings(study: Study, result: DesignResult) -> LifeResult | str:
    """The fatigue life of a result whose response has one stress column per setting
    (``result.info[STRESS_SETTINGS]``: setting name -> column, each (n_rows,) MPa from that
    setting's own nonlinear solve over the driven column ``plot["x"]``): each level at the
    setting it names, the others at the worst one (:func:`~optimise.durability.life_of_table`
    ``settings=``), or why not (a str)."""
    settings = {str(k): str(v) for k, v in result.info[STRESS_SETTINGS].items()}
    x_col = str((result.plot or {}).get("x") or "")
    columns = ", ".join(dict.fromkeys(settings.values()))
    try:
        return life_of_table(
            study.duty_cycle,  # type: ignore[attr-defined]
            result.table or {},
            x_col,
            study.material.name,
            settings=settings,
            stress_figure=f"the stress of each level's setting ({columns})",
        )
    except OptimiseError as exc:
        return str(exc)


def life_values(study: Study, result: DesignResult) -> dict[str, Any]:
    """The life figures a requirement judges (empty without ``duty_cycle:``; None values
    when the life cannot be computed or lies in low-cycle fatigue: NOT MET)."""
    life = life_of_result(study, result)
    if life is None:
        return {}
    if isinstance(life, str):
        return dict.fromkeys(LIFE_QUANTITIES)
    return life.values()


def with_life(study: Study, result: DesignResult) -> DesignResult:
    """``result`` with the fatigue life over the study's ``duty_cycle:`` in its summary
    (``life_cycles``, ``life_hours``, ``fatigue_damage_per_cycle_block``, the method and the
    data source) and each level in ``info["fatigue"]``; ``result`` itself without one."""
    from dataclasses import replace

    life = life_of_result(study, result)
    if life is None:
        return result
    if isinstance(life, str):
        note = {"life_cycles": None, "life_hours": None, "fatigue_note": life}
        summary = _verdict_with_life(study, {**result.summary, **note}, {})
        return replace(result, summary=summary)
    info = {
        **result.info,
        "fatigue": {
            **life.summary(),
            "scale": life.scale,
            "levels": [lv.record() for lv in life.levels],
        },
    }
    head = result.headline and (*result.headline, *LIFE_QUANTITIES)  # empty: the CLI shows all
    summary = _verdict_with_life(study, {**result.summary, **life.summary()}, life.values())
    return replace(result, summary=summary, info=info, headline=head or ())


#: The provisional word of a kind's per-design ``verdict`` metric (the mechanism's) when the
#: study judges a life the optimiser does not compute per design (a life ``role: check``).
LIFE_PROVISIONAL = " (life judged on the best design only)"


def _verdict_with_life(
    study: Study, metrics: Mapping[str, Any], life: Mapping[str, Any] | None
) -> dict[str, Any]:
    """``metrics`` whose ``verdict`` word (a kind that states one per design: the mechanism's
    evaluations table and summary) takes the study's life requirements too, judged on ``life``
    (:meth:`~optimise.durability.LifeResult.values`; empty: not computable, NOT MET; None: not
    computed for this design, the word says so), so that it agrees with the verdict
    :func:`judge_result` gives. Unchanged without a ``verdict`` word or a life requirement."""
    out = dict(metrics)
    reqs = [r for r in user_requirements(study) if r.quantity in LIFE_QUANTITIES]
    word = out.get("verdict")
    if not reqs or word not in ("MET", "NOT MET"):
        return out
    if life is None:
        out["verdict"] = f"{word}{LIFE_PROVISIONAL}" if word == "MET" else word
        return out
    values = dict(life) or dict.fromkeys(LIFE_QUANTITIES)
    met = all(r.check(values).met for r in reqs)
    out["verdict"] = "MET" if word == "MET" and met else "NOT MET"
    return out


def _with_life_rows(
    study: Study, given: tuple[Verdict, ...], life: Mapping[str, Any]
) -> tuple[Verdict, ...]:
    """A kind's own verdicts with its rows on the life quantities judged on ``life`` (the
    kind does not compute the life: the pipeline does, once for every kind)."""
    if not life:
        return given
    reqs = [r for r in user_requirements(study) if r.quantity in LIFE_QUANTITIES]
    judged = {v.name: v for v in (r.check(dict(life)) for r in reqs)}
    out = [judged.pop(v.name, v) if v.quantity in LIFE_QUANTITIES else v for v in given]
    return (*out, *judged.values())


# --------------------------------------------------------------------------------------------
# hold: creep and relaxation over a hold time (docs/durability.md, Creep)


def _hold_names(study: Study) -> set[str]:
    """The names a requirement on the hold judges (empty without ``hold:``)."""
    if getattr(study, "hold", None) is None:
        return set()
    return set(hold_quantities(quantities_of(study)))


def peak_stress_scale(study: Study, result: DesignResult) -> tuple[float, str]:
    """The factor on the response table's ``peak_stress_MPa`` that gives the figure the verdict
    judges the peak stress on (the highest-ranked figure the design has, not one a built-in row
    judges on its own; as :func:`life_of_result`), and that figure's model; (1, "") when the
    kind has one model."""
    table = result.table or {}
    if "peak_stress_MPa" not in table:
        return 1.0, ""
    peak = np.abs(np.asarray(table["peak_stress_MPa"], dtype=float))
    peak = peak[np.isfinite(peak)]
    values = result_values(result)
    taken = {r.quantity for r in builtin_requirements(study)} - {"peak_stress_MPa"}
    ladder = [
        f
        for f in figures_of(study).get("peak_stress_MPa", ())
        if f.quantity not in taken
        and isinstance(values.get(f.quantity), int | float)
        and math.isfinite(float(values[f.quantity]))
    ]
    ladder.sort(key=lambda f: -f.rank)
    if ladder and ladder[0].quantity != "peak_stress_MPa" and peak.size and peak.max() > 0.0:
        return float(values[ladder[0].quantity]) / float(peak.max()), ladder[0].model
    return 1.0, ""


def hold_of_result(study: Study, result: DesignResult) -> HoldResult | str | None:
    """The design of ``result`` held as the study's ``hold:`` says (None without one), or why
    it cannot be computed (a str: no response table, a held value beyond the traced curve ...).

    The driven column is the kind's plot x, the force column ``hold.column`` or the kind's
    plotted force (``plot["y"]``, else ``plot["left"]``), the stress the ``peak_stress_MPa``
    column (scaled as :func:`peak_stress_scale`); the strength is the material's
    ``yield_MPa``.
    """
    spec = getattr(study, "hold", None)
    if spec is None:
        return None
    table = result.table or {}
    plot = result.plot or {}
    x_col = plot.get("x")
    f_col = spec.column or plot.get("y") or plot.get("left")
    if not x_col or not isinstance(f_col, str):
        return f"hold: the response has no driven and force column (plot: {dict(plot)})"
    scale, model = peak_stress_scale(study, result)
    try:
        law = creep_law_of(study.material)
        return hold_of_table(
            spec, table, str(x_col), f_col, law, float(study.material.yield_MPa),
            scale=scale, scale_model=model,
        )  # fmt: skip
    except OptimiseError as exc:
        return str(exc)


def _hold_values(study: Study, hold: HoldResult | str | None) -> dict[str, Any]:
    """The hold's figures a requirement judges (None when it cannot be computed: NOT MET)."""
    if hold is None:
        return {}
    if isinstance(hold, str):
        return dict.fromkeys(_hold_names(study))
    return hold.values()


def _hold_columns(hold: HoldResult | str | None) -> dict[str, Any]:
    """A displacement hold's held curve as the table column ``held_<force column>``."""
    if isinstance(hold, HoldResult) and hold.held_curve is not None and hold.in_range:
        return {hold.held_name: hold.held_curve}
    return {}


def _hold_details(
    study: Study, verdicts: Sequence[Verdict], hold: HoldResult | str | None
) -> tuple[Verdict, ...]:
    """``verdicts`` with each row on a hold quantity saying its creep data (an assumed law
    in its bound, so the verdict line shows it) and, when not computed, why."""
    from dataclasses import replace

    if hold is None:
        return tuple(verdicts)
    names = _hold_names(study)
    out = []
    for v in verdicts:
        if v.quantity in names:
            if isinstance(hold, str):
                v = replace(v, detail=hold)
            else:
                why = hold.note if hold.note and not math.isfinite(v.value) else ""
                parts = (why, "" if why else v.detail, hold.law.label)
                v = replace(v, detail="; ".join(p for p in parts if p))
                if hold.law.assumed:
                    v = replace(v, bound=f"{v.bound} [ASSUMED creep law]")
        out.append(v)
    return tuple(out)


def _with_hold_rows(
    study: Study, given: tuple[Verdict, ...], hold: HoldResult | str | None
) -> tuple[Verdict, ...]:
    """A kind's own verdicts with its rows on the hold quantities judged on ``hold``."""
    if hold is None:
        return given
    names = _hold_names(study)
    values = _hold_values(study, hold)
    reqs = [r for r in user_requirements(study) if r.quantity in names]
    judged = {v.name: v for v in (r.check(dict(values)) for r in reqs)}
    out = [judged.pop(v.name, v) if v.quantity in names else v for v in given]
    return _hold_details(study, (*out, *judged.values()), hold)


def with_hold(study: Study, result: DesignResult) -> DesignResult:
    """``result`` with the study's ``hold:`` in its summary (the held value, the retention or
    growth, the stress ratio, the method and the creep data), ``info["hold"]`` and the held
    curve as a table column; ``result`` itself without one."""
    from dataclasses import replace

    hold = hold_of_result(study, result)
    if hold is None:
        return result
    if isinstance(hold, str):
        note = {**_hold_values(study, hold), "hold_note": hold}
        return replace(result, summary={**result.summary, **note})
    summary = {**result.summary, **hold.summary()}
    info = {**result.info, "hold": hold.record()}
    table = {**(result.table or {}), **_hold_columns(hold)}
    note = ("hold_note",) if hold.note else ()  # out of range: the CLI table says why
    head = result.headline and (*result.headline, *hold.values(), *note)
    return replace(result, summary=summary, info=info, table=table, headline=head or ())


class HoldDetail(ProblemWrapper):
    """A kind's design problem whose :meth:`detail` carries the study's ``hold:``
    (:func:`with_hold`), which a run's best.json writes. Picklable."""

    def __init__(self, inner: Any, study: Study) -> None:
        super().__init__(as_design_problem(inner))
        self.hold_study = study

    def detail(self, x: np.ndarray) -> DesignDetail:
        return with_hold(self.hold_study, self.inner.detail(x))


def detail_values(detail: DesignDetail | None, evaluation: Evaluation) -> dict[str, Any]:
    """Scalars of a run's design: its metrics, the detail's info, the outline's bounding box
    (:func:`result_values` of the detail, or of the evaluation alone)."""
    return result_values(detail if detail is not None else DesignResult(evaluation))


def judge_detail(
    study: Study, detail: DesignDetail | None, evaluation: Evaluation
) -> tuple[Verdict, ...]:
    """Verdicts of a run's design (:func:`judge_result` of its detail, or of its evaluation
    when the detail failed), with the design-range row of ``evaluation.x``."""
    result = detail if detail is not None else DesignResult(evaluation)
    return judge_result(study, result, design=evaluation.x)


class RequirementConstraints(ProblemWrapper):
    """A kind's design problem with the ``role: constraint`` requirements as more constraints.

    The extra rows are ``requirement.constraint(metrics)`` (``-margin / scale``, dimensionless,
    g <= 0 when met), named ``req_<name>``. Only requirements that read scalar metrics become
    constraints (a target band needs the response curve, which a plain evaluation does not
    carry: it stays a check of the best design).

    Picklable; everything else (``detail``, ``initial_designs`` ...) is the inner problem's.
    """

    def __init__(self, inner: Any, requirements: Sequence[Requirement]) -> None:
        super().__init__(as_design_problem(inner))
        self.requirements = tuple(requirements)
        self.constraint_names = (
            *self.inner.constraint_names,
            *(f"req_{r.label}" for r in self.requirements),
        )

    def _extend(self, ev: Evaluation) -> Evaluation:
        from dataclasses import replace

        if ev.reason:
            extra = np.full(len(self.requirements), float(np.max(ev.g, initial=1.0e12)))
        else:
            metrics = _scalars(ev.metrics)
            extra = np.array([r.constraint(metrics) for r in self.requirements], dtype=float)
        return replace(ev, g=np.concatenate([np.asarray(ev.g, dtype=float), extra]))

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return self._extend(self.inner.evaluate(x))

    def jacobian(self, x: np.ndarray) -> Any:
        """The inner kind's exact derivatives with these rows where its hook takes them
        (``jacobian(x, extend=)``: the mechanism kind's linearised evaluation), else None."""
        hook = getattr(self.inner, "jacobian_extends", False)
        return self.inner.jacobian(x, extend=self._extend) if hook else None

    def detail(self, x: np.ndarray) -> DesignDetail:
        from dataclasses import replace

        detail = self.inner.detail(x)
        return replace(detail, evaluation=self._extend(detail.evaluation))


class LifeConstraints(ProblemWrapper):
    """A kind's design problem with the ``role: constraint`` requirements on the life as more
    constraints, each computed per design.

    Two ways to the life of one design ``x``, one for every kind:

    - the inner problem has :data:`RESPONSE_HOOK` (sea_spring): the evaluation and its
      response table of one solve; the life over the study's ``duty_cycle:`` is
      :func:`~optimise.durability.life_of_table` of that table (the stress of the model the
      optimiser solves, unscaled);
    - else (every other kind, the generic way): the inner problem's :meth:`evaluate` scores
      the design exactly as a run without a life constraint does, and the design's
      :meth:`detail` (the report's response table and its higher-fidelity stress figures, the
      same solve ``flexopt evaluate`` shows) gives the life by :func:`life_of_result`: on the
      best figure of the peak stress the design has, what the verdict of the best design
      judges. A design the evaluation already rejects is not detailed (it gets the largest
      row). Costs one detail per design (the kind's checks included: a plane-stress or 3D
      check the study turns on runs for every design).

    Each row is :func:`~optimise.durability.life_constraint` (decades, g <= 0 when met), named
    ``req_<name>``. The evaluation's metrics gain ``life_cycles``, ``life_hours`` (None:
    infinite or not computed) and ``fatigue_damage_per_cycle_block``. A design whose life
    cannot be computed (a drive beyond its traced stroke, a detail that failed) gets the
    largest row.

    Picklable; everything else is the inner problem's.
    """

    def __init__(self, inner: Any, study: Study, requirements: Sequence[Requirement]) -> None:
        super().__init__(as_design_problem(inner))
        why = life_constraint_refusal(study, self.inner)
        if why:
            raise StudyError("requirements", f"a life cannot be a constraint: {why}")
        self.duty_study = study
        self.requirements = tuple(requirements)
        self.by_detail = not callable(getattr(self.inner, RESPONSE_HOOK, None))
        self.constraint_names = (
            *self.inner.constraint_names,
            *(f"req_{r.label}" for r in self.requirements),
        )

    def _table_life(self, table: Mapping[str, Any] | None, x_col: str) -> LifeResult | None:
        study = self.duty_study
        if not table:
            return None
        try:
            return life_of_table(study.duty_cycle, table, x_col, study.material.name)  # type: ignore[arg-type]
        except OptimiseError:
            return None

    def _detail_life(self, x: np.ndarray) -> tuple[LifeResult | None, DesignResult | None]:
        """The life of ``x`` (n_var,) from the inner problem's detail (None: not computed)."""
        import logging

        try:
            detail = self.inner.detail(np.asarray(x, dtype=float))
        except Exception as exc:  # the GA's contract: one design never ends the run
            logging.getLogger(__name__).warning("life of %s: detail raised %r", x, exc)
            return None, None
        life = life_of_result(self.duty_study, detail)
        return (life if isinstance(life, LifeResult) else None), detail

    def _extend(self, ev: Evaluation, life: LifeResult | None) -> Evaluation:
        from dataclasses import replace

        if ev.reason:
            extra = np.full(len(self.requirements), float(np.max(ev.g, initial=1.0e12)))
            return replace(ev, g=np.concatenate([np.asarray(ev.g, dtype=float), extra]))
        values = life.values() if life is not None else dict.fromkeys(LIFE_QUANTITIES)
        extra = np.array([life_constraint(r, values) for r in self.requirements], dtype=float)
        finite = life.summary() if life is not None else {}
        metrics = {
            **_verdict_with_life(self.duty_study, ev.metrics, values),
            "life_cycles": finite.get("life_cycles"),
            "life_hours": finite.get("life_hours"),
            "fatigue_damage_per_cycle_block": finite.get("fatigue_damage_per_cycle_block"),
        }
        return replace(
            ev, g=np.concatenate([np.asarray(ev.g, dtype=float), extra]), metrics=metrics
        )

    def evaluate_response(self, x: np.ndarray) -> tuple[Evaluation, Mapping[str, Any] | None, str]:
        if not self.by_detail:
            ev, table, x_col = getattr(self.inner, RESPONSE_HOOK)(x)
            life = None if ev.reason else self._table_life(table, x_col)
            return self._extend(ev, life), table, x_col
        ev = self.inner.evaluate(x)
        if ev.reason:
            return self._extend(ev, None), None, ""
        life, detail = self._detail_life(x)
        if detail is None:
            return self._extend(ev, None), None, ""
        return self._extend(ev, life), detail.table, str((detail.plot or {}).get("x") or "")

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return self.evaluate_response(x)[0]

    def warm_up(self) -> None:
        # every evaluation runs a detail in the generic way: load what it needs before a pool
        # forks its workers, so that each worker does not load it again
        self.inner.warm_up()
        if self.by_detail:
            self.inner.warm_up_detail()

    def detail(self, x: np.ndarray) -> DesignDetail:
        from dataclasses import replace

        detail = self.inner.detail(x)
        if detail.evaluation is None:
            return detail
        if self.by_detail:
            found = life_of_result(self.duty_study, detail)
            life = found if isinstance(found, LifeResult) else None
        else:
            life = self._table_life(detail.table, str((detail.plot or {}).get("x") or ""))
        return replace(detail, evaluation=self._extend(detail.evaluation, life))


class LifeDetail(ProblemWrapper):
    """A kind's design problem whose :meth:`detail` carries the fatigue life over the study's
    ``duty_cycle:`` (:func:`with_life`: the summary and ``info["fatigue"]``, which a run's
    best.json writes). Picklable; everything else is the inner problem's."""

    def __init__(self, inner: Any, study: Study) -> None:
        super().__init__(as_design_problem(inner))
        self.duty_study = study

    def detail(self, x: np.ndarray) -> DesignDetail:
        return with_life(self.duty_study, self.inner.detail(x))

    def evaluate(self, x: np.ndarray) -> Evaluation:
        from dataclasses import replace

        ev = self.inner.evaluate(x)
        if "verdict" not in ev.metrics or "life_cycles" in ev.metrics:
            return ev  # no verdict word, or LifeConstraints judged the life of this design
        return replace(ev, metrics=_verdict_with_life(self.duty_study, ev.metrics, None))


def with_requirement_constraints(study: Study, problem: Any) -> Any:
    """``problem`` with the study's ``role: constraint`` requirements added (those on the life
    computed per design, :class:`LifeConstraints`; the scalar ones,
    :class:`RequirementConstraints`) and, with a ``duty_cycle:``, the life in its detail
    (:class:`LifeDetail`); or itself.

    Raises
    ------
    StudyError
        When a life constraint's kind cannot give each design's response table.
    """
    constraints = [
        r for r in user_requirements(study) if r.role == "constraint" and not r.needs_curve
    ]
    # the life rows first: they need the inner problem's response table (RESPONSE_HOOK), which
    # the scalar rows' wrapper does not pass on
    lives = [r for r in constraints if r.quantity in LIFE_QUANTITIES]
    if lives and getattr(study, "duty_cycle", None) is not None:
        problem = LifeConstraints(problem, study, lives)
    constraints = [r for r in constraints if r.quantity not in LIFE_QUANTITIES]
    if constraints:
        problem = RequirementConstraints(problem, constraints)
    if getattr(study, "duty_cycle", None) is not None:
        problem = LifeDetail(problem, study)
    if getattr(study, "hold", None) is not None:
        problem = HoldDetail(problem, study)
    return problem


def scalar_names(values: Iterable[str]) -> tuple[str, ...]:
    """Sorted unique names (a helper for kinds declaring ``quantities``)."""
    return tuple(sorted(set(values)))
