"""Mortar coupling of a contact pair with dual Lagrange multipliers (Wohlmuth; docs/theory.md §1.5).

A pair couples a slave surface Γ_s of one body to a master surface Γ_m of another, once,
in the reference configuration (small deformation).  With the trace basis φ_i on Γ_s (P1,
or P2: every node of a slave facet, edge midpoints included; on P2 triangles the
transformed basis φ̃ = T φ, whose functions all integrate positively, and the slave
unknowns are the values ũ = T⁻¹ u in it), its dual basis ψ_i (biorthogonal: ∫ ψ_i φ_k =
δ_ik D_ii) and the projection π along the slave facet normals onto Γ_m
(:mod:`contact.models.overlap`),

    D_ii = ∫_{Γ_s} φ_i ds,       M_ij = ∫_{Γ_s} ψ_i (φ_j^m ∘ π) ds,       c_ij = M_ij / Σ_k M_ik,

(Σ_k M_ik = D_ii where master facets cover the support of φ_i; dividing by the covered
part keeps rigid translations exact at the ends of a partly covered slave surface).  Each
slave node i gets the common normal n_i = (n_i^s − n_i^m)/|n_i^s − n_i^m|, the bisector of
its own averaged facet normal n_i^s (towards the master) and the reversed master normal
n_i^m = Σ_j c_ij n_j^m at its projection — the normal of the deformed interface of two
elastically similar bodies (flat between two equal cylinders, where the slave normal is
tilted by x/R: measured along it, the normal approach would look like a tangential slip
of the order of the approach times x/R, which friction would resist) — and the weighted gap

    g_i = n_i · (Σ_j c_ij X_j − X_i)     (X the reference coordinates),

(on curved cells, a coordinate element of degree 2, the positions X are those of the curved
P2 nodes while the search, the normals, the overlap and its quadrature use the segments'
chords: the weighted gap of the curved surfaces at the chords' quadrature points,
docs/theory.md §1.5), and its unknowns become the displacement relative to the master, in a
frame R_i = [n_i t …] (:mod:`contact.models.basis`): x_i = R_iᵀ (u_i − Σ_j c_ij P_i u_j).
Non-penetration is the bound x_{i,n} ≤ g_i on one unknown, the interface pressure is
λ_i = R̃_i / D_ii (≤ 0 in compression; R̃ = Qᵀ R) and Qᵀ hands the slave force to the
master nodes through the same c_ij (action = reaction).  The tangential unknowns are the
relative slip.

Components fixed by a symmetry condition at a slave node stay absolute unknowns (their
frame axis is the coordinate axis, the normal loses that component: the mirror image
holds the other half), and a slave node fixed in every component carries no constraint.

Parallel: each rank integrates the slave facets of its owned cells against the master
facets it receives from the ranks that own them (only those within the search distance
of its slave facets' bounding box; the master surface is small next to the volume), and
the rows of M are summed on the owner of the slave node, so the coupling is the same for
any number of ranks (up to the order of floating-point sums).
"""

from __future__ import annotations

from dataclasses import dataclass

import dolfinx.fem.petsc
import numpy as np
from dolfinx import fem, la
from mpi4py import MPI
from petsc4py import PETSc

from ..base import spaces
from ..base.buckets import box_point_pairs
from ..base.errors import ConfigError
from ..solvers.result import Result
from . import overlap
from .basis import node_frames
from .constraints import MortarPair, measure_facets

FACING = 0.0  # a master facet is paired only if n_S · n_M < FACING (the surfaces face each other)
# Σ_j M_ij / D_ii below which slave node i counts as uncovered: where a master surface ends
# inside a slave facet, ψ_i (negative on part of its support) may weigh the covered part
# with either sign; a node less than half covered is refused rather than extrapolated.
MIN_COVERAGE = 0.5


@dataclass
class Facets:
    """The facets of one surface held by this rank (those of its owned cells)."""

    X: np.ndarray  # (F, nv, gdim) vertex coordinates
    nodes: np.ndarray  # (F, nv) local node indices (blocks of V's DoFs)
    gnodes: np.ndarray  # (F, nv) global node indices
    normals: np.ndarray  # (F, gdim) unit normals out of the body
    # (F, nv, gdim) the surface's nodal normals at the vertices
    vertex_normals: np.ndarray | None = None


