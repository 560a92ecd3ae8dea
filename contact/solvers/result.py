"""The outcome of one solve: :class:`Result`.

:func:`finish` builds it from the final iterate: u_h, the multiplier λ_h, the gap, the
active set, the iteration history.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base.timing import Stopwatch
from .problem import DiscreteProblem
from .stopping import AdaptiveStopping

#: the functions of a result that :meth:`Result.stow` keeps the values of, u_h first
STOWED = ("u_h", "lmbda_h", "gap", "active")
#: the names of the output functions among them (``DiscreteProblem.outputs``)
OUTPUT_NAMES = ("lambda_h", "gap", "active")
REASONS = {v: k.lower() for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}


@dataclass
class Result:
    """The outcome of one solve (:func:`contact.solve`, ``ComplementarityProblem.solve``).

    A solve that did not converge returns a Result too (``converged`` false, ``reason``
    says why); nothing raises on divergence. Every number is global (the same on every
    rank); the functions' arrays hold a rank's own part.

    Attributes:
        u_h: The solution (displacement, or the scalar u).
        lmbda_h: The multiplier λ_i at the constrained DoFs, 0 elsewhere: the contact
            pressure or flux density (force per length in 2D, per area in 3D; λ_n ≤ 0 is
            a pressure for elasticity).
        gap: σ(g − u_h) at the constrained DoFs of Γ_C, NaN elsewhere (obstacle scenes:
            ψ − u_h everywhere).
        active: 1 at the active constrained DoFs, 0 elsewhere.
        history: One dict per Newton iteration: residual ‖Φ‖, step length, active-set size,
            status changes, polishing.
        converged: Whether the solver met its tolerance.
        reason: PETSc's converged or diverged reason, lower case (``converged_fnorm_abs``,
            ``diverged_max_it``, …).
        iterations: Newton iterations on the final mesh.
        residual: The last ‖Φ‖ (a force, in the units of K x − b).
        method: The method solved with (fb, min, blend, vinewtonrsls, vinewtonssls).
        n_active: The number of active constrained DoFs, summed over the ranks.
        timings: Seconds spent in ``assembly``, ``solve``, ``other`` and ``total``.
        problem: The discrete problem solved (released by :meth:`release`).
        active_mask: The active ones among the constraint's owned DoFs, by the solver's
            rule at the solution (b_i − a_i > τ, or both within τ of 0).
        polish_solves: Active-set polishing solves besides the Newton steps.
        contact_force: The resultant contact force summed over all ranks (elasticity: of
            the whole body, symmetric copies counted).
        friction: Frictional scenes: the nodal λ_n, λ_t, ρ, slip and status (0 separated,
            1 stick, 2 slip); ``None`` otherwise.
        linear: The linear solver used (direct, gamg, bcgs, gmres).
        krylov_iterations: Krylov iterations of all linear solves (0 for a direct solver).
        max_it: The Newton step limit of the solve (``solver.max_it``; for ``auto`` and fb,
            min or blend its floor of 50 unless the solve went that far, then the limit by
            the mesh).
        sequence: The coarse levels of grid sequencing, coarsest first.
        predictor: A load step's secant predictor: ``None`` (none offered), ``True`` (it
            started the solve) or ``False`` (the previous step's solution did).
        hint: For a failed solve, what in the scene makes it hard ("" if nothing known).
        figures: The method's own figures for the run's summary, measured at the solution
            (a baseline's parameter, Uzawa's outer iterations and the largest penetration,
            ``contact.solvers.baselines.baseline_figures``); empty for the NCP methods.
        first_contact: The first point of contact (gdim coordinates): of the constrained
            nodes, the one with the smallest initial gap σg, ties broken in coordinate order
            (``contact.models.problem.first_contact_point``; the same on any number of
            ranks); with pairs coupled on the current configuration, of the nodes that touch
            (the smallest current gap) the one of smallest bound
            (``DiscreteProblem.contact_gaps``); None when no
            solve filled it in or no node is constrained.
        interface_forces: With mortar pairs, (F_s, F_m): the forces on the pairs' slave and
            master surfaces, Σ of the residual a(u_h, v) − L(v) over their nodes, the
            Dirichlet DoFs left out (``contact.models.mortar.interface_forces``; of the
            modelled part, the symmetric copies not counted); None otherwise, and for a
            problem without a reaction form (``ProblemData.reaction_form``: a scene's).
    """

    u_h: fem.Function
    lmbda_h: fem.Function
    gap: fem.Function
    active: fem.Function
    history: list[dict]
    converged: bool
    reason: str
    iterations: int
    residual: float
    method: str
    n_active: int
    timings: dict
    problem: DiscreteProblem
    active_mask: np.ndarray
    options: dict = field(default_factory=dict)  # the solve's SolverOptions as a dict
    polish_solves: int = 0
    backtracked: int = 0  # min, line search auto: steps shortened once a cycle showed
    # line search energy: the Newton steps whose tangent was not definite or that were
    # shortened (iteration, negative, shift, t, merit, curvature, along; .energy_search)
    tangent_log: list = field(default_factory=list)
    # solver.predictor: whether the solve started from the tangent predictor's point (None:
    # no predictor; False: it was not admissible, the plain start was taken; .predictor)
    predicted: bool | None = None
    linear: str = ""  # the linear solver used (direct, gamg, bcgs)
    krylov_iterations: int = 0  # Krylov iterations of all linear solves (0 for direct)
    max_it: int = 0  # the Newton step limit the solve had (solver.max_it, auto resolved)
    krylov_log: list = field(default_factory=list)  # gamg: rtol, iterations, seconds of each solve
    sequence: list = field(default_factory=list)  # coarse levels of grid sequencing (CoarseLevel)
    sequence_note: str = ""  # why there are fewer coarse levels than asked, or none
    contact_force: float = 0.0
    friction: dict | None = (
        None  # frictional scenes: nodal λ_n, λ_t, ρ, slip, status (solvers.friction)
    )
    # a load path's predictor: None (none offered), True (it started the solve: a smaller ‖Φ‖
    # than the previous step's solution), False (the previous step's solution did)
    predictor: bool | None = None
    hint: str = ""  # a failed solve: what in the scene makes it hard ('' if nothing known)
    stopping: AdaptiveStopping | None = None  # solver.stopping adaptive: its criteria (.stopping)
    #: a baseline enforcement (``contact.setup.baselines``): its nodal contact force in the solver's
    #: unknowns (owned), which ``owned_residual`` returns — the method's own multiplier,
    #: not the Galerkin residual K x − b (they differ for Nitsche with θ ≠ 0)
    contact_residual: np.ndarray | None = None
    outer_iterations: int = 0  # the augmented Lagrangian's Uzawa iterations (0: none)
    #: One row per coupling of the fixed point of mortar pairs at finite strain
    #: (``contact.drivers.recouple``); empty otherwise.
    couplings: list = field(default_factory=list)
    figures: dict = field(default_factory=dict)
    first_contact: np.ndarray | None = None
    interface_forces: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def linear_solves(self) -> int:
        """The linear systems solved, Newton steps plus active-set polishing solves."""
        return self.iterations + self.polish_solves

    @property
    def coarse_iterations(self) -> int:
        """Newton iterations on the coarse levels of grid sequencing (0 without).

        The work that let the final mesh's Newton (``iterations``) start from a near
        solution.
        """
        return sum(lv.newton_iterations for lv in self.sequence)

    @property
    def coarse_linear_solves(self) -> int:
        """Linear solves (Newton steps + polishing) on the coarse levels of grid sequencing."""
        return sum(lv.linear_solves for lv in self.sequence)

    @property
    def weighted_linear_solves(self) -> float:
        """All linear solves, each weighted by its level's DoFs / the fine DoFs."""
        return (
            self.linear_solves + sum(lv.linear_solves * lv.dofs for lv in self.sequence) / self.dofs
        )

    @functools.cached_property
    def dofs(self) -> int:
        """The number of degrees of freedom of u_h, over all ranks."""
        V = self.u_h.function_space
        return V.dofmap.index_map.size_global * V.dofmap.index_map_bs

    def shed_operator(self) -> None:
        """Destroy the problem's operator K, keeping what the result's files are made of.

        The result's nodal contact force, which the output reads as K x − b
        (``owned_residual``), is computed first and kept (``contact_residual``); the
        functions, the problem's forms, b and the change of basis stay, so the result can
        still be written, estimated and reported, but not solved on.  The adaptive loop does
        this to a level it will release once the next level is solved, before that solve,
        the loop's peak (:func:`contact.adapt`).  Collective.
        """
        K = None if self.problem is None else self.problem.K
        if K is None or not K.handle:
            return
        if self.contact_residual is None:
            self.contact_residual = owned_residual(self)
        K.destroy()

    def stow(self) -> dict[str, np.ndarray] | None:
        """Drop the problem and the functions, keeping their values to restore them from.

        The values of u_h, λ_h, the gap and the active set (each rank's part, ghosts
        included) are returned, and the problem's PETSc objects destroyed and the problem
        and functions dropped (None), after the nodal contact force K x − b is kept
        (:meth:`shed_operator`); the nodal arrays (``active_mask``, friction's fields) and
        every figure stay.  :meth:`restore` gives the functions back on the same problem
        built again on the same mesh: its DoF layout is the same, so the values are the
        same bit for bit.  Returns None, and changes nothing, unless u_h is the problem's
        and the other three live on its output space (what :meth:`restore` rebuilds).
        Collective.
        """
        p = self.problem
        if p is None or self.u_h is not p.u_h:
            return None
        S = p.output.space or p.V
        if any(
            getattr(self, attr).function_space is not S or getattr(self, attr).name != name
            for attr, name in zip(STOWED[1:], OUTPUT_NAMES, strict=True)
        ):
            return None
        self.shed_operator()
        _ = self.dofs  # cached while u_h is there
        values = {name: getattr(self, name).x.array.copy() for name in STOWED}
        p.destroy()
        self.u_h = self.lmbda_h = self.gap = self.active = None  # type: ignore[assignment]
        self.problem = None  # type: ignore[assignment]
        return values

    def restore(self, problem: DiscreteProblem, values: dict[str, np.ndarray]) -> None:
        """Give a stowed result (:meth:`stow`) its problem and functions back.

        ``problem`` is the stowed one built again on the same mesh (the same DoF layout);
        ``values`` what :meth:`stow` returned.  u_h is the problem's own function, λ_h, the
        gap and the active set new functions on its output space.
        """
        S = problem.output.space or problem.V
        functions = [problem.u_h] + [fem.Function(S, name=n) for n in OUTPUT_NAMES]
        for name, fn in zip(STOWED, functions, strict=True):
            if fn.x.array.shape != values[name].shape:
                raise RuntimeError(f"restoring {name}: the rebuilt problem's DoFs differ")
            fn.x.array[:] = values[name]
            setattr(self, name, fn)
        self.problem = problem

    def release(self) -> None:
        """Keep the figures only, and release the memory that grows with the mesh.

        The problem's PETSc objects are destroyed, the functions, the problem and the nodal
        arrays (``active_mask``, friction's fields) dropped (None; ``friction`` keeps its
        numbers). What stays — iterations, residual, history, timings, contact force, DoFs
        — takes no memory that grows with the mesh. A load path releases each step's result
        once the next step is done; a stowed result (:meth:`stow`) drops its nodal arrays.
        """
        if self.problem is not None:
            _ = self.dofs  # cached while u_h is there
            self.problem.destroy()
        # released (the doc above): these fields are None from here on
        self.u_h = self.lmbda_h = self.gap = self.active = None  # type: ignore[assignment]
        self.problem = self.active_mask = None  # type: ignore[assignment]
        self.contact_residual = None
        if self.friction is not None:
            self.friction = {k: v for k, v in self.friction.items() if np.ndim(v) == 0}


def not_converged_text(result: Result) -> str:
    """Return the message of a failed solve.

    'did not converge (reason) after n Newton iterations, last |Phi| = r' and the result's
    hint.
    """
    text = (
        f"did not converge ({result.reason}) after {result.iterations} Newton iterations, "
        f"last |Phi| = {result.residual:.3e}"
    )
    return f"{text} ({result.hint})" if result.hint else text


#: the hint of a failed solve on a semi-coercive scene (DiscreteProblem.semicoercive)
SEMICOERCIVE_HINT = (
    "no dirichlet boundary: K is singular while no contact node is active, as in a cold "
    "min or vinewtonrsls step; fb and blend avoid it"
)


def floating_hint(floating: list[tuple[str, int]]) -> str:
    """Return the hint of a failed solve with elastic bodies that no condition holds.

    ``floating`` is ``DiscreteProblem.floating`` (:mod:`contact.solvers.floating`).
    """
    name, free = floating[0]
    what = f"body {name}" if name else "the body"
    what += f" (and {len(floating) - 1} more)" if floating[1:] else ""
    return (
        f"{what}: no dirichlet or symmetry part holds it, {free} rigid motion(s) free: K is "
        "singular until contact holds it (frictionless contact never holds a sliding motion)"
    )


def not_unique_text(free: list[tuple[str, int]]) -> str:
    """Return the warning of a converged solve whose body only frictionless contact holds.

    ``free``: (body, free rigid motions) of :func:`contact.solvers.floating.free_in_contact`,
    the first named. The displacement is one of infinitely many — any sliding of the body
    along its free rigid motions solves the problem as well, and which copy the solver
    returned depends on the linear solver's null pivots, i.e. on rounding —, while its
    strains, stresses and contact forces are unique.
    """
    name, n = free[0]
    return (
        f"the displacement is not unique: {'body ' + name if name else 'the body'} keeps "
        f"{n} free rigid motion(s) with its contact nodes active (no dirichlet or symmetry "
        "part holds it, and frictionless contact never holds a sliding motion); the "
        "stresses and contact forces are unique, u_h is one of the solutions"
    )


def newton_text(result: Result) -> str:
    """Return the Newton iterations of a solve for one line.

    '5 Newton iterations (+1 polishing)', and after grid sequencing the final mesh's beside
    the coarse levels' total: '0 Newton iterations (+1 polishing) on the final mesh, 14 (+2)
    on 3 coarser meshes'.
    """
    polish = f" (+{result.polish_solves} polishing)" if result.polish_solves else ""
    text = f"{result.iterations} Newton iterations{polish}"
    if not result.sequence:
        return text
    coarse_polish = sum(lv.polish_solves for lv in result.sequence)
    n = len(result.sequence)
    coarse = f"{result.coarse_iterations}" + (f" (+{coarse_polish})" if coarse_polish else "")
    return f"{text} on the final mesh, {coarse} on {n} coarser mesh{'es' if n > 1 else ''}"


def solves_text(newton: int, polish: int) -> str:
    """'n' Newton iterations, or 'n+p' with p active-set polishing solves (tables, charts)."""
    return f"{newton}+{polish}" if polish else str(newton)


def owned_residual(result: Result) -> np.ndarray:
    """The nodal contact force at the solution, owned entries.

    R = K x − b (x = Qᵀ u_h, the solver's unknowns); for a baseline enforcement its own nodal
    contact force (``Result.contact_residual``) instead.
    """
    if result.contact_residual is not None:
        return result.contact_residual.copy()
    p = result.problem
    x, r = p.b.duplicate(), p.b.duplicate()
    p.to_unknowns(result.u_h.x.petsc_vec, x)
    p.residual(x, r)
    out = r.array_r.copy()
    x.destroy()
    r.destroy()
    return out


def close_timings(timers: dict, clock: Stopwatch) -> None:
    """Close a solve's timers.

    ``total``: the seconds of ``clock``; ``other``: what assembly, linear solves and coarse
    levels leave of it.
    """
    timers["total"] = clock.seconds
    timers["other"] = max(
        timers["total"] - timers["assembly"] - timers["solve"] - timers.get("coarse", 0.0), 0.0
    )


def finish(
    comm,
    problem,
    cp,
    x,
    snes,
    history,
    method,
    opts,
    timers,
    clock: Stopwatch,
    reason_code,
    inexact: bool = False,
) -> Result:
    """Copy the iterate into functions: u_h, and λ_h, the gap and the active set.

    Timings count on ``clock`` (started the assembly earlier when this solve built the
    problem). ``inexact``: the iterate keeps an algebraic residual (adaptive stopping), and
    λ_h is the complementarity law's, 0 off the active set, not the residual there (the
    algebraic residual on inactive rows is no contact force: in the bound's complementarity
    term it would weigh like a multiplier times the gap).
    """
    u_h = problem.u_h
    problem.to_displacement(x, u_h.x.petsc_vec)
    u_h.x.scatter_forward()
    a, b, r = cp.pair(x)
    active = cp.active_set(a, b)
    if inexact:
        r = r.copy()
        r[cp.dofs[~active]] = 0.0
    lmbda, gap, active_fn = problem.outputs(x.array_r, r, active)
    close_timings(timers, clock)
    converged = reason_code > 0
    hint = (
        ""
        if converged
        else SEMICOERCIVE_HINT
        if problem.semicoercive
        else (floating_hint(problem.floating) if problem.floating else "")
    )
    return Result(
        u_h=u_h,
        lmbda_h=lmbda,
        gap=gap,
        active=active_fn,
        history=history,
        converged=converged,
        reason=REASONS.get(reason_code, str(reason_code)),
        iterations=snes.getIterationNumber(),
        residual=history[-1]["residual"] if history else float("nan"),
        method=method,
        n_active=comm.allreduce(int(active.sum()), op=MPI.SUM),
        timings=timers,
        problem=problem,
        active_mask=active,
        options=opts.model_dump(),
        contact_force=problem.contact_force(r),
        hint=hint,
    )
