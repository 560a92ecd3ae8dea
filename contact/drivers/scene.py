"""ESTIMATE and REFINE for a scene: :func:`contact.adaptivity.estimate.estimate` of a scene's
solve with the scene's ``estimator``, and :func:`contact.adaptivity.refine.refine` of the
scene's mesh as a :class:`~contact.adaptivity.refine.Domain`."""

from __future__ import annotations

from typing import Any

import numpy as np
from dolfinx import fem

from ..adaptivity.estimate import Estimate
from ..adaptivity.estimate import estimate as estimate_problem
from ..adaptivity.refine import Domain
from ..adaptivity.refine import refine as refine_domain
from ..setup.geometry import builder_surfaces
from ..setup.meshes import Boundary
from ..setup.scene import Scene
from ..setup.surfaces import boundary_surfaces, warn_undeclared_curves
from ..solvers import Result


def estimate(subject: Any, result: Result, kind: str | None = None) -> Estimate:
    """η_T and η of a solve (collective).

    Args:
        subject: the :class:`~contact.setup.scene.Scene` that was solved (its ``estimator``
            is the default kind), or a problem with its physics declared
            (:func:`contact.adaptivity.estimate.estimate`; the default kind ``residual``).
        result: the solve's :class:`~contact.solvers.result.Result`.
        kind: ``residual``, ``equilibrated`` or ``equilibrated_rt0``.

    Returns:
        The :class:`~contact.adaptivity.estimate.Estimate`.  A result of another scene or
        problem is a ValueError."""
    if not isinstance(subject, Scene):
        if subject is None or isinstance(subject, (str, bytes)) or not hasattr(subject, "V"):
            if getattr(subject, "problem", None) is None:
                raise ValueError(
                    "scene: expected a contact.Scene (from contact.load_scene) or a problem, "
                    f"got {type(subject).__name__}"
                )
        return estimate_problem(subject, result, kind or "residual")
    if not isinstance(result, Result) or result.u_h.function_space.mesh is not subject.mesh:
        raise ValueError(
            "result: expected the contact.Result of contact.solve on this scene (same mesh)"
        )
    return estimate_problem(result.problem, result, kind or subject.config.estimator)


def scene_domain(scene: Scene) -> Domain:
    """The scene's mesh as a :class:`~contact.adaptivity.refine.Domain`: its boundary tags,
    body tags, the mesh builder's surface tags (``surfaces``), the history functions, and
    the snapping of curved boundary parts (the declared ``surface`` of a part, the curved
    surfaces of the built-in Hertz meshes)."""
    cfg, bnd = scene.config, scene.boundary
    ids, roles = dict(bnd.ids), dict(bnd.roles)

    def snap(parent: Domain, child: Domain) -> None:
        assert parent.facets is not None and child.facets is not None  # a scene's boundary
        boundary = Boundary(parent.facets, ids, roles)
        warn_undeclared_curves(cfg, parent.mesh, boundary)
        for surface in boundary_surfaces(cfg, parent.mesh.geometry.dim, boundary):
            surface.snap(child.mesh, child.facets)
        # by the mesh's own tags of its curved surfaces
        for surface in builder_surfaces(cfg.mesh):
            surface.snap(child.mesh, child.tags["surfaces"])

    return Domain(
        scene.mesh,
        bnd.tags,
        scene.bodies,
        {} if scene.surfaces is None else {"surfaces": scene.surfaces},
        dict(scene.history),
        snap,
    )


def on_domain(scene: Scene, domain: Domain, parent: Scene | None = None) -> Scene:
    """The scene on another domain of its mesh's (a refinement of it): the same configuration,
    boundary parts and pseudo-time, the domain's tags and functions; ``parent`` the scene of
    the domain's parent (the coarser levels of grid sequencing)."""
    bnd = scene.boundary
    assert domain.facets is not None  # a scene's domain has its boundary tags
    return Scene(
        scene.config,
        domain.mesh,
        Boundary(domain.facets, dict(bnd.ids), dict(bnd.roles)),
        time=scene.time,
        history=dict(domain.functions),
        previous_time=scene.previous_time,
        bodies=domain.cells,
        surfaces=domain.tags.get("surfaces"),
        parent=None if parent is None or domain.parent is None else (parent, domain.parent[1]),
    )


def refine(
    scene: Scene,
    cells: np.ndarray,
    u_h: fem.Function | None = None,
    rebalance: bool | None = None,
    *,
    timings: dict[str, float] | None = None,
) -> tuple[Scene, fem.Function | None]:
    """Refine the marked cells of the scene's mesh (:func:`contact.adaptivity.refine.refine`
    on :func:`scene_domain`): the boundary and body tags carried over, ``u_h`` interpolated
    onto the new mesh (nested iteration), the history functions prolonged, curved boundary
    parts snapped to their surfaces (a gmsh contact part that looks curved and declares no
    surface gets a one-line warning).  ``rebalance``: default the scene's
    ``adapt.rebalance`` (true).  Returns (the refined scene, u_h on it or None); a ``u_h``
    on another mesh, or cells that are not owned indices, is a ValueError."""
    if u_h is not None and (
        not isinstance(u_h, fem.Function) or u_h.function_space.mesh is not scene.mesh
    ):
        raise ValueError(
            "u_h: expected a dolfinx.fem.Function on the scene's mesh (e.g. result.u_h of "
            "contact.solve on this scene)"
        )
    if rebalance is None:
        adapt = scene.config.adapt
        rebalance = adapt.rebalance if adapt is not None else True
    child, u0 = refine_domain(scene_domain(scene), cells, u_h, rebalance, timings=timings)
    return on_domain(scene, child, parent=scene), u0
