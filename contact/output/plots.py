"""The pictures of one run (a study's are :mod:`.charts`), to look at without ParaView.

2D fields are drawn with matplotlib (axes in the scene's length unit, colour bars with their
title beside the ticks); 3D fields with pyvista off-screen, seen from the obstacle's side so
that the contact zone is in view.  The pictures of fields are collective: the fields are
gathered on one rank with :func:`contact.output.vtk.gather_grid` and drawn there;
:func:`draw_in_turn` draws several at once, one per rank.
"""

from __future__ import annotations

import errno
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from dolfinx import fem

from .figures import new_figure, release_figure
from .vtk import Grid, gather_grid

MAX_EDGES = 20000  # cells above which mesh edges would paint everything black
RASTER_CELLS = 200_000  # cells above which a nodal field is drawn as an image (cells < pixels)
RASTER_WIDTH = 1200  # its pixels across the domain (the axes are 700-1000 pixels wide)


#: the units of the contact plots' axes: nothing is non-dimensionalized (docs/theory.md),
#: so a pressure has the units of the scene's E (a stress), a flux those of k ∂u/∂n
LENGTH = "length, scene units"
PRESSURE_UNIT = "stress: the units of E"
FLUX_UNIT = "the units of k ∂u/∂n"


def _magnitude(values: np.ndarray) -> np.ndarray:
    return values if values.ndim == 1 else np.linalg.norm(values, axis=1)


def _field_label(fn: fem.Function) -> str:
    """The colour bar's label of a field: a displacement's magnitude is a length."""
    if fn.function_space.dofmap.index_map_bs > 1:
        return f"{fn.name} magnitude ({LENGTH})"
    return f"{fn.name} (scene units of u)"


def _triangulation(grid):
    """matplotlib's Triangulation of a 2D grid's cells (their vertices: P2 cells are drawn
    on their corners)."""
    import matplotlib.tri as mtri

    cells = next(iter(grid.cells_dict.values()))[:, :3]
    return mtri.Triangulation(grid.points[:, 0], grid.points[:, 1], cells)


def smooth_shading(ax, tri, values: np.ndarray, cmap: str, plan: Raster | None = None):
    """Nodal ``values`` drawn smoothly: Gouraud shading (one triangle mesh for matplotlib, kept
    out of tight_layout, which would turn every triangle into a path), or on meshes of more
    than :data:`RASTER_CELLS` cells, whose cells are smaller than the pixels, the P1
    interpolant sampled at pixel centres (:func:`raster`) shown as an image, about three
    times faster there (timings: demos/RESULTS.md §10).
    ``plan``: that sampling, when it is already built for ``tri`` (:func:`_raster_plan`)."""
    plan = plan or _raster_plan(tri)
    if plan is None:
        shade = ax.tripcolor(tri, values, shading="gouraud", cmap=cmap)
        shade.set_in_layout(False)
        return shade
    return ax.imshow(
        np.ma.masked_invalid(plan.image(values)),
        extent=plan.extent,
        origin="lower",
        cmap=cmap,
        interpolation="antialiased",
    )


def _raster_plan(tri) -> Raster | None:
    """The pixel sampling of ``tri`` when it has more than :data:`RASTER_CELLS` cells, else
    None (Gouraud shading)."""
    return Raster(tri) if len(tri.triangles) > RASTER_CELLS else None


def raster(
    tri, values: np.ndarray, width: int = RASTER_WIDTH, chunk: int = 2_000_000
) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """The piecewise linear interpolant of nodal ``values`` on the triangles ``tri``
    (a matplotlib Triangulation) at the centres of a ``width``-pixel-wide grid of square
    pixels over the bounding box: (image (ny, width), NaN outside the triangles; extent
    (x0, x1, y0, y1) for ``imshow(origin="lower")``).  One :class:`Raster`, sampled once."""
    plan = Raster(tri, width, chunk)
    return plan.image(values), plan.extent


