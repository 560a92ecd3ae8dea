"""Which driver runs a scene — one solve, the adaptive loop or a load path: one rule for
``contact run`` and for every run of a study."""

from __future__ import annotations

from typing import Literal

from ..setup.scene_config import SceneConfig

Driver = Literal["solve", "adapt", "load_path"]


def choose_driver(config: SceneConfig, adaptive: bool | None = None) -> Driver:
    """The driver of a scene.

    A scene is solved step by step (:func:`contact.drivers.load_path.run_load_path`) when
    it has a ``load`` section, when its contact has friction (the slip of a step is
    measured from the previous one), and when its body is hyperelastic (one step at t = 1
    without a load section: a step that fails is cut, since Newton's method converges for
    finite strain only near enough to the solution, and the stability of the answer — the
    inertia of the tangent, det F — is checked); the path runs the adaptive loop at its
    steps when ``adaptive``.  Otherwise an adaptive run is the adaptive loop
    (:func:`contact.drivers.adaptive.adapt`) and any other one solve
    (:func:`contact.drivers.solve.solve`).

    Args:
        config: the scene's config.
        adaptive: whether the run refines adaptively (default: whether the scene has an
            ``adapt`` section; a study decides it per run).

    Returns:
        ``"load_path"``, ``"adapt"`` or ``"solve"``.
    """
    if adaptive is None:
        adaptive = config.adapt is not None
    if config.load is not None or config.frictional or config.model.type == "hyperelastic":
        return "load_path"
    return "adapt" if adaptive else "solve"
