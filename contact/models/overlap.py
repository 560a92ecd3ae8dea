"""Overlap of slave and master facets and the exact mortar integrals over it (pure NumPy).

For a pair (S, M) of a slave facet S and a master facet M (straight P1 or P2 segments in
2D, flat P1 or P2 triangles in 3D) and the projection π along the slave facet's unit normal n_S
(pointing out of the slave body, towards the master), this module computes

    M_loc[a, b] = ∫_{S ∩ π⁻¹(M)} ψ_a (φ_b^M ∘ π) ds,

a, b the local nodes of S and M, with the slave dual basis ψ biorthogonal to the slave
trace basis φ (Wohlmuth): ψ = A φ with A = D_e M_e⁻¹, M_e the facet's mass matrix and
D_e = diag(∫_S φ_a ds), so ∫_S ψ_a φ_b ds = δ_ab ∫_S φ_a ds.  P1: ψ_a = 2φ_a − φ_b on a
segment, ψ_a = 3φ_a − φ_b − φ_c on a triangle.  P2 segment (nodes: the two end points,
then the midpoint; ∫ φ_a = |S| (1/6, 1/6, 2/3), all positive, so A exists):
ψ_end = (3/2) φ_end + (1/2) φ_other − φ_mid for each end, ψ_mid = −(1/4)(φ_0 + φ_1) +
(3/2) φ_mid (Lamichhane & Wohlmuth).  The vertex functions of a P2 triangle integrate to
zero, so D_e is singular: there ψ is dual to the transformed basis φ̃ = T φ
(:data:`TRIANGLE_P2_TRANSFORM`, Popp, Wohlmuth, Gee & Wall 2012), ∫ ψ_a φ̃_b = δ_ab ∫ φ̃_a,
and the slave unknowns are the values in φ̃ (:func:`contact.models.mortar.couple`).

The overlap S ∩ π⁻¹(M) is computed exactly: an interval of the slave segment (2D: the
master end points projected onto the slave line), or a convex polygon in the slave
triangle's plane (3D: the projected master triangle clipped by the slave triangle,
Sutherland–Hodgman).  π is affine on a pair of flat facets, so φ_b^M ∘ π has the
master's degree on the overlap and ψ_a φ_b^M ∘ π twice it: two Gauss points per interval
(P1; three for P2) / the three edge midpoints of each triangle of a fan of the polygon
(P1; the 6-point Dunavant rule for P2) integrate it exactly.  Since
Σ_b φ_b^M = 1 and Σ_a ψ_a = 1, Σ_b M_loc[a, b] = ∫_{overlap} ψ_a ds and Σ_ab M_loc = |overlap|:
a slave facet covered by master facets transmits constants exactly (the contact patch
test).

Every function is vectorised over P pairs (leading axis) and knows nothing of meshes,
MPI or PETSc.  Lengths are in the mesh's unit; M_loc has the unit of the facet measure
(length in 2D, area in 3D).
"""

from __future__ import annotations

import numpy as np

# ψ = DUAL[nv] @ φ on a P1 facet with nv vertices (rows: ψ_a, columns: φ_b)
DUAL = {
    2: np.array([[2.0, -1.0], [-1.0, 2.0]]),
    3: np.array([[3.0, -1.0, -1.0], [-1.0, 3.0, -1.0], [-1.0, -1.0, 3.0]]),
}
# ψ = SEGMENT_P2_DUAL @ φ on a P2 segment (nodes: end 0, end 1, midpoint): D_e M_e⁻¹ with
# M_e = [[4, −1, 2], [−1, 4, 2], [2, 2, 16]] / 30 and D_e = diag(1/6, 1/6, 2/3) (|S| = 1)
SEGMENT_P2_DUAL = np.array([[1.5, 0.5, -0.25], [0.5, 1.5, -0.25], [-1.0, -1.0, 1.5]])

