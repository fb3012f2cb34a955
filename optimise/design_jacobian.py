"""Exact derivatives of a design's responses, as a study kind hands them to the optimiser
(issue 27: :meth:`optimise.problem.DesignProblem.jacobian`, used by :mod:`optimise.hybrid`
instead of finite-difference columns and by the report's sensitivity chart)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["DesignJacobian"]


@dataclass(frozen=True)
class DesignJacobian:
    """The derivatives of one design's objectives, constraints and residuals by its variables.

    Shapes: ``n_var`` design variables (the problem's space), ``n_obj`` objectives, ``n_con``
    constraint rows, ``n_res`` least-squares residuals. Units: the response's unit per unit of
    the variable (e.g. N/mm).

    Attributes
    ----------
    x : (n_var,) the design.
    f : (n_obj, n_var) d(objective)/d(x).
    g : (n_con, n_var) d(constraint row)/d(x); where a row is a max (a peak stress), the
        derivative of the smooth aggregate the kind documents (``info``).
    residuals : (n_res, n_var) d(residual_i)/d(x) of the metrics ``residual_1`` ... (see
        :meth:`optimise.problem.DesignProblem.with_residuals`), or None.
    values : the responses the derivatives belong to, as the derivative computation saw them:
        "f" (n_obj,), "g" (n_con,), "residuals" (n_res,) where given.
    info : what the kind reports besides (aggregate parameters, costs).
    """

    x: np.ndarray
    f: np.ndarray
    g: np.ndarray
    residuals: np.ndarray | None = None
    values: dict[str, np.ndarray] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)
