"""Exception family of the fea package."""


class FeaError(ValueError):
    """An analysis was asked for something it cannot do (bad input, not a numerical failure).

    Numerical failure (no convergence) is never raised: it comes back as data in the response.
    """
