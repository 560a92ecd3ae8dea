"""Speed against accuracy of the baseline enforcements — penalty, augmented Lagrangian
(Uzawa) and Nitsche (θ = 1 and θ = −1) — against semismooth Newton on Fischer–Burmeister
(fb), on the same scenes and meshes, in one process (docs/theory.md §10).

For every problem and mesh: fb, then each method over its parameter (ε₀, r₀, γ₀; ≥ 6
decades), each solve timed with the scene's defaults otherwise (grid sequencing, the
linear solver of its size).  Figures per solve:

* ``error`` — the energy-norm error: against the exact solution (problems A and C, data.exact),
  or, for Hertz, against fb on the mesh refined uniformly once (|||u_ref − u_h|||, the
  reference's mesh; :func:`common.elastic_reference`); ``error_fb`` — fb's on this mesh;
* ``dist_fb`` — |||u_h − u_fb||| / |||u_fb|||, the distance to the exact-constraint discrete
  solution on the same mesh (penalty: O(1/ε₀));
* ``penetration`` — max over the contact nodes of [d(u_h) − g]₊ (units of u), and
  ``penetration_rel`` the same over max |u_h|;
* ``force_rel`` — contact force / fb's − 1; Hertz: ``a_error``, ``p0_error`` against Hertz;
* ``seconds``, ``ratio`` = seconds / fb's seconds on the same mesh (fb timed ``--repeat``
  times around each method's sweep, the median), Newton and Uzawa iterations, Krylov
  iterations, the linear solver.

The script prints every row, then per problem the parameter each method needs for the
accuracy fb reaches by construction — its solution within 1 % of fb's discretization error
of fb's, |||u_h − u_fb||| ≤ 0.01 error_fb, so that its error is fb's to 1 % whatever the signs
(a penalty's softening can cancel part of the discretization error: penalty ε₀ = 10 on
hertz_3d is 1 % *closer* to the reference than fb) — and its time ratio then, and the
observed orders (penalty: dist_fb and penetration against ε₀; every method: the error
against the DoFs N at its default parameter, beside fb's).  CSV: ``<out>/<problem>.csv``;
charts ``<out>/<problem>.png`` (error against time, distance to fb and penetration against
the parameter) and ``<out>/convergence.png`` (error against DoFs at the default parameters,
every problem).

    python demos/bench/bench_baselines.py --out demos/results/baselines        (~25 minutes)
    python demos/bench/bench_baselines.py --problems A --quick                   (~1 minute)
    python demos/bench/bench_baselines.py --problems cattaneo                    (~5 minutes)
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import contact
from contact.adaptivity.energy_error import energy_error
from contact.post.hertz import compare as hertz_compare
from contact.post.reference import compare as reference_compare
from contact.setup.posed import posed_of
from contact.setup.run import run_load_path
from contact.solvers.baselines import PARAMETERS, penetration

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import elastic_reference, energy_distance, save_csv  # noqa: E402

#: problem -> (scene, its meshes as --set overrides)
PROBLEMS = {
    "A": (
        "signorini_free_boundary",
        [[f"mesh.cells=[{2 * n},{n}]"] for n in (8, 16, 32, 64)],
    ),
    "C": ("signorini_smooth", [[f"mesh.cells=[{n},{n}]"] for n in (8, 16, 32, 64)]),
    "hertz2d": ("hertz_2d", [[f"mesh.h_contact={h}"] for h in (0.008, 0.004, 0.002)]),
    "hertz3d": ("hertz_3d", [[f"mesh.h_contact={h}"] for h in (0.04, 0.02, 0.01)]),
    "cattaneo": ("two_body_cattaneo_2d", [[f"mesh.h_contact={h}"] for h in (0.04, 0.02)]),
}
#: the swept values of each method's parameter (decades)
SWEEPS = {
    "penalty": [10.0**k for k in range(-2, 9)],
    "augmented_lagrangian": [10.0**k for k in range(-1, 7)],
    "nitsche": [10.0**k for k in range(-3, 5)],
}
#: the variants charted: (method, θ)
VARIANTS = [("penalty", None), ("augmented_lagrangian", None), ("nitsche", 1.0), ("nitsche", -1.0)]
#: two bodies through the mortar gap: penalty and augmented Lagrangian (Nitsche: one body), over
#: fewer decades — each run is a 4-step load path (Uzawa below r₀ = 1 needs ~100 outer
#: iterations per step)
TWO_BODY_VARIANTS = VARIANTS[:2]
TWO_BODY_SWEEPS = {
    "penalty": [10.0**k for k in range(0, 8)],
    "augmented_lagrangian": [10.0**k for k in range(0, 5)],
}
DEFAULTS = {"penalty": 1e3, "augmented_lagrangian": 1e2, "nitsche": 10.0}
#: the penalty's order is fitted up to this ε₀: beyond, |||u − u_fb||| meets the floor that the
#: Krylov tolerance 1e-10 leaves on a system ε₀ times stiffer (hertz_2d at 29k DoFs: 1e-9)
ORDER_MAX = 1e5
TOLERANCE = 0.01  # equal accuracy: |||u_h − u_fb||| ≤ TOLERANCE error_fb


def label(method: str, theta: float | None) -> str:
    return method if theta is None else f"{method} θ={theta:g}"


def energy_norm(scene, e) -> float:
    """|||e||| of the scene's bilinear form (k ∇·∇ for scalar models, σ:ε for elasticity)."""
    msh = scene.mesh
    if scene.config.elastic:
        model = scene.config.model
        E, nu = model.E, model.nu
        mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
        eps = ufl.sym(ufl.grad(e))
        form = (2 * mu * ufl.inner(eps, eps) + lam * ufl.tr(eps) ** 2) * ufl.dx(domain=msh)
    else:
        form = ufl.inner(ufl.grad(e), ufl.grad(e)) * ufl.dx(domain=msh)
    return float(np.sqrt(max(msh.comm.allreduce(fem.assemble_scalar(fem.form(form))), 0.0)))


