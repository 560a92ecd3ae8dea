"""Errors against an exact solution (docs/theory.md §7): energy / H¹-seminorm and L² norms."""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from ..base import expressions
from ..models.discrete import Problem
from ..models.physics import Elasticity
from ..solvers.problem import DiscreteProblem


def default_degree(u_h: fem.Function) -> int:
    """Quadrature degree 2p + 2 for P_p: exact for the polynomial part |∇u_h|² (degree
    2p − 2) with four orders to spare for the smooth u.  Problem A (u = −r^{3/2} cos(3θ/2),
    singular at the origin, P1) against degree 12: relative change of ‖u − u_h‖_E 7e-5 on
    the first mesh (degree 8: 3e-5), ≤ 5e-7 from 10⁴ DoFs on and 2e-8 at 4.4·10⁵ DoFs, in
    less than half the time of degree 8 (``python demos/bench/bench_error_quadrature.py``,
    demos/results/error_quadrature.csv; timings: demos/RESULTS.md §10)."""
    return 2 * u_h.function_space.element.basix_element.degree + 2


def _integrate(expr, msh, degree: int) -> float:
    dx = ufl.dx(domain=msh, metadata={"quadrature_degree": degree})
    return msh.comm.allreduce(fem.assemble_scalar(fem.form(expr * dx)), op=MPI.SUM)


def energy_error(
    u_h: fem.Function,
    exact: str | ufl.core.expr.Expr,
    k=1.0,
    constants: dict | None = None,
    quadrature_degree: int | None = None,
    t: float = 1.0,
) -> float:
    """‖u − u_h‖_E = (∫ k |∇(u − u_h)|² dx)^{1/2}, u a UFL expression or an expression
    string (in x, y, z, t and ``constants``, :mod:`contact.base.expressions`).

    The exact solution enters as a UFL expression (not an interpolant), so the error is
    exact up to quadrature of degree ``quadrature_degree`` (default :func:`default_degree`).
    """
    msh = u_h.function_space.mesh
    quadrature_degree = quadrature_degree or default_degree(u_h)
    u = expressions.to_ufl(exact, msh, constants or {}, t=t) if isinstance(exact, str) else exact
    e = ufl.grad(u - u_h)
    return float(np.sqrt(max(_integrate(k * ufl.inner(e, e), msh, quadrature_degree), 0.0)))


def elastic_energy_error(
    u_h: fem.Function,
    exact: str | list[str] | ufl.core.expr.Expr,
    mu: float,
    lmbda_L: float,
    constants: dict | None = None,
    t: float = 1.0,
    quadrature_degree: int | None = None,
) -> float:
    """‖u − u_h‖_E = a(u − u_h, u − u_h)^{1/2} = (∫ σ(e) : ε(e) dx)^{1/2}, e = u − u_h, for linear
    elasticity (Lamé μ, λ_L; plane strain in 2D), u given per component (energy per unit
    thickness in 2D, its square root in the unit √(E·L^d)); u a UFL vector, or its
    components as expression strings (one for all)."""
    from ..models.physics import epsilon, stress

    msh = u_h.function_space.mesh
    quadrature_degree = quadrature_degree or default_degree(u_h)
    e = _exact_vector(exact, msh, constants or {}, t) - u_h
    return float(
        np.sqrt(
            max(
                _integrate(ufl.inner(stress(e, mu, lmbda_L), epsilon(e)), msh, quadrature_degree),
                0.0,
            )
        )
    )


def _exact_vector(exact, msh, constants: dict, t: float):
    """A vector exact solution as UFL (given so, or one expression string per component)."""
    if not isinstance(exact, (str, list, tuple)):
        return exact
    gdim = msh.geometry.dim
    texts = [exact] * gdim if isinstance(exact, str) else list(exact)
    if len(texts) != gdim:
        from ..base.errors import ConfigError

        raise ConfigError(
            f"data.exact: a {gdim}D elasticity scene needs {gdim} components, got {len(texts)}"
        )
    return ufl.as_vector([expressions.to_ufl(e, msh, constants, t=t) for e in texts])


def solution_error(problem: DiscreteProblem, result) -> float | None:
    """The energy error of ``result`` against the exact solution the problem's physics
    declares (None without one): k-weighted for the scalar equations, the elastic energy
    norm for elasticity."""
    physics = problem.physics if isinstance(problem, Problem) else None
    if physics is None or physics.exact is None:
        return None
    if isinstance(physics, Elasticity):
        return elastic_energy_error(result.u_h, physics.exact, physics.mu, physics.lmbda)
    return energy_error(result.u_h, physics.exact, physics.k)


def l2_error(
    u_h: fem.Function,
    exact: str,
    constants: dict | None = None,
    quadrature_degree: int | None = None,
) -> float:
    """‖u − u_h‖_{L²(Ω)} (quadrature of degree 2p + 2 unless given)."""
    msh = u_h.function_space.mesh
    quadrature_degree = quadrature_degree or default_degree(u_h)
    u = expressions.to_ufl(exact, msh, constants or {})
    return float(np.sqrt(max(_integrate((u - u_h) ** 2, msh, quadrature_degree), 0.0)))
