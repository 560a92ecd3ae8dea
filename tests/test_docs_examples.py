"""Every example in README.md and docs/**/*.md runs as printed (docs/README.md, "Examples
are tested"): each ```python block as a script in a fresh folder, each ```yaml block by its
first line —

* a whole scene (no marker): run through ``contact run`` with its default outputs; a scene
  that declares ``data.exact`` must show the error falling (its adaptive levels, or three
  uniform refinements of a scene without ``adapt``);
* ``# fragment of configs/NAME.yaml``: merged into that scene and loaded (validated, mesh
  built, boundary parts tagged);
* ``# study file in configs/studies/``: validated as a study file in that folder;

and a python block whose first line is ``# after: contact run ARGS`` runs after that
command. The folder has links ``configs`` and ``demos`` to the repository's, so the paths
read as they do from a clone's root."""

import csv
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
SKIP_DIRS = ("_build", "reference", "generated")
BLOCK = re.compile(r"^```(python|yaml)[^\n]*\n(.*?)^```", re.M | re.S)
FRAGMENT = re.compile(r"# fragment of (configs/\S+\.yaml)")
STUDY = "# study file in configs/studies/"
AFTER = re.compile(r"# after: contact run (.+)")


def markdown_files() -> list[Path]:
    docs = [
        p
        for p in sorted((ROOT / "docs").rglob("*.md"))
        if not set(SKIP_DIRS) & set(p.relative_to(ROOT / "docs").parts)
    ]
    return [ROOT / "README.md", *docs]


def examples() -> list[tuple[str, str, str]]:
    """(id, language, code) of every python and yaml block, id = file:line."""
    found = []
    for path in markdown_files():
        text = path.read_text()
        for m in BLOCK.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            found.append((f"{path.relative_to(ROOT)}:{line}", m.group(1), m.group(2)))
    return found


EXAMPLES = examples()


def _env() -> dict[str, str]:
    return {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}


def _folder(tmp_path: Path) -> Path:
    for name in ("configs", "demos"):
        (tmp_path / name).symlink_to(ROOT / name)
    return tmp_path


def _python(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, *args], cwd=cwd, capture_output=True, text=True, timeout=600, env=_env()
    )


def _contact(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    proc = _python(["-m", "contact.app.cli", *args], cwd)
    assert proc.returncode == 0, f"contact {' '.join(args)}: {proc.stderr}"
    return proc


def _merge(base: dict, fragment: dict) -> dict:
    merged = dict(base)
    for key, value in fragment.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = _merge(merged[key], value)
        else:
            merged[key] = value
    return merged


def _errors(folder: Path) -> list[float]:
    with open(folder / "convergence.csv") as f:
        return [float(row["error"]) for row in csv.DictReader(f)]


def test_the_docs_have_examples_of_each_kind():
    """The collection finds the blocks (a changed fence or marker would silently test
    nothing): python scripts, whole scenes, fragments and a study."""
    kinds = {"python": 0, "scene": 0, "fragment": 0, "study": 0}
    for _, lang, code in EXAMPLES:
        first = code.splitlines()[0]
        kind = (
            "python"
            if lang == "python"
            else "fragment"
            if FRAGMENT.match(first)
            else "study"
            if first.startswith(STUDY)
            else "scene"
        )
        kinds[kind] += 1
    assert kinds["python"] >= 8 and kinds["scene"] >= 2 and kinds["fragment"] >= 4
    assert kinds["study"] >= 1


@pytest.mark.parametrize(("where", "code"), [(w, c) for w, lang, c in EXAMPLES if lang == "python"])
def test_python_example_runs(where, code, tmp_path):
    cwd = _folder(tmp_path)
    first = code.splitlines()[0]
    if m := AFTER.match(first):
        _contact(["run", *m.group(1).split(), "-q"], cwd)
    (cwd / "example.py").write_text(code)
    proc = _python(["example.py"], cwd)
    assert proc.returncode == 0, f"{where}: {proc.stderr}"


@pytest.mark.parametrize(("where", "code"), [(w, c) for w, lang, c in EXAMPLES if lang == "yaml"])
def test_yaml_example_is_valid_and_runs(where, code, tmp_path):
    import contact
    from contact.app.study import load_study

    first = code.splitlines()[0]
    data = yaml.safe_load(code)
    if m := FRAGMENT.match(first):
        base = yaml.safe_load((ROOT / m.group(1)).read_text())
        scene = contact.load_scene(_merge(base, data))
        for key, value in data.items():  # the fragment's keys are what the scene has
            assert getattr(scene.config, key) is not None or value is None, key
        return
    if first.startswith(STUDY):
        cwd = os.getcwd()
        os.chdir(ROOT / "configs" / "studies")
        try:
            study = load_study(data)
        finally:
            os.chdir(cwd)
        assert study.runs()
        return
    # a whole scene, through the CLI with its default outputs (pictures included)
    folder = _folder(tmp_path)
    (folder / "scene.yaml").write_text(code)
    _contact(["run", "scene.yaml", "-o", "out"], folder)
    out = folder / "out"
    assert (out / "summary.json").is_file() and any(out.glob("*.png"))
    if (data.get("data") or {}).get("exact") is None:
        return
    if data.get("adapt") is None:
        sets = ["--set", "adapt.strategy=uniform", "--set", "adapt.max_levels=3"]
        _contact(["run", "scene.yaml", "-o", "uniform", "-q", *sets], folder)
        out = folder / "uniform"
    errors = _errors(out)
    # the error falls on every level; under uniform refinement at least at the rate
    # h^(1/2) (P1 on problem A converges like h^1 = N^(-1/2): factor 0.5 per level)
    assert len(errors) >= 3 and all(b < a for a, b in zip(errors, errors[1:])), errors
    if data.get("adapt") is None:
        assert all(b < 0.71 * a for a, b in zip(errors, errors[1:])), errors
