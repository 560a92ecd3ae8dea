"""Tests of the safe scene-data expressions (contact.base.expressions)."""

from __future__ import annotations

import math

import contact  # noqa: F401  (sets up dolfinx_solver before dolfinx is imported)
from contact.base import expressions as E
from contact.base.expressions import ExpressionError

import numpy as np
import pytest

CONSTS = {"k": 2.5, "L": 3.0, "alpha_1": -0.75}


def _points(n=60, seed=0):
    """(3, n) points in [-2, 2]³, away from the axes (y ≠ 0 keeps θ off its branch cut)."""
    rng = np.random.default_rng(seed)
    X = rng.uniform(-2.0, 2.0, (3, n))
    X[1] = np.where(np.abs(X[1]) < 0.05, 0.3, X[1])
    X[:, 0] = [1.0, 2.0, -0.5]  # a few fixed, human-checkable points
    X[:, 1] = [-1.0, 0.5, 1.5]
    return X


def _hyp(x, y):
    return np.sqrt(x * x + y * y)


# (expression, reference f(x, y, z)) — every name, operator and function of the grammar
NUMERIC = [
    ("x", lambda x, y, z: x),
    ("y", lambda x, y, z: y),
    ("z", lambda x, y, z: z),
    ("r", lambda x, y, z: _hyp(x, y)),
    ("theta", lambda x, y, z: np.arctan2(y, x)),
    ("pi", lambda x, y, z: np.full_like(x, math.pi)),
    ("e", lambda x, y, z: np.full_like(x, math.e)),
    ("2*pi*x - e", lambda x, y, z: 2 * math.pi * x - math.e),
    ("k*x + L", lambda x, y, z: 2.5 * x + 3.0),
    ("alpha_1*y**2", lambda x, y, z: -0.75 * y**2),
    ("x + y - z", lambda x, y, z: x + y - z),
    ("x*y/(1 + z*z)", lambda x, y, z: x * y / (1 + z * z)),
    ("-x**2", lambda x, y, z: -(x**2)),
    ("+x - -y", lambda x, y, z: x + y),
    ("2**3**0.5", lambda x, y, z: np.full_like(x, 2**3**0.5)),
    ("(1 + x)**2 - 1e-3", lambda x, y, z: (1 + x) ** 2 - 1e-3),
    (
        "-r**1.5*cos(1.5*theta)",
        lambda x, y, z: -(_hyp(x, y) ** 1.5) * np.cos(1.5 * np.arctan2(y, x)),
    ),
    ("sin(x)", lambda x, y, z: np.sin(x)),
    ("cos(y)", lambda x, y, z: np.cos(y)),
    ("tan(0.5*x)", lambda x, y, z: np.tan(0.5 * x)),
    ("exp(-x*x)", lambda x, y, z: np.exp(-x * x)),
    ("log(1 + x*x)", lambda x, y, z: np.log(1 + x * x)),
    ("sqrt(1 + y*y)", lambda x, y, z: np.sqrt(1 + y * y)),
    ("atan2(y, x)", lambda x, y, z: np.arctan2(y, x)),
    ("atan2(x, y)", lambda x, y, z: np.arctan2(x, y)),
    ("abs(x - y)", lambda x, y, z: np.abs(x - y)),
    ("min(x, y)", lambda x, y, z: np.minimum(x, y)),
    ("max(x, y)", lambda x, y, z: np.maximum(x, y)),
    ("min(max(x, -0.5), 0.5)", lambda x, y, z: np.clip(x, -0.5, 0.5)),
    ("sinh(x)", lambda x, y, z: np.sinh(x)),
    ("cosh(y)", lambda x, y, z: np.cosh(y)),
    ("tanh(3*x)", lambda x, y, z: np.tanh(3 * x)),
    ("asinh(5*x)", lambda x, y, z: np.arcsinh(5 * x)),
    ("1 if x < y else 0", lambda x, y, z: np.where(x < y, 1.0, 0.0)),
    ("1 if x <= y else 0", lambda x, y, z: np.where(x <= y, 1.0, 0.0)),
    ("x if x > 0 else -2*x", lambda x, y, z: np.where(x > 0, x, -2 * x)),
    ("y if x >= 0.5 else z", lambda x, y, z: np.where(x >= 0.5, y, z)),
    ("1 if -0.5 < x < 0.5 else 2", lambda x, y, z: np.where((-0.5 < x) & (x < 0.5), 1.0, 2.0)),
    ("1 if x > 0 and y > 0 else 0", lambda x, y, z: np.where((x > 0) & (y > 0), 1.0, 0.0)),
    ("1 if x > 0 or y > 0 else 0", lambda x, y, z: np.where((x > 0) | (y > 0), 1.0, 0.0)),
    ("1 if not x > 0 else 0", lambda x, y, z: np.where(~(x > 0), 1.0, 0.0)),
    (
        "1 if x > 0 and y > 0 and z > 0 else 0",
        lambda x, y, z: np.where((x > 0) & (y > 0) & (z > 0), 1.0, 0.0),
    ),
    (
        "1 if x > 1 or y > 1 or z > 1 else 0",
        lambda x, y, z: np.where((x > 1) | (y > 1) | (z > 1), 1.0, 0.0),
    ),
    (
        "1 if not (x > 0 and y < 0) or z > 1 else 0",
        lambda x, y, z: np.where(~((x > 0) & (y < 0)) | (z > 1), 1.0, 0.0),
    ),
    (
        "(x if y > 0 else y) if z < 0 else (0 if x < y else 1)",
        lambda x, y, z: np.where(z < 0, np.where(y > 0, x, y), np.where(x < y, 0.0, 1.0)),
    ),
]
NUMERIC_IDS = [t for t, _ in NUMERIC]


