"""The Korn-type constant of the elastic bound (docs/theory.md §9.2): C_K with

    ‖skw ∇v‖ ≤ C_K ‖ε(v)‖    for every v ∈ H¹(Ω)^d vanishing where u is prescribed

(Γ_D, and the normal component on symmetry planes; skw A = (A − Aᵀ)/2).  It multiplies the
two terms of the bound that a weakly symmetric stress cannot make exact: the asymmetry
‖skw σ_h‖ and the data oscillation (through ‖∇v‖² = ‖ε(v)‖² + ‖skw ∇v‖² ≤ (1 + C_K²)‖ε(v)‖²).

C_K² is the largest eigenvalue θ of  (skw ∇u, skw ∇v) = θ (ε(u), ε(v))  over the problem's
displacement space V_h with its Dirichlet and symmetry conditions: a Rayleigh–Ritz value,
so it approaches the exact constant **from below** as the mesh is refined (it is computed,
not bounded: the one constant of the bound that is not guaranteed).  Two facts frame it:
C_K ≥ 1 on every domain (divergence-free fields with compact support have
‖skw ∇v‖ = ‖ε(v)‖; Korn's first inequality ‖∇v‖² ≤ 2‖ε(v)‖² for v ∈ H¹₀ makes 1 the exact
constant for a clamped boundary), so C_K² = max(1, θ); and θ > 1 comes from the near-rigid
rotations the boundary conditions hold only weakly — smooth eigenfunctions that coarse
meshes already resolve — though on hertz_2d the top of the discrete spectrum is a cluster
(2.94, 2.97, 2.98, 2.99 at 8k DoFs) that creeps up under refinement.  Solved by
:data:`STEPS` steps of subspace iteration with Rayleigh–Ritz on a block of
:data:`BLOCK` vectors (the stiffness factorized once by MUMPS, each step one solve with
BLOCK right-hand sides), from start vectors that are functions of the coordinates (the
same on any number of ranks).
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from petsc4py import PETSc

#: the block size and the number of steps of the subspace iteration (a fixed number, so that
#: every rank count takes the same steps: θ is the same to round-off).  C_K after 10 / 20 /
#: 40 / 80 steps: the Tresca scene (32², isolated top eigenvalue) 3.479260 for all four;
#: hertz_2d (8k DoFs, a cluster) 1.726941 / 1.728507 / 1.729408 / 1.729650 — 20 steps are
#: within 0.1 % (the asymmetry term, 4 % of η there, moves by 4e-5 of η)
BLOCK, STEPS = 4, 20


def korn_constant(V: fem.FunctionSpace, bcs: list) -> float:
    """C_K of the module docstring on V with the conditions ``bcs`` (collective)."""
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    dx = ufl.dx(domain=V.mesh)
    eps = ufl.inner(ufl.sym(ufl.grad(u)), ufl.sym(ufl.grad(v))) * dx
    skw = ufl.inner(ufl.skew(ufl.grad(u)), ufl.skew(ufl.grad(v))) * dx
    A = fem_petsc.assemble_matrix(fem.form(eps), bcs=bcs, diag=1.0)
    A.assemble()
    B = fem_petsc.assemble_matrix(fem.form(skw), bcs=bcs, diag=0.0)
    B.assemble()
    theta = _largest(A, B, _start(V))
    for mat in (A, B):
        mat.destroy()
    return float(np.sqrt(max(1.0, theta)))


def _start(V: fem.FunctionSpace) -> np.ndarray:
    """BLOCK start vectors (owned entries), smooth functions of the DoF coordinates."""
    n = V.dofmap.index_map.size_local
    bs = V.dofmap.index_map_bs
    X = V.tabulate_dof_coordinates()[:n]
    cols = []
    for k in range(BLOCK):
        vals = np.empty((n, bs))
        for c in range(bs):
            vals[:, c] = np.sin((k + 1.3) * X[:, 0] + (c + 0.7) * X[:, 1] + 0.1 * k * c) + 0.5
        cols.append(vals.ravel())
    return np.array(cols)


def _largest(A: PETSc.Mat, B: PETSc.Mat, start: np.ndarray) -> float:
    """The largest θ of B x = θ A x (A SPD, B PSD) by subspace iteration; the block is a
    dense PETSc matrix (owned rows × BLOCK), so each step is one product with B and one
    factorized solve with BLOCK right-hand sides (MUMPS: half the time of BLOCK single
    solves at 64k DoFs)."""
    comm = A.getComm().tompi4py()
    ksp = PETSc.KSP().create(A.getComm())
    ksp.setOperators(A)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("cholesky")
    pc.setFactorSolverType("mumps")
    n, N = A.getLocalSize()[0], A.getSize()[0]
    X = PETSc.Mat().createDense(((n, N), (BLOCK, BLOCK)), comm=A.getComm())
    X.setUp()
    X.getDenseArray()[:] = start.T
    X.assemble()
    Y, AX, BX = X.duplicate(), X.duplicate(), X.duplicate()
    theta = 0.0
    for _ in range(STEPS):
        B.matMult(X, Y)
        ksp.matSolve(Y, X)  # X ← A⁻¹ B X
        A.matMult(X, AX)
        B.matMult(X, BX)
        x = X.getDenseArray(readonly=True)
        Ab = comm.allreduce(x.T @ AX.getDenseArray(readonly=True))
        Bb = comm.allreduce(x.T @ BX.getDenseArray(readonly=True))
        # Rayleigh–Ritz: B_s y = θ A_s y through A_s = L Lᵀ; the Ritz vectors A-orthonormal
        Li = np.linalg.inv(np.linalg.cholesky(Ab))
        w, V = np.linalg.eigh(Li @ Bb @ Li.T)
        theta = float(w[-1])
        X.getDenseArray()[:] = x @ (Li.T @ V[:, ::-1])
        X.assemble()
    for obj in (X, Y, AX, BX, ksp):
        obj.destroy()
    return theta