# The transformed P2 triangle basis φ̃ = TRIANGLE_P2_TRANSFORM @ φ (Popp, Wohlmuth, Gee & Wall
# 2012): φ̃_a = φ_a + α (φ of a's two edges), φ̃_e = (1 − 2α) φ_e, α = 1/5, so that every
# function integrates positively (|T| (2α/3, (1 − 2α)/3)); nodal values ũ = T⁻ᵀ u: the
# vertices' unchanged, an edge's ũ_e = (u_e − α (u_a + u_b)) / (1 − 2α)
TRIANGLE_P2_ALPHA = 0.2
TRIANGLE_P2_TRANSFORM = np.eye(6)
for _a in range(3):
    for _k in range(3):
        if _k != _a:  # the edge opposite vertex k contains vertex a
            TRIANGLE_P2_TRANSFORM[_a, 3 + _k] = TRIANGLE_P2_ALPHA
    TRIANGLE_P2_TRANSFORM[3 + _a, 3 + _a] = 1.0 - 2.0 * TRIANGLE_P2_ALPHA
# the 6-point Dunavant rule on a triangle (barycentric points, weights summing to 1; exact
# to degree 4)
_D1, _D2 = 0.445948490915965, 0.091576213509771
_DUNAVANT4 = np.array(
    [[_D1, _D1, 1 - 2 * _D1], [_D1, 1 - 2 * _D1, _D1], [1 - 2 * _D1, _D1, _D1]]
    + [[_D2, _D2, 1 - 2 * _D2], [_D2, 1 - 2 * _D2, _D2], [1 - 2 * _D2, _D2, _D2]]
)
_DUNAVANT4_WEIGHTS = np.array([0.223381589678011] * 3 + [0.109951743655322] * 3)


def _triangle_p2_dual() -> np.ndarray:
    """ψ = A φ̃ = (A T) φ with A = D̃ M̃⁻¹, M̃ = T M Tᵀ the mass matrix of φ̃ on the unit
    triangle (by the rule above, exact) and D̃ = diag ∫ φ̃."""
    phi = triangle_basis(_DUNAVANT4)
    mass = np.einsum("k,ka,kb->ab", _DUNAVANT4_WEIGHTS, phi, phi)
    T = TRIANGLE_P2_TRANSFORM
    D = np.diag(T @ (phi.T @ _DUNAVANT4_WEIGHTS))
    return D @ np.linalg.inv(T @ mass @ T.T) @ T


# Gauss–Legendre points and weights on [0, 1]: 2 points (exact to degree 3), 3 (degree 5)
_GAUSS = {
    2: (np.array([0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0)]), np.array([0.5, 0.5])),
    3: (
        np.array([0.5 - 0.5 * np.sqrt(0.6), 0.5, 0.5 + 0.5 * np.sqrt(0.6)]),
        np.array([5.0, 8.0, 5.0]) / 18.0,
    ),
}
MAX_POLYGON = 8  # vertices of a triangle clipped by a triangle: at most 6 (+ slack)


