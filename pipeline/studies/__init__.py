"""Registry of study kinds, keyed by the YAML ``geometry.kind``.

A kind is one module in this package that calls :func:`register` with a :class:`StudyKind`: the
pydantic model of its whole study, a ``check`` that builds the geometry and material once, and a
design ``problem`` (whose nominal design's :meth:`~optimise.problem.DesignProblem.result` is what
``flexopt evaluate`` shows) or an ``evaluate`` that solves the study. The CLI and the runner
know only this registry, so a new kind is a new module here and touches no other file (modules
are discovered on first use; names starting with ``_`` are skipped so they can hold shared
helpers).

A kind may also come from a package of the user's own, through the entry-point group
``flexopt.kinds`` (docs/plugins.md). The entry point's name is the kind's name; its value is either
a module that calls :func:`register` when imported (``my_pkg.kind``) or an object in a module
(``my_pkg.kind:make_kind``): a :class:`StudyKind`, or a callable taking no argument that returns
one, which flexopt registers. Plugins are loaded after the built-in kinds, on first use. A plugin
that fails to load does not break flexopt: its kind is recorded as unavailable with the reason
(:func:`unavailable_kinds`), reported in one line when a study asks for that kind and by
``flexopt list``. A plugin may not take a built-in kind's name, nor one another plugin took first.
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.metadata
import importlib.util
import os
import pkgutil
import sys
import threading
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from flexopt.optimise.problem import DesignProblem, DesignResult
from flexopt.optimise.requirements import Figure, Requirement
from flexopt.pipeline.errors import StudyError

if TYPE_CHECKING:  # annotations only: study.validate_study looks kinds up here at run time
    from flexopt.pipeline.study import Study

__all__ = [
    "ENTRY_POINT_GROUP",
    "EvaluationResult",
    "StudyKind",
    "builtin_kind_names",
    "get_kind",
    "kind_summary",
    "kinds",
    "refused_plugins",
    "register",
    "unavailable_kinds",
]

#: The entry-point group a package names its study kinds in (``[project.entry-points]``).
ENTRY_POINT_GROUP = "flexopt.kinds"

#: Longest a plugin's import (and its factory call) may take, s, before it is given up as
#: unavailable (``FLEXOPT_PLUGIN_TIMEOUT_S`` overrides it): a plugin that blocks at import must not
#: hang ``flexopt list`` or any other command (docs/plugins.md).
PLUGIN_IMPORT_TIMEOUT_S = 15.0


class EvaluationResult(DesignResult):
    """A kind's evaluation of its study: a :class:`~optimise.problem.DesignResult` built with
    the positional order this name always had (``table, summary, converged, message,
    solve_times_s``, then keywords). The old name, kept while the kinds move to the one result
    type; see :class:`~optimise.problem.DesignResult` for every field.
    """

    def __init__(
        self,
        table: dict[str, np.ndarray] | None = None,
        summary: dict[str, Any] | None = None,
        converged: bool = True,
        message: str = "",
        solve_times_s: tuple[float, ...] = (),
        **fields: Any,
    ) -> None:
        super().__init__(
            table={} if table is None else table,
            summary={} if summary is None else summary,
            converged=converged,
            message=message,
            solve_times_s=tuple(solve_times_s),
            **fields,
        )


@dataclass(frozen=True)
class StudyKind:
    """One study kind.

    Attributes
    ----------
    name : str
        The YAML ``geometry.kind``.
    model : type of Study
        The pydantic model of the whole study file.
    check : callable(study) -> None
        Builds geometry and material once; raises :class:`StudyError` naming the key path.
    evaluate : callable(study, repeat) -> optimise.problem.DesignResult, optional
        The result hook of a kind without a design problem: solves the study ``repeat`` times
        (for timing) and summarises the last solve. Without it, ``flexopt evaluate`` is the
        result of the problem's nominal design (:func:`pipeline.problems.study_result`; a kind
        whose answer is more than a design's detail overrides ``DesignProblem.result``). No
        built-in kind has both (tests/test_layering.py).
    problem : callable(study) -> optimise.DesignProblem, optional
        For kinds that ``flexopt run`` optimises: the picklable problem built once from the study
        (its ``optimiser:`` block is an :class:`pipeline.study.OptimiserSpec` at
        ``study.optimiser``); a subclass of :class:`optimise.problem.DesignProblem`, or (a
        plugin's) an object with the protocol's parts, adapted.
    requirements : callable(study) -> sequence of optimise.requirements.Requirement, optional
        The kind's BUILT-IN requirements: what its study already constrains or targets (an
        allowable stress, a force band, a stiffness window, stability), judged MET / NOT MET
        in every verdict before the study's own ``requirements:``.
    quantities : tuple of str or callable(study) -> iterable of str, optional
        The names a ``requirements:`` item may judge: summary / metrics keys and response
        columns (units in the names). The built-in requirements' names are always included.
    figures : mapping or callable(study) -> mapping, optional
        ``{quantity: (optimise.requirements.Figure, ...)}``: the figures of a quantity by model
        and fidelity rank; a requirement on it is judged on the best the design has
        (:mod:`pipeline.verdict`).
    design_space : callable(study) -> (optimise.DesignSpace, (n_var,) array or None), optional
        For a kind with design variables: the space its problem moves in (the same names, order
        and bounds as ``problem(study).space``) and the design ``flexopt evaluate`` solves in it
        (None when the study gives none). "Every design variable inside its stated range" is
        then a requirement of every verdict of a design (:func:`pipeline.verdict.judge`).
    summary : str, optional
        One line: what the kind designs (``flexopt list``). Default: the first line of the
        docstring of the module that defines ``model``, without its ``Study kind ``x``:`` lead.
    width_key : str or callable(study) -> str or None, optional
        The study key of the part's out-of-plane width (mm), when every force of the design is
        proportional to it: ``flexopt retrim``'s default ``--key`` (docs/print_to_part.md). A
        callable gives it per study (None: not exact for this study, e.g. a solved thickness).
    """

    name: str
    model: type[Study]
    check: Callable[[Study], None]
    evaluate: Callable[[Study, int], EvaluationResult] | None = None
    problem: Callable[[Study], DesignProblem] | None = None
    requirements: Callable[[Study], Sequence[Requirement]] | None = None
    quantities: tuple[str, ...] | Callable[[Study], Iterable[str]] | None = None
    summary: str = ""
    figures: Mapping[str, Sequence[Figure]] | Callable[[Study], Mapping] | None = None
    design_space: Callable[[Study], tuple[Any, np.ndarray | None]] | None = None
    width_key: str | Callable[[Study], str | None] | None = None


_KINDS: dict[str, StudyKind] = {}
#: Kinds that plugins name but could not provide, with the reason in one line.
_UNAVAILABLE: dict[str, str] = {}
#: Entry points refused for their name (a built-in kind's, or one another plugin took first).
_REFUSED: list[str] = []
#: Names of the kinds shipped in this package (filled by discovery): plugins may not take them.
_BUILTIN: set[str] = set()
_discovered = False
#: The entry point being loaded while a plugin runs (names it in a clash message), else None.
_loading: importlib.metadata.EntryPoint | None = None
#: A plugin's own StudyKind by name, where the registry holds it guarded (:func:`_guarded`).
_ORIGINAL: dict[str, StudyKind] = {}
#: Loader threads given up on (a plugin that blocked at import): what they register is ignored.
_ABANDONED: set[threading.Thread] = set()


def register(kind: StudyKind) -> StudyKind:
    """Add a kind to the registry (called by each kind module at import).

    Raises
    ------
    ValueError
        When another kind holds the name already, or a plugin claims a built-in kind's name.
    """
    if not isinstance(kind, StudyKind):
        raise TypeError(f"register() takes a StudyKind, not {type(kind).__name__}")
    if threading.current_thread() in _ABANDONED:
        raise RuntimeError("this plugin took too long to import; its kinds are not registered")
    if _loading is not None:
        _check_plugin_kind(kind)
    if _loading is not None and kind.name in _BUILTIN:
        # a plugin module may register more than its entry point names: none may be built-in
        raise ValueError(
            f"the kind name '{kind.name}' is taken by a built-in kind; give the plugin's kind "
            "(entry point name and geometry.kind) another name"
        )
    if kind.name in _KINDS and not _holds(kind):
        raise ValueError(f"study kind '{kind.name}' registered twice")
    if _loading is not None and kind.name not in _KINDS:
        _ORIGINAL[kind.name] = kind
        _KINDS[kind.name] = _guarded(kind)
        return kind
    _KINDS.setdefault(kind.name, kind)
    return kind


def _holds(kind: StudyKind) -> bool:
    """Whether the registry holds this very kind (itself, or its guarded copy)."""
    return kind is _KINDS.get(kind.name) or kind is _ORIGINAL.get(kind.name)


def _check_plugin_kind(kind: StudyKind) -> None:
    """Refuse a plugin's kind whose parts are not what the contract says (``schema``, ``init``
    and ``evaluate`` would crash on them later)."""
    model = kind.model
    # Study by its place in the class tree: this module does not import pipeline.study at run
    # time (pipeline.study imports it; tests/test_layering.py)
    is_study = isinstance(model, type) and any(
        c.__name__ == "Study" and c.__module__ == "flexopt.pipeline.study" for c in model.__mro__
    )
    if not is_study:
        what = model.__name__ if isinstance(model, type) else type(model).__name__
        raise TypeError(
            f"the kind '{kind.name}' has model {what}, not a pydantic subclass of "
            "pipeline.study.Study"
        )
    for part in ("check", "evaluate", "problem", "requirements"):
        value = getattr(kind, part)
        if value is not None and not callable(value) or part == "check" and value is None:
            raise TypeError(f"the kind '{kind.name}' has a {part} that is not callable")


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    text = text if len(text) <= 200 else text[:197] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _guarded(kind: StudyKind) -> StudyKind:
    """A plugin's kind whose parts cannot crash flexopt: an exception from its ``check``,
    ``evaluate``, ``problem``, ``requirements`` or ``quantities`` (other than the
    :class:`StudyError` the contract asks for), or an ``evaluate`` that returns no
    :class:`EvaluationResult`, is one line at ``geometry.kind`` saying the plugin failed."""
    who = f"the plugin kind '{kind.name}'"

    def failed(part: str, exc: BaseException) -> StudyError:
        return StudyError(
            "geometry.kind",
            f"{who} failed in its {part}: {_one_line(exc)} (a fault of the plugin, not of the "
            "study: report it to the plugin's authors)",
        )

    def guard(part: str, call: Callable[..., Any] | None) -> Callable[..., Any] | None:
        if call is None:
            return None

        def guarded(*args: Any) -> Any:
            try:
                result = call(*args)
            except StudyError:
                raise
            except (Exception, SystemExit) as exc:  # whatever third-party code raises
                raise failed(part, exc) from None
            if part == "evaluate" and not isinstance(result, DesignResult):
                raise StudyError(
                    "geometry.kind",
                    f"{who}'s evaluate returned {type(result).__name__}, not an "
                    "EvaluationResult (a DesignResult; a fault of the plugin: report it to its "
                    "authors)",
                )
            if part == "problem" and result is None:
                raise StudyError(
                    "geometry.kind",
                    f"{who}'s problem returned None, not a design problem (a fault of the "
                    "plugin: report it to its authors)",
                )
            return result

        return guarded

    quantities = kind.quantities
    return dataclasses.replace(
        kind,
        check=guard("check", kind.check),  # type: ignore[arg-type]
        evaluate=guard("evaluate", kind.evaluate),
        problem=guard("problem", kind.problem),
        requirements=guard("requirements", kind.requirements),
        quantities=guard("quantities", quantities) if callable(quantities) else quantities,
    )


def _is_builtin_module(kind: StudyKind) -> bool:
    return getattr(kind.model, "__module__", "").startswith(f"{__name__}.")


def _discover() -> None:
    global _discovered
    if _discovered:
        return
    # set first: a plugin that calls kinds() while it is imported must not recurse into here
    _discovered = True
    for info in pkgutil.iter_modules(__path__):
        if not info.name.startswith("_"):
            importlib.import_module(f"{__name__}.{info.name}")
    _BUILTIN.update(name for name, kind in _KINDS.items() if _is_builtin_module(kind))
    _load_plugins()


def _entry_points() -> list[importlib.metadata.EntryPoint]:
    """The ``flexopt.kinds`` entry points of the installed distributions, in name order."""
    try:
        found = importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)
    except Exception:  # a broken dist-info on sys.path must not stop flexopt
        return []
    return sorted(found, key=lambda ep: (ep.name, ep.value))


def _origin(ep: importlib.metadata.EntryPoint) -> str:
    """``'my_kind = my_pkg.kind' (package my-pkg 0.1)``: where a plugin kind comes from."""
    dist = getattr(ep, "dist", None)
    package = f" (package {dist.name} {dist.version})" if dist is not None else ""
    return f"plugin '{ep.name} = {ep.value}'{package}"


def _load_plugins() -> None:
    """Load every ``flexopt.kinds`` entry point; record the ones that fail (never raise)."""
    global _loading
    for ep in _entry_points():
        if ep.name in _BUILTIN:
            _REFUSED.append(
                f"{_origin(ep)} refused: '{ep.name}' is a built-in kind; rename the plugin's "
                "kind (entry point name and geometry.kind)"
            )
            continue
        if ep.name in _KINDS or ep.name in _UNAVAILABLE:
            held = _KINDS.get(ep.name)
            if held is not None and getattr(held.model, "__module__", "") == ep.module:
                continue  # the same plugin, imported before discovery (a test, a notebook)
            _REFUSED.append(
                f"{_origin(ep)} refused: another plugin took the kind name '{ep.name}' first; "
                "uninstall one of them or rename its kind"
            )
            continue
        _loading = ep
        before = set(_KINDS)
        try:
            problem = _load_plugin(ep, before)
        except Exception as exc:  # whatever a third-party import raises
            problem = f"{_origin(ep)} failed to load: {_one_line(exc)}"
        finally:
            _loading = None
        if problem:  # a plugin that failed contributes nothing, not half its kinds
            for name in set(_KINDS) - before:
                del _KINDS[name]
                _ORIGINAL.pop(name, None)
            _UNAVAILABLE[ep.name] = problem


def _import_timeout_s() -> float:
    try:
        value = float(os.environ.get("FLEXOPT_PLUGIN_TIMEOUT_S", PLUGIN_IMPORT_TIMEOUT_S))
    except ValueError:
        return PLUGIN_IMPORT_TIMEOUT_S
    return value if value > 0 else PLUGIN_IMPORT_TIMEOUT_S


class _PluginFailed(Exception):
    """A plugin's import raised something, or blocked: the reason, in one line."""


