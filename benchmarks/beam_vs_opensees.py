"""flexopt's nonlinear beam against OpenSees on three large-deflection problems with exact answers.

Run from the repository root::

    python benchmarks/beam_vs_opensees.py [--repeat 7] [--elements 20 50 100] [--kernel numba]

Problems (L = 100 mm, rectangular section t = 0.1 mm (``--thickness``) x b = 5 mm, ABS
E = 1800 MPa, nu = 0.35; every curve is 20 equal steps, both codes are asked for the same rows):

* ``cantilever-force``: clamped cantilever, dead tip force perpendicular to the axis raised to
  alpha = P L^2 / EI = 10. Error: tip deflection at the last step against the exact elastica.
* ``cantilever-disp``: the same cantilever with the tip's vertical displacement driven to
  0.6 L (tip rotation and horizontal motion free). Error: tip force at the last step.
* ``fixed-guided``: clamped at x = 0; the other end keeps zero rotation, slides axially freely and
  is pushed transversely to d = 0.8 L. Error: end force at the last step.

The exact answers (fea/elastica.py) are for an inextensible, unshearable beam. flexopt's
Simo–Reissner beam is extensible and shearable and OpenSees' elasticBeamColumn is extensible; with
t / L = 1e-3 those effects move the answers by ~1e-6 (cantilevers) and ~4e-5 (fixed–guided,
where the force is very sensitive to the geometry): below OpenSees' discretisation error at 100
elements, but not below flexopt's from ~20 elements on (run ``--thickness 0.02`` to push the floor
down 25 times). Times are medians of ``--repeat`` runs after a warm-up, both codes in this process,
runs interleaved so both see the same machine load; each run builds its model from scratch. Each
time is taken as CPU time of this process (``time.process_time``, the figure the ratios use: it
does not count time the process waited for a core another job held) and as wall time. flexopt runs
its compiled kernel (``--kernel numba``, the default when numba imports) or the numpy reference
path (``--kernel numpy``); the warm-up run loads (or, in a fresh install, compiles) the compiled
kernel, so no timed run includes compilation (``benchmarks/beam_kernel_speed.py`` times that).
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np

# Allow `python benchmarks/beam_vs_opensees.py` from a source checkout without installing.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive  # noqa: E402
from flexopt.fea.elastica import (  # noqa: E402
    cantilever_load_for_deflection,
    cantilever_tip_load,
    fixed_guided,
)
from flexopt.fea.materials import get_material  # noqa: E402
from flexopt.geometry.profile import BeamProfile  # noqa: E402

LENGTH_MM = 100.0
WIDTH_MM = 5.0
# t / L = 1e-3 keeps the extensibility and shear the elastica ignores at ~(t/L)^2 ~ 1e-6; see the
# module docstring. --thickness changes it (the exact answers are dimensionless and follow).
DEFAULT_THICKNESS_MM = 0.1
MATERIAL = get_material("ABS")
STEPS = 20
# OpenSees convergence: Newton converges quadratically, so once the displacement increment is
# below 1e-10 L the unbalance (hence the force) is converged to round-off, far below 1e-6.
OPS_DISP_TOL_MM = 1e-10 * LENGTH_MM
OPS_MAX_ITER = 50
OPS_SYSTEMS = ("BandSPD", "ProfileSPD", "BandGeneral", "SparseGeneral", "UmfPack")
# Meshes tried for the "matched accuracy" line (flexopt's P2 elements may need few).
MATCH_LADDER = (2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 25, 32, 40, 50, 64, 80, 100)


@dataclass(frozen=True)
class Section:
    """The rectangular section both codes use.

    Attributes
    ----------
    thickness_mm : float, mm — in-plane thickness t.
    width_mm : float, mm — out-of-plane width b.
    """

    thickness_mm: float
    width_mm: float = WIDTH_MM

    @property
    def area_mm2(self) -> float:
        return self.width_mm * self.thickness_mm

    @property
    def inertia_mm4(self) -> float:
        return self.width_mm * self.thickness_mm**3 / 12.0

    @property
    def ei_Nmm2(self) -> float:
        return MATERIAL.E_MPa * self.inertia_mm4


@dataclass(frozen=True)
class Problem:
    """One benchmark curve and its exact end value.

    Attributes
    ----------
    key : str
    section : Section
    flexopt_settings : BeamSettings — flexopt's solver settings; n_elements is set per run.
    control : "force" (max_value in N; the tip deflection is compared) or "displacement"
        (max_value in mm; the end force is compared).
    rotation : "free" or "fixed" — the driven end's rotation.
    max_value : float, N or mm
    exact : float, mm or N — the compared quantity at the last step.
    """

    key: str
    section: Section
    control: Literal["force", "displacement"]
    rotation: Literal["free", "fixed"]
    max_value: float
    exact: float
    flexopt_settings: BeamSettings = field(default_factory=BeamSettings)


def make_problems(section: Section, settings: BeamSettings | None = None) -> list[Problem]:
    """The three curves of the module docstring with their exact elastica answers."""
    settings = BeamSettings() if settings is None else settings
    force_scale = section.ei_Nmm2 / LENGTH_MM**2  # N per unit of P L^2 / EI
    alpha = 10.0
    return [
        Problem(
            "cantilever-force",
            section,
            "force",
            "free",
            alpha * force_scale,
            cantilever_tip_load(alpha).deflection_over_L * LENGTH_MM,
            settings,
        ),
        Problem(
            "cantilever-disp",
            section,
            "displacement",
            "free",
            0.6 * LENGTH_MM,
            cantilever_load_for_deflection(0.6).alpha * force_scale,
            settings,
        ),
        Problem(
            "fixed-guided",
            section,
            "displacement",
            "fixed",
            0.8 * LENGTH_MM,
            fixed_guided(0.8).load * force_scale,
            settings,
        ),
    ]


@dataclass(frozen=True)
class Outcome:
    """What one run of one code returned.

    Attributes
    ----------
    value : float, mm or N — the compared quantity at the last step (nan when it failed).
    ok : bool — every step converged.
    iterations : int — Newton iterations over the whole curve.
    message : str — why not ok.
    """

    value: float
    ok: bool
    iterations: int
    message: str = ""


def run_flexopt(problem: Problem, n_elements: int, kernel: str = "auto") -> Outcome:
    """Build flexopt's beam model and trace the 20-step curve (``kernel``: BeamSettings.kernel)."""
    profile = BeamProfile(
        points_mm=np.array([[0.0, 0.0], [LENGTH_MM, 0.0]]),
        thickness_mm=np.full(2, problem.section.thickness_mm),
        width_mm=problem.section.width_mm,
    )
    drive = EndDrive(
        control=problem.control,
        direction=(0.0, 1.0),
        max_value=problem.max_value,
        steps=STEPS,
        rotation=problem.rotation,
        transverse="free",
    )
    settings = replace(problem.flexopt_settings, n_elements=n_elements, kernel=kernel)
    model = BeamModel(profile, MATERIAL, "clamped", settings)
    response = model.solve(drive)
    column = response.displacement_mm if problem.control == "force" else response.force_N
    value = float(column[-1]) if response.ok else float("nan")
    return Outcome(value, bool(response.ok), int(np.sum(response.iterations)), response.message)


