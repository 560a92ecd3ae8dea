"""The package's layout: data flows one way, so no two modules of ``contact`` import each
other, directly or around a loop — function-level ("lazy") imports included, imports used
only for annotations (``if TYPE_CHECKING:``) left out."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "contact"


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _annotation_only_lines(tree: ast.Module) -> set[int]:
    return {node.lineno
            for block in ast.walk(tree)
            if isinstance(block, ast.If) and "TYPE_CHECKING" in ast.unparse(block.test)
            for node in ast.walk(block) if hasattr(node, "lineno")}


def import_graph() -> dict[str, set[str]]:
    """module -> the package's modules it imports (``from .x import y`` names module ``x.y``
    when ``y`` is a module, else ``x``)."""
    paths = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in paths.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        tree = ast.parse(path.read_text())
        skip = _annotation_only_lines(tree)
        targets = graph.setdefault(name, set())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import) and node.lineno not in skip:   # import contact.x
                targets |= {a.name for a in node.names} & paths.keys() - {name}
            if not isinstance(node, ast.ImportFrom) or node.lineno in skip:
                continue
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            submodules = {f"{module}.{a.name}" for a in node.names} & paths.keys()
            targets |= (submodules or {module} & paths.keys()) - {name}
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while (w := stack.pop()) != v:
                component.append(w)
            if component:
                found.append(sorted([v, *component]))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_the_circle_finder_finds_a_planted_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert circles(graph) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": set()}) == []


def test_the_import_graph_sees_lazy_imports():
    graph = import_graph()
    # models.build_problem imports the elasticity model inside the function
    assert "contact.models.elasticity" in graph["contact.models"]
    # a package's __init__ importing its own submodule
    assert "contact.solvers.result" in graph["contact.solvers"]


def test_no_two_modules_import_each_other():
    assert circles(import_graph()) == []
