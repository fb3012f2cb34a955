"""Design spaces, evaluations and optimisers (pymoo GA / NSGA-II by ask-and-tell)."""

from optimise.errors import OptimiseError
from optimise.evaluation import INFEASIBLE_VALUE, Evaluation
from optimise.ga import GAConfig, GAResult, Generation, best_of, run_ga
from optimise.problem import DesignDetail, DesignProblem
from optimise.space import DesignSpace

__all__ = [
    "DesignDetail",
    "DesignProblem",
    "DesignSpace",
    "Evaluation",
    "GAConfig",
    "GAResult",
    "Generation",
    "INFEASIBLE_VALUE",
    "OptimiseError",
    "best_of",
    "run_ga",
]
