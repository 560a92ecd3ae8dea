"""The discrete multiplier the flux carries, and how the vertex patches share it.

The solver's multiplier λ_h ∈ P_p has nodal values λ_i = R_i / w_i: the residual of the
discrete equation at node i over the lumped weight w_i = ∫ φ_i (Γ_C for Signorini, Ω for
the obstacle; docs/theory.md §2).  With ψ_a the P1 hat of vertex a (ψ_a = Σ_i ψ_a(x_i) φ_i in P_p)
the patch of a must carry R(ψ_a) = Σ_i ψ_a(x_i) w_i λ_i, and on each contact entity E (a
Γ_C facet, or a cell for the obstacle) its part

    m_a^E = Σ_{i ∈ E} w_i^E ψ_a(x_i) λ_i,        w_i^E = ∫_E φ_i,

the lumped quadrature of ∫_E ψ_a λ_h (exact for P2 on segments: Simpson's rule; for P1 it
is the trapezoidal / vertex rule).  The flux's normal trace (Signorini) or source (obstacle)
on E is

    λ̃_E = κ_E B⁻(λ_h|_E),

where B⁻ drops the Bernstein coefficients of the wrong sign (P1: none, the nodal values
carry the sign; P2: the edge coefficient 2λ_m − (λ_a + λ_b)/2 where it has the wrong sign,
i.e. where λ_h changes sign between its nodes, near the free boundary) and κ_E ≥ 0 restores
the total ∫_E λ̃_E = Σ_a m_a^E.  So σλ̃_E ≤ 0 pointwise, λ̃_E ∈ P_p(E), and λ̃_E = λ_h where λ_h
has the right sign.  The patch of a receives the share

    ψ_a λ̃_E + g_a^E b_E / ∫_E b_E,      g_a^E = m_a^E − ∫_E ψ_a λ̃_E,

b_E the bubble Π_{v ∈ E} ψ_v: its integral is m_a^E (so every patch balances), and the
shares add up to λ̃_E (Σ_a g_a^E = 0).  For P2 on a segment with λ_h of one sign g = 0: the
share is ψ_a λ_h, which is what the target ψ_a k∇u_h·n carries; a share c_a ψ_a built from a
lumped value alone (the obvious choice) would leave each patch an O(h λ') imbalance its
flux carries sideways, an O(h) error that costs P2 a factor 4 in the effectivity.
Nodal values of the wrong sign (round-off at inactive nodes) are clipped first.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import basix
import numpy as np

from ...models.problem import ISO_P2_FRACTIONS
from .reference import CELLS

#: P1's moments (:func:`shares`) by ``np.einsum`` in one thread; False: the BLAS product, the
#: plain path (the same numbers to round-off)
EINSUM = True


@dataclass(frozen=True)
class EntityRule:
    """Reference data of a contact entity (the facet j of the cell, or the cell itself):
    the P_p basis of λ_h at the entity's quadrature points and its lumped weights."""

    phi: np.ndarray  # (nq, nu) Lagrange basis at the points
    lam: np.ndarray  # (nq, D) barycentric coordinates (the hats) at the points
    w: np.ndarray  # (nq,) weights (reference entity measure)
    basis: np.ndarray  # (nk, nq) test polynomials (q̂ on facets, Q̂ on cells)
    W: np.ndarray  # (nu,) ∫ φ_u over the reference entity
    hat: np.ndarray  # (nu, D) ψ_a at the Lagrange nodes
    vertices: np.ndarray  # the entity's vertices (local indices)
    edges: list  # (v0, v1, midpoint DoF) of the entity's edges (P2)

    @cached_property
    def linear(self) -> np.ndarray:
        """(nu, D·nk): the moments of :func:`shares` as a linear map of the nodal values
        where λ̃_E = λ_h (no edges): ∫ ψ_a λ_h b̂_k + (m_a − ∫ ψ_a λ_h) ∫ b̂_k b_E / ∫ b_E."""
        nq, D = self.lam.shape
        table = np.einsum("kq,q,qa->qak", self.basis, self.w, self.lam).reshape(nq, -1)
        g = self.W[:, None] * self.hat - self.phi.T @ (self.w[:, None] * self.lam)  # (nu, D)
        bubble = np.prod(self.lam[:, self.vertices], axis=1)
        bub_mom = self.basis @ (self.w * bubble) / (self.w @ bubble)  # (nk,)
        return self.phi.T @ table + (g[:, :, None] * bub_mom[None, None]).reshape(len(g), -1)


