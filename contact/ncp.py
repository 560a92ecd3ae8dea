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
    """φ_FB(a, b) = a + b − √(a² + b²), evaluated without cancellation.

    Where a + b > 0 the algebraically equal form 2ab / (a + b + r) is used, which keeps
    full relative accuracy when a and b are both large and positive.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    r = np.hypot(a, b)
    s = a + b
    with np.errstate(divide="ignore", invalid="ignore"):
        stable = 2.0 * a * (b / (s + r))  # b/(a+b+r) ∈ [0, 1): no overflow/underflow
    return np.where(s > 0, stable, s - r)


def dphi_fb(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Element (∂_a φ, ∂_b φ) of the generalized derivative of φ_FB (see module doc)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    r = np.hypot(a, b)
    safe = np.where(r > 0, r, 1.0)
    da = np.where(r > 0, 1.0 - a / safe, _BIACTIVE)
    db = np.where(r > 0, 1.0 - b / safe, _BIACTIVE)
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
