"""The compiled kernels of the equilibration (contact/adaptivity/equilibration/compiled.py and
kernels/*.c) are C files shipped with the package, checked with -Wall -Wextra -Werror by
``make lint`` (tools/check_kernels.py), and built on first use into a cache that is never
trusted blindly: a library is loaded only when its manifest names this build (sources,
dimensions, flags, compiler, CPU) and its bytes hash to the manifest's SHA-256.  Every
failure — an unwritable cache folder, a file where the folder should be, no compiler, a
truncated or corrupted library, a corrupted manifest — gives exactly one warning line per
run and the right η: that of the NumPy backend (bit for bit where the estimate falls back
to it, to round-off where the library was rebuilt).  Under MPI the ranks agree on the
backend, and concurrent builds into one cache are safe."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import warnings
import zipfile
from pathlib import Path

import contact
from contact.adaptivity.equilibration import compiled
from contact.adaptivity.equilibration.bound import guaranteed_bound
from contact.adaptivity.equilibration.reference import reference
from contact.setup.surfaces import ContactWarning

import pytest
from clirun import contact as cli
from clirun import script_json

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "configs" / "signorini_free_boundary.yaml"
#: the flux kernel of that scene: P1 in 2D (RT_1, dim P_1 = 3)
DIMS = compiled.dimensions(reference(2, 1), 3)
#: the cheapest kernel to compile (the lowest-order flux in 2D), for the concurrent builds
LOWEST = compiled.dimensions(reference(2, 0, 1), 3)
#: what a warning of the NumPy fallback says
FALLS_BACK = "falls back to backend='numpy'"


@pytest.fixture(scope="module")
def solved():
    """The scene solved once, and η of the NumPy backend (the reference)."""
    scene = contact.load_scene(SCENE, ["output.verbose=false"])
    result = contact.solve(scene, verbose=False)
    return scene, result, guaranteed_bound(result.problem, result, backend="numpy").eta


@pytest.fixture(scope="module")
def warm(tmp_path_factory) -> Path:
    """A cache folder holding the scene's flux kernel, built with this process's compiler."""
    folder = tmp_path_factory.mktemp("warm")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CONTACT_CACHE_DIR", str(folder))
        compiled.build(compiled.entry("eqlb", DIMS))
    return folder


def _estimate(scene, result, monkeypatch, levels: int = 2):
    """η of ``levels`` estimates in one fresh run (nothing loaded or warned yet), and the
    warnings they gave."""
    monkeypatch.setattr(compiled, "LOADED", compiled.Loaded())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        etas = [guaranteed_bound(result.problem, result).eta for _ in range(levels)]
    return etas, [w for w in caught]


def _unwritable(tmp_path: Path) -> Path:
    """A folder this process cannot write into: read-only by its mode, or (for root, whom
    modes do not stop) sysfs."""
    folder = tmp_path / "readonly"
    folder.mkdir()
    folder.chmod(0o555)
    for candidate in (folder, Path("/sys")):
        try:
            tempfile.TemporaryDirectory(dir=candidate).cleanup()
        except OSError:
            return candidate
    raise AssertionError("no unwritable folder to test with")


def _manifest(folder: Path) -> tuple[Path, dict]:
    (path,) = folder.glob("eqlb_*.json")
    return path, json.loads(path.read_text())


def _library(folder: Path) -> Path:
    return folder / _manifest(folder)[1]["library"]


def _copy(warm: Path, tmp_path: Path) -> Path:
    folder = tmp_path / "cache"
    shutil.copytree(warm, folder)
    return folder


def _the_line(caught: list) -> str:
    """The one warning caught: a ContactWarning of one line, within the CLI's 300
    characters with its ``contact: warning: `` prefix."""
    assert len(caught) == 1, [str(w.message) for w in caught]
    message = str(caught[0].message)
    assert caught[0].category is ContactWarning
    assert "\n" not in message and len("contact: warning: " + message) <= 300, message
    return message


#: what is wrong, and what the warning names: the cases that fall back to NumPy
FALLBACKS = {
    "unwritable cache folder": "cannot write the cache",
    "a file where the folder should be": "is not a folder",
    "CC names a missing compiler": "no C compiler",
    "no cc on PATH": "no C compiler",
    "truncated library, no compiler": "does not match the SHA-256 of its manifest",
    "corrupted manifest, no compiler": "does not match the SHA-256 of its manifest",
}


@pytest.mark.parametrize("case", FALLBACKS)
def test_a_broken_cache_falls_back_with_one_warning(case, solved, warm, tmp_path, monkeypatch):
    """Where the library cannot be built (or rebuilt): one warning line for two estimates,
    naming the cause, and η equal to the NumPy backend's."""
    scene, result, eta = solved
    cache = tmp_path / "cache"
    if case == "unwritable cache folder":
        cache = _unwritable(tmp_path)
    elif case == "a file where the folder should be":
        cache.write_text("")
    elif case == "CC names a missing compiler":
        monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    elif case == "no cc on PATH":
        monkeypatch.delenv("CC", raising=False)
        (tmp_path / "empty").mkdir()
        monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    else:
        # the warm cache of this compiler, then the compiler gone (the same key: no CC change)
        cache = _copy(warm, tmp_path)
        if case.startswith("truncated"):
            library = _library(cache)
            library.write_bytes(library.read_bytes()[: library.stat().st_size // 2])
        else:
            path, manifest = _manifest(cache)
            path.write_text(json.dumps({**manifest, "sha256": "0" * 64}))
        monkeypatch.setattr(compiled, "compile_in", _missing_compiler)
    monkeypatch.setenv("CONTACT_CACHE_DIR", str(cache))
    etas, caught = _estimate(scene, result, monkeypatch)
    assert etas == [eta, eta]
    message = _the_line(caught)
    assert FALLS_BACK in message and FALLBACKS[case] in message, message


def _missing_compiler(*args, **kwargs):
    raise FileNotFoundError(2, "No such file or directory", "cc")


#: what is wrong, and what the warning names: the cases rebuilt
REBUILT = {
    "truncated library": "does not match the SHA-256 of its manifest",
    "corrupted manifest": "does not match the SHA-256 of its manifest",
    "a manifest of another build": "names another build",
    "a library that does not load": "does not load",
}


@pytest.mark.parametrize("case", REBUILT)
def test_a_corrupted_cache_is_rebuilt_with_one_warning(case, solved, warm, tmp_path, monkeypatch):
    """A cached library that does not verify (or verifies and does not load) is rebuilt
    once: one warning line naming it, η of the compiled kernel (the NumPy backend's to
    round-off), and a cache entry that verifies again."""
    scene, result, eta = solved
    cache = _copy(warm, tmp_path)
    path, manifest = _manifest(cache)
    library = cache / manifest["library"]
    if case == "truncated library":
        library.write_bytes(library.read_bytes()[:4096])
    elif case == "corrupted manifest":
        path.write_text(json.dumps({**manifest, "sha256": "f" * 64}))
    elif case == "a manifest of another build":
        path.write_text(json.dumps({**manifest, "key": "0" * 64}))
    else:  # bytes that hash as the manifest says but are no library
        library.write_bytes(b"not an ELF file")
        path.write_text(json.dumps({**manifest, "sha256": compiled.sha256_hex(b"not an ELF file")}))
    monkeypatch.setenv("CONTACT_CACHE_DIR", str(cache))
    etas, caught = _estimate(scene, result, monkeypatch)
    assert etas[0] == etas[1] and etas[0] == pytest.approx(eta, rel=1e-10)
    message = _the_line(caught)
    assert "was rebuilt" in message and REBUILT[case] in message, message
    assert all(v is not None for v in compiled.LOADED.kernels.values())  # the compiled backend
    assert compiled.verified_library(compiled.entry("eqlb", DIMS))[0] is not None


def test_a_warm_cache_loads_without_a_word(solved, warm, tmp_path, monkeypatch):
    """The usual case: the verified library is loaded (no compile: the compiler is gone, the
    key the same), no warning, η of the NumPy backend to round-off."""
    scene, result, eta = solved
    monkeypatch.setenv("CONTACT_CACHE_DIR", str(_copy(warm, tmp_path)))
    monkeypatch.setattr(compiled, "compile_in", _missing_compiler)
    etas, caught = _estimate(scene, result, monkeypatch)
    assert caught == []
    assert etas[0] == pytest.approx(eta, rel=1e-10)
    assert all(v is not None for v in compiled.LOADED.kernels.values())


CONCURRENT = """
import sys, warnings
warnings.simplefilter("error")
import contact
from mpi4py import MPI
from contact.adaptivity.equilibration import compiled
from contact.adaptivity.equilibration.reference import reference
kernel = compiled.library(MPI.COMM_SELF, reference(2, 0, 1), 3)
assert kernel is not None and kernel[1].eq_work_size() > 0
print("ok")
"""


def test_concurrent_builds_into_one_cache(tmp_path):
    """Three processes building the same kernel into one empty cache at once: each loads a
    complete library, none warns, and the cache holds one entry that verifies."""
    cache = tmp_path / "cache"
    env = {**os.environ, "CONTACT_CACHE_DIR": str(cache)}
    procs = [
        subprocess.Popen([sys.executable, "-c", CONCURRENT], env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
        for _ in range(3)
    ]  # fmt: skip
    outs = [p.communicate(timeout=900) for p in procs]
    assert [p.returncode for p in procs] == [0, 0, 0], [e for _, e in outs]
    assert [o.strip() for o, _ in outs] == ["ok"] * 3
    assert len(list(cache.glob("*.json"))) == 1
    assert not list(cache.glob(".build-*"))  # no temporary folder left behind
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CONTACT_CACHE_DIR", str(cache))
        assert compiled.verified_library(compiled.entry("eqlb", LOWEST))[0] is not None


AGREE = """
import json, os, sys, warnings
from mpi4py import MPI
import contact
from contact.adaptivity.equilibration import compiled
from contact.adaptivity.equilibration.bound import guaranteed_bound
comm = MPI.COMM_WORLD
# rank 0 sees the warm cache; rank 1 a node-local one where a file stands for the folder
os.environ["CONTACT_CACHE_DIR"] = sys.argv[2] if comm.rank == 0 else sys.argv[3]
scene = contact.load_scene(sys.argv[1], ["output.verbose=false"])
result = contact.solve(scene, verbose=False)
reference = guaranteed_bound(result.problem, result, backend="numpy").eta
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    etas = [guaranteed_bound(result.problem, result).eta for _ in range(2)]
backends = comm.allgather([v is not None for v in compiled.LOADED.kernels.values()])
lines = comm.allgather([str(w.message) for w in caught])
if comm.rank == 0:
    print(json.dumps({"etas": etas, "reference": reference, "backends": backends,
                      "lines": lines}))
"""


@pytest.mark.mpi
def test_ranks_agree_on_the_backend(warm, tmp_path):
    """Two ranks, one of which cannot build (a node-local cache that is a file): both use
    NumPy (no rank left on the compiled kernel, no hang), one warning line in all, and η
    equal to the NumPy backend's."""
    (tmp_path / "file").write_text("")
    out = script_json(AGREE, tmp_path, str(SCENE), str(warm), str(tmp_path / "file"), ranks=2)
    assert out["backends"] == [[False], [False]]
    assert out["etas"] == [out["reference"]] * 2
    lines = [line for rank in out["lines"] for line in rank]
    assert len(lines) == 1 and FALLS_BACK in lines[0] and "is not a folder" in lines[0]


@pytest.mark.mpi
def test_cli_on_two_ranks_with_a_file_for_the_cache(solved, tmp_path):
    """As users run it: ``mpirun -n 2 contact run`` where a file stands for the cache
    folder, two adaptive levels: exit 0, stderr exactly one line (the warning), and η of
    the first level that of the NumPy backend (serially here, so to the solver's
    tolerance).  (A missing compiler is tested in-process above: DOLFINx's JIT needs the
    same compiler for forms not in its cache yet.)"""
    _, _, eta = solved
    (tmp_path / "file").write_text("")
    env = {"CONTACT_CACHE_DIR": str(tmp_path / "file"), "PYTHONWARNINGS": "default"}
    out = tmp_path / "out"
    sets = ["--set", "adapt.max_levels=2", "--set", "output.png=false", "-q"]
    proc = cli(ROOT, "run", str(SCENE), "-o", str(out), *sets, ranks=2, env=env)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("contact: warning: the compiled flux kernel is unavailable")
    assert "is not a folder" in lines[0] and FALLS_BACK in lines[0]
    assert len(lines[0]) <= 300
    with open(out / "convergence.csv") as f:
        header, first = f.readline().strip().split(","), f.readline().strip().split(",")
    assert float(first[header.index("eta")]) == pytest.approx(eta, rel=1e-8)


def test_the_check_fails_on_a_warning(tmp_path):
    """The lint step fails on a warning: a planted unused variable in a copy of the sources
    makes tools/check_kernels.py exit 1 naming it."""
    sources = tmp_path / "kernels"
    shutil.copytree(compiled.SOURCES, sources)
    with open(sources / "stress.c", "a") as f:
        f.write("\nint st_planted(void) { int unused = 0; return 0; }\n")
    proc = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "check_kernels.py"), "--sources", str(sources),
         "--kernel", "stress"],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "unused variable" in proc.stderr and "FAIL stress" in proc.stdout


def test_an_install_ships_the_sources(tmp_path):
    """A wheel built from the tree holds every C file and header of the kernels (package
    data), so an installed copy can build them."""
    tree = tmp_path / "tree"
    tree.mkdir()
    shutil.copytree(
        ROOT / "contact", tree / "contact", ignore=shutil.ignore_patterns("__pycache__")
    )
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, tree)
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
         "-w", str(tmp_path / "dist"), str(tree)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    (wheel,) = (tmp_path / "dist").glob("contact-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    want = {
        f"contact/adaptivity/equilibration/kernels/{p.name}"
        for p in compiled.SOURCES.iterdir()
        if p.suffix in (".c", ".h")
    }
    assert len(want) >= 5 and want <= names, want - names
