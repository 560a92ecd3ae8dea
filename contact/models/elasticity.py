"""Linear elasticity against a rigid obstacle, frictionless (docs/theory.md §1.3).

    σ(u) = 2μ ε(u) + λ_L tr ε(u) I   (plane strain in 2D),   −div σ(u) = f in Ω,
    u = u_D on Γ_D,   σ n = t on Γ_N,   u·n_s = 0 on symmetry planes,
    u·n ≤ g,  λ_n := σ_nn(u) ≤ 0,  λ_n (u·n − g) = 0,  σ_nt(u) = 0   on Γ_C,

with n the unit normal towards the obstacle and g ≥ 0 the initial gap along n
(:mod:`contact.models.obstacles` turns u·n ≤ g into a bound on one unknown per contact
node).  The nodal complementarity problem then has exactly the structure of the scalar
models and every solver applies unchanged; the multiplier λ_n,i = σ R_i / w_i is the
contact pressure (negative in compression).
Units: E and stresses in Pa (or any consistent unit), lengths in m, forces per unit
thickness in N/m in 2D.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import dolfinx.fem.petsc
import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from ..base import expressions
from ..base.errors import ConfigError
from ..base.lifetime import destroy
from ..setup.checks import check_scene_data
from ..setup.scene import Scene
from ..setup.scene_config import components
from ..solvers.floating import floating_bodies
from .constraints import RigidObstacle
from .discrete import Problem
from .obstacles import curved_contact, plane_contact, scene_surface
from .physics import BoundaryData, Elasticity, epsilon, stress
from .problem import assemble_system


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lamé parameters (μ, λ_L) of Young's modulus E and Poisson's ratio ν."""
    return E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))


def _vector(texts: list[str], scene: Scene):
    """Vector data: a ``fem.Constant`` when every component is constant (so a zero load
    still gives a non-empty form), else a UFL vector of the expressions."""
    consts = scene.config.constants
    if all(expressions.is_constant(t, consts) for t in texts):
        values = [float(expressions.to_numpy(t, consts)(np.zeros((3, 1)))[0]) for t in texts]
        return fem.Constant(scene.mesh, np.array(values, dtype=PETSc.ScalarType))
    return ufl.as_vector(
        [expressions.to_ufl(t, scene.mesh, consts, t=scene.t_constant) for t in texts]
    )


def _vector_numpy(texts: list[str], scene: Scene):
    fns = [expressions.to_numpy(t, scene.config.constants, t=scene.time) for t in texts]
    return lambda x: np.vstack([f(x) for f in fns])


def _facet_normal_axis(scene: Scene, name: str, facets: np.ndarray) -> int:
    """The axis k of the plane x_k = const that holds ``facets``, those of part ``name``."""
    msh = scene.mesh
    tdim = msh.topology.dim
    nodes = dolfinx.mesh.entities_to_geometry(msh, tdim - 1, facets).ravel()
    x = msh.geometry.x[nodes, :tdim]
    lo = np.min(
        np.vstack(msh.comm.allgather(x.min(axis=0) if len(x) else np.full(tdim, np.inf))), axis=0
    )
    hi = np.max(
        np.vstack(msh.comm.allgather(x.max(axis=0) if len(x) else np.full(tdim, -np.inf))), axis=0
    )
    axes = np.flatnonzero(hi - lo < 1e-10 * max(1.0, float(np.max(np.abs(hi)))))
    if len(axes) != 1:
        raise ConfigError(f"boundaries.{name}: a symmetry part must lie in one plane x_k = const")
    return int(axes[0])


@dataclass
class ElasticSetting:
    """What an elastic body's problem needs before any material law: the vector space, the
    load L(v) = ∫ f·v dx + ∫_{Γ_N} t·v ds, the Dirichlet and symmetry conditions, and the
    data the estimator and outputs read (f, t, ds).  Shared by linear elasticity, the
    multi-body model and the hyperelastic model (:mod:`.hyperelastic`)."""

    V: fem.FunctionSpace
    L_ufl: ufl.Form
    bcs: list
    fixed: np.ndarray  # local DoFs with a Dirichlet or symmetry condition
    data: dict  # f, t, ds
    symmetry_axes: tuple[int, ...] = ()  # k of each symmetry part's plane x_k = const


@dataclass
class ElasticSystem:
    """Linear elasticity on the scene's mesh before any contact: the space, the forms, the
    Dirichlet and symmetry conditions, K (their rows and columns identity) and the lifted
    load b, shared by the rigid-obstacle and the multi-body models."""

    V: fem.FunctionSpace
    a_ufl: ufl.Form
    L_ufl: ufl.Form
    bcs: list
    K: PETSc.Mat
    b: PETSc.Vec
    fixed: np.ndarray  # local DoFs with a Dirichlet or symmetry condition
    data: dict  # f, t, ds, mu, lmbda_L, exact (None) and the reaction form
    symmetry_axes: tuple[int, ...] = ()  # k of each symmetry part's plane x_k = const