def facet_normals(X: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Unit normals (F, gdim) of facets X (F, nv, gdim) (segments in 2D, triangles in 3D),
    oriented away from the points ``inside`` (F, gdim), e.g. the centroids of their cells."""
    if X.shape[2] == 2:
        t = X[:, 1] - X[:, 0]
        n = np.column_stack([t[:, 1], -t[:, 0]])
    else:
        n = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    flip = np.einsum("ij,ij->i", n, X.mean(axis=1) - inside) < 0
    n[flip] *= -1.0
    return n


def dual_weights(nv: int, gdim: int) -> np.ndarray:
    """∫_F ψ_a φ̃_a ds / |F| = ∫_F φ̃_a ds / |F|: the diagonal D_e of the dual basis on a
    facet with ``nv`` nodes, φ̃ the slave trace basis the multiplier is dual to (φ itself,
    but on a P2 triangle the transformed basis :data:`TRIANGLE_P2_TRANSFORM` φ, whose
    functions all integrate positively)."""
    if (nv, gdim) == (6, 3):
        return TRIANGLE_P2_TRANSFORM @ trace_weights(6, 3)
    return trace_weights(nv, gdim)


def trace_weights(nv: int, gdim: int) -> np.ndarray:
    """∫_F φ_a ds / |F| of the trace basis of a flat facet with ``nv`` nodes in ``gdim``
    dimensions (P1 segment or triangle, P2 segment or triangle; the node order of the
    facet's closure DoFs: vertices, then edge midpoints): the diagonal D_e of the dual
    basis and the nodal weights ∫ φ_i ds (zero at a P2 triangle's vertices)."""
    weights = {
        (2, 2): [0.5, 0.5],
        (3, 2): [1 / 6, 1 / 6, 2 / 3],
        (3, 3): [1 / 3] * 3,
        (6, 3): [0.0] * 3 + [1 / 3] * 3,
    }
    return np.array(weights[(nv, gdim)])


def triangle_basis(lam: np.ndarray) -> np.ndarray:
    """The P2 Lagrange basis of a triangle at points of barycentric coordinates ``lam``
    (k, 3): the vertex functions λ_a (2λ_a − 1), then the edge functions 4 λ_b λ_c of the
    edges opposite vertices 0, 1, 2 (the order of a facet's closure DoFs); (k, 6)."""
    edges = 4.0 * np.stack([lam[:, 1] * lam[:, 2], lam[:, 0] * lam[:, 2], lam[:, 0] * lam[:, 1]], 1)
    return np.concatenate([lam * (2.0 * lam - 1.0), edges], axis=1)


# ψ = TRIANGLE_P2_DUAL @ φ on a P2 triangle: dual to the transformed basis φ̃ (∫ ψ_a φ̃_b
# = δ_ab ∫ φ̃_a)
TRIANGLE_P2_DUAL = _triangle_p2_dual()


def segment_basis(nv: int, xi: np.ndarray) -> np.ndarray:
    """The P1 (``nv`` = 2) or P2 (``nv`` = 3: end 0, end 1, midpoint) Lagrange basis of a
    segment at the points ``xi`` (k,) of [0, 1]; (k, nv)."""
    if nv == 2:
        return np.column_stack([1.0 - xi, xi])
    return np.column_stack(
        [(1.0 - xi) * (1.0 - 2.0 * xi), xi * (2.0 * xi - 1.0), 4.0 * xi * (1.0 - xi)]
    )


def facet_measures(X: np.ndarray) -> np.ndarray:
    """Length (2D) or area (3D) of facets X (F, nv, gdim)."""
    if X.shape[2] == 2:
        return np.linalg.norm(X[:, 1] - X[:, 0], axis=1)
    return 0.5 * np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)


def mortar_pairs(
    Xs: np.ndarray, ns: np.ndarray, Xm: np.ndarray, tol: float = 1e-12
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M_loc (P, nv, nv), the overlap measure (P,) and the signed normal distance (P,) from
    the slave facet to the master facet at the overlap's centroid (> 0: a gap, < 0:
    penetration), for slave facets Xs (P, nv, gdim) with unit normals ns (P, gdim) and
    master facets Xm (P, nv, gdim) (nv nodes per facet: P1 segments or triangles, or P2
    segments, their vertices first; the facets are straight, defined by their vertices: on
    curved cells their chords).
    Pairs without overlap (or whose master facet is parallel to n_S) give zeros and
    distance +inf.  ``tol`` is relative to the slave facet's size."""
    if Xs.shape[2] == 2:
        return _segments(Xs, ns, Xm, tol)
    return _triangles(Xs, ns, Xm, tol)


def _segments(Xs, ns, Xm, tol):
    P, nv = Xs.shape[:2]
    t = Xs[:, 1] - Xs[:, 0]
    L = np.linalg.norm(t, axis=1)
    tau = t / L[:, None]
    # slave coordinate ξ ∈ [0, 1] of the master end points projected along n_S
    xi = np.einsum("pkd,pd->pk", Xm[:, :2] - Xs[:, :1], tau) / L[:, None]
    lo = np.maximum(0.0, xi.min(axis=1))
    hi = np.minimum(1.0, xi.max(axis=1))
    dxi = xi[:, 1] - xi[:, 0]
    ok = (hi - lo > tol) & (np.abs(dxi) > tol)
    M = np.zeros((P, nv, nv))
    dist = np.full(P, np.inf)
    if not ok.any():
        return M, np.zeros(P), dist
    Xs, ns, Xm, L, xi, lo, hi, dxi = (a[ok] for a in (Xs, ns, Xm, L, xi, lo, hi, dxi))
    dual = DUAL[2] if nv == 2 else SEGMENT_P2_DUAL
    points, weights = _GAUSS[nv]
    for g, w in zip(points, weights):
        q = lo + g * (hi - lo)  # slave coordinate of the Gauss point
        eta = (q - xi[:, 0]) / dxi  # master coordinate of its projection
        psi = segment_basis(nv, q) @ dual.T
        phim = segment_basis(nv, eta)
        M[ok] += w * ((hi - lo) * L)[:, None, None] * psi[:, :, None] * phim[:, None, :]
    qc = 0.5 * (lo + hi)
    etac = (qc - xi[:, 0]) / dxi
    xs = Xs[:, 0] + qc[:, None] * (Xs[:, 1] - Xs[:, 0])
    xm = Xm[:, 0] + etac[:, None] * (Xm[:, 1] - Xm[:, 0])
    dist[ok] = np.einsum("pd,pd->p", xm - xs, ns)
    meas = np.zeros(P)
    meas[ok] = (hi - lo) * L
    return M, meas, dist


def _triangles(Xs, ns, Xm, tol):
    P, nv = Xs.shape[:2]
    Xs, Xm = Xs[:, :3], Xm[:, :3]  # the (flat) facets are their vertices' triangles
    # in-plane axes of the slave triangle: e1 along its first edge, e2 = n × e1
    e1 = Xs[:, 1] - Xs[:, 0]
    h = np.linalg.norm(e1, axis=1)
    e1 /= h[:, None]
    e2 = np.cross(ns, e1)
    origin = Xs[:, 0]

    def plane(Y):  # (P, k, 3) → (P, k, 2): projection along n_S, in (e1, e2) coordinates
        D = Y - origin[:, None, :]
        return np.stack([np.einsum("pkd,pd->pk", D, e1), np.einsum("pkd,pd->pk", D, e2)], axis=-1)

    s2, m2 = plane(Xs), plane(Xm)
    poly, count = clip_polygons(m2, s2)
    area_tol = tol * h**2
    # fan of the convex polygon from its vertex 0: triangles (v0, v_k, v_{k+1}), k = 1 … n−2
    Bs, Bm = _barycentric_maps(s2), _barycentric_maps(m2)
    M = np.zeros((P, nv, nv))
    meas = np.zeros(P)
    centroid = np.zeros((P, 2))
    for k in range(1, poly.shape[1] - 1):
        use = k + 1 < count
        if not use.any():
            break
        A, B, C = poly[:, 0], poly[:, k], poly[:, np.minimum(k + 1, poly.shape[1] - 1)]
        area = 0.5 * np.abs(
            (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])
        )
        area = np.where(use, area, 0.0)
        meas += area
        centroid += area[:, None] * (A + B + C) / 3.0
        if nv == 3:
            for q in (0.5 * (A + B), 0.5 * (B + C), 0.5 * (C + A)):  # exact for quadratics
                psi = _apply(Bs, q) @ DUAL[3].T
                phim = _apply(Bm, q)
                M += (area / 3.0)[:, None, None] * psi[:, :, None] * phim[:, None, :]
            continue
        for bary, w in zip(_DUNAVANT4, _DUNAVANT4_WEIGHTS):  # exact for quartics
            q = bary[0] * A + bary[1] * B + bary[2] * C
            psi = triangle_basis(_apply(Bs, q)) @ TRIANGLE_P2_DUAL.T
            phim = triangle_basis(_apply(Bm, q))
            M += (w * area)[:, None, None] * psi[:, :, None] * phim[:, None, :]
    good = (meas > area_tol) & (
        np.abs(np.linalg.det(np.stack([m2[:, 1] - m2[:, 0], m2[:, 2] - m2[:, 0]], 1))) > area_tol
    )
    M[~good] = 0.0
    meas[~good] = 0.0
    dist = np.full(P, np.inf)
    if good.any():
        c2 = centroid[good] / meas[good, None]
        x = origin[good] + c2[:, :1] * e1[good] + c2[:, 1:] * e2[good]  # slave point
        nm = np.cross(Xm[good, 1] - Xm[good, 0], Xm[good, 2] - Xm[good, 0])  # master plane
        # the projected master triangle is not degenerate, so n_S·n_M ≠ 0
        dist[good] = np.einsum("pd,pd->p", Xm[good, 0] - x, nm) / np.einsum(
            "pd,pd->p", ns[good], nm
        )
    return M, meas, dist


def _barycentric_maps(T: np.ndarray) -> np.ndarray:
    """Affine maps (P, 3, 3) with [λ0, λ1, λ2] = B @ [x, y, 1] for triangles T (P, 3, 2);
    a degenerate triangle gets a zero map."""
    A = np.concatenate([T.transpose(0, 2, 1), np.ones((len(T), 1, 3))], axis=1)  # columns [x; y; 1]
    det = np.linalg.det(A)
    safe = np.abs(det) > 1e-300
    out = np.zeros_like(A)
    out[safe] = np.linalg.inv(A[safe])
    return out


def _apply(B: np.ndarray, q: np.ndarray) -> np.ndarray:
    return np.einsum("pij,pj->pi", B, np.column_stack([q, np.ones(len(q))]))


def clip_polygons(subject: np.ndarray, clip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sutherland–Hodgman: the convex polygons subject (P, 3, 2) ∩ clip (P, 3, 2) (both
    triangles, either orientation) as vertex arrays (P, MAX_POLYGON, 2) with counts (P,)."""
    P = len(subject)
    poly = np.zeros((P, MAX_POLYGON, 2))
    poly[:, :3] = subject
    count = np.full(P, 3)
    orient = np.sign(_signed_area(clip))
    for e in range(3):
        a, b = clip[:, e], clip[:, (e + 1) % 3]
        # inside: on the left of a → b for a counter-clockwise clip triangle
        normal = orient[:, None] * np.column_stack([b[:, 1] - a[:, 1], a[:, 0] - b[:, 0]])
        poly, count = _clip_half_plane(poly, count, normal, np.einsum("pd,pd->p", normal, a))
    return poly, count


def _signed_area(T: np.ndarray) -> np.ndarray:
    return 0.5 * (
        (T[:, 1, 0] - T[:, 0, 0]) * (T[:, 2, 1] - T[:, 0, 1])
        - (T[:, 1, 1] - T[:, 0, 1]) * (T[:, 2, 0] - T[:, 0, 0])
    )


def _clip_half_plane(poly, count, normal, offset):
    """Keep the part {x : normal·x ≤ offset} of each polygon (vectorised Sutherland–Hodgman
    step: every vertex emits itself if inside and the crossing of its edge if the edge
    crosses)."""
    P, K, _ = poly.shape
    k = np.arange(K)
    valid = k[None, :] < count[:, None]
    nxt = poly[np.arange(P)[:, None], (k[None, :] + 1) % np.maximum(count, 1)[:, None]]
    s_cur = np.einsum("pkd,pd->pk", poly, normal) - offset[:, None]
    s_nxt = np.einsum("pkd,pd->pk", nxt, normal) - offset[:, None]
    in_cur, in_nxt = s_cur <= 0, s_nxt <= 0
    emit_cur = valid & in_cur
    emit_cross = valid & (in_cur != in_nxt)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(emit_cross, s_cur / (s_cur - s_nxt), 0.0)
    cross = poly + t[:, :, None] * (nxt - poly)
    n_emit = emit_cur.astype(int) + emit_cross.astype(int)
    start = np.cumsum(n_emit, axis=1) - n_emit
    out = np.zeros((P, K, 2))
    p_idx = np.broadcast_to(np.arange(P)[:, None], (P, K))
    out[p_idx[emit_cur], start[emit_cur]] = poly[emit_cur]
    pos = start + emit_cur
    out[p_idx[emit_cross], np.minimum(pos[emit_cross], K - 1)] = cross[emit_cross]
    return out, np.minimum(n_emit.sum(axis=1), K)
