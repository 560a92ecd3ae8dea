"""The vertex-patch problems of the flux reconstruction, solved batched.

For a vertex a with hat function ψ_a and patch ω_a (the cells around a), Ern & Vohralík
(SIAM J. Numer. Anal. 53, 2015) take

    σ_a = argmin ‖k_T^{-1/2}(σ − ψ_a k∇u_h)‖_{ω_a}   over σ ∈ RT_p(ω_a) with
    −div σ = Π_p(ψ_a f − k∇u_h·∇ψ_a + ψ_a λ̃_T [obstacle])       in each cell,
    σ·n = Π_p(ψ_a t)  on Γ_N,   Π_p(ψ_a (t_C + λ̃_F))  on Γ_C,   0 on the rest of ∂ω_a
    (free on Γ_D),

and σ_h = Σ_a σ_a (k_T: the cell mean of k; ψ_a λ̃: the share of :mod:`.multiplier`).
Cells meet only through the Lagrange multipliers μ of the normal moments on the facets
that contain a ("spokes"; :mod:`.operators`); the facet opposite a is eliminated in its
cell.  Patches without a Dirichlet facet are determined up to a constant multiplier
(regularized) and solvable only if their balance holds, which the nodal shares c_a
make true up to the algebraic residual of the solve at free vertices (and a clipped
sign); what remains is projected out and reported as ``defect``.

All patches of one size (number of unknown spokes) are solved in one batched dense solve;
no loop runs over vertices.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .cells import CONTACT, DIRICHLET, CellTable
from .operators import CellOperators
from .reference import Reference


@dataclass
class PatchOutput:
    alpha: np.ndarray  # (rows, m): the RT_p coefficients Σ_a σ_a|_T (of the patches solved here)
    defect: float  # Σ_a |balance defect| (flux units) projected out
    stats: dict = field(default_factory=dict)  # counters of the compiled kernel


def solve_patches(
    table: CellTable,
    owned_vertex: np.ndarray,
    ref: Reference,
    multiplier: str | None,
    sign: float,
    chunk: int = 50_000,
) -> PatchOutput:
    """Solve the patches of the vertices ``owned_vertex`` (global indices, complete in
    ``table``).  ``multiplier``: None, "facets" (λ on Γ_C) or "cells" (λ in Ω); ``sign``:
    the admissible sign of λ (−1: λ ≤ 0, +1: λ ≥ 0)."""
    rows, locs = np.nonzero(np.isin(table.gvert, owned_vertex))
    verts = table.gvert[rows, locs]
    order = np.argsort(verts, kind="stable")
    rows, locs, verts = rows[order], locs[order], verts[order]
    alpha = np.zeros((len(table), ref.m))
    uniq, starts = np.unique(verts, return_index=True)
    defect = 0.0
    bounds = list(range(0, len(uniq), chunk)) + [len(uniq)]
    ends = np.append(starts, len(verts))
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        sl = slice(ends[lo], ends[hi])
        defect += _solve_chunk(
            table,
            rows[sl],
            locs[sl],
            np.searchsorted(uniq[lo:hi], verts[sl]),
            hi - lo,
            ref,
            multiplier,
            sign,
            alpha,
        )
    return PatchOutput(alpha, defect)


def _solve_chunk(table, prow, ploc, patch, n_patches, ref: Reference, multiplier, sign, alpha):
    """One batch of whole patches: pairs (row prow, local vertex ploc) of patch ``patch``."""
    D, nf = ref.d + 1, ref.nf
    cells, inv = np.unique(prow, return_inverse=True)
    ops = CellOperators(table, cells, ref, multiplier, sign)
    npair = len(prow)
    ar = np.arange(npair)
    # the spokes of each pair: facets j != ploc; key = the other vertices of the facet
    spoke_facets = np.array([[j for j in range(D) if j != i] for i in range(D)])  # (D, d)
    sf = spoke_facets[ploc]  # (npair, d)
    keys = spoke_keys(table.gvert[prow], ploc, sf, patch)  # (npair*d,)
    kinds = np.concatenate([table.kind[prow, sf[:, s]] for s in range(ref.d)])
    ukeys, first_of, spoke = np.unique(keys, return_index=True, return_inverse=True)
    spoke = spoke.reshape(ref.d, npair).T  # (npair, d)
    spoke_patch = np.tile(patch, ref.d)[first_of]
    spoke_kind = np.zeros(len(ukeys), dtype=np.int8)
    spoke_kind[spoke.T.ravel()] = kinds
    has_dirichlet = np.zeros(n_patches, bool)
    has_dirichlet[spoke_patch[spoke_kind == DIRICHLET]] = True
    has_contact = np.zeros(n_patches, bool)
    has_contact[spoke_patch[spoke_kind == CONTACT]] = True
    # spokes with μ
    free = spoke_kind != DIRICHLET
    # patch-local numbering of the unknown spokes
    n_unknown = np.bincount(spoke_patch[free], minlength=n_patches)
    local = np.full(len(ukeys), -1)
    first = np.concatenate([[0], np.cumsum(n_unknown)[:-1]])
    fs = np.flatnonzero(free)
    local[fs] = np.arange(len(fs)) - first[spoke_patch[fs]]
    # (npair, d) or -1
    pair_local = local[spoke]

    # condensation of the opposite facet in each pair's cell
    dof = np.arange(D * nf).reshape(D, nf)
    # (npair, d nf)
    I_s = dof[spoke_facets].reshape(D, -1)[ploc]
    # (npair, nf)
    I_o = dof[ploc]
    S = ops.S[inv]
    Sss = S[ar[:, None, None], I_s[:, :, None], I_s[:, None, :]]
    Sso = S[ar[:, None, None], I_s[:, :, None], I_o[:, None, :]]
    Soo_inv = np.linalg.inv(S[ar[:, None, None], I_o[:, :, None], I_o[:, None, :]])
    # (npair, d nf, nf)
    T = Sso @ Soo_inv
    Shat = Sss - T @ np.transpose(Sso, (0, 2, 1))
    R0, src = ops.div_moments
    s = ops.geometry["s"][inv]
    beta = -s[:, None] * (R0[inv, ploc] + src[inv, ploc])
    ZTg = ops.ZTg[inv, ploc]
    h = _h(ops, inv, beta, ZTg)
    # (npair, d nf)
    data = ops.facet_data[inv[:, None], sf, ploc[:, None]].reshape(npair, -1)
    b = _condense(h, I_s, I_o, T) - data

    mu_s = np.zeros((npair, ref.d, nf))
    defect = 0.0
    for size in np.unique(n_unknown[n_unknown > 0]):
        members = np.flatnonzero(n_unknown == size)
        where = np.full(n_patches, -1)
        where[members] = np.arange(len(members))
        sel = np.flatnonzero(where[patch] >= 0)
        A, rhs = assemble_patches(
            where[patch[sel]], pair_local[sel], Shat[sel], b[sel], len(members), size, nf
        )
        pure = ~has_dirichlet[members]
        # regularize the constant multiplier; project out what is left of the balance
        if np.any(pure):
            kv = np.tile(ref.kappa, size)
            bal = rhs[pure] @ kv
            defect += float(np.abs(bal).sum() / (kv @ kv) * np.sqrt(kv @ kv))
            rhs[pure] -= np.outer(bal / (kv @ kv), kv)
            scale = np.trace(A[pure], axis1=1, axis2=2) / (size * nf * (kv @ kv))
            A[pure] += scale[:, None, None] * np.outer(kv, kv)[None]
        sol = np.linalg.solve(A, rhs[..., None])[..., 0].reshape(len(members), size, nf)
        pl = pair_local[sel]
        got = sol[where[patch[sel]][:, None], np.maximum(pl, 0)]
        mu_s[sel] = np.where(pl[..., None] >= 0, got, 0.0)
    mu_flat = mu_s.reshape(npair, -1)
    mu_o = np.einsum(
        "nab,nb->na", Soo_inv, h[ar[:, None], I_o] - np.einsum("nba,nb->na", Sso, mu_flat)
    )
    mu = np.zeros((npair, D * nf))
    mu[ar[:, None], I_s] = mu_flat
    mu[ar[:, None], I_o] = mu_o
    rhs_g = (
        ZTg - np.einsum("nab,nb->na", ops.ZMR[inv], beta) - np.einsum("nka,nk->na", ops.OZ[inv], mu)
    )
    gamma = np.einsum("nab,nb->na", ops.MZinv[inv], rhs_g)
    contrib = beta @ ref.R.T + gamma @ ref.Z.T
    for col in range(ref.m):
        alpha[:, col] += np.bincount(prow, weights=contrib[:, col], minlength=len(alpha))
    return defect


def spoke_keys(gvert: np.ndarray, ploc: np.ndarray, sf: np.ndarray, patch: np.ndarray):
    """One int64 key per (spoke s, pair), s-major: (npair·d,).  A spoke is the facet sf[:, s]
    of the pair's cell through its vertex ploc, in the patch ``patch``; the key combines
    the patch and the facet's other vertices (compact ids of ``gvert`` (npair, D), the
    cells' global vertices), so the pairs of one spoke share it."""
    npair, D = gvert.shape
    ar = np.arange(npair)
    _, gv = np.unique(gvert, return_inverse=True)  # compact ids
    gv = gv.reshape(npair, D).astype(np.int64)
    nv = int(gv.max()) + 1 if npair else 1
    keys = []
    for s in range(D - 1):
        others = np.sort(np.stack([gv[ar, v] for v in _others(ploc, sf[:, s], D)], axis=1), axis=1)
        key = patch.astype(np.int64)
        for col in others.T:
            key = key * nv + col
        keys.append(key)
    return np.concatenate(keys)


