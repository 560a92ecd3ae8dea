"""Geometry kernels of the mortar coupling (contact.models.overlap, pure NumPy): the dual
basis is biorthogonal, clipping gives exact polygons, and the mortar integrals over a
slave facet covered by any master mesh of the same line / plane reproduce constants and
linear functions exactly (what the contact patch test needs)."""

from contact.models.overlap import (
    DUAL,
    SEGMENT_P2_DUAL,
    TRIANGLE_P2_DUAL,
    TRIANGLE_P2_TRANSFORM,
    clip_polygons,
    dual_weights,
    facet_measures,
    facet_normals,
    mortar_pairs,
    segment_basis,
    trace_weights,
    triangle_basis,
)

import numpy as np
import pytest


def _grid_triangles(rng, lo, hi, n, jitter=0.3):
    """A perturbed structured triangulation of the square [lo, hi]² (boundary nodes fixed)."""
    t = np.linspace(lo, hi, n + 1)
    X, Y = np.meshgrid(t, t, indexing="ij")
    P = np.column_stack([X.ravel(), Y.ravel()])
    inner = (np.abs(P - lo) > 1e-12).all(1) & (np.abs(P - hi) > 1e-12).all(1)
    P[inner] += jitter * (hi - lo) / n * (rng.random((inner.sum(), 2)) - 0.5)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    v = lambda a, b: (a * (n + 1) + b).ravel()  # noqa: E731
    tris = np.vstack(
        [np.c_[v(i, j), v(i + 1, j), v(i + 1, j + 1)], np.c_[v(i, j), v(i + 1, j + 1), v(i, j + 1)]]
    )
    return P[tris]


def test_dual_basis_is_biorthogonal():
    for nv, mass in (
        (2, np.array([[2, 1], [1, 2]]) / 6.0),
        (3, np.array([[2, 1, 1], [1, 2, 1], [1, 1, 2]]) / 12.0),
    ):
        # ∫ ψ_a φ_b = (DUAL @ mass)_ab on the unit facet (|facet| = 1): δ_ab ∫ φ_a = δ_ab / nv
        assert np.allclose(DUAL[nv] @ mass, np.eye(nv) / nv, atol=1e-15)
        assert np.allclose(DUAL[nv].sum(axis=0), 1.0)  # Σ_a ψ_a = 1


def test_normals_point_away_from_the_cell():
    X = np.array([[[0.0, 0.0], [1.0, 0.0]], [[0.0, 0.0], [1.0, 0.0]]])
    n = facet_normals(X, np.array([[0.3, 0.5], [0.3, -0.5]]))
    assert np.allclose(n, [[0, -1], [0, 1]])
    T = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    assert np.allclose(facet_normals(T, np.array([[0.2, 0.2, 1.0]])), [[0, 0, -1]])
    assert np.allclose(facet_measures(T), 0.5)


def test_clipping_star_of_david_is_the_hexagon():
    a = np.array([[np.cos(t), np.sin(t)] for t in np.pi / 2 + 2 * np.pi * np.arange(3) / 3])
    for clip in (-a, -a[::-1]):  # either orientation of the clip triangle
        poly, count = clip_polygons(a[None], clip[None])
        assert count[0] == 6
        hexagon = poly[0, :6]
        assert np.allclose(np.linalg.norm(hexagon, axis=1), 1 / np.sqrt(3))  # its vertices
    disjoint, count = clip_polygons(a[None], a[None] + 5.0)
    assert count[0] == 0


def test_segments_identical_and_offset():
    Xs = np.array([[[0.0, 0.0], [2.0, 0.0]]])
    n = np.array([[0.0, 1.0]])
    M, meas, d = mortar_pairs(Xs, n, Xs[:, ::-1] + [0.0, 0.1])  # reversed master, gap 0.1
    assert (
        np.allclose(M[0], [[0, 1], [1, 0]])
        and meas[0] == pytest.approx(2.0)
        and d[0] == pytest.approx(0.1)
    )
    M, meas, d = mortar_pairs(Xs, n, Xs + [5.0, -0.2])  # no overlap
    assert not M.any() and meas[0] == 0 and np.isinf(d[0])