class Mesh:
    """One mesh of a problem: the scene, fb's solution and its reference figures."""

    variants, sweeps = VARIANTS, SWEEPS

    def __init__(self, problem: str, scene_name: str, overrides: list[str], repeat: int):
        self.problem, self.repeat = problem, repeat
        self.scene = contact.load_scene(
            f"configs/{scene_name}.yaml", ["adapt=null", "output.verbose=false", *overrides]
        )
        self.hertz = self.scene.config.reference is not None
        contact.solve(self.scene, method="fb", verbose=False)  # JIT, untimed
        fb = self.timed("fb", {})
        self.fb = fb
        V = fb.u_h.function_space
        self.u_fb = fem.Function(V)
        self.u_fb.x.array[:] = fb.u_h.x.array
        self.norm_fb = energy_norm(self.scene, self.u_fb)
        self.reference = None
        if self.hertz:
            self.reference = elastic_reference(self.scene, fb.u_h, refinements=1)
        self.error_fb = self.error(fb)
        self.fb_seconds = [fb.seconds]

    def warm(self, method: str, options: dict) -> None:
        """One untimed solve: the forms' JIT compilation."""
        contact.solve(self.scene, method=method, verbose=False, **options)

    def timed(self, method: str, options: dict):
        t0 = time.perf_counter()
        r = contact.solve(self.scene, method=method, verbose=False, **options)
        r.seconds = time.perf_counter() - t0
        return r

    def fb_time(self) -> float:
        """fb's wall time: median of the runs so far and ``repeat`` new ones."""
        for _ in range(self.repeat):
            self.fb_seconds.append(self.timed("fb", {}).seconds)
        return statistics.median(self.fb_seconds)

    def error(self, r) -> float:
        cfg = self.scene.config
        if self.reference is not None:
            return energy_distance(self.reference, r.u_h)
        assert isinstance(cfg.data.exact, str)
        return energy_error(r.u_h, cfg.data.exact, 1.0, cfg.constants)

    def distance(self, r) -> float:
        """|||u_h − u_fb||| / |||u_fb|||."""
        e = fem.Function(self.u_fb.function_space)
        e.x.array[:] = r.u_h.x.array - self.u_fb.x.array
        return energy_norm(self.scene, e) / self.norm_fb

    def extra(self, r) -> dict:
        """The problem's own figures: Hertz's a and p0 errors."""
        out = {"a_error": float("nan"), "p0_error": float("nan")}
        if r.converged and r.contact_force > 0:
            errors = hertz_compare(posed_of(self.scene), r, self.scene.config.reference).errors
            out["a_error"], out["p0_error"] = errors["a_error"], errors["p0_error"]
        return out if self.hertz else {}

    def row(self, r, method: str, theta: float | None, value: float | None, fb_seconds: float):
        umax = self.scene.comm.allreduce(
            float(np.max(np.abs(self.u_fb.x.array), initial=0.0)), op=MPI.MAX
        )
        pen = penetration(r) if r.converged else float("nan")
        out = {
            "problem": self.problem,
            "dofs": r.dofs,
            "h_min": self.h_min(),
            "method": method,
            "theta": "" if theta is None else theta,
            "parameter": PARAMETERS.get(method, ""),
            "value": "" if value is None else value,
            "converged": r.converged,
            "reason": r.reason,
            "newton_iterations": r.iterations,
            "outer_iterations": r.outer_iterations,
            "coarse_iterations": r.coarse_iterations,
            "krylov_iterations": r.krylov_iterations,
            "linear_solver": r.linear,
            "seconds": r.seconds,
            "fb_seconds": fb_seconds,
            "ratio": r.seconds / fb_seconds,
            "error": self.error(r) if r.converged else float("nan"),
            "error_fb": self.error_fb,
            "dist_fb": self.distance(r),
            "norm_fb": self.norm_fb,
            "penetration": pen,
            "penetration_rel": pen / umax if umax > 0 else float("nan"),
            "force_rel": r.contact_force / self.fb.contact_force - 1.0,
        }
        return {**out, **self.extra(r)}

    def h_min(self) -> float:
        msh = self.scene.mesh
        tdim = msh.topology.dim
        n = msh.topology.index_map(tdim).size_local
        h = msh.h(tdim, np.arange(n, dtype=np.int32))
        return msh.comm.allreduce(float(np.min(h, initial=np.inf)), op=MPI.MIN)


