"""Complementarity (NCP) functions and elements of their generalized derivatives (SPEC §3).

For a, b ∈ R:   a ≥ 0, b ≥ 0, a·b = 0   ⇔   φ(a, b) = 0,   for each φ below.

==========  =====================================  =====================================
name        φ(a, b)                                element (∂_a φ, ∂_b φ) returned
==========  =====================================  =====================================
``fb``      a + b − √(a² + b²)  (Fischer–Burmeister) (1 − a/r, 1 − b/r), r = √(a² + b²);
                                                     at r = 0: (1 − 1/√2, 1 − 1/√2)
``min``     min(a, b)  (natural residual)          (1, 0) if a < b, (0, 1) if a ≥ b
``blend``   (1 − μ) φ_fb + μ φ_min, μ ∈ (0, 1)     the same convex combination
==========  =====================================  =====================================

Choices at the kinks (deterministic, documented, tested):

* FB at the biactive point (0, 0): ∂φ_FB(0, 0) = {(1 − α, 1 − β) : α² + β² ≤ 1}; we take
  α = β = 1/√2, the limit of the derivative along the diagonal a = b ↓ 0, which treats the
  gap and the pressure symmetrically.
* min at a tie a = b: we take (0, 1), i.e. the node is *inactive* (the equilibrium row is
  kept).  With a = g − u and b = −cλ this is the primal–dual active set rule of
  Hintermüller–Ito–Kunisch (2002): active ⇔ −cλ_i > g_i − u_i, strictly.

Each function exists for NumPy arrays (``phi``/``dphi``, used by the solver and tests)
and for UFL operands (``phi_ufl``, used in forms), from the same formulas.
"""
from __future__ import annotations

from typing import Any

import numpy as np

METHODS = ("fb", "min", "blend")
_BIACTIVE = 1.0 - 1.0 / np.sqrt(2.0)


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


def dphi_fb(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Element (∂_a φ, ∂_b φ) of the generalized derivative of φ_FB (see module doc).

    a/r and b/r are formed after scaling by m = max(|a|, |b|), so neither subnormal nor
    huge operands lose the direction (a, b)/r.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    m = np.maximum(np.abs(a), np.abs(b))
    safe = np.where(m > 0, m, 1.0)
    an, bn = a / safe, b / safe
    r = np.hypot(an, bn)
    da = np.where(m > 0, 1.0 - an / np.where(m > 0, r, 1.0), _BIACTIVE)
    db = np.where(m > 0, 1.0 - bn / np.where(m > 0, r, 1.0), _BIACTIVE)
    return da, db


def phi_min(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """φ_min(a, b) = min(a, b) = a − max(0, a − b)."""
    return np.minimum(np.asarray(a, dtype=float), np.asarray(b, dtype=float))


def dphi_min(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Element of ∂φ_min: (1, 0) where a < b, (0, 1) where a ≥ b (ties inactive)."""
    active = np.asarray(a) < np.asarray(b)
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


def dphi(a: np.ndarray, b: np.ndarray, method: str, mu: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Generalized-derivative element (∂_a φ, ∂_b φ) of ``method``."""
    if method == "fb":
        return dphi_fb(a, b)
    if method == "min":
        return dphi_min(a, b)
    if method == "blend":
        (fa, fb_), (ma, mb) = dphi_fb(a, b), dphi_min(a, b)
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
