"""Gmsh geometries for Hertz contact validation, built from parameters (no ``.msh`` file).

``quarter_disk`` (2D triangles) and ``sphere_octant`` (3D tetrahedra) are the parts of a
disk / ball of radius R resting on the plane y = 0 / z = 0 at the contact point (the
origin) that symmetry leaves to compute.  Both are built by gmsh on rank 0 and distributed
over ``comm`` by ``dolfinx.io.gmsh.model_to_mesh``; they return ``(mesh, facet_tags)`` like
a ``.msh`` scene does, with physical facet tags

    1 = curved (contact) surface, 2 = flat top (y = R / z = R),
    3 = symmetry axis / plane x = 0, 4 = symmetry plane y = 0 (3D only),

and cell tag 10.  The mesh size is ``h_contact`` within distance ``zone`` of the contact
point, grows linearly with slope ``GRADING`` beyond it, and is ``h`` everywhere else
(gmsh Distance + Threshold fields; sizes from points, curvature and boundary are off, so
the field alone sets the size).  Elements are linear: triangles by gmsh's Frontal-Delaunay
algorithm, one thread per surface (:data:`TRIANGLES`), tetrahedra by its HXT algorithm on
one thread (:data:`TETRAHEDRA`), so the mesh is the same on every run and any number of
ranks; while rank 0 meshes, the other ranks sleep rather than spin.

Refinement (``dolfinx.mesh.refine``) puts new vertices at edge midpoints, which keeps the
coarse polygon / polyhedron; :func:`curved_boundary` gives the exact surface of tag 1 of
these scenes, whose :meth:`CurvedBoundary.snap` moves the vertices of the refined mesh's
tag-1 facets back onto it (as deal.II's manifolds do), so the discrete body converges to
the disk / ball and the contact pressure to Hertz's instead of peaking at the kinks.

:func:`gmsh_to_mesh` turns any gmsh model (these builders, a ``.msh`` file read by
:mod:`contact.meshes`) into a distributed DOLFINx mesh; gmsh is imported there only, so a
built-in mesh never imports it.  :func:`signed_volumes` and :func:`collapsed_cells` check
that a move of the geometry nodes (a snap, a ``mesh.map``) keeps every cell's orientation.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from dolfinx import la
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..base.errors import ConfigError
from ..base.validation import block_pair

if TYPE_CHECKING:
    from .scene_config import MeshConfig

CONTACT, TOP, AXIS, PLANE_Y, BODY = 1, 2, 3, 4, 10
GRADING = 0.3  # growth of the mesh size per unit distance between the zone and size h


def gmsh_to_mesh(comm: MPI.Comm, build, error: str, gdim: int | None = None, cells: bool = False):
    """Run ``build(gmsh)`` on rank 0 (gmsh's terminal output off) and distribute the mesh
    with its physical groups; the geometric dimension is the model's unless given.  Returns
    (mesh, facet tags), and the cell tags too if ``cells``.  Any failure is one ConfigError
    line ``<error>: <gmsh's message>``, raised on every rank."""
    import gmsh  # only for gmsh scenes
    from dolfinx.io import gmsh as gmshio

    problem = None
    if comm.rank == 0:
        gmsh.initialize(interruptible=False)
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("scene")
        try:
            build(gmsh)
            gdim = gdim or gmsh.model.getDimension()
        except Exception as err:  # gmsh reports its errors as generic exceptions
            problem = str(err) or type(err).__name__
    _sleep_until_all_arrive(comm)  # the other ranks leave rank 0's gmsh the machine's cores
    problem, gdim = comm.bcast((problem, gdim), root=0)
    try:
        if problem is None:
            ghosts = dmesh.GhostMode.shared_facet
            partitioner = dmesh.create_cell_partitioner(ghosts, 2)  # type: ignore[call-arg]
            data = gmshio.model_to_mesh(
                gmsh.model if comm.rank == 0 else None, comm, 0, gdim=gdim, partitioner=partitioner
            )
    except Exception as err:  # e.g. no physical groups (raised on every rank)
        problem = str(err)
    finally:
        if comm.rank == 0:
            gmsh.finalize()
    if problem is not None:
        raise ConfigError(f"{error}: {' '.join(problem.split())}")
    return (data.mesh, data.facet_tags, data.cell_tags) if cells else (data.mesh, data.facet_tags)


def _sleep_until_all_arrive(comm: MPI.Comm, poll: float = 0.005) -> None:
    """A barrier that the ranks waiting in it spend asleep, polling every ``poll`` seconds
    (MPI's own barrier and broadcast spin at 100 % of a core until the last rank comes)."""
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(poll)


def vertex_nodes(msh: dmesh.Mesh) -> np.ndarray:
    """The vertex geometry nodes of each cell (local cells, ghosts included)."""
    return msh.geometry.dofmaps[0][:, : msh.topology.dim + 1]


def signed_volumes(msh: dmesh.Mesh, cells: np.ndarray | None = None) -> np.ndarray:
    """det(x_1 − x_0, …, x_d − x_0) of each simplex (d! times its signed volume, in the
    mesh's length unit to the power d): of the local ``cells`` (default all, ghosts
    included)."""
    gdim = msh.geometry.dim
    nodes = vertex_nodes(msh) if cells is None else vertex_nodes(msh)[cells]
    P = msh.geometry.x[nodes][:, :, :gdim]
    return np.linalg.det(P[:, 1:] - P[:, :1])


def worst_angle(msh: dmesh.Mesh) -> float:
    """The smallest angle of the mesh's cells in degrees (collective): the interior angles
    of triangles, the dihedral angles of tetrahedra (π minus the angle between the outward
    normals of the two faces at an edge), over the owned cells of every rank."""
    tdim = msh.topology.dim
    owned = msh.topology.index_map(tdim).size_local
    P = msh.geometry.x[vertex_nodes(msh)[:owned]][:, :, : msh.geometry.dim]
    k = np.arange(tdim + 1)
    if tdim == 2:  # the angle at vertex i between the edges to the other two
        e1, e2 = P[:, (k + 1) % 3] - P, P[:, (k + 2) % 3] - P
        e1, e2 = (e / np.linalg.norm(e, axis=2, keepdims=True) for e in (e1, e2))
        cosines = np.einsum("cid,cid->ci", e1, e2)
    else:  # n_i: the unit outward normal of the face opposite vertex i
        a, b, c = (P[:, (k + j) % 4] for j in (1, 2, 3))
        n = np.cross(b - a, c - a)
        n *= -np.sign(np.einsum("cid,cid->ci", n, P - a))[:, :, None]
        n /= np.linalg.norm(n, axis=2, keepdims=True)
        i, j = np.triu_indices(4, 1)
        cosines = -np.einsum("ced,ced->ce", n[:, i], n[:, j])
    largest = float(np.max(cosines, initial=-1.0))
    return math.degrees(math.acos(np.clip(msh.comm.allreduce(largest, op=MPI.MAX), -1.0, 1.0)))


def cells_touching(msh: dmesh.Mesh, node_flag: np.ndarray) -> np.ndarray:
    """The local cells (ghosts included) with a vertex geometry node whose ``node_flag``
    (one value per local geometry node) is nonzero."""
    return np.flatnonzero(np.any(node_flag[vertex_nodes(msh)] != 0, axis=1)).astype(np.int32)


def collapsed_cells(
    msh: dmesh.Mesh, before: np.ndarray, tol: float = 1e-12, cells: np.ndarray | None = None
) -> tuple[np.ndarray, int]:
    """The owned cells a move of the geometry nodes inverted or flattened, and their number
    over all ranks (collective).

    ``before`` is :func:`signed_volumes` of ``cells`` (default all local cells) before the
    move; with J_T = det_after / det_before the cell's (mean) Jacobian determinant of the
    move, a cell is bad if J_T ≤ tol · max_T |J_T| (maximum over all owned cells of all
    ranks).  ``cells`` must contain every cell the move touched: the others keep J_T = 1.
    """
    owned = msh.topology.index_map(msh.topology.dim).size_local
    cells = np.arange(len(before)) if cells is None else np.asarray(cells)
    jac = signed_volumes(msh, cells) / before
    mine = cells < owned
    cells, jac = cells[mine], jac[mine]
    untouched = 1.0 if len(cells) < owned else 0.0  # J_T = 1 on the cells not listed
    scale = msh.comm.allreduce(max(float(np.max(np.abs(jac), initial=0.0)), untouched), op=MPI.MAX)
    bad = cells[jac <= tol * scale]
    return bad, msh.comm.allreduce(len(bad), op=MPI.SUM)


def quarter_disk(
    comm: MPI.Comm, radius: float, h: float, h_contact: float, zone: float
) -> tuple[dmesh.Mesh, dmesh.MeshTags]:
    """Triangulation of {x ≥ 0, y ≤ R} ∩ disk((0, R), R): the arc from (0, 0) to (R, R)
    (tag 1, contact), the top y = R (tag 2) and the axis x = 0 (tag 3); surface tag 10."""
    radius, h, h_contact, zone = _check(radius, h, h_contact, zone)

    def build(gmsh):
        occ, R = gmsh.model.occ, radius
        bottom, centre = occ.addPoint(0, 0, 0), occ.addPoint(0, R, 0)
        corner = occ.addPoint(R, R, 0)
        arc = occ.addCircleArc(bottom, centre, corner)
        top = occ.addLine(corner, centre)
        axis = occ.addLine(centre, bottom)
        surface = occ.addPlaneSurface([occ.addCurveLoop([arc, top, axis])])
        occ.synchronize()
        for tag, curve, name in (
            (CONTACT, arc, "contact"),
            (TOP, top, "top"),
            (AXIS, axis, "axis"),
        ):
            gmsh.model.addPhysicalGroup(1, [curve], tag, name=name)
        gmsh.model.addPhysicalGroup(2, [surface], BODY, name="body")
        _size_field(gmsh, bottom, h, h_contact, zone)
        _generate(gmsh, 2)

    return gmsh_to_mesh(comm, build, "mesh: gmsh cannot build the quarter_disk", gdim=2)


def sphere_octant(
    comm: MPI.Comm, radius: float, h: float, h_contact: float, zone: float
) -> tuple[dmesh.Mesh, dmesh.MeshTags]:
    """Tetrahedra of {x ≥ 0, y ≥ 0, z ≤ R} ∩ ball((0, 0, R), R): the spherical surface
    (tag 1, contact), the top z = R (tag 2), the planes x = 0 (tag 3) and y = 0 (tag 4);
    volume tag 10."""
    radius, h, h_contact, zone = _check(radius, h, h_contact, zone)

    def build(gmsh):
        occ, R = gmsh.model.occ, radius
        # latitude −π/2..0 (lower hemisphere), longitude 0..π/2 (x, y ≥ 0): the south pole,
        # a vertex of the model, is the contact point (0, 0, 0)
        volume = occ.addSphere(0, 0, R, R, -1, -math.pi / 2, 0, math.pi / 2)
        occ.synchronize()
        groups: dict[int, list[int]] = {CONTACT: [], TOP: [], AXIS: [], PLANE_Y: []}
        tol = 1e-8 * R
        for _, face in gmsh.model.getBoundary([(3, volume)], oriented=False):
            x, y, z = occ.getCenterOfMass(2, face)
            kind = (
                TOP
                if abs(z - R) < tol
                else AXIS
                if abs(x) < tol
                else PLANE_Y
                if abs(y) < tol
                else CONTACT
            )
            groups[kind].append(face)
        if any(len(faces) != 1 for faces in groups.values()):
            raise RuntimeError(f"unexpected faces of the sphere octant: {groups}")
        pole = [
            p
            for _, p in gmsh.model.getEntities(0)
            if max(abs(c) for c in gmsh.model.getValue(0, p, [])) < tol
        ]
        if len(pole) != 1:
            raise RuntimeError("the sphere octant has no vertex at the contact point")
        for tag, name in ((CONTACT, "contact"), (TOP, "top"), (AXIS, "x0"), (PLANE_Y, "y0")):
            gmsh.model.addPhysicalGroup(2, groups[tag], tag, name=name)
        gmsh.model.addPhysicalGroup(3, [volume], BODY, name="body")
        _size_field(gmsh, pole[0], h, h_contact, zone)
        _generate(gmsh, 3)

    return gmsh_to_mesh(comm, build, "mesh: gmsh cannot build the sphere_octant", gdim=3)


# two-body builders: facet tags of the curved surfaces and cell tags of the bodies
UPPER_ARC, UPPER_TOP, LOWER_ARC, LOWER_BOTTOM = 1, 2, 3, 4
SPHERE, SPHERE_TOP, BLOCK_TOP, BLOCK_BOTTOM, SYM_X, SYM_Y, BLOCK_SIDES = 1, 2, 3, 4, 5, 6, 7
FIRST_BODY, SECOND_BODY = 1, 2


def half_disks(
    comm: MPI.Comm,
    radius: float,
    radius2: float,
    h: float,
    h_contact: float,
    zone: float,
    overlap: float = 0.0,
    order: int = 1,
) -> tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags]:
    """Two half-disks touching at the origin, meshed independently (2D triangles): the upper
    one {|x − (0, R1)| ≤ R1, y ≤ R1} (cell tag 1; arc tag 1, top y = R1 tag 2) and the lower
    one {|x − (0, d − R2)| ≤ R2, y ≥ d − R2} (cell tag 2; arc tag 3, bottom tag 4), moved up
    by d = ``overlap`` (≥ 0: the bodies interpenetrate by d at x = 0, an interference that
    loads them without a prescribed displacement).  The mesh size is ``h_contact`` within
    ``zone`` of the contact point, ``h`` far from it (lengths in the scene's unit).  With
    ``order`` 2 the cells are gmsh's quadratic triangles (a coordinate element of degree 2):
    the midpoint of every edge on an arc lies on the circle (at the arc's parameter
    midpoint), the other midpoints halfway along their straight edges, so the P2 surfaces
    are curved and the normal gap between them is the circles' to O(h³).  Returns (mesh,
    facet tags, cell tags)."""
    radius, h, h_contact, zone = _check(radius, h, h_contact, zone)
    radius2, *_ = _check(radius2, h, h_contact, zone, "radius2")
    if not (
        isinstance(overlap, (int, float))
        and not isinstance(overlap, bool)
        and 0 <= overlap < 0.1 * min(radius, radius2)
    ):
        raise ConfigError(f"mesh.overlap: must be a number in [0, 0.1 × radius), got {overlap!r}")

    def build(gmsh):
        occ = gmsh.model.occ
        contacts, surfaces, arcs, flats = [], [], [], []
        # upper (centre (0, R1)), lower (centre (0, d − R2))
        for R, s, y0 in ((radius, 1.0, 0.0), (radius2, -1.0, overlap)):
            p0 = occ.addPoint(0, y0, 0)
            centre = occ.addPoint(0, y0 + s * R, 0)
            left, right = occ.addPoint(-R, y0 + s * R, 0), occ.addPoint(R, y0 + s * R, 0)
            arc_l, arc_r = occ.addCircleArc(left, centre, p0), occ.addCircleArc(p0, centre, right)
            flat = occ.addLine(right, left)
            surfaces.append(occ.addPlaneSurface([occ.addCurveLoop([arc_l, arc_r, flat])]))
            contacts.append(p0)
            arcs.append([arc_l, arc_r])
            flats.append(flat)
        occ.synchronize()
        for tag, curves, name in (
            (UPPER_ARC, arcs[0], "upper_arc"),
            (UPPER_TOP, [flats[0]], "upper_top"),
            (LOWER_ARC, arcs[1], "lower_arc"),
            (LOWER_BOTTOM, [flats[1]], "lower_bottom"),
        ):
            gmsh.model.addPhysicalGroup(1, curves, tag, name=name)
        gmsh.model.addPhysicalGroup(2, [surfaces[0]], FIRST_BODY, name="upper")
        gmsh.model.addPhysicalGroup(2, [surfaces[1]], SECOND_BODY, name="lower")
        _size_field(gmsh, contacts, h, h_contact, zone)
        _generate(gmsh, 2)
        if order > 1:
            gmsh.model.mesh.setOrder(order)

    return gmsh_to_mesh(comm, build, "mesh: gmsh cannot build the half_disks", gdim=2, cells=True)


