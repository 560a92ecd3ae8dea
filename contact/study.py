"""Parameter studies: one scene, a cartesian product of solver / refinement settings.

A study file (``configs/studies/*.yaml``)::

    name: tiny
    scene: ../signorini_square.yaml      # relative to this file (or an inline mapping)
    set: [mesh.cells=[16,16]]            # --set-style overrides of the base scene
    axes:                                # the cartesian product is the list of runs
      method: [fb, min, vinewtonrsls]
      line_search: [basic]
    adapt: {max_levels: 6}               # options of adaptive runs (see below)
    repeat: 1                            # run every combination this many times

Axes (:data:`AXES`): ``method``, ``mu``, ``c`` (number or ``auto``), ``kappa``,
``line_search``, ``max_it``, ``u0`` (initial-guess expression) set the scene's ``solver``
keys; ``linear_solver`` is ``direct`` (the default MUMPS LU) or ``gamg`` (BiCGStab + GAMG,
``ksp_rtol`` 1e-10); ``strategy`` is ``none`` (one solve) or an adaptive marking strategy
(``uniform``, ``dorfler``, ``maximum``) with ``theta``; ``level`` refines the base mesh
uniformly that many times before solving (``contact.refine`` with every cell marked, so it
works for every mesh type, gmsh files included).  Without a ``strategy`` axis a run is
adaptive when the study's ``adapt.strategy`` or the scene's ``adapt`` section says so.

Every run is one row of ``study.csv``: the swept values, DoFs, Newton iterations (for
adaptive runs on the final level and summed over the levels), converged, the SNES reason,
the energy error (scenes with ``data.exact``), η of the final solution, the wall time and
the peak memory.  A run that raises or does not converge is a row with
``converged=False`` and the reason in ``failure``; the study goes on.

Validation uses the scene schema's machinery (:class:`contact.config.Field`), so a bad
study file fails before anything runs with one line ``<key path>: <problem>``.
"""
from __future__ import annotations

import copy
import dataclasses
import functools
import itertools
import math
import resource
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping

import numpy as np
from mpi4py import MPI

from .config import (SCENE, ConfigError, Field, _nonnegative, _positive, _typename, _validate,
                     _validate_mapping, apply_overrides, load_config, read_yaml)

LINEAR_SOLVERS: dict[str, dict] = {
    "direct": {},  # the solver's default: preonly + LU (MUMPS)
    "gamg": {"ksp_type": "bcgs", "pc_type": "gamg", "ksp_rtol": 1e-10},
}
STRATEGIES = ("none", "uniform", "dorfler", "maximum")

_SOLVER = SCENE["solver"].schema
_ADAPT = SCENE["adapt"].schema

#: axis name -> the Field each of its values is validated with
AXES: dict[str, Field] = {
    "method": _SOLVER["method"],
    "mu": _SOLVER["mu"],
    "c": _SOLVER["c"],
    "kappa": _SOLVER["kappa"],
    "line_search": _SOLVER["line_search"],
    "max_it": _SOLVER["max_it"],
    "u0": _SOLVER["u0"],
    "linear_solver": Field("str", choices=tuple(LINEAR_SOLVERS)),
    "strategy": Field("str", choices=STRATEGIES),
    "theta": _ADAPT["theta"],
    "level": Field("int", check=_nonnegative, doc="uniform refinements of the base mesh"),
}
_SOLVER_AXES = ("method", "mu", "c", "kappa", "line_search", "max_it", "u0")


def _optional(f: Field, **changes: Any) -> Field:
    return dataclasses.replace(f, default=None, **changes)


def _scene_ref(v: Any) -> str | None:
    if isinstance(v, str) and v.strip() or isinstance(v, dict):
        return None
    return f"expected a path to a scene YAML file (or a scene mapping), got {_typename(v)} {v!r}"


STUDY: dict[str, Field] = {
    "name": Field("str", None),
    "scene": Field("any", check=_scene_ref, doc="scene YAML, relative to the study file"),
    "set": Field("list", [], doc="overrides of the base scene, as contact run --set"),
    "axes": Field("any", None, doc="axis name -> list of values (validated by AXES)"),
    "adapt": Field("dict", None, schema={
        "strategy": _optional(_ADAPT["strategy"], choices=STRATEGIES),
        "theta": _optional(_ADAPT["theta"]),
        "tol": _optional(_ADAPT["tol"]),
        "max_dofs": _optional(_ADAPT["max_dofs"]),
        "max_levels": _optional(_ADAPT["max_levels"]),
        "nested": _optional(_ADAPT["nested"]),
        "newton_rtol": _optional(_ADAPT["newton_rtol"]),
    }),
    "repeat": Field("int", 1, check=_positive),
}


