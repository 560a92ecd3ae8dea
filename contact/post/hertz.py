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
in ρ.  The computed peak pressure p0 is the largest nodal pressure max_i p_i in 2D and, in
3D, the largest patch average max_i p̄_i (:func:`patch_average`: the mean of the P1
interpolant of the nodal pressures over the contact facets around node i).  On tetrahedra
refined by ``dolfinx.mesh.refine`` the nodal pressures scatter by ±5–7 % about a smooth
profile (two_body_hertz_3d, Dörfler to 340k DoFs on 2 ranks: max_i p_i is 7.3 % above
Hertz's p0, max_i p̄_i 0.2 %), which the average over a patch removes, while it lowers a
smooth peak by about (h/a)²/4 (h the facet size): 0.03 % there, but 1 % on a coarse 2D mesh
with a = 5 h, where the nodal values do not scatter (hertz_2d at h_contact = 0.02: −0.9 %
against −0.4 % for max_i p_i).  3D reports max_i p_i too (``p0_nodal_error``).  Hertz theory
needs a ≪ R (a/R ≲ 0.1).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from dolfinx import fem, la
from mpi4py import MPI

from ..models.mortar import part_facets, surface_facets
from ..models.overlap import facet_measures
from ..models.problem import first_contact_point
from ..solvers import Result, owned_residual
from .comparison import Comparison
from .posed import Posed


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


def compare(posed: Posed, result: Result, ref: Any) -> Comparison:
    """Contact half-width / radius and peak pressure against Hertz's for the computed force
    (collective).  With contact pairs: on the slave nodes of the pairs, R the declared
    effective radius and E* of the first pair's two bodies, 1/E* = Σ (1 − ν_k²)/E_k.  The
    peak pressure is max_i p_i in 2D, max_i p̄_i in 3D (:func:`patch_average`; then
    max_i p_i gives ``p0_nodal_error`` beside it)."""
    comm = posed.comm
    p = result.problem
    con = p.constraint
    on = slice(0, p.data.pair_nodes) if posed.pairs else slice(None)
    n = np.asarray(p.data.n)
    V = p.V
    nodes = con.dofs[on] // V.dofmap.index_map_bs
    X = p.node_coordinates()[on]
    rel = X - first_contact_point(comm, X, p.contact_gaps()[on])
    rho = np.linalg.norm(rel - np.outer(rel @ n, n), axis=1)
    pressure = p.pressure(owned_residual(result))[on]
    a = contact_extent(comm, rho, result.active_mask[on])  # the solver's rule: b_i > a_i
    dim, R = posed.mesh.geometry.dim, ref.radius
    p0_nodal = _largest(comm, pressure)
    p0 = _largest(comm, patch_average(posed, V, nodes, pressure)) if dim == 3 else p0_nodal
    a_H, p0_H = hertz_values(R, contact_modulus(posed), result.contact_force, dim)
    errors = {"a_error": a / a_H - 1.0, "p0_error": p0 / p0_H - 1.0}
    values = {
        "contact_half_width" if dim == 2 else "contact_radius": a,
        "hertz_radius": R,
        "hertz_a": a_H,
        "hertz_p0": p0_H,
        **errors,
        "a_over_R": a / R,
    }
    if dim == 3:
        values.update(peak_pressure_patch=p0, p0_nodal_error=p0_nodal / p0_H - 1.0)
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


def patch_average(
    posed: Posed, V: fem.FunctionSpace, nodes: np.ndarray, values: np.ndarray
) -> np.ndarray:
    """The patch averages p̄_i of nodal values p_i (a pressure) on the contact surface
    (collective): with Γ_h the contact facets (the slave parts of the scene's pairs, else
    its contact parts) and ω_i the facets of Γ_h through node i,

        p̄_i = Σ_{F ∈ ω_i} |F| p̄_F / Σ_{F ∈ ω_i} |F|,  p̄_F the mean of p over F's nodes,

    that is (1/|ω_i|) ∫_{ω_i} p_h dA for the P1 interpolant p_h of the p_i (|F| a length in
    2D, an area in 3D; p̄ in the unit of p).  ``nodes`` are owned local node indices (blocks
    of V's DoFs) with ``values`` p_i; a facet node without a value (an end of Γ_C fixed in
    every component) is left out of p̄_F, and a node whose patch has no valued facet keeps
    p_i.  Returns p̄_i at ``nodes``."""
    bnd, imap = posed.boundary, V.dofmap.index_map
    pairs = posed.pairs
    facets = (
        np.concatenate([part_facets(bnd, slave) for slave, _ in pairs])
        if pairs
        else bnd.facets("contact")
    )
    surface = surface_facets(V, facets)  # those of owned cells: each facet on one rank
    known = la.vector(imap, 2)  # (p_i, 1) at the nodes with a value
    known.array.reshape(-1, 2)[nodes] = np.c_[values, np.ones(len(nodes))]
    known.scatter_forward()
    at = known.array.reshape(-1, 2)[surface.nodes]  # (F, nv, 2)
    count = at[:, :, 1].sum(axis=1)
    weight = np.where(count > 0, facet_measures(surface.X) if len(surface.X) else 0.0, 0.0)
    mean = at[:, :, 0].sum(axis=1) / np.maximum(count, 1.0)
    sums = la.vector(imap, 2)  # (Σ |F| p̄_F, Σ |F|) over the facets at each node
    nv = surface.nodes.shape[1]
    np.add.at(
        sums.array.reshape(-1, 2),
        surface.nodes.ravel(),
        np.repeat(np.c_[weight * mean, weight], nv, axis=0),
    )
    sums.scatter_reverse(la.InsertMode.add)
    total, area = sums.array.reshape(-1, 2)[nodes].T
    return np.where(area > 0, total / np.where(area > 0, area, 1.0), values)


def _largest(comm: MPI.Comm, values: np.ndarray) -> float:
    """max(values) over all ranks, 0 if none (collective)."""
    return comm.allreduce(float(np.max(values, initial=0.0)), op=MPI.MAX)


def contact_modulus(posed: Posed) -> float:
    """E* = E / (1 − ν²) of the body against a rigid plane; for contact pairs that of the
    first pair's two bodies, 1/E* = (1 − ν₁²)/E₁ + (1 − ν₂²)/E₂ (docs/theory.md §7)."""
    if not posed.pairs:
        (E, nu), *_ = posed.materials.values()  # one body: model.E is required
        return E / (1.0 - nu**2)
    from .interface import effective_modulus, pair_bodies

    return effective_modulus([posed.materials[b] for b in pair_bodies(posed, 0)])


def contact_extent(comm: MPI.Comm, rho: np.ndarray, active: np.ndarray) -> float:
    """Half-width / radius of the contact set: the midpoint between the last active node and
    the first inactive one beyond it, in the distance ρ from the first point of contact."""
    last_active = comm.allreduce(float(rho[active].max(initial=0.0)), op=MPI.MAX)
    first_free = comm.allreduce(
        float(rho[(~active) & (rho > last_active)].min(initial=np.inf)), op=MPI.MIN
    )
    return 0.5 * (last_active + first_free) if np.isfinite(first_free) else last_active
