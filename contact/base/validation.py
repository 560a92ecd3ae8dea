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

from pydantic import BaseModel, ValidationError
from pydantic_core import PydanticCustomError

from .errors import ConfigError

Check = Callable[[Any], "str | None"]


def typename(v: Any) -> str:
    """'a mapping', 'a list', 'a string', … for messages."""
    if isinstance(v, dict):
        return "a mapping"
    return {
        dict: "a mapping",
        list: "a list",
        str: "a string",
        bool: "a boolean",
        int: "an integer",
        float: "a number",
        type(None): "empty",
    }.get(type(v), type(v).__name__)


class FrozenDict(dict):
    """A mapping of the config: a dict (JSON, ``==``, iteration as usual) that refuses
    every change in place."""

    def _refuse(self, *args: Any, **kwargs: Any) -> Any:
        raise TypeError(
            "a validated config is immutable (load the scene again with overrides: "
            "contact.load_scene(path, ['key.path=value']))"
        )

    __setitem__ = __delitem__ = __ior__ = _refuse
    clear = pop = popitem = setdefault = update = _refuse

    def __reduce__(self) -> tuple:
        return FrozenDict, (dict(self),)

    def __copy__(self) -> FrozenDict:
        return self

    def __deepcopy__(self, memo: dict) -> FrozenDict:
        return self


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


def fail(text: str, key: str = "") -> PydanticCustomError:
    """The error of one value; ``key`` a sub-key below the field (a mapping's entry, or
    ``[i]``: a list's item)."""
    return PydanticCustomError("config", "{text}", {"text": text, "key": key})


def _then(check: Check | None, v: Any) -> Any:
    if check is not None and (problem := check(v)):
        raise fail(problem)
    return v


def number(check: Check | None = None) -> Callable[[Any], float]:
    """A finite number (an int becomes a float), then ``check``."""

    def validate(v: Any) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise fail(f"expected a number, got {typename(v)} {v!r}")
        if not math.isfinite(v):
            raise fail(f"must be finite, got {v}")
        return _then(check, float(v))

    return validate


def integer(check: Check | None = None) -> Callable[[Any], int]:
    def validate(v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            raise fail(f"expected an integer, got {typename(v)} {v!r}")
        return _then(check, v)

    return validate


def boolean(v: Any) -> bool:
    if not isinstance(v, bool):
        raise fail(f"expected true or false, got {typename(v)} {v!r}")
    return v


def one_of(choices: Iterable[str]) -> Callable[[Any], str]:
    """A string among ``choices``."""
    choices = tuple(choices)

    def validate(v: Any) -> str:
        if not isinstance(v, str):
            raise fail(f"expected a string, got {typename(v)} {v!r}")
        if v not in choices:
            raise fail(f"{v!r} is not one of {', '.join(choices)}")
        return v

    return validate


def checked(check: Check) -> Callable[[Any], Any]:
    """Any value that passes ``check``."""
    return lambda v: _then(check, v)


def mapping_of(check: Check) -> Callable[[Any], FrozenDict]:
    """A mapping with string keys whose values pass ``check`` (empty: ``{}``), frozen."""

    def validate(v: Any) -> FrozenDict:
        if v is None:
            return FrozenDict()
        if not isinstance(v, dict):
            raise fail(f"expected a mapping, got {typename(v)} {v!r}")
        for key, item in v.items():
            if not isinstance(key, str):
                raise fail("keys must be strings", key=str(key))
            if problem := check(item):
                raise fail(problem, key=key)
        return FrozenDict(v)

    return validate


def config_error(
    err: ValidationError, path: str, keys: Iterable[str], rename: bool = False
) -> ConfigError:
    """The one-line ConfigError of a model's ValidationError: ``<path>.<key>: <text>``.
    An unknown key comes first (as the scene's config reports it), naming ``keys``, the
    keys the section may hold.  ``rename``: ``path`` names the field itself (not its
    section)."""
    keys = tuple(keys)
    # the first error in the order of ``keys`` (the order of the section's schema), as a
    # schema that checks key by key reports it
    errors = sorted(err.errors(), key=lambda e: _rank(e["loc"], keys))
    unknown = [e for e in errors if e["type"] == "extra_forbidden"]
    e = (unknown or errors)[0]
    loc = e["loc"][1:] if rename else e["loc"]
    where = ".".join(str(part) for part in (path, *loc) if part != "")
    if unknown:
        return ConfigError(f"{where}: unknown key (expected one of {', '.join(keys)})")
    ctx = e.get("ctx") or {}
    if key := ctx.get("key"):
        where = f"{where}{key}" if key.startswith("[") else f"{where}.{key}"
    return ConfigError(f"{where}: {ctx.get('text', e['msg'])}")


def _rank(loc: tuple, keys: tuple[str, ...]) -> int:
    return keys.index(loc[0]) if loc and loc[0] in keys else len(keys)


def parse_section[Section: BaseModel](
    cls: type[Section],
    values: Any,
    path: str,
    context: dict[str, Any] | None = None,
    keys: Iterable[str] | None = None,
) -> Section:
    """A frozen model ``cls`` of keyword ``values`` (a key given as None: the default),
    validated: one ConfigError line ``<path>.<key>: …`` naming an unknown key with ``keys``
    (default: the model's fields, in their order).  ``context``: the validators' (e.g. a
    scene's ``constants`` for expressions)."""
    given = {k: v for k, v in values.items() if v is not None}
    try:
        return cls.model_validate(given, context=context)
    except ValidationError as err:
        raise config_error(err, path, cls.model_fields if keys is None else keys) from None


def parse_member(
    cls: type[BaseModel], key: str, value: Any, path: str, context: dict[str, Any] | None = None
) -> Any:
    """``value`` validated as field ``key`` of model ``cls`` (its type, its message), the
    error line naming ``path`` (e.g. a study's axis value ``axes.mu[2]``)."""
    try:
        return getattr(cls.model_validate({key: value}, context=context), key)
    except ValidationError as err:
        raise config_error(err, path, (key,), rename=True) from None
