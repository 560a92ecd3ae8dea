"""Linear elasticity against a rigid obstacle, frictionless (SPEC §1.3).

    σ(u) = 2μ ε(u) + λ_L tr ε(u) I   (plane strain in 2D),   −div σ(u) = f in Ω,
    u = u_D on Γ_D,   σ n = t on Γ_N,   u·n_s = 0 on symmetry planes,
    u·n ≤ g,  λ_n := σ_nn(u) ≤ 0,  λ_n (u·n − g) = 0,  σ_nt(u) = 0   on Γ_C,

with n the unit normal towards the obstacle and g ≥ 0 the initial gap along n.  For a
rigid plane through p with outward normal ν (pointing from the obstacle to the body),
n = −ν and g(x) = (x − p)·ν; for a rigid circle/sphere (centre c, radius R_o, the body
outside) n = (c − x)/|c − x| and g = |x − c| − R_o.  When n is a coordinate direction ±e_k,
u·n ≤ g is a bound on the single component u_k (σ = n_k, bound n_k g); otherwise each
contact node's displacement is rotated to its (n, t) axes so that it is a bound on one
unknown again.  Either way the nodal complementarity problem has exactly the structure of
the scalar models and every solver applies unchanged; the multiplier λ_n,i = σ R_i / w_i
is the contact pressure (negative in compression).
Units: E and stresses in Pa (or any consistent unit), lengths in m, forces per unit
thickness in N/m in 2D.
"""
from __future__ import annotations

import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc
import ufl
from dolfinx import fem