@dataclass
class Coupling:
    """The mortar coupling of one pair on this rank (rows of the owned slave nodes)."""

    nodes: np.ndarray  # owned local slave nodes with a constraint
    D: np.ndarray  # D_ii of those nodes
    normals: np.ndarray  # (n, gdim) unit normals n_i
    frames: np.ndarray  # (n, bs, bs) frames R_i (columns: n_i, then the other axes)
    projectors: np.ndarray  # (n, bs, bs) P_i onto the relative axes
    absolute: list  # per node: the coordinate axes kept absolute (fixed by symmetry)
    gap: np.ndarray  # weighted gaps g_i
    rows: np.ndarray  # coupling entries: index into ``nodes`` …
    cols: np.ndarray  # … global master node …
    c: np.ndarray  # … and c_ij
    # M_ij (scalar, node layout; owned slave rows, global master columns; on P2 triangles
    # against the master's transformed basis φ̃_j^m, whose functions integrate positively)
    M: PETSc.Mat
    master_weights: la.Vector  # ∫ φ_j^m (φ̃_j^m) over Γ_m at the master nodes (node layout)
    ends: np.ndarray  # owned slave nodes fixed in every component (no constraint)
    # owned slave nodes facing no master facet on the current configuration (no constraint)
    uncovered: np.ndarray
    coverage: float  # min_i Σ_j M_ij / D_ii over all ranks (1 where fully covered)
    search: float  # the search distance used
    #: the owned nodes of the slave surface and of the master surface (all their nodes, the
    #: constrained ones and the others)
    surfaces: tuple[np.ndarray, np.ndarray] = (np.zeros(0, np.int64), np.zeros(0, np.int64))
    #: (T, T⁻¹) of a transformed slave basis (P2 triangles: u = T ũ, the slave unknowns
    #: are ũ), or None
    transform: tuple[PETSc.Mat, PETSc.Mat] | None = None

    def surface_forces(self, force: np.ndarray, comm: MPI.Comm) -> tuple[np.ndarray, np.ndarray]:
        """Return the resultants of a nodal force on the pair's slave and master surfaces.

        F_s = Σ_{i ∈ Γ_s} f_i and F_m = Σ_{j ∈ Γ_m} f_j over the surfaces' owned nodes, summed
        over all ranks (collective).  With f the residual a(u_h, v) − L(v) at the solution
        (its Dirichlet DoFs left out) they are the forces each body's surface needs from the
        other, and F_s + F_m = 0 when action equals reaction.

        Args:
            force: nodal forces f, one row per owned node of V (owned nodes × block size).
            comm: the mesh's communicator.

        Returns:
            (F_s, F_m), each a vector of the block size's components.
        """
        slave, master = (
            comm.allreduce(force[nodes].sum(axis=0), op=MPI.SUM) for nodes in self.surfaces
        )
        return slave, master


def surface_facets(
    V: fem.FunctionSpace, facets: np.ndarray, displacement: np.ndarray | None = None
) -> Facets:
    """The exterior ``facets`` of V's mesh that belong to owned cells, as :class:`Facets`
    (the facet's nodes in the order of its closure DoFs: the vertices, then for P2 the edge
    midpoints), at the positions X + ``displacement`` (the nodal displacements, owned and
    ghost nodes × gdim; None: the reference positions X)."""
    msh = V.mesh
    tdim, gdim = msh.topology.dim, msh.geometry.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    msh.topology.create_connectivity(tdim, tdim - 1)
    f2c, c2f = msh.topology.connectivity(tdim - 1, tdim), msh.topology.connectivity(tdim, tdim - 1)
    cells = f2c.array[f2c.offsets[facets]]
    owned = cells < msh.topology.index_map(tdim).size_local
    facets, cells = facets[owned], cells[owned]
    nf = tdim + 1
    local = np.argmax(c2f.array.reshape(-1, nf)[cells] == facets[:, None], axis=1)
    closure = np.array([V.dofmap.dof_layout.entity_closure_dofs(tdim - 1, j) for j in range(nf)])
    cell_nodes = V.dofmap.list[cells]
    nodes = (
        np.take_along_axis(cell_nodes, closure[local], axis=1)
        if len(cells)
        else np.zeros((0, closure.shape[1]), np.int32)
    )
    X = positions(V, displacement)
    Xf = X[nodes]
    normals = (
        overlap.facet_normals(Xf, X[cell_nodes].mean(axis=1)) if len(cells) else np.zeros((0, gdim))
    )
    gnodes = V.dofmap.index_map.local_to_global(nodes.ravel().astype(np.int32)).reshape(nodes.shape)
    return Facets(Xf, nodes, gnodes, normals)


def positions(V: fem.FunctionSpace, displacement: np.ndarray | None = None) -> np.ndarray:
    """The nodes' positions (owned and ghost nodes × gdim): the reference coordinates X, or
    the current ones x = X + u for the nodal ``displacement`` u (V's node order)."""
    gdim = V.mesh.geometry.dim
    X = V.tabulate_dof_coordinates()[:, :gdim]
    if displacement is None:
        return X
    return X + np.asarray(displacement).reshape(len(X), -1)[:, :gdim]


