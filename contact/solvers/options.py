"""Solver options: :class:`SolverOptions` (the solver's knobs, typed and immutable), method
names as benchmarks list them, the default PETSc options of each linear solver (a function
of its kind and the dimension alone, known before any mesh exists), and PETSc's options
database (set, read, errors as one line).  Nothing here reads a scene: its ``solver``
section with call-time overrides becomes SolverOptions in :mod:`contact.drivers.solve`.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from typing import Annotated, Any, Literal

from mpi4py import MPI
from petsc4py import PETSc
from pydantic import BaseModel, BeforeValidator, ConfigDict

from ..base.errors import ConfigError, petsc_message
from ..base.validation import (
    FrozenDict,
    at_least_one,
    auto_or,
    auto_or_positive,
    boolean,
    checked,
    half_open_unit,
    integer,
    mapping_of,
    nonnegative,
    number,
    one_of,
    open_unit,
    parse_section,
    positive,
)
from ..base.validation import petsc_value as valid_petsc_value
from . import ncp
from .reduced import REDUCED_PETSC_OPTIONS

VI_METHODS = ("vinewtonrsls", "vinewtonssls")
#: the enforcements other contact codes use, as baselines (:mod:`.baselines`)
BASELINE_METHODS = ("penalty", "augmented_lagrangian", "nitsche")
#: every method: semismooth Newton on an NCP function, one of PETSc's VI solvers, or a
#: baseline enforcement
METHODS = ncp.METHODS + VI_METHODS + BASELINE_METHODS
LINE_SEARCHES = ("auto", "basic", "bt", "energy")
LINEAR = ("auto", "direct", "gamg", "bcgs", "gmres", "hp_patch")
PREDICTORS = ("auto", "tangent", "none")
#: the forcing rule of inexact Newton on the gamg path (:mod:`.reduced`)
FORCINGS = ("active_set", "eisenstat_walker")
#: the tangential NCP of friction: Alart–Curnier's projection, or Hüeber–Stadler–Wohlmuth's max
FRICTION_FORMS = ("projection", "hsw")
#: how Coulomb friction is solved: semismooth Newton on all rows, or the fixed point on ρ
COULOMB_SOLVERS = ("ssn", "fixed_point")


def theta_value(value: float) -> str | None:
    """θ of Nitsche's method: 1, 0 or −1."""
    return None if value in (1.0, 0.0, -1.0) else f"must be 1, 0 or -1, got {value}"


