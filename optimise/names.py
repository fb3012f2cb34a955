"""The one rule for names a study gives: design variables, requirements, and a mechanism's beams,
bodies, load cases and outputs (docs/usage.md, "Names").

A name becomes a CSV column (evaluations.csv, history.csv, the response CSVs), a JSON key, a
label of report.md, report.html and the plots, a line on the terminal and, for a load case, part
of a file name. So it is held to a set that is safe in all of them:

- 1 to :data:`NAME_MAX_CHARS` characters;
- ASCII letters, digits, ``_``, ``-``, ``.``, ``[``, ``]``, ``*`` and inner spaces: no control
  character (no newline, tab or escape sequence), no comma, quote or other markup;
- first a letter, last not a space: never a leading ``=``, ``+``, ``-`` or ``@``, so no cell
  of a CSV file flexopt writes can be taken for a formula by a spreadsheet (the name rule
  refuses such names; no cell is rewritten).

The whole value must match (:func:`re.fullmatch`: ``"abc\\n"`` is refused; ``re.match`` with
``$`` accepts it, as ``$`` matches before a final newline). A kind may ask for less on top
(a mechanism's part and case names have no dots or spaces: they are joined with dots).
"""

from __future__ import annotations

import re

__all__ = ["NAME_MAX_CHARS", "NAME_RULE", "check_name", "name_problem"]

#: Longest name (characters): a column header or a legend entry stays readable.
NAME_MAX_CHARS = 64
#: The characters and shape of a name (the whole value must match: use ``fullmatch``).
NAME_RULE = re.compile(r"[A-Za-z](?:[A-Za-z0-9_.\-\[\]* ]*[A-Za-z0-9_.\-\[\]*])?")
#: What the rule says, for messages and docs.
NAME_RULE_TEXT = (
    f"1 to {NAME_MAX_CHARS} characters: ASCII letters, digits, '_', '-', '.', '[', ']', '*' "
    "and inner spaces, starting with a letter"
)


def _shown(value: str) -> str:
    """The value for a message: ``repr`` (control characters escaped), cut to 40 characters."""
    text = repr(value)
    return text if len(text) <= 40 else text[:39] + "…"


def name_problem(value: object) -> str | None:
    """What is wrong with ``value`` as a name (one phrase), or None when it obeys the rule."""
    if not isinstance(value, str):
        return f"{_shown(str(value))} is not text"
    if not value:
        return "an empty name"
    if len(value) > NAME_MAX_CHARS:
        return f"{_shown(value)} has {len(value)} characters (at most {NAME_MAX_CHARS})"
    if NAME_RULE.fullmatch(value) is None:
        bad = next((c for c in value if not re.fullmatch(r"[A-Za-z0-9_.\-\[\]* ]", c)), None)
        if bad is not None:
            return f"{_shown(value)} holds {_shown(bad)}"
        if not value[0].isalpha():
            return f"{_shown(value)} does not start with a letter"
        return f"{_shown(value)} ends with a space"
    return None


def check_name(value: str, what: str = "name") -> str:
    """``value`` when it obeys the name rule.

    Raises
    ------
    ValueError
        Naming what is wrong and the rule (pydantic turns it into the key path's one line).
    """
    problem = name_problem(value)
    if problem is not None:
        suggestion = re.sub(r"[^A-Za-z0-9_.-]+", "_", str(value)[:200]).strip("_.-")
        suggestion = re.sub(r"^[^A-Za-z]+", "", suggestion)[:NAME_MAX_CHARS] or "my_name"
        raise ValueError(f"{problem}: a {what} takes {NAME_RULE_TEXT}, e.g. '{suggestion}'")
    return value
