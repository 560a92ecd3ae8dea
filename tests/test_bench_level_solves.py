"""demos/bench/bench_level_solves.py on small meshes of PETSc's ex9: the loop's levels and
the uniform run's sequencing levels, each solve's figures as its result reports them."""

from __future__ import annotations

from pathlib import Path

import contact

import pytest

ROOT = Path(__file__).resolve().parents[1]
EX9 = ROOT / "configs" / "peers" / "petsc_ex9.yaml"


@pytest.fixture(scope="module")
def bench():
    """The bench script imported as a module."""
    from bench_scripts import load

    return load("bench_level_solves")


def test_levels_and_uniform_run_report_their_solves(bench) -> None:
    """Per loop level: its DoFs grow, each Newton step and polishing solve of a GAMG level
    is one Krylov solve (a set-up each at most), ‖Φ‖ falls from its start; the uniform run on
    the 8× mesh has (16·8 + 1)² DoFs and its coarser sequencing levels before it."""
    sets = ["output.verbose=false", "adapt.growth=3", "adapt.indicators=residual"]
    scene = contact.load_scene(EX9, sets)
    rows = bench.adaptive_run(scene, 40_000, "loop", krylov=False)
    assert [r["level"] for r in rows] == list(range(len(rows))) and len(rows) >= 4
    assert all(a["dofs"] < b["dofs"] for a, b in zip(rows, rows[1:]))
    gamg = [r for r in rows if r["linear"] == "gamg"]
    assert gamg and all(r["dofs"] >= 5_000 for r in gamg)
    for r in gamg:
        solves = r["newton_iterations"] + r["polish_solves"]
        assert r["krylov_solves"] == solves and 1 <= r["gamg_setups"] <= solves, r
    assert all(r["phi_end"] < r["phi_start"] and r["stopping"] == "fixed" for r in rows)
    uniform = bench.uniform_run(EX9, 8, [], krylov=False)
    *coarse, fine = uniform
    assert fine["run"] == "uniform" and fine["dofs"] == (16 * 8 + 1) ** 2
    assert [r["run"] for r in coarse] == ["sequence"] * len(coarse) and coarse
    assert all(r["dofs"] < fine["dofs"] for r in coarse)


def test_a_switch_is_measured_old_against_new(bench) -> None:
    """``--switch``: the loop runs with the switch off, then on, and the pair's figures say
    whether both made the same levels and how far their errors differ.  The projected guess
    (``contact.solvers.snes.ADMISSIBLE_GUESS``) takes ex9's levels with fewer linear solves
    to the same errors; the switch is left on; a name that is no switch is refused."""
    import argparse

    from contact.solvers import snes

    sets = ["output.verbose=false", "adapt.growth=3", "adapt.indicators=residual"]
    scene = contact.load_scene(EX9, sets)
    args = argparse.Namespace(
        pairs=1,
        max_dofs=12_000,
        uniform=0,
        switch="contact.solvers.snes.ADMISSIBLE_GUESS",
        krylov=False,
        history=True,
        overrides=sets[1:],
    )
    rows = bench.switch_runs(args, EX9, scene)
    pair = rows[-1]
    assert pair["run"] == "pair" and pair["same_levels"], pair
    assert pair["error_rel_diff"] < 1e-10, pair
    assert pair["solves_new"] < pair["solves_old"], pair
    assert {r["run"] for r in rows[:-1]} == {"loop-old", "loop-new"}
    assert snes.ADMISSIBLE_GUESS is True
    with pytest.raises(SystemExit):
        bench.set_switch("contact.solvers.snes.ROUNDOFF", True)
