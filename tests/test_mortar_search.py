"""The mortar facet-pair search (contact/models/mortar.py ``candidate_pairs``) and the bucket
search under it (contact/base/buckets.py) find exactly the pairs a brute-force test over
every (slave, master) pair finds: graded master facets (radii over a factor 8), curved
slave normals, 2D and 3D, a search distance from the facet size to the whole diameter."""

import contact  # noqa: F401  (dolfinx_solver before dolfinx)
from contact.base.buckets import box_point_pairs
from contact.models.mortar import Facets, candidate_pairs

import numpy as np
import pytest


def _brute_force(slave: Facets, master: Facets, search: float) -> set:
    cs, cm = slave.X.mean(axis=1), master.X.mean(axis=1)
    rs = np.linalg.norm(slave.X - cs[:, None], axis=2).max(axis=1)
    rm = np.linalg.norm(master.X - cm[:, None], axis=2).max(axis=1)
    d = cm[None, :, :] - cs[:, None, :]
    along = np.einsum("smd,sd->sm", d, slave.normals)
    perp = np.linalg.norm(d - along[:, :, None] * slave.normals[:, None, :], axis=2)
    ok = (perp <= rs[:, None] + rm[None, :]) & (np.abs(along) <= search + rm[None, :])
    return set(zip(*map(list, np.nonzero(ok))))


def _surfaces(dim: int, rng) -> tuple[Facets, Facets]:
    """A curved slave surface (an arc / a cap of radius 1 above the plane) and a flat master
    surface below it whose facet sizes grade from 0.01 to 0.08 away from the middle."""
    nv = dim
    n_s, n_m = 300, 400
    # slave: facets around points of a cap, normals pointing down-and-out
    c = rng.uniform(-0.4, 0.4, size=(n_s, dim - 1))
    top = np.c_[c, 1.0 - np.sqrt(1.0 - np.sum(c**2, axis=1))[:, None] + 0.002]
    normal = -np.c_[c, np.sqrt(1.0 - np.sum(c**2, axis=1))[:, None]]
    offsets = rng.normal(scale=0.01, size=(n_s, nv, dim))
    offsets -= np.einsum("svd,sd->sv", offsets, normal)[:, :, None] * normal[:, None, :]
    Xs = top[:, None, :] + offsets
    # master: facets on the plane, graded sizes
    m = rng.uniform(-0.6, 0.6, size=(n_m, dim - 1))
    size = 0.01 + 0.07 * np.abs(m).max(axis=1) / 0.6
    Xm = np.concatenate(
        [
            m[:, None, :] + size[:, None, None] * rng.uniform(-1, 1, (n_m, nv, dim - 1)),
            np.zeros((n_m, nv, 1)),
        ],
        axis=2,
    )
    up = np.tile(np.eye(dim)[-1], (n_m, 1))
    zeros = np.zeros((0, nv), np.int32)
    return (
        Facets(Xs, zeros, zeros, normal),
        Facets(Xm, zeros, zeros, up),
    )


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("search", [0.02, 0.3, 3.0])
def test_mortar_candidates_equal_brute_force(dim, search):
    slave, master = _surfaces(dim, np.random.default_rng(dim))
    s, m = candidate_pairs(slave, master, search)
    found = list(zip(s.tolist(), m.tolist()))
    assert len(found) == len(set(found))  # no pair twice
    assert found == sorted(found)  # sorted by slave, then master
    expected = _brute_force(slave, master, search)
    assert len(expected) >= 100  # a real search: many pairs to find
    assert set(found) == expected


def test_box_point_pairs_hold_every_contained_point():
    rng = np.random.default_rng(5)
    lo = rng.uniform(0, 1, (200, 3))
    hi = lo + rng.uniform(0.001, 0.1, (200, 3))
    points = rng.uniform(-0.1, 1.2, (3000, 3))
    p, b = box_point_pairs(lo, hi, points)
    inside = np.all((points[:, None] >= lo[None]) & (points[:, None] <= hi[None]), axis=2)
    contained = set(zip(*map(list, np.nonzero(inside))))
    assert contained and contained <= set(zip(p.tolist(), b.tolist()))
    assert np.all(np.diff(p) >= 0)