def sphere_on_block(
    comm: MPI.Comm,
    radius: float,
    block: Sequence[float],
    h: float,
    h_contact: float,
    zone: float,
    order: int = 1,
) -> tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags]:
    """A sphere of radius R resting on an elastic block at the origin, the quarter x, y ≥ 0
    of both (3D tetrahedra, meshed independently): the octant of the sphere's lower half
    (cell tag 1; spherical surface tag 1, top z = R tag 2) and the block [0, W]² × [−H, 0]
    for ``block`` = [W, H] (cell tag 2; top z = 0 tag 3, bottom z = −H tag 4, sides x = W and
    y = W tag 7); the symmetry planes x = 0 (tag 5) and y = 0 (tag 6) of both bodies.  Mesh
    size ``h_contact`` within ``zone`` of the contact point, ``h`` far from it.  With
    ``order`` 2 the cells are gmsh's quadratic tetrahedra: the midpoint of every edge on
    the sphere lies on it, the other edges stay straight."""
    radius, h, h_contact, zone = _check(radius, h, h_contact, zone)
    if problem := block_pair(block):
        raise ConfigError(f"mesh.block: {problem}")
    W, H = float(block[0]), float(block[1])

    def build(gmsh):
        occ, R = gmsh.model.occ, radius
        # the ball turned about the x-axis so that the contact point lies on the equator of
        # its parametrisation, not at a pole (regular surface triangles where the contact
        # pressure is measured), then cut to the octant x, y ≥ 0, z ≤ R
        ball = occ.addSphere(0, 0, R, R)
        occ.rotate([(3, ball)], 0, 0, R, 1, 0, 0, math.pi / 2)
        cut, _ = occ.intersect([(3, ball)], [(3, occ.addBox(0, 0, 0, R, R, R))])
        sphere = cut[0][1]
        box = occ.addBox(0, 0, -H, W, W, H)
        occ.synchronize()
        tol = 1e-8 * max(R, W, H)
        groups: dict[int, list[int]] = {
            k: [] for k in (SPHERE, SPHERE_TOP, BLOCK_TOP, BLOCK_BOTTOM, SYM_X, SYM_Y, BLOCK_SIDES)
        }
        for volume, top, bottom in ((sphere, SPHERE_TOP, None), (box, BLOCK_TOP, BLOCK_BOTTOM)):
            for _, face in gmsh.model.getBoundary([(3, volume)], oriented=False):
                x, y, z = occ.getCenterOfMass(2, face)
                if abs(x) < tol:
                    kind = SYM_X
                elif abs(y) < tol:
                    kind = SYM_Y
                elif volume == sphere:
                    kind = SPHERE_TOP if abs(z - R) < tol else SPHERE
                else:
                    assert bottom is not None  # the block has a bottom
                    kind = top if abs(z) < tol else bottom if abs(z + H) < tol else BLOCK_SIDES
                groups[kind].append(face)
        names = {
            SPHERE: "sphere",
            SPHERE_TOP: "sphere_top",
            BLOCK_TOP: "block_top",
            BLOCK_BOTTOM: "block_bottom",
            SYM_X: "x0",
            SYM_Y: "y0",
            BLOCK_SIDES: "block_sides",
        }
        for tag, faces in groups.items():
            gmsh.model.addPhysicalGroup(2, faces, tag, name=names[tag])
        gmsh.model.addPhysicalGroup(3, [sphere], FIRST_BODY, name="sphere")
        gmsh.model.addPhysicalGroup(3, [box], SECOND_BODY, name="block")
        origin = [
            p
            for _, p in gmsh.model.getEntities(0)
            if max(abs(c) for c in gmsh.model.getValue(0, p, [])) < tol
        ]
        if len(origin) != 2:
            raise RuntimeError("the sphere and the block need a vertex each at the contact point")
        _size_field(gmsh, origin, h, h_contact, zone)
        _generate(gmsh, 3)
        if order > 1:
            gmsh.model.mesh.setOrder(order)

    return gmsh_to_mesh(
        comm, build, "mesh: gmsh cannot build the sphere_on_block", gdim=3, cells=True
    )


