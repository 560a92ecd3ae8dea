"""Safe expressions in x, y, z for scene data (docs/theory.md §1: f, u_D, t, g, ψ, t_C, k, exact).

A scene writes its data as strings such as ``"-r**1.5*cos(1.5*theta)"``.  They are parsed
with :mod:`ast` and checked against a whitelist; nothing is ever passed to ``eval``.
A checked expression is then *translated* to one of two back ends:

* :func:`to_ufl` gives a UFL expression in ``ufl.SpatialCoordinate(mesh)``, used inside
  forms (exact up to quadrature);
* :func:`to_numpy` gives a vectorised ``callable(x) -> ndarray`` with ``x`` of shape
  ``(3, n)``, used for interpolation into finite element spaces (the DOLFINx convention).

Grammar: numbers, the names ``x y z r theta t pi e`` and user constants, ``+ - * / **``,
unary ``-``/``+``, comparisons ``< <= > >=``, ``and``/``or``/``not``, the conditional
``a if cond else b``, and the functions ``sin cos tan exp log sqrt atan2 abs min max
sinh cosh tanh asinh``; a comparison used as a number (``2*(x > 0.5) - 1``) is 1 or 0.
``r = sqrt(x² + y²)`` and ``theta = atan2(y, x) ∈ (-π, π]``
are polar helpers about the origin.  ``t`` is the pseudo-time of a quasi-static load path
(``load:`` section; t = 1 at the end of the path and for a scene without one): the back
ends take its value (a number, or a UFL object such as a ``fem.Constant`` so that a form
is compiled once for all steps) as the keyword ``t``.  It is a reserved name, never a
user constant.

Limits (hostile or mistaken input fails in one line instead of exhausting the stack or
the memory): at most :data:`MAX_LENGTH` characters and :data:`MAX_DEPTH` levels of
nesting of the syntax tree (``x+x+…+x`` with n terms nests n levels).  Every constant
subexpression is evaluated once when parsing, in floating point: one that cannot be
evaluated (``1/0``, ``log(-1)``), overflows (``2**10000``), is complex (``(-1)**0.5``,
``(-8)**(1/3)``) or not finite is an error naming it.  Data that depend on x, y, z are
checked on the mesh where they are used (:mod:`contact.setup.checks`).
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable, Mapping
from typing import Any, cast

import numpy as np

FUNCTIONS = (
    "sin",
    "cos",
    "tan",
    "exp",
    "log",
    "sqrt",
    "atan2",
    "abs",
    "min",
    "max",
    "sinh",
    "cosh",
    "tanh",
    "asinh",
)
_ARITY = {"atan2": 2, "min": 2, "max": 2}
COORDINATES = ("x", "y", "z")
HELPERS = ("r", "theta")
TIME = "t"  # the pseudo-time of a load path
BUILTIN_CONSTANTS = {"pi": math.pi, "e": math.e}
MAX_LENGTH = 10_000  # characters of one expression
MAX_DEPTH = 100  # nesting levels of its syntax tree


class ExpressionError(ValueError):
    """An expression that is not in the whitelisted grammar."""


def parse(text: str | int | float, constants: Mapping[str, float] = {}) -> ast.Expression:
    """Parse and validate ``text``; raise :class:`ExpressionError` naming the problem."""
    if isinstance(text, bool) or not isinstance(text, (str, int, float)):
        raise ExpressionError(
            f"expected an expression string or a number, got {type(text).__name__}"
        )
    source = str(text).strip()
    if not source:
        raise ExpressionError("empty expression")
    if len(source) > MAX_LENGTH:
        raise ExpressionError(
            f"the expression has {len(source)} characters, more than the limit of {MAX_LENGTH}"
        )
    shown = source if len(source) <= 80 else source[:60] + "…"  # in messages
    try:
        tree = ast.parse(source, mode="eval")
    except SyntaxError as err:
        raise ExpressionError(f"cannot parse {shown!r}: {err.msg}") from None
    except (RecursionError, MemoryError) as err:
        raise ExpressionError(
            f"cannot parse {shown!r}: nested too deeply ({type(err).__name__})"
        ) from None
    except ValueError as err:
        raise ExpressionError(f"cannot parse {shown!r}: {err}") from None
    if (depth := _depth(tree)) > MAX_DEPTH:
        raise ExpressionError(
            f"the expression nests {depth} levels deep, more than the limit of {MAX_DEPTH}"
        )
    names = set(COORDINATES) | set(HELPERS) | {TIME} | set(BUILTIN_CONSTANTS) | set(constants)
    called = {id(n.func) for n in ast.walk(tree) if isinstance(n, ast.Call)}
    for node in ast.walk(tree):
        _check_node(node, names, shown)
        if (
            isinstance(node, ast.Name)
            and node.id in FUNCTIONS
            and node.id not in names
            and id(node) not in called
        ):
            raise ExpressionError(f"{node.id!r} is a function, call it with arguments in {shown!r}")
    _fold(tree.body, {**BUILTIN_CONSTANTS, **constants}, shown)
    return tree


def _depth(tree: ast.AST) -> int:
    """Nesting depth of a syntax tree (iterative: safe for any depth)."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, d = stack.pop()
        deepest = max(deepest, d)
        stack.extend((child, d + 1) for child in ast.iter_child_nodes(node))
    return deepest