@pytest.mark.parametrize("text,ref", NUMERIC, ids=NUMERIC_IDS)
def test_to_numpy(text, ref):
    X = _points()
    val = E.to_numpy(text, CONSTS)(X)
    assert isinstance(val, np.ndarray) and val.shape == (X.shape[1],) and val.dtype == float
    np.testing.assert_allclose(val, ref(*X), rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize(
    "text,want",
    [
        ("x", [1.0, -1.0]),
        ("y", [2.0, 0.5]),
        ("z", [-0.5, 1.5]),
        ("r", [np.sqrt(5), np.sqrt(1.25)]),
        ("theta", [np.arctan2(2, 1), np.pi - np.arctan(0.5)]),
        ("x*y*z", [-1.0, -0.75]),
        ("k", [2.5, 2.5]),
        ("1 if x > 0 else 7", [1.0, 7.0]),
        ("max(x, y) - min(y, z)", [2.5, 0.0]),
    ],
)
def test_to_numpy_by_hand(text, want):
    X = np.array([[1.0, -1.0], [2.0, 0.5], [-0.5, 1.5]])
    np.testing.assert_allclose(E.to_numpy(text, CONSTS)(X), want, rtol=1e-15)


def test_theta_range():
    X = np.array([[1.0, 0.0, -1.0, 0.0, -1.0], [0.0, 1.0, 0.0, -1.0, -1e-300], [0.0] * 5])
    np.testing.assert_allclose(E.to_numpy("theta")(X), [0.0, np.pi / 2, np.pi, -np.pi / 2, -np.pi])


@pytest.mark.parametrize(
    "text",
    [
        "x < y",
        "x <= y",
        "x > y",
        "x >= y",
        "-1 < x < y",
        "x > 0 and y > 0",
        "x > 0 or y > 0",
        "not x > 0",
    ],
)
def test_to_numpy_boolean_value_is_zero_one(text):
    X = _points()
    val = E.to_numpy(text)(X)
    assert val.dtype == float
    assert set(np.unique(val)) == {0.0, 1.0}


def test_to_numpy_comparisons_exact():
    X = np.array([[0.0, 1.0, 2.0], [1.0, 1.0, 1.0], [0.0, 0.0, 0.0]])
    np.testing.assert_array_equal(E.to_numpy("x < y")(X), [1, 0, 0])
    np.testing.assert_array_equal(E.to_numpy("x <= y")(X), [1, 1, 0])
    np.testing.assert_array_equal(E.to_numpy("x > y")(X), [0, 0, 1])
    np.testing.assert_array_equal(E.to_numpy("x >= y")(X), [0, 1, 1])
    np.testing.assert_array_equal(E.to_numpy("0 < x < 2")(X), [0, 1, 0])
    np.testing.assert_array_equal(E.to_numpy("5 if x < y else -5")(X), [5, -5, -5])


@pytest.mark.parametrize("value", [3, -2, 2.5, 1e-20, "7", " 4.5 ", "2*pi", "k*L"])
def test_to_numpy_constant_expressions_broadcast(value):
    X = _points(n=7)
    val = E.to_numpy(value, CONSTS)(X)
    want = {"2*pi": 2 * math.pi, "k*L": 7.5}.get(value, None)
    want = float(value) if want is None else want
    assert val.shape == (7,)
    np.testing.assert_allclose(val, want, rtol=1e-15)
    # the returned array is writable and not shared between calls
    val[0] = 123.0
    assert E.to_numpy(value, CONSTS)(X)[0] == pytest.approx(want)


def test_to_numpy_two_dimensional_points_have_z_zero():
    X = np.array([[1.0, 2.0], [3.0, 4.0]])
    np.testing.assert_allclose(E.to_numpy("x + 10*y + 100*z + 1")(X), [32.0, 43.0])


def test_to_numpy_user_constant_overrides_builtin():
    X = _points(n=3)
    np.testing.assert_allclose(E.to_numpy("e*x", {"e": 2.0})(X), 2.0 * X[0])


def test_to_numpy_domain_errors_give_nan_inf_not_exceptions():
    X = np.array([[-1.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    val = E.to_numpy("log(x + 1)")(X)
    assert np.isnan(val[0]) or np.isinf(val[0])
    assert np.isinf(E.to_numpy("1/x")(X)[1])
    assert np.isnan(E.to_numpy("sqrt(x)")(X)[0])


# --------------------------------------------------------------------------------------
# to_ufl agrees with to_numpy
# --------------------------------------------------------------------------------------
REF_POINTS_2D = np.array([[0.2113, 0.1057], [0.6123, 0.2718], [0.1311, 0.7204], [0.3017, 0.4471]])
REF_POINTS_3D = np.array([[0.2113, 0.1057, 0.3141], [0.1, 0.6, 0.2], [0.25, 0.25, 0.25]])


def _ufl_vs_numpy(msh, ref_points, texts, constants):
    """Evaluate every text with to_ufl (one compiled kernel) and to_numpy at the same points."""
    import ufl
    from dolfinx import fem

    cells = np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)
    gdim = msh.geometry.dim
    vec = ufl.as_vector([E.to_ufl(t, msh, constants) for t in texts])
    got = (
        fem.Expression(vec, ref_points)
        .eval(msh, cells)
        .reshape(len(cells), len(ref_points), len(texts))
    )
    xs = fem.Expression(ufl.SpatialCoordinate(msh), ref_points).eval(msh, cells)
    xs = xs.reshape(len(cells) * len(ref_points), gdim).T
    X = np.vstack([xs, np.zeros((3 - gdim, xs.shape[1]))])
    got = got.reshape(-1, len(texts)).T
    want = np.array([E.to_numpy(t, constants)(X) for t in texts])
    return got, want, X


# expressions whose value is a number (a bare comparison/and/or/not is a UFL condition)
UFL_TEXTS = [t for t, _ in NUMERIC] + [
    "3",
    "k",
    "2.5*k - L",
    "1 if 0 < 1 else 2",
    "min(1, k)",
    "abs(-2)",
    "sin(pi/4)",
    "asinh(-30*x)",
]


@pytest.fixture(scope="module")
def mesh2d():
    from dolfinx import mesh
    from mpi4py import MPI

    # not symmetric about the axes, contains the origin, no dof/point on y = 0
    return mesh.create_rectangle(MPI.COMM_SELF, [[-1.3, -0.7], [1.1, 1.4]], [5, 4])


@pytest.fixture(scope="module")
def mesh3d():
    from dolfinx import mesh
    from mpi4py import MPI

    return mesh.create_box(MPI.COMM_SELF, [[-1.1, -0.7, -0.9], [0.8, 1.2, 1.3]], [2, 2, 2])


def test_to_ufl_agrees_with_to_numpy_2d(mesh2d):
    got, want, X = _ufl_vs_numpy(mesh2d, REF_POINTS_2D, UFL_TEXTS, CONSTS)
    assert np.all(np.abs(X[1]) > 1e-8) and X.shape[1] > 100
    for text, g, w in zip(UFL_TEXTS, got, want):
        np.testing.assert_allclose(g, w, rtol=1e-11, atol=1e-12, err_msg=text)


def test_to_ufl_agrees_with_to_numpy_3d(mesh3d):
    texts = [
        "z",
        "x*y*z",
        "r + z",
        "sin(x)*cos(y)*exp(z)",
        "1 if z > 0 and x < y else -1",
        "theta*z",
        "k*z**2",
        "min(z, x) + max(y, z)",
    ]
    got, want, X = _ufl_vs_numpy(mesh3d, REF_POINTS_3D, texts, CONSTS)
    assert np.ptp(X[2]) > 1.0
    for text, g, w in zip(texts, got, want):
        np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-13, err_msg=text)


def test_to_ufl_interpolated_into_p2_matches_to_numpy_at_dofs(mesh2d):
    from dolfinx import fem

    V = fem.functionspace(mesh2d, ("Lagrange", 2))
    text = "k*x*y - sin(3*x) + (y if x > 0.1 else 0.5*y**2)"
    u_ufl, u_np = fem.Function(V), fem.Function(V)
    u_ufl.interpolate(
        fem.Expression(E.to_ufl(text, mesh2d, CONSTS), V.element.interpolation_points)
    )
    u_np.interpolate(E.to_numpy(text, CONSTS))
    np.testing.assert_allclose(u_ufl.x.array, u_np.x.array, rtol=1e-12, atol=1e-13)
    x = V.tabulate_dof_coordinates().T
    np.testing.assert_allclose(u_np.x.array, E.to_numpy(text, CONSTS)(x), rtol=1e-14, atol=1e-14)


def test_to_ufl_condition_used_as_a_number_is_one_or_zero(mesh2d):
    """``2*(x > 0.5) - 1`` is a step of ±1 in both back ends, also inside an assembled form
    (UFL's degree estimation had no degree for a bare condition: an internal error)."""
    import ufl
    from dolfinx import fem
    from mpi4py import MPI

    texts = ["2*(x > 0.1) - 1", "-(y < 0.2)", "sin(x > 0) + (x < y)*x", "(x > 0) if y > 0 else 0.5"]
    got, want, _ = _ufl_vs_numpy(mesh2d, REF_POINTS_2D, texts, {})
    for text, g, w in zip(texts, got, want):
        np.testing.assert_allclose(g, w, rtol=1e-14, atol=1e-14, err_msg=text)
    assert set(np.unique(want[0])) == {-1.0, 1.0}
    # ∫ (2·[x > 0] − 1) dx over [-1, 0.5] × [0, 1], x = 0 a mesh line: 0.5 − 1 exactly
    from dolfinx import mesh

    msh = mesh.create_rectangle(MPI.COMM_SELF, [[-1.0, 0.0], [0.5, 1.0]], [6, 2])
    step = fem.assemble_scalar(fem.form(E.to_ufl("2*(x > 0) - 1", msh) * ufl.dx(domain=msh)))
    assert abs(step - (0.5 - 1.0)) < 1e-13


def test_to_ufl_z_is_zero_on_2d_mesh(mesh2d):
    got, want, X = _ufl_vs_numpy(mesh2d, REF_POINTS_2D, ["z", "x + z"], {})
    assert np.all(got[0] == 0.0)
    np.testing.assert_allclose(got[1], X[0], rtol=1e-14)


def test_to_ufl_is_ufl_expression(mesh2d):
    import ufl

    for text in ["x", 3, "pi", "k"]:
        assert isinstance(E.to_ufl(text, mesh2d, CONSTS), ufl.core.expr.Expr)


def test_to_ufl_asinh_large_negative_argument(mesh2d):
    got, want, _ = _ufl_vs_numpy(mesh2d, REF_POINTS_2D, ["asinh(-1e8*(x + 2))"], {})
    np.testing.assert_allclose(got[0], want[0], rtol=1e-10)


# --------------------------------------------------------------------------------------
# is_constant
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "text,expected",
    [
        ("1", True),
        (2.5, True),
        (0, True),
        ("2*pi", True),
        ("e**2", True),
        ("k*L", True),
        ("sin(pi/4) + sqrt(2)", True),
        ("1 if k > 2 else 0", True),
        ("max(k, L)", True),
        ("x", False),
        ("y", False),
        ("z", False),
        ("r", False),
        ("theta", False),
        ("0*x", False),
        ("x - x", False),
        ("k*y", False),
        ("1 if z > 0 else 1", False),
        ("sin(atan2(y, 1))", False),
        ("max(k, r)", False),
    ],
)
def test_is_constant(text, expected):
    assert E.is_constant(text, CONSTS) is expected


def test_is_constant_validates():
    with pytest.raises(ExpressionError):
        E.is_constant("x.real")
    with pytest.raises(ExpressionError, match="unknown name"):
        E.is_constant("k*2")  # k is only known when passed as a constant


# --------------------------------------------------------------------------------------
# everything outside the grammar is rejected with a message
# --------------------------------------------------------------------------------------
BAD = [
    # attribute access
    ("x.real", "attribute is not allowed"),
    ("(1).__class__", "attribute is not allowed"),
    ("np.sin(x)", r"only the functions .* may be called"),
    ("math.pi", "attribute is not allowed"),
    # subscripts, slices, containers
    ("x[0]", "subscript is not allowed"),
    ("x[0:1]", "is not allowed"),
    ("[1, 2]", "list is not allowed"),
    ("(1, 2)", "tuple is not allowed"),
    ("{1: 2}", "dict is not allowed"),
    ("{1, 2}", "set is not allowed"),
    # lambdas and comprehensions
    ("lambda: 1", "lambda is not allowed"),
    ("(lambda t: t)(x)", r"only the functions .* may be called"),
    ("[t for t in (1, 2)]", "listcomp is not allowed"),
    ("(t for t in (1, 2))", "generatorexp is not allowed"),
    ("{t for t in (1, 2)}", "setcomp is not allowed"),
    ("{t: t for t in (1, 2)}", "dictcomp is not allowed"),
    ("sum(t for t in (1, 2))", r"only the functions"),
    # unknown names and functions
    ("foo", "unknown name 'foo'"),
    ("x + w", "unknown name 'w'"),
    ("Pi", "unknown name 'Pi'"),
    ("inf", "unknown name 'inf'"),
    ("nan", "unknown name 'nan'"),
    ("__builtins__", "unknown name '__builtins__'"),
    ("floor(x)", r"only the functions sin, cos, .* may be called"),
    ("acos(x)", r"only the functions"),
    ("eval('1')", r"only the functions"),
    ("exec('1')", r"only the functions"),
    ("open('f')", r"only the functions"),
    ("k(x)", r"only the functions"),
    ("x(1)", r"only the functions"),
    ("sin(x)(y)", r"only the functions"),
    # __import__
    ("__import__('os')", r"only the functions"),
    ("__import__('os').system('true')", r"only the functions|attribute is not allowed"),
    # keyword arguments, unpacking
    ("sin(x=1)", "keyword arguments are not allowed"),
    ("atan2(y, x=x)", "keyword arguments are not allowed"),
    ("max(x, y, key=1)", "keyword arguments are not allowed"),
    ("sin(**k)", "keyword arguments are not allowed"),
    ("sin(*x)", "starred is not allowed"),
    # wrong arity
    ("sin()", r"sin\(\) takes 1 argument"),
    ("sin(x, y)", r"sin\(\) takes 1 argument"),
    ("sqrt(x, 2)", r"sqrt\(\) takes 1 argument"),
    ("atan2(y)", r"atan2\(\) takes 2 argument"),
    ("atan2(x, y, z)", r"atan2\(\) takes 2 argument"),
    ("min(x)", r"min\(\) takes 2 argument"),
    ("max(x, y, z)", r"max\(\) takes 2 argument"),
    ("abs()", r"abs\(\) takes 1 argument"),
    # strings, bytes, booleans, other constants
    ("'abc'", "constant 'abc' is not a number"),
    ("x + 'a'", "constant 'a' is not a number"),
    ("b'x'", "is not a number"),
    ("f'{x}'", "is not allowed"),
    ("True", "constant True is not a number"),
    ("x + False", "constant False is not a number"),
    ("1 if True else 0", "constant True is not a number"),
    ("None", "constant None is not a number"),
    ("...", "constant Ellipsis is not a number"),
    ("1j", "constant 1j is not a number"),
    ("x*2j", "is not a number"),
    # operators outside the grammar
    ("x == y", "eq is not allowed"),
    ("x != y", "noteq is not allowed"),
    ("x is y", "is is not allowed"),
    ("x in y", "in is not allowed"),
    ("x // y", "floordiv is not allowed"),
    ("x % y", "mod is not allowed"),
    ("x @ y", "matmult is not allowed"),
    ("x & y", "bitand is not allowed"),
    ("x | y", "bitor is not allowed"),
    ("x ^ y", "bitxor is not allowed"),
    ("x << 1", "lshift is not allowed"),
    ("~x", "invert is not allowed"),
    ("(t := 1)", "namedexpr is not allowed"),
    # empty input and syntax errors
    ("", "empty expression"),
    ("   ", "empty expression"),
    ("\n\t", "empty expression"),
    ("x +", "cannot parse"),
    ("(x", "cannot parse"),
    ("x y", "cannot parse"),
    ("1 +* 2", "cannot parse"),
    ("x = 1", "cannot parse"),
    ("import os", "cannot parse"),
    ("x; y", "cannot parse"),
    ("x if y", "cannot parse"),
    ("sin(x", "cannot parse"),
    ("1..2", "cannot parse"),
    ("x\ny", "cannot parse"),
]


@pytest.mark.parametrize("text,message", BAD, ids=[repr(t) for t, _ in BAD])
def test_disallowed_constructs_raise(text, message):
    with pytest.raises(ExpressionError, match=message) as info:
        E.parse(text, CONSTS)
    assert str(info.value)  # a non-empty message
    # every public entry point validates before doing anything
    for func in (E.to_numpy, E.is_constant):
        with pytest.raises(ExpressionError, match=message):
            func(text, CONSTS)


@pytest.mark.parametrize(
    "text", ["x.real", "__import__('os')", "foo", "sin(x, y)", "'a'", "", "x +"]
)
def test_to_ufl_rejects_like_parse(mesh2d, text):
    with pytest.raises(ExpressionError):
        E.to_ufl(text, mesh2d, CONSTS)


@pytest.mark.parametrize(
    "value,message",
    [
        (True, "got bool"),
        (False, "got bool"),
        (None, "got NoneType"),
        ([1.0], "got list"),
        (b"x", "got bytes"),
        (1j, "got complex"),
        ({"x": 1}, "got dict"),
    ],
)
def test_non_string_non_number_inputs_raise(value, message):
    with pytest.raises(
        ExpressionError, match=f"expected an expression string or a number, {message}"
    ):
        E.parse(value)
    with pytest.raises(ExpressionError):
        E.to_numpy(value)


def test_expression_error_is_a_value_error():
    assert issubclass(ExpressionError, ValueError)


def test_constants_are_only_known_when_passed():
    with pytest.raises(ExpressionError, match="unknown name 'k'"):
        E.to_numpy("k*x")
    E.parse("k*x", {"k": 1.0})  # fine with the constant


def test_bare_function_name_is_rejected_when_translated(mesh2d):
    X = _points(n=3)
    with pytest.raises(ExpressionError, match="'sin'"):
        E.to_numpy("sin + 1")(X)
    with pytest.raises(ExpressionError, match="'max'"):
        E.to_ufl("max", mesh2d)


def test_bare_function_name_is_rejected_by_parse():
    with pytest.raises(ExpressionError):
        E.parse("sin + 1")


def test_never_evaluates_python(tmp_path, monkeypatch):
    """Nothing reaches eval: a would-be side effect is rejected and leaves no trace."""
    target = tmp_path / "pwned"
    text = f"__import__('pathlib').Path({str(target)!r}).touch()"
    with pytest.raises(ExpressionError):
        E.to_numpy(text)(_points(n=2))
    assert not target.exists()
