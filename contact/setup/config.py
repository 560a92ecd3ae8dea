"""Reading a scene: YAML → ``--set`` overrides → the typed, immutable
:class:`~contact.setup.scene_config.SceneConfig` (:func:`load_config`).

Every check runs before any mesh is built or any solve starts, and every failure is a
:class:`ConfigError` whose message is one line ``<key path>: <what is wrong>``, e.g.
``solver.method: 'fbb' is not one of fb, min, blend, vinewtonrsls, vinewtonssls``.
``--set`` overrides are applied to the raw mapping before anything is checked.  The schema
is :mod:`contact.setup.scene_config` (each section's keys) and
:mod:`contact.setup.scene_rules` (the rules across sections).  A scene describes only what
it needs; everything else has a default that works.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from ..base.errors import ConfigError  # also contact.base.errors.ConfigError, as before
from ..base.validation import config_error, parse_member, typename
from .scene_config import (
    ELASTIC_MODELS,
    EQUILIBRATED,
    FRICTION_LAWS,
    MAX_LOAD_STEPS,
    MAX_STEP_CUTS,
    SceneConfig,
    folder_name,
)
from .scene_rules import STRESS_3D, complete

__all__ = [
    "ELASTIC_MODELS",
    "EQUILIBRATED",
    "FRICTION_LAWS",
    "MAX_LOAD_STEPS",
    "MAX_STEP_CUTS",
    "STRESS_3D",
    "ConfigError",
    "SceneConfig",
    "apply_overrides",
    "folder_name",
    "load_config",
    "load_yaml",
    "read_yaml",
    "switch_off",
    "validate_scene",
]


class _Loader(yaml.SafeLoader):
    """YAML 1.1 safe loader that also reads 1e6, 1E-3, 2.5e+4 as floats (YAML 1.2 / Python
    notation; PyYAML alone returns the string '1e6', which a number field would reject)."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^[-+]?(?:[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?|[0-9][0-9_]*[eE][-+]?[0-9]+
                   |\.[0-9_]+(?:[eE][-+]?[0-9]+)?|\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


MAX_FILE_BYTES = 1_000_000  # a scene or study file
MAX_YAML_NODES = 100_000  # nodes of a YAML document with its aliases expanded


class YAMLTooLarge(yaml.YAMLError):
    """A YAML document beyond the limits (aliases expanding too far, nesting too deep)."""


class DuplicateKey(yaml.YAMLError):
    """A mapping of a YAML document that gives one key twice (PyYAML would keep the last
    one silently); ``str(err)`` names its path: ``duplicate key mesh.cells (lines 3 and 5)``."""


def load_yaml(text: str) -> Any:
    """Parse YAML text safely (no Python objects), with Python's float notation.

    A document whose aliases expand to more than :data:`MAX_YAML_NODES` nodes (a "billion
    laughs" bomb: a few hundred bytes that stand for 10⁹ list items), a recursive alias or
    nesting too deep for the parser raise :class:`YAMLTooLarge` before anything is built.
    """
    loader = _Loader(text)
    try:
        try:
            node = loader.get_single_node()
        except RecursionError:
            raise YAMLTooLarge("the YAML document is nested too deeply") from None
        if node is None:
            return None
        _check_expansion(node, MAX_YAML_NODES)
        _check_duplicates(node)
        return loader.construct_document(node)
    finally:
        loader.dispose()


def _check_expansion(root: yaml.Node, limit: int) -> None:
    """Count the nodes of the document as its consumers see it (each alias expanded), one
    visit per distinct node (sizes memoized), iteratively; refuse cycles and > limit."""

    def children(node: yaml.Node) -> list:
        if isinstance(node, yaml.SequenceNode):
            return node.value
        if isinstance(node, yaml.MappingNode):
            return [n for pair in node.value for n in pair]
        return []

    size: dict[int, int] = {}
    open_nodes: set[int] = set()  # the current path from the root
    stack = [(root, False)]
    while stack:
        node, finished = stack.pop()
        key = id(node)
        if finished:
            open_nodes.discard(key)
            size[key] = 1 + sum(size[id(c)] for c in children(node))
            if size[key] > limit:
                raise YAMLTooLarge(
                    f"the YAML document expands to more than {limit} nodes "
                    "(aliases * of anchors & repeat whole subtrees)"
                )
            continue
        if key in size:
            continue
        open_nodes.add(key)
        stack.append((node, True))
        for child in children(node):
            if id(child) in open_nodes:
                raise YAMLTooLarge(
                    "the YAML document has a recursive alias (an anchor used inside itself)"
                )
            if id(child) not in size:
                stack.append((child, False))


def _check_duplicates(root: yaml.Node) -> None:
    """Refuse a mapping that gives a key twice (:class:`DuplicateKey`, naming the key's path
    ``a.b[2].c``).  Keys are compared as written with their resolved tag (``1`` and ``'1'``
    differ, as they do for PyYAML); merge keys ``<<`` are YAML's way to take a mapping's
    keys and override some, not a duplicate.  Each node is visited once (aliases share it)."""
    seen: set[int] = set()
    stack: list[tuple[yaml.Node, str]] = [(root, "")]
    while stack:
        node, path = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.SequenceNode):
            stack.extend((child, f"{path}[{i}]") for i, child in enumerate(node.value))
        elif isinstance(node, yaml.MappingNode):
            first: dict[tuple[str, str], yaml.Node] = {}
            for key, value in node.value:
                if key.tag == "tag:yaml.org,2002:merge" or not isinstance(key, yaml.ScalarNode):
                    continue
                name = f"{path}.{key.value}" if path else str(key.value)
                if (key.tag, key.value) in first:
                    before = first[key.tag, key.value].start_mark.line + 1
                    lines = f"lines {before} and {key.start_mark.line + 1}"
                    raise DuplicateKey(f"duplicate key {name} ({lines}); give each key once")
                first[key.tag, key.value] = key
                stack.append((value, name))


