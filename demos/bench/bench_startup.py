"""Start-up: the CPU seconds of ``import contact`` and of a tiny ``contact run``.

Each measurement is a fresh Python process; its CPU seconds (user + system, from
``resource.getrusage(RUSAGE_CHILDREN)``) are what a shared, loaded machine leaves steady,
and its wall seconds are printed beside them.  The tiny run is ``contact run
configs/signorini_square.yaml --set mesh.cells=[8,8]`` with its default outputs (pictures
included).  Beside it, in the same round so that ratios are of one machine state:

* ``--old-png``: the PNG files compressed at zlib level 6, matplotlib's default
  (``contact.output.figures.PNG_LEVEL``; the new level is 1);
* ``--old-plots``: the pictures drawn through matplotlib.pyplot
  (``contact.output.figures.PYPLOT``, the old path; the new one draws on Figures of their own);
* ``--old-gc``: the cyclic garbage collector on while the command loads its modules and scene
  (``contact.app.cli.FREEZE_LOADED`` False, the old path; the new one keeps it off there and
  then freezes what was loaded);
* ``--old-process``: the pictures drawn in the command's process
  (``contact.output.picture_process.ENABLED`` False, the old path; the new one draws them
  in a process started before DOLFINx is imported, which imports matplotlib meanwhile: its
  CPU seconds are counted with the run's);
* ``--old-grid``: the old output grid (``contact.output.vtk.PYVISTA_GRID``: pyvista and VTK
  imported for every file and picture);
* the tiny run without pictures (``output.png=false``), as one ``contact.solve`` without
  files, and "libraries only": a process that imports, in the order the tiny run loaded
  them, the modules other than contact's that the tiny run loads, and does nothing else (the
  floor that no change in contact's own code goes below).

Also prints ``python -X importtime``'s cumulative microseconds of ``import contact``.

The children compile their bytecode once (an untimed first round) into a cache folder of
their own (``PYTHONPYCACHEPREFIX``; ``PYTHONDONTWRITEBYTECODE`` dropped), as an installed
package or a repeated run has it: without that cache every run compiles contact's modules
again, about 0.1 s CPU.  ``--no-bytecode-cache`` keeps the inherited environment.
Writes CSV.

    python demos/bench/bench_startup.py --repeat 5 --old-process --old-png --old-plots \\
        --old-gc --old-grid --out demos/results/startup.csv
"""

from __future__ import annotations

import argparse
import json
import os
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
    "import sys\n"
    "{flags}"
    "from contact.app.cli import main\n"
    "code = main(['run', 'configs/signorini_square.yaml', '--set', 'mesh.cells=[8,8]',\n"
    "             '--set', 'output.verbose=false', *{sets!r}, '-o', {out!r}])\n"
    "{after}\n"
    "sys.exit(code)"
)
#: the old paths' switches, each set before main() only when it is on: setting one imports
#: its module, and the output modules import DOLFINx, which must not be loaded before main()
#: starts the picture process
SWITCHES = {
    "old_grid": "import contact.output.vtk as vtk; vtk.PYVISTA_GRID = True\n",
    "old_plots": "import contact.output.figures as figures; figures.PYPLOT = True\n",
    "old_gc": "import contact.app.cli as cli; cli.FREEZE_LOADED = False\n",
    "old_process": "import contact.output.picture_process as pp; pp.ENABLED = False\n",
    "old_png": "import contact.output.figures as figures; figures.PNG_LEVEL = 6\n",
}
#: what the tiny run's child prints after it: the modules other than contact's it loaded
LOADED = (
    "import json; print(json.dumps([m for m in sys.modules"
    " if m != 'contact' and not m.startswith(('contact.', '__main__'))]))"
)

#: the scene solved by the API: the imports and the solve, no files
SOLVE = (
    "import contact\n"
    "scene = contact.load_scene('configs/signorini_square.yaml', ['mesh.cells=[8,8]'])\n"
    "assert contact.solve(scene, verbose=False).converged"
)

#: imports ``modules`` in order (one that cannot be imported on its own is skipped), with
#: the cyclic collector off as in the CLI's loading
LIBRARIES = (
    "import gc, importlib\n"
    "gc.disable()\n"
    "for name in {modules!r}:\n"
    "    try:\n"
    "        importlib.import_module(name)\n"
    "    except Exception:\n"
    "        pass"
)


