"""Penalty, augmented Lagrangian and Nitsche: the ways other contact codes enforce a
unilateral constraint, as baselines beside semismooth Newton on an NCP function
(docs/theory.md §10).  Scene-free: a problem hands over its stiffness and load, the
contact measure and the constraint as UFL (:class:`UnilateralContact`); each method adds
its contact term to the residual, F(u; v) = a(u, v) − L(v) + C(u; v) = 0, solved by Newton
through PETSc SNES (``newtonls``) with the generalized derivative of [·]₊ / [·]₋ (UFL's
derivative of ``max_value`` / ``min_value``: 0 at the kink).

The constraint is d(u) ≤ g on the contact measure: d(u) = u (scalar Signorini, u ≤ g),
σ u (an obstacle in Ω, σ = ±1) or u·n (elasticity, n towards the obstacle, g the initial
gap along n).  p ≥ 0 is the contact pressure (scalar: the flux into the obstacle, −λ),
σ_n(w) the normal traction of w along n on Γ_C (scalar: k ∇w·n_Γ), linear in w, and
σ_n(u) + t₀ the traction of u (t₀ = −t_C for the scalar model, 0 for elasticity).
[x]₊ = max(x, 0), [x]₋ = min(x, 0).  The scaling s = E/h (k/h for scalar models):

* ``penalty`` — p = ε [d(u) − g]₊,  ε = ε₀ s:  C(u; v) = ∫ p d(v).  The constraint is
  violated by O(1/ε): penetration and multiplier error O(1/ε₀).  Vertex quadrature
  (nodal, node-to-surface penalty as commercial codes and MOOSE do it): at a contact node
  the term is w_i ε_i [d_i − g_i]₊, so that as ε → ∞ the solution tends to the discrete
  solution of the NCP methods (the same lumped weights w_i), at the rate 1/ε₀.
* ``augmented_lagrangian`` — Uzawa's outer loop on the nodal pressure μ ≥ 0 (Alart &
  Curnier's augmented Lagrangian with r = r₀ s): the inner problem is the penalty problem
  shifted by μ_k, p = [μ_k + r (d(u) − g)]₊ (vertex quadrature), then
  μ_{k+1} = [μ_k + r (d(u_{k+1}) − g)]₊ nodewise, until max|μ_{k+1} − μ_k| ≤
  ``uzawa_rtol`` · max μ_{k+1}.  Its fixed point is the exact discrete complementarity
  solution for any r > 0; r sets the outer rate (and the inner conditioning).  Newton on
  (u, μ) jointly instead — Alart–Curnier's generalized Newton — is the NCP ``min`` with
  c = 1/r: μ = [μ + r(d − g)]₊ ⇔ min(g − d, μ/r) = 0, already a method of the package.
* ``nitsche`` — Chouly & Hild (2013): with γ = γ₀ s, P(u) = σ_n(u) + t₀ − γ (d(u) − g)
  and P_θ(v) = θ σ_n(v) − γ d(v),

      C(u; v) = −(θ/γ) ∫ (σ_n(u) + t₀) σ_n(v) + (1/γ) ∫ [P(u)]₋ P_θ(v),   p = −[P(u)]₋,

  θ = 1 symmetric (the gradient of an energy; coercive only for γ₀ large enough), θ = −1
  skew-symmetric (coercive for every γ₀ > 0), θ = 0.  Consistent: the exact solution
  satisfies it for every γ, so the error is the discretization's, O(h^{1/2+ν}) in H¹
  (no parameter limit to take).  Gauss quadrature of degree 2p + 2 on the facets.

Friction (:class:`FrictionLaw`, elasticity): with the slip s_t = u_t − u_t^prev and the
bound ρ (Tresca: the threshold; Coulomb: F p), the tangential traction on the body is
−[ε_t s_t]_ρ (penalty, ε_t = ε), −[ν_k + r s_t]_ρ (augmented Lagrangian, the tangential
multiplier ν updated by Uzawa like μ) or, for Nitsche (Chouly, Hild & Renard 2015),
[σ_t(u) − γ s_t]_ρ with ρ = F (−[P(u)]₋) and the term (1/γ) ∫ [σ_t(u) − γ s_t]_ρ ·
(θ σ_t(v) − γ v_t) − (θ/γ) ∫ σ_t(u)·σ_t(v); [x]_ρ is the projection onto the ball of
radius ρ.

Linear solvers as for the NCP methods (:mod:`.linear`): MUMPS below the 2D size switch,
else CG + GAMG (symmetric Jacobians: penalty, augmented Lagrangian and symmetric Nitsche
without friction) or GMRES + GAMG (the others), with the rigid-body near-nullspace, each
Newton system solved to ksp_rtol 1e-10 (``solver.inexact`` does not apply: Eisenstat–Walker
forcing, even capped at 0.1, made the penalty's Newton iteration wander on hertz_2d — a
Krylov error δ at a contact node leaves a residual ε w δ, ε₀ times the bulk's — where exact
steps take 7; ``solver.petsc_options: {snes_ksp_ew: true}`` turns it on).  The Jacobian is
K + C′(u): the bulk K is assembled once, only the contact term's tangent at each Newton
step.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import dolfinx.fem.petsc
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base import progress
from ..base.lifetime import Owner
from ..base.norms import norm2, norm_inf
from ..base.timing import Stopwatch, Timer
from .linear import DIRECT_MAX_DOFS_2D, DIRECT_MAX_DOFS_3D
from .options import (
    BASELINE_METHODS,
    DEFAULT_PETSC_OPTIONS,
    SolverOptions,
    default_options,
    petsc_value,
)
from .options import set_from_options as set_options_of
from .problem import DiscreteProblem, newton_max_it, nodes_across
from .result import REASONS, Result, close_timings
from .snes import ROUNDOFF, roundoff_floor

#: the enforcement methods of this module (``solver.method``)
METHODS = BASELINE_METHODS
#: the dimensionless parameter of each method (``solver.<name>``): ε₀, r₀, γ₀
PARAMETERS = {"penalty": "epsilon0", "augmented_lagrangian": "r0", "nitsche": "gamma0"}

_counter = itertools.count()


@dataclass(frozen=True)
class FrictionLaw:
    """Tresca or Coulomb friction on the contact measure of an elastic body.

    ``tangential(w)`` — the tangential part w − (w·n) n of a vector field; ``traction(w)`` —
    σ(w) n_Γ − σ_n(w) n, the tangential traction of w (Nitsche); ``u_prev`` — the
    displacement of the previous load step (the slip is measured from it); ``threshold`` —
    Tresca's bound s ≥ 0 (UFL, stress), or ``coefficient`` — Coulomb's F."""

    tangential: Callable[[Any], Any]
    traction: Callable[[Any], Any]
    u_prev: fem.Function
    threshold: Any = None
    coefficient: float | None = None


@dataclass
class UnilateralContact:
    """What a baseline method needs of a problem: the constraint d(u) ≤ g as UFL.

    ``u`` — the unknown (its values: the initial guess, Dirichlet values included); ``K``,
    ``b`` — the bulk stiffness and lifted load of a(u, v) = L(v) (Dirichlet rows and columns
    identity), R(u) = K u − b; ``bcs``; ``measure`` — the contact measure (``ds(tags)``,
    or ``dx`` for an obstacle in Ω); ``normal_part`` — d(w), linear; ``gap`` — g;
    ``modulus`` — E (or k) of the default scaling s = modulus / h; ``traction`` — σ_n(w)
    (None: Nitsche does not apply, an obstacle in Ω); ``traction_data`` — t₀;
    ``near_nullspace`` — rigid-body modes (GAMG); ``friction`` — a :class:`FrictionLaw`."""

    u: fem.Function
    K: PETSc.Mat
    b: PETSc.Vec
    bcs: list
    measure: ufl.Measure
    normal_part: Callable[[Any], Any]
    gap: Any
    modulus: Any
    traction: Callable[[Any], Any] | None = None
    traction_data: Any = 0.0
    near_nullspace: PETSc.NullSpace | None = None
    friction: FrictionLaw | None = None


def ball(x, radius):
    """[x]_ρ: the projection of the vector x onto the ball of radius ρ ≥ 0 (UFL)."""
    size = ufl.sqrt(ufl.dot(x, x) + 1e-300)
    return ufl.conditional(ufl.le(size, radius), x, radius * x / size)


def nodal_scaling(contact: UnilateralContact, S: fem.FunctionSpace) -> fem.Function:
    """s_i = ∫ (modulus / h) φ_i / ∫ φ_i over the contact measure, a P1 function (1 off the
    contact nodes): the nodal value of E/h (h the cell diameter), so that the penalty and
    the augmented Lagrangian, integrated at the vertices, act with one scale per node (a
    cellwise E/h would give a node one scale per facet and no nodal multiplier)."""
    return nodal_scale(contact.measure, contact.modulus, S)


def nodal_scale(measure: ufl.Measure, modulus: Any, S: fem.FunctionSpace) -> fem.Function:
    """s_i = ∫ (modulus / h) φ_i / ∫ φ_i over ``measure`` (vertex rule) on the P1 space S,
    1 off the measure's nodes (:func:`nodal_scaling`)."""
    msh = S.mesh
    phi = ufl.TestFunction(S)
    vertex = _vertex(measure)
    w = dolfinx.fem.petsc.assemble_vector(fem.form(phi * vertex))
    sw = dolfinx.fem.petsc.assemble_vector(fem.form(modulus / ufl.CellDiameter(msh) * phi * vertex))
    add, reverse = PETSc.InsertMode.ADD, PETSc.ScatterMode.REVERSE
    for vec in (w, sw):
        vec.ghostUpdate(addv=add, mode=reverse)  # type: ignore[arg-type]
    out = fem.Function(S, name="scale")
    n = S.dofmap.index_map.size_local
    on = w.array_r > 0
    out.x.array[:n] = 1.0
    out.x.array[:n][on] = sw.array_r[on] / w.array_r[on]
    out.x.scatter_forward()
    w.destroy()
    sw.destroy()
    return out


