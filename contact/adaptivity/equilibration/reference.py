"""Reference-cell tables of the flux reconstruction: everything that does not depend on the
physical cell, computed once per (simplex dimension d, polynomial degree p) with basix.

The flux lives in the Raviart–Thomas space RT_p (normal traces in P_p, divergence in P_p;
basix ``RT`` of degree p + 1, Legendre variant) mapped by the contravariant Piola map
σ = J σ̂ / det J; the divergence constraint is tested with P_p (basix's orthonormal Legendre
polynomials Q̂_j on the reference cell) and the normal fluxes on a facet with P_p(F) (the
orthonormal polynomials q̂_k of the reference facet simplex, in barycentric coordinates of
the facet's vertices).

The tables split RT_p into a right inverse R̂ of the divergence and its kernel Z:
B̂ R̂ = I and B̂ Z = 0 with B̂_jl = ∫_T̂ div̂ φ̂_l Q̂_j, so a flux with prescribed divergence
moments β is R̂ β + Z γ and only γ (dimension m − dim P_p) is free in a cell.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass

import basix
import numpy as np

CELLS = {2: basix.CellType.triangle, 3: basix.CellType.tetrahedron}
FACETS = {2: basix.CellType.interval, 3: basix.CellType.triangle}


@dataclass(frozen=True)
class Reference:
    """Reference tables for dimension ``d`` and flux degree ``p`` (σ_h ∈ RT_p) of a solution
    u_h ∈ P_pu (``pu`` = p; p + 1: the lowest-order flux of a P1 solution; pu < p: a flux
    richer than u_h, as hp's patch degree p_a + 1)."""

    d: int
    p: int
    # cell quadrature (points (nq, d), weights (nq,)) and facet-simplex quadrature
    X: np.ndarray
    w: np.ndarray
    S: np.ndarray  # facet-simplex points (nqf, d - 1)
    wS: np.ndarray
    XF: np.ndarray  # the facet points mapped into the reference cell, (d + 1, nqf, d)
    # RT_p: values (nq, m, d) and the divergence split
    phi: np.ndarray
    R: np.ndarray  # (m, np) right inverse of the divergence moments
    Z: np.ndarray  # (m, mz) kernel of the divergence moments
    mass: np.ndarray  # (d, d, m, m): mass[i, j] = ∫ φ̂_·,i φ̂_·,j
    N: np.ndarray  # (d + 1, nf, m) outward normal moments ∫_F̂ φ̂·n̂ q̂_k dS
    Q: np.ndarray  # (np, nq) orthonormal P_p on the cell at the points
    q: np.ndarray  # (nf, nqf) orthonormal P_p on the facet simplex at its points
    lam: np.ndarray  # (nq, d + 1) barycentric coordinates (the hats ψ_a) at the points
    lamF: np.ndarray  # (d + 1, nqf, d + 1) the same at the facet points of each facet
    facet_area: np.ndarray  # (d + 1,) |F̂_j| / |facet simplex|
    dlam: np.ndarray  # (d + 1, d) reference gradients of the hats
    perms: tuple  # the d! orders of a facet's vertices
    P: np.ndarray  # (d!, nf, nf) q̂(local order) = P q̂(global order)
    kappa: np.ndarray  # (nf,) the constant function 1 in the facet basis
    pu: int  # the degree of u_h (and of the multiplier λ_h)

    @property
    def lowest(self) -> bool:
        """The lowest-order flux of a P1 solution (σ_h ∈ RT_0 for u_h ∈ P1)."""
        return self.p < self.pu

    @property
    def m(self) -> int:
        return self.phi.shape[1]

    @property
    def nf(self) -> int:
        return self.q.shape[0]

    @property
    def np_(self) -> int:
        return self.Q.shape[0]


def quadrature_degree(p: int) -> int:
    """Degree 2p + 4: exact for the RT mass (2p + 2) and the weighted data moments of data in
    P_{p+2} (f ψ_a Q̂_j: p + 3 + p)."""
    return 2 * p + 4


@functools.cache
def reference(d: int, p: int, pu: int | None = None) -> Reference:
    """The tables of RT_p on the reference d-simplex for u_h ∈ P_pu (default pu = p)."""
    pu = p if pu is None else pu
    if not 1 <= pu <= p + 1:
        raise ValueError(
            f"flux degree {p} for u_h of degree {pu}: expected {pu - 1} or more (hp: the "
            "flux of a patch may be of higher degree than u_h)"
        )
    cell, facet = CELLS[d], FACETS[d]
    deg = quadrature_degree(p)
    X, w = (np.asarray(a) for a in basix.make_quadrature(cell, deg))
    S, wS = (np.asarray(a) for a in basix.make_quadrature(facet, deg))
    verts = np.asarray(basix.geometry(cell))
    facets = basix.topology(cell)[d - 1]  # facet j: the sorted vertices other than j
    bary_S = np.column_stack([1.0 - S.sum(axis=1), S])  # (nqf, d): barycentrics on the facet
    XF = np.array([bary_S @ verts[f] for f in facets])  # (d + 1, nqf, d)
    normals = np.asarray(basix.cell.facet_outward_normals(cell))
    facet_area = np.array([_simplex_volume(verts[f]) for f in facets]) / _simplex_volume(
        basix.geometry(facet)
    )

    rt = basix.create_element(basix.ElementFamily.RT, cell, p + 1, basix.LagrangeVariant.legendre)
    tab = np.asarray(rt.tabulate(1, X))  # (1 + d, nq, m, d)
    phi = tab[0]
    div = sum(tab[1 + i][:, :, i] for i in range(d))  # (nq, m)
    Q = np.asarray(basix.tabulate_polynomials(basix.PolynomialType.legendre, cell, p, X))
    q = np.asarray(basix.tabulate_polynomials(basix.PolynomialType.legendre, facet, p, S))
    B = np.einsum("q,jq,ql->jl", w, Q, div)
    R = np.linalg.pinv(B)  # B R = I (B has full row rank)
    Z = _kernel(B)
    mass = np.einsum("q,qli,qmj->ijlm", w, phi, phi)
    N = np.empty((d + 1, q.shape[0], phi.shape[1]))
    for j in range(d + 1):
        vals = np.asarray(rt.tabulate(0, XF[j]))[0] @ normals[j]  # (nqf, m)
        N[j] = facet_area[j] * np.einsum("q,kq,ql->kl", wS, q, vals)
    lam = _barycentric(X)
    lamF = np.array([_barycentric(XF[j]) for j in range(d + 1)])
    dlam = np.vstack([-np.ones(d), np.eye(d)])
    perms = tuple(itertools.permutations(range(d)))
    P = np.array([_facet_permutation(facet, S, wS, bary_S, pi, p) for pi in perms])
    kappa = np.einsum("q,kq->k", wS, q)
    return Reference(
        d,
        p,
        X,
        w,
        S,
        wS,
        XF,
        phi,
        R,
        Z,
        mass,
        N,
        Q,
        q,
        lam,
        lamF,
        facet_area,
        dlam,
        perms,
        P,
        kappa,
        pu,
    )


def _simplex_volume(v: np.ndarray) -> float:
    E = (v[1:] - v[0]).T
    return float(np.sqrt(abs(np.linalg.det(E.T @ E))) / np.prod(np.arange(1, E.shape[1] + 1)))


def _barycentric(X: np.ndarray) -> np.ndarray:
    return np.column_stack([1.0 - X.sum(axis=1), X])


def _kernel(B: np.ndarray) -> np.ndarray:
    _, s, Vt = np.linalg.svd(B)
    rank = int(np.sum(s > s[0] * 1e-12))
    return Vt[rank:].T.copy()


def _facet_permutation(facet, S, wS, bary_S, pi, p) -> np.ndarray:
    """P[k, l] = ∫ q̂_k(ŝ) q̂_l(ŝ') dŝ, where ŝ' is the same point in the facet coordinates of
    the vertices reordered so that local vertex r sits at position pi[r]: the local basis
    function q̂_k is Σ_l P[k, l] (q̂_l in the global order) (P is orthogonal)."""
    ref = np.asarray(basix.geometry(facet))  # (d, d - 1) vertices of the facet simplex
    bary_global = np.empty_like(bary_S)
    bary_global[:, list(pi)] = bary_S
    S_global = bary_global @ ref
    q_loc = np.asarray(basix.tabulate_polynomials(basix.PolynomialType.legendre, facet, p, S))
    q_glob = np.asarray(
        basix.tabulate_polynomials(basix.PolynomialType.legendre, facet, p, S_global)
    )
    return np.einsum("q,kq,lq->kl", wS, q_loc, q_glob)