def child(code: str, env: dict, *flags: str) -> tuple[float, float, str, str]:
    """(CPU seconds, wall seconds, stdout, stderr) of ``python flags -c code``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, *flags, "-c", code], cwd=ROOT, capture_output=True, text=True, env=env
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert proc.returncode == 0, proc.stderr[-2000:]
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    return cpu, wall, proc.stdout, proc.stderr


def child_env(cache: str | None) -> dict:
    """The children's environment: bytecode written to and read from ``cache`` (None: the
    inherited environment)."""
    env = dict(os.environ)
    if cache is not None:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = cache
    return env


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--old-grid", action="store_true", help="alternate with the old grid")
    ap.add_argument("--old-plots", action="store_true", help="alternate with pyplot's pictures")
    ap.add_argument("--old-gc", action="store_true", help="alternate with the collector on")
    ap.add_argument(
        "--old-process", action="store_true", help="alternate with the pictures drawn in-process"
    )
    ap.add_argument("--old-png", action="store_true", help="alternate with PNG zlib level 6")
    ap.add_argument(
        "--no-bytecode-cache", action="store_true", help="keep the inherited environment"
    )
    ap.add_argument("--out", default=None, help="CSV file")
    args = ap.parse_args()
    # (case, old paths switched on, --set items)
    cases: list[tuple[str, tuple[str, ...], list[str]]] = [("tiny run", (), [])]
    if args.old_process:
        cases.append(("tiny run, pictures in-process (old)", ("old_process",), []))
    if args.old_png:
        cases.append(("tiny run, PNG zlib level 6 (old)", ("old_png",), []))
    if args.old_plots:
        cases.append(("tiny run, pictures through pyplot (old)", ("old_plots",), []))
    if args.old_gc:
        cases.append(("tiny run, collector on while loading (old)", ("old_gc",), []))
    if args.old_grid:
        cases.append(("tiny run, pyvista grid (old)", ("old_grid",), []))
    png = ["--set", "output.png=false"]
    cases.append(("tiny run, output.png=false", (), png))
    cases.append(("solve only (API, no files)", (), []))
    with tempfile.TemporaryDirectory() as cache:
        env = child_env(None if args.no_bytecode_cache else cache)
        bytecode = "inherited environment" if args.no_bytecode_cache else "cached"
        rows = []
        libraries: list[str] = []
        for k in range(-1, args.repeat):  # round -1: untimed, compiles the bytecode
            cpu, wall, _, err = child("import contact", env, "-X", "importtime")
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
            for case, switches, sets in cases:
                with tempfile.TemporaryDirectory() as tmp:
                    code = RUN.format(
                        flags="".join(SWITCHES[name] for name in switches),
                        sets=sets,
                        out=f"{tmp}/tiny",
                        after=LOADED if case == "tiny run" else "",
                    )
                    if case.startswith("solve only"):
                        code = SOLVE
                    cpu, wall, out, _ = child(code, env)
                if case == "tiny run":
                    libraries = json.loads(out.splitlines()[-1])
                rows.append(
                    {"case": case, "repeat": k, "cpu": round(cpu, 3), "wall": round(wall, 3)}
                )
            cpu, wall, _, _ = child(LIBRARIES.format(modules=libraries), env)
            rows.append(
                {
                    "case": "libraries only",
                    "repeat": k,
                    "cpu": round(cpu, 3),
                    "wall": round(wall, 3),
                }
            )
    rows = [dict(r, bytecode=bytecode) for r in rows if r["repeat"] >= 0]
    print(f"bytecode: {bytecode}; {len(libraries)} modules other than contact's in a tiny run")
    for case in dict.fromkeys(r["case"] for r in rows):
        mine = [r for r in rows if r["case"] == case]
        text = (
            f"{case:40s} median CPU {statistics.median(r['cpu'] for r in mine):.3f} s, "
            f"wall {statistics.median(r['wall'] for r in mine):.3f} s"
        )
        if "importtime_cumulative_s" in mine[0]:
            text += (
                ", importtime cumulative "
                f"{statistics.median(r['importtime_cumulative_s'] for r in mine):.3f} s (self "
                f"{statistics.median(r['importtime_self_s'] for r in mine):.4f} s)"
            )
        print(text, flush=True)

    def median_cpu(case: str) -> float:
        return statistics.median(r["cpu"] for r in rows if r["case"] == case)

    def median_wall(case: str) -> float:
        return statistics.median(r["wall"] for r in rows if r["case"] == case)

    if args.old_process:
        old = "tiny run, pictures in-process (old)"
        print(
            f"tiny run, new/old (picture process): CPU "
            f"{median_cpu('tiny run') / median_cpu(old):.2f}, wall "
            f"{median_wall('tiny run') / median_wall(old):.2f}"
        )
    for flag, case in (
        (args.old_png, "PNG zlib level 6"),
        (args.old_plots, "pyplot"),
        (args.old_gc, "collector"),
        (args.old_grid, "pyvista grid"),
    ):
        if flag:
            old = next(c for c, *_ in cases if case in c)
            print(f"tiny run CPU, new/old ({case}): {median_cpu('tiny run') / median_cpu(old):.2f}")
    if args.out:
        save_csv(args.out, rows)


if __name__ == "__main__":
    main()
