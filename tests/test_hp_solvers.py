"""``solver.linear: hp_patch`` (contact.hp.precondition): CG with the two-level vertex-patch
preconditioner on the hp systems gives the direct solve's hp loop on problem C — the same
unknowns, degrees and η per level to solver tolerance — with Krylov iterations that do not
grow with p_max, on 1 and 2 ranks; it refuses, naming the key, where it does not apply."""

from __future__ import annotations

from pathlib import Path

import contact
from contact.base.errors import ConfigError

import pytest
from clirun import ROOT, hp_serial_equals_two_ranks
from clirun import contact as cli

SMOOTH = ROOT / "configs" / "signorini_smooth.yaml"


def _hp_loop(linear: str, p_max: int, levels: int):
    scene = contact.load_scene(
        SMOOTH, ["output.verbose=false", f"solver.linear={linear}", "solver.inexact=false"]
    )
    return contact.adapt(scene, strategy="hp", p_max=p_max, max_levels=levels)


def test_hp_patch_gives_the_direct_solves_loop() -> None:
    """Per level: the same unknowns, cells and degrees as with MUMPS, η and the error to
    1e-8 relative (CG stops at a relative residual of 1e-10)."""
    direct, patch = (_hp_loop(linear, 4, 8) for linear in ("direct", "hp_patch"))
    assert [lv.result.linear for lv in patch.levels] == ["hp_patch"] * 8
    assert all(lv.result.krylov_iterations > 0 for lv in patch.levels)
    for a, b in zip(direct.levels, patch.levels, strict=True):
        ra, rb = a.row(), b.row()
        for key in ("dofs", "cells", "p_min", "p_max", "h_cells", "p_cells"):
            assert ra[key] == rb[key], (key, ra, rb)
        assert abs(a.estimate.eta - b.estimate.eta) <= 1e-8 * a.estimate.eta
        assert abs(a.error - b.error) <= 1e-8 * a.error


def test_hp_patch_iterations_do_not_grow_with_the_degree() -> None:
    """The most CG iterations of any solve of 14 hp levels at p_max 6 are at most 1.25 × those
    at p_max 2 (measured 11 against 12; CG + GAMG: 37 against 25, 1.48 ×), and below 20."""
    most = {}
    for p_max in (2, 6):
        run = _hp_loop("hp_patch", p_max, 14)
        most[p_max] = max(e["iterations"] for lv in run.levels for e in lv.result.krylov_log)
        assert run.levels[-1].row()["p_max"] >= min(p_max, 5)  # the degrees did grow
    assert most[6] <= 1.25 * most[2] and most[6] < 20, most


CUBE = {  # problem C in the unit cube, coarse
    "name": "cube",
    "mesh": {"type": "box", "corners": [[0, 0, 0], [1, 1, 1]], "cells": [2, 2, 2]},
    "boundaries": {
        "contact": {"role": "contact", "where": "z < 1e-10"},
        # one part per face: a facet of a face has all its vertices on it, and on no other
        **{
            f"face{i}": {"role": "dirichlet", "where": where}
            for i, where in enumerate(
                ("x < 1e-10", "x > 1 - 1e-10", "y < 1e-10", "y > 1 - 1e-10", "z > 1 - 1e-10")
            )
        },
    },
    "model": "signorini",
    "data": {"f": "-2", "g": "0", "u_D": "z**2"},
    "solver": {"linear": "hp_patch"},
    "output": {"verbose": False},
}


def test_hp_patch_refuses_where_it_does_not_apply() -> None:
    """One ConfigError naming solver.linear: a problem that is not hp, an elastic hp problem,
    a 3D hp problem."""
    plain = contact.load_scene(SMOOTH, ["output.verbose=false", "solver.linear=hp_patch"])
    with pytest.raises(ConfigError, match="solver.linear: hp_patch"):
        contact.solve(plain)
    hertz = contact.load_scene(
        ROOT / "configs" / "hertz_2d.yaml", ["output.verbose=false", "solver.linear=hp_patch"]
    )
    with pytest.raises(ConfigError, match="solver.linear: hp_patch"):
        contact.adapt(hertz, strategy="hp", max_levels=1)
    with pytest.raises(ConfigError, match="solver.linear: hp_patch applies to 2D"):
        contact.adapt(contact.load_scene(CUBE), strategy="hp", p_max=2, max_levels=1)


def test_hp_patch_serial_equals_two_ranks(tmp_path: Path) -> None:
    """``--set solver.linear=hp_patch`` through ``contact run`` on 1 and 2 ranks: the same
    unknowns, cells and degrees per level, η to 1e-8 (the patches are cut at the ranks'
    boundaries: the iterations may differ, the solutions not)."""
    sets = [
        "adapt.strategy=hp",
        "adapt.p_max=4",
        "adapt.max_levels=5",
        "output.png=false",
        "solver.linear=hp_patch",
    ]
    one, two = hp_serial_equals_two_ranks(tmp_path, SMOOTH.name, sets, 5)
    for a, b in zip(one, two):
        assert 0 < int(b["krylov_iterations"]) < 3 * int(a["krylov_iterations"])


def test_hp_patch_on_a_bad_scene_exits_2(tmp_path: Path) -> None:
    """The CLI: hp_patch on a scene that is not hp is bad input, one line naming the key."""
    proc = cli(
        tmp_path,
        "run",
        str(SMOOTH),
        "-o",
        str(tmp_path / "out"),
        "-q",
        "--set",
        "solver.linear=hp_patch",
    )
    assert proc.returncode == 2, proc.stderr
    assert "solver.linear" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
