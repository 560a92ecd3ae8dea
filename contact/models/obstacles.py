"""A rigid obstacle (:class:`~.constraints.RigidObstacle`) as the nodal constraint set of an
elastic body (docs/theory.md §1.3), and the change of basis u = Q x that rotates contact
nodes to their axes.

For a rigid plane through p with outward normal ν (pointing from the obstacle to the body),
n = −ν and g(x) = (x − p)·ν; for a rigid circle/sphere (centre c, radius R_o, the body
outside) n = (c − x)/|c − x| and g = |x − c| − R_o (:mod:`.constraints`: any surface's
n and g).  When n is a coordinate direction ±e_k, u·n ≤ g is a bound on the single
component u_k (σ = n_k, bound n_k g, :func:`plane_contact`); otherwise each contact node's
displacement is rotated to its (n, t) axes, u = Q x with Q orthogonal and block-diagonal,
K̃ = Qᵀ K Q, b̃ = Qᵀ b, so that it is a bound on one unknown again
(:func:`rotated_contact`).  Each function returns the :class:`~.constraints.ContactSet`
the obstacle determines (constraint, output space, basis, contact data).

A finite-strain body meets the obstacle on the current configuration instead
(:func:`current_contact`): the obstacle's signed distance is evaluated at the deformed
nodes x = X + u at every Newton iterate, and the normal and frame follow it
(:mod:`contact.solvers.current`).
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from ..base.errors import ConfigError
from ..solvers.problem import Constraint, NodeBlockMatrix, Output, ProblemData
from .basis import frame
from .constraints import ContactSet, Plane, RigidObstacle, measure_facets
from .problem import coordinate_scale, first_contact_point, first_contact_row, lumped_weights


def contact_nodes(V: fem.FunctionSpace, k: int, facets: np.ndarray):
    """For component k: its collapsed space S, the S → V map, and the (V-DoF, S-DoF) pairs
    on the contact facets."""
    S, collapsed = V.sub(k).collapse()
    s_to_v = np.asarray(collapsed, dtype=np.int32).ravel()
    tdim = V.mesh.topology.dim
    v_dofs, s_dofs = fem.locate_dofs_topological((V.sub(k), S), tdim - 1, facets)
    return S, s_to_v, v_dofs, s_dofs


def plane_contact(V: fem.FunctionSpace, fixed: np.ndarray, obstacle: RigidObstacle) -> ContactSet:
    """A rigid plane with a coordinate normal n = −ν = ±e_k: u·n ≤ g is the bound
    σ(n_k g − u_k) ≥ 0 on one component (σ = n_k), g(x) = (x − p)·ν."""
    plane = obstacle.surface
    assert isinstance(plane, Plane) and plane.axis() is not None  # a coordinate plane
    msh = V.mesh
    gdim = msh.geometry.dim
    nu_o, p = plane.normal, plane.point
    k = int(np.argmax(np.abs(nu_o)))
    n_k = float(np.sign(-nu_o[k]))
    S, s_to_v, v_dofs, s_dofs = contact_nodes(V, k, measure_facets(obstacle.measure))
    n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    keep = (v_dofs < n_owned) & ~np.isin(v_dofs, fixed)
    dofs, sd = v_dofs[keep].astype(np.int32), s_dofs[keep]
    w = lumped_weights(S, obstacle.measure)[sd]
    gap = (S.tabulate_dof_coordinates()[:, :gdim] - p) @ nu_o  # g(x) = (x − p)·ν
    bound = fem.Function(S, name="bound")
    bound.x.array[:] = n_k * gap
    n_ufl, g_ufl = plane.expression(ufl.SpatialCoordinate(msh))
    return ContactSet(
        Constraint(dofs, n_k * gap[sd], w, n_k, coordinate_scale(msh)),
        Output(S, s_to_v, bound, lambda_sign=n_k),
        ProblemData(n=-nu_o, n_ufl=n_ufl, g_ufl=g_ufl),
    )


def rotated_contact(
    V: fem.FunctionSpace, K: PETSc.Mat, b: PETSc.Vec, fixed: np.ndarray, obstacle: RigidObstacle
) -> ContactSet:
    """Contact along a normal n(x) that is not a coordinate direction (a tilted plane, a
    circle, a sphere, any surface): each contact node's displacement is rotated to its own
    axes (n, t[, t2]): u = Q x with Q orthogonal block-diagonal, K̃ = Qᵀ K Q, b̃ = Qᵀ b, and
    u·n ≤ g becomes the bound x_{i,0} ≤ g_i on one unknown, as for a coordinate plane.
    Contact nodes with a Dirichlet or symmetry condition on some component cannot be
    rotated and are refused (fully fixed ones are left out); nodes inside a curved obstacle
    at rest are refused (a moving one may have moved into the body: a prescribed
    penetration)."""
    msh = V.mesh
    gdim, bs = msh.geometry.dim, V.dofmap.index_map_bs
    surface = obstacle.surface
    S, s_to_v, v_dofs, s_dofs = contact_nodes(V, 0, measure_facets(obstacle.measure))
    nodes = v_dofs // bs
    node_fixed = np.isin(nodes[:, None] * bs + np.arange(bs), fixed)
    partial = node_fixed.any(axis=1) & ~node_fixed.all(axis=1)
    if msh.comm.allreduce(int(partial.sum())):
        raise ConfigError(
            "obstacle: contact nodes with a symmetry or partial Dirichlet condition "
            "cannot be rotated to the obstacle's normal"
        )
    keep = (nodes < V.dofmap.index_map.size_local) & ~node_fixed.all(axis=1)
    nodes, sd = nodes[keep], s_dofs[keep]
    Xs = S.tabulate_dof_coordinates()[:, :gdim]
    g_all = surface.project(Xs)[0]
    inside = g_all[sd] < -1e-12 * max(1.0, float(np.max(np.abs(Xs))))
    at_rest = not isinstance(surface, Plane) and not obstacle.moving
    if at_rest and msh.comm.allreduce(int(np.sum(inside))):
        raise ConfigError("obstacle: contact nodes lie inside the obstacle (negative initial gap)")
    normals = surface.project(Xs[sd])[1]
    Q = _rotation(V, K, nodes, normals)
    Kt = K.PtAP(Q)  # K̃ = Qᵀ K Q
    bt = b.duplicate()
    Q.multTranspose(b, bt)  # b̃ = Qᵀ b
    w = lumped_weights(S, obstacle.measure)[sd]
    bound = fem.Function(S, name="bound")
    bound.x.array[:] = g_all
    first = first_contact_point(msh.comm, Xs[sd], g_all[sd])
    n_ufl, g_ufl = surface.expression(ufl.SpatialCoordinate(msh))
    return ContactSet(
        Constraint((nodes * bs).astype(np.int32), g_all[sd], w, 1.0, coordinate_scale(msh)),
        Output(S, s_to_v, bound),
        ProblemData(
            n=surface.project(first[None, :])[1][0], normals=normals, n_ufl=n_ufl, g_ufl=g_ufl
        ),
        K=Kt,
        b=bt,
        basis=Q,
    )


def _rotation(
    V: fem.FunctionSpace, K: PETSc.Mat, nodes: np.ndarray, normals: np.ndarray
) -> PETSc.Mat:
    """Q (u = Q x): identity, except the blocks [n t (t2)] of the given owned nodes."""
    Q = NodeBlockMatrix(K, V.dofmap.index_map_bs)
    blocks = Q.identity()
    for node, n in zip(nodes, normals):
        blocks[node] = frame(n)
    return Q.set(blocks)


def current_contact(
    V: fem.FunctionSpace,
    fixed: np.ndarray,
    obstacle: RigidObstacle,
    u_prev: fem.Function | None = None,
) -> ContactSet:
    """Contact on the current configuration (:mod:`contact.solvers.current`): the gap of the
    deformed node x = X + u to the obstacle's surface, normal and frame followed at every
    Newton iterate; the unknowns stay the displacements (no change of basis).  Contact
    nodes fixed in every component are left out; one with some components fixed (a
    symmetry plane) is refused when the obstacle's normal there lies mostly along them (its
    constrained normal ñ = P n / |P n| would not be the obstacle's).  The constraint's g
    are the reference gaps g(X) (the first point of contact, the output's bound); λ_i is
    the normal component of the nodal force per reference area (nominal pressure).
    ``u_prev``: the previous load step's displacement (friction's slips start there), with
    the obstacle's translation since then (``obstacle.motion``)."""
    from ..solvers.problem import CurrentContact

    msh = V.mesh
    gdim, bs = msh.geometry.dim, V.dofmap.index_map_bs
    S, s_to_v, v_dofs, s_dofs = contact_nodes(V, 0, measure_facets(obstacle.measure))
    nodes = v_dofs // bs
    node_fixed = np.isin(nodes[:, None] * bs + np.arange(bs), fixed)
    keep = (nodes < V.dofmap.index_map.size_local) & ~node_fixed.all(axis=1)
    nodes, sd, node_fixed = nodes[keep], s_dofs[keep], node_fixed[keep]
    Xs = S.tabulate_dof_coordinates()[:, :gdim]
    X = Xs[sd]
    surface = obstacle.surface
    g0, n0, _ = surface.project(X)
    along_fixed = np.linalg.norm(np.where(node_fixed, 0.0, n0), axis=1) <= 0.5
    if msh.comm.allreduce(int(np.sum(along_fixed))):
        raise ConfigError(
            "obstacle: at contact nodes on a symmetry or Dirichlet part the obstacle's normal "
            "lies mostly along the fixed components (the obstacle is not symmetric about it)"
        )
    previous = (
        np.zeros((len(nodes), gdim))
        if u_prev is None
        else u_prev.x.array[nodes[:, None] * bs + np.arange(gdim)]
    )
    motion = np.zeros(gdim) if obstacle.motion is None else np.asarray(obstacle.motion, float)
    w = lumped_weights(S, obstacle.measure)[sd]
    bound = fem.Function(S, name="bound")
    bound.x.array[:] = surface.project(Xs)[0]
    first = first_contact_row(msh.comm, X, g0, n0)
    return ContactSet(
        Constraint((nodes * bs).astype(np.int32), g0, w, 1.0, coordinate_scale(msh)),
        Output(S, s_to_v, bound),
        ProblemData(n=first),
        current=CurrentContact(nodes.astype(np.int32), X, node_fixed, surface, previous, motion),
    )
