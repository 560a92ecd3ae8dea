"""Models: a scene's mesh and data → the discrete contact problem (K, b, constraint set).

* :mod:`.problem` — what every model shares (assembly, lumped weights, the scene's
  expressions) to build the solvers' :class:`~contact.solvers.problem.DiscreteProblem`;
* :mod:`.scalar` — scalar Signorini and obstacle problems (docs/theory.md §1.1–1.2);
* :mod:`.elasticity` — linear elasticity (docs/theory.md §1.3), with its rigid
  :mod:`.obstacles` (plane, circle, sphere; the rotation u = Q x);
* :mod:`.bodies` — several elastic bodies in contact through :mod:`.mortar` pairs (SPEC §1.5);
* :mod:`.hyperelastic` — hyperelastic bodies (finite strain, neo-Hookean / St Venant–
  Kirchhoff) against rigid planes: a residual re-assembled at each Newton iterate;
* :mod:`.friction` — Tresca / Coulomb friction on the contact nodes (SPEC §1.4): tangential
  unknowns, thresholds, c_t (only a frictional scene imports it);
* :mod:`.forms` — bring your own forms: the problem of the user's UFL forms and a
  unilateral constraint, with no scene (``contact.ComplementarityProblem``).

A scene imports only its own model: a scalar scene never loads the elasticity modules, a
linear one never the hyperelastic module.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from ..solvers.problem import DiscreteProblem
from .constraints import Unilateral
from .discrete import Problem

if TYPE_CHECKING:
    from ..setup.scene import Scene

__all__ = ["build_problem"]


def build_problem(scene: Scene) -> DiscreteProblem:
    """The discrete problem of the scene's model (within the DoF budget, else ConfigError);
    an elasticity scene with ``bodies`` is the multi-body model of :mod:`.bodies`."""
    from ..setup.budget import check_dofs, mesh_dofs

    cfg, msh = scene.config, scene.mesh
    components = msh.geometry.dim if cfg.elastic else 1
    check_dofs(
        cfg.solver,
        mesh_dofs(msh, cfg.mesh.degree, components),
        msh.geometry.dim,
        "mesh",
        "the mesh gives",
    )
    if cfg.model.type in ("elasticity", "hyperelastic"):
        problem: DiscreteProblem
        if cfg.model.type == "hyperelastic":
            from .hyperelastic import hyperelastic_problem

            problem = hyperelastic_problem(scene, cfg.frictional)
        elif cfg.bodies:
            from .bodies import bodies_problem

            problem = bodies_problem(scene)
        else:
            from .elasticity import elasticity_problem

            problem = elasticity_problem(scene)
        if cfg.frictional:
            from .friction import friction_law, friction_set

            problem.friction = friction_set(scene, problem)
            assert isinstance(problem, Problem)  # every model's
            law = friction_law(scene, problem)
            problem.contacts = tuple(
                c if isinstance(c, Unilateral) else replace(c, friction=law)
                for c in problem.contacts
            )
            problem.u_prev = scene.history.get("u_prev")
        return problem
    from .scalar import scalar_problem

    return scalar_problem(scene)
