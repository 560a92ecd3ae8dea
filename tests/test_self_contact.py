"""Self-contact at finite strain: a neo-Hookean ring squeezed until its inner faces touch
(configs/hyperelastic_self_contact_ring.yaml), one body whose two boundary parts are a
dual-mortar pair coupled on the current configuration.  Checked: the faces touch and do not
interpenetrate (the mortar gap of the final configuration, and each slave node's signed
distance to the deformed master polyline), action = reaction on the pair to 1e-8, serial =
2 ranks; the Aitken-relaxed coupling against the plain fixed point; the ring mesh and the
self-contact pair's one-line errors."""

from pathlib import Path
from types import SimpleNamespace

import contact
from contact.base.errors import ConfigError
from contact.drivers import recouple
from contact.drivers.recouple import COUPLING_RTOL, solve_recoupled
from contact.models import mortar
from contact.models.mortar import part_facets, surface_facets
from contact.models.problem import TOUCH_RTOL
from contact.output.run_report import UNFACED_NOTE
from contact.setup.elastic import scene_pairs
from contact.solvers import owned_residual

import numpy as np
import pytest
import ufl
from clirun import run_scene
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from readback import read_xdmf
from scene_runs import read_folder
from test_bodies import run as run_script
from test_hyperelastic_bodies import interface_force

ROOT = Path(__file__).resolve().parents[1]
RING = ROOT / "configs" / "hyperelastic_self_contact_ring.yaml"
SCRIPT = ROOT / "tests" / "hyperelastic_bodies_run.py"
H = 2 * np.pi * 0.8 / 96  # the inner surface's facet length


@pytest.fixture(scope="module")
def ring():
    scene = contact.load_scene(RING, ["output.verbose=false"])
    run = contact.run_load_path(scene, verbose=False)
    assert run.converged and run.steps[-1].time == 1.0
    return scene, run.steps[-1].result


def gathered(comm, a: np.ndarray) -> np.ndarray:
    return np.concatenate(comm.allgather(a))


def test_inner_faces_touch_and_do_not_interpenetrate(ring):
    """At the end of the load path ≥ 6 slave nodes are pressed, their weighted gaps are 0
    and no gap is below −COUPLING_RTOL; geometrically, no slave node lies deeper than
    0.05 h² behind the deformed master polyline."""
    scene, r = ring
    p, comm = r.problem, scene.comm
    u = r.u_h.x.array
    assert r.n_active >= 6
    # the pair coupled afresh on the final configuration: its weighted gaps (the contact
    # condition the solver enforced, at the coupling of its own configuration)
    (pair,) = scene_pairs(scene, p.data.ds)
    fixed = np.concatenate([bc.dof_indices()[0] for bc in p.data.u_bcs])
    gap = gathered(comm, mortar.couple(p.V, pair, fixed, displacement=u).gap)
    assert gap.min() >= -COUPLING_RTOL and np.sum(np.abs(gap) <= 1e-8) >= 6  # touching
    # independently of the mortar projection: each slave node's signed distance to the
    # deformed master polyline (outward normals), ≥ 0 up to the mortar's weak enforcement,
    # O(h²) where the master surface bends (measured −4.8e-5 = −0.018 h²)
    slave = surface_facets(p.V, part_facets(scene.boundary, "inner_top"), u)
    master = surface_facets(p.V, part_facets(scene.boundary, "inner_bottom"), u)
    xs = gathered(comm, slave.X.reshape(-1, 2))
    A, B, n = (gathered(comm, a) for a in (master.X[:, 0], master.X[:, 1], master.normals))
    t = np.clip(np.einsum("sfd,fd->sf", xs[:, None] - A, B - A) / np.sum((B - A) ** 2, 1), 0, 1)
    closest = A + t[..., None] * (B - A)
    dist = np.linalg.norm(xs[:, None] - closest, axis=2)
    k = np.argmin(dist, axis=1)
    side = np.einsum("sd,sd->s", xs - closest[np.arange(len(xs)), k], n[k])
    signed = np.sign(side) * dist[np.arange(len(xs)), k]
    assert signed.min() >= -0.05 * H**2 and np.sum(np.abs(signed) <= 1e-3 * H) >= 3


def test_contact_force_balances_on_the_pair(ring):
    """The nodal forces on the slave part are those on the master part, reversed, to 1e-8
    (Qᵀ hands the slave force to the master nodes through the same c_ij); the pair pushes
    the upper wall up (the residual at a node: the force the rest of the world exerts
    there), and the scene's contact force is its size |Σ D_ii p_i n_i| to 1e-8 (along the
    normal of one node, the first point of contact, it was 8.7e-5 smaller)."""
    scene, r = ring
    slave, master = (interface_force(r, scene, part) for part in ("inner_top", "inner_bottom"))
    assert slave[1] > 0.05
    assert np.linalg.norm(slave + master) <= 1e-8 * np.linalg.norm(slave)
    assert abs(r.contact_force - np.linalg.norm(slave)) <= 1e-8 * np.linalg.norm(slave)


