"""The same answer on any number of MPI ranks (issue 10, defect 5): adaptive meshes do not
depend on how round-off split mirror-image indicators (marking within a relative 1e-6 of
its threshold) nor on DOLFINx's vertex numbers (equally long edges of a face decided by the
coordinates, contact.adaptivity.longest_edge), and Newton's generalized-Jacobian element at
a kink does not depend on the sign of round-off (ties within 1e-12 of the global scale of
(a, b), contact.solvers.ncp): with Newton steps solved to the linear solver's tolerance the
Newton path is the same; inexact GAMG steps depend on the partition, the answer does not.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from clirun import MPIRUN, ROOT, contact

HERTZ_FIRST_SOLVE = """
import json, sys
from mpi4py import MPI
import contact
scene = contact.load_scene(sys.argv[1])
# the cold start on the direct solver: GAMG's aggregates (hence inexact steps) depend on the
# partition
r = contact.solve(scene, verbose=False, sequence="off", linear="direct")
rows = [(h["active"], h["changed"]) for h in r.history]
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps({"iterations": r.iterations, "polish": r.polish_solves, "history": rows}))
"""


def run_script(tmp_path: Path, source: str, scene: str, ranks: tuple[int, ...]) -> dict:
    """Run ``source`` on ``configs/<scene>`` under mpirun on each number of ranks: the JSON
    its rank 0 prints last, by number of ranks."""
    script = tmp_path / "script.py"
    script.write_text(source)
    runs = {}
    for n in ranks:
        proc = subprocess.run(
            [str(MPIRUN), "-n", str(n), sys.executable, str(script), str(ROOT / "configs" / scene)],
            capture_output=True,
            text=True,
            timeout=300,
            cwd=tmp_path,
        )
        assert proc.returncode == 0, proc.stderr
        runs[n] = json.loads(proc.stdout.strip().splitlines()[-1])
    return runs


@pytest.fixture(scope="module")
def lshape_runs(tmp_path_factory) -> dict[int, list[dict]]:
    """configs/lshape_corner.yaml, 6 adaptive levels, by the CLI on 1, 3 and 4 ranks."""
    out = {}
    for ranks in (1, 3, 4):
        folder = tmp_path_factory.mktemp(f"lshape{ranks}")
        proc = contact(
            folder,
            "run",
            str(ROOT / "configs" / "lshape_corner.yaml"),
            "-o",
            "out",
            "-q",
            "--set",
            "adapt.max_levels=6",
            "--set",
            "output.png=false",
            "--set",  # the estimator whose mirror-image ties the test below recalls
            "estimator=residual",
            ranks=ranks,
        )
        assert proc.returncode == 0, proc.stderr
        out[ranks] = list(csv.DictReader(open(folder / "out" / "convergence.csv")))
    return out


@pytest.mark.parametrize("ranks", [3, 4])
def test_lshape_adaptive_meshes_identical_on_any_number_of_ranks(lshape_runs, ranks: int) -> None:
    one, many = lshape_runs[1], lshape_runs[ranks]
    assert len(one) == len(many) == 6
    assert [int(r["dofs"]) for r in one] == [int(r["dofs"]) for r in many]
    assert [int(r["cells"]) for r in one] == [int(r["cells"]) for r in many]
    eta1, eta_n = (np.array([float(r["eta"]) for r in rows]) for rows in (one, many))
    np.testing.assert_allclose(eta_n, eta1, rtol=1e-10, atol=0)
    # the level the partition used to change (80 DoFs on 4 ranks against 78 on 1): the
    # two mirror-image cells at the threshold are now marked together
    assert int(one[1]["dofs"]) == 80


def test_hertz_2d_newton_path_identical_on_1_and_2_ranks(tmp_path: Path) -> None:
    """Before: 9 Newton steps on 1 rank, 8 on 2–4 (a contact node with gap exactly 0 whose
    round-off multiplier sign picked the Jacobian branch at the first step).  The whole path
    is compared: every kink is decided with the tie tolerance τ = 10⁻¹² × the problem's
    scale, and no (a_i, b_i) of this scene lands within round-off of τ, so the path does not
    depend on rounding."""
    runs = run_script(tmp_path, HERTZ_FIRST_SOLVE, "hertz_2d.yaml", (1, 2))
    assert runs[1] == runs[2]
    assert runs[1]["history"][0] == [1, 0]  # the node at the origin touches: in contact everywhere


STACK_SOLVES = """
import json, sys
from mpi4py import MPI
import contact
scene = contact.load_scene(sys.argv[1])
out = {}
for method in ("fb", "min"):
    r = contact.solve(scene, method=method, verbose=False)
    history = [(h["active"], h["residual"]) for h in r.history]
    out[method] = {"converged": r.converged, "history": history, "force": r.contact_force}
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(out))
"""


def test_two_body_first_iterate_identical_on_1_and_3_ranks(tmp_path: Path) -> None:
    """two_body_stack_2d (issue 26): the cold start had 21 / 23 / 21 / 1 active nodes and a
    different ‖Φ‖ on 1–4 ranks.  Two causes: the initial guess lacked the Dirichlet values
    (the bodies' DirichletBC on the unknowns read DoF indices as node numbers, so each
    partition fixed other DoFs), and every contact node is a tie (gap ±1e-16 from the
    coordinates, multiplier 0) decided with τ = 10⁻¹² × max|a|, max|b| — itself round-off
    there.  Now τ is relative to the coordinates' size as well (Constraint.scale): every
    one of the 38 contact nodes is at the biactive point (|a_i| ≤ 1e-15 ≪ τ = 1e-12, b_i = 0)
    and in contact at iteration 0 on any partition, and the whole path is the same."""
    runs = run_script(tmp_path, STACK_SOLVES, "two_body_stack_2d.yaml", (1, 3))
    for method in ("fb", "min"):
        one, three = runs[1][method], runs[3][method]
        assert one["converged"] and three["converged"]
        assert one["history"][0][0] == three["history"][0][0] == 38
        assert abs(one["history"][0][1] - three["history"][0][1]) <= 1e-12 * one["history"][0][1]
        assert abs(one["force"] - three["force"]) <= 1e-10 * one["force"]
        # the same path: every kink decided with τ, none within round-off of it (see the
        # hertz test above)
        assert [a for a, _ in one["history"]] == [a for a, _ in three["history"]]


NEXT_DOFS = """
import json, sys
from mpi4py import MPI
import contact
from contact.adaptivity.mark import mark
from contact.adaptivity.refine import next_dofs_bound
from contact.setup.run import refine
from dolfinx import fem
scene = contact.load_scene(sys.argv[1])
rows = []
for level in range(4):
    r = contact.solve(scene, verbose=False)
    cells = mark(contact.estimate(scene, r).eta_T, "dorfler", 0.5)
    bound = next_dofs_bound(scene.mesh, cells, r.u_h.function_space)
    scene, u0 = refine(scene, cells, r.u_h)
    rows.append([bound, u0.function_space.dofmap.index_map.size_global])
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(rows))
"""


def test_next_dofs_bound_identical_on_any_number_of_ranks(tmp_path: Path) -> None:
    """The adaptive loop's lower bound on the next level's DoFs (its stop message) counts
    each marked edge once on its owning rank.  Before, an edge owned by one rank but marked
    only through another rank's cells was missed (problem A at 1.23M DoFs: 1919257 serially,
    1919249 on 2 ranks)."""
    runs = run_script(tmp_path, NEXT_DOFS, "lshape_corner.yaml", (1, 3))
    assert runs[1] == runs[3]
    # a lower bound of the refined mesh's DoFs
    assert all(bound <= dofs for bound, dofs in runs[1])


SEQUENCE_CHAIN = """
import json, sys
import numpy as np
from mpi4py import MPI
import ufl
from dolfinx import fem
import contact
from contact.setup.levels import transfer
comm = MPI.COMM_WORLD
scene = first = contact.load_scene(sys.argv[1], ["mesh.cells=[16,16]"])
for _ in range(5):     # Dörfler: local refinement, each child mesh redistributed (adapt.rebalance)
    r = contact.solve(scene, method="min", verbose=False, sequence="off")
    scene, _ = contact.refine(scene, contact.mark(contact.estimate(scene, r).eta_T, "dorfler", 0.5))
