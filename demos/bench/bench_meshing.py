"""Meshing the parametric gmsh scenes, and the accuracy of the sphere on a block (issue 29).

    python demos/bench/bench_meshing.py mesh [--kinds ...] [--h-contact ...] [--variants ...]
    mpirun -n 2 python demos/bench/bench_meshing.py hertz [--h-contact ...] [--variants ...]
    mpirun -n 2 python demos/bench/bench_meshing.py refined

Each part prints its table and writes CSV to demos/results/meshing/ (rank 0); rows are
merged by their key, so a run of one more size or variant keeps the others.

* ``mesh.csv`` — each builder (sphere_on_block, sphere_octant: ``two_body_hertz_3d`` /
  ``hertz_3d``'s h, zone; half_disks, quarter_disk: ``two_body_hertz_2d`` / ``hertz_2d``'s)
  with each set of gmsh options (``--variants``, :data:`VARIANTS`; ``chosen`` is what
  :mod:`contact.setup.geometry` uses), in one process: gmsh's meshing alone (wall and CPU
  seconds), the whole builder (gmsh and the distribution by ``dolfinx.io.gmsh``), vertices,
  cells, the worst angle (:func:`contact.setup.geometry.worst_angle`: dihedral in 3D) and whether
  building twice gives the same mesh (``repeatable``; ``--repeat 1`` builds once);
* ``hertz.csv`` — ``two_body_hertz_3d`` at gmsh sizes ``h_contact`` with a 3D variant, on
  the ranks it runs on: ``contact.load_scene`` (wall, max over ranks; CPU, summed over
  ranks) with gmsh's part on rank 0, one solve (fb, grid sequencing ``auto``: the coarse
  levels' DoFs, Newton and Krylov iterations, wall and CPU), DoFs, and the errors of the
  contact radius a and of the peak
  pressure p0 against Hertz: p0 as reported (the patch average,
  :func:`contact.post.hertz.patch_average`) and the largest nodal value;
* ``refined.csv`` — ``two_body_hertz_3d`` as shipped (Dörfler refinement by
  ``dolfinx.mesh.refine``, four levels to 340k DoFs): per level the DoFs, a error, the
  patch-averaged and the nodal p0 errors, and the rms deviation of the nodal and of the
  patch-averaged pressure from Hertz's within 0.8 a (relative to p0).

The machine is shared: ``uptime`` is printed with each part; compare CPU seconds when the
load is high.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import os
import sys
import time
from pathlib import Path
from unittest import mock

import contact
from contact.post.hertz import patch_average
from contact.post.reference import compare
from contact.setup import geometry
from contact.setup.config import load_config
from contact.setup.posed import posed_of
from contact.solvers import owned_residual

import numpy as np
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "demos" / "results" / "meshing"
comm = MPI.COMM_WORLD
QUIET = ["output.verbose=false"]

#: gmsh options to compare, by name, for the tetrahedra (3D) and the triangles (2D); they
#: replace :data:`contact.setup.geometry.TETRAHEDRA` / :data:`~contact.setup.geometry.TRIANGLES`
VARIANTS = {
    3: {
        "chosen": dict(geometry.TETRAHEDRA),
        "delaunay+netgen": {
            "Mesh.Algorithm3D": 1,
            "General.NumThreads": 1,
            "Mesh.OptimizeNetgen": 1,
        },
        "delaunay": {"Mesh.Algorithm3D": 1, "General.NumThreads": 1},
        "hxt+optimise": {**geometry.TETRAHEDRA, "Mesh.OptimizeThreshold": 0.45},
        "hxt 2 threads": {**geometry.TETRAHEDRA, "General.NumThreads": 2},
    },
    2: {
        "chosen": dict(geometry.TRIANGLES),
        "1 thread": {**geometry.TRIANGLES, "Mesh.MaxNumThreads2D": 1},
        "delaunay": {**geometry.TRIANGLES, "Mesh.Algorithm": 5},
    },
}
#: builder -> (scene file whose h, zone it takes, dimension)
KINDS = {
    "sphere_on_block": ("two_body_hertz_3d.yaml", 3),
    "sphere_octant": ("hertz_3d.yaml", 3),
    "half_disks": ("two_body_hertz_2d.yaml", 2),
    "quarter_disk": ("hertz_2d.yaml", 2),
}


def say(*args) -> None:
    if comm.rank == 0:
        print(*args, flush=True)


def load() -> str:
    return f"load average {os.getloadavg()[0]:.2f}"


def write(name: str, rows: list[dict], key: tuple[str, ...]) -> None:
    """Rows to OUT/name, keeping the rows of an existing file with other key values."""
    if comm.rank != 0 or not rows:
        return
    mine = {tuple(str(r[k]) for k in key) for r in rows}
    old = []
    if (OUT / name).is_file():
        with open(OUT / name) as fh:
            old = [r for r in csv.DictReader(fh) if tuple(r[k] for k in key) not in mine]
    fields = list(rows[0]) + [k for r in old for k in r if k not in rows[0]]
    OUT.mkdir(parents=True, exist_ok=True)
    with open(OUT / name, "w", newline="") as fh:
        out = csv.DictWriter(fh, fieldnames=list(dict.fromkeys(fields)), restval="")
        out.writeheader()
        out.writerows(old + rows)
    print(f"wrote {OUT / name}", flush=True)


def table(rows: list[dict]) -> None:
    if rows:
        say("  ".join(f"{k:>14s}" for k in rows[0]))
        for r in rows:
            say(
                "  ".join(
                    f"{v:>14.4g}" if isinstance(v, float) else f"{str(v):>14s}" for v in r.values()
                )
            )


class GmshClock:
    """Wall and CPU seconds spent in ``gmsh.model.mesh.generate`` (rank 0) while active."""

    def __enter__(self):
        import gmsh

        self.wall = self.cpu = 0.0
        generate = gmsh.model.mesh.generate

        def timed(dim=3):
            t, c = time.perf_counter(), time.process_time()
            generate(dim)
            self.wall += time.perf_counter() - t
            self.cpu += time.process_time() - c

        self._patch = mock.patch.object(gmsh.model.mesh, "generate", timed)
        self._patch.start()
        return self

    def __exit__(self, *exc):
        self._patch.stop()


def options(dim: int, variant: str):
    """Replace the builders' gmsh options of dimension ``dim`` by ``variant``'s."""
    defaults = geometry.TETRAHEDRA if dim == 3 else geometry.TRIANGLES
    return mock.patch.dict(defaults, VARIANTS[dim][variant], clear=True)


def build(kind: str, h_contact: float):
    """The builder's mesh at ``h_contact`` (one process), the rest of the sizes from its scene."""
    cfg = load_config(ROOT / "configs" / KINDS[kind][0], QUIET + [f"mesh.h_contact={h_contact}"])
    m = cfg.mesh
    sizes = (m.h, m.h_contact, m.zone)
    if kind == "sphere_on_block":
        return geometry.sphere_on_block(MPI.COMM_SELF, m.radius, m.block, *sizes)[0]
    if kind == "half_disks":
        return geometry.half_disks(
            MPI.COMM_SELF, m.radius, m.radius2 or m.radius, *sizes, m.overlap or 0.0
        )[0]
    return getattr(geometry, kind)(MPI.COMM_SELF, m.radius, *sizes)[0]


