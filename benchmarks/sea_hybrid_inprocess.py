"""The SEA spring's hybrid (issue 27 items 2-3) in one process: the study's problem after stage 1,
its first objective (the peak stress, :class:`optimise.first_objective.FirstObjective`), the GA's
one generation and the trust-region Gauss-Newton (or SLSQP) stage on the exact Jacobian, serial,
one BLAS thread; no runner, no report. Prints per seed the designs, the best design's peak stress,
mass, ST and feasibility, each start's outcome and the CPU time of the optimisation (designs and
Jacobians; stage 1 excluded), and the load average.

    nice python benchmarks/sea_hybrid_inprocess.py                    # seeds 1 2 3, Gauss-Newton
    nice python benchmarks/sea_hybrid_inprocess.py --local slsqp --seeds 1
    nice python benchmarks/sea_hybrid_inprocess.py --max-evaluations 44 --patience 3

``benchmarks/hybrid.py --studies sea-spring`` runs the whole ``flexopt run`` (report and 3D
checks included) against NSGA-II instead.
"""

from __future__ import annotations

import argparse
import datetime
import os
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    parser.add_argument("--pop-size", type=int, default=16)
    parser.add_argument("--ga-n-gen", type=int, default=1)
    parser.add_argument("--starts", type=int, default=2)
    parser.add_argument("--local", choices=("gauss_newton", "slsqp"), default="gauss_newton")
    parser.add_argument("--max-evaluations", type=int, default=None)
    parser.add_argument("--patience", type=int, default=6, help="the study's default: 6")
    args = parser.parse_args()

    from flexopt.optimise.first_objective import FirstObjective
    from flexopt.optimise.ga import GAConfig
    from flexopt.optimise.hybrid import HybridConfig, run_hybrid
    from flexopt.pipeline.run import prepare_run
    from flexopt.pipeline.screening import one_blas_thread
    from flexopt.pipeline.study import load_study

    print(f"date      {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC")
    print(f"load avg  {' '.join(f'{v:.2f}' for v in os.getloadavg())} at start")
    print(f"settings  {vars(args)}")
    study = load_study(ROOT / "pipeline" / "examples" / "sea-spring.yaml")
    setup = prepare_run(study)
    inner = setup.problem
    _ = inner.stage1  # stage 1 once, outside the timings
    problem = FirstObjective(inner)
    if args.local == "gauss_newton":
        problem = problem.with_residuals()
    for seed in args.seeds:
        config = HybridConfig(
            GAConfig("ga", args.pop_size, 16, seed),
            args.ga_n_gen,
            args.local,
            args.starts,
            patience=args.patience,
            max_evaluations=args.max_evaluations,
        )
        cpu0, wall0 = time.process_time(), time.perf_counter()
        with one_blas_thread():
            result = run_hybrid(
                problem.space,
                lambda X: [problem.evaluate(x) for x in X],
                1,
                len(problem.constraint_names),
                config,
                initial=setup.initial,
                jacobian=problem.jacobian,
            )
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
        best, report = result.best, result.report
        print(
            f"seed {seed}: designs {sum(report['n_evaluations'].values())} "
            f"{report['n_evaluations']}, best {best.f[0]:.2f} MPa "
            f"{'feasible' if best.feasible else 'INFEASIBLE'}, mass "
            f"{best.metrics.get('mass_g', float('nan')):.1f} g, ST "
            f"{best.metrics.get('ST_mm', float('nan')):.3f} mm, Jacobians {report['jacobians']}, "
            f"CPU {cpu:.1f} s, wall {wall:.1f} s"
        )
        for start in report["starts"]:
            print(
                f"    start {start['start']}: {start['f_start']:.1f} -> {start['f_end']:.1f} MPa "
                f"({'feasible' if start['feasible_end'] else 'infeasible'}), "
                f"{start['n_evaluations']} designs, {start['stop']}"
            )
    print(f"load avg  {' '.join(f'{v:.2f}' for v in os.getloadavg())} at end")


if __name__ == "__main__":
    main()
