"""The vertex-patch problems of :mod:`.patches` through the compiled kernel (``kernels/eqlb.c``).

The same mathematics (the patch minimization of :mod:`.patches`, the cell operators of
:mod:`.operators`, osc_T of :class:`.flux.Flux`), one patch at a time in C: each patch's
minimizer is unique, so σ_h agrees with the NumPy backend to round-off.  NumPy spends
1–3 µs of call overhead on each of the millions of small matrices; the kernel spends
what the flops cost.  Here: the reference tables in the kernel's layout, the multiplier
shares of :mod:`.multiplier` (vectorized, only on contact entities), and the call.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from mpi4py import MPI

from .cells import CONTACT, CellTable
from .multiplier import clipped, shares
from .operators import cell_rule, data_tables, facet_rule, lowest_tables, projected_mass
from .patches import PatchOutput
from .reference import Reference

#: the initial work rows of the kernel (one per live cell; doubled when the front of live
#: cells needs more)
CAPACITY = 4096


@functools.cache
def _tables(d: int, p: int, pu: int, nu: int) -> dict:
    """The reference arrays of ``eq_ref`` (contiguous float64, the layouts of ``eqlb.h``)."""
    from .reference import reference

    r = reference(d, p, pu)
    t = data_tables(r, nu)
    D = d + 1
    lookup = np.full(max(d**d, 1), -1, dtype=np.int64)
    for i, pi in enumerate(r.perms):
        code = 0
        for rank in pi:
            code = code * d + rank
        lookup[code] = i
    arrays = {
        "w": r.w,
        "ZZ": projected_mass(r, "ZZ"),
        "ZR": projected_mass(r, "ZR"),
        "NZ": np.einsum("jkm,mz->jkz", r.N, r.Z),
        "NR": np.einsum("jkm,mz->jkz", r.N, r.R),
        "P": r.P,
        "phiZ": np.einsum("qmd,mz->qdz", r.phi, r.Z),
        "wlam": r.w[:, None] * r.lam,
        "DZG": np.einsum("qud,qdaz->uaz", t["dphi_u"], t["ZG"]),
        "wlamQ": t["wlamQ"],
        "wQ": t["wQ"],
        "dphi": t["dphi_u"],
        "dlam": r.dlam,
        "base": np.einsum("q,jqa,kq->jakq", r.wS, r.lamF, r.q),
        "R": r.R,
        "Z": r.Z,
        "kappa": r.kappa,
        "Q": r.Q,
        "q": r.q,
        "wS": r.wS,
        **_flow_tables(r),
        **lowest_tables(r),
    }
    out = {k: np.ascontiguousarray(v, dtype=np.float64) for k, v in arrays.items()}
    assert out["base"].shape == (D, D, r.nf, len(r.wS))
    out["lookup"] = lookup
    return out


def _flow_tables(r: Reference) -> dict:
    """The reference arrays of the moment path (``eq_flow``, p = 1): with G the left inverse of
    N̂Z, the flux of reference facet moments m̂ and divergence moments β is GL m̂ + RL β
    (GL = Z G, RL = R̂ − Z G N̂R̂: for p = 1 the moments determine it); AR_ij = GLᵀ mass_ij GL
    and BR_ij = GLᵀ mass_ij RL give its energy, GT = Gᵀ the load; qint_j = ∫_T̂ Q̂_j;
    TB[j, a, k] = ∫_F̂ λ_a q̂_k / |F̂| on facet j (the target's facet moments)."""
    D = r.d + 1
    NZ = np.einsum("jkm,mz->jkz", r.N, r.Z).reshape(D * r.nf, -1)
    NR = np.einsum("jkm,mz->jkz", r.N, r.R).reshape(D * r.nf, -1)
    G = np.linalg.pinv(NZ)
    GL, RL = r.Z @ G, r.R - r.Z @ G @ NR
    return {
        "GL": GL,
        "RL": RL,
        "AR": np.einsum("mx,ijmn,ny->ijxy", GL, r.mass, GL),
        "BR": np.einsum("mx,ijmn,ny->ijxy", GL, r.mass, RL),
        "GT": G.T,
        "TB": np.einsum("q,jqa,kq->jak", r.wS, r.lamF, r.q) / r.wS.sum(),
        "qint": r.Q @ r.w,
    }


def _multiplier(table: CellTable, ref: Reference, multiplier: str | None, sign: float) -> dict:
    """The shares of λ̃_h the patches carry: ``src`` (n, D, np) per reference measure for the
    obstacle; ``cidx`` (n,) and ``cmom`` (rows with a contact facet, D facets, D, nf) for
    Signorini; None where absent."""
    out: dict[str, np.ndarray | None] = {"src": None, "cidx": None, "cmom": None}
    if multiplier is None:
        return out
    if multiplier == "cells":
        out["src"] = np.ascontiguousarray(shares(clipped(table.lam, sign), cell_rule(ref), sign)[0])
        return out
    D = ref.d + 1
    crow = np.flatnonzero(np.any(table.kind == CONTACT, axis=1))
    cidx = np.full(len(table), -1, dtype=np.int64)
    cidx[crow] = np.arange(len(crow))
    if table.cmom.ndim == 4:  # given (FluxData.multiplier_rule)
        out.update(cidx=cidx, cmom=np.ascontiguousarray(table.cmom[crow]))
        return out
    nodal = clipped(table.lam[crow], sign)
    cmom = np.zeros((len(crow), D, D, ref.nf))
    for j in range(D):
        on = np.flatnonzero(table.kind[crow, j] == CONTACT)
        if len(on):
            cmom[on, j] = shares(nodal[on], facet_rule(ref, j), sign)[0]
    out.update(cidx=cidx, cmom=cmom)
    return out


def solve_patches_compiled(
    comm: MPI.Comm,
    kernel: tuple[Any, Any],
    table: CellTable,
    vertices: tuple[int, int],
    ref: Reference,
    multiplier: str | None,
    sign: float,
    flow: int = -1,
) -> tuple[PatchOutput, np.ndarray]:
    """The patches of the vertices with global index in [vertices[0], vertices[1]) (complete in
    ``table``), and osc_T of every row; ``flow`` ≥ 0: by the moment path of ``eqlb.c``
    (``eq_flow``, p = 1, that many rounds) instead of the patch minimizations; ``kernel``:
    :func:`.compiled.library`'s (ffi, lib) for ``ref``.  Collective (the error codes)."""
    nu = table.U.shape[1]
    ffi, lib = kernel
    tabs = _tables(ref.d, ref.p, ref.pu, nu)
    keep = []  # the buffers must outlive the call

    def ptr(a, ctype="double"):
        if a is None:
            return ffi.NULL
        a = np.ascontiguousarray(a)
        keep.append(a)
        return ffi.cast(f"{ctype} *", ffi.from_buffer(a))

    r = ffi.new("eq_ref *")
    for name, arr in tabs.items():
        setattr(r, name, ptr(arr, "int64_t" if name == "lookup" else "double"))
    r.wsum = float(ref.w.sum())
    extra = _multiplier(table, ref, multiplier, sign)
    t = ffi.new("eq_table *")
    t.n = len(table)
    t.gvert = ptr(table.gvert.astype(np.int64, copy=False), "int64_t")
    t.kind = ptr(table.kind.astype(np.int8, copy=False), "int8_t")
    for name in ("x", "U", "t"):
        setattr(t, name, ptr(getattr(table, name).astype(np.float64, copy=False)))
    t.Ut = ffi.NULL
    for name in ("f", "k"):  # a constant is a stride-0 view (cells._at_points)
        a = getattr(table, name)
        constant = len(a) > 0 and a.strides[0] == 0
        setattr(t, name, ptr(a[0] if constant else a))
        setattr(t, f"{name}stride", 0 if constant else a.shape[1])
    t.tau = ptr(table.tau if table.tau.shape[1] else None)
    t.src = ptr(extra["src"])
    t.cidx = ptr(extra["cidx"], "int64_t")
    t.cmom = ptr(extra["cmom"])
    alpha = np.zeros((len(table), ref.m))
    osc = np.full(len(table), np.nan)
    stats = np.zeros(3)
    args = (r, t, int(vertices[0]), int(vertices[1]), CAPACITY, ptr(alpha), ptr(osc), ptr(stats))
    err = lib.eq_flow(*args, flow) if flow >= 0 else lib.eq_patches(*args)
    lib.eq_oscillation(r, t, ptr(osc))
    err = comm.allreduce(err, op=MPI.MAX)
    if err:
        what = {
            1: "a singular cell matrix (a degenerate cell?)",
            2: "a singular vertex-patch system",
            3: "out of memory",
        }.get(err, f"error {err}")
        raise RuntimeError(f"flux reconstruction: {what}")
    counters = {"cell_evaluations": int(stats[1]), "work_rows": int(stats[2])}
    out = PatchOutput(alpha, float(stats[0]), counters)
    return out, osc
