"""``report.md`` of a run folder: a short Markdown report built from plain data (no I/O here).

Everything the study kind puts in ``DesignDetail.info`` that a person can read in a table shows:
scalars as rows, short lists inline, lists of text as bullets, mappings of scalars and lists of
records as tables, columns of equal length as a table; a large array is named with its shape and
left to ``best.json``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import DesignDetail, DesignProblem
from flexopt.optimise.requirements import Verdict, overall, verdict_rows
from flexopt.pipeline.runfolder import grouped_files
from flexopt.pipeline.study import Study

__all__ = ["ReportData", "format_value", "render_info", "render_report", "render_verdict"]

#: Tables from ``info`` longer than this are left to best.json (a report is read, not parsed).
MAX_TABLE_ROWS = 60
#: A list of numbers up to this long is shown inline in one cell.
MAX_INLINE_ITEMS = 12
#: Nested mappings deeper than this are summarised.
MAX_DEPTH = 3

_PLOTS = (
    ("force_displacement.png", "Force–displacement of the best design"),
    ("stress.png", "Peak stress along the stroke (the line: the allowable the verdict uses)"),
    ("outputs.png", "The study's outputs in every load case (one axis per unit)"),
    ("deformed_shapes.png", "Deformed shapes in every load case"),
    ("shapes.png", "Deformed shapes"),
    ("stress_map.png", "Stress map of the best design"),
    ("stress_deformed.png", "Von Mises stress on the deformed part of the best design"),
    ("front.png", "Pareto front"),
    ("taguchi.png", "Taguchi stage: main effects and contributions"),
    ("convergence.png", "Convergence"),
)


@dataclass(frozen=True)
class ReportData:
    """What the report shows.

    Attributes
    ----------
    record : the run.json record (settings, timing, counts, versions).
    study : the resolved study.
    problem : the design problem (names of variables, objectives, constraints).
    best : the best evaluation; ``best_where`` its (generation, index) in evaluations.csv.
    front : non-dominated designs (more than one only for several objectives).
    detail : the best design's detail, or None when it failed.
    files : files written to the run folder; ``notes`` what was skipped and why.
    stl : facts about best.stl (volume_mm3, triangles, size_mm), empty when not written.
    verdicts : the best design against the study's requirements (default: ``detail.verdicts``);
        report.md opens with them.
    """

    record: Mapping[str, Any]
    study: Study
    problem: DesignProblem
    best: Evaluation
    best_where: tuple[int | None, int | None] = (None, None)
    front: tuple[Evaluation, ...] = ()
    detail: DesignDetail | None = None
    files: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    stl: Mapping[str, Any] = field(default_factory=dict)
    verdicts: tuple[Verdict, ...] = ()


def _escape(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def format_value(value: Any) -> str:
    """One cell: 6 significant digits, yes/no, ``–`` for None, short lists inline."""
    if isinstance(value, np.generic):
        value = value.item()
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            return str(value)
        return f"{value:.6g}"
    if isinstance(value, list | tuple | np.ndarray):
        return (
            "[" + ", ".join(format_value(v) for v in np.asarray(value, dtype=object).ravel()) + "]"
        )
    return _escape(str(value))


def _is_scalar(value: Any) -> bool:
    return value is None or isinstance(value, bool | int | float | str | np.generic)


def _is_short_list(value: Any) -> bool:
    if isinstance(value, np.ndarray):
        return value.ndim == 1 and value.size <= MAX_INLINE_ITEMS
    return (
        isinstance(value, list | tuple)
        and len(value) <= MAX_INLINE_ITEMS
        and all(_is_scalar(v) and not isinstance(v, str) for v in value)
    )


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    lines = ["| " + " | ".join(_escape(h) for h in header) + " |"]
    lines.append("|" + "|".join("---" for _ in header) + "|")
    for row in rows:
        lines.append("| " + " | ".join(format_value(v) for v in row) + " |")
    return lines + [""]


def _columns_table(value: Mapping[str, Any]) -> list[str] | None:
    """A mapping of equal-length 1-D columns as a table, or None if it is not one."""
    columns = {}
    for key, col in value.items():
        if isinstance(col, str) or not isinstance(col, list | tuple | np.ndarray):
            return None
        arr = np.asarray(col, dtype=object)
        if arr.ndim != 1:
            return None
        columns[str(key)] = arr
    lengths = {len(c) for c in columns.values()}
    if len(lengths) != 1 or not 0 < lengths.pop() <= MAX_TABLE_ROWS:
        return None
    return _table(list(columns), list(zip(*columns.values(), strict=True)))


def _records_table(value: Sequence[Any]) -> list[str] | None:
    """A list of flat mappings as a table, or None if it is not one."""
    if not value or len(value) > MAX_TABLE_ROWS:
        return None
    if not all(isinstance(r, Mapping) for r in value):
        return None
    header: list[str] = []
    for record in value:
        for key in record:
            if str(key) not in header:
                header.append(str(key))
    if not all(_is_scalar(v) or _is_short_list(v) for r in value for v in r.values()):
        return None
    return _table(header, [[r.get(k) for k in header] for r in value])


def _array_table(value: np.ndarray) -> list[str] | None:
    if value.ndim != 2 or not 0 < len(value) <= MAX_TABLE_ROWS or value.shape[1] > 12:
        return None
    return _table(["row", *map(str, range(value.shape[1]))], [[i, *r] for i, r in enumerate(value)])


def _parallel_columns(info: Mapping[str, Any]) -> dict[str, list[Any]]:
    """The lists of numbers in ``info`` that share the most common length (at least two lists of
    3 … MAX_TABLE_ROWS items): values at the same points (``stroke_mm``, ``force_N``, …). Pairs
    are left inline: they are usually ranges (``band_N: [1.47, 1.53]``), not columns."""
    lists = {
        str(k): list(np.asarray(v, dtype=object).ravel())
        for k, v in info.items()
        if isinstance(v, list | tuple | np.ndarray)
        and np.ndim(v) == 1
        and 3 <= len(v) <= MAX_TABLE_ROWS
        and all(_is_scalar(x) and not isinstance(x, str) for x in v)
    }
    lengths = [len(v) for v in lists.values()]
    if not lengths:
        return {}
    common = max(set(lengths), key=lengths.count)
    if lengths.count(common) < 2:
        return {}
    return {k: v for k, v in lists.items() if len(v) == common}


def render_info(info: Mapping[str, Any], level: int = 3) -> list[str]:
    """Markdown lines for the ``info`` a study kind reports.

    Scalars and short lists of numbers go in one key/value table first, lists of numbers of the
    same length side by side in a second table; then, under a heading of
    their key, long texts as paragraphs, lists of text as bullets, mappings recursively (up to
    :data:`MAX_DEPTH` levels), columns or records as tables. Anything else (a large array, an
    object) is named with its type or shape.
    """
    lines: list[str] = []
    columns = _parallel_columns(info)
    simple = [
        (k, v)
        for k, v in info.items()
        if k not in columns
        and ((_is_scalar(v) and not (isinstance(v, str) and len(v) > 80)) or _is_short_list(v))
    ]
    if simple:
        lines += _table(["item", "value"], simple)
    if columns:
        lines += _table(list(columns), list(zip(*columns.values(), strict=True)))
    shown = {k for k, _ in simple} | set(columns)
    omitted: list[str] = []
    heading = "#" * min(level, 6)
    for key, value in info.items():
        if key in shown:
            continue
        title = f"{heading} {_escape(str(key))}"
        if isinstance(value, str):
            lines += [title, "", value.strip(), ""]
        elif isinstance(value, list | tuple) and value and all(isinstance(v, str) for v in value):
            lines += [title, "", *(f"- {_escape(v)}" for v in value), ""]
        elif isinstance(value, Mapping):
            table = _columns_table(value)
            if table is not None:
                lines += [title, "", *table]
            elif level - 2 < MAX_DEPTH:
                lines += [title, "", *render_info(value, level + 1)]
            else:
                omitted.append(f"`{key}` (nested mapping, see best.json)")
        elif isinstance(value, list | tuple) and (table := _records_table(value)) is not None:
            lines += [title, "", *table]
        elif isinstance(value, np.ndarray) and (table := _array_table(value)) is not None:
            lines += [title, "", *table]
        elif isinstance(value, np.ndarray | list | tuple):
            shape = np.shape(value) if not isinstance(value, np.ndarray) else value.shape
            omitted.append(f"`{key}` (array of shape {tuple(shape)}, see best.json)")
        else:
            omitted.append(f"`{key}` ({type(value).__name__})")
    if omitted:
        lines += ["Not shown: " + ", ".join(omitted) + ".", ""]
    return lines


def _seconds(value: Any) -> str:
    if value is None:
        return "–"
    value = float(value)
    if value < 120:
        return f"{value:.3g} s"
    return f"{value:.0f} s ({value / 60:.1f} min)"


def _backend(record: Mapping[str, Any]) -> str:
    """How the designs were evaluated, as run.json records it (``processes (2 workers)``)."""
    parallel = record.get("parallel") or {}
    return str(parallel.get("description") or parallel.get("backend") or "not recorded")


def _rate(value: Any) -> str:
    return "–" if value is None else f"{float(value):.3g}"


def render_verdict(verdicts: Sequence[Verdict]) -> list[str]:
    """The ``## Verdict`` section: the overall word, then one row per requirement."""
    met = sum(v.met for v in verdicts)
    lines = [
        "## Verdict",
        "",
        f"**{overall(verdicts)}** — {met} of {len(verdicts)} requirements met by the best design.",
        "",
    ]
    if verdicts:
        rows = [[*row[:4], f"**{row[4]}**" if not v.met else row[4]]
                for v, row in zip(verdicts, verdict_rows(verdicts), strict=True)]  # fmt: skip
        lines += ["| requirement | value | bound | margin | verdict |", "|---|---|---|---|---|"]
        lines += ["| " + " | ".join(_escape(c) for c in row) + " |" for row in rows]
        lines += [""]
        lines += [f"- {_escape(v.name)}: {_escape(v.detail)}" for v in verdicts
                  if not v.met and v.detail]  # fmt: skip
        if any(not v.met and v.detail for v in verdicts):
            lines += [""]
    else:
        lines += ["No requirement was stated, so nothing is claimed.", ""]
    return lines


