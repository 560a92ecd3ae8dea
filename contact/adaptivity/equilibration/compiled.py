"""The compiled kernels of the equilibration: C sources shipped with the package, built on
first use for one reference element at a time, kept in a verified on-disk cache, and loaded
through cffi.

The sources are ``kernels/eqlb.c`` (the flux's patch solver, called by :mod:`.patches_c`) and
``kernels/stress.c`` (the stress's cell operators and patch systems, :mod:`.stress_c`), with
the headers they include (``eqlb.h``, ``stress.h``: the interfaces cffi reads; ``lu.h``).
The dimensions of the reference element are ``-D`` flags (:func:`dimensions`,
:func:`stress_dimensions`), so the compiler unrolls the small loops.

**Build.** ``$CC`` (else ``cc``: the compiler DOLFINx's JIT already needs) with ``-O3
-march=native`` (the lane loops of the cell kernels vectorize), ``-O2`` where the compiler
refuses ``-march=native``.  Warnings are errors in the lint step (``tools/check_kernels.py``
compiles every variant with :data:`WERROR`), not on a user's machine, where a newer
compiler's new warning would cost the compiled backend.

**Cache.** ``$CONTACT_CACHE_DIR`` (default ``$XDG_CACHE_HOME/contact``, else
``~/.cache/contact``).  A build is known by its key: the SHA-256 of the sources, the
dimensions, the flags, the compiler command and its ``--version`` line, and the CPU's model
and feature flags (a cache shared by machines never hands one another's ``-march=native``
instructions).  The library is written to a temporary file in the cache folder, flushed to
disk and renamed under a name carrying its own SHA-256; then the manifest
``<name>_<dims>_<key>.json`` (the key, the library's file name and SHA-256) is written the
same way.  Before a library is opened, the manifest's key is compared with the key of this
build and the library's bytes are hashed: a truncated or corrupted library, a corrupted
manifest or a missing file is rebuilt once (one warning line).  When the build or the
load fails — no compiler, a cache folder that cannot be written, a rebuilt library that
still does not load — :func:`load` returns None and the caller uses the NumPy backend (the
reference: the same σ_h to round-off), after one warning line per process.  Concurrent
builds (processes, ranks) write their own temporary files and rename whole files, so a
reader sees a complete library or none.

**MPI.** :func:`load` is collective: rank 0 builds while the others wait, then every rank
verifies and opens the library (a rank that does not see rank 0's file, a node-local
cache, builds its own); the ranks agree, so either every rank has the library or every
rank falls back to NumPy, and rank 0 gives the one warning.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import platform
import re
import shlex
import subprocess
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mpi4py import MPI

from .reference import Reference

#: the folder of the C sources (package data)
SOURCES = Path(__file__).with_name("kernels")
#: the kernels by name: the C file (its interface: the header of the same stem)
KERNELS = {"eqlb": "eqlb.c", "stress": "stress.c"}
#: what each kernel computes (in the warning lines)
PURPOSE = {"eqlb": "flux", "stress": "stress"}
#: the optimization flags, in order of preference
FLAGS = (("-O3", "-march=native"), ("-O2",))
#: the flags of every build: C99, a shared library
COMMON = ("-std=c99", "-fPIC", "-shared")
#: the warnings that fail the lint step
WERROR = ("-Wall", "-Wextra", "-Werror")
#: the longest a compile may take, seconds (a hung compiler is a failed build)
TIMEOUT = 600
#: the longest reason in a warning line, characters (the line stays within 300)
REASON = 170


def dimensions(ref: Reference, nu: int) -> dict[str, int]:
    """The compile-time constants of ``kernels/eqlb.c`` for ``ref`` and dim P_p = ``nu``."""
    d = ref.d
    return {
        "DIM": d,
        "NV": d + 1,
        "NQ": len(ref.w),
        "NQF": len(ref.wS),
        "NU": nu,
        "M": ref.m,
        "NP": ref.np_,
        "MZ": ref.Z.shape[1],
        "NF": ref.nf,
        "NPERM": len(ref.perms),
        "NLOOK": d**d,
        "LOWEST": int(ref.lowest),
    }


def stress_dimensions(ref: Reference) -> dict[str, int]:
    """The compile-time constants of ``kernels/stress.c`` for the rows' reference element."""
    d = ref.d
    return {
        "DIM": d,
        "NV": d + 1,
        "NF": ref.nf,
        "BF": d * ref.nf,
        "MZ": ref.Z.shape[1],
        "NP": ref.np_,
        "NAS": d * (d - 1) // 2,
    }


