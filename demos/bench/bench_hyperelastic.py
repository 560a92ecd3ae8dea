"""Finite deformation (issue 31): the energy line search on nonconvex and buckling cases, the
buckling strip against Euler, and the refinement study of the neo-Hookean cylinder.

    python demos/bench/bench_hyperelastic.py line_search   # plain Newton vs the energy search
    python demos/bench/bench_hyperelastic.py strip         # the strip's buckling load vs Euler
    python demos/bench/bench_hyperelastic.py refinement    # cylinder to 0.5 R, uniform refinement
    python demos/bench/bench_hyperelastic.py refinement --levels 5   # a level more (~110k DoFs)

``line_search`` — St Venant–Kirchhoff (SVK) bodies solved with ``line_search: basic`` (plain
Newton, MUMPS LU: the behaviour before the energy search) and ``energy`` (the default for
this model, contact/solvers/energy_search.py), fb / min / blend: the arch of
tests/test_hyperelastic.py (a curved bottom y = 0.2 x² pressed by a rising plane, its flat
top clamped) to δ = 0.1 … 0.3 of its height 0.5 in one step without step cutting, its load
path to 0.2 in 10 steps with the default cuts, the SVK block pressed to 50 % in one step,
the buckling strip (configs/hyperelastic_strip.yaml), and — where the tangent stays
definite — the neo-Hookean cylinder (configs/hyperelastic_cylinder.yaml), whose CPU time is
compared in the same process (the smaller of two runs each).  Per run: converged, the
reason, Newton iterations (all steps), the pseudo-time reached, the last solution's
smallest det F and negative eigenvalues of K_T, and the outcome: ``stable`` (det F > 0, K_T
definite), ``inverted`` (det F ≤ 0 somewhere: not a deformation), ``unstable`` (K_T
indefinite), ``stopped`` (the energy search found no admissible step), or the SNES reason.

``strip`` — the strip's critical load on P1 / P2 meshes: a load path of plain Newton along
the straight branch (t ∈ [0.97, 1.07] in steps of 0.002, in units of Euler's δ_E) and the
first step whose tangent has a negative eigenvalue: the critical load lies between it and
the step before; with the energy search, the step where it acts and the largest force.
Euler's load of a fixed–guided column (effective length L): P_E = π² E' I / L²,
E' = E / (1 − ν²) (plane strain), I = h³ / 12.

``refinement`` — configs/hyperelastic_cylinder.yaml (neo-Hookean) pressed to indentation
δ = 0.5 R in 10 steps on a uniform mesh (h = h_contact = 0.1) refined uniformly 0 … levels−1
times (``contact.refine``: new arc nodes moved onto the circle); per level the contact force
at each step, and the same discrete problem solved by PETSc's vinewtonrsls (the plane's
constraint is a bound): the largest difference of u_h (relative to max |u_h|) and of the
forces at the load steps both reach.  The observed rate of the force at δ = 0.5 R,
log₂(|F_l − F_{l−1}| / |F_{l+1} − F_l|).

Writes CSV under demos/results/hyperelastic/ (``--out``).
"""

from __future__ import annotations

import argparse
import copy
import math
import time
from pathlib import Path

import contact  # noqa: F401  (before petsc4py)
from contact.adaptivity.refine import refine
from contact.models.hyperelastic import min_det_F, negative_eigenvalues

import numpy as np
from common import save_csv
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[2]
COMM = MPI.COMM_WORLD
CYLINDER = ROOT / "configs" / "hyperelastic_cylinder.yaml"
STRIP = ROOT / "configs" / "hyperelastic_strip.yaml"
#: Euler's load of the strip: π² E/(1 − ν²) h³/12 / L² with E = 1, ν = 0.3, h = 0.05, L = 1
STRIP_EULER = math.pi**2 / (1 - 0.3**2) * 0.05**3 / 12


def say(*args) -> None:
    if COMM.rank == 0:
        print(*args, flush=True)


