"""Friction on the contact nodes of an elastic body (docs/theory.md §1.4): the friction law of
a rigid obstacle's or a mortar pair's contact nodes (:class:`~.constraints.Tresca`,
:class:`~.constraints.Coulomb`) as the solver's :class:`~contact.solvers.problem.FrictionSet`.

Per contact node i (the constrained nodes of :class:`~contact.solvers.problem.Constraint`)
with normal n_i and tangent(s) t_i (1 in 2D, 2 in 3D), in the solver's unknowns x:

* the normal unknown x_n,i (already the constraint's DoF) and the tangential unknowns
  x_t,i: for a coordinate plane n = ±e_k the node's other displacement components
  (t = e_j, j ≠ k); for a tilted plane, a circle or a sphere the rotated unknowns 1..d−1
  of the node's frame [n t (t2)] (u = Q x, :mod:`contact.models.obstacles`);
* the tangential multiplier  λ_t,i = R_t,i / w_i  (R = K x − b; the traction on the body
  along t_i, in stress units) and μ_t = −λ_t;
* the slip increment  s_t,i = x_t,i − x_t,i^prev  (m: the displacement of the body relative
  to the rigid obstacle since the previous load step; x^prev = 0 on the first step);
* the friction bound ρ_i ≥ 0 (stress): Tresca ρ_i = s(x_i, t) (``friction.threshold``),
  Coulomb ρ_i = F·max(0, ξ_i) (``friction.coefficient`` F, see
  :mod:`contact.solvers.friction`);
* the tangential scaling c_t,i (stress per length; ``friction.c_t``).  ``auto``:

      c_t,i = K_tt,i / (κ_t w_i),

  K_tt,i the mean diagonal stiffness of the node's tangential unknowns, κ_t =
  ``friction.kappa_t`` (default 1).  Then c_t s_t = K_tt s_t / w is the tangential traction a
  Jacobi step of s_t would create: z = μ_t + c_t s_t adds two tractions of the same
  discrete origin, as the normal ``c: auto`` compares two lengths
  (:func:`contact.solvers.problem.nodal_scaling`); scaling E scales both, so it cancels.

Two bodies.  The tangential unknowns are read in the solver's unknowns x of the change of
basis u = Q x, and the frames from Q's diagonal node blocks; with the mortar basis of
docs/theory.md §1.5, whose slave unknowns are relative displacements (slave minus the
mortar-projected master), x_t − x_t^prev is the relative slip and the same rows apply unchanged.
On P2 triangles the slave unknowns are the transformed values ũ = T⁻¹ u (u = T Q x): x_t is
the relative slip in the transformed basis φ̃, λ_t = R̃_t / D̃_ii the tangential multiplier in
its dual basis (as λ_n), and Coulomb's bound acts node by node on the pair (λ_n, λ_t) of the
same dual function.  T scales the node block of an edge node by 1 − 2α (its other entries sit
on the edge's vertices), so the frames are the blocks' columns made unit.

Symmetry planes.  A contact node on a symmetry plane x_k = const has u_k = 0: that
tangential component is not free, it sticks by symmetry, and friction acts on the node's
other tangential components (none in 2D).  This is exact when the loading is symmetric
about the plane; a drag across a symmetry plane is not, and the Dirichlet data may not
prescribe one (checked here: a one-line error).  Tangential components fixed by Dirichlet
data are not free either.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base.errors import ConfigError
from ..solvers.problem import DiscreteProblem, FrictionSet
from .constraints import Coulomb, Tresca


def friction_set(
    problem: DiscreteProblem, law: Tresca | Coulomb, u_prev: fem.Function | None = None
) -> FrictionSet:
    """The friction data of ``law`` on the contact nodes of ``problem`` (elasticity: its
    constraint set's nodes); ``u_prev`` the previous load step's displacement, from which
    the slips are measured.  A Tresca threshold that is negative or undefined at a contact
    node is a ConfigError naming ``law.key``."""
    V, con = problem.V, problem.constraint
    comm = V.mesh.comm
    gdim, bs = V.mesh.geometry.dim, V.dofmap.index_map_bs
    nodes = con.dofs // bs
    current = problem.current
    if current is not None:  # the current frame's rows [n t (t2)] (contact.solvers.current)
        n_comp, t_comps = 0, np.arange(1, bs, dtype=np.int32)
        frames = np.zeros((len(nodes), gdim, bs - 1))  # set at each iterate
    elif problem.basis is None:  # coordinate plane: the normal is the component k
        n_comp = int(np.asarray(problem.data.n).nonzero()[0][0])
        t_comps = np.array([j for j in range(bs) if j != n_comp], dtype=np.int32)
        frames = np.broadcast_to(np.eye(gdim)[:, t_comps], (len(nodes), gdim, len(t_comps))).copy()
    else:  # rotated frames [n t (t2)]: the columns of Q's node blocks, made unit
        n_comp, t_comps = 0, np.arange(1, bs, dtype=np.int32)
        frames = node_blocks(problem.basis, bs)[nodes][:, :, t_comps]
        frames /= np.linalg.norm(frames, axis=1, keepdims=True)
    tangent = (nodes[:, None] * bs + t_comps[None, :]).astype(np.int32)
    fixed = np.concatenate([bc.dof_indices()[0] for bc in problem.bcs])
    free = ~np.isin(tangent, fixed)
    stiff, stiff_free = tangent, free  # the DoFs whose stiffness K_tt averages
    if current is not None:  # the node's fixed axes are the first tangent columns
        count = current.fixed.sum(axis=1)
        free = np.arange(bs - 1)[None, :] >= count[:, None]
        stiff = nodes[:, None] * bs + np.arange(bs)
        stiff_free = ~current.fixed
    _check_symmetry_drag(problem)

    options = law.options
    w = con.w
    diag = problem.K.getDiagonal()
    K_tt = np.where(stiff_free, diag.array_r[stiff], 0.0).sum(axis=1) / np.maximum(
        stiff_free.sum(axis=1), 1
    )
    diag.destroy()
    c_t = (
        K_tt / (options.kappa_t * w)
        if options.c_t == "auto"
        else np.full(len(nodes), float(options.c_t))
    )

    threshold = None
    if isinstance(law, Tresca):
        threshold = law.values(V, nodes)
        bad = comm.allreduce(int(np.sum(~(threshold >= 0))), op=MPI.SUM)
        if bad:
            raise ConfigError(
                f"{law.key}: negative or undefined at {bad} contact node(s){law.when} "
                "(a slip threshold is >= 0)"
            )
    return FrictionSet(
        law=law.law,
        n_comp=n_comp,
        t_comps=t_comps,
        tangent=tangent,
        free=free,
        frames=frames,
        c_t=c_t,
        threshold=threshold,
        coefficient=law.coefficient if isinstance(law, Coulomb) else None,
        # (on the current configuration the slip is the solver's: CurrentContact.u_prev)
        x_prev=previous_tangential(problem, tangent, u_prev),
        options=options.knobs(),
    )


def node_blocks(Q: PETSc.Mat, bs: int) -> np.ndarray:
    """The diagonal bs×bs block of every owned node of Q (local nodes, bs, bs): for the
    rotation u = Q x the node's frame F = [n t (t2)] (u_node = F x_node).  Entries outside
    the node's own block (a mortar basis couples slave and master nodes) are ignored."""
    lo, hi = Q.getOwnershipRange()
    indptr, cols, values = Q.getValuesCSR()
    rows = np.repeat(np.arange(hi - lo), np.diff(indptr))
    own = cols // bs == (lo + rows) // bs
    blocks = np.zeros(((hi - lo) // bs, bs, bs))
    blocks[rows[own] // bs, rows[own] % bs, cols[own] % bs] = values[own]
    return blocks


def previous_tangential(
    problem: DiscreteProblem, tangent: np.ndarray, u_prev: fem.Function | None
) -> np.ndarray:
    """x_t^prev: the tangential unknowns of the previous step's displacement (zero without)."""
    if u_prev is None:
        return np.zeros(tangent.shape)
    x = problem.b.duplicate()
    problem.to_unknowns(u_prev.x.petsc_vec, x)
    out = x.array_r[tangent].copy()
    x.destroy()
    return out


def _check_symmetry_drag(problem: DiscreteProblem) -> None:
    """A symmetry plane x_k = c keeps u_k = 0; Dirichlet data that moves its nodes along e_k
    (a drag across the plane) contradicts it: one line naming the data component."""
    bcs = problem.bcs
    if len(bcs) < 2:
        return
    bs = problem.V.dofmap.index_map_bs
    dirichlet = bcs[0].dof_indices()[0]
    values = np.zeros(problem.b.getLocalSize())
    bcs[0].set(values)  # u_D at the Dirichlet DoFs
    n_owned = len(values)
    clash = np.concatenate([np.intersect1d(bc.dof_indices()[0], dirichlet) for bc in bcs[1:]])
    clash = clash[clash < n_owned]
    scale = max(1.0, float(np.max(np.abs(values), initial=0.0)))
    bad = clash[np.abs(values[clash]) > 1e-12 * scale]
    comps = problem.V.mesh.comm.allgather(sorted(set((bad % bs).tolist())))
    comps = sorted(set(c for part in comps for c in part))
    if comps:
        raise ConfigError(
            f"data.u_D[{comps[0]}]: moves nodes of a symmetry plane across it; with "
            "friction a drag across a symmetry plane is not symmetric (model the "
            "full body)"
        )
