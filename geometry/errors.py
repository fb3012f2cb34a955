"""Exception family of the geometry package."""


class GeometryError(ValueError):
    """A geometry cannot be built from the given parameters.

    The message names the offending value, the valid range and how to fix it.
    """
