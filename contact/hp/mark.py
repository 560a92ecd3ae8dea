"""hp marking (docs/theory.md §11): Dörfler's bulk criterion chooses the cells, then each
chosen cell is refined in h or in p.

* Cells touching the free boundary — a vertex of Γ_C around which the solver's contact
  nodes are both active and inactive — are h-refined, and kept at degree 1, or at the
  first level's degree if that is higher (the solution is only H^{5/2−ε} across the free
  boundary: h is the right tool there).
* Every other marked cell is p-refined if u_h looks analytic on it: with u_h|_T expanded in
  the L²(T̂)-orthonormal Dubiner basis of the reference cell (basix's Legendre polynomials,
  ordered by degree) and a_k the norm of its coefficients of degree k, the least-squares
  slope −σ_T of log a_k over k = 1 … p_T measures their decay; σ_T ≥ σ₀ means faster
  than e^{−σ₀ k}: p-refine (Houston & Süli 2005; Mavriplis 1994; Eibner & Melenk 2007).
  Slower decay, or p_T = p_max: h-refine.  Coefficients below 1e-12 of a_1 count as zero
  (u_h is a polynomial of lower degree there: analytic).  A cell of degree 1 away from
  the free boundary (it was at degree 1 because the free boundary was there) has one
  degree only and is p-refined.
* Refinement: an h-refined cell's children keep its degree, a p-refined cell gets
  p_T + 1 (:func:`child_degrees`); no p-coarsening but at the free boundary.

Every decision is a function of the cell's own data, and the Dörfler threshold is global:
the same marks on any number of ranks.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import basix
import numpy as np
from dolfinx import fem, la
from dolfinx import mesh as dmesh

from ..adaptivity.transfer import transfer_cell_tags
from .reference import CELLS, lagrange

#: the decay rate σ₀ above which a cell is p-refined (a_k ≈ e^{−σ k}): measured on problems
#: A and C (demos/RESULTS.md, hp)
SIGMA0 = 1.0
#: coefficients below this fraction of a_1 are zero
ZERO = 1e-12


@dataclass
class HPMarks:
    """The decisions of one MARK step.

    Attributes:
        h: Owned cells to refine in h (int32).
        p: Owned cells whose degree goes up by one.
        degrees: The owned cells' degrees after the decisions (before h-refinement: the
            children inherit them).
        front: Owned cells touching the free boundary.
        sigma: σ_T of the owned cells (inf where every coefficient beyond a_1 vanishes,
            nan for degree 1).
    """

    h: np.ndarray
    p: np.ndarray
    degrees: np.ndarray
    front: np.ndarray
    sigma: np.ndarray


@functools.cache
def _dubiner(d: int, p_max: int) -> tuple[np.ndarray, np.ndarray]:
    """The projection of P_{p_max} Lagrange coefficients onto the orthonormal polynomials
    (n_pmax → n_pmax) and the degree of each orthonormal polynomial."""
    cell = CELLS[d]
    X, w = (np.asarray(a) for a in basix.make_quadrature(cell, 2 * p_max))
    P = np.asarray(basix.tabulate_polynomials(basix.PolynomialType.legendre, cell, p_max, X))
    phi = np.asarray(lagrange(d, p_max).tabulate(0, X))[0, :, :, 0]
    project = (P * w[None, :]) @ phi  # (n_poly, n_pmax)
    degree = np.zeros(P.shape[0], dtype=int)
    for k in range(1, p_max + 1):
        degree[math.comb(k - 1 + d, d) : math.comb(k + d, d)] = k
    return project, degree


def decay_rates(u_h: fem.Function, degrees: np.ndarray) -> np.ndarray:
    """σ_T of the owned cells (module docstring): the decay rate of u_h's orthonormal
    coefficients by degree, nan for p_T = 1; for a vector u_h, a_k sums the squares of
    every component's coefficients of degree k."""
    V = u_h.function_space
    d = V.mesh.topology.dim
    bs = V.dofmap.index_map_bs
    p_max = V.element.basix_element.degree
    n = len(degrees)
    project, degree = _dubiner(d, p_max)
    values = u_h.x.array.reshape(-1, bs)[V.dofmap.list[:n]]  # (n, n_pmax, bs)
    coef = np.einsum("pj,njc->npc", project, values)  # (n, n_poly, bs)
    a = np.sqrt(
        np.stack([np.sum(coef[:, degree == k] ** 2, axis=(1, 2)) for k in range(p_max + 1)], 1)
    )
    sigma = np.full(n, np.nan)
    for p in range(2, p_max + 1):
        rows = np.flatnonzero(degrees == p)
        if len(rows) == 0:
            continue
        ak = a[rows, 1 : p + 1]
        floor = ZERO * np.maximum(ak[:, :1], 1e-300)
        zero = ak <= floor
        logs = np.log(np.maximum(ak, floor))
        k = np.arange(1, p + 1, dtype=float)
        kc = k - k.mean()
        slope = (logs - logs.mean(axis=1, keepdims=True)) @ kc / (kc @ kc)
        s = -slope
        s[np.all(zero[:, 1:], axis=1)] = np.inf
        sigma[rows] = s
    return sigma