class SolverOptions(BaseModel):
    """The knobs of one solve (SPEC §3–4, §8), validated once and immutable.

    Attributes:
        method: fb, min, blend (semismooth Newton on that NCP function), vinewtonrsls /
            vinewtonssls (PETSc's VI solvers) or a baseline enforcement (penalty,
            augmented_lagrangian, nitsche).
        mu: blend's weight of φ_min, in (0, 1).
        c: the NCP scaling (gap per multiplier): ``auto`` (nodal, c_i = κ w_i / K_ii,
            ``nodal_scaling``) or a number > 0.
        kappa: κ of the nodal scaling.
        line_search: auto (plain Newton, for min backtracking once a cycle shows; energy for
            a problem with an energy and a direct solver), basic, bt, energy
            (``energy_search``).
        polish: active-set polishing of fb / blend steps.
        rtol: Newton's tolerance relative to ‖Φ(x_0)‖.
        atol: relative to the force scale ‖Φ(x_D)‖_∞ of the data (dimensionless).
        max_it: the most Newton iterations: a number, or ``auto`` (the default):
            max(50, n) with n the nodes across the constrained set
            (``contact.solvers.problem.newton_max_it``), since a cold start's active-set
            path takes O(1/h) steps.
        linear: direct, gamg, bcgs, gmres, hp_patch or auto (``linear``).
        inexact: inexact Newton on the gamg path (Krylov tolerances from a forcing rule).
        forcing: the forcing rule of ``inexact`` for fb / min / blend without friction:
            ``active_set`` (a step after one that changed statuses is solved loosely, at
            most to a relative ``ETA_SET`` = 1e-2, and its Krylov solve starts from the
            last step's direction) or ``eisenstat_walker`` (Eisenstat–Walker's forcing
            alone, tightening towards exact Newton while ‖Φ‖ falls slowly; from zero).
        petsc_options: PETSc options over the linear solver's defaults.
        predictor: the start of a nonlinear solve lifted by the tangent
            (``predictor``): tangent, none, or auto (tangent for a problem with an
            energy).
        epsilon0: the penalty baseline's ε = ε₀ E/h (E: Young's modulus, or k for scalar
            models; h the cell diameter; ``baselines``).
        r0: the augmented Lagrangian baseline's r = r₀ E/h.
        gamma0: Nitsche's γ = γ₀ E/h.
        nitsche_theta: Nitsche's θ ∈ {1, 0, −1} (symmetric, θ = 0, skew-symmetric).
        uzawa_rtol: the augmented Lagrangian's outer loop stops at
            max|μ_{k+1} − μ_k| ≤ uzawa_rtol · max μ_{k+1}.
        uzawa_max_it: at most this many outer iterations.

    Build it from keywords: ``SolverOptions.parse({"method": "min"})`` (an invalid value is
    one ConfigError line naming the key) or ``SolverOptions(method="min")`` (pydantic's
    ValidationError); a scene's driver builds it once from its ``solver`` section
    (``contact.drivers.solve.solve``).  A changed copy:
    ``options.model_copy(update={"rtol": 1e-6})`` (unchecked: use :meth:`parse`).
    Friction's tangential knobs (form, c_t, …) are ``FrictionOptions``.

    Example:
        >>> import contact
        >>> contact.SolverOptions.parse({"method": "min", "rtol": 1e-8}).method
        'min'
        >>> contact.SolverOptions.parse({"rtol": -1})
        Traceback (most recent call last):
        contact.base.errors.ConfigError: solver.rtol: ...
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    method: Annotated[str, BeforeValidator(one_of(METHODS))] = "fb"
    mu: Annotated[float, BeforeValidator(number(open_unit))] = 0.5
    c: Annotated[Literal["auto"] | float, BeforeValidator(checked(auto_or_positive))] = "auto"
    kappa: Annotated[float, BeforeValidator(number(positive))] = 1.0
    line_search: Annotated[str, BeforeValidator(one_of(LINE_SEARCHES))] = "auto"
    polish: Annotated[bool, BeforeValidator(boolean)] = True
    rtol: Annotated[float, BeforeValidator(number(nonnegative))] = 1e-12
    atol: Annotated[float, BeforeValidator(number(nonnegative))] = 1e-12
    max_it: Annotated[Literal["auto"] | int, BeforeValidator(auto_or(integer(positive)))] = "auto"
    linear: Annotated[str, BeforeValidator(one_of(LINEAR))] = "auto"
    inexact: Annotated[bool, BeforeValidator(boolean)] = True
    forcing: Annotated[str, BeforeValidator(one_of(FORCINGS))] = "active_set"
    petsc_options: Annotated[dict, BeforeValidator(mapping_of(valid_petsc_value))] = FrozenDict()
    predictor: Annotated[str, BeforeValidator(one_of(PREDICTORS))] = "auto"
    # the baselines' parameters (:mod:`.baselines`), each scaled by E/h (k/h): ε = ε₀ E/h, …
    epsilon0: Annotated[float, BeforeValidator(number(positive))] = 1e3
    r0: Annotated[float, BeforeValidator(number(positive))] = 100.0
    gamma0: Annotated[float, BeforeValidator(number(positive))] = 10.0
    nitsche_theta: Annotated[float, BeforeValidator(number(theta_value))] = 1.0
    uzawa_rtol: Annotated[float, BeforeValidator(number(positive))] = 1e-8
    uzawa_max_it: Annotated[int, BeforeValidator(integer(positive))] = 100

    @classmethod
    def parse(cls, values: Mapping[str, Any], path: str = "solver") -> SolverOptions:
        """Return the options of keyword ``values`` (None: the default), validated.

        A bad value is one ConfigError line ``<path>.<key>: …`` with the scene's messages,
        an unknown key named too.

        Args:
            values: the knobs by name.
            path: the section's name in messages.

        Returns:
            The options.
        """
        return parse_section(cls, values, path)

    def knobs(self) -> SolverOptions:
        """Return these options as the plain :class:`SolverOptions`.

        A subclass's extra fields, such as a scene section's driver keys, are left out; not
        validated again.
        """
        return SolverOptions.model_construct(
            **{key: getattr(self, key) for key in SolverOptions.model_fields}
        )


class FrictionOptions(BaseModel):
    """The knobs of the tangential (friction) rows of a solve (docs/theory.md §1.4, §4.3), validated
    once and immutable, like :class:`SolverOptions`.

    ``c_t`` — the tangential NCP scaling, a stress per length: ``auto`` (nodal,
    c_t,i = K_tt,i / (κ_t w_i)) or a number > 0; ``kappa_t`` — κ_t; ``form`` — the
    tangential NCP, ``projection`` (Alart–Curnier) or ``hsw`` (Hüeber–Stadler–Wohlmuth's max
    form); ``coulomb`` — ``ssn`` (semismooth Newton on all rows) or ``fixed_point`` (a
    sequence of Tresca problems on the normal pressure); ``fixed_point_rtol`` — it stops at
    |ρ_new − ρ| ≤ rtol |ρ|; ``fixed_point_max_it`` — at most this many Tresca solves.
    The friction law's data (the law, F, the Tresca threshold) are the scene's, not
    options: a scene's ``friction`` section is these knobs plus them
    (:class:`contact.setup.scene_config.FrictionConfig`).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    c_t: Annotated[Literal["auto"] | float, BeforeValidator(checked(auto_or_positive))] = "auto"
    kappa_t: Annotated[float, BeforeValidator(number(positive))] = 1.0
    form: Annotated[str, BeforeValidator(one_of(FRICTION_FORMS))] = "hsw"
    coulomb: Annotated[str, BeforeValidator(one_of(COULOMB_SOLVERS))] = "ssn"
    fixed_point_rtol: Annotated[float, BeforeValidator(number(positive))] = 1e-10
    fixed_point_max_it: Annotated[int, BeforeValidator(integer(positive))] = 100

    @classmethod
    def parse(cls, values: Mapping[str, Any], path: str = "friction") -> FrictionOptions:
        """The options of keyword ``values`` (None: the default), validated: one ConfigError
        line ``<path>.<key>: …``.
        """
        return parse_section(cls, values, path)

    def knobs(self) -> FrictionOptions:
        """These options as the plain ``FrictionOptions`` (a subclass's extra fields,
        such as a scene section's data, left out; not validated again).
        """
        return FrictionOptions.model_construct(
            **{key: getattr(self, key) for key in FrictionOptions.model_fields}
        )