class CattaneoMesh(Mesh):
    """Cattaneo–Mindlin (two bodies, Coulomb F = 0.3 on the mortar interface): each run is
    the scene's 4-step load path (P, then Q to Q/(F P) = 0.75), timed whole.  ``error`` — the
    relative L² error of the tangential traction against Cattaneo–Mindlin's at the last step
    (``q_error`` of :func:`contact.post.reference.compare`), ``c_error`` its stick zone's;
    ``dist_fb`` — ‖λ_t − λ_t^fb‖ / ‖λ_t^fb‖ over the slave nodes at the last step (``norm_fb``
    = 1: fb's accuracy is dist_fb ≤ TOLERANCE · fb's q_error); the penetration and the contact
    force at the last step."""

    variants, sweeps = TWO_BODY_VARIANTS, TWO_BODY_SWEEPS

    def __init__(self, problem: str, scene_name: str, overrides: list[str], repeat: int):
        self.problem, self.repeat = problem, repeat
        self.scene = contact.load_scene(
            f"configs/{scene_name}.yaml", ["output.verbose=false", *overrides]
        )
        self.hertz = False
        self.warm("fb", {})
        self.fb = fb = self.timed("fb", {})
        self.lam_fb = fb.friction["lambda_t"].copy()
        self.u_fb = fem.Function(fb.u_h.function_space)
        self.u_fb.x.array[:] = fb.u_h.x.array
        self.norm_fb = 1.0
        self.error_fb = fb.q_error
        self.fb_seconds = [fb.seconds]

    def warm(self, method: str, options: dict) -> None:
        self.timed(method, options).release()

    def timed(self, method: str, options: dict):
        """The load path by ``method``: its last step's result, with the path's wall time,
        iterations summed over the steps and the last step's Cattaneo–Mindlin figures."""
        t0 = time.perf_counter()
        path = run_load_path(self.scene, method=method, verbose=False, keep_all=True, **options)
        seconds = time.perf_counter() - t0
        last = path.steps[-1]
        r = last.result
        r.seconds = seconds
        r.converged = bool(path.converged)
        steps = [s.result for s in path.steps]
        r.iterations = sum(s.iterations for s in steps)
        r.outer_iterations = sum(s.outer_iterations for s in steps)
        r.krylov_iterations = sum(s.krylov_iterations for s in steps)
        values = reference_compare(last.posed, r).values if r.converged else {}
        r.q_error = values.get("q_error", float("nan"))
        r.c_error = values.get("c_error", float("nan"))
        return r

    def error(self, r) -> float:
        return r.q_error

    def distance(self, r) -> float:
        """‖λ_t − λ_t^fb‖ / ‖λ_t^fb‖ at the slave nodes, the last step."""
        lam = r.friction["lambda_t"] if r.converged else self.lam_fb * np.nan
        return float(np.linalg.norm(lam - self.lam_fb) / np.linalg.norm(self.lam_fb))

    def extra(self, r) -> dict:
        return {"c_error": r.c_error}


