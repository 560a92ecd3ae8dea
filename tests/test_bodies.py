"""Two deformable bodies in contact through mortar pairs with dual multipliers (issue 13):
the contact patch test in 2D and 3D (serial and 2 ranks), every NCP method against
vinewtonrsls, serial = 2 ranks on a Hertz scene, the slave/master choice, the adaptive
loop on two bodies, the multi-body meshes, and one-line errors for bad pairs."""

import os
import subprocess
import sys
from pathlib import Path

import contact
from contact.base.errors import ConfigError
from contact.models.mortar import master_pressure
from contact.post.interface import resultants
from contact.post.reference import compare
from contact.setup.build import build_problem
from contact.setup.posed import posed_of

import numpy as np
import pytest
from mpi4py import MPI
from ties import tie_margin

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"
SCRIPT = ROOT / "tests" / "bodies_run.py"
PATCH_2D, PATCH_3D = (
    ROOT / "configs" / "two_body_patch_2d.yaml",
    ROOT / "configs" / "two_body_patch_3d.yaml",
)
HERTZ_2D = ROOT / "configs" / "two_body_hertz_2d.yaml"
COARSE_2D = ["mesh.h=2.0", "mesh.h_contact=0.1", "mesh.zone=1.0", "output.verbose=false"]
P = 0.01  # the patch tests' applied pressure


def run(tmp_path, scene, nproc, *args, script=SCRIPT):
    """The npz a runner ``script`` (default tests/bodies_run.py) writes for ``scene`` on
    ``nproc`` ranks."""
    out = tmp_path / f"np{nproc}.npz"
    cmd = [sys.executable, str(script), str(out), str(scene), *args]
    if nproc > 1:
        cmd = [str(MPIRUN), "-n", str(nproc)] + cmd
    subprocess.run(
        cmd, check=True, cwd=ROOT, timeout=300, env={**os.environ, "OMP_NUM_THREADS": "1"}
    )
    return dict(np.load(out))


@pytest.fixture(scope="module")
def patch_2d():
    scene = contact.load_scene(PATCH_2D, ["output.verbose=false"])
    return scene, build_problem(scene)


@pytest.mark.parametrize("method", ["fb", "min", "blend", "vinewtonrsls"])
def test_patch_2d_pressure_is_exact_at_every_slave_node(patch_2d, method):
    """Non-matching meshes (31 against 10 interface cells), two materials: λ_i = −p at every
    slave node and λ^m_j = −p at every master node to 1e-8 relative, forces balance."""
    scene, problem = patch_2d
    check_patch_2d(scene, problem, method, slave=32, master=11)


def check_patch_2d(scene, problem, method: str, slave: int, master: int) -> None:
    """Solve the 2D contact patch with ``method``: every one of the ``slave`` slave nodes
    pressed by p (no tie, no rounding can move it), λ_i = −p there and λ^m_j = −p at the
    ``master`` master nodes to 1e-8 relative, the interface forces balance and the contact
    force is p × width, mirrored at x = 0."""
    r = contact.solve(scene, method=method, problem=problem, verbose=False)
    assert r.converged
    lam = r.lmbda_h.x.array[problem.output.nodes]
    assert len(lam) == slave and r.n_active == slave
    assert np.max(np.abs(lam + P)) <= 1e-8 * P
    lam_m = master_pressure(r).x.array
    pressed = np.abs(lam_m) > 0
    assert pressed.sum() == master and np.max(np.abs(lam_m[pressed] + P)) <= 1e-8 * P
    res = resultants(posed_of(scene), r)
    assert res["interface_balance_error"] < 1e-10
    assert res["contact_force"] == pytest.approx(2 * P, rel=1e-10)


def test_patch_2d_estimator_vanishes(patch_2d):
    """The discrete solution is the exact uniform stress: every indicator term, on both
    sides of the interface, is round-off."""
    scene, problem = patch_2d
    r = contact.solve(scene, method="min", problem=problem, verbose=False)
    est = contact.estimate(scene, r)
    assert {"consistency", "consistency_master", "tangential", "complementarity"} <= set(est.terms)
    assert est.eta < 1e-9


def test_patch_3d_pressure_is_exact_at_every_slave_node():
    scene = contact.load_scene(PATCH_3D, ["output.verbose=false"])
    problem = build_problem(scene)
    for method in ("min", "vinewtonrsls"):
        r = contact.solve(scene, method=method, problem=problem, verbose=False)
        lam = r.lmbda_h.x.array[problem.output.nodes]
        # uniform p: every node far from a tie
        assert r.converged and len(lam) == 14 * 14 == r.n_active
        assert np.max(np.abs(lam + P)) <= 1e-6 * P, method


