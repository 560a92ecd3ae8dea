"""The scene's schema: every section of a scene file as a frozen pydantic model, with the
one-line messages users read (``mesh.cells: must be a positive integer or a list of
positive integers, got 0``).  :class:`SceneConfig` is the validated scene, read by
attribute everywhere after loading (``scene.config.solver.method``); nothing downstream of
:mod:`contact.setup` sees a dict.

**Why pydantic v2**: the solver's options are a frozen pydantic model
(:class:`~contact.solvers.options.SolverOptions`) whose field types the scene shares
(:mod:`contact.base.validation`: each type checks its value itself and raises our text, so
pydantic's own wording never reaches a user); pydantic's errors carry the key path the
messages name; ``frozen=True`` makes "validated once" structural — a section cannot change
after it was checked, so no solve checks it again; nested models, defaults and
``model_copy`` give one declaration per key and cheap changed copies (grid sequencing's
coarser meshes).  Lists become tuples and mappings :class:`FrozenDict`, so no part of the
tree can be changed in place.

**How a scene is checked** (:func:`contact.setup.config.load_config`): each section checks
its own keys — types, ranges, choices, unknown keys, and the rules among its keys (a mesh
type's keys, the steps or times of a load path) — and fills in what its other keys imply
(a rectangle's default corners, ``load.times`` from ``load.steps``); then the rules across
sections (:mod:`contact.setup.scene_rules`) run once, in a fixed order, and complete what
depends on several sections (``estimator: auto``, the radius of a Hertz reference).  Of
several errors, the first in the order of the keys is reported
(:func:`contact.base.validation.config_error`).  The expressions' validators read the
scene's ``constants`` from the validation context, which :func:`SceneConfig.parse` fills.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

from pydantic import (
    AfterValidator,
    BeforeValidator,
    Field,
    SkipValidation,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from ..base import expressions
from ..base.errors import ConfigError
from ..base.validation import (
    FrozenDict,
    Section,
    a_list,
    among,
    below,
    block_pair,
    boolean,
    checked,
    fail,
    half_open_unit,
    integer,
    nonnegative,
    number,
    one_of,
    open_unit,
    parse_section,
    positive,
    rule,
    string,
    string_keys,
    typename,
)
from ..solvers.options import AdaptOptions, FrictionOptions, SolverOptions

#: models whose unknown is a displacement vector: linear elasticity (small strain) and
#: hyperelastic bodies (finite strain, contact/models/hyperelastic.py)
ELASTIC_MODELS = ("elasticity", "hyperelastic")
MODELS = ("signorini", "obstacle", *ELASTIC_MODELS)
HYPERELASTIC_LAWS = ("neo_hookean", "saint_venant_kirchhoff")
FRICTION_LAWS = ("none", "tresca", "coulomb")
STRATEGIES = ("dorfler", "maximum", "uniform", "hp", "none")
#: the largest polynomial degree ``adapt.p_max`` accepts (Lagrange P_{p_max} carries V_hp)
MAX_DEGREE = 8
MESH_TYPES = (
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
    "ring",
)
#: the keys each mesh type takes (besides ``type`` and ``degree``)
MESH_KEYS = {
    "rectangle": {"corners", "cells", "diagonal", "map"},
    "unit_square": {"cells", "diagonal", "map"},
    "box": {"corners", "cells", "map"},
    "lshape": {"cells", "diagonal", "map"},
    "gmsh": {"file"},
    "quarter_disk": {"radius", "h", "h_contact", "zone"},
    "sphere_octant": {"radius", "h", "h_contact", "zone"},
    "blocks": {"blocks", "diagonal"},
    "half_disks": {"radius", "radius2", "h", "h_contact", "zone", "overlap", "geometry_degree"},
    "sphere_on_block": {"radius", "block", "h", "h_contact", "zone", "geometry_degree"},
    "ring": {"radius", "inner_radius", "cells", "diagonal"},
}
#: the mesh types whose boundary parts may be gmsh tags
GMSH_MESHES = ("gmsh", "quarter_disk", "sphere_octant", "half_disks", "sphere_on_block")
#: the built-in gmsh meshes of a curved body (their radius is a Hertz reference's)
CURVED_MESHES = ("quarter_disk", "sphere_octant", "half_disks", "sphere_on_block")
#: how a rectangle's squares are cut into triangles
DIAGONALS = ("left", "right", "crossed", "left/right", "right/left")
ROLES = ("dirichlet", "neumann", "contact", "symmetry", "interface", "natural")
#: the guaranteed bounds (docs/theory.md §9): σ_h ∈ RT_p, or RT_0 for a P1 solution
EQUILIBRATED = ("equilibrated", "equilibrated_rt0")
ESTIMATORS = ("auto", "residual", *EQUILIBRATED)
OUTPUT_FORMATS = ("xdmf", "vtk")
#: the longest load path: as many steps as an explicit ``times`` list can have items (a scene
#: file holds at most contact.setup.config.MAX_YAML_NODES nodes); every step is at least one
#: Newton solve and a row of each per-step output, so 10⁵ steps of the smallest mesh already
#: take hours
MAX_LOAD_STEPS = 100_000
#: ``load.cuts`` at most: a step halved this many times in a row is 2^-20 ≈ 1e-6 of itself
MAX_STEP_CUTS = 20


# ------------------------------------------------------------------------- field types
def _constants(info: ValidationInfo) -> Mapping[str, float]:
    return (info.context or {}).get("constants", {})


def _expression(v: Any, info: ValidationInfo) -> str:
    """One data expression in x, y, z, t and the scene's ``constants`` (the validation
    context), kept as its text."""
    try:
        expressions.parse(v, _constants(info))
    except expressions.ExpressionError as err:
        raise fail(str(err)) from None
    return str(v)


def _expressions(v: Any, info: ValidationInfo) -> str | tuple[str, ...]:
    """An expression, or a non-empty list of them (one per component of a vector)."""
    if not isinstance(v, (list, tuple)):
        return _expression(v, info)
    if not v:
        raise fail("expected an expression or a non-empty list of them")
    out = []
    for i, item in enumerate(v):
        try:
            out.append(_expression(item, info))
        except PydanticCustomError as err:
            raise fail(str((err.context or {})["text"]), key=f"[{i}]") from None
    return tuple(out)


def _predicate(v: Any, info: ValidationInfo) -> str:
    """A predicate in x, y, z selecting facets or cells (``where``): a string, then an
    expression (checked as a :func:`~contact.base.validation.rule`, with the others)."""
    try:
        return _expression(string()(v), info)
    except PydanticCustomError as err:
        if err.message().startswith("expected a string"):
            raise
        raise rule(err.message()) from None


def _coordinate_map(v: Any, info: ValidationInfo) -> tuple[str, ...]:
    """``mesh.map``: a list of expressions, one per coordinate."""
    value = _expressions(v, info)
    if not isinstance(value, tuple):
        raise fail(
            f"expected a list of expressions, one per coordinate, got {typename(value)} {value!r}"
        )
    return value


Expression = Annotated[str, BeforeValidator(_expression)]
#: an expression, or one per component (elasticity): a tuple
Expressions = Annotated[str | tuple[str, ...], BeforeValidator(_expressions)]
Predicate = Annotated[str, BeforeValidator(_predicate)]
#: a coordinate as the scene gives it (an int stays an int, so that messages quote it as given)
Number = int | float
String = Annotated[str, BeforeValidator(string())]
Integer = Annotated[int, BeforeValidator(integer())]
Positive = Annotated[float, BeforeValidator(number(positive))]
Float = Annotated[float, BeforeValidator(number())]


def _poisson(v: Any) -> str | None:
    return None if -1 < v < 0.5 else f"must lie in (-1, 0.5), got {v}"


#: Poisson's ratio: the elastic energy is positive definite for -1 < ν < 1/2
Poisson = Annotated[float, BeforeValidator(number(_poisson))]


def _as_tuple(v: Any) -> tuple:
    return tuple(a_list()(v))


#: a list kept as the scene gives it (a tuple), its items checked by the rules across
#: sections (:mod:`.scene_rules`), which know what the list is for
Loose = BeforeValidator(_as_tuple)


def components(value: str | tuple[str, ...], n: int) -> tuple[str, ...]:
    """The ``n`` component expressions of a datum: its own, or one expression for all."""
    return value if isinstance(value, tuple) else (value,) * n


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


def _cells(v: Any) -> str | None:
    items = v if isinstance(v, list) else [v]
    if not items or not all(
        isinstance(n, int) and not isinstance(n, bool) and n > 0 for n in items
    ):
        return f"must be a positive integer or a list of positive integers, got {v!r}"
    return None


def _point_list(v: Any) -> str | None:
    ok = (
        len(v) == 2
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


def _numbers(*lengths: int) -> Any:
    def check(v: Any) -> str | None:
        ok = len(v) in lengths and all(
            isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in v
        )
        return (
            None if ok else f"expected {' or '.join(map(str, lengths))} finite numbers, got {v!r}"
        )

    return BeforeValidator(a_list(check))


Corners = Annotated[tuple[tuple[float, ...], ...], BeforeValidator(a_list(_point_list))]
Cells = Annotated[tuple[int, ...] | int, BeforeValidator(checked(_cells))]


def _listed(value: Any) -> Any:
    """A value as the scene gave it, for messages (tuples were lists)."""
    return [_listed(v) for v in value] if isinstance(value, tuple) else value


# ------------------------------------------------------------------ the solver section
def _sequence(v: Any) -> str | int:
    # YAML 1.1 reads an unquoted `off` (`sequence: off`, `--set solver.sequence=off`) as false
    if v is False:
        return "off"
    if v in ("auto", "off") or (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
        return v
    raise fail(f"must be auto, off or a number of coarser levels >= 0, got {v!r}")


def _max_dofs(v: Any) -> str | None:
    if v == "auto" or isinstance(v, int) and not isinstance(v, bool) and v > 0:
        return None
    return f"must be 'auto' or a positive integer, got {v!r}"


#: the keys of a scene's ``solver`` section, in the order its messages list them
SOLVER_KEYS = (
    "method",
    "mu",
    "c",
    "kappa",
    "line_search",
    "polish",
    "rtol",
    "atol",
    "max_it",
    "u0",
    "linear",
    "inexact",
    "forcing",
    "predictor",
    "epsilon0",
    "r0",
    "gamma0",
    "nitsche_theta",
    "uzawa_rtol",
    "uzawa_max_it",
    "sequence",
    "max_dofs",
    "petsc_options",
    "stopping",
    "gamma_lin",
    "gamma_alg",
)


class SolverConfig(SolverOptions, Section):
    """A scene's ``solver`` section: the solver's knobs (:class:`SolverOptions`, what the
    solver receives: :meth:`knobs`) and the driver's: ``u0`` — the initial guess, an
    expression (every component) or one per component; ``sequence`` — grid sequencing of
    a single solve, ``auto``, ``off`` or the number of coarser levels (at ``mesh.degree``
    2 the finest of them is P1 on the same mesh); ``max_dofs`` — the
    DoF budget of one solve, ``auto`` (:mod:`contact.setup.budget`) or a number;
    ``stopping`` — ``fixed`` or ``adaptive`` (:mod:`contact.solvers.stopping`) with its
    ``gamma_lin``, ``gamma_alg``."""

    KEYS: ClassVar[tuple[str, ...]] = SOLVER_KEYS
    KEYWORDS: ClassVar[bool] = True  # also the keywords of contact.solve: None = not given

    u0: Expressions = "0"
    sequence: Annotated[str | int, BeforeValidator(_sequence)] = "auto"
    max_dofs: Annotated[Literal["auto"] | int, BeforeValidator(checked(_max_dofs))] = "auto"
    stopping: Annotated[str, BeforeValidator(one_of(("fixed", "adaptive")))] = "fixed"
    gamma_lin: Annotated[float, BeforeValidator(number(open_unit))] = 0.1
    gamma_alg: Annotated[float, BeforeValidator(number(open_unit))] = 0.1

    @classmethod
    def parse(
        cls, values: Mapping[str, Any], path: str = "solver", constants: Mapping = {}
    ) -> SolverConfig:
        """The section of keyword ``values`` (None: the default), validated: one
        ConfigError line ``<path>.<key>: …``.

        Args:
            values: the section's keys.
            path: the key path its messages name.
            constants: the scene's constants (for the expression ``u0``).

        Returns:
            The validated section.
        """
        return parse_section(cls, values, path, {"constants": constants})

    def updated(self, constants: Mapping[str, float] = {}, **changes: Any) -> SolverConfig:
        """A copy with keyword ``changes``, each validated as in the scene file
        (``solver.<key>: …`` on a bad one); the rest is not checked again.

        Args:
            constants: the scene's constants (for the expression ``u0``).
            **changes: new values of keys (None: unchanged).

        Returns:
            The changed copy (this section itself without changes).
        """
        given = {k: v for k, v in changes.items() if v is not None}
        if not given:
            return self
        checked_ = SolverConfig.parse(given, "solver", constants)
        return self.model_copy(update={k: getattr(checked_, k) for k in given})


# -------------------------------------------------------------------- the adapt section
#: the marking fraction θ of Dörfler's strategy, in (0, 1]
Fraction = Annotated[float, BeforeValidator(number(half_open_unit))]
NonNegative = Annotated[float, BeforeValidator(number(nonnegative))]
Count = Annotated[int, BeforeValidator(integer(positive))]


def _degree(v: int) -> str | None:
    return None if 1 <= v <= MAX_DEGREE else f"must lie in 1..{MAX_DEGREE}, got {v}"


#: a polynomial degree of V_hp (1 … MAX_DEGREE)
Degree = Annotated[int, BeforeValidator(integer(_degree))]
Switch = Annotated[bool, BeforeValidator(boolean)]


class AdaptConfig(AdaptOptions, Section):
    """A scene's ``adapt`` section (docs/theory.md §6): the loop's knobs
    (:class:`~contact.solvers.options.AdaptOptions`: ``strategy``, ``theta``, ``growth``, ``tol``,
    ``max_dofs``, ``max_levels``, ``estimate_last``, ``nested``, ``rebalance``,
    ``newton_rtol``), ``strategy`` also hp (Dörfler, then h or p per marked cell:
    :mod:`contact.hp`), ``pictures`` —
    levels drawn; ``p_max``, ``p_start`` — with ``hp``, the largest degree and every
    cell's first degree."""

    KEYWORDS: ClassVar[bool] = True  # also the keywords of contact.adapt: None = not given
    strategy: Annotated[str, BeforeValidator(one_of(STRATEGIES))] = "dorfler"
    pictures: Annotated[int, BeforeValidator(integer(nonnegative))] = 3
    p_max: Degree = 6
    p_start: Degree = 1

    @classmethod
    def parse(cls, values: Mapping[str, Any], path: str = "adapt") -> AdaptConfig:
        """The section of keyword ``values`` (None: the default), validated.

        Args:
            values: the section's keys.
            path: the key path its messages name.

        Returns:
            The validated section.
        """
        return parse_section(cls, values, path)

    def updated(self, **changes: Any) -> AdaptConfig:
        """A copy with keyword ``changes``, each validated as in the scene file
        (``adapt.<key>: …``).

        Args:
            **changes: new values of keys (None: unchanged).

        Returns:
            The changed copy (this section itself without changes).
        """
        given = {k: v for k, v in changes.items() if v is not None}
        if not given:
            return self
        checked_ = AdaptConfig.parse(given)
        return self.model_copy(update={k: getattr(checked_, k) for k in given})


