"""contact: Signorini and obstacle problems by semismooth Newton on DOLFINx.

scene = contact.load_scene("configs/signorini_square.yaml")
result = contact.solve(scene, method="fb")
levels = contact.adapt(scene, strategy="dorfler", theta=0.5)   # SOLVE-ESTIMATE-MARK-REFINE
path = contact.run_load_path(scene)        # quasi-static steps (load: section), e.g. friction

# your own UFL forms: a residual F(u; v) (or a, L) and a unilateral constraint, no scene
lower = contact.Unilateral(psi, side="lower")
problem = contact.ComplementarityProblem.from_residual(F, u, lower, bcs)
result = problem.solve(method="fb")

``import contact`` loads only the FEniCS wheel's libraries (MPI, PETSc): each name below
imports its module the first time it is used (PEP 562), so that a command that needs no
solver (``contact --version``, ``contact check``) or a script that needs one stack pays
for no other (DOLFINx, UFL, the estimators, the output and plotting stacks).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

try:  # the PyPI wheel 'dolfinx-solver-real' must set up its libraries before dolfinx/petsc4py
    import dolfinx_solver  # noqa: F401
except ImportError:  # a conda / Debian DOLFINx needs nothing
    pass

if TYPE_CHECKING:  # the names as mypy and readers see them; at run time: __getattr__
    from .adaptivity.estimate import Estimate, estimate
    from .adaptivity.mark import mark
    from .adaptivity.refine import refine
    from .base.errors import ConfigError
    from .drivers.adaptive import AdaptResult
    from .drivers.load_path import LoadPath, run_load_path
    from .drivers.solve import solve
    from .hp.adapt import adapt
    from .models.forms import ComplementarityProblem, Unilateral
    from .setup.scene import Scene, load_scene
    from .solvers.result import Result

#: the public API, bottom (setup) to top (drivers) of the layers (docs/development.md,
#: "Layout"): name → (module, attribute, checked) — a checked function's scene argument is
#: checked here, once (contact.setup.scene.public); inside, the drivers hand on Scenes they got
_API: dict[str, tuple[str, str, bool]] = {
    "ConfigError": ("base.errors", "ConfigError", False),
    "Scene": ("setup.scene", "Scene", False),
    "load_scene": ("setup.scene", "load_scene", False),
    "Result": ("solvers.result", "Result", False),
    "solve": ("drivers.solve", "solve", True),
    "Estimate": ("adaptivity.estimate", "Estimate", False),
    "estimate": ("adaptivity.estimate", "estimate", True),
    "AdaptResult": ("drivers.adaptive", "AdaptResult", False),
    "adapt": ("hp.adapt", "adapt", True),  # the h loop, or the hp loop for strategy hp
    "mark": ("adaptivity.mark", "mark", False),
    "refine": ("adaptivity.refine", "refine", True),
    "LoadPath": ("drivers.load_path", "LoadPath", False),
    "run_load_path": ("drivers.load_path", "run_load_path", True),
    "ComplementarityProblem": ("models.forms", "ComplementarityProblem", False),
    "Unilateral": ("models.forms", "Unilateral", False),
}

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


#: the subpackages, imported on first use as attributes too (``contact.setup.config`` after
#: ``import contact.setup.config``, as before)
_PACKAGES = ("adaptivity", "app", "base", "drivers", "models", "output", "post", "setup", "solvers")


def __getattr__(name: str) -> Any:
    """The public name ``name``, its module imported on first use (then kept here)."""
    if name in _PACKAGES:
        return importlib.import_module(f".{name}", __name__)
    if name not in _API:
        raise AttributeError(f"module 'contact' has no attribute {name!r}")
    module, attribute, checked = _API[name]
    value = getattr(importlib.import_module(f".{module}", __name__), attribute)
    if checked:
        from .setup.scene import public

        value = public(value)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The module's names and the public API's, imported or not."""
    return sorted({*globals(), *_API})
