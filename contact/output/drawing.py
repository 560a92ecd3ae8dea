"""The 2D pictures of a run drawn with matplotlib from numpy data: u_h (:func:`solution_2d`),
the mesh (:func:`mesh_2d`), the convergence and pressure charts.

Nothing here takes a DOLFINx object: the fields arrive gathered on a
:class:`~contact.output.grid.Grid` and the labels as text, and this module imports numpy
and matplotlib only (matplotlib inside the functions).  So a picture is a call of one of
these functions with its keywords bound (``functools.partial``), which pickles, and the
picture process (:mod:`.picture_process`) draws it while the command still imports,
solves and writes (:mod:`.plots` builds the pictures).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .figures import new_figure, save_figure

MAX_EDGES = 20000  # cells above which mesh edges would paint everything black
RASTER_CELLS = 200_000  # cells above which a nodal field is drawn as an image (cells < pixels)
RASTER_WIDTH = 1200  # its pixels across the domain (the axes are 700-1000 pixels wide)


#: the units of the contact plots' axes: nothing is non-dimensionalized (docs/theory.md),
#: so a pressure has the units of the scene's E (a stress), a flux those of k ∂u/∂n
LENGTH = "length, scene units"
PRESSURE_UNIT = "stress: the units of E"
FLUX_UNIT = "the units of k ∂u/∂n"


def magnitude(values: np.ndarray) -> np.ndarray:
    return values if values.ndim == 1 else np.linalg.norm(values, axis=1)


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


def active_points(grid) -> np.ndarray:
    return (
        grid.points[grid.point_data["active"] > 0.5]
        if "active" in grid.point_data
        else np.zeros((0, 3))
    )


def solution_2d(grid, *, path: str | Path, name: str, label: str, title: str) -> None:
    """solution.png of a 2D field: the point field ``name`` of ``grid`` (its magnitude if a
    vector) shaded smoothly, the mesh edges (up to :data:`MAX_EDGES` cells), the active
    nodes (point field ``active``) in red, and a colour bar titled ``label``."""
    tri = _triangulation(grid)
    fig, ax = new_figure(figsize=(8.5, 1.5 + 7.0 * _aspect(grid)))
    shade = smooth_shading(ax, tri, magnitude(grid.point_data[name]), "viridis")
    if grid.n_cells <= MAX_EDGES:
        ax.triplot(tri, color="k", lw=0.15, alpha=0.5)
    pts = active_points(grid)
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
    _colorbar(fig, shade, ax, label)
    _axes_2d(ax, title)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def mesh_2d(
    grid, *, path: str | Path, name: str, label: str, title: str, max_edges: int = MAX_EDGES
) -> None:
    """mesh.png of a 2D field: two panels, the mesh (its edges, or the cell size log10 h_T
    on meshes of more than ``max_edges`` cells) and the point field ``name`` of ``grid``
    (colour bar ``label``)."""
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
    shade = smooth_shading(ax_u, tri, magnitude(grid.point_data[name]), "viridis", plan)
    _colorbar(fig, shade, ax_u, label)
    _axes_2d(ax_u, label)
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


# ------------------------------------------------------------------------------- 3D (pyvista)


def plot_convergence(path: str | Path, rows: list[dict], title: str = "") -> None:
    """η (and the error, where known) against DoFs on log–log axes with N^{-1/2}, N^{-1/3}.

    A level without η (``eta`` '': the last with ``adapt.estimate_last`` false) has no η
    point; the reference lines start at the first η, else at the first error.
    """
    N = np.array([r["dofs"] for r in rows], dtype=float)
    estimated = np.array([r["eta"] != "" for r in rows])
    eta = np.array([r["eta"] for r in rows if r["eta"] != ""], dtype=float)
    fig, ax = new_figure(figsize=(7, 5))
    ax.loglog(N[estimated], eta, "o-", label="estimator η")
    errors = [r["error"] for r in rows]
    start = (N[estimated][0], eta[0]) if len(eta) else None
    if all(e != "" for e in errors):
        ax.loglog(N, np.array(errors, dtype=float), "s-", label="error ‖u − u_h‖_E")
        start = start or (N[0], float(errors[0]))
    for p, style in ((0.5, "k--"), (1.0 / 3.0, "k:")):
        if start is None:  # neither η nor an error: no line to start from
            break
        ref = start[1] * (N / start[0]) ** (-p)
        ax.loglog(N, ref, style, lw=1, label=f"N^(-{'1/2' if p == 0.5 else '1/3'})")
    ax.set_xlabel("degrees of freedom N (a count)")
    ax.set_ylabel("energy norm ‖·‖_E (scene units)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    ax.set_title(title)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


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
    save_figure(fig, path, dpi=120)


def convergence_chart(grid: None, *, path: str | Path, rows: list[dict], title: str) -> None:
    """:func:`plot_convergence` as a picture without fields (``grid``: None)."""
    plot_convergence(path, rows, title)


def pressure_chart(
    grid: None, *, path: str | Path, table: dict | None, value: str, comparison, title: str
) -> None:
    """:func:`plot_pressure` as a picture without fields (``grid``: None), drawn by the
    rank that holds the ``table`` (rank 0; None on the others)."""
    assert table is not None
    plot_pressure(path, table, value, comparison, title=title)
