"""Cell operators of the hybridized patch problems, for a batch of cell rows at once.

On a cell T (affine map x = x_0 + J x̂, s = sign det J) a flux with prescribed divergence
moments β is σ = Piola(R̂ β + Z γ) (:mod:`.reference`).  With the weighted mass
M = ∫_T k_T⁻¹ φ·φ (k_T the cell mean of k: any weight gives an admissible flux, this one
a near-optimal one), the Lagrange multipliers μ of the outward normal moments O σ on the
facets of T, and the load g_a = ∫_T ψ_a ∇u_h·φ (k cancels: k⁻¹ · k∇u_h), minimizing
½ σᵀMσ − g_aᵀσ + μᵀ(Oσ − data) over γ gives

    γ = M_Z⁻¹ Zᵀ(g_a − M R̂ β − Oᵀ μ),   O σ = h_a − S μ,
    S = (O Z) M_Z⁻¹ (O Z)ᵀ,   h_a = O R̂ β + (O Z) M_Z⁻¹ (Zᵀ g_a − Zᵀ M R̂ β),

M_Z = Zᵀ M Z.  The patch problem then couples cells only through μ on the facets they
share.  Under the Piola map ∫_F σ·n q ds = s ∫_F̂ σ̂·n̂ q̂ dŝ and ∫_T div σ q = s ∫_T̂ div̂ σ̂ q̂,
and ∫_T ∇u_h·σ = s ∫_T̂ ∇̂û·σ̂: only M and the data integrals see the geometry.  Facet
moments are taken against P_p(F) in the facet coordinates of its vertices sorted by
global index (the same on both sides of a facet and on every rank): O_j = s P_πᵀ N̂_j.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .cells import CONTACT, FLUX, CellTable
from .multiplier import clipped, entity_rule, shares
from .reference import Reference, reference


def det_inv(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """det J and J⁻¹ of a stack of 2×2 or 3×3 matrices (closed form)."""
    if J.shape[-1] == 2:
        det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        adj = np.empty_like(J)
        adj[:, 0, 0], adj[:, 1, 1] = J[:, 1, 1], J[:, 0, 0]
        adj[:, 0, 1], adj[:, 1, 0] = -J[:, 0, 1], -J[:, 1, 0]
    else:
        adj = np.empty_like(J)
        for i in range(3):
            for j in range(3):
                r = [k for k in range(3) if k != j]
                c = [k for k in range(3) if k != i]
                minor = J[:, r[0], c[0]] * J[:, r[1], c[1]] - J[:, r[0], c[1]] * J[:, r[1], c[0]]
                adj[:, i, j] = (-1) ** (i + j) * minor
        det = np.einsum("nj,nj->n", J[:, 0, :], adj[:, :, 0])
    return det, adj / det[:, None, None]


def facet_permutations(gvert: np.ndarray, ref: Reference) -> np.ndarray:
    """(n, d+1) index into ``ref.perms`` of each facet: the rank of each of the facet's
    local vertices (local order) among their global indices."""
    n, D = gvert.shape
    index = {pi: i for i, pi in enumerate(ref.perms)}
    out = np.empty((n, D), dtype=np.int64)
    for j in range(D):
        g = gvert[:, [v for v in range(D) if v != j]]
        ranks = np.argsort(np.argsort(g, axis=1), axis=1)
        code = np.zeros(n, dtype=np.int64)
        for r in range(D - 1):
            code = code * (D - 1) + ranks[:, r]
        lookup = np.full((D - 1) ** (D - 1), -1, dtype=np.int64)
        for pi, i in index.items():
            c = 0
            for r in pi:
                c = c * (D - 1) + r
            lookup[c] = i
        out[:, j] = lookup[code]
    return out


@dataclass
class CellOperators:
    """The operators of the rows ``rows`` of a cell table (see the module docstring)."""

    table: CellTable
    rows: np.ndarray
    ref: Reference
    multiplier: str | None = None  # where λ lives: None, "facets" (Γ_C) or "cells" (Ω)
    sign: float = 0.0  # its admissible sign

    @cached_property
    def nodal(self) -> np.ndarray:
        """λ_h's coefficients with wrong-signed nodal values clipped: (n, nu)."""
        return clipped(self.table.lam[self.rows], self.sign)

    @cached_property
    def geometry(self) -> dict:
        x = self.table.x[self.rows]
        J = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
        det, Jinv = det_inv(J)
        return {
            "s": np.sign(det),
            "absdet": np.abs(det),
            "GM": np.einsum("nki,nkj->nij", J, J) / np.abs(det)[:, None, None],
            "KS": np.einsum("nik,njk->nij", Jinv, Jinv) * np.abs(det)[:, None, None],
        }

    @cached_property
    def kT(self) -> np.ndarray:
        w = self.ref.w
        return self.table.k[self.rows] @ w / w.sum()

    @cached_property
    def MZinv(self) -> np.ndarray:
        r = self.ref
        MZ = (
            np.einsum("nij,ijab->nab", self.geometry["GM"], projected_mass(r, "ZZ"))
            / self.kT[:, None, None]
        )
        return np.linalg.inv(MZ)

    @cached_property
    def ZMR(self) -> np.ndarray:
        return (
            np.einsum("nij,ijab->nab", self.geometry["GM"], projected_mass(self.ref, "ZR"))
            / self.kT[:, None, None]
        )

    @cached_property
    def perm(self) -> np.ndarray:
        return facet_permutations(self.table.gvert[self.rows], self.ref)

    def _oriented(self, NX: np.ndarray) -> np.ndarray:
        """s P_πᵀ (N̂_j X) for every facet j: (n, d+1, nf, ·)."""
        P = self.ref.P[self.perm]  # (n, D, nf, nf)
        return self.geometry["s"][:, None, None, None] * np.einsum("njkl,jka->njla", P, NX)

    @cached_property
    def OZ(self) -> np.ndarray:
        r = self.ref
        return self._oriented(np.einsum("jkm,mz->jkz", r.N, r.Z)).reshape(
            len(self.rows), -1, r.Z.shape[1]
        )

    @cached_property
    def OR(self) -> np.ndarray:
        r = self.ref
        return self._oriented(np.einsum("jkm,mz->jkz", r.N, r.R)).reshape(
            len(self.rows), -1, r.R.shape[1]
        )

    @cached_property
    def Yt(self) -> np.ndarray:
        """(O Z) M_Z⁻¹: (n, (d+1) nf, mz)."""
        return self.OZ @ self.MZinv

    @cached_property
    def S(self) -> np.ndarray:
        return self.Yt @ np.transpose(self.OZ, (0, 2, 1))

    @cached_property
    def grad_u(self) -> np.ndarray:
        """Reference gradient of u_h at the cell quadrature points: (n, nq, d)."""
        return np.einsum("nu,qud->nqd", self.table.U[self.rows], self.ref_tables["dphi_u"])

    @cached_property
    def ZTg(self) -> np.ndarray:
        """Zᵀ g_a for each vertex a of the cell, (n, d+1, mz), with the load of the weight
        k_T⁻¹ of M and the target τ (default k∇u_h): g_a = ∫_T k_T⁻¹ ψ_a τ·φ =
        s k_T⁻¹ ∫_T̂ ψ̂_a (Jᵀτ)·φ̂, and Jᵀ k∇u_h = k ∇̂û."""
        n, nq, d = self.grad_u.shape
        tau = self.table.tau[self.rows]
        if tau.shape[1]:
            x = self.table.x[self.rows]
            J = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
            ref_tau = np.einsum("nji,nqj->nqi", J, tau)
        else:
            ref_tau = self.grad_u * self.table.k[self.rows][:, :, None]
        lhs = ref_tau / self.kT[:, None, None]
        if self.ref.lowest:
            return self._lowest_load(lhs)
        lhs = lhs.reshape(n, nq * d)
        ZG = self.ref_tables["ZG"]  # (nq, d, D, mz): w λ_a (φ̂ Z)
        return self.geometry["s"][:, None, None] * (lhs @ ZG.reshape(nq * d, -1)).reshape(
            n, d + 1, -1
        )

    def _lowest_load(self, lhs: np.ndarray) -> np.ndarray:
        """Zᵀg_a of the lowest-order flux of a P1 solution (RT_0; Braess & Schöberl): the
        target is the RT_0 interpolant of ψ_a w, w = J⁻ᵀŵ the cell mean of τ/k_T,

            I(ψ_a w) = (w + (∇ψ_a·w)(x − x_a)) / d,

        so Zᵀg_a = s (ŵ·IZ + (∇ψ_a·w) Σ_ij (JᵀJ)_ij EZ_aij) / d (the tables of
        :func:`lowest_tables`)."""
        r = self.ref
        g = self.geometry
        wq = r.w if lhs.shape[1] == len(r.w) else np.ones(1)  # a given τ: at the centroid
        w_ref = np.einsum("nqd,q->nd", lhs, wq) / wq.sum()  # ŵ (n, d)
        JtJ = g["GM"] * g["absdet"][:, None, None]
        inv = g["KS"] / g["absdet"][:, None, None]  # (JᵀJ)⁻¹
        c = np.einsum("ak,nkl,nl->na", r.dlam, inv, w_ref)  # ∇ψ_a·w
        tab = lowest_tables(r)
        load = (w_ref @ tab["IZ"])[:, None, :] + c[:, :, None] * np.einsum(
            "nij,aijz->naz", JtJ, tab["EZ"]
        )
        return g["s"][:, None, None] * load / r.d

    @cached_property
    def ref_tables(self) -> dict:
        return data_tables(self.ref, self.table.U.shape[1])

    @cached_property
    def div_moments(self) -> tuple[np.ndarray, np.ndarray]:
        """∫_T (ψ_a f − k∇u_h·∇ψ_a) Q_j and, for the obstacle, the multiplier's share
        ∫_T ψ_a λ̃_T Q_j: each (n, d+1, np)."""
        r, t = self.ref, self.ref_tables
        rows = self.rows
        g = self.geometry
        v = np.einsum("nqi,nik,ak->nqa", self.grad_u, g["KS"], r.dlam)
        R0 = g["absdet"][:, None, None] * np.einsum(
            "nq,qaj->naj", self.table.f[rows], t["wlamQ"]
        ) - np.einsum("nqa,nq,qj->naj", v, self.table.k[rows], t["wQ"])
        src = np.zeros_like(R0)
        if self.multiplier == "cells":
            src = g["absdet"][:, None, None] * shares(self.nodal, cell_rule(r), self.sign)[0]
        return R0, src

    @cached_property
    def facet_data(self) -> np.ndarray:
        """Outward-flux data moments of each vertex's share, ∫_F ψ_a (t + λ̃_F) q_k (λ̃ on Γ_C),
        in the global facet basis: (n, d+1 facets, d+1 vertices a, nf)."""
        r = self.ref
        rows = self.rows
        x = self.table.x[rows]
        kind = self.table.kind[rows]
        D = r.d + 1
        size = np.empty((len(rows), D))
        for j in range(D):
            E = x[:, [v for v in range(D) if v != j]]
            E = E[:, 1:] - E[:, :1]
            # |F| / |F̂|
            size[:, j] = np.sqrt(np.abs(np.linalg.det(np.einsum("nad,nbd->nab", E, E))))
        factor = size * ((kind == FLUX) | (kind == CONTACT))
        base = np.einsum("q,jqa,kq->jakq", r.wS, r.lamF, r.q)  # (D, D, nf, nqf)
        data = np.einsum("nj,jakq,njq->njak", factor, base, self.table.t[rows])
        if self.multiplier == "facets":
            given = self.table.cmom[rows] if self.table.cmom.ndim == 4 else None
            for j in range(D):
                on = np.flatnonzero(kind[:, j] == CONTACT)
                mom = (
                    given[on, j]
                    if given is not None
                    else shares(self.nodal[on], facet_rule(r, j), self.sign)[0]
                )
                data[on, j] += size[on, j][:, None, None] * mom
        P = r.P[self.perm]  # (n, D, nf, nf): m_glob = Pᵀ m_loc
        return np.einsum("njkl,njak->njal", P, data)


