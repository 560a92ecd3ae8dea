"""Finite deformation (issue 31): the energy line search on nonconvex and buckling cases, the
buckling strip against Euler, and the refinement study of the neo-Hookean cylinder.

    python demos/bench/bench_hyperelastic.py line_search   # plain Newton vs the energy search
    python demos/bench/bench_hyperelastic.py predictor     # tangent predictor vs plain start
    python demos/bench/bench_hyperelastic.py strip         # the strip's buckling load vs Euler
    python demos/bench/bench_hyperelastic.py refinement    # cylinder to 0.5 R, uniform refinement
    python demos/bench/bench_hyperelastic.py refinement --levels 5   # a level more (50k DoFs)
    python demos/bench/bench_hyperelastic.py refinement --top symmetry  # between two plates
    python demos/bench/bench_hyperelastic.py adaptive      # Dörfler vs uniform refinement
    python demos/bench/bench_hyperelastic.py adaptive --case indenter     # a rigid cylinder
    python demos/bench/bench_hyperelastic.py adaptive --case indentation  # (curved obstacles)
    mpirun -n 2 python demos/bench/bench_hyperelastic.py ball --mesh-size 0.0135  # 500k DoFs
    python demos/bench/bench_hyperelastic.py recouple      # mortar re-coupling: Aitken vs plain
    python demos/bench/bench_hyperelastic.py sequence      # grid sequencing of the first step
    python demos/bench/bench_hyperelastic.py drag          # Coulomb between bodies, 2D and 3D
    python demos/bench/bench_hyperelastic.py kink          # a tube kinked into self-contact
    python demos/bench/bench_hyperelastic.py pairs         # adapt and sequencing of two bodies

``line_search`` — St Venant–Kirchhoff (SVK) bodies solved with ``line_search: basic`` (plain
Newton, MUMPS LU: the behaviour before the energy search) and ``energy`` (the default for
this model, contact/solvers/energy_search.py), fb / min / blend: the arch of
tests/test_hyperelastic.py (a curved bottom y = 0.2 x² pressed by a rising plane, its flat
top clamped) to δ = 0.1 … 0.3 of its height 0.5 in one step without step cutting, its load
path to 0.2 in 10 steps with the default cuts, the SVK block pressed to 50 % in one step,
the buckling strip (configs/hyperelastic_strip.yaml), and — where the tangent stays
definite — the neo-Hookean cylinder (configs/hyperelastic_cylinder.yaml), whose CPU time is
compared in the same process (the smaller of two runs each).  Per run: converged, the
reason, Newton iterations (all steps), the pseudo-time reached, the last solution's
smallest det F and negative eigenvalues of K_T, and the outcome: ``stable`` (det F > 0, K_T
definite), ``inverted`` (det F ≤ 0 somewhere: not a deformation), ``unstable`` (K_T
indefinite), ``stopped`` (the energy search found no admissible step), or the SNES reason.

``predictor`` — ``solver.predictor`` none (each load step starts from the previous solution
with the new Dirichlet values and bounds) against auto (the tangent predictor, the default
for this model: contact/solvers/predictor.py): the arch's clamped top pushed 0.1 in one
step (the plain start inverts cells: a step cut), the neo-Hookean cylinder to 0.5 R in 1,
2, 5, 10 steps (fb, and vinewtonrsls in 10), the buckling strip; steps, cuts, Newton
iterations, CPU seconds.

``strip`` — the strip's critical load on P1 / P2 meshes: plain Newton's straight state at a
wall displacement t δ_E (one step from the reference state) and the inertia of its tangent,
t bisected in [0.9, 1.3] until the bracket between a definite and an indefinite tangent is
1e-4 wide.
Euler's load of a fixed–guided column (effective length L): P_E = π² E' I / L²,
E' = E / (1 − ν²) (plane strain), I = h³ / 12.

``refinement`` — configs/hyperelastic_cylinder.yaml (neo-Hookean) pressed to indentation
δ = 0.5 R in 10 steps on a uniform mesh (h = h_contact = 0.1) refined uniformly 0 … levels−1
times, its flat top held (``--top clamped``, the shipped scene) or a symmetry plane
(``--top symmetry``: a whole cylinder squeezed between two plates, each indenting it by δ;
no corner where the held top meets the free arc; ``contact.refine``: new arc nodes moved
onto the circle); per level the contact force at each step, and the same discrete problem
solved by PETSc's vinewtonrsls (the plane's constraint is a bound): the largest difference
of u_h (relative to max |u_h|) and of the forces at the load steps both reach.  The
observed rate of the force at δ = 0.5 R, log₂(|F_l − F_{l−1}| / |F_{l+1} − F_l|).
Writes refinement_<top>.csv and refinement_<top>.png.

``adaptive`` — ``adapt`` at finite strain: configs/block_on_plane.yaml made neo-Hookean
(E = 1, ν = 0.3), its clamped top pushed down by 10 % of the height in 2 load steps
(``load.adapt: end``: the adaptive loop at the last step, u and the step's state prolonged
to every level and the step solved again), from a coarse 8 × 2 mesh, refined uniformly
(``adapt.strategy: uniform``, 0 … uniform-levels − 1) and by Dörfler marking of the residual
estimator (θ = 0.5, 0 … levels − 1).  Both forces decrease monotonically under refinement,
so the finest force F_ref bounds the limit from above: per tolerance, the first level of each
strategy within it of F_ref and the ratio of their DoFs (errors against F_ref understate
both strategies' true errors alike), and the first Dörfler level whose force is below the
finest uniform level's (closer to the limit than it, a reference-free comparison).  Writes
adaptive.csv and adaptive.png.

``adaptive --case indenter`` / ``--case indentation`` — the same comparison against a rigid
cylinder, met on the current configuration (the estimator's contact terms with the normal
and gap of the deformed point): ``indenter`` is the Hertz-type scene of
tests/test_hyperelastic_adapt.py (a cylinder of radius 0.05 lowered 0.2 R into the unit
neo-Hookean half block on rollers, 4 steps, from 8 × 8: a contact zone a few hundredths of
the block wide), ``indentation`` the shipped configs/hyperelastic_indentation.yaml (radius
0.5 lowered 0.4 R into the clamped block, 4 steps, from 20 × 10: a contact zone as wide as
the radius).  Uniform refinement's force is not monotone here, so the reference F_ref is
Aitken's Δ² extrapolation of Dörfler's last three forces (which decrease with contracting
changes); per tolerance, the first level of each strategy from which every later level is
within it of F_ref, and the DoFs where the log–log segment of |F / F_ref − 1| into that
level crosses the tolerance (levels come in factors of ~4 for uniform refinement).  Writes
adaptive_<case>.csv and adaptive_<case>.png.

``ball`` — configs/hertz_3d.yaml made a neo-Hookean ball (the octant of a unit ball, its
flat top pushed down, the symmetry planes x = 0, y = 0) pressed onto the rigid plane z = 0
to δ = 0.2 R in ``--ball-steps`` steps, the gmsh mesh of size ``--mesh-size`` everywhere;
3D takes the iterative Newton system (CG + GAMG with the rigid-body near-nullspace and the
indefiniteness test, contact/solvers/krylov_curvature.py).  Per step: DoFs, Newton and
Krylov iterations, the force, seconds; the mesh and path times and the peak resident memory
summed over the ranks.  Writes ball_h<h>_np<ranks>.csv.

``recouple`` — mortar pairs on the current configuration (contact/drivers/recouple.py): the
coupling's fixed point plain (``relaxation="none"``) and Aitken-relaxed (the default), on the
self-contact ring (configs/hyperelastic_self_contact_ring.yaml, its 8 load steps, no step
cuts) and two neo-Hookean cylinders (configs/two_body_hertz_2d.yaml made hyperelastic) pressed
to δ = 0.1 R_c and 0.2 R_c in one step.  Per run: converged, the couplings and Newton
iterations of all steps, the largest couplings of a step, CPU seconds, the contact force; the
ratio of Aitken's couplings and CPU to the plain sequence's, in the same process (the load
path takes the driver's default, set here for the run).  Writes recouple.csv.

``sequence`` — grid sequencing (``solver.sequence``) of a hyperelastic load path's first
step: configs/hyperelastic_indentation.yaml on 80 × 40 and 160 × 80 cells, its 5 steps to
0.4 R and the whole indentation in 1 step, solved with ``sequence: off`` and with
``--coarse`` (2) coarser levels, each twice, alternating, in this process; per run the first
step's fine Newton iterations and its coarse levels (DoFs, Newton iterations), the CPU
seconds to the end of the first step (problem built, coarse levels and fine solve) and of
the whole path (the smaller of the two runs), the contact force of the first and last steps;
the ratio sequenced / off of both CPU times.  Writes sequence.csv (``--cells 320x160
--path-steps 1``: other meshes and paths, sequence_<cells>.csv).
``drag`` — Coulomb friction between two neo-Hookean bodies on the current configuration:
configs/hyperelastic_two_body_drag_2d.yaml and its 3D extrusion
configs/hyperelastic_two_body_drag_3d.yaml (a block pressed by 10 % onto a longer one, then
dragged along it, F = 0.3), each along its shipped load path.  Per load step: the slide of
the held top, the couplings and Newton iterations, the stick / slip / separated slave nodes,
Σ w|λ_t| / Σ w|λ_n| over the slipping nodes against F, the slave part's internal force
(drag and press) and its balance with the master's, |f_slave + f_master| / |f_slave|; CPU
seconds of the whole path.  Writes two_body_drag.csv.

``kink`` — self-contact after buckling: configs/hyperelastic_self_contact_kink.yaml (a
neo-Hookean tube, R = 1, r = 0.9, length 4, a quarter) whose end sections are turned by φ
about the x axis through the middle section, in ``--kink-steps`` (24) equal steps to
φ = 1.2 and in the scene's own 12.  Per step: φ, the bending moment M the end section carries
(about its centre, from the reactions: tests/test_self_contact_kink.py), the beam's
E I φ / a, the end's axial reaction, the pressed slave nodes and the contact force, the
couplings and Newton iterations, the smallest det F and K_T's negative eigenvalues; CPU
seconds of each path.  Writes kink.csv and kink.png (M against φ, both paths, the pressed
nodes on a second axis).
``pairs`` — two neo-Hookean cylinders (configs/two_body_hertz_2d.yaml made hyperelastic,
re-coupled on the current configuration) pressed to δ = 0.1 R_c in one step: Dörfler
(θ = 0.5, ``--levels`` 6) and uniform refinement (``--uniform-levels`` 3) from the shipped
mesh, per level DoFs, η, the contact force, couplings and Newton iterations, and the
interface forces' balance; then grid sequencing (``solver.sequence: 2`` against off) at
δ = 0.1 R_c on the shipped mesh and with h_contact = 0.025, and at 0.2 R_c: the fine
Newton iterations and couplings, the coarse levels, the force, CPU seconds (the smaller of
two alternating runs in this process) and their ratio.  Writes pairs_adaptive.csv and
pairs_sequence.csv.

Writes CSV under demos/results/hyperelastic/ (``--out``).
"""

