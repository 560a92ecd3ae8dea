"""``contact.solvers.snes.SemismoothNewton`` (issue 28c), in the spirit of dolfinx's
NonlinearProblem: it owns its SNES, options prefix and Newton system and destroys them; one
object solves again from another guess with per-solve figures; ``solve_problem`` is one
solve with one solver (the callers' path, unchanged)."""

from __future__ import annotations

import gc

import contact
from contact.base.lifetime import petsc_objects
from contact.base.timing import Stopwatch
from contact.setup.build import build_problem
from contact.solvers.options import SolverOptions
from contact.solvers.snes import SemismoothNewton, solve_problem

import numpy as np
import pytest
from clirun import ROOT
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

SCENE = str(ROOT / "configs" / "signorini_square.yaml")


@pytest.fixture(scope="module")
def problem():
    scene = contact.load_scene(SCENE, ["mesh.cells=[12,12]"])
    p = build_problem(scene)
    yield p
    p.destroy()


def largest(a: np.ndarray) -> float:
    return MPI.COMM_WORLD.allreduce(float(np.max(np.abs(a), initial=0.0)), op=MPI.MAX)


@pytest.mark.parametrize("method", ["fb", "min", "vinewtonrsls"])
def test_one_solver_solves_twice_as_two_fresh_ones(problem, method):
    """A second solve on the same object from the same cold start repeats the first one:
    iterations, history, polishing solves (counted per solve, not summed) and u_h."""
    options = SolverOptions.parse({"method": method, "kappa": 100.0})
    zero = fem.Function(problem.V)
    fresh = solve_problem(
        problem,
        zero,
        options,
        problem.V.mesh.comm,
        False,
        False,
        {"assembly": 0.0, "solve": 0.0},
        Stopwatch(),
    )
    u_fresh = fresh.u_h.x.array.copy()
    with SemismoothNewton(problem, options) as solver:
        first = solver.solve(zero)
        second = solver.solve(zero)
        u_second = second.u_h.x.array.copy()
    for r in (first, second):
        assert r.converged and r.iterations == fresh.iterations
        assert r.polish_solves == fresh.polish_solves and r.backtracked == fresh.backtracked
        assert [h["active"] for h in r.history] == [h["active"] for h in fresh.history]
    assert largest(u_second - u_fresh) < 1e-12


def test_close_destroys_what_the_solver_made(problem):
    """Every PETSc object the solver created is gone after close (the problem's stay), and
    its options prefix is its own."""
    PETSc.Log.begin()
    gc.collect()
    before = petsc_objects()
    solver = SemismoothNewton(problem, SolverOptions.parse({"method": "fb"}), prefix="mine_")
    assert solver.snes.getOptionsPrefix() == "mine_"
    result = solver.solve(fem.Function(problem.V))
    assert result.converged and solver.snes.handle != 0
    during = petsc_objects()
    assert sum(during.values()) > sum(before.values())
    solver.close()
    solver.close()  # twice is harmless
    del result
    gc.collect()
    after = petsc_objects()
    # only growth is the solver's: a class may also shrink, when objects of earlier tests in
    # this process (the vectors of spaces cached on their meshes, contact.base.spaces) become
    # garbage during this one and the collector frees them
    grown = {k: v - before.get(k, 0) for k, v in after.items() if v > before.get(k, 0)}
    assert not grown, grown
    assert problem.K.handle != 0 and problem.b.handle != 0


