"""The constraint set of a problem's contact conditions (:mod:`.constraints`): what the
conditions make of an assembled system — the nodal complementarity set, the change of basis
that makes each condition a bound on one unknown, the output space of its nodal fields, and
the data its estimators and reports read.  One implementation for every builder: the own-forms
:class:`~contact.models.forms.ComplementarityProblem` and the scene's models build the same
conditions and call :func:`contact_set`.

* one :class:`~.constraints.Unilateral`: its DoFs, weights and bound
  (:meth:`~.constraints.Unilateral.discretise`);
* one :class:`~.constraints.RigidObstacle` (an elastic body): a bound on one component
  against a coordinate plane, the contact nodes rotated to the obstacle's normal otherwise
  (:mod:`.obstacles`), or — ``current``, a finite-strain body where the gap is not affine in
  u — contact on the current configuration;
* :class:`~.constraints.MortarPair` s, with or without a rigid obstacle (several bodies in one
  mesh, docs/theory.md §1.5): the mortar change of basis u = Q x of :mod:`.basis`, every
  slave node's relative displacement in its frame and the obstacle's nodes rotated
  (:func:`mortar_set`; the Dirichlet conditions imposed again on the unknowns).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from ..base import spaces
from ..base.errors import ConfigError
from ..solvers.problem import Constraint, Output, ProblemData
from . import mortar
from .basis import change_of_basis, node_frames
from .constraints import (
    Condition,
    ContactSet,
    MortarPair,
    Plane,
    RigidObstacle,
    Unilateral,
    measure_facets,
)
from .discrete import Problem
from .obstacles import (
    contact_nodes,
    current_contact,
    plane_contact,
    rotated_contact,
)
from .problem import (
    contact_ends,
    coordinate_scale,
    first_contact_point,
    first_contact_row,
    lumped_weights,
)


def contact_set(
    V: fem.FunctionSpace,
    K: PETSc.Mat,
    b: PETSc.Vec,
    bcs: list,
    conditions: Sequence[Condition],
    *,
    current: bool = False,
    u_prev: fem.Function | None = None,
    allow_empty: bool = False,
    coupled_at: np.ndarray | None = None,
) -> ContactSet:
    """The constraint set of ``conditions`` on the space V with the assembled K, b and the
    Dirichlet conditions ``bcs`` (module doc).  ``current``: a finite-strain body meets a
    rigid obstacle on its current configuration wherever the gap is not affine in u (a
    curved surface, or friction); ``u_prev``: the previous load step's displacement
    (friction's slips start there); ``allow_empty``: a unilateral condition may constrain
    no DoF (else a ValueError); ``coupled_at``: mortar pairs coupled on the current
    configuration of these nodal displacements (:func:`mortar_set`).  K and b stay the
    caller's (a change of basis returns new ones).  Conditions of kinds that do not go
    together are a ValueError."""
    conditions = tuple(conditions)
    kinds = {type(c) for c in conditions}
    fixed = np.concatenate([bc.dof_indices()[0] for bc in bcs] or [np.zeros(0, np.int32)])
    if kinds == {Unilateral} and len(conditions) == 1:
        (unilateral,) = conditions
        assert isinstance(unilateral, Unilateral)
        return unilateral.discretise(V, bcs, allow_empty)
    pairs = [c for c in conditions if isinstance(c, MortarPair)]
    rigid = [c for c in conditions if isinstance(c, RigidObstacle)]
    if Unilateral in kinds or len(rigid) > 1 or not conditions:
        raise ValueError(
            "constraints: expected one Unilateral, one RigidObstacle, or MortarPairs with at "
            f"most one RigidObstacle; got {', '.join(type(c).__name__ for c in conditions)}"
        )
    if pairs:
        return mortar_set(V, K, b, bcs, fixed, pairs, rigid[0] if rigid else None, coupled_at)
    (obstacle,) = rigid
    surface = obstacle.surface
    if current and (not isinstance(surface, Plane) or obstacle.friction is not None):
        return current_contact(V, fixed, obstacle, u_prev)
    if isinstance(surface, Plane) and surface.axis() is not None:
        return plane_contact(V, fixed, obstacle)
    return rotated_contact(V, K, b, fixed, obstacle)


@dataclass
class ObstacleNodes:
    """The rigid obstacle's contact nodes beside mortar pairs (owned, constrained), with the
    fields a mortar :class:`~contact.models.mortar.Coupling` has for its slave nodes."""

    nodes: np.ndarray
    D: np.ndarray  # lumped weights w_i = ∫_{Γ_C} φ_i ds
    normals: np.ndarray
    frames: np.ndarray
    projectors: np.ndarray
    absolute: list
    gap: np.ndarray
    ends: np.ndarray
    data: ProblemData


def obstacle_nodes(
    V: fem.FunctionSpace, fixed: np.ndarray, obstacle: RigidObstacle
) -> ObstacleNodes:
    """The obstacle's contact nodes rotated to their (n, t) frames (symmetry-fixed
    components kept as absolute axes, as for slave nodes), none of them a node of a pair."""
    surface = obstacle.surface
    msh = V.mesh
    bs, gdim, comm = V.dofmap.index_map_bs, msh.geometry.dim, msh.comm
    S, _, v_dofs, s_dofs = contact_nodes(V, 0, measure_facets(obstacle.measure))
    nodes = v_dofs // bs
    owned = nodes < V.dofmap.index_map.size_local
    nodes, s_dofs = nodes[owned], s_dofs[owned]
    is_fixed = np.isin(nodes[:, None] * bs + np.arange(bs), fixed)
    full = is_fixed.all(axis=1)
    X = S.tabulate_dof_coordinates()[:, :gdim]
    g = surface.project(X[s_dofs])[0]
    if comm.allreduce(
        int(np.sum(g[~full] < -1e-12 * max(1.0, float(np.max(np.abs(X), initial=0.0))))), op=MPI.SUM
    ):
        raise ConfigError("obstacle: contact nodes lie inside the obstacle (negative initial gap)")
    n, frames, projectors, absolute, bad = node_frames(
        surface.project(X[s_dofs[~full]])[1], is_fixed[~full], bs
    )
    if comm.allreduce(int(bad.sum()), op=MPI.SUM):
        raise ConfigError(
            "obstacle: a contact node has a symmetry condition along the obstacle's normal"
        )
    w = lumped_weights(S, obstacle.measure)[s_dofs[~full]]
    first = first_contact_point(comm, X[s_dofs], g)
    n_ufl, g_ufl = surface.expression(ufl.SpatialCoordinate(msh))
    return ObstacleNodes(
        nodes[~full],
        w,
        n,
        frames,
        projectors,
        absolute,
        g[~full],
        nodes[full],
        ProblemData(n=surface.project(first[None, :])[1][0], n_ufl=n_ufl, g_ufl=g_ufl),
    )


def mortar_set(
    V: fem.FunctionSpace,
    K: PETSc.Mat,
    b: PETSc.Vec,
    bcs: list,
    fixed: np.ndarray,
    pairs: Sequence[MortarPair],
    obstacle: RigidObstacle | None = None,
    coupled_at: np.ndarray | None = None,
) -> ContactSet:
    """Mortar pairs (and a rigid obstacle's nodes) as the change of basis u = Q x
    (:mod:`.basis`): K̃ = Qᵀ K Q, b̃ = Qᵀ b, the Dirichlet and symmetry conditions imposed
    again on the unknowns x (:func:`dirichlet_on_unknowns`), the constraint x_{i,n} ≤ g_i
    on every slave node (then the obstacle's nodes), its weights D_ii.

    ``coupled_at``: the nodal displacements u^k (V's function values, owned and ghost) of a
    finite-strain body, whose pairs are then coupled on the current configuration
    x^k = X + u^k (:func:`~.mortar.couple`: c_ij, n_i, D_ii and the gap g_i^k there).  The
    bound on the unknown x = Q⁻¹ u is then g_i^k + x_{i,n}(u^k): non-penetration
    n_i · (x_i − Σ_j c_ij x_j) ≤ 0 with the coupling frozen at u^k, exact at u = u^k
    (the frozen coupling's fixed point, :mod:`contact.drivers.recouple`).  An obstacle's
    nodes beside the pairs keep their reference gap (exact for a plane)."""
    msh = V.mesh
    bs = V.dofmap.index_map_bs
    mortar.check_disjoint(
        V,
        [(measure_facets(p.slave), measure_facets(p.master)) for p in pairs],
        None if obstacle is None else measure_facets(obstacle.measure),
    )
    couplings = [
        mortar.couple(V, pair, fixed, f"pairs[{i}]", coupled_at) for i, pair in enumerate(pairs)
    ]
    rigid = obstacle_nodes(V, fixed, obstacle) if obstacle is not None else None
    sets = couplings + ([rigid] if rigid is not None else [])

    nodes = np.concatenate([c.nodes for c in sets]).astype(np.int32)
    offsets = np.cumsum([0] + [len(c.nodes) for c in couplings])
    frames = np.concatenate([c.frames for c in sets]).reshape(-1, bs, bs)
    projectors = np.concatenate([c.projectors for c in sets]).reshape(-1, bs, bs)
    coupling = (
        np.concatenate([c.rows + o for c, o in zip(couplings, offsets)] + [np.zeros(0, int)]),
        np.concatenate([c.cols for c in couplings] + [np.zeros(0, int)]),
        np.concatenate([c.c for c in couplings] + [np.zeros(0)]),
    )
    Q, Q_inv = change_of_basis(V, K, nodes, frames, coupling, projectors)
    for c in couplings:  # a transformed slave basis: u = T ũ, ũ = Q x
        if c.transform is not None:
            T, T_inv = c.transform
            Q, Q_inv = T.matMult(Q), Q_inv.matMult(T_inv)
    current_gap = None
    if coupled_at is not None:  # the current gap as a bound on the total unknowns
        current_gap = np.concatenate([c.gap for c in sets])
        for c, relative in zip(couplings, _relative_normal(V, b, Q_inv, coupled_at, couplings)):
            c.gap = c.gap + relative
    Kt = K.PtAP(Q)  # K̃ = Qᵀ K Q
    bt = b.duplicate()
    Q.multTranspose(b, bt)  # b̃ = Qᵀ b
    on_unknowns = dirichlet_on_unknowns(
        V, bcs, nodes, frames, [a for c in sets for a in c.absolute], Kt, bt
    )
    S, collapsed = spaces.collapsed(V, 0)
    s_to_v = np.asarray(collapsed, dtype=np.int32).ravel()
    v_to_s = np.empty(len(s_to_v), dtype=np.int32)
    v_to_s[s_to_v // bs] = np.arange(len(s_to_v), dtype=np.int32)
    gap = np.concatenate([c.gap for c in sets])
    on = spaces.zero_vector(V, 2)  # (slave marker, bound) per node
    on.array.reshape(-1, 2)[nodes] = np.c_[np.ones(len(nodes)), gap]
    on.scatter_forward()
    marker, bound_nodes = on.array.reshape(-1, 2).T
    bound = spaces.zero_function(S, "bound")
    bound.x.array[:] = bound_nodes[s_to_v // bs]
    slave_nodes = np.flatnonzero(marker > 0)
    ends = np.concatenate([c.ends for c in sets]).astype(np.int32)
    end_dofs, end_neighbours = contact_ends(
        V, (ends * bs).astype(np.int32), np.concatenate([slave_nodes, ends]) * bs, ends * bs
    )
    constraint = Constraint(
        (nodes * bs).astype(np.int32),
        gap,
        np.concatenate([c.D for c in sets]),
        1.0,
        coordinate_scale(msh),
    )
    normals = np.concatenate([c.normals for c in sets])
    pair_nodes = int(offsets[-1])  # the first pair_nodes constrained nodes are slave nodes
    X = V.tabulate_dof_coordinates()[nodes, : msh.geometry.dim]
    on_pairs = slice(0, pair_nodes) if couplings else slice(None)
    ranking = gap if current_gap is None else np.c_[current_gap, gap]
    data = replace(
        rigid.data if rigid is not None else ProblemData(),
        u_bcs=bcs,
        couplings=couplings,
        normals=normals,
        pair_nodes=pair_nodes,
        current_gap=current_gap,
        # the contact normal at the first point of contact (of the pairs, if any): the
        # smallest gap; on a current configuration the current gap, not the bound, then
        # the bound among the nodes that touch (DiscreteProblem.contact_gaps)
        n=first_contact_row(msh.comm, X[on_pairs], ranking[on_pairs], normals[on_pairs]),
        contact_nodes=X[on_pairs],  # the pairs' slave nodes (this rank's): their mirrors
    )
    output = Output(
        S,
        s_to_v,
        bound,
        nodes=v_to_s[slave_nodes],
        ends=end_dofs,
        end_neighbours=end_neighbours,
    )
    return ContactSet(constraint, output, data, Kt, bt, on_unknowns, basis=Q, basis_inverse=Q_inv)


def _relative_normal(
    V: fem.FunctionSpace,
    b: PETSc.Vec,
    Q_inv: PETSc.Mat,
    displacement: np.ndarray,
    couplings: list,
) -> list[np.ndarray]:
    """x_{i,n}(u) = n_i · (u_i − Σ_j c_ij P_i u_j) of each coupling's slave nodes for the
    nodal ``displacement`` u: the normal components of x = Q⁻¹ u."""
    bs = V.dofmap.index_map_bs
    n_owned = V.dofmap.index_map.size_local * bs
    u, x = b.duplicate(), b.duplicate()
    u.array_w[:] = np.asarray(displacement)[:n_owned]
    Q_inv.mult(u, x)
    out = [x.array_r[c.nodes * bs].copy() for c in couplings]
    for vec in (u, x):
        vec.destroy()
    return out


def dirichlet_on_unknowns(
    V: fem.FunctionSpace,
    bcs: list,
    nodes: np.ndarray,
    frames: np.ndarray,
    absolute: list,
    Kt: PETSc.Mat,
    bt: PETSc.Vec,
) -> list:
    """The Dirichlet and symmetry conditions as conditions on the unknowns x = Q⁻¹ u, imposed
    on K̃ and b̃ (rows and columns identity, the prescribed values lifted into b̃), and
    returned as DirichletBCs on x (one per component) for the solvers' initial guess.

    A fixed component u_k of a slave node whose frame keeps e_k as its axis 1 + m
    (``absolute``) is the unknown x_{1+m} = ±u_k; every other fixed DoF keeps its index
    (Q's row there is the identity).  Only owned DoFs are listed."""
    bs = V.dofmap.index_map_bs
    n_owned = V.dofmap.index_map.size_local * bs
    values = spaces.zero_function(V)
    for bc in bcs:
        bc.set(values.x.array)
    fixed = np.unique(np.concatenate([bc.dof_indices()[0] for bc in bcs]))
    fixed = fixed[fixed < n_owned]
    x_values = np.zeros(n_owned)
    is_fixed = np.zeros(n_owned, dtype=bool)
    is_fixed[fixed] = True
    x_values[fixed] = values.x.array[fixed]
    for node, R, axes in zip(nodes, frames, absolute):
        if not axes:
            continue
        block = slice(node * bs, node * bs + bs)
        u_fixed = np.where(is_fixed[block], values.x.array[block], 0.0)
        is_fixed[block] = False
        x_values[block] = 0.0
        for m in range(len(axes)):
            is_fixed[node * bs + 1 + m] = True
            x_values[node * bs + 1 + m] = R[:, 1 + m] @ u_fixed
    dofs = np.flatnonzero(is_fixed).astype(np.int32)
    xbar = bt.duplicate()
    xbar.set(0.0)
    xbar.array_w[dofs] = x_values[dofs]
    lo = bt.getOwnershipRange()[0]
    Kt.zeroRowsColumns((lo + dofs).astype(PETSc.IntType), diag=1.0, x=xbar, b=bt)  # type: ignore[arg-type]
    xbar.destroy()
    return [_component_bc(V, k, dofs[dofs % bs == k], x_values) for k in range(bs)]


def _component_bc(
    V: fem.FunctionSpace, k: int, dofs: np.ndarray, values: np.ndarray
) -> fem.DirichletBC:
    """x_j = values[j] on the (unrolled, owned) DoFs ``dofs`` of component k, as a DirichletBC
    on V.sub(k): ``fem.dirichletbc(g, dofs)`` on the blocked V would read the indices as
    node (block) numbers and fix other DoFs."""
    S, collapsed = spaces.collapsed(V, k)
    imap = V.dofmap.index_map
    n = (imap.size_local + imap.num_ghosts) * V.dofmap.index_map_bs
    v_to_s = np.full(n, -1, dtype=np.int32)
    s_to_v = np.asarray(collapsed, dtype=np.int32).ravel()
    v_to_s[s_to_v] = np.arange(len(s_to_v), dtype=np.int32)
    g = spaces.zero_function(S)
    g.x.array[v_to_s[dofs]] = values[dofs]
    return fem.dirichletbc(g, [dofs.astype(np.int32), v_to_s[dofs]], V.sub(k))  # type: ignore[arg-type]


class BodiesProblem(Problem):
    """The multi-body problem: its contact force is the one the pairs transmit (the slave
    nodes' pressures; an obstacle's nodes, if any, are left out)."""

    def contact_force(self, r: np.ndarray) -> float:
        """The force the pairs transmit, of the whole body (collective):

            N = Σ_{slave i} D_ii p_i n_i,    F = m_n N · n,   n = N̄ / |N̄|,

        p_i = −λ_i the interface pressure, n_i the slave nodes' normals, N the modelled
        part's normal contact resultant (summed over all ranks) and N̄ that of the whole
        body: N with its components normal to the symmetry planes set to 0 (they cancel
        between mirror images); m_n the mirror images pressing along n
        (:meth:`DiscreteProblem.copies_along`).  So F = |N̄| times the copies: the size
        of the whole body's normal contact force, whatever the shape of the contact zone
        and wherever it touched first (for a zone symmetric about n, Σ D_ii p_i (n_i · n)).
        Only when N̄ vanishes (N normal to a mirror plane) is n = N / |N|.  Without pairs:
        :meth:`DiscreteProblem.contact_force` over all nodes."""
        data = self.data
        if not data.couplings:
            return super().contact_force(r)
        assert data.normals is not None  # a mortar set's
        if data.n is None:  # no slave node faces the master on any rank: nothing transmitted
            return 0.0
        on = slice(0, data.pair_nodes)
        local = (self.constraint.w[on] * self.pressure(r)[on]) @ data.normals[on]
        part = np.asarray(self.V.mesh.comm.allreduce(local, op=MPI.SUM), dtype=float)
        whole = part.copy()
        whole[list(self.symmetry.axes)] = 0.0
        size = float(np.linalg.norm(part))
        if size == 0.0:
            return 0.0
        n = whole if np.linalg.norm(whole) > 1e-12 * size else part
        n = n / np.linalg.norm(n)
        return self.copies_along(n) * float(part @ n)


def mirror_axes(
    msh: dmesh.Mesh, planes: Sequence[tuple[np.ndarray, int]], X: np.ndarray
) -> set[int]:
    """The coordinate axes k of the symmetry planes x_k = c (``planes``: their facets and k)
    that pass through a contact node (rows of X, this rank's): the planes that mirror the
    contact zone, each counted once however many bodies it cuts (a support plane away from
    the interface is not one).  Collective."""
    comm, tdim = msh.comm, msh.topology.dim
    scale = comm.allreduce(float(np.max(np.abs(msh.geometry.x), initial=0.0)), op=MPI.MAX)
    axes = set()
    for facets, k in planes:
        nodes = dmesh.entities_to_geometry(msh, tdim - 1, facets[:1]).ravel()
        local = float(msh.geometry.x[nodes[0], k]) if len(nodes) else np.nan
        c = next(v for v in comm.allgather(local) if not np.isnan(v))
        if comm.allreduce(bool(np.any(np.abs(X[:, k] - c) <= 1e-10 * max(scale, 1.0))), op=MPI.LOR):
            axes.add(k)
    return axes