seq = contact.solve(scene, method="min", verbose=False, sequence=2)
cold = contact.solve(scene, method="min", verbose=False, sequence="off", linear="direct")
gap = comm.allreduce(float(np.max(np.abs(seq.u_h.x.array - cold.u_h.x.array))), op=MPI.MAX)
norm = comm.allreduce(fem.assemble_scalar(fem.form(cold.u_h ** 2 * ufl.dx)), op=MPI.SUM) ** 0.5
# the chain's prolongation is exact for P1 data: the same piecewise-linear function, so the same
# integral of its square (a wrong parent cell would extrapolate another cell's plane)
u = fem.Function(fem.functionspace(first.mesh, ("Lagrange", 1)))
u.interpolate(lambda x: np.sin(3 * x[0]) * np.exp(x[1]))
fine = transfer(u, first, scene)
square = lambda f: comm.allreduce(fem.assemble_scalar(fem.form(f ** 2 * ufl.dx)), op=MPI.SUM)
chain = abs(square(fine) - square(u)) / square(u)
if comm.rank == 0:
    print(json.dumps({"dofs": seq.dofs, "levels": [lv.dofs for lv in seq.sequence], "gap": gap,
                      "norm": norm, "chain": chain}))
"""


def test_sequencing_through_a_rebalanced_refinement_chain(tmp_path: Path) -> None:
    """A scene refined by contact.refine on 2 and 3 ranks, each child mesh redistributed by
    the graph partitioner: the prolongation through the chain of ancestors (pulling each
    node's value from the rank that created its cell) carries a P1 function from the first
    mesh to the last unchanged (the same ∫ u² to 1e-12), and grid sequencing gives the cold direct
    answer, with the serial run's meshes and norm."""
    runs = run_script(tmp_path, SEQUENCE_CHAIN, "signorini_free_boundary.yaml", (1, 2, 3))
    for n, run in runs.items():
        # an ancestor several levels up
        assert run["levels"] and run["levels"][-1] * 4 <= run["dofs"], run
        assert run["gap"] <= 1e-8 and run["chain"] <= 1e-12, (n, run)
        assert run["dofs"] == runs[1]["dofs"] and run["levels"] == runs[1]["levels"], (n, run)
        assert abs(run["norm"] - runs[1]["norm"]) <= 1e-10 * runs[1]["norm"], (n, run)


TWO_BODY_SEQUENCED = """
import json, sys
from mpi4py import MPI
import contact
from contact.post.reference import compare
from contact.setup.posed import posed_of
sets = ["adapt=null", "mesh.h_contact=0.025", "output.verbose=false"]
scene = contact.load_scene(sys.argv[1], sets)
r = contact.solve(scene, verbose=False, method="fb")
values = compare(posed_of(scene), r).values
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps({"levels": [lv.dofs for lv in r.sequence], "converged": bool(r.converged),
                      "force": r.contact_force, "a": values["contact_half_width"],
                      "p0_error": values["p0_error"]}))
"""


def test_two_body_grid_sequencing_same_answer_on_1_2_and_3_ranks(tmp_path: Path) -> None:
    """two_body_hertz_2d sequenced (a coarser gmsh mesh first, each body's points carried in
    that body's coarse cells, gathered on every rank): the same levels and, to solver
    tolerance, the same force, contact half-width and peak pressure on 1, 2 and 3 ranks."""
    runs = run_script(tmp_path, TWO_BODY_SEQUENCED, "two_body_hertz_2d.yaml", (1, 2, 3))
    serial = runs[1]
    assert serial["converged"] and len(serial["levels"]) >= 1
    for n in (2, 3):
        assert runs[n]["converged"] and runs[n]["levels"] == serial["levels"], runs[n]
        assert runs[n]["force"] == pytest.approx(serial["force"], rel=1e-8)
        assert runs[n]["a"] == pytest.approx(serial["a"], rel=1e-12)
        assert runs[n]["p0_error"] == pytest.approx(serial["p0_error"], abs=1e-8)


MESH_DIGESTS = '''
import hashlib
import numpy as np
from mpi4py import MPI
from dolfinx import mesh as dmesh

def gathered(a):
    """The rows of all ranks' ``a``, sorted lexicographically, on rank 0."""
    parts = MPI.COMM_WORLD.gather(np.ascontiguousarray(a, dtype=float), root=0)
    if parts is not None:
        rows = np.concatenate(parts)
        return rows[np.lexsort(rows.T[::-1])]

def mesh_digest(scene):
    """[vertices, cells, SHA-256 of the sorted vertex coordinates, of the sorted cell
    midpoints with their body tags] on rank 0: the same mesh, the same digest."""
    msh = scene.mesh
    tdim = msh.topology.dim
    owned = np.arange(msh.topology.index_map(tdim).size_local, dtype=np.int32)
    body = np.zeros(len(owned))
    if scene.bodies is not None:
        keep = scene.bodies.indices < len(owned)
        body[scene.bodies.indices[keep]] = scene.bodies.values[keep]
    cells = np.column_stack([dmesh.compute_midpoints(msh, tdim, owned), body])
    X = gathered(msh.geometry.x[: msh.geometry.index_map().size_local])
    C = gathered(cells)
    if X is not None:
        digest = lambda a: hashlib.sha256(a.tobytes()).hexdigest()[:16]
        return [len(X), len(C), digest(X), digest(C)]
'''

TIED_REFINEMENT = (
    MESH_DIGESTS
    + """
import json, sys
import contact
comm = MPI.COMM_WORLD
scene = contact.load_scene(sys.argv[1])
rows = []
for level in range(3):
    msh = scene.mesh
    for dim in (1, 2):
        msh.topology.create_entities(dim)
    msh.topology.create_connectivity(2, 0)
    # faces (owned) whose two longest edges have exactly the same length
    f2v = msh.topology.connectivity(2, 0).array.reshape(-1, 3)
    f2v = f2v[: msh.topology.index_map(2).size_local]
    vertices = msh.topology.index_map(0)
    node = np.empty(vertices.size_local + vertices.num_ghosts, dtype=np.int64)
    node[msh.topology.connectivity(3, 0).array] = msh.geometry.dofmaps[0].ravel()
    p = msh.geometry.x[node[f2v]]
    sides = np.sort(np.linalg.norm(p - p[:, [1, 2, 0]], axis=2), axis=1)
    ties = comm.allreduce(int(np.count_nonzero(sides[:, 2] == sides[:, 1])), op=MPI.SUM)
    rows.append([mesh_digest(scene), ties])
    # marked by position: the same cells on any partition
    n = msh.topology.index_map(3).size_local
    mid = dmesh.compute_midpoints(msh, 3, np.arange(n, dtype=np.int32))
    cells = np.flatnonzero(np.linalg.norm(mid, axis=1) < 0.08).astype(np.int32)
    scene, _ = contact.refine(scene, cells)
if comm.rank == 0:
    print(json.dumps(rows))
"""
)


def test_refinement_of_tied_faces_identical_on_1_2_and_3_ranks(tmp_path: Path) -> None:
    """The sphere on a block (3D, two bodies): its gmsh mesh has faces whose two longest edges
    have exactly the same length, which DOLFINx's refinement decided by partition-dependent
    global vertex numbers — the cells around the origin refined twice gave other cells on 2
    ranks (level 1) and 3 ranks (level 2) than on one, the adaptive two_body_hertz_3d other
    DoFs (level 2: 67,464 on 1 rank, 67,461 on 2).  Now the longest edge of a tied face is
    chosen by the coordinates (contact.adaptivity.longest_edge): the same vertices, cells and
    body tags on 1, 2 and 3 ranks."""
    runs = run_script(tmp_path, TIED_REFINEMENT, "two_body_hertz_3d.yaml", (1, 2, 3))
    serial = runs[1]
    assert [row[1] > 0 for row in serial] == [True] * 3  # tied faces at every level
    assert serial[2][0][1] > 4 * serial[0][0][1]  # refined cells around the origin
    assert runs[2] == serial and runs[3] == serial


TWO_BODY_ADAPTIVE = (
    MESH_DIGESTS
    + """
import json, sys
import contact
scene = contact.load_scene(sys.argv[1], ["output.verbose=false"])
rows = []
def record(level):
    rows.append({"mesh": mesh_digest(level.scene), "dofs": level.result.dofs,
                 "eta": level.estimate.eta, "force": level.result.contact_force,
                 "converged": bool(level.result.converged)})
contact.adapt(scene, max_levels=4, verbose=False, on_level=record)
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(rows))
"""
)


def test_two_body_adaptive_meshes_identical_on_1_2_and_3_ranks(tmp_path: Path) -> None:
    """two_body_hertz_2d through the adaptive loop (two bodies, mortar pairs, body and
    interface tags carried to each refined mesh): per level the same DoFs, vertices, cells
    and body tags on 1, 2 and 3 ranks, and η and the contact force to solver tolerance."""
    runs = run_script(tmp_path, TWO_BODY_ADAPTIVE, "two_body_hertz_2d.yaml", (1, 2, 3))
    serial = runs[1]
    assert len(serial) == 4 and all(row["converged"] for row in serial)
    assert serial[-1]["dofs"] > 2 * serial[0]["dofs"]
    for n in (2, 3):
        assert len(runs[n]) == 4
        for one, many in zip(serial, runs[n]):
            assert many["mesh"] == one["mesh"] and many["dofs"] == one["dofs"], (n, many, one)
            assert many["eta"] == pytest.approx(one["eta"], rel=1e-8)
            assert many["force"] == pytest.approx(one["force"], rel=1e-8)


NEWTON_3D = """
import json, sys
from mpi4py import MPI
import contact
scene = contact.load_scene(sys.argv[1], ["mesh.h=0.5", "mesh.h_contact=0.04"])
out = {}
for name, options in (("direct", {"linear": "direct"}),
                      ("gamg_exact", {"linear": "gamg", "inexact": False}),
                      ("gamg_inexact", {"linear": "gamg"})):
    r = contact.solve(scene, verbose=False, **options)
    out[name] = {"converged": bool(r.converged), "iterations": r.iterations,
                 "polish": r.polish_solves, "active": r.n_active, "force": r.contact_force,
                 "history": [(h["active"], h["residual"]) for h in r.history]}
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(out))
"""


def test_newton_path_on_any_number_of_ranks_when_steps_are_exact(tmp_path: Path) -> None:
    """two_body_hertz_3d's first level, on a coarse mesh, on 1 and 3 ranks.  Each Newton
    step solved to the linear solver's tolerance — MUMPS, or CG + GAMG without the
    inexact-Newton forcing — gives the same Newton path: the active set and ‖Φ‖ of every
    iterate, the iterations and the polishing solves.  The default inexact steps stop CG
    at the forcing tolerance, and GAMG's aggregates depend on the partition, so the iterates
    do too (on the scene's own mesh: 9 Newton steps + 2 polishing solves on one rank, 8 + 1
    on two).  What holds there is the answer: the same active set and contact force to
    solver tolerance."""
    runs = run_script(tmp_path, NEWTON_3D, "two_body_hertz_3d.yaml", (1, 3))
    for name in ("direct", "gamg_exact"):
        _same_newton_path(runs[1][name], runs[3][name])
    _same_newton_path(runs[1]["direct"], runs[1]["gamg_exact"])
    reference = runs[1]["direct"]
    for run in runs.values():
        for solve in run.values():
            assert solve["converged"] and solve["active"] == reference["active"], solve
            assert solve["force"] == pytest.approx(reference["force"], rel=1e-10), solve


def _same_newton_path(one: dict, other: dict) -> None:
    """The same iterations, polishing solves, active sets and ‖Φ‖ (to 10⁻⁶; the last one is
    round-off about 0)."""
    assert one["converged"] and other["converged"]
    assert (other["iterations"], other["polish"]) == (one["iterations"], one["polish"])
    assert [a for a, _ in other["history"]] == [a for a, _ in one["history"]]
    residuals = [[r for _, r in run["history"][:-1]] for run in (one, other)]
    assert residuals[1] == pytest.approx(residuals[0], rel=1e-6)
