"""Peak memory per degree of freedom of one solve with the default linear solvers — the
figure behind ``solver.max_dofs: auto`` (contact/setup/budget.py).

Each size runs in a fresh process (serial): load the scene, solve it once with the
scene's defaults (fb; ``solver.linear: auto``, which picks CG + GAMG on the reduced system
at these sizes, and grid sequencing where it pays), and report the peak resident set size
(``ru_maxrss``) and the linear solver used.  The per-DoF figure is the slope between the two
largest sizes of a kind, (RSS₂ − RSS₁)/(N₂ − N₁), which leaves out the ~0.3 GB the
interpreter and libraries take whatever the size; ``bytes_per_dof`` is the peak over N.

    python demos/bench/bench_memory.py                       # every kind, ~6 minutes
    python demos/bench/bench_memory.py --kinds scalar2d --out /tmp/memory.csv

Prints one row per run and writes CSV (kind, cells, dofs, linear, seconds, peak_rss_mib,
bytes_per_dof, slope_bytes_per_dof).
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# kind -> (scene overrides template, sizes); {n} is the cell count per direction
KINDS = {
    "scalar2d": ("configs/signorini_square.yaml", ["mesh.cells=[{n},{n}]"], [256, 512, 1024]),
    "elasticity2d": (None, "box2d", [128, 256, 512]),
    "scalar3d": (None, "box3d_scalar", [24, 36, 48]),
    "elasticity3d": (None, "box3d_elastic", [24, 40, 69]),
}

# A block pressed onto a rigid plane: the elastic scenes of this benchmark (no Hertz).
BLOCK = {
    "box2d": {
        "mesh": {"type": "rectangle", "corners": [[0, 0], [1, 1]], "cells": ["{n}", "{n}"]},
        "boundaries": {
            "floor": {"role": "contact", "where": "y < 1e-10"},
            "top": {"role": "dirichlet", "where": "y > 1 - 1e-10"},
        },
        "model": {"type": "elasticity", "E": 1.0, "nu": 0.3},
        "obstacle": {"type": "plane", "point": [0, -0.001], "normal": [0, 1]},
        "data": {"u_D": ["0", "-0.01"]},
    },
    "box3d_elastic": {
        "mesh": {"type": "box", "corners": [[0, 0, 0], [1, 1, 1]], "cells": ["{n}", "{n}", "{n}"]},
        "boundaries": {
            "floor": {"role": "contact", "where": "z < 1e-10"},
            "top": {"role": "dirichlet", "where": "z > 1 - 1e-10"},
        },
        "model": {"type": "elasticity", "E": 1.0, "nu": 0.3},
        "obstacle": {"type": "plane", "point": [0, 0, -0.001], "normal": [0, 0, 1]},
        "data": {"u_D": ["0", "0", "-0.01"]},
    },
    "box3d_scalar": {
        "mesh": {"type": "box", "corners": [[0, 0, 0], [1, 1, 1]], "cells": ["{n}", "{n}", "{n}"]},
        "boundaries": {
            "floor": {"role": "contact", "where": "z < 1e-10"},
            "top": {"role": "dirichlet", "where": "z > 1 - 1e-10"},
        },
        "model": "signorini",
        "data": {"f": "-10", "g": "0.01", "u_D": "0"},
    },
}

CHILD = r"""
import json, resource, sys, time
import contact
spec = json.loads(sys.argv[1])
t0 = time.perf_counter()
scene = contact.load_scene(spec["source"], spec["overrides"] + ["solver.max_dofs=100000000"])
result = contact.solve(scene, verbose=False)
rss_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps({"dofs": result.dofs, "linear": result.linear, "converged": bool(result.converged),
                  "seconds": time.perf_counter() - t0, "rss_mib": rss_mib}))
"""


def _spec(kind: str, n: int) -> dict:
    source, template, _ = KINDS[kind]
    if source is not None:
        return {"source": str(ROOT / source), "overrides": [t.format(n=n) for t in template]}
    scene = json.loads(json.dumps(BLOCK[template]).replace('"{n}"', str(n)))
    scene["name"] = f"{kind}_{n}"
    return {"source": scene, "overrides": []}


def measure(kind: str, n: int) -> dict:
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, json.dumps(_spec(kind, n))],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    if proc.returncode != 0:
        raise SystemExit(f"{kind} n={n} failed:\n{proc.stderr}")
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    return {
        "kind": kind,
        "cells": n,
        "dofs": out["dofs"],
        "linear": out["linear"],
        "converged": out["converged"],
        "seconds": round(out["seconds"], 2),
        "peak_rss_mib": round(out["rss_mib"], 1),
        "bytes_per_dof": round(out["rss_mib"] * 2**20 / out["dofs"]),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", nargs="+", default=list(KINDS), choices=list(KINDS))
    ap.add_argument("--out", default="demos/results/memory.csv")
    args = ap.parse_args()
    rows = []
    for kind in args.kinds:
        runs = [measure(kind, n) for n in KINDS[kind][2]]
        for a, b in zip(runs, runs[1:]):
            b["slope_bytes_per_dof"] = round(
                (b["peak_rss_mib"] - a["peak_rss_mib"]) * 2**20 / (b["dofs"] - a["dofs"])
            )
        for r in runs:
            print(
                f"{r['kind']:13s} n={r['cells']:5d} {r['dofs']:9d} DoFs  {r['linear']:6s} "
                f"{r['seconds']:7.1f} s  "
                f"{r['peak_rss_mib']:8.0f} MiB  {r['bytes_per_dof']:6d} B/DoF  "
                f"slope {r.get('slope_bytes_per_dof', '-')} B/DoF",
                flush=True,
            )
        rows += runs
    out = ROOT / args.out
    out.parent.mkdir(parents=True, exist_ok=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(out, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
