"""A scene's data as the core takes them: its expressions (``data``, ``solver.u0``, …) as UFL
coefficients (a ``fem.Constant`` when constant, so that forms compile once for every
pseudo-time t) or interpolated into a space."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from ..base import expressions, spaces
from ..base.errors import ConfigError
from .checks import check_data, data_items
from .scene import Scene

#: :func:`interpolate_expression` evaluates at the space's DoF points tabulated once per
#: space (``contact.base.spaces.dof_coordinates``, shared with the refinement's
#: prolongation and the other data); False: tabulated at each call, the old path
SHARED_POINTS = True


def coefficient(text: str, scene: Scene) -> Any:
    """UFL data: a ``fem.Constant`` when the expression is constant (in space and in the
    pseudo-time t), else a UFL expression (t enters as ``scene.t_constant``)."""
    consts = scene.config.constants
    if expressions.is_constant(text, consts):
        value = float(expressions.to_numpy(text, consts)(np.zeros((3, 1)))[0])
        return fem.Constant(scene.mesh, PETSc.ScalarType(value))  # type: ignore[operator]
    return expressions.to_ufl(text, scene.mesh, consts, t=scene.t_constant)


def interpolate_expression(
    V: fem.FunctionSpace,
    text: str | Sequence[str],
    scene: Scene,
    key: str | None = None,
    nodes: np.ndarray | None = None,
) -> fem.Function:
    """``text`` interpolated into the Lagrange space V at the scene's pseudo-time; for a
    vector space one expression is every component, a tuple gives one per component.
    Lagrange interpolation is evaluation at the DoF points, so each expression is evaluated
    once per DoF point (not once per cell and point, as ``Function.interpolate`` does), and
    a constant is just assigned.  With a scene ``key`` (``solver.u0``) the expressions are
    first checked finite at the mesh vertices (:func:`contact.setup.checks.check_data`:
    a ConfigError naming the key).  With ``nodes`` (local node indices of V, ghosts
    included) only these nodes are given their values, the others are zero (a Dirichlet
    condition reads its nodes only)."""
    if key is not None:
        check_data(scene, data_items(key, text if isinstance(text, str) else tuple(text)))
    fn = fem.Function(V)
    consts = scene.config.constants
    bs = V.dofmap.index_map_bs
    texts = [text] * bs if isinstance(text, str) else list(text)
    if len(texts) != bs:
        raise ConfigError(
            f"solver.u0: expected {bs} expressions (one per component), got {len(texts)}"
        )
    values = fn.x.array.reshape(-1, bs)
    rows = slice(None) if nodes is None else np.asarray(nodes)
    points = None
    for c, t in enumerate(texts):
        f = expressions.to_numpy(t, consts, t=scene.time)
        if expressions.is_constant(t, consts):
            values[rows, c] = f(np.zeros((3, 1)))[0]
        else:
            if points is None:
                X = spaces.dof_coordinates(V) if SHARED_POINTS else V.tabulate_dof_coordinates()
                points = X[rows].T
            values[rows, c] = f(points)
    return fn


def vector(texts: list[str], scene: Scene):
    """Vector data: a ``fem.Constant`` when every component is constant (so a zero load
    still gives a non-empty form), else a UFL vector of the expressions."""
    consts = scene.config.constants
    if all(expressions.is_constant(t, consts) for t in texts):
        values = [float(expressions.to_numpy(t, consts)(np.zeros((3, 1)))[0]) for t in texts]
        return fem.Constant(scene.mesh, np.array(values, dtype=PETSc.ScalarType))
    return ufl.as_vector(
        [expressions.to_ufl(t, scene.mesh, consts, t=scene.t_constant) for t in texts]
    )


def vector_numpy(texts: list[str], scene: Scene):
    """The components as one NumPy function of points x, shape (3, n) to (k, n)."""
    fns = [expressions.to_numpy(t, scene.config.constants, t=scene.time) for t in texts]
    return lambda x: np.vstack([f(x) for f in fns])