class Raster:
    """Where the pixel centres of a ``width``-pixel-wide grid of square pixels over the
    bounding box of the triangles ``tri`` fall: for each covered pixel its triangle's corners
    (i0, i1, i2) and barycentric coordinates λ1, λ2, so that :meth:`image` of nodal values v
    is Σ λ_i v_i there — exactly what Gouraud shading paints, without drawing a polygon per
    cell.  Built once per mesh, sampled for every field drawn on it (the mesh picture draws
    two: 1.2M cells, the second field costs a tenth of the first).

    Every triangle visits the pixel centres of its bounding box and keeps those inside it
    (λ ≥ 0).  Work and memory are O(#triangles + #pixels); the candidates are processed
    ``chunk`` at a time."""

    def __init__(self, tri, width: int = RASTER_WIDTH, chunk: int = 2_000_000):
        x, y = np.asarray(tri.x, float), np.asarray(tri.y, float)
        x0, x1, y0, y1 = x.min(), x.max(), y.min(), y.max()
        d = (x1 - x0) / width if x1 > x0 else max(y1 - y0, 1.0) / width
        ny = max(int(np.ceil((y1 - y0) / d)), 1)
        self.shape = (ny, width)
        self.extent = (x0, x0 + width * d, y0, y0 + ny * d)
        # in pixel units (pixel (i, j) has its centre at (i + ½, j + ½)), one array per corner
        x, y = (x - x0) / d, (y - y0) / d
        corners = tri.triangles.T
        X = [x[c] for c in corners]
        Y = [y[c] for c in corners]
        i0 = np.maximum(np.ceil(np.minimum(np.minimum(X[0], X[1]), X[2]) - 0.5), 0).astype(np.int64)
        i1 = np.minimum(np.floor(np.maximum(np.maximum(X[0], X[1]), X[2]) - 0.5), width - 1).astype(
            np.int64
        )
        j0 = np.maximum(np.ceil(np.minimum(np.minimum(Y[0], Y[1]), Y[2]) - 0.5), 0).astype(np.int64)
        j1 = np.minimum(np.floor(np.maximum(np.maximum(Y[0], Y[1]), Y[2]) - 0.5), ny - 1).astype(
            np.int64
        )
        nx_t = np.maximum(i1 - i0 + 1, 0)
        n_t = nx_t * np.maximum(j1 - j0 + 1, 0)
        hit = np.flatnonzero(n_t)  # triangles with a pixel centre in their box
        i0, j0, nx_t, n_t = i0[hit], j0[hit], nx_t[hit], n_t[hit]
        X, Y = [c[hit] for c in X], [c[hit] for c in Y]
        nodes = [c[hit] for c in corners]
        # λ1, λ2 are affine in the pixel position p: λ1 = c1 + p·g1, λ2 = c2 + p·g2 with
        # g1 = (by, −bx)/det, g2 = (−ay, ax)/det (a, b the edges from corner 0)
        ax_, ay_, bx_, by_ = X[1] - X[0], Y[1] - Y[0], X[2] - X[0], Y[2] - Y[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / (ax_ * by_ - ay_ * bx_)
        g1x, g1y, g2x, g2y = by_ * inv, -bx_ * inv, -ay_ * inv, ax_ * inv
        c1 = -(X[0] * g1x + Y[0] * g1y)
        c2 = -(X[0] * g2x + Y[0] * g2y)
        ends = np.cumsum(n_t)
        # per covered pixel: flat index, the three corners, λ1, λ2 (one empty row to start)
        pieces = [(np.zeros(0, np.int64),) * 4 + (np.zeros(0),) * 2]
        start = 0
        while start < len(n_t):
            stop = max(
                int(np.searchsorted(ends, (ends[start - 1] if start else 0) + chunk, side="right")),
                start + 1,
            )
            n = n_t[start:stop]
            tt = np.repeat(np.arange(start, stop), n)  # a triangle per candidate pixel
            k = np.arange(len(tt)) - np.repeat(np.cumsum(n) - n, n)
            i = i0[tt] + k % nx_t[tt]
            j = j0[tt] + k // nx_t[tt]
            px, py = i + 0.5, j + 0.5
            l1 = c1[tt] + px * g1x[tt] + py * g1y[tt]
            l2 = c2[tt] + px * g2x[tt] + py * g2y[tt]
            inside = (l1 >= -1e-9) & (l2 >= -1e-9) & (l1 + l2 <= 1 + 1e-9)
            tt = tt[inside]
            pieces.append(
                (j[inside] * width + i[inside], *(c[tt] for c in nodes), l1[inside], l2[inside])
            )
            start = stop
        self.pixel, *self.corners, self.l1, self.l2 = (
            np.concatenate(column) for column in zip(*pieces)
        )

    def image(self, values: np.ndarray) -> np.ndarray:
        """The interpolant of the nodal ``values`` at the pixel centres, (ny, width), NaN
        outside the triangles (where a pixel centre lies on a shared edge, the last
        triangle holding it wins: the interpolant is continuous, so any will do)."""
        v = np.asarray(values, float)
        v0, v1, v2 = (v[c] for c in self.corners)
        image = np.full(self.shape[0] * self.shape[1], np.nan)
        image[self.pixel] = v0 + self.l1 * (v1 - v0) + self.l2 * (v2 - v0)
        return image.reshape(self.shape)


def _aspect(grid) -> float:
    """Height over width of a 2D grid, kept within [0.3, 1.2] for the figure size."""
    width, height = np.ptp(grid.points[:, :2], axis=0)
    return float(np.clip(height / width, 0.3, 1.2)) if width > 0 else 1.0


def _colorbar(fig, mappable, ax, label: str) -> None:
    """A colour bar as tall as the axes, its label beside the ticks."""
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    cax = make_axes_locatable(ax).append_axes("right", size="4%", pad=0.1)
    fig.colorbar(mappable, cax=cax, label=label)


def _axes_2d(ax, title: str) -> None:
    ax.set_aspect("equal")
    ax.set_xlabel(f"x ({LENGTH})")
    ax.set_ylabel(f"y ({LENGTH})")
    ax.set_title(title, fontsize=10)


def _active_points(grid) -> np.ndarray:
    return (
        grid.points[grid.point_data["active"] > 0.5]
        if "active" in grid.point_data
        else np.zeros((0, 3))
    )


@dataclass(frozen=True)
class Picture:
    """A picture of fields: the point ``fields`` gathered on one grid (all ranks hold them)
    and ``draw(grid)``, which writes the file ``path`` on the rank that holds the grid.  A
    picture without fields (a chart) is drawn by its rank with ``grid`` None; ``root``: its
    data are held by rank 0 only (a contact table), so rank 0 draws it."""

    fields: list
    draw: Callable[[Any], None]
    path: Path | None = None
    root: bool = False


#: how many ranks draw pictures at once (None: all; 1: rank 0 draws every picture, the old
#: path, kept to measure the difference)
DRAW_RANKS: int | None = None
#: OS errors that are the folder's, not a picture's: a picture that meets one fails the run
WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EIO}
WRITTEN = "written"