def cache_dir() -> Path:
    """The cache folder: ``$CONTACT_CACHE_DIR``, else ``$XDG_CACHE_HOME/contact``, else
    ``~/.cache/contact``."""
    base = (
        os.environ.get("CONTACT_CACHE_DIR")
        or Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "contact"
    )
    return Path(base)


def compiler() -> tuple[str, ...]:
    """The C compiler command: ``$CC`` split as a shell would, else ``cc``."""
    return tuple(shlex.split(os.environ.get("CC") or "cc"))


def sources(name: str) -> dict[str, bytes]:
    """The files kernel ``name`` is built from: its C file and the local headers it
    includes (``#include "..."``, recursively), by file name."""
    out: dict[str, bytes] = {}
    todo = [KERNELS[name]]
    while todo:
        file = todo.pop()
        if file not in out:
            out[file] = (SOURCES / file).read_bytes()
            todo += [
                m.decode() for m in re.findall(rb'^\s*#\s*include\s+"([^"]+)"', out[file], re.M)
            ]
    return dict(sorted(out.items()))


def cdef(name: str) -> str:
    """The declarations of kernel ``name`` for cffi: its header without comments and
    preprocessor lines (the include guard, the includes)."""
    text = (SOURCES / KERNELS[name]).with_suffix(".h").read_text()
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    return "".join(line for line in text.splitlines(True) if not line.lstrip().startswith("#"))


def command(
    cc: tuple[str, ...], name: str, dims: dict[str, int], flags: tuple[str, ...]
) -> list[str]:
    """The compile command of kernel ``name`` into ``lib.so``, run in a folder holding
    :func:`sources` (relative names: the library does not depend on the folder)."""
    defines = [f"-D{k}={v}" for k, v in dims.items()]
    return [*cc, *flags, *COMMON, *defines, KERNELS[name], "-o", "lib.so", "-lm"]


def compile_in(
    folder: Path, name: str, dims: dict[str, int], flags: tuple[str, ...], cc: tuple[str, ...]
) -> subprocess.CompletedProcess:
    """Write the sources of kernel ``name`` into ``folder`` and compile them there into
    ``folder/lib.so`` (:func:`command`); OSError where the compiler cannot be started,
    subprocess.TimeoutExpired after :data:`TIMEOUT` seconds."""
    for file, text in sources(name).items():
        (folder / file).write_bytes(text)
    return subprocess.run(
        command(cc, name, dims, flags),
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
    )


