"""Solvers of the discrete contact problem (SPEC §3–4, §8).  Quasi-static load paths, which
call the adaptive loop, live above them in :mod:`contact.drivers.load_path`.

* :mod:`.ncp` — complementarity functions φ (fb, min, blend) and their generalized
  derivatives;
* :mod:`.newton` — semismooth Newton on Φ(x) = 0 through PETSc SNES, with the
  generalized-Jacobian callback; :mod:`.polish` — active-set polishing of its steps;
* :mod:`.friction` — the tangential rows of Tresca / Coulomb friction and their block
  Jacobian H = B K + D, the Coulomb fixed point (frictional scenes only);
* :mod:`.vi` — PETSc's VI solvers (vinewtonrsls, vinewtonssls) as baselines;
* :mod:`.linear` — the linear solver of each step; :mod:`.reduced` — the symmetric
  reduction of the diagonal law solved by CG + GAMG;
* :mod:`.sequencing` — grid sequencing of a single solve (coarser meshes first);
* :mod:`.options` — the ``solver`` section and PETSc options (each linear solver's defaults);
* :mod:`.solve` — one solve end to end; :mod:`.result` — its outcome.
"""
from .linear import default_linear_solver
from .options import (DEFAULT_PETSC_OPTIONS, ELASTICITY_3D_PETSC_OPTIONS, method_variant,
                      solver_options)
from .result import Result, newton_text, owned_residual, solves_text
from .snes import solve

__all__ = ["DEFAULT_PETSC_OPTIONS", "ELASTICITY_3D_PETSC_OPTIONS", "Result", "default_linear_solver",
           "method_variant", "newton_text", "owned_residual", "solve", "solver_options",
           "solves_text"]
