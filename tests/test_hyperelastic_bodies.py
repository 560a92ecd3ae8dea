"""Two hyperelastic bodies in contact through dual-mortar pairs coupled on the current
configuration (contact/drivers/recouple.py): the finite-strain contact patch test (2D and 3D,
non-matching meshes: the interface pressure is the exact Cauchy traction at every slave node,
action = reaction), two neo-Hookean cylinders at δ = 0.001 R_c against Hertz, the coupling's
fixed point at a moderate load, serial = 2 ranks, a load step identical to the previous one,
and what the scene still refuses (friction: tests/test_hyperelastic_friction.py)."""

from pathlib import Path

import contact
from contact.base.errors import ConfigError
from contact.drivers.recouple import COUPLING_RTOL
from contact.models.hyperelastic import uniaxial_stretch
from contact.models.mortar import part_facets, surface_facets
from contact.post.hertz import compare
from contact.setup.posed import posed_of
from contact.solvers import owned_residual

import dolfinx.fem.petsc
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc
from test_bodies import run as run_script

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "tests" / "hyperelastic_bodies_run.py"
PATCH_2D = ROOT / "configs" / "hyperelastic_two_body_patch_2d.yaml"
PATCH_3D = ROOT / "configs" / "two_body_patch_3d.yaml"
HERTZ_2D = ROOT / "configs" / "two_body_hertz_2d.yaml"
P = 0.2  # the patch scenes' nominal pressure at t = 1
E, NU = 1.0, 0.3
# the 3D small-strain patch made a finite-strain one: one material, a 17 % compression
PATCH_3D_FINITE = [
    "model.type=hyperelastic",
    "model.law=neo_hookean",
    "bodies.upper.E=1.0",
    "bodies.upper.nu=0.3",
    f"constants.p={P}",
    'data.t=["0", "0", "-p * t"]',
    "load.steps=2",
    'solver.u0=["0", "0", "-0.001 * (z > 0.5 - 1e-10)"]',
]
HYPERELASTIC = ["model.type=hyperelastic", "model.law=neo_hookean", "adapt=none"]


def run(tmp_path, scene, nproc, *overrides):
    return run_script(tmp_path, scene, nproc, *overrides, script=SCRIPT)


def uniaxial(gdim: int, p: float = P) -> tuple[float, float]:
    """(λ_1, λ_2) of homogeneous uniaxial compression of the neo-Hookean material under the
    nominal stress P_22 = −p (secant iteration on the stretch λ_2)."""
    a, b = 0.7, 0.95
    fa, fb = (uniaxial_stretch("neo_hookean", E, NU, s, gdim)[1] + p for s in (a, b))
    for _ in range(60):
        a, b, fa = b, b - fb * (b - a) / (fb - fa), fb
        fb = uniaxial_stretch("neo_hookean", E, NU, b, gdim)[1] + p
        if abs(b - a) <= 1e-15:
            break
    return uniaxial_stretch("neo_hookean", E, NU, b, gdim)[0], b


def interface_force(result, scene, part: str) -> np.ndarray:
    """Σ F_i over the nodes of a boundary part: the internal force the body's interface
    nodes carry (the residual without Dirichlet rows), summed over all ranks."""
    p = result.problem
    V = p.V
    F = dolfinx.fem.petsc.assemble_vector(p.F_form)
    F.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    bs = V.dofmap.index_map_bs
    nodes = np.unique(surface_facets(V, part_facets(scene.boundary, part)).nodes)
    owned = np.zeros(V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts, bool)
    owned[nodes] = True
    owned[V.dofmap.index_map.size_local :] = False  # each node on its owner only
    local = F.array_r.reshape(-1, bs)[owned[: V.dofmap.index_map.size_local]].sum(axis=0)
    F.destroy()
    return scene.comm.allreduce(local, op=MPI.SUM)