@functools.cache
def compiler_version(cc: tuple[str, ...]) -> str:
    """The first line of ``cc --version`` ('' where it does not run)."""
    try:
        run = subprocess.run([*cc, "--version"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return ""
    lines = run.stdout.strip().splitlines() if run.returncode == 0 else []
    return lines[0] if lines else ""


@functools.cache
def cpu_signature() -> str:
    """What ``-march=native`` depends on: the CPU's model and feature flags."""
    try:
        with open("/proc/cpuinfo") as f:
            keys = ("model name", "flags", "Features", "CPU part", "CPU implementer")
            return "".join(sorted({line for line in f if line.startswith(keys)}))
    except OSError:
        return platform.platform() + platform.processor()


def sha256_hex(data: bytes) -> str:
    """The SHA-256 of ``data`` as 64 hexadecimal digits (cache keys, library names)."""
    return hashlib.sha256(data).hexdigest()


@dataclass(frozen=True)
class Build:
    """One library: kernel ``name`` for the constants ``dims``, built by ``cc`` (whose
    ``--version`` line is ``version``), and its place in the cache."""

    name: str
    dims: tuple[tuple[str, int], ...]
    cc: tuple[str, ...]
    version: str

    @functools.cached_property
    def key(self) -> str:
        """The SHA-256 of everything the library depends on (module docstring)."""
        recipe = {
            "sources": {f: sha256_hex(text) for f, text in sources(self.name).items()},
            "dims": self.dims,
            "flags": FLAGS,
            "common": COMMON,
            "cc": self.cc,
            "version": self.version,
            "cpu": cpu_signature(),
        }
        return sha256_hex(json.dumps(recipe, sort_keys=True).encode())

    @property
    def stem(self) -> str:
        return "_".join([self.name, *(str(v) for _, v in self.dims), self.key[:16]])

    @property
    def manifest(self) -> Path:
        """The cache entry: the manifest naming the library and its SHA-256."""
        return cache_dir() / f"{self.stem}.json"


def entry(name: str, dims: dict[str, int], version: str | None = None) -> Build:
    """The build of kernel ``name`` for ``dims`` with this process's compiler (``version``:
    its ``--version`` line, found here when None)."""
    cc = compiler()
    return Build(
        name, tuple(dims.items()), cc, compiler_version(cc) if version is None else version
    )


class BuildError(Exception):
    """A library could not be built, verified or opened (the message: one line)."""


def _one_line(text: str, limit: int = REASON) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def verified_library(build: Build) -> tuple[Path | None, str]:
    """The library of ``build``'s manifest if its key is this build's and its bytes hash to
    the manifest's SHA-256; else (None, what is wrong) — '' where there is no manifest."""
    try:
        text = build.manifest.read_text()
    except (FileNotFoundError, NotADirectoryError):  # not built yet, or no cache folder
        return None, ""
    except OSError as err:
        return None, f"cannot read {build.manifest.name} ({err.strerror})"
    try:
        manifest = json.loads(text)
        key, name, digest = manifest["key"], manifest["library"], manifest["sha256"]
    except (ValueError, TypeError, KeyError):
        return None, f"{build.manifest.name} is not a manifest"
    if key != build.key or not isinstance(name, str) or Path(name).name != name:
        return None, f"{build.manifest.name} names another build"
    library = build.manifest.with_name(name)
    try:
        data = library.read_bytes()
    except OSError as err:
        return None, f"cannot read {name} ({err.strerror})"
    if sha256_hex(data) != digest:
        return None, f"{name} does not match the SHA-256 of its manifest"
    return library, ""


def _sync(path: Path, folder: bool = False) -> None:
    """Flush the file ``path`` to disk; a ``folder`` (its entries: the renames) where the
    file system can (some refuse a folder's fsync: then the renames are as durable as it
    makes them)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    except OSError:
        if not folder:
            raise
    finally:
        os.close(fd)


def build(b: Build) -> Path:
    """Compile ``b`` into the cache (module docstring: temporary files, fsync, renames;
    the manifest last) and return the library; BuildError with a one-line reason."""
    folder = cache_dir()
    if folder.exists() and not folder.is_dir():
        raise BuildError(f"the cache {folder} is not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=folder, prefix=".build-") as tmp:
            work = Path(tmp)
            errors = []
            for flags in FLAGS:
                try:
                    run = compile_in(work, b.name, dict(b.dims), flags, b.cc)
                except OSError as err:
                    what = f"no C compiler {shlex.join(b.cc)!r} ({err.strerror})"
                    raise BuildError(what) from err
                except subprocess.TimeoutExpired as err:
                    raise BuildError(f"{shlex.join(b.cc)} took over {TIMEOUT} s") from err
                if run.returncode == 0:
                    break
                lines = run.stderr.strip().splitlines() or [f"exit {run.returncode}"]
                errors.append(next((s for s in lines if "error" in s), lines[0]))
            else:
                raise BuildError(f"{shlex.join(b.cc)} failed: {errors[0]}")
            built = work / "lib.so"
            digest = sha256_hex(built.read_bytes())
            _sync(built)
            library = folder / f"{b.stem}_{digest[:16]}.so"
            os.replace(built, library)
            manifest = {
                "key": b.key,
                "library": library.name,
                "sha256": digest,
                "kernel": b.name,
                "dims": dict(b.dims),
                "flags": list(flags),
                "compiler": list(b.cc),
                "version": b.version,
            }
            note = work / "manifest.json"
            note.write_text(json.dumps(manifest, indent=1) + "\n")
            _sync(note)
            os.replace(note, b.manifest)
            _sync(folder, folder=True)
    except OSError as err:
        raise BuildError(f"cannot write the cache {folder} ({err.strerror or err})") from err
    return library


def _dlopen(b: Build, library: Path) -> tuple[Any, Any]:
    """(ffi, lib) of ``library`` with every function of its interface resolved."""
    import cffi

    ffi = cffi.FFI()
    declarations = cdef(b.name)
    ffi.cdef(declarations)
    lib = ffi.dlopen(str(library))
    for function in re.findall(r"(\w+)\s*\(", declarations):
        getattr(lib, function)  # AttributeError where the library lacks it
    return ffi, lib


def open_library(b: Build) -> tuple[tuple[Any, Any] | None, str]:
    """(ffi, lib) of ``b`` from the cache, built where it is missing; an entry that does not
    verify or load is rebuilt once.  Returns the pair (None where it failed) and a note: ''
    where all went as usual, else what went wrong (one line)."""
    library, problem = verified_library(b)
    if library is not None:
        try:
            return _dlopen(b, library), ""
        except (OSError, AttributeError) as err:
            problem = f"{library.name} does not load ({_one_line(str(err), 60)})"
    try:
        library = build(b)
        checked, why = verified_library(b)
        if checked is None:
            raise BuildError(why or f"{b.manifest.name} vanished")
        kernel = _dlopen(b, checked)
    except (BuildError, OSError, AttributeError) as err:
        reason = f"{problem}; rebuilding it: {err}" if problem else str(err)
        return None, _one_line(reason)
    if problem:
        note = f"the cached {PURPOSE[b.name]} kernel was rebuilt: {problem}"
        return kernel, _one_line(note, 280)
    return kernel, ""


def _attempt(b: Build) -> tuple[tuple[Any, Any] | None, str]:
    """:func:`open_library`, with any error a failure like the others: one rank's error
    must reach the collectives the other ranks wait in, not end this rank alone."""
    try:
        return open_library(b)
    except Exception as err:  # noqa: BLE001 - cffi's CDefError, MemoryError, a bug: all ranks hear
        return None, _one_line(f"{type(err).__name__}: {err}")


class Loaded:
    """What this process has loaded ((ffi, lib) per (name, dims); None: the NumPy backend)
    and whether it has warned (one warning line per process)."""

    def __init__(self) -> None:
        self.kernels: dict[tuple, tuple[Any, Any] | None] = {}
        self.warned = False


LOADED = Loaded()


def _warn(comm: MPI.Comm, message: str) -> None:
    """One warning line per process, from rank 0 (a ContactWarning: the CLI prints it as
    ``contact: warning: ...``)."""
    from ...base.errors import ContactWarning

    if not LOADED.warned and comm.rank == 0:
        warnings.warn(message, ContactWarning, stacklevel=4)
    LOADED.warned = True


def load(comm: MPI.Comm, name: str, dims: dict[str, int]) -> tuple[Any, Any] | None:
    """(ffi, lib) of kernel ``name`` compiled with the constants ``dims``, or None where
    it cannot be had on every rank: then the caller uses the NumPy backend (one warning
    line per process).  Collective; every rank returns the same kind of answer."""
    key = (name, *dims.items())
    known = key in LOADED.kernels
    here = LOADED.kernels.get(key)  # None: not loaded here (not tried, or given up on)
    status = comm.allreduce(0 if here is not None else 2 if known else 1, op=MPI.MAX)
    if status != 1:  # every rank has it, or some rank has given up on it
        if status == 2:
            LOADED.kernels[key] = None
        return LOADED.kernels[key]
    version = comm.bcast(compiler_version(compiler()) if comm.rank == 0 else None, root=0)
    b = entry(name, dims, version)
    mine: tuple[tuple[Any, Any] | None, str] = (here, "")
    if comm.rank == 0 and here is None:
        mine = _attempt(b)
    first = comm.bcast(mine[0] is not None if comm.rank == 0 else None, root=0)
    if comm.rank != 0 and here is None and first:
        mine = _attempt(b)  # rank 0's file where the cache is shared
    outcomes = comm.allgather((mine[0] is not None, mine[1]))
    ok = all(o for o, _ in outcomes)
    note = next((n for _, n in outcomes if n), "")
    LOADED.kernels[key] = mine[0] if ok else None
    if not ok:
        reason = note or "it did not load on every rank"
        _warn(comm, f"the compiled {PURPOSE[name]} kernel is unavailable ({reason}); the "
              "estimate falls back to backend='numpy' (same result, slower)")  # fmt: skip
    elif note:
        _warn(comm, note)
    return LOADED.kernels[key]


def library(comm: MPI.Comm, ref: Reference, nu: int) -> tuple[Any, Any] | None:
    """(ffi, lib) of the flux kernel for ``ref`` and dim P_p = ``nu``, or None: the NumPy
    backend (collective, :func:`load`)."""
    return load(comm, "eqlb", dimensions(ref, nu))