from __future__ import annotations

import argparse
import copy
import functools
import math
import sys
import time
import warnings
from pathlib import Path

import contact  # noqa: F401  (before petsc4py)
import contact.setup.run as scene_run
from contact import refine
from contact.base.errors import ContactWarning
from contact.drivers import recouple as recouple_driver
from contact.models.hyperelastic import min_det_F, negative_eigenvalues

import numpy as np
from common import save_csv
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))  # the scenes the tests check, measured here too
import hyperelastic_friction_run  # noqa: E402
import test_hyperelastic  # noqa: E402
import test_hyperelastic_adapt  # noqa: E402
import test_self_contact_kink  # noqa: E402

COMM = MPI.COMM_WORLD
CYLINDER = ROOT / "configs" / "hyperelastic_cylinder.yaml"
STRIP = ROOT / "configs" / "hyperelastic_strip.yaml"
#: Euler's load of the strip: π² E/(1 − ν²) h³/12 / L² with E = 1, ν = 0.3, h = 0.05, L = 1
STRIP_EULER = math.pi**2 / (1 - 0.3**2) * 0.05**3 / 12


def say(*args) -> None:
    if COMM.rank == 0:
        print(*args, flush=True)


def arch(law: str, delta: float, steps: int, cuts: int) -> dict:
    """The arch of tests/test_hyperelastic.py (12 × 6 cells: bottom y = 0.2 x², top y = 0.5
    clamped, the plane y = δ t rising into it; the tests' own builder) on a load path."""
    return {**test_hyperelastic.arch(law, delta=delta), "load": {"steps": steps, "cuts": cuts}}


def block(law: str, compression: float) -> dict:
    """The quarter block of tests/test_hyperelastic.py (3 × 3 cells) pressed to
    ``compression`` in one step."""
    return {
        **test_hyperelastic.block(law, compression=compression),
        "load": {"steps": 1, "cuts": 0},
    }


def outcome(path, last) -> str:
    """The class of a load path's end (module doc)."""
    r = last.result
    if path.converged:
        if last.min_det_F is not None and last.min_det_F <= 0:
            return "inverted"
        if last.negative_eigenvalues:
            return "unstable"
        return "stable"
    if r.tangent_log and r.tangent_log[-1]["merit"] == "none":
        return "stopped"
    return r.reason