def couple(
    V: fem.FunctionSpace,
    pair: MortarPair,
    fixed: np.ndarray,
    key: str = "pairs[0]",
    displacement: np.ndarray | None = None,
) -> Coupling:
    """The mortar coupling of a :class:`~.constraints.MortarPair`; ``fixed`` are the local DoFs
    with a Dirichlet or symmetry condition, ``key`` names the pair in messages.  With a
    ``displacement`` u (the nodal values of V's function, owned and ghost) the search,
    projection, normals, D and M are those of the current configuration x = X + u and the
    gap is the current one, g_i = n_i · (Σ_j c_ij x_j − x_i) (finite strain; the module
    doc's formulas with X replaced by x).  A slave node facing master facets over less than
    half of its facets (within the search distance) is an error in the reference
    configuration (ConfigError, one line, every rank: the slave part reaches beyond the
    master) but out of contact on a current one (no constraint, gap +∞, listed in
    ``uncovered``): where a body deforms, a slave node may face no master facet yet, or no
    longer (the far side of a self-contact, a slave surface slid past the master's end)."""
    comm = V.mesh.comm
    slave = surface_facets(V, measure_facets(pair.slave), displacement)
    master = surface_facets(V, measure_facets(pair.master), displacement)
    gdim = slave.X.shape[2]
    search = pair.search or _diameter(comm, slave, master)
    imap = V.dofmap.index_map
    master.vertex_normals = _vertex_normals(V, master, gdim)
    remote = _gather_master(comm, slave, master, search)

    # pairs (slave facet, master facet) whose overlap is non-empty, facing and within reach
    s_idx, m_idx = candidate_pairs(slave, remote, search)
    M_loc, meas, dist = overlap.mortar_pairs(slave.X[s_idx], slave.normals[s_idx], remote.X[m_idx])
    facing = np.einsum("pd,pd->p", slave.normals[s_idx], remote.normals[m_idx]) < FACING
    keep = (meas > 0) & facing & (np.abs(dist) <= search)
    s_idx, m_idx, M_loc = s_idx[keep], m_idx[keep], M_loc[keep]

    nv = slave.nodes.shape[1]
    share = overlap.trace_weights(nv, gdim)  # ∫_F φ_a ds / |F|
    # nodal sums over the slave facets (D_ii = ∫ φ̃_i, Σ |F| n_F) and the master facets (∫ φ_j^m)
    measure = overlap.facet_measures(slave.X) if len(slave.X) else np.zeros(0)
    D = _nodal_sum(V, slave.nodes, measure[:, None] * overlap.dual_weights(nv, gdim))
    nsum = _nodal_sum(
        V,
        slave.nodes,
        np.repeat((measure[:, None] * slave.normals)[:, None, :], nv, axis=1),
        gdim,
    )
    w_master = spaces.zero_vector(V, 1)
    m_measure = overlap.facet_measures(master.X) if len(master.X) else np.zeros(0)
    np.add.at(w_master.array, master.nodes.ravel(), (m_measure[:, None] * share).ravel())
    w_master.scatter_reverse(la.InsertMode.add)
    w_master.scatter_forward()
    M_rows, cols, M_vals, attrs = _owned_rows(
        comm,
        imap,
        slave.nodes[s_idx],
        remote.gnodes[m_idx],
        np.concatenate([remote.X, remote.vertex_normals], axis=2)[m_idx],
        M_loc,
    )
    X_of, N_of = attrs[:, :gdim], attrs[:, gdim:]

    n_owned = imap.size_local
    D_owned = D[:n_owned]
    on_slave = np.flatnonzero(D_owned > 0)
    bs = V.dofmap.index_map_bs
    fixed_set = np.zeros(n_owned * bs, dtype=bool)
    fixed_set[fixed[fixed < n_owned * bs]] = True
    fixed_comp = fixed_set.reshape(n_owned, bs)[on_slave]
    ends = on_slave[fixed_comp.all(axis=1)]
    nodes = on_slave[~fixed_comp.all(axis=1)]
    fixed_comp = fixed_comp[~fixed_comp.all(axis=1)]

    covered = np.bincount(M_rows, weights=M_vals, minlength=n_owned)[nodes]
    coverage = covered / D_owned[nodes]
    bare = coverage < MIN_COVERAGE
    if displacement is None:
        _no_master(comm, V, nodes[bare], key, pair, search)
    # on the current configuration a slave node facing no master facet is out of contact:
    # no constraint (gap +∞), an ordinary node of its body until a coupling finds one
    uncovered = nodes[bare]
    nodes, fixed_comp, covered, coverage = (
        a[~bare] for a in (nodes, fixed_comp, covered, coverage)
    )

    # c_ij = M_ij / Σ_k M_ik for the constrained nodes
    position = np.full(n_owned, -1)
    position[nodes] = np.arange(len(nodes))
    use = position[M_rows] >= 0
    rows, cols_c = position[M_rows[use]], cols[use]
    c = M_vals[use] / covered[rows]
    transform = None
    X_all = positions(V, displacement)
    if (nv, gdim) == (6, 3):  # the slave unknowns are the transformed values ũ = T⁻¹ u
        transform, X_all = _transform(V, slave.nodes, X_all)
    Xs = X_all[:n_owned][nodes]
    target = np.zeros((len(nodes), gdim))
    np.add.at(target, rows, c[:, None] * X_of[use])  # Σ_j c_ij X_j
    n_master = np.zeros((len(nodes), gdim))
    np.add.at(n_master, rows, c[:, None] * N_of[use])  # Σ_j c_ij n_j^m
    n_slave = nsum.reshape(-1, gdim)[nodes]
    n_slave = n_slave / np.linalg.norm(n_slave, axis=1, keepdims=True)
    n_master /= np.maximum(np.linalg.norm(n_master, axis=1, keepdims=True), 1e-300)
    # the common normal: the bisector of the slave normal and the reversed master normal
    normals, frames, projectors, absolute = _frames(
        comm, V, n_slave - n_master, fixed_comp, Xs, key
    )
    gap = np.einsum("nd,nd->n", normals, target - Xs)
    M = _node_matrix(V, M_rows, cols, M_vals)
    if transform is not None:  # λ^m in the master's transformed basis too: ∫ φ̃_j^m > 0
        alpha = overlap.TRIANGLE_P2_ALPHA
        T_m = edge_matrix(comm, imap, master.nodes, 1, 1 - 2 * alpha, alpha)
        M_t = M.matMult(T_m)  # Σ_i M̃_ij v_i = Σ_k T_kj Σ_i M_ik v_i
        w, w_t = T_m.createVecRight(), T_m.createVecRight()
        w.array_w[:] = w_master.array[:n_owned]
        T_m.multTranspose(w, w_t)
        w_master.array[:n_owned] = w_t.array_r
        w_master.scatter_forward()
        for obj in (M, T_m, w, w_t):
            obj.destroy()
        M = M_t
    return Coupling(
        nodes=nodes.astype(np.int32),
        D=D_owned[nodes],
        normals=normals,
        frames=frames,
        projectors=projectors,
        absolute=absolute,
        gap=gap,
        rows=rows,
        cols=cols_c,
        c=c,
        M=M,
        master_weights=w_master,
        ends=ends.astype(np.int32),
        uncovered=uncovered.astype(np.int32),
        coverage=comm.allreduce(float(coverage.min(initial=1.0)), op=MPI.MIN),
        search=search,
        surfaces=(_owned_nodes(V, slave.nodes), _owned_nodes(V, master.nodes)),
        transform=transform,
    )


