"""The hp basis on the reference simplex, one cell configuration at a time.

A cell T of degree p_T whose edges (and faces, 3D) carry the degrees p_e of the minimum
rule (docs/theory.md §11) has, as its share of the basis of V_hp, one function per node of
the Lagrange element of degree p_e on each of its entities e (vertices: degree 1):

* a node z of an edge, face or the cell's interior: φ_z, the Lagrange basis function of
  degree p_e of the whole cell at z (gll_warped points, as DOLFINx's Lagrange spaces).  It
  vanishes on every entity of T that does not contain z (its restriction there is a
  polynomial of degree p_e vanishing at that entity's p_e-lattice), so it is continuous
  across facets and supported on the cells around e;
* a vertex a: v_a = λ_a − Σ_{E ∋ a} Σ_{z ∈ E°} λ_a(z) φ_z (the hat minus its values at the
  interior nodes of the edges at a), whose trace on each edge E is the Lagrange vertex
  function of degree p_E.

Every function is a polynomial of degree ≤ p_T on T, so its Lagrange interpolant of degree
p_max is itself: these values are the local columns of Q (u = Q x).  On every edge the
coefficients are nodal values: x_a = u(a), x_z = u(z) (the vertex functions vanish at the
edge nodes), which keeps the contact constraint at the nodes of Γ_C a bound on one unknown.
The evaluation at the hp nodes, Φ, is unit lower block triangular (vertices and edges,
faces, interior), so x = Φ⁻¹ (u at the hp nodes) is the hp interpolant, and an entity's
coefficients depend only on u on its closure: the same from every cell that shares it.

The nodes of an entity are matched to the DoFs of degree p_max on it (the "slots" of the
unknowns x in V's layout) in a canonical order that depends only on the global vertex
order: by their barycentric coordinates with respect to the entity's vertices sorted by
global index.  Both sides of an edge or face therefore agree on which unknown is which.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import basix
import numpy as np

CELLS = {2: basix.CellType.triangle, 3: basix.CellType.tetrahedron}
#: barycentric coordinates are compared after rounding to this many decimals
ROUND = 9


@functools.cache
def lagrange(d: int, p: int) -> basix.finite_element.FiniteElement:
    """The Lagrange element of degree p on the reference d-simplex (DOLFINx's variant)."""
    return basix.create_element(
        basix.ElementFamily.P, CELLS[d], p, basix.LagrangeVariant.gll_warped
    )


@functools.cache
def lagrange_points(d: int, p: int) -> np.ndarray:
    """(n, 2d + 1): the Lagrange points of degree p (:func:`lagrange`'s order) in the
    first d columns, their barycentric coordinates in the other d + 1; read-only (one array
    shared by every call)."""
    X = np.asarray(lagrange(d, p).points)
    out = np.hstack([X, barycentric(X)])
    out.flags.writeable = False
    return out


def barycentric(X: np.ndarray) -> np.ndarray:
    """(n, d + 1) barycentric coordinates of reference points X (n, d)."""
    return np.column_stack([1.0 - X.sum(axis=1), X])


def entities(d: int) -> list[list[tuple[int, ...]]]:
    """The reference cell's entities by dimension: tuples of their vertices."""
    return [[tuple(int(v) for v in e) for e in ents] for ents in basix.topology(CELLS[d])]


def canonical(points: np.ndarray, vertices: tuple[int, ...], order: tuple[int, ...]) -> np.ndarray:
    """The order of ``points`` (reference coordinates) on an entity with reference
    ``vertices``, sorted by their barycentric coordinates with respect to those vertices in
    increasing global index (``order[v]``: the rank of vertex v among the cell's)."""
    lam = barycentric(points)
    ranked = sorted(vertices, key=lambda v: order[v])
    keys = [np.round(lam[:, v], ROUND) for v in reversed(ranked[1:])]
    return np.lexsort(keys) if keys else np.arange(len(points))


def count(dim: int, p: int) -> int:
    """The interior nodes of an entity of dimension ``dim`` for degree p."""
    if dim == 0:
        return 1
    if dim == 1:
        return max(p - 1, 0)
    if dim == 2:
        return max((p - 1) * (p - 2) // 2, 0)
    return max((p - 1) * (p - 2) * (p - 3) // 6, 0)


@dataclass(frozen=True)
class LocalBasis:
    """A cell configuration's hp basis (n_hp functions) on the reference cell.

    Attributes:
        Q: (n_pmax, n_hp) the functions at the Lagrange points of degree p_max.
        L: (n_hp, n_pmax) the left inverse: the hp interpolant's coefficients of a function
            of degree p_max given by its values at those points (L Q = I).
        Phi_inv: (n_hp, n_hp) the inverse of the functions' values at the hp nodes.
        nodes: (n_hp, d) the hp nodes (reference coordinates), the function's own node.
        slots: (n_hp,) the cell-local DoF of degree p_max each function's unknown sits on.
        dims: (n_hp,) the dimension of the entity each function belongs to.
    """

    Q: np.ndarray
    L: np.ndarray
    Phi_inv: np.ndarray
    nodes: np.ndarray
    slots: np.ndarray
    dims: np.ndarray


@functools.cache
def local_basis(
    d: int, p_max: int, degrees: tuple[tuple[int, ...], ...], order: tuple[int, ...]
) -> LocalBasis:
    """The hp basis of a cell (module docstring).

    Args:
        d: The dimension of the simplex.
        p_max: The degree of the Lagrange space V ⊇ V_hp.
        degrees: Per dimension 1 … d the degrees of the cell's entities of that dimension
            in basix's order (the last one the cell's own p_T).
        order: The rank of each of the cell's vertices in the global vertex order.
    """
    ents = entities(d)
    top = lagrange(d, p_max)
    X = np.asarray(top.points)
    evaluators: list = []  # per function: ('node', p, index) or ('vertex', a, corrections)
    nodes, slots, dims = [], [], []
    for a in range(d + 1):
        corr = []
        for e, edge in enumerate(ents[1]):
            p = degrees[0][e]
            if a in edge and p >= 2:
                el = lagrange(d, p)
                for i in el.entity_dofs[1][e]:
                    corr.append((p, i, lagrange_points(d, p)[i, d + a]))
        evaluators.append(("vertex", a, corr))
        nodes.append(X[top.entity_dofs[0][a][0]])
        slots.append(top.entity_dofs[0][a][0])
        dims.append(0)
    for dim in range(1, d + 1):
        for e, verts in enumerate(ents[dim]):
            p = degrees[dim - 1][e]
            if count(dim, p) == 0:
                continue
            el = lagrange(d, p)
            own = np.asarray(el.entity_dofs[dim][e])
            el_points = lagrange_points(d, p)[:, :d]
            pts = el_points[own]
            cand = np.asarray(top.entity_dofs[dim][e])
            if dim < d:  # shared: the canonical order on both sides
                own = own[canonical(pts, verts, order)]
                cand = cand[canonical(X[cand], verts, order)]
            for k, node in enumerate(own):
                evaluators.append(("node", p, int(node)))
                nodes.append(el_points[node])
                slots.append(int(cand[k]))
                dims.append(dim)
    nodes_arr = np.asarray(nodes)

    def evaluate(Y: np.ndarray) -> np.ndarray:
        lam = barycentric(Y)
        tabs: dict[int, np.ndarray] = {}

        def tab(p: int) -> np.ndarray:
            if p not in tabs:
                tabs[p] = np.asarray(lagrange(d, p).tabulate(0, Y))[0, :, :, 0]
            return tabs[p]

        out = np.empty((len(Y), len(evaluators)))
        for j, ev in enumerate(evaluators):
            if ev[0] == "vertex":
                val = lam[:, ev[1]].copy()
                for p, i, c in ev[2]:
                    val -= c * tab(p)[:, i]
                out[:, j] = val
            else:
                out[:, j] = tab(ev[1])[:, ev[2]]
        return out

    Qloc = evaluate(X)
    Phi = evaluate(nodes_arr)
    E = np.asarray(top.tabulate(0, nodes_arr))[0, :, :, 0]  # (n_hp, n_pmax)
    Phi_inv = np.linalg.inv(Phi)
    return LocalBasis(
        Qloc, Phi_inv @ E, Phi_inv, nodes_arr, np.asarray(slots, np.int64), np.asarray(dims)
    )
