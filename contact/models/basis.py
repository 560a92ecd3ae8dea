"""The change of basis u = Q x that makes every contact condition a bound on one unknown.

Two kinds of nodes carry a non-trivial block of Q (every other node keeps x_j = u_j):

* a *rotated* node j (rigid curved obstacle, docs/theory.md §1.3): u_j = R_j x_j with
  R_j = [n t (t2)] an orthonormal frame whose first axis is the contact normal;
* a *slave* node i of a mortar contact pair (docs/theory.md §1.5): its unknowns are the displacement
  relative to the master surface, in its own frame R_i,

      x_i = R_iᵀ (u_i − Σ_j c_ij P_i u_j),    c_ij = M_ij / D_ii,   P_i = Σ_{b relative} e_b e_bᵀ,

  i.e. u_i = R_i x_i + Σ_j c_ij P_i u_j.  The axes b of R_i are *relative* (normal, and the
  tangents: the relative slip) except those fixed by a symmetry condition, which stay
  absolute (x_i,b = e_b·u_i) so that the condition is still a bound on one unknown.

With no node both slave and master (a master node keeps x_j = u_j), Q is unit block
triangular: invertible, with the inverse written down directly,

      x_i = R_iᵀ u_i − Σ_j c_ij R_iᵀ P_i u_j   (slave),    x_j = R_jᵀ u_j   (other nodes).

Q and Q⁻¹ are parallel AIJ matrices with the layout of V (block size bs): each rank sets
the rows of its owned nodes, with global column indices (a master node may live on
another rank).  For pure rotations Q⁻¹ = Qᵀ.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from petsc4py import PETSc


def frame(n: np.ndarray, fixed_axes: tuple[int, ...] = ()) -> np.ndarray:
    """Columns n, t (, t2): an orthonormal frame whose first axis is the unit vector n.  In 3D
    a coordinate axis e_k in ``fixed_axes`` (with n_k = 0) becomes the second column, so a
    symmetry condition on u_k stays a condition on one unknown."""
    if len(n) == 2:
        return np.array([[n[0], -n[1]], [n[1], n[0]]])
    if fixed_axes:
        t1 = np.eye(3)[fixed_axes[0]]
    else:
        helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        t1 = np.cross(n, helper)
        t1 /= np.linalg.norm(t1)
    return np.column_stack([n, t1, np.cross(n, t1)])


def node_frames(n: np.ndarray, fixed: np.ndarray, bs: int) -> tuple:
    """Frames of contact nodes with normals ``n`` (k, gdim; any length) and components
    ``fixed`` (k, bs; bool) held by a symmetry condition: the normal loses the fixed
    components (the mirror image holds the other half) and is normalised; the frame is
    R = [n, e_k (fixed k) …, completion], the fixed axes absolute, the others relative
    (projector P onto them).  Returns (normals, frames, projectors, absolute axes per node,
    and a mask of nodes whose normal lay mostly along fixed components)."""
    n = np.array(n, dtype=float)
    length = np.linalg.norm(n, axis=1)
    n[fixed] = 0.0
    norm = np.linalg.norm(n, axis=1)
    bad = norm <= 0.5 * length
    n /= np.where(norm > 0, norm, 1.0)[:, None]
    assert bs == n.shape[1], "a frame per node of a vector field of gdim components"
    with np.errstate(invalid="ignore", divide="ignore"):  # degenerate normals: set below
        frames = _frames(n)
    projectors = np.tile(np.eye(bs), (len(n), 1, 1))  # every axis relative: P = R Rᵀ = I
    absolute: list[tuple[int, ...]] = [()] * len(n)
    # nodes with fixed components or a degenerate normal: one by one (a few, on symmetry planes)
    for i in np.flatnonzero(bad | fixed.any(axis=1)):
        axes = tuple(int(k) for k in np.flatnonzero(fixed[i]))
        if bad[i]:
            R = np.eye(bs)
        elif len(axes) <= 1:
            R = frame(n[i], axes)
        else:  # 3D, two fixed axes: n is the third coordinate axis
            R = np.column_stack([n[i], np.eye(3)[axes[0]], np.eye(3)[axes[1]]])
        frames[i] = R
        relative = [0] + list(range(1 + len(axes), bs))
        projectors[i] = R[:, relative] @ R[:, relative].T
        absolute[i] = axes
    return n, frames, projectors, absolute, bad


def _frames(n: np.ndarray) -> np.ndarray:
    """:func:`frame` of every row of the unit normals n (k, gdim), no fixed axes:
    (k, gdim, gdim)."""
    if n.shape[1] == 2:
        return np.stack([np.stack([n[:, 0], -n[:, 1]], 1), np.stack([n[:, 1], n[:, 0]], 1)], 1)
    helper = np.where((np.abs(n[:, 0]) < 0.9)[:, None], np.eye(3)[0], np.eye(3)[1])
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return np.stack([n, t1, np.cross(n, t1)], axis=2)


def change_of_basis(
    V: fem.FunctionSpace,
    K: PETSc.Mat,
    nodes: np.ndarray,
    frames: np.ndarray,
    coupling: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    projectors: np.ndarray | None = None,
) -> tuple[PETSc.Mat, PETSc.Mat]:
    """(Q, Q⁻¹) for owned local ``nodes`` with frames (n, bs, bs) and, optionally, the mortar
    ``coupling`` (rows, cols, c): entry c_ij with ``rows`` an index into ``nodes`` (slave i)
    and ``cols`` the *global* node index of master j; ``projectors`` (n, bs, bs) are the P_i
    of the slave nodes (the identity if omitted).  Every other owned node gets the identity."""
    bs = V.dofmap.index_map_bs
    imap = V.dofmap.index_map
    n_local = imap.size_local
    first = imap.local_range[0]
    blocks = np.tile(np.eye(bs), (n_local, 1, 1))
    blocks[nodes] = frames
    inverse_blocks = blocks.transpose(0, 2, 1).copy()
    # per owned node: its own block, then its coupling blocks (global node, block)
    own_cols = first + np.arange(n_local)
    if coupling is None or len(coupling[0]) == 0:
        row_node = own_cols - first
        cols, Qb, Qib = own_cols, blocks, inverse_blocks
    else:
        rows, master, c = coupling
        P = np.tile(np.eye(bs), (len(nodes), 1, 1)) if projectors is None else projectors
        slave = nodes[rows]
        cP = c[:, None, None] * P[rows]  # c_ij P_i
        cRP = -c[:, None, None] * np.einsum("nba,nbc->nac", frames[rows], P[rows])  # −c_ij R_iᵀ P_i
        row_node = np.concatenate([np.arange(n_local), slave])
        cols = np.concatenate([own_cols, master])
        Qb = np.concatenate([blocks, cP])
        Qib = np.concatenate([inverse_blocks, cRP])
    order = np.lexsort((cols, row_node))
    row_node, cols, Qb, Qib = row_node[order], cols[order], Qb[order], Qib[order]
    per_node = np.bincount(row_node, minlength=n_local)
    return _blocked_csr(K, bs, per_node, cols, Qb), _blocked_csr(K, bs, per_node, cols, Qib)


def _blocked_csr(
    K: PETSc.Mat, bs: int, per_node: np.ndarray, cols: np.ndarray, blocks: np.ndarray
) -> PETSc.Mat:
    """AIJ matrix with K's layout from node blocks sorted by (row node, column node):
    ``per_node[i]`` blocks in row node i, block columns ``cols`` (global nodes)."""
    n_local = len(per_node)
    # scalar row (i, a) holds, for each block (i, j), the columns (j, 0 … bs−1)
    block_start = np.concatenate([[0], np.cumsum(per_node)])
    row_len = np.repeat(per_node * bs, bs)  # per scalar row
    indptr = np.concatenate([[0], np.cumsum(row_len)]).astype(PETSc.IntType)
    indices = np.empty(indptr[-1], dtype=PETSc.IntType)
    values = np.empty(indptr[-1])
    scalar_cols = (cols[:, None] * bs + np.arange(bs)).astype(PETSc.IntType)  # (nblocks, bs)
    # vectorised fill: scalar row (i, a) = concatenation over its blocks of [cols_j*bs + b]_b
    node_of_block = np.repeat(np.arange(n_local), per_node)
    rank_in_row = np.arange(len(cols)) - block_start[node_of_block]
    for a in range(bs):
        # first entry of the block in row (i, a)
        start = indptr[node_of_block * bs + a] + rank_in_row * bs
        pos = start[:, None] + np.arange(bs)
        indices[pos] = scalar_cols
        values[pos] = blocks[:, a, :]
    sizes, csr = K.getSizes(), (indptr, indices, values)
    Q = PETSc.Mat().createAIJ(sizes, bsize=bs, comm=K.comm, csr=csr)  # type: ignore[arg-type]
    Q.assemble()
    return Q
