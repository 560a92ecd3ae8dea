"""How one solve runs, chosen once from the problem's parts and the options
(:func:`choose`) — what :class:`~contact.solvers.snes.SemismoothNewton` sets up and owns.

* the complementarity rows (:func:`complementarity`): the diagonal law of a bound
  (:class:`~.newton.Complementarity`), friction's block law
  (:class:`~.friction.FrictionalComplementarity`) or contact on the current configuration
  (:class:`~.current.CurrentComplementarity`, with or without friction);
* the Newton method (a :class:`Strategy`): semismooth Newton on the diagonal law
  (:class:`DiagonalNewton`: the Newton system of :mod:`.linear` — assembled, reduced CG + GAMG,
  or the energy search's system: factorized (:mod:`.curvature`) or CG + GAMG with an
  indefiniteness test (:mod:`.krylov_curvature`) — and the line-search
  pre-check: active-set polishing, min's cycle guard or the energy search), on a block law
  (:class:`BlockNewton`: H = B K + D assembled, or the reduced block system of
  :mod:`.block_system`), or one of PETSc's VI solvers (:class:`PetscVI`);
* the linear solver's kind (:meth:`Strategy.linear_kind`) and its default PETSc options.

Each strategy owns the objects it creates (through the solver's
:class:`~contact.base.lifetime.Owner`); the problem stays the caller's.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..base.lifetime import Owner
from ..base.timing import Timer
from . import ncp
from .curvature import CURVATURE_PETSC_OPTIONS, CurvatureSystem
from .energy_search import EnergySearch
from .globalize import Guarded, GuardedMin
from .krylov_curvature import KrylovCurvatureSystem
from .linear import (
    AssembledSystem,
    ReducedNewtonSystem,
    assembled_kind,
    attach_near_nullspace,
    choose_linear,
    friction_kind,
    newton_system,
    petsc_defaults,
)
from .newton import BlockComplementarity, Complementarity
from .options import SolverOptions
from .polish import Polisher
from .problem import DiscreteProblem
from .reduced import ReducedSystem
from .vi import setup_vi

if TYPE_CHECKING:
    from .block_system import BlockReducedSystem


def complementarity(problem: DiscreteProblem) -> Complementarity:
    """The complementarity rows of the problem's parts: contact on the current configuration
    (:mod:`.current`; friction's rows in its frames, if any), a friction law (:mod:`.friction`),
    or the diagonal law of a bound.  Only a problem with such a part loads its module."""
    if problem.current is not None:
        from .current import CurrentComplementarity

        return CurrentComplementarity(problem)
    if problem.friction is not None:
        from .friction import FrictionalComplementarity

        return FrictionalComplementarity(problem)
    return Complementarity(problem)


class Strategy:
    """One way of running the solve: which linear solver, which Newton system, which
    pre-check.  :meth:`configure` sets the SNES up and leaves ``system`` (the Newton system
    with a KSP of its own, if any), ``J`` (the Jacobian matrix) and the pre-check objects
    (``polisher``, ``guard``, ``search``) for the solver to read."""

    system: ReducedNewtonSystem | BlockReducedSystem | AssembledSystem | None = None
    polisher: Polisher | None = None
    guard: Guarded | None = None
    search: EnergySearch | None = None
    J: PETSc.Mat

    def __init__(self, problem: DiscreteProblem, cp: Complementarity, options: SolverOptions):
        self.problem, self.cp, self.options = problem, cp, options

    @staticmethod
    def linear_kind(problem: DiscreteProblem, options: SolverOptions, user: dict) -> str:
        """The kind of linear solver (``direct``, ``gamg``, ``bcgs``, ``gmres``)."""
        return assembled_kind(problem, options.linear, user)

    @staticmethod
    def defaults(problem: DiscreteProblem, options: SolverOptions, linear: str) -> dict:
        """The default PETSc options of the linear solver ``linear``."""
        return petsc_defaults(problem, linear)

    def configure(
        self,
        snes: PETSc.SNES,
        owner: Owner,
        prefix: str,
        linear: str,
        timers: dict,
        state: dict,
        petsc_options: dict,
        verbose: bool,
    ) -> None:
        raise NotImplementedError

    def newton(
        self,
        snes: PETSc.SNES,
        J: PETSc.Mat,
        jacobian: Callable[[PETSc.Vec, PETSc.Mat], None],
        timers: dict,
        state: dict,
        petsc_options: dict,
    ) -> None:
        """Make ``snes`` Newton on the Φ of the strategy's rows (:func:`set_newton`)."""
        opts, cp = self.options, self.cp
        set_newton(
            snes,
            self.problem,
            J,
            lambda x, f: cp.phi(x, f, opts.method, opts.mu),
            jacobian,
            opts,
            timers,
            state,
            petsc_options,
        )

    @property
    def inner_ksp(self) -> PETSc.KSP | None:
        """The KSP of a Newton system that solves on its own (None: SNES's)."""
        return self.system.ksp if isinstance(self.system, ReducedSystem) else None


class DiagonalNewton(Strategy):
    """Semismooth Newton on Φ of fb / min / blend with the diagonal law H = diag(s) K + diag(d)
    (:mod:`.newton`): the Newton system of :mod:`.linear` (or, with the energy line search,
    the factorized system of :mod:`.curvature` or CG + GAMG of :mod:`.krylov_curvature`),
    and as the line search's pre-check active-set polishing (fb / blend with ``polish``),
    min's cycle guard (line search ``auto``) or the energy search (:mod:`.energy_search`,
    polishing inside it)."""

    @staticmethod
    def linear_kind(problem: DiscreteProblem, options: SolverOptions, user: dict) -> str:
        if options.line_search == "energy":  # LDLᵀ and its inertia, or CG + GAMG and its test
            return energy_linear(problem, options, user) or "direct"
        if problem.nonlinear:  # K = K_T(x) changes: an assembled matrix
            return assembled_kind(problem, options.linear, user)
        return choose_linear(problem, options.linear, user)

    @staticmethod
    def defaults(problem: DiscreteProblem, options: SolverOptions, linear: str) -> dict:
        if options.line_search == "energy" and linear == "direct":
            return dict(CURVATURE_PETSC_OPTIONS)
        return petsc_defaults(problem, linear)

    def configure(self, snes, owner, prefix, linear, timers, state, petsc_options, verbose):
        problem, cp, opts = self.problem, self.cp, self.options
        energy = opts.line_search == "energy"
        system = self.system = owner.own(
            (
                CurvatureSystem(problem, prefix)
                if linear == "direct"
                else KrylovCurvatureSystem(problem, prefix, forcing=opts.inexact)
            )
            if energy
            else newton_system(problem, linear, prefix, forcing=opts.inexact)
        )
        if isinstance(system, ReducedNewtonSystem) and not energy:
            system.policy = opts.forcing  # the forcing rule of the Krylov tolerances
        # a system with a KSP of its own: SNES's KSP gets another prefix (the options
        # of ``prefix`` are the inner KSP's)
        inner = prefix + "newton_" if isinstance(system, ReducedSystem) else prefix
        system.configure(snes, inner)
        method, mu = opts.method, opts.mu

        def jacobian(x: PETSc.Vec, P: PETSc.Mat) -> None:
            cp.p.linearize(x)
            a, b, _ = cp.pair(x)
            system.set_law(*cp.law(a, b, method, mu))

        self.newton(snes, system.J, jacobian, timers, state, petsc_options)
        polisher = (
            Polisher(cp, method, mu, system, timers) if opts.polish and method != "min" else None
        )
        precheck: Polisher | GuardedMin | EnergySearch | None = None
        if energy:  # polishing first, then the energy's line search
            precheck = self.search = EnergySearch(
                cp, method, mu, system, timers, body_size(problem), polisher
            )
        elif polisher is not None:
            precheck = polisher
        elif method == "min" and opts.line_search == "auto":
            precheck = self.guard = GuardedMin(cp, mu, timers, verbose)
        self.polisher = polisher
        if precheck is not None:
            snes.setLineSearchPreCheck(precheck)
            owner.own(precheck)
        self.J = system.J


class BlockNewton(Strategy):
    """Semismooth Newton on Φ of a block law H = B K + D (friction, :mod:`.friction`; contact
    on the current configuration, :mod:`.current`): ``cp.matrix()`` a matrix of the pattern of
    B K, ``cp.block_jacobian(x, H, method, mu)`` the element at x; plain Newton or ``bt``, no
    polishing (a friction law with line search ``auto``: the cycle guard of
    :class:`~.friction.GuardedFriction`).  With ``gmres`` the reduced block system of
    :mod:`.block_system` solves with GMRES + GAMG from each Jacobian's blocks."""

    @staticmethod
    def linear_kind(problem: DiscreteProblem, options: SolverOptions, user: dict) -> str:
        if problem.friction is not None:
            return friction_kind(problem, options.linear, user)
        return assembled_kind(problem, options.linear, user)

    def configure(self, snes, owner, prefix, linear, timers, state, petsc_options, verbose):
        problem, opts = self.problem, self.options
        cp = self.cp
        assert isinstance(cp, BlockComplementarity)  # friction's or .current's
        method, mu = opts.method, opts.mu
        if linear == "gmres":  # reduced, GMRES + GAMG (.block_system)
            from .block_system import BlockReducedSystem

            block = owner.own(
                BlockReducedSystem(problem, cp.matrix(), prefix, forcing=opts.inexact)
            )
            block.configure(snes, prefix + "newton_")
            self.system, J = block, block.J

            def jacobian(x: PETSc.Vec, P: PETSc.Mat) -> None:
                block.set_block(*cp.block_jacobian(x, P, method, mu))

        else:
            J = owner.own(cp.matrix())
            attach_near_nullspace(problem, J)

            def jacobian(x: PETSc.Vec, P: PETSc.Mat) -> None:
                cp.block_jacobian(x, P, method, mu)

        self.newton(snes, J, jacobian, timers, state, petsc_options)
        self.J = J
        if problem.friction is not None and opts.line_search == "auto":
            from .friction import GuardedFriction

            self.guard = owner.own(GuardedFriction(cp, method, mu, timers, verbose))
            snes.setLineSearchPreCheck(self.guard)


class PetscVI(Strategy):
    """PETSc's VI solvers (vinewtonrsls / vinewtonssls) on R(x) = K x − b with the bound as
    box constraints (:mod:`.vi`): the baselines."""

    def configure(self, snes, owner, prefix, linear, timers, state, petsc_options, verbose):
        self.J = owner.own(setup_vi(snes, self.problem, self.options.method, timers, state))


def choose(problem: DiscreteProblem, options: SolverOptions) -> type[Strategy]:
    """The strategy of the problem's parts and the options: PETSc's VI solvers for their
    methods, a block law where the problem has friction or contact on the current
    configuration, the diagonal law otherwise."""
    if options.method not in ncp.METHODS:
        return PetscVI
    if problem.friction is not None or problem.current is not None:
        return BlockNewton
    return DiagonalNewton


def energy_linear(problem: DiscreteProblem, options: SolverOptions, user: dict) -> str | None:
    """The Newton system of the energy search: ``direct`` (LDLᵀ and its inertia,
    :mod:`.curvature`) where the assembled path would factorize, ``gamg`` (CG + GAMG and
    an indefiniteness test, :mod:`.krylov_curvature`) where it would not — 3D elasticity by
    default, or ``solver.linear: gamg`` —, None for an explicit ``bcgs`` / ``gmres``
    (BiCGStab / GMRES on the assembled H, plain Newton; also ``hp_patch``, whose problems
    have no energy search)."""
    if options.linear == "hp_patch":
        return None
    kind = assembled_kind(problem, options.linear, user)
    if kind == "direct":
        return "direct"
    if options.linear == "gamg" or (options.linear == "auto" and kind == "bcgs"):
        return "gamg"
    return None


def body_size(problem: DiscreteProblem) -> float:
    """The diagonal of the mesh's bounding box (collective): the length scale of the energy
    search's curvature steps."""
    X = problem.V.mesh.geometry.x
    comm = problem.V.mesh.comm
    lo = np.min(X, axis=0, initial=np.inf)
    hi = np.max(X, axis=0, initial=-np.inf)
    comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    return float(np.linalg.norm(hi - lo))


def set_newton(
    snes: PETSc.SNES,
    problem: DiscreteProblem,
    J: PETSc.Mat,
    phi: Callable[[PETSc.Vec, PETSc.Vec], Any],
    jacobian: Callable[[PETSc.Vec, PETSc.Mat], None],
    opts: SolverOptions,
    timers: dict,
    state: dict,
    petsc_opts: dict,
) -> None:
    """Make ``snes`` PETSc's ``newtonls`` on Φ: ``phi(x, f)`` writes Φ(x) into f and
    ``jacobian(x, P)`` an element of its generalized Jacobian into P (the matrix J).  Time in
    both is added to ``timers['assembly']``; ``state['t_jac']`` is the linear solve's Timer
    (``timers['solve']``), started at the end of the Jacobian.  PETSc's line search
    ``opts.line_search`` (``auto``: ``basic``, the cycle guard being a pre-check) unless the
    PETSc options say otherwise."""

    def residual(snes, x, f):
        with Timer(timers, "assembly"):
            phi(x, f)

    def jac(snes, x, J_, P):
        with Timer(timers, "assembly"):
            jacobian(x, P)
        state["t_jac"] = Timer(timers, "solve").start()  # stopped after the linear solve

    snes.setType("newtonls")
    snes.setFunction(residual, problem.b.duplicate())
    snes.setJacobian(jac, J)
    # auto's cycle guard and the energy search are pre-checks of PETSc's basic line search
    line_search = "basic" if opts.line_search in ("auto", "energy") else opts.line_search
    petsc_opts.setdefault("snes_linesearch_type", line_search)