def front_cells(problem, active_mask: np.ndarray, contact_facets: np.ndarray) -> np.ndarray:
    """The owned cells with a vertex on the free boundary: a vertex of Γ_C whose contact
    facets carry both active and inactive constrained nodes (``active_mask``: the
    solver's, over ``problem.constraint.dofs``).  Collective."""
    V = problem.V
    msh = V.mesh
    tdim = msh.topology.dim
    con = problem.constraint
    status = la.vector(V.dofmap.index_map)  # per node: 1 inactive, 2 active, 0 unconstrained
    status.array[con.dofs // V.dofmap.index_map_bs] = np.where(active_mask, 2.0, 1.0)
    status.scatter_forward()
    msh.topology.create_connectivity(tdim - 1, tdim)
    msh.topology.create_connectivity(tdim, tdim - 1)
    msh.topology.create_connectivity(tdim - 1, 0)
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    c2f = msh.topology.connectivity(tdim, tdim - 1).array.reshape(-1, tdim + 1)
    layout = V.dofmap.dof_layout
    closure = [layout.entity_closure_dofs(tdim - 1, j) for j in range(tdim + 1)]
    vmap = msh.topology.index_map(0)
    seen = la.vector(vmap, dtype=np.int32)  # bit 1: inactive seen, bit 2: active seen
    inactive = np.zeros(vmap.size_local + vmap.num_ghosts, dtype=np.int32)
    active = np.zeros_like(inactive)
    f2v = msh.topology.connectivity(tdim - 1, 0)
    for f in np.asarray(contact_facets, dtype=np.int32):
        c = f2c.links(f)[0]
        j = int(np.flatnonzero(c2f[c] == f)[0])
        vals = status.array[V.dofmap.cell_dofs(c)[closure[j]]]
        verts = f2v.links(f)
        inactive[verts] += int(np.any(vals == 1.0))
        active[verts] += int(np.any(vals == 2.0))
    for arr in (inactive, active):
        seen.array[:] = arr
        seen.scatter_reverse(la.InsertMode.add)
        seen.scatter_forward()
        arr[:] = seen.array
    front = np.flatnonzero((inactive > 0) & (active > 0)).astype(np.int32)
    msh.topology.create_connectivity(0, tdim)
    cells = dmesh.compute_incident_entities(msh.topology, front, 0, tdim)
    n_owned = msh.topology.index_map(tdim).size_local
    return np.unique(cells[cells < n_owned]).astype(np.int32)


def hp_mark(
    marked: np.ndarray,
    degrees: np.ndarray,
    sigma: np.ndarray,
    front: np.ndarray,
    p_max: int,
    sigma0: float = SIGMA0,
    front_degree: int | None = 1,
    refine_front: bool = True,
) -> HPMarks:
    """Split the Dörfler-marked owned cells ``marked`` into h and p (module docstring) and
    return the new degrees; ``front_degree``: the largest degree of the free boundary's
    cells (higher ones are lowered to it; None: they keep theirs); ``refine_front``:
    h-refine them on every level, marked or not (a geometric mesh towards the free
    boundary)."""
    degrees = np.asarray(degrees, dtype=np.int32).copy()
    at_front = np.zeros(len(degrees), dtype=bool)
    at_front[front] = True
    smooth = (degrees == 1) | (sigma >= sigma0)
    choose_p = np.zeros(len(degrees), dtype=bool)
    choose_p[marked] = True
    choose_p &= smooth & ~at_front & (degrees < p_max)
    is_marked = np.zeros(len(degrees), dtype=bool)
    is_marked[marked] = True
    if refine_front:
        is_marked |= at_front
    h = np.flatnonzero(is_marked & ~choose_p).astype(np.int32)
    p = np.flatnonzero(choose_p).astype(np.int32)
    degrees[p] += 1
    if front_degree is not None:
        degrees[at_front] = np.minimum(degrees[at_front], front_degree)
    return HPMarks(h, p, degrees, np.asarray(front, dtype=np.int32), sigma)


def child_degrees(degrees: np.ndarray, old: dmesh.Mesh, new: dmesh.Mesh, parent_cell) -> np.ndarray:
    """The owned cells' degrees on the refined mesh ``new``: each child inherits its parent's
    (``degrees``: of the owned cells of ``old``; collective)."""
    tdim = old.topology.dim
    cmap = old.topology.index_map(tdim)
    full = la.vector(cmap, dtype=np.int32)
    full.array[: cmap.size_local] = degrees
    full.scatter_forward()
    n = cmap.size_local + cmap.num_ghosts
    tags = dmesh.meshtags(old, tdim, np.arange(n, dtype=np.int32), full.array[:n])
    child = transfer_cell_tags(tags, new, parent_cell)
    n_new = new.topology.index_map(tdim).size_local
    out = np.empty(n_new, dtype=np.int32)
    out[child.indices[child.indices < n_new]] = child.values[child.indices < n_new]
    return out
