"""Self-contact at finite strain in 3D after buckling: a neo-Hookean tube kinked by turning its
ends (configs/hyperelastic_self_contact_kink.yaml; a quarter, the symmetry planes x = 0 and
z = 0), displacement controlled past the limit point of its bending moment until the wall
on the inside of the bend, folded inward at the middle, lies on the opposite wall.  Checked:
the moment against beam theory at small rotation, its limit point and fall, the walls open
until well past the limit point and pressed together at the end near the middle, no
interpenetration (the mortar gap of the final configuration, and each slave node's signed
distance to the deformed master triangulation), the pair's y-forces opposite to 1e-8 and
without a moment, serial = 2 ranks."""

from pathlib import Path

import contact
from contact.drivers.recouple import COUPLING_RTOL
from contact.models.mortar import part_facets, surface_facets

import dolfinx.fem.petsc
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc
from test_bodies import run as run_script
from test_self_contact_3d import check_serial_equals_parallel, final_gaps, gathered

ROOT = Path(__file__).resolve().parents[1]
KINK = ROOT / "configs" / "hyperelastic_self_contact_kink.yaml"
SCRIPT = ROOT / "tests" / "hyperelastic_bodies_run.py"
H = 2.0 / 12  # the inner surface's longest facet edge (along the axis; 0.118 around)
#: the half section's second moment of area about the x axis, π/8 (R⁴ − r⁴)
INERTIA = np.pi / 8 * (1.0 - 0.9**4)


