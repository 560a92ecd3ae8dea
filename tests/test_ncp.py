"""Tests of the complementarity functions and their generalized derivatives (docs/theory.md §3)."""

from __future__ import annotations

import decimal

import contact  # noqa: F401  (sets up dolfinx_solver before dolfinx is imported)
from contact.solvers import ncp

import numpy as np
import pytest

MUS = (0.3, 0.5, 0.7)
CASES = [("fb", 0.5), ("min", 0.5)] + [("blend", mu) for mu in MUS]
CASE_IDS = [m if m != "blend" else f"blend-{mu}" for m, mu in CASES]
SIGNED = ["fb", "min"]  # methods with the sign convention φ > 0 ⇔ a > 0 and b > 0

C_FB = 1.0 - 1.0 / np.sqrt(2.0)  # documented FB element at (0, 0), per component
TINY = 5e-324  # smallest subnormal
HUGE = 1e300
FMAX = np.finfo(float).max


def _loguniform(rng, lo, hi, n):
    return 10.0 ** rng.uniform(np.log10(lo), np.log10(hi), n)


def _complementary(rng, lo=1e-300, hi=1e300, n=4000):
    """Random pairs a ≥ 0, b ≥ 0, a·b = 0 over magnitudes lo..hi (both orders, some zeros)."""
    mag = _loguniform(rng, lo, hi, n)
    mag[::17] = 0.0
    first = rng.random(n) < 0.5
    a = np.where(first, mag, 0.0)
    b = np.where(first, 0.0, mag)
    return a, b


def _not_complementary(rng, lo, hi, n=4000):
    """Random pairs with a < 0, or b < 0, or both > 0, magnitudes lo..hi (some zeros)."""
    a = _loguniform(rng, lo, hi, n) * rng.choice([-1.0, 1.0], n)
    b = _loguniform(rng, lo, hi, n) * rng.choice([-1.0, 1.0], n)
    # a zero on one side with a negative other side is not complementary either
    a[(np.arange(n) % 23 == 0) & (b < 0)] = 0.0
    b[(np.arange(n) % 29 == 0) & (a < 0)] = 0.0
    keep = (a < 0) | (b < 0) | ((a > 0) & (b > 0))
    assert keep.all()
    return a, b


EDGE_COMPLEMENTARY = [
    (0.0, 0.0),
    (-0.0, 0.0),
    (0.0, -0.0),
    (-0.0, -0.0),
    (0.0, 1.0),
    (1.0, 0.0),
    (0.0, TINY),
    (TINY, 0.0),
    (0.0, 1e-300),
    (1e-300, 0.0),
    (0.0, HUGE),
    (HUGE, 0.0),
    (0.0, 1e-5),
    (3.7e12, 0.0),
]
EDGE_COMPLEMENTARY_OVERFLOW = [(0.0, 1e308), (1e308, 0.0), (0.0, FMAX), (FMAX, 0.0)]
EDGE_NOT_COMPLEMENTARY = [
    (-1.0, 0.0),
    (0.0, -1.0),
    (-1.0, -1.0),
    (1.0, 1.0),
    (-1.0, 1.0),
    (1.0, -1.0),
    (-TINY, 0.0),
    (0.0, -TINY),
    (-TINY, -TINY),
    (1e-310, 1e-310),
    (-1e-310, 1e-310),
    (-1e-300, HUGE),
    (-HUGE, 1e-300),
    (1e-300, HUGE),
    (-HUGE, -HUGE),
    (HUGE, HUGE),
    (-HUGE, HUGE),
    (HUGE, -HUGE),
    (-HUGE, 0.0),
    (0.0, -HUGE),
    (1e-300, 1e-300),
    (-1e-300, -1e-300),
    (2.0, 3.0),
    (-2.0, 3.0),
    (1e-10, 1e10),
]
# pairs with 0 < |b| ≪ a, where b/(a+b+r) underflows (to 0 or to a subnormal): see
# test_fb_small_partner_*
EDGE_NOT_COMPLEMENTARY_UNDERFLOW = [(HUGE, 1e-300), (HUGE, -1e-300), (1e20, -1e-300), (1.0, -TINY)]


