"""The equations a problem discretises, as the estimators and reports read them.

A contact problem is an equilibrium

    −div σ(u) = f  in Ω,    u = u_D  on Γ_D,    σ(u) n = t  on Γ_N,    σ(u) n = 0  on Γ_free,

with σ(u) = k ∇u (:class:`Diffusion`, scalar Signorini and obstacle problems,
docs/theory.md §1.1–1.2) or the stress of an elastic body (:class:`Elasticity`, linear or
hyperelastic, §1.3), and contact conditions on other facets or in Ω (the constraint objects
of :mod:`.constraints`).  The residual estimator (docs/theory.md §5) checks each of these
equations with u_h; the equilibrated bound (§9) reconstructs a flux that satisfies them.  The
forms a solver assembles say none of this (a(u, v) = ∫ k ∇u·∇v dx could come from any flux):
a problem declares it once, as one of these objects, when it is built.

The data are UFL (numbers, ``fem.Constant``, functions or expressions of
``ufl.SpatialCoordinate``); the boundary parts are the values of facet tags
(:class:`BoundaryData`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh

#: a coefficient of the equations: a number, a ``fem.Constant``/``fem.Function`` or a UFL
#: expression
Coefficient = Any


def epsilon(u: Any) -> Any:
    """ε(u) = sym ∇u."""
    return ufl.sym(ufl.grad(u))


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lamé parameters (μ, λ_L) of Young's modulus E and Poisson's ratio ν."""
    return E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))


def stress(u: Any, mu: Coefficient, lmbda_L: Coefficient) -> Any:
    """σ(u) = 2μ ε(u) + λ_L tr ε(u) I (plane strain when 2D)."""
    eps = epsilon(u)
    return 2.0 * mu * eps + lmbda_L * ufl.tr(eps) * ufl.Identity(len(u))


#: the hyperelastic laws of :class:`Elasticity`
LAWS = ("neo_hookean", "saint_venant_kirchhoff")


def deformation_gradient(u: Any) -> Any:
    """F = I + ∇u as a 3 × 3 tensor (2D: plane strain, F_33 = 1)."""
    gdim = len(u)
    F = ufl.Identity(gdim) + ufl.grad(u)
    if gdim == 3:
        return F
    return ufl.as_matrix([[F[0, 0], F[0, 1], 0], [F[1, 0], F[1, 1], 0], [0, 0, 1]])


def strain_energy(F: Any, law: str, mu: Coefficient, lmbda_L: Coefficient) -> Any:
    """Return the strain energy ψ(F) per unit reference volume.

    ψ(F) per unit reference volume (F 3 × 3):

        neo-Hookean (compressible):   ψ = μ/2 (tr C − 3 − 2 ln J) + λ_L/2 (ln J)²,
        St Venant–Kirchhoff:          ψ = λ_L/2 (tr E)² + μ E:E,

    C = FᵀF, J = det F, E = ½(C − I) (``hyperelastic``).
    """
    C = F.T * F
    if law == "neo_hookean":
        lnJ = ufl.ln(ufl.det(F))
        return mu / 2 * (ufl.tr(C) - 3 - 2 * lnJ) + lmbda_L / 2 * lnJ**2
    if law == "saint_venant_kirchhoff":
        E = (C - ufl.Identity(3)) / 2
        return lmbda_L / 2 * ufl.tr(E) ** 2 + mu * ufl.inner(E, E)
    raise ValueError(f"model.law: expected one of {', '.join(LAWS)}, got {law!r}")


def piola_and_cauchy(u: Any, law: str, mu: Coefficient, lmbda_L: Coefficient) -> tuple:
    """Return the first Piola–Kirchhoff and the Cauchy stress of a hyperelastic law.

    (P, σ): the first Piola–Kirchhoff stress P = ∂ψ/∂F (gdim × gdim, for the residual's
    tractions in the reference configuration) and the Cauchy stress σ = J⁻¹ P Fᵀ (3 × 3,
    σ_33 ≠ 0 in plane strain), both in the unit of E.
    """
    gdim = len(u)
    F = ufl.variable(deformation_gradient(u))
    P = ufl.diff(strain_energy(F, law, mu, lmbda_L), F)
    sigma = P * F.T / ufl.det(F)
    return ufl.as_matrix([[P[i, j] for j in range(gdim)] for i in range(gdim)]), sigma


