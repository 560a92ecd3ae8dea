"""contact: Signorini and obstacle problems by semismooth Newton on DOLFINx.

scene = contact.load_scene("configs/signorini_square.yaml")
result = contact.solve(scene, method="fb")
levels = contact.adapt(scene, strategy="dorfler", theta=0.5)   # SOLVE-ESTIMATE-MARK-REFINE
path = contact.run_load_path(scene)        # quasi-static steps (load: section), e.g. friction
"""

try:  # the PyPI wheel 'dolfinx-solver-real' must set up its libraries before dolfinx/petsc4py
    import dolfinx_solver  # noqa: F401
except ImportError:  # a conda / Debian DOLFINx needs nothing
    pass

# the public API, bottom (setup) to top (drivers) of the layers (README, "Layout")
from .adaptivity.estimate import Estimate, estimate  # noqa: E402
from .adaptivity.mark import mark  # noqa: E402
from .adaptivity.refine import refine  # noqa: E402
from .base.errors import ConfigError  # noqa: E402
from .drivers.adaptive import AdaptResult, adapt  # noqa: E402
from .drivers.load_path import LoadPath, run_load_path  # noqa: E402
from .drivers.solve import solve  # noqa: E402
from .setup.scene import Scene, load_scene  # noqa: E402
from .solvers.result import Result  # noqa: E402

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
]
__version__ = "0.1.0"
