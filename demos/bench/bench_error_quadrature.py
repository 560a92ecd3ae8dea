"""How accurate and how costly is the energy error ‖u − u_h‖_E per quadrature degree?

What it shows: the adaptive loop of problem A (docs/theory.md §7, u = −r^{3/2} cos(3θ/2), singular
at the origin) reports ‖u − u_h‖_E on every level; the integrand holds the exact solution
(r^{3/2}, atan2, cos at every quadrature point), so its quadrature degree sets the cost.
On each level this script evaluates the error with degrees 2 … 8 and a reference of
degree 12, and prints the relative change |e_q / e_12 − 1| and the seconds per
evaluation.  The default, degree 2p + 2 = 4 for P1
(:func:`contact.adaptivity.energy_error.default_degree`), is where the change stays far below the
two digits an effectivity index is read to.

    python demos/bench/bench_error_quadrature.py --max-dofs 500000 --out
    demos/results/error_quadrature.csv
"""

from __future__ import annotations

import argparse
import time

import contact
import dolfinx_solver  # noqa: F401  (before dolfinx / petsc4py with the solver wheel)
from contact.adaptivity.energy_error import energy_error
from contact.drivers.adaptive import Level

from common import save_csv

DEGREES = (2, 3, 4, 5, 6, 8)
REFERENCE = 12


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--max-dofs", type=int, default=500_000)
    ap.add_argument("--out", default="demos/results/error_quadrature.csv")
    args = ap.parse_args()
    scene = contact.load_scene(
        "configs/signorini_free_boundary.yaml",
        overrides=[f"adapt.max_dofs={args.max_dofs}", "adapt.max_levels=40"],
    )
    exact, rows = scene.config.data.exact, []

    def on_level(level: Level) -> None:
        u_h, k = level.result.u_h, level.result.problem.data.k
        ref = energy_error(u_h, exact, k, quadrature_degree=REFERENCE)
        row = {"level": level.index, "dofs": level.result.dofs, "error_q12": ref}
        for q in DEGREES:
            t0 = time.perf_counter()
            e = energy_error(u_h, exact, k, quadrature_degree=q)
            row[f"change_q{q}"] = abs(e / ref - 1.0)
            row[f"seconds_q{q}"] = time.perf_counter() - t0
        rows.append(row)
        print(
            f"{row['level']:3d} {row['dofs']:8d}  "
            + "  ".join(
                f"q{q} {row[f'change_q{q}']:.1e} {row[f'seconds_q{q}']:.2f}s" for q in DEGREES
            ),
            flush=True,
        )

    print("level     DoFs  relative change against degree 12, seconds", flush=True)
    contact.adapt(scene, on_level=on_level, verbose=False)
    save_csv(args.out, rows)


if __name__ == "__main__":
    main()
