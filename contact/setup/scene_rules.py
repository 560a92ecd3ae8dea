"""The rules across a scene's sections: what one section asks of another (a Signorini scene
needs a contact part; friction needs an elastic body; the equilibrated estimator covers
the scalar models and one elastic body against a plane; …), checked once, in a fixed order,
after every section has checked its own keys (:mod:`.scene_config`).  Each failure is a
:class:`ConfigError` of one line naming the key that asks for what cannot be.

:func:`complete` is the last step of :func:`contact.setup.config.validate_scene`; it
also fills in what depends on several sections: ``estimator: auto``, the contact pairs
(checked against the bodies and parts), the grid sequencing of a hyperelastic body (off).
"""

from __future__ import annotations

import ast
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from pydantic import ValidationError

from ..base import expressions
from ..base.errors import ConfigError
from ..base.validation import config_error
from ..solvers.options import BASELINE_METHODS, NO_LAST_ESTIMATE_STOPPING
from .scene_config import (
    CURVED_MESHES,
    ELASTIC_MODELS,
    EQUILIBRATED,
    GMSH_MESHES,
    HYPERELASTIC_LAWS,
    PairConfig,
    ReferenceConfig,
)

if TYPE_CHECKING:
    from .scene_config import SceneConfig

#: the models ``estimator: auto`` gives the equilibrated bound (a guaranteed bound, of
#: effectivity near 1); elasticity keeps the residual estimator
EQUILIBRATED_MODELS = ("signorini", "obstacle")
#: the methods that solve a gap nonlinear in u, and friction: semismooth Newton's
NCP_METHODS = ("fb", "min", "blend")
#: the message for an elastic 3D scene with the equilibrated estimator (also raised at
#: estimate time for a gmsh mesh, whose dimension the configuration does not show)
STRESS_3D = (
    "mesh.type: estimator: equilibrated for elasticity is 2D only (in 3D each vertex "
    "patch of the stress is a dense system of ~400 unknowns: too slow); use residual"
)

#: the residual estimator of a 3D P2 obstacle solution, refused (also by the estimator, for a
#: gmsh mesh whose dimension the configuration does not show: contact.adaptivity.estimate)
RESIDUAL_P2_OBSTACLE_3D = (
    "estimator: residual does not converge with a P2 obstacle solution in 3D (its volume "
    "term sees the vertices lifted off the obstacle in the contact zone); use equilibrated"
)


