"""One table of labels: column, metric and variable names turned into words with units.

flexopt names every quantity with its unit as a suffix (``force_N``, ``stiffness_Nm_per_rad``,
``torque_Nm_sliding_l28``): readable in a CSV, not on the axis of a plot. :func:`label` turns a
name into words with the unit in brackets (``torque, sliding, l = 28 mm (N·m)``) from

- :data:`NAMES`, whole names with a hand-written label (looked up first), then
- the unit suffix conventions (:data:`UNITS`): what stands before the unit is the quantity, what
  follows it qualifies the curve (a setting, a length), and
- :data:`WORDS`, known words for the quantity and qualifier tokens.

:func:`variable_meanings` says what each design variable of a kind means (``a3``: where p3 sits
between S2 and S3), from :data:`VARIABLES` or the problem's own ``variable_meanings``.
Used by the plots (``pipeline/plots.py``) and the HTML report (``pipeline/report_html.py``), so a
name reads the same everywhere.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from flexopt.optimise.problem import as_design_problem
from flexopt.optimise.variables import DesignVariables

__all__ = [
    "MAXIMISED",
    "best_design_rows",
    "design_columns",
    "constraint_quantities",
    "curves_label",
    "objective_text",
    "objective_view",
    "physical_text",
    "NAMES",
    "UNITS",
    "VARIABLES",
    "WORDS",
    "label",
    "path_words",
    "siblings",
    "split_meaning",
    "split_name",
    "strip_unit",
    "unit_of",
    "variable_meanings",
    "variable_rows",
    "words",
]

#: Unit suffixes (as the ``_``-separated tokens of a name) and how they are written. Longest
#: first, so ``Nm_per_rad`` wins over ``Nm``.
UNITS: dict[tuple[str, ...], str] = {
    ("Nmm", "per", "rad"): "N·mm/rad",
    ("Nmm", "per", "deg"): "N·mm/°",
    ("Nm", "per", "rad"): "N·m/rad",
    ("Nm", "per", "deg"): "N·m/°",
    ("N", "per", "mm"): "N/mm",
    ("N", "per", "m"): "N/m",
    ("mm", "per", "N"): "mm/N",
    ("rad", "per", "Nm"): "rad/(N·m)",
    ("N",): "N",
    ("kN",): "kN",
    ("Nmm",): "N·mm",
    ("Nm",): "N·m",
    ("mm",): "mm",
    ("m",): "m",
    ("mm2",): "mm²",
    ("mm3",): "mm³",
    ("mm4",): "mm⁴",
    ("MPa",): "MPa",
    ("GPa",): "GPa",
    ("deg",): "°",
    ("rad",): "rad",
    ("s",): "s",
    ("ms",): "ms",
    ("g",): "g",  # grams (mass_g) or standard gravity (head_acceleration_g): both written g
    ("kg",): "kg",
    ("kg", "m2"): "kg·m²",
    ("J",): "J",
    ("mJ",): "mJ",
    ("Hz",): "Hz",
    ("pct",): "%",
    ("percent",): "%",
}
_UNITS_BY_LENGTH = sorted(UNITS, key=len, reverse=True)

#: Whole names with a label of their own (the generic rule would say less).
NAMES: dict[str, str] = {
    "displacement_mm": "end displacement along the work direction (mm)",
    "force_N": "end force along the work direction (N)",
    "peak_stress_MPa": "peak von Mises stress (MPa)",
    "stress_ratio": "peak stress / allowable stress (–)",
    "stress_ratio_minus_1": "peak stress / allowable stress − 1 (–, ≤ 0 is within the allowable)",
    "rms_error_N": "RMS force error over the stroke (N)",
    "negative_operative_stroke_mm": "operative stroke, negated to be minimised (mm)",
    "operative_stroke_shortfall_mm": "operative stroke short of the minimum (mm, ≤ 0 is met)",
    "head_acceleration_g": "head acceleration (g, standard gravity)",
    "mass_g": "mass (g)",
    "stiffness_error_percent": "stiffness error (%)",
    "safety_factor": "safety factor (–)",
    "feasible": "feasible (meets every constraint)",
    "generation": "generation",
    "time_s": "evaluation time (s)",
    "converged": "converged",
}

#: Words for single tokens of a name (quantity or qualifier); others are kept as written.
WORDS: dict[str, str] = {
    "lmin": "l = l_min (stiff setting)",
    "lmax": "l = l_max (soft setting)",
    "rms": "RMS",
    "max": "maximum",
    "ccw": "counter-clockwise",
    "cw": "clockwise",
    "min": "minimum",
    "avg": "mean",
    "fe": "FE",
    "prb": "PRB",
    "sab": "SAB",
    "cam": "cam",
    "virtual": "virtual",
    "nmm": "N·mm",
}


def _constant_force() -> dict[str, str]:
    """Paper 003's beam: ten points p1..p10 on the segments S1→S6 (two per segment, Eq. 13),
    a thickness at each, the two ends and the width."""
    out: dict[str, str] = {}
    for j in range(1, 11):
        k = (j + 1) // 2
        where = f"where p{j} sits between S{k} and S{k + 1}, 0 at S{k} and 1 at S{k + 1} (–)"
        out[f"a{j}"] = where
        for name in (f"t{j}_mm", f"t{j}"):
            out[name] = f"in-plane thickness of the beam at p{j} (mm)"
    for name in ("T1_mm", "T1"):
        out[name] = "in-plane thickness at the clamped end S1 (mm)"
    for name in ("T6_mm", "T6"):
        out[name] = "in-plane thickness at the driven end S6 (mm)"
    for name in ("B_mm", "B"):
        out[name] = "out-of-plane width of the part (mm)"
    return out


def _sea_spring() -> dict[str, str]:
    """Paper 004's spring, both topologies: the spiral arm (geometry.arm_spring) and the
    serpentine of concentric arcs (geometry.sea_spring, Table 9)."""
    out = {
        # spiral arms
        "sweep_deg": "angle the arm sweeps from the hub to its pad (°)",
        "R_pad_mm": "radius of the pad centre, where the arm ends (mm)",
        "F1_fraction": "share of the radial rise from hub to pad reached at a third of the sweep "
        "(1/3 with F2 = 1/2 is an Archimedean spiral) (–)",
        "F2_fraction": "share of the remaining radial rise reached at two thirds of the sweep (–)",
        # serpentine
        "alpha_deg": "angular span of the arcs of one set (°)",
        "P1_mm": "width of the hub spoke, hub rim to the first arc (mm)",
        "P2_mm": "radial width of the neck, last arc to the pad (mm)",
        "ST_mm": "out-of-plane thickness of the spring (the extrusion) (mm)",
    }
    for i in range(1, 10):
        out[f"R{i}_mm"] = f"centre radius of arc {i}, counted from the hub (mm)"
        out[f"S{i}_mm"] = f"radial thickness of arc {i} (mm)"
    for i in range(1, 10):  # W1..W4: the spiral's width at t = 0, 1/3, 2/3, 1
        out[f"W{i}_mm"] = (
            f"spiral: arm width at the {_FOURTHS.get(i, f'point {i}')}; serpentine: width of "
            f"link {i}, joining arc {i} to arc {i + 1} (mm)"
        )
    return out


_FOURTHS = {1: "hub (t = 0)", 2: "first third (t = 1/3)", 3: "second third (t = 2/3)",
            4: "pad (t = 1)"}  # fmt: skip


def _threshold_spring() -> dict[str, str]:
    """Issue 7's threshold spring (geometry.threshold_spring): four polar control points of the
    arm at t = 0, 1/3, 2/3, 1."""
    return {
        "sweep_deg": "angle from the arm's root at the hub to its pad (°)",
        "pad_radius_mm": "radius of the pad centre, where the arm ends (mm)",
        "F1": "radius of the first-third control point, as a share of hub → pad (–)",
        "F2": "radius of the second-third control point, as a share of hub → pad (–)",
        "G1": "angle of the first-third control point, as a share of the sweep (–)",
        "G2": "angle of the second-third control point, as a share of the sweep (–)",
        "W1_mm": "in-plane width of the arm at the hub (t = 0) (mm)",
        "W2_mm": "in-plane width of the arm at the first-third point (t = 1/3) (mm)",
        "W3_mm": "in-plane width of the arm at the second-third point (t = 2/3) (mm)",
        "W4_mm": "in-plane width of the arm at the pad (t = 1) (mm)",
    }


#: Design variables with a meaning of their own, by study kind (the problem's
#: ``variable_meanings`` attribute, when it has one, wins). Each ends with its unit in brackets
#: (``–`` for a fraction or a count). The ``mechanism`` kind's variables are study paths: their
#: meaning is the path in words (:func:`path_words`).
VARIABLES: dict[str, dict[str, str]] = {
    "constant_force": _constant_force(),
    "gripper": _constant_force(),  # the gripper's force is held by a constant-force beam
    "sea_spring": _sea_spring(),
    "threshold_spring": _threshold_spring(),
    "flexure_pivot": {
        "type_index": "pivot type: the integer part picks one of geometry.candidates, in order (–)",
        "length_mm": "compliant length: leaf length L, notch length 2R / 2a / L + 2r by type (mm)",
        "thickness_mm": "thinnest section: leaf thickness t or notch web t (mm)",
        "shape": "type-specific shape: variable leaf end thickness t (1 + 2 shape), elliptical "
        "notch depth, corner fillet radius; unused by the other types (–)",
    },
    "leaf_spring_joint": {
        "arm_mm": "joint arm l_j = |OB|, from the joint axis to the leaf's slider (mm)",
        "thickness_mm": "thickness t of each 65Mn leaf (mm)",
        "width_mm": "width b of each leaf, along the joint axis (mm)",
    },
    "cam": {
        "rest_radius_mm": "r0: distance of the follower centre from the cam axis at zero "
        "rotation (mm)",
        "stiffness_N_per_mm": "K: rate of one extension spring pulling the follower (N/mm)",
        "free_length_mm": "l0: initial length of one spring (mm)",
        "offset_mm": "b: lateral offset of the spring's anchor (mm)",
    },
}


def path_words(path: str) -> str:
    """A study key path in words: ``geometry.beams.upper.thickness_mm`` → ``thickness of beam
    'upper' (mm)``, ``geometry.beams.beam.points_mm[1][0]`` → ``x of point 1 of beam 'beam'
    (mm)``; other paths keep their keys, joined by ›, with the unit of the last one."""
    keys = [k for k in re.split(r"[.\[\]]+", str(path)) if k]
    axis = {"0": "x", "1": "y", "2": "z"}
    plural = {"beams": "beam", "bodies": "body", "joints": "joint", "load_cases": "load case",
              "outputs": "output"}  # fmt: skip
    if keys and keys[0] == "geometry":
        keys = keys[1:]
    if len(keys) < 3 or keys[0] not in plural:
        last = keys[-1] if keys else str(path)
        unit = unit_of(last)
        text = " › ".join(keys[:-1] + [words(last)]) if keys else str(path)
        return f"{text} ({unit})" if unit else text
    owner = f"{plural[keys[0]]} '{keys[1]}'"
    key, rest = keys[2], keys[3:]
    unit = unit_of(key)
    what = words(key)
    if key.startswith("points") and len(rest) == 2:
        what = f"{axis.get(rest[1], rest[1])} of point {rest[0]}"
    elif key.startswith("ref") and len(rest) == 1:
        what = f"{axis.get(rest[0], rest[0])} of the reference point"
    elif key.startswith("outline") and len(rest) == 2:
        what = f"{axis.get(rest[1], rest[1])} of outline point {rest[0]}"
    elif rest == ["*"]:
        what += " at every point"
    elif rest:
        what += " at point " + ", ".join(rest)
    text = f"{what} of {owner}"
    return f"{text} ({unit})" if unit else text


_LENGTH = re.compile(r"^l(\d+(?:\.\d+)?)$")  # l28: the curve at effective length 28 mm
_AT = re.compile(r"^(\d+(?:\.\d+)?)(deg|mm|N)$")  # 5deg in at_5deg


def split_name(name: str) -> tuple[list[str], str | None, list[str]]:
    """``(quantity tokens, unit as written, qualifier tokens)`` of a name.

    ``torque_Nm_sliding_l28`` → ``(['torque'], 'N·m', ['sliding', 'l28'])``; a name without a
    unit suffix gives ``(tokens, None, [])``. The first token is never a unit (``s_mm`` is a
    quantity s in mm).
    """
    tokens = [t for t in str(name).split("_") if t]
    for i in range(1, len(tokens)):
        for key in _UNITS_BY_LENGTH:
            if tuple(tokens[i : i + len(key)]) == key:
                return tokens[:i], UNITS[key], tokens[i + len(key) :]
    return tokens, None, []


def _token_words(token: str) -> str:
    if token in WORDS:
        return WORDS[token]
    if token.lower() in WORDS:
        return WORDS[token.lower()]
    if m := _LENGTH.match(token):
        return f"l = {m.group(1)} mm"
    if m := _AT.match(token):
        return f"{m.group(1)} {UNITS.get((m.group(2),), m.group(2))}"
    return token


def words(name: str, plain: bool = False) -> str:
    """The words of a name without its unit: ``torque_Nm_sliding_l28`` → ``torque, sliding,
    l = 28 mm`` (``plain``: not from :data:`NAMES`)."""
    if name in NAMES and not plain:
        return re.sub(r"\s*\([^()]*\)$", "", NAMES[name])
    quantity, _, qualifier = split_name(name)
    text = " ".join(_token_words(t) for t in quantity) or str(name)
    if qualifier:
        text += ", " + " ".join(_token_words(t) for t in qualifier).replace(" l = ", ", l = ")
    return text


def unit_of(name: str) -> str | None:
    """The unit of a name as written (``N·m``), or None when it has none."""
    return split_name(name)[1]


def label(name: str, given: str | None = None, plain: bool = False) -> str:
    """Words with the unit in brackets: ``torque_Nm_sliding_l28`` → ``torque, sliding, l = 28 mm
    (N·m)``; ``given`` (a label the study kind chose) wins. ``plain``: from the name's own
    words only, not :data:`NAMES` (a user's output named ``force_N`` is not the beam's end
    force)."""
    if given:
        return given
    if name in NAMES and not plain:
        return NAMES[name]
    unit = unit_of(name)
    text = words(name, plain)
    return f"{text} ({unit})" if unit else text


def _mechanism_meanings(problem: Any) -> dict[str, str]:
    """A mechanism study's variables: each one's path in words, its factor and offset, and the
    keys tied to it (``problem.variables``: optimise.variables.DesignVariables)."""
    variables = as_design_problem(problem).variables
    if not isinstance(variables, DesignVariables):
        return {}
    paths, targets = variables.paths, variables.targets
    out: dict[str, str] = {}
    for k, (name, path) in enumerate(zip(variables.names, paths, strict=True)):
        meaning, unit = split_meaning(path_words(path))
        own = targets[k][0] if targets and targets[k] else None
        factor = float(getattr(own, "factor", 1.0)) if own is not None else 1.0
        offset = float(getattr(own, "offset", 0.0)) if own is not None else 0.0
        if factor != 1.0 or offset != 0.0:
            sign = "+" if offset >= 0 else "−"
            meaning += f", set to {factor:.4g} × {name} {sign} {abs(offset):.4g} {unit}"
            if factor != 1.0:
                unit = "–"  # the variable is a scaled stand-in for the key, not the key itself
        ties = len(targets[k]) - 1 if targets else 0
        if ties > 0:
            meaning += f"; also sets {ties} tied key{'s' if ties > 1 else ''}"
        out[name] = f"{meaning} [{path}] ({unit})"
    return out


def split_meaning(text: str) -> tuple[str, str]:
    """``(meaning, unit)`` of a meaning written ``words (unit)``; the unit is ``–`` when the text
    ends in no brackets."""
    m = re.match(r"^(.*\S)\s*\(([^()]*)\)$", text.strip(), re.S)
    if not m:
        return text.strip(), "–"
    return m.group(1), m.group(2)


def variable_meanings(kind: str, names: Iterable[str], problem: Any = None) -> dict[str, str]:
    """What each design variable means, ``words (unit)``: the problem's ``variable_meanings``
    mapping, else the study path in words (``mechanism``), else :data:`VARIABLES` of the kind,
    else the variable's label (its words and unit)."""
    own = as_design_problem(problem).variable_meanings if problem is not None else None
    table: Mapping[str, str]
    if isinstance(own, Mapping):
        table = own
    elif kind == "mechanism" and problem is not None:
        table = _mechanism_meanings(problem)
    else:
        table = VARIABLES.get(kind, {})
    return {n: str(table[n]) if n in table else label(n) for n in names}


