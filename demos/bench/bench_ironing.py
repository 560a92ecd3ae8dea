"""Benchmark: the ironing problem in plane strain (configs/hyperelastic_ironing_2d.yaml) —
a rigid circular die pressed into a neo-Hookean block and dragged across it with Coulomb
friction, on three meshes (h halved twice), the force curves of all on one chart.

The scene is the ironing benchmark (Puso & Laursen 2004; Yang & Laursen 2005) in a
plane-strain section, with the parameters of Puso & Laursen's 3D problem: block 9 × 4
(E = 1, ν = 0.3, neo-Hookean, clamped at its bottom), die radius 3, its lowest point at 2.5
from the block's left end, pressed in by 1.4 (t ≤ 0.2) and then dragged by 4 (t ≤ 1),
Coulomb coefficient μ = 0.3.  The published die
is a stiff elastic body (E = 1000) and the published runs are 3D; here the die is rigid
and the section 2D, so the forces are per unit thickness and not the published numbers.

Each mesh runs through ``contact run`` (the path users take) and its steps.csv is read
back.  Per step ``ironing.csv`` has the die's forces — the drag force F_x (the contact
force on the block along the sliding direction) and the press force F_y (its downward
component), which the block's clamped bottom balances (``balance``: |contact force +
support reaction| relative to |contact force|) —, the contact-surface resultants
F_n = Σ w |λ_n| and F_t = Σ w |λ_t| with their ratio (= μ where every pressed node slips,
the steady sliding state), F_x split into its friction part (Σ w λ_t along x) and its
pressure part (Σ w λ_n n_x: the die's leading side pressing harder than its trailing side),
the Newton iterations and the run's wall seconds.
``ironing_meshes.csv`` (printed): per mesh the steady sliding steps, the largest
|F_t/F_n − μ| / μ there, F_x / F_y there, the die's forces at the sliding distance 2 and
their relative difference to the next finer mesh (and the largest over the sliding steps),
with the observed order of that difference.

    python demos/bench/bench_ironing.py --out demos/results/hyperelastic    # 2–5 minutes
    python demos/bench/bench_ironing.py --cells 36 16 --cells 72 32 --ranks 2

Writes ``ironing.csv``, ``ironing_meshes.csv`` and ``ironing.png`` (the die's forces and
the force ratios against the sliding distance, every mesh) into ``--out``.
"""

from __future__ import annotations

import argparse
import csv
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from common import save_csv

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "configs" / "hyperelastic_ironing_2d.yaml"
BIN = Path(sys.executable).parent
MU = 0.3  # the scene's friction.coefficient


def run(cells: list[int], steps: int, ranks: int, folder: Path) -> tuple[list[dict], float]:
    """The scene on ``cells`` through the CLI: (its steps.csv rows as floats, wall seconds)."""
    command = [
        str(BIN / "contact"),
        "run",
        "-q",
        str(SCENE),
        "-o",
        str(folder),
        "--set",
        f"mesh.cells=[{cells[0]},{cells[1]}]",
        "--set",
        f"load.steps={steps}",
        "--set",
        "output.formats=[]",
        "--set",
        "output.png=false",
    ]
    if ranks > 1:
        command = [str(BIN / "mpirun"), "-n", str(ranks), *command]
    t0 = time.perf_counter()
    subprocess.run(command, check=True)
    seconds = time.perf_counter() - t0
    with open(folder / "steps.csv", newline="") as f:
        rows = [
            {k: float(v) if k not in ("reason", "converged") else v for k, v in r.items() if v}
            for r in csv.DictReader(f)
        ]
    return rows, seconds


