"""Genetic algorithms (pymoo GA and NSGA-II) driven by ask-and-tell.

The optimiser never calls the model itself: each generation it asks for a population, hands the
design vectors to ``evaluate`` (which the pipeline backs with a process pool or a Dask cluster and
an evaluation cache), and is told the results. That keeps parallelism, caching, fault isolation and
checkpoints outside the algorithm, and makes a run a deterministic function of its seed: replaying
it with every evaluation served from the cache reproduces every population exactly, which is how
a killed run is resumed from data rather than from a pickled optimiser.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.evaluation import INFEASIBLE_VALUE, Evaluation
from flexopt.optimise.space import DesignSpace
from pymoo.algorithms.soo.nonconvex.ga import GA
from pymoo.core.evaluator import Evaluator
from pymoo.core.problem import Problem
from pymoo.operators.sampling.lhs import LHS
from pymoo.problems.static import StaticProblem
from pymoo.termination import get_termination

__all__ = ["GAConfig", "Generation", "GAResult", "run_ga", "best_of", "pareto_front"]


@dataclass(frozen=True)
class GAConfig:
    """Settings of a GA run.

    Attributes
    ----------
    algorithm : "ga" (single objective) or "nsga2" (multi-objective).
    pop_size : designs per generation.
    n_gen : generations, the initial one included.
    seed : seeds pymoo's random state; the same seed gives the same run.
    """

    algorithm: Literal["ga", "nsga2"] = "ga"
    pop_size: int = 40
    n_gen: int = 30
    seed: int = 1

    def __post_init__(self) -> None:
        if self.algorithm not in ("ga", "nsga2"):
            raise OptimiseError(f"algorithm = {self.algorithm!r}; use 'ga' or 'nsga2'")
        if self.pop_size < 2:
            raise OptimiseError(f"pop_size = {self.pop_size} must be >= 2")
        if self.n_gen < 1:
            raise OptimiseError(f"n_gen = {self.n_gen} must be >= 1")


@dataclass(frozen=True)
class Generation:
    """What one generation produced.

    Attributes
    ----------
    index : 0-based generation number.
    evaluations : the designs evaluated in this generation, in the order asked.
    best : the best design found so far (feasible first, then least violation).
    n_evaluations : designs evaluated so far, this generation included.
    population : (pop_size, n_var) float — the designs the optimiser keeps after this generation
        (what a checkpoint records; a resumed run rebuilds it by replay, not from here).
    """

    index: int
    evaluations: tuple[Evaluation, ...]
    best: Evaluation
    n_evaluations: int
    population: np.ndarray | None = field(default=None, repr=False)

    @property
    def feasible_fraction(self) -> float:
        return float(np.mean([e.feasible for e in self.evaluations])) if self.evaluations else 0.0


@dataclass(frozen=True)
class GAResult:
    """The outcome of :func:`run_ga`.

    best : the best evaluation (single objective) or the feasible design with the smallest first
        objective (multi-objective; see ``front``).
    front : non-dominated feasible evaluations (multi-objective), or (best,) for one objective.
    generations : one record per generation.
    """

    best: Evaluation
    front: tuple[Evaluation, ...]
    generations: tuple[Generation, ...] = field(repr=False)


class _Box(Problem):
    def __init__(self, space: DesignSpace, n_obj: int, n_con: int) -> None:
        super().__init__(
            n_var=space.n_var, n_obj=n_obj, n_ieq_constr=n_con, xl=space.lower, xu=space.upper
        )


def best_of(evaluations: Sequence[Evaluation]) -> Evaluation:
    """Feasible design with the smallest first objective; else the least constraint violation."""
    if not evaluations:
        raise OptimiseError("no evaluations to choose from")
    feasible = [e for e in evaluations if e.feasible]
    if feasible:
        return min(feasible, key=lambda e: float(e.f[0]))
    evaluated = [e for e in evaluations if not e.reason] or list(evaluations)
    return min(evaluated, key=lambda e: (e.violation, float(e.f[0])))


def pareto_front(evaluations: Sequence[Evaluation]) -> tuple[Evaluation, ...]:
    """Non-dominated feasible evaluations, sorted by their objectives."""
    feasible = [e for e in evaluations if e.feasible]
    front = []
    for a in feasible:
        dominated = any(np.all(b.f <= a.f) and np.any(b.f < a.f) for b in feasible if b is not a)
        if not dominated:
            front.append(a)
    return tuple(sorted(front, key=lambda e: tuple(e.f)))


def run_ga(
    space: DesignSpace,
    evaluate: Callable[[np.ndarray], Sequence[Evaluation]],
    n_obj: int,
    n_con: int,
    config: GAConfig = GAConfig(),
    on_generation: Callable[[Generation], None] | None = None,
    initial: np.ndarray | None = None,
) -> GAResult:
    """Minimise ``n_obj`` objectives subject to ``n_con`` constraints g <= 0 over ``space``.

    Parameters
    ----------
    space : the design space.
    evaluate : maps a (m, n_var) array of designs to m Evaluations, in order. A design that cannot
        be evaluated must come back as an infeasible Evaluation with a reason, not raise.
    n_obj, n_con : numbers of objectives and constraints.
    config : GAConfig.
    on_generation : called after each generation (progress, checkpoints).
    initial : (k, n_var) designs to put into the first population (e.g. a published optimum or
        the Taguchi optimum); the rest is a Latin hypercube.
    """
    if not space.n_var:  # a space without variables is one fixed design: nothing to search
        raise OptimiseError("the design space is empty: give at least one variable")
    if config.algorithm == "ga" and n_obj != 1:
        raise OptimiseError(f"algorithm 'ga' needs one objective, got {n_obj}; use 'nsga2'")
    problem = _Box(space, n_obj, n_con)
    sampling: object = LHS()
    if initial is not None:
        initial = np.atleast_2d(np.asarray(initial, dtype=float))
        if initial.shape[1] != space.n_var:
            raise OptimiseError(
                f"initial designs have {initial.shape[1]} variables, the space {space.n_var}"
            )
        rng = np.random.default_rng(config.seed)
        n_fill = max(config.pop_size - len(initial), 0)
        fill = space.lower + rng.random((n_fill, space.n_var)) * (space.upper - space.lower)
        sampling = np.vstack([space.clip(initial), fill])[: config.pop_size]
    if config.algorithm == "ga":
        cls = GA
    else:  # imported here: NSGA-II pulls in scipy.spatial (~0.4 s) a single-objective run skips
        from pymoo.algorithms.moo.nsga2 import NSGA2

        cls = NSGA2
    algorithm = cls(pop_size=config.pop_size, sampling=sampling, eliminate_duplicates=True)
    algorithm.setup(problem, termination=get_termination("n_gen", config.n_gen), seed=config.seed)

    generations: list[Generation] = []
    everything: list[Evaluation] = []
    best: Evaluation | None = None
    while algorithm.has_next():
        pop = algorithm.ask()
        X = np.asarray(pop.get("X"), dtype=float)
        evaluations = tuple(evaluate(X))
        if len(evaluations) != len(X):
            raise OptimiseError(
                f"evaluate returned {len(evaluations)} results for {len(X)} designs"
            )
        F = np.array([e.f for e in evaluations], dtype=float).reshape(len(X), n_obj)
        G = np.array([e.g for e in evaluations], dtype=float).reshape(len(X), n_con)
        # A design with a reason was not (fully) evaluated, whatever values it carries: pymoo
        # must rank it below every evaluated design, and never as feasible.
        failed = np.array([bool(e.reason) for e in evaluations])
        F[failed] = INFEASIBLE_VALUE
        G[failed] = INFEASIBLE_VALUE
        kwargs = {"F": F}
        if n_con:
            kwargs["G"] = G
        Evaluator().eval(StaticProblem(problem, **kwargs), pop)
        algorithm.tell(infills=pop)
        everything.extend(evaluations)
        # The best so far, from the previous best and this generation: best_of over all
        # evaluations every generation was quadratic in the run (~3 s of a 2400-design run in the
        # process that feeds the workers). The same choice: the previous best stands for every
        # earlier design (ties keep the earlier one, as min over the whole list does).
        best = best_of(evaluations if best is None else (best, *evaluations))
        gen = Generation(
            len(generations),
            evaluations,
            best,
            len(everything),
            np.array(algorithm.pop.get("X"), dtype=float),
        )
        generations.append(gen)
        if on_generation is not None:
            on_generation(gen)

    best = best_of(everything)  # the same as the last generation's; also for no generation
    front = pareto_front(everything) if n_obj > 1 else (best,)
    return GAResult(best, front, tuple(generations))
