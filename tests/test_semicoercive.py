"""Case (l) of the stability map: a body held only by contact (configs/semicoercive.yaml,
no Dirichlet part, K singular on the inactive set), at 32² (serial, a few seconds).

Documented behaviour: a load whose resultant does not push the body onto the obstacle is
rejected at assembly (ConfigError naming data.f: no solution / no unique solution); with a
pushing load fb converges from the cold start to the solution PETSc's semismooth VI solver
finds, and the contact force carries the whole load; min's first cold step solves K itself,
and CG + GAMG breaks down on it: a non-converged result whose message names the cause."""

from __future__ import annotations

import json
from pathlib import Path

import contact
from contact.base.errors import ConfigError
from contact.setup.build import build_problem
from contact.solvers.result import SEMICOERCIVE_HINT, not_converged_text

import numpy as np
import pytest
from ties import tie_margin

SCENE = Path(__file__).resolve().parents[1] / "configs" / "semicoercive.yaml"


@pytest.mark.parametrize(
    "f, what", [("-1", "pulls it away from the obstacle"), ("0", "is zero"), ("1 - 2*x", "is zero")]
)
def test_a_load_not_pushing_onto_the_obstacle_is_bad_input(f: str, what: str) -> None:
    scene = contact.load_scene(SCENE, [f"data.f={f}", "mesh.cells=[8,8]"])
    with pytest.raises(ConfigError, match=r"^data\.f: the scene has no dirichlet boundary") as err:
        build_problem(scene)
    assert what in str(err.value)


def test_the_check_needs_the_whole_resultant() -> None:
    """A pushing body load with a pulling Neumann flux: the resultant decides (∫f = 1 on
    the square, the flux t on the three free sides of total length 3)."""
    push = contact.load_scene(SCENE, ["mesh.cells=[8,8]", "data.t=-0.3"])  # 1 − 0.9 > 0
    assert build_problem(push).semicoercive
    pull = contact.load_scene(SCENE, ["mesh.cells=[8,8]", "data.t=-0.4"])  # 1 − 1.2 < 0
    with pytest.raises(ConfigError, match="= -0.2 pulls"):
        build_problem(pull)
    clamped = contact.load_scene(
        Path(SCENE).parent / "signorini_square.yaml", ["mesh.cells=[8,8]", "data.f=-1"]
    )
    assert not build_problem(clamped).semicoercive  # a Dirichlet part: any load is fine


def test_fb_solves_the_semicoercive_scene_like_the_vi_solver() -> None:
    scene = contact.load_scene(SCENE)
    fb = contact.solve(scene, method="fb", verbose=False)
    ssls = contact.solve(scene, method="vinewtonssls", max_it=100, verbose=False)
    assert fb.converged and ssls.converged and fb.hint == ""
    assert tie_margin(fb) >= 1e-6  # no node near a tie: the counts cannot move with rounding
    assert fb.n_active > 0 and fb.n_active == ssls.n_active
    assert np.max(np.abs(fb.u_h.x.array - ssls.u_h.x.array)) < 1e-8
    # nothing else holds the body: the contact force carries the whole load, ∫f = Σ b_i
    assert fb.contact_force == pytest.approx(fb.problem.b.sum(), rel=1e-9)
    gap = fb.gap.x.array[np.isfinite(fb.gap.x.array)]
    assert gap.min() > -1e-12


def test_min_with_cg_gamg_fails_on_the_singular_first_step_and_says_why() -> None:
    """With exact CG + GAMG steps the singular first system is a failed linear solve, and
    the message says why.  Not a path: K y = −Φ has no solution there (K singular along the
    constants, the pushing load's resultant along them), so CG cannot reach its tight
    tolerance.  With the default inexact steps the loose first tolerance may be met — on
    this CPU with 1 of 3 perturbed loads (CONTACT_TEST_PERTURB) — and min recovers from the
    huge step, as with MUMPS: that outcome depends on rounding and is not asserted."""
    scene = contact.load_scene(SCENE)
    r = contact.solve(scene, method="min", linear="gamg", inexact=False, verbose=False)
    assert not r.converged and r.reason == "diverged_linear_solve" and r.iterations == 0
    assert r.history[0]["active"] == 0  # the cold start: no node active, H = K
    assert r.hint == SEMICOERCIVE_HINT and SEMICOERCIVE_HINT in not_converged_text(r)


