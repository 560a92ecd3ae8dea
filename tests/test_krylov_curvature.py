"""The energy search with CG + GAMG instead of LDLᵀ (contact/solvers/krylov_curvature.py), and
P2 contact on 3D meshes (contact/models/problem.py's lumped weights).

Checked: the Lanczos estimate tells a definite from an indefinite matrix; the Krylov energy
search follows the SVK strip through its buckling load like the factorized one (the same
Newton step meets the indefinite tangent, the same states to solver tolerance); a 3D dome
pressed by a plate takes the Krylov path by default and gives the direct path's forces; the
tangent predictor's CG solve equals its LU solve; P2 on a 3D boundary has positive weights
that sum to the area and a P2 hyperelastic dome and a linear elastic one converge."""

from __future__ import annotations

import contact
from contact.setup.posed import posed_of
from contact.solvers.krylov_curvature import lanczos_negative

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc
from test_hyperelastic import NU, E


def dome(degree: int = 1, cells=(4, 4, 3), steps: int = 2, law: str = "neo_hookean") -> dict:
    """A 3D body with a curved bottom z = c (x² + y²) (a quarter: x = 0, y = 0 symmetry
    planes), its top z = 0.5 clamped, pressed by the rigid plate z = 0.08 t from below."""
    return {
        "name": "dome",
        "mesh": {
            "type": "box",
            "corners": [[0, 0, 0], [1, 1, 0.5]],
            "cells": list(cells),
            "degree": degree,
            "map": ["x", "y", "z + 0.2*(x*x + y*y)*(1 - 2*z)"],
        },
        "boundaries": {
            "sym_x": {"role": "symmetry", "where": "x < 1e-10"},
            "sym_y": {"role": "symmetry", "where": "y < 1e-10"},
            "bottom": {"role": "contact", "where": "z < 0.2*(x*x + y*y) + 1e-10"},
            "top": {"role": "dirichlet", "where": "z > 0.5 - 1e-10"},
        },
        "model": {"type": "hyperelastic", "law": law, "E": E, "nu": NU},
        "obstacle": {"type": "plane", "point": [0, 0, "0.08*t"], "normal": [0, 0, 1]},
        "load": {"steps": steps},
        "output": {"verbose": False},
    }


def laplacian(n: int, shift: float) -> PETSc.Mat:
    """The 1D Dirichlet Laplacian tridiag(−1, 2, −1) − shift·I (eigenvalues
    2 − 2 cos(kπ/(n+1)) − shift), distributed over the ranks."""
    A = PETSc.Mat().createAIJ((n, n), nnz=3, comm=MPI.COMM_WORLD)
    lo, hi = A.getOwnershipRange()
    for i in range(lo, hi):
        A.setValue(i, i, 2.0 - shift)
        if i > 0:
            A.setValue(i, i - 1, -1.0)
        if i < n - 1:
            A.setValue(i, i + 1, -1.0)
    A.assemble()
    return A


def test_the_lanczos_estimate_tells_definite_from_indefinite():
    """The smallest eigenvalue of tridiag(−1, 2, −1) of order 200 is 2 − 2cos(π/201) ≈ 2.4e-4:
    shifted by half of it the matrix is definite (0), by twice it indefinite with one
    negative eigenvalue (1), and by 0.02 indefinite with several (still 1: 'at least one')."""
    n = 200
    lam1 = 2 - 2 * np.cos(np.pi / (n + 1))
    for shift, expected in ((0.5 * lam1, 0), (2 * lam1, 1), (0.02, 1)):
        A = laplacian(n, shift)
        try:
            assert lanczos_negative(A, None, 2, "test_lanczos_") == expected, shift
        finally:
            A.destroy()


