"""Penalty and augmented Lagrangian on a problem's nodal constraint set: two bodies through
the mortar gap (docs/theory.md §1.5, §10).

Where the constraint is a bound on one unknown per node — the mortar change of basis u = Q x
makes x_{i,n} the weighted relative normal displacement of slave node i, x_{i,n} ≤ g_i with the
dual-mortar weight w_i = D_ii (:func:`contact.models.contacts.mortar_set`) — the penalty and the
augmented Lagrangian of :mod:`.baselines` are algebraic, node by node, in the problem's own
unknowns:

    F(x) = K̃ x − b̃ + Σ_i w_i (p_i e_{i,n} + q_i · e_{i,t}) = 0,
    p_i = [μ_i + k_i (x_{i,n} − g_i)]₊,   q_i = [ν_i + k_i s_i]_ρ,   s_i = x_{i,t} − x_{i,t}^prev,

with k_i = κ₀ s_i the nodal ε (penalty, μ = ν = 0) or r (augmented Lagrangian, Uzawa's
μ ← p, ν ← q after each inner solve), s_i = E/h at the node (:func:`.baselines.nodal_scaling`
of the slave surfaces), ρ = F p_i (Coulomb) or Tresca's threshold and [·]_ρ the projection
onto the ball of radius ρ.  It is the vertex-quadrature penalty of :mod:`.baselines` with the
mortar gap in place of d(u) − g: at the same ε₀ the same O(1/ε₀) penetration and pressure
error, and Uzawa's fixed point is the NCP methods' discrete solution.  The nodal multiplier
is λ_i = R_i / w_i = −p_i, as the NCP methods report it.  The Jacobian is K̃ plus one block
per contact node: w k H(p) on the normal row; on the tangential rows w k I in stick, and in
slip w (ρ k / |z|)(I − ẑ ẑᵀ) with, for Coulomb, w F k ẑ in the normal column (not symmetric).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base.lifetime import Owner
from ..base.timing import Stopwatch, Timer
from .baselines import EnforcedNewton, nodal_scale, result_of
from .options import SolverOptions
from .problem import DiscreteProblem, newton_max_it
from .result import Result
from .snes import ROUNDOFF

#: the methods this module solves
NODAL_METHODS = ("penalty", "augmented_lagrangian")


@dataclass
class NodalContact:
    """What the Newton driver reads of the constraint: the problem's K̃, b̃, the Dirichlet
    conditions on the unknowns, the near-nullspace, and whether there is friction."""

    K: PETSc.Mat
    b: PETSc.Vec
    bcs: list
    near_nullspace: PETSc.NullSpace | None
    friction: Any


class NodalFormulation:
    """The penalty or augmented-Lagrangian term of a :class:`.DiscreteProblem` whose
    constraint is x_i ≤ g_i at nodes (sign +1): its residual and tangent at x, Uzawa's step.

    Args:
        problem: the problem (affine, sign +1: a mortar or rotated constraint set).
        method: ``penalty`` or ``augmented_lagrangian``.
        value: ε₀ or r₀.
        scale: s_i = E/h at the constrained nodes (stress per length).
    """

    def __init__(self, problem: DiscreteProblem, method: str, value: float, scale: np.ndarray):
        if method not in NODAL_METHODS:
            raise ValueError(f"method: {method!r} is not one of {', '.join(NODAL_METHODS)}")
        con = problem.constraint
        if con.sign != 1.0:
            raise ValueError("NodalFormulation: expects constraints x_i ≤ g_i (sign +1)")
        self.problem, self.method, self.value = problem, method, float(value)
        self.k = self.value * np.asarray(scale, dtype=float)
        self.contact = NodalContact(
            problem.K, problem.b, problem.bcs, problem.near_nullspace, problem.friction
        )
        fs = problem.friction
        n = len(con.dofs)
        self.mu = np.zeros(n)
        self.nu = np.zeros((n, fs.m)) if fs is not None else np.zeros((n, 0))
        self.symmetric = fs is None or fs.law == "tresca"
        self.x: np.ndarray = np.zeros(0)  # the current iterate's owned unknowns

    # --- the law at the nodes ----------------------------------------------------------------
    def normal(self, x: np.ndarray) -> np.ndarray:
        """z_i = μ_i + k_i (x_{i,n} − g_i), the argument of [·]₊ (owned unknowns ``x``)."""
        con = self.problem.constraint
        return self.mu + self.k * (x[con.dofs] - con.g)

    def tangential(self, x: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, ...]:
        """(z, ρ, q): z_i = ν_i + k_i s_i (0 on fixed components), the bound ρ_i and
        q_i = [z_i]_ρ."""
        fs = self.problem.friction
        assert fs is not None, "a frictional problem"
        slip = np.where(fs.free, x[fs.tangent] - fs.x_prev, 0.0)
        z = np.where(fs.free, self.nu + self.k[:, None] * slip, 0.0)
        rho = fs.coefficient * p if fs.law == "coulomb" else np.asarray(fs.threshold, float)
        size = np.linalg.norm(z, axis=1)
        slip = size > rho
        factor = np.where(slip, rho / np.where(slip, size, 1.0), 1.0)
        return z, rho, z * factor[:, None]

    def force(self, x: np.ndarray) -> np.ndarray:
        """The nodal contact force −w (p e_n + q · e_t) at x: K̃ x − b̃ at the solution
        (owned entries, 0 off the contact nodes)."""
        p = self.problem
        con = p.constraint
        out = np.zeros(len(x))
        pressure = np.maximum(self.normal(x), 0.0)
        out[con.dofs] = -con.w * pressure
        if p.friction is not None:
            q = self.tangential(x, pressure)[2]
            fs = p.friction
            out[fs.tangent] = np.where(fs.free, -con.w[:, None] * q, 0.0)
        return out

    def jacobian_blocks(self, x: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """The tangent's contact entries: (rows, cols, values), owned local indices."""
        p = self.problem
        con, fs = p.constraint, p.friction
        z_n = self.normal(x)
        on = z_n > 0.0
        w, k = con.w, self.k
        out = [(con.dofs, con.dofs, np.where(on, w * k, 0.0))]
        if fs is None:
            return out
        z, rho, _ = self.tangential(x, np.maximum(z_n, 0.0))
        size = np.linalg.norm(z, axis=1)
        slip = size > rho
        m = fs.m
        safe = np.where(slip, size, 1.0)  # |z| > ρ ≥ 0 where it divides
        zhat = np.where(slip[:, None], z / safe[:, None], 0.0)
        eye = np.eye(m)[None]
        stick_block = eye * k[:, None, None]
        slip_block = np.where(slip, rho * k / safe, 0.0)[:, None, None] * (
            eye - zhat[:, :, None] * zhat[:, None, :]
        )
        tt = np.where(slip[:, None, None], slip_block, stick_block) * w[:, None, None]
        free = fs.free
        tt = tt * free[:, :, None] * free[:, None, :]
        rows = np.repeat(fs.tangent, m, axis=1).reshape(-1, m, m)
        cols = np.repeat(fs.tangent[:, None, :], m, axis=1)
        out.append((rows.ravel(), cols.ravel(), tt.ravel()))
        if fs.law == "coulomb":  # ∂q/∂x_n = F k H(z_n) ẑ in slip
            tn = np.where(
                (slip & on)[:, None], w[:, None] * fs.coefficient * k[:, None] * zhat, 0.0
            )
            tn = tn * free
            out.append((fs.tangent.ravel(), np.repeat(con.dofs, m), tn.ravel()))
        return out

    def in_contact(self, x: np.ndarray) -> np.ndarray:
        """Whether each constrained node is in contact: z_i > 0."""
        return self.normal(x) > 0.0

    def update_multipliers(self) -> tuple[float, float, float]:
        """One Uzawa step at the current iterate: μ ← p, ν ← q; returns (the largest change,
        max μ, the round-off floor 16 ε max k max|x|) over all ranks."""
        x, comm = self.x, self.problem.V.mesh.comm
        p = np.maximum(self.normal(x), 0.0)
        change = float(np.max(np.abs(p - self.mu), initial=0.0))
        if self.problem.friction is not None:
            q = self.tangential(x, p)[2]
            change = max(change, float(np.max(np.abs(q - self.nu), initial=0.0)))
            self.nu = q
        self.mu = p
        size = float(np.max(p, initial=0.0))
        top = float(np.max(self.k, initial=0.0)) * float(np.max(np.abs(x), initial=0.0))
        floor = ROUNDOFF * np.finfo(float).eps * top
        return (
            comm.allreduce(change, op=MPI.MAX),
            comm.allreduce(size, op=MPI.MAX),
            comm.allreduce(floor, op=MPI.MAX),
        )


