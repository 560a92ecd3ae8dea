"""A Poisson problem whose equilibrated flux the estimator tests reconstruct, shared by
tests/test_equilibration.py and tests/test_equilibration_backends.py."""

from __future__ import annotations

from contact.adaptivity.equilibration import FluxData

import numpy as np
import ufl
from dolfinx import fem, mesh
from dolfinx.fem.petsc import LinearProblem
from mpi4py import MPI


def integral(expr, msh, degree=8):
    """∫ expr dx over the mesh (quadrature of the given degree), summed over the ranks."""
    dx = ufl.dx(domain=msh, metadata={"quadrature_degree": degree})
    return msh.comm.allreduce(fem.assemble_scalar(fem.form(expr * dx)), op=MPI.SUM)


def poisson(d: int, p: int, n: int):
    """−div(k∇u) = f on the unit square / cube, u = u_D on x < 1 (tag 1), k∂u/∂n = t on x = 1
    (tag 2), u cubic and k = 1 + x² (f and t polynomials that the reconstruction's quadrature
    of degree 2p + 4 integrates exactly); returns (data, exact u, Neumann measure)."""
    msh = (
        mesh.create_unit_square(MPI.COMM_WORLD, n, n)
        if d == 2
        else mesh.create_unit_cube(MPI.COMM_WORLD, n, n, n)
    )
    V = fem.functionspace(msh, ("Lagrange", p))
    x = ufl.SpatialCoordinate(msh)
    k = 1 + x[0] ** 2
    u_ex = (
        x[0] ** 3
        + x[0] ** 2 * x[1]
        - x[1] ** 3 / 3
        + (0 if d == 2 else x[2] ** 3 - x[0] * x[2] ** 2)
    )
    f = -ufl.div(k * ufl.grad(u_ex))
    msh.topology.create_connectivity(d - 1, d)
    facets = mesh.exterior_facet_indices(msh.topology)
    values = np.where(mesh.compute_midpoints(msh, d - 1, facets)[:, 0] > 1 - 1e-10, 2, 1).astype(
        np.int32
    )
    tags = mesh.meshtags(msh, d - 1, facets, values)
    t = k * ufl.grad(u_ex)[0]
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
    u_D = fem.Function(V)
    u_D.interpolate(fem.Expression(u_ex, V.element.interpolation_points))
    bc = fem.dirichletbc(u_D, fem.locate_dofs_topological(V, d - 1, facets[values == 1]))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    problem = LinearProblem(
        k * ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx,
        f * v * ufl.dx + t * v * ds(2),
        bcs=[bc],
        petsc_options_prefix="eq_poisson_",
        petsc_options={"ksp_type": "preonly", "pc_type": "lu"},
    )
    u_h = problem.solve()
    return FluxData(u_h, f, k, tags, dirichlet=(1,), neumann={2: t}), u_ex, ds(2)
