"""Scene configuration: YAML → checked once → the typed, immutable
:class:`~contact.setup.scene_config.SceneConfig` (:func:`load_config`).

Every check runs before any mesh is built or any solve starts, and every failure is a
:class:`ConfigError` whose message is one line ``<key path>: <what is wrong>``, e.g.
``solver.method: 'fbb' is not one of fb, min, blend, vinewtonrsls, vinewtonssls``.
``--set`` overrides are applied to the raw mapping before anything is checked.

The schema is data (:data:`SCENE`): nested :class:`Field` s, checked key by key in order,
then the cross-key rules (:func:`validate_scene`).  The sections a caller may override in
the Python API — ``solver``, ``adapt``, ``friction`` — are pydantic models with the same
messages (:mod:`contact.setup.scene_config`), which the schema checks them through; why
pydantic, and how the checked mapping becomes typed objects, is said there.  A scene
describes only what it needs; everything else has a default that works.
"""

from __future__ import annotations

import ast
import copy
import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from ..base.errors import ConfigError  # also contact.base.errors.ConfigError, as before
from ..base.validation import nonnegative as _nonnegative  # noqa: F401 - the study schema uses it
from ..base.validation import parse_member, parse_section
from ..base.validation import positive as _positive
from ..base.validation import typename as _typename
from . import expressions
from .geometry import block_pair
from .scene_config import (
    ELASTIC_MODELS,
    FRICTION_KEYS,
    FRICTION_LAWS,
    SOLVER_KEYS,
    AdaptConfig,
    FrictionConfig,
    SceneConfig,
    SolverConfig,
)

__all__ = ["ELASTIC_MODELS", "FRICTION_LAWS", "ConfigError", "SceneConfig", "load_config"]

#: the models ``estimator: auto`` gives the equilibrated bound (a guaranteed error bound with
#: effectivity 1.1–1.45 against the residual estimator's unknown 3.5–11; to certify a
#: tolerance it needs an order of magnitude fewer DoFs: demos/RESULTS.md §12); elasticity
#: keeps the residual estimator
EQUILIBRATED_MODELS = ("signorini", "obstacle")
#: the guaranteed bounds (docs/theory.md §9): σ_h ∈ RT_p, or RT_0 for a P1 solution
EQUILIBRATED = ("equilibrated", "equilibrated_rt0")
HYPERELASTIC_LAWS = ("neo_hookean", "saint_venant_kirchhoff")
_REQUIRED = object()


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


@dataclass(frozen=True)
class Field:
    """One key of the schema.

    ``kind`` is one of ``str int float number bool expr dict list any``, ``model`` (a
    section that is a pydantic ``model`` of :mod:`.scene_config`, whose messages it keeps)
    or ``member`` (one field ``key`` of a ``model``); ``schema`` gives the keys of a
    ``dict`` (``None`` = free-form mapping whose values follow ``item``) or of a ``model``
    (its members, for code that validates one key: :mod:`contact.app.study`'s axes);
    ``check`` returns an error text or ``None``.
    """

    kind: str
    default: Any = _REQUIRED
    choices: tuple | None = None
    check: Callable[[Any], str | None] | None = None
    schema: Mapping[str, Field] | None = None
    item: Field | None = None
    doc: str = ""
    model: Any = None
    key: str = ""


def section(model: Any, keys: tuple[str, ...], default: Any = _REQUIRED, doc: str = "") -> Field:
    """The schema of a section that is a pydantic ``model``: ``keys`` in the order its
    messages list them, each a ``member`` Field with the model's default."""
    members = {
        key: Field("member", model.model_fields[key].default, model=model, key=key) for key in keys
    }
    return Field("model", default, schema=members, model=model, doc=doc)


def _cells(v: Any) -> str | None:
    items = v if isinstance(v, list) else [v]
    if not items or not all(
        isinstance(n, int) and not isinstance(n, bool) and n > 0 for n in items
    ):
        return f"must be a positive integer or a list of positive integers, got {v!r}"
    return None


def _point_list(v: Any) -> str | None:
    ok = (
        isinstance(v, list)
        and len(v) == 2
        and all(
            isinstance(p, list)
            and 2 <= len(p) <= 3
            and all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in p)
            for p in v
        )
        and len(v[0]) == len(v[1])
    )
    if not ok:
        return f"must be two points [[x0, y0(, z0)], [x1, y1(, z1)]], got {v!r}"
    if not all(math.isfinite(c) for p in v for c in p):
        return f"coordinates must be finite, got {v!r}"
    if any(b <= a for a, b in zip(v[0], v[1])):
        return f"the second corner must exceed the first in every coordinate, got {v!r}"
    return None


def folder_name(v: str) -> str | None:
    """A name that becomes one folder (``results/<name>``): no path separator, not ``.``,
    no ``..``, at most 100 characters."""
    if not v.strip():
        return "must not be empty"
    if any(c in v for c in "/\\\0") or ".." in v or v.strip() == ".":
        return f"must be a plain folder name (no '/', '\\' or '..'), got {v!r}"
    if len(v) > 100:
        return f"must be at most 100 characters, got {len(v)}"
    return None


def _numbers(v: Any, lengths: tuple[int, ...]) -> str | None:
    ok = len(v) in lengths and all(
        isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in v
    )
    return None if ok else f"expected {' or '.join(map(str, lengths))} finite numbers, got {v!r}"


def _expression_list(v: Any) -> str | None:
    if not isinstance(v, list):
        return f"expected a list of expressions, one per coordinate, got {_typename(v)} {v!r}"
    return None


#: the longest load path: as many steps as an explicit ``times`` list can have items (a scene
#: file holds at most MAX_YAML_NODES nodes); every step is at least one Newton solve and a row
#: of each per-step output, so 10⁵ steps of the smallest mesh already take hours
MAX_LOAD_STEPS = 100_000


def _steps(v: Any) -> str | None:
    if v <= 0:
        return f"must be > 0, got {v}"
    if v > MAX_LOAD_STEPS:
        return f"must be at most {MAX_LOAD_STEPS} (the longest load path), got {v}"
    return None


