"""Exception family of the optimise package."""


class OptimiseError(ValueError):
    """A design space or optimiser setting is invalid; the message names the value and the fix."""