def _import_entry_point(ep: importlib.metadata.EntryPoint) -> Any:
    """``ep.load()`` (and, for a factory, its call) in a thread of its own, waited for at most
    :data:`PLUGIN_IMPORT_TIMEOUT_S`.

    In its own thread, whatever the plugin raises (a ``KeyboardInterrupt``, ``SystemExit`` or
    another ``BaseException`` included) is caught there and never mistaken for the user's Ctrl-C,
    which reaches the main thread as before; and a plugin that blocks is given up on (the
    thread is a daemon: it does not keep the process alive).
    """
    outcome: dict[str, Any] = {}

    def load() -> None:
        try:
            loaded = ep.load()
            if ep.attr and callable(loaded) and not isinstance(loaded, StudyKind):
                loaded = loaded()
            outcome["value"] = loaded
        except BaseException as exc:  # noqa: BLE001 - a plugin's fault, reported in one line
            outcome["error"] = exc

    thread = threading.Thread(target=load, name=f"flexopt-plugin-{ep.name}", daemon=True)
    thread.start()
    timeout = _import_timeout_s()
    thread.join(timeout)
    if thread.is_alive():
        _ABANDONED.add(thread)
        raise _PluginFailed(
            f"did not finish importing within {timeout:g} s (it blocks at import); fix the "
            "plugin, or set FLEXOPT_PLUGIN_TIMEOUT_S for one that is only slow"
        )
    if "error" in outcome:
        raise _PluginFailed(f"failed to load: {_one_line(outcome['error'])}")
    return outcome["value"]


