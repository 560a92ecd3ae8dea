"""contact: Signorini and obstacle problems by semismooth Newton on DOLFINx.

scene = contact.load_scene("configs/signorini_square.yaml")
result = contact.solve(scene, method="fb")
levels = contact.adapt(scene, strategy="dorfler", theta=0.5)   # SOLVE-ESTIMATE-MARK-REFINE
path = contact.run_load_path(scene)        # quasi-static steps (load: section), e.g. friction

# your own UFL forms: a residual F(u; v) (or a, L) and a unilateral constraint, no scene
lower = contact.Unilateral(psi, side="lower")
problem = contact.ComplementarityProblem.from_residual(F, u, lower, bcs)
result = problem.solve(method="fb")
"""

try:  # the PyPI wheel 'dolfinx-solver-real' must set up its libraries before dolfinx/petsc4py
    import dolfinx_solver  # noqa: F401
except ImportError:  # a conda / Debian DOLFINx needs nothing
    pass

# the public API, bottom (setup) to top (drivers) of the layers (docs/development.md, "Layout")
from .adaptivity import estimate as _estimate  # noqa: E402
from .adaptivity import refine as _refine  # noqa: E402
from .adaptivity.estimate import Estimate  # noqa: E402
from .adaptivity.mark import mark  # noqa: E402
from .base.errors import ConfigError  # noqa: E402
from .drivers import adaptive as _adaptive  # noqa: E402
from .drivers import load_path as _load_path  # noqa: E402
from .drivers import solve as _solve  # noqa: E402
from .drivers.adaptive import AdaptResult  # noqa: E402
from .drivers.load_path import LoadPath  # noqa: E402
from .models.forms import ComplementarityProblem, Unilateral  # noqa: E402
from .setup.scene import Scene, load_scene, public  # noqa: E402
from .solvers.result import Result  # noqa: E402

# a user's scene argument is checked here, once; inside, the drivers hand on Scenes they got
solve = public(_solve.solve)
estimate = public(_estimate.estimate)
adapt = public(_adaptive.adapt)
refine = public(_refine.refine)
run_load_path = public(_load_path.run_load_path)

__all__ = [
    "ConfigError",
    "Scene",
    "load_scene",
    "Result",
    "solve",
    "Estimate",
    "estimate",
    "AdaptResult",
    "adapt",
    "mark",
    "refine",
    "LoadPath",
    "run_load_path",
    "ComplementarityProblem",
    "Unilateral",
]
__version__ = "0.1.0"