def figures(rows: list[dict], cells: list[int], seconds: float) -> list[dict]:
    """The benchmark's row per step (module doc)."""
    out = []
    for r in rows:
        contact = np.array([r["contact_force_x"], r["contact_force_y"]])
        reaction = np.array([r["reaction_force_x"], r["reaction_force_y"]])
        sliding = r["time"] > 0.2 + 1e-12
        out.append(
            {
                "cells": f"{cells[0]}x{cells[1]}",
                "dofs": int(r["dofs"]),
                "step": int(r["step"]),
                "time": r["time"],
                "sliding_distance": r["obstacle_translation_x"],
                "depth": -r["obstacle_translation_y"],
                "drag_force_x": contact[0],
                "press_force_y": -contact[1],
                "drag_by_friction": r["tangential_force_x"],
                "drag_by_pressure": contact[0] - r["tangential_force_x"],
                "F_n": abs(r["normal_force"]),
                "F_t": r["surface_friction_force"],
                "F_t_over_F_n": r["surface_friction_ratio"],
                "F_x_over_F_y": -contact[0] / contact[1],
                "steady_sliding": bool(sliding and r["stick_nodes"] == 0 and r["slip_nodes"] > 0),
                "balance": float(np.linalg.norm(contact + reaction) / np.linalg.norm(contact)),
                "newton_iterations": int(r["newton_iterations"]),
                "run_seconds": round(seconds, 1),
            }
        )
    return out


