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

``import contact`` loads only the FEniCS wheel's libraries (MPI, PETSc): each name below
imports its module the first time it is used (PEP 562), so that a command that needs no
solver (``contact --version``, ``contact check``) or a script that needs one stack pays
for no other (DOLFINx, UFL, the estimators, the output and plotting stacks).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .base.version import __version__ as __version__

try:  # the PyPI wheel 'dolfinx-solver-real' must set up its libraries before dolfinx/petsc4py
    import dolfinx_solver  # noqa: F401
except ImportError:  # a conda / Debian DOLFINx needs nothing
    pass

if TYPE_CHECKING:  # the names as mypy and readers see them; at run time: __getattr__
    from .adaptivity.estimate import Estimate
    from .adaptivity.mark import mark
    from .adaptivity.refine import Domain
    from .base.errors import ConfigError
    from .drivers.adaptive import AdaptResult
    from .drivers.load_path import LoadPath
    from .drivers.sequencing import Hierarchy
    from .drivers.solve import sequence
    from .hp.adapt import adapt
    from .models.constraints import (
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
    from .models.forms import ComplementarityProblem
    from .models.physics import BoundaryData, Diffusion, Elasticity
    from .setup.run import estimate, refine, run_load_path, solve
    from .setup.scene import Scene, load_scene
    from .solvers.options import AdaptOptions, SolverOptions
    from .solvers.result import Result

#: the public API, bottom to top of the layers (docs/development.md, "Layout"): name →
#: (module, attribute, checked) — a checked function's first argument is checked here, once:
#: a scene (contact.setup.scene.public), or for the names of :data:`_PROBLEMS` a scene or
#: what the core's function takes (contact.setup.run.either); inside, the drivers hand on
#: what they got
_API: dict[str, tuple[str, str, bool]] = {
    "ConfigError": ("base.errors", "ConfigError", False),
    "SolverOptions": ("solvers.options", "SolverOptions", False),
    "AdaptOptions": ("solvers.options", "AdaptOptions", False),
    "Result": ("solvers.result", "Result", False),
    "ComplementarityProblem": ("models.forms", "ComplementarityProblem", False),
    "Diffusion": ("models.physics", "Diffusion", False),
    "Elasticity": ("models.physics", "Elasticity", False),
    "BoundaryData": ("models.physics", "BoundaryData", False),
    "Unilateral": ("models.constraints", "Unilateral", False),
    "RigidObstacle": ("models.constraints", "RigidObstacle", False),
    "Plane": ("models.constraints", "Plane", False),
    "Ball": ("models.constraints", "Ball", False),
    "Cylinder": ("models.constraints", "Cylinder", False),
    "SignedDistance": ("models.constraints", "SignedDistance", False),
    "MortarPair": ("models.constraints", "MortarPair", False),
    "Tresca": ("models.constraints", "Tresca", False),
    "Coulomb": ("models.constraints", "Coulomb", False),
    "Estimate": ("adaptivity.estimate", "Estimate", False),
    "mark": ("adaptivity.mark", "mark", False),
    "Domain": ("adaptivity.refine", "Domain", False),
    "Hierarchy": ("drivers.sequencing", "Hierarchy", False),
    "sequence": ("drivers.solve", "sequence", False),
    "AdaptResult": ("drivers.adaptive", "AdaptResult", False),
    "LoadPath": ("drivers.load_path", "LoadPath", False),
    "Scene": ("setup.scene", "Scene", False),
    "load_scene": ("setup.scene", "load_scene", False),
    "estimate": ("setup.run", "estimate", True),
    "solve": ("setup.run", "solve", True),
    "refine": ("setup.run", "refine", True),
    "run_load_path": ("setup.run", "run_load_path", True),
    "adapt": ("hp.adapt", "adapt", True),  # the h loop, or the hp loop for strategy hp
}

#: the checked names that take a problem too: the core's function (module, attribute) and
#: which first arguments it takes (a function of contact.setup.run)
_PROBLEMS: dict[str, tuple[str, str, str]] = {
    "solve": ("drivers.solve", "solve", "is_problem"),
    "estimate": ("setup.run", "estimate", "is_problem"),  # one function of both
    "adapt": ("drivers.adaptive", "adapt", "is_builder"),
    "refine": ("adaptivity.refine", "refine", "is_domain"),
    "run_load_path": ("drivers.load_path", "load_path", "is_builder"),
}

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


#: the subpackages, imported on first use as attributes too (``contact.setup.config`` after
#: ``import contact.setup.config``, as before)
_PACKAGES = (
    "adaptivity",
    "app",
    "base",
    "drivers",
    "hp",
    "models",
    "output",
    "post",
    "setup",
    "solvers",
)


def __getattr__(name: str) -> Any:
    """The public name ``name``, its module imported on first use (then kept here)."""
    if name in _PACKAGES:
        return importlib.import_module(f".{name}", __name__)
    if name not in _API:
        raise AttributeError(f"module 'contact' has no attribute {name!r}")
    module, attribute, checked = _API[name]
    value = getattr(importlib.import_module(f".{module}", __name__), attribute)
    if checked and name in _PROBLEMS:
        from .setup import run

        core, function, takes = _PROBLEMS[name]
        for_problem = getattr(importlib.import_module(f".{core}", __name__), function)
        value = run.either(value, for_problem, getattr(run, takes))
    elif checked:
        from .setup.scene import public

        value = public(value)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The module's names and the public API's, imported or not."""
    return sorted({*globals(), *_API})
