"""The load of a load path's step as a displacement: the x-axis of the force–displacement
curve (steps.csv, force.png; :mod:`contact.output.step_report`).

A step's scene is driven by a moving obstacle, by prescribed displacements, or both.  The
obstacle's **approach** at a point X is how far it has moved towards the body there since
t = 0, in the reference gap g_t(X) of the obstacle at the step's pseudo-time t,

    a(t) = g_0(X) − g_t(X),

the same at every X for a plane translated along its normal (indentation of the
hyperelastic cylinder, the wall pushing the buckling strip), measured at the first point
of contact otherwise.  The obstacle's **translation** is the move of its reference point (a
plane's point, a circle's or sphere's centre) since t = 0, a vector: an obstacle pressed in
and then dragged along the body (the ironing die) changes direction, and its tangential
component is the sliding distance.  The **prescribed displacement** is the largest |u_i|
over the Dirichlet DoFs of the step's solution (u = u_D there).
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from .posed import Posed


def prescribed_displacement(result) -> float:
    """The largest |u_i| over the owned Dirichlet DoFs of ``result.u_h`` (all ranks)."""
    p = result.problem
    n_owned = p.V.dofmap.index_map.size_local * p.V.dofmap.index_map_bs
    u = result.u_h.x.array
    local = 0.0
    for bc in p.bcs:
        dofs, _ = bc.dof_indices()
        dofs = dofs[dofs < n_owned]
        local = max(local, float(np.max(np.abs(u[dofs]), initial=0.0)))
    return p.V.mesh.comm.allreduce(local, op=MPI.MAX)


def load_displacements(posed: Posed, result) -> dict[str, float | list[float]]:
    """{'obstacle_approach': a(t) at the first point of contact (module doc; 0 for a scene
    whose contact is not with one rigid obstacle — bodies against each other, a scalar
    scene's gap or obstacle function), 'obstacle_translation': its translation since t = 0
    (a vector; only with one rigid obstacle), 'prescribed_displacement': max |u_D|} of a
    step (collective)."""
    approach = 0.0
    out: dict[str, float | list[float]] = {}
    if posed.approach is not None and posed.translation is not None:  # one rigid obstacle
        out["obstacle_translation"] = posed.translation()
        approach = posed.approach(result.first_contact)
    return {
        "obstacle_approach": approach,
        **out,
        "prescribed_displacement": prescribed_displacement(result),
    }
