"""Friction on the contact surface Γ_C: the resultants of a step (the nodal fields of the
field files are :func:`contact.solvers.friction.surface_functions`).  The per-node friction
columns of ``contact.csv`` (λ_t,i, s_t,i, the status, the weight w_i = ∫_{Γ_C} φ_i of contact
node i: a length in 2D, an area in 3D) are :func:`contact.post.contact_table.friction_columns`.

Resultants (of the whole body when symmetry planes cut it:
:func:`contact.post.resultants.whole_body`, m times the modelled part's along the planes, 0
across them): the normal force m_n Σ w_i λ_n,i (m_n the mirror images pressing along the
contact normal, :meth:`~contact.solvers.problem.DiscreteProblem.copies_along`), the
tangential force Σ w_i λ_t,i (vector), the
contact force on the body Σ w_i (λ_n,i n_i + λ_t,i) (vector; with no body or Neumann load it
balances the Dirichlet reaction), the Dirichlet reaction per component
(:func:`contact.post.resultants.reaction_force`: the force the supports exert on the body or
bodies), |F_t| / |F_n|, the friction force along the surface m_n Σ w_i |λ_t,i| and its
ratio to |F_n| (on a curved surface the tangents turn and |F_t| is shorter than it; where
every pressed node slips under Coulomb's law it is F |F_n|), and the node counts and
measures Σ w_i of the stick, slip and separated sets (of the modelled part); in 2D also the
number of stick zones (maximal runs of stick nodes along Γ_C) and their extent in s.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from mpi4py import MPI

from ..solvers import Result
from .contact_table import STATUS, Table, contact_table
from .posed import Posed
from .resultants import reaction_force, whole_body


def surface_figures(posed: Posed, result: Result, table: Table | None = None) -> dict:
    """The resultants and zone measures of the module doc (collective); ``table`` is the
    step's contact table as :func:`contact.post.contact_table.contact_table` returns it (the
    table on rank 0, None elsewhere), if already gathered (for the stick zones in 2D).  Whether to
    gather it is rank 0's decision, broadcast: a collective entered on some ranks only
    would hang the others."""
    comm, p, fr = posed.comm, result.problem, result.friction
    if fr is None:
        raise ValueError("friction figures of a frictionless result")
    w, lam_n = fr["w"], fr["lambda_n"]
    if "normals" in fr:  # on the current configuration: each node's current normal
        normals = fr["normals"]
    elif p.data.normals is not None:
        normals = p.data.normals
    else:
        normals = np.tile(np.asarray(p.data.n, float), (len(w), 1))

    def total(values) -> np.ndarray:  # Σ over the nodes of every rank, per column
        values = np.asarray(values, dtype=float)
        return comm.allreduce(
            (values[:, None] if values.ndim == 1 else values).sum(axis=0), op=MPI.SUM
        )

    tangential = w[:, None] * fr["lambda_t_vec"]
    out: dict[str, Any] = {
        "normal_force": p.copies_along() * float(total(w * lam_n)[0]),
        "tangential_force": whole_body(p, total(tangential)),
        "contact_force": whole_body(p, total(w[:, None] * lam_n[:, None] * normals + tangential)),
        "reaction_force": reaction_force(result),
    }
    out["friction_ratio"] = float(
        np.linalg.norm(out["tangential_force"]) / max(abs(out["normal_force"]), 1e-300)
    )
    magnitude = float(total(w * np.linalg.norm(np.atleast_2d(fr["lambda_t"]), axis=1))[0])
    out["surface_friction_force"] = p.copies_along() * magnitude
    out["surface_friction_ratio"] = out["surface_friction_force"] / max(
        abs(out["normal_force"]), 1e-300
    )
    for code, name in enumerate(STATUS):
        mine = fr["status"] == code
        out[f"{name}_nodes"] = comm.allreduce(int(mine.sum()), op=MPI.SUM)
        out[f"{name}_measure"] = float(total(np.where(mine, w, 0.0))[0])
    out["max_slip"] = comm.allreduce(
        float(np.max(np.linalg.norm(fr["slip_vec"], axis=1), initial=0.0)), op=MPI.MAX
    )
    if posed.mesh.geometry.dim == 2:
        if comm.bcast(table is None if comm.rank == 0 else None, root=0):
            table = contact_table(posed, result)
        out.update(comm.bcast(stick_zones(table) if table is not None else None, root=0))
    return out


def stick_zones(table: Table) -> dict:
    """2D, from a contact table sorted along Γ_C: the number of stick zones and the arc
    lengths of the first and last stick node."""
    stick = table["status"] == "stick"
    zones = int(np.sum(stick[1:] & ~stick[:-1]) + (int(stick[0]) if len(stick) else 0))
    ends = [float(table["s"][stick].min()), float(table["s"][stick].max())] if stick.any() else []
    return {"stick_zones": zones, "stick_extent": ends}