from . import expressions
from .config import ConfigError
from .models import Constraint, DiscreteProblem, assemble_system, lumped_weights
from .scene import Scene


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lamé parameters (μ, λ_L) of Young's modulus E and Poisson's ratio ν."""
    return E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))


def epsilon(u):
    """ε(u) = sym ∇u."""
    return ufl.sym(ufl.grad(u))


def stress(u, mu: float, lmbda_L: float):
    """σ(u) = 2μ ε(u) + λ_L tr ε(u) I (plane strain when 2D)."""
    eps = epsilon(u)
    return 2.0 * mu * eps + lmbda_L * ufl.tr(eps) * ufl.Identity(len(u))


def _vector(texts: list[str], scene: Scene):
    """Vector data: a ``fem.Constant`` when every component is constant (so a zero load
    still gives a non-empty form), else a UFL vector of the expressions."""
    consts = scene.cfg["constants"]
    if all(expressions.is_constant(t, consts) for t in texts):
        values = [float(expressions.to_numpy(t, consts)(np.zeros((3, 1)))[0]) for t in texts]
        return fem.Constant(scene.mesh, np.array(values, dtype=PETSc.ScalarType))
    return ufl.as_vector([expressions.to_ufl(t, scene.mesh, consts) for t in texts])


def _vector_numpy(texts: list[str], scene: Scene):
    fns = [expressions.to_numpy(t, scene.cfg["constants"]) for t in texts]
    return lambda x: np.vstack([f(x) for f in fns])


def _facet_normal_axis(scene: Scene, name: str, facets: np.ndarray) -> int:
    """The axis k of the plane x_k = const that holds ``facets``, those of part ``name``."""
    msh = scene.mesh
    tdim = msh.topology.dim
    nodes = dolfinx.mesh.entities_to_geometry(msh, tdim - 1, facets).ravel()
    x = msh.geometry.x[nodes, :tdim]
    lo = np.min(np.vstack(msh.comm.allgather(x.min(axis=0) if len(x) else np.full(tdim, np.inf))), axis=0)
    hi = np.max(np.vstack(msh.comm.allgather(x.max(axis=0) if len(x) else np.full(tdim, -np.inf))), axis=0)
    axes = np.flatnonzero(hi - lo < 1e-10 * max(1.0, float(np.max(np.abs(hi)))))
    if len(axes) != 1:
        raise ConfigError(f"boundaries.{name}: a symmetry part must lie in one plane x_k = const")
    return int(axes[0])


def elasticity_problem(scene: Scene) -> DiscreteProblem:
    """Assemble the frictionless elastic contact problem of ``scene`` (SPEC §1.3, §2)."""
    t0 = time.perf_counter()
    cfg, msh, bnd = scene.cfg, scene.mesh, scene.boundary
    model, data, obstacle = cfg["model"], cfg["data"], cfg["obstacle"]  # data: f, u_D, t below
    gdim, tdim = msh.geometry.dim, msh.topology.dim
    data = {key: (data[key] if isinstance(data[key], list) else [data[key]] * gdim) for key in ("f", "u_D", "t")}
    for key, texts in data.items():
        if len(texts) != gdim:
            raise ConfigError(f"data.{key}: a {gdim}D elasticity scene needs {gdim} components, got {len(texts)}")
    degree = cfg["mesh"]["degree"]
    V = fem.functionspace(msh, ("Lagrange", degree, (gdim,)))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    mu, lmbda_L = lame(model["E"], model["nu"])
    f, t = _vector(data["f"], scene), _vector(data["t"], scene)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=bnd.tags)
    dx = ufl.Measure("dx", domain=msh)

    # a(u, v) = ∫ σ(u) : ε(v) dx,   L(v) = ∫ f·v dx + ∫_{Γ_N} t·v ds
    a_ufl = ufl.inner(stress(u, mu, lmbda_L), epsilon(v)) * dx
    L_ufl = ufl.inner(f, v) * dx
    for i in bnd.ids_with_role("neumann"):
        L_ufl += ufl.inner(t, v) * ds(i)
    a, L = fem.form(a_ufl), fem.form(L_ufl)

    # Dirichlet: u = u_D on Γ_D;  symmetry: u_k = 0 on a plane x_k = const.
    u_D = fem.Function(V)
    u_D.interpolate(_vector_numpy(data["u_D"], scene))
    bcs = [fem.dirichletbc(u_D, fem.locate_dofs_topological(V, tdim - 1, bnd.facets("dirichlet")))]
    for name, role in bnd.roles.items():
        if role == "symmetry":
            facets = bnd.tags.indices[bnd.tags.values == bnd.ids[name]]
            k = _facet_normal_axis(scene, name, facets)
            dofs = fem.locate_dofs_topological(V.sub(k), tdim - 1, facets)
            bcs.append(fem.dirichletbc(PETSc.ScalarType(0.0), dofs, V.sub(k)))
    K, b = assemble_system(a, L, bcs)

    fixed = np.concatenate([bc.dof_indices()[0] for bc in bcs])
    if obstacle["type"] == "plane":
        contact = _plane_contact(scene, V, K, b, fixed, ds)
    else:
        contact = _curved_contact(scene, V, K, b, fixed, ds)
    K, b = contact.pop("K", K), contact.pop("b", b)
    con = contact.pop("constraint")
    u_h = fem.Function(V, name="u_h")
    data = {"f": f, "t": t, "ds": ds, "mu": mu, "lmbda_L": lmbda_L, "exact": None,
            # residual without Dirichlet rows, for reaction forces: a(u_h, v) − L(v)
            "reaction_form": fem.form(ufl.action(a_ufl, u_h) - L_ufl), **contact.pop("data")}
    return DiscreteProblem(V, u_h, bcs, K, b, con, data=data, **contact,
                           near_nullspace=rigid_body_modes(V, contact.get("basis")),
                           assembly_time=time.perf_counter() - t0)


def _contact_nodes(V: fem.FunctionSpace, k: int, facets: np.ndarray):
    """For component k: its collapsed space S, the S → V map, and the (V-DoF, S-DoF) pairs
    on the contact facets."""
    S, s_to_v = V.sub(k).collapse()
    s_to_v = np.asarray(s_to_v, dtype=np.int32).ravel()
    tdim = V.mesh.topology.dim
    v_dofs, s_dofs = fem.locate_dofs_topological((V.sub(k), S), tdim - 1, facets)
    return S, s_to_v, v_dofs, s_dofs


def _plane_contact(scene: Scene, V, K, b, fixed, ds) -> dict:
    """Rigid plane with a coordinate normal n = −ν = ±e_k: u·n ≤ g is the bound
    σ(n_k g − u_k) ≥ 0 on one component (σ = n_k), g(x) = (x − p)·ν."""
    obstacle, gdim = scene.cfg["obstacle"], scene.mesh.geometry.dim
    nu_o = np.asarray(obstacle["normal"], dtype=float)
    nu_o = nu_o / np.linalg.norm(nu_o)
    p = np.asarray(obstacle["point"], dtype=float)
    if len(nu_o) != gdim or len(p) != gdim:
        raise ConfigError(f"obstacle: point and normal need {gdim} components in a {gdim}D scene")
    k = int(np.argmax(np.abs(nu_o)))
    X = ufl.SpatialCoordinate(scene.mesh)
    n_ufl = ufl.as_vector((-nu_o).tolist())                                       # n = −ν
    g_ufl = ufl.dot(X - ufl.as_vector(p.tolist()), ufl.as_vector(nu_o.tolist()))  # g = (x − p)·ν
    if abs(abs(nu_o[k]) - 1.0) > 1e-12:  # a tilted plane: rotate the contact nodes
        return _rotated_contact(scene, V, K, b, fixed, ds,
                                normal=lambda x: np.tile(-nu_o, (len(x), 1)),
                                gap=lambda x: (x - p) @ nu_o, n_ufl=n_ufl, g_ufl=g_ufl)
    n_k = float(np.sign(-nu_o[k]))
    S, s_to_v, v_dofs, s_dofs = _contact_nodes(V, k, scene.boundary.facets("contact"))
    n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    keep = (v_dofs < n_owned) & ~np.isin(v_dofs, fixed)
    dofs, sd = v_dofs[keep].astype(np.int32), s_dofs[keep]
    w = lumped_weights(S, ds(scene.boundary.ids_with_role("contact")))[sd]
    gap = (S.tabulate_dof_coordinates()[:, :gdim] - p) @ nu_o     # g(x) = (x − p)·ν
    bound = fem.Function(S, name="bound")
    bound.x.array[:] = n_k * gap
    return {"constraint": Constraint(dofs, n_k * gap[sd], w, n_k),
            "output_space": S, "output_map": s_to_v, "output_bound": bound, "lambda_sign": n_k,
            "data": {"n": -nu_o, "n_ufl": n_ufl, "g_ufl": g_ufl}}


def _curved_contact(scene: Scene, V, K, b, fixed, ds) -> dict:
    """Rigid circle (2D) or sphere (3D) of centre c and radius R_o, the body outside it:
    n(x) = (c − x)/|c − x| and g(x) = |x − c| − R_o vary from node to node."""
    obstacle, msh = scene.cfg["obstacle"], scene.mesh
    gdim = msh.geometry.dim
    want = "circle" if gdim == 2 else "sphere"
    if obstacle["type"] != want:
        raise ConfigError(f"obstacle.type: a {gdim}D scene needs a {want}, got {obstacle['type']}")
    centre, R_o = np.asarray(obstacle["center"], dtype=float), float(obstacle["radius"])
    if len(centre) != gdim:
        raise ConfigError(f"obstacle.center: needs {gdim} components in a {gdim}D scene")
    X = ufl.SpatialCoordinate(msh)
    c_ufl = ufl.as_vector(centre.tolist())
    return _rotated_contact(
        scene, V, K, b, fixed, ds,
        normal=lambda x: (centre - x) / np.linalg.norm(centre - x, axis=1)[:, None],
        gap=lambda x: np.linalg.norm(x - centre, axis=1) - R_o,
        n_ufl=(c_ufl - X) / ufl.sqrt(ufl.dot(c_ufl - X, c_ufl - X)),
        g_ufl=ufl.sqrt(ufl.dot(X - c_ufl, X - c_ufl)) - R_o)


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
        raise ConfigError("obstacle: contact nodes with a symmetry or partial Dirichlet condition "
                          "cannot be rotated to the obstacle's normal")
    keep = (nodes < V.dofmap.index_map.size_local) & ~node_fixed.all(axis=1)
    nodes, sd = nodes[keep], s_dofs[keep]
    Xs = S.tabulate_dof_coordinates()[:, :gdim]
    g_all = gap(Xs)
    if msh.comm.allreduce(int(np.sum(g_all[sd] < -1e-12 * max(1.0, float(np.max(np.abs(Xs)))))) ):
        raise ConfigError("obstacle: contact nodes lie inside the obstacle (negative initial gap)")
    normals = normal(Xs[sd])
    Q = _rotation(V, K, nodes, normals)
    Kt = K.PtAP(Q)                                          # K̃ = Qᵀ K Q
    bt = b.duplicate()
    Q.multTranspose(b, bt)                                  # b̃ = Qᵀ b
    w = lumped_weights(S, ds(scene.boundary.ids_with_role("contact")))[sd]
    bound = fem.Function(S, name="bound")
    bound.x.array[:] = g_all
    first = first_contact_point(msh.comm, Xs[sd], g_all[sd])
    return {"K": Kt, "b": bt, "basis": Q,
            "constraint": Constraint((nodes * bs).astype(np.int32), g_all[sd], w, 1.0),
            "output_space": S, "output_map": s_to_v, "output_bound": bound, "lambda_sign": 1.0,
            "data": {"n": normal(first[None, :])[0], "normals": normals, "n_ufl": n_ufl, "g_ufl": g_ufl}}


def first_contact_point(comm: MPI.Comm, X: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """The point of X with the smallest ``dist`` over all ranks (the first point of contact)."""
    local = (float(dist.min()), X[np.argmin(dist)].tolist()) if len(dist) else (np.inf, None)
    return np.asarray(min(comm.allgather(local), key=lambda t: t[0])[1])


def _rotation(V: fem.FunctionSpace, K: PETSc.Mat, nodes: np.ndarray, normals: np.ndarray) -> PETSc.Mat:
    """Q (u = Q x): identity, except the blocks [n t (t2)] of the given owned nodes."""
    bs = V.dofmap.index_map_bs
    Q = PETSc.Mat().createAIJ(K.getSizes(), bsize=bs, nnz=(bs, 0), comm=K.comm)
    lo, hi = Q.getOwnershipRange()
    local_nodes = (hi - lo) // bs
    blocks = np.tile(np.eye(bs), (local_nodes, 1, 1))
    for node, n in zip(nodes, normals):
        blocks[node] = _frame(n)
    # CSR of the owned rows: row (node, i) holds columns (node, 0 … bs−1), values blocks[node, i, :]
    indptr = np.arange(0, local_nodes * bs * bs + 1, bs, dtype=PETSc.IntType)
    cols = lo + np.arange(local_nodes * bs, dtype=PETSc.IntType).reshape(local_nodes, 1, bs)
    indices = np.broadcast_to(cols, (local_nodes, bs, bs)).ravel()
    Q.setValuesCSR(indptr, indices, blocks.ravel())
    Q.assemble()
    return Q


def _frame(n: np.ndarray) -> np.ndarray:
    """Columns n, t (, t2): an orthonormal frame whose first axis is n."""
    if len(n) == 2:
        return np.array([[n[0], -n[1]], [n[1], n[0]]])
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1)
    return np.column_stack([n, t1, np.cross(n, t1)])


def rigid_body_modes(V: fem.FunctionSpace, rotation: PETSc.Mat | None = None) -> PETSc.NullSpace:
    """Near-nullspace of elasticity for GAMG: gdim translations and the infinitesimal
    rotations (1 in 2D, 3 in 3D), in the solver's unknowns (Qᵀ m when rotated),
    orthonormalised."""
    msh = V.mesh
    gdim = msh.geometry.dim
    n_local = V.dofmap.index_map.size_local
    X = V.tabulate_dof_coordinates()[:n_local, :gdim]
    modes = []
    for i in range(gdim):
        m = np.zeros((n_local, gdim))
        m[:, i] = 1.0
        modes.append(m)
    for i, j in [(0, 1)] if gdim == 2 else [(0, 1), (1, 2), (2, 0)]:
        m = np.zeros((n_local, gdim))
        m[:, i], m[:, j] = -X[:, j], X[:, i]
        modes.append(m)
    basis = []
    for m in modes:
        vec = PETSc.Vec().createMPI((n_local * gdim, PETSc.DECIDE), comm=msh.comm)
        vec.array[:] = m.ravel()
        if rotation is not None:
            rotated = vec.duplicate()
            rotation.multTranspose(vec, rotated)
            vec = rotated
        for prev in basis:  # modified Gram–Schmidt
            vec.axpy(-vec.dot(prev), prev)
        vec.normalize()
        basis.append(vec)
    return PETSc.NullSpace().create(vectors=basis, comm=msh.comm)


def von_mises(u_h: fem.Function, mu: float, lmbda_L: float) -> fem.Function:
    """Cellwise (DG0) von Mises stress √(3/2 s:s), s the deviator of the 3D stress; in
    plane strain σ_zz = λ_L tr ε (ε_zz = 0) is included."""
    msh = u_h.function_space.mesh
    sig = stress(u_h, mu, lmbda_L)
    if msh.geometry.dim == 2:
        szz = lmbda_L * ufl.tr(epsilon(u_h))
        sig = ufl.as_matrix([[sig[0, 0], sig[0, 1], 0], [sig[1, 0], sig[1, 1], 0], [0, 0, szz]])
    dev = sig - ufl.tr(sig) / 3 * ufl.Identity(3)
    W = fem.functionspace(msh, ("DG", 0))
    out = fem.Function(W, name="von_mises")
    out.interpolate(fem.Expression(ufl.sqrt(1.5 * ufl.inner(dev, dev)), W.element.interpolation_points))
    return out
