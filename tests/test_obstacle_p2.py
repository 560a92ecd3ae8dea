"""P2 for the obstacle problem u ≥ ψ in Ω (model type ``obstacle``, ``mesh.degree: 2``).

The nodal complementarity R_i = w_i λ_i, u_i ≥ ψ_i, λ_i ≥ 0, (u_i − ψ_i) λ_i = 0 needs
weights w_i > 0; the lumped mass ∫ φ_i is 0 at the P2 vertices of a triangle and negative at
those of a tetrahedron, so w_i is the P1-iso-P2 lumped mass (contact.models.problem
.lumped_weights).  Checked against exact solutions:

* PETSc ex9 (configs/peers/petsc_ex9.yaml, 2D, a radial free boundary at r = a): P2 below
  P1 on the same mesh and an energy-error rate ≈ 3/2 under uniform refinement
  (u ∈ H^{5/2−ε}: λ jumps at the free boundary, which limits any degree to h^{3/2} in
  energy on uniform meshes);
* its 3D analogue (a ball of contact of radius a = 0.6 under the upper unit hemisphere,
  u = A/ρ + B outside): P2 below P1 on the same mesh (and per DoF: measured on 16³ against
  32³), at the rate ≈ 1: the P2 vertex functions integrate to −|T|/20, so in the contact
  zone the vertices carry a downward load ∫ λ φ_i < 0 the multiplier cannot balance and
  are lifted by O(h²), an O(h) energy error;

with λ_h ≥ 0 and u_h ≥ ψ at the nodes to solver tolerance and the contact set converging
(its measure counted on the cells' edge midpoints, output.run_report.active_measure).  The
equilibrated bound is guaranteed (the flux balances the P1-iso-P2 weights to round-off, as
on the faces of a 3D P2 Signorini boundary, lumped alike) and drives ``adapt``; the residual
estimator works in 2D with the multiplier as a P1 density and is refused in 3D.  Serial =
2 ranks.
"""

from __future__ import annotations

import csv
import math

import contact
from contact import ConfigError
from contact.adaptivity.energy_error import energy_error, solution_error
from contact.adaptivity.equilibration.bound import guaranteed_bound
from contact.adaptivity.estimate import estimate
from contact.models.problem import lumped_weights
from contact.output.run_report import active_measure

import numpy as np
import pytest
import ufl
from clirun import ROOT, pytest_on_ranks
from clirun import contact as cli
from dolfinx import fem, mesh
from mpi4py import MPI

EX9 = ROOT / "configs" / "peers" / "petsc_ex9.yaml"
A_EX9 = 0.697965148223374  # ex9's free-boundary radius
RHO = "sqrt(x**2 + y**2 + z**2)"
A_BALL = 0.6  # the 3D problem's radius of contact: A = a³/√(1 − a²), B = √(1 − a²) − A/a
BALL = {
    "name": "obstacle_ball_3d",
    "mesh": {"type": "box", "corners": [[-1, -1, -1], [1, 1, 1]]},
    "boundaries": {
        "outer": {
            "role": "dirichlet",
            "where": "abs(x) > 1 - 1e-10 or abs(y) > 1 - 1e-10 or abs(z) > 1 - 1e-10",
        }
    },
    "model": {"type": "obstacle", "bound": "lower"},
    "constants": {"r0": 0.9, "a": A_BALL, "A": 0.27, "B": 0.35},
    "data": {
        "f": "0",
        "psi": f"sqrt(1 - ({RHO})**2) if {RHO} <= r0 "
        f"else sqrt(1 - r0**2) - r0/sqrt(1 - r0**2)*({RHO} - r0)",
        "u_D": f"sqrt(1 - ({RHO})**2) if {RHO} <= a else A/{RHO} + B",
        "exact": f"sqrt(1 - ({RHO})**2) if {RHO} <= a else A/{RHO} + B",
    },
    "output": {"verbose": False},
}


def _ex9(cells: int, degree: int, *sets: str) -> contact.Scene:
    return contact.load_scene(
        EX9,
        [f"mesh.cells=[{cells},{cells}]", f"mesh.degree={degree}", "output.verbose=false"]
        + list(sets),
    )


def _ball(cells: int, degree: int, **changes) -> contact.Scene:
    mesh_ = {**BALL["mesh"], "cells": [cells] * 3, "degree": degree}
    return contact.load_scene({**BALL, "mesh": mesh_, **changes})


def _solve(scene: contact.Scene) -> tuple[contact.Result, float]:
    """The solution and its energy error |u − u_h|_H¹ against the scene's exact solution."""
    result = contact.solve(scene, verbose=False)
    assert result.converged, result.reason
    data = scene.config
    return result, energy_error(result.u_h, data.data.exact, 1.0, data.constants)