@pytest.mark.parametrize("gdim", [2, 3])
def test_patch_pressure_is_the_exact_cauchy_traction_at_every_slave_node(gdim):
    path, overrides = (PATCH_2D, []) if gdim == 2 else (PATCH_3D, PATCH_3D_FINITE)
    scene = contact.load_scene(path, ["output.verbose=false", *overrides])
    run_ = contact.run_load_path(scene, verbose=False)
    assert run_.converged and len(run_.steps) == 2
    r = run_.steps[-1].result
    assert type(r.problem).__name__ == "MortarResidualProblem"
    # the coupling's fixed point: re-coupled at the solution, the solution stays
    assert len(r.couplings) == 2 and r.couplings[-1]["change"] <= 1e-12
    l1, l2 = uniaxial(gdim)
    p = r.problem
    on = slice(0, p.data.pair_nodes)
    pressure = p.pressure(owned_residual(r))[on]
    exact = P / l1 ** (gdim - 1)  # the force P over the deformed area l1^(d-1) of a unit one
    err = scene.comm.allreduce(float(np.max(np.abs(pressure / exact - 1), initial=0)), MPI.MAX)
    assert err <= 1e-8 and abs(exact / P - 1) > 0.05  # finite strain: 7 % (2D) off nominal
    # the homogeneous deformation u = (λ − 1) X, both blocks, every node
    X = p.V.tabulate_dof_coordinates()[:, :gdim]
    u = r.u_h.x.array.reshape(-1, gdim)
    want = X * np.r_[[l1 - 1] * (gdim - 1), l2 - 1]
    assert np.max(np.abs(u - want)) <= 1e-8 * (1 - l2)
    # action = reaction: the slave surface's force is the master's, reversed (normal axis)
    slave, master = interface_force(r, scene, "slave"), interface_force(r, scene, "master")
    area = 1.0  # the unit reference interface
    assert abs(slave[-1] - P * area) <= 1e-10 * P and abs(slave[-1] + master[-1]) <= 1e-12 * P


@pytest.mark.mpi
def test_patch_2d_two_ranks_equals_serial(tmp_path):
    s, p = run(tmp_path, PATCH_2D, 1), run(tmp_path, PATCH_2D, 2)
    l1, _ = uniaxial(2)
    for res in (s, p):
        assert res["converged"] and np.max(np.abs(res["pressure"] * l1 / P - 1)) <= 1e-8
    assert np.allclose(s["X"], p["X"], atol=1e-14)
    assert abs(s["force"] - p["force"]) <= 1e-12 * abs(s["force"])


def test_neo_hookean_cylinders_at_small_load_meet_hertz():
    """δ = 0.001 R_c (R_c = 8): p0 within 1 % of Hertz's for the computed force, the
    half-width within the mesh's resolution (h_contact = 0.02, a ≈ 8 h)."""
    scene = contact.load_scene(
        HERTZ_2D,
        [*HYPERELASTIC, "constants.delta=0.008", "mesh.h_contact=0.02", "mesh.zone=0.5"],
    )
    r = contact.solve(scene, verbose=False)
    assert r.converged and len(r.couplings) >= 2
    errors = compare(posed_of(scene), r, scene.config.reference).errors
    assert abs(errors["p0_error"]) < 0.01
    assert abs(errors["a_error"]) < 0.05


@pytest.fixture(scope="module")
def moderate(tmp_path_factory):
    """δ = 0.1 R_c on the default mesh: serial and 2 ranks."""
    tmp = tmp_path_factory.mktemp("moderate")
    args = [*HYPERELASTIC, "constants.delta=0.8"]
    return run(tmp, HERTZ_2D, 1, *args), run(tmp, HERTZ_2D, 2, *args)


@pytest.mark.mpi
def test_coupling_fixed_point_converges_linearly_at_moderate_load(moderate):
    for res in moderate:
        assert res["converged"]
        newton, change, error = res["couplings"].T
        assert len(change) >= 4  # the coupling moves: re-coupled several times
        # each re-coupling moves u less, by a factor ρ < 0.5 (linear convergence, Aitken-
        # relaxed: 11 couplings, 13 with the plain sequence) …
        rates = change[2:] / change[1:-1]
        assert np.all(rates < 0.5) and np.all(newton[1:] <= 2)
        # … down to the tolerance
        assert error[-1] <= COUPLING_RTOL < error[-2]
    s, p = moderate
    assert abs(s["force"] - p["force"]) <= 1e-10 * abs(s["force"])
    assert np.allclose(s["X"], p["X"], atol=1e-12)
    assert np.max(np.abs(s["pressure"] - p["pressure"])) <= 1e-8 * np.max(s["pressure"])


def test_identical_load_step_converges_from_the_solution():
    """Newton from a converged solution of the same problem converges at once.  Here the
    prescribed displacement alone inverts cells (Φ(x_D) undefined): the round-off floor of
    the stopping test is capped by the total force at a fraction of x_D; capped by 0 (rtol
    alone) the repeated solve ran to max_it."""
    scene = contact.load_scene(HERTZ_2D, [*HYPERELASTIC, "constants.delta=0.8"])
    r1 = contact.solve(scene, verbose=False)
    assert r1.converged
    r2 = contact.solve(scene, problem=r1.problem, u0=r1.u_h, verbose=False)
    assert r2.converged and r2.iterations <= 1, r2.reason


def test_what_two_hyperelastic_bodies_do_not_do_is_refused():
    """A rigid obstacle beside the pairs (one line naming the key)."""
    plane = ["obstacle.type=plane", "obstacle.point=[0, 2]", "obstacle.normal=[0, -1]"]
    with pytest.raises(ConfigError, match=r"^obstacle: "):
        contact.load_scene(PATCH_2D, plane)
