"""Cattaneo–Mindlin partial slip as a declared reference (docs/theory.md §7; Johnson, Contact
Mechanics §7.1): ``reference: {type: cattaneo_mindlin, radius: R}``.

Two elastically similar bodies (the normal and the tangential response decouple) pressed
by the normal force P and then loaded by a tangential force Q < F P, Coulomb coefficient F:
the contact half-width a and peak pressure p0 are Hertz's (effective radius R, contact
modulus E*), the stick zone is |x| < c and the tangential traction is

    2D:  c/a = √(1 − Q/(F P)),
         q(x) = F p0 √(1 − x²/a²) − [|x| < c] F p0 (c/a) √(1 − x²/c²),
    3D:  c/a = (1 − Q/(F P))^{1/3},  the same q with x → r.

Computed: P the contact force, Q = |Σ_i w_i λ_t,i| over the contact nodes, the half-width
a_h and the stick half-width c_h (midpoints between the last active / stick node and the
first inactive / slipping one, in the distance ρ from the first point of contact), and
q_h,i = |λ_t,i|.  Errors: ``c_error`` = (c_h/a_h) / (c/a) − 1 and ``q_error`` =
‖q_h − q‖ / ‖q‖, a discrete L² norm over the contact nodes with ρ ≤ a (weights w_i).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from mpi4py import MPI

from ..models.problem import first_contact_point
from ..solvers import Result
from .comparison import Comparison
from .hertz import contact_extent, contact_modulus, hertz_values
from .posed import Posed
from .resultants import whole_body


def stick_ratio(ratio: float, dim: int) -> float:
    """c/a of Cattaneo–Mindlin for Q/(F P) = ``ratio``."""
    return (1.0 - ratio) ** (0.5 if dim == 2 else 1.0 / 3.0)


def traction(rho: np.ndarray, a: float, c: float, p0: float, F: float) -> np.ndarray:
    """q(ρ) = F p0 [√(1 − ρ²/a²) − (c/a) √(1 − ρ²/c²) for ρ < c], 0 beyond a."""
    outer = F * p0 * np.sqrt(np.clip(1.0 - (rho / a) ** 2, 0.0, None))
    inner = F * p0 * (c / a) * np.sqrt(np.clip(1.0 - (rho / c) ** 2, 0.0, None)) if c > 0 else 0.0
    return outer - inner


def compare(posed: Posed, result: Result, ref: Any) -> Comparison:
    """The partial-slip state against Cattaneo–Mindlin for the computed P and Q (collective)."""
    comm = posed.comm
    p, fr = result.problem, result.friction
    if fr is None:
        raise ValueError("reference cattaneo_mindlin: the solve has no friction")
    con = p.constraint
    on = slice(0, p.data.pair_nodes) if posed.pairs else slice(None)
    dim = posed.mesh.geometry.dim
    X = p.V.tabulate_dof_coordinates()[con.dofs[on] // p.V.dofmap.index_map_bs, :dim]
    n = np.asarray(p.data.n)
    rel = X - first_contact_point(comm, X, p.contact_gaps()[on])
    rho = np.linalg.norm(rel - np.outer(rel @ n, n), axis=1)
    w, lam_t = fr["w"][on], fr["lambda_t_vec"][on]
    stick = fr["status"][on] == 1
    P = result.contact_force
    Q = float(
        np.linalg.norm(whole_body(p, comm.allreduce((w[:, None] * lam_t).sum(axis=0), op=MPI.SUM)))
    )
    F = posed.coefficient
    assert F is not None  # Coulomb's (load)
    a_H, p0_H = hertz_values(ref.radius, contact_modulus(posed), P, dim)
    ratio = Q / (F * P)
    c_over_a = stick_ratio(min(ratio, 1.0), dim)
    a_h = contact_extent(comm, rho, result.active_mask[on])
    c_h = contact_extent(comm, rho, stick) if comm.allreduce(int(stick.sum()), op=MPI.SUM) else 0.0
    q_h = np.linalg.norm(lam_t, axis=1)
    q = traction(rho, a_H, c_over_a * a_H, p0_H, F)
    inside = rho <= a_H
    num = comm.allreduce(float(np.sum(w[inside] * (q_h[inside] - q[inside]) ** 2)), op=MPI.SUM)
    den = comm.allreduce(float(np.sum(w[inside] * q[inside] ** 2)), op=MPI.SUM)
    errors = {
        "c_error": (c_h / a_h) / c_over_a - 1.0,
        "q_error": float(np.sqrt(num / max(den, 1e-300))),
    }
    values = {
        "Q_over_FP": ratio,
        "c_over_a": c_h / a_h,
        "c_over_a_theory": c_over_a,
        "stick_half_width": c_h,
        "contact_half_width" if dim == 2 else "contact_radius": a_h,
        "hertz_radius": ref.radius,
        "hertz_a": a_H,
        "hertz_p0": p0_H,
        "tangential_force": Q,
        **errors,
    }
    profile = np.vstack(comm.gather(np.c_[rho, q_h], root=0) or [np.zeros((0, 2))])
    profile = profile[np.argsort(profile[:, 0])] if comm.rank == 0 else np.zeros((0, 2))
    r = np.linspace(0.0, a_H, 300)
    # the sign of λ_t as computed (2D: along the tangent t0 = (−n_y, n_x) of the plots)
    force = comm.allreduce((w[:, None] * lam_t).sum(axis=0), op=MPI.SUM)
    sign = float(np.sign(force @ np.array([-n[1], n[0]]))) if dim == 2 else 1.0
    return Comparison(
        values,
        errors,
        profile,
        xlabel="distance ρ from the first point of contact",
        curves=[
            (r, p0_H * np.sqrt(1.0 - (r / a_H) ** 2), f"Hertz: a = {a_H:.4g}, p0 = {p0_H:.4g}")
        ],
        traction_curves=[
            (
                r,
                sign * traction(r, a_H, c_over_a * a_H, p0_H, F),
                f"Cattaneo–Mindlin: c/a = {c_over_a:.3f} (Q/FP = {ratio:.3f})",
            )
        ],
        marks=[(c_h, f"computed c = {c_h:.4g} (c/a {c_h / a_h:.3f})")],
    )