# ----------------------------------------------------------------- the friction section
class FrictionConfig(FrictionOptions, Section):
    """A scene's ``friction`` section: the law (``none``, ``tresca``, ``coulomb``), its data
    (Coulomb's ``coefficient`` F, dimensionless; Tresca's slip ``threshold`` s(x, t) ≥ 0, a
    stress) and the solver's tangential knobs (:class:`FrictionOptions`: :meth:`knobs`)."""

    KEYS: ClassVar[tuple[str, ...]] = (
        "law",
        "coefficient",
        "threshold",
        *FrictionOptions.model_fields,
    )
    KEYWORDS: ClassVar[bool] = True  # None = not given, as for the solver's section

    law: Annotated[str, BeforeValidator(one_of(FRICTION_LAWS))] = "none"
    coefficient: Annotated[float | None, BeforeValidator(number(nonnegative))] = None
    threshold: Expression | None = None

    @classmethod
    def parse(
        cls, values: Mapping[str, Any], path: str = "friction", constants: Mapping = {}
    ) -> FrictionConfig:
        """The section of keyword ``values`` (None: the default), validated.

        Args:
            values: the section's keys.
            path: the key path its messages name.
            constants: the scene's constants (for the expression ``threshold``).

        Returns:
            The validated section.
        """
        return parse_section(cls, values, path, {"constants": constants})