def read_yaml(path: str | Path) -> dict:
    """Read a YAML mapping from ``path``; a missing file or bad YAML is a ConfigError."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{p}: no such file")
    try:
        if (size := p.stat().st_size) > MAX_FILE_BYTES:
            raise ConfigError(
                f"{p}: the file has {size} bytes, more than the limit of {MAX_FILE_BYTES} "
                "for a scene or study (put meshes and data in files of their own)"
            )
        data = load_yaml(p.read_text(encoding="utf-8"))
    except UnicodeDecodeError as err:
        raise ConfigError(
            f"{p}: not UTF-8 text (byte {err.object[err.start]:#04x} at offset {err.start})"
        ) from None
    except OSError as err:
        raise ConfigError(f"{p}: cannot read: {err.strerror or err}") from None
    except (YAMLTooLarge, DuplicateKey) as err:
        raise ConfigError(f"{p}: {err}") from None
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise ConfigError(f"{p}: malformed YAML{where}: {problem}") from None
    if not isinstance(data, dict):
        raise ConfigError(
            f"{p}: expected a mapping of sections at the top level, got {typename(data)}"
        )
    return data


def apply_overrides(data: dict, overrides: list[str] | tuple[str, ...]) -> dict:
    """Apply ``--set a.b.c=value`` overrides; ``value`` is parsed as YAML (so 1e-8 is a number)."""
    data = copy.deepcopy(data)
    for item in overrides:
        if "=" not in item:
            raise ConfigError(f"--set {item}: expected KEY.PATH=VALUE")
        key, raw = item.split("=", 1)
        if not all(key.strip().split(".")):
            raise ConfigError(
                f"--set {item}: expected KEY.PATH=VALUE, the key path has an empty part"
            )
        try:
            value = load_yaml(raw)
        except DuplicateKey as err:
            raise ConfigError(f"--set {key}: {err}") from None
        except yaml.YAMLError:
            value = raw
        node = data
        parts = key.strip().split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ConfigError(f"--set {key}: {part} is not a section")
        node[parts[-1]] = value
    return data


#: the optional sections: ``<section>: none`` (``--set load=none``) switches one off
OPTIONAL_SECTIONS = ("bodies", "pairs", "obstacle", "reference", "adapt", "friction", "load")


def switch_off(data: Mapping) -> dict:
    """``data`` without the optional sections whose value is the word ``none`` (as if they
    were not given): ``load: none``, ``friction: none``, ``adapt: none``, …

    Args:
        data: a scene's raw mapping.

    Returns:
        A new mapping without them.
    """
    return {
        key: value
        for key, value in data.items()
        if not (key in OPTIONAL_SECTIONS and value == "none")
    }


def validate_scene(
    data: Mapping, base_dir: str | Path = ".", name: str | None = None
) -> SceneConfig:
    """Validate a raw scene mapping: its config, complete (defaults filled in), typed and
    immutable.

    The ``constants`` first (every expression may use them), then each section
    (:mod:`.scene_config`), then the rules across sections (:func:`.scene_rules.complete`).

    Args:
        data: the scene (``--set`` overrides applied).
        base_dir: the folder relative paths (``mesh.file``) are taken from.
        name: the default name (the scene file's stem; else ``scene``).

    Returns:
        The validated config.

    Raises:
        ConfigError: one line ``<key path>: <what is wrong>``.
    """
    if not isinstance(data, Mapping):
        raise ConfigError(f"scene: expected a mapping, got {typename(data)}")
    data = switch_off(data)  # adapt: none  =  no adaptive loop, load: none  =  one solve, …
    if isinstance(data.get("model"), str):  # short form  model: signorini
        data = {**data, "model": {"type": data["model"]}}
    constants = parse_member(SceneConfig, "constants", data.get("constants") or {}, "constants")
    context = {"constants": constants, "base_dir": str(Path(base_dir).resolve()), "name": name}
    try:
        config = SceneConfig.model_validate(data, context=context)
    except ValidationError as err:
        raise config_error(err, "", SceneConfig) from None
    return complete(config, data)


def load_config(
    source: str | Path | Mapping, overrides: list[str] | tuple[str, ...] = ()
) -> SceneConfig:
    """Read (if a path), apply ``--set`` overrides and validate a scene.

    Args:
        source: a scene file, or its mapping (relative paths: from the current folder).
        overrides: ``"key.path=value"`` strings, as ``contact run --set`` takes them.

    Returns:
        The scene's typed, immutable config.

    Raises:
        ConfigError: one line naming the key, file or override that is wrong.
    """
    if isinstance(source, Mapping):
        return validate_scene(apply_overrides(dict(source), overrides))
    path = Path(source)
    data = apply_overrides(read_yaml(path), overrides)
    return validate_scene(data, base_dir=path.parent, name=path.stem)