def arch(law: str, delta: float, steps: int, cuts: int) -> dict:
    """The arch of tests/test_hyperelastic.py (12 × 6 cells): bottom y = 0.2 x², top y = 0.5
    clamped, the plane y = δ t rising into it."""
    return {
        "name": "arch",
        "constants": {"delta": delta},
        "mesh": {
            "type": "rectangle",
            "corners": [[0, 0], [1, 0.5]],
            "cells": [12, 6],
            "map": ["x", "y + 0.2*x*x*(1 - 2*y)"],
        },
        "boundaries": {
            "axis": {"role": "symmetry", "where": "x < 1e-10"},
            "bottom": {"role": "contact", "where": "y < 0.2*x*x + 1e-10"},
            "top": {"role": "dirichlet", "where": "y > 0.5 - 1e-10"},
        },
        "model": {"type": "hyperelastic", "law": law, "E": 1.0, "nu": 0.3},
        "obstacle": {"type": "plane", "point": [0, "delta*t"], "normal": [0, 1]},
        "load": {"steps": steps, "cuts": cuts},
        "output": {"verbose": False},
    }


def block(law: str, compression: float) -> dict:
    """The quarter block of configs/hyperelastic_block.yaml (3 × 3 cells) pressed to
    ``compression`` in one step."""
    return {
        "name": "block",
        "mesh": {"type": "rectangle", "corners": [[0, 0], [1, 1]], "cells": [3, 3]},
        "boundaries": {
            "left": {"role": "symmetry", "where": "x < 1e-10"},
            "bottom": {"role": "symmetry", "where": "y < 1e-10"},
            "top": {"role": "contact", "where": "y > 1 - 1e-10"},
        },
        "model": {"type": "hyperelastic", "law": law, "E": 1.0, "nu": 0.3},
        "obstacle": {"type": "plane", "point": [0, f"1 - {compression}*t"], "normal": [0, -1]},
        "load": {"steps": 1, "cuts": 0},
        "output": {"verbose": False},
    }


def outcome(path, last) -> str:
    """The class of a load path's end (module doc)."""
    r = last.result
    if path.converged:
        if last.min_det_F is not None and last.min_det_F <= 0:
            return "inverted"
        if last.negative_eigenvalues:
            return "unstable"
        return "stable"
    if r.tangent_log and r.tangent_log[-1]["merit"] == "none":
        return "stopped"
    return r.reason


def run(case: str, source, sets: list[str], method: str, line_search: str) -> dict:
    scene = contact.load_scene(source, [*sets, "output.verbose=false"])
    t0 = time.process_time()
    path = contact.run_load_path(scene, method=method, line_search=line_search)
    cpu = COMM.allreduce(time.process_time() - t0, op=MPI.MAX)
    last = path.steps[-1]
    if last.min_det_F is None:  # a failed step: its iterate's det F and inertia
        last.min_det_F = min_det_F(last.result)
        last.negative_eigenvalues = negative_eigenvalues(last.result)
    reached = max((s.time for s in path.steps if s.result.converged), default=0.0)
    row = {
        "case": case,
        "method": method,
        "line_search": line_search,
        "converged": path.converged,
        "reason": last.result.reason,
        "newton_iterations": sum(s.result.iterations for s in path.steps),
        "max_step_iterations": max(s.result.iterations for s in path.steps),
        "steps": len(path.steps),
        "cuts": len(path.cuts),
        "reached_t": reached,
        "min_det_F": last.min_det_F,
        "negative_eigenvalues": last.negative_eigenvalues,
        "indefinite_newton_steps": sum(
            1 for s in path.steps for e in s.result.tangent_log if e["negative"]
        ),
        "curvature_steps": sum(
            1 for s in path.steps for e in s.result.tangent_log if e.get("along")
        ),
        "outcome": outcome(path, last),
        "contact_force": last.result.contact_force,
        "cpu_seconds": round(cpu, 3),
    }
    say(
        f"{case:28s} {method:6s} {line_search:7s} {row['outcome']:22s} "
        f"its {row['newton_iterations']:4d}  t {reached:.4g}  det F {row['min_det_F']:.3g}  "
        f"neg {row['negative_eigenvalues']}  F {row['contact_force']:.5g}  cpu {cpu:.2f} s"
    )
    return row