def _transform(
    V: fem.FunctionSpace, nodes: np.ndarray, X: np.ndarray
) -> tuple[tuple[PETSc.Mat, PETSc.Mat], np.ndarray]:
    """The slave basis transformation of P2 triangles (:data:`overlap.TRIANGLE_P2_TRANSFORM`)
    on V: (T, T⁻¹) with u = T ũ — u_e = (1 − 2α) ũ_e + α (ũ_a + ũ_b) at every edge node e of
    the slave facets (``nodes``, local, (F, 6)), a, b its edge's vertices, every other DoF
    unchanged — and the nodal positions ``X`` transformed the same way, X̃ = T⁻¹ X (owned
    and ghost nodes; equal to X on straight edges)."""
    imap, bs = V.dofmap.index_map, V.dofmap.index_map_bs
    alpha = overlap.TRIANGLE_P2_ALPHA
    edge, a, b = _edges(nodes)
    gdim = X.shape[1]
    # X̃_e on the owner of e (each facet holding the edge gives the same value: averaged)
    Xt = la.vector(imap, gdim + 1)
    arr = Xt.array.reshape(-1, gdim + 1)
    moved = (X[edge] - alpha * (X[a] + X[b])) / (1 - 2 * alpha)
    np.add.at(arr, edge, np.c_[moved, np.ones(len(edge))])
    Xt.scatter_reverse(la.InsertMode.add)
    Xt.scatter_forward()
    on_edge = arr[:, gdim] > 0
    X = X.copy()
    X[on_edge] = arr[on_edge, :gdim] / arr[on_edge, gdim:]
    T = edge_matrix(V.mesh.comm, imap, nodes, bs, 1 - 2 * alpha, alpha)
    T_inv = edge_matrix(V.mesh.comm, imap, nodes, bs, 1 / (1 - 2 * alpha), -alpha / (1 - 2 * alpha))
    return (T, T_inv), X


def _edges(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(edge node, vertex a, vertex b) of every edge of P2 triangles ``nodes`` (F, 6): the
    edge opposite vertex k is node 3 + k, between vertices k + 1 and k + 2 (mod 3)."""
    return tuple(  # type: ignore[return-value]
        np.concatenate([nodes[:, (3 + k, (k + 1) % 3, (k + 2) % 3)[j]] for k in range(3)])
        for j in range(3)
    )


def edge_matrix(
    comm: MPI.Comm, imap, nodes: np.ndarray, bs: int, own: float, side: float
) -> PETSc.Mat:
    """The AIJ matrix (``bs`` components per node; owned rows, global columns) that is the
    identity except at the edge nodes e of P2 triangles ``nodes`` (local, (F, 6), held on
    any rank): row e·bs + k has ``own`` at e and ``side`` at the edge's two vertices."""
    edge, a, b = _edges(nodes)
    to_global = lambda n: imap.local_to_global(n.astype(np.int32)) if len(n) else n  # noqa: E731
    e_g, a_g, b_g = _to_owners(comm, imap, edge, to_global(a), to_global(b))
    triples = np.unique(np.c_[e_g, np.sort(np.c_[a_g, b_g], axis=1)], axis=0)
    n_owned, first = imap.size_local, imap.local_range[0]
    nodes_g = first + np.arange(n_owned)
    plain = np.ones(n_owned, dtype=bool)
    plain[triples[:, 0] - first] = False
    comps = np.arange(bs)
    # entries (local row DoF, global column DoF, value)
    rows = [(nodes_g[plain] - first)[:, None] * bs + comps]
    cols = [nodes_g[plain][:, None] * bs + comps]
    vals = [np.ones((plain.sum(), bs))]
    for column, value in ((0, own), (1, side), (2, side)):
        rows.append((triples[:, 0] - first)[:, None] * bs + comps)
        cols.append(triples[:, column][:, None] * bs + comps)
        vals.append(np.full((len(triples), bs), value))
    r, c, v = (np.concatenate([x.ravel() for x in arrays]) for arrays in (rows, cols, vals))
    order = np.lexsort((c, r))
    r, c, v = r[order], c[order], v[order]
    indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=n_owned * bs))])
    size = (n_owned * bs, imap.size_global * bs)
    csr = (indptr.astype(PETSc.IntType), c.astype(PETSc.IntType), v)
    T = PETSc.Mat().createAIJ((size, size), comm=comm, csr=csr)  # type: ignore[arg-type]
    T.assemble()
    return T