def sweep(mesh: Mesh, quick: bool) -> list[dict]:
    rows = [mesh.row(mesh.fb, "fb", None, None, mesh.fb_seconds[0])]
    print_row(rows[-1])
    for method, theta in mesh.variants:
        values = mesh.sweeps[method][::3] if quick else mesh.sweeps[method]
        extra = {} if theta is None else {"nitsche_theta": theta}
        mesh.warm(method, extra)  # JIT, untimed
        runs = [(v, mesh.timed(method, {PARAMETERS[method]: v, **extra})) for v in values]
        fb_seconds = mesh.fb_time()
        for v, r in runs:
            rows.append(mesh.row(r, method, theta, v, fb_seconds))
            print_row(rows[-1])
            r.release()
    return rows


def print_row(r: dict) -> None:
    if MPI.COMM_WORLD.rank:
        return
    value = f"{r['parameter']}={r['value']:g}" if r["value"] != "" else ""
    theta = f" θ={r['theta']:g}" if r["theta"] != "" else ""
    print(
        f"{r['problem']:8s} {r['dofs']:7d} {r['method'] + theta:24s} {value:16s} "
        f"conv={r['converged']!s:5s} its={r['newton_iterations']:3d}/{r['outer_iterations']:2d} "
        f"err={r['error']:.4e} (fb {r['error_fb']:.4e}) dist={r['dist_fb']:.2e} "
        f"pen={r['penetration']:.2e} t={r['seconds']:.3f}s ×{r['ratio']:.2f}",
        flush=True,
    )


# ------------------------------------------------------------------------------ analysis
def reaches_fb(r: dict) -> bool:
    """Whether a run is as accurate as fb by construction: converged, and its distance to
    fb's solution at most TOLERANCE of fb's error (energy norms)."""
    return bool(r["converged"]) and r["dist_fb"] * r["norm_fb"] <= TOLERANCE * r["error_fb"]


def present(rows: list[dict]) -> list[tuple[str, float | None]]:
    """The variants that have rows (two bodies: penalty and augmented Lagrangian)."""
    return [
        (m, t) for m, t in VARIANTS if any(r["method"] == m and r["theta"] in ("", t) for r in rows)
    ]


def equal_accuracy(rows: list[dict]) -> list[dict]:
    """Per mesh and variant: the smallest swept parameter that :func:`reaches_fb` (the
    fastest such run for the augmented Lagrangian, whose accuracy does not depend on r), its
    time ratio; None where no swept value reaches it."""
    out = []
    for dofs in sorted({r["dofs"] for r in rows}):
        for method, theta in present(rows):
            runs = [
                r
                for r in rows
                if r["dofs"] == dofs
                and r["method"] == method
                and (theta is None or r["theta"] == theta)
            ]
            ok = [r for r in runs if reaches_fb(r)]
            if method == "augmented_lagrangian":
                best = min(ok, key=lambda r: r["seconds"]) if ok else None
            else:
                best = min(ok, key=lambda r: r["value"]) if ok else None
            out.append({"dofs": dofs, "variant": label(method, theta), "best": best})
    return out