#: ``load.cuts`` at most: a step halved this many times in a row is 2^-20 ≈ 1e-6 of itself
MAX_STEP_CUTS = 20


def _cuts(v: Any) -> str | None:
    if v < 0:
        return f"must be >= 0, got {v}"
    if v > MAX_STEP_CUTS:
        return f"must be at most {MAX_STEP_CUTS} (a step halved {MAX_STEP_CUTS} times), got {v}"
    return None


def _not_empty(v: str) -> str | None:
    return None if v.strip() else "must not be empty (leave the key out for results/<name>)"


OUTPUT_FORMATS = ("xdmf", "vtk")


def _formats(v: Any) -> str | None:
    if any(f not in OUTPUT_FORMATS for f in v) or len(set(v)) != len(v):
        return f"expected a list of distinct formats from {', '.join(OUTPUT_FORMATS)}, got {v!r}"
    return None


def _times(v: Any) -> str | None:
    if not v or not all(
        isinstance(t, (int, float)) and not isinstance(t, bool) and math.isfinite(t) for t in v
    ):
        return f"expected a non-empty list of numbers, got {v!r}"
    if v[0] <= 0 or any(b <= a for a, b in zip(v, v[1:])):
        return f"the pseudo-times must be > 0 and strictly increasing, got {v!r}"
    return None


EXPR = Field("expr", "0")
EXPRS = Field(
    "exprs", "0", doc="an expression, or a list of them (one per component) for elasticity"
)

BOUNDARY = Field(
    "dict",
    schema={
        "role": Field(
            "str",
            choices=("dirichlet", "neumann", "contact", "symmetry", "interface", "natural"),
            doc="what the part is: Dirichlet (u = u_D), Neumann (flux t), natural (zero flux "
            "k ∂u/∂n = 0, elasticity traction-free: as an exterior facet in no part, but "
            "declared), contact (with the rigid obstacle), symmetry (elasticity: zero normal "
            "displacement on a plane x_k = const), or interface (a slave or master surface of "
            "a contact pair)",
        ),
        "where": Field(
            "str", None, doc="predicate in x, y, z selecting facets whose vertices all satisfy it"
        ),
        "tag": Field(
            "int", None, doc="gmsh physical tag of the facets (with where: those satisfying it)"
        ),
        "body": Field(
            "str", None, doc="only the facets of this body (a name of the bodies section)"
        ),
        "surface": Field(
            "dict",
            None,
            schema={
                "type": Field("str", choices=("circle", "sphere", "cylinder")),
                "center": Field("list", check=lambda v: _numbers(v, (2, 3))),
                "radius": Field("number", check=_positive),
                "axis": Field("list", None, check=lambda v: _numbers(v, (3,))),
            },
            doc="the exact curve / surface the part lies on (circle 2D; sphere, cylinder 3D): "
            "refinement moves the part's new vertices onto it",
        ),
    },
)

BODY = Field(
    "dict",
    schema={
        "tag": Field(
            "int",
            None,
            doc="the body's cells: a cell tag of the mesh (gmsh physical volume "
            "or surface; block number 1, 2, … of mesh type blocks)",
        ),
        "where": Field(
            "str", None, doc="the body's cells: predicate in x, y, z on the cell midpoints"
        ),
        "E": Field("number", check=_positive, doc="Young's modulus of the body"),
        "nu": Field(
            "number",
            0.3,
            check=lambda v: None if -1 < v < 0.5 else f"must lie in (-1, 0.5), got {v}",
            doc="Poisson's ratio of the body",
        ),
    },
)

PAIR = Field(
    "dict",
    schema={
        "slave": Field("str", doc="boundary part (role interface) carrying the multiplier"),
        "master": Field("str", doc="boundary part (role interface) of another body"),
        "search": Field(
            "number",
            None,
            check=_positive,
            doc="largest normal distance between a slave facet and a master facet it is "
            "paired with (default: the diameter of the two surfaces' bounding box); "
            "a slave node with no master facet within it is an error",
        ),
    },
)

BLOCK = Field(
    "dict",
    schema={
        "corners": Field("list", check=_point_list, doc="two opposite corners of the block"),
        "cells": Field("any", check=_cells, doc="cells per direction"),
    },
)