#: the keys of a scene's ``friction`` section, in the order its messages list them
FRICTION_KEYS = FrictionConfig.KEYS


# ------------------------------------------------------------------------ the mesh
class Block(Section):
    """One block of mesh type ``blocks``: two opposite corners, cells per direction (one
    count for every direction, or one each)."""

    corners: Corners
    cells: tuple[int, ...]

    @field_validator("cells", mode="before")
    @classmethod
    def _per_direction(cls, cells: Any, info: ValidationInfo) -> Any:
        cells = checked(_cells)(cells)
        corners = info.data.get("corners")
        return (cells,) * len(corners[0]) if corners and isinstance(cells, int) else cells

    @model_validator(mode="after")
    def _dimension(self) -> Block:
        d = len(self.corners[0])
        if len(self.cells) != d:
            raise rule(
                f"a {d}D block needs {d} cell counts, got {_listed(self.cells)!r}", key="cells"
            )
        return self


class MeshConfig(Section):
    """The ``mesh`` section: its ``type`` and the keys of that type (the others are None,
    or their default).  ``corners`` / ``cells`` of a rectangle, unit_square, box or lshape
    are filled in (the unit square or cube; one count per direction); the file of mesh
    type gmsh is made absolute (relative to the scene file) and must exist."""

    type: Annotated[str, BeforeValidator(one_of(MESH_TYPES))] = "rectangle"
    corners: Corners | None = Field(None, validate_default=True)
    cells: Cells = Field(16, validate_default=True)
    diagonal: Annotated[
        str, BeforeValidator(one_of(("left", "right", "crossed", "left/right", "right/left")))
    ] = "right"
    file: String | None = Field(None, validate_default=True)
    degree: Annotated[int, BeforeValidator(integer(among((1, 2))))] = 1
    #: quarter_disk / sphere_octant / half_disks / sphere_on_block: the radius R
    radius: Float | None = None
    #: the mesh size away from contact
    h: Float | None = None
    #: the mesh size at the contact point
    h_contact: Float | None = None
    #: the radius of the fine zone
    zone: Float | None = None
    #: half_disks: radius of the lower disk (default: radius)
    radius2: Float | None = None
    #: half_disks: the lower disk moved up by this much (an interference load)
    overlap: Float | None = None
    #: half_disks / sphere_on_block: the degree of the coordinate element, 2 for curved
    #: (isoparametric P2) cells whose boundary edges' midpoints lie on the arcs / the
    #: sphere (needs ``degree`` 2)
    geometry_degree: Annotated[int, BeforeValidator(integer(among((1, 2))))] = 1
    #: ring: the radius of the hole (``radius`` the outer one)
    inner_radius: Positive | None = None
    #: sphere_on_block: [half-width, depth] of the block
    block: Annotated[tuple[Number, ...] | None, BeforeValidator(a_list(block_pair))] = None
    #: blocks: a list of {corners, cells}, one body each (cell tags 1, 2, …)
    blocks: Annotated[tuple[Block, ...] | None, SkipValidation, Loose] = None
    #: new vertex coordinates [x', y'(, z')] as expressions in the built mesh's x, y, z,
    #: applied before the boundary parts are tagged (rectangle / unit_square / box / lshape)
    map: Annotated[tuple[str, ...] | None, BeforeValidator(_coordinate_map)] = None

    @field_validator("corners")
    @classmethod
    def _corners(cls, corners: Any, info: ValidationInfo) -> Any:
        dims = {"rectangle": 2, "box": 3}.get(info.data.get("type") or "")
        return ((0.0,) * dims, (1.0,) * dims) if corners is None and dims else corners

    @field_validator("cells")
    @classmethod
    def _cells(cls, cells: Any, info: ValidationInfo) -> Any:
        """One count for every direction: a count per direction."""
        dims = {"rectangle": 2, "unit_square": 2, "lshape": 1, "box": 3, "ring": 2}.get(
            info.data.get("type") or ""
        )
        return (cells,) * dims if dims and isinstance(cells, int) else cells

    @field_validator("file")
    @classmethod
    def _file(cls, file: str | None, info: ValidationInfo) -> str | None:
        """A gmsh file relative to the scene's folder (the validation context's
        ``base_dir``), made absolute."""
        if file is None or Path(file).is_absolute():
            return file
        return str(Path((info.context or {}).get("base_dir", ".")) / file)

    @field_validator("blocks")
    @classmethod
    def _blocks(cls, blocks: tuple | None, info: ValidationInfo) -> tuple | None:
        """The blocks of mesh type blocks (of another type: not used), one by one."""
        if blocks is None or info.data.get("type") != "blocks":
            return blocks
        checked_ = []
        for i, raw in enumerate(blocks):
            try:
                checked_.append(Block.model_validate(raw, context=info.context))
            except ValidationError as err:
                raise below(err, Block, f"[{i}]") from None
            dims = len(checked_[0].corners[0])
            if len(checked_[-1].corners[0]) != dims:
                raise rule(f"every block needs {dims}D points", key=f"[{i}].corners")
        return tuple(checked_)

    @model_validator(mode="after")
    def _type_keys(self) -> MeshConfig:
        """The keys of the mesh type, and what they need of each other."""
        for key in type(self).model_fields:
            if key in self.model_fields_set and key not in MESH_KEYS[self.type] | {
                "type",
                "degree",
            }:
                raise rule(f"not used by mesh type {self.type!r}", key=key)
        if self.type == "gmsh":
            if self.file is None:
                raise rule("required for mesh type 'gmsh'", key="file")
            if not Path(self.file).is_file():
                raise rule(f"no such file {self.file!r}", key="file")
        dims = {"rectangle": 2, "unit_square": 2, "lshape": 2, "box": 3, "ring": 2}.get(self.type)
        if self.type == "ring":
            self._check_ring()
        if self.type in ("rectangle", "box") and len((self.corners or ((),))[0]) != dims:
            raise rule(f"a {self.type} needs {dims}D points", key="corners")
        if dims is not None:
            want = 1 if self.type == "lshape" else dims
            if len(self.cells if isinstance(self.cells, tuple) else (self.cells,)) != want:
                raise rule(
                    f"a {self.type} mesh needs {want} cell count(s), got {_listed(self.cells)!r}",
                    key="cells",
                )
        if self.type == "blocks":
            dims = self._check_blocks()
        if self.map is not None and len(self.map) != dims:
            raise rule(
                f"expected {dims} expressions for a {dims}D mesh, got {len(self.map)}", key="map"
            )
        if self.geometry_degree > self.degree:
            raise rule(
                f"curved cells of degree {self.geometry_degree} carry isoparametric "
                f"displacements; needs mesh.degree {self.geometry_degree}",
                key="geometry_degree",
            )
        if self.type in CURVED_MESHES:
            for key in ("radius", "h", "h_contact", "zone") + (
                ("block",) if self.type == "sphere_on_block" else ()
            ):
                if getattr(self, key) is None:
                    raise rule(f"required for mesh type {self.type!r}", key=key)
        return self

    def _check_ring(self) -> None:
        """Mesh type ring: both radii, the hole inside, at least 3 cells around, left or
        right diagonals."""
        for key in ("radius", "inner_radius"):
            if getattr(self, key) is None:
                raise rule("required for mesh type 'ring'", key=key)
        assert self.radius is not None and self.inner_radius is not None
        if not 0 < self.inner_radius < self.radius:
            raise rule(
                f"must lie between 0 and radius {self.radius:g}, got {self.inner_radius:g}",
                key="inner_radius",
            )
        cells = self.cells if isinstance(self.cells, tuple) else (self.cells,)
        if len(cells) == 2 and cells[0] < 3:
            raise rule(f"a ring needs at least 3 cells around, got {cells[0]}", key="cells")
        if self.diagonal not in ("left", "right"):
            raise rule(f"a ring takes left or right, got {self.diagonal!r}", key="diagonal")

    def _check_blocks(self) -> int:
        """Mesh type blocks: at least one block (all of one dimension); returns it."""
        if not self.blocks:
            raise rule("required for mesh type 'blocks' (a list of {corners, cells})", key="blocks")
        dims = len(self.blocks[0].corners[0])
        if dims == 3 and self.diagonal != "right":
            raise rule("not used by 3D blocks", key="diagonal")
        if dims == 2 and self.diagonal not in ("left", "right"):
            raise rule(f"blocks take left or right, got {self.diagonal!r}", key="diagonal")
        return dims


