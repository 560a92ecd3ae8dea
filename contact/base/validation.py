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
from collections.abc import Callable, Iterable, Mapping
from types import UnionType
from typing import Annotated, Any, Union, get_args, get_origin

from pydantic import BaseModel, ConfigDict, ValidationError, ValidationInfo, model_validator
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


def at_least_one(v: Any) -> str | None:
    return None if v >= 1 else f"must be >= 1, got {v}"


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


def block_pair(block: Any) -> str | None:
    """``mesh.block`` of sphere_on_block: [half-width, depth], two positive numbers."""
    if (
        isinstance(block, (list, tuple))
        and len(block) == 2
        and all(isinstance(v, (int, float)) and v > 0 for v in block)
    ):
        return None
    shown = list(block) if isinstance(block, tuple) else block
    return f"must be [half-width, depth] with positive numbers, got {shown!r}"


def fail(text: str, key: str = "") -> PydanticCustomError:
    """The error of one value; ``key`` a sub-key below the field (a mapping's entry, or
    ``[i]``: a list's item)."""
    return PydanticCustomError("config", "{text}", {"text": text, "key": key})


def rule(text: str, key: str = "") -> PydanticCustomError:
    """The error of a rule among a section's keys (which keys a mesh type takes, …): it is
    reported after every value of a wrong type or range (:func:`config_error`)."""
    return PydanticCustomError("config", "{text}", {"text": text, "key": key, "rule": True})


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


