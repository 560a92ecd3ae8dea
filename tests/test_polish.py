"""Active-set polishing (``solver.polish``, :class:`contact.solvers.polish.Polisher`): it changes
how fast FB / blend Newton converges, never what it converges to."""

from __future__ import annotations

import gc
from pathlib import Path

import contact
from contact.setup.build import build_problem
from contact.solvers.linear import AssembledSystem
from contact.solvers.newton import Complementarity
from contact.solvers.polish import Polisher
from contact.solvers.problem import nodal_scaling
from contact.solvers.snes import set_dirichlet

import numpy as np
import pytest
from petsc4py import PETSc
from ties import tie_margin

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def scene():
    return contact.load_scene(
        ROOT / "configs" / "signorini_square.yaml",
        overrides=["mesh.cells=[96,96]", "solver.kappa=1", "output.verbose=false"],
    )


@pytest.mark.parametrize("method", ["fb", "blend"])
def test_polish_same_solution_fewer_linear_solves(scene, method):
    """Same discrete solution (1e-10) and active set; fewer linear solves in all."""
    problem = build_problem(scene)
    pure = contact.solve(scene, method=method, problem=problem, polish=False)
    u_pure = pure.u_h.x.array.copy()
    pol = contact.solve(scene, method=method, problem=problem, polish=True)
    assert pure.converged and pol.converged
    assert pure.polish_solves == 0 and pol.polish_solves >= 1
    assert pol.linear_solves == pol.iterations + pol.polish_solves
    # 2 against 4 here: FB's own end game shrinks a node with a small gap and multiplier by
    # 0.15 per step (contact.solvers.polish), where one polishing solve ends it — a margin of
    # whole solves, not of rounding
    assert pol.linear_solves < pure.linear_solves, (pol.linear_solves, pure.linear_solves)
    assert np.max(np.abs(pol.u_h.x.array - u_pure)) <= 1e-10
    assert tie_margin(pol) >= 1e-6  # no node near a tie: the counts cannot move with rounding
    assert pol.n_active == pure.n_active
    assert any(row["polished"] for row in pol.history)
    assert not any(row["polished"] for row in pure.history)


def test_min_is_never_polished(scene):
    """A Newton step of φ_min already is the polishing step: no second solve."""
    r = contact.solve(scene, method="min", polish=True)
    assert r.converged and r.polish_solves == 0


def _state(scene, method="fb"):
    problem = build_problem(scene)
    problem.c = nodal_scaling(
        problem.K, problem.constraint.dofs, problem.constraint.w, scene.config.solver.kappa
    )
    cp = Complementarity(problem)
    timers = {"solve": 0.0, "assembly": 0.0}
    ksp = PETSc.KSP().create(problem.b.getComm())
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.setOperators(problem.K)  # stands in for the Newton solver's KSP and its Jacobian
    pol = Polisher(cp, method, 0.5, AssembledSystem(problem, ksp), timers)
    x = problem.b.duplicate()
    x.set(0.0)
    set_dirichlet(x, problem.bcs)
    return problem, cp, pol, x


def test_polisher_waits_while_the_active_set_moves(scene):
    """A step that changes the active set is left alone, and no solve is spent."""
    ref = contact.solve(scene, method="min")
    problem, cp, pol, x = _state(scene)  # x: u = 0, nothing active
    sol = x.duplicate()
    problem.to_unknowns(ref.u_h.x.petsc_vec, sol)
    y = x - sol  # the step x -> W = x - y lands on the solution, whose active set differs
    assert not cp.active(x).any() and ref.active_mask.any()
    before = y.array.copy()
    pol(x, y)
    assert pol.solves == 0 and not pol.accepted
    assert np.array_equal(y.array, before)
    pol.destroy()


def _near_solution(scene):
    """The min solution, and the state of :func:`_state` with x the solution perturbed
    slightly off the contact nodes only (its active set the final one)."""
    ref = contact.solve(scene, method="min")
    problem, cp, pol, x = _state(scene)
    u = ref.u_h.copy()
    free = np.setdiff1d(np.arange(u.x.array.size), cp.dofs)
    u.x.array[free] *= 1.0 + 1e-3
    problem.to_unknowns(u.x.petsc_vec, x)
    set_dirichlet(x, problem.bcs)
    assert np.array_equal(cp.active(x), ref.active_mask)
    return ref, problem, cp, pol, x


