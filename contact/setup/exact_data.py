"""A declared exact solution checked against the boundary conditions the scene poses.

``data.exact`` is what ``error_energy`` and the effectivities are measured against, so it
must solve the problem the scene poses.  Where it does not — Dirichlet data u_D other than
u on a Dirichlet part, or a flux k ∂u/∂n (elasticity: traction σ(u)n) other than the data
on a Neumann part, or other than 0 on a natural part (a part with ``role: natural``, or the
exterior facets no part selects) — the run converges to another solution and its "error"
stops falling.  :func:`exact_mismatches` measures, on each such part P,

    d_P = ‖B u − b‖_{L²(P)}    against    i_P = ‖B (u − I_h u)‖_{L²(P)},

with B u the trace u (Dirichlet), u·n (symmetry), or the flux (Neumann, natural), b the
data (u_D, 0, t, 0) and I_h u the Lagrange interpolant of u in the scene's space: the scene
and its exact solution disagree when d_P exceeds the exact solution's own interpolation
error on P — what no mesh of this size can tell apart — and a relative round-off floor
10⁻⁸ (‖B u‖ + ‖b‖).  Each integral is by quadrature of degree 2p + 2 (UFL expressions, not
interpolants, for u and the data), all of them in one compiled form.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import ufl
from dolfinx import fem, la
from mpi4py import MPI

from ..base import expressions
from ..base.errors import ContactWarning
from ..models.physics import lame, stress
from .meshes import NATURAL
from .scene_config import components
from .untagged import untagged_boundary

if TYPE_CHECKING:
    from .scene import Scene

#: relative round-off floor of the test d_P > max(i_P, RTOL (‖B u‖ + ‖b‖))
RTOL = 1e-8


@dataclass(frozen=True)
class Mismatch:
    """A boundary part on which the exact solution does not satisfy the scene's condition:
    ``difference`` d_P and ``tolerance`` max(i_P, round-off floor) as in the module's text."""

    part: str
    role: str
    difference: float
    tolerance: float

    def as_dict(self) -> dict[str, Any]:
        """The mismatch as JSON data (``summary.json``'s ``exact_mismatch``)."""
        return {
            "part": self.part,
            "role": self.role,
            "difference": self.difference,
            "tolerance": self.tolerance,
        }

    def line(self, elastic: bool = False) -> str:
        """One warning line naming the part and the condition the exact solution misses."""
        flux = "σ(u)n" if elastic else "k ∂u/∂n"
        where = (
            "the exterior facets in no part (see the 'boundary:' line)"
            if self.part == NATURAL
            else f"boundaries.{self.part}"
        )
        what = {
            "dirichlet": f"u ≠ data.u_D on {where}: ‖u − u_D‖",
            "symmetry": f"u·n ≠ 0 on the symmetry plane {where}: ‖u·n‖",
            "neumann": f"{flux} ≠ data.t on {where}: ‖{flux} − t‖",
            "natural": f"{flux} ≠ 0 on {where}: ‖{flux}‖",
        }[self.role]
        return (
            f"data.exact: {what} = {self.difference:.3g} > {self.tolerance:.3g} (its "
            "interpolation error there): the scene poses another problem, and error_energy "
            "is not its discretization error"
        )


