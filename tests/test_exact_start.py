"""A solve started from its own discrete solution stops at once, with that solution.

The stopping test is ‖Φ‖ ≤ max(atol · F, rtol ‖Φ_0‖, the round-off floor of ‖Φ‖) (F the
largest nodal force of the data, :func:`contact.solvers.snes.force_scale`).  From the
converged u_h, ‖Φ_0‖ is round-off: rtol ‖Φ_0‖ is below it, and atol · F may be too (P2's
nodal forces are small), so only the floor can stop the solve.  Two defects made such a
start run to max_it or pay a step: a body held by contact alone had no floor (the P2
contact patch: ‖Φ‖ 4e-16 against atol · F 2e-16, diverged_max_it after 63 steps with every
method), and SNES tests iteration 0 before the monitor raises its tolerance to the floor
(step-41 at 256² with min took one step).  The multiplier is recomputed from u (the NCP is
primal), so u_h is all the state a restart needs."""

from __future__ import annotations

import contact
from contact.setup.build import build_problem

import numpy as np
import pytest
from clirun import ROOT
from dolfinx import fem
from mpi4py import MPI
from test_parallel_invariance import run_script

PATCH_P2 = ("two_body_patch_2d.yaml", ["mesh.degree=2"])  # the upper block: contact holds it
CASES = {
    "patch_p2": PATCH_P2,
    "step41": ("peers/dealii_step41.yaml", ["mesh.cells=[256,256]"]),
    "hertz": ("hertz_2d.yaml", ["adapt=null"]),
    "tresca": ("friction_tresca_manufactured.yaml", ["adapt=null"]),
    "hyperelastic": ("hyperelastic_block.yaml", ["load.steps=1"]),
}


def restart(config: str, overrides: list, method: str) -> tuple:
    """The cold solve of ``configs/<config>`` and the solve started from its u_h (a fresh
    problem), without grid sequencing: (cold, restarted, max|Δu| / max|u|)."""
    scene = contact.load_scene(ROOT / "configs" / config, [*overrides, "output.verbose=false"])
    cold = contact.solve(scene, problem=build_problem(scene), method=method, sequence="off")
    u0 = fem.Function(cold.u_h.function_space)
    u0.x.array[:] = cold.u_h.x.array
    again = contact.solve(
        scene, problem=build_problem(scene), method=method, sequence="off", u0=u0, verbose=False
    )
    comm = MPI.COMM_WORLD
    diff = comm.allreduce(float(np.max(np.abs(again.u_h.x.array - u0.x.array))), op=MPI.MAX)
    size = comm.allreduce(float(np.max(np.abs(u0.x.array))), op=MPI.MAX)
    return cold, again, diff / size


@pytest.mark.parametrize(
    "case, method",
    [
        *[("patch_p2", m) for m in ("fb", "min", "blend", "vinewtonrsls", "vinewtonssls")],
        ("step41", "min"),
        ("step41", "fb"),
        ("hertz", "fb"),
        ("tresca", "min"),
        ("tresca", "fb"),
    ],
)
def test_a_solve_from_its_own_solution_takes_no_step(case: str, method: str) -> None:
    """Converged at iteration 0, same u_h to 1e-12 of its largest value.  Fails on the old
    code for patch_p2 (diverged_max_it, every method) and step41/min (1 step)."""
    cold, again, diff = restart(*CASES[case], method)
    assert cold.converged, cold.reason
    assert again.converged and again.iterations == 0, (again.reason, again.iterations)
    assert again.reason == "converged_fnorm_abs" and diff <= 1e-12


@pytest.mark.parametrize("method", ["fb", "min"])
def test_a_hyperelastic_solve_from_its_own_solution_takes_one_step(method: str) -> None:
    """The energy line search forces one Newton step (its factorization tests the tangent's
    inertia: a start that is an equilibrium may be a saddle); one, and the same u_h."""
    cold, again, diff = restart(*CASES["hyperelastic"], method)
    assert cold.converged and again.converged and again.iterations == 1, again.reason
    assert diff <= 1e-12


RESTART = """
import json, sys
import contact
from contact.setup.build import build_problem
from dolfinx import fem
from mpi4py import MPI
import numpy as np
scene = contact.load_scene(sys.argv[1], ["mesh.degree=2", "output.verbose=false"])
out = {}
for method in ("fb", "min"):
    cold = contact.solve(scene, problem=build_problem(scene), method=method, sequence="off")
    u0 = fem.Function(cold.u_h.function_space)
    u0.x.array[:] = cold.u_h.x.array
    again = contact.solve(scene, problem=build_problem(scene), method=method, sequence="off",
                          u0=u0, verbose=False)
    diff = MPI.COMM_WORLD.allreduce(float(np.max(np.abs(again.u_h.x.array - u0.x.array))),
                                    op=MPI.MAX)
    size = MPI.COMM_WORLD.allreduce(float(np.max(np.abs(u0.x.array))), op=MPI.MAX)
    out[method] = [cold.converged, again.converged, again.iterations, diff / size,
                   again.contact_force]
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(out))
"""


@pytest.mark.mpi
def test_the_floating_p2_patch_restarts_on_two_ranks(tmp_path) -> None:
    """The P2 patch from its own solution on 1 and 2 ranks: no step, the same u_h and
    contact force (fails on the old code: diverged_max_it on both)."""
    runs = run_script(tmp_path, RESTART, PATCH_P2[0], (1, 2))
    for n in (1, 2):
        for method, (cold, ok, its, diff, _) in runs[n].items():
            assert cold and ok and its == 0 and diff <= 1e-12, (n, method, runs[n])
    for method in ("fb", "min"):
        assert runs[2][method][4] == pytest.approx(runs[1][method][4], rel=1e-10)
