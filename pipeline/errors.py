"""Exception family of the pipeline package."""

from __future__ import annotations

__all__ = ["StudyError"]


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
        self.problem = " ".join(problem.split())  # the CLI promises one line
        self.source = source
        super().__init__(self.problem)

    def __str__(self) -> str:
        return ": ".join(part for part in (self.source, self.path, self.problem) if part)