def complete(config: SceneConfig, data: Mapping[str, Any]) -> SceneConfig:
    """The rules across the sections of ``config``, in order; its completed copy.

    Args:
        config: the scene, each section checked alone.
        data: the scene's raw mapping (which keys a section gives: a datum given for
            a model that does not use it is an error, not a default).

    Returns:
        The complete config: ``estimator`` resolved, ``pairs`` typed, ``solver.sequence:
        auto`` off for hyperelastic bodies through pairs.

    Raises:
        ConfigError: the first rule the scene breaks.
    """
    updates: dict[str, Any] = {}
    mesh, parts = config.mesh, config.boundaries
    if not parts:
        raise ConfigError("boundaries: at least one boundary part is required")
    for name, part in parts.items():
        if part.tag is not None and mesh.type not in GMSH_MESHES:
            raise ConfigError(
                f"boundaries.{name}.tag: tags need a gmsh mesh (mesh.type: "
                f"{', '.join(GMSH_MESHES)})"
            )
    roles = [p.role for p in parts.values()]
    model = config.model.type
    if _check_hyperelastic(config, model) and config.pairs and config.solver.sequence == "auto":
        # pairs at finite strain: auto does not sequence (the couplings' linear fixed point,
        # not its start, sets their work); a number of levels opts in
        updates["solver"] = config.solver.model_copy(update={"sequence": "off"})
    if model == "hyperelastic":  # the rest of the checks: those of an elastic body
        model = "elasticity"
    if (
        model == "signorini"
        and "contact" not in roles
        or model == "elasticity"
        and not ("contact" in roles or config.pairs)
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
    if model != "elasticity" and config.obstacle is not None:
        raise ConfigError(
            "obstacle: only for model type elasticity (scalar models use data.g / data.psi)"
        )
    if model != "elasticity" and config.model.E is not None:
        raise ConfigError("model.E: only for model type elasticity")
    if model == "signorini" and "psi" in given:
        raise ConfigError("data.psi: only for model type obstacle (Signorini uses data.g)")
    if model == "obstacle" and ({"g", "t_C"} & given):
        raise ConfigError(
            f"data.{sorted({'g', 't_C'} & given)[0]}: only for model type signorini "
            f"(obstacles use data.psi)"
        )
    if config.model.bound != "upper" and model == "signorini":
        raise ConfigError("model.bound: Signorini contact is always u ≤ g (upper)")
    _check_vector_data(config, model)
    _check_time(config)
    _check_friction(config, data)
    _check_baselines(config)
    estimator = config.estimator
    if estimator == "auto":  # the guaranteed bound where it is cheap
        estimator = updates["estimator"] = (
            "equilibrated" if model in EQUILIBRATED_MODELS else "residual"
        )
    _check_equilibrated(config, estimator)
    if config.solver.stopping == "adaptive" and estimator not in EQUILIBRATED:
        raise ConfigError(
            "solver.stopping: adaptive needs estimator: equilibrated (the "
            "discretization error it balances against)"
        )
    if config.solver.stopping == "adaptive" and config.adapt and not config.adapt.estimate_last:
        raise ConfigError(NO_LAST_ESTIMATE_STOPPING)
    if model == "elasticity":
        updates["pairs"] = _check_bodies(config)
        _check_elasticity(config)
    else:
        for key in ("bodies", "pairs"):
            if getattr(config, key):
                raise ConfigError(f"{key}: only for model type elasticity")
        if "symmetry" in roles or "interface" in roles:
            role = "symmetry" if "symmetry" in roles else "interface"
            raise ConfigError(f"boundaries: role {role} is for elasticity scenes")
    if config.reference is not None:
        updates["reference"] = _check_reference(config)
    if mesh.degree == 2 and model == "obstacle" and estimator == "residual" and _is_3d(mesh):
        raise ConfigError(RESIDUAL_P2_OBSTACLE_3D)  # a gmsh mesh: when it is estimated
    return config.model_copy(update=updates)


def _check_hyperelastic(config: SceneConfig, model: str) -> bool:
    """``model.law`` only and always for hyperelastic bodies; what the hyperelastic model
    does not do yet (contact/models/hyperelastic.py) is refused by name: contact pairs with
    an obstacle, a reference solution against an obstacle, an exact solution, Coulomb's
    fixed point.  Returns whether the scene is
    hyperelastic."""
    law = config.model.law
    if model != "hyperelastic":
        if law is not None:
            raise ConfigError("model.law: only for model type hyperelastic")
        return False
    if law is None:
        raise ConfigError(
            f"model.law: required for model type hyperelastic ({', '.join(HYPERELASTIC_LAWS)})"
        )
    if config.reference is not None and not config.pairs:
        raise ConfigError(
            "reference: not available for model type hyperelastic against a rigid obstacle"
        )
    friction = config.friction
    frictional = friction is not None and friction.law != "none"
    if config.pairs and config.obstacle is not None:
        raise ConfigError(
            "obstacle: hyperelastic bodies in contact through pairs are without a rigid "
            "obstacle (not implemented)"
        )
    method = config.solver.method
    obstacle = config.obstacle.type if config.obstacle is not None else "plane"
    if (obstacle != "plane" or frictional) and method not in NCP_METHODS:
        raise ConfigError(
            f"solver.method: {method} needs a gap affine in u (PETSc's VI bounds); a "
            "hyperelastic body against a circle or sphere, or with friction, takes fb, min "
            "or blend"
        )
    if frictional and friction is not None and friction.coulomb == "fixed_point":
        raise ConfigError(
            "friction.coulomb: fixed_point is not available for model type hyperelastic (use ssn)"
        )
    if config.data.exact is not None:
        raise ConfigError("data.exact: not available for model type hyperelastic")
    return True


def _check_vector_data(config: SceneConfig, model: str) -> None:
    """Vector data (lists) only for elasticity (where a single expression means every
    component, so the default "0" is the zero vector)."""
    for key in ("f", "u_D", "t", "exact"):
        if isinstance(getattr(config.data, key), tuple) and model != "elasticity":
            raise ConfigError(f"data.{key}: a list of components is only for model type elasticity")
    if isinstance(config.solver.u0, tuple) and model != "elasticity":
        raise ConfigError("solver.u0: a list of components is only for model type elasticity")


def _check_time(config: SceneConfig) -> None:
    """The pseudo-time t is for data only: the mesh and its parts are fixed along a load
    path."""
    constants = config.constants
    for key, texts in (
        ("mesh.map", config.mesh.map or ()),
        *((f"boundaries.{n}.where", (p.where,)) for n, p in config.boundaries.items()),
    ):
        if any(t is not None and expressions.uses_time(t, constants) for t in texts):
            raise ConfigError(
                f"{key}: the pseudo-time t is only for data expressions (the mesh is fixed)"
            )


def _check_friction(config: SceneConfig, data: Mapping[str, Any]) -> None:
    """Friction needs elastic contact, and the keys of its law (Tresca: a threshold;
    Coulomb: a coefficient, and not the other law's keys); PETSc's VI solvers cannot solve it.
    ``law: none`` ignores the other keys (``--set friction.law=none`` switches it off)."""
    friction = config.friction
    if friction is None or friction.law == "none":
        return
    law = friction.law
    if config.model.type not in ELASTIC_MODELS:
        raise ConfigError(
            f"friction.law: {law} friction needs model type elasticity or hyperelastic "
            f"(a {config.model.type} scene has no tangential direction)"
        )
    need = {"tresca": "threshold", "coulomb": "coefficient"}.get(law)
    if need is not None and getattr(friction, need) is None:
        raise ConfigError(f"friction.{need}: required for friction law {law}")
    given = {k for k, v in (data.get("friction") or {}).items() if v is not None}
    unused = sorted(
        given
        - {"law", need, "c_t", "kappa_t", "form"}
        - ({"coulomb", "fixed_point_rtol", "fixed_point_max_it"} if law == "coulomb" else set())
    )
    if unused:
        raise ConfigError(f"friction.{unused[0]}: not used by friction law {law}")
    if config.solver.method not in (*NCP_METHODS, *BASELINE_METHODS):
        raise ConfigError(
            f"solver.method: {config.solver.method} cannot solve frictional contact "
            f"(friction.law: {law}); use fb, min, blend or a baseline (penalty, "
            "augmented_lagrangian, nitsche)"
        )


def _check_baselines(config: SceneConfig) -> None:
    """The baseline enforcements (penalty, augmented Lagrangian, Nitsche) cover the scalar
    models and one linear elastic body against a rigid obstacle, P1 (penalty and augmented
    Lagrangian integrate at the vertices); Nitsche needs a contact boundary.  Penalty and
    augmented Lagrangian also take linear elastic bodies through mortar pairs, on the mortar
    gap node by node (:mod:`contact.solvers.nodal_baselines`)."""
    method, model = config.solver.method, config.model.type
    if method not in BASELINE_METHODS:
        return
    if model == "hyperelastic" or (config.bodies and not config.pairs):
        what = "a hyperelastic body" if model == "hyperelastic" else "bodies without pairs"
        raise ConfigError(
            f"solver.method: {method} is available for scalar scenes and linear elastic "
            f"bodies against a rigid obstacle or each other, not {what} (use fb, min or blend)"
        )
    if method == "nitsche" and config.pairs:
        raise ConfigError(
            "solver.method: nitsche takes one body against a rigid obstacle; two bodies "
            "through mortar pairs take penalty or augmented_lagrangian (or fb, min, blend)"
        )
    if method == "nitsche" and model == "obstacle":
        raise ConfigError(
            "solver.method: nitsche needs a contact boundary; an obstacle scene constrains "
            "the whole domain (use penalty or augmented_lagrangian)"
        )
    if config.mesh.degree != 1 and method != "nitsche":
        raise ConfigError(
            f"mesh.degree: {method} integrates its contact term at the vertices, P1 only; use 1"
        )


def _check_equilibrated(config: SceneConfig, estimator: str) -> None:
    """``estimator: equilibrated`` covers the scalar models and one linear elastic body
    against a rigid plane, frictionless or with Tresca friction (docs/theory.md §9); what
    it does not cover is refused by the key that asks for it."""
    model = config.model.type
    if estimator == "equilibrated_rt0":
        if model not in EQUILIBRATED_MODELS:
            raise ConfigError(
                "estimator: equilibrated_rt0 is the lowest-order flux of the scalar models "
                f"(signorini, obstacle), not model type {model}; use equilibrated or residual"
            )
        if config.mesh.degree != 1:
            raise ConfigError(
                "mesh.degree: estimator: equilibrated_rt0 is the lowest-order flux of a P1 "
                "solution; use 1, or estimator: equilibrated"
            )
        return
    if estimator != "equilibrated" or model in EQUILIBRATED_MODELS:
        return
    if model != "elasticity":
        raise ConfigError(
            "estimator: equilibrated is implemented for model types signorini, obstacle "
            f"and elasticity, not {model}; use residual"
        )
    if config.pairs or config.bodies:
        raise ConfigError(
            f"{'pairs' if config.pairs else 'bodies'}: estimator: equilibrated takes one "
            "elastic body against a rigid plane (two bodies: not implemented); use residual"
        )
    if config.obstacle is None or config.obstacle.type != "plane":
        raise ConfigError(
            "obstacle.type: estimator: equilibrated needs a rigid plane (a circle's or "
            "sphere's normal varies along the contact surface: not implemented); use residual"
        )
    if config.friction is not None and config.friction.law == "coulomb":
        raise ConfigError(
            "friction.law: estimator: equilibrated covers frictionless contact and Tresca "
            "friction, not coulomb; use residual"
        )
    if _is_3d(config.mesh):
        raise ConfigError(STRESS_3D)


def _is_3d(mesh: Any) -> bool:
    """Whether the built-in mesh of the ``mesh`` section is 3D (a gmsh file's dimension is
    not known before it is read: False)."""
    corners = mesh.blocks[0].corners if mesh.type == "blocks" and mesh.blocks else None
    return mesh.type in ("box", "sphere_octant", "sphere_on_block") or (
        corners is not None and len(corners[0]) == 3
    )


def _check_bodies(config: SceneConfig) -> tuple[PairConfig, ...] | None:
    """bodies (each with exactly one of tag / where), boundary parts' ``body``, and pairs:
    slave and master parts of role interface (of two bodies, or of one: self-contact), each
    part in one pair.
    Returns the pairs, typed."""
    bodies, parts = config.bodies or {}, config.boundaries
    for name, body in bodies.items():
        if (body.where is None) == (body.tag is None):
            raise ConfigError(f"bodies.{name}: give exactly one of 'where' or 'tag'")
    if bodies and config.model.E is not None:
        raise ConfigError("model.E: a scene with bodies gives E (and nu) per body")
    for pname, part in parts.items():
        if part.body is not None and part.body not in bodies:
            known = ", ".join(bodies) or "none"
            raise ConfigError(
                f"boundaries.{pname}.body: {part.body!r} is not a body (bodies: {known})"
            )
    if config.pairs and not bodies:
        raise ConfigError("pairs: contact pairs need a bodies section (one material per body)")
    used: dict[str, str] = {}
    pairs = []
    for i, raw in enumerate(config.pairs or ()):
        pair = raw if isinstance(raw, PairConfig) else _pair(raw, f"pairs[{i}]")
        pairs.append(pair)
        for side in ("slave", "master"):
            name = getattr(pair, side)
            if name not in parts:
                raise ConfigError(f"pairs[{i}].{side}: {name!r} is not a boundary part")
            if parts[name].role != "interface":
                raise ConfigError(
                    f"pairs[{i}].{side}: boundary part {name!r} needs role: interface"
                )
            if name in used:
                raise ConfigError(
                    f"pairs[{i}].{side}: boundary part {name!r} is already the {used[name]}"
                )
            used[name] = f"{side} of pairs[{i}]"
    for pname, part in parts.items():
        if part.role == "interface" and pname not in used:
            raise ConfigError(
                f"boundaries.{pname}: a part with role interface must be the slave or "
                "master of a contact pair (pairs)"
            )
    return tuple(pairs) if config.pairs is not None else None


def _pair(raw: Any, path: str) -> PairConfig:
    """One contact pair of the scene file, validated (``pairs[i].<key>: …``)."""
    try:
        return PairConfig.model_validate(raw)
    except ValidationError as err:
        raise config_error(err, path, PairConfig) from None


def _check_elasticity(config: SceneConfig) -> None:
    """An elastic scene's obstacle: a rigid plane, circle or sphere touching a part of role
    contact, with the keys of its type (coordinates: numbers; a point or centre may move
    with the pseudo-time t) — or contact pairs between bodies."""
    if config.model.E is None and not config.bodies:
        raise ConfigError(f"model.E: required for model type {config.model.type} (Young's modulus)")
    obstacle = config.obstacle
    contact_parts = [n for n, p in config.boundaries.items() if p.role == "contact"]
    if obstacle is not None and not contact_parts:
        raise ConfigError(
            "obstacle: needs a boundary part with role: contact (the surface it touches)"
        )
    if obstacle is None and config.pairs and not contact_parts:
        return
    if obstacle is None:
        raise ConfigError(
            "obstacle: an elasticity scene needs a rigid obstacle (type plane, circle or "
            "sphere) or contact pairs between bodies (pairs)"
        )
    keys = ("point", "normal") if obstacle.type == "plane" else ("center", "radius")
    for key in keys:
        if getattr(obstacle, key) is None:
            raise ConfigError(f"obstacle.{key}: required for an obstacle of type {obstacle.type}")
    for key in ("point", "normal", "center", "radius"):
        if getattr(obstacle, key) is not None and key not in keys:
            raise ConfigError(f"obstacle.{key}: not used by an obstacle of type {obstacle.type}")
    for key in keys[:2] if obstacle.type == "plane" else ("center",):
        vec = getattr(obstacle, key)
        if key in ("point", "center") and all(
            isinstance(c, (str, int, float)) and not isinstance(c, bool) for c in vec
        ):
            _check_moving_point(vec, config.constants, key)
            continue
        if not all(
            isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c)
            for c in vec
        ):
            raise ConfigError(f"obstacle.{key}: expected a list of numbers, got {list(vec)!r}")
    if obstacle.type == "plane" and not any(obstacle.normal or ()):
        raise ConfigError("obstacle.normal: must not be the zero vector")


