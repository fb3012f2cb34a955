"""The constant-force study's exact derivatives against central differences of its evaluate, and
what a Jacobian costs (issue 27 items 1-2; the figures of docs/sensitivities.md).

Uses the tests' own functions (tests/pipeline/test_constant_force_gradient.py: the study's
problem solved at rtol = 1e-11, the fourth-order stencil, the mesh-keeping step ladder) over
every variable, and prints per variable the worst relative error of the Eq. 8 residuals, of the
RMS (via mean(r^2)/2), and of the bound-normalised Jacobian; then the KS and peak-stress checks
and the CPU of one Jacobian against one evaluation (the example's problem, default tolerance).

    OMP_NUM_THREADS=1 nice python benchmarks/constant_force_gradient.py
    OMP_NUM_THREADS=1 nice python benchmarks/constant_force_gradient.py --timing-only --repeat 15

``--timing-only``: only the CPU of a Jacobian and of an evaluation at the example's design
(medians and minima of ``--repeat`` calls each, one call first to load the code; the load
average printed; the Jacobian twice: with nothing kept at x, so it solves the path itself, and
right after an evaluation of x in the same process, which it starts from), without the
finite-difference checks: what A/B runs of two checkouts compare.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def timing(repeat: int) -> None:
    """Medians and minima of the CPU of one Jacobian and one evaluation (module docstring)."""
    import os
    import statistics

    from flexopt.pipeline.run import prepare_run
    from flexopt.pipeline.study import load_study

    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    problem = prepare_run(study).problem  # the example as it runs (default tolerance)
    x = problem.nominal_design()
    problem.jacobian(x)  # loads the code once
    problem.evaluate(x)

    def cpu(call, n: int) -> list[float]:
        out = []
        for _ in range(n):
            t0 = time.process_time()
            call()
            out.append(time.process_time() - t0)
        return out

    try:  # the solves kept for a Jacobian at them (session 29); absent in older checkouts
        from flexopt.pipeline.studies import _constant_force_solved as kept
    except ImportError:
        kept = None

    def cold() -> None:  # the Jacobian solving its path itself (nothing kept at x)
        if kept is not None:
            kept.clear()
        problem.jacobian(x)

    def after_evaluate() -> float:  # the stage's case: x was just evaluated in this process
        problem.evaluate(x)
        t0 = time.process_time()
        problem.jacobian(x)
        return time.process_time() - t0

    load = os.getloadavg()[0]
    t_jac = cpu(cold, repeat)
    t_hit = [after_evaluate() for _ in range(repeat)]
    t_ev = cpu(lambda: problem.evaluate(x), 3 * repeat)
    jac, hit, ev = (statistics.median(t) for t in (t_jac, t_hit, t_ev))
    print(
        f"CPU: Jacobian median {jac * 1e3:.1f} ms (min {min(t_jac) * 1e3:.1f}), after an "
        f"evaluation of x in this process {hit * 1e3:.1f} ms (min {min(t_hit) * 1e3:.1f}), "
        f"evaluation median {ev * 1e3:.2f} ms (min {min(t_ev) * 1e3:.2f}): {jac / ev:.1f} "
        f"evaluations (medians); load average {load:.1f} -> {os.getloadavg()[0]:.1f}"
    )


def main() -> None:
    if "--timing-only" in sys.argv:
        repeat = int(sys.argv[sys.argv.index("--repeat") + 1]) if "--repeat" in sys.argv else 15
        timing(repeat)
        return
    sys.path.insert(0, str(ROOT / "tests" / "pipeline"))
    import test_constant_force_gradient as T
    from flexopt.pipeline.run import prepare_run
    from flexopt.pipeline.study import load_study

    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    geometry = study.geometry.model_copy(update={"min_feature_mm": 0.5})
    p = T.TightProblem(study.model_copy(update={"geometry": geometry}))
    x = p.nominal_design()
    out = T.gradient.study_sensitivities(p, x, p._beam, p._drive)
    n, span = len(out["residuals_N"]), p.space.upper - p.space.lower

    def at(k: int, step: float) -> np.ndarray:
        v = x.copy()
        v[k] += step
        return v

    rows = []
    for k in range(23):
        h = next(h for h in T._step(p, k) * T.LADDER if T._same_mesh(p, x, k, h))
        fd_r = T._fd(lambda s, k=k: T._residuals(p, at(k, s)), h)
        fd_q = T._fd(lambda s, k=k: 0.5 * np.mean(T._residuals(p, at(k, s)) ** 2), h / 3)
        rows.append((k, h / T._step(p, k), fd_r, fd_q))
    fd = np.array([np.append(r[2], r[3]) for r in rows]).T
    exact = np.vstack([out["d_residuals"], out["rms_error_N"] * out["d_rms"]])
    err = np.abs(exact - fd)
    per_r = err[:n].max(0) / np.abs(fd[:n]).max(0)
    bound = np.linalg.norm(out["residuals_N"]) * np.linalg.norm(fd[:n], axis=0) / n
    per_f = err[n] / bound
    jac = err[:n].max(0) * span / np.abs(fd[:n] * span).max()
    print("variable  step (x _step)  residuals   rms        Jacobian (bound-normalised)")
    for k, frac, _, _ in rows:
        name = p.space.names[k]
        print(f"{name:8s}  {frac:5.3f}          {per_r[k]:.2e}  {per_f[k]:.2e}  {jac[k]:.2e}")
    print(f"worst: residuals {per_r.max():.2e}, rms {per_f.max():.2e}, Jacobian {jac.max():.2e}")

    rho = out["rho"]
    ks_err = []
    for k in (0, 4, 9, 10, 15, 19, 20, 21, 22):
        fd_ks = T._fd(lambda s, k=k: T._path_ks(p, at(k, s), rho), T._step(p, k) / 10)
        ks_err.append(abs(out["d_ks"][k] - fd_ks) / np.abs(out["d_ks"]).max())
    jacobian = p.jacobian(x)
    grad = jacobian.info["peak_stress_gradient"]
    pk_err = []
    for k in (2, 11, 14, 20):
        fd_pk = T._fd(lambda s, k=k: p.evaluate(at(k, s)).g[0], T._step(p, k) / 10)
        pk_err.append(abs(grad[k] - fd_pk) / np.abs(grad).max())
    g_ks, g_max = out["d_ks"], out["d_peak"]
    print(
        f"KS {out['ks_stress_MPa']:.4f} MPa, max {out['peak_stress_MPa']:.4f} MPa, rho "
        f"{rho:.4g} /MPa, rows differentiated {len(out['rows'])}; KS vs max gradient: "
        f"{np.abs(g_ks - g_max).max() / np.abs(g_max).max():.3g} of the largest, cosine "
        f"{g_ks @ g_max / np.linalg.norm(g_ks) / np.linalg.norm(g_max):.6f}"
    )
    print(f"KS worst {max(ks_err):.2e}; peak (max) worst {max(pk_err):.2e}")

    problem = prepare_run(study).problem  # the example as it runs (default tolerance)
    problem.jacobian(x)  # loads the code once
    t0 = time.process_time()
    for _ in range(5):
        problem.jacobian(x)
    t_jac = (time.process_time() - t0) / 5
    t0 = time.process_time()
    for _ in range(20):
        problem.evaluate(x)
    t_ev = (time.process_time() - t0) / 20
    print(
        f"CPU: Jacobian {t_jac * 1e3:.0f} ms, evaluation {t_ev * 1e3:.1f} ms: "
        f"{t_jac / t_ev:.1f} evaluations (forward differences: 23)"
    )


if __name__ == "__main__":
    main()