def lowest_tables(r: Reference) -> dict:
    """The reference integrals of the lowest-order target (:meth:`CellOperators._lowest_load`,
    ``LOWEST`` in ``kernels/eqlb.c``): IZ[i, z] = ∫_T̂ (φ̂Z)_i and
    EZ[a, i, j, z] = ∫_T̂ (x̂ − x̂_a)_i (φ̂Z)_j."""
    phiZ = np.einsum("qmd,mz->qdz", r.phi, r.Z)
    verts = np.vstack([np.zeros(r.d), np.eye(r.d)])
    rel = r.X[None, :, :] - verts[:, None, :]  # (D, nq, d)
    return {
        "IZ": np.einsum("q,qiz->iz", r.w, phiZ),
        "EZ": np.einsum("q,aqi,qjz->aijz", r.w, rel, phiZ),
    }


def projected_mass(r: Reference, which: str) -> np.ndarray:
    """The reference mass tensor between the Z basis (left) and the Z basis (``"ZZ"``) or the
    R basis (``"ZR"``) on the right: Σ_mn Z_ma M_ijmn B_nb with B = Z or R."""
    right = r.Z if which == "ZZ" else r.R
    return np.einsum("ma,ijmn,nb->ijab", r.Z, r.mass, right)


def data_tables(r: Reference, nu: int) -> dict:
    """Reference integrals of the data terms (P_p Lagrange basis of u_h at the points)."""
    import basix

    from .reference import CELLS

    lag = basix.create_element(
        basix.ElementFamily.P, CELLS[r.d], r.pu, basix.LagrangeVariant.gll_warped
    )
    assert lag.dim == nu
    dphi_u = np.moveaxis(np.asarray(lag.tabulate(1, r.X))[1:, :, :, 0], 0, -1)  # (nq, nu, d)
    phiZ = np.einsum("qmd,mz->qzd", r.phi, r.Z)
    return {
        "dphi_u": dphi_u,
        "ZG": np.einsum("q,qa,qzd->qdaz", r.w, r.lam, phiZ),
        "wlamQ": np.einsum("q,qa,jq->qaj", r.w, r.lam, r.Q),
        "wQ": np.einsum("q,jq->qj", r.w, r.Q),
    }


def facet_rule(r: Reference, j: int):
    """The contact-entity rule (:mod:`.multiplier`) of the cell's facet j."""
    return _entity(r.d, r.p, r.pu, j)


def cell_rule(r: Reference):
    """The contact-entity rule of the cell itself (the obstacle)."""
    return _entity(r.d, r.p, r.pu, None)


@functools.cache
def _entity(d: int, p: int, pu: int, j: int | None):
    r = reference(d, p, pu)
    if j is None:
        return entity_rule(d, pu, r.X, r.w, r.Q, np.arange(d + 1))
    return entity_rule(d, pu, r.XF[j], r.wS, r.q, np.array([v for v in range(d + 1) if v != j]))
