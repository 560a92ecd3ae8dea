"""One solve of a discrete problem from an initial guess: the NCP scaling, a PETSc SNES
(semismooth Newton on an NCP function, or one of PETSc's VI solvers) with a monitor that
records the history, and the :class:`~contact.solvers.result.Result`.  The scene's part of
a solve (its problem, options and initial guess) is :func:`contact.drivers.solve.solve`."""

from __future__ import annotations

import itertools
import time
from typing import Any

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base import progress
from ..base.lifetime import Owner
from . import ncp
from .globalize import GuardedMin
from .linear import assembled_kind, choose_linear, newton_system, petsc_defaults
from .newton import Complementarity, setup_newton
from .options import check_petsc_options, petsc_value, set_from_options
from .polish import Polisher
from .problem import DiscreteProblem, nodal_scaling
from .reduced import ReducedSystem
from .result import Result, finish
from .vi import setup_vi

_counter = itertools.count()


def solve_problem(
    problem: DiscreteProblem,
    u0: fem.Function,
    opts: dict,
    comm: MPI.Comm,
    verbose: bool,
    guess: bool,
    timers: dict,
    t_start: float,
    check_options: bool = False,
) -> Result:
    """Solve ``problem`` from ``u0`` (a function of ``problem.V`` holding the Dirichlet values;
    ``guess``: a real initial guess, given or from coarser levels, not a cold start) with
    the validated ``solver`` options ``opts``; return a :class:`Result` (never raises on
    divergence).  ``timers`` holds the seconds counted so far (``assembly``, ``solve``,
    ``coarse``), ``t_start`` the start of the whole solve; ``check_options``: the PETSc
    options were given for this solve and are checked first (a scene's were checked
    when it was loaded)."""
    method = opts["method"]
    friction = problem.friction
    if friction is not None:
        from .friction import (
            FrictionalComplementarity,
            friction_fields,
            setup_friction_newton,
            status_counts,
        )

    con = problem.constraint  # the NCP scaling follows the options of this solve
    problem.c = (
        nodal_scaling(problem.K, con.dofs, con.w, opts["kappa"])
        if opts["c"] == "auto"
        else float(opts["c"])
    )
    user = {str(k): v for k, v in opts["petsc_options"].items()}
    # friction's block law and the VI baselines keep an assembled matrix (their own linear algebra)
    diagonal_law = friction is None and method in ncp.METHODS
    linear = (choose_linear if diagonal_law else assembled_kind)(problem, opts["linear"], user)
    defaults = petsc_defaults(problem, linear)
    petsc_opts = {**defaults, **user}
    if check_options:
        check_petsc_options(opts["petsc_options"], defaults, comm)

    owner = Owner()  # this solve's PETSc objects, destroyed when it is done
    x = owner.own(problem.b.duplicate())
    problem.to_unknowns(u0.x.petsc_vec, x)
    set_dirichlet(x, problem.bcs)
    cp = owner.own((Complementarity if friction is None else FrictionalComplementarity)(problem))
    # solver.atol is relative to the data's force scale (force_scale), rtol to ‖Φ(x_0)‖
    atol = opts["atol"] * force_scale(
        cp, problem, method if method in ncp.METHODS else "fb", opts["mu"]
    )
    snes = owner.own(PETSc.SNES().create(comm))
    prefix = f"contact{next(_counter)}_"
    snes.setOptionsPrefix(prefix)
    state = {"t_jac": None, "dir_norm": np.nan}
    polisher, guard, system = None, None, None
    if friction is not None:  # the block law H = B K + D (no polishing)
        owner.own(setup_friction_newton(snes, problem, cp, opts, timers, state, petsc_opts))
    elif method in ncp.METHODS:
        system = owner.own(newton_system(problem, linear, prefix, forcing=opts["inexact"]))
        system.configure(snes, prefix + "newton_" if linear == "gamg" else prefix)
        precheck = owner.own(
            setup_newton(snes, cp, system, opts, timers, state, petsc_opts, verbose)
        )
        polisher = precheck if isinstance(precheck, Polisher) else None
        guard = precheck if isinstance(precheck, GuardedMin) else None
    else:
        owner.own(setup_vi(snes, problem, method, timers, state))

    def post_solve(ksp, rhs, sol):
        if system is not None:
            system.count(ksp)
        if state["t_jac"] is not None:
            timers["solve"] += time.perf_counter() - state["t_jac"]
            state["t_jac"] = None
        state["dir_norm"] = sol.norm()

    snes.getKSP().setPostSolve(post_solve)
    snes.setTolerances(rtol=opts["rtol"], atol=atol, stol=0.0, max_it=opts["max_it"])
    # semismooth Newton may raise ‖Φ‖ on its way: no dtol stop
    snes.setDivergenceTolerance(PETSc.UNLIMITED)
    history: list[dict] = []
    prev = {"x": owner.own(x.duplicate()), "active": None}

    def monitor(snes, its, fnorm):
        xk = snes.getSolution()
        active = cp.active(xk)
        n_active = comm.allreduce(int(active.sum()), op=MPI.SUM)
        changed = (
            0
            if prev["active"] is None
            else comm.allreduce(int((active != prev["active"]).sum()), op=MPI.SUM)
        )
        step = np.nan
        if its > 0:
            prev["x"].axpy(-1.0, xk)
            polished = polisher is not None and polisher.taken is not None
            dn = polisher.taken if polished else state["dir_norm"]  # the direction actually taken
            step = prev["x"].norm() / dn if dn > 0 else 0.0
        else:  # SNES's stopping test, newtonls: ‖Φ‖ ≤ max(atol, rtol ‖Φ_0‖)
            done = state.get("stop") or max(atol, opts["rtol"] * fnorm)
            if polisher is not None:
                polisher.done = done
            if system is not None:
                system.stop = done
        xk.copy(prev["x"])
        prev["active"] = active
        polished = polisher is not None and (
            polisher.accepted if its > 0 else polisher.initial_accepted
        )
        row = {
            "iteration": its,
            "residual": float(fnorm),
            "step": float(step),
            "active": n_active,
            "changed": changed,
            "polished": polished,
        }
        extra = ""
        if friction is not None:
            counts = status_counts(comm, cp.status(xk))
            row.update(stick=counts["stick"], slip=counts["slip"])
            extra = f"  stick {counts['stick']:6d}  slip {counts['slip']:6d}"
        history.append(row)
        if verbose and comm.rank == 0:
            st = "    -" if its == 0 else f"{step:5.2f}"
            print(
                f"  {method:>12s} it {its:3d}  |Phi| = {fnorm:10.3e}  step {st}  "
                f"active {n_active:7d}  changed "
                f"{changed:6d}{extra}{'  polished' if row['polished'] else ''}",
                flush=True,
            )
            progress.heard()
        else:
            progress.note(lambda: f"{method} Newton iteration {its}, |Phi| = {fnorm:.3e}")

    snes.setMonitor(monitor)
    progress.watch(
        system.ksp if isinstance(system, ReducedSystem) else snes.getKSP(), f"{method} linear solve"
    )
    popts = PETSc.Options()
    try:  # the options stay until the solve is done: some are read at set-up (GAMG's
        # mg_levels_*, MUMPS's mat_mumps_*), which happens in the first linear solve
        for key, val in petsc_opts.items():
            popts[prefix + key] = petsc_value(val)
        set_from_options(snes, *([system.ksp] if isinstance(system, ReducedSystem) else []))
        if system is not None:
            system.set_options()
        if isinstance(system, ReducedSystem):
            # the first Newton step from a guess is exact — unless the guess is polished
            # first: that exact solve on the guess's active set is then done, and a Newton
            # step still needed means the active set moves, where a loose step does as well
            system.guess = guess and polisher is None
        if polisher is not None and guess:
            # polish the guess first; SNES's relative tolerance still refers to the guess's ‖Φ‖
            stop = max(atol, opts["rtol"] * cp_norm(cp, x, method, opts["mu"]))
            polisher.initial(x, stop)
            state["stop"] = stop
            snes.setTolerances(rtol=0.0, atol=stop, stol=0.0, max_it=opts["max_it"])
        snes.solve(None, x)
        reason_code = snes.getConvergedReason()
        result = finish(
            comm, problem, cp, x, snes, history, method, opts, timers, t_start, reason_code
        )
        result.linear = linear
        if friction is not None:
            result.friction = friction_fields(problem, cp, x)
        if polisher is not None:
            result.polish_solves = polisher.solves
        if guard is not None:
            result.backtracked = guard.backtracked
        if system is not None:
            result.krylov_iterations = system.krylov_iterations
            result.krylov_log = getattr(system, "log", [])
        else:
            result.krylov_iterations = snes.getLinearSolveIterations()
    finally:
        for key in petsc_opts:
            popts.delValue(prefix + key)
        owner.close()
    return result


