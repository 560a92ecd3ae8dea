"""Start-up: ``import contact`` loads the FEniCS wheel's MPI and PETSc and none of the heavy
stacks (DOLFINx, UFL, FFCx, the estimators, the output and plotting stacks): each public name
imports its module on first use.  And the forms of an adaptive loop are compiled once: a
later level looks its kernels up in the JIT cache and compiles none.  (Seconds are not
asserted, the machine's load decides them: demos/RESULTS.md has the figures.)"""

from __future__ import annotations

import json
import subprocess
import sys

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