@dataclass
class Study:
    """A validated study: the base scene (raw mapping, ``set`` applied, validated once) and
    the axes.  ``runs()`` lists the parameter combinations (cartesian product, in the order
    of the axes as written; the last axis varies fastest)."""

    name: str
    scene: str                      # absolute path of the scene file, or "<inline>"
    set: list[str]
    axes: dict[str, list]
    adapt: dict[str, Any]           # only the keys given
    repeat: int
    base_raw: dict = field(repr=False)   # raw scene mapping with `set` applied
    base_cfg: dict = field(repr=False)   # its validated config

    @property
    def has_exact(self) -> bool:
        return bool(self.base_cfg["data"].get("exact"))

    def runs(self) -> list[dict[str, Any]]:
        names = list(self.axes)
        return [dict(zip(names, combo)) for combo in itertools.product(*(self.axes[n] for n in names))]

    @functools.cached_property
    def adaptive_possible(self) -> bool:
        """Whether any run is adaptive (then the rows get a ``stop`` column)."""
        return any(_plan(self, params)[2] is not None for params in self.runs())

    def as_dict(self) -> dict[str, Any]:
        cfg = {k: v for k, v in self.base_cfg.items() if not k.startswith("_")}
        return {"name": self.name, "scene": self.scene, "set": self.set, "axes": self.axes,
                "adapt": self.adapt, "repeat": self.repeat, "runs": len(self.runs()) * self.repeat,
                "base_scene": cfg}


def load_study(source: str | Path | Mapping | Study) -> Study:
    """Read (if a path) and validate a study; raise :class:`ConfigError` (one line) on bad
    input.  A relative ``scene`` path is taken relative to the study file (to the current
    directory for a mapping)."""
    if isinstance(source, Study):
        return source
    if isinstance(source, Mapping):
        data, base_dir, stem = dict(source), Path.cwd(), None
    else:
        path = Path(source)
        data, base_dir, stem = read_yaml(path), path.parent, path.stem
    st = _validate_mapping(data, Field("dict", schema=STUDY), "", {})

    # the base scene: read, apply `set`, make it location-independent, validate once
    ref = st["scene"]
    if isinstance(ref, dict):
        raw, scene_name, scene_dir, scene_label = copy.deepcopy(ref), None, base_dir, "<inline>"
    else:
        scene_path = Path(ref).expanduser()
        scene_path = (scene_path if scene_path.is_absolute() else Path(base_dir) / scene_path).resolve()
        if not scene_path.is_file():
            raise ConfigError(f"scene: no such file {str(scene_path)!r}")
        raw, scene_name, scene_dir, scene_label = (read_yaml(scene_path), scene_path.stem,
                                                   scene_path.parent, str(scene_path))
    for i, item in enumerate(st["set"]):
        if not isinstance(item, str) or "=" not in item:
            raise ConfigError(f"set[{i}]: expected a string KEY.PATH=VALUE, got {_typename(item)} {item!r}")
        try:
            raw = apply_overrides(raw, [item])
        except ConfigError as err:
            raise ConfigError(f"set[{i}]: {str(err).removeprefix('--set ')}") from None
    if isinstance(raw.get("mesh"), dict) and isinstance(raw["mesh"].get("file"), str):
        mesh_file = Path(raw["mesh"]["file"])
        if not mesh_file.is_absolute():
            raw["mesh"]["file"] = str((Path(scene_dir) / mesh_file).resolve())
    if not raw.get("name"):
        raw["name"] = scene_name or "scene"
    try:
        base_cfg = load_config(raw)
    except ConfigError as err:  # the key path inside the scene, after `set`
        raise ConfigError(f"scene.{err}") from None

    axes = _validate_axes(st["axes"], base_cfg["constants"])
    adapt = {k: v for k, v in st["adapt"].items() if v is not None} if st["adapt"] else {}
    return Study(name=st["name"] or stem or "study", scene=scene_label, set=list(st["set"]), axes=axes,
                 adapt=adapt, repeat=st["repeat"], base_raw=raw, base_cfg=base_cfg)