def variable_rows(kind: str, problem: Any, x: Iterable[float]) -> list[list[Any]]:
    """The rows of a report's variables table: ``variable | meaning | unit | bounds | best
    value`` of design ``x`` (the bounds ``[lower, upper]`` in the variable's unit)."""
    space = problem.space
    meanings = variable_meanings(kind, space.names, problem)
    rows: list[list[Any]] = []
    for name, lo, hi, value in zip(space.names, space.lower, space.upper, x, strict=True):
        meaning, unit = split_meaning(meanings[name])
        if meaning == name:  # a label with no words beyond the name
            meaning = "–"
        rows.append([name, meaning, unit, f"{float(lo):.4g} – {float(hi):.4g}", float(value)])
    return rows


#: Prefixes of a column that compares with another of the same quantity and unit: drawn beside
#: it (``reference_contact_force_N`` beside ``contact_force_N``, ``closed_form_torque_Nmm``
#: beside ``torque_Nmm``). ``target_`` columns are targets, drawn as such, never as curves.
COMPARISONS: tuple[tuple[str, ...], ...] = (
    ("reference",),
    ("closed", "form"),
    ("plane", "stress"),
)


def siblings(table: Mapping[str, Any], column: str) -> list[str]:
    """``column`` and the other curves to draw with it, ``column`` first.

    Those of the same quantity and unit with another qualifier (the six curves of the
    leaf-spring joint: ``torque_Nm_sliding_l28`` beside ``torque_Nm_fixed_l40``), then those
    that compare with it (:data:`COMPARISONS`: ``reference_contact_force_N``); each a 1-D
    column as long as ``column``.
    """
    quantity, unit, _ = split_name(column)
    if unit is None or column not in table:
        return [column]
    n = len(table[column])

    def same_shape(c: str) -> bool:
        try:
            return c != column and len(table[c]) == n and getattr(table[c], "ndim", 1) == 1
        except TypeError:
            return False

    found = [c for c in table if same_shape(c) and split_name(c)[:2] == (quantity, unit)]
    for c in table:
        if c in found or not same_shape(c):
            continue
        q, u, _ = split_name(c)
        if u == unit and any(tuple(q) == (*p, *quantity) for p in COMPARISONS):
            found.append(c)
    return [column, *found]


