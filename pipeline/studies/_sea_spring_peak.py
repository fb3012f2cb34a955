"""The SEA spring kind's converged peak stress and fine outline of one design of its problem
(:class:`pipeline.studies.sea_spring.SeaSpringProblem`): thin wrappers of
:func:`fea.sea_design.peak_convergence` and :func:`fea.sea_design.fine_geometry` with the
problem's frame, material, angle and mesh. Module level, so the report's side process
(:class:`pipeline.screening.SideProcess`) pickles :func:`peak_job` by name; the job looks
:func:`peak_of` up in this module when it runs, so a stand-in set here is what both run.

Also the detail's stage-1 plot (taguchi.png, :func:`start_taguchi_png`), made in a process of
its own beside the detail's solves.
"""

from __future__ import annotations

from typing import Any

from flexopt.fea.sea_design import fine_geometry, peak_convergence
from flexopt.geometry.sea_spring import SpringGeometry
from flexopt.pipeline.screening import SideProcess

__all__ = ["fine_geometry_of", "peak_job", "peak_of", "start_taguchi_png", "taguchi_png"]


def peak_of(prob: Any, params: Any, sign: float) -> dict[str, Any]:
    """:func:`fea.sea_design.peak_convergence` of the design ``params`` (SpringParams or
    ArmSpringParams) of the problem ``prob``, turned the worse direction ``sign`` (+1 or -1).

    Raises
    ------
    FeaError, GeometryError
        When a refined mesh cannot be built or solved.
    """
    return peak_convergence(
        params, prob.frame, prob.material, prob.theta, sign, prob.study.mesh,
        prob.study.solid_3d.curve_step_mm,
    )  # fmt: skip


def fine_geometry_of(prob: Any, params: Any) -> SpringGeometry:
    """:func:`fea.sea_design.fine_geometry`: the outline the peak converged on, exported."""
    return fine_geometry(params, prob.frame, prob.study.solid_3d.curve_step_mm)


def peak_job(prob: Any, params: Any, sign: float) -> dict[str, Any]:
    """:func:`peak_of`, looked up when the side process runs it (module level: the pool
    pickles it by name)."""
    return peak_of(prob, params, sign)


def _taguchi_args(stage1: dict[str, Any], topology: str) -> tuple | None:
    """:func:`pipeline.plots.plot_taguchi`'s arguments for stage 1's results; None without
    its main effects (no plot)."""
    if "main_effects" not in stage1:
        return None
    title = f"stage 1: {stage1['array']} over the {topology}'s factors"
    return stage1["main_effects"], stage1["anova"], title


def plot_job(*args: Any) -> bytes:
    """:func:`pipeline.plots.plot_taguchi` (module level: the side process pickles it by name;
    matplotlib is imported where it runs)."""
    from flexopt.pipeline.plots import plot_taguchi

    return plot_taguchi(*args)


def start_taguchi_png(stage1: dict[str, Any], topology: str) -> SideProcess | None:
    """A process of its own that draws taguchi.png (:func:`taguchi_png` takes it): the plot
    is ~3 s CPU of matplotlib's constrained layout that needs no answer of the detail's, which
    ran on its critical path (before the 3D checks; the peak convergence's process is the
    other critical path, so it goes to neither). None without a plot to make."""
    args = _taguchi_args(stage1, topology)
    if args is None:
        return None
    side = SideProcess.start()
    side.submit("taguchi.png", plot_job, *args)
    return side


def taguchi_png(side: SideProcess | None, stage1: dict[str, Any], topology: str) -> bytes | None:
    """taguchi.png's bytes: from ``side`` (:func:`start_taguchi_png`), else (no process, or it
    failed) drawn here; None without a plot (``stage1`` without main effects, e.g. ``{}`` to
    only close ``side``). Closes ``side``."""
    args = _taguchi_args(stage1, topology)
    try:
        png = side.get("taguchi.png") if side is not None and args is not None else None
    finally:
        if side is not None:
            side.close()
    if args is None:
        return None
    return png if png is not None else plot_job(*args)


def solves_here(s3: Any) -> bool:
    """Whether the detail's two extra 2D solves run in the report's process, beside the 3D
    checks, rather than in the peak convergence's (``s3``: the study's ``solid_3d`` block).
    With CHOLMOD's factor the checks (~10 s CPU) were shorter than the peak convergence
    (~14 s; ~10.3 s since its warm start, session 31: the two processes now about even,
    either place costs the same): the solves fill the report's process's wait. Without it (a
    plain install's multigrid, ~35 s) the checks are far the longer: the solves go to the
    other process."""
    from flexopt.fea.solid3d import cholmod_available

    return s3.solver == "cholmod" or (s3.solver == "auto" and cholmod_available())
