"""How far a solution's nodes are from the kink of the complementarity condition.

A count of active nodes (or of stick / slip nodes) compared between two solves — methods,
rank counts, CPUs — can only differ by a node whose b_i − a_i lies within the solves'
difference of the tie tolerance τ (contact.solvers.ncp): a node that is nearly biactive
(gap ≈ 0 and pressure ≈ 0).  ``tie_margin`` measures that distance; a test that compares
counts asserts a margin far above the solver tolerance, so that its count cannot move
with rounding (or compares node sets only away from ties)."""

from __future__ import annotations

from contact.solvers.newton import Complementarity

import numpy as np
from mpi4py import MPI


def tie_margin(result) -> float:
    """min_i |b_i − a_i| / max_j max(|a_j|, |b_j|) over the constrained nodes of every rank
    at the solution of ``result`` (collective); inf without constrained nodes."""
    p = result.problem
    cp = Complementarity(p)
    x = p.b.duplicate()
    p.to_unknowns(result.u_h.x.petsc_vec, x)
    a, b, _ = cp.pair(x)
    x.destroy()
    comm = p.V.mesh.comm
    scale = comm.allreduce(
        float(max(np.max(np.abs(a), initial=0.0), np.max(np.abs(b), initial=0.0))), op=MPI.MAX
    )
    gap = comm.allreduce(float(np.min(np.abs(b - a), initial=np.inf)), op=MPI.MIN)
    return gap / scale if scale > 0 else np.inf
