"""Elastic bodies no Dirichlet or symmetry condition holds (semi-coercive elasticity).

A rigid motion m of a body (a translation, or an infinitesimal rotation x ↦ A (x − c) with
A antisymmetric) has zero strain, so K m = 0 on the body's rows; if m also vanishes at
every DoF with a Dirichlet or symmetry condition, K is singular: only contact can hold the
body, and frictionless contact never holds a sliding motion.  Such a scene is not always
wrong (a body pressed into contact by a load is held once its contact nodes are active),
but when its solve fails this is why, and the message says so
(:func:`contact.solvers.result.finish`), as the one-body scalar scene without a Dirichlet
part does (``DiscreteProblem.semicoercive``).

Bodies that share a node (bonded materials of one mesh) are one rigid unit.  For each unit
the Gram matrix G = Σ_i m(x_i) m(x_i)ᵀ of its 3 (2D) or 6 (3D) rigid motions over the
unit's fixed DoFs i (owned, summed over all ranks; coordinates relative to the unit's
bounding box, scaled by its size) is singular exactly when some motion is free: its
eigenvalues at most FREE_RTOL · trace G count the free motions.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem, la
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..base import spaces

FREE_RTOL = 1e-10


def floating_bodies(
    V: fem.FunctionSpace, fixed: np.ndarray, bodies: dmesh.MeshTags | None, names: list[str]
) -> list[tuple[str, int]]:
    """The rigid units of the vector space ``V`` (one per body of the cell tags ``bodies``,
    k + 1 for ``names[k]``, bodies sharing a node joined; the whole mesh if ``bodies`` is
    None, named ``''``) that the local DoFs ``fixed`` (Dirichlet and symmetry) do not hold,
    as (name, number of free rigid motions); names of joined bodies joined by '+'.
    Collective; the same list on every rank."""
    gdim, n_owned = V.mesh.geometry.dim, V.dofmap.index_map.size_local
    fixed = np.unique(fixed[fixed < n_owned * gdim])
    node, comp = fixed // gdim, fixed % gdim
    out = []
    for name, on, centre, size in _units(V, bodies, names):
        held = on[node]
        modes = _rigid_modes((_coordinates(V)[node[held]] - centre) / size, comp[held], gdim)
        free = _free(V.mesh.comm, modes)
        if free:
            out.append((name, free))
    return out


def free_in_contact(
    problem, bodies: dmesh.MeshTags | None, names: list[str], active: np.ndarray
) -> list[tuple[str, int]]:
    """The floating units of ``problem`` (:attr:`DiscreteProblem.floating`) that a solution
    with the active set ``active`` (a mask of ``problem.constraint.dofs``) still leaves free,
    as (name, number of free rigid motions).  A rigid motion m is held where its unknowns
    x = Q⁻¹ m are nonzero at a Dirichlet DoF or at an active constraint row (a normal or
    gap component); frictionless contact holds no sliding, so a body held by contact alone
    keeps its tangential motions and the solution is not unique (any sliding of it solves
    the problem as well).  Collective; the same list on every rank."""
    V = problem.V
    gdim, n_owned = V.mesh.geometry.dim, V.dofmap.index_map.size_local
    con = problem.constraint
    held = np.unique(
        np.concatenate([problem.dirichlet_rows(), con.dofs[np.asarray(active, dtype=bool)]])
    )
    held = held[held < n_owned * gdim].astype(np.int64)
    floating = dict(problem.floating)
    m, x = spaces.zero_function(V), problem.b.duplicate()
    X, comp = _coordinates(V), np.arange(n_owned * gdim) % gdim
    out = []
    for name, on, centre, size in _units(V, bodies, names):
        if name not in floating:
            continue
        dofs = np.flatnonzero(np.repeat(on, gdim))
        modes = _rigid_modes((X[dofs // gdim] - centre) / size, comp[dofs], gdim)
        columns = []
        for k in range(modes.shape[1]):  # each motion as the solver's unknowns x = Q⁻¹ m
            m.x.array[:] = 0.0
            m.x.array[dofs] = modes[:, k]
            m.x.scatter_forward()
            problem.to_unknowns(m.x.petsc_vec, x)
            columns.append(x.array_r[held].copy())
        free = _free(V.mesh.comm, np.column_stack(columns))
        if free:
            out.append((name, free))
    x.destroy()
    return out


def _units(V: fem.FunctionSpace, bodies: dmesh.MeshTags | None, names: list[str]):
    """(name, owned-node mask, centre, size) of each rigid unit (bodies joined where they
    share a node), the same on every rank."""
    msh, comm = V.mesh, V.mesh.comm
    gdim, imap = msh.geometry.dim, V.dofmap.index_map
    n_owned = imap.size_local
    cells = V.dofmap.list
    if bodies is None:
        member = np.ones((1, n_owned), dtype=bool)
        names = [""]
    else:
        member = np.zeros((len(names), n_owned), dtype=bool)
        body = np.zeros(len(cells), dtype=np.int32)
        body[bodies.indices] = bodies.values
        for k in range(len(names)):  # the owned nodes of body k's cells, on any rank
            flag = spaces.zero_vector(V)
            flag.array[cells[body == k + 1].ravel()] = 1.0
            flag.scatter_reverse(la.InsertMode.add)
            member[k] = flag.array[:n_owned] > 0
    X = _coordinates(V)
    out = []
    for unit in _join(comm, member):
        on = member[unit].any(axis=0)
        lo, hi = np.empty(gdim), np.empty(gdim)
        comm.Allreduce(X[on].min(axis=0, initial=np.inf), lo, op=MPI.MIN)
        comm.Allreduce(X[on].max(axis=0, initial=-np.inf), hi, op=MPI.MAX)
        size = max(float(np.max(hi - lo)), np.finfo(float).tiny)
        out.append(("+".join(names[k] for k in unit), on, 0.5 * (lo + hi), size))
    return out


def _coordinates(V: fem.FunctionSpace) -> np.ndarray:
    """The owned nodes' coordinates (n_owned × gdim)."""
    gdim = V.mesh.geometry.dim
    return V.tabulate_dof_coordinates()[: V.dofmap.index_map.size_local, :gdim]


