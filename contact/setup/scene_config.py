"""The scene's configuration as typed, immutable objects: :class:`SceneConfig`, validated
once when the scene is read (:func:`contact.setup.config.load_config`) and read by attribute
everywhere after that (``scene.config.solver.method``, ``scene.config.mesh.degree``,
``scene.config.friction.law``).  Nothing downstream of :mod:`contact.setup` sees a dict.

**Why pydantic v2** (and not attrs + cattrs or plain dataclasses): the solver's options are
a frozen pydantic model already (:class:`~contact.solvers.options.SolverOptions`), whose
one-line messages the loader shares (:mod:`contact.base.validation`: each field type checks
its value itself and raises our text, so pydantic's own wording never reaches a user);
pydantic's errors carry the key path those messages name; ``frozen=True`` makes "validated
once" structural — a section cannot change after it was checked, so no solve has to check it
again — and nested models, unions, defaults and ``model_copy`` give one declaration per key
and cheap changed copies for the code that builds scenes (grid sequencing's coarser meshes).

**How it is built.** The sections a caller may override when calling the Python API —
``solver`` (:class:`SolverConfig` = :class:`SolverOptions` + the driver's keys), ``adapt``
(:class:`AdaptConfig`) and ``friction`` (:class:`FrictionConfig` =
:class:`~contact.solvers.options.FrictionOptions` + the law's data) — are pydantic models
with the loader's messages; the scene's schema (:data:`contact.setup.config.SCENE`) validates
them through these models and checks the other sections and every cross-key rule key by key,
with the messages it has always written (the bad-input battery, ``tests/test_cli_errors.py``);
the checked mapping then becomes the typed tree below, once.  Lists become tuples and
mappings :class:`FrozenDict`, so no part of the tree can be changed in place.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    ValidationError,
    ValidationInfo,
)
from pydantic_core import PydanticCustomError

from ..base.errors import ConfigError
from ..base.validation import (
    FrozenDict,
    boolean,
    checked,
    config_error,
    fail,
    half_open_unit,
    integer,
    nonnegative,
    number,
    one_of,
    open_unit,
    parse_section,
    positive,
)
from ..solvers.options import FrictionOptions, SolverOptions
from . import expressions

#: models whose unknown is a displacement vector: linear elasticity (small strain) and
#: hyperelastic bodies (finite strain, contact/models/hyperelastic.py)
ELASTIC_MODELS = ("elasticity", "hyperelastic")
FRICTION_LAWS = ("none", "tresca", "coulomb")
STRATEGIES = ("dorfler", "maximum", "uniform", "hp", "none")
#: the largest polynomial degree ``adapt.p_max`` accepts (Lagrange P_{p_max} carries V_hp)
MAX_DEGREE = 8


def _degree(v: int) -> str | None:
    return None if 1 <= v <= MAX_DEGREE else f"must lie in 1..{MAX_DEGREE}, got {v}"


class _Section(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


# --------------------------------------------------------------------- expressions
def _expression(v: Any, info: ValidationInfo) -> str:
    """One data expression in x, y, z, t and the scene's ``constants`` (the validation
    context), kept as its text."""
    try:
        expressions.parse(v, (info.context or {}).get("constants", {}))
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


Expression = Annotated[str, BeforeValidator(_expression)]
#: an expression, or one per component (elasticity): a tuple
Expressions = Annotated[str | tuple[str, ...], BeforeValidator(_expressions)]


#: a coordinate as the scene gives it (an int stays an int, so that messages quote it as given)
Number = int | float


def components(value: str | tuple[str, ...], n: int) -> tuple[str, ...]:
    """The ``n`` component expressions of a datum: its own, or one expression for all."""
    return value if isinstance(value, tuple) else (value,) * n


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


class SolverConfig(SolverOptions):
    """A scene's ``solver`` section: the solver's knobs (:class:`SolverOptions`, what the
    solver receives: :meth:`knobs`) and the driver's: ``u0`` — the initial guess, an
    expression (every component) or one per component; ``sequence`` — grid sequencing of
    a single solve, ``auto``, ``off`` or the number of coarser levels; ``max_dofs`` — the
    DoF budget of one solve, ``auto`` (:mod:`contact.setup.budget`) or a number;
    ``stopping`` — ``fixed`` or ``adaptive`` (:mod:`contact.solvers.stopping`) with its
    ``gamma_lin``, ``gamma_alg``."""

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
        return parse_section(cls, values, path, {"constants": constants}, SOLVER_KEYS)

    def updated(self, constants: Mapping[str, float] = {}, **changes: Any) -> SolverConfig:
        """A copy with keyword ``changes`` (None: unchanged), each validated as in the scene
        file (``solver.<key>: …`` on a bad one); the rest is not checked again."""
        given = {k: v for k, v in changes.items() if v is not None}
        if not given:
            return self
        checked_ = parse_section(
            SolverConfig, given, "solver", {"constants": constants}, SOLVER_KEYS
        )
        return self.model_copy(update={k: getattr(checked_, k) for k in given})


# -------------------------------------------------------------------- the adapt section
class AdaptConfig(_Section):
    """A scene's ``adapt`` section (docs/theory.md §6): ``strategy`` — dorfler, maximum,
    uniform, hp (Dörfler, then h or p per marked cell: :mod:`contact.hp`) or none (one
    solve); ``theta`` — the marking fraction in (0, 1]; ``tol`` — stop at η ≤ tol;
    ``max_dofs``, ``max_levels`` — budgets; ``nested`` — each level starts from the previous
    solution; ``rebalance`` — repartition refined meshes; ``newton_rtol`` — Newton's relative
    tolerance inside the loop; ``pictures`` — levels drawn; ``p_max``, ``p_start`` — with
    ``hp``, the largest degree and every cell's first degree."""

    strategy: Annotated[str, BeforeValidator(one_of(STRATEGIES))] = "dorfler"
    theta: Annotated[float, BeforeValidator(number(half_open_unit))] = 0.5
    tol: Annotated[float, BeforeValidator(number(nonnegative))] = 0.0
    max_dofs: Annotated[int, BeforeValidator(integer(positive))] = 200000
    max_levels: Annotated[int, BeforeValidator(integer(positive))] = 8
    nested: Annotated[bool, BeforeValidator(boolean)] = True
    rebalance: Annotated[bool, BeforeValidator(boolean)] = True
    newton_rtol: Annotated[float, BeforeValidator(number(positive))] = 1e-10
    pictures: Annotated[int, BeforeValidator(integer(nonnegative))] = 3
    p_max: Annotated[int, BeforeValidator(integer(_degree))] = 6
    p_start: Annotated[int, BeforeValidator(integer(_degree))] = 1

    @classmethod
    def parse(cls, values: Mapping[str, Any], path: str = "adapt") -> AdaptConfig:
        return parse_section(cls, values, path)

    def updated(self, **changes: Any) -> AdaptConfig:
        """A copy with keyword ``changes`` (None: unchanged), each validated as in the scene
        file (``adapt.<key>: …``)."""
        given = {k: v for k, v in changes.items() if v is not None}
        if not given:
            return self
        checked_ = AdaptConfig.parse(given)
        return self.model_copy(update={k: getattr(checked_, k) for k in given})


