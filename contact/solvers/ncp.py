"""Complementarity (NCP) functions and elements of their generalized derivatives
(docs/theory.md §3).

For a, b ∈ R:   a ≥ 0, b ≥ 0, a·b = 0   ⇔   φ(a, b) = 0,   for each φ below.

==========  =====================================  =====================================
name        φ(a, b)                                element (∂_a φ, ∂_b φ) returned
==========  =====================================  =====================================
``fb``      a + b − √(a² + b²)  (Fischer–Burmeister) (1 − a/r, 1 − b/r), r = √(a² + b²);
                                                     at r = 0: (1 − 1/√2, 1 − 1/√2)
``min``     min(a, b)  (natural residual)          (1, 0) if a < b or a = b = 0,
                                                     (0, 1) otherwise
``blend``   (1 − μ) φ_fb + μ φ_min, μ ∈ (0, 1)     the same convex combination
==========  =====================================  =====================================

Choices at the kinks (deterministic, documented, tested):

* FB at the biactive point (0, 0): ∂φ_FB(0, 0) = {(1 − α, 1 − β) : α² + β² ≤ 1}; we take
  α = β = 1/√2, the limit of the derivative along the diagonal a = b ↓ 0, which treats the
  gap and the pressure symmetrically.
* min at a tie a = b ≠ 0: we take (0, 1), i.e. the node is *inactive* (the equilibrium row
  is kept).  With a = g − u and b = −cλ this is the primal–dual active set rule of
  Hintermüller–Ito–Kunisch (2002): active ⇔ −cλ_i > g_i − u_i, strictly.
* min at the biactive point a = b = 0 — the node touches with zero pressure — we take
  (1, 0): the node is *in contact* (its gap row is kept), where the strict rule would drop
  it.  At a cold start two bodies that touch (or a body on a plane it touches) have every
  contact node there; a body held by contact alone (two_body_patch_2d's upper block, the
  stack's lower block) would then have no node holding it, and the first Newton system
  would be singular: its step a round-off direction, after which Newton-min cycled on the
  stack and never converged on the patch.  Active at (0, 0), the first step is the linear
  problem of "everything touching stays in contact", regular, and PDAS goes on from there.

Ties within round-off.  A node touching the obstacle with zero pressure has (a, b) = (0, 0)
only up to round-off: b comes from a residual whose last bits depend on the summation
order, i.e. on the MPI partition, and the element of (0, ±10⁻¹⁷) would be (1, 0) or (1, 2)
by its sign alone (hertz_2d took 9 Newton steps on one rank and 8 on two).  So a kink is
decided with a tolerance τ ≥ 0: FB takes the biactive element where r = √(a² + b²) ≤ τ, min
(and the active set) the tie element where |a − b| ≤ τ and the biactive one where
|a|, |b| ≤ τ, i.e. active ⇔ b − a > τ or max(|a|, |b|) ≤ τ.  The solver uses
τ = :data:`TIE_RTOL` × max(max_i |a_i|, max_i |b_i|, s), the largest gap or scaled
multiplier over all constrained nodes of all ranks at the iterate, or s if larger
(:meth:`contact.solvers.newton.Complementarity.tie_tolerance`): far above round-off
(≈ 10⁻¹⁶ of that scale), far below any value Newton resolves.  s is the size of what the
gaps are computed from (:attr:`contact.solvers.problem.Constraint.scale`: max |X| over the mesh for
gaps between node coordinates, 0 for gaps given as data): two bodies that touch at a cold
start have every a_i = ±10⁻¹⁶ (coordinate round-off, its sign set by the partition) and
every b_i = 0, so without s the scale itself was round-off and two_body_stack_2d began with
21, 23, 21 or 1 active nodes on 1–4 ranks.  With τ = 0 the elements are the exact ones
above.

Each function exists for NumPy arrays (``phi``/``dphi``, used by the solver and tests)
and for UFL operands (``phi_ufl``, used in forms), from the same formulas.
"""

from __future__ import annotations

from typing import Any

import numpy as np

METHODS = ("fb", "min", "blend")
_BIACTIVE = 1.0 - 1.0 / np.sqrt(2.0)
TIE_RTOL = 1e-12  # relative tolerance of a kink (see the module doc)


