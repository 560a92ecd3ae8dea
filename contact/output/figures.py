"""matplotlib figures of their own for the pictures (:mod:`.plots`) and charts (:mod:`.charts`).

A picture is drawn on a :class:`matplotlib.figure.Figure` with an Agg canvas and written
with ``savefig``: nothing goes through :mod:`matplotlib.pyplot`, so drawing neither imports
pyplot and its backend machinery nor touches the process's state (pyplot's registry of open
figures, and the backend a user chose, e.g. in a notebook, which ``matplotlib.use("Agg")``
would replace).  The pixels are those pyplot draws: the figure takes the same rcParams.
"""

from __future__ import annotations

from typing import Any

#: draw through matplotlib.pyplot (the old path, kept to measure the difference): switches
#: the process's backend to Agg and registers every figure with pyplot until it is closed
PYPLOT = False

#: the zlib level of the PNG files (0-9): 1 encodes fastest; matplotlib's own default, 6
#: (the old path), makes files about a third smaller.  The pixels are the same.
PNG_LEVEL = 1

#: the switches above, which the picture process takes from the command
#: (:mod:`.picture_process`)
SWITCHES = ("PYPLOT", "PNG_LEVEL")


def new_figure(*grid: int, figsize: tuple[float, float], **kw: Any) -> tuple[Any, Any]:
    """A figure and its axes, as ``matplotlib.pyplot.subplots(*grid, figsize=figsize, **kw)``.

    Args:
        grid: rows and columns of axes (none: one axes).
        figsize: width and height in inches.
        kw: the keywords of :meth:`matplotlib.figure.Figure.subplots` (``sharex``,
            ``squeeze``, ...).

    Returns:
        (figure, axes): the axes as ``subplots`` returns them (one, or an array)."""
    if PYPLOT:
        return _pyplot().subplots(*grid, figsize=figsize, **kw)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(*grid, **kw)


def save_figure(fig: Any, path: Any, dpi: float) -> None:
    """Write ``fig`` to the file ``path`` at ``dpi`` (a PNG compressed at :data:`PNG_LEVEL`)
    and let go of it (:func:`release_figure`)."""
    png = str(path).lower().endswith(".png")
    fig.savefig(path, dpi=dpi, **({"pil_kwargs": {"compress_level": PNG_LEVEL}} if png else {}))
    release_figure(fig)


def release_figure(fig: Any) -> None:
    """Let go of a figure of :func:`new_figure` once it is saved (pyplot's registry holds
    it on the old path; a figure of its own is freed with its last reference)."""
    if PYPLOT:
        _pyplot().close(fig)


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
