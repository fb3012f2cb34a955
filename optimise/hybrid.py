"""The hybrid optimiser: the GA's global search, then a gradient method from several distinct good
GA designs until a stop rule (issue 27, ``optimiser: {method: hybrid}``).

The gradient stage works in bound-normalised variables ``u = (x - lower) / (upper - lower)`` in
[0, 1]. Its derivatives are forward differences (step ``fd_step`` in u; a backward one where the
forward step would leave the bounds): the ``n_var`` perturbed designs of one Jacobian are one
batch of ``evaluate``, so a pool or a cluster solves them in parallel like a generation, and the
run's cache, store, resume (replay) and tables serve them as they serve the GA's designs. The
stage is a deterministic function of the evaluations it is given, as the GA is of its seed: a
resumed run replays it from the store.

Where the problem differentiates its responses exactly (:meth:`optimise.problem.DesignProblem.
jacobian`, passed as ``run_hybrid(..., jacobian=)``; the constant-force study), a Jacobian is one
call of it at the current design instead of ``n_var`` perturbed designs: nothing is evaluated
for it (the designs the stage steps to are, as before), and it is a deterministic function of
the design, so a resumed run computes the same one again. ``HybridResult.report["jacobians"]``
counts the exact and the finite-difference Jacobians.

Two gradient methods:

* **Gauss-Newton with a trust region** (``gauss_newton``) where the objective is a least-squares
  one: ``f[0] = sqrt(mean(r**2))`` of residuals ``r`` (n_res,) the evaluations carry (the hook
  :meth:`optimise.problem.DesignProblem.with_residuals`). Each iteration minimises the linear
  model ``||r + J d||**2`` subject to the linearised constraints ``g + J_g d <= -backoff``
  (elastic: a violation it cannot remove is priced, not refused; ``backoff`` the linearisation
  error a trial showed), the bounds and ``|d|_inf <= radius`` (a small QP solved by SciPy's
  SLSQP), evaluates the step, accepts it when the objective falls and a feasible design stays
  feasible (from an infeasible design: when the violation falls), and sets the radius by the
  ratio of the actual to the predicted decrease (of the violation while infeasible). A
  constraint row that is a max, given as pieces by the exact Jacobian (:func:`pieces_of`,
  ``info["g_pieces"]``), is linearised piece by piece (one slack for the row), so a step sees
  the max about to move to another piece.
* **SLSQP** (``slsqp``, SciPy) on ``f[0]`` scaled by its start value, with the constraints and
  bounds, otherwise.

The stop rule of a start: ``patience`` iterations in a row that lower its best objective by no
more than ``tolerance`` times it (relative), or ``max_iter`` iterations, or the whole stage's
``max_evaluations``; Gauss-Newton counts its accepted steps only (a rejected trial shrinks the
radius, and rejections end a start only when the radius falls below 1e-6).
:attr:`HybridResult.report` says which stage found the best design, the
evaluations of each stage and why each start stopped.

The starts run in lockstep (:func:`_drive`): each start is a generator of requests (evaluate
these designs; the problem's Jacobian or check at a design) and each round sends every live
start's request as one batch (:meth:`_Stage.serve`; through ``run_hybrid(requests=)`` a pool's
workers compute the Jacobians and checks beside the designs). A start's requests and answers do
not depend on the others', so each start asks for the same designs, and the stage ends on the
same best design, as with the starts one after the other; only the order of the batches differs.
Starts sharing a ``max_evaluations`` budget, and SLSQP's (SciPy calls back synchronously), run
one after the other. On a pool of two or more workers (``run_hybrid(ahead=True)``), a round in
which one start asks for a Jacobian or a check and another for one trial design takes the
trial's Jacobian too, on the worker that solved the trial: a start that accepts its trial is
answered from it without waiting a round (:meth:`_Stage._ahead_calls`); its designs and answers
are the same. There too, a check whose problem splits it (``check_parts``: the constant-force
study's plane-stress rows and its refined re-solve) is sent as its parts, each to a worker, and
merged in the run's process into the whole check's answer (:meth:`_Stage._split`): the check's
round is shorter, its rounds, designs and answers the same.

Calibration (Gauss-Newton, where the problem has a ``check_constraints(x)`` hook: a
:class:`ConstraintCheck` of the figures its verdict judges, from a finer model than
``evaluate``'s): once every start's gradient method has ended, each start's best design is
checked, the lowest first (:func:`_calibrate_starts`); a row whose judged figure exceeds its
bound is tightened by the measured ratio and Gauss-Newton goes on from that design, at most
:data:`CALIBRATION_ROUNDS` times (:func:`_calibrate`); the result is the lowest design whose
check was met, so a start whose best is not below a design already checked and met is not
checked. A check is not an evaluation (nothing stored) and is a deterministic function of
the design, as the exact Jacobian is, so a resumed run makes the same ones.
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from flexopt.geometry.errors import FlexoptError
from flexopt.optimise import hybrid_defaults as defaults
from flexopt.optimise.design_jacobian import DesignJacobian
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.ga import GAConfig, GAResult, Generation, best_of, run_ga
from flexopt.optimise.hook_call import HookAnswer, hook_answer
from flexopt.optimise.space import DesignSpace

__all__ = [
    "ConstraintCheck",
    "GradientStep",
    "HybridConfig",
    "HybridResult",
    "pieces_of",
    "residuals_of",
    "run_hybrid",
    "pick_starts",
    "StallRule",
]

log = logging.getLogger(__name__)

#: Jacobians taken ahead of a request and not yet asked for, kept (a rejected trial's never is)
AHEAD_KEPT = 8

#: a failed design's objective and constraint in the scaled SLSQP problem: finite (SLSQP's line
#: search backs off from it) and far above any evaluated design's
_FAILED_SCALED = 1.0e3


@dataclass(frozen=True)
class HybridConfig:
    """Settings of a hybrid run.

    Attributes
    ----------
    ga : the GA stage's settings; its ``n_gen`` is the stage's most generations.
    ga_n_gen : the GA stage ends after this many generations; without exact derivatives
        (no ``jacobian`` given to :func:`run_hybrid`, or ``exact_jacobian`` False) only once its
        best design is feasible (else it goes on, to ``ga.n_gen`` at most); None: ``ga.n_gen``.
    local : ``"gauss_newton"`` (needs residuals) or ``"slsqp"``.
    starts : distinct GA designs the gradient stage starts from, best first.
    min_distance : least max-norm distance of two starts in bound-normalised units.
    tolerance : relative improvement of a start's best objective an iteration must exceed.
    patience : iterations in a row without such an improvement that stop a start.

    The defaults of these and of ``max_iter`` and ``fd_step`` are the study schema's
    (:mod:`optimise.hybrid_defaults`).
    max_iter : iterations per start at most.
    fd_step : forward-difference step in bound-normalised units.
    max_evaluations : designs the gradient stage may ask for at most (None: no limit).
    exact_jacobian : use the problem's exact derivatives where :func:`run_hybrid` is given them
        (``jacobian``); False: forward differences always (to compare the two).
    retry_inside : Gauss-Newton: after a trial breaks a constraint row, the retry from the same
        design aims inside that row by the error the trial showed, where that still predicts a
        decrease (:func:`_gauss_newton_step`'s ``broken``; session 33). Off by default: it
        helps a start walking a curved row's boundary (constant-force: fewer rounds, lower RMS
        over seeds 1-5), but on sea-spring it ran 50 designs instead of 43 (a lower stress,
        613.6 against 638.0 MPa, in 49 s against 35 s), past that study's time target.
    step_solver : Gauss-Newton: how each step's QP is solved. ``"slsqp"`` (the default):
        SciPy's SLSQP on the elastic problem. ``"exact"``: exactly, by Lawson and Hanson's
        least squares with inequalities (:func:`least_squares_inequalities`), SLSQP only where
        the linearised rows cannot be met (session 34). SLSQP's BFGS model of ``J^T J`` stops
        short of the QP's optimum (model objectives up to 24x the optimum's on constant-force)
        and meets the rows to ~1e-7; the exact solve is ~12x faster and meets them to ~1e-10.
        Not the default: the path changes, and on sea-spring the exact steps ran 61 designs
        instead of 47 (637.3 against 639.7 MPa) in 49.9 s against 44.0 s, past its 45 s target
        (docs/benchmarks.md, "Session 34").
    """

    ga: GAConfig = GAConfig()
    ga_n_gen: int | None = None
    local: Literal["gauss_newton", "slsqp"] = "slsqp"
    starts: int = 3
    min_distance: float = defaults.MIN_DISTANCE
    tolerance: float = defaults.TOLERANCE
    patience: int = defaults.PATIENCE
    max_iter: int = defaults.MAX_ITER
    fd_step: float = defaults.FD_STEP
    max_evaluations: int | None = None
    exact_jacobian: bool = True
    retry_inside: bool = False
    step_solver: Literal["slsqp", "exact"] = "slsqp"

    def __post_init__(self) -> None:
        if self.local not in ("gauss_newton", "slsqp"):
            raise OptimiseError(f"local = {self.local!r}; use 'gauss_newton' or 'slsqp'")
        if self.step_solver not in ("slsqp", "exact"):
            raise OptimiseError(f"step_solver = {self.step_solver!r}; use 'slsqp' or 'exact'")
        if self.ga.algorithm != "ga":
            raise OptimiseError("the hybrid optimiser optimises one objective: algorithm 'ga'")
        if self.starts < 1 or self.patience < 1 or self.max_iter < 1:
            raise OptimiseError("starts, patience and max_iter must be >= 1")
        if not 0.0 < self.fd_step < 0.1:
            raise OptimiseError(f"fd_step = {self.fd_step} must be in (0, 0.1)")

    def record(self) -> dict[str, Any]:
        """The gradient stage's settings as run.json records them."""
        return {
            "local": self.local,
            "ga_n_gen": self.ga_n_gen,
            "starts": self.starts,
            "min_distance": self.min_distance,
            "tolerance": self.tolerance,
            "patience": self.patience,
            "max_iter": self.max_iter,
            "fd_step": self.fd_step,
            "max_evaluations": self.max_evaluations,
            # only when on: the run.json of a study without it is what it was
            **({"retry_inside": True} if self.retry_inside else {}),
            **({"step_solver": self.step_solver} if self.step_solver != "slsqp" else {}),
        }