def _load_cases(detail: DesignDetail | None) -> list[str]:
    """A table per load case: the drive, its reaction, the peak stress and every output of the
    case (unit, start, end, smallest, largest over the converged rows)."""
    from flexopt.pipeline.responses import case_rows

    cases = detail.cases if detail is not None else {}
    if not cases:
        return []
    lines = ["### Load cases", "", "Every load case of the best design (converged rows); "
             "the curves are in the plots below and in best_response.csv.", ""]  # fmt: skip
    header = ["column", "", "unit", "start", "end", "smallest", "largest"]
    for name, case in cases.items():
        lines += [f"#### {name}", ""]
        lines += _table(header, [list(row) for row in case_rows(case)])
    return lines


def _checks_row(record: Mapping[str, Any]) -> list[list[Any]]:
    """The hybrid's checks of its designs by the verdict's own figures (optimise/hybrid.py,
    ``run.json`` ``hybrid.checks``): one row where the run made any, else none."""
    checks = (record.get("hybrid") or {}).get("checks")
    if not checks:
        return []
    count = checks.get("count")
    spared = checks.get("spared") or 0
    text = f"{count} design{'' if count == 1 else 's'} ({checks.get('met')} met), "
    text += _seconds(checks.get("time_s"))
    if spared:  # a start whose best was above a design already checked and met
        text += f"; {spared} start{'' if spared == 1 else 's'} not checked (a lower design was met)"
    return [["of which checks of the verdict's figures (hybrid)", text]]