class NodalNewton(EnforcedNewton):
    """:class:`.EnforcedNewton` on a :class:`NodalFormulation`: the contact term assembled
    node by node in the problem's unknowns instead of from UFL forms."""

    form: NodalFormulation  # type: ignore[assignment]

    def space(self) -> fem.FunctionSpace:
        return self.form.problem.V

    def prepare(self, owner: Owner) -> None:
        lo = self.form.contact.K.getOwnershipRange()[0]
        self._lo = lo

    def max_it(self) -> int:
        """The Newton step limit (``solver.max_it``; ``auto``: by the problem's constrained
        nodes across the slave surfaces, :meth:`.DiscreteProblem.nodes_across`; collective)."""
        if self.opts.max_it != "auto":
            return int(self.opts.max_it)
        return newton_max_it(self.opts.max_it, self.form.problem.nodes_across())

    def _set_iterate(self, x: PETSc.Vec) -> None:
        self.form.x = x.array_r.copy()

    def add_contact(self, F: PETSc.Vec) -> None:
        F.array_w[:] -= self.form.force(self.form.x)

    def _jacobian(self, snes: PETSc.SNES, x: PETSc.Vec, J: PETSc.Mat, P: PETSc.Mat) -> None:
        with Timer(self.timers, "assembly"):
            self._set_iterate(x)
            self.form.contact.K.copy(J, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)  # type: ignore[arg-type]
            J.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)  # type: ignore[arg-type]
            add = PETSc.InsertMode.ADD_VALUES
            for rows, cols, values in self.form.jacobian_blocks(self.form.x):
                for i, j, v in zip(rows + self._lo, cols + self._lo, values):
                    if v != 0.0:
                        J.setValue(int(i), int(j), float(v), addv=add)  # type: ignore[arg-type]
            J.assemble()
            self._k_norm = float(J.norm(PETSc.NormType.INFINITY))  # type: ignore[arg-type]

    def contact_nodes(self) -> int:
        x = self.form.x if len(self.form.x) else self.form.problem.b.array_r
        local = int(np.count_nonzero(self.form.in_contact(x)))
        return self.comm.allreduce(local, op=MPI.SUM)