def run(case: str, source, sets: list[str], method: str, line_search: str) -> dict:
    scene = contact.load_scene(source, [*sets, "output.verbose=false"])
    t0 = time.process_time()
    path = contact.run_load_path(scene, method=method, line_search=line_search)
    cpu = COMM.allreduce(time.process_time() - t0, op=MPI.MAX)
    last = path.steps[-1]
    if last.min_det_F is None:  # a failed step: its iterate's det F and inertia
        last.min_det_F = min_det_F(last.result)
        last.negative_eigenvalues = negative_eigenvalues(last.result)
    reached = max((s.time for s in path.steps if s.result.converged), default=0.0)
    row = {
        "case": case,
        "method": method,
        "line_search": line_search,
        "converged": path.converged,
        "reason": last.result.reason,
        "newton_iterations": sum(s.result.iterations for s in path.steps),
        "max_step_iterations": max(s.result.iterations for s in path.steps),
        "steps": len(path.steps),
        "cuts": len(path.cuts),
        "reached_t": reached,
        "min_det_F": last.min_det_F,
        "negative_eigenvalues": last.negative_eigenvalues,
        "indefinite_newton_steps": sum(
            1 for s in path.steps for e in s.result.tangent_log if e["negative"]
        ),
        "curvature_steps": sum(
            1 for s in path.steps for e in s.result.tangent_log if e.get("along")
        ),
        "outcome": outcome(path, last),
        "contact_force": last.result.contact_force,
        "cpu_seconds": round(cpu, 3),
    }
    say(
        f"{case:28s} {method:6s} {line_search:7s} {row['outcome']:22s} "
        f"its {row['newton_iterations']:4d}  t {reached:.4g}  det F {row['min_det_F']:.3g}  "
        f"neg {row['negative_eigenvalues']}  F {row['contact_force']:.5g}  cpu {cpu:.2f} s"
    )
    return row


def line_search(out: Path) -> None:
    rows = []
    cases = [
        (f"SVK arch d={d}, 1 step", arch("saint_venant_kirchhoff", d, 1, 0))
        for d in (0.1, 0.16, 0.2, 0.3)
    ]
    cases.append(("SVK block 50 %, 1 step", block("saint_venant_kirchhoff", 0.5)))
    for name, cfg in cases:
        for method in ("fb", "min", "blend"):
            for ls in ("basic", "energy"):
                rows.append(run(name, copy.deepcopy(cfg), [], method, ls))
    path_cfg = arch("saint_venant_kirchhoff", 0.2, 10, 4)
    for ls in ("basic", "energy"):
        rows.append(run("SVK arch d=0.2, 10 steps", copy.deepcopy(path_cfg), [], "fb", ls))
    for ls in ("basic", "energy"):
        rows.append(run("SVK strip to 1.2 P_E", STRIP, [], "fb", ls))
    for _ in range(2):  # the definite case twice: the smaller CPU time of each counts
        for ls in ("basic", "energy"):
            rows.append(run("NH cylinder to 0.2 R", CYLINDER, [], "fb", ls))
    save_csv(out / "line_search.csv", rows)


def predictor(out: Path) -> None:
    """solver.predictor none (the plain start: the previous solution with the step's new
    data) against auto (the tangent predictor, the default for this model)."""
    pushed = arch("neo_hookean", 0.1, 1, 4)
    pushed["mesh"]["cells"] = [8, 4]
    pushed["obstacle"]["point"], pushed["data"] = [0, 0], {"u_D": ["0", "-delta*t"]}
    cyl = ["mesh.h=0.1", "mesh.h_contact=0.04", "mesh.zone=0.9", "constants.delta=0.5"]
    cases: list[tuple[str, object, list[str], str]] = [
        ("NH arch, top pushed 0.1 in 1 step", pushed, [], "fb"),
        *(
            (f"NH cylinder to 0.5 R, {n} steps", CYLINDER, [*cyl, f"load.steps={n}"], "fb")
            for n in (1, 2, 5, 10)
        ),
        ("NH cylinder to 0.5 R, 10 steps", CYLINDER, [*cyl, "load.steps=10"], "vinewtonrsls"),
        ("SVK strip to 1.2 P_E", STRIP, [], "fb"),
    ]
    rows = []
    for name, source, sets, method in cases:
        for choice in ("none", "auto"):
            scene = contact.load_scene(copy.deepcopy(source), [*sets, "output.verbose=false"])
            t0 = time.process_time()
            path = contact.run_load_path(scene, method=method, predictor=choice)
            cpu = COMM.allreduce(time.process_time() - t0, op=MPI.MAX)
            its = [s.result.iterations for s in path.steps]
            row = {
                "case": name,
                "method": method,
                "predictor": choice,
                "converged": path.converged,
                "steps": len(path.steps),
                "cuts": len(path.cuts),
                "newton_iterations": sum(its),
                "max_step_iterations": max(its),
                "contact_force": path.steps[-1].result.contact_force,
                "cpu_seconds": round(cpu, 3),
            }
            rows.append(row)
            say(
                f"{name:34s} {method:12s} predictor {choice:4s}: {path.stop}; Newton {its}, "
                f"cpu {cpu:.2f} s"
            )
    save_csv(out / "predictor.csv", rows)


def strip_state(sets: list[str], t: float) -> tuple[int, float, int]:
    """(negative eigenvalues of K_T, contact force, DoFs) of the strip's straight state at t."""
    scene = contact.load_scene(STRIP, [*sets, f"load.times=[{t!r}]", "output.verbose=false"])
    path = contact.run_load_path(scene, line_search="basic")
    if not path.converged:
        raise SystemExit(f"bench_hyperelastic strip: {sets} t = {t}: {path.stop}")
    step = path.steps[-1]
    return step.negative_eigenvalues or 0, step.result.contact_force, step.result.dofs


def strip(out: Path) -> None:
    """The critical load of each mesh by bisection on the inertia of the straight state: the
    solve at wall displacement t δ_E (one step from the reference state, plain Newton — the
    straight solution) has K_T definite below the critical t and one negative eigenvalue
    above; the bracket [0.9, 1.3] is halved until it is 1e-4 wide."""
    rows = []
    for cells, degree in (((40, 2), 1), ((80, 4), 1), ((160, 8), 1), ((40, 2), 2), ((80, 4), 2)):
        t0 = time.perf_counter()
        base = [f"mesh.cells=[{cells[0]},{cells[1]}]", f"mesh.degree={degree}"]

        lo, hi = 0.9, 1.3
        (n_lo, f_lo, dofs), (n_hi, f_hi, _) = strip_state(base, lo), strip_state(base, hi)
        if n_lo or not n_hi:
            raise SystemExit(f"bench_hyperelastic strip: {cells} P{degree}: not bracketed")
        while hi - lo > 1e-4:
            mid = round(0.5 * (lo + hi), 6)
            n, f, _ = strip_state(base, mid)
            if n:
                hi, f_hi = mid, f
            else:
                lo, f_lo = mid, f
        row = {
            "cells": f"{cells[0]}x{cells[1]}",
            "degree": degree,
            "dofs": dofs,
            "t_definite": lo,
            "t_indefinite": hi,
            "force_definite_over_euler": f_lo / STRIP_EULER,
            "force_indefinite_over_euler": f_hi / STRIP_EULER,
            "seconds": round(time.perf_counter() - t0, 2),
        }
        rows.append(row)
        say(
            "  ".join(
                f"{k} {v:.5g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()
            )
        )
    save_csv(out / "strip.csv", rows)