def _load_plugin(ep: importlib.metadata.EntryPoint, before: set[str]) -> str | None:
    """Import one entry point and register its kind; the problem in one line, or None.

    ``before``: the names registered before it was imported (to name what it registered).
    """
    try:
        loaded = _import_entry_point(ep)
    except _PluginFailed as exc:
        return f"{_origin(ep)} {exc}"
    if ep.attr:  # `module:object`: a StudyKind, or a callable that returns one (called above)
        kind = loaded
        if not isinstance(kind, StudyKind):
            return (
                f"{_origin(ep)} gave {type(kind).__name__}, not a StudyKind; point the entry "
                "point at a StudyKind or a function returning one"
            )
        if kind.name in _BUILTIN:
            return (
                f"{_origin(ep)} gave the kind '{kind.name}': that name is taken by a built-in "
                "kind; give the plugin's kind (entry point name and geometry.kind) another name"
            )
        if kind.name != ep.name:
            return (
                f"{_origin(ep)} gave the kind '{kind.name}'; the entry point name must be the "
                "kind's name (its geometry.kind)"
            )
        if not _holds(kind):
            register(kind)
    elif ep.name not in _KINDS:  # a module: importing it must have registered the kind
        registered = sorted(set(_KINDS) - before)
        also = f" (it registered {', '.join(registered)})" if registered else ""
        return (
            f"{_origin(ep)} was imported but registered no kind named '{ep.name}'{also}; call "
            f"register(StudyKind('{ep.name}', ...)) in it, or name the entry point after its kind"
        )
    return None


