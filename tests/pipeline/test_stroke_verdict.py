"""A solve that stops part-way through its stroke is NOT MET ("solved through the stroke",
pipeline/stroke_verdict.py): parallel-guide-landing with its load case cut after row 8 of 20,
as a solver that stops converging there leaves it (NaN rows, ``ok`` False)."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from flexopt.pipeline.stroke_verdict import STROKE_ROW, with_stroke_row
from flexopt.pipeline.studies import mechanism as mk
from flexopt.pipeline.study import load_study
from flexopt.pipeline.verdict import judge_result

CUT = 8  # rows 0 .. 7 reached of 0 .. 20 (4 N of the 10 N drive)


def _cut(response):
    ok = np.asarray(response.converged, dtype=bool).copy()
    ok[CUT:] = False
    peak = np.asarray(response.peak_stress_MPa, dtype=float).copy()
    peak[CUT:] = np.nan
    roots = np.asarray(response.root_stress_MPa, dtype=float).copy()
    roots[CUT:] = np.nan
    outputs = {
        k: np.where(ok, np.asarray(v, dtype=float), np.nan) if np.ndim(v) == 1 else v
        for k, v in response.outputs.items()
    }
    return dataclasses.replace(
        response,
        converged=ok,
        peak_stress_MPa=peak,
        root_stress_MPa=roots,
        outputs=outputs,
        ok=False,
        message=f"no convergence at row {CUT}",
    )


@pytest.fixture(scope="module")
def landing():
    study = load_study("parallel-guide-landing")
    problem = mk.MechanismProblem(study)
    x = problem.nominal_design()
    full = problem.result(x)
    solved = problem.solve(x)
    problem.given_responses = {c: _cut(r) for c, r in solved.responses.items()}
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # the NaN rows warn no more
        cut = problem.result(x)
    return study, full, cut


def test_cut_stroke_is_not_met_and_full_stroke_unchanged(landing):
    study, full, cut = landing
    whole = judge_result(study, full)
    part = judge_result(study, cut)
    assert full.converged and all(v.met for v in whole)
    assert all(v.name != STROKE_ROW for v in whole)
    # the part of the stroke reached under-reads the stress: the peak over rows 0 .. 7 is the
    # full table's peak over those same rows, below the whole stroke's
    rows = np.asarray(full.table["peak_stress_MPa"], dtype=float)
    peak = {v.quantity: v for v in part}["max_peak_stress_MPa"]
    assert peak.value == pytest.approx(np.nanmax(rows[:CUT]), rel=1e-12)
    assert peak.value < 0.8 * np.nanmax(rows)
    assert peak.met  # on the rows reached: what the verdict used to stop at
    row = part[-1]
    assert row.name == STROKE_ROW and not row.met and f"row {CUT}" in row.detail
    assert cut.summary["verdict"] == "NOT MET" and full.summary["verdict"] == "MET"


def test_only_a_result_that_did_not_converge_gets_the_row():
    class Result:
        def __init__(self, converged):
            self.converged, self.message = converged, "stopped at row 3"

    class Detail:  # a design's detail (no ``converged``): nothing added
        pass

    assert with_stroke_row((), Detail()) == ()
    assert with_stroke_row((), Result(True)) == ()
    (row,) = with_stroke_row((), Result(False))
    assert row.name == STROKE_ROW and not row.met and "stopped at row 3" in row.detail