@pytest.mark.parametrize("tilt", [0.0, 0.4])
def test_segments_reproduce_linear_functions(tilt):
    """Slave segment covered by an unrelated master mesh of the same line: Σ_j M_ij = D_ii
    and Σ_j M_ij x_j = D_ii x_i (x_j the master node coordinates), whatever the tilt."""
    rng = np.random.default_rng(1)
    c, s = np.cos(tilt), np.sin(tilt)
    R = np.array([[c, -s], [s, c]])
    xs = np.array([0.13, 0.71])
    xm = np.sort(np.concatenate([[-0.2, 1.1], rng.random(7)]))
    Xs = (np.column_stack([xs, 0 * xs]) @ R.T)[None]
    Xm = (
        np.stack(
            [np.column_stack([xm[:-1], 0 * xm[:-1]]), np.column_stack([xm[1:], 0 * xm[1:]])], 1
        )
        @ R.T
    )
    n = np.repeat((R @ [0.0, 1.0])[None], len(Xm), 0)
    M, meas, _ = mortar_pairs(np.repeat(Xs, len(Xm), 0), n, Xm)
    L = xs[1] - xs[0]
    assert meas.sum() == pytest.approx(L, rel=1e-14)
    assert np.allclose(M.sum(axis=(0, 2)), L / 2, rtol=1e-14)
    moment = np.einsum("pab,pbd->ad", M, Xm)
    assert np.allclose(moment, L / 2 * Xs[0], atol=1e-14)


def test_p2_segment_dual_basis_is_biorthogonal():
    """ψ = A φ on the P2 segment: ∫ ψ_a φ_b = δ_ab ∫ φ_a = δ_ab (1/6, 1/6, 2/3) (Gauss
    quadrature of degree 5 on the unit segment), Σ_a ψ_a = 1."""
    g, w = np.polynomial.legendre.leggauss(5)
    q, w = 0.5 + 0.5 * g, 0.5 * w
    phi = segment_basis(3, q)
    mass = np.einsum("k,ka,kb->ab", w, phi, phi)
    assert np.allclose(np.diag(mass.sum(axis=1)), np.diag(trace_weights(3, 2)), atol=1e-15)
    assert np.allclose(SEGMENT_P2_DUAL @ mass, np.diag(trace_weights(3, 2)), atol=1e-15)
    assert np.allclose(SEGMENT_P2_DUAL.sum(axis=0), 1.0)


@pytest.mark.parametrize("tilt", [0.0, 0.4])
def test_p2_segments_reproduce_quadratic_functions(tilt):
    """A P2 slave segment covered by an unrelated P2 master mesh of the same line: for
    f = 1, x, x² (which the master's P2 interpolant reproduces) Σ_j M_ij f(x_j) = ∫_S ψ_i f
    ds (Gauss quadrature on the slave segment), and Σ_j M_ij = D_ii, whatever the tilt."""
    rng = np.random.default_rng(3)
    c, s = np.cos(tilt), np.sin(tilt)
    R = np.array([[c, -s], [s, c]])
    xs = np.array([0.13, 0.71, 0.42])  # ends, then the midpoint
    xm = np.sort(np.concatenate([[-0.2, 1.1], rng.random(6)]))
    ends = np.stack([xm[:-1], xm[1:], 0.5 * (xm[:-1] + xm[1:])], 1)  # (P, 3)
    line = lambda t: np.stack([t, 0 * t], -1) @ R.T  # noqa: E731
    Xs, Xm = line(xs)[None], line(ends)
    n = np.repeat((R @ [0.0, 1.0])[None], len(Xm), 0)
    M, meas, _ = mortar_pairs(np.repeat(Xs, len(Xm), 0), n, Xm)
    L = xs[1] - xs[0]
    assert M.shape == (len(Xm), 3, 3) and meas.sum() == pytest.approx(L, rel=1e-14)
    g, w = np.polynomial.legendre.leggauss(5)
    q, w = 0.5 + 0.5 * g, 0.5 * w * L
    psi = segment_basis(3, q) @ SEGMENT_P2_DUAL.T  # (k, 3)
    x_q = xs[0] + q * L
    for k in range(3):
        exact = np.einsum("k,ka,k->a", w, psi, x_q**k)  # ∫ ψ_a x^k along the line
        assert np.allclose(np.einsum("pab,pb->a", M, ends**k), exact, atol=1e-14)
    assert np.allclose(M.sum(axis=(0, 2)), L * trace_weights(3, 2), rtol=1e-13)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_triangles_reproduce_linear_functions(seed):
    """A slave triangle inside a perturbed master triangulation of its plane (arbitrary
    orientation): Σ_j M_ij = D_ii = |T|/3 and Σ_j M_ij x_j = D_ii x_i, to round-off."""
    rng = np.random.default_rng(seed)
    master2 = _grid_triangles(rng, -0.5, 1.5, 7)
    slave2 = np.array([[0.1, 0.05], [0.93, 0.22], [0.35, 0.8]])
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    lift = lambda T: np.concatenate([T, np.zeros(T.shape[:-1] + (1,))], -1) @ Q.T  # noqa: E731
    Xs, Xm = lift(slave2)[None], lift(master2)
    n = facet_normals(Xs, Xs.mean(1) - Q[:, 2])  # away from a point below: +Q e_z
    M, meas, d = mortar_pairs(np.repeat(Xs, len(Xm), 0), np.repeat(n, len(Xm), 0), Xm)
    area = facet_measures(Xs)[0]
    assert meas.sum() == pytest.approx(area, rel=1e-13)
    assert np.allclose(M.sum(axis=(0, 2)), area / 3, rtol=1e-13)
    assert np.allclose(np.einsum("pab,pbd->ad", M, Xm), area / 3 * Xs[0], atol=1e-13)
    assert np.allclose(d[meas > 0], 0.0, atol=1e-13)