def fingerprint(msh) -> str:
    """A hash of the sorted vertex coordinates (the same mesh, whatever its numbering)."""
    X = np.round(msh.geometry.x, 12)
    return hashlib.sha1(X[np.lexsort(X.T[::-1])].tobytes()).hexdigest()[:12]


def mesh_part(
    kinds: list[str], sizes: dict[str, list[float]], variants: list[str] | None, repeat: int
) -> None:
    if comm.rank != 0:
        return
    rows = []
    for kind in kinds:
        dim = KINDS[kind][1]
        for h_contact in sizes[kind]:
            for variant in variants or list(VARIANTS[dim]):
                if variant not in VARIANTS[dim]:
                    continue
                prints = []
                for _ in range(repeat):
                    with options(dim, variant), GmshClock() as clock:
                        t, c = time.perf_counter(), time.process_time()
                        msh = build(kind, h_contact)
                        wall, cpu = time.perf_counter() - t, time.process_time() - c
                    prints.append(fingerprint(msh))
                row = {
                    "kind": kind,
                    "h_contact": h_contact,
                    "variant": variant,
                    "vertices": msh.topology.index_map(0).size_global,
                    "cells": msh.topology.index_map(dim).size_global,
                    "gmsh_wall": round(clock.wall, 2),
                    "gmsh_cpu": round(clock.cpu, 2),
                    "builder_wall": round(wall, 2),
                    "builder_cpu": round(cpu, 2),
                    "worst_angle": round(geometry.worst_angle(msh), 2),
                    "repeatable": "" if repeat < 2 else len(set(prints)) == 1,
                    "load": round(os.getloadavg()[0], 2),
                }
                rows.append(row)
                print(
                    f"{kind} h_contact {h_contact} {variant}: {row['vertices']} vertices, "
                    f"gmsh {row['gmsh_wall']} s ({row['gmsh_cpu']} s CPU), builder "
                    f"{row['builder_wall']} s, worst angle {row['worst_angle']}°, repeatable "
                    f"{row['repeatable']} ({load()})",
                    flush=True,
                )
    table(rows)
    write("mesh.csv", rows, ("kind", "h_contact", "variant"))