def _owned_nodes(V: fem.FunctionSpace, nodes: np.ndarray) -> np.ndarray:
    """The owned nodes among a surface's facet ``nodes`` held on any rank (sorted;
    collective)."""
    mark = spaces.zero_vector(V, 1)
    mark.array[np.unique(nodes)] = 1.0
    mark.scatter_reverse(la.InsertMode.add)
    return np.flatnonzero(mark.array[: V.dofmap.index_map.size_local] > 0)


def interface_forces(problem) -> tuple[np.ndarray, np.ndarray]:
    """Return the forces on the slave and master surfaces of a solved problem's pairs.

    F_s and F_m (:meth:`Coupling.surface_forces`) of the residual a(u_h, v) − L(v) at the
    problem's displacement (``data.reaction_form``), its Dirichlet and symmetry DoFs
    (``data.u_bcs``) left out, summed over the pairs: the forces of the modelled part, the
    symmetric copies not counted.  Collective (assembly).

    Args:
        problem: a :class:`~contact.solvers.problem.DiscreteProblem` with mortar couplings,
            its displacement at the solution.

    Returns:
        (F_s, F_m), vectors of gdim components, the same on every rank.
    """
    V, data = problem.V, problem.data
    comm, gdim = V.mesh.comm, V.mesh.geometry.dim
    bs, n_owned = V.dofmap.index_map_bs, V.dofmap.index_map.size_local
    assert data.reaction_form is not None and data.u_bcs is not None  # an elastic problem's
    full = dolfinx.fem.petsc.assemble_vector(data.reaction_form)
    full.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]
    residual = full.array_r.reshape(-1, bs).copy()
    full.destroy()
    fixed = np.zeros(n_owned * bs, dtype=bool)
    for bc in data.u_bcs:
        dofs = bc.dof_indices()[0]
        fixed[dofs[dofs < n_owned * bs]] = True
    free = np.where(fixed.reshape(-1, bs), 0.0, residual)
    F_s, F_m = np.zeros(gdim), np.zeros(gdim)
    for coupling in data.couplings or []:
        slave, master = coupling.surface_forces(free, comm)
        F_s += slave
        F_m += master
    return F_s, F_m


def _owned_rows(
    comm: MPI.Comm,
    imap,
    slave_nodes: np.ndarray,
    master_gnodes: np.ndarray,
    master_X: np.ndarray,
    M_loc: np.ndarray,
) -> tuple:
    """The entries M_ij of this rank's owned slave rows from the local pair integrals
    M_loc (P, nv, nv) of slave facets with local ``slave_nodes`` (P, nv) against master
    facets with global ``master_gnodes`` and per-vertex data ``master_X`` (P, nv, k; the
    coordinates and the nodal normals): each entry goes to the owner of its slave node,
    duplicates (i, j) from several facets are summed.  Returns (local row, global column,
    value, the column's data)."""
    nv = M_loc.shape[1]
    gdim = master_X.shape[2]
    rows_local = np.repeat(slave_nodes, nv, axis=1).ravel()  # (p, a, b) → slave a …
    cols = np.tile(master_gnodes, (1, nv)).ravel()  # … and master b
    Xcol = np.tile(master_X, (1, nv, 1)).reshape(-1, gdim)
    rows_g, cols, vals, Xcol = _to_owners(comm, imap, rows_local, cols, M_loc.ravel(), Xcol)
    key_ij, inverse = np.unique(
        np.c_[rows_g - imap.local_range[0], cols], axis=0, return_inverse=True
    )
    inverse = inverse.ravel()
    X_of = np.zeros((len(key_ij), gdim))
    X_of[inverse] = Xcol
    return (
        key_ij[:, 0],
        key_ij[:, 1],
        np.bincount(inverse, weights=vals, minlength=len(key_ij)),
        X_of,
    )