@dataclass(frozen=True)
class CurvedBoundary:
    """The exact surface on which the facets tagged ``tag`` lie: S = {x : |x − c| = R} (a
    circle in 2D, a sphere in 3D) or, with an ``axis`` a, the cylinder of points at distance
    R from the line c + t a (3D); c = ``centre`` and R = ``radius`` in the mesh's length
    unit."""

    centre: tuple[float, ...]
    radius: float
    tag: int = CONTACT
    axis: tuple[float, ...] | None = None

    def project(self, x: np.ndarray) -> np.ndarray:
        """The radial projection π(x) = c + R (x − c) / |x − c| of points ``x`` (n, gdim)
        onto S (same length unit; x = c has none); for a cylinder the component along the
        axis is kept, π(x) = c + ((x − c)·a) a + R d / |d| with d = x − c − ((x − c)·a) a.
        A plane through c (containing the axis) is mapped into itself (the component of
        x − c normal to it stays 0), so the arc's ends on the axis / top and the sphere's
        edges on the symmetry planes and the top stay on those planes."""
        c = np.asarray(self.centre, dtype=float)
        d = x - c
        along: float | np.ndarray = 0.0
        if self.axis is not None:
            a = np.asarray(self.axis, dtype=float) / np.linalg.norm(self.axis)
            along = np.outer(d @ a, a)
            d = d - along
        return c + along + self.radius * d / np.linalg.norm(d, axis=1, keepdims=True)

    def snap(self, msh: dmesh.Mesh, tags: dmesh.MeshTags, tol: float = 1e-12) -> int:
        """Move every geometry node of a facet tagged ``tag`` to π(x) (collective); return
        the number of nodes moved over all ranks.

        A rank may hold a node (owned or ghost) without holding a tagged facet through it,
        so the ranks first agree on the set of nodes (a flag summed onto the owner and sent
        back to the ghosts); each owner projects its nodes and the ghosts receive the
        owner's coordinates, so every rank holds bit-identical coordinates.  Raises
        RuntimeError if the move inverts or flattens a cell (cell Jacobian determinant
        J_T ≤ tol · max J_T, :func:`collapsed_cells`), e.g. a coarse mesh
        whose cells are thinner than the sagitta h²/(8R) of its boundary edges.
        """
        tdim, gdim = msh.topology.dim, msh.geometry.dim
        msh.topology.create_connectivity(tdim - 1, tdim)
        nodes = dmesh.entities_to_geometry(msh, tdim - 1, tags.find(self.tag)).ravel()
        imap = msh.geometry.index_map()
        flag = la.vector(imap)
        flag.array[nodes] = 1.0
        flag.scatter_reverse(la.InsertMode.add)
        flag.scatter_forward()
        on = np.flatnonzero(flag.array > 0)
        owned = on[on < imap.size_local]
        X = msh.geometry.x
        coords = la.vector(imap, gdim)
        xs = coords.array.reshape(-1, gdim)
        xs[:] = X[:, :gdim]
        xs[owned] = self.project(xs[owned])
        coords.scatter_forward()
        touched = cells_touching(msh, flag.array)  # the only cells whose volume changes
        before = signed_volumes(msh, touched)
        X[on, :gdim] = xs[on]
        _, n_bad = collapsed_cells(msh, before, tol, touched)
        if n_bad:
            total = msh.topology.index_map(tdim).size_global
            raise RuntimeError(
                f"snapping the refined mesh to the curved boundary (tag {self.tag}) "
                f"inverts or flattens {n_bad} of {total} cells"
            )
        return msh.comm.allreduce(len(owned), op=MPI.SUM)