def _free(comm: MPI.Comm, rows: np.ndarray) -> int:
    """How many motions (columns) the rows leave free: the eigenvalues of the Gram matrix
    Σ rows ᵀ rows (summed over ranks) at most FREE_RTOL · its trace."""
    G = comm.allreduce(rows.T @ rows, op=MPI.SUM)
    eig = np.linalg.eigvalsh(G)
    return int(np.sum(eig <= FREE_RTOL * max(float(np.trace(G)), 1.0)))


def _rigid_modes(x: np.ndarray, comp: np.ndarray, gdim: int) -> np.ndarray:
    """Row i: the gdim translations and the rotations (1 in 2D, 3 in 3D) at the DoF of
    component ``comp[i]`` of the point ``x[i]``."""
    rows = np.arange(len(comp))
    out = np.zeros((len(comp), 3 if gdim == 2 else 6))
    out[rows, comp] = 1.0
    for r, (i, j) in enumerate([(0, 1)] if gdim == 2 else [(0, 1), (1, 2), (2, 0)]):
        out[:, gdim + r] = np.where(comp == i, -x[:, j], 0.0) + np.where(comp == j, x[:, i], 0.0)
    return out


def _join(comm: MPI.Comm, member: np.ndarray) -> list[list[int]]:
    """Groups of the bodies (rows of ``member``, owned nodes) that share a node, on any rank."""
    n = len(member)
    share = comm.allreduce(member.astype(np.int64) @ member.T.astype(np.int64), op=MPI.SUM) > 0
    group = list(range(n))
    for a in range(n):
        for b in range(a + 1, n):
            if share[a, b]:
                old, new = group[b], group[a]
                group = [new if g == old else g for g in group]
    return [[k for k in range(n) if group[k] == g] for g in sorted(set(group))]