_MATH: dict[str, Callable[..., float]] = {
    "sin": math.sin,
    "cos": math.cos,
    "tan": math.tan,
    "exp": math.exp,
    "log": math.log,
    "sqrt": math.sqrt,
    "atan2": math.atan2,
    "abs": abs,
    "min": min,
    "max": max,
    "sinh": math.sinh,
    "cosh": math.cosh,
    "tanh": math.tanh,
    "asinh": math.asinh,
}
_FLOAT_OPS = {
    ast.Add: lambda a, b: a + b,
    ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b,
    ast.Pow: lambda a, b: a**b,
    ast.Lt: lambda a, b: a < b,
    ast.LtE: lambda a, b: a <= b,
    ast.Gt: lambda a, b: a > b,
    ast.GtE: lambda a, b: a >= b,
}


def _fold(node: ast.AST, values: Mapping[str, float], source: str) -> float | None:
    """The value of ``node`` if it is constant (no coordinate in it), else None; raise
    ExpressionError for a constant subexpression without a finite real value."""
    if isinstance(node, ast.Constant):
        value = cast(float, node.value)  # _check_tree admits numeric constants only
        return _finite(node, lambda: float(value), source)
    if isinstance(node, ast.Name):
        return values.get(node.id)
    children = [
        _fold(c, values, source)
        for c in ast.iter_child_nodes(node)
        if isinstance(c, ast.expr) and not (isinstance(node, ast.Call) and c is node.func)
    ]
    if any(v is None for v in children):
        return None
    if isinstance(node, ast.BinOp):
        return _finite(node, lambda: _FLOAT_OPS[type(node.op)](*children), source)
    if isinstance(node, ast.UnaryOp):
        (v,) = children
        assert v is not None
        return (
            float(not v)
            if isinstance(node.op, ast.Not)
            else -v
            if isinstance(node.op, ast.USub)
            else v
        )
    if isinstance(node, ast.Call):
        name = cast(ast.Name, node.func).id  # _check_tree admits calls of names only
        return _finite(node, lambda: _MATH[name](*children), source)
    if isinstance(node, ast.Compare):
        pairs = zip(children, children[1:])
        return float(all(_FLOAT_OPS[type(op)](a, b) for op, (a, b) in zip(node.ops, pairs)))
    if isinstance(node, ast.BoolOp):
        return float(all(children) if isinstance(node.op, ast.And) else any(children))
    if isinstance(node, ast.IfExp):
        test, body, orelse = children
        return body if test else orelse
    return None


def _finite(node: ast.AST, evaluate: Callable[[], Any], source: str) -> float:
    sub = ast.unparse(node)
    where = "" if sub.replace(" ", "") == source.replace(" ", "") else f" in {source!r}"
    try:
        value = evaluate()
    except ZeroDivisionError:
        raise ExpressionError(f"{sub} divides by zero{where}") from None
    except OverflowError:
        raise ExpressionError(f"{sub} overflows (too large for a float){where}") from None
    except (ValueError, TypeError):
        raise ExpressionError(f"{sub} is undefined (math domain error){where}") from None
    if isinstance(value, complex):
        raise ExpressionError(f"{sub} is not a real number{where}")
    if not math.isfinite(value):
        raise ExpressionError(f"{sub} is not a finite number{where}")
    return float(value)