def elastic_setting(scene: Scene) -> ElasticSetting:
    """The space (Lagrange of ``mesh.degree``, gdim components), the load
    L(v) = ∫ f·v dx + ∫_{Γ_N} t·v ds, u = u_D on Γ_D and u_k = 0 on each symmetry plane
    x_k = const."""
    cfg, msh, bnd = scene.config, scene.mesh, scene.boundary
    gdim, tdim = msh.geometry.dim, msh.topology.dim
    data = {key: list(components(getattr(cfg.data, key), gdim)) for key in ("f", "u_D", "t")}
    for key, texts in data.items():
        if len(texts) != gdim:
            raise ConfigError(
                f"data.{key}: a {gdim}D elasticity scene needs {gdim} components, got {len(texts)}"
            )
    degree = cfg.mesh.degree
    V = fem.functionspace(msh, ("Lagrange", degree, (gdim,)))
    v = ufl.TestFunction(V)
    f, t = _vector(data["f"], scene), _vector(data["t"], scene)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=bnd.tags)
    dx = ufl.Measure("dx", domain=msh)
    L_ufl = ufl.inner(f, v) * dx
    for i in bnd.ids_with_role("neumann"):
        L_ufl += ufl.inner(t, v) * ds(i)

    # Dirichlet: u = u_D on Γ_D;  symmetry: u_k = 0 on a plane x_k = const.
    u_D = fem.Function(V)
    u_D.interpolate(_vector_numpy(data["u_D"], scene))
    bcs = [fem.dirichletbc(u_D, fem.locate_dofs_topological(V, tdim - 1, bnd.facets("dirichlet")))]
    axes = []
    for name, role in bnd.roles.items():
        if role == "symmetry":
            facets = bnd.tags.indices[bnd.tags.values == bnd.ids[name]]
            axes.append(k := _facet_normal_axis(scene, name, facets))
            dofs = fem.locate_dofs_topological(V.sub(k), tdim - 1, facets)
            zero = PETSc.ScalarType(0.0)  # type: ignore[operator]
            bcs.append(fem.dirichletbc(zero, dofs, V.sub(k)))
    fixed = np.concatenate([bc.dof_indices()[0] for bc in bcs])
    # u_D as UFL beside its interpolant in the conditions: the equilibrated bound measures the
    # interpolation error on Γ_D (contact.adaptivity.equilibration.elastic)
    fields = {"f": f, "t": t, "ds": ds, "u_D": _vector(data["u_D"], scene)}
    return ElasticSetting(V, L_ufl, bcs, fixed, fields, tuple(axes))


def elastic_system(scene: Scene, mu, lmbda_L) -> ElasticSystem:
    """Assemble linear elasticity with Lamé parameters ``mu``, ``lmbda_L`` (numbers, or DG0
    functions for several bodies): a(u, v) = ∫ σ(u) : ε(v) dx with the load and conditions
    of :func:`elastic_setting`."""
    s = elastic_setting(scene)
    u, v = ufl.TrialFunction(s.V), ufl.TestFunction(s.V)
    a_ufl = ufl.inner(stress(u, mu, lmbda_L), epsilon(v)) * ufl.dx(domain=scene.mesh)
    K, b = assemble_system(fem.form(a_ufl), fem.form(s.L_ufl), s.bcs)
    return ElasticSystem(
        s.V,
        a_ufl,
        s.L_ufl,
        s.bcs,
        K,
        b,
        s.fixed,
        {**s.data, "mu": mu, "lmbda_L": lmbda_L, "exact": None},
        s.symmetry_axes,
    )


def elastic_physics(
    scene: Scene, setting: ElasticSetting | ElasticSystem, mu, lmbda_L, law: str | None = None
) -> Elasticity:
    """The equations of the scene's elastic body (bodies): Lamé parameters, load, the
    boundary parts and their tractions, the Dirichlet datum and the exact solution."""
    bnd, cfg = scene.boundary, scene.config
    planes = [bnd.ids[name] for name, role in bnd.roles.items() if role == "symmetry"]
    exact = None
    if cfg.data.exact is not None:
        gdim = scene.mesh.geometry.dim
        texts = components(cfg.data.exact, gdim)
        exact = ufl.as_vector(
            [expressions.to_ufl(e, scene.mesh, cfg.constants, t=scene.time) for e in texts]
        )
    t = setting.data["t"]
    return Elasticity(
        mu,
        lmbda_L,
        setting.data["f"],
        BoundaryData(
            bnd.tags,
            dirichlet=bnd.ids_with_role("dirichlet"),
            neumann={i: t for i in bnd.ids_with_role("neumann")},
            free=bnd.ids_with_role("natural"),
            symmetry=tuple(zip(planes, setting.symmetry_axes)),
        ),
        law=law,
        dirichlet_value=setting.data["u_D"],
        exact=exact,
    )


def contact_measure(scene: Scene, ds) -> ufl.Measure:
    """``ds`` over the scene's contact parts (the facets a rigid obstacle meets)."""
    return ds(scene.boundary.ids_with_role("contact"))


def reaction_form(system: ElasticSystem, u_h: fem.Function) -> fem.Form:
    """The residual without Dirichlet rows, a(u_h, v) − L(v), for reaction forces."""
    return fem.form(ufl.action(system.a_ufl, u_h) - system.L_ufl)


