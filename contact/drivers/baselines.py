"""One solve of a scene by a baseline enforcement — penalty, augmented Lagrangian (Uzawa)
or Nitsche (:mod:`contact.solvers.baselines`, docs/theory.md §10): the scene's constraint as
UFL (:func:`contact.models.baselines.unilateral_contact`), the solve from the initial guess
the scene's driver chose, and the :class:`~contact.solvers.result.Result` on the scene's
discrete problem, so that every output of a scene (fields, tables, forces, estimators)
reads it as it reads an NCP method's."""

from __future__ import annotations

from dolfinx import fem

from ..base.lifetime import destroy
from ..base.timing import Stopwatch
from ..models.baselines import unilateral_contact
from ..setup.scene import Scene
from ..solvers.baselines import solve_enforced
from ..solvers.options import SolverOptions
from ..solvers.problem import DiscreteProblem
from ..solvers.result import Result


def solve_baseline(
    scene: Scene,
    problem: DiscreteProblem,
    u0: fem.Function,
    opts: SolverOptions,
    verbose: bool,
    timers: dict,
    clock: Stopwatch,
) -> Result:
    """Solve ``scene`` by ``opts.method`` from ``u0`` (a function of ``problem.V``; the
    Dirichlet values are put in); never raises on divergence."""
    u = problem.u_h
    u.x.array[:] = u0.x.array
    for bc in problem.bcs:
        bc.set(u.x.array)
    u.x.scatter_forward()
    contact, made = unilateral_contact(scene, problem)
    try:
        return solve_enforced(problem, contact, opts, verbose, timers, clock)
    finally:
        destroy(*made)