def entity_rule(
    d: int, p: int, points: np.ndarray, w: np.ndarray, basis: np.ndarray, vertices: np.ndarray
) -> EntityRule:
    lag = basix.create_element(basix.ElementFamily.P, CELLS[d], p, basix.LagrangeVariant.gll_warped)
    phi = np.asarray(lag.tabulate(0, points))[0, :, :, 0]
    lam = np.column_stack([1.0 - points.sum(axis=1), points])
    nodes = np.asarray(lag.points)
    hat = np.column_stack([1.0 - nodes.sum(axis=1), nodes])
    edges = []
    if p == 2:
        for e, (v0, v1) in enumerate(basix.topology(CELLS[d])[1]):
            if v0 in vertices and v1 in vertices:
                edges.append((v0, v1, d + 1 + e))
    W = w @ phi
    if p == 2 and len(vertices) > 2:  # a triangle or a tetrahedron: the solve's P1-iso-P2 weights
        vertex, edge = ISO_P2_FRACTIONS[len(vertices) - 1]
        W = np.zeros_like(W)
        W[np.asarray(vertices)] = vertex * w.sum()
        W[[m for _, _, m in edges]] = edge * w.sum()
    return EntityRule(phi, lam, w, basis, W, hat, np.asarray(vertices), edges)


def shares(
    nodal: np.ndarray, rule: EntityRule, sign: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The moments ∫ (ψ_a λ̃_E + g_a b_E/∫b_E) b̂_k of each vertex a against the entity's
    test polynomials, per reference measure: (n, D, nk); and κ_E (n,) and the removed
    Bernstein coefficients β_e (n, edges).  ``nodal``: the clipped nodal values (n, nu).

    Without edge coefficients to remove (P1) λ̃_E = λ_h, κ_E = 1 and the moments are linear
    in the nodal values: one product with :attr:`EntityRule.linear`.  Otherwise an entity
    whose nodal values are all zero (no contact there) has zero moments, κ_E = 1 and β = 0,
    and only the others are computed."""
    n, D = len(nodal), rule.lam.shape[1]
    kappa, beta = np.ones(n), np.zeros((n, len(rule.edges)))
    if not rule.edges:
        # (n, nu) × (nu, D·nk), nu = d + 1: a BLAS product this thin costs its threads'
        # spinning (8-10× the CPU on a shared 2-core machine), einsum loops in one thread
        mom = np.einsum("na,am->nm", nodal, rule.linear) if EINSUM else nodal @ rule.linear
        return mom.reshape(n, D, len(rule.basis)), kappa, beta
    mom = np.zeros((n, D, len(rule.basis)))
    rows = np.flatnonzero(np.any(nodal != 0.0, axis=1))
    if len(rows):
        mom[rows], kappa[rows], beta[rows] = _shares(nodal[rows], rule, sign)
    return mom, kappa, beta


def _shares(
    nodal: np.ndarray, rule: EntityRule, sign: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`shares` of entities with a nonzero nodal value.

    Every product is an ``np.einsum`` loop, not BLAS: a row's result must not depend on how
    many rows are computed together (the bound made a block of cells at a time is the
    bound made at once, bit for bit), and a BLAS product's rounding can depend on the
    number of rows on some CPUs (OpenBLAS kernels and blocking)."""
    lam_q = np.einsum("na,qa->nq", nodal, rule.phi)  # (n, nq)
    beta = np.zeros((len(nodal), len(rule.edges)))
    bminus = lam_q.copy()
    for e, (v0, v1, m) in enumerate(rule.edges):
        coef = 2 * nodal[:, m] - 0.5 * (nodal[:, v0] + nodal[:, v1])
        beta[:, e] = np.where(sign * coef < 0, coef, 0.0)
        bminus -= beta[:, e][:, None] * (2 * rule.lam[:, v0] * rule.lam[:, v1])[None]
    total = np.einsum("na,a->n", nodal, rule.W)
    integral = np.einsum("nq,q->n", bminus, rule.w)
    tiny = 1e-14 * np.einsum("na,a->n", np.abs(nodal), rule.W) + 1e-300
    kappa = np.where(np.abs(integral) > tiny, total / np.where(integral == 0, 1, integral), 1.0)
    lt = kappa[:, None] * bminus  # λ̃_E at the points
    m = np.einsum("na,ad->nd", nodal * rule.W[None], rule.hat)  # m_a (n, D)
    own = np.einsum("nq,qd->nd", lt, rule.w[:, None] * rule.lam)  # ∫ ψ_a λ̃_E
    g = m - own
    bubble = np.prod(rule.lam[:, rule.vertices], axis=1)
    bub_mom = rule.basis @ (rule.w * bubble) / (rule.w @ bubble)  # (nk,)
    nq, D = rule.lam.shape
    # ∫ ψ_a λ̃_E b̂_k by quadrature: one product with the (q, a·k) table
    table = np.einsum("kq,q,qa->qak", rule.basis, rule.w, rule.lam).reshape(nq, -1)
    mom = np.einsum("nq,qm->nm", lt, table).reshape(len(lt), D, -1)
    mom += g[:, :, None] * bub_mom[None, None]
    return mom, kappa, beta


def clipped(nodal: np.ndarray, sign: float) -> np.ndarray:
    """Nodal values with the wrong sign set to 0 (σλ_i ≤ 0 kept)."""
    return sign * np.maximum(sign * nodal, 0.0) if sign else nodal