def _vertex(measure: ufl.Measure) -> ufl.Measure:
    """The measure with vertex quadrature (the lumped, nodal rule of P1)."""
    return measure.reconstruct(metadata={"quadrature_rule": "vertex", "quadrature_degree": 1})


class Formulation:
    """The contact term of one method on a :class:`UnilateralContact`: the residual form
    C(u; v), its tangent, the pressure p (UFL) and its measure.  The parameter (ε₀, r₀,
    γ₀) and θ are ``fem.Constant``s: a sweep re-assembles, it does not re-compile."""

    def __init__(self, contact: UnilateralContact, method: str, value: float, theta: float = 1.0):
        if method not in METHODS:
            raise ValueError(f"method: {method!r} is not one of {', '.join(METHODS)}")
        if method == "nitsche" and contact.traction is None:
            raise ValueError("nitsche: needs the normal traction of the constraint's boundary")
        u = contact.u
        V = u.function_space
        msh = V.mesh
        self.method, self.contact = method, contact
        self.value = fem.Constant(msh, PETSc.ScalarType(value))  # type: ignore[operator]
        self.theta = fem.Constant(msh, PETSc.ScalarType(theta))  # type: ignore[operator]
        self.S = fem.functionspace(msh, ("Lagrange", 1))
        # the Uzawa multipliers (nodal pressure μ, tangential ν), zero for the penalty
        self.mu = fem.Function(self.S, name="mu")
        gdim = msh.geometry.dim
        self.nu = (
            fem.Function(fem.functionspace(msh, ("Lagrange", 1, (gdim,))), name="nu")
            if contact.friction is not None and method != "nitsche"
            else None
        )
        v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
        d, g = contact.normal_part, contact.gap
        if method == "nitsche":
            degree = V.element.basix_element.degree
            self.measure = contact.measure.reconstruct(
                metadata={"quadrature_degree": 2 * degree + 2}
            )
            gamma = self.value * contact.modulus / ufl.CellDiameter(msh)
            assert contact.traction is not None
            sn = contact.traction
            traction = sn(u) + contact.traction_data
            P = traction - gamma * (d(u) - g)
            self.pressure = -ufl.min_value(P, 0.0)
            self.indicator = -P
            th = self.theta
            C = -th / gamma * (traction + self.pressure) * sn(v) + self.pressure * d(v)
            if contact.friction is not None:
                fr = contact.friction
                bound = self._bound(fr, self.pressure)
                st = fr.tangential(u - fr.u_prev)
                q = ball(fr.traction(u) - gamma * st, bound)  # the tangential traction
                C += ufl.dot(q, th / gamma * fr.traction(v) - fr.tangential(v))
                C -= th / gamma * ufl.dot(fr.traction(u), fr.traction(v))
                self.tangential = q
        else:
            self.measure = _vertex(contact.measure)
            self.scale = nodal_scaling(contact, self.S)
            k = self.value * self.scale  # ε or r, nodal
            shift: Any = self.mu if method == "augmented_lagrangian" else 0.0
            self.indicator = shift + k * (d(u) - g)
            self.pressure = ufl.max_value(self.indicator, 0.0)
            C = self.pressure * d(v)
            if contact.friction is not None:
                fr = contact.friction
                bound = self._bound(fr, self.pressure)
                st = fr.tangential(u - fr.u_prev)
                shift_t = self.nu if method == "augmented_lagrangian" else ufl.zero(gdim)
                q = -ball(shift_t + k * st, bound)  # the tangential traction on the body
                C -= ufl.dot(q, fr.tangential(v))
                self.tangential = q
        self.residual = C * self.measure
        self.jacobian = ufl.derivative(self.residual, u, du)
        # the contact traction's nodal force (normal −p n, tangential q on the body), what
        # K u − b is at the solution for penalty and augmented Lagrangian (Nitsche with θ = 0)
        force = -self.pressure * d(v)
        if contact.friction is not None:
            force += ufl.dot(self.tangential, contact.friction.tangential(v))
        self.force = force * self.measure
        # a node is in contact where the argument of [·]₊ is positive there: its lumped mean
        # by the vertex rule (nodal for the penalty and the augmented Lagrangian; Nitsche's
        # −P(u) at the node averaged over the node's facets — Gauss points would count a node
        # next to the contact zone in it), ∫ φ_i beside it.  Σ_k v_k: the same value at every
        # component's DoF of a node
        weight = v if V.dofmap.index_map_bs == 1 else sum(v[k] for k in range(gdim))
        vertex = _vertex(contact.measure)
        self.contact_form = self.indicator * weight * vertex
        self.weight_form = weight * vertex
        self.symmetric = contact.friction is None and (method != "nitsche" or theta == 1.0)

    @staticmethod
    def _bound(fr: FrictionLaw, pressure):
        """ρ: Tresca's threshold, or Coulomb's F p."""
        if fr.coefficient is not None:
            return fr.coefficient * pressure
        return fr.threshold

    def update_multipliers(self) -> tuple[float, float, float]:
        """One Uzawa step at the current u: μ ← [μ + r(d(u) − g)]₊ = p(u) (and ν ← −q(u), the
        tangential traction, with friction) at the contact nodes, both from the same u and
        μ; returns (the largest change of μ or ν, max μ, the round-off floor of the change:
        16 ε max r max|u|) over all ranks.  Without the floor a large r never stops: the
        inner solve leaves d(u) − g at round-off, and r magnifies it (r₀ = 1e7 on problem A
        at 128 × 64: Δμ / μ ≈ 1e-7 at every outer iteration)."""
        S = self.S
        if not hasattr(self, "_updates"):  # compiled once: p(u), and −q(u) with friction
            self._updates = [
                (self.mu, fem.Expression(self.pressure, S.element.interpolation_points))
            ]
            if self.nu is not None:
                points = self.nu.function_space.element.interpolation_points
                self._updates.append((self.nu, fem.Expression(-self.tangential, points)))
        fresh = []
        for target, expr in self._updates:
            new = fem.Function(target.function_space)
            new.interpolate(expr)
            fresh.append(new)
        on = np.flatnonzero(self._contact_nodes())
        change = size = 0.0
        for (target, _), new in zip(self._updates, fresh):
            bs = target.function_space.dofmap.index_map_bs
            idx = (on[:, None] * bs + np.arange(bs)).ravel()
            moved = np.abs(new.x.array[idx] - target.x.array[idx])
            change = max(change, float(np.max(moved, initial=0.0)))
            if target is self.mu:
                size = float(np.max(new.x.array[idx], initial=0.0))
            target.x.array[idx] = new.x.array[idx]
            target.x.scatter_forward()
        # what a change of μ can be measured to: r times the round-off of d(u) − g
        r = float(self.value.value) * float(np.max(self.scale.x.array[on], initial=0.0))
        u = float(np.max(np.abs(self.contact.u.x.array), initial=0.0))
        comm = S.mesh.comm
        floor = ROUNDOFF * np.finfo(float).eps * r * comm.allreduce(u, op=MPI.MAX)
        return (
            comm.allreduce(change, op=MPI.MAX),
            comm.allreduce(size, op=MPI.MAX),
            comm.allreduce(floor, op=MPI.MAX),
        )

    def _contact_nodes(self) -> np.ndarray:
        """The owned P1 nodes the contact measure weighs (w_i > 0), a mask."""
        if not hasattr(self, "_on"):
            w = dolfinx.fem.petsc.assemble_vector(
                fem.form(ufl.TestFunction(self.S) * _vertex(self.contact.measure))
            )
            w.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]
            self._on = w.array_r > 0
            w.destroy()
        return self._on