@pytest.mark.mpi
@pytest.mark.parametrize("scene, tol", [(PATCH_2D, 1e-8), (PATCH_3D, 1e-6)], ids=["2d", "3d"])
def test_patch_on_two_ranks_equals_serial(tmp_path, scene, tol):
    s = run(tmp_path, scene, 1, "--methods=fb,vinewtonrsls")
    p = run(tmp_path, scene, 2, "--methods=fb,vinewtonrsls")
    for method in ("fb", "vinewtonrsls"):
        for res in (s, p):
            assert res[f"{method}/info"][0] == 1
            assert np.max(np.abs(res[f"{method}/lambda"] + P)) <= tol * P
            assert np.max(np.abs(res[f"{method}/lambda_master"] + P)) <= tol * P
        assert np.allclose(s[f"{method}/Xs"], p[f"{method}/Xs"], atol=1e-14)
        assert np.max(np.abs(s[f"{method}/u"] - p[f"{method}/u"])) <= tol * np.max(
            np.abs(s[f"{method}/u"])
        )


@pytest.fixture(scope="module")
def hertz_runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("hertz2d")
    args = [f"--set={o}" for o in COARSE_2D]
    return run(tmp, HERTZ_2D, 1, *args), run(tmp, HERTZ_2D, 2, *args)


@pytest.mark.mpi
@pytest.mark.parametrize("which", [0, 1], ids=["serial", "2 ranks"])
@pytest.mark.parametrize("method", ["fb", "min", "blend"])
def test_hertz_2d_methods_agree_with_vinewtonrsls(hertz_runs, which, method):
    res = hertz_runs[which]
    info, ref = res[f"{method}/info"], res["vinewtonrsls/info"]
    # no node near a tie (tests/ties.py): the counts cannot move
    assert min(info[5], ref[5]) >= 1e-6
    assert info[0] == 1 and ref[0] == 1 and info[2] == ref[2] > 5
    assert np.max(np.abs(res[f"{method}/u"] - res["vinewtonrsls/u"])) <= 1e-8
    lam, lam_ref = res[f"{method}/lambda"], res["vinewtonrsls/lambda"]
    assert np.max(np.abs(lam - lam_ref)) <= 1e-8 * np.max(np.abs(lam_ref))


@pytest.mark.mpi
@pytest.mark.parametrize("method", ["fb", "min", "vinewtonrsls"])
def test_hertz_2d_serial_equals_two_ranks(hertz_runs, method):
    s, p = hertz_runs
    assert np.allclose(s[f"{method}/X"], p[f"{method}/X"], atol=1e-12)
    assert np.max(np.abs(s[f"{method}/u"] - p[f"{method}/u"])) <= 1e-8
    assert np.max(np.abs(s[f"{method}/lambda"] - p[f"{method}/lambda"])) <= 1e-8 * np.max(
        np.abs(s[f"{method}/lambda"])
    )
    assert min(s[f"{method}/info"][5], p[f"{method}/info"][5]) >= 1e-6  # no node near a tie
    assert s[f"{method}/info"][2] == p[f"{method}/info"][2]
    assert s[f"{method}/info"][4] < 1e-10 and p[f"{method}/info"][4] < 1e-10  # action = reaction


def test_slave_and_master_swapped_agree_within_discretization_error():
    """Which surface carries the multiplier changes the discrete problem, not the answer:
    the contact force and the peak pressure move by less than the mesh's Hertz error."""
    base = contact.load_scene(HERTZ_2D, COARSE_2D)
    # the lower arc is the slave now, the narrower one
    swapped = contact.load_scene(
        HERTZ_2D,
        COARSE_2D
        + [
            "boundaries.slave.where=abs(x) < 3 and y < 1",
            "boundaries.master.where=abs(x) < 2 and y > -1",
            "pairs=[{slave: master, master: slave}]",
        ],
    )
    figures = []
    for scene in (base, swapped):
        r = contact.solve(scene, method="min", verbose=False)
        assert r.converged
        figures.append({**resultants(posed_of(scene), r), **compare(posed_of(scene), r).values})
    a, b = figures
    assert abs(b["contact_force"] / a["contact_force"] - 1) < 0.01
    assert abs(b["peak_pressure"] / a["peak_pressure"] - 1) < 0.03
    assert max(abs(a["p0_error"]), abs(b["p0_error"])) < 0.05


