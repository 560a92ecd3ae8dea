"""Hertz theory (docs/theory.md §7) as a declared reference:
``reference: {type: hertz, radius: R}``.

For the computed total force (:attr:`contact.solvers.Result.contact_force`, the symmetric
copies included) Hertz theory gives, with E* = E / (1 − ν²) against a rigid plane (or a
rigid cylinder / sphere of radius R indenting an elastic half-space):

    2D (force P per unit thickness):  a = 2 √(R P / (π E*)),    p0 = 2 P / (π a)
    3D (force F):                     a = (3 F R / (4 E*))^{1/3}, p0 = 3 F / (2π a²)
    pressure p(ρ) = p0 √(1 − ρ²/a²),

ρ the in-plane distance from the first point of contact.  Two elastic bodies (contact
pairs) are Hertz's problem for the effective radius 1/R = 1/R₁ + 1/R₂ and
1/E* = (1 − ν₁²)/E₁ + (1 − ν₂²)/E₂.  The computed contact half-width
(2D) or radius (3D) is the midpoint between the last active node and the first inactive one
in ρ; the computed peak pressure is max_i p_i.  Hertz theory needs a ≪ R (a/R ≲ 0.1).
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from ..models.obstacles import first_contact_point
from ..setup.scene import Scene
from ..solvers import Result, owned_residual
from .comparison import Comparison


def hertz(R: float, E: float, nu: float, force: float, dim: int) -> tuple[float, float]:
    """(a, p0) of Hertz theory for a cylinder (dim 2, force per thickness) or a sphere."""
    return hertz_values(R, E / (1.0 - nu**2), force, dim)


def hertz_values(R: float, Es: float, force: float, dim: int) -> tuple[float, float]:
    """(a, p0) of Hertz theory for the (effective) radius R and contact modulus E*."""
    if dim == 2:
        a = 2.0 * np.sqrt(R * force / (np.pi * Es))
        return a, 2.0 * force / (np.pi * a)
    a = (3.0 * force * R / (4.0 * Es)) ** (1.0 / 3.0)
    return a, 3.0 * force / (2.0 * np.pi * a**2)


def compare(scene: Scene, result: Result, ref: dict) -> Comparison:
    """Contact half-width / radius and peak pressure against Hertz's for the computed force
    (collective).  With contact pairs: on the slave nodes of the pairs, R the declared
    effective radius and E* of the first pair's two bodies, 1/E* = Σ (1 − ν_k²)/E_k."""
    comm = scene.comm
    p = result.problem
    con = p.constraint
    on = slice(0, p.data["pair_nodes"]) if scene.cfg.get("pairs") else slice(None)
    n = np.asarray(p.data["n"])
    V = p.V
    X = V.tabulate_dof_coordinates()[
        con.dofs[on] // V.dofmap.index_map_bs, : scene.mesh.geometry.dim
    ]
    rel = X - first_contact_point(comm, X, (con.g * con.sign)[on])
    rho = np.linalg.norm(rel - np.outer(rel @ n, n), axis=1)
    pressure = p.pressure(owned_residual(result))[on]
    a = contact_extent(comm, rho, result.active_mask[on])  # the solver's rule: b_i > a_i
    p0 = comm.allreduce(float(np.max(pressure, initial=0.0)), op=MPI.MAX)
    dim, R = scene.mesh.geometry.dim, float(ref["radius"])
    a_H, p0_H = hertz_values(R, contact_modulus(scene), result.contact_force, dim)
    errors = {"a_error": a / a_H - 1.0, "p0_error": p0 / p0_H - 1.0}
    values = {
        "contact_half_width" if dim == 2 else "contact_radius": a,
        "hertz_radius": R,
        "hertz_a": a_H,
        "hertz_p0": p0_H,
        **errors,
        "a_over_R": a / R,
    }
    profile = np.vstack(comm.gather(np.c_[rho, pressure], root=0) or [np.zeros((0, 2))])
    profile = profile[np.argsort(profile[:, 0])] if comm.rank == 0 else np.zeros((0, 2))
    r = np.linspace(0.0, a_H, 200)
    return Comparison(
        values,
        errors,
        profile,
        xlabel="distance ρ from the first point of contact",
        curves=[
            (r, p0_H * np.sqrt(1.0 - (r / a_H) ** 2), f"Hertz: a = {a_H:.4g}, p0 = {p0_H:.4g}")
        ],
        marks=[(a, f"computed a = {a:.4g} ({100 * errors['a_error']:+.1f}% vs Hertz)")],
    )


def contact_modulus(scene: Scene) -> float:
    """E* = E / (1 − ν²) of the body against a rigid plane; for contact pairs that of the
    first pair's two bodies, 1/E* = (1 − ν₁²)/E₁ + (1 − ν₂²)/E₂ (docs/theory.md §7)."""
    if not scene.cfg.get("pairs"):
        model = scene.cfg["model"]
        return model["E"] / (1.0 - model["nu"] ** 2)
    from .interface import effective_modulus, pair_bodies

    bodies = scene.cfg["bodies"]
    return effective_modulus([(bodies[b]["E"], bodies[b]["nu"]) for b in pair_bodies(scene, 0)])


def contact_extent(comm: MPI.Comm, rho: np.ndarray, active: np.ndarray) -> float:
    """Half-width / radius of the contact set: the midpoint between the last active node and
    the first inactive one beyond it, in the distance ρ from the first point of contact."""
    last_active = comm.allreduce(float(rho[active].max(initial=0.0)), op=MPI.MAX)
    first_free = comm.allreduce(
        float(rho[(~active) & (rho > last_active)].min(initial=np.inf)), op=MPI.MIN
    )
    return 0.5 * (last_active + first_free) if np.isfinite(first_free) else last_active