@pytest.mark.parametrize("method", ["fb", "min"])
def test_inexact_newton_starts_afresh_on_each_solve(method):
    """On the CG + GAMG path the forcing terms of inexact Newton build on the last step's
    ‖Φ‖ and η.  A second solve of the same object — a load path's next step — starts
    from nothing of the first: from a cold start and from a guess (half the solution,
    whose first step min solves exactly) it takes the Krylov tolerances, Newton steps
    and ‖Φ‖ history of a fresh solver from that start.  (GAMG is set up afresh at every
    step here: a hierarchy the last solve left, lagged or with its interpolation reused,
    changes the loose solves' iterates in their third digit.)"""
    scene = contact.load_scene(SCENE, ["mesh.cells=[40,40]"])
    p = build_problem(scene)
    no_reuse = {"reduced_lag_pc": False, "pc_gamg_reuse_interpolation": False}
    options = SolverOptions.parse({"method": method, "linear": "gamg", "petsc_options": no_reuse})
    zero = fem.Function(p.V)

    def fresh(u0: fem.Function, guess: bool):
        with SemismoothNewton(p, options) as solver:
            return solver.solve(u0, guess=guess)

    try:
        cold = fresh(zero, False)
        assert cold.converged and cold.linear == "gamg"
        half = fem.Function(p.V)
        half.x.array[:] = 0.5 * cold.u_h.x.array
        from_half = fresh(half, True)
        with SemismoothNewton(p, options) as solver:
            runs = [solver.solve(zero), solver.solve(half, guess=True), solver.solve(zero)]
        for again, reference in zip(runs, (cold, from_half, cold), strict=True):
            assert again.converged, again.reason
            assert [e["rtol"] for e in again.krylov_log] == [
                e["rtol"] for e in reference.krylov_log
            ]
            assert again.iterations == reference.iterations
            residuals = np.array([h["residual"] for h in again.history])
            expected = np.array([h["residual"] for h in reference.history])
            assert np.allclose(residuals, expected, rtol=1e-8, atol=1e-12 * expected[0])
        if method == "min":  # a guess's first Newton step is solved exactly
            assert from_half.krylov_log[0]["rtol"] <= 1e-10
    finally:
        p.destroy()


@pytest.mark.parametrize("cells", [128, 256])
def test_a_sequenced_guess_ends_in_its_polishing_solve(cells):
    """Grid sequencing hands the finest mesh a guess with the final active set: fb's
    polishing solve of it lands on the solution to the round-off floor of ‖Φ‖, and the
    solve ends there, 0 Newton steps + 1 polishing solve.  (SNES tests its stop at
    iteration 0 before the monitor raises it to the floor; without the floor in the stop
    the guess cost a Newton step and a second polishing solve.)"""
    scene = contact.load_scene(SCENE, [f"mesh.cells=[{cells},{cells}]"])
    r = contact.solve(scene, method="fb", verbose=False)
    assert r.converged and r.linear == "gamg" and len(r.sequence) >= 2, r.reason
    assert (r.iterations, r.polish_solves) == (0, 1), (r.iterations, r.polish_solves)
    assert r.residual <= r.history[0]["residual"]


def test_each_iterate_evaluates_the_residual_once():
    """SNES's Φ, the monitor's active set, the Jacobian's law and min's cycle guard are all
    taken at the same iterate: a linear residual R(x) = K x − b is computed once per Newton
    iterate (it was four times), and the iteration is the same as with
    ``reuse_residual: false``, which computes it at each of them (the deal.II step-41
    obstacle, cold, min: one step per band of nodes, many iterates)."""
    scene = contact.load_scene(
        str(ROOT / "configs" / "peers" / "dealii_step41.yaml"), ["mesh.cells=[48,48]"]
    )
    p = build_problem(scene)
    evaluate, count = p.residual, [0]

    def counted(x, out):
        count[0] += 1
        evaluate(x, out)

    p.residual = counted  # type: ignore[method-assign]
    zero = fem.Function(p.V)
    runs = {}
    try:
        for reuse in (True, False):
            options = SolverOptions.parse(
                {"method": "min", "petsc_options": {"reuse_residual": reuse}}
            )
            count[0] = 0
            with SemismoothNewton(p, options) as solver:
                r = solver.solve(zero)
            assert r.converged, r.reason
            runs[reuse] = (r, count[0], r.u_h.x.array.copy())
    finally:
        p.destroy()
    (new, once, u_new), (old, each, u_old) = runs[True], runs[False]
    steps = new.iterations
    assert steps >= 8 and old.iterations == steps
    assert [h["active"] for h in new.history] == [h["active"] for h in old.history]
    assert [h["residual"] for h in new.history] == [h["residual"] for h in old.history]
    assert largest(u_new - u_old) == 0.0
    # one per iterate (steps + 1) and the few of the set-up (scaling, ‖Φ(x_0)‖)
    assert once <= steps + 4, (once, steps)
    assert each >= 3 * steps, (each, steps)


