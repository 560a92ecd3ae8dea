"""Frictional Newton and its cycles: the tangential forms × line search.

What it shows: plain semismooth Newton (``solver.line_search: basic``) on the projection
(Alart–Curnier) form 2-cycles on some of bench_friction.py's form cases — the nodes slide
one way, then the other — and whether a case cycles can hang on rounding (the 3D box with
MUMPS cycled on some CPUs and converged on others).  ``auto``, the default, takes plain steps
until a cycle shows and then backtracks on ½‖Φ‖² (:class:`contact.solvers.friction.
GuardedFriction`, :mod:`contact.solvers.globalize`); ``bt`` is PETSc's backtracking from the
first step.  The cases: each form (hsw, projection) × normal NCP (fb, min, blend) on the
block (stick- and slip-dominated), the cylinder and the 3D box, one step from u = 0 and from
the frictionless solution (bench_friction.py's ``forms``), at most 100 Newton steps.  Printed:
per line search the runs converged, the Newton steps, and how many of the runs plain steps
converge in keep plain's count.  About 3 minutes (``--quick``: coarser meshes).

    python demos/bench/bench_friction_cycle.py --out demos/results/friction/line_search.csv
"""

from __future__ import annotations

import argparse

from bench_friction import forms
from common import save_csv

LINE_SEARCHES = ("basic", "auto", "bt")


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", default="demos/results/friction/line_search.csv")
    ap.add_argument("--quick", action="store_true", help="small meshes (a smoke run)")
    args = ap.parse_args()
    rows = [row for ls in LINE_SEARCHES for row in forms(args.quick, line_search=ls)]
    key = ("case", "start", "form", "method")
    plain = {tuple(r[k] for k in key): r for r in rows if r["line_search"] == "basic"}
    for ls in LINE_SEARCHES:
        runs = [r for r in rows if r["line_search"] == ls]
        done = [r for r in runs if r["converged"]]
        kept = sum(
            1
            for r in done
            if plain[tuple(r[k] for k in key)]["converged"]
            and plain[tuple(r[k] for k in key)]["newton_iterations"] == r["newton_iterations"]
        )
        print(
            f"{ls:6s} converged {len(done)} of {len(runs)}, "
            f"{sum(r['newton_iterations'] for r in done)} Newton steps in those, "
            f"plain's count kept in {kept} of {sum(p['converged'] for p in plain.values())}",
            flush=True,
        )
    save_csv(args.out, rows)


if __name__ == "__main__":
    main()