def draw_in_turn(pictures: Sequence[Picture], comm) -> dict[str, str]:
    """Draw ``pictures`` (collective): picture k is gathered on rank k mod n and drawn
    there, n = ``comm.size`` (or :data:`DRAW_RANKS`); a ``root`` picture on rank 0.  With
    n > 1 every rank first gathers its pictures, then draws them, all ranks at once; put the
    largest first, so that the two largest go to different ranks.  With n = 1 each picture
    is drawn as soon as it is gathered (one grid held at a time).

    A picture that fails costs one warning line naming it (a ContactWarning on the rank
    that drew it; a partial file is removed) and nothing else: the run and its other files
    go on.  A full disk (:data:`WRITE_ERRNOS`) is not the picture's failure but the
    folder's: every rank raises :class:`contact.output.folder.OutputError`.

    Returns, on every rank, ``{file name: "written" | "not written: <reason>"}`` of the
    pictures with a ``path``; every file exists when it returns."""
    n = min(comm.size, DRAW_RANKS or comm.size)
    mine: list = []
    done: dict[str, tuple[str, str]] = {}
    for k, picture in enumerate(pictures):
        owner = 0 if picture.root else k % n
        try:
            grid = gather_grid(picture.fields, root=owner) if picture.fields else None
        except Exception as err:  # noqa: BLE001 - the picture's failure, reported by its owner
            grid = _Failed(err)
        if comm.rank == owner:
            name = Path(picture.path).name if picture.path is not None else f"picture {k}"
            mine.append((name, picture, grid))
        if n == 1:
            _draw(mine, done)
    _draw(mine, done)
    outcomes: dict[str, tuple[str, str]] = {}
    for part in comm.allgather(done):
        outcomes.update(part)
    full = [text for kind, text in outcomes.values() if kind == "disk"]
    if full:
        from .folder import OutputError

        raise OutputError(full[0])
    return {name: text for name, (_, text) in outcomes.items()}


@dataclass(frozen=True)
class _Failed:
    """What a failed gather leaves for the picture's owner to report."""

    error: BaseException


def _draw(held: list, done: dict[str, tuple[str, str]]) -> None:
    """Draw the (name, picture, grid) of ``held``, let go of their grids and note in
    ``done`` how each went: (kind, text) by name, kind "ok", "failed" or "disk"."""
    while held:
        name, picture, grid = held.pop(0)
        try:
            if isinstance(grid, _Failed):
                raise grid.error
            picture.draw(grid)
            done[name] = ("ok", WRITTEN)
        except Exception as err:  # noqa: BLE001 - a picture's failure costs a warning only
            if picture.path is not None:
                Path(picture.path).unlink(missing_ok=True)
            if isinstance(err, OSError) and err.errno in WRITE_ERRNOS:
                done[name] = ("disk", f"cannot write {name}: {err.strerror or err}")
                continue
            reason = _one_line(f"{type(err).__name__}: {err}")
            done[name] = ("failed", f"not written: {reason}")
            from ..base.errors import ContactWarning

            warnings.warn(f"{name} not written: {reason}", ContactWarning, stacklevel=2)


def _one_line(text: str, limit: int = 200) -> str:
    line = " ".join(text.split())
    return line if len(line) <= limit else line[: limit - 1].rstrip() + "…"


def solution_picture(
    path: str | Path,
    u_h: fem.Function,
    active: fem.Function | None = None,
    title: str = "",
    lmbda: fem.Function | None = None,
    normal: Sequence[float] | np.ndarray | None = None,
) -> Picture:
    """u_h (|u_h| for vectors) over the domain with the active contact nodes in red.

    3D: two views — the whole body, and the contact zone seen from the obstacle's side
    (``normal``: the direction from the body towards the obstacle) coloured by the contact
    pressure −λ_h when ``lmbda`` is given."""
    fields = [f for f in (u_h, active, lmbda) if f is not None]
    if u_h.function_space.mesh.geometry.dim == 3:
        return Picture(
            fields, lambda grid: _solution_3d(path, grid, u_h, lmbda, normal, title), Path(path)
        )
    return Picture(fields, lambda grid: _solution_2d(path, grid, u_h, title), Path(path))


def plot_solution(
    path: str | Path,
    u_h: fem.Function,
    active: fem.Function | None = None,
    title: str = "",
    lmbda: fem.Function | None = None,
    normal: Sequence[float] | np.ndarray | None = None,
) -> None:
    """solution.png (:func:`solution_picture`), drawn on rank 0 (collective)."""
    draw_in_turn(
        [solution_picture(path, u_h, active, title, lmbda, normal)], u_h.function_space.mesh.comm
    )


