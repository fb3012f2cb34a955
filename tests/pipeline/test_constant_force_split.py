"""The constant-force check in two parts (pipeline/studies/_constant_force_split.py): part 0 the
coarse rows but the guessed peak row, part 1 that row and its refined re-solve, each in its own
process (a pool's worker: here a pickled copy of the problem), merged in the run's process. The
merged check must be the whole check: the same factor, figures and verdict, and the same record
(every figure to the bit, the tangent's smallest eigenvalue too since session 31 fixed ARPACK's
start vector), whether or not the peak sits at the guessed row."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
from flexopt.pipeline.run import prepare_run
from flexopt.pipeline.studies import _constant_force_kinks as kinks
from flexopt.pipeline.studies import _constant_force_split as split
from flexopt.pipeline.studies._constant_force_clamp import CHECKED_PEAK, REFINED_PEAK
from flexopt.pipeline.study import load_study

ROOT = Path(__file__).resolve().parents[2]

#: noise keys: the wall time
NOISE = {"time_s"}


@pytest.fixture(scope="module")
def problem():
    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    return prepare_run(study).problem


def fresh(problem):
    """A worker's copy of the problem (what the pool unpickles: no kept checks)."""
    return pickle.loads(pickle.dumps(problem))


def record_of(problem) -> dict:
    (record,) = problem.checks.records.values()
    return record


def assert_same_record(a: dict, b: dict, path: str = "") -> None:
    """``a`` and ``b`` equal, keys in the same order, arrays to the bit, but :data:`NOISE`."""
    if isinstance(a, dict):
        assert list(a) == list(b), path
        for key in a:
            if key not in NOISE:
                assert_same_record(a[key], b[key], f"{path}/{key}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (u, v) in enumerate(zip(a, b, strict=True)):
            assert_same_record(u, v, f"{path}[{i}]")
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and np.array_equal(a, b), path
    else:
        assert a == b and type(a) is type(b), path


def parts_and_merge(problem, x, monkeypatch=None):
    """Parts 1 and 0 each in a fresh copy of the problem (as on two workers), sent back by
    pickle, merged in another copy (the run's process): (merged check, that copy, the parts).
    With ``monkeypatch``: the merge may solve nothing (plane_stress_check raises)."""
    answers = {}
    for p in (1, 0):
        answers[p] = pickle.loads(pickle.dumps(fresh(problem).check_constraints(x, part=p)))
    here = fresh(problem)
    if monkeypatch is not None:

        def no_solve(*args, **kwargs):
            raise AssertionError("the merge solved")

        monkeypatch.setattr(kinks, "plane_stress_check", no_solve)
    merged = here.check_constraints(x, part=(answers[0], answers[1]))
    if monkeypatch is not None:
        monkeypatch.undo()
    return merged, here, answers


def test_the_parts_merged_are_the_whole_check(problem, monkeypatch):
    """The peak at the guessed row (the study's nominal design): the merge solves nothing."""
    x = problem.nominal_design()
    whole_problem = fresh(problem)
    whole = whole_problem.check_constraints(x)
    merged, here, answers = parts_and_merge(problem, x, monkeypatch)
    assert merged.factors == whole.factors and merged.info == whole.info
    assert merged.met == whole.met
    # the parts: part 1 the guessed row (the beam's largest peak among the rows), part 0 the rest
    rows = answers[0].rows + answers[1].rows
    assert len(answers[1].rows) == 1 and len(rows) == len(set(rows)) >= 2
    record = record_of(here)
    assert_same_record(record, record_of(whole_problem))
    assert REFINED_PEAK in record  # part 1's re-solve was the peak's
    # a part's record is not the verdict's: never kept by the worker's memo
    worker = fresh(problem)
    worker.check_constraints(x, part=0)
    assert not worker.checks.records
    # the report of the merged design serves the merged record (no new solve)
    assert here.checks.solved == 1


def test_a_peak_away_from_the_guessed_row_is_re_solved_in_the_run_process(problem, monkeypatch):
    """Part 1 guessed the wrong row (here forced: the first checked row): the merge sees the
    peak at another row and makes its refined re-solve itself; the record is the whole check's."""
    x = problem.nominal_design()
    whole_problem = fresh(problem)
    whole = whole_problem.check_constraints(x)
    monkeypatch.setattr(split, "guess_row", lambda response, rows: int(np.asarray(rows)[0]))
    merged, here, answers = parts_and_merge(problem, x)
    assert answers[1].rows == (int(min(answers[0].rows + answers[1].rows)),)
    assert merged.info == whole.info and merged.factors == whole.factors
    assert_same_record(record_of(here), record_of(whole_problem))
    assert whole.info[CHECKED_PEAK] > 0


def test_a_missing_part_makes_the_whole_check_in_the_run_process(problem):
    x = problem.nominal_design()
    whole = fresh(problem).check_constraints(x)
    part0 = fresh(problem).check_constraints(x, part=0)
    for parts in ((part0, None), (None, None)):
        merged = fresh(problem).check_constraints(x, part=parts)
        assert merged.info == whole.info and merged.factors == whole.factors


def test_the_guessed_row_is_the_beams_largest_peak():
    class Response:
        peak_stress_MPa = np.array([0.0, 10.0, 30.0, np.nan, 30.0, 20.0])

    assert split.guess_row(Response, np.array([1, 2, 3, 4, 5])) == 2  # the first of a tie
    np.testing.assert_array_equal(split.part_rows(Response, np.array([1, 2, 5]), 0), [1, 5])
    np.testing.assert_array_equal(split.part_rows(Response, np.array([1, 2, 5]), 1), [2])
