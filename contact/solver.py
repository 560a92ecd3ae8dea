"""Semismooth Newton for the nodal complementarity problem, and PETSc's VI baselines.

With R(u) = K u − b and the constraint set of :class:`contact.models.Constraint`, the
multiplier is eliminated (SPEC §4, implementation note): on a constrained node i

    a_i = σ (g_i − u_i)  [gap],     b_i = −σ c R_i / w_i  [c × multiplier density],

and the nonsmooth equation is Φ(u) = 0 with

    Φ_i = −σ (w_i / c) φ(a_i, b_i)   on constrained rows,    Φ_i = R_i   elsewhere.

The factor −σ w_i / c is a constant row scaling of SPEC's Φ_i = φ(a_i, b_i): it does not
change the zeros or the Newton steps, but it gives every row the units of R (a force), so
that ‖Φ‖ and the merit ½‖Φ‖² mix no units, and an inactive row is exactly R_i.  An element
of the generalized Jacobian is then

    H = diag(s) K + diag(d),   s_i = ∂_b φ,  d_i = (w_i / c) ∂_a φ  (constrained rows),
                               s_i = 1,      d_i = 0                (other rows),

built from the assembled K by one ``MatDiagonalScale`` and one ``MatDiagonalSet`` per
iteration; the sparsity pattern never changes, so a direct solver reuses its symbolic
factorization.  ``vinewtonrsls`` / ``vinewtonssls`` solve the same discrete problem as the
bound-constrained VI  l ≤ u ≤ u_max,  F(u) = K u − b  (PETSc.INFINITY where unbounded).
"""
from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from dolfinx import fem

from . import ncp
from .config import SCENE, ConfigError, _validate
from .models import DiscreteProblem, nodal_scaling, scalar_problem
from .scene import Scene