SCENE: dict[str, Field] = {
    "name": Field("str", None, check=folder_name, doc="the default output folder results/<name>"),
    "mesh": Field(
        "dict",
        schema={
            "type": Field(
                "str",
                "rectangle",
                choices=(
                    "rectangle",
                    "unit_square",
                    "box",
                    "lshape",
                    "gmsh",
                    "quarter_disk",
                    "sphere_octant",
                    "blocks",
                    "half_disks",
                    "sphere_on_block",
                ),
            ),
            "corners": Field("list", None, check=_point_list),
            "cells": Field("any", 16, check=_cells),
            "diagonal": Field(
                "str", "right", choices=("left", "right", "crossed", "left/right", "right/left")
            ),
            "file": Field("str", None),
            "degree": Field("int", 1, choices=(1, 2)),
            "radius": Field("number", None, doc="quarter_disk / sphere_octant: radius R"),
            "h": Field(
                "number", None, doc="quarter_disk / sphere_octant: mesh size away from contact"
            ),
            "h_contact": Field(
                "number", None, doc="quarter_disk / sphere_octant: mesh size at the contact point"
            ),
            "zone": Field(
                "number", None, doc="quarter_disk / sphere_octant: radius of the fine zone"
            ),
            "radius2": Field(
                "number", None, doc="half_disks: radius of the lower disk (default: radius)"
            ),
            "overlap": Field(
                "number",
                None,
                doc="half_disks: the lower disk moved up by this much (the "
                "bodies interpenetrate: an interference load)",
            ),
            "block": Field(
                "list",
                None,
                check=block_pair,
                doc="sphere_on_block: [half-width, depth] of the block",
            ),
            "blocks": Field(
                "list",
                None,
                doc="blocks: a list of {corners, cells}, one body each "
                "(cell tags 1, 2, …), meshed independently",
            ),
            "map": Field(
                "exprs",
                None,
                check=_expression_list,
                doc="rectangle / unit_square / box / lshape: new vertex coordinates "
                "[x', y'(, z')] as expressions in the built mesh's x, y, z (lengths in "
                "the scene's length unit, one per coordinate), applied before the "
                "boundary parts are tagged (their 'where' sees mapped coordinates); "
                "a map that inverts or flattens a cell is an error. Not for gmsh "
                "meshes: shape those in gmsh, which meshes the shape it is given",
            ),
        },
    ),
    "boundaries": Field("dict", schema=None, item=BOUNDARY),
    "model": Field(
        "dict",
        schema={
            "type": Field("str", "signorini", choices=("signorini", "obstacle") + ELASTIC_MODELS),
            "law": Field(
                "str",
                None,
                choices=HYPERELASTIC_LAWS,
                doc="hyperelastic: the strain energy, neo_hookean (compressible) or "
                "saint_venant_kirchhoff (nonconvex in strong compression)",
            ),
            "bound": Field(
                "str",
                "upper",
                choices=("upper", "lower"),
                doc="obstacle only: u ≤ ψ (upper) or u ≥ ψ (lower)",
            ),
            "E": Field(
                "number", None, check=_positive, doc="elasticity, hyperelastic: Young's modulus"
            ),
            "nu": Field(
                "number",
                0.3,
                check=lambda v: None if -1 < v < 0.5 else f"must lie in (-1, 0.5), got {v}",
                doc="elasticity: Poisson's ratio (the elastic energy is positive definite for -1 "
                "< ν < 1/2)",
            ),
        },
    ),
    "bodies": Field("dict", None, schema=None, item=BODY),
    "pairs": Field("list", None, doc="contact pairs between bodies: [{slave, master, search}]"),
    "obstacle": Field(
        "dict",
        None,
        schema={
            "type": Field("str", "plane", choices=("plane", "circle", "sphere")),
            "point": Field(
                "list",
                None,
                doc="plane: a point of the rigid plane; its coordinates "
                "may be expressions of the pseudo-time t (a moving "
                "plane, e.g. a plate pressed along a load path)",
            ),
            "normal": Field(
                "list", None, doc="plane: its outward normal, pointing towards the body"
            ),
            "center": Field(
                "list",
                None,
                doc="circle / sphere: the centre; its coordinates may be expressions of the "
                "pseudo-time t (an indenter moved along a load path)",
            ),
            "radius": Field("number", None, check=_positive, doc="circle / sphere: the radius"),
        },
    ),
    "reference": Field(
        "dict",
        None,
        schema={
            "type": Field(
                "str",
                choices=("hertz", "cattaneo_mindlin"),
                doc="the reference solution the results are compared with "
                "(docs/theory.md §7): hertz, or cattaneo_mindlin (partial slip of "
                "two similar bodies, Coulomb friction)",
            ),
            "radius": Field(
                "number",
                None,
                check=_positive,
                doc="hertz: the radius R of the curved body (default: mesh.radius of a "
                "quarter_disk / sphere_octant)",
            ),
        },
        doc="optional: a declared reference solution; only then are its values and errors reported",
    ),
    "constants": Field("dict", schema=None, item=Field("number")),
    "data": Field(
        "dict",
        schema={
            "f": EXPRS,
            "k": Field("expr", "1"),
            "u_D": EXPRS,
            "t": EXPRS,
            "t_C": EXPR,
            "g": EXPR,
            "psi": EXPR,
            "exact": Field(
                "exprs",
                None,
                doc="the exact solution, if known (one expression per component "
                "for elasticity): reports the energy error",
            ),
        },
    ),
    # the solver's knobs and the driver's (contact/setup/scene_config.py: SolverConfig)
    "solver": section(SolverConfig, SOLVER_KEYS),
    "estimator": Field(
        "str",
        "auto",
        choices=("auto", "residual", *EQUILIBRATED),
        doc="a posteriori error estimator: residual (docs/theory.md §5, reliable up "
        "to a constant), equilibrated (docs/theory.md §9: a guaranteed "
        "bound; scalar models, and one elastic body against a rigid plane), "
        "equilibrated_rt0 (the same bound from the lowest-order flux of a P1 solution of "
        "the scalar models: cheaper, larger) or auto: "
        "equilibrated for the scalar models (signorini, obstacle), residual for elasticity "
        "(demos/RESULTS.md §12)",
    ),
    # the adaptive loop (AdaptConfig; strategy none: one solve, as without the section)
    "adapt": section(AdaptConfig, tuple(AdaptConfig.model_fields), None),
    # the friction law, its data and the tangential knobs (FrictionConfig)
    "friction": section(FrictionConfig, FRICTION_KEYS, None),
    "load": Field(
        "dict",
        None,
        schema={
            "steps": Field(
                "int",
                None,
                check=_steps,
                doc="N equal steps t = 1/N, 2/N, ..., 1 (N ≤ MAX_LOAD_STEPS = 100 000)",
            ),
            "times": Field(
                "list", None, check=_times, doc="the pseudo-times of the steps, increasing, > 0"
            ),
            "adapt": Field(
                "str",
                "end",
                choices=("each", "end"),
                doc="with an adapt section: the adaptive loop at every step, or only at the last",
            ),
            "cuts": Field(
                "int",
                None,
                check=_cuts,
                doc="step cutting: a step that does not converge is halved (t_k → "
                "(t_{k-1} + t_k)/2) and retried, at most this many times in a row "
                "(default: 4 for model type hyperelastic, 0 otherwise; at most "
                "MAX_STEP_CUTS = 20); no step is cut below 1e-9 of the path's last t",
            ),
            "predictor": Field(
                "str",
                "secant",
                choices=("secant", "none"),
                doc="the guess of step k ≥ 3: secant (u_{k-1} extrapolated along the last "
                "increment, taken if its |Phi| is below that of u_{k-1}; linear models) or "
                "none (u_{k-1})",
            ),
        },
    ),
    "output": Field(
        "dict",
        schema={
            "dir": Field("str", None, check=_not_empty),
            "formats": Field(
                "list",
                ["xdmf", "vtk"],
                check=_formats,
                doc="the field files: xdmf (solution.xdmf + .h5, for ParaView), vtk "
                "(solution.vtu, for pyvista); a series for levels and load steps",
            ),
            "xdmf": Field("bool", None, doc="true / false: add xdmf to / drop it from formats"),
            "vtk": Field("bool", None, doc="true / false: add vtk to / drop it from formats"),
            "png": Field("bool", True),
            "verbose": Field("bool", True),
        },
    ),
}