# ----------------------------------------------------------------- the friction section
class FrictionConfig(FrictionOptions):
    """A scene's ``friction`` section: the law (``none``, ``tresca``, ``coulomb``), its data
    (Coulomb's ``coefficient`` F, dimensionless; Tresca's slip ``threshold`` s(x, t) ≥ 0, a
    stress) and the solver's tangential knobs (:class:`FrictionOptions`: :meth:`knobs`)."""

    law: Annotated[str, BeforeValidator(one_of(FRICTION_LAWS))] = "none"
    coefficient: Annotated[float | None, BeforeValidator(number(nonnegative))] = None
    threshold: Expression | None = None

    @classmethod
    def parse(
        cls, values: Mapping[str, Any], path: str = "friction", constants: Mapping = {}
    ) -> FrictionConfig:
        return parse_section(cls, values, path, {"constants": constants}, FRICTION_KEYS)


#: the keys of a scene's ``friction`` section, in the order its messages list them
FRICTION_KEYS = ("law", "coefficient", "threshold", *FrictionOptions.model_fields)


# -------------------------------------------------------------- the checked sections
class SurfaceSpec(_Section):
    """The exact curve / surface a boundary part lies on (refinement snaps to it)."""

    type: str
    center: tuple[Number, ...]
    radius: float
    axis: tuple[Number, ...] | None = None


class BoundaryPart(_Section):
    """A named part of the boundary: its ``role`` and the facets (``where`` predicate,
    gmsh ``tag``, ``body``), optionally the ``surface`` it lies on."""

    role: str
    where: str | None = None
    tag: int | None = None
    body: str | None = None
    surface: SurfaceSpec | None = None


class Block(_Section):
    """One block of mesh type ``blocks``: two corners, cells per direction."""

    corners: tuple[tuple[float, ...], ...]
    cells: tuple[int, ...]


