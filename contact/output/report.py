"""What a run writes: a plain record of its output settings and labels.

The writers of :mod:`contact.output` (:mod:`.run_report`, :mod:`.step_report`) take a
solve's result and this record; the application reads it from the scene's configuration
once (``contact.app.dispatch.report_of``), so the writers never read a scene's configuration.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Report:
    """The output settings and labels of one run.

    Attributes:
        name: The scene's name (titles; ``summary.json``'s ``scene``).
        model: The model type (``summary.json``'s ``model``).
        elastic: Whether the unknown is a displacement (the von Mises cell field, the
            ``lambda_n`` column, the resultants).
        formats: The field files' formats (``xdmf``, ``vtk``; none: no field files).
        png: Whether pictures are drawn.
        levels: ``all``: an adaptive run writes every level's fields as the loop goes;
            ``last``: the last level's, once it stops.
        pictures: How many levels of an adaptive run get a mesh picture.
        strategy: The adaptive loop's marking strategy; None without an ``adapt`` section.
        reference: The type of the declared reference solution; None without one.
        friction: The friction law; ``none`` without friction.
        tangential_form: The friction law's tangential form; None without friction.
        estimator: The error estimator's kind (``residual``, ``equilibrated``, …) of a
            step that did not run the adaptive loop.
        verbose: Whether the run prints its progress as it goes.
    """

    name: str
    model: str
    elastic: bool
    formats: tuple[str, ...] = ("xdmf",)
    png: bool = True
    levels: str = "all"
    pictures: int = 3
    strategy: str | None = None
    reference: str | None = None
    friction: str = "none"
    tangential_form: str | None = None
    estimator: str = "residual"
    verbose: bool = True
