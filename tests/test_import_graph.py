"""The package's modules import one another without cycles.

Every module of `python/irfidelity` is parsed (not imported) and its imports of other
irfidelity modules collected. Imports a module runs when it is loaded (module level, class
bodies, module-level `if`/`try`) are its hard dependencies; imports inside a function run on
the first call and are recorded apart as deferred ones, because a deferred import is the usual
way to hide a cycle. Imports under `if TYPE_CHECKING:` never run and do not count.

An import names a module: `from .x import y` and `from . import x` name `x` when it is a module
and the package's `__init__` otherwise; importing `a.b.c` runs the `__init__`s of `a` and `a.b`
first, so those packages count too, unless they enclose the importer (they are then already loading).
The top package `irfidelity` imports the whole public surface, so no module imports it.
"""

from __future__ import annotations

import ast
import pathlib
from collections.abc import Iterator

TOP = "irfidelity"
PACKAGE = pathlib.Path(__file__).resolve().parent.parent / "python" / TOP

# Deferred imports that may close a cycle, each (importer, imported): the reason why.
# Keep it short; the fix for a cycle is to move code to where it belongs.
ALLOWED_DEFERRED: dict[tuple[str, str], str] = {}


def module_names() -> dict[str, pathlib.Path]:
    """Every module's dotted name and its source file (a package's is its `__init__.py`)."""
    names = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = (TOP, *path.relative_to(PACKAGE).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        names[".".join(parts)] = path
    return names


def extension_names() -> set[str]:
    """Compiled modules (`_core`), known by their type stubs: imported, never importing."""
    return {".".join((TOP, *p.relative_to(PACKAGE).with_suffix("").parts)) for p in PACKAGE.rglob("*.pyi")}


def is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def imports(tree: ast.AST, in_function: bool = False) -> Iterator[tuple[ast.Import | ast.ImportFrom, bool]]:
    """Each import statement and whether it sits inside a function; TYPE_CHECKING blocks skipped."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node, in_function
        elif isinstance(node, ast.If) and is_type_checking(node.test):
            for child in node.orelse:
                yield from imports(ast.Module(body=[child], type_ignores=[]), in_function)
        else:
            nested = in_function or isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda)
            yield from imports(node, nested)


def targets(importer: str, is_package: bool, node: ast.Import | ast.ImportFrom, known: set[str]) -> set[str]:
    """The irfidelity modules one import statement loads: the named ones and their packages."""
    named: set[str] = set()
    if isinstance(node, ast.Import):
        named = {alias.name for alias in node.names}
    else:
        if node.level:
            base = importer.split(".") if is_package else importer.split(".")[:-1]
            base = base[: len(base) - (node.level - 1)]
            source = ".".join(base + ([node.module] if node.module else []))
        else:
            source = node.module or ""
        modules = {f"{source}.{alias.name}" for alias in node.names} & known
        # `from p import m` of a module m only needs p loading; any other name needs p's body run
        named = modules | ({source} if len(modules) < len(node.names) else set())
    named = {name for name in named if name == TOP or name.startswith(TOP + ".")}
    # importing a.b.c runs the `__init__`s of a and a.b first; those enclosing the importer are
    # already loading, so they count only where named (`from .. import x` takes x from one)
    own_packages = {".".join(importer.split(".")[:end]) for end in range(1, importer.count(".") + 1)}
    parents = {".".join(name.split(".")[:end]) for name in named for end in range(1, name.count(".") + 1)}
    return ((named | (parents - own_packages)) & known) - {importer}


def import_graph() -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """(hard, deferred): each module's module-level dependencies, and its function-level ones."""
    sources = module_names()
    known = set(sources) | extension_names()
    hard: dict[str, set[str]] = {name: set() for name in known}
    deferred: dict[str, set[str]] = {name: set() for name in known}
    for name, path in sources.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node, in_function in imports(tree):
            found = targets(name, path.name == "__init__.py", node, known)
            (deferred if in_function else hard)[name] |= found
    for name in deferred:
        deferred[name] -= hard[name]
    return hard, deferred


def cycles(graph: dict[str, set[str]]) -> list[tuple[list[str], set[str]]]:
    """Each strongly connected component of more than one module, with a shortest cycle through it."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[set[str]] = []

    def visit(node: str) -> None:  # Tarjan's algorithm; the graph has a few hundred nodes
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for succ in sorted(graph[node]):
            if succ not in index:
                visit(succ)
                low[node] = min(low[node], low[succ])
            elif succ in on_stack:
                low[node] = min(low[node], index[succ])
        if low[node] == index[node]:
            component = set()
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.add(member)
                if member == node:
                    break
            if len(component) > 1 or node in graph[node]:
                components.append(component)

    for node in sorted(graph):
        if node not in index:
            visit(node)

    found = []
    for component in components:
        start = min(component)
        # breadth-first from start back to start, within the component
        paths = {start: [start]}
        frontier = [start]
        cycle: list[str] = []
        while frontier and not cycle:
            following = []
            for node in frontier:
                for succ in sorted(graph[node] & component):
                    if succ == start:
                        cycle = [*paths[node], start]
                        break
                    if succ not in paths:
                        paths[succ] = [*paths[node], succ]
                        following.append(succ)
                if cycle:
                    break
            frontier = following
        found.append((cycle, component))
    return sorted(found, key=lambda found: found[0])


def describe(found: list[tuple[list[str], set[str]]], deferred: dict[str, set[str]] | None = None) -> str:
    """One line a cycle, ``a -> b -> a``, with its function-level steps (``deferred``) and the
    other modules of its component, which lie on further cycles with it."""
    def short(name: str) -> str:
        return name.removeprefix(TOP + ".") or TOP

    lines = []
    for cycle, component in found:
        line = " -> ".join(map(short, cycle))
        steps = [f"{short(a)} -> {short(b)}" for a, b in zip(cycle, cycle[1:]) if deferred and b in deferred[a]]
        if steps:
            line += f"  (deferred: {', '.join(steps)})"
        others = sorted(component - set(cycle))
        if others:
            line += f"  (also in the cycles: {', '.join(map(short, others))})"
        lines.append(line)
    return "\n".join(lines)


def test_the_graph_sees_the_package():
    hard, deferred = import_graph()
    assert "irfidelity.evaluation" in hard["irfidelity"]
    assert "irfidelity._core" in hard["irfidelity.stats"]
    assert "irfidelity.curves" in hard
    assert sum(map(len, hard.values())) > 100


def test_no_module_imports_the_top_package():
    hard, deferred = import_graph()
    importers = sorted(name for name in hard if TOP in hard[name] | deferred[name])
    assert not importers, f"these modules import the top package `{TOP}` (it imports them): {importers}"


def test_no_cycle_among_module_level_imports():
    hard, _ = import_graph()
    found = cycles(hard)
    assert not found, "import cycles among module-level imports:\n" + describe(found)


def test_no_cycle_counting_deferred_imports():
    hard, deferred = import_graph()
    graph = {
        name: hard[name] | {dep for dep in deferred[name] if (name, dep) not in ALLOWED_DEFERRED}
        for name in hard
    }
    found = cycles(graph)
    assert not found, "import cycles through function-level imports:\n" + describe(found, deferred)


def test_the_allowed_deferred_imports_exist():
    _, deferred = import_graph()
    stale = [pair for pair in ALLOWED_DEFERRED if pair[1] not in deferred.get(pair[0], set())]
    assert not stale, f"allowed deferred imports no longer in the code: {stale}"
