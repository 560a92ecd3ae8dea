"""Adaptive stopping (``solver.stopping: adaptive``): Newton and its Krylov solves stop once
their errors are small against the discretization error (Ern & Vohralík, SIAM J. Sci.
Comput. 35, 2013; for semismooth Newton on contact, Dabaghi, Martin & Vohralík, J. Sci.
Comput. 2020).  Three estimates of the energy error |||·||| (|||v|||² = ∫ k |∇v|² = vᵀ K v):

* η_disc — the discretization error: the guaranteed bound of
  :mod:`contact.adaptivity.equilibration` at the iterate.  Inside a solve the driver's
  estimate of it is used (:class:`AdaptiveStopping` ``eta_disc``: the previous level's η
  times the optimal rate (N_prev / N)^{p/d}); after the solve the driver computes η_disc at
  the final iterate and solves on if the two criteria fail against it
  (:mod:`contact.drivers.adaptive`).
* η_lin — the linearization error of the iterate x_k.  A semismooth Newton step on an
  active set A (a ``min`` step, or an fb / blend step replaced by active-set polishing) solves
  the linear problem u = g on A, R(u) = 0 elsewhere; when x_k's own active set is A again,
  x_k is the discrete solution up to the algebraic error (the primal–dual active set
  method's fixed point): η_lin = 0.  Otherwise η_lin = |||x_k − x_{k−1}|||, the energy of the
  last step (for a superlinear iteration, an over-estimate of the error of x_{k−1}, and so
  of x_k's); ∞ before any step.
* η_alg — the algebraic error of the last Krylov solve A y = r of a Newton step: CG with
  the natural norm (r, B r)^{1/2} (B the GAMG preconditioner), which is |||y − y*||| when
  B = A⁻¹ and within the spectral bounds of BA otherwise (A is K on the free rows,
  :mod:`.reduced`).

Newton stops when η_lin ≤ γ_lin η_disc, each CG solve when η_alg ≤ γ_alg (η_disc + η_lin)
(η_lin of the last iterate, 0 while it is ∞).  The defaults γ_lin = γ_alg = 0.1 make the
linearization and algebraic errors a tenth of the discretization error: the total moves by
≤ (1 + 0.1² + 0.1²)^{1/2} − 1 ≈ 1 % if the three were orthogonal (0.1 is this code's
choice, not a value copied from the papers, which were not at hand to cite).

Two departures from the papers, both for cost: η_disc is not recomputed at every Newton
and CG iterate (one bound per level, as with fixed tolerances; the prediction is checked
after the solve), and η_alg is CG's own natural norm instead of a flux built from ν extra
CG iterations.  An iterate that keeps an algebraic residual takes the complementarity
law's multiplier (0 off the active set, :func:`.result.finish`), so that the bound's
complementarity term does not weigh the residual of inactive contact rows as a force.

The solver consults this object at two places only: its Newton monitor calls
:meth:`AdaptiveStopping.newton_done` with each iterate, and the Krylov solves of the
reduced system take :meth:`AdaptiveStopping.krylov_atol` as their absolute tolerance (in
the natural norm) and report what they reached through :meth:`AdaptiveStopping.krylov_done`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from petsc4py import PETSc

#: defaults of γ_lin and γ_alg (the ``solver`` keys ``gamma_lin``, ``gamma_alg``)
GAMMA_LIN = GAMMA_ALG = 0.1


@dataclass
class AdaptiveStopping:
    """The stopping criteria of one solve (module doc).  ``eta_disc``: the discretization
    error the solve balances against."""

    eta_disc: float
    gamma_lin: float = GAMMA_LIN
    gamma_alg: float = GAMMA_ALG
    eta_lin: float = math.inf
    eta_alg: float = math.nan
    stopped: bool = False  # Newton stopped by η_lin ≤ γ_lin η_disc
    history: list[dict] = field(default_factory=list)  # per iterate: its, eta_lin, eta_alg
    _guess_active: np.ndarray | None = None

    def krylov_atol(self) -> float:
        """The absolute tolerance of a Krylov solve, natural norm: γ_alg (η_disc + η_lin)."""
        lin = self.eta_lin if math.isfinite(self.eta_lin) else 0.0
        return self.gamma_alg * (self.eta_disc + lin)

    def krylov_done(self, natural_norm: float) -> None:
        """The natural residual norm the last Krylov solve reached (η_alg)."""
        self.eta_alg = float(natural_norm)

    def start(self, active: np.ndarray) -> None:
        """The active set of the initial guess, before it is polished (a polished guess that
        keeps it is the discrete solution up to the algebraic error)."""
        self._guess_active = active

    def guess_kept(self, active: np.ndarray) -> bool:
        """Whether ``active`` (owned entries) is the guess's active set (this rank only)."""
        g = self._guess_active
        return g is not None and len(g) == len(active) and bool((g == active).all())

    def newton_done(self, its: int, same_set: bool, step_energy: float) -> bool:
        """Record iterate ``its`` and decide: ``same_set`` — the iterate came from an
        active-set step (min, or polishing) and keeps that active set (on every rank);
        ``step_energy`` — |||x_k − x_{k−1}||| (∞ for the first iterate of a cold start)."""
        self.eta_lin = 0.0 if same_set else step_energy
        self.history.append({"iteration": its, "eta_lin": self.eta_lin, "eta_alg": self.eta_alg})
        self.stopped = self.eta_lin <= self.gamma_lin * self.eta_disc
        return self.stopped

    def balanced(self, eta_disc: float) -> bool:
        """Whether the final iterate meets both criteria against the discretization error
        ``eta_disc`` computed at it (the driver's check after the solve)."""
        lin = self.eta_lin if math.isfinite(self.eta_lin) else math.inf
        alg = 0.0 if math.isnan(self.eta_alg) else self.eta_alg
        return lin <= self.gamma_lin * eta_disc and alg <= self.gamma_alg * (eta_disc + lin)


def energy_norm(K: PETSc.Mat, v: PETSc.Vec) -> float:
    """(vᵀ K v)^{1/2} (collective)."""
    w = K.createVecLeft()
    K.mult(v, w)
    out = math.sqrt(max(float(np.real(w.dot(v))), 0.0))
    w.destroy()
    return out


#: SNES's reason for a Newton iteration that adaptive stopping ended (converged: the
#: iterate is as good as the discretization allows)
STOPPED_REASON = PETSc.SNES.ConvergedReason.CONVERGED_ITS