def builder_surfaces(m: MeshConfig) -> list[CurvedBoundary]:
    """The curved surfaces of the two-body builders, by the mesh's own facet tags: the two
    arcs of ``half_disks`` (tags 1 and 3) and the sphere of ``sphere_on_block`` (tag 1);
    empty for every other mesh (``m``: the scene's mesh section)."""
    if m.type not in ("half_disks", "sphere_on_block"):
        return []
    assert m.radius is not None  # required for these types (checked at load)
    if m.type == "half_disks":
        R1 = float(m.radius)
        R2 = float(m.radius2 or R1)
        d = float(m.overlap or 0.0)
        return [
            CurvedBoundary((0.0, R1), R1, UPPER_ARC),
            CurvedBoundary((0.0, d - R2), R2, LOWER_ARC),
        ]
    R = float(m.radius)  # sphere_on_block
    return [CurvedBoundary((0.0, 0.0, R), R, SPHERE)]


def curved_boundary(m: MeshConfig) -> CurvedBoundary | None:
    """The curved surface of the scene's mesh (its mesh section ``m``): for
    ``quarter_disk`` the circle of radius R about (0, R), for ``sphere_octant`` the sphere
    of radius R about (0, 0, R), tag 1 (CONTACT) in both; ``None`` for every other mesh
    (its refinement is left as dolfinx makes it)."""
    centres = {"quarter_disk": 2, "sphere_octant": 3}
    if m.type not in centres:
        return None
    assert m.radius is not None  # required for these types (checked at load)
    R = float(m.radius)
    return CurvedBoundary(centre=(0.0,) * (centres[m.type] - 1) + (R,), radius=R)