def nodal_forces(result, scene, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The current positions x = X + u and the internal forces (the residual without
    Dirichlet rows: the reaction on Γ_D, the contact force on a free interface node) of the
    given nodes, each on its owner rank only."""
    p = result.problem
    V = p.V
    F = dolfinx.fem.petsc.assemble_vector(p.data.reaction_form)
    F.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    owned = np.unique(nodes[nodes < V.dofmap.index_map.size_local])
    f = F.array_r.reshape(-1, 3)[owned].copy()
    F.destroy()
    x = V.tabulate_dof_coordinates()[owned] + result.u_h.x.array.reshape(-1, 3)[owned]
    return x, f


def end_moment(result, scene, time: float) -> float:
    """The bending moment M the turned end section carries, about its centre c = R(φ)(0, 0, a)
    (the end turned by −φ about the x axis: M = −Σ ((x_i − c) × R_i)_x over its nodes, R_i
    the reaction), summed over the ranks."""
    c = scene.config.constants
    phi, a = c["p"] * time, c["a"]
    X = result.problem.V.tabulate_dof_coordinates()
    x, f = nodal_forces(result, scene, np.flatnonzero(X[:, 2] > a - 1e-9))
    centre = np.array([0.0, a * np.sin(phi), a * np.cos(phi)])
    return -scene.comm.allreduce(float(np.cross(x - centre, f)[:, 0].sum()), op=MPI.SUM)


def part_nodes(result, scene, part: str) -> np.ndarray:
    return np.unique(surface_facets(result.problem.V, part_facets(scene.boundary, part)).nodes)


@pytest.fixture(scope="module")
def kink():
    scene = contact.load_scene(KINK, ["output.verbose=false"])
    path = []

    def on_step(step) -> None:
        r = step.result
        path.append((step.time, end_moment(r, scene, step.time), r.n_active))

    run = contact.run_load_path(scene, on_step=on_step, verbose=False)
    assert run.converged and run.steps[-1].time == 1.0
    return scene, run, np.array(path)


def test_the_moment_passes_its_limit_point_before_the_walls_touch(kink):
    """At φ = 0.1 the moment is the beam's E I φ / a (to 3 %); it peaks at an intermediate
    rotation (the limit point: a moment prescribed by load control could not go past it)
    and falls to under a tenth of its peak, the path followed by the end rotation with no
    step cut.  No slave node is pressed until φ = 0.8, long after the limit point; at the
    end the walls are pressed together near the middle, where the kink forms."""
    scene, run, path = kink
    c = scene.config.constants
    phi, moment, pressed = path[:, 0] * c["p"], path[:, 1], path[:, 2]
    assert abs(moment[0] / (INERTIA * phi[0] / c["a"]) - 1) <= 0.03
    peak = int(np.argmax(moment))
    assert 0 < peak < len(moment) - 1 and phi[peak] <= 0.5
    assert np.all(np.diff(moment[peak:]) < 0) and moment[-1] < 0.1 * moment[peak]
    assert not run.cuts and not run.branch_steps
    assert np.all(pressed[phi < 0.8 - 1e-12] == 0) and pressed[-1] >= 3
    r = run.steps[-1].result
    X = r.problem.V.tabulate_dof_coordinates()[r.problem.constraint.dofs // 3]
    at = gathered(scene.comm, X[r.active_mask.astype(bool)])
    assert len(at) == pressed[-1] and at[:, 2].max() <= 0.5


def test_the_walls_do_not_interpenetrate(kink):
    """The pair coupled afresh on the final configuration: its weighted gaps ≥ −COUPLING_RTOL
    (measured 2.4e-13), ≥ 3 of them 0 (touching).  Independently of the mortar projection:
    every slave node over the deformed master triangulation (mirrored in the symmetry
    planes) lies no deeper than 0.1 h² behind it and ≥ 3 lie within 0.1 h² of it (measured
    −9.7e-4 = −0.035 h², a pressed node on the plane z = 0: the mortar condition is weak,
    O(h²) where the master bends — it is a valley there, its facets meeting their mirror
    images at an angle, so a foot within 0.01 outside a facet counts as on it)."""
    scene, run, _ = kink
    # slack: the master is a valley at the plane z = 0 where the wall is pressed into it
    gap, over = final_gaps(scene, run.steps[-1].result, slack=0.01)
    assert gap.min() >= -COUPLING_RTOL and np.sum(np.abs(gap) <= 1e-8) >= 3
    assert len(over) >= 20
    assert over.min() >= -0.1 * H**2 and np.sum(np.abs(over) <= 0.1 * H**2) >= 3


def test_the_pair_forces_balance_without_a_moment(kink):
    """The y-forces on the slave part are those on the master part, reversed, to 1e-8 (no
    node of either part has y held: the master stops short of the turned end).  Their
    moments about the x and z axes through the middle section (Σ z f_y, Σ x f_y over both
    parts, x the current positions) cancel too, to 1e-4 of |F_y| times the tube's radius 1
    (measured 2e-5): the pair transmits no spurious couple (its nodal forces act at points
    that coincide in contact up to the weak O(h²) gap)."""
    scene, run, _ = kink
    r = run.steps[-1].result
    comm = scene.comm
    x, f = zip(
        *(nodal_forces(r, scene, part_nodes(r, scene, k)) for k in ("inner_top", "inner_bottom"))
    )
    slave, master = (comm.allreduce(fk.sum(axis=0), op=MPI.SUM) for fk in f)
    assert slave[1] > 1e-4  # the compressed (upper) wall is pushed up by the lower one
    assert abs(slave[1] + master[1]) <= 1e-8 * abs(slave[1])
    x, f = np.concatenate(x), np.concatenate(f)
    moments = comm.allreduce(np.array([(x[:, 2] * f[:, 1]).sum(), (x[:, 0] * f[:, 1]).sum()]))
    assert np.all(np.abs(moments) <= 1e-4 * abs(slave[1]))


def test_the_contact_force_is_the_whole_tubes_y_force(kink):
    """The scalar contact force is the size of the whole tube's normal contact force: 4 times
    the quarter's y-force on the slave wall (the mirror planes x = 0 and z = 0 both contain
    the pressing direction y; the quarter's x-force cancels against its mirror image), to
    1e-8.  The pressed nodes lie on the plane z = 0 and lean in x, away from any single
    node's normal: a force along one slave node's normal (the first point of contact) is
    not this."""
    scene, run, _ = kink
    r = run.steps[-1].result
    _, f = nodal_forces(r, scene, part_nodes(r, scene, "inner_top"))
    slave = scene.comm.allreduce(f.sum(axis=0), op=MPI.SUM)
    assert slave[1] > 1e-4
    assert abs(r.contact_force - 4 * slave[1]) <= 1e-8 * 4 * slave[1]


@pytest.mark.mpi
def test_two_ranks_equal_serial(tmp_path):
    """The scene on a coarser mesh in 6 load steps (walls pressed at the end): the same slave
    nodes, pressures to 1e-8, force to 1e-8, the first point of contact and its normal."""
    small = ["mesh.cells=[2,24,6]", "load.steps=6"]
    s, p = (run_script(tmp_path, KINK, n, *small, script=SCRIPT) for n in (1, 2))
    check_serial_equals_parallel(s, p, pressed=3, floor=1e-6)


def test_the_first_point_of_contact_is_a_pressed_node(kink):
    """The first point of contact and its normal come from a pressed node on the plane z = 0
    (ranked by the current gap): n within 2° of the quarter's slave y-force, and the pair's
    balance |F_s·n + F_m·n| / |F_s·n| measured along it is below 1e-4 (measured 1.3e-5).
    Ranked by the bound g^k + x_n(u^k) they were those of a node on the fold, not pressed,
    with n = (0.16, −0.38, 0.91) at 69° from the force (balance 3.8e-5 along it)."""
    scene, run, _ = kink
    r = run.steps[-1].result
    p, comm = r.problem, scene.comm
    X = gathered(comm, p.node_coordinates())
    pressed = gathered(comm, r.active_mask.astype(bool))
    (i,) = np.flatnonzero(np.all(np.abs(X - r.first_contact) <= 1e-14, axis=1))
    assert pressed[i] and abs(r.first_contact[2]) <= 1e-14
    F_s, F_m = r.interface_forces
    assert abs(p.data.n @ F_s) >= np.cos(np.radians(2)) * np.linalg.norm(F_s)
    assert abs(F_s @ p.data.n + F_m @ p.data.n) <= 1e-4 * abs(F_s @ p.data.n)
