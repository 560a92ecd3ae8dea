"""Pictures a user can look at without ParaView (pyvista, off-screen)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from dolfinx import fem, plot


def _gather_grid(fn: fem.Function):
    """The function on a pyvista grid on rank 0 (``None`` elsewhere): each rank sends its
    part.  The grid also carries the cell data ``log10 h`` (cell diameter)."""
    import pyvista

    V = fn.function_space
    msh = V.mesh
    topology, cell_types, x = plot.vtk_mesh(V)
    bs = V.dofmap.index_map_bs
    values = fn.x.array[: x.shape[0] * bs].real.reshape(x.shape[0], bs)
    values = values[:, 0].copy() if bs == 1 else np.linalg.norm(values, axis=1)  # |u| for vectors
    sizes = np.log10(msh.h(msh.topology.dim, np.arange(len(cell_types), dtype=np.int32)))
    parts = msh.comm.gather((topology, cell_types, x, values, sizes), root=0)
    if msh.comm.rank != 0:
        return None
    grids = []
    for top, types, xx, vals, hs in parts:
        if len(types) == 0:
            continue
        g = pyvista.UnstructuredGrid(top, types, xx)
        g.point_data[fn.name] = vals
        g.cell_data["log10 h"] = hs
        grids.append(g)
    grid = grids[0] if len(grids) == 1 else grids[0].merge(grids[1:])
    return grid


def _quiet_vtk() -> None:
    """VTK warns on stderr when there is no X display before it falls back to off-screen."""
    import vtk

    vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_OFF)
    vtk.vtkObject.GlobalWarningDisplayOff()


def plot_solution(path: str | Path, u_h: fem.Function, active: fem.Function | None = None,
                  title: str = "") -> None:
    """u_h coloured over the mesh (warped in 2D), active contact nodes as red points."""
    import pyvista

    pyvista.OFF_SCREEN = True
    _quiet_vtk()
    comm = u_h.function_space.mesh.comm
    grid = _gather_grid(u_h)
    pts = None
    if active is not None:
        V = active.function_space
        n = V.dofmap.index_map.size_local
        X = V.tabulate_dof_coordinates()[:n]
        local = X[active.x.array[:n] > 0.5]
        gathered = comm.gather(local, root=0)
        pts = np.vstack(gathered) if comm.rank == 0 else None
    if comm.rank != 0:
        return
    gdim = u_h.function_space.mesh.geometry.dim
    plotter = pyvista.Plotter(off_screen=True, window_size=(1200, 900))
    show_edges = grid.n_cells <= 20000
    plotter.add_mesh(grid, scalars=u_h.name, cmap="viridis", show_edges=show_edges,
                     edge_color="#555555", line_width=0.5,
                     scalar_bar_args={"title": u_h.name, "vertical": True})
    if pts is not None and len(pts):
        plotter.add_points(pyvista.PolyData(pts), color="red", point_size=8,
                           render_points_as_spheres=True, label=f"active nodes ({len(pts)})")
        plotter.add_legend(bcolor="white", size=(0.25, 0.06), loc="lower left")
    if title:
        plotter.add_title(title, font_size=12)
    if gdim == 2:
        plotter.view_xy()
    else:
        plotter.view_isometric()
    plotter.screenshot(str(path))
    plotter.close()


def plot_mesh(path: str | Path, u_h: fem.Function, title: str = "", max_edges: int = 20000) -> None:
    """Two panels: the mesh (its edges, or the cell size log10 h_T on meshes of more than
    ``max_edges`` cells, where edges would paint everything black) and u_h."""
    import pyvista

    pyvista.OFF_SCREEN = True
    _quiet_vtk()
    grid = _gather_grid(u_h)
    if u_h.function_space.mesh.comm.rank != 0:
        return
    plotter = pyvista.Plotter(off_screen=True, window_size=(1800, 800), shape=(1, 2))
    plotter.subplot(0, 0)
    if grid.n_cells <= max_edges:
        plotter.add_mesh(grid, color="white", show_edges=True, edge_color="black", line_width=0.5)
        plotter.add_text("mesh", font_size=12)
    else:
        plotter.add_mesh(grid, scalars="log10 h", cmap="magma", show_edges=False,
                         scalar_bar_args={"title": "log10 h_T", "vertical": True})
        plotter.add_text("cell size log10 h_T", font_size=12)
    plotter.view_xy() if u_h.function_space.mesh.geometry.dim == 2 else plotter.view_isometric()
    plotter.subplot(0, 1)
    plotter.add_mesh(grid.copy(), scalars=u_h.name, cmap="viridis", show_edges=False,
                     scalar_bar_args={"title": u_h.name, "vertical": True})
    plotter.add_text(title or u_h.name, font_size=12)
    plotter.view_xy() if u_h.function_space.mesh.geometry.dim == 2 else plotter.view_isometric()
    plotter.screenshot(str(path))
    plotter.close()


def plot_convergence(path: str | Path, rows: list[dict], title: str = "") -> None:
    """η (and the error, where known) against DoFs on log–log axes with N^{-1/2}, N^{-1/3}."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    N = np.array([r["dofs"] for r in rows], dtype=float)
    eta = np.array([r["eta"] for r in rows], dtype=float)
    fig, ax = plt.subplots(figsize=(7, 5))
    ax.loglog(N, eta, "o-", label="estimator η")
    errors = [r["error"] for r in rows]
    if all(e != "" for e in errors):
        ax.loglog(N, np.array(errors, dtype=float), "s-", label="error ‖u − u_h‖_E")
    for p, style in ((0.5, "k--"), (1.0 / 3.0, "k:")):
        ref = eta[0] * (N / N[0]) ** (-p)
        ax.loglog(N, ref, style, lw=1, label=f"N^(-{'1/2' if p == 0.5 else '1/3'})")
    ax.set_xlabel("degrees of freedom N")
    ax.set_ylabel("energy norm")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_pressure(path: str | Path, table: dict, value: str, comparison=None, title: str = "") -> None:
    """The contact pressure −λ_n (elasticity) or flux −λ (scalar) at the contact nodes along
    Γ_C: against the arc length s (2D) or the distance r from the first point of contact
    (3D), active nodes filled; with a declared reference (``comparison``,
    :class:`contact.reference.Comparison`) against its position axis, with its curves."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    name = "contact pressure −λ_n" if value == "lambda_n" else "contact flux −λ"
    if comparison is not None:
        prof = comparison.profile
        reach = max([c[0].max() for c in comparison.curves] + [m[0] for m in comparison.marks] + [0.0])
        keep = prof[:, 0] <= 2.0 * reach if reach > 0 else slice(None)
        ax.plot(prof[keep, 0], prof[keep, 1], "o", ms=3, label=f"computed {name} (nodal)")
        for x, y, label in comparison.curves:
            ax.plot(x, y, "k-", label=label)
        for x, label in comparison.marks:
            ax.axvline(x, color="C1", ls="--", lw=1, label=label)
        ax.set_xlabel(comparison.xlabel)
        extra = ", ".join(f"{k} {100 * v:+.2f}%" for k, v in comparison.errors.items())
        title = f"{title}\n{extra}" if extra else title
    else:
        pos = "s" if "s" in table else "r"
        x, y, act = table[pos], -table[value], table["active"] > 0
        ax.plot(x, y, "-", color="C0", lw=0.8, alpha=0.6)
        ax.plot(x[act], y[act], "o", ms=3.5, color="C3", label=f"active ({int(act.sum())} nodes)")
        ax.plot(x[~act], y[~act], "o", ms=3.5, mfc="none", color="C0", label=f"inactive ({int((~act).sum())})")
        ax.set_xlabel("arc length s along Γ_C (scene length unit)" if pos == "s"
                      else "distance r from the first point of contact (scene length unit)")
    ax.set_ylabel(name)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
