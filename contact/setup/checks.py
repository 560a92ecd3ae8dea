"""Scene data checked on the mesh before anything is assembled or solved.

An expression of the scene's data (``data.f``, ``data.k``, ``data.g``, …, ``solver.u0``)
that is not a finite number somewhere it is used — ``log(x - 2)`` on Ω = (0, 1)²,
``1/x`` at x = 0, ``sqrt(-1)`` — or a coefficient ``k`` that is not positive would
otherwise reach the solver as NaN / Inf (a "diverged_function_nanorinf" after a full
solve) or as a meaningless "solution".  :func:`check_data` evaluates each expression at the
mesh vertices where it enters the problem (every vertex, or those of the facets of one
boundary role: ``g`` and ``t_C`` on Γ_C, ``t`` on Γ_N, ``u_D`` on Γ_D) on every rank and
raises one :class:`~contact.base.errors.ConfigError` line on all ranks, e.g.

    data.g: not a finite number at 12 of 289 nodes, e.g. at x = 2, y = 0.5

(Nodes are where the finite element data live; between them a UFL coefficient is not
evaluated here, so ``1/(x - 0.55)`` on a mesh without a vertex at x = 0.55 passes.)
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..base import expressions, indices
from ..base.errors import ConfigError
from .scene_config import SceneConfig

#: the points of a role are gathered once for all its data, every vertex's as a view of
#: the geometry; False: copied for each datum, the old path (the same check)
POINTS_ONCE = True


@dataclass(frozen=True)
class Datum:
    """One expression and where it is used: ``role`` names the boundary role whose facets'
    vertices matter (None: every vertex); ``positive`` requires values > 0 (k)."""

    key: str
    text: str
    role: str | None = None
    positive: bool = False


def data_items(
    key: str, value: str | tuple[str, ...], role: str | None = None, positive: bool = False
) -> list[Datum]:
    """The :class:`Datum` of a scene key: one, or one per component of a tuple
    (``data.u_D[1]``)."""
    if not isinstance(value, str):
        return [Datum(f"{key}[{i}]", text, role, positive) for i, text in enumerate(value)]
    return [Datum(key, value, role, positive)]


def scene_data(cfg: SceneConfig) -> list[Datum]:
    """Every data expression of a scene's model and where it is used (docs/theory.md §1): f, exact
    in Ω; t on Γ_N; u_D on Γ_D; scalar models also k > 0 in Ω, and g, t_C on Γ_C
    (Signorini) or ψ in Ω (obstacle)."""
    data, model = cfg.data, cfg.model.type
    items = [
        *data_items("data.f", data.f),
        *data_items("data.t", data.t, "neumann"),
        *data_items("data.u_D", data.u_D, "dirichlet"),
    ]
    if data.exact is not None:
        items += data_items("data.exact", data.exact)
    if model == "signorini":
        items += [
            *data_items("data.g", data.g, "contact"),
            *data_items("data.t_C", data.t_C, "contact"),
        ]
    elif model == "obstacle":
        items += data_items("data.psi", data.psi)
    if not cfg.elastic:
        items += data_items("data.k", data.k, positive=True)
    return items


def check_scene_data(scene) -> None:
    """:func:`check_data` of :func:`scene_data` (collective): call before assembling."""
    check_data(scene, scene_data(scene.config))


def check_data(scene, items: Iterable[Datum]) -> None:
    """Evaluate every item on the vertices where it is used; ConfigError (collective) at
    the first one that is not finite (or not positive when required) somewhere."""
    msh, comm = scene.mesh, scene.comm
    imap = msh.geometry.index_map()
    n_owned = imap.size_local
    X = msh.geometry.x
    nodes_of: dict[str | None, np.ndarray] = {}
    points_of: dict[str | None, np.ndarray] = {}
    for item in items:
        if item.role not in nodes_of:
            nodes_of[item.role] = _nodes(scene, item.role, n_owned)
            if POINTS_ONCE:  # every vertex: the owned ones are the first n_owned
                points = (X[:n_owned] if item.role is None else X[nodes_of[item.role]]).T
                points.flags.writeable = False  # the geometry's own coordinates
                points_of[item.role] = points
        nodes = nodes_of[item.role]
        points = points_of[item.role] if POINTS_ONCE else X[nodes].T
        constants = scene.config.constants
        values = expressions.to_numpy(item.text, constants, t=scene.time)(points)
        if expressions.uses_time(item.text, constants):  # name the load step's time
            item = Datum(f"{item.key} (at t = {scene.time:g})", item.text, item.role, item.positive)
        with np.errstate(invalid="ignore"):
            finite = np.isfinite(values)
            problem = [("not a finite number", ~finite)]
            if item.positive:
                problem.append(("must be > 0", finite & ~(values > 0)))
        for what, bad in problem:
            _report(msh, comm, item, what, nodes, bad, values, imap)


def _nodes(scene, role: str | None, n_owned: int) -> np.ndarray:
    """Local geometry nodes where data of ``role`` are used: the owned vertices (every
    vertex counted once over the ranks), or all local vertices of the role's facets."""
    if role is None:
        return np.arange(n_owned, dtype=np.int32)
    msh = scene.mesh
    facets = scene.boundary.facets(role)
    if len(facets) == 0:
        return np.zeros(0, dtype=np.int32)
    return indices.unique(dmesh.entities_to_geometry(msh, msh.topology.dim - 1, facets)).astype(
        np.int32
    )


def _report(
    msh,
    comm: MPI.Comm,
    item: Datum,
    what: str,
    nodes: np.ndarray,
    bad: np.ndarray,
    values: np.ndarray,
    imap,
) -> None:
    """Raise on every rank if any rank found ``bad`` nodes: counts of distinct vertices
    over the ranks and one example (coordinates, and the value when finite)."""
    if not comm.allreduce(bool(bad.any()), op=MPI.LOR):
        return
    if item.role is None:  # owned vertices: counts add up
        n_bad, total = comm.allreduce(int(bad.sum()), op=MPI.SUM), imap.size_global
    else:  # boundary vertices may be local to several ranks: count global indices once
        glob = imap.local_to_global(nodes)
        n_bad = len(np.unique(np.concatenate(comm.allgather(glob[bad]))))
        total = len(np.unique(np.concatenate(comm.allgather(glob))))
    example = None  # the lexicographically first bad vertex: the same on any partition
    if bad.any():
        idx = np.flatnonzero(bad)
        P = msh.geometry.x[nodes[idx], : msh.geometry.dim]
        i = idx[np.lexsort(P.T[::-1])[0]]
        example = (msh.geometry.x[nodes[i], : msh.geometry.dim].tolist(), float(values[i]))
    x, value = min(e for e in comm.allgather(example) if e is not None)
    at = ", ".join(f"{c} = {v:.6g}" for c, v in zip("xyz", x))
    got = f" (got {value:.6g})" if np.isfinite(value) else ""
    raise ConfigError(f"{item.key}: {what} at {n_bad} of {total} nodes, e.g. at {at}{got}")