# --------------------------------------------------------------------------------------
# φ = 0 exactly on complementary pairs
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("method,mu", CASES, ids=CASE_IDS)
def test_zero_on_random_complementary_pairs(method, mu):
    a, b = _complementary(np.random.default_rng(1))
    val = ncp.phi(a, b, method, mu)
    assert val.shape == a.shape
    bad = val != 0.0
    assert not bad.any(), list(zip(a[bad][:5], b[bad][:5], val[bad][:5]))


@pytest.mark.parametrize("a,b", EDGE_COMPLEMENTARY)
@pytest.mark.parametrize("method,mu", CASES, ids=CASE_IDS)
def test_zero_on_edge_complementary_pairs(method, mu, a, b):
    assert ncp.phi(a, b, method, mu) == 0.0
    assert ncp.phi(np.array([a]), np.array([b]), method, mu)[0] == 0.0


@pytest.mark.parametrize(
    "method,mu,a,b",
    [
        pytest.param(
            m,
            mu,
            a,
            b,
            id=f"{i}-{a}-{b}",
        )
        for m, mu, i in [(m, mu, i) for (m, mu), i in zip(CASES, CASE_IDS)]
        for a, b in EDGE_COMPLEMENTARY_OVERFLOW
    ],
)
def test_zero_on_complementary_pairs_near_overflow(method, mu, a, b):
    with np.errstate(all="ignore"):
        assert ncp.phi(a, b, method, mu) == 0.0


# --------------------------------------------------------------------------------------
# φ ≠ 0 off the complementarity set, and the sign convention
# --------------------------------------------------------------------------------------
def _check_not_complementary(method, mu, a, b):
    val = ncp.phi(a, b, method, mu)
    bad = ~(np.isfinite(val) & (val != 0.0))
    assert not bad.any(), list(zip(a[bad][:5], b[bad][:5], val[bad][:5]))
    if method in SIGNED:
        positive = (a > 0) & (b > 0)
        assert np.array_equal(val > 0, positive)
        assert np.array_equal(val < 0, ~positive)


@pytest.mark.parametrize("method,mu", CASES, ids=CASE_IDS)
def test_nonzero_on_random_non_complementary_pairs_moderate(method, mu):
    """Magnitudes 1e-150..1e150: every ratio |b|/|a| stays in the normal range."""
    a, b = _not_complementary(np.random.default_rng(2), 1e-150, 1e150)
    _check_not_complementary(method, mu, a, b)


@pytest.mark.parametrize(
    "method,mu", [pytest.param(m, mu, id=i) for (m, mu), i in zip(CASES, CASE_IDS)]
)
def test_nonzero_on_random_non_complementary_pairs_full_range(method, mu):
    a, b = _not_complementary(np.random.default_rng(3), 1e-300, 1e300)
    _check_not_complementary(method, mu, a, b)


@pytest.mark.parametrize("a,b", EDGE_NOT_COMPLEMENTARY)
@pytest.mark.parametrize("method,mu", CASES, ids=CASE_IDS)
def test_nonzero_on_edge_non_complementary_pairs(method, mu, a, b):
    _check_not_complementary(method, mu, np.array([a]), np.array([b]))


@pytest.mark.parametrize("a,b", EDGE_NOT_COMPLEMENTARY_UNDERFLOW)
def test_fb_small_partner_is_not_flushed_to_zero(a, b):
    val = float(ncp.phi_fb(a, b))
    assert val != 0.0 and np.sign(val) == np.sign(b)
    assert val == pytest.approx(_fb_reference(a, b), rel=1e-12, abs=0)


def test_fb_small_partner_other_order_is_fine():
    """The mirrored pairs (|a| ≪ b) are computed correctly — the bug is asymmetric."""
    for a, b in EDGE_NOT_COMPLEMENTARY_UNDERFLOW:
        val = float(ncp.phi_fb(b, a))
        assert val == pytest.approx(_fb_reference(b, a), rel=1e-12, abs=0)


