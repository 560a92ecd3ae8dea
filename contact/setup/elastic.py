"""An elastic scene's models (docs/theory.md §1.3–1.5): linear elasticity against a rigid
obstacle, several bodies in one mesh in contact through mortar pairs (and an obstacle), and
the friction law of their contact nodes — the scene's data read into the core's objects
(:class:`~contact.models.physics.Elasticity`, :class:`~contact.models.constraints.RigidObstacle`,
:class:`~contact.models.constraints.MortarPair`, :class:`~contact.models.constraints.Tresca`,
:class:`~contact.models.constraints.Coulomb`) and built by the same
:func:`~contact.models.forms.make_problem` as a user's own forms.

    σ(u) = 2μ ε(u) + λ_L tr ε(u) I   (plane strain in 2D),   −div σ(u) = f in Ω,
    u = u_D on Γ_D,   σ n = t on Γ_N,   u·n_s = 0 on symmetry planes,
    u·n ≤ g,  λ_n := σ_nn(u) ≤ 0,  λ_n (u·n − g) = 0,  σ_nt(u) = 0   on Γ_C,

with n the unit normal towards the obstacle and g ≥ 0 the initial gap along n
(:mod:`contact.models.obstacles` turns u·n ≤ g into a bound on one unknown per contact
node; :mod:`contact.models.contacts` the pairs into the mortar change of basis).  Several
bodies are the disconnected components of one DOLFINx mesh, told apart by the cell tags of
:func:`~.meshes.tag_bodies`; one vector space carries them all, with Lamé parameters that
are DG0 functions (E_k, ν_k of body k).  Units: E and stresses in Pa (or any consistent
unit), lengths in m, forces per unit thickness in N/m in 2D.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import dolfinx.mesh
import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from ..base import expressions, spaces
from ..base.errors import ConfigError
from ..models.constraints import Coulomb, MortarPair, RigidObstacle, Tresca
from ..models.discrete import Problem
from ..models.forms import make_problem
from ..models.physics import BoundaryData, Elasticity, epsilon, lame, stress
from ..models.problem import assemble_system
from ..solvers.problem import ProblemData
from .checks import check_scene_data
from .data import vector, vector_numpy
from .obstacle import scene_obstacle, scene_surface
from .scene import Scene
from .scene_config import components


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


def elastic_setting(scene: Scene, degree: int | None = None) -> ElasticSetting:
    """The space (Lagrange of ``degree``, default ``mesh.degree``, gdim components), the load
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
    V = spaces.functionspace(msh, ("Lagrange", degree or cfg.mesh.degree, (gdim,)))
    v = ufl.TestFunction(V)
    f, t = vector(data["f"], scene), vector(data["t"], scene)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=bnd.tags)
    dx = ufl.Measure("dx", domain=msh)
    L_ufl = ufl.inner(f, v) * dx
    for i in bnd.ids_with_role("neumann"):
        L_ufl += ufl.inner(t, v) * ds(i)

    # Dirichlet: u = u_D on Γ_D;  symmetry: u_k = 0 on a plane x_k = const.
    u_D = spaces.zero_function(V)
    u_D.interpolate(vector_numpy(data["u_D"], scene))
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
    fields = {"f": f, "t": t, "ds": ds, "u_D": vector(data["u_D"], scene)}
    return ElasticSetting(V, L_ufl, bcs, fixed, fields, tuple(axes))