#: the optional sections: ``<section>: none`` (``--set load=none``) switches one off
OPTIONAL_SECTIONS = tuple(
    key for key, f in SCENE.items() if f.default is None and f.kind in ("dict", "list", "model")
)


def switch_off(data: Mapping) -> dict:
    """``data`` without the optional sections whose value is the word ``none`` (as if they
    were not given): ``load: none``, ``friction: none``, ``adapt: none``, …"""
    return {
        key: value
        for key, value in data.items()
        if not (key in OPTIONAL_SECTIONS and value == "none")
    }


def _validate(value: Any, spec: Field, path: str, constants: Mapping[str, float]) -> Any:
    kind = spec.kind
    if kind == "float" or kind == "number":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{path}: expected a number, got {_typename(value)} {value!r}")
        if not math.isfinite(value):
            raise ConfigError(f"{path}: must be finite, got {value}")
        value = float(value)
    elif kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{path}: expected an integer, got {_typename(value)} {value!r}")
    elif kind == "str":
        if not isinstance(value, str):
            raise ConfigError(f"{path}: expected a string, got {_typename(value)} {value!r}")
    elif kind == "bool":
        if not isinstance(value, bool):
            raise ConfigError(f"{path}: expected true or false, got {_typename(value)} {value!r}")
    elif kind == "list":
        if not isinstance(value, list):
            raise ConfigError(f"{path}: expected a list, got {_typename(value)} {value!r}")
    elif kind == "exprs" and isinstance(value, list):
        if not value:
            raise ConfigError(f"{path}: expected an expression or a non-empty list of them")
        value = [_validate(item, EXPR, f"{path}[{i}]", constants) for i, item in enumerate(value)]
    elif kind in ("expr", "exprs"):
        try:
            expressions.parse(value, constants)
        except expressions.ExpressionError as err:
            raise ConfigError(f"{path}: {err}") from None
        value = str(value)
    elif kind in ("dict", "model"):
        if value is None:
            value = {}
        if not isinstance(value, dict):
            raise ConfigError(f"{path}: expected a mapping, got {_typename(value)} {value!r}")
        if kind == "dict":
            value = _validate_mapping(value, spec, path, constants)
        else:
            context = {"constants": constants}
            value = parse_section(spec.model, value, path, context, spec.schema)
    elif kind == "member":
        value = parse_member(spec.model, spec.key, value, path, {"constants": constants})
    if spec.choices is not None and value not in spec.choices:
        raise ConfigError(f"{path}: {value!r} is not one of {', '.join(map(str, spec.choices))}")
    if spec.check is not None and (problem := spec.check(value)):
        raise ConfigError(f"{path}: {problem}")
    return value


def _validate_mapping(
    data: Mapping, spec: Field, path: str, constants: Mapping[str, float]
) -> dict:
    prefix = f"{path}." if path else ""
    out = {}
    if spec.schema is None:  # free-form mapping: every value follows spec.item
        for key, val in data.items():
            if not isinstance(key, str):
                raise ConfigError(f"{prefix}{key}: keys must be strings")
            out[key] = _validate(val, spec.item, prefix + key, constants) if spec.item else val
        return out
    for key in data:
        if key not in spec.schema:
            raise ConfigError(
                f"{prefix}{key}: unknown key (expected one of {', '.join(spec.schema)})"
            )
    for key, sub in spec.schema.items():
        if key in data and data[key] is not None:
            out[key] = _validate(data[key], sub, prefix + key, constants)
        elif sub.default is _REQUIRED:
            if sub.kind in ("dict", "model"):
                out[key] = _validate({}, sub, prefix + key, constants)
            else:
                raise ConfigError(f"{prefix}{key}: required key is missing")
        else:
            out[key] = copy.deepcopy(sub.default)
    return out


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
            f"{p}: expected a mapping of sections at the top level, got {_typename(data)}"
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


