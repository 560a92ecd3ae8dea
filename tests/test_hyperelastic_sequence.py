"""Grid sequencing (``solver.sequence``) of a hyperelastic body's load path.

The first step of a path (no previous solution) is solved on coarser meshes first, each
from the coarser solution, and the fine Newton iteration starts from the last one; later
steps start from the tangent predictor.  Checked on configs/hyperelastic_indentation.yaml
(a neo-Hookean block indented 0.4 R by a rigid cylinder, met on the current
configuration): the sequenced and the cold solve reach the same discrete solution (the
contact force to 1e-8) and the fine mesh takes fewer Newton steps; ``auto`` sequences a
body in 2D from 16k DoFs on (below, the coarse solves cost more than they save:
demos/bench/bench_hyperelastic.py sequence), in 3D never; coarse levels that all fail
(cells inverted at a large first load) fall back to the cold start with a warning;
serial = 2 ranks.  Contact pairs at finite strain take it on request only (``auto``: off).
"""

from __future__ import annotations

import warnings

import contact
from contact.base.errors import ContactWarning

import pytest
from clirun import ROOT

INDENTATION = ROOT / "configs" / "hyperelastic_indentation.yaml"


def indentation(cells: str, steps: int, sequence, *sets: str, verbose: bool = False):
    """The shipped indentation on ``cells`` (e.g. "80,40") in ``steps`` steps to 0.4 R with
    ``solver.sequence``: its load path."""
    scene = contact.load_scene(
        INDENTATION,
        [
            f"mesh.cells=[{cells}]",
            f"load.steps={steps}",
            f"solver.sequence={sequence}",
            "output.verbose=false",
            *sets,
        ],
    )
    with warnings.catch_warnings():  # the block's untagged sides carry σn = 0 (as shipped)
        warnings.filterwarnings("ignore", "boundary: .* exterior facet", ContactWarning)
        return contact.run_load_path(scene, verbose=verbose)


@pytest.mark.parametrize(
    "config, cells, option, levels",
    [
        ("hyperelastic_indentation", "80,40", "auto", 0),  # 6 642 DoFs: below 16k
        ("hyperelastic_indentation", "160,80", "auto", 2),  # 26 082: 6 642 and 1 722
        ("hyperelastic_indentation", "80,40", 2, 2),
        ("hyperelastic_sphere", "24,24,16", "auto", 0),  # 31 875 DoFs in 3D: not measured
        ("hyperelastic_sphere", "24,24,16", 1, 1),
    ],
)
def test_auto_sequences_a_hyperelastic_body_from_16k_dofs_in_2d(config, cells, option, levels):
    """``solver.sequence: auto`` plans coarse levels for a hyperelastic body in 2D from
    16 000 fine DoFs on (as many as keep the coarsest at ≥ 1 000), in 3D none; a number
    asks for that many."""
    from contact.setup.levels import plan

    scene = contact.load_scene(
        ROOT / "configs" / f"{config}.yaml",
        [f"mesh.cells=[{cells}]", f"solver.sequence={option}", "output.verbose=false"],
    )
    assert scene.config.solver.sequence == option
    builders, note = plan(scene, option, scene.mesh.geometry.dim, 1)
    assert len(builders) == levels and note == ""


@pytest.mark.parametrize("steps", [1, 3])
def test_sequenced_first_step_is_the_cold_solution_in_fewer_fine_newton_steps(steps):
    """80 × 40 cells (6 642 DoFs), two coarser levels (1 722 and 462 DoFs): every coarse
    level converges, the first step's fine Newton iteration is shorter than the cold one's,
    later steps are not sequenced, and every step's contact force is the cold path's to 1e-8."""
    cold = indentation("80,40", steps, "off")
    seq = indentation("80,40", steps, 2)
    assert cold.converged and seq.converged
    assert len(seq.steps) == len(cold.steps) == steps
    first, first_cold = seq.steps[0].result, cold.steps[0].result
    assert [lv.dofs for lv in first.sequence] == [462, 1722]
    assert all(lv.converged for lv in first.sequence)
    assert not first_cold.sequence
    assert first.iterations < first_cold.iterations
    assert all(not s.result.sequence for s in seq.steps[1:])
    for a, b in zip(seq.steps, cold.steps, strict=True):
        assert a.result.contact_force == pytest.approx(b.result.contact_force, rel=1e-8)
    assert cold.steps[-1].result.contact_force > 0.1  # the deep indentation, not a touch


def test_coarse_levels_that_all_fail_fall_back_to_the_cold_start(capsys):
    """0.9 R in one step on 40 × 20 cells: both coarse levels (462 and 132 DoFs) invert
    cells from the zero start and fail; the step falls back to the cold solve (a note, as
    the sequencing's other notes: printed when verbose, kept in ``Result.sequence_note``),
    not an error — that fails too and the path cuts the step — and the path ends at the
    cold path's contact force (1e-8)."""
    sets = ("constants.delta=0.45",)
    cold = indentation("40,20", 1, "off", *sets)
    seq = indentation("40,20", 1, 2, *sets, verbose=True)
    assert "grid sequencing: none of the 2 coarse level(s) converged; cold start" in (
        capsys.readouterr().out
    )
    assert cold.converged and seq.converged
    assert len(seq.cuts) == len(cold.cuts) >= 1  # the full step cut alike
    assert len(seq.steps) == len(cold.steps)
    for a, b in zip(seq.steps, cold.steps, strict=True):
        assert a.result.contact_force == pytest.approx(b.result.contact_force, rel=1e-8)


def test_pairs_at_finite_strain_sequence_on_request_only():
    """Hyperelastic bodies through contact pairs (re-coupled on the current configuration)
    take a number of coarse levels (tests/test_hyperelastic_pairs_adapt.py solves them);
    ``auto`` is off there."""
    scene = contact.load_scene(ROOT / "configs" / "hyperelastic_two_body_patch_2d.yaml")
    assert scene.config.solver.sequence == "off"
    scene = contact.load_scene(
        ROOT / "configs" / "hyperelastic_two_body_patch_2d.yaml", ["solver.sequence=2"]
    )
    assert scene.config.solver.sequence == 2


MPI_RUN = """
import json, sys, warnings
sys.path.insert(0, sys.argv[1])  # the tests folder
import contact
from test_hyperelastic_sequence import indentation
path = indentation("80,40", 2, 2)
r = path.steps[0].result
figures = [path.converged, [lv.dofs for lv in r.sequence], [lv.converged for lv in r.sequence],
           [s.result.contact_force for s in path.steps]]
from mpi4py import MPI
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(figures))
"""


@pytest.mark.mpi
def test_sequenced_path_serial_equals_two_ranks(tmp_path):
    """The sequenced path on 1 and 2 ranks: the same coarse levels, all converged, and the
    same contact force at every step (1e-8)."""
    from clirun import script_json

    tests = str(ROOT / "tests")
    out = {ranks: script_json(MPI_RUN, tmp_path, tests, ranks=ranks) for ranks in (1, 2)}
    assert out[1][0] and out[2][0]
    assert out[1][1] == out[2][1] == [462, 1722]
    assert all(out[1][2]) and all(out[2][2])
    assert out[2][3] == pytest.approx(out[1][3], rel=1e-8)