@pytest.mark.parametrize("a,b", [(TINY, TINY), (-TINY, TINY), (TINY, -TINY)])
@pytest.mark.parametrize("method", SIGNED)
def test_nonzero_at_smallest_subnormals(method, a, b):
    """(For blend the weighted sum of two values ~5e-324 may underflow to 0: not tested.)"""
    _check_not_complementary(method, 0.5, np.array([a]), np.array([b]))


@pytest.mark.parametrize("method", SIGNED)
def test_sign_convention_on_edge_pairs(method):
    a = np.array([1.0, 1e-300, HUGE, -1.0, 1.0, -1.0, 0.0, 0.0, 0.0])
    b = np.array([2.0, 1e-300, 1e-10, 5.0, -5.0, -1.0, 0.0, 3.0, -3.0])
    val = ncp.phi(a, b, method)
    np.testing.assert_array_equal(np.sign(val), [1, 1, 1, -1, -1, -1, 0, 0, -1])


# --------------------------------------------------------------------------------------
# accuracy of the (cancellation-free) FB formula
# --------------------------------------------------------------------------------------
def _fb_reference(a: float, b: float) -> float:
    with decimal.localcontext() as ctx:
        ctx.prec = 1400  # enough for |a|/|b| up to 1e600 without cancellation
        ctx.Emin, ctx.Emax = -999999, 999999
        A, B = decimal.Decimal(float(a)), decimal.Decimal(float(b))
        return float(A + B - (A * A + B * B).sqrt())


def test_fb_relative_accuracy():
    rng = np.random.default_rng(4)
    a = _loguniform(rng, 1e-100, 1e100, 400) * rng.choice([-1.0, 1.0], 400)
    b = _loguniform(rng, 1e-100, 1e100, 400) * rng.choice([-1.0, 1.0], 400)
    # include large, nearly equal positive pairs where the naive formula cancels
    a[:50] = _loguniform(rng, 1e3, 1e100, 50)
    b[:50] = a[:50] * rng.uniform(0.5, 2.0, 50)
    val = ncp.phi_fb(a, b)
    ref = np.array([_fb_reference(x, y) for x, y in zip(a, b)])
    np.testing.assert_allclose(val, ref, rtol=1e-14, atol=0)