def refinement(out: Path, levels: int, steps: int, top: str) -> None:
    base = [
        "mesh.h=0.1",
        "mesh.h_contact=0.1",
        "constants.delta=0.5",
        f"load.steps={steps}",
        "output.verbose=false",
        *(["boundaries.top.role=symmetry"] if top == "symmetry" else []),
    ]
    scene = contact.load_scene(CYLINDER, base)
    rows = []
    for level in range(levels):
        if level:
            n = scene.mesh.topology.index_map(scene.mesh.topology.dim).size_local
            scene, _ = refine(scene, np.arange(n, dtype=np.int32))
        paths, seconds = {}, {}
        for method in ("fb", "vinewtonrsls"):
            t0 = time.perf_counter()
            paths[method] = contact.run_load_path(scene, method=method, keep_all=True)
            seconds[method] = time.perf_counter() - t0
            if not paths[method].converged:
                raise SystemExit(
                    f"bench_hyperelastic: level {level}, {method}: {paths[method].stop}"
                )
        fb, vi = paths["fb"].steps, {round(s.time, 12): s for s in paths["vinewtonrsls"].steps}
        du = df = 0.0
        for s in fb:
            other = vi.get(round(s.time, 12))
            if other is None:
                continue
            u, v = s.result.u_h.x.array, other.result.u_h.x.array
            largest = COMM.allreduce(float(np.max(np.abs(u))), op=MPI.MAX)
            du = max(du, COMM.allreduce(float(np.max(np.abs(u - v))), op=MPI.MAX) / largest)
            df = max(df, abs(s.result.contact_force / other.result.contact_force - 1))
        energy = {}
        for method, p in paths.items():  # Π of each solver's last state (stable minima differ)
            r = p.steps[-1].result
            x = r.problem.b.duplicate()
            r.problem.to_unknowns(r.u_h.x.petsc_vec, x)
            energy[method] = r.problem.energy(x)
            x.destroy()
        for s in fb:
            rows.append(
                {
                    "level": level,
                    "dofs": s.result.dofs,
                    "step": s.index,
                    "indentation": 0.5 * s.time,
                    "contact_force": s.result.contact_force,
                    "newton_iterations": s.result.iterations,
                    "negative_eigenvalues": s.negative_eigenvalues,
                    "vi_u_difference": du,
                    "vi_force_difference": df,
                    "seconds_fb": round(seconds["fb"], 2),
                    "seconds_vinewtonrsls": round(seconds["vinewtonrsls"], 2),
                    "vi_steps": len(paths["vinewtonrsls"].steps),
                    "energy_fb": energy["fb"],
                    "energy_vinewtonrsls": energy["vinewtonrsls"],
                    "negative_eigenvalues_vinewtonrsls": paths["vinewtonrsls"]
                    .steps[-1]
                    .negative_eigenvalues,
                }
            )
        last = fb[-1].result
        say(
            f"level {level}: {last.dofs} DoFs, F(0.5 R) = {last.contact_force:.10g}, "
            f"Newton {[s.result.iterations for s in fb]}, vinewtonrsls: |du|/|u| {du:.1e}, "
            f"force {df:.1e} ({len(paths['vinewtonrsls'].steps)} steps), "
            f"{seconds['fb']:.1f} s / {seconds['vinewtonrsls']:.1f} s"
        )
        for p in paths.values():
            for s in p.steps:
                s.release()
    force = [r["contact_force"] for r in rows if r["step"] == steps]
    diffs = np.abs(np.diff(force))
    rates = np.log2(diffs[:-1] / diffs[1:]) if len(diffs) > 1 else []
    say("observed rates of F(0.5 R):", " ".join(f"{r:.2f}" for r in rates))
    save_csv(out / f"refinement_{top}.csv", rows)
    if COMM.rank == 0:
        chart_refinement(out / f"refinement_{top}.png", rows)