def line_search(out: Path) -> None:
    rows = []
    cases = [
        (f"SVK arch d={d}, 1 step", arch("saint_venant_kirchhoff", d, 1, 0))
        for d in (0.1, 0.16, 0.2, 0.3)
    ]
    cases.append(("SVK block 50 %, 1 step", block("saint_venant_kirchhoff", 0.5)))
    for name, cfg in cases:
        for method in ("fb", "min", "blend"):
            for ls in ("basic", "energy"):
                rows.append(run(name, copy.deepcopy(cfg), [], method, ls))
    path_cfg = arch("saint_venant_kirchhoff", 0.2, 10, 4)
    for ls in ("basic", "energy"):
        rows.append(run("SVK arch d=0.2, 10 steps", copy.deepcopy(path_cfg), [], "fb", ls))
    for ls in ("basic", "energy"):
        rows.append(run("SVK strip to 1.2 P_E", STRIP, [], "fb", ls))
    for _ in range(2):  # the definite case twice: the smaller CPU time of each counts
        for ls in ("basic", "energy"):
            rows.append(run("NH cylinder to 0.2 R", CYLINDER, [], "fb", ls))
    save_csv(out / "line_search.csv", rows)


def strip(out: Path) -> None:
    rows = []
    times = [round(t, 4) for t in np.arange(0.97, 1.0701, 0.002)]
    for cells, degree in (((40, 2), 1), ((80, 4), 1), ((160, 8), 1), ((40, 2), 2), ((80, 4), 2)):
        sets = [
            f"mesh.cells=[{cells[0]},{cells[1]}]",
            f"mesh.degree={degree}",
            "load.times=[" + ",".join(str(t) for t in times) + "]",
            "output.verbose=false",
        ]
        scene = contact.load_scene(STRIP, sets)
        t0 = time.perf_counter()
        path = contact.run_load_path(scene, line_search="basic")
        first = next((s for s in path.steps if s.negative_eigenvalues), None)
        k = path.steps.index(first) if first is not None else None
        before = path.steps[k - 1] if k else None
        row = {
            "cells": f"{cells[0]}x{cells[1]}",
            "degree": degree,
            "dofs": path.steps[-1].result.dofs,
            "t_definite": before.time if before else "",
            "t_indefinite": first.time if first else "",
            "force_definite_over_euler": before.result.contact_force / STRIP_EULER
            if before
            else "",
            "force_indefinite_over_euler": first.result.contact_force / STRIP_EULER
            if first
            else "",
            "seconds": round(time.perf_counter() - t0, 2),
        }
        rows.append(row)
        say(
            "  ".join(
                f"{k} {v:.5g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()
            )
        )
    save_csv(out / "strip.csv", rows)


