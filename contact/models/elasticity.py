"""What an elastic body needs beyond its forms (docs/theory.md §1.3): the Lamé parameters of
E and ν, the rigid-body modes (the near-nullspace GAMG needs), and the von Mises stress of a
solution.  The stress σ(u) itself is :func:`contact.models.physics.stress`."""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from .physics import epsilon, stress


def rigid_body_modes(
    V: fem.FunctionSpace, rotation: PETSc.Mat | None = None, inverse: PETSc.Mat | None = None
) -> PETSc.NullSpace:
    """Near-nullspace of elasticity for GAMG: gdim translations and the infinitesimal
    rotations (1 in 2D, 3 in 3D), in the solver's unknowns (Q⁻¹ m: Qᵀ m for a rotation,
    ``inverse`` m for a general change of basis), orthonormalised."""
    msh = V.mesh
    gdim = msh.geometry.dim
    n_local = V.dofmap.index_map.size_local
    X = V.tabulate_dof_coordinates()[:n_local, :gdim]
    modes = []
    for i in range(gdim):
        m = np.zeros((n_local, gdim))
        m[:, i] = 1.0
        modes.append(m)
    for i, j in [(0, 1)] if gdim == 2 else [(0, 1), (1, 2), (2, 0)]:
        m = np.zeros((n_local, gdim))
        m[:, i], m[:, j] = -X[:, j], X[:, i]
        modes.append(m)
    basis: list[PETSc.Vec] = []
    for m in modes:
        vec = PETSc.Vec().createMPI((n_local * gdim, PETSc.DECIDE), comm=msh.comm)
        vec.array[:] = m.ravel()
        if rotation is not None or inverse is not None:
            rotated = vec.duplicate()
            if inverse is not None:
                inverse.mult(vec, rotated)
            else:
                assert rotation is not None
                rotation.multTranspose(vec, rotated)
            vec.destroy()
            vec = rotated
        for prev in basis:  # modified Gram–Schmidt
            vec.axpy(-vec.dot(prev), prev)
        vec.normalize()
        basis.append(vec)
    return PETSc.NullSpace().create(vectors=basis, comm=msh.comm)


def von_mises(
    u_h: fem.Function, mu: float | None, lmbda_L: float | None, stresses=None
) -> fem.Function:
    """Cellwise (DG0) von Mises stress √(3/2 s:s), s the deviator of the 3D stress; in
    plane strain σ_zz = λ_L tr ε (ε_zz = 0) is included.  ``stresses``: u ↦ (P, σ) of a
    hyperelastic body (:func:`contact.models.hyperelastic.piola_and_cauchy`), whose 3 × 3
    Cauchy stress σ is used instead (at the cell's midpoint, in the current configuration)."""
    msh = u_h.function_space.mesh
    if stresses is not None:
        sig = stresses(u_h)[1]
    else:
        assert mu is not None and lmbda_L is not None, "a linear body's Lamé parameters"
        sig = stress(u_h, mu, lmbda_L)
        if msh.geometry.dim == 2:
            szz = lmbda_L * ufl.tr(epsilon(u_h))
            sig = ufl.as_matrix([[sig[0, 0], sig[0, 1], 0], [sig[1, 0], sig[1, 1], 0], [0, 0, szz]])
    dev = sig - ufl.tr(sig) / 3 * ufl.Identity(3)
    W = fem.functionspace(msh, ("DG", 0))
    out = fem.Function(W, name="von_mises")
    out.interpolate(
        fem.Expression(ufl.sqrt(1.5 * ufl.inner(dev, dev)), W.element.interpolation_points)
    )
    return out