def render_report(data: ReportData) -> str:
    """The Markdown text of report.md (plots linked relative to the run folder)."""
    record, problem, best = data.record, data.problem, data.best
    study = data.study
    lines = [f"# {study.name} — flexopt run", ""]
    verdicts = data.verdicts or (data.detail.verdicts if data.detail is not None else ())
    lines += render_verdict(verdicts)  # the verdict first: what a reader asks first
    if "report.html" in data.files:
        lines += [
            "Explore every evaluated design (parallel coordinates, scatter matrix, sensitivities, "
            "top 10, the part in 3D) in [report.html](report.html), one file that opens offline.",
            "",
        ]
    status = record.get("status", "")
    lines += _table(
        ["", ""],
        [
            ["study", f"{study.name} (kind `{study.kind}`)"],
            ["study file", record.get("source") or "–"],
            ["command", f"`{record['command_line']}`" if record.get("command_line") else "–"],
            ["started", record.get("started")],
            ["finished", f"{record.get('finished')} ({status})"],
        ],
    )

    opt = record.get("optimiser", {})
    lines += ["## Settings", ""]
    lines += _table(
        ["algorithm", "pop_size", "n_gen", "seed", "quick"],
        [
            [
                opt.get("algorithm"),
                opt.get("pop_size"),
                opt.get("n_gen"),
                opt.get("seed"),
                bool(record.get("quick")),
            ]
        ],
    )
    from flexopt.pipeline.labels import MAXIMISED, best_design_rows, objective_view

    def stated(name: str) -> str:  # a maximised objective as the study states it
        sense, quantity, _ = objective_view(name, 0.0)
        minimised = f" (the optimiser minimises `{name}`)" if name.startswith(MAXIMISED) else ""
        return f"{sense} `{quantity}`{minimised}"

    lines += [
        f"Design variables: {len(problem.space.names)}; objectives: "
        + ", ".join(stated(n) for n in problem.objective_names)
        + "; constraints (feasible when ≤ 0): "
        + (", ".join(f"`{n}`" for n in problem.constraint_names) or "none")
        + ".",
        "",
    ]

    from flexopt.pipeline.labels import variable_rows

    lines += ["## Design variables", ""]
    lines += _table(
        ["variable", "meaning", "unit", "bounds", "best value"],
        variable_rows(study.kind, problem, best.x),
    )

    generation, index = data.best_where
    lines += ["## Best design", ""]
    where = (
        f"Found in generation {generation} (evaluation {index} in evaluations.csv)."
        if index is not None
        else "Found in the run."
    )
    verdict = "met" if best.feasible else "**not met**"
    lines += [
        f"{where} The optimiser's constraints are {verdict} (feasible: "
        f"{format_value(best.feasible)}); whether the design meets its requirements is the "
        "verdict above."
    ]
    if best.reason:
        lines += [f"Reason: {_escape(best.reason)}"]
    if not best.feasible:
        lines += [
            "",
            "No design met every constraint; this is the one that violates them least. "
            "Widen the design space, relax the constraints or run longer.",
        ]
    lines += [""]
    # objectives as the study states them (maximised ones too), constraints as the physical
    # value their requirement bounds, with the bound
    rows = best_design_rows(
        problem.space.names, problem.objective_names, problem.constraint_names, best, verdicts
    )
    lines += _table(["", "name", "value"], [list(row) for row in rows])
    bounds_hit = [
        n
        for n, v, lo, hi in zip(
            problem.space.names, best.x, problem.space.lower, problem.space.upper, strict=True
        )
        if np.isclose(v, lo, rtol=0, atol=1e-6 * (hi - lo))
        or np.isclose(v, hi, rtol=0, atol=1e-6 * (hi - lo))
    ]
    if bounds_hit:
        lines += [
            "At a bound of the design space: "
            + ", ".join(f"`{n}`" for n in bounds_hit)
            + " (the optimum may lie outside; consider widening).",
            "",
        ]
    if best.metrics:
        lines += ["### Metrics", ""]
        lines += render_info(best.metrics, level=4)
    if len(data.front) > 1:
        lines += [f"### Pareto front ({len(data.front)} designs, see best.json)", ""]
        lines += _table(
            [" ".join(objective_view(n, 0.0)[:2]) for n in problem.objective_names],
            [
                [
                    objective_view(n, float(v), ev.metrics)[2]
                    for n, v in zip(problem.objective_names, ev.f, strict=True)
                ]  # fmt: skip
                for ev in data.front[:MAX_TABLE_ROWS]
            ],
        )
    from flexopt.pipeline.sensitivity_report import sensitivity_markdown

    lines += sensitivity_markdown(problem, best)  # d f / d x at the best, x range
    lines += _load_cases(data.detail)
    if data.detail is not None:  # the study's duty_cycle, hold and stops: life, creep, contact
        from flexopt.pipeline.durability_report import durability_markdown, durability_record

        lines += durability_markdown(durability_record(study, data.detail))

    plots = [(name, caption) for name, caption in _PLOTS if name in data.files]
    if plots:
        lines += ["## Plots", ""]
        for name, caption in plots:
            lines += [f"### {caption}", "", f"![{caption}]({name})", ""]

    if record.get("robustness"):  # the chosen design under the study's scatter
        from flexopt.pipeline.robustness import robustness_markdown

        png = "robustness.png" if "robustness.png" in data.files else None
        lines += [*robustness_markdown(record["robustness"], png).splitlines(), ""]

    n = record.get("n_evaluations") or 0
    n_failed = record.get("n_failed") or 0
    n_feasible = record.get("n_feasible") or 0
    lines += ["## Performance", ""]
    lines += _table(
        ["", ""],
        [
            ["designs solved", n],
            ["served from the cache (repeats)", record.get("n_cache_hits")],
            ["generations", record.get("generations_done")],
            ["feasible", f"{n_feasible} ({100 * n_feasible / n:.0f} %)" if n else "–"],
            ["failed (see reasons)", n_failed],
            ["wall time", _seconds(record.get("wall_s"))],
            ["of which optimisation", _seconds(record.get("optimise_wall_s"))],
            *_checks_row(record),
            ["evaluations per second", _rate(record.get("evaluations_per_s"))],
            ["mean time per evaluation", _seconds(record.get("mean_evaluation_s"))],
            ["machine", f"{record.get('host', {}).get('cpu_count')} CPUs"],
            ["evaluation backend", _backend(record)],
        ],
    )
    reasons = record.get("failure_reasons") or {}
    if reasons:
        lines += ["Most frequent failure reasons:", ""]
        lines += _table(["designs", "reason"], [[k, r] for r, k in reasons.items()])

    if data.detail is not None and data.detail.info:
        lines += ["## From the study kind", ""]
        lines += render_info(data.detail.info, level=3)

    if data.stl:
        size = data.stl.get("size_mm", [])
        lines += [
            "## Printable part",
            "",
            f"[best.stl](best.stl): {data.stl.get('triangles')} triangles, volume "
            f"{format_value(data.stl.get('volume_mm3'))} mm³, size "
            + " × ".join(f"{v:.4g}" for v in size)
            + " mm (extruded outline lying flat; watertight: "
            + format_value(data.stl.get("watertight"))
            + ").",
            "",
        ]

    if data.notes:
        lines += ["## Notes", "", *(f"- {_escape(note)}" for note in data.notes), ""]

    lines += ["## Files", ""]
    listed = grouped_files(data.files)[0]  # best_steps/ once, not a line per load step
    for name in sorted(set(listed) | {"study.yaml", "run.json", "evaluations.csv"}):
        lines.append(f"- [{name}]({name})")
    versions = record.get("versions", {})
    lines += [
        "",
        "Versions: " + ", ".join(f"{k} {v}" for k, v in versions.items() if v) + ".",
        "",
    ]
    return "\n".join(lines)