def curves_label(column: str, curves: list[str]) -> str:
    """The axis label of ``column`` drawn with ``curves`` (:func:`siblings`): its own label
    when alone; of several curves, their common quantity and unit (each curve is named in the
    legend): ``torque_Nm_sliding_l28`` with five more → ``torque (N·m)``."""
    if len(curves) <= 1:
        return label(column)
    quantity, unit, qualifier = split_name(column)
    if unit is None:
        return label(column)
    tokens = [t for t in column.split("_") if t]
    unit_tokens = tokens[len(quantity) : len(tokens) - len(qualifier)]
    return label("_".join([*quantity, *unit_tokens]))


def strip_unit(text: str) -> str:
    """A label without its trailing ``(unit)``: ``torque on the hub (N m)`` → ``torque on the
    hub``."""
    return re.sub(r"\s*\([^()]*\)$", "", str(text))


# --------------------------------------------------------------------------------------------
# Objectives and constraints as the user asked for them

#: The prefix of an objective that maximises a quantity: the optimiser minimises its negative.
MAXIMISED = "negative_"


def _finite_number(value: Any) -> bool:
    import math

    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def objective_view(
    name: str, value: float, metrics: Mapping[str, Any] | None = None
) -> tuple[str, str, float]:
    """An objective as the study states it: ``(sense, quantity, value)``.

    ``negative_X`` is X maximised (the optimiser minimises its negative): ``("maximise", X,
    the value of X)``, read from ``metrics`` when the design reports X (exact, without a
    tie-breaker the objective may carry), else the objective negated. Any other name is
    ``("minimise", name, value)``.
    """
    if name.startswith(MAXIMISED):
        quantity = name[len(MAXIMISED) :]
        measured = (metrics or {}).get(quantity)
        if _finite_number(measured):
            return "maximise", quantity, float(measured)
        return "maximise", quantity, -float(value)
    return "minimise", name, float(value)


