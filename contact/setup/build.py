"""A scene's problem: its model (``model.type``; several bodies with ``bodies``) built within
the DoF budget — :mod:`.scalar` (Signorini and obstacle problems), :mod:`.elastic` (one
elastic body against a rigid obstacle, several bodies through mortar pairs, friction) or
:mod:`.hyperelastic` (finite strain).  A scene imports only its own model: a scalar scene
never loads the elasticity modules, a linear one never the hyperelastic module."""

from __future__ import annotations

import numpy as np

from ..models.discrete import Problem
from .scene import Scene


def build_problem(scene: Scene, coupled_at: np.ndarray | None = None) -> Problem:
    """The problem of the scene's model (within the DoF budget, else ConfigError): its
    discrete problem with the physics and contact conditions the estimators read;
    ``coupled_at``: the nodal displacements on whose current configuration a hyperelastic
    scene's mortar pairs are coupled (None: the reference configuration)."""
    from .budget import check_dofs, mesh_dofs

    cfg, msh = scene.config, scene.mesh
    components = msh.geometry.dim if cfg.elastic else 1
    check_dofs(
        cfg.solver,
        mesh_dofs(msh, cfg.mesh.degree, components),
        msh.geometry.dim,
        "mesh",
        "the mesh gives",
    )
    if cfg.model.type == "hyperelastic":
        from .hyperelastic import hyperelastic_problem

        return hyperelastic_problem(scene, coupled_at)
    if cfg.model.type == "elasticity":
        from .elastic import bodies_problem, elasticity_problem

        return bodies_problem(scene) if cfg.bodies else elasticity_problem(scene)
    from .scalar import scalar_problem

    return scalar_problem(scene)
