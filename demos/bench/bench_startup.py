"""Start-up: the CPU seconds of ``import contact`` and of a tiny ``contact run``.

Each measurement is a fresh Python process; its CPU seconds (user + system, from
``resource.getrusage(RUSAGE_CHILDREN)``) are what a shared, loaded machine leaves steady,
and its wall seconds are printed beside them.  The tiny run is ``contact run
configs/signorini_square.yaml --set mesh.cells=[8,8]`` with its default outputs (pictures
included); ``--old-grid`` runs alternate with the old output grid
(``contact.output.vtk.PYVISTA_GRID``: pyvista and VTK imported for every file and
picture), so the ratio is of one machine state.  Also prints ``python -X importtime``'s
cumulative microseconds of ``import contact``, and the same tiny run without pictures
(``output.png=false``) and as one ``contact.solve`` without files: what the pictures and
the files cost.  Writes CSV.

    python demos/bench/bench_startup.py --repeat 5 --out demos/results/startup.csv
"""

from __future__ import annotations

import argparse
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import save_csv

ROOT = Path(__file__).resolve().parents[2]
RUN = (
    "import sys; import contact.output.vtk as vtk; vtk.PYVISTA_GRID = {old}\n"
    "from contact.app.cli import main\n"
    "sys.exit(main(['run', 'configs/signorini_square.yaml', '--set', 'mesh.cells=[8,8]',\n"
    "               '--set', 'output.verbose=false', *{sets!r}, '-o', {out!r}]))"
)

#: the scene solved by the API: the imports and the solve, no files
SOLVE = (
    "import contact\n"
    "scene = contact.load_scene('configs/signorini_square.yaml', ['mesh.cells=[8,8]'])\n"
    "assert contact.solve(scene, verbose=False).converged"
)


def child(code: str, *flags: str) -> tuple[float, float, str]:
    """(CPU seconds, wall seconds, stderr) of ``python flags -c code``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, *flags, "-c", code], cwd=ROOT, capture_output=True, text=True
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert proc.returncode == 0, proc.stderr[-2000:]
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    return cpu, wall, proc.stderr


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--old-grid", action="store_true", help="alternate with the old grid")
    ap.add_argument("--out", default=None, help="CSV file")
    args = ap.parse_args()
    rows = []
    for k in range(args.repeat):
        cpu, wall, err = child("import contact", "-X", "importtime")
        line = next(x for x in err.splitlines() if re.search(r"\|\s+contact$", x))
        self_us, cumulative_us = int(line.split("|")[0].split()[-1]), int(line.split("|")[1])
        rows.append(
            {
                "case": "import contact",
                "repeat": k,
                "cpu": round(cpu, 3),
                "wall": round(wall, 3),
                "importtime_self_s": self_us / 1e6,
                "importtime_cumulative_s": cumulative_us / 1e6,
            }
        )
        cases = [("tiny run", False, [])]
        if args.old_grid:
            cases.append(("tiny run, pyvista grid (old)", True, []))
        cases.append(("tiny run, output.png=false", False, ["--set", "output.png=false"]))
        cases.append(("solve only (API, no files)", False, ["--set", "output.png=false"]))
        for case, old, sets in cases:
            with tempfile.TemporaryDirectory() as tmp:
                code = RUN.format(old=old, sets=sets, out=f"{tmp}/tiny")
                if case.startswith("solve only"):
                    code = SOLVE
                cpu, wall, _ = child(code)
            rows.append({"case": case, "repeat": k, "cpu": round(cpu, 3), "wall": round(wall, 3)})
    for case in dict.fromkeys(r["case"] for r in rows):
        mine = [r for r in rows if r["case"] == case]
        text = (
            f"{case:32s} median CPU {statistics.median(r['cpu'] for r in mine):.3f} s, "
            f"wall {statistics.median(r['wall'] for r in mine):.3f} s"
        )
        if "importtime_cumulative_s" in mine[0]:
            text += (
                ", importtime cumulative "
                f"{statistics.median(r['importtime_cumulative_s'] for r in mine):.3f} s (self "
                f"{statistics.median(r['importtime_self_s'] for r in mine):.4f} s)"
            )
        print(text, flush=True)
    if args.old_grid:
        new = statistics.median(r["cpu"] for r in rows if r["case"] == "tiny run")
        old = statistics.median(r["cpu"] for r in rows if "old" in r["case"])
        print(f"tiny run CPU, new/old grid: {new / old:.2f}")
    if args.out:
        save_csv(args.out, rows)


if __name__ == "__main__":
    main()
