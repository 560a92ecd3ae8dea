"""The adaptive loop at finite strain: a hyperelastic body against a rigid plane with
``adapt`` (the residual estimator in the reference configuration, Dörfler marking at the
load steps, u and the load step's state prolonged to the refined mesh and the step solved
again).

Checked: in the small-load limit the neo-Hookean estimator is the linear elastic one (the
same η to 1 % and the same cells marked: the same meshes level by level); along a load path
(``load.adapt: each``) every step refines on from the previous step's final mesh, η falls
with every level, the refined cells crowd the contact zone and the held corner, the
contact force equals the reaction at the held top, and the force converges; the refusals
that remain (friction, a curved obstacle) name the key."""

from __future__ import annotations

import csv
import json

import contact
from contact import ConfigError
from contact.post.resultants import contact_resultants
from contact.setup.run import refine

import numpy as np
import pytest
import yaml
from clirun import ROOT
from clirun import contact as cli
from mpi4py import MPI

CYLINDER = ROOT / "configs" / "hyperelastic_cylinder.yaml"


def test_small_load_estimator_is_the_linear_elastic_one():
    """configs/hertz_2d.yaml on a coarse mesh at indentation 0.001 R, three Dörfler levels:
    the neo-Hookean body's levels have the DoFs of the linear elastic body's levels (the
    same cells marked), its η and contact force agree to 1 % on every level, and its η
    falls with every level."""
    sets = [
        "mesh.h=0.2",
        "mesh.h_contact=0.05",
        "mesh.zone=0.3",
        "output.verbose=false",
        "reference=none",
        "constants.delta=0.001",
        "adapt.max_levels=3",
    ]
    runs = {}
    for model in (["model.type=elasticity"], ["model.type=hyperelastic", "model.law=neo_hookean"]):
        scene = contact.load_scene(ROOT / "configs" / "hertz_2d.yaml", sets + model)
        path = contact.run_load_path(scene, verbose=False)
        assert path.converged, path.stop
        runs[model[0]] = path.steps[-1].levels
    linear, neo = runs["model.type=elasticity"], runs["model.type=hyperelastic"]
    assert len(linear) == len(neo) == 3
    for a, b in zip(linear, neo):
        assert a.result.dofs == b.result.dofs
        assert b.estimate.eta == pytest.approx(a.estimate.eta, rel=1e-2)
        assert b.result.contact_force == pytest.approx(a.result.contact_force, rel=1e-2)
        assert b.estimate.eta != a.estimate.eta  # a different model, not the same numbers
    etas = [lv.estimate.eta for lv in neo]
    assert all(e1 < e0 for e0, e1 in zip(etas, etas[1:]))