#: gmsh's vertices per unit area (2D) / volume (3D) at mesh size s, times s^d, and per unit
#: length (2D) / area (3D) of the boundary, times s^(d-1): (interior, boundary), fitted to
#: uniform meshes, quarter_disk h = 0.02, 0.01 and sphere_octant h = 0.04, 0.025 (2 383 to
#: 25 404 vertices; 3D: HXT's tetrahedra, :data:`TETRAHEDRA`); the interior's 2D value is an
#: equilateral triangulation's 2/√3
VERTEX_DENSITY = {2: (1.153, 0.665), 3: (0.616, 0.808)}


def estimated_vertices(mesh: MeshConfig) -> float:
    """The number of vertices gmsh makes for the parametric mesh ``mesh`` (the ``mesh``
    section of a scene: quarter_disk, sphere_octant, half_disks, sphere_on_block), from its
    parameters alone, before meshing (the DoF budget, :mod:`contact.budget`):

        N_V ≈ Σ_bodies  D_d ∫_body s^{−d} dx + B_d ∫_∂body s^{1−d} dA,

    with s the size field of :func:`_size_field` (h_contact within ``zone`` of the nearest
    contact point, growing with slope GRADING up to h) and (D_d, B_d) =
    :data:`VERTEX_DENSITY`.  Each body is a signed distance φ (≤ 0 inside: the largest of
    those of the disks, balls and half-spaces it is cut from); both integrals run over
    spheres about the body's contact point, sampled by directions on radii spaced
    geometrically, the boundary's as the band |φ| < s/2 divided by its width s.
    Parameters are checked first (ConfigError as the builders raise)."""
    kind = mesh.type
    R, h, h_c, zone = _check(mesh.radius, mesh.h, mesh.h_contact, mesh.zone)
    bodies: list[tuple] = []  # (φ(x) for points x of shape (gdim, ...), contact point, reach)
    if kind in ("quarter_disk", "half_disks"):
        R2 = _check(mesh.radius2 or R, h, h_c, zone, "radius2")[0] if kind == "half_disks" else R
        d = float(mesh.overlap or 0.0)
        for Rk, s, y0 in ((R, 1.0, 0.0),) + (((R2, -1.0, d),) if kind == "half_disks" else ()):

            def disk(x, Rk=Rk, s=s, y0=y0, half=kind == "quarter_disk"):
                c = y0 + s * Rk
                phi = np.maximum(np.hypot(x[0], x[1] - c) - Rk, s * (x[1] - c))
                return np.maximum(phi, -x[0]) if half else phi

            bodies.append((disk, np.array([0.0, y0]), 2 * Rk))
    else:

        def octant(x):
            ball = np.sqrt(x[0] ** 2 + x[1] ** 2 + (x[2] - R) ** 2) - R
            return np.maximum.reduce([ball, -x[0], -x[1], x[2] - R])

        bodies.append((octant, np.zeros(3), 2 * R))
        if kind == "sphere_on_block":
            W, H = (float(v) for v in mesh.block or ())

            def block(x):
                return np.maximum.reduce([-x[0], x[0] - W, -x[1], x[1] - W, x[2], -H - x[2]])

            bodies.append((block, np.zeros(3), math.sqrt(2 * W * W + H * H)))
    gdim = len(bodies[0][1])
    interior, boundary = VERTEX_DENSITY[gdim]
    directions = _directions(gdim)
    points = [p for _, p, _ in bodies]  # the size field measures the distance to the nearest
    total = 0.0
    for phi, p, reach in bodies:
        r = np.geomspace(min(h_c, zone) * 1e-3, 1.2 * reach, 200)
        x = p[:, None, None] + r[None, :, None] * directions[:, None, :]  # (gdim, r, direction)
        dist = np.min([np.linalg.norm(x - q[:, None, None], axis=0) for q in points], axis=0)
        size = np.minimum(h_c + GRADING * np.maximum(dist - zone, 0.0), h)
        level = phi(x)
        band = np.abs(level) < size / 2
        density = (interior * (level <= 0) + boundary * band) * size ** (-gdim)
        sphere = 2 * math.pi * r if gdim == 2 else 4 * math.pi * r**2
        f = sphere * density.mean(axis=1)  # the integral over the sphere of radius r
        total += float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(r)))
    return total


