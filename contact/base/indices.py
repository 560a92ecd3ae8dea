"""Set operations on integer index arrays (DoFs, vertices, facets) by sorting.

NumPy ≥ 2.3 finds the distinct values of an integer array with a hash table
(``np.unique``, and with it ``np.setdiff1d``): on arrays of mostly distinct values, such as
the DoFs of a mesh, that is many times slower than sorting them (figures in the changelog),
and an obstacle problem's assembly asks for the distinct constrained DoFs of the whole mesh.
These functions give the same arrays (same values, same order, same dtype) by a sort and a
comparison of neighbours.
"""

from __future__ import annotations

import numpy as np

#: sort-based ``unique`` and ``setdiff``; False: ``np.unique`` and ``np.setdiff1d``
#: (the old path, kept to measure the difference)
SORTED = True


def unique(a: np.ndarray) -> np.ndarray:
    """The sorted distinct values of the integer array ``a`` (flattened), as ``np.unique(a)``.

    Args:
        a: integer values.

    Returns:
        Its distinct values in increasing order, ``a``'s dtype.
    """
    a = np.asarray(a)
    if not SORTED:
        return np.unique(a)
    s = np.sort(a, axis=None)
    keep = np.empty(s.shape, dtype=bool)
    keep[:1] = True
    np.not_equal(s[1:], s[:-1], out=keep[1:])
    return s[keep]


def setdiff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The sorted distinct values of ``a`` that are not in ``b``, as ``np.setdiff1d(a, b)``.

    Args:
        a: integer values.
        b: integer values to leave out.

    Returns:
        The distinct values of ``a`` not in ``b``, in increasing order, ``a``'s dtype.
    """
    if not SORTED:
        return np.setdiff1d(a, b)
    values = unique(a)
    return values[np.isin(values, np.asarray(b), invert=True)]