def _solution_2d(path: str | Path, grid, u_h: fem.Function, title: str) -> None:
    tri = _triangulation(grid)
    fig, ax = new_figure(figsize=(8.5, 1.5 + 7.0 * _aspect(grid)))
    shade = smooth_shading(ax, tri, _magnitude(grid.point_data[u_h.name]), "viridis")
    if grid.n_cells <= MAX_EDGES:
        ax.triplot(tri, color="k", lw=0.15, alpha=0.5)
    pts = _active_points(grid)
    if len(pts):
        ax.plot(
            pts[:, 0],
            pts[:, 1],
            "o",
            color="red",
            ms=3 if len(pts) < 300 else 1.2,
            alpha=0.8,
            label=f"active nodes ({len(pts)})",
        )
        # "best" tests every triangle against the legend box (demos/RESULTS.md §10)
        ax.legend(loc="best" if grid.n_cells <= MAX_EDGES else "upper right", fontsize=8)
    _colorbar(fig, shade, ax, _field_label(u_h))
    _axes_2d(ax, title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    release_figure(fig)


def mesh_picture(
    path: str | Path,
    u_h: fem.Function,
    title: str = "",
    max_edges: int = MAX_EDGES,
    normal: Sequence[float] | np.ndarray | None = None,
    active: fem.Function | None = None,
) -> Picture:
    """Two panels: the mesh (its edges, or the cell size log10 h_T on meshes of more than
    ``max_edges`` cells) and u_h.  3D: the surface mesh seen from the obstacle's side
    (``normal``), whole and zoomed to the contact zone (the ``active`` nodes)."""
    fields = [u_h] + ([active] if active is not None else [])
    if u_h.function_space.mesh.geometry.dim == 3:
        return Picture(fields, lambda grid: _mesh_3d(path, grid, title, normal), Path(path))
    return Picture(fields, lambda grid: _mesh_2d(path, grid, u_h, title, max_edges), Path(path))


def plot_mesh(
    path: str | Path,
    u_h: fem.Function,
    title: str = "",
    max_edges: int = MAX_EDGES,
    normal: Sequence[float] | np.ndarray | None = None,
    active: fem.Function | None = None,
) -> None:
    """mesh.png (:func:`mesh_picture`), drawn on rank 0 (collective)."""
    draw_in_turn(
        [mesh_picture(path, u_h, title, max_edges, normal, active)], u_h.function_space.mesh.comm
    )


def _mesh_2d(path: str | Path, grid, u_h: fem.Function, title: str, max_edges: int) -> None:
    tri = _triangulation(grid)
    fig, (ax_m, ax_u) = new_figure(1, 2, figsize=(14, 1.5 + 5.5 * _aspect(grid)))
    plan = _raster_plan(tri)  # both panels sample the same pixels
    if grid.n_cells <= max_edges:
        ax_m.triplot(tri, color="k", lw=0.3)
        _axes_2d(ax_m, f"mesh: {grid.n_cells} cells")
    else:  # h_T carried to the vertices (largest adjacent cell) and drawn smoothly: one
        # triangle mesh for matplotlib instead of one polygon per cell (demos/RESULTS.md §10)
        xy = grid.points[tri.triangles][:, :, :2]
        h = np.max(np.linalg.norm(xy - np.roll(xy, 1, axis=1), axis=2), axis=1)
        h_v = np.zeros(len(grid.points))
        np.maximum.at(h_v, tri.triangles.ravel(), np.repeat(h, 3))
        shade = smooth_shading(ax_m, tri, np.log10(h_v), "magma", plan)
        _colorbar(fig, shade, ax_m, "cell size log10 h_T")
        _axes_2d(ax_m, f"cell size: {grid.n_cells} cells")
    shade = smooth_shading(ax_u, tri, _magnitude(grid.point_data[u_h.name]), "viridis", plan)
    _colorbar(fig, shade, ax_u, _field_label(u_h))
    _axes_2d(ax_u, _field_label(u_h))
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    release_figure(fig)


# ------------------------------------------------------------------------------- 3D (pyvista)


def _quiet_vtk() -> None:
    """VTK warns on stderr when there is no X display before it falls back to off-screen."""
    import vtk

    vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_OFF)
    vtk.vtkObject.GlobalWarningDisplayOff()


def _plotter(shape=(1, 2), size=(1800, 850)):
    import pyvista

    pyvista.OFF_SCREEN = True
    _quiet_vtk()
    return pyvista.Plotter(off_screen=True, window_size=size, shape=shape, border=False)


def _bar(title: str) -> dict:
    """A horizontal colour bar under the view: title above the bar, tick labels below."""
    return {
        "title": title,
        "vertical": False,
        "position_x": 0.2,
        "position_y": 0.05,
        "width": 0.6,
        "height": 0.07,
        "fmt": "%.3g",
        "n_labels": 5,
        "title_font_size": 16,
        "label_font_size": 14,
        "color": "black",
    }