def test_triangles_distance_and_partial_overlap():
    T = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    n = np.array([[0.0, 0, 1]])
    M, meas, d = mortar_pairs(T, n, T + [0.5, 0.0, -0.05])  # shifted half-way, penetrating 0.05
    # overlap: the triangle (0.5, 0), (1, 0), (0.5, 0.5) of area 1/8
    assert meas[0] == pytest.approx(0.125) and d[0] == pytest.approx(-0.05)
    assert M.sum() == pytest.approx(0.125)


def _triangle_rule(order: int = 6):
    """A Gauss rule on the unit triangle (barycentric points, weights summing to 1/2) from
    a collapsed tensor product of Gauss–Legendre rules: exact to degree 2 order − 1."""
    g, w = np.polynomial.legendre.leggauss(order)
    t, w = 0.5 + 0.5 * g, 0.5 * w
    x = t[:, None] * np.ones(order)
    y = (1 - t)[:, None] * t[None, :]
    W = (w[:, None] * w[None, :]) * (1 - t)[:, None]
    x, y = x.ravel(), y.ravel()
    return np.c_[1 - x - y, x, y], W.ravel()


def test_p2_triangle_dual_basis_is_biorthogonal_to_the_transformed_basis():
    """∫ ψ_a φ̃_b = δ_ab ∫ φ̃_a on the unit triangle, ∫ φ̃_a > 0 for all six (the vertex
    functions φ_a themselves integrate to zero), Σ_a ψ_a = 1."""
    lam, w = _triangle_rule()
    phi = triangle_basis(lam)
    area = 0.5
    assert np.allclose(phi.T @ w / area, trace_weights(6, 3), atol=1e-15)
    tilde = phi @ TRIANGLE_P2_TRANSFORM.T
    assert np.all(tilde.T @ w / area > 0.1)
    assert np.allclose(tilde.T @ w / area, dual_weights(6, 3), atol=1e-15)
    psi = phi @ TRIANGLE_P2_DUAL.T
    assert np.allclose(np.einsum("k,ka,kb->ab", w, psi, tilde) / area, np.diag(dual_weights(6, 3)))
    assert np.allclose(psi.sum(axis=1), 1.0)


@pytest.mark.parametrize("seed", [0, 1])
def test_p2_triangles_reproduce_quadratic_functions(seed):
    """A P2 slave triangle inside a perturbed P2 master triangulation of its plane: for
    f = 1, x, y, x², xy (reproduced by the master's P2 interpolant) Σ_j M_ij f(x_j) =
    ∫_T ψ_i f (quadrature on the slave triangle), to round-off."""
    rng = np.random.default_rng(seed)
    master2 = _grid_triangles(rng, -0.5, 1.5, 5)
    mid = lambda T: 0.5 * (T[:, [1, 0, 0]] + T[:, [2, 2, 1]])  # noqa: E731  edges opposite 0, 1, 2
    master6 = np.concatenate([master2, mid(master2)], axis=1)
    slave2 = np.array([[[0.1, 0.05], [0.93, 0.22], [0.35, 0.8]]])
    slave6 = np.concatenate([slave2, mid(slave2)], axis=1)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    lift = lambda T: np.concatenate([T, np.zeros(T.shape[:-1] + (1,))], -1) @ Q.T  # noqa: E731
    Xs, Xm = lift(slave6), lift(master6)
    n = facet_normals(Xs[:, :3], Xs[:, :3].mean(1) - Q[:, 2])
    M, meas, _ = mortar_pairs(np.repeat(Xs, len(Xm), 0), np.repeat(n, len(Xm), 0), Xm)
    area = facet_measures(Xs[:, :3])[0]
    assert M.shape == (len(Xm), 6, 6) and meas.sum() == pytest.approx(area, rel=1e-13)
    lam, w = _triangle_rule()
    psi = triangle_basis(lam) @ TRIANGLE_P2_DUAL.T
    pts = lam @ slave2[0]  # in-plane coordinates of the quadrature points
    jac = area / 0.5
    for f in (
        lambda p: np.ones(len(p)),
        lambda p: p[:, 0],
        lambda p: p[:, 1],
        lambda p: p[:, 0] ** 2,
        lambda p: p[:, 0] * p[:, 1],
    ):
        exact = jac * np.einsum("k,ka,k->a", w, psi, f(pts))
        nodal = f(master6.reshape(-1, 2)).reshape(len(Xm), 6)
        assert np.allclose(np.einsum("pab,pb->a", M, nodal), exact, atol=1e-13)