def run_opensees(problem: Problem, n_elements: int, system: str) -> Outcome:
    """Build the same beam in OpenSees (corotational elasticBeamColumn) and trace the curve."""
    import openseespy.opensees as ops

    ops.wipe()
    ops.model("basic", "-ndm", 2, "-ndf", 3)
    for i in range(n_elements + 1):
        ops.node(i + 1, LENGTH_MM * i / n_elements, 0.0)
    tip = n_elements + 1
    ops.fix(1, 1, 1, 1)
    if problem.rotation == "fixed":
        # Guided end: rotation held, both translations free (the push is a displacement control
        # on y, x slides without an axial force) -- no equalDOF needed.
        ops.fix(tip, 0, 0, 1)
    ops.geomTransf("Corotational", 1)
    sec = problem.section
    for e in range(n_elements):
        ops.element(
            "elasticBeamColumn",
            e + 1,
            e + 1,
            e + 2,
            sec.area_mm2,
            MATERIAL.E_MPa,
            sec.inertia_mm4,
            1,
        )
    ops.timeSeries("Linear", 1)
    ops.pattern("Plain", 1, 1)
    # Nodal loads in OpenSees stay in the global frame: a dead force, as in the elastica.
    if problem.control == "force":
        ops.load(tip, 0.0, problem.max_value, 0.0)
    else:
        ops.load(tip, 0.0, 1.0, 0.0)  # reference load; the load factor is the end force in N
    ops.constraints("Plain")
    ops.numberer("RCM")
    ops.system(system)
    ops.test("NormDispIncr", OPS_DISP_TOL_MM, OPS_MAX_ITER)
    ops.algorithm("Newton")
    if problem.control == "force":
        ops.integrator("LoadControl", 1.0 / STEPS)
    else:
        ops.integrator("DisplacementControl", tip, 2, problem.max_value / STEPS)
    ops.analysis("Static")
    iterations = 0
    for step in range(STEPS):
        if ops.analyze(1) != 0:
            return Outcome(float("nan"), False, iterations, f"no convergence in step {step + 1}")
        iterations += ops.testIter()
    value = ops.nodeDisp(tip, 2) if problem.control == "force" else ops.getLoadFactor(1)
    return Outcome(float(value), True, iterations)