def test_adaptive_two_bodies_refines_both_and_recouples():
    """Two Dörfler levels: both bodies refined (cells of each body multiply), the body tags
    and the curved arcs carried over, the coupling rebuilt with the same force balance."""
    scene = contact.load_scene(HERTZ_2D, COARSE_2D)
    out = contact.adapt(scene, max_levels=3, verbose=False)
    assert len(out.levels) == 3 and all(lv.result.converged for lv in out.levels)
    counts = []
    for lv in out.levels:
        tags = lv.scene.bodies
        n_owned = lv.scene.mesh.topology.index_map(2).size_local
        counts.append(
            [MPI.COMM_WORLD.allreduce(int(np.sum(tags.values[:n_owned] == k))) for k in (1, 2)]
        )
        res = resultants(lv.posed, lv.result)
        assert res["interface_balance_error"] < 1e-10 and res["mortar_coverage"] > 0.999
        # every vertex of the refined arcs lies on its circle (R = 8 about (0, ±8))
        X = lv.scene.mesh.geometry.x[:, :2]
        for tag, centre in ((1, (0.0, 8.0)), (3, (0.0, -8.0))):
            facets = lv.scene.surfaces.find(tag)
            from dolfinx.mesh import entities_to_geometry

            nodes = entities_to_geometry(lv.scene.mesh, 1, facets).ravel()
            assert np.allclose(np.linalg.norm(X[nodes] - centre, axis=1), 8.0, rtol=1e-12)
    assert counts[2][0] > counts[0][0] and counts[2][1] > counts[0][1]
    assert out.levels[-1].estimate.eta < out.levels[0].estimate.eta


def test_blocks_mesh_has_disconnected_bodies():
    scene = contact.load_scene(PATCH_2D, ["output.verbose=false"])
    msh = scene.mesh
    n_owned = msh.topology.index_map(2).size_local
    counts = [
        MPI.COMM_WORLD.allreduce(int(np.sum(scene.bodies.values[:n_owned] == k))) for k in (1, 2)
    ]
    assert counts == [2 * 10 * 5, 2 * 31 * 15]
    # no vertex is shared by the two bodies: the interface has two copies of its corners
    X = msh.geometry.x[:, :2]
    corner = np.flatnonzero(np.linalg.norm(X - [1.0, 0.5], axis=1) < 1e-12)
    assert MPI.COMM_WORLD.allreduce(len(corner)) >= 2


def _scene(**changes):
    import yaml

    cfg = yaml.safe_load(PATCH_2D.read_text())
    for key, value in changes.items():
        node = cfg
        *path, last = key.split(".")
        for part in path:
            node = node[part]
        node[last] = value
    return cfg


@pytest.mark.parametrize(
    "changes, message",
    [
        (
            {"pairs": [{"slave": "slave", "master": "slave"}]},
            "pairs[0].master: boundary part 'slave' is already the slave",
        ),
        (
            {"pairs": [{"slave": "slave", "master": "top"}]},
            "pairs[0].master: boundary part 'top' needs role: interface",
        ),
        (
            {"pairs": [{"slave": "slave", "master": "nowhere"}]},
            "pairs[0].master: 'nowhere' is not a boundary part",
        ),
        ({"boundaries.slave.body": "middle"}, "boundaries.slave.body: 'middle' is not a body"),
        ({"bodies.upper": {"E": 1.0}}, "bodies.upper: give exactly one of 'where' or 'tag'"),
        (
            {"bodies.upper": {"tag": 7, "E": 1.0}},
            "bodies.upper.tag: tag 7 does not exist in the mesh",
        ),
        (
            {"bodies.upper": {"where": "y > 0.4", "E": 1.0}},
            "bodies.upper: 20 of its cells belong to an earlier body",
        ),
        (
            {"bodies.upper": {"where": "y > 2", "E": 1.0}},
            "bodies.upper: where 'y > 2' selects no cell",
        ),
        ({"model.E": 1.0}, "model.E: a scene with bodies gives E (and nu) per body"),
        (
            {
                "pairs": [{"slave": "slave", "master": "master", "search": 1e-3}],
                "mesh.blocks": [
                    {"corners": [[0, 0], [1, 0.5]], "cells": [10, 5]},
                    {"corners": [[0.5, 0.5], [1.5, 1]], "cells": [31, 15]},
                ],
            },
            "pairs[0].slave: 16 slave node(s) of 'slave', e.g. at (",
        ),
        (
            {
                "mesh.blocks": [
                    {"corners": [[0, 0], [1, 0.5]], "cells": [10, 5]},
                    {"corners": [[0, 0.5], [1, 1]], "cells": [31, 15]},
                ],
                "boundaries.slave": {
                    "role": "interface",
                    "where": "abs(y - 0.5) < 1e-10 and x < 0.5",
                    "body": "upper",
                },
                "boundaries.master": {
                    "role": "interface",
                    "where": "abs(y - 0.5) < 1e-10 and x > 0.4",
                    "body": "upper",
                },
            },
            "boundaries: slave and master share",
        ),
    ],
)
def test_bad_pairs_are_one_line_errors(changes, message):
    with pytest.raises(ConfigError) as err:
        scene = contact.load_scene(_scene(**changes))
        build_problem(scene)
    text = str(err.value)
    assert "\n" not in text and text.startswith(message), text