def refinement(out: Path, levels: int, steps: int) -> None:
    base = [
        "mesh.h=0.1",
        "mesh.h_contact=0.1",
        "constants.delta=0.5",
        f"load.steps={steps}",
        "output.verbose=false",
    ]
    scene = contact.load_scene(CYLINDER, base)
    rows = []
    for level in range(levels):
        if level:
            n = scene.mesh.topology.index_map(scene.mesh.topology.dim).size_local
            scene, _ = refine(scene, np.arange(n, dtype=np.int32))
        paths, seconds = {}, {}
        for method in ("fb", "vinewtonrsls"):
            t0 = time.perf_counter()
            paths[method] = contact.run_load_path(scene, method=method, keep_all=True)
            seconds[method] = time.perf_counter() - t0
            if not paths[method].converged:
                raise SystemExit(
                    f"bench_hyperelastic: level {level}, {method}: {paths[method].stop}"
                )
        fb, vi = paths["fb"].steps, {round(s.time, 12): s for s in paths["vinewtonrsls"].steps}
        du = df = 0.0
        for s in fb:
            other = vi.get(round(s.time, 12))
            if other is None:
                continue
            u, v = s.result.u_h.x.array, other.result.u_h.x.array
            top = COMM.allreduce(float(np.max(np.abs(u))), op=MPI.MAX)
            du = max(du, COMM.allreduce(float(np.max(np.abs(u - v))), op=MPI.MAX) / top)
            df = max(df, abs(s.result.contact_force / other.result.contact_force - 1))
        for s in fb:
            rows.append(
                {
                    "level": level,
                    "dofs": s.result.dofs,
                    "step": s.index,
                    "indentation": 0.5 * s.time,
                    "contact_force": s.result.contact_force,
                    "newton_iterations": s.result.iterations,
                    "negative_eigenvalues": s.negative_eigenvalues,
                    "vi_u_difference": du,
                    "vi_force_difference": df,
                    "seconds_fb": round(seconds["fb"], 2),
                    "seconds_vinewtonrsls": round(seconds["vinewtonrsls"], 2),
                    "vi_steps": len(paths["vinewtonrsls"].steps),
                }
            )
        last = fb[-1].result
        say(
            f"level {level}: {last.dofs} DoFs, F(0.5 R) = {last.contact_force:.10g}, "
            f"Newton {[s.result.iterations for s in fb]}, vinewtonrsls: |du|/|u| {du:.1e}, "
            f"force {df:.1e} ({len(paths['vinewtonrsls'].steps)} steps), "
            f"{seconds['fb']:.1f} s / {seconds['vinewtonrsls']:.1f} s"
        )
        for p in paths.values():
            for s in p.steps:
                s.release()
    force = [r["contact_force"] for r in rows if r["step"] == steps]
    diffs = np.abs(np.diff(force))
    rates = np.log2(diffs[:-1] / diffs[1:]) if len(diffs) > 1 else []
    say("observed rates of F(0.5 R):", " ".join(f"{r:.2f}" for r in rates))
    save_csv(out / "refinement.csv", rows)
    if COMM.rank == 0:
        chart_refinement(out / "refinement.png", rows)


def chart_refinement(path: Path, rows: list[dict]) -> None:
    """Left: force–indentation per level; right: |F_l − F_{l−1}| at δ = 0.5 R against the
    DoFs of level l, with a slope of h² (N⁻¹) for reference."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.8))
    levels = sorted({r["level"] for r in rows})
    last = []
    for level in levels:
        lv = [r for r in rows if r["level"] == level]
        x = [0.0] + [r["indentation"] for r in lv]
        left.plot(
            x,
            [0.0] + [r["contact_force"] for r in lv],
            "o-",
            ms=3,
            label=f"level {level}: {lv[0]['dofs']} DoFs",
        )
        last.append((lv[0]["dofs"], lv[-1]["contact_force"]))
    left.set_xlabel("indentation δ / R")
    left.set_ylabel("contact force (quarter model, per unit depth)")
    left.grid(alpha=0.3)
    left.legend(fontsize=8)
    left.set_title("neo-Hookean cylinder on a rigid plane")
    N = np.array([d for d, _ in last[1:]], dtype=float)
    diff = np.abs(np.diff([f for _, f in last]))
    right.loglog(N, diff, "o-", label="|F_l − F_{l−1}| at δ = 0.5 R")
    if len(N):
        right.loglog(N, diff[0] * (N / N[0]) ** -1.0, "k--", lw=1, label="N⁻¹ (h²)")
        right.loglog(N, diff[0] * (N / N[0]) ** -0.5, "k:", lw=1, label="N⁻¹ᐟ² (h)")
    right.set_xlabel("DoFs N of level l")
    right.grid(True, which="both", alpha=0.3)
    right.legend(fontsize=8)
    right.set_title("uniform refinement: change of the force at 0.5 R")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("part", choices=("line_search", "strip", "refinement"))
    ap.add_argument("--out", type=Path, default=ROOT / "demos" / "results" / "hyperelastic")
    ap.add_argument("--levels", type=int, default=4, help="refinement: mesh levels")
    ap.add_argument("--steps", type=int, default=10, help="refinement: load steps to 0.5 R")
    args = ap.parse_args()
    if args.part == "line_search":
        line_search(args.out)
    elif args.part == "strip":
        strip(args.out)
    else:
        refinement(args.out, args.levels, args.steps)


if __name__ == "__main__":
    main()