#: the adaptive loop's marking: Dörfler's bulk criterion, the maximum strategy, every cell,
#: or none (one solve)
STRATEGIES = ("dorfler", "maximum", "uniform", "none")
#: the indicators that mark: the estimator's own, or the residual ones (the bound at the end)
INDICATORS = ("estimator", "residual")


#: adaptive stopping balances each solve against its level's estimate: it needs every one
NO_LAST_ESTIMATE_STOPPING = (
    "adapt.estimate_last: false does not go with solver.stopping: adaptive (which estimates "
    "every solve of every level)"
)


class AdaptOptions(BaseModel):
    """The knobs of an adaptive loop (docs/theory.md §6), validated once and immutable.

    Like :class:`SolverOptions`; a scene's ``adapt`` section is these knobs and its output's
    (``contact.setup.scene_config.AdaptConfig``).

    Attributes:
        strategy: dorfler, maximum, uniform or none (one solve).
        theta: the marking fraction in (0, 1].
        growth: each level has at least this many times its parent's DoFs: the cells of
            largest η_T join Dörfler's set until the predicted DoFs grow by it
            (``contact.adaptivity.mark.Growth``), so the levels are O(log N) and the
            loop costs at most growth/(growth − 1) times its last level; 1 (the default):
            Dörfler's set alone.
        indicators: what marks the cells: ``estimator`` (the default: the estimator's own
            η_T, its η on every level) or ``residual`` (the residual estimator's DG0
            indicators mark every level; an equilibrated estimator's guaranteed bound is
            computed only on the last level and where it may meet ``tol``, so the other
            levels' η are the residual estimator's, not bounds; adaptive stopping, which
            needs the bound on every level, keeps ``estimator``).
        tol: stop at η ≤ tol.
        max_dofs: the most DoFs of a level.
        max_levels: the most levels.
        estimate_last: estimate the last level (the default).  False: a level the loop
            knows to be its last before estimating it — ``max_levels`` reached, strategy
            ``none``, or (P1 on triangles) a next level certainly above ``max_dofs`` — is
            solved and not estimated: a loop run on a level budget then ends with its last
            solution, as a uniform run does, and that level has no η, η_T or effectivity.
        nested: each level starts from the previous solution.
        rebalance: repartition refined meshes.
        newton_rtol: Newton's relative tolerance inside the loop.

    Example:
        >>> import contact
        >>> contact.AdaptOptions().updated(theta=0.3, max_levels=4).theta
        0.3
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    strategy: Annotated[str, BeforeValidator(one_of(STRATEGIES))] = "dorfler"
    theta: Annotated[float, BeforeValidator(number(half_open_unit))] = 0.5
    growth: Annotated[float, BeforeValidator(number(at_least_one))] = 1.0
    indicators: Annotated[str, BeforeValidator(one_of(INDICATORS))] = "estimator"
    tol: Annotated[float, BeforeValidator(number(nonnegative))] = 0.0
    max_dofs: Annotated[int, BeforeValidator(integer(positive))] = 200000
    max_levels: Annotated[int, BeforeValidator(integer(positive))] = 8
    estimate_last: Annotated[bool, BeforeValidator(boolean)] = True
    nested: Annotated[bool, BeforeValidator(boolean)] = True
    rebalance: Annotated[bool, BeforeValidator(boolean)] = True
    newton_rtol: Annotated[float, BeforeValidator(number(positive))] = 1e-10

    @classmethod
    def parse(cls, values: Mapping[str, Any], path: str = "adapt") -> AdaptOptions:
        """Return the options of keyword ``values``, validated.

        A bad value is one ConfigError line ``<path>.<key>: …``.

        Args:
            values: the knobs by name.
            path: the section's name in messages.

        Returns:
            The options.
        """
        return parse_section(cls, values, path)

    def updated(self, **changes: Any) -> Any:
        """Return a copy with keyword ``changes``, each validated.

        A change that is None leaves its knob unchanged; a bad one is a ConfigError
        ``adapt.<key>: …``.

        Args:
            **changes: the knobs to change.

        Returns:
            The changed options.
        """
        given = {k: v for k, v in changes.items() if v is not None}
        if not given:
            return self
        checked_ = type(self).parse(given)
        return self.model_copy(update={k: getattr(checked_, k) for k in given})


DEFAULT_PETSC_OPTIONS = {
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}
ELASTICITY_3D_PETSC_OPTIONS = {"ksp_type": "bcgs", "pc_type": "gamg", "ksp_rtol": 1e-10}
#: friction's reduced block system (:mod:`.block_system`): GMRES, right preconditioned so that
#: its residual norm is the unpreconditioned one the stopping test reads; GAMG as for ``gamg``
BLOCK_PETSC_OPTIONS = {"ksp_type": "gmres", "ksp_pc_side": "right", "ksp_gmres_restart": 100}
#: ``hp_patch`` (:mod:`contact.hp.precondition`): CG on the reduced system as for ``gamg``, its
#: two-level preconditioner set up by the problem (PCMG: the Galerkin coarse matrix, one LU per
#: vertex patch in the additive Schwarz smoother)
HP_PATCH_PETSC_OPTIONS = {
    **{k: v for k, v in REDUCED_PETSC_OPTIONS.items() if not k.startswith("pc_gamg")},
    "pc_type": "mg",
    "pc_mg_galerkin": "both",
    "mg_levels_sub_ksp_type": "preonly",
    "mg_levels_sub_pc_type": "lu",
}
ASSEMBLED_PETSC_OPTIONS: dict[str, dict[str, Any]] = {
    "direct": DEFAULT_PETSC_OPTIONS,
    "bcgs": ELASTICITY_3D_PETSC_OPTIONS,
}


#: method variants as studies and benchmarks list them, beside :data:`METHODS`
METHOD_VARIANTS = ("fb-nopolish", "blend-nopolish", "nitsche-skew")


def method_variant(name: str) -> tuple[str, dict]:
    """Return (method, options) of a method name as benchmarks, studies and tests list it.

    ``fb``, … or ``fb-nopolish`` / ``blend-nopolish`` (the pure Newton method),
    ``nitsche-skew`` (Nitsche with θ = −1) → (method, options for ``contact.solve``).
    """
    if name.endswith("-nopolish"):
        return name.removesuffix("-nopolish"), {"polish": False}
    if name == "nitsche-skew":
        return "nitsche", {"nitsche_theta": -1.0}
    return name, {}


def default_options(kind: str, tdim: int, ranks: int = 1) -> dict:
    """PETSc options of linear solver ``kind`` (``direct``, ``gamg``, ``bcgs``, or ``auto``:
    direct in 2D, gamg in 3D — the choice for small problems, known before the mesh exists,
    used to check the user's options at load) in ``tdim`` dimensions.  For ``gamg`` in 3D,
    plain (unsmoothed) aggregation: its setup is ~5× cheaper than smoothed aggregation's
    Galerkin products (hertz_3d, 302k DoFs: 1.6 s against 7.9 s, 78 against 32 CG
    iterations to 1e-8), and a Newton solve sets GAMG up once per step while its forcing
    terms ask few iterations (on hertz_3d's final mesh, 185k DoFs, min: 1.4–1.8× one
    smoothed CG + GAMG solve of K against 2.6–3.1×).  In 2D smoothed aggregation stays
    (unsmoothed needs 161 instead of 17 iterations on the 1024² Poisson matrix).

    On ``ranks`` > 1 in 2D the first level's aggressive coarsening uses MIS-2 instead of the
    squared graph AᵀA, whose product scales badly across ranks (problem A's finest level,
    1.23M DoFs, 2 ranks: ``MatTrnMatMultSym`` 1.01 s against 0.56 s serially, GAMG's setup
    2.68 s against 3.17 s).  Measured (the finest solve repeated from the same guess,
    alternating): 2 ranks 4.30–5.30 s against 5.01–5.72 s (21 against 19 CG iterations),
    but serially 6.55–7.25 s against 5.70–6.95 s, and in 3D on 2 ranks (hertz_3d, 865k DoFs)
    31.4 s against 24.4 s: the squared graph stays there.
    """
    if kind == "auto":
        kind = "direct" if tdim == 2 else "gamg"
    if kind == "gamg":
        if tdim == 3:
            extra = {"pc_gamg_agg_nsmooths": 0}
        elif ranks > 1:
            extra = {"pc_gamg_aggressive_square_graph": False}
        else:
            extra = {}
        return {**REDUCED_PETSC_OPTIONS, **extra}
    if kind == "gmres":
        return {**default_options("gamg", tdim, ranks), **BLOCK_PETSC_OPTIONS}
    if kind == "hp_patch":
        return dict(HP_PATCH_PETSC_OPTIONS)
    return dict(ASSEMBLED_PETSC_OPTIONS[kind])


def set_from_options(snes: PETSc.SNES, *inner: PETSc.KSP) -> None:
    """SetFromOptions of SNES, its KSP and PC and the ``inner`` KSPs; a bad PETSc option
    becomes a one-line ConfigError.
    """
    PETSc.Sys.pushErrorHandler("python")  # raise, do not print PETSc's trace
    try:
        snes.setFromOptions()
        snes.getKSP().setFromOptions()
        snes.getKSP().getPC().setFromOptions()
        for ksp in inner:
            ksp.setFromOptions()
    except PETSc.Error as err:
        raise ConfigError(
            f"solver.petsc_options: PETSc rejected the options ({petsc_message(err)})"
        ) from None
    finally:
        PETSc.Sys.popErrorHandler()


def petsc_value(val: Any) -> str:
    if isinstance(val, bool):
        return "true" if val else "false"
    return "" if val is None else str(val)


_checks = itertools.count()


def check_petsc_options(
    options: Mapping[str, Any], defaults: Mapping[str, Any], comm: MPI.Comm = MPI.COMM_WORLD
) -> None:
    """Refuse PETSc options that PETSc cannot set up, before any mesh is built: the
    ``options`` (``solver.petsc_options``) over the model's ``defaults`` configure a SNES
    (newtonls) that solves a tiny linear system — the 1D Laplacian, 4 rows per rank, as
    an MPI matrix on ``comm`` — so that unknown solver, preconditioner or factorization
    types (``pc_factor_mat_solver_type: nonsense``) fail here and not after the assembly.
    The failure is one ConfigError line naming the option that fails on its own (or all
    of them).  Collective.
    """
    if not options:
        return
    problem = _tiny_solve({**defaults, **options}, comm)
    if problem is None:
        return
    for key, value in options.items():  # which option is it?
        if _tiny_solve({**defaults, key: value}, comm) is not None:
            raise ConfigError(
                f"solver.petsc_options.{key}: PETSc cannot use {petsc_value(value)!r} ({problem})"
            )
    raise ConfigError(f"solver.petsc_options: PETSc cannot use these options together ({problem})")


def _tiny_solve(options: Mapping[str, Any], comm: MPI.Comm) -> str | None:
    """PETSc's message if ``options`` fail on the tiny system (on any rank), else None."""
    n = 4
    sizes = ((n, PETSc.DECIDE), (n, PETSc.DECIDE))
    A = PETSc.Mat().createAIJ(sizes, nnz=(3, 1), comm=comm)  # type: ignore[arg-type]
    lo, hi = A.getOwnershipRange()
    size = A.getSize()[0]
    for i in range(lo, hi):
        A.setValues(
            [i],
            [j for j in (i - 1, i, i + 1) if 0 <= j < size],
            [-1.0 if j != i else 2.0 for j in (i - 1, i, i + 1) if 0 <= j < size],
        )
    A.assemble()
    b, x, f = A.createVecLeft(), A.createVecRight(), A.createVecLeft()
    b.set(1.0)
    x.set(0.0)
    snes = PETSc.SNES().create(comm)  # type: ignore[arg-type]
    prefix = f"contactcheck{next(_checks)}_"
    snes.setOptionsPrefix(prefix)
    snes.setType("newtonls")

    def residual(s: PETSc.SNES, X: PETSc.Vec, F: PETSc.Vec) -> None:  # F = A x − b
        A.mult(X, F)
        F.axpy(-1.0, b)

    snes.setFunction(residual, f)
    snes.setJacobian(lambda s, X, J, P: None, A)
    db = PETSc.Options()
    for key, value in options.items():
        db.setValue(prefix + key, petsc_value(value))
    problem = None
    PETSc.Sys.pushErrorHandler("python")
    try:
        snes.setFromOptions()
        snes.solve(None, x)
    except PETSc.Error as err:
        problem = petsc_message(err)
    finally:
        PETSc.Sys.popErrorHandler()
        for key in options:
            db.delValue(prefix + key)
        for obj in (snes, A, b, x, f):
            obj.destroy()
    problems = [p for p in comm.allgather(problem) if p]
    return problems[0] if problems else None