def _validate_axes(axes: Any, constants: Mapping[str, float]) -> dict[str, list]:
    if axes is None:
        return {}
    if not isinstance(axes, dict):
        raise ConfigError(f"axes: expected a mapping of axis name to a list of values, got {_typename(axes)} {axes!r}")
    out: dict[str, list] = {}
    for name, values in axes.items():
        if name not in AXES:
            raise ConfigError(f"axes.{name}: unknown axis (expected one of {', '.join(AXES)})")
        if not isinstance(values, list) or not values:
            raise ConfigError(f"axes.{name}: expected a non-empty list of values, got {_typename(values)} {values!r}")
        checked = [_validate(v, AXES[name], f"axes.{name}[{i}]", constants) for i, v in enumerate(values)]
        for i, v in enumerate(checked):
            if v in checked[:i]:
                raise ConfigError(f"axes.{name}[{i}]: {v!r} is listed twice")
        out[name] = checked
    return out


# --------------------------------------------------------------------------------- running
def _peak_rss_mib(comm: MPI.Comm) -> float:
    """Peak resident memory in MiB summed over the ranks.

    This is ``getrusage(RUSAGE_SELF).ru_maxrss``: each process's high-water mark *so far*
    (it never goes down), so a run's value includes every earlier run of the study in the
    same process; it is an upper bound for the run itself (run the study with a single
    combination, or compare along the study, to isolate one setting)."""
    kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    return round(comm.allreduce(kib, op=MPI.SUM) / 1024.0, 1)


def _refine_uniformly(scene, times: int):
    from .adapt import refine

    for _ in range(times):
        tdim = scene.mesh.topology.dim
        n_owned = scene.mesh.topology.index_map(tdim).size_local
        scene, _ = refine(scene, np.arange(n_owned, dtype=np.int32))
    return scene


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _plan(study: Study, params: Mapping[str, Any]) -> tuple[dict, int, dict | None]:
    """The run's raw scene, its number of uniform refinements and its adaptive options
    (``None``: one solve)."""
    raw = copy.deepcopy(study.base_raw)
    solver = raw["solver"] = dict(raw.get("solver") or {})
    raw["output"] = {**(raw.get("output") or {}), "verbose": False}
    for key in _SOLVER_AXES:
        if key in params:
            solver[key] = params[key]
    if "linear_solver" in params:
        solver["petsc_options"] = dict(LINEAR_SOLVERS[params["linear_solver"]])
    adapt = dict(study.adapt)
    if "theta" in params:
        adapt["theta"] = params["theta"]
    strategy = adapt.pop("strategy", None)
    strategy = params.get("strategy", strategy)
    if strategy is None:
        adaptive = study.base_cfg.get("adapt") is not None
    else:
        adaptive = strategy != "none"
        if adaptive:
            adapt["strategy"] = strategy
    return raw, params.get("level", 0), (adapt if adaptive else None)


def run_one(study: Study, params: Mapping[str, Any], comm: MPI.Comm = MPI.COMM_WORLD) -> dict[str, Any]:
    """Build the scene for ``params``, solve (or run the adaptive loop) and return the row's
    figures (without the swept values).  Never raises for a failing run.

    ``seconds`` is the wall time (maximum over ranks) of building the scene, the uniform
    refinements and the solve or the whole adaptive loop (which estimates on every level);
    for a single solve the final η / error evaluation is not included.  The first run of a
    study also pays for any JIT compilation not yet in the FFCx cache (use ``repeat: 2``).
    Under MPI a failure is caught on every rank alike as long as it is collective (bad
    options, divergence, an error raised by all ranks); an exception on one rank only would
    leave the others waiting in the next collective call, as in any MPI program."""
    from .adapt import adapt
    from .errors import energy_error
    from .estimate import estimate
    from .scene import load_scene
    from .solver import solve

    out: dict[str, Any] = {"dofs": "", "levels": "", "newton_iterations": "", "newton_iterations_total": "",
                           "converged": False, "reason": ""}
    if study.has_exact:
        out["error"] = ""
    out["eta"] = ""
    comm.barrier()
    t0 = time.perf_counter()
    failure = ""
    try:
        raw, level, adapt_opts = _plan(study, params)
        scene = load_scene(raw, comm=comm)
        scene = _refine_uniformly(scene, level)
        if adapt_opts is None:
            result = solve(scene, verbose=False)
            seconds = time.perf_counter() - t0
            out.update(dofs=result.dofs, levels=1, newton_iterations=result.iterations,
                       newton_iterations_total=result.iterations, converged=bool(result.converged),
                       reason=result.reason)
            if result.converged:
                out["eta"] = estimate(scene, result).eta
                exact = scene.cfg["data"]["exact"]
                if exact:
                    out["error"] = energy_error(result.u_h, exact, result.problem.data["k"],
                                                scene.cfg["constants"])
            else:
                failure = (f"did not converge ({result.reason}) after {result.iterations} Newton "
                           f"iterations, last |Phi| = {result.residual:.3e}")
            if study.adaptive_possible:
                out["stop"] = "single solve"
        else:
            res = adapt(scene, verbose=False, **adapt_opts)
            seconds = time.perf_counter() - t0
            last = res.levels[-1]
            its = [lv.result.iterations for lv in res.levels]
            converged = all(lv.result.converged for lv in res.levels)
            out.update(dofs=last.result.dofs, levels=len(res.levels), newton_iterations=its[-1],
                       newton_iterations_total=sum(its), converged=converged, reason=last.result.reason)
            if converged:
                out["eta"] = last.estimate.eta
                if study.has_exact and last.error is not None:
                    out["error"] = last.error
            else:
                failure = f"{res.stop}, last |Phi| = {last.result.residual:.3e}"
            out["stop"] = res.stop
    except Exception as err:  # noqa: BLE001 - any failing run is a row, never a crashed study
        seconds = time.perf_counter() - t0
        out["converged"] = False
        failure = str(err) if isinstance(err, ConfigError) else f"{type(err).__name__}: {err}"
        if study.adaptive_possible:
            out.setdefault("stop", "")
    out["seconds"] = round(comm.allreduce(seconds, op=MPI.MAX), 4)
    out["peak_rss_mib"] = _peak_rss_mib(comm)
    out["ranks"] = comm.size
    out["failure"] = _one_line(failure)
    return out


