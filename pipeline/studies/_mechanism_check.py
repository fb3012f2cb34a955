"""The ``mechanism`` study file's refusals across its keys, each with its key path: the parts
joints, drives, supports and outputs name; the outputs' units and references; the names
requirements and objectives read; a width solved from a force; and the key path of a refusal of
the geometry or the engine (the kind, pipeline/studies/mechanism.py, builds and checks the
initial design itself).
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Mapping, Sequence

from flexopt.fea.mechanism_design import REACTION_UNIT
from flexopt.geometry.mechanism import end_ref
from flexopt.optimise.mechanism_objectives import STATS
from flexopt.optimise.requirements import Range, Requirement, TargetBand, unit_of
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies._mechanism_schema import (
    MechanismGeometry,
    MechanismStudy,
    OutputSpec,
    output_exponent,
    output_refs,
)

__all__ = ["check_choices", "check_references", "fea_refusal", "geometry_path"]

#: Columns every case table has; an output may not take one of these names.
BUILTIN_COLUMNS = ("step", "converged", "stable", "peak_stress_MPa")


def _part_exists(geometry: MechanismGeometry, ref: str, allow_beam: bool = False) -> bool:
    end = end_ref(ref)
    if end is not None:
        return end[0] in geometry.beams
    return ref in geometry.bodies or (allow_beam and ref in geometry.beams)


def _part_hint(geometry: MechanismGeometry) -> str:
    ends = [f"{b}.start, {b}.end" for b in list(geometry.beams)[:3]]
    return ", ".join([*ends, *list(geometry.bodies)[:3]])


def _output_unit_problem(name: str, spec: OutputSpec, control: str) -> str | None:
    """Why an output's name does not carry its quantity's unit (None when it does)."""
    wanted = {
        "reaction_force": ("N",),
        "reaction_moment": ("N·mm",),
        "displacement": ("mm",),
        "rotation": ("deg", "rad"),
        "peak_stress": ("MPa",),
        "reaction": ("N·mm",) if REACTION_UNIT[control] == "Nmm" else ("N",),
    }.get(spec.quantity)
    if wanted is None or unit_of(name) in wanted:
        return None
    suffix = {"N·mm": "_Nmm"}.get(wanted[0], f"_{wanted[0]}")
    return (
        f"a {spec.quantity} output is in {' or '.join(wanted)}; end its name with the unit, "
        f"e.g. {name.rsplit('_', 1)[0] if '_' in name else name}{suffix}"
    )


def check_references(study: MechanismStudy) -> None:
    """Refuse (StudyError at the key path) a joint, drive, support or output that names no
    part, a support not to ground, an output named like a built-in column, read in no load
    case, referring to no other output, or whose name does not end in its unit, and slopes and
    ratios that refer to each other in a loop."""
    g = study.geometry
    hint = _part_hint(g)
    for i, joint in enumerate(g.joints):
        for key in ("a", "b"):
            ref = getattr(joint, key)
            ok = ref == "ground" and key == "b" or _part_exists(g, ref)
            if not ok:
                raise StudyError(
                    f"geometry.joints[{i}].{key}",
                    f"'{ref}' names no part; use a beam end ({hint})"
                    + (", or ground" if key == "b" else ""),
                )
    for case, spec in study.load_cases.items():
        here = f"load_cases.{case}"
        if not _part_exists(g, spec.drive.part):
            raise StudyError(f"{here}.drive.part", f"'{spec.drive.part}' names no part; use {hint}")
        for j, s in enumerate(spec.supports):
            if s.b != "ground":
                raise StudyError(f"{here}.supports[{j}].b", "a support holds to ground; b: ground")
            if not _part_exists(g, s.a):
                raise StudyError(f"{here}.supports[{j}].a", f"'{s.a}' names no part; use {hint}")
    for name, o in study.outputs.items():
        here = f"outputs.{name}"
        if name in BUILTIN_COLUMNS or name.startswith("drive_"):
            raise StudyError(here, f"'{name}' is a column every response has; rename the output")
        for case in o.cases or ():
            if case not in study.load_cases:
                raise StudyError(
                    f"{here}.cases",
                    f"'{case}' is no load case; use {', '.join(study.load_cases)}",
                )
        if o.quantity in ("slope", "ratio"):
            refs = output_refs(o)
            if len(refs) != (1 if o.quantity == "slope" else 2):
                need = "of: <output>" if o.quantity == "slope" else "of: [numerator, denominator]"
                raise StudyError(f"{here}.of", f"a {o.quantity} needs {need}")
            for ref in refs:
                if ref not in study.outputs or ref == name:
                    raise StudyError(
                        f"{here}.of", f"'{ref}' is no other output; use one of the outputs"
                    )
        elif o.part and not (_part_exists(g, o.part, allow_beam=o.quantity == "peak_stress")):
            raise StudyError(f"{here}.part", f"'{o.part}' names no part; use {hint}")
        for case in o.cases or study.load_cases:
            problem = _output_unit_problem(name, o, study.load_cases[case].drive.control)
            if problem:
                raise StudyError(here, problem)
    _refuse_derived_cycles(study)


def _refuse_derived_cycles(study: MechanismStudy) -> None:
    """Refuse slopes and ratios that refer to each other in a loop (``a`` the slope of ``b``,
    ``b`` the slope of ``a``): nothing can be computed first, so every such column would be NaN."""

    def refs(name: str) -> list[str]:
        o = study.outputs[name]
        if o.quantity not in ("slope", "ratio"):
            return []
        return list(output_refs(o))

    done: set[str] = set()
    for start in study.outputs:
        path: list[str] = []
        stack: list[tuple[str, int]] = [(start, 0)]
        while stack:  # depth-first, iterative: a long chain of outputs cannot overflow
            name, i = stack.pop()
            if i == 0:
                if name in done:
                    continue
                if name in path:
                    loop = " -> ".join([*path[path.index(name) :], name])
                    raise StudyError(
                        f"outputs.{name}.of",
                        f"outputs refer to each other in a loop ({loop}), so none of them can "
                        "be computed; make one of them a measured quantity (reaction, "
                        "displacement, rotation) or refer to one",
                    )
                path.append(name)
            children = [r for r in refs(name) if r in study.outputs]
            if i < len(children):
                stack.append((name, i + 1))
                stack.append((children[i], 0))
            else:
                done.add(path.pop())


def check_choices(
    study: MechanismStudy,
    reqs: Sequence[Requirement],
    quantities: Sequence[str],
    metrics: Sequence[str],
) -> None:
    """Refuse a requirement that reads none of ``quantities`` (the study's metrics and columns),
    an objective on none of ``metrics`` or on no target requirement of ``reqs`` (the study's
    requirements, in order), a width solved from what does not scale with it, and several
    objectives for the single-objective GA."""
    valid = set(quantities)
    labels = {r.label: r for r in reqs}
    for i, spec in enumerate(study.requirements):
        for key, name in (("quantity", spec.quantity), ("x", spec.x)):
            if name is not None and name not in valid:
                close = difflib.get_close_matches(name, sorted(valid), n=1)
                raise StudyError(
                    f"requirements[{i}].{key}",
                    f"this study reports no '{name}'; "
                    + (f"did you mean '{close[0]}'? " if close else "")
                    + f"use one of {', '.join(sorted(valid))}",
                )
    for i, obj in enumerate(study.objectives):
        key, name = obj.key
        if key in ("minimise", "maximise"):
            if name not in metrics:
                raise StudyError(
                    f"objectives[{i}].{key}",
                    f"'{name}' is no metric of this study; use one of " + ", ".join(metrics),
                )
        elif not isinstance(labels.get(name), TargetBand):
            targets = [r.label for r in reqs if isinstance(r, TargetBand)]
            raise StudyError(
                f"objectives[{i}].{key}",
                f"'{name}' is no target requirement; name one of: "
                + (", ".join(targets) or "(none: add a requirement with target:)"),
            )
    if study.solve_width_from is not None:
        _check_width_solve(study, labels)
    if len(study.objectives) > 1 and study.optimiser.algorithm == "ga":
        raise StudyError(
            "optimiser.algorithm",
            f"{len(study.objectives)} objectives need algorithm: nsga2 (ga optimises one)",
        )


def _quantity_output(study: MechanismStudy, quantity: str) -> str | None:
    """The output a metric or column name reads (``blocked.max_jaw_force_N`` → jaw_force_N)."""
    name = quantity.split(".", 1)[1] if "." in quantity else quantity
    for stat in sorted(STATS, key=len, reverse=True):
        if name.startswith(f"{stat}_") and name[len(stat) + 1 :] in study.outputs:
            return name[len(stat) + 1 :]
    return name if name in study.outputs else None


def _check_width_solve(study: MechanismStudy, labels: Mapping[str, Requirement]) -> None:
    spec = study.solve_width_from
    assert spec is not None
    here = "solve_width_from.requirement"
    req = labels.get(spec.requirement)
    if not isinstance(req, Range | TargetBand):
        raise StudyError(
            here,
            f"'{spec.requirement}' is no range or target requirement; name one of: "
            + ", ".join(r for r, q in labels.items() if isinstance(q, Range | TargetBand)),
        )
    output = _quantity_output(study, req.quantity)
    if output is None or output_exponent(study, output) != 1:
        raise StudyError(
            here,
            f"'{req.quantity}' does not scale with the width (only forces, moments and their "
            "slopes do); solve the width from a force requirement",
        )
    per_beam = [n for n, b in study.geometry.beams.items() if b.width_mm is not None]
    if per_beam:
        raise StudyError(
            f"geometry.beams.{per_beam[0]}.width_mm",
            "a beam of its own width does not scale with the shared width; remove width_mm here "
            "or drop solve_width_from",
        )
    for case, c in study.load_cases.items():
        if c.drive.control in ("force", "moment"):
            raise StudyError(
                f"load_cases.{case}.drive.control",
                "under force control the motion, not the force, changes with the width; drive "
                "by displacement or rotation to solve the width",
            )
    for i, v in enumerate(study.variables):
        if v.path.strip() == "geometry.width_mm":
            raise StudyError(
                f"variables[{i}].path", "the width is solved (solve_width_from); drop this variable"
            )


def geometry_path(message: str) -> str:
    """The key path a geometry refusal is about: the beam it names (and the point), else the
    geometry."""
    m = re.match(r"beam '([A-Za-z][A-Za-z0-9_-]*)'(?: turns .* at point \[(\d+)\])?", message)
    if m is None:
        return "geometry"
    return f"geometry.beams.{m[1]}" + (f".points_mm[{m[2]}]" if m[2] else "")


def fea_refusal(case: str, message: str) -> StudyError:
    """The engine's refusal of load case ``case`` as a StudyError: at the joints for a free
    motion or a joint, at the case's drive or supports when the message starts with them; a
    free motion with the fix."""
    head = message.split(":", 1)[0]
    path = "geometry.joints"
    if "free rigid-body motion" in message or "joint" in head:
        path = "geometry.joints"
    elif "support" in head:
        path = f"load_cases.{case}.supports"
    elif "drive" in head:
        path = f"load_cases.{case}.drive"
    if "free" in message and "add a joint" not in message:
        message = f"{message}; add a joint or a support that holds it"
    return StudyError(path, message)