def defaults(rows: list[dict], method: str, theta: float | None) -> list[dict]:
    """The converged runs of a variant at its default parameter (fb: all), coarse to fine."""
    return sorted(
        (
            r
            for r in rows
            if r["method"] == method
            and (theta is None or r["theta"] == theta)
            and (method == "fb" or r["value"] == DEFAULTS[method])
            and r["converged"]
        ),
        key=lambda r: r["dofs"],
    )


def slope(x: list[float], y: list[float]) -> float:
    """Least-squares slope of log y against log x."""
    lx, ly = np.log(np.asarray(x)), np.log(np.asarray(y))
    return float(np.polyfit(lx, ly, 1)[0])


def orders(rows: list[dict]) -> list[str]:
    """The observed orders: penalty's dist_fb and penetration against ε₀ (10 ≤ ε₀ ≤
    ORDER_MAX: 1/ε₀ small, and the distance above the Krylov solver's floor), on the finest
    mesh; each variant's error against the DoFs N at its default (fb: N^{−1/2} on problem A,
    the rate of its r^{3/2} singularity)."""
    lines = []
    finest = max(r["dofs"] for r in rows)
    pen = [
        r
        for r in rows
        if r["dofs"] == finest
        and r["method"] == "penalty"
        and r["converged"]
        and 10 <= r["value"] <= ORDER_MAX
    ]
    pen = [r for r in pen if r["dist_fb"] > 1e-12]
    if len(pen) >= 3:
        eps = [r["value"] for r in pen]
        dist = slope(eps, [r["dist_fb"] for r in pen])
        depth = slope(eps, [r["penetration"] for r in pen])
        lines.append(
            f"penalty on {finest} DoFs, ε₀ ∈ [{eps[0]:g}, {eps[-1]:g}]: "
            f"dist_fb ∝ ε₀^{dist:.2f}, penetration ∝ ε₀^{depth:.2f}"
        )
    for method, theta in [("fb", None), *present(rows)]:
        runs = defaults(rows, method, theta)
        if len(runs) >= 2:
            rate = slope([r["dofs"] for r in runs], [r["error"] for r in runs])
            lines.append(f"{label(method, theta)} (default): error ∝ N^{rate:.2f}")
    return lines


# ------------------------------------------------------------------------------ charts
COLOURS = {
    "penalty": "tab:red",
    "augmented_lagrangian": "tab:green",
    "nitsche θ=1": "tab:purple",
    "nitsche θ=-1": "tab:orange",
}


