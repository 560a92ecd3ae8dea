"""Contact resultants of an elasticity solve and the Hertz values they imply (SPEC §7).

For the computed total force (sum of nodal multipliers, Σ_i w_i |λ_n,i|, times the
number of symmetric copies the model stands for) Hertz theory gives, with
E* = E / (1 − ν²) against a rigid plane:

    2D (force P per unit thickness):  a = 2 √(R P / (π E*)),    p0 = 2 P / (π a)
    3D (force F):                     a = (3 F R / (4 E*))^{1/3}, p0 = 3 F / (2π a²)

The computed contact half-width (2D) or radius (3D) is the midpoint between the last
active node and the first inactive one, in the in-plane distance ρ from the first point
of contact; the peak pressure is max |λ_n|.  The reaction on the Dirichlet boundary
(sum of the residual a(u_h, v) − L(v) over its DoFs, normal component) checks the force.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc

from .models.obstacles import first_contact_point
from .scene import Scene
from .solvers import Result, owned_residual


def hertz(R: float, E: float, nu: float, force: float, dim: int) -> tuple[float, float]:
    """(a, p0) of Hertz theory for a cylinder (dim 2, force per thickness) or a sphere."""
    return hertz_values(R, E / (1.0 - nu**2), force, dim)


def hertz_values(R: float, Es: float, force: float, dim: int) -> tuple[float, float]:
    """(a, p0) of Hertz theory for the effective radius R and contact modulus E*."""
    if dim == 2:
        a = 2.0 * np.sqrt(R * force / (np.pi * Es))
        return a, 2.0 * force / (np.pi * a)
    a = (3.0 * force * R / (4.0 * Es)) ** (1.0 / 3.0)
    return a, 3.0 * force / (2.0 * np.pi * a**2)


def hertz_radius(cfg: dict) -> float | None:
    """R of a validated scene config: the mesh radius of a built-in Hertz geometry, else
    the constant ``R``; None when neither is given (no Hertz values)."""
    m = cfg["mesh"]
    if m["type"] == "half_disks":  # two cylinders: 1/R = 1/R1 + 1/R2
        R1, R2 = float(m["radius"]), float(m.get("radius2") or m["radius"])
        return R1 * R2 / (R1 + R2)
    R = m.get("radius") or cfg["constants"].get("R")
    return None if R is None else float(R)


def radius_of(scene: Scene) -> float:
    """R of :func:`hertz_radius`; a ValueError without one."""
    R = hertz_radius(scene.cfg)
    if R is None:
        raise ValueError("Hertz values need mesh.radius or a constant R")
    return R


def contact_resultants(scene: Scene, result: Result) -> dict:
    """Half-width/radius, peak pressure, contact force and reaction, and the Hertz values
    (for a scene with contact pairs: :func:`contact.interface.interface_resultants`)."""
    if scene.cfg.get("pairs"):
        from .interface import interface_resultants

        return interface_resultants(scene, result)
    comm = scene.comm
    p = result.problem
    con = p.constraint
    n = np.asarray(p.data["n"])          # contact normal at the first point of contact
    k = int(np.argmax(np.abs(n)))        # the reaction's component along it
    copies = 2 ** sum(role == "symmetry" for role in scene.boundary.roles.values())
    raw = owned_residual(result)[con.dofs] / con.w      # R_i / w_i
    lam = p.lambda_sign * raw                             # λ_n,i
    # total force along the first contact normal: Σ w_i |λ_n,i| (n_i · n), n_i the nodal normals
    along = p.data["normals"] @ n if "normals" in p.data else np.ones(len(con.dofs))
    force = copies * comm.allreduce(float(np.sum(con.w * -lam * along)), op=MPI.SUM)

    # reaction on the Dirichlet boundary, component k
    full = dolfinx.fem.petsc.assemble_vector(p.data["reaction_form"])
    full.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    n_owned = p.V.dofmap.index_map.size_local * p.V.dofmap.index_map_bs
    bc_dofs = p.bcs[0].dof_indices()[0]
    bc_dofs = bc_dofs[(bc_dofs < n_owned) & (bc_dofs % p.V.dofmap.index_map_bs == k)]
    reaction = copies * comm.allreduce(float(np.sum(full.array_r[bc_dofs])), op=MPI.SUM)
    full.destroy()

    # ρ: in-plane distance of each constrained node from the first point of contact
    V = p.V
    X = V.tabulate_dof_coordinates()[con.dofs // V.dofmap.index_map_bs, : scene.mesh.geometry.dim]
    unknowns = p.b.duplicate()
    p.to_unknowns(result.u_h.x.petsc_vec, unknowns)
    gap = con.sign * (con.g - unknowns.array_r[con.dofs])
    unknowns.destroy()
    origin = first_contact_point(comm, X, con.g * con.sign)
    rel = X - origin
    rho = np.linalg.norm(rel - np.outer(rel @ n, n), axis=1)
    a = contact_extent(comm, rho, result.active_mask)     # the solver's rule: b_i > a_i
    p0 = comm.allreduce(float(np.max(-lam, initial=0.0)), op=MPI.MAX)
    model = scene.cfg["model"]
    dim = scene.mesh.geometry.dim
    R = radius_of(scene)
    a_H, p0_H = hertz(R, model["E"], model["nu"], force, dim)
    return {"contact_half_width" if dim == 2 else "contact_radius": a, "peak_pressure": p0,
            "contact_force": force, "reaction_force": abs(reaction),
            "force_balance_error": abs(abs(reaction) - force) / max(force, 1e-300),
            "hertz_a": a_H, "hertz_p0": p0_H, "a_error": a / a_H - 1.0, "p0_error": p0 / p0_H - 1.0,
            "a_over_R": a / R, "symmetric_copies": copies, "min_gap": comm.allreduce(float(gap.min(initial=np.inf)), op=MPI.MIN),
            "pressure_profile": _profile(comm, rho, -lam)}


def contact_extent(comm: MPI.Comm, rho: np.ndarray, active: np.ndarray) -> float:
    """Half-width / radius of the contact set: the midpoint between the last active node and
    the first inactive one beyond it, in the distance ρ from the first point of contact."""
    last_active = comm.allreduce(float(rho[active].max(initial=0.0)), op=MPI.MAX)
    first_free = comm.allreduce(float(rho[(~active) & (rho > last_active)].min(initial=np.inf)), op=MPI.MIN)
    return 0.5 * (last_active + first_free) if np.isfinite(first_free) else last_active


def _profile(comm: MPI.Comm, rho: np.ndarray, pressure: np.ndarray) -> list[list[float]]:
    parts = comm.allgather(np.c_[rho, pressure])
    data = np.vstack(parts)
    return data[np.argsort(data[:, 0])].tolist()