def check_disjoint(
    V: fem.FunctionSpace,
    pairs: list[tuple[np.ndarray, np.ndarray]],
    obstacle: np.ndarray | None = None,
) -> None:
    """No node may be a slave node twice or both a slave and a master node (Q would not be
    unit triangular), nor a pair's node and a rigid obstacle's contact node; a one-line
    ConfigError otherwise.  ``pairs``: the (slave, master) facets of each pair;
    ``obstacle``: the facets a rigid obstacle meets, or None.  Checked on the surfaces,
    before any coupling is computed."""
    comm, imap = V.mesh.comm, V.dofmap.index_map
    # per owned node: slave, master, obstacle parts through it
    owned = np.zeros((imap.size_local, 3), dtype=int)

    def count(column: int, facets: np.ndarray) -> None:
        flag = spaces.zero_vector(V, 1)
        flag.array[np.unique(surface_facets(V, facets).nodes)] = 1.0
        flag.scatter_reverse(la.InsertMode.add)
        owned[:, column] += flag.array[: imap.size_local] > 0

    for slave, master in pairs:
        count(0, slave)
        count(1, master)
    if obstacle is not None:
        count(2, obstacle)
    bad = np.flatnonzero(
        (owned[:, 0] > 1)
        | ((owned[:, 0] > 0) & (owned[:, 1] > 0))
        | ((owned[:, 2] > 0) & (owned[:, :2].sum(axis=1) > 0))
    )
    if comm.allreduce(len(bad), op=MPI.SUM):
        where = _first_point(comm, V, bad)
        raise ConfigError(
            f"pairs: the node at {where} is both a slave and a master node (or a slave node of "
            "two pairs, or on a pair and on the obstacle's contact part); a node may "
            "be the slave of one pair only, and never a master or obstacle contact "
            "node too"
        )


def part_facets(bnd, name: str) -> np.ndarray:
    """The facets of boundary part ``name`` (sorted local indices)."""
    return np.sort(bnd.tags.indices[bnd.tags.values == bnd.ids[name]]).astype(np.int32)


def _diameter(comm: MPI.Comm, *sides: Facets) -> float:
    """Diameter of the bounding box of the given surfaces (all ranks)."""
    pts = [s.X.reshape(-1, s.X.shape[2]) for s in sides if len(s.X)]
    gdim = sides[0].X.shape[2]
    lo = np.min(pts[0], axis=0) if pts else np.full(gdim, np.inf)
    hi = np.max(pts[0], axis=0) if pts else np.full(gdim, -np.inf)
    for p in pts[1:]:
        lo, hi = np.minimum(lo, p.min(axis=0)), np.maximum(hi, p.max(axis=0))
    lo, hi = np.min(comm.allgather(lo), axis=0), np.max(comm.allgather(hi), axis=0)
    return float(np.linalg.norm(hi - lo))


def _gather_master(comm: MPI.Comm, slave: Facets, master: Facets, search: float) -> Facets:
    """The master facets (of every rank) within ``search`` of this rank's slave facets'
    bounding box: each rank sends every other rank only the facets that box needs."""
    gdim = slave.X.shape[2]
    box = None
    if len(slave.X):
        pts = slave.X.reshape(-1, gdim)
        box = (pts.min(axis=0) - search, pts.max(axis=0) + search)
    boxes = comm.allgather(box)
    lo, hi = (
        (master.X.min(axis=1), master.X.max(axis=1))
        if len(master.X)
        else (np.zeros((0, gdim)),) * 2
    )
    send = []
    assert master.vertex_normals is not None  # set for every master surface (_surface)
    for b in boxes:
        sel = (
            np.zeros(len(master.X), dtype=bool)
            if b is None
            else np.all((lo <= b[1]) & (hi >= b[0]), axis=1)
        )
        send.append(
            (master.X[sel], master.gnodes[sel], master.normals[sel], master.vertex_normals[sel])
        )
    recv = comm.alltoall(send)
    nv = slave.X.shape[1]  # the facets' nodes (held even by an empty surface)
    X = np.concatenate([r[0] for r in recv]).reshape(-1, nv, gdim)
    return Facets(
        X,
        np.zeros((len(X), nv), np.int32),
        np.concatenate([r[1] for r in recv]).reshape(-1, nv),
        np.concatenate([r[2] for r in recv]).reshape(-1, gdim),
        np.concatenate([r[3] for r in recv]).reshape(-1, nv, gdim),
    )


def _vertex_normals(V: fem.FunctionSpace, side: Facets, gdim: int) -> np.ndarray:
    """The surface's unit nodal normals (measure-weighted facet normals summed over all
    ranks) at the vertices of its facets, (F, nv, gdim)."""
    nv = side.nodes.shape[1]
    measure = overlap.facet_measures(side.X) if len(side.X) else np.zeros(0)
    nsum = _nodal_sum(
        V, side.nodes, np.repeat((measure[:, None] * side.normals)[:, None, :], nv, axis=1), gdim
    )
    N = nsum.reshape(-1, gdim)[side.nodes]
    return N / np.maximum(np.linalg.norm(N, axis=-1, keepdims=True), 1e-300)


