"""Exception family of the geometry package, and the root of every flexopt error."""

__all__ = ["FlexoptError", "GeometryError"]


class FlexoptError(Exception):
    """The root of every error flexopt raises on purpose (a study it cannot use, a run folder it
    cannot read, a design it cannot build, ...): ``except flexopt.FlexoptError`` catches them all.

    Each error also derives from the built-in a caller would expect (StudyError and FeaError are
    ValueErrors, BackendError a RuntimeError, StepUnavailable an ImportError). It is defined here,
    in the lowest layer, so that geometry's, fea's and optimise's errors can derive from it
    (a layer imports only from its own or a lower one); ``pipeline.errors`` re-exports it.
    Ctrl-C and SIGTERM (:class:`pipeline.errors.Terminated`, a KeyboardInterrupt) are not errors
    and not under it.
    """


class GeometryError(FlexoptError, ValueError):
    """A geometry cannot be built from the given parameters.

    The message names the offending value, the valid range and how to fix it.
    """