def _add_mesh(plotter, mesh, **kw) -> None:
    """add_mesh with the colour bar's tick labels under the bar and its title above it (VTK
    puts both on one side, where they overlap)."""
    plotter.add_mesh(mesh, **kw)
    args = kw.get("scalar_bar_args", {})
    if args.get("title") in plotter.scalar_bars:
        bar = plotter.scalar_bars[args["title"]]
        bar.SetTextPositionToPrecedeScalarBar()
        bar.SetTitle("")
        plotter.add_text(
            args["title"],
            position=(args["position_x"], args["position_y"] + args["height"] + 0.01),
            viewport=True,
            font_size=11,
            color="black",
        )


def _look_from(
    plotter, focus: np.ndarray, normal: np.ndarray, extent: float, tilt: float = 35.0
) -> None:
    """Camera on the obstacle's side of ``focus`` (``normal`` points from the body to the
    obstacle), tilted by ``tilt`` degrees for depth, parallel projection showing ``extent``
    around it."""
    n = normal / np.linalg.norm(normal)
    side = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
    side /= np.linalg.norm(side)
    direction = np.cos(np.radians(tilt)) * n + np.sin(np.radians(tilt)) * side
    up = np.cross(side, n)
    plotter.camera.focal_point = focus
    plotter.camera.position = focus + 10.0 * extent * direction
    plotter.camera.up = up
    plotter.enable_parallel_projection()
    plotter.camera.parallel_scale = extent


def _contact_view(grid, normal) -> tuple[np.ndarray, np.ndarray, float]:
    """(focus, view normal, extent): the active nodes' centre and spread (the whole body
    if none is active), seen along ``normal`` (default −z)."""
    n = np.asarray(normal if normal is not None else (0.0, 0.0, -1.0), dtype=float)
    pts = _active_points(grid)
    size = float(np.linalg.norm(np.ptp(grid.points, axis=0)))
    if len(pts) == 0:
        return grid.center, n, 0.6 * size
    focus = pts.mean(axis=0)
    spread = float(np.max(np.linalg.norm(pts - focus, axis=1)))
    return focus, n, min(max(2.0 * spread, 0.02 * size), 0.6 * size)


def _solution_3d(path, grid, u_h, lmbda, normal, title) -> None:
    import pyvista

    grid = _vtk_grid(grid)
    p = _plotter()
    label = _field_label(u_h)
    grid.point_data["shown"] = _magnitude(grid.point_data[u_h.name])
    p.subplot(0, 0)
    _add_mesh(
        p,
        grid.copy(),
        scalars="shown",
        cmap="viridis",
        show_edges=grid.n_cells <= MAX_EDGES,
        edge_color="#555555",
        line_width=0.5,
        scalar_bar_args=_bar(label),
    )
    focus, n, extent = _contact_view(grid, normal)
    _look_from(p, grid.center, n, 0.6 * float(np.linalg.norm(np.ptp(grid.points, axis=0))))
    p.add_text(
        f"{label}, whole body seen from the obstacle's side", position="upper_edge", font_size=11
    )
    p.subplot(0, 1)
    surface = grid.extract_surface(algorithm="dataset_surface")  # explicit: the default changes
    if lmbda is not None:
        surface.point_data["pressure"] = np.abs(surface.point_data[lmbda.name])
        _add_mesh(
            p,
            surface,
            scalars="pressure",
            cmap="YlOrRd",
            show_edges=True,
            edge_color="#999999",
            line_width=0.5,
            scalar_bar_args=_bar(f"contact pressure -{lmbda.name} (units of E)"),
        )
    else:
        _add_mesh(
            p,
            surface,
            scalars="shown",
            cmap="viridis",
            show_edges=True,
            scalar_bar_args=_bar(label),
        )
    pts = _active_points(grid)
    if len(pts):
        p.add_points(
            pyvista.PolyData(pts), color="#1f4fff", point_size=7, render_points_as_spheres=True
        )
    p.add_text(
        f"contact zone seen from the obstacle: {len(pts)} active nodes (blue)",
        position="upper_edge",
        font_size=11,
    )
    _look_from(p, focus, n, extent, tilt=0.0)
    _save(p, path, title)


def _vtk_grid(grid):
    """A pyvista grid of ``grid`` (a :class:`~contact.output.vtk.Grid` or one already)."""
    return grid.pyvista() if isinstance(grid, Grid) else grid


def _mesh_3d(path, grid, title, normal) -> None:
    grid = _vtk_grid(grid)
    p = _plotter()
    focus, n, extent = _contact_view(grid, normal)
    whole = 0.6 * float(np.linalg.norm(np.ptp(grid.points, axis=0)))
    surface = grid.extract_surface(algorithm="dataset_surface")  # explicit: the default changes
    for col, (centre, scale, text) in enumerate(
        (
            (grid.center, whole, "surface mesh seen from the obstacle's side"),
            (focus, extent, "contact zone seen from the obstacle"),
        )
    ):
        p.subplot(0, col)
        p.add_mesh(
            surface.copy(), color="white", show_edges=True, edge_color="black", line_width=0.4
        )
        p.add_text(text, position="upper_edge", font_size=11)
        _look_from(p, centre, n, scale, tilt=35.0 if col == 0 else 0.0)
    _save(p, path, title)


