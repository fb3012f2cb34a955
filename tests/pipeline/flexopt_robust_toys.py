"""A toy cantilever kind whose robust optimum is known in closed form (robust requirements).

Importing this module registers the kind ``toy_cantilever``: a rectangular cantilever of length
L and out-of-plane width b under a tip force F, its in-plane thickness t the one design
variable ``thickness_mm``. Its root stress is the beam formula sigma = 6 F L / (b t^2) (MPa for
N and mm), its mass rho L b t; it minimises the mass. A print shifts t by the thickness scatter
(the variable's name says it is a thickness) and b by the width scatter (``geometry.width_mm``):
the stress of a print is 6 F L / ((b + dw) (t + dt)^2), E does not enter.

``fail_below_mm``: a design (or a print) thinner than this cannot be solved (the kind returns
``Evaluation.failed`` with a reason), for the failed-sample tests. ``stall_below_mm``: a design
(or a print) thinner than this solves only the first rows of its load (as a solver that stops
converging part-way leaves it: ``converged`` False, the later rows NaN), its figures those of
the rows it reached (``STALL_FRACTION`` of the load: they under-read the stress). A module of
its own so that worker processes can import it by name to unpickle the problem.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from flexopt.optimise import DesignDetail, DesignProblem, DesignSpace, Evaluation
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study
from pydantic import BaseModel

DENSITY_G_MM3 = 1.05e-3  # ABS
STALL_FRACTION = 0.5  # the load a stalled solve reached: rows 0 .. 2 of 0 .. 4


class CantileverGeometry(BaseModel):
    model_config = STUDY_CONFIG

    kind: Literal["toy_cantilever"]
    length_mm: float = 50.0
    width_mm: float = 6.0
    force_N: float = 2.0
    t_bounds: tuple[float, float] = (0.5, 3.0)  # not a key ending in thickness_mm: not printed
    design_t: float = 2.0
    fail_below_mm: float | None = None
    stall_below_mm: float | None = None


class CantileverStudy(Study):
    geometry: CantileverGeometry
    optimiser: OptimiserSpec = OptimiserSpec(pop_size=12, n_gen=12, seed=3)


def stress_MPa(g: CantileverGeometry, t_mm: float) -> float:
    """Root bending stress of the cantilever, MPa: 6 F L / (b t^2)."""
    return 6.0 * g.force_N * g.length_mm / (g.width_mm * t_mm**2)


@dataclass
class CantileverProblem(DesignProblem):
    geometry: CantileverGeometry
    objective_names: tuple[str, ...] = ("mass_g",)
    constraint_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        lo, hi = self.geometry.t_bounds
        self.space = DesignSpace(("thickness_mm",), np.array([lo]), np.array([hi]))

    def evaluate(self, x: np.ndarray) -> Evaluation:
        g = self.geometry
        t = float(np.asarray(x, dtype=float).ravel()[0])
        if g.fail_below_mm is not None and t < g.fail_below_mm:
            return Evaluation.failed(x, 1, 0, f"SolverError: t = {t:.4f} mm does not converge")
        mass = DENSITY_G_MM3 * g.length_mm * g.width_mm * t
        reached = STALL_FRACTION if self.stalls(t) else 1.0  # a stalled solve's figures
        metrics = {"peak_stress_MPa": reached * stress_MPa(g, t), "mass_g": mass}
        return Evaluation(np.array(x, dtype=float), np.array([mass]), np.zeros(0), metrics)

    def detail(self, x: np.ndarray) -> DesignDetail:
        ev = self.evaluate(x)
        s = np.linspace(0.0, 1.0, 5)
        peak = ev.metrics.get("peak_stress_MPa") or np.nan
        t = float(np.asarray(x, dtype=float).ravel()[0])
        if self.stalls(t):  # rows 0 .. 2 reached; peak is already the reached rows' figure
            s = np.where(s <= STALL_FRACTION, s, np.nan)
            peak = peak / STALL_FRACTION
        table = {"load_fraction": s, "force_N": self.geometry.force_N * s, "stress": peak * s}
        plot = {"x": "load_fraction", "y": "force_N"}
        if self.stalls(t):
            return DesignDetail(ev, table, plot, converged=False, message="no convergence at row 3")
        return DesignDetail(ev, table, plot)

    def stalls(self, t_mm: float) -> bool:
        """A design (or print) of thickness ``t_mm`` (mm) solves only part of its load."""
        return self.geometry.stall_below_mm is not None and t_mm < self.geometry.stall_below_mm

    def nominal_design(self) -> np.ndarray:
        return np.array([self.geometry.design_t])


register(
    StudyKind(
        "toy_cantilever",
        CantileverStudy,
        check=lambda study: None,
        problem=lambda study: CantileverProblem(study.geometry),  # type: ignore[attr-defined]
        quantities=("peak_stress_MPa", "mass_g"),
    )
)


def study(name: str = "toy-cantilever", **geometry: object) -> dict:
    """A toy_cantilever study as a raw mapping (write it as JSON, which is YAML)."""
    return {
        "name": name,
        "geometry": {"kind": "toy_cantilever", **geometry},
        "material": "ABS",
        "parallel": {"backend": "serial"},
    }