# ---------------------------------------------------------------- boundaries and bodies
class SurfaceSpec(Section):
    """The exact curve / surface a boundary part lies on (circle 2D; sphere, cylinder 3D):
    refinement moves the part's new vertices onto it."""

    type: Annotated[str, BeforeValidator(one_of(("circle", "sphere", "cylinder")))]
    center: Annotated[tuple[Number, ...], _numbers(2, 3)]
    radius: Positive
    axis: Annotated[tuple[Number, ...] | None, _numbers(3)] = None


class BoundaryPart(Section):
    """A named part of the boundary: its ``role`` — Dirichlet (u = u_D), Neumann (flux t),
    natural (zero flux, traction-free: declared), contact (with the rigid obstacle),
    symmetry (elasticity: zero normal displacement on a plane x_k = const) or interface (a
    surface of a contact pair) — and its facets: ``where`` (a predicate in x, y, z all their
    vertices satisfy), a gmsh ``tag`` (with ``where``: those of its facets where it holds),
    ``body`` (only the facets of this body); optionally the ``surface`` it lies on."""

    role: Annotated[str, BeforeValidator(one_of(ROLES))]
    where: Predicate | None = None
    tag: Integer | None = None
    body: String | None = None
    surface: SurfaceSpec | None = None

    @model_validator(mode="after")
    def _facets(self) -> BoundaryPart:
        if self.where is None and self.tag is None:
            raise rule("give 'where' or 'tag' (or both: the tag's facets where it holds)")
        return self


