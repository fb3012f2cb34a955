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
from collections.abc import Iterable, Mapping
from typing import Any

__all__ = [
    "NAMES",
    "UNITS",
    "VARIABLES",
    "WORDS",
    "label",
    "split_name",
    "unit_of",
    "variable_meanings",
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
    "min": "minimum",
    "avg": "mean",
    "fe": "FE",
    "prb": "PRB",
    "sab": "SAB",
    "cam": "cam",
    "virtual": "virtual",
    "nmm": "N·mm",
}

#: Design variables with a meaning of their own, by study kind (the kind's ``variable_meanings``
#: attribute, when it has one, wins).
VARIABLES: dict[str, dict[str, str]] = {
    "constant_force": {
        **{
            f"a{j}": (
                f"where p{j} sits between S{(j + 1) // 2} and S{(j + 1) // 2 + 1} "
                f"(0 at S{(j + 1) // 2}, 1 at S{(j + 1) // 2 + 1}; fraction, –)"
            )
            for j in range(1, 11)
        },
        **{f"t{j}_mm": f"in-plane thickness of the beam at p{j} (mm)" for j in range(1, 11)},
        **{f"t{j}": f"in-plane thickness of the beam at p{j} (mm)" for j in range(1, 11)},
        "T1_mm": "thickness at the clamped end S1 (mm)",
        "T6_mm": "thickness at the driven end S6 (mm)",
        "T1": "thickness at the clamped end S1 (mm)",
        "T6": "thickness at the driven end S6 (mm)",
        "B_mm": "out-of-plane width of the part (mm)",
        "B": "out-of-plane width of the part (mm)",
    },
}

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


def words(name: str) -> str:
    """The words of a name without its unit: ``torque_Nm_sliding_l28`` → ``torque, sliding,
    l = 28 mm``."""
    if name in NAMES:
        return re.sub(r"\s*\([^()]*\)$", "", NAMES[name])
    quantity, _, qualifier = split_name(name)
    text = " ".join(_token_words(t) for t in quantity) or str(name)
    if qualifier:
        text += ", " + " ".join(_token_words(t) for t in qualifier).replace(" l = ", ", l = ")
    return text


def unit_of(name: str) -> str | None:
    """The unit of a name as written (``N·m``), or None when it has none."""
    return split_name(name)[1]


def label(name: str, given: str | None = None) -> str:
    """Words with the unit in brackets: ``torque_Nm_sliding_l28`` → ``torque, sliding, l = 28 mm
    (N·m)``; ``given`` (a label the study kind chose) wins."""
    if given:
        return given
    if name in NAMES:
        return NAMES[name]
    unit = unit_of(name)
    return f"{words(name)} ({unit})" if unit else words(name)


def variable_meanings(kind: str, names: Iterable[str], problem: Any = None) -> dict[str, str]:
    """What each design variable means: the problem's ``variable_meanings`` mapping, else
    :data:`VARIABLES` of the kind, else the variable's label (its words and unit)."""
    own = getattr(problem, "variable_meanings", None)
    table: Mapping[str, str] = own if isinstance(own, Mapping) else VARIABLES.get(kind, {})
    return {n: str(table[n]) if n in table else label(n) for n in names}