def physical_text(quantity: str, value: Any, unit: str | None = None) -> str:
    """``4.436``, ``30.28 MPa``: a value with the unit of its name (or ``unit``), 4 digits."""
    if not _finite_number(value):
        return "–" if value is None else str(value)
    unit = unit if unit is not None else (unit_of(quantity.rpartition(".")[2]) or "")
    return f"{float(value):.4g}" + (f" {unit}" if unit else "")


def objective_text(name: str, value: float, metrics: Mapping[str, Any] | None = None) -> str:
    """``maximise free.min_advantage = 4.436``; a minimised one plainly,
    ``max_peak_stress_MPa = 21.66 MPa`` (minimising is what an objective does unless said)."""
    sense, quantity, shown = objective_view(name, value, metrics)
    said = "maximise " if sense == "maximise" else ""
    return f"{said}{quantity} = {physical_text(quantity, shown)}"


def constraint_quantities(
    constraint_names: Iterable[str], requirements: Iterable[Any]
) -> dict[str, tuple[str, str]]:
    """The physical quantity behind each requirement constraint: ``req_<label>`` → (quantity,
    unit) of the requirement labelled so (a curve requirement's value is its worst deviation,
    in its unit). Constraints of the kind itself (``stress_ratio_minus_1``) are left out: their
    name says what they are."""
    by_label = {getattr(r, "label", None): r for r in requirements}
    out: dict[str, tuple[str, str]] = {}
    for name in constraint_names:
        if not name.startswith("req_"):
            continue
        req = by_label.get(name[len("req_") :])
        if req is None:
            continue
        out[name] = (str(req.quantity), str(getattr(req, "unit", "") or ""))
    return out


