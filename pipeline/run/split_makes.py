"""A group of result files made by two forked children instead of one (issue 27 item 4).

The run's PNG plots (six for constant-force, ~1.3 s CPU in all, the convergence plot ~0.4 s of
it) were made one after the other in one child while this process writes report.html (~0.6 s):
the child was the report's critical path. Two children, each with every other file, finish in
about half that on a machine with a core free; the files come back in the order they were
queued, so the run folder and its file lists are the same.
"""

from __future__ import annotations

from collections.abc import Callable

from flexopt.pipeline.fork import ForkedMakes

#: a group of this many files or more is made by two children
SPLIT_GROUP_AT = 4

Make = Callable[[], str | bytes | None]


class SplitMakes:
    """:class:`pipeline.fork.ForkedMakes` of every other item, twice; :meth:`results` in the
    items' order. Each half falls back to this process as ForkedMakes does."""

    def __init__(self, items: list[tuple[str, Make]]) -> None:
        self.items = items
        self.halves = [ForkedMakes(items[0::2]), ForkedMakes(items[1::2])]

    def results(self) -> list[tuple[str, str | bytes | None, str | None]]:
        first, second = (half.results() for half in self.halves)
        merged: list[tuple[str, str | bytes | None, str | None]] = []
        for i in range(
            len(self.items)
        ):  # back in the queued order: 0, 1, 2, ... from 0, 2, 4 | 1, 3
            merged.append(first[i // 2] if i % 2 == 0 else second[i // 2])
        return merged


Result = tuple[str, str | bytes | None, str | None]


def forked(items: list[tuple[str, Make]]) -> ForkedMakes | SplitMakes:
    """The children for a group: two (:class:`SplitMakes`) from :data:`SPLIT_GROUP_AT` files,
    else one (:class:`pipeline.fork.ForkedMakes`)."""
    return SplitMakes(items) if len(items) >= SPLIT_GROUP_AT else ForkedMakes(items)


class WithEarly:
    """A group of files of which some were started earlier in children of their own (``early``:
    name -> the job making it, e.g. convergence.png, started before the best design's detail
    because it needs only the run's history); the rest are started now (:func:`forked`).
    :meth:`results` gives every file in the group's queued order, as one job would have."""

    def __init__(self, items: list[tuple[str, Make]], early: dict[str, ForkedMakes]) -> None:
        self.names = [name for name, _ in items]
        rest = [(name, make) for name, make in items if name not in early]
        self.early = early
        self.rest = forked(rest) if rest else None

    def results(self) -> list[Result]:
        made: dict[str, Result] = {}
        for job in [*self.early.values(), *([self.rest] if self.rest is not None else [])]:
            for row in job.results():
                made[row[0]] = row
        return [made[name] for name in self.names]