def validate_scene(
    data: Mapping, base_dir: str | Path = ".", name: str | None = None
) -> SceneConfig:
    """Validate a raw scene mapping; return the completed config (defaults filled in),
    typed and immutable (:class:`~contact.setup.scene_config.SceneConfig`).

    Cross-key rules checked here: mesh keys that fit the mesh type, a mesh file that
    exists, one ``mesh.map`` expression per coordinate (whether the map inverts cells is
    checked on the mesh: :func:`contact.setup.meshes.map_geometry`), boundary parts with exactly
    one of ``where``/``tag`` (``tag`` only for gmsh meshes), at least one contact part for
    Signorini, ``c`` > 0, and data keys that fit the model (``g`` for Signorini, ``psi``
    for obstacles).
    """
    if not isinstance(data, Mapping):
        raise ConfigError(f"scene: expected a mapping, got {_typename(data)}")
    data = switch_off(data)  # adapt: none  =  no adaptive loop, load: none  =  one solve, …
    if isinstance(data.get("model"), str):  # short form  model: signorini
        data = {**data, "model": {"type": data["model"]}}
    raw_constants = data.get("constants") or {}
    constants = _validate(raw_constants, SCENE["constants"], "constants", {})
    for key in constants:
        if (
            key
            in expressions.COORDINATES
            + expressions.HELPERS
            + expressions.FUNCTIONS
            + (expressions.TIME,)
            or not key.isidentifier()
        ):
            raise ConfigError(f"constants.{key}: is not a usable constant name")
    cfg = _validate_mapping(data, Field("dict", schema=SCENE), "", constants)
    cfg["name"] = cfg["name"] or name or "scene"
    if cfg["adapt"] is not None and cfg["adapt"].strategy == "none":
        cfg["adapt"] = None
    cfg["_base_dir"] = str(Path(base_dir).resolve())

    mesh = cfg["mesh"]
    allowed = {
        "rectangle": {"corners", "cells", "diagonal", "map"},
        "unit_square": {"cells", "diagonal", "map"},
        "box": {"corners", "cells", "map"},
        "lshape": {"cells", "diagonal", "map"},
        "gmsh": {"file"},
        "quarter_disk": {"radius", "h", "h_contact", "zone"},
        "sphere_octant": {"radius", "h", "h_contact", "zone"},
        "blocks": {"blocks", "diagonal"},
        "half_disks": {"radius", "radius2", "h", "h_contact", "zone", "overlap"},
        "sphere_on_block": {"radius", "block", "h", "h_contact", "zone"},
    }[mesh["type"]]
    given = {k for k, v in (data.get("mesh") or {}).items() if v is not None}
    for key in SCENE["mesh"].schema or {}:
        if key in given and key not in allowed | {"type", "degree"}:
            raise ConfigError(f"mesh.{key}: not used by mesh type {mesh['type']!r}")
    if mesh["type"] == "gmsh":
        if mesh["file"] is None:
            raise ConfigError("mesh.file: required for mesh type 'gmsh'")
        path = Path(mesh["file"])
        path = path if path.is_absolute() else Path(cfg["_base_dir"]) / path
        if not path.is_file():
            raise ConfigError(f"mesh.file: no such file {str(path)!r}")
        mesh["file"] = str(path)
    dims = {"rectangle": 2, "unit_square": 2, "lshape": 2, "box": 3}.get(mesh["type"])
    if dims is not None and mesh["type"] in ("rectangle", "box"):
        if mesh["corners"] is None:
            mesh["corners"] = [[0.0] * dims, [1.0] * dims]
        if len(mesh["corners"][0]) != dims:
            raise ConfigError(f"mesh.corners: a {mesh['type']} needs {dims}D points")
    if dims is not None:
        cells = (
            mesh["cells"]
            if isinstance(mesh["cells"], list)
            else [mesh["cells"]] * (1 if mesh["type"] == "lshape" else dims)
        )
        want = 1 if mesh["type"] == "lshape" else dims
        if len(cells) != want:
            raise ConfigError(
                f"mesh.cells: a {mesh['type']} mesh needs {want} cell count(s), got "
                f"{mesh['cells']!r}"
            )
        mesh["cells"] = cells
    if mesh["type"] == "blocks":
        dims = _check_blocks(mesh)
    if mesh["map"] is not None and len(mesh["map"]) != dims:
        raise ConfigError(
            f"mesh.map: expected {dims} expressions for a {dims}D mesh, got {len(mesh['map'])}"
        )

    if not cfg["boundaries"]:
        raise ConfigError("boundaries: at least one boundary part is required")
    for bname, part in cfg["boundaries"].items():
        if part["where"] is None and part["tag"] is None:
            raise ConfigError(
                f"boundaries.{bname}: give 'where' or 'tag' (or both: the tag's facets where "
                f"it holds)"
            )
        if part["tag"] is not None and mesh["type"] not in GMSH_MESHES:
            raise ConfigError(
                f"boundaries.{bname}.tag: tags need a gmsh mesh (mesh.type: "
                f"{', '.join(GMSH_MESHES)})"
            )
        if part["where"] is not None:
            try:
                expressions.parse(part["where"], constants)
            except expressions.ExpressionError as err:
                raise ConfigError(f"boundaries.{bname}.where: {err}") from None
    roles = [p["role"] for p in cfg["boundaries"].values()]
    model = cfg["model"]["type"]
    _check_hyperelastic(cfg, model)
    if model == "hyperelastic":  # the rest of the checks: those of an elastic body
        model = "elasticity"
    if (
        model == "signorini"
        and "contact" not in roles
        or model == "elasticity"
        and not ("contact" in roles or cfg["pairs"])
    ):
        raise ConfigError(f"boundaries: a {model} scene needs a part with role: contact")
    if model == "obstacle" and "contact" in roles:
        raise ConfigError(
            "boundaries: an obstacle scene constrains the whole domain; use data.psi, not a "
            "contact part"
        )
    given = set(data.get("data") or {})
    if model == "elasticity" and ({"k", "g", "psi", "t_C"} & given):
        raise ConfigError(
            f"data.{sorted({'k', 'g', 'psi', 't_C'} & given)[0]}: not used by model type elasticity"
        )
    if model != "elasticity" and cfg.get("obstacle"):
        raise ConfigError(
            "obstacle: only for model type elasticity (scalar models use data.g / data.psi)"
        )
    if model != "elasticity" and (cfg["model"]["E"] is not None):
        raise ConfigError("model.E: only for model type elasticity")
    if model == "signorini" and "psi" in given:
        raise ConfigError("data.psi: only for model type obstacle (Signorini uses data.g)")
    if model == "obstacle" and ({"g", "t_C"} & given):
        raise ConfigError(
            f"data.{sorted({'g', 't_C'} & given)[0]}: only for model type signorini "
            f"(obstacles use data.psi)"
        )
    if cfg["model"]["bound"] != "upper" and model == "signorini":
        raise ConfigError("model.bound: Signorini contact is always u ≤ g (upper)")
    _check_vector_data(cfg, model)
    _check_time(cfg)
    _check_friction(cfg, data)
    if cfg["estimator"] == "auto":  # the guaranteed bound where it is cheap (RESULTS.md §12)
        cfg["estimator"] = "equilibrated" if model in EQUILIBRATED_MODELS else "residual"
    _check_equilibrated(cfg)
    if cfg["solver"].stopping == "adaptive" and cfg["estimator"] not in EQUILIBRATED:
        raise ConfigError(
            "solver.stopping: adaptive needs estimator: equilibrated (the "
            "discretization error it balances against)"
        )
    if model == "elasticity":
        _check_bodies(cfg, constants)
        _check_elasticity(cfg)
    else:
        for key in ("bodies", "pairs"):
            if cfg[key]:
                raise ConfigError(f"{key}: only for model type elasticity")
        if "symmetry" in roles or "interface" in roles:
            role = "symmetry" if "symmetry" in roles else "interface"
            raise ConfigError(f"boundaries: role {role} is for elasticity scenes")
    if mesh["type"] in ("quarter_disk", "sphere_octant", "half_disks", "sphere_on_block"):
        for key in ("radius", "h", "h_contact", "zone") + (
            ("block",) if mesh["type"] == "sphere_on_block" else ()
        ):
            if mesh[key] is None:
                raise ConfigError(f"mesh.{key}: required for mesh type {mesh['type']!r}")
    if mesh["degree"] == 2 and cfg["pairs"]:
        raise ConfigError("mesh.degree: contact pairs (mortar) are implemented for P1; use 1")
    if cfg.get("reference"):
        _check_reference(cfg)
    if mesh["degree"] == 2 and (model == "obstacle" or mesh["type"] in ("box", "sphere_octant")):
        where = "an obstacle scene" if model == "obstacle" else "contact on a 3D mesh"
        raise ConfigError(
            f"mesh.degree: 2 does not work for {where} (P2 vertex basis functions "
            "integrate to ≤ 0 over triangles and tetrahedra, so the lumped weights "
            "vanish); use 1"
        )
    _resolve_formats(cfg["output"])
    cfg["constants"] = constants
    return SceneConfig.of_checked(cfg)