@dataclass(frozen=True)
class BoundaryData:
    """The boundary parts of a problem, by facet tag value.

    Args:
        tags: the facet tags (``dolfinx.mesh.MeshTags`` of dimension tdim − 1).
        dirichlet: tags of Γ_D (u = u_D).
        neumann: tag → the given flux / traction t on that part (Γ_N, or the load t_C on a
            contact part Γ_C).
        free: tags of traction-free parts (σ(u) n = 0).
        symmetry: (tag, k) pairs: a symmetry plane x_k = const, u_k = 0 there (elasticity).

    Example:
        >>> import contact, numpy as np
        >>> from dolfinx import mesh
        >>> from mpi4py import MPI
        >>> msh = mesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
        >>> top = mesh.locate_entities_boundary(msh, 1, lambda x: x[1] > 1 - 1e-12)
        >>> tags = mesh.meshtags(msh, 1, np.sort(top), 1)
        >>> parts = contact.BoundaryData(tags, dirichlet=(1,))
        >>> MPI.COMM_WORLD.allreduce(len(parts.facets((1,))))
        4
    """

    tags: dmesh.MeshTags
    dirichlet: tuple[int, ...] = ()
    neumann: Mapping[int, Coefficient] = field(default_factory=dict)
    free: tuple[int, ...] = ()
    symmetry: tuple[tuple[int, int], ...] = ()

    def measure(self, mesh: dmesh.Mesh) -> ufl.Measure:
        """``ds`` over these facet tags."""
        return ufl.Measure("ds", domain=mesh, subdomain_data=self.tags)

    def facets(self, ids: tuple[int, ...] | list[int]) -> np.ndarray:
        """The local facets (sorted) whose tag is one of ``ids``."""
        return np.sort(self.tags.indices[np.isin(self.tags.values, ids)]).astype(np.int32)


@dataclass(frozen=True)
class Diffusion:
    """−div(k ∇u) = f in Ω (the scalar Signorini and obstacle problems).

    Args:
        k: the conductivity (> 0).
        f: the source.
        boundary: the boundary parts and their data.
        exact: the exact solution u, if known (the true error beside the estimate).
        dirichlet_value: u_D interpolated into a given Lagrange space (the equilibrated
            bound's Dirichlet term); None: u_h's own values on Γ_D are exact.

    Example:
        >>> import contact, numpy as np
        >>> from dolfinx import fem, mesh
        >>> from mpi4py import MPI
        >>> msh = mesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
        >>> facets = mesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
        >>> tags = mesh.meshtags(msh, 1, np.sort(facets), 1)
        >>> one = fem.Constant(msh, 1.0)
        >>> physics = contact.Diffusion(one, one, contact.BoundaryData(tags, dirichlet=(1,)))
        >>> physics.flux(fem.Function(fem.functionspace(msh, ("Lagrange", 1)))).ufl_shape
        (2,)
    """

    k: Coefficient
    f: Coefficient
    boundary: BoundaryData
    exact: Coefficient | None = None
    dirichlet_value: Callable[[fem.FunctionSpace], fem.Function] | None = None

    def flux(self, u: Any) -> Any:
        """σ(u) = k ∇u."""
        return self.k * ufl.grad(u)


@dataclass(frozen=True)
class Elasticity:
    """The equations of an elastic body: −div σ(u) = f in Ω.

    σ(u) = 2μ ε(u) + λ_L tr ε(u) I (plane strain in 2D) when ``law`` is None, else the
    first Piola–Kirchhoff stress P(u) of the hyperelastic ``law`` (neo_hookean,
    saint_venant_kirchhoff; ``hyperelastic``).

    Args:
        mu: the Lamé parameter μ (a number, or a DG0 function for several bodies).
        lmbda: the Lamé parameter λ_L (idem).
        f: the body load (a vector).
        boundary: the boundary parts and their data (tractions t on Γ_N).
        law: None (linear, small strain) or the hyperelastic law.
        dirichlet_value: u_D as UFL (the equilibrated bound's Dirichlet lifting), or None.
        exact: the exact displacement, if known.

    Example:
        >>> import contact, numpy as np
        >>> from dolfinx import fem, mesh
        >>> from mpi4py import MPI
        >>> msh = mesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
        >>> bottom = mesh.locate_entities_boundary(msh, 1, lambda x: x[1] < 1e-12)
        >>> tags = mesh.meshtags(msh, 1, np.sort(bottom), 1)
        >>> f = fem.Constant(msh, np.zeros(2))
        >>> body = contact.Elasticity(1.0, 1.5, f, contact.BoundaryData(tags, dirichlet=(1,)))
        >>> body.flux(fem.Function(fem.functionspace(msh, ("Lagrange", 1, (2,))))).ufl_shape
        (2, 2)
    """

    mu: Coefficient
    lmbda: Coefficient
    f: Coefficient
    boundary: BoundaryData
    law: str | None = None
    dirichlet_value: Coefficient | None = None
    exact: Coefficient | None = None

    def flux(self, u: Any) -> Any:
        """σ(u) (linear) or P(u) (hyperelastic), tractions per reference area."""
        if self.law is None:
            return stress(u, self.mu, self.lmbda)
        return self.stresses(u)[0]

    def stresses(self, u: Any) -> tuple:
        """(P, σ) of a hyperelastic law (``piola_and_cauchy``)."""
        assert self.law is not None, "a linear body: flux() is its stress"
        return piola_and_cauchy(u, self.law, self.mu, self.lmbda)


#: the equations of a problem (what :func:`contact.estimate` reads)
Physics = Diffusion | Elasticity