class MeshConfig(_Section):
    """The ``mesh`` section; the keys of other mesh types are None (or their default)."""

    type: str = "rectangle"
    corners: tuple[tuple[float, ...], ...] | None = None
    cells: tuple[int, ...] | int = 16
    diagonal: str = "right"
    file: str | None = None
    degree: int = 1
    radius: float | None = None
    h: float | None = None
    h_contact: float | None = None
    zone: float | None = None
    radius2: float | None = None
    overlap: float | None = None
    block: tuple[Number, ...] | None = None
    blocks: tuple[Block, ...] | None = None
    map: tuple[str, ...] | None = None


class ModelConfig(_Section):
    type: str = "signorini"
    law: str | None = None
    bound: str = "upper"
    E: float | None = None
    nu: float = 0.3


class BodyConfig(_Section):
    tag: int | None = None
    where: str | None = None
    E: float
    nu: float = 0.3


class PairConfig(_Section):
    slave: str
    master: str
    search: float | None = None


class ObstacleConfig(_Section):
    """A rigid obstacle: a plane (``point`` and ``normal``), a circle or a sphere (``center``,
    ``radius``); the point's or centre's coordinates may be expressions of the pseudo-time t
    (an obstacle moved along a load path)."""

    type: str = "plane"
    point: tuple[Number | str, ...] | None = None
    normal: tuple[Number, ...] | None = None
    center: tuple[Number | str, ...] | None = None
    radius: float | None = None


class ReferenceConfig(_Section):
    """A declared reference solution: its ``type`` and the ``radius`` R of the curved body
    (the effective radius of two; filled in from the mesh where the scene leaves it out)."""

    type: str
    radius: float


class DataConfig(_Section):
    """The data expressions (docs/theory.md §1): a vector datum of elasticity is one
    expression for every component or a tuple of them (:func:`components`)."""

    f: str | tuple[str, ...] = "0"
    k: str = "1"
    u_D: str | tuple[str, ...] = "0"
    t: str | tuple[str, ...] = "0"
    t_C: str = "0"
    g: str = "0"
    psi: str = "0"
    exact: str | tuple[str, ...] | None = None


class LoadConfig(_Section):
    """A quasi-static load path: the pseudo-times of its steps (``steps`` N fills them in
    as 1/N, …, 1), ``adapt`` at each step or the end, step ``cuts``, the ``predictor`` of
    steps ≥ 3."""

    steps: int | None = None
    times: tuple[float, ...]
    adapt: str = "end"
    cuts: int | None = None
    predictor: str = "secant"


class OutputConfig(_Section):
    dir: str | None = None
    formats: tuple[str, ...] = ("xdmf", "vtk")
    png: bool = True
    verbose: bool = True


class SceneConfig(_Section):
    """A scene, validated: one attribute per section of the YAML (an optional section
    that is absent is None)."""

    name: str
    mesh: MeshConfig
    boundaries: Annotated[dict[str, BoundaryPart], AfterValidator(FrozenDict)]
    model: ModelConfig
    bodies: Annotated[dict[str, BodyConfig], AfterValidator(FrozenDict)] | None = None
    pairs: tuple[PairConfig, ...] | None = None
    obstacle: ObstacleConfig | None = None
    reference: ReferenceConfig | None = None
    constants: Annotated[dict[str, float], AfterValidator(FrozenDict)] = FrozenDict()
    data: DataConfig
    solver: SolverConfig
    estimator: str = "residual"
    adapt: AdaptConfig | None = None
    friction: FrictionConfig | None = None
    load: LoadConfig | None = None
    output: OutputConfig

    @classmethod
    def of_checked(cls, cfg: Mapping[str, Any]) -> SceneConfig:
        """The typed config of a mapping the schema has checked (keys starting with ``_``
        are the loader's own and left out)."""
        try:
            return cls.model_validate({k: v for k, v in cfg.items() if not k.startswith("_")})
        except ValidationError as err:  # a value the schema lets through untyped
            raise config_error(err, "", cls.model_fields) from None

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
        sequencing; not checked again: the caller derives them from checked ones)."""
        return self.model_copy(update={"mesh": self.mesh.model_copy(update=changes)})

    def as_dict(self) -> dict[str, Any]:
        """The config as plain JSON data (lists, dicts), e.g. for a study's ``study.json``."""
        return self.model_dump(mode="json")


def require_config(config: Any) -> SceneConfig:
    """ConfigError unless ``config`` is a :class:`SceneConfig`."""
    if not isinstance(config, SceneConfig):
        raise ConfigError(
            f"config: expected a validated SceneConfig (contact.setup.config.load_config), "
            f"got {type(config).__name__}"
        )
    return config