class BodyConfig(Section):
    """A body of a scene with several: its cells (a cell ``tag`` of the mesh, or a
    ``where`` predicate on the cell midpoints: exactly one) and its material."""

    tag: Integer | None = None
    where: Predicate | None = None
    E: Positive
    nu: Poisson = 0.3


class PairConfig(Section):
    """A contact pair: the ``slave`` part (role interface) carrying the multiplier, the
    ``master`` part of another body, and the ``search`` distance: the largest normal
    distance between a slave facet and a master facet it is paired with (default: the
    diameter of the two surfaces' bounding box)."""

    slave: String
    master: String
    search: Positive | None = None


class ModelConfig(Section):
    """The ``model`` section: its ``type``; a hyperelastic body's ``law`` (neo_hookean,
    saint_venant_kirchhoff); an obstacle problem's ``bound`` (u ≤ ψ upper, u ≥ ψ lower);
    the material of one elastic body (Young's modulus ``E``, Poisson's ratio ``nu``)."""

    type: Annotated[str, BeforeValidator(one_of(MODELS))] = "signorini"
    law: Annotated[str, BeforeValidator(one_of(HYPERELASTIC_LAWS))] | None = None
    bound: Annotated[str, BeforeValidator(one_of(("upper", "lower")))] = "upper"
    E: Positive | None = None
    nu: Poisson = 0.3


