"""A p-robust preconditioner of the hp systems (``solver.linear: hp_patch``).

The reduced Newton system A of a scalar hp problem (K_hp = Qᵀ K Q with its fixed rows
eliminated, :mod:`contact.solvers.reduced`) is solved by CG with a two-level preconditioner:

* coarse space: the P1 space, x = P x_1 with P = L I_1 (I_1 the interpolation P1 → P_{p_max},
  L the hp left inverse of Q; P1 ⊂ V_hp, so P is exact), the Galerkin coarse matrix Pᵀ A P
  solved by one GAMG V-cycle;
* smoother: two Chebyshev steps preconditioned by additive Schwarz on the vertex patches
  (the active unknowns of the vertex, of its edges' interiors, of its faces' interiors in 3D
  and of its cells' interiors; one LU per patch), the p-robust choice of Schöberl, Melenk,
  Pechstein & Zaglmayr (IMA J. Numer. Anal. 28, 2008) and Pavarino (Numer. Math. 66, 1994).

The patches are built from each rank's owned cells and unknowns: across rank boundaries a
patch is cut, which keeps the preconditioner symmetric positive definite.
"""

from __future__ import annotations

import dolfinx.fem.petsc
import numpy as np
from dolfinx import fem
from petsc4py import PETSc

from .space import HPSpace

#: Chebyshev smoothing steps on the fine level
SMOOTHING_STEPS = 2


def coarse_interpolation(space: HPSpace) -> PETSc.Mat:
    """P: the P1 coefficients to the hp unknowns, x = L I_1 x_1 (P1 ⊂ V_hp, so exact).

    Args:
        space: the hp space.

    Returns:
        The matrix P (rows: V = P_{p_max}'s layout, columns: P1's); the caller destroys it.
    """
    V1 = fem.functionspace(space.mesh, ("Lagrange", 1))
    interp = dolfinx.fem.petsc.interpolation_matrix(V1, space.V)
    interp.assemble()
    _, L = space.matrices()
    P = L.matMult(interp)
    interp.destroy()
    L.destroy()
    return P


def _ref_edges(tdim: int) -> list[tuple[int, int]]:
    """The reference cell's edges by their vertices (DOLFINx's numbering)."""
    if tdim == 2:
        return [(1, 2), (0, 2), (0, 1)]
    return [(2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1)]


def vertex_patches(space: HPSpace) -> list[PETSc.IS]:
    """The owned active unknowns of each owned vertex's patch (module docstring), as index
    sets of global row numbers.

    Args:
        space: the hp space.

    Returns:
        One index set per owned vertex (on PETSc.COMM_SELF); the caller destroys them.
    """
    msh, V = space.mesh, space.V
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    c2v = msh.topology.connectivity(tdim, 0).array.reshape(-1, tdim + 1)
    layout = V.dofmap.dof_layout
    edges_of = [
        [e for e, ends in enumerate(_ref_edges(tdim)) if a in ends] for a in range(tdim + 1)
    ]
    local = [
        np.concatenate(
            [layout.entity_dofs(0, a)]
            + [layout.entity_dofs(1, e) for e in edges_of[a]]
            + ([layout.entity_dofs(2, f) for f in range(4) if f != a] if tdim == 3 else [])
            + [layout.entity_dofs(tdim, 0)]
        ).astype(np.int64)
        for a in range(tdim + 1)
    ]
    n_vertices = msh.topology.index_map(0).size_local
    n_cells = msh.topology.index_map(tdim).size_local
    dofs = V.dofmap.list
    members: list[list[np.ndarray]] = [[] for _ in range(n_vertices)]
    for c in range(n_cells):
        for a in range(tdim + 1):
            v = c2v[c, a]
            if v < n_vertices:
                members[v].append(dofs[c][local[a]])
    imap = V.dofmap.index_map
    owned, first = imap.size_local, imap.local_range[0]
    out = []
    for parts in members:
        if not parts:
            continue
        idx = np.unique(np.concatenate(parts))
        idx = idx[(idx < owned) & space.active[idx]]
        if len(idx):
            out.append(
                PETSc.IS().createGeneral((idx + first).astype(PETSc.IntType), comm=PETSc.COMM_SELF)
            )
    return out


class PatchPreconditioner:
    """Makes a PC the two-level patch preconditioner of the hp space (module docstring).

    P and the patches depend on the space only (not on the active set), so they are built
    once and set again whenever the PC is reset.

    Args:
        space: the hp space (scalar).
    """

    def __init__(self, space: HPSpace):
        self.P = coarse_interpolation(space)
        self.patches = vertex_patches(space)

    def __call__(self, pc: PETSc.PC) -> None:
        """Set ``pc`` up as the two-level preconditioner (its operators are the Newton
        system's; the coarse matrix is PCMG's Galerkin product, option ``pc_mg_galerkin``)."""
        pc.setType("mg")
        pc.setMGLevels(2)
        pc.setMGType(PETSc.PC.MGType.MULTIPLICATIVE)  # type: ignore[arg-type]
        pc.setMGCycleType(PETSc.PC.MGCycleType.V)  # type: ignore[arg-type]
        pc.setMGInterpolation(1, self.P)
        pc.setMGRestriction(1, self.P)
        coarse = pc.getMGCoarseSolve()
        coarse.setType("preonly")
        coarse.getPC().setType("gamg")
        smoother = pc.getMGSmoother(1)
        smoother.setType("chebyshev")  # eigenvalue estimates of the preconditioned A
        smoother.setTolerances(max_it=SMOOTHING_STEPS)
        spc = smoother.getPC()
        spc.setType("asm")
        spc.setASMType(PETSc.PC.ASMType.BASIC)  # type: ignore[arg-type]
        spc.setASMOverlap(0)
        spc.setASMLocalSubdomains(len(self.patches), self.patches)

    def destroy(self) -> None:
        self.P.destroy()
        for s in self.patches:
            s.destroy()
