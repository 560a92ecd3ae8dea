"""Adaptive against uniform refinement on docs/theory.md §7 problems A and D (issue #3 figures).

What it shows, per problem, strategy and method: the energy error and the estimator η
per level, the convergence rate r in error ~ N^{-r} (least squares over the last five
levels), the effectivity η / error and its band (max / min) over those levels, Newton
iterations per level with nested iteration, and, for problem D, how many DoFs uniform and
Dörfler refinement need to reach an energy error of 1e-2.  Writes one CSV per run and a
summary CSV; prints a table.

    python demos/bench/bench_adaptive.py --out bench/adaptive        (about 3 minutes on 2 cores)
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import contact
from contact.output.folder import write_csv
from contact.setup.run import adapt

import numpy as np

RUNS = [  # (problem, scene, strategy, method, options)
    (
        "A",
        "configs/signorini_free_boundary.yaml",
        "dorfler",
        "fb",
        dict(max_levels=14, max_dofs=150_000),
    ),
    (
        "A",
        "configs/signorini_free_boundary.yaml",
        "dorfler",
        "min",
        dict(max_levels=14, max_dofs=150_000),
    ),
    (
        "A",
        "configs/signorini_free_boundary.yaml",
        "uniform",
        "min",
        dict(max_levels=6, max_dofs=600_000),
    ),
    ("D", "configs/lshape_corner.yaml", "uniform", "fb", dict(max_levels=9, max_dofs=1_000_000)),
    ("D", "configs/lshape_corner.yaml", "dorfler", "fb", dict(max_levels=30, max_dofs=300_000)),
    ("D", "configs/lshape_corner.yaml", "dorfler", "min", dict(max_levels=30, max_dofs=300_000)),
]


def rate(rows: list[dict], last: int = 5) -> float:
    """r in error ~ N^{-r}, least squares over the last ``last`` levels."""
    N = np.array([r["dofs"] for r in rows[-last:]], dtype=float)
    e = np.array([r["error"] for r in rows[-last:]], dtype=float)
    return float(-np.polyfit(np.log(N), np.log(e), 1)[0])


def dofs_to_reach(rows: list[dict], target: float) -> float:
    """DoFs at which the error first reaches ``target`` (log–log interpolation); nan if never."""
    for a, b in zip(rows, rows[1:]):
        if b["error"] <= target < a["error"]:
            t = np.log(target / a["error"]) / np.log(b["error"] / a["error"])
            return float(np.exp(np.log(a["dofs"]) + t * np.log(b["dofs"] / a["dofs"])))
    return float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", default="bench/adaptive")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary = []
    for problem, path, strategy, method, opts in RUNS:
        scene = contact.load_scene(path, ["output.verbose=false"])
        t0 = time.perf_counter()
        res = adapt(scene, method=method, strategy=strategy, verbose=False, **opts)
        wall = time.perf_counter() - t0
        rows = res.rows
        write_csv(out / f"{problem}_{strategy}_{method}.csv", rows)
        eff = np.array([r["effectivity"] for r in rows[-5:]], dtype=float)
        its = [r["newton_iterations"] for r in rows]
        row = {
            "problem": problem,
            "strategy": strategy,
            "method": method,
            "levels": len(rows),
            "final_dofs": rows[-1]["dofs"],
            "final_error": rows[-1]["error"],
            "rate_last5": round(rate(rows), 3),
            "effectivity_min": round(eff.min(), 3),
            "effectivity_max": round(eff.max(), 3),
            "effectivity_band": round(eff.max() / eff.min(), 3),
            "newton_max_after_level2": max(its[2:]) if len(its) > 2 else "",
            "newton_per_level": " ".join(map(str, its)),
            "dofs_to_error_1e-2": round(dofs_to_reach(rows, 1e-2)),
            "seconds": round(wall, 1),
        }
        summary.append(row)
        print(
            f"{problem} {strategy:8s} {method:4s} levels {row['levels']:2d}  N "
            f"{row['final_dofs']:8d}  "
            f"error {row['final_error']:.3e}  r {row['rate_last5']:.3f}  eff "
            f"[{row['effectivity_min']:.2f}, {row['effectivity_max']:.2f}] band "
            f"{row['effectivity_band']:.2f}  Newton {row['newton_per_level']}  "
            f"N(1e-2) {row['dofs_to_error_1e-2']}  {wall:.0f} s",
            flush=True,
        )
    uni = next(r for r in summary if r["problem"] == "D" and r["strategy"] == "uniform")
    dor = next(r for r in summary if r["problem"] == "D" and r["strategy"] == "dorfler")
    print(
        f"problem D: DoFs to reach energy error 1e-2: uniform {uni['dofs_to_error_1e-2']}, "
        f"Dörfler {dor['dofs_to_error_1e-2']}, ratio "
        f"{uni['dofs_to_error_1e-2'] / dor['dofs_to_error_1e-2']:.1f}"
    )
    write_csv(out / "summary.csv", summary)
    print(f"wrote {out}/summary.csv")


if __name__ == "__main__":
    main()