class ObstacleConfig(Section):
    """A rigid obstacle: a plane (``point`` and outward ``normal``, pointing towards the
    body), a circle or a sphere (``center``, ``radius``); the point's or centre's
    coordinates may be expressions of the pseudo-time t (an obstacle moved along a load
    path).  Which keys a type takes, and their coordinates, are checked with the model
    (:mod:`.scene_rules`)."""

    type: Annotated[str, BeforeValidator(one_of(("plane", "circle", "sphere")))] = "plane"
    point: Annotated[tuple[Number | str, ...] | None, SkipValidation, Loose] = None
    normal: Annotated[tuple[Number, ...] | None, SkipValidation, Loose] = None
    center: Annotated[tuple[Number | str, ...] | None, SkipValidation, Loose] = None
    radius: Positive | None = None


class ReferenceConfig(Section):
    """A declared reference solution (docs/theory.md §7): its ``type`` — hertz, or
    cattaneo_mindlin (partial slip of two similar bodies, Coulomb friction) — and the
    ``radius`` R of the curved body (the effective radius of two; filled in from a built-in
    curved mesh where the scene leaves it out)."""

    type: Annotated[str, BeforeValidator(one_of(("hertz", "cattaneo_mindlin")))]
    #: None only until the rules across sections fill it in (:mod:`.scene_rules`)
    radius: float = Field(None, validate_default=True)

    @field_validator("radius", mode="wrap")
    @classmethod
    def _given(cls, radius: Any, handler: Any) -> Any:
        return None if radius is None else handler(number(positive)(radius))