_ALLOWED = (
    ast.Expression,
    ast.BinOp,
    ast.UnaryOp,
    ast.BoolOp,
    ast.Compare,
    ast.IfExp,
    ast.Call,
    ast.Name,
    ast.Constant,
    ast.Load,
    ast.Add,
    ast.Sub,
    ast.Mult,
    ast.Div,
    ast.Pow,
    ast.USub,
    ast.UAdd,
    ast.Not,
    ast.And,
    ast.Or,
    ast.Lt,
    ast.LtE,
    ast.Gt,
    ast.GtE,
)


def _check_node(node: ast.AST, names: set[str], source: str) -> None:
    """Refuse a node outside the grammar (``source``, as shown in messages)."""
    if not isinstance(node, _ALLOWED):
        raise ExpressionError(f"{type(node).__name__.lower()} is not allowed in {source!r}")
    if isinstance(node, ast.Constant) and (
        isinstance(node.value, bool) or not isinstance(node.value, (int, float))
    ):
        raise ExpressionError(f"constant {node.value!r} is not a number in {source!r}")
    if isinstance(node, ast.Name) and node.id not in names and node.id not in FUNCTIONS:
        raise ExpressionError(f"unknown name {node.id!r} in {source!r}")
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            raise ExpressionError(
                f"only the functions {', '.join(FUNCTIONS)} may be called in {source!r}"
            )
        if node.keywords:
            raise ExpressionError(f"keyword arguments are not allowed in {source!r}")
        if len(node.args) != _ARITY.get(node.func.id, 1):
            raise ExpressionError(
                f"{node.func.id}() takes {_ARITY.get(node.func.id, 1)} argument(s) in {source!r}"
            )


class _Backend:
    """Operations of one target (UFL or NumPy) used by :func:`_translate`."""

    def __init__(
        self,
        ops: dict[str, Callable],
        cond: Callable,
        logic: dict[type, Callable],
        compare: dict[type, Callable],
        number: Callable = float,
        value: Callable = lambda v: v,
    ):
        self.ops, self.cond, self.logic, self.compare = ops, cond, logic, compare
        self.number = number
        # a condition where a number is expected (``2*(x > 0.5)``) counts as 1 or 0
        self.value = value


def _translate(tree: ast.Expression, symbols: Mapping[str, Any], be: _Backend) -> Any:
    def num(node: ast.AST) -> Any:
        return be.value(go(node))

    def go(node: ast.AST) -> Any:
        if isinstance(node, ast.Expression):
            return go(node.body)
        if isinstance(node, ast.Constant):
            return be.number(node.value)
        if isinstance(node, ast.Name):
            if node.id not in symbols:
                raise ExpressionError(f"{node.id!r} is a function, call it with arguments")
            return symbols[node.id]
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.Not):
                return be.logic[ast.Not](go(node.operand))
            v = num(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.BinOp):
            a, b = num(node.left), num(node.right)
            return {
                ast.Add: lambda: a + b,
                ast.Sub: lambda: a - b,
                ast.Mult: lambda: a * b,
                ast.Div: lambda: a / b,
                ast.Pow: lambda: a**b,
            }[type(node.op)]()
        if isinstance(node, ast.BoolOp):
            vals = [go(v) for v in node.values]
            out = vals[0]
            for v in vals[1:]:
                out = be.logic[type(node.op)](out, v)
            return out
        if isinstance(node, ast.Compare):
            left, out = go(node.left), None
            for op, right_node in zip(node.ops, node.comparators):
                right = go(right_node)
                term = be.compare[type(op)](left, right)
                out = term if out is None else be.logic[ast.And](out, term)
                left = right
            return out
        if isinstance(node, ast.IfExp):
            return be.cond(go(node.test), num(node.body), num(node.orelse))
        if isinstance(node, ast.Call):
            return be.ops[cast(ast.Name, node.func).id](*[num(a) for a in node.args])
        raise ExpressionError(f"unsupported node {type(node).__name__}")  # pragma: no cover

    return num(tree)


