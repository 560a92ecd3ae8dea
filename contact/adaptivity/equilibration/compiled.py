"""The compiled patch solver: builds the C library of :mod:`.kernel_c` for a reference
element (one per (d, p)), caches it on disk and loads it through cffi.

The library is compiled at first use with the C compiler DOLFINx's JIT already needs
(``$CC``, else ``cc``; ``-O3 -march=native``: the lane loops of the cell kernel vectorize,
≈ 25 % faster than ``-O2`` here; ``-O2`` where the compiler refuses ``-march=native``) into
``$CONTACT_CACHE_DIR`` (default ``$XDG_CACHE_HOME/contact``, ``~/.cache/contact``) under a
name hashing the source, the dimensions, the compiler command and the CPU's model and
feature flags (so a cache shared by different machines never hands one another's
instructions); it is written to a temporary file and renamed, so concurrent processes
never load half a library.  Under MPI, rank 0 compiles while the
others wait, the outcome is broadcast (an error ends every rank with the same message),
and a rank that does not see rank 0's file (a node-local cache) compiles its own.
"""

from __future__ import annotations

import functools
import hashlib
import os
import platform
import shlex
import subprocess
import tempfile
from pathlib import Path

from mpi4py import MPI

from .kernel_c import CDEF, SOURCE
from .reference import Reference

_LOADED: dict = {}


def dimensions(ref: Reference, nu: int) -> dict:
    """The compile-time constants of :mod:`.kernel_c` for ``ref`` and dim P_p = ``nu``."""
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


def cache_dir() -> Path:
    base = (
        os.environ.get("CONTACT_CACHE_DIR")
        or Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "contact"
    )
    return Path(base)


FLAGS = (["-O3", "-march=native"], ["-O2"])


def _command(src: Path, out: Path, flags: list[str]) -> list[str]:
    cc = shlex.split(os.environ.get("CC", "cc"))
    return cc + flags + ["-std=c99", "-fPIC", "-shared", str(src), "-o", str(out), "-lm"]


@functools.cache
def _cpu() -> str:
    """What ``-march=native`` depends on: the CPU's model and feature flags."""
    try:
        with open("/proc/cpuinfo") as f:
            keys = ("model name", "flags", "Features", "CPU part", "CPU implementer")
            return "".join(sorted({line for line in f if line.startswith(keys)}))
    except OSError:
        return platform.platform() + platform.processor()


def _source(dims: dict, source: str = SOURCE) -> str:
    return "".join(f"#define {k} {v}\n" for k, v in dims.items()) + source


def _path(dims: dict, name: str = "eqlb", source: str = SOURCE) -> Path:
    command = " ".join(" ".join(_command(Path("s"), Path("o"), f)) for f in FLAGS)
    digest = hashlib.sha256((_source(dims, source) + command + _cpu()).encode()).hexdigest()
    tag = "_".join(str(v) for v in dims.values())
    return cache_dir() / f"{name}_{tag}_{digest[:16]}.so"


def _compile(source: str, path: Path) -> str:
    """Compile ``source`` into ``path`` unless it exists; returns '' or the error message."""
    if path.exists():
        return ""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=path.parent) as tmp:
            src = Path(tmp) / "eqlb.c"
            src.write_text(source)
            out = Path(tmp) / path.name
            for flags in FLAGS:
                run = subprocess.run(_command(src, out, flags), capture_output=True, text=True)
                if run.returncode == 0:
                    break
            if run.returncode != 0:
                return f"compiling the equilibration kernel failed: {run.stderr.strip()[:500]}"
            os.replace(out, path)
    except OSError as err:
        return f"compiling the equilibration kernel into {path.parent} failed: {err}"
    return ""


def load(comm: MPI.Comm, name: str, cdef: str, source: str, dims: dict):
    """(ffi, lib) of the C ``source`` (its declarations ``cdef``) compiled with the
    constants ``dims`` (``#define``s), cached on disk under ``name`` (collective)."""
    import cffi

    key = (name, *dims.items())
    missing = comm.allreduce(key not in _LOADED, op=MPI.LOR)
    if missing:
        path = _path(dims, name, source)
        text = _source(dims, source)
        error = comm.bcast(_compile(text, path) if comm.rank == 0 else "", root=0)
        if not error and key not in _LOADED:
            error = _compile(text, path)  # a no-op where rank 0's file is seen
            if not error:
                try:
                    ffi = cffi.FFI()
                    ffi.cdef(cdef)
                    _LOADED[key] = (ffi, ffi.dlopen(str(path)))
                except OSError as err:
                    error = f"loading the equilibration kernel {path} failed: {err}"
        error = next((e for e in comm.allgather(error) if e), "")
        if error:
            raise RuntimeError(error)
    return _LOADED[key]


def library(comm: MPI.Comm, ref: Reference, nu: int):
    """(ffi, lib) of the flux kernel of :mod:`.kernel_c` for ``ref`` (collective)."""
    return load(comm, "eqlb", CDEF, SOURCE, dimensions(ref, nu))