def _check_nodal_complementarity(result: contact.Result) -> None:
    """λ_i ≥ 0 and u_i ≥ ψ_i at every constrained node to the solver's tolerance (over all
    ranks): relative 1e-8 of the largest λ_i, 1e-10 of the obstacle's size."""
    con = result.problem.constraint
    comm = result.u_h.function_space.mesh.comm
    lam = result.lmbda_h.x.array[con.dofs]
    gap = result.u_h.x.array[con.dofs] - con.g
    lam_max = comm.allreduce(float(lam.max(initial=0.0)), op=MPI.MAX)
    lam_min = comm.allreduce(float(lam.min(initial=np.inf)), op=MPI.MIN)
    gap_min = comm.allreduce(float(gap.min(initial=np.inf)), op=MPI.MIN)
    assert lam_max > 1 and lam_min >= -1e-8 * lam_max, (lam_min, lam_max)
    assert gap_min >= -1e-10, gap_min


@pytest.mark.parametrize("dim", [2, 3])
def test_p2_weights_are_positive_and_exact_for_affine_functions(dim: int) -> None:
    """The P1-iso-P2 weights on the unit square / cube: every w_i > 0, Σ w_i = |Ω| and
    Σ w_i x_i = ∫ x (a nodal rule exact for affine functions)."""
    comm = MPI.COMM_WORLD
    msh = mesh.create_unit_square(comm, 3, 3) if dim == 2 else mesh.create_unit_cube(comm, 2, 2, 2)
    V = fem.functionspace(msh, ("Lagrange", 2))
    n = V.dofmap.index_map.size_local
    w = lumped_weights(V, ufl.dx(domain=msh))[:n]
    x = V.tabulate_dof_coordinates()[:n]
    assert comm.allreduce(float(w.min()), op=MPI.MIN) > 0
    assert abs(comm.allreduce(float(w.sum()), op=MPI.SUM) - 1) < 1e-14
    first = comm.allreduce(x.T @ w, op=MPI.SUM)
    assert np.abs(first[:dim] - 0.5).max() < 1e-14


@pytest.fixture(scope="module")
def ex9() -> dict:
    """ex9 with P1 on 16² and P2 on 16², 32², 64² (one diagonal per square): energy
    errors, contact radii sqrt(|A_h|/π) and the residual estimator's η/error; the λ_h ≥ 0,
    u_h ≥ ψ check on each P2 run."""
    out = {"p1": _solve(_ex9(16, 1))[1]}
    for cells in (16, 32, 64):
        result, error = _solve(_ex9(cells, 2))
        _check_nodal_complementarity(result)
        eta = estimate(result.problem, result, "residual").eta
        out[cells] = (error, math.sqrt(active_measure(result) / math.pi), eta / error)
    return out


def test_ex9_p2_is_below_p1_and_converges_at_the_rate_of_its_regularity(ex9) -> None:
    """Energy errors 0.263 (P1) and 0.0614, 0.0229, 0.00720 (P2 on 16², 32², 64²): P2 4.3×
    below P1 on the same mesh, rates 1.42 and 1.67; u ∈ H^{5/2−ε} (λ = −Δψ jumps at the free
    boundary) limits P2 to h^{3/2} in energy."""
    assert ex9[16][0] < ex9["p1"] / 3, (ex9[16][0], ex9["p1"])
    rates = [math.log2(ex9[c][0] / ex9[2 * c][0]) for c in (16, 32)]
    assert min(rates) >= 1.3, rates


def test_ex9_p2_contact_set_converges(ex9) -> None:
    """The radius sqrt(|A_h|/π) of the discrete contact set: measured r_h − a = 0.048, 0.030,
    0.0084 on 16², 32², 64² (h = 4/cells), always above 0 and below h/2 as for P1
    (test_peers.py), and falling."""
    dist = {c: ex9[c][1] - A_EX9 for c in (16, 32, 64)}
    assert all(0 < d <= 2 / c for c, d in dist.items()), dist
    assert dist[64] < dist[16], dist


@pytest.fixture(scope="module")
def ball() -> dict:
    """The 3D problem with P1 on 8³ and P2 on 4³, 8³: energy errors and contact radii."""
    out = {"p1": _solve(_ball(8, 1))[1]}
    for cells in (4, 8):
        result, error = _solve(_ball(cells, 2))
        _check_nodal_complementarity(result)
        out[cells] = (error, (3 * active_measure(result) / (4 * math.pi)) ** (1 / 3))
    return out


def test_ball_p2_is_below_p1_and_converges(ball) -> None:
    """Energy errors 0.266 (P1, 8³) and 0.169, 0.0896 (P2 on 4³, 8³; 0.0433 on 16³): P2 3×
    below P1 on 8³, rate 0.91 (1.05 to 16³, where P2 on 16³ is 1.65× below P1 on 32³, the
    same 35,937 DoFs) — the O(h) of the vertices lifted by O(h²) in the contact zone."""
    assert ball[8][0] < ball["p1"] / 2.5, (ball[8][0], ball["p1"])
    assert math.log2(ball[4][0] / ball[8][0]) >= 0.8