#: the message for an elastic 3D scene with the equilibrated estimator (also raised at
#: estimate time for a gmsh mesh, whose dimension the configuration does not show)
STRESS_3D = (
    "mesh.type: estimator: equilibrated for elasticity is 2D only (in 3D each vertex "
    "patch of the stress is a dense system of ~400 unknowns: too slow); use residual"
)


def _check_equilibrated(cfg: dict) -> None:
    """``estimator: equilibrated`` covers the scalar models and one linear elastic body
    against a rigid plane, frictionless or with Tresca friction (docs/theory.md §9); what
    it does not cover is refused by the key that asks for it."""
    model = cfg["model"]["type"]
    if cfg["estimator"] == "equilibrated_rt0":
        if model not in EQUILIBRATED_MODELS:
            raise ConfigError(
                "estimator: equilibrated_rt0 is the lowest-order flux of the scalar models "
                f"(signorini, obstacle), not model type {model}; use equilibrated or residual"
            )
        if cfg["mesh"]["degree"] != 1:
            raise ConfigError(
                "mesh.degree: estimator: equilibrated_rt0 is the lowest-order flux of a P1 "
                "solution; use 1, or estimator: equilibrated"
            )
        return
    if cfg["estimator"] != "equilibrated" or model in EQUILIBRATED_MODELS:
        return
    if model != "elasticity":
        raise ConfigError(
            "estimator: equilibrated is implemented for model types signorini, obstacle "
            f"and elasticity, not {model}; use residual"
        )
    if cfg["pairs"] or cfg["bodies"]:
        raise ConfigError(
            f"{'pairs' if cfg['pairs'] else 'bodies'}: estimator: equilibrated takes one "
            "elastic body against a rigid plane (two bodies: not implemented); use residual"
        )
    if (cfg.get("obstacle") or {}).get("type") != "plane":
        raise ConfigError(
            "obstacle.type: estimator: equilibrated needs a rigid plane (a circle's or "
            "sphere's normal varies along the contact surface: not implemented); use residual"
        )
    if cfg["friction"] is not None and cfg["friction"].law == "coulomb":
        raise ConfigError(
            "friction.law: estimator: equilibrated covers frictionless contact and Tresca "
            "friction, not coulomb; use residual"
        )
    mesh = cfg["mesh"]
    corners = (mesh.get("blocks") or [{}])[0].get("corners") if mesh["type"] == "blocks" else None
    if mesh["type"] in ("box", "sphere_octant", "sphere_on_block") or (
        corners is not None and len(corners[0]) == 3
    ):
        raise ConfigError(STRESS_3D)


def _check_hyperelastic(cfg: dict, model: str) -> None:
    """``model.law`` only and always for hyperelastic bodies; what the hyperelastic model
    does not do yet (contact/models/hyperelastic.py) is refused by name: contact pairs,
    the adaptive loop, a reference solution, an exact solution, grid sequencing, Coulomb's
    fixed point."""
    if model != "hyperelastic":
        if cfg["model"]["law"] is not None:
            raise ConfigError("model.law: only for model type hyperelastic")
        return
    if cfg["model"]["law"] is None:
        raise ConfigError(
            f"model.law: required for model type hyperelastic ({', '.join(HYPERELASTIC_LAWS)})"
        )
    obstacle = cfg.get("obstacle") or {}
    for key, what in (
        ("bodies", "several bodies"),
        ("pairs", "contact pairs"),
        ("adapt", "the adaptive loop"),
        ("reference", "a reference solution"),
    ):
        if cfg.get(key):
            raise ConfigError(f"{key}: not available for model type hyperelastic ({what})")
    friction = cfg["friction"]
    frictional = friction is not None and friction.law != "none"
    method = cfg["solver"].method
    if (obstacle.get("type", "plane") != "plane" or frictional) and method not in (
        "fb",
        "min",
        "blend",
    ):
        raise ConfigError(
            f"solver.method: {method} needs a gap affine in u (PETSc's VI bounds); a "
            "hyperelastic body against a circle or sphere, or with friction, takes fb, min "
            "or blend"
        )
    if frictional and friction.coulomb == "fixed_point":
        raise ConfigError(
            "friction.coulomb: fixed_point is not available for model type hyperelastic (use ssn)"
        )
    if cfg["data"]["exact"] is not None:
        raise ConfigError("data.exact: not available for model type hyperelastic")
    if cfg["solver"].sequence not in ("auto", "off", 0):
        raise ConfigError(
            "solver.sequence: grid sequencing is not available for model type "
            "hyperelastic (use off)"
        )
    cfg["solver"] = cfg["solver"].model_copy(update={"sequence": "off"})


