"""The contact data along Γ_C as one table: ``contact.csv`` and the data of ``pressure.png``.

One row per constrained node — Signorini and elasticity: the nodes of Γ_C that carry the
constraint (not those on the closure of Γ_D); obstacle problems (constraint in Ω): the nodes
of the contact set only — with the named columns

    x, y(, z)           coordinates
    s                   2D contact boundary: arc length along Γ_C (from its end with the
                        smallest coordinates; several pieces follow one another)
    r, theta            3D contact boundary: polar position about the first point of contact
                        (smallest initial gap) in the plane ⟂ n (elasticity: the contact
                        normal there; scalar: the mean normal of Γ_C)
    lambda_n | lambda   the multiplier: normal pressure λ_n ≤ 0 (elasticity), flux λ (scalar)
    lambda_exact        scalar Signorini with a declared ``data.exact``: the exact flux
                        λ = k ∂u/∂n − t_C, averaged over each node's support on Γ_C
                        (∫ φ_i λ ds / ∫ φ_i ds), to compare ``lambda`` with
    gap                 σ(g − u) ≥ 0 (elasticity: g − u·n)
    active              1 in the active set (the solver's rule b_i > a_i), else 0
    (friction)          lambda_t, slip (2D; 3D: their x, y, z components), lambda_t_norm,
                        bound, slip_norm, status, weight (below)

For every contact node i (weight w_i = ∫_{Γ_C} φ_i, a length in 2D, an area in 3D) a
frictional solve adds to the columns above (coordinates, ``s`` / ``r``, λ_n, gap, active)
:func:`friction_columns`: the tangential traction on the body λ_t,i (stress; in 2D its
component along t_0 = (−n_y, n_x), n the contact normal at the first point of contact — for
a plane y = 0 below the body, the x component; in 3D the vector in global axes), |λ_t|, the
friction bound ρ_i, the slip increment s_t,i of the load step (length; the same way), |s_t|,
the status separated / stick / slip, and w_i.  Their resultants are
:mod:`contact.post.friction_resultants`'s.

:func:`contact_columns` gives this rank's rows as named NumPy columns; a model with more
data per contact node (friction: λ_t, slip, status) adds columns there.  :func:`gather`
collects them on rank 0 with the arc length; :func:`contact.output.folder.write_table` writes
any such table.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem, la
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..solvers import Result, owned_residual
from .posed import Posed

Table = dict[str, np.ndarray]
STATUS = ("separated", "stick", "slip")


def value_name(posed: Posed) -> str:
    """The multiplier column: ``lambda_n`` for elasticity, ``lambda`` for scalar models."""
    return "lambda_n" if posed.elastic else "lambda"


def contact_columns(posed: Posed, result: Result) -> Table:
    """This rank's rows (owned constrained nodes; the contact set for obstacles) as named
    columns (collective: the 3D position needs global data)."""
    p = result.problem
    con = p.constraint
    gdim = posed.mesh.geometry.dim
    X = p.V.tabulate_dof_coordinates()[con.dofs // p.V.dofmap.index_map_bs, :gdim]
    from .resultants import current_pressure, nodal_gap

    cols: Table = {name: X[:, i] for i, name in enumerate("xyz"[:gdim])}
    if gdim == 3 and not p.constraint.in_domain:
        cols.update(_polar(posed, result, X))
    cols[value_name(posed)] = p.multiplier(owned_residual(result))
    exact = exact_multiplier(posed, result)
    if exact is not None:
        cols["lambda_exact"] = exact
    current = current_pressure(result)
    if current is not None:  # a finite-strain body: the pressure per deformed area
        cols["pressure_current"] = current
    cols["gap"] = nodal_gap(result)
    cols["active"] = result.active_mask.astype(np.int8)
    if result.friction is not None:  # λ_t, bound, slip, status, weight
        cols.update(friction_columns(posed, result))
    if p.constraint.in_domain:  # obstacle: the contact set only
        cols = {k: v[result.active_mask] for k, v in cols.items()}
    return cols


def exact_multiplier(posed: Posed, result: Result) -> np.ndarray | None:
    """The exact flux λ = k ∇u·n − t_C of a scalar Signorini scene's declared ``data.exact``
    at this rank's constrained nodes, averaged over each node's support on Γ_C:
    ∫ φ_i λ ds / ∫ φ_i ds (collective; None for other scenes).  The average, not a point
    value, because λ of a free boundary problem has a kink or a root singularity where the
    contact zone ends (problem A: λ = −(3/2)|x|^{1/2} for x < 0)."""
    p = result.problem
    u = posed.exact
    if u is None or posed.elastic or p.constraint.in_domain:
        return None
    msh, V = posed.mesh, p.V
    n, v = ufl.FacetNormal(msh), ufl.TestFunction(V)
    degree = 2 * V.element.basix_element.degree + 4
    ds = p.data.ds(metadata={"quadrature_degree": degree})
    flux = p.data.k * ufl.dot(ufl.grad(u), n) - p.data.t_C
    ids = posed.boundary.ids_with_role("contact")
    sums = []
    for integrand in (flux * v, v):
        vec = fem.assemble_vector(fem.form(sum(integrand * ds(i) for i in ids)))
        vec.scatter_reverse(la.InsertMode.add)
        sums.append(vec.array[p.constraint.dofs])
    return sums[0] / sums[1]


def tangent_2d(result: Result) -> np.ndarray:
    """t_0 = (−n_y, n_x) of the contact normal n at the first point of contact (2D)."""
    n = np.asarray(result.problem.data.n, dtype=float)
    return np.array([-n[1], n[0]])


def friction_columns(posed: Posed, result: Result) -> Table:
    """This rank's friction columns, row for row with :func:`contact_columns`."""
    fr = result.friction
    if fr is None:
        raise ValueError("friction columns of a frictionless result")
    lam_t, slip = fr["lambda_t_vec"], fr["slip_vec"]
    cols: Table = {}
    if posed.mesh.geometry.dim == 2:
        t0 = tangent_2d(result)
        cols.update(lambda_t=lam_t @ t0, slip=slip @ t0)
    else:
        cols.update({f"lambda_t_{a}": lam_t[:, i] for i, a in enumerate("xyz")})
        cols.update({f"slip_{a}": slip[:, i] for i, a in enumerate("xyz")})
    cols.update(
        lambda_t_norm=np.linalg.norm(lam_t, axis=1),
        bound=np.asarray(fr["rho"], dtype=np.float64),
        slip_norm=np.linalg.norm(slip, axis=1),
        status=np.array(STATUS, dtype=object)[fr["status"]],
        weight=np.asarray(fr["w"], dtype=np.float64),
    )
    return cols