def test_the_gamg_path_keeps_digests_of_laws_and_iterates_not_copies(monkeypatch):
    """What the CG + GAMG path remembers across Newton steps — the law A was built from,
    the last Newton step's law, the iterate whose residual it holds — it only compares
    later arrays with: it keeps a 32-byte digest of each, not a copy (five vectors at the
    last level of an adaptive run).  The iteration is that of copies
    (``lifetime.DIGESTS = False``, the path before): the same Newton steps, GAMG set-ups,
    Krylov tolerances and iterations, and the same solution to the last bit (the deal.II
    step-41 obstacle, fb, cold, lagged hierarchy)."""
    from contact.base import lifetime
    from contact.solvers import reduced

    scene = contact.load_scene(
        str(ROOT / "configs" / "peers" / "dealii_step41.yaml"), ["mesh.cells=[48,48]"]
    )
    p = build_problem(scene)
    n = p.b.getLocalSize()
    options = SolverOptions.parse({"method": "fb", "linear": "gamg"})
    krylov, records, solvers = reduced.ReducedSystem._krylov, [], []

    def spied(system, *args):
        records.append((system._held, system._newton, solvers[-1].cp._memo))
        return krylov(system, *args)

    monkeypatch.setattr(reduced.ReducedSystem, "_krylov", spied)

    def size(record) -> int:
        if record is None:
            return 0
        if isinstance(record, bytes):
            return len(record)
        return sum(np.asarray(a).nbytes for a in record)

    runs = {}
    try:
        for digests in (True, False):
            monkeypatch.setattr(lifetime, "DIGESTS", digests)
            records.clear()
            with SemismoothNewton(p, options) as solver:
                solvers.append(solver)
                r = solver.solve(fem.Function(p.V))
            assert r.converged and r.linear == "gamg", r.reason
            largest = [max(size(rec[k]) for rec in records) for k in range(3)]
            runs[digests] = (r, largest, r.u_h.x.array.copy())
    finally:
        p.destroy()
    (new, new_sizes, new_u), (old, old_sizes, old_u) = runs[True], runs[False]
    assert new_sizes == [32, 32, 32], new_sizes
    assert old_sizes == [16 * n, 16 * n, 8 * n], (old_sizes, n)
    assert new.iterations == old.iterations >= 2
    assert [(e["rtol"], e["iterations"], e["setups"]) for e in new.krylov_log] == [
        (e["rtol"], e["iterations"], e["setups"]) for e in old.krylov_log
    ]
    assert np.array_equal(new_u, old_u)


EX9 = str(ROOT / "configs" / "peers" / "petsc_ex9.yaml")


@pytest.mark.parametrize("admissible", [True, False])
def test_a_guess_below_the_obstacle_is_projected_onto_it(monkeypatch, admissible):
    """A guess is made admissible before the solve (``snes.ADMISSIBLE_GUESS``): the discrete
    solution of ex9 pushed 0.05 below ψ on its contact set is projected back onto ψ there,
    which is that solution again, so the solve stops at iteration 0 without a linear solve;
    given as it is (the old path) the same guess costs Newton steps, to the same solution."""
    from contact.solvers import snes

    monkeypatch.setattr(snes, "ADMISSIBLE_GUESS", admissible)
    scene = contact.load_scene(EX9, ["output.verbose=false"])
    exact = contact.solve(scene, problem=build_problem(scene), sequence="off")
    assert exact.converged and exact.n_active > 0
    problem = build_problem(scene)
    guess = fem.Function(problem.V)
    guess.x.array[:] = exact.u_h.x.array
    owned = problem.constraint.dofs
    gap = exact.u_h.x.array[owned] - problem.constraint.g  # u − ψ ≥ 0
    contact_set = owned[gap <= 1e-12]
    assert MPI.COMM_WORLD.allreduce(len(contact_set), op=MPI.SUM) == exact.n_active
    guess.x.array[contact_set] -= 0.05
    guess.x.scatter_forward()
    r = contact.solve(scene, problem=problem, u0=guess, sequence="off")
    assert r.converged
    assert largest(r.u_h.x.array - exact.u_h.x.array) < 1e-10
    if admissible:
        assert (r.iterations, r.polish_solves) == (0, 0), (r.iterations, r.polish_solves)
    else:
        assert r.iterations + r.polish_solves >= 2, (r.iterations, r.polish_solves)
