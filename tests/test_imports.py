"""The package's import structure, read from the source with ``ast``: nothing outside ``krl.cli`` imports
``krl.cli``, and no chain of krl imports leads back to where it started.

Every ``krl`` import counts, at module level and inside functions: a circle of function-level imports
still ties the modules together. ``from krl.x import y`` is an import of module ``krl.x.y`` when that is a
module and of ``krl.x`` otherwise; importing a package is importing its ``__init__``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import krl

ROOT = Path(krl.__file__).resolve().parent


def module_name(path: Path) -> str:
    parts = ("krl", *path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES: dict[str, Path] = {module_name(path): path for path in sorted(ROOT.rglob("*.py"))}


def _absolute(node: ast.ImportFrom, module: str) -> str:
    """The absolute module a ``from … import`` names (relative imports resolved against ``module``)."""
    if not node.level:
        return node.module or ""
    package = module if MODULES[module].name == "__init__.py" else module.rpartition(".")[0]
    base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
    return f"{base}.{node.module}" if node.module else base


def _known(name: str) -> str | None:
    """``name`` or its nearest enclosing module that is a krl module."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def imports_of(module: str) -> set[str]:
    """The krl modules ``module`` imports, anywhere in its source."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(MODULES[module].read_text(), str(MODULES[module]))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            source = _absolute(node, module)
            targets = [
                f"{source}.{alias.name}" if f"{source}.{alias.name}" in MODULES else source
                for alias in node.names
            ]
        else:
            continue
        found |= {known for target in targets if target.split(".")[0] == "krl" and (known := _known(target))}
    found.discard(module)
    return found


GRAPH: dict[str, set[str]] = {module: imports_of(module) for module in MODULES}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One import cycle for each strongly connected component of more than one module (Tarjan), each as
    the chain of modules ``[a, b, …, a]``."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[set[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for successor in sorted(graph[node]):
            if successor not in index:
                visit(successor)
                low[node] = min(low[node], low[successor])
            elif successor in on_stack:
                low[node] = min(low[node], index[successor])
        if low[node] == index[node]:
            component = set()
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.add(member)
                if member == node:
                    break
            if len(component) > 1:
                components.append(component)

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return [_cycle_in(graph, component) for component in components]


def _cycle_in(graph: dict[str, set[str]], component: set[str]) -> list[str]:
    """A shortest chain of imports from the component's first module (sorted) back to itself."""
    start = min(component)
    paths = {start: [start]}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for successor in sorted(graph[node] & component):
                if successor == start:
                    return [*paths[node], start]
                if successor not in paths:
                    paths[successor] = [*paths[node], successor]
                    following.append(successor)
        frontier = following
    raise AssertionError(f"no cycle through {start}")


def test_the_module_list_sees_the_package():
    assert {"krl", "krl.cli", "krl.cli.common", "krl.kernel.registry", "krl.runner"} <= set(MODULES)


def test_imports_resolve_to_modules():
    assert "krl.cli.common" in GRAPH["krl.cli.kernel"]  # from krl.cli.common import …
    assert "krl.cli.kernel" in GRAPH["krl.cli"]  # from krl.cli import kernel (a module)
    assert "krl.kernel.registry" in GRAPH["krl.kernel.controller"]


def test_the_cycle_finder_on_a_known_graph():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set(), "e": {"e"}}
    assert cycles(graph) == [["a", "b", "c", "a"]]


def test_nothing_outside_the_cli_imports_it():
    upward = sorted(
        f"{module} imports {target}"
        for module, targets in GRAPH.items()
        if not (module == "krl.cli" or module.startswith("krl.cli."))
        for target in targets
        if target == "krl.cli" or target.startswith("krl.cli.")
    )
    assert not upward, "\n".join(upward)


def test_no_import_cycle():
    found = cycles(GRAPH)
    assert not found, "import cycles:\n" + "\n".join(" -> ".join(cycle) for cycle in found)