def chart_refinement(path: Path, rows: list[dict]) -> None:
    """Left: force–indentation per level; right: |F_l − F_{l−1}| at δ = 0.5 R against the
    DoFs of level l, with a slope of h² (N⁻¹) for reference."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.8))
    levels = sorted({r["level"] for r in rows})
    last = []
    for level in levels:
        lv = [r for r in rows if r["level"] == level]
        x = [0.0] + [r["indentation"] for r in lv]
        left.plot(
            x,
            [0.0] + [r["contact_force"] for r in lv],
            "o-",
            ms=3,
            label=f"level {level}: {lv[0]['dofs']} DoFs",
        )
        last.append((lv[0]["dofs"], lv[-1]["contact_force"]))
    left.set_xlabel("indentation δ / R")
    left.set_ylabel("contact force (quarter model, per unit depth)")
    left.grid(alpha=0.3)
    left.legend(fontsize=8)
    left.set_title("neo-Hookean cylinder on a rigid plane")
    N = np.array([d for d, _ in last[1:]], dtype=float)
    diff = np.abs(np.diff([f for _, f in last]))
    right.loglog(N, diff, "o-", label="|F_l − F_{l−1}| at δ = 0.5 R")
    curve = np.array(
        [
            [
                r["contact_force"]
                for r in rows
                if r["level"] == lv and r["indentation"] <= 0.4 + 1e-9
            ]
            for lv in levels
        ]
    )
    right.loglog(
        N,
        np.max(np.abs(np.diff(curve, axis=0)), axis=1),
        "s-",
        label="largest |F_l − F_{l−1}| over δ ≤ 0.4 R",
    )
    if len(N):
        right.loglog(N, diff[0] * (N / N[0]) ** -1.0, "k--", lw=1, label="N⁻¹ (h²)")
        right.loglog(N, diff[0] * (N / N[0]) ** -0.5, "k:", lw=1, label="N⁻¹ᐟ² (h)")
    right.set_xlabel("DoFs N of level l")
    right.grid(True, which="both", alpha=0.3)
    right.legend(fontsize=8)
    right.set_title("uniform refinement: change of the force at 0.5 R")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


BLOCK = ROOT / "configs" / "block_on_plane.yaml"
#: the adaptive study's scene: configs/block_on_plane.yaml made neo-Hookean, its clamped top
#: pushed down by 10 % of the height, on a coarse start mesh
ADAPTIVE_SETS = [
    "model.type=hyperelastic",
    "model.law=neo_hookean",
    "constants.delta=0.05",
    "mesh.cells=[8,2]",
    "load.steps=2",
    "load.adapt=end",
    "adapt.theta=0.5",
    "adapt.max_dofs=400000",
    "output.verbose=false",
]
#: the force tolerances of the adaptive study's comparison
ADAPTIVE_TOLERANCES = (5e-3, 1e-3, 5e-4)


INDENTATION = ROOT / "configs" / "hyperelastic_indentation.yaml"
#: the ``indentation`` case: the shipped scene from 20 × 10, the loop at the last of 4 steps
INDENTATION_SETS = [
    "mesh.cells=[20,10]",
    "load.steps=4",
    "load.adapt=end",
    "adapt.theta=0.5",
    "adapt.max_dofs=400000",
    "output.verbose=false",
]
#: the ``indenter`` case: test_hyperelastic_adapt.indenter(radius, depth, cells)
INDENTER = (0.05, 0.01, 8)
#: the adaptive study's cases: (Dörfler levels, uniform levels) by default
ADAPTIVE_CASES = {"block": (12, 6), "indenter": (16, 6), "indentation": (12, 5)}


def adaptive_scene(case: str, strategy: str, levels: int):
    """The scene of an adaptive ``case`` (module doc) with ``adapt.strategy`` and levels."""
    if case == "indenter":
        cfg = test_hyperelastic_adapt.indenter(*INDENTER)
        cfg["adapt"] = {**cfg["adapt"], "strategy": strategy, "max_levels": levels}
        return contact.load_scene(cfg)
    source, sets = (BLOCK, ADAPTIVE_SETS) if case == "block" else (INDENTATION, INDENTATION_SETS)
    return contact.load_scene(
        source, [*sets, f"adapt.strategy={strategy}", f"adapt.max_levels={levels}"]
    )


def aitken(forces: list[float]) -> float | None:
    """Aitken's Δ² limit of the last three terms of a sequence whose changes contract
    (same sign, shrinking); None otherwise."""
    f1, f2, f3 = forces[-3:]
    d1, d2 = f2 - f1, f3 - f2
    if d1 * d2 <= 0 or abs(d2) >= abs(d1):
        return None
    return f3 - d2 * d2 / (d2 - d1)


def within(rows: list[dict], tol: float) -> tuple[int | None, float | None]:
    """(DoFs, interpolated DoFs) of a strategy's levels ``rows``: the first level from which
    every later level's |F / F_ref − 1| is ≤ tol, and where the log–log segment from the
    level before it crosses tol (None, None: no such level)."""
    errors = [abs(r["force_above_reference"]) for r in rows]
    first = next((i for i in range(len(rows)) if max(errors[i:]) <= tol), None)
    if first is None:
        return None, None
    dofs = rows[first]["dofs"]
    if first == 0 or errors[first] == 0:
        return dofs, float(dofs)
    n0, e0, e1 = rows[first - 1]["dofs"], errors[first - 1], errors[first]
    slope = math.log(e1 / e0) / math.log(dofs / n0)
    return dofs, n0 * math.exp(math.log(tol / e0) / slope)


def adaptive(out: Path, case: str, levels: int, uniform_levels: int) -> None:
    """Dörfler against uniform refinement on the adaptive ``case`` (module doc)."""
    runs: dict[str, list] = {}
    rows = []
    for strategy, n in (("uniform", uniform_levels), ("dorfler", levels)):
        scene = adaptive_scene(case, strategy, n)
        t0 = time.perf_counter()
        path = contact.run_load_path(scene, verbose=False)
        if not path.converged:
            raise SystemExit(f"bench_hyperelastic: adaptive {case}, {strategy}: {path.stop}")
        runs[strategy] = path.steps[-1].levels
        say(f"{case}, {strategy}: {len(runs[strategy])} levels, {time.perf_counter() - t0:.1f} s")
        for lv in runs[strategy]:
            rows.append(
                {
                    "strategy": strategy,
                    "level": lv.index,
                    "dofs": lv.result.dofs,
                    "eta": lv.estimate.eta,
                    "contact_force": lv.result.contact_force,
                    "newton_iterations": lv.result.iterations,
                    "seconds_solve": round(lv.seconds["solve"], 2),
                }
            )
            say(
                f"  level {lv.index}: {lv.result.dofs} DoFs, eta {lv.estimate.eta:.4e}, "
                f"F = {lv.result.contact_force:.9f}, Newton {lv.result.iterations}"
            )
    if case == "block":  # both sequences decrease: the finest force bounds the limit above
        reference = min(r["contact_force"] for r in rows)
    else:
        dorfler = [lv.result.contact_force for lv in runs["dorfler"]]
        extrapolated = aitken(dorfler)
        if extrapolated is None:
            raise SystemExit(
                f"bench_hyperelastic: adaptive {case}: Dörfler's forces do not contract"
            )
        reference = extrapolated
        say(f"F_ref = {reference:.9f} (Aitken's limit of Dörfler's last three levels)")
    for r in rows:
        r["reference_force"] = reference
        r["force_above_reference"] = r["contact_force"] / reference - 1
    summary = []
    for tol in ADAPTIVE_TOLERANCES:
        first = {k: within([r for r in rows if r["strategy"] == k], tol) for k in runs}
        (u, u_fit), (d, d_fit) = first["uniform"], first["dorfler"]
        summary.append(
            {
                "tolerance": tol,
                "uniform_dofs": u,
                "dorfler_dofs": d,
                "ratio": u / d if u and d else None,
                "uniform_interpolated": u_fit,
                "dorfler_interpolated": d_fit,
                "ratio_interpolated": u_fit / d_fit if u_fit and d_fit else None,
            }
        )
        ratio = f"{u / d:.1f}x fewer" if u and d else "-"
        fit = f"; interpolated {u_fit:.0f} vs {d_fit:.0f}" if u_fit and d_fit else ""
        say(
            f"within {tol:.2%} of F_ref = {reference:.9f} from then on: uniform {u} DoFs, "
            f"dorfler {d} DoFs ({ratio}{fit})"
        )
    finest = runs["uniform"][-1].result
    below = [
        lv.result.dofs for lv in runs["dorfler"] if lv.result.contact_force <= finest.contact_force
    ]
    if below and case == "block":
        say(
            f"dorfler's force is below uniform's finest ({finest.dofs} DoFs) from "
            f"{below[0]} DoFs on: {finest.dofs / below[0]:.1f}x fewer"
        )
    name = "adaptive" if case == "block" else f"adaptive_{case}"
    save_csv(out / f"{name}.csv", rows)
    if case != "block":
        save_csv(out / f"{name}_summary.csv", summary)
    if COMM.rank == 0:
        chart_adaptive(out / f"{name}.png", rows, reference, ADAPTIVE_TITLES[case])


#: the charts' titles
ADAPTIVE_TITLES = {
    "block": "neo-Hookean block pressed 10 %",
    "indenter": "rigid cylinder R = 0.05 pressed 0.2 R (half block)",
    "indentation": "configs/hyperelastic_indentation.yaml (0.4 R)",
}


def chart_adaptive(path: Path, rows: list[dict], reference: float, title: str) -> None:
    """Left: |F / F_ref − 1| against the DoFs, uniform and Dörfler; right: η against the
    DoFs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.8))
    for strategy, style in (("uniform", "s-"), ("dorfler", "o-")):
        lv = [r for r in rows if r["strategy"] == strategy and r["force_above_reference"] != 0]
        N = [r["dofs"] for r in lv]
        error = [abs(r["force_above_reference"]) for r in lv]
        left.loglog(N, error, style, ms=4, label=strategy)
        lv = [r for r in rows if r["strategy"] == strategy]
        right.loglog([r["dofs"] for r in lv], [r["eta"] for r in lv], style, ms=4, label=strategy)
    for tol in ADAPTIVE_TOLERANCES:
        left.axhline(tol, color="k", lw=0.6, ls=":")
    left.set_xlabel("DoFs")
    left.set_ylabel(f"|F / F_ref − 1|  (F_ref = {reference:.7f})")
    left.set_title(f"{title}: contact force")
    right.set_xlabel("DoFs")
    right.set_ylabel("η (residual estimator)")
    right.set_title("estimated error")
    for ax in (left, right):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


