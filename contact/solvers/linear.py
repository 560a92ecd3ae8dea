"""The linear solver of each Newton step (``solver.linear``) and the Newton systems.

* ``direct`` — MUMPS LU of the assembled H = diag(s) K + diag(d) (:class:`AssembledSystem`);
* ``gamg``   — the symmetric reduction of H (:mod:`.reduced`), CG + GAMG on the SPD system,
  GAMG's interpolation reused across Newton steps, inexact Newton (``solver.inexact``);
* ``bcgs``   — BiCGStab + GAMG on the assembled H (the generic Krylov path, also for
  non-symmetric laws);
* ``hp_patch`` — as ``gamg`` with the problem's own p-robust preconditioner
  (:meth:`.problem.DiscreteProblem.patch_preconditioner`: scalar hp problems in 2D);
* ``auto``   — :func:`choose_linear`: MUMPS for small 2D problems (scalar hp problems: up to
  :data:`DIRECT_MAX_HP_2D` unknowns), ``gamg`` otherwise.

``solver.petsc_options`` go to the KSP that does the work: SNES's for ``direct`` / ``bcgs``,
the reduced system's inner KSP for ``gamg``.  With ``auto``, petsc_options naming a
``ksp_type`` or ``pc_type`` select the assembled path with exactly those options (as before
``solver.linear`` existed).
"""

from __future__ import annotations

from petsc4py import PETSc

from ..base.errors import ConfigError
from .options import default_options
from .problem import DiscreteProblem
from .reduced import ReducedSystem

#: ``auto`` uses MUMPS for 2D problems below this many DoFs (measured: demos/bench/bench_linear.py)
DIRECT_MAX_DOFS_2D = 5_000
#: ... and for 3D problems below this many
DIRECT_MAX_DOFS_3D = 0
#: ... and for 2D problems of variable degree (an hp space, whose GAMG iterations grow with
#: the degree) below this many unknowns (measured: demos/bench/bench_hp_solvers.py)
DIRECT_MAX_HP_2D = 150_000


def choose_linear(
    problem: DiscreteProblem, linear: str = "auto", petsc_options: dict | None = None
) -> str:
    """The linear solver of ``solver.linear`` for the diagonal Newton law (``auto``
    resolved by size and dimension)."""
    if linear != "auto":
        return linear
    if _user_solver(petsc_options):
        return "direct"  # the user's options on the assembled H, as they always applied
    if problem.V.mesh.geometry.dim == 3:
        limit = DIRECT_MAX_DOFS_3D
    else:
        limit = DIRECT_MAX_HP_2D if problem.variable_degree else DIRECT_MAX_DOFS_2D
    return "direct" if problem.unknowns() < limit else "gamg"


def _user_solver(petsc_options: dict | None) -> bool:
    """Whether the user's PETSc options choose the Krylov method or preconditioner."""
    return petsc_options is not None and bool({"ksp_type", "pc_type"} & set(petsc_options))


def assembled_kind(
    problem: DiscreteProblem, linear: str = "auto", petsc_options: dict | None = None
) -> str:
    """The linear solver of a Newton matrix that stays assembled (friction's block law
    H = B K + D, not symmetric; PETSc's VI solvers on K): ``direct``, or BiCGStab + GAMG
    (``bcgs``) when ``solver.linear`` asks for an iterative solver, and by default for 3D
    elasticity (as before the reduced system existed) — but for contact on the current
    configuration (:mod:`.current`), whose rows of the contact nodes are turned to their
    current frames: there BiCGStab + GAMG broke down (a sphere lowered into a 6 × 6 × 3
    block in 3 steps: ``diverged_linear_solve`` at step 3; GMRES + GAMG: 10 000 iterations
    without converging) where MUMPS took 5 Newton steps per load step."""
    refuse_patch(linear)
    if linear == "direct" or _user_solver(petsc_options):
        return "direct"
    if linear in ("gamg", "bcgs", "gmres"):
        return linear if linear == "gmres" else "bcgs"
    if problem.current is not None:
        return "direct"
    elastic_3d = problem.near_nullspace is not None and problem.V.mesh.geometry.dim == 3
    return "bcgs" if elastic_3d else "direct"


def refuse_patch(linear: str) -> None:
    """``hp_patch`` preconditions the symmetric reduced system of a diagonal law only: not
    an assembled Newton matrix (friction, a finite-strain or current-configuration problem,
    PETSc's VI solvers, the energy line search)."""
    if linear == "hp_patch":
        raise ConfigError(
            "solver.linear: hp_patch applies to frictionless small-strain scalar hp problems "
            "solved by fb, min or blend without the energy line search"
        )


