"""Exception family of the pipeline package."""

from __future__ import annotations

__all__ = ["MAX_PROBLEM_CHARS", "StudyError", "Terminated"]

#: Longest problem text of one error: echoed values are cut at their source to ~60 characters,
#: and this is the safety net for any that are not (the start and the fix at the end are kept).
MAX_PROBLEM_CHARS = 600


class StudyError(ValueError):
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
        self.path = path
        if len(problem) > 2 * MAX_PROBLEM_CHARS:  # bound the work of split() on a huge echo
            problem = problem[:MAX_PROBLEM_CHARS] + " ... " + problem[-200:]
        problem = " ".join(problem.split())  # the CLI promises one line
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
