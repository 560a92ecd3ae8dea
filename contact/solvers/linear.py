"""The linear solver of each Newton step: PETSc options chosen by problem kind.

MUMPS LU, except BiCGStab + GAMG with the rigid-body near-nullspace for 3D elasticity.
Measured on the final hertz_3d mesh (185679 DoFs, fb from u = 0, 16 Newton steps each):
87 s against 219 s for MUMPS; in 2D (hertz_2d, 13650 DoFs) MUMPS is faster (0.30 s
against 0.46 s).  ``solver.petsc_options`` overrides any of these keys.
"""
from __future__ import annotations

from petsc4py import PETSc

from ..models import DiscreteProblem

DEFAULT_PETSC_OPTIONS = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
ELASTICITY_3D_PETSC_OPTIONS = {"ksp_type": "bcgs", "pc_type": "gamg", "ksp_rtol": 1e-10}


def default_linear_solver(problem: DiscreteProblem) -> dict:
    """MUMPS LU, except Krylov + GAMG for 3D elasticity (faster there; see the figures above)."""
    model = "elasticity" if problem.near_nullspace is not None else "scalar"
    return default_options(model, problem.V.mesh.geometry.dim)


def default_options(model: str, gdim: int) -> dict:
    """The default PETSc options of a model type (``elasticity`` or another) in ``gdim``
    dimensions, known before the problem is built (for checking the user's options)."""
    if model == "elasticity" and gdim == 3:
        return dict(ELASTICITY_3D_PETSC_OPTIONS)
    return dict(DEFAULT_PETSC_OPTIONS)


def attach_near_nullspace(problem: DiscreteProblem, J: PETSc.Mat) -> None:
    """Rigid-body modes for GAMG on elasticity (kept by J across its re-copies)."""
    if problem.near_nullspace is not None:
        J.setNearNullSpace(problem.near_nullspace)