def test_polisher_lands_on_the_active_set_solution(scene):
    """From an iterate with the final active set, the polished step hits the solution."""
    ref, problem, cp, pol, x = _near_solution(scene)
    y = problem.b.duplicate()
    y.set(0.0)  # a Newton step that goes nowhere: W = x
    pol(x, y)
    assert pol.solves == 1 and pol.accepted
    assert pol.system.ksp.getOperators()[0] == problem.K  # the Newton solver's operator is put back
    P = x.copy()
    P.axpy(-1.0, y)
    n = ref.u_h.x.petsc_vec.getLocalSize()
    assert np.max(np.abs(P.array_r[:n] - ref.u_h.x.array[:n])) <= 1e-10
    pol.destroy()


def test_the_polisher_solves_for_its_step_in_the_vector_of_phi_at_the_trial_point(scene):
    """Once the step is solved for, Φ at the Newton point W is needed only through its
    norm: the step takes that vector, so the polisher holds three vectors (W, Φ(W) then the
    step, Φ_min), not four, through the solver's life — one vector fewer during the exact
    solve that ends an adaptive level.  It still lands on the active-set solution
    (:func:`test_polisher_lands_on_the_active_set_solution`) and a rejected step leaves the
    Newton step alone."""
    from contact.base.lifetime import petsc_objects

    PETSc.Log.begin()
    problem, cp, pol, x = _state(scene)
    gc.collect()
    gc.disable()  # counted: no earlier test's vectors freed by the collector in between
    try:
        before = petsc_objects().get("Vector", 0)
        one = problem.b.duplicate()  # (a ghosted vector is two PETSc objects)
        per_vector = petsc_objects().get("Vector", 0) - before
        one.destroy()
        before = petsc_objects().get("Vector", 0)
        again = Polisher(cp, "fb", 0.5, pol.system, {"solve": 0.0, "assembly": 0.0})
        assert petsc_objects().get("Vector", 0) - before == 3 * per_vector
    finally:
        gc.enable()
    # a Newton point whose polished step raises ‖Φ‖: x = 0 with the step −x_ref (W = x_ref)
    # is the solution itself; polishing from the origin with y = 0 is rejected or accepted
    # by ‖Φ‖ alone, and y is only ever replaced by the polished step
    y = problem.b.duplicate()
    y.set(0.0)
    again(x, y)
    if not again.accepted:
        assert y.norm() == 0.0
    else:
        assert again.taken == pytest.approx(y.norm(), rel=1e-14)
    again.system = None  # shared with pol
    for obj in (again.W, again.FW, again.FP):
        obj.destroy()
    pol.destroy()


@pytest.mark.parametrize("few", [True, False])
def test_a_step_that_changes_a_handful_of_statuses_is_polished_on_the_set_it_reaches(
    scene, monkeypatch, few
):
    """A Newton step x → W that changes the status of a handful of nodes (the last ring of a
    receding free boundary) is polished on the active set W reaches: one exact solve from W,
    taken as the step x → P when it lowers ‖Φ‖, lands on the solution where W's set is the
    final one.  The old path (``POLISH_FEW = False``) polishes only a step that keeps x's
    set and leaves this one alone."""
    from contact.solvers import polish

    monkeypatch.setattr(polish, "POLISH_FEW", few)
    monkeypatch.setattr(polish, "FEW_CHANGES", 0.1)  # 41 active nodes here: a handful is 4
    ref, problem, cp, pol, W = _near_solution(scene)  # W's active set: the final one
    final = cp.active(W)
    # x: W with one contact node pushed in, which turns one to four nodes' statuses
    x = W.copy()
    for k in np.flatnonzero(final):
        W.copy(x)
        x.array_w[cp.dofs[k]] -= 1e-2
        if 1 <= np.count_nonzero(cp.active(x) != final) <= 4:
            break
    assert 1 <= np.count_nonzero(cp.active(x) != final) <= 4
    y = x - W
    before = y.array.copy()
    pol(x, y)
    if not few:
        assert pol.solves == 0 and not pol.accepted
        assert np.array_equal(y.array, before)
    else:
        assert pol.solves == 1 and pol.accepted
        P = x.copy()
        P.axpy(-1.0, y)
        n = ref.u_h.x.petsc_vec.getLocalSize()
        assert np.max(np.abs(P.array_r[:n] - ref.u_h.x.array[:n])) <= 1e-10
        assert pol.taken == pytest.approx(y.norm(), rel=1e-14)
    pol.destroy()


def test_no_polishing_when_the_newton_point_already_converged(scene):
    """A Newton point with ‖Φ‖ below SNES's stopping value is not polished (no wasted solve)."""
    ref = contact.solve(scene, method="min")
    problem, cp, pol, x = _state(scene)
    problem.to_unknowns(ref.u_h.x.petsc_vec, x)
    y = problem.b.duplicate()
    y.set(0.0)  # W = x = the solution
    pol.done = 1e-10
    pol(x, y)
    assert pol.solves == 0 and not pol.accepted and pol.taken is None
    pol.destroy()