def elasticity_problem(scene: Scene) -> Problem:
    """Assemble the frictionless elastic contact problem of ``scene`` (docs/theory.md §1.3,
    §2) against its rigid obstacle (a scene with ``bodies`` is
    :func:`contact.models.bodies.bodies_problem`)."""
    t0 = time.perf_counter()
    check_scene_data(scene)  # every datum finite where it is used (ConfigError)
    model, obstacle = scene.config.model, scene.config.obstacle
    assert model.E is not None and obstacle is not None  # one body against an obstacle
    system = elastic_system(scene, *lame(model.E, model.nu))
    V, K, b, fixed, ds = system.V, system.K, system.b, system.fixed, system.data["ds"]
    if obstacle.type == "plane":
        contact = plane_contact(scene, V, K, b, fixed, ds)
    else:
        contact = curved_contact(scene, V, K, b, fixed, ds)
    if "K" in contact:  # a curved obstacle: K̃ = Qᵀ K Q and b̃ = Qᵀ b replace K and b
        destroy(K, b)
        K, b = contact.pop("K"), contact.pop("b")
    con = contact.pop("constraint")
    u_h = fem.Function(V, name="u_h")
    data = {**system.data, "reaction_form": reaction_form(system, u_h), **contact.pop("data")}
    rigid = RigidObstacle(scene_surface(scene), contact_measure(scene, ds))
    return Problem(
        V,
        u_h,
        system.bcs,
        K,
        b,
        con,
        data=data,
        **contact,
        **body_fields(system, contact.get("basis")),
        assembly_time=time.perf_counter() - t0,
        physics=elastic_physics(scene, system, system.data["mu"], system.data["lmbda_L"]),
        contacts=(rigid,),
    )


def body_fields(system, basis: PETSc.Mat | None) -> dict:
    """The DiscreteProblem fields of one elastic body (linear or hyperelastic) that follow
    from its setting: the symmetric copies it stands for, the rigid-body near-nullspace (in
    the contact basis Q) and the rigid motions no Dirichlet or symmetry part holds."""
    V = system.V
    return {
        "symmetric_copies": 2 ** len(system.symmetry_axes),
        "symmetry_axes": system.symmetry_axes,
        "near_nullspace": rigid_body_modes(V, basis),
        "floating": floating_bodies(V, system.fixed, None, []),
    }


def rigid_body_modes(
    V: fem.FunctionSpace, rotation: PETSc.Mat | None = None, inverse: PETSc.Mat | None = None
) -> PETSc.NullSpace:
    """Near-nullspace of elasticity for GAMG: gdim translations and the infinitesimal
    rotations (1 in 2D, 3 in 3D), in the solver's unknowns (Q⁻¹ m: Qᵀ m for a rotation,
    ``inverse`` m for a general change of basis), orthonormalised."""
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
    basis: list[PETSc.Vec] = []
    for m in modes:
        vec = PETSc.Vec().createMPI((n_local * gdim, PETSc.DECIDE), comm=msh.comm)
        vec.array[:] = m.ravel()
        if rotation is not None or inverse is not None:
            rotated = vec.duplicate()
            if inverse is not None:
                inverse.mult(vec, rotated)
            else:
                assert rotation is not None
                rotation.multTranspose(vec, rotated)
            vec.destroy()
            vec = rotated
        for prev in basis:  # modified Gram–Schmidt
            vec.axpy(-vec.dot(prev), prev)
        vec.normalize()
        basis.append(vec)
    return PETSc.NullSpace().create(vectors=basis, comm=msh.comm)


def von_mises(
    u_h: fem.Function, mu: float | None, lmbda_L: float | None, stresses=None
) -> fem.Function:
    """Cellwise (DG0) von Mises stress √(3/2 s:s), s the deviator of the 3D stress; in
    plane strain σ_zz = λ_L tr ε (ε_zz = 0) is included.  ``stresses``: u ↦ (P, σ) of a
    hyperelastic body (:func:`contact.models.hyperelastic.piola_and_cauchy`), whose 3 × 3
    Cauchy stress σ is used instead (at the cell's midpoint, in the current configuration)."""
    msh = u_h.function_space.mesh
    if stresses is not None:
        sig = stresses(u_h)[1]
    else:
        assert mu is not None and lmbda_L is not None, "a linear body's Lamé parameters"
        sig = stress(u_h, mu, lmbda_L)
        if msh.geometry.dim == 2:
            szz = lmbda_L * ufl.tr(epsilon(u_h))
            sig = ufl.as_matrix([[sig[0, 0], sig[0, 1], 0], [sig[1, 0], sig[1, 1], 0], [0, 0, szz]])
    dev = sig - ufl.tr(sig) / 3 * ufl.Identity(3)
    W = fem.functionspace(msh, ("DG", 0))
    out = fem.Function(W, name="von_mises")
    out.interpolate(
        fem.Expression(ufl.sqrt(1.5 * ufl.inner(dev, dev)), W.element.interpolation_points)
    )
    return out
