"""The guaranteed bound of an hp solution (docs/theory.md §9, §11).

The equilibrated flux of :mod:`contact.adaptivity.equilibration` with two hp pieces:

* **the multiplier** (:class:`HPMultiplier`).  On a contact facet E of degree p_E the
  solver's multiplier is nodal at the Lagrange nodes z_i of degree p_E (:mod:`.problem`):
  R_i = w_i λ_i with w_i = Σ_E W_i^E, W_i^E = ∫_E ψ_i.  The patch of vertex a must carry
  R(ψ_a) = Σ_E m_a^E with m_a^E = Σ_{i ∈ E} W_i^E ψ_a(z_i) λ_i (the hat ψ_a ∈ V_hp is a
  combination of the hp basis functions, with the coefficients ψ_a(z_i) on the edges).  The
  flux's normal trace is λ̃_E = κ_E B⁻(λ_h|_E): λ_h's Bernstein coefficients of degree p_E
  on E with the wrong-signed ones dropped (so σλ̃_E ≤ 0 pointwise) and κ_E restoring the
  total Σ_i W_i^E λ_i; vertex a's share is ψ_a λ̃_E + (m_a^E − ∫_E ψ_a λ̃_E) b_E / ∫_E b_E
  (b_E the facet bubble), exactly as :mod:`contact.adaptivity.equilibration.multiplier`
  does for P1 and P2, now for every degree.
* **the feasibility lifting** (:func:`hp_lifting`).  u_h − g_h has degree ≤ p_max on a
  contact facet; w ∈ V takes there the Bernstein coefficients max(c_β, 0) of u_h − g_h
  (degree p_max), so w ≥ max(u_h − g_h, 0) pointwise, and 0 at every other DoF.

The flux itself lives in RT_q with q = p + 1 on every patch, p the degree of the space's
Lagrange space V (the largest p_T of the level, or p_max): it contains RT_{p_a + 1}, the patch
degree of Braess, Pillwein & Schöberl (2009) and Ern & Vohralík (2015) that makes the bound
robust in p, so its effectivity is at most theirs; the price is the cost of the level's
largest degree on every patch.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from dolfinx import fem

from ..adaptivity.equilibration.bound import Bound, guaranteed_bound
from ..adaptivity.equilibration.cells import CONTACT
from ..adaptivity.equilibration.multiplier import clipped
from ..adaptivity.equilibration.reference import Reference
from ..models.discrete import Problem
from ..setup.scene import Scene
from ..solvers import Result
from .reference import lagrange
from .space import HPSpace

#: the flux degree above p_max
EXTRA = 1


@functools.cache
def _bernstein(d: int, p: int, j: int, points: tuple) -> np.ndarray:
    """Bernstein polynomials of degree p on facet j of the reference d-simplex at reference
    ``points`` (a tuple of tuples, for the cache): (n_points, n_bernstein), in the facet's
    barycentric coordinates (its vertices: the cell's others than j, in order)."""
    X = np.asarray(points)
    lam = np.column_stack([1.0 - X.sum(axis=1), X])[:, [v for v in range(d + 1) if v != j]]
    out = []
    for alpha in _multi_indices(d, p):
        coef = math.factorial(p) / np.prod([math.factorial(a) for a in alpha])
        out.append(coef * np.prod(lam ** np.asarray(alpha)[None, :], axis=1))
    return np.column_stack(out)


def _multi_indices(d: int, p: int) -> list[tuple[int, ...]]:
    """Exponents (d of them, summing to p) of the Bernstein polynomials on a (d−1)-simplex."""
    if d == 1:
        return [(p,)]
    return [(i, *rest) for i in range(p, -1, -1) for rest in _multi_indices(d - 1, p - i)]


@functools.cache
def _facet_nodes(d: int, p: int, j: int) -> tuple[np.ndarray, np.ndarray]:
    """The Lagrange nodes of degree p on the closure of facet j of the reference cell: their
    indices in the cell element of degree p and their reference coordinates."""
    el = lagrange(d, p)
    ids = np.asarray(el.entity_closure_dofs[d - 1][j])
    return ids, np.asarray(el.points)[ids]


def _bernstein_coefficients(d: int, p: int, j: int, values: np.ndarray) -> np.ndarray:
    """Bernstein coefficients (n, n_b) of the polynomials of degree p on facet j with the
    given ``values`` (n, n_nodes) at the Lagrange nodes of :func:`_facet_nodes`."""
    _, pts = _facet_nodes(d, p, j)
    B = _bernstein(d, p, j, tuple(map(tuple, pts)))
    return np.linalg.solve(B, values.T).T


class HPMultiplier:
    """The multiplier rule of an hp solve (module docstring): ``moments`` for the patches
    and ``function`` (λ̃_h on Γ_C, a DG function) for the bound."""

    def __init__(self, result: Result, space: HPSpace, sign: float):
        self.result, self.space, self.sign = result, space, sign
        self.lam_tilde: list = []  # per (facet j, degree): (cells, Bernstein coefficients)

    def _facet_degrees(self, cells: np.ndarray) -> np.ndarray:
        """(n, d+1) the degree of each facet of the cells (from the space)."""
        msh, d = self.space.mesh, self.space.tdim
        c2f = msh.topology.connectivity(d, d - 1).array.reshape(-1, d + 1)
        return self.space.entity_degrees[d - 2][c2f[cells]]

    def moments(self, cells: np.ndarray, kind: np.ndarray, ref: Reference) -> np.ndarray:
        """(n, d+1, d+1, nf): the share of each vertex on each contact facet of the owned
        ``cells`` against the flux's facet basis q̂_k, per reference measure."""
        d, D = ref.d, ref.d + 1
        out = np.zeros((len(cells), D, D, ref.nf))
        lmbda = self.result.lmbda_h
        V = lmbda.function_space
        top = lagrange(d, self.space.p_max)
        fdeg = self._facet_degrees(cells)
        self.lam_tilde = []
        for j in range(D):
            verts = [v for v in range(D) if v != j]
            for p in np.unique(fdeg[kind[:, j] == CONTACT]):
                rows = np.flatnonzero((kind[:, j] == CONTACT) & (fdeg[:, j] == p))
                ids, pts = _facet_nodes(d, int(p), j)
                phi_top = np.asarray(top.tabulate(0, pts))[0, :, :, 0]  # (nodes, n_pmax)
                nodal = clipped(lmbda.x.array[V.dofmap.list[cells[rows]]] @ phi_top.T, self.sign)
                # ∫_F̂ ℓ_i and the hats at the nodes
                el = lagrange(d, int(p))
                ell = np.asarray(el.tabulate(0, ref.XF[j]))[0, :, ids, 0].T  # (nqf, nodes)
                W = ref.wS @ ell
                hat = np.column_stack([1.0 - pts.sum(axis=1), pts])  # (nodes, D)
                m = (nodal * W[None]) @ hat  # (n, D)
                total = nodal @ W
                c = _bernstein_coefficients(d, int(p), j, nodal)
                c = np.where(self.sign * c < 0, 0.0, c)  # the wrong-signed ones dropped
                Bq = _bernstein(d, int(p), j, tuple(map(tuple, ref.XF[j])))  # (nqf, nb)
                lt = c @ Bq.T  # (n, nqf)
                integral = lt @ ref.wS
                tiny = 1e-14 * (np.abs(nodal) @ W) + 1e-300
                kappa = np.where(
                    np.abs(integral) > tiny, total / np.where(integral == 0, 1, integral), 1.0
                )
                lt *= kappa[:, None]
                self.lam_tilde.append((j, int(p), cells[rows], c * kappa[:, None]))
                lamq = ref.lamF[j]  # (nqf, D)
                own = lt @ (ref.wS[:, None] * lamq)  # ∫ ψ_a λ̃
                g = m - own
                bubble = np.prod(lamq[:, verts], axis=1)
                bub_mom = ref.q @ (ref.wS * bubble) / (ref.wS @ bubble)
                out[rows, j] = (
                    np.einsum("kq,q,qa,nq->nak", ref.q, ref.wS, lamq, lt)
                    + g[:, :, None] * bub_mom[None, None]
                )
        return out

    def function(self) -> fem.Function:
        """λ̃_h as a discontinuous Lagrange function of degree p_max whose trace on each
        contact facet is λ̃_E (a cell with two contact facets: at their common nodes the
        value of larger modulus, an upper bound of |λ̃_h|)."""
        space = self.space
        d = space.tdim
        W = fem.functionspace(space.mesh, ("DG", space.p_max))
        fn = fem.Function(W, name="lambda_tilde")
        # a discontinuous Lagrange element keeps the points (and order) of the continuous one
        assert np.allclose(W.element.basix_element.points, lagrange(d, space.p_max).points)
        for j, p, cells, coef in self.lam_tilde:
            ids, pts = _facet_nodes(d, space.p_max, j)
            vals = coef @ _bernstein(d, p, j, tuple(map(tuple, pts))).T  # (n, nodes)
            dofs = W.dofmap.list[cells][:, ids]
            old = fn.x.array[dofs]
            fn.x.array[dofs] = np.where(np.abs(vals) >= np.abs(old), vals, old)
        fn.x.scatter_forward()
        return fn


def hp_lifting(scene: Scene, result: Result, space: HPSpace) -> fem.Function:
    """w ∈ V of the module docstring: on each contact facet the Bernstein coefficients of
    degree p_max of max(u_h − g_h, 0) coefficientwise, 0 at the other DoFs and on Γ_D."""
    msh, d = space.mesh, space.tdim
    V = space.V
    u_h, g_h = result.u_h, result.problem.data.g_h
    assert g_h is not None  # the bound of the hp problem
    w = fem.Function(V, name="w")
    facets = scene.boundary.facets("contact")
    msh.topology.create_connectivity(d - 1, d)
    f2c = msh.topology.connectivity(d - 1, d)
    c2f = msh.topology.connectivity(d, d - 1).array.reshape(-1, d + 1)
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
    local = np.argmax(c2f[cells] == facets[:, None], axis=1) if len(facets) else np.zeros(0, int)
    p = space.p_max
    for j in range(d + 1):
        rows = np.flatnonzero(local == j)
        if not len(rows):
            continue
        ids, _ = _facet_nodes(d, p, j)
        dofs = V.dofmap.list[cells[rows]][:, ids]
        diff = u_h.x.array[dofs] - g_h.x.array[dofs]
        c = np.maximum(_bernstein_coefficients(d, p, j, diff), 0.0)
        _, pts = _facet_nodes(d, p, j)
        w.x.array[dofs] = c @ _bernstein(d, p, j, tuple(map(tuple, pts))).T
    dirichlet = fem.locate_dofs_topological(V, d - 1, scene.boundary.facets("dirichlet"))
    w.x.array[dirichlet] = 0.0
    w.x.scatter_forward()
    return w


def hp_bound(scene: Scene, result: Result, space: HPSpace, extra: int = EXTRA) -> Bound:
    """The guaranteed bound ‖u − u_h‖_E ≤ η of an hp solve (module docstring; the theorem:
    :mod:`contact.adaptivity.equilibration.bound`).  Collective."""
    rule = HPMultiplier(result, space, sign=-1.0)
    lifting = hp_lifting(scene, result, space)
    problem = result.problem
    assert isinstance(problem, Problem)  # hp_problem's, with its physics and condition
    return guaranteed_bound(
        problem, result, degree=space.p_max + extra, lifting=lifting, multiplier_rule=rule
    )
