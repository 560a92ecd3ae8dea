"""``solver.line_search: energy`` — globalized Newton steps for a problem with an energy
(a hyperelastic body), nonconvex laws included (issue 31).

The Newton step y (x → x − y, PETSc's sign) comes from :class:`.curvature.CurvatureSystem`:
the exact semismooth Newton step where the reduced tangent A is positive definite, a step
of the shifted tangent A_τ = A + τ D where it is not.  This pre-check of the line search
then decides how much of it to take:

1. a Newton step of a definite tangent that lowers ‖Φ‖ by the Armijo factor and inverts
   no matter is taken whole (near a solution this is Newton's method, its local rate
   kept; a polished step, which already lowered ‖Φ‖, likewise);
2. otherwise backtracking t = 1, ½, … ≥ :data:`MIN_STEP` on the merit

       θ_ρ(x) = Π(x) + ρ Σ_{i ∈ C} w_i |φ(a_i, b_i)|,     ρ ≥ 2 max_i |λ_i|,

   Π the total potential (energy) and the second term the contact constraint measured
   by the NCP function itself (a gap, times the weight w_i and a pressure ρ: an energy),
   with the Armijo condition θ_ρ(x − t y) ≤ θ_ρ(x) + ARMIJO t θ'.  θ is the ℓ₁ exact
   penalty merit of SQP (Han, JOTA 22, 1977; Nocedal & Wright §15.4): on the active set
   φ is the gap (the penetration), elsewhere the scaled multiplier.  Its slope along the
   step, θ' = −R(x)·y − ρ Σ w_i |φ_i|, is negative for a step of a positive definite
   (shifted) A once ρ exceeds the multipliers (R = ∂Π/∂x; the contact rows keep the
   exact linearization of φ, so the second term falls at the rate −ρ Σ w_i |φ_i|); ρ only
   grows within a solve.  Π = +∞ where a step inverts matter (det F ≤ 0 at a quadrature
   point, :meth:`contact.models.forms.ResidualProblem.admissible`: no deformation does,
   whatever the law — St Venant–Kirchhoff's ψ is finite there, zero for a reflection,
   and plain Newton on SVK converges to such states), and θ = NaN rejects a step too;
3. where that fails (θ' ≥ 0, θ' below θ's round-off, or no t ≥ MIN_STEP decreases θ
   enough) the step backtracks on ½‖Φ‖² instead (:func:`.globalize.backtrack`, inverting
   steps rejected); if no step keeps the matter whole the solve stops
   (``diverged_line_search``, :attr:`stalled`): past a material limit point (SVK in strong
   compression) the only equilibria nearby may invert cells, or the only admissible one is
   the unstable branch the search left (a load path then follows that branch by plain
   Newton and reports it: :func:`contact.drivers.load_path.follow_branch`);
4. when A had negative eigenvalues, from the point reached, a step along the direction of
   negative curvature v (:meth:`.curvature.CurvatureSystem.negative_direction`) with
   the sign that descends (R·v, or the fixed field's sign on a symmetric saddle): its
   length starts at :data:`CURVATURE_LENGTH` times the body's size and doubles while θ
   keeps falling (up to a quarter of the size), or halves until θ falls; without a
   decrease no such step is taken.

Every Newton iteration where the tangent was not definite, or a step was shortened, is one
entry of ``log`` (iteration, negative eigenvalues, τ, t, the curvature μ₁ and the length of
the curvature step, the merit used): the load path reports them per step
(:mod:`contact.drivers.load_path`).  ``line_search: basic`` keeps plain Newton (the
factorization is then MUMPS LU of the assembled H, as before).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..base.norms import norm2
from ..base.timing import Timer
from .curvature import CurvatureSystem
from .globalize import backtrack

if TYPE_CHECKING:
    from .newton import Complementarity
    from .polish import Polisher

ARMIJO = 1e-4  # sufficient decrease, as in .globalize
MIN_STEP = 2.0**-12  # the energy backtracking stops below this step length
RHO_FACTOR = 2.0  # ρ = RHO_FACTOR · the largest multiplier |λ_i| (at least)
ROUNDOFF = 1e-12  # θ' below this fraction of |θ| is round-off: the ‖Φ‖ backtracking decides
CURVATURE_LENGTH = 1e-3  # the first curvature step, relative to the body's size
CURVATURE_MAX = 0.25  # the longest one, relative to the body's size
CURVATURE_HALVINGS = 10


class EnergySearch:
    """The line-search pre-check of ``line_search: energy`` (module doc).  ``size`` is the
    body's size (the diagonal of its bounding box, in the units of x); ``polisher``: fb /
    blend's active-set polishing, tried first."""

    def __init__(
        self,
        cp: Complementarity,
        method: str,
        mu: float,
        system: CurvatureSystem,
        timers: dict,
        size: float,
        polisher: Polisher | None = None,
    ):
        self.cp, self.method, self.mu, self.system = cp, method, mu, system
        self.timers, self.size, self.polisher = timers, size, polisher
        b = cp.p.b
        self.W, self.F, self.F0, self.R0, self.d = (b.duplicate() for _ in range(5))
        self.comm = b.getComm().tompi4py()
        self.log: list[dict] = []
        self.restart()

    def restart(self) -> None:
        """A new solve: ρ from zero, iterations from 0, an empty log."""
        self.rho, self.iteration, self.log = 0.0, 0, []
        self.fnorm = np.nan  # ‖Φ‖ of the current iterate, told by the solver's monitor
        self.stalled = False  # no admissible step: the solve stops (diverged_line_search)

    # -- the merit -------------------------------------------------------------------------
    def _phi_norm(self, W: PETSc.Vec) -> float:
        """‖Φ(W)‖ (Φ left in self.F, R(W) in cp.R)."""
        self.cp.phi(W, self.F, self.method, self.mu)
        return norm2(self.F)

    def _violation(self, F: PETSc.Vec) -> float:
        """Σ_C w_i |φ_i| = Σ_C c_i |Φ_i| of Φ = F (collective)."""
        cp = self.cp
        local = float(np.sum(np.asarray(cp.c) * np.abs(F.array_r[cp.dofs])))
        return self.comm.allreduce(local, op=MPI.SUM)

    def _theta(self, W: PETSc.Vec) -> float:
        """θ_ρ(W) (NaN → inf: a step into inverted cells is rejected)."""
        self._phi_norm(W)
        value = self.cp.p.energy(W) + self.rho * self._violation(self.F)
        return value if np.isfinite(value) else np.inf

    def _at(self, x: PETSc.Vec, y: PETSc.Vec, t: float) -> PETSc.Vec:
        """W = x − t y."""
        x.copy(self.W)
        self.W.axpy(-t, y)
        return self.W

    # -- the pre-check ---------------------------------------------------------------------
    def __call__(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        it = self.iteration
        self.iteration += 1
        polisher = self.polisher
        if polisher is not None:
            polisher(x, y)
        with Timer(self.timers, "assembly"):
            self._search(x, y, it)

    def _search(self, x: PETSc.Vec, y: PETSc.Vec, it: int) -> None:
        """The step y of Newton iteration ``it`` from x: taken whole, shortened, or bent
        along negative curvature (module doc)."""
        polisher, sy = self.polisher, self.system
        definite = not sy.shift
        if definite and polisher is not None and polisher.accepted:
            return
        if definite and not np.isnan(self.fnorm):
            # Newton's own step where it lowers ‖Φ‖ enough, or where x already meets SNES's
            # stopping test (a step forced from a solution: round-off either way); ‖Φ(x)‖ is
            # the monitor's (SemismoothNewton._monitor), one residual saved
            W = self._at(x, y, 1.0)
            good = max((1.0 - ARMIJO) * self.fnorm, sy.stop)
            if self._phi_norm(W) <= good and self.cp.p.admissible(W):
                return
        f0 = self._phi_norm(x)
        self.cp.R.copy(self.R0)
        self.F.copy(self.F0)
        event: dict = {"iteration": it, "negative": sy.negative, "shift": sy.shift}
        t, merit = self._energy_step(x, y, f0)
        if merit == "residual":
            t = backtrack(self._residual_merit(x, y), 0.5 * f0**2)
            if not self.cp.p.admissible(self._at(x, y, t)):  # no t keeps the matter whole
                t, merit = 0.0, "none"
                self.stalled = True
        if t != 1.0:
            y.scale(t)
        event.update(t=t, merit=merit)
        if not definite:
            event.update(self._curvature_step(x, y))
        self.log.append(event)

    def _energy_step(self, x: PETSc.Vec, y: PETSc.Vec, f0: float) -> tuple[float, str]:
        """(t, "energy") of the Armijo backtracking on θ_ρ, or (1, "residual") where the
        energy cannot decide (module doc, 2–3).  R(x) is in self.R0, Φ(x) in self.F0."""
        cp = self.cp
        lam = np.abs(self.R0.array_r[cp.dofs]) / cp.w
        largest = self.comm.allreduce(float(np.max(lam, initial=0.0)), op=MPI.MAX)
        self.rho = max(self.rho, RHO_FACTOR * largest)
        violation = self._violation(self.F0)
        theta0 = cp.p.energy(x) + self.rho * violation
        slope = -float(self.R0.dot(y).real) - self.rho * violation
        if not (np.isfinite(theta0) and slope < -ROUNDOFF * abs(theta0)):
            return 1.0, "residual"
        t = 1.0
        while t >= MIN_STEP:
            if self._theta(self._at(x, y, t)) <= theta0 + ARMIJO * t * slope:
                return t, "energy"
            t *= 0.5
        return 1.0, "residual"

    def _residual_merit(self, x: PETSc.Vec, y: PETSc.Vec) -> Callable[[float], float]:
        def merit(t: float) -> float:
            W = self._at(x, y, t)
            value = 0.5 * self._phi_norm(W) ** 2
            return value if np.isfinite(value) and self.cp.p.admissible(W) else np.inf

        return merit

    def _curvature_step(self, x: PETSc.Vec, y: PETSc.Vec) -> dict:
        """From W = x − y (y already scaled), a step α d along the direction of negative
        curvature that lowers θ_ρ (module doc, 4); y becomes y − α d.  Returns the log's
        fields: μ₁ and the step's largest nodal component (0: none taken)."""
        sy = self.system
        v = sy.negative_direction()
        if v is None:
            return {"curvature": sy.curvature, "along": 0.0, "inverse_its": sy.inverse_iterations}
        W0 = self.W.duplicate()
        self._at(x, y, 1.0).copy(W0)
        theta_w = self._theta(W0)
        slope = float(self.cp.R.dot(v).real)  # R(W)·v
        if abs(slope) > 1e-8 * norm2(self.cp.R) * norm2(v):
            sign = -np.sign(slope)
        else:  # a symmetric saddle: R·v is round-off; the fixed field decides
            sign = 1.0 if sy.orientation(v) >= 0 else -1.0
        v.copy(self.d)
        top = float(v.norm(PETSc.NormType.INFINITY))  # type: ignore[arg-type]
        self.d.scale(sign / top)  # ‖d‖_∞ = 1

        def theta(alpha: float) -> float:
            W0.copy(self.W)
            self.W.axpy(alpha, self.d)
            return self._theta(self.W)

        alpha = CURVATURE_LENGTH * self.size
        best, best_alpha = theta(alpha), alpha
        if best < theta_w:  # expand while θ falls
            while 2 * alpha <= CURVATURE_MAX * self.size:
                value = theta(2 * alpha)
                if not value < best:
                    break
                alpha *= 2
                best, best_alpha = value, alpha
        else:  # shrink until θ falls
            best_alpha = 0.0
            for _ in range(CURVATURE_HALVINGS):
                alpha *= 0.5
                if theta(alpha) < theta_w:
                    best_alpha = alpha
                    break
        W0.destroy()
        if best_alpha:
            y.axpy(-best_alpha, self.d)  # x − y = W + α d
        return {
            "curvature": sy.curvature,
            "along": best_alpha,
            "inverse_its": sy.inverse_iterations,
        }

    def destroy(self) -> None:
        for obj in (self.W, self.F, self.F0, self.R0, self.d):
            obj.destroy()
        if self.polisher is not None:
            self.polisher.destroy()
        self.cp = self.system = self.polisher = None  # type: ignore[assignment]


def tangent_figures(log: list[dict]) -> dict:
    """The figures of one solve's log for steps.csv: Newton steps with an indefinite
    tangent, the largest shift τ, curvature steps, steps shortened (t < 1)."""
    return {
        "indefinite_newton_steps": sum(1 for e in log if e["negative"]),
        "largest_shift": max((e["shift"] for e in log), default=0.0),
        "curvature_steps": sum(1 for e in log if e.get("along")),
        "shortened_steps": sum(1 for e in log if e["t"] < 1.0),
    }


def tangent_text(log: list[dict]) -> str:
    """One solve's log in one phrase ('' if Newton's steps were taken whole throughout):
    'K_T indefinite at Newton steps 0-2 (up to 6 negative eigenvalues): shifted tangent
    (tau up to 25 diag K), 1 negative-curvature step; 3 steps shortened (t >= 0.25)'."""
    if not log:
        return ""
    parts = []
    bad = [e for e in log if e["negative"]]
    if bad:
        its = [e["iteration"] for e in bad]
        where = f"{its[0]}" if len(its) == 1 else f"{its[0]}-{its[-1]}"
        what = f"shifted tangent (tau up to {max(e['shift'] for e in bad):.2g} diag K)"
        curv = sum(1 for e in bad if e.get("along"))
        if curv:
            what += f", {curv} negative-curvature step(s)"
        most = max(e["negative"] for e in bad)
        parts.append(
            f"K_T indefinite at Newton step(s) {where} (up to {most} negative eigenvalue(s)): "
            + what
        )
    short = [e for e in log if e["t"] < 1.0]
    if short:
        merits = sorted({e["merit"] for e in short})
        parts.append(
            f"{len(short)} step(s) shortened (t >= {min(e['t'] for e in short):.3g}, "
            f"merit {'/'.join(merits)})"
        )
    if any(e["merit"] == "none" for e in log):
        parts.append("no step keeps det F > 0: stopped")
    return "; ".join(parts)