def _directions(gdim: int) -> np.ndarray:
    """Unit vectors spread evenly, shape (gdim, n): 720 angles (2D), a Fibonacci sphere of
    2048 points (3D)."""
    n = 720 if gdim == 2 else 2048
    k = np.arange(n) + 0.5
    if gdim == 2:
        return np.array([np.cos(2 * np.pi * k / n), np.sin(2 * np.pi * k / n)])
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5**0.5) * k
    return np.array([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z])


def _check(
    radius, h, h_contact, zone, radius_key: str = "radius"
) -> tuple[float, float, float, float]:
    """The four parameters as floats; a ConfigError naming the first bad one."""
    values = {radius_key: radius, "h": h, "h_contact": h_contact, "zone": zone}
    for name, value in values.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"mesh.{name}: must be a number, got {value!r}")
        if not math.isfinite(value) or value <= 0:
            raise ConfigError(f"mesh.{name}: must be > 0, got {value:g}")
    if h_contact > h:
        raise ConfigError(f"mesh.h_contact: must be <= mesh.h ({h:g}), got {h_contact:g}")
    if zone >= radius:
        raise ConfigError(f"mesh.zone: must be < mesh.{radius_key} ({radius:g}), got {zone:g}")
    return float(radius), float(h), float(h_contact), float(zone)