DEFAULT_PETSC_OPTIONS = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
# 3D elasticity: BiCGStab + GAMG with the rigid-body near-nullspace.  Measured on the final
# hertz_3d mesh (185679 DoFs, fb from u = 0, 16 Newton steps each): 87 s against 219 s for
# MUMPS; in 2D (hertz_2d, 13650 DoFs) MUMPS is faster (0.30 s against 0.46 s).
ELASTICITY_3D_PETSC_OPTIONS = {"ksp_type": "bcgs", "pc_type": "gamg", "ksp_rtol": 1e-10}
_REASONS = {v: k.lower() for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
_counter = itertools.count()


@dataclass
class Result:
    """The outcome of one solve.  ``lmbda_h`` holds λ_i at constrained DoFs (0 elsewhere);
    ``active_mask`` marks the active ones among ``problem.constraint.dofs`` (owned) by the
    solver's rule b_i > a_i at the solution, the set ``active`` and ``n_active`` show."""

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
    options: dict = field(default_factory=dict)
    polish_solves: int = 0

    @property
    def linear_solves(self) -> int:
        """Newton steps plus active-set polishing solves: the linear systems solved."""
        return self.iterations + self.polish_solves

    @property
    def dofs(self) -> int:
        V = self.u_h.function_space
        return V.dofmap.index_map.size_global * V.dofmap.index_map_bs


def solves_text(newton: int, polish: int) -> str:
    """'n' Newton iterations, or 'n+p' with p active-set polishing solves (tables, charts)."""
    return f"{newton}+{polish}" if polish else str(newton)


def build_problem(scene: Scene) -> DiscreteProblem:
    """The discrete problem of the scene's model (elasticity code is imported only for
    elasticity scenes)."""
    if scene.cfg["model"]["type"] == "elasticity":
        from .elasticity import elasticity_problem

        return elasticity_problem(scene)
    return scalar_problem(scene)


def solver_options(scene: Scene, **overrides: Any) -> dict:
    """The scene's ``solver`` section with keyword overrides, validated like the YAML."""
    raw = {**scene.cfg["solver"], **{k: v for k, v in overrides.items() if v is not None}}
    return _validate(raw, SCENE["solver"], "solver", scene.cfg["constants"])


class _Complementarity:
    """Vectorised nodal quantities a_i, b_i for an iterate (no loop over DoFs)."""

    def __init__(self, problem: DiscreteProblem):
        self.p = problem
        self.R = problem.b.duplicate()
        con = problem.constraint
        self.dofs, self.g, self.w, self.sign, self.c = con.dofs, con.g, con.w, con.sign, problem.c
        self.s, self.d = problem.b.duplicate(), problem.b.duplicate()  # Jacobian scalings

    def pair(self, x: PETSc.Vec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(a, b, R) at x: gap a = σ(g − u), scaled multiplier b = −σ c R / w, residual R."""
        self.p.residual(x, self.R)
        r = self.R.array_r
        u = x.array_r[self.dofs]
        a = self.sign * (self.g - u)
        b = -self.sign * self.c * r[self.dofs] / self.w
        return a, b, r

    def active(self, x: PETSc.Vec) -> np.ndarray:
        """Active nodes: scaled multiplier exceeds the gap, b_i > a_i (ties inactive)."""
        a, b, _ = self.pair(x)
        return b > a

    def phi(self, x: PETSc.Vec, f: PETSc.Vec, method: str, mu: float) -> tuple[np.ndarray, np.ndarray]:
        """f = Φ(x): R on free rows, −σ (w/c) φ(a, b) on constrained rows; returns (a, b)."""
        a, b, _ = self.pair(x)
        self.R.copy(f)
        f.array_w[self.dofs] = -self.sign * (self.w / self.c) * ncp.phi(a, b, method, mu)
        return a, b

    def jacobian(self, a: np.ndarray, b: np.ndarray, H: PETSc.Mat, method: str, mu: float) -> None:
        """H = diag(s) K + diag(d), the generalized-Jacobian element of Φ at the pair (a, b)."""
        da, db = ncp.dphi(a, b, method, mu)
        self.s.set(1.0)
        self.d.set(0.0)
        self.s.array_w[self.dofs] = db
        self.d.array_w[self.dofs] = (self.w / self.c) * da
        self.p.K.copy(H, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        H.diagonalScale(L=self.s)
        H.setDiagonal(self.d, addv=PETSc.InsertMode.ADD_VALUES)


class _Polisher:
    """Active-set polishing, a line-search pre-check of the Newton step x → W = x − y.

    When the step leaves the active set A = {i : b_i > a_i} unchanged, the linear problem
    that A defines,  u_i = g_i on A,  R_i(u) = 0 on every other row,  is solved as well: it
    is one Newton step of φ_min from x (one primal–dual active-set step), landing on the
    point P.  If ‖Φ(P)‖ < ‖Φ(W)‖ the step is replaced by x → P.  Then once the Newton
    iterates of φ_FB have identified A, one extra linear solve finishes the job, instead of
    FB's slow approach to nodes with a small gap and a small multiplier (from (a, b) with
    |b| = a/2, a Newton step of φ_FB on one node only shrinks b to 0.15 b).  The idea is the
    active-set identification of Facchinei, Fischer and Kanzow (SIAM J. Optim. 9, 1998),
    and the solution polishing of QP solvers (OSQP).  Φ, and so the solution, are those of
    φ; each attempt costs one linear solve, counted in ``solves``.  No attempt is made when
    W already meets SNES's stopping test (``done``).  The solve borrows the Newton solver's
    KSP and gives it back its operators, so only one factorization is alive at a time.
    """

    def __init__(self, cp: "_Complementarity", method: str, mu: float, ksp: PETSc.KSP, timers: dict):
        problem = cp.p
        self.cp, self.method, self.mu, self.ksp, self.timers = cp, method, mu, ksp, timers
        self.H = problem.K.duplicate(copy=True)
        _attach_near_nullspace(problem, self.H)
        self.W, self.FW, self.FP, self.dP = (problem.b.duplicate() for _ in range(4))
        self.solves, self.accepted, self.taken = 0, False, None
        self.done = 0.0  # ‖Φ‖ at which SNES stops: a Newton point below it needs no polishing

    def __call__(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        cp, W = self.cp, self.W
        self.accepted, self.taken = False, None
        x.copy(W)
        W.axpy(-1.0, y)
        t0 = time.perf_counter()
        a_w, b_w = cp.phi(W, self.FW, self.method, self.mu)  # one residual evaluation per point
        a, b = cp.phi(x, self.FP, "min", self.mu)
        same = np.array_equal(b > a, b_w > a_w)  # the active-set rule of _Complementarity.active
        if not x.getComm().tompi4py().allreduce(bool(same), op=MPI.LAND) or self.FW.norm() <= self.done:
            self.timers["assembly"] += time.perf_counter() - t0
            return
        self.taken = y.norm()
        cp.jacobian(a, b, self.H, "min", self.mu)
        # the Newton solver's own KSP: one factorization alive at a time (memory), then J back
        A, P = self.ksp.getOperators()
        self.ksp.setOperators(self.H)
        t1 = time.perf_counter()
        self.ksp.solve(self.FP, self.dP)
        t2 = time.perf_counter()
        self.ksp.setOperators(A, P)
        self.solves += 1
        x.copy(W)
        W.axpy(-1.0, self.dP)  # W = P
        cp.phi(W, self.FP, self.method, self.mu)
        if self.FP.norm() < self.FW.norm():
            self.dP.copy(y)
            self.accepted, self.taken = True, self.dP.norm()
        self.timers["solve"] += t2 - t1
        self.timers["assembly"] += (t1 - t0) + (time.perf_counter() - t2)

    def destroy(self) -> None:
        for obj in (self.H, self.W, self.FW, self.FP, self.dP):
            obj.destroy()


def solve(scene: Scene, method: str | None = None, problem: DiscreteProblem | None = None,
          u0: fem.Function | None = None, verbose: bool | None = None, **options: Any) -> Result:
    """Solve the scene's contact problem; return a :class:`Result` (never raises on divergence).

    ``method`` ∈ {fb, min, blend, vinewtonrsls, vinewtonssls}; further keyword options
    override the scene's ``solver`` section (``mu``, ``c``, ``kappa``, ``line_search``,
    ``polish``, ``rtol``, ``atol``, ``max_it``, ``petsc_options``).  ``problem`` reuses an assembled problem,
    ``u0`` is an initial guess (default: the scene's ``solver.u0``, zero by default).
    """
    opts = solver_options(scene, method=method, **options)
    method = opts["method"]
    verbose = scene.cfg["output"]["verbose"] if verbose is None else verbose
    built_here = problem is None
    problem = problem or build_problem(scene)
    t_start = time.perf_counter()
    con = problem.constraint  # the NCP scaling follows the options of this solve
    problem.c = (nodal_scaling(problem.K, con.dofs, con.w, opts["kappa"]) if opts["c"] == "auto"
                 else float(opts["c"]))
    comm = scene.comm
    # the problem's assembly counts once: in the solve that built it
    built = problem.assembly_time if built_here else 0.0
    timers = {"assembly": built, "solve": 0.0}
    cp = _Complementarity(problem)

    # Initial guess with the Dirichlet values in place.
    x = problem.b.duplicate()
    if u0 is None:
        from .models import _interpolate
        u0 = _interpolate(problem.V, opts["u0"], scene)
    problem.to_unknowns(u0.x.petsc_vec, x)
    dolfinx_set_bc(x, problem.bcs)

    snes = PETSc.SNES().create(comm)
    prefix = f"contact{next(_counter)}_"
    snes.setOptionsPrefix(prefix)
    petsc_opts = {**default_linear_solver(problem), **{str(k): v for k, v in opts["petsc_options"].items()}}
    F = problem.b.duplicate()
    state = {"t_jac": None, "dir_norm": np.nan}
    polisher: _Polisher | None = None

    if method in ncp.METHODS:
        mu = opts["mu"]
        J = problem.K.duplicate(copy=True)
        _attach_near_nullspace(problem, J)

        def residual(snes, x, f):
            t0 = time.perf_counter()
            cp.phi(x, f, method, mu)
            timers["assembly"] += time.perf_counter() - t0

        def jacobian(snes, x, J_, P):
            t0 = time.perf_counter()
            a, b, _ = cp.pair(x)
            cp.jacobian(a, b, P, method, mu)
            now = time.perf_counter()
            timers["assembly"] += now - t0
            state["t_jac"] = now

        snes.setType("newtonls")
        snes.setFunction(residual, F)
        snes.setJacobian(jacobian, J)
        petsc_opts.setdefault("snes_linesearch_type", opts["line_search"])
        if opts["polish"] and method != "min":
            polisher = _Polisher(cp, method, mu, snes.getKSP(), timers)
            snes.setLineSearchPreCheck(polisher)
    else:
        def residual(snes, x, f):
            t0 = time.perf_counter()
            problem.residual(x, f)
            timers["assembly"] += time.perf_counter() - t0

        def jacobian(snes, x, J_, P):
            # vinewtonssls scales the Jacobian in place: hand it a fresh copy of K each time
            t0 = time.perf_counter()
            problem.K.copy(P, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
            state["t_jac"] = now = time.perf_counter()
            timers["assembly"] += now - t0

        snes.setType(method)
        snes.setFunction(residual, F)
        J = problem.K.duplicate(copy=True)
        _attach_near_nullspace(problem, J)
        snes.setJacobian(jacobian, J)
        lower, upper = problem.b.duplicate(), problem.b.duplicate()
        lower.set(PETSc.NINFINITY)
        upper.set(PETSc.INFINITY)
        con = problem.constraint
        (upper if con.sign > 0 else lower).array_w[con.dofs] = con.g
        snes.setVariableBounds(lower, upper)

    def post_solve(ksp, rhs, sol):
        if state["t_jac"] is not None:
            timers["solve"] += time.perf_counter() - state["t_jac"]
            state["t_jac"] = None
        state["dir_norm"] = sol.norm()

    snes.getKSP().setPostSolve(post_solve)
    snes.setTolerances(rtol=opts["rtol"], atol=opts["atol"], stol=0.0, max_it=opts["max_it"])
    snes.setDivergenceTolerance(PETSc.UNLIMITED)  # semismooth Newton may raise ‖Φ‖ on its way: no dtol stop
    history: list[dict] = []
    prev = {"x": x.duplicate(), "active": None}

    def monitor(snes, its, fnorm):
        xk = snes.getSolution()
        active = cp.active(xk)
        n_active = comm.allreduce(int(active.sum()), op=MPI.SUM)
        changed = 0 if prev["active"] is None else comm.allreduce(int((active != prev["active"]).sum()), op=MPI.SUM)
        step = np.nan
        if its > 0:
            prev["x"].axpy(-1.0, xk)
            polished = polisher is not None and polisher.taken is not None
            dn = polisher.taken if polished else state["dir_norm"]  # the direction actually taken
            step = prev["x"].norm() / dn if dn > 0 else 0.0
        elif polisher is not None:  # SNES's stopping test, newtonls: ‖Φ‖ ≤ max(atol, rtol ‖Φ_0‖)
            polisher.done = max(opts["atol"], opts["rtol"] * fnorm)
        xk.copy(prev["x"])
        prev["active"] = active
        row = {"iteration": its, "residual": float(fnorm), "step": float(step),
               "active": n_active, "changed": changed, "polished": its > 0 and polisher is not None and polisher.accepted}
        history.append(row)
        if verbose and comm.rank == 0:
            st = "    -" if its == 0 else f"{step:5.2f}"
            print(f"  {method:>12s} it {its:3d}  |Phi| = {fnorm:10.3e}  step {st}  "
                  f"active {n_active:7d}  changed {changed:6d}{'  polished' if row['polished'] else ''}", flush=True)

    snes.setMonitor(monitor)
    popts = PETSc.Options()
    for key, val in petsc_opts.items():
        popts[prefix + key] = _petsc_value(val)
    try:
        _set_from_options(snes)
    finally:
        for key in petsc_opts:
            popts.delValue(prefix + key)
    snes.solve(None, x)
    reason_code = snes.getConvergedReason()
    result = _finish(scene, problem, cp, x, snes, history, method, opts, timers, t_start - built, reason_code)
    if polisher is not None:
        result.polish_solves = polisher.solves
        polisher.destroy()
    for obj in (snes, F, x, prev["x"]):
        obj.destroy()
    return result


def method_variant(name: str) -> tuple[str, dict]:
    """A method name as benchmarks and tests list it: ``fb``, … or ``fb-nopolish`` /
    ``blend-nopolish`` (the pure Newton method) → (method, options for :func:`solve`)."""
    if name.endswith("-nopolish"):
        return name.removesuffix("-nopolish"), {"polish": False}
    return name, {}


def default_linear_solver(problem: DiscreteProblem) -> dict:
    """MUMPS LU, except Krylov + GAMG for 3D elasticity (faster there; see the figures above)."""
    if problem.near_nullspace is not None and problem.V.mesh.geometry.dim == 3:
        return dict(ELASTICITY_3D_PETSC_OPTIONS)
    return dict(DEFAULT_PETSC_OPTIONS)


def _attach_near_nullspace(problem: DiscreteProblem, J: PETSc.Mat) -> None:
    """Rigid-body modes for GAMG on elasticity (kept by J across its re-copies)."""
    if problem.near_nullspace is not None:
        J.setNearNullSpace(problem.near_nullspace)


def _set_from_options(snes: PETSc.SNES) -> None:
    """setFromOptions + setUp; a bad PETSc option becomes a one-line ConfigError."""
    PETSc.Sys.pushErrorHandler("python")  # raise, do not print PETSc's trace
    try:
        snes.setFromOptions()
        snes.getKSP().setFromOptions()
        snes.getKSP().getPC().setFromOptions()
    except PETSc.Error as err:
        raise ConfigError(f"solver.petsc_options: PETSc rejected the options ({_petsc_message(err)})") from None
    finally:
        PETSc.Sys.popErrorHandler()


def _petsc_message(err: PETSc.Error) -> str:
    lines = [ln.split("]", 1)[-1].strip() for ln in str(err).strip().splitlines()]
    return lines[-1] if lines else f"error code {err.ierr}"


def owned_residual(result: Result) -> np.ndarray:
    """R = K x − b at the solution (x = Qᵀ u_h, the solver's unknowns), owned entries."""
    p = result.problem
    x, r = p.b.duplicate(), p.b.duplicate()
    p.to_unknowns(result.u_h.x.petsc_vec, x)
    p.residual(x, r)
    out = r.array_r.copy()
    x.destroy()
    r.destroy()
    return out


def _petsc_value(val: Any) -> str:
    if isinstance(val, bool):
        return "true" if val else "false"
    return "" if val is None else str(val)


def dolfinx_set_bc(x: PETSc.Vec, bcs: list) -> None:
    """Insert Dirichlet values into the owned entries of x."""
    for bc in bcs:
        bc.set(x.array_w)


def _finish(scene, problem, cp, x, snes, history, method, opts, timers, t_start, reason_code) -> Result:
    """Copy the iterate into functions: u_h, and λ_h, the gap and the active set.  Timings
    count from ``t_start`` (shifted back by the assembly when this solve built the problem)."""
    u_h = problem.u_h
    problem.to_displacement(x, u_h.x.petsc_vec)
    u_h.x.scatter_forward()
    a, b, r = cp.pair(x)
    active = b > a
    lmbda, gap, active_fn = problem.outputs(x.array_r, r, active)
    comm = scene.comm
    timers["total"] = time.perf_counter() - t_start
    timers["other"] = max(timers["total"] - timers["assembly"] - timers["solve"], 0.0)
    converged = reason_code > 0
    return Result(u_h=u_h, lmbda_h=lmbda, gap=gap, active=active_fn, history=history,
                  converged=converged, reason=_REASONS.get(reason_code, str(reason_code)),
                  iterations=snes.getIterationNumber(),
                  residual=history[-1]["residual"] if history else float("nan"),
                  method=method, n_active=comm.allreduce(int(active.sum()), op=MPI.SUM),
                  timings=timers, problem=problem, active_mask=active, options=opts)
