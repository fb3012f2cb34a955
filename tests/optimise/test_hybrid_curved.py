"""The Gauss-Newton step's aim inside a constraint row (optimise/hybrid.py,
``_gauss_newton_step``, session 33).

A feasible design's step aims no further inside a row than the design already is (not moving
stays a feasible step), except for the rows the last trial from this design broke: there it
aims inside by the error that trial showed (the row's backoff). Why: on the boundary of a curved
row (the constant-force beam's stress row at its optimum, g ~ -1e-7) a trial breaks the row by
its curvature, and a retry aimed at the same boundary breaks it again, whatever the radius,
until the radius is small enough: constant-force seed 1 rejected the last 14 of its 40
iterations so.

The step's problem below is small enough to solve by hand: the least squares pull both
variables up, the row holds y, and the QP's answer is checked against the hand solution of each
aim.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.hybrid import FEASIBILITY_MARGIN, _gauss_newton_step

# r = (x - 3, y - 1) at x = y = 0 (so r = (-3, -1)), J = I; one row g = y + g0 with g0 = -1e-7
# (a design on the boundary); a trust region of 0.5. Unconstrained, the step is d = (0.5, 0.5).
R = np.array([-3.0, -1.0])
J = np.eye(2)
G = np.array([-1e-7])
JG = np.array([[0.0, 1.0]])
LOWER, UPPER = np.full(2, -0.5), np.full(2, 0.5)
BACKOFF = np.array([1e-3])


def test_a_feasible_design_aims_no_further_inside_than_it_is():
    d = _gauss_newton_step(R, J, G, JG, LOWER, UPPER, BACKOFF)
    # the row holds y at its present value: d_y = 0 (to SLSQP's 1e-10), d_x the whole radius
    assert d[0] == pytest.approx(0.5, abs=1e-9)
    assert d[1] == pytest.approx(0.0, abs=1e-8)
    d = _gauss_newton_step(R, J, G, JG, LOWER, UPPER, BACKOFF, broken=np.array([False]))
    assert d[1] == pytest.approx(0.0, abs=1e-8)


def test_a_row_the_last_trial_broke_is_aimed_inside_by_its_backoff():
    d = _gauss_newton_step(R, J, G, JG, LOWER, UPPER, BACKOFF, broken=np.array([True]))
    # g + JG d = -backoff - margin: d_y = -(backoff + margin) + 1e-7
    assert d[0] == pytest.approx(0.5, abs=1e-9)
    assert d[1] == pytest.approx(-(BACKOFF[0] + FEASIBILITY_MARGIN) - G[0], abs=1e-9)