def kinds() -> dict[str, StudyKind]:
    """All registered (available) kinds by name, built-in and plugins."""
    _discover()
    return dict(_KINDS)


def unavailable_kinds() -> dict[str, str]:
    """Kinds that plugins name but could not provide, each with the reason in one line."""
    _discover()
    return dict(_UNAVAILABLE)


def refused_plugins() -> list[str]:
    """One line per plugin entry point refused for its kind name (the kind stays as it was)."""
    _discover()
    return list(_REFUSED)


def builtin_kind_names() -> set[str]:
    """Names of the kinds shipped with flexopt (the rest come from plugins or tests)."""
    _discover()
    return set(_BUILTIN)


def kind_summary(kind: StudyKind) -> str:
    """One line: what ``kind`` designs (its ``summary``, else its module's docstring)."""
    text = kind.summary
    if not text:
        module = sys.modules.get(getattr(kind.model, "__module__", ""))
        doc = (getattr(module, "__doc__", None) or kind.model.__doc__ or "").strip()
        text = doc.split("\n\n")[0]  # the first paragraph: some first lines wrap mid-sentence
        prefix = f"Study kind ``{kind.name}``:"
        if text.startswith(prefix):
            text = text[len(prefix) :]
    text = " ".join(text.replace("``", "").split())
    return text if len(text) <= 100 else text[:97].rstrip() + "..."


