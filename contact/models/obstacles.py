"""Rigid obstacles (plane, circle, sphere) as nodal constraint sets of the elastic model
(docs/theory.md §1.3), and the change of basis u = Q x that rotates contact nodes to their axes.

For a rigid plane through p with outward normal ν (pointing from the obstacle to the body),
n = −ν and g(x) = (x − p)·ν; for a rigid circle/sphere (centre c, radius R_o, the body
outside) n = (c − x)/|c − x| and g = |x − c| − R_o.  When n is a coordinate direction ±e_k,
u·n ≤ g is a bound on the single component u_k (σ = n_k, bound n_k g); otherwise each
contact node's displacement is rotated to its (n, t) axes, u = Q x with Q orthogonal and
block-diagonal, K̃ = Qᵀ K Q, b̃ = Qᵀ b, so that it is a bound on one unknown again.
Each function returns the pieces of :class:`contact.solvers.problem.DiscreteProblem` that
the obstacle determines (constraint, output space, basis, contact data).

A finite-strain body meets the obstacle on the current configuration instead
(:func:`current_contact`): the obstacle is a signed distance (:class:`RigidPlane`,
:class:`RigidBall`) evaluated at the deformed nodes x = X + u at every Newton iterate, and
the normal and frame follow it (:mod:`contact.solvers.current`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base.errors import ConfigError
from ..setup.obstacle import RigidObstacle, rigid_obstacle
from ..setup.scene import Scene
from ..solvers.problem import Constraint, NodeBlockMatrix
from .basis import frame
from .problem import coordinate_scale, lumped_weights


def _contact_nodes(V: fem.FunctionSpace, k: int, facets: np.ndarray):
    """For component k: its collapsed space S, the S → V map, and the (V-DoF, S-DoF) pairs
    on the contact facets."""
    S, collapsed = V.sub(k).collapse()
    s_to_v = np.asarray(collapsed, dtype=np.int32).ravel()
    tdim = V.mesh.topology.dim
    v_dofs, s_dofs = fem.locate_dofs_topological((V.sub(k), S), tdim - 1, facets)
    return S, s_to_v, v_dofs, s_dofs


def obstacle_shape(scene: Scene) -> tuple:
    """(normal, gap, n_ufl, g_ufl) of the scene's obstacle: ``normal``/``gap`` map node
    coordinates (n, gdim) to the unit normals n (towards the obstacle) and the initial gaps
    g, the UFL expressions are the same for forms.  Plane: n = −ν, g = (x − p)·ν; circle /
    sphere: n = (c − x)/|c − x|, g = |x − c| − R_o."""
    obstacle, msh = scene.config.obstacle, scene.mesh
    assert obstacle is not None  # the scene's rigid obstacle
    gdim = msh.geometry.dim
    X = ufl.SpatialCoordinate(msh)
    if obstacle.type == "plane":
        nu_o = np.asarray(obstacle.normal, dtype=float)
        nu_o = nu_o / np.linalg.norm(nu_o)
        p = plane_point(scene)
        if len(nu_o) != gdim or len(p) != gdim:
            raise ConfigError(
                f"obstacle: point and normal need {gdim} components in a {gdim}D scene"
            )
        return (
            lambda x: np.tile(-nu_o, (len(x), 1)),
            lambda x: (x - p) @ nu_o,
            ufl.as_vector((-nu_o).tolist()),  # n = −ν
            # g = (x − p)·ν
            ufl.dot(X - ufl.as_vector(p.tolist()), ufl.as_vector(nu_o.tolist())),
        )
    want = "circle" if gdim == 2 else "sphere"
    if obstacle.type != want:
        raise ConfigError(f"obstacle.type: a {gdim}D scene needs a {want}, got {obstacle.type}")
    assert obstacle.radius is not None  # checked at load
    centre, R_o = scene_obstacle(scene).center, float(obstacle.radius)
    assert centre is not None  # a circle / sphere has its centre (at t)
    if len(centre) != gdim:
        raise ConfigError(f"obstacle.center: needs {gdim} components in a {gdim}D scene")
    c_ufl = ufl.as_vector(centre.tolist())
    return (
        lambda x: (centre - x) / np.linalg.norm(centre - x, axis=1)[:, None],
        lambda x: np.linalg.norm(x - centre, axis=1) - R_o,
        (c_ufl - X) / ufl.sqrt(ufl.dot(c_ufl - X, c_ufl - X)),
        ufl.sqrt(ufl.dot(X - c_ufl, X - c_ufl)) - R_o,
    )


def scene_obstacle(scene: Scene, time: float | None = None) -> RigidObstacle:
    """The scene's rigid obstacle at its pseudo-time (or at ``time``): a plane's point or a
    circle's centre may be expressions of t, an obstacle moved along a load path."""
    config = scene.config
    assert config.obstacle is not None  # an elastic scene with an obstacle (checked at load)
    return rigid_obstacle(config.obstacle, config.constants, scene.time if time is None else time)


