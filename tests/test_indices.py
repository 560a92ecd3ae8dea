"""contact.base.indices: the sort-based set operations give NumPy's arrays (values, order and
dtype) — the DoF sets of an obstacle problem's assembly — and the switch selects NumPy's."""

from contact.base import indices

import numpy as np
import pytest


def _cases():
    rng = np.random.default_rng(7)
    dofs = rng.permutation(50_000).astype(np.int32)  # distinct, as a mesh's DoFs
    repeated = rng.integers(-40, 40, size=2_000)  # int64, negatives, many repeats
    return [
        (dofs, dofs[::7].copy()),
        (np.concatenate([dofs, dofs[:1000]]), np.zeros(0, np.int32)),
        (repeated, repeated[:25]),
        (repeated.reshape(40, 50), np.array([3, 3, 100])),  # 2D: flattened, as np.unique
        (np.zeros(0, np.int32), dofs[:5]),
        (np.array([5], np.int64), np.array([5], np.int32)),
    ]


@pytest.mark.parametrize("case", range(len(_cases())))
def test_sorted_set_operations_are_numpys(case):
    a, b = _cases()[case]
    for got, want in [
        (indices.unique(a), np.unique(a)),
        (indices.setdiff(a, b), np.setdiff1d(a, b)),
    ]:
        assert got.dtype == want.dtype and got.shape == want.shape
        assert np.array_equal(got, want)


def test_the_switch_selects_numpys_functions(monkeypatch):
    a = np.array([4, 1, 4, 9, 1], dtype=np.int32)
    calls = []
    unique, setdiff1d = np.unique, np.setdiff1d
    monkeypatch.setattr(np, "unique", lambda x: calls.append("unique") or unique(x))
    monkeypatch.setattr(np, "setdiff1d", lambda x, y: calls.append("setdiff1d") or setdiff1d(x, y))
    assert indices.unique(a).tolist() == [1, 4, 9]
    assert indices.setdiff(a, [4]).tolist() == [1, 9]
    assert calls == []  # the sort-based path asks NumPy for neither
    monkeypatch.setattr(indices, "SORTED", False)
    assert indices.unique(a).tolist() == [1, 4, 9]
    assert indices.setdiff(a, [4]).tolist() == [1, 9]
    assert calls == ["unique", "setdiff1d"]
