"""Reference solutions a scene declares (``reference: {type: hertz, radius: R}``).

Only a declared reference is compared with: its values and relative errors go into
summary.json, study.csv and levels.csv, and its curve into pressure.png.  Each type is one
function ``(scene, result, reference section) -> Comparison`` in :data:`REFERENCES`; a new
type (two-body Hertz, Cattaneo–Mindlin, ...) is one more entry.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .comparison import Comparison

if TYPE_CHECKING:
    from ..setup.scene import Scene
    from ..setup.scene_config import ReferenceConfig
    from ..solvers import Result


def _hertz(scene: Scene, result: Result, ref: ReferenceConfig) -> Comparison:
    from .hertz import compare

    return compare(scene, result, ref)


@dataclass(frozen=True)
class ReferenceType:
    """How to compare with one type of reference: the function, and the names of the
    relative errors it reports (their largest magnitude is the column ``<type>_error``)."""

    compare: Callable[[Scene, Result, ReferenceConfig], Comparison]
    errors: tuple[str, ...]


def _cattaneo_mindlin(scene: Scene, result: Result, ref: ReferenceConfig) -> Comparison:
    from .cattaneo import compare

    return compare(scene, result, ref)


#: reference type -> how to compare with it
REFERENCES: dict[str, ReferenceType] = {
    "hertz": ReferenceType(_hertz, ("a_error", "p0_error")),
    "cattaneo_mindlin": ReferenceType(_cattaneo_mindlin, ("c_error", "q_error")),
}


def compare(scene: Scene, result: Result) -> Comparison | None:
    """The comparison with the scene's declared reference, None without one (collective)."""
    ref = scene.config.reference
    return None if ref is None else REFERENCES[ref.type].compare(scene, result, ref)


def error_columns(ref: ReferenceConfig | None) -> tuple[str, ...]:
    """The columns a study gets for a scene's declared reference ``ref``: each relative
    error and ``<type>_error``, the largest magnitude; empty without a reference."""
    return (*REFERENCES[ref.type].errors, f"{ref.type}_error") if ref is not None else ()


def error_values(ref: ReferenceConfig, comparison: Comparison) -> dict[str, float]:
    """The values of :func:`error_columns` for one comparison."""
    errors = dict(comparison.errors)
    return {**errors, f"{ref.type}_error": max(abs(v) for v in errors.values())}
