"""Typed options with one-line messages: the field types of frozen pydantic models whose
errors read ``<key path>: <what is wrong>``, as the scene's config has always written them
(``solver.mu: must lie in (0, 1), got 1.5``).

Each type checks its value itself in a *before* validator and raises a
:class:`~pydantic_core.PydanticCustomError` with our text, so pydantic's own messages
("Input should be a valid number") never reach a user; :func:`config_error` turns a
:class:`~pydantic.ValidationError` into one :class:`~contact.base.errors.ConfigError` line
naming the key path.  The check functions (``positive``, ``open_unit``, …) return an error
text or None and serve the scene's schema as well (:mod:`contact.setup.config`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

from pydantic import ValidationError
from pydantic_core import PydanticCustomError

from .errors import ConfigError

Check = Callable[[Any], "str | None"]


def typename(v: Any) -> str:
    """'a mapping', 'a list', 'a string', … for messages."""
    return {
        dict: "a mapping",
        list: "a list",
        str: "a string",
        bool: "a boolean",
        int: "an integer",
        float: "a number",
        type(None): "empty",
    }.get(type(v), type(v).__name__)


def positive(v: Any) -> str | None:
    return None if v > 0 else f"must be > 0, got {v}"


def nonnegative(v: Any) -> str | None:
    return None if v >= 0 else f"must be >= 0, got {v}"


def open_unit(v: Any) -> str | None:
    return None if 0 < v < 1 else f"must lie in (0, 1), got {v}"


def half_open_unit(v: Any) -> str | None:
    return None if 0 < v <= 1 else f"must lie in (0, 1], got {v}"


def auto_or_positive(v: Any) -> str | None:
    """``auto`` or a finite number > 0 (a scaling such as ``solver.c``)."""
    if v == "auto":
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return f"must be 'auto' or a positive number, got {v!r}"
    return positive(v)


def petsc_value(v: Any) -> str | None:
    """A PETSc option's value: a string, a number, a boolean, or empty (a flag)."""
    if v is None or isinstance(v, (str, int, float)):
        return None
    return f"must be a string, number or boolean, got {typename(v)} {v!r}"


def _fail(text: str, key: str = "") -> PydanticCustomError:
    """The error of one value; ``key`` a sub-key below the field (a mapping's entry)."""
    return PydanticCustomError("config", "{text}", {"text": text, "key": key})


def _then(check: Check | None, v: Any) -> Any:
    if check is not None and (problem := check(v)):
        raise _fail(problem)
    return v


def number(check: Check | None = None) -> Callable[[Any], float]:
    """A finite number (an int becomes a float), then ``check``."""

    def validate(v: Any) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise _fail(f"expected a number, got {typename(v)} {v!r}")
        if not math.isfinite(v):
            raise _fail(f"must be finite, got {v}")
        return _then(check, float(v))

    return validate


def integer(check: Check | None = None) -> Callable[[Any], int]:
    def validate(v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            raise _fail(f"expected an integer, got {typename(v)} {v!r}")
        return _then(check, v)

    return validate


def boolean(v: Any) -> bool:
    if not isinstance(v, bool):
        raise _fail(f"expected true or false, got {typename(v)} {v!r}")
    return v


def one_of(choices: Iterable[str]) -> Callable[[Any], str]:
    """A string among ``choices``."""
    choices = tuple(choices)

    def validate(v: Any) -> str:
        if not isinstance(v, str):
            raise _fail(f"expected a string, got {typename(v)} {v!r}")
        if v not in choices:
            raise _fail(f"{v!r} is not one of {', '.join(choices)}")
        return v

    return validate


def checked(check: Check) -> Callable[[Any], Any]:
    """Any value that passes ``check``."""
    return lambda v: _then(check, v)


def mapping_of(check: Check) -> Callable[[Any], dict]:
    """A mapping with string keys whose values pass ``check`` (empty: ``{}``)."""

    def validate(v: Any) -> dict:
        if v is None:
            return {}
        if not isinstance(v, dict):
            raise _fail(f"expected a mapping, got {typename(v)} {v!r}")
        for key, item in v.items():
            if not isinstance(key, str):
                raise _fail("keys must be strings", key=str(key))
            if problem := check(item):
                raise _fail(problem, key=key)
        return dict(v)

    return validate


def config_error(err: ValidationError, path: str, keys: Iterable[str]) -> ConfigError:
    """The one-line ConfigError of a model's ValidationError: ``<path>.<key>: <text>``.
    An unknown key comes first (as the scene's config reports it), naming ``keys``, the
    keys the section may hold."""
    errors = err.errors()
    unknown = [e for e in errors if e["type"] == "extra_forbidden"]
    e = (unknown or errors)[0]
    where = ".".join(str(part) for part in (path, *e["loc"]) if part != "")
    if unknown:
        return ConfigError(f"{where}: unknown key (expected one of {', '.join(keys)})")
    ctx = e.get("ctx") or {}
    if ctx.get("key"):
        where = f"{where}.{ctx['key']}"
    return ConfigError(f"{where}: {ctx.get('text', e['msg'])}")