def test_first_contact_is_a_node_that_touches(ring):
    """On a current configuration the first point of contact is ranked by the current gap
    (then by the bound, then by coordinates), not by the bound g^k + x_n(u^k) alone: the
    node ``Result.first_contact`` and ``ProblemData.n`` name is pressed, its gap on the final
    configuration is 0 to the coupling's tolerance and no slave node's is smaller by more
    than the ties' tolerance; n is that node's normal.  (Ranked by the bound it was a node
    off the contact zone, (−0.444, 0.665), with no pressure.)"""
    scene, r = ring
    p, comm = r.problem, scene.comm
    on = slice(0, p.data.pair_nodes)
    X, normals = (gathered(comm, a[on]) for a in (p.node_coordinates(), p.data.normals))
    current = gathered(comm, p.data.current_gap[on])
    pressure = gathered(comm, p.pressure(owned_residual(r))[on])
    (i,) = np.flatnonzero(np.all(np.abs(X - r.first_contact) <= 1e-14, axis=1))
    assert pressure[i] > 0 and abs(current[i]) <= 1e-8
    assert current[i] <= current.min() + TOUCH_RTOL
    assert np.allclose(p.data.n, normals[i], rtol=0, atol=1e-14)
    # the pair coupled afresh on the final configuration: the node touches there too
    (pair,) = scene_pairs(scene, p.data.ds)
    fixed = np.concatenate([bc.dof_indices()[0] for bc in p.data.u_bcs])
    c = mortar.couple(p.V, pair, fixed, displacement=r.u_h.x.array)
    Xc = gathered(comm, p.V.tabulate_dof_coordinates()[c.nodes, :2])
    gap = gathered(comm, c.gap)
    assert abs(gap[np.all(np.abs(Xc - r.first_contact) <= 1e-14, axis=1)][0]) <= 1e-8


@pytest.mark.mpi
def test_two_ranks_equal_serial(tmp_path):
    s, p = (run_script(tmp_path, RING, n, script=SCRIPT) for n in (1, 2))
    for res in (s, p):
        assert res["converged"] and np.sum(res["pressure"] > 0) >= 6
    assert np.allclose(s["X"], p["X"], atol=1e-14)
    assert abs(s["force"] - p["force"]) <= 1e-10 * abs(s["force"])
    assert np.max(np.abs(s["pressure"] - p["pressure"])) <= 1e-8 * np.max(s["pressure"])
    assert np.allclose(s["first_contact"], p["first_contact"], rtol=0, atol=1e-14)
    assert np.allclose(s["n"], p["n"], rtol=0, atol=1e-8)


def apart(tmp_path: Path) -> Path:
    """The ring squeezed by 2 × 0.05 in two steps, its pair searching 0.1 along the normals:
    the inner faces, 1.5 apart, never face each other within reach."""
    text = RING.read_text()
    for old, new in (
        (
            "{slave: inner_top, master: inner_bottom}",
            "{slave: inner_top, master: inner_bottom, search: 0.1}",
        ),
        ("constants: {d: 0.83}", "constants: {d: 0.05}"),
        ("load: {steps: 8}", "load: {steps: 2}"),
    ):
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "ring_apart.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("ranks", [0, pytest.param(2, marks=pytest.mark.mpi)])
def test_a_pair_facing_nowhere_writes_readable_outputs(tmp_path, ranks):
    """A self-contact pair none of whose slave nodes faces the master: no node constrained,
    contact force 0, every file read back; the gap (NaN off the constrained nodes) is
    undefined at every node and contact.csv has its header only, which summary.json notes
    (``unfaced_steps``, ``unfaced_note``) — before, nothing said so and the all-NaN gap
    failed the readback."""
    out, _ = run_scene(tmp_path, str(apart(tmp_path)), ranks, [], 300)
    summary = read_folder(out)
    assert summary["unfaced_steps"] == [1, 2] and summary["unfaced_note"] == UNFACED_NOTE
    assert [s["contact_force"] for s in summary["steps"]] == [0.0, 0.0]
    with open(out / "contact.csv") as fh:
        assert fh.read().splitlines() == ["x,y,s,lambda_n,gap,active"]
    gaps = [read_xdmf(out / "contact_surface.xdmf")[-1], read_xdmf(out / "solution.xdmf")[-1]]
    assert all(np.isnan(g["point"]["gap"]).all() for g in gaps)
    assert all(np.isfinite(g["point"]["u_h"]).all() for g in gaps)