def phi_fb(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """φ_FB(a, b) = a + b − √(a² + b²), evaluated without cancellation or overflow.

    Where a + b > 0 the algebraically equal form 2ab / (a + b + r) is used, written with
    lo = min(a, b), hi = max(a, b), q = lo / hi ∈ (−1, 1] as 2 lo / (1 + q + √(1 + q²)):
    full relative accuracy from the smallest subnormal to the largest float.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        q = np.where(hi > 0, lo / np.where(hi > 0, hi, 1.0), 0.0)
        stable = 2.0 * lo / (1.0 + q + np.sqrt(1.0 + q * q))
        plain = a + b - np.hypot(a, b)  # a + b ≤ 0: no cancellation
    return np.where(a + b > 0, stable, plain)


def dphi_fb(a: np.ndarray, b: np.ndarray, tol: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Element (∂_a φ, ∂_b φ) of the generalized derivative of φ_FB (see module doc); the
    biactive element where r = √(a² + b²) ≤ ``tol``.

    a/r and b/r are formed after scaling by m = max(|a|, |b|), so neither subnormal nor
    huge operands lose the direction (a, b)/r.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    m = np.maximum(np.abs(a), np.abs(b))
    safe = np.where(m > 0, m, 1.0)
    an, bn = a / safe, b / safe
    r = np.hypot(an, bn)
    kink = (m == 0) | (m * r <= tol)
    da = np.where(kink, _BIACTIVE, 1.0 - an / np.where(kink, 1.0, r))
    db = np.where(kink, _BIACTIVE, 1.0 - bn / np.where(kink, 1.0, r))
    return da, db


def phi_min(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """φ_min(a, b) = min(a, b) = a − max(0, a − b)."""
    return np.minimum(np.asarray(a, dtype=float), np.asarray(b, dtype=float))


def active_min(a: np.ndarray, b: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """The active rows of φ_min: b − a > ``tol``, or the biactive point |a|, |b| ≤ ``tol``
    (a node that touches with zero pressure is in contact); other ties inactive."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return (b - a > tol) | ((np.abs(a) <= tol) & (np.abs(b) <= tol))


def dphi_min(a: np.ndarray, b: np.ndarray, tol: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Element of ∂φ_min: (1, 0) on the rows of :func:`active_min`, else (0, 1)."""
    active = active_min(a, b, tol)
    return active.astype(float), (~active).astype(float)


def phi(a: np.ndarray, b: np.ndarray, method: str, mu: float = 0.5) -> np.ndarray:
    """φ of ``method`` ∈ {fb, min, blend}; ``mu`` is the blend weight of φ_min."""
    if method == "fb":
        return phi_fb(a, b)
    if method == "min":
        return phi_min(a, b)
    if method == "blend":
        return (1.0 - mu) * phi_fb(a, b) + mu * phi_min(a, b)
    raise ValueError(f"unknown NCP function {method!r}; expected one of {', '.join(METHODS)}")


def dphi(
    a: np.ndarray, b: np.ndarray, method: str, mu: float = 0.5, tol: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Generalized-derivative element (∂_a φ, ∂_b φ) of ``method``; kinks within ``tol``
    take the documented tie / biactive element."""
    if method == "fb":
        return dphi_fb(a, b, tol)
    if method == "min":
        return dphi_min(a, b, tol)
    if method == "blend":
        (fa, fb_), (ma, mb) = dphi_fb(a, b, tol), dphi_min(a, b, tol)
        return (1.0 - mu) * fa + mu * ma, (1.0 - mu) * fb_ + mu * mb
    raise ValueError(f"unknown NCP function {method!r}; expected one of {', '.join(METHODS)}")


def phi_ufl(a: Any, b: Any, method: str, mu: float = 0.5) -> Any:
    """The same φ for UFL operands (for forms, e.g. vertex-quadrature residuals).

    UFL's derivative of √(a² + b²) is undefined at (0, 0), which is why the solver's
    Jacobian is the explicit element :func:`dphi` rather than ``ufl.derivative`` of this.
    """
    import ufl

    fb = a + b - ufl.sqrt(a * a + b * b)
    mn = ufl.min_value(a, b)
    if method == "fb":
        return fb
    if method == "min":
        return mn
    if method == "blend":
        return (1.0 - mu) * fb + mu * mn
    raise ValueError(f"unknown NCP function {method!r}; expected one of {', '.join(METHODS)}")
