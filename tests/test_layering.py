"""The layering the design notes ask for (docs/DESIGN "Layers"), checked on the source.

Every module of geometry/, fea/, optimise/, pipeline/ (and pipeline/api/, the package ``flexopt``
itself) is parsed with ``ast``; every import counts, also inside functions and under
``TYPE_CHECKING`` (a lazy import is still a dependency, it only hides it). Asserted:

- imports go one way: geometry ← fea ← optimise ← pipeline (← the public API ``flexopt``);
- no study kind in ``pipeline/studies/`` imports another kind (modules starting with ``_`` are
  shared blocks and may be imported by any kind);
- no import cycle among flexopt modules (imports under ``TYPE_CHECKING`` never run and do not
  count here);
- fea/'s pivoting banded LU and its sparsity-pattern builder are written once (fea/_banded.py,
  fea/_sparse.py);
- no module uses a private (``_name``) name of another flexopt module (a private module is its
  package's own), and every flexopt error class derives from ``FlexoptError``;
- no module reads a private attribute of another module's objects (``model._chol``, a private
  method or table of a class defined elsewhere): the owner has a public name for it.
- no built-in study kind has both a design problem and its own ``evaluate`` (one result per
  design: ``flexopt evaluate`` of a kind with a problem is its nominal design's result).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

# Source folder -> installed package name (pyproject.toml's package-dir).
PACKAGE_DIRS = {
    "geometry": "flexopt.geometry",
    "fea": "flexopt.fea",
    "optimise": "flexopt.optimise",
    "pipeline/api": "flexopt",
    "pipeline": "flexopt.pipeline",
}

# Rank of each layer: a module may import only from its own layer or a lower one.
LAYER_RANK = {"geometry": 0, "fea": 1, "optimise": 2, "pipeline": 3, "api": 4}

STUDIES = "flexopt.pipeline.studies"


def _module_files() -> dict[str, Path]:
    """Installed module name -> source file, for every module of the four layers and the API."""
    modules: dict[str, Path] = {}
    for folder, package in PACKAGE_DIRS.items():
        root = REPO / folder
        for path in sorted(root.rglob("*.py")):
            rel = path.relative_to(root)
            if folder == "pipeline" and rel.parts[0] == "api":
                continue  # the API is its own package, ``flexopt``
            parts = list(rel.with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join([package, *parts])] = path
    return modules


MODULES = _module_files()


def _layer(module: str) -> str:
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in LAYER_RANK and parts[1] != "api":
        return parts[1]
    return "api"  # flexopt itself and its own modules (pipeline/api/*.py)


def _is_package(module: str) -> bool:
    return MODULES[module].name == "__init__.py"


def _is_type_checking(test: ast.expr) -> bool:
    """``if TYPE_CHECKING:`` or ``if typing.TYPE_CHECKING:``."""
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(module: str) -> tuple[set[str], set[str]]:
    """The flexopt modules ``module`` imports: (all of them, those imported at run time).

    "All" counts every import anywhere in the source, also inside functions and under
    ``if TYPE_CHECKING:``; "at run time" leaves out the latter (they never execute, so they
    cannot close an import cycle, but they are still a dependency on a layer).
    """
    tree = ast.parse(MODULES[module].read_text(encoding="utf-8"), filename=str(MODULES[module]))
    package = module if _is_package(module) else module.rpartition(".")[0]
    every: set[str] = set()
    runtime: set[str] = set()

    def resolve(name: str) -> str:
        # ``from flexopt.fea import beam`` names a module, ``from flexopt.fea.beam import X``
        # names an attribute: take the longest prefix that is a flexopt module.
        while name and name not in MODULES:
            name = name.rpartition(".")[0]
        return name

    def targets(node: ast.Import | ast.ImportFrom) -> list[str]:
        if isinstance(node, ast.Import):
            return [resolve(a.name) for a in node.names if a.name.split(".")[0] == "flexopt"]
        if node.level:
            base = package.split(".")
            if node.level > 1:
                base = base[: -(node.level - 1)]
            target = ".".join(base + ([node.module] if node.module else []))
        else:
            target = node.module or ""
        if target.split(".")[0] != "flexopt":
            return []
        return [
            resolve(f"{target}.{a.name}" if f"{target}.{a.name}" in MODULES else target)
            for a in node.names
        ]

    def visit(node: ast.AST, typing_only: bool) -> None:
        if isinstance(node, ast.Import | ast.ImportFrom):
            for target in targets(node):
                if target and target != module:
                    every.add(target)
                    if not typing_only:
                        runtime.add(target)
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.body:
                visit(child, True)
            for child in node.orelse:
                visit(child, typing_only)
            return
        for child in ast.iter_child_nodes(node):
            visit(child, typing_only)

    visit(tree, False)
    return every, runtime


_SCANNED = {module: _imports(module) for module in MODULES}
#: module -> every flexopt module it imports
GRAPH = {module: scanned[0] for module, scanned in _SCANNED.items()}
#: module -> the flexopt modules it imports at run time (not under TYPE_CHECKING)
RUNTIME_GRAPH = {module: scanned[1] for module, scanned in _SCANNED.items()}


def test_the_scan_sees_the_layers():
    # Guards the test itself: a wrong folder map would make every assertion below vacuous.
    layers = {_layer(m) for m in MODULES}
    assert layers == set(LAYER_RANK), layers
    assert "flexopt.fea.beam" in MODULES
    assert "flexopt.pipeline.study" in GRAPH["flexopt.pipeline.run.setup"]
    assert "flexopt.fea.beam" in GRAPH["flexopt.fea.mechanism"]
    # an import inside a function counts, at run time too
    assert "flexopt.pipeline.verdict" in RUNTIME_GRAPH["flexopt.pipeline.study"]
    # an import under TYPE_CHECKING counts for the layers, not for cycles
    assert "flexopt.pipeline.study" in GRAPH["flexopt.pipeline.studies"]
    assert "flexopt.pipeline.study" not in RUNTIME_GRAPH["flexopt.pipeline.studies"]


def test_imports_go_one_way():
    upward = [
        f"{module} ({_layer(module)}) imports {target} ({_layer(target)})"
        for module, targets in sorted(GRAPH.items())
        for target in sorted(targets)
        if LAYER_RANK[_layer(target)] > LAYER_RANK[_layer(module)]
    ]
    assert not upward, "imports against the layers:\n" + "\n".join(upward)


def _is_kind(module: str) -> bool:
    prefix = STUDIES + "."
    return module.startswith(prefix) and not module[len(prefix) :].startswith("_")


def test_no_kind_imports_another_kind():
    crossing = [
        f"{module} imports {target}"
        for module, targets in sorted(GRAPH.items())
        if _is_kind(module)
        for target in sorted(targets)
        if _is_kind(target)
    ]
    assert not crossing, (
        "a study kind imports another kind (shared schema blocks go into "
        "pipeline/studies/_*.py, shared physics into fea/):\n" + "\n".join(crossing)
    )


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), each as one cycle.

    Each cycle is reported as a path ``a -> b -> ... -> a`` found inside its component.
    """
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []
    counter = 0

    def strongconnect(start: str) -> None:
        # Iterative Tarjan: the module graph is deep enough to make recursion fragile.
        nonlocal counter
        work = [(start, iter(sorted(graph.get(start, ()))))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        components.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            strongconnect(node)

    cycles = []
    for component in components:
        members = set(component)
        # Breadth-first search inside the component for a shortest way back to its first module.
        first = component[0]
        previous: dict[str, str] = {}
        frontier = [first]
        path: list[str] = []
        while frontier and not path:
            nxt = []
            for node in frontier:
                for child in sorted(graph[node] & members):
                    if child == first:
                        path = [node]
                        while path[-1] != first:
                            path.append(previous[path[-1]])
                        path = [first, *reversed(path[:-1]), first]
                        break
                    if child not in previous:
                        previous[child] = node
                        nxt.append(child)
                if path:
                    break
            frontier = nxt
        cycles.append(path)
    return cycles


@pytest.mark.parametrize(
    ("graph", "expected"),
    [
        ({"a": {"b"}, "b": {"c"}, "c": set()}, []),
        ({"a": {"b"}, "b": {"a"}}, [["a", "b", "a"]]),
        ({"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set()}, [["a", "b", "c", "a"]]),
    ],
)
def test_find_cycles_on_known_graphs(graph, expected):
    assert find_cycles(graph) == expected


#: Import edges that close a cycle and are known, each with why and how it goes: cut from the graph
#: before the search, so any OTHER cycle fails the test, and each must still exist (remove it
#: from here when it is gone). They came with work committed beside the layering (e72d909,
#: fe988c4, and the HTML report's) in files other sessions own; none may be added without the
#: lead.
KNOWN_CYCLE_EDGES: dict[tuple[str, str], str] = {}


def test_known_cycle_edges_still_exist():
    gone = [f"{a} -> {b}" for a, b in KNOWN_CYCLE_EDGES if b not in RUNTIME_GRAPH.get(a, set())]
    assert not gone, "remove from KNOWN_CYCLE_EDGES, it is gone:\n" + "\n".join(gone)


def test_no_import_cycle():
    graph = {
        module: {t for t in targets if (module, t) not in KNOWN_CYCLE_EDGES}
        for module, targets in RUNTIME_GRAPH.items()
    }
    cycles = find_cycles(graph)
    assert not cycles, "import cycles among flexopt modules:\n" + "\n".join(
        " -> ".join(cycle) for cycle in cycles
    )


# -- shared compiled kernels (issue 24): one banded LU, one sparsity-pattern builder -------------

#: name written by a subscript -> the one module whose functions may write it: the pivot rows of
#: a pivoting LU (``ipiv[j] = ...``) and the row marker of a pattern builder (``mark[c] = ...``)
SHARED_KERNELS = {"ipiv": "flexopt.fea._banded", "mark": "flexopt.fea._sparse"}


def _subscript_writers(module: str) -> dict[str, set[str]]:
    """Names written through a subscript (``x[i] = ...``, ``x[i] += ...``) -> functions doing it."""
    tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
    found: dict[str, set[str]] = {}
    for fn in ast.walk(tree):
        if not isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        for node in ast.walk(fn):
            targets = node.targets if isinstance(node, ast.Assign) else []
            if isinstance(node, ast.AugAssign):
                targets = [node.target]
            for t in targets:
                if isinstance(t, ast.Subscript) and isinstance(t.value, ast.Name):
                    found.setdefault(t.value.id, set()).add(fn.name)
    return found


def test_the_banded_lu_and_the_pattern_builder_are_written_once():
    """A second pivoting banded LU or marker-deduplicating pattern builder in fea/ is a copy of
    fea/_banded.py's or fea/_sparse.py's: call those instead (they are numba functions, callable
    from any njit code, and cache with their callers)."""
    writers = {name: set() for name in SHARED_KERNELS}
    for module in MODULES:
        if _layer(module) != "fea":
            continue
        for name, fns in _subscript_writers(module).items():
            if name in writers:
                writers[name] |= {f"{module}.{f}" for f in fns}
    for name, home in SHARED_KERNELS.items():
        assert writers[name], f"the scan finds no {name}[...] write at all: is it still {home}'s?"
        strays = sorted(w for w in writers[name] if not w.startswith(home + "."))
        assert not strays, f"{name}[...] written outside {home}: {strays}"


# -- what a study kind may hold (issue 24): no process, solver or plotting library; a size bound --
#
# A kind is its schema, its composition, its requirements and labels (shared/DESIGN.md): process
# handling belongs to the execution layer (pipeline/parallel.py), solving to fea/ and optimise/,
# figures to the shared plotting module. Only kinds count (pipeline/studies/<name>.py, not the
# ``_``-prefixed shared blocks nor the registry ``__init__.py``).

#: library family -> the top-level packages that make it up
FORBIDDEN_IN_KINDS = {
    "process": {"multiprocessing", "concurrent", "subprocess"},
    "solver": {"scipy"},
    "plotting": {"matplotlib", "plotly"},
}

#: the most lines a kind may have (issue 24: "the largest kind is under 700 lines")
MAX_KIND_LINES = 699

#: Offenders, to be kept empty: kind -> the forbidden packages it imports. A kind listed here may
#: drop a package (then remove it from here: the test says so) but not add one. Emptied by #24.
KIND_IMPORT_OFFENDERS: dict[str, set[str]] = {}

#: Offenders, to be kept empty: kind -> its line count. A kind listed here may shrink but not
#: grow; once it is at or under MAX_KIND_LINES, remove it. Emptied by #24: every kind is under 700.
KIND_SIZE_OFFENDERS: dict[str, int] = {}


def _kinds() -> dict[str, Path]:
    """Kind name (``sea_spring``) -> its source file, for every kind in pipeline/studies/."""
    prefix = STUDIES + "."
    return {m[len(prefix) :]: path for m, path in sorted(MODULES.items()) if _is_kind(m)}


def _external_imports(path: Path) -> set[str]:
    """Top-level names of the non-flexopt packages a file imports, anywhere in it (also inside
    functions and under ``TYPE_CHECKING``: a lazy import is still a dependency)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            found |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            found.add(node.module.split(".")[0])
    return found


def _line_count(path: Path) -> int:
    return len(path.read_text(encoding="utf-8").splitlines())


def test_the_kind_scan_sees_the_kinds():
    # Guards the two tests below: an empty or wrong kind list would make them vacuous.
    kinds = _kinds()
    assert {"constant_force", "sea_spring", "polyline_beam"} <= set(kinds), sorted(kinds)
    assert not any(name.startswith("_") for name in kinds)
    assert "multiprocessing" in _external_imports(MODULES["flexopt.pipeline.parallel"])
    assert set(KIND_IMPORT_OFFENDERS) <= set(kinds) and set(KIND_SIZE_OFFENDERS) <= set(kinds)


def test_kinds_import_no_process_solver_or_plotting_library():
    forbidden = set().union(*FORBIDDEN_IN_KINDS.values())
    family = {pkg: fam for fam, pkgs in FORBIDDEN_IN_KINDS.items() for pkg in pkgs}
    new, gone = [], []
    for kind, path in _kinds().items():
        imported = _external_imports(path) & forbidden
        allowed = KIND_IMPORT_OFFENDERS.get(kind, set())
        new += [f"{kind} imports {p} (a {family[p]} library)" for p in sorted(imported - allowed)]
        gone += [f"{kind}: {p}" for p in sorted(allowed - imported)]
    assert not new, (
        "a study kind imports a process, solver or plotting library; processes go through "
        "pipeline/parallel.py, solving into fea/ or optimise/, figures into the shared plotting "
        "module:\n" + "\n".join(new)
    )
    assert not gone, "no longer imported: remove from KIND_IMPORT_OFFENDERS:\n" + "\n".join(gone)


def test_every_kind_is_under_700_lines():
    over, grown, done = [], [], []
    for kind, path in _kinds().items():
        lines = _line_count(path)
        if kind in KIND_SIZE_OFFENDERS:
            if lines <= MAX_KIND_LINES:
                done.append(f"{kind}: {lines} lines")
            elif lines > KIND_SIZE_OFFENDERS[kind]:
                grown.append(f"{kind}: {lines} lines, was {KIND_SIZE_OFFENDERS[kind]}")
        elif lines > MAX_KIND_LINES:
            over.append(f"{kind}: {lines} lines")
    assert not over, (
        f"a study kind over {MAX_KIND_LINES} lines (a kind is its schema and a short "
        "composition; physics goes into fea/, scoring into optimise/):\n" + "\n".join(over)
    )
    assert not grown, "a listed kind grew; it may only shrink:\n" + "\n".join(grown)
    assert not done, (
        f"at or under {MAX_KIND_LINES} lines now: remove from KIND_SIZE_OFFENDERS:\n"
        + "\n".join(done)
    )


def test_no_builtin_kind_has_both_a_problem_and_an_evaluate():
    """One result per design (issue 24): ``flexopt evaluate``, the API and a robustness sample of
    a kind with a design problem are its nominal design's ``DesignProblem.result``
    (:func:`pipeline.problems.study_result`; a kind overrides ``result`` where its answer is more
    than the design's detail). ``StudyKind.evaluate`` is the result hook of a kind without a
    problem only (and of plugins): a kind with both would answer one design two ways."""
    from flexopt.pipeline.studies import builtin_kind_names, get_kind

    names = builtin_kind_names()
    # guards the rule: the scan sees the kinds that lost their evaluate to their problem
    assert {"gripper", "mechanism", "leaf_spring_joint", "constant_force"} <= names
    assert all(get_kind(n).problem is not None for n in ("gripper", "mechanism"))
    both = sorted(
        n for n in names if get_kind(n).problem is not None and get_kind(n).evaluate is not None
    )
    assert not both, (
        "built-in kinds with both a design problem and their own evaluate (give the problem a "
        "result() override instead): " + ", ".join(both)
    )


# -- no private names across modules (issue 24) ----------------------------------------------------

#: (importing module, "module.name") pairs the rule below still lets through. Emptied by #24 (the
#: kinds' target tables are pipeline/targets.py, cam's variables _cam.CAM_VARIABLES); none may be
#: added.
PRIVATE_IMPORTS_ALLOWED: frozenset[tuple[str, str]] = frozenset()


def _is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _private_uses(module: str, source: str | None = None) -> set[str]:
    """The private names of other flexopt modules that ``module`` uses, as ``"module.name"``.

    Counted: ``from flexopt.x import _name`` (also relative, inside functions, under
    TYPE_CHECKING), ``import flexopt.x._y``, and ``alias._name`` where ``alias`` is a flexopt
    module imported by name. A private *module* (``fea/_banded.py``) is private to its package:
    any module of that package may import it. ``source`` stands in for the module's file.
    """
    if source is None:
        source = MODULES[module].read_text(encoding="utf-8")
    tree = ast.parse(source)
    package = module if _is_package(module) else module.rpartition(".")[0]
    found: set[str] = set()
    aliases: dict[str, str] = {}  # local name -> the flexopt module it is bound to

    def inside(owner: str) -> bool:  # module is owner's package or one of its modules
        return module == owner or module.startswith(owner + ".")

    def private_module_ok(path: str) -> bool:
        """Every private part of a dotted module path is one ``module`` may reach."""
        parts = path.split(".")
        return all(
            not _is_private(part) or inside(".".join(parts[:i]))
            for i, part in enumerate(parts)
            if i
        )

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] != "flexopt":
                    continue
                if not private_module_ok(a.name):
                    found.add(a.name)
                if a.asname:
                    aliases[a.asname] = a.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                if node.level > 1:
                    base = base[: -(node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "flexopt" or target == module:
                continue
            if not private_module_ok(target):
                found.add(target)
            for a in node.names:
                full = f"{target}.{a.name}"
                if full in MODULES:  # a module: private to its package
                    if not private_module_ok(full):
                        found.add(full)
                    aliases[a.asname or a.name] = full
                elif _is_private(a.name):
                    found.add(full)
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and _is_private(node.attr)
            and isinstance(node.value, ast.Name)
            and node.value.id in aliases
            and aliases[node.value.id] != module
        ):
            full = f"{aliases[node.value.id]}.{node.attr}"
            if full not in MODULES or not private_module_ok(full):
                found.add(full)
    return found


def test_the_private_name_scan_sees_what_it_must():
    # Guards the rule: a scan that finds nothing would make it vacuous.
    source = (
        "from flexopt.pipeline.run.folder import Columns, _csv\n"
        "from flexopt.fea import _banded\n"
        "import flexopt.fea._sparse\n"
        "from flexopt.pipeline import parallel\n"
        "def f():\n"
        "    from .fork import _hidden\n"
        "    return parallel._context()\n"
    )
    assert _private_uses("flexopt.pipeline.cli", source) == {
        "flexopt.pipeline.run.folder._csv",
        "flexopt.fea._banded",
        "flexopt.fea._sparse",
        "flexopt.pipeline.fork._hidden",
        "flexopt.pipeline.parallel._context",
    }
    # a private module imported inside its package is the package's own (fea's kernels)
    assert not _private_uses("flexopt.fea.beam", "from flexopt.fea import _banded\n")
    assert not _private_uses("flexopt.fea.beam")


def test_no_private_name_is_used_across_modules():
    """A name starting with ``_`` is its module's own: another module that needs it gets a
    public name in its home module (or the code moves). Tests are not scanned."""
    used = {(module, name) for module in MODULES for name in _private_uses(module)}
    stray = sorted(used - PRIVATE_IMPORTS_ALLOWED)
    assert not stray, "private names used across modules:\n" + "\n".join(
        f"{module} uses {name}" for module, name in stray
    )
    gone = sorted(PRIVATE_IMPORTS_ALLOWED - used)
    assert not gone, "remove from PRIVATE_IMPORTS_ALLOWED, it is gone:\n" + "\n".join(
        f"{module} uses {name}" for module, name in gone
    )


#: Exception classes that are not under FlexoptError, with why: Ctrl-C / SIGTERM is not an error,
#: and a plugin's failure in pipeline/studies/__init__.py is left to the kinds' refactor.
NOT_FLEXOPT_ERRORS = {
    "flexopt.geometry.errors.FlexoptError": "the root itself",
    "flexopt.pipeline.errors.Terminated": "a KeyboardInterrupt: a stop, not an error",
    "flexopt.pipeline.studies._PluginFailed": "internal to the plugin loader; the kinds' refactor",
}


def test_every_flexopt_error_derives_from_flexopt_error():
    """One root: a class of flexopt that derives from a built-in exception names FlexoptError
    among its bases (or derives from a flexopt error, which does)."""
    import builtins

    bare, exempt = [], set()
    for module in MODULES:
        tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if not isinstance(node, ast.ClassDef):
                continue
            bases = {b.id for b in node.bases if isinstance(b, ast.Name)}
            builtin = {
                b
                for b in bases
                if isinstance(getattr(builtins, b, None), type)
                and issubclass(getattr(builtins, b), BaseException)
            }
            if builtin and "FlexoptError" not in bases:
                name = f"{module}.{node.name}"
                if name in NOT_FLEXOPT_ERRORS:
                    exempt.add(name)
                else:
                    bare.append(f"{name}({', '.join(sorted(builtin))})")
    assert not bare, "errors not under FlexoptError (add it to their bases):\n" + "\n".join(bare)
    gone = sorted(set(NOT_FLEXOPT_ERRORS) - exempt)
    assert not gone, f"remove from NOT_FLEXOPT_ERRORS, gone or under FlexoptError now: {gone}"


# -- no reaching into another module's objects (issue 24) ------------------------------------------

#: (module, private attribute) reads of another module's object the rule below lets through, each
#: with why: none (the mechanism kind's reads went with its evaluate, issue 24).
PRIVATE_ATTRIBUTES_ALLOWED: dict[tuple[str, str], str] = {}

_OWN = ("self", "cls")
#: The public API of a namedtuple, underscored so as not to clash with its fields.
_NAMEDTUPLE_API = frozenset({"_replace", "_asdict", "_fields", "_make", "_field_defaults"})


def _private_members(tree: ast.Module) -> set[str]:
    """The private names a module defines for its objects: its classes' methods and class
    attributes, ``self._x`` / ``cls._x`` it assigns anywhere, and its module-level functions and
    classes (a module handed around as a value, ``kind._helper``)."""
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            if _is_private(node.name):
                names.add(node.name)
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef):
            for item in node.body:
                if isinstance(item, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                    targets: list[ast.expr] = [ast.Name(item.name)]
                elif isinstance(item, ast.AnnAssign):
                    targets = [item.target]
                elif isinstance(item, ast.Assign):
                    targets = item.targets
                else:
                    continue
                names |= {t.id for t in targets if isinstance(t, ast.Name) and _is_private(t.id)}
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            if (
                isinstance(node.value, ast.Name)
                and node.value.id in _OWN
                and _is_private(node.attr)
            ):
                names.add(node.attr)
    return names


def _attribute_reads(tree: ast.Module) -> set[str]:
    """The private attributes ``tree`` reads off anything but ``self`` / ``cls``: ``obj._x`` and
    ``getattr(obj, "_x")`` (and ``hasattr``)."""
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _is_private(node.attr):
            if not (isinstance(node.value, ast.Name) and node.value.id in _OWN):
                found.add(node.attr)
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id in ("getattr", "hasattr")
            and len(node.args) >= 2
            and isinstance(node.args[1], ast.Constant)
            and isinstance(node.args[1].value, str)
            and _is_private(node.args[1].value)
            and not (isinstance(node.args[0], ast.Name) and node.args[0].id in _OWN)
        ):
            found.add(node.args[1].value)
    return found


def _foreign_private_reads(sources: dict[str, str]) -> dict[tuple[str, str], list[str]]:
    """``(module, name) -> [modules defining name]`` for every private attribute a module reads
    off another object (:func:`_attribute_reads`) that it does not define itself but another
    flexopt module does (:func:`_private_members`): a reach into that module's objects.

    A name that the reading module defines too counts as its own (the scan cannot tell whose
    object it is); a private name no flexopt module defines (a library's) is not ours to judge,
    nor a namedtuple's own API (``_replace``, ``_asdict`` ...).
    """
    trees = {m: ast.parse(s) for m, s in sources.items()}
    members = {m: _private_members(t) for m, t in trees.items()}
    owners: dict[str, set[str]] = {}
    for m, names in members.items():
        for n in names:
            owners.setdefault(n, set()).add(m)
    out: dict[tuple[str, str], list[str]] = {}
    for m, tree in trees.items():
        for name in _attribute_reads(tree) - members[m] - _NAMEDTUPLE_API:
            if owners.get(name):
                out[(m, name)] = sorted(owners[name])
    return out


def test_the_private_attribute_scan_sees_what_it_must():
    # Guards the rule: a scan that finds nothing would make it vacuous.
    sources = {
        "flexopt.fea.model": (
            "class Model:\n"
            "    _table = None\n"
            "    def __init__(self):\n"
            "        self._chol = 1\n"
            "    def _solve(self, b):\n"
            "        return self._chol * b\n"
            "def _helper():\n"
            "    pass\n"
        ),
        "flexopt.fea.user": (
            "def f(model, kind, np):\n"
            "    model._solve(1)\n"
            "    kind._helper()\n"
            "    np._private_thing\n"  # nobody of ours defines it: a library's business
            "    return model._chol, getattr(model, '_table')\n"
        ),
        "flexopt.fea.own": (
            "class Other:\n"
            "    def __init__(self):\n"
            "        self._chol = 2\n"
            "    def g(self, other):\n"
            "        return other._chol\n"  # a name it defines: its own objects
        ),
    }
    found = _foreign_private_reads(sources)
    assert set(found) == {
        ("flexopt.fea.user", "_solve"),
        ("flexopt.fea.user", "_helper"),
        ("flexopt.fea.user", "_chol"),
        ("flexopt.fea.user", "_table"),
    }
    assert found[("flexopt.fea.user", "_chol")] == ["flexopt.fea.model", "flexopt.fea.own"]


def test_no_module_reads_private_attributes_of_another_modules_objects():
    """``model._chol`` where ``model`` is an object of another module's class is an implicit
    contract: the owner gets a public, documented method or property instead (fea/beam.py's
    ``BeamModel.tables``, fea/plane_stress.py's ``reduced_solve``). Tests are not scanned."""
    sources = {m: p.read_text(encoding="utf-8") for m, p in MODULES.items()}
    found = _foreign_private_reads(sources)
    stray = sorted(set(found) - set(PRIVATE_ATTRIBUTES_ALLOWED))
    assert not stray, "private attributes of other modules' objects read:\n" + "\n".join(
        f"{m} reads .{n} (defined in {', '.join(found[(m, n)])})" for m, n in stray
    )
    gone = sorted(set(PRIVATE_ATTRIBUTES_ALLOWED) - set(found))
    assert not gone, "remove from PRIVATE_ATTRIBUTES_ALLOWED, it is gone:\n" + "\n".join(
        f"{m} .{n}" for m, n in gone
    )