def to_numpy(
    text: str | float, constants: Mapping[str, float] = {}, t: float = 1.0
) -> Callable[[np.ndarray], np.ndarray]:
    """Vectorised ``f(x)`` for ``x`` of shape ``(3, n)`` (DOLFINx interpolation convention),
    at pseudo-time ``t``."""
    tree = parse(text, constants)
    be = _Backend(
        ops={
            "sin": np.sin,
            "cos": np.cos,
            "tan": np.tan,
            "exp": np.exp,
            "log": np.log,
            "sqrt": np.sqrt,
            "atan2": np.arctan2,
            "abs": np.abs,
            "min": np.minimum,
            "max": np.maximum,
            "sinh": np.sinh,
            "cosh": np.cosh,
            "tanh": np.tanh,
            "asinh": np.arcsinh,
        },
        cond=np.where,
        logic={ast.And: np.logical_and, ast.Or: np.logical_or, ast.Not: np.logical_not},
        compare={
            ast.Lt: np.less,
            ast.LtE: np.less_equal,
            ast.Gt: np.greater,
            ast.GtE: np.greater_equal,
        },
        number=np.float64,
        value=lambda v: v.astype(float) if getattr(v, "dtype", np.dtype(float)).kind == "b" else v,
    )

    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}

    def f(x: np.ndarray) -> np.ndarray:
        X = np.asarray(x, dtype=float)
        symbols = dict(
            BUILTIN_CONSTANTS,
            **constants,
            x=X[0],
            y=X[1],
            z=X[2] if len(X) > 2 else 0 * X[0],
            t=np.float64(t),
        )
        # only what the expression uses (interpolation evaluates millions of points)
        if "r" in names:
            symbols["r"] = np.hypot(symbols["x"], symbols["y"])
        if "theta" in names:
            symbols["theta"] = np.arctan2(symbols["y"], symbols["x"])
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            val = _translate(tree, symbols, be)
        return np.broadcast_to(np.asarray(val, dtype=float), X[0].shape).copy()

    return f


def to_ufl(text: str | float, mesh: Any, constants: Mapping[str, float] = {}, t: Any = 1.0) -> Any:
    """UFL expression of ``text`` in the spatial coordinates of ``mesh``; ``t`` is the
    pseudo-time (a number, or a ``fem.Constant`` to keep one compiled form for all steps)."""
    import ufl

    tree = parse(text, constants)
    X = ufl.SpatialCoordinate(mesh)
    gdim = mesh.geometry.dim
    xs = [X[i] if i < gdim else 0.0 for i in range(3)]
    symbols = dict(BUILTIN_CONSTANTS, **constants, x=xs[0], y=xs[1], z=xs[2], t=t)
    symbols["r"] = ufl.sqrt(xs[0] ** 2 + xs[1] ** 2)
    symbols["theta"] = ufl.atan2(xs[1], xs[0])
    be = _Backend(
        ops={
            "sin": ufl.sin,
            "cos": ufl.cos,
            "tan": ufl.tan,
            "exp": ufl.exp,
            "log": ufl.ln,
            "sqrt": ufl.sqrt,
            "atan2": ufl.atan2,
            "abs": abs,
            "min": ufl.min_value,
            "max": ufl.max_value,
            "sinh": ufl.sinh,
            "cosh": ufl.cosh,
            "tanh": ufl.tanh,
            "asinh": lambda a: ufl.sign(a) * ufl.ln(abs(a) + ufl.sqrt(a * a + 1)),
        },
        cond=ufl.conditional,
        logic={ast.And: ufl.And, ast.Or: ufl.Or, ast.Not: ufl.Not},
        compare={ast.Lt: ufl.lt, ast.LtE: ufl.le, ast.Gt: ufl.gt, ast.GtE: ufl.ge},
        value=lambda v: ufl.conditional(v, 1.0, 0.0) if isinstance(v, ufl.classes.Condition) else v,
    )
    value = _translate(tree, symbols, be)
    return ufl.as_ufl(value)


def is_constant(text: str | float, constants: Mapping[str, float] = {}) -> bool:
    """True when the expression uses neither a coordinate nor the pseudo-time ``t`` (so it
    can be a ``fem.Constant`` fixed once)."""
    tree = parse(text, constants)
    return not any(
        isinstance(n, ast.Name) and n.id in COORDINATES + HELPERS + (TIME,) for n in ast.walk(tree)
    )


def uses_time(text: str | float, constants: Mapping[str, float] = {}) -> bool:
    """True when the expression uses the pseudo-time ``t``."""
    tree = parse(text, constants)
    return any(isinstance(n, ast.Name) and n.id == TIME for n in ast.walk(tree))