def test_a_node_both_slave_and_master_is_refused():
    # the upper block's right side as the master: its corner (1, 0.5) is a slave node too
    cfg = _scene(
        **{
            "boundaries.master": {
                "role": "interface",
                "where": "abs(x - 1) < 1e-10",
                "body": "upper",
            }
        }
    )
    with pytest.raises(
        ConfigError, match="both a slave and a master|slave or master node of another"
    ):
        build_problem(contact.load_scene(cfg))


STACK = ROOT / "configs" / "two_body_stack_2d.yaml"


def test_pair_and_rigid_obstacle_in_one_scene():
    """A block on a wider block on a rigid floor: the force through the pair, the floor's
    force and the reaction on the pushed top balance; every method agrees with vinewtonrsls;
    the estimator has both the obstacle's and the pair's terms."""
    scene = contact.load_scene(STACK, ["output.verbose=false"])
    problem = build_problem(scene)
    ref = contact.solve(scene, method="vinewtonrsls", problem=problem, verbose=False)
    res = resultants(posed_of(scene), ref)
    F_pair, F_floor, F_top = (
        res["interface_force_slave"][1],
        res["obstacle_force"][1],
        res["reactions"]["top"][1],
    )
    assert F_pair > 0 and abs(F_floor / F_pair - 1) < 1e-10 and abs(F_top / F_pair + 1) < 1e-10
    assert res["interface_balance_error"] < 1e-10
    # min on the defaults: cycles guarded (contact.solvers.globalize)
    for method in ("fb", "min", "blend"):
        r = contact.solve(scene, method=method, problem=problem, verbose=False)
        assert r.converged and tie_margin(r) >= 1e-6  # no node near a tie: the counts cannot move
        assert r.n_active == ref.n_active
        assert np.max(np.abs(r.u_h.x.array - ref.u_h.x.array)) <= 1e-8 * np.max(
            np.abs(ref.u_h.x.array)
        )
    est = contact.estimate(scene, ref)
    assert est.terms["consistency_master"] > 0 and est.terms["consistency"] > 0


def test_three_blocks_two_pairs_patch_test():
    """Two interfaces in series (three blocks, three mesh sizes): the uniform pressure crosses
    both pairs exactly."""
    cfg = _scene(
        **{
            "mesh.blocks": [
                {"corners": [[0, 0], [1, 0.5]], "cells": [10, 5]},
                {"corners": [[0, 0.5], [1, 1]], "cells": [31, 15]},
                {"corners": [[0, 1], [1, 1.5]], "cells": [7, 4]},
            ],
            "bodies": {
                "lower": {"tag": 1, "E": 1.0, "nu": 0.3},
                "upper": {"tag": 2, "E": 3.0, "nu": 0.2},
                "cap": {"tag": 3, "E": 2.0, "nu": 0.25},
            },
            "boundaries.top": {"role": "neumann", "where": "y > 1.5 - 1e-10"},
            "boundaries.slave2": {
                "role": "interface",
                "where": "abs(y - 1) < 1e-10",
                "body": "upper",
            },
            "boundaries.master2": {
                "role": "interface",
                "where": "abs(y - 1) < 1e-10",
                "body": "cap",
            },
            "pairs": [
                {"slave": "slave", "master": "master"},
                {"slave": "slave2", "master": "master2"},
            ],
            "solver.u0": ["0", "-1e-4 * (y > 0.5 - 1e-10) - 1e-4 * (y > 1 - 1e-10)"],
        }
    )
    scene = contact.load_scene(cfg)
    r = contact.solve(scene, method="min", verbose=False)
    lam = r.lmbda_h.x.array[r.problem.output.nodes]
    # uniform p: every node far from a tie
    assert r.converged and len(lam) == 32 + 32 == r.n_active
    assert np.max(np.abs(lam + P)) <= 1e-8 * P


