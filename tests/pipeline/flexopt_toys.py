"""A toy study kind whose designs fail on purpose, for the runner's parallel and fault tests.

Importing this module registers the kind ``toy_faults``. It is a module of its own (not a test
file) so that worker processes, Dask workers and a ``flexopt run`` subprocess can import it by name
(``tests/pipeline`` on ``sys.path`` / ``PYTHONPATH``) to unpickle the problem.

The problem minimises (a - 0.6)^2 + (b - 0.3)^2 + c^2 subject to a + b <= 1.1 over [0, 1]^3, and
misbehaves where its geometry block says (every threshold is on ``a``):

- ``raise_above``: evaluate raises RuntimeError;
- ``nan_above``: evaluate returns a NaN objective;
- ``mesh_fail_above``: evaluate returns ``Evaluation.failed`` with a meshing reason (what a kind
  does for a design it cannot mesh);
- ``hang_above``: evaluate sleeps ``hang_s`` (a stuck solve);
- ``exit_above``: the process exits at once (``os._exit``: a segfault, an OOM kill);
- ``exit_once_above``: the process exits the first time it sees each such design (a marker file in
  ``marker_dir``), and evaluates it normally when it is resubmitted;
- ``sleep_s``: every evaluation takes this long (a solve of realistic length);
- ``call_log``: a file that every finished solve appends a line to (to count solves across
  processes).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from flexopt.optimise import DesignDetail, DesignProblem, DesignSpace, Evaluation
from flexopt.optimise.design_jacobian import DesignJacobian
from flexopt.pipeline.studies import StudyKind, register
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study
from pydantic import BaseModel, Field


class FaultGeometry(BaseModel):
    model_config = STUDY_CONFIG

    kind: Literal["toy_faults"]
    sleep_s: float = Field(0.0, ge=0)
    raise_above: float | None = None
    nan_above: float | None = None
    mesh_fail_above: float | None = None
    hang_above: float | None = None
    hang_s: float = 30.0
    exit_above: float | None = None
    exit_once_above: float | None = None
    marker_dir: str | None = None
    call_log: str | None = None  # every finished solve appends a line here (counts solves)
    # HookProblem's Jacobian: exits its process / raises / sleeps above these (on a)
    jacobian_exit_above: float | None = None
    jacobian_raise_above: float | None = None
    jacobian_sleep_s: float = Field(0.0, ge=0)


class FaultStudy(Study):
    geometry: FaultGeometry
    optimiser: OptimiserSpec = OptimiserSpec(pop_size=8, n_gen=4, seed=5)


def _above(value: float, threshold: float | None) -> bool:
    return threshold is not None and value > threshold


@dataclass
class FaultProblem(DesignProblem):
    geometry: FaultGeometry
    space: DesignSpace = DesignSpace(("a", "b", "c"), np.zeros(3), np.ones(3))
    objective_names: tuple[str, ...] = ("error",)
    constraint_names: tuple[str, ...] = ("sum_excess",)

    def evaluate(self, x: np.ndarray) -> Evaluation:
        g = self.geometry
        a, b, c = (float(v) for v in x)
        if g.sleep_s:
            time.sleep(g.sleep_s)
        if _above(a, g.exit_above):
            os._exit(3)
        if _above(a, g.exit_once_above):
            marker = Path(g.marker_dir or ".") / hashlib.sha1(x.tobytes()).hexdigest()
            if not marker.exists():
                marker.write_text("died here once")
                os._exit(4)
        if _above(a, g.hang_above):
            time.sleep(g.hang_s)
        if _above(a, g.raise_above):
            raise RuntimeError(f"cannot build a = {a:.3f}")
        if _above(a, g.mesh_fail_above):
            return Evaluation.failed(x, 1, 1, "MeshError: the outline could not be meshed")
        f = (a - 0.6) ** 2 + (b - 0.3) ** 2 + c**2
        if _above(a, g.nan_above):
            f = float("nan")
        if g.call_log:
            with open(g.call_log, "a") as log:  # one short write: whole lines from any process
                log.write(hashlib.sha1(x.tobytes()).hexdigest() + "\n")
        return Evaluation(np.array(x), np.array([f]), np.array([a + b - 1.1]), {"sum": a + b})

    def detail(self, x: np.ndarray) -> DesignDetail:
        d = np.linspace(0.0, 1.0, 6)
        table = {"displacement_mm": d, "force_N": float(x[0]) * d}
        return DesignDetail(self.evaluate(x), table, {"x": "displacement_mm", "y": "force_N"})


@dataclass
class HookProblem(FaultProblem):
    """FaultProblem with the hybrid's hooks (not a kind: the pool's hook-call tests build it
    themselves): ``jacobian`` the exact derivatives of the objective and the row, misbehaving
    where the geometry's ``jacobian_*`` fields say; ``check_constraints`` a "finer" reading of
    the row, a + b (1 + a) against 1.1."""

    def evaluate(self, x: np.ndarray) -> Evaluation:
        """FaultProblem's, with the process that solved it (metric ``pid``)."""
        evaluation = super().evaluate(x)
        return dataclasses.replace(evaluation, metrics={**evaluation.metrics, "pid": os.getpid()})

    def jacobian(self, x: np.ndarray) -> DesignJacobian:
        g = self.geometry
        a, b, c = (float(v) for v in x)
        if g.jacobian_sleep_s:
            time.sleep(g.jacobian_sleep_s)
        if _above(a, g.jacobian_raise_above):
            raise RuntimeError(f"no derivatives at a = {a:.3f}")
        if _above(a, g.jacobian_exit_above):
            os._exit(5)
        f = np.array([[2.0 * (a - 0.6), 2.0 * (b - 0.3), 2.0 * c]])
        # the process that answered (the pool's tests of where a call runs)
        return DesignJacobian(
            np.array(x), f, np.array([[1.0, 1.0, 0.0]]), info={"pid": os.getpid()}
        )

    def check_constraints(self, x: np.ndarray) -> object:
        from flexopt.optimise.hybrid import ConstraintCheck  # pymoo: not in every worker

        a, b = float(x[0]), float(x[1])
        finer = a + b * (1.0 + a)
        return ConstraintCheck({0: finer / (a + b)}, finer <= 1.1, {"finer": finer})


# Not kinds(): that imports every kind module, which a worker unpickling the problem should not
# pay for. A module is imported once per process, so this registers once.
register(
    StudyKind(
        "toy_faults",
        FaultStudy,
        check=lambda study: None,
        problem=lambda study: FaultProblem(study.geometry),  # type: ignore[attr-defined]
    )
)


def study(name: str = "faults", **geometry: object) -> dict:
    """A toy_faults study as a raw mapping (write it as JSON, which is YAML)."""
    return {
        "name": name,
        "geometry": {"kind": "toy_faults", **geometry},
        "material": "PLA",
        "optimiser": {"pop_size": 8, "n_gen": 4, "seed": 5},
    }