def chart(path: Path, meshes: dict[str, list[dict]]) -> None:
    """ironing.png: the die's forces and the force ratios against the sliding distance."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    styles = ("-", "--", ":", "-.")
    for (name, rows), style in zip(meshes.items(), styles):
        rows = [r for r in rows if r["time"] >= 0.2 - 1e-12]  # the end of the press, then sliding
        s = [r["sliding_distance"] for r in rows]
        label = f"{name} ({rows[0]['dofs']} DoFs)"
        ax.plot(s, [r["press_force_y"] for r in rows], "C0" + style, label=f"press F_y, {label}")
        ax.plot(s, [r["drag_force_x"] for r in rows], "C1" + style, label=f"drag F_x, {label}")
        bx.plot(s, [r["F_t_over_F_n"] for r in rows], "C2" + style, label=f"F_t / F_n, {label}")
        bx.plot(s, [r["F_x_over_F_y"] for r in rows], "C3" + style, label=f"F_x / F_y, {label}")
    bx.axhline(MU, color="k", lw=0.8, label=f"μ = {MU}")
    ax.set(xlabel="sliding distance of the die", ylabel="force per unit thickness")
    bx.set(xlabel="sliding distance of the die", ylabel="ratio")
    ax.set_title("die forces (contact force on the block)")
    bx.set_title("surface resultants F_t / F_n and die forces F_x / F_y")
    for a in (ax, bx):
        a.grid(alpha=0.3)
        a.legend(fontsize=7)
    fig.suptitle("ironing, plane strain: rigid die R = 3 pressed 1.4 into a neo-Hookean block")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}", flush=True)


#: the sliding distance at which the meshes' forces are compared (mid-path, steady sliding)
COMPARE_AT = 2.0


def summary(meshes: dict[str, list[dict]]) -> list[dict]:
    """One row per mesh: the steady sliding steps, the largest |F_t/F_n − μ| / μ there, the
    range of F_x / F_y there, the worst balance, the mean Newton iterations per step, the
    wall seconds, the die's forces at the sliding distance :data:`COMPARE_AT` and their
    relative difference to the next finer mesh (and the largest one over the sliding steps),
    with the observed order of that difference under halving h where there are three."""
    out = []
    for name, rows in meshes.items():
        steady = [r for r in rows if r["steady_sliding"]]
        at = min(rows, key=lambda r: abs(r["sliding_distance"] - COMPARE_AT))
        ratio = [r["F_x_over_F_y"] for r in steady] or [float("nan")]
        out.append(
            {
                "cells": name,
                "dofs": rows[0]["dofs"],
                "steady_steps": len(steady),
                "max_rel_dev_Ft_Fn": max(
                    (abs(r["F_t_over_F_n"] - MU) / MU for r in steady), default=float("nan")
                ),
                "min_Fx_over_Fy": min(ratio),
                "max_Fx_over_Fy": max(ratio),
                "max_balance": max(r["balance"] for r in rows),
                "newton_per_step": round(float(np.mean([r["newton_iterations"] for r in rows])), 2),
                "run_seconds": rows[0]["run_seconds"],
                "press_force_y_at_2": at["press_force_y"],
                "drag_force_x_at_2": at["drag_force_x"],
                "drag_by_pressure_at_2": at["drag_by_pressure"],
            }
        )
    for coarse, fine, (a, b) in zip(out, out[1:], zip(meshes.values(), list(meshes.values())[1:])):
        pairs = [(p, q) for p, q in zip(a, b) if p["time"] > 0.2 + 1e-12]
        for key in ("press_force_y", "drag_force_x"):
            coarse[f"{key}_diff_at_2"] = abs(coarse[f"{key}_at_2"] / fine[f"{key}_at_2"] - 1)
            coarse[f"{key}_max_diff"] = max(abs(p[key] / q[key] - 1) for p, q in pairs)
    for coarse, middle in zip(out, out[1:]):
        for key in ("press_force_y_diff_at_2", "drag_force_x_diff_at_2"):
            if key in middle:
                coarse[key.replace("diff_at_2", "order")] = float(
                    np.log2(coarse[key] / middle[key])
                )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cells", nargs=2, type=int, action="append", metavar=("NX", "NY"))
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--ranks", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("bench/ironing"))
    args = parser.parse_args()
    meshes: dict[str, list[dict]] = {}
    tmp = Path(tempfile.mkdtemp(prefix="ironing-"))
    try:
        for cells in args.cells or [[36, 16], [72, 32], [144, 64]]:
            rows, seconds = run(cells, args.steps, args.ranks, tmp / f"{cells[0]}x{cells[1]}")
            meshes[f"{cells[0]}x{cells[1]}"] = figures(rows, cells, seconds)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    table = summary(meshes)
    print(
        f"{'mesh':>8} {'DoFs':>6} {'steady':>6} {'|Ft/Fn-mu|/mu':>13} {'Fx/Fy steady':>15} "
        f"{'balance':>8} {'Newton':>6} {'wall s':>7} {'F_y(s=2)':>9} {'dF_y':>8} {'F_x(s=2)':>9} "
        f"{'dF_x':>8} {'max dF_y':>8} {'max dF_x':>8}"
    )
    for r in table:
        print(
            f"{r['cells']:>8} {r['dofs']:>6} {r['steady_steps']:>6} "
            f"{r['max_rel_dev_Ft_Fn']:>13.2e} "
            f"{r['min_Fx_over_Fy']:>7.4f}–{r['max_Fx_over_Fy']:<7.4f} {r['max_balance']:>8.1e} "
            f"{r['newton_per_step']:>6} {r['run_seconds']:>7} {r['press_force_y_at_2']:>9.5f} "
            f"{r.get('press_force_y_diff_at_2', float('nan')):>8.1e} "
            f"{r['drag_force_x_at_2']:>9.5f} {r.get('drag_force_x_diff_at_2', float('nan')):>8.1e} "
            f"{r.get('press_force_y_max_diff', float('nan')):>8.1e} "
            f"{r.get('drag_force_x_max_diff', float('nan')):>8.1e}"
        )
    for r in table:
        if "press_force_y_order" in r:
            print(
                f"observed order of the difference at s = {COMPARE_AT} from {r['cells']}: "
                f"F_y {r['press_force_y_order']:.2f}, F_x {r['drag_force_x_order']:.2f}"
            )
    args.out.mkdir(parents=True, exist_ok=True)
    save_csv(args.out / "ironing.csv", [r for rows in meshes.values() for r in rows])
    save_csv(args.out / "ironing_meshes.csv", table)
    chart(args.out / "ironing.png", meshes)


if __name__ == "__main__":
    main()