def candidate_pairs(slave: Facets, master: Facets, search: float) -> tuple[np.ndarray, np.ndarray]:
    """(slave facet, master facet) pairs whose master facet may meet the prism swept by the
    slave facet along its normal over [−search, search]: the master centroid within
    r_S + r_M of the slave facet's normal line, and within search + r_M along it (r the
    largest centroid-to-vertex distance); sorted by slave, then master facet.

    Vectorised (no loop over facets): the master facets are sorted into classes of radii
    within a factor 2 (a graded mesh has facets from h_contact to h); for each class, the
    segment |t| ≤ search + r_M of each slave facet's normal line is clipped to the slab of
    the class's centroids (grown by r_S + r_M), its bounding box grown by r_S + r_M is
    matched with the centroids through a grid of buckets
    (:func:`~contact.base.buckets.box_point_pairs`), and the exact test above keeps the
    pairs."""
    if not len(slave.X) or not len(master.X):
        return np.zeros(0, int), np.zeros(0, int)
    cs, cm = slave.X.mean(axis=1), master.X.mean(axis=1)
    rs = np.linalg.norm(slave.X - cs[:, None], axis=2).max(axis=1)
    rm = np.linalg.norm(master.X - cm[:, None], axis=2).max(axis=1)
    n = slave.normals
    smallest = max(float(rm.min()), 1e-300)
    size_class = np.floor(np.log2(np.maximum(rm, smallest) / smallest))
    out_s, out_m = [np.zeros(0, int)], [np.zeros(0, int)]
    for k in np.unique(size_class):
        members = np.flatnonzero(size_class == k)
        lo, hi, live = _clipped_boxes(
            cs, n, rs + rm[members].max(), search + rm[members].max(), cm[members]
        )
        m_local, s_local = box_point_pairs(lo[live], hi[live], cm[members])
        s_idx, m_idx = np.flatnonzero(live)[s_local], members[m_local]
        d = cm[m_idx] - cs[s_idx]
        along = np.einsum("pd,pd->p", d, n[s_idx])
        perp = np.linalg.norm(d - along[:, None] * n[s_idx], axis=1)
        ok = (perp <= rs[s_idx] + rm[m_idx]) & (np.abs(along) <= search + rm[m_idx])
        out_s.append(s_idx[ok])
        out_m.append(m_idx[ok])
    s_idx, m_idx = np.concatenate(out_s), np.concatenate(out_m)
    order = np.lexsort((m_idx, s_idx))
    return s_idx[order], m_idx[order]


def _clipped_boxes(
    cs: np.ndarray, n: np.ndarray, reach: np.ndarray, length: float, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bounding boxes (lo, hi) of the segments cs + t n, |t| ≤ ``length``, clipped to the
    bounding box of ``points`` grown by ``reach`` (per segment) and then grown by ``reach``,
    and which segments meet that box at all (``live``): every point within ``reach`` of
    a segment is inside its box."""
    lo_p, hi_p = points.min(axis=0), points.max(axis=0)
    t0, t1 = np.full(len(cs), -length), np.full(len(cs), length)
    for d in range(cs.shape[1]):  # the slab of each axis
        nd = n[:, d]
        along = nd != 0
        safe = np.where(along, nd, 1.0)
        a = (lo_p[d] - reach - cs[:, d]) / safe
        b = (hi_p[d] + reach - cs[:, d]) / safe
        t0 = np.where(along, np.maximum(t0, np.minimum(a, b)), t0)
        t1 = np.where(along, np.minimum(t1, np.maximum(a, b)), t1)
        beside = ~along & ((cs[:, d] < lo_p[d] - reach) | (cs[:, d] > hi_p[d] + reach))
        t1 = np.where(beside, -np.inf, t1)
    live = t0 <= t1
    p0, p1 = cs + t0[:, None] * n, cs + np.where(live, t1, t0)[:, None] * n
    return np.minimum(p0, p1) - reach[:, None], np.maximum(p0, p1) + reach[:, None], live


def _nodal_sum(
    V: fem.FunctionSpace, nodes: np.ndarray, values: np.ndarray, bs: int = 1
) -> np.ndarray:
    """Σ over facets of per-vertex ``values`` at their local ``nodes``, summed on the owners
    (owned and ghost entries, ghosts updated)."""
    vec = spaces.zero_vector(V, bs)
    arr = vec.array.reshape(-1, bs)
    np.add.at(arr, nodes.ravel(), values.reshape(-1, bs))
    vec.scatter_reverse(la.InsertMode.add)
    vec.scatter_forward()
    return vec.array.copy() if bs == 1 else vec.array.reshape(-1, bs).copy()


def _to_owners(comm: MPI.Comm, imap, rows_local: np.ndarray, *columns: np.ndarray):
    """Send entries keyed by a local node (owned or ghost) to that node's owner; returns the
    global node of each received entry and the received columns."""
    n_owned = imap.size_local
    owner = np.full(len(rows_local), comm.rank)
    ghost = rows_local >= n_owned
    owner[ghost] = imap.owners[rows_local[ghost] - n_owned]
    rows_g = (
        imap.local_to_global(rows_local.astype(np.int32))
        if len(rows_local)
        else np.zeros(0, np.int64)
    )
    send = [tuple(a[owner == r] for a in (rows_g, *columns)) for r in range(comm.size)]
    recv = comm.alltoall(send)
    return tuple(np.concatenate([r[k] for r in recv]) for k in range(1 + len(columns)))


def _frames(comm, V, nsum: np.ndarray, fixed: np.ndarray, Xs: np.ndarray, key: str):
    """Frames of the slave nodes from the summed facet normals (:func:`basis.node_frames`);
    a node whose normal lies mostly along a component fixed by symmetry is an error."""
    normals, frames, projectors, absolute, bad = node_frames(nsum, fixed, V.dofmap.index_map_bs)
    if comm.allreduce(int(bad.sum()), op=MPI.SUM):
        where = _first_point(comm, V, np.flatnonzero(bad), Xs)
        raise ConfigError(
            f"{key}.slave: the slave node at {where} has a symmetry condition along its "
            "contact normal"
        )
    return normals, frames, projectors, absolute


def _node_matrix(
    V: fem.FunctionSpace, rows: np.ndarray, cols: np.ndarray, vals: np.ndarray
) -> PETSc.Mat:
    """Scalar AIJ matrix in V's node layout from owned (local row, global column) entries."""
    imap = V.dofmap.index_map
    n_owned = imap.size_local
    order = np.lexsort((cols, rows))
    rows, cols, vals = rows[order], cols[order], vals[order]
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=n_owned))]).astype(
        PETSc.IntType
    )
    sizes = ((n_owned, imap.size_global), (n_owned, imap.size_global))
    csr = (indptr, cols.astype(PETSc.IntType), vals)
    M = PETSc.Mat().createAIJ(sizes, comm=V.mesh.comm, csr=csr)  # type: ignore[arg-type]
    M.assemble()
    return M