BALL = ROOT / "configs" / "hertz_3d.yaml"


def ball(out: Path, h: float, steps: int) -> None:
    """A neo-Hookean ball pressed onto a rigid plane to 0.2 R, iterative Newton (module doc)."""
    import resource

    sets = [
        "model.type=hyperelastic",
        "model.law=neo_hookean",
        "reference=none",
        "adapt=none",
        "constants.delta=0.2",
        'data.u_D=["0", "0", "-delta*t"]',
        f"load.steps={steps}",
        f"mesh.h={h}",
        f"mesh.h_contact={h}",
        "output.verbose=false",
    ]
    t0 = time.perf_counter()
    scene = contact.load_scene(BALL, sets)
    t1 = time.perf_counter()
    rows = []

    def on_step(step) -> None:
        r = step.result
        rows.append(
            {
                "ranks": COMM.size,
                "h": h,
                "step": step.index,
                "indentation": 0.2 * step.time,
                "dofs": r.dofs,
                "linear": r.linear,
                "newton_iterations": r.iterations,
                "krylov_iterations": r.krylov_iterations,
                "contact_force": r.contact_force,
                "negative_eigenvalues": step.negative_eigenvalues,
                "seconds": round(step.seconds, 2),
            }
        )
        say(
            f"step {step.index} (t = {step.time:g}): {r.dofs} DoFs, {r.linear}, Newton "
            f"{r.iterations}, Krylov {r.krylov_iterations}, F = {r.contact_force:.6g}, "
            f"{step.seconds:.1f} s"
        )

    path = contact.run_load_path(scene, verbose=False, on_step=on_step)
    t2 = time.perf_counter()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # MiB (Linux: KiB)
    total, top = COMM.allreduce(rss, op=MPI.SUM), COMM.allreduce(rss, op=MPI.MAX)
    say(
        f"{path.stop}; mesh {t1 - t0:.1f} s, load path {t2 - t1:.1f} s, peak RSS "
        f"{total:.0f} MiB over {COMM.size} rank(s) (largest {top:.0f} MiB)"
    )
    for r in rows:
        r.update(
            mesh_seconds=round(t1 - t0, 1),
            path_seconds=round(t2 - t1, 1),
            peak_rss_mib=round(total),
        )
    save_csv(out / f"ball_h{h:g}_np{COMM.size}.csv", rows)


def recouple(out: Path) -> None:
    """The coupling's fixed point plain and Aitken-relaxed (module doc)."""
    hertz = ["model.type=hyperelastic", "model.law=neo_hookean", "adapt=none", "load.steps=1"]
    cases = {
        "self-contact ring": (ROOT / "configs" / "hyperelastic_self_contact_ring.yaml", []),
        "cylinders 0.1 R": (
            ROOT / "configs" / "two_body_hertz_2d.yaml",
            [*hertz, "constants.delta=0.8"],
        ),
        "cylinders 0.2 R": (
            ROOT / "configs" / "two_body_hertz_2d.yaml",
            [*hertz, "constants.delta=1.6"],
        ),
    }
    default = scene_run.solve_recoupled
    rows = []
    try:
        for case, (path, sets) in cases.items():
            for relaxation in recouple_driver.RELAXATIONS[::-1]:  # none first
                scene_run.solve_recoupled = functools.partial(
                    recouple_driver.solve_recoupled, relaxation=relaxation
                )
                scene = contact.load_scene(path, ["output.verbose=false", "load.cuts=0", *sets])
                t0 = time.process_time()
                run = contact.run_load_path(scene, verbose=False)
                cpu = COMM.allreduce(time.process_time() - t0, op=MPI.SUM)
                couplings = [len(s.result.couplings) for s in run.steps]
                rows.append(
                    {
                        "case": case,
                        "relaxation": relaxation,
                        "converged": run.converged,
                        "steps": len(run.steps),
                        "couplings": sum(couplings),
                        "max_couplings_per_step": max(couplings),
                        "newton": sum(s.result.iterations for s in run.steps),
                        "cpu_seconds": round(cpu, 2),
                        "force": run.steps[-1].result.contact_force if run.converged else "",
                    }
                )
                say(", ".join(f"{k} {v}" for k, v in rows[-1].items()))
            plain, aitken = rows[-2], rows[-1]
            say(
                f"{case}: Aitken / plain couplings {aitken['couplings'] / plain['couplings']:.2f}, "
                f"CPU {aitken['cpu_seconds'] / plain['cpu_seconds']:.2f}"
                + ("" if plain["converged"] else " (the plain sequence did not converge)")
            )
    finally:
        scene_run.solve_recoupled = default
    save_csv(out / "recouple.csv", rows)


#: the ``sequence`` part: meshes (cells) and load paths (steps to 0.4 R) of the indentation
SEQUENCE_CELLS = ((80, 40), (160, 80))
SEQUENCE_STEPS = (5, 1)
INDENTATION = ROOT / "configs" / "hyperelastic_indentation.yaml"


def sequenced_path(cells: tuple[int, int], steps: int, sequence: str | int) -> dict:
    """One load path of the indentation with ``solver.sequence`` (module doc)."""
    scene = contact.load_scene(
        INDENTATION,
        [
            f"mesh.cells=[{cells[0]}, {cells[1]}]",
            f"load.steps={steps}",
            f"solver.sequence={sequence}",
            "output.verbose=false",
        ],
    )
    first: dict = {}
    t0 = time.process_time()

    def on_step(step) -> None:
        if not first:
            first["cpu"] = time.process_time() - t0
            first["result"] = step.result

    path = contact.run_load_path(scene, verbose=False, on_step=on_step)
    cpu = COMM.allreduce(time.process_time() - t0, op=MPI.MAX)
    r = first["result"]
    return {
        "cells": f"{cells[0]}x{cells[1]}",
        "steps": steps,
        "sequence": sequence,
        "dofs": r.dofs,
        "converged": path.converged,
        "cuts": len(path.cuts),
        "first_newton": r.iterations,
        "coarse_dofs": " ".join(str(lv.dofs) for lv in r.sequence),
        "coarse_newton": " ".join(str(lv.newton_iterations) for lv in r.sequence),
        "newton_all_steps": sum(s.result.iterations for s in path.steps),
        "first_cpu": COMM.allreduce(first["cpu"], op=MPI.MAX),
        "path_cpu": cpu,
        "first_force": r.contact_force,
        "last_force": path.steps[-1].result.contact_force,
    }


