"""Exception family of the fea package."""

from flexopt.geometry.errors import FlexoptError


class FeaError(FlexoptError, ValueError):
    """An analysis was asked for something it cannot do (bad input, not a numerical failure).

    Numerical failure (no convergence) is never raised: it comes back as data in the response.
    """
