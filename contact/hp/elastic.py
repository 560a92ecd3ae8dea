"""Linear elasticity against a rigid coordinate plane in V_hp^d (docs/theory.md §1.3, §11):
each displacement component in the hp space of :mod:`.space`, u = Q x with Q = Q_hp ⊗ I_d.

K and b are assembled in P_{p_max}^d without boundary conditions and reduced,
K_hp = Qᵀ K Q, b_hp = Qᵀ b; the inactive slots (every component), the Dirichlet slots (every
component: the hp interpolant of u_D) and the symmetry planes' normal components are
eliminated symmetrically, as in the scalar problem (:mod:`.problem`).  The plane's normal
n = ±e_k makes u·n ≤ g the bound σ(σ g − x_{i,k}) ≥ 0 on one unknown per hp node of Γ_C,
with the lumped weights w_i = (Q_hpᵀ w^{p_max})_i > 0 of the scalar problem (Gauss–Lobatto
weights on each contact edge), so the contact condition stays nodal at the vertices and
Lagrange nodes of degree p_E of the contact facets.  The rigid motions are linear, hence in
V_hp^d: their coefficients x = L m (L the left inverse) are GAMG's near-nullspace.

The multiplier λ_h (and the gap, the active set) are scalar hp functions of the nodes of
Γ_C, written in the scalar space P_{p_max} through Q_hp (the residual estimator reads
λ_h there).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base.errors import ConfigError
from ..models.constraints import Plane
from ..models.discrete import Problem
from ..models.elasticity import rigid_body_modes
from ..models.physics import epsilon, lame, stress
from ..models.problem import coordinate_scale, lumped_weights
from ..setup.checks import check_scene_data
from ..setup.data import vector_numpy
from ..setup.elastic import (
    elastic_physics,
    elastic_setting,
    reaction_form,
    scene_rigid,
    scene_surface,
)
from ..setup.scene import Scene
from ..setup.scene_config import components
from ..solvers.floating import floating_bodies
from ..solvers.problem import Constraint, Output, ProblemData, Symmetry
from .problem import eliminate, reduce_system
from .space import HPSpace


class HPElasticProblem(Problem):
    """An elastic problem in the hp unknowns x (:class:`~contact.models.discrete.Problem`):
    its nodal outputs (λ_h, gap, active set) are scalar hp functions of the contact nodes,
    mapped to the scalar P_{p_max} space by Q_hp."""

    space: HPSpace
    scalar_basis: PETSc.Mat
    #: with the rigid motions as its near-nullspace, CG + GAMG reached the Hertz 2D targets
    #: in less CPU time than MUMPS (demos/RESULTS.md §15): ``solver.linear: auto`` as for P1
    variable_degree = False

    def unknowns(self) -> int:
        """The hp unknowns (every component), not V's DoFs: the inactive slots are
        eliminated rows (which size decides ``solver.linear: auto``)."""
        return self.space.dimension * self.V.dofmap.index_map_bs

    def nodal_output(self, name: str, values: np.ndarray) -> fem.Function:
        """``values`` at the constrained nodes (0 at the other nodes) as the scalar function
        Q_hp x of P_{p_max}."""
        bs = self.V.dofmap.index_map_bs
        S = self.space.V
        fn = fem.Function(S)
        fn.x.array[self.constraint.dofs // bs] = values
        out = fem.Function(S, name=name)
        self.scalar_basis.mult(fn.x.petsc_vec, out.x.petsc_vec)
        out.x.scatter_forward()
        return out

    def gap_output(self, x: np.ndarray) -> fem.Function:
        """σ(g − u·e_k) on the contact facets (the hp interpolant of the nodal gaps), NaN at
        the other DoFs of P_{p_max}."""
        con = self.constraint
        gap = self.nodal_output("gap", con.sign * (con.g - x[con.dofs]))
        assert self.data.contact_mask is not None  # set when built
        gap.x.array[~self.data.contact_mask] = np.nan
        return gap

    def node_coordinates(self) -> np.ndarray:
        """The hp nodes of the constrained unknowns (gdim columns)."""
        bs = self.V.dofmap.index_map_bs
        gdim = self.V.mesh.geometry.dim
        return self.space.points[self.constraint.dofs // bs, :gdim]

    def destroy(self) -> None:
        """Also the scalar Q_hp."""
        super().destroy()
        self.scalar_basis.destroy()


def _component(values: Callable[[np.ndarray], np.ndarray], k: int):
    """Component k of a vector function of points (3, n) → (d, n)."""
    return lambda X: values(X)[k]


def _refuse(scene: Scene) -> None:
    """ConfigError (one line, naming the key) for what the hp elastic problem does not do."""
    cfg = scene.config
    if cfg.bodies or cfg.pairs:
        raise ConfigError("adapt.strategy: hp solves one elastic body, not bodies or pairs")
    if cfg.frictional:
        raise ConfigError("adapt.strategy: hp solves frictionless contact (remove friction)")
    if cfg.obstacle is None:
        raise ConfigError("adapt.strategy: hp needs an obstacle for an elastic body")
    surface = scene_surface(scene)
    if not isinstance(surface, Plane) or surface.axis() is None:
        raise ConfigError(
            "obstacle: adapt.strategy hp needs a plane with a coordinate normal (±e_k)"
        )


def hp_elastic_problem(scene: Scene, space: HPSpace) -> HPElasticProblem:
    """Assemble the elastic contact problem of ``scene`` in V_hp^d (module docstring).

    Args:
        scene: One linear elastic body against a rigid plane with a coordinate normal.
        space: The hp space (scalar; every component uses it).

    Returns:
        The discrete problem in the hp unknowns (``basis`` Q_hp ⊗ I_d, ``basis_inverse``
        L ⊗ I_d), with the rigid motions as its near-nullspace.

    Raises:
        ConfigError: For several bodies, pairs, friction, or another obstacle.
    """
    t0 = time.perf_counter()
    cfg, msh, bnd = scene.config, scene.mesh, scene.boundary
    if cfg.model.type != "elasticity":
        raise ConfigError(f"model.type: expected elasticity, got {cfg.model.type!r}")
    if msh is not space.mesh:
        raise ValueError("space: built on another mesh than the scene's")
    _refuse(scene)
    check_scene_data(scene)
    tdim, gdim = msh.topology.dim, msh.geometry.dim
    assert cfg.model.E is not None  # one body
    mu, lmbda_L = lame(cfg.model.E, cfg.model.nu)
    s = elastic_setting(scene, space.p_max)
    V, ds = s.V, s.data["ds"]
    bs = V.dofmap.index_map_bs
    if not np.array_equal(V.dofmap.list, space.V.dofmap.list):
        raise RuntimeError("P_{p_max}^d and P_{p_max} number their nodes differently")
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a_ufl = ufl.inner(stress(u, mu, lmbda_L), epsilon(v)) * ufl.dx(domain=msh)
    Q, Linv = space.vector_matrices(bs)
    K_hp, b_hp = reduce_system(fem.form(a_ufl), fem.form(s.L_ufl), Q)

    # the fixed unknowns: inactive slots, Dirichlet slots (u_D's hp interpolant), symmetry
    imap = V.dofmap.index_map
    n_owned = imap.size_local
    n_nodes = n_owned + imap.num_ghosts
    fixed = np.zeros((n_nodes, bs), dtype=bool)
    fixed[~space.active] = True
    dirichlet = space.slots_of(tdim - 1, bnd.facets("dirichlet"))
    fixed[dirichlet] = True
    values = fem.Function(V)
    u_D = vector_numpy(list(components(cfg.data.u_D, gdim)), scene)
    vals = values.x.array.reshape(-1, bs)
    for comp in range(bs):
        vals[dirichlet, comp] = space.interpolate(_component(u_D, comp))[dirichlet]
    blocks = np.flatnonzero(fixed.all(axis=1)).astype(np.int32)
    bcs = [fem.dirichletbc(values, blocks)]
    symmetry = [name for name, role in bnd.roles.items() if role == "symmetry"]
    for name, k in zip(symmetry, s.symmetry_axes):
        facets = bnd.tags.indices[bnd.tags.values == bnd.ids[name]]
        nodes = space.slots_of(tdim - 1, facets)
        fixed[nodes, k] = True
        zero = PETSc.ScalarType(0.0)  # type: ignore[operator]
        sub = fem.locate_dofs_topological(V.sub(k), tdim - 1, facets)
        sub = sub[space.active[sub // bs]]
        bcs.append(fem.dirichletbc(zero, sub, V.sub(k)))
    fixed_dofs = np.flatnonzero(fixed.ravel()).astype(np.int32)
    eliminate(K_hp, b_hp, np.repeat(~space.active[:n_owned], bs), fixed_dofs, values)

    # Γ_C: the bound on component k at the hp nodes of the contact facets
    obstacle = scene_rigid(scene, ds)
    plane = obstacle.surface
    assert isinstance(plane, Plane)  # checked by _refuse
    k = int(np.argmax(np.abs(plane.normal)))
    n_k = float(np.sign(-plane.normal[k]))
    contact_facets = bnd.facets("contact")
    candidates = space.slots_of(tdim - 1, contact_facets)
    nodes = candidates[(candidates < n_owned) & ~fixed[candidates, k]]
    Q_s, L_s = space.matrices()
    L_s.destroy()
    w_max = fem.Function(space.V)
    w_max.x.array[:n_owned] = lumped_weights(space.V, obstacle.measure)
    w_hp = fem.Function(space.V)
    Q_s.multTranspose(w_max.x.petsc_vec, w_hp.x.petsc_vec)
    w = w_hp.x.array[nodes].copy()
    if msh.comm.allreduce(bool(np.any(w <= 0)), op=MPI.LOR):
        raise ConfigError(
            "adapt.p_max: a contact node of V_hp has lumped weight <= 0; lower adapt.p_max"
        )
    gap = (space.points[nodes, :gdim] - plane.point) @ plane.normal  # g(x) = (x − p)·ν
    dofs = (nodes * bs + k).astype(np.int32)
    constraint = Constraint(dofs, n_k * gap, w, n_k, coordinate_scale(msh))
    contact_mask = np.zeros(n_nodes, dtype=bool)
    contact_mask[fem.locate_dofs_topological(space.V, tdim - 1, contact_facets)] = True
    bound = fem.Function(space.V, name="bound")  # n_k g, exact in P_{p_max} (g is affine)
    bound.interpolate(lambda X: n_k * ((X[:gdim].T - plane.point) @ plane.normal))
    n_ufl, g_ufl = plane.expression(ufl.SpatialCoordinate(msh))
    u_h = fem.Function(V, name="u_h")
    problem = HPElasticProblem(
        V,
        u_h,
        bcs,
        K_hp,
        b_hp,
        constraint,
        output=Output(space=space.V, bound=bound, lambda_sign=n_k),
        near_nullspace=rigid_body_modes(V, None, Linv),
        basis=Q,
        basis_inverse=Linv,
        data=ProblemData(
            f=s.data["f"],
            t=s.data["t"],
            ds=ds,
            mu=mu,
            lmbda_L=lmbda_L,
            n=-plane.normal,
            n_ufl=n_ufl,
            g_ufl=g_ufl,
            contact_mask=contact_mask,
            reaction_form=reaction_form(a_ufl, s.L_ufl, u_h),
            reaction_basis=Q,  # the reaction of the hp test functions (p.bcs[0])
        ),
        assembly_time=time.perf_counter() - t0,
        floating=floating_bodies(V, fixed_dofs, None, []),
        symmetry=Symmetry(tuple(sorted(set(s.symmetry_axes)))),
        physics=elastic_physics(scene, s, mu, lmbda_L),
        contacts=(obstacle,),
    )
    problem.space = space
    problem.scalar_basis = Q_s
    return problem