def sequence(
    out: Path,
    coarse: int,
    cells_list: tuple = SEQUENCE_CELLS,
    steps_list: tuple = SEQUENCE_STEPS,
    repeats: int = 2,
) -> None:
    """Grid sequencing of a hyperelastic path's first step against none (module doc)."""
    rows = []
    for cells in cells_list:
        for steps in steps_list:
            runs: dict = {"off": [], coarse: []}
            for _ in range(repeats):  # alternating: the machine's load hits both alike
                for mode in runs:
                    runs[mode].append(sequenced_path(cells, steps, mode))
            best = {
                mode: {
                    **rs[0],
                    "first_cpu": min(r["first_cpu"] for r in rs),
                    "path_cpu": min(r["path_cpu"] for r in rs),
                }
                for mode, rs in runs.items()
            }
            for mode, row in best.items():
                row["first_cpu_ratio"] = row["first_cpu"] / best["off"]["first_cpu"]
                row["path_cpu_ratio"] = row["path_cpu"] / best["off"]["path_cpu"]
                for key in ("first_cpu", "path_cpu", "first_cpu_ratio", "path_cpu_ratio"):
                    row[key] = round(row[key], 3)
                rows.append(row)
                say(
                    f"{row['cells']:>7s} {steps} step(s) sequence {mode!s:>3s}: {row['dofs']} "
                    f"DoFs, first step Newton {row['first_newton']:2d} (coarse "
                    f"{row['coarse_dofs'] or '-'}: {row['coarse_newton'] or '-'}), CPU first "
                    f"step {row['first_cpu']:.2f} s ({row['first_cpu_ratio']:.2f}x), path "
                    f"{row['path_cpu']:.2f} s ({row['path_cpu_ratio']:.2f}x), F "
                    f"{row['last_force']:.10g}"
                )
    name = (
        "sequence"
        if cells_list == SEQUENCE_CELLS
        else "sequence_" + "_".join(f"{a}x{b}" for a, b in cells_list)
    )
    save_csv(out / f"{name}.csv", rows)


#: the dragged blocks (the ``drag`` part): dimension -> shipped scene
DRAGS = {
    2: ROOT / "configs" / "hyperelastic_two_body_drag_2d.yaml",
    3: ROOT / "configs" / "hyperelastic_two_body_drag_3d.yaml",
}


def drag(out: Path) -> None:
    """Coulomb between two neo-Hookean bodies, pressed and dragged (module doc)."""
    rows = []
    for gdim, path in DRAGS.items():
        scene = contact.load_scene(path, ["output.verbose=false"])
        constants = scene.config.constants
        figures = []

        def on_step(step, scene=scene, figures=figures) -> None:
            if step.result.converged:
                figures.append(hyperelastic_friction_run.step_row(step, scene))

        t0 = time.process_time()
        run = contact.run_load_path(scene, on_step=on_step, verbose=False)
        cpu = COMM.allreduce(time.process_time() - t0, op=MPI.SUM)
        if not run.converged:
            raise SystemExit(f"bench_hyperelastic: drag {gdim}D: {run.stop}")
        F = scene.config.friction.coefficient
        for row in figures:
            t, _, couplings, newton, stick, slip, separated, ratio = row[:8]
            slave, master = np.array(row[8 : 8 + gdim]), np.array(row[8 + gdim :])
            rows.append(
                {
                    "scene": path.stem,
                    "dim": gdim,
                    "dofs": run.steps[-1].result.problem.V.dofmap.index_map.size_global * gdim,
                    "t": round(t, 12),
                    "slide": constants["drag"] * max(t - 0.2, 0) / 0.8,
                    "couplings": couplings,
                    "newton": newton,
                    "stick": stick,
                    "slip": slip,
                    "separated": separated,
                    "ratio": ratio,
                    "ratio_error": abs(ratio / F - 1),
                    "drag_force": abs(slave[0]),
                    "press_force": abs(slave[1]),
                    "balance": float(np.linalg.norm(slave + master) / np.linalg.norm(slave)),
                    "path_cpu_seconds": round(cpu, 1),
                }
            )
            say(
                ", ".join(
                    f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                    for k, v in rows[-1].items()
                )
            )
    save_csv(out / "two_body_drag.csv", rows)


KINK = ROOT / "configs" / "hyperelastic_self_contact_kink.yaml"


def kink(out: Path, steps: int) -> None:
    """A tube kinked by end rotations into self-contact (module doc)."""
    rows = []
    for n in (steps, None):
        sets = [] if n is None else [f"load.steps={n}"]
        scene = contact.load_scene(KINK, ["output.verbose=false", *sets])
        c = scene.config.constants
        figures = []

        def on_step(step, scene=scene, figures=figures, c=c) -> None:
            r = step.result
            moment = test_self_contact_kink.end_moment(r, scene, step.time)
            X = r.problem.V.tabulate_dof_coordinates()
            _, f = test_self_contact_kink.nodal_forces(
                r, scene, np.flatnonzero(X[:, 2] > c["a"] - 1e-9)
            )
            axial = COMM.allreduce(float(f[:, 2].sum()), op=MPI.SUM)
            figures.append(
                {
                    "path_steps": scene.config.load.steps,
                    "phi": c["p"] * step.time,
                    "moment": moment,
                    "beam_moment": test_self_contact_kink.INERTIA * c["p"] * step.time / c["a"],
                    "axial_reaction": axial,
                    "pressed": r.n_active,
                    "contact_force": r.contact_force,
                    "couplings": len(r.couplings),
                    "newton": sum(k["newton"] for k in r.couplings),
                    "min_det_F": min_det_F(r),
                }
            )
            say(", ".join(f"{k} {v:.4g}" for k, v in figures[-1].items()))

        t0 = time.process_time()
        run = contact.run_load_path(scene, on_step=on_step, verbose=False)
        cpu = COMM.allreduce(time.process_time() - t0, op=MPI.SUM)
        if not run.converged:
            raise SystemExit(f"bench_hyperelastic: kink: {run.stop}")
        rows += [{**row, "path_cpu_seconds": round(cpu, 1)} for row in figures]
    save_csv(out / "kink.csv", rows)
    if COMM.rank == 0:
        chart_kink(out / "kink.png", rows)