#: in-plane coordinates below this fraction of the contact zone's extent are round-off: 0
POLAR_ROUNDOFF = 1e-12


def _polar(posed: Posed, result: Result, X: np.ndarray) -> Table:
    """r, theta about the first point of contact (``Result.first_contact``) in the plane ⟂ n
    (collective)."""
    n = contact_normal(posed, result)
    if n is None:  # mortar pairs none of whose slave nodes faces a master facet: no row
        return {"r": np.zeros(0), "theta": np.zeros(0)}
    origin = result.first_contact
    t1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    rel = X - origin
    extent = posed.comm.allreduce(float(np.max(np.abs(rel), initial=0.0)), op=MPI.MAX)
    return polar(rel, t1, t2, POLAR_ROUNDOFF * extent)


def polar(rel: np.ndarray, t1: np.ndarray, t2: np.ndarray, roundoff: float) -> Table:
    """r and theta ∈ (−π, π] of the points ``rel`` (rows, relative to the origin) in the
    plane of the unit vectors t1, t2.  The in-plane coordinates are summed component by
    component (the same for a row on any number of ranks, whatever the array's length) and
    those of magnitude ≤ ``roundoff`` become +0: a point on the axis −t1 gets θ = +π,
    never −π from a signed zero or a round-off −1e-18 (which the partition decides)."""

    def along(t: np.ndarray) -> np.ndarray:
        value = sum(rel[:, i] * t[i] for i in range(rel.shape[1]))
        return np.where(np.abs(value) <= roundoff, 0.0, value)

    a, b = along(t1), along(t2)
    return {"r": np.hypot(a, b), "theta": np.arctan2(b, a)}


def contact_normal(posed: Posed, result: Result) -> np.ndarray | None:
    """The unit normal from the body towards the obstacle (collective): elasticity, the
    contact normal at the first point of contact; scalar Signorini, the mean outward normal
    of Γ_C; None for an obstacle in Ω, or for mortar pairs none of whose slave nodes faces a
    master facet (finite strain: all out of contact)."""
    p = result.problem
    if p.constraint.in_domain or (p.data.n is None and p.data.couplings):
        return None
    return np.asarray(p.data.n, dtype=float) if p.data.n is not None else _mean_normal(posed)


def view_normal(posed: Posed, result: Result) -> np.ndarray | None:
    """The direction the pictures of a 3D scene look along, from the obstacle's side:
    :func:`contact_normal` (collective); None in 2D."""
    return contact_normal(posed, result) if posed.mesh.geometry.dim == 3 else None


def _mean_normal(posed: Posed) -> np.ndarray:
    """∫_{Γ_C} n ds / |∫_{Γ_C} n ds|, the mean outward normal of the contact boundary."""
    msh = posed.mesh
    ds = ufl.Measure("ds", domain=msh, subdomain_data=posed.boundary.tags)
    n = ufl.FacetNormal(msh)
    measure = ds(posed.boundary.ids_with_role("contact"))
    v = np.array(
        [
            posed.comm.allreduce(fem.assemble_scalar(fem.form(n[i] * measure)), op=MPI.SUM)
            for i in range(msh.geometry.dim)
        ]
    )
    return v / np.linalg.norm(v)


