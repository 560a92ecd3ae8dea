"""The pictures of one run (a study's are :mod:`.charts`), to look at without ParaView.

2D fields are drawn with matplotlib (axes in the scene's length unit, colour bars with their
title beside the ticks); 3D fields with pyvista off-screen, seen from the obstacle's side so
that the contact zone is in view.  The pictures of fields are collective: the fields are
gathered on one rank with :func:`contact.output.vtk.gather_grid` and drawn there;
:func:`draw_in_turn` draws several at once, one per rank.
"""

from __future__ import annotations

import errno
import functools
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from dolfinx import fem

from . import drawing, picture_process
from .drawing import (
    FLUX_UNIT,
    LENGTH,
    MAX_EDGES,
    PRESSURE_UNIT,
    RASTER_CELLS,
    Raster,
    active_points,
    bin_average,
    magnitude,
    plot_convergence,
    plot_pressure,
    raster,
    smooth_shading,
)
from .figures import new_figure, save_figure
from .vtk import Grid, gather_grid

__all__ = [
    "RASTER_CELLS",
    "Raster",
    "bin_average",
    "plot_convergence",
    "plot_pressure",
    "raster",
    "smooth_shading",
]


def _field_label(fn: fem.Function) -> str:
    """The colour bar's label of a field: a displacement's magnitude is a length."""
    if fn.function_space.dofmap.index_map_bs > 1:
        return f"{fn.name} magnitude ({LENGTH})"
    return f"{fn.name} (scene units of u)"


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

    On rank 0 the 2D pictures go to the command's picture process if it has one
    (:mod:`.picture_process`), which draws them while this rank gathers the next; they
    are all drawn when this function returns.

    Returns, on every rank, ``{file name: "written" | "not written: <reason>"}`` of the
    pictures with a ``path``; every file exists when it returns."""
    n = min(comm.size, DRAW_RANKS or comm.size)
    process = picture_process.current() if comm.rank == 0 else None
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
            _draw(mine, done, process)
    _draw(mine, done, process)
    if process is not None:
        _collect(process, done)
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


def _draw(held: list, done: dict[str, tuple[str, str]], process=None) -> None:
    """Draw the (name, picture, grid) of ``held``, let go of their grids and note in
    ``done`` how each went: (kind, text) by name, kind "ok", "failed" or "disk".  A picture
    the picture ``process`` takes (:mod:`.picture_process`) is sent to it instead: its
    outcome comes with :func:`_collect`."""
    while held:
        name, picture, grid = held.pop(0)
        if (
            process is not None
            and not isinstance(grid, _Failed)
            and process.takes(picture.draw, grid)
        ):
            process.send(name, picture.draw, grid)
            done[name] = ("sent", str(picture.path) if picture.path is not None else "")
            continue
        try:
            if isinstance(grid, _Failed):
                raise grid.error
            picture.draw(grid)
            done[name] = ("ok", WRITTEN)
        except Exception as err:  # noqa: BLE001 - a picture's failure costs a warning only
            _failed(name, picture.path, err, done)


def _collect(process, done: dict[str, tuple[str, str]]) -> None:
    """The outcomes of the pictures sent to the picture ``process``, into ``done``, once
    all are drawn."""
    for name, err in process.outcomes():
        path = done[name][1] or None
        if err is None:
            done[name] = ("ok", WRITTEN)
        else:
            _failed(name, path, err, done)


def _failed(
    name: str, path: str | Path | None, err: BaseException, done: dict[str, tuple[str, str]]
) -> None:
    """Note picture ``name``'s failure ``err`` in ``done`` and remove its partial file: a
    full disk (:data:`WRITE_ERRNOS`) is the folder's; any other failure one warning line."""
    if path is not None:
        Path(path).unlink(missing_ok=True)
    if isinstance(err, OSError) and err.errno in WRITE_ERRNOS:
        done[name] = ("disk", f"cannot write {name}: {err.strerror or err}")
        return
    text = (
        str(err) if isinstance(err, picture_process.RemoteError) else f"{type(err).__name__}: {err}"
    )
    reason = _one_line(text)
    done[name] = ("failed", f"not written: {reason}")
    from ..base.errors import ContactWarning

    warnings.warn(f"{name} not written: {reason}", ContactWarning, stacklevel=3)


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
    return Picture(
        fields,
        functools.partial(
            drawing.solution_2d, path=path, name=u_h.name, label=_field_label(u_h), title=title
        ),
        Path(path),
    )


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
    return Picture(
        fields,
        functools.partial(
            drawing.mesh_2d,
            path=path,
            name=u_h.name,
            label=_field_label(u_h),
            title=title,
            max_edges=max_edges,
        ),
        Path(path),
    )


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
    pts = active_points(grid)
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
    grid.point_data["shown"] = magnitude(grid.point_data[u_h.name])
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
    pts = active_points(grid)
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
    """A pyvista grid of ``grid`` (a :class:`~contact.output.grid.Grid` or one already)."""
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
    save_figure(fig, path, dpi=120)


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
    save_figure(fig, path, dpi=120)


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
    save_figure(fig, path, dpi=120)


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
