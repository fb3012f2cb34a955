"""A check split over the pool's workers (a problem whose ``check_parts`` is 2: the constant-force
study, pipeline/studies/_constant_force_split.py): with calls in parallel (``ahead``) the hybrid
sends a check as its parts ``"check:1"``, ``"check:0"`` and merges their answers in the run's
process through the problem's ``check_constraints(x, part=(...))``. The merged answer is the
whole check's, so every round, design, report and the best are those of the unsplit run, to the
bit; a part that did not answer is made good by the whole check in the run's process."""

from __future__ import annotations

import numpy as np
from flexopt.optimise.hook_call import HookAnswer, call_hook
from flexopt.optimise.hybrid import ConstraintCheck, run_hybrid
from test_hybrid import SPACE
from test_hybrid_calibration import BOUND, judged
from test_hybrid_calibration import evaluate as calibration_evaluate
from test_hybrid_calibration import jacobian as calibration_jacobian
from test_hybrid_lockstep import batches, config, without_time


class Toy:
    """A problem with a check in two parts: part 0 the judged figure, part 1 the row's figure;
    the merge divides them (``parts``: 1 answers the whole check only)."""

    def __init__(self, parts: int) -> None:
        self.check_parts = parts
        self.calls: list[tuple[str, object]] = []  # (where: "part p" / "merge" / "whole", ...)

    def jacobian(self, x: np.ndarray):
        return calibration_jacobian(x)

    def check_constraints(self, x: np.ndarray, part=None):
        if isinstance(part, int):
            self.calls.append((f"part {part}", None))
            return ("part", part, float(judged(x)) if part == 0 else float(x[0]))
        if part is not None and all(p is not None for p in part):
            self.calls.append(("merge", [p[1] for p in part]))
            figure, row = part[0][2], part[1][2]
        else:
            self.calls.append(("whole", None))
            figure, row = float(judged(x)), float(x[0])
        return ConstraintCheck({0: figure / row}, figure <= BOUND, {"judged": figure})


def run(problem: Toy, fail: str = ""):
    sent: list[list[str]] = []

    def requests(X, calls):
        sent.append([kind for kind, _ in calls])
        answers = [
            HookAnswer(None, "WorkerDied: the worker died")
            if kind == fail
            else call_hook(problem, kind, x)
            for kind, x in calls
        ]
        return (calibration_evaluate(X) if len(X) else []), answers

    cfg = config(starts=2, max_iter=100)
    result = run_hybrid(
        SPACE,
        calibration_evaluate,
        1,
        1,
        cfg,
        jacobian=problem.jacobian,
        requests=requests,
        ahead=True,
    )
    return result, sent


def test_a_split_check_changes_no_round_design_or_result():
    whole, sent_whole = run(Toy(1))
    split, sent_split = run(Toy(2))
    assert whole.report["checks"]["count"] >= 2  # the toy's starts are checked
    assert batches(split) == batches(whole)  # every round's designs, to the bit
    assert without_time(split.report) == without_time(whole.report)
    assert split.best.x.tobytes() == whole.best.x.tobytes()
    flat = [k for kinds in sent_split for k in kinds]
    assert "check" not in flat and flat.count("check:1") == flat.count("check:0") > 0
    # each check's parts are sent together, the last part first, in the check's round
    for kinds in sent_split:
        if "check:1" in kinds:
            i = kinds.index("check:1")
            assert kinds[i + 1] == "check:0"
    n_checks = whole.report["checks"]["count"]
    assert sum(k == "check" for kinds in sent_whole for k in kinds) == n_checks
    assert flat.count("check:0") == n_checks


def test_a_split_check_is_merged_in_the_run_process():
    problem = Toy(2)
    result, _ = run(problem)
    merges = [c for c in problem.calls if c[0] == "merge"]
    assert len(merges) == result.report["checks"]["count"]
    assert all(parts == [0, 1] for _, parts in merges)  # in part order
    assert not any(c[0] == "whole" for c in problem.calls)


def test_a_part_that_did_not_answer_is_made_good_by_the_whole_check_here():
    whole, _ = run(Toy(1))
    problem = Toy(2)
    failed, _ = run(problem, fail="check:1")
    assert without_time(failed.report) == without_time(whole.report)
    assert batches(failed) == batches(whole)
    assert sum(c[0] == "whole" for c in problem.calls) == whole.report["checks"]["count"]


def test_no_split_where_calls_do_not_run_in_parallel():
    problem = Toy(2)
    cfg = config(starts=2, max_iter=100)
    result = run_hybrid(
        SPACE, calibration_evaluate, 1, 1, cfg, jacobian=problem.jacobian, ahead=True
    )
    assert result.report["checks"]["count"] >= 2
    assert {c[0] for c in problem.calls} == {"whole"}
