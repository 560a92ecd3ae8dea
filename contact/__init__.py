"""contact: Signorini and obstacle problems by semismooth Newton on DOLFINx.

scene = contact.load_scene("configs/signorini_square.yaml")
result = contact.solve(scene, method="fb")
levels = contact.adapt(scene, strategy="dorfler", theta=0.5)   # SOLVE-ESTIMATE-MARK-REFINE
path = contact.run_load_path(scene)        # quasi-static steps (load: section), e.g. friction

# your own UFL forms: a residual F(u; v) (or a, L), a contact condition and the equations
# the estimators check, no scene
lower = contact.Unilateral(psi, side="lower")
physics = contact.Diffusion(k, f, contact.BoundaryData(facet_tags, dirichlet=(1,)))
problem = contact.ComplementarityProblem.from_residual(F, u, lower, bcs, physics=physics)
result = contact.solve(problem, method="fb")
est = contact.estimate(problem, result, kind="equilibrated")
levels = contact.adapt(build, mesh, theta=0.5)            # build(mesh) -> problem
"""

try:  # the PyPI wheel 'dolfinx-solver-real' must set up its libraries before dolfinx/petsc4py
    import dolfinx_solver  # noqa: F401
except ImportError:  # a conda / Debian DOLFINx needs nothing
    pass

# the public API, bottom to top of the layers (docs/development.md, "Layout")
from .adaptivity import refine as _refine  # noqa: E402
from .adaptivity.estimate import Estimate  # noqa: E402
from .adaptivity.mark import mark  # noqa: E402
from .adaptivity.refine import Domain  # noqa: E402
from .base.errors import ConfigError  # noqa: E402
from .drivers import adaptive as _adaptive  # noqa: E402
from .drivers import load_path as _load_path  # noqa: E402
from .drivers import solve as _solve  # noqa: E402
from .drivers.adaptive import AdaptResult  # noqa: E402
from .drivers.load_path import LoadPath  # noqa: E402
from .drivers.sequencing import Hierarchy  # noqa: E402
from .drivers.solve import sequence  # noqa: E402
from .models.constraints import (  # noqa: E402
    Ball,
    Coulomb,
    Cylinder,
    MortarPair,
    Plane,
    RigidObstacle,
    SignedDistance,
    Tresca,
    Unilateral,
)
from .models.forms import ComplementarityProblem  # noqa: E402
from .models.physics import BoundaryData, Diffusion, Elasticity  # noqa: E402
from .setup import run as _scene  # noqa: E402
from .setup.run import estimate, is_problem  # noqa: E402
from .setup.scene import Scene, load_scene  # noqa: E402
from .solvers.options import AdaptOptions, SolverOptions  # noqa: E402
from .solvers.result import Result  # noqa: E402

# a scene or a problem: a user's first argument is checked here, once; inside, the drivers
# hand on what they got
solve = _scene.either(_scene.solve, _solve.solve, is_problem)
adapt = _scene.either(_scene.adapt, _adaptive.adapt, callable)
refine = _scene.either(_scene.refine, _refine.refine, lambda d: isinstance(d, Domain))
run_load_path = _scene.either(_scene.run_load_path, _load_path.load_path, callable)

__all__ = [
    "ConfigError",
    "Scene",
    "load_scene",
    "Result",
    "SolverOptions",
    "AdaptOptions",
    "solve",
    "sequence",
    "Hierarchy",
    "Estimate",
    "estimate",
    "AdaptResult",
    "adapt",
    "mark",
    "Domain",
    "refine",
    "LoadPath",
    "run_load_path",
    "ComplementarityProblem",
    "Diffusion",
    "Elasticity",
    "BoundaryData",
    "Unilateral",
    "RigidObstacle",
    "Plane",
    "Ball",
    "Cylinder",
    "SignedDistance",
    "MortarPair",
    "Tresca",
    "Coulomb",
]
__version__ = "0.1.0"