def _short(value: float) -> str:
    import math

    return f"{value:.4g}" if math.isfinite(value) else str(value)


def _named(verdict: Any) -> str:
    """``jaw_force: blocked.end_jaw_force_N``; the quantity alone when it is the name."""
    if verdict.name == verdict.quantity:
        return str(verdict.quantity)
    return f"{verdict.name}: {verdict.quantity}"


def best_design_rows(
    variables: Sequence[str],
    objectives: Sequence[str],
    constraints: Sequence[str],
    best: Any,
    verdicts: Sequence[Any] = (),
) -> list[tuple[str, str, str]]:
    """The rows (what, name, value) of a best design's table, as the console and report.md
    show it: its variables; its objectives as the study states them (``maximise
    free.min_advantage`` = ``4.436``, not the negative the optimiser minimises, with the unit);
    its constraints as the physical value the requirement bounds, with the bound (``4.264 N
    (<= 10 N)``), and the normalised g only where no requirement stands behind it.

    Parameters
    ----------
    best : an optimise Evaluation (``x``, ``f``, ``g``, ``metrics``)
    verdicts : the design's verdicts (a ``req_<name>`` constraint is the requirement ``name``)
    """
    metrics = getattr(best, "metrics", None) or {}
    rows = [("variable", n, _short(float(v))) for n, v in zip(variables, best.x, strict=True)]
    for name, value in zip(objectives, best.f, strict=True):
        sense, quantity, shown = objective_view(name, float(value), metrics)
        rows.append(("objective", f"{sense} {quantity}", physical_text(quantity, shown)))
    judged = {v.name: v for v in verdicts}
    for name, value in zip(constraints, best.g, strict=True):
        v = judged.get(name.removeprefix("req_")) if name.startswith("req_") else None
        if v is not None:
            shown = f"{physical_text(v.quantity, v.value, v.unit)} ({v.bound})"
            rows.append(("constraint", _named(v), shown))
        else:
            rows.append(("constraint", name, _short(float(value))))
    return rows