def _first_point(
    comm: MPI.Comm, V: fem.FunctionSpace, nodes: np.ndarray, X: np.ndarray | None = None
) -> str:
    """'(x, y[, z])' of the first listed node on the lowest rank that has one."""
    gdim = V.mesh.geometry.dim
    mine = None
    if len(nodes):
        X = V.tabulate_dof_coordinates()[:, :gdim] if X is None else X
        mine = X[nodes[0]].tolist()
    point = next(p for p in comm.allgather(mine) if p is not None)
    return "(" + ", ".join(f"{c:.6g}" for c in point) + ")"


def _no_master(comm, V, nodes: np.ndarray, key: str, pair: MortarPair, search: float) -> None:
    if comm.allreduce(len(nodes), op=MPI.SUM):
        total = comm.allreduce(len(nodes), op=MPI.SUM)
        where = _first_point(comm, V, nodes)
        slave, master = pair.names
        raise ConfigError(
            f"{key}.slave: {total} slave node(s) of {slave!r}, e.g. at {where}, have no "
            f"master facet of {master!r} within the search distance "
            f"{search:.4g} ({key}.search) facing (at least half of) their facets; "
            f"restrict the slave part "
            "to lie within the master surface, or raise the search distance"
        )


def to_master(result: Result, values: np.ndarray) -> np.ndarray:
    """Nodal data of the slave nodes carried to the master nodes the way the mortar
    coupling carries forces, (Σ_i M_ij v_i) / ∫ φ_j^m, per component: ``values`` (local
    nodes, k) → (local nodes, k), 0 off the master surfaces (owned and ghost entries)."""
    p = result.problem
    imap = p.V.dofmap.index_map
    n_owned = imap.size_local
    k = values.shape[1]
    v = PETSc.Vec().createMPI((n_owned, imap.size_global), comm=p.V.mesh.comm)
    y = v.duplicate()
    out = la.vector(imap, k)
    arr = out.array.reshape(-1, k)
    weight = np.zeros(n_owned + imap.num_ghosts)
    couplings = p.data.couplings or []
    for coupling in couplings:
        weight += coupling.master_weights.array
    for comp in range(k):
        v.array[:] = values[:n_owned, comp]
        for coupling in couplings:
            coupling.M.multTranspose(v, y)  # Σ_i M_ij v_i
            arr[:n_owned, comp] += y.array_r
    out.scatter_forward()
    for vec in (v, y):
        vec.destroy()
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(weight[:, None] > 0, arr / np.where(weight > 0, weight, 1.0)[:, None], 0.0)


def master_pressure(result: Result) -> fem.Function:
    """λ^m on the output space (nodal; 0 away from the master surfaces), named
    ``lambda_master``."""
    p = result.problem
    S, bs = p.output.space, p.V.dofmap.index_map_bs
    assert S is not None and p.output.map is not None  # a bodies problem has its output space
    node_of_s = p.output.map // bs
    lam_nodes = np.zeros((len(node_of_s), 1))
    lam_nodes[node_of_s, 0] = result.lmbda_h.x.array
    fn = fem.Function(S, name="lambda_master")
    fn.x.array[:] = to_master(result, lam_nodes)[node_of_s, 0]
    return fn


def master_vector(result: Result, fn: fem.Function) -> fem.Function:
    """A vector nodal function (on V) of the slave nodes carried to the master nodes."""
    bs = fn.function_space.dofmap.index_map_bs
    out = fem.Function(fn.function_space)
    out.x.array[:] = to_master(result, fn.x.array.reshape(-1, bs)).ravel()
    return out