def test_two_ranks_reject_the_pulling_load_and_solve_the_pushing_one(tmp_path: Path) -> None:
    """Under mpirun -n 2: the same one-line exit 2 for a pulling load, and fb's serial answer
    (active nodes, contact force) for the pushing one."""
    from clirun import contact as cli

    bad = cli(
        tmp_path,
        "run",
        str(SCENE),
        "-o",
        str(tmp_path / "bad"),
        "--set",
        "data.f=-1",
        "-q",
        ranks=2,
    )
    lines = [ln for ln in bad.stderr.splitlines() if ln.strip()]
    assert (
        bad.returncode == 2 and len(lines) == 1 and lines[0].startswith("contact: error: data.f: ")
    )
    assert not (tmp_path / "bad").exists()
    ok = cli(
        tmp_path,
        "run",
        str(SCENE),
        "-o",
        str(tmp_path / "ok"),
        "--set",
        "output.png=false",
        "-q",
        ranks=2,
    )
    assert ok.returncode == 0, ok.stderr
    summary = json.loads((tmp_path / "ok" / "summary.json").read_text())
    serial = contact.solve(contact.load_scene(SCENE), method="fb", verbose=False)
    assert tie_margin(serial) >= 1e-6  # no node near a tie: the count cannot move with rounding
    assert summary["active_nodes"] == serial.n_active
    assert summary["contact_force"] == pytest.approx(serial.contact_force, rel=1e-9)


# ------------------------------------------------------------------------- issue 26
APART = {  # two blocks 0.1 apart; the upper one, loaded on top, is held by nothing but contact
    "name": "apart",
    "mesh": {
        "type": "blocks",
        "blocks": [
            {"corners": [[0, 0], [1, 0.5]], "cells": [10, 5]},
            {"corners": [[0, 0.6], [1, 1.1]], "cells": [11, 5]},
        ],
    },
    "bodies": {"lower": {"tag": 1, "E": 1.0}, "upper": {"tag": 2, "E": 3.0, "nu": 0.2}},
    "boundaries": {
        "top": {"role": "neumann", "where": "y > 1.1 - 1e-10"},
        "bottom": {"role": "dirichlet", "where": "y < 1e-10"},
        "slave": {"role": "interface", "where": "abs(y - 0.6) < 1e-10", "body": "upper"},
        "master": {"role": "interface", "where": "abs(y - 0.5) < 1e-10", "body": "lower"},
    },
    "pairs": [{"slave": "slave", "master": "master"}],
    "model": {"type": "elasticity"},
    "data": {"t": ["0", "-0.01"]},
    "output": {"png": False},
}


@pytest.mark.parametrize("ranks", [0, 2])
def test_two_bodies_apart_fail_with_the_singular_stiffness_hint(tmp_path: Path, ranks: int) -> None:
    """Exit 1 after 50 iterations with no word on why: now the line names the body no
    condition holds and its free rigid motions (x, y and the rotation), on any rank count.
    Whether Newton gets there at all is decided by the linear solver's null pivots (serial
    MUMPS stalls; on 2 ranks it has now and then converged to a copy of the solution slid
    along x): such a converged run must then carry the non-unique warning instead."""
    import yaml
    from clirun import contact as cli
    from clirun import error_lines

    (tmp_path / "apart.yaml").write_text(yaml.safe_dump(APART))
    proc = cli(
        tmp_path,
        "run",
        "apart.yaml",
        "-o",
        "out",
        "-q",
        ranks=ranks,
        env={"PYTHONWARNINGS": "default"},
    )
    if proc.returncode == 0:  # rounding found a solution: one of many, and said so
        assert "the displacement is not unique: body upper keeps" in proc.stderr, proc.stderr
        return
    assert proc.returncode == 1
    (line,) = error_lines(proc)
    assert (
        "(body upper: no dirichlet or symmetry part holds it, 3 rigid motion(s) free: K is "
        "singular until contact holds it" in line
    ), line
    assert not (tmp_path / "out").exists()