def _label(params: Mapping[str, Any]) -> str:
    return " ".join(f"{k}={v}" for k, v in params.items()) or "(base scene)"


def _duration(s: float) -> str:
    if s < 100:
        return f"{s:.2f} s" if s < 1 else f"{s:.1f} s" if s < 10 else f"{s:.0f} s"
    m, s = divmod(int(round(s)), 60)
    return f"{m} min {s:02d} s" if m < 60 else f"{m // 60} h {m % 60:02d} min"


def _progress(k: int, n: int, params: Mapping[str, Any], row: Mapping[str, Any], eta_s: float) -> str:
    if row["converged"]:
        if row.get("stop") not in (None, "single solve") and row["levels"] != "":
            what = (f"converged, {row['levels']} levels, {row['dofs']} DoFs, {row['newton_iterations']} its "
                    f"({row['newton_iterations_total']} total)")
        else:
            what = f"converged, {row['newton_iterations']} its"
    elif row["reason"]:
        what = f"FAILED ({row['reason']}), {row['newton_iterations']} its"
    else:
        what = f"FAILED: {row['failure']}"
    tail = f" (ETA {_duration(eta_s)})" if k < n else ""
    return f"[{k}/{n}] {_label(params)} → {what}, {_duration(row['seconds'])}{tail}"


def iter_study(study: Study, comm: MPI.Comm = MPI.COMM_WORLD, verbose: bool = True) -> Iterator[dict]:
    """Run the study's combinations one by one and yield each finished row."""
    combos = [(params, rep) for params in study.runs() for rep in range(1, study.repeat + 1)]
    n = len(combos)
    spent = 0.0
    for k, (params, rep) in enumerate(combos, start=1):
        t0 = time.perf_counter()
        figures = run_one(study, params, comm)
        spent += comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        row = {"run": k, **params, "repeat": rep, **figures}
        if verbose and comm.rank == 0:
            label = {**params, **({"repeat": rep} if study.repeat > 1 else {})}
            print(_progress(k, n, label, row, spent / k * (n - k)), flush=True)
        yield row


def pareto_front(points: list[tuple[float, float]], rtol: float = 1e-6) -> list[bool]:
    """For (time, error) pairs: True where no other point dominates, i.e. is at least as
    fast and at least as accurate and strictly better in one of the two.  Errors within a
    relative ``rtol`` count as equal (different solvers reach the same discrete solution up
    to round-off).  NaN / non-positive entries are never on the front."""
    ok = [math.isfinite(t) and math.isfinite(e) and t > 0 and e > 0 for t, e in points]

    def dominates(q: tuple[float, float], p: tuple[float, float]) -> bool:
        (tq, eq), (tp, ep) = q, p
        return tq <= tp and eq <= ep * (1 + rtol) and (tq < tp or eq < ep * (1 - rtol))

    return [ok[i] and not any(ok[j] and j != i and dominates(points[j], p) for j in range(len(points)))
            for i, p in enumerate(points)]