def mortar_scale(problem: DiscreteProblem, measure: ufl.Measure, modulus: Any) -> np.ndarray:
    """s_i = E/h at the constrained nodes: :func:`.baselines.nodal_scale` of ``measure`` (the
    slave surfaces, and a rigid obstacle's contact facets) on the first component's space."""
    V = problem.V
    S, to_parent = V.sub(0).collapse()
    s = nodal_scale(measure, modulus, S)
    bs = V.dofmap.index_map_bs
    node_values = np.ones(V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts)
    node_values[np.asarray(to_parent) // bs] = s.x.array
    return node_values[problem.constraint.dofs // bs]


def solve_nodal(
    problem: DiscreteProblem,
    scale: np.ndarray,
    options: SolverOptions,
    verbose: bool = False,
    timers: dict | None = None,
    clock: Stopwatch | None = None,
) -> Result:
    """Solve ``problem`` by ``options.method`` (penalty or augmented Lagrangian) from the
    iterate in ``problem.u_h`` (displacements, Dirichlet values in place) and return its
    :class:`Result`: λ_h the method's nodal multiplier −p_i, active the nodes with z_i > 0.

    Args:
        problem: an affine problem with a nodal constraint set x_i ≤ g_i.
        scale: s_i = E/h at its constrained nodes (:func:`mortar_scale`).
        options: the solver options (``epsilon0`` / ``r0``, Uzawa's and Newton's).
        verbose: print the Newton iterations.
        timers: the timings to add to.
        clock: the solve's clock.
    """
    method = options.method
    value = float(options.epsilon0 if method == "penalty" else options.r0)
    timers = {"assembly": 0.0, "solve": 0.0} if timers is None else timers
    clock = Stopwatch() if clock is None else clock
    form = NodalFormulation(problem, method, value, scale)
    x = problem.b.duplicate()
    problem.to_unknowns(problem.u_h.x.petsc_vec, x)
    try:
        with NodalNewton(form, options, verbose, timers) as newton:  # type: ignore[arg-type]
            outcome = newton.solve(x)
        problem.to_displacement(x, problem.u_h.x.petsc_vec)
        problem.u_h.x.scatter_forward()
        xa = x.array_r.copy()
    finally:
        x.destroy()
    active = form.in_contact(xa)
    return result_of(problem, form.force(xa), xa, active, outcome, options, timers, clock)