def sphere_pressures(scene, result) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ρ, nodal pressure p_i, patch average p̄_i) of the slave nodes, gathered on every rank."""
    p = result.problem
    on = slice(0, p.data.pair_nodes)
    nodes = p.constraint.dofs[on] // p.V.dofmap.index_map_bs
    X = p.V.tabulate_dof_coordinates()[nodes]
    pressure = p.pressure(owned_residual(result))[on]
    smooth = patch_average(posed_of(scene), p.V, nodes, pressure)
    rho = np.hypot(X[:, 0], X[:, 1])
    return tuple(np.concatenate(comm.allgather(v)) for v in (rho, pressure, smooth))


def rms_to_hertz(values: dict, rho: np.ndarray, pressure: np.ndarray) -> float:
    """The rms of p − p_Hertz over the nodes within 0.8 a, relative to Hertz's p0."""
    hertz = values["hertz_p0"] * np.sqrt(np.maximum(0.0, 1 - (rho / values["hertz_a"]) ** 2))
    inside = rho < 0.8 * values["hertz_a"]
    return float(np.sqrt(np.mean((pressure - hertz)[inside] ** 2)) / values["hertz_p0"])


def errors(v: dict, rho: np.ndarray, pressure: np.ndarray, smooth: np.ndarray) -> dict:
    """The columns a_error, p0_error, p0_nodal_error, rms_nodal, rms_patch."""
    return {
        "a_error": v["a_error"],
        "p0_error": v["p0_error"],
        "p0_nodal_error": v["p0_nodal_error"],
        "rms_nodal": rms_to_hertz(v, rho, pressure),
        "rms_patch": rms_to_hertz(v, rho, smooth),
    }


