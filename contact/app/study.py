"""Parameter studies: one scene (or a few named variants of it), a cartesian product of
solver / refinement settings, one CSV row per run and the charts that compare them.

A study file (``configs/studies/*.yaml``)::

    name: tiny
    scene: ../signorini_square.yaml      # relative to this file (or an inline mapping)
    set: [mesh.cells=[16,16]]            # --set-style overrides of the base scene
    axes:                                # the cartesian product is the list of runs
      method: [fb, min, vinewtonrsls]
      line_search: [basic]
    cases:                               # optional: named variants, crossed with the axes
      far guess: {u0: "10"}              #   any axis value, and/or
      obtuse:    {scene: ../obtuse_square.yaml, set: [mesh.cells=[32,32]]}
    adapt: {max_levels: 6}               # options of adaptive runs (see below)
    charts: [speed_accuracy]             # which charts to draw (:data:`CHARTS`)
    repeat: 1                            # run every combination this many times

Axes (:data:`AXES`): ``method`` (a method or a variant: ``fb-nopolish``, ``blend-nopolish``,
``nitsche-skew``), ``parameter`` (a baseline's ε₀, r₀ or γ₀), ``mu``, ``c`` (number or
``auto``), ``kappa``,
``line_search``, ``max_it``, ``u0`` (initial-guess expression), ``linear`` (``solver.linear``:
auto, direct, gamg, bcgs) and ``sequence`` (grid sequencing: auto, off or a number of coarser
levels) set the scene's ``solver`` keys; ``linear_solver`` puts PETSc options on the
assembled Newton matrix: ``direct`` (MUMPS LU) or ``gamg`` (BiCGStab + GAMG, ``ksp_rtol``
1e-10); ``strategy`` is ``none`` (one solve) or an adaptive marking strategy
(``uniform``, ``dorfler``, ``maximum``) with ``theta``, ``growth`` (each level at least
that many times its parent's DoFs), ``indicators`` (``estimator`` or ``residual``: what
marks the cells) and ``nested`` (start each level from the previous solution, or cold from
``u0``); ``level`` refines the base mesh
uniformly that many times before solving (``contact.refine`` with every cell marked, so it
works for every mesh type, gmsh files included).  Without a ``strategy`` axis a run is
adaptive when the study's ``adapt.strategy`` or the scene's ``adapt`` section says so.

A case fixes some axis values and may swap the scene (its own file and ``set``); the runs
are every case × every combination of the axes, and each row names its ``case``.

Every run is one row of ``study.csv``: the case and swept values, DoFs, the exterior facets
in no boundary part (``untagged_facets``: they carry the natural condition; the study prints
the line of ``contact run`` on them once per mesh), Newton iterations
and active-set polishing solves (for adaptive runs on the final level and summed over the
levels), the linear solver and its Krylov iterations (MUMPS: one per solve; the final
level's or step's), converged, the SNES
reason and its :func:`outcome` class, the accuracy figures the scene allows (energy error
with ``data.exact``; the relative errors of a declared ``reference``, e.g. Hertz's
``a_error``, ``p0_error`` and their largest magnitude ``hertz_error``), η, the measure of the active
set, the wall time and the peak memory.  Every level of every run is one row of ``levels.csv``, with
the wall time since the start of the run (the x axis of speed-against-accuracy charts).  A run
that raises or does not converge is a row with ``converged=False`` and the reason in
``failure``; the study goes on.

A study file is validated as a whole (:class:`StudyConfig`, the scene's field types and
messages), so a bad study file fails before anything runs with one line
``<key path>: <problem>``.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import itertools
import json
import math
import resource
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from mpi4py import MPI
from pydantic import BeforeValidator, Field, ValidationError

from ..base.errors import ConfigError
from ..base.timing import Stopwatch
from ..base.validation import (
    Section,
    a_list,
    at_least_one,
    boolean,
    checked,
    config_error,
    integer,
    nonnegative,
    number,
    one_of,
    parse_member,
    positive,
    string,
    string_keys,
    typename,
)
from ..setup.config import apply_overrides, folder_name, load_config, read_yaml, switch_off
from ..setup.scene_config import (
    AdaptConfig,
    Count,
    Fraction,
    FrictionConfig,
    NonNegative,
    Positive,
    SceneConfig,
    SolverConfig,
    Switch,
)
from ..solvers import DEFAULT_PETSC_OPTIONS, ELASTICITY_3D_PETSC_OPTIONS, method_variant
from ..solvers.baselines import PARAMETERS as BASELINE_PARAMETERS
from ..solvers.options import INDICATORS, METHOD_VARIANTS, METHODS
from .dispatch import choose_driver
from .failures import INTERNAL, abort, all_failed, describe, interrupted, one_line

LINEAR_SOLVERS: dict[str, dict] = {  # named linear solvers (PETSc options) of the axis
    "direct": DEFAULT_PETSC_OPTIONS,  # preonly + LU (MUMPS), also for 3D elasticity
    "gamg": ELASTICITY_3D_PETSC_OPTIONS,  # BiCGStab + GAMG (the 3D elasticity default)
}
STRATEGIES = ("none", "uniform", "dorfler", "maximum")
CHARTS = ("speed_accuracy", "stability", "iterations")


class StudyAxes(Section):
    """The axes of a study that are no key of a scene section, or more than one: ``method``
    (a method or a variant: ``fb-nopolish``, ``nitsche-skew``, …), ``linear_solver`` (a
    named linear solver, :data:`LINEAR_SOLVERS`), ``strategy`` (none: one solve; or an
    adaptive marking strategy), ``level`` (uniform refinements of the base mesh), ``steps``
    (load steps: ``load.steps``), ``parameter`` (a baseline method's parameter: epsilon0
    for penalty, r0 for augmented_lagrangian, gamma0 for nitsche)."""

    method: Annotated[str, BeforeValidator(one_of((*METHODS, *METHOD_VARIANTS)))] = "fb"
    linear_solver: Annotated[str, BeforeValidator(one_of(tuple(LINEAR_SOLVERS)))] = "direct"
    strategy: Annotated[str, BeforeValidator(one_of(STRATEGIES))] = "none"
    level: Annotated[int, BeforeValidator(integer(nonnegative))] = 0
    steps: Annotated[int, BeforeValidator(integer(positive))] = 1
    parameter: Annotated[float, BeforeValidator(number(positive))] = 1.0


#: axis name -> the section (and its key) each of its values is validated as
AXES: dict[str, tuple[type[Section], str]] = {
    "method": (StudyAxes, "method"),
    **{key: (SolverConfig, key) for key in ("mu", "c", "kappa", "line_search")},
    **{key: (SolverConfig, key) for key in ("max_it", "u0", "linear", "sequence")},
    "linear_solver": (StudyAxes, "linear_solver"),
    "strategy": (StudyAxes, "strategy"),
    "theta": (AdaptConfig, "theta"),
    "growth": (AdaptConfig, "growth"),
    "indicators": (AdaptConfig, "indicators"),
    "nested": (AdaptConfig, "nested"),
    "level": (StudyAxes, "level"),
    "friction": (FrictionConfig, "law"),
    "coefficient": (FrictionConfig, "coefficient"),
    "threshold": (FrictionConfig, "threshold"),
    "c_t": (FrictionConfig, "c_t"),
    "kappa_t": (FrictionConfig, "kappa_t"),
    "friction_form": (FrictionConfig, "form"),
    "coulomb": (FrictionConfig, "coulomb"),
    "steps": (StudyAxes, "steps"),
    "parameter": (StudyAxes, "parameter"),
}
_SOLVER_AXES = ("method", "mu", "c", "kappa", "line_search", "max_it", "u0", "linear", "sequence")
_ADAPT_AXES = ("theta", "growth", "indicators", "nested")
#: the scene sections that decide a run's mesh and boundary parts (:meth:`Study.mesh_key`)
_MESH_KEYS = ("mesh", "boundaries", "bodies", "pairs", "constants", "model")
#: friction axes -> keys of the scene's friction section
_FRICTION_AXES = {axis: key for axis, (model, key) in AXES.items() if model is FrictionConfig}
#: friction keys each law uses (the others are dropped when an axis switches the law)
_LAW_KEYS = {
    "none": {"law"},
    "tresca": {"law", "threshold", "c_t", "kappa_t", "form"},
    "coulomb": {
        "law",
        "coefficient",
        "c_t",
        "kappa_t",
        "form",
        "coulomb",
        "fixed_point_rtol",
        "fixed_point_max_it",
    },
}


def _axis_value(axis: str, value: Any, path: str, constants: Mapping[str, float]) -> Any:
    """One value of an axis, validated as the key it sets (its message naming ``path``)."""
    model, key = AXES[axis]
    return parse_member(model, key, value, path, {"constants": constants})


def _scene_ref(v: Any) -> str | None:
    if isinstance(v, str) and v.strip() or isinstance(v, dict):
        return None
    return f"expected a path to a scene YAML file (or a scene mapping), got {typename(v)} {v!r}"


def _charts(v: list) -> str | None:
    bad = [c for c in v if c not in CHARTS]
    if bad:
        return f"unknown chart {bad[0]!r} (expected some of {', '.join(CHARTS)})"
    return None


#: a free-form mapping (a case: its scene, set and axis values, checked by load_study)
_Mapping = Annotated[dict, BeforeValidator(string_keys)]


class StudyAdapt(Section):
    """A study's ``adapt`` section: the adaptive loop's options of its adaptive runs (only
    the keys given; the others are the scene's or the defaults)."""

    strategy: Annotated[str, BeforeValidator(one_of(STRATEGIES))] | None = None
    theta: Fraction | None = None
    growth: Annotated[float, BeforeValidator(number(at_least_one))] | None = None
    indicators: Annotated[str, BeforeValidator(one_of(INDICATORS))] | None = None
    tol: NonNegative | None = None
    max_dofs: Count | None = None
    max_levels: Count | None = None
    estimate_last: Switch | None = None
    nested: Switch | None = None
    newton_rtol: Positive | None = None


class StudyConfig(Section):
    """A study file, validated (the scenes it names are validated by :func:`load_study`)."""

    name: Annotated[str, BeforeValidator(string(folder_name))] | None = None
    #: the scene: a YAML file relative to the study file, or an inline mapping
    scene: Annotated[Any, BeforeValidator(checked(_scene_ref))]
    #: overrides of the base scene, as contact run --set
    set: Annotated[list, BeforeValidator(a_list())] = Field(default_factory=list)
    #: axis name -> list of values (validated by AXES)
    axes: Any = None
    #: label -> {scene, set, <axis>: value}: named variants crossed with the axes
    cases: (
        Annotated[
            dict[str, Annotated[dict, BeforeValidator(string_keys)]], BeforeValidator(string_keys)
        ]
        | None
    ) = None
    adapt: StudyAdapt | None = None
    charts: Annotated[list, BeforeValidator(a_list(_charts))] = Field(
        default_factory=lambda: ["speed_accuracy"]
    )
    repeat: Annotated[int, BeforeValidator(integer(positive))] = 1
    #: solve each case once, untimed, before the timed runs
    warmup: Annotated[bool, BeforeValidator(boolean)] = True


@dataclass
class Case:
    """A named variant of the study's scene: its raw mapping (``set`` applied), its
    validated config and the axis values it fixes."""

    label: str | None
    raw: dict = field(repr=False)
    config: SceneConfig = field(repr=False)
    params: dict = field(default_factory=dict)


@dataclass
class Study:
    """A validated study: the base scene, its cases (one unnamed case when the study has
    none) and the axes.  ``runs()`` lists the parameter combinations: every case, then the
    cartesian product of the axes in the order written (the last axis varies fastest)."""

    name: str
    scene: str  # absolute path of the scene file, or "<inline>"
    set: list[str]
    axes: dict[str, list]
    adapt: dict[str, Any]  # only the keys given
    repeat: int
    cases: dict[str | None, Case] = field(repr=False)
    charts: list[str] = field(default_factory=lambda: ["speed_accuracy"])
    warmup: bool = True

    @property
    def base_config(self) -> SceneConfig:
        return next(iter(self.cases.values())).config

    @property
    def named_cases(self) -> bool:
        return None not in self.cases

    @functools.cached_property
    def has_exact(self) -> bool:
        """Whether some case knows its exact solution (then rows carry the energy error)."""
        return any(bool(c.config.data.exact) for c in self.cases.values())

    @functools.cached_property
    def reference_columns(self) -> tuple[str, ...]:
        """The relative-error columns of the references the cases declare
        (:func:`contact.post.reference.error_columns`, e.g. a_error, p0_error, hertz_error)."""
        from ..post.reference import error_columns

        cols: list[str] = []
        for c in self.cases.values():
            cols += [k for k in error_columns(c.config.reference) if k not in cols]
        return tuple(cols)

    @property
    def accuracy(self) -> str:
        """The column the speed-against-accuracy chart plots: the energy error, else a
        declared reference's combined error (``<type>_error``), else η."""
        combined = [
            k for k in self.reference_columns if k.removesuffix("_error") in _reference_types()
        ]
        return "error" if self.has_exact else combined[0] if combined else "eta"

    def runs(self) -> list[dict[str, Any]]:
        names = list(self.axes)
        combos = [
            dict(zip(names, combo)) for combo in itertools.product(*(self.axes[n] for n in names))
        ]
        head = (lambda label: {"case": label}) if self.named_cases else (lambda label: {})
        return [{**head(label), **combo} for label in self.cases for combo in combos]

    def plan(self, params: Mapping[str, Any]) -> tuple[dict, int, dict | None]:
        """The run's raw scene, its number of uniform refinements and its adaptive options
        (``None``: one solve)."""
        case = self.cases[params.get("case")]
        params = {**case.params, **params}
        raw = copy.deepcopy(case.raw)
        solver = raw["solver"] = dict(raw.get("solver") or {})
        raw["output"] = {**(raw.get("output") or {}), "verbose": False}
        for key in _SOLVER_AXES:
            if key in params:
                solver[key] = params[key]
        if "method" in params:  # a variant (fb-nopolish, nitsche-skew): its method and options
            solver["method"], variant = method_variant(params["method"])
            solver.update(variant)
        if "parameter" in params and solver.get("method") in BASELINE_PARAMETERS:
            solver[BASELINE_PARAMETERS[solver["method"]]] = params["parameter"]
        if "linear_solver" in params:
            solver["petsc_options"] = dict(LINEAR_SOLVERS[params["linear_solver"]])
        if any(axis in params for axis in _FRICTION_AXES):
            friction = {
                **(raw.get("friction") or {}),
                **{key: params[axis] for axis, key in _FRICTION_AXES.items() if axis in params},
            }
            law = friction.get("law", "none")
            raw["friction"] = {
                k: v for k, v in friction.items() if k in _LAW_KEYS.get(law, friction)
            }
        if "steps" in params:
            raw["load"] = {
                **{k: v for k, v in (raw.get("load") or {}).items() if k != "times"},
                "steps": params["steps"],
            }
        adapt = dict(self.adapt)
        adapt.update({k: params[k] for k in _ADAPT_AXES if k in params})
        strategy = adapt.pop("strategy", None)
        strategy = params.get("strategy", strategy)
        if strategy is None:
            adaptive = case.config.adapt is not None
        else:
            adaptive = strategy != "none"
            if adaptive:
                adapt["strategy"] = strategy
        return raw, params.get("level", 0), (adapt if adaptive else None)

    @functools.cached_property
    def adaptive_possible(self) -> bool:
        """Whether any run is adaptive (then the rows get a ``stop`` column)."""
        return any(self.plan(params)[2] is not None for params in self.runs())

    def as_dict(self) -> dict[str, Any]:
        out = {
            "name": self.name,
            "scene": self.scene,
            "set": self.set,
            "axes": self.axes,
            "adapt": self.adapt,
            "charts": self.charts,
            "repeat": self.repeat,
            "runs": len(self.runs()) * self.repeat,
            "base_scene": self.base_config.as_dict(),
        }
        if self.named_cases:
            out["cases"] = {
                label: {**c.params, "scene": c.config.name} for label, c in self.cases.items()
            }
        return out


def _reference_types() -> tuple[str, ...]:
    from ..post.reference import REFERENCES

    return tuple(REFERENCES)


def _read_scene(
    ref: str | dict, sets: list, base_dir: Path, path: str, extra: tuple[str, ...] = ()
) -> tuple[dict, SceneConfig, str]:
    """Read a scene reference (a path relative to ``base_dir``, or a mapping), apply the
    ``set`` overrides, then the command line's ``extra`` ones (``contact study --set``), make
    a relative mesh file absolute and validate: (raw, cfg, label).  Errors name the study
    key ``path`` (or the --set item)."""
    if isinstance(ref, dict):
        raw, scene_name, scene_dir, label = copy.deepcopy(ref), None, base_dir, "<inline>"
    else:
        scene_path = Path(ref).expanduser()
        scene_path = (
            scene_path if scene_path.is_absolute() else Path(base_dir) / scene_path
        ).resolve()
        if not scene_path.is_file():
            raise ConfigError(f"{path}scene: no such file {str(scene_path)!r}")
        raw, scene_name, scene_dir, label = (
            read_yaml(scene_path),
            scene_path.stem,
            scene_path.parent,
            str(scene_path),
        )
    if not isinstance(sets, list):
        raise ConfigError(
            f"{path}set: expected a list of KEY.PATH=VALUE strings, got {typename(sets)} {sets!r}"
        )
    for i, item in enumerate(sets):
        if not isinstance(item, str) or "=" not in item:
            raise ConfigError(
                f"{path}set[{i}]: expected a string KEY.PATH=VALUE, got {typename(item)} {item!r}"
            )
        try:
            raw = apply_overrides(raw, [item])
        except ConfigError as err:
            raise ConfigError(f"{path}set[{i}]: {str(err).removeprefix('--set ')}") from None
    raw = switch_off(apply_overrides(raw, list(extra)))  # the runs' own sections see no 'none'
    if isinstance(raw.get("mesh"), dict) and isinstance(raw["mesh"].get("file"), str):
        mesh_file = Path(raw["mesh"]["file"])
        if not mesh_file.is_absolute():
            raw["mesh"]["file"] = str((Path(scene_dir) / mesh_file).resolve())
    if not raw.get("name"):
        raw["name"] = scene_name or "scene"
    try:
        cfg = load_config(raw)
    except ConfigError as err:  # the key path inside the scene, after `set`
        raise ConfigError(f"{path}scene.{err}") from None
    return raw, cfg, label


def load_study(
    source: str | Path | Mapping | Study, overrides: list[str] | tuple[str, ...] = ()
) -> Study:
    """Read (if a path) and validate a study; raise :class:`ConfigError` (one line) on bad
    input.  A relative ``scene`` path is taken relative to the study file (to the current
    directory for a mapping).  ``overrides`` (``contact study --set``) apply to the scene of
    every case, after the study's and the case's own ``set``."""
    if isinstance(source, Study):
        if overrides:
            raise ValueError("load_study: overrides need a study file or mapping, not a Study")
        return source
    if isinstance(source, Mapping):
        data, base_dir, stem = dict(source), Path.cwd(), None
    else:
        path = Path(source)
        data, base_dir, stem = read_yaml(path), path.parent, path.stem
    try:
        st = StudyConfig.model_validate(data)
    except ValidationError as err:
        raise config_error(err, "", StudyConfig) from None
    extra = tuple(overrides)
    base_raw, base_cfg, label = _read_scene(st.scene, st.set, base_dir, "", extra)
    axes = _validate_axes(st.axes, base_cfg.constants)
    cases: dict[str | None, Case] = {None: Case(None, base_raw, base_cfg)}
    if st.cases:
        cases = {
            name: _validate_case(name, spec, st, base_raw, base_cfg, base_dir, axes, extra)
            for name, spec in st.cases.items()
        }
    adapt = st.adapt.model_dump(exclude_none=True) if st.adapt is not None else {}
    return Study(
        name=st.name or stem or "study",
        scene=label,
        set=list(st.set) + list(extra),
        axes=axes,
        adapt=adapt,
        repeat=st.repeat,
        cases=cases,
        charts=list(st.charts),
        warmup=st.warmup,
    )


def _validate_case(
    name: str,
    spec: dict,
    st: StudyConfig,
    base_raw: dict,
    base_cfg: SceneConfig,
    base_dir: Path,
    axes: dict,
    extra: tuple[str, ...] = (),
) -> Case:
    path = f"cases.{name}."
    raw, cfg = base_raw, base_cfg
    # the case's own scene (default: the study's), then its `set`
    if "scene" in spec or "set" in spec:
        ref = spec.get("scene", st.scene)
        sets = ([] if "scene" in spec else list(st.set)) + list(spec.get("set") or [])
        raw, cfg, _ = _read_scene(ref, sets, base_dir, path, extra)
    params = {}
    for key, value in spec.items():
        if key in ("scene", "set"):
            continue
        if key not in AXES:
            raise ConfigError(
                f"{path}{key}: unknown key (expected scene, set or an axis: {', '.join(AXES)})"
            )
        if key in axes:
            raise ConfigError(f"{path}{key}: is also an axis of the study; set it in one place")
        params[key] = _axis_value(key, value, path + key, cfg.constants)
    return Case(name, raw, cfg, params)


def _validate_axes(axes: Any, constants: Mapping[str, float]) -> dict[str, list]:
    if axes is None:
        return {}
    if not isinstance(axes, dict):
        raise ConfigError(
            f"axes: expected a mapping of axis name to a list of values, got "
            f"{typename(axes)} {axes!r}"
        )
    out: dict[str, list] = {}
    for name, values in axes.items():
        if name not in AXES:
            raise ConfigError(f"axes.{name}: unknown axis (expected one of {', '.join(AXES)})")
        if not isinstance(values, list) or not values:
            raise ConfigError(
                f"axes.{name}: expected a non-empty list of values, got {typename(values)} "
                f"{values!r}"
            )
        checked = [
            _axis_value(name, v, f"axes.{name}[{i}]", constants) for i, v in enumerate(values)
        ]
        for i, v in enumerate(checked):
            if v in checked[:i]:
                raise ConfigError(f"axes.{name}[{i}]: {v!r} is listed twice")
        out[name] = checked
    return out


# --------------------------------------------------------------------------------- running
def outcome(row: Mapping[str, Any]) -> str:
    """The class of a run for the stability map, from its SNES reason: ``converged``;
    ``max iterations`` (the iteration limit, e.g. an active set that cycles); ``stalled``
    (no step reduces the merit ½‖Φ‖²: line search failure, local minimum of the merit);
    ``diverged`` (NaN/Inf, a failed linear solve, any other divergence); ``error`` (the run
    raised, e.g. bad options).  A hyperelastic run that converged to no stable state is
    ``inverted`` (its solution has det F ≤ 0 somewhere: no deformation) or ``unstable``
    (K_T has negative eigenvalues there: a saddle of the energy)."""
    reason = str(row.get("reason") or "")
    if row.get("converged") is True or reason.startswith("converged"):
        if row.get("min_det_F") not in (None, "") and float(row["min_det_F"]) <= 0:
            return "inverted"
        if row.get("tangent_negative_eigenvalues") not in (None, "", 0):
            return "unstable"
        return "converged"
    # Newton's or the fixed point's limit
    if reason.startswith("diverged") and reason.endswith("max_it"):
        return "max iterations"
    if reason in ("diverged_line_search", "diverged_local_min", "diverged_tr_delta"):
        return "stalled"
    return "diverged" if reason.startswith("diverged") else "error"


def _peak_rss_mib(comm: MPI.Comm) -> float:
    """Peak resident memory in MiB summed over the ranks.

    This is ``getrusage(RUSAGE_SELF).ru_maxrss``: each process's high-water mark *so far*
    (it never goes down), so a run's value includes every earlier run of the study in the
    same process; it is an upper bound for the run itself (run the study with a single
    combination, or compare along the study, to isolate one setting)."""
    kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    return round(comm.allreduce(kib, op=MPI.SUM) / 1024.0, 1)


def _mesh_key(raw: Mapping[str, Any], level: int) -> str:
    """What decides the mesh a run starts from, its boundary parts and the condition its
    untagged facets carry (the scene's mesh, boundaries, bodies, pairs, constants and model,
    and the run's uniform refinements): runs with equal keys pose the same boundary, which
    the study reports once (:func:`iter_study`)."""
    scene = {key: raw.get(key) for key in _MESH_KEYS}
    return json.dumps([scene, level], sort_keys=True, default=str)


def _refine_uniformly(scene, times: int):
    from ..setup.run import refine

    for _ in range(times):
        tdim = scene.mesh.topology.dim
        n_owned = scene.mesh.topology.index_map(tdim).size_local
        scene, _ = refine(scene, np.arange(n_owned, dtype=np.int32))
    return scene


def _figures(study: Study, scene, result, eta: float | None, error: float | None) -> dict[str, Any]:
    """The accuracy figures of one converged solve: energy error, Hertz errors, η, and the
    measure of the active set (Σ w_i over active nodes: a length or an area)."""
    from ..output.run_report import active_measure

    out: dict[str, Any] = {}
    if study.has_exact:
        out["error"] = "" if error is None else error
    out.update({k: "" for k in study.reference_columns})
    if scene.config.reference is not None:
        from ..post.reference import compare, error_values
        from ..setup.posed import posed_of

        comparison = compare(posed_of(scene), result)
        assert comparison is not None  # the scene declares a reference
        out.update(error_values(scene.config.reference, comparison))
    out["eta"] = "" if eta is None else eta
    out["active_measure"] = active_measure(result)
    return out


def _empty_figures(study: Study) -> dict[str, Any]:
    out: dict[str, Any] = {"error": ""} if study.has_exact else {}
    out.update({k: "" for k in study.reference_columns})
    return {**out, "eta": "", "active_measure": ""}


def run_one(
    study: Study,
    params: Mapping[str, Any],
    comm: MPI.Comm = MPI.COMM_WORLD,
    posed: Callable[[str, str], None] | None = None,
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Build the scene for ``params``, solve (or run the adaptive loop); return the row's
    figures (without the swept values) and one row per level.  Never raises for a failing
    run.

    ``seconds`` is the wall time (maximum over ranks) of building the scene, the uniform
    refinements and the solve or the whole adaptive loop (which estimates on every level);
    for a single solve the final η / error evaluation is not included.  A level row's
    ``seconds`` is the time from the start of the run to the end of that level.  The first
    run of a study also pays for any JIT compilation not yet in the FFCx cache (use
    ``repeat: 2``).  Under MPI an exception raised on every rank (bad options, an error
    raised by all ranks) is a failed row; one raised on some ranks only ends the job
    (:func:`.failures.abort`, exit code 3) after :data:`~.failures.AGREE_SECONDS`, since the
    other ranks wait in a collective; Ctrl-C is raised on (:mod:`.failures`).

    ``untagged_facets`` counts the exterior facets in no boundary part of the run's final
    mesh (those carry the natural condition; summary.json's ``untagged_boundary`` of
    ``contact run``).  ``posed(key, line)``, when given, receives the one line on the
    untagged facets of the mesh the run starts from
    (:meth:`contact.setup.untagged.Untagged.line`) with the key of that mesh
    (:func:`_mesh_key`), before the solve."""
    from ..adaptivity.energy_error import solution_error
    from ..hp.adapt import adapt
    from ..setup.run import estimate, solve
    from ..setup.scene import load_scene
    from ..setup.untagged import untagged_boundary
    from ..solvers.result import not_converged_text

    out: dict[str, Any] = {
        "dofs": "",
        "untagged_facets": "",
        "levels": "",
        "newton_iterations": "",
        "newton_iterations_total": "",
        "polish_solves": "",
        "polish_solves_total": "",
        "linear_solver": "",
        "krylov_iterations": "",
        "converged": False,
        "reason": "",
        **_empty_figures(study),
    }
    levels: list[dict[str, Any]] = []
    agree = comm.Dup() if comm.size > 1 else None  # only for agreeing on a failure
    comm.barrier()
    clock = Stopwatch()
    failure = ""
    try:
        raw, level, adapt_opts = study.plan(params)
        scene = load_scene(raw, comm=comm)
        scene = _refine_uniformly(scene, level)
        untagged = untagged_boundary(scene.mesh, scene.boundary)
        out["untagged_facets"] = untagged.facets
        if posed is not None:
            posed(_mesh_key(raw, level), untagged.line(scene.config.elastic))
        final = scene
        driver = choose_driver(scene.config, adaptive=adapt_opts is not None)
        if driver == "load_path":
            seconds, failure, final = _run_path(study, scene, adapt_opts, out, levels, clock)
        elif driver == "solve":
            result = solve(scene, verbose=False)
            seconds = clock.seconds
            out.update(
                dofs=result.dofs,
                levels=1,
                newton_iterations=result.iterations,
                newton_iterations_total=result.iterations,
                polish_solves=result.polish_solves,
                polish_solves_total=result.polish_solves,
                linear_solver=result.linear,
                krylov_iterations=result.krylov_iterations,
                converged=bool(result.converged),
                reason=result.reason,
            )
            if result.converged:
                error = solution_error(result.problem, result)
                out.update(_figures(study, scene, result, estimate(scene, result).eta, error))
            else:
                failure = not_converged_text(result)
            levels.append(
                {
                    "level": 0,
                    **{
                        k: out[k]
                        for k in (
                            "dofs",
                            "newton_iterations",
                            "polish_solves",
                            "converged",
                            "reason",
                        )
                    },
                    **{k: out[k] for k in _empty_figures(study)},
                    "seconds": seconds,
                }
            )
            if study.adaptive_possible:
                out["stop"] = "single solve"
        else:

            def on_level(lv) -> None:
                row = {
                    "level": lv.index,
                    "dofs": lv.result.dofs,
                    "newton_iterations": lv.result.iterations,
                    "polish_solves": lv.result.polish_solves,
                    "converged": bool(lv.result.converged),
                    "reason": lv.result.reason,
                }
                row.update(
                    _figures(study, lv.scene, lv.result, lv.eta, lv.error)
                    if lv.result.converged
                    else _empty_figures(study)
                )
                # reduced over ranks with the others below
                row["seconds"] = clock.seconds
                levels.append(row)

            assert adapt_opts is not None  # the driver of an adaptive run
            res = adapt(scene, verbose=False, on_level=on_level, **adapt_opts)
            seconds = clock.seconds
            final = res.levels[-1].scene if res.levels else scene
            last = levels[-1]
            its = [lv.result.iterations for lv in res.levels]
            polish = [lv.result.polish_solves for lv in res.levels]
            converged = all(lv.result.converged for lv in res.levels)
            out.update(
                dofs=last["dofs"],
                levels=len(res.levels),
                newton_iterations=its[-1],
                newton_iterations_total=sum(its),
                polish_solves=polish[-1],
                polish_solves_total=sum(polish),
                linear_solver=res.levels[-1].result.linear,
                krylov_iterations=res.levels[-1].result.krylov_iterations,
                converged=converged,
                reason=last["reason"],
            )
            if converged:
                out.update({k: last[k] for k in _empty_figures(study)})
            else:
                failure = f"{res.stop}, last |Phi| = {res.levels[-1].result.residual:.3e}"
            out["stop"] = res.stop
        if final is not scene:  # refined by the loop: its final mesh's untagged facets
            out["untagged_facets"] = untagged_boundary(final.mesh, final.boundary).facets
    except Exception as err:  # noqa: BLE001 - any failing run is a row, never a crashed study
        if interrupted(err):
            raise
        seconds = clock.seconds
        out["converged"] = False
        failure = str(err) if isinstance(err, ConfigError) else describe(err)
        if not all_failed(agree):  # this rank's alone: the others wait in a collective
            abort(comm, INTERNAL, f"contact: internal error: study run {_label(params)}: {failure}")
    if agree is not None:  # every rank is here
        agree.Free()
        if study.adaptive_possible:
            out.setdefault("stop", "")
    out["outcome"] = "error" if failure and not out["reason"] else outcome(out)
    out["seconds"] = round(comm.allreduce(seconds, op=MPI.MAX), 4)
    out["peak_rss_mib"] = _peak_rss_mib(comm)
    out["ranks"] = comm.size
    out["failure"] = one_line(failure)  # one line, at most failures.MAX_LINE characters
    for row in levels:
        row["seconds"] = round(comm.allreduce(row["seconds"], op=MPI.MAX), 4)
    return out, levels


def _run_path(
    study: Study, scene, adapt_opts: dict | None, out: dict, levels: list, clock: Stopwatch
) -> tuple[float, str, Any]:
    """Run a load path for :func:`run_one`: one level row per step; the run's row has the last
    step's Newton iterations, their total, ``max_step_iterations``, and the figures (and, with
    friction, the friction ratio and the stick / slip measures) of the last step.  Returns
    (seconds, failure text, the last step's scene)."""
    from ..adaptivity.energy_error import solution_error
    from ..post.friction_resultants import surface_figures
    from ..setup.run import estimate, run_load_path

    def on_step(step) -> None:
        r = step.result
        levels.append(
            {
                "level": step.index - 1,
                "step": step.index,
                "time": step.time,
                "dofs": r.dofs,
                "newton_iterations": r.iterations,
                "polish_solves": 0,
                "converged": bool(r.converged),
                "reason": r.reason,
                **_empty_figures(study),
                "seconds": clock.seconds,
            }
        )

    path = run_load_path(
        scene,
        verbose=False,
        on_step=on_step,
        adaptive=adapt_opts is not None,
        adapt_options=adapt_opts,
    )
    seconds = clock.seconds
    last, its = path.steps[-1], [s.result.iterations for s in path.steps]
    out.update(
        dofs=last.result.dofs,
        levels=len(path.steps),
        newton_iterations=its[-1],
        newton_iterations_total=sum(its),
        polish_solves=0,
        polish_solves_total=0,
        linear_solver=last.result.linear,
        krylov_iterations=last.result.krylov_iterations,
        converged=path.converged,
        reason=last.result.reason,
        max_step_iterations=max(its),
    )
    if study.adaptive_possible:
        out["stop"] = path.stop
    if last.negative_eigenvalues is not None:  # hyperelastic: is the answer a stable state?
        out.update(min_det_F=last.min_det_F, tangent_negative_eigenvalues=last.negative_eigenvalues)
    if not path.converged:
        return seconds, f"{path.stop}, last |Phi| = {last.result.residual:.3e}", last.scene
    est = last.levels[-1].estimate if last.levels else estimate(last.scene, last.result)
    figures = _figures(
        study,
        last.scene,
        last.result,
        est.eta if est.computed else None,
        solution_error(last.result.problem, last.result),
    )
    if last.result.friction is not None:
        surface = surface_figures(last.posed, last.result)
        figures.update({k: surface[k] for k in ("friction_ratio", "stick_measure", "slip_measure")})
        if "fixed_point_iterations" in last.result.friction:
            figures["fixed_point_iterations"] = last.result.friction["fixed_point_iterations"]
    out.update(figures)
    levels[-1].update(figures)
    return seconds, "", last.scene


def _label(params: Mapping[str, Any]) -> str:
    return " ".join(f"{k}={v}" for k, v in params.items()) or "(base scene)"


def _duration(s: float) -> str:
    if s < 100:
        return f"{s:.2f} s" if s < 1 else f"{s:.1f} s" if s < 10 else f"{s:.0f} s"
    m, s = divmod(int(round(s)), 60)
    return f"{m} min {s:02d} s" if m < 60 else f"{m // 60} h {m % 60:02d} min"


def _progress(
    k: int, n: int, params: Mapping[str, Any], row: Mapping[str, Any], eta_s: float
) -> str:
    if row["converged"]:
        if row.get("stop") not in (None, "single solve") and row["levels"] != "":
            what = (
                f"converged, {row['levels']} levels, {row['dofs']} DoFs, "
                f"{row['newton_iterations']} its "
                f"({row['newton_iterations_total']} total)"
            )
        else:
            what = f"converged, {row['newton_iterations']} its"
    elif row["reason"]:
        what = f"FAILED ({row['reason']}), {row['newton_iterations']} its"
    else:
        what = f"FAILED: {row['failure']}"
    tail = f" (ETA {_duration(eta_s)})" if k < n else ""
    return f"[{k}/{n}] {_label(params)} → {what}, {_duration(row['seconds'])}{tail}"


def _warm_up(study: Study, comm: MPI.Comm) -> None:
    """Run the first combination of every case once, untimed, on its base mesh (two levels
    when adaptive, so the estimator and refinement are compiled too): the just-in-time
    compilation of the forms (FFCx/ffcx cache misses) is then not charged to the first
    timed run."""
    runs = study.runs()
    for label in study.cases:
        params = next(p for p in runs if p.get("case") == label)
        warm = dataclasses.replace(study, adapt={**study.adapt, "max_levels": 2}, warmup=False)
        run_one(warm, {**params, "level": 0}, comm)


def iter_study(
    study: Study, comm: MPI.Comm = MPI.COMM_WORLD, verbose: bool = True
) -> Iterator[tuple[dict, list[dict]]]:
    """Run the study's combinations one by one; yield each finished row with its level rows
    (which repeat the run number and swept values).  When ``verbose``, rank 0 prints the line
    ``contact: boundary: …`` on the exterior facets in no boundary part (as ``contact run``)
    once per distinct mesh the runs start from, before its first run's progress line."""
    combos = [(params, rep) for params in study.runs() for rep in range(1, study.repeat + 1)]
    n = len(combos)
    if study.warmup:
        _warm_up(study, comm)
    reported: set[str] = set()

    def posed(key: str, line: str) -> None:
        if key not in reported:
            reported.add(key)
            if verbose and comm.rank == 0:
                print(f"contact: {line}", flush=True)

    spent = 0.0
    for k, (params, rep) in enumerate(combos, start=1):
        watch = Stopwatch()
        figures, levels = run_one(study, params, comm, posed)
        spent += comm.allreduce(watch.seconds, op=MPI.MAX)
        row = {"run": k, **params, "repeat": rep, **figures}
        if verbose and comm.rank == 0:
            label = {**params, **({"repeat": rep} if study.repeat > 1 else {})}
            print(_progress(k, n, label, row, spent / k * (n - k)), flush=True)
        yield row, [{"run": k, **params, "repeat": rep, **lv} for lv in levels]


def pareto_front(points: list[tuple[float, float]], rtol: float = 1e-6) -> list[bool]:
    """For (time, error) pairs: True where no other point dominates, i.e. is at least as
    fast and at least as accurate and strictly better in one of the two.  Errors within a
    relative ``rtol`` count as equal (different solvers reach the same discrete solution up
    to round-off).  NaN / non-positive entries are never on the front."""
    ok = [math.isfinite(t) and math.isfinite(e) and t > 0 and e > 0 for t, e in points]

    def dominates(q: tuple[float, float], p: tuple[float, float]) -> bool:
        (tq, eq), (tp, ep) = q, p
        return tq <= tp and eq <= ep * (1 + rtol) and (tq < tp or eq < ep * (1 - rtol))

    return [
        ok[i] and not any(ok[j] and j != i and dominates(points[j], p) for j in range(len(points)))
        for i, p in enumerate(points)
    ]


def mark_pareto(rows: list[dict], key: str) -> None:
    """Add the ``pareto`` column (before ``failure`` when there is one): on the front of
    (seconds, ``key``) among the converged rows."""
    pts = [
        (float(r["seconds"]), float(r[key]))
        if r["converged"] and r.get(key, "") != ""
        else (math.nan, math.nan)
        for r in rows
    ]
    for row, on in zip(rows, pareto_front(pts)):
        failure = row.pop("failure", None)
        row["pareto"] = bool(on)
        if failure is not None:
            row["failure"] = failure  # keep the failure text the last column


def _chart(tmp: Path, chart: str, study: Study, rows: list[dict], level_rows: list[dict]):
    """The study's chart ``chart`` as a picture drawn by rank 0 (:mod:`contact.output.charts`)."""
    from ..output import charts, plots

    path = tmp / f"{chart}.png"

    def draw(_) -> None:
        charts.DRAW[chart](path, study, rows, level_rows)

    return plots.Picture([], draw, path, root=True)


def run_study(
    source: str | Path | Mapping | Study,
    outdir: str | Path | None = None,
    *,
    comm: MPI.Comm = MPI.COMM_WORLD,
    verbose: bool = True,
    label: str | None = None,
) -> tuple[list[dict], list[dict]]:
    """Validate and run a study (YAML path, mapping or :class:`Study`); return its rows and
    its level rows.

    Collective: call it on every rank.  With ``outdir`` the folder is written atomically
    (``contact.output.folder.atomic_folder``) with ``study.csv``, ``levels.csv``,
    ``study.json`` (the validated study) and the study's charts (``<chart>.png``, see
    :mod:`contact.output.charts`);
    with ``outdir=None`` nothing is written.  Bad input raises :class:`ConfigError` before
    any run; failing runs are rows with ``converged=False`` and a ``failure`` text.
    Progress (one line per run, with an ETA) goes to rank 0's stdout when ``verbose``."""
    from ..output import folder, plots

    study = load_study(source)
    if outdir is not None:  # refuse a folder it may not write before any run (ConfigError)
        folder.check_output(outdir, label or f"outdir {outdir}", comm)
    n = len(study.runs()) * study.repeat
    if verbose and comm.rank == 0:
        print(
            f"contact: study {study.name!r}: {n} run(s) on {study.scene}, {comm.size} MPI rank(s)",
            flush=True,
        )
    rows, level_rows = [], []
    for row, levels in iter_study(study, comm, verbose):
        rows.append(row)
        level_rows += levels
    mark_pareto(rows, study.accuracy)
    mark_pareto(level_rows, study.accuracy)
    if outdir is not None:
        with folder.atomic_folder(outdir, comm, label) as tmp:
            folder.csv_file(tmp / "study.csv", rows, comm)
            folder.csv_file(tmp / "levels.csv", level_rows, comm)
            folder.json_file(tmp / "study.json", study.as_dict(), comm)
            # the charts after the data, on rank 0 (it holds the rows alike); one that
            # fails is a warning line (contact.output.plots.draw_in_turn)
            drawn = plots.draw_in_turn(
                [_chart(tmp, chart, study, rows, level_rows) for chart in study.charts], comm
            )
        if verbose and comm.rank == 0:
            ok = sum(1 for r in rows if r["converged"])
            pictures = [name for name, outcome in drawn.items() if outcome == plots.WRITTEN]
            files = ", ".join(["study.csv", "levels.csv", "study.json", *pictures])
            print(f"contact: {ok}/{n} runs converged; wrote {outdir}/ ({files})", flush=True)
    return rows, level_rows