@dataclass(frozen=True)
class ConstraintCheck:
    """What a problem's :meth:`~optimise.problem.DesignProblem.check_constraints` finds at a
    design: the constraint figures its verdict will judge, from a finer model than ``evaluate``'s
    (the constant-force study's plane-stress check of the part as exported).

    Attributes
    ----------
    factors : {row c: k} for constraint rows of the form ``g_c = figure / bound - 1``: the judged
        figure is ``k`` times the row's figure at this design (k > 1: the row under-reads it).
        The gradient stage then holds ``k (g_c + 1) - 1 <= 0`` (:func:`run_hybrid`).
    met : every judged figure within its bound at this design.
    info : plain numbers for the report (each name carries its unit).
    time_s : wall time of the check, s.
    kept : the problem's own record of the check, not reported: where the check ran in a pool's
        worker, the run's process hands it to its problem's ``adopt_check(x, check)`` (when it
        has one), so that the report serves the same figure instead of solving it again
        (:meth:`pipeline.run.evaluator.Evaluator.map_calls`).
    """

    factors: dict[int, float]
    met: bool
    info: dict[str, Any] = field(default_factory=dict)
    time_s: float = 0.0
    kept: Any = field(default=None, compare=False, repr=False)


#: re-converges of a start on a calibrated constraint (:func:`run_hybrid`) at most
CALIBRATION_ROUNDS = 3


@dataclass(frozen=True)
class HybridResult(GAResult):
    """A :class:`~optimise.ga.GAResult` of both stages (``generations``: the GA's, then one per
    batch of the gradient stage), with ``report``: ``best_stage`` (``"ga"`` or
    ``"gradient"``), ``n_evaluations`` per stage, ``stop`` (why the stage ended) and one entry
    per start (its objective at the start and the end, iterations, evaluations, why it
    stopped)."""

    report: dict[str, Any] = field(default_factory=dict)
    #: the problem's exact :class:`~optimise.design_jacobian.DesignJacobian` at ``best.x`` when
    #: the gradient stage took one there (the report's sensitivities reuse it), else None
    jacobian: Any = None


@dataclass(frozen=True)
class GradientStep(Generation):
    """One batch of the gradient stage, passed to ``on_generation`` like a generation (its
    ``index`` counts on from the GA stage's): a run shows it as a gradient step, not as a
    generation beyond the GA's ``n_gen``."""


def residuals_of(evaluation: Evaluation) -> np.ndarray | None:
    """(n_res,) the residuals ``residual_1`` ... an evaluation carries (see
    :meth:`optimise.problem.DesignProblem.with_residuals`), or None when it carries none or a
    failed design's."""
    if evaluation.reason:
        return None
    values = []
    while (key := f"residual_{len(values) + 1}") in evaluation.metrics:
        values.append(evaluation.metrics[key])
    if not values:
        return None
    r = np.asarray(values, dtype=float)
    return r if np.all(np.isfinite(r)) else None