#: friction's ``auto`` uses MUMPS on H for 2D problems below this many DoFs, the reduced block
#: system with GMRES + GAMG above and in 3D (measured: demos/bench/bench_cost.py friction cases)
FRICTION_DIRECT_MAX_DOFS_2D = 5_000


def friction_kind(
    problem: DiscreteProblem, linear: str = "auto", petsc_options: dict | None = None
) -> str:
    """The linear solver of friction's block law H = B K + D: ``direct`` (MUMPS on H), ``bcgs``
    (BiCGStab + GAMG on H, the 3D default before issue 29), ``gmres`` (the reduced block
    system, :mod:`.block_system`); ``auto`` (and ``gamg``, the Krylov choice of the
    frictionless path) resolved by size and dimension; the user's ksp/pc options select the
    assembled H with exactly those options."""
    refuse_patch(linear)
    if linear in ("direct", "bcgs", "gmres"):
        return linear
    if _user_solver(petsc_options):
        return "direct"
    if linear == "gamg":
        return "gmres"
    if problem.current is not None:  # turned frames on the current configuration (assembled_kind)
        return "direct"
    V = problem.V
    dofs = V.dofmap.index_map.size_global * V.dofmap.index_map_bs
    small_2d = V.mesh.geometry.dim == 2 and dofs < FRICTION_DIRECT_MAX_DOFS_2D
    return "direct" if small_2d else "gmres"


def default_linear_solver(problem: DiscreteProblem, linear: str = "auto") -> dict:
    """The default PETSc options of the solver ``choose_linear`` picks."""
    return petsc_defaults(problem, choose_linear(problem, linear))


def petsc_defaults(problem: DiscreteProblem, kind: str) -> dict:
    """PETSc options of linear solver ``kind`` for ``problem``."""
    return default_options(kind, problem.V.mesh.topology.dim, problem.V.mesh.comm.size)


#: most unknowns of a factorized system that on more than one rank is gathered whole onto
#: every rank and factorized there (:class:`GatheredFactor`); 0: always MUMPS across the ranks
GATHERED_FACTOR_SIZE = 2000


def gathers(A: PETSc.Mat) -> bool:
    """Whether a factorization of A is made whole on every rank (:class:`GatheredFactor`): on
    more than one rank, up to :data:`GATHERED_FACTOR_SIZE` unknowns."""
    return A.getComm().size > 1 and A.getSize()[0] <= GATHERED_FACTOR_SIZE


