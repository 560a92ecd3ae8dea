"""Start-up: ``import contact`` loads the FEniCS wheel's MPI and PETSc and none of the heavy
stacks (DOLFINx, UFL, FFCx, the estimators, the output and plotting stacks): each public name
imports its module on first use.  And the forms of an adaptive loop are compiled once: a
later level looks its kernels up in the JIT cache and compiles none.  (Seconds are not
asserted, the machine's load decides them: demos/RESULTS.md has the figures.)"""

from __future__ import annotations

import json
import subprocess
import sys
from types import SimpleNamespace

import contact

from clirun import ROOT

#: what ``import contact`` must leave unloaded (top-level packages, and contact's own layers)
HEAVY = (
    "dolfinx",
    "ufl",
    "basix",
    "ffcx",
    "numpy",
    "matplotlib",
    "pyvista",
    "vtkmodules",
    "h5py",
    "pydantic",
    "yaml",
    "contact.adaptivity",
    "contact.drivers",
    "contact.models",
    "contact.output",
    "contact.post",
    "contact.setup",
    "contact.solvers",
)


def loaded_after(code: str) -> list[str]:
    """The modules of HEAVY (or under them) loaded by a fresh Python running ``code``."""
    script = (
        f"import sys, json\n{code}\nheavy = {HEAVY!r}\n"
        "print(json.dumps(sorted({h for h in heavy for m in sys.modules"
        " if m == h or m.startswith(h + '.')})))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.splitlines()[-1])


def test_import_contact_loads_no_heavy_stack():
    """``import contact`` (and the version the CLI prints) loads nothing of HEAVY; the error
    type users catch loads only ``contact.base``; a public function loads its stack."""
    assert loaded_after("import contact; contact.__version__") == []
    assert loaded_after("from contact import ConfigError") == []
    after_solve = loaded_after("import contact; contact.solve")
    assert {"dolfinx", "ufl", "contact.drivers", "contact.setup"} <= set(after_solve)
    assert "matplotlib" not in after_solve and "pyvista" not in after_solve


def test_public_names_resolve_and_check_their_scene():
    """Every name of ``__all__`` resolves (in ``dir(contact)`` before it is used), and the
    drivers are the checked ones: a non-Scene is refused with one line, before any work."""
    assert set(contact.__all__) <= set(dir(contact))
    for name in contact.__all__:
        assert getattr(contact, name) is getattr(contact, name), name
    for name in ("solve", "estimate", "adapt", "refine", "run_load_path"):
        try:
            getattr(contact, name)("configs/signorini_square.yaml")
        except ValueError as err:
            assert "Scene" in str(err), (name, err)
        else:
            raise AssertionError(f"contact.{name} accepted a path for a Scene")
    try:
        contact.no_such_name  # noqa: B018
    except AttributeError as err:
        assert "no_such_name" in str(err)
    else:
        raise AssertionError("an unknown attribute resolved")


def test_later_levels_compile_no_form(monkeypatch):
    """Three levels of the adaptive loop (estimate and energy error included): every kernel
    a level after the first asks the JIT for is in its cache already (FFCx compiles
    nothing), and each level asks for the same number of kernels."""
    import ffcx.codegeneration.jit as jit

    compiled: list[int] = [0]
    asked: list[int] = [0]
    compile_objects, compile_forms = jit._compile_objects, jit.compile_forms

    def counting_compile(*args, **kwargs):
        compiled[0] += 1
        return compile_objects(*args, **kwargs)

    def counting_forms(*args, **kwargs):
        asked[0] += 1
        return compile_forms(*args, **kwargs)

    monkeypatch.setattr(jit, "_compile_objects", counting_compile)
    monkeypatch.setattr(jit, "compile_forms", counting_forms)
    per_level: list[tuple[int, int]] = []

    def on_level(level):
        per_level.append((compiled[0], asked[0]))
        compiled[0] = asked[0] = 0

    scene = contact.load_scene(
        ROOT / "configs" / "signorini_square.yaml", ["mesh.cells=[8, 8]", "output.verbose=false"]
    )
    run = contact.adapt(scene, strategy="dorfler", max_levels=3, on_level=on_level)
    assert len(run.levels) == 3
    assert [c for c, _ in per_level[1:]] == [0, 0], per_level
    assert per_level[1][1] == per_level[2][1] > 0, per_level


#: a tiny run through the CLI in a fresh process (output folder, then ``--set`` items);
#: ``{before}`` is run first; prints (exit code, matplotlib's backend or None, pyplot
#: loaded) as JSON
TINY_RUN = """
import json, sys
{before}
from contact.app.cli import main
code = main(["run", "configs/signorini_square.yaml", "--set", "mesh.cells=[8,8]",
             "--set", "output.verbose=false", *sys.argv[2:], "-o", sys.argv[1]])
mpl = sys.modules.get("matplotlib")
print(json.dumps([code, mpl and mpl.get_backend().lower(), "matplotlib.pyplot" in sys.modules]))
"""


def tiny_run(tmp_path, name: str, before: str = "", sets: tuple = ()) -> list:
    """The JSON that :data:`TINY_RUN` prints, its output folder ``tmp_path / name``."""
    script = tmp_path / f"{name}.py"
    script.write_text(TINY_RUN.format(before=before))
    proc = subprocess.run(
        [sys.executable, str(script), str(tmp_path / name), *sets],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.splitlines()[-1])


def test_pictures_leave_matplotlib_alone(tmp_path):
    """A tiny run draws its pictures without matplotlib.pyplot: it neither imports it nor
    switches the backend the user chose (here svg); without pictures (output.png=false) it
    imports no part of matplotlib."""
    assert tiny_run(tmp_path, "svg", 'import matplotlib\nmatplotlib.use("svg")') == [
        0,
        "svg",
        False,
    ]
    pngs = sorted(p.name for p in (tmp_path / "svg").glob("*.png"))
    assert pngs == ["pressure.png", "solution.png"], pngs
    for name in pngs:
        assert (tmp_path / "svg" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    assert tiny_run(tmp_path, "bare", sets=("--set", "output.png=false")) == [0, None, False]
    assert not list((tmp_path / "bare").glob("*.png"))


def test_pictures_have_the_pixels_of_the_pyplot_path(tmp_path, monkeypatch):
    """Every 2D picture kind drawn on a Figure of its own has the pixels the old path
    (``figures.PYPLOT``, through matplotlib.pyplot) draws: the solution, the pressure along
    Γ_C, the mesh panels, a convergence and a force curve, and a study's stability chart."""
    from contact.app.cli import main
    from contact.output import charts, figures, plots

    import numpy as np
    from PIL import Image

    scene = contact.load_scene(
        ROOT / "configs" / "signorini_square.yaml", ["mesh.cells=[8, 8]", "output.verbose=false"]
    )
    result = contact.solve(scene, verbose=False)
    rows = [{"dofs": n, "eta": 1.0 / n, "error": 0.8 / n} for n in (81, 289, 1089)]
    study = SimpleNamespace(name="pixels", axes={"method": ["fb", "min"]}, named_cases=False)
    cells = [
        {"method": m, "repeat": 1, "outcome": o, "newton_iterations_total": k}
        for m, o, k in (("fb", "converged", 4), ("min", "max iterations", 100))
    ]
    for old in (True, False):
        monkeypatch.setattr(figures, "PYPLOT", old)
        out = tmp_path / ("old" if old else "new")
        code = main(
            ["run", "configs/signorini_square.yaml", "--set", "mesh.cells=[8,8]"]
            + ["--set", "output.verbose=false", "-o", str(out)]
        )
        assert code == 0
        plots.plot_mesh(out / "mesh.png", result.u_h, title="mesh")
        plots.plot_convergence(out / "convergence.png", rows, title="rates")
        plots.plot_force_displacement(out / "force.png", [0.1, 0.2], [1.0, 1.5], "approach")
        charts.stability(out / "stability.png", study, cells, [])
    names = sorted(p.name for p in (tmp_path / "new").glob("*.png"))
    assert names == sorted(p.name for p in (tmp_path / "old").glob("*.png"))
    assert {"solution.png", "pressure.png", "mesh.png", "stability.png"} <= set(names)
    for name in names:
        new, old = (np.asarray(Image.open(tmp_path / d / name)) for d in ("new", "old"))
        assert new.shape == old.shape and np.array_equal(new, old), name


#: three commands in one fresh process: a tiny run, a bad scene key (exit 2 while loading),
#: the tiny run again; prints per command (exit code, collector on, objects frozen by it)
THREE_COMMANDS = """
import gc, json, sys
import contact.app.cli as cli
cli.FREEZE_LOADED = sys.argv[2] == "new"
tiny = ["run", "configs/signorini_square.yaml", "--set", "mesh.cells=[8,8]", "--set",
        "output.verbose=false", "-o"]
seen = []
before = gc.get_freeze_count()  # (the libraries' own, if any)
for k, extra in enumerate(([], ["--set", "solver.no_such_key=1"], [])):
    code = cli.main(tiny + [f"{sys.argv[1]}/run{k}", *extra])
    seen.append([code, gc.isenabled(), gc.get_freeze_count() - before])
    before = gc.get_freeze_count()
print(json.dumps(seen))
"""


def test_loading_is_frozen_once(tmp_path):
    """The first command of a process runs its loading with the cyclic collector off and
    then freezes what it loaded (objects in the permanent generation, collector on again);
    a later command freezes nothing more (the count does not grow), and a command that
    fails while loading (exit 2) leaves the collector on.  With ``FREEZE_LOADED`` False
    (the old path) nothing is frozen."""
    script = tmp_path / "three.py"
    script.write_text(THREE_COMMANDS)
    seen = {}
    for path in ("new", "old"):
        proc = subprocess.run(
            [sys.executable, str(script), str(tmp_path), path],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 0, proc.stderr
        seen[path] = json.loads(proc.stdout.splitlines()[-1])
    (c0, on0, frozen0), (c1, on1, frozen1), (c2, on2, frozen2) = seen["new"]
    assert (c0, c1, c2) == (0, 2, 0) and on0 and on1 and on2, seen
    # the count is net: objects frozen by the first command that are freed later (its picture
    # process's handle, ended with it) lower it
    assert frozen0 > 10_000 and frozen1 <= 0 and frozen2 <= 0, seen
    assert [row[:2] for row in seen["old"]] == [[0, True], [2, True], [0, True]], seen
    assert [row[2] for row in seen["old"]] == [0, 0, 0], seen