# --------------------------------------------------------------------------------------
# dphi = ∇φ away from the kinks (central finite differences)
# --------------------------------------------------------------------------------------
def _smooth_points(method, rng, scale, n=300):
    a = rng.uniform(-1.0, 1.0, n) * scale
    b = rng.uniform(-1.0, 1.0, n) * scale
    ok = np.ones(n, bool)
    if method in ("min", "blend"):
        ok &= np.abs(a - b) > 1e-2 * scale
    if method in ("fb", "blend"):
        ok &= np.hypot(a, b) > 1e-1 * scale
    return a[ok], b[ok]


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e4])
@pytest.mark.parametrize("method,mu", CASES, ids=CASE_IDS)
def test_dphi_matches_finite_differences(method, mu, scale):
    a, b = _smooth_points(method, np.random.default_rng(5), scale)
    assert a.size > 100
    h = 1e-6 * scale
    fd_a = (ncp.phi(a + h, b, method, mu) - ncp.phi(a - h, b, method, mu)) / (2 * h)
    fd_b = (ncp.phi(a, b + h, method, mu) - ncp.phi(a, b - h, method, mu)) / (2 * h)
    da, db = ncp.dphi(a, b, method, mu)
    assert da.shape == a.shape and db.shape == b.shape
    np.testing.assert_allclose(da, fd_a, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(db, fd_b, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("method,mu", CASES, ids=CASE_IDS)
def test_dphi_is_lipschitz_bounded(method, mu):
    """Elements of the generalized derivative of these φ lie in [0, 2]² (FB) / {0,1} (min)."""
    rng = np.random.default_rng(6)
    a = _loguniform(rng, 1e-200, 1e200, 2000) * rng.choice([-1.0, 1.0], 2000)
    b = _loguniform(rng, 1e-200, 1e200, 2000) * rng.choice([-1.0, 1.0], 2000)
    da, db = ncp.dphi(a, b, method, mu)
    for d in (da, db):
        assert np.all(np.isfinite(d)) and np.all(d >= 0.0) and np.all(d <= 2.0)
    # ∂_a φ + ∂_b φ ≥ 2 - √2 (FB) resp. = 1 (min): never a vanishing row
    assert np.all(da + db > 0.0)


# --------------------------------------------------------------------------------------
# the chosen elements at the kinks
# --------------------------------------------------------------------------------------
def test_fb_element_at_biactive_point():
    da, db = ncp.dphi(0.0, 0.0, "fb")
    alpha, beta = 1.0 - float(da), 1.0 - float(db)
    assert alpha**2 + beta**2 <= 1.0 + 1e-15  # in ∂φ_FB(0, 0)
    assert float(da) == pytest.approx(1.0 - 1.0 / np.sqrt(2.0), rel=1e-15)
    assert float(db) == pytest.approx(1.0 - 1.0 / np.sqrt(2.0), rel=1e-15)
    # the documented choice is the limit along the diagonal a = b ↓ 0
    for t in (1e-3, 1e-100, 1e-300, 1e-310):
        ta, tb = ncp.dphi(t, t, "fb")
        assert float(ta) == pytest.approx(float(da), rel=1e-12)
        assert float(tb) == pytest.approx(float(db), rel=1e-12)


def test_fb_element_on_diagonal_at_smallest_subnormal():
    da, db = ncp.dphi(TINY, TINY, "fb")
    assert float(da) == pytest.approx(C_FB) and float(db) == pytest.approx(C_FB)


def test_fb_element_at_biactive_point_in_arrays():
    a = np.array([0.0, 1.0, 0.0, -0.0, 2.0])
    b = np.array([0.0, 0.0, 3.0, 0.0, 2.0])
    da, db = ncp.dphi(a, b, "fb")
    np.testing.assert_allclose(da, [C_FB, 0.0, 1.0, C_FB, C_FB], rtol=1e-15, atol=1e-16)
    np.testing.assert_allclose(db, [C_FB, 1.0, 0.0, C_FB, C_FB], rtol=1e-15, atol=1e-16)


def _ties(rng):
    t = np.concatenate(
        [
            [0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300, HUGE, -HUGE],
            _loguniform(rng, 1e-300, 1e300, 200) * rng.choice([-1.0, 1.0], 200),
        ]
    )
    return t


def test_min_element_at_ties():
    t = _ties(np.random.default_rng(7))
    da, db = ncp.dphi(t, t.copy(), "min")
    # an element of the B-subdifferential {(1, 0), (0, 1)} ...
    assert np.all(((da == 1) & (db == 0)) | ((da == 0) & (db == 1)))
    # ... namely the documented one: ties are inactive, except the biactive point (0, 0):
    # a node touching with zero pressure is in contact
    zero = t == 0
    assert zero.sum() == 2 and np.all(da[zero] == 1.0) and np.all(db[zero] == 0.0)
    assert np.all(da[~zero] == 0.0) and np.all(db[~zero] == 1.0)


def test_min_element_off_ties():
    a = np.array([-1.0, 1.0, 0.0, 0.0, 1e-300, -HUGE, 2.0])
    b = np.array([1.0, -1.0, TINY, -TINY, 2e-300, HUGE, 2.0 - 4e-16])
    da, db = ncp.dphi(a, b, "min")
    np.testing.assert_array_equal(da, [1, 0, 1, 0, 1, 1, 0])
    np.testing.assert_array_equal(db, [0, 1, 0, 1, 0, 0, 1])


# ties within a tolerance: the element must not depend on the sign of round-off
ROUNDOFF = [(0.0, 1e-17), (0.0, -1e-17), (1e-17, 0.0), (-1e-17, 0.0), (3e-18, -2e-18), (0.0, 0.0)]


@pytest.mark.parametrize("method,mu", CASES, ids=CASE_IDS)
def test_kinks_within_tolerance_take_the_documented_element(method, mu):
    """Pairs within τ = 1e-12 of a kink (here round-off around (0, 0)) all get the element
    of the exact kink: (0, 0) for FB, the tie for min, their blend — whatever the signs."""
    a, b = np.array(ROUNDOFF).T
    da, db = ncp.dphi(a, b, method, mu, tol=1e-12)
    want = ncp.dphi(0.0, 0.0, method, mu)
    np.testing.assert_array_equal(da, np.full(len(a), float(want[0])))
    np.testing.assert_array_equal(db, np.full(len(a), float(want[1])))
    assert ncp.active_min(a, b, tol=1e-12).all()  # all at the biactive point: in contact
    # without the tolerance the signs decide: (0, +1e-17) is active, (0, -1e-17) is not
    assert list(ncp.active_min(a[:2], b[:2])) == [True, False]
    if method == "fb":
        np.testing.assert_allclose(ncp.dphi(a[:2], b[:2], "fb")[1], [0.0, 2.0])


@pytest.mark.parametrize("method,mu", CASES, ids=CASE_IDS)
def test_tolerance_leaves_resolved_pairs_alone(method, mu):
    rng = np.random.default_rng(11)
    a, b = rng.normal(size=400), rng.normal(size=400)
    keep = (np.hypot(a, b) > 1e-6) & (np.abs(a - b) > 1e-6)
    exact, tolerant = ncp.dphi(a, b, method, mu), ncp.dphi(a, b, method, mu, tol=1e-12)
    np.testing.assert_array_equal(exact[0][keep], tolerant[0][keep])
    np.testing.assert_array_equal(exact[1][keep], tolerant[1][keep])


@pytest.mark.parametrize("mu", MUS)
def test_blend_element_at_kinks(mu):
    t = _ties(np.random.default_rng(8))
    # FB is smooth on the diagonal off the origin: ∇φ_FB(t, t) = (1 - sign(t)/√2) · (1, 1)
    fb_elem = np.where(t < 0, 2.0 - C_FB, C_FB)
    min_a = (t == 0).astype(float)  # min's element: (0, 1) at ties, (1, 0) at (0, 0)
    da, db = ncp.dphi(t, t.copy(), "blend", mu)
    np.testing.assert_allclose(da, (1 - mu) * fb_elem + mu * min_a, rtol=1e-14)
    np.testing.assert_allclose(db, (1 - mu) * fb_elem + mu * (1.0 - min_a), rtol=1e-14)
    # at (0, 0) in particular
    da0, db0 = ncp.dphi(0.0, 0.0, "blend", mu)
    assert float(da0) == pytest.approx((1 - mu) * C_FB + mu, rel=1e-14)
    assert float(db0) == pytest.approx((1 - mu) * C_FB, rel=1e-14)


@pytest.mark.parametrize("mu", MUS)
def test_blend_is_convex_combination(mu):
    rng = np.random.default_rng(9)
    a, b = rng.normal(size=500), rng.normal(size=500)
    a[:20] = b[:20]
    a[20:25] = b[20:25] = 0.0
    np.testing.assert_allclose(
        ncp.phi(a, b, "blend", mu), (1 - mu) * ncp.phi_fb(a, b) + mu * np.minimum(a, b), rtol=1e-14
    )
    da, db = ncp.dphi(a, b, "blend", mu)
    fa, fb_ = ncp.dphi_fb(a, b)
    biactive = (a == 0) & (b == 0)  # min's element there: (1, 0)
    ma, mb = ((a < b) | biactive).astype(float), ((a >= b) & ~biactive).astype(float)
    np.testing.assert_allclose(da, (1 - mu) * fa + mu * ma, rtol=1e-14)
    np.testing.assert_allclose(db, (1 - mu) * fb_ + mu * mb, rtol=1e-14)


def test_blend_default_mu_is_one_half():
    a, b = np.array([1.0, -2.0, 0.5]), np.array([3.0, 1.0, 0.5])
    np.testing.assert_allclose(
        ncp.phi(a, b, "blend"), 0.5 * ncp.phi_fb(a, b) + 0.5 * np.minimum(a, b)
    )


# --------------------------------------------------------------------------------------
# unknown method names
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["", "FB", "Min", "fischer", "blend ", "nr", None])
@pytest.mark.parametrize("func", ["phi", "dphi", "phi_ufl"])
def test_unknown_method_raises(func, name):
    with pytest.raises(ValueError, match="unknown NCP function"):
        getattr(ncp, func)(1.0, 2.0, name)


def test_methods_constant():
    assert set(ncp.METHODS) == {"fb", "min", "blend"}


# --------------------------------------------------------------------------------------
# the UFL version agrees with the NumPy one
# --------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def dg0_pair():
    from dolfinx import fem, mesh
    from mpi4py import MPI

    msh = mesh.create_unit_square(MPI.COMM_SELF, 8, 8)
    V = fem.functionspace(msh, ("DG", 0))
    n = V.dofmap.index_map.size_local
    rng = np.random.default_rng(10)
    a_val = rng.normal(size=n) * 10.0 ** rng.integers(-3, 4, n)
    b_val = rng.normal(size=n) * 10.0 ** rng.integers(-3, 4, n)
    # complementary pairs, (0, 0), ties, a sign pattern of each kind
    special = [
        (0.0, 0.0),
        (0.0, 2.0),
        (3.0, 0.0),
        (0.0, 1e-8),
        (1.5, 1.5),
        (-1.5, -1.5),
        (-1.0, 0.0),
        (0.0, -1.0),
        (1.0, 2.0),
        (-1.0, 2.0),
        (1.0, -2.0),
        (1e3, 1e3 + 1),
    ]
    for i, (x, y) in enumerate(special):
        a_val[i], b_val[i] = x, y
    a, b = fem.Function(V), fem.Function(V)
    a.x.array[:n] = a_val
    b.x.array[:n] = b_val
    a.x.scatter_forward()
    b.x.scatter_forward()
    cells = np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)
    dofs = np.array([V.dofmap.cell_dofs(c)[0] for c in cells])
    return msh, a, b, cells, a.x.array[dofs].copy(), b.x.array[dofs].copy(), len(special)