def _check_moving_point(point: tuple, constants: Mapping[str, float], key: str = "point") -> None:
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


def _check_reference(config: SceneConfig) -> ReferenceConfig:
    """A declared reference fits the scene: Hertz needs elastic contact (hyperelastic bodies:
    the small-load limit, two bodies only) and a radius (given,
    or the radius of a built-in quarter_disk / sphere_octant / sphere_on_block, the effective
    radius R1 R2 / (R1 + R2) of half_disks, filled in here).  With contact pairs the radius is
    the effective one, 1/R = 1/R1 + 1/R2, and E* comes from the two bodies of the first pair.
    Returns the reference with its radius."""
    ref, mesh = config.reference, config.mesh
    assert ref is not None  # the caller's condition
    if ref.type == "cattaneo_mindlin" and (
        config.friction is None or config.friction.law != "coulomb"
    ):
        raise ConfigError(
            "reference.type: cattaneo_mindlin needs Coulomb friction (friction.law: coulomb)"
        )
    if config.model.type not in ELASTIC_MODELS:  # hyperelastic: its small-load limit
        raise ConfigError(f"reference.type: {ref.type} needs model type elasticity")
    if ref.radius is not None:
        return ref
    if mesh.type not in CURVED_MESHES:
        raise ConfigError(
            f"reference.radius: required for type {ref.type} (the radius R of the curved body, "
            "the effective radius of two) unless the mesh is a quarter_disk, sphere_octant, "
            "half_disks or sphere_on_block"
        )
    R1 = float(mesh.radius)
    R2 = float(mesh.radius2 or R1) if mesh.type == "half_disks" else None
    # a radius <= 0 is the mesh's error (reported when it is built)
    radius = R1 if R2 is None or R1 + R2 == 0 else R1 * R2 / (R1 + R2)
    return ref.model_copy(update={"radius": radius})
