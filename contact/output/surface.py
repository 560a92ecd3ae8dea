"""The contact surface as a dataset of its own: ``contact_surface.xdmf`` beside ``solution.xdmf``.

The nodal fields of a run live on the whole body, where a field of Γ_C (the multiplier, the
gap, the friction status) is zero or undefined away from it, and ParaView interpolates it
across the cells next to Γ_C.  This module writes the facet mesh of Γ_C itself — the facets
of the ``contact`` parts, and of both surfaces of every contact pair (``interface`` parts) —
with the contact fields on it, node for node the values of the body's fields (no
interpolation: a submesh node is a node of the body):

=================  =====================================================================
``pressure``       the contact pressure −λ_n ≥ 0 (elasticity; on a pair's master surface
                   the pressure it sees, −λ^m); ``flux`` −λ for the scalar models
``gap``            σ(g − u) at the constrained nodes (NaN elsewhere, e.g. master nodes)
``status``         0 separated, 1 in contact (frictionless) or sticking, 2 slipping
``traction_t``     friction: the tangential traction λ_t on the body (a vector)
``slip``           friction: the slip increment of the load step (a vector)
``bound``          friction: the bound ρ of |λ_t|
``u_h``            the displacement (or u), to warp the surface as the body
``part``           per facet: the boundary part's tag (slave and master differ)
=================  =====================================================================

For P1 fields ∫_{Γ_C} pressure ds = Σ_i p_i ∫ φ_i ds = Σ_i w_i p_i: the facets' areas
times the mean of their nodes' pressures add up to the contact force of ``summary.json``
(before its symmetric copies).  One solve writes ``contact_surface.xdmf`` + ``.h5``; an
adaptive run or a load path writes the series ``contact_surface.xdmf`` over
``contact_surface_KKK.xdmf`` + ``.h5``, one grid per level or load step, in the temporal
collection scheme of ``solution.xdmf`` (:class:`contact.output.xdmf.XdmfSeries`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from .xdmf import XdmfSeries, write_xdmf

if TYPE_CHECKING:
    from ..post.posed import Parts as Boundary

NAME = "contact_surface"
#: the boundary roles whose facets make the contact surface
ROLES = ("contact", "interface")


def surface_facets(boundary: Boundary) -> np.ndarray:
    """The local facets of Γ_C: of the contact parts and of both surfaces of the pairs."""
    return np.unique(np.concatenate([boundary.facets(role) for role in ROLES])).astype(np.int32)


def match_points(X: np.ndarray, Y: np.ndarray, tol: float) -> np.ndarray:
    """For each point of ``Y``, the index of a point of ``X`` within ``tol`` (−1 if none).

    A node of the submesh is a node of the body: the same numbers up to the last bits of a
    midpoint's arithmetic. Both sets are rounded to a grid of spacing 100 ``tol`` and equal
    grid points matched at once (vectorized); a point whose twin rounded to a neighbouring
    grid point (the two straddle a rounding boundary: rare) is looked up among them.
    """
    size = 100.0 * tol
    qx, qy = np.round(X / size).astype(np.int64), np.round(Y / size).astype(np.int64)
    _, ids = np.unique(np.vstack([qx, qy]), axis=0, return_inverse=True)
    ids = ids.ravel()
    owner = np.full(ids.max() + 1 if len(ids) else 0, -1, dtype=np.int64)
    owner[ids[: len(X)]] = np.arange(len(X))
    out = owner[ids[len(X) :]]
    close = np.zeros(len(Y), dtype=bool)
    hit = out >= 0
    close[hit] = np.max(np.abs(X[out[hit]] - Y[hit]), axis=1) <= tol
    out[~close] = -1
    if close.all():
        return out
    where = {tuple(k): i for i, k in enumerate(qx)}
    dim = X.shape[1]
    offsets = np.array(np.meshgrid(*[[-1, 0, 1]] * dim, indexing="ij")).reshape(dim, -1).T
    for j in np.flatnonzero(~close):
        for offset in offsets:
            i = where.get(tuple(qy[j] + offset))
            if i is not None and np.max(np.abs(X[i] - Y[j])) <= tol:
                out[j] = i
                break
    return out


class Restriction:
    """The facet mesh of Γ_C and how to carry the body's nodal fields onto it (collective).

    Args:
        boundary: The scene's boundary parts (their facet tags).
        V: A Lagrange space of the body (its degree is the surface fields' degree).
    """

    def __init__(self, boundary: Boundary, V: fem.FunctionSpace):
        msh = V.mesh
        fdim = msh.topology.dim - 1
        self.facets = surface_facets(boundary)
        self.mesh, self.parent_facet = dmesh.create_submesh(msh, fdim, self.facets)[:2]
        self.degree = V.element.basix_element.degree
        self.scalar = fem.functionspace(self.mesh, ("Lagrange", self.degree))
        self.vector = fem.functionspace(self.mesh, ("Lagrange", self.degree, (msh.geometry.dim,)))
        extent = float(np.ptp(msh.geometry.x, axis=0).max()) or 1.0
        self._tol = 1e-10 * extent
        self._maps: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._tags = boundary.tags

    def _map(self, W: fem.FunctionSpace) -> tuple[np.ndarray, np.ndarray]:
        """(submesh nodes, body nodes) at the same points, for a body space W."""
        key = id(W)
        if key not in self._maps:
            fdim = self.mesh.topology.dim
            body = fem.locate_dofs_topological(W, fdim, self.facets)
            X = W.tabulate_dof_coordinates()[body]
            found = match_points(X, self.scalar.tabulate_dof_coordinates(), self._tol)
            if np.any(found < 0):
                missing = int(np.sum(found < 0))
                raise ValueError(f"contact surface: {missing} surface nodes are no body node")
            self._maps[key] = (np.arange(len(found)), np.asarray(body, np.int64)[found])
        return self._maps[key]

    def restrict(self, fn: fem.Function, name: str, scale: float = 1.0) -> fem.Function:
        """The body's nodal field ``fn`` (times ``scale``) on the surface, named ``name``."""
        W = fn.function_space
        bs = W.dofmap.index_map_bs
        S = self.scalar if bs == 1 else self.vector
        out = fem.Function(S, name=name)
        sub, body = self._map(W)
        out.x.array.reshape(-1, bs)[sub] = scale * fn.x.array.reshape(-1, bs)[body]
        return out

    def part(self) -> fem.Function:
        """Per facet of the surface, the tag of the boundary part it belongs to (DG0)."""
        Q = fem.functionspace(self.mesh, ("DG", 0))
        out = fem.Function(Q, name="part")
        n = self.mesh.topology.index_map(self.mesh.topology.dim).size_local
        parent = np.asarray(self.parent_facet.sub_topology_to_topology(np.arange(n), False))
        order = np.argsort(self._tags.indices)
        found = order[np.searchsorted(self._tags.indices, parent, sorter=order)]
        out.x.array[Q.dofmap.list[:n, 0]] = self._tags.values[found]
        out.x.scatter_forward()
        return out


def surface_fields(
    restriction: Restriction, point_fields: Sequence[fem.Function], elastic: bool
) -> list[fem.Function]:
    """The contact fields on the surface (module doc) from the run's nodal output fields
    (named as in ``solution.xdmf``: ``u_h``, ``lambda_h``, ``gap``, ``active``, with pairs
    ``lambda_master``, with friction ``lambda_t``, ``slip``, ``status``, ``bound``)."""
    by_name = {fn.name: fn for fn in point_fields}
    out = [restriction.restrict(by_name["u_h"], "u_h")]
    pressure = restriction.restrict(by_name["lambda_h"], "pressure" if elastic else "flux", -1.0)
    if "lambda_master" in by_name:  # the master surface: the pressure it sees (0 on slaves)
        pressure.x.array[:] -= restriction.restrict(by_name["lambda_master"], "m").x.array
    out.append(pressure)
    out.append(restriction.restrict(by_name["gap"], "gap"))
    status = by_name.get("status", by_name["active"])
    out.append(restriction.restrict(status, "status"))
    renamed = {"lambda_t": "traction_t", "slip": "slip", "bound": "bound"}
    out += [restriction.restrict(by_name[k], v) for k, v in renamed.items() if k in by_name]
    if "pressure_current" in by_name:
        out.append(restriction.restrict(by_name["pressure_current"], "pressure_current"))
    return out


class SurfaceFiles:
    """``contact_surface.xdmf`` in a result folder (collective): :meth:`write_one` for one
    solve, :meth:`write_step` step after step of a series (time value t: the level, the load
    step's pseudo-time), each on that step's mesh.

    Args:
        folder: The result folder.
        elastic: Whether the model is elastic (``pressure``) or scalar (``flux``).
        comm: The communicator of the meshes.
    """

    def __init__(self, folder: str | Path, elastic: bool, comm: MPI.Comm = MPI.COMM_WORLD):
        self.folder, self.elastic = Path(folder), elastic
        self._series = XdmfSeries(folder, NAME, comm)

    def _fields(self, boundary: Boundary, point_fields: Sequence[fem.Function]):
        restriction = Restriction(boundary, point_fields[0].function_space)
        return surface_fields(restriction, point_fields, self.elastic), [restriction.part()]

    def write_one(self, boundary: Boundary, point_fields: Sequence[fem.Function]) -> None:
        """``contact_surface.xdmf`` (+ .h5) of one solve."""
        points, cells = self._fields(boundary, point_fields)
        write_xdmf(self.folder / f"{NAME}.xdmf", points, cells)

    def write_step(
        self, t: float, boundary: Boundary, point_fields: Sequence[fem.Function]
    ) -> None:
        """Step ``contact_surface_KKK`` of the series, with time value ``t``."""
        points, cells = self._fields(boundary, point_fields)
        self._series.write(t, points, cells)


def has_surface(boundary: Boundary, comm: MPI.Comm) -> bool:
    """Whether the scene has a contact surface (an obstacle in Ω has none; collective)."""
    return comm.allreduce(len(surface_facets(boundary)), op=MPI.SUM) > 0
