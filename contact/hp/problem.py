"""The scalar Signorini problem in V_hp (docs/theory.md §1.1, §11): the discrete problem of
the solvers, in the hp unknowns x (u = Q x).

K and b are assembled in V = P_{p_max} without boundary conditions and reduced,

    K_hp = Qᵀ K Q,   b_hp = Qᵀ b,

then the fixed unknowns — the inactive slots (x = 0) and the Dirichlet ones (x = the hp
interpolant of u_D: vertex values and the values at the edge (face) nodes, docs/theory.md
§11) — are eliminated symmetrically (identity rows and columns, the lifting moved into
b_hp).  On Γ_C every unknown of an edge of degree p_E is the value of u_h at a Lagrange node
of degree p_E (:mod:`.reference`), so the contact condition stays nodal: u_h(z_i) ≤ g(z_i) at
the vertices and Lagrange nodes of the contact facets, with the lumped weights

    w_i = ∫_{Γ_C} ψ_i ds = (Qᵀ w^{p_max})_i,   w^{p_max}_j = ∫_{Γ_C} φ_j ds,

positive: on a segment ψ_i's trace is the Lagrange function of degree p_E at Gauss–Lobatto
points, whose integrals are the Gauss–Lobatto weights (that rule is exact to degree
2p_E − 1 ≥ p_E).  In 3D the contact facets keep degree 1 (a quadratic triangle's vertex
functions integrate to 0).  Between nodes u_h may cross g for p_E ≥ 2; the equilibrated
bound measures that (its feasibility lifting), the solver does not see it.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import dolfinx.fem.petsc
import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..base import expressions
from ..base.errors import ConfigError
from ..models.constraints import Unilateral
from ..models.discrete import Problem
from ..models.problem import contact_ends, lumped_weights
from ..setup.checks import check_scene_data
from ..setup.data import interpolate_expression
from ..setup.scalar import scalar_forms, scalar_physics
from ..setup.scene import Scene
from ..solvers.problem import Constraint, Output, ProblemData
from .precondition import PatchPreconditioner
from .space import HPSpace


class HPProblem(Problem):
    """A problem (:class:`~contact.models.discrete.Problem`) in the hp unknowns x: its nodal
    outputs (λ_h, gap, active set) are hp functions mapped to V by Q, so that λ_h is the
    Lagrange interpolant of degree p_E of the nodal multipliers on each contact facet."""

    space: HPSpace

    variable_degree = True

    def unknowns(self) -> int:
        """The hp unknowns (every component), not V's DoFs: the inactive slots are
        eliminated rows (which size decides ``solver.linear: auto``)."""
        return self.space.dimension * self.V.dofmap.index_map_bs

    def patch_preconditioner(self) -> Callable[[PETSc.PC], None]:
        """The two-level vertex-patch preconditioner of the hp space
        (:mod:`.precondition`), built once per problem; 2D only (3D is not measured).

        Returns:
            The :class:`~.precondition.PatchPreconditioner` of the space.
        """
        if self.V.mesh.topology.dim != 2:
            raise ConfigError("solver.linear: hp_patch applies to 2D hp problems only")
        if self._patch is None:
            self._patch = PatchPreconditioner(self.space)
        return self._patch

    def destroy(self) -> None:
        """Destroy the PETSc objects of the problem and of its preconditioner."""
        if self._patch is not None:
            self._patch.destroy()
            self._patch = None
        super().destroy()

    #: the patch preconditioner once built (:meth:`patch_preconditioner`)
    _patch: PatchPreconditioner | None = None

    def nodal_output(self, name: str, values: np.ndarray) -> fem.Function:
        """``values`` at the constrained unknowns (0 at the other unknowns), as the function
        Q x of V (λ_h also at the ends of Γ_C)."""
        fn = self.unknowns_function(name, values)
        out = fem.Function(self.V, name=name)
        assert self.basis is not None
        self.basis.mult(fn.x.petsc_vec, out.x.petsc_vec)
        out.x.scatter_forward()
        return out

    def gap_output(self, x: np.ndarray) -> fem.Function:
        """The gap g − u_h on the contact facets (the hp interpolant of the nodal gaps),
        NaN at the other DoFs of V."""
        con = self.constraint
        gap = self.nodal_output("gap", con.sign * (con.g - x[con.dofs]))
        gap.x.array[~self.space_contact] = np.nan
        return gap

    @property
    def space_contact(self) -> np.ndarray:
        """Mask of the DoFs of V on the closure of Γ_C (local, owned and ghost)."""
        assert self.data.contact_mask is not None  # set when built
        return self.data.contact_mask


def reduce_system(a: fem.Form, L: fem.Form, Q: PETSc.Mat) -> tuple[PETSc.Mat, PETSc.Vec]:
    """K_hp = Qᵀ K Q and b_hp = Qᵀ b of the forms a and L assembled in P_{p_max} (no
    boundary conditions; collective)."""
    K = dolfinx.fem.petsc.assemble_matrix(a)
    K.assemble()
    b = dolfinx.fem.petsc.assemble_vector(L)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]
    K_hp = K.PtAP(Q)  # Qᵀ K Q
    K.destroy()
    b_hp = K_hp.createVecRight()
    Q.multTranspose(b, b_hp)
    b.destroy()
    return K_hp, b_hp


def eliminate(
    K: PETSc.Mat, b: PETSc.Vec, inactive: np.ndarray, fixed: np.ndarray, values: fem.Function
) -> None:
    """Fix the unknowns ``fixed`` (local, unrolled) of K x = b at ``values`` symmetrically:
    identity rows and columns, the lifting moved into b.  The rows ``inactive`` (a mask over
    the owned unknowns) are empty in K: they get a diagonal first, added as a matrix (the
    merged pattern is built once, where inserting into K's rows reallocates its storage row
    by row)."""
    ones = K.createVecRight()
    ones.array_w[:] = inactive.astype(float)
    D = PETSc.Mat().createAIJ(K.getSizes(), nnz=1, comm=K.getComm())  # type: ignore[arg-type]
    D.setDiagonal(ones)
    D.assemble()
    K.axpy(1.0, D, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)  # type: ignore[arg-type]
    D.destroy()
    ones.destroy()
    V = values.function_space
    bs = V.dofmap.index_map_bs
    owned = fixed[fixed < V.dofmap.index_map.size_local * bs]
    rows = V.dofmap.index_map.local_to_global(owned // bs) * bs + owned % bs
    K.zeroRowsColumns(rows.astype(PETSc.IntType), diag=1.0, x=values.x.petsc_vec, b=b)


def hp_problem(scene: Scene, space: HPSpace) -> HPProblem:
    """Assemble the scalar Signorini problem of ``scene`` in ``space`` (module docstring).

    Args:
        scene: A scalar Signorini scene on ``space``'s mesh.
        space: The hp space.

    Returns:
        The discrete problem in the hp unknowns (``basis`` Q, ``basis_inverse`` L).

    Raises:
        ConfigError: For a model other than signorini (the obstacle constrains every node,
            and a cell's interior unknowns of V_hp are no nodal values).
    """
    t0 = time.perf_counter()
    cfg, msh, bnd = scene.config, scene.mesh, scene.boundary
    if cfg.model.type != "signorini":
        raise ConfigError(
            f"adapt.strategy: hp solves the scalar signorini model, not {cfg.model.type!r}"
        )
    if msh is not space.mesh:
        raise ValueError("space: built on another mesh than the scene's")
    check_scene_data(scene)
    data = cfg.data
    V = space.V
    tdim = msh.topology.dim
    a, L_form, forms = scalar_forms(scene, V)
    contact_ids = bnd.ids_with_role("contact")
    Q, Linv = space.matrices()
    K_hp, b_hp = reduce_system(a, L_form, Q)

    imap = V.dofmap.index_map
    n_owned = imap.size_local
    consts = cfg.constants
    dirichlet = space.slots_of(tdim - 1, bnd.facets("dirichlet"))
    assert isinstance(data.u_D, str) and isinstance(data.g, str)  # a scalar model's
    x_D = space.interpolate(expressions.to_numpy(data.u_D, consts, t=scene.time))
    fixed_mask = ~space.active
    fixed_mask[dirichlet] = True
    values = fem.Function(V)
    values.x.array[dirichlet] = x_D[dirichlet]
    fixed = np.flatnonzero(fixed_mask).astype(np.int32)
    eliminate(K_hp, b_hp, ~space.active[:n_owned], fixed, values)
    bcs = [fem.dirichletbc(values, fixed)]

    # Γ_C: the nodal constraint at the active slots of the contact facets' closure
    contact_facets = bnd.facets("contact")
    candidates = space.slots_of(tdim - 1, contact_facets)
    owned = candidates[candidates < n_owned]
    dofs = np.setdiff1d(owned, dirichlet).astype(np.int32)
    w_max = fem.Function(V)
    w_max.x.array[:n_owned] = lumped_weights(V, forms["ds"](contact_ids))
    w_hp = fem.Function(V)
    Q.multTranspose(w_max.x.petsc_vec, w_hp.x.petsc_vec)
    w = w_hp.x.array[dofs].copy()
    if msh.comm.allreduce(bool(np.any(w <= 0)), op=MPI.LOR):
        raise ConfigError(
            "adapt.p_max: a contact node of V_hp has lumped weight <= 0 (a Gauss–Lobatto "
            "rule of this degree); lower adapt.p_max"
        )
    g = expressions.to_numpy(data.g, consts, t=scene.time)(space.points[dofs].T)
    constraint = Constraint(dofs, np.asarray(g, dtype=float).copy(), w, 1.0)
    contact_mask = np.zeros(len(space.active), dtype=bool)
    contact_mask[fem.locate_dofs_topological(V, tdim - 1, contact_facets)] = True
    end_dofs, end_neighbours = contact_ends(V, owned, candidates, dirichlet)
    g_h = interpolate_expression(V, data.g, scene)
    problem = HPProblem(
        V,
        fem.Function(V, name="u_h"),
        bcs,
        K_hp,
        b_hp,
        constraint,
        basis=Q,
        basis_inverse=Linv,
        output=Output(ends=end_dofs, end_neighbours=end_neighbours),
        data=ProblemData(**forms, g_h=g_h, contact_mask=contact_mask),
        assembly_time=time.perf_counter() - t0,
        physics=scalar_physics(scene, forms),
        contacts=(
            Unilateral(g_h, side="upper", measure=forms["ds"](contact_ids), nodal=lambda _: g_h),
        ),
    )
    problem.space = space
    return problem