def contact_table(posed: Posed, result: Result, columns: Table | None = None) -> Table | None:
    """The whole table on rank 0 (None elsewhere), rows sorted along Γ_C: by arc length s in
    2D, by r in 3D, by coordinates for obstacles.  ``columns`` defaults to
    :func:`contact_columns` (collective)."""
    columns = contact_columns(posed, result) if columns is None else columns
    segments = None
    if posed.mesh.geometry.dim == 2 and not result.problem.constraint.in_domain:
        segments = _contact_segments(posed)
    table = gather(columns, posed.comm)
    if posed.comm.rank != 0:
        return None
    assert table is not None  # gathered on rank 0
    if segments is not None:
        s = arc_length(np.c_[table["x"], table["y"]], segments)
        keys = list(table)
        table = {**{k: table[k] for k in keys[:2]}, "s": s, **{k: table[k] for k in keys[2:]}}
    order = _order(table)
    # no signed zeros in the files: −0.0 + 0.0 = +0.0 (a value's sign is no property of a zero)
    return {k: v[order] + 0.0 if v.dtype.kind == "f" else v[order] for k, v in table.items()}


def _order(table: Table) -> np.ndarray:
    for key in ("s", "r"):
        if key in table:
            return np.argsort(table[key], kind="stable")
    coords = [table[c] for c in "zyx" if c in table]  # lexsort: last key is primary
    return np.lexsort(coords)


def gather(columns: Table, comm: MPI.Comm) -> Table | None:
    """Concatenate every rank's rows on rank 0 (None elsewhere)."""
    parts = comm.gather(columns, root=0)
    if comm.rank != 0:
        return None
    assert parts is not None  # gathered on rank 0
    return {k: np.concatenate([part[k] for part in parts]) for k in columns}


def _contact_segments(posed: Posed) -> np.ndarray | None:
    """(m, 2, 2) end points of all Γ_C facets (2D) on rank 0, each facet once: the parts
    of role contact and the slave surfaces of contact pairs."""
    msh = posed.mesh
    tdim = msh.topology.dim
    facets = posed.boundary.facets("contact")
    if posed.pairs:
        from ..models.mortar import part_facets

        facets = np.union1d(
            facets,
            np.concatenate([part_facets(posed.boundary, slave) for slave, _ in posed.pairs]),
        ).astype(np.int32)
    facets = facets[facets < msh.topology.index_map(tdim - 1).size_local]
    nodes = dmesh.entities_to_geometry(msh, tdim - 1, facets)[:, :2]
    local = msh.geometry.x[nodes][:, :, :2]
    parts = msh.comm.gather(local, root=0)
    return np.concatenate(parts) if msh.comm.rank == 0 else None


def arc_length(points: np.ndarray, segments: np.ndarray, digits: int = 9) -> np.ndarray:
    """Arc length along the polyline(s) made of ``segments`` (m, 2, 2) at ``points`` (n, 2),
    which are segment end points or midpoints (P2); NaN for any other point.

    Chains start at their end with the smallest (x, y); several chains follow one another
    in that order.  Points are matched to vertices by their coordinates rounded to
    ``digits`` significant digits of the polyline's size."""
    if len(segments) == 0:
        return np.full(len(points), np.nan)
    scale = float(np.max(np.abs(segments))) or 1.0

    def key(x: np.ndarray) -> list[tuple]:
        return [tuple(row) for row in np.round(np.asarray(x) / scale, digits)]

    ends = segments.reshape(-1, 2)
    vkeys = key(ends)
    ids: dict[tuple, int] = {}
    vid = np.array([ids.setdefault(k, len(ids)) for k in vkeys]).reshape(-1, 2)
    coords = np.zeros((len(ids), 2))
    coords[vid.ravel()] = ends
    adjacency: dict[int, list[int]] = {}
    for j, (a, b) in enumerate(vid):
        if a != b:
            adjacency.setdefault(a, []).append(j)
            adjacency.setdefault(b, []).append(j)
    s_vertex = np.full(len(ids), np.nan)
    used = np.zeros(len(vid), dtype=bool)
    total = 0.0
    while not used.all():
        free = [v for v in adjacency if any(not used[j] for j in adjacency[v])]
        if not free:
            break
        ends_ = [v for v in free if sum(not used[j] for j in adjacency[v]) == 1] or free
        v = min(ends_, key=lambda i: tuple(coords[i]))
        if np.isnan(s_vertex[v]):
            s_vertex[v] = total
        while True:
            nxt = [j for j in adjacency[v] if not used[j]]
            if not nxt:
                break
            j = nxt[0]
            used[j] = True
            w = vid[j, 1] if vid[j, 0] == v else vid[j, 0]
            total = s_vertex[v] + float(np.linalg.norm(coords[w] - coords[v]))
            if np.isnan(s_vertex[w]):
                s_vertex[w] = total
            v = w
    lookup = dict(zip(key(coords), s_vertex))
    mids = key(0.5 * (coords[vid[:, 0]] + coords[vid[:, 1]]))
    lookup.update(zip(mids, 0.5 * (s_vertex[vid[:, 0]] + s_vertex[vid[:, 1]])))
    return np.array([lookup.get(k, np.nan) for k in key(points)])
