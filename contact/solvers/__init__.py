"""Solvers of the discrete contact problem (docs/theory.md §3–4, §8): they take a
:class:`~contact.solvers.problem.DiscreteProblem` and options, never a scene.  The drivers
that build a scene's problem and run them live above, in :mod:`contact.drivers`.

* :mod:`.problem` — the discrete problem every model produces and every solver takes
  (:class:`~.problem.DiscreteProblem`, :class:`~.problem.Constraint`, friction's
  :class:`~.problem.FrictionSet`), and the NCP scaling;
* :mod:`.ncp` — complementarity functions φ (fb, min, blend) and their generalized
  derivatives;
* :mod:`.newton` — semismooth Newton on Φ(x) = 0 through PETSc SNES, with the
  generalized-Jacobian callback; :mod:`.polish` — active-set polishing of its steps;
  :mod:`.globalize` — line searches and the cycle guard; :mod:`.lcp` — small LCPs;
* :mod:`.friction` — the tangential rows of Tresca / Coulomb friction and their block
  Jacobian H = B K + D (frictional problems only);
* :mod:`.floating` — rigid motions of elastic bodies that no condition holds (K singular);
* :mod:`.vi` — PETSc's VI solvers (vinewtonrsls, vinewtonssls) as baselines;
* :mod:`.linear` — the linear solver of each step; :mod:`.reduced` — the symmetric
  reduction of the diagonal law solved by CG + GAMG;
* :mod:`.options` — :class:`~.options.SolverOptions` (the typed knobs of a solve) and PETSc
  options (each linear solver's defaults);
* :mod:`.snes` — :class:`~.snes.SemismoothNewton` (it owns its SNES, options prefix and
  Newton system) and one solve from an initial guess; :mod:`.result` — its outcome.
"""

from .linear import default_linear_solver
from .options import DEFAULT_PETSC_OPTIONS, ELASTICITY_3D_PETSC_OPTIONS, method_variant
from .result import Result, newton_text, owned_residual, solves_text

__all__ = [
    "DEFAULT_PETSC_OPTIONS",
    "ELASTICITY_3D_PETSC_OPTIONS",
    "Result",
    "default_linear_solver",
    "method_variant",
    "newton_text",
    "owned_residual",
    "solves_text",
]
