"""The vertex-patch μ-systems of the equilibrated stress (:mod:`.stress`) through a compiled
kernel: the same algebra as :func:`.stress._patch_multipliers`, one patch at a time in C.

Per pair (cell T of the patch of vertex a): the facet of T opposite a is condensed,

    X = S_oo⁻¹ S_os,   y = S_oo⁻¹ h_o,   Ŝ = S_ss − S_so X,   b = h_s − S_so y − d_s,

the pairs' Ŝ and b are summed into the patch system A μ_s = b (the unknown (spoke, row)
slots), which is solved by LU with partial pivoting after a shift of 1e-12 of its mean
diagonal (a closed patch's rigid motions span the kernel of A; the kernel part of μ does
not change σ_a), and μ_o = y − X μ_s.  The residual ‖A μ_s − b‖ of the unshifted system is
summed into the defect.  The NumPy reference shifts every patch of one size by the largest
mean diagonal among them; both shifts move only the kernel part, so σ_h agrees to round-off.

Why: NumPy spends most of the patch stage on fancy indexing and the scatter of the pairs'
blocks into batched patch matrices; the kernel spends what the flops cost.  The C source is
``kernels/stress.c`` (with the LU of ``kernels/lu.h``), built, verified and cached by
:mod:`.compiled` (one library per reference element).  Here: the calls.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from mpi4py import MPI

from .compiled import load, stress_dimensions
from .reference import Reference


def library(comm: MPI.Comm, ref: Reference) -> tuple[Any, Any] | None:
    """(ffi, lib) of ``kernels/stress.c`` for the rows' reference element ``ref``, or None:
    the NumPy backend (collective, :func:`.compiled.load`)."""
    return load(comm, "stress", stress_dimensions(ref))


def _ptr(ffi, keep: list, a: np.ndarray, ctype: str = "double"):
    """A C pointer to ``a`` (contiguous, of ``ctype``), kept alive in ``keep``."""
    dtype = {"double": np.float64, "int64_t": np.int64, "int32_t": np.int32}[ctype]
    a = np.ascontiguousarray(a, dtype=dtype)
    keep.append(a)
    return ffi.cast(f"{ctype} *", ffi.from_buffer(a))


def cell_operators(kernel: tuple, ref: Reference, arrays: dict, out: dict) -> int:
    """The per-cell arrays of :func:`.stress._cell_operators` (``out``: S, gamma0, h, POt,
    C-contiguous, written in place) from its inputs (``arrays``: J, s, absdet, the
    reference tables ZZ, ZR, W, M1Z, M1R, the oriented OZ, OR, and q0, beta, m); the
    kernel's error code (1: a singular cell matrix)."""
    ffi, lib = kernel
    keep: list = []
    names = ("J", "s", "absdet", "ZZ", "ZR", "W", "M1Z", "M1R", "OZ", "OR", "q0", "beta", "m")
    args = [_ptr(ffi, keep, arrays[k]) for k in names]
    for k in ("S", "gamma0", "h", "POt"):
        assert out[k].flags.c_contiguous and out[k].dtype == np.float64
        args.append(ffi.cast("double *", ffi.from_buffer(out[k])))
    return int(lib.st_cells(len(arrays["s"]), *args))


def patch_multipliers(
    kernel: tuple,
    d: int,
    nf: int,
    pstart: np.ndarray,
    prow: np.ndarray,
    ploc: np.ndarray,
    idx: np.ndarray,
    pdim: np.ndarray,
    S: np.ndarray,
    hp: np.ndarray,
    dp: np.ndarray,
) -> tuple[np.ndarray, float, int]:
    """μ (npair, D·d·nf) of every pair and the summed defect (module docstring).  The pairs
    are sorted by patch (``pstart``: the offsets, ``pdim``: each patch's unknowns);
    ``prow``/``ploc``: the pair's cell (a row of ``S`` (n, D d nf, D d nf)) and local
    vertex; ``idx`` (npair, d·d·nf): the patch-local unknown of each spoke moment, −1
    where the row is prescribed; ``hp``, ``dp``: the normal moments at μ = 0 and the
    prescribed data, (npair, D d nf); ``kernel``: :func:`library`'s (ffi, lib).  Returns
    μ, the defect and the kernel's error code (0: none; 1: a singular cell block, 2: a
    singular patch system, 3: out of memory): the caller decides collectively."""
    ffi, lib = kernel
    keep: list = []
    mu = np.zeros((len(prow), (d + 1) * d * nf))
    defect = np.zeros(1)
    err = lib.st_patches(
        len(pdim),
        _ptr(ffi, keep, pstart, "int64_t"),
        _ptr(ffi, keep, prow, "int64_t"),
        _ptr(ffi, keep, ploc, "int32_t"),
        _ptr(ffi, keep, idx, "int64_t"),
        _ptr(ffi, keep, pdim, "int64_t"),
        _ptr(ffi, keep, S),
        _ptr(ffi, keep, hp),
        _ptr(ffi, keep, dp),
        ffi.cast("double *", ffi.from_buffer(mu)),
        ffi.cast("double *", ffi.from_buffer(defect)),
    )
    return mu, float(defect[0]), int(err)