def test_adaptive_load_path_refines_on_and_balances_forces():
    """configs/hyperelastic_cylinder.yaml (neo-Hookean, indentation 0.2 R) on a uniform
    h = 0.2 mesh, 2 load steps, ``load.adapt: each`` with 3 Dörfler levels a step: step 2
    starts on step 1's final mesh, the DoFs grow and η falls level by level, the smallest
    5 % of the cells lie in the contact zone (x < 0.8, y < 0.3; the arc touches the plane
    at the origin) or at the held corner (1, 1), where the arc meets the held top; every
    level's contact force equals the reaction at the held top to 1e-8; and the last level's
    force is closer to that of the start mesh refined uniformly 3 times than step 2's first
    level's, within 0.5 % of it, on less than half its DoFs."""
    sets = [
        "mesh.h=0.2",
        "mesh.h_contact=0.2",
        "load.steps=2",
        "load.adapt=each",
        "adapt.strategy=dorfler",
        "adapt.theta=0.5",
        "adapt.max_levels=3",
        "output.verbose=false",
    ]
    scene = contact.load_scene(CYLINDER, sets)
    path = contact.run_load_path(scene, verbose=False, keep_all=True)
    assert path.converged, path.stop
    first, second = path.steps
    assert len(first.levels) == len(second.levels) == 3
    assert second.levels[0].result.dofs == first.levels[-1].result.dofs
    for step in path.steps:
        dofs = [lv.result.dofs for lv in step.levels]
        etas = [lv.estimate.eta for lv in step.levels]
        assert all(d1 > d0 for d0, d1 in zip(dofs, dofs[1:]))
        assert all(e1 < e0 for e0, e1 in zip(etas, etas[1:]))
        for lv in step.levels:
            res = contact_resultants(lv.posed, lv.result)
            assert res["force_balance_error"] <= 1e-8, res
    # the reference: the start mesh refined uniformly 3 times (within 0.05 % of the limit:
    # demos/RESULTS.md §11.6), without adapt
    fine = contact.load_scene(CYLINDER, sets[:3] + ["output.verbose=false"])
    for _ in range(3):
        n = fine.mesh.topology.index_map(fine.mesh.topology.dim).size_local
        fine, _ = refine(fine, np.arange(n, dtype=np.int32))
    uniform = contact.run_load_path(fine, verbose=False)
    assert uniform.converged
    reference = uniform.steps[-1].result
    first, last = second.levels[0].result, second.levels[-1].result
    assert abs(last.contact_force / reference.contact_force - 1) < 5e-3
    assert abs(last.contact_force - reference.contact_force) < abs(
        first.contact_force - reference.contact_force
    )
    assert last.dofs < reference.dofs / 2
    # where the refinement went: the smallest cells of the final mesh
    msh = second.levels[-1].scene.mesh
    tdim = msh.topology.dim
    n = msh.topology.index_map(tdim).size_local
    h = msh.h(tdim, np.arange(n, dtype=np.int32))
    midpoints = msh.geometry.x[msh.geometry.dofmaps[0][np.argsort(h)[: max(1, n // 20)]]].mean(
        axis=1
    )  # centroids of the smallest 5 % of the cells
    near_contact = (midpoints[:, 1] < 0.3) & (midpoints[:, 0] < 0.8)
    near_corner = np.hypot(midpoints[:, 0] - 1.0, midpoints[:, 1] - 1.0) < 0.2
    comm = MPI.COMM_WORLD
    outside = comm.allreduce(int(np.sum(~(near_contact | near_corner))), op=MPI.SUM)
    assert outside == 0


@pytest.mark.parametrize(
    "change",
    [
        {"friction": {"law": "coulomb", "coefficient": 0.3}},
        {"obstacle": {"type": "circle", "center": [0.0, -1.0], "radius": 1.0}},
    ],
)
def test_adapt_refuses_what_it_does_not_estimate(change):
    """Friction and curved obstacles (estimator terms on the current configuration): one
    ConfigError naming ``adapt``."""
    cfg = {**yaml.safe_load(CYLINDER.read_text()), **change, "adapt": {"strategy": "dorfler"}}
    with pytest.raises(ConfigError, match="^adapt: the adaptive loop of model type hyperel"):
        contact.load_scene(cfg)


def _read(path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_cli_adaptive_hyperelastic_block_serial_equals_two_ranks(tmp_path):
    """The command of docs/guide/finite-strain.md (configs/block_on_plane.yaml made
    neo-Hookean, pressed 10 %, 2 steps, its adaptive loop at the last step) with 4 levels,
    serial and on 2 ranks: exit 0; convergence.csv's levels grow and their η falls;
    steps.csv's last step and summary.json report the last level's DoFs and the same force;
    the two runs have the same meshes level by level and the same η and
    forces to 1e-8."""
    args = [
        "run",
        str(ROOT / "configs" / "block_on_plane.yaml"),
        "-q",
        *("--set", "model.type=hyperelastic", "--set", "model.law=neo_hookean"),
        *("--set", "constants.delta=0.05", "--set", "load.steps=2"),
        *("--set", "adapt.max_levels=4"),
    ]
    runs = {}
    for ranks in (0, 2):
        out = tmp_path / f"np{ranks}"
        proc = cli(tmp_path, *args, "-o", str(out), ranks=ranks)
        assert proc.returncode == 0, proc.stderr[-2000:]
        levels = _read(out / "convergence.csv")
        steps = _read(out / "steps.csv")
        summary = json.loads((out / "summary.json").read_text())
        dofs = [int(r["dofs"]) for r in levels]
        etas = [float(r["eta"]) for r in levels]
        assert len(levels) == 4 and all(b > a for a, b in zip(dofs, dofs[1:]))
        assert all(b < a for a, b in zip(etas, etas[1:]))
        assert int(steps[-1]["dofs"]) == dofs[-1]
        assert summary["dofs"] == dofs[-1]
        assert summary["steps"][-1]["contact_force"] == pytest.approx(
            float(steps[-1]["contact_force"]), rel=1e-12
        )
        runs[ranks] = (dofs, etas, [float(r["contact_force"]) for r in steps])
    (d0, e0, f0), (d2, e2, f2) = runs[0], runs[2]
    assert d0 == d2
    np.testing.assert_allclose(e2, e0, rtol=1e-8)
    np.testing.assert_allclose(f2, f0, rtol=1e-8)