def test_gmsh_file_with_one_physical_surface_per_body(tmp_path):
    """A .msh file with two physical surfaces (the bodies) and tagged curves: bodies by tag,
    the pair by facet tags."""
    import gmsh

    path = tmp_path / "two.msh"
    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        occ = gmsh.model.occ
        lower, upper = occ.addRectangle(0, 0, 0, 1, 0.5), occ.addRectangle(0, 0.5, 0, 1, 0.5)
        occ.synchronize()
        curves = {}
        for surface in (lower, upper):
            for _, c in gmsh.model.getBoundary([(2, surface)], oriented=False):
                x, y, _ = occ.getCenterOfMass(1, c)
                curves[(surface, round(x, 3), round(y, 3))] = c
        tags = {
            "bottom": (lower, 0.5, 0.0),
            "master": (lower, 0.5, 0.5),
            "slave": (upper, 0.5, 0.5),
            "top": (upper, 0.5, 1.0),
        }
        for k, (name, key) in enumerate(tags.items(), start=1):
            gmsh.model.addPhysicalGroup(1, [curves[key]], k, name=name)
        gmsh.model.addPhysicalGroup(2, [lower], 11, name="lower")
        gmsh.model.addPhysicalGroup(2, [upper], 12, name="upper")
        gmsh.model.mesh.setSize(gmsh.model.getEntities(0), 0.1)
        gmsh.model.mesh.setSize(gmsh.model.getBoundary([(2, upper)], recursive=True), 0.037)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    cfg = {
        "mesh": {"type": "gmsh", "file": str(path)},
        "bodies": {"lower": {"tag": 11, "E": 1.0}, "upper": {"tag": 12, "E": 3.0, "nu": 0.2}},
        "boundaries": {
            "bottom": {"role": "dirichlet", "tag": 1},
            "top": {"role": "neumann", "tag": 4},
            "master": {"role": "interface", "tag": 2},
            "slave": {"role": "interface", "tag": 3},
        },
        "pairs": [{"slave": "slave", "master": "master"}],
        "model": {"type": "elasticity"},
        "data": {"t": ["0", f"-{P}"]},
        "solver": {"u0": ["0", "-1e-4 * (y > 0.5 - 1e-10)"]},
        "output": {"verbose": False},
    }
    scene = contact.load_scene(cfg)
    r = contact.solve(scene, method="min")
    lam = r.lmbda_h.x.array[r.problem.output.nodes]
    assert r.converged and r.n_active == len(lam) > 20  # every slave node pressed by ≈ p: no tie
    # the bottom is clamped (not a roller): the stress is not uniform near the corners, but the
    # total force is p × width and it crosses the interface unchanged
    res = resultants(posed_of(scene), r)
    assert res["interface_force_slave"][1] == pytest.approx(P, rel=1e-10)
    assert res["interface_balance_error"] < 1e-10