def relative_error(outcome: Outcome, problem: Problem) -> float:
    return abs(outcome.value - problem.exact) / abs(problem.exact) if outcome.ok else float("nan")


@dataclass(frozen=True)
class Timing:
    """Medians over the timed rounds of one run.

    Attributes
    ----------
    cpu : float, s — CPU time of this process (``time.process_time``).
    wall : float, s — wall time (``time.perf_counter``).
    """

    cpu: float
    wall: float


def time_pair(runs: list[Callable[[], Outcome]], repeat: int) -> tuple[list[Timing], list[Outcome]]:
    """Median CPU and wall time of each run, interleaved over ``repeat`` rounds after a warm-up."""
    outcomes = [run() for run in runs]  # warm-up: imports, caches, compiled kernels, first touch
    cpu: list[list[float]] = [[] for _ in runs]
    wall: list[list[float]] = [[] for _ in runs]
    for _ in range(repeat):
        for run, c, w in zip(runs, cpu, wall, strict=True):
            start_cpu, start = time.process_time(), time.perf_counter()
            run()
            w.append(time.perf_counter() - start)
            c.append(time.process_time() - start_cpu)
    timings = [
        Timing(statistics.median(c), statistics.median(w)) for c, w in zip(cpu, wall, strict=True)
    ]
    return timings, outcomes


def pick_opensees_system(problems: list[Problem], n_elements: int) -> tuple[str, list[str]]:
    """Fastest OpenSees linear solver that converges and agrees with BandGeneral on every problem.

    Returns the choice and one report line per candidate.
    """
    reference = {p.key: run_opensees(p, n_elements, "BandGeneral").value for p in problems}
    lines, best, best_time = [], "BandGeneral", float("inf")
    for system in OPS_SYSTEMS:
        total, note = 0.0, ""
        for problem in problems:
            try:
                times, (outcome,) = time_pair(
                    [lambda p=problem, s=system: run_opensees(p, n_elements, s)], 3
                )
            except Exception as exc:  # an unavailable solver raises from the C++ layer
                note = f"unavailable ({exc})"
                break
            if not outcome.ok or abs(outcome.value - reference[problem.key]) > 1e-9 * abs(
                reference[problem.key]
            ):
                note = f"rejected on {problem.key} ({outcome.message or 'different answer'})"
                break
            total += times[0].cpu
        if note:
            lines.append(f"  {system:<14} {note}")
            continue
        lines.append(
            f"  {system:<14} {total * 1e3:8.1f} ms CPU for the three curves at {n_elements} el."
        )
        if total < best_time:
            best, best_time = system, total
    return best, lines


