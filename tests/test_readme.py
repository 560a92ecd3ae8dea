"""README.md and the docs' pages as a user reads them: the Python example runs as written
(and prints global values under mpirun), the output tables of docs/guide/outputs.md and
adaptivity.md list what runs write, the pyvista and meshio snippets load results, the
dolfinx import note of docs/getting-started.md is true, and docs/development.md lists the
locked versions. (tests/test_docs_examples.py runs every example block serially.)"""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def test_readme_python_example_runs():
    text = (ROOT / "README.md").read_text()
    section = text.split("## At a glance", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    assert 5 <= len(code.strip().splitlines()) <= 12
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    assert any(line.startswith("True ") for line in proc.stdout.splitlines())
    assert "min (primal-dual active set):" in proc.stdout


def test_readme_study_example_validates(monkeypatch):
    """The study YAML of docs/guide/studies.md is a valid study (paths
    relative to configs/studies/, as a study file there would be)."""
    from contact.app.study import load_study

    import yaml

    section = (DOCS / "guide" / "studies.md").read_text()
    block = re.search(r"```yaml\n(.*?)```", section, re.S).group(1)
    monkeypatch.chdir(ROOT / "configs" / "studies")
    study = load_study(yaml.safe_load(block))
    assert study.axes["method"] == ["fb", "min", "vinewtonrsls"] and set(study.cases) == {
        "cold far",
        "obtuse",
    }
    assert len(study.runs()) == 2 * 3 * 3 and study.charts == ["speed_accuracy", "stability"]


def test_readme_python_example_prints_global_values_under_mpirun(tmp_path):
    """Under mpirun -n 2 each rank prints exactly the serial output (global values)."""
    text = (ROOT / "README.md").read_text()
    code = re.search(r"```python\n(.*?)```", text.split("## At a glance", 1)[1], re.S).group(1)
    # each rank's stdout to its own file (mpirun may interleave the two streams mid-line)
    to_file = (
        f"import os, sys; sys.stdout = open(r'{tmp_path}/out' + os.environ.get('PMI_RANK', 's'), "
        f"'w')\n"
    )
    mpirun = Path(sys.executable).parent / "mpirun"
    serial = subprocess.run(
        [sys.executable, "-c", to_file + code],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    par = subprocess.run(
        [str(mpirun), "-n", "2", sys.executable, "-c", to_file + code],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert serial.returncode == 0 and par.returncode == 0, par.stderr

    def printed(name: str) -> list[str]:  # without the Newton progress lines
        return [ln for ln in (tmp_path / name).read_text().splitlines() if not ln.startswith("  ")]

    assert printed("out0") == printed("out1") == printed("outs")
    assert any(ln.startswith("contact force ") for ln in printed("outs"))


def _table_files(section: str) -> set[str]:
    """The file names in the first column of the first table of a section of the docs."""
    table = re.search(r"\| file \| contents \|\n\|---\|---\|\n((?:\|.*\n)+)", section).group(1)
    names = set()
    for row in table.splitlines():
        names |= set(re.findall(r"`([\w.-]+)`", row.split("|")[1]))
    return names


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """results/square (one solve) and results/demo (an adaptive run) in a scratch folder."""
    cwd = tmp_path_factory.mktemp("readme")
    for scene, out, sets in (
        ("signorini_square.yaml", "square", ["mesh.cells=[12,10]"]),
        ("signorini_free_boundary.yaml", "demo", ["adapt.max_levels=2"]),
    ):
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "contact.app.cli",
                "run",
                str(ROOT / "configs" / scene),
                "-o",
                str(cwd / "results" / out),
                "-q",
                *(f"--set={s}" for s in sets),
            ],
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 0, proc.stderr
    return cwd


def test_readme_output_tables_match_what_runs_write(results):
    text = (DOCS / "guide" / "outputs.md").read_text()
    single = _table_files(text.split("## Running a scene", 1)[1])
    assert single == {p.name for p in (results / "results" / "square").iterdir()}
    adaptive = _table_files((DOCS / "guide" / "adaptivity.md").read_text())
    written = {p.name for p in (results / "results" / "demo").iterdir()}
    pattern = r"((solution|contact_surface)_\d{3}\.(vtu|xdmf|h5)|mesh_level_\d+\.png)"
    numbered = {n for n in written if re.fullmatch(pattern, n)}
    levels = {f"solution_00{k}.{ext}" for k in (0, 1) for ext in ("vtu", "xdmf", "h5")}
    levels |= {f"contact_surface_00{k}.{ext}" for k in (0, 1) for ext in ("xdmf", "h5")}
    assert levels <= adaptive & numbered
    assert adaptive - levels - {"mesh_level_K.png"} == written - numbered


def test_readme_pyvista_snippets_load_results(results):
    outputs = (DOCS / "guide" / "outputs.md").read_text().split("## Running a scene", 1)[1]
    for text in (outputs, (DOCS / "guide" / "adaptivity.md").read_text()):
        code = re.search(r"```python\n(# after.*?)```", text, re.S).group(1)
        # the first line names the run it reads (tests/test_docs_examples.py runs it first)
        assert code.startswith("# after: contact run ")
        assert len(code.strip().splitlines()) == 4
        proc = subprocess.run(
            [sys.executable, "-c", code + "\nprint('loaded', grid.n_points)"],
            cwd=results,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert proc.returncode == 0 and "loaded" in proc.stdout, proc.stderr


def test_readme_meshio_snippet_loads_the_xdmf(results):
    """The second Python block of "Running a scene" reads solution.xdmf with meshio."""
    text = (DOCS / "guide" / "outputs.md").read_text()
    code = re.findall(r"```python\n(.*?)```", text.split("## Running a scene", 1)[1], re.S)[1]
    assert 'meshio.read("results/square/solution.xdmf")' in code
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=results, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    points, shape, _ = proc.stdout.split(" ", 2)
    assert int(points) == 13 * 11 and shape == "(143,"


def test_readme_says_how_to_import_dolfinx():
    """With the PyPI wheel a bare `import dolfinx` fails and `import dolfinx_solver` first
    works, as Getting started says."""
    text = (DOCS / "getting-started.md").read_text()
    assert "`import dolfinx_solver`" in text and "libmpi.so.12" in text
    bare = subprocess.run(
        [sys.executable, "-c", "import dolfinx"], capture_output=True, text=True, timeout=120
    )
    first = subprocess.run(
        [sys.executable, "-c", "import dolfinx_solver, dolfinx; print(dolfinx.__version__)"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert bare.returncode != 0 and "libmpi.so.12" in bare.stderr
    assert first.returncode == 0 and first.stdout.startswith("0.11")


def _locked() -> dict[str, str]:
    """constraints.txt as {normalized name: version}."""
    lines = (ROOT / "constraints.txt").read_text().splitlines()
    pins = [ln.split("==") for ln in lines if ln and not ln.startswith("#")]
    assert all(len(p) == 2 for p in pins), "every line of constraints.txt pins one exact version"
    return {re.sub(r"[-_.]+", "-", name).lower(): version for name, version in pins}


def test_lock_pins_every_dependency() -> None:
    """constraints.txt (what `make venv` installs) pins every dependency of pyproject.toml,
    the test and docs extras included, and pip."""
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]
    wanted = project["dependencies"] + extras["test"] + extras["docs"] + ["pip"]
    names = {
        re.sub(r"[-_.]+", "-", re.split(r"[<>=!~\[; ]", req, maxsplit=1)[0]).lower()
        for req in wanted
    }
    assert names - set(_locked()) == set()
    makefile = (ROOT / "Makefile").read_text()
    assert "$(VENV)/.installed: pyproject.toml $(LOCK)" in makefile
    assert "-c $(LOCK) -e '.[test,docs]'" in makefile


def test_readme_lists_the_locked_versions() -> None:
    """docs/development.md's table of tested versions says what constraints.txt pins (and the lock's
    header the interpreter and PETSc it was recorded with)."""
    section = (
        (DOCS / "development.md").read_text().split("## Environment: the tested versions", 1)[1]
    )
    table = dict(re.findall(r"^\| ([^|]+?) \| (.+?) \|$", section.split("\n\n## ", 1)[0], re.M))
    locked = _locked()
    rows = {
        "DOLFINx": ["dolfinx-solver-real", "fenics-basix", "fenics-ffcx", "fenics-ufl"],
        "MPICH": ["mpich", "mpi4py"],
        "numpy": ["numpy"],
        "gmsh": ["gmsh"],
        "pyvista": ["pyvista", "vtk"],
        "matplotlib": ["matplotlib"],
        "h5py / meshio": ["h5py", "meshio"],
    }
    for row, packages in rows.items():
        for name in packages:
            assert locked[name] in table[row], (
                f"{row}: README {table[row]!r}, lock {name}=={locked[name]}"
            )
    header = (ROOT / "constraints.txt").read_text()
    python, petsc = re.search(r"CPython (\S+) .*PETSc (\S+) ", header).groups()
    assert f"CPython {python}" in table["Python"] and table["PETSc / petsc4py"].startswith(petsc)


def test_readme_scene_example_converges_to_its_exact_solution(tmp_path):
    """The YAML of docs/guide/scenes.md's "Every key", run as printed (its adaptive levels, default
    outputs, pictures included): every exterior facet is in a part, no warning, the error
    against its declared exact solution falls on every level at the optimal rate of P1,
    ‖u − u_h‖_E ~ N^(−1/2) (fitted slope ≤ −0.45; −0.53 measured), and the guaranteed η
    bounds it on every level."""
    import csv
    import json

    from clirun import contact

    section = (DOCS / "guide" / "scenes.md").read_text().split("## Every key", 1)[1]
    block = re.search(r"```yaml\n(.*?)```", section, re.S).group(1)
    (tmp_path / "scene.yaml").write_text(block)
    proc = contact(tmp_path, "run", "scene.yaml", env={"PYTHONWARNINGS": "default"})
    assert proc.returncode == 0, proc.stderr
    assert not proc.stderr.strip(), proc.stderr
    assert "contact: boundary: every exterior facet is in a boundary part" in proc.stdout
    out = tmp_path / "results" / "my_scene"
    info = json.loads((out / "summary.json").read_text())
    assert info["untagged_boundary"]["facets"] == 0 and info["exact_mismatch"] == []
    rows = list(csv.DictReader((out / "convergence.csv").open()))
    assert len(rows) == info["levels"] == 6
    dofs, eta, error = (np.array([float(r[k]) for r in rows]) for k in ("dofs", "eta", "error"))
    assert np.all(np.diff(error) < 0) and np.all(eta >= error), (eta, error)
    slope = np.polyfit(np.log(dofs), np.log(error), 1)[0]
    assert -0.7 < slope <= -0.45, slope
    from matplotlib.image import imread

    for name in ("solution.png", "convergence.png", "pressure.png", "mesh_level_5.png"):
        assert imread(out / name).ndim == 3
