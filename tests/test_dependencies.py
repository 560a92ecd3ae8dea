"""pyproject.toml's dependencies are what the code uses: every runtime dependency is imported
by contact/ (or is the MPI launcher), every third-party module contact/ imports is declared
(or comes with the FEniCS wheel), and every test-extra package is imported by tests/ or run
by the Makefile."""

import ast
import importlib.metadata as md
import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: declared without an import: mpich provides `mpirun` (`make demo`, the MPI tests)
LAUNCHERS = {"mpich"}
#: the FEniCS wheel that brings petsc4py, dolfinx and the packages it requires (ufl, basix, …)
STACK = "dolfinx-solver-real"


def _normal(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _declared(group: str | None = None) -> set[str]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    wanted = project["dependencies"] if group is None else project["optional-dependencies"][group]
    return {_normal(re.split(r"[<>=!~\[; ]", req, maxsplit=1)[0]) for req in wanted}


def _imported_distributions(folder: str) -> set[str]:
    """The distributions of every top-level module imported anywhere in ``folder`` (function-
    level imports included), the standard library and local modules left out."""
    modules: set[str] = set()
    for path in (ROOT / folder).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                modules.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                modules.add(node.module.split(".")[0])
    owners = md.packages_distributions()
    return {_normal(d) for m in modules - set(sys.stdlib_module_names) for d in owners.get(m, [])}


def test_every_runtime_dependency_is_used() -> None:
    unused = _declared() - _imported_distributions("contact") - LAUNCHERS
    assert unused == set(), f"declared dependencies that contact/ never imports: {unused}"


def test_every_import_of_contact_is_declared() -> None:
    stack = {STACK} | {
        _normal(re.split(r"[<>=!~\[; ]", r, maxsplit=1)[0])
        for r in md.requires(STACK) or []
        if "extra ==" not in r
    }
    undeclared = _imported_distributions("contact") - {"contact"} - _declared() - stack
    assert undeclared == set(), f"imported by contact/ but not declared: {undeclared}"


def _commands(distribution: str) -> set[str]:
    """The commands a distribution installs: its console scripts (``lint-imports``), or its
    own name for a binary wheel without any (``ruff``)."""
    scripts = md.distribution(distribution).entry_points.select(group="console_scripts")
    return {ep.name for ep in scripts} or {distribution}


def test_every_test_dependency_is_used() -> None:
    text = "\n".join(p.read_text() for p in [ROOT / "Makefile", *(ROOT / "tests").glob("*.py")])
    run = {
        name
        for name in _declared("test")
        if any(re.search(rf"\b{re.escape(cmd)}\b", text) for cmd in _commands(name))
    }
    unused = _declared("test") - _imported_distributions("tests") - run
    assert unused == set(), f"in the test extra, used neither by tests/ nor as a command: {unused}"


def test_make_test_lints_first() -> None:
    """`make test` (and so CI) runs `make lint` first: ruff check, ruff format --check, mypy
    and the C kernels' -Werror compiles, with the versions of constraints.txt."""
    makefile = (ROOT / "Makefile").read_text()
    assert re.search(r"^test: venv lint$", makefile, re.M)
    lint = makefile.split("\nlint: venv\n", 1)[1].split("\n\n", 1)[0]
    for command in (
        "ruff check contact tests demos",
        "ruff format --check contact tests demos",
        "mypy",
    ):
        assert f"$(VENV)/bin/{command}" in lint, command
    assert {"ruff", "mypy"} <= _declared("test")
    # and the C kernels, every variant with -Wall -Wextra -Werror (tests/test_kernel_cache.py)
    assert "$(PY) tools/check_kernels.py" in lint
