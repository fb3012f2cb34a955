"""The hybrid optimiser's default settings, in one place: :class:`optimise.hybrid.HybridConfig`
(the API) and the study schema's ``optimiser.hybrid:`` (pipeline/study.py, ``HybridSpec``) both
read them, so a study that leaves a setting out and a script that leaves it out run the same
stage. Light on purpose: the schema is loaded at every command's start (no pymoo, no SciPy)."""

from __future__ import annotations

__all__ = ["FD_STEP", "MAX_ITER", "MIN_DISTANCE", "PATIENCE", "TOLERANCE"]

#: least max-norm distance of two starts, in bound-normalised units
MIN_DISTANCE = 0.1
#: relative improvement of a start's best objective an iteration must exceed
TOLERANCE = 1e-3
#: iterations in a row without such an improvement that stop a start (the stop rule): the
#: schema's value since the hybrid became a study option (the API's HybridConfig said 3 until
#: session 28, so a script and a study left at their defaults stopped differently)
PATIENCE = 6
#: iterations per start at most
MAX_ITER = 40
#: forward-difference step, in bound-normalised units
FD_STEP = 1e-4