def hertz_part(sizes: list[float], variants: list[str]) -> None:
    rows = []
    for variant in variants:
        for h_contact in sizes:
            with options(3, variant), GmshClock() as clock:
                t, c = time.perf_counter(), time.process_time()
                scene = contact.load_scene(
                    ROOT / "configs" / "two_body_hertz_3d.yaml",
                    QUIET + [f"mesh.h_contact={h_contact}", "adapt=null"],
                )
                load_wall, load_cpu = time.perf_counter() - t, time.process_time() - c
            t, c = time.perf_counter(), time.process_time()
            r = contact.solve(scene, method="fb", verbose=False)
            solve_wall, solve_cpu = time.perf_counter() - t, time.process_time() - c
            v = compare(posed_of(scene), r).values
            rho, pressure, smooth = sphere_pressures(scene, r)
            gmsh_wall, gmsh_cpu = comm.bcast((clock.wall, clock.cpu), root=0)
            row = {
                "variant": variant,
                "h_contact": h_contact,
                "ranks": comm.size,
                "dofs": r.dofs,
                "load_wall": round(comm.allreduce(load_wall, op=MPI.MAX), 2),
                "load_cpu": round(comm.allreduce(load_cpu, op=MPI.SUM), 2),
                "gmsh_wall": round(gmsh_wall, 2),
                "gmsh_cpu": round(gmsh_cpu, 2),
                "worst_angle": round(geometry.worst_angle(scene.mesh), 2),
                "coarse_dofs": " ".join(str(level.dofs) for level in r.sequence),
                "newton": f"{r.iterations}+{r.polish_solves}",
                "krylov": r.krylov_iterations,
                "solve_wall": round(comm.allreduce(solve_wall, op=MPI.MAX), 1),
                "solve_cpu": round(comm.allreduce(solve_cpu, op=MPI.SUM), 1),
                "converged": r.converged,
                **errors(v, rho, pressure, smooth),
                "load": round(os.getloadavg()[0], 2),
            }
            rows.append(row)
            say(
                f"{variant} h_contact {h_contact}: {r.dofs} DoFs, load_scene {row['load_wall']} s "
                f"(gmsh {row['gmsh_wall']} s), solve {row['solve_wall']} s, "
                f"a {100 * v['a_error']:+.2f}%, p0 {100 * v['p0_error']:+.2f}% "
                f"(nodal {100 * v['p0_nodal_error']:+.2f}%) ({load()})"
            )
    table(rows)
    write("hertz.csv", rows, ("variant", "h_contact", "ranks"))


def refined_part() -> None:
    rows = []
    scene = contact.load_scene(ROOT / "configs" / "two_body_hertz_3d.yaml", QUIET)

    def on_level(level):
        v = compare(level.posed, level.result).values
        rho, pressure, smooth = sphere_pressures(level.scene, level.result)
        rows.append(
            {
                "level": level.index,
                "ranks": comm.size,
                "dofs": level.result.dofs,
                **errors(v, rho, pressure, smooth),
            }
        )

    contact.adapt(scene, method="fb", on_level=on_level, verbose=False)
    say(f"two_body_hertz_3d, Dörfler refinement, {comm.size} ranks ({load()})")
    table(rows)
    write("refined.csv", rows, ("level", "ranks"))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("part", choices=("mesh", "hertz", "refined"))
    parser.add_argument("--kinds", nargs="+", choices=list(KINDS), default=list(KINDS))
    parser.add_argument(
        "--h-contact",
        type=float,
        nargs="+",
        default=None,
        help="mesh: sizes for every kind (default: 0.005 and 0.0025 for "
        "sphere_on_block, 0.005 for sphere_octant, 0.004 for half_disks, "
        "0.001 for quarter_disk); hertz: default 0.01 0.005 0.0025",
    )
    parser.add_argument(
        "--variants",
        nargs="+",
        default=None,
        help=f"mesh: of {', '.join(sorted(set(VARIANTS[2]) | set(VARIANTS[3])))}"
        " (default all); hertz: 3D ones (default chosen)",
    )
    parser.add_argument(
        "--repeat", type=int, default=2, help="mesh: builds of each mesh (repeatable column)"
    )
    args = parser.parse_args(argv)
    say(f"{args.part}: {comm.size} rank(s), {load()}")
    if args.part == "mesh":
        default = {
            "sphere_on_block": [0.005, 0.0025],
            "sphere_octant": [0.005],
            "half_disks": [0.004],
            "quarter_disk": [0.001],
        }
        sizes = {k: args.h_contact or default[k] for k in args.kinds}
        mesh_part(args.kinds, sizes, args.variants, args.repeat)
    elif args.part == "hertz":
        hertz_part(args.h_contact or [0.01, 0.005, 0.0025], args.variants or ["chosen"])
    else:
        refined_part()


if __name__ == "__main__":
    main(sys.argv[1:])
