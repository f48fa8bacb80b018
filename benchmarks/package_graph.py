"""The package graph as tests/test_architecture.py checks it: cycles between subpackages, imports
from a later stage into an earlier one, and what ``import rapomdp.config`` / ``rapomdp.planning``
load in a fresh interpreter.

    PYTHONPATH=src python benchmarks/package_graph.py
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.test_architecture import (  # noqa: E402
    import_graph,
    loaded_modules,
    module_cycles,
    package_cycles,
    upward_imports,
)

HEAVY = ("torch", "roboticstoolbox", "matplotlib", "trimesh", "embreex", "plotly")


def main() -> None:
    graph = import_graph()
    edges = sum(len(e) for e in graph.values())
    print(f"modules: {len(graph)}, import edges between them: {edges}")
    cycles = package_cycles(graph)
    print(f"cycles between subpackages: {len(cycles)}")
    for group in cycles:
        print("  " + " <-> ".join(group))
    cycles = module_cycles(graph)
    print(f"cycles between modules: {len(cycles)}")
    for group in cycles:
        print("  " + " <-> ".join(group))
    upward = upward_imports(graph)
    print(f"upward imports (later stage into earlier, or stage into a foundation): {len(upward)}")
    for line in upward:
        print("  " + line)
    for statement in ("import rapomdp.config", "import rapomdp.planning",
                      "import rapomdp.planning.policy"):
        modules = loaded_modules(statement)
        ours = [m for m in modules if m.startswith("rapomdp")]
        heavy = [m for m in HEAVY if m in modules]
        print(f"{statement}: {len(ours)} rapomdp modules, heavy: {heavy or 'none'}")
        print("  " + ", ".join(m.removeprefix("rapomdp.") for m in ours))


if __name__ == "__main__":
    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