def _builtin_kind(name: str) -> StudyKind | None:
    """The built-in kind ``name`` from its own module (``pipeline/studies/<name>.py``), without
    importing the other kind modules, or None when it is not found that way.

    Importing every kind module (and what each imports) to find one cost 0.3-0.5 s CPU at the start
    of every ``flexopt run`` and ``evaluate``; a built-in kind wins over a plugin of its name
    anyway (a clashing plugin is refused), so the full discovery is not needed to return it.
    """
    if name not in _KINDS:
        if not name.isidentifier() or name.startswith("_"):
            return None
        if importlib.util.find_spec(f"{__name__}.{name}") is None:
            return None
        importlib.import_module(f"{__name__}.{name}")
    kind = _KINDS.get(name)
    return kind if kind is not None and _is_builtin_module(kind) else None


def get_kind(name: Any) -> StudyKind:
    """The kind registered under ``name``.

    Raises
    ------
    StudyError
        At ``geometry.kind`` when the name is missing or unknown.
    """
    if isinstance(name, str) and (kind := _builtin_kind(name)) is not None:
        return kind
    available = ", ".join(sorted(kinds()))
    if name is None:
        raise StudyError("geometry.kind", f"required key is missing; add kind: one of {available}")
    if isinstance(name, str) and name not in _KINDS and name in _UNAVAILABLE:
        raise StudyError("geometry.kind", f"kind '{name}' is unavailable: {_UNAVAILABLE[name]}")
    if not isinstance(name, str) or name not in _KINDS:
        raise StudyError("geometry.kind", f"unknown kind {name!r}; use one of {available}")
    return _KINDS[name]
