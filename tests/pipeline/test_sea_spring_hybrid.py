"""``optimiser: {algorithm: nsga2, method: hybrid}`` on the sea_spring kind (issue 27 items 2-3):
the run minimises the peak stress (the first objective, by which the run's best design is
chosen) with Gauss-Newton on the kind's exact Jacobian; the mass stays a metric."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.first_objective import FirstObjective
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.run import prepare_run
from flexopt.pipeline.study import HybridSpec, load_study


def _hybrid(name: str, **options):
    study = load_study(name)
    optimiser = study.optimiser.model_copy(
        update={"method": "hybrid", "hybrid": HybridSpec(**options)}
    )
    return study.model_copy(update={"optimiser": optimiser})


def test_nsga2_study_runs_the_hybrid_on_its_first_objective():
    setup = prepare_run(_hybrid("sea-spring-quick", ga_n_gen=1))
    assert isinstance(setup.problem, FirstObjective)
    assert setup.problem.objective_names == ("peak_stress_MPa",)
    assert setup.problem.dropped_objectives == ("mass_g",)
    assert setup.hybrid is not None and setup.hybrid.local == "gauss_newton"
    assert setup.config.algorithm == "ga"  # the GA stage optimises the one objective


def test_slsqp_asked_for_is_kept():
    setup = prepare_run(_hybrid("sea-spring-quick", local="slsqp"))
    assert setup.hybrid is not None and setup.hybrid.local == "slsqp"
    assert setup.problem.with_residuals() is not None  # offered, not taken


def test_ga_with_two_objectives_is_still_refused():
    study = load_study("sea-spring-quick")
    optimiser = study.optimiser.model_copy(update={"algorithm": "ga", "method": "hybrid"})
    with pytest.raises(StudyError, match="set algorithm: nsga2"):
        prepare_run(study.model_copy(update={"optimiser": optimiser}))


@pytest.mark.slow
def test_the_hybrids_evaluation_and_jacobian_of_the_quick_design():
    """The wrapped problem's evaluation is the kind's, its mass a metric and its stress the one
    residual; the Jacobian's residual row is the KS stress's derivative and every constraint
    row, the loaded slot's included, is differentiated (finite)."""
    setup = prepare_run(_hybrid("sea-spring-quick"))
    problem = setup.problem.with_residuals()
    inner = setup.problem.inner
    x = inner.nominal_design()
    ev, full = problem.evaluate(x), inner.evaluate(x)
    assert ev.f[0] == full.f[0] and ev.metrics["mass_g"] == full.f[1]
    assert ev.metrics["residual_1"] == ev.f[0]
    jac = problem.jacobian(x)
    assert jac.f.shape == (1, x.size) and np.all(np.isfinite(jac.g))
    np.testing.assert_array_equal(jac.residuals, jac.f)
    assert "zero_rows" not in jac.info