def _others(ploc, facet, D):
    """Local indices of the vertices of ``facet`` other than ``ploc`` (d − 1 of them)."""
    out = []
    cand = np.arange(D)
    mask = (cand[None, :] != ploc[:, None]) & (cand[None, :] != facet[:, None])
    idx = np.nonzero(mask)[1].reshape(len(ploc), D - 2)
    for r in range(D - 2):
        out.append(idx[:, r])
    return out


def _h(ops: CellOperators, inv, beta, ZTg):
    """h_a = O R̂ β + (O Z) M_Z⁻¹ (Zᵀ g_a − Zᵀ M R̂ β) for each pair: (npair, (d+1) nf)."""
    return np.einsum("nka,na->nk", ops.OR[inv], beta) + np.einsum(
        "nkz,nz->nk", ops.Yt[inv], ZTg - np.einsum("nzb,nb->nz", ops.ZMR[inv], beta)
    )


def _condense(h, I_s, I_o, T):
    ar = np.arange(len(h))
    return h[ar[:, None], I_s] - np.einsum("nab,nb->na", T, h[ar[:, None], I_o])


def assemble_patches(patch, local, Shat, b, n, size, nf):
    """Dense patch matrices (n, size nf, size nf) and right-hand sides from the pairs."""
    npair, d = local.shape
    dim = size * nf
    # (npair, d nf)
    idx = (local[:, :, None] * nf + np.arange(nf)[None, None, :]).reshape(npair, d * nf)
    ok = np.repeat(local >= 0, nf, axis=1)
    rows = np.where(ok, idx, -1)
    flat_rhs = patch[:, None] * dim + rows
    rhs = np.bincount(flat_rhs[ok], weights=b[ok], minlength=n * dim).reshape(n, dim)
    both = ok[:, :, None] & ok[:, None, :]
    flat = patch[:, None, None] * dim * dim + rows[:, :, None] * dim + rows[:, None, :]
    A = np.bincount(flat[both], weights=Shat[both], minlength=n * dim * dim).reshape(n, dim, dim)
    return A, rhs
