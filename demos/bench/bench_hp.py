"""hp against h-adaptive P1 and P2 on problems C and A (docs/theory.md §7, §11).

What it shows, per problem and method: the energy error and η per level against the
unknowns N (hp: the unknowns of V_hp, h: the DoFs), the cumulative wall seconds of SOLVE,
ESTIMATE, MARK and REFINE (the error's own computation excluded) and the process's CPU
seconds when the level is estimated (less disturbed by other jobs on a shared machine);
per run, the first level whose error is ≤ the problem's target, its N and seconds, and the
ratios to h-P2 measured in the same process (each method first runs two untimed levels, so
that no run pays for loading or compiling its forms); for hp, the least-squares fit
log(error) ≈ c − b N^{1/3} over the levels past the third, with its r², and η / error on
every level.  Writes levels.csv and summary.csv; prints a table.

    python demos/bench/bench_hp.py --out demos/results/hp          (about 2 minutes on 2 cores)
    python demos/bench/bench_hp.py --p-robust --out demos/results/hp   (η / error against p_max)
    python demos/bench/bench_hp.py --hertz --out demos/results/hp      (Hertz 2D, elastic)
    python demos/bench/bench_hp.py --three-d 6 --out demos/results/hp  (3D problem C, 6 levels)
    python demos/bench/bench_hp.py --profile A [--space-degree p_max]  (where a level's CPU goes)

``--three-d``: problem C extruded to the unit cube (u = −(x − ½)₊³ + z², Γ_C = {z = 0},
u_D = u on the other faces), hp with p_max 3 from the 4 × 4 × 4 box: per level N, the error, η
and η / error (three_d.csv), the guaranteed bound in 3D.

``--hertz``: the elastic Hertz scene (configs/hertz_2d.yaml) with the h loop (P1, the
scene's Dörfler θ) and the hp loop (residual estimator with h/p weights), per level the
contact half-width a and peak pressure p0 against Hertz theory; per method the first level
with |a/a_H − 1| and |p0/p0_H − 1| both ≤ 0.5 %, its unknowns and CPU seconds, and the
ratios to P1 measured in the same process (hertz_levels.csv, hertz_summary.csv).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import contact
from contact.hp.adapt import adapt_hp
from contact.output.folder import write_csv

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
#: (problem, scene, the target energy error, h-P1's DoF budget, h-P2's DoF budget): P2 reaches
#: C's 1e-6 at about 4e5 DoFs (error ≈ N^−1), P1 (error ≈ N^−1/2) would need about 1e12
PROBLEMS = [
    ("C", "configs/signorini_smooth.yaml", 1e-6, 40_000, 1_000_000),
    ("A", "configs/signorini_free_boundary.yaml", 1e-4, 60_000, 60_000),
]
#: (method, scene overrides, adapt options)
METHODS = [
    ("hp", [], dict(strategy="hp", p_max=6, p_start=1, max_levels=60)),
    ("hp-start2", [], dict(strategy="hp", p_max=6, p_start=2, max_levels=60)),
    ("hp-theta0.7", [], dict(strategy="hp", p_max=6, p_start=1, theta=0.7, max_levels=60)),
    ("hp-theta0.85", [], dict(strategy="hp", p_max=6, p_start=1, theta=0.85, max_levels=60)),
    ("hp-theta0.9", [], dict(strategy="hp", p_max=6, p_start=1, theta=0.9, max_levels=60)),
    # the former path: every level assembles, solves and estimates in P_{p_max}, not in
    # P_{max p_T}
    (
        "hp-theta0.85-pmax-space",
        [],
        dict(strategy="hp", p_max=6, p_start=1, theta=0.85, max_levels=60, space_degree="p_max"),
    ),
    ("h-P2", ["mesh.degree=2"], dict(strategy="dorfler", max_levels=40)),
    ("h-P1", [], dict(strategy="dorfler", max_levels=40)),
]
TIMED = ("assembly", "solve", "estimate", "mark", "refine")


def run(problem: str, path: str, target: float, budget: int, method: str, sets, options):
    scene = contact.load_scene(
        ROOT / path, [*sets, "output.verbose=false", "estimator=equilibrated"]
    )
    cpu: list[float] = []  # the process's CPU seconds when each level is estimated
    start = time.process_time()
    on_level = lambda lv: cpu.append(time.process_time() - start)  # noqa: E731
    if "space_degree" in options:  # not a scene key: the hp loop itself
        hp = {k: v for k, v in options.items() if k != "strategy"}
        out = adapt_hp(scene, tol=target, max_dofs=200_000, on_level=on_level, **hp)
    else:
        out = contact.adapt(
            scene,
            tol=target,
            max_dofs=200_000 if method.startswith("hp") else budget,
            on_level=on_level,
            **options,
        )
    rows, seconds = [], 0.0
    for lv, cpu_seconds in zip(out.levels, cpu):
        seconds += sum(lv.seconds.get(k, 0.0) for k in TIMED)
        row = lv.row()
        rows.append(
            {
                "problem": problem,
                "method": method,
                "level": lv.index,
                "unknowns": row["dofs"],
                "error": lv.error,
                "eta": lv.estimate.eta,
                "effectivity": lv.estimate.eta / lv.error,
                "seconds": seconds,
                "cpu_seconds": cpu_seconds,
                "p_max": row.get("p_max", 2 if method == "h-P2" else 1),
                "p_min": row.get("p_min", 2 if method == "h-P2" else 1),
            }
        )
    return rows, out.stop


def first_below(rows: list[dict], target: float) -> dict | None:
    return next((r for r in rows if r["error"] <= target), None)


def exponential_fit(rows: list[dict]) -> tuple[float, float]:
    """(b, r²) of log(error) ≈ c − b N^{1/3} over the levels past the third."""
    x = np.array([r["unknowns"] ** (1 / 3) for r in rows[3:]])
    y = np.log([r["error"] for r in rows[3:]])
    A = np.vstack([np.ones_like(x), x]).T
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    resid = y - A @ coef
    r2 = 1 - float(resid @ resid) / float(((y - y.mean()) ** 2).sum())
    return -float(coef[1]), r2


#: the largest degrees of the p-robustness runs, and their targets (the energy error)
P_MAXES = (2, 3, 4, 6)
P_ROBUST_TARGETS = {"C": 1e-4, "A": 1e-3}


def p_robust(out: Path, problems: list[str]) -> None:
    """η / error of the hp bound against p_max: per problem and p_max the largest and the
    median effectivity past level 3 of a run to :data:`P_ROBUST_TARGETS` (p_robust.csv)."""
    found = []
    for problem, path, *_ in PROBLEMS:
        if problem not in problems:
            continue
        for p_max in P_MAXES:
            options = dict(strategy="hp", p_max=p_max, p_start=1, max_levels=60)
            rows, stop = run(problem, path, P_ROBUST_TARGETS[problem], 30_000, "hp", [], options)
            eff = [r["effectivity"] for r in rows[3:]]
            found.append(
                {
                    "problem": problem,
                    "p_max": p_max,
                    "levels": len(rows),
                    "unknowns": rows[-1]["unknowns"],
                    "error": rows[-1]["error"],
                    "effectivity_max_past_3": max(eff),
                    "effectivity_median_past_3": float(np.median(eff)),
                    "bound_holds": all(r["eta"] >= r["error"] for r in rows),
                    "stop": stop,
                }
            )
            r = found[-1]
            print(
                f"{problem} p_max {p_max}: {r['levels']} levels, N {r['unknowns']}, error "
                f"{r['error']:.2e}, eta/error past level 3 max {r['effectivity_max_past_3']:.3f} "
                f"median {r['effectivity_median_past_3']:.3f}, bound {r['bound_holds']}"
            )
    write_csv(out / "p_robust.csv", found)


#: the Hertz runs: (method, adapt options); the target |error| of a and p0
HERTZ = "configs/hertz_2d.yaml"
HERTZ_METHODS = [
    ("h-P1", dict(strategy="dorfler", max_levels=12, max_dofs=120_000)),
    ("hp-p4", dict(strategy="hp", p_max=4, max_levels=14, max_dofs=120_000)),
    ("hp-p6", dict(strategy="hp", p_max=6, max_levels=14, max_dofs=120_000)),
]
HERTZ_TARGET = 5e-3


def hertz_run(method: str, options: dict) -> list[dict]:
    """The levels of one Hertz run: unknowns, η, a and p0 against Hertz, and the process's
    CPU seconds when the level is estimated (the comparisons' own seconds excluded)."""
    from contact.post.hertz import compare

    scene = contact.load_scene(ROOT / HERTZ, ["output.verbose=false"])
    rows: list[dict] = []
    start, excluded = time.process_time(), [0.0]

    def on_level(lv) -> None:
        now = time.process_time()
        found = compare(lv.posed, lv.result, lv.scene.config.reference)
        row = lv.row()
        rows.append(
            {
                "method": method,
                "level": lv.index,
                "unknowns": row["dofs"],
                "cells": row["cells"],
                "p_max": row.get("p_max", 1),
                "eta": lv.estimate.eta,
                "a_error": float(found.errors["a_error"]),
                "p0_error": float(found.errors["p0_error"]),
                "cpu_seconds": now - start - excluded[0],
            }
        )
        excluded[0] += time.process_time() - now

    contact.adapt(scene, on_level=on_level, **options)
    return rows


def hertz(out: Path) -> None:
    """Hertz 2D: hp against h-adaptive P1 (module docstring)."""
    for method, options in HERTZ_METHODS:  # forms compiled before any timing
        hertz_run(method, {**options, "max_levels": 2})
    levels, summary = [], []
    for method, options in HERTZ_METHODS:
        rows = hertz_run(method, options)
        levels += rows
        hit = next(
            (
                r
                for r in rows
                if abs(r["a_error"]) <= HERTZ_TARGET and abs(r["p0_error"]) <= HERTZ_TARGET
            ),
            None,
        )
        last = rows[-1]
        summary.append(
            {
                "method": method,
                "target": HERTZ_TARGET,
                "reached": hit is not None,
                "level": (hit or last)["level"],
                "unknowns": (hit or last)["unknowns"],
                "a_error": (hit or last)["a_error"],
                "p0_error": (hit or last)["p0_error"],
                "cpu_seconds": (hit or last)["cpu_seconds"],
                "levels": len(rows),
            }
        )
    p1 = summary[0]
    for entry in summary:
        entry["unknowns_ratio_P1"] = p1["unknowns"] / entry["unknowns"]
        entry["cpu_ratio_P1"] = p1["cpu_seconds"] / entry["cpu_seconds"]
    write_csv(out / "hertz_levels.csv", levels)
    write_csv(out / "hertz_summary.csv", summary)
    print(f"{'method':8}{'level':>6}{'N':>8}{'a err %':>9}{'p0 err %':>9}{'cpu':>8}  (per level)")
    for r in levels:
        print(
            f"{r['method']:8}{r['level']:6d}{r['unknowns']:8d}{100 * r['a_error']:+9.3f}"
            f"{100 * r['p0_error']:+9.3f}{r['cpu_seconds']:8.2f}"
        )
    print(f"first level with |a|, |p0| errors <= {100 * HERTZ_TARGET:g} %:")
    for e in summary:
        print(
            f"{e['method']:8} reached {e['reached']!s:5} level {e['level']:3d} N {e['unknowns']:7d}"
            f" a {100 * e['a_error']:+.3f} % p0 {100 * e['p0_error']:+.3f} % cpu "
            f"{e['cpu_seconds']:.2f}  N(P1)/N {e['unknowns_ratio_P1']:.2f}"
            f"  cpu(P1)/cpu {e['cpu_ratio_P1']:.2f}"
        )


#: problem C in the unit cube (module docstring)
CUBE = {
    "name": "signorini_smooth_3d",
    "mesh": {"type": "box", "corners": [[0, 0, 0], [1, 1, 1]], "cells": [4, 4, 4]},
    "boundaries": {
        "contact": {"role": "contact", "where": "z < 1e-10"},
        # one part per face: a facet of a face has all its vertices on it, and on no other
        **{
            name: {"role": "dirichlet", "where": where}
            for name, where in (
                ("x0", "x < 1e-10"),
                ("x1", "x > 1 - 1e-10"),
                ("y0", "y < 1e-10"),
                ("y1", "y > 1 - 1e-10"),
                ("top", "z > 1 - 1e-10"),
            )
        },
    },
    "model": "signorini",
    "data": {
        "f": "6*max(x - 0.5, 0) - 2",
        "g": "0",
        "t_C": "max(0.5 - x, 0)**2",
        "u_D": "-max(x - 0.5, 0)**3 + z**2",
        "exact": "-max(x - 0.5, 0)**3 + z**2",
    },
    "solver": {"method": "fb"},
    "output": {"verbose": False},
}


def three_d(out: Path, levels: int) -> None:
    """The hp loop on problem C in 3D (module docstring)."""
    scene = contact.load_scene(CUBE)
    rows = []
    start = time.process_time()

    def on_level(lv) -> None:
        row = lv.row()
        rows.append(
            {
                "level": lv.index,
                "unknowns": row["dofs"],
                "cells": row["cells"],
                "p_min": row["p_min"],
                "p_max": row["p_max"],
                "error": lv.error,
                "eta": lv.estimate.eta,
                "effectivity": lv.estimate.eta / lv.error,
                "cpu_seconds": time.process_time() - start,
            }
        )
        r = rows[-1]
        print(
            f"{r['level']:3d} N {r['unknowns']:7d} cells {r['cells']:7d} p {r['p_min']}-"
            f"{r['p_max']} error {r['error']:.3e} eta {r['eta']:.3e} eta/error "
            f"{r['effectivity']:.3f} cpu {r['cpu_seconds']:.1f}",
            flush=True,
        )

    run = contact.adapt(scene, strategy="hp", p_max=3, max_levels=levels, on_level=on_level)
    write_csv(out / "three_d.csv", rows)
    print(run.stop, "| eta >= error on every level:", all(r["eta"] >= r["error"] for r in rows))


#: the parts of an hp level the profile reports: (label, module path, function name)
PROFILED = [
    ("V_hp and its basis (HPSpace)", "contact/hp/space.py", "__init__"),
    ("Q and L", "contact/hp/space.py", "matrices"),
    ("assembly in P_q + QᵀKQ", "contact/hp/problem.py", "reduce_system"),
    ("hp problem (all of it)", "contact/hp/problem.py", "hp_problem"),
    ("solve (Newton, MUMPS)", "contact/setup/run.py", "solve"),
    ("estimate (the bound)", "contact/hp/bound.py", "hp_bound"),
    ("error (exact solution)", "contact/adaptivity/energy_error.py", "solution_error"),
    ("smoothness (decay rates)", "contact/hp/mark.py", "decay_rates"),
    ("free boundary cells", "contact/hp/mark.py", "front_cells"),
    ("refine + transfer", "contact/setup/run.py", "refine"),
    ("degree transfer", "contact/hp/mark.py", "child_degrees"),
    ("u_0 raised to the new degree", "contact/hp/adapt.py", "_raised"),
    ("form/expression JIT look-ups", "dolfinx/jit.py", "ffcx_jit"),
]


def profile(problem: str, space_degree: str) -> None:
    """cProfile (CPU seconds) of the hp loop with its default θ on one problem: the
    cumulative seconds of the parts of a level (:data:`PROFILED`) over the run."""
    import cProfile
    import pstats

    from contact.hp.adapt import HP_THETA

    _, path, target, *_ = next(p for p in PROBLEMS if p[0] == problem)

    def go(levels: int):
        scene = contact.load_scene(ROOT / path, ["output.verbose=false"])
        return adapt_hp(
            scene,
            p_max=6,
            theta=HP_THETA,
            tol=target,
            max_levels=levels,
            space_degree=space_degree,
        )

    go(2)  # the forms compiled
    prof = cProfile.Profile(time.process_time)
    start = time.process_time()
    prof.enable()
    out = go(60)
    prof.disable()
    total = time.process_time() - start
    stats = pstats.Stats(prof).stats  # type: ignore[attr-defined]
    print(
        f"problem {problem}, space {space_degree}: {len(out.levels)} levels, "
        f"{total:.2f} CPU s profiled"
    )
    for label, module, name in PROFILED:
        cum = sum(v[3] for k, v in stats.items() if k[0].endswith(module) and k[2] == name)
        print(f"  {label:32} {cum:7.3f} s  {100 * cum / total:5.1f} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="demos/results/hp")
    parser.add_argument("--problems", default="C,A")
    parser.add_argument(
        "--p-robust",
        action="store_true",
        help="only the effectivity of the bound against p_max (p_robust.csv)",
    )
    parser.add_argument(
        "--hertz", action="store_true", help="only Hertz 2D: hp against h-adaptive P1"
    )
    parser.add_argument(
        "--methods", default="", help="comma-separated subset of the methods (default: all)"
    )
    parser.add_argument("--three-d", type=int, default=0, metavar="LEVELS", help="3D problem C")
    parser.add_argument(
        "--profile",
        default="",
        metavar="PROBLEM",
        help="only a CPU profile of the hp loop on problem C or A (with --space-degree)",
    )
    parser.add_argument("--space-degree", default="used", choices=("used", "p_max"))
    args = parser.parse_args()
    if args.profile:
        profile(args.profile, args.space_degree)
        return
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.three_d:
        three_d(out, args.three_d)
        return
    if args.hertz:
        hertz(out)
        return
    if args.p_robust:
        p_robust(out, args.problems.split(","))
        return
    methods = [m for m in METHODS if not args.methods or m[0] in args.methods.split(",")]
    levels, summary = [], []
    for problem, path, target, p1_budget, p2_budget in PROBLEMS:
        if problem not in args.problems.split(","):
            continue
        reached = {}
        for method, sets, options in methods:  # the compiled forms loaded before any timing
            run(problem, path, target, p1_budget, method, sets, {**options, "max_levels": 2})
        for method, sets, options in methods:
            budget = p2_budget if method == "h-P2" else p1_budget
            rows, stop = run(problem, path, target, budget, method, sets, options)
            levels += rows
            hit = first_below(rows, target)
            last = rows[-1]
            entry = {
                "problem": problem,
                "method": method,
                "target": target,
                "reached": hit is not None,
                "unknowns": (hit or last)["unknowns"],
                "seconds": (hit or last)["seconds"],
                "cpu_seconds": (hit or last)["cpu_seconds"],
                "error": (hit or last)["error"],
                "levels": len(rows),
                "effectivity_min": min(r["effectivity"] for r in rows),
                "effectivity_max_past_3": max(
                    (r["effectivity"] for r in rows[3:]), default=math.nan
                ),
                "bound_holds": all(r["eta"] >= r["error"] for r in rows),
                "stop": stop,
                "exp_rate_b": "",
                "exp_fit_r2": "",
            }
            if method.startswith("hp") and len(rows) > 5:
                entry["exp_rate_b"], entry["exp_fit_r2"] = exponential_fit(rows)
            reached[method] = entry
            summary.append(entry)
        p2 = reached["h-P2"]
        for entry in reached.values():
            # h-P2 short of the target: its last level's N and seconds bound the need below
            entry["unknowns_ratio_P2"] = p2["unknowns"] / entry["unknowns"]
            entry["seconds_ratio_P2"] = p2["seconds"] / entry["seconds"]
            entry["cpu_ratio_P2"] = p2["cpu_seconds"] / entry["cpu_seconds"]
    write_csv(out / "levels.csv", levels)
    write_csv(out / "summary.csv", summary)
    print(
        f"{'problem':8}{'method':12}{'target':>8}{'reached':>8}{'N':>8}{'error':>11}{'s':>8}"
        f"{'cpu':>8}{'P2 N/N':>8}{'P2 s/s':>8}{'P2 cpu':>8}{'eff max':>8}  bound"
    )
    for e in summary:
        print(
            f"{e['problem']:8}{e['method']:12}{e['target']:8.0e}{str(e['reached']):>8}"
            f"{e['unknowns']:8d}{e['error']:11.3e}{e['seconds']:8.2f}{e['cpu_seconds']:8.2f}"
            f"{e['unknowns_ratio_P2']:8.1f}{e['seconds_ratio_P2']:8.2f}{e['cpu_ratio_P2']:8.2f}"
            f"{e['effectivity_max_past_3']:8.2f}  {e['bound_holds']}"
        )
        if e["exp_rate_b"] != "":
            print(
                f"        hp: log(error) ~ c - {e['exp_rate_b']:.3f} N^(1/3),"
                f" r^2 = {e['exp_fit_r2']:.3f}"
            )


if __name__ == "__main__":
    main()