def test_ball_p2_contact_set_converges(ball) -> None:
    """The radius (3|A_h|/4π)^{1/3}: r_h − a = 0.076, 0.030 (0.015 on 16³) on 4³, 8³, above
    0 and below h/2 (h = 2/cells)."""
    dist = {c: ball[c][1] - A_BALL for c in (4, 8)}
    assert all(0 < d <= 1 / c for c, d in dist.items()), dist
    assert dist[8] < dist[4], dist


@pytest.mark.parametrize("case", ["ex9_16", "ex9_32", "ball_4"])
def test_equilibrated_bound_is_guaranteed(case: str) -> None:
    """The flux balances the P1-iso-P2 weights (patch defect at round-off, where the
    entity weights ∫ φ_i left 0.4–0.6) and η ≥ |u − u_h|_H¹: measured η/error = 1.27, 2.36
    (ex9 on 16², 32²), 1.94 (the ball on 4³)."""
    name, cells = case.split("_")
    scene = _ex9(int(cells), 2) if name == "ex9" else _ball(int(cells), 2)
    result, error = _solve(scene)
    bound = guaranteed_bound(result.problem, result)
    assert bound.flux.defect < 1e-9, bound.flux.defect
    assert error <= bound.eta <= 3 * error, (bound.eta, error)


def test_flux_balances_a_3d_p2_signorini_boundary() -> None:
    """The faces of a 3D P2 Γ_C are lumped with the same P1-iso-P2 weights, and so are the
    flux's multiplier shares: problem A's 3D extrusion on 6 × 3 × 3 with P2 has the patch
    defect at round-off (0.088 with the faces' ∫ φ_i before) and η ≥ error (η/error 4.4)."""
    scene = contact.load_scene(
        ROOT / "configs" / "signorini_free_boundary.yaml",
        ["mesh.type=box", "mesh.corners=[[-1,0,0],[1,1,1]]", "mesh.cells=[6,3,3]"]
        + ["mesh.degree=2", "output.verbose=false"],
    )
    result = contact.solve(scene, verbose=False)
    assert result.converged, result.reason
    bound = guaranteed_bound(result.problem, result)
    assert bound.flux.defect < 1e-9, bound.flux.defect
    assert bound.eta >= solution_error(result.problem, result)


def test_residual_estimator_in_2d(ex9) -> None:
    """The residual estimator with the multiplier tested by the P1 hats (a P1 density,
    estimate.vertex_density): η/error = 8.0, 7.7, 9.6 on ex9's 16², 32², 64² (9.1 on 128²;
    P1: 5.5–5.7), where the alternating nodal λ_h gave 11, 14, 21."""
    effectivity = [ex9[c][2] for c in (16, 32, 64)]
    assert all(1 <= e <= 12 for e in effectivity), effectivity


def test_residual_estimator_is_refused_in_3d() -> None:
    """In 3D the vertices of a contact zone are lifted by O(h²), which the volume residual
    measures: η/error grew 11, 13, 16 on the ball's 4³, 8³, 16³.  Refused by the scene, and
    by the estimator (a gmsh mesh shows its dimension only when read)."""
    match = r"^estimator: residual does not converge with a P2 obstacle solution in 3D"
    with pytest.raises(ConfigError, match=match):
        _ball(4, 2, estimator="residual")
    result, _ = _solve(_ball(4, 2))
    with pytest.raises(ConfigError, match=match):
        estimate(result.problem, result, "residual")


def _adapt(tmp_path, ranks: int) -> list[dict]:
    out = tmp_path / f"np{ranks}"
    args = ["run", str(EX9), "-o", str(out), "-q", "--set", "mesh.degree=2"]
    for item in ("mesh.cells=[8,8]", "adapt.max_levels=4", "output.png=false"):
        args += ["--set", item]
    proc = cli(tmp_path, *args, ranks=ranks)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return list(csv.DictReader(open(out / "convergence.csv")))


def test_adapt_with_p2_serial_equals_two_ranks(tmp_path) -> None:
    """``adapt`` on ex9 with P2 (the equilibrated bound marks): 289 → 1233 DoFs in 4 levels,
    η ≥ error on each (η/error 1.5–2.1) and the error falling; the same meshes and figures
    on 2 ranks."""
    serial, parallel = _adapt(tmp_path, 0), _adapt(tmp_path, 2)
    assert [r["dofs"] for r in serial] == [r["dofs"] for r in parallel]
    for s, p in zip(serial, parallel, strict=True):
        for key in ("eta", "error"):
            assert abs(float(s[key]) - float(p[key])) <= 1e-8 * float(s[key]), (key, s, p)
    errors = [float(r["error"]) for r in serial]
    assert all(float(r["eta"]) >= float(r["error"]) for r in serial)
    assert errors[-1] < 0.2 * errors[0], errors


def test_on_two_ranks() -> None:
    """The tests above that solve in this process pass on each of 2 MPI ranks (their
    assertions compare global sums and extrema)."""
    proc = pytest_on_ranks(__file__, "not ranks and not adapt", timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert " failed" not in proc.stdout and proc.stdout.count(" passed") == 2