class GatheredFactor:
    """Python PC context: the operator gathered whole onto every rank (one
    ``MatCreateRedundantMatrix``) and factorized there by serial MUMPS (``lu``, or
    ``cholesky`` = LDLᵀ with null pivots detected); a solve gathers the right-hand side
    onto every rank (one scatter), solves and keeps the owned slice.

    Why: a distributed MUMPS factorization and solve exchange many small messages; for a
    system of a few hundred unknowns, above all on ranks that share cores, waiting for them
    costs far more than the arithmetic, which every rank can then afford whole.  Every rank
    factorizes the same matrix with the same serial code, so the inertia
    (:func:`factor_inertia`) and the solution are the same on every rank; they equal the
    distributed factorization's to round-off."""

    def __init__(self, factor: str = "lu"):
        self.factor = factor
        self.R: PETSc.Mat | None = None  # the gathered operator (sequential, every rank)
        self.ksp: PETSc.KSP | None = None  # its serial factorization
        self.scatter: PETSc.Scatter | None = None  # the right-hand side onto every rank
        self.full: PETSc.Vec | None = None
        self.sol: PETSc.Vec | None = None

    def setUp(self, pc: PETSc.PC) -> None:  # noqa: N802  (petsc4py's name)
        """Gather the operator's current values and factorize them (collective)."""
        _, A = pc.getOperators()
        for obj in (self.R, self.ksp):  # a new factorization (its analysis is cheap serially)
            if obj is not None:
                obj.destroy()
        self.R = A.getRedundantMatrix(A.getComm().size, PETSc.COMM_SELF)
        self.ksp = ksp = PETSc.KSP().create(PETSc.COMM_SELF)
        ksp.setType("preonly")
        ksp.setOperators(self.R)
        inner = ksp.getPC()
        inner.setType(self.factor)
        inner.setFactorSolverType("mumps")
        if self.factor == "cholesky":
            inner.setFactorSetUpSolverType()
            inner.getFactorMatrix().setMumpsIcntl(24, 1)  # a null pivot is a zero eigenvalue
        ksp.setUp()
        if self.scatter is None:
            x = A.createVecRight()
            self.scatter, self.full = PETSc.Scatter.toAll(x)
            self.sol = self.full.duplicate()
            x.destroy()

    def apply(self, pc: PETSc.PC, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = A⁻¹ x: x gathered, solved on every rank, y's owned slice kept."""
        full, sol, ksp = self.full, self.sol, self.ksp
        assert self.scatter is not None and full is not None and sol is not None and ksp
        self.scatter.scatter(x, full, PETSc.InsertMode.INSERT, PETSc.ScatterMode.FORWARD)  # type: ignore[arg-type]
        ksp.solve(full, sol)
        if ksp.getConvergedReason() < 0:  # type: ignore[operator]  # the outer solve: a failed PC
            pc.setFailedReason(PETSc.PC.FailedReason.SUBPC_ERROR)  # type: ignore[arg-type]
        lo, hi = y.getOwnershipRange()
        y.array_w[:] = sol.array_r[lo:hi]

    def inertia(self) -> tuple[int, int, int]:
        """(n₋, n₀, n₊) of the factorized operator (``cholesky``)."""
        assert self.ksp is not None, "inertia after setUp"
        return self.ksp.getPC().getFactorMatrix().getInertia()

    def destroy(self, pc: PETSc.PC | None = None) -> None:
        for obj in (self.R, self.ksp, self.scatter, self.full, self.sol):
            if obj is not None:
                obj.destroy()
        self.R = self.ksp = self.scatter = self.full = self.sol = None


def gather_factor(pc: PETSc.PC, factor: str) -> None:
    """Make ``pc`` a :class:`GatheredFactor` of ``factor`` (``lu`` or ``cholesky``)."""
    pc.setType(PETSc.PC.Type.PYTHON)
    pc.setPythonContext(GatheredFactor(factor))


def factor_inertia(pc: PETSc.PC) -> tuple[int, int, int]:
    """(n₋, n₀, n₊) of the LDLᵀ factorization ``pc`` holds (set up): MUMPS's across the ranks
    or that of a :class:`GatheredFactor`."""
    if pc.getType() == PETSc.PC.Type.PYTHON:
        return pc.getPythonContext().inertia()
    return pc.getFactorMatrix().getInertia()


def mumps_ksp(A: PETSc.Mat, factor: str = "lu") -> PETSc.KSP:
    """A KSP solving with A by one MUMPS factorization (``lu``, or ``cholesky`` = LDLᵀ for a
    symmetric A, set up so that its inertia (:func:`factor_inertia`) counts over all ranks and
    a null pivot counts as a zero eigenvalue), its operators set; the caller destroys it.
    A small A on several ranks is factorized whole on every rank (:func:`gathers`)."""
    ksp = PETSc.KSP().create(A.getComm())
    ksp.setOperators(A)
    ksp.setType("preonly")
    pc = ksp.getPC()
    if gathers(A):
        gather_factor(pc, factor)
        return ksp
    pc.setType(factor)
    pc.setFactorSolverType("mumps")
    if factor == "cholesky":
        pc.setFactorSetUpSolverType()
        mumps = pc.getFactorMatrix()
        mumps.setMumpsIcntl(13, 1)  # the root node without ScaLAPACK: the global inertia
        mumps.setMumpsIcntl(24, 1)  # null pivots detected (a singular A counts as zero)
    return ksp


def attach_near_nullspace(problem: DiscreteProblem, J: PETSc.Mat) -> None:
    """Rigid-body modes for GAMG on elasticity (kept by J across its re-copies)."""
    if problem.near_nullspace is not None:
        J.setNearNullSpace(problem.near_nullspace)


class AssembledSystem:
    """H = diag(s) K + diag(d) assembled (K's pattern: a direct solver reuses its symbolic
    factorization) and solved by SNES's own KSP with the PETSc options as given.  Works for
    any law that can write H into a matrix of K's pattern."""

    def __init__(self, problem: DiscreteProblem, ksp: PETSc.KSP | None = None):
        self.K = problem.K
        self.J = problem.K.duplicate(copy=True)
        attach_near_nullspace(problem, self.J)
        self._problem = problem
        self.ksp = ksp  # SNES's KSP (:meth:`configure`)
        self.H: PETSc.Mat | None = None  # the polishing system's matrix, made when first needed
        self.krylov_iterations = 0
        self.stop = 0.0

    def configure(self, snes: PETSc.SNES, prefix: str) -> None:
        self.ksp = snes.getKSP()

    def set_options(self) -> None:
        """SNES's KSP reads the options itself (same prefix)."""

    def set_law(self, s: PETSc.Vec, d: PETSc.Vec, H: PETSc.Mat | None = None) -> None:
        """H (default: SNES's Jacobian J) = diag(s) K + diag(d)."""
        H = self.J if H is None else H
        self.K.copy(H, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)  # type: ignore[arg-type]
        H.diagonalScale(L=s)
        H.setDiagonal(d, addv=PETSc.InsertMode.ADD_VALUES)  # type: ignore[arg-type]

    #: whether a polishing solve can be cut short and resumed (:class:`ReducedNewtonSystem`)
    resumable = False

    def solve_law(self, s: PETSc.Vec, d: PETSc.Vec, F: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = H⁻¹ F for another law (polishing) with SNES's own KSP, whose operators are put
        back afterwards: one factorization alive at a time (memory)."""
        assert self.ksp is not None, "solve_law after configure and before destroy"
        if self.H is None:
            self.H = self.K.duplicate(copy=True)
            attach_near_nullspace(self._problem, self.H)
        self.set_law(s, d, self.H)
        A, P = self.ksp.getOperators()
        self.ksp.setOperators(self.H)
        self.ksp.solve(F, y)
        self.krylov_iterations += self.ksp.getIterationNumber()
        self.ksp.setOperators(A or self.J, P or self.J)

    def count(self, ksp: PETSc.KSP) -> None:
        """Add the Krylov iterations of SNES's last linear solve."""
        self.krylov_iterations += ksp.getIterationNumber()

    def destroy(self) -> None:
        for obj in (self.J, self.H):
            if obj is not None:
                obj.destroy()
        # SNES's KSP holds callbacks that hold this object: drop the reference back (a cycle
        # through PETSc objects that Python's collector cannot see would keep the mesh alive)
        self.ksp = None
        self._problem = None  # type: ignore[assignment]  # released: unused after destroy


class ReducedNewtonSystem(ReducedSystem):
    """:class:`.reduced.ReducedSystem` with the interface of :class:`AssembledSystem`."""

    def __init__(self, problem: DiscreteProblem, prefix: str, forcing: bool = True):
        super().__init__(
            problem.K, problem.near_nullspace, prefix, forcing, dirichlet=problem.dirichlet_rows()
        )

    resumable = True

    def solve_law(
        self,
        s: PETSc.Vec,
        d: PETSc.Vec,
        F: PETSc.Vec,
        y: PETSc.Vec,
        rtol: float | None = None,
        resume: bool = False,
    ) -> None:
        """y = H⁻¹ F for another law (polishing); ``rtol`` and ``resume`` as in
        :meth:`.reduced.ReducedSystem.solve`.  The Newton law stays the one the matrix-free J
        applies; the next Newton step rebuilds its own A.  (Before the first Newton step of a
        solve — a guess polished first — J applies no law yet and none is kept.)"""
        kept = (self.s.copy(), self.d.copy()) if self.newton_law else None
        # an exact solve on a new law sets GAMG up afresh (:meth:`solve`): A need not be kept
        # apart from the lagged hierarchy's matrix meanwhile
        self.exact_law, self.polishing = not resume, True
        try:
            self.set_law(s, d)
        finally:
            self.exact_law, self.polishing = False, False
        self.solve(F, y, rtol=rtol, resume=resume)
        if kept is not None:
            kept[0].copy(self.s)
            kept[1].copy(self.d)
            for vec in kept:
                vec.destroy()

    def count(self, ksp: PETSc.KSP) -> None:
        """The inner solves count themselves."""


def newton_system(problem: DiscreteProblem, kind: str, prefix: str, forcing: bool = True):
    """The Newton system object of linear solver ``kind`` (``direct``, ``gamg``, ``bcgs``,
    ``hp_patch``)."""
    if kind == "hp_patch":
        system = ReducedNewtonSystem(problem, prefix, forcing)
        system.pc_setup = problem.patch_preconditioner()
        return system
    if kind == "gamg":
        return ReducedNewtonSystem(problem, prefix, forcing)
    return AssembledSystem(problem)
