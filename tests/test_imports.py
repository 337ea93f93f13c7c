"""The package's import structure, read from the source with ``ast``: krl's packages stand in one declared
order (:data:`PACKAGE_ORDER`, bottom first) and each imports only itself and packages below it; no chain of
krl imports leads back to where it started; ``src/krl/`` holds packages, not modules.

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


PACKAGE_ORDER: tuple[str, ...] = (
    "util",  # rates, atomic output, progress bars, the process pool, hashes, the thesis's constants
    "robots",  # the A1 model and its constants
    "sim",  # MuJoCo: terrains, the robot, pushes, the batch of simulators, rendering
    "control",  # kinematics, gait, commands, filters, swing, the MPC expert
    "task",  # the waypoint task, the reward, the runner that walks a controller through it
    "data",  # expert datasets: columns, schema, writer, reader, collection
    "kernel",  # the kernel: features, MLP, training, studies, the kernel as a controller
    "agent",  # the residual agent: action path, environments, PPO training, policy files
    "envs",  # Gymnasium registration (krl/A1-v0, krl/A1Residual-v0)
    "eval",  # courses, controllers, metrics, push sweep, reports
    "analysis",  # figures
    "bench",  # throughput benchmarks
    "apps",  # demo, viewer, export, reproduce: programs built from everything below
    "cli",  # the krl command
)
"""krl's packages from the bottom up: a module may import its own package and the packages before it."""

ROOT_IMPORTS: frozenset[str] = frozenset({"krl.sim.render", "krl.envs"})
"""What the root ``krl/__init__.py`` may import: it runs before every krl import, to select the offscreen
GL backend before MuJoCo loads and to register the environments (by entry-point string, importing none)."""


def package_of(module: str) -> str | None:
    """``krl.kernel.model`` -> ``kernel``; the root ``krl`` -> None."""
    return module.split(".")[1] if module.count(".") else None


def upward_imports(graph: dict[str, set[str]], order: tuple[str, ...] = PACKAGE_ORDER) -> list[str]:
    """Every import that breaks ``order``: a module importing a package above its own, or the root
    importing more than :data:`ROOT_IMPORTS`. Any module may import the root (``krl.__version__``)."""
    rank = {package: level for level, package in enumerate(order)}
    broken = []
    for module, targets in sorted(graph.items()):
        own = package_of(module)
        for target in sorted(targets):
            other = package_of(target)
            if own is None:
                if target not in ROOT_IMPORTS:
                    broken.append(f"{module} imports {target} (the root may import {sorted(ROOT_IMPORTS)})")
            elif other is not None and rank[other] > rank[own]:
                broken.append(f"{module} ({own}) imports {target} ({other}, above it)")
    return broken


def test_the_module_list_sees_the_package():
    assert {"krl", "krl.cli", "krl.cli.common", "krl.kernel.registry", "krl.task.runner"} <= set(MODULES)


def test_every_package_has_a_place_in_the_order():
    packages = {package_of(module) for module in MODULES} - {None}
    assert packages == set(PACKAGE_ORDER), f"not in PACKAGE_ORDER: {sorted(packages ^ set(PACKAGE_ORDER))}"
    loose = sorted(path.name for path in ROOT.glob("*.py") if path.name != "__init__.py")
    assert not loose, f"src/krl/ holds modules outside a package: {loose}"


def test_the_order_checker_catches_a_planted_upward_import():
    planted = {
        "krl.util.timing": {"krl.sim.robot"},
        "krl.sim.robot": {"krl.util.timing", "krl"},
        "krl.cli.sim": {"krl.sim.robot"},
        "krl": {"krl.envs", "krl.agent.env"},
    }
    assert upward_imports(planted) == [
        "krl imports krl.agent.env (the root may import ['krl.envs', 'krl.sim.render'])",
        "krl.util.timing (util) imports krl.sim.robot (sim, above it)",
    ]


def test_packages_import_only_packages_below_them():
    broken = upward_imports(GRAPH)
    assert not broken, "imports against PACKAGE_ORDER:\n" + "\n".join(broken)


def test_imports_resolve_to_modules():
    assert "krl.cli.common" in GRAPH["krl.cli.kernel"]  # from krl.cli.common import …
    assert "krl.cli.kernel" in GRAPH["krl.cli"]  # from krl.cli import kernel (a module)
    assert "krl.kernel.settings" in GRAPH["krl.kernel.controller"]


def test_the_cycle_finder_on_a_known_graph():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set(), "e": {"e"}}
    assert cycles(graph) == [["a", "b", "c", "a"]]


def test_no_import_cycle():
    found = cycles(GRAPH)
    assert not found, "import cycles:\n" + "\n".join(" -> ".join(cycle) for cycle in found)


def test_the_packages_page_and_the_cli_docstring_list_every_package_in_order():
    import re

    import krl.cli

    table = (ROOT.parents[1] / "docs" / "packages.md").read_text()
    assert re.findall(r"^\| `krl\.(\w+)` \|", table, re.MULTILINE) == list(PACKAGE_ORDER)
    assert re.findall(r"^- :mod:`krl\.(\w+)`", krl.cli.__doc__, re.MULTILINE) == list(PACKAGE_ORDER)
