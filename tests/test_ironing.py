"""The ironing benchmark in plane strain (configs/hyperelastic_ironing_2d.yaml): a rigid
circular die pressed into a neo-Hookean block and dragged across it with Coulomb friction,
run as users run it (``contact run``, its default small mesh and load path, steps.csv read
back), serially and on 2 MPI ranks.

What must hold: the die follows its prescribed path (steps.csv's ``obstacle_translation``);
the contact force on the block is balanced by the clamped bottom's reaction (no other load;
to 1e-8); while the die is pressed in, the contact zone mostly sticks, and once it has slid
far enough every pressed node slips (steady sliding, most of the path); there the friction
force along the surface is μ times the normal force, |F_t / F_n − μ| ≤ 1 % μ; and the
2-rank run gives the serial forces (1e-8)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from clirun import ROOT, contact

pytestmark = pytest.mark.mpi

SCENE = ROOT / "configs" / "hyperelastic_ironing_2d.yaml"
MU = 0.3
#: the die's path: pressed in by 1.4 for t ≤ 0.2, then dragged by 4 (the scene's constants)
DEPTH, SLIDE = 1.4, 4.0
FORCES = (
    "normal_force",
    "surface_friction_force",
    "contact_force_x",
    "contact_force_y",
    "reaction_force_x",
    "reaction_force_y",
)


def run(tmp_path: Path, ranks: int) -> list[dict]:
    """The shipped scene through the CLI (no field files, no pictures): its steps.csv."""
    out = tmp_path / f"np{ranks}"
    proc = contact(
        tmp_path,
        "run",
        "-q",
        str(SCENE),
        "-o",
        str(out),
        "--set",
        "output.formats=[]",
        "--set",
        "output.png=false",
        ranks=ranks,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    with open(out / "steps.csv", newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def serial(tmp_path_factory) -> list[dict]:
    return run(tmp_path_factory.mktemp("ironing"), 0)


def column(rows: list[dict], key: str) -> np.ndarray:
    return np.array([float(r[key]) for r in rows])


def test_the_die_is_pressed_in_and_dragged_along_its_path(serial) -> None:
    t = column(serial, "time")
    assert len(t) == 30 and all(r["converged"] == "True" for r in serial)
    expected_x = SLIDE * np.maximum(t - 0.2, 0.0) / 0.8
    expected_y = -DEPTH * np.minimum(t / 0.2, 1.0)
    assert np.max(np.abs(column(serial, "obstacle_translation_x") - expected_x)) < 1e-12
    assert np.max(np.abs(column(serial, "obstacle_translation_y") - expected_y)) < 1e-12


def test_the_supports_balance_the_die(serial) -> None:
    """Action = reaction: the contact force on the block (each node's λ_n along its current
    normal plus λ_t) against the clamped bottom's reaction, every step."""
    contact_force = np.c_[column(serial, "contact_force_x"), column(serial, "contact_force_y")]
    reaction = np.c_[column(serial, "reaction_force_x"), column(serial, "reaction_force_y")]
    balance = np.linalg.norm(contact_force + reaction, axis=1)
    assert np.all(balance <= 1e-8 * np.linalg.norm(contact_force, axis=1))
    assert np.all(-column(serial, "contact_force_y") > 0)  # the die presses down
    sliding = column(serial, "time") > 0.2 + 1e-12
    assert np.all(column(serial, "contact_force_x")[sliding] > 0)  # and drags along +x


def test_steady_sliding_has_the_friction_coefficient_as_force_ratio(serial) -> None:
    """Pressed in, the contact zone mostly sticks; dragged, it goes through partial slip to
    full slip, where the friction force along the surface Σ w |λ_t| is μ times the normal
    force Σ w |λ_n| (1 % of μ)."""
    t = column(serial, "time")
    stick, slip = column(serial, "stick_nodes"), column(serial, "slip_nodes")
    pressed = np.isclose(t, 0.2)
    assert stick[pressed][0] > slip[pressed][0]
    steady = (t > 0.2 + 1e-12) & (stick == 0) & (slip > 0)
    assert steady.sum() >= 15  # of the 24 sliding steps
    assert np.all(steady[np.argmax(steady) :])  # once reached, it lasts
    ratio = column(serial, "surface_friction_force") / np.abs(column(serial, "normal_force"))
    assert np.all(np.abs(ratio[steady] - MU) <= 0.01 * MU)
    assert np.all(ratio[~steady & (t > 0)] < MU * (1 - 1e-6))  # stick: below the cone's edge
    assert np.allclose(column(serial, "surface_friction_ratio"), ratio, rtol=1e-12)


def test_two_ranks_give_the_serial_forces(serial, tmp_path: Path) -> None:
    parallel = run(tmp_path, 2)
    assert len(parallel) == len(serial)
    for key in ("stick_nodes", "slip_nodes", "separated_nodes"):
        assert np.array_equal(column(parallel, key), column(serial, key)), key
    for key in FORCES:
        a, b = column(serial, key), column(parallel, key)
        assert np.max(np.abs(a - b)) <= 1e-8 * np.max(np.abs(a)), key


def test_force_png_is_drawn_against_t_when_the_die_turns() -> None:
    """force.png's axis: the obstacle's approach while it moves along one direction, the
    pseudo-time once its translation turns (pressed in, then dragged)."""
    from contact.output.step_report import translation_turns

    down = [{"obstacle_translation": [0.0, -0.1 * k]} for k in range(4)]
    assert not translation_turns(down)
    assert not translation_turns([{"contact_force": 1.0}] * 3)  # no rigid obstacle
    assert translation_turns([*down, {"obstacle_translation": [0.5, -0.3]}])
