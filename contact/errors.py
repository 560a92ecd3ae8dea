"""Errors against an exact solution (SPEC §7): energy / H¹-seminorm and L² norms."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

import ufl
from dolfinx import fem

from . import expressions


def _integrate(expr, msh, degree: int) -> float:
    dx = ufl.dx(domain=msh, metadata={"quadrature_degree": degree})
    return msh.comm.allreduce(fem.assemble_scalar(fem.form(expr * dx)), op=MPI.SUM)


def energy_error(u_h: fem.Function, exact: str, k=1.0, constants: dict | None = None,
                 quadrature_degree: int = 8) -> float:
    """‖u − u_h‖_E = (∫ k |∇(u − u_h)|² dx)^{1/2}, u given as an expression string.

    The exact solution enters as a UFL expression (not an interpolant), so the error is
    exact up to quadrature of degree ``quadrature_degree``.
    """
    msh = u_h.function_space.mesh
    u = expressions.to_ufl(exact, msh, constants or {})
    e = ufl.grad(u - u_h)
    return float(np.sqrt(max(_integrate(k * ufl.inner(e, e), msh, quadrature_degree), 0.0)))


def l2_error(u_h: fem.Function, exact: str, constants: dict | None = None,
             quadrature_degree: int = 8) -> float:
    """‖u − u_h‖_{L²(Ω)}."""
    msh = u_h.function_space.mesh
    u = expressions.to_ufl(exact, msh, constants or {})
    return float(np.sqrt(max(_integrate((u - u_h) ** 2, msh, quadrature_degree), 0.0)))