def environment_lines() -> list[str]:
    import openseespy.opensees as ops
    import scipy

    try:
        import numba

        numba_version = f", numba {numba.__version__}"
    except ImportError:
        numba_version = ", no numba"

    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            cwd=Path(__file__).resolve().parent,
        ).stdout.strip()
        # The solver may be edited in the working tree; say so rather than cite a commit alone.
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--", "fea/beam.py"],
            capture_output=True,
            text=True,
            check=True,
            cwd=Path(__file__).resolve().parents[1],
        ).stdout.strip()
        if dirty:
            commit += " (fea/beam.py modified)"
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    return [
        f"date      {datetime.datetime.now().astimezone():%Y-%m-%d %H:%M %Z}",
        f"machine   {platform.machine()}, {os.cpu_count()} cores, {platform.system()} "
        f"{platform.release()}",
        f"load avg  {' '.join(f'{x:.2f}' for x in os.getloadavg())} (1, 5, 15 min) at start",
        f"software  Python {platform.python_version()}, numpy {np.__version__}, scipy "
        f"{scipy.__version__}{numba_version}, OpenSees {ops.version()}, flexopt commit {commit}",
    ]


def format_pct(error: float) -> str:
    return "FAIL" if np.isnan(error) else f"{100.0 * error:.2e}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=7, help="timed runs per case (median)")
    parser.add_argument("--elements", type=int, nargs="+", default=[20, 50, 100])
    parser.add_argument(
        "--thickness",
        type=float,
        default=DEFAULT_THICKNESS_MM,
        help="section thickness t in mm (L = 100 mm); the elastica ignores O((t/L)^2) effects",
    )
    parser.add_argument(
        "--flexopt-rtol",
        type=float,
        default=BeamSettings().rtol,
        help="flexopt's Newton residual tolerance (BeamSettings.rtol; default: its default)",
    )
    parser.add_argument(
        "--opensees-system",
        default="auto",
        choices=("auto", *OPS_SYSTEMS),
        help="OpenSees linear solver; auto times them all and keeps the fastest that works",
    )
    parser.add_argument(
        "--kernel",
        default="auto",
        choices=("auto", "numba", "numpy"),
        help="flexopt's beam kernel (BeamSettings.kernel; auto: FLEXOPT_BEAM_KERNEL, else numba)",
    )
    args = parser.parse_args(argv)
    kernel = args.kernel
    import openseespy.opensees as ops

    # OpenSees writes warnings and banners through its own streams; send them to the null device.
    ops.logFile(os.devnull, "-noEcho")

    section = Section(args.thickness)
    problems = make_problems(section, BeamSettings(rtol=args.flexopt_rtol, kernel=kernel))
    print("\n".join(environment_lines()))
    print(
        f"beam      L = {LENGTH_MM:g} mm, t = {section.thickness_mm:g} mm, "
        f"b = {section.width_mm:g} mm, E = {MATERIAL.E_MPa:g} MPa, nu = {MATERIAL.nu:g}, "
        f"EI = {section.ei_Nmm2:.6g} N mm^2, {STEPS} steps"
    )
    for p in problems:
        unit, what = ("mm", "tip deflection") if p.control == "force" else ("N", "end force")
        driven = "N" if p.control == "force" else "mm"
        print(
            f"          {p.key:<17} drive {p.max_value:.6g} {driven}, exact {what} "
            f"{p.exact:.10g} {unit}"
        )

    system = args.opensees_system
    if system == "auto":
        system, lines = pick_opensees_system(problems, max(args.elements))
        print("OpenSees linear solvers (3 runs each, summed medians):")
        print("\n".join(lines))
    print(f"OpenSees system: {system}; test NormDispIncr {OPS_DISP_TOL_MM:g} mm; Newton; RCM")
    probe = BeamModel(
        BeamProfile([[0.0, 0.0], [LENGTH_MM, 0.0]], [section.thickness_mm] * 2, WIDTH_MM),
        MATERIAL,
        settings=BeamSettings(kernel=kernel),
    )
    print(
        f"flexopt: BeamSettings defaults but rtol = {args.flexopt_rtol:g}; kernel {probe.kernel} "
        f"(--kernel {kernel})"
    )
    print(
        f"times: median of {args.repeat} runs (model build + 20-step curve), after a warm-up; "
        f"ms = CPU time, ratios CPU (wall)\n"
    )

    header = (
        f"{'problem':<17} {'el.':>4} | {'flexopt ms':>10} {'err %':>9} {'iters':>5} | "
        f"{'OpenSees ms':>11} {'err %':>9} {'iters':>5} | {'OpenSees/flexopt':>18}"
    )
    print(header)
    print("-" * len(header))
    ops_at_max: dict[str, float] = {}  # OpenSees' error on the finest mesh
    failures: list[str] = []
    for problem in problems:
        for n in args.elements:
            (t_fx, t_os), (fx, os_) = time_pair(
                [
                    lambda p=problem, n=n: run_flexopt(p, n, kernel),
                    lambda p=problem, n=n: run_opensees(p, n, system),
                ],
                args.repeat,
            )
            e_fx, e_os = relative_error(fx, problem), relative_error(os_, problem)
            for name, out in (("flexopt", fx), ("OpenSees", os_)):
                if not out.ok:
                    failures.append(f"{name} {problem.key} {n} el.: {out.message}")
            print(
                f"{problem.key:<17} {n:>4} | {t_fx.cpu * 1e3:>10.2f} {format_pct(e_fx):>9} "
                f"{fx.iterations:>5} | {t_os.cpu * 1e3:>11.1f} {format_pct(e_os):>9} "
                f"{os_.iterations:>5} | {t_os.cpu / t_fx.cpu:>9.2f} ({t_os.wall / t_fx.wall:5.2f})"
            )
            if n == max(args.elements):
                ops_at_max[problem.key] = e_os
        print()

    n_max = max(args.elements)
    print(f"matched accuracy (smallest flexopt mesh with error <= OpenSees at {n_max} el.):")
    for problem in problems:
        target = ops_at_max[problem.key]
        match = next(
            (
                n
                for n in MATCH_LADDER
                if relative_error(run_flexopt(problem, n, kernel), problem) <= target
            ),
            None,
        )
        if match is None or np.isnan(target):
            print(
                f"  {problem.key:<17} none up to {MATCH_LADDER[-1]} el. "
                f"(target {format_pct(target)} %)"
            )
            continue
        # Re-time OpenSees here, interleaved with this flexopt mesh, so both see the same load.
        (t_fx, t_os), (fx, _) = time_pair(
            [
                lambda p=problem, n=match: run_flexopt(p, n, kernel),
                lambda p=problem: run_opensees(p, n_max, system),
            ],
            args.repeat,
        )
        print(
            f"  {problem.key:<17} flexopt {match:>3} el.: "
            f"{format_pct(relative_error(fx, problem))} % "
            f"in {t_fx.cpu * 1e3:.2f} ms vs OpenSees {n_max} el.: {format_pct(target)} % in "
            f"{t_os.cpu * 1e3:.1f} ms -> OpenSees/flexopt CPU time {t_os.cpu / t_fx.cpu:.2f} "
            f"(wall {t_os.wall / t_fx.wall:.2f})"
        )
    print(f"load avg  {' '.join(f'{x:.2f}' for x in os.getloadavg())} (1, 5, 15 min) at end")
    if failures:
        print("\nconvergence failures:")
        print("\n".join(f"  {line}" for line in failures))
    return 0


if __name__ == "__main__":
    status = main()
    sys.stdout.flush()
    sys.stderr.flush()
    # OpenSees prints "Process 0 Terminating" from a C++ destructor at exit; point the process's
    # stdout and stderr at the null device so the table stays the last thing printed.
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    sys.exit(status)
