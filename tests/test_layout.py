"""The package's layout (docs/development.md, "Layout"): the import-linter contracts of
pyproject.toml hold — the layers app > output > post > hp > setup > drivers > adaptivity > models
> solvers > base (a package imports only the packages below it), no two modules or packages
importing each other, a core (drivers, adaptivity, models, solvers, base) that never imports
a scene, a report or the application, writers (output) that import no scene, hp loop or
application module (they take results and a Report), figures (post) that import none of
them either (they take a Posed record and a result), solvers that never import a model or a
driver, a scalar model that never imports elasticity. Function-level ("lazy") imports count;
imports used only for annotations (``if TYPE_CHECKING:``) do not. That a scalar *run* loads
no elasticity module is test_elasticity.py::test_a_run_imports_only_its_own_model."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT = Path(sys.executable).with_name("lint-imports")


def lint(root: Path) -> subprocess.CompletedProcess:
    """``lint-imports`` on the package ``contact`` under ``root`` with the contracts of
    ``root/pyproject.toml`` (that copy of the package, not the installed one)."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    return subprocess.run(
        [str(LINT), "--no-cache", "--no-logo", str(root / "pyproject.toml")],
        cwd=root,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_the_contracts_hold():
    proc = lint(ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "0 broken" in proc.stdout


def _copy(tmp_path: Path) -> Path:
    shutil.copytree(
        ROOT / "contact", tmp_path / "contact", ignore=shutil.ignore_patterns("__pycache__")
    )
    shutil.copy(ROOT / "pyproject.toml", tmp_path)
    return tmp_path


LAYERS, ACYCLIC = "app > output > post", "no two modules"
SOLVERS, SCALAR = "the solvers take a problem", "a scalar model imports no elasticity"
CORE = "the core takes problems and meshes, never a scene"
OUTPUT = "the writers take results and a report"
POST = "the figures take a posed record and a result"

# (module, code appended to it, the contracts it breaks: an import up the layers closes a
# loop too, since the lower package already imports the higher one's dependencies)
PLANTED = {
    # the figures use the solvers and models, and the writers the figures, so a scene read
    # there reaches post and output too (their contracts count indirect imports)
    "a solver reads a scene (lazy import)": (
        "solvers/ncp.py",
        "def _planted():\n    from ..setup.scene import Scene\n    return Scene\n",
        [LAYERS, ACYCLIC, CORE, POST, OUTPUT],
    ),
    "a solver calls a driver": (
        "solvers/result.py",
        "from ..drivers import sequencing\n",
        [LAYERS, ACYCLIC, SOLVERS],
    ),
    "the estimator imports an output helper": (
        "adaptivity/estimate.py",
        "from ..output.plots import draw_in_turn\n",
        [LAYERS, ACYCLIC, CORE],
    ),
    "a model reads a scene's configuration": (
        "models/physics.py",
        "def _planted():\n    from ..setup.scene_config import SceneConfig\n"
        "    return SceneConfig\n",
        [LAYERS, ACYCLIC, CORE, POST, OUTPUT],
    ),
    "a writer reads a scene (lazy import)": (
        "output/fields.py",
        "def _planted():\n    from ..setup.scene import Scene\n    return Scene\n",
        [OUTPUT],
    ),
    "a writer asks the application": (
        "output/folder.py",
        "def _planted():\n    from ..app.dispatch import report_of\n    return report_of\n",
        [LAYERS, ACYCLIC, OUTPUT],
    ),
    "a figure reads a scene (lazy import)": (
        "post/hertz.py",
        "def _planted():\n    from ..setup.scene import Scene\n    return Scene\n",
        [POST, OUTPUT],
    ),
    # the package's __init__ reaches every layer: a writer takes the version from base
    "a writer reads the version from the package": (
        "output/folder.py",
        "def _planted():\n    from .. import __version__\n    return __version__\n",
        [OUTPUT],
    ),
    "two models import each other": (
        "models/basis.py",
        "def _planted():\n    from . import mortar\n    return mortar\n",
        [ACYCLIC],
    ),
    "a scalar model imports elasticity through another module": (
        "models/problem.py",
        "def _planted():\n    from .elasticity import von_mises\n    return von_mises\n",
        [SCALAR],
    ),
}


@pytest.mark.parametrize("case", PLANTED)
def test_a_planted_import_breaks_its_contract(tmp_path, case):
    module, code, broken = PLANTED[case]
    root = _copy(tmp_path)
    with open(root / "contact" / module, "a") as f:
        f.write("\n\n" + code)
    proc = lint(root)
    assert proc.returncode != 0, proc.stdout
    report = proc.stdout.split("Broken contracts", 1)[1]
    assert all(name in report for name in broken), proc.stdout
    assert proc.stdout.count(" BROKEN") == len(broken), proc.stdout


def test_an_annotation_only_import_breaks_nothing(tmp_path):
    """``if TYPE_CHECKING:`` imports are left out (charts.py annotates with study's Study)."""
    root = _copy(tmp_path)
    with open(root / "contact" / "solvers" / "ncp.py", "a") as f:
        f.write(
            "\n\nfrom typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n    from "
            "..setup.scene import Scene\n"
        )
    proc = lint(root)
    assert proc.returncode == 0, proc.stdout