class DataConfig(Section):
    """The data expressions (docs/theory.md §1): a vector datum of elasticity is one
    expression for every component or a tuple of them (:func:`components`); ``exact``, the
    exact solution if known, reports the energy error."""

    f: Expressions = "0"
    k: Expression = "1"
    u_D: Expressions = "0"
    t: Expressions = "0"
    t_C: Expression = "0"
    g: Expression = "0"
    psi: Expression = "0"
    exact: Expressions | None = None


def _steps(v: Any) -> str | None:
    if v <= 0:
        return f"must be > 0, got {v}"
    if v > MAX_LOAD_STEPS:
        return f"must be at most {MAX_LOAD_STEPS} (the longest load path), got {v}"
    return None


def _cuts(v: Any) -> str | None:
    if v < 0:
        return f"must be >= 0, got {v}"
    if v > MAX_STEP_CUTS:
        return f"must be at most {MAX_STEP_CUTS} (a step halved {MAX_STEP_CUTS} times), got {v}"
    return None


def _times(v: Any) -> str | None:
    if not v or not all(
        isinstance(t, (int, float)) and not isinstance(t, bool) and math.isfinite(t) for t in v
    ):
        return f"expected a non-empty list of numbers, got {v!r}"
    if v[0] <= 0 or any(b <= a for a, b in zip(v, v[1:])):
        return f"the pseudo-times must be > 0 and strictly increasing, got {v!r}"
    return None


class LoadConfig(Section):
    """A quasi-static load path: the pseudo-times of its steps (``steps`` N: t = 1/N, …, 1;
    or ``times``, increasing, > 0: exactly one of them), ``adapt`` at each step or at the
    end, step ``cuts`` (a step that does not converge is halved and retried, at most this
    many times in a row, at most :data:`MAX_STEP_CUTS`; default: 4 for model type
    hyperelastic, 0 otherwise; no step is cut below 1e-9 of the path's last t), the
    ``predictor`` of steps ≥ 3 (secant: u_{k−1} extrapolated along the last increment;
    none: u_{k−1})."""

    steps: Annotated[int | None, BeforeValidator(integer(_steps))] = None
    times: tuple[float, ...] = Field(None, validate_default=True)
    adapt: Annotated[str, BeforeValidator(one_of(("each", "end")))] = "end"
    cuts: Annotated[int | None, BeforeValidator(integer(_cuts))] = None
    predictor: Annotated[str, BeforeValidator(one_of(("secant", "none")))] = "secant"

    @field_validator("times", mode="before")
    @classmethod
    def _times(cls, times: Any, info: ValidationInfo) -> Any:
        if times is not None:
            return a_list(_times)(times)
        steps = info.data.get("steps")
        return [(k + 1) / steps for k in range(steps)] if steps is not None else []

    @model_validator(mode="after")
    def _steps_or_times(self) -> LoadConfig:
        if ("steps" in self.model_fields_set) == ("times" in self.model_fields_set):
            raise rule("give exactly one of 'steps' or 'times'")
        return self


def _formats(v: Any) -> str | None:
    if any(f not in OUTPUT_FORMATS for f in v) or len(set(v)) != len(v):
        return f"expected a list of distinct formats from {', '.join(OUTPUT_FORMATS)}, got {v!r}"
    return None


def _not_empty(v: str) -> str | None:
    return None if v.strip() else "must not be empty (leave the key out for results/<name>)"


class OutputConfig(Section):
    """The ``output`` section: the folder (``dir``; default ``results/<name>``), the field
    files (``formats``: xdmf — solution.xdmf + .h5, for ParaView —, vtk — solution.vtu,
    for pyvista; a series for levels and load steps), pictures (``png``), progress
    (``verbose``), an adaptive run's field files of every level or of the last only
    (``levels``: all, written as the loop goes; last, once it stops).  ``xdmf`` / ``vtk``
    true or false switch one format on or off; then ``formats`` alone says what is
    written."""

    KEYS: ClassVar[tuple[str, ...]] = (
        "dir",
        "formats",
        "xdmf",
        "vtk",
        "png",
        "verbose",
        "levels",
    )

    dir: Annotated[str | None, BeforeValidator(string(_not_empty))] = None
    xdmf: Switch | None = Field(None, exclude=True, repr=False)
    vtk: Switch | None = Field(None, exclude=True, repr=False)
    formats: Annotated[tuple[str, ...], BeforeValidator(a_list(_formats))] = Field(
        ("xdmf", "vtk"), validate_default=True
    )
    png: Switch = True
    verbose: Switch = True
    levels: Annotated[str, BeforeValidator(one_of(("all", "last")))] = "all"

    @field_validator("formats", mode="before")
    @classmethod
    def _switches(cls, formats: Any, info: ValidationInfo) -> Any:
        formats = list(a_list(_formats)(list(formats) if isinstance(formats, tuple) else formats))
        for key in OUTPUT_FORMATS:
            switch = info.data.get(key)
            if switch is True and key not in formats:
                formats = formats + [key]
            elif switch is False:
                formats = [f for f in formats if f != key]
        return formats


