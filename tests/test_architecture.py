"""The package graph flows one way: geometry -> data -> recognition -> pretrain -> awareness ->
robot -> planning -> experiment -> robot_api -> study (with pipeline) -> cli, with the top-level
helpers (io, progress, parallel, workspace, section, config, context) beneath every stage. Every
import counts, lazy ones inside functions included. Nothing but the command line imports
robot_api."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

SOURCE = Path(__file__).resolve().parents[1] / "src" / "rapomdp"

#: The pipeline's stage packages in order; a package may import only itself and earlier ones.
STAGE_ORDER = ["geometry", "data", "recognition", "pretrain", "awareness", "robot", "planning",
               "experiment", "robot_api", "study", "cli"]
#: Top-level modules that belong to the command line's level (they assemble every stage).
TOP_LEVEL_STAGE = {"cli": "cli", "pipeline": "study"}
#: The level of the foundations: top-level helpers that import no stage package.
FOUNDATION = "foundation"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SOURCE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports_of(path: Path) -> Iterator[tuple[str, int]]:
    """Every ``rapomdp`` module ``path`` imports (at any depth: lazy imports too), with its line."""
    package = module_name(path)
    if path.name != "__init__.py":
        package = package.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "rapomdp":
                    yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "rapomdp":
                continue
            # ``from rapomdp.x import y`` imports the module ``rapomdp.x.y`` when it is one.
            for alias in node.names:
                candidate = f"{target}.{alias.name}"
                as_module = SOURCE.parent / Path(*candidate.split("."))
                is_module = as_module.with_suffix(".py").exists() or as_module.is_dir()
                yield (candidate if is_module else target), node.lineno


def level_of(module: str) -> str:
    """The stage package a module belongs to, or :data:`FOUNDATION` for the top-level helpers."""
    parts = module.split(".")
    if len(parts) == 1:
        return FOUNDATION
    head = parts[1]
    if head in STAGE_ORDER:
        return head
    return TOP_LEVEL_STAGE.get(head, FOUNDATION)


def rank(level: str) -> int:
    return -1 if level == FOUNDATION else STAGE_ORDER.index(level)


def import_graph() -> dict[str, dict[str, int]]:
    """``{module: {imported module: line}}`` over every module of the package."""
    graph: dict[str, dict[str, int]] = {}
    for path in sorted(SOURCE.rglob("*.py")):
        edges: dict[str, int] = {}
        for target, line in imports_of(path):
            edges.setdefault(target, line)
        graph[module_name(path)] = edges
    return graph


def package_of(module: str) -> str:
    """A module's subpackage (``rapomdp.awareness``) or itself for a top-level module."""
    return ".".join(module.split(".")[:2])


def upward_imports(graph: dict[str, dict[str, int]]) -> list[str]:
    """Each import from a later stage's package into an earlier one (or a foundation)."""
    found = []
    for module, edges in graph.items():
        for target, line in edges.items():
            if rank(level_of(target)) > rank(level_of(module)):
                found.append(f"{module}:{line} imports {target} "
                             f"({level_of(module)} -> {level_of(target)})")
    return sorted(found)


def package_cycles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """Strongly connected groups of two or more subpackages / top-level modules."""
    packages: dict[str, set[str]] = {}
    for module, edges in graph.items():
        source = package_of(module)
        packages.setdefault(source, set())
        for target in edges:
            if package_of(target) != source and package_of(target) != "rapomdp":
                packages[source].add(package_of(target))
    return strongly_connected(packages)


def module_cycles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """Strongly connected groups of two or more modules (a package's ``__init__`` aside)."""
    packages = {name for name in graph if (SOURCE.parent / Path(*name.split("."))).is_dir()}
    edges = {module: {t for t in targets if t in graph and t not in packages and t != module}
             for module, targets in graph.items() if module not in packages}
    return strongly_connected(edges)


