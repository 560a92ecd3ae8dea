"""Boxes against points through a uniform grid of buckets, vectorised (no Python loop over
boxes or points): the candidate search of grid sequencing's point location
(:func:`contact.drivers.sequencing.point_transfer`) and of the mortar facet pairs
(:func:`contact.models.mortar.couple`)."""

from __future__ import annotations

import numpy as np


def box_point_pairs(
    lo: np.ndarray, hi: np.ndarray, points: np.ndarray, grow: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """(point, box) index pairs: every point with each box [lo_k, hi_k] (k, dim) that,
    grown by ``grow`` buckets, overlaps the point's bucket — a superset of the pairs where
    the box holds the point, for the caller's exact test.  The buckets have half the boxes'
    mean extent (at least the size that gives ~4 buckets a box over their common bounding
    box), so a box spans a few buckets when the boxes have similar sizes (sort boxes of
    very different sizes into classes first); points outside the boxes' common bounding
    box (grown) meet no box.  Pairs come sorted by point, then by box."""
    dim = lo.shape[1]
    if not len(lo) or not len(points):
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    size = max(0.5 * float(np.mean(hi - lo)), 1e-300)
    box_lo, box_hi = lo.min(axis=0) - grow * size, hi.max(axis=0) + grow * size
    size = max(size, float(np.prod(box_hi - box_lo) / (4 * len(lo))) ** (1 / dim))
    shape = np.maximum(np.ceil((box_hi - box_lo) / size).astype(np.int64), 1)
    # every box into the buckets its grown box overlaps
    first = np.clip(np.floor((lo - box_lo) / size - grow).astype(np.int64), 0, shape - 1)
    last = np.clip(np.floor((hi - box_lo) / size + grow).astype(np.int64), 0, shape - 1)
    span = last - first + 1
    count = np.prod(span, axis=1)
    box_of = np.repeat(np.arange(len(lo)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    offset = np.empty((len(box_of), dim), dtype=np.int64)
    for axis in range(dim - 1, -1, -1):
        k, offset[:, axis] = np.divmod(k, span[box_of, axis])
    bucket = np.ravel_multi_index(tuple((first[box_of] + offset).T), shape)
    order = np.argsort(bucket, kind="stable")
    bucket, box_of = bucket[order], box_of[order]
    start = np.searchsorted(bucket, np.arange(np.prod(shape) + 1))
    # the points inside the common box, with the boxes of their bucket
    inside = np.flatnonzero(np.all((points >= box_lo) & (points <= box_hi), axis=1))
    at = np.clip(np.floor((points[inside] - box_lo) / size).astype(np.int64), 0, shape - 1)
    pb = np.ravel_multi_index(tuple(at.T), shape)
    n_cand = start[pb + 1] - start[pb]
    point_of = np.repeat(inside, n_cand)
    j = np.arange(n_cand.sum()) - np.repeat(np.cumsum(n_cand) - n_cand, n_cand)
    return point_of, box_of[np.repeat(start[pb], n_cand) + j]