# --------------------------------------------------------------------------- the scene
def _usable(constants: dict[str, float]) -> dict[str, float]:
    reserved = (
        expressions.COORDINATES + expressions.HELPERS + expressions.FUNCTIONS + (expressions.TIME,)
    )
    for key in constants:
        if key in reserved or not key.isidentifier():
            raise fail("is not a usable constant name", key=key)
    return FrozenDict(constants)


Constants = Annotated[dict[str, Float], BeforeValidator(string_keys), AfterValidator(_usable)]


class SceneConfig(Section):
    """A scene, validated: one attribute per section of the YAML (an optional section
    that is absent is None).  :func:`contact.setup.config.validate_scene` builds it: the
    sections, then the rules across them (:mod:`.scene_rules`)."""

    #: the default output folder results/<name> (default: the scene file's stem)
    name: str = Field(None, validate_default=True)
    mesh: MeshConfig = Field(default_factory=lambda: MeshConfig.model_validate({}))
    boundaries: Annotated[
        dict[str, BoundaryPart], BeforeValidator(string_keys), AfterValidator(FrozenDict)
    ] = FrozenDict()
    model: ModelConfig = Field(default_factory=ModelConfig)
    bodies: (
        Annotated[dict[str, BodyConfig], BeforeValidator(string_keys), AfterValidator(FrozenDict)]
        | None
    ) = None
    #: contact pairs between bodies: their items are checked with the bodies and parts
    pairs: Annotated[tuple[PairConfig, ...] | None, SkipValidation, Loose] = None
    obstacle: ObstacleConfig | None = None
    reference: ReferenceConfig | None = None
    constants: Constants = FrozenDict()
    data: DataConfig = Field(default_factory=DataConfig)
    solver: SolverConfig = Field(default_factory=SolverConfig)
    #: a posteriori error estimator: residual (docs/theory.md §5), equilibrated (§9: a
    #: guaranteed bound), equilibrated_rt0 (the same bound from the lowest-order flux of a
    #: P1 scalar solution) or auto (equilibrated for the scalar models, residual otherwise)
    estimator: Annotated[str, BeforeValidator(one_of(ESTIMATORS))] = "auto"
    adapt: AdaptConfig | None = None
    friction: FrictionConfig | None = None
    load: LoadConfig | None = None
    output: OutputConfig = Field(default_factory=lambda: OutputConfig.model_validate({}))

    @field_validator("name", mode="before")
    @classmethod
    def _name(cls, name: Any, info: ValidationInfo) -> str:
        if name is None:
            return (info.context or {}).get("name") or "scene"
        return string(folder_name)(name)

    @field_validator("adapt")
    @classmethod
    def _one_solve(cls, adapt: AdaptConfig | None) -> AdaptConfig | None:
        return None if adapt is not None and adapt.strategy == "none" else adapt

    @property
    def elastic(self) -> bool:
        """Whether the unknown is a displacement vector (:data:`ELASTIC_MODELS`)."""
        return self.model.type in ELASTIC_MODELS

    @property
    def frictional(self) -> bool:
        """Whether the contact has friction (a ``friction`` section whose law is not none)."""
        return self.friction is not None and self.friction.law != "none"

    def with_mesh(self, **changes: Any) -> SceneConfig:
        """This config with other mesh parameters (e.g. a coarser ``h`` for grid
        sequencing; not checked again: the caller derives them from checked ones).

        Args:
            **changes: new values of mesh keys.

        Returns:
            The changed copy.
        """
        return self.model_copy(update={"mesh": self.mesh.model_copy(update=changes)})

    def as_dict(self) -> dict[str, Any]:
        """The config as plain JSON data (lists, dicts), e.g. for a study's ``study.json``.

        Returns:
            The config's sections as JSON data.
        """
        return self.model_dump(mode="json")


def require_config(config: Any) -> SceneConfig:
    """ConfigError unless ``config`` is a :class:`SceneConfig`.

    Args:
        config: what a caller passed as a config.

    Returns:
        ``config`` itself.
    """
    if not isinstance(config, SceneConfig):
        raise ConfigError(
            f"config: expected a validated SceneConfig (contact.setup.config.load_config), "
            f"got {type(config).__name__}"
        )
    return config
