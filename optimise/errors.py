"""Exception family of the optimise package."""

from flexopt.geometry.errors import FlexoptError


class OptimiseError(FlexoptError, ValueError):
    """A design space or optimiser setting is invalid; the message names the value and the fix."""