def chart(problem: str, rows: list[dict], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    meshes = sorted({r["dofs"] for r in rows})
    shades = np.linspace(0.35, 1.0, len(meshes))
    for dofs, alpha in zip(meshes, shades):
        fb = next(r for r in rows if r["dofs"] == dofs and r["method"] == "fb")
        axes[0].plot(fb["seconds"], fb["error"], "k*", ms=12, alpha=alpha)
        for method, theta in VARIANTS:
            name = label(method, theta)
            runs = [
                r
                for r in rows
                if r["dofs"] == dofs
                and r["method"] == method
                and (theta is None or r["theta"] == theta)
                and r["converged"]
            ]
            if not runs:
                continue
            kw = {"color": COLOURS[name], "alpha": alpha, "ms": 3}
            kw["label"] = name if dofs == meshes[-1] else None
            for ax, x, y in (
                (axes[0], "seconds", "error"),
                (axes[1], "value", "dist_fb"),
                (axes[2], "value", "penetration_rel"),
            ):
                ax.plot([r[x] for r in runs], [max(r[y], 1e-16) for r in runs], "o-", **kw)
    axes[0].plot([], [], "k*", ms=10, label="fb")
    axes[0].set(
        xscale="log",
        yscale="log",
        xlabel="wall time [s]",
        ylabel=(
            "tangential traction error (L², vs Cattaneo–Mindlin)"
            if problem == "cattaneo"
            else "energy error" + (" (vs refined fb)" if "hertz" in problem else "")
        ),
        title=f"{problem}: error against time (lighter: coarser mesh)",
    )
    axes[1].set(
        xscale="log",
        yscale="log",
        xlabel="parameter ε₀ / r₀ / γ₀",
        ylabel="‖λ_t − λ_t,fb‖ / ‖λ_t,fb‖"
        if problem == "cattaneo"
        else "|||u − u_fb||| / |||u_fb|||",
        title="distance to the exact-constraint solution",
    )
    ref = np.array([1e1, 1e8])
    axes[1].plot(ref, 1e-2 * ref[0] / ref, "k:", lw=1, label="slope −1")
    axes[2].set(
        xscale="log",
        yscale="log",
        xlabel="parameter ε₀ / r₀ / γ₀",
        ylabel="max penetration / max |u|",
        title="largest penetration",
    )
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    print(f"wrote {out}", flush=True)


def convergence_chart(all_rows: dict[str, list[dict]], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [p for p in ("A", "C", "hertz2d", "hertz3d") if p in all_rows]
    if not names:  # Cattaneo–Mindlin alone: its error is a traction's, charted on its own
        return
    fig, axes = plt.subplots(1, len(names), figsize=(5 * len(names), 4.5), squeeze=False)
    for ax, problem in zip(axes[0], names):
        rows = all_rows[problem]
        for method, theta in [("fb", None), *VARIANTS]:
            name = label(method, theta)
            runs = defaults(rows, method, theta)
            ax.loglog(
                [r["dofs"] for r in runs],
                [r["error"] for r in runs],
                "*-" if method == "fb" else "o--",
                color="k" if method == "fb" else COLOURS[name],
                label=name + ("" if method == "fb" else " (default)"),
                ms=8 if method == "fb" else 4,
            )
        ax.set(xlabel="DoFs", ylabel="energy error", title=problem)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    print(f"wrote {out}", flush=True)


def read_csv(path: Path) -> list[dict]:
    """The rows of a CSV this script wrote, numbers as numbers."""
    import csv

    def value(v: str):
        if v in ("True", "False"):
            return v == "True"
        try:
            return float(v)
        except ValueError:
            return v

    with open(path, newline="") as fh:
        return [{k: value(v) for k, v in r.items()} for r in csv.DictReader(fh)]


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", default="demos/results/baselines")
    ap.add_argument("--problems", nargs="+", default=list(PROBLEMS), choices=list(PROBLEMS))
    ap.add_argument("--repeat", type=int, default=2, help="fb timings per method sweep")
    ap.add_argument("--levels", type=int, default=None, help="use the first N meshes only")
    ap.add_argument("--quick", action="store_true", help="every third parameter, 2 meshes")
    args = ap.parse_args()
    out = Path(args.out)
    all_rows: dict[str, list[dict]] = {}
    for problem in args.problems:
        scene_name, levels = PROBLEMS[problem]
        levels = levels[: 2 if args.quick else args.levels]
        rows: list[dict] = []
        for overrides in levels:
            kind = CattaneoMesh if problem == "cattaneo" else Mesh
            rows += sweep(kind(problem, scene_name, overrides, args.repeat), args.quick)
        all_rows[problem] = rows
        save_csv(out / f"{problem}.csv", rows)
        if MPI.COMM_WORLD.rank == 0:
            print(
                f"\n{problem}: the parameter for fb's accuracy (|||u - u_fb||| <= 1 % of its error)"
            )
            for entry in equal_accuracy(rows):
                b = entry["best"]
                text = (
                    "not reached in the sweep"
                    if b is None
                    else f"{b['parameter']} = {b['value']:g}: {b['ratio']:.2f}× fb "
                    f"({b['newton_iterations']} Newton, {b['outer_iterations']} outer)"
                )
                print(f"  {entry['dofs']:7d} DoFs  {entry['variant']:22s} {text}")
            for line in orders(rows):
                print("  " + line)
            chart(problem, rows, out / f"{problem}.png")
    if MPI.COMM_WORLD.rank == 0 and all_rows:  # every problem whose CSV is in the folder
        for problem in PROBLEMS:
            if problem not in all_rows and (out / f"{problem}.csv").is_file():
                all_rows[problem] = read_csv(out / f"{problem}.csv")
        convergence_chart(all_rows, out / "convergence.png")


if __name__ == "__main__":
    main()