def test_the_krylov_energy_search_follows_the_strip_through_its_buckling_load():
    """configs/hyperelastic_strip.yaml (SVK, past Euler's load at t = 1.034) with
    ``solver.linear: gamg``: CG + GAMG with the indefiniteness test meets the indefinite
    tangent first at the same Newton step of the same load step as LDLᵀ's inertia (step 7,
    t = 1.04, iteration 0), takes the same number of Newton steps give or take one (its
    steps are inexact), and reaches the same
    states: the wall's force to 1e-8 relative at every step and the buckled strip's
    lateral deflection to 1e-6 relative."""
    runs = {}
    for linear in ("direct", "gamg"):
        scene = contact.load_scene("configs/hyperelastic_strip.yaml", [f"solver.linear={linear}"])
        path = contact.run_load_path(scene, keep_all=True)
        assert path.converged
        runs[linear] = path
    direct, krylov = runs["direct"], runs["gamg"]
    assert krylov.steps[-1].result.linear == "gamg" and direct.steps[-1].result.linear == "direct"
    for a, b in zip(direct.steps, krylov.steps):
        fa, fb = a.result.contact_force, b.result.contact_force
        assert abs(fa - fb) <= 1e-8 * abs(fa), (a.index, fa, fb)
        # CG's inexact steps (Eisenstat–Walker forcing) may cost one Newton step more
        assert abs(a.result.iterations - b.result.iterations) <= 1, a.index

    def first_negative(path):
        return [
            (s.index, e["iteration"])
            for s in path.steps
            for e in s.result.tangent_log
            if e["negative"]
        ][:1]

    assert first_negative(direct) == first_negative(krylov) == [(7, 0)]
    buckled = [s.index for s in krylov.steps if any(e["negative"] for e in s.result.tangent_log)]
    assert buckled == [7]
    ya = direct.steps[-1].result.u_h.x.array[1::2]
    yb = krylov.steps[-1].result.u_h.x.array[1::2]
    assert np.max(np.abs(ya)) > 1e-3  # buckled sideways
    assert np.max(np.abs(ya - yb)) <= 1e-6 * np.max(np.abs(ya))


def test_a_3d_body_takes_the_krylov_energy_search_and_the_direct_path_s_forces():
    """The neo-Hookean dome pressed by a plate in 2 steps: by default the Newton steps are
    CG + GAMG (``result.linear`` gamg, the energy search on, the predictor by CG); the forces
    equal those of the factorized energy search (``solver.linear: direct``) to 1e-9
    relative, every step converges in at most 12 Newton steps, and the stability check is
    the Lanczos estimate (0 negative eigenvalues seen)."""
    forces = {}
    for linear in ("auto", "direct"):
        scene = contact.load_scene(dome(), [f"solver.linear={linear}"])
        path = contact.run_load_path(scene)
        assert path.converged
        last = path.steps[-1]
        assert last.result.linear == ("gamg" if linear == "auto" else "direct")
        assert all(s.result.iterations <= 12 for s in path.steps)
        assert last.negative_eigenvalues == 0
        forces[linear] = [s.result.contact_force for s in path.steps]
    assert forces["auto"][-1] > 0
    np.testing.assert_allclose(forces["auto"], forces["direct"], rtol=1e-9)


def test_p2_weights_on_a_3d_boundary_are_positive_and_sum_to_the_area():
    """P2 on the boundary triangles of a tetrahedral mesh: every node of the contact face
    (vertices and edge midpoints) gets a positive weight, and the weights add up to the
    face's area (the P1-iso-P2 rule is exact for constants)."""
    from contact.models.problem import lumped_weights

    import ufl
    from dolfinx import fem, mesh

    msh = mesh.create_unit_cube(MPI.COMM_WORLD, 3, 2, 2)
    V = fem.functionspace(msh, ("Lagrange", 2))
    facets = mesh.locate_entities_boundary(msh, 2, lambda x: np.isclose(x[2], 0.0))
    tags = mesh.meshtags(msh, 2, facets, np.full(len(facets), 1, dtype=np.int32))
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
    w = lumped_weights(V, ds(1))
    dofs = fem.locate_dofs_topological(V, 2, facets)
    owned = dofs[dofs < V.dofmap.index_map.size_local]
    assert np.all(w[owned] > 0)
    total = MPI.COMM_WORLD.allreduce(float(np.sum(w[owned])), op=MPI.SUM)
    assert abs(total - 1.0) <= 1e-12


def test_p2_contact_on_3d_meshes():
    """P2 on tetrahedra: the hyperelastic dome (2 steps, Krylov energy search) converges and
    its force lies between P1's on the same mesh and P1's on the mesh refined once (P1 is too
    stiff); the linear elastic dome converges with the contact force equal to the reaction
    at the clamped top to 1e-9 relative."""
    p2 = contact.run_load_path(contact.load_scene(dome(degree=2)))
    p1 = contact.run_load_path(contact.load_scene(dome()))
    p1f = contact.run_load_path(contact.load_scene(dome(cells=(8, 8, 6))))
    assert p2.converged and p1.converged and p1f.converged
    f2, f1, f1f = (p.steps[-1].result.contact_force for p in (p2, p1, p1f))
    assert f1f < f1 and f2 < f1, (f2, f1, f1f)
    cfg = dome(degree=2)
    cfg["model"] = {"type": "elasticity", "E": E, "nu": NU}
    cfg["obstacle"]["point"] = [0, 0, 0.02]
    del cfg["load"]
    scene = contact.load_scene(cfg)
    result = contact.solve(scene)
    assert result.converged and result.n_active > 0
    from contact.post.resultants import contact_resultants

    res = contact_resultants(posed_of(scene), result)
    assert abs(res["force_balance_error"]) <= 1e-9, res