#: gmsh options of the tetrahedra of the 3D builders: the HXT algorithm (``Mesh.Algorithm3D``
#: = 10) on one thread.  sphere_on_block at h_contact = 0.0025 (demos/bench/bench_meshing.py,
#: CPU seconds): 2.3 s against 107–113 s for gmsh's Delaunay with Netgen's optimisation
#: (formerly used; Netgen took 86 s of it), 160 096 vertices against 169 427, the worst
#: dihedral angle 13.5° against 19.6°; at h_contact = 0.005 the same Krylov iterations (808
#: against 807) and Hertz errors within 0.3 % of each other.  On two threads HXT's mesh
#: changes from run to run; its optimisation of cells below quality 0.45
#: (``Mesh.OptimizeThreshold``) lifts the worst angle to 19.4° for 3× the time, with no
#: change in those figures.
TETRAHEDRA = {"Mesh.Algorithm3D": 10, "General.NumThreads": 1}


#: gmsh options of the triangles of the 2D builders: gmsh's default Frontal-Delaunay
#: algorithm, each surface on its own thread (half_disks: both bodies at once, 5.4 s against
#: 10.4 s at h_contact = 0.004, 230k vertices; the same triangles, each surface's mesh being
#: its own; Delaunay, ``Mesh.Algorithm`` = 5, saves 15 % for 14 % more vertices and a worst
#: angle of 27.8° against 31.4°)
TRIANGLES = {"Mesh.Algorithm": 6, "Mesh.MaxNumThreads2D": 2}