def test_cli_run_writes_both_bodies_and_the_slave_table(tmp_path):
    """contact run on the patch test: solution.vtu holds u_h, λ_h, lambda_master and the DG0
    body number, contact.csv one row per slave node, summary.json the interface forces."""
    import csv
    import json

    import pyvista

    out = tmp_path / "patch"
    proc = subprocess.run(
        [sys.executable, "-m", "contact.app.cli", "run", str(PATCH_2D), "-o", str(out), "-q"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    grid = pyvista.read(out / "solution.vtu")
    assert {"u_h", "lambda_h", "lambda_master", "gap", "active"} <= set(grid.point_data)
    assert {"body", "von_mises"} <= set(grid.cell_data)
    assert sorted(np.unique(grid.cell_data["body"])) == [1, 2]
    rows = list(csv.DictReader(open(out / "contact.csv")))
    assert len(rows) == 32 and all(abs(float(r["lambda_n"]) + P) < 1e-8 * P for r in rows)
    info = json.loads((out / "summary.json").read_text())
    assert info["interface_balance_error"] < 1e-10
    # every force of the whole body (issue 26): the symmetry plane x = 0 doubles the modelled
    # unit width, the pressure P acts on width 2, the x components cancel between the halves
    assert info["symmetric_copies"] == 2
    assert info["contact_force"] == pytest.approx(2 * P, rel=1e-10)
    assert info["interface_force_slave"] == pytest.approx([0.0, 2 * P], rel=1e-10, abs=0.0)
    assert info["interface_force_master"] == pytest.approx([0.0, -2 * P], rel=1e-10, abs=0.0)


def test_readme_two_body_example_validates():
    import re

    from contact.setup.config import validate_scene

    import yaml

    section = (ROOT / "docs" / "guide" / "two-bodies.md").read_text()
    cfg = validate_scene(yaml.safe_load(re.search(r"```yaml\n(.*?)```", section, re.S).group(1)))
    assert cfg.pairs[0].slave == "slave" and cfg.bodies["upper"].E == 3.0


CATTANEO = ROOT / "configs" / "two_body_cattaneo_2d.yaml"


@pytest.fixture(scope="module")
def cattaneo_runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cattaneo")
    out = []
    for nproc in (1, 2):
        path = tmp / f"np{nproc}.npz"
        cmd = [
            sys.executable,
            str(ROOT / "tests" / "cattaneo_run.py"),
            str(path),
            str(CATTANEO),
            "--set=mesh.h_contact=0.02",
        ]
        subprocess.run(
            ([str(MPIRUN), "-n", "2"] if nproc > 1 else []) + cmd,
            check=True,
            cwd=ROOT,
            timeout=300,
            env={**os.environ, "OMP_NUM_THREADS": "1"},
        )
        out.append(dict(np.load(path)))
    return out


@pytest.mark.mpi
def test_cattaneo_mindlin_partial_slip(cattaneo_runs):
    """Two identical cylinders, Coulomb F = 0.3, P then Q as forces: pressing alone makes
    no tangential force (the common normal), and at Q/(F P) = 0.25, 0.5, 0.75 the stick
    zone c/a = √(1 − Q/(F P)) within 3 % and q(x) within 10 % (5 % at 0.5 and 0.75) in L²,
    on a 17k-DoF mesh (the figures of RESULTS.md are finer)."""
    steps = cattaneo_runs[0]["steps"]
    assert np.all(steps[:, 0] == 1)
    assert abs(steps[0, 1]) < 1e-3  # t = 0.5: P only
    assert np.allclose(steps[1:, 1], [0.25, 0.5, 0.75], atol=0.005)  # Q/(F P)
    assert np.all(np.abs(steps[1:, 4]) < 0.03)  # c/a
    assert np.all(steps[1:, 5] < 0.10) and np.all(steps[2:, 5] < 0.05)  # q(x) in L²


@pytest.mark.mpi
def test_cattaneo_mindlin_serial_equals_two_ranks(cattaneo_runs):
    s, p = cattaneo_runs
    assert np.allclose(s["nodes"][:, :2], p["nodes"][:, :2], atol=1e-12)
    scale = np.max(np.abs(s["nodes"][:, 2:]))
    assert np.max(np.abs(s["nodes"][:, 2:] - p["nodes"][:, 2:])) <= 1e-8 * scale
    # step 1: Q ~ 1e-7, ratios of round-off
    assert np.allclose(s["steps"][1:], p["steps"][1:], rtol=1e-8, atol=1e-10)


def test_reaction_force_of_two_bodies_with_friction_is_the_supports():
    """steps.csv's reaction_force (surface_figures) of the Cattaneo scene (coarse, two steps):
    the reaction of the clamp, its only Dirichlet part, as interface_resultants finds it on
    the part's own facets; in x the clamp alone holds the lower body, which carries no load,
    so it equals the tangential force the interface transmits (the contact force on the
    slave body).  Before issue 26 it summed the solver's rotated unknowns and the rollers'
    DoFs: [9e-15, -0.32] against a clamp reaction of [-1.05, 1.53]."""
    from contact.post.friction_resultants import surface_figures
    from contact.post.interface import interface_resultants

    scene = contact.load_scene(
        CATTANEO, ["output.verbose=false", "mesh.h_contact=0.05", "load.times=[0.5,0.875]"]
    )
    path = contact.run_load_path(scene)
    last = path.steps[-1]
    assert path.converged
    figures = surface_figures(last.posed, last.result)
    clamp = interface_resultants(last.posed, last.result)["reactions"]["clamp"]
    assert figures["reaction_force"] == pytest.approx(clamp, rel=1e-10)
    F_x = figures["contact_force"][0]
    assert abs(F_x) > 0.5 and figures["reaction_force"][0] == pytest.approx(F_x, rel=1e-8)