def strongly_connected(packages: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of two or more nodes of a directed graph (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in sorted(packages.get(node, ())):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            group = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                group.append(member)
                if member == node:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for node in sorted(packages):
        if node not in index:
            visit(node)
    return sorted(groups)


def loaded_modules(statement: str) -> list[str]:
    """The modules (``rapomdp.*`` and heavy third-party roots) a fresh interpreter holds after
    ``statement``."""
    code = (f"import sys, json; {statement}; "
            "print(json.dumps(sorted(m for m in sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True).stdout
    return json.loads(out)


def test_the_graph_tool_sees_lazy_and_relative_imports(tmp_path: Path) -> None:
    graph = import_graph()
    # ``pipeline`` imports every stage at module level; the CLI imports some lazily.
    assert "rapomdp.awareness.stage" in graph["rapomdp.pipeline"]
    assert "rapomdp.data.dataset" in graph["rapomdp.cli.dataset"]  # inside _write_preview
    assert "rapomdp.cli.stages" in graph["rapomdp.cli"]  # the app registers them
    assert level_of("rapomdp.io") == FOUNDATION
    assert level_of("rapomdp.planning.cli") == "planning"
    assert level_of("rapomdp.pipeline") == "study"  # the study runs the pipeline; cli both


def test_no_import_cycle_between_subpackages() -> None:
    assert package_cycles(import_graph()) == []


def test_no_import_cycle_between_modules() -> None:
    assert module_cycles(import_graph()) == []


def test_no_import_from_a_later_stage_into_an_earlier_one() -> None:
    assert upward_imports(import_graph()) == []


def test_only_the_command_line_imports_the_robot_api() -> None:
    importers = sorted(f"{module}:{line}" for module, edges in import_graph().items()
                       for target, line in edges.items()
                       if level_of(target) == "robot_api"
                       and level_of(module) not in ("robot_api", "cli"))
    assert importers == []


@pytest.mark.parametrize("statement", ["import rapomdp.config", "import rapomdp.workspace"])
def test_the_configuration_loads_no_stage_code(statement: str) -> None:
    modules = loaded_modules(statement)
    stage_modules = [m for m in modules if m.startswith("rapomdp.")
                     and level_of(m) != FOUNDATION]
    assert stage_modules == []
    for heavy in ("torch", "roboticstoolbox", "matplotlib", "trimesh"):
        assert heavy not in modules


def _library_trees() -> Iterator[tuple[Path, ast.AST]]:
    for path in sorted(SOURCE.rglob("*.py")):
        yield path, ast.parse(path.read_text(), str(path))


def test_no_module_rebinds_its_globals() -> None:
    """Run settings travel in a RunContext: no ``global`` statement anywhere in the library."""
    found = [f"{path.relative_to(SOURCE)}:{node.lineno}" for path, tree in _library_trees()
             for node in ast.walk(tree) if isinstance(node, ast.Global)]
    assert found == []


def test_figures_use_the_object_api() -> None:
    """No pyplot state and no backend switch (``matplotlib.use``) in the library: a notebook
    user's backend stays theirs."""
    found = []
    for path, tree in _library_trees():
        for node in ast.walk(tree):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [f"{node.module}.{a.name}" for a in node.names]
                     if isinstance(node, ast.ImportFrom) else [])
            if any(name.startswith("matplotlib.pyplot") for name in names):
                found.append(f"{path.relative_to(SOURCE)}:{node.lineno} imports pyplot")
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr == "use" and isinstance(node.func.value, ast.Name)
                    and node.func.value.id == "matplotlib"):
                found.append(f"{path.relative_to(SOURCE)}:{node.lineno} calls matplotlib.use")
    assert found == []


def test_the_artefact_readers_and_the_solve_stage_load_no_torch() -> None:
    for statement in ("import rapomdp.recognition.artefacts", "import rapomdp.awareness.artefacts",
                      "import rapomdp.robot.artefacts", "import rapomdp.planning.artefacts",
                      "import rapomdp.planning.stage"):
        modules = loaded_modules(statement)
        assert "torch" not in modules and "roboticstoolbox" not in modules, statement