def _generate(gmsh, dim: int) -> None:
    """Mesh the model up to dimension ``dim`` with the options :data:`TRIANGLES` (2) or
    :data:`TETRAHEDRA` (3): the same mesh on every run, whatever the machine's cores."""
    for option, value in (TRIANGLES if dim == 2 else TETRAHEDRA).items():
        gmsh.option.setNumber(option, value)
    gmsh.model.mesh.generate(dim)


def _size_field(gmsh, point: int | list[int], h: float, h_contact: float, zone: float) -> None:
    """Size h_contact within ``zone`` of model vertex ``point`` (or of any of a list of
    them), growing linearly (slope GRADING) up to h; the field alone sets the size."""
    field = gmsh.model.mesh.field
    distance = field.add("Distance")
    field.setNumbers(distance, "PointsList", point if isinstance(point, list) else [point])
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", h_contact)
    field.setNumber(threshold, "SizeMax", h)
    field.setNumber(threshold, "DistMin", zone)
    field.setNumber(threshold, "DistMax", zone + (h - h_contact) / GRADING)
    field.setAsBackgroundMesh(threshold)
    for option in ("MeshSizeFromPoints", "MeshSizeFromCurvature", "MeshSizeExtendFromBoundary"):
        gmsh.option.setNumber(f"Mesh.{option}", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
