"""Exception family of the pipeline package (under :class:`FlexoptError`, the root of all)."""

from __future__ import annotations

import re

from flexopt.geometry.errors import FlexoptError

__all__ = [
    "MAX_PROBLEM_CHARS",
    "FlexoptError",
    "MAX_REASON_CHARS",
    "StudyError",
    "Terminated",
    "one_line",
    "printable",
]

#: Characters never printed as they are: C0 controls (escape sequences start with ESC), DEL, C1
#: controls, and the bidirectional and zero-width formatting characters that make a line read
#: otherwise than it is (docs/usage.md, "Names").
_UNPRINTABLE = re.compile(
    "[\x00-\x1f\x7f-\x9f\u200b-\u200f\u2028\u2029\u202a-\u202e\u2060-\u2064\u2066-\u2069\ufeff]"
)


def _escaped(match: re.Match[str]) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def printable(text: object, keep_newlines: bool = False) -> str:
    """``str(text)`` with every control and formatting character written as an escape
    (``\\x1b``, ``\\u202e``): text from a study, a run folder or a plugin cannot move the
    cursor, retitle or clear the terminal, or hide part of a line. The one helper of every
    message flexopt prints; ``keep_newlines`` keeps ``\\n`` (a text of several lines)."""
    value = str(text)
    if keep_newlines:
        return "\n".join(_UNPRINTABLE.sub(_escaped, line) for line in value.split("\n"))
    return _UNPRINTABLE.sub(_escaped, value)


#: Longest failure reason kept in a row (exception messages can quote whole arrays).
MAX_REASON_CHARS = 300


def one_line(text: str) -> str:
    """``text`` folded to one line of at most :data:`MAX_REASON_CHARS` characters."""
    text = " ".join(text.split())
    return text if len(text) <= MAX_REASON_CHARS else text[: MAX_REASON_CHARS - 3] + "..."


#: Longest problem text of one error: echoed values are cut at their source to ~60 characters,
#: and this is the safety net for any that are not (the start and the fix at the end are kept).
MAX_PROBLEM_CHARS = 600


class StudyError(FlexoptError, ValueError):
    """A study file cannot be read or describes something flexopt cannot evaluate.

    Parameters
    ----------
    path : str
        Where the problem is: a YAML key path such as ``geometry.thickness_mm`` (list items as
        ``[i]``); empty when the file as a whole is unusable.
    problem : str
        What is wrong and how to fix it (folded to one line).
    source : str, optional
        The study file, when there is one.
    """

    def __init__(self, path: str, problem: str, source: str | None = None) -> None:
        # One line with no control character from the input (an unknown key made of escape
        # bytes is echoed escaped, a key of 200 000 characters cut).
        path = printable(" ".join(str(path)[: 2 * MAX_PROBLEM_CHARS].split()))
        if len(path) > 200:
            path = path[:150] + "…" + path[-40:]
        self.path = path
        problem = str(problem)
        if len(problem) > 2 * MAX_PROBLEM_CHARS:  # bound the work of split() on a huge echo
            problem = problem[:MAX_PROBLEM_CHARS] + " ... " + problem[-200:]
        problem = printable(" ".join(problem.split()))  # the CLI promises one line
        source = None if source is None else printable(source)
        if len(problem) > MAX_PROBLEM_CHARS:  # an echoed value must not flood the terminal
            problem = problem[: MAX_PROBLEM_CHARS - 205] + " ... " + problem[-200:]
        self.problem = problem
        self.source = source
        super().__init__(self.problem)

    def __str__(self) -> str:
        return ": ".join(part for part in (self.source, self.path, self.problem) if part)


class Terminated(KeyboardInterrupt):
    """SIGTERM reached ``flexopt`` (a scheduler's stop, ``kill PID``): end the run as Ctrl-C does.

    A :class:`KeyboardInterrupt`, so every ``except KeyboardInterrupt`` that saves work on
    Ctrl-C saves it here too; a run folder records status ``stopped`` instead of ``interrupted``.
    """