def exact_mismatches(scene: Scene) -> list[Mismatch] | None:
    """The parts of ``scene`` on which its ``data.exact`` misses the boundary condition
    (None for a scene without an exact solution).  Collective; the same on every rank.
    Fluxes are checked for the scalar models and one linear elastic body (several bodies:
    the Dirichlet and symmetry parts only)."""
    cfg = scene.config
    if cfg.data.exact is None:
        return None
    msh, bnd = scene.mesh, scene.boundary
    gdim = msh.geometry.dim
    n = ufl.FacetNormal(msh)
    elastic = cfg.elastic
    size = gdim if elastic else 1

    def data(text: str | tuple[str, ...]) -> Any:
        texts = components(text, size)
        parts = [expressions.to_ufl(s, msh, cfg.constants, t=scene.time) for s in texts]
        return ufl.as_vector(parts) if elastic else parts[0]

    u = data(cfg.data.exact)
    V = fem.functionspace(msh, ("Lagrange", cfg.mesh.degree, (gdim,) if elastic else ()))
    I_u = fem.Function(V)
    exact = [
        expressions.to_numpy(s, cfg.constants, t=scene.time)
        for s in components(cfg.data.exact, size)
    ]
    I_u.interpolate(lambda x: np.vstack([f(x) for f in exact]) if elastic else exact[0](x))
    flux = None
    if elastic and not cfg.bodies:
        assert cfg.model.E is not None  # one linear elastic body (checked at load)

        mu, lmbda_L = lame(cfg.model.E, cfg.model.nu)
        flux = lambda w: stress(w, mu, lmbda_L) * n  # noqa: E731
    elif not elastic:
        k = expressions.to_ufl(cfg.data.k, msh, cfg.constants, t=scene.time)
        flux = lambda w: k * ufl.dot(_grad(w, gdim), n)  # noqa: E731

    conditions = []  # (part, role, B u − b, B (u − I_h u), B u, b)
    for name, role in bnd.roles.items():
        if role == "dirichlet":
            g = data(cfg.data.u_D)
            conditions.append((name, role, u - g, u - I_u, u, g))
        elif role == "symmetry":
            conditions.append((name, role, ufl.dot(u, n), ufl.dot(u - I_u, n), u, None))
        elif role in ("neumann", "natural") and flux is not None:
            q = flux(u)
            b = data(cfg.data.t) if role == "neumann" else None
            conditions.append((name, role, q - b if b is not None else q, flux(u - I_u), q, b))
    if not conditions:
        return []
    sq = lambda e: ufl.inner(e, e)  # noqa: E731
    terms = []
    for name, _, diff, interp, Bu, b in conditions:
        i = bnd.ids[name]
        terms += [(i, sq(diff)), (i, sq(interp)), (i, sq(Bu)), (i, sq(b) if b is not None else 0)]
    values = np.sqrt(np.maximum(facet_integrals(msh, bnd.tags, terms, 2 * cfg.mesh.degree + 2), 0))
    out = []
    for (name, role, *_), (d, i, s_u, s_b) in zip(conditions, values.reshape(-1, 4)):
        tolerance = max(i, RTOL * (s_u + s_b))
        if d > tolerance:
            out.append(Mismatch(name, role, float(d), float(tolerance)))
    return out


def warn_exact_mismatches(scene: Scene) -> list[Mismatch] | None:
    """:func:`exact_mismatches`, each one a one-line ContactWarning on rank 0 (collective)."""
    found = exact_mismatches(scene)
    if scene.comm.rank == 0:
        for m in found or []:
            warnings.warn(m.line(scene.config.elastic), ContactWarning, stacklevel=2)
    return found


def _grad(w: Any, gdim: int) -> Any:
    """∇w, also of an expression without the mesh's coordinates (a constant: 0)."""
    if not ufl.domain.extract_domains(w):
        return ufl.zero(*w.ufl_shape, gdim)
    return ufl.grad(w)


def facet_integrals(msh, tags, terms: list[tuple[int, Any]], degree: int) -> np.ndarray:
    """∫_{P_j} f_j ds for the (facet tag value, scalar integrand) pairs ``terms``, summed over
    the ranks: one linear form over a DG0 space with one component per term, so that all of
    them compile once.  Collective."""
    count = len(terms)
    W = fem.functionspace(msh, ("DG", 0, (count,)))
    v = ufl.TestFunction(W)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags, metadata={"quadrature_degree": degree})
    form = None
    for j, (i, f) in enumerate(terms):
        if not _zero(f):
            form = f * v[j] * ds(i) if form is None else form + f * v[j] * ds(i)
    local = np.zeros(count)
    if form is not None:
        b = fem.assemble_vector(fem.form(form))
        b.scatter_reverse(la.InsertMode.add)
        owned = W.dofmap.index_map.size_local
        local = b.array[: owned * count].reshape(owned, count).sum(axis=0)
    msh.comm.Allreduce(MPI.IN_PLACE, local, op=MPI.SUM)
    return local


def _zero(f: Any) -> bool:
    return isinstance(f, (int, float)) and f == 0 or isinstance(f, ufl.constantvalue.Zero)


def posed_problem(scene: Scene) -> dict[str, Any]:
    """What the scene poses beyond its parts (collective): ``untagged_boundary``, the
    exterior facets in no boundary part, which carry the natural condition
    (:func:`contact.setup.untagged.untagged_boundary`: ``facets``, ``measure``, ``where``,
    ``next_to``), and for a scene with ``data.exact`` the parts where the exact solution
    misses the scene's boundary condition (``exact_mismatch``,
    :func:`exact_mismatches`; empty when it satisfies them all)."""
    out: dict[str, Any] = {
        "untagged_boundary": untagged_boundary(scene.mesh, scene.boundary).as_dict()
    }
    mismatches = exact_mismatches(scene)
    if mismatches is not None:
        out["exact_mismatch"] = [m.as_dict() for m in mismatches]
    return out
