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


def plot_pressure(path: str | Path, res: dict, title: str = "") -> None:
    """Computed contact pressure −λ_n against the in-plane distance from the first point of
    contact, with the Hertz profile p0 √(1 − ρ²/a²) for the computed total force."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    prof = np.asarray(res["pressure_profile"])
    a_H, p0_H = res["hertz_a"], res["hertz_p0"]
    a = res.get("contact_half_width", res.get("contact_radius"))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    keep = prof[:, 0] <= 2.0 * a_H
    ax.plot(prof[keep, 0], prof[keep, 1], "o", ms=3, label="computed −λ_n (nodal)")
    rho = np.linspace(0, a_H, 200)
    ax.plot(rho, p0_H * np.sqrt(1 - (rho / a_H) ** 2), "k-", label=f"Hertz: a = {a_H:.4g}, p0 = {p0_H:.4g}")
    ax.axvline(a, color="C1", ls="--", lw=1, label=f"computed a = {a:.4g} ({100 * res['a_error']:+.1f}%)")
    ax.set_xlabel("distance from the first point of contact ρ")
    ax.set_ylabel("contact pressure")
    ax.set_title(title + f"\npeak {res['peak_pressure']:.4g} ({100 * res['p0_error']:+.1f}% vs Hertz)")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_traction(path: str | Path, steps: list[tuple[float, list[dict]]], title: str = "",
                  references: list[tuple[int, np.ndarray, np.ndarray, str]] = ()) -> None:
    """Contact tractions along Γ_C (rows of :func:`contact.surface.surface_rows`), one curve
    per load step coloured by the pseudo-time t: the pressure −λ_n (top) and the tangential
    traction λ_t (2D, along the position's tangent) or |λ_t| (3D) (bottom), with the
    friction bound ±ρ of the last step dashed (where λ_t reaches it, the node slips) and
    slipping nodes of the last step marked (zoomed on the contact zone when it is less than
    half of Γ_C).  ``references``: (panel 0 | 1, x, y, label)
    curves such as the Hertz pressure or an exact traction."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = steps[-1][1]
    if "z" in rows[0] and "lambda_t_norm" in rows[0]:
        return plot_traction_map(path, rows, title, t=steps[-1][0])
    three_d = "lambda_t_norm" in rows[0] and "lambda_t" not in rows[0]
    key = "lambda_t_norm" if three_d else "lambda_t"
    style = dict(marker=".", ls="none", ms=3) if three_d else dict(marker=".", ms=3, lw=1)
    fig, axes = plt.subplots(2, 1, figsize=(7.5, 6.5), sharex=True)
    cmap = plt.get_cmap("viridis")
    t_max = max(t for t, _ in steps)
    for t, rs in steps:
        x = np.array([r["position"] for r in rs])
        colour = cmap(t / t_max if len(steps) > 1 else 0.0)
        label = f"t = {t:g}" if len(steps) <= 8 or t in (steps[0][0], t_max) else None
        axes[0].plot(x, [-r["lambda_n"] for r in rs], color=colour, label=label, **style)
        if key in rs[0]:
            axes[1].plot(x, [r[key] for r in rs], color=colour, label=label, **style)
    x = np.array([r["position"] for r in rows])
    if key in rows[0]:
        bound = np.array([r["bound"] for r in rows])
        order = np.argsort(x)
        axes[1].plot(x[order], bound[order], "k--", lw=1, label="friction bound ±ρ")
        if not three_d:
            axes[1].plot(x[order], -bound[order], "k--", lw=1)
        slip = np.array([r["status"] == "slip" for r in rows])
        axes[1].plot(x[slip], np.array([r[key] for r in rows])[slip], "o", mfc="none", mec="C3", ms=6,
                     label=f"slipping at t = {t_max:g}")
    for panel, rx, ry, label in references:
        axes[panel].plot(rx, ry, "k-", lw=1.5, label=label)
    lam_n = np.array([r["lambda_n"] for r in rows])
    pressed = lam_n < -1e-9 * np.max(np.abs(lam_n), initial=0.0)
    if pressed.any() and np.ptp(x[pressed]) < 0.5 * np.ptp(x):   # a small contact zone: zoom on it
        lo, hi = x[pressed].min(), x[pressed].max()
        pad = 0.3 * max(hi - lo, 1e-12)
        axes[1].set_xlim(lo - pad if not three_d else 0.0, hi + pad)
    axes[0].set_ylabel("pressure −λ_n")
    axes[1].set_ylabel("|λ_t|" if three_d else "tangential traction λ_t")
    axes[1].set_xlabel("distance from the first contact point in the tangent plane" if three_d
                       else "position along Γ_C")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_traction_map(path: str | Path, rows: list[dict], title: str = "", t: float = 1.0) -> None:
    """3D friction: the contact surface seen along the obstacle's normal (the coordinate of
    least spread dropped), left the pressure −λ_n, right the tangential traction λ_t as arrows
    coloured by the status (stick / slip), separated nodes grey."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    X = np.array([[r["x"], r["y"], r["z"]] for r in rows])
    keep = [i for i in range(3) if i != int(np.argmin(np.ptp(X, axis=0)))]
    P = X[:, keep]
    lam_t = np.array([[r[f"lambda_t_{a}"] for a in "xyz"] for r in rows])[:, keep]
    status = np.array([r["status"] for r in rows])
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.5))
    sc = axes[0].scatter(P[:, 0], P[:, 1], c=[-r["lambda_n"] for r in rows], s=12, cmap="viridis")
    fig.colorbar(sc, ax=axes[0], label="pressure −λ_n")
    axes[0].set_title("contact pressure")
    for name, colour in (("stick", "C0"), ("slip", "C3")):
        m = status == name
        axes[1].quiver(P[m, 0], P[m, 1], lam_t[m, 0], lam_t[m, 1], color=colour, label=f"{name} ({m.sum()})",
                       angles="xy", scale_units="xy", scale=np.max(np.abs(lam_t)) / (0.06 * np.ptp(P)) or 1.0)
    m = status == "separated"
    axes[1].plot(P[m, 0], P[m, 1], ".", color="0.6", ms=3, label=f"separated ({m.sum()})")
    axes[1].set_title(f"tangential traction λ_t at t = {t:g}")
    axes[1].legend(loc="upper right", fontsize=8)
    labels = ["xyz"[i] for i in keep]
    for ax in axes:
        ax.set_aspect("equal")
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