def test_staged_initial_polish_resumes_only_on_the_same_active_set():
    """With the iterative (reduced) Newton system, the polishing solve of a guess first
    stops at STAGE_RTOL; it is finished (resumed from where it stopped) only when that step
    keeps the guess's active set, otherwise Newton takes over."""
    from contact.solvers.polish import STAGE_RTOL

    scene = contact.load_scene("configs/signorini_free_boundary.yaml", ["mesh.cells=[64,32]"])
    exact = contact.solve(scene, method="fb", verbose=False, linear="gamg", sequence="off")
    assert exact.converged
    # (a) the solution plus a tiny interior bump (zero on ∂Ω): the active set is the final one
    u0 = exact.u_h.copy()
    u0.interpolate(lambda x: 1e-6 * x[1] * (1 - x[1]) * (1 - x[0] ** 2))
    u0.x.array[:] += exact.u_h.x.array
    near = contact.solve(scene, method="fb", verbose=False, linear="gamg", u0=u0)
    # by construction, not by rounding: the guess's active set is final (the bump is 1e-6,
    # the tie margin O(1e-3)), so the polished point solves the problem to CG's tolerance
    assert near.converged and near.iterations == 0 and near.polish_solves == 1
    assert [e["rtol"] == STAGE_RTOL for e in near.krylov_log] == [True, False]
    assert [e["resume"] for e in near.krylov_log] == [False, True]
    assert np.abs(near.u_h.x.array - exact.u_h.x.array).max() < 1e-8
    # (b) a guess with nothing in contact: the first look changes the active set, no resume
    cold = exact.u_h.copy()
    cold.x.array[:] = 0.0
    far = contact.solve(scene, method="fb", verbose=False, linear="gamg", u0=cold)
    assert far.converged and far.iterations > 0
    assert far.krylov_log[0]["rtol"] == STAGE_RTOL and not any(e["resume"] for e in far.krylov_log)
    assert np.abs(far.u_h.x.array - exact.u_h.x.array).max() < 1e-8


def test_a_guess_polished_before_newton_keeps_no_law_for_the_jacobian(monkeypatch):
    """Polishing solves on a law of its own and gives the Newton law back to the
    matrix-free Jacobian J afterwards; before the first Newton step of a solve (a guess
    polished first, the first — and largest — GAMG set-up of an adaptive level) J applies no
    law yet, so no copy of one is made: the solve holds two vectors fewer there.  After a
    Newton step the law is kept and given back as before, and the solution is the cold
    solve's (problem A, fb on the CG + GAMG path, the solution plus a small bump)."""
    from contact.base.lifetime import petsc_objects
    from contact.solvers import reduced
    from contact.solvers.linear import ReducedNewtonSystem

    PETSc.Log.begin()
    scene = contact.load_scene("configs/signorini_free_boundary.yaml", ["mesh.cells=[64,32]"])
    exact = contact.solve(scene, method="fb", verbose=False, linear="gamg", sequence="off")
    assert exact.converged
    solve_law, krylov = ReducedNewtonSystem.solve_law, reduced.ReducedSystem._krylov
    calls: list[list] = []

    def spied_solve_law(system, *args, **kwargs):
        calls.append([system.newton_law, petsc_objects().get("Vector", 0), None])
        return solve_law(system, *args, **kwargs)

    def spied_krylov(system, *args):
        if calls and calls[-1][2] is None:
            calls[-1][2] = petsc_objects().get("Vector", 0) - calls[-1][1]
        return krylov(system, *args)

    monkeypatch.setattr(ReducedNewtonSystem, "solve_law", spied_solve_law)
    monkeypatch.setattr(reduced.ReducedSystem, "_krylov", spied_krylov)
    u0 = exact.u_h.copy()
    u0.interpolate(lambda x: 1e-3 * x[1] * (1 - x[1]) * (1 - x[0] ** 2))
    u0.x.array[:] += exact.u_h.x.array
    gc.collect()
    gc.disable()  # counted: no earlier test's vectors freed by the collector in between
    try:
        r = contact.solve(scene, method="fb", verbose=False, linear="gamg", u0=u0)
    finally:
        gc.enable()
    assert r.converged and r.polish_solves >= 1 and calls
    first_law, _, made = calls[0]
    assert first_law is False and made == 0, calls
    assert all(made == 0 for law, _, made in calls if not law), calls
    assert np.abs(r.u_h.x.array - exact.u_h.x.array).max() < 1e-8
