"""Setting a run up: everything that can refuse the inputs, before any file is written."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.first_objective import FirstObjective
from flexopt.optimise.ga import GAConfig
from flexopt.optimise.hybrid import HybridConfig
from flexopt.optimise.problem import DesignProblem
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.problems import build_base_problem
from flexopt.pipeline.study import HybridSpec, OptimiserSpec, Study

# --------------------------------------------------------------------------------------------
# Setting a run up (everything that can refuse the inputs, before any file is written)


@dataclass(frozen=True)
class RunSetup:
    """A validated run, ready to go.

    Attributes
    ----------
    study : the study as it will run (``optimiser.seed`` replaced by ``--seed``).
    problem : the kind's design problem, built once.
    config : GA settings (``--quick`` applied).
    quick : whether ``--quick`` was given.
    initial : (k, n_var) designs seeded into the first population, from the problem's optional
        ``initial_designs()`` (e.g. a published optimum), or None.
    hybrid : the settings of ``optimiser.method: hybrid`` (``config`` is then its GA stage), or
        None for the GA alone.
    """

    study: Study
    problem: DesignProblem
    config: GAConfig
    quick: bool
    initial: np.ndarray | None = None
    hybrid: HybridConfig | None = None


def build_problem(study: Study) -> DesignProblem:
    """The kind's design problem for ``study``, as ``flexopt run`` optimises it: the kind's own
    problem with the study's ``role: constraint`` requirements as g rows
    (:func:`pipeline.problems.build_base_problem`), its ``robust:`` constraints held on fixed
    scatter samples, scored by its worst scatter sample when ``robustness.objective`` is
    ``worst``.

    Raises
    ------
    StudyError
        When the kind cannot be optimised, or refuses the study while building the problem.
    """
    from flexopt.pipeline.robustness import with_robust_constraints, with_worst_case

    # robust: requirements of role constraint held on fixed scatter samples (docs/robustness.md)
    return with_worst_case(study, with_robust_constraints(study, build_base_problem(study)))


def prepare_run(study: Study, quick: bool = False, seed: int | None = None) -> RunSetup:
    """Check the optimiser settings and build the design problem once.

    Parameters
    ----------
    study : Study
        A validated study whose kind has a ``problem``.
    quick : bool
        Use ``optimiser.quick_pop_size`` and ``optimiser.quick_n_gen``.
    seed : int, optional
        Replaces ``optimiser.seed`` (also in the resolved study.yaml).

    Raises
    ------
    StudyError
        Naming the key path, for anything that would stop the run before it starts.
    """
    spec = getattr(study, "optimiser", None)
    if spec is None:
        spec = OptimiserSpec()
    if seed is not None:
        spec = spec.model_copy(update={"seed": int(seed)})
        if hasattr(study, "optimiser"):
            study = study.model_copy(update={"optimiser": spec})
    problem = build_problem(study)
    n_obj = len(problem.objective_names)
    if spec.algorithm == "ga" and n_obj != 1:
        raise StudyError(
            "optimiser.algorithm",
            f"'ga' optimises one objective but kind '{study.kind}' has {n_obj} "
            f"({', '.join(problem.objective_names)}); set algorithm: nsga2",
        )
    pop_size, n_gen = (
        (spec.quick_pop_size, spec.quick_n_gen) if quick else (spec.pop_size, spec.n_gen)
    )
    if spec.method == "hybrid":
        return _hybrid_setup(study, problem, spec, quick, pop_size, n_gen)
    try:
        config = GAConfig(spec.algorithm, pop_size, n_gen, spec.seed)
    except OptimiseError as exc:
        raise StudyError("optimiser", str(exc)) from None
    return RunSetup(study, problem, config, quick, initial_designs(problem))


#: ``--quick`` of a hybrid run: one start, at most this many iterations
QUICK_HYBRID_ITERATIONS = 3


def _hybrid_setup(
    study: Study,
    problem: DesignProblem,
    spec: OptimiserSpec,
    quick: bool,
    pop_size: int,
    n_gen: int,
) -> RunSetup:
    """The run of ``optimiser.method: hybrid``: its GA stage (``hybrid.ga_n_gen`` generations,
    without exact derivatives more until its best is feasible, ``n_gen`` at most;
    ``quick_n_gen`` under ``--quick``) and
    its gradient stage; Gauss-Newton on the problem's
    :meth:`~optimise.problem.DesignProblem.with_residuals`. With ``algorithm: nsga2`` and
    several objectives it minimises the first (:class:`optimise.first_objective.
    FirstObjective`: the objective the run's best design is chosen by)."""
    options = spec.hybrid or HybridSpec()
    if spec.algorithm == "nsga2" and len(problem.objective_names) > 1:
        # several objectives: the hybrid minimises the first, the one a run's best design is
        # chosen by (optimise/first_objective.py); the others stay in every design's metrics
        problem = FirstObjective(problem)
    if spec.algorithm != "ga" and not isinstance(problem, FirstObjective):
        raise StudyError(
            "optimiser.method",
            f"'hybrid' with algorithm: {spec.algorithm} needs several objectives; kind "
            f"'{study.kind}' has one ({problem.objective_names[0]}): use algorithm: ga",
        )
    if len(problem.objective_names) != 1:
        raise StudyError(
            "optimiser.method",
            f"'hybrid' optimises one objective with algorithm: ga (or the first of several "
            f"with nsga2); kind '{study.kind}' has {len(problem.objective_names)} "
            f"({', '.join(problem.objective_names)})",
        )
    local = options.local
    if local in ("auto", "gauss_newton"):
        with_residuals = problem.with_residuals()
        if with_residuals is not None:
            problem, local = with_residuals, "gauss_newton"
        elif local == "gauss_newton":
            raise StudyError(
                "optimiser.hybrid.local",
                f"gauss_newton needs a least-squares objective; kind '{study.kind}' gives no "
                f"residuals for {problem.objective_names[0]}; use slsqp (or auto)",
            )
        else:
            local = "slsqp"
    try:
        config = HybridConfig(
            GAConfig("ga", pop_size, n_gen, spec.seed),  # its GA stage: one objective
            None if quick else options.ga_n_gen,
            local,
            1 if quick else options.starts,
            options.min_distance,
            options.tolerance,
            options.patience,
            min(options.max_iter, QUICK_HYBRID_ITERATIONS) if quick else options.max_iter,
            options.fd_step,
            options.max_evaluations,
            retry_inside=bool(options.retry_inside),
            step_solver=options.step_solver or "slsqp",
        )
    except OptimiseError as exc:
        raise StudyError("optimiser", str(exc)) from None
    return RunSetup(study, problem, config.ga, quick, initial_designs(problem), config)


def initial_designs(problem: DesignProblem) -> np.ndarray | None:
    """The designs a problem asks to seed the first population with (its
    :meth:`~optimise.problem.DesignProblem.initial_designs`), as (k, n_var), or None."""
    initial = problem.initial_designs()
    if initial is None:
        return None
    initial = np.atleast_2d(np.asarray(initial, dtype=float))
    if initial.ndim != 2 or initial.shape[1] != problem.space.n_var or not len(initial):
        raise TypeError(
            f"initial_designs() returned shape {initial.shape}; expected (k, {problem.space.n_var})"
        )
    return initial