def design_columns(
    objectives: Sequence[str], constraints: Sequence[str], verdicts: Sequence[Any] = ()
) -> tuple[list[str], Any]:
    """Headers and a row function for a table of designs (report.html's top 10) in physical
    values: each objective as the study states it (``maximise free.min_advantage``), each
    requirement constraint as the quantity it bounds with its unit (``actuator_force:
    free.end_input_force_N (N)``, read from the design's metrics), the normalised g only where
    no metric stands behind it.

    Returns
    -------
    headers : list of str
    row : callable (Evaluation) -> list of float or None
    """
    judged = {v.name: v for v in verdicts}
    headers: list[str] = []
    for name in objectives:
        sense, quantity, _ = objective_view(name, 0.0)
        unit = unit_of(quantity.rpartition(".")[2])
        headers.append(f"{sense} {quantity}" + (f" ({unit})" if unit else ""))
    quantities: list[str | None] = []
    for name in constraints:
        v = judged.get(name.removeprefix("req_")) if name.startswith("req_") else None
        if v is None:
            quantities.append(None)
            headers.append(f"{name} (g ≤ 0 is met)")
        else:
            quantities.append(v.quantity)
            headers.append(_named(v) + (f" ({v.unit})" if v.unit else ""))

    def number(value: Any) -> float | None:
        return float(value) if _finite_number(value) else None

    def row(ev: Any) -> list[float | None]:
        metrics = getattr(ev, "metrics", None) or {}
        out = [number(objective_view(n, float(f), metrics)[2])
               for n, f in zip(objectives, ev.f, strict=True)]  # fmt: skip
        for quantity, g in zip(quantities, ev.g, strict=True):
            value = metrics.get(quantity) if quantity is not None else None
            out.append(number(value) if _finite_number(value) else number(float(g)))
        return out

    return headers, row
