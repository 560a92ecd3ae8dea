"""Resultants of an elastic contact solve: the numbers every elastic contact scene reports.

* contact force  F = m_n Σ_i w_i p_i (n_i · n)  (``Result.contact_force``: p_i = −λ_n,i the
  nodal pressure, w_i the lumped weights, n_i the nodal normals, n the normal at the first
  point of contact, m_n the mirror images pressing along n, below; with contact pairs n
  is the direction of the whole bodies' normal contact force on the slave side, so that F
  is its size: :meth:`contact.models.contacts.BodiesProblem.contact_force`);
* reaction on the Dirichlet boundary along n: the sum of the residual a(u_h, v) − L(v) over
  its DoFs, times m_n — equal to F at equilibrium (``force_balance_error`` = |R − F| / F);
* peak pressure max_i p_i and the smallest gap min_i (g_i − u_i·n_i) (≥ 0: no penetration).

**Every force is of the whole body** (:func:`whole_body`): when symmetry planes cut the
body, the modelled part stands for m = 2^(number of planes) mirror images, so a force
vector's components along the planes are m times the modelled part's, and its component
normal to a plane is 0 (it cancels between mirror images).  A scalar force along the
contact normal n (the contact force, the reaction along n, friction's normal force) is
m_n times the modelled part's, m_n = 2^(planes that contain n)
(:meth:`~contact.solvers.problem.DiscreteProblem.copies_along`): the image across a plane
normal to n is a second contact zone pressing the other way, not one alongside.  Measures
(``active_measure``, the stick / slip measures) and node counts stay those of the modelled
part.

Units: forces per unit thickness (N/m) in 2D plane strain, forces (N) in 3D; pressures in
the unit of E.  Reference solutions (Hertz, ...) are compared in :mod:`contact.post.reference`.
"""

from __future__ import annotations

import dolfinx.fem.petsc
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..solvers import Result, owned_residual
from .posed import Posed


def whole_body(problem, force) -> list[float]:
    """A force of the modelled part (a vector summed over all ranks) as the force on the whole
    body its symmetric copies stand for (module doc): component k is 0 for each symmetry
    plane x_k = c, m times the modelled part's otherwise (m = ``symmetric_copies``)."""
    out = problem.symmetry.copies * np.asarray(force, dtype=float)
    out[list(problem.symmetry.axes)] = 0.0
    return out.tolist()


def reaction_force(result: Result) -> list[float]:
    """The reaction of the Dirichlet boundary (the force the supports exert on the body or
    bodies), per component, of the whole body (:func:`whole_body`; collective)."""
    return whole_body(result.problem, part_reaction(result))


def part_reaction(result: Result) -> np.ndarray:
    """The reaction of the Dirichlet boundary on the modelled part, per component (summed
    over all ranks; collective): Σ over the Dirichlet DoFs of the residual a(u_h, v) − L(v),
    in the displacement's own components (with contact pairs the solver's unknowns are
    rotated; the reaction is not).  A problem whose test functions are a subspace, u = Q x
    (``data.reaction_basis`` Q: an hp space), sums Qᵀ(a(u_h, ·) − L) over the Dirichlet
    unknowns x instead — the residual at the DoFs outside the subspace is no reaction."""
    p = result.problem
    assert p.data.reaction_form is not None  # an elastic scene's
    full = dolfinx.fem.petsc.assemble_vector(p.data.reaction_form)
    full.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]
    basis = p.data.reaction_basis
    if basis is not None:
        reduced = basis.createVecRight()
        basis.multTranspose(full, reduced)
        full.destroy()
        full = reduced
    bs = p.V.dofmap.index_map_bs
    n_owned = p.V.dofmap.index_map.size_local * bs
    dofs = (p.data.u_bcs or p.bcs)[0].dof_indices()[0]  # the Dirichlet condition on u
    dofs = dofs[dofs < n_owned]
    local = np.bincount(dofs % bs, weights=full.array_r[dofs], minlength=bs)
    full.destroy()
    return p.V.mesh.comm.allreduce(local, op=MPI.SUM)


def nodal_gap(result: Result) -> np.ndarray:
    """g_i − (Qᵀu)_i, the gap at the owned constrained nodes (≥ 0 when feasible; on the
    current configuration the gap of the deformed node, :meth:`DiscreteProblem.nodal_gap`)."""
    p = result.problem
    unknowns = p.b.duplicate()
    p.to_unknowns(result.u_h.x.petsc_vec, unknowns)
    gap = p.nodal_gap(unknowns.array_r)
    unknowns.destroy()
    return gap


def current_pressure(result: Result) -> np.ndarray | None:
    """The contact pressure on the deformed surface of a finite-strain body at the owned
    contact nodes (None for a linear model, whose one configuration is the reference):

        p_i^cur = w_i p_i / w_i^cur,

    the node's normal contact force w_i p_i (p_i the nominal pressure of
    :meth:`DiscreteProblem.pressure`, force per reference area) over its lumped deformed
    area w_i^cur = ∫ φ_i da, da = J |F⁻ᵀ N| dA (Nanson; ``data.deformed_area``,
    :func:`contact.models.hyperelastic.deformed_area`): the discrete Cauchy normal traction
    −σn·n on the current surface, the counterpart of the nominal one; Σ_i w_i^cur p_i^cur =
    Σ_i w_i p_i, the same force.  Collective (assembly)."""
    p = result.problem
    form = p.data.deformed_area
    if form is None:
        return None
    r = owned_residual(result)  # puts u_h in place for the form too
    area = dolfinx.fem.petsc.assemble_vector(form)
    area.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]
    con = p.constraint
    out = p.pressure(r) * con.w / area.array_r[con.dofs]
    area.destroy()
    return out


def pressure_peaks(result: Result) -> dict:
    """``peak_pressure`` (nominal) and ``peak_pressure_current`` (per deformed area,
    :func:`current_pressure`) of a finite-strain body, {} for a linear model (collective)."""
    current = current_pressure(result)
    if current is None:
        return {}
    comm = result.problem.V.mesh.comm
    nominal = result.problem.pressure(owned_residual(result))
    return {
        "peak_pressure": comm.allreduce(float(np.max(nominal, initial=0.0)), op=MPI.MAX),
        "peak_pressure_current": comm.allreduce(float(np.max(current, initial=0.0)), op=MPI.MAX),
    }


def contact_resultants(posed: Posed, result: Result) -> dict:
    """Contact force, reaction, force balance, peak pressure and smallest gap (collective)."""
    comm = posed.comm
    p = result.problem
    n = np.asarray(p.data.n)  # contact normal at the first point of contact
    reaction = p.copies_along(n) * abs(float(part_reaction(result) @ n))
    force = result.contact_force
    pressure = p.pressure(owned_residual(result))
    return {
        "contact_force": force,
        "reaction_force": reaction,
        "force_balance_error": abs(reaction - force) / max(force, 1e-300),
        "peak_pressure": comm.allreduce(float(np.max(pressure, initial=0.0)), op=MPI.MAX),
        "symmetric_copies": p.symmetry.copies,
        "min_gap": comm.allreduce(float(nodal_gap(result).min(initial=np.inf)), op=MPI.MIN),
    }
