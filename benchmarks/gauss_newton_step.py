"""The Gauss-Newton step's QP, SLSQP against the exact solve, on the steps of a real run
(session 34, docs/constant_force.md "Each step's QP solved exactly").

    python benchmarks/gauss_newton_step.py [--study constant-force] [--repeat 3]

Runs ``flexopt run STUDY -q`` once in this process (into a temporary folder) and captures every
Gauss-Newton step problem its gradient stage solves (``optimise.hybrid._gauss_newton_step``'s
arguments), then solves each again with SLSQP (``exact=False``) and with the exact solve
(``exact=True``; SLSQP's elastic problem where the rows cannot be met) and prints: the steps,
how many the exact solve handed to the elastic fallback, each solver's time for all of them
(median of ``--repeat``, wall s, this process), the model objective ``||r + J d||^2 / ||r||^2``
of each solver's step (the ratio SLSQP / exact: its median and largest), and each solver's worst
linearised-row value past its aim, ``max(g + Jg d) + backoff + 1e-8`` (> 0: outside the row it
aimed inside), over the steps whose rows can be met.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--study", default="constant-force")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    import flexopt.optimise.hybrid as hybrid
    from flexopt.pipeline.cli import main as cli

    captured: list[tuple[tuple, dict]] = []
    solve = hybrid._gauss_newton_step

    def capturing(*a: object, **k: object) -> np.ndarray:
        captured.append((a, dict(k)))
        return solve(*a, **k)

    hybrid._gauss_newton_step = capturing
    with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(io.StringIO()):
        try:
            cli(["run", args.study, "-q", "--out", str(Path(tmp) / "run")])
        except SystemExit:
            pass
    hybrid._gauss_newton_step = solve
    print(f"{args.study}: {len(captured)} steps captured; load {os.getloadavg()[0]:.2f}")

    def problem(a: tuple, k: dict) -> dict:
        names = ("r", "J", "g", "Jg", "lower", "upper", "backoff", "pieces", "broken", "exact")
        given = dict(zip(names, a, strict=False))
        given.update(k)
        given.pop("exact", None)
        return given

    problems = [problem(a, k) for a, k in captured]
    steps: dict[bool, list[np.ndarray]] = {}
    times: dict[bool, float] = {}
    for exact in (False, True):
        walls = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            out = [solve(**p, exact=exact) for p in problems]
            walls.append(time.perf_counter() - t0)
        steps[exact], times[exact] = out, statistics.median(walls)
    feasible = [
        hybrid._exact_step(p["r"], p["J"], *_rows(hybrid, p), p["lower"], p["upper"]) is not None
        for p in problems
    ]
    fallbacks = feasible.count(False)

    def model(p: dict, d: np.ndarray) -> float:
        e = p["r"] + p["J"] @ d
        return float(e @ e) / float(p["r"] @ p["r"])

    def outside(p: dict, d: np.ndarray) -> float:
        grads, aim = _rows(hybrid, p)
        return float(np.max(grads @ d - aim)) if len(aim) else -np.inf

    ratio = [
        model(p, a) / max(model(p, b), 1e-300)
        for p, a, b in zip(problems, steps[False], steps[True], strict=True)
    ]
    print(f"  exact solve handed {fallbacks} of {len(problems)} to SLSQP's elastic problem")
    for exact, label in ((False, "SLSQP"), (True, "exact")):
        worst = max(
            outside(p, d)
            for p, d, ok in zip(problems, steps[exact], feasible, strict=True)
            if ok  # the elastic problems pay for what they cannot meet
        )
        print(
            f"  {label:5s}: {times[exact]:.3f} s for all ({times[exact] / len(problems) * 1e3:.2f}"
            f" ms a step); worst row value past its aim {worst:.2e}"
        )
    print(
        f"  model objective SLSQP / exact: median {statistics.median(ratio):.4f}, "
        f"largest {max(ratio):.3g}"
    )


def _rows(hybrid: object, p: dict) -> tuple[np.ndarray, np.ndarray]:
    """The step's linearised rows as :func:`optimise.hybrid._gauss_newton_step` builds them:
    ``grads d <= aim`` (grads (k, n_var), aim (k,))."""
    values, grads, owner = hybrid._linear_rows(p["g"], p["Jg"], p.get("pieces"))
    g, backoff, broken = p["g"], p["backoff"], p.get("broken")
    limit = -backoff - hybrid.FEASIBILITY_MARGIN
    clamp = g <= 0.0 if broken is None else (g <= 0.0) & ~broken
    limit = np.where(clamp, np.maximum(limit, g), limit)
    return grads, limit[owner] - values


if __name__ == "__main__":
    sys.exit(main())
