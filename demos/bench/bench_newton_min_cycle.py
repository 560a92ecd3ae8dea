"""Case (p) of the stability map: plain Newton-min cycles on a P-matrix LCP.

What it shows: Ben Gharbia & Gilbert (Math. Program. 134, 2012) proved that the plain
Newton-min algorithm — the primal–dual active set method, our ``min`` with line search
``basic`` — may cycle on an LCP 0 ≤ x ⟂ M x + q ≥ 0 whose M is a P-matrix of order ≥ 3,
although such an LCP has exactly one solution for every q.  On the order-3 problem of
:func:`contact.solvers.lcp.cycling_lcp` each NCP function of the package (its own φ and ∂φ,
:mod:`contact.solvers.ncp`) drives a dense semismooth Newton iteration from the same start,
with plain steps (``basic``), backtracking on ½‖Φ‖² (``bt``) and for min the default
globalization (``auto``: plain steps until an active set repeats, then ``bt``,
:mod:`contact.solvers.globalize`); the table gives iterations, convergence, the
period of a cycle (0: none) and the distance to the solution (1, 1, 1)/3.  A control row:
plain Newton-min on an M-matrix (the 1D Laplacian, q = −1) from the same start.  Runs in
well under a second.

    python demos/bench/bench_newton_min_cycle.py --out demos/results/newton_min_cycle.csv
"""

from __future__ import annotations

import argparse

from contact.solvers.lcp import cycling_lcp, is_p_matrix, lcp_residual, newton_lcp

import numpy as np
from common import save_csv

MAX_IT = 100


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", default="demos/results/newton_min_cycle.csv")
    args = ap.parse_args()
    M, q, x0 = cycling_lcp()
    laplace = 2.0 * np.eye(3) - np.eye(3, k=1) - np.eye(3, k=-1)
    problems = {
        "P-matrix of order 3 (cyclic)": (M, q, np.ones(3) / 3.0),
        "M-matrix (1D Laplacian)": (laplace, -np.ones(3), np.linalg.solve(laplace, np.ones(3))),
    }
    rows = []
    for name, (A, b, x_star) in problems.items():
        runs = (
            [(m, ls) for m in ("min", "fb", "blend") for ls in ("basic", "bt")] + [("min", "auto")]
            if name.startswith("P")
            else [("min", "basic")]
        )
        for method, line_search in runs:
            r = newton_lcp(A, b, x0, method=method, line_search=line_search, max_it=MAX_IT)
            rows.append(
                {
                    "matrix": name,
                    "p_matrix": is_p_matrix(A),
                    "method": method,
                    "line_search": line_search,
                    "iterations": r.iterations,
                    "converged": r.converged,
                    "period": r.period(),
                    "residual": float(np.linalg.norm(lcp_residual(A, b, r.x, method))),
                    "error": float(np.max(np.abs(r.x - x_star))),
                    "x0": " ".join(f"{v:g}" for v in x0),
                }
            )
    width = max(len(r["matrix"]) for r in rows)
    print(
        f"{'matrix':{width}s}  method  line search  its  converged  period  |Phi|      max|x - x*|"
    )
    for r in rows:
        print(
            f"{r['matrix']:{width}s}  {r['method']:6s}  {r['line_search']:11s}  "
            f"{r['iterations']:3d}  "
            f"{str(r['converged']):9s}  {r['period']:6d}  {r['residual']:.2e}  {r['error']:.2e}"
        )
    save_csv(args.out, rows)


if __name__ == "__main__":
    main()