def auto_or(validate: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """``auto``, or a value that ``validate`` accepts (its messages)."""
    return lambda v: v if v == "auto" else validate(v)


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


def string(check: Check | None = None) -> Callable[[Any], str]:
    """A string, then ``check``."""

    def validate(v: Any) -> str:
        if not isinstance(v, str):
            raise fail(f"expected a string, got {typename(v)} {v!r}")
        return _then(check, v)

    return validate


def a_list(check: Check | None = None) -> Callable[[Any], list]:
    """A list, then ``check``."""

    def validate(v: Any) -> list:
        if not isinstance(v, list):
            raise fail(f"expected a list, got {typename(v)} {v!r}")
        return _then(check, v)

    return validate


def among(choices: Iterable[Any]) -> Check:
    """The check that a value is one of ``choices`` (e.g. the integers 1, 2)."""
    choices = tuple(choices)
    listed = ", ".join(map(str, choices))
    return lambda v: None if v in choices else f"{v!r} is not one of {listed}"


def section_keys(cls: type[BaseModel]) -> tuple[str, ...]:
    """The keys of a section as its messages list them: the model's ``KEYS`` if it names
    them in another order than its fields, else its fields."""
    return tuple(getattr(cls, "KEYS", None) or cls.model_fields)


def section_input(cls: type[BaseModel], data: Any, info: ValidationInfo) -> Any:
    """The input of a section (a model's *before* validator): a mapping with string keys,
    its keys given as None left out (they take their defaults; :func:`parse_member` keeps
    them, to check a value alone); nothing (None) is the empty mapping.  Anything else is
    the error ``expected a mapping``."""
    if data is None:
        return {}
    if isinstance(data, BaseModel):
        return data
    if not isinstance(data, dict):
        raise fail(f"expected a mapping, got {typename(data)} {data!r}")
    for key in data:
        if not isinstance(key, str):
            raise fail(_unknown(section_keys(cls)), key=str(key))
    if (info.context or {}).get(_MEMBER):
        return data
    # an unknown key is one whatever its value, but for the sections that are keywords of
    # the Python API too (solver, adapt, friction: None = not given)
    keywords = getattr(cls, "KEYWORDS", False)
    return {
        key: value
        for key, value in data.items()
        if value is not None or not (keywords or key in cls.model_fields)
    }


_MEMBER = "contact.validation.member"  # the context key of parse_member


class Section(BaseModel):
    """A section of an input file: frozen, no unknown keys, a key given as None takes its
    default (:func:`section_input`)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    @model_validator(mode="before")
    @classmethod
    def _input(cls, data: Any, info: ValidationInfo) -> Any:
        return section_input(cls, data, info)


def string_keys(v: Any) -> Any:
    """A free-form mapping (names of the scene's choosing): string keys; nothing is empty."""
    if v is None:
        return {}
    if not isinstance(v, dict):
        raise fail(f"expected a mapping, got {typename(v)} {v!r}")
    for key in v:
        if not isinstance(key, str):
            raise fail("keys must be strings", key=str(key))
    return v


def _unknown(keys: Iterable[str]) -> str:
    return f"unknown key (expected one of {', '.join(keys)})"


def config_error(err: ValidationError, path: str, model: type[BaseModel]) -> ConfigError:
    """The one-line ConfigError of a ``model``'s ValidationError: ``<path>.<key>: <text>``.

    Of several errors, the one a reader meets first: a value of a wrong type or range
    before a broken :func:`rule`, each in the order of the sections' keys
    (:func:`section_keys`), depth first, an unknown key of a mapping before its other
    errors.  A ConfigError a validator raised (a whole line, e.g. a rule across sections)
    is that error.

    Args:
        err: pydantic's error.
        path: the key path of ``model``'s input (``""``: the top level).
        model: the model that raised it.

    Returns:
        The error to raise.
    """
    line = _first(err, model)
    if isinstance(line, ConfigError):
        return line
    loc, text = line
    return ConfigError(f"{_join(path, loc)}: {text}")


def below(err: ValidationError, model: type[BaseModel], key: str) -> PydanticCustomError:
    """The error of a section validated by a rule of another (e.g. the blocks of a mesh of
    type blocks), as the outer section's :func:`rule` error at sub-key ``key`` (``[i]``)."""
    line = _first(err, model)
    if isinstance(line, ConfigError):
        raise line
    loc, text = line
    return rule(text, key=_join(key, loc))


def _first(err: ValidationError, model: type[BaseModel]) -> tuple[tuple, str] | ConfigError:
    """The first error (:func:`config_error`): its location and text, or the ConfigError
    a validator raised."""
    seen: dict[tuple, int] = {}  # a free-form mapping's entries: in their given order
    ranked = [
        (_walk(model, e["loc"], e["type"] == "extra_forbidden", seen), e) for e in err.errors()
    ]
    (_, keys), e = min(
        ranked, key=lambda item: (bool((item[1].get("ctx") or {}).get("rule")), item[0][0])
    )
    ctx = e.get("ctx") or {}
    if isinstance(ctx.get("error"), ConfigError):
        return ctx["error"]
    if e["type"] == "extra_forbidden":
        return e["loc"], _unknown(keys)
    if e["type"] == "missing":
        return e["loc"], "required key is missing"
    key = ctx.get("key")
    return (*e["loc"], *([key] if key else [])), ctx.get("text", e["msg"])


def _join(path: str, loc: Iterable[Any]) -> str:
    """``a.b[2].c`` of a path and the location below it (an item: ``2`` or ``"[2]…"``)."""
    for part in loc:
        if isinstance(part, int):
            path = f"{path}[{part}]"
        elif isinstance(part, str) and part.startswith("["):
            path = f"{path}{part}"
        elif part != "":
            path = f"{path}.{part}" if path else str(part)
    return path


def _walk(
    model: type[BaseModel] | None, loc: tuple, unknown: bool, seen: dict[tuple, int]
) -> tuple[tuple[int, ...], tuple[str, ...]]:
    """The rank of an error at ``loc`` below ``model`` (one entry per level: the key's
    place among its section's keys, -1 for an unknown key) and the keys of the section
    it is in."""
    ranks: list[int] = []
    keys: tuple[str, ...] = ()
    node: tuple[str, Any] = ("model", model)
    for depth, part in enumerate(loc):
        kind, cls = node
        if kind == "model" and cls is not None and isinstance(part, str):
            keys = section_keys(cls)
            last = depth == len(loc) - 1
            ranks.append(
                -1 if unknown and last else keys.index(part) if part in keys else len(keys)
            )
            field = cls.model_fields.get(part)
            node = _inner(field.annotation) if field is not None else ("", None)
        elif kind == "dict":
            ranks.append(seen.setdefault((*loc[:depth], part), len(seen)))
            node = ("model", cls)
        elif kind == "seq" and isinstance(part, int):
            ranks.append(part)
            node = ("model", cls)
        else:
            ranks.append(0)
            node = ("", None)
    return tuple(ranks), keys


def _inner(annotation: Any) -> tuple[str, Any]:
    """What a field holds: a section (``model``), a mapping of sections (``dict``), a
    sequence of them (``seq``) or values (``""``)."""
    origin, args = get_origin(annotation), get_args(annotation)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return "model", annotation
    if origin is Annotated:
        return _inner(args[0])
    if origin in (dict, Mapping):
        return "dict", _inner(args[-1])[1]
    if origin in (tuple, list):
        return "seq", _inner(args[0])[1]
    if origin in (Union, UnionType):
        return next((inner for arg in args if (inner := _inner(arg))[0]), ("", None))
    return "", None


def parse_section[Section: BaseModel](
    cls: type[Section],
    values: Any,
    path: str,
    context: dict[str, Any] | None = None,
) -> Section:
    """A frozen model ``cls`` of keyword ``values`` (a key given as None: the default),
    validated: one ConfigError line ``<path>.<key>: …`` (:func:`config_error`).
    ``context``: the validators' (e.g. a scene's ``constants`` for expressions)."""
    given = {k: v for k, v in values.items() if v is not None}
    try:
        return cls.model_validate(given, context=context)
    except ValidationError as err:
        raise config_error(err, path, cls) from None


def parse_member(
    cls: type[BaseModel], key: str, value: Any, path: str, context: dict[str, Any] | None = None
) -> Any:
    """``value`` validated as field ``key`` of model ``cls`` (its type, its message), the
    error line naming ``path`` (e.g. a study's axis value ``axes.mu[2]``)."""
    try:
        checked = cls.model_validate({key: value}, context={**(context or {}), _MEMBER: True})
        return getattr(checked, key)
    except ValidationError as err:
        message = str(config_error(err, "", cls))
        raise ConfigError(path + message.removeprefix(key)) from None