def fixed_point(A: np.ndarray, b: np.ndarray, relaxation: str, max_couplings: int = 60):
    """solve_recoupled on the affine map ũ ↦ A ũ + b (a stand-in for 'solve with the
    coupling frozen at ũ'): the driver's logic without a finite-element solve (its guess
    functions are plain arrays, see the ``vectors`` fixture)."""
    space = SimpleNamespace(
        mesh=SimpleNamespace(comm=MPI.COMM_SELF),
        dofmap=SimpleNamespace(index_map=SimpleNamespace(size_local=len(b)), index_map_bs=1),
    )

    def solve(problem, guess):
        u = A @ problem.at + b
        return SimpleNamespace(
            u_h=SimpleNamespace(x=SimpleNamespace(array=u)),
            problem=SimpleNamespace(destroy=lambda: None),
            history=[{"residual": 0.0}],
            iterations=1,
            converged=True,
        )

    start = SimpleNamespace(x=SimpleNamespace(array=np.zeros(len(b))))
    build = lambda at: SimpleNamespace(V=space, at=at)  # noqa: E731
    return solve_recoupled(build, solve, start, max_couplings, relaxation)


@pytest.fixture
def vectors(monkeypatch):
    """fem.Function(V) in the driver made a plain array of V's size."""

    def function(V):
        return SimpleNamespace(x=SimpleNamespace(array=np.zeros(V.dofmap.index_map.size_local)))

    monkeypatch.setattr(recouple.fem, "Function", function)


def test_aitken_relaxation_converges_where_the_plain_fixed_point_flips(vectors):
    """Modes with multipliers −1.3 and 0.2 (the plain sequence flips between growing mirror
    states, as the ring's lobes did): the plain sequence diverges, Aitken's relaxation
    reaches the fixed point to COUPLING_RTOL.  Multipliers 0.9 and 0.5 (slow and monotone,
    as two cylinders pressed far): Aitken needs a quarter of the plain couplings or less.
    (One factor for all modes: a spectrum reaching both −1.3 and 0.9 is not helped.)"""
    b = np.ones(2)
    flips = np.diag([-1.3, 0.2])
    plain = fixed_point(flips, b, "none")
    assert not plain.converged and plain.reason == "diverged_couplings"
    relaxed = fixed_point(flips, b, "aitken")
    assert relaxed.converged and len(relaxed.couplings) <= 30
    u, exact = relaxed.u_h.x.array, np.linalg.solve(np.eye(2) - flips, b)
    assert np.max(np.abs(u - exact)) <= 10 * COUPLING_RTOL * np.max(np.abs(u))
    slow = np.diag([0.9, 0.5])
    n_plain = len(fixed_point(slow, b, "none", 400).couplings)
    relaxed = fixed_point(slow, b, "aitken")
    assert relaxed.converged and len(relaxed.couplings) * 4 <= n_plain
    u, exact = relaxed.u_h.x.array, np.linalg.solve(np.eye(2) - slow, b)
    assert np.max(np.abs(u - exact)) <= 10 * COUPLING_RTOL * np.max(np.abs(u))


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["mesh.inner_radius=1.2"], r"^mesh\.inner_radius: must lie between 0 and radius 1"),
        (["mesh.cells=[96]"], r"^mesh\.cells: a ring mesh needs 2 cell count\(s\)"),
        (["mesh.diagonal=crossed"], r"^mesh\.diagonal: a ring takes left or right"),
        (["mesh.map=[x, y]"], r"^mesh\.map: not used by mesh type 'ring'"),
    ],
)
def test_ring_mesh_errors_are_one_line(overrides, message):
    with pytest.raises(ConfigError, match=message):
        contact.load_scene(RING, overrides)


def test_self_contact_parts_sharing_a_node_are_refused():
    """The master part reaching the slave part's end node: one line naming the node."""
    overrides = [
        "boundaries.inner_bottom.where=x*x + y*y < 0.81 and (y < 1e-9 or x > 0.44)",
        "boundaries.inner_sides.where=x*x + y*y < 0.81 and y > -1e-9 and x < -0.44",
    ]
    scene = contact.load_scene(RING, ["output.verbose=false", *overrides])
    with pytest.raises(ConfigError, match=r"^pairs: the node at \(0\.44\d*, 0\.66\d*\) is both"):
        contact.solve(scene, verbose=False)


def test_ring_mesh_is_one_closed_body():
    """The ring mesh closes on itself (no seam): n_θ (n_r + 1) vertices, its boundary two
    closed polygons of n_θ facets each, area π (R² − r²) up to the inscribed polygons'."""
    scene = contact.load_scene(RING, ["output.verbose=false"])
    msh = scene.mesh
    comm = msh.comm
    assert msh.topology.index_map(0).size_global == 96 * 4
    msh.topology.create_connectivity(1, 2)
    exterior = dmesh.exterior_facet_indices(msh.topology)
    owned = exterior[exterior < msh.topology.index_map(1).size_local]
    assert comm.allreduce(len(owned), op=MPI.SUM) == 2 * 96
    area = comm.allreduce(fem.assemble_scalar(fem.form(1.0 * ufl.dx(msh))))
    polygon = 0.5 * 96 * np.sin(2 * np.pi / 96) * (1.0 - 0.8**2)
    assert abs(area - polygon) <= 1e-12
