"""Overlap of slave and master facets and the exact mortar integrals over it (pure NumPy).

For a pair (S, M) of a slave facet S and a master facet M (P1 segments in 2D, P1
triangles in 3D) and the projection π along the slave facet's unit normal n_S (pointing
out of the slave body, towards the master), this module computes

    M_loc[a, b] = ∫_{S ∩ π⁻¹(M)} ψ_a (φ_b^M ∘ π) ds,

a, b the local vertices of S and M, with the slave dual basis ψ biorthogonal to the slave
trace basis φ (Wohlmuth): ψ_a = 2φ_a − φ_b on a segment, ψ_a = 3φ_a − φ_b − φ_c on a
triangle, so ∫_S ψ_a φ_b ds = δ_ab ∫_S φ_a ds.

The overlap S ∩ π⁻¹(M) is computed exactly: an interval of the slave segment (2D: the
master end points projected onto the slave line), or a convex polygon in the slave
triangle's plane (3D: the projected master triangle clipped by the slave triangle,
Sutherland–Hodgman).  π is affine on a pair of flat facets, so φ_b^M ∘ π is linear on
the overlap and ψ_a φ_b^M ∘ π quadratic: two Gauss points per interval / the three edge
midpoints of each triangle of a fan of the polygon integrate it exactly.  Since
Σ_b φ_b^M = 1 and Σ_a ψ_a = 1, Σ_b M_loc[a, b] = ∫_{overlap} ψ_a ds and Σ_ab M_loc = |overlap|:
a slave facet covered by master facets transmits constants exactly (the contact patch
test).

Every function is vectorised over P pairs (leading axis) and knows nothing of meshes,
MPI or PETSc.  Lengths are in the mesh's unit; M_loc has the unit of the facet measure
(length in 2D, area in 3D).
"""

from __future__ import annotations

import numpy as np

# ψ = DUAL[nv] @ φ on a facet with nv vertices (rows: ψ_a, columns: φ_b)
DUAL = {
    2: np.array([[2.0, -1.0], [-1.0, 2.0]]),
    3: np.array([[3.0, -1.0, -1.0], [-1.0, 3.0, -1.0], [-1.0, -1.0, 3.0]]),
}

_GAUSS2 = (0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0))  # 2-point Gauss on [0, 1]
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
    master facets Xm (P, nv, gdim).  Pairs without overlap (or whose master facet is
    parallel to n_S) give zeros and distance +inf.  ``tol`` is relative to the slave
    facet's size."""
    if Xs.shape[2] == 2:
        return _segments(Xs, ns, Xm, tol)
    return _triangles(Xs, ns, Xm, tol)


def _segments(Xs, ns, Xm, tol):
    P = len(Xs)
    t = Xs[:, 1] - Xs[:, 0]
    L = np.linalg.norm(t, axis=1)
    tau = t / L[:, None]
    # slave coordinate ξ ∈ [0, 1] of the master end points projected along n_S
    xi = np.einsum("pkd,pd->pk", Xm - Xs[:, :1], tau) / L[:, None]
    lo = np.maximum(0.0, xi.min(axis=1))
    hi = np.minimum(1.0, xi.max(axis=1))
    dxi = xi[:, 1] - xi[:, 0]
    ok = (hi - lo > tol) & (np.abs(dxi) > tol)
    M = np.zeros((P, 2, 2))
    dist = np.full(P, np.inf)
    if not ok.any():
        return M, np.zeros(P), dist
    Xs, ns, Xm, L, xi, lo, hi, dxi = (a[ok] for a in (Xs, ns, Xm, L, xi, lo, hi, dxi))
    for g in _GAUSS2:
        q = lo + g * (hi - lo)  # slave coordinate of the Gauss point
        eta = (q - xi[:, 0]) / dxi  # master coordinate of its projection
        psi = np.column_stack([1.0 - q, q]) @ DUAL[2].T
        phim = np.column_stack([1.0 - eta, eta])
        M[ok] += 0.5 * ((hi - lo) * L)[:, None, None] * psi[:, :, None] * phim[:, None, :]
    qc = 0.5 * (lo + hi)
    etac = (qc - xi[:, 0]) / dxi
    xs = Xs[:, 0] + qc[:, None] * (Xs[:, 1] - Xs[:, 0])
    xm = Xm[:, 0] + etac[:, None] * (Xm[:, 1] - Xm[:, 0])
    dist[ok] = np.einsum("pd,pd->p", xm - xs, ns)
    meas = np.zeros(P)
    meas[ok] = (hi - lo) * L
    return M, meas, dist


def _triangles(Xs, ns, Xm, tol):
    P = len(Xs)
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
    M = np.zeros((P, 3, 3))
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
        for q in (0.5 * (A + B), 0.5 * (B + C), 0.5 * (C + A)):  # exact for quadratics
            psi = _apply(Bs, q) @ DUAL[3].T
            phim = _apply(Bm, q)
            M += (area / 3.0)[:, None, None] * psi[:, :, None] * phim[:, None, :]
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