@dataclass
class Outcome:
    """What a baseline solve did: the SNES reason of the last Newton solve, Newton iterations
    (all outer iterations), Uzawa's outer iterations (augmented Lagrangian; 1 otherwise),
    Krylov iterations, the history (one row per Newton iterate) and the linear solver."""

    reason: int
    iterations: int
    outer: int
    krylov: int
    history: list[dict] = field(default_factory=list)
    linear: str = "direct"


def linear_kind(V: fem.FunctionSpace, linear: str, petsc_options: dict) -> str:
    """``direct`` (MUMPS) or ``krylov`` (GAMG-preconditioned) for ``solver.linear``; ``auto``
    switches at the NCP methods' sizes (:data:`.linear.DIRECT_MAX_DOFS_2D`)."""
    if {"ksp_type", "pc_type"} & set(petsc_options) or linear == "direct":
        return "direct"
    if linear != "auto":
        return "krylov"
    dofs = V.dofmap.index_map.size_global * V.dofmap.index_map_bs
    limit = DIRECT_MAX_DOFS_2D if V.mesh.geometry.dim == 2 else DIRECT_MAX_DOFS_3D
    return "direct" if dofs < limit else "krylov"


def linear_options(kind: str, V: fem.FunctionSpace, symmetric: bool, linear: str) -> dict:
    """PETSc options of the Newton systems: MUMPS LU, or CG + GAMG (symmetric) / GMRES + GAMG
    (``linear: gmres``, or a Jacobian that is not symmetric), as :func:`.options.default_options`
    configures GAMG for the NCP methods (unsmoothed aggregation in 3D)."""
    if kind == "direct":
        return dict(DEFAULT_PETSC_OPTIONS)
    msh = V.mesh
    out = default_options("gamg", msh.topology.dim, msh.comm.size)
    out.pop("pc_use_amat", None)
    if linear == "bcgs":
        out["ksp_type"] = "bcgs"
    elif not symmetric or linear == "gmres":
        out.update(ksp_type="gmres", ksp_gmres_restart=100, ksp_pc_side="right")
    return out


