"""Reference solutions a scene declares (``reference: {type: hertz, radius: R}``).

Only a declared reference is compared with: its values and relative errors go into
summary.json, study.csv and levels.csv, and its curve into pressure.png.  Each type is one
function ``(posed, result, reference section) -> Comparison`` in :data:`REFERENCES`; a new
type (two-body Hertz, Cattaneo–Mindlin, ...) is one more entry.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .comparison import Comparison

if TYPE_CHECKING:
    from ..solvers import Result
    from .posed import Posed


def _hertz(posed: Posed, result: Result, ref: Any) -> Comparison:
    from .hertz import compare

    return compare(posed, result, ref)


@dataclass(frozen=True)
class ReferenceType:
    """How to compare with one type of reference: the function, and the names of the
    relative errors it reports (their largest magnitude is the column ``<type>_error``)."""

    compare: Callable[[Posed, Result, Any], Comparison]
    errors: tuple[str, ...]


def _cattaneo_mindlin(posed: Posed, result: Result, ref: Any) -> Comparison:
    from .cattaneo import compare

    return compare(posed, result, ref)


#: reference type -> how to compare with it
REFERENCES: dict[str, ReferenceType] = {
    "hertz": ReferenceType(_hertz, ("a_error", "p0_error")),
    "cattaneo_mindlin": ReferenceType(_cattaneo_mindlin, ("c_error", "q_error")),
}


def compare(posed: Posed, result: Result) -> Comparison | None:
    """The comparison with the declared reference (``posed.reference``: its ``type`` and
    data), None without one (collective)."""
    ref = posed.reference
    return None if ref is None else REFERENCES[ref.type].compare(posed, result, ref)


def error_columns(ref: Any) -> tuple[str, ...]:
    """The columns a study gets for a scene's declared reference ``ref``: each relative
    error and ``<type>_error``, the largest magnitude; empty without a reference."""
    return (*REFERENCES[ref.type].errors, f"{ref.type}_error") if ref is not None else ()


def error_values(ref: Any, comparison: Comparison) -> dict[str, float]:
    """The values of :func:`error_columns` for one comparison."""
    errors = dict(comparison.errors)
    return {**errors, f"{ref.type}_error": max(abs(v) for v in errors.values())}
