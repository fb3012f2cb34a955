"""The mechanism kind's exact Jacobian (pipeline/studies/_mechanism_gradient.py) against central
differences of the run's own ``evaluate`` (the problem as ``flexopt run`` builds it, with the
requirements' constraint rows), computed here (issue 27, items 1-2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from flexopt.pipeline.run import prepare_run
from flexopt.pipeline.study import load_study

EXAMPLES = Path(__file__).resolve().parents[2] / "pipeline" / "examples"


def problem_of(name: str):
    return prepare_run(load_study(EXAMPLES / f"{name}.yaml")).problem


def central(problem, x: np.ndarray, i: int, h: float) -> tuple[np.ndarray, ...]:
    """Fourth-order central differences of (f, g, [width_mm]) of ``problem.evaluate`` along
    variable i."""
    ev = {}
    for s in (1, -1, 2, -2):
        xs = x.copy()
        xs[i] += s * h
        e = problem.evaluate(xs)
        assert not e.reason, e.reason
        ev[s] = (np.asarray(e.f, float), np.asarray(e.g, float), np.array([e.metrics["width_mm"]]))
    return tuple(
        (8.0 * (ev[1][k] - ev[-1][k]) - (ev[2][k] - ev[-2][k])) / (12.0 * h) for k in (0, 1, 2)
    )


@pytest.mark.parametrize(
    ("name", "step"),
    [("parallel-guide", 1e-3), ("gripper-amplifier", 1e-4), ("constant-force-mechanism", 1e-5)],
)
def test_jacobian_against_central_differences(name, step):
    """Objective and every constraint row (the interference, the requirements' rows: the peak
    stress with the roots' Kt and the optimiser's stress factor, the solved width, the
    gripper's amplification and forces, constant-force-mechanism's RMS error over its 23
    variables: vertex positions, thicknesses, width), each variable: within 1e-6 of the row's
    largest |FD| (steps ``step`` of the range: constant-force-mechanism's response switches
    place (peak, mesh) within 1.5e-4 of a3's range; gripper-amplifier's recorded optimum holds
    the stress constraint, and its peak switches place within 1e-3 of the hinge's range (the
    central difference at 1e-3 was 2 % off, one-sided slopes at 1e-4 and 1e-5 agree with the
    exact one to 3e-4 and 3e-5); measured at 1e-3, 1e-3, 1e-5 on earlier designs: 4.7e-8,
    1.3e-7, 4.9e-8)."""
    problem = problem_of(name)
    x = problem.nominal_design()
    jac = problem.jacobian(x)
    assert jac is not None
    ev = problem.evaluate(x)
    np.testing.assert_allclose(jac.values["f"], ev.f, rtol=1e-12)
    np.testing.assert_allclose(jac.values["g"], ev.g, rtol=1e-12)
    span = problem.space.upper - problem.space.lower
    F = np.zeros_like(jac.f)
    G = np.zeros_like(jac.g)
    W = np.zeros(x.size)
    for i in range(x.size):
        F[:, i], G[:, i], W[i : i + 1] = central(problem, x, i, step * span[i])
    # the width: solved from the stiffness (parallel-guide) or the study's own (gripper)
    assert np.abs(jac.info["width_gradient"] - W).max() <= 1e-6 * max(np.abs(W).max(), 1e-300)
    for exact, ref in ((jac.f, F), (jac.g, G)):
        for row in range(ref.shape[0]):
            scale = np.abs(ref[row]).max()
            if scale == 0.0:  # a row the design does not move (no interference)
                assert np.abs(exact[row]).max() == 0.0
                continue
            assert np.abs(exact[row] - ref[row]).max() <= 1e-6 * scale, (row, exact, ref)


def test_imperfect_path_is_not_differentiated():
    """bistable-switch's printed path is solved again with an imperfection along its buckling
    mode (a mesh of the mode's nodes): the hook answers None (forward differences) instead of
    differentiating another mechanism's path."""
    problem = problem_of("bistable-switch")
    assert problem.jacobian(problem.nominal_design()) is None


def test_a_hybrid_parallel_guide_run_uses_exact_jacobians(tmp_path):
    """The runner's problem wraps the kind's (the requirements' constraint rows): the hybrid's
    SLSQP stage still takes the exact Jacobian (none by forward differences) and the report's
    sensitivity section comes from it."""
    import json

    from flexopt.pipeline.parallel import ParallelSettings
    from flexopt.pipeline.run import run_study
    from flexopt.pipeline.study import HybridSpec

    study = load_study(EXAMPLES / "parallel-guide.yaml")
    optimiser = study.optimiser.model_copy(
        update={
            "method": "hybrid",
            "hybrid": HybridSpec(ga_n_gen=1, starts=1, max_iter=2, max_evaluations=6),
            "pop_size": 4,
        }
    )
    study = study.model_copy(
        update={
            "optimiser": optimiser,
            "fidelity": study.fidelity.model_copy(update={"enabled": False}),
        }
    )
    run_study(prepare_run(study), out=tmp_path / "run", parallel=ParallelSettings("serial"))
    hybrid = json.loads((tmp_path / "run" / "run.json").read_text())["hybrid"]
    assert hybrid["jacobians"]["exact"] >= 1 and hybrid["jacobians"]["finite_differences"] == 0
    report = (tmp_path / "run" / "report.md").read_text()
    assert "## Sensitivity of the best design" in report and "exact derivatives" in report