def _assemble(form: fem.Form) -> PETSc.Vec:
    """The vector of a linear form, ghost contributions summed into the owners."""
    vec = dolfinx.fem.petsc.assemble_vector(form)
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]
    return vec


class EnforcedNewton:
    """Newton on K u − b + C(u) = 0 for one :class:`Formulation`, through a PETSc SNES
    (``newtonls``; ``solver.line_search`` bt or basic — auto is basic without friction, bt
    with it) that it owns with its
    options prefix; :meth:`solve` runs it from an iterate (augmented Lagrangian: Uzawa's
    outer loop around it).  Stopping as for the NCP methods: ‖F‖ ≤ max(rtol ‖F(x₀)‖,
    atol ‖F(x_D)‖_∞, the round-off floor 16 ε ‖J‖_∞ ‖x‖)."""

    def __init__(
        self,
        form: Formulation,
        options: SolverOptions,
        verbose: bool = False,
        timers: dict | None = None,
        prefix: str | None = None,
    ):
        c = form.contact
        self.form, self.opts, self.verbose = form, options, verbose
        self.timers = {"assembly": 0.0, "solve": 0.0} if timers is None else timers
        V = self.space()
        self.comm = V.mesh.comm
        self._owner = owner = Owner()
        with Timer(self.timers, "assembly"):
            self.prepare(owner)
            self.J = owner.own(c.K.duplicate(copy=True))
            if c.near_nullspace is not None:
                self.J.setNearNullSpace(c.near_nullspace)
        n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        rows = [dofs[:owned] for dofs, owned in (bc.dof_indices() for bc in c.bcs)]
        self.dirichlet = np.unique(np.concatenate([np.zeros(0, np.int32), *rows]))
        self.dirichlet = self.dirichlet[self.dirichlet < n_owned]
        user = {str(k): v for k, v in options.petsc_options.items()}
        self.kind = linear_kind(V, options.linear, user)
        self.petsc_options = {
            **linear_options(self.kind, V, form.symmetric, options.linear),
            **user,
        }
        #: the linear solver's name as the NCP methods report it (direct, gamg: CG + GAMG, …)
        ksp = str(self.petsc_options.get("ksp_type", "preonly"))
        self.linear = "direct" if ksp == "preonly" else {"cg": "gamg"}.get(ksp, ksp)
        self.snes = snes = owner.own(PETSc.SNES().create(self.comm))
        self.prefix = f"contactbase{next(_counter)}_" if prefix is None else prefix
        snes.setOptionsPrefix(self.prefix)
        snes.setType("newtonls")
        snes.setFunction(self._residual, owner.own(c.b.duplicate()))
        snes.setJacobian(self._jacobian, self.J)
        snes.setDivergenceTolerance(PETSc.UNLIMITED)  # no dtol stop (semismooth steps)
        snes.setMonitor(self._monitor)
        progress.watch(snes.getKSP(), f"{form.method} linear solve")
        self.history: list[dict] = []
        self._prev = owner.own(c.b.duplicate())
        self._k_norm = 0.0
        self.atol = 0.0
        self._outer = 0

    def space(self) -> fem.FunctionSpace:
        """The space of the iterate (its layout, the size switch of the linear solver)."""
        return self.form.contact.u.function_space

    def prepare(self, owner: Owner) -> None:
        """Compile the contact term's forms and create their vectors and matrix."""
        form = self.form
        self.F_form = fem.form(form.residual)
        self.J_form = fem.form(form.jacobian)
        self.force_form = fem.form(form.force)
        self.indicator_form = fem.form(form.contact_form)
        weights = _assemble(fem.form(form.weight_form))
        self._weights = weights.array_r.copy()
        weights.destroy()
        self.Fc = owner.own(dolfinx.fem.petsc.create_vector(self.space()))
        self.Jc = owner.own(dolfinx.fem.petsc.create_matrix(self.J_form))

    # --- callbacks ---------------------------------------------------------------------
    def _set_iterate(self, x: PETSc.Vec) -> None:
        u = self.form.contact.u.x
        u.petsc_vec.array_w[:] = x.array_r
        u.scatter_forward()

    def _residual(self, snes: PETSc.SNES, x: PETSc.Vec, F: PETSc.Vec) -> None:
        with Timer(self.timers, "assembly"):
            c = self.form.contact
            self._set_iterate(x)
            c.K.mult(x, F)
            F.axpy(-1.0, c.b)
            self.add_contact(F)

    def add_contact(self, F: PETSc.Vec) -> None:
        """F += C(u; ·) at the current iterate, Dirichlet rows untouched."""
        Fc = self.Fc
        with Fc.localForm() as local:
            local.set(0.0)
        dolfinx.fem.petsc.assemble_vector(Fc, self.F_form)  # type: ignore[arg-type]
        Fc.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]
        Fc.array_w[self.dirichlet] = 0.0
        F.axpy(1.0, Fc)

    def _jacobian(self, snes: PETSc.SNES, x: PETSc.Vec, J: PETSc.Mat, P: PETSc.Mat) -> None:
        with Timer(self.timers, "assembly"):
            self._set_iterate(x)
            Jc = self.Jc
            Jc.zeroEntries()
            assemble = dolfinx.fem.petsc.assemble_matrix
            assemble(Jc, self.J_form, bcs=self.form.contact.bcs, diag=0.0)  # type: ignore[arg-type, misc]
            Jc.assemble()
            same = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
            self.form.contact.K.copy(J, structure=same)  # type: ignore[arg-type]
            J.axpy(1.0, Jc, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)  # type: ignore[arg-type]
            # ‖J‖_∞ for the round-off floor: a large penalty raises it
            self._k_norm = float(J.norm(PETSc.NormType.INFINITY))  # type: ignore[arg-type]

    def _monitor(self, snes: PETSc.SNES, its: int, fnorm: float) -> None:
        xk = snes.getSolution()
        floor = roundoff_floor(self._k_norm, xk)
        if floor > snes.getTolerances()[1]:
            snes.setTolerances(atol=floor)
        step = np.nan
        if its > 0:
            self._prev.axpy(-1.0, xk)
            step = norm2(self._prev)
        xk.copy(self._prev)
        active = self.contact_nodes()
        row = {
            "iteration": len(self.history),
            "residual": float(fnorm),
            "step": float(step),
            "active": active,
            "changed": 0,
            "polished": False,
            "outer": self._outer,
        }
        self.history.append(row)
        if self.verbose and self.comm.rank == 0:
            st = "    -" if its == 0 else f"{step:9.3e}"
            uzawa = self.form.method == "augmented_lagrangian"
            outer = f"  outer {self._outer:3d}" if uzawa else ""
            print(
                f"  {self.form.method:>12s} it {its:3d}  |F| = {fnorm:10.3e}  |du| {st}  "
                f"in contact {active:7d}{outer}",
                flush=True,
            )
            progress.heard()
        else:
            progress.note(lambda: f"{self.form.method} Newton iteration {its}, |F| = {fnorm:.3e}")

    # --- quantities ----------------------------------------------------------------------
    def nodal_force(self) -> PETSc.Vec:
        """−∫ p d(φ_i) at the current u (owned entries, Dirichlet rows 0): a new vector."""
        vec = _assemble(self.force_form)
        vec.array_w[self.dirichlet] = 0.0
        return vec

    def in_contact(self, dofs: np.ndarray) -> np.ndarray:
        """Whether each of the owned DoFs ``dofs`` is in contact at the current u: the lumped
        mean of the method's indicator (d − g for the penalty, μ + r(d − g) for the
        augmented Lagrangian, −P(u) for Nitsche) is positive there."""
        vec = _assemble(self.indicator_form)
        w = self._weights[dofs]
        out = np.zeros(len(dofs), dtype=bool)
        on = w > 0
        out[on] = vec.array_r[dofs][on] / w[on] > 0.0
        vec.destroy()
        return out

    def max_it(self) -> int:
        """The Newton step limit (``solver.max_it``; ``auto``: by the contact nodes across
        the contact set, :func:`~.problem.newton_max_it`; collective)."""
        if self.opts.max_it != "auto":
            return int(self.opts.max_it)
        V = self.space()
        bs, tdim = V.dofmap.index_map_bs, V.mesh.topology.dim
        nodes = np.unique(np.flatnonzero(self._weights > 0) // bs)
        dim = tdim if self.form.contact.measure.integral_type() == "cell" else tdim - 1
        across = nodes_across(V.tabulate_dof_coordinates()[nodes], dim, self.comm)
        return newton_max_it(self.opts.max_it, across)

    def contact_nodes(self) -> int:
        """Contact nodes in contact at the current u (:meth:`in_contact`; all ranks)."""
        n = len(self._weights)
        dofs = np.flatnonzero(self._weights > 0)
        bs = self.form.contact.u.function_space.dofmap.index_map_bs
        local = int(np.count_nonzero(self.in_contact(dofs[dofs % bs == 0]))) if n else 0
        return self.comm.allreduce(local, op=MPI.SUM)

    # --- the solve -----------------------------------------------------------------------
    def solve(self, x: PETSc.Vec) -> Outcome:
        """Solve from x (Dirichlet values in place) into x."""
        opts, snes, prefix = self.opts, self.snes, self.prefix
        popts = PETSc.Options()
        for key, val in self.petsc_options.items():
            popts.setValue(prefix + key, petsc_value(val))
        # auto: plain Newton steps without friction (backtracking cut the penalty's active-set
        # steps short: 100 steps against 7 on the stability map's square), backtracking with
        # friction (plain steps cycled between slip directions on the Tresca manufactured
        # solution: penalty 6 steps with bt, none without)
        frictional = self.form.contact.friction is not None
        auto = "bt" if frictional else "basic"
        line_search = {"auto": auto, "bt": "bt"}.get(opts.line_search, "basic")
        popts.setValue(prefix + "snes_linesearch_type", line_search)
        try:
            set_options_of(snes)
            F = x.duplicate()
            start = x.duplicate()
            start.set(0.0)
            for bc in self.form.contact.bcs:
                bc.set(start.array_w)
            self._residual(snes, start, F)
            scale = norm_inf(F)
            x.copy(start)
            self._set_iterate(x)
            start.destroy()
            F.destroy()
            self.atol = opts.atol * scale
            self._k_norm = 0.0
            total_its, krylov, outer = 0, 0, 0
            uzawa = self.form.method == "augmented_lagrangian"
            reason = 0
            max_it = self.max_it()
            for outer in range(1, (opts.uzawa_max_it if uzawa else 1) + 1):
                self._outer = outer
                snes.setTolerances(rtol=opts.rtol, atol=self.atol, stol=0.0, max_it=max_it)
                # after a multiplier update at least one Newton step: the update may leave
                # ‖F‖ below atol, and an inner solve that stops at once leaves u — and the
                # next update's change — as they were (Uzawa creeping by 0.1 % per outer
                # iteration on the fine Cattaneo–Mindlin mesh at r₀ = 1000)
                snes.setForceIteration(outer > 1)
                with Timer(self.timers, "solve"):
                    snes.solve(None, x)
                reason = snes.getConvergedReason()  # type: ignore[assignment]
                total_its += snes.getIterationNumber()
                krylov += snes.getLinearSolveIterations()
                if reason <= 0 or not uzawa:
                    break
                self._set_iterate(x)
                change, size, floor = self.form.update_multipliers()
                if change <= max(opts.uzawa_rtol * size, floor):
                    break
            else:
                reason = -5  # PETSc's SNES_DIVERGED_MAX_IT
            self._set_iterate(x)
            return Outcome(reason, total_its, outer, krylov, self.history, self.linear)
        finally:
            for key in self.petsc_options:
                popts.delValue(prefix + key)
            popts.delValue(prefix + "snes_linesearch_type")

    def close(self) -> None:
        self._owner.close()

    def __enter__(self) -> EnforcedNewton:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def solve_enforced(
    problem: DiscreteProblem,
    contact: UnilateralContact,
    options: SolverOptions,
    verbose: bool = False,
    timers: dict | None = None,
    clock: Stopwatch | None = None,
) -> Result:
    """Solve ``contact`` (its ``u`` is ``problem.u_h``, holding the initial guess) by
    ``options.method`` with its parameter and return the :class:`Result` of ``problem``'s
    outputs: λ_h the method's own nodal pressure (lumped, −∫ p d(φ_i) / w_i in the
    problem's unknowns), active the nodes in contact (:meth:`EnforcedNewton.in_contact`),
    the contact force its resultant."""
    method = options.method
    value = float(getattr(options, PARAMETERS[method]))
    timers = {"assembly": 0.0, "solve": 0.0} if timers is None else timers
    clock = Stopwatch() if clock is None else clock
    with Timer(timers, "assembly"):
        form = Formulation(contact, method, value, float(options.nitsche_theta))
    u = contact.u
    with EnforcedNewton(form, options, verbose, timers) as newton:
        x = u.x.petsc_vec.copy()
        try:
            outcome = newton.solve(x)
            active = newton.in_contact(problem.constraint.dofs)
            force = newton.nodal_force()
            r = problem.b.duplicate()
            problem.to_unknowns(force, r)
            force.destroy()
            xt = problem.b.duplicate()
            problem.to_unknowns(u.x.petsc_vec, xt)
            residual = r.array_r.copy()
            xa = xt.array_r.copy()
            r.destroy()
            xt.destroy()
        finally:
            x.destroy()
    friction = contact.friction.coefficient if contact.friction is not None else None
    return result_of(problem, residual, xa, active, outcome, options, timers, clock, friction)


def result_of(
    problem: DiscreteProblem,
    residual: np.ndarray,
    xa: np.ndarray,
    active: np.ndarray,
    outcome: Outcome,
    options: SolverOptions,
    timers: dict,
    clock: Stopwatch,
    coefficient: float | None = None,
) -> Result:
    """The :class:`Result` of a baseline solve on ``problem``: ``residual`` the nodal contact
    force and ``xa`` the solution in the problem's unknowns (owned), ``active`` the mask of
    the constrained DoFs in contact; ``coefficient`` Coulomb's F of the friction law (None:
    the problem's own, Tresca's threshold otherwise)."""
    lmbda, gap, active_fn = problem.outputs(xa, residual, active)
    close_timings(timers, clock)
    friction = None
    if problem.friction is not None:
        fs = problem.friction
        F = coefficient if coefficient is not None else fs.coefficient
        friction = friction_fields(problem, F, xa, residual, active)
    history = outcome.history
    comm = problem.V.mesh.comm
    result = Result(
        u_h=problem.u_h,
        lmbda_h=lmbda,
        gap=gap,
        active=active_fn,
        history=history,
        converged=outcome.reason > 0,
        reason=REASONS.get(outcome.reason, str(outcome.reason)),
        iterations=outcome.iterations,
        residual=history[-1]["residual"] if history else float("nan"),
        method=options.method,
        n_active=comm.allreduce(int(active.sum()), op=MPI.SUM),
        timings=timers,
        problem=problem,
        active_mask=active,
        options=options.model_dump(),
        contact_force=problem.contact_force(residual),
        linear=outcome.linear,
        krylov_iterations=outcome.krylov,
        contact_residual=residual,
        outer_iterations=outcome.outer,
        friction=friction,
    )
    result.figures = baseline_figures(result)
    return result


def penetration(result: Result) -> float:
    """The largest penetration max_i [d_i − g_i]₊ over the constrained nodes (all ranks;
    in the units of u)."""
    p = result.problem
    x = p.b.duplicate()
    p.to_unknowns(result.u_h.x.petsc_vec, x)
    local = max(0.0, float(np.max(-p.nodal_gap(x.array_r), initial=0.0)))
    x.destroy()
    return p.V.mesh.comm.allreduce(local, op=MPI.MAX)


def baseline_figures(result: Result) -> dict:
    """The figures of a baseline solve for its summary: the method's parameter (ε₀, r₀ or
    γ₀; θ for Nitsche), Uzawa's outer iterations (augmented Lagrangian) and the largest
    penetration (:func:`penetration`; collective)."""
    method, opts = result.method, result.options
    name = PARAMETERS[method]
    out: dict[str, Any] = {name: opts.get(name)}
    if method == "nitsche":
        out["nitsche_theta"] = opts.get("nitsche_theta")
    if method == "augmented_lagrangian":
        out["uzawa_iterations"] = result.outer_iterations
    out["penetration"] = penetration(result)
    return out


#: |λ_t| ≥ (1 − SLIP_RTOL) ρ counts as slip: the penalty's and the augmented Lagrangian's
#: regularized law has no exact stick, Nitsche's projection puts slipping nodes on the ball
SLIP_RTOL = 1e-8


def friction_fields(
    problem: DiscreteProblem,
    coefficient: float | None,
    x: np.ndarray,
    residual: np.ndarray,
    active: np.ndarray,
) -> dict:
    """The nodal friction results of a baseline solve, as the NCP methods report them
    (:func:`contact.solvers.friction.friction_fields`): λ_n, λ_t (n, m) = the method's
    nodal traction / w_i in the node's frame, ρ (Tresca's threshold, or F (−λ_n)), the
    slip increment s = x_t − x_t^prev, the status (separated, stick where |λ_t| <
    (1 − :data:`SLIP_RTOL`) ρ, else slip), the gap, w and the global-axes vectors.
    ``x``, ``residual``: the owned unknowns and nodal contact force (the problem's basis)."""
    from .friction import tangential_vector
    from .newton import SEPARATED, SLIP, STICK

    fs, con = problem.friction, problem.constraint
    assert fs is not None, "a frictional problem"
    lam_n = problem.multiplier(residual)
    lam_t = residual[fs.tangent] / con.w[:, None]
    if coefficient is not None:
        rho = coefficient * np.maximum(-lam_n, 0.0)
    else:
        rho = np.asarray(fs.threshold, dtype=float)
    slip = np.where(fs.free, x[fs.tangent] - fs.x_prev, 0.0)
    size = np.linalg.norm(np.where(fs.free, lam_t, 0.0), axis=1)
    status = np.where(
        ~active, SEPARATED, np.where(size < (1.0 - SLIP_RTOL) * rho, STICK, SLIP)
    ).astype(np.int8)
    return {
        "lambda_n": lam_n,
        "lambda_t": lam_t,
        "rho": rho,
        "slip": slip,
        "status": status,
        "gap": problem.nodal_gap(x),
        "lambda_t_vec": tangential_vector(fs, lam_t),
        "slip_vec": tangential_vector(fs, slip),
        "w": con.w,
    }