def elastic_physics(
    scene: Scene, setting: ElasticSetting, mu, lmbda_L, law: str | None = None
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


def obstacle_shape(scene: Scene) -> tuple:
    """(normal, gap, n_ufl, g_ufl) of the scene's obstacle: ``normal``/``gap`` map node
    coordinates (n, gdim) to the unit normals n (towards the obstacle) and the initial gaps
    g, the UFL expressions are the same for forms (:func:`scene_surface`)."""
    surface = scene_surface(scene)
    n_ufl, g_ufl = surface.expression(ufl.SpatialCoordinate(scene.mesh))
    return (
        lambda x: surface.project(x)[1],
        lambda x: surface.project(x)[0],
        n_ufl,
        g_ufl,
    )


def friction_law(scene: Scene) -> Tresca | Coulomb | None:
    """The scene's friction law (``friction`` section; None without friction): Coulomb's
    coefficient, or Tresca's threshold s(x, t) as UFL (the estimators' ρ) with its values at
    the nodes from the scene's expression, and the section's tangential knobs."""
    cfg = scene.config.friction
    if cfg is None or not scene.config.frictional:
        return None
    if cfg.law == "coulomb":
        assert cfg.coefficient is not None  # Coulomb's, required at load
        return Coulomb(cfg.coefficient, options=cfg.knobs())
    assert cfg.threshold is not None  # Tresca's, required at load
    consts = scene.config.constants
    return Tresca(
        expressions.to_ufl(cfg.threshold, scene.mesh, consts, t=scene.t_constant),
        at_nodes=expressions.to_numpy(cfg.threshold, consts, t=scene.time),
        options=cfg.knobs(),
        key="friction.threshold",
        when=f" at t = {scene.time:g}",
    )


def scene_rigid(scene: Scene, ds: ufl.Measure) -> RigidObstacle:
    """The scene's rigid obstacle as a contact condition on its contact parts (``ds`` over the
    boundary tags), with the scene's friction law; a moving obstacle (its point or centre an
    expression of t) with its translation since the state the slip starts from — the
    previous step's solution, or the unloaded body at t = 0."""
    obstacle = scene_obstacle(scene)
    motion = None
    if obstacle.moving:
        previous = scene.previous_time if "u_prev" in scene.history else None
        start = previous if previous else 0.0
        motion = obstacle.position - scene_obstacle(scene, start).position
    return RigidObstacle(
        scene_surface(scene),
        ds(scene.boundary.ids_with_role("contact")),
        friction=friction_law(scene),
        motion=motion,
        moving=obstacle.moving,
    )


def scene_pairs(scene: Scene, ds: ufl.Measure) -> tuple[MortarPair, ...]:
    """The scene's contact pairs as :class:`~contact.models.constraints.MortarPair` s on
    their boundary parts (``ds`` over the boundary tags), with the scene's friction law."""
    bnd, law = scene.boundary, friction_law(scene)
    return tuple(
        MortarPair(
            ds(bnd.ids[pair.slave]),
            ds(bnd.ids[pair.master]),
            friction=law,
            search=pair.search,
            names=(pair.slave, pair.master),
        )
        for pair in scene.config.pairs or ()
    )


def reaction_form(a_ufl: ufl.Form, L_ufl: ufl.Form, u_h: fem.Function) -> fem.Form:
    """The residual without Dirichlet rows, a(u_h, v) − L(v), for reaction forces."""
    return fem.form(ufl.action(a_ufl, u_h) - L_ufl)


def elasticity_problem(scene: Scene, mu=None, lmbda_L=None, body=None) -> Problem:
    """The elastic contact problem of ``scene`` (docs/theory.md §1.3–1.5, §2): one body (Lamé
    parameters of ``model.E``, ``model.nu``) against its rigid obstacle, or several bodies
    (``mu``, ``lmbda_L`` DG0 functions of their materials, ``body`` their numbers;
    :func:`bodies_problem`) in contact through the scene's pairs and, if any, its obstacle;
    with the scene's friction law."""
    t0 = time.perf_counter()
    check_scene_data(scene)  # every datum finite where it is used (ConfigError)
    cfg = scene.config
    if mu is None:
        assert cfg.model.E is not None  # one body against an obstacle
        mu, lmbda_L = lame(cfg.model.E, cfg.model.nu)
    s = elastic_setting(scene)
    V, ds = s.V, s.data["ds"]
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a_ufl = ufl.inner(stress(u, mu, lmbda_L), epsilon(v)) * ufl.dx(domain=scene.mesh)
    u_h = fem.Function(V, name="u_h")
    conditions: tuple = scene_pairs(scene, ds)
    if cfg.obstacle is not None:
        conditions += (scene_rigid(scene, ds),)
    data = ProblemData(
        f=s.data["f"],
        t=s.data["t"],
        ds=ds,
        mu=mu,
        lmbda_L=lmbda_L,
        reaction_form=reaction_form(a_ufl, s.L_ufl, u_h),
        body=body,
    )
    return make_problem(
        "linear",
        V,
        u_h,
        s.bcs,
        lambda: assemble_system(fem.form(a_ufl), fem.form(s.L_ufl), s.bcs),
        conditions,
        t0,
        physics=elastic_physics(scene, s, mu, lmbda_L),
        data=data,
        u_prev=scene.history.get("u_prev"),
        bodies=(scene.bodies, list(cfg.bodies or ())),
    )


def materials(scene: Scene) -> tuple[fem.Function, fem.Function, fem.Function]:
    """DG0 Lamé parameters μ, λ_L of each cell's body and the DG0 ``body`` number (1, 2, …
    in the order of the bodies section; the output tells the bodies apart by it)."""
    msh, tags = scene.mesh, scene.bodies
    assert tags is not None  # a scene of several bodies has its body tags
    W = spaces.functionspace(msh, ("DG", 0))
    mu, lmbda_L, body = (spaces.zero_function(W, name) for name in ("mu", "lmbda_L", "body"))
    bodies = scene.config.bodies
    assert bodies is not None  # a scene with bodies
    values = [lame(b.E, b.nu) for b in bodies.values()]
    k = tags.values - 1
    dofs = W.dofmap.list[tags.indices].ravel()
    mu.x.array[dofs] = np.array([v[0] for v in values])[k]
    lmbda_L.x.array[dofs] = np.array([v[1] for v in values])[k]
    body.x.array[dofs] = tags.values
    return mu, lmbda_L, body


def bodies_problem(scene: Scene) -> Problem:
    """The multi-body contact problem of ``scene``: elasticity with one material per body,
    its mortar pairs (and a rigid obstacle's nodes) as the change of basis u = Q x
    (:func:`contact.models.contacts.mortar_set`)."""
    return elasticity_problem(scene, *materials(scene))