def _resolve_formats(output: dict) -> None:
    """``output.xdmf`` / ``output.vtk`` (true or false) switch one format of
    ``output.formats`` on or off; afterwards ``formats`` alone says what is written."""
    for key in OUTPUT_FORMATS:
        switch = output.pop(key)
        if switch is True and key not in output["formats"]:
            output["formats"] = output["formats"] + [key]
        elif switch is False:
            output["formats"] = [f for f in output["formats"] if f != key]


GMSH_MESHES = ("gmsh", "quarter_disk", "sphere_octant", "half_disks", "sphere_on_block")


def _check_blocks(mesh: dict) -> int:
    """Mesh type blocks: a list of at least one {corners, cells} of one dimension; returns it."""
    blocks = mesh["blocks"]
    if not blocks:
        raise ConfigError(
            "mesh.blocks: required for mesh type 'blocks' (a list of {corners, cells})"
        )
    dims = 0
    for i, raw in enumerate(blocks):
        block = _validate(raw, BLOCK, f"mesh.blocks[{i}]", {})
        d = len(block["corners"][0])
        cells = block["cells"] if isinstance(block["cells"], list) else [block["cells"]] * d
        if len(cells) != d:
            raise ConfigError(
                f"mesh.blocks[{i}].cells: a {d}D block needs {d} cell counts, got "
                f"{block['cells']!r}"
            )
        if dims not in (0, d):
            raise ConfigError(f"mesh.blocks[{i}].corners: every block needs {dims}D points")
        dims = d
        blocks[i] = {"corners": block["corners"], "cells": cells}
    if dims == 3 and mesh["diagonal"] != "right":
        raise ConfigError("mesh.diagonal: not used by 3D blocks")
    if dims == 2 and mesh["diagonal"] not in ("left", "right"):
        raise ConfigError(f"mesh.diagonal: blocks take left or right, got {mesh['diagonal']!r}")
    return dims


def _check_bodies(cfg: dict, constants: Mapping[str, float]) -> None:
    """bodies (each with exactly one of tag / where), boundary parts' ``body``, and pairs:
    slave and master parts of role interface, of different bodies, each part in one pair."""
    bodies, parts, pairs = cfg["bodies"] or {}, cfg["boundaries"], cfg["pairs"]
    for name, body in bodies.items():
        if (body["where"] is None) == (body["tag"] is None):
            raise ConfigError(f"bodies.{name}: give exactly one of 'where' or 'tag'")
        if body["where"] is not None:
            try:
                expressions.parse(body["where"], constants)
            except expressions.ExpressionError as err:
                raise ConfigError(f"bodies.{name}.where: {err}") from None
    if bodies and cfg["model"]["E"] is not None:
        raise ConfigError("model.E: a scene with bodies gives E (and nu) per body")
    for pname, part in parts.items():
        if part["body"] is not None and part["body"] not in bodies:
            known = ", ".join(bodies) or "none"
            raise ConfigError(
                f"boundaries.{pname}.body: {part['body']!r} is not a body (bodies: {known})"
            )
    if pairs and not bodies:
        raise ConfigError("pairs: contact pairs need a bodies section (one material per body)")
    used: dict[str, str] = {}
    for i, raw in enumerate(pairs or []):
        pair = _validate(raw, PAIR, f"pairs[{i}]", constants)
        pairs[i] = pair
        for side in ("slave", "master"):
            name = pair[side]
            if name not in parts:
                raise ConfigError(f"pairs[{i}].{side}: {name!r} is not a boundary part")
            if parts[name]["role"] != "interface":
                raise ConfigError(
                    f"pairs[{i}].{side}: boundary part {name!r} needs role: interface"
                )
            if name in used:
                raise ConfigError(
                    f"pairs[{i}].{side}: boundary part {name!r} is already the {used[name]}"
                )
            used[name] = f"{side} of pairs[{i}]"
    for pname, part in parts.items():
        if part["role"] == "interface" and pname not in used:
            raise ConfigError(
                f"boundaries.{pname}: a part with role interface must be the slave or "
                "master of a contact pair (pairs)"
            )


def _check_vector_data(cfg: dict, model: str) -> None:
    """Vector data (lists) only for elasticity (where a single expression means every
    component, so the default "0" is the zero vector)."""
    for key in ("f", "u_D", "t", "exact"):
        if isinstance(cfg["data"][key], list) and model != "elasticity":
            raise ConfigError(f"data.{key}: a list of components is only for model type elasticity")
    if isinstance(cfg["solver"].u0, tuple) and model != "elasticity":
        raise ConfigError("solver.u0: a list of components is only for model type elasticity")


def _check_time(cfg: dict) -> None:
    """The pseudo-time t is for data only (the mesh and its parts are fixed along a load
    path); ``load`` takes steps or times, not both."""
    constants = cfg["constants"]
    for key, texts in (
        ("mesh.map", cfg["mesh"]["map"] or []),
        *((f"boundaries.{n}.where", [p["where"]]) for n, p in cfg["boundaries"].items()),
    ):
        if any(t is not None and expressions.uses_time(t, constants) for t in texts):
            raise ConfigError(
                f"{key}: the pseudo-time t is only for data expressions (the mesh is fixed)"
            )
    load = cfg.get("load")
    if load is not None:
        if (load["steps"] is None) == (load["times"] is None):
            raise ConfigError("load: give exactly one of 'steps' or 'times'")
        if load["steps"] is not None:
            load["times"] = [(k + 1) / load["steps"] for k in range(load["steps"])]
        load["times"] = [float(t) for t in load["times"]]