def chart_kink(path: Path, rows: list[dict]) -> None:
    """The moment against the end rotation (both paths; the beam's E I φ / a dashed), the
    pressed slave nodes on a second axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    right = ax.twinx()
    for n, style in zip(sorted({r["path_steps"] for r in rows}, reverse=True), ("o-", "s--")):
        path_rows = [r for r in rows if r["path_steps"] == n]
        phi = [0.0] + [r["phi"] for r in path_rows]
        ax.plot(phi, [0.0] + [r["moment"] for r in path_rows], style, ms=3, label=f"{n} steps")
        right.plot(phi, [0] + [r["pressed"] for r in path_rows], style, ms=3, color="C3")
    beam = [r for r in rows if r["phi"] <= 0.2]
    ax.plot([0, beam[-1]["phi"]], [0, beam[-1]["beam_moment"]], "k:", label="beam E I φ / a")
    ax.set(xlabel="end rotation φ (rad)", ylabel="bending moment M (quarter model)")
    right.set_ylabel("pressed slave nodes", color="C3")
    ax.set_title("neo-Hookean tube kinked by end rotations")
    ax.legend(loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    print(f"wrote {path}", flush=True)


HERTZ_2D = ROOT / "configs" / "two_body_hertz_2d.yaml"
NEO_HOOKEAN = ["model.type=hyperelastic", "model.law=neo_hookean", "output.verbose=false"]
#: the sequencing cases of the ``pairs`` part: (δ, the mesh's h_contact or None: shipped)
PAIRS_SEQUENCE = ((0.8, None), (0.8, 0.025), (1.6, None))


def pairs(out: Path, levels: int, uniform_levels: int) -> None:
    """Adapt and grid sequencing of two neo-Hookean cylinders (module doc)."""
    # the half-disks' arcs away from the contact carry σn = 0, as shipped
    warnings.filterwarnings("ignore", "boundary: .* exterior facet", ContactWarning)
    rows = []
    for strategy, count in (("dorfler", levels), ("uniform", uniform_levels)):
        scene = contact.load_scene(
            HERTZ_2D,
            [
                *NEO_HOOKEAN,
                "constants.delta=0.8",
                f"adapt.strategy={strategy}",
                f"adapt.max_levels={count}",
                "adapt.max_dofs=1000000",
            ],
        )
        run = contact.adapt(scene, verbose=False)
        for lv in run.levels:
            r = lv.result
            slave, master = r.interface_forces
            rows.append(
                {
                    "strategy": strategy,
                    "level": lv.index,
                    "dofs": r.dofs,
                    "eta": lv.estimate.eta,
                    "force": r.contact_force,
                    "couplings": len(r.couplings),
                    "newton": r.iterations,
                    "balance": float(np.linalg.norm(slave + master) / np.linalg.norm(slave)),
                    "solve_seconds": round(lv.seconds["solve"], 2),
                }
            )
            say(
                ", ".join(
                    f"{k} {v:.6g}" if isinstance(v, float) else f"{k} {v}"
                    for k, v in rows[-1].items()
                )
            )
    save_csv(out / "pairs_adaptive.csv", rows)
    rows = []
    for delta, h_contact in PAIRS_SEQUENCE:
        sets = [*NEO_HOOKEAN, "adapt=none", f"constants.delta={delta}"]
        if h_contact is not None:
            sets.append(f"mesh.h_contact={h_contact}")
        runs: dict = {"off": [], 2: []}
        for _ in range(2):  # alternating: the machine's load hits both alike
            for mode in runs:
                scene = contact.load_scene(HERTZ_2D, [*sets, f"solver.sequence={mode}"])
                t0 = time.process_time()
                r = contact.solve(scene, verbose=False)
                runs[mode].append((COMM.allreduce(time.process_time() - t0, op=MPI.MAX), r))
        cold = min(cpu for cpu, _ in runs["off"])
        for mode, done in runs.items():
            cpu, r = min(done, key=lambda x: x[0])
            rows.append(
                {
                    "delta": delta,
                    "h_contact": h_contact or scene.config.mesh.h_contact,
                    "sequence": mode,
                    "dofs": r.dofs,
                    "converged": r.converged,
                    "newton": r.iterations,
                    "couplings": len(r.couplings),
                    "coarse_dofs": " ".join(str(lv.dofs) for lv in r.sequence),
                    "coarse_newton": " ".join(str(lv.newton_iterations) for lv in r.sequence),
                    "force": r.contact_force,
                    "cpu": round(cpu, 3),
                    "cpu_ratio": round(cpu / cold, 3),
                }
            )
            say(
                ", ".join(
                    f"{k} {v:.10g}" if isinstance(v, float) else f"{k} {v}"
                    for k, v in rows[-1].items()
                )
            )
    save_csv(out / "pairs_sequence.csv", rows)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "part",
        choices=(
            "line_search",
            "predictor",
            "strip",
            "refinement",
            "adaptive",
            "ball",
            "recouple",
            "sequence",
            "drag",
            "kink",
            "pairs",
        ),
    )
    ap.add_argument("--coarse", type=int, default=2, help="sequence: coarser levels (2)")
    ap.add_argument(
        "--cells",
        nargs="+",
        default=None,
        help="sequence: meshes NXxNY (80x40 160x80; others write sequence_<cells>.csv)",
    )
    ap.add_argument(
        "--path-steps", type=int, nargs="+", default=None, help="sequence: load paths (5 1)"
    )
    ap.add_argument("--out", type=Path, default=ROOT / "demos" / "results" / "hyperelastic")
    ap.add_argument(
        "--levels",
        type=int,
        default=None,
        help="refinement: mesh levels (4); adaptive: Dörfler levels (12; indenter 16)",
    )
    ap.add_argument(
        "--uniform-levels", type=int, default=None, help="adaptive: uniform levels (6; 5)"
    )
    ap.add_argument(
        "--case",
        choices=tuple(ADAPTIVE_CASES),
        default="block",
        help="adaptive: the neo-Hookean block on a plane, or a rigid cylinder pressed into a "
        "block (indenter: a small one, indentation: the shipped scene)",
    )
    ap.add_argument("--kink-steps", type=int, default=24, help="kink: load steps to φ = 1.2")
    ap.add_argument("--mesh-size", type=float, default=0.05, help="ball: the mesh size")
    ap.add_argument("--ball-steps", type=int, default=4, help="ball: load steps to 0.2 R")
    ap.add_argument("--steps", type=int, default=10, help="refinement: load steps to 0.5 R")
    ap.add_argument(
        "--top",
        choices=("clamped", "symmetry"),
        default="clamped",
        help="refinement: the cylinder's flat top held (the shipped scene) or a symmetry "
        "plane (a whole cylinder squeezed between two plates)",
    )
    args = ap.parse_args()
    if args.part == "line_search":
        line_search(args.out)
    elif args.part == "predictor":
        predictor(args.out)
    elif args.part == "strip":
        strip(args.out)
    elif args.part == "ball":
        ball(args.out, args.mesh_size, args.ball_steps)
    elif args.part == "adaptive":
        dorfler, uniform = ADAPTIVE_CASES[args.case]
        adaptive(args.out, args.case, args.levels or dorfler, args.uniform_levels or uniform)
    elif args.part == "recouple":
        recouple(args.out)
    elif args.part == "sequence":
        cells = tuple(tuple(int(n) for n in c.split("x")) for c in args.cells or ())
        sequence(
            args.out,
            args.coarse,
            cells or SEQUENCE_CELLS,
            tuple(args.path_steps or SEQUENCE_STEPS),
        )
    elif args.part == "drag":
        drag(args.out)
    elif args.part == "kink":
        kink(args.out, args.kink_steps)
    elif args.part == "pairs":
        pairs(args.out, args.levels or 6, args.uniform_levels or 3)
    else:
        refinement(args.out, args.levels or 4, args.steps, args.top)


if __name__ == "__main__":
    main()
