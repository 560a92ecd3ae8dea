"""Which driver runs a scene — one solve, the adaptive loop or a load path: one rule for
``contact run`` and for every run of a study."""

from __future__ import annotations

from typing import Literal

from ..output.report import Report
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


def report_of(config: SceneConfig) -> Report:
    """What a run of the scene writes (:class:`contact.output.report.Report`), read from its
    configuration: the ``output`` section, the adaptive loop's pictures and strategy, the
    reference's and the friction law's names, and the labels (name, model).

    Args:
        config: the scene's config.

    Returns:
        The record the writers of :mod:`contact.output` take.
    """
    out, adapt, friction = config.output, config.adapt, config.friction
    return Report(
        name=config.name,
        model=config.model.type,
        elastic=config.elastic,
        formats=tuple(out.formats),
        png=out.png,
        levels=out.levels,
        pictures=adapt.pictures if adapt is not None else 3,
        strategy=adapt.strategy if adapt is not None else None,
        reference=config.reference.type if config.reference is not None else None,
        friction=friction.law if friction is not None else "none",
        tangential_form=friction.form if friction is not None else None,
        estimator=config.estimator,
        verbose=out.verbose,
    )