def _check_friction(cfg: dict, data: Mapping) -> None:
    """Friction needs elastic contact, and the keys of its law (Tresca: a threshold;
    Coulomb: a coefficient, and not the other law's keys); PETSc's VI solvers cannot solve it.
    ``law: none`` ignores the other keys."""
    fr = cfg.get("friction")
    if fr is None:
        return
    given = {k for k, v in (data.get("friction") or {}).items() if v is not None}
    law = fr.law
    # frictionless: the other keys are ignored (--set friction.law=none switches it off)
    if law == "none":
        return
    if cfg["model"]["type"] not in ELASTIC_MODELS:
        raise ConfigError(
            f"friction.law: {law} friction needs model type elasticity or hyperelastic "
            f"(a {cfg['model']['type']} scene has no tangential direction)"
        )
    need = {"tresca": "threshold", "coulomb": "coefficient"}.get(law)
    if need is not None and getattr(fr, need) is None:
        raise ConfigError(f"friction.{need}: required for friction law {law}")
    unused = sorted(
        given
        - {"law", need, "c_t", "kappa_t", "form"}
        - ({"coulomb", "fixed_point_rtol", "fixed_point_max_it"} if law == "coulomb" else set())
    )
    if unused:
        raise ConfigError(f"friction.{unused[0]}: not used by friction law {law}")
    if law != "none" and cfg["solver"].method not in ("fb", "min", "blend"):
        raise ConfigError(
            f"solver.method: {cfg['solver'].method} cannot solve frictional contact "
            f"(friction.law: {law}); use fb, min or blend"
        )


def _check_reference(cfg: dict) -> None:
    """A declared reference fits the scene: Hertz needs elastic contact and a radius (given,
    or the radius of a built-in quarter_disk / sphere_octant / sphere_on_block, the effective
    radius R1 R2 / (R1 + R2) of half_disks, filled in here).  With contact pairs the radius is
    the effective one, 1/R = 1/R1 + 1/R2, and E* comes from the two bodies of the first pair."""
    ref = cfg["reference"]
    if ref["type"] == "cattaneo_mindlin" and (
        cfg["friction"] is None or cfg["friction"].law != "coulomb"
    ):
        raise ConfigError(
            "reference.type: cattaneo_mindlin needs Coulomb friction (friction.law: coulomb)"
        )
    if ref["type"] in ("hertz", "cattaneo_mindlin"):
        if cfg["model"]["type"] != "elasticity":
            raise ConfigError(f"reference.type: {ref['type']} needs model type elasticity")
        mesh = cfg["mesh"]
        if ref["radius"] is None:
            if mesh["type"] not in (
                "quarter_disk",
                "sphere_octant",
                "half_disks",
                "sphere_on_block",
            ):
                raise ConfigError(
                    f"reference.radius: required for type {ref['type']} (the radius R of the "
                    "curved body, the effective radius of two) unless the mesh is a "
                    "quarter_disk, sphere_octant, half_disks or sphere_on_block"
                )
            R1 = float(mesh["radius"])
            R2 = float(mesh["radius2"] or R1) if mesh["type"] == "half_disks" else None
            ref["radius"] = R1 if R2 is None else R1 * R2 / (R1 + R2)


def _check_elasticity(cfg: dict) -> None:
    if cfg["model"]["E"] is None and not cfg["bodies"]:
        raise ConfigError(
            f"model.E: required for model type {cfg['model']['type']} (Young's modulus)"
        )
    obstacle = cfg.get("obstacle")
    contact_parts = [n for n, p in cfg["boundaries"].items() if p["role"] == "contact"]
    if obstacle and not contact_parts:
        raise ConfigError(
            "obstacle: needs a boundary part with role: contact (the surface it touches)"
        )
    if not obstacle and cfg["pairs"] and not contact_parts:
        return
    if not obstacle:
        raise ConfigError(
            "obstacle: an elasticity scene needs a rigid obstacle (type plane, circle or "
            "sphere) or contact pairs between bodies (pairs)"
        )
    keys = ("point", "normal") if obstacle["type"] == "plane" else ("center", "radius")
    for key in keys:
        if obstacle[key] is None:
            raise ConfigError(
                f"obstacle.{key}: required for an obstacle of type {obstacle['type']}"
            )
    for key in ("point", "normal", "center", "radius"):
        if obstacle[key] is not None and key not in keys:
            raise ConfigError(f"obstacle.{key}: not used by an obstacle of type {obstacle['type']}")
    for key in keys[:2] if obstacle["type"] == "plane" else ("center",):
        vec = obstacle[key]
        if key in ("point", "center") and all(
            isinstance(c, (str, int, float)) and not isinstance(c, bool) for c in vec
        ):
            _check_moving_point(vec, cfg["constants"], key)
            continue
        if not all(
            isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c)
            for c in vec
        ):
            raise ConfigError(f"obstacle.{key}: expected a list of numbers, got {vec!r}")
    if obstacle["type"] == "plane" and not any(obstacle["normal"]):
        raise ConfigError("obstacle.normal: must not be the zero vector")


def _check_moving_point(point: list, constants: Mapping[str, float], key: str = "point") -> None:
    """obstacle.point / obstacle.center: numbers, or expressions of constants and the
    pseudo-time t only."""
    for c in point:
        try:
            tree = expressions.parse(c, constants)
        except expressions.ExpressionError as err:
            raise ConfigError(f"obstacle.{key}: {err}") from None
        names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
        if names & set(expressions.COORDINATES + expressions.HELPERS):
            raise ConfigError(f"obstacle.{key}: {c!r} may use the pseudo-time t, not x, y, z")


def load_config(
    source: str | Path | Mapping, overrides: list[str] | tuple[str, ...] = ()
) -> SceneConfig:
    """Read (if a path), apply ``--set`` overrides and validate a scene: its typed,
    immutable config."""
    if isinstance(source, Mapping):
        return validate_scene(apply_overrides(dict(source), overrides))
    path = Path(source)
    data = apply_overrides(read_yaml(path), overrides)
    return validate_scene(data, base_dir=path.parent, name=path.stem)
