"""Two bodies in contact (mortar coupling with dual multipliers): the figures of issue 13.

    python demos/bench/bench_two_bodies.py patch           # patch tests 2D / 3D, every method
    python demos/bench/bench_two_bodies.py cylinders       # two cylinders: adaptive, slave/master
    mpirun -n 2 python demos/bench/bench_two_bodies.py sphere [--h-contact 0.01 0.005 ...]
    python demos/bench/bench_two_bodies.py sphere_degrees  # the sphere with P1 and P2, η
    python demos/bench/bench_two_bodies.py p1_start [--h-contact 0.1 0.05]  # P2 cold / from P1
    python demos/bench/bench_two_bodies.py p1_start_floating  # the same, P2 patch tests
    python demos/bench/bench_two_bodies.py cattaneo [--h-contact 0.02 0.01]   # partial slip
    python demos/bench/bench_two_bodies.py p2 [--h-contact 0.1 0.05 0.025]   # P2, curved cells
    python demos/bench/bench_two_bodies.py p2sphere [--h-contact 0.04 0.02]   # the same in 3D

Each part prints its table and writes CSV to demos/results/two_bodies/ (rank 0):

* ``patch.csv`` — contact patch test (uniform pressure p across non-matching meshes):
  max_i |λ_i + p| / p on the slave nodes and on the master nodes, per method;
* ``cylinders_levels.csv`` — two cylinders R_c = 8, E = 200, ν = 0.3, Dörfler refinement
  with nested iteration (fb): DoFs, Newton iterations + polishing solves, seconds, η, the
  errors of the half-width a and the peak pressure p0 against Hertz (R = R_c/2,
  E* = E/(2(1 − ν²))), and the interface force balance;
* ``cylinders_methods.csv`` — every method on the final mesh, cold (u = 0) and nested,
  iterations, seconds and the largest nodal difference to vinewtonrsls from u = 0;
* ``slave_master.csv`` — the same scene with the other surface as slave (2D: the final
  adaptive mesh size, fixed gmsh mesh; 3D: one gmsh mesh): force, a, p0 and the relative
  L² difference of the two pressure profiles;
* ``sphere.csv`` — a sphere on a block (quarter model), gmsh meshes of decreasing
  ``h_contact`` (no refinement: gmsh's own meshes give smoother nodal pressures than
  refined ones), on the ranks it runs on: DoFs, Newton iterations, seconds, a and p0
  errors, and the rms deviation of the nodal pressure from Hertz's within 0.8 a (rows are
  merged by mesh size and rank count, so a run of one more size keeps the others);
* ``sphere_degrees.csv`` — the sphere on a block with P1 and with P2 (``run`` gmsh: one
  solve on gmsh meshes of decreasing ``h_contact``; ``run`` dorfler: the adaptive loop from
  h_contact = 0.05 with the residual estimator): DoFs, force, strain energy E_h, η, the a
  and p0 errors against Hertz, the force's error against the limit of the P2 gmsh
  sequence and the energy error √(2 |E_h − E|) against that sequence's limit E, η over it;
* ``p1_start.csv`` — P2 pairs started cold (``solver.sequence: off``) and from P1 on the
  same mesh (``auto``): the sphere on a block at the given ``h_contact`` and the 2D Hertz
  pair at 0.05, fb; Newton steps + polishing solves and seconds of each (the coarse levels
  included), their ratio cold / P1-start, and the largest nodal difference of the two
  answers relative to the largest displacement, and the CPU seconds (summed over ranks)
  and their ratio; ``p1_start_floating.csv`` the same for the contact patch tests
  (``configs/two_body_patch_2d.yaml``, ``two_body_patch_3d.yaml``) at P2, whose upper block
  contact alone holds and whose P1 solution is P2's;
* ``cattaneo.csv`` — two cylinders with Coulomb friction F = 0.3, the load path of
  ``configs/two_body_cattaneo_2d.yaml`` (P, then Q as a body force) on meshes of decreasing
  ``h_contact``: per step Q/(F P), c/a against √(1 − Q/(F P)) and the L² error of the
  tangential traction; ``cattaneo_traction.csv`` and ``cattaneo_traction.png`` the computed
  and the analytic traction at Q/(F P) = 0.25, 0.5, 0.75 on the finest mesh;
* ``cylinders_p2.csv`` — the two cylinders (``mesh.h`` = 2, ``zone`` = 1, method min) on
  gmsh meshes of decreasing ``h_contact``, P1, P2 on straight cells and P2 on curved cells
  (``mesh.geometry_degree: 2``): DoFs, the largest deviation of a slave node's pressure from
  Hertz's within 0.8 a and the peak's (both over p0), the contact force, a's error and the
  interface balance; ``sphere_p2.csv`` the same for the sphere on a block
  (``configs/two_body_hertz_3d.yaml``), with the rms deviation within 0.8 a too.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import contact
from contact.models.mortar import master_pressure
from contact.post.interface import interface_resultants, output_dofs
from contact.post.reference import compare
from contact.setup.build import build_problem
from contact.setup.posed import posed_of

import numpy as np
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "demos" / "results" / "two_bodies"
comm = MPI.COMM_WORLD
METHODS = ("fb", "min", "blend", "vinewtonrsls", "vinewtonssls")
QUIET = ["output.verbose=false"]


def say(*args):
    if comm.rank == 0:
        print(*args, flush=True)


def write(name: str, rows: list[dict], key: tuple[str, ...] = ()) -> None:
    """Rows to OUT/name; with ``key``, the rows of an existing file with other key values
    are kept (a run of one more mesh size adds its rows)."""
    if comm.rank == 0 and key and (OUT / name).is_file():
        with open(OUT / name) as fh:
            old = [
                r
                for r in csv.DictReader(fh)
                if tuple(str(r[k]) for k in key)
                not in {tuple(str(n[k]) for k in key) for n in rows}
            ]
        rows = sorted(
            old + [{k: str(v) for k, v in r.items()} for r in rows],
            key=lambda r: [float(r[k]) for k in key],
        )
    if comm.rank == 0 and rows:
        OUT.mkdir(parents=True, exist_ok=True)
        with open(OUT / name, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        print(f"wrote {OUT / name}", flush=True)


def table(rows: list[dict]) -> None:
    if not rows:
        return
    keys = list(rows[0])
    say("  ".join(f"{k:>12s}" for k in keys))
    for r in rows:
        say(
            "  ".join(
                f"{v:>12.4g}" if isinstance(v, float) else f"{str(v):>12s}" for v in r.values()
            )
        )


def slave_pressure(result) -> tuple[np.ndarray, np.ndarray]:
    """(coordinates, pressure −λ_i) of the slave nodes, gathered on every rank."""
    p = result.problem
    bs = p.V.dofmap.index_map_bs
    nodes = p.constraint.dofs[: p.data.pair_nodes] // bs
    X = p.V.tabulate_dof_coordinates()[nodes]
    lam = -result.lmbda_h.x.array[output_dofs(p, nodes)]
    X = np.vstack(comm.allgather(X))
    return X, np.concatenate(comm.allgather(lam))


def patch() -> None:
    rows = []
    for dim in (2, 3):
        scene = contact.load_scene(ROOT / "configs" / f"two_body_patch_{dim}d.yaml", QUIET)
        problem = build_problem(scene)
        for method in METHODS:
            t0 = time.perf_counter()
            r = contact.solve(scene, method=method, problem=problem, verbose=False)
            seconds = time.perf_counter() - t0
            lam = r.lmbda_h.x.array[problem.output.nodes]
            lam_m = master_pressure(r).x.array
            err = comm.allreduce(float(np.max(np.abs(lam + 0.01))), op=MPI.MAX) / 0.01
            err_m = (
                comm.allreduce(
                    float(np.max(np.abs(lam_m[lam_m != 0] + 0.01), initial=0.0)), op=MPI.MAX
                )
                / 0.01
            )
            rows.append(
                {
                    "dim": dim,
                    "method": method,
                    "dofs": r.dofs,
                    "ranks": comm.size,
                    "converged": r.converged,
                    "newton": r.iterations,
                    "polish": r.polish_solves,
                    "seconds": round(seconds, 3),
                    "slave_error": err,
                    "master_error": err_m,
                }
            )
    table(rows)
    write("patch.csv", rows)


def cylinders(max_dofs: int) -> None:
    scene = contact.load_scene(ROOT / "configs" / "two_body_hertz_2d.yaml", QUIET)
    rows, start = [], time.perf_counter()

    def on_level(level):
        res = {
            **interface_resultants(level.posed, level.result),
            **compare(level.posed, level.result).values,
        }
        rows.append(
            {
                "level": level.index,
                "dofs": level.result.dofs,
                "newton": level.result.iterations,
                "polish": level.result.polish_solves,
                "seconds_solve": round(level.seconds["solve"], 3),
                "seconds_total": round(time.perf_counter() - start, 2),
                "eta": level.estimate.eta,
                "a_error": res["a_error"],
                "p0_error": res["p0_error"],
                "a_over_Rc": res["contact_half_width"] / 8.0,
                "balance": res["interface_balance_error"],
            }
        )

    levels = contact.adapt(
        scene,
        method="fb",
        strategy="dorfler",
        theta=0.5,
        max_levels=12,
        max_dofs=max_dofs,
        on_level=on_level,
        verbose=False,
    ).levels
    say("two cylinders, Dörfler (θ = 0.5), fb, nested iteration")
    table(rows)
    write("cylinders_levels.csv", rows)

    # every method on the final mesh (refined again from the previous level, with the nested
    # guess on it), cold and nested
    previous = levels[-2]
    final_scene, nested = contact.refine(
        previous.scene, contact.mark(previous.estimate.eta_T, "dorfler", 0.5), previous.result.u_h
    )
    problem = build_problem(final_scene)
    # from u = 0
    ref = contact.solve(final_scene, method="vinewtonrsls", problem=problem, verbose=False)
    u_ref = ref.u_h.x.array.copy()
    methods = []
    for method in METHODS:
        for start_name, u0 in (("cold", None), ("nested", nested)):
            t0 = time.perf_counter()
            r = contact.solve(
                final_scene, method=method, problem=problem, u0=u0, verbose=False, max_it=100
            )
            seconds = time.perf_counter() - t0
            diff = comm.allreduce(float(np.max(np.abs(r.u_h.x.array - u_ref))), op=MPI.MAX)
            methods.append(
                {
                    "method": method,
                    "start": start_name,
                    "dofs": r.dofs,
                    "converged": r.converged,
                    "newton": r.iterations,
                    "polish": r.polish_solves,
                    "seconds": round(seconds, 3),
                    "max_diff_to_vinewtonrsls": diff,
                }
            )
    say(f"\nevery method on the final mesh ({ref.dofs} DoFs)")
    table(methods)
    write("cylinders_methods.csv", methods)
    swap(
        "2d",
        ROOT / "configs" / "two_body_hertz_2d.yaml",
        ["mesh.h_contact=0.01", "mesh.zone=1.0"],
        [
            "boundaries.slave.where=abs(x) < 3 and y < 1",
            "boundaries.master.where=abs(x) < 2 and y > -1",
        ],
        "slave_master.csv",
    )


def swap(label: str, path: Path, mesh: list[str], parts: list[str], csv_name: str) -> None:
    """The scene as shipped against the other surface as slave (same meshes)."""
    rows, profiles = [], []
    for which, extra in (
        ("as shipped", []),
        ("swapped", parts + ["pairs=[{slave: master, master: slave}]"]),
    ):
        scene = contact.load_scene(path, QUIET + mesh + extra + ["adapt=null"])
        t0 = time.perf_counter()
        r = contact.solve(scene, method="min", verbose=False)
        seconds = time.perf_counter() - t0
        res = {**interface_resultants(posed_of(scene), r), **compare(posed_of(scene), r).values}
        X, pressure = slave_pressure(r)
        rho = (
            np.linalg.norm(X[:, :-1], axis=1)
            if X.shape[1] == 3 and label == "3d"
            else np.abs(X[:, 0])
        )
        order = np.argsort(rho)
        profiles.append((rho[order], pressure[order], res["hertz_a"]))
        rows.append(
            {
                "case": label,
                "slave": which,
                "dofs": r.dofs,
                "newton": r.iterations,
                "seconds": round(seconds, 2),
                "force": res["contact_force"],
                "a": res.get("contact_half_width", res.get("contact_radius")),
                "p0": res["peak_pressure"],
                "a_error": res["a_error"],
                "p0_error": res["p0_error"],
            }
        )
    # relative L² difference of the two profiles on [0, a] (each interpolated to a common grid)
    a = min(p[2] for p in profiles)
    grid = np.linspace(0.0, a, 400)
    curves = [np.interp(grid, rho, pres) for rho, pres, _ in profiles]
    diff = float(np.sqrt(np.mean((curves[0] - curves[1]) ** 2)) / np.sqrt(np.mean(curves[0] ** 2)))
    for row in rows:
        row["profile_L2_difference"] = diff
        row["force_difference"] = rows[1]["force"] / rows[0]["force"] - 1.0
    say(f"\n{label}: slave / master swapped (same meshes)")
    table(rows)
    write(csv_name, rows)


def sphere(sizes: list[float], swap_size: float | None) -> None:
    rows = []
    for h_contact in sizes:
        scene = contact.load_scene(
            ROOT / "configs" / "two_body_hertz_3d.yaml", QUIET + [f"mesh.h_contact={h_contact}"]
        )
        t0 = time.perf_counter()
        r = contact.solve(scene, method="fb", verbose=False)
        seconds = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        res = {**interface_resultants(posed_of(scene), r), **compare(posed_of(scene), r).values}
        X, pressure = slave_pressure(r)
        rho = np.hypot(X[:, 0], X[:, 1])
        hertz = res["hertz_p0"] * np.sqrt(np.maximum(0.0, 1 - (rho / res["hertz_a"]) ** 2))
        inside = rho < 0.8 * res["hertz_a"]
        rms = float(np.sqrt(np.mean((pressure - hertz)[inside] ** 2)) / res["hertz_p0"])
        rows.append(
            {
                "h_contact": h_contact,
                "dofs": r.dofs,
                "ranks": comm.size,
                "converged": r.converged,
                "newton": r.iterations,
                "polish": r.polish_solves,
                "seconds": round(seconds, 1),
                "a_error": res["a_error"],
                "p0_error": res["p0_error"],
                "pressure_rms": rms,
                "a_over_R": res["a_over_R"],
                "balance": res["interface_balance_error"],
            }
        )
        say(
            f"h_contact {h_contact}: {r.dofs} DoFs, {r.iterations}+{r.polish_solves} its, "
            f"{seconds:.1f} s, "
            f"a {100 * res['a_error']:+.2f}%, p0 {100 * res['p0_error']:+.2f}%, rms "
            f"{100 * rms:.2f}%"
        )
    table(rows)
    write("sphere.csv", rows, key=("h_contact", "ranks"))
    if swap_size is not None:
        swap(
            "3d",
            ROOT / "configs" / "two_body_hertz_3d.yaml",
            [f"mesh.h_contact={swap_size}"],
            # the block's top becomes the slave: the sphere's part must now cover it
            ["boundaries.slave.where=x*x + y*y < 0.16", "boundaries.master.where=x*x + y*y < 0.09"],
            "slave_master_3d.csv",
        )


def strain_energy(result) -> float:
    """½ ∫ σ(u_h) : ε(u_h) dx of the solution (both bodies; collective)."""
    import ufl
    from dolfinx import fem

    u = result.u_h
    sigma = result.problem.physics.flux(u)
    form = fem.form(0.5 * ufl.inner(sigma, ufl.sym(ufl.grad(u))) * ufl.dx)
    return comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)


def aitken(values: list[float]) -> float:
    """The limit of a sequence from its last three terms (Aitken's Δ²)."""
    a, b, c = values[-3:]
    return c - (c - b) ** 2 / ((c - b) - (b - a))


def sphere_degrees(p2_sizes: list[float], p1_sizes: list[float], max_dofs: int) -> None:
    """P1 and P2 on the sphere on a block: gmsh meshes of decreasing h_contact (the far field
    h = 0.25 of the scene), then Dörfler's loop at each degree from h_contact = 0.05.  The
    references are the limits of the P2 gmsh sequence (Aitken's Δ² on its last three
    forces and strain energies); the loop's error is √(2 |E_h − E|), E the strain energy."""
    path = ROOT / "configs" / "two_body_hertz_3d.yaml"
    rows = []
    for degree, sizes in ((2, p2_sizes), (1, p1_sizes)):
        for h_contact in sizes:
            scene = contact.load_scene(
                path, QUIET + ["adapt=null", f"mesh.degree={degree}", f"mesh.h_contact={h_contact}"]
            )
            t0 = time.perf_counter()
            r = contact.solve(scene, method="fb", verbose=False)
            seconds = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
            res = {**interface_resultants(posed_of(scene), r), **compare(posed_of(scene), r).values}
            rows.append(
                {
                    "run": "gmsh",
                    "degree": degree,
                    "h_contact": h_contact,
                    "level": 0,
                    "dofs": r.dofs,
                    "ranks": comm.size,
                    "converged": r.converged,
                    "newton": r.iterations,
                    "seconds": round(seconds, 1),
                    "force": r.contact_force,
                    "energy": strain_energy(r),
                    "eta": float("nan"),
                    "a_error": res["a_error"],
                    "p0_error": res["p0_error"],
                    "p0_nodal_error": res["p0_nodal_error"],
                    "balance": res["interface_balance_error"],
                }
            )
            say(f"P{degree} h_contact {h_contact}: {r.dofs} DoFs, {seconds:.1f} s")
    p2 = [r for r in rows if r["degree"] == 2]
    force, energy = aitken([r["force"] for r in p2]), aitken([r["energy"] for r in p2])
    for degree in (2, 1):
        scene = contact.load_scene(
            path,
            QUIET
            + [f"mesh.degree={degree}", "mesh.h_contact=0.05", f"adapt.max_dofs={max_dofs}"]
            + ["adapt.max_levels=8"],
        )

        def on_level(level, degree=degree):
            r = level.result
            res = {**interface_resultants(level.posed, r), **compare(level.posed, r).values}
            rows.append(
                {
                    "run": "dorfler",
                    "degree": degree,
                    "h_contact": 0.05,
                    "level": level.index,
                    "dofs": r.dofs,
                    "ranks": comm.size,
                    "converged": r.converged,
                    "newton": r.iterations,
                    "seconds": round(comm.allreduce(level.elapsed, op=MPI.MAX), 1),
                    "force": r.contact_force,
                    "energy": strain_energy(r),
                    "eta": level.estimate.eta,
                    "a_error": res["a_error"],
                    "p0_error": res["p0_error"],
                    "p0_nodal_error": res["p0_nodal_error"],
                    "balance": res["interface_balance_error"],
                }
            )
            say(f"P{degree} Dörfler: {r.dofs} DoFs, η {level.estimate.eta:.3g}")

        contact.adapt(scene, method="fb", verbose=False, on_level=on_level)
    for r in rows:
        r["force_error"] = r["force"] / force - 1.0
        r["energy_error"] = float(np.sqrt(2.0 * abs(r["energy"] - energy)))
        r["eta_over_error"] = r["eta"] / r["energy_error"]
        r["force_reference"], r["energy_reference"] = force, energy
    table(rows)
    write("sphere_degrees.csv", rows)


def p1_start(sizes: list[float]) -> None:
    """P2 pairs cold and started from P1 on the same mesh, in one process."""
    cases = [("two_body_hertz_3d", h) for h in sizes] + [("two_body_hertz_2d", 0.05)]
    rows = [cold_and_p1_start(name, h, ["adapt=null", f"mesh.h_contact={h}"]) for name, h in cases]
    table(rows)
    write("p1_start.csv", rows)


def p1_start_floating() -> None:
    """The contact patch tests at P2 (the upper block held by contact alone), cold and
    started from P1 on the same mesh, whose solution is P2's there."""
    rows = [cold_and_p1_start(name, "", []) for name in ("two_body_patch_2d", "two_body_patch_3d")]
    table(rows)
    write("p1_start_floating.csv", rows)


def cold_and_p1_start(name: str, h_contact, overrides: list[str]) -> dict:
    """One row of p1_start.csv: ``configs/<name>.yaml`` at P2 with ``overrides``, fb, cold
    (``solver.sequence: off``) and then ``auto``: steps, wall and CPU seconds (CPU: summed
    over ranks), their ratios and the largest nodal difference of the answers."""
    scene = contact.load_scene(
        ROOT / "configs" / f"{name}.yaml", QUIET + ["mesh.degree=2", *overrides]
    )
    runs = {}
    for sequence in ("off", "auto"):
        t0, c0 = time.perf_counter(), time.process_time()
        r = contact.solve(scene, method="fb", verbose=False, sequence=sequence)
        wall = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        runs[sequence] = (r, wall, comm.allreduce(time.process_time() - c0, op=MPI.SUM))
    (cold, t_cold, c_cold), (warm, t_warm, c_warm) = runs["off"], runs["auto"]
    u = cold.u_h.x.array
    diff = comm.allreduce(float(np.max(np.abs(warm.u_h.x.array - u))), op=MPI.MAX)
    scale = comm.allreduce(float(np.max(np.abs(u))), op=MPI.MAX)
    say(
        f"{name} P2 {h_contact}: cold / P1-start {t_cold / t_warm:.2f} (wall), "
        f"{c_cold / c_warm:.2f} (CPU)"
    )
    return {
        "scene": name,
        "h_contact": h_contact,
        "dofs": cold.dofs,
        "ranks": comm.size,
        "converged": cold.converged and warm.converged,
        "cold_newton": f"{cold.iterations}+{cold.polish_solves}",
        "p1_start_newton": f"{warm.iterations}+{warm.polish_solves}",
        "levels": " ".join(f"{lv.dofs}:{lv.newton_iterations}" for lv in warm.sequence),
        "cold_seconds": round(t_cold, 2),
        "p1_start_seconds": round(t_warm, 2),
        "ratio": t_cold / t_warm,
        "difference": diff / scale,
        "cold_cpu": round(c_cold, 2),
        "p1_start_cpu": round(c_warm, 2),
        "cpu_ratio": c_cold / c_warm,
    }


def cattaneo(sizes: list[float]) -> None:
    from contact.post.cattaneo import traction
    from contact.setup.run import run_load_path

    rows, profiles = [], None
    for h_contact in sizes:
        scene = contact.load_scene(
            ROOT / "configs" / "two_body_cattaneo_2d.yaml", QUIET + [f"mesh.h_contact={h_contact}"]
        )
        t0 = time.perf_counter()
        path = run_load_path(scene, verbose=False, keep_all=True)
        seconds = time.perf_counter() - t0
        profiles = []
        for step in path.steps:
            r, v = step.result, compare(step.posed, step.result).values
            rows.append(
                {
                    "h_contact": h_contact,
                    "dofs": r.dofs,
                    "t": step.time,
                    "newton": r.iterations,
                    "seconds_path": round(seconds, 2),
                    "Q_over_FP": v["Q_over_FP"],
                    "c_over_a": v["c_over_a"],
                    "c_over_a_theory": v["c_over_a_theory"],
                    "c_error": v["c_error"],
                    "q_error": v["q_error"],
                    "a_error": v["contact_half_width"] / v["hertz_a"] - 1.0,
                }
            )
            p = r.problem
            on = slice(0, p.data.pair_nodes)
            X = p.V.tabulate_dof_coordinates()[p.constraint.dofs[on] // p.V.dofmap.index_map_bs]
            lam_t = np.vstack(comm.allgather(r.friction["lambda_t_vec"][on]))
            profiles.append(
                (v, np.concatenate(comm.allgather(X[:, 0])), np.linalg.norm(lam_t, axis=1))
            )
    say("two cylinders, Coulomb F = 0.3: Cattaneo–Mindlin partial slip")
    table(rows)
    write("cattaneo.csv", rows)
    F = 0.3
    out = []
    for v, x, q in profiles[1:]:  # the finest mesh, Q > 0
        order = np.argsort(x)
        c = v["c_over_a_theory"] * v["hertz_a"]
        exact = traction(np.abs(x[order]), v["hertz_a"], c, v["hertz_p0"], F)
        out += [
            {"Q_over_FP": round(v["Q_over_FP"], 4), "x": xi, "q_h": qi, "q": ei}
            for xi, qi, ei in zip(x[order], q[order], exact)
        ]
    write("cattaneo_traction.csv", out)
    if comm.rank == 0:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(8, 4.6))
        for k, (v, x, q) in enumerate(profiles[1:]):
            order = np.argsort(x)
            a = v["hertz_a"]
            xs = np.linspace(-a, a, 600)
            ax.plot(
                xs,
                traction(np.abs(xs), a, v["c_over_a_theory"] * a, v["hertz_p0"], F),
                "-",
                color=f"C{k}",
                lw=1,
                label=f"Cattaneo–Mindlin, Q/(F P) = {v['Q_over_FP']:.2f} (c/a = "
                f"{v['c_over_a_theory']:.3f})",
            )
            near = np.abs(x[order]) <= 1.3 * a
            ax.plot(
                x[order][near],
                q[order][near],
                "o",
                ms=2.5,
                color=f"C{k}",
                label=f"computed |λ_t| (c/a = {v['c_over_a']:.3f}, L² error "
                f"{100 * v['q_error']:.1f}%)",
            )
        v = profiles[-1][0]
        xs = np.linspace(-v["hertz_a"], v["hertz_a"], 600)
        ax.plot(
            xs,
            F * v["hertz_p0"] * np.sqrt(1 - (xs / v["hertz_a"]) ** 2),
            "k--",
            lw=0.8,
            label="F p(x) (Hertz)",
        )
        ax.set_xlabel("x (along the contact)")
        ax.set_ylabel("tangential traction")
        ax.set_title(f"two cylinders, Coulomb F = {F}, {path.steps[-1].result.dofs} DoFs")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower center")
        fig.tight_layout()
        fig.savefig(OUT / "cattaneo_traction.png", dpi=100)
        print(f"wrote {OUT / 'cattaneo_traction.png'}", flush=True)


def p2_cells(scene_file: str, sizes: list[float], mesh: list[str], csv_name: str) -> None:
    """P1, P2 on straight cells and P2 on curved cells of the same gmsh meshes of
    ``scene_file`` (``mesh``: its other mesh overrides), method min: the slave nodes'
    deviation from Hertz's pressure within 0.8 a (largest and rms, over p0) and the peak's."""
    rows = []
    for h_contact in sizes:
        for degree, geometry in ((1, 1), (2, 1), (2, 2)):
            overrides = [
                *QUIET,
                *mesh,
                f"mesh.h_contact={h_contact}",
                f"mesh.degree={degree}",
                f"mesh.geometry_degree={geometry}",
            ]
            scene = contact.load_scene(ROOT / "configs" / scene_file, overrides)
            t0 = time.perf_counter()
            r = contact.solve(scene, method="min", verbose=False)
            seconds = time.perf_counter() - t0
            posed = posed_of(scene)
            res = {**interface_resultants(posed, r), **compare(posed, r).values}
            X, pressure = slave_pressure(r)
            a, p0 = res["hertz_a"], res["hertz_p0"]
            radius = np.linalg.norm(X[:, : X.shape[1] - 1], axis=1)  # from the axis
            inner = radius < 0.8 * a
            error = (pressure[inner] - p0 * np.sqrt(1 - (radius[inner] / a) ** 2)) / p0
            rows.append(
                {
                    "h_contact": h_contact,
                    "degree": degree,
                    "cells": "curved" if geometry == 2 else "straight",
                    "dofs": r.dofs,
                    "converged": r.converged,
                    "nodal_max_error": float(np.max(np.abs(error))),
                    "nodal_rms_error": float(np.sqrt(np.mean(error**2))),
                    "peak_error": float(np.max(pressure) / p0 - 1),
                    "force": res["contact_force"],
                    "a_error": res["a_error"],
                    "balance": res["interface_balance_error"],
                    "seconds": round(seconds, 2),
                }
            )
    say(f"{scene_file}: P1, P2 on straight cells, P2 on curved cells (min)")
    table(rows)
    write(csv_name, rows)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "part",
        choices=(
            "patch",
            "cylinders",
            "sphere",
            "sphere_degrees",
            "p1_start",
            "p1_start_floating",
            "cattaneo",
            "p2",
            "p2sphere",
        ),
    )
    parser.add_argument(
        "--max-dofs",
        type=int,
        default=100000,
        help="cylinders, sphere_degrees: DoF budget of the adaptive runs",
    )
    parser.add_argument(
        "--h-contact",
        type=float,
        nargs="+",
        default=None,
        help="sphere (default 0.01 0.005 0.0035) / sphere_degrees (P2, default 0.1 0.05 0.025 "
        "0.0125) / p1_start (3D, default 0.1 0.05) / cattaneo (default 0.02 0.01) / p2 "
        "(default 0.1 0.05 0.025) / p2sphere (default 0.04 0.02): gmsh mesh sizes at the "
        "contact point",
    )
    parser.add_argument(
        "--h-contact-p1",
        type=float,
        nargs="+",
        default=None,
        help="sphere_degrees: the P1 mesh sizes (default 0.025 0.0125 0.009 0.00625)",
    )
    parser.add_argument(
        "--swap", type=float, default=None, help="sphere: h_contact of the slave/master comparison"
    )
    args = parser.parse_args(argv)
    if args.part == "patch":
        patch()
    elif args.part == "cylinders":
        cylinders(args.max_dofs)
    elif args.part == "cattaneo":
        cattaneo(args.h_contact or [0.02, 0.01])
    elif args.part == "p1_start":
        p1_start(args.h_contact or [0.1, 0.05])
    elif args.part == "p1_start_floating":
        p1_start_floating()
    elif args.part == "sphere_degrees":
        sphere_degrees(
            args.h_contact or [0.1, 0.05, 0.025, 0.0125],
            args.h_contact_p1 or [0.025, 0.0125, 0.009, 0.00625],
            args.max_dofs,
        )
    elif args.part == "p2":
        p2_cells(
            "two_body_hertz_2d.yaml",
            args.h_contact or [0.1, 0.05, 0.025],
            ["mesh.h=2.0", "mesh.zone=1.0"],
            "cylinders_p2.csv",
        )
    elif args.part == "p2sphere":
        p2_cells("two_body_hertz_3d.yaml", args.h_contact or [0.04, 0.02], [], "sphere_p2.csv")
    else:
        sphere(args.h_contact or [0.01, 0.005, 0.0035], args.swap)


if __name__ == "__main__":
    main(sys.argv[1:])