# the same blocks touching: contact holds the upper one's vertical motion and its rotation,
# nothing holds its sliding along x
TOUCHING = {
    **APART,
    "mesh": {
        "type": "blocks",
        "blocks": [
            {"corners": [[0, 0], [1, 0.5]], "cells": [10, 5]},
            {"corners": [[0, 0.5], [1, 1.0]], "cells": [11, 5]},
        ],
    },
    "boundaries": {
        **APART["boundaries"],
        "top": {"role": "neumann", "where": "y > 1.0 - 1e-10"},
        "slave": {"role": "interface", "where": "abs(y - 0.5) < 1e-10", "body": "upper"},
    },
}


@pytest.mark.parametrize("ranks", [0, 2])
def test_a_body_only_contact_holds_gets_a_non_unique_warning(tmp_path: Path, ranks: int) -> None:
    """The upper block pressed onto the lower one converged in one step and was written
    without a word although any sliding of it along x solves the problem as well (K is
    singular on that motion; u_h was whichever null pivot the linear solver met).  Now the
    converged iterate is checked: the rigid motions that neither the Dirichlet rows nor the
    active contact rows hold are named in one warning line (the displacement is not unique;
    stresses and forces are), and the results are written.  Fails on the old code (no
    warning)."""
    import yaml
    from clirun import contact as cli

    (tmp_path / "touching.yaml").write_text(yaml.safe_dump(TOUCHING))
    proc = cli(
        tmp_path,
        "run",
        "touching.yaml",
        "-o",
        "out",
        "-q",
        ranks=ranks,
        env={"PYTHONWARNINGS": "default"},
    )
    assert proc.returncode == 0, proc.stderr
    warned = [ln for ln in proc.stderr.splitlines() if "the displacement is not unique" in ln]
    assert len(warned) == 1 and "body upper keeps 1 free rigid motion(s)" in warned[0], warned
    assert (tmp_path / "out" / "summary.json").exists()


LAYERS = "bodies={lower: {where: 'y < 0.25', E: 1}, upper: {where: 'y > 0.25', E: 2}}"


@pytest.mark.parametrize(
    "source, overrides, floating",
    [
        ("hertz_2d.yaml", [], []),
        ("two_body_hertz_2d.yaml", [], []),
        ("two_body_patch_2d.yaml", [], [("upper", 1)]),  # held by the symmetry x = 0 only
        ("two_body_patch_3d.yaml", [], [("upper", 1)]),
        ("block_on_plane.yaml", ["boundaries.top.role=neumann"], [("", 3)]),
        # two materials of one mesh share nodes: one rigid unit, held by the clamped top
        ("block_on_plane.yaml", [LAYERS, "model.E=null"], []),
        (
            "block_on_plane.yaml",
            [LAYERS, "model.E=null", "boundaries.top.role=neumann"],
            [("lower+upper", 3)],
        ),
    ],
)
def test_floating_bodies(source: str, overrides: list, floating: list) -> None:
    """The bodies no Dirichlet or symmetry part holds, and how many rigid motions they keep."""
    root = Path(__file__).resolve().parents[1] / "configs"
    scene = contact.load_scene(
        root / source,
        [*overrides, "adapt=none", "mesh.cells=[8,4]"]
        if source == "block_on_plane.yaml"
        else overrides,
    )
    assert build_problem(scene).floating == floating