def _save(plotter, path, title: str) -> None:
    if title:
        plotter.subplot(0, 0)
        plotter.add_text(title, position="lower_left", font_size=10)
    plotter.screenshot(str(path))
    plotter.close()


def plot_convergence(path: str | Path, rows: list[dict], title: str = "") -> None:
    """η (and the error, where known) against DoFs on log–log axes with N^{-1/2}, N^{-1/3}."""
    N = np.array([r["dofs"] for r in rows], dtype=float)
    eta = np.array([r["eta"] for r in rows], dtype=float)
    fig, ax = new_figure(figsize=(7, 5))
    ax.loglog(N, eta, "o-", label="estimator η")
    errors = [r["error"] for r in rows]
    if all(e != "" for e in errors):
        ax.loglog(N, np.array(errors, dtype=float), "s-", label="error ‖u − u_h‖_E")
    for p, style in ((0.5, "k--"), (1.0 / 3.0, "k:")):
        ref = eta[0] * (N / N[0]) ** (-p)
        ax.loglog(N, ref, style, lw=1, label=f"N^(-{'1/2' if p == 0.5 else '1/3'})")
    ax.set_xlabel("degrees of freedom N (a count)")
    ax.set_ylabel("energy norm ‖·‖_E (scene units)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    release_figure(fig)


def bin_average(
    x: np.ndarray, y: np.ndarray, per_bin: int = 8, most: int = 30
) -> tuple[np.ndarray, np.ndarray]:
    """The mean of scattered values y over bins of x: equal widths from min(x) to max(x),
    about ``per_bin`` values each (at most ``most`` bins); empty bins are left out.  The
    profile of nodal pressures that scatter at one radius (3D, unstructured meshes)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) == 0:
        return x, y
    bins = int(np.clip(len(x) // per_bin, 1, most))
    edges = np.linspace(x.min(), x.max(), bins + 1)
    which = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, bins - 1)
    count = np.bincount(which, minlength=bins)
    full = count > 0
    mean_x = np.bincount(which, x, minlength=bins)[full] / count[full]
    return mean_x, np.bincount(which, y, minlength=bins)[full] / count[full]


def plot_pressure(
    path: str | Path, table: dict, value: str, comparison=None, title: str = ""
) -> None:
    """The contact pressure −λ_n (elasticity) or flux −λ (scalar) at the contact nodes along
    Γ_C: against the arc length s (2D) or the distance r from the first point of contact
    (3D), as points (nodal values; active nodes filled), with the reference curves as
    lines: a declared reference (``comparison``, :class:`contact.post.comparison.Comparison`,
    against its position axis) or the exact flux of a declared ``data.exact``
    (``lambda_exact``).  In 3D the nodal values scatter at one r (the mesh is not symmetric
    about the axis), so the profile drawn through them is their average over bins of r, not
    a line joining them."""
    fig, ax = new_figure(figsize=(7.5, 4.8))
    scalar = value != "lambda_n"
    name = (
        f"contact flux −λ ({FLUX_UNIT})" if scalar else f"contact pressure −λ_n ({PRESSURE_UNIT})"
    )
    what = "flux" if scalar else "pressure"
    three_d = "r" in table
    if comparison is not None:
        prof = comparison.profile
        reach = max(
            [c[0].max() for c in comparison.curves] + [m[0] for m in comparison.marks] + [0.0]
        )
        keep = prof[:, 0] <= 2.0 * reach if reach > 0 else slice(None)
        x, y = prof[keep, 0], prof[keep, 1]
        ax.plot(x, y, "o", ms=3, color="C0", label=f"computed {what}: nodal values")
        xlabel = comparison.xlabel
    else:
        pos = "r" if three_d else "s"
        x, y, act = table[pos], -table[value], table["active"] > 0
        ax.plot(x[act], y[act], "o", ms=3.5, color="C3", label=f"active ({int(act.sum())} nodes)")
        ax.plot(
            x[~act],
            y[~act],
            "o",
            ms=3.5,
            mfc="none",
            color="C0",
            label=f"inactive ({int((~act).sum())} nodes)",
        )
        xlabel = (
            f"distance r from the first point of contact ({LENGTH})"
            if three_d
            else f"arc length s along Γ_C ({LENGTH})"
        )
    if three_d:
        bx, by = bin_average(x, y)
        ax.plot(bx, by, "-", color="C2", lw=1.5, label=f"computed {what}: average over bins of r")
    elif comparison is None:
        # a curve along Γ_C, in order of s (2D: consecutive nodes are neighbours)
        ax.plot(x, y, "-", color="C0", lw=0.8, alpha=0.6, label=f"computed {what} along Γ_C")
    if comparison is not None:
        for cx, cy, label in comparison.curves:
            ax.plot(cx, cy, "k-", lw=1.2, label=label)
        for mx, label in comparison.marks:
            ax.axvline(mx, color="C1", ls="--", lw=1, label=label)
        extra = ", ".join(f"{k} {100 * v:+.2f}%" for k, v in comparison.errors.items())
        title = f"{title}\n{extra}" if extra else title
    if "lambda_exact" in table and comparison is None:
        ax.plot(
            x,
            -np.asarray(table["lambda_exact"]),
            "k-",
            lw=1.2,
            label="exact flux −λ of data.exact (averaged over each node's support)",
        )
    ax.set_xlabel(xlabel if "(" in xlabel else f"{xlabel} ({LENGTH})")
    ax.set_ylabel(name)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    release_figure(fig)


#: the most load steps whose curves a traction picture draws (each one in the legend)
MAX_TRACTION_CURVES = 10


def drawn_steps(count: int, most: int = MAX_TRACTION_CURVES) -> list[int]:
    """The indices of the steps a traction picture draws: all of ``count`` up to ``most``,
    else ``most`` of them evenly spaced, the first and the last included."""
    if count <= most:
        return list(range(count))
    return sorted({int(round(k)) for k in np.linspace(0, count - 1, most)})


def plot_traction(
    path: str | Path,
    steps: list[tuple[float, dict]],
    title: str = "",
    references: Sequence[tuple[int, np.ndarray, np.ndarray, str]] = (),
) -> None:
    """Contact tractions along Γ_C, one curve per load step coloured by the pseudo-time t
    (``steps``: (t, contact table of :mod:`contact.post.contact_table` with the friction
    columns)): the pressure −λ_n (top) and the tangential traction λ_t (bottom, 2D: its
    component along t_0) against the arc length s, with the friction bounds +ρ and −ρ of the
    last step dashed on top (where λ_t reaches one the node slips) and the slipping nodes of
    the last step circled, zoomed on the contact zone when it is less than half of Γ_C; a
    scalar model's table (column ``lambda``): its flux −λ, one panel.  Every curve drawn is
    in the legend; of more than :data:`MAX_TRACTION_CURVES` steps that many are drawn, evenly
    spaced (the title says so).  3D: :func:`plot_traction_map`.
    ``references``: (panel 0 | 1, x, y, label) curves such as the Hertz pressure or an exact
    traction."""
    from matplotlib import colormaps

    table = steps[-1][1]
    if "s" not in table:
        return plot_traction_map(path, table, title, t=steps[-1][0])
    scalar = "lambda_n" not in table  # a scalar model: the flux −λ, no tangential panel
    value = "lambda" if scalar else "lambda_n"
    fig, grid = new_figure(
        1 if scalar else 2, 1, figsize=(9.0, 4.5 if scalar else 7.0), sharex=True, squeeze=False
    )
    axes = grid[:, 0]
    cmap = colormaps["viridis"]
    t_max = max(t for t, _ in steps)
    friction = "lambda_t" in table
    shown = drawn_steps(len(steps))
    for k in shown:
        t, tab = steps[k]
        colour = cmap(t / t_max if len(steps) > 1 else 0.0)
        kw = {"color": colour, "ms": 3, "lw": 1, "label": f"t = {t:.4g}"}
        axes[0].plot(tab["s"], -np.asarray(tab[value]), ".-", **kw)
        if friction:
            axes[1].plot(tab["s"], tab["lambda_t"], ".-", **kw)
    x = np.asarray(table["s"])
    if friction:
        bound = np.asarray(table["bound"])
        axes[1].plot(x, bound, "k--", lw=1.2, zorder=4, label=f"friction bound +ρ at t = {t_max:g}")
        axes[1].plot(x, -bound, "k:", lw=1.6, zorder=4, label=f"friction bound −ρ at t = {t_max:g}")
        slip = np.asarray(table["status"]) == "slip"
        axes[1].plot(
            x[slip],
            np.asarray(table["lambda_t"])[slip],
            "o",
            mfc="none",
            mec="C3",
            ms=6,
            zorder=5,
            label=f"slipping at t = {t_max:g}",
        )
    for panel, rx, ry, label in references:
        if panel < len(axes):
            axes[panel].plot(rx, ry, "k-", lw=1.5, label=label)
    lam_n = np.asarray(table[value])
    pressed = lam_n < -1e-9 * np.max(np.abs(lam_n), initial=0.0)
    if pressed.any() and np.ptp(x[pressed]) < 0.5 * np.ptp(x):  # a small contact zone: zoom on it
        lo, hi = x[pressed].min(), x[pressed].max()
        pad = 0.3 * max(hi - lo, 1e-12)
        axes[-1].set_xlim(lo - pad, hi + pad)
    if scalar:
        axes[0].set_ylabel(f"flux −λ ({FLUX_UNIT})")
    else:
        axes[0].set_ylabel(f"pressure −λ_n ({PRESSURE_UNIT})")
        axes[1].set_ylabel(f"tangential traction λ_t ({PRESSURE_UNIT})")
    axes[-1].set_xlabel(f"arc length s along Γ_C ({LENGTH})")
    # the load steps: one legend beside both panels (the same curves in each); the bounds,
    # the slipping nodes and the references: in their panel's legend
    step_labels = {f"t = {steps[k][0]:.4g}" for k in shown}
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(
        [h for h, lb in zip(handles, labels) if lb in step_labels],
        [lb for lb in labels if lb in step_labels],
        loc="center right",
        fontsize=8,
        title="load step",
    )
    for ax in axes:
        ax.grid(alpha=0.3)
        own = [(h, lb) for h, lb in zip(*ax.get_legend_handles_labels()) if lb not in step_labels]
        if own:
            ax.legend(*zip(*own), fontsize=8)
    if len(shown) < len(steps):
        title = f"{title}\n{len(shown)} of {len(steps)} load steps drawn, evenly spaced"
    axes[0].set_title(title, fontsize=10)
    fig.tight_layout(rect=(0, 0, 0.83, 1))
    fig.savefig(path, dpi=120)
    release_figure(fig)


def plot_force_displacement(
    path: str | Path,
    x: Sequence[float],
    force: Sequence[float] | Mapping[str, Sequence[float]],
    xlabel: str,
    title: str = "",
    indefinite: Sequence[bool] = (),
    unstable: Sequence[bool] = (),
) -> None:
    """The contact force of each load step against the load's displacement ``x`` (the
    obstacle's approach, or a prescribed displacement): one marker per step, joined, from
    (0, 0); ``force`` one value per step, or several curves by label (the normal and the
    tangential force of a frictional path).  ``indefinite[k]``: the Newton iteration of
    step k met an indefinite tangent (the energy search acted: a buckle or a snap happens
    there); ``unstable[k]``: K_T has negative eigenvalues at step k's solution (an unstable
    equilibrium).  The marks go on the first curve."""
    curves = force if isinstance(force, Mapping) else {"contact force per step": force}
    x = np.r_[0.0, np.asarray(x, float)]
    fig, ax = new_figure(figsize=(7, 5))
    first = None
    for k, (label, values) in enumerate(curves.items()):
        y = np.r_[0.0, np.asarray(values, float)]
        if len(y) != len(x):
            raise ValueError(f"force curve {label!r}: {len(y) - 1} values for {len(x) - 1} steps")
        ax.plot(x, y, "o-", color=f"C{k}", ms=4, label=label)
        first = y if first is None else first
    for flags, marker, color, label in (
        (indefinite, "s", "C3", "K_T indefinite during the step (energy search acted)"),
        (unstable, "x", "k", "K_T indefinite at the solution (unstable)"),
    ):
        mask = np.r_[False, np.asarray(flags, dtype=bool)] if len(flags) else None
        if first is not None and mask is not None and mask.any():
            ax.plot(
                x[mask], first[mask], marker, mfc="none", mec=color, color=color, ms=10, label=label
            )
    ax.set_xlabel(xlabel)
    ax.set_ylabel("contact force (per unit depth in 2D)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    release_figure(fig)


def plot_traction_map(path: str | Path, table: dict, title: str = "", t: float = 1.0) -> None:
    """3D: the contact surface seen along the obstacle's normal (the coordinate of least
    spread dropped), left the pressure −λ_n, right (with friction) the tangential traction
    λ_t as arrows coloured by the status (stick / slip), separated nodes grey.  A
    frictionless table (no λ_t columns) gets the pressure panel alone."""
    X = np.c_[table["x"], table["y"], table["z"]]
    keep = [i for i in range(3) if i != int(np.argmin(np.ptp(X, axis=0)))]
    P = X[:, keep]
    friction = "lambda_t_x" in table
    fig, axes = new_figure(
        1, 2 if friction else 1, figsize=(12 if friction else 6.5, 5.5), squeeze=False
    )
    axes = axes[0]
    scalar = "lambda_n" not in table  # a scalar model: the flux −λ
    value = -np.asarray(table["lambda" if scalar else "lambda_n"])
    sc = axes[0].scatter(P[:, 0], P[:, 1], c=value, s=12, cmap="viridis")
    label = f"flux −λ ({FLUX_UNIT})" if scalar else f"pressure −λ_n ({PRESSURE_UNIT})"
    fig.colorbar(sc, ax=axes[0], label=label)
    axes[0].set_title("contact pressure" if friction else f"contact pressure at t = {t:g}")
    if friction:
        _tangential_arrows(axes[1], P, table, keep, t)
    labels = ["xyz"[i] for i in keep]
    for ax in axes:
        ax.set_aspect("equal")
        ax.set_xlabel(f"{labels[0]} ({LENGTH})")
        ax.set_ylabel(f"{labels[1]} ({LENGTH})")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    release_figure(fig)


def _tangential_arrows(ax, P: np.ndarray, table: dict, keep: list[int], t: float) -> None:
    """λ_t of a 3D table at the points P (the ``keep`` components) as arrows by status."""
    lam_t = np.c_[table["lambda_t_x"], table["lambda_t_y"], table["lambda_t_z"]][:, keep]
    status = np.asarray(table["status"])
    scale = float(np.max(np.abs(lam_t), initial=0.0)) / (0.06 * float(np.ptp(P))) or 1.0
    for name, colour in (("stick", "C0"), ("slip", "C3")):
        m = status == name
        ax.quiver(
            P[m, 0],
            P[m, 1],
            lam_t[m, 0],
            lam_t[m, 1],
            color=colour,
            label=f"{name} ({m.sum()})",
            angles="xy",
            scale_units="xy",
            scale=scale,
        )
    m = status == "separated"
    ax.plot(P[m, 0], P[m, 1], ".", color="0.6", ms=3, label=f"separated ({m.sum()})")
    ax.set_title(f"tangential traction λ_t at t = {t:g} (arrow length ∝ |λ_t|)")
    ax.legend(loc="upper right", fontsize=8)
