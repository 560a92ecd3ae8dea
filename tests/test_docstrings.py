"""The docstrings of contact.__all__ are the API reference (docs/api.md): each public
function documents its parameters (Args:), what it returns (Returns:) and its examples run
(doctest, from the repository's root, serially)."""

import doctest
import inspect
import os
from pathlib import Path

import contact

import pytest

ROOT = Path(__file__).resolve().parents[1]
PUBLIC = {name: getattr(contact, name) for name in contact.__all__}


def _documented(obj) -> list[tuple[str, object]]:
    """The object and, for a class, its public methods defined in the package."""
    out = [(obj.__name__, obj)]
    if inspect.isclass(obj):
        for name, member in vars(obj).items():
            func = member.fget if isinstance(member, property) else member
            func = getattr(func, "__func__", func)
            if not name.startswith("_") and inspect.isfunction(func):
                out.append((f"{obj.__name__}.{name}", func))
    return out


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_public_names_document_their_parameters(name):
    for qualname, obj in _documented(PUBLIC[name]):
        doc = inspect.getdoc(obj) or ""
        assert doc and doc.splitlines()[0].endswith((".", ")")), f"{qualname}: no summary line"
        if inspect.isclass(obj):
            assert "Attributes:" in doc or "Args:" in doc or issubclass(obj, Exception), qualname
            continue
        signature = inspect.signature(inspect.unwrap(obj))
        params = [p for p in signature.parameters if p not in ("self", "cls")]
        if params and qualname in {n for n in PUBLIC} | {"ComplementarityProblem.solve"}:
            assert "Args:" in doc, f"{qualname}: no Args: section"
            for p in params:
                assert f"{p}:" in doc, f"{qualname}: parameter {p} not documented"
        returns = signature.return_annotation
        if returns not in (None, "None", inspect.Signature.empty) and "Args:" in doc:
            assert "Returns:" in doc, f"{qualname}: no Returns: section"


def test_public_docstrings_have_examples():
    examples = [n for n, obj in PUBLIC.items() if ">>>" in (inspect.getdoc(obj) or "")]
    assert {
        "Scene",
        "load_scene",
        "solve",
        "estimate",
        "mark",
        "refine",
        "adapt",
        "run_load_path",
        "ComplementarityProblem",
        "Unilateral",
    } <= set(examples)


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_docstring_examples_run(name, monkeypatch):
    monkeypatch.chdir(ROOT)
    monkeypatch.setenv("OMP_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", "1"))
    finder = doctest.DocTestFinder(recurse=False)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    tried = 0
    for qualname, obj in _documented(PUBLIC[name]):
        for test in finder.find(obj, qualname, globs={}):
            result = runner.run(test)
            assert result.failed == 0, f"{qualname}: {result.failed} example(s) failed"
            tried += result.attempted
    assert tried or name in {"ConfigError", "Estimate", "Result", "AdaptResult", "LoadPath"}