@pytest.mark.parametrize("method,mu", CASES, ids=CASE_IDS)
def test_phi_ufl_agrees_with_numpy(dg0_pair, method, mu):
    from dolfinx import fem

    msh, a, b, cells, a_c, b_c, n_special = dg0_pair
    points = np.array([[1.0 / 3.0, 1.0 / 3.0]])
    expr = fem.Expression(ncp.phi_ufl(a, b, method, mu), points)
    got = expr.eval(msh, cells).reshape(len(cells), -1)[:, 0]
    want = ncp.phi(a_c, b_c, method, mu)
    # phi_ufl uses the naive a + b - √(a² + b²) (error ~ ε·max(|a|, |b|)), phi the stable form
    scale = np.maximum(np.abs(a_c), np.abs(b_c))
    assert np.all(np.abs(got - want) <= 1e-14 * scale), np.max(np.abs(got - want) / scale)
    # exactly zero on the complementary pairs, nonzero elsewhere in the special set
    comp = (a_c >= 0) & (b_c >= 0) & (a_c * b_c == 0)
    assert comp[:n_special].sum() == 4
    assert np.all(got[comp] == 0.0)
    assert np.all(got[~comp] != 0.0)


def test_phi_ufl_blend_with_constant_mu(dg0_pair):
    """μ may also be a UFL Constant (one compiled kernel for every μ)."""
    from dolfinx import fem

    msh, a, b, cells, a_c, b_c, _ = dg0_pair
    mu = fem.Constant(msh, 0.0)
    expr = fem.Expression(ncp.phi_ufl(a, b, "blend", mu), np.array([[0.25, 0.25]]))
    for value in MUS:
        mu.value = value
        got = expr.eval(msh, cells).reshape(len(cells), -1)[:, 0]
        want = ncp.phi(a_c, b_c, "blend", value)
        assert np.all(np.abs(got - want) <= 1e-14 * np.maximum(np.abs(a_c), np.abs(b_c)))
        assert not np.allclose(got, ncp.phi(a_c, b_c, "blend", 0.5)) or value == 0.5