def plane_point(scene: Scene) -> np.ndarray:
    """The plane's point p at the scene's pseudo-time."""
    return scene_obstacle(scene).position


def plane_contact(scene: Scene, V, K, b, fixed, ds) -> dict:
    """Rigid plane with a coordinate normal n = −ν = ±e_k: u·n ≤ g is the bound
    σ(n_k g − u_k) ≥ 0 on one component (σ = n_k), g(x) = (x − p)·ν."""
    obstacle, gdim = scene.config.obstacle, scene.mesh.geometry.dim
    assert obstacle is not None  # the scene's rigid plane
    normal, gap, n_ufl, g_ufl = obstacle_shape(scene)
    nu_o = np.asarray(obstacle.normal, dtype=float)
    nu_o = nu_o / np.linalg.norm(nu_o)
    p = plane_point(scene)
    k = int(np.argmax(np.abs(nu_o)))
    if abs(abs(nu_o[k]) - 1.0) > 1e-12:  # a tilted plane: rotate the contact nodes
        return _rotated_contact(scene, V, K, b, fixed, ds, normal, gap, n_ufl, g_ufl)
    n_k = float(np.sign(-nu_o[k]))
    S, s_to_v, v_dofs, s_dofs = _contact_nodes(V, k, scene.boundary.facets("contact"))
    n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    keep = (v_dofs < n_owned) & ~np.isin(v_dofs, fixed)
    dofs, sd = v_dofs[keep].astype(np.int32), s_dofs[keep]
    w = lumped_weights(S, ds(scene.boundary.ids_with_role("contact")))[sd]
    gap = (S.tabulate_dof_coordinates()[:, :gdim] - p) @ nu_o  # g(x) = (x − p)·ν
    bound = fem.Function(S, name="bound")
    bound.x.array[:] = n_k * gap
    return {
        "constraint": Constraint(dofs, n_k * gap[sd], w, n_k, coordinate_scale(scene.mesh)),
        "output_space": S,
        "output_map": s_to_v,
        "output_bound": bound,
        "lambda_sign": n_k,
        "data": {"n": -nu_o, "n_ufl": n_ufl, "g_ufl": g_ufl},
    }


def curved_contact(scene: Scene, V, K, b, fixed, ds) -> dict:
    """Rigid circle (2D) or sphere (3D) of centre c and radius R_o, the body outside it:
    n(x) = (c − x)/|c − x| and g(x) = |x − c| − R_o vary from node to node."""
    return _rotated_contact(scene, V, K, b, fixed, ds, *obstacle_shape(scene))


def _rotated_contact(scene: Scene, V, K, b, fixed, ds, normal, gap, n_ufl, g_ufl) -> dict:
    """Contact along a normal n(x) that is not a coordinate direction: each contact node's
    displacement is rotated to its own axes (n, t[, t2]): u = Q x with Q orthogonal
    block-diagonal, K̃ = Qᵀ K Q, b̃ = Qᵀ b, and u·n ≤ g becomes the bound x_{i,0} ≤ g_i on
    one unknown, as for a coordinate plane.  ``normal``/``gap`` map node coordinates to n
    and g.  Contact nodes with a Dirichlet or symmetry condition on some component cannot
    be rotated and are refused (fully fixed ones are left out)."""
    msh = scene.mesh
    gdim, bs = msh.geometry.dim, V.dofmap.index_map_bs
    S, s_to_v, v_dofs, s_dofs = _contact_nodes(V, 0, scene.boundary.facets("contact"))
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
    g_all = gap(Xs)
    inside = g_all[sd] < -1e-12 * max(1.0, float(np.max(np.abs(Xs))))
    # an obstacle may have moved into the body (obstacle.point / center in t): a prescribed
    # penetration
    obstacle = scene_obstacle(scene)
    if obstacle.kind != "plane" and not obstacle.moving and msh.comm.allreduce(int(np.sum(inside))):
        raise ConfigError("obstacle: contact nodes lie inside the obstacle (negative initial gap)")
    normals = normal(Xs[sd])
    Q = _rotation(V, K, nodes, normals)
    Kt = K.PtAP(Q)  # K̃ = Qᵀ K Q
    bt = b.duplicate()
    Q.multTranspose(b, bt)  # b̃ = Qᵀ b
    w = lumped_weights(S, ds(scene.boundary.ids_with_role("contact")))[sd]
    bound = fem.Function(S, name="bound")
    bound.x.array[:] = g_all
    first = first_contact_point(msh.comm, Xs[sd], g_all[sd])
    return {
        "K": Kt,
        "b": bt,
        "basis": Q,
        "constraint": Constraint(
            (nodes * bs).astype(np.int32), g_all[sd], w, 1.0, coordinate_scale(msh)
        ),
        "output_space": S,
        "output_map": s_to_v,
        "output_bound": bound,
        "lambda_sign": 1.0,
        "data": {
            "n": normal(first[None, :])[0],
            "normals": normals,
            "n_ufl": n_ufl,
            "g_ufl": g_ufl,
        },
    }


