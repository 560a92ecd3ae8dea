"""The hp space V_hp ⊂ V = P_{p_max} on a DOLFINx mesh (docs/theory.md §11), its basis as the
columns of Q (u = Q x) and the left inverse L (x = L u for u ∈ V_hp).

Each cell T carries a degree p_T ∈ {1, …, p_max}; each edge (and face, 3D) the minimum of
the degrees of the cells around it (the minimum rule), lowered further where a ``cap`` asks
(the facets of a contact boundary in 3D: degree 1 and their edges too).  Then

    V_hp = {v ∈ C⁰ : v|_T ∈ P_{p_T}(T), v|_e ∈ P_{p_e}(e) on every edge and face e} ⊂ V,

with the basis of :mod:`.reference`.  The unknowns x live in V's own layout: the unknown of a
basis function sits on one DoF of degree p_max of its entity (its *slot*); the other DoFs
are *inactive* (their x is 0, their row of the reduced system the identity).  So x and u
share one parallel layout, and the reduction K_hp = Qᵀ K Q, b_hp = Qᵀ b is the change of
basis the solvers already know (rotations, dual mortar).

Parallel: a rank sets the rows of Q of the DoFs it owns, from any of its cells (owned or
ghost) that contains the DoF — every basis function is continuous, so every cell gives the
same value; the columns are global.  The degrees of ghost cells and of entities shared
between ranks are made consistent first (a min-reduction over the ranks that hold them).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from dolfinx import fem, la
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from .reference import LocalBasis, local_basis


class HPSpace:
    """V_hp on ``msh`` for the owned cells' ``degrees`` (module docstring).

    Args:
        msh: A simplex mesh with affine geometry.
        p_max: The degree of the Lagrange space V that contains V_hp.
        degrees: p_T of the owned cells (int, 1 … p_max).
        caps: Optional local facet indices whose degree (and, in 3D, their edges') is at
            most ``cap``.
        cap: The degree of the capped facets.
    """

    def __init__(
        self,
        msh: dmesh.Mesh,
        p_max: int,
        degrees: np.ndarray,
        caps: np.ndarray | None = None,
        cap: int = 1,
    ):
        tdim = msh.topology.dim
        self.mesh, self.p_max, self.tdim = msh, p_max, tdim
        self.V = fem.functionspace(msh, ("Lagrange", p_max))
        cmap = msh.topology.index_map(tdim)
        n_owned = cmap.size_local
        degrees = np.asarray(degrees, dtype=np.int32)
        if len(degrees) != n_owned or (n_owned and (degrees.min() < 1 or degrees.max() > p_max)):
            raise ValueError(f"degrees: one degree in 1 … {p_max} per owned cell expected")
        cells = la.vector(cmap, dtype=np.int32)
        cells.array[:n_owned] = degrees
        cells.scatter_forward()
        self.cell_degrees = cells.array.copy()  # owned and ghost cells
        self.entity_degrees = [self._entity_degrees(dim, caps, cap) for dim in range(1, tdim)]
        self._build()

    # ------------------------------------------------------------------ entity degrees
    def _entity_degrees(self, dim: int, caps: np.ndarray | None, cap: int) -> np.ndarray:
        """p_e = the smallest degree of the cells (and caps) around each local entity of
        dimension ``dim``, the same on every rank: for each threshold k, the owner counts
        the cells of degree ≤ k around the entity on all ranks."""
        msh, tdim = self.mesh, self.tdim
        msh.topology.create_entities(dim)
        msh.topology.create_connectivity(tdim, dim)
        imap = msh.topology.index_map(dim)
        n = imap.size_local + imap.num_ghosts
        per = math.comb(tdim + 1, dim + 1)
        ents = msh.topology.connectivity(tdim, dim).array.reshape(-1, per)
        own = np.full(n, self.p_max, dtype=np.int32)
        np.minimum.at(own, ents.ravel(), np.repeat(self.cell_degrees, per))
        if caps is not None and len(caps):
            capped = np.asarray(caps, dtype=np.int32)
            if dim < tdim - 1:  # the closure of the capped facets
                msh.topology.create_connectivity(tdim - 1, dim)
                capped = dmesh.compute_incident_entities(msh.topology, capped, tdim - 1, dim)
            if dim <= tdim - 1:
                own[capped] = np.minimum(own[capped], cap)
        out = np.full(n, self.p_max, dtype=np.int32)
        marks = la.vector(imap, dtype=np.int32)
        for k in range(self.p_max - 1, 0, -1):
            marks.array[:] = (own <= k).astype(np.int32)
            marks.scatter_reverse(la.InsertMode.add)
            marks.scatter_forward()
            out[marks.array > 0] = k
        return out

    # ------------------------------------------------------------------ the basis
    def _build(self) -> None:
        msh, tdim, V = self.mesh, self.tdim, self.V
        msh.topology.create_connectivity(tdim, 0)
        c2v = msh.topology.connectivity(tdim, 0).array.reshape(-1, tdim + 1)
        vmap = msh.topology.index_map(0)
        gv = vmap.local_to_global(c2v.ravel().astype(np.int32)).reshape(c2v.shape)
        order = np.argsort(np.argsort(gv, axis=1), axis=1)
        cols = [self.cell_degrees[:, None]]
        for dim in range(1, tdim):
            c2e = msh.topology.connectivity(tdim, dim).array.reshape(len(c2v), -1)
            cols.insert(len(cols) - 1, self.entity_degrees[dim - 1][c2e])
        keys = np.column_stack(cols + [order]).astype(np.int64)
        uniq, inverse = np.unique(keys, axis=0, return_inverse=True)
        self.groups: list[tuple[LocalBasis, np.ndarray]] = []
        widths = [c.shape[1] for c in cols]
        for g, key in enumerate(uniq):
            parts, start = [], 0
            for w in widths:
                parts.append(tuple(int(v) for v in key[start : start + w]))
                start += w
            basis = local_basis(tdim, self.p_max, tuple(parts), tuple(int(v) for v in key[start:]))
            self.groups.append((basis, np.flatnonzero(inverse.ravel() == g).astype(np.int32)))
        imap = V.dofmap.index_map
        n_local = imap.size_local + imap.num_ghosts
        dofs = V.dofmap.list
        self.active = np.zeros(n_local, dtype=bool)
        self.slot_dim = np.full(n_local, -1, dtype=np.int8)
        self.points = np.zeros((n_local, 3))  # the hp node of each active slot
        x = msh.geometry.x
        geo = msh.geometry.dofmaps[0]
        for basis, cells in self.groups:
            sl = dofs[cells][:, basis.slots]
            self.active[sl.ravel()] = True
            self.slot_dim[sl] = basis.dims[None, :]
            lam = np.column_stack([1.0 - basis.nodes.sum(axis=1), basis.nodes])
            self.points[sl] = np.einsum("qa,nak->nqk", lam, x[geo[cells]])
        self.dimension = msh.comm.allreduce(
            int(np.count_nonzero(self.active[: imap.size_local])), op=MPI.SUM
        )

    # ------------------------------------------------------------------ matrices
    def _matrix(self, which: str) -> PETSc.Mat:
        """Q (``which`` = "Q": rows p_max DoFs, columns slots) or L ("L": rows slots,
        columns p_max DoFs), AIJ with V's layout; each owned row from one of its cells."""
        V = self.V
        imap = V.dofmap.index_map
        n_owned, N = imap.size_local, imap.size_global
        dofs = V.dofmap.list
        rows, colsl, vals = [], [], []
        for basis, cells in self.groups:
            cd = dofs[cells]  # (n, n_pmax)
            sl = cd[:, basis.slots]  # (n, n_hp)
            if which == "Q":
                r = np.repeat(cd[:, :, None], sl.shape[1], axis=2)
                c = np.repeat(sl[:, None, :], cd.shape[1], axis=1)
                v = np.broadcast_to(basis.Q, r.shape)
            else:
                r = np.repeat(sl[:, :, None], cd.shape[1], axis=2)
                c = np.repeat(cd[:, None, :], sl.shape[1], axis=1)
                v = np.broadcast_to(basis.L, r.shape)
            keep = (r < n_owned) & (np.abs(v) > 1e-14)
            rows.append(r[keep])
            colsl.append(c[keep])
            vals.append(v[keep])
        row = np.concatenate(rows).astype(np.int64)
        col = np.concatenate(colsl).astype(np.int64)
        val = np.concatenate(vals)
        key = row * (n_owned + imap.num_ghosts + 1) + col
        _, first = np.unique(key, return_index=True)  # one cell's value per entry
        row, col, val = row[first], col[first], val[first]
        gcol = imap.local_to_global(col.astype(np.int32)).astype(PETSc.IntType)
        order = np.lexsort((gcol, row))
        row, gcol, val = row[order], gcol[order], val[order]
        indptr = np.zeros(n_owned + 1, dtype=PETSc.IntType)
        np.add.at(indptr, row + 1, 1)
        indptr = np.cumsum(indptr).astype(PETSc.IntType)
        M = PETSc.Mat().createAIJ(
            ((n_owned, N), (n_owned, N)),
            csr=(indptr, gcol, val),  # type: ignore[arg-type]
            comm=self.mesh.comm,
        )
        M.assemble()
        return M

    def matrices(self) -> tuple[PETSc.Mat, PETSc.Mat]:
        """(Q, L): u = Q x for the hp coefficients x; x = L u for u ∈ V_hp (L Q = I on the
        active slots, 0 on the inactive ones)."""
        return self._matrix("Q"), self._matrix("L")

    def vector_matrices(self, bs: int) -> tuple[PETSc.Mat, PETSc.Mat]:
        """(Q, L) of the vector space V_hp^bs (each component in V_hp) in the blocked layout
        of P_{p_max}^bs: Q ⊗ I_bs and L ⊗ I_bs, row (i, a) = the scalar row i on the
        component a's columns (j, a)."""
        return tuple(_blocked(M, bs) for M in self.matrices())  # type: ignore[return-value]

    # ------------------------------------------------------------------ functions
    def interpolate(self, values: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """The hp interpolant's coefficients x (local array, owned and ghost slots; 0 on
        inactive ones) of the function given by ``values`` (points (3, n) → (n,)): exact
        at every hp node."""
        dofs = self.V.dofmap.list
        x = np.zeros(len(self.active))
        act = np.flatnonzero(self.active)
        vals = np.zeros(len(self.active))
        vals[act] = values(self.points[act].T)
        for basis, cells in self.groups:
            sl = dofs[cells][:, basis.slots]
            x[sl] = vals[sl] @ basis.Phi_inv.T
        return x

    def degree_function(self) -> fem.Function:
        """p_T as a DG0 function named ``degree`` (for XDMF: the hp mesh in ParaView)."""
        DG0 = fem.functionspace(self.mesh, ("DG", 0))
        fn = fem.Function(DG0, name="degree")
        n = len(fn.x.array)
        fn.x.array[:] = self.cell_degrees[:n]
        return fn

    def slots_of(self, dim: int, entities: np.ndarray) -> np.ndarray:
        """The local active slots (owned and ghost) on the closure of the given local
        entities of dimension ``dim``."""
        dofs = fem.locate_dofs_topological(self.V, dim, np.asarray(entities, dtype=np.int32))
        return dofs[self.active[dofs]]

    def owned_dimension(self) -> int:
        """The active slots this rank owns."""
        return int(np.count_nonzero(self.active[: self.V.dofmap.index_map.size_local]))


def _blocked(M: PETSc.Mat, bs: int) -> PETSc.Mat:
    """M ⊗ I_bs for a square AIJ matrix M in V's node layout: entry (i·bs + a, j·bs + a) =
    M_ij for each component a (consumes M)."""
    indptr, cols, vals = M.getValuesCSR()
    n, N = M.getLocalSize()[0], M.getSize()[0]
    comm = M.getComm()
    M.destroy()
    counts = np.diff(indptr)
    row = np.repeat(np.arange(len(counts)), counts)
    comp = np.arange(bs)
    # entries in the order (row i, component a, the row's own order)
    key_row = (row[None, :] * bs + comp[:, None]).ravel()
    entry = np.tile(np.arange(len(cols)), bs)
    order = np.lexsort((entry, key_row))
    new_cols = (cols[None, :] * bs + comp[:, None]).ravel()[order]
    new_vals = np.tile(vals, bs)[order]
    new_ptr = np.concatenate([[0], np.cumsum(np.repeat(counts, bs))]).astype(PETSc.IntType)
    B = PETSc.Mat().createAIJ(
        ((n * bs, N * bs), (n * bs, N * bs)),
        bsize=bs,
        csr=(new_ptr, new_cols.astype(PETSc.IntType), new_vals),  # type: ignore[arg-type]
        comm=comm,
    )
    B.assemble()
    return B
