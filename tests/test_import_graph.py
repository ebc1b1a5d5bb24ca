"""The import graph has no cycle, and the pillars never import the app layer.

Every ``import`` counts, also one inside a function (a lazy import is still a
dependency: the cycle ``servoid.monitor`` <-> ``servoid.plots.monitor`` was
one), except those under ``if TYPE_CHECKING:``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: import name -> folder, as pyproject.toml's package-dir maps them
PACKAGES = {"servoid.ident": ROOT / "ident", "servoid.excitation": ROOT / "excitation",
            "servoid.drivers": ROOT / "drivers", "servoid": ROOT / "servoid"}  # fmt: skip
#: the modules of the app layer every pillar may use: the exception root, the argument checks, the limits, the
#: lazy package loader, the names of the readings' side (a driver states it, identification judges by it)
SHARED = {"servoid.errors", "servoid.validation", "servoid.limits", "servoid.lazy", "servoid.readings_side"}


def _modules() -> dict[str, Path]:
    found: dict[str, Path] = {}
    for package, folder in PACKAGES.items():
        for path in folder.rglob("*.py"):
            rel = path.relative_to(folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            found[".".join([package, *parts])] = path
    return found


def _type_checking_lines(tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for sub in node.body:
                lines.update(range(sub.lineno, (sub.end_lineno or sub.lineno) + 1))
    return lines


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        skip = _type_checking_lines(tree)
        edges: set[str] = set()
        for node in ast.walk(tree):
            if getattr(node, "lineno", None) in skip:
                continue
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in modules else node.module
                           for a in node.names]  # fmt: skip
            else:
                continue
            edges.update(t for t in targets if t in modules and t != name)
        graph[name] = edges
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def _is_package_init(name: str, graph: dict[str, set[str]]) -> bool:
    return any(other.startswith(name + ".") for other in graph)


def test_no_import_cycle():
    graph = _graph()
    # a package's __init__ re-exporting its own modules is not a dependency of those modules on it
    graph = {m: {t for t in e if not (_is_package_init(t, graph) and m.startswith(t + "."))} for m, e in graph.items()}
    for m in list(graph):
        if _is_package_init(m, graph):
            graph[m] = {t for t in graph[m] if not t.startswith(m + ".")}
    cycle = _cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


@pytest.mark.parametrize("pillar", ["servoid.ident", "servoid.excitation", "servoid.drivers"])
def test_the_pillars_never_import_the_app_layer(pillar):
    graph = _graph()
    pillars = ("servoid.ident", "servoid.excitation", "servoid.drivers")
    bad = sorted(
        f"{m} imports {t}"
        for m, edges in graph.items() if m == pillar or m.startswith(pillar + ".")
        for t in edges
        if not t.startswith(pillars) and t not in SHARED
    )  # fmt: skip
    assert not bad, "; ".join(bad)
