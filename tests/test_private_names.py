"""No module uses another module's private names: a name
that starts with one underscore belongs to the module that defines it, so that module may
change it freely.  Scanned statically over the package, the tests, the demos and the tools:

* ``from m import _name`` (and ``from . import _name`` unless ``_name`` is a private
  submodule of the importer's own package);
* ``m._name`` where ``m`` is a module of this repository bound by an import;
* ``setattr(m, "_name", …)``, ``getattr(m, "_name")``, ``monkeypatch.setattr(m, "_name",
  …)`` — a test that patches a private name depends on it as much as one that imports it.

A helper that tests share lives in a module of its own (``tests/*.py`` without the
``test_`` prefix) under a public name."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the trees scanned, and the prefix of their modules' names (tests, demos and tools put
#: their own folder on sys.path: their modules are imported by their bare names)
TREES = {"contact": "contact.", "tests": "", "demos": "", "tools": ""}

#: uses left in modules other branches are rewriting now (the output folder and plots): each
#: one must still exist (the list only shrinks), none may be added
KNOWN: set[str] = {
    f"{file}: {use}"
    for file, names in {
        "contact/output/step_report.py": ("contact.output.run_report._finish",),
        "demos/bench/bench_kernels.py": ("contact.output.plots._smooth",),
        "tests/test_output_safety.py": ("contact.output.folder._host",),
        "tests/test_plots.py": ("contact.output.plots._smooth",),
    }.items()
    for use in names
}


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _modules() -> dict[str, Path]:
    """Every module of the scanned trees by its import name (a package by its own name)."""
    out: dict[str, Path] = {}
    for tree, prefix in TREES.items():
        base = ROOT / tree
        for path in sorted(base.rglob("*.py")):
            rel = path.relative_to(ROOT if prefix else base).with_suffix("")
            parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
            out[".".join(parts)] = path
    return out


def _resolve(module: str | None, level: int, importer: str, is_package: bool) -> str:
    """The absolute name of ``from <level dots><module> import …`` in module ``importer``."""
    if level == 0:
        return module or ""
    parts = importer.split(".")
    if not is_package:
        parts = parts[:-1]
    parts = parts[: len(parts) - (level - 1)]
    return ".".join(parts + ([module] if module else []))


def _dotted(node: ast.expr) -> list[str] | None:
    """``a.b.c`` of a chain of names and attributes, else None."""
    names = []
    while isinstance(node, ast.Attribute):
        names.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    return [node.id, *reversed(names)]


def uses(path: Path, name: str, modules: dict[str, Path]) -> Iterator[str]:
    """The private names of other modules that the module ``name`` at ``path`` uses, each
    as ``<module>.<private name>``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    is_package = path.name == "__init__.py"
    bound: dict[str, str] = {}  # local name -> the module of this repository it is
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.asname:
                    bound[alias.asname] = alias.name
                else:
                    head = alias.name.split(".")[0]
                    bound[head] = head
        elif isinstance(node, ast.ImportFrom):
            source = _resolve(node.module, node.level, name, is_package)
            for alias in node.names:
                full = f"{source}.{alias.name}"
                if full in modules:
                    bound[alias.asname or alias.name] = full
                    own_package = source == (name if is_package else name.rpartition(".")[0])
                    if _private(alias.name) and not own_package:
                        yield full
                elif _private(alias.name) and source != name:
                    yield full

    def module_of(node: ast.expr) -> str | None:
        chain = _dotted(node)
        if chain is None or chain[0] not in bound:
            return None
        full = ".".join([bound[chain[0]], *chain[1:]])
        return full if full in modules and full != name else None

    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            if (module := module_of(node.value)) is not None:
                yield f"{module}.{node.attr}"
        elif isinstance(node, ast.Call) and len(node.args) >= 2:
            func = _dotted(node.func)
            target, attr = node.args[0], node.args[1]
            if (
                func is not None
                and func[-1] in ("setattr", "getattr", "delattr", "hasattr")
                and isinstance(attr, ast.Constant)
                and isinstance(attr.value, str)
                and _private(attr.value)
                and (module := module_of(target)) is not None
            ):
                yield f"{module}.{attr.value}"


def scan() -> set[str]:
    """Every use of another module's private name: ``<file>: <module>.<name>``."""
    modules = _modules()
    found = set()
    for name, path in modules.items():
        for use in uses(path, name, modules):
            found.add(f"{path.relative_to(ROOT)}: {use}")
    return found


def test_no_module_uses_another_modules_private_names():
    found = scan()
    new = sorted(found - KNOWN)
    assert not new, "private names of another module used (make them public or move them):\n" + (
        "\n".join(new)
    )
    gone = sorted(KNOWN - found)
    assert not gone, "no longer used, remove from KNOWN:\n" + "\n".join(gone)


def test_the_scan_finds_each_kind_of_use(tmp_path):
    """The scanner sees an import, an attribute and a monkeypatch of a private name, and
    lets a module use its own private names and a package its private submodules."""
    modules = {"pkg": tmp_path / "pkg/__init__.py", "pkg.a": tmp_path / "a.py"}
    modules["pkg._impl"] = tmp_path / "_impl.py"
    source = tmp_path / "b.py"
    source.write_text(
        "import pkg.a as m\n"
        "from pkg import a\n"
        "from .a import _x, public\n"
        "from . import _impl\n"
        "_mine = 1\n"
        "y = m._y + a._z + _mine + public\n"
        "def test(monkeypatch):\n"
        "    monkeypatch.setattr(a, '_w', 1)\n"
        "    monkeypatch.setattr(a, 'ok', 1)\n"
    )
    modules["pkg.b"] = source
    assert sorted(uses(source, "pkg.b", modules)) == [
        "pkg.a._w",
        "pkg.a._x",
        "pkg.a._y",
        "pkg.a._z",
    ]