#: initial gaps within TIE_RTOL × (the largest coordinate, at least 1) of the smallest count as
#: one, and coordinates are compared rounded to TIE_RTOL × the largest (meshes of different
#: partitions differ in the last bits of their coordinates)
TIE_RTOL = 1e-9


def first_contact_point(comm: MPI.Comm, X: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """The first point of contact (the same on any number of ranks; collective): of the rows
    of X (this rank's points) with the smallest ``dist`` over all ranks, the first in
    coordinate order (smallest x, then y, then z).  Several nodes touching at once (a flat
    face on a plane, a patch test) are a tie, broken by that order rather than by the rank
    that holds them; gaps and coordinates are compared to :data:`TIE_RTOL` of the largest
    coordinate.  None when no rank has a point."""
    return _first_contact(comm, X, dist, X)[0]


def first_contact_row(
    comm: MPI.Comm, X: np.ndarray, dist: np.ndarray, rows: np.ndarray
) -> np.ndarray:
    """The row of ``rows`` (e.g. the nodal normals, row for row with X) at
    :func:`first_contact_point` (collective)."""
    return _first_contact(comm, X, dist, rows)[1]


def _first_contact(comm: MPI.Comm, X: np.ndarray, dist: np.ndarray, rows: np.ndarray) -> tuple:
    """(point, row of ``rows``) of :func:`first_contact_point`, as arrays (None, None if no
    rank has a point)."""
    lowest = comm.allreduce(float(np.min(dist, initial=np.inf)), op=MPI.MIN)
    scale = max(
        comm.allreduce(float(np.max(np.abs(X), initial=0.0)), op=MPI.MAX), np.finfo(float).tiny
    )
    near = np.flatnonzero(dist <= lowest + TIE_RTOL * max(scale, 1.0))
    local = None
    if len(near):
        key = np.round(X[near] / scale, -int(np.log10(TIE_RTOL))) + 0.0  # + 0.0: no −0.0
        i = np.lexsort(key.T[::-1])[0]  # lexsort: the last key is the primary one
        local = (key[i].tolist(), X[near[i]].tolist(), np.asarray(rows[near[i]]).tolist())
    found = [c for c in comm.allgather(local) if c is not None]
    if not found:
        return None, None
    _, point, row = min(found, key=lambda c: c[0])  # lists compare in coordinate order
    return np.asarray(point), np.asarray(row)


def _rotation(
    V: fem.FunctionSpace, K: PETSc.Mat, nodes: np.ndarray, normals: np.ndarray
) -> PETSc.Mat:
    """Q (u = Q x): identity, except the blocks [n t (t2)] of the given owned nodes."""
    Q = NodeBlockMatrix(K, V.dofmap.index_map_bs)
    blocks = Q.identity()
    for node, n in zip(nodes, normals):
        blocks[node] = frame(n)
    return Q.set(blocks)


@dataclass(frozen=True)
class RigidPlane:
    """The rigid plane through p with unit normal ν (towards the body) as a signed distance
    (:class:`contact.solvers.current.RigidSurface`): g = (x − p)·ν, n = −ν, Dn = 0."""

    point: np.ndarray
    normal: np.ndarray

    @property
    def scale(self) -> float:
        return float(np.max(np.abs(self.point), initial=0.0))

    def project(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        k, d = x.shape
        return (x - self.point) @ self.normal, np.tile(-self.normal, (k, 1)), np.zeros((k, d, d))


@dataclass(frozen=True)
class RigidBall:
    """The rigid circle (2D) / sphere (3D) of centre c and radius R_o, the body outside, as a
    signed distance (:class:`contact.solvers.current.RigidSurface`): with r = |x − c|,
    g = r − R_o, n = (c − x)/r, Dn = −(I − n nᵀ)/r (the closest point c − R_o n is the
    point of the obstacle under x, wherever x has slid to)."""

    center: np.ndarray
    radius: float

    @property
    def scale(self) -> float:
        return float(np.max(np.abs(self.center), initial=0.0)) + self.radius

    def project(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(g, n, Dn) at the points x.  A point at the centre or not finite (an iterate that
        diverged) gives NaN there, without a warning: the solver stops on it
        (``diverged_function_nanorinf``) and says so."""
        rel = x - self.center
        r = np.linalg.norm(rel, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            n = -rel / r[:, None]
            d = x.shape[1]
            Dn = -(np.eye(d)[None] - n[:, :, None] * n[:, None, :]) / r[:, None, None]
        return r - self.radius, n, Dn


def rigid_surface(obstacle: RigidObstacle) -> RigidPlane | RigidBall:
    """The signed distance of a rigid obstacle (plane, circle or sphere)."""
    if obstacle.kind == "plane":
        assert obstacle.point is not None and obstacle.normal is not None
        return RigidPlane(obstacle.point, obstacle.normal)
    assert obstacle.center is not None and obstacle.radius is not None
    return RigidBall(obstacle.center, obstacle.radius)


def current_contact(
    scene: Scene, V: fem.FunctionSpace, fixed: np.ndarray, ds, obstacle: RigidObstacle
) -> dict:
    """Contact on the current configuration (:mod:`contact.solvers.current`): the gap of the
    deformed node x = X + u to ``obstacle``, normal and frame followed at every Newton
    iterate; the unknowns stay the displacements (no change of basis).  Contact nodes
    fixed in every component are left out; one with some components fixed (a symmetry
    plane) is refused when the obstacle's normal there lies mostly along them (its
    constrained normal ñ = P n / |P n| would not be the obstacle's).  The constraint's g
    are the reference gaps g(X) (the first point of contact, the output's bound); λ_i is
    the normal component of the nodal force per reference area (nominal pressure)."""
    from ..solvers.current import CurrentContact

    msh = scene.mesh
    gdim, bs = msh.geometry.dim, V.dofmap.index_map_bs
    S, s_to_v, v_dofs, s_dofs = _contact_nodes(V, 0, scene.boundary.facets("contact"))
    nodes = v_dofs // bs
    node_fixed = np.isin(nodes[:, None] * bs + np.arange(bs), fixed)
    keep = (nodes < V.dofmap.index_map.size_local) & ~node_fixed.all(axis=1)
    nodes, sd, node_fixed = nodes[keep], s_dofs[keep], node_fixed[keep]
    Xs = S.tabulate_dof_coordinates()[:, :gdim]
    X = Xs[sd]
    surface = rigid_surface(obstacle)
    g0, n0, _ = surface.project(X)
    along_fixed = np.linalg.norm(np.where(node_fixed, 0.0, n0), axis=1) <= 0.5
    if msh.comm.allreduce(int(np.sum(along_fixed))):
        raise ConfigError(
            "obstacle: at contact nodes on a symmetry or Dirichlet part the obstacle's normal "
            "lies mostly along the fixed components (the obstacle is not symmetric about it)"
        )
    u_prev = scene.history.get("u_prev")
    previous = (
        np.zeros((len(nodes), gdim))
        if u_prev is None
        else u_prev.x.array[nodes[:, None] * bs + np.arange(gdim)]
    )
    # the obstacle's translation since the state the slip starts from: the previous step's
    # solution, or the unloaded body at t = 0
    motion = np.zeros(gdim)
    if obstacle.moving:
        start = scene.previous_time if u_prev is not None and scene.previous_time else 0.0
        motion = obstacle.position - scene_obstacle(scene, start).position
    w = lumped_weights(S, ds(scene.boundary.ids_with_role("contact")))[sd]
    bound = fem.Function(S, name="bound")
    bound.x.array[:] = surface.project(Xs)[0]
    first = first_contact_row(msh.comm, X, g0, n0)
    return {
        "current": CurrentContact(nodes.astype(np.int32), X, node_fixed, surface, previous, motion),
        "constraint": Constraint((nodes * bs).astype(np.int32), g0, w, 1.0, coordinate_scale(msh)),
        "output_space": S,
        "output_map": s_to_v,
        "output_bound": bound,
        "lambda_sign": 1.0,
        "data": {"n": first},
    }
