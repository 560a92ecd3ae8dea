"""A computed solution against a declared reference solution: the record each reference
type's ``compare`` (:mod:`contact.post.hertz`, :mod:`contact.post.cattaneo`) returns and
:mod:`contact.post.reference` dispatches to, and that the output writes (summary.json, study.csv,
pressure.png).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Comparison:
    """A computed solution against a reference.

    ``values``: figures for summary.json (reference values, computed counterparts, relative
    errors); ``errors``: the relative errors a study charts (name -> value);
    ``profile``: (n, 2) computed (position, pressure) at the contact nodes, rank 0 only
    (empty elsewhere); ``curves``: reference curves ``(x, y, label)`` of the pressure;
    ``traction_curves``: the same of the tangential traction (its sign as computed, for the
    traction plot of a frictional load path); ``marks``: vertical lines ``(x, label)``;
    ``xlabel``: the position axis of the plot."""

    values: dict[str, float]
    errors: dict[str, float]
    profile: np.ndarray
    xlabel: str
    curves: list[tuple[np.ndarray, np.ndarray, str]] = field(default_factory=list)
    marks: list[tuple[float, str]] = field(default_factory=list)
    traction_curves: list[tuple[np.ndarray, np.ndarray, str]] = field(default_factory=list)