def _mark_pareto(rows: list[dict], key: str) -> None:
    pts = [(float(r["seconds"]), float(r[key])) if r["converged"] and r[key] != "" else (math.nan, math.nan)
           for r in rows]
    for row, on in zip(rows, pareto_front(pts)):
        failure = row.pop("failure")
        row["pareto"] = bool(on)
        row["failure"] = failure   # keep the failure text the last column


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def plot_speed_accuracy(path: str | Path, study: Study, rows: list[dict]) -> None:
    """Error (η without an exact solution) against wall time, log–log: one marker and
    colour per combination of the non-numeric axes (numeric axes such as ``level`` or
    ``theta`` vary along each curve), Pareto front (not dominated in both) circled and
    joined by a dashed step line.  Failed runs are left out (their count is in the title)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    key = "error" if study.has_exact else "eta"
    categorical = [a for a, vals in study.axes.items() if not all(_is_number(v) for v in vals)]
    numeric = [a for a in study.axes if a not in categorical]
    good = [r for r in rows if r["converged"] and r[key] != "" and float(r[key]) > 0 and float(r["seconds"]) > 0]
    groups: dict[tuple, list[dict]] = {}
    for r in good:
        groups.setdefault(tuple(r[a] for a in categorical), []).append(r)
    fig, ax = plt.subplots(figsize=(8, 5.5))
    markers = "osD^v<>pPX*h"
    for i, (gkey, members) in enumerate(groups.items()):
        members.sort(key=lambda r: (tuple(r[a] for a in numeric), r["seconds"]))
        t = [float(r["seconds"]) for r in members]
        e = [float(r[key]) for r in members]
        label = ", ".join(f"{a}={v}" for a, v in zip(categorical, gkey)) or "runs"
        ax.loglog(t, e, marker=markers[i % len(markers)], color=f"C{i % 10}", ls="-" if len(t) > 1 else "none",
                  lw=1, ms=6, label=label)
    front = sorted(((float(r["seconds"]), float(r[key])) for r in good if r.get("pareto")))
    if front:
        ft, fe = zip(*front)
        ax.loglog(ft, fe, "o", ms=13, mfc="none", mec="k", mew=1.2, label="Pareto front")
        ax.step(ft, fe, where="post", color="k", ls="--", lw=0.8)
    if not good:
        ax.text(0.5, 0.5, "no converged run", transform=ax.transAxes, ha="center", va="center")
    ax.set_xlabel("wall time per run [s]")
    ax.set_ylabel("energy error ‖u − u_h‖_E" if key == "error" else "estimator η")
    failed = sum(1 for r in rows if not r["converged"])
    title = f"study {study.name}: {len(rows)} runs" + (f" ({failed} failed, not shown)" if failed else "")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    if good:
        ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run_study(source: str | Path | Mapping | Study, outdir: str | Path | None = None, *,
              comm: MPI.Comm = MPI.COMM_WORLD, verbose: bool = True) -> list[dict]:
    """Validate and run a study (YAML path, mapping or :class:`Study`); return its rows.

    Collective: call it on every rank.  With ``outdir`` the folder is written atomically
    (``contact.io.atomic_folder``) with ``study.csv``, ``study.json`` (the validated study)
    and ``speed_accuracy.png``; with ``outdir=None`` nothing is written.  Bad input raises
    :class:`ConfigError` before any run; failing runs are rows with ``converged=False``
    and a ``failure`` text.  Progress (one line per run, with an ETA) goes to rank 0's
    stdout when ``verbose``."""
    from . import io

    study = load_study(source)
    n = len(study.runs()) * study.repeat
    if verbose and comm.rank == 0:
        print(f"contact: study {study.name!r}: {n} run(s) on {study.scene}, {comm.size} MPI rank(s)", flush=True)
    rows = list(iter_study(study, comm, verbose))
    _mark_pareto(rows, "error" if study.has_exact else "eta")
    if outdir is not None:
        with io.atomic_folder(outdir, comm) as tmp:
            io.write_csv(tmp / "study.csv", rows, comm)
            io.write_json(tmp / "study.json", study.as_dict(), comm)
            if comm.rank == 0:
                plot_speed_accuracy(tmp / "speed_accuracy.png", study, rows)
        if verbose and comm.rank == 0:
            ok = sum(1 for r in rows if r["converged"])
            print(f"contact: {ok}/{n} runs converged; wrote {outdir}/ (study.csv, study.json, "
                  f"speed_accuracy.png)", flush=True)
    return rows