def cp_norm(cp: Complementarity, x: PETSc.Vec, method: str, mu: float) -> float:
    """‖Φ(x)‖."""
    f = x.duplicate()
    cp.phi(x, f, method, mu)
    out = f.norm()
    f.destroy()
    return out


def force_scale(cp: Complementarity, problem: DiscreteProblem, method: str, mu: float) -> float:
    """F = ‖Φ(x_D)‖_∞, the largest entry of the residual at the start x_D that holds the
    Dirichlet values and zero elsewhere: the largest nodal force of the scene's loads,
    prescribed displacements and gaps (the units of Φ, :mod:`.newton`; the maximum does not
    overflow where the 2-norm of huge data would).  ``solver.atol`` is relative to it, a
    tolerance of atol · F on ‖Φ‖, so that a scene may be written in any units: with an
    absolute 1e-12, E = 1e-12 made ‖Φ_0‖ = 8e-14 "converged" before the first step."""
    x, f = problem.b.duplicate(), problem.b.duplicate()
    x.set(0.0)
    set_dirichlet(x, problem.bcs)
    cp.phi(x, f, method, mu)
    out = f.norm(PETSc.NormType.INFINITY)
    x.destroy()
    f.destroy()
    return out


def check_guess(u0: Any, problem: DiscreteProblem) -> None:
    """An initial guess must be a function in the problem's space (same mesh object,
    element and layout); else one ValueError line on every rank."""
    V = problem.V
    if not isinstance(u0, fem.Function):
        raise ValueError(
            f"u0: expected a dolfinx.fem.Function on the scene's mesh, got {type(u0).__name__}"
        )
    W = u0.function_space
    local = (
        W.mesh is not V.mesh
        or W.ufl_element() != V.ufl_element()
        or W.dofmap.index_map.size_local * W.dofmap.index_map_bs
        != V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    )
    if V.mesh.comm.allreduce(bool(local), op=MPI.LOR):
        where = "another mesh" if W.mesh is not V.mesh else "another function space"
        raise ValueError(
            f"u0: lives on {where} than the scene's problem; interpolate it first "
            "(contact.refine returns the guess on the refined mesh)"
        )


def set_dirichlet(x: PETSc.Vec, bcs: list) -> None:
    """Insert Dirichlet values into the owned entries of x."""
    for bc in bcs:
        bc.set(x.array_w)
