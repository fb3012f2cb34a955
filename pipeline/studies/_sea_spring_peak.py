"""The SEA spring kind's converged peak stress and fine outline of one design of its problem
(:class:`pipeline.studies.sea_spring.SeaSpringProblem`): thin wrappers of
:func:`fea.sea_design.peak_convergence` and :func:`fea.sea_design.fine_geometry` with the
problem's frame, material, angle and mesh. Module level, so the report's side process
(:class:`pipeline.screening.SideProcess`) pickles :func:`peak_job` by name; the job looks
:func:`peak_of` up in this module when it runs, so a stand-in set here is what both run.
"""

from __future__ import annotations

from typing import Any

from flexopt.fea.sea_design import fine_geometry, peak_convergence
from flexopt.geometry.sea_spring import SpringGeometry

__all__ = ["fine_geometry_of", "peak_job", "peak_of"]


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
