"""The curves a load path's traction picture draws beside the computed tractions: the exact
tractions of a declared exact solution, or the pressure of a declared reference, placed
about the first point of contact (:mod:`contact.output.step_report` draws them)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .contact_table import Table, tangent_2d

if TYPE_CHECKING:
    from .posed import Posed


def first_contact(posed: Posed, result) -> tuple[np.ndarray, np.ndarray | None]:
    """The first point of contact (``Result.first_contact``: the smallest initial gap) and, in
    2D with a contact normal (elasticity), the tangent t_0 of the position's sign convention
    (None for the scalar models, whose tractions have no tangential part)."""
    gdim = posed.mesh.geometry.dim
    return result.first_contact, (
        tangent_2d(result) if gdim == 2 and result.problem.data.n is not None else None
    )


def reference_curves(
    posed: Posed,
    table: Table | None,
    comparison=None,
    origin: np.ndarray | None = None,
    t0: np.ndarray | None = None,
) -> list:
    """Reference curves of the traction plot (rank 0): the exact tractions of a declared
    exact solution (``data.exact``, 2D), or the pressure of a declared reference
    (``reference:``, e.g. Hertz for the computed force) on both sides of the first point of
    contact ``origin`` (2D; in 3D against r)."""
    if table is None or posed.comm.rank != 0:
        return []
    if posed.exact is not None:
        return exact_tractions(posed, table, t0)
    if comparison is None or not (comparison.curves or comparison.traction_curves):
        return []
    curves = [(0, *c) for c in comparison.curves] + [(1, *c) for c in comparison.traction_curves]
    if "s" not in table:
        return curves
    X = np.c_[table["x"], table["y"]]
    assert origin is not None  # a table with arc lengths s has a first point of contact
    s0 = float(table["s"][int(np.argmin(np.linalg.norm(X - origin[:2], axis=1)))])
    return [
        (panel, np.r_[s0 - x[::-1], s0 + x], np.r_[y[::-1], y], label)
        for panel, x, y, label in curves
    ]


def exact_tractions(posed: Posed, table: Table, t0: np.ndarray | None, h: float = 1e-6) -> list:
    """2D: −λ_n = −n·σ(u)n and λ_t = t_0·(σ(u)n − λ_n n) of the exact solution at the contact
    nodes of ``table`` (σ by central differences of ``data.exact`` with step h, n the
    obstacle's normal at the node, t_0 of :func:`contact.post.contact_table.tangent_2d`)."""
    from ..models.physics import lame

    u = posed.exact_values  # one function per component of a displacement
    if posed.mesh.geometry.dim != 2 or len(u) != 2 or "s" not in table or t0 is None:
        return []
    X = np.vstack([table["x"], table["y"], np.zeros(len(table["x"]))])
    grad = np.empty((X.shape[1], 2, 2))
    for j in range(2):
        e = np.zeros((3, 1))
        e[j] = h
        for i in range(2):
            grad[:, i, j] = (u[i](X + e) - u[i](X - e)) / (2 * h)
    assert posed.materials and posed.obstacle is not None  # one body, an obstacle
    mu, lmbda = lame(*posed.materials[""])
    eps = 0.5 * (grad + grad.transpose(0, 2, 1))
    sigma = 2 * mu * eps + lmbda * np.trace(eps, axis1=1, axis2=2)[:, None, None] * np.eye(2)
    obstacle = posed.obstacle
    if obstacle.type == "plane":
        nu_o = np.asarray(obstacle.normal, float)
        n = np.tile(
            -nu_o / np.linalg.norm(nu_o),
            (X.shape[1], 1),
        )
    else:
        d = np.asarray(obstacle.center, float)[:, None] - X[:2]
        n = (d / np.linalg.norm(d, axis=0)).T
    T = np.einsum("nij,nj->ni", sigma, n)
    lam_n = np.einsum("ni,ni->n", T, n)
    lam_t = (T - lam_n[:, None] * n) @ t0
    return [(0, table["s"], -lam_n, "exact solution"), (1, table["s"], lam_t, "exact solution")]
