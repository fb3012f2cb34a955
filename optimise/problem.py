"""The contract between a study kind and the optimisers / the run pipeline.

A :class:`DesignProblem` is built once from a validated study and then called for every design.
It must be picklable (it is sent once to each worker process or Dask worker, not with every
design) and deterministic (the same ``x`` gives the same :class:`~optimise.Evaluation`).

Every built-in kind's problem subclasses :class:`DesignProblem`, whose optional hooks (the
design a study describes, seeds, the robustness scatter, kernel warm-up ...) are methods with
documented defaults: the pipeline calls them plainly. A plugin's problem that only has the
protocol's parts (``space``, ``objective_names``, ``constraint_names``, ``evaluate``,
``detail``) still runs: :func:`as_design_problem` wraps it once, where a problem comes from a
kind, so that its missing hooks take the defaults.

One design's full answer is a :class:`DesignResult`: what the report, the verdict,
``flexopt evaluate`` and the API show of it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any

import numpy as np
from flexopt.optimise.design_jacobian import DesignJacobian
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.requirements import Verdict
from flexopt.optimise.space import DesignSpace

__all__ = [
    "CaseResponse",
    "DesignDetail",
    "DesignProblem",
    "DesignResult",
    "ProblemWrapper",
    "as_design_problem",
]


@dataclass(frozen=True)
class CaseResponse:
    """One load case of a design's response, for a kind with several (a mechanism's free and
    blocked jaw); the pipeline shows every case wherever it shows a response
    (:func:`pipeline.responses.case_responses`).

    Attributes
    ----------
    table : dict of str to (n_rows,) array — the case's response columns, units in the names.
    plot : dict — how to plot it, in the vocabulary of :attr:`DesignResult.plot` (``x``,
        ``y``, ``stress``, ``allowable_MPa``, a target band, ``x_label``).
    outputs : tuple of str — the columns the user defined for this case (``advantage``,
        ``jaw_force_N``), each drawn on the axis of its unit.
    vtu : dict — the case's ``shapes_mm`` and ``beam_field`` as :class:`DesignResult` has
        them, for best_CASE.vtu (pipeline/vtu.py); empty: the case is not drawn.
    """

    table: dict[str, np.ndarray]
    plot: dict[str, Any] = field(default_factory=dict)
    outputs: tuple[str, ...] = ()
    vtu: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class DesignResult:
    """Everything known about one design: what the optimiser scored (``evaluation``), its
    response per load case, the part, the solver's record and the verdicts.

    One type for a run's best design (a problem's :meth:`DesignProblem.detail`) and for
    ``flexopt evaluate`` / the API (a kind's evaluation of its study). The fields a producer
    does not know keep their defaults.

    Attributes
    ----------
    evaluation : Evaluation or None — the design as the optimiser scored it (None for a
        study solved without a design problem).
    table : dict of str to (n_rows,) array — response columns, units in the names
        (``displacement_mm``, ``force_N``, ``peak_stress_MPa``); written as CSV.
    plot : dict — how to plot ``table``, one vocabulary for a problem's detail and an
        evaluation (:mod:`pipeline.plot_targets`, whose ``plot_spec`` every reader goes
        through): the columns ``x`` (default ``displacement_mm``), ``y`` (the response, default
        ``force_N``) and ``stress`` (the second panel, default ``peak_stress_MPa``); the words
        ``x_label``, ``y_label``, ``stress_label``, ``y_title``, ``stress_title``; the stress
        line ``allowable_MPa`` (MPa) with ``allowable_label``; the target of ``y``: ``target``,
        ``target_curve`` or ``target_range``, its band ``tolerance`` (absolute, unit of ``y``),
        ``tolerance_rel`` or ``tolerance_of_max``, ``band_x`` (x-range of the band),
        ``target_label``. The old names a plugin may still give (``left`` / ``right`` for ``y``
        / ``stress``, ``xlabel``, ``ylabel``, ``left_label`` ...) are read as these.
    shapes_mm : (n_rows, n_nodes, 2) float, mm, optional — deformed centrelines to draw.
    outline : shapely Polygon, optional — the printable outline (mm), extruded by ``height_mm``.
    height_mm : float, optional — extrusion height of the outline (the out-of-plane width).
    info : dict — anything else worth reporting (derived geometry, checks, notes).
    field_map : dict, optional — a scalar field on a triangle mesh to draw (a stress map):
        ``points_mm`` (n, 2) mm, ``triangles`` (m, 3) int, ``values`` (n,), ``label`` (name and
        unit of the values), optional ``limit`` (an allowable in the same unit), optional
        ``displacement_mm`` (n, 2) mm, the nodes' displacement in the solve whose field it is.
        Drawn as ``stress_map.png`` (and, with the displacement, ``stress_deformed.png`` on the
        deformed part); not written into best.json (it is large).
    beam_field : dict, optional — the beam's section and stresses per node and load step
        (:func:`fea.beam_fields.beam_field`: ``thickness_mm``, ``width_mm``, the signed fibre
        stresses and the equivalent stress, rows as ``shapes_mm``), for best.vtu; not written
        into best.json.
    solid_field : dict, optional — the 3D check's last state on its P2 tetrahedra
        (:meth:`fea.solid3d.Solid3DModel.last_field`), for best_3d.vtu; not written into
        best.json.
    files : dict of str to bytes — more files of the kind (``taguchi.png``, ``sweeps.png``), by
        plain file name; ``flexopt run`` / ``flexopt evaluate`` write them into the folder.
    verdicts : tuple of Verdict — the design's verdicts. A kind that judges itself fills them;
        empty (the default, what every shipped kind does) lets the pipeline judge the study's
        requirements on :meth:`values` and ``table`` (:func:`pipeline.verdict.judge_result`).
    cases : dict of str to CaseResponse — every load case by name, for a kind with several
        (``table`` and ``plot`` are then the first one's); empty for a kind with one.
    summary : dict — the scalar results of an evaluation (units in the names; ``None`` where a
        metric is undefined).
    converged : bool — every row of the response converged.
    message : str — why not, when not converged.
    solve_times_s : tuple of float, s — wall time of building the model and solving, one per
        repeat.
    inputs : dict — resolved inputs beyond the study itself (material record, settings, derived
        geometry).
    diagnostics : dict — what the solver reports about itself (element and DOF counts ...).
    headline : tuple of str — the summary keys worth a line in the CLI's table (all when empty).
    """

    evaluation: Evaluation | None = None
    table: dict[str, np.ndarray] = field(default_factory=dict)
    plot: dict[str, Any] = field(default_factory=dict)
    shapes_mm: np.ndarray | None = None
    outline: Any = None
    height_mm: float | None = None
    info: dict[str, Any] = field(default_factory=dict)
    field_map: dict[str, Any] | None = None
    beam_field: dict[str, Any] | None = None
    solid_field: dict[str, Any] | None = None
    files: dict[str, bytes] = field(default_factory=dict)
    verdicts: tuple[Verdict, ...] = ()
    cases: dict[str, CaseResponse] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    converged: bool = True
    message: str = ""
    solve_times_s: tuple[float, ...] = ()
    inputs: dict[str, Any] = field(default_factory=dict)
    diagnostics: dict[str, Any] = field(default_factory=dict)
    headline: tuple[str, ...] = ()

    def values(self) -> dict[str, Any]:
        """Every value of the design by name (units in the names): the detail's ``info``, the
        evaluation's metrics, then the summary (later ones win); what a requirement judges."""
        metrics = self.evaluation.metrics if self.evaluation is not None else {}
        return {**self.info, **metrics, **self.summary}


#: The old name of a problem's result, kept while the kinds move to :class:`DesignResult`.
DesignDetail = DesignResult


class DesignProblem:
    """What a study kind hands to ``flexopt run``: subclass it and give ``space``,
    ``objective_names``, ``constraint_names``, :meth:`evaluate` and :meth:`detail`; override a
    hook below only where the kind has more to say than its default.

    Attributes
    ----------
    space : the design space (variable names carry units where they have one).
    objective_names : (n_obj,) names of the minimised objectives, with units.
    constraint_names : (n_con,) names of the constraints g <= 0, with units.
    study : the validated study the problem was built from, or None. The design lives in it
        (``flexopt export --format yaml`` writes a design back into it); a kind that optimises
        another kind's study (the gripper: its resolved constant-force study) holds that one.
    variables : optimise.variables.DesignVariables or None — the design variables on key paths
        of the study (the mechanism kind): their paths name the variables in the report and
        say which of them a robustness scatter moves.
    variable_meanings : mapping of str to str or None — what each design variable means,
        ``words (unit)``, for the report's variables table (else the kind's table in
        :mod:`pipeline.labels`).
    held_scatter : mapping of str to ``"thickness"`` or ``"width"`` — the quantities the
        problem solves per design (not variables) that a robustness sample holds at the
        nominal design's value and the scatter that moves them (:meth:`held_state`,
        :meth:`hold_solved`); empty when it solves none.
    life_refusal : str — why a fatigue life cannot be computed for each design ("", the
        default: it can, from :meth:`detail`'s response table, its driven column the plot's x
        and its ``peak_stress_MPa``; :class:`pipeline.verdict.LifeConstraints`). A kind whose
        response has no such column names the reason, and a life constraint is refused with it.
    """

    space: DesignSpace
    objective_names: tuple[str, ...]
    constraint_names: tuple[str, ...]
    study: Any = None
    variables: Any = None
    variable_meanings: Mapping[str, str] | None = None
    held_scatter: Mapping[str, str] = MappingProxyType({})
    life_refusal: str = ""

    def evaluate(self, x: np.ndarray) -> Evaluation:
        """Evaluate one design vector (n_var,). Never raises for a bad design: a design that
        cannot be built, meshed or solved comes back as ``Evaluation.failed(..., reason)``."""
        raise NotImplementedError(f"{type(self).__name__} has no evaluate()")

    def detail(self, x: np.ndarray) -> DesignResult:
        """Full response of one design (n_var,) for plots, report and STL."""
        raise NotImplementedError(f"{type(self).__name__} has no detail()")

    def result(self, x: np.ndarray, repeat: int = 1) -> DesignResult:
        """The design ``x`` (n_var,) as ``flexopt evaluate`` and the API show it: solved
        ``repeat`` times (``solve_times_s``, s, one per solve), the last solve's result.

        The default is :meth:`detail`, its evaluation's metrics as the ``summary`` and its
        failure reason as the ``message``; a kind overrides it where ``flexopt evaluate``
        records more (the solver's inputs and diagnostics, the CLI's headline).
        """
        import time

        times = []
        detail = None
        for _ in range(max(1, int(repeat))):
            t0 = time.perf_counter()
            detail = self.detail(np.asarray(x, dtype=float))
            times.append(time.perf_counter() - t0)
        assert detail is not None
        evaluation = detail.evaluation
        reason = evaluation.reason if evaluation is not None else ""
        metrics = dict(evaluation.metrics) if evaluation is not None else {}
        return replace(
            detail,
            summary={**metrics, **detail.summary},
            converged=detail.converged and not reason,
            message=detail.message or reason,
            solve_times_s=tuple(times),
        )

    # -- optional hooks, with their defaults ---------------------------------------------------

    def nominal_design(self) -> np.ndarray | None:
        """(n_var,) the design the study file describes, what ``flexopt evaluate`` solves;
        None (the default) reads each variable from the study by its name
        (:func:`pipeline.problems.nominal_design`)."""
        return None

    def initial_designs(self) -> np.ndarray | None:
        """(k, n_var) designs seeding the first population (a published optimum, the study's
        design), or None (the default: a random first population)."""
        return None

    def scatter_design(
        self, x: np.ndarray, thickness_delta_mm: float, width_delta_mm: float
    ) -> np.ndarray | None:
        """(n_var,) the design ``x`` as printed off by a tolerance (a robustness sample: every
        in-plane thickness plus ``thickness_delta_mm``, every out-of-plane width plus
        ``width_delta_mm``), or None (the default): the pipeline's rule by variable name or
        :attr:`variables` path (:func:`pipeline.robustness.scatter_design`)."""
        return None

    def held_state(self, evaluation: Evaluation) -> dict[str, float]:
        """What the problem solved for the nominal design (``evaluation``) that a robustness
        sample holds (see :attr:`held_scatter`); ``{}`` (the default) holds nothing."""
        return {}

    def hold_solved(
        self, held: Mapping[str, float], thickness_delta_mm: float, width_delta_mm: float
    ) -> None:
        """Use ``held`` (from :meth:`held_state`), moved by the scatter, instead of solving it
        again; an empty ``held`` solves it again. The default holds nothing."""

    def study_values(self, x: np.ndarray) -> dict[str, Any] | None:
        """``{key path: value}`` that make :attr:`study` describe the design ``x`` (n_var,), or
        None (the default): the pipeline's rule (``variables:``, ``design:``, a key of the
        variable's name; :func:`pipeline.design_study.design_values`)."""
        return None

    def with_residuals(self) -> DesignProblem | None:
        """A problem like this one whose every :class:`~optimise.Evaluation` also carries the
        residuals of a least-squares objective, for a Gauss-Newton step
        (``optimiser.method: hybrid``, :mod:`optimise.hybrid`); None (the default) when the
        objective is not one.

        The residuals r (n_res,) are the metrics ``residual_1`` ... ``residual_<n_res>`` (in the
        objective's unit) with ``f[0] = sqrt(mean(r**2))``; objectives and constraints are this
        problem's exactly. A separate problem, not extra metrics of this one: a run of another
        method keeps its tables as they are. A wrapper of a problem answers None unless it
        says otherwise (its objective may not be the inner one's, as a worst-case score).
        """
        return None

    def jacobian(self, x: np.ndarray) -> DesignJacobian | None:
        """Exact derivatives of the design ``x`` (n_var,)'s objectives, constraints and
        residuals (:class:`~optimise.design_jacobian.DesignJacobian`), or None (the default, and
        for a design or a problem the kind cannot differentiate): the hybrid optimiser then takes
        finite differences. A wrapper answers None unless it says otherwise."""
        return None

    def warm_up(self) -> None:
        """Compile or load the compiled kernels :meth:`evaluate` uses, once, before a pool
        forks its workers (which inherit them). The default loads the beam kernel, which most
        kinds use."""
        from flexopt.fea.beam import warm_up

        warm_up()

    def warm_up_detail(self) -> None:
        """Load what :meth:`detail` needs beyond :meth:`evaluate` (a run calls it in a thread
        while its workers solve). The default loads nothing."""


class ProblemWrapper(DesignProblem):
    """A problem around another one (``inner``): every hook and attribute is the inner
    problem's unless the wrapper overrides it. Picklable."""

    def __init__(self, inner: DesignProblem) -> None:
        self.inner = inner
        self.space = inner.space
        self.objective_names = tuple(inner.objective_names)
        self.constraint_names = tuple(inner.constraint_names)

    def __getattr__(self, name: str) -> Any:
        # what the hooks do not name (a kind's own attributes) is the inner problem's too
        if name == "inner":  # during unpickling, before __dict__ is filled
            raise AttributeError(name)
        return getattr(self.inner, name)

    @property  # type: ignore[override]
    def study(self) -> Any:
        return self.inner.study

    @property  # type: ignore[override]
    def variables(self) -> Any:
        return self.inner.variables

    @property  # type: ignore[override]
    def variable_meanings(self) -> Mapping[str, str] | None:
        return self.inner.variable_meanings

    @property  # type: ignore[override]
    def held_scatter(self) -> Mapping[str, str]:
        return self.inner.held_scatter

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return self.inner.evaluate(x)

    def detail(self, x: np.ndarray) -> DesignResult:
        return self.inner.detail(x)

    def result(self, x: np.ndarray, repeat: int = 1) -> DesignResult:
        return self.inner.result(x, repeat)

    def nominal_design(self) -> np.ndarray | None:
        return self.inner.nominal_design()

    def initial_designs(self) -> np.ndarray | None:
        return self.inner.initial_designs()

    def scatter_design(
        self, x: np.ndarray, thickness_delta_mm: float, width_delta_mm: float
    ) -> np.ndarray | None:
        return self.inner.scatter_design(x, thickness_delta_mm, width_delta_mm)

    def held_state(self, evaluation: Evaluation) -> dict[str, float]:
        return self.inner.held_state(evaluation)

    def hold_solved(
        self, held: Mapping[str, float], thickness_delta_mm: float, width_delta_mm: float
    ) -> None:
        self.inner.hold_solved(held, thickness_delta_mm, width_delta_mm)

    def study_values(self, x: np.ndarray) -> dict[str, Any] | None:
        return self.inner.study_values(x)

    def warm_up(self) -> None:
        self.inner.warm_up()

    def warm_up_detail(self) -> None:
        self.inner.warm_up_detail()


#: The protocol's parts a problem must have to be adapted (:func:`as_design_problem`).
PROTOCOL = ("space", "objective_names", "constraint_names", "evaluate", "detail")


class _ProtocolProblem(DesignProblem):
    """A plugin's problem that implements the protocol but does not subclass
    :class:`DesignProblem`: each hook is the plugin's when it has one, else the default."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.space = inner.space
        self.objective_names = tuple(inner.objective_names)
        self.constraint_names = tuple(inner.constraint_names)

    def __getattr__(self, name: str) -> Any:
        if name == "inner":  # during unpickling, before __dict__ is filled
            raise AttributeError(name)
        return getattr(self.inner, name)

    def _own(self, name: str) -> Any:
        # the one place a hook is looked up by name: the plugin may or may not define it
        return getattr(self.inner, name, None)

    @property  # type: ignore[override]
    def study(self) -> Any:
        return self._own("study")

    @property  # type: ignore[override]
    def variables(self) -> Any:
        return self._own("variables")

    @property  # type: ignore[override]
    def variable_meanings(self) -> Mapping[str, str] | None:
        own = self._own("variable_meanings")
        return own if isinstance(own, Mapping) else None

    @property  # type: ignore[override]
    def held_scatter(self) -> Mapping[str, str]:
        # a plugin's held_state() is asked for when it names what it holds here
        own = self._own("held_scatter")
        return own if isinstance(own, Mapping) else MappingProxyType({})

    def _call(self, name: str, *args: Any) -> Any:
        hook = self._own(name)
        if callable(hook):
            return hook(*args)
        return getattr(DesignProblem, name)(self, *args)

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return self.inner.evaluate(x)

    def detail(self, x: np.ndarray) -> DesignResult:
        return self.inner.detail(x)

    def result(self, x: np.ndarray, repeat: int = 1) -> DesignResult:
        return self._call("result", x, repeat)

    def nominal_design(self) -> np.ndarray | None:
        return self._call("nominal_design")

    def initial_designs(self) -> np.ndarray | None:
        return self._call("initial_designs")

    def scatter_design(
        self, x: np.ndarray, thickness_delta_mm: float, width_delta_mm: float
    ) -> np.ndarray | None:
        return self._call("scatter_design", x, thickness_delta_mm, width_delta_mm)

    def held_state(self, evaluation: Evaluation) -> dict[str, float]:
        return dict(self._call("held_state", evaluation) or {})

    def hold_solved(
        self, held: Mapping[str, float], thickness_delta_mm: float, width_delta_mm: float
    ) -> None:
        self._call("hold_solved", held, thickness_delta_mm, width_delta_mm)

    def study_values(self, x: np.ndarray) -> dict[str, Any] | None:
        return self._call("study_values", x)

    def warm_up(self) -> None:
        self._call("warm_up")

    def warm_up_detail(self) -> None:
        self._call("warm_up_detail")


def as_design_problem(problem: Any) -> DesignProblem:
    """``problem`` as a :class:`DesignProblem`: itself when it subclasses it, else (a plugin's
    problem with only the protocol's parts) wrapped so that its missing hooks take the
    defaults.

    Raises
    ------
    TypeError
        When ``problem`` lacks a part of the protocol (:data:`PROTOCOL`) or its ``space`` is
        not a DesignSpace.
    """
    if isinstance(problem, DesignProblem):
        return problem
    missing = [part for part in PROTOCOL if not hasattr(problem, part)]
    if missing or not isinstance(problem.space, DesignSpace):
        raise TypeError(
            f"{type(problem).__name__} is not a DesignProblem (space, objective_names, "
            "constraint_names, evaluate, detail)"
            + (f": it has no {', '.join(missing)}" if missing else ": its space is no DesignSpace")
        )
    return _ProtocolProblem(problem)