def pieces_of(
    jac: DesignJacobian, n_con: int, span: np.ndarray
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """The constraint rows a problem gives as pieces: ``jac.info["g_pieces"]`` maps a row
    index c to ``{"values": (p,), "gradients": (p, n_var)}``, smooth functions of the design
    whose max is row c (a peak stress: one piece per place and row of the path it may sit at).
    Returned per row as (values (p,), gradients (p, n_var) times ``span``: per normalised unit);
    rows whose pieces are missing, malformed or not finite are left out (the row's own
    derivative serves)."""
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    given = jac.info.get("g_pieces") if isinstance(jac.info, dict) else None
    for c, piece in (given or {}).items():
        try:
            values = np.asarray(piece["values"], dtype=float).ravel()
            grads = np.asarray(piece["gradients"], dtype=float)
        except (KeyError, TypeError, ValueError):
            continue
        ok = 0 <= int(c) < n_con and len(values) and grads.shape == (len(values), len(span))
        if ok and np.all(np.isfinite(values)) and np.all(np.isfinite(grads)):
            out[int(c)] = (values, grads * span)
    return out


def pick_starts(
    space: DesignSpace, evaluations: Sequence[Evaluation], n: int, min_distance: float
) -> list[Evaluation]:
    """Up to ``n`` good, distinct designs: evaluated ones ranked as :func:`~optimise.ga.best_of`
    ranks them (feasible by objective, then by violation), each at least ``min_distance`` (max
    norm, bound-normalised) from those chosen before it."""
    evaluated = [e for e in evaluations if not e.reason]
    ranked = sorted(
        evaluated, key=lambda e: (not e.feasible, e.violation if not e.feasible else 0.0, e.f[0])
    )
    span = space.upper - space.lower
    chosen: list[Evaluation] = []
    for ev in ranked:
        u = (ev.x - space.lower) / span
        if all(np.max(np.abs(u - (c.x - space.lower) / span)) >= min_distance for c in chosen):
            chosen.append(ev)
            if len(chosen) == n:
                break
    return chosen


class _Stop(FlexoptError):
    """Ends one start (the stop rule, or the stage's budget) from inside SciPy's loop (control
    flow, caught in this module; under FlexoptError as every flexopt exception)."""

    def __init__(self, reason: str, budget: bool = False) -> None:
        super().__init__(reason)
        self.reason = reason
        self.budget = budget


@dataclass(frozen=True)
class _Evaluate:
    """A start's request: evaluate the (m, n_var) designs ``X`` (one batch of the run)."""

    X: np.ndarray


@dataclass(frozen=True)
class _Call:
    """A start's request: the problem's hook ``kind`` (:data:`optimise.hook_call.HOOKS`) at the
    design ``x`` (n_var,)."""

    kind: str
    x: np.ndarray


#: what :func:`run_hybrid`'s ``requests`` is given and returns: (m, n_var) designs and hook calls
#: (kind, x (n_var,)) to run as one batch -> (m evaluations, one HookAnswer per call)
Requests = Callable[
    [np.ndarray, Sequence[tuple[str, np.ndarray]]],
    tuple[Sequence[Evaluation], Sequence[HookAnswer]],
]


class _Stage:
    """What the gradient stage's starts share: the run's ``evaluate`` (every batch counted,
    reported as a generation), the hooks, the checks made and the counts for the report. Each
    start's own state is a :class:`_Start`; :meth:`serve` answers one round of their requests
    as one batch."""

    def __init__(
        self,
        space: DesignSpace,
        evaluate: Callable[[np.ndarray], Sequence[Evaluation]],
        config: HybridConfig,
        ga: GAResult,
        on_generation: Callable[[Generation], None] | None,
        jacobian: Callable[[np.ndarray], DesignJacobian | None] | None = None,
        check: Callable[[np.ndarray], ConstraintCheck | None] | None = None,
        requests: Requests | None = None,
        ahead: bool = False,
    ) -> None:
        self.space = space
        self.check = check
        #: the parts a check splits into over the pool's workers (the problem's ``check_parts``:
        #: ``check(x, part=p)`` computes part p, ``check(x, part=(answers...))`` merges them;
        #: :meth:`serve`); 1: whole, where ``requests`` does not run calls in parallel
        owner = getattr(check, "__self__", None)
        parts = int(getattr(owner, "check_parts", 1) or 1)
        self.check_parts = parts if ahead and requests is not None else 1
        #: take the Jacobian at a start's trial design in the trial's own round when that round
        #: holds another start's Jacobian or check (:meth:`serve`): only where ``requests`` runs
        #: the calls in parallel (a pool of two or more workers)
        self.ahead = ahead and requests is not None
        #: the Jacobians so taken, by design bytes, until a start asks for one (:meth:`taken`)
        self.taken_ahead: dict[bytes, HookAnswer] = {}
        #: every exact Jacobian the problem answered, by design bytes (the result's at its best)
        self.found: dict[bytes, DesignJacobian] = {}
        #: the checks made, by design (a design checked twice is checked once); their count and
        #: time for the report
        self.checked: dict[bytes, ConstraintCheck | None] = {}
        self.check_time_s = 0.0
        #: the objective of the lowest start's design where its first check was met (else inf:
        #: :func:`_calibrate_starts`; a start whose best is not lower is not checked), and how
        #: many starts were spared their check
        self.best_verified_f = math.inf
        self.checks_spared = 0
        self.jacobian = jacobian if config.exact_jacobian else None
        #: Jacobians taken: "exact" (the problem's), "finite_differences" (a batch of columns);
        #: counts only, so a resumed run's report equals the uninterrupted one's
        self.jacobians = {"exact": 0, "finite_differences": 0}
        self.span = space.upper - space.lower
        self.evaluate = evaluate
        self.requests = requests
        self.config = config
        self.on_generation = on_generation
        self.everything: list[Evaluation] = [e for g in ga.generations for e in g.evaluations]
        #: the best evaluation so far in the order the batches ran (what a generation reports)
        self.best = ga.best
        self.generations: list[Generation] = list(ga.generations)
        self.n = 0

    def x_of(self, u: np.ndarray) -> np.ndarray:
        """(n_var,) the design of normalised ``u``, inside the bounds."""
        return self.space.clip(self.space.lower + np.clip(u, 0.0, 1.0) * self.span)

    def u_of(self, x: np.ndarray) -> np.ndarray:
        return (np.asarray(x, dtype=float) - self.space.lower) / self.span

    def serve(self, asked: Sequence[_Evaluate | _Call]) -> list[Any]:
        """Answer one round of requests (one per live start) as one batch: every design asked
        for is one generation of the run; the hook calls run beside them (on the pool's workers
        where ``requests`` sends them there). Returns per request its evaluations (a list) or
        its :class:`~optimise.hook_call.HookAnswer`."""
        blocks = [r.X for r in asked if isinstance(r, _Evaluate)]
        X = np.vstack(blocks) if blocks else np.zeros((0, self.space.n_var))
        # one call per design and kind: two starts asking the same are answered once
        unique: dict[tuple[str, bytes], int] = {}
        calls: list[tuple[str, np.ndarray]] = []
        for r in asked:
            if isinstance(r, _Call) and (r.kind, r.x.tobytes()) not in unique:
                unique[(r.kind, r.x.tobytes())] = len(calls)
                calls.append((r.kind, r.x))
        early = self._ahead_calls(asked, unique)
        calls.extend(("jacobian", x) for x in early)
        if self.requests is not None and calls:
            sent, spans = self._split(calls)
            evaluations, got = self.requests(X, sent)
            evaluations, got = list(evaluations), list(got)
            if len(got) != len(sent):
                raise OptimiseError(f"{len(got)} answers for {len(sent)} calls")
            answers = [self._joined(c, got[a:b]) for c, (a, b) in zip(calls, spans, strict=True)]
        else:  # in this process: the designs as one batch, then the hooks one after another
            evaluations = list(self.evaluate(X)) if len(X) else []
            answers = [self._call_here(kind, x) for kind, x in calls]
        if len(evaluations) != len(X) or len(answers) != len(calls):
            raise OptimiseError(
                f"evaluate returned {len(evaluations)} results for {len(X)} designs and "
                f"{len(answers)} for {len(calls)} calls"
            )
        if len(X):
            self.n += len(X)
            self.everything.extend(evaluations)
            self.best = best_of((self.best, *evaluations))
            gen = GradientStep(
                len(self.generations), tuple(evaluations), self.best, len(self.everything), X
            )
            self.generations.append(gen)
            if self.on_generation is not None:
                self.on_generation(gen)
        for (kind, x), answer in zip(calls, answers, strict=True):
            if kind == "jacobian" and answer.value is not None:
                self.found[x.tobytes()] = answer.value
        for i, x in enumerate(early):
            self.taken_ahead[x.tobytes()] = answers[len(calls) - len(early) + i]
        while len(self.taken_ahead) > AHEAD_KEPT:  # rejected trials' are never asked for
            del self.taken_ahead[next(iter(self.taken_ahead))]
        out: list[Any] = []
        row = 0
        for r in asked:
            if isinstance(r, _Evaluate):
                out.append(evaluations[row : row + len(r.X)])
                row += len(r.X)
            else:
                out.append(answers[unique[(r.kind, r.x.tobytes())]])
        return out

    def _ahead_calls(
        self, asked: Sequence[_Evaluate | _Call], unique: dict[tuple[str, bytes], int]
    ) -> list[np.ndarray]:
        """The designs (n_var,) of this round whose Jacobian is taken in the round itself: a
        start's one trial design, and a design a start has checked (the check's round is long).

        Why: in lockstep a round lasts as long as its longest request. When one start asks for
        a Jacobian (~7 designs' time) or a check (~70) and another for one trial design, the
        second start's worker idles after the trial; a Gauss-Newton start that accepts its trial
        asks for the Jacobian there next (:func:`_gauss_newton`), so taking it now, on the
        worker that solved the trial (:meth:`pipeline.parallel.ProcessPool.run` queues it right
        behind that design, whose solved path the Jacobian reuses), saves that start a round.
        A rejected trial's Jacobian is never used (its worker's time only). The Jacobian is a
        deterministic function of the design, so a start's answers, and its designs, are the
        same with or without this; the rounds (generations) are fewer and ordered otherwise,
        the same on every run (it depends on the requests only, never on timing)."""
        if not self.ahead or self.jacobian is None or not unique:
            return []
        early: list[np.ndarray] = []
        for r in asked:
            if isinstance(r, _Evaluate) and len(r.X) == 1:
                x = r.X[0]
            elif isinstance(r, _Call) and r.kind == "check":
                # a checked design: a start whose check is not met goes on from it, asking its
                # Jacobian first (_calibrate), and the report's sensitivities are the best's
                x = r.x
                if x.tobytes() in self.found:
                    continue
            else:
                continue
            key = x.tobytes()
            if ("jacobian", key) not in unique and key not in self.taken_ahead:
                if not any(key == e.tobytes() for e in early):
                    early.append(np.array(x, dtype=float))
        return early

    def _split(
        self, calls: Sequence[tuple[str, np.ndarray]]
    ) -> tuple[list[tuple[str, np.ndarray]], list[tuple[int, int]]]:
        """The calls sent to the pool for ``calls``: a check whose problem splits it
        (:attr:`check_parts` > 1) as its parts ``"check:p"``, the last part first (the one that
        also re-solves the peak: the longer), each on its own worker; returns them and, per
        call, the slice of them that answers it.

        Why: a check (~0.8-1 s CPU on the constant-force study) held its round, and the other
        start in it, on one worker while the other idled; its parts are independent solves
        (pipeline/studies/_constant_force_split.py). Its answer, merged in this process
        (:meth:`_joined`), is the whole check's, so the rounds and designs are unchanged."""
        sent: list[tuple[str, np.ndarray]] = []
        spans: list[tuple[int, int]] = []
        for kind, x in calls:
            start = len(sent)
            if kind == "check" and self.check_parts > 1:
                sent.extend((f"check:{p}", x) for p in reversed(range(self.check_parts)))
            else:
                sent.append((kind, x))
            spans.append((start, len(sent)))
        return sent, spans

    def _joined(self, call: tuple[str, np.ndarray], got: Sequence[HookAnswer]) -> HookAnswer:
        """The answer to ``call`` from its parts' answers ``got`` (last part first, as
        :meth:`_split` sent them): one answer as it is; a check's parts merged by the problem's
        ``check(x, part=(part 0's, part 1's, ...))`` here (a part that failed is passed as None:
        the problem then makes the whole check here). ``time_s``: the longest part's and the
        merge's."""
        if len(got) == 1:
            return got[0]
        kind, x = call
        for answer in got:
            if answer.error:
                log.warning("hybrid: a part of the problem's check raised: %s", answer.error)
        values = tuple(answer.value for answer in reversed(got))
        merged = hook_answer(functools.partial(self.check, part=values), x)
        return replace(merged, time_s=merged.time_s + max(a.time_s for a in got))

    def taken(self, request: _Evaluate | _Call) -> HookAnswer | None:
        """The Jacobian taken ahead (:meth:`_ahead_calls`) that answers ``request``, or None;
        it is handed out once."""
        if not isinstance(request, _Call) or request.kind != "jacobian":
            return None
        return self.taken_ahead.pop(request.x.tobytes(), None)

    def _call_here(self, kind: str, x: np.ndarray) -> HookAnswer:
        hook = self.jacobian if kind == "jacobian" else self.check
        return hook_answer(hook, x) if hook is not None else HookAnswer()


class _Start:
    """One start of the gradient stage: its calibration, its evaluations, and the requests it
    makes of the stage (generators: ``yield`` a request, receive its answer; a start is run
    alone or in lockstep with the others by :func:`_drive`, with the same answers)."""

    def __init__(self, stage: _Stage, n_con: int) -> None:
        self.stage = stage
        self.config = stage.config
        self.space = stage.space
        #: per constraint row, the factor k of this start's calibration (1: none): the start
        #: sees ``k (g + 1) - 1`` (:meth:`view`)
        self.factors = np.ones(n_con)
        #: the calibration rounds (:func:`_calibrate`), and the designs whose check was met (by
        #: design key, in the order found)
        self.rounds: list[dict[str, Any]] = []
        self.verified: dict[bytes, Evaluation] = {}
        #: every evaluation this start asked for, in order, and how many
        self.mine: list[Evaluation] = []
        #: the last exact Jacobian's constraint pieces (:func:`pieces_of`), in normalised units
        self.pieces: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def x_of(self, u: np.ndarray) -> np.ndarray:
        return self.stage.x_of(u)

    def u_of(self, x: np.ndarray) -> np.ndarray:
        return self.stage.u_of(x)

    def view(self, ev: Evaluation) -> Evaluation:
        """``ev`` as this start's calibration sees it: each calibrated row c (factor ``k !=
        1``) is ``k (g_c + 1) - 1``, so ``feasible`` and ``violation`` follow (the stored
        evaluation is unchanged)."""
        k = self.factors
        if ev.reason or not len(k) or np.all(k == 1.0):
            return ev
        g = np.asarray(ev.g, dtype=float)
        return replace(ev, g=np.where(k != 1.0, k * (g + 1.0) - 1.0, g))

    def batch(self, U: np.ndarray) -> Any:
        """(generator) Evaluate (m, n_var) normalised designs as one request; returns their
        evaluations. Raises :class:`_Stop` (budget) when the stage's ``max_evaluations`` would
        be passed."""
        X = np.array([self.x_of(u) for u in np.atleast_2d(U)])
        limit = self.config.max_evaluations
        if limit is not None and self.stage.n + len(X) > limit:
            raise _Stop(f"the gradient stage's max_evaluations ({limit})", budget=True)
        evaluations = yield _Evaluate(X)
        self.mine.extend(evaluations)
        return evaluations

    def verify(self, ev: Evaluation) -> Any:
        """(generator) The problem's :class:`ConstraintCheck` at the evaluated design ``ev``
        (once per design for the whole stage; a deterministic function of it, so a resumed run
        makes the same ones), or None when the problem has none or it did not answer."""
        stage = self.stage
        x = np.asarray(ev.x, dtype=float)
        key = x.tobytes()
        if key not in stage.checked:
            answer: HookAnswer = yield _Call("check", x)
            if key not in stage.checked:  # another start may have asked in the same round
                if answer.error:  # an aid: its failure must not end the run (the verdict judges)
                    log.warning("hybrid: the problem's constraint check raised: %s", answer.error)
                stage.checked[key] = answer.value
                stage.check_time_s += answer.time_s
        return stage.checked[key]

    def exact(self, ev: Evaluation, n_res: int | None, n_con: int) -> Any:
        """(generator) The problem's exact derivatives at the evaluated design ``ev`` in
        normalised units (d/du = d/dx (upper - lower)): residuals (n_res, n_var) (None when
        ``n_res`` is None), constraints (n_con, n_var), objective (n_var,); None when there is
        no hook, it answers None or its shapes do not fit (the caller then takes finite
        differences). Not a new design: nothing is evaluated, stored or counted as an
        evaluation."""
        stage = self.stage
        if stage.jacobian is None:
            return None
        answer: HookAnswer = yield _Call("jacobian", np.asarray(ev.x, dtype=float))
        if answer.error:  # an aid, not a requirement: forward differences instead
            log.warning(
                "hybrid: the problem's Jacobian raised (%s); forward differences instead",
                answer.error,
            )
            return None
        jac = answer.value
        n_var = len(stage.span)
        if jac is None or np.shape(jac.g) != (n_con, n_var) or np.shape(jac.f)[1:] != (n_var,):
            return None
        J = None
        if n_res is not None:
            if jac.residuals is None or np.shape(jac.residuals) != (n_res, n_var):
                return None
            J = np.asarray(jac.residuals, dtype=float) * stage.span
        stage.jacobians["exact"] += 1
        self.pieces = pieces_of(jac, n_con, stage.span)
        Jg = np.asarray(jac.g, dtype=float) * stage.span
        k = self.factors
        if len(k) == n_con and np.any(k != 1.0):  # a calibrated row: k (g + 1) - 1, k g' its slope
            Jg = Jg * k[:, None]
            self.pieces = {
                c: (k[c] * (h + 1.0) - 1.0, k[c] * H) if k[c] != 1.0 else (h, H)
                for c, (h, H) in self.pieces.items()
            }
        return J, Jg, np.asarray(jac.f[0]) * stage.span

    def jacobian_designs(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n_var, n_var) the forward-difference designs around ``u`` and (n_var,) their signed
        steps (backward where the forward step would leave [0, 1])."""
        h = self.config.fd_step
        self.stage.jacobians["finite_differences"] += 1
        steps = np.where(u + h <= 1.0, h, -h)
        return u[None, :] + np.diag(steps), steps

    def alone(self, request: Any) -> Any:
        """Run the request generator ``request`` to its end with this start alone (SLSQP's
        callbacks, which SciPy calls synchronously); returns its value."""
        try:
            asked = next(request)
            while True:
                (answer,) = self.stage.serve([asked])
                asked = request.send(answer)
        except StopIteration as done:
            return done.value


def _drive(
    stage: _Stage, runs: Sequence[Any], lockstep: bool
) -> list[tuple[Any, BaseException | None]]:
    """Run the starts' request generators ``runs`` to their ends; returns per start (its
    value, or None and the :class:`_Stop` that ended it).

    ``lockstep``: every live start's next request goes into one round (:meth:`_Stage.serve`:
    the designs one batch, the hook calls beside them), so the starts' Jacobians and checks run
    at the same time on a pool's workers; otherwise one start after the other, as a shared
    budget needs (it would split differently between starts in lockstep). A start's requests
    and answers are the same either way (each is a deterministic function of its design, and
    a start reads nothing another writes but the checks' cache, whose answers are the same), so
    each start's designs are too; only the order of the batches in the run differs. A
    :class:`_Stop` of the budget ends the stage: the starts not yet run do not run."""
    out: list[tuple[Any, _Stop | None]] = [(None, None)] * len(runs)
    pending: dict[int, Any] = {}  # start -> its request waiting for an answer
    following = iter(range(len(runs)))
    stopped = False

    def step(i: int, answer: Any, first: bool) -> None:
        nonlocal stopped
        try:
            pending[i] = next(runs[i]) if first else runs[i].send(answer)
        except StopIteration as done:
            pending.pop(i, None)
            out[i] = (done.value, None)
        except _Stop as stop:
            pending.pop(i, None)
            out[i] = (None, stop)
            stopped = stopped or stop.budget

    def admit() -> None:  # the next start(s): all in lockstep, else the next that asks
        for i in following:
            step(i, None, True)
            if stopped or (pending and not lockstep):
                return

    admit()
    while pending and not stopped:
        live = sorted(pending) if lockstep else [min(pending)]
        # a Jacobian taken ahead answers its start at once: it asks again in this same round
        ready = [(i, stage.taken(pending[i])) for i in live]
        ready = [(i, answer) for i, answer in ready if answer is not None]
        if ready:
            for i, answer in ready:
                step(i, answer, False)
        else:
            answers = stage.serve([pending[i] for i in live])
            for i, answer in zip(live, answers, strict=True):
                step(i, answer, False)
        if not pending and not stopped:
            admit()
    for i in list(pending):  # the budget ended the stage under these starts too
        runs[i].close()
        out[i] = (None, next(stop for _, stop in out if stop is not None and stop.budget))
    return out


class StallRule:
    """The stop rule of a start: no improvement of its best objective beyond ``tolerance``
    (relative to it) over ``patience`` iterations in a row; ``f0`` is the start's objective."""

    def __init__(self, f0: float, tolerance: float, patience: int) -> None:
        self.best = f0
        self.tolerance = tolerance
        self.patience = patience
        self.stalled = 0

    def update(self, f: float) -> str | None:
        """Record one iteration's best objective; the stop reason when the rule fires."""
        if f < self.best - self.tolerance * max(abs(self.best), 1e-300):
            self.stalled = 0
        else:
            self.stalled += 1
        self.best = min(self.best, f)
        return self.verdict()

    def restart(self, f: float) -> None:
        """Progress of another kind (an infeasible start's violation fell): count again from
        ``f``."""
        self.best = f
        self.stalled = 0

    def verdict(self) -> str | None:
        """The stop reason when the rule fires, else None."""
        if self.stalled >= self.patience:
            return (
                f"no improvement beyond {self.tolerance:g} (relative) over {self.patience} "
                "iterations"
            )
        return None


def _linear_rows(
    g: np.ndarray, Jg: np.ndarray, pieces: dict[int, tuple[np.ndarray, np.ndarray]] | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linearised constraints as rows: (k,) values, (k, n_var) gradients and (k,) the row
    c each belongs to. A row given as pieces (:func:`pieces_of`) is one row per piece, shifted
    so that their max is ``g[c]`` (the evaluation's value: the pieces are its terms), the others
    one row each (``g``, ``Jg``)."""
    values, grads, owner = [], [], []
    for c in range(len(g)):
        if pieces and c in pieces:
            h, H = pieces[c]
            values.append(h + (g[c] - float(np.max(h))))
            grads.append(H)
            owner.append(np.full(len(h), c))
        else:
            values.append(g[c : c + 1])
            grads.append(Jg[c : c + 1])
            owner.append(np.array([c]))
    if not values:
        return np.zeros(0), np.zeros((0, Jg.shape[1])), np.zeros(0, dtype=int)
    return np.concatenate(values), np.vstack(grads), np.concatenate(owner)


def _predicted(g: np.ndarray, Jg: np.ndarray, d: np.ndarray, pieces: dict | None) -> np.ndarray:
    """(n_con,) each constraint row's value after the step ``d`` by its linearisation: the max
    of its pieces' where it has pieces."""
    values, grads, owner = _linear_rows(g, Jg, pieces)
    out = np.full(len(g), -np.inf)
    np.maximum.at(out, owner, values + grads @ d)
    return out


def _gauss_newton_step(
    r: np.ndarray,
    J: np.ndarray,
    g: np.ndarray,
    Jg: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    backoff: np.ndarray,
    pieces: dict[int, tuple[np.ndarray, np.ndarray]] | None = None,
    broken: np.ndarray | None = None,
    exact: bool = False,
) -> np.ndarray:
    """(n_var,) the step d minimising ``||r + J d||**2`` subject to ``g + Jg d <= -backoff``
    and ``lower <= d <= upper`` (the trust region within the bounds).

    ``exact`` (``HybridConfig.step_solver == "exact"``): solved exactly where the linearised
    constraints can be met inside the trust region: a
    least-squares problem with linear inequalities (:func:`least_squares_inequalities`, Lawson
    and Hanson's LSI -> LDP -> NNLS, a direct active-set method), with ``STEP_DAMPING * ||d||**2``
    added to the scaled objective. Why the damping: ``J`` has fewer rows than columns (the
    constant-force study: 10 residuals, 23 variables), so the objective is flat along J's null
    space and the constraints alone do not fix the step; the damping picks the shortest of the
    equally good steps (it changes the scaled objective by <= 1.25e-7 inside the largest
    radius, 0.5). Otherwise, and where the constraints cannot be met, SciPy's SLSQP solves the
    elastic problem (what cannot be met is paid for at :data:`ELASTIC_WEIGHT`). SLSQP takes
    ~12 ms a step in the run's process while the workers idle (~1 s of a constant-force run),
    and it often stops short of the QP's optimum (its BFGS model of ``J^T J`` after 15-45
    iterations: on constant-force, steps whose model objective was up to 24x the optimum's) or
    past a linearised row's aim by up to 1e-7, more than :data:`FEASIBILITY_MARGIN`; the exact
    solve takes ~1 ms and meets the rows to ~1e-10 (``benchmarks/gauss_newton_step.py``;
    docs/benchmarks.md, "Session 34").

    r (n_res,), J (n_res, n_var), g (n_con,), Jg (n_con, n_var), lower, upper (n_var,), backoff
    (n_con,) >= 0: how far inside each linearised constraint to aim (its linearisation error
    as seen so far). ``pieces`` (:func:`pieces_of`): a row that is a max of smooth pieces is
    held by each piece's linearisation (``h_k + H_k d <= -backoff_c``), one slack per row, so
    the step sees a piece other than the active one rise (the peak stress moving from the clamp
    to mid-beam) instead of stepping onto it blind. An infeasible design's step aims at
    feasibility to first order. The objective is scaled by ``||r||**2`` (SLSQP's tolerances are
    absolute).
    """
    from scipy.optimize import minimize

    n, m = len(lower), len(g)
    scale = max(float(r @ r), 1e-300)
    values, grads, owner = _linear_rows(g, Jg, pieces)

    def objective(z: np.ndarray) -> float:
        e = r + J @ z[:n]
        return 0.5 * float(e @ e) / scale + ELASTIC_WEIGHT * float(np.sum(z[n:]))

    def gradient(z: np.ndarray) -> np.ndarray:
        return np.concatenate([J.T @ (r + J @ z[:n]) / scale, np.full(m, ELASTIC_WEIGHT)])

    # elastic: h + H d <= -backoff + s with slacks s >= 0 (one per constraint row) at a high
    # price, so a step that cannot reach feasibility in the trust region still lowers the
    # violation as far as it can
    slack = np.zeros((len(values), m))
    slack[np.arange(len(values)), owner] = 1.0
    A = np.hstack([-grads, slack])
    # aim inside by the backoff, but never further in than the design already is: a feasible
    # design's step need not move inwards (at a cost in the objective) to honour a backoff
    # larger than its slack; d = 0 stays a feasible step. Except for the rows ``broken`` by
    # the last trial from this very design (session 33): on the boundary of a curved row (the
    # stress row at its optimum, g ~ -1e-7) the retry must aim inside by the error it just
    # learnt, else every retry aims at the same boundary and only a smaller radius helps,
    # iteration after iteration (constant-force seed 1: the last 14 of 40 iterations so).
    limit = -backoff - FEASIBILITY_MARGIN
    clamp = g <= 0.0 if broken is None else (g <= 0.0) & ~broken
    limit = np.where(clamp, np.maximum(limit, g), limit)
    aim = limit[owner] - values
    d = _exact_step(r, J, grads, aim, lower, upper) if exact else None
    if d is not None:
        return d
    start = np.zeros(m)
    np.maximum.at(start, owner, np.maximum(-aim, 0.0))
    constraints = [{"type": "ineq", "fun": lambda z: aim + A @ z, "jac": lambda z: A}] if m else []
    qp = minimize(
        objective,
        np.concatenate([np.zeros(n), start]),
        jac=gradient,
        bounds=[*zip(lower, upper, strict=True), *([(0.0, None)] * m)],
        constraints=constraints,
        method="SLSQP",
        options={"maxiter": 200, "ftol": 1e-12},
    )
    return np.clip(np.asarray(qp.x[:n], dtype=float), lower, upper)


def _exact_step(
    r: np.ndarray,
    J: np.ndarray,
    grads: np.ndarray,
    aim: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> np.ndarray | None:
    """(n_var,) the step of :func:`_gauss_newton_step` with every linearised row held (``aim +
    (-grads) d >= 0``, grads (k, n_var), aim (k,)) and ``lower <= d <= upper``: the minimiser of
    ``||r + J d||**2 / ||r||**2 + STEP_DAMPING ||d||**2``; None where no step meets them all
    (the caller then solves the elastic problem)."""
    n = len(lower)
    root = np.sqrt(max(float(r @ r), 1e-300))
    E = np.vstack([J / root, np.sqrt(STEP_DAMPING) * np.eye(n)])
    f = np.concatenate([-r / root, np.zeros(n)])
    eye = np.eye(n)
    G = np.vstack([-grads, eye, -eye])
    h = np.concatenate([-aim, lower, -upper])
    d = least_squares_inequalities(E, f, G, h)
    if d is None:
        return None
    return np.clip(d, lower, upper)


def least_squares_inequalities(
    E: np.ndarray, f: np.ndarray, G: np.ndarray, h: np.ndarray
) -> np.ndarray | None:
    """(n,) the x minimising ``||E x - f||`` subject to ``G x >= h``, or None when no x meets
    the constraints (to round-off). E (m, n) of full column rank n, f (m,), G (k, n), h (k,).

    Lawson and Hanson, *Solving Least Squares Problems* (1974), ch. 23: with ``E = Q R``
    (economic QR) and ``y = R x - Q^T f``, the problem is the least-distance problem ``min
    ||y|| s.t. (G R^-1) y >= h - G R^-1 Q^T f`` (LDP), whose solution comes from one
    non-negative least-squares problem (SciPy's ``nnls``): ``min ||[G~^T; h~^T] u - e_{n+1}||``
    over ``u >= 0``; its residual ``rho`` is zero when the constraints are inconsistent, else
    ``y = -rho[:n] / rho[n]``. The same reduction SLSQP makes inside each of its iterations;
    here it is made once, on the exact objective.
    """
    from scipy.linalg import qr, solve_triangular
    from scipy.optimize import nnls

    n = E.shape[1]
    Q, R = qr(E, mode="economic")
    ft = Q.T @ f
    Gt = solve_triangular(R, np.asarray(G, dtype=float).T, trans="T").T  # G R^-1 (k, n)
    ht = h - Gt @ ft
    A = np.vstack([Gt.T, ht[None, :]])
    e = np.zeros(n + 1)
    e[n] = 1.0
    try:
        u, _ = nnls(A, e, maxiter=50 * A.shape[1])
    except RuntimeError:  # NNLS did not converge: let the caller solve it otherwise
        return None
    rho = A @ u - e
    # rho[n] = u . h~ - 1 = -||rho||^2 <= 0: zero (to round-off) when the rows are inconsistent
    if -rho[n] <= 1e-12:
        return None
    y = -rho[:n] / rho[n]
    x = solve_triangular(R, y + ft)
    if len(h) and float(np.max(h - G @ x)) > 1e-9 * max(1.0, float(np.max(np.abs(h)))):
        return None  # round-off lost the constraints: the elastic solve decides
    return x


#: the damping of the exact Gauss-Newton step (:func:`_exact_step`), against the objective
#: scaled to 1 at the current design, in bound-normalised units: ties between equally good steps
#: (J's null space) go to the shortest
STEP_DAMPING = 1.0e-6

#: how far inside every linearised constraint row a step aims besides its backoff: SLSQP meets
#: its constraints to ~1e-10, and a trial on a linear constraint's boundary by that much is
#: infeasible by round-off (g > 0) and rejected (constraint rows are O(1): a stress ratio minus
#: 1, a band fraction)
FEASIBILITY_MARGIN = 1.0e-8

#: the price of a unit of linearised constraint violation in the Gauss-Newton step, against the
#: objective scaled to 1/2 at the current design: feasibility comes first
ELASTIC_WEIGHT = 1.0e3


STATIONARY = "the trust region shrank below 1e-6 (a stationary point)"


def _gauss_newton(run: _Start, start: Evaluation, n_con: int) -> Any:
    """(generator of requests, :class:`_Start`) A trust-region Gauss-Newton run from ``start``;
    returns (iterations, why it stopped).

    From a feasible design a step is taken when the trial is feasible and lowers ``||r||``
    (ratio of actual to predicted decrease > 1e-4); from an infeasible one when it lowers the
    violation (feasibility first). A constraint the trial violates that its linearisation said
    it would not sets that constraint's backoff to the error seen, so the next steps aim inside
    by it; a trial inside halves it. A constraint row given as pieces (an exact Jacobian's
    ``g_pieces``) is linearised piece by piece (:func:`_gauss_newton_step`).

    The stop rule (:class:`StallRule`) counts accepted steps only: a rejected trial says the
    model was wrong over that radius, not that the design is stationary, so it shrinks the
    radius (to half the step when the trial broke a constraint, whose backoff it has just
    learnt; to a quarter when it raised the objective) and the next step is tried from the same
    design with the same Jacobian. Rejections end a start only when the radius falls below
    1e-6 (:data:`STATIONARY`), or at ``max_iter`` or the stage's budget.
    """
    config = run.config
    u = run.u_of(start.x)
    current = run.view(start)  # as the start's calibration sees it (the evaluation unchanged)
    r = residuals_of(current)
    if r is None:
        return 0, "the start carries no residuals"
    rule = StallRule(float(current.f[0]), config.tolerance, config.patience)
    radius = 0.1
    backoff = np.zeros(n_con)
    # rows the last trial from this design broke (config.retry_inside; else never set)
    broken = np.zeros(n_con, dtype=bool)
    J = Jg = None
    pieces: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    frozen = np.zeros(len(u), dtype=bool)
    exact_qp = config.step_solver == "exact"
    for iteration in range(1, config.max_iter + 1):
        exact = (yield from run.exact(current, len(r), n_con)) if J is None else None
        if exact is not None:  # the problem's derivatives: no perturbed designs
            J, Jg, _ = exact
            pieces = run.pieces
            frozen[:] = False
        if J is None:  # a Jacobian at every accepted point (a rejected step reuses it)
            pieces = {}
            U, steps = run.jacobian_designs(u)
            columns = yield from run.batch(U)
            J = np.zeros((len(r), len(u)))
            Jg = np.zeros((n_con, len(u)))
            frozen[:] = False
            for i, ev in enumerate(map(run.view, columns)):
                ri = residuals_of(ev)
                if ri is None or ri.shape != r.shape:
                    frozen[i] = True  # a perturbed design failed: this variable stays put
                    continue
                J[:, i] = (ri - r) / steps[i]
                Jg[:, i] = (ev.g - current.g) / steps[i]
        lower = np.where(frozen, 0.0, np.maximum(-u, -radius))
        upper = np.where(frozen, 0.0, np.minimum(1.0 - u, radius))
        d = _gauss_newton_step(r, J, current.g, Jg, lower, upper, backoff, pieces, broken, exact_qp)
        predicted = 0.5 * float(r @ r) - 0.5 * float((r + J @ d) @ (r + J @ d))
        if current.feasible and predicted <= 0.0 and broken.any():
            # aiming inside the broken rows costs more than the step gains (a kink's error, not
            # a curvature's: it does not shrink with the step): aim at the boundary as before
            broken[:] = False
            d = _gauss_newton_step(
                r, J, current.g, Jg, lower, upper, backoff, pieces, broken, exact_qp
            )
            predicted = 0.5 * float(r @ r) - 0.5 * float((r + J @ d) @ (r + J @ d))
        size = float(np.max(np.abs(d))) if len(d) else 0.0
        if size < 1e-12 or (current.feasible and predicted <= 0.0):
            radius *= 0.25
            reason = rule.update(float(current.f[0]))
            if radius < 1e-6:
                return iteration, STATIONARY
            if reason:
                return iteration, reason
            continue
        (trial,) = yield from run.batch((u + d)[None, :])
        trial = run.view(trial)
        rt = residuals_of(trial)
        linear = _predicted(current.g, Jg, d, pieces) if n_con else np.zeros(0)
        if rt is not None and n_con:
            missed = trial.g > 0.0
            error = trial.g - linear
            # the last error seen where it mattered; halved where the trial kept inside, so a
            # wild step's error does not hold every later step back
            backoff = np.where(missed, np.maximum(error, 0.0), 0.5 * backoff)
        if current.feasible:
            actual = 0.5 * float(r @ r) - 0.5 * float(rt @ rt) if rt is not None else -np.inf
            ratio = actual / predicted if predicted > 0.0 else 0.0
        else:  # restoring: the radius follows how well the violation's model predicts it
            model = float(np.sum(np.maximum(linear, 0.0)))
            expected = current.violation - model
            ratio = (current.violation - trial.violation) / expected if expected > 0 else 0.0
        if current.feasible:
            accept = rt is not None and trial.feasible and ratio > 1e-4
        else:  # feasibility first
            accept = rt is not None and (trial.feasible or trial.violation < current.violation)
        if log.isEnabledFor(logging.DEBUG):  # each trial, for reading a start's path
            log.debug(
                "gauss-newton %d: f %.6g -> %s, |d| %.3g, radius %.3g, ratio %.3g, %s%s",
                iteration,
                float(current.f[0]),
                "failed" if rt is None else f"{float(trial.f[0]):.6g}",
                size,
                radius,
                ratio,
                "accepted" if accept else "rejected",
                ""
                if rt is None or not n_con
                else f"; g {trial.g} (linearised {linear}) from {current.g}",
            )
        if accept:
            restored = trial.feasible and not current.feasible
            u, current, r, J = run.u_of(trial.x), trial, rt, None
            broken[:] = False
            if ratio > 0.75 and size >= 0.99 * radius:
                radius = min(2.0 * radius, 0.5)
            elif ratio < 0.25:
                radius = max(0.25 * size, 1e-3 * radius)
            if restored or not current.feasible:
                rule.restart(float(current.f[0]))  # progress towards feasibility
                continue
        else:
            # rejected: not counted by the stop rule; a broken constraint has just taught its
            # backoff, so half the step is tried, an objective that rose a quarter of it
            broke = rt is not None and not trial.feasible
            if rt is not None and n_con and config.retry_inside:  # the retry aims inside them
                broken |= trial.g > 0.0
            radius = (0.5 if broke else 0.25) * size
            if radius < 1e-6:
                return iteration, STATIONARY
            continue
        reason = rule.update(float(current.f[0]))
        if reason:
            return iteration, reason
        if radius < 1e-6:
            return iteration, STATIONARY
    return config.max_iter, f"max_iter ({config.max_iter}) iterations"


def _slsqp(run: _Start, start: Evaluation, n_con: int) -> Any:
    """(generator, :class:`_Start`; it yields nothing: SciPy calls back synchronously, so its
    requests are served with this start alone, :meth:`_Start.alone`) SciPy's SLSQP from
    ``start``, gradients by forward differences in one batch each; returns (iterations, why it
    stopped)."""
    from scipy.optimize import minimize

    config = run.config
    f0 = max(abs(float(start.f[0])), 1e-12)
    known: dict[bytes, Evaluation] = {run.u_of(start.x).tobytes(): start}

    def value(u: np.ndarray) -> Evaluation:
        key = np.asarray(u, dtype=float).tobytes()
        if key not in known:
            (known[key],) = run.alone(run.batch(np.asarray(u, dtype=float)[None, :]))
        return known[key]

    def scaled(ev: Evaluation) -> tuple[float, np.ndarray]:
        if ev.reason:
            return _FAILED_SCALED, np.full(n_con, _FAILED_SCALED)
        return float(ev.f[0]) / f0, np.asarray(ev.g, dtype=float)

    gradients: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def gradient(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = np.asarray(u, dtype=float).tobytes()
        if key not in gradients and not value(u).reason:
            exact = run.alone(run.exact(value(u), None, n_con))
            if exact is not None:  # the problem's derivatives, at the objective's scale
                gradients[key] = (exact[2] / f0, exact[1])
        if key not in gradients:
            fu, gu = scaled(value(u))
            U, steps = run.jacobian_designs(np.asarray(u, dtype=float))
            df = np.zeros(len(u))
            dg = np.zeros((n_con, len(u)))
            for i, ev in enumerate(run.alone(run.batch(U))):
                if ev.reason:
                    continue  # a perturbed design failed: no slope along this variable
                fi, gi = scaled(ev)
                df[i] = (fi - fu) / steps[i]
                dg[:, i] = (gi - gu) / steps[i]
            gradients[key] = (df, dg)
        return gradients[key]

    rule = StallRule(float(start.f[0]), config.tolerance, config.patience)
    state = {"iterations": 0}

    def callback(u: np.ndarray) -> None:
        state["iterations"] += 1
        ev = value(u)
        best = min((e for e in known.values() if e.feasible), key=lambda e: e.f[0], default=ev)
        reason = rule.update(float(best.f[0]))
        if reason:
            raise _Stop(reason)

    constraints = (
        [
            {
                "type": "ineq",
                "fun": lambda u: -scaled(value(u))[1],
                "jac": lambda u: -gradient(u)[1],
            }
        ]
        if n_con
        else []
    )
    try:
        result = minimize(
            lambda u: scaled(value(u))[0],
            run.u_of(start.x),
            jac=lambda u: gradient(u)[0],
            bounds=[(0.0, 1.0)] * run.space.n_var,
            constraints=constraints,
            method="SLSQP",
            callback=callback,
            options={"maxiter": config.max_iter, "ftol": 1e-12},
        )
    except _Stop as stop:
        if stop.budget:
            raise
        return state["iterations"], stop.reason
    return state["iterations"], f"SLSQP: {result.message}"
    yield  # a generator like _gauss_newton (unreached)


class _GADone(FlexoptError):
    """Ends the GA stage early (see :attr:`HybridConfig.ga_n_gen`)."""


def _ga_stage(
    space: DesignSpace,
    evaluate: Callable[[np.ndarray], Sequence[Evaluation]],
    n_obj: int,
    n_con: int,
    config: HybridConfig,
    on_generation: Callable[[Generation], None] | None,
    initial: np.ndarray | None,
    until_feasible: bool = True,
) -> GAResult:
    """The GA for ``config.ga_n_gen`` generations; with ``until_feasible`` more until its best
    is feasible. Why the two: with forward differences (23 designs a Jacobian on the
    constant-force study) a gradient method from an infeasible GA design mostly spends itself
    restoring feasibility; with exact derivatives a restoring step costs one design, and the GA
    generations it saves are the larger cost (constant-force with 0.5 mm pad fillets, seed 1: the
    GA's first feasible best came at generation 9, 360 designs, seed 4 at 16, 640 designs; from
    generation 5's infeasible best Gauss-Newton restored and ended lower in 278 designs,
    docs/benchmarks.md).

    Stopped from its generation callback: pymoo draws the same populations whatever its
    ``n_gen``, so the stage is the first generations of the GA of ``config.ga`` (and a resume
    replays it)."""
    generations: list[Generation] = []

    def done(gen: Generation) -> None:
        generations.append(gen)
        if on_generation is not None:
            on_generation(gen)
        if config.ga_n_gen is not None and gen.index + 1 >= config.ga_n_gen:
            if gen.best.feasible or not until_feasible:
                raise _GADone

    try:
        return run_ga(space, evaluate, n_obj, n_con, config.ga, done, initial)
    except _GADone:
        best = generations[-1].best
        return GAResult(best, (best,), tuple(generations))


def run_hybrid(
    space: DesignSpace,
    evaluate: Callable[[np.ndarray], Sequence[Evaluation]],
    n_obj: int,
    n_con: int,
    config: HybridConfig = HybridConfig(),
    on_generation: Callable[[Generation], None] | None = None,
    initial: np.ndarray | None = None,
    jacobian: Callable[[np.ndarray], DesignJacobian | None] | None = None,
    check: Callable[[np.ndarray], ConstraintCheck | None] | None = None,
    requests: Requests | None = None,
    lockstep: bool | None = None,
    ahead: bool = False,
) -> HybridResult:
    """Minimise one objective subject to ``n_con`` constraints g <= 0 over ``space``: the GA
    (``config.ga``), then the gradient method from ``config.starts`` distinct good GA designs.

    Parameters are those of :func:`optimise.ga.run_ga`; every batch of the gradient stage is
    passed to ``on_generation`` as one more generation. With ``config.local ==
    "gauss_newton"`` the evaluations must carry residuals (:func:`residuals_of`).
    ``jacobian(x)`` (the problem's :meth:`~optimise.problem.DesignProblem.jacobian`), where
    given and ``config.exact_jacobian``, replaces the forward-difference columns wherever it
    answers; every design the stage steps to is still evaluated by ``evaluate``.

    ``check(x)`` (the problem's :meth:`~optimise.problem.DesignProblem.check_constraints`; when
    not given, found on the object ``jacobian`` is a bound method of), with Gauss-Newton: once
    every start's method has ended, each start's best design is checked by the figures the
    verdict judges, the lowest first (:func:`_calibrate_starts`: where that one is met, a start
    whose best is not lower is not checked); where one exceeds its bound, that start's row is
    tightened by the measured factor and Gauss-Newton goes on (:func:`_calibrate`). The
    result's best is then the lowest design whose check was met (the stage's best when none
    was); ``report["checks"]``: how many designs were checked, how many met, the checks' wall
    time, how many starts were ``spared`` a check; each start's ``calibration``: its rounds'
    figures.

    ``requests(X, calls)`` (optional; the run's evaluator on a process pool): evaluates the
    (m, n_var) designs ``X`` as ``evaluate`` does and answers the hook ``calls`` ((kind, x):
    ``"jacobian"`` / ``"check"``, the problem's own hooks, :mod:`optimise.hook_call`) beside
    them as one batch, one :class:`~optimise.hook_call.HookAnswer` each. Without it the hooks
    run here, one after another (``jacobian`` and ``check``).

    ``lockstep`` (default: True for Gauss-Newton without ``max_evaluations``): the starts run
    at the same time, each round one batch of every live start's request (:func:`_drive`), so
    their Jacobians and checks run in parallel where ``requests`` sends them to workers. Each
    start's designs and the result are the same as one start after the other (False); only the
    order of the batches (generations) in the run differs. SLSQP's starts run one after the
    other (SciPy drives them); so do starts sharing a ``max_evaluations`` budget.

    ``ahead`` (with ``requests`` on two or more parallel workers, and exact Jacobians): in a
    lockstep round where one start asks for a Jacobian or a check and another for one trial
    design, the trial's Jacobian is taken in the same round (:meth:`_Stage._ahead_calls`), so a
    start that accepts its trial does not wait a round for it. The starts' designs, answers
    and result are the same; the rounds are fewer and ordered otherwise (deterministically).
    """
    if n_obj != 1:
        raise OptimiseError(f"the hybrid optimiser needs one objective, got {n_obj}")
    exact = jacobian is not None and config.exact_jacobian
    if check is None and config.local == "gauss_newton":
        # the problem's own check, found through its Jacobian hook (a bound method of it): the
        # runner hands the hybrid that hook; a problem without a check answers None
        owner = getattr(jacobian, "__self__", None)
        check = getattr(owner, "check_constraints", None)
    ga = _ga_stage(space, evaluate, n_obj, n_con, config, on_generation, initial, not exact)
    n_ga = ga.generations[-1].n_evaluations if ga.generations else 0
    stage = _Stage(space, evaluate, config, ga, on_generation, jacobian, check, requests, ahead)
    calibrated = stage.check is not None and config.local == "gauss_newton"
    method = _gauss_newton if config.local == "gauss_newton" else _slsqp
    starts = pick_starts(space, stage.everything, config.starts, config.min_distance)
    if lockstep is None:
        lockstep = config.local == "gauss_newton" and config.max_evaluations is None
    runs = [_Start(stage, n_con) for _ in starts]
    ended = _drive(
        stage, [method(run, s, n_con) for run, s in zip(runs, starts, strict=True)], lockstep
    )
    if calibrated:
        ended = _calibrate_starts(stage, runs, starts, ended, n_con, lockstep)
    report: dict[str, Any] = {
        "method": "hybrid",
        "local": config.local,
        "ga": {
            "n_evaluations": n_ga,
            "generations": len(ga.generations),
            "best_f": float(ga.best.f[0]),
        },
        "starts": [],
    }
    stop = f"every start stopped ({len(starts)} of {config.starts} distinct GA designs)"
    # the stage's best as one start after the other finds it (a batch's best is its first
    # lowest, so folding the starts in their order gives it whatever order the batches ran in)
    best = ga.best
    for number, (start, run, (value, stopped)) in enumerate(
        zip(starts, runs, ended, strict=True), 1
    ):
        if value is None and stopped is None:
            break  # never run: an earlier start's budget ended the stage
        best_before = best
        best = best_of((best, *run.mine))
        if stopped is not None:  # the budget: the stage ends here
            iterations, reason = -1, stopped.reason
            stop = f"reached {stopped.reason}"
        else:
            iterations, reason = value
        found = best_of((start, *run.mine))
        entry: dict[str, Any] = {
            "start": number,
            "x": [float(v) for v in start.x],
            "f_start": float(start.f[0]),
            "f_end": float(found.f[0]),
            "feasible_end": found.feasible,
            "iterations": iterations,
            "n_evaluations": len(run.mine),
            "improved_best": best is not best_before,
            "stop": reason,
        }
        if calibrated:
            entry["calibration"] = run.rounds
        report["starts"].append(entry)
    # designs whose check found every figure met, in the order of the starts
    verified = [e for run in runs for e in run.verified.values()]
    if verified:  # the best design the check found meeting every judged figure
        best = min(verified, key=lambda e: float(e.f[0]))
    ga_keys = {e.x.tobytes() for g in ga.generations for e in g.evaluations}
    report.update(
        best_stage="ga" if best.x.tobytes() in ga_keys else "gradient",
        best_f=float(best.f[0]),
        n_evaluations={"ga": n_ga, "gradient": stage.n},
        jacobians=dict(stage.jacobians),
        stop=stop,
    )
    if calibrated:
        report["checks"] = {
            "count": len(stage.checked),
            "met": sum(1 for c in stage.checked.values() if c is not None and c.met),
            "time_s": round(stage.check_time_s, 3),
            "best_verified": bool(verified),
            "spared": stage.checks_spared,
        }
    return HybridResult(
        best, (best,), tuple(stage.generations), report, stage.found.get(best.x.tobytes())
    )


def _calibrate_starts(
    stage: _Stage,
    runs: Sequence[_Start],
    starts: Sequence[Evaluation],
    ended: Sequence[tuple[Any, BaseException | None]],
    n_con: int,
    lockstep: bool,
) -> list[tuple[Any, BaseException | None]]:
    """Calibrate (:func:`_calibrate`) the starts whose gradient method ended on its own (not
    the budget), once every start's has; returns :func:`_drive`'s list with each calibrated
    start's (iterations, why it stopped) summed over its rounds, or the :class:`_Stop` that
    ended it.

    The start whose best design has the lowest objective is checked first, alone. Where its
    check is met, a start whose best is not lower is not checked at all: the result is the
    lowest design whose check was met, which that start's cannot become (a calibration only
    tightens its rows). On the constant-force study this spares one check of two (~0.5 s of
    both workers; the worse start, which ended first, used to be checked first). Where it is
    not met, every start calibrates as before (in lockstep where the stage is: its checks and
    Gauss-Newton rounds beside the others'). The decision depends on the starts' designs
    alone, so the starts in lockstep or one after the other make the same checks and ask for
    the same designs.
    """
    out = list(ended)
    done = [i for i, (value, stop) in enumerate(ended) if value is not None and stop is None]
    if not done:
        return out

    def objective(i: int) -> float:
        found = _candidate(runs[i], starts[i])
        return float(found.f[0]) if found is not None else math.inf

    first = min(done, key=lambda i: (objective(i), i))
    candidate = _candidate(runs[first], starts[first])
    if candidate is not None:
        _drive(stage, [runs[first].verify(candidate)], lockstep=False)
        check = stage.checked.get(candidate.x.tobytes())
        if check is not None and check.met:
            stage.best_verified_f = float(candidate.f[0])
    ended_here = _drive(
        stage,
        [_calibrate(runs[i], starts[i], n_con, *ended[i][0]) for i in done],
        lockstep,
    )
    for i, value in zip(done, ended_here, strict=True):
        out[i] = value
    return out


def _candidate(run: _Start, start: Evaluation) -> Evaluation | None:
    """The start's lowest design feasible as its calibration sees it (:meth:`_Start.view`),
    or None."""
    pairs = [(run.view(e), e) for e in (start, *run.mine) if not e.reason]
    feasible = [(v, e) for v, e in pairs if v.feasible]
    if not feasible:
        return None
    return min(feasible, key=lambda p: float(p[0].f[0]))[1]


def _calibrate(run: _Start, start: Evaluation, n_con: int, iterations: int, reason: str) -> Any:
    """(generator of requests) Check the start's best design by the problem's check (its
    verdict's figures); where a judged figure exceeds its bound, tighten that row by the
    measured factor (``k (g + 1) - 1 <= 0``, never loosened: the largest factor seen this
    start) and Gauss-Newton again from that design, at most :data:`CALIBRATION_ROUNDS` times.
    Each round's figures go to ``run.rounds``; a design whose check is met to
    ``run.verified``. Returns the start's (iterations, why it stopped) summed over the rounds.

    Why: the beam model under-reads the verdict's plane-stress peak by a few % near a taper
    kink (the ratio depends on the design), so a design held at the beam's bound x a fixed
    ``beam_stress_factor`` can be NOT MET; the measured ratio at the converged design is the
    bound's honest correction there, and re-measuring after each re-converge follows it as the
    design moves."""
    for round_ in range(CALIBRATION_ROUNDS + 1):
        candidate = _candidate(run, start)
        if candidate is None:
            run.rounds.append({"round": round_, "stop": "no design feasible as calibrated"})
            break
        record: dict[str, Any] = {
            "round": round_,
            "f": float(candidate.f[0]),
            "factors": {str(c): float(k) for c, k in enumerate(run.factors) if k != 1.0},
        }
        stage = run.stage
        key = candidate.x.tobytes()
        if float(candidate.f[0]) >= stage.best_verified_f and key not in stage.checked:
            # the lowest start's design is checked and met (:func:`_calibrate_starts`): the
            # result is the lowest verified design, which this start's cannot become
            run.rounds.append(
                {**record, "stop": "not checked: another start's design of lower objective "
                 f"({stage.best_verified_f:.6g}) is checked and met"}
            )  # fmt: skip
            stage.checks_spared += 1
            break
        found = yield from run.verify(candidate)
        if found is None:
            run.rounds.append({**record, "stop": "the check did not answer"})
            break
        record.update(met=found.met, **found.info)
        run.rounds.append(record)
        if found.met:
            run.verified[candidate.x.tobytes()] = candidate
            break
        if round_ == CALIBRATION_ROUNDS:
            break
        k = run.factors.copy()
        for c, factor in found.factors.items():
            if 0 <= c < n_con:
                k[c] = max(k[c], float(factor))  # never loosened within the start
        if np.all(k == run.factors):
            run.rounds[-1]["stop"] = "the check is not met but names no row to tighten"
            break
        run.factors = k
        more, reason = yield from _gauss_newton(run, candidate, n_con)
        iterations += more
    return iterations, reason
